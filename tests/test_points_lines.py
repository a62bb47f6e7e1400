"""Points and lines through the pipeline (issue 29): topologies, joints, clipping, interpolation, depth,
points' sizes and gl_PointCoord, polygon mode, and the errors.

Which pixels a segment or a point produces is checked exhaustively against the rational reference
in tests/test_lines_points_exact.py; here each test states its own pixels or formula.

Window coordinates (y up, pixel (x, y) centred at (x + ½, y + ½)) are turned into clip
coordinates with w = 1 and binary fractions, so they arrive exactly.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.sampling import pattern_named

W = H = 16


def clip(points, z=0.0, w=1.0):
    """Window positions (x, y) → clip coordinates for a W × H viewport (exact for binary fractions)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(p), 4))
    out[:, 0] = (2.0 * p[:, 0] / W - 1.0) * w
    out[:, 1] = (2.0 * p[:, 1] / H - 1.0) * w
    out[:, 2] = np.broadcast_to(z, len(p)) * w if np.ndim(z) else z * w
    out[:, 3] = w
    return out


def hits(fb) -> dict:
    """{(x, y) window pixel: times drawn} from an additive draw of color 1/64 per hit."""
    counts = np.rint(fb.color[..., 0] * 64).astype(int)
    return {(int(x), int(H - 1 - r)): int(counts[r, x]) for r, x in zip(*np.nonzero(counts))}


def draw_hits(points, topology, **state):
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    n = len(points)
    sp.draw(fb, clip(points), topology=topology, varyings={"color": np.full((n, 3), 1 / 64)},
            depth_test=None, blend="additive", **state)
    return hits(fb)


# ------------------------------------------------------------------ topologies and joints

def test_a_horizontal_line_from_centre_to_centre_leaves_out_its_last_pixel():
    assert draw_hits([(2.5, 3.5), (9.5, 3.5)], "lines") == {(x, 3): 1 for x in range(2, 9)}


def test_a_vertical_line_going_down_leaves_out_its_last_pixel():
    assert draw_hits([(4.5, 12.5), (4.5, 5.5)], "lines") == {(4, y): 1 for y in range(6, 13)}


def test_a_closed_loop_hits_every_pixel_of_its_outline_exactly_once_joints_included():
    corners = [(2.5, 2.5), (13.5, 2.5), (13.5, 11.5), (2.5, 11.5)]
    outline = ({(x, 2) for x in range(2, 14)} | {(x, 11) for x in range(2, 14)}
               | {(2, y) for y in range(2, 12)} | {(13, y) for y in range(2, 12)})
    assert draw_hits(corners, "line_loop") == dict.fromkeys(outline, 1)


def test_a_strip_is_its_segments_drawn_one_by_one_and_each_joint_pixel_is_hit_once():
    points = [(1.3, 1.1), (6.6, 9.2), (9.1, 3.7), (14.2, 12.9), (3.05, 14.6)]
    strip = draw_hits(points, "line_strip")
    separate: dict = {}
    for a, b in zip(points[:-1], points[1:]):
        for p, k in draw_hits([a, b], "lines").items():
            separate[p] = separate.get(p, 0) + k
    assert separate == strip
    # the pixel whose diamond holds a joint is drawn by one segment only: (6.6, 9.2) is in the diamond
    # of (6, 9), |0.1| + |−0.3| < ½ (the joints (9.1, 3.7) and (14.2, 12.9) lie in no diamond)
    assert strip[(6, 9)] == 1
    # the rule keeps joints from a double hit, not a sharp turn: at (6.6, 9.2) the first segment
    # (going up) and the second (coming down) both cross the diamond of pixel (6, 8) below the joint
    assert strip[(6, 8)] == 2


def test_a_convex_loop_whose_joints_lie_in_diamonds_hits_every_pixel_once():
    corners = [(3.6, 1.4), (11.4, 2.6), (14.4, 8.6), (9.6, 14.3), (2.7, 11.5)]
    loop = draw_hits(corners, "line_loop")
    assert set(loop.values()) == {1} and len(loop) == sum(
        len(draw_hits([a, b], "lines")) for a, b in zip(corners, corners[1:] + corners[:1]))


def test_a_line_list_pairs_vertices_and_a_strip_joins_them_through_indices():
    points = [(1.5, 1.5), (7.5, 1.5), (7.5, 6.5), (1.5, 6.5)]
    fb_list, fb_strip = sp.Framebuffer(W, H), sp.Framebuffer(W, H)
    color = {"color": np.ones((4, 3))}
    sp.draw(fb_list, clip(points), np.array([[0, 1], [1, 2], [2, 3]]), topology="lines", varyings=color)
    sp.draw(fb_strip, clip(points), np.array([0, 1, 2, 3]), topology="line_strip", varyings=color)
    assert (fb_list.color == fb_strip.color).all() and fb_list.color[..., 0].sum() == 6 + 5 + 6


@pytest.mark.parametrize("topology, indices, message", [
    ("lines", None, "a line list needs an even number of vertices, got 3"),
    ("lines", np.array([[0, 1, 2]]), r"indices must have shape \[M\] or \[M, 2\], got \[1, 3\]"),
    ("line_strip", np.array([[0, 1]]), r"indices for a line_strip must be 1-D, got shape \[1, 2\]"),
    ("lines", np.array([0, 5]), r"indices\[1\] = 5 is out of range for 3 vertices"),
    ("quads", None, "topology must be one of"),
])
def test_a_bad_topology_or_index_array_is_named(topology, indices, message):
    with pytest.raises(ValueError, match=message):
        sp.draw(sp.Framebuffer(4, 4), clip([(0, 0), (1, 1), (2, 2)]), indices, topology=topology,
                varyings={"color": np.ones((3, 3))})


@pytest.mark.parametrize("state, message", [
    ({"point_size": 0}, "point_size must be a finite number of pixels > 0, got 0"),
    ({"line_width": float("nan")}, "line_width must be a finite number of pixels > 0, got nan"),
    ({"point_size": "big"}, "point_size must be a number of pixels, got 'big'"),
    ({"polygon_mode": "wire"}, "polygon_mode must be one of"),
])
def test_a_bad_size_or_polygon_mode_is_named(state, message):
    with pytest.raises(ValueError, match=message):
        sp.draw(sp.Framebuffer(4, 4), clip([(0, 0), (1, 1)]), topology="lines",
                varyings={"color": np.ones((2, 3))}, **state)


# ------------------------------------------------------------------ wide lines

def test_a_wide_x_major_line_is_a_run_of_round_width_fragments_up_from_the_moved_line():
    # width 3: the line moved down by 1 runs along row 2, and each fragment is a run of 3 up: rows 2–4
    assert draw_hits([(2.5, 3.5), (9.5, 3.5)], "lines", line_width=3) == {
        (x, y): 1 for x in range(2, 9) for y in (2, 3, 4)}
    # width 2.5 rounds to 3; width 2: moved down by ½, the line runs along the diamonds' corners of
    # rows 2 and 3 (y = 3.0) — the perturbation (ε, ε²) puts it just below, in row 2 — then 2 up
    assert draw_hits([(2.5, 3.5), (9.5, 3.5)], "lines", line_width=2.5) == draw_hits(
        [(2.5, 3.5), (9.5, 3.5)], "lines", line_width=3)
    assert draw_hits([(2.5, 3.5), (9.5, 3.5)], "lines", line_width=2) == {
        (x, y): 1 for x in range(2, 9) for y in (2, 3)}


def test_a_wide_y_major_line_runs_across_to_the_right():
    assert draw_hits([(6.5, 2.5), (6.5, 8.5)], "lines", line_width=3) == {
        (x, y): 1 for x in (5, 6, 7) for y in range(2, 8)}


# ------------------------------------------------------------------ interpolation and depth

def _traced_line(a, b, za, zb, wa, wb, interpolation=None):
    fb = sp.Framebuffer(W, H)
    pos = np.vstack([clip([a], za, wa), clip([b], zb, wb)])
    values = np.array([[0.0, 10.0, 0.0], [1.0, 30.0, 0.0]])
    varyings = {"t": values[:, 0], "v": values[:, 1], "f": np.array([5.0, 7.0])}
    return sp.draw(fb, pos, topology="lines", varyings=varyings, interpolation=interpolation,
                   fragment_shader=lambda v, u, f: (v.t, v.v / 64, v.f / 8, 1.0), trace=True)


def test_depth_and_varyings_along_a_line_follow_the_formula_at_every_fragment():
    a, b, za, zb, wa, wb = (1.5, 2.25), (13.75, 9.5), -0.5, 0.25, 1.0, 4.0
    trace = _traced_line(a, b, za, zb, wa, wb, {"v": "noperspective", "f": "flat"})
    frags, color = trace.fragments, trace.shaded.color
    assert len(frags) == 12        # x-major: columns 1 … 12 (b's pixel, 13, holds b: left out)
    # the snapped ends, in pixels (pixel centres at +½)
    (xa, ya), (xb, yb) = (np.rint((np.array(p) - 0.5) * 256) / 256 + 0.5 for p in (a, b))
    for k in range(len(frags)):
        px, py = frags.x[k] + 0.5, H - 1 - frags.y[k] + 0.5
        t = min(max(((px - xa) * (xb - xa) + (py - ya) * (yb - ya)) / ((xb - xa) ** 2 + (yb - ya) ** 2), 0.0), 1.0)
        # window depth is linear in t (the depth range maps z/w from [−1, 1] to [0, 1]; clip() made z/w = z)
        z = (1 - t) * (za + 1) / 2 + t * (zb + 1) / 2
        assert frags.depth[k] == pytest.approx(z, abs=1e-12)
        # smooth: perspective-correct, weights (1 − t)/w_a and t/w_b
        smooth = (t / wb) / ((1 - t) / wa + t / wb)
        assert color[k, 0] == pytest.approx(smooth, abs=1e-6)
        assert color[k, 1] == pytest.approx((10 + 20 * t) / 64, abs=1e-6)         # noperspective
        assert color[k, 2] == pytest.approx(7.0 / 8)                                 # flat: the last end's


def test_a_line_clipped_by_the_near_plane_keeps_its_varyings_on_the_segment():
    # b is behind the near plane: clipping moves it to z = −w, where t_clip = 2/3 of the way in clip space
    trace = _traced_line((2.5, 4.5), (14.5, 4.5), 0.0, -3.0, 1.0, 1.0)
    prims = trace.primitives
    assert prims.clipped.tolist() == [True]
    new_end = prims.window[0, 1]
    assert new_end[2] == pytest.approx(0.0) and new_end[0] == pytest.approx(2.5 + 12 * (1 / 3))
    assert trace.shaded.color[:, 0].max() <= 1 / 3 + 1e-9


def test_a_line_crossing_the_viewport_edge_keeps_the_rule_inside_the_viewport():
    # x from 3.5 to 40.5 (past the right edge at 16): the guard band keeps the segment whole and the
    # viewport cuts the pixels, so the last column inside (15) is drawn, as for an unclipped line
    assert draw_hits([(3.5, 5.5), (40.5, 5.5)], "lines") == {(x, 5): 1 for x in range(3, 16)}


def test_points_and_lines_face_the_front_and_are_not_culled():
    for topology in ("points", "lines"):
        fb = sp.Framebuffer(W, H)
        trace = sp.draw(fb, clip([(2.5, 2.5), (9.5, 2.5)]), topology=topology, cull="front",
                        fragment_shader=lambda v, u, f: (1.0, 1.0, 1.0, 1.0) if f.front_facing else (0.0, 0.0, 0.0, 1.0),
                        trace=True)
        assert len(trace.fragments) and (trace.shaded.color[:, 0] == 1).all()


# ------------------------------------------------------------------ points

@pytest.mark.parametrize("size, centre, pixels", [
    (1, (4.5, 4.5), [(4, 4)]),
    (0.75, (4.5, 4.5), [(4, 4)]),                       # clamped to 1
    (2, (5.0, 5.0), [(4, 4), (5, 4), (4, 5), (5, 5)]),  # centres 4.5 and 5.5 in [4, 6)
    (2, (4.5, 4.5), [(3, 3), (4, 3), (3, 4), (4, 4)]),  # [3.5, 5.5): 3.5 in, 5.5 out
    (3, (4.5, 4.5), [(x, y) for x in (3, 4, 5) for y in (3, 4, 5)]),
])
def test_a_point_covers_the_pixel_centres_in_its_half_open_square(size, centre, pixels):
    assert draw_hits([centre], "points", point_size=size) == dict.fromkeys(pixels, 1)


def test_a_point_outside_the_view_volume_is_discarded_whole():
    # a 5-pixel point centred just left of the viewport would reach into it; GL discards it
    assert draw_hits([(-0.25, 8.5), (3.5, 8.5)], "points", point_size=5) == {
        (x, y): 1 for x in range(1, 6) for y in range(6, 11)}


def test_point_size_per_vertex_from_the_vertex_shader_varying():
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    sizes = np.array([1.0, 3.0, 300.0])
    pos = clip([(2.5, 2.5), (8.5, 8.5), (8.5, 8.5)])
    pos[2, 3] = np.nan  # dropped: a non-finite position
    trace = sp.draw(fb, pos, topology="points", varyings={"point_size": sizes, "color": np.ones((3, 3))},
                    trace=True)
    assert trace.primitives.size.tolist() == [1.0, 3.0]
    assert len(trace.fragments) == 1 + 9


def test_gl_point_coord_runs_from_the_upper_left_corner_and_draws_a_round_point():
    fb = sp.Framebuffer(W, H)

    def round_point(varyings, uniforms, frag):
        s, t = frag.point_coord
        if (s - 0.5) ** 2 + (t - 0.5) ** 2 > 0.25:
            return sp.DISCARD
        return (s, t, 1.0, 1.0)

    trace = sp.draw(fb, clip([(8.0, 8.0)]), topology="points", point_size=8, fragment_shader=round_point,
                    trace=True)
    f, color = trace.fragments, trace.shaded
    for k in range(len(f)):
        x, y = f.x[k] + 0.5, H - f.y[k] - 0.5             # window position of the fragment's centre
        s, t = 0.5 + (x - 8.0) / 8, 0.5 - (y - 8.0) / 8
        inside = (s - 0.5) ** 2 + (t - 0.5) ** 2 <= 0.25
        assert bool(color.discarded[k]) == (not inside)
        if inside:
            assert color.color[k, 0] == pytest.approx(s) and color.color[k, 1] == pytest.approx(t)
    # the upper-left pixel of the square (image row 4, column 4) has the smallest s and t
    assert len(f) == 64 and int(color.discarded.sum()) == 64 - 52


# ------------------------------------------------------------------ polygon mode

def test_polygon_mode_line_draws_each_kept_triangles_edges_with_its_provoking_vertex():
    pos = clip([(2.5, 2.5), (12.5, 2.5), (2.5, 12.5), (12.5, 12.5)])
    tris = np.array([[0, 1, 2], [1, 2, 3]])            # the second is clockwise: culled as a back face
    fb = sp.Framebuffer(W, H)
    trace = sp.draw(fb, pos, tris, varyings={"c": np.array([0.1, 0.2, 0.3, 0.4])},
                    interpolation={"c": "flat"}, fragment_shader=lambda v, u, f: (v.c, f.primitive_id, 0.0, 1.0),
                    polygon_mode="line", cull="back", trace=True)
    assert trace.primitives.kind == "lines" and len(trace.primitives) == 3
    assert set(trace.shaded.color[:, 0].round(6)) == {np.float32(0.3).round(6)}   # vertex 2's, the provoking one
    assert set(trace.shaded.color[:, 1]) == {0.0}                                   # the triangle's id
    drawn = {(int(x), int(H - 1 - y)) for x, y in zip(trace.fragments.x, trace.fragments.y)}
    # (2.5, 2.5)→(12.5, 2.5) leaves out (12, 2), which (12.5, 2.5)→(2.5, 12.5) starts at; that one
    # leaves out (2, 12), where (2.5, 12.5)→(2.5, 2.5) starts, which leaves out (2, 2)
    assert drawn == ({(x, 2) for x in range(2, 12)} | {(12 - k, 2 + k) for k in range(10)}
                     | {(2, y) for y in range(3, 13)})


def test_polygon_mode_point_draws_each_triangles_corners():
    pos = clip([(2.5, 2.5), (12.5, 2.5), (2.5, 12.5)])
    assert draw_hits([(2.5, 2.5), (12.5, 2.5), (2.5, 12.5)], "triangles", polygon_mode="point",
                     point_size=3) == {(x + dx, y + dy): 1 for x, y in ((2, 2), (12, 2), (2, 12))
                                       for dx in (-1, 0, 1) for dy in (-1, 0, 1)}
    assert len(pos) == 3


# ------------------------------------------------------------------ multisampling

def test_a_line_on_a_multisample_framebuffer_covers_every_sample_of_its_pixels():
    fb = sp.Framebuffer(W, H, pattern=pattern_named("rgss4"))
    trace = sp.draw(fb, clip([(2.5, 3.5), (9.5, 3.5)]), topology="lines", varyings={"color": np.ones((2, 3))},
                    trace=True)
    assert len(trace.fragments) == 7 * 4
    assert (fb.samples_color[:, H - 1 - 3, 2:9, 0] == 1).all() and fb.samples_color[:, H - 1 - 3, 9, 0].max() == 0
