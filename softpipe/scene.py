"""Drawing meshes with a camera and a built-in program: the glue above :func:`softpipe.draw`.

:func:`standard_uniforms` builds the uniforms every built-in program reads
(``model_view``, ``projection``, ``normal_matrix``); :func:`draw_mesh` draws a
:class:`~softpipe.mesh.Mesh` with them.
"""
from __future__ import annotations

from typing import Any, Dict, Mapping, Optional

import numpy as np

from .camera import Camera
from .framebuffer import Framebuffer
from .pipeline import draw
from .shaders import Program, get_program
from .transforms import compose, normal_matrix

__all__ = ["standard_uniforms", "draw_mesh"]


def standard_uniforms(camera: Camera, aspect: float, model: Optional[np.ndarray] = None) -> Dict[str, Any]:
    """``model_view``, ``projection``, ``normal_matrix`` and ``view`` for a camera and model matrix."""
    model = np.eye(4) if model is None else np.asarray(model, dtype=np.float64)
    if model.shape != (4, 4):
        raise ValueError(f"model must be a 4×4 matrix, got shape {model.shape}")
    view = camera.view
    model_view = compose(view, model)
    return {"model_view": model_view, "projection": camera.projection(aspect),
            "normal_matrix": normal_matrix(model_view), "view": view}


def draw_mesh(framebuffer: Framebuffer, mesh, camera: Camera, program="phong", *,
              model: Optional[np.ndarray] = None, lighting=None, uniforms: Optional[Mapping[str, Any]] = None,
              cull: str = "back", **state):
    """Draw ``mesh`` seen by ``camera`` with a built-in ``program`` (a name or a Program).

    The mesh's normals are used when it has them, else computed (area-weighted);
    a faceted program (``flat``) gets the mesh with one normal per face. A
    mesh with several materials is drawn once per material. ``lighting`` (a
    Lighting, a Light, a list of Lights, or None for the default lights) is
    given to every program as the uniform ``lighting``, in eye space.
    ``uniforms`` are added to the standard ones (and override them); ``state``
    is passed on to :func:`softpipe.draw` (``depth_test``, ``blend``, ``trace``, …), whose
    result (a Trace with ``trace=True``) is returned.
    """
    prog = get_program(program)
    if getattr(mesh, "materials", ()) and len(mesh.materials) > 1:
        result = None
        for _, part in mesh.by_material():
            result = draw_mesh(framebuffer, part, camera, prog, model=model, lighting=lighting, uniforms=uniforms,
                               cull=cull, **state)
        return result
    if prog.faceted:
        mesh = mesh.flat_shaded()
    from .shaders.common import lighting_uniform
    u = standard_uniforms(camera, framebuffer.width / framebuffer.height, model)
    u["material"] = mesh.material
    u["color"] = mesh.material.kd
    u["lighting"] = lighting_uniform(lighting, u["view"])
    u.update(uniforms or {})
    normals = mesh.normals if mesh.normals is not None else mesh.vertex_normals()
    attributes = {"normal": normals}
    if mesh.uvs is not None:
        attributes["uv"] = mesh.uvs
    interpolation = dict(prog.interpolation)
    return draw(framebuffer, mesh.positions, mesh.indices, vertex_shader=prog.vertex, fragment_shader=prog.fragment,
         uniforms=u, attributes=attributes, interpolation=interpolation or None, cull=cull, **state)
