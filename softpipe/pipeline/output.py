"""Stage 5: the output merger — GL's per-fragment operations, in primitive order, per sample.

For each fragment, in the order the rasterizer produced them (primitive order),
at its sample of the framebuffer, GL's chain (:mod:`softpipe.pipeline.merge_state`
holds the state, by GL's names):

1. a discarded fragment does nothing;
2. the **scissor** test: outside the rectangle, the fragment stops;
3. the **multisample** operations (a framebuffer with more than one sample):
   alpha to coverage, then the sample mask; a sample they leave out stops;
4. the **stencil** test, with the front or back face's state: ``(ref & mask) OP
   (stored & mask)``; a failing fragment applies the ``fail`` op and stops;
5. the **depth** test compares the fragment's depth (as float32, the buffer's type;
   clamped to [0, 1] first with depth clamp) with the stored one; a failing fragment
   applies the stencil's ``depth_fail`` op and stops; a passing one applies
   ``depth_pass`` and, with depth writes on, stores its depth;
6. **blending**: ``src·F_src ∘ dst·F_dst`` per channel with the equation ∘ (GL's
   FUNC_ADD, FUNC_SUBTRACT, …, MIN, MAX), RGB and alpha each with their own factors
   and equation; or the color replaces the stored one when blending is off;
7. the **color mask**: only the unmasked channels are written.

The buffers hold floats, so nothing is clamped (GL clamps only fixed-point
buffers); sRGB encoding happens where the colors become bytes
(:meth:`~softpipe.pipeline.framebuffer.Framebuffer.to_uint8`). Each fragment's
verdict is recorded (:data:`VERDICTS`: which step stopped it) so a trace can say
what happened to it, and the samples that passed every test are counted
(:class:`OcclusionQuery`). A framebuffer with a visibility record
(``Framebuffer(..., record=True)``) gets one more store where a fragment writes the depth:
which draw, instance and source primitive it came from (the fast path has its own,
:func:`softpipe.pipeline.visibility.record_visible`;
docs/outputs.md).

A framebuffer of several color attachments (multiple render targets) gets each other
attachment's value where location 0's was written: through that attachment's own blending
and color mask (:class:`~softpipe.pipeline.merge_state.AttachmentState`, GL's
``glBlendFunci`` / ``glColorMaski``), in fragment order (:func:`merge_more`); integer
attachments are never blended.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numba
import numpy as np

from softpipe.pipeline.fragment import ShadedFragments
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.merge_state import (
    ST_ALPHA_TO_COVERAGE,
    ST_BLEND,
    ST_COLOR_MASK,
    ST_DEPTH_CLAMP,
    ST_DEPTH_FUNC,
    ST_DEPTH_WRITE,
    ST_DST_ALPHA,
    ST_DST_RGB,
    ST_EQUATION_ALPHA,
    ST_EQUATION_RGB,
    ST_SAMPLE_MASK,
    ST_SCISSOR,
    ST_SRC_ALPHA,
    ST_SRC_RGB,
    ST_STENCIL,
    ST_STENCIL_BACK,
    ST_STENCIL_FRONT,
    AttachmentState,
    MergeState,
)
from softpipe.pipeline.raster import Fragments

__all__ = ["MergeResult", "merge", "VERDICTS", "depth_passes", "compare", "stencil_op", "blend_factor",
           "blend_channel", "covered_by_alpha", "OcclusionQuery", "NonFiniteColorWarning", "NonFinite",
           "non_finite_written", "merge_more"]

#: What the merger did with a fragment: its index in this tuple is stored per fragment
#: (the step of the chain that stopped it, or "written": it passed every test).
VERDICTS = ("written", "depth-failed", "discarded", "scissored", "stencil-failed", "sample-masked")
WRITTEN, DEPTH_FAILED, DISCARDED, SCISSORED, STENCIL_FAILED, SAMPLE_MASKED = 0, 1, 2, 3, 4, 5


@numba.njit(cache=True)
def compare(func, a, b):
    """GL's compare function ``a OP b`` (codes as in :data:`~softpipe.pipeline.merge_state.COMPARE_FUNCS`)."""
    if func == 0:
        return False
    if func == 1:
        return a < b
    if func == 2:
        return a == b
    if func == 3:
        return a <= b
    if func == 4:
        return a > b
    if func == 5:
        return a != b
    if func == 6:
        return a >= b
    return True


@numba.njit(cache=True)
def depth_passes(func, z, stored):
    """The depth test: ``z OP stored`` (codes as in DEPTH_FUNCS)."""
    return compare(func, z, stored)


@numba.njit(cache=True)
def stencil_op(op, stored, ref):
    """The new stencil value by GL's op (codes as in STENCIL_OPS), before the write mask; 8 bits."""
    if op == 0:
        return stored
    if op == 1:
        return 0
    if op == 2:
        return ref
    if op == 3:
        return min(stored + 1, 255)
    if op == 4:
        return (stored + 1) & 255
    if op == 5:
        return max(stored - 1, 0)
    if op == 6:
        return (stored - 1) & 255
    return (~stored) & 255


@numba.njit(cache=True)
def blend_factor(code, c, src, dst, src_alpha, dst_alpha, constant, constant_alpha):
    """One blend factor for channel ``c`` (0..3) (codes as in BLEND_FACTORS): ``src`` and ``dst``
    are that channel's values, ``constant`` the blend color's that channel, ``constant_alpha`` its alpha."""
    if code == 0:
        return 0.0
    if code == 1:
        return 1.0
    if code == 2:
        return src
    if code == 3:
        return 1.0 - src
    if code == 4:
        return dst
    if code == 5:
        return 1.0 - dst
    if code == 6:
        return src_alpha
    if code == 7:
        return 1.0 - src_alpha
    if code == 8:
        return dst_alpha
    if code == 9:
        return 1.0 - dst_alpha
    if code == 10:
        return constant
    if code == 11:
        return 1.0 - constant
    if code == 12:
        return constant_alpha
    if code == 13:
        return 1.0 - constant_alpha
    return min(src_alpha, 1.0 - dst_alpha) if c < 3 else 1.0      # src_alpha_saturate


@numba.njit(cache=True)
def blend_channel(equation, src_f, dst_f, c, src, dst, src_alpha, dst_alpha, constant, constant_alpha):
    """One channel blended (float64, so that numba and plain Python agree): GL's equation
    (codes as in BLEND_EQUATIONS) of ``src·F_src`` and ``dst·F_dst``."""
    if equation == 3:
        return min(src, dst)
    if equation == 4:
        return max(src, dst)
    s = src * blend_factor(src_f, c, src, dst, src_alpha, dst_alpha, constant, constant_alpha)
    d = dst * blend_factor(dst_f, c, src, dst, src_alpha, dst_alpha, constant, constant_alpha)
    if equation == 1:
        return s - d
    if equation == 2:
        return d - s
    return s + d


@numba.njit(cache=True)
def covered_by_alpha(alpha, sample, samples):
    """Alpha to coverage: does a fragment of this alpha cover ``sample`` of its pixel's ``samples``?
    It covers the samples m < round(clamp(alpha, 0, 1)·samples) (half to even; NaN covers none)."""
    if not alpha > 0.0:
        return False
    return sample < np.rint(min(alpha, 1.0) * samples)


@numba.njit(cache=True)
def _merge_kernel(x, y, s, depth, color, discarded, prim, front_facing, st, blend_color, fb_color, fb_depth,
                  fb_stencil, verdict, after, stencil_after, ids, fb_record):
    # The state read once into scalars: branches on them are the same for every fragment, and a
    # value in a register costs nothing per fragment (a read of ``st`` would be a load each time).
    scissor, x0, x1, y0, y1 = st[ST_SCISSOR], st[ST_SCISSOR + 1], st[ST_SCISSOR + 2], st[ST_SCISSOR + 3], \
        st[ST_SCISSOR + 4]
    samples = fb_color.shape[0]
    coverage = samples > 1 and (st[ST_ALPHA_TO_COVERAGE] != 0 or (st[ST_SAMPLE_MASK] & ((1 << samples) - 1))
                                != (1 << samples) - 1)
    stencil_on, two_sided = st[ST_STENCIL] != 0, front_facing.shape[0] > 0
    func, depth_write, clamp = st[ST_DEPTH_FUNC], st[ST_DEPTH_WRITE] != 0, st[ST_DEPTH_CLAMP] != 0
    blend = st[ST_BLEND] != 0
    eq_rgb, src_rgb, dst_rgb = st[ST_EQUATION_RGB], st[ST_SRC_RGB], st[ST_DST_RGB]
    eq_a, src_a, dst_a = st[ST_EQUATION_ALPHA], st[ST_SRC_ALPHA], st[ST_DST_ALPHA]
    const_r, const_g, const_b, const_a = blend_color[0], blend_color[1], blend_color[2], blend_color[3]
    mask_r, mask_g, mask_b, mask_a = (st[ST_COLOR_MASK] != 0, st[ST_COLOR_MASK + 1] != 0, st[ST_COLOR_MASK + 2] != 0,
                                      st[ST_COLOR_MASK + 3] != 0)
    record = after.shape[0] > 0
    keep_ids = fb_record.shape[0] > 0      # the framebuffer's visibility record: one store where the depth is
    for k in range(x.shape[0]):
        i, j, m = x[k], y[k], s[k]
        verdict[k] = WRITTEN
        if discarded[k]:
            verdict[k] = DISCARDED
        elif scissor and not (x0 <= i < x1 and y0 <= j < y1):
            verdict[k] = SCISSORED
        elif coverage and not _covers(st, color[k, 3], m, samples):
            verdict[k] = SAMPLE_MASKED
        else:
            face = ST_STENCIL_BACK if two_sided and not front_facing[prim[k]] else ST_STENCIL_FRONT
            stored = np.int64(fb_stencil[m, j, i]) if stencil_on else np.int64(0)
            if stencil_on and not compare(st[face], st[face + 1] & st[face + 2], stored & st[face + 2]):
                _write_stencil(fb_stencil, m, j, i, st, face, st[face + 3], stored)
                verdict[k] = STENCIL_FAILED
            else:
                z = np.float32(depth[k])
                if clamp:
                    z = min(max(z, np.float32(0.0)), np.float32(1.0))
                if func >= 0 and not depth_passes(func, z, fb_depth[m, j, i]):
                    if stencil_on:
                        _write_stencil(fb_stencil, m, j, i, st, face, st[face + 4], stored)
                    verdict[k] = DEPTH_FAILED
                else:
                    if func >= 0 and depth_write:
                        fb_depth[m, j, i] = z
                        if keep_ids:
                            fb_record[m, j, i] = ids[prim[k]]
                    if stencil_on:
                        _write_stencil(fb_stencil, m, j, i, st, face, st[face + 5], stored)
                    if not blend:
                        r, g, b, a = color[k, 0], color[k, 1], color[k, 2], color[k, 3]
                    else:
                        # float64 explicitly: numba and plain Python (NumPy keeps float32 scalars) then agree
                        sa, da = np.float64(color[k, 3]), np.float64(fb_color[m, j, i, 3])
                        r = blend_channel(eq_rgb, src_rgb, dst_rgb, 0, np.float64(color[k, 0]),
                                          np.float64(fb_color[m, j, i, 0]), sa, da, const_r, const_a)
                        g = blend_channel(eq_rgb, src_rgb, dst_rgb, 1, np.float64(color[k, 1]),
                                          np.float64(fb_color[m, j, i, 1]), sa, da, const_g, const_a)
                        b = blend_channel(eq_rgb, src_rgb, dst_rgb, 2, np.float64(color[k, 2]),
                                          np.float64(fb_color[m, j, i, 2]), sa, da, const_b, const_a)
                        a = blend_channel(eq_a, src_a, dst_a, 3, sa, da, sa, da, const_a, const_a)
                    if mask_r:
                        fb_color[m, j, i, 0] = r
                    if mask_g:
                        fb_color[m, j, i, 1] = g
                    if mask_b:
                        fb_color[m, j, i, 2] = b
                    if mask_a:
                        fb_color[m, j, i, 3] = a
        if record:
            for c in range(4):
                after[k, c] = fb_color[m, j, i, c]
            stencil_after[k] = fb_stencil[m, j, i]


_NO_IDS = np.zeros(0, np.int32)
_NO_RECORD = np.zeros((0, 0, 0), np.int32)


@numba.njit(cache=True)
def _covers(st, alpha, sample, samples):
    """GL's multisample operations: alpha to coverage, then the sample mask."""
    if st[ST_ALPHA_TO_COVERAGE] and not covered_by_alpha(np.float64(alpha), sample, samples):
        return False
    return (st[ST_SAMPLE_MASK] >> sample) & 1 != 0


@numba.njit(cache=True)
def _write_stencil(fb_stencil, m, j, i, st, face, op, stored):
    """Apply a stencil op (the face's state at ``st[face:face + 7]``) through its write mask."""
    if op == 0:
        return
    wmask = st[face + 6]
    fb_stencil[m, j, i] = (stored & ~wmask & 255) | (stencil_op(op, stored, st[face + 1]) & wmask)


@dataclass
class MergeResult:
    """What the output merger did: a verdict per fragment, and (when recorded) the sample after it.

    Attributes
    ----------
    verdict : int8 [F]
        Index into :data:`VERDICTS`: "written", or the step that stopped the fragment.
    color_after : float32 [F, 4] or None
        The sample's color right after each fragment was merged.
    stencil_after : uint8 [F] or None
        The sample's stencil value right after each fragment was merged.
    """

    verdict: np.ndarray
    color_after: Optional[np.ndarray] = None
    stencil_after: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.verdict)

    @property
    def samples_passed(self) -> int:
        """How many fragments (samples) passed every test: what an occlusion query counts."""
        return int(np.count_nonzero(self.verdict == WRITTEN))

    def __repr__(self) -> str:
        counts = np.bincount(self.verdict, minlength=len(VERDICTS)) if len(self.verdict) else [0] * len(VERDICTS)
        return "MergeResult(" + ", ".join(f"{n}: {int(c)}" for n, c in zip(VERDICTS, counts) if c or n in VERDICTS[:3]) + ")"


@numba.njit(cache=True)
def _merge_more_float(x, y, s, verdict, values, target, codes, blend_color):
    """Another float attachment's values ([F, C], C = 4 or 1) into ``target`` [S, H, W, C] at the samples whose
    fragment was written, in fragment order, blended and masked by ``codes`` (AttachmentState.codes).
    A one-channel value blends as (r, 0, 0, 1): source and destination alpha 1 (GL: a format without
    alpha reads as alpha 1)."""
    blend, src_rgb, dst_rgb, src_a, dst_a, eq_rgb, eq_a = (codes[0] != 0, codes[1], codes[2], codes[3], codes[4],
                                                           codes[5], codes[6])
    channels = values.shape[1]
    const_a = blend_color[3]
    for k in range(x.shape[0]):
        if verdict[k] != WRITTEN:
            continue
        i, j, m = x[k], y[k], s[k]
        sa = np.float64(values[k, 3]) if channels == 4 else 1.0
        da = np.float64(target[m, j, i, 3]) if channels == 4 else 1.0
        for c in range(channels):
            if codes[7 + c] == 0:
                continue
            src = np.float64(values[k, c])
            if blend:
                dst = np.float64(target[m, j, i, c])
                if c < 3:
                    target[m, j, i, c] = blend_channel(eq_rgb, src_rgb, dst_rgb, c, src, dst, sa, da, blend_color[c],
                                                       const_a)
                else:
                    target[m, j, i, c] = blend_channel(eq_a, src_a, dst_a, 3, sa, da, sa, da, const_a, const_a)
            else:
                target[m, j, i, c] = values[k, c]


@numba.njit(cache=True)
def _merge_more_int(x, y, s, verdict, values, target, write):
    """An integer attachment's values ([F]) into ``target`` [S, H, W] where the fragment was written
    (never blended), in fragment order, if its mask lets R be written."""
    if not write:
        return
    for k in range(x.shape[0]):
        if verdict[k] == WRITTEN:
            target[s[k], y[k], x[k]] = values[k]


def merge_more(frags: Fragments, shaded: ShadedFragments, verdict: np.ndarray, fb: Framebuffer,
               states: Sequence[AttachmentState], blend_color: Sequence[float]) -> None:
    """The other attachments' values (:attr:`ShadedFragments.outputs`, locations 1, 2, …) where the merger
    wrote location 0's (``verdict`` "written"), each by its own :class:`AttachmentState`.

    Run after :func:`merge` over the same fragments in the same order: each sample then sees
    the same writes in the same order as if they were made fragment by fragment.
    """
    for state, values in zip(states, shaded.outputs):
        target = fb.samples_attachment(state.name)
        if state.format == "r32i":
            _merge_more_int(frags.x, frags.y, frags.sample, verdict, values, target, bool(state.codes[7]))
            continue
        if values.ndim == 1:
            values, target = values[:, None], target[..., None]
        _merge_more_float(frags.x, frags.y, frags.sample, verdict, values, target, state.codes,
                          np.asarray(blend_color, np.float64))


def merge(frags: Fragments, shaded: ShadedFragments, state: MergeState, fb: Framebuffer,
          record: bool = False, front_facing: Optional[np.ndarray] = None,
          record_ids: Optional[np.ndarray] = None) -> MergeResult:
    """Apply the fragments to the framebuffer in order, through the chain of the module docstring.

    ``front_facing`` (bool, one per row of the Primitives the fragments came from) picks each
    fragment's stencil state (front or back); without it every fragment faces the front.
    With ``record``, also keep each sample's color and stencil right after its fragment
    (for pixel history). ``record_ids`` (int32, one per row of the Primitives) is what a
    framebuffer with a visibility record (:attr:`Framebuffer.record`) stores at each sample
    whose depth a fragment writes; without it the record is left as it is.
    """
    n = len(frags)
    verdict = np.empty(n, dtype=np.int8)
    after = np.empty((n if record else 0, 4), dtype=np.float32)
    stencil_after = np.empty(n if record else 0, dtype=np.uint8)
    if n:
        facing = (np.zeros(0, np.bool_) if front_facing is None or state.stencil_back is None
                  else np.ascontiguousarray(front_facing, dtype=np.bool_))
        keep = fb.record is not None and record_ids is not None
        _merge_kernel(frags.x, frags.y, frags.sample, frags.depth, shaded.color, shaded.discarded, frags.triangle,
                      facing, state.codes(fb.height), np.asarray(state.blend_color, np.float64), fb.samples_color,
                      fb.samples_depth, fb.samples_stencil, verdict, after, stencil_after,
                      np.ascontiguousarray(record_ids, np.int32) if keep else _NO_IDS,
                      fb.record if keep else _NO_RECORD)
    return MergeResult(verdict, after if record else None, stencil_after if record else None)


class OcclusionQuery:
    """GL's occlusion query (``GL_SAMPLES_PASSED``): how many samples of the draws given it passed
    every per-fragment test (scissor, sample mask, stencil, depth).

    ``q = softpipe.OcclusionQuery(); softpipe.draw(fb, ..., query=q)``; then
    ``q.samples_passed``. It adds up over every draw given it; :meth:`reset` starts again.
    """

    def __init__(self) -> None:
        self.samples_passed = 0
        self.draws = 0

    def add(self, samples: int) -> None:
        """Count one draw's passing samples."""
        self.samples_passed += int(samples)
        self.draws += 1

    def reset(self) -> None:
        self.samples_passed, self.draws = 0, 0

    def __repr__(self) -> str:
        return f"OcclusionQuery(samples_passed={self.samples_passed:,}, draws={self.draws})"


# ------------------------------------------------------------------ colors that are not numbers

class NonFiniteColorWarning(UserWarning):
    """A draw wrote a NaN or infinite color into the framebuffer (a shader's ``math.pow`` of a negative
    number, a division by zero, …): such a sample saves as black, so softpipe says so, once per draw."""


@dataclass(frozen=True)
class NonFinite:
    """What a draw wrote that is not a finite color: how many samples, and the first (its pixel as
    ``Trace.at`` and ``debug_fragment`` take it: column ``x``, image row ``y``; its primitive id)."""

    count: int
    x: int
    y: int
    primitive_id: int

    def message(self) -> str:
        return (f"the draw wrote {self.count:,} sample{'s' if self.count != 1 else ''} whose color is NaN or "
                f"infinite, the first at pixel ({self.x}, {self.y}) (column, image row) from primitive "
                f"{self.primitive_id}; a PNG shows a NaN as 0 (black). To see why, draw again with trace=True and call "
                f"trace.debug_fragment({self.x}, {self.y}): it runs the fragment shader there in Python, with "
                "math's functions giving NaN or infinity as the compiled shader's do")


def non_finite_written(frags: Fragments, shaded: ShadedFragments, merged: MergeResult,
                       color_mask: Sequence[bool] = (True, True, True, True)) -> Optional[NonFinite]:
    """The fragments the merger wrote with a NaN or infinite color component, or None.

    Only the channels ``color_mask`` lets through count: a channel masked off is not written,
    whatever the shader returned for it (a depth-only pass's NaN says nothing)."""
    channels = np.flatnonzero(np.asarray(color_mask, bool))
    if not len(channels):
        return None
    bad = np.flatnonzero((merged.verdict == WRITTEN) & ~np.isfinite(shaded.color[:, channels]).all(axis=1))
    if not len(bad):
        return None
    k = int(bad[0])
    return NonFinite(len(bad), int(frags.x[k]), int(frags.y[k]), int(frags.primitive_id[k]))
