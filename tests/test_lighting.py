"""The lighting equations (FORMULAS §1–§10, §13, §14, §20, §26) against the formulas.

Every expected value is evaluated here, independently, with numpy/math — never by
calling softpipe.light.lighting to make it.
"""
import math
import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from conftest import tilt, unit

from softpipe.light.lighting import (
    BLINN_PHONG,
    PHONG,
    ambient,
    attenuation,
    b_factor,
    beckmann_d,
    blinn_phong_specular,
    cook_torrance,
    cook_torrance_lighting,
    emission,
    fresnel,
    fresnel_rs_rp,
    fresnel_schlick,
    geometry_g,
    gooch,
    hall_local,
    hall_transmission,
    lambert,
    opengl_lighting,
    phong_specular,
    spot_factor,
    transmitted_half_vector,
)
from softpipe.light.material import Light, Lighting, LightingUniform, Material, pack_lights
from softpipe.light.shadowmap import no_shadows

N_UP = (0.0, 0.0, 1.0)
NO_LIGHTS = np.zeros((0, 22))
BLACK = (0.0, 0.0, 0.0)
KS, IS = (0.5, 0.6, 0.7), (1.0, 0.9, 0.8)
KD, ID = (0.8, 0.4, 0.2), (0.9, 1.0, 0.7)


def uniform(**kw):
    return Material(**kw).__softpipe_uniform__()


def lit(global_ambient, lights):
    """The lighting uniform of packed ``lights`` without shadow maps."""
    lights = np.asarray(lights, dtype=np.float64)
    return LightingUniform(tuple(global_ambient), lights, no_shadows(len(lights)))


def close(got, expected, rel=1e-12, abs_=1e-14):
    np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(expected, dtype=float),
                               rtol=rel, atol=abs_)


# --- §1, §2: emission and ambient ----------------------------------------

def test_emission_only():
    ke = (0.3, 0.1, 0.2)
    assert emission(ke) == ke
    lights = pack_lights([Light.point((0, 0, 2), ambient=1.0)], np.eye(4))
    m = uniform(ke=ke, ka=0, kd=0, ks=0)
    close(opengl_lighting((0.0, 0.0, 0.0), N_UP, N_UP, m, lit((0.5, 0.5, 0.5), lights), BLINN_PHONG), ke)


def test_ambient_only():
    ka, ia = (0.2, 0.4, 0.6), (0.5, 0.5, 0.25)
    close(ambient(ka, ia), np.multiply(ka, ia))
    m = uniform(ke=0, ka=ka, kd=0, ks=0)
    close(opengl_lighting((0.0, 0.0, 0.0), N_UP, N_UP, m, lit(ia, NO_LIGHTS), BLINN_PHONG), np.multiply(ka, ia))


def test_each_lights_ambient_is_attenuated_but_not_cut_by_b():
    # A light *below* the surface (B = 0) still adds f_att·ka·I_a,j (§10: the ambient term is outside B).
    ka, ga, ia = (0.2, 0.4, 0.6), (0.1, 0.1, 0.1), (0.3, 0.2, 0.1)
    a, b, c, r = 1.0, 0.5, 0.25, 3.0
    lights = pack_lights([Light.point((0, 0, -r), ambient=ia, attenuation=(a, b, c))], np.eye(4))
    m = uniform(ke=0, ka=ka, kd=0.9, ks=0.9)
    expected = np.multiply(ka, ga) + np.multiply(ka, ia) / (a + b * r + c * r * r)
    close(opengl_lighting((0.0, 0.0, 0.0), N_UP, N_UP, m, lit(ga, lights), BLINN_PHONG), expected)


# --- §3, §4: Lambert and B -------------------------------------------------

@pytest.mark.parametrize("theta", [0.0, 30.0, 60.0, 89.0])
def test_lambert_at_angles(theta):
    L = tilt(theta, 40.0)
    close(lambert(KD, ID, N_UP, L), np.multiply(KD, ID) * math.cos(math.radians(theta)))
    assert b_factor(N_UP, L) == 1.0


@pytest.mark.parametrize("theta", [90.0, 91.0, 120.0, 180.0])
def test_b_cuts_off_light_from_below(theta):
    L = tilt(theta, 10.0)
    if theta == 90.0:
        L = (1.0, 0.0, 0.0)  # exactly in the tangent plane: N·L = 0
    V = tilt(30.0, 190.0)
    assert b_factor(N_UP, L) == 0.0
    assert lambert(KD, ID, N_UP, L) == BLACK
    assert phong_specular(KS, IS, N_UP, L, V, 10.0) == BLACK
    assert blinn_phong_specular(KS, IS, N_UP, L, V, 10.0) == BLACK
    assert blinn_phong_specular(KS, IS, N_UP, L, V, 0.0) == BLACK  # even with 0⁰ = 1


def test_light_from_below_gives_only_ambient_and_emission():
    m = uniform(ke=(0.01, 0.02, 0.03), ka=0.1, kd=0.8, ks=0.5)
    lights = pack_lights([Light.directional((0.0, 0.3, 1.0))], np.eye(4))  # travels up: from below
    got = opengl_lighting((0.0, 0.0, -3.0), N_UP, N_UP, m, lit((0.2, 0.2, 0.2), lights), PHONG)
    close(got, np.array((0.01, 0.02, 0.03)) + 0.1 * 0.2)


# --- §5, §6: Phong and Blinn-Phong ---------------------------------------

@pytest.mark.parametrize("phi", [0.0, 10.0, 30.0, 50.0, 80.0])
def test_phong_and_blinn_phong_at_known_vectors(phi):
    # L at +30° in the xz-plane; V at phi on the other side. R = (−sin 30°, 0, cos 30°), so
    # R·V = cos(phi − 30°); H bisects L and V, at (30° − phi)/2 from N: N·H = cos((30° − phi)/2).
    n = 20.0
    L, V = tilt(30.0), tilt(phi, 180.0)
    rv = math.cos(math.radians(phi - 30.0))
    nh = math.cos(math.radians((30.0 - phi) / 2.0))
    close(phong_specular(KS, IS, N_UP, L, V, n), np.multiply(KS, IS) * max(rv, 0.0) ** n)
    close(blinn_phong_specular(KS, IS, N_UP, L, V, n), np.multiply(KS, IS) * nh ** n)


def test_phong_and_blinn_phong_agree_when_v_is_r():
    for theta in (0.0, 25.0, 70.0):
        L, V = tilt(theta, 15.0), tilt(theta, 195.0)  # V = R
        p, b = phong_specular(KS, IS, N_UP, L, V, 8.0), blinn_phong_specular(KS, IS, N_UP, L, V, 8.0)
        close(p, np.multiply(KS, IS))
        close(b, p)


def test_phong_clamps_beyond_v_perpendicular_to_r():
    L = tilt(60.0)                                      # R at 60° on the −x side
    at_90 = phong_specular(KS, IS, N_UP, L, tilt(30.0), 5.0)  # R·V = 0 up to rounding
    assert max(at_90) < 1e-60
    assert phong_specular(KS, IS, N_UP, L, tilt(50.0), 5.0) == BLACK  # 110°: R·V < 0, clamped
    for V in (tilt(30.0), tilt(50.0)):
        assert min(blinn_phong_specular(KS, IS, N_UP, L, V, 5.0)) > 0.0  # N·H stays > 0


def test_shininess_zero_is_the_planet():
    # 0⁰ = 1: with n = 0 the lobe is 1 wherever B = 1, even where R·V clamps to 0.
    L, V_far = tilt(60.0), tilt(30.0)
    close(phong_specular(KS, IS, N_UP, L, V_far, 0.0), np.multiply(KS, IS))
    close(blinn_phong_specular(KS, IS, N_UP, L, V_far, 0.0), np.multiply(KS, IS))


# --- §7, §8: attenuation and spotlights ------------------------------------

@pytest.mark.parametrize("abc", [(1.0, 0.0, 0.0), (1.0, 0.5, 0.25), (0.0, 0.0, 1.0), (0.2, 1.0, 0.0)])
@pytest.mark.parametrize("r", [0.25, 1.0, 2.0, 10.0])
def test_attenuation_at_distances(abc, r):
    a, b, c = abc
    assert attenuation(a, b, c, r) == pytest.approx(1.0 / (a + b * r + c * r * r), rel=1e-15)


@pytest.mark.parametrize("r", [0.5, 2.0, 7.0])
def test_point_light_attenuates_diffuse(r):
    a, b, c = 0.5, 0.3, 0.1
    P = (0.5, -0.25, -4.0)
    lights = pack_lights([Light.point((P[0], P[1], P[2] + r), diffuse=ID, specular=0, attenuation=(a, b, c))],
                         np.eye(4))
    m = uniform(ke=0, ka=0, kd=KD, ks=0)
    got = opengl_lighting(P, N_UP, tuple(unit(np.negative(P))), m, lit(BLACK, lights), BLINN_PHONG)
    close(got, np.multiply(KD, ID) / (a + b * r + c * r * r))


def test_directional_light_is_not_attenuated():
    lights = pack_lights([Light.directional((0.0, 0.0, -1.0), diffuse=ID, specular=0)], np.eye(4))
    m = uniform(ke=0, ka=0, kd=KD, ks=0)
    for P in ((0.0, 0.0, -1.0), (0.0, 0.0, -1000.0)):
        close(opengl_lighting(P, N_UP, N_UP, m, lit(BLACK, lights), BLINN_PHONG), np.multiply(KD, ID))


def spot_scene(beta, e, angle):
    """A spot at the origin pointing down −z; the surface point at ``angle`` off its axis, facing it."""
    P = (math.tan(math.radians(angle)), 0.0, -1.0)
    lights = pack_lights([Light.spot((0, 0, 0), (0, 0, -1), cutoff=beta, exponent=e, diffuse=ID, specular=0)],
                         np.eye(4))
    m = uniform(ke=0, ka=0, kd=KD, ks=0)
    L = unit(np.negative(P))
    N = tuple(L)  # facing the light: N·L = 1
    return opengl_lighting(P, N, N, m, lit(BLACK, lights), BLINN_PHONG)


@pytest.mark.parametrize("beta,e", [(30.0, 4.0), (45.0, 0.0), (10.0, 100.0)])
def test_spot_inside_and_outside_the_cone_edge(beta, e):
    inside = math.cos(math.radians(beta - 0.5)) ** e
    close(spot_scene(beta, e, beta - 0.5), np.multiply(KD, ID) * inside)
    assert spot_scene(beta, e, beta + 0.5) == BLACK
    close(spot_scene(beta, e, 0.0), np.multiply(KD, ID))  # on the axis: (−L·S)ᵉ = 1


def test_spot_factor_at_the_edge_and_beta_180():
    S = (0.0, 0.0, -1.0)
    L = (math.sqrt(0.75), 0.0, 0.5)  # −L·S = 0.5 exactly
    assert spot_factor(L, S, 0.5, 3.0) == 0.125  # −L·S ≥ cos β: inside
    assert spot_factor(L, S, 0.5000001, 3.0) == 0.0
    for L in ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0)):  # any direction, even behind
        assert spot_factor(L, S, -1.0, 5.0) == 1.0


def test_spot_with_cutoff_180_is_a_point_light():
    # β = 180°: f_spot = 1, so a point "behind" the spot is lit like by a point light.
    P = (0.0, 0.0, 1.0)
    lights = pack_lights([Light.spot((0, 0, 0), (0, 0, -1), cutoff=180, exponent=50, diffuse=ID, specular=0)],
                         np.eye(4))
    m = uniform(ke=0, ka=0, kd=KD, ks=0)
    close(opengl_lighting(P, (0.0, 0.0, -1.0), (0.0, 0.0, -1.0), m, lit(BLACK, lights), BLINN_PHONG),
          np.multiply(KD, ID))


# --- §10: the whole equation, several lights, against a numpy reference ---

def reference_opengl(P, N, V, mat, global_ambient, lights, phong):
    """FORMULAS §10 evaluated with numpy in *world* space, straight from the Light objects."""
    ke, ka, kd, ks = (np.array(getattr(mat, k)) for k in ("ke", "ka", "kd", "ks"))
    I = ke + ka * np.array(global_ambient)
    for light in lights:
        if light.kind == "directional":
            L, f = unit(np.negative(light.direction)), 1.0
        else:
            d = np.array(light.position) - P
            r = np.linalg.norm(d)
            L = d / r
            a, b, c = light.attenuation
            f = 1.0 / (a + b * r + c * r * r)
            if light.kind == "spot" and light.cutoff != 180.0:
                cos_angle = -L @ unit(light.spot_direction)
                f *= cos_angle ** light.exponent if cos_angle >= math.cos(math.radians(light.cutoff)) else 0.0
        term = ka * np.array(light.ambient)
        n_dot_l = N @ L
        if n_dot_l > 0:
            if phong:
                lobe = max((2 * n_dot_l * N - L) @ V, 0.0) ** mat.shininess
            else:
                lobe = max(N @ unit(L + V), 0.0) ** mat.shininess
            term = term + kd * np.array(light.diffuse) * n_dot_l + ks * np.array(light.specular) * lobe
        I = I + f * term
    return I


def view_matrix(eye, target):
    f = unit(np.subtract(target, eye))
    s = unit(np.cross(f, (0.0, 1.0, 0.0)))
    u = np.cross(s, f)
    M = np.eye(4)
    M[0, :3], M[1, :3], M[2, :3] = s, u, -f
    M[:3, 3] = -M[:3, :3] @ np.asarray(eye, dtype=float)
    return M


SCENE_LIGHTS = [
    Light.point((2.0, 3.0, 1.0), ambient=0.05, diffuse=(0.9, 0.8, 0.7), specular=(1.0, 1.0, 0.9),
                attenuation=(1.0, 0.05, 0.01)),
    Light.directional((-1.0, -2.0, -0.5), diffuse=(0.3, 0.3, 0.5), specular=0.4),
    Light.spot((0.0, 4.0, 0.5), (0.1, -1.0, 0.0), cutoff=40.0, exponent=6.0, diffuse=(1.0, 0.5, 0.5)),
    Light.point((-1.0, -2.0, 0.0), diffuse=1.0),  # below the surface at P: B = 0
]


@pytest.mark.parametrize("specular_model", [BLINN_PHONG, PHONG])
def test_several_lights_add_up_in_eye_space(specular_model):
    mat = Material(ke=(0.01, 0.0, 0.02), ka=(0.1, 0.1, 0.12), kd=(0.6, 0.5, 0.4), ks=(0.3, 0.3, 0.3),
                   shininess=24.0)
    eye, P_world, N_world = np.array((3.0, 2.0, 5.0)), np.array((0.2, 0.1, -0.3)), unit((0.1, 1.0, 0.2))
    ga = (0.2, 0.2, 0.2)
    expected = reference_opengl(P_world, N_world, unit(eye - P_world), mat, ga, SCENE_LIGHTS,
                                specular_model == PHONG)

    # The same scene in eye space: P and N transformed, V = normalize(−P), lights packed.
    view = view_matrix(eye, (0.0, 0.0, 0.0))
    u = Lighting(SCENE_LIGHTS, global_ambient=ga).uniform(view)
    P = tuple((view @ np.append(P_world, 1.0))[:3])
    N = tuple(view[:3, :3] @ N_world)
    V = tuple(unit(np.negative(P)))
    got = opengl_lighting(P, N, V, mat.__softpipe_uniform__(), lit(u.global_ambient, u.lights), specular_model)
    close(got, expected, rel=1e-11)

    # and the sum is more than any one light: each light contributes
    one_by_one = [opengl_lighting(P, N, V, mat.__softpipe_uniform__(), lit(BLACK, u.lights[j:j + 1].copy()),
                                  specular_model) for j in range(len(SCENE_LIGHTS))]
    base = np.array(mat.ke)
    close(np.sum([np.subtract(x, base) for x in one_by_one], axis=0) + base + np.multiply(mat.ka, ga), expected,
          rel=1e-11)


# --- §20: Fresnel ----------------------------------------------------------

def test_fresnel_glass_at_normal_incidence():
    rs, rp = fresnel_rs_rp(1.0, 1.0, 1.5)
    assert rs == pytest.approx(0.04, abs=1e-15) and rp == pytest.approx(0.04, abs=1e-15)
    assert fresnel(1.0, 1.0, 1.5) == pytest.approx(0.04, abs=1e-15)
    assert fresnel(1.0, 1.5, 1.0) == pytest.approx(0.04, abs=1e-15)  # the same from inside
    assert fresnel_schlick(1.0, 1.0, 1.5) == pytest.approx(0.04, abs=1e-15)


@pytest.mark.parametrize("n1,n2", [(1.0, 1.52), (1.0, 1.33), (1.52, 1.0)])
def test_rp_vanishes_at_brewster(n1, n2):
    theta_b = math.atan(n2 / n1)
    rs, rp = fresnel_rs_rp(math.cos(theta_b), n1, n2)
    assert rp == pytest.approx(0.0, abs=1e-15)
    assert rs > 0.01


@pytest.mark.parametrize("n1,n2,theta", [(1.0, 1.52, 30.0), (1.0, 1.33, 70.0), (1.52, 1.0, 20.0),
                                         (2.417, 1.0, 10.0)])
def test_fresnel_matches_the_sine_and_tangent_laws(n1, n2, theta):
    # Fresnel's equations in their angle form: R_s = sin²(θ₁−θ₂)/sin²(θ₁+θ₂),
    # R_p = tan²(θ₁−θ₂)/tan²(θ₁+θ₂), with θ₂ from Snell's law (§17).
    t1 = math.radians(theta)
    t2 = math.asin(n1 / n2 * math.sin(t1))
    rs = (math.sin(t1 - t2) / math.sin(t1 + t2)) ** 2
    rp = (math.tan(t1 - t2) / math.tan(t1 + t2)) ** 2
    close(fresnel_rs_rp(math.cos(t1), n1, n2), (rs, rp), rel=1e-12)
    assert fresnel(math.cos(t1), n1, n2) == pytest.approx((rs + rp) / 2, rel=1e-12)


def test_fresnel_is_one_beyond_the_critical_angle():
    critical = math.degrees(math.asin(1.0 / 1.5))  # ≈ 41.8°
    for theta in (critical + 0.01, 60.0, 89.9):
        c = math.cos(math.radians(theta))
        assert fresnel(c, 1.5, 1.0) == 1.0 and fresnel_schlick(c, 1.5, 1.0) == 1.0
    assert fresnel(math.cos(math.radians(critical - 1.0)), 1.5, 1.0) < 1.0


def test_schlick_is_labelled_approximation_with_the_right_ends():
    assert fresnel_schlick(0.0, 1.0, 1.5) == 1.0  # grazing
    exact = [fresnel(math.cos(math.radians(t)), 1.0, 1.5) for t in (0, 30, 60, 80)]
    approx = [fresnel_schlick(math.cos(math.radians(t)), 1.0, 1.5) for t in (0, 30, 60, 80)]
    assert np.all(np.diff(approx) > -1e-15) and np.max(np.abs(np.subtract(exact, approx))) < 0.05


# --- §13, §14: Hall --------------------------------------------------------

@pytest.mark.parametrize("eta", [1.5, 1.33, 1 / 1.5])
@pytest.mark.parametrize("theta_v,theta_l,phi_l", [(0.0, 180.0, 0.0), (30.0, 160.0, 200.0),
                                                   (50.0, 170.0, 90.0), (10.0, 130.0, 150.0),
                                                   (40.0, 150.0, 60.0)])
def test_transmitted_half_vector_refracts_the_light_into_v(eta, theta_v, theta_l, phi_l):
    # Viewer's medium η₁ = 1, light's side η₂ = eta. The facet normal H′ must refract the
    # light's ray d = −L into V by Snell's law (§17), in vector form: the tangential parts
    # of η₂·d and η₁·V are equal.
    V, L = np.array(tilt(theta_v, 20.0)), np.array(tilt(theta_l, phi_l))
    h = np.array(transmitted_half_vector(tuple(map(float, L)), tuple(map(float, V)), eta))
    d = -L
    assert np.linalg.norm(h) == pytest.approx(1.0, abs=1e-14)
    close(eta * (d - (d @ h) * h), 1.0 * (V - (V @ h) * h), abs_=1e-14)
    # Refraction bends a ray by at most 90° − θ_c, θ_c = asin(smaller index / larger index).
    # Within that, the ray crosses the facet (d·H′ and V·H′ of one sign) and the lobe
    # faces the light; beyond it no facet exists and Hall's transmission is 0.
    deviation = math.degrees(math.acos(np.clip(d @ V, -1.0, 1.0)))
    max_deviation = 90.0 - math.degrees(math.asin(min(eta, 1.0 / eta)))
    transmitted = hall_transmission((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), N_UP, tuple(map(float, L)),
                                    tuple(map(float, V)), eta, 1.0)
    if deviation < max_deviation - 1.0:
        assert (d @ h) * (V @ h) > 0
        close(transmitted, [max(-h[2], 0.0)] * 3)
    elif deviation > max_deviation + 1.0:
        assert (d @ h) * (V @ h) < 0
        assert transmitted == BLACK


def test_transmitted_half_vector_is_formulas_14_as_corrected():
    """FORMULAS §14 (corrected): with L toward the light, H′ = normalize((V + η·L)/(η − 1)).

    The check §14 gives: light straight through the surface (L = −N, V = N, η = 1.5) has
    the full lobe, (−N·H′) = 1; the notes' literal (V − η·L)/(η − 1) gives 0 there.
    """
    L, V, eta = np.array((0.0, 0.0, -1.0)), np.array(N_UP), 1.5
    h = np.array(transmitted_half_vector(tuple(L), tuple(V), eta))
    close(h, unit((V + eta * L) / (eta - 1.0)))
    assert -(np.array(N_UP) @ h) == pytest.approx(1.0, abs=1e-15)
    literal = unit((V - eta * L) / (eta - 1.0))
    assert -(np.array(N_UP) @ literal) == pytest.approx(-1.0) and max(-(np.array(N_UP) @ literal), 0.0) == 0.0
    for L in (tilt(150.0, 30.0), tilt(170.0, 200.0)):          # and off-axis: the corrected formula itself
        h = np.array(transmitted_half_vector(L, tuple(V), eta))
        close(h, unit((V + eta * np.array(L)) / (eta - 1.0)))


def test_hall_straight_through_transmission_and_no_refraction():
    kt = (0.3, 0.5, 0.7)
    close(hall_transmission(kt, IS, N_UP, (0.0, 0.0, -1.0), N_UP, 1.5, 40.0), np.multiply(kt, IS))
    assert hall_transmission(kt, IS, N_UP, tilt(30.0), N_UP, 1.5, 40.0) == BLACK  # light in front
    assert hall_transmission(kt, IS, N_UP, (0.0, 0.0, -1.0), N_UP, 1.0, 40.0) == BLACK  # η = 1


def test_hall_local_sums_its_terms():
    mat = Material(ke=0, ka=(0.1, 0.2, 0.1), kd=KD, ks=KS, kt=(0.2, 0.3, 0.4), shininess=12.0,
                   transmission_shininess=30.0, ior=1.5)
    ga, n = (0.3, 0.3, 0.3), 12.0
    V = tilt(20.0, 180.0)
    L_front, L_back = np.array(tilt(40.0)), np.array(tilt(170.0, 10.0))
    lights = pack_lights([Light.directional(tuple(-L_front), ambient=0.1, diffuse=ID, specular=IS),
                          Light.directional(tuple(-L_back), diffuse=ID, specular=IS)], np.eye(4))
    H = unit(L_front + V)
    Ht = unit((np.array(V) + 1.5 * L_back) / (1.5 - 1.0))
    expected = (np.multiply(mat.ka, ga) + np.multiply(mat.ka, 0.1)
                + np.multiply(KS, IS) * (np.array(N_UP) @ H) ** n
                + np.multiply(KD, ID) * (np.array(N_UP) @ L_front)
                + np.multiply(mat.kt, IS) * max(-(np.array(N_UP) @ Ht), 0.0) ** 30.0)
    got = hall_local((0.0, 0.0, -2.0), N_UP, V, mat.__softpipe_uniform__(), lit(ga, lights), 1.5)
    close(got, expected)


# --- §26: Cook-Torrance and Gooch -----------------------------------------

@pytest.mark.parametrize("m", [0.1, 0.3, 0.6])
@pytest.mark.parametrize("alpha", [0.0, 10.0, 25.0, 60.0])
def test_beckmann_d_at_known_alpha(m, alpha):
    a = math.radians(alpha)
    expected = math.exp(-math.tan(a) ** 2 / m ** 2) / (math.pi * m ** 2 * math.cos(a) ** 4)
    assert beckmann_d(math.cos(a), m) == pytest.approx(expected, rel=1e-12)


def test_beckmann_d_is_normalized():
    # ∫ D(α) cos α dω over the hemisphere = 1 (this D carries its 1/π).
    theta = np.linspace(0.0, math.pi / 2, 4001)
    d = np.array([beckmann_d(math.cos(t), 0.3) for t in theta])
    integral = 2 * math.pi * np.trapezoid(d * np.cos(theta) * np.sin(theta), theta)
    assert integral == pytest.approx(1.0, abs=1e-6)


def test_geometry_g_values():
    # G = min(1, 2(N·H)(N·V)/(V·H), 2(N·H)(N·L)/(V·H)), each branch once.
    for L, V, which in ((tilt(0.0), tilt(0.0), "one"), (tilt(20.0), tilt(85.0, 180.0), "masking"),
                        (tilt(85.0, 180.0), tilt(20.0), "shadowing")):
        L, V = np.array(L), np.array(V)
        H = unit(L + V)
        nh, nv, nl, vh = H[2], V[2], L[2], V @ H
        terms = {"one": 1.0, "masking": 2 * nh * nv / vh, "shadowing": 2 * nh * nl / vh}
        assert min(terms.values()) == terms[which]
        assert geometry_g(nh, nv, nl, vh) == pytest.approx(terms[which], rel=1e-14)


def test_cook_torrance_value():
    """FORMULAS §26's normalized form f_s = D·G·F / (4 (N·L)(N·V)), D Beckmann's with its 1/π.

    At this point the 1982 paper's R_s = F·D′·G / (π (N·L)(N·V)) (D′ = π·D, no 1/π) is
    0.2027 and the normalized f_s is 0.0507 = R_s/4; the earlier code's 0.0645 paired
    the paper's π with the normalized D.
    """
    m, n2 = 0.35, 1.5
    L, V = np.array(tilt(35.0, 10.0)), np.array(tilt(50.0, 200.0))
    H = unit(L + V)
    nh, nv, nl, vh = H[2], V[2], L[2], V @ H
    alpha = math.acos(nh)
    D = math.exp(-(math.tan(alpha) / m) ** 2) / (math.pi * m * m * math.cos(alpha) ** 4)
    G = min(1.0, 2 * nh * nv / vh, 2 * nh * nl / vh)
    t1 = math.acos(vh)
    t2 = math.asin(math.sin(t1) / n2)
    F = ((math.sin(t1 - t2) / math.sin(t1 + t2)) ** 2 + (math.tan(t1 - t2) / math.tan(t1 + t2)) ** 2) / 2
    expected = D * G * F / (4.0 * nl * nv)
    paper = F * (math.pi * D) * G / (math.pi * nl * nv)
    assert paper == pytest.approx(0.20273, abs=1e-5) and expected == pytest.approx(0.050682, abs=1e-6)
    assert expected == pytest.approx(paper / 4.0, rel=1e-14)
    assert cook_torrance(N_UP, tuple(L), tuple(V), m, 1.0, n2) == pytest.approx(expected, rel=1e-11)
    assert cook_torrance(N_UP, tilt(100.0), tuple(V), m, 1.0, n2) == 0.0  # light below


def test_cook_torrance_lighting_one_light():
    mat = Material(ke=0, ka=0.1, kd=KD, ks=KS, ior=1.5, roughness=0.3)
    L, V = np.array(tilt(30.0)), tilt(30.0, 180.0)
    lights = pack_lights([Light.directional(tuple(-L), diffuse=ID, specular=IS)], np.eye(4))
    f_s = cook_torrance(N_UP, tuple(L), V, 0.3, 1.0, 1.5)  # its own value is tested above
    expected = 0.1 * 0.2 + (np.multiply(KD, ID) + np.multiply(KS, IS) * f_s) * L[2]
    got = cook_torrance_lighting((0.0, 0.0, -1.0), N_UP, V, mat.__softpipe_uniform__(), lit((0.2, 0.2, 0.2), lights))
    close(got, expected)


def test_gooch_cool_to_warm():
    kd, blue, yellow, a, b = (0.8, 0.3, 0.2), (0.0, 0.0, 0.4), (0.4, 0.4, 0.0), 0.2, 0.6
    cool = np.array(blue) + a * np.array(kd)
    warm = np.array(yellow) + b * np.array(kd)
    close(gooch(N_UP, (0.0, 0.0, -1.0), kd, blue, yellow, a, b), cool)          # N·L = −1
    close(gooch(N_UP, (1.0, 0.0, 0.0), kd, blue, yellow, a, b), (cool + warm) / 2)  # N·L = 0
    close(gooch(N_UP, N_UP, kd, blue, yellow, a, b), warm)                       # N·L = 1


# --- NaN-free at grazing angles and zero vectors ---------------------------

def test_degenerate_geometry_stays_finite():
    m = uniform(ke=0.1, ka=0.1, kd=0.5, ks=0.5, kt=0.5, shininess=0.0, ior=1.5, roughness=0.2)
    P = (0.0, 0.0, -2.0)
    lights = pack_lights([Light.point(P, attenuation=(0.0, 0.0, 1.0)),           # the light at P, 1/r²
                          Light.spot(P, (0, 0, -1), cutoff=90.0, exponent=0.0),
                          Light.directional((0.0, 0.0, 1.0)),                    # L = −V
                          Light.directional((1.0, 0.0, 0.0))], np.eye(4))       # grazing: N·L = 0
    for N, V in ((N_UP, N_UP), ((0.0, 0.0, 0.0), N_UP), (N_UP, (1.0, 0.0, 0.0)), (N_UP, (0.0, 0.0, 0.0))):
        for model in (BLINN_PHONG, PHONG):
            assert np.all(np.isfinite(opengl_lighting(P, N, V, m, lit((0.2, 0.2, 0.2), lights), model)))
        assert np.all(np.isfinite(hall_local(P, N, V, m, lit((0.2, 0.2, 0.2), lights), 1.5)))
        assert np.all(np.isfinite(cook_torrance_lighting(P, N, V, m, lit((0.2, 0.2, 0.2), lights))))
    assert np.isfinite(beckmann_d(1e-200, 0.3)) and np.isfinite(beckmann_d(1e-5, 0.3))
    assert np.isfinite(cook_torrance(N_UP, (1e-300, 0.0, 1.0), (1.0, 0.0, 1e-300), 0.3, 1.0, 1.5))
    assert np.isfinite(attenuation(0.0, 1.0, 1.0, 0.0))
    assert np.all(np.isfinite(transmitted_half_vector((0.0, 0.0, -1.0), (0.0, 0.0, -1.0), 1.0)))
    assert np.isfinite(fresnel(0.0, 1.0, 1.5)) and fresnel(0.0, 1.0, 1.5) == 1.0


# --- jitted, .py_func and NUMBA_DISABLE_JIT give the same bits -------------

def identity_cases():
    """Calls whose results must be bit-identical in every mode (used in-process and in a subprocess)."""
    mat = Material(ke=(0.01, 0.02, 0.0), ka=0.1, kd=(0.6, 0.5, 0.4), ks=0.4, kt=0.3, shininess=17.5,
                   ior=1.45, roughness=0.25).__softpipe_uniform__()
    u = Lighting(SCENE_LIGHTS).uniform(view_matrix((3.0, 2.0, 5.0), (0.0, 0.0, 0.0)))
    P = (0.3, -0.2, -5.5)
    N = tuple(unit((0.2, 0.3, 0.9)))
    V = tuple(unit(np.negative(P)))
    return [
        (opengl_lighting, (P, N, V, mat, u, BLINN_PHONG)),
        (opengl_lighting, (P, N, V, mat, u, PHONG)),
        (hall_local, (P, N, V, mat, u, 1.45)),
        (cook_torrance_lighting, (P, N, V, mat, u)),
        (gooch, (N, tuple(unit((1.0, 1.0, 1.0))), (0.5, 0.4, 0.3), (0.0, 0.0, 0.4), (0.4, 0.4, 0.0), 0.2, 0.6)),
        (fresnel, (0.3, 1.0, 1.52)),
        (fresnel_schlick, (0.3, 1.0, 1.52)),
        (beckmann_d, (0.9, 0.3)),
    ]


def bits(result):
    """A result as the hex strings of its floats: equal bits, whatever the float type."""
    return [float(x).hex() for x in np.atleast_1d(result)]


def identity_bits():
    return [bits(f(*args)) for f, args in identity_cases()]


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="compares compiled code with Python")
def test_jitted_python_and_nojit_are_bit_identical():
    jitted = identity_bits()
    assert jitted == [bits(f.py_func(*args)) for f, args in identity_cases()]
    code = "import sys; sys.path.insert(0, sys.argv[1]); import test_lighting as t; print(t.identity_bits())"
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", code, os.path.dirname(__file__)],
                         capture_output=True, text=True, env=env, check=True).stdout.strip()
    assert out == repr(jitted)
