"""A shadow map through glass applies k_t but not §15's falloff inside it; a shadow ray applies both.

docs/shadows.md ("Transparent occluders") states the limit with these figures: a glass slab 0.5 thick with
k_t = 0.8 and T = 0.5 per unit distance, the sun straight down — the map gives V = k_t = 0.800 under it, the
shadow ray k_t·T^d = 0.8·0.5^0.5 = 0.566 (FORMULAS §15, §21).
"""
from __future__ import annotations

import numpy as np

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.transforms import scale, translate
from softpipe.rays.queries import RayScene, ray_visibility
from softpipe.scenes import shapes
from softpipe.scenes.scene import SceneObject
from softpipe.scenes.shadow_pass import render_shadow_maps

KT, T, THICKNESS = 0.8, 0.5, 0.5


def test_a_shadow_map_through_glass_applies_kt_but_not_the_falloff_a_shadow_ray_applies_both():
    floor = SceneObject("floor", shapes.plane(8.0, material=Material(kd=0.8)), np.eye(4))
    slab = SceneObject("slab", shapes.cube(1.0, material=Material(kd=0.1, kt=KT, transmittance=T)),
                       translate(0.0, 1.0, 0.0) @ scale(2.0, THICKNESS, 2.0))
    sun = Light.directional((0.0, -1.0, 0.0), shadows=True, name="sun")
    under = (0.0, 0.0, 0.0)
    by_map = render_shadow_maps([floor, slab], Lighting((sun,))).visibility(0, under)
    np.testing.assert_allclose(by_map, [KT] * 3, rtol=1e-6)                       # 0.800: k_t only
    rays = RayScene([floor, slab]).uniform()
    by_ray = ray_visibility(rays, under, (0.0, 1.0, 0.0), np.inf)
    np.testing.assert_allclose(by_ray, [KT * T ** THICKNESS] * 3, rtol=1e-9)     # 0.566: k_t·T^d
    assert round(by_map[0], 3) == 0.800 and round(by_ray[0], 3) == 0.566
