"""User clip planes (``clip_planes``, a varying ``clip_distance`` = GLSL's gl_ClipDistance) and depth clamp
(GL_DEPTH_CLAMP), clipped in primitive assembly by the frustum's clipper (issue 30).

Window coordinates (y up, pixel (x, y) centred at (x + ½, y + ½)) become clip coordinates with binary
fractions, so they arrive exactly; a vertex may be given any w > 0 (its clip coordinates scaled by w),
which moves nothing on screen but changes where, in clip space, the clipper works. The expected pixels
come from the plane's equation at each pixel centre, in window coordinates, and from the exact
reference rasterizer (tests/reference.py) for the primitive's own coverage.
"""
from __future__ import annotations

import numpy as np
import pytest
import reference

import softpipe as sp
from softpipe.pipeline.assembly import assemble

W = H = 32


def clip(points, z=0.0, w=1.0):
    """Window positions (x, y) → clip coordinates for a W × H viewport, scaled by w (exact for binary
    fractions and powers of two)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    w = np.broadcast_to(np.asarray(w, np.float64), len(p))
    out = np.empty((len(p), 4))
    out[:, 0] = (2.0 * p[:, 0] / W - 1.0) * w
    out[:, 1] = (2.0 * p[:, 1] / H - 1.0) * w
    out[:, 2] = np.broadcast_to(z, len(p)) * w
    out[:, 3] = w
    return out


def plane_in_window(plane, x, y, z=0.0):
    """a·x + b·y + c·z + d·w at the window point (x, y), with w = 1 (the sign is what clipping keeps)."""
    a, b, c, d = plane
    return a * (2.0 * x / W - 1.0) + b * (2.0 * y / H - 1.0) + c * z + d


def hit_counts(fb) -> dict:
    """{(x, y) window pixel: times drawn} from an additive draw of 1/64 per hit."""
    counts = np.rint(fb.color[..., 0] * 64).astype(int)
    return {(int(x), int(H - 1 - r)): int(counts[r, x]) for r, x in zip(*np.nonzero(counts))}


def draw_counts(pos, topology="triangles", indices=None, **state) -> dict:
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    sp.draw(fb, pos, indices, topology=topology, varyings={"color": np.full((len(pos), 3), 1 / 64)},
            depth_test=None, blend="additive", **state)
    return hit_counts(fb)


QUAD = [(3.0, 2.0), (29.0, 6.0), (27.0, 30.0), (5.0, 26.0)]   # its edges cross x_w = 16 at binary fractions
QUAD_TRIS = [[0, 1, 2], [0, 2, 3]]


def quad_coverage():
    cells = set()
    for tri in QUAD_TRIS:
        cells |= {(i, j) for i, j, _ in reference.covered([QUAD[k] for k in tri], W, H)}
    return cells


# ------------------------------------------------------------------ triangles

@pytest.mark.parametrize("w", [1.0, [0.5, 2.0, 4.0, 1.0], 2.0 ** 30], ids=["w=1", "mixed-w", "huge (exact)"])
def test_a_quad_clipped_at_x_0_covers_the_pixels_whose_centres_are_on_the_planes_side(w):
    plane = (1.0, 0.0, 0.0, 0.0)
    pos = clip(QUAD, w=w)
    got = draw_counts(pos, indices=np.array(QUAD_TRIS).reshape(-1), clip_planes=[plane])
    expected = {(i, j) for i, j in quad_coverage() if plane_in_window(plane, i + 0.5, j + 0.5) >= 0}
    assert 0 < len(expected) < len(quad_coverage())
    assert got == dict.fromkeys(expected, 1)


def test_the_plane_with_the_opposite_sign_keeps_the_other_part():
    pos, idx = clip(QUAD), np.array(QUAD_TRIS).reshape(-1)
    right = draw_counts(pos, indices=idx, clip_planes=[(1.0, 0.0, 0.0, 0.0)])
    left = draw_counts(pos, indices=idx, clip_planes=[(-1.0, 0.0, 0.0, 0.0)])
    assert not set(left) & set(right)
    assert {**left, **right} == dict.fromkeys(quad_coverage(), 1)


def grid_mesh(cells=8, lo=2.0, hi=30.0, seed=7):
    """A square [lo, hi]² cut into cells² × 2 triangles, interior vertices jittered, each vertex at its
    own w: a closed (watertight) surface on screen."""
    rng = np.random.default_rng(seed)
    t = np.linspace(lo, hi, cells + 1)
    xy = np.stack(np.meshgrid(t, t, indexing="xy"), axis=-1).reshape(-1, 2)
    inner = ((xy > lo) & (xy < hi)).all(axis=1)
    xy[inner] += np.round(rng.uniform(-1.2, 1.2, (int(inner.sum()), 2)) * 256) / 256
    w = 2.0 ** rng.integers(-2, 3, len(xy))
    tris = []
    for r in range(cells):
        for c in range(cells):
            a = r * (cells + 1) + c
            b, d, e = a + 1, a + cells + 1, a + cells + 2
            tris += [[a, b, e], [a, e, d]]
    return clip(xy, z=0.25, w=w), np.array(tris, np.int64).reshape(-1)


TILTED = (0.8, 0.6, 0.0, 0.1)     # kept where 0.8·x + 0.6·y + 0.1·w ≥ 0


def test_a_watertight_mesh_clipped_by_a_tilted_plane_covers_every_pixel_on_its_side_exactly_once():
    pos, idx = grid_mesh()
    got = draw_counts(pos, indices=idx, clip_planes=[TILTED])
    assert max(got.values()) == 1                                            # no double hit anywhere
    px = 2.0 / W                                                             # a pixel, in NDC
    margin = 1 / 128 * px                                                    # the new vertices' snapping
    for i in range(2, 30):                                                   # the square's pixels
        for j in range(2, 30):
            d = plane_in_window(TILTED, i + 0.5, j + 0.5)
            if d > margin:
                assert got.get((i, j)) == 1, (i, j)                          # no gap
            elif d < -margin:
                assert (i, j) not in got, (i, j)
    assert not {(i, j) for i, j in got if not (2 <= i < 30 and 2 <= j < 30)}


def distances(pos, *planes):
    """Each vertex's distance to each plane, a·x + b·y + c·z + d·w, left to right (as the clipper sums)."""
    return np.stack([a * pos[:, 0] + b * pos[:, 1] + c * pos[:, 2] + d * pos[:, 3] for a, b, c, d in planes],
                    axis=1)


def draw_picture(pos, indices, varyings, **state):
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    sp.draw(fb, pos, indices, varyings=varyings, **state)
    return fb.color.copy()


def test_a_clip_distance_varying_gives_the_pixels_and_colors_of_the_equivalent_planes():
    pos, idx = grid_mesh()
    color = np.random.default_rng(3).uniform(0, 1, (len(pos), 3))
    second = (-0.5, 1.0, 0.0, 0.3)
    by_planes = draw_picture(pos, idx, {"color": color}, clip_planes=[TILTED, second])
    by_varying = draw_picture(pos, idx, {"color": color, "clip_distance": distances(pos, TILTED, second)})
    unclipped = draw_picture(pos, idx, {"color": color})
    assert np.array_equal(by_planes, by_varying)
    assert not np.array_equal(by_planes, unclipped)


def test_a_clip_distance_written_by_a_vertex_shader_clips_as_the_plane_does_and_reaches_the_fragment_shader():
    from collections import namedtuple
    Varyings = namedtuple("Varyings", ["color", "clip_distance"])

    def vs(attributes, uniforms):
        p = attributes.position
        a, b, c, d = uniforms.plane
        return (p[0], p[1], p[2], p[3]), Varyings(attributes.color, a * p[0] + b * p[1] + c * p[2] + d * p[3])

    def fs(varyings, uniforms, frag):            # the interpolated distance, ≥ 0 wherever a fragment is
        return (varyings.color[0], varyings.color[1], varyings.color[2], 1.0 if varyings.clip_distance > -1e-9
                else 0.0)

    pos, idx = grid_mesh()
    color = np.random.default_rng(5).uniform(0, 1, (len(pos), 3))
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    sp.draw(fb, pos, idx, vertex_shader=vs, fragment_shader=fs, attributes={"color": color},
            uniforms={"plane": np.array(TILTED)})
    expected = draw_picture(pos, idx, {"color": color}, clip_planes=[TILTED])
    covered = expected[..., 3] > 0
    assert covered.any() and not covered.all()
    assert np.array_equal(fb.color[..., :3], expected[..., :3])
    assert np.array_equal(fb.color[..., 3] > 0, covered)                 # the fragment saw a distance ≥ 0


def test_a_triangle_entirely_outside_a_user_plane_is_dropped_as_outside_and_one_across_is_cut():
    pos = clip([(2.0, 2.0), (10.0, 2.0), (2.0, 10.0), (20.0, 2.0), (30.0, 2.0), (20.0, 10.0)])
    vout = sp.run_vertex_stage(pos)
    prims = assemble(vout, viewport=sp.Viewport(0, 0, W, H), clip_planes=[(1.0, 0.0, 0.0, -0.25)])  # x_w ≥ 20
    assert prims.dropped["outside"].tolist() == [0]
    assert prims.primitive_id.tolist() == [1] and not prims.clipped.any()
    cut = assemble(vout, viewport=sp.Viewport(0, 0, W, H), clip_planes=[(1.0, 0.0, 0.0, -0.5)])   # x_w ≥ 24
    assert cut.clipped.all() and set(cut.primitive_id.tolist()) == {1}
    assert cut.window[:, :, 0].min() == 24.0


def test_polygon_mode_line_clips_the_edges():
    pos = clip([(2.0, 4.0), (30.0, 8.0), (6.0, 28.0)])
    full = draw_counts(pos, polygon_mode="line")
    clipped = draw_counts(pos, polygon_mode="line", clip_planes=[(1.0, 0.0, 0.0, 0.0)])     # x_w ≥ 16
    assert min(x for x, _ in full) < 15
    assert clipped and min(x for x, _ in clipped) >= 15
    assert {p: n for p, n in full.items() if p[0] >= 17} == {p: n for p, n in clipped.items() if p[0] >= 17}


# ------------------------------------------------------------------ lines and points

def test_a_line_clipped_by_a_plane_is_the_line_from_the_crossing():
    plane = (1.0, 0.0, 0.0, 0.0)                          # x_w ≥ 16: the line crosses it at (16, 17)
    colors = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    for ends, cut in (([(2.0, 10.0), (30.0, 24.0)], [(16.0, 17.0), (30.0, 24.0)]),
                      ([(30.0, 24.0), (2.0, 10.0)], [(30.0, 24.0), (16.0, 17.0)])):
        k = 0 if ends[0] == cut[0] else 1                     # which end is kept
        mid = colors.mean(axis=0)
        cut_colors = np.array([colors[0], mid]) if k == 0 else np.array([mid, colors[1]])
        got = draw_picture(clip(ends, w=[1.0, 4.0]), None, {"color": colors}, topology="lines",
                           clip_planes=[plane], interpolation={"color": "noperspective"})
        want = draw_picture(clip(cut), None, {"color": cut_colors}, topology="lines",
                            interpolation={"color": "noperspective"})
        assert want[..., 3].sum() > 0
        assert np.array_equal(got, want)


def test_a_point_outside_a_plane_is_discarded_whole_and_one_on_it_is_kept():
    centres = [(15.0, 8.0), (16.0, 16.0), (20.5, 24.5), (12.5, 4.5)]   # x_w < 16 is outside
    got = draw_counts(clip(centres), "points", point_size=5, clip_planes=[(1.0, 0.0, 0.0, 0.0)])
    want = draw_counts(clip(centres[1:3]), "points", point_size=5)
    assert got == want and min(x for x, _ in got) < 16                    # a kept point's square reaches across


def test_a_point_outside_a_clip_distance_is_discarded():
    centres = [(4.5, 4.5), (8.5, 8.5), (12.5, 12.5)]
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    sp.draw(fb, clip(centres), topology="points", depth_test=None, blend="additive",
            varyings={"color": np.full((3, 3), 1 / 64), "clip_distance": np.array([[1.0, 0.0], [1.0, -1e-300],
                                                                                  [0.0, 2.0]])})
    got = hit_counts(fb)
    assert got == {(4, 4): 1, (12, 12): 1}


# ------------------------------------------------------------------ depth clamp

def far_crossing_triangle():
    return clip([(4.0, 4.0), (28.0, 6.0), (10.0, 28.0)], z=np.array([0.5, 0.5, 1.5]))


def test_depth_clamp_keeps_the_part_beyond_the_far_plane_at_depth_1():
    pos = far_crossing_triangle()
    whole = {(i, j) for i, j, _ in reference.covered([(4.0, 4.0), (28.0, 6.0), (10.0, 28.0)], W, H)}
    fb = sp.Framebuffer(W, H)
    clipped = sp.draw(fb, pos, varyings={"color": np.ones((3, 3))}, trace=True)
    fb = sp.Framebuffer(W, H)
    clamped = sp.draw(fb, pos, varyings={"color": np.ones((3, 3))}, depth_clamp=True, trace=True)
    pixels = lambda t: {(int(x), H - 1 - int(y)) for x, y in zip(t.fragments.x, t.fragments.y)}  # noqa: E731
    assert pixels(clipped) < whole                                     # the far part clipped away
    assert pixels(clamped) == whole                                    # kept whole
    assert clipped.primitives.clipped.all() and not clamped.primitives.clipped.any()
    assert clamped.primitives.window[0, 2, 2] == 1.25                   # beyond the depth range, in assembly
    depth = clamped.fragments.depth
    beyond = np.array([(i, j) not in pixels(clipped) for i, j in zip(clamped.fragments.x,
                                                                     H - 1 - clamped.fragments.y)])
    assert beyond.any() and (depth[beyond] == 1.0).all()               # the rasterizer clamps to [0, 1]
    assert ((depth >= 0) & (depth <= 1)).all()


def test_depth_clamp_keeps_points_beyond_near_and_far_but_not_behind_the_eye():
    pos = clip([(4.5, 4.5), (8.5, 8.5), (12.5, 12.5)], z=np.array([-3.0, 3.0, 0.0]))
    pos[2, 3] = -1.0                                                   # behind the eye: still discarded
    assert draw_counts(pos, "points") == {}
    assert draw_counts(pos, "points", depth_clamp=True) == {(4, 4): 1, (8, 8): 1}


def test_depth_clamp_still_clips_at_the_eye_and_gives_finite_depths():
    pos = clip([(4.0, 4.0), (28.0, 6.0), (10.0, 28.0)], z=np.array([0.0, 0.0, -5.0]))
    pos[2] = (0.1, 0.2, -3.0, -0.5)                                    # a corner behind the eye
    fb = sp.Framebuffer(W, H)
    trace = sp.draw(fb, pos, varyings={"color": np.ones((3, 3))}, depth_clamp=True, trace=True)
    assert trace.primitives.clipped.all() and (trace.primitives.inv_w > 0).all()
    assert len(trace.fragments) and np.isfinite(trace.fragments.depth).all()


def test_without_user_planes_or_depth_clamp_the_draw_is_byte_identical():
    pos, idx = grid_mesh()
    pos = pos * 1.0
    pos[::5, 2] = 1.5 * pos[::5, 3]                                    # some vertices beyond the far plane
    color = np.random.default_rng(1).uniform(0, 1, (len(pos), 3))
    a = draw_picture(pos, idx, {"color": color})
    b = draw_picture(pos, idx, {"color": color}, clip_planes=None, depth_clamp=False)
    c = draw_picture(pos, idx, {"color": color}, clip_planes=[])
    assert np.array_equal(a, b) and np.array_equal(a, c)


# ------------------------------------------------------------------ errors

@pytest.mark.parametrize("planes, message", [
    (np.zeros((9, 4)), "clip_planes has shape [9, 4]: at most 8 planes (GL's MAX_CLIP_DISTANCES)"),
    ([1.0, 0.0, 0.0], "clip_planes must have shape [k, 4], one plane (a, b, c, d) a row (kept where "
                      "a·x + b·y + c·z + d·w ≥ 0), got shape [3]"),
    ([[1.0, 0.0, 0.0, 0.0], [0.0, np.nan, 0.0, 1.0]],
     "clip_planes (shape [2, 4]) must be finite, got plane 1 = [0.0, nan, 0.0, 1.0]"),
    ([[1.0, "x", 0.0, 0.0]], "clip_planes must be an array [k, 4] of numbers, one plane (a, b, c, d) a row, got "
                             "[[1.0, 'x', 0.0, 0.0]]"),
])
def test_bad_clip_planes_are_refused_by_name_and_shape(planes, message):
    with pytest.raises(ValueError) as e:
        sp.DrawCall(sp.Framebuffer(W, H), clip(QUAD[:3]), clip_planes=planes)
    assert str(e.value) == message


def test_a_clip_distance_varying_of_9_components_is_refused():
    with pytest.raises(ValueError) as e:
        sp.draw(sp.Framebuffer(W, H), clip(QUAD[:3]),
                varyings={"color": np.ones((3, 3)), "clip_distance": np.ones((3, 9))})
    assert str(e.value) == ("varyings['clip_distance'] has 9 components: a varying holds at most 4, so "
                            "gl_ClipDistance[4..7] go in a second varying, 'clip_distance2' (8 in all at most, "
                            "GL's MAX_CLIP_DISTANCES)")


def test_eight_clip_distances_in_two_varyings_clip_as_eight_planes():
    pos, idx = grid_mesh()
    color = np.random.default_rng(4).uniform(0, 1, (len(pos), 3))
    angles = np.arange(8) * np.pi / 4 + 0.1
    planes = [(-np.cos(a), -np.sin(a), 0.0, 0.7) for a in angles]        # an octagon around the centre
    d = distances(pos, *planes)
    by_planes = draw_picture(pos, idx, {"color": color}, clip_planes=planes)
    by_varyings = draw_picture(pos, idx, {"color": color, "clip_distance": d[:, :4], "clip_distance2": d[:, 4:]})
    assert np.array_equal(by_planes, by_varyings)
    covered = by_planes[..., 3] > 0
    assert covered[16, 16] and not covered[2, 16] and not covered[16, 29] and not covered[4, 4]


def test_a_non_finite_clip_distance_drops_its_primitives_as_non_finite():
    pos = clip([(2.0, 2.0), (10.0, 2.0), (2.0, 10.0), (20.0, 2.0), (30.0, 2.0), (20.0, 10.0)])
    d = np.ones(6)
    d[4] = np.nan
    trace = sp.draw(sp.Framebuffer(W, H), pos, varyings={"color": np.ones((6, 3)), "clip_distance": d},
                    trace=True)
    assert trace.primitives.dropped["non-finite"].tolist() == [1]
    assert trace.primitives.primitive_id.tolist() == [0]


def test_depth_clamp_must_be_a_bool():
    vout = sp.run_vertex_stage(clip(QUAD[:3]))
    with pytest.raises(ValueError) as e:
        assemble(vout, viewport=sp.Viewport(0, 0, W, H), depth_clamp="yes")
    assert str(e.value) == "depth_clamp must be True or False, got 'yes'"
