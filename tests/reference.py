"""A reference rasterizer for the tests: plain Python, exact rational arithmetic.

Written independently of softpipe.raster from the rules in DESIGN.md: snap to
1/256 pixel (round half to even), then for every sample of the whole
framebuffer decide coverage with Fractions. The fill rule is stated here
geometrically, not with softpipe's edge-direction test: a sample exactly on an
edge is covered when the edge is a *left* edge (the triangle lies to its right)
or a *bottom* edge (horizontal, the triangle above it), in y-up window
coordinates.
"""
from fractions import Fraction


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


def covered(tri, width, height, samples=((Fraction(1, 2), Fraction(1, 2)),)):
    """The set of (i, j, s) covered by a triangle given in window coordinates (y up).

    ``tri`` is three (x, y) window positions; ``samples`` positions within a pixel.
    Returns window pixel coordinates (j counts rows from the bottom).
    """
    v = [(snap(x), snap(y)) for x, y in tri]
    orient = _side(v[0], v[1], v[2])
    if orient == 0:
        return set()
    edges = [(v[1], v[2], v[0]), (v[2], v[0], v[1]), (v[0], v[1], v[2])]
    offs = [(snap(sx), snap(sy)) for sx, sy in samples]  # sample positions, pixel 0
    out = set()
    for j in range(height):
        for i in range(width):
            for s, (ox, oy) in enumerate(offs):
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
