"""Drawing meshes and scenes with a camera and a built-in program: the glue above :func:`softpipe.draw`.

- :func:`standard_uniforms` builds the uniforms every built-in program reads
  (``model_view``, ``projection``, ``normal_matrix``, ``view``);
- :func:`draw_mesh` draws one :class:`~softpipe.scenes.mesh.Mesh` with them: the one way
  the Python API, the command line and scene files draw a mesh (its material,
  lighting, texture, faceted programs, mirrored model matrices; its line segments
  and points after the triangles, :func:`draw_lines_and_points`);
- :func:`render_scene` draws a :class:`~softpipe.scenes.scene.Scene` into a new
  framebuffer, one :func:`draw_mesh` per object (the opaque ones in the scene's order,
  then the transparent ones sorted back to front: :func:`draw_order`), and the
  wireframe over it if asked (:func:`draw_wireframe`: the pipeline's own lines,
  polygon mode "line"); :func:`scene_lighting` and :func:`draw_object` are its two
  steps, for other renderers of a scene (:mod:`softpipe.scenes.transparency`);
- :func:`render` and :func:`turntable` are ``softpipe render`` and ``softpipe
  turntable`` in Python (``softpipe.render("teapot")``): the command line calls
  them, so they make the same pixels, with the same defaults (size, framing, the
  studio lights, the program); :func:`prepare_scene` is the scene they draw;
- :class:`DrawResult` is what one draw left (post-clip primitives, trace, timings).

A mesh is a :class:`~softpipe.scenes.mesh.Mesh` or anything with ``.vertices`` [N, 3] and
``.faces`` [M, 3] (a ``trimesh.Trimesh``, say): :func:`as_mesh` converts it.

Uniforms
--------
Every draw gets the standard uniforms plus ``material`` (the mesh's
:class:`~softpipe.light.material.Material`), ``color`` (its ``kd``), ``lighting`` (a
:class:`~softpipe.light.material.LightingUniform`: the lights in eye space and the global
ambient) and, when there is one, ``texture`` (a :class:`~softpipe.light.texture.Texture2D`);
a caller's ``uniforms`` are added last and override these.
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy as np

from softpipe.core.colors import parse_color, rgba
from softpipe.light.material import Lighting, LightingUniform
from softpipe.pipeline.assembly import check_size
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES, Framebuffer
from softpipe.pipeline.sampling import pattern_named
from softpipe.pipeline.transforms import compose, normal_matrix
from softpipe.programs import PROGRAMS, Program, get_program
from softpipe.programs.common import lighting_uniform
from softpipe.scenes.formats import FORMATS
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.outputs import RenderOutputs, check_outputs, derive_outputs
from softpipe.scenes.scene import Scene, SceneObject, program_for, studio_lights
from softpipe.scenes.shadow_pass import render_shadow_maps

__all__ = ["standard_uniforms", "draw_mesh", "draw_lines_and_points", "render_scene", "draw_wireframe", "WIREFRAME_STATE", "DrawResult", "as_mesh", "prepare_scene", "render",
           "is_transparent", "eye_depth", "draw_order", "TRANSPARENT_STATE", "scene_lighting", "draw_object",
           "turntable", "input_kind", "default_lighting", "gif_frame",
           "MAX_FRAMES", "RENDER_SIZE", "TURNTABLE_SIZE", "animation_format", "frame_duration"]

FRONT_FACES = ("ccw", "cw")
CULL_MODES = ("back", "front", "none")
#: The most frames :func:`turntable` renders.
MAX_FRAMES = 3600
#: What :func:`render` and :func:`turntable` draw at when no size is given (a model; a scene keeps its own).
RENDER_SIZE = (640, 480)
TURNTABLE_SIZE = (320, 240)


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
    pictures : dict
        Stage name → path of the pictures :func:`render` wrote for this draw (``stages=``).
    """

    name: str
    program: str
    primitives: Any
    trace: Any = None
    timings: Dict[str, float] = field(default_factory=dict)
    pictures: Dict[str, Path] = field(default_factory=dict)


def as_mesh(mesh) -> Mesh:
    """A :class:`~softpipe.scenes.mesh.Mesh` as it is, or one made from a trimesh-like object.

    Anything with ``.vertices`` (float [N, 3]) and ``.faces`` (int [M, 3],
    counter-clockwise seen from outside) is taken, e.g. a ``trimesh.Trimesh``; its
    ``vertex_normals`` are used when it has them ([N, 3]), and ``visual.uv`` as texture
    coordinates when that is [N, 2]. Its name is its ``name`` (or ``metadata["name"]``).
    """
    if isinstance(mesh, Mesh):
        return mesh
    if not (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
        raise TypeError(f"expected a softpipe Mesh or an object with .vertices and .faces (like a trimesh.Trimesh), "
                        f"got {type(mesh).__name__}")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces)
    label = getattr(mesh, "name", None)
    if not isinstance(label, str) or not label:
        metadata = getattr(mesh, "metadata", None)
        label = metadata.get("name") if isinstance(metadata, dict) else None
        label = label if isinstance(label, str) and label else type(mesh).__name__
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"{label}: faces must be triangles, an [M, 3] array of vertex indices, got shape "
                         f"{faces.shape}")
    normals = _optional_array(mesh, "vertex_normals", (len(vertices), 3))
    uvs = _optional_array(getattr(mesh, "visual", None), "uv", (len(vertices), 2))
    return Mesh(vertices, faces, normals=normals, uvs=uvs, name=label)


def _optional_array(owner, name: str, shape) -> Optional[np.ndarray]:
    """``owner.name`` as a float array when it exists and has ``shape``; else None."""
    try:
        value = getattr(owner, name, None)
        a = None if value is None else np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, AttributeError):
        return None
    return a if a is not None and a.shape == tuple(shape) and np.all(np.isfinite(a)) else None


def default_lighting(camera: Camera) -> Lighting:
    """What :func:`draw_mesh` lights with when given no lighting: the command line's studio lights.

    :func:`softpipe.scenes.scene.studio_lights` for ``camera`` (key, fill and rim, following
    the camera) with OpenGL's global ambient (0.2): what ``softpipe render`` shows.
    """
    return Lighting(studio_lights(camera))


def draw_mesh(framebuffer: Framebuffer, mesh, camera: Camera, program: Union[str, Program, Callable] = "phong", *,
              model: Optional[np.ndarray] = None, lighting=None, texture=None,
              uniforms: Optional[Mapping[str, Any]] = None, cull: str = "back", front_face: str = "ccw",
              results: Optional[List[DrawResult]] = None, trace: bool = False, point_size: float = 1.0,
              line_width: float = 1.0, **state):
    """Draw ``mesh`` seen by ``camera`` with a built-in ``program`` (a name or a Program).

    Parameters
    ----------
    framebuffer : Framebuffer
    mesh : Mesh or trimesh-like
        A :class:`~softpipe.scenes.mesh.Mesh`, or anything with ``.vertices`` and ``.faces``
        (:func:`as_mesh`). Its normals are used when it has them, else computed
        (area-weighted, shared by vertex records at one position). A
        faceted program (``flat``) gets ``mesh.flat_shaded()``: one normal per face. A
        mesh with several materials is drawn once per material, in order.
    camera : Camera
    program : str, Program or function
        A registered program (:data:`softpipe.programs.PROGRAMS`; ``softpipe programs`` lists
        them), a Program, a fragment shader function (drawn with ``standard_vertex``) or
        ``"module:function"`` (:func:`~softpipe.programs.get_program`).
    model : array [4, 4], optional
        Model → world. A mirroring matrix (negative determinant) turns the mesh's
        winding around on the screen, so the front faces become ``front_face``'s
        opposite there and culling still removes the back faces.
    lighting : Lighting, Light, list of Lights, LightingUniform or None
        Given to the program as the uniform ``lighting``, in eye space (a
        LightingUniform is taken as already in eye space); None: the command line's
        studio lights for ``camera`` (:func:`default_lighting`). For the single key light
        of :data:`softpipe.programs.common.DEFAULT_LIGHTING`, pass it.
    texture : Texture2D, image path or None
        The uniform ``texture`` (``textured`` reads it), for every material of the
        mesh. A material's ``diffuse_texture`` is not loaded here:
        :meth:`softpipe.scenes.scene.Scene.from_model` and scene files load it.
    uniforms : dict, optional
        Added to the standard ones, last (they override them).
    cull : "back", "front" or "none"
    front_face : "ccw" or "cw"
        The winding of the mesh's front faces as it is stored (before ``model``).
    results : list, optional
        Receives one :class:`DrawResult` per draw (one per material).
    trace : bool
        Keep every stage's output (:class:`~softpipe.pipeline.trace.Trace`).
    point_size, line_width : float
        The size of the mesh's points and the width of its line segments (an OBJ's
        ``p`` and ``l``), in pixels, as :func:`softpipe.draw` takes them; they are drawn
        after the triangles by :func:`draw_lines_and_points` (which see for the program).
    **state
        Passed on to :class:`softpipe.DrawCall` as :func:`softpipe.draw` takes them
        (``depth_test``, ``blend``, ``sample_shading``, ``path``, ``viewport``, …).

    Returns
    -------
    Trace or None
        As :func:`softpipe.draw` returns: the (last) draw's Trace with ``trace=True``.
    """
    prog = get_program(program)
    mesh = as_mesh(mesh)
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    if prog.name == "textured" and mesh.uvs is None:
        raise ValueError(f"{mesh.name or 'the mesh'} has no texture coordinates (uv), so program 'textured' "
                         "cannot draw it")
    if getattr(mesh, "materials", ()) and len(mesh.materials) > 1:
        out = None
        for _, part in mesh.by_material():
            out = draw_mesh(framebuffer, part, camera, prog, model=model, lighting=lighting, texture=texture,
                            uniforms=uniforms, cull=cull, front_face=front_face, results=results, trace=trace,
                            point_size=point_size, line_width=line_width, **state)
        return out
    loose = mesh if mesh.segment_count or mesh.point_count else None
    mesh = mesh.without_lines_and_points()
    if prog.faceted:
        mesh = mesh.flat_shaded()
    u = standard_uniforms(camera, framebuffer.width / framebuffer.height, model)
    u["material"] = mesh.material
    u["color"] = mesh.material.kd
    if lighting is None:
        lighting = default_lighting(camera)
    u["lighting"] = lighting if isinstance(lighting, LightingUniform) else lighting_uniform(lighting, u["view"])
    if texture is not None:
        u["texture"] = _texture(texture)
    u.update(uniforms or {})
    out = None
    if loose is not None and mesh.triangle_count == 0:
        return draw_lines_and_points(framebuffer, loose, prog, u, results=results, trace=trace,
                                     point_size=point_size, line_width=line_width, **state)
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
    if loose is not None:
        out = draw_lines_and_points(framebuffer, loose, prog, u, results=results, trace=trace,
                                    point_size=point_size, line_width=line_width, **state) or out
    return out


#: State that applies to triangles only, which the draws of a mesh's lines and points leave out.
_TRIANGLE_STATE = ("polygon_mode", "polygon_offset")


def draw_lines_and_points(framebuffer: Framebuffer, mesh: Mesh, program: Program, uniforms: Mapping[str, Any], *,
                          results: Optional[List[DrawResult]] = None, trace: bool = False,
                          point_size: float = 1.0, line_width: float = 1.0, **state):
    """Draw a single-material mesh's line segments (one ``"lines"`` draw) and then its points
    (one ``"points"`` draw), as :func:`draw_mesh` does after its triangles.

    Lines and points have no surface, so no normal to light: a built-in program
    (:data:`softpipe.programs.PROGRAMS`: ``phong``, ``flat``, ``textured``, …) draws them as
    ``unlit`` does, in the uniform ``color`` (the material's ``kd``), as most renderers show a
    curve or a point cloud. A program of the caller's own (a Program not registered, a
    fragment shader function) draws them itself, so that it can read ``frag.point_coord``
    (round points, sprites); its ``normal`` attribute is then the constant one that faces
    the camera (eye-space +z). Neither is culled (GL culls polygons only); the triangles'
    polygon mode and offset do not apply. ``uniforms`` are :func:`draw_mesh`'s, complete.

    Returns the last draw's Trace with ``trace=True`` (else None).
    """
    builtin = PROGRAMS.get(program.name) is program
    prog = PROGRAMS["unlit"] if builtin else program
    toward_eye = np.asarray(uniforms["model_view"], np.float64)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    norm = float(np.linalg.norm(toward_eye))
    normal = toward_eye / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    attributes = {"normal": np.tile(normal, (mesh.vertex_count, 1))}
    if mesh.uvs is not None:
        attributes["uv"] = mesh.uvs
    state = {k: v for k, v in state.items() if k not in _TRIANGLE_STATE}
    out = None
    for topology, indices in (("lines", mesh.lines), ("points", mesh.points)):
        if not len(indices):
            continue
        call = DrawCall(framebuffer, mesh.positions, indices, None, prog.vertex, prog.fragment, dict(uniforms),
                        attributes=attributes, interpolation=dict(prog.interpolation) or None, topology=topology,
                        point_size=point_size, line_width=line_width, **state)
        out = call.run(trace=trace)
        if results is not None:
            primitives = out.primitives if trace else call.primitives
            results.append(DrawResult(getattr(mesh, "name", ""), prog.name, primitives, out, dict(call.timings)))
    return out


def _texture(texture):
    """A Texture2D as it is, or one read from an image file."""
    if isinstance(texture, (str, os.PathLike)):
        from softpipe.light.texture import Texture2D
        return Texture2D(texture)
    return texture


#: The state :func:`render_scene` draws a transparent object in (:func:`is_transparent`): blended
#: "over" what is behind it, color src·α + dst·(1 − α) (as ``blend="alpha"``) and alpha
#: α + A·(1 − α) (separate alpha factors, so the picture's alpha is the coverage, not α² + …),
#: and tested against the depth buffer without writing it, so a transparent surface hides
#: neither the opaque ones (drawn before it) nor the transparent ones drawn after it.
TRANSPARENT_STATE: Dict[str, Any] = {"blend": ("src_alpha", "one_minus_src_alpha", "one", "one_minus_src_alpha"),
                                     "depth_write": False}


def is_transparent(obj: SceneObject) -> bool:
    """Does ``obj`` let what is behind it show: a material of its mesh with ``opacity`` below 1?"""
    materials = getattr(obj.mesh, "materials", ()) or (obj.mesh.material,)
    return any(m.opacity < 1.0 for m in materials)


def eye_depth(obj: SceneObject, camera: Camera) -> float:
    """How far in front of ``camera`` ``obj`` is, for sorting: −z, in eye space, of the centre of its
    world bounding box (the box's centre, not the vertices' mean, so a finely tessellated side
    does not pull it). One number an object: objects that interpenetrate cannot be put in one
    order that is right at every pixel, and sorting does not try."""
    positions = obj.world_positions()
    if not len(positions):
        return 0.0
    centre = (positions.min(axis=0) + positions.max(axis=0)) / 2.0
    return float(-(camera.view[2, :3] @ centre + camera.view[2, 3]))


def draw_order(objects: List[SceneObject], camera: Camera) -> List[SceneObject]:
    """The order :func:`render_scene` draws ``objects`` in: the opaque ones first, in the order given;
    then the transparent ones (:func:`is_transparent`) back to front, farthest :func:`eye_depth`
    first (equal depths keep the order given)."""
    opaque = [o for o in objects if not is_transparent(o)]
    clear = [o for o in objects if is_transparent(o)]
    return opaque + sorted(clear, key=lambda o: -eye_depth(o, camera))


def scene_lighting(scene: Scene, camera: Camera, objects: List[SceneObject], shadow_maps: Optional[list] = None):
    """The ``lighting`` uniform every draw of ``scene`` seen by ``camera`` gets, in eye space: its lights,
    with their shadow maps made first (from ``objects``' casters) when a light casts shadows; the
    :class:`~softpipe.scenes.shadow_pass.ShadowMaps` are appended to ``shadow_maps`` if given."""
    lights = scene.lighting_for(camera)
    if any(light.shadows is not None for light in lights.lights):
        maps = render_shadow_maps(objects, lights)
        if shadow_maps is not None:
            shadow_maps.append(maps)
        return maps.lighting_uniform(lights, camera.view)
    return lights.uniform(camera.view)  # once for every draw: eye space


def draw_object(fb: Framebuffer, scene: Scene, obj: SceneObject, camera: Camera, lighting, *,
                program: Union[str, Program, Callable, None] = None, trace: bool = False,
                results: Optional[list] = None, **state):
    """Draw one object of ``scene`` as :func:`render_scene` does (its program, model matrix, texture,
    cull mode; the scene's sample shading, point size and line width), with ``lighting`` from
    :func:`scene_lighting`. ``program`` replaces the object's; ``state`` is added to the draw's
    (:func:`draw_mesh`'s ``**state``). The :class:`DrawResult` s appended to ``results`` are
    named as the object. Returns what :func:`draw_mesh` returns."""
    first = len(results) if results is not None else 0
    out = draw_mesh(fb, obj.mesh, camera, program or program_for(obj, scene.program), model=obj.model,
                    lighting=lighting, texture=obj.texture, cull=obj.cull or scene.cull,
                    sample_shading=scene.sample_shading, trace=trace, results=results,
                    point_size=scene.point_size, line_width=scene.line_width, **state)
    for r in (results or [])[first:]:
        r.name = obj.name
    return out


def render_scene(scene: Scene, *, camera: Optional[Camera] = None, trace: bool = False,
                 results: Optional[list] = None,
                 progress: Optional[Callable[[int, int, SceneObject], None]] = None,
                 shadow_maps: Optional[list] = None, wireframe: bool = True, record: bool = False) -> Framebuffer:
    """Draw every object of ``scene`` into a new framebuffer (and the wireframe, if asked).

    Parameters
    ----------
    scene : Scene
    camera : Camera, optional
        Replaces the scene's (:meth:`~softpipe.scenes.scene.Scene.view_camera` by default).
    trace : bool
        Keep each draw's Trace (in its :class:`DrawResult`).
    results : list, optional
        Receives one :class:`DrawResult` per object, named as the object, in the order drawn.
    progress : callable, optional
        ``progress(k, n, object)`` is called before draw k of n.
    shadow_maps : list, optional
        Receives the :class:`~softpipe.scenes.shadow_pass.ShadowMaps` when a light casts shadows.
    wireframe : bool
        False leaves the edges of a scene with ``wireframe`` set to the caller, who draws them
        later with :func:`draw_wireframe`.
    record : bool
        Draw into a framebuffer that keeps a visibility record (``Framebuffer(..., record=True)``),
        each recorded draw tagged with its object's index in ``scene.drawn_objects(camera)``
        (what :func:`softpipe.scenes.outputs.derive_outputs` reads).

    Returns
    -------
    Framebuffer
        ``scene.width`` × ``scene.height``, the scene's sample pattern, cleared to its
        background, every object drawn with :func:`draw_mesh` (and the ground,
        :meth:`~softpipe.scenes.scene.Scene.drawn_objects`) in :func:`draw_order`: the
        opaque objects in the scene's order, then the transparent ones (a material's
        ``opacity`` below 1) sorted back to front by :func:`eye_depth` and drawn in
        :data:`TRANSPARENT_STATE` (alpha blending, no depth writes). Sorting by object is
        right where the transparent objects do not overlap in depth; where they
        interpenetrate it is not (docs/transparency.md: depth peeling and weighted OIT in
        :mod:`softpipe.scenes.transparency`). Lights with ``shadows`` set get their shadow
        maps first (:func:`softpipe.scenes.shadow_pass.render_shadow_maps`, from the
        objects whose ``cast_shadows`` is true).
    """
    camera = camera or scene.view_camera()
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples), srgb=scene.srgb, record=record)
    fb.clear(scene.background)
    objects = scene.drawn_objects(camera)
    index = {id(o): k for k, o in enumerate(objects)}
    lighting = scene_lighting(scene, camera, objects, shadow_maps)
    drawn: List[DrawResult] = []
    order = draw_order(objects, camera)
    for k, obj in enumerate(order):
        if progress is not None:
            progress(k, len(order), obj)
        first = len(fb.recorded_draws)
        draw_object(fb, scene, obj, camera, lighting, trace=trace, results=drawn,
                    **(TRANSPARENT_STATE if is_transparent(obj) else {}))
        for entry in fb.recorded_draws[first:]:
            entry.tag = index[id(obj)]
    if results is not None:
        results.extend(drawn)
    if scene.wireframe and wireframe:
        draw_wireframe(fb, scene, camera)
    return fb


#: The state of a wireframe's draw over a shaded surface, as GL users draw one: polygon mode
#: "line", the depth test "lequal" against the surface, no depth written, and GL's polygon
#: offset (factor −1, units −1) pulling each edge toward the viewer by its triangle's slope,
#: so it wins against the faces it bounds instead of z-fighting with them.
WIREFRAME_STATE: Dict[str, Any] = {"polygon_mode": "line", "depth_test": "lequal", "depth_write": False,
                   "polygon_offset": (-1.0, -1.0)}


def draw_wireframe(fb: Framebuffer, scene: Scene, camera: Camera, *, trace: bool = False,
                   results: Optional[list] = None) -> None:
    """Draw the edges of every object of ``scene`` over ``fb``: the pipeline's own lines.

    Each object's triangles again, in polygon mode "line" (GL's ``glPolygonMode``), with the
    program ``unlit`` in ``scene.wireframe_color``, culled as the object is, in the state
    :data:`WIREFRAME_STATE`: the edges on the visible surface and its silhouettes show,
    those behind it do not. A mesh's own line segments and points are not drawn again.
    ``trace`` and ``results`` are :func:`draw_mesh`'s; each :class:`DrawResult` is named
    "OBJECT (wireframe)".
    """
    for obj in scene.drawn_objects(camera):
        first = len(results) if results is not None else 0
        draw_mesh(fb, obj.mesh.without_lines_and_points(), camera, "unlit", model=obj.model,
                  uniforms={"color": scene.wireframe_color}, cull=obj.cull or scene.cull,
                  sample_shading=scene.sample_shading, trace=trace, results=results, **WIREFRAME_STATE)
        for r in (results or [])[first:]:
            r.name = f"{obj.name} (wireframe)"


# ---------------------------------------------------------------------------- softpipe render / turntable in Python


def _size_value(name: str, v) -> Optional[int]:
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise TypeError(f"{name} must be a whole number of pixels, got {type(v).__name__} {v!r}")
    if not 1 <= v <= MAX_DIMENSION:
        raise ValueError(f"{name} must be 1 to {MAX_DIMENSION} pixels (MAX_DIMENSION), got {v}")
    return int(v)


def _angle_value(name: str, v, low: Optional[float] = None, high: Optional[float] = None) -> Optional[float]:
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite angle in degrees, got {v!r}")
    if low is not None and high is not None and not low < v < high:
        raise ValueError(f"{name} must be in ({low:g}, {high:g}) degrees, got {v!r}")
    return float(v)


def input_kind(model) -> str:
    """``".obj"``, ``".toml"``, or a suffix of :data:`softpipe.scenes.formats.FORMATS` (``".ply"``,
    ``".stl"``, ``".gltf"``, ``".glb"``): what a model name or path given to :func:`render` is.

    A bundled model's name is its OBJ file. Raises one line naming the input: an
    unknown bare name (ValueError listing the models), a missing file
    (FileNotFoundError), a folder, or another extension (ValueError).
    """
    from softpipe.scenes.models import model_path
    path = os.fspath(model_path(model))  # a bare word that is neither a model nor a file: ValueError
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path}: is a directory, not a model or scene file")
    kind = Path(path).suffix.lower()
    if kind not in (".obj", ".toml") and kind not in FORMATS:
        raise ValueError(f"{path}: expected a .obj model or a .toml scene file (or a {', '.join(FORMATS)} model, "
                         "read through trimesh)")
    return kind


def _load_input(model, default_size, width, height, texture, azimuth, elevation, fovy,
                allow_outside: bool = False, srgb_textures: bool = False) -> Tuple[Scene, bool]:
    """The Scene for a model name, an OBJ, PLY, STL, glTF or TOML path, a mesh or a Scene; and whether it is one
    model."""
    size = {"width": width or default_size[0], "height": height or default_size[1]}
    angles = {"azimuth": 30.0 if azimuth is None else azimuth, "elevation": 20.0 if elevation is None else elevation,
              "fovy": 35.0 if fovy is None else fovy}
    if isinstance(model, Scene) or not isinstance(model, (str, os.PathLike)):
        if not isinstance(model, Scene):
            mesh = as_mesh(model)
            return Scene.from_model(mesh, texture=texture, srgb_textures=srgb_textures, allow_outside=allow_outside,
                                    **angles, **size), True
        scene = model
    else:
        from softpipe.scenes.models import model_path
        kind, path = input_kind(model), os.fspath(model_path(model))
        if kind == ".obj" or kind in FORMATS:   # a model: its suffix read by models.load_model, the one dispatch
            return Scene.from_model(model, texture=texture, srgb_textures=srgb_textures, allow_outside=allow_outside,
                                    **angles, **size, path=os.fspath(model)), True
        from softpipe.scenes.scenefile import load_scene  # the one place drawing reads a scene file: render()'s input
        scene = load_scene(path, allow_outside=allow_outside)
    # a scene (file or object): its own settings, changed only by what is given
    if texture is not None:
        raise ValueError(f"{scene.path}: texture= applies to one model; in a scene give the material a "
                         "diffuse_texture")
    changes: Dict[str, Any] = {}
    if width or height:
        changes.update(width=width or scene.width, height=height or scene.height)
    if (azimuth is not None or elevation is not None) and scene.camera is not None:
        raise ValueError(f"{scene.path}: azimuth/elevation apply to a framed camera, and this scene's "
                         "[camera] gives an eye")
    if fovy is not None:
        if scene.camera is not None:
            changes["camera"] = scene.camera.replace(fovy=fovy)
        else:
            changes["frame"] = dataclasses.replace(scene.frame, fovy=fovy)
    if scene.camera is None and (azimuth is not None or elevation is not None):
        f = changes.get("frame", scene.frame)
        changes["frame"] = dataclasses.replace(f, azimuth=f.azimuth if azimuth is None else azimuth,
                                               elevation=f.elevation if elevation is None else elevation)
    return scene.replace(**changes), False


def prepare_scene(model, *, width: Optional[int] = None, height: Optional[int] = None,
                  program: Union[str, Program, Callable, None] = None, texture=None, background=None, samples: Optional[str] = None,
                  msaa: bool = False, cull: Optional[str] = None, wireframe: bool = False, wire_color=None,
                  azimuth: Optional[float] = None, elevation: Optional[float] = None, fovy: Optional[float] = None,
                  default_size: Tuple[int, int] = RENDER_SIZE, allow_outside: bool = False,
                  shadows: bool = False, point_size: Optional[float] = None,
                  line_width: Optional[float] = None, srgb: bool = False) -> Scene:
    """The :class:`~softpipe.scenes.scene.Scene` that :func:`render` draws (the options of ``softpipe render``).

    Takes the arguments of :func:`render` (which see) and ``default_size``, the size
    of a model's picture when ``width``/``height`` are not given (a scene keeps its
    own). The scene given is not changed: a new one is returned.
    """
    from softpipe.programs import PROGRAMS

    width, height = _size_value("width", width), _size_value("height", height)
    azimuth, elevation = _angle_value("azimuth", azimuth), _angle_value("elevation", elevation)
    fovy = _angle_value("fovy", fovy, 0.0, 180.0)
    if isinstance(program, str) and program not in PROGRAMS and ":" not in program:
        raise ValueError(f"program: unknown program {program!r}; registered programs: {', '.join(sorted(PROGRAMS))}")
    if program is not None and not (isinstance(program, str) and program in PROGRAMS):
        try:        # a Program, a shader function, "module:function": the Program itself
            program = get_program(program)
        except ValueError as e:
            raise ValueError(f"program: {e}") from None
    if cull is not None and cull not in CULL_MODES:
        raise ValueError(f"cull must be one of {', '.join(CULL_MODES)}, got {cull!r}")
    if samples is not None:
        pattern_named(samples)      # an unknown pattern: its ValueError, before the model is read
    changes: Dict[str, Any] = {}
    for name, size in (("point_size", point_size), ("line_width", line_width)):
        if size is not None:        # a bad size: its ValueError, before the model is read
            changes[name] = check_size(name, size)
    if isinstance(texture, (str, os.PathLike)) and not os.path.isfile(texture):
        raise FileNotFoundError(f"texture: {os.fspath(texture)}: no such file")
    if not isinstance(srgb, (bool, np.bool_)):
        raise TypeError(f"srgb must be True or False, got {type(srgb).__name__} {srgb!r}")
    if background is not None:
        try:
            changes["background"] = rgba(background)
        except (TypeError, ValueError) as e:
            raise ValueError(f"background: {e}") from None
    if wire_color is not None:
        try:
            changes["wireframe_color"] = parse_color(wire_color)[:3]
        except (TypeError, ValueError) as e:
            raise ValueError(f"wire_color: {e}") from None
    scene, one_model = _load_input(model, default_size, width, height, texture, azimuth, elevation, fovy,
                                   allow_outside, srgb_textures=bool(srgb))
    samples = samples or ("rgss4" if msaa and scene.samples in ("1", "center", "none") else None)
    if samples:
        changes["samples"] = samples
    if msaa:
        changes["sample_shading"] = "center"
    objects = scene.objects
    if program is not None:
        changes["program"] = program
        objects = [dataclasses.replace(o, program=None) for o in objects]
    if cull is not None:
        changes["cull"] = cull
        objects = [dataclasses.replace(o, cull=None) for o in objects]
    if wireframe:
        changes["wireframe"] = True
    if srgb:
        changes["srgb"] = True
    if shadows:
        changes["shadows"] = True
        if one_model:   # a model alone has nothing to throw its shadow on: stand it on a floor
            changes["ground"] = True
    scene = scene.replace(objects=list(objects), **changes)
    count = len(pattern_named(scene.samples))
    if max(scene.width, scene.height) > MAX_DIMENSION:
        raise ValueError(f"image size {scene.width}×{scene.height}: a side may be at most {MAX_DIMENSION} pixels "
                         "(MAX_DIMENSION)")
    if scene.width * scene.height * count > MAX_TOTAL_SAMPLES:
        raise ValueError(f"image size {scene.width}×{scene.height} × {count} samples exceeds the limit "
                         f"MAX_TOTAL_SAMPLES = {MAX_TOTAL_SAMPLES}")
    for obj in scene.objects:
        if program_for(obj, scene.program) == "textured" and obj.mesh.uvs is None:
            what = "the model" if one_model else f"mesh {obj.name!r}"
            raise ValueError(f"{scene.path}: {what} has no texture coordinates (vt), so program 'textured' "
                             "cannot draw it")
    return scene


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "draw"


@overload
def render(model, *, width: Optional[int] = None, height: Optional[int] = None,
           program: Union[str, Program, Callable, None] = None, texture=None, background=None, samples: Optional[str] = None, msaa: bool = False,
           cull: Optional[str] = None, wireframe: bool = False, wire_color=None, azimuth: Optional[float] = None,
           elevation: Optional[float] = None, fovy: Optional[float] = None, camera: Optional[Camera] = None,
           stages=None, trace: bool = False, results: Optional[list] = None,
           progress: Optional[Callable[[int, int, SceneObject], None]] = None,
           allow_outside: bool = False, shadows: bool = False, point_size: Optional[float] = None,
           line_width: Optional[float] = None, srgb: bool = False,
           outputs: None = None) -> Framebuffer: ...


@overload
def render(model, *, width: Optional[int] = None, height: Optional[int] = None,
           program: Union[str, Program, Callable, None] = None, texture=None, background=None, samples: Optional[str] = None, msaa: bool = False,
           cull: Optional[str] = None, wireframe: bool = False, wire_color=None, azimuth: Optional[float] = None,
           elevation: Optional[float] = None, fovy: Optional[float] = None, camera: Optional[Camera] = None,
           stages=None, trace: bool = False, results: Optional[list] = None,
           progress: Optional[Callable[[int, int, SceneObject], None]] = None,
           allow_outside: bool = False, shadows: bool = False, point_size: Optional[float] = None,
           line_width: Optional[float] = None, srgb: bool = False,
           outputs: Sequence[str]) -> RenderOutputs: ...


def render(model, *, width: Optional[int] = None, height: Optional[int] = None,
           program: Union[str, Program, Callable, None] = None, texture=None, background=None, samples: Optional[str] = None, msaa: bool = False,
           cull: Optional[str] = None, wireframe: bool = False, wire_color=None, azimuth: Optional[float] = None,
           elevation: Optional[float] = None, fovy: Optional[float] = None, camera: Optional[Camera] = None,
           stages=None, trace: bool = False, results: Optional[list] = None,
           progress: Optional[Callable[[int, int, SceneObject], None]] = None,
           allow_outside: bool = False, shadows: bool = False, point_size: Optional[float] = None,
           line_width: Optional[float] = None, srgb: bool = False,
           outputs: Optional[Sequence[str]] = None) -> Union[Framebuffer, RenderOutputs]:
    """``softpipe render MODEL`` in Python: the same picture, as a :class:`Framebuffer`.

    ``softpipe.render("teapot").save("teapot.png")`` writes what ``softpipe render
    teapot -o teapot.png`` writes, byte for byte (the command line calls this).

    Parameters
    ----------
    model : str, path-like, Mesh, trimesh-like or Scene
        A bundled model's name (``"teapot"``, see :mod:`softpipe.scenes.models`), an OBJ file,
        a PLY, STL or glTF 2.0 file (read through trimesh, :mod:`softpipe.scenes.formats`),
        a TOML scene file (:mod:`softpipe.scenes.scenefile`), a :class:`~softpipe.scenes.mesh.Mesh` or
        anything with ``.vertices`` and ``.faces``, or a :class:`~softpipe.scenes.scene.Scene`.
        A model is framed by the camera (azimuth 30°, elevation 20°, field of view 35°)
        under the studio lights (:func:`softpipe.scenes.scene.studio_lights`) with the default
        program (``textured`` for a textured model, else ``phong``); a scene keeps its
        own settings except the ones given here.
    width, height : int, optional
        Pixels; 640×480 for a model, the scene's size for a scene.
    program : str, Program or function, optional
        A registered program (``softpipe programs``), a :class:`~softpipe.programs.Program`, a
        fragment shader function (drawn with ``standard_vertex``) or ``"module:function"``
        (:func:`~softpipe.programs.get_program`); for a scene, every object's.
    texture : str, path-like or Texture2D, optional
        A diffuse texture for a model with texture coordinates.
    background, wire_color : color, optional
        Anything :func:`softpipe.core.colors.parse_color` reads: ``"white"``, ``"#202830"``,
        ``(0.1, 0.1, 0.12)``. The default background is (0.08, 0.09, 0.12).
    samples : str, optional
        A sample pattern's name (``"rgss4"``, ``"grid16"``, …); ``msaa=True`` shades once
        per pixel and triangle (with ``rgss4`` unless ``samples`` is given).
    cull : "back", "front" or "none", optional
    wireframe : bool
        Draw the visible triangle edges over the picture.
    azimuth, elevation, fovy : float, optional
        The framed camera's angles and field of view, in degrees.
    camera : Camera, optional
        Instead of the scene's (or the framed) camera.
    stages : str or path-like, optional
        Also write every draw's stage pictures and a contact sheet into this folder
        (a subfolder per draw when there are several); their paths are in each
        :class:`DrawResult`'s ``pictures``.
    trace : bool
        Keep every draw's Trace (in ``results``).
    results : list, optional
        Receives one :class:`DrawResult` per draw.
    progress : callable, optional
        ``progress(k, n, object)`` before draw k of n.
    allow_outside : bool
        Let the OBJ or scene file name files outside its own folder (``mtllib``,
        ``map_Kd``, meshes, textures; :func:`softpipe.core.files.resolve_inside`), for files
        you trust (``--allow-outside-paths``). FIFOs and devices stay refused.
    shadows : bool
        Every light casts shadows (shadow maps, :mod:`softpipe.scenes.shadow_pass`); a model alone
        is stood on a floor that receives them (``--shadows``).
    point_size, line_width : float, optional
        Pixels: the size of the model's points and the width of its lines (an OBJ's ``p``
        and ``l``; ``--point-size``, ``--line-width``); GL's default 1 for both (a scene
        keeps its own). They are drawn after the faces, unlit in their material's ``kd``
        (:func:`draw_lines_and_points`).
    srgb : bool
        Render into an sRGB framebuffer (``--srgb``; FORMULAS §28, docs/gamma.md): shaded in
        linear light and encoded as the picture becomes bytes. A model's texture files (the
        ``texture`` path, its MTL's ``map_Kd``) are then read as sRGB too (decoded to linear
        when loaded); a scene file says that of its textures itself (``[render]
        srgb_textures``), and a scene's ``srgb = true`` is kept when this is False.
    outputs : sequence of str, optional
        Buffers beside the picture (``--outputs``), any of
        :data:`softpipe.scenes.outputs.OUTPUTS`: ``"color"``, ``"depth"``, ``"linear_depth"``,
        ``"position"``, ``"normal"``, ``"object_id"``, ``"triangle_id"``, ``"barycentrics"``,
        ``"uv"``, ``"albedo"`` (docs/outputs.md: each one's space, units and background).
        Given, ``render`` returns a :class:`~softpipe.scenes.outputs.RenderOutputs`: the
        buffers by name and ``.framebuffer``, the picture it returns without them.

    Raises
    ------
    ValueError, OSError
        One line naming what was wrong: an unknown model or program, a missing file, a
        bad option, ``program="textured"`` for a model without texture coordinates, …
    """
    names = None if outputs is None else check_outputs(outputs)
    scene = prepare_scene(model, width=width, height=height, program=program, texture=texture,
                          background=background, samples=samples, msaa=msaa, cull=cull, wireframe=wireframe,
                          wire_color=wire_color, azimuth=azimuth, elevation=elevation, fovy=fovy,
                          allow_outside=allow_outside, shadows=shadows, point_size=point_size,
                          line_width=line_width, srgb=srgb)
    camera = camera or scene.view_camera()
    drawn: List[DrawResult] = []
    fb = render_scene(scene, camera=camera, trace=trace or stages is not None, results=drawn, progress=progress,
                      wireframe=False,
                      record=names is not None and any(n != "color" for n in names))   # (the color is the fb's)
    if stages is not None:   # before the wireframe: the "final" picture is the framebuffer as drawn
        folder = Path(stages)
        for k, r in enumerate(drawn):
            r.pictures = r.trace.save_pictures(folder if len(drawn) == 1 else
                                               folder / f"{k + 1:02d}-{_safe_name(r.name)}")
    if scene.wireframe:
        draw_wireframe(fb, scene, camera)
    if results is not None:
        results.extend(drawn)
    if names is not None:
        # fb is this call's own and drawn into no more: its color is handed out, not copied
        return RenderOutputs(fb, derive_outputs(fb, names, scene.drawn_objects(camera), copy_color=False))
    return fb


def _orbit(camera: Camera, degrees: float) -> Camera:
    """The camera with its eye turned about the vertical axis through its target."""
    from softpipe.pipeline.transforms import rotate_y
    eye, target = np.asarray(camera.eye), np.asarray(camera.target)
    offset = (rotate_y(degrees) @ np.append(eye - target, 0.0))[:3]
    return camera.replace(eye=tuple(target + offset))


def animation_format(path) -> str:
    """``"GIF"`` for a .gif, ``"PNG"`` (animated PNG) for a .png; a ValueError names any other extension."""
    ext = Path(os.fspath(path)).suffix.lower()
    if ext not in (".gif", ".png"):
        raise ValueError(f"{os.fspath(path)}: an animation is written as .gif or .png (animated PNG), not "
                         f"{ext or 'no extension'!r}")
    return "GIF" if ext == ".gif" else "PNG"


def gif_frame(image):
    """One RGB frame as a GIF holds it: 256 colors chosen for this frame, Floyd–Steinberg dithered.

    The palette is the frame's own (median cut), and every pixel's rounding error is
    spread over its neighbours, so a smooth shading gradient comes out as a fine
    grain of palette colors instead of flat bands.
    """
    from PIL import Image
    palette = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    return image.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG)


def turntable(model, path, *, frames: int = 36, fps: float = 15.0, width: Optional[int] = None,
              height: Optional[int] = None, program: Union[str, Program, Callable, None] = None, texture=None,
              background=None, samples: Optional[str] = None, msaa: bool = False, cull: Optional[str] = None,
              wireframe: bool = False, wire_color=None, azimuth: Optional[float] = None,
              elevation: Optional[float] = None, fovy: Optional[float] = None,
              progress: Optional[Callable[[int, int], None]] = None, allow_outside: bool = False,
              format: Optional[str] = None, shadows: bool = False, point_size: Optional[float] = None,
              line_width: Optional[float] = None) -> Path:
    """``softpipe turntable MODEL`` in Python: the camera circling the model, written as an animation.

    ``softpipe.turntable("suzanne", "spin.gif", frames=36)`` writes what ``softpipe
    turntable suzanne -o spin.gif --frames 36`` writes, byte for byte (the command line
    calls this).

    Parameters
    ----------
    model
        As :func:`render` takes it (a scene with its own camera turns that eye about its target).
    path : str, path-like or binary file object
        A ``.gif`` (256 colors per frame, dithered: :func:`gif_frame`) or a ``.png``
        (an animated PNG, every color kept). Its folder is made and checked before any
        frame is drawn, and the file is written whole or not at all
        (:func:`softpipe.core.files.atomic_write`). A file object opened for writing bytes
        gets a GIF, or an animated PNG with ``format="png"``.
    frames : int
        Frames in one turn about the vertical axis (1 to :data:`MAX_FRAMES`).
    fps : float
        Frames per second when played (0.1 to 100; GIF stores hundredths of a second).
    width, height
        320×240 for a model by default; the other options are :func:`render`'s.
    progress : callable, optional
        ``progress(i, frames)`` after frame i (from 1) is drawn.
    allow_outside, shadows : bool
        As :func:`render` takes them.
    point_size, line_width : float, optional
        As :func:`render` takes them.

    Returns
    -------
    Path or the file object
        Where it was written.
    """
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not 1 <= frames <= MAX_FRAMES:
        raise ValueError(f"frames must be a whole number from 1 to {MAX_FRAMES}, got {frames!r}")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0.1 <= fps <= 100.0:
        raise ValueError(f"fps must be in 0.1..100 frames per second, got {fps!r}")
    is_path = isinstance(path, (str, os.PathLike))
    if not is_path and not callable(getattr(path, "write", None)):
        raise TypeError(f"turntable() takes a path or a binary file object, got {type(path).__name__}")
    fmt = animation_format(path if is_path else "animation." + (format or "gif").lower().lstrip("."))
    if is_path:                  # a bad folder is said before the frames are drawn, not after
        from softpipe.core.files import check_writable
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        check_writable(out)
    scene = prepare_scene(model, width=width, height=height, program=program, texture=texture,
                          background=background, samples=samples, msaa=msaa, cull=cull, wireframe=wireframe,
                          wire_color=wire_color, azimuth=azimuth, elevation=elevation, fovy=fovy,
                          default_size=TURNTABLE_SIZE, allow_outside=allow_outside, shadows=shadows,
                          point_size=point_size, line_width=line_width)
    base = scene.view_camera()
    first = scene.frame.azimuth
    images = []
    for i in range(int(frames)):
        turn = 360.0 * i / frames
        camera = _orbit(base, turn) if scene.camera is not None else scene.view_camera(azimuth=first + turn)
        images.append(render_scene(scene, camera=camera).to_image())
        if progress is not None:
            progress(i + 1, int(frames))
    duration = frame_duration(fps)
    pictures = [gif_frame(im) for im in images] if fmt == "GIF" else images

    def write(f) -> None:
        pictures[0].save(f, format=fmt, save_all=True, append_images=pictures[1:], duration=duration, loop=0)

    if not is_path:
        write(path)
        return path
    from softpipe.core.files import atomic_write
    atomic_write(out, write)     # whole or not at all: Ctrl-C or a full disk leaves the previous file
    return out


def frame_duration(fps: float) -> int:
    """Milliseconds per frame at ``fps``, in whole hundredths of a second (what a GIF stores)."""
    return max(int(round(100.0 / fps)), 1) * 10
