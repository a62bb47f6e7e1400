"""softpipe: the graphics pipeline of a GPU, on the CPU, in Python.

Stages (one module each): :mod:`~softpipe.transforms` → :mod:`~softpipe.vertex`
→ :mod:`~softpipe.assembly` → :mod:`~softpipe.raster` →
:mod:`~softpipe.fragment` → :mod:`~softpipe.output`, wired by
:mod:`~softpipe.pipeline`. Shaders are Python functions (:mod:`~softpipe.shader`,
:mod:`~softpipe.glsl`, :mod:`~softpipe.lighting`); built-in programs live in
:mod:`softpipe.shaders`.
"""
from . import _runtime  # noqa: F401  (first: process settings, see its docstring)
from . import glsl, lighting, shading, shapes
from .assembly import Primitives, assemble
from .camera import Camera
from .colors import parse_color
from .fragment import ShadedFragments
from .framebuffer import Framebuffer
from .material import Light, Lighting, LightingUniform, Material, MaterialUniform, pack_lights
from .mesh import Mesh
from .mesh import concatenate as concatenate_meshes
from .models import load_model, model_path
from .obj import OBJError, load_obj, parse_obj
from .output import MergeResult, MergeState
from .pipeline import DrawCall, Stage, draw
from .raster import Fragments, rasterize
from .sampling import CENTER, SamplePattern, grid, jittered, random_pattern, rotated_grid_4x
from .drawing import draw_mesh, render, render_scene, standard_uniforms, turntable
from .scene import Scene
from .shader import DISCARD, FragInfo, ShaderError, make_uniforms
from .shadowmap import ShadowSettings, ShadowUniform
from .shadows import ShadowMaps, render_shadow_maps
from .texture import Texture2D, TextureUniform
from .trace import PixelHistory, Trace
from .transforms import (Viewport, compose, frustum, identity, look_at, normal_matrix, opencv_camera,
                         orthographic, perspective, rotate, rotate_x, rotate_y, rotate_z, scale, translate)
from .shaders.common import standard_vertex
from .vertex import VertexOut, run_vertex_stage

__version__ = "0.1.0"


def __getattr__(name: str):
    """``softpipe.batch`` on first use: it renders a job (``softpipe.batch(job, out_dir)``, the module is
    callable) and is not imported with softpipe, which does not need it to draw."""
    if name == "batch":
        import importlib
        return importlib.import_module(".batch", __name__)
    raise AttributeError(f"module 'softpipe' has no attribute {name!r}")
