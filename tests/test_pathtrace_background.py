"""Light sampling toward the background (``pathtrace(..., background_light=True)``): next-event estimation to a
uniform sky, combined by MIS.

At a diffuse or glossy bounce the light sample goes to the background with probability p_bg (the sky's share
of the light, by power) and then draws a direction ∝ cos θ about the shading normal; a shadow ray that leaves
the scene brings back the background's radiance, weighted by the power heuristic against the lobes' densities,
and a drawn direction that leaves is weighted against p_bg·cos θ/π.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.pathtrace import BACKGROUND_LIGHT, pathtrace

SKY = (1.0, 1.0, 1.0, 1.0)


def furnace(strategy="mis"):
    camera = Camera(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fovy=45.0, near=0.01, far=50.0)
    ball = SceneObject("ball", shapes.icosphere(0.8, 4, material=Material(ka=0.0, kd=1.0, ks=0.0)), np.eye(4))
    scene = Scene(objects=[ball], camera=camera, width=16, height=16, background=SKY, lights=())
    return pathtrace(scene, spp=16, seed=3, strategy=strategy, background_light=True)


def test_white_furnace_a_white_diffuse_sphere_under_a_sky_of_one_is_one_everywhere():
    """The noise bound, derived: on a convex white Lambert sphere under radiance 1, the light sample (drawn ∝ cos θ
    about N, p_bg = 1: no other light) and the drawn Lambert direction have the same density cos θ/π, so each
    MIS weight is exactly 1/2, each finds the sky unoccluded (nothing of a convex object lies above its tangent
    plane) and brings back kd·L = 1: every sample is 1/2 + 1/2 = 1, with no variance at all. So the bound at any
    spp is float rounding: every pixel 1 to 10⁻⁶, its variance 0 to 10⁻¹². The sky seen past the ball is 1 too."""
    traced = furnace()
    assert np.abs(traced.image - 1.0).max() < 1e-6
    assert traced.variance.max() < 1e-12
    path = traced.path_story(8, 8, sample=0)[0]
    first, out = path.bounces
    assert first.object == "ball" and first.light == BACKGROUND_LIGHT and first.nee == "light sample lit it"
    assert first.nee_lambert_weight == pytest.approx(0.5, abs=1e-12)
    assert first.nee_lambert == pytest.approx((0.5, 0.5, 0.5), abs=1e-12)
    assert out.end == "left the scene" and out.emission_weight == pytest.approx(0.5, abs=1e-12)
    assert out.background == pytest.approx((0.5, 0.5, 0.5), abs=1e-12)
    assert "light sample lit it (the background)" in str(traced.path_story(8, 8, sample=0))
    # light sampling alone finds the same 1 (the drawn direction that leaves then counts nothing)
    assert np.abs(furnace("light").image - 1.0).max() < 1e-6


def sky_scene(lamp=False, size=24, ground_kd=0.7, ball=None):
    """A glossy ball on a diffuse ground under a blue sky (and, with ``lamp``, a small warm emissive quad above):
    the ground in the ball's shadow, the ball lit by the ground — a scene that is not convex."""
    camera = Camera(eye=(0.0, 2.0, 4.0), target=(0.0, 0.0, 0.0), fovy=45.0, near=0.01, far=50.0)
    ground = SceneObject("ground", shapes.plane(6.0, material=Material(ka=0.0, kd=ground_kd, ks=0.0)),
                         translate(0, -0.8, 0))
    ball = SceneObject("ball", shapes.icosphere(0.8, 3, material=ball or Material(ka=0.0, kd=0.5, ks=0.3,
                                                                                    shininess=20.0)), np.eye(4))
    objects = [ground, ball]
    if lamp:
        down = np.diag([1.0, -1.0, -1.0, 1.0])
        down[:3, 3] = (0.8, 2.0, 0.5)
        objects.append(SceneObject("lamp", shapes.plane(0.4, material=Material(ke=(8.0, 6.0, 4.0), kd=0.0, ks=0.0)),
                                   down))
    return Scene(objects=objects, camera=camera, width=size, height=size, background=(0.6, 0.7, 0.9, 1.0), lights=())


def z_blocks(a, b, block=4):
    """Per block and channel, (Σ A − Σ B)/√(Σ V_A + Σ V_B): near N(0, 1) when both estimate the same image
    (the blocks with noise; the others, all sky, must agree exactly)."""
    def sums(x):
        h, w, _ = x.shape
        return x.reshape(h // block, block, w // block, block, 3).sum(axis=(1, 3))
    ia, ib = a.image.astype(np.float64), b.image.astype(np.float64)
    d, v = sums(ia - ib), sums(a.variance.astype(np.float64) + b.variance.astype(np.float64))
    return d[v > 0.0] / np.sqrt(v[v > 0.0]), np.abs(d[v == 0.0])


@pytest.mark.parametrize("lamp", [False, True])
def test_mis_with_the_background_light_sample_equals_bsdf_sampling_in_expectation(lamp):
    """The same image three ways: MIS (sky light sample + drawn directions), the drawn directions alone, the light
    samples alone. Per 4×4 block and channel z is near N(0, 1): mean z² below 1.6, no |z| above 5; and the
    test can see a 3 % error (the BSDF image scaled by 1.03 fails)."""
    scene = sky_scene(lamp)
    mis = pathtrace(scene, spp=256, seed=1, background_light=True)
    bsdf = pathtrace(scene, spp=256, seed=2, strategy="bsdf")
    light = pathtrace(scene, spp=256, seed=3, strategy="light", background_light=True)
    for other in (bsdf, light):
        z, exact = z_blocks(mis, other)
        assert np.mean(z ** 2) < 1.6 and np.abs(z).max() < 5.0, (other.strategy, np.mean(z ** 2), np.abs(z).max())
        assert np.all(exact < 1e-5)                     # blocks of sky seen directly: no noise, the same numbers
    bsdf._total *= 1.03
    z, exact = z_blocks(mis, bsdf)
    assert np.mean(z ** 2) > 4.0 and exact.min() > 0.1


@pytest.mark.parametrize("ground_kd,ratio", [(0.05, 0.7), (0.7, None)])
def test_the_sky_light_sample_halves_the_noise_where_what_hides_the_sky_is_dark(ground_kd, ratio):
    """A white Lambert ball on a ground. A sample of the ball's direct light from the sky: with drawn directions
    alone, kd·L where the direction escapes and kd·L_ground where it meets the ground; with the light sample, two
    independent draws of the same density, weight 1/2 each. Over a dark ground (L_ground ≈ 0) that halves the
    variance of the direct light — the gain a light sample gives under an area light; over a ground about as bright
    as the sky the drawn direction alone was nearly noiseless (L ≈ L_ground) and the light sample adds noise
    (measured: ×0.55 on the ball over kd 0.05, ×1.5 over kd 0.7; docs/pathtracing.md says when to use it)."""
    scene = sky_scene(ground_kd=ground_kd, ball=Material(ka=0.0, kd=0.8, ks=0.0))
    light = pathtrace(scene, spp=128, seed=4, background_light=True).variance[6:18, 7:17].mean()
    alone = pathtrace(scene, spp=128, seed=4).variance[6:18, 7:17].mean()
    if ratio is not None:
        assert light < ratio * alone
    else:
        assert light > alone


def test_by_default_the_background_is_not_a_light_sample():
    """Without background_light the image is the same bytes as drawn directions finding the sky (p_bg = 0)."""
    scene = sky_scene(lamp=True, size=8)
    default = pathtrace(scene, spp=8, seed=6)
    assert default.background_light is False
    assert all(b.light != BACKGROUND_LIGHT for x in range(8) for path in default.path_story(x, 6) for b in path.bounces)
    assert default.image.tobytes() != pathtrace(scene, spp=8, seed=6, background_light=True).image.tobytes()
    with pytest.raises(ValueError, match=r"^pathtrace: background_light must be True or False, got 'yes'$"):
        pathtrace(scene, spp=1, background_light="yes")


def test_the_sky_and_a_lamp_share_the_light_samples_by_power():
    """p_bg = mean(L_sky)·4πR² / (that + Σ A·mean(ke)): both kinds of light sample occur on the ground, and a pixel
    lit by both records which one its sample went to."""
    traced = pathtrace(sky_scene(lamp=True), spp=64, seed=5, background_light=True)
    lights = {b.light for path in traced.path_story(12, 21) for b in path.bounces[:1]}
    assert BACKGROUND_LIGHT in lights and any(k >= 0 for k in lights)
    assert math.isfinite(float(traced.image.sum()))


def test_a_path_story_with_the_sky_as_a_light_adds_up_to_the_sample_to_the_last_bit():
    traced = pathtrace(sky_scene(lamp=True, size=8), spp=3, seed=8, background_light=True)
    kinds = set()
    for y in range(8):
        for x in range(8):
            for path in traced.path_story(x, y):
                assert path.total() == path.value, (x, y, path.sample)
                kinds.update(b.light for b in path.bounces)
    assert BACKGROUND_LIGHT in kinds
