"""The exact transparent composite: every fragment of some draws, sorted per sample, "over" an opaque picture.

:func:`sorted_composite` is the reference the transparency methods of
:mod:`softpipe.scenes.transparency` (and a renderer of one's own) are measured against. It
takes what the reference path made (the :class:`~softpipe.pipeline.trace.Trace` of each
transparent draw: every fragment, with its sample, its depth and its shaded color) and an
opaque framebuffer (its color and depth), and at each sample:

1. keeps the fragments that were not discarded and lie in front of the opaque surface
   (GL's depth test "less": float32(depth) < the stored depth, as the merger compares);
2. sorts them back to front by depth; fragments at the same depth keep the order they were
   drawn in (trace by trace, and in a trace primitive order), the later one in front, as a
   draw order would put it;
3. composites them over the opaque color, one after the other, with Porter and Duff's
   "over" on straight (not premultiplied) alpha: C ← α·c + (1 − α)·C and
   A ← α + (1 − α)·A, in float64.

It lives here, beside the other references of :mod:`softpipe.testing`, and not beside the
methods it judges: it shares no code with them (no blending, no depth buffer, no draw), only
the fragments the pipeline's reference path made, so a mistake in a method cannot hide in it.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from softpipe.pipeline.framebuffer import Framebuffer

__all__ = ["sorted_composite"]


def sorted_composite(traces: Sequence, background: Framebuffer) -> Framebuffer:
    """Every fragment of ``traces``, sorted by depth per sample, composited over ``background``.

    Parameters
    ----------
    traces : sequence of Trace
        The transparent draws, in the order they were drawn, each drawn with ``trace=True``
        on the reference path (``path="reference"``: the fast path keeps only the visible
        fragment of each sample) into a framebuffer of ``background``'s size and pattern.
        Draw them with ``depth_test=None`` so that none is lost to the depth buffer: the
        opaque depth test is made here.
    background : Framebuffer
        The opaque picture: its color is what the fragments are composited over, its depth
        what they are tested against ("less"). It is not changed.

    Returns
    -------
    Framebuffer
        A new framebuffer of ``background``'s size and pattern: the composite in every
        sample's color (float32, unclamped), ``background``'s depth.

    Raises
    ------
    ValueError
        A trace of the fast path, or one drawn into a framebuffer of another size or pattern.
    """
    S, H, W = background.samples, background.height, background.width
    parts = []
    for n, tr in enumerate(traces):
        if getattr(tr, "path", "reference") != "reference":
            raise ValueError(f"trace {n} was drawn on the {tr.path!r} path, which keeps only the visible "
                             "fragments; draw with path=\"reference\"")
        if (tr.width, tr.height, len(tr.pattern)) != (W, H, S):
            raise ValueError(f"trace {n} is of a {tr.width}×{tr.height} framebuffer with {len(tr.pattern)} "
                             f"sample(s); the background is {W}×{H} with {S}")
        f, sh = tr.fragments, tr.shaded
        parts.append((np.asarray(f.sample, np.int64), np.asarray(f.y, np.int64), np.asarray(f.x, np.int64),
                      np.asarray(f.depth, np.float64).astype(np.float32), np.asarray(sh.color, np.float64),
                      np.asarray(sh.discarded, bool)))
    out = Framebuffer(W, H, background.pattern, srgb=background.srgb)      # its bytes encoded as the background's
    color = background.samples_color.astype(np.float64)
    depth = background.samples_depth
    if parts:
        s, y, x, z, c, discarded = (np.concatenate([p[i] for p in parts]) for i in range(6))
        keep = ~discarded & (z < depth[s, y, x])
        key = (s * H + y) * W + x
        order = np.arange(len(key))             # draw order: trace by trace, then primitive order
        key, z, c, order = key[keep], z[keep], c[keep], order[keep]
        # per sample, back to front (depth descending), equal depths in draw order
        rank_order = np.lexsort((order, -z.astype(np.float64), key))
        key, c = key[rank_order], c[rank_order]
        starts = np.r_[0, np.flatnonzero(np.diff(key)) + 1] if len(key) else np.zeros(0, np.int64)
        group = np.repeat(starts, np.diff(np.r_[starts, len(key)]))
        rank = np.arange(len(key)) - group
        flat = color.reshape(-1, 4)
        for r in range(int(rank.max()) + 1 if len(rank) else 0):
            at = rank == r                      # at most one fragment per sample at each rank
            k, a = key[at], c[at, 3:4]
            flat[k, :3] = a * c[at, :3] + (1.0 - a) * flat[k, :3]
            flat[k, 3:4] = a + (1.0 - a) * flat[k, 3:4]
        color = flat.reshape(S, H, W, 4)
    out.samples_color[...] = color
    out.samples_depth[...] = depth
    return out
