"""The lighting equations of the notes (docs/formulas.md, cited FORMULAS §n), as numba functions on tuples.

One implementation shared by every built-in program: a Gouraud shader calls
these per vertex, a Phong shader per fragment, and a user's shader may call them
too. Each function is ``@njit(cache=True)``; under ``NUMBA_DISABLE_JIT=1`` (or via
``.py_func``) it is the same code as plain Python, with bit-identical results.

Names: P, N, L, V, H, R, H′, B, (x)₊, ke, ka, kd, ks, kt, n, n′, I_a, I_d, I_s,
f_att, f_spot, η and m are the notes', defined once in :mod:`softpipe.shading`
(the module a shader author imports from; it re-exports every function here).
All vectors are in eye space and of unit length unless said.

Colors are RGB 3-tuples multiplied per channel. Lights arrive packed in eye
space, one row per light (``softpipe.light.material.pack_lights``; columns :mod:`softpipe.light.packed`),
in the ``lighting`` uniform (a :class:`~softpipe.light.material.LightingUniform`: the
global ambient, the packed lights and their shadow maps). The sums over lights
(:func:`opengl_lighting`, :func:`hall_local`, :func:`two_sided_lighting`,
:func:`cook_torrance_lighting`) are one loop, :func:`sum_over_lights`, to which each model
gives its own part for one light (``opengl_light``, …); it multiplies light j's diffuse
and specular terms by its visibility V_j
(:func:`~softpipe.light.shadowmap.light_visibility`; FORMULAS §11 and §21): 1 without shadows, 0 in a
shadow, a color behind glass. Ambient terms are not shadowed (§10).

Conventions
-----------
* Results are not clamped. OpenGL clamps a lit color to [0, 1]; here the output
  merger clamps once, at conversion to 8 bits, so a Gouraud shader that wants
  OpenGL's look should ``saturate`` the color before it is interpolated.
* 0⁰ = 1: with shininess n = 0 (the notes' "planet") the specular lobe (N·H)₊⁰
  or (R·V)₊⁰ is 1 wherever B = 1, including where the dot product clamps to 0;
  where B = 0 there is no specular term at all. The planet material has ks = 0,
  so nothing shows.
* No NaN from geometry: zero vectors normalize to zero (a light exactly at P,
  L = −V, …), every division is guarded, and ``pow`` only sees bases ≥ 0.
"""
from __future__ import annotations

import math
from typing import Tuple

import numpy as np
from numba import njit

from softpipe.language.glsl import add, dot, length, mul, normalize, pow_, reflect, refract, scale, sub
from softpipe.light.material import LightingUniform, MaterialUniform
from softpipe.light.packed import (
    LIGHT_AMBIENT,
    LIGHT_ATTENUATION,
    LIGHT_DIFFUSE,
    LIGHT_DIRECTIONAL,
    LIGHT_KIND,
    LIGHT_POSITION,
    LIGHT_SPECULAR,
    LIGHT_SPOT_COS_CUTOFF,
    LIGHT_SPOT_DIRECTION,
    LIGHT_SPOT_EXPONENT,
    light_vec3,
)
from softpipe.light.shadowmap import casts_shadows, light_visibility

Vec3 = Tuple[float, float, float]
Color = Tuple[float, float, float]

__all__ = [
    "BLINN_PHONG", "PHONG",
    "positive_power", "b_factor", "half_vector",
    "emission", "ambient", "lambert", "phong_specular", "blinn_phong_specular",
    "attenuation", "spot_factor", "light_at", "light_colors",
    "sum_over_lights", "opengl_light", "hall_light", "two_sided_light", "cook_torrance_light",
    "opengl_lighting",
    "transmitted_half_vector", "hall_transmission", "hall_local", "fresnel_directions",
    "two_sided_lighting",
    "fresnel_rs_rp", "fresnel", "fresnel_schlick",
    "beckmann_d", "geometry_g", "cook_torrance", "cook_torrance_lighting",
    "gooch",
]

BLINN_PHONG = 0  # specular_model: (N·H)₊ⁿ, §6 (OpenGL's choice, §10)
PHONG = 1        # specular_model: (R·V)₊ⁿ, §5

ZERO3 = (0.0, 0.0, 0.0)

# f_att's denominator a + b·r + c·r² is 0 only for a = 0 at r = 0 (a light exactly
# on the surface); it is floored here so that f_att stays finite.
MIN_ATTENUATION_DENOMINATOR = 1e-12


# --------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------

@njit(cache=True, forceinline=True)
def positive_power(x: float, n: float) -> float:
    """(x)₊ⁿ with 0⁰ = 1: the specular lobe's power (§5, §6).

    It is :func:`~softpipe.language.glsl.pow_`: for a whole n in 1..MAX_SQUARING_EXPONENT
    and x > 0 by repeated squaring (at most 2·log₂ n products; within about (n − 1) ulp of
    xⁿ: a third of a lit sample's time less than C's pow, issue 18); otherwise C's pow.
    """
    return pow_(x, n)


@njit(cache=True)
def b_factor(N: Vec3, L: Vec3) -> float:
    """B = 1 if N·L > 0 else 0 (FORMULAS §4)."""
    return 1.0 if dot(N, L) > 0.0 else 0.0


@njit(cache=True)
def half_vector(L: Vec3, V: Vec3) -> Vec3:
    """H = (L + V)/|L + V| (FORMULAS notation); the zero vector when L = −V."""
    return normalize(add(L, V))


# --------------------------------------------------------------------------
# The OpenGL / Blinn-Phong family (§1–§10)
# --------------------------------------------------------------------------

@njit(cache=True)
def emission(ke: Color) -> Color:
    """I = ke (FORMULAS §1)."""
    return (ke[0], ke[1], ke[2])


@njit(cache=True)
def ambient(ka: Color, Ia: Color) -> Color:
    """I = ka · I_a (FORMULAS §2)."""
    return mul(ka, Ia)


@njit(cache=True)
def lambert(kd: Color, Id: Color, N: Vec3, L: Vec3) -> Color:
    """I = kd · I_d · B · (N·L) (FORMULAS §3, with B of §4)."""
    n_dot_l = dot(N, L)
    if n_dot_l <= 0.0:  # B = 0: the light is below the surface
        return ZERO3
    return scale(mul(kd, Id), n_dot_l)


@njit(cache=True)
def phong_specular(ks: Color, Is: Color, N: Vec3, L: Vec3, V: Vec3, n: float) -> Color:
    """I = ks · I_s · B · (R·V)₊ⁿ, R = 2(N·L)N − L (FORMULAS §5)."""
    n_dot_l = dot(N, L)
    if n_dot_l <= 0.0:  # B = 0
        return ZERO3
    R = sub(scale(N, 2.0 * n_dot_l), L)
    return scale(mul(ks, Is), positive_power(dot(R, V), n))


@njit(cache=True)
def blinn_phong_specular(ks: Color, Is: Color, N: Vec3, L: Vec3, V: Vec3, n: float) -> Color:
    """I = ks · I_s · B · (N·H)₊ⁿ, H = normalize(L + V) (FORMULAS §6)."""
    if dot(N, L) <= 0.0:  # B = 0
        return ZERO3
    # N·H as N·(L + V) / |L + V|: one division, not normalize's three (H itself is not needed)
    S = add(L, V)
    norm = length(S)
    n_dot_h = dot(N, S) / norm if norm > 0.0 else 0.0     # L = −V: H is the zero vector
    return scale(mul(ks, Is), positive_power(n_dot_h, n))


@njit(cache=True)
def attenuation(a: float, b: float, c: float, r: float) -> float:
    """f_att = 1/(a + b·r + c·r²) at distance r (FORMULAS §7); finite even for a = r = 0."""
    d = a + b * r + c * r * r
    if d < MIN_ATTENUATION_DENOMINATOR:
        d = MIN_ATTENUATION_DENOMINATOR
    return 1.0 / d


@njit(cache=True)
def spot_factor(L: Vec3, S: Vec3, cos_cutoff: float, e: float) -> float:
    """f_spot = (−L·S)ᵉ if −L·S ≥ cos β, else 0 (FORMULAS §8).

    ``cos_cutoff`` = cos β ≤ −1 (β = 180°) means "not a spotlight": f_spot = 1.
    Inside the cone −L·S ≥ cos β ≥ 0 (β ≤ 90°), so the power has a base ≥ 0.
    """
    if cos_cutoff <= -1.0:
        return 1.0
    cos_angle = -dot(L, S)
    if cos_angle < cos_cutoff:
        return 0.0
    return positive_power(cos_angle, e)


@njit(cache=True, forceinline=True)
def light_colors(lights: np.ndarray, j: int) -> Tuple[Color, Color, Color]:
    """Light j's ambient, diffuse and specular colors (I_a,j, I_d,j, I_s,j)."""
    return (light_vec3(lights, j, LIGHT_AMBIENT), light_vec3(lights, j, LIGHT_DIFFUSE),
            light_vec3(lights, j, LIGHT_SPECULAR))


@njit(cache=True, forceinline=True)
def light_at(P: Vec3, lights: np.ndarray, j: int) -> Tuple[Vec3, float]:
    """(L, f_att · f_spot) for packed light j at the eye-space point P (FORMULAS §7–§9).

    A directional light stores L itself (w = 0) and has f_att = f_spot = 1.
    """
    position = light_vec3(lights, j, LIGHT_POSITION)  # for a directional light: L itself
    if lights[j, LIGHT_KIND] == LIGHT_DIRECTIONAL:
        return position, 1.0
    to_light = sub(position, P)
    r = length(to_light)
    L = scale(to_light, 1.0 / r) if r > 0.0 else ZERO3     # normalize(to_light), one division for three
    f_att = attenuation(lights[j, LIGHT_ATTENUATION], lights[j, LIGHT_ATTENUATION + 1],
                        lights[j, LIGHT_ATTENUATION + 2], r)
    f_spot = spot_factor(L, light_vec3(lights, j, LIGHT_SPOT_DIRECTION),
                         lights[j, LIGHT_SPOT_COS_CUTOFF], lights[j, LIGHT_SPOT_EXPONENT])
    return L, f_att * f_spot


@njit(cache=True, forceinline=True)
def sum_over_lights(light_terms, P: Vec3, N: Vec3, V: Vec3, material: MaterialUniform, lighting: LightingUniform,
                    color: Color, option) -> Color:
    """``color`` + Σ_j f_j · (ambient_j + V_j · direct_j): every lit model's sum over lights, once.

    ``light_terms(P, N, V, material, lights, j, option)`` is a model's own part: it returns
    light j's weight f_j, its ambient term, its direct terms and whether light reaches the
    surface at all (B_j = 1; only then is there light to shadow). The sum multiplies the
    direct terms by light j's visibility V_j when the light casts shadows
    (:func:`~softpipe.light.shadowmap.light_visibility`, FORMULAS §11, §21); the ambient
    term is never shadowed (§10). ``option`` is the model's parameter (§10's specular
    model, §13's η). The models pass their part as a function: numba compiles one loop per
    model with the part inlined, and each model keeps the order of its arithmetic, so the
    sum gives the same bytes a loop of the model's own would.
    """
    lights = lighting.lights
    for j in range(lights.shape[0]):
        f, ambient_j, direct, reached = light_terms(P, N, V, material, lights, j, option)
        if reached and casts_shadows(lighting, j):
            direct = mul(direct, light_visibility(lighting, j, P))
        color = add(color, scale(add(ambient_j, direct), f))
    return color


@njit(cache=True, forceinline=True)
def opengl_lighting(P: Vec3, N: Vec3, V: Vec3, material: MaterialUniform, lighting: LightingUniform,
                    specular_model: int) -> Color:
    """The OpenGL lighting equation, summed over all lights (FORMULAS §10), with shadows.

    I = ke + ka·I_a,global
        + Σ_j f_att,j · f_spot,j · [ ka·I_a,j + V_j·B_j·( kd·I_d,j·(N·L_j) + ks·I_s,j·spec_j ) ]

    with spec_j = (N·H_j)₊ⁿ for ``specular_model`` = BLINN_PHONG (0, OpenGL's) or
    (R_j·V)₊ⁿ for PHONG (1), and V_j light j's visibility at P
    (:func:`~softpipe.light.shadowmap.light_visibility`, FORMULAS §11/§21; 1 without shadows).

    Parameters
    ----------
    P, N, V
        Eye-space point, unit normal (on the viewer's side) and unit vector to the eye.
    material
        A :class:`~softpipe.light.material.MaterialUniform`.
    lighting
        The ``lighting`` uniform: ``global_ambient`` (I_a,global), ``lights`` (packed
        in eye space, [num_lights, LIGHT_COLUMNS]) and ``shadows``.
    specular_model
        BLINN_PHONG or PHONG.
    """
    m = material
    color = add(emission(m.ke), ambient(m.ka, lighting.global_ambient))
    return sum_over_lights(opengl_light, P, N, V, m, lighting, color, specular_model)


@njit(cache=True, forceinline=True)
def opengl_light(P: Vec3, N: Vec3, V: Vec3, m: MaterialUniform, lights: np.ndarray, j: int,
                 specular_model: int) -> Tuple[float, Color, Color, bool]:
    """Light j's part of §10 (for :func:`sum_over_lights`): f_j, ka·I_a,j, and where B_j = 1
    kd·I_d,j·(N·L_j) + ks·I_s,j·spec_j."""
    L, f = light_at(P, lights, j)
    Ia, Id, Is = light_colors(lights, j)
    if not (f > 0.0 and dot(N, L) > 0.0):
        return f, ambient(m.ka, Ia), ZERO3, False
    if specular_model == PHONG:
        specular = phong_specular(m.ks, Is, N, L, V, m.shininess)
    else:
        specular = blinn_phong_specular(m.ks, Is, N, L, V, m.shininess)
    return f, ambient(m.ka, Ia), add(lambert(m.kd, Id, N, L), specular), True


# --------------------------------------------------------------------------
# Hall (§13, §14): the local terms
# --------------------------------------------------------------------------

@njit(cache=True)
def transmitted_half_vector(L: Vec3, V: Vec3, eta: float) -> Vec3:
    """H′ = normalize((V + η·L)/(η − 1)) (FORMULAS §14), L toward the light.

    η = η₂/η₁ with the view ray passing from medium η₁ (the viewer's side) into
    η₂ (the far side, where the transmitted light comes from); for a viewer in
    air and a glass surface η = 1.5; for a viewer inside the glass (a back face) η = 1/1.5.
    H′ is the normal of the microfacet that
    refracts the light's ray (direction −L) into V, by Snell's law (§17): it
    satisfies η₂·(−L)_tangential = η₁·V_tangential. It points to the light's side,
    so the lobe is (−N·H′)₊ⁿ′. Such a facet exists only when the ray really
    crosses it, (L·H′)(V·H′) < 0 — refraction bends a ray by at most 90° − θ_c;
    :func:`hall_transmission` checks that.

    This is FORMULAS §14 as corrected: the notes' H′ = (V − η·L)/(η − 1) holds for L
    the direction the light *travels*; with L toward the light, as everywhere in
    FORMULAS, it is (V + η·L)/(η − 1), and light straight through the surface (L = −N,
    V = N) gets the full lobe (−N·H′) = 1, where the literal form gives 0
    (``tests/test_lighting.py::test_transmitted_half_vector_is_formulas_14_as_corrected``).
    η = 1 (no refraction) gives the zero vector.
    """
    if eta == 1.0:
        return ZERO3
    return normalize(scale(add(V, scale(L, eta)), 1.0 / (eta - 1.0)))


@njit(cache=True)
def hall_transmission(kt: Color, Is: Color, N: Vec3, L: Vec3, V: Vec3, eta: float, n_t: float) -> Color:
    """Hall's specular transmission of a light: kt · I_s · (−N·H′)₊ⁿ′ (FORMULAS §13, §14).

    Only for a light behind the surface (N·L < 0), the counterpart of B; none when
    η = 1, and none when no facet can refract the light into V (the ray would have
    to be bent further than Snell's law allows: (L·H′)(V·H′) ≥ 0).
    """
    if dot(N, L) >= 0.0 or eta == 1.0:
        return ZERO3
    Ht = transmitted_half_vector(L, V, eta)
    if dot(L, Ht) * dot(V, Ht) >= 0.0:
        return ZERO3
    return scale(mul(kt, Is), positive_power(-dot(N, Ht), n_t))


@njit(cache=True)
def hall_local(P: Vec3, N: Vec3, V: Vec3, material: MaterialUniform, lighting: LightingUniform,
               eta: float) -> Color:
    """The local terms of the Hall model (FORMULAS §13), summed over all lights, with shadows.

    I = ka·I_a
        + Σ_j f_j·[ ka·I_a,j + V_j·( ks·I_s,j·B_j·(N·H_j)₊ⁿ      (specular reflection of lights)
                                   + kt·I_s,j·B′_j·(−N·H′_j)₊ⁿ′  (specular transmission, §14)
                                   + kd·I_d,j·B_j·(N·L_j) ) ]    (diffuse)

    The material's RGB ks, kt, kd, ka are Hall's products k_s·F_s, k_t·F_t,
    k_d·F_d and k_a·F_d (a coefficient times a color). I_a is the global ambient
    plus each light's ambient (times f_j), as in §10; f_j = f_att·f_spot; B′_j = 1
    for a light behind the surface (N·L_j < 0). η is as in
    :func:`transmitted_half_vector`, (far side)/(viewer's side): ``material.ior`` for a
    viewer in air (a front face), 1/``material.ior`` for a viewer inside the object (a
    back face, N flipped toward the viewer) — the caller knows which (FORMULAS §14); n′ is
    ``material.transmission_shininess``; V_j is light j's visibility
    (:func:`~softpipe.light.shadowmap.light_visibility`). The reflected and transmitted rays
    (k_r, k_t terms with T^d) belong to a ray tracer and are not included here:
    :func:`softpipe.tracers.whitted.raytrace_scene` adds them, k_r·I_r·T_r^{d_r} and
    k_t·I_t·T_t^{d_t} with I_r, I_t from the reflected and refracted rays and the
    falloff of :func:`softpipe.rays.queries.medium_falloff`.
    """
    color = ambient(material.ka, lighting.global_ambient)
    return sum_over_lights(hall_light, P, N, V, material, lighting, color, eta)


@njit(cache=True, forceinline=True)
def hall_light(P: Vec3, N: Vec3, V: Vec3, m: MaterialUniform, lights: np.ndarray, j: int,
               eta: float) -> Tuple[float, Color, Color, bool]:
    """Light j's part of §13 (for :func:`sum_over_lights`): f_j, ka·I_a,j, and the reflected
    and transmitted terms (each with its own B_j or B′_j) where f_j > 0."""
    L, f = light_at(P, lights, j)
    Ia, Id, Is = light_colors(lights, j)
    if not f > 0.0:
        return f, ambient(m.ka, Ia), ZERO3, False
    reflected = add(blinn_phong_specular(m.ks, Is, N, L, V, m.shininess), lambert(m.kd, Id, N, L))
    transmitted = hall_transmission(m.kt, Is, N, L, V, eta, m.transmission_shininess)
    return f, ambient(m.ka, Ia), add(reflected, transmitted), True


# --------------------------------------------------------------------------
# The ray-tracing course's two-sided form (§11)
# --------------------------------------------------------------------------

@njit(cache=True)
def two_sided_lighting(P: Vec3, N: Vec3, V: Vec3, material: MaterialUniform, lighting: LightingUniform) -> Color:
    """The direct light of FORMULAS §11, the ray-tracing course's two-sided form, summed over all lights.

    c = ρ_d·L_a + Σ_i (ρ_d + ρ_s(N·H_i)) · L_i · V_i(p) · |N·L_i|,   ρ_s(N·H) = k_s·(N·H)₊ⁿ

    with ρ_d = ``kd``, k_s = ``ks``, n = ``shininess``, L_a the global ambient light,
    H_i = normalize(L_i + V) and V_i light i's visibility (:func:`~softpipe.light.shadowmap.light_visibility`:
    shadow maps or shadow rays). L_i is light i's response at P: its diffuse color
    k_l (``I_d``) divided by r² for a point light, r the distance to it (§11's
    L_i = k_l/r², not §7's coefficients), times f_spot for a spot (§8); k_l for a
    directional light. The §11 terms k_r·trace(p, R) + k_t·trace(p, T) are the ray
    tracer's (:func:`softpipe.tracers.whitted.raytrace_scene`), not this function's.

    **note** (FORMULAS §11): |N·L_i|, so a light *behind* the surface lights it as
    much as one in front (two-sided: no B factor), and the cosine multiplies the
    specular lobe too; §10 (:func:`opengl_lighting`) does neither. There is no
    emission k_e and no k_a in §11: the ambient term is ρ_d·L_a.
    """
    color = mul(material.kd, lighting.global_ambient)
    return sum_over_lights(two_sided_light, P, N, V, material, lighting, color, 0.0)


@njit(cache=True, forceinline=True)
def two_sided_light(P: Vec3, N: Vec3, V: Vec3, m: MaterialUniform, lights: np.ndarray, i: int,
                    unused: float) -> Tuple[float, Color, Color, bool]:
    """Light i's part of §11 (for :func:`sum_over_lights`): (ρ_d + ρ_s(N·H_i))·L_i·|N·L_i|,
    with weight 1 and no ambient term of its own (L_i holds the falloff)."""
    position = light_vec3(lights, i, LIGHT_POSITION)
    if lights[i, LIGHT_KIND] == LIGHT_DIRECTIONAL:
        L, response = position, 1.0
    else:
        to_light = sub(position, P)
        r2 = dot(to_light, to_light)
        L = normalize(to_light)
        response = 1.0 / r2 if r2 > MIN_ATTENUATION_DENOMINATOR else 1.0 / MIN_ATTENUATION_DENOMINATOR
        response *= spot_factor(L, light_vec3(lights, i, LIGHT_SPOT_DIRECTION),
                                lights[i, LIGHT_SPOT_COS_CUTOFF], lights[i, LIGHT_SPOT_EXPONENT])
    cos_l = abs(dot(N, L))
    if response <= 0.0 or cos_l == 0.0:
        return 1.0, ZERO3, ZERO3, False
    H = half_vector(L, V)
    rho = add(m.kd, scale(m.ks, positive_power(dot(N, H), m.shininess)))   # ρ_d + ρ_s(N·H)
    return 1.0, ZERO3, scale(mul(rho, light_vec3(lights, i, LIGHT_DIFFUSE)), response * cos_l), True


# --------------------------------------------------------------------------
# Fresnel (§20)
# --------------------------------------------------------------------------

@njit(cache=True)
def fresnel_rs_rp(cos_i: float, n1: float, n2: float) -> Tuple[float, float]:
    """(R_s, R_p), the reflectances for s- and p-polarized light (FORMULAS §20).

    Light in medium n1 meets medium n2 at incidence angle θ₁, cos θ₁ = ``cos_i``
    (its sign is ignored). Beyond the critical angle (§19) both are 1.
    """
    c1 = min(abs(cos_i), 1.0)
    sin2_t = (n1 / n2) ** 2 * (1.0 - c1 * c1)  # Snell (§17): sin θ₂ = (n1/n2) sin θ₁
    if sin2_t >= 1.0:
        return 1.0, 1.0
    c2 = math.sqrt(1.0 - sin2_t)
    # Both denominators are > 0 here: they vanish only when c1 = c2 = 0, i.e. sin2_t = 1.
    rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)
    rp = (n1 * c2 - n2 * c1) / (n1 * c2 + n2 * c1)
    return rs * rs, rp * rp


@njit(cache=True)
def fresnel(cos_i: float, n1: float, n2: float) -> float:
    """F_R = (R_s + R_p)/2, the exact Fresnel reflectance of unpolarized light (FORMULAS §20).

    F_T = 1 − F_R. ((n1 − n2)/(n1 + n2))² at normal incidence (0.04 for glass in
    air), 1 beyond the critical angle.
    """
    rs, rp = fresnel_rs_rp(cos_i, n1, n2)
    return 0.5 * (rs + rp)


@njit(cache=True)
def fresnel_schlick(cos_i: float, n1: float, n2: float) -> float:
    """Schlick's *approximation* of F_R: R₀ + (1 − R₀)(1 − cos θ)⁵, R₀ = ((n1 − n2)/(n1 + n2))².

    Labelled an approximation (FORMULAS §20 allows it). Going into a less dense
    medium (n1 > n2) it uses the transmitted angle's cosine, and is 1 beyond the
    critical angle, as the exact form.
    """
    r0 = ((n1 - n2) / (n1 + n2)) ** 2
    c = min(abs(cos_i), 1.0)
    if n1 > n2:
        sin2_t = (n1 / n2) ** 2 * (1.0 - c * c)
        if sin2_t >= 1.0:
            return 1.0
        c = math.sqrt(1.0 - sin2_t)
    return r0 + (1.0 - r0) * (1.0 - c) ** 5


@njit(cache=True)
def fresnel_directions(N: Vec3, V: Vec3, n1: float, n2: float) -> Tuple[Vec3, Vec3, float]:
    """(R, T, F_R) at a surface between media n1 (V's side) and n2: where light goes, and how much of it reflects.

    R = 2(N·V)N − V (§16); T the refracted direction (§18, η = n1/n2), the zero
    vector on total internal reflection (§19), when F_R = 1 (all of it reflected);
    F_R the exact Fresnel reflectance at cos θ₁ = N·V (§20), so 1 − F_R goes to T.
    N and V unit, N on V's side.
    """
    R = reflect(scale(V, -1.0), N)
    eta = n1 / n2
    T = refract(scale(V, -1.0), N, eta)
    c1 = dot(N, V)
    if eta * eta * (1.0 - c1 * c1) > 1.0:          # §19: total internal reflection
        return R, T, 1.0
    return R, T, fresnel(c1, n1, n2)


# --------------------------------------------------------------------------
# Cook-Torrance and Gooch (§26)
# --------------------------------------------------------------------------

@njit(cache=True)
def beckmann_d(n_dot_h: float, m: float) -> float:
    """Beckmann's D = exp(−tan²α/m²)/(π m² cos⁴α), cos α = N·H (FORMULAS §26); 0 for N·H ≤ 0.

    This D is normalized: ∫ D cos α dω = 1 over the hemisphere.
    """
    c2 = n_dot_h * n_dot_h
    if n_dot_h <= 0.0 or c2 == 0.0:  # c2 underflows for N·H < 1e-154
        return 0.0
    tan2 = (1.0 - c2) / c2
    e = math.exp(-tan2 / (m * m))
    denominator = math.pi * m * m * c2 * c2
    if e == 0.0 or denominator == 0.0:  # far out in the tail: D = 0, never 0/0
        return 0.0
    return e / denominator


@njit(cache=True)
def geometry_g(n_dot_h: float, n_dot_v: float, n_dot_l: float, v_dot_h: float) -> float:
    """G = min(1, 2(N·H)(N·V)/(V·H), 2(N·H)(N·L)/(V·H)) (FORMULAS §26); 0 if V·H ≤ 0."""
    if v_dot_h <= 0.0:  # only when L = −V: no reflection toward V
        return 0.0
    return min(1.0, 2.0 * n_dot_h * n_dot_v / v_dot_h, 2.0 * n_dot_h * n_dot_l / v_dot_h)


@njit(cache=True)
def cook_torrance(N: Vec3, L: Vec3, V: Vec3, m: float, n1: float, n2: float) -> float:
    """The Cook-Torrance specular BRDF in the normalized microfacet form f_s = D·G·F / (4 (N·L)(N·V)) (FORMULAS §26).

    The form used, stated: FORMULAS §26's normalized one, with Beckmann's D that
    integrates to 1 over the projected hemisphere (its own 1/π, :func:`beckmann_d`),
    G as given (:func:`geometry_g`), and F the exact Fresnel reflectance (§20) at
    cos θ = V·H from medium n1 (the viewer's) into n2 (the surface).

    **note:** the 1982 paper writes R_s = F·D′·G / (π (N·L)(N·V)) with D′ = π·D (a
    Beckmann D without the 1/π), so R_s = F·D·G / ((N·L)(N·V)) = 4·f_s. At the point of
    ``tests/test_lighting.py::test_cook_torrance_value`` (m = 0.35, glass): the
    paper's R_s = 0.2027, this f_s = 0.0507; softpipe's earlier form — the paper's π
    with the normalized D, dividing by π twice — gave 0.0645.
    0 when L or V is below the surface.
    """
    n_dot_l = dot(N, L)
    n_dot_v = dot(N, V)
    if n_dot_l <= 0.0 or n_dot_v <= 0.0:
        return 0.0
    H = half_vector(L, V)
    n_dot_h = dot(N, H)
    v_dot_h = dot(V, H)
    D = beckmann_d(n_dot_h, m)
    G = geometry_g(n_dot_h, n_dot_v, n_dot_l, v_dot_h)
    F = fresnel(v_dot_h, n1, n2)
    denominator = 4.0 * n_dot_l * n_dot_v
    if denominator == 0.0:  # the product underflowed at a grazing angle
        return 0.0
    return D * G * F / denominator


@njit(cache=True)
def cook_torrance_lighting(P: Vec3, N: Vec3, V: Vec3, material: MaterialUniform,
                           lighting: LightingUniform) -> Color:
    """§10 with Cook-Torrance in place of the Phong lobe, summed over all lights, with shadows.

    I = ke + ka·I_a,global
        + Σ_j f_j·[ ka·I_a,j + V_j·B_j·(N·L_j)·( kd·I_d,j + ks·I_s,j·f_s,j ) ]

    f_s from :func:`cook_torrance` with m = ``material.roughness``, F from air
    (n1 = 1) into ``material.ior``: a material with ior = 1 has no specular term.
    The diffuse term is §3's (no 1/π), so switching from §10 keeps its brightness.
    """
    color = add(emission(material.ke), ambient(material.ka, lighting.global_ambient))
    return sum_over_lights(cook_torrance_light, P, N, V, material, lighting, color, 0.0)


@njit(cache=True, forceinline=True)
def cook_torrance_light(P: Vec3, N: Vec3, V: Vec3, m: MaterialUniform, lights: np.ndarray, j: int,
                        unused: float) -> Tuple[float, Color, Color, bool]:
    """Light j's part of §10 with Cook-Torrance (for :func:`sum_over_lights`): f_j, ka·I_a,j,
    and where B_j = 1 (N·L_j)·(kd·I_d,j + ks·I_s,j·f_s,j)."""
    L, f = light_at(P, lights, j)
    Ia, Id, Is = light_colors(lights, j)
    n_dot_l = dot(N, L)
    if not (f > 0.0 and n_dot_l > 0.0):
        return f, ambient(m.ka, Ia), ZERO3, False
    f_s = cook_torrance(N, L, V, m.roughness, 1.0, m.ior)
    lit = add(mul(m.kd, Id), scale(mul(m.ks, Is), f_s))
    return f, ambient(m.ka, Ia), scale(lit, n_dot_l), True


@njit(cache=True)
def gooch(N: Vec3, L: Vec3, kd: Color, k_blue: Color, k_yellow: Color, alpha: float, beta: float) -> Color:
    """Gooch's cool-to-warm shading (FORMULAS §26).

    k_cool = k_blue + α·kd, k_warm = k_yellow + β·kd, t = (1 + N·L)/2,
    I = t·k_warm + (1 − t)·k_cool: warm where N faces the light, cool away from it.
    The paper's values: k_blue = (0, 0, 0.4), k_yellow = (0.4, 0.4, 0), α = 0.2, β = 0.6.
    """
    k_cool = add(k_blue, scale(kd, alpha))
    k_warm = add(k_yellow, scale(kd, beta))
    t = (1.0 + dot(N, L)) / 2.0
    return add(scale(k_warm, t), scale(k_cool, 1.0 - t))
