"""The fast path: a second back end for opaque draws — find the visible samples first, then shade only those.

For a draw whose result depends only on which fragment is written last at each
sample (no blending, no discard), the hidden fragments need not be shaded. The
reference back end (:mod:`~softpipe.pipeline.raster` → :mod:`~softpipe.pipeline.fragment`
→ :mod:`~softpipe.pipeline.output`) makes, shades and merges every fragment in
primitive order; this one replaces those stages below the triangle setup. It
**shares** assembly, the triangle setup and its rules (:mod:`softpipe.pipeline.setup`),
the depth compare (``output.depth_passes``) and the shader inputs (interpolated by
the same generated code of :mod:`softpipe.language.kernels`); its **own** are the
coverage walk of :mod:`softpipe.pipeline.tiles`, which keeps only a visibility
buffer, a shading loop over that buffer, and no output merger.

Here:

1. **The choice** (:func:`choose_path`, :func:`fast_path_blocker`): the one place
   that decides which back end a draw takes, and why; :func:`depth_only` decides
   whether a draw writes depth alone (a shadow map's pass), whose result is then the
   visibility pass's depth, with nothing shaded.
2. **The visibility pass** (:func:`visibility_pass`): the tiles' binning and walk over
   the draw's triangle setup. Output: :class:`Visibility`, the last triangle that
   passed the depth test at each sample.
3. **Shading** (:func:`shade_visible`, the generated ``visible_loop``): the fragment
   shader runs once per visible sample (with multisampling, once per pixel and
   triangle there). Output: :class:`ShadedSamples`. A shader that raises, or returns
   a NaN alpha (:class:`DiscardOnFastPath`: the draw is then done on the reference
   path), has the draw undone.
4. **Points and lines** (:func:`primitive_visibility_pass`, :func:`shade_primitives`): the
   same design on the same tiles. Each is binned to the tiles its box touches; each tile
   walks its points or lines in order by the reference rasterizer's rules
   (:mod:`~softpipe.pipeline.tiles`), depth-testing every fragment's samples as the merger
   would and keeping no fragment, only the last primitive written at each sample
   (:class:`PrimitiveVisibility`); then the visible samples are made into fragments and
   shaded, in bands on the helper threads.

The bytes are the reference's (tests/test_fast_path.py, test_fast_path_sound.py,
test_properties.py hold them so); docs/08-fast-path.md walks through it and says why.
"""
from __future__ import annotations

import dis
import inspect
import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple, Union

import numba
import numpy as np

from softpipe.core.parallel import in_bands, threads
from softpipe.language import kernels
from softpipe.language.contract import python_function
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.fragment import (
    ShadedFragments,
    default_fragment_shader,
    derivative_gradients,
    run_fragment_stage,
)
from softpipe.pipeline.lines import LineSetup, line_sample_inputs, sample_means
from softpipe.pipeline.merge_state import DEPTH_FUNCS, MergeState
from softpipe.pipeline.output import NonFinite
from softpipe.pipeline.points import PointSetup, point_sample_inputs
from softpipe.pipeline.raster import Fragments
from softpipe.pipeline.setup import (
    SHADE_SAMPLE,
    SHADING_POSITIONS,
    TriangleSetup,
    pixel_coverage,
    sample_depth,
    shading_point,
)
from softpipe.pipeline.tiles import (
    TILE_H,
    TILE_W,
    bin_primitives,
    bin_triangles,
    primitive_boxes,
    raster_line_tiles,
    raster_point_tiles,
    raster_tiles,
)

__all__ = ["Visibility", "ShadedSamples", "visibility_pass", "shade_visible", "choose_path", "fast_path_blocker",
           "PATHS", "FAST_PATH_MIN_SAMPLES", "DiscardOnFastPath", "shading_may_fail",
           "visible_loop_args", "PrimitiveVisibility", "primitive_visibility_pass", "shade_primitives",
           "shade_outputs", "depth_only", "constant_color"]

#: The orders a draw can take: "reference" (rasterize, shade every fragment, merge
#: in order), "fast" (this module), or "auto" (fast when it can, see :func:`choose_path`).
PATHS = ("auto", "reference", "fast")
#: path="auto" takes the fast path from this many framebuffer samples on
#: (small draws, such as most tests, keep to the reference path and its compile costs).
FAST_PATH_MIN_SAMPLES = 128 * 128


# ------------------------------------------------------------------ the decision

#: Bytecode that does nothing (a function's prologue, padding), read past by :func:`constant_color`.
_NO_OPS = ("RESUME", "NOP", "CACHE", "PRECALL")


def constant_color(shader: Optional[Callable]) -> Optional[Tuple[float, float, float, float]]:
    """The color a fragment shader returns when its whole body is ``return (r, g, b, a)`` of four finite
    number literals (``lambda varyings, uniforms, frag: (0.0, 0.0, 0.0, 1.0)``), else None.

    A proof, read from the bytecode: such a shader takes the three parameters, compiles, cannot
    raise, discard or return a non-finite color, and gives every fragment the same color, so
    running it changes nothing a draw that writes no color keeps.
    """
    f = python_function(shader) if shader is not None else None
    code = getattr(f, "__code__", None)
    if code is None or code.co_argcount != 3 or code.co_kwonlyargcount \
            or code.co_flags & (inspect.CO_VARARGS | inspect.CO_VARKEYWORDS):
        return None
    body = [(i.opname, i.argval) for i in dis.get_instructions(code) if i.opname not in _NO_OPS]
    if len(body) == 1 and body[0][0] == "RETURN_CONST":
        value = body[0][1]
    elif len(body) == 2 and body[0][0] == "LOAD_CONST" and body[1][0] == "RETURN_VALUE":
        value = body[0][1]
    else:
        return None
    if not (isinstance(value, tuple) and len(value) == 4
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        return None
    r, g, b, a = (float(v) for v in value)
    return r, g, b, a


def depth_only(state: MergeState, fragment_shader: Optional[Callable], attachments: int = 1) -> bool:
    """Does the draw write depth alone, so that its visibility pass's depth is all it leaves?

    True when every color channel is masked off (``color_mask=(False,) * 4``) in a framebuffer
    of one color attachment and the fragment shader returns a constant color
    (:func:`constant_color`): it cannot discard, raise or warn, and writes nothing. Such a draw
    (a shadow map's depth pass) takes the fast path without its shading: no shader runs, no
    color is read or written; the depth and the visibility record are those of the reference
    path (which runs the shader and throws its colors away).
    """
    return (attachments == 1 and not any(state.color_mask) and state.blend is None
            and constant_color(fragment_shader) is not None)


def fast_path_blocker(state: MergeState, fragment_shader: Optional[Callable], samples_per_pixel: int = 1,
                      counts_samples: bool = False, attachments: int = 1) -> Optional[str]:
    """Why a draw with this merge state and shader cannot take the fast path, or None if it can.

    The fast path tests depth and writes whole colors, or none (:func:`depth_only`); the scissor it
    takes as the rectangle its coverage walk stays in (the same pixels). ``samples_per_pixel`` is the
    framebuffer's (the multisample operations apply only with more than one); ``counts_samples``: an
    occlusion query counts the samples that pass; ``attachments``: the framebuffer's color attachments.
    """
    if state.blend is not None:
        return "blending is on (the result depends on every fragment, not only the last)"
    if state.stencil is not None:
        return "the stencil test is on (the fast path's visibility pass tests depth only)"
    if state.masks_color and not depth_only(state, fragment_shader, attachments):
        return f"the color mask {state.color_mask} holds back a channel (the fast path writes whole colors)"
    if state.depth_clamp:
        return "depth clamp is on (the fast path's visibility pass compares unclamped depths)"
    if samples_per_pixel > 1 and state.alpha_to_coverage:
        return "alpha to coverage is on (which samples a fragment covers depends on the shader's alpha)"
    if samples_per_pixel > 1 and (state.sample_mask & ((1 << samples_per_pixel) - 1)) != (1 << samples_per_pixel) - 1:
        return f"the sample mask {state.sample_mask:#x} leaves samples out (the fast path writes every covered sample)"
    if counts_samples:
        return "an occlusion query counts the samples that pass, which only the reference path's merger counts"
    if fragment_shader is not None and kernels.may_discard(fragment_shader):
        return "the fragment shader may return DISCARD"
    if state.depth_test == "notequal" and state.depth_write and not (
            fragment_shader is not None and kernels.alpha_is_finite(fragment_shader)):
        # the one compare function under which discarding a hidden fragment can change which one shows
        return ("depth test 'notequal' with depth writes, and a fragment shader whose alpha is not a finite "
                "literal (a hidden fragment it discarded could change the picture)")
    return None


def choose_path(path: str, state: MergeState, fragment_shader: Optional[Callable], samples: int,
                keep_fragments: bool = False, samples_per_pixel: int = 1,
                counts_samples: bool = False, attachments: int = 1) -> Tuple[str, str]:
    """Which order a draw takes, and why: ("reference" | "fast", reason).

    ``path`` is the draw's request (:data:`PATHS`), ``samples`` the framebuffer's
    width × height × samples per pixel, ``keep_fragments`` whether the caller
    needs every fragment (a trace with ``path="auto"``); ``samples_per_pixel``,
    ``counts_samples`` and ``attachments`` as :func:`fast_path_blocker` takes them. A depth-only
    draw (:func:`depth_only`) on the fast path says so in its reason. The same for every kind of
    primitive (points and lines have a visibility pass of their own, :func:`primitive_visibility_pass`).
    """
    if path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, got {path!r}")
    if path == "reference":
        return "reference", "path='reference' was asked for"
    blocker = fast_path_blocker(state, fragment_shader, samples_per_pixel, counts_samples, attachments)
    only = depth_only(state, fragment_shader, attachments)
    why_only = ("depth only (every color channel masked off, a constant fragment shader): the visibility "
                "pass's depth is the draw's result, nothing is shaded")
    if path == "fast":
        if blocker:
            raise ValueError(f"path='fast' is not possible for this draw: {blocker}")
        return "fast", "path='fast' was asked for" + (f"; {why_only}" if only else "")
    if blocker:
        return "reference", blocker
    if keep_fragments:
        return "reference", "a trace keeps every fragment, which only the reference path makes (path='fast' traces the fast path)"
    if samples < FAST_PATH_MIN_SAMPLES:
        return "reference", f"a small framebuffer ({samples} samples < FAST_PATH_MIN_SAMPLES = {FAST_PATH_MIN_SAMPLES})"
    if only:
        return "fast", why_only
    return "fast", "opaque draw without discard: only the visible samples are shaded"


# --------------------------------------------------------------- the visibility pass

@dataclass
class Visibility:
    """What the visibility pass hands to shading: which triangle to shade at each sample.

    Attributes
    ----------
    vis : int32 [S, H, W]
        The triangle (row of the Primitives) whose fragment was written last at
        each sample by this draw, or −1 (image rows: row 0 at the top).
    setup : TriangleSetup
        The triangle setup the pass used (edges, fill-rule biases, depth planes, boxes).
    touched : bool [tiles_y, tiles_x]
        Tiles (TILE_W × TILE_H pixels, in window coordinates: tile row 0 at the
        bottom) where some triangle was depth-tested; the others hold no ``vis`` entry.
    saved_depth : float32 [S, H, W] or None
        The framebuffer's depth before the pass, in the touched tiles (elsewhere
        unset), while shading may still undo the draw; None once it cannot (or
        when the pass wrote no depth).
    """

    vis: np.ndarray
    setup: TriangleSetup
    touched: np.ndarray
    saved_depth: Optional[np.ndarray] = field(default=None, repr=False)

    def restore_depth(self, fb) -> None:
        """Put back the depth the pass replaced (the touched tiles' ``saved_depth``)."""
        if self.saved_depth is None:
            return
        depth, h, w = fb.samples_depth, self.vis.shape[1], self.vis.shape[2]
        for ty, tx in zip(*np.nonzero(self.touched)):
            rows = slice(max(h - (ty + 1) * TILE_H, 0), h - ty * TILE_H)
            cols = slice(tx * TILE_W, min((tx + 1) * TILE_W, w))
            depth[:, rows, cols] = self.saved_depth[:, rows, cols]

    def __repr__(self) -> str:
        return (f"Visibility({int((self.vis >= 0).sum())} visible samples of {self.vis.size}, "
                f"{len(self.setup)} triangles, {int(self.touched.sum())} of {self.touched.size} tiles touched)")

    def visible_triangles(self) -> np.ndarray:
        """The rows of the Primitives that are visible at some sample, sorted."""
        return np.unique(self.vis[self.vis >= 0])

    def fragments(self, prims: Primitives, pattern, shading: str = "sample") -> Fragments:
        """The fragments the fast path shaded, as the rasterizer's :class:`~softpipe.pipeline.raster.Fragments`.

        One per visible sample, in (sample, image row, column) order, with the
        barycentrics, depth and window position the shading loop gave the
        shader. (The fragments that lost the depth test were never made.)
        """
        s_idx, rows, cols = np.nonzero(self.vis >= 0)
        n = len(s_idx)
        tri = self.vis[s_idx, rows, cols].astype(np.int32)
        depth, bary, pos = np.empty(n), np.empty((n, 3)), np.empty((2, n))
        height = self.vis.shape[1]
        _visible_fragments(s_idx, rows, cols, tri, self.setup.edges, self.setup.bias, self.setup.plane, height,
                           pattern.offsets, pattern.positions, SHADING_POSITIONS.index(shading), depth, bary, pos)
        return Fragments(cols.astype(np.int32), rows.astype(np.int32), s_idx.astype(np.int32), depth, bary, tri,
                         prims.primitive_id[tri], pos[0], pos[1], self.setup)


@numba.njit(cache=True)
def _visible_fragments(s_idx, rows, cols, tri, edges, bias, plane, height, offsets, positions, mode, depth, bary,
                       pos):
    for k in range(s_idx.shape[0]):
        s, i, j, t = s_idx[k], cols[k], height - 1 - rows[k], tri[k]
        mask, count = np.int64(0), 1
        if mode != SHADE_SAMPLE:
            mask, _, count = pixel_coverage(edges, bias, t, i, j, offsets)
        b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets, positions, mode)
        depth[k] = sample_depth(edges, plane, t, i, j, s, offsets)
        bary[k, 0], bary[k, 1], bary[k, 2] = b0, b1, b2
        pos[0, k], pos[1, k] = fx, fy


def shading_may_fail(fragment_shader: Optional[Callable], layout) -> bool:
    """Can shading on the fast path fail, raising or returning a NaN alpha? (False is a proof.)

    False for a shader that cannot raise (:func:`~softpipe.language.kernels.may_raise`) and
    returns a finite literal alpha (:func:`~softpipe.language.kernels.alpha_is_finite`), such
    as the default shader of an RGB ``color``: its draw keeps nothing to undo.
    """
    may_raise, may_nan = _failure_modes(fragment_shader or default_fragment_shader(layout), layout)
    return may_raise or may_nan


def _failure_modes(shader: Callable, layout) -> Tuple[bool, bool]:
    """(may it raise, may its alpha be NaN), read from its code once per compiled loop (the loop is
    kept per shader, layout and values of the globals it reads, helpers included)."""
    module = kernels.fragment_module(shader, layout)
    modes = getattr(module, "_softpipe_failure_modes", None)
    if modes is None:
        modes = module._softpipe_failure_modes = (kernels.may_raise(shader), not kernels.alpha_is_finite(shader))  # type: ignore[attr-defined]  # kept on the module
    return modes


def visibility_pass(prims: Primitives, setup: TriangleSetup, fb, state: MergeState,
                    undo: bool = True) -> Visibility:
    """Binning and the tiled visibility pass of a draw's set-up triangles; the framebuffer's depth is updated.

    ``undo``: keep the depth it replaces (``Visibility.saved_depth``), so that
    :func:`shade_visible` can put it back if shading fails (see :func:`shading_may_fail`).
    """
    w, h, offsets = fb.width, fb.height, fb.pattern.offsets
    func = -1 if state.depth_test is None else DEPTH_FUNCS.index(state.depth_test)
    depth_write = bool(state.depth_write) and func >= 0
    vis = np.empty((len(offsets), h, w), np.int32)      # raster_tiles sets every tile to −1 first
    tiles_x, tiles_y = -(-w // TILE_W), -(-h // TILE_H)
    touched = np.zeros((tiles_y, tiles_x), np.bool_)
    if len(prims) == 0:
        vis.fill(-1)
        return Visibility(vis, setup, touched)
    starts, items = bin_triangles(setup.box, tiles_x, tiles_y)
    # the depth the pass replaces, kept (tile by tile, as each is first touched) until shading succeeded
    undo = undo and depth_write
    saved = _scratch(fb.samples_depth) if undo else np.empty((0, 0, 0), np.float32)
    in_bands(raster_tiles, tiles_x * tiles_y, setup.edges, setup.bias, setup.plane, setup.box, starts, items,
             tiles_x, w, h, offsets, func, depth_write, fb.samples_depth, vis, touched.reshape(-1), saved)
    return Visibility(vis, setup, touched, saved if undo else None)


# ------------------------------------------------------------ shading what is visible

class ShadedSamples:
    """What the fast path's shading did: the shader ran on the visible samples and wrote their color.

    Attributes
    ----------
    written : bool [S, H, W]
        The samples this draw wrote (those the :class:`Visibility` kept).
    invocations : int
        Fragment shader invocations (one per written sample; with multisampling,
        one per pixel and visible triangle).

    Both are computed when first asked for (a full-frame pass each), not by every draw. A
    depth-only draw (:func:`depth_only`, ``depth_only`` True) wrote the depth of those samples
    and ran no shader: 0 invocations.
    """

    def __init__(self, visibility: Visibility, shading: str, non_finite: Optional[NonFinite] = None,
                 depth_only: bool = False):
        self.visibility, self.shading = visibility, shading
        #: the samples written with a NaN or infinite color (:class:`~softpipe.pipeline.output.NonFinite`), or None
        self.non_finite = non_finite
        #: a depth-only draw: nothing was shaded, no color written
        self.depth_only = depth_only

    @property
    def written(self) -> np.ndarray:
        return self.visibility.vis >= 0

    @property
    def invocations(self) -> int:
        return 0 if self.depth_only else _invocations(self.visibility.vis, self.shading)

    def __repr__(self) -> str:
        if self.depth_only:
            return f"ShadedSamples({int(self.written.sum())} samples' depth written, depth only: nothing shaded)"
        return f"ShadedSamples({int(self.written.sum())} samples written, {self.invocations} shader invocations)"


class DiscardOnFastPath(Exception):
    """The fast path's shader returned a NaN alpha (DISCARD) at a visible sample.

    The reference path discards such a fragment, and then what lies behind it
    shows: only the reference path can draw that. When this is raised
    :func:`shade_visible` has put the depth back as it was before the draw, and
    the colors it wrote are ones the reference path writes over (the fragment
    the fast path shaded at a sample passes the depth test there on the
    reference path too, for every compare function but "notequal" with depth
    writes, which :func:`fast_path_blocker` keeps for shaders with a literal alpha).
    """


#: Buffers for what a draw may have to undo, kept between draws: a new one's pages cost more
#: to map (a page fault per page on first touch) than the copies made into them (benchmarks/README.md).
_SCRATCH: dict = {}
_SCRATCH_KEPT = 4


def _scratch(like: np.ndarray) -> np.ndarray:
    """A buffer shaped like ``like`` for what a draw may have to undo (only the parts used are written).

    Taken from the ones kept (each is used by one draw at a time: two draws at once get two)
    and handed back by :func:`_release`.
    """
    key = (like.shape, like.dtype.str)
    try:
        return _SCRATCH.pop(key)         # atomic under the GIL
    except KeyError:
        return np.empty_like(like)


def _release(buffer: Optional[np.ndarray]) -> None:
    """Keep a scratch buffer for the next draw of this size."""
    if buffer is None or buffer.size == 0:
        return
    _SCRATCH[(buffer.shape, buffer.dtype.str)] = buffer
    while len(_SCRATCH) > _SCRATCH_KEPT:       # the oldest size goes
        _SCRATCH.pop(next(iter(_SCRATCH)), None)


def _restore_colors(color, saved, vis, started) -> None:
    """Put back the colors of the visible samples of the rows shading started."""
    for row in np.nonzero(started)[0]:
        m = vis[:, row] >= 0
        color[:, row][m] = saved[:, row][m]


def visible_loop_args(prims: Primitives, visibility: Visibility, fb, shader: Callable, uniforms,
                      shading: str = "sample") -> tuple:
    """The arguments of the generated ``visible_loop`` after its rows (row_lo, row_hi).

    ``shading``: per "sample", or once per pixel and triangle at the pixel
    "center" or "centroid" (multisampling).
    """
    if shading not in SHADING_POSITIONS:
        raise ValueError(f"shading must be one of {SHADING_POSITIONS}, got {shading!r}")
    pattern, s = fb.pattern, visibility.setup
    return (visibility.vis, visibility.touched, TILE_W, TILE_H, s.edges, s.bias, s.plane, pattern.offsets,
            pattern.positions, SHADING_POSITIONS.index(shading), prims.inv_w, prims.varyings, prims.front_facing,
            prims.primitive_id, derivative_gradients(shader, s), uniforms, fb.samples_color,
            np.empty((0, 0, 0, 4), np.float32), np.zeros(fb.height, np.bool_), np.zeros(1 + fb.height, np.int64))


def shade_visible(prims: Primitives, visibility: Visibility, fb, fragment_shader: Optional[Callable], uniforms,
                  shading: str = "sample") -> ShadedSamples:
    """Run the shader on the samples a :class:`Visibility` kept, writing their color into ``fb``.

    If the shader raises, the framebuffer's depth and color are put back as they
    were before the visibility pass (the colors it overwrote are kept while it
    runs when :func:`~softpipe.language.kernels.may_raise` says it may raise) and the
    error is raised. If it returns a NaN alpha (DISCARD) at a visible sample,
    shading stops, that sample is not written, the depth is put back and
    :class:`DiscardOnFastPath` is raised: the caller draws again on the
    reference path, which writes every sample the fast path wrote.
    """
    saved_color = None
    try:
        if len(prims) == 0:
            return ShadedSamples(visibility, shading)
        shader = fragment_shader or default_fragment_shader(prims.layout)
        kernel = kernels.visible_kernel(shader, prims.layout, shading)
        args = visible_loop_args(prims, visibility, fb, shader, uniforms, shading)
        started, status = args[-2], args[-1]
        if _failure_modes(shader, prims.layout)[0]:
            # the colors it overwrites are kept, to put back if it raises (a NaN alpha needs no
            # colors back: the reference path then draws every sample the fast path wrote)
            saved_color = _scratch(fb.samples_color)
            args = args[:-3] + (saved_color, started, status)
        # compile (or load) once, in this thread, where errors are reported clearly
        kernels.run_compiled("fragment", shader, kernel, 0, 0, *args)

        def site():        # finding the invocation that raised re-runs the loop: on copies
            rerun = visible_loop_args(prims, visibility, fb, shader, uniforms, shading)
            rerun = rerun[:-4] + (fb.samples_color.copy(),) + rerun[-3:]
            return kernels.visible_site(shader, kernel, fb.height, rerun)()

        try:
            kernels.run_compiled("fragment", shader, lambda *a: in_bands(kernel, fb.height, *a), *args, site=site)
        except BaseException:
            if saved_color is not None:
                _restore_colors(fb.samples_color, saved_color, visibility.vis, started)
            raise
        if status[0]:
            raise DiscardOnFastPath("the fragment shader returned a NaN alpha (DISCARD) at a visible sample")
        non_finite = _non_finite_from_rows(status[1:], fb.samples_color, visibility.vis, prims.primitive_id)
    except BaseException:
        visibility.restore_depth(fb)
        _release(visibility.saved_depth)
        visibility.saved_depth = None
        raise
    finally:
        _release(saved_color)
    _release(visibility.saved_depth)
    visibility.saved_depth = None          # the draw stands: nothing to undo
    return ShadedSamples(visibility, shading, non_finite)


def _non_finite_from_rows(per_row: np.ndarray, color: np.ndarray, vis: np.ndarray,
                          primitive_id: np.ndarray) -> Optional[NonFinite]:
    """The non-finite samples the shading loop counted per image row: how many, and the first (the
    lowest row holding one, its first column)."""
    rows = np.flatnonzero(per_row)
    if not len(rows):
        return None
    row = int(rows[0])
    bad = (vis[:, row] >= 0) & ~np.isfinite(color[:, row].astype(np.float64).sum(axis=-1))
    samples, cols = np.nonzero(bad)
    k = int(np.argmin(cols))
    return NonFinite(int(per_row.sum()), int(cols[k]), row, int(primitive_id[vis[samples[k], row, cols[k]]]))


def _invocations(vis: np.ndarray, shading: str) -> int:
    """Shader invocations of visible_loop: every visible sample, or each (pixel, triangle) once."""
    if shading == "sample" or vis.shape[0] == 1:
        return int((vis >= 0).sum())
    seen = vis >= 0
    for s in range(1, vis.shape[0]):
        seen[s] &= (vis[:s] != vis[s]).all(axis=0)
    return int(seen.sum())


# ------------------------------------------------- points and lines: their own walk over the same tiles

@dataclass
class PrimitiveVisibility(Visibility):
    """The visibility pass of points or lines (:func:`primitive_visibility_pass`): which one to shade at
    each sample, as :class:`Visibility` for triangles.

    Attributes
    ----------
    vis, touched, saved_depth
        As :class:`Visibility`'s (``vis``: the line or point, a row of the Primitives, written
        last at each sample, or −1).
    setup : LineSetup or PointSetup
        The setup the pass used.
    run : uint8 [S, H, W]
        For wide lines, the place in its run (0 … w − 1) of the fragment written at each
        sample, from which its attributes (the run's first fragment's) are found; empty [0, 0, 0]
        otherwise.
    """

    run: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0), np.uint8), repr=False)

    def __repr__(self) -> str:
        kind = "lines" if isinstance(self.setup, LineSetup) else "points"
        return (f"PrimitiveVisibility({int((self.vis >= 0).sum())} visible samples of {self.vis.size}, "
                f"{len(self.setup)} {kind}, {int(self.touched.sum())} of {self.touched.size} tiles touched)")

    def fragments(self, prims: Primitives, pattern, shading: str = "sample") -> Fragments:
        """The fragments the fast path shades: one per visible sample, in primitive order, with the
        inputs the reference path's fragment there gives the shader (with multisampling at the
        centre or centroid, every sample of a pixel gets its run's first fragment's: the depth of
        its sample 0, where the reference path shades it)."""
        return _visible_primitive_fragments(self, prims, pattern, SHADING_POSITIONS.index(shading))


def primitive_visibility_pass(prims: Primitives, setup: Union[LineSetup, PointSetup], fb, state: MergeState,
                              rect: np.ndarray, undo: bool = True) -> PrimitiveVisibility:
    """The fast path's visibility pass of points or lines: binned to the triangles' tiles
    (:func:`~softpipe.pipeline.tiles.primitive_boxes`, :func:`~softpipe.pipeline.tiles.bin_primitives`),
    each tile walking its primitives in order with the early depth test (no fragment is kept);
    the framebuffer's depth is updated. ``rect`` is the scissor (:func:`~softpipe.pipeline.setup.pixel_rect`);
    ``undo`` keeps the depth it replaces, as :func:`visibility_pass`."""
    w, h, offsets = fb.width, fb.height, fb.pattern.offsets
    func = -1 if state.depth_test is None else DEPTH_FUNCS.index(state.depth_test)
    depth_write = bool(state.depth_write) and func >= 0
    vis = np.empty((len(offsets), h, w), np.int32)      # every tile is set to −1 first
    tiles_x, tiles_y = -(-w // TILE_W), -(-h // TILE_H)
    touched = np.zeros((tiles_y, tiles_x), np.bool_)
    lines = isinstance(setup, LineSetup)
    wide = isinstance(setup, LineSetup) and len(prims) > 0 and int(setup.width.max()) > 1
    run = np.empty(vis.shape if wide else (0, 0, 0), np.uint8)
    box = primitive_boxes(setup, rect)
    undo = undo and depth_write and len(prims) > 0
    saved = _scratch(fb.samples_depth) if undo else np.empty((0, 0, 0), np.float32)
    if lines:
        assert isinstance(setup, LineSetup)
        starts, items, rows = bin_primitives(box, tiles_x, tiles_y, (setup.ends, setup.width, setup.depth))
        in_bands(raster_line_tiles, tiles_x * tiles_y, *rows, starts, items, tiles_x, rect, w, h, offsets, func,
                 depth_write, fb.samples_depth, vis, run, touched.reshape(-1), saved)
    else:
        assert isinstance(setup, PointSetup)
        starts, items, rows = bin_primitives(box, tiles_x, tiles_y, (setup.centre, setup.size, setup.depth))
        in_bands(raster_point_tiles, tiles_x * tiles_y, *rows, starts, items, tiles_x, rect, w, h, offsets, func,
                 depth_write, fb.samples_depth, vis, touched.reshape(-1), saved)
    return PrimitiveVisibility(vis, setup, touched, saved if undo else None, run)  # type: ignore[arg-type]  # a line's or point's setup


@numba.njit(cache=True, nogil=True)
def _visible_by_primitive(band_lo, band_hi, bounds, vis, touched, tile_w, tile_h, places, keys, tri, fill):
    """Bands band_lo:band_hi of image rows (``bounds``): count the visible samples of each primitive
    (``fill`` False, into ``places[band]``), or put each at its primitive's next place (``fill``: its
    (row, sample, column) into ``keys`` as (row·S + sample)·W + column, its primitive into ``tri``)."""
    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]
    for band in range(band_lo, band_hi):
        at = places[band]
        for row in range(bounds[band], bounds[band + 1]):
            j = height - 1 - row
            for tile_x in range(touched.shape[1]):
                if not touched[j // tile_h, tile_x]:
                    continue
                for s in range(samples):
                    for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                        t = vis[s, row, i]
                        if t < 0:
                            continue
                        if fill:
                            k = at[t]
                            keys[k] = (row * samples + s) * width + i
                            tri[k] = t
                        at[t] += 1


@numba.njit(cache=True, nogil=True, forceinline=True)
def _key_place(key, width, samples):
    """(row, sample, column) of a sorted visible sample's key, (row·S + sample)·W + column."""
    return key // (width * samples), (key // width) % samples, key % width


@numba.njit(cache=True, nogil=True)
def _line_inputs(lo, hi, keys, tri, run, samples, width, height, ends, zends, offsets, positions, mode, depth, bary,
                 fx, fy):
    """The shader's inputs at the visible samples lo:hi (``keys``, ``tri``: :func:`_visible_by_primitive`) of
    lines: depth, barycentrics and window position, as the reference path's fragments have them."""
    means = sample_means(offsets, positions)
    for k in range(lo, hi):
        t = tri[k]
        row, s, i = _key_place(keys[k], width, samples)
        bary[k, 0], bary[k, 1], bary[k, 2], fx[k], fy[k], depth[k] = line_sample_inputs(
            ends, zends, run, t, i, height - 1 - row, s, row, offsets, positions, mode, means)


@numba.njit(cache=True, nogil=True)
def _point_inputs(lo, hi, keys, tri, samples, width, height, centre, size, zpoint, offsets, positions, mode, depth,
                  bary, fx, fy):
    """The shader's inputs at the visible samples lo:hi (``keys``, ``tri``: :func:`_visible_by_primitive`) of
    points."""
    means = sample_means(offsets, positions)
    for k in range(lo, hi):
        t = tri[k]
        row, s, i = _key_place(keys[k], width, samples)
        bary[k, 0], bary[k, 1], bary[k, 2], fx[k], fy[k], depth[k] = point_sample_inputs(
            centre, size, zpoint, t, i, height - 1 - row, s, positions, mode, means)


#: Buffers of the points' and lines' shading (its sorted samples and the shader's inputs and colors), kept
#: between draws as the depth saved for an undo is (:func:`_scratch`): a cloud's 400,000 visible samples take
#: 30 MB, whose first touch (a page fault a page) cost more than making them.
_POOL: dict = {}


def _pooled(name: str, n: int, dtype, *shape) -> np.ndarray:
    """An array [n, *shape] of ``dtype`` from the pool (taken: a draw at the same time gets its own)."""
    buffer = _POOL.pop(name, None)           # atomic under the GIL
    if buffer is None or len(buffer) < n or buffer.dtype != dtype or buffer.shape[1:] != shape:
        buffer = np.empty((max(n, 1024),) + shape, dtype)
    return buffer


def _return_pooled(**buffers) -> None:
    """Hand buffers back to the pool (the larger of two of a name kept)."""
    for name, buffer in buffers.items():
        kept = _POOL.get(name)
        if kept is None or len(kept) <= len(buffer):
            _POOL[name] = buffer


def _sorted_samples(visibility: PrimitiveVisibility, n_prims: int, pooled: bool) -> Tuple[np.ndarray, np.ndarray]:
    """The visible samples sorted by primitive: (keys, tri), each sample's (row·S + sample)·W + column and
    its primitive.

    In primitive order, because shading reads each primitive's varyings: in the order of the
    screen a cloud's points come in no order at all, and every fragment's varyings were a
    cache miss (shading took 10 times longer). A counting sort in bands of image rows (as
    :func:`~softpipe.pipeline.tiles.bin_triangles`: each band counts per primitive, a prefix sum
    over (primitive, band) gives each band its places), so a primitive's samples are in
    (image row, tile, sample, column) order on any thread count.
    """
    vis, touched = visibility.vis, visibility.touched
    height = vis.shape[1]
    bands = max(1, min(threads(), height // 16))
    bounds = np.linspace(0, height, bands + 1).astype(np.int64)
    # 32-bit places where every sample's fits (a smaller table, more of it in the cache: the sort 25 % faster)
    places_type = np.int32 if vis.size < 2**31 else np.int64
    places = np.zeros((bands, n_prims), places_type)
    keys, tri = np.empty(0, np.int64), np.empty(0, np.int32)
    if touched.any() and n_prims:
        in_bands(_visible_by_primitive, bands, bounds, vis, touched, TILE_W, TILE_H, places, keys, tri, False)
    running = np.zeros(places.size + 1, np.int64)
    np.cumsum(places.T.ravel(), out=running[1:])
    n = int(running[-1])
    if not n:
        return keys, tri
    places = running[:-1].reshape(n_prims, bands).T.astype(places_type)
    keys = _pooled("keys", n, np.int64)[:n] if pooled else np.empty(n, np.int64)
    tri = _pooled("tri", n, np.int32)[:n] if pooled else np.empty(n, np.int32)
    in_bands(_visible_by_primitive, bands, bounds, vis, touched, TILE_W, TILE_H, places, keys, tri, True)
    return keys, tri


def _shader_inputs(visibility: PrimitiveVisibility, keys, tri, pattern, mode: int, depth, bary, fx, fy) -> None:
    """The shader's inputs at the sorted samples (:func:`_sorted_samples`), in bands."""
    setup, (samples, height, width) = visibility.setup, visibility.vis.shape
    if isinstance(setup, LineSetup):
        in_bands(_line_inputs, len(keys), keys, tri, visibility.run, samples, width, height, setup.ends, setup.depth,
                 pattern.offsets, pattern.positions, mode, depth, bary, fx, fy, grain=16384)
    else:
        assert isinstance(setup, PointSetup)
        in_bands(_point_inputs, len(keys), keys, tri, samples, width, height, setup.centre, setup.size, setup.depth,
                 pattern.offsets, pattern.positions, mode, depth, bary, fx, fy, grain=16384)


def _decode(keys: np.ndarray, shape) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(column, image row, sample) of sorted samples' keys, int32 each."""
    samples, _, width = shape
    return ((keys % width).astype(np.int32), (keys // (width * samples)).astype(np.int32),
            ((keys // width) % samples).astype(np.int32))


def _visible_primitive_fragments(visibility: PrimitiveVisibility, prims: Primitives, pattern, mode: int) -> Fragments:
    """:meth:`PrimitiveVisibility.fragments`: the visible samples sorted by primitive, made into fragments."""
    keys, tri = _sorted_samples(visibility, len(prims), pooled=False)
    n = len(keys)
    depth, bary, fx, fy = np.empty(n), np.empty((n, 3)), np.empty(n), np.empty(n)
    if n:
        _shader_inputs(visibility, keys, tri, pattern, mode, depth, bary, fx, fy)
    x, y, sample = _decode(keys, visibility.vis.shape)
    return Fragments(x, y, sample, depth, bary, tri, prims.primitive_id[tri], fx, fy, visibility.setup)


@numba.njit(cache=True)
def _write_kept(x, y, s, color, fb_color):
    """Write the fragments' colors at their samples; returns how many are not finite."""
    bad = 0
    for k in range(x.shape[0]):
        total = 0.0
        for c in range(4):
            fb_color[s[k], y[k], x[k], c] = color[k, c]
            total += np.float64(color[k, c])
        if not (total - total == 0.0):
            bad += 1
    return bad


@numba.njit(cache=True, nogil=True)
def _write_by_keys(lo, hi, keys, color, samples, height, width, fb_color, bad):
    """Write the colors of sorted samples lo:hi (:func:`_sorted_samples`); bad[lo] counts those not finite."""
    n = 0
    for k in range(lo, hi):
        key = keys[k]
        i, s, row = key % width, (key // width) % samples, key // (width * samples)
        total = 0.0
        for c in range(4):
            fb_color[s, row, i, c] = color[k, c]
            total += np.float64(color[k, c])
        if not (total - total == 0.0):
            n += 1
    bad[lo] = n


def _shade_in_place(prims: Primitives, visibility: PrimitiveVisibility, fb, shader: Callable, uniforms, mode: int,
                    keys: np.ndarray, tri: np.ndarray) -> Optional[NonFinite]:
    """Shade the sorted visible samples (:func:`_sorted_samples`) with ``primitive_loop``
    (:func:`~softpipe.language.kernels.primitive_kernel`), which computes each sample's inputs where it
    shades it and writes its color into ``fb`` at once: for a shader proved not to fail
    (:func:`_failure_modes`), which leaves nothing to put back. Making the inputs into arrays, the colors
    into another and then writing them took most of the points' and lines' shading. Returns the
    non-finite colors written, as :func:`shade_primitives` names them."""
    setup = visibility.setup
    shape = visibility.vis.shape
    if isinstance(setup, LineSetup):
        kind, arrays, run = "lines", (setup.ends, setup.width, setup.depth), visibility.run
    else:
        assert isinstance(setup, PointSetup)
        kind, arrays, run = "points", (setup.centre, setup.size, setup.depth), np.zeros((0, 0, 0), np.uint8)
    kernel = kernels.primitive_kernel(shader, prims.layout, kind)
    n = len(keys)
    bad = np.zeros(n + 1, np.int64)
    args = (keys, tri, run, *arrays, fb.pattern.offsets, fb.pattern.positions, mode, prims.inv_w, prims.varyings,
            prims.front_facing, prims.primitive_id, derivative_gradients(shader, setup), uniforms,
            fb.samples_color, bad)
    # compile (or load) once, in this thread, where errors are reported clearly
    kernels.run_compiled("fragment", shader, kernel, 0, 0, *args)
    kernels.run_compiled("fragment", shader, lambda *a: in_bands(kernel, n, *a, grain=SHADE_GRAIN // 4), *args)
    if not bad.any():
        return None
    x, y, s = _decode(keys, shape)
    wrong = np.flatnonzero(~np.isfinite(fb.samples_color[s, y, x]).all(axis=1))
    first = int(wrong[np.lexsort((x[wrong], y[wrong]))[0]])     # the lowest image row, then column
    return NonFinite(len(wrong), int(x[first]), int(y[first]), int(prims.primitive_id[tri[first]]))


#: Fragments a band of the points' and lines' shading holds at least (a band costs a call of the
#: compiled loop from Python, some microseconds).
SHADE_GRAIN = 65536


def _shade_band(lo, hi, kernel, args) -> None:
    """The fragment loop over fragments lo:hi (a band of :func:`shade_primitives`, on a helper thread: the
    loop is compiled with nogil)."""
    kernel(*(a[lo:hi] for a in args[:5]), *args[5:-1], args[-1][lo:hi])


def shade_primitives(prims: Primitives, visibility: PrimitiveVisibility, fb, fragment_shader: Optional[Callable],
                     uniforms, shading: str = "sample") -> ShadedSamples:
    """Run the shader on the samples a :class:`PrimitiveVisibility` kept and write their color into ``fb``.

    The visible samples, sorted by primitive (:func:`_sorted_samples`), get the inputs the
    reference path's fragments there give the shader (the same as
    :meth:`PrimitiveVisibility.fragments`) and are shaded by the reference path's loop
    (``fragment_loop``) in bands on the helper threads; nothing is written before every one is
    shaded. A shader proved not to fail (:func:`_failure_modes`) is run by ``primitive_loop`` instead
    (:func:`_shade_in_place`), which makes each sample's inputs where it shades it and writes its
    color at once: the same bytes, with no arrays of inputs or colors. As :func:`shade_visible`: a shader that raises has the depth put back and nothing
    written; a NaN alpha (DISCARD) at a visible sample raises :class:`DiscardOnFastPath` with the
    depth put back. With multisampling at the centre or centroid each visible sample is shaded
    with its pixel's inputs, so it gets the color the reference path copies to it.
    """
    shape = visibility.vis.shape
    buffers: dict = {}
    try:
        shader = fragment_shader or default_fragment_shader(prims.layout)
        keys, tri = _sorted_samples(visibility, len(prims), pooled=True)
        if len(keys) and not any(_failure_modes(shader, prims.layout)):
            buffers = dict(keys=keys.base, tri=tri.base)
            non_finite = _shade_in_place(prims, visibility, fb, shader, uniforms, SHADING_POSITIONS.index(shading),
                                         keys, tri)
            _release(visibility.saved_depth)
            visibility.saved_depth = None          # the draw stands: nothing to undo
            return ShadedSamples(visibility, shading, non_finite)
        n = len(keys)
        if n:
            buffers = dict(keys=keys.base, tri=tri.base, depth=_pooled("depth", n, np.float64),
                           bary=_pooled("bary", n, np.float64, 3), fx=_pooled("fx", n, np.float64),
                           fy=_pooled("fy", n, np.float64), color=_pooled("color", n, np.float32, 4))
        color = buffers["color"][:n] if n else np.empty((0, 4), np.float32)
        if n:
            depth, bary, fx, fy = (buffers[k][:n] for k in ("depth", "bary", "fx", "fy"))
            _shader_inputs(visibility, keys, tri, fb.pattern, SHADING_POSITIONS.index(shading), depth, bary, fx, fy)
            kernel = kernels.fragment_kernel(shader, prims.layout)
            args = (tri, fx, fy, depth, bary, prims.inv_w, prims.varyings, prims.front_facing, prims.primitive_id,
                    derivative_gradients(shader, visibility.setup), uniforms, color)
            # compile (or load) once, in this thread, where errors are reported clearly
            kernels.run_compiled("fragment", shader, kernel, *(a[:0] for a in args[:5]), *args[5:-1], color[:0])

            def site():        # which fragment raised: the shading again, on copies, one by one
                return kernels.fragment_site(shader, kernel, args[:-1] + (color.copy(),), *_decode(keys, shape))()

            kernels.run_compiled("fragment", shader, lambda *a: in_bands(_shade_band, n, kernel, a,
                                                                         grain=SHADE_GRAIN), *args, site=site)
        if np.isnan(color[:, 3]).any():
            raise DiscardOnFastPath("the fragment shader returned a NaN alpha (DISCARD) at a visible sample")
        bad = np.zeros(n + 1, np.int64)
        non_finite = None
        if n:
            in_bands(_write_by_keys, n, keys, color, *shape, fb.samples_color, bad, grain=65536)
        if bad.any():
            wrong = np.flatnonzero(~np.isfinite(color).all(axis=1))
            x, y, _ = _decode(keys[wrong], shape)
            first = int(np.lexsort((x, y))[0])          # the lowest image row, then column
            non_finite = NonFinite(len(wrong), int(x[first]), int(y[first]),
                                   int(prims.primitive_id[tri[wrong[first]]]))
    except BaseException:
        visibility.restore_depth(fb)
        _release(visibility.saved_depth)
        visibility.saved_depth = None
        raise
    finally:
        _return_pooled(**buffers)
    _release(visibility.saved_depth)
    visibility.saved_depth = None              # the draw stands: nothing to undo
    return ShadedSamples(visibility, shading, non_finite)


# ------------------------------------------------- several color attachments (multiple render targets)

def shade_outputs(prims: Primitives, visibility, fb, fragment_shader: Optional[Callable], uniforms,
                  shading: str = "sample") -> ShadedSamples:
    """The fast path into a framebuffer of several attachments: the shader once per visible sample, its
    values written into every attachment.

    The visible samples are made into fragments (:meth:`Visibility.fragments`, or
    :meth:`PrimitiveVisibility.fragments` for points and lines), with the barycentrics, depth and position the reference path's
    fragment gives the shader there (at the pixel's shading point with multisampling, so every
    sample of a pixel gets the value the reference path copies to them), and shaded by the same
    loop as the reference path's (``fragment_loop_outputs``); nothing is written before every one
    is shaded. A shader that raises, or returns DISCARD first (:class:`DiscardOnFastPath`), has the
    depth put back, as :func:`shade_visible`.
    """
    attachments = tuple(fb.attachments.items())
    try:
        frags = visibility.fragments(prims, fb.pattern, shading)
        if shading != "sample" and isinstance(visibility, Visibility) and fb.samples > 1:
            # multisampling: once per pixel and triangle (every sample of it has the same inputs), as the
            # reference path and visible_loop shade, the values copied to its other samples
            key = (frags.triangle.astype(np.int64) * fb.height + frags.y) * fb.width + frags.x
            _, heads, copy = np.unique(key, return_index=True, return_inverse=True)
            once = run_fragment_stage(frags.take(heads), prims, fragment_shader, uniforms, "sample", attachments)
            copy = copy.reshape(-1)
            shaded = ShadedFragments(once.color[copy], once.discarded[copy], len(heads),
                                     tuple(a[copy] for a in once.outputs))
        else:
            shaded = run_fragment_stage(frags, prims, fragment_shader, uniforms, "sample", attachments)
        if shaded.discarded.any():
            raise DiscardOnFastPath("the fragment shader returned DISCARD (a NaN alpha) at a visible sample")
    except BaseException:
        visibility.restore_depth(fb)
        if isinstance(visibility, Visibility):       # its saved depth is a scratch buffer to hand back
            _release(visibility.saved_depth)
        visibility.saved_depth = None
        raise
    if isinstance(visibility, Visibility):
        _release(visibility.saved_depth)
    visibility.saved_depth = None
    non_finite = None
    if _write_kept(frags.x, frags.y, frags.sample, shaded.color, fb.samples_color):
        bad = np.flatnonzero(~np.isfinite(shaded.color).all(axis=1))
        first = int(bad[np.lexsort((frags.x[bad], frags.y[bad]))[0]])
        non_finite = NonFinite(len(bad), int(frags.x[first]), int(frags.y[first]), int(frags.primitive_id[first]))
    for (name, _), values in zip(attachments[1:], shaded.outputs):
        fb.samples_attachment(name)[frags.sample, frags.y, frags.x] = values
    return ShadedSamples(visibility, shading, non_finite)
