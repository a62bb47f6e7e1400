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
4. **Several attachments** (:func:`shade_outputs`): the visible samples made into fragments
   and shaded by the reference path's loop, their values written into every attachment.

Points and lines take the same design on the same tiles, in
:mod:`softpipe.pipeline.primitive_visibility`; the decision above is theirs too.

The bytes are the reference's (tests/test_fast_path.py, test_fast_path_sound.py,
test_properties.py hold them so); docs/08-fast-path.md walks through it and says why.
"""
from __future__ import annotations

import dis
import inspect
import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.language import kernels
from softpipe.language.contract import python_function
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.fragment import (
    ShadedFragments,
    default_fragment_shader,
    derivative_gradients,
    run_fragment_stage,
)
from softpipe.pipeline.merge_state import DEPTH_FUNCS, MergeState
from softpipe.pipeline.output import NonFinite
from softpipe.pipeline.raster import Fragments
from softpipe.pipeline.setup import (
    SHADE_SAMPLE,
    SHADING_POSITIONS,
    TriangleSetup,
    pixel_coverage,
    sample_depth,
    shading_point,
)
from softpipe.pipeline.tiles import TILE_H, TILE_W, bin_triangles, gather_setup, raster_tiles, scattered

__all__ = ["Visibility", "ShadedSamples", "visibility_pass", "record_visible", "shade_visible", "choose_path", "fast_path_blocker",
           "PATHS", "FAST_PATH_MIN_SAMPLES", "DiscardOnFastPath", "shading_may_fail",
           "visible_loop_args", "shade_outputs", "depth_only", "constant_color", "failure_modes",
           "scratch_buffer", "release_scratch", "pass_buffers"]

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
    primitive (points and lines have a visibility pass of their own,
    :func:`~softpipe.pipeline.primitive_visibility.primitive_visibility_pass`).
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

    def undo(self, fb) -> None:
        """The draw failed: put back the depth the pass replaced, and hand its copy back (:meth:`keep`)."""
        self.restore_depth(fb)
        self.keep()

    def keep(self) -> None:
        """The draw stands: nothing to undo, so the saved depth's buffer goes back for the next draw."""
        release_scratch(self.saved_depth)
        self.saved_depth = None

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
        shader (with multisampling at the centre or centroid, those of the pixel's
        shading point, and the depth of the first sample the triangle covers there).
        (The fragments that lost the depth test were never made.)
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
    """Each visible sample's shader inputs; with multisampling at the centre or centroid, the depth is
    that of the first sample the triangle covers in the pixel (visible or not), as the reference
    path's run of the pixel's samples and ``visible_loop`` give the shader."""
    for k in range(s_idx.shape[0]):
        s, i, j, t = s_idx[k], cols[k], height - 1 - rows[k], tri[k]
        mask, depth_sample, count = np.int64(0), s, 1
        if mode != SHADE_SAMPLE:
            mask, depth_sample, count = pixel_coverage(edges, bias, t, i, j, offsets)
        b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets, positions, mode)
        depth[k] = sample_depth(edges, plane, t, i, j, depth_sample, offsets)
        bary[k, 0], bary[k, 1], bary[k, 2] = b0, b1, b2
        pos[0, k], pos[1, k] = fx, fy


def shading_may_fail(fragment_shader: Optional[Callable], layout) -> bool:
    """Can shading on the fast path fail, raising or returning a NaN alpha? (False is a proof.)

    False for a shader that cannot raise (:func:`~softpipe.language.kernels.may_raise`) and
    returns a finite literal alpha (:func:`~softpipe.language.kernels.alpha_is_finite`), such
    as the default shader of an RGB ``color``: its draw keeps nothing to undo.
    """
    may_raise, may_nan = failure_modes(fragment_shader or default_fragment_shader(layout), layout)
    return may_raise or may_nan


def failure_modes(shader: Callable, layout) -> Tuple[bool, bool]:
    """(may it raise, may its alpha be NaN), read from its code once per compiled loop (the loop is
    kept per shader, layout and values of the globals it reads, helpers included)."""
    module = kernels.fragment_module(shader, layout)
    modes = getattr(module, "_softpipe_failure_modes", None)
    if modes is None:
        modes = module._softpipe_failure_modes = (kernels.may_raise(shader), not kernels.alpha_is_finite(shader))  # type: ignore[attr-defined]  # kept on the module
    return modes


def pass_buffers(fb, state: MergeState) -> Tuple[int, bool, np.ndarray, int, int, np.ndarray]:
    """What a visibility pass starts from, for any kind of primitive: (depth compare code, or −1 for no
    depth test; whether it writes depth; ``vis`` int32 [S, H, W], unset: each tile's walk sets its own
    part to −1 first; tiles_x, tiles_y; ``touched`` bool [tiles_y, tiles_x], all False)."""
    func = -1 if state.depth_test is None else DEPTH_FUNCS.index(state.depth_test)
    depth_write = bool(state.depth_write) and func >= 0
    vis = np.empty((len(fb.pattern.offsets), fb.height, fb.width), np.int32)
    tiles_x, tiles_y = -(-fb.width // TILE_W), -(-fb.height // TILE_H)
    return func, depth_write, vis, tiles_x, tiles_y, np.zeros((tiles_y, tiles_x), np.bool_)


def visibility_pass(prims: Primitives, setup: TriangleSetup, fb, state: MergeState,
                    undo: bool = True) -> Visibility:
    """Binning and the tiled visibility pass of a draw's set-up triangles; the framebuffer's depth is updated.

    ``undo``: keep the depth it replaces (``Visibility.saved_depth``), so that
    :func:`shade_visible` can put it back if shading fails (see :func:`shading_may_fail`).
    """
    w, h, offsets = fb.width, fb.height, fb.pattern.offsets
    func, depth_write, vis, tiles_x, tiles_y, touched = pass_buffers(fb, state)
    if len(prims) == 0:
        vis.fill(-1)
        return Visibility(vis, setup, touched)
    starts, items = bin_triangles(setup.box, tiles_x, tiles_y)
    # a mesh far from the screen's order has its setup copied in the bins' order, read in one sweep per tile
    gathered = scattered(items)
    rows = (gather_setup(setup.edges, setup.bias, setup.plane, setup.box, items) if gathered
            else (setup.edges, setup.bias, setup.plane, setup.box))
    # the depth the pass replaces, kept (tile by tile, as each is first touched) until shading succeeded
    undo = undo and depth_write
    saved = scratch_buffer(fb.samples_depth) if undo else np.empty((0, 0, 0), np.float32)
    in_bands(raster_tiles, tiles_x * tiles_y, *rows, starts, items, gathered, tiles_x, w, h, offsets, func, depth_write,
             fb.samples_depth, vis, touched.reshape(-1), saved)
    return Visibility(vis, setup, touched, saved if undo else None)


# ------------------------------------------------------------------ the visibility record

def record_visible(fb, visibility: Visibility, record_ids: np.ndarray, state: MergeState) -> None:
    """The fast path's record write: at every sample where ``visibility.vis`` (int32 [S, H, W], the row
    of the Primitives written last there, or −1) names a primitive, the framebuffer's visibility record
    holds its ``record_ids`` entry, as the merger stores it where it writes the depth (so only with the
    depth test on and depth writes on). Nothing without a record.

    The framebuffer stores them when the record is next read or written
    (:meth:`~softpipe.pipeline.framebuffer.Framebuffer.defer_visible`): a frame of one draw whose record
    is read only by the derived buffers never stores them, which read ``vis`` itself (the store took
    ~0.3–0.45 ms of a 13 ms bunny frame at 1024²: benchmarks/README.md, "Outputs, round 7")."""
    if not fb.has_record or state.depth_test is None or not state.depth_write:
        return
    fb.defer_visible(visibility.vis, visibility.touched, TILE_W, TILE_H, np.ascontiguousarray(record_ids, np.int32))


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


def scratch_buffer(like: np.ndarray) -> np.ndarray:
    """A buffer shaped like ``like`` for what a draw may have to undo (only the parts used are written).

    Taken from the ones kept (each is used by one draw at a time: two draws at once get two)
    and handed back by :func:`release_scratch`.
    """
    key = (like.shape, like.dtype.str)
    try:
        return _SCRATCH.pop(key)         # atomic under the GIL
    except KeyError:
        return np.empty_like(like)


def release_scratch(buffer: Optional[np.ndarray]) -> None:
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
        if failure_modes(shader, prims.layout)[0]:
            # the colors it overwrites are kept, to put back if it raises (a NaN alpha needs no
            # colors back: the reference path then draws every sample the fast path wrote)
            saved_color = scratch_buffer(fb.samples_color)
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
        visibility.undo(fb)
        raise
    finally:
        release_scratch(saved_color)
    visibility.keep()
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


# ------------------------------------------------- several color attachments (multiple render targets)

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


def shade_outputs(prims: Primitives, visibility, fb, fragment_shader: Optional[Callable], uniforms,
                  shading: str = "sample") -> ShadedSamples:
    """The fast path into a framebuffer of several attachments: the shader once per visible sample, its
    values written into every attachment.

    The visible samples are made into fragments (:meth:`Visibility.fragments`, or, for points and
    lines, :meth:`~softpipe.pipeline.primitive_visibility.PrimitiveVisibility.fragments`), with the
    barycentrics, depth and position the reference path's
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
        visibility.undo(fb)
        raise
    visibility.keep()
    non_finite = None
    if _write_kept(frags.x, frags.y, frags.sample, shaded.color, fb.samples_color):
        bad = np.flatnonzero(~np.isfinite(shaded.color).all(axis=1))
        first = int(bad[np.lexsort((frags.x[bad], frags.y[bad]))[0]])
        non_finite = NonFinite(len(bad), int(frags.x[first]), int(frags.y[first]), int(frags.primitive_id[first]))
    for (name, _), values in zip(attachments[1:], shaded.outputs):
        fb.samples_attachment(name)[frags.sample, frags.y, frags.x] = values
    return ShadedSamples(visibility, shading, non_finite)
