"""Stage 3 for points: point setup and GL's square.

A point of size s (clamped to at least 1) at window position (x, y) produces a
fragment for each pixel whose centre lies in the square
[x − s/2, x + s/2) × [y − s/2, y + s/2) (OpenGL 4.6 §14.4, non-antialiased points;
the half-open sides make two points a size apart meet without a double hit).
The position is snapped to the triangles' grid (1/256 pixel,
:func:`~softpipe.pipeline.setup.snap`) and the comparisons are exact.

**gl_PointCoord** at a fragment shaded at window position (x_f, y_f):
s = ½ + (x_f − x)/size, t = ½ − (y_f − y)/size — (0, 0) at the square's upper-left
corner, as GL's default ``POINT_SPRITE_COORD_ORIGIN``. The fragment's barycentrics
over the point's corners (p, p, p) are (1 − s − t, s, t): the varyings are the
vertex's, and the fragment shader reads (s, t) as ``frag.point_coord``.

**Multisampling**: a fragment covers every sample of its pixel (GL's rule
without MULTISAMPLE, §14.3.1), shaded at each sample or once at the centre as for
triangles; its depth is the vertex's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.pipeline.sampling import SUBPIXEL
from softpipe.pipeline.setup import SHADE_CENTER, SHADE_SAMPLE, snap

__all__ = ["PointSetup", "setup_points", "in_square", "cover_point", "point_box", "point_shading_point",
           "point_sample_inputs"]


@dataclass
class PointSetup:
    """Per point of the :class:`~softpipe.pipeline.assembly.Primitives`.

    Attributes
    ----------
    centre : int64 [Q, 2]
        The snapped position (X, Y) in fixed point (pixel i's centre at 256·i).
    size : float64 [Q]
        The side of the square in pixels (at least 1).
    depth : float64 [Q]
        The window depth.
    """

    centre: np.ndarray
    size: np.ndarray
    depth: np.ndarray

    def __len__(self) -> int:
        return len(self.size)

    def __repr__(self) -> str:
        return f"PointSetup({len(self)} points)"

    def barycentric_gradients(self) -> np.ndarray:
        """∂b_k/∂x and ∂b_k/∂y per window pixel, [Q, 2, 3]: b = (1 − s − t, s, t), where s grows by
        1/size per pixel right and t by 1/size per pixel down."""
        out = np.zeros((len(self), 2, 3))
        out[:, 0, 1] = 1.0 / self.size
        out[:, 1, 2] = -1.0 / self.size
        out[:, :, 0] = -(out[:, :, 1] + out[:, :, 2])
        return out


@numba.njit(cache=True, nogil=True)
def _setup_kernel(lo, hi, window, size, centre, side, depth):
    for t in range(lo, hi):
        centre[t, 0], centre[t, 1] = snap(window[t, 0, 0]), snap(window[t, 0, 1])
        side[t] = max(size[t], 1.0)
        depth[t] = min(max(window[t, 0, 2], 0.0), 1.0)


def setup_points(window: np.ndarray, size: np.ndarray) -> PointSetup:
    """Set up every point: ``window`` [Q, 3, 3] the corners (p, p, p), ``size`` [Q] in pixels."""
    n = len(window)
    s = PointSetup(np.empty((n, 2), np.int64), np.empty(n), np.empty(n))
    if n:
        in_bands(_setup_kernel, n, window, np.ascontiguousarray(size, np.float64), s.centre, s.size, s.depth,
                 grain=8192)
    return s


@numba.njit(cache=True, forceinline=True)
def in_square(c, half):
    """Is a pixel centre ``c`` fixed-point units from the point's (an integer) in [−half, half)?

    ``half`` = 128·size is exact in floating point, and so is the comparison.
    """
    return -half <= c < half


@numba.njit(cache=True, inline="always")
def point_box(centre, size, t, x_lo, x_hi, y_lo, y_hi):
    """The pixels (i0, i1, j0, j1) around point t whose centres may lie in its square, within
    [x_lo, x_hi] × [y_lo, y_hi] (window rows, y up); :func:`in_square` decides each."""
    cx, cy = centre[t, 0], centre[t, 1]
    half = size[t] * (SUBPIXEL // 2)
    i0 = max(np.int64(np.floor((cx - half) / SUBPIXEL)) - 1, x_lo)
    i1 = min(np.int64(np.floor((cx + half) / SUBPIXEL)) + 1, x_hi)
    j0 = max(np.int64(np.floor((cy - half) / SUBPIXEL)) - 1, y_lo)
    j1 = min(np.int64(np.floor((cy + half) / SUBPIXEL)) + 1, y_hi)
    return i0, i1, j0, j1


@numba.njit(cache=True, forceinline=True)
def point_shading_point(centre, size, t, i, j, s, positions, mode, means):
    """Where point t's fragment at pixel (i, j) is shaded: (s_p, t_p, fx, fy), its gl_PointCoord and the
    window position (``means``: the samples' mean position, (px, py), all of them being covered)."""
    # the point's position in window coordinates (pixel centres at +½)
    x, y = centre[t, 0] / SUBPIXEL + 0.5, centre[t, 1] / SUBPIXEL + 0.5
    if mode == SHADE_SAMPLE:
        fx, fy = i + positions[s, 0], j + positions[s, 1]
    elif mode == SHADE_CENTER:
        fx, fy = i + 0.5, j + 0.5
    else:                    # the centroid of the covered samples: all of them
        fx, fy = i + means[0], j + means[1]
    side = size[t]
    return 0.5 + (fx - x) / side, 0.5 - (fy - y) / side, fx, fy


@numba.njit(cache=True, inline="always")
def point_sample_inputs(centre, size, zpoint, t, i, j, s, positions, mode, means):
    """The shader's inputs at sample s of pixel (i, j) where point t is the one kept: (b0, b1, b2, fx, fy, z),
    the barycentrics (1 − s_p − t_p, s_p, t_p) of its gl_PointCoord, the window position and the point's
    depth, as the reference path's fragment there has them (``means``: the four of
    :func:`~softpipe.pipeline.lines.sample_means`)."""
    ps, pt, px, py = point_shading_point(centre, size, t, i, j, s, positions, mode, (means[2], means[3]))
    return 1.0 - ps - pt, ps, pt, px, py, zpoint[t]


@numba.njit(cache=True)
def cover_point(centre, size, depth, t, rect, height, offsets, positions, mode, out_x, out_y, out_s, out_depth,
                out_bary, out_pos, start, emit):
    """Visit every fragment of point t (every sample of each pixel in its square, within ``rect``);
    write them from ``start`` if ``emit``. Returns the count."""
    cx, cy = centre[t, 0], centre[t, 1]
    half = size[t] * (SUBPIXEL // 2)
    i0, i1, j0, j1 = point_box(centre, size, t, rect[0], rect[1], rect[2], rect[3])
    samples = offsets.shape[0]
    px, py = 0.0, 0.0                    # the centroid of all the samples (every one is covered), once
    for m in range(samples):
        px += positions[m, 0]
        py += positions[m, 1]
    means = (px / samples, py / samples)
    n = 0
    for j in range(j0, j1 + 1):
        if not in_square(j * SUBPIXEL - cy, half):
            continue
        for i in range(i0, i1 + 1):
            if not in_square(i * SUBPIXEL - cx, half):
                continue
            if not emit:
                n += samples
                continue
            for s in range(samples):
                k = start + n
                ps, pt, fx, fy = point_shading_point(centre, size, t, i, j, s, positions, mode, means)
                out_x[k] = i
                out_y[k] = height - 1 - j     # the y flip: window row → image row
                out_s[k] = s
                out_depth[k] = depth[t]
                out_bary[k, 0] = 1.0 - ps - pt
                out_bary[k, 1] = ps
                out_bary[k, 2] = pt
                out_pos[0, k] = fx
                out_pos[1, k] = fy
                n += 1
    return n
