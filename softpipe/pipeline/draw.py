"""The pipeline: wires the stages together, and nothing else.

One pipeline, two orders of the same stages (as early depth in Mesa's softpipe):

    reference:  vertex → assembly → setup → raster → fragment → output
    fast:       vertex → assembly → setup → visibility (raster + depth test) → fragment (visible samples only)

(:mod:`~softpipe.pipeline.vertex`, :mod:`~softpipe.pipeline.assembly`,
:mod:`~softpipe.pipeline.setup`, :mod:`~softpipe.pipeline.raster`,
:mod:`~softpipe.pipeline.fragment`, :mod:`~softpipe.pipeline.output`;
:mod:`~softpipe.pipeline.visibility` for the fast order). :func:`softpipe.pipeline.visibility.choose_path` is the
one function that picks the order; the draw records which it took and why
(:attr:`DrawCall.path_taken`, :attr:`DrawCall.path_reason`).

:func:`draw` is the entry point. :class:`DrawCall` holds one draw's inputs and
runs it either all at once (:meth:`DrawCall.run`) or one stage at a time
(:meth:`DrawCall.steps`, a generator of :class:`Stage`, on whichever path the
draw takes), which is how a notebook steps through a draw;
``draw(..., trace=True)`` keeps every stage's output in a
:class:`~softpipe.pipeline.trace.Trace`.

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
import types
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Mapping, Optional, Tuple, Union

import numpy as np

from softpipe.core.runtime import check_memory
from softpipe.language.contract import make_uniforms
from softpipe.pipeline.assembly import Primitives, assemble, check_clip_planes, check_size, primitive_kind
from softpipe.pipeline.fragment import ShadedFragments, default_fragment_shader, run_fragment_stage
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.merge_state import ALL_SAMPLES, MergeState, Stencil, attachment_states
from softpipe.pipeline.output import (
    MergeResult,
    NonFinite,
    NonFiniteColorWarning,
    OcclusionQuery,
    merge,
    merge_more,
    non_finite_written,
)
from softpipe.pipeline.primitive_visibility import primitive_visibility_pass, shade_primitives
from softpipe.pipeline.raster import Fragments, count_fragments, rasterize, setup_primitives
from softpipe.pipeline.setup import SHADING_POSITIONS, TriangleSetup, apply_polygon_offset, pixel_rect, setup_triangles
from softpipe.pipeline.transforms import Viewport
from softpipe.pipeline.vertex import check_instances, run_vertex_stage
from softpipe.pipeline.visibility import (
    PATHS,
    DiscardOnFastPath,
    ShadedSamples,
    choose_path,
    depth_only,
    record_visible,
    shade_outputs,
    shade_visible,
    shading_may_fail,
    visibility_pass,
)

__all__ = ["draw", "DrawCall", "Stage", "MAX_FRAGMENTS_PER_BATCH", "STAGES"]

MAX_FRAGMENTS_PER_BATCH = 1 << 22
#: The stages :meth:`DrawCall.steps` yields: the reference path's, and the fast path's.
STAGES = ("vertex", "assembly", "raster", "fragment", "output")
FAST_STAGES = ("vertex", "assembly", "visibility", "fragment")
#: Memory a draw takes per triangle in assembly and triangle setup, plus per float of
#: varyings (three corners): 223 bytes measured with 3 varyings; checked before assembly.
BYTES_PER_TRIANGLE, BYTES_PER_TRIANGLE_VARYING = 160, 24
#: Memory a trace takes per fragment: 106 bytes kept (Fragments, ShadedFragments, MergeResult
#: with the colors after), twice while the batches are joined.
BYTES_PER_TRACED_FRAGMENT = 212
#: The keys of :attr:`DrawCall.timings`, the same on both paths.
TIMED = ("vertex", "assembly", "setup", "raster", "fragment", "output")


@dataclass
class Stage:
    """One stage's result while stepping through a draw.

    ``name`` is one of :data:`STAGES` on the reference path, of
    :data:`FAST_STAGES` on the fast path; ``output`` is that stage's data type
    (VertexOut, Primitives, then Fragments, ShadedFragments, MergeResult on the
    reference path, or Visibility, ShadedSamples on the fast path); ``batch``
    counts the fragment batches (raster, fragment and output repeat per batch).
    """

    name: str
    output: Any
    batch: int = 0

    def __repr__(self) -> str:
        batch = f", batch {self.batch}" if isinstance(self.output, _BATCHED) else ""
        return f"Stage({self.name!r}{batch}: {self.output!r})"


_BATCHED = (Fragments, ShadedFragments, MergeResult)


def _debug_stages() -> set:
    value = os.environ.get("SOFTPIPE_DEBUG", "")
    names = {s.strip() for s in value.split(",") if s.strip()}
    return set(STAGES + FAST_STAGES) if "all" in names else names


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


def _polygon_offset(value) -> Optional[Tuple[float, float]]:
    """None, or (factor, units) as two finite floats."""
    if value is None:
        return None
    try:
        factor, units = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"polygon_offset must be (factor, units), two numbers, got {value!r}") from None
    if not (np.isfinite(factor) and np.isfinite(units)):
        raise ValueError(f"polygon_offset must be finite, got {value!r}")
    return factor, units


#: ``blend=``: one state (None, a preset, 2 or 4 factors), or a dict of attachment name → state.
Blend = Union[None, str, Tuple[str, str], Tuple[str, str, str, str], Mapping[str, Any]]
#: ``color_mask=``: 4 bools, or a dict of attachment name → 4 bools.
ColorMask = Union[Tuple[bool, bool, bool, bool], Mapping[str, Tuple[bool, ...]]]


class DrawCall:
    """One draw: its inputs, checked, and the stages that run it.

    The parameters are those of :func:`draw`.
    """

    def __init__(self, framebuffer: Framebuffer, positions, indices=None,
                 varyings: Optional[Mapping[str, Any]] = None, vertex_shader: Optional[Callable] = None,
                 fragment_shader: Optional[Callable] = None, uniforms: Optional[Mapping[str, Any]] = None, *,
                 attributes: Optional[Mapping[str, Any]] = None, topology: str = "triangles",
                 interpolation: Optional[Mapping[str, str]] = None, depth_test: Optional[str] = "less",
                 depth_write: bool = True, blend: Blend = None, cull: str = "none",
                 front_face: str = "ccw", viewport: Optional[Viewport] = None, sample_shading: str = "sample",
                 path: str = "auto", polygon_offset: Optional[Tuple[float, float]] = None,
                 polygon_mode: str = "fill", point_size: float = 1.0, line_width: float = 1.0,
                 clip_planes=None, depth_clamp: bool = False,
                 stencil: Optional[Stencil] = None, stencil_back: Optional[Stencil] = None,
                 scissor: Optional[Tuple[int, int, int, int]] = None,
                 color_mask: ColorMask = (True, True, True, True),
                 blend_equation: Union[str, Tuple[str, str]] = "add",
                 blend_color: Tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
                 sample_mask: int = ALL_SAMPLES, alpha_to_coverage: bool = False,
                 query: Optional[OcclusionQuery] = None, instances: Optional[int] = None,
                 instance_attributes: Optional[Mapping[str, Any]] = None):
        if not isinstance(framebuffer, Framebuffer):
            raise TypeError(f"framebuffer must be a softpipe.Framebuffer, got {type(framebuffer).__name__}")
        viewport = viewport or Viewport(0, 0, framebuffer.width, framebuffer.height)
        if not isinstance(viewport, Viewport):
            raise TypeError(f"viewport must be a softpipe.Viewport, got {type(viewport).__name__}")
        self.framebuffer, self.viewport = framebuffer, viewport
        self.positions, self.indices, self.varyings, self.attributes = positions, indices, varyings, attributes
        for name, f in (("vertex_shader", vertex_shader), ("fragment_shader", fragment_shader)):
            if f is not None and not isinstance(getattr(f, "py_func", f), types.FunctionType):
                raise TypeError(f"{name} must be a function (def or lambda, or a numba.njit one), got "
                                f"{type(f).__name__}; a shader's extra inputs are uniforms (a functools.partial "
                                "or a callable object cannot be compiled)")
        self.vertex_shader, self.fragment_shader = vertex_shader, fragment_shader
        if instances is not None:       # checked now; the vertex stage checks them against the shader
            check_instances(instances, instance_attributes, attributes)
        self.instances, self.instance_attributes = instances, instance_attributes
        self.uniforms = make_uniforms(uniforms)
        self.topology, self.interpolation, self.cull, self.front_face = topology, interpolation, cull, front_face
        self.polygon_mode = polygon_mode
        #: what the draw's primitives are: "triangles", "lines" or "points" (the topology's, or the polygon mode's)
        self.kind = primitive_kind(topology, polygon_mode)
        self.point_size, self.line_width = check_size("point_size", point_size), check_size("line_width", line_width)
        self.clip_planes = check_clip_planes(clip_planes)
        #: the framebuffer's color attachments, ((name, format), …) in location order
        self.attachments = tuple(framebuffer.attachments.items())
        if len(self.attachments) > 1 and fragment_shader is None:
            names = ", ".join(n for n, _ in self.attachments)
            raise ValueError(f"a framebuffer of {len(self.attachments)} attachments ({names}) needs a fragment_shader "
                             "that returns one value per attachment; with none, a draw writes only the varying 'color'")
        # blend= and color_mask= may be given per attachment (GL's glBlendFunci, glColorMaski): location 0's
        # goes to the MergeState, the others' to their AttachmentState
        first_blend, first_mask, self.attachment_states = attachment_states(blend, color_mask, blend_equation,
                                                                            self.attachments)
        self.state = MergeState(depth_test=depth_test, depth_write=depth_write, blend=first_blend,
                                blend_equation=blend_equation, blend_color=blend_color, color_mask=first_mask,
                                stencil=stencil, stencil_back=stencil_back, scissor=scissor,
                                sample_mask=sample_mask, alpha_to_coverage=alpha_to_coverage,
                                depth_clamp=depth_clamp)
        self.depth_clamp = self.state.depth_clamp
        if query is not None and not isinstance(query, OcclusionQuery):
            raise TypeError(f"query must be a softpipe.OcclusionQuery or None, got {type(query).__name__}")
        self.query = query
        self.rect = self._pixel_rect(scissor=True)
        if sample_shading not in SHADING_POSITIONS:
            raise ValueError(f"sample_shading must be one of {SHADING_POSITIONS}, got {sample_shading!r}")
        self.sample_shading = sample_shading
        if path not in PATHS:
            raise ValueError(f"path must be one of {PATHS}, got {path!r}")
        self.path = path
        self.polygon_offset = _polygon_offset(polygon_offset)
        #: seconds spent in each stage by the last run, keyed by :data:`TIMED` on both paths (on
        #: the fast path "raster" is the visibility pass, with its depth test, and "output" is 0:
        #: shading writes the visible samples' color)
        self.timings: dict = {}
        #: the last run's assembled triangles (what reached the rasterizer), on either path
        self.primitives: Optional[Primitives] = None
        #: which path the last run took ("reference" or "fast"), and why
        self.path_taken: Optional[str] = None
        self.path_reason: Optional[str] = None
        #: the samples the last run wrote with a NaN or infinite color (None: none), of which a
        #: :class:`~softpipe.pipeline.output.NonFiniteColorWarning` told
        self.non_finite: Optional[NonFinite] = None
        # what this draw's primitives store in the framebuffer's visibility record (None: it keeps none)
        self._record_ids: Optional[np.ndarray] = None

    def choose_path(self, keep_fragments: bool = False) -> Tuple[str, str]:
        """The path this draw takes and why (:func:`softpipe.pipeline.visibility.choose_path`)."""
        fb = self.framebuffer
        blocker = next((f"attachment {a.name!r} " + ("is blended" if a.blends else f"has the color mask {a.color_mask}")
                        + " (the fast path writes whole values, unblended)"
                        for a in self.attachment_states if a.blends or a.masks_color), None)
        if blocker is None and len(self.attachments) > 1 and self.state.depth_test == "notequal" \
                and self.state.depth_write:
            blocker = ("depth test 'notequal' with depth writes into several attachments (a hidden fragment the "
                       "shader discarded could change the picture)")
        if blocker is not None and self.path == "fast":
            raise ValueError(f"path='fast' is not possible for this draw: {blocker}")
        if blocker is not None and self.path == "auto":
            return "reference", blocker
        return choose_path(self.path, self.state, self.fragment_shader, fb.width * fb.height * fb.samples,
                           keep_fragments, fb.samples, self.query is not None, len(self.attachments))

    def steps(self, record: bool = False) -> Iterator[Stage]:
        """Run the draw one stage at a time, yielding each stage's result as it is made.

        The stages are those of the path the draw takes (:meth:`choose_path`;
        ``record`` asks for every fragment, so "auto" keeps to the reference
        path). The framebuffer is updated by each "output" stage (the
        "fragment" stage on the fast path); a draw stepped to the end leaves it
        exactly as :meth:`run` would. ``record`` keeps each fragment's color
        after merging (for pixel history).

        The draw holds the framebuffer's lock (:attr:`Framebuffer.lock`) from its
        first stage to its last, so draws from several threads into one
        framebuffer take turns; and it refuses (ValueError), before any stage, a
        framebuffer with an array flagged read-only (:meth:`Framebuffer.check_drawable`).
        """
        with self.framebuffer.lock:
            self.framebuffer.check_drawable()
            self.framebuffer.count_write()
            yield from self._steps(record)

    def _steps(self, record: bool) -> Iterator[Stage]:
        self.path_taken, self.path_reason = self.choose_path(keep_fragments=record)
        #: the pixels this run may touch (:func:`~softpipe.pipeline.setup.pixel_rect`, with the scissor)
        self.rect = self._pixel_rect(scissor=not record)
        debug = _debug_stages()
        clock = self._clock()
        vout = self._vertex_stage()
        clock("vertex")
        yield self._emit(Stage("vertex", vout), debug)
        clock(None)
        fast = self.path_taken == "fast"
        self._check_memory(vout)
        prims = self.primitives = assemble(vout, self.topology, self.indices, viewport=self.viewport,
                                           cull=self.cull, front_face=self.front_face, keep_culled=not fast,
                                           polygon_mode=self.polygon_mode, point_size=self.point_size,
                                           line_width=self.line_width, clip_planes=self.clip_planes,
                                           depth_clamp=self.depth_clamp)
        self._record_ids = self._recorded(vout, prims)
        clock("assembly")
        yield self._emit(Stage("assembly", prims), debug)
        clock(None)
        fb = self.framebuffer
        setup = setup_primitives(prims, self.rect, fb.pattern.offsets)
        if self.polygon_offset is not None:
            if isinstance(setup, TriangleSetup):
                apply_polygon_offset(setup, prims.window, *self.polygon_offset)
            elif prims.faces is not None:
                self._offset_polygon_mode(prims, setup, self.polygon_offset)
        clock("setup")
        stages = self._fast_stages(prims, setup, clock) if fast else self._reference_stages(prims, setup, clock,
                                                                                               record)
        self.non_finite = None
        for stage in stages:
            yield self._emit(stage, debug)
            clock(None)
        if self.non_finite is not None:
            warnings.warn(NonFiniteColorWarning(self.non_finite.message()), stacklevel=2)

    def _offset_polygon_mode(self, prims: Primitives, setup, polygon_offset: Tuple[float, float]) -> None:
        """The polygon offset of triangles drawn as edges or corners: each takes its triangle's offset
        (its slope, GL's ``POLYGON_OFFSET_LINE`` / ``_POINT``), added to the line's or point's depth."""
        faces = prims.faces
        assert faces is not None
        face_setup = setup_triangles(faces.window, self.rect, self.framebuffer.pattern.offsets)
        before = face_setup.plane[:, 0].copy()
        apply_polygon_offset(face_setup, faces.window, *polygon_offset)
        triangles, first_row = np.unique(_draw_wide_ids(faces), return_index=True)
        offset = (face_setup.plane[:, 0] - before)[first_row[np.searchsorted(triangles, _draw_wide_ids(prims))]]
        setup.depth += offset[:, None] if setup.depth.ndim == 2 else offset

    def _pixel_rect(self, scissor: bool) -> np.ndarray:
        """The pixels the draw may touch: the viewport within the framebuffer, and within the scissor
        rectangle if ``scissor`` (a traced draw makes the fragments outside it too, for the merger to
        stop and the pixel history to show; either way the same pixels are written)."""
        rect = pixel_rect(self.framebuffer.width, self.framebuffer.height, self.viewport)
        if scissor and self.state.scissor is not None:
            x, y, w, h = self.state.scissor
            rect = np.array([max(rect[0], x), min(rect[1], x + w - 1), max(rect[2], y), min(rect[3], y + h - 1)],
                            np.int64)
        return rect

    def _check_memory(self, vout) -> None:
        """Refuse, before assembly, a draw whose primitives cannot fit in memory (:data:`BYTES_PER_TRIANGLE`:
        a line or point takes as much as a triangle)."""
        n = len(vout.position) if self.indices is None else np.size(self.indices) * vout.instances
        per_kind = {"triangles": n // 3, "lines": n // 2, "triangle_strip": n - 2, "triangle_fan": n - 2}
        triangles = max(per_kind.get(self.topology, n), 0) * (3 if self.polygon_mode != "fill" else 1)
        per_triangle = BYTES_PER_TRIANGLE + BYTES_PER_TRIANGLE_VARYING * vout.layout.width
        check_memory(f"drawing {triangles:,} triangles (assembly and triangle setup, {per_triangle} bytes each)",
                     triangles * per_triangle)

    def _reference_stages(self, prims, setup, clock, record: bool) -> Iterator[Stage]:
        """Rasterize, shade every fragment and merge in order, in batches of whole triangles."""
        fb = self.framebuffer
        counts = count_fragments(prims, fb.width, fb.height, fb.pattern, rect=self.rect, setup=setup)
        if record:
            total = int(counts.sum())
            check_memory(f"tracing {total:,} fragments ({BYTES_PER_TRACED_FRAGMENT} bytes each, kept by the trace)",
                         total * BYTES_PER_TRACED_FRAGMENT)
        clock("raster")
        batches = list(_batches(counts, MAX_FRAGMENTS_PER_BATCH))
        # A shader that raises leaves the framebuffer as it was: with one batch nothing is merged
        # before every fragment is shaded; with more (millions of fragments), a copy is kept.
        saved = ((fb.samples_color.copy(), fb.samples_depth.copy(), fb.samples_stencil.copy(),
                  None if fb.record is None else fb.record.copy()) if len(batches) > 1 else None)
        saved_more = ([fb.samples_attachment(n).copy() for n, _ in self.attachments[1:]] if len(batches) > 1
                      else None)
        passed = 0
        for batch, (first, last) in enumerate(batches):
            frags = rasterize(prims, fb.width, fb.height, fb.pattern, first, last, counts, self.sample_shading,
                              rect=self.rect, setup=setup)
            clock("raster")
            yield Stage("raster", frags, batch)
            try:
                shaded = run_fragment_stage(frags, prims, self.fragment_shader, self.uniforms, self.sample_shading,
                                            self.attachments)
            except BaseException:
                if saved is not None:
                    fb.samples_color[...], fb.samples_depth[...], fb.samples_stencil[...] = saved[:3]
                    if saved[3] is not None and fb.record is not None:
                        fb.record[...] = saved[3]
                for (name, _), before in zip(self.attachments[1:], saved_more or ()):
                    fb.samples_attachment(name)[...] = before
                raise
            clock("fragment")
            yield Stage("fragment", shaded, batch)
            merged = merge(frags, shaded, self.state, fb, record=record, front_facing=prims.front_facing,
                           record_ids=self._record_ids)
            if self.attachment_states:
                merge_more(frags, shaded, merged.verdict, fb, self.attachment_states, self.state.blend_color)
            if self.query is not None:
                passed += merged.samples_passed
            self._note_non_finite(non_finite_written(frags, shaded, merged, self.state.color_mask))
            clock("output")
            yield Stage("output", merged, batch)
        if self.query is not None:
            self.query.add(passed)

    def _fast_stages(self, prims, setup, clock) -> Iterator[Stage]:
        """Early depth: the visibility pass, then the shader on the visible samples only.

        Triangles: the tiled visibility pass (:func:`~softpipe.pipeline.visibility.visibility_pass`).
        Points and lines: their own walk over the same tiles
        (:func:`~softpipe.pipeline.primitive_visibility.primitive_visibility_pass`); no fragment list is made.
        A depth-only draw (:func:`~softpipe.pipeline.visibility.depth_only`) stops after the
        visibility pass: nothing is shaded.
        """
        fb = self.framebuffer
        # a depth-only draw (a shadow map's pass): the visibility pass's depth is its whole result
        only = depth_only(self.state, self.fragment_shader, len(self.attachments))
        undo = shading_may_fail(self.fragment_shader, prims.layout) if len(prims) and not only else False
        if len(self.attachments) > 1 and len(prims):
            # the proofs that shading cannot fail read a single RGBA's alpha; a shader returning a value per
            # attachment is not proved, so the depth is kept to put back
            undo = True
        visibility: Any
        shade: Callable[..., Any]
        if prims.kind == "triangles":
            visibility, shade = visibility_pass(prims, setup, fb, self.state, undo=undo), shade_visible
            if len(self.attachments) > 1:
                shade = shade_outputs
        else:
            visibility = primitive_visibility_pass(prims, setup, fb, self.state, self.rect, undo=undo)
            shade = shade_primitives
            if len(self.attachments) > 1:
                shade = shade_outputs
        clock("raster")
        yield Stage("visibility", visibility)
        if only:        # no shader runs, no color is read or written
            if self._record_ids is not None:
                record_visible(fb, visibility, self._record_ids, self.state)
            clock("fragment")
            yield Stage("fragment", ShadedSamples(visibility, self.sample_shading, depth_only=True))
            return
        try:
            shaded = shade(prims, visibility, fb, self.fragment_shader, self.uniforms, self.sample_shading)
        except DiscardOnFastPath as e:
            # the depth is as it was before the draw: draw it again in the reference order (even with
            # path="fast": only the reference path can draw what a discarded fragment lets show)
            self.path_taken = "reference"
            self.path_reason = (f"{e} on the fast path, which then drew it again on the reference path "
                                "(a discarded fragment lets what is behind it show)")
            clock("fragment")
            yield from self._reference_stages(prims, setup, clock, record=False)
            return
        self._note_non_finite(shaded.non_finite)
        if self._record_ids is not None:
            record_visible(fb, visibility, self._record_ids, self.state)
        clock("fragment")
        yield Stage("fragment", shaded)

    def _recorded(self, vout, prims: Primitives) -> Optional[np.ndarray]:
        """With a framebuffer that keeps a visibility record: note this draw in it and return what its
        primitives store there (the draw's first value + the draw-wide input primitive, in the record's
        dtype: the framebuffer refused a draw whose values would not fit); else None."""
        fb = self.framebuffer
        if not fb.has_record:
            return None
        instances = max(prims.instances, 1)
        corners = prims.source_corners
        if corners is not None and self.indices is not None and np.may_share_memory(corners, self.indices):
            corners = corners.copy()             # (int64 indices come back as a view: the record keeps them as drawn)
        entry = fb.add_recorded_draw(self, vout.position, vout.vertices_per_instance, prims.input_count,
                                     prims.input_count // instances, prims.kind, corners)
        return (entry.base + _draw_wide_ids(prims)).astype(np.int32)      # (the record's dtype)

    def _note_non_finite(self, found: Optional[NonFinite]) -> None:
        """Add a batch's non-finite samples to the draw's (the first one kept)."""
        if found is None:
            return
        if self.non_finite is None:
            self.non_finite = found
        else:
            self.non_finite = NonFinite(self.non_finite.count + found.count, self.non_finite.x, self.non_finite.y,
                                        self.non_finite.primitive_id)

    def _clock(self):
        """A stopwatch that adds the time since its last call to ``self.timings[name]`` (None: skip)."""
        self.timings = dict.fromkeys(TIMED, 0.0)
        last = [time.perf_counter()]

        def lap(name):
            now = time.perf_counter()
            if name is not None:
                self.timings[name] = self.timings.get(name, 0.0) + (now - last[0])
            last[0] = now
        return lap

    def run(self, trace: bool = False):
        """Run every stage; returns a :class:`~softpipe.pipeline.trace.Trace` if ``trace``, else None."""
        if trace:
            from softpipe.pipeline.trace import Trace
            return Trace.record(self)
        for _ in self.steps():
            pass
        return None

    def _vertex_stage(self):
        vout = run_vertex_stage(self.positions, self.varyings, self.vertex_shader, self.uniforms, self.attributes,
                                self.instances, self.instance_attributes)
        vout.layout = vout.layout.with_qualifiers(self.interpolation)
        if self.fragment_shader is None:
            default_fragment_shader(vout.layout)     # no 'color' varying: say so now, drawn or not
        return vout

    def uses_fast_path(self) -> bool:
        """Does :meth:`run` (without a trace) take the fast path? See :mod:`softpipe.pipeline.visibility`."""
        return self.choose_path()[0] == "fast"

    @staticmethod
    def _emit(stage: Stage, debug: set) -> Stage:
        if stage.name in debug:
            print(f"[softpipe {stage.name}] {stage.output!r}", file=sys.stderr)
        return stage


def _draw_wide_ids(prims: Primitives) -> np.ndarray:
    """Each primitive's input primitive over the whole draw (an instanced draw's ids restart per instance)."""
    if prims.instances in (0, 1) or prims.instance is None:
        return prims.primitive_id
    return prims.instance * (prims.input_count // prims.instances) + prims.primitive_id


def draw(framebuffer: Framebuffer, positions, indices=None, varyings: Optional[Mapping[str, Any]] = None,
         vertex_shader: Optional[Callable] = None, fragment_shader: Optional[Callable] = None,
         uniforms: Optional[Mapping[str, Any]] = None, *, trace: bool = False, **state):
    """Draw points, lines or triangles into ``framebuffer``.

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
        See :mod:`softpipe.language.contract`. Without a fragment shader the color is the
        interpolated varying ``color``. Into a framebuffer of several color attachments
        (``Framebuffer(attachments=...)``) the fragment shader returns a tuple of one value per
        attachment, in their order (docs/shaders.md).
    uniforms : dict, optional
        Values every shader invocation sees (:func:`softpipe.language.contract.make_uniforms`).
    trace : bool
        Keep every stage's output and return it as a :class:`~softpipe.pipeline.trace.Trace`.
    attributes : dict name → [N, k] array, optional
        Extra vertex-shader inputs.
    instances : int, optional
        Instancing (GL's ``glDrawArraysInstanced`` / ``glDrawElementsInstanced``): draw the
        vertices (and indices) this many times, the vertex shader running once per vertex per
        instance and seeing ``attributes.instance_id`` (``gl_InstanceID``, an int from 0).
        Instance 0's primitives are drawn first, then instance 1's, …; strips, fans and loops
        restart in each instance; ``frag.primitive_id`` restarts at 0 in each
        (:attr:`Primitives.instance` names the instance). 0 draws nothing. Needs a vertex shader.
    instance_attributes : dict name → [instances, k] array, optional
        Per-instance vertex-shader inputs (``glVertexAttribDivisor`` 1): every vertex of instance
        i sees row i as ``attributes.<name>``; k is 1 to 4, the values finite, the names apart
        from the per-vertex attributes'.
    topology : "points" | "lines" | "line_strip" | "line_loop" | "triangles" | "triangle_strip" | "triangle_fan"
        GL's primitive types (default "triangles"); lines follow GL's diamond-exit rule
        (:mod:`softpipe.pipeline.lines`), points GL's square (:mod:`softpipe.pipeline.points`).
    polygon_mode : "fill" | "line" | "point"
        GL's ``glPolygonMode``: triangles drawn filled (default), or as their edges or corners
        (after culling; flat varyings from the triangle's provoking vertex).
    point_size : float
        Points' size in pixels (GL's ``glPointSize``, default 1, clamped to [1, 255]); a vertex
        shader's varying ``point_size`` (GLSL's ``gl_PointSize``) sets it per vertex.
    line_width : float
        Lines' width in pixels (GL's ``glLineWidth``, default 1): a run of round(width)
        fragments across the line's minor axis.
    clip_planes, depth_clamp : [[a, b, c, d], ...] (at most 8), bool (default None, False)
        User clip planes, kept where a·x+b·y+c·z+d·w ≥ 0 (a varying ``clip_distance`` too); GL_DEPTH_CLAMP.
    interpolation : dict varying name → "smooth" | "noperspective" | "flat"
    depth_test : compare function (see :data:`softpipe.pipeline.merge_state.DEPTH_FUNCS`) or None
        (default "less")
    depth_write : bool (default True)
    blend : None, "alpha", "premultiplied", "additive", (src_factor, dst_factor) or
        (src_rgb, dst_rgb, src_alpha, dst_alpha) (default None: off); factors are GL's, lower case
        (:data:`softpipe.pipeline.merge_state.BLEND_FACTORS`). Into a framebuffer of several
        attachments, one state for every float attachment, or a dict of attachment name → state
        (GL's ``glBlendFunci``; those not named are not blended, nor is an integer attachment)
    blend_equation : "add" | "subtract" | "reverse_subtract" | "min" | "max", or (rgb, alpha)
        (default "add")
    blend_color : (r, g, b, a)
        The ``constant_*`` factors' color (GL's ``glBlendColor``, default (0, 0, 0, 0)).
    color_mask : 4 bools, or a dict of attachment name → 4 bools
        Which channels are written (GL's ``glColorMask``, default all; per attachment,
        ``glColorMaski``: those not named are written whole).
    stencil : Stencil, optional
        Turns the stencil test on with this state (:class:`softpipe.Stencil`: func, ref, mask, the ops
        on stencil fail, depth fail and depth pass, write mask); the framebuffer's stencil buffer
        holds 8 bits per sample.
    stencil_back : Stencil, optional
        The state for back-facing triangles (GL's ``*Separate``); the same as ``stencil`` by default.
    scissor : (x, y, width, height), optional
        Only pixels in this rectangle are written (window coordinates, row 0 at the bottom, as the
        viewport).
    sample_mask : int
        Bit m lets sample m be written (multisampling; default every sample).
    alpha_to_coverage : bool
        With several samples per pixel, a fragment covers round(alpha·S) of them (default False).
    query : OcclusionQuery, optional
        Counts the samples that passed every test (``query.samples_passed``).
    cull : "none" | "back" | "front" (default "none")
    front_face : "ccw" | "cw" (default "ccw")
    viewport : Viewport, optional; the whole framebuffer by default
    polygon_offset : (factor, units), optional
        OpenGL's ``glPolygonOffset`` (for triangles, filled or in a polygon mode, whose edges
        and corners take their triangle's offset; not for the line and point topologies):
        every triangle's depth is moved by
        factor·DZ + units·r (:func:`softpipe.pipeline.setup.apply_polygon_offset`); a shadow
        map's depth bias.
    sample_shading : "sample" | "center" | "centroid"
        With a multisample framebuffer: shade every sample (supersampling, the
        default), or once per pixel and primitive at the pixel centre or at the
        centroid of its covered samples (multisampling).
    path : "auto" | "reference" | "fast"
        "reference" rasterizes, shades and merges every fragment in order;
        "fast" finds the visible samples first and shades only those
        (:mod:`softpipe.pipeline.visibility`; not for blending or discard); "auto"
        (default) takes the fast path when it can and the framebuffer has at
        least FAST_PATH_MIN_SAMPLES samples, and the reference path for a
        trace. Both give the same bytes; the DrawCall records which ran.

    Returns
    -------
    None, or a Trace when ``trace=True``.
    """
    call = DrawCall(framebuffer, positions, indices, varyings, vertex_shader, fragment_shader, uniforms, **state)
    return call.run(trace=trace)
