"""The path tracer's fast paths give the answers of the slow ones, bit for bit (issue 36, its speed).

The path tracer walks the BVH through :func:`softpipe.rays.bvh.hit_inline` (the walk compiled into its
kernel, one site for closest hits and one for shadow rays) and draws its numbers through
:func:`~softpipe.tracers.montecarlo.sample_key` and :func:`~softpipe.tracers.montecarlo.uniform_of`
(the sample's hash once, one mix per number). Each must equal what it stands for: closest_hit,
any_hit and uniform, on the same inputs, to the last bit.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from softpipe.rays.bvh import BVH, any_hit, closest_hit, hit_inline
from softpipe.rays.queries import RayScene
from softpipe.scenes.scenefile import load_scene
from softpipe.tracers.montecarlo import sample_key, uniform, uniform_of

CORNELL = Path(__file__).resolve().parent.parent / "examples" / "cornell_box.toml"


@njit(cache=True)
def _both_ways(bvh, origins, directions, t_max):
    """Per ray: hit_inline's closest hit and any hit, and closest_hit's and any_hit's answers."""
    n = origins.shape[0]
    inline_closest = np.empty((n, 4))
    called_closest = np.empty((n, 4))
    inline_any = np.empty(n, np.bool_)
    called_any = np.empty(n, np.bool_)
    for r in range(n):
        o = (origins[r, 0], origins[r, 1], origins[r, 2])
        d = (directions[r, 0], directions[r, 1], directions[r, 2])
        a = hit_inline(bvh, o, d, 1e-9, t_max[r], False)
        b = closest_hit(bvh, o, d, 1e-9, t_max[r])
        inline_closest[r, 0], inline_closest[r, 1], inline_closest[r, 2], inline_closest[r, 3] = float(a[0]), a[1], a[2], a[3]
        called_closest[r, 0], called_closest[r, 1], called_closest[r, 2], called_closest[r, 3] = float(b[0]), b[1], b[2], b[3]
        inline_any[r] = hit_inline(bvh, o, d, 1e-9, t_max[r], True)[0] >= 0
        called_any[r] = any_hit(bvh, o, d, 1e-9, t_max[r])
    return inline_closest, called_closest, inline_any, called_any


def _check_rays(bvh_uniform, origins, directions, t_max):
    inline_closest, called_closest, inline_any, called_any = _both_ways(bvh_uniform, origins, directions, t_max)
    assert inline_closest.tobytes() == called_closest.tobytes()        # ids, t, b1, b2: the same bits
    assert np.array_equal(inline_any, called_any)
    # and the any-hit walk, which stops at its first hit, sees what the closest hit sees
    assert np.array_equal(inline_any, called_closest[:, 0] >= 0)
    return inline_any


def test_the_inlined_walk_answers_as_closest_hit_and_any_hit_in_the_cornell_box():
    rays = RayScene(load_scene(CORNELL).drawn_objects(load_scene(CORNELL).view_camera()))
    rng = np.random.default_rng(36)
    n = 4000
    origins = rng.uniform(-0.99, 0.99, (n, 3))                       # inside the box, as a path's bounces are
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    # shadow rays of every length: some end before the wall they point at, some reach it
    t_max = np.where(rng.uniform(size=n) < 0.5, np.inf, rng.uniform(0.0, 3.0, n))
    occluded = _check_rays(rays.uniform().bvh, origins, directions, t_max)
    assert 0.3 < occluded.mean() < 0.9                               # both answers are well represented


def test_the_inlined_walk_answers_as_closest_hit_on_a_random_soup_with_shared_edges():
    rng = np.random.default_rng(7)
    # a grid of quads (every edge shared by two triangles: ties and exact edges) and random triangles
    g = np.linspace(-1.0, 1.0, 9)
    xs, ys = np.meshgrid(g, g)
    grid = np.stack([xs, ys, np.zeros_like(xs)], -1)
    quads = []
    for i in range(8):
        for j in range(8):
            a, b, c, d = grid[i, j], grid[i, j + 1], grid[i + 1, j + 1], grid[i + 1, j]
            quads += [(a, b, c), (a, c, d)]
    soup = rng.uniform(-1.0, 1.0, (200, 3, 3)) * [1.0, 1.0, 0.5] + [0.0, 0.0, 1.0]
    tris = np.concatenate([np.array(quads), soup])
    bvh = BVH.build(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3))
    n = 3000
    origins = np.concatenate([rng.uniform(-1.0, 1.0, (n // 2, 3)) + [0.0, 0.0, 3.0],
                              np.stack([rng.choice(g, n // 2), rng.choice(g, n // 2), np.full(n // 2, 2.0)], -1)])
    directions = np.concatenate([rng.normal(size=(n // 2, 3)) - [0.0, 0.0, 2.0],
                                 np.tile([0.0, 0.0, -1.0], (n // 2, 1))])      # straight down the grid's edges
    t_max = np.where(rng.uniform(size=n) < 0.5, np.inf, rng.uniform(0.5, 4.0, n))
    _check_rays(bvh.__softpipe_uniform__(), origins, directions, t_max)


@njit(cache=True)
def _numbers_both_ways(seeds, pixels, samples, dims):
    a = np.empty(seeds.shape[0])
    b = np.empty(seeds.shape[0])
    for k in range(seeds.shape[0]):
        a[k] = uniform(seeds[k], pixels[k], samples[k], dims[k])
        b[k] = uniform_of(sample_key(seeds[k], pixels[k], samples[k]), dims[k])
    return a, b


def test_a_samples_key_gives_the_numbers_uniform_gives():
    rng = np.random.default_rng(3)
    n = 5000
    seeds = rng.integers(0, 2 ** 63, n, dtype=np.uint64) * np.uint64(2) + rng.integers(0, 2, n, dtype=np.uint64)
    pixels = rng.integers(0, 1 << 40, n)
    samples = rng.integers(0, 1 << 20, n)
    dims = rng.integers(0, 200, n)
    seeds[:3], pixels[:3], samples[:3], dims[:3] = (0, 2 ** 64 - 1, 5), 0, 0, 0    # the extremes too
    a, b = _numbers_both_ways(seeds, pixels, samples, dims)
    assert a.tobytes() == b.tobytes()
    assert 0.0 <= a.min() and a.max() < 1.0
