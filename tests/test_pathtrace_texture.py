"""Textures in the path tracer: kd from the object's texture at the hit's uv, as the rasterizer's ``textured`` program.

A Lambert plane under a uniform sky of radiance 1 and nothing else reflects exactly its albedo: every path
escapes after one bounce (the light sample and the drawn direction both find the sky, their MIS weights summing
to 1), so each sample's value is kd at the point its ray hit, and the test compares it with
:meth:`~softpipe.light.texture.Texture2D.sample` — the rasterizer's own lookup code — at the same uv.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.light.texture import Texture2D
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.pathtrace import pathtrace

SKY = (1.0, 1.0, 1.0, 1.0)


def image(seed=0, size=(8, 8)):
    return np.random.default_rng(seed).uniform(0.05, 1.0, (*size, 4)).astype(np.float32)


def textured_plane(texture, kd=(1.0, 0.8, 0.6), program="textured", size=12, background=SKY, lamp=False):
    """A plane of side 2 at y = 0 (u = (x + 1)/2, v = (1 − z)/2), seen from above by a camera that fills the frame
    with it, under a sky (and, with ``lamp``, a small emissive quad above it)."""
    camera = Camera(eye=(0.0, 3.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fovy=30.0, near=0.01, far=50.0)
    objects = [SceneObject("floor", shapes.plane(2.0, material=Material(ka=0.0, kd=kd, ks=0.0)), np.eye(4),
                           program=program, texture=texture)]
    if lamp:
        flip = np.diag([1.0, -1.0, -1.0, 1.0])                         # the quad faces down
        flip[1, 3] = 1.0
        objects.append(SceneObject("lamp", shapes.plane(0.3, material=Material(ke=4.0, kd=0.0, ks=0.0)), flip))
    return Scene(objects=objects, camera=camera, width=size, height=size, background=background, lights=())


def test_every_sample_is_kd_times_the_texture_at_its_uv_as_the_rasterizer_samples_it():
    tex = Texture2D(image(), filter="bilinear", wrap="repeat")
    kd = (1.0, 0.8, 0.6)
    traced = pathtrace(textured_plane(tex, kd), spp=4, seed=3)
    assert traced.notes == []
    checked = 0
    for x, y in ((0, 0), (5, 7), (11, 11), (6, 2)):
        for path in traced.path_story(x, y):
            first = path.bounces[0]
            assert first.object == "floor" and first.lobe == "Lambert"
            P = first.point
            u, v = (P[0] + 1.0) / 2.0, (1.0 - P[2]) / 2.0
            t = tex.sample(u, v)                                   # the rasterizer's lookup, level of detail 0
            expected = tuple(k * c for k, c in zip(kd, t[:3]))
            assert tuple(c * math.pi for c in first.f) == pytest.approx(expected, rel=1e-9)
            assert path.value == pytest.approx(expected, rel=1e-9)     # sky radiance 1 times the albedo
            checked += 1
    assert checked == 16
    # the picture is the texture: a texel-sized pattern, not one colour
    assert traced.image[..., 0].std() > 0.1


@pytest.mark.parametrize("filter,wrap", [("nearest", "repeat"), ("trilinear", "clamp"), ("bilinear", "mirror")])
def test_the_texture_filter_and_wrap_are_the_rasterizers_at_level_zero(filter, wrap):
    """uv beyond [0, 1] (the plane's uvs scaled by 3) wraps as the texture says; a mipmapped texture is read at
    level 0 (the path tracer's samples average it over the pixel)."""
    tex = Texture2D(image(1, (4, 6)), filter=filter, wrap=wrap)
    scene = textured_plane(tex, kd=1.0)
    floor = scene.objects[0]
    scene = scene.replace(objects=[SceneObject("floor", floor.mesh.replace(uvs=floor.mesh.uvs * 3.0 - 1.0),
                                               floor.model, program="textured", texture=tex)])
    traced = pathtrace(scene, spp=2, seed=5)
    for x, y in ((1, 1), (10, 3), (4, 9)):
        for path in traced.path_story(x, y):
            P = path.bounces[0].point
            u, v = 3.0 * (P[0] + 1.0) / 2.0 - 1.0, 3.0 * (1.0 - P[2]) / 2.0 - 1.0
            if filter == "nearest" and min(abs(u * 6 - round(u * 6)), abs(v * 4 - round(v * 4))) < 1e-9:
                continue                                           # on a texel edge: either side is right
            assert path.value == pytest.approx(tex.sample(u, v)[:3], rel=1e-9), (x, y)


def test_a_texture_on_an_object_not_drawn_textured_is_not_read():
    """As in the rasterizer, only the ``textured`` program reads the texture: a phong floor is its kd."""
    tex = Texture2D(image(), filter="nearest")
    traced = pathtrace(textured_plane(tex, kd=(0.5, 0.4, 0.3), program="phong"), spp=2, seed=1)
    assert np.allclose(traced.image, np.float32([0.5, 0.4, 0.3]), rtol=1e-6)


def test_a_textured_scene_with_sky_and_lamp_is_the_same_bytes_on_one_and_two_threads_and_progressively():
    """With every new part at once: a texture, the sky as a light sample beside a lamp."""
    tex = Texture2D(image(2), filter="bilinear")
    scene = textured_plane(tex, background=(0.3, 0.4, 0.5, 1.0), lamp=True, size=10)
    whole = pathtrace(scene, spp=20, seed=9, background_light=True)
    parts = pathtrace(scene, spp=7, seed=9, background_light=True).add(13)
    assert parts.image.tobytes() == whole.image.tobytes() and parts.variance.tobytes() == whole.variance.tobytes()
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here (NUMBA_NUM_THREADS=1)")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = pathtrace(scene, spp=6, seed=2, background_light=True)
        numba.set_num_threads(2)
        two = pathtrace(scene, spp=6, seed=2, background_light=True)
    finally:
        numba.set_num_threads(before)
    assert one.image.tobytes() == two.image.tobytes()
    assert (one.image > 0).mean() > 0.8               # lit (the lamp, seen from above, shows its black back)
