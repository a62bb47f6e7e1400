"""Homogeneous clipping, seen through softpipe.draw, against an exact clipper written here.

The expected pixels come from clipping the triangle in homogeneous clip
coordinates with Fractions (Sutherland–Hodgman against the near plane
z ≥ −w and the far plane z ≤ w, which together also keep w ≥ 0), dividing and
mapping to the window exactly, and covering the resulting convex polygon with
the exact reference rasterizer (tests/reference.py ``covered()``, one fan
triangle at a time).

softpipe computes the new vertices in float64 and snaps them to 1/256 pixel,
exactly as it snaps any vertex; the reference snaps the exact new vertices.
The two can differ only for a pixel centre lying within a rounding error of an
edge through a new vertex, so a difference is allowed only for pixel centres
within 1/128 pixel of such a "clipped edge" (an edge of the clipped polygon with
at least one new vertex). In the scenes below no such difference actually
occurs, but the allowance is what the rules promise.

Eye-space vertices are dyadic, and the projection is the exact matrix of
perspective(90°, 1, near=1, far=3), so the clip coordinates given to softpipe
are exact floats.
"""
from fractions import Fraction as F

import numpy as np
import pytest
import reference
from conftest import window_to_clip

import softpipe

N = 16
P = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -2, -3], [0, 0, -1, 0]]   # perspective(90, 1, 1, 3)


def test_the_exact_projection_is_softpipes():
    np.testing.assert_allclose(softpipe.perspective(90.0, 1.0, 1.0, 3.0), np.array(P, float), atol=1e-15)


def to_clip(eye):
    e = [F(c) for c in eye] + [F(1)]
    return tuple(sum(P[r][c] * e[c] for c in range(4)) for r in range(4))


# ------------------------------------------------------------ the exact clipper

NEAR = lambda p: p[2] + p[3]          # noqa: E731  z ≥ −w
FAR = lambda p: p[3] - p[2]           # noqa: E731  z ≤ w


def clip_exact(corners, planes=(NEAR, FAR)):
    """Clip a polygon of (clip position, varying tuple, is_new) in exact arithmetic."""
    poly = list(corners)
    for plane in planes:
        out = []
        for k in range(len(poly)):
            a, b = poly[k], poly[(k + 1) % len(poly)]
            da, db = plane(a[0]), plane(b[0])
            if da >= 0:
                out.append(a)
            if (da >= 0) != (db >= 0):
                t = da / (da - db)
                pos = tuple(pa + t * (pb - pa) for pa, pb in zip(a[0], b[0]))
                var = tuple(va + t * (vb - va) for va, vb in zip(a[1], b[1]))
                out.append((pos, var, True))
        poly = out
    return poly


def window(pos, w=N, h=N):
    x, y, z, ww = pos
    assert ww > 0
    return ((x / ww + 1) * w / 2, (y / ww + 1) * h / 2, (z / ww + 1) / 2)


def polygon_coverage(win):
    """Pixels (i, j) of a convex window polygon: the union of its fan triangles' exact coverage."""
    cells = set()
    for k in range(1, len(win) - 1):
        cells |= {(i, j) for i, j, _ in reference.covered([win[0][:2], win[k][:2], win[k + 1][:2]], N, N)}
    return cells


def near_segment(i, j, a, b, limit=F(1, 128)):
    """Is the centre of pixel (i, j) within ``limit`` of the segment a–b (exactly)?"""
    p = (F(2 * i + 1, 2), F(2 * j + 1, 2))
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)
    t = min(max(t, F(0)), F(1))
    qx, qy = a[0] + t * dx - p[0], a[1] + t * dy - p[1]
    return qx * qx + qy * qy <= limit * limit


def assert_same_pixels(got, want, win, is_new):
    """got == want, except pixel centres within 1/128 px of an edge through a new vertex."""
    edges = [(win[k], win[(k + 1) % len(win)]) for k in range(len(win))
             if is_new[k] or is_new[(k + 1) % len(win)]]
    bad = [(i, j) for i, j in got ^ want if not any(near_segment(i, j, a, b) for a, b in edges)]
    assert not bad, (f"pixels differ away from clipped edges: {sorted(bad)}\n"
                     + reference.picture(got, N, N) + "\n--- want ---\n" + reference.picture(want, N, N))


def show_eye(varyings, uniforms, frag):
    return (varyings.eye[0], varyings.eye[2], varyings.eye_np[2], 1.0)


def draw_counting(clip, eye, depth_test=None):
    """Draw one triangle; alpha counts how often each pixel was written (clear alpha 0, additive)."""
    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    eye = np.asarray(eye, float)
    softpipe.draw(fb, np.asarray(clip, float), varyings={"eye": eye, "eye_np": eye}, fragment_shader=show_eye,
                  interpolation={"eye_np": "noperspective"}, depth_test=depth_test,
                  blend=None if depth_test else ("one", "one"))
    return fb


def drawn(fb):
    assert set(np.unique(fb.color[..., 3])) <= {0.0, 1.0}, "a pixel was written more than once"
    return {(i, N - 1 - r) for r in range(N) for i in range(N) if fb.color[r, i, 3] == 1.0}


def eye_on_plane(tri_eye, i, j):
    """The eye-space point of the triangle's plane seen through the centre of pixel (i, j)."""
    a, b, c = (np.array(v, float) for v in tri_eye)
    n = np.cross(b - a, c - a)
    d = np.array([(i + 0.5) / (N / 2) - 1, (j + 0.5) / (N / 2) - 1, -1.0])   # x_ndc = x/(−z), y_ndc = y/(−z)
    return d * (n @ a) / (n @ d)


# Eye space, near = 1, far = 3. A is in front of the eye but nearer than the
# near plane; A_BEHIND is behind the eye (w = −1). B and C are inside.
A, A_BEHIND = (-1.5, -1.0, -0.5), (-3.5, 0.0, 0.5)
B, C = (2.0, -1.5, -2.5), (0.5, 2.0, -2.0)
CROSSING = {"crossing_near": (A, B, C), "vertex_behind_eye": (A_BEHIND, B, C)}


@pytest.mark.parametrize("case", list(CROSSING))
def test_near_clipped_triangle_covers_the_exact_clipped_polygon(case):
    tri = CROSSING[case]
    clip = [to_clip(v) for v in tri]
    assert clip[0][2] < -clip[0][3], "the first vertex is outside the near plane"
    if case == "vertex_behind_eye":
        assert clip[0][3] < 0
    poly = clip_exact([(p, tuple(F(c) for c in e), False) for p, e in zip(clip, tri)])
    assert len(poly) == 4 and sum(v[2] for v in poly) == 2
    win = [window(v[0]) for v in poly]
    want = polygon_coverage(win)
    got = drawn(draw_counting(clip, tri))
    assert len(want) > 40
    assert_same_pixels(got, want, win, [v[2] for v in poly])
    # the naive answer (divide by w without clipping) would have been different
    naive = set()
    if case == "crossing_near":
        naive = {(i, j) for i, j, _ in reference.covered([window(p)[:2] for p in clip], N, N)}
        assert naive != want


@pytest.mark.parametrize("case", list(CROSSING))
def test_smooth_varyings_at_new_vertices_stay_perspective_correct(case):
    # The varying is the eye-space position: at a pixel it must be the point of
    # the triangle's plane on the ray through the pixel centre. The tolerance
    # covers the snapping of the new vertices (1/512 px) times the gradient
    # (the largest error seen is 7e-4).
    tri = CROSSING[case]
    fb = draw_counting([to_clip(v) for v in tri], tri)
    checked = 0
    for r in range(N):
        for i in range(N):
            if fb.color[r, i, 3] == 1.0:
                p = eye_on_plane(tri, i, N - 1 - r)
                assert fb.color[r, i, 0] == pytest.approx(p[0], abs=2e-3)
                assert fb.color[r, i, 1] == pytest.approx(p[2], abs=2e-3)
                assert -3.0 <= p[2] <= -1.0
                checked += 1
    assert checked > 40


def test_noperspective_varyings_at_new_vertices_stay_linear_in_window_space():
    # All of A, B, C have w > 0, so the unclipped triangle exists in window
    # space; a noperspective varying must be the window-space-linear
    # interpolation of the corner values over that whole triangle.
    tri = CROSSING["crossing_near"]
    clip = [to_clip(v) for v in tri]
    win = [window(p) for p in clip]
    fb = draw_counting(clip, tri)
    (x0, y0, _), (x1, y1, _), (x2, y2, _) = win
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    checked = 0
    for r in range(N):
        for i in range(N):
            if fb.color[r, i, 3] == 1.0:
                px, py = F(2 * i + 1, 2), F(2 * (N - 1 - r) + 1, 2)
                b1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / area
                b2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / area
                z = (1 - b1 - b2) * F(tri[0][2]) + b1 * F(tri[1][2]) + b2 * F(tri[2][2])
                assert fb.color[r, i, 2] == pytest.approx(float(z), abs=5e-4)
                # and it is measurably not the perspective-correct value
                checked += abs(float(z) - eye_on_plane(tri, i, N - 1 - r)[2]) > 0.05
    assert checked > 20


@pytest.mark.parametrize("case", list(CROSSING))
def test_depth_of_a_near_clipped_triangle_is_the_planes_depth(case):
    # window depth = (z_ndc + 1)/2 with z_ndc = (−2z − 3)/(−z): 3/2 + 3/(2z)
    tri = CROSSING[case]
    fb = draw_counting([to_clip(v) for v in tri], tri, depth_test="always")
    covered = fb.color[..., 3] == 1.0
    assert covered.sum() > 40
    for r, i in zip(*np.nonzero(covered)):
        z = eye_on_plane(tri, i, N - 1 - r)[2]
        assert fb.depth[r, i] == pytest.approx(1.5 + 1.5 / z, abs=5e-4)
        assert 0.0 <= fb.depth[r, i] <= 1.0
    assert (fb.depth[~covered] == 1.0).all()


def test_flat_value_survives_when_the_provoking_vertex_is_clipped_away():
    # the provoking (last) vertex is behind the eye: every piece still takes its value
    tri = (B, C, A_BEHIND)
    colors = np.array([[1.0, 0, 0], [0, 1.0, 0], [0.25, 0.5, 0.75]])
    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    softpipe.draw(fb, np.array([to_clip(v) for v in tri], float), varyings={"color": colors},
                  interpolation={"color": "flat"})
    covered = fb.color[..., 3] == 1.0
    assert covered.sum() > 40
    assert (fb.color[covered] == (0.25, 0.5, 0.75, 1.0)).all()


def test_far_plane_clipping():
    # w = 1 everywhere: window depth (z + 1)/2. P1 lies beyond the far plane (z = 3).
    pts = [(1, 1, -0.5), (15, 3, 3.0), (4, 14, 0.0)]
    clip = window_to_clip(pts, N, N)
    exact = [tuple(F(c) for c in p) for p in clip]
    poly = clip_exact([(p, (), False) for p in exact])
    assert len(poly) == 4
    win = [window(v[0]) for v in poly]
    # by hand: P0→P1 leaves at t = 1.5/3.5 = 3/7, (1 + 6, 1 + 6/7); P1→P2 at t = 2/3 from P1
    assert (win[1][0], win[1][1]) == (7, F(13, 7))
    assert (win[2][0], win[2][1]) == (F(23, 3), F(31, 3))
    want = polygon_coverage(win)
    full = {(i, j) for i, j, _ in reference.covered([p[:2] for p in pts], N, N)}
    assert len(full - want) > 10                 # clipping removed a visible part
    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    softpipe.draw(fb, clip, varyings={"color": np.ones((3, 4))}, blend=("one", "one"), depth_test=None)
    assert_same_pixels(drawn(fb), want, win, [v[2] for v in poly])


def test_triangle_entirely_behind_the_eye_draws_nothing():
    # Negating every clip coordinate gives the same NDC points, so a naive
    # divide would draw the triangle; with w < 0 at every corner it is invisible.
    visible = window_to_clip([(2, 2), (14, 3), (5, 13)], N, N)
    fb = softpipe.Framebuffer(N, N)
    softpipe.draw(fb, visible, varyings={"color": np.ones((3, 3))})
    assert (fb.color[..., 0] == 1).sum() > 40
    fb = softpipe.Framebuffer(N, N)
    softpipe.draw(fb, -visible, varyings={"color": np.ones((3, 3))})
    assert (fb.color == (0, 0, 0, 1)).all() and (fb.depth == 1).all()
    # and through a projection: all three eye-space points have z > 0
    behind = np.array([to_clip(v) for v in [(-1, -1, 1.0), (1, -1, 2.0), (0, 1, 0.5)]], float)
    softpipe.draw(fb, behind, varyings={"color": np.ones((3, 3))})
    assert (fb.color == (0, 0, 0, 1)).all()
    prims = softpipe.assemble(softpipe.pipeline.vertex.run_vertex_stage(np.concatenate([visible, -visible, behind])),
                              viewport=softpipe.Viewport(0, 0, N, N))
    assert list(prims.dropped["outside"]) == [1, 2]
    assert set(prims.primitive_id) == {0}


# ------------------------------------------------------------ huge triangles

def huge_cases():
    for L in (1e6, 1e30):
        yield pytest.param(L, "one_triangle", [[(-L, -L), (3 * L, -L), (-L, 3 * L)]], id=f"{L:g}-one_triangle")
        yield pytest.param(L, "quad", [[(-L, -L), (L, -L), (L, L)], [(-L, -L), (L, L), (-L, L)]],
                           id=f"{L:g}-quad")


@pytest.mark.parametrize("L, shape, tris", list(huge_cases()))
def test_huge_triangle_covers_every_pixel_exactly_once_with_finite_depth(L, shape, tris):
    # clip coordinates ±L with w = 1 and z = 0; the quad's diagonal passes
    # through the pixel centres (i + ½, i + ½), which must be covered once.
    pos = np.array([[x, y, 0.0, 1.0] for t in tris for x, y in t])
    fb = softpipe.Framebuffer(8, 8).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, varyings={"color": np.ones((len(pos), 4))}, blend=("one", "one"), depth_test=None)
    assert (fb.color == 1.0).all(), f"coverage counts:\n{fb.color[..., 3]}"
    fb = softpipe.Framebuffer(8, 8)
    softpipe.draw(fb, pos, varyings={"color": np.ones((len(pos), 4))}, depth_test="always")
    assert np.isfinite(fb.depth).all() and (fb.depth == 0.5).all()


def test_guard_band_gives_the_pixels_of_full_clipping_away_from_clipped_edges():
    # One vertex far outside the guard band (32768 px): the edges through the
    # screen are those of the exact, unclipped triangle.
    pts = [(-3.25, 2.5), (400000.0, 90000.0), (5.5, 14.75)]
    clip = window_to_clip(pts, N, N)
    want = {(i, j) for i, j, _ in reference.covered(pts, N, N)}
    assert 20 < len(want) < N * N
    fb = softpipe.Framebuffer(N, N).clear((0, 0, 0, 0))
    softpipe.draw(fb, clip, varyings={"color": np.ones((3, 4))}, blend=("one", "one"), depth_test=None)
    win = [(F(x), F(y)) for x, y in pts]
    assert_same_pixels(drawn(fb), want, win, [False, True, False])


def test_nothing_is_drawn_outside_a_smaller_viewport():
    # A triangle covering NDC [−3, 3]²; with full clipping only the viewport's pixels are drawn.
    fb = softpipe.Framebuffer(8, 8).clear((0, 0, 0, 0))
    pos = np.array([[-3, -3, 0, 1], [9, -3, 0, 1], [-3, 9, 0, 1]], float)
    softpipe.draw(fb, pos, varyings={"color": np.ones((3, 4))}, viewport=softpipe.Viewport(2, 1, 4, 4))
    want = np.zeros((8, 8), bool)
    want[8 - 5:8 - 1, 2:6] = True                 # window rows 1–4, columns 2–5
    assert np.array_equal(fb.color[..., 3] == 1.0, want)


def test_triangle_inside_a_smaller_viewport_lands_in_it():
    # NDC (−1,−1), (1,−1), (−1, 1) in Viewport(2, 1, 4, 4): window (2,1), (6,1), (2,5)
    fb = softpipe.Framebuffer(8, 8).clear((0, 0, 0, 0))
    pos = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [-1, 1, 0, 1]], float)
    softpipe.draw(fb, pos, varyings={"color": np.ones((3, 4))}, viewport=softpipe.Viewport(2, 1, 4, 4))
    want = {(i, j) for i, j, _ in reference.covered([(2, 1), (6, 1), (2, 5)], 8, 8)}
    assert {(i, 7 - r) for r in range(8) for i in range(8) if fb.color[r, i, 3] == 1.0} == want
    assert len(want) == 6


# ------------------------------------------------------ non-finite positions
#
# A 3×3 grid of vertices (x, y) = (4a, 4b), vertex 3b + a, over an 8×8
# framebuffer; quad (a, b) is split along its rising diagonal into
# (v00, v10, v11) and (v00, v11, v01). A non-finite vertex drops exactly the
# triangles that use it; every other triangle is drawn as usual.

GRID = [(4 * (k % 3), 4 * (k // 3)) for k in range(9)]
GRID_TRIS = []
for _b in range(2):
    for _a in range(2):
        v00, v10, v01, v11 = 3 * _b + _a, 3 * _b + _a + 1, 3 * _b + _a + 3, 3 * _b + _a + 4
        GRID_TRIS += [(v00, v10, v11), (v00, v11, v01)]


# softpipe lets numpy warn "invalid value encountered in matmul" on an inf; the result is right.
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("vertex, component, value", [
    (0, 0, np.nan),        # the lower-left corner: drops triangles 0 and 1 (the lower-left quad)
    (2, 1, np.inf),        # the lower-right corner: drops triangle 2 only
    (4, 3, -np.inf),       # the centre (w): drops all but triangles 2 and 5
    (8, 2, np.nan),        # the upper-right corner (z): drops triangles 6 and 7
])
def test_non_finite_vertices_drop_only_their_triangles(vertex, component, value):
    pos = window_to_clip(GRID, 8, 8)
    pos[vertex, component] = value
    fb = softpipe.Framebuffer(8, 8).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, np.array(GRID_TRIS), varyings={"color": np.ones((9, 4))}, blend=("one", "one"),
                  depth_test=None)
    kept = [t for t, tri in enumerate(GRID_TRIS) if vertex not in tri]
    want = set()
    for t in kept:
        want |= {(i, j) for i, j, _ in reference.covered([GRID[k] for k in GRID_TRIS[t]], 8, 8)}
    assert drawn_8(fb) == want
    assert set(np.unique(fb.color[..., 0])) <= {0.0, 1.0}
    prims = softpipe.assemble(softpipe.pipeline.vertex.run_vertex_stage(pos), "triangles", np.array(GRID_TRIS),
                              viewport=softpipe.Viewport(0, 0, 8, 8))
    assert sorted(prims.dropped["non-finite"]) == sorted(set(range(8)) - set(kept))
    assert np.isfinite(prims.window).all()


def drawn_8(fb):
    return {(i, 7 - r) for r in range(8) for i in range(8) if fb.color[r, i, 3] == 1.0}


def test_non_finite_lower_left_corner_leaves_exactly_that_quad_empty():
    pos = window_to_clip(GRID, 8, 8)
    pos[0, 0] = np.nan
    fb = softpipe.Framebuffer(8, 8).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, np.array(GRID_TRIS), varyings={"color": np.ones((9, 4))})
    want = np.ones((8, 8), bool)
    want[4:, :4] = False                              # image rows 4–7, columns 0–3
    assert np.array_equal(fb.color[..., 3] == 1.0, want)
