"""Drawing meshes and scenes with a camera and a built-in program: the glue above :func:`softpipe.draw`.

- :func:`standard_uniforms` builds the uniforms every built-in program reads
  (``model_view``, ``projection``, ``normal_matrix``, ``view``);
- :func:`draw_mesh` draws one :class:`~softpipe.mesh.Mesh` with them: the one way
  the Python API, the command line and scene files draw a mesh (its material,
  lighting, texture, faceted programs, mirrored model matrices);
- :func:`render_scene` draws a :class:`~softpipe.scene.Scene` into a new
  framebuffer, one :func:`draw_mesh` per object, and the wireframe over it if asked;
- :class:`DrawResult` is what one draw left (post-clip primitives, trace, timings).

Uniforms
--------
Every draw gets the standard uniforms plus ``material`` (the mesh's
:class:`~softpipe.material.Material`), ``color`` (its ``kd``), ``lighting`` (a
:class:`~softpipe.material.LightingUniform`: the lights in eye space and the global
ambient) and, when there is one, ``texture`` (a :class:`~softpipe.texture.Texture2D`);
a caller's ``uniforms`` are added last and override these.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Union

import numpy as np

from .camera import Camera
from .framebuffer import Framebuffer
from .material import LightingUniform
from .pipeline import DrawCall
from .sampling import pattern_named
from .scene import Scene, SceneObject, program_for
from .shaders import Program, get_program
from .shaders.common import lighting_uniform
from .transforms import compose, normal_matrix

__all__ = ["standard_uniforms", "draw_mesh", "render_scene", "DrawResult"]

FRONT_FACES = ("ccw", "cw")


def standard_uniforms(camera: Camera, aspect: float, model: Optional[np.ndarray] = None) -> Dict[str, Any]:
    """The matrices every built-in program reads, for a camera and a model matrix.

    Parameters
    ----------
    camera : Camera
    aspect : float
        Width / height of the image (the projection's aspect ratio).
    model : array [4, 4], optional
        Model → world; the identity by default.

    Returns
    -------
    dict
        ``model_view`` (view · model), ``projection``, ``normal_matrix`` (the inverse
        transpose of model_view's upper 3×3, so normals stay perpendicular to the
        surface under any scale or mirror) and ``view``.
    """
    model = np.eye(4) if model is None else np.asarray(model, dtype=np.float64)
    if model.shape != (4, 4):
        raise ValueError(f"model must be a 4×4 matrix, got shape {model.shape}")
    view = camera.view
    model_view = compose(view, model)
    return {"model_view": model_view, "projection": camera.projection(aspect),
            "normal_matrix": normal_matrix(model_view), "view": view}


@dataclass
class DrawResult:
    """What one draw of :func:`draw_mesh` left.

    Attributes
    ----------
    name : str
        The mesh's name (a scene object's name in :func:`render_scene`).
    program : str
        The program's name.
    primitives : Primitives
        The post-clip triangles that reached the rasterizer (a wireframe draws them).
    trace : Trace or None
        Every stage's output, when drawn with ``trace=True``.
    timings : dict
        Seconds spent in each stage.
    """

    name: str
    program: str
    primitives: Any
    trace: Any = None
    timings: Dict[str, float] = field(default_factory=dict)


def draw_mesh(framebuffer: Framebuffer, mesh, camera: Camera, program: Union[str, Program] = "phong", *,
              model: Optional[np.ndarray] = None, lighting=None, texture=None,
              uniforms: Optional[Mapping[str, Any]] = None, cull: str = "back", front_face: str = "ccw",
              results: Optional[List[DrawResult]] = None, trace: bool = False, **state):
    """Draw ``mesh`` seen by ``camera`` with a built-in ``program`` (a name or a Program).

    Parameters
    ----------
    framebuffer : Framebuffer
    mesh : Mesh
        Its normals are used when it has them, else computed (area-weighted). A
        faceted program (``flat``) gets ``mesh.flat_shaded()``: one normal per face. A
        mesh with several materials is drawn once per material, in order.
    camera : Camera
    program : str or Program
        See :data:`softpipe.shaders.PROGRAMS` (``softpipe programs`` lists them).
    model : array [4, 4], optional
        Model → world. A mirroring matrix (negative determinant) turns the mesh's
        winding around on the screen, so the front faces become ``front_face``'s
        opposite there and culling still removes the back faces.
    lighting : Lighting, Light, list of Lights, LightingUniform or None
        Given to the program as the uniform ``lighting``, in eye space (a
        LightingUniform is taken as already in eye space); None: the default lights.
    texture : Texture2D, image path or None
        The uniform ``texture`` (``textured`` reads it), for every material of the
        mesh. A material's ``diffuse_texture`` is not loaded here:
        :meth:`softpipe.scene.Scene.from_model` and scene files load it.
    uniforms : dict, optional
        Added to the standard ones, last (they override them).
    cull : "back", "front" or "none"
    front_face : "ccw" or "cw"
        The winding of the mesh's front faces as it is stored (before ``model``).
    results : list, optional
        Receives one :class:`DrawResult` per draw (one per material).
    trace : bool
        Keep every stage's output (:class:`~softpipe.trace.Trace`).
    **state
        Passed on to :class:`softpipe.DrawCall` as :func:`softpipe.draw` takes them
        (``depth_test``, ``blend``, ``sample_shading``, ``path``, ``viewport``, …).

    Returns
    -------
    Trace or None
        As :func:`softpipe.draw` returns: the (last) draw's Trace with ``trace=True``.
    """
    prog = get_program(program)
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    if getattr(mesh, "materials", ()) and len(mesh.materials) > 1:
        out = None
        for _, part in mesh.by_material():
            out = draw_mesh(framebuffer, part, camera, prog, model=model, lighting=lighting, texture=texture,
                            uniforms=uniforms, cull=cull, front_face=front_face, results=results, trace=trace,
                            **state)
        return out
    if prog.faceted:
        mesh = mesh.flat_shaded()
    u = standard_uniforms(camera, framebuffer.width / framebuffer.height, model)
    u["material"] = mesh.material
    u["color"] = mesh.material.kd
    u["lighting"] = lighting if isinstance(lighting, LightingUniform) else lighting_uniform(lighting, u["view"])
    if texture is not None:
        u["texture"] = _texture(texture)
    u.update(uniforms or {})
    attributes = {"normal": mesh.normals if mesh.normals is not None else mesh.vertex_normals()}
    if mesh.uvs is not None:
        attributes["uv"] = mesh.uvs
    if model is not None and np.linalg.det(np.asarray(model, dtype=np.float64)[:3, :3]) < 0:
        # A mirror reverses the order in which a triangle's corners go round on the
        # screen, so a front face of the mesh arrives wound the other way.
        front_face = "cw" if front_face == "ccw" else "ccw"
    call = DrawCall(framebuffer, mesh.positions, mesh.indices, None, prog.vertex, prog.fragment, u,
                    attributes=attributes, interpolation=dict(prog.interpolation) or None, cull=cull,
                    front_face=front_face, **state)
    out = call.run(trace=trace)
    if results is not None:
        primitives = out.primitives if trace else call.primitives
        results.append(DrawResult(getattr(mesh, "name", ""), prog.name, primitives, out, dict(call.timings)))
    return out


def _texture(texture):
    """A Texture2D as it is, or one read from an image file."""
    if isinstance(texture, (str, os.PathLike)):
        from .texture import Texture2D
        return Texture2D(texture)
    return texture


def render_scene(scene: Scene, *, camera: Optional[Camera] = None, trace: bool = False,
                 results: Optional[list] = None,
                 progress: Optional[Callable[[int, int, SceneObject], None]] = None) -> Framebuffer:
    """Draw every object of ``scene`` into a new framebuffer (and the wireframe, if asked).

    Parameters
    ----------
    scene : Scene
    camera : Camera, optional
        Replaces the scene's (:meth:`~softpipe.scene.Scene.view_camera` by default).
    trace : bool
        Keep each draw's Trace (in its :class:`DrawResult`).
    results : list, optional
        Receives one :class:`DrawResult` per object, named as the object.
    progress : callable, optional
        ``progress(k, n, object)`` is called before draw k of n.

    Returns
    -------
    Framebuffer
        ``scene.width`` × ``scene.height``, the scene's sample pattern, cleared to its
        background, every object drawn in order with :func:`draw_mesh`.
    """
    from .pictures import draw_wireframe

    camera = camera or scene.view_camera()
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples))
    fb.clear(scene.background)
    lighting = scene.lighting_for(camera).uniform(camera.view)  # once for every draw: eye space
    drawn: List[DrawResult] = []
    for k, obj in enumerate(scene.objects):
        if progress is not None:
            progress(k, len(scene.objects), obj)
        first = len(drawn)
        draw_mesh(fb, obj.mesh, camera, program_for(obj, scene.program), model=obj.model, lighting=lighting,
                  texture=obj.texture, cull=obj.cull or scene.cull, sample_shading=scene.sample_shading,
                  trace=trace, results=drawn)
        for r in drawn[first:]:
            r.name = obj.name
    if results is not None:
        results.extend(drawn)
    if scene.wireframe:
        draw_wireframe(fb, [r.primitives for r in drawn], scene.wireframe_color)
    return fb
