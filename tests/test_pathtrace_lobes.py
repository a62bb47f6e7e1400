"""The path tracer's glossy lobes (softpipe.tracers.lobes): energy, closed forms, densities, MIS.

Each lobe is normalized so that its albedo ∫ f (N·L) dω is at most ks (FORMULAS §27):
white furnace tests (a plane of ks = 1 under a sky of radiance 1) and the closed forms at
V = N; its sampling density is checked against a quadrature of the same integral, and the
path tracer's light-sampling-only and BSDF-sampling-only images against each other.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import compose, rotate_x, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.lobes import BLINN_PHONG_LOBE, COOK_TORRANCE_LOBE, PHONG_LOBE, lobe_eval, lobe_sample
from softpipe.tracers.montecarlo import uniform
from softpipe.tracers.pathtrace import pathtrace

PROGRAMS = {PHONG_LOBE: "phong_phong_specular", BLINN_PHONG_LOBE: "phong", COOK_TORRANCE_LOBE: "cook_torrance"}
N = (0.0, 0.0, 1.0)


@njit(cache=False)
def _quadrature(code, V, n, m, ior, steps):
    total = density = 0.0
    for i in range(steps):
        ct = (i + 0.5) / steps
        st = math.sqrt(1 - ct * ct)
        for j in range(2 * steps):
            ph = (j + 0.5) / (2 * steps) * 2 * math.pi
            f, p = lobe_eval(code, N, V, (st * math.cos(ph), st * math.sin(ph), ct), n, m, ior)
            total += f * ct
            density += p
    cell = (1.0 / steps) * (2 * math.pi / (2 * steps))
    return total * cell, density * cell


def albedo_quadrature(code, V, n=32.0, m=0.3, ior=1.5, steps=400):
    """∫ f (N·L) dω over the hemisphere by the midpoint rule in (cos θ, φ) (dω = d cos θ dφ), and ∫ p dω."""
    return _quadrature(code, V, float(n), float(m), float(ior), steps)


def albedo_sampled(code, V, n=32.0, m=0.3, ior=1.5, count=40000):
    """E[f (N·L) / p] over directions drawn by lobe_sample: the same integral, if p is sampling's density."""
    weights = np.zeros(count)
    for k in range(count):
        L = lobe_sample(code, N, V, n, m, uniform(1, k, 0, 0), uniform(1, k, 0, 1))
        f, p = lobe_eval(code, N, V, L, n, m, ior)
        if f > 0.0:
            weights[k] = f * L[2] / p
    return weights.mean(), weights.std() / math.sqrt(count)


def blinn_phong_albedo_at_normal(n):
    """(n + 1)·[2(1 − a^(n+3))/(n + 3) − (1 − a^(n+1))/(n + 1)], a = 1/√2: FORMULAS §27 at V = N."""
    a = 1 / math.sqrt(2)
    return (n + 1) * (2 * (1 - a ** (n + 3)) / (n + 3) - (1 - a ** (n + 1)) / (n + 1))


@pytest.mark.parametrize("code", [PHONG_LOBE, BLINN_PHONG_LOBE, COOK_TORRANCE_LOBE])
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_sampling_density_matches_the_lobe_and_energy_is_at_most_one(code, theta):
    V = (math.sin(math.radians(theta)), 0.0, math.cos(math.radians(theta)))
    quad, density = albedo_quadrature(code, V)
    sampled, se = albedo_sampled(code, V)
    assert quad <= 1.0 + 1e-3 and density <= 1.0 + 1e-3, (quad, density)
    assert abs(sampled - quad) < 4 * se + 2e-3, (sampled, quad, se)


@pytest.mark.parametrize("n", [1.0, 8.0, 64.0, 200.0])
def test_closed_forms_at_normal_incidence(n):
    """At V = N: normalized Phong reflects exactly ks for every n; Blinn-Phong the closed form, → 1 as n → ∞."""
    phong, _ = albedo_quadrature(PHONG_LOBE, N, n=n, steps=300 if n < 100 else 2000)
    assert abs(phong - 1.0) < 2e-3, phong
    blinn, _ = albedo_quadrature(BLINN_PHONG_LOBE, N, n=n, steps=300 if n < 100 else 2000)
    assert abs(blinn - blinn_phong_albedo_at_normal(n)) < 2e-3, (blinn, blinn_phong_albedo_at_normal(n))
    assert 0.9995 < blinn_phong_albedo_at_normal(1e4) < 1.0      # ≈ (n − 1)/(n + 3) for large n: → 1


def test_cook_torrance_tends_to_fresnel_at_normal_incidence_as_m_falls():
    albedo, _ = albedo_quadrature(COOK_TORRANCE_LOBE, N, m=0.02, ior=1.5, steps=2000)
    assert abs(albedo - 0.04) < 1e-3, albedo          # ((1.5 − 1)/(1.5 + 1))² = 0.04


def scene_of(*objects, camera, size=8, background=(0.0, 0.0, 0.0, 1.0)):
    return Scene(objects=[SceneObject(name, mesh, model, program=program) for name, mesh, model, program in objects],
                 camera=camera, width=size, height=size, background=background, lights=())


@pytest.mark.parametrize("code, expected", [(PHONG_LOBE, 1.0), (BLINN_PHONG_LOBE, blinn_phong_albedo_at_normal(32.0))])
def test_white_furnace_image(code, expected):
    """A plane of kd = 0, ks = 1 under a sky of radiance 1, seen from straight above (within 1°): every
    pixel estimates the lobe's albedo at V ≈ N, its closed form; never more than 1 beyond the noise."""
    glossy = Material(kd=0.0, ks=1.0, shininess=32.0, name="glossy")
    above = Camera(eye=(0.0, 3.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fovy=2.0, near=0.01, far=50.0)
    scene = scene_of(("floor", shapes.plane(2.0, material=glossy), np.eye(4), PROGRAMS[code]), camera=above,
                     background=(1.0, 1.0, 1.0, 1.0))
    traced = pathtrace(scene, spp=256, seed=2)
    mean = traced.image.reshape(-1, 3).mean(0)
    se = np.sqrt(traced.variance.reshape(-1, 3).sum(0)) / 64
    assert np.all(np.abs(mean - expected) < 5 * se + 3e-3), (mean, expected, se)
    assert np.all(mean < 1.0 + 5 * se + 1e-6)


@pytest.mark.parametrize("code", [PHONG_LOBE, BLINN_PHONG_LOBE, COOK_TORRANCE_LOBE])
def test_light_sampling_alone_equals_bsdf_sampling_alone(code):
    """A glossy floor (kd 0.3, ks 0.7, n = 8, m = 0.4) lit by a quad lamp above it at 45°: the image with only
    light samples and the image with only sampled directions estimate the same integral, if each lobe's density
    is the one its sampling draws from. Their means agree within 4 standard errors; MIS agrees with both."""
    mat = Material(kd=0.3, ks=0.7, shininess=8.0, roughness=0.4, ior=1.5, name="glossy")
    lamp = Material(ke=(4.0, 4.0, 4.0), kd=0.0, ks=0.0, name="lamp")
    camera = Camera(eye=(0.0, 1.0, 1.0), target=(0.0, 0.0, 0.0), fovy=30.0, near=0.01, far=50.0)
    lamp_model = compose(translate(0.0, 1.0, -1.0), rotate_x(180.0 - 45.0))
    scene = scene_of(("floor", shapes.plane(4.0, material=mat), np.eye(4), PROGRAMS[code]),
                     ("lamp", shapes.plane(1.0, material=lamp), lamp_model, "phong"), camera=camera)
    means = {}
    for strategy in ("light", "bsdf", "mis"):
        t = pathtrace(scene, spp=512, seed=9, max_depth=2, strategy=strategy)
        means[strategy] = (t.image.reshape(-1, 3).mean(0)[0], math.sqrt(t.variance[..., 0].sum()) / 64)
    (a, sa), (b, sb), (c, sc) = means["light"], means["bsdf"], means["mis"]
    assert a > 0.05, means                              # the floor is lit: the test compares something
    assert abs(a - b) < 4 * math.hypot(sa, sb), means
    assert abs(c - b) < 4 * math.hypot(sc, sb) and abs(c - a) < 4 * math.hypot(sc, sa), means


def test_a_bad_strategy_is_named():
    scene = scene_of(("floor", shapes.plane(2.0, material=Material()), np.eye(4), None),
                     camera=Camera(eye=(0.0, 3.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0)))
    with pytest.raises(ValueError) as e:
        pathtrace(scene, spp=1, strategy="nee")
    assert str(e.value) == "pathtrace: strategy must be one of 'mis', 'bsdf', 'light', got 'nee'"
