"""The fast path's walk for points and lines: the triangles' tiles, each tile walking its primitives by their own rules.

The same design as :mod:`softpipe.pipeline.tiles` for triangles, with another coverage rule:

1. **Boxes** (:func:`primitive_boxes`): the pixels each line or point may produce, which
   :func:`~softpipe.pipeline.tiles.bin_primitives` bins to the 128×32 tiles, copying each
   primitive's setup into tile order as it goes.
2. **Tiles** (:func:`raster_line_tiles`, :func:`raster_point_tiles`): bands of tiles in
   parallel; inside a tile, its lines or points in primitive order, each fragment produced
   by the reference rasterizer's rule (:mod:`softpipe.pipeline.lines`' diamond exit,
   :mod:`softpipe.pipeline.points`' square) and each of its samples depth-tested as the
   output merger would (``output.depth_passes``); only the last primitive written at each
   sample is kept, in the visibility buffer.

:mod:`softpipe.pipeline.primitive_visibility` runs this pass and shades what it left visible;
docs/points-and-lines.md says why the walk is shaped so.
"""
from __future__ import annotations

import numba
import numpy as np

from softpipe.core.borrow import borrowed_tuple
from softpipe.core.parallel import in_bands
from softpipe.pipeline.lines import (
    LineSetup,
    column_candidates,
    depth_at,
    line_depth_terms,
    line_walk,
    minor_start,
    minor_step,
    produces,
)
from softpipe.pipeline.output import depth_passes
from softpipe.pipeline.points import in_square, point_box
from softpipe.pipeline.sampling import SUBPIXEL
from softpipe.pipeline.tiles import TILE_H, TILE_W, save_tile

__all__ = ["primitive_boxes", "raster_line_tiles", "raster_point_tiles"]


@numba.njit(cache=True, nogil=True)
def _line_boxes(lo, hi, ends, width, rect, box):
    """The pixels each of lines lo:hi may produce, within ``rect``: a box around its candidate diamonds
    and its runs; empty for a line of length 0.

    The walk's columns (:func:`~softpipe.pipeline.lines.line_walk`) have their centres less than
    ½ pixel past an end along the major axis, where the line's minor coordinate is at most ½
    pixel beyond the ends' (|slope| ≤ 1); a candidate's centre is within ½ pixel of it
    (:func:`~softpipe.pipeline.lines.column_candidates`): rows from ⌈min/256⌉ − 1 to
    ⌊max/256⌋ + 1 of the ends' minor coordinates, and a run's w − 1 more."""
    for t in range(lo, hi):
        x_major, ma, mb, na, nd, md, step, first, last = line_walk(ends, t)
        if step == 0:
            box[t, 0], box[t, 1], box[t, 2], box[t, 3] = 1, 0, 1, 0
            continue
        m0, m1 = min(first, last), max(first, last)
        nb = na + nd
        n0 = -((-min(na, nb)) // SUBPIXEL) - 1
        n1 = max(na, nb) // SUBPIXEL + 1 + width[t] - 1          # a run goes up (right) from its fragment
        i0, i1, j0, j1 = (m0, m1, n0, n1) if x_major else (n0, n1, m0, m1)
        box[t, 0], box[t, 1] = max(i0, rect[0]), min(i1, rect[1])
        box[t, 2], box[t, 3] = max(j0, rect[2]), min(j1, rect[3])


@numba.njit(cache=True, nogil=True)
def _point_boxes(lo, hi, centre, size, rect, box):
    """The pixels each of points lo:hi may cover, within ``rect``."""
    for t in range(lo, hi):
        box[t, 0], box[t, 1], box[t, 2], box[t, 3] = point_box(centre, size, t, rect[0], rect[1], rect[2], rect[3])


def primitive_boxes(setup, rect: np.ndarray) -> np.ndarray:
    """int64 [P, 4]: the pixel box (i_0, i_1, j_0, j_1) of each line or point of ``setup`` (a
    :class:`~softpipe.pipeline.lines.LineSetup` or :class:`~softpipe.pipeline.points.PointSetup`)
    within ``rect``, what :func:`~softpipe.pipeline.tiles.bin_primitives` bins."""
    n = len(setup)
    box = np.empty((n, 4), np.int64)
    if n and isinstance(setup, LineSetup):
        in_bands(_line_boxes, n, setup.ends, setup.width, rect, box, grain=16384)
    elif n:
        in_bands(_point_boxes, n, setup.centre, setup.size, rect, box, grain=16384)
    return box


@numba.njit(cache=True, inline="always")
def _test_sample(s, row, i, z, t, func, write, depth, vis):
    """The early depth test of one fragment's sample (the merger's, :func:`depth_passes`, on float32):
    does it pass (and then it is written)?"""
    if func >= 0:
        if not depth_passes(func, z, depth[s, row, i]):
            return False
        if write:
            depth[s, row, i] = z
    vis[s, row, i] = t
    return True


@numba.njit(cache=True, inline="always")
def _draw_column(xa, ya, xb, yb, x_major, major, lo, hi, sure, w, n_lo, n_hi, t, height, offsets, func, write,
                 depth, vis, terms, run, keep_run):
    """One column (row) of :func:`_draw_line`'s walk: its candidates lo..hi, each fragment's run within
    the tile's rows (columns) [n_lo, n_hi] and every sample (``terms``: the line's
    :func:`~softpipe.pipeline.lines.line_depth_terms`)."""
    for minor in range(lo, hi + 1):
        r_lo, r_hi = max(n_lo - minor, 0), min(n_hi - minor, w - 1)    # the run's part in the tile
        if r_lo > r_hi:
            continue
        i, j = (major, minor) if x_major else (minor, major)
        if not sure and not produces(xa, ya, xb, yb, i, j):
            continue
        for r in range(r_lo, r_hi + 1):
            pi, pj = (i, j + r) if x_major else (i + r, j)
            row = height - 1 - pj
            for s in range(offsets.shape[0]):
                z = np.float32(depth_at(terms, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1]))
                if _test_sample(s, row, pi, z, t, func, write, depth, vis) and keep_run:
                    run[s, row, pi] = r


@numba.njit(cache=True, inline="always")
def _draw_line(ends, width, zends, k, t, x_lo, x_hi, y_lo, y_hi, height, offsets, func, write, depth, vis, run):
    """Depth-test the fragments of line t (its setup at row k of ``ends``, ``width``, ``zends``) in pixels
    [x_lo, x_hi] × [y_lo, y_hi]: the reference rasterizer's walk
    (:func:`~softpipe.pipeline.lines.cover_line`, in its order) over the columns (rows) of the tile
    alone, each fragment's samples at their depth; ``run`` (unless empty) gets the place in its
    run of each sample written, from which shading finds the run's first fragment.

    The walk starts at the tile's first column with the line's row there computed exactly
    (:func:`~softpipe.pipeline.lines.minor_start`), so it is the same in every tile the line
    crosses; the line's depth terms (:func:`~softpipe.pipeline.lines.line_depth_terms`) are read
    once, and each sample's depth is :func:`~softpipe.pipeline.lines.depth_at`'s, the reference
    path's arithmetic. A thin line on a framebuffer of one sample (the common case: a wireframe)
    takes a loop without the inner loops over the candidates, the run and the samples: at most
    one fragment a column, where each of those short loops cost a mispredicted branch."""
    xa, ya, xb, yb = ends[k, 0], ends[k, 1], ends[k, 2], ends[k, 3]
    x_major, ma, mb, na, nd, md, step, first, last = line_walk(ends, k)
    if step == 0:
        return
    m_lo, m_hi = (x_lo, x_hi) if x_major else (y_lo, y_hi)          # the tile along the major axis
    n_lo, n_hi = (y_lo, y_hi) if x_major else (x_lo, x_hi)          # and across it
    if step > 0:
        first, last = max(first, m_lo), min(last, m_hi)
    else:
        first, last = min(first, m_hi), max(last, m_lo)
    if (last - first) * step < 0:
        return
    w = width[k]
    keep_run = run.shape[0] > 0
    row, rem, inc, span = minor_start(first, ma, na, nd, md)
    terms = line_depth_terms(ends, zends, k)      # once a line and tile, not once a sample
    if w == 1 and offsets.shape[0] == 1 and not keep_run:
        ox, oy = offsets[0, 0], offsets[0, 1]
        for major in range(first, last + step, step):
            lo, minor, sure = column_candidates(major, ma, mb, row, rem, span)
            row, rem = minor_step(row, rem, inc, span)
            if lo < minor:            # a tie between two rows: the general loop below, for this column
                _draw_column(xa, ya, xb, yb, x_major, major, lo, minor, sure, 1, n_lo, n_hi, t, height, offsets,
                             func, write, depth, vis, terms, run, False)
            elif n_lo <= minor <= n_hi:
                i, j = (major, minor) if x_major else (minor, major)
                if sure or produces(xa, ya, xb, yb, i, j):
                    z = np.float32(depth_at(terms, i * SUBPIXEL + ox, j * SUBPIXEL + oy))
                    _test_sample(0, height - 1 - j, i, z, t, func, write, depth, vis)
        return
    for major in range(first, last + step, step):
        lo, hi, sure = column_candidates(major, ma, mb, row, rem, span)
        row, rem = minor_step(row, rem, inc, span)
        _draw_column(xa, ya, xb, yb, x_major, major, lo, hi, sure, w, n_lo, n_hi, t, height, offsets, func,
                     write, depth, vis, terms, run, keep_run)


@numba.njit(cache=True, inline="always")
def _draw_point(centre, size, zpoint, k, t, x_lo, x_hi, y_lo, y_hi, height, offsets, func, write, depth, vis):
    """Depth-test the fragments of point t (its setup at row k of ``centre``, ``size``, ``zpoint``) in
    pixels [x_lo, x_hi] × [y_lo, y_hi] (GL's square, :func:`~softpipe.pipeline.points.in_square`)."""
    cx, cy = centre[k, 0], centre[k, 1]
    half = size[k] * (SUBPIXEL // 2)
    i0, i1, j0, j1 = point_box(centre, size, k, x_lo, x_hi, y_lo, y_hi)
    z = np.float32(zpoint[k])
    for j in range(j0, j1 + 1):
        if not in_square(j * SUBPIXEL - cy, half):
            continue
        row = height - 1 - j
        for i in range(i0, i1 + 1):
            if not in_square(i * SUBPIXEL - cx, half):
                continue
            for s in range(offsets.shape[0]):
                _test_sample(s, row, i, z, t, func, write, depth, vis)


@numba.njit(cache=True, inline="always")
def _begin_tile(tile, starts, tiles_x, rect, width, height, samples, depth, vis, touched, saved_depth):
    """A tile of the points' or lines' pass: nothing visible in it yet; if some primitive is binned
    to it, it is touched and its depth saved (unless ``saved_depth`` is empty). Returns its pixels
    within ``rect`` (x_lo, x_hi, y_lo, y_hi), empty when nothing is binned to it."""
    tx, ty = tile % tiles_x, tile // tiles_x
    x_lo, x_hi = tx * TILE_W, min(tx * TILE_W + TILE_W, width) - 1
    y_lo, y_hi = ty * TILE_H, min(ty * TILE_H + TILE_H, height) - 1
    for s in range(samples):      # (here, in parallel, not one serial fill)
        for row in range(height - 1 - y_hi, height - y_lo):
            vis[s, row, x_lo:x_hi + 1] = -1
    if starts[tile + 1] == starts[tile]:
        return 1, 0, 1, 0
    if saved_depth.shape[0] > 0:      # the tile's depth before this draw, to undo it
        save_tile(depth, saved_depth, height - 1 - y_hi, height - y_lo, x_lo, x_hi + 1)
    touched[tile] = True
    return max(x_lo, rect[0]), min(x_hi, rect[1]), max(y_lo, rect[2]), min(y_hi, rect[3])


@numba.njit(cache=True, nogil=True)
def raster_line_tiles(tile_lo, tile_hi, ends, width, zends, starts, items, tiles_x, rect, fb_width, height,
                      offsets, func, depth_write, depth, vis, run, touched, saved_depth):
    """The visibility pass of lines over tiles [tile_lo, tile_hi) (run in bands).

    As :func:`~softpipe.pipeline.tiles.raster_tiles` for triangles: a tile's lines in primitive order (binned by
    :func:`~softpipe.pipeline.tiles.bin_primitives` from :func:`primitive_boxes`), so that each sample sees them in the
    reference's order on any thread count, with the early depth test of each fragment's samples;
    ``vis`` gets the last line written at each sample (−1: none), ``touched`` the tiles holding
    some line, whose depth is first copied to ``saved_depth`` (unless it is empty). ``ends``,
    ``width``, ``zends``: the :class:`~softpipe.pipeline.lines.LineSetup`'s rows taken in the bins'
    order (row k is line ``items[k]``'s: each tile reads its lines' setup in one sweep, where
    reading them through ``items`` was a cache miss a line); ``rect`` the scissor (window pixels
    (i_0, i_1, j_0, j_1)); ``run`` as :func:`_draw_line`'s.
    """
    # borrowed: handing the arrays to each tile's and line's walk counted references to them, an atomic
    # add and subtract per array and line, which both threads made on the same counts (benchmarks/README.md)
    ends, width, zends, starts, items, rect, offsets, depth, vis, run, touched, saved_depth = borrowed_tuple(
        (ends, width, zends, starts, items, rect, offsets, depth, vis, run, touched, saved_depth))
    for tile in range(tile_lo, tile_hi):
        x_lo, x_hi, y_lo, y_hi = _begin_tile(tile, starts, tiles_x, rect, fb_width, height, offsets.shape[0],
                                             depth, vis, touched, saved_depth)
        if x_lo > x_hi or y_lo > y_hi:
            continue
        for k in range(starts[tile], starts[tile + 1]):
            _draw_line(ends, width, zends, k, items[k], x_lo, x_hi, y_lo, y_hi, height, offsets, func, depth_write,
                       depth, vis, run)


@numba.njit(cache=True, nogil=True)
def raster_point_tiles(tile_lo, tile_hi, centre, size, zpoint, starts, items, tiles_x, rect, fb_width, height,
                       offsets, func, depth_write, depth, vis, touched, saved_depth):
    """The visibility pass of points over tiles [tile_lo, tile_hi): :func:`raster_line_tiles` for a
    :class:`~softpipe.pipeline.points.PointSetup`'s (centre, size, depth), in the bins' order."""
    centre, size, zpoint, starts, items, rect, offsets, depth, vis, touched, saved_depth = borrowed_tuple(
        (centre, size, zpoint, starts, items, rect, offsets, depth, vis, touched, saved_depth))    # (as above)
    for tile in range(tile_lo, tile_hi):
        x_lo, x_hi, y_lo, y_hi = _begin_tile(tile, starts, tiles_x, rect, fb_width, height, offsets.shape[0],
                                             depth, vis, touched, saved_depth)
        if x_lo > x_hi or y_lo > y_hi:
            continue
        for k in range(starts[tile], starts[tile + 1]):
            _draw_point(centre, size, zpoint, k, items[k], x_lo, x_hi, y_lo, y_hi, height, offsets, func,
                        depth_write, depth, vis)
