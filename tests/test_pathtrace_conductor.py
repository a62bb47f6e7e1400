"""Conductors with a complex index η + ik (FORMULAS §30): the exact Fresnel reflectance and the path tracer's metal mirror.

The gold and copper indices are Mitsuba 3's RGB values for its conductor materials "Au" and "Cu"
(``mitsuba.traverse(load_dict({"type": "conductor", "material": "Au"}))`` in the ``scalar_rgb``
variant: its measured spectral data reduced to RGB).
"""
from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from softpipe.light.lighting import fresnel
from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.scenes.scenefile import parse_scene
from softpipe.tracers.lobes import conductor_fresnel
from softpipe.tracers.pathtrace import pathtrace

GOLD = dict(eta=(0.143036, 0.375307, 1.44205), k=(3.983, 2.38556, 1.60336))
COPPER = dict(eta=(0.201005, 0.92375, 1.10222), k=(3.91326, 2.45305, 2.14209))


def fresnel_complex(cos_i: float, eta: float, k: float) -> float:
    """F_R from air into the index η + ik with Python's complex numbers: Snell's law and Fresnel's r_s, r_p."""
    n = complex(eta, k)
    sin_i = math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
    cos_t = cmath.sqrt(1.0 - (sin_i / n) ** 2)          # Snell: sin θ_t = sin θ_i / n, complex
    rs = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    rp = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return 0.5 * (abs(rs) ** 2 + abs(rp) ** 2)


@pytest.mark.parametrize("eta,k", [(0.143036, 3.983), (1.44205, 1.60336), (0.92375, 2.45305), (1.5, 0.0),
                                   (2.0, 10.0), (0.05, 0.01)])
def test_conductor_fresnel_at_normal_incidence(eta, k):
    expected = ((eta - 1) ** 2 + k * k) / ((eta + 1) ** 2 + k * k)
    assert conductor_fresnel(1.0, eta, k) == pytest.approx(expected, rel=1e-13)


@pytest.mark.parametrize("eta,k", [(0.143036, 3.983), (1.44205, 1.60336), (1.5, 0.0), (2.0, 10.0)])
def test_conductor_fresnel_is_one_at_grazing_incidence(eta, k):
    assert conductor_fresnel(0.0, eta, k) == 1.0
    assert conductor_fresnel(1e-7, eta, k) == pytest.approx(1.0, abs=1e-5)
    assert conductor_fresnel(1e-7, eta, k) < 1.0


@pytest.mark.parametrize("eta,k", [*zip(GOLD["eta"], GOLD["k"]), *zip(COPPER["eta"], COPPER["k"]), (1.5, 0.0),
                                   (0.3, 0.0), (3.0, 0.5), (1.0, 1.0)])
def test_conductor_fresnel_agrees_with_complex_numbers(eta, k):
    for degrees in (0, 10, 30, 45, 60, 75, 80, 85, 89, 89.9):
        c = math.cos(math.radians(degrees))
        assert conductor_fresnel(c, eta, k) == pytest.approx(fresnel_complex(c, eta, k), rel=1e-11, abs=1e-14), degrees


def test_with_k_zero_it_is_the_dielectric_fresnel_of_formula_20():
    for degrees in (0, 20, 40, 60, 80):
        c = math.cos(math.radians(degrees))
        assert conductor_fresnel(c, 1.5, 0.0) == pytest.approx(fresnel(c, 1.0, 1.5), rel=1e-12)


def test_gold_and_copper_are_coloured_at_normal_incidence_and_white_at_grazing():
    gold = [conductor_fresnel(1.0, e, k) for e, k in zip(GOLD["eta"], GOLD["k"])]
    copper = [conductor_fresnel(1.0, e, k) for e, k in zip(COPPER["eta"], COPPER["k"])]
    assert gold == pytest.approx([0.9667, 0.8020, 0.3241], abs=5e-5)       # yellow: red and green, little blue
    assert copper == pytest.approx([0.9520, 0.6198, 0.5106], abs=5e-5)     # orange: red, less green and blue
    assert [conductor_fresnel(0.0, e, k) for e, k in zip(GOLD["eta"], GOLD["k"])] == [1.0, 1.0, 1.0]


# ---------------------------------------------------------------------------- the material

def test_material_k_and_eta_default_to_no_conductor():
    m = Material()
    assert m.k == (0.0, 0.0, 0.0) and m.eta is None and m.conductor_eta == (1.0, 1.0, 1.0)
    assert Material(ior=2.5, k=1).conductor_eta == (2.5, 2.5, 2.5) and Material(k=1).k == (1.0, 1.0, 1.0)


def test_bad_k_and_eta_are_named():
    with pytest.raises(ValueError, match=r"^Material\.k must hold numbers >= 0"):
        Material(k=(1.0, -1.0, 0.0))
    with pytest.raises(ValueError, match=r"^Material\.eta is the real part of a conductor's complex index η \+ ik, "
                                         r"> 0 in every channel, got \(0\.1, 0, 1\)"):
        Material(eta=(0.1, 0, 1))


def test_a_scene_file_sets_k_and_eta():
    text = ('[camera]\neye = [0, 0, 3]\n[materials.gold]\nkd = 0\nks = 0\nkr = 1\n'
            'eta = [0.143036, 0.375307, 1.44205]\nk = [3.983, 2.38556, 1.60336]\n'
            '[[meshes]]\nshape = "plane"\nmaterial = "gold"\n')
    m = parse_scene(text, "gold.toml").materials["gold"]
    assert m.eta == GOLD["eta"] and m.k == GOLD["k"] and m.kr == (1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match=r"^gold\.toml: key 'k' in \[materials\.gold\] must hold numbers >= 0, got float -3\.983 "):
        parse_scene(text.replace("k = [3.983", "k = [-3.983"), "gold.toml")


# ---------------------------------------------------------------------------- the path tracer

def mirror_under_sky(material, degrees=60.0, size=8):
    """A mirror plane (y = 0, facing +y) under a uniform white sky, seen at ``degrees`` from its normal by a
    narrow camera: every path is one mirror bounce into the sky, so a sample is kr·F at its angle."""
    a = math.radians(degrees)
    camera = Camera(eye=(0.0, 4.0 * math.cos(a), 4.0 * math.sin(a)), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                    fovy=1.0, near=0.01, far=50.0)
    scene = Scene(objects=[SceneObject("metal", shapes.plane(4.0, material=material), np.eye(4))], camera=camera,
                  width=size, height=size, background=(1.0, 1.0, 1.0, 1.0), lights=())
    return pathtrace(scene, spp=4, seed=7)


def test_the_path_tracer_weights_a_conductor_mirror_by_its_fresnel_reflectance_per_channel():
    gold = Material(kd=0.0, ks=0.0, kr=1.0, **GOLD)
    traced = mirror_under_sky(gold)
    assert traced.notes == []
    story = traced.path_story(3, 4)
    for path in story:
        first = path.bounces[0]
        assert first.lobe == "mirror" and path.bounces[1].end == "left the scene"
        c = first.direction[1]                   # N = +y: cos θ = N·R = N·V
        expected = tuple(fresnel_complex(c, e, k) for e, k in zip(GOLD["eta"], GOLD["k"]))
        assert first.f == pytest.approx(expected, rel=1e-12)
        assert path.value == pytest.approx(expected, rel=1e-12)   # the sky's radiance 1 times F
    c60 = math.cos(math.radians(60.0))
    at_60 = [fresnel_complex(c60, e, k) for e, k in zip(GOLD["eta"], GOLD["k"])]
    assert traced.image.mean(axis=(0, 1)) == pytest.approx(at_60, abs=2e-3)   # the 1° camera: angles 60 ± 0.5°


def test_kr_tints_a_conductor_and_a_material_without_k_stays_a_plain_mirror():
    half = mirror_under_sky(Material(kd=0.0, ks=0.0, kr=0.5, **COPPER))
    full = mirror_under_sky(Material(kd=0.0, ks=0.0, kr=1.0, **COPPER))
    assert np.allclose(half.image, 0.5 * full.image, rtol=1e-6)
    plain = mirror_under_sky(Material(kd=0.0, ks=0.0, kr=(0.9, 0.8, 0.7), eta=COPPER["eta"]))   # η without k
    assert np.array_equal(plain.image, np.broadcast_to(np.float32([0.9, 0.8, 0.7]), plain.image.shape))


def test_a_conductor_without_kr_is_noted():
    traced = mirror_under_sky(Material(kd=0.5, ks=0.0, **GOLD), size=2)
    assert traced.notes == ["metal: a conductor's k weights the mirror lobe kr by its Fresnel reflectance, but kr "
                            "is 0: set kr = 1 for a bare metal"]


def test_the_fresnel_reflectance_agrees_with_mitsubas_conductor():
    mi = pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed (pip install mitsuba)")
    mi.set_variant("scalar_rgb")
    for name, index in (("Au", GOLD), ("Cu", COPPER)):
        bsdf = mi.load_dict({"type": "conductor", "material": name})
        for degrees in (0.0, 30.0, 60.0, 80.0):
            a = math.radians(degrees)
            si = mi.SurfaceInteraction3f()
            si.n = si.sh_frame.n = mi.Vector3f(0, 0, 1)
            si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
            si.wi = mi.Vector3f(math.sin(a), 0.0, math.cos(a))
            _, weight = bsdf.sample(mi.BSDFContext(), si, 0.5, mi.Point2f(0.5, 0.5))
            ours = [conductor_fresnel(math.cos(a), e, k) for e, k in zip(index["eta"], index["k"])]
            assert [weight[0], weight[1], weight[2]] == pytest.approx(ours, rel=1e-5), (name, degrees)


@pytest.mark.parametrize("program", ["mirror", "phong", "hall"])
def test_the_whitted_tracer_weights_a_conductor_reflection_by_its_fresnel_reflectance_per_channel(program):
    """A gold plane seen at about 60° under a white background: the reflected ray's weight is kr·F_R(N·V) per
    channel, F_R the conductor's (FORMULAS §30) evaluated here with complex numbers at the ray's own angle."""
    from softpipe.tracers.whitted import ray_tree, raytrace_scene
    a = math.radians(60.0)
    camera = Camera(eye=(0.0, 4.0 * math.cos(a), 4.0 * math.sin(a)), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                    fovy=10.0, near=0.01, far=50.0)
    gold = Material(ka=0.0, kd=0.0, ks=0.0, kr=(1.0, 0.9, 0.8), **GOLD)
    scene = Scene(objects=[SceneObject("metal", shapes.plane(4.0, material=gold), np.eye(4), program=program)],
                  camera=camera, width=4, height=4, background=(1.0, 1.0, 1.0, 1.0), lights=())
    notes = []
    image = raytrace_scene(scene, notes=notes).color[..., :3]
    assert notes == []                                   # k is read: nothing to say about it
    for x, y in ((0, 0), (2, 1), (3, 3)):
        tree = ray_tree(scene, x, y)
        primary, reflected = tree[0], tree[1]
        assert primary.object == "metal" and reflected.kind == "reflected" and reflected.object == ""
        c = -primary.direction[1]                        # N = +y: cos θ = N·V
        expected = tuple(kr * fresnel_complex(c, e, k) for kr, e, k in zip(gold.kr, GOLD["eta"], GOLD["k"]))
        assert reflected.weight == pytest.approx(expected, rel=1e-12)
        assert tree.color[:3] == pytest.approx(expected, rel=1e-6)           # the white background times kr·F (float32)
        assert image[y, x] == pytest.approx(expected, rel=1e-6)                # row 0 the top, as ray_tree
    c60 = math.cos(a)
    assert image.mean(axis=(0, 1)) == pytest.approx(
        [kr * fresnel_complex(c60, e, k) for kr, e, k in zip(gold.kr, GOLD["eta"], GOLD["k"])], abs=5e-3)


def test_the_whitted_tracers_glass_program_says_it_does_not_read_k():
    from softpipe.tracers.whitted import raytrace_scene
    scene = Scene(objects=[SceneObject("metal", shapes.plane(4.0, material=Material(kr=1.0, **GOLD)), np.eye(4),
                                       program="glass")],
                  camera=Camera(eye=(0.0, 3.0, 1.0), target=(0.0, 0.0, 0.0)), width=4, height=4, lights=())
    notes = []
    raytrace_scene(scene, notes=notes)
    assert "metal: the glass program's reflection is §20's dielectric Fresnel into ior; the conductor's k " \
           "(FORMULAS §30) is not read by it" in notes
