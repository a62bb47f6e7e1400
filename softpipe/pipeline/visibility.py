"""The fast path: early depth, then shading of the visible samples only — the same stages in another order.

For a draw whose result depends only on which fragment is written last at
each sample (no blending, no discard), the pipeline can skip shading every
fragment. As in Mesa's softpipe, where early depth is the same quad stages in
another order chosen by one function, this is a configuration of the one
pipeline, not a second one: the same assembly, the same triangle setup
(``setup.py``), the same depth test (``output.depth_passes``), the same
generated shading code (``kernels.py``). :func:`choose_path` is the one place
that decides which order a draw takes.

1. **Setup** (:func:`~softpipe.pipeline.setup.setup_triangles`): the triangle setup
   the reference rasterizer uses too.
2. **Binning** (:func:`bin_triangles`): each 128×32 tile gets the list of
   triangles whose box touches it, in primitive order.
3. **Visibility** (:func:`visibility_pass`): bands of tiles run in parallel;
   inside a tile, triangles in order; each row's covered span comes from
   solving the three edge inequalities exactly in integers (a triangle less
   than :data:`NARROW` pixels wide in the tile has each sample's edges tested
   instead: cheaper for small triangles), then the depth test runs per sample
   and the visibility buffer keeps the last triangle that passed. Output:
   :class:`Visibility`.
4. **Shading** (:func:`shade_visible`, the generated ``visible_loop`` of
   ``kernels.py``): the fragment shader runs once per sample whose visibility
   entry is set (with multisampling, once per pixel and triangle there), with
   the barycentrics, depth and window position of the triangle setup's
   functions, as the reference rasterizer computes them. Output:
   :class:`ShadedSamples` (the colors are in the framebuffer).

The result is the same bytes as the reference path (rasterize every fragment,
shade it, merge in order), because there the final color of a sample is the
shader's output for the last fragment that passed the depth test. Tests hold
the two paths to identical color and depth.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple

import numba
import numpy as np

from softpipe.language import kernels
from softpipe.core.parallel import in_bands, threads
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.fragment import default_fragment_shader, derivative_gradients
from softpipe.pipeline.output import DEPTH_FUNCS, MergeState, depth_passes
from softpipe.pipeline.raster import Fragments
from softpipe.pipeline.sampling import SUBPIXEL
from softpipe.pipeline.setup import (SHADE_SAMPLE, SHADING_POSITIONS, TriangleSetup, covers, depth_at, edge_values, offset_bounds,
                    pixel_coverage, plane_depth, sample_depth, shading_point)

__all__ = ["TILE_W", "TILE_H", "NARROW", "Visibility", "ShadedSamples", "bin_triangles", "visibility_pass",
           "shade_visible", "choose_path", "fast_path_blocker", "PATHS", "FAST_PATH_MIN_SAMPLES", "DiscardOnFastPath",
           "shading_may_fail"]

#: Tiles are wide and short: rows inside a tile are long enough for the compiler's
#: vectorized loop to pay off, and a tile's depth and visibility (128×32×8 bytes)
#: stay in the core's cache while every triangle binned to it is drawn.
TILE_W, TILE_H = 128, 32

#: The orders a draw can take: "reference" (rasterize, shade every fragment, merge
#: in order), "fast" (this module), or "auto" (fast when it can, see :func:`choose_path`).
PATHS = ("auto", "reference", "fast")
#: path="auto" takes the fast path from this many framebuffer samples on
#: (small draws, such as most tests, keep to the reference path and its compile costs).
FAST_PATH_MIN_SAMPLES = 128 * 128


# ------------------------------------------------------------------ the decision

def fast_path_blocker(state: MergeState, fragment_shader: Optional[Callable]) -> Optional[str]:
    """Why a draw with this merge state and shader cannot take the fast path, or None if it can."""
    if state.blend is not None:
        return "blending is on (the result depends on every fragment, not only the last)"
    if fragment_shader is not None and kernels.may_discard(fragment_shader):
        return "the fragment shader may return DISCARD"
    if state.depth_test == "notequal" and state.depth_write and not (
            fragment_shader is not None and kernels.alpha_is_finite(fragment_shader)):
        # the one compare function under which discarding a hidden fragment can change which one shows
        return ("depth test 'notequal' with depth writes, and a fragment shader whose alpha is not a finite "
                "literal (a hidden fragment it discarded could change the picture)")
    return None


def choose_path(path: str, state: MergeState, fragment_shader: Optional[Callable], samples: int,
                keep_fragments: bool = False) -> Tuple[str, str]:
    """Which order a draw takes, and why: ("reference" | "fast", reason).

    ``path`` is the draw's request (:data:`PATHS`), ``samples`` the framebuffer's
    width × height × samples per pixel, ``keep_fragments`` whether the caller
    needs every fragment (a trace with ``path="auto"``).
    """
    if path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, got {path!r}")
    if path == "reference":
        return "reference", "path='reference' was asked for"
    blocker = fast_path_blocker(state, fragment_shader)
    if path == "fast":
        if blocker:
            raise ValueError(f"path='fast' is not possible for this draw: {blocker}")
        return "fast", "path='fast' was asked for"
    if blocker:
        return "reference", blocker
    if keep_fragments:
        return "reference", "a trace keeps every fragment, which only the reference path makes (path='fast' traces the fast path)"
    if samples < FAST_PATH_MIN_SAMPLES:
        return "reference", f"a small framebuffer ({samples} samples < FAST_PATH_MIN_SAMPLES = {FAST_PATH_MIN_SAMPLES})"
    return "fast", "opaque draw without discard: only the visible samples are shaded"


# --------------------------------------------------------------- the visibility pass

#: Binning runs in bands of at least this many triangles (each counted, then filled, on its own),
#: two per thread at most. Handing bands to the helper threads costs about 0.3 ms a phase, more
#: than binning the sphere's 68k triangles in the calling thread (0.45 ms for both phases).
BIN_BAND_MIN = 131072


def bin_triangles(box, tiles_x, tiles_y):
    """Triangles per tile, in primitive order: (starts [tiles + 1], items).

    In bands of triangles, in parallel: each band counts its triangles per tile, a prefix
    sum over (tile, band) gives every band its place in each tile's list, and each band
    fills its places. Band b's triangles come before band b + 1's in every tile, so the
    lists are in primitive order, the same for any thread count.
    """
    n_tiles = tiles_x * tiles_y
    bands = max(1, min(2 * threads(), box.shape[0] // BIN_BAND_MIN))
    bounds = np.linspace(0, box.shape[0], bands + 1).astype(np.int64)
    counts = np.zeros((bands, n_tiles), np.int64)
    in_bands(_bin_count, bands, bounds, box, tiles_x, counts)
    starts, fill = _bin_places(counts)
    items = np.empty(starts[-1], np.int32)
    in_bands(_bin_fill, bands, bounds, box, tiles_x, fill, items)
    return starts, items


@numba.njit(cache=True, nogil=True)
def _bin_count(band_lo, band_hi, bounds, box, tiles_x, counts):
    for band in range(band_lo, band_hi):
        for t in range(bounds[band], bounds[band + 1]):
            if box[t, 0] > box[t, 1] or box[t, 2] > box[t, 3]:
                continue
            for ty in range(box[t, 2] // TILE_H, box[t, 3] // TILE_H + 1):
                for tx in range(box[t, 0] // TILE_W, box[t, 1] // TILE_W + 1):
                    counts[band, ty * tiles_x + tx] += 1


def _bin_places(counts):
    """(starts [tiles + 1], fill [bands, tiles]): where each tile's list begins, and each band's place in it.

    A prefix sum over (tile, band) in that order; numpy's (the arrays are a few hundred
    entries: a compiled loop would cost its compile at a cold start and save nothing).
    """
    bands, n_tiles = counts.shape
    running = np.zeros(n_tiles * bands + 1, np.int64)
    np.cumsum(counts.T.ravel(), out=running[1:])
    fill = running[:-1].reshape(n_tiles, bands).T.copy()     # (copies: _bin_fill counts fill up in place)
    return running[::bands].copy(), fill


@numba.njit(cache=True, nogil=True)
def _bin_fill(band_lo, band_hi, bounds, box, tiles_x, fill, items):
    for band in range(band_lo, band_hi):
        for t in range(bounds[band], bounds[band + 1]):
            if box[t, 0] > box[t, 1] or box[t, 2] > box[t, 3]:
                continue
            for ty in range(box[t, 2] // TILE_H, box[t, 3] // TILE_H + 1):
                for tx in range(box[t, 0] // TILE_W, box[t, 1] // TILE_W + 1):
                    tile = ty * tiles_x + tx
                    items[fill[band, tile]] = t
                    fill[band, tile] += 1


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
    _, e1, e2 = edge_values(edges, t, float(px), float(py))
    return depth_at(plane, t, e1, e2)


@numba.njit(cache=True)
def _covers_box(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi):
    """Are all samples of pixels [i0, i1] × [j0, j1] inside the triangle? (Convex: the corners decide.)"""
    qx0, qx1 = i0 * SUBPIXEL + ox_lo, i1 * SUBPIXEL + ox_hi
    qy0, qy1 = j0 * SUBPIXEL + oy_lo, j1 * SUBPIXEL + oy_hi
    return (covers(edges, bias, t, qx0, qy0) and covers(edges, bias, t, qx1, qy0)
            and covers(edges, bias, t, qx0, qy1) and covers(edges, bias, t, qx1, qy1))


@numba.njit(cache=True)
def _row_less(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, strict, write):
    """One span (contiguous views of one row of one sample plane) under LESS (strict) or LEQUAL.

    Written so that the compiler vectorizes it: 1-D contiguous views indexed
    from 0, and selects rather than branches. e1 + k·a1 is exact in float64
    (integers below 2^53), so the depth is the reference rasterizer's
    (:func:`~softpipe.pipeline.setup.plane_depth`).
    """
    for k in range(drow.shape[0]):
        kf = float(k)
        zf = np.float32(plane_depth(z0, dz1, dz2, inv_area, e1 + kf * a1, e2 + kf * a2))
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
        zf = np.float32(plane_depth(z0, dz1, dz2, inv_area, e1 + kf * a1, e2 + kf * a2))
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

    Along a row the edge values step by A_k·256 (exact integers); depth is
    :func:`~softpipe.pipeline.setup.plane_depth` of the sample's exact edge values.
    """
    z0, dz1, dz2, inv_area = plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3]
    step0, step1, step2 = edges[t, 0, 0] * SUBPIXEL, edges[t, 1, 0] * SUBPIXEL, edges[t, 2, 0] * SUBPIXEL
    for s in range(offsets.shape[0]):
        ox, oy = offsets[s, 0], offsets[s, 1]
        px = i0 * SUBPIXEL + ox
        for j in range(j0, j1 + 1):
            py = j * SUBPIXEL + oy
            row = height - 1 - j
            e0, e1, e2 = edge_values(edges, t, px, py)
            for i in range(i0, i1 + 1):
                if e0 + bias[t, 0] >= 0 and e1 + bias[t, 1] >= 0 and e2 + bias[t, 2] >= 0:
                    zf = np.float32(plane_depth(z0, dz1, dz2, inv_area, e1, e2))
                    if depth_passes(func, zf, depth[s, row, i]):
                        if write:
                            depth[s, row, i] = zf
                        vis[s, row, i] = t
                e0 += step0
                e1 += step1
                e2 += step2


@numba.njit(cache=True)
def _draw_spans(edges, bias, plane, t, i0, i1, j0, j1, whole, offsets, height, func, write, depth, vis):
    """Depth-test the covered samples of pixels [i0, i1] × [j0, j1] row span by row span.

    ``whole``: every sample of the box is inside (no span to solve).
    """
    z0, dz1, dz2, inv_area = plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3]
    a1, a2 = float(edges[t, 1, 0] * SUBPIXEL), float(edges[t, 2, 0] * SUBPIXEL)
    for s in range(offsets.shape[0]):
        ox, oy = offsets[s, 0], offsets[s, 1]
        dplane, vplane = depth[s], vis[s]
        for j in range(j0, j1 + 1):
            py = j * SUBPIXEL + oy
            lo, hi = (i0, i1) if whole else _span(edges, bias, t, ox, py, i0, i1)
            if lo > hi:
                continue
            px = lo * SUBPIXEL + ox
            _, e1i, e2i = edge_values(edges, t, px, py)
            e1, e2 = float(e1i), float(e2i)
            row = height - 1 - j
            drow, vrow = dplane[row, lo:hi + 1], vplane[row, lo:hi + 1]
            if func == LESS or func == LEQUAL:
                _row_less(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func == LESS, write)
            else:
                _row_any(drow, vrow, t, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func, write)


@numba.njit(cache=True, inline="never")
def _save_tile(depth, saved_depth, row_lo, row_hi, col_lo, col_hi):
    for s in range(depth.shape[0]):
        for row in range(row_lo, row_hi):
            for i in range(col_lo, col_hi):
                saved_depth[s, row, i] = depth[s, row, i]


@numba.njit(cache=True, inline="always")
def _raster_tile(tile, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func, depth_write,
                 depth, vis, touched, saved_depth):
    """One tile of the visibility pass: its triangles, in primitive order (see :func:`raster_tiles`)."""
    hiz = depth_write and (func == LESS or func == LEQUAL)
    ox_lo, ox_hi, oy_lo, oy_hi = offset_bounds(offsets)
    tx, ty = tile % tiles_x, tile // tiles_x
    x_lo, x_hi = tx * TILE_W, min(tx * TILE_W + TILE_W, width) - 1
    y_lo, y_hi = ty * TILE_H, min(ty * TILE_H + TILE_H, height) - 1
    for s in range(offsets.shape[0]):      # nothing visible yet (here, in parallel, not one serial fill)
        for row in range(height - 1 - y_hi, height - y_lo):
            vis[s, row, x_lo:x_hi + 1] = -1
    far = 0.0
    save = saved_depth.shape[0] > 0
    tile_touched = touched[tile]
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
            if whole_tile and _covers_box(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi):
                far = min(far, max(za, zb, zc, zd) + HIZ_MARGIN)
        if not tile_touched:
            if save:                        # the tile's depth before this draw, to undo it (shade_visible)
                _save_tile(depth, saved_depth, height - 1 - y_hi, height - y_lo, x_lo, x_hi + 1)
            # written once per tile, not per triangle: neighbouring tiles' flags share a cache
            # line, and the other thread is drawing those tiles
            touched[tile] = tile_touched = True
        if i1 - i0 < NARROW:
            _draw_narrow(edges, bias, plane, t, i0, i1, j0, j1, offsets, height, func, depth_write, depth, vis)
        else:
            whole = _covers_box(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi)
            _draw_spans(edges, bias, plane, t, i0, i1, j0, j1, whole, offsets, height, func, depth_write,
                        depth, vis)


@numba.njit(cache=True, nogil=True)
def raster_tiles(tile_lo, tile_hi, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func,
                 depth_write, depth, vis, touched, saved_depth):
    """The visibility pass over tiles [tile_lo, tile_hi); see the module docstring.

    Hierarchical depth (LESS/LEQUAL with writes): each tile keeps an upper bound
    of its depths; a triangle whose nearest point over the tile lies beyond it
    cannot pass anywhere there and is skipped; a triangle that covers the whole
    tile lowers the bound to its own farthest depth there. ``touched[tile]`` is
    set for every tile where some triangle was depth-tested (the others keep no
    visible sample of this draw: shading skips them); unless ``saved_depth`` is
    empty, such a tile's depth is first copied there (to undo the draw).
    """
    for tile in range(tile_lo, tile_hi):
        _raster_tile(tile, edges, bias, plane, box, starts, items, tiles_x, width, height, offsets, func,
                     depth_write, depth, vis, touched, saved_depth)


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
        modes = module._softpipe_failure_modes = (kernels.may_raise(shader), not kernels.alpha_is_finite(shader))
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

    Both are computed when first asked for (a full-frame pass each), not by every draw.
    """

    def __init__(self, visibility: Visibility, shading: str):
        self.visibility, self.shading = visibility, shading

    @property
    def written(self) -> np.ndarray:
        return self.visibility.vis >= 0

    @property
    def invocations(self) -> int:
        return _invocations(self.visibility.vis, self.shading)

    def __repr__(self) -> str:
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
#: to map (page faults: 6 ms for a 1920×1080 color buffer) than the copies made into them.
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
            np.empty((0, 0, 0, 4), np.float32), np.zeros(fb.height, np.bool_), np.zeros(1, np.int64))


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
    except BaseException:
        visibility.restore_depth(fb)
        _release(visibility.saved_depth)
        visibility.saved_depth = None
        raise
    finally:
        _release(saved_color)
    _release(visibility.saved_depth)
    visibility.saved_depth = None          # the draw stands: nothing to undo
    return ShadedSamples(visibility, shading)


def _invocations(vis: np.ndarray, shading: str) -> int:
    """Shader invocations of visible_loop: every visible sample, or each (pixel, triangle) once."""
    if shading == "sample" or vis.shape[0] == 1:
        return int((vis >= 0).sum())
    seen = vis >= 0
    for s in range(1, vis.shape[0]):
        seen[s] &= (vis[:s] != vis[s]).all(axis=0)
    return int(seen.sum())
