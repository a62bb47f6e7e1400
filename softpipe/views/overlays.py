"""RenderDoc's overlays of a traced draw (or of a scene's draws into one framebuffer), as pictures.

Each is an [H, W, 3] uint8 array the size of the framebuffer, computed from the trace:

``triangle size``       at each pixel, the size of the triangle whose fragment was last
                        written there: every sample the rasterizer made for that input
                        triangle (its clipped pieces together, the ones that lost the
                        depth test too: the work it cost) ÷ the samples per pixel, on
                        :data:`SIZE_STOPS`' log scale: red 1 pixel or less, orange 4,
                        yellow 16, green 64, cyan 256, blue 1024 or more (black: nothing
                        written). Where small triangles cost: every triangle's edge pixels
                        are shaded in part for nothing (:func:`triangle_size`)
``depth test``          at each pixel, what the depth test did with the draws' fragments:
                        green all passed, red all failed, yellow some of each (black: none
                        reached it). Passed: written; failed: "depth-failed"; a fragment
                        stopped before the depth test (discarded, scissored, stencil-failed,
                        sample-masked) is neither (:func:`depth_test_counts`)
``clipped and culled``  the final picture at half brightness, with the pixels written by
                        the pieces clipping made in cyan, and the outline of each triangle
                        culled for facing in red where the draws wrote nothing (where the
                        culling shows: a closed mesh's back faces lie under its front)

The other overlays RenderDoc users ask for are stage pictures already
(:mod:`softpipe.views.pictures`): ``overdraw``, ``non-finite`` (NaN and infinity),
``stencil`` and ``tests`` (the scissor, stencil and sample-mask verdicts). These three are
not on the default contact sheet (it stays readable): ask :func:`overlay_pictures`, or the
explorer's ``overlays=True`` (``softpipe explore --overlays``).
"""
from __future__ import annotations

from typing import Dict, Tuple

import numpy as np

from softpipe.views.draws import traced_draws
from softpipe.views.pictures import CYAN, RED, draw_triangle_outlines

__all__ = ["OVERLAYS", "SIZE_STOPS", "DEPTH_TEST_COLORS", "overlay_pictures", "triangle_size", "size_colors",
           "depth_test_counts", "depth_test_picture", "clipped_and_culled"]

#: The overlays' names, in the order :func:`overlay_pictures` gives them.
OVERLAYS = ("triangle size", "depth test", "clipped and culled")

#: The triangle-size picture's colors at 1, 4, 16, 64, 256 and 1024 pixels (log-linear in between).
SIZE_STOPS = ((1, (230, 50, 40)), (4, (250, 150, 40)), (16, (240, 220, 40)), (64, (40, 200, 80)),
              (256, (60, 200, 230)), (1024, (40, 60, 220)))

#: The depth-test picture's colors: every fragment passed, every one failed, some of each.
DEPTH_TEST_COLORS = {"passed": (70, 200, 90), "failed": RED, "both": (250, 220, 60)}


def _traces(traces) -> list:
    return [t for _, t in traced_draws(traces, "overlays")]


def _samples(trace) -> int:
    return max(int(getattr(trace.call.framebuffer, "samples", 1)), 1)


def triangle_size(traces) -> np.ndarray:
    """float64 [H, W]: the size in pixels of the input triangle whose fragment was last written at each pixel
    (all its fragments ÷ the samples per pixel), across the draws in order; 0 where nothing was written."""
    ts = _traces(traces)
    h, w = ts[0].height, ts[0].width
    out = np.zeros((h, w))
    for t in ts:
        f = t.fragments
        if not len(f):
            continue
        size = np.bincount(f.primitive_id, minlength=int(f.primitive_id.max()) + 1) / _samples(t)
        wr = t.written()
        pix = (f.y[wr].astype(np.int64) * w + f.x[wr])[::-1]
        _, first = np.unique(pix, return_index=True)      # the first of the reversed: the last written
        rows = np.flatnonzero(wr)[::-1][first]
        out[f.y[rows], f.x[rows]] = size[f.primitive_id[rows]]
    return out


def size_colors(pixels: np.ndarray) -> np.ndarray:
    """[..., 3] uint8: :data:`SIZE_STOPS` at sizes in pixels (log2-linear between them; black for 0)."""
    at = np.log2([s for s, _ in SIZE_STOPS])
    lg = np.log2(np.maximum(pixels, 1e-300))
    rgb = np.stack([np.interp(lg, at, [c[i] for _, c in SIZE_STOPS]) for i in range(3)], axis=-1)
    return np.where(np.asarray(pixels)[..., None] > 0, np.round(rgb), 0).astype(np.uint8)


def depth_test_counts(traces) -> Tuple[np.ndarray, np.ndarray]:
    """int64 [H, W] twice: the fragments (samples) at each pixel that passed the depth test (written) and that
    failed it ("depth-failed"), over the draws."""
    ts = _traces(traces)
    h, w = ts[0].height, ts[0].width
    passed, failed = np.zeros((h, w), np.int64), np.zeros((h, w), np.int64)
    for t in ts:
        f, v = t.fragments, t.merged.verdict
        np.add.at(passed, (f.y[v == 0], f.x[v == 0]), 1)
        np.add.at(failed, (f.y[v == 1], f.x[v == 1]), 1)
    return passed, failed


def depth_test_picture(traces) -> np.ndarray:
    """[H, W, 3] uint8: :data:`DEPTH_TEST_COLORS` by :func:`depth_test_counts` (black: no fragment tested)."""
    passed, failed = depth_test_counts(traces)
    img = np.zeros(passed.shape + (3,), np.uint8)
    img[(passed > 0) & (failed == 0)] = DEPTH_TEST_COLORS["passed"]
    img[(passed == 0) & (failed > 0)] = DEPTH_TEST_COLORS["failed"]
    img[(passed > 0) & (failed > 0)] = DEPTH_TEST_COLORS["both"]
    return img


def clipped_and_culled(traces) -> np.ndarray:
    """[H, W, 3] uint8: the last draw's framebuffer at half brightness; cyan where a piece clipping made
    was last written; the outline of each triangle culled for facing in red where the draws wrote nothing
    (where culling left a hole: a closed mesh's back faces, hidden under its front, show no red)."""
    ts = _traces(traces)
    img = (ts[-1].call.framebuffer.to_uint8(alpha=False) // 2).astype(np.uint8)
    h, w = img.shape[:2]
    cut = np.zeros((h, w), np.int8)         # 1: a clipped piece wrote last; -1: an uncut primitive did
    for t in ts:
        f, wr = t.fragments, t.written()
        if wr.any():
            cut[f.y[wr], f.x[wr]] = np.where(t.primitives.clipped[f.triangle[wr]], 1, -1)
    img[cut == 1] = CYAN
    outline = np.zeros_like(img)        # a closed mesh's back faces lie under its front: outlines there are noise
    for t in ts:
        draw_triangle_outlines(outline, t.primitives.culled_window, h, RED)
    img[outline.any(axis=2) & (cut == 0)] = RED
    return img


def overlay_pictures(traces) -> Dict[str, np.ndarray]:
    """The :data:`OVERLAYS` of a trace, a DrawResult, or a scene's list of either (one framebuffer, in order)."""
    return {"triangle size": size_colors(triangle_size(traces)), "depth test": depth_test_picture(traces),
            "clipped and culled": clipped_and_culled(traces)}
