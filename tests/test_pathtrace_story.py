"""A path's story per pixel (PathTrace.path_story): the kernel's own paths, bounce by bounce, as data."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import SceneObject
from softpipe.scenes.scenefile import load_scene
from softpipe.tracers.pathtrace import pathtrace

CORNELL = Path(__file__).resolve().parent.parent / "examples" / "cornell_box.toml"


@pytest.fixture(scope="module")
def scene():
    """The Cornell box with a glossy Blinn-Phong box, a mirror ball and a glass ball: every kind of lobe."""
    box = load_scene(CORNELL).replace(width=12, height=12)
    mirror = SceneObject("mirror ball", shapes.icosphere(0.3, 2, material=Material(kd=0.0, ks=0.0, kr=0.9)),
                         translate(-0.4, -0.3, 0.3))
    glass = SceneObject("glass ball", shapes.icosphere(0.3, 2, material=Material(kd=0.0, ks=0.0, kt=1.0, ior=1.5)),
                        translate(0.4, -0.3, 0.5))
    shiny = SceneObject("shiny ball", shapes.icosphere(0.25, 2, material=Material(kd=0.3, ks=0.5, shininess=20.0)),
                        translate(0.0, 0.4, 0.0))
    return box.replace(objects=[o for o in box.objects if o.name != "large box"] + [mirror, glass, shiny])


def test_each_samples_story_sums_to_its_value_and_the_pixel(scene):
    """One sample per pixel: the image is that sample's value (float32), and the story's collected light, summed
    in the kernel's order, is that value to the last bit, for every pixel."""
    traced = pathtrace(scene, spp=1, seed=5)
    lobes = set()
    for y in range(scene.height):
        for x in range(scene.width):
            story = traced.path_story(x, y)
            assert len(story) == 1 and story[0].sample == 0
            (path,) = story
            assert path.total() == path.value
            assert np.array_equal(traced.image[y, x], np.float32(path.value))
            assert [b.depth for b in path.bounces] == list(range(len(path.bounces)))
            assert path.bounces[-1].end                # the last ray says why the path ended
            lobes.update(b.lobe for b in path.bounces)
    assert {"Lambert", "Blinn-Phong", "mirror"} <= lobes, lobes       # the story saw more than one kind of lobe
    assert lobes & {"glass, reflected", "glass, refracted"}, lobes


def test_a_pixels_samples_add_up_to_its_mean(scene):
    traced = pathtrace(scene, spp=6, seed=2)
    story = traced.path_story(6, 7)
    assert [p.sample for p in story] == list(range(6))
    acc = np.zeros(3)
    for p in story:
        acc += np.array(p.value)
        assert p.total() == p.value
    assert np.array_equal(traced.image[7, 6], (acc / 6).astype(np.float32))
    assert traced.path_story(6, 7, sample=3)[0] == story[3]                 # one sample: the same numbers
    later = traced.path_story(6, 7, sample=9)[0]                            # one not rendered yet …
    traced.add(4)
    assert traced.path_story(6, 7, sample=9)[0] == later                    # … is the one add() renders


def test_light_is_collected_with_its_mis_weights(scene):
    """Along the stories of the whole image: next-event estimation found lit points, its weights lie in (0, 1],
    and a diffuse bounce's f is kd/π with a pdf of p_d·cos θ/π."""
    traced = pathtrace(scene, spp=1, seed=5)
    lit = [b for y in range(12) for x in range(12) for b in traced.path_story(x, y)[0].bounces
           if b.nee == "light sample lit it"]
    assert lit and all(0.0 < b.nee_lambert_weight <= 1.0 for b in lit)
    b = [b for b in lit if b.object in ("back", "floor", "ceiling") and b.lobe == "Lambert"][0]
    assert b.pdf == pytest.approx(b.cos / np.pi, rel=1e-12)          # a wall is Lambert only: p_d = 1
    glossy = [b for b in lit if b.object == "shiny ball" and any(b.nee_glossy)]
    assert glossy and all(0.0 < b.nee_glossy_weight <= 1.0 for b in glossy)


def test_printed_story_and_bad_pixel(scene):
    traced = pathtrace(scene, spp=2, seed=1)
    text = str(traced.path_story(6, 6))
    assert text.startswith("pixel (6, 6): 2 sampled path(s)\nsample 0: value (")
    assert "hits " in text and "ends: " in text
    with pytest.raises(ValueError) as e:
        traced.path_story(12, 0)
    assert str(e.value) == "path_story: pixel (12, 0) is outside the 12×12 image"
    with pytest.raises(ValueError) as e:
        traced.path_story(0, 0, sample=-1)
    assert str(e.value) == "pathtrace: sample must be a whole number 0…1048575, got -1"
