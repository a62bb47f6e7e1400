"""Stage 5: the output merger — depth test, depth write and blending, in primitive order.

For each fragment, in the order the rasterizer produced them (primitive order),
at its sample of the framebuffer:

1. a discarded fragment does nothing;
2. the depth test compares the fragment's depth (as float32, the buffer's type)
   with the stored one using the compare function; a failing fragment stops;
3. if depth writes are on, its depth is stored;
4. its color is blended with the stored color, ``src·F_src + dst·F_dst`` per
   channel (OpenGL's FUNC_ADD), or replaces it when blending is off.

Each fragment's verdict is recorded (:data:`VERDICTS`) so a trace can say what
happened to it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple, Union

import numba
import numpy as np

from softpipe.pipeline.fragment import ShadedFragments
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.raster import Fragments

__all__ = ["MergeState", "MergeResult", "merge", "DEPTH_FUNCS", "BLEND_FACTORS", "VERDICTS",
           "depth_passes", "NonFiniteColorWarning", "NonFinite", "non_finite_written"]

#: OpenGL's eight depth compare functions: the fragment passes if ``z_frag OP z_stored``.
DEPTH_FUNCS = ("never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always")
BLEND_FACTORS = ("zero", "one", "src_color", "one_minus_src_color", "dst_color", "one_minus_dst_color",
                 "src_alpha", "one_minus_src_alpha", "dst_alpha", "one_minus_dst_alpha")
#: Named blend modes: ``"alpha"`` (over), ``"additive"``.
BLEND_PRESETS = {"alpha": ("src_alpha", "one_minus_src_alpha"), "additive": ("one", "one")}
#: What the merger did with a fragment: its index in this tuple is stored per fragment.
VERDICTS = ("written", "depth-failed", "discarded")
WRITTEN, DEPTH_FAILED, DISCARDED = 0, 1, 2


@dataclass(frozen=True)
class MergeState:
    """The output merger's fixed-function state.

    Parameters
    ----------
    depth_test : one of :data:`DEPTH_FUNCS`, or None to turn the test off
        (OpenGL then neither tests nor writes depth).
    depth_write : bool
    blend : None (off), ``"alpha"``, ``"additive"``, or (src_factor, dst_factor)
        with factors from :data:`BLEND_FACTORS`.
    """

    depth_test: Optional[str] = "less"
    depth_write: bool = True
    blend: Union[None, str, Tuple[str, str]] = None

    def __post_init__(self):
        if self.depth_test is not None and self.depth_test not in DEPTH_FUNCS:
            raise ValueError(f"depth_test must be one of {DEPTH_FUNCS} or None, got {self.depth_test!r}")
        if not isinstance(self.depth_write, (bool, np.bool_)):
            raise TypeError(f"depth_write must be True or False, got {self.depth_write!r}")
        self.blend_factors()

    def blend_factors(self) -> Tuple[int, int]:
        """(src, dst) factor codes, or (-1, -1) when blending is off."""
        b = self.blend
        if b is None:
            return -1, -1
        if isinstance(b, str):
            if b not in BLEND_PRESETS:
                raise ValueError(f"blend must be None, one of {tuple(BLEND_PRESETS)} or a (src, dst) pair of "
                                 f"{BLEND_FACTORS}, got {b!r}")
            b = BLEND_PRESETS[b]
        if not (isinstance(b, (tuple, list)) and len(b) == 2):
            raise ValueError(f"blend must be None, a preset name or a (src_factor, dst_factor) pair, got {b!r}")
        for f in b:
            if f not in BLEND_FACTORS:
                raise ValueError(f"unknown blend factor {f!r}; expected one of {BLEND_FACTORS}")
        return BLEND_FACTORS.index(b[0]), BLEND_FACTORS.index(b[1])


@numba.njit(cache=True)
def depth_passes(func, z, stored):
    """The depth compare function (codes as in DEPTH_FUNCS)."""
    if func == 0:
        return False
    if func == 1:
        return z < stored
    if func == 2:
        return z == stored
    if func == 3:
        return z <= stored
    if func == 4:
        return z > stored
    if func == 5:
        return z != stored
    if func == 6:
        return z >= stored
    return True


@numba.njit(cache=True)
def blend_factor(code, channel_src, channel_dst, src_alpha, dst_alpha):
    """One blend factor for one channel (codes as in BLEND_FACTORS)."""
    if code == 0:
        return 0.0
    if code == 1:
        return 1.0
    if code == 2:
        return channel_src
    if code == 3:
        return 1.0 - channel_src
    if code == 4:
        return channel_dst
    if code == 5:
        return 1.0 - channel_dst
    if code == 6:
        return src_alpha
    if code == 7:
        return 1.0 - src_alpha
    if code == 8:
        return dst_alpha
    return 1.0 - dst_alpha


@numba.njit(cache=True)
def _merge_kernel(x, y, s, depth, color, discarded, func, depth_write, src_f, dst_f, fb_color, fb_depth, verdict,
                  after):
    record = after.shape[0] > 0
    for k in range(x.shape[0]):
        i, j, m = x[k], y[k], s[k]
        verdict[k] = _merge_one(k, i, j, m, depth, color, discarded, func, depth_write, src_f, dst_f,
                                fb_color, fb_depth)
        if record:
            for c in range(4):
                after[k, c] = fb_color[m, j, i, c]


@numba.njit(cache=True)
def _merge_one(k, i, j, m, depth, color, discarded, func, depth_write, src_f, dst_f, fb_color, fb_depth):
    """One fragment through the merger; returns its verdict."""
    if discarded[k]:
        return DISCARDED
    z = np.float32(depth[k])
    if func >= 0:
        if not depth_passes(func, z, fb_depth[m, j, i]):
            return DEPTH_FAILED
        if depth_write:
            fb_depth[m, j, i] = z
    if src_f < 0:
        for c in range(4):
            fb_color[m, j, i, c] = color[k, c]
    else:
        # float64 explicitly: numba and plain Python (NumPy keeps float32 scalars) then agree
        sa, da = np.float64(color[k, 3]), np.float64(fb_color[m, j, i, 3])
        for c in range(4):
            src, dst = np.float64(color[k, c]), np.float64(fb_color[m, j, i, c])
            fb_color[m, j, i, c] = (src * blend_factor(src_f, src, dst, sa, da)
                                    + dst * blend_factor(dst_f, src, dst, sa, da))
    return WRITTEN


@dataclass
class MergeResult:
    """What the output merger did: a verdict per fragment, and (when recorded) the color after it.

    Attributes
    ----------
    verdict : int8 [F]
        Index into :data:`VERDICTS` ("written", "depth-failed", "discarded").
    color_after : float32 [F, 4] or None
        The sample's color right after each fragment was merged.
    """

    verdict: np.ndarray
    color_after: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.verdict)

    def __repr__(self) -> str:
        counts = np.bincount(self.verdict, minlength=len(VERDICTS)) if len(self.verdict) else [0] * len(VERDICTS)
        return "MergeResult(" + ", ".join(f"{n}: {int(c)}" for n, c in zip(VERDICTS, counts)) + ")"


def merge(frags: Fragments, shaded: ShadedFragments, state: MergeState, fb: Framebuffer,
          record: bool = False) -> MergeResult:
    """Apply the fragments to the framebuffer in order.

    With ``record``, also keep each sample's color right after its fragment (for pixel history).
    """
    verdict = np.empty(len(frags), dtype=np.int8)
    after = np.empty((len(frags) if record else 0, 4), dtype=np.float32)
    if len(frags):
        func = -1 if state.depth_test is None else DEPTH_FUNCS.index(state.depth_test)
        src_f, dst_f = state.blend_factors()
        _merge_kernel(frags.x, frags.y, frags.sample, frags.depth, shaded.color, shaded.discarded, func,
                      bool(state.depth_write) and func >= 0, src_f, dst_f, fb.samples_color, fb.samples_depth,
                      verdict, after)
    return MergeResult(verdict, after if record else None)


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


def non_finite_written(frags: Fragments, shaded: ShadedFragments, merged: MergeResult) -> Optional[NonFinite]:
    """The fragments the merger wrote with a NaN or infinite color component, or None."""
    bad = np.flatnonzero((merged.verdict == WRITTEN) & ~np.isfinite(shaded.color).all(axis=1))
    if not len(bad):
        return None
    k = int(bad[0])
    return NonFinite(len(bad), int(frags.x[k]), int(frags.y[k]), int(frags.primitive_id[k]))

