"""A reference for line segments and points: plain Python, exact arithmetic, slow on purpose.

The companion of :mod:`softpipe.testing.reference` (triangles), in a file of its
own because it states other rules (a segment's diamond-exit rule, a point's
square) and shares only :func:`~softpipe.testing.reference.snap` with it. Written
from the OpenGL specification's text, not from softpipe's pipeline (which it does
not import), so a line drawer (softpipe's, or one's own) can be checked against it.

Every position is first snapped to the 1/256-pixel grid exactly as triangle corners
are (:func:`~softpipe.testing.reference.snap`: round half to even of (v − ½)·256).
From there on all is exact integers: in snapped units pixel (i, j)'s centre is at
(256·i, 256·j) and its diamond is |X − 256·i| + |Y − 256·j| < 128.

The rules, as the specification states them
-------------------------------------------
Segments, width 1 (GL 4.6 §14.5.1; the same text as GL 1.1 §3.4.1):

    "Ideally, the GL uses a 'diamond-exit' rule to determine those fragments that
    are produced by rasterizing a line segment. For each fragment f with center at
    window coordinates x_f and y_f, define a diamond-shaped region that is the
    intersection of four half planes: R_f = {(x, y) | |x − x_f| + |y − y_f| < 1/2}.
    Essentially, a line segment starting at p_a and ending at p_b produces those
    fragments f for which the segment intersects R_f, except if p_b is contained
    in R_f."

    "To avoid difficulties when an endpoint lies on a boundary of R_f we (in
    principle) perturb the supplied endpoints by a tiny amount. Let p_a and p_b
    have window coordinates (x_a, y_a) and (x_b, y_b), respectively. Obtain the
    perturbed endpoints p'_a given by (x_a, y_a) − (ε, ε²) and p'_b given by
    (x_b, y_b) − (ε, ε²). Rasterizing the line segment starting at p_a and ending
    at p_b produces those fragments f for which the segment starting at p'_a and
    ending on p'_b intersects R_f, except if p'_b is contained in R_f. ε is chosen
    to be so small that rasterizing the line segment produces the same fragments
    when δ is substituted for ε for any 0 < δ ≤ ε."

    "When p_a and p_b lie on fragment centers, this characterization of fragments
    reduces to Bresenham's algorithm with one modification: lines produced in this
    description are 'half-open,' meaning that the final fragment (corresponding to
    p_b) is not drawn."

    "x-major line segments have slope in the closed interval [−1, 1]; all other
    line segments are y-major."

ε is kept symbolic here: a number a + b·ε + c·ε² is the tuple (a, b, c), and
"small enough ε" is exactly the lexicographic order of those tuples (Python's
tuple comparison), so ties on a diamond's boundary get the one answer the
specification means, never a float's. (ε is applied in snapped units; that
scales the ε² term by 1/256 against the ε term, and every quantity compared is
linear in the perturbation, so no comparison's sign changes.)

Wide lines (GL 4.6 compatibility profile §14.5.2.1, GL 1.1 §3.4.2 "Wide Lines"):

    "Non-antialiased line segments of width other than one are rasterized by
    offsetting them in the minor direction (for an x-major line, the minor
    direction is y, and for a y-major line, the minor direction is x) and
    replicating fragments in the minor direction."

    "Let w be the width rounded to the nearest integer (if w = 0, then it is as if
    w = 1). If the line segment has endpoints given by (x_0, y_0) and (x_1, y_1) in
    window coordinates, the segment with endpoints (x_0, y_0 − (w − 1)/2) and
    (x_1, y_1 − (w − 1)/2) is rasterized, but instead of a single fragment, a
    column of fragments of height w (a row of fragments of length w for a y-major
    segment) is produced at each x (y for y-major) location. The lowest fragment
    of this column is the fragment that would be produced by rasterizing the
    segment of width 1 with the modified coordinates."

The specification does not say which way a width of exactly k + ½ rounds; this
reference rounds halves up (⌊w + ½⌋, as the issue's ⌊w⌉). The offset (w − 1)/2 is
a multiple of ½, on the snapping grid, so offsetting before or after snapping is
the same.

Points (the square of GL 4.6 §14.4, with the half-open edges softpipe's issue #29
states): a fragment for every pixel whose centre lies in
[x − s/2, x + s/2) × [y − s/2, y + s/2), s = max(size, 1); the point's (x, y) is
snapped to the 1/256 grid like a vertex, the size is used exactly as given (not
snapped, not rounded).
"""
from __future__ import annotations

import math
from fractions import Fraction
from typing import Iterable, Set, Tuple

from softpipe.testing.reference import snap

__all__ = ["reference_line", "reference_point", "reference_line_parameter", "line_width_fragments",
           "snapped", "diamond_touched"]

Pixel = Tuple[int, int]

HALF = 128          # ½ pixel in snapped units
UNIT = 256          # 1 pixel in snapped units


def _number(value, name: str) -> Fraction:
    """An exact Fraction of a finite number, or a ValueError naming the argument."""
    try:
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError
        return Fraction(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None


def _xy(p, name: str) -> Tuple[Fraction, Fraction]:
    try:
        items = list(p)
    except TypeError:
        raise ValueError(f"{name} must be a window position (x, y), got {p!r}") from None
    if len(items) < 2:
        raise ValueError(f"{name} must be a window position (x, y), got {p!r}")
    return _number(items[0], f"{name}[0]"), _number(items[1], f"{name}[1]")


def snapped(p) -> Tuple[int, int]:
    """A window position (x, y), pixels, y up, snapped: integers in 1/256 pixel, pixel i's centre at 256·i."""
    return _snap_named(p, "position")


def _snap_named(p, name):
    x, y = _xy(p, name)
    return snap(x), snap(y)


# --------------------------------------------------------------- the diamond rule

def _inside(q) -> bool:
    """Is the perturbed point q (two (a, b, c) tuples, relative to a centre) inside the open diamond?"""
    for sx in (1, -1):
        for sy in (1, -1):
            value = tuple(sx * u + sy * v for u, v in zip(q[0], q[1]))
            if not value < (HALF, 0, 0):
                return False
    return True


def diamond_touched(a: Tuple[int, int], b: Tuple[int, int], centre: Tuple[int, int]) -> bool:
    """Does the perturbed segment a' → b' meet the open diamond of ``centre`` (all in snapped units)?

    The diamond is four open half-planes s_x·(x − x_c) + s_y·(y − y_c) < 128. Along
    P(t) = a' + t·(b − a), t ∈ [0, 1], each is A + t·B < 0 with A = s_x·(a'_x − x_c)
    + s_y·(a'_y − y_c) − 128 (a number with ε terms) and B = s_x·Δx + s_y·Δy (an
    integer): B > 0 bounds t above (t < −A/B), B < 0 below (t > −A/B), B = 0 needs
    A < 0 outright. The segment meets the diamond iff the largest lower bound
    (0 among them) is below the smallest upper bound (1 among them); only the
    pair (0, 1) is non-strict, and 0 < 1.
    """
    dx, dy = b[0] - a[0], b[1] - a[1]
    # a' − centre = (a_x − x_c − ε, a_y − y_c − ε²) as (constant, ε, ε²) tuples
    qx = (a[0] - centre[0], -1, 0)
    qy = (a[1] - centre[1], 0, -1)
    lower: tuple = (Fraction(0), 0, 0)
    upper: tuple = (Fraction(1), 0, 0)
    for sx in (1, -1):
        for sy in (1, -1):
            big_a = (sx * qx[0] + sy * qy[0] - HALF, sx * qx[1] + sy * qy[1], sx * qx[2] + sy * qy[2])
            big_b = sx * dx + sy * dy
            if big_b == 0:
                if not big_a < (0, 0, 0):
                    return False
                continue
            bound = tuple(Fraction(-k, big_b) for k in big_a)
            if big_b > 0:
                upper = min(upper, bound)
            else:
                lower = max(lower, bound)
    return lower < upper


def _end_inside(b: Tuple[int, int], centre: Tuple[int, int]) -> bool:
    """Is b' = b − (ε, ε²) inside the open diamond of ``centre``?"""
    return _inside(((b[0] - centre[0], -1, 0), (b[1] - centre[1], 0, -1)))


def _candidates(a, b) -> Iterable[Pixel]:
    """Pixels whose diamond the segment could meet: a superset, walked along the major axis.

    Along an x-major segment (|slope| ≤ 1) the line's y moves at most 128 across a
    diamond's width of 256, so a diamond it meets has its centre within 256 of the
    line's y at the centre's x; 512 is kept as a margin. y-major: the same with x and y swapped.
    """
    (ax, ay), (bx, by) = a, b
    x_major = abs(bx - ax) >= abs(by - ay)
    if not x_major:
        for i, j in _candidates((ay, ax), (by, bx)):
            yield j, i
        return
    lo, hi = min(ax, bx), max(ax, bx)
    for i in range((lo - HALF) // UNIT - 1, (hi + HALF) // UNIT + 2):
        xc = UNIT * i
        if bx == ax:
            y_line = Fraction(ay)
        else:
            x_clamped = min(max(xc, lo), hi)
            y_line = ay + Fraction((x_clamped - ax) * (by - ay), bx - ax)
        for j in range(math.floor((y_line - 2 * UNIT) / UNIT), math.ceil((y_line + 2 * UNIT) / UNIT) + 1):
            yield i, j


def _diamond_exit(a: Tuple[int, int], b: Tuple[int, int]) -> Set[Pixel]:
    """The width-1 diamond-exit fragments of the snapped segment a → b."""
    if a == b:
        return set()        # b' lies in every diamond the (one-point) segment meets
    dx, dy = b[0] - a[0], b[1] - a[1]
    far = (HALF + 1) ** 2 * (dx * dx + dy * dy)
    out = set()
    for i, j in _candidates(a, b):
        centre = (UNIT * i, UNIT * j)
        # a shortcut, exact in integers: the diamond lies within 128 of its centre, so a centre more
        # than 129 from the segment's line (the perturbation moves it by far less than 1) is not met
        cross = dx * (centre[1] - a[1]) - dy * (centre[0] - a[0])
        if cross * cross > far:
            continue
        if diamond_touched(a, b, centre) and not _end_inside(b, centre):
            out.add((i, j))
    return out


def line_width_fragments(width) -> int:
    """The number of fragments across a non-antialiased wide line: ⌊width + ½⌋, at least 1."""
    w = _number(width, "width")
    if w <= 0:
        raise ValueError(f"width must be > 0 (pixels), got {width!r}")
    return max(1, math.floor(w + Fraction(1, 2)))


def reference_line(pa, pb, width=1) -> Set[Pixel]:
    """The window pixels (x, y), y up, that GL's rules give the segment from ``pa`` to ``pb``.

    Parameters
    ----------
    pa, pb : (x, y)
        Window coordinates in pixels, y up, pixel (x, y)'s centre at (x + ½, y + ½);
        floats, ints or Fractions (further items, such as z, are ignored).
    width : number
        The line width; rounded to ⌊width + ½⌋ (at least 1) fragments across.

    Returns
    -------
    set of (int, int)
        Every pixel the rule produces, unbounded (pixels may lie outside any framebuffer).

    Both endpoints are snapped to 1/256 pixel; width 1 is the diamond-exit rule with
    the (ε, ε²) perturbation done exactly; a wider line is the width-1 rule on the
    segment moved by −(w − 1)/2 along its minor axis, each fragment grown into a
    run of w along the minor axis (upwards for x-major, rightwards for y-major).
    The module docstring quotes the specification. A zero-length segment (after
    snapping) produces nothing.
    """
    a, b = _snap_named(pa, "pa"), _snap_named(pb, "pb")
    w = line_width_fragments(width)
    x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])
    shift = (w - 1) * HALF                      # (w − 1)/2 pixels, in snapped units
    if x_major:
        base = _diamond_exit((a[0], a[1] - shift), (b[0], b[1] - shift))
        return {(i, j + k) for i, j in base for k in range(w)}
    base = _diamond_exit((a[0] - shift, a[1]), (b[0] - shift, b[1]))
    return {(i + k, j) for i, j in base for k in range(w)}


def reference_line_parameter(pa, pb, pixel) -> Fraction:
    """GL's parameter t along the segment at ``pixel``'s centre, exactly, clamped to [0, 1].

    t = ((p_c − p_a)·(p_b − p_a)) / |p_b − p_a|² on the snapped endpoints (GL 4.6
    §14.5.1, equation 14.1), p_c = (x + ½, y + ½). Attributes along a line are
    (1 − t)·a + t·b (before any perspective correction). A zero-length segment
    has no parameter (ValueError).
    """
    a, b = _snap_named(pa, "pa"), _snap_named(pb, "pb")
    try:
        i, j = (int(v) for v in pixel)
    except (TypeError, ValueError):
        raise ValueError(f"pixel must be a pair of integers (x, y), got {pixel!r}") from None
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    if length2 == 0:
        raise ValueError(f"the segment from {pa!r} to {pb!r} has zero length after snapping to 1/256 pixel: "
                         f"it has no parameter t")
    t = Fraction((UNIT * i - a[0]) * dx + (UNIT * j - a[1]) * dy, length2)
    return min(max(t, Fraction(0)), Fraction(1))


# ---------------------------------------------------------------------- points

def _axis(c: int, s: Fraction) -> range:
    """Pixels i with c − 128·s ≤ 256·i < c + 128·s (snapped units): centres in [c − s/2, c + s/2)."""
    lo, hi = c - HALF * s, c + HALF * s
    return range(math.ceil(lo / UNIT), math.ceil(hi / UNIT))


def reference_point(p, size) -> Set[Pixel]:
    """The window pixels (x, y), y up, that a point at ``p`` of ``size`` pixels produces.

    Every pixel whose centre lies in [x − s/2, x + s/2) × [y − s/2, y + s/2) with
    s = max(size, 1) and (x, y) = ``p`` snapped to 1/256 pixel as a vertex is; the
    size itself is used exactly as given. ``size`` must be a finite number > 0.
    """
    x, y = _snap_named(p, "p")
    s = _number(size, "size")
    if s <= 0:
        raise ValueError(f"size must be > 0 (pixels), got {size!r}")
    s = max(s, Fraction(1))
    return {(i, j) for i in _axis(x, s) for j in _axis(y, s)}
