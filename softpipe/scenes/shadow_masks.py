"""Which pixels are in a light's shadow, by shadow rays and by shadow maps; the band along shadow edges.

To put the shadow methods side by side — shadow rays (FORMULAS §21, what the ray tracer
:mod:`softpipe.tracers.whitted` casts), shadow maps (:mod:`softpipe.scenes.shadow_pass`) and
stencil shadow volumes (:mod:`softpipe.scenes.shadow_volumes`) — each is reduced to a
boolean picture: the pixels whose visible point light j does not reach.

- :func:`visible_points`: each pixel's primary ray (the ray tracer's, through the pixel
  centre) and the world-space point it meets;
- :func:`shadow_mask`: light j's V_j at those points, by ``"ray"`` (the ray tracer's
  shadow ray, t ∈ (ε, t_max − ε), the casters only) or ``"map"`` (the shadow map, with its
  depth bias and PCF as the light's ShadowSettings give them), through the same
  :func:`~softpipe.light.shadowmap.light_visibility` the shaders call;
- :func:`edge_band`: the pixels within n pixels (8-connected steps) of an edge of a mask,
  where a pixel and a 4-neighbour differ — where methods that sample a shadow differently
  may disagree;
- :func:`compare_masks`: the pixels two masks disagree on, inside and outside such a band.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
from numba import njit

from softpipe.light.material import Lighting
from softpipe.light.shadowmap import ShadowSettings, light_visibility
from softpipe.pipeline.camera import Camera
from softpipe.scenes.shadow_pass import render_shadow_maps
from softpipe.tracers.whitted import primary_visibility

__all__ = ["visible_points", "shadow_mask", "edge_band", "compare_masks", "MaskComparison", "MASK_METHODS"]

#: How :func:`shadow_mask` asks whether a point sees the light.
MASK_METHODS = ("ray", "map")


def visible_points(scene, camera: Optional[Camera] = None) -> Tuple[np.ndarray, np.ndarray]:
    """(covered bool [H, W], points float64 [H, W, 3]): what each pixel's primary ray meets, in world space.

    The ray tracer's primary ray through the pixel centre
    (:func:`softpipe.tracers.whitted.primary_visibility`); the point is the hit's barycentric
    combination of its triangle's world-space corners. Uncovered pixels hold 0.
    """
    camera = camera or scene.view_camera()
    objects = scene.drawn_objects(camera)
    obj, tri, b = primary_visibility(scene, camera=camera)
    covered = obj >= 0
    points = np.zeros(obj.shape + (3,))
    for k, o in enumerate(objects):
        here = obj == k
        if not here.any():
            continue
        corners = o.world_positions()[o.mesh.indices[tri[here]]]          # [n, 3, 3]
        b1, b2 = b[here][:, 0:1], b[here][:, 1:2]
        points[here] = (1.0 - b1 - b2) * corners[:, 0] + b1 * corners[:, 1] + b2 * corners[:, 2]
    return covered, points


@njit(cache=True)
def _visibility_of(lighting, j, points, out):
    for i in range(points.shape[0]):
        v = light_visibility(lighting, j, (points[i, 0], points[i, 1], points[i, 2]))
        out[i] = v[0]


def shadow_mask(scene, light_index: int = 0, method: str = "ray", *, camera: Optional[Camera] = None,
                settings: Optional[ShadowSettings] = None) -> Tuple[np.ndarray, np.ndarray]:
    """(covered, shadowed), bool [H, W]: the pixels some object covers, and those whose point light j misses.

    Parameters
    ----------
    scene : Scene
    light_index : int
        Which of ``scene.lighting_for(camera).lights``.
    method : "ray" or "map"
        "ray": the shadow ray of §21 from the visible point toward the light, against
        the objects that cast shadows (what :func:`~softpipe.tracers.whitted.raytrace_scene`
        computes); "map": light j's shadow map(s), ``settings`` (the light's own, or the
        defaults) — bias, resolution, PCF.
    camera : Camera, optional
        Instead of the scene's.

    A point is shadowed when V_j < 1/2 (opaque casters give 0 or 1; a map's PCF gives
    fractions along its edges, read at one half).
    """
    if method not in MASK_METHODS:
        raise ValueError(f"method must be one of {', '.join(map(repr, MASK_METHODS))}, got {method!r}")
    camera = camera or scene.view_camera()
    lighting = scene.lighting_for(camera)
    if not 0 <= light_index < len(lighting.lights):
        raise ValueError(f"light_index {light_index} is out of range for the scene's {len(lighting.lights)} lights")
    light = lighting.lights[light_index]
    if method == "ray":
        chosen = ShadowSettings(method="ray")
    else:
        chosen = settings or light.shadows or ShadowSettings()
    alone = Lighting((dataclasses.replace(light, shadows=chosen),), global_ambient=lighting.global_ambient)
    maps = render_shadow_maps(scene.drawn_objects(camera), alone)
    uniform = maps.lighting_uniform(alone, np.eye(4))          # eye space = world space
    covered, points = visible_points(scene, camera)
    flat = np.ascontiguousarray(points[covered])
    v = np.ones(len(flat))
    if len(flat):
        _visibility_of(uniform, 0, flat, v)
    shadowed = np.zeros(covered.shape, bool)
    shadowed[covered] = v < 0.5
    return covered, shadowed


def edge_band(mask: np.ndarray, n: int) -> np.ndarray:
    """bool [H, W]: the pixels within n steps (8-connected) of an edge of ``mask``.

    An edge pixel is one whose value differs from one of its four neighbours' (both
    sides of the edge are edge pixels); n = 0 is the edge pixels themselves.
    """
    m = np.asarray(mask, bool)
    if m.ndim != 2:
        raise ValueError(f"mask must be a 2-D bool array, got shape {m.shape}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n must be a whole number of pixels ≥ 0, got {n!r}")
    edge = np.zeros_like(m)
    dx = m[:, 1:] != m[:, :-1]
    dy = m[1:, :] != m[:-1, :]
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    edge[1:, :] |= dy
    edge[:-1, :] |= dy
    band = edge
    for _ in range(int(n)):
        grown = band.copy()
        grown[1:, :] |= band[:-1, :]
        grown[:-1, :] |= band[1:, :]
        grown[:, 1:] |= grown[:, :-1].copy()
        grown[:, :-1] |= grown[:, 1:].copy()
        band = grown
    return band


@dataclass(frozen=True)
class MaskComparison:
    """Two shadow masks compared over the covered pixels.

    ``differ`` (bool [H, W]) marks where they disagree; ``band`` the edge band of the
    reference mask; ``outside`` = differ and not in the band. ``width`` is the band's n,
    ``needed`` the smallest n at which nothing differs outside the band (None when some
    pixel differs however wide).
    """

    differ: np.ndarray
    band: np.ndarray
    width: int
    needed: Optional[int]

    @property
    def outside(self) -> np.ndarray:
        return self.differ & ~self.band

    @property
    def count(self) -> int:
        return int(self.differ.sum())

    @property
    def count_outside(self) -> int:
        return int(self.outside.sum())


def compare_masks(reference: np.ndarray, other: np.ndarray, covered: np.ndarray, width: int = 1,
                  max_width: int = 16) -> MaskComparison:
    """Where ``other`` disagrees with ``reference`` over ``covered``, and the edge band needed to hold it all.

    The band is :func:`edge_band` of ``reference`` (restricted to the covered pixels); ``needed``
    is searched from 0 to ``max_width``.
    """
    ref, oth, cov = (np.asarray(a, bool) for a in (reference, other, covered))
    if not (ref.shape == oth.shape == cov.shape):
        raise ValueError(f"the masks' shapes differ: {ref.shape}, {oth.shape}, covered {cov.shape}")
    differ = (ref != oth) & cov
    needed = None
    for n in range(max_width + 1):
        if not (differ & ~edge_band(ref & cov, n)).any():
            needed = n
            break
    return MaskComparison(differ, edge_band(ref & cov, width), width, needed)
