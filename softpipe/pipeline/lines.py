"""Stage 3 for lines: line setup and GL's diamond-exit rule.

A line segment from p_a to p_b produces the fragments whose *diamond*
R_f = {|x − x_f| + |y − y_f| < ½} (x_f, y_f the pixel's centre) it crosses,
except the one whose diamond holds p_b — so a strip's segments share their joint
pixel without a double hit or a gap (OpenGL 4.6 §14.5.1). Ties are broken as
the specification says, by perturbing both ends by −(ε, ε²) for an infinitesimal
ε: here that perturbation is carried exactly, as the sign of ε and ε² terms
(:func:`crosses_diamond`, :func:`holds_end`), so every case has one answer.

The ends are snapped to the triangles' grid (1/256 pixel, :func:`~softpipe.pipeline.setup.snap`),
so the tests are exact 64-bit integer arithmetic. A segment is *x-major* when
|Δx| ≥ |Δy|; then at most one diamond per column can meet it (the one whose centre
is within ½ of the line vertically), which is where :func:`cover_line` looks: the
walk (:func:`line_walk`, :func:`minor_start`, :func:`minor_step`, :func:`column_candidates`)
visits the columns whose diamonds the segment's extent can reach and carries the line's
row there as an exact fraction, stepped by one addition a column.

**Wide lines** (width w, rounded to the nearest integer, at least 1; GL's
non-antialiased wide-line rule, OpenGL 4.6 compatibility profile §14.5.2.1): the
segment moved by −(w − 1)/2 along its minor axis is rasterized as above, and each
of its fragments becomes a run of w fragments going up (x-major) or right
(y-major) from it; every fragment of a run has its first fragment's attributes.

**Attributes** at a fragment: t = ((p − p_a)·(p_b − p_a)) / |p_b − p_a|², the
position along the segment of the point p where it is shaded (the sample, or the
pixel centre), clamped to [0, 1]; depth (1 − t)·z_a + t·z_b; the fragment stage
interpolates the varyings with barycentrics (1 − t, t, 0) over the corners
(a, b, b) of :class:`~softpipe.pipeline.assembly.Primitives` (perspective-correct,
``noperspective`` or ``flat`` as for triangles).

**Multisampling**: a fragment covers every sample of its pixel — GL's rule for
lines rasterized without MULTISAMPLE (§14.3.1); its depth and (with
``sample_shading="sample"``) its shading are taken at each sample. GL's
antialiased multisample lines (a rectangle of sample coverage) are not drawn.

docs/points-and-lines.md walks through the rule with pictures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.pipeline.sampling import SUBPIXEL
from softpipe.pipeline.setup import SHADE_CENTER, SHADE_SAMPLE, snap

__all__ = ["LineSetup", "setup_lines", "crosses_diamond", "holds_end", "produces", "cover_line", "run_width",
           "line_walk", "minor_start", "minor_step", "column_candidates", "sample_means", "line_parameter",
           "depth_along", "line_depth_terms", "depth_at", "line_sample_depth", "line_shading_point",
           "line_sample_inputs"]

#: The diamond's half-diagonal, ½ pixel, in fixed point.
RADIUS = SUBPIXEL // 2


@dataclass
class LineSetup:
    """Per line of the :class:`~softpipe.pipeline.assembly.Primitives`: what coverage, depth and shading need.

    Attributes
    ----------
    ends : int64 [L, 4]
        (X_a, Y_a, X_b, Y_b): the snapped ends in fixed point (pixel i's centre at
        256·i), moved by −(w − 1)/2 pixels along the minor axis for a wide line.
    width : int64 [L]
        w, the fragments in each run across the minor axis (1 for a thin line).
    depth : float64 [L, 2]
        (z_a, z_b), the ends' window depths.
    """

    ends: np.ndarray
    width: np.ndarray
    depth: np.ndarray

    def __len__(self) -> int:
        return len(self.width)

    def __repr__(self) -> str:
        zero = int(((self.ends[:, 0] == self.ends[:, 2]) & (self.ends[:, 1] == self.ends[:, 3])).sum())
        return f"LineSetup({len(self)} lines, {zero} of length 0 after snapping)"

    def barycentric_gradients(self) -> np.ndarray:
        """∂b_k/∂x and ∂b_k/∂y per window pixel, [L, 2, 3]: b = (1 − t, t, 0), and t changes by
        256·ΔX/|Δ|² per pixel in x (256·ΔY/|Δ|² in y); zero for a line of length 0."""
        dx = (self.ends[:, 2] - self.ends[:, 0]).astype(np.float64)
        dy = (self.ends[:, 3] - self.ends[:, 1]).astype(np.float64)
        length2 = dx * dx + dy * dy
        scale = np.where(length2 > 0, SUBPIXEL / np.where(length2 > 0, length2, 1.0), 0.0)
        out = np.zeros((len(self), 2, 3))
        out[:, 0, 1], out[:, 1, 1] = dx * scale, dy * scale
        out[:, :, 0] = -out[:, :, 1]
        return out


def run_width(width: float) -> int:
    """GL's width of a non-antialiased wide line: the width rounded to the nearest integer (halves up), ≥ 1."""
    return max(int(np.floor(width + 0.5)), 1)


@numba.njit(cache=True, nogil=True)
def _setup_kernel(lo, hi, window, size, ends, width, depth):
    for t in range(lo, hi):
        xa, ya = snap(window[t, 0, 0]), snap(window[t, 0, 1])
        xb, yb = snap(window[t, 1, 0]), snap(window[t, 1, 1])
        w = max(np.int64(np.floor(size[t] + 0.5)), np.int64(1))
        shift = (w - 1) * RADIUS                     # (w − 1)/2 pixels, exact in fixed point
        if abs(xb - xa) >= abs(yb - ya):             # x-major: move down
            ya -= shift
            yb -= shift
        else:                                        # y-major: move left
            xa -= shift
            xb -= shift
        ends[t, 0], ends[t, 1], ends[t, 2], ends[t, 3] = xa, ya, xb, yb
        width[t] = w
        depth[t, 0], depth[t, 1] = window[t, 0, 2], window[t, 1, 2]


def setup_lines(window: np.ndarray, size: np.ndarray) -> LineSetup:
    """Set up every line: ``window`` [L, 3, 3] the corners (a, b, b) in window coordinates, ``size`` [L]
    the widths in pixels."""
    n = len(window)
    s = LineSetup(np.empty((n, 4), np.int64), np.empty(n, np.int64), np.empty((n, 2)))
    if n:
        in_bands(_setup_kernel, n, window, np.ascontiguousarray(size, np.float64), s.ends, s.width, s.depth,
                 grain=8192)
    return s


# --------------------------------------------------------------- the rule, exactly

@numba.njit(cache=True, forceinline=True)
def _at_most(x, k, e1, e2):
    """x ≤ k + e1·ε + e2·ε² for an infinitesimal ε > 0 (x, k, e1, e2 integers)."""
    if x != k:
        return x < k
    return e1 > 0 or (e1 == 0 and e2 >= 0)


@numba.njit(cache=True, forceinline=True)
def _at_least(x, k, e1, e2):
    """x ≥ k + e1·ε + e2·ε² for an infinitesimal ε > 0."""
    if x != k:
        return x > k
    return e1 < 0 or (e1 == 0 and e2 <= 0)


@numba.njit(cache=True, forceinline=True)
def _apart_along(nx, ny, xa, ya, xb, yb, cx, cy, reach):
    """Is the segment apart from the perturbed diamond along the axis (nx, ny)?

    The segment's projection is [lo, hi]; the diamond moved by +(ε, ε²) (the same as
    moving the segment by −(ε, ε²)) projects to the open interval centred at
    n·c + n_x·ε + n_y·ε² with half-width ``reach``. Touching is apart: the diamond is open.
    """
    pa, pb = nx * xa + ny * ya, nx * xb + ny * yb
    lo, hi = min(pa, pb), max(pa, pb)
    centre = nx * cx + ny * cy
    return _at_most(hi, centre - reach, nx, ny) or _at_least(lo, centre + reach, nx, ny)


@numba.njit(cache=True, forceinline=True)
def crosses_diamond(xa, ya, xb, yb, cx, cy):
    """Does the segment (X_a, Y_a)–(X_b, Y_b), both ends moved by −(ε, ε²), meet the open diamond of
    half-diagonal ½ pixel centred at (cx, cy)? All in fixed point.

    Two convex shapes are apart exactly when some axis among their edges' normals separates
    them: the diamond's (1, 1) and (1, −1), and the segment's normal. The diamond's reach
    along (n_x, n_y) is ½·max(|n_x|, |n_y|) pixels.
    """
    if _apart_along(1, 1, xa, ya, xb, yb, cx, cy, RADIUS) or _apart_along(1, -1, xa, ya, xb, yb, cx, cy, RADIUS):
        return False
    nx, ny = -(yb - ya), xb - xa
    return not _apart_along(nx, ny, xa, ya, xb, yb, cx, cy, RADIUS * max(abs(nx), abs(ny)))


@numba.njit(cache=True, forceinline=True)
def holds_end(xb, yb, cx, cy):
    """Is the end (X_b, Y_b), moved by −(ε, ε²), inside the open diamond centred at (cx, cy)?

    |u − ε| + |v − ε²| < ½ with (u, v) the end less the centre: inside the diamond, or
    on its border with u > 0 (the perturbation takes such a point inside, and every
    other border point outside).
    """
    u, v = xb - cx, yb - cy
    d = abs(u) + abs(v)
    return d < RADIUS or (d == RADIUS and u > 0)


@numba.njit(cache=True, forceinline=True)
def produces(xa, ya, xb, yb, i, j):
    """The diamond-exit rule: does the segment produce the fragment of pixel (i, j) (window, y up)?"""
    cx, cy = i * SUBPIXEL, j * SUBPIXEL
    return crosses_diamond(xa, ya, xb, yb, cx, cy) and not holds_end(xb, yb, cx, cy)


@numba.njit(cache=True, forceinline=True)
def _parameter(xa, ya, dx, dy, length2, px, py):
    """t = ((p − a)·(b − a)) / |b − a|² at the fixed-point position (px, py), clamped to [0, 1]."""
    t = ((px - xa) * dx + (py - ya) * dy) / length2
    return min(max(t, 0.0), 1.0)


@numba.njit(cache=True, inline="always")
def line_walk(ends, t):
    """What walking line t needs: (x_major, ma, mb, na, nd, md, step, first, last), or step 0 for a line of
    length 0 (no fragment).

    (ma, mb) are the ends' major coordinates, na the first end's minor one, (nd, md) the
    minor and major extents; the walk goes from column (row, for a y-major line) ``first``
    to ``last`` by ``step`` (±1): exactly the columns whose open slab (centre ± ½) the
    segment's major extent meets once moved by −ε (the perturbation's part along the major
    axis, ε or ε²), the only ones where one of its diamonds can be crossed: column c with
    c·256 + 128 ≥ min(ma, mb) and c·256 − 128 < max(ma, mb).
    """
    xa, ya, xb, yb = ends[t, 0], ends[t, 1], ends[t, 2], ends[t, 3]
    dx, dy = xb - xa, yb - ya
    x_major = abs(dx) >= abs(dy)
    # (major, minor) coordinates: x and y for an x-major line, y and x for a y-major one
    ma, mb, na, nd, md = (xa, xb, ya, dy, dx) if x_major else (ya, yb, xa, dx, dy)
    if dx == 0 and dy == 0:
        return x_major, ma, mb, na, nd, md, 0, 0, -1
    low = -((RADIUS - min(ma, mb)) // SUBPIXEL)                # ⌈(min − 128)/256⌉
    high = -((-(max(ma, mb) + RADIUS)) // SUBPIXEL) - 1         # ⌈(max + 128)/256⌉ − 1
    if mb >= ma:
        return x_major, ma, mb, na, nd, md, 1, low, high
    return x_major, ma, mb, na, nd, md, -1, high, low


@numba.njit(cache=True, forceinline=True)
def minor_start(major, ma, na, nd, md):
    """Where the line (as :func:`line_walk` gives it) passes column (row) ``major``, exactly: (row, rem, inc,
    span), with its minor coordinate there na + (256·major − ma)·nd/md = 256·row + rem/|md|.

    ``row`` is the row (column) nearest the line, halves down, so rem is in [−128·|md|, 128·|md|);
    ``inc`` is what rem gains from one column to the next along the walk's step, and ``span`` =
    256·|md| (one row): :func:`minor_step` carries them on. All integers, so the walk's rows are
    exact: no row is missed or guessed where the line passes ½ pixel from two.
    """
    span = SUBPIXEL * abs(md)
    sign = 1 if md > 0 else -1
    p = (na * md + (major * SUBPIXEL - ma) * nd) * sign          # = the minor coordinate · |md|
    row = (2 * p + span) // (2 * span)                          # ⌊p / span + ½⌋
    # the walk steps by sign(md) columns, so p gains sign(md)·256·nd·sign = 256·nd a column
    return row, p - row * span, SUBPIXEL * nd, span


@numba.njit(cache=True, forceinline=True)
def minor_step(row, rem, inc, span):
    """(row, rem) of :func:`minor_start` at the walk's next column: |inc| ≤ span (|slope| ≤ 1), so the
    row moves by at most one; without a branch (which row it moves to follows the line, not a pattern)."""
    rem += inc
    carry = np.int64(2 * rem >= span) - np.int64(2 * rem < -span)
    return row + carry, rem - carry * span


@numba.njit(cache=True, forceinline=True)
def column_candidates(major, ma, mb, row, rem, span):
    """The candidate diamonds of column (row) ``major`` of a line, at (row, rem) of :func:`minor_start`:
    (lo, hi, sure), minor indices lo..hi.

    An x-major line (|slope| ≤ 1) meets a diamond of this column only if it passes within ½
    pixel of its centre here: along the line the minor coordinate moves no faster than the
    major one, and the diamond's |u| + |v| < ½ then bounds |v| at u = 0. So the candidate is
    ``row``, the row nearest the line, and the row below it too where the line passes exactly
    halfway between them (rem = −½ pixel: the perturbation decides); :func:`produces` decides.

    A column whose whole slab (centre ± ½) lies strictly inside the segment's major extent,
    where the line passes strictly within ½ of ``row``, is ``sure``: the segment crosses that
    diamond (through its centre's column) and no other in the column, the end is not in it
    (it is beyond the slab), and no tie needs the perturbation. So the rule's answer is known
    without the exact tests.
    """
    tie = 2 * rem == -span
    inside = major * SUBPIXEL - RADIUS > min(ma, mb) and major * SUBPIXEL + RADIUS < max(ma, mb)
    return (row - 1 if tie else row), row, inside and not tie


@numba.njit(cache=True, forceinline=True)
def sample_means(offsets, positions):
    """The centroid of all the samples (a line's or point's fragment covers every one): their mean
    fixed-point offset and mean position, (mx, my, px, py)."""
    samples = offsets.shape[0]
    mx, my, px, py = 0.0, 0.0, 0.0, 0.0
    for m in range(samples):
        mx += offsets[m, 0]
        my += offsets[m, 1]
        px += positions[m, 0]
        py += positions[m, 1]
    return mx / samples, my / samples, px / samples, py / samples


@numba.njit(cache=True, inline="always")
def line_parameter(ends, t, px, py):
    """t = ((p − a)·(b − a)) / |b − a|² along line t at the fixed-point position (px, py), clamped to [0, 1]."""
    xa, ya = ends[t, 0], ends[t, 1]
    dx, dy = ends[t, 2] - xa, ends[t, 3] - ya
    return _parameter(xa, ya, dx, dy, float(dx * dx + dy * dy), px, py)


@numba.njit(cache=True, inline="always")
def depth_along(depth, t, ts):
    """The window depth (1 − t)·z_a + t·z_b of line t at ``ts``, clamped to [0, 1]."""
    return _clamped_depth(depth[t, 0], depth[t, 1] - depth[t, 0], ts)


@numba.njit(cache=True, forceinline=True)
def _clamped_depth(z_a, dz, ts):
    """z_a + t·(z_b − z_a) (``dz`` = z_b − z_a) clamped to [0, 1]: the one formula of a line's depth."""
    return min(max(z_a + ts * dz, 0.0), 1.0)


@numba.njit(cache=True, inline="always")
def line_depth_terms(ends, depth, t):
    """What the depth along line t needs, read once a line: (X_a, Y_a, ΔX, ΔY, |Δ|², z_a, z_b − z_a), for
    :func:`depth_at`."""
    xa, ya = ends[t, 0], ends[t, 1]
    dx, dy = ends[t, 2] - xa, ends[t, 3] - ya
    return xa, ya, dx, dy, float(dx * dx + dy * dy), depth[t, 0], depth[t, 1] - depth[t, 0]


@numba.njit(cache=True, inline="always")
def depth_at(terms, px, py):
    """The window depth at the fixed-point position (px, py) of the line of ``terms`` (:func:`line_depth_terms`):
    :func:`depth_along` at :func:`line_parameter`'s t there, the same operations, so the same bits."""
    xa, ya, dx, dy, length2, z_a, dz = terms
    return _clamped_depth(z_a, dz, _parameter(xa, ya, dx, dy, length2, px, py))


@numba.njit(cache=True, inline="always")
def line_sample_depth(ends, depth, t, i, j, s, offsets):
    """The window depth of line t's fragment of run start (i, j) at sample s: t taken at the sample."""
    return depth_at(line_depth_terms(ends, depth, t), i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1])


@numba.njit(cache=True, forceinline=True)
def line_shading_point(ends, t, i, j, pi, pj, s, offsets, positions, mode, means):
    """Where line t's fragment at pixel (pi, pj), of the run starting at (i, j), is shaded: (t_b, fx, fy),
    the parameter along the segment and the window position (``means``: :func:`sample_means`).

    The run's attributes are its first fragment's: t at (i, j), not (pi, pj).
    """
    xa, ya = ends[t, 0], ends[t, 1]
    dx, dy = ends[t, 2] - xa, ends[t, 3] - ya
    length2 = float(dx * dx + dy * dy)
    if mode == SHADE_SAMPLE:         # (the t of the sample's depth, line_sample_depth's)
        tb = line_parameter(ends, t, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1])
        return tb, pi + positions[s, 0], pj + positions[s, 1]
    if mode == SHADE_CENTER:
        return _parameter(xa, ya, dx, dy, length2, i * SUBPIXEL, j * SUBPIXEL), pi + 0.5, pj + 0.5
    # the centroid of the covered samples: all of them
    mx, my, px, py = means
    return _parameter(xa, ya, dx, dy, length2, i * SUBPIXEL + mx, j * SUBPIXEL + my), pi + px, pj + py


@numba.njit(cache=True, inline="always")
def line_sample_inputs(ends, zends, run, t, i, j, s, row, offsets, positions, mode, means):
    """The shader's inputs at sample s of pixel (i, j) (image row ``row``) where line t is the one kept:
    (b0, b1, b2, fx, fy, z), the barycentrics, window position and depth the reference path's
    fragment there has (``run``: the place in its run of a wide line's fragment at each sample,
    or empty; ``means``: :func:`sample_means`).

    A run's fragments have its first fragment's attributes; shaded at the sample, t and the depth
    are the sample's; at the centre or centroid the depth is the run's first sample's, where the
    reference path shades a multisampled pixel's run once.
    """
    r = np.int64(run[s, row, i]) if run.shape[0] > 0 else np.int64(0)
    x_major = abs(ends[t, 2] - ends[t, 0]) >= abs(ends[t, 3] - ends[t, 1])
    i0, j0 = (i, j - r) if x_major else (i - r, j)          # the run's first fragment
    if mode == SHADE_SAMPLE:     # t at the sample, for the depth and the attributes alike
        tb = line_parameter(ends, t, i0 * SUBPIXEL + offsets[s, 0], j0 * SUBPIXEL + offsets[s, 1])
        px, py = i + positions[s, 0], j + positions[s, 1]
        z = depth_along(zends, t, tb)
    else:
        tb, px, py = line_shading_point(ends, t, i0, j0, i, j, s, offsets, positions, mode, means)
        z = line_sample_depth(ends, zends, t, i0, j0, 0, offsets)
    return 1.0 - tb, tb, 0.0, px, py, z


@numba.njit(cache=True)
def cover_line(ends, width, depth, t, rect, height, offsets, positions, mode, out_x, out_y, out_s, out_depth,
               out_bary, out_pos, start, emit):
    """Visit every fragment of line t (every sample of each produced pixel); write them from ``start`` if
    ``emit``. Returns the count.

    Along the major axis from a's end to b's (:func:`line_walk`), the candidate diamonds of
    each column (row, for a y-major line) are the one nearest the line there, and at a tie
    the one below it too (:func:`column_candidates`); :func:`produces` decides. Each produced
    fragment is a run of ``width`` pixels across the minor axis (within ``rect``, the
    scissor), and every sample of a pixel is covered.
    """
    xa, ya, xb, yb = ends[t, 0], ends[t, 1], ends[t, 2], ends[t, 3]
    x_major, ma, mb, na, nd, md, step, first, last = line_walk(ends, t)
    if step == 0:
        return 0
    samples = offsets.shape[0]
    means = sample_means(offsets, positions)
    terms = line_depth_terms(ends, depth, t)
    n = 0
    row, rem, inc, span = minor_start(first, ma, na, nd, md)
    for major in range(first, last + step, step):
        lo, hi, sure = column_candidates(major, ma, mb, row, rem, span)
        row, rem = minor_step(row, rem, inc, span)
        for minor in range(lo, hi + 1):
            i, j = (major, minor) if x_major else (minor, major)
            if not sure and not produces(xa, ya, xb, yb, i, j):
                continue
            for r in range(width[t]):
                pi, pj = (i, j + r) if x_major else (i + r, j)
                if pi < rect[0] or pi > rect[1] or pj < rect[2] or pj > rect[3]:
                    continue
                if not emit:
                    n += samples
                    continue
                for s in range(samples):
                    k = start + n
                    tb, fx, fy = line_shading_point(ends, t, i, j, pi, pj, s, offsets, positions, mode, means)
                    out_x[k] = pi
                    out_y[k] = height - 1 - pj     # the y flip: window row → image row
                    out_s[k] = s
                    out_depth[k] = depth_at(terms, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1])
                    out_bary[k, 0] = 1.0 - tb
                    out_bary[k, 1] = tb
                    out_bary[k, 2] = 0.0
                    out_pos[0, k] = fx
                    out_pos[1, k] = fy
                    n += 1
    return n
