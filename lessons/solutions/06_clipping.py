# Lesson 06, the exercise completed: Sutherland–Hodgman against one plane, in clip space.

import numpy as np


def clip_polygon(polygon, plane):
    """Keep each corner inside (distance ≥ 0); where an edge crosses the plane, add the crossing point,
    computed from the edge's inside end (t = d_in / (d_in − d_out))."""
    d = polygon @ plane
    out = []
    n = len(polygon)
    for k in range(n):
        a, b = k, (k + 1) % n
        if d[a] >= 0:
            out.append(polygon[a])
        if (d[a] >= 0) != (d[b] >= 0):
            inside, outside = (a, b) if d[a] >= 0 else (b, a)
            t = d[inside] / (d[inside] - d[outside])
            out.append(polygon[inside] + t * (polygon[outside] - polygon[inside]))
    return np.array(out).reshape(-1, 4)
