"""Primitive assembly through softpipe.draw and softpipe.assemble: culling, topologies, indices, dropped ids.

Window coordinates are OpenGL's (y up): a triangle counter-clockwise there —
and so counter-clockwise in NDC — is front-facing by default. In the stored
image (row 0 at the top) the same triangle appears clockwise.
"""
from fractions import Fraction as F

import numpy as np
import pytest
import reference
from conftest import window_to_clip

import softpipe
from softpipe.pipeline.vertex import run_vertex_stage

S = 8
RED, GREEN = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)

# lower-left, counter-clockwise (y up); upper-right, clockwise
CCW = [(0, 0), (4, 0), (0, 4)]
CW = [(8, 8), (8, 4), (4, 8)]


def image_cells(cells):
    """Window pixels (i, j) → boolean image mask (row 0 at the top)."""
    m = np.zeros((S, S), bool)
    for i, j in cells:
        m[S - 1 - j, i] = True
    return m


def cells_of(tri):
    return {(i, j) for i, j, _ in reference.covered(tri, S, S)}


def draw_pair(cull, front_face):
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    pos = window_to_clip(CCW + CW, S, S)
    softpipe.draw(fb, pos, varyings={"color": np.array([RED] * 3 + [GREEN] * 3)}, cull=cull, front_face=front_face)
    return fb


def test_a_counter_clockwise_ndc_triangle_is_drawn_right_side_up():
    fb = draw_pair("back", "ccw")
    # window (0..4, 0..4) is the bottom-left of the image: rows 7, 6, 5
    assert tuple(fb.color[S - 1, 0, :3]) == RED and tuple(fb.color[S - 1, 2, :3]) == RED
    assert tuple(fb.color[S - 3, 0, :3]) == RED
    assert fb.color[0, 0, 3] == 0 and fb.color[S - 1, S - 1, 3] == 0
    assert np.array_equal(fb.color[..., 3] == 1, image_cells(cells_of(CCW)))


@pytest.mark.parametrize("cull, front_face, want_red, want_green", [
    ("none", "ccw", True, True),
    ("none", "cw", True, True),
    ("back", "ccw", True, False),
    ("front", "ccw", False, True),
    ("back", "cw", False, True),
    ("front", "cw", True, False),
])
def test_culling_by_winding(cull, front_face, want_red, want_green):
    fb = draw_pair(cull, front_face)
    want = np.zeros((S, S, 4), np.float32)
    if want_red:
        want[image_cells(cells_of(CCW))] = (*RED, 1)
    if want_green:
        want[image_cells(cells_of(CW))] = (*GREEN, 1)
    assert np.array_equal(fb.color, want)


def test_default_is_no_culling():
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    softpipe.draw(fb, window_to_clip(CW, S, S), varyings={"color": np.array([GREEN] * 3)})
    assert (fb.color[..., 3] == 1).sum() == len(cells_of(CW)) > 0


# Eye space, projection perspective(90°, 1, 1, 3) (exact). The first vertex is
# behind the eye (w = −0.5); the part in front is a quadrilateral.
P = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -2, -3], [0, 0, -1, 0]], float)
BEHIND = [(-3.5, 0.0, 0.5), (2.0, -1.5, -2.5), (0.5, 2.0, -2.0)]


def clip_of(eye):
    return (P @ np.hstack([np.asarray(eye, float), np.ones((len(eye), 1))]).T).T


def test_facing_of_a_triangle_with_a_vertex_behind_the_eye():
    # Seen from the eye (the origin), the triangle is counter-clockwise when its
    # normal (B − A) × (C − A) points toward the eye: n · (0 − A) > 0.
    a, b, c = (np.array([F(x) for x in v]) for v in BEHIND)
    n = np.cross(b - a, c - a)
    assert n @ (-a) == F(205, 8) > 0                     # front-facing
    # Dividing by the negative w would have said the opposite: window A = (64, 8).
    clip = clip_of(BEHIND)
    assert clip[0, 3] < 0
    win = (clip[:, :2] / clip[:, 3:] + 1) * S / 2
    naive = (win[1, 0] - win[0, 0]) * (win[2, 1] - win[0, 1]) - (win[2, 0] - win[0, 0]) * (win[1, 1] - win[0, 1])
    assert naive < 0
    for cull, drawn in [("none", True), ("back", True), ("front", False)]:
        fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
        softpipe.draw(fb, clip, varyings={"color": np.ones((3, 3))}, cull=cull)
        assert ((fb.color[..., 3] == 1).sum() > 10) == drawn, cull


# --------------------------------------------------- strips and fans vs lists
#
# Per-vertex colors with flat interpolation, so every triangle shows its
# provoking vertex's color. The equivalent lists are written out by hand
# (OpenGL 4.6 §10.1): strip triangle i is (i, i+1, i+2) for even i and
# (i+1, i, i+2) for odd i (keeping the first triangle's winding); fan triangle
# i is (0, i+1, i+2).

STRIP = [(0, 8), (0, 0), (3, 8), (5, 0), (8, 8), (8, 0)]          # counter-clockwise first triangle
STRIP_AS_LIST = [(0, 1, 2), (2, 1, 3), (2, 3, 4), (4, 3, 5)]
FAN = [(0, 0), (8, 0), (8, 3), (8, 8), (3, 8), (0, 8)]
FAN_AS_LIST = [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)]
VCOLORS = np.array([[k / 8, 1 - k / 8, (k % 3) / 4] for k in range(6)])
PERM = np.array([3, 5, 0, 4, 1, 2])            # vertex k is stored at row PERM[k] of the shuffled arrays


def draw_flat(points, topology, indices=None, colors=VCOLORS, cull="none"):
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    softpipe.draw(fb, window_to_clip(points, S, S), indices, varyings={"color": colors}, topology=topology,
                  interpolation={"color": "flat"}, cull=cull)
    return fb.color.copy()


def shuffled(points):
    pts = [None] * len(points)
    for k, p in enumerate(points):
        pts[PERM[k]] = p
    cols = np.empty_like(VCOLORS)
    cols[PERM] = VCOLORS
    return pts, cols


@pytest.mark.parametrize("topology, points, as_list", [
    ("triangle_strip", STRIP, STRIP_AS_LIST),
    ("triangle_fan", FAN, FAN_AS_LIST),
])
def test_strips_and_fans_match_the_equivalent_triangle_list(topology, points, as_list):
    from_list = draw_flat(points, "triangles", np.array(as_list))
    # the list itself: every triangle shows the color of its last vertex
    want = np.zeros((S, S, 4), np.float32)
    for tri in as_list:
        want[image_cells(cells_of([points[k] for k in tri]))] = (*VCOLORS[tri[2]], 1)
    assert np.array_equal(from_list, want)
    assert (want[..., 3] == 1).all()

    assert np.array_equal(draw_flat(points, topology), from_list)
    pts, cols = shuffled(points)
    seq = PERM[np.arange(len(points))]
    assert np.array_equal(draw_flat(pts, topology, seq, cols), from_list)
    assert np.array_equal(draw_flat(pts, "triangles", PERM[np.array(as_list)], cols), from_list)          # [M, 3]
    assert np.array_equal(draw_flat(pts, "triangles", PERM[np.array(as_list)].reshape(-1), cols), from_list)  # [M]


@pytest.mark.parametrize("topology, points", [("triangle_strip", STRIP), ("triangle_fan", FAN)])
def test_every_triangle_of_a_strip_or_fan_keeps_the_first_ones_winding(topology, points):
    everything = draw_flat(points, topology)
    assert np.array_equal(draw_flat(points, topology, cull="back"), everything)
    assert (draw_flat(points, topology, cull="front")[..., 3] == 0).all()


def test_strip_primitive_ids_count_triangles():
    prims = softpipe.assemble(run_vertex_stage(window_to_clip(STRIP, S, S)), "triangle_strip",
                              viewport=softpipe.Viewport(0, 0, S, S))
    assert list(prims.primitive_id) == [0, 1, 2, 3] and prims.input_count == 4
    # the corners of triangle 1 are vertices (2, 1, 3), in that order
    want = window_to_clip(STRIP, S, S)[[2, 1, 3], :2]
    np.testing.assert_allclose((prims.window[1, :, :2] / S) * 2 - 1, want, atol=1e-15)
    assert prims.front_facing.all()


@pytest.mark.parametrize("n", [0, 1, 2])
def test_strips_and_fans_with_fewer_than_three_vertices_draw_nothing(n):
    for topology in ("triangle_strip", "triangle_fan"):
        fb = softpipe.Framebuffer(S, S)
        pos = window_to_clip(STRIP[:n], S, S) if n else np.zeros((0, 4))
        softpipe.draw(fb, pos, varyings={"color": np.ones((n, 3))},
                      topology=topology)
        assert (fb.color == (0, 0, 0, 1)).all()


@pytest.mark.parametrize("dtype", [np.int8, np.uint16, np.int32, np.uint64])
def test_indices_of_any_integer_dtype(dtype):
    pts, cols = shuffled(FAN)
    want = draw_flat(FAN, "triangle_fan")
    assert np.array_equal(draw_flat(pts, "triangle_fan", PERM.astype(dtype), cols), want)


def test_indices_may_repeat_and_skip_vertices():
    # two vertices that no index uses (NaN, even): they are never assembled
    pts = window_to_clip(CCW, S, S)
    pos = np.vstack([np.full((1, 4), np.nan), pts, np.full((1, 4), np.nan)])
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, [1, 2, 3, 3, 2, 1], varyings={"color": np.ones((5, 3))}, depth_test=None,
                  blend="additive")
    # the same triangle twice (once each winding): every pixel written twice
    assert np.array_equal(fb.color[..., 3] == 2, image_cells(cells_of(CCW)))
    assert set(np.unique(fb.color[..., 3])) == {0.0, 2.0}


# -------------------------------------------------------- Primitives.dropped

def test_dropped_reports_culled_outside_and_non_finite_ids():
    g = 32768 / (S / 2)                  # the guard band, in NDC units, for an 8-pixel viewport
    eye_cross = [(-1.5, -1.0, -0.5), (2.0, -1.5, -2.5), (0.5, 2.0, -2.0)]   # crosses the near plane, CCW
    c = clip_of(eye_cross)
    tris = [
        window_to_clip(CCW, S, S),                                   # 0: drawn
        window_to_clip(CW, S, S),                                    # 1: back-facing → culled
        np.array([[0, 0, 2, 1], [1, 0, 2, 1], [0, 1, 2, 1.0]]),     # 2: beyond the far plane → outside
        np.array([[0, 0, 0, 1], [np.nan, 0, 0, 1], [0, 1, 0, 1.0]]),  # 3: non-finite
        c,                                                           # 4: clipped into pieces, drawn
        # 5: outside the clip volume though no single plane rejects all its corners:
        #    x ≤ g needs a ≥ ½ in P + a(Q − P) + b(R − P), and then z ≥ 1.75 > w
        np.array([[g + 2, 0, 0.5, 1], [g - 2, 1, 3, 1], [g + 2, 2, 3, 1]]),
        c[[0, 2, 1]],                                                # 6: clipped and back-facing → culled
    ]
    vout = run_vertex_stage(np.concatenate(tris))
    prims = softpipe.assemble(vout, viewport=softpipe.Viewport(0, 0, S, S), cull="back")
    assert prims.input_count == 7
    assert list(prims.dropped["non-finite"]) == [3]
    assert list(prims.dropped["outside"]) == [2, 5]
    assert list(prims.dropped["culled"]) == [1, 6]
    assert set(prims.primitive_id) == {0, 4}
    assert list(prims.primitive_id) == sorted(prims.primitive_id)          # pieces stay in primitive order
    assert (prims.primitive_id == 4).sum() == 2                             # a quadrilateral: two pieces
    assert list(prims.clipped) == [pid == 4 for pid in prims.primitive_id]
    assert prims.front_facing.all()
    # with no culling the back-facing ones come back
    prims = softpipe.assemble(vout, viewport=softpipe.Viewport(0, 0, S, S), cull="none")
    assert len(prims.dropped["culled"]) == 0
    assert set(prims.primitive_id) == {0, 1, 4, 6}
    assert list(prims.front_facing) == [pid in (0, 4) for pid in prims.primitive_id]


def test_dropped_ids_refer_to_strip_triangles():
    pts = window_to_clip(STRIP, S, S)
    pts[4] = np.inf                       # vertex 4 is in strip triangles 2 and 3
    with np.errstate(invalid="ignore"):
        prims = softpipe.assemble(run_vertex_stage(pts), "triangle_strip", viewport=softpipe.Viewport(0, 0, S, S))
    assert list(prims.dropped["non-finite"]) == [2, 3]
    assert list(prims.primitive_id) == [0, 1]


@pytest.mark.parametrize("case", ["all kept", "one culled", "one clipped", "one outside"])
def test_unindexed_list_gives_what_indices_in_order_give(case):
    """A triangle list without indices whose triangles are all kept whole reuses the vertex arrays
    as the corner arrays; the result must be what the general path (indices 0, 1, 2, …) gives."""
    rng = np.random.default_rng(4)
    tris = rng.uniform(0.5, 7.5, (6, 3, 2))
    tris[::2, [1, 2]] = tris[::2, [2, 1]]          # windings of both kinds
    z = rng.uniform(-0.5, 0.5, (6, 3, 1))
    pos = window_to_clip(np.concatenate([tris, z], axis=2).reshape(-1, 3), S, S) * rng.uniform(0.5, 2, (18, 1))
    if case == "one clipped":
        pos[4, 2] = -2 * pos[4, 3]                 # behind the near plane
    elif case == "one outside":
        pos[3:6, 0] = 1e5 * pos[3:6, 3]            # far right, beyond the guard band
    vout = run_vertex_stage(pos, {"color": rng.uniform(0, 1, (18, 3)), "t": rng.uniform(0, 1, 18)})
    vp = softpipe.Viewport(0, 0, S, S)
    cull = "back" if case == "one culled" else "none"
    a = softpipe.assemble(vout, viewport=vp, cull=cull)
    b = softpipe.assemble(vout, indices=np.arange(18), viewport=vp, cull=cull)
    for name in ("window", "inv_w", "varyings", "primitive_id", "front_facing", "clipped"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert {k: list(v) for k, v in a.dropped.items()} == {k: list(v) for k, v in b.dropped.items()}
    assert (len(a) == 6) == (case == "all kept")


def test_a_huge_unsigned_index_is_reported_as_it_is_not_wrapped_negative():
    import softpipe as sp
    clip = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]], float)
    idx = np.array([0, 1, 2, 0, 1, 2**64 - 1], dtype=np.uint64)
    with pytest.raises(ValueError, match=r"indices\[5\] = 18446744073709551615 is out of range for 3 vertices"):
        sp.draw(sp.Framebuffer(8, 8), clip, idx, varyings={"color": np.ones((3, 3))})


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.uint32, np.int32])
def test_an_index_past_the_vertices_is_named_whatever_its_integer_type(dtype):
    import softpipe as sp
    clip = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]], float)
    idx = np.array([0, 1, 2, 2, 1, 200], dtype=dtype)
    with pytest.raises(ValueError, match=r"indices\[5\] = 200 is out of range for 3 vertices"):
        sp.draw(sp.Framebuffer(8, 8), clip, idx, varyings={"color": np.ones((3, 3))})
