# Lesson 02, the exercise completed: the edge function and the fill rule, and the loop over
# pixel centres they make a rasterizer of (window coordinates, y up; corners counter-clockwise).


def edge_function(a, b, p):
    """Twice the signed area of (a, b, p): positive when p is left of a → b (y up)."""
    return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])


def owns_centres_on_it(a, b):
    """The fill rule: a counter-clockwise triangle's edge a → b owns the centres on it when it is a
    left edge (it runs down, dy < 0) or a bottom edge (horizontal, running right)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    return dy < 0 or (dy == 0 and dx > 0)


def covers(tri, p):
    """Does the counter-clockwise triangle ``tri`` cover the point ``p``?"""
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        e = edge_function(a, b, p)
        if e < 0 or (e == 0 and not owns_centres_on_it(a, b)):
            return False
    return True


def rasterize(triangles, width, height):
    """Every pixel (x, y) whose centre (x + ½, y + ½) one of the triangles covers."""
    return {(x, y) for tri in triangles for y in range(height) for x in range(width)
            if covers(tri, (x + 0.5, y + 0.5))}
