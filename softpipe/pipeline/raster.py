"""Stage 3: the rasterizer — which samples each primitive covers, and where.

Triangles by the rules below; lines by GL's diamond-exit rule
(:mod:`softpipe.pipeline.lines`) and points by GL's square
(:mod:`softpipe.pipeline.points`), each set up by its own module
(:func:`setup_primitives` picks it) and giving the same :class:`Fragments`.

It answers exactly three questions per covered sample: which pixel and sample,
which triangle, and the barycentrics (and from them the depth). Shading is a
later stage. The rules are OpenGL's, as Mesa implements them (docs/design.md); each
is one function of the triangle setup (:mod:`softpipe.pipeline.setup`), which this stage shares
with the fast path and the shading loops:

1. **Snapping** (:func:`~softpipe.pipeline.setup.snap`): fixed point with 8 subpixel
   bits, ``X = round_half_even((x_w − ½)·256)``, so pixel i's centre is at ``256·i``.
2. **Edge functions** ``E_k = A_k·x + B_k·y + C_k``, exact in 64-bit integers;
   ``b_k = E_k / area`` are the barycentrics.
3. **The fill rule** (:func:`~softpipe.pipeline.setup.owns_samples_on_edge`): a sample
   strictly inside all three edges is covered; a sample exactly on an edge is
   covered only if that edge owns it: left edges and bottom horizontal edges,
   in OpenGL window coordinates (y up). Two triangles sharing an edge never
   both cover, and never both miss, a sample on it.
4. **Depth** (:func:`~softpipe.pipeline.setup.depth_at`), linear in window space:
   ``z = z_0 + (E_1 (z_1 − z_0) + E_2 (z_2 − z_0)) / area``.

The one y flip of softpipe happens here, when a fragment is emitted: window row
``y`` (y up) becomes image row ``height − 1 − y`` (row 0 at the top).

The kernels are plain loops compiled by numba; with ``NUMBA_DISABLE_JIT=1`` they
run as Python and a debugger can step through :func:`_cover_triangle`, sample
by sample (docs/07-debugging.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.lines import LineSetup, cover_line, setup_lines
from softpipe.pipeline.points import PointSetup, cover_point, setup_points
from softpipe.pipeline.sampling import CENTER, SUBPIXEL, SamplePattern
from softpipe.pipeline.setup import (
    SHADE_SAMPLE,
    SHADING_POSITIONS,
    TriangleSetup,
    depth_at,
    edge_function,
    edge_values,
    owns_samples_on_edge,
    pixel_coverage,
    pixel_rect,
    setup_triangles,
    shading_point,
    snap,
)

__all__ = ["Fragments", "rasterize", "count_fragments", "snap", "edge_function", "owns_samples_on_edge",
           "SHADING_POSITIONS", "pixel_rect", "TriangleSetup", "setup_triangles", "setup_primitives", "AnySetup"]

#: The setup of any kind of primitive.
AnySetup = Union[TriangleSetup, LineSetup, PointSetup]


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
        Window-space (linear) barycentrics, w.r.t. the primitive's corners, where
        the fragment is shaded: at its sample, or (multisampling) at the pixel
        centre or the centroid of the triangle's covered samples in the pixel.
        A line's are (1 − t, t, 0), t along the segment; a point's (1 − s − t, s, t),
        (s, t) its ``gl_PointCoord``.
    frag_x, frag_y : float64 [F]
        That position in window coordinates (``gl_FragCoord``: y up, pixel
        centres at +½).
    triangle : int32 [F]
        Row in :class:`~softpipe.pipeline.assembly.Primitives` (a triangle, line or point).
    primitive_id : int64 [F]
        The input primitive the row came from.
    setup : TriangleSetup, LineSetup, PointSetup or None
        The setup the fragments came from (for derivatives).
    """

    x: np.ndarray
    y: np.ndarray
    sample: np.ndarray
    depth: np.ndarray
    bary: np.ndarray
    triangle: np.ndarray
    primitive_id: np.ndarray
    frag_x: np.ndarray | None = None
    frag_y: np.ndarray | None = None
    setup: AnySetup | None = None

    def __len__(self) -> int:
        return len(self.x)

    def __repr__(self) -> str:
        return f"Fragments({len(self)} covered samples from {len(np.unique(self.triangle))} primitives)"

    def take(self, rows: np.ndarray) -> "Fragments":
        """The fragments at ``rows`` (same setup): one compiled pass in bands over every field (numpy's
        fancy indexing took a pass a field)."""
        assert self.frag_x is not None and self.frag_y is not None   # every stage that makes fragments gives them
        n = len(rows)
        out = Fragments(np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n),
                        np.empty((n, 3)), np.empty(n, np.int32), np.empty(n, np.int64), np.empty(n), np.empty(n),
                        self.setup)
        if n:
            in_bands(_take_kernel, n, np.ascontiguousarray(rows, np.int64), self.x, self.y, self.sample, self.depth,
                     self.bary, self.triangle, self.primitive_id, self.frag_x, self.frag_y, out.x, out.y,
                     out.sample, out.depth, out.bary, out.triangle, out.primitive_id, out.frag_x, out.frag_y,
                     grain=65536)
        return out


@numba.njit(cache=True, nogil=True)
def _take_kernel(lo, hi, rows, x, y, s, depth, bary, tri, pid, fx, fy, ox, oy, os, odepth, obary, otri, opid, ofx, ofy):
    """:meth:`Fragments.take` for rows lo:hi."""
    for k in range(lo, hi):
        r = rows[k]
        ox[k], oy[k], os[k], odepth[k] = x[r], y[r], s[r], depth[r]
        obary[k, 0], obary[k, 1], obary[k, 2] = bary[r, 0], bary[r, 1], bary[r, 2]
        otri[k], opid[k], ofx[k], ofy[k] = tri[r], pid[r], fx[r], fy[r]


@numba.njit(cache=True)
def _cover_triangle(edges, bias, plane, box, t, height, offsets, positions, mode, out_x, out_y, out_s, out_depth,
                    out_bary, out_pos, start, emit):
    """Visit every covered sample of triangle t; write them from ``start`` if ``emit``. Returns the count.

    Pixel by pixel over the triangle's box (window rows, bottom up), the
    covered samples of a pixel first (:func:`~softpipe.pipeline.setup.pixel_coverage`),
    then for each one its edge functions, depth and shading position.
    """
    n = 0
    for j in range(box[t, 2], box[t, 3] + 1):
        for i in range(box[t, 0], box[t, 1] + 1):
            mask, first, count = pixel_coverage(edges, bias, t, i, j, offsets)
            if count == 0 or not emit:
                n += count
                continue
            for s in range(offsets.shape[0]):
                if not (mask >> s) & 1:
                    continue
                px = i * SUBPIXEL + offsets[s, 0]
                py = j * SUBPIXEL + offsets[s, 1]
                e0, e1, e2 = edge_values(edges, t, px, py)
                b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets, positions, mode)
                k = start + n
                out_x[k] = i
                out_y[k] = height - 1 - j   # the y flip: window row → image row
                out_s[k] = s
                out_depth[k] = depth_at(plane, t, e1, e2)
                out_bary[k, 0] = b0
                out_bary[k, 1] = b1
                out_bary[k, 2] = b2
                out_pos[0, k] = fx
                out_pos[1, k] = fy
                n += 1
    return n


@numba.njit(cache=True, nogil=True)
def _count_kernel(lo, hi, edges, bias, plane, box, height, offsets, positions, counts):
    """The covered samples of triangles lo:hi (run in bands by softpipe.core.parallel)."""
    dummy_i = np.empty(0, np.int32)
    dummy_f = np.empty(0, np.float64)
    dummy_b = np.empty((0, 3), np.float64)
    dummy_p = np.empty((2, 0), np.float64)
    for t in range(lo, hi):
        counts[t] = _cover_triangle(edges, bias, plane, box, t, height, offsets, positions, SHADE_SAMPLE,
                                    dummy_i, dummy_i, dummy_i, dummy_f, dummy_b, dummy_p, 0, False)


@numba.njit(cache=True, nogil=True)
def _emit_kernel(lo, hi, edges, bias, plane, box, first, starts, height, offsets, positions, mode, out_x, out_y,
                 out_s, out_depth, out_bary, out_pos, out_tri):
    """The fragments of triangles first + lo : first + hi, each at its start (run in bands)."""
    for t in range(first + lo, first + hi):
        begin = starts[t]
        n = _cover_triangle(edges, bias, plane, box, t, height, offsets, positions, mode, out_x, out_y, out_s,
                            out_depth, out_bary, out_pos, begin, True)
        for k in range(begin, begin + n):
            out_tri[k] = t


@numba.njit(cache=True, nogil=True)
def _count_lines(lo, hi, ends, width, depth, rect, height, offsets, positions, counts):
    """The fragments of lines lo:hi (run in bands)."""
    dummy_i, dummy_f = np.empty(0, np.int32), np.empty(0, np.float64)
    dummy_b, dummy_p = np.empty((0, 3), np.float64), np.empty((2, 0), np.float64)
    for t in range(lo, hi):
        counts[t] = cover_line(ends, width, depth, t, rect, height, offsets, positions, SHADE_SAMPLE, dummy_i,
                               dummy_i, dummy_i, dummy_f, dummy_b, dummy_p, 0, False)


@numba.njit(cache=True, nogil=True)
def _emit_lines(lo, hi, ends, width, depth, rect, first, starts, height, offsets, positions, mode, out_x, out_y,
                out_s, out_depth, out_bary, out_pos, out_tri):
    """The fragments of lines first + lo : first + hi, each at its start (run in bands)."""
    for t in range(first + lo, first + hi):
        begin = starts[t]
        n = cover_line(ends, width, depth, t, rect, height, offsets, positions, mode, out_x, out_y, out_s, out_depth,
                       out_bary, out_pos, begin, True)
        for k in range(begin, begin + n):
            out_tri[k] = t


@numba.njit(cache=True, nogil=True)
def _count_points(lo, hi, centre, size, depth, rect, height, offsets, positions, counts):
    """The fragments of points lo:hi (run in bands)."""
    dummy_i, dummy_f = np.empty(0, np.int32), np.empty(0, np.float64)
    dummy_b, dummy_p = np.empty((0, 3), np.float64), np.empty((2, 0), np.float64)
    for t in range(lo, hi):
        counts[t] = cover_point(centre, size, depth, t, rect, height, offsets, positions, SHADE_SAMPLE, dummy_i,
                                dummy_i, dummy_i, dummy_f, dummy_b, dummy_p, 0, False)


@numba.njit(cache=True, nogil=True)
def _emit_points(lo, hi, centre, size, depth, rect, first, starts, height, offsets, positions, mode, out_x, out_y,
                 out_s, out_depth, out_bary, out_pos, out_tri):
    """The fragments of points first + lo : first + hi, each at its start (run in bands)."""
    for t in range(first + lo, first + hi):
        begin = starts[t]
        n = cover_point(centre, size, depth, t, rect, height, offsets, positions, mode, out_x, out_y, out_s,
                        out_depth, out_bary, out_pos, begin, True)
        for k in range(begin, begin + n):
            out_tri[k] = t


def setup_primitives(prims: Primitives, rect: np.ndarray, offsets: np.ndarray) -> AnySetup:
    """The setup of the primitives' kind: :func:`~softpipe.pipeline.setup.setup_triangles`,
    :func:`~softpipe.pipeline.lines.setup_lines` or :func:`~softpipe.pipeline.points.setup_points`
    (``rect`` the scissor, :func:`pixel_rect`; ``offsets`` the sample pattern's, fixed point)."""
    if prims.kind == "lines":
        return setup_lines(prims.window, prims.size)
    if prims.kind == "points":
        return setup_points(prims.window, prims.size)
    return setup_triangles(prims.window, rect, offsets)


def _setup_for(prims: Primitives, width: int, height: int, pattern: SamplePattern, rect, setup):
    if setup is not None:
        return setup
    rect = pixel_rect(width, height) if rect is None else rect
    return setup_primitives(prims, rect, pattern.offsets)


def count_fragments(prims: Primitives, width: int, height: int, pattern: SamplePattern = CENTER,
                    rect: np.ndarray | None = None, setup: AnySetup | None = None) -> np.ndarray:
    """How many samples each primitive covers (int64 [P]); the rasterizer's first pass.

    ``rect`` is the scissor (:func:`pixel_rect`; the whole framebuffer by default): lines
    and points are cut to it here, triangles in their setup.
    """
    rect = pixel_rect(width, height) if rect is None else rect
    setup = _setup_for(prims, width, height, pattern, rect, setup)
    counts = np.zeros(len(prims), dtype=np.int64)
    if not len(prims):
        return counts
    if isinstance(setup, LineSetup):
        in_bands(_count_lines, len(prims), setup.ends, setup.width, setup.depth, rect, height, pattern.offsets,
                 pattern.positions, counts, grain=1024)
    elif isinstance(setup, PointSetup):
        in_bands(_count_points, len(prims), setup.centre, setup.size, setup.depth, rect, height, pattern.offsets,
                 pattern.positions, counts, grain=1024)
    else:
        in_bands(_count_kernel, len(prims), setup.edges, setup.bias, setup.plane, setup.box, height,
                 pattern.offsets, pattern.positions, counts, grain=256)
    return counts


def rasterize(prims: Primitives, width: int, height: int, pattern: SamplePattern = CENTER,
              first: int = 0, last: int | None = None, counts: np.ndarray | None = None,
              shading: str = "sample", rect: np.ndarray | None = None,
              setup: AnySetup | None = None) -> Fragments:
    """The covered samples of primitives ``first:last`` (all by default), in primitive order.

    Within a triangle, fragments come row by row from the bottom of the window
    (y up), left to right, sample by sample, so the samples one triangle covers
    in one pixel are consecutive; within a line, from its first end to its last;
    within a point, row by row from the bottom. ``shading`` says where the
    barycentrics are taken: at each "sample", the pixel "center", or the
    "centroid" of the pixel's covered samples (see :data:`SHADING_POSITIONS`).
    ``setup`` (from :func:`setup_primitives` with the same ``rect``) is made here
    when not given.
    """
    if shading not in SHADING_POSITIONS:
        raise ValueError(f"sample_shading must be one of {SHADING_POSITIONS}, got {shading!r}")
    mode = SHADING_POSITIONS.index(shading)
    rect = pixel_rect(width, height) if rect is None else rect
    setup = _setup_for(prims, width, height, pattern, rect, setup)
    last = len(prims) if last is None else last
    if counts is None:
        counts = count_fragments(prims, width, height, pattern, rect=rect, setup=setup)
    starts = np.zeros(len(prims) + 1, dtype=np.int64)
    np.cumsum(counts, out=starts[1:])
    starts -= starts[first]
    total = int(starts[last]) if len(prims) else 0
    x = np.empty(total, np.int32)
    y = np.empty(total, np.int32)
    s = np.empty(total, np.int32)
    depth = np.empty(total, np.float64)
    bary = np.empty((total, 3), np.float64)
    pos = np.empty((2, total), np.float64)
    tri = np.empty(total, np.int32)
    if total:
        out = (x, y, s, depth, bary, pos, tri)
        if isinstance(setup, LineSetup):
            in_bands(_emit_lines, last - first, setup.ends, setup.width, setup.depth, rect, first, starts, height,
                     pattern.offsets, pattern.positions, mode, *out, grain=1024)
        elif isinstance(setup, PointSetup):
            in_bands(_emit_points, last - first, setup.centre, setup.size, setup.depth, rect, first, starts, height,
                     pattern.offsets, pattern.positions, mode, *out, grain=1024)
        else:
            in_bands(_emit_kernel, last - first, setup.edges, setup.bias, setup.plane, setup.box, first, starts,
                     height, pattern.offsets, pattern.positions, mode, *out, grain=256)
    return Fragments(x=x, y=y, sample=s, depth=depth, bary=bary, triangle=tri,
                     primitive_id=prims.primitive_id[tri] if total else np.zeros(0, np.int64),
                     frag_x=pos[0], frag_y=pos[1], setup=setup)
