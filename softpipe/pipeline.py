"""The pipeline: wires the stages together, and nothing else.

    vertex → assembly → raster → fragment → output
    (vertex.py, assembly.py, raster.py, fragment.py, output.py)

:func:`draw` is the entry point. Triangles are rasterized, shaded and merged in
batches of whole triangles holding at most :data:`MAX_FRAGMENTS_PER_BATCH`
fragments (one triangle larger than that is a batch of its own), so memory stays
bounded however much a draw covers; batches go in primitive order, so the
result is the same as one batch.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, Optional, Tuple, Union

import numpy as np

from .assembly import assemble
from .fragment import run_fragment_stage
from .framebuffer import Framebuffer
from .output import MergeState, merge
from .raster import count_fragments, rasterize
from .shader import make_uniforms
from .transforms import Viewport
from .vertex import run_vertex_stage

__all__ = ["draw", "MAX_FRAGMENTS_PER_BATCH"]

MAX_FRAGMENTS_PER_BATCH = 1 << 22


def _batches(counts: np.ndarray, limit: int):
    """Split triangles into consecutive runs of at most ``limit`` fragments (at least one triangle)."""
    first, total = 0, 0
    for t, c in enumerate(counts):
        if total and total + c > limit:
            yield first, t
            first, total = t, 0
        total += int(c)
    if first < len(counts):
        yield first, len(counts)


def draw(framebuffer: Framebuffer, positions, indices=None, varyings: Optional[Mapping[str, Any]] = None,
         vertex_shader: Optional[Callable] = None, fragment_shader: Optional[Callable] = None,
         uniforms: Optional[Mapping[str, Any]] = None, *, attributes: Optional[Mapping[str, Any]] = None,
         topology: str = "triangles", interpolation: Optional[Mapping[str, str]] = None,
         depth_test: Optional[str] = "less", depth_write: bool = True,
         blend: Union[None, str, Tuple[str, str]] = None, cull: str = "none", front_face: str = "ccw",
         viewport: Optional[Viewport] = None) -> None:
    """Draw triangles into ``framebuffer``.

    Parameters
    ----------
    framebuffer : Framebuffer
    positions : array [N, 4]
        Clip coordinates when there is no vertex shader; otherwise the vertex
        shader's ``position`` attribute ([N, 2|3|4]).
    indices : int array [M] or [M, 3], optional
        Vertex indices; without them vertices are taken in order.
    varyings : dict name → [N] or [N, k] array, optional
        Per-vertex values to interpolate (no vertex shader).
    vertex_shader, fragment_shader : functions, optional
        See :mod:`softpipe.shader`. Without a fragment shader the color is the
        interpolated varying ``color``.
    uniforms : dict, optional
        Values every shader invocation sees (:func:`softpipe.shader.make_uniforms`).
    attributes : dict name → [N, k] array, optional
        Extra vertex-shader inputs.
    topology : "triangles" | "triangle_strip" | "triangle_fan"
    interpolation : dict varying name → "smooth" | "noperspective" | "flat"
    depth_test : compare function (see :data:`softpipe.output.DEPTH_FUNCS`) or None
    depth_write : bool
    blend : None, "alpha", "additive" or (src_factor, dst_factor)
    cull : "none" | "back" | "front"
    front_face : "ccw" | "cw"
    viewport : Viewport, optional; the whole framebuffer by default
    """
    if not isinstance(framebuffer, Framebuffer):
        raise TypeError(f"framebuffer must be a softpipe.Framebuffer, got {type(framebuffer).__name__}")
    state = MergeState(depth_test=depth_test, depth_write=depth_write, blend=blend)
    viewport = viewport or Viewport(0, 0, framebuffer.width, framebuffer.height)
    if not isinstance(viewport, Viewport):
        raise TypeError(f"viewport must be a softpipe.Viewport, got {type(viewport).__name__}")
    u = make_uniforms(uniforms)

    vout = run_vertex_stage(positions, varyings, vertex_shader, u, attributes)
    vout.layout = vout.layout.with_qualifiers(interpolation)
    prims = assemble(vout, topology, indices, viewport=viewport, cull=cull, front_face=front_face)

    w, h, pattern = framebuffer.width, framebuffer.height, framebuffer.pattern
    counts = count_fragments(prims, w, h, pattern)
    for first, last in _batches(counts, MAX_FRAGMENTS_PER_BATCH):
        frags = rasterize(prims, w, h, pattern, first, last, counts)
        shaded = run_fragment_stage(frags, prims, fragment_shader, u, pattern, h)
        merge(frags, shaded, state, framebuffer)
