"""V_j of many fragments in one compiled pass (softpipe.light.shadowmap.light_visibilities).

The explorer page holds the shadow term of every fragment it shows (FORMULAS §21); it once asked
``light_visibility`` from Python fragment by fragment (~45 s on the bunny with shadows). The compiled
pass calls the same lookup the shaders call: its numbers are the per-fragment ones, bit for bit.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings, light_visibilities
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject


def _scene() -> Scene:
    """A box over a floor under three lights: a sun with a soft (PCF) map, a point light with a cube map,
    and a spot light whose shadows come from rays."""
    floor = shapes.plane(6.0, material=Material(ka=0.2, kd=0.8, ks=0.0))
    box = shapes.cube(1.0, material=Material(kd=(0.8, 0.3, 0.2)))
    lights = (Light.directional((0.3, -1.0, -0.2), shadows=ShadowSettings(resolution=128, pcf=1), name="sun"),
              Light.point((1.0, 3.0, 0.5), shadows=ShadowSettings(resolution=64, pcf=0), name="bulb"),
              Light.spot((-1.0, 4.0, 0.0), (0.2, -1.0, 0.0), 40.0, shadows=ShadowSettings(method="ray"), name="spot"))
    return Scene([SceneObject("floor", floor, np.eye(4), cast_shadows=False),
                  SceneObject("box", box, translate(0.0, 1.5, 0.0))],
                 camera=sp.Camera(eye=(0.0, 8.0, 0.01), target=(0.0, 0.0, 0.0), fovy=45.0),
                 lights=lights, width=48, height=48)


@pytest.fixture(scope="module")
def floor_trace():
    results = []
    sp.render_scene(_scene(), trace=True, results=results)
    return results[0].trace


def test_the_compiled_pass_equals_the_per_fragment_python_values(floor_trace):
    t = floor_trace
    points = np.array([t.fragment_inputs(i)[0].position for i in range(len(t))], dtype=np.float64)
    lighting = t.call.uniforms.lighting
    one_by_one = np.array([lighting.visibilities(P) for P in points])       # what pixel_history shows
    at_once = t.shadow_terms(points)
    assert at_once.shape == one_by_one.shape == (len(t), 3, 3)
    assert np.array_equal(at_once, one_by_one)
    # the scene has shadow and light and a soft edge: the values compared are not all the same
    assert (at_once == 0.0).any() and (at_once == 1.0).any() and ((at_once > 0) & (at_once < 1)).any()


def test_the_explorer_holds_the_same_shadow_terms(floor_trace):
    from softpipe.views.explorer import ExplorerData, explorer_data
    data = ExplorerData(explorer_data([floor_trace])["meta"])
    rows, shadow = data.arrays["f_index"].astype(np.int64), data.arrays["f_shadow"]
    lighting = floor_trace.call.uniforms.lighting
    want = np.array([lighting.visibilities(floor_trace.fragment_inputs(int(i))[0].position) for i in rows],
                    np.float32)
    assert data.meta["draws"][0]["shadow_lights"] == 3 and len(rows) == len(floor_trace)
    assert np.array_equal(shadow, want)


def test_no_shadows_is_none_and_bad_points_are_named(floor_trace):
    lighting = floor_trace.call.uniforms.lighting
    assert lighting._replace(shadows=None).visibilities_at(np.zeros((2, 3))) is None
    with pytest.raises(ValueError, match=r"points must be an \[N, 3\] array of eye-space points, got shape \(4,\)"):
        light_visibilities(lighting, np.zeros(4))
