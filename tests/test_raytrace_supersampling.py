"""Supersampling in the Whitted tracer (FORMULAS §23, §24): the rasterizer's sample patterns, and adaptive.

The expected images are made here from the tracer's own samples: one primary ray per sample through the same
code (:func:`raytrace_samples`), the pixel their mean summed in the pattern's order; adaptive supersampling at
its two ends is full supersampling on the 2^depth grid (threshold 0) and the one-sample image (a huge threshold).
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.pipeline.sampling import CENTER, SamplePattern, grid, pattern_named
from softpipe.pipeline.transforms import rotate_z, translate
from softpipe.scenes import shapes
from softpipe.scenes.drawing import prepare_scene
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tools.cli import main
from softpipe.tracers.whitted import ray_tree, raytrace_samples, raytrace_scene

MIRROR = Material(ka=0.0, kd=0.0, ks=0.0, kr=(0.9, 0.8, 0.7))
GLASS = Material(ka=0.0, kd=0.0, ks=0.0, kt=(0.9, 0.9, 0.9), ior=1.5)


def spheres(width=24, height=16) -> Scene:
    """A mirror and a glass ball on a floor under the sun: edges, reflections, refractions and a shadow."""
    floor = shapes.plane(8.0, material=Material(kd=(0.6, 0.6, 0.6), ks=0.0))
    return Scene([SceneObject("floor", floor, np.eye(4)),
                  SceneObject("mirror", shapes.uv_sphere(0.8, 16, 8, material=MIRROR), translate(-1.0, 0.8, 0.0)),
                  SceneObject("glass", shapes.uv_sphere(0.8, 16, 8, material=GLASS), translate(1.0, 0.8, 0.0))],
                 camera=sp.Camera(eye=(0.0, 1.5, 5.0), target=(0.0, 0.7, 0.0), fovy=40.0),
                 lights=(Light.directional((0.3, -1.0, -0.4), name="sun"),), width=width, height=height)


WHITE = Material(ke=(1.0, 1.0, 1.0), ka=0.0, kd=0.0, ks=0.0)


def white_square(width=16, height=16) -> Scene:
    """A white square (emission only) turned 20° on a black background, facing the camera: every pixel is 0 or 1
    but on its silhouette."""
    square = shapes.plane(2.0, material=WHITE)
    stand_up = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])     # +y → +z
    return Scene([SceneObject("square", square, rotate_z(20.0) @ stand_up)],
                 camera=sp.Camera(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fovy=40.0), lights=(),
                 ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0, 1.0), width=width, height=height)


def _mean_in_order(samples: np.ndarray) -> np.ndarray:
    """Σ over the samples in the pattern's order, then ÷ S, in float64, stored as float32 (the tracer's steps)."""
    total = np.zeros(samples.shape[:2] + (3,))
    for s in range(samples.shape[2]):
        total = total + samples[:, :, s]
    return (total / samples.shape[2]).astype(np.float32)


def test_one_sample_at_the_centre_is_the_one_ray_image():
    """samples "1", CENTER or a scene whose samples are "1": one ray through the centre (§23), the same bytes,
    and the pixel's ray tree (the centre's) adds up to it."""
    scene = spheres()
    plain = raytrace_scene(scene).color
    for samples in ("1", CENTER, SamplePattern([(0.5, 0.5)])):
        assert raytrace_scene(scene, samples=samples).color.tobytes() == plain.tobytes()
    assert raytrace_scene(scene.replace(samples="grid4"), samples="1").color.tobytes() == plain.tobytes()
    t = ray_tree(scene, 7, 9)
    np.testing.assert_array_equal(np.float32(np.sum([np.multiply(n.weight, n.local) for n in t], axis=0)),
                                  plain[9, 7, :3])


@pytest.mark.parametrize("name", ["grid4", "rgss4", "random3"])
def test_a_patterns_image_is_the_mean_of_its_single_sample_images(name):
    """One primary ray per sample through the same code: each sample alone (a one-sample pattern at its offset)
    renders the tracer's sample exactly, and the pattern's pixel is their mean in the pattern's order (a box
    filter). The scene's samples are used when none are given."""
    scene = spheres()
    pattern = pattern_named(name)
    samples = raytrace_samples(scene, pattern)
    assert samples.shape == (scene.height, scene.width, len(pattern), 3)
    for s, position in enumerate(pattern.positions):
        alone = raytrace_scene(scene, samples=SamplePattern([position])).color
        np.testing.assert_array_equal(alone[..., :3], samples[:, :, s].astype(np.float32))
        assert np.all(alone[..., 3] == 1.0)
    whole = raytrace_scene(scene, samples=pattern).color
    np.testing.assert_array_equal(whole[..., :3], _mean_in_order(samples))
    assert raytrace_scene(scene.replace(samples=name)).color.tobytes() == whole.tobytes()
    assert not np.array_equal(whole, raytrace_scene(scene).color)        # the samples are not ignored


@pytest.mark.parametrize("depth", [1, 2])
def test_adaptive_with_threshold_zero_is_full_supersampling_at_its_depth(depth):
    """Threshold 0 splits every cell down to ``depth``: the pixel is the 2^depth × 2^depth grid of §24, the same
    bytes as samples=grid(2^depth); every level's rays are traced (1 + 4 + … per pixel)."""
    scene = spheres()
    timings: dict = {}
    adaptive = raytrace_scene(scene, adaptive=True, threshold=0.0, adaptive_depth=depth, timings=timings)
    full = raytrace_scene(scene, samples=grid(1 << depth)).color
    assert adaptive.color.tobytes() == full.tobytes()
    assert timings["rays"] == scene.width * scene.height * sum(4 ** k for k in range(depth + 1))


def test_adaptive_with_a_huge_threshold_or_depth_zero_is_the_centre_only_image():
    scene = spheres()
    plain = raytrace_scene(scene).color.tobytes()
    timings: dict = {}
    assert raytrace_scene(scene, adaptive=True, threshold=1e9, timings=timings).color.tobytes() == plain
    assert timings["rays"] == scene.width * scene.height
    assert raytrace_scene(scene, adaptive=True, adaptive_depth=0, threshold=0.0).color.tobytes() == plain


def test_a_silhouette_pixel_is_antialiased_and_adaptive_refines_only_there():
    """One ray per pixel: the white square's pixels are 0 or 1. With grid16 a pixel on its silhouette is
    between (its share of the square, to 1/16); adaptively, only pixels by the edge get more rays, and most of
    those pixels are between too (a cell whose samples agree is not split, so an edge that clips a corner
    between them is missed: the adaptive scheme's known limit), none elsewhere."""
    scene = white_square()
    one = raytrace_scene(scene).color[..., 0]
    assert set(np.unique(one)) == {0.0, 1.0}
    full = raytrace_scene(scene, samples="grid16").color[..., 0]
    between = (full > 0.0) & (full < 1.0)
    assert between.sum() >= scene.width                     # an edge crosses the picture several times
    assert set(np.unique(np.round(full * 16, 6))) <= set(range(17))
    timings: dict = {}
    adaptive = raytrace_scene(scene, adaptive=True, timings=timings).color[..., 0]
    assert scene.width * scene.height < timings["rays"] < 0.5 * scene.width * scene.height * 21
    smooth = (adaptive > 0.0) & (adaptive < 1.0)
    assert smooth.sum() >= between.sum() / 2 and not np.any(smooth & ~between)    # on the silhouette only
    assert np.abs(adaptive - full).mean() < 0.5 * np.abs(one - full).mean()       # nearer grid16 than one ray
    interior = (one == full) & ~between                      # away from the edge: the same as one ray
    np.testing.assert_array_equal(adaptive[interior], one[interior])


def test_supersampling_is_the_same_bytes_on_one_thread_and_two():
    scene = spheres()
    before = numba.get_num_threads()
    pictures = []
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            pictures.append((raytrace_scene(scene, samples="rgss4").color.tobytes(),
                             raytrace_scene(scene, adaptive=True).color.tobytes()))
    finally:
        numba.set_num_threads(before)
    assert pictures[0] == pictures[1]


@pytest.mark.parametrize("kwargs, message", [
    (dict(samples="grid5"), "grid needs a square number of samples, got 5"),
    (dict(samples="nine"), "unknown sample pattern 'nine'"),
    (dict(samples=4), "samples must be a sample pattern's name"),
    (dict(adaptive=True, samples="grid4"), "samples does not apply with adaptive=True"),
    (dict(threshold=0.2), "threshold applies only with adaptive=True"),
    (dict(adaptive_depth=1), "adaptive_depth applies only with adaptive=True"),
    (dict(adaptive=True, threshold=-0.1), "threshold must be a number ≥ 0"),
    (dict(adaptive=True, adaptive_depth=4), "adaptive_depth must be an integer in 0…3, got 4"),
    (dict(adaptive="yes"), "adaptive must be True or False"),
])
def test_options_that_do_not_apply_are_refused_by_name(kwargs, message):
    with pytest.raises(ValueError, match=message):
        raytrace_scene(spheres(4, 4), **kwargs)


def test_the_scenes_multisampling_is_the_rasterizers_and_says_so():
    notes: list = []
    raytrace_scene(spheres(4, 4).replace(samples="rgss4", sample_shading="center"), notes=notes)
    assert "sample_shading 'center' (multisampling) is the rasterizer's: the ray tracer traces and shades each " \
           "of the 4 samples" in notes


def test_supersampling_on_the_command_line(tmp_path, capsys):
    """--raytrace --samples grid4 writes raytrace_scene(scene, samples "grid4")'s picture and says how many
    samples; --adaptive says how many rays per pixel; options that do not apply are refused, nothing written."""
    out = tmp_path / "t.png"
    assert main(["render", "suzanne", "--raytrace", "--samples", "grid4", "--size", "24x16", "-o", str(out)]) == 0
    assert "ray traced, 4 samples per pixel (grid 2x2)" in capsys.readouterr().out
    expected = tmp_path / "e.png"
    raytrace_scene(prepare_scene("suzanne", width=24, height=16, samples="grid4")).save(expected)
    assert out.read_bytes() == expected.read_bytes()
    assert main(["render", "suzanne", "--raytrace", "--adaptive", "--threshold", "0", "--adaptive-depth", "1",
                 "--size", "24x16", "-o", str(out)]) == 0
    assert "ray traced, adaptive: 5.00 rays per pixel" in capsys.readouterr().out
    raytrace_scene(prepare_scene("suzanne", width=24, height=16, samples="grid4")).save(expected)
    assert out.read_bytes() == expected.read_bytes()          # threshold 0, depth 1: the 2×2 grid
    refused = [(["--adaptive"], "--adaptive applies only with --raytrace"),
               (["--raytrace", "--adaptive", "--samples", "grid4"], "--adaptive chooses its own samples"),
               (["--raytrace", "--threshold", "0.2"], "--threshold applies only with --adaptive"),
               (["--raytrace", "--adaptive-depth", "1"], "--adaptive-depth applies only with --adaptive"),
               (["--raytrace", "--msaa"], "--msaa shades once per pixel and triangle (the rasterizer's "
                                          "multisampling); it does not apply with --raytrace"),
               (["--raytrace", "--adaptive", "--adaptive-depth", "4"], "expected a whole number from 0 to 3"),
               (["--raytrace", "--adaptive", "--threshold", "-1"], "expected a number ≥ 0")]
    for options, message in refused:
        fresh = tmp_path / "never.png"
        assert main(["render", "suzanne", *options, "--size", "8x8", "-o", str(fresh)]) == 2
        assert message in capsys.readouterr().err
        assert not fresh.exists()
