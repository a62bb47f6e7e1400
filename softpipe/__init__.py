"""softpipe: the graphics pipeline of a GPU, on the CPU, in Python.

``import softpipe as sp`` is the API: the stages' entry points and data types
(softpipe/pipeline/: transforms → vertex → assembly → setup and raster →
fragment → output, wired by :func:`draw`), scenes and meshes (softpipe/scenes/),
materials and lights (softpipe/light/). A shader author imports from
:mod:`softpipe.shading`; graphics tests use :mod:`softpipe.testing`.
docs/design.md draws the whole house.
"""
from softpipe import shading
from softpipe.core.colors import parse_color
from softpipe.core.runtime import keep_freed_memory
from softpipe.core.version import VERSION
from softpipe.language import glsl
from softpipe.language.contract import DISCARD, FragInfo, ShaderError, make_uniforms
from softpipe.language.kernels.diagnostics import hide_internal_frames
from softpipe.light import lighting
from softpipe.light.material import Light, Lighting, LightingUniform, Material, MaterialUniform, pack_lights
from softpipe.light.shadowmap import ShadowSettings, ShadowUniform
from softpipe.light.texture import Texture2D, TextureUniform
from softpipe.pipeline.assembly import Primitives, assemble
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.draw import DrawCall, Stage, draw
from softpipe.pipeline.fragment import ShadedFragments
from softpipe.pipeline.framebuffer import ATTACHMENT_FORMATS, Framebuffer
from softpipe.pipeline.merge_state import MergeState, Stencil
from softpipe.pipeline.output import MergeResult, NonFiniteColorWarning, OcclusionQuery
from softpipe.pipeline.raster import Fragments, rasterize
from softpipe.pipeline.sampling import CENTER, SamplePattern, grid, jittered, random_pattern, rotated_grid_4x
from softpipe.pipeline.trace import PixelHistory, Trace
from softpipe.pipeline.transforms import (
    Viewport,
    compose,
    frustum,
    identity,
    look_at,
    normal_matrix,
    opencv_camera,
    orthographic,
    perspective,
    rotate,
    rotate_x,
    rotate_y,
    rotate_z,
    scale,
    translate,
)
from softpipe.pipeline.vertex import VertexOut, run_vertex_stage
from softpipe.programs.common import standard_vertex
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh, render, render_scene, standard_uniforms, turntable
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.mesh import concatenate as concatenate_meshes
from softpipe.scenes.models import load_model, model_path
from softpipe.scenes.obj import OBJError, load_obj, parse_obj
from softpipe.scenes.planar_mirror import render_planar_mirror
from softpipe.scenes.scene import Scene
from softpipe.scenes.shadow_pass import ShadowMaps, render_shadow_maps
from softpipe.scenes.shadow_volumes import render_shadow_volumes
from softpipe.scenes.transparency import depth_peel, weighted_oit
from softpipe.tracers.pathtrace import PathTrace, pathtrace

__all__ = [
    "shading", "parse_color", "keep_freed_memory", "glsl", "DISCARD", "FragInfo", "ShaderError", "NonFiniteColorWarning",
    "make_uniforms", "lighting", "Light", "Lighting", "LightingUniform", "Material", "MaterialUniform",
    "pack_lights", "ShadowSettings", "ShadowUniform", "Texture2D", "TextureUniform", "Primitives", "assemble",
    "Camera", "DrawCall", "Stage", "draw", "ShadedFragments", "Framebuffer", "ATTACHMENT_FORMATS", "MergeResult", "MergeState",
    "Stencil", "OcclusionQuery",
    "render_shadow_volumes", "render_planar_mirror", "depth_peel", "weighted_oit",
    "Fragments", "rasterize", "CENTER", "SamplePattern", "grid", "jittered", "random_pattern",
    "rotated_grid_4x", "PixelHistory", "Trace", "Viewport", "compose", "frustum", "identity", "look_at",
    "normal_matrix", "opencv_camera", "orthographic", "perspective", "rotate", "rotate_x", "rotate_y",
    "rotate_z", "scale", "translate", "VertexOut", "run_vertex_stage", "standard_vertex", "shapes",
    "draw_mesh", "render", "render_scene", "standard_uniforms", "turntable", "Mesh", "concatenate_meshes",
    "load_model", "model_path", "OBJError", "load_obj", "parse_obj", "Scene", "ShadowMaps",
    "render_shadow_maps", "PathTrace", "pathtrace", "view", "__version__",
]

__version__ = VERSION


def view(model, **options):
    """Show ``model`` live (``softpipe view MODEL`` in Python): a page served on loopback in a background
    thread, shown in Jupyter as an IFrame; drag to orbit, scroll to zoom, click a pixel for its history.
    Returns the :class:`softpipe.tools.viewer.Viewer` (``.url``, ``.stop()``); the options are
    :func:`softpipe.tools.viewer.view`'s (which see). docs/viewer.md."""
    from softpipe.tools.viewer import view as serve_view  # the tool, on first use (as softpipe.batch)
    return serve_view(model, **options)


def __getattr__(name: str):
    """``softpipe.batch`` on first use: it renders a job (``softpipe.batch(job, out_dir)``, the module is
    callable) and is not imported with softpipe, which does not need it to draw."""
    if name == "batch":
        from softpipe.tools import batch
        return batch
    raise AttributeError(f"module 'softpipe' has no attribute {name!r}")

hide_internal_frames()     # a ShaderError's traceback ends in the user's code (SOFTPIPE_SHADER_DEBUG=1: every frame)
