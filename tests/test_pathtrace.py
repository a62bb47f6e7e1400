"""The path tracer (softpipe.tracers.pathtrace): analytic answers, determinism, progressive rendering, errors, CLI.

Mitsuba's Cornell box is in test_pathtrace_mitsuba.py.
"""
from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np
import pytest
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import compose, rotate_x, scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.scenes.scenefile import load_scene
from softpipe.tracers.pathtrace import MAX_SPP, pathtrace

CORNELL = Path(__file__).resolve().parent.parent / "examples" / "cornell_box.toml"
BLACK = (0.0, 0.0, 0.0, 1.0)
LAMP = Material(ke=(2.0, 1.0, 0.5), kd=0.0, ks=0.0, name="lamp")


def scene_of(*objects, camera, size=16, background=BLACK) -> Scene:
    return Scene(objects=[SceneObject(name, mesh, model) for name, mesh, model in objects], camera=camera,
                 width=size, height=size, background=background, lights=())


def looking_down(height=3.0):
    """A narrow camera above the origin looking down -y (what it sees at y = 0 is within ±0.27 of the axis)."""
    return Camera(eye=(0.0, height, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fovy=10.0, near=0.01, far=50.0)


@pytest.fixture(scope="module")
def box():
    """Mitsuba's Cornell box (examples/cornell_box.toml) at 24×24: light, shadows, colour bleeding."""
    return load_scene(CORNELL).replace(width=24, height=24)


# ---------------------------------------------------------------------------- analytic answers

def test_an_emissive_quad_seen_directly_is_its_radiance_in_every_pixel():
    scene = scene_of(("lamp", shapes.plane(2.0, material=LAMP), np.eye(4)), camera=looking_down())
    traced = pathtrace(scene, spp=4, seed=3)
    assert traced.image.shape == (16, 16, 3) and traced.image.dtype == np.float32
    assert np.array_equal(traced.image, np.broadcast_to(np.float32([2.0, 1.0, 0.5]), (16, 16, 3)))
    assert np.array_equal(traced.variance, np.zeros((16, 16, 3), np.float32))    # every sample the same


def test_an_emissive_quad_emits_from_its_front_only():
    below = Camera(eye=(0.0, -3.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fovy=10.0, near=0.01, far=50.0)
    traced = pathtrace(scene_of(("lamp", shapes.plane(2.0, material=LAMP), np.eye(4)), camera=below), spp=2)
    assert np.array_equal(traced.image, np.zeros((16, 16, 3), np.float32))


def test_the_background_is_a_uniform_sky_that_lights_the_scene():
    """Under a sky of radiance B from every direction, a Lambert plane of albedo a facing it reflects exactly
    a·B: every cosine-drawn direction escapes to the sky, each with weight kd/p = a. Beside it, the sky itself."""
    sky = (0.4, 0.6, 0.8, 1.0)
    matte = Material(kd=0.5, ks=0.0, name="matte")
    scene = scene_of(("floor", shapes.plane(2.0, material=matte), np.eye(4)), camera=looking_down(), background=sky)
    traced = pathtrace(scene, spp=8)
    assert np.array_equal(traced.image, np.broadcast_to(np.float32([0.2, 0.3, 0.4]), (16, 16, 3)))
    aside = pathtrace(scene.replace(camera=Camera(eye=(0.0, 3.0, 0.0), target=(0.0, 3.0, -1.0), near=0.01)), spp=2)
    assert np.array_equal(aside.image, np.broadcast_to(np.float32([0.4, 0.6, 0.8]), (16, 16, 3)))


def test_a_mirror_shows_the_lamp_times_kr():
    mirror = Material(kd=0.0, ks=0.0, kr=(0.5, 0.25, 1.0), name="mirror")
    lamp_above = compose(translate(0.0, 5.0, 0.0), rotate_x(180.0))           # facing down, behind the eye
    scene = scene_of(("mirror", shapes.plane(4.0, material=mirror), np.eye(4)),
                     ("lamp", shapes.plane(8.0, material=LAMP), lamp_above), camera=looking_down())
    traced = pathtrace(scene, spp=4)
    assert np.array_equal(traced.image, np.broadcast_to(np.float32([1.0, 0.25, 0.5]), (16, 16, 3)))


def test_a_glass_slab_passes_the_fresnel_share():
    """Seen through a slab of glass (ior 1.5) at near-normal incidence, a lamp's radiance is multiplied by
    Σ (1 − F)² F^(2k) = (1 − F)/(1 + F), F = ((1.5 − 1)/(1.5 + 1))² = 0.04 (FORMULAS §20): 0.923."""
    glass = Material(kd=0.0, ks=0.0, kt=1.0, ior=1.5, name="glass")
    lamp_below = translate(0.0, -3.0, 0.0)                                      # facing up, toward the slab
    scene = scene_of(("slab", shapes.cube(2.0, material=glass), scale(3.0, 0.1, 3.0)),
                     ("lamp", shapes.plane(8.0, material=LAMP), lamp_below), camera=looking_down(), size=32)
    traced = pathtrace(scene, spp=64, seed=1)
    f = ((1.5 - 1.0) / 2.5) ** 2
    share = traced.image.reshape(-1, 3).mean(0) / np.float32([2.0, 1.0, 0.5])
    # each sample brings back the lamp or nothing: a Bernoulli share, standard error ≈ 0.001 over 65 536 samples
    assert np.allclose(share, (1 - f) / (1 + f), atol=0.005), share


def inward_sphere(material) -> Mesh:
    """A closed icosphere whose front faces (and flat normals) face its inside: every triangle its own corners."""
    sphere = shapes.icosphere(1.0, subdivisions=2)
    corners = sphere.positions[sphere.indices.reshape(-1, 3)[:, ::-1]]          # reversed winding
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", n, corners.mean(axis=1)) < 0)             # toward the centre
    return Mesh(corners.reshape(-1, 3), np.arange(len(corners) * 3).reshape(-1, 3),
                normals=np.repeat(n, 3, axis=0), material=material)


def test_furnace_a_closed_emitting_diffuse_sphere_has_radiance_le_over_one_minus_albedo():
    """Inside a closed surface that emits Le and reflects a share a (Lambert) everywhere, the radiance is the
    same in every direction and L = Le + a·L: L = Le/(1 − a). Here Le = (1, 0.5, 0.25), a = (0.5, 0.8, 0.2):
    L = (2, 2.5, 0.3125), with next-event estimation, MIS and Russian roulette all at work."""
    le, a = np.array([1.0, 0.5, 0.25]), np.array([0.5, 0.8, 0.2])
    m = Material(ke=tuple(le), kd=tuple(a), ks=0.0, name="furnace")
    inside = Camera(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fovy=60.0, near=0.01, far=10.0)
    traced = pathtrace(scene_of(("sphere", inward_sphere(m), np.eye(4)), camera=inside), spp=128, seed=5)
    expected = le / (1 - a)
    mean = traced.image.reshape(-1, 3).mean(0)
    se = np.sqrt(traced.variance.reshape(-1, 3).sum(0)) / 256
    assert np.all(np.abs(mean - expected) < 5 * se + 1e-6), (mean, expected, se)
    assert np.all(np.abs(mean / expected - 1) < 0.01), (mean, expected)


# ---------------------------------------------------------------------------- determinism and progress

def test_same_seed_same_bytes_other_seed_other_image(box):
    one = pathtrace(box, spp=4, seed=7).image
    assert one.tobytes() == pathtrace(box, spp=4, seed=7).image.tobytes()
    assert not np.array_equal(one, pathtrace(box, spp=4, seed=8).image)
    assert (one > 0).mean() > 0.9                  # the box is lit: the test compares pictures, not black frames


def test_the_image_is_the_same_bytes_on_one_and_two_threads(box):
    before = numba.get_num_threads()
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here (NUMBA_NUM_THREADS=1)")
    try:
        numba.set_num_threads(1)
        one = pathtrace(box, spp=4, seed=2)
        numba.set_num_threads(2)
        two = pathtrace(box, spp=4, seed=2)
    finally:
        numba.set_num_threads(before)
    assert one.image.tobytes() == two.image.tobytes()
    assert one.variance.tobytes() == two.variance.tobytes()


def test_progressive_n_then_more_is_the_same_bytes_as_all_at_once(box):
    # 40 samples are three passes of PASS_SPP (16) at once, and other splits when added in parts
    small = box.replace(width=12, height=12)
    whole = pathtrace(small, spp=40, seed=4)
    for first in (1, 16, 17, 20):
        parts = pathtrace(small, spp=first, seed=4)
        assert parts.spp == first
        parts.add(40 - first)
        assert parts.spp == 40
        assert parts.image.tobytes() == whole.image.tobytes()
        assert parts.variance.tobytes() == whole.variance.tobytes()


def test_variance_is_the_variance_of_the_pixel_mean(box):
    """Over 30 independent renders (seeds) of 8 samples, each pixel's mean has an empirical variance; the
    renders' ``variance`` (s²/n), averaged over the renders, estimates it. Their ratio's median over the pixels
    is near 1 (a mean over the pixels is not a good figure: a rare bright path in one pixel moves it far)."""
    small = box.replace(width=12, height=12)
    renders = [pathtrace(small, spp=8, seed=100 + k) for k in range(30)]
    images = np.array([r.image for r in renders], np.float64)
    estimated = np.array([r.variance for r in renders], np.float64).mean(axis=0)
    empirical = images.var(axis=0, ddof=1)
    lit = estimated > 0
    ratio = np.median(empirical[lit] / estimated[lit])
    assert lit.mean() > 0.9 and 0.8 < ratio < 1.25, ratio
    assert np.all(np.isinf(pathtrace(small, spp=1).variance))                # one sample: no estimate


# ---------------------------------------------------------------------------- errors, notes, output

@pytest.mark.parametrize("kw, message", [
    ({"spp": 0}, f"pathtrace: spp must be a whole number 1…{MAX_SPP}, got 0"),
    ({"spp": 2.5}, f"pathtrace: spp must be a whole number 1…{MAX_SPP}, got 2.5"),
    ({"seed": -1}, "pathtrace: seed must be a whole number 0…18446744073709551615, got -1"),
    ({"max_depth": -2}, "pathtrace: max_depth must be a whole number ≥ -1, got -2"),
    ({"rr_depth": 0}, "pathtrace: rr_depth must be a whole number ≥ 1, got 0"),
])
def test_bad_arguments_are_named(kw, message):
    scene = scene_of(("lamp", shapes.plane(2.0, material=LAMP), np.eye(4)), camera=looking_down())
    with pytest.raises(ValueError) as e:
        pathtrace(scene, **kw)
    assert str(e.value) == message


def test_notes_say_what_the_path_tracer_leaves_out(box):
    notes = pathtrace(box, spp=1).notes
    assert notes == ["the scene's point, directional and spot lights have no area and do not light the path "
                     "tracer's image: only emissive surfaces (material ke) and the background do"]
    shiny = Material(ks=0.5, name="shiny")
    scene = scene_of(("ball", shapes.icosphere(1.0, 1, material=shiny), np.eye(4)), camera=looking_down())
    assert pathtrace(scene, spp=1).notes == [       # ks is a Blinn-Phong lobe now (test_pathtrace_lobes.py)
        "nothing emits light (no material has ke and the background is black): the image is black"]
    dull = [SceneObject("ball", shapes.icosphere(1.0, 1, material=shiny), np.eye(4), program="cook_torrance")]
    assert pathtrace(scene.replace(objects=dull), spp=1).notes[0] == \
        "ball: Cook-Torrance with ior 1 reflects nothing (Fresnel's F is 0): its ks lobe is black"


def test_the_top_level_api_and_the_framebuffer(box, tmp_path):
    traced = sp.pathtrace(box, spp=2, seed=1)
    assert isinstance(traced, sp.PathTrace)
    fb = traced.framebuffer()
    assert np.array_equal(fb.color[..., :3], traced.image) and np.all(fb.color[..., 3] == 1.0)
    traced.save(tmp_path / "box.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "box.png")), fb.to_uint8(alpha=False))


def test_cli_pathtrace_writes_the_same_picture_as_python(box, capsys, tmp_path):
    scene = CORNELL
    out = tmp_path / "box.png"
    code, stdout, err = run_cli(capsys, "render", scene, "--pathtrace", "--spp", "3", "--seed", "9", "--size",
                                "24x24", "-o", out)
    assert code == 0, err
    assert "path traced, 3 samples per pixel, seed 9" in stdout
    assert "point, directional and spot lights have no area" in err
    expected = sp.pathtrace(box, spp=3, seed=9).framebuffer().to_uint8(alpha=False)
    assert np.array_equal(np.asarray(Image.open(out)), expected)


def test_cli_background_light_writes_the_same_picture_as_python(capsys, tmp_path):
    """``--background-light`` is ``pathtrace(..., background_light=True)``: the same bytes. The box is opened to a
    grey sky (Mitsuba's has none, and with no sky the light sample never goes there), so the flag changes them."""
    scene = tmp_path / "sky_box.toml"
    scene.write_text(CORNELL.read_text().replace("background = [0.0, 0.0, 0.0]", "background = [0.6, 0.7, 0.8]"))
    out = tmp_path / "box.png"
    code, stdout, err = run_cli(capsys, "render", scene, "--pathtrace", "--background-light", "--spp", "2", "--seed",
                                "4", "--size", "16x16", "-o", out)
    assert code == 0, err
    assert "path traced, 2 samples per pixel, seed 4, the background sampled as a light, " in stdout
    sky_box = load_scene(scene).replace(width=16, height=16)
    expected = sp.pathtrace(sky_box, spp=2, seed=4, background_light=True).framebuffer().to_uint8(alpha=False)
    assert np.array_equal(np.asarray(Image.open(out)), expected)
    without = sp.pathtrace(sky_box, spp=2, seed=4).framebuffer().to_uint8(alpha=False)
    assert not np.array_equal(expected, without)


@pytest.mark.parametrize("argv, message", [
    (["--spp", "4"], "--spp applies only with --pathtrace"),
    (["--background-light"], "--background-light applies only with --pathtrace"),
    (["--pathtrace", "--raytrace"], "--pathtrace renders by paths; it does not apply with --raytrace"),
    (["--pathtrace", "--spp", "0"], "expected a positive number of samples per pixel, got 0"),
    (["--pathtrace", "--seed", "-3"], "expected a whole number from 0 to 2**64 - 1, got -3"),
    (["--pathtrace", "--samples", "grid16"], "--samples picks the rasterizer's and the ray tracer's sample pattern; "
     "it does not apply with --pathtrace, whose samples are jittered over each pixel (a box filter): use --spp N for "
     "its samples per pixel"),
    (["--pathtrace", "--msaa"], "--msaa is the rasterizer's multisampling; it does not apply with --pathtrace (use "
     "--spp N for the path tracer's samples per pixel)"),
])
def test_cli_pathtrace_option_errors(argv, message, capsys, tmp_path):
    scene = CORNELL
    code, _, err = run_cli(capsys, "render", scene, *argv, "--size", "8x8", "-o", tmp_path / "x.png")
    assert code != 0 and message in err, err
    assert not (tmp_path / "x.png").exists()


def test_mean_of_many_samples_converges():
    """The error of the image mean falls as 1/√spp: 16× the samples, about a quarter of the standard error."""
    le, a = np.array([1.0, 1.0, 1.0]), np.array([0.5, 0.5, 0.5])
    m = Material(ke=tuple(le), kd=tuple(a), ks=0.0, name="furnace")
    inside = Camera(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fovy=60.0, near=0.01, far=10.0)
    scene = scene_of(("sphere", inward_sphere(m), np.eye(4)), camera=inside, size=8)
    few, many = pathtrace(scene, spp=4), pathtrace(scene, spp=64)
    se_few = math.sqrt(few.variance.sum()) / few.variance.size
    se_many = math.sqrt(many.variance.sum()) / many.variance.size
    assert 0.15 < se_many / se_few < 0.4, (se_few, se_many)
