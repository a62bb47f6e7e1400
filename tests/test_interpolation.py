"""Varying interpolation (smooth, noperspective, flat) and the fragment shader's inputs.

The receding plane: a floor y = −1 in eye space, x ∈ [−5, 5], from z = −1 to
z = −5, seen through ``softpipe.perspective(90°, 1, 0.5, 10)`` on a 10×10
framebuffer. With cot(45°) = 1, x_ndc = x/(−z) and y_ndc = y/(−z), so its
window corners are (−20, 0), (30, 0) (near edge) and (10, 4), (0, 4) (far
edge): all on the 1/256 grid, so snapping moves nothing. It covers window rows
0–3 (centres 0.5 … 3.5) completely.

The ray through a pixel centre with NDC (x_n, y_n) is t·(x_n, y_n, −1); it
meets the floor at t = −1/y_n, so there

    z_eye = 1/y_n,   x_eye = −x_n/y_n     (perspective-correct, "smooth")

while a varying interpolated linearly in window space ("noperspective") goes
from −1 at y_w = 0 to −5 at y_w = 4: z = −1 − y_w (the values at the four
corners fit that affine function, so both triangles agree with it).
"""
import numpy as np
import pytest
import reference
from conftest import window_to_clip

import softpipe

N = 10
PROJ = softpipe.perspective(90.0, 1.0, 0.5, 10.0)
FLOOR = np.array([[-5, -1, -1], [5, -1, -1], [5, -1, -5], [-5, -1, -5]], dtype=float)
FLOOR_IDX = np.array([[0, 1, 2], [0, 2, 3]])


def floor_clip():
    hom = np.hstack([FLOOR, np.ones((4, 1))])
    return (PROJ @ hom.T).T


def show_eye(varyings, uniforms, frag):
    """x_eye and z_eye (smooth) and z_eye (noperspective), written into the color."""
    return (varyings.eye[0], varyings.eye[2], varyings.eye_np[2], 1.0)


def draw_floor():
    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    softpipe.draw(fb, floor_clip(), FLOOR_IDX, varyings={"eye": FLOOR, "eye_np": FLOOR},
                  fragment_shader=show_eye, interpolation={"eye_np": "noperspective"})
    return fb


def test_floor_covers_exactly_window_rows_0_to_3():
    fb = draw_floor()
    drawn = fb.color[..., 3] == 1.0
    want = np.zeros((N, N), bool)
    want[N - 4:, :] = True                        # image rows 6–9 = window rows 0–3
    assert np.array_equal(drawn, want)


@pytest.mark.parametrize("i, j", [(0, 0), (5, 0), (9, 1), (2, 2), (7, 3), (4, 3)])
def test_smooth_varying_is_perspective_correct_on_the_receding_plane(i, j):
    fb = draw_floor()
    x_n, y_n = (i + 0.5) / 5 - 1, (j + 0.5) / 5 - 1
    z_eye, x_eye = 1 / y_n, -x_n / y_n
    r, g, _, _ = fb.color[N - 1 - j, i]
    assert g == pytest.approx(z_eye, rel=1e-6)
    assert r == pytest.approx(x_eye, rel=1e-6, abs=1e-6)


def test_smooth_depth_varying_at_every_covered_pixel():
    fb = draw_floor()
    for j in range(4):
        y_n = (j + 0.5) / 5 - 1
        np.testing.assert_allclose(fb.color[N - 1 - j, :, 1], 1 / y_n, rtol=1e-6)
        # and it is not the linear-in-window value (which the test would catch)
        assert abs(1 / y_n - (-1 - (j + 0.5))) > 0.3


def test_noperspective_varying_is_linear_in_window_space():
    fb = draw_floor()
    for j in range(4):
        np.testing.assert_allclose(fb.color[N - 1 - j, :, 2], -1 - (j + 0.5), rtol=1e-6)


def test_standard_vertex_shader_gives_the_same_perspective_correct_eye_position():
    def show_position(varyings, uniforms, frag):
        p = varyings.position
        return (p[0], p[2], 0.0, 1.0)

    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    normals = np.tile([0.0, 1.0, 0.0], (4, 1))
    softpipe.draw(fb, FLOOR, FLOOR_IDX, vertex_shader=softpipe.standard_vertex, fragment_shader=show_position,
                  attributes={"normal": normals},
                  uniforms={"model_view": np.eye(4), "projection": PROJ, "normal_matrix": np.eye(3)})
    for j in range(4):
        x_n = (np.arange(N) + 0.5) / 5 - 1
        y_n = (j + 0.5) / 5 - 1
        np.testing.assert_allclose(fb.color[N - 1 - j, :, 1], 1 / y_n, rtol=1e-6)
        np.testing.assert_allclose(fb.color[N - 1 - j, :, 0], -x_n / y_n, rtol=1e-6, atol=1e-6)
    assert (fb.color[:N - 4, :, 3] == 0).all()


# ------------------------------------------------------------- flat: provoking vertex
#
# Each case lists the vertices (window coordinates, 8×8), and by hand the
# triangles the topology makes (as vertex numbers, OpenGL 4.6 §10.1) and the
# provoking vertex of each: the last, v_{i+2} for strips and fans.

S = 8
COLORS = np.array([[k / 8, 1 - k / 8, (k % 2) / 2] for k in range(8)])

FLAT_CASES = {
    "triangles": ([(0, 0), (8, 0), (0, 8), (8, 0), (8, 8), (0, 8)],
                  [((0, 1, 2), 2), ((3, 4, 5), 5)]),
    "triangle_strip": ([(0, 0), (0, 8), (3, 0), (5, 8), (8, 0), (8, 8)],
                       [((0, 1, 2), 2), ((1, 2, 3), 3), ((2, 3, 4), 4), ((3, 4, 5), 5)]),
    "triangle_fan": ([(0, 0), (8, 0), (8, 3), (8, 8), (3, 8), (0, 8)],
                     [((0, 1, 2), 2), ((0, 2, 3), 3), ((0, 3, 4), 4), ((0, 4, 5), 5)]),
}


@pytest.mark.parametrize("topology", list(FLAT_CASES))
def test_flat_takes_the_last_vertex_of_each_triangle(topology):
    points, tris = FLAT_CASES[topology]
    n = len(points)
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    softpipe.draw(fb, window_to_clip(points, S, S), varyings={"color": COLORS[:n]}, topology=topology,
                  interpolation={"color": "flat"})
    want = np.zeros((S, S, 4), np.float32)
    for corners, provoking in tris:
        cells = reference.covered([points[k] for k in corners], S, S)
        assert cells, "every triangle of the case covers some pixel"
        for i, j, _ in cells:
            want[S - 1 - j, i] = (*COLORS[provoking], 1.0)
    assert (want[..., 3] == 1).all(), "the cases tile the framebuffer"
    assert np.array_equal(fb.color, want)


def test_smooth_color_differs_from_flat():
    # the same strip without the flat qualifier: interior pixels are blends, not vertex colors
    points, _ = FLAT_CASES["triangle_strip"]
    fb = softpipe.Framebuffer(S, S)
    softpipe.draw(fb, window_to_clip(points, S, S), varyings={"color": COLORS[:6]}, topology="triangle_strip")
    vertex_colors = {tuple(np.float32(c)) for c in COLORS}
    assert sum(tuple(fb.color[r, c, :3]) not in vertex_colors for r in range(S) for c in range(S)) > S * S // 2


# ----------------------------------------------------------------- fragment inputs

def show_frag(varyings, uniforms, frag):
    """gl_FragCoord.xyz and 2·primitive_id + front_facing, as the color."""
    facing = 1.0 if frag.front_facing else 0.0
    return (frag.x, frag.y, frag.z, 2.0 * frag.primitive_id + facing)


def test_fragment_shader_sees_frag_coord_depth_facing_and_primitive_id():
    # T0: counter-clockwise (front), window depth (x + 2y)/64.
    # T1: entirely beyond the far plane (z = 2w): dropped, but it keeps id 1.
    # T2: clockwise (back), window depth 1/2 + (x − y)/64.
    t0 = [(0, 0, 0.0), (4, 0, 1 / 16), (0, 4, 1 / 8)]
    t2 = [(8, 8, 0.5), (8, 4, 0.5625), (4, 8, 0.4375)]
    pos0 = window_to_clip([(x, y, 2 * z - 1) for x, y, z in t0], S, S)
    pos2 = window_to_clip([(x, y, 2 * z - 1) for x, y, z in t2], S, S)
    pos1 = np.array([[0.0, 0, 2, 1], [1.0, 0, 2, 1], [0.0, 1, 2, 1]])
    fb = softpipe.Framebuffer(S, S).clear((0, 0, 0, 0))
    softpipe.draw(fb, np.concatenate([pos0, pos1, pos2]), fragment_shader=show_frag, depth_test="always")

    want = np.zeros((S, S, 4), np.float32)
    want_depth = np.ones((S, S), np.float32)
    for tri, depth, tag in [(t0, lambda x, y: (x + 2 * y) / 64, 0 * 2 + 1),
                            (t2, lambda x, y: 0.5 + (x - y) / 64, 2 * 2 + 0)]:
        cells = reference.covered([p[:2] for p in tri], S, S)
        assert len(cells) >= 6
        for i, j, _ in cells:
            x, y = i + 0.5, j + 0.5
            want[S - 1 - j, i] = (x, y, depth(x, y), tag)
            want_depth[S - 1 - j, i] = depth(x, y)
    assert np.array_equal(fb.color, want), f"got\n{fb.color}\nwant\n{want}"
    assert np.array_equal(fb.depth, want_depth)
