"""softpipe: the graphics pipeline of a GPU, on the CPU, in Python.

Stages (one module each): :mod:`~softpipe.transforms` → :mod:`~softpipe.vertex`
→ :mod:`~softpipe.assembly` → :mod:`~softpipe.raster` →
:mod:`~softpipe.fragment` → :mod:`~softpipe.output`, wired by
:mod:`~softpipe.pipeline`.
"""
from .assembly import Primitives, assemble
from .fragment import ShadedFragments
from .framebuffer import Framebuffer
from .material import Material
from .output import MergeState
from .pipeline import draw
from .raster import Fragments, rasterize
from .sampling import CENTER, SamplePattern
from .shader import DISCARD, FragInfo, ShaderError, make_uniforms
from .transforms import (Viewport, compose, frustum, identity, look_at, normal_matrix, orthographic,
                         perspective, rotate, rotate_x, rotate_y, rotate_z, scale, translate)
from .vertex import VertexOut, standard_vertex

__version__ = "0.1.0"
