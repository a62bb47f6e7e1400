"""The visibility fast path gives the same bytes as the reference path (issue 6's rule).

Scenes are chosen to exercise what the fast path adds: tiles (framebuffers that
are not multiples of the tile size), hierarchical depth rejecting and lowering
per tile (large constant-depth triangles in random and back-to-front order),
exact row spans (vertices on ties), every depth function, depth writes off,
supersampling, a smaller viewport, clipping, and every interpolation qualifier.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.merge_state import DEPTH_FUNCS
from softpipe.pipeline.sampling import grid, rotated_grid_4x
from softpipe.pipeline.transforms import perspective


def both_paths(make_fb, **draw):
    out = []
    for path in ("reference", "fast"):
        fb = make_fb()
        call = DrawCall(fb, path=path, **draw)
        assert call.uses_fast_path() == (path == "fast")
        call.run()
        out.append(fb)
    return out


def assert_same(a, b):
    assert np.array_equal(a.samples_depth, b.samples_depth)
    assert np.array_equal(a.samples_color, b.samples_color)


def big_triangles(rng, n, width, height, order):
    """Large triangles (30–60 % of the screen), each at one random depth: the fill benchmark, small."""
    pts, zs = [], rng.uniform(-0.9, 0.9, n)
    for _ in range(n):
        s = np.sqrt(2 * rng.uniform(0.3, 0.6) * width * height)
        c = rng.uniform([0.3 * width, 0.3 * height], [0.7 * width, 0.7 * height])
        a = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        pts.append((np.array([[0, 0], [s, 0], [0, s]]) - s / 3) @ rot.T + c)
    pts = np.round(np.array(pts) * 256) / 256
    if order == "back-to-front":
        idx = np.argsort(-zs)
        pts, zs = pts[idx], zs[idx]
    clip = window_to_clip(np.c_[pts.reshape(-1, 2), np.repeat(zs, 3)], width, height)
    return clip, rng.uniform(0, 1, (3 * n, 3))


@pytest.mark.parametrize("order", ["random", "back-to-front"])
@pytest.mark.parametrize("func", ["less", "lequal"])
def test_fill_scene_with_hierarchical_depth(order, func):
    rng = np.random.default_rng(7)
    w, h = 300, 170                               # not multiples of the 128×32 tiles
    clip, colors = big_triangles(rng, 60, w, h, order)
    a, b = both_paths(lambda: sp.Framebuffer(w, h), positions=clip, varyings={"color": colors},
                      depth_test=func)
    assert_same(a, b)
    assert len(np.unique(a.color[..., 0])) > 20    # many triangles show


@pytest.mark.parametrize("func", DEPTH_FUNCS + (None,))
@pytest.mark.parametrize("write", [True, False])
def test_every_depth_function_and_write_mode(func, write):
    rng = np.random.default_rng(3)
    w, h = 140, 90
    pts = np.round(rng.uniform(-10, [w + 10, h + 10], size=(90, 2)) * 2) / 2   # many ties on half pixels
    z = rng.choice([-0.5, 0.0, 0.25, 0.5], size=(90, 1))
    clip = window_to_clip(np.c_[pts, z], w, h)

    def make():
        fb = sp.Framebuffer(w, h)
        fb.clear((0.1, 0.2, 0.3, 1.0), depth=0.6)
        return fb

    shader = None
    if func == "notequal" and write:
        # the fast path takes it only for a shader whose alpha is a finite literal (a hidden
        # fragment discarded could change which one shows): the default shader's is not proven
        from softpipe.pipeline.merge_state import MergeState
        from softpipe.pipeline.visibility import fast_path_blocker
        assert "notequal" in fast_path_blocker(MergeState(func, write), None)
        assert fast_path_blocker(MergeState(func, write), opaque) is None
        shader = opaque
    a, b = both_paths(make, positions=clip, varyings={"color": rng.uniform(0, 1, (90, 3))},
                      depth_test=func, depth_write=write, fragment_shader=shader)
    assert_same(a, b)


def opaque(varyings, uniforms, frag):
    c = varyings.color
    return (c[0], c[1], c[2], 1.0)


def frag_info(varyings, uniforms, frag):
    return (frag.x * 0.01 + varyings.uv[0], frag.y * 0.01 + varyings.flat_id, frag.z,
            (0.5 if frag.front_facing else 0.25) + frag.primitive_id * 0.001)


@pytest.mark.parametrize("pattern", [sp.CENTER, grid(2), rotated_grid_4x()], ids=lambda p: p.name)
def test_perspective_scene_with_clipping_qualifiers_and_samples(pattern):
    rng = np.random.default_rng(5)
    w, h = 150, 100
    tris = rng.uniform(-2, 2, size=(120, 3, 3))
    tris[:, :, 2] = rng.uniform(-6, 0.4, size=(120, 3))          # some cross the near plane
    clip = (perspective(60, w / h, 0.5, 10) @ np.c_[tris.reshape(-1, 3), np.ones(360)].T).T
    varyings = {"uv": rng.uniform(0, 1, (360, 2)), "flat_id": np.repeat(np.arange(120.0), 3) / 120}
    a, b = both_paths(lambda: sp.Framebuffer(w, h, pattern=pattern), positions=clip, varyings=varyings,
                      fragment_shader=frag_info, interpolation={"uv": "noperspective", "flat_id": "flat"})
    assert_same(a, b)
    a, b = both_paths(lambda: sp.Framebuffer(w, h, pattern=pattern), positions=clip, varyings=varyings,
                      fragment_shader=frag_info, cull="back")
    assert_same(a, b)


def test_smaller_viewport_is_a_scissor_on_both_paths():
    rng = np.random.default_rng(9)
    w, h = 160, 120
    clip, colors = big_triangles(rng, 10, w, h, "random")
    vp = sp.Viewport(20, 10, 100, 70)
    a, b = both_paths(lambda: sp.Framebuffer(w, h), positions=clip, varyings={"color": colors}, viewport=vp)
    assert_same(a, b)
    drawn = a.depth < 1.0
    rows, cols = np.nonzero(drawn)
    assert cols.min() >= 20 and cols.max() < 120
    assert (h - 1 - rows).min() >= 10 and (h - 1 - rows).max() < 80


def test_fast_path_is_refused_when_it_cannot_give_the_same_bytes():
    fb = sp.Framebuffer(4, 4)
    clip = window_to_clip([(0, 0), (4, 0), (0, 4)], 4, 4)
    color = {"color": np.ones((3, 3))}
    with pytest.raises(ValueError, match="blending"):
        DrawCall(fb, clip, varyings=color, blend="alpha", path="fast").run()

    def discarding(varyings, uniforms, frag):
        return sp.DISCARD if frag.x < 2 else (1.0, 1.0, 1.0, 1.0)

    with pytest.raises(ValueError, match="DISCARD"):
        DrawCall(fb, clip, varyings=color, fragment_shader=discarding, path="fast").run()
    assert not DrawCall(sp.Framebuffer(8, 8), clip, varyings=color).uses_fast_path()     # small: reference
    assert DrawCall(sp.Framebuffer(256, 256), clip, varyings=color).uses_fast_path()


@pytest.mark.parametrize("pattern", [sp.CENTER, rotated_grid_4x()], ids=lambda p: p.name)
@pytest.mark.parametrize("func", ["less", "lequal", "greater", "always"])
def test_narrow_and_wide_triangles_across_tile_edges(pattern, func):
    """Boxes just under, at and over NARROW pixels wide (sample by sample vs row spans), 1-pixel
    triangles and slivers, placed across the 128×32 tile edges, overlapping at random depths."""
    from softpipe.pipeline.tiles import NARROW, TILE_H, TILE_W
    rng = np.random.default_rng(11)
    w, h = 2 * TILE_W + 20, 3 * TILE_H + 7
    tris = []
    for width in (0.7, 1.0, 3.0, NARROW - 1.5, NARROW - 0.5, NARROW + 0.5, NARROW + 3.0, 40.0):
        for _ in range(12):
            c = rng.choice([TILE_W, 2 * TILE_W, w / 2]) + rng.uniform(-8, 8), \
                rng.choice([TILE_H, 2 * TILE_H, h / 2]) + rng.uniform(-8, 8)
            x = np.array([-0.5, 0.5, rng.uniform(-0.5, 0.5)]) * width         # box exactly `width` wide
            y = rng.uniform(-0.5, 0.5, 3) * rng.choice([0.3, 2.0, 30.0])
            corners = np.c_[x, y] + c
            tris.append(np.c_[np.round(corners * 4) / 4, rng.uniform(-0.8, 0.8, 3)])
    tris = np.array(tris)
    box_w = np.ceil(tris[:, :, 0].max(1)) - np.floor(tris[:, :, 0].min(1))
    assert (box_w <= NARROW - 2).sum() > 20 and (box_w >= NARROW + 2).sum() > 20   # both ways are taken
    clip = window_to_clip(tris.reshape(-1, 3), w, h)

    def make():
        fb = sp.Framebuffer(w, h, pattern=pattern)
        fb.clear((0.0, 0.0, 0.0, 1.0), depth=0.5)
        return fb

    a, b = both_paths(make, positions=clip, varyings={"color": rng.uniform(0, 1, (len(clip), 3))},
                      depth_test=func)
    assert_same(a, b)
    assert (a.samples_depth != 0.5).sum() > 300


def shading_inputs(varyings, uniforms, frag):
    """Everything a multisampled invocation is given, folded into a color that shows any difference."""
    return (varyings.uv[0] + frag.x * 0.001, varyings.uv[1] + frag.y * 0.001, frag.z,
            0.5 + 0.25 * frag.front_facing + frag.primitive_id * 1e-4)


@pytest.mark.parametrize("shading", ["center", "centroid"])
@pytest.mark.parametrize("pattern", [grid(2), rotated_grid_4x(), sp.jittered(3, seed=2)], ids=lambda p: p.name)
@pytest.mark.parametrize("func", ["less", "lequal", "greater"])
def test_multisampling_gives_the_reference_bytes(pattern, func, shading):
    """Multisampling: one invocation per pixel and triangle, at the centre or at the centroid of the
    triangle's covered samples there, with the depth of the pixel's first covered sample; every
    covered, visible sample of the pixel gets its color.
    Small and large triangles, edges through pixels (so pixels hold several triangles), perspective."""
    rng = np.random.default_rng(21)
    w, h = 150, 70
    tris = rng.uniform(-1.5, 1.5, size=(160, 3, 3))
    tris[:, :, :2] = tris[:, :1, :2] + (tris[:, :, :2] - tris[:, :1, :2]) * rng.choice([0.02, 0.2, 1.0], (160, 1, 1))
    tris[:, :, 2] = rng.uniform(-5, -1, size=(160, 1)) + rng.uniform(-0.8, 0.8, size=(160, 3))   # slanted
    clip = (perspective(60, w / h, 0.5, 10) @ np.c_[tris.reshape(-1, 3), np.ones(480)].T).T
    varyings = {"uv": rng.uniform(0, 1, (480, 2))}

    def make():
        fb = sp.Framebuffer(w, h, pattern=pattern)
        fb.clear((0.0, 0.0, 0.0, 1.0), depth=1.0 if func != "greater" else 0.0)
        return fb

    a, b = both_paths(make, positions=clip, varyings=varyings, fragment_shader=shading_inputs,
                      sample_shading=shading, depth_test=func)
    assert_same(a, b)
    covered = (a.samples_depth != a.samples_depth[0, 0, 0]).sum()
    assert covered > 2000
    partial = ((a.samples_color[..., 0] != a.samples_color[:1, ..., 0]).any(axis=0)).sum()
    assert partial > 100            # pixels whose samples show different triangles (or none)


def with_derivatives(varyings, uniforms, frag, derivatives):
    """Reads the screen-space derivatives of a smooth and a noperspective varying."""
    return (derivatives.dx.uv[0] * 10.0, derivatives.dy.uv[1] * 10.0 + varyings.uv[0],
            derivatives.dx.w * 5.0 + derivatives.dy.w, 1.0)


@pytest.mark.parametrize("shading", ["sample", "center", "centroid"])
def test_derivatives_are_the_reference_paths_at_every_shading_position(shading):
    rng = np.random.default_rng(33)
    w, h = 140, 90
    tris = rng.uniform(-1.5, 1.5, size=(60, 3, 3))
    tris[:, :, 2] = rng.uniform(-5, -1, size=(60, 3))
    clip = (perspective(60, w / h, 0.5, 10) @ np.c_[tris.reshape(-1, 3), np.ones(180)].T).T
    varyings = {"uv": rng.uniform(0, 1, (180, 2)), "w": rng.uniform(0, 1, 180)}
    a, b = both_paths(lambda: sp.Framebuffer(w, h, pattern=rotated_grid_4x()), positions=clip, varyings=varyings,
                      fragment_shader=with_derivatives, interpolation={"w": "noperspective"},
                      sample_shading=shading)
    assert_same(a, b)
    assert len(np.unique(a.samples_color[..., 0])) > 50
