# Lesson 08, the exercises completed: GL's LINEAR filter on one level, the texture repeating; the level of detail.

import math


def bilinear(image, u, v):
    """The four texels whose centres surround (u·W − ½, v·H − ½), weighted by nearness; v = 0 is the
    image's bottom row; each index wrapped on its own (repeat)."""
    h, w = image.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    i0, j0 = math.floor(x), math.floor(y)
    a, b = x - i0, y - j0

    def texel(i, j):
        return image[h - 1 - (j % h), i % w]

    return ((1 - a) * (1 - b) * texel(i0, j0) + a * (1 - b) * texel(i0 + 1, j0)
            + (1 - a) * b * texel(i0, j0 + 1) + a * b * texel(i0 + 1, j0 + 1))


def level_of_detail(duv_dx, duv_dy, width, height):
    """GL's λ = log2 ρ: the derivatives in texels of level 0 (u by the width, v by the height), the
    longer of the footprint's two sides, ρ = max(ρ_x, ρ_y)."""
    rho_x = math.hypot(duv_dx[0] * width, duv_dx[1] * height)
    rho_y = math.hypot(duv_dy[0] * width, duv_dy[1] * height)
    return math.log2(max(rho_x, rho_y))
