# Lesson 09, the exercise completed: the shadow-map depth compare (GL_LEQUAL) with percentage-closer filtering.

import math


def shadow_compare(depth, x, y, ref, r):
    """The share of the (2r+1)² texels around (floor(x), floor(y)) whose stored depth is ≥ ref (nothing nearer
    the light there); a texel outside the map counts as lit."""
    h, w = depth.shape
    i0, j0 = math.floor(x), math.floor(y)
    lit = 0
    for j in range(j0 - r, j0 + r + 1):
        for i in range(i0 - r, i0 + r + 1):
            if not (0 <= i < w and 0 <= j < h) or ref <= depth[j, i]:
                lit += 1
    return lit / (2 * r + 1) ** 2
