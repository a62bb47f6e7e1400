"""The exact ray/triangle test: watertight, after Woop, Benthin and Wald (JCGT 2013).

A ray that passes exactly through the edge two triangles share must hit at least one of
them, or a closed mesh leaks (a shadow ray escapes a closed box, a camera ray sees the
background through a sphere). The test moves the corners to the ray's origin and shears
them so that the ray becomes the +z axis (:func:`ray_space`, once per ray); the 2D edge
functions U, V, W of the sheared corners are then computed from the *same* numbers for an
edge both triangles share, so they are exact negatives of each other. Where one is exactly
0 the three are recomputed exactly (error-free products and sums, :func:`_exact_cross`),
so that 0 means "exactly on the edge"; 0 counts as inside for both triangles, and both
sides of a triangle are hit. docs/raytracing.md ("The BVH") tells the longer story.

:func:`intersect_triangle` is the test on its own; the traversal
(:mod:`softpipe.rays.traverse`) computes the shear once per ray and calls
:func:`hit_sheared` on the triangles its vector filter names.
"""
from __future__ import annotations

import numba

__all__ = ["intersect_triangle", "ray_space", "hit_sheared"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _two_product(a, b):
    """a·b = p + e exactly (Dekker's product with Veltkamp's split; no overflow or underflow assumed)."""
    p = a * b
    c = 134217729.0 * a                      # 2^27 + 1
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = al * bl - (((p - ah * bh) - al * bh) - ah * bl)
    return p, e


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _two_sum(a, b):
    """a + b = s + e exactly (Knuth)."""
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)
    return s, e


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _exact_cross(a, b, c, d):
    """a·b − c·d with the exact sign (0 only when it is exactly 0), and nearly its value.

    The four doubles of two error-free products (a·b = p1 + e1, c·d = p2 + e2)
    are summed exactly into a nonoverlapping expansion (Shewchuk 1997,
    Grow-Expansion); its largest component has the sign of the exact sum, and the
    components summed from the smallest up give its value to within an ulp.
    """
    p1, e1 = _two_product(a, b)
    p2, e2 = _two_product(c, d)
    # grow the expansion by e1, −e2, p1, −p2 (each step: TwoSum through the components, smallest first)
    h0 = e1
    q, h0 = _two_sum(-e2, h0)
    h1 = q
    q, h0 = _two_sum(p1, h0)
    q, h1 = _two_sum(q, h1)
    h2 = q
    q, h0 = _two_sum(-p2, h0)
    q, h1 = _two_sum(q, h1)
    q, h2 = _two_sum(q, h2)
    h3 = q
    s = ((h0 + h1) + h2) + h3
    if s == 0.0:                             # the rounded sum cancelled: the largest nonzero part decides
        if h3 != 0.0:
            return h3
        if h2 != 0.0:
            return h2
        if h1 != 0.0:
            return h1
        return h0
    return s


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def ray_space(dx: float, dy: float, dz: float) -> tuple:
    """The shear of Woop et al. for direction (dx, dy, dz): (kx, ky, kz, Sx, Sy, Sz).

    kz is the axis where the direction is largest in magnitude; kx, ky the two
    others, swapped when d[kz] < 0 so that the shear keeps the winding. A point q
    becomes q' = (q[kx] − Sx·q[kz], q[ky] − Sy·q[kz], Sz·q[kz]) (after subtracting the
    origin): the ray is then the +z axis, and z' is the ray's t. A zero direction gives
    Sx = Sy = Sz = 0 (no ray: nothing is hit).
    """
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax > ay and ax > az:
        kz = 0
    elif ay > az:
        kz = 1
    else:
        kz = 2
    kx = kz + 1 if kz < 2 else 0
    ky = kx + 1 if kx < 2 else 0
    d = (dx, dy, dz)
    dkz = d[kz]
    if dkz < 0.0:
        kx, ky = ky, kx
    if dkz == 0.0:                           # a zero direction: no ray (a NaN one gives NaN below: no hit)
        return kx, ky, kz, 0.0, 0.0, 0.0
    return kx, ky, kz, d[kx] / dkz, d[ky] / dkz, 1.0 / dkz


# Not inlined into the traversal: it runs only on the block filter's candidates (about once per
# hit), so inlining it into every caller only lengthened cold compilation (benchmarks/README.md, "Rays").
@numba.njit(cache=True, nogil=True, error_model="numpy")
def hit_sheared(ax: float, ay: float, az: float, bx: float, by: float, bz: float, cx: float, cy: float, cz: float,
                kx: int, ky: int, kz: int, sx: float, sy: float, sz: float, t_min: float, t_max: float) -> tuple:
    """The watertight test on corners already moved to the ray's origin: (hit, t, b1, b2).

    Parameters
    ----------
    ax, ay, az, bx, by, bz, cx, cy, cz : float
        The corners a, b, c minus the origin, each in axis order (kx, ky, kz): ``ax`` is
        ``v0[kx] − origin[kx]``.
    kx, ky, kz, sx, sy, sz : int, float
        The ray's axes and shear, from :func:`ray_space`.
    t_min, t_max : float
        The open interval a hit must lie in.

    Returns
    -------
    tuple
        As :func:`intersect_triangle`: (hit, t, b1, b2), zeros for a miss.
    """
    # shear the corners into ray space (x', y'); z' scaled below
    Ax = ax - sx * az
    Ay = ay - sy * az
    Bx = bx - sx * bz
    By = by - sy * bz
    Cx = cx - sx * cz
    Cy = cy - sy * cz
    # edge functions: U opposite corner a (edge b→c), V opposite b, W opposite c
    U = Cx * By - Cy * Bx
    V = Ax * Cy - Ay * Cx
    W = Bx * Ay - By * Ax
    # (the tests below combine their comparisons with | and &, not "or" and "and": one branch
    # each, where short-circuits would branch on every sign, which a predictor cannot guess)
    if (U == 0.0) | (V == 0.0) | (W == 0.0):  # on an edge in float64: decide exactly
        U = _exact_cross(Cx, By, Cy, Bx)
        V = _exact_cross(Ax, Cy, Ay, Cx)
        W = _exact_cross(Bx, Ay, By, Ax)
    if ((U < 0.0) | (V < 0.0) | (W < 0.0)) & ((U > 0.0) | (V > 0.0) | (W > 0.0)):
        return False, 0.0, 0.0, 0.0          # the ray passes outside an edge
    det = U + V + W
    if det == 0.0:                           # seen edge-on, or a degenerate triangle
        return False, 0.0, 0.0, 0.0
    T = U * (sz * az) + V * (sz * bz) + W * (sz * cz)
    t = T / det
    if not ((t > t_min) & (t < t_max)):
        return False, 0.0, 0.0, 0.0
    return True, t, V / det, W / det


@numba.njit(cache=True, nogil=True, error_model="numpy")
def intersect_triangle(v0, v1, v2, origin, direction, t_min: float, t_max: float) -> tuple:
    """Watertight ray/triangle test (Woop, Benthin and Wald 2013): (hit, t, b1, b2).

    ``v0, v1, v2, origin, direction`` are 3-vectors (arrays or tuples). A hit
    has ``t_min < t < t_max`` and the point ``origin + t·direction`` equals
    ``(1 − b1 − b2)·v0 + b1·v1 + b2·v2``; either side of the triangle is hit.
    A ray through an edge or corner shared by two triangles hits at least one of
    them (see the module docstring). A zero direction or a degenerate triangle
    never hits.
    """
    dx, dy, dz = float(direction[0]), float(direction[1]), float(direction[2])
    kx, ky, kz, sx, sy, sz = ray_space(dx, dy, dz)
    if sz == 0.0:
        return False, 0.0, 0.0, 0.0
    o = (float(origin[0]), float(origin[1]), float(origin[2]))
    p0 = (v0[0] - o[0], v0[1] - o[1], v0[2] - o[2])
    p1 = (v1[0] - o[0], v1[1] - o[1], v1[2] - o[2])
    p2 = (v2[0] - o[0], v2[1] - o[1], v2[2] - o[2])
    return hit_sheared(p0[kx], p0[ky], p0[kz], p1[kx], p1[ky], p1[kz], p2[kx], p2[ky], p2[kz],
                       kx, ky, kz, sx, sy, sz, float(t_min), float(t_max))
