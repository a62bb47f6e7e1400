"""The fast path for points and lines: their visibility pass over the triangles' tiles, then their shading.

The design of :mod:`softpipe.pipeline.visibility` (find the visible samples, then shade
only those), for the pipeline's other two primitives:

1. **The visibility pass** (:func:`primitive_visibility_pass`): each line or point binned to
   the tiles its box touches (:func:`~softpipe.pipeline.tiles.bin_primitives`), each tile
   walking its primitives in order by the reference rasterizer's rules
   (:mod:`softpipe.pipeline.primitive_tiles`). Output: :class:`PrimitiveVisibility`, the last
   primitive written at each sample.
2. **Shading** (:func:`shade_primitives`): the visible samples sorted by primitive (each
   primitive's varyings read once, in order), given the inputs the reference path's
   fragment there gives the shader, and shaded in bands on the helper threads — by the
   generated ``primitive_loop`` in place when the shader cannot fail, else buffered, nothing
   written until every sample is shaded. Output:
   :class:`~softpipe.pipeline.visibility.ShadedSamples`.

Which path a draw takes is decided in one place for all three primitives
(:func:`~softpipe.pipeline.visibility.choose_path`); docs/points-and-lines.md walks through it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple, Union

import numba
import numpy as np

from softpipe.core.parallel import in_bands, threads
from softpipe.language import kernels
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.fragment import default_fragment_shader, derivative_gradients
from softpipe.pipeline.lines import LineSetup, line_sample_inputs, sample_means
from softpipe.pipeline.merge_state import MergeState
from softpipe.pipeline.output import NonFinite
from softpipe.pipeline.points import PointSetup, point_sample_inputs
from softpipe.pipeline.primitive_tiles import primitive_boxes, raster_line_tiles, raster_point_tiles
from softpipe.pipeline.raster import Fragments
from softpipe.pipeline.setup import SHADING_POSITIONS
from softpipe.pipeline.tiles import TILE_H, TILE_W, bin_primitives
from softpipe.pipeline.visibility import (
    DiscardOnFastPath,
    ShadedSamples,
    Visibility,
    failure_modes,
    pass_buffers,
    scratch_buffer,
)

__all__ = ["PrimitiveVisibility", "primitive_visibility_pass", "shade_primitives", "SHADE_GRAIN"]


@dataclass
class PrimitiveVisibility(Visibility):
    """The visibility pass of points or lines (:func:`primitive_visibility_pass`): which one to shade at
    each sample, as :class:`~softpipe.pipeline.visibility.Visibility` for triangles.

    Attributes
    ----------
    vis, touched, saved_depth
        As :class:`~softpipe.pipeline.visibility.Visibility`'s (``vis``: the line or point, a row of the Primitives, written
        last at each sample, or −1).
    setup : LineSetup or PointSetup
        The setup the pass used.
    run : uint8 [S, H, W]
        For wide lines, the place in its run (0 … w − 1) of the fragment written at each
        sample, from which its attributes (the run's first fragment's) are found; empty [0, 0, 0]
        otherwise.
    """

    run: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0), np.uint8), repr=False)

    def __repr__(self) -> str:
        kind = "lines" if isinstance(self.setup, LineSetup) else "points"
        return (f"PrimitiveVisibility({int((self.vis >= 0).sum())} visible samples of {self.vis.size}, "
                f"{len(self.setup)} {kind}, {int(self.touched.sum())} of {self.touched.size} tiles touched)")

    def fragments(self, prims: Primitives, pattern, shading: str = "sample") -> Fragments:
        """The fragments the fast path shades: one per visible sample, in primitive order, with the
        inputs the reference path's fragment there gives the shader (with multisampling at the
        centre or centroid, every sample of a pixel gets its run's first fragment's: the depth of
        its sample 0, where the reference path shades it)."""
        return _visible_primitive_fragments(self, prims, pattern, SHADING_POSITIONS.index(shading))


def primitive_visibility_pass(prims: Primitives, setup: Union[LineSetup, PointSetup], fb, state: MergeState,
                              rect: np.ndarray, undo: bool = True) -> PrimitiveVisibility:
    """The fast path's visibility pass of points or lines: binned to the triangles' tiles
    (:func:`~softpipe.pipeline.primitive_tiles.primitive_boxes`, :func:`~softpipe.pipeline.tiles.bin_primitives`),
    each tile walking its primitives in order with the early depth test (no fragment is kept);
    the framebuffer's depth is updated. ``rect`` is the scissor (:func:`~softpipe.pipeline.setup.pixel_rect`);
    ``undo`` keeps the depth it replaces, as :func:`~softpipe.pipeline.visibility.visibility_pass`."""
    w, h, offsets = fb.width, fb.height, fb.pattern.offsets
    func, depth_write, vis, tiles_x, tiles_y, touched = pass_buffers(fb, state)
    lines = isinstance(setup, LineSetup)
    wide = isinstance(setup, LineSetup) and len(prims) > 0 and int(setup.width.max()) > 1
    run = np.empty(vis.shape if wide else (0, 0, 0), np.uint8)
    box = primitive_boxes(setup, rect)
    undo = undo and depth_write and len(prims) > 0
    saved = scratch_buffer(fb.samples_depth) if undo else np.empty((0, 0, 0), np.float32)
    if lines:
        assert isinstance(setup, LineSetup)
        starts, items, rows = bin_primitives(box, tiles_x, tiles_y, (setup.ends, setup.width, setup.depth))
        in_bands(raster_line_tiles, tiles_x * tiles_y, *rows, starts, items, tiles_x, rect, w, h, offsets, func,
                 depth_write, fb.samples_depth, vis, run, touched.reshape(-1), saved)
    else:
        assert isinstance(setup, PointSetup)
        starts, items, rows = bin_primitives(box, tiles_x, tiles_y, (setup.centre, setup.size, setup.depth))
        in_bands(raster_point_tiles, tiles_x * tiles_y, *rows, starts, items, tiles_x, rect, w, h, offsets, func,
                 depth_write, fb.samples_depth, vis, touched.reshape(-1), saved)
    return PrimitiveVisibility(vis, setup, touched, saved if undo else None, run)  # type: ignore[arg-type]  # a line's or point's setup


@numba.njit(cache=True, nogil=True)
def _visible_by_primitive(band_lo, band_hi, bounds, vis, touched, tile_w, tile_h, places, keys, tri, fill):
    """Bands band_lo:band_hi of image rows (``bounds``): count the visible samples of each primitive
    (``fill`` False, into ``places[band]``), or put each at its primitive's next place (``fill``: its
    (row, sample, column) into ``keys`` as (row·S + sample)·W + column, its primitive into ``tri``)."""
    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]
    for band in range(band_lo, band_hi):
        at = places[band]
        for row in range(bounds[band], bounds[band + 1]):
            j = height - 1 - row
            for tile_x in range(touched.shape[1]):
                if not touched[j // tile_h, tile_x]:
                    continue
                for s in range(samples):
                    for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                        t = vis[s, row, i]
                        if t < 0:
                            continue
                        if fill:
                            k = at[t]
                            keys[k] = (row * samples + s) * width + i
                            tri[k] = t
                        at[t] += 1


@numba.njit(cache=True, nogil=True)
def _first_places(places):
    """The counts ``places[band, t]`` (:func:`_visible_by_primitive`) replaced, in place, by each band's first
    place for primitive t: a running sum over (primitive, band) in that order, so that a primitive's
    samples are its bands' in turn. Returns the total.

    In place and in one pass: the table stays in (band, primitive) order, each band's places
    its own rows (numpy's running sum over the transposed table made three copies of it, and a
    table left transposed put the two bands' places side by side, where the bands' threads
    wrote each other's cache lines)."""
    total = 0
    for t in range(places.shape[1]):
        for band in range(places.shape[0]):
            count = places[band, t]
            places[band, t] = total
            total += count
    return total


@numba.njit(cache=True, nogil=True, forceinline=True)
def _key_place(key, width, samples):
    """(row, sample, column) of a sorted visible sample's key, (row·S + sample)·W + column."""
    return key // (width * samples), (key // width) % samples, key % width


@numba.njit(cache=True, nogil=True)
def _line_inputs(lo, hi, keys, tri, run, samples, width, height, ends, zends, offsets, positions, mode, depth, bary,
                 fx, fy):
    """The shader's inputs at the visible samples lo:hi (``keys``, ``tri``: :func:`_visible_by_primitive`) of
    lines: depth, barycentrics and window position, as the reference path's fragments have them."""
    means = sample_means(offsets, positions)
    for k in range(lo, hi):
        t = tri[k]
        row, s, i = _key_place(keys[k], width, samples)
        bary[k, 0], bary[k, 1], bary[k, 2], fx[k], fy[k], depth[k] = line_sample_inputs(
            ends, zends, run, t, i, height - 1 - row, s, row, offsets, positions, mode, means)


@numba.njit(cache=True, nogil=True)
def _point_inputs(lo, hi, keys, tri, samples, width, height, centre, size, zpoint, offsets, positions, mode, depth,
                  bary, fx, fy):
    """The shader's inputs at the visible samples lo:hi (``keys``, ``tri``: :func:`_visible_by_primitive`) of
    points."""
    means = sample_means(offsets, positions)
    for k in range(lo, hi):
        t = tri[k]
        row, s, i = _key_place(keys[k], width, samples)
        bary[k, 0], bary[k, 1], bary[k, 2], fx[k], fy[k], depth[k] = point_sample_inputs(
            centre, size, zpoint, t, i, height - 1 - row, s, positions, mode, means)


#: Buffers of the points' and lines' shading (its sorted samples and the shader's inputs and colors), kept
#: between draws as the depth saved for an undo is (:func:`~softpipe.pipeline.visibility.scratch_buffer`): a cloud's 400,000 visible samples take
#: 30 MB, whose first touch (a page fault a page) cost more than making them.
_POOL: dict = {}


def _pooled(name: str, n: int, dtype, *shape) -> np.ndarray:
    """An array [n, *shape] of ``dtype`` from the pool (taken: a draw at the same time gets its own)."""
    buffer = _POOL.pop(name, None)           # atomic under the GIL
    if buffer is None or len(buffer) < n or buffer.dtype != dtype or buffer.shape[1:] != shape:
        buffer = np.empty((max(n, 1024),) + shape, dtype)
    return buffer


def _return_pooled(**buffers) -> None:
    """Hand buffers back to the pool (the larger of two of a name kept)."""
    for name, buffer in buffers.items():
        kept = _POOL.get(name)
        if kept is None or len(kept) <= len(buffer):
            _POOL[name] = buffer


#: Every how many image rows :func:`_balanced_bounds` counts the visible samples.
BALANCE_STEP = 8


@numba.njit(cache=True, nogil=True)
def _visible_in_rows(vis, touched, tile_w, tile_h, step):
    """The visible samples of every ``step``-th image row (the others 0), the touched tiles' only."""
    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]
    count = np.zeros(height, np.int64)
    for row in range(0, height, step):
        j = height - 1 - row
        for tile_x in range(touched.shape[1]):
            if touched[j // tile_h, tile_x]:
                for s in range(samples):
                    for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                        if vis[s, row, i] >= 0:
                            count[row] += 1
    return count


def _balanced_bounds(vis: np.ndarray, touched: np.ndarray, bands: int) -> np.ndarray:
    """Bands of image rows [bands + 1] for the sort's two passes, each with about as many visible
    samples, as every :data:`BALANCE_STEP`-th row counts them: the bands are the threads' work, and
    a wireframe's halves of the screen can hold one and two thirds of it. Which rows a band
    holds changes no byte (:func:`_sorted_samples`)."""
    height = vis.shape[1]
    even = np.linspace(0, height, bands + 1).astype(np.int64)
    if bands == 1:
        return even
    # each counted row stands for itself and the rows up to the next counted one
    counted = _visible_in_rows(vis, touched, TILE_W, TILE_H, BALANCE_STEP)[::BALANCE_STEP]
    running = np.cumsum(np.repeat(counted, BALANCE_STEP)[:height])
    if running[-1] == 0:
        return even
    # a band ends after the row where the running count reaches its share (rows of the same count share a band)
    cuts = np.searchsorted(running, running[-1] * np.arange(1, bands) / bands) + 1
    return np.concatenate([[0], np.minimum(cuts, height), [height]]).astype(np.int64)


def _sorted_samples(visibility: PrimitiveVisibility, n_prims: int, pooled: bool) -> Tuple[np.ndarray, np.ndarray]:
    """The visible samples sorted by primitive: (keys, tri), each sample's (row·S + sample)·W + column and
    its primitive.

    In primitive order, because shading reads each primitive's varyings: in the order of the
    screen a cloud's points come in no order at all, and every fragment's varyings were a
    cache miss (shading took 10 times longer). A counting sort in bands of image rows (as
    :func:`~softpipe.pipeline.tiles.bin_triangles`: each band counts per primitive, a prefix sum
    over (primitive, band) gives each band its places), so a primitive's samples are in
    (image row, tile, sample, column) order on any thread count.
    """
    vis, touched = visibility.vis, visibility.touched
    height = vis.shape[1]
    bands = max(1, min(threads(), height // 16))
    bounds = _balanced_bounds(vis, touched, bands)
    # 32-bit places where every sample's fits (a smaller table, more of it in the cache: the sort 25 % faster)
    places_type = np.int32 if vis.size < 2**31 else np.int64
    places = np.zeros((bands, n_prims), places_type)
    keys, tri = np.empty(0, np.int64), np.empty(0, np.int32)
    if touched.any() and n_prims:
        in_bands(_visible_by_primitive, bands, bounds, vis, touched, TILE_W, TILE_H, places, keys, tri, False)
    n = int(_first_places(places))
    if not n:
        return keys, tri
    keys = _pooled("keys", n, np.int64)[:n] if pooled else np.empty(n, np.int64)
    tri = _pooled("tri", n, np.int32)[:n] if pooled else np.empty(n, np.int32)
    in_bands(_visible_by_primitive, bands, bounds, vis, touched, TILE_W, TILE_H, places, keys, tri, True)
    return keys, tri


def _shader_inputs(visibility: PrimitiveVisibility, keys, tri, pattern, mode: int, depth, bary, fx, fy) -> None:
    """The shader's inputs at the sorted samples (:func:`_sorted_samples`), in bands."""
    setup, (samples, height, width) = visibility.setup, visibility.vis.shape
    if isinstance(setup, LineSetup):
        in_bands(_line_inputs, len(keys), keys, tri, visibility.run, samples, width, height, setup.ends, setup.depth,
                 pattern.offsets, pattern.positions, mode, depth, bary, fx, fy, grain=16384)
    else:
        assert isinstance(setup, PointSetup)
        in_bands(_point_inputs, len(keys), keys, tri, samples, width, height, setup.centre, setup.size, setup.depth,
                 pattern.offsets, pattern.positions, mode, depth, bary, fx, fy, grain=16384)


def _decode(keys: np.ndarray, shape) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(column, image row, sample) of sorted samples' keys, int32 each."""
    samples, _, width = shape
    return ((keys % width).astype(np.int32), (keys // (width * samples)).astype(np.int32),
            ((keys // width) % samples).astype(np.int32))


def _visible_primitive_fragments(visibility: PrimitiveVisibility, prims: Primitives, pattern, mode: int) -> Fragments:
    """:meth:`PrimitiveVisibility.fragments`: the visible samples sorted by primitive, made into fragments."""
    keys, tri = _sorted_samples(visibility, len(prims), pooled=False)
    n = len(keys)
    depth, bary, fx, fy = np.empty(n), np.empty((n, 3)), np.empty(n), np.empty(n)
    if n:
        _shader_inputs(visibility, keys, tri, pattern, mode, depth, bary, fx, fy)
    x, y, sample = _decode(keys, visibility.vis.shape)
    return Fragments(x, y, sample, depth, bary, tri, prims.primitive_id[tri], fx, fy, visibility.setup)


@numba.njit(cache=True, nogil=True)
def _write_by_keys(lo, hi, keys, color, samples, height, width, fb_color, bad):
    """Write the colors of sorted samples lo:hi (:func:`_sorted_samples`); bad[lo] counts those not finite."""
    n = 0
    for k in range(lo, hi):
        key = keys[k]
        i, s, row = key % width, (key // width) % samples, key // (width * samples)
        total = 0.0
        for c in range(4):
            fb_color[s, row, i, c] = color[k, c]
            total += np.float64(color[k, c])
        if not (total - total == 0.0):
            n += 1
    bad[lo] = n


def _shade_in_place(prims: Primitives, visibility: PrimitiveVisibility, fb, shader: Callable, uniforms, mode: int,
                    keys: np.ndarray, tri: np.ndarray) -> Optional[NonFinite]:
    """Shade the sorted visible samples (:func:`_sorted_samples`) with ``primitive_loop``
    (:func:`~softpipe.language.kernels.primitive_kernel`), which computes each sample's inputs where it
    shades it and writes its color into ``fb`` at once: for a shader proved not to fail
    (:func:`~softpipe.pipeline.visibility.failure_modes`), which leaves nothing to put back. Making the inputs into arrays, the colors
    into another and then writing them took most of the points' and lines' shading. Returns the
    non-finite colors written, as :func:`shade_primitives` names them."""
    setup = visibility.setup
    shape = visibility.vis.shape
    if isinstance(setup, LineSetup):
        kind, arrays, run = "lines", (setup.ends, setup.width, setup.depth), visibility.run
    else:
        assert isinstance(setup, PointSetup)
        kind, arrays, run = "points", (setup.centre, setup.size, setup.depth), np.zeros((0, 0, 0), np.uint8)
    kernel = kernels.primitive_kernel(shader, prims.layout, kind)
    n = len(keys)
    bad = np.zeros(n + 1, np.uint8)        # a flag at each band's first sample (bytes: the array is read whole)
    args = (keys, tri, run, *arrays, fb.pattern.offsets, fb.pattern.positions, mode, prims.inv_w, prims.varyings,
            prims.front_facing, prims.primitive_id, derivative_gradients(shader, setup), uniforms,
            fb.samples_color, bad)
    # compile (or load) once, in this thread, where errors are reported clearly
    kernels.run_compiled("fragment", shader, kernel, 0, 0, *args)
    kernels.run_compiled("fragment", shader, lambda *a: in_bands(kernel, n, *a, grain=SHADE_GRAIN // 4), *args)
    if not bad.any():
        return None
    x, y, s = _decode(keys, shape)
    wrong = np.flatnonzero(~np.isfinite(fb.samples_color[s, y, x]).all(axis=1))
    first = int(wrong[np.lexsort((x[wrong], y[wrong]))[0]])     # the lowest image row, then column
    return NonFinite(len(wrong), int(x[first]), int(y[first]), int(prims.primitive_id[tri[first]]))


#: Fragments a band of the points' and lines' shading holds at least (a band costs a call of the
#: compiled loop from Python, some microseconds).
SHADE_GRAIN = 65536


def _shade_band(lo, hi, kernel, args) -> None:
    """The fragment loop over fragments lo:hi (a band of :func:`shade_primitives`, on a helper thread: the
    loop is compiled with nogil)."""
    kernel(*(a[lo:hi] for a in args[:5]), *args[5:-1], args[-1][lo:hi])


def shade_primitives(prims: Primitives, visibility: PrimitiveVisibility, fb, fragment_shader: Optional[Callable],
                     uniforms, shading: str = "sample") -> ShadedSamples:
    """Run the shader on the samples a :class:`PrimitiveVisibility` kept and write their color into ``fb``.

    The visible samples, sorted by primitive (:func:`_sorted_samples`), get the inputs the
    reference path's fragments there give the shader (the same as
    :meth:`PrimitiveVisibility.fragments`) and are shaded by the reference path's loop
    (``fragment_loop``) in bands on the helper threads; nothing is written before every one is
    shaded. A shader proved not to fail (:func:`~softpipe.pipeline.visibility.failure_modes`) is run by ``primitive_loop`` instead
    (:func:`_shade_in_place`), which makes each sample's inputs where it shades it and writes its
    color at once: the same bytes, with no arrays of inputs or colors. As :func:`~softpipe.pipeline.visibility.shade_visible`: a shader that raises has the depth put back and nothing
    written; a NaN alpha (DISCARD) at a visible sample raises :class:`~softpipe.pipeline.visibility.DiscardOnFastPath` with the
    depth put back. With multisampling at the centre or centroid each visible sample is shaded
    with its pixel's inputs, so it gets the color the reference path copies to it.
    """
    shape = visibility.vis.shape
    buffers: dict = {}
    try:
        shader = fragment_shader or default_fragment_shader(prims.layout)
        keys, tri = _sorted_samples(visibility, len(prims), pooled=True)
        if len(keys) and not any(failure_modes(shader, prims.layout)):
            buffers = dict(keys=keys.base, tri=tri.base)
            non_finite = _shade_in_place(prims, visibility, fb, shader, uniforms, SHADING_POSITIONS.index(shading),
                                         keys, tri)
            visibility.keep()
            return ShadedSamples(visibility, shading, non_finite)
        n = len(keys)
        if n:
            buffers = dict(keys=keys.base, tri=tri.base, depth=_pooled("depth", n, np.float64),
                           bary=_pooled("bary", n, np.float64, 3), fx=_pooled("fx", n, np.float64),
                           fy=_pooled("fy", n, np.float64), color=_pooled("color", n, np.float32, 4))
        color = buffers["color"][:n] if n else np.empty((0, 4), np.float32)
        if n:
            depth, bary, fx, fy = (buffers[k][:n] for k in ("depth", "bary", "fx", "fy"))
            _shader_inputs(visibility, keys, tri, fb.pattern, SHADING_POSITIONS.index(shading), depth, bary, fx, fy)
            kernel = kernels.fragment_kernel(shader, prims.layout)
            args = (tri, fx, fy, depth, bary, prims.inv_w, prims.varyings, prims.front_facing, prims.primitive_id,
                    derivative_gradients(shader, visibility.setup), uniforms, color)
            # compile (or load) once, in this thread, where errors are reported clearly
            kernels.run_compiled("fragment", shader, kernel, *(a[:0] for a in args[:5]), *args[5:-1], color[:0])

            def site():        # which fragment raised: the shading again, on copies, one by one
                return kernels.fragment_site(shader, kernel, args[:-1] + (color.copy(),), *_decode(keys, shape))()

            kernels.run_compiled("fragment", shader, lambda *a: in_bands(_shade_band, n, kernel, a,
                                                                         grain=SHADE_GRAIN), *args, site=site)
        if np.isnan(color[:, 3]).any():
            raise DiscardOnFastPath("the fragment shader returned a NaN alpha (DISCARD) at a visible sample")
        bad = np.zeros(n + 1, np.int64)
        non_finite = None
        if n:
            in_bands(_write_by_keys, n, keys, color, *shape, fb.samples_color, bad, grain=65536)
        if bad.any():
            wrong = np.flatnonzero(~np.isfinite(color).all(axis=1))
            x, y, _ = _decode(keys[wrong], shape)
            first = int(np.lexsort((x, y))[0])          # the lowest image row, then column
            non_finite = NonFinite(len(wrong), int(x[first]), int(y[first]),
                                   int(prims.primitive_id[tri[wrong[first]]]))
    except BaseException:
        visibility.undo(fb)
        raise
    finally:
        _return_pooled(**buffers)
    visibility.keep()
    return ShadedSamples(visibility, shading, non_finite)
