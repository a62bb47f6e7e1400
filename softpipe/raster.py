"""Stage 3: the rasterizer — which samples each triangle covers, and where.

It answers exactly three questions per covered sample: which pixel and sample,
which triangle, and the barycentrics (and from them the depth). Shading is a
later stage. The rules are OpenGL's, as Mesa implements them (DESIGN.md):

1. **Snapping.** Window coordinates become fixed point with 8 subpixel bits:
   ``X = round_half_even((x_w − ½)·256)``, so pixel i's centre is at ``256·i``
   (:func:`snap`).
2. **Edge functions**, exact in 64-bit integers. For the edge a→b and a sample
   p: ``E(p) = (X_b − X_a)(P_y − Y_a) − (Y_b − Y_a)(P_x − X_a)``. E_k is the
   edge opposite corner k, so E_0 + E_1 + E_2 = twice the snapped area, and
   ``b_k = E_k / area`` are the barycentrics. A triangle with snapped area 0
   produces nothing. Clockwise triangles are turned around (every E negated).
3. **The fill rule** (:func:`owns_samples_on_edge`). A sample strictly inside
   all three edges is covered; a sample exactly on an edge is covered only if
   that edge owns it: left edges and bottom horizontal edges, in OpenGL window
   coordinates (y up). Two triangles sharing an edge never both cover, and never
   both miss, a sample on it.
4. **Depth** is interpolated linearly in window space at the sample:
   ``z = b_0 z_0 + b_1 z_1 + b_2 z_2``, evaluated as
   ``z_0 + (E_1 (z_1 − z_0) + E_2 (z_2 − z_0)) / area`` so that a fast path
   stepping the integer E's along a row computes the very same float.

The one y flip of softpipe happens here, when a fragment is emitted: window row
``y`` (y up) becomes image row ``height − 1 − y`` (row 0 at the top).

The kernels are plain loops compiled by numba; with ``NUMBA_DISABLE_JIT=1`` they
run as Python and a debugger can step through the edge functions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ._parallel import in_bands
from .assembly import Primitives
from .sampling import CENTER, SUBPIXEL, SamplePattern

__all__ = ["Fragments", "rasterize", "count_fragments", "snap", "edge_function", "owns_samples_on_edge",
           "SHADING_POSITIONS", "barycentric_gradients"]

#: Where a fragment's barycentrics (its shading inputs) are taken: every sample on
#: its own (ordinary and supersampled rendering), or once per pixel at its centre
#: or at the centroid of its covered samples (multisampling).
SHADING_POSITIONS = ("sample", "center", "centroid")
SHADE_SAMPLE, SHADE_CENTER, SHADE_CENTROID = 0, 1, 2


@dataclass
class Fragments:
    """The rasterizer's output: one row per covered sample, in primitive order.

    Attributes
    ----------
    x, y : int32 [F]
        The pixel: column, and image row (row 0 at the top).
    sample : int32 [F]
        Index of the sample in the pattern.
    depth : float64 [F]
        Window-space depth at the sample.
    bary : float64 [F, 3]
        Window-space (linear) barycentrics of the sample w.r.t. the triangle's corners.
    triangle : int32 [F]
        Row in :class:`~softpipe.assembly.Primitives`.
    primitive_id : int64 [F]
        The input primitive the triangle came from.
    """

    x: np.ndarray
    y: np.ndarray
    sample: np.ndarray
    depth: np.ndarray
    bary: np.ndarray
    triangle: np.ndarray
    primitive_id: np.ndarray

    def __len__(self) -> int:
        return len(self.x)

    def __repr__(self) -> str:
        return f"Fragments({len(self)} covered samples from {len(np.unique(self.triangle))} triangles)"


# ------------------------------------------------------- the rules, one by one

@numba.njit(cache=True)
def snap(v):
    """Window coordinate → fixed point, 1/256 pixel, round half to even; centre of pixel i ↦ 256·i.

    Computed as rint(v·256) − 128, which equals round((v − ½)·256) exactly:
    v·256 is exact in floating point, while v − ½ could round.
    """
    return np.int64(np.rint(v * SUBPIXEL)) - SUBPIXEL // 2


@numba.njit(cache=True)
def edge_function(xa, ya, xb, yb, px, py):
    """Twice the signed area of (a, b, p): positive when p is left of a→b (y up)."""
    return (xb - xa) * (py - ya) - (yb - ya) * (px - xa)


@numba.njit(cache=True)
def owns_samples_on_edge(dx, dy):
    """The fill rule for a counter-clockwise triangle's edge with direction (dx, dy), y up.

    Going counter-clockwise, a left edge runs downward (dy < 0) and the bottom
    horizontal edge runs to the right (dy = 0, dx > 0): those own their samples.
    """
    return dy < 0 or (dy == 0 and dx > 0)


@numba.njit(cache=True)
def _setup(window, t):
    """Triangle setup: snapped corners, orientation sign, and twice the (positive) area."""
    x0, y0 = snap(window[t, 0, 0]), snap(window[t, 0, 1])
    x1, y1 = snap(window[t, 1, 0]), snap(window[t, 1, 1])
    x2, y2 = snap(window[t, 2, 0]), snap(window[t, 2, 1])
    area = edge_function(x0, y0, x1, y1, x2, y2)
    sign = np.int64(1) if area > 0 else np.int64(-1)
    return x0, y0, x1, y1, x2, y2, sign, area * sign


@numba.njit(cache=True)
def _bias(xa, ya, xb, yb, sign):
    """0 for an edge that owns the samples on it, −1 otherwise (E + bias ≥ 0 ⇔ covered)."""
    return np.int64(0) if owns_samples_on_edge(sign * (xb - xa), sign * (yb - ya)) else np.int64(-1)


@numba.njit(cache=True)
def _box(x0, x1, x2, lo_off, hi_off, first_pixel, last_pixel):
    """Pixels whose samples may lie inside [min, max] of the snapped corners, clamped to the
    pixel range [first_pixel, last_pixel] (the viewport within the framebuffer: the scissor)."""
    lo = min(x0, x1, x2) - hi_off
    hi = max(x0, x1, x2) - lo_off
    first = -((-lo) // SUBPIXEL)            # ceil(lo / 256)
    last = hi // SUBPIXEL                   # floor(hi / 256)
    return max(first, first_pixel), min(last, last_pixel)


@numba.njit(cache=True)
def _covered(x0, y0, x1, y1, x2, y2, sign, b0, b1, b2, px, py):
    """The three oriented edge functions at (px, py), and whether the fill rule covers it."""
    e0 = sign * edge_function(x1, y1, x2, y2, px, py)
    e1 = sign * edge_function(x2, y2, x0, y0, px, py)
    e2 = sign * edge_function(x0, y0, x1, y1, px, py)
    return e0, e1, e2, e0 + b0 >= 0 and e1 + b1 >= 0 and e2 + b2 >= 0


@numba.njit(cache=True)
def _cover_triangle(window, t, rect, height, offsets, mode, out_x, out_y, out_s, out_depth, out_bary, start,
                    emit):
    """Visit every covered sample of triangle t; write them from ``start`` if ``emit``. Returns the count.

    Depth is always the sample's. The barycentrics written are the sample's
    (``mode`` SHADE_SAMPLE), the pixel centre's (SHADE_CENTER) or those of the
    centroid of the pixel's covered samples (SHADE_CENTROID): where a
    multisampled fragment is shaded.
    """
    x0, y0, x1, y1, x2, y2, sign, area = _setup(window, t)
    if area == 0:
        return 0
    b0 = _bias(x1, y1, x2, y2, sign)        # edge opposite corner 0
    b1 = _bias(x2, y2, x0, y0, sign)
    b2 = _bias(x0, y0, x1, y1, sign)
    ox_lo, ox_hi = offsets[:, 0].min(), offsets[:, 0].max()
    oy_lo, oy_hi = offsets[:, 1].min(), offsets[:, 1].max()
    i_first, i_last = _box(x0, x1, x2, ox_lo, ox_hi, rect[0], rect[1])
    j_first, j_last = _box(y0, y1, y2, oy_lo, oy_hi, rect[2], rect[3])
    z0, dz1, dz2 = window[t, 0, 2], window[t, 1, 2] - window[t, 0, 2], window[t, 2, 2] - window[t, 0, 2]
    inv_area = 1.0 / area
    n = 0
    for j in range(j_first, j_last + 1):
        for i in range(i_first, i_last + 1):
            # which samples of pixel (i, j) are covered: a bit mask, and their centroid
            mask = np.int64(0)
            count = 0
            sum_x = np.int64(0)
            sum_y = np.int64(0)
            for s in range(offsets.shape[0]):
                px = i * SUBPIXEL + offsets[s, 0]
                py = j * SUBPIXEL + offsets[s, 1]
                if _covered(x0, y0, x1, y1, x2, y2, sign, b0, b1, b2, px, py)[3]:
                    mask |= np.int64(1) << s
                    count += 1
                    sum_x += px
                    sum_y += py
            if count == 0 or not emit:
                n += count
                continue
            c0, c1, c2 = 0.0, 0.0, 0.0
            if mode == SHADE_CENTER:
                c0, c1, c2, _ = _covered(x0, y0, x1, y1, x2, y2, sign, b0, b1, b2, i * SUBPIXEL, j * SUBPIXEL)
            elif mode == SHADE_CENTROID:
                c0, c1, c2, _ = _covered(x0, y0, x1, y1, x2, y2, sign, b0, b1, b2, sum_x / count, sum_y / count)
            for s in range(offsets.shape[0]):
                if not (mask >> s) & 1:
                    continue
                px = i * SUBPIXEL + offsets[s, 0]
                py = j * SUBPIXEL + offsets[s, 1]
                e0, e1, e2, _ = _covered(x0, y0, x1, y1, x2, y2, sign, b0, b1, b2, px, py)
                w0, w1, w2 = e0 * inv_area, e1 * inv_area, e2 * inv_area
                k = start + n
                out_x[k] = i
                out_y[k] = height - 1 - j   # the y flip: window row → image row
                out_s[k] = s
                z = z0 + (e1 * dz1 + e2 * dz2) * inv_area     # = b0 z0 + b1 z1 + b2 z2
                out_depth[k] = min(max(z, 0.0), 1.0)
                if mode != SHADE_SAMPLE:
                    w0, w1, w2 = c0 * inv_area, c1 * inv_area, c2 * inv_area
                out_bary[k, 0] = w0
                out_bary[k, 1] = w1
                out_bary[k, 2] = w2
                n += 1
    return n


@numba.njit(cache=True, nogil=True)
def _count_kernel(lo, hi, window, rect, height, offsets, counts):
    """The covered samples of triangles lo:hi (run in bands by softpipe._parallel)."""
    dummy_i = np.empty(0, np.int32)
    dummy_f = np.empty(0, np.float64)
    dummy_b = np.empty((0, 3), np.float64)
    for t in range(lo, hi):
        counts[t] = _cover_triangle(window, t, rect, height, offsets, SHADE_SAMPLE,
                                    dummy_i, dummy_i, dummy_i, dummy_f, dummy_b, 0, False)


@numba.njit(cache=True, nogil=True)
def _emit_kernel(lo, hi, window, first, starts, rect, height, offsets, mode, out_x, out_y, out_s, out_depth,
                 out_bary, out_tri):
    """The fragments of triangles first + lo : first + hi, each at its start (run in bands)."""
    for t in range(first + lo, first + hi):
        begin = starts[t]
        n = _cover_triangle(window, t, rect, height, offsets, mode, out_x, out_y, out_s, out_depth, out_bary,
                            begin, True)
        for k in range(begin, begin + n):
            out_tri[k] = t


def barycentric_gradients(prims: Primitives) -> np.ndarray:
    """∂b_k/∂x and ∂b_k/∂y of each triangle's window-space barycentrics, per pixel: [P, 2, 3].

    From the snapped corners: E_k changes by −(Y_b − Y_a)·256 per pixel in x and
    (X_b − X_a)·256 in y, and b_k = E_k / area. Zero for zero-area triangles.
    (These are what make screen-space derivatives, e.g. for mipmapping, exact.)
    """
    w = prims.window
    X = np.rint(w[:, :, 0] * SUBPIXEL).astype(np.int64) - SUBPIXEL // 2
    Y = np.rint(w[:, :, 1] * SUBPIXEL).astype(np.int64) - SUBPIXEL // 2
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (Y[:, 1] - Y[:, 0]) * (X[:, 2] - X[:, 0])
    sign = np.where(area > 0, 1, -1)
    out = np.zeros((len(w), 2, 3))
    ok = area != 0
    scale = np.where(ok, SUBPIXEL / np.where(ok, np.abs(area), 1), 0.0)
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3            # edge a→b is opposite corner k
        out[:, 0, k] = -sign * (Y[:, b] - Y[:, a]) * scale
        out[:, 1, k] = sign * (X[:, b] - X[:, a]) * scale
    return out


def pixel_rect(width: int, height: int, viewport=None) -> np.ndarray:
    """The window pixels a draw may touch, (i_min, i_max, j_min, j_max): the viewport ∩ framebuffer.

    Clipping to the view volume keeps geometry inside the viewport; with a guard
    band the rasterizer does that part, as a scissor rectangle.
    """
    if viewport is None:
        return np.array([0, width - 1, 0, height - 1], np.int64)
    return np.array([max(viewport.x, 0), min(viewport.x + viewport.width, width) - 1,
                     max(viewport.y, 0), min(viewport.y + viewport.height, height) - 1], np.int64)


def count_fragments(prims: Primitives, width: int, height: int, pattern: SamplePattern = CENTER,
                    rect: np.ndarray | None = None) -> np.ndarray:
    """How many samples each triangle covers (int64 [P]); the rasterizer's first pass."""
    counts = np.zeros(len(prims), dtype=np.int64)
    rect = pixel_rect(width, height) if rect is None else rect
    if len(prims):
        in_bands(_count_kernel, len(prims), prims.window, rect, height, pattern.offsets, counts, grain=256)
    return counts


def rasterize(prims: Primitives, width: int, height: int, pattern: SamplePattern = CENTER,
              first: int = 0, last: int | None = None, counts: np.ndarray | None = None,
              shading: str = "sample", rect: np.ndarray | None = None) -> Fragments:
    """The covered samples of triangles ``first:last`` (all by default), in primitive order.

    Within a triangle, fragments come row by row from the bottom of the window
    (y up), left to right, sample by sample, so the samples one triangle covers
    in one pixel are consecutive. ``shading`` says where the barycentrics are
    taken: at each "sample", the pixel "center", or the "centroid" of the
    pixel's covered samples (see :data:`SHADING_POSITIONS`).
    """
    if shading not in SHADING_POSITIONS:
        raise ValueError(f"sample_shading must be one of {SHADING_POSITIONS}, got {shading!r}")
    mode = SHADING_POSITIONS.index(shading)
    rect = pixel_rect(width, height) if rect is None else rect
    last = len(prims) if last is None else last
    if counts is None:
        counts = count_fragments(prims, width, height, pattern, rect)
    starts = np.zeros(len(prims) + 1, dtype=np.int64)
    np.cumsum(counts, out=starts[1:])
    starts -= starts[first]
    total = int(starts[last]) if len(prims) else 0
    x = np.empty(total, np.int32)
    y = np.empty(total, np.int32)
    s = np.empty(total, np.int32)
    depth = np.empty(total, np.float64)
    bary = np.empty((total, 3), np.float64)
    tri = np.empty(total, np.int32)
    if total:
        in_bands(_emit_kernel, last - first, prims.window, first, starts, rect, height, pattern.offsets, mode, x, y,
                 s, depth, bary, tri, grain=256)
    return Fragments(x=x, y=y, sample=s, depth=depth, bary=bary, triangle=tri,
                     primitive_id=prims.primitive_id[tri] if total else np.zeros(0, np.int64))
