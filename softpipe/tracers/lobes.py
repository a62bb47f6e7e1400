"""The path tracer's glossy lobes: Phong, Blinn-Phong and Cook-Torrance as BRDFs that conserve energy (FORMULAS §27).

The notes' specular terms (§5, §6) are shading formulas, not BRDFs: ks·(R·V)ⁿ
reflects more light than it receives for small n and less for large n. The path
tracer (:mod:`.pathtrace`) needs each one as a density over directions that
integrates, with the cosine, to at most ks, so each is *normalized* here:

- **Phong** (Lafortune and Willems 1994): f = ks·(n + 2)/(2π)·(R·L)₊ⁿ, R = V
  mirrored about N. At V = N its albedo ∫ f (N·L) dω is exactly ks; elsewhere part
  of the lobe lies below the surface and it is less. Drawn about R with density
  (n + 1)/(2π)·(R·L)ⁿ, so f·(N·L)/p = ks·(n + 2)/(n + 1)·(N·L).
- **Blinn-Phong** (Ashikhmin and Shirley 2000): f = ks·(n + 1)/(8π)·(N·H)ⁿ /
  ((V·H)·max(N·L, N·V)). H is drawn about N with density (n + 1)/(2π)·(N·H)ⁿ and
  L = V mirrored about H (density that / (4 V·H)), so f·(N·L)/p = ks·(N·L)/max(N·L, N·V)
  ≤ ks: the albedo is at most ks for every V and n, and tends to ks as n → ∞.
- **Cook-Torrance** (§26, its normalized microfacet form): f = ks·D·G·F/(4 (N·L)(N·V)),
  Beckmann's D with m = ``roughness``, F exact (§20) from air into ``ior``. H is drawn
  from D (density D·(N·H), tan²α = −m²·ln(1 − u)), so f·(N·L)/p = ks·F·G·(V·H)/((N·V)(N·H)).
  A conductor (k ≠ 0) takes its exact F per channel instead (§30, :func:`conductor_fresnel`), from
  its complex index η + ik at cos θ = V·H: :func:`cook_torrance_conductor`, the same D, G and density.

Which lobe an object has follows its program, as the Whitted tracer's local colour
does (:data:`LOBE_CODES`): "phong" and the other OpenGL programs are Blinn-Phong (§10's
choice), the "*_phong_specular" ones Phong, "cook_torrance" Cook-Torrance.

:func:`lobe_eval` gives (f/ks, p) for a pair of directions, :func:`lobe_sample` draws one
direction (:func:`cook_torrance_conductor` is Cook-Torrance's (f/ks per channel, p) for a
conductor); the path tracer combines them with next-event estimation by multiple
importance sampling. All vectors are unit, world space, N on V's side.
"""
from __future__ import annotations

import math

from numba import njit

from softpipe.light.lighting import beckmann_d, cook_torrance, geometry_g
from softpipe.tracers.montecarlo import basis

__all__ = ["NO_LOBE", "PHONG_LOBE", "BLINN_PHONG_LOBE", "COOK_TORRANCE_LOBE", "LOBE_CODES", "LOBE_NAMES",
           "lobe_eval", "lobe_sample", "lobe_code", "conductor_fresnel", "cook_torrance_conductor"]

NO_LOBE, PHONG_LOBE, BLINN_PHONG_LOBE, COOK_TORRANCE_LOBE = 0, 1, 2, 3
#: The glossy lobe of each program (the others: Blinn-Phong, §10's lobe, with a note).
LOBE_CODES = {"phong": BLINN_PHONG_LOBE, "gouraud": BLINN_PHONG_LOBE, "flat": BLINN_PHONG_LOBE,
              "textured": BLINN_PHONG_LOBE, "two_sided": BLINN_PHONG_LOBE, "hall": BLINN_PHONG_LOBE,
              "phong_phong_specular": PHONG_LOBE, "gouraud_phong_specular": PHONG_LOBE,
              "flat_phong_specular": PHONG_LOBE, "cook_torrance": COOK_TORRANCE_LOBE}
#: The names of the lobes, by code (path stories print them).
LOBE_NAMES = ("none", "Phong", "Blinn-Phong", "Cook-Torrance")
_INV_2PI = 0.5 / math.pi


def lobe_code(program: str) -> int:
    """The glossy lobe (a ``*_LOBE`` code) an object drawn with ``program`` has in the path tracer."""
    return LOBE_CODES.get(program, BLINN_PHONG_LOBE)


@njit(cache=True, forceinline=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, forceinline=True)
def _about(axis, cos_t, phi):
    """The unit direction at angle acos(cos_t) from the unit ``axis``, turned by phi about it."""
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    x, y = sin_t * math.cos(phi), sin_t * math.sin(phi)
    t, b = basis(axis)
    return (x * t[0] + y * b[0] + cos_t * axis[0], x * t[1] + y * b[1] + cos_t * axis[1],
            x * t[2] + y * b[2] + cos_t * axis[2])


@njit(cache=True, forceinline=True)
def _mirror(V, A):
    """V mirrored about the unit A: 2(V·A)A − V."""
    c = 2.0 * _dot(V, A)
    return (c * A[0] - V[0], c * A[1] - V[1], c * A[2] - V[2])


@njit(cache=True)
def conductor_fresnel(cos_i, eta, k):
    """F_R of a conductor of complex index η + ik, seen from air: the exact, unpolarized reflectance (FORMULAS §30).

    One channel. With s² = sin²θ, a² + b² = √((η² − k² − s²)² + 4η²k²) and
    a = √(((a² + b²) + η² − k² − s²)/2):
    R_s = (a² + b² − 2a·cos θ + cos²θ)/(a² + b² + 2a·cos θ + cos²θ),
    R_p = R_s·((a² + b²)cos²θ − 2a·cos θ·s² + s⁴)/((a² + b²)cos²θ + 2a·cos θ·s² + s⁴),
    F_R = (R_s + R_p)/2: ((η − 1)² + k²)/((η + 1)² + k²) at normal incidence, 1 at grazing.
    With k = 0 it is §20's F_R from n₁ = 1 into n₂ = η (below the critical angle).
    """
    c = min(max(cos_i, 0.0), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
    a = math.sqrt(max(0.0, 0.5 * (a2b2 + t0)))
    den_s = a2b2 + 2.0 * a * c + c2
    if den_s <= 0.0:
        return 1.0
    rs = (a2b2 - 2.0 * a * c + c2) / den_s
    den_p = a2b2 * c2 + 2.0 * a * c * s2 + s2 * s2
    rp = rs if den_p <= 0.0 else rs * (a2b2 * c2 - 2.0 * a * c * s2 + s2 * s2) / den_p
    return 0.5 * (rs + rp)


@njit(cache=True)
def lobe_eval(code, N, V, L, n, m, ior):
    """(f/ks, p): the lobe's BRDF over ks toward L, and the density (solid angle) :func:`lobe_sample` draws L with.

    (0, 0) when L or V is below the surface. n the shininess, m the roughness, ior Cook-Torrance's index.
    """
    nl = _dot(N, L)
    nv = _dot(N, V)
    if nl <= 0.0 or nv <= 0.0:
        return 0.0, 0.0
    if code == PHONG_LOBE:
        c = _dot(_mirror(V, N), L)
        if c <= 0.0:
            return 0.0, 0.0
        cn = c ** n
        return (n + 2.0) * _INV_2PI * cn, (n + 1.0) * _INV_2PI * cn
    hx, hy, hz = V[0] + L[0], V[1] + L[1], V[2] + L[2]
    h = math.sqrt(hx * hx + hy * hy + hz * hz)
    if h == 0.0:
        return 0.0, 0.0
    H = (hx / h, hy / h, hz / h)
    nh = _dot(N, H)
    vh = _dot(V, H)
    if nh <= 0.0 or vh <= 0.0:
        return 0.0, 0.0
    if code == BLINN_PHONG_LOBE:
        d = (n + 1.0) * _INV_2PI * nh ** n           # the density of H
        return d / (4.0 * vh * max(nl, nv)), d / (4.0 * vh)
    if code == COOK_TORRANCE_LOBE:
        return cook_torrance(N, L, V, m, 1.0, ior), beckmann_d(nh, m) * nh / (4.0 * vh)
    return 0.0, 0.0


@njit(cache=True)
def cook_torrance_conductor(N, V, L, m, eta_r, eta_g, eta_b, k_r, k_g, k_b):
    """(f_R, f_G, f_B, p): Cook-Torrance (§26) over ks for a conductor, F its exact one per channel (§30).

    f_c = D·G·F_c/(4 (N·L)(N·V)), F_c = :func:`conductor_fresnel` (V·H, η_c, k_c): the
    metal's colour comes from F, as its mirror lobe's does. D, G and the density p are
    :func:`lobe_eval`'s for ``COOK_TORRANCE_LOBE`` (the same H, to the last bit), so the
    lobe is drawn by :func:`lobe_sample` as the dielectric one is. (0, 0, 0, 0) when L or
    V is below the surface.
    """
    nl = _dot(N, L)
    nv = _dot(N, V)
    if nl <= 0.0 or nv <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    hx, hy, hz = V[0] + L[0], V[1] + L[1], V[2] + L[2]
    h = math.sqrt(hx * hx + hy * hy + hz * hz)
    if h == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    H = (hx / h, hy / h, hz / h)
    nh = _dot(N, H)
    vh = _dot(V, H)
    if nh <= 0.0 or vh <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    d = beckmann_d(nh, m)
    denominator = 4.0 * nl * nv
    if denominator == 0.0:                           # the product underflowed at a grazing angle
        return 0.0, 0.0, 0.0, d * nh / (4.0 * vh)
    base = d * geometry_g(nh, nv, nl, vh) / denominator
    return (base * conductor_fresnel(vh, eta_r, k_r), base * conductor_fresnel(vh, eta_g, k_g),
            base * conductor_fresnel(vh, eta_b, k_b), d * nh / (4.0 * vh))


@njit(cache=True)
def lobe_sample(code, N, V, n, m, u1, u2):
    """A direction L drawn from the lobe's density (:func:`lobe_eval`'s p), from two uniform numbers.

    It may lie below the surface (then f = 0 there and the path ends).
    """
    phi = 2.0 * math.pi * u2
    if code == PHONG_LOBE:
        return _about(_mirror(V, N), (1.0 - u1) ** (1.0 / (n + 1.0)), phi)      # 1 − u1 in (0, 1]
    if code == BLINN_PHONG_LOBE:
        cos_h = (1.0 - u1) ** (1.0 / (n + 1.0))
    else:                                            # Beckmann: tan²α = −m² ln(1 − u1)
        tan2 = -m * m * math.log(1.0 - u1)
        cos_h = 1.0 / math.sqrt(1.0 + tan2)
    return _mirror(V, _about(N, cos_h, phi))
