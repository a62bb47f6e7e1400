"""A planar mirror by the stencil buffer (issue 30's first recipe, docs/planar-mirror.md): the reflection
matrix, the four passes, the clip plane at the mirror, agreement with the ray tracer (FORMULAS §10, §13,
§16, §21), and the errors for a mirror that is not one."""
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.transforms import translate
from softpipe.scenes import planar_mirror, shapes
from softpipe.scenes.drawing import draw_mesh, render_scene
from softpipe.scenes.planar_mirror import clip_plane, find_mirror, reflection_matrix, render_planar_mirror
from softpipe.scenes.scene import SceneObject
from softpipe.tracers.whitted import raytrace_scene

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def example():
    """examples/planar_mirror.py: the scene of docs/planar-mirror.md and its edge band."""
    sys.path.insert(0, str(EXAMPLES))
    try:
        import planar_mirror as module
        yield module
    finally:
        sys.path.remove(str(EXAMPLES))


@pytest.fixture(scope="module")
def small(example):
    return example.scene((64, 48))


# ------------------------------------------------------------------ the reflection and the clip plane


@pytest.mark.parametrize("normal, offset", [((0, 0, 1), -1.5), ((0, 2, 0), 1.0), ((1, -2, 0.5), 0.3)])
def test_a_point_and_its_image_are_equidistant_from_the_plane_and_det_is_minus_one(normal, offset):
    m = reflection_matrix(normal, offset)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    d = offset / np.linalg.norm(normal)
    points = np.random.default_rng(1).uniform(-3, 3, (20, 3))
    images = points @ m[:3, :3].T + m[:3, 3]
    assert np.allclose(images @ n - d, -(points @ n - d))                # same distance, the other side
    assert np.allclose(np.cross(images - points, n), 0.0)                # along the normal
    assert np.isclose(np.linalg.det(m), -1.0)
    assert np.allclose(m @ m, np.eye(4))                                 # twice is nothing
    on_plane = points - np.outer(points @ n - d, n)
    assert np.allclose(on_plane @ m[:3, :3].T + m[:3, 3], on_plane)      # the plane stays


def test_a_zero_normal_is_refused():
    with pytest.raises(ValueError, match=r"the plane's normal must be a non-zero 3-vector, got \(0, 0, 0\)"):
        reflection_matrix((0, 0, 0), 1.0)


def test_the_clip_plane_keeps_in_clip_space_what_the_world_plane_keeps(small):
    camera = small.camera
    vp = camera.projection(small.width / small.height) @ camera.view
    world = np.array([0.0, 0.0, -1.0, -1.5])                              # kept: z ≤ -1.5, behind the mirror
    plane = np.array(clip_plane(world, vp))
    points = np.c_[np.random.default_rng(2).uniform(-4, 4, (50, 3)), np.ones(50)]
    assert np.allclose((points @ vp.T) @ plane, points @ world)


# ------------------------------------------------------------------ the passes


def test_the_stencil_marks_exactly_the_mirrors_pixels(small):
    fb = render_planar_mirror(small)
    alone = Framebuffer(small.width, small.height).clear(small.background)
    mirror = small.objects[0]
    draw_mesh(alone, mirror.mesh, small.camera, "phong", model=mirror.model, cull="back")
    covered = alone.depth < 1.0
    assert covered.sum() > 0.3 * covered.size
    assert np.array_equal(fb.stencil, covered.astype(np.uint8))


def test_nothing_of_the_reflection_is_drawn_outside_the_mirror(small):
    fb = render_planar_mirror(small)
    without = render_scene(small.replace(objects=small.objects[1:]))
    outside = fb.stencil == 0
    got, want = fb.to_uint8(alpha=False), without.to_uint8(alpha=False)
    assert np.array_equal(got[outside], want[outside])
    assert not np.array_equal(got[~outside], want[~outside])              # inside, the mirror is there


def test_an_object_behind_the_mirror_does_not_appear_in_it(small, monkeypatch):
    # a ball behind the wall (z = -1.5), hidden by it: its image would be in front, in the mirror's view
    hidden = SceneObject("hidden", shapes.uv_sphere(0.5, 24, 12, material=Material(ke=(0.1, 0.9, 0.1))),
                         translate(0.0, 1.0, -2.2))
    with_hidden = small.replace(objects=[*small.objects, hidden])
    plain = render_planar_mirror(small).to_uint8(alpha=False)
    assert np.array_equal(render_planar_mirror(with_hidden).to_uint8(alpha=False), plain)
    # without the clip plane at the mirror, it would be seen in it: the test can fail
    monkeypatch.setattr(planar_mirror, "clip_plane", lambda world, vp: (0.0, 0.0, 0.0, 1.0))
    unclipped = render_planar_mirror(with_hidden).to_uint8(alpha=False)
    assert (np.abs(unclipped.astype(int) - plain).max(axis=-1) > 40).sum() > 20


def test_the_steps_are_the_four_passes(small):
    steps = {}
    fb = render_planar_mirror(small, steps=steps)
    assert list(steps) == ["stencil", "reflection", "mirror", "scene"]
    assert np.array_equal(steps["stencil"], fb.stencil)
    outside = fb.stencil == 0
    background = np.round(np.array(small.background[:3]) * 255)
    assert (steps["reflection"][outside] == background).all()             # pass 2 wrote only inside
    assert np.array_equal(steps["scene"], fb.to_uint8(alpha=False))


def test_the_stencil_mirror_agrees_with_the_ray_tracer_except_on_the_edge_band(example):
    """The figures of docs/planar-mirror.md, 160 × 120: of the 5921 mirror pixels, 14 differ from the
    ray tracer by more than 1/255 (at most 13/255), all but 1 (3/255) within a pixel of the mirror's
    outline or a silhouette (the edge band, 1212 pixels)."""
    scene = example.scene((160, 120))
    steps = {}
    ours = render_planar_mirror(scene, steps=steps).to_uint8(alpha=False).astype(int)
    traced = raytrace_scene(scene).to_uint8(alpha=False).astype(int)
    inside = steps["stencil"] == 1
    band = example.edge_band(scene, steps["stencil"])
    d = np.abs(ours - traced).max(axis=-1)
    assert inside.sum() == 5921 and (inside & band).sum() == 1212
    assert (d[inside] > 1).sum() == 14 and d[inside].max() == 13
    assert (d[inside & ~band] > 1).sum() == 1 and d[inside & ~band].max() == 3


# ------------------------------------------------------------------ bad mirrors


def test_a_curved_mirror_is_refused_naming_it_and_how_far_off_plane(small):
    ball = dataclasses.replace(small.objects[1], program="mirror",
                               mesh=small.objects[1].mesh.replace(material=Material(kr=(0.9, 0.9, 0.9))))
    scene = small.replace(objects=[small.objects[0], ball, *small.objects[2:]])
    with pytest.raises(ValueError, match=r"mirror 'red ball' is not planar: its vertices are up to 0\.5 off "
                                         r"their best-fit plane \(the limit is MIRROR_FLATNESS = 1e-06 × its size 1\.73\)"):
        render_planar_mirror(scene, mirror="red ball")
    with pytest.raises(ValueError, match=r"2 objects are \('mirror', 'red ball'\) drawn with program 'mirror'; "
                                         r"name the planar mirror: render_planar_mirror\(scene, mirror='name'\)"):
        render_planar_mirror(scene)


def test_a_scene_without_a_mirror_or_with_an_unknown_name_is_refused(small):
    plain = small.replace(objects=small.objects[1:])
    with pytest.raises(ValueError, match=r"no object is drawn with program 'mirror'; name the planar mirror"):
        render_planar_mirror(plain)
    with pytest.raises(ValueError, match=r"no object is named 'glass' \(the objects: 'mirror', 'red ball', "
                                         r"'blue ball', 'gold ring'\)"):
        render_planar_mirror(small, mirror="glass")


def test_a_mirror_that_reflects_nothing_or_is_seen_edge_on_is_refused(small):
    dull = dataclasses.replace(small.objects[0], mesh=small.objects[0].mesh.replace(material=Material()))
    with pytest.raises(ValueError, match=r"mirror 'mirror': its material's kr is \(0\.0, 0\.0, 0\.0\): it reflects "
                                         r"nothing \(FORMULAS §13's k_r\); give the material kr > 0"):
        render_planar_mirror(small.replace(objects=[dull, *small.objects[1:]]))
    edge_on = small.camera.replace(eye=(3.0, 1.0, -1.5), target=(0.0, 1.0, -1.5))
    with pytest.raises(ValueError, match=r"mirror 'mirror': the camera's eye \(3\.0, 1\.0, -1\.5\) is in the "
                                         r"mirror's plane: it is seen edge-on"):
        render_planar_mirror(small, edge_on)


def test_the_plane_faces_the_camera_and_is_the_walls(small):
    _, plane = find_mirror(small, small.camera)
    assert np.allclose(plane.normal, (0.0, 0.0, 1.0)) and np.isclose(plane.offset, -1.5)
    behind = small.camera.replace(eye=(0.5, 1.0, -6.0))
    _, seen_from_behind = find_mirror(small, behind)
    assert np.allclose(seen_from_behind.normal, (0.0, 0.0, -1.0)) and np.isclose(seen_from_behind.offset, 1.5)
