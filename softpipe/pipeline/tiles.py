"""The fast path's coverage walk: which samples of which tile a triangle covers, and does it pass the depth test there.

The second back end's rasterizer, beside the reference one (:mod:`softpipe.pipeline.raster`, which
emits every covered sample as a fragment for the output merger). It shares the
triangle setup with it and asks setup's rules rather than restating them
(:mod:`softpipe.pipeline.setup`: the fill rule :func:`~softpipe.pipeline.setup.inside_edge`, the
depth plane :func:`~softpipe.pipeline.setup.plane_depth`), and the depth compare
(``output.depth_passes``); it walks coverage its own way and keeps only a
visibility buffer, the last triangle that passed the depth test at each sample:

1. **Binning** (:func:`bin_triangles`): each TILE_W × TILE_H tile gets the list of
   triangles whose box touches it, in primitive order; when those lists jump about the
   mesh (:func:`scattered`), the setup is copied into their order (:func:`gather_setup`).
2. **Tiles** (:func:`raster_tiles`): bands of tiles in parallel; inside a tile, its
   triangles in order (so every sample sees them in the reference's order, on
   any thread count), and a hierarchical depth bound that skips the triangles
   lying behind everything there.
3. **Rows**: a triangle at least :data:`NARROW` pixels wide in the tile has each
   row's covered span solved from the three edge inequalities (made exact by the
   fill rule itself), and the depth test runs along the span in a loop the
   compiler vectorizes; a narrower one has each sample tested, on edge values
   stepped along the row (:func:`~softpipe.pipeline.setup.inside`).

:mod:`softpipe.pipeline.visibility` chooses the path, runs this pass and shades what it left
visible; docs/08-fast-path.md walks through both. Points and lines are binned here too
(:func:`bin_primitives`) and walk the same tiles by their own rules in
:mod:`softpipe.pipeline.primitive_tiles`.
"""
from __future__ import annotations

import numba
import numpy as np

from softpipe.core.parallel import in_bands, threads
from softpipe.pipeline.output import depth_passes
from softpipe.pipeline.sampling import SUBPIXEL
from softpipe.pipeline.setup import covers, depth_at, edge_values, inside, inside_edge, offset_bounds, plane_depth

__all__ = ["TILE_W", "TILE_H", "NARROW", "bin_triangles", "SCATTERED", "scattered", "gather_setup", "raster_tiles",
           "bin_primitives", "save_tile"]

#: Tiles are wide and short: rows inside a tile are long enough for the compiler's
#: vectorized loop to pay off, and a tile's depth and visibility (128×32×8 bytes)
#: stay in the core's cache while every triangle binned to it is drawn.
TILE_W, TILE_H = 128, 32

# ------------------------------------------------------------------------ binning

#: Binning runs in bands of at least this many triangles (each counted, then filled, on its own),
#: two per thread at most. Handing bands to the helper threads costs more than binning a
#: mesh of tens of thousands of triangles in the calling thread (benchmarks/README.md).
BIN_BAND_MIN = 131072


def bin_triangles(box: np.ndarray, tiles_x: int, tiles_y: int) -> tuple:
    """Triangles per tile, in primitive order: (starts [tiles + 1], items).

    In bands of triangles, in parallel: each band counts its triangles per tile, a prefix
    sum over (tile, band) gives every band its place in each tile's list, and each band
    fills its places. Band b's triangles come before band b + 1's in every tile, so the
    lists are in primitive order, the same for any thread count.

    Parameters
    ----------
    box : int64 [T, 4]
        The triangle setup's pixel boxes (i_0, i_1, j_0, j_1), window rows (y up);
        an empty box is binned nowhere.
    tiles_x, tiles_y : int
        Tiles across and up the framebuffer (tile ``ty * tiles_x + tx``, row 0 at the bottom).

    Returns
    -------
    starts : int64 [tiles + 1]
        Tile k's triangles are ``items[starts[k]:starts[k + 1]]``.
    items : int32
        The triangles (rows of the setup), tile after tile.
    """
    bands, bounds, starts, fill, items = _bin_layout(box, tiles_x, tiles_y, BIN_BAND_MIN)
    in_bands(_bin_fill, bands, bounds, box, tiles_x, fill, items)
    return starts, items


#: The share of a tile list's neighbours that are not consecutive triangles from which the visibility
#: pass copies the setup into the bins' order (:func:`gather_setup`): a mesh drawn in an order far from the
#: screen's (the bunny from its lights: 0.6) gains more than the copy costs; one in order (a UV sphere,
#: 0.03; ``tiny``, 0.01) only pays for it (benchmarks/README.md, issue 35).
SCATTERED = 0.25


def scattered(items: np.ndarray) -> bool:
    """Do the tiles' lists :func:`bin_triangles` made jump about the triangles (more than :data:`SCATTERED`)?"""
    return len(items) > 1 and _breaks(items) > SCATTERED * (len(items) - 1)


@numba.njit(cache=True, nogil=True)
def _breaks(items):
    n = 0
    for k in range(1, items.shape[0]):
        n += items[k] != items[k - 1] + 1
    return n


def gather_setup(edges: np.ndarray, bias: np.ndarray, plane: np.ndarray, box: np.ndarray,
                 items: np.ndarray) -> tuple:
    """The setup's rows in the bins' order, (edges, bias, plane, box): row k is triangle ``items[k]``'s.

    The tile walk (:func:`raster_tiles`) then reads each tile's triangles in one sweep. Read through
    ``items``, the triangles of a mesh drawn in another order than the screen's lie all over its
    arrays, and the walk of a small triangle waited on the cache for its setup longer than it took to
    draw; gathered in one compiled loop, in bands, the reads overlap (benchmarks/README.md, issue 35).
    """
    n = len(items)
    rows = (np.empty((n, 3, 3), edges.dtype), np.empty((n, 3), bias.dtype), np.empty((n, 4), plane.dtype),
            np.empty((n, 4), box.dtype))
    in_bands(_gather_rows, n, items, edges.reshape(-1, 9), bias, plane, box, rows[0].reshape(n, 9), *rows[1:],
             grain=16384)
    return rows


@numba.njit(cache=True, nogil=True)
def _gather_rows(lo, hi, items, a, b, c, d, a_out, b_out, c_out, d_out):
    for k in range(lo, hi):
        t = items[k]
        for m in range(9):
            a_out[k, m] = a[t, m]
        for m in range(3):
            b_out[k, m] = b[t, m]
        for m in range(4):
            c_out[k, m] = c[t, m]
            d_out[k, m] = d[t, m]


def _bin_layout(box: np.ndarray, tiles_x: int, tiles_y: int, band_min: int) -> tuple:
    """The binning's first half, for triangles and for points and lines alike: the primitives cut into
    bands (one per ``band_min`` primitives, up to two per thread), each band's count per tile, and from
    them (bands, bounds, starts, fill, items): where each tile's list begins and each band writes, and
    the list to fill."""
    n_tiles = tiles_x * tiles_y
    bands = max(1, min(2 * threads(), box.shape[0] // band_min))
    bounds = np.linspace(0, box.shape[0], bands + 1).astype(np.int64)
    counts = np.zeros((bands, n_tiles), np.int64)
    in_bands(_bin_count, bands, bounds, box, tiles_x, counts)
    starts, fill = _bin_places(counts)
    return bands, bounds, starts, fill, np.empty(starts[-1], np.int32)


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


#: :func:`bin_primitives` runs in bands of at least this many points or lines: copying their setup
#: as well, a band has several times a triangle's work (benchmarks/README.md).
PRIMITIVE_BAND_MIN = 16384


def bin_primitives(box: np.ndarray, tiles_x: int, tiles_y: int, setup: tuple) -> tuple:
    """:func:`bin_triangles` for points and lines, their setup copied in the bins' order as they are
    binned: (starts, items, rows), ``rows[m][k]`` being ``setup[m][items[k]]``.

    The primitives are read in order and each tile's rows written one after the other, so a
    tile's walk reads its primitives' setup in one sweep (reading a point cloud's through
    ``items`` was a cache miss a point).
    """
    bands, bounds, starts, fill, items = _bin_layout(box, tiles_x, tiles_y, PRIMITIVE_BAND_MIN)
    # every array as rows of columns (a view), so that one compiled loop copies them all
    columns = tuple(a.reshape(len(a), int(np.prod(a.shape[1:]))) for a in setup)
    rows = tuple(np.empty((len(items), a.shape[1]), a.dtype) for a in columns)
    in_bands(_bin_fill_rows, bands, bounds, box, tiles_x, fill, items, *columns, *rows)
    return starts, items, tuple(r.reshape((len(items),) + a.shape[1:]) for r, a in zip(rows, setup))


@numba.njit(cache=True, nogil=True)
def _bin_fill_rows(band_lo, band_hi, bounds, box, tiles_x, fill, items, a, b, c, a_out, b_out, c_out):
    for band in range(band_lo, band_hi):
        for t in range(bounds[band], bounds[band + 1]):
            if box[t, 0] > box[t, 1] or box[t, 2] > box[t, 3]:
                continue
            for ty in range(box[t, 2] // TILE_H, box[t, 3] // TILE_H + 1):
                for tx in range(box[t, 0] // TILE_W, box[t, 1] // TILE_W + 1):
                    tile = ty * tiles_x + tx
                    k = fill[band, tile]
                    items[k] = t
                    for m in range(a.shape[1]):
                        a_out[k, m] = a[t, m]
                    for m in range(b.shape[1]):
                        b_out[k, m] = b[t, m]
                    for m in range(c.shape[1]):
                        c_out[k, m] = c[t, m]
                    fill[band, tile] += 1


# ------------------------------------------------- one triangle in one tile

@numba.njit(cache=True)
def _span(edges, bias, t, px0, py, i_lo, i_hi):
    """The pixels i in [i_lo, i_hi] whose sample (256·i + px0, py) triangle t covers: (first, last).

    Along the row E_k = r + a·i (a = 256·A_k) is linear in i, so each edge's fill
    rule (:func:`~softpipe.pipeline.setup.inside_edge`) bounds i from one side. The
    bound is estimated in floating point (a division is far cheaper there than in
    64-bit integers) and then made exact by asking the rule itself at the bound and
    next to it, so the span is exactly the covered pixels. (1, 0) when none is.
    """
    for k in range(3):
        a = edges[t, k, 0] * SUBPIXEL
        # E_k at i = 0, edge by edge: edge_values' three at once before the loop was slower (benchmarks/README.md)
        r = edges[t, k, 0] * px0 + edges[t, k, 1] * py + edges[t, k, 2]
        if a == 0:
            if not inside_edge(r, bias, t, k):
                return 1, 0
            continue
        # one call of the rule per loop, either way along the row (each inlined call costs compile time)
        inward = 1 if a > 0 else -1          # the direction in which E_k grows
        i = np.int64(np.ceil(-r / a)) if a > 0 else np.int64(np.floor(r / -a))
        while not inside_edge(r + a * i, bias, t, k):
            i += inward
        while inside_edge(r + a * (i - inward), bias, t, k):
            i -= inward
        if a > 0:
            i_lo = max(i_lo, i)      # the first i inside edge k
        else:
            i_hi = min(i_hi, i)      # the last
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
def _row_less(drow, vrow, tid, e1, e2, a1, a2, z0, dz1, dz2, inv_area, strict, write):
    """One span (contiguous views of one row of one sample plane) under LESS (strict) or LEQUAL; ``tid``
    is recorded where a sample passes.

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
        vrow[k] = tid if passed else vrow[k]


@numba.njit(cache=True)
def _row_any(drow, vrow, tid, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func, write):
    """One span under any compare function."""
    for k in range(drow.shape[0]):
        kf = float(k)
        zf = np.float32(plane_depth(z0, dz1, dz2, inv_area, e1 + kf * a1, e2 + kf * a2))
        if depth_passes(func, zf, drow[k]):
            if write:
                drow[k] = zf
            vrow[k] = tid


#: A triangle whose box inside a tile is at most this many pixels wide is walked
#: sample by sample: for small triangles, testing each sample costs less than
#: solving each row's span.
NARROW = 16


@numba.njit(cache=True)
def _draw_narrow(edges, bias, plane, t, tid, i0, i1, j0, j1, offsets, height, func, write, depth, vis):
    """Depth-test the covered samples of pixels [i0, i1] × [j0, j1], testing every sample; record ``tid``.

    The edge values are found once, at the box's first sample, and stepped from there: by
    A_k·256 along a row, by B_k·256 from row to row (exact integers); the triangle setup's
    fill rule decides on them (:func:`~softpipe.pipeline.setup.inside`); depth is
    :func:`~softpipe.pipeline.setup.plane_depth` of the sample's exact edge values.
    (Calling :func:`~softpipe.pipeline.setup.covers` at each sample instead, which
    evaluates the edges there rather than stepping them, made the tile pass slower;
    benchmarks/README.md.)
    """
    z0, dz1, dz2, inv_area = plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3]
    step0, step1, step2 = edges[t, 0, 0] * SUBPIXEL, edges[t, 1, 0] * SUBPIXEL, edges[t, 2, 0] * SUBPIXEL
    up0, up1, up2 = edges[t, 0, 1] * SUBPIXEL, edges[t, 1, 1] * SUBPIXEL, edges[t, 2, 1] * SUBPIXEL
    for s in range(offsets.shape[0]):
        r0, r1, r2 = edge_values(edges, t, i0 * SUBPIXEL + offsets[s, 0], j0 * SUBPIXEL + offsets[s, 1])
        for j in range(j0, j1 + 1):
            row = height - 1 - j
            e0, e1, e2 = r0, r1, r2
            for i in range(i0, i1 + 1):
                if inside(e0, e1, e2, bias, t):
                    zf = np.float32(plane_depth(z0, dz1, dz2, inv_area, e1, e2))
                    if depth_passes(func, zf, depth[s, row, i]):
                        if write:
                            depth[s, row, i] = zf
                        vis[s, row, i] = tid
                e0 += step0
                e1 += step1
                e2 += step2
            r0 += up0
            r1 += up1
            r2 += up2


@numba.njit(cache=True)
def _draw_spans(edges, bias, plane, t, tid, i0, i1, j0, j1, whole, offsets, height, func, write, depth, vis):
    """Depth-test the covered samples of pixels [i0, i1] × [j0, j1] row span by row span; record ``tid``.

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
                _row_less(drow, vrow, tid, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func == LESS, write)
            else:
                _row_any(drow, vrow, tid, e1, e2, a1, a2, z0, dz1, dz2, inv_area, func, write)


# ------------------------------------------------------------------------- tiles

@numba.njit(cache=True, inline="never")
def save_tile(depth, saved_depth, row_lo, row_hi, col_lo, col_hi):
    """Copy the depth of image rows [row_lo, row_hi) × columns [col_lo, col_hi) of every sample into
    ``saved_depth``: a tile's depth before a draw first touches it, kept to undo the draw."""
    for s in range(depth.shape[0]):
        for row in range(row_lo, row_hi):
            for i in range(col_lo, col_hi):
                saved_depth[s, row, i] = depth[s, row, i]


@numba.njit(cache=True, forceinline=True)
def _raster_tile(tile, edges, bias, plane, box, starts, items, gathered, tiles_x, width, height, offsets, func, depth_write,
                 depth, vis, touched, saved_depth):
    """One tile of the visibility pass: its triangles, in primitive order (see :func:`raster_tiles`); the
    setup's rows are the triangles', or the bins' when ``gathered`` (row k is then triangle ``items[k]``)."""
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
        t = k if gathered else items[k]             # the triangle's row of the setup
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
                save_tile(depth, saved_depth, height - 1 - y_hi, height - y_lo, x_lo, x_hi + 1)
            # written once per tile, not per triangle: neighbouring tiles' flags share a cache
            # line, and the other thread is drawing those tiles
            touched[tile] = tile_touched = True
        if i1 - i0 < NARROW:
            _draw_narrow(edges, bias, plane, t, items[k], i0, i1, j0, j1, offsets, height, func, depth_write, depth,
                         vis)
        else:
            whole = _covers_box(edges, bias, t, i0, i1, j0, j1, ox_lo, ox_hi, oy_lo, oy_hi)
            _draw_spans(edges, bias, plane, t, items[k], i0, i1, j0, j1, whole, offsets, height, func,
                        depth_write, depth, vis)


@numba.njit(cache=True, nogil=True)
def raster_tiles(tile_lo, tile_hi, edges, bias, plane, box, starts, items, gathered, tiles_x, width, height, offsets, func,
                 depth_write, depth, vis, touched, saved_depth):
    """The visibility pass over tiles [tile_lo, tile_hi) (run in bands by softpipe.core.parallel).

    Hierarchical depth (LESS/LEQUAL with writes): each tile keeps an upper bound
    of its depths; a triangle whose nearest point over the tile lies beyond it
    cannot pass anywhere there and is skipped; a triangle that covers the whole
    tile lowers the bound to its own farthest depth there. ``touched[tile]`` is
    set for every tile where some triangle was depth-tested (the others keep no
    visible sample of this draw: shading skips them); unless ``saved_depth`` is
    empty, such a tile's depth is first copied there (to undo the draw).

    Parameters
    ----------
    tile_lo, tile_hi : int
        The tiles of this band (tile ``ty * tiles_x + tx``, tile row 0 at the bottom).
    edges, bias, plane, box : the arrays of a :class:`~softpipe.pipeline.setup.TriangleSetup`, or
        when ``gathered`` its rows in the bins' order (:func:`gather_setup`: row k is triangle ``items[k]``'s)
    starts, items : the tiles' triangle lists (:func:`bin_triangles`)
    gathered : bool
    tiles_x, width, height : int
        Tiles across; the framebuffer's size in pixels.
    offsets : int64 [S, 2]
        The sample pattern's fixed-point offsets.
    func : int
        The depth compare function (its index in ``merge_state.DEPTH_FUNCS``), −1 for no depth test.
    depth_write : bool
    depth : float32 [S, H, W]
        The framebuffer's depth (image rows), tested and written in place.
    vis : int32 [S, H, W]
        Out: the last triangle that passed at each sample of these tiles, or −1.
    touched : bool [tiles]
        Out: set for the tiles where some triangle was depth-tested (clear on entry).
    saved_depth : float32 [S, H, W], or empty [0, 0, 0] to save nothing
    """
    for tile in range(tile_lo, tile_hi):
        _raster_tile(tile, edges, bias, plane, box, starts, items, gathered, tiles_x, width, height, offsets, func,
                     depth_write, depth, vis, touched, saved_depth)
