"""softpipe: the graphics pipeline of a GPU, on the CPU, in Python.

Stages (one module each): :mod:`~softpipe.pipeline.transforms` → :mod:`~softpipe.pipeline.vertex`
→ :mod:`~softpipe.pipeline.assembly` → :mod:`~softpipe.pipeline.raster` →
:mod:`~softpipe.pipeline.fragment` → :mod:`~softpipe.pipeline.output`, wired by
:mod:`~softpipe.pipeline.draw`. Shaders are Python functions (:mod:`~softpipe.language.contract`,
:mod:`~softpipe.language.glsl`, :mod:`~softpipe.light.lighting`); built-in programs live in
:mod:`softpipe.programs`.
"""
from softpipe import shading
from softpipe.language import glsl
from softpipe.light import lighting
from softpipe.scenes import shapes
from softpipe.pipeline.assembly import Primitives, assemble
from softpipe.pipeline.camera import Camera
from softpipe.core.colors import parse_color
from softpipe.core.runtime import keep_freed_memory
from softpipe.pipeline.fragment import ShadedFragments
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.light.material import Light, Lighting, LightingUniform, Material, MaterialUniform, pack_lights
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.mesh import concatenate as concatenate_meshes
from softpipe.scenes.models import load_model, model_path
from softpipe.scenes.obj import OBJError, load_obj, parse_obj
from softpipe.pipeline.output import MergeResult, MergeState
from softpipe.pipeline.draw import DrawCall, Stage, draw
from softpipe.pipeline.raster import Fragments, rasterize
from softpipe.pipeline.sampling import CENTER, SamplePattern, grid, jittered, random_pattern, rotated_grid_4x
from softpipe.scenes.drawing import draw_mesh, render, render_scene, standard_uniforms, turntable
from softpipe.scenes.scene import Scene
from softpipe.language.contract import DISCARD, FragInfo, ShaderError, make_uniforms
from softpipe.light.shadowmap import ShadowSettings, ShadowUniform
from softpipe.scenes.shadow_pass import ShadowMaps, render_shadow_maps
from softpipe.light.texture import Texture2D, TextureUniform
from softpipe.pipeline.trace import PixelHistory, Trace
from softpipe.pipeline.transforms import (Viewport, compose, frustum, identity, look_at, normal_matrix, opencv_camera,
                         orthographic, perspective, rotate, rotate_x, rotate_y, rotate_z, scale, translate)
from softpipe.programs.common import standard_vertex
from softpipe.pipeline.vertex import VertexOut, run_vertex_stage

__version__ = "0.1.0"


def __getattr__(name: str):
    """``softpipe.tools.batch`` on first use: it renders a job (``softpipe.batch(job, out_dir)``, the module is
    callable) and is not imported with softpipe, which does not need it to draw."""
    if name == "batch":
        from softpipe.tools import batch
        return batch
    raise AttributeError(f"module 'softpipe' has no attribute {name!r}")
