# Lesson 10, the exercise completed: Möller–Trumbore, both sides of the triangle, hits in front of the origin.

import numpy as np


def intersect(origin, direction, v0, v1, v2):
    """None for a miss, or (t, b1, b2): origin + t·direction = (1 − b1 − b2)·v0 + b1·v1 + b2·v2 with t > 0."""
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(direction, e2)
    det = p @ e1
    if det == 0:                                  # the ray is parallel to the triangle's plane
        return None
    s = origin - v0
    u = (s @ p) / det
    if u < 0 or u > 1:
        return None
    q = np.cross(s, e1)
    v = (direction @ q) / det
    if v < 0 or u + v > 1:
        return None
    t = (e2 @ q) / det
    if t <= 0:                                    # behind the origin
        return None
    return t, u, v
