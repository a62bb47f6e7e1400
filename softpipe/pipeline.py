"""The pipeline: wires the stages together, and nothing else.

    vertex → assembly → raster → fragment → output
    (vertex.py, assembly.py, raster.py, fragment.py, output.py)

:func:`draw` is the entry point. :class:`DrawCall` holds one draw's inputs and
runs it either all at once (:meth:`DrawCall.run`) or one stage at a time
(:meth:`DrawCall.steps`, a generator of :class:`Stage`), which is how a notebook
steps through a draw; ``draw(..., trace=True)`` keeps every stage's output in a
:class:`~softpipe.trace.Trace`.

Triangles are rasterized, shaded and merged in batches of whole triangles
holding at most :data:`MAX_FRAGMENTS_PER_BATCH` fragments (one triangle larger
than that is a batch of its own), so memory stays bounded however much a draw
covers; batches go in primitive order, so the result is the same as one batch.

Set ``SOFTPIPE_DEBUG=vertex,assembly,raster,fragment,output`` (or ``all``) to
print what passes through those stages, as Mesa's per-stage debug switches do.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Mapping, Optional, Tuple, Union

import numpy as np

from .assembly import assemble
from .fragment import run_fragment_stage
from .framebuffer import Framebuffer
from .fragment import default_fragment_shader, shade_visible
from .output import DEPTH_FUNCS, MergeState, merge
from .raster import SHADING_POSITIONS, count_fragments, pixel_rect, rasterize
from .shader import make_uniforms, may_discard
from .transforms import Viewport
from .vertex import run_vertex_stage
from .visibility import visibility_pass

__all__ = ["draw", "DrawCall", "Stage", "MAX_FRAGMENTS_PER_BATCH", "STAGES"]

MAX_FRAGMENTS_PER_BATCH = 1 << 22
#: path="auto" takes the fast path from this many framebuffer samples on
#: (small draws, such as most tests, keep to the reference path and its compile costs).
FAST_PATH_MIN_SAMPLES = 128 * 128
PATHS = ("auto", "reference", "fast")
STAGES = ("vertex", "assembly", "raster", "fragment", "output")


@dataclass
class Stage:
    """One stage's result while stepping through a draw.

    ``name`` is one of :data:`STAGES`; ``output`` is that stage's data type
    (VertexOut, Primitives, Fragments, ShadedFragments, MergeResult); ``batch``
    counts the fragment batches (raster, fragment and output repeat per batch).
    """

    name: str
    output: Any
    batch: int = 0

    def __repr__(self) -> str:
        batch = f", batch {self.batch}" if self.name in ("raster", "fragment", "output") else ""
        return f"Stage({self.name!r}{batch}: {self.output!r})"


def _debug_stages() -> set:
    value = os.environ.get("SOFTPIPE_DEBUG", "")
    names = {s.strip() for s in value.split(",") if s.strip()}
    return set(STAGES) if "all" in names else names


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


class DrawCall:
    """One draw: its inputs, checked, and the stages that run it.

    The parameters are those of :func:`draw`.
    """

    def __init__(self, framebuffer: Framebuffer, positions, indices=None,
                 varyings: Optional[Mapping[str, Any]] = None, vertex_shader: Optional[Callable] = None,
                 fragment_shader: Optional[Callable] = None, uniforms: Optional[Mapping[str, Any]] = None, *,
                 attributes: Optional[Mapping[str, Any]] = None, topology: str = "triangles",
                 interpolation: Optional[Mapping[str, str]] = None, depth_test: Optional[str] = "less",
                 depth_write: bool = True, blend: Union[None, str, Tuple[str, str]] = None, cull: str = "none",
                 front_face: str = "ccw", viewport: Optional[Viewport] = None, sample_shading: str = "sample",
                 path: str = "auto"):
        if not isinstance(framebuffer, Framebuffer):
            raise TypeError(f"framebuffer must be a softpipe.Framebuffer, got {type(framebuffer).__name__}")
        viewport = viewport or Viewport(0, 0, framebuffer.width, framebuffer.height)
        if not isinstance(viewport, Viewport):
            raise TypeError(f"viewport must be a softpipe.Viewport, got {type(viewport).__name__}")
        self.framebuffer, self.viewport = framebuffer, viewport
        self.positions, self.indices, self.varyings, self.attributes = positions, indices, varyings, attributes
        for name, f in (("vertex_shader", vertex_shader), ("fragment_shader", fragment_shader)):
            if f is not None and not callable(f):
                raise TypeError(f"{name} must be a function, got {type(f).__name__}")
        self.vertex_shader, self.fragment_shader = vertex_shader, fragment_shader
        self.uniforms = make_uniforms(uniforms)
        self.topology, self.interpolation, self.cull, self.front_face = topology, interpolation, cull, front_face
        self.state = MergeState(depth_test=depth_test, depth_write=depth_write, blend=blend)
        if sample_shading not in SHADING_POSITIONS:
            raise ValueError(f"sample_shading must be one of {SHADING_POSITIONS}, got {sample_shading!r}")
        self.sample_shading = sample_shading
        if path not in PATHS:
            raise ValueError(f"path must be one of {PATHS}, got {path!r}")
        self.path = path
        #: seconds spent in each stage by the last run: vertex, assembly, setup, raster, fragment, output
        self.timings: dict = {}
        #: the last run's assembled triangles (what reached the rasterizer), on either path
        self.primitives = None

    def steps(self, record: bool = False) -> Iterator[Stage]:
        """Run the draw one stage at a time, yielding each stage's result as it is made.

        The framebuffer is updated by each "output" stage; a draw stepped to the
        end leaves it exactly as :meth:`run` would. ``record`` keeps each
        fragment's color after merging (for pixel history).
        """
        debug = _debug_stages()
        fb = self.framebuffer
        clock = self._clock()
        vout = self._vertex_stage()
        clock("vertex")
        yield self._emit(Stage("vertex", vout), debug)
        clock(None)
        prims = self.primitives = assemble(vout, self.topology, self.indices, viewport=self.viewport,
                                           cull=self.cull, front_face=self.front_face)
        clock("assembly")
        yield self._emit(Stage("assembly", prims), debug)
        clock(None)
        rect = pixel_rect(fb.width, fb.height, self.viewport)
        counts = count_fragments(prims, fb.width, fb.height, fb.pattern, rect)
        clock("setup")
        for batch, (first, last) in enumerate(_batches(counts, MAX_FRAGMENTS_PER_BATCH)):
            frags = rasterize(prims, fb.width, fb.height, fb.pattern, first, last, counts, self.sample_shading, rect)
            clock("raster")
            yield self._emit(Stage("raster", frags, batch), debug)
            clock(None)
            shaded = run_fragment_stage(frags, prims, self.fragment_shader, self.uniforms, fb.pattern, fb.height,
                                        self.sample_shading)
            clock("fragment")
            yield self._emit(Stage("fragment", shaded, batch), debug)
            clock(None)
            merged = merge(frags, shaded, self.state, fb, record=record)
            clock("output")
            yield self._emit(Stage("output", merged, batch), debug)
            clock(None)

    def _clock(self):
        """A stopwatch that adds the time since its last call to ``self.timings[name]`` (None: skip)."""
        self.timings = {}
        last = [time.perf_counter()]

        def lap(name):
            now = time.perf_counter()
            if name is not None:
                self.timings[name] = self.timings.get(name, 0.0) + (now - last[0])
            last[0] = now
        return lap

    def run(self, trace: bool = False):
        """Run every stage; returns a :class:`~softpipe.trace.Trace` if ``trace``, else None."""
        if trace:
            from .trace import Trace
            return Trace.record(self)
        if self.uses_fast_path():
            self._run_fast()
            return None
        for _ in self.steps():
            pass
        return None

    def _vertex_stage(self):
        vout = run_vertex_stage(self.positions, self.varyings, self.vertex_shader, self.uniforms, self.attributes)
        vout.layout = vout.layout.with_qualifiers(self.interpolation)
        if self.fragment_shader is None:
            default_fragment_shader(vout.layout)     # no 'color' varying: say so now, drawn or not
        return vout

    def fast_path_blocker(self) -> Optional[str]:
        """Why this draw cannot take the visibility fast path, or None if it can."""
        if self.state.blend is not None:
            return "blending is on (the result depends on every fragment, not only the last)"
        if self.fragment_shader is not None and may_discard(self.fragment_shader):
            return "the fragment shader may return DISCARD"
        return None

    def uses_fast_path(self) -> bool:
        """Does :meth:`run` (without a trace) take the fast path? See :mod:`softpipe.visibility`."""
        if self.path == "reference":
            return False
        blocker = self.fast_path_blocker()
        if self.path == "fast":
            if blocker:
                raise ValueError(f"path='fast' is not possible for this draw: {blocker}")
            return True
        fb = self.framebuffer
        return blocker is None and fb.width * fb.height * fb.samples >= FAST_PATH_MIN_SAMPLES

    def _run_fast(self) -> None:
        fb = self.framebuffer
        debug = _debug_stages()
        clock = self._clock()
        vout = self._vertex_stage()
        clock("vertex")
        self._emit(Stage("vertex", vout), debug)
        prims = self.primitives = assemble(vout, self.topology, self.indices, viewport=self.viewport,
                                           cull=self.cull, front_face=self.front_face, keep_culled=False)
        clock("assembly")
        self._emit(Stage("assembly", prims), debug)
        func = -1 if self.state.depth_test is None else DEPTH_FUNCS.index(self.state.depth_test)
        visibility = visibility_pass(prims, fb, func, bool(self.state.depth_write) and func >= 0,
                                     pixel_rect(fb.width, fb.height, self.viewport))
        clock("raster")
        if debug & {"raster", "fragment", "output"}:
            print(f"[softpipe raster] fast path: {visibility!r} "
                  f"(fragments are not kept on the fast path; use path='reference' to see them)",
                  file=sys.stderr)
        if len(prims):
            shade_visible(prims, visibility, fb, self.fragment_shader, self.uniforms, self.sample_shading)
        clock("fragment")

    @staticmethod
    def _emit(stage: Stage, debug: set) -> Stage:
        if stage.name in debug:
            print(f"[softpipe {stage.name}] {stage.output!r}", file=sys.stderr)
        return stage


def draw(framebuffer: Framebuffer, positions, indices=None, varyings: Optional[Mapping[str, Any]] = None,
         vertex_shader: Optional[Callable] = None, fragment_shader: Optional[Callable] = None,
         uniforms: Optional[Mapping[str, Any]] = None, *, trace: bool = False, **state):
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
    trace : bool
        Keep every stage's output and return it as a :class:`~softpipe.trace.Trace`.
    attributes : dict name → [N, k] array, optional
        Extra vertex-shader inputs.
    topology : "triangles" | "triangle_strip" | "triangle_fan"
    interpolation : dict varying name → "smooth" | "noperspective" | "flat"
    depth_test : compare function (see :data:`softpipe.output.DEPTH_FUNCS`) or None
        (default "less")
    depth_write : bool (default True)
    blend : None, "alpha", "additive" or (src_factor, dst_factor) (default None)
    cull : "none" | "back" | "front" (default "none")
    front_face : "ccw" | "cw" (default "ccw")
    viewport : Viewport, optional; the whole framebuffer by default
    sample_shading : "sample" | "center" | "centroid"
        With a multisample framebuffer: shade every sample (supersampling, the
        default), or once per pixel and primitive at the pixel centre or at the
        centroid of its covered samples (multisampling).
    path : "auto" | "reference" | "fast"
        "reference" rasterizes, shades and merges every fragment in order;
        "fast" finds the visible samples first and shades only those
        (:mod:`softpipe.visibility`; not for blending or discard); "auto"
        (default) takes the fast path when it can and the framebuffer has at
        least FAST_PATH_MIN_SAMPLES samples. Both give
        the same bytes.

    Returns
    -------
    None, or a Trace when ``trace=True``.
    """
    call = DrawCall(framebuffer, positions, indices, varyings, vertex_shader, fragment_shader, uniforms, **state)
    return call.run(trace=trace)
