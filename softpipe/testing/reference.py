"""A reference rasterizer: plain Python, exact rational arithmetic, slow on purpose.

Written independently of softpipe.pipeline.raster (and imported by nothing in the
pipeline) from the rules in docs/design.md: snap to 1/256 pixel (round half to
even), then decide every sample with exact integers and Fractions. The fill
rule is stated here geometrically, not with softpipe's edge-direction test: a
sample exactly on an edge is covered when the edge is a *left* edge (the
triangle lies to its right) or a *bottom* edge (horizontal, the triangle above
it), in y-up window coordinates.

:func:`reference_coverage` is the public face (softpipe.testing), for testing
a rasterizer of one's own against it; :func:`covered` is the per-triangle core
softpipe's own test suite uses.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np

__all__ = ["reference_coverage", "covered", "snap", "picture"]

CENTRE = ((Fraction(1, 2), Fraction(1, 2)),)


def snap(v) -> int:
    """round((v − ½)·256) with ties to even, exactly (Python's round is half-even)."""
    return round((Fraction(v) - Fraction(1, 2)) * 256)


def _side(a, b, p) -> int:
    """Sign of the cross product (b − a) × (p − a): +1 left of a→b, −1 right, 0 on the line."""
    v = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
    return (v > 0) - (v < 0)


def _edge_owns(a, b, c) -> bool:
    """Does edge ab own the samples on it, given the triangle's third corner c?"""
    if a[1] == b[1]:                       # horizontal: owned if it is the bottom (c above)
        return c[1] > a[1]
    # not horizontal: owned if it is a left edge, i.e. c lies to the right of the line
    # at c's height: compare c.x with the edge's x at y = c.y
    t = Fraction(c[1] - a[1], b[1] - a[1])
    x_on_edge = a[0] + t * (b[0] - a[0])
    return c[0] > x_on_edge


def _first_last(lo, hi, offset, size):
    """Pixels i in [0, size) with lo ≤ 256·i + offset ≤ hi (a sample can only be covered inside the box)."""
    first = max(0, -((offset - lo) // 256))
    last = min(size - 1, (hi - offset) // 256)
    return first, last


def covered(tri, width, height, samples=CENTRE):
    """The set of (i, j, s) covered by a triangle given in window coordinates (y up).

    ``tri`` is three (x, y) window positions (numbers or Fractions); ``samples``
    positions within a pixel (y up). Returns window pixel coordinates (j counts
    rows from the bottom) and the sample's index.
    """
    v = [(snap(x), snap(y)) for x, y in tri]
    orient = _side(v[0], v[1], v[2])
    if orient == 0:
        return set()
    edges = [(v[1], v[2], v[0]), (v[2], v[0], v[1]), (v[0], v[1], v[2])]
    offs = [(snap(sx), snap(sy)) for sx, sy in samples]  # sample positions, pixel 0
    xs, ys = [p[0] for p in v], [p[1] for p in v]
    out = set()
    for s, (ox, oy) in enumerate(offs):
        i0, i1 = _first_last(min(xs), max(xs), ox, width)
        j0, j1 = _first_last(min(ys), max(ys), oy, height)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                p = (256 * i + ox, 256 * j + oy)
                ok = True
                for a, b, c in edges:
                    side = _side(a, b, p)
                    if side == 0:
                        if not _edge_owns(a, b, c):
                            ok = False
                            break
                    elif side != orient:
                        ok = False
                        break
                if ok:
                    out.add((i, j, s))
    return out


def picture(cells, width, height, mark="#"):
    """ASCII picture of a set of (i, j) window pixels, top row first."""
    rows = []
    for j in reversed(range(height)):
        rows.append("".join(mark if (i, j) in cells else "." for i in range(width)))
    return "\n".join(rows)


def _exact(value, name):
    try:
        return Fraction(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be finite numbers, got {value!r}") from None


def reference_coverage(positions, width: int, height: int, *, indices=None, samples=None, cull: str = "none",
                       front_face: str = "ccw"):
    """:func:`~softpipe.testing.coverage`, computed the slow exact way (window coordinates only).

    Every vertex is snapped to 1/256 pixel with exact rationals and every sample
    decided with exact integers; independent of softpipe's rasterizer, so a
    rasterizer of your own (or softpipe's) can be checked against it. Arguments
    and result as :func:`~softpipe.testing.coverage` with ``space="window"``;
    ``positions`` may also hold ``fractions.Fraction``. The facing (for
    ``cull``) is the sign of the exact signed area of the given corners. Slow:
    keep images small (a few thousand samples per triangle).
    """
    from softpipe.pipeline.assembly import CULL_MODES, FRONT_FACES, triangle_indices
    from softpipe.testing.coverage import Coverage, as_pattern, check_samples, check_size

    width, height = check_size(width, height)
    if cull not in CULL_MODES:
        raise ValueError(f"cull must be one of {CULL_MODES}, got {cull!r}")
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    pattern = as_pattern(samples)
    rows = _rows(positions)
    pos = [(_exact(r[0], "positions"), _exact(r[1], "positions")) for r in rows]
    tri = triangle_indices("triangles", indices, len(pos))
    offsets = CENTRE if pattern is None else [(Fraction(float(x)), Fraction(float(y))) for x, y in pattern.positions]
    s_count = len(offsets)
    check_samples(width, height, s_count)
    count = np.zeros((height, width, s_count), np.int64)
    ids = np.full((height, width, s_count), -1, np.int64)
    for t, (a, b, c) in enumerate(tri.tolist()):
        corners = [pos[a], pos[b], pos[c]]
        if cull != "none":
            (ax, ay), (bx, by), (cx, cy) = corners
            area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
            front = area > 0 if front_face == "ccw" else area < 0
            if (cull == "back") != front:
                continue
        for i, j, s in covered(corners, width, height, offsets):
            count[height - 1 - j, i, s] += 1
            ids[height - 1 - j, i, s] = t
    if pattern is None:
        count, ids = count[:, :, 0], ids[:, :, 0]
    return Coverage(mask=count > 0, primitive_id=ids, count=count, pattern=pattern)


def _rows(positions):
    """[N, 2|3] or [T, 3, 2|3] rows of numbers or Fractions, as a list of rows."""
    arr = np.asarray(positions, dtype=object)
    if arr.ndim == 3 and arr.shape[1] == 3 and arr.shape[2] in (2, 3):
        arr = arr.reshape(-1, arr.shape[2])
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"positions must have shape [N, 2] or [N, 3] or [T, 3, 2|3] (window coordinates in "
                         f"pixels), got {list(arr.shape)}")
    return arr.tolist()
