"""The fast path: tiled rasterization with early depth, then shading of the visible samples only.

For a draw whose result depends only on which fragment is written last at
each sample (no blending, no discard), the pipeline can skip shading every
fragment:

1. **Setup** (:func:`setup_triangles`): each triangle's snapped edge functions
   as ``E_k(p) = A_k·p_x + B_k·p_y + C_k`` (oriented, exact int64), its fill-rule
   biases, depth plane and pixel bounding box — the same numbers the reference
   rasterizer (``raster.py``) computes.
2. **Binning** (:func:`bin_triangles`): each 128×32 tile gets the list of
   triangles whose box touches it, in primitive order.
3. **Visibility** (:func:`raster_tiles`): bands of tiles run in parallel; inside a tile,
   triangles in order; each row's covered span comes from solving the three
   edge inequalities exactly in integers (a triangle less than :data:`NARROW`
   pixels wide in the tile has each sample's edges tested instead: cheaper
   for small triangles), then the depth test runs per sample and the
   visibility buffer keeps the last triangle that passed. Depth is
   computed by the same expression as in the reference rasterizer, so the
   depth buffer is identical.
4. **Shading** (``shader.visible_kernel``): the fragment shader runs once per
   sample whose visibility entry is set (with multisampling, once per pixel
   and triangle there), with the barycentrics, depth and window position
   recomputed exactly as the reference path computes them.

The result is the same bytes as the reference path (rasterize every fragment,
shade it, merge in order), because there the final color of a sample is the
shader's output for the last fragment that passed the depth test. Tests hold
the two paths to identical color and depth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ._parallel import in_bands
from .output import depth_passes
from .raster import _covered, _setup, snap
from .sampling import SUBPIXEL

__all__ = ["TILE_W", "TILE_H", "Visibility", "setup_triangles", "bin_triangles", "raster_tiles", "visibility_pass"]

#: Tiles are wide and short: rows inside a tile are long enough for the compiler's
#: vectorized loop to pay off, and a tile's depth and visibility (128×32×8 bytes)
#: stay in the core's cache while every triangle binned to it is drawn.
TILE_W, TILE_H = 128, 32


@numba.njit(cache=True, nogil=True)
def setup_triangles(lo, hi, window, rect, offsets, edges, bias, plane, box):
    """Per triangle t in [lo, hi): oriented edge coefficients [T, 3, 3] (A, B, C), biases [T, 3],
    depth plane [T, 4] (z0, z1 − z0, z2 − z0, 1/area) and pixel box [T, 4]
    (i0, i1, j0, j1; empty when i0 > i1)."""
    ox_lo, ox_hi = offsets[:, 0].min(), offsets[:, 0].max()
    oy_lo, oy_hi = offsets[:, 1].min(), offsets[:, 1].max()
    for t in range(lo, hi):
        x = (snap(window[t, 0, 0]), snap(window[t, 1, 0]), snap(window[t, 2, 0]))
        y = (snap(window[t, 0, 1]), snap(window[t, 1, 1]), snap(window[t, 2, 1]))
        area = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0])
        sign = np.int64(1) if area > 0 else np.int64(-1)
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3            # edge a→b, opposite corner k
            dx, dy = sign * (x[b] - x[a]), sign * (y[b] - y[a])
            edges[t, k, 0] = -dy
            edges[t, k, 1] = dx
            edges[t, k, 2] = dy * x[a] - dx * y[a]
            bias[t, k] = 0 if (dy < 0 or (dy == 0 and dx > 0)) else -1
        z0 = window[t, 0, 2]
        plane[t, 0] = z0
        plane[t, 1] = window[t, 1, 2] - z0
        plane[t, 2] = window[t, 2, 2] - z0
        plane[t, 3] = 1.0 / (area * sign) if area != 0 else 0.0
        if area == 0:
            box[t, 0], box[t, 1], box[t, 2], box[t, 3] = 1, 0, 1, 0
            continue
        lo_x, hi_x = min(x[0], x[1], x[2]) - ox_hi, max(x[0], x[1], x[2]) - ox_lo
        lo_y, hi_y = min(y[0], y[1], y[2]) - oy_hi, max(y[0], y[1], y[2]) - oy_lo
        box[t, 0] = max(-((-lo_x) // SUBPIXEL), rect[0])
        box[t, 1] = min(hi_x // SUBPIXEL, rect[1])
        box[t, 2] = max(-((-lo_y) // SUBPIXEL), rect[2])
        box[t, 3] = min(hi_y // SUBPIXEL, rect[3])


@numba.njit(cache=True)
def bin_triangles(box, tiles_x, tiles_y):
    """Triangles per tile, in primitive order: (starts [tiles + 1], items)."""
    n_tiles = tiles_x * tiles_y
    counts = np.zeros(n_tiles + 1, np.int64)
    for t in range(box.shape[0]):
        if box[t, 0] > box[t, 1] or box[t, 2] > box[t, 3]:
            continue
        for ty in range(box[t, 2] // TILE_H, box[t, 3] // TILE_H + 1):
            for tx in range(box[t, 0] // TILE_W, box[t, 1] // TILE_W + 1):
                counts[ty * tiles_x + tx + 1] += 1
    starts = np.cumsum(counts)
    items = np.empty(starts[-1], np.int32)
    fill = starts[:-1].copy()
    for t in range(box.shape[0]):
        if box[t, 0] > box[t, 1] or box[t, 2] > box[t, 3]:
            continue
        for ty in range(box[t, 2] // TILE_H, box[t, 3] // TILE_H + 1):
            for tx in range(box[t, 0] // TILE_W, box[t, 1] // TILE_W + 1):
                tile = ty * tiles_x + tx
                items[fill[tile]] = t
                fill[tile] += 1
    return starts, items


@numba.njit(cache=True)
def _span(edges, bias, t, px0, py, i_lo, i_hi):
    """The pixels i in [i_lo, i_hi] whose sample (256·i + px0, py) every edge covers.

    E_k = A·(256 i + px0) + B·py + C + bias ≥ 0 is linear in i; each edge bounds i
    from one side. The bound is estimated in floating point (a division is far
    cheaper there than in 64-bit integers) and then made exact by testing the
    integer inequality itself, so the span is exactly the covered pixels.
    """
    for k in range(3):
        a = edges[t, k, 0] * SUBPIXEL
        r = edges[t, k, 0] * px0 + edges[t, k, 1] * py + edges[t, k, 2] + bias[t, k]   # E at i = 0
        if a > 0:                      # first i with r + a·i ≥ 0
            i = np.int64(np.ceil(-r / a))
            while r + a * i < 0:
                i += 1
            while r + a * (i - 1) >= 0:
                i -= 1
            i_lo = max(i_lo, i)
        elif a < 0:                    # last i with r + a·i ≥ 0
            i = np.int64(np.floor(r / -a))
            while r + a * i < 0:
                i -= 1
            while r + a * (i + 1) >= 0:
                i += 1
            i_hi = min(i_hi, i)
        elif r < 0:
            return 1, 0
        if i_lo > i_hi:
            return 1, 0
    return i_lo, i_hi


#: Depth tests for which a tile's farthest depth can reject whole triangles (with writes on).
LESS, LEQUAL = 1, 3
#: Safety margin of the hierarchical depth test: far larger than any rounding in
#: the per-sample depth, far smaller than anything a picture could show.
HIZ_MARGIN = 1e-6


@numba.njit(cache=True)
def _plane_z(edges, plane, t, px, py):
    """The depth plane at a (possibly off-sample) fixed-point position, in float: for bounds only."""
    e1 = edges[t, 1, 0] * float(px) + edges[t, 1, 1] * float(py) + edges[t, 1, 2]
    e2 = edges[t, 2, 0] * float(px) + edges[t, 2, 1] * float(py) + edges[t, 2, 2]
    return plane[t, 0] + (e1 * plane[t, 1] + e2 * plane[t, 2]) * plane[t, 3]


@numba.njit(cache=True)
def _inside(edges, bias, t, px, py):
    for k in range(3):
        if edges[t, k, 0] * px + edges[t, k, 1] * py + edges[t, k, 2] + bias[t, k] < 0:
            return False
    return True


@numba.njit(cache=True)
def first_covered_sample(edges, bias, t, i, j, offsets):
    """The first sample of pixel (i, j), in pattern order, that triangle t covers (−1: none).

    Where the rasterizer's run of t's samples in that pixel starts: a
    multisampled fragment takes that sample's depth (``raster.py``).
    """
    for s in range(offsets.shape[0]):
        if _inside(edges, bias, t, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1]):
            return s
    return -1


@numba.njit(cache=True)
def centroid_of_run(window, edges, bias, t, i, j, offsets, positions):
    """Multisampling at the centroid: the run of triangle t's covered samples in pixel (i, j).

    Returns (its first sample, the three edge functions at the centroid of its
    samples, the centroid within the pixel), computed as the rasterizer and the
    fragment stage compute them: the centroid in subpixel units is the integer
    sum over the count, and its edge functions are ``raster._covered``'s on the
    snapped corners. (Sample positions are multiples of 1/256, so their sum is
    exact in any order.)
    """
    first, count = -1, 0
    sum_x, sum_y = np.int64(0), np.int64(0)
    pos_x, pos_y = 0.0, 0.0
    for s in range(offsets.shape[0]):
        px, py = i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1]
        if _inside(edges, bias, t, px, py):
            if first < 0:
                first = s
            count += 1
            sum_x += px
            sum_y += py
            pos_x += positions[s, 0]
            pos_y += positions[s, 1]
    x0, y0, x1, y1, x2, y2, sign, _ = _setup(window, t)
    e0, e1, e2, _ = _covered(x0, y0, x1, y1, x2, y2, sign, bias[t, 0], bias[t, 1], bias[t, 2],
                             sum_x / count, sum_y / count)
    return first, e0, e1, e2, pos_x / count, pos_y / count


@numba.njit(cache=True)
def same_triangle_before(vis, s, row, i):
    """An earlier sample of the pixel that shows the same triangle as sample s, or −1."""
    for earlier in range(s):
        if vis[earlier, row, i] == vis[s, row, i]:
            return earlier
    return -1


@numba.njit(cache=True)
def _covers(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi):
    """Are all samples of pixels [i0, i1] × [j0, j1] inside the triangle? (Convex: the corners decide.)"""
    qx0, qx1 = i0 * SUBPIXEL + ox_lo, i1 * SUBPIXEL + ox_hi
    qy0, qy1 = j0 * SUBPIXEL + oy_lo, j1 * SUBPIXEL + oy_hi
    return (_inside(edges, bias, t, qx0, qy0) and _inside(edges, bias, t, qx1, qy0)
            and _inside(edges, bias, t, qx0, qy1) and _inside(edges, bias, t, qx1, qy1))


@numba.njit(cache=True)
def _row_less(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, strict, write):
    """One span (contiguous views of one row of one sample plane) under LESS (strict) or LEQUAL.

    Written so that the compiler vectorizes it: 1-D contiguous views indexed
    from 0, and selects rather than branches. e1 + k·a1 is exact in float64
    (integers below 2^53), so z is the very expression the reference
    rasterizer evaluates.
    """
    for k in range(drow.shape[0]):
        kf = float(k)
        z = z0 + ((e1 + kf * a1) * dz1 + (e2 + kf * a2) * dz2) * inv_area
        zf = np.float32(min(max(z, 0.0), 1.0))
        old = drow[k]
        passed = zf < old if strict else zf <= old
        if write:
            drow[k] = zf if passed else old
        vrow[k] = t if passed else vrow[k]


@numba.njit(cache=True)
def _row_any(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func, write):
    """One span under any compare function."""
    for k in range(drow.shape[0]):
        kf = float(k)
        z = z0 + ((e1 + kf * a1) * dz1 + (e2 + kf * a2) * dz2) * inv_area
        zf = np.float32(min(max(z, 0.0), 1.0))
        if depth_passes(func, zf, drow[k]):
            if write:
                drow[k] = zf
            vrow[k] = t


#: A triangle whose box inside a tile is at most this many pixels wide is walked
#: sample by sample: for small triangles, testing each sample costs less than
#: solving each row's span.
NARROW = 16


@numba.njit(cache=True)
def _draw_narrow(edges, bias, plane, t, i0, i1, j0, j1, offsets, height, func, write, depth, vis):
    """Depth-test the covered samples of pixels [i0, i1] × [j0, j1], testing every sample's edges.

    Along a row the edge values step by A_k·256 (exact integers); depth is the
    reference rasterizer's expression on the sample's exact edge values.
    """
    z0, dz1, dz2, inv_area = plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3]
    step0, step1, step2 = edges[t, 0, 0] * SUBPIXEL, edges[t, 1, 0] * SUBPIXEL, edges[t, 2, 0] * SUBPIXEL
    for s in range(offsets.shape[0]):
        ox, oy = offsets[s, 0], offsets[s, 1]
        px = i0 * SUBPIXEL + ox
        for j in range(j0, j1 + 1):
            py = j * SUBPIXEL + oy
            row = height - 1 - j
            e0 = edges[t, 0, 0] * px + edges[t, 0, 1] * py + edges[t, 0, 2]
            e1 = edges[t, 1, 0] * px + edges[t, 1, 1] * py + edges[t, 1, 2]
            e2 = edges[t, 2, 0] * px + edges[t, 2, 1] * py + edges[t, 2, 2]
            for i in range(i0, i1 + 1):
                if e0 + bias[t, 0] >= 0 and e1 + bias[t, 1] >= 0 and e2 + bias[t, 2] >= 0:
                    z = z0 + (e1 * dz1 + e2 * dz2) * inv_area
                    zf = np.float32(min(max(z, 0.0), 1.0))
                    if depth_passes(func, zf, depth[s, row, i]):
                        if write:
                            depth[s, row, i] = zf
                        vis[s, row, i] = t
                e0 += step0
                e1 += step1
                e2 += step2


@numba.njit(cache=True)
def _draw_spans(edges, bias, plane, t, i0, i1, j0, j1, covers, offsets, height, func, write, depth, vis):
    """Depth-test the covered samples of pixels [i0, i1] × [j0, j1] row span by row span.

    ``covers``: every sample of the box is inside (no span to solve).
    """
    z0, dz1, dz2, inv_area = plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3]
    a1, a2 = float(edges[t, 1, 0] * SUBPIXEL), float(edges[t, 2, 0] * SUBPIXEL)
    for s in range(offsets.shape[0]):
        ox, oy = offsets[s, 0], offsets[s, 1]
        dplane, vplane = depth[s], vis[s]
        for j in range(j0, j1 + 1):
            py = j * SUBPIXEL + oy
            lo, hi = (i0, i1) if covers else _span(edges, bias, t, ox, py, i0, i1)
            if lo > hi:
                continue
            px = lo * SUBPIXEL + ox
            e1 = float(edges[t, 1, 0] * px + edges[t, 1, 1] * py + edges[t, 1, 2])
            e2 = float(edges[t, 2, 0] * px + edges[t, 2, 1] * py + edges[t, 2, 2])
            row = height - 1 - j
            drow, vrow = dplane[row, lo:hi + 1], vplane[row, lo:hi + 1]
            if func == LESS or func == LEQUAL:
                _row_less(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func == LESS, write)
            else:
                _row_any(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func, write)


@numba.njit(cache=True)
def _raster_tile(tile, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func, depth_write,
                 depth, vis, touched):
    """One tile of the visibility pass: its triangles, in primitive order (see :func:`raster_tiles`)."""
    hiz = depth_write and (func == LESS or func == LEQUAL)
    ox_lo, ox_hi = offsets[:, 0].min(), offsets[:, 0].max()
    oy_lo, oy_hi = offsets[:, 1].min(), offsets[:, 1].max()
    tx, ty = tile % tiles_x, tile // tiles_x
    x_lo, x_hi = tx * TILE_W, min(tx * TILE_W + TILE_W, width) - 1
    y_lo, y_hi = ty * TILE_H, min(ty * TILE_H + TILE_H, height) - 1
    for s in range(offsets.shape[0]):      # nothing visible yet (here, in parallel, not one serial fill)
        for row in range(height - 1 - y_hi, height - y_lo):
            vis[s, row, x_lo:x_hi + 1] = -1
    far = 0.0
    if hiz and starts[tile + 1] > starts[tile]:
        for s in range(offsets.shape[0]):
            for row in range(height - 1 - y_hi, height - y_lo):
                for i in range(x_lo, x_hi + 1):
                    far = max(far, depth[s, row, i])
    for k in range(starts[tile], starts[tile + 1]):
        t = items[k]
        i0, i1 = max(box[t, 0], x_lo), min(box[t, 1], x_hi)
        j0, j1 = max(box[t, 2], y_lo), min(box[t, 3], y_hi)
        if i0 > i1 or j0 > j1:
            continue
        whole_tile = i0 == x_lo and i1 == x_hi and j0 == y_lo and j1 == y_hi
        if hiz and (far < 1.0 or whole_tile):      # (at far = 1, nothing can be rejected)
            # the rectangle holding every sample this triangle may cover in the tile
            qx0, qx1 = i0 * SUBPIXEL + ox_lo, i1 * SUBPIXEL + ox_hi
            qy0, qy1 = j0 * SUBPIXEL + oy_lo, j1 * SUBPIXEL + oy_hi
            za, zb = _plane_z(edges, plane, t, qx0, qy0), _plane_z(edges, plane, t, qx1, qy0)
            zc, zd = _plane_z(edges, plane, t, qx0, qy1), _plane_z(edges, plane, t, qx1, qy1)
            if min(za, zb, zc, zd) - HIZ_MARGIN > far:
                continue
            if whole_tile and _covers(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi):
                far = min(far, max(za, zb, zc, zd) + HIZ_MARGIN)
        touched[tile] = True
        if i1 - i0 < NARROW:
            _draw_narrow(edges, bias, plane, t, i0, i1, j0, j1, offsets, height, func, depth_write, depth, vis)
        else:
            covers = _covers(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi)
            _draw_spans(edges, bias, plane, t, i0, i1, j0, j1, covers, offsets, height, func, depth_write,
                        depth, vis)


@numba.njit(cache=True, nogil=True)
def raster_tiles(tile_lo, tile_hi, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func,
                 depth_write, depth, vis, touched):
    """The visibility pass over tiles [tile_lo, tile_hi); see the module docstring.

    Hierarchical depth (LESS/LEQUAL with writes): each tile keeps an upper bound
    of its depths; a triangle whose nearest point over the tile lies beyond it
    cannot pass anywhere there and is skipped; a triangle that covers the whole
    tile lowers the bound to its own farthest depth there. ``touched[tile]`` is
    set for every tile where some triangle was depth-tested (the others keep no
    visible sample of this draw: shading skips them).
    """
    for tile in range(tile_lo, tile_hi):
        _raster_tile(tile, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func,
                     depth_write, depth, vis, touched)


@dataclass
class Visibility:
    """What the visibility pass hands to shading: which triangle to shade at each sample.

    Attributes
    ----------
    vis : int32 [S, H, W]
        The triangle (row of the Primitives) whose fragment was written last at
        each sample by this draw, or −1.
    edges : int64 [T, 3, 3]
        Each triangle's oriented edge functions (A, B, C): the barycentrics are
        E_k / area, as the rasterizer computes them.
    bias : int64 [T, 3]
        The fill rule: a sample is covered when every E_k + bias_k ≥ 0.
    plane : float64 [T, 4]
        Each triangle's depth plane (z0, z1 − z0, z2 − z0, 1/area).
    touched : bool [tiles_y, tiles_x]
        Tiles (TILE_W × TILE_H pixels, in window coordinates: tile row 0 at the
        bottom) where some triangle was depth-tested; the others hold no ``vis`` entry.
    """

    vis: np.ndarray
    edges: np.ndarray
    bias: np.ndarray
    plane: np.ndarray
    touched: np.ndarray

    def __repr__(self) -> str:
        return (f"Visibility({int((self.vis >= 0).sum())} visible samples of {self.vis.size}, "
                f"{len(self.edges)} triangles, {int(self.touched.sum())} of {self.touched.size} tiles touched)")


def visibility_pass(prims, fb, func: int, depth_write: bool, rect: np.ndarray) -> Visibility:
    """Setup, binning and the tiled visibility pass of a draw's primitives; the framebuffer's depth is updated."""
    w, h, offsets = fb.width, fb.height, fb.pattern.offsets
    n = len(prims)
    edges = np.empty((n, 3, 3), np.int64)
    bias = np.empty((n, 3), np.int64)
    plane = np.empty((n, 4), np.float64)
    box = np.empty((n, 4), np.int64)
    vis = np.empty((len(offsets), h, w), np.int32)      # raster_tiles sets every tile to −1 first
    tiles_x, tiles_y = -(-w // TILE_W), -(-h // TILE_H)
    touched = np.zeros((tiles_y, tiles_x), np.bool_)
    if n == 0:
        vis.fill(-1)
        return Visibility(vis, edges, bias, plane, touched)
    in_bands(setup_triangles, n, prims.window, rect, offsets, edges, bias, plane, box, grain=4096)
    starts, items = bin_triangles(box, tiles_x, tiles_y)
    in_bands(raster_tiles, tiles_x * tiles_y, edges, bias, plane, box, starts, items, tiles_x, w, h, offsets,
             func, depth_write, fb.samples_depth, vis, touched.reshape(-1))
    return Visibility(vis, edges, bias, plane, touched)
