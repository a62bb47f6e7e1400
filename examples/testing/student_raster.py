"""A student's triangle rasterizer, twice: the naive first try, and the one that follows OpenGL's rules.

Both take a triangle in window coordinates (pixels, y up: pixel (x, y) has its
centre at (x + ½, y + ½)) and return the set of (x, y) pixels it covers, the way
an assignment might ask for it. test_student_raster.py checks them against
softpipe.testing.coverage; the naive one fails, and the failures say why.
"""


def _edge(ax, ay, bx, by, px, py):
    """Twice the signed area of (a, b, p): > 0 when p is left of a→b (y up)."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


def naive_triangle(v0, v1, v2, width, height):
    """Every pixel whose centre is inside the triangle or on any of its edges.

    The bug: ``>= 0`` on every edge. A pixel centre exactly on an edge is drawn
    by *both* triangles that share the edge (and by a lone triangle, on its
    right and top edges too), so a mesh draws some pixels twice and blended
    meshes show seams.
    """
    (x0, y0), (x1, y1), (x2, y2) = v0[:2], v1[:2], v2[:2]
    if _edge(x0, y0, x1, y1, x2, y2) < 0:          # make it counter-clockwise
        (x1, y1), (x2, y2) = (x2, y2), (x1, y1)
    pixels = set()
    for y in range(height):
        for x in range(width):
            px, py = x + 0.5, y + 0.5
            if (_edge(x1, y1, x2, y2, px, py) >= 0 and _edge(x2, y2, x0, y0, px, py) >= 0
                    and _edge(x0, y0, x1, y1, px, py) >= 0):
                pixels.add((x, y))
    return pixels


def _snap(v):
    """Fixed point with 8 subpixel bits, relative to pixel centres: round((v − ½)·256), ties to even.

    Computed as round(v·256) − 128: v·256 is exact in floating point, v − ½ might not be.
    """
    return round(v * 256) - 128


def _owns(dx, dy):
    """OpenGL's fill rule for a counter-clockwise edge going (dx, dy), y up: left and bottom edges own their pixels."""
    return dy < 0 or (dy == 0 and dx > 0)


def fixed_triangle(v0, v1, v2, width, height):
    """The same loop, with OpenGL's rules: snapped vertices, exact integer edges, the fill rule."""
    pts = [(_snap(v[0]), _snap(v[1])) for v in (v0, v1, v2)]
    area = _edge(*pts[0], *pts[1], *pts[2])
    if area == 0:
        return set()
    if area < 0:
        pts = [pts[0], pts[2], pts[1]]
    edges = [(pts[k], pts[(k + 1) % 3]) for k in range(3)]
    pixels = set()
    for y in range(height):
        for x in range(width):
            px, py = 256 * x, 256 * y                   # pixel centres, in the same fixed point
            inside = True
            for (ax, ay), (bx, by) in edges:
                e = _edge(ax, ay, bx, by, px, py)
                if e < 0 or (e == 0 and not _owns(bx - ax, by - ay)):
                    inside = False
                    break
            if inside:
                pixels.add((x, y))
    return pixels
