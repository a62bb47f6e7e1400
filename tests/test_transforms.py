"""Stage 0: model/view transforms, projections and the viewport, against OpenGL's formulas.

Every expected matrix or point below is written out by hand from the OpenGL
reference pages (glTranslate, glScale, glRotate, gluLookAt, glFrustum,
gluPerspective, glOrtho, glViewport, glDepthRange), not taken from softpipe.
Points are column vectors: p' = M @ p.
"""
import math

import numpy as np
import pytest

import softpipe
from softpipe import (
    Viewport,
    compose,
    frustum,
    identity,
    look_at,
    normal_matrix,
    orthographic,
    perspective,
    rotate,
    rotate_x,
    rotate_y,
    rotate_z,
    scale,
    translate,
)

X, Y, Z = np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0]), np.array([0, 0, 1.0, 0])


def point(x, y, z):
    return np.array([x, y, z, 1.0])


# ------------------------------------------------------------ affine basics

def test_identity_is_the_4x4_identity():
    assert np.array_equal(identity(), np.eye(4))


def test_translate_moves_points_but_not_directions():
    t = translate(1, -2, 3)
    assert np.array_equal(t @ point(10, 20, 30), point(11, 18, 33))
    assert np.array_equal(t @ X, X)                       # w = 0: a direction
    assert np.array_equal(translate([1, -2, 3]), t)       # the 3-vector form
    assert np.array_equal(translate(5), translate(5, 0, 0))


def test_scale_per_axis_and_uniform():
    assert np.array_equal(scale(2, 3, 4) @ point(1, 1, 1), point(2, 3, 4))
    assert np.array_equal(scale(3), np.diag([3.0, 3.0, 3.0, 1.0]))
    assert np.array_equal(scale([2, 3, 4]), scale(2, 3, 4))


@pytest.mark.parametrize("rot, a, b", [
    (rotate_x, Y, Z),      # about +x: y → z
    (rotate_y, Z, X),      # about +y: z → x
    (rotate_z, X, Y),      # about +z: x → y
])
def test_axis_rotations_by_90_degrees_are_exact_and_right_handed(rot, a, b):
    m = rot(90)
    assert np.array_equal(m @ a, b)                        # exactly, no 6e-17
    assert np.array_equal(m @ b, -a)
    assert np.array_equal(rot(180) @ a, -a)
    assert np.array_equal(rot(-90) @ b, a)
    assert np.array_equal(rot(360), np.eye(4))


def test_axis_rotation_by_30_degrees_matches_cos_sin():
    c, s = math.sqrt(3) / 2, 0.5
    np.testing.assert_allclose(rotate_z(30) @ X, [c, s, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rotate_x(30) @ Y, [0, c, s, 0], atol=1e-15)
    np.testing.assert_allclose(rotate_y(30) @ Z, [s, 0, c, 0], atol=1e-15)


@pytest.mark.parametrize("angle", [17.0, 90.0, -123.0])
@pytest.mark.parametrize("axis, axis_rot", [((1, 0, 0), rotate_x), ((0, 1, 0), rotate_y), ((0, 0, 1), rotate_z)])
def test_rotate_about_a_coordinate_axis_agrees_with_the_axis_rotation(angle, axis, axis_rot):
    np.testing.assert_allclose(rotate(angle, axis), axis_rot(angle), atol=1e-15)


def test_rotate_90_about_z_maps_x_to_y_exactly():
    assert np.array_equal(rotate(90, (0, 0, 1)) @ X, Y)


def test_rotate_about_an_arbitrary_axis_follows_the_right_hand_rule():
    # 120° about (1, 1, 1): counter-clockwise seen from the tip, it cycles x → y → z → x.
    m = rotate(120, (1, 1, 1))
    np.testing.assert_allclose(m @ X, Y, atol=1e-15)
    np.testing.assert_allclose(m @ Y, Z, atol=1e-15)
    np.testing.assert_allclose(m @ Z, X, atol=1e-15)
    # the axis is not normalized by the caller
    np.testing.assert_allclose(rotate(120, (5, 5, 5)), m, atol=1e-15)


def test_rotate_is_a_proper_rotation_that_fixes_its_axis():
    axis = np.array([2.0, -1.0, 0.5])
    m = rotate(73.0, axis)
    r = m[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(r @ axis, axis, atol=1e-14)
    assert np.array_equal(m[3], [0, 0, 0, 1]) and np.array_equal(m[:3, 3], [0, 0, 0])
    # the rotation angle: cos θ = (trace − 1) / 2
    assert math.degrees(math.acos((np.trace(r) - 1) / 2)) == pytest.approx(73.0, abs=1e-9)


def test_compose_multiplies_in_the_written_order_so_the_last_applies_first():
    p = point(1, 0, 0)
    # scale first (1 → 2), then translate (→ 3)
    assert np.array_equal(compose(translate(1, 0, 0), scale(2)) @ p, point(3, 0, 0))
    # translate first (1 → 2), then scale (→ 4)
    assert np.array_equal(compose(scale(2), translate(1, 0, 0)) @ p, point(4, 0, 0))
    # rotate x onto y, then translate
    assert np.array_equal(compose(translate(0, 0, 5), rotate_z(90)) @ p, point(0, 1, 5))
    assert np.array_equal(compose(), np.eye(4))
    a, b, c = translate(1, 2, 3), rotate_x(90), scale(1, 2, 3)
    assert np.array_equal(compose(a, b, c), a @ b @ c)


# ---------------------------------------------------------------- look_at

def test_look_at_along_minus_z_is_a_translation():
    # the camera at (0, 0, 5) looking at the origin: the view matrix moves the world by −5 in z
    assert np.allclose(look_at((0, 0, 5), (0, 0, 0)), translate(0, 0, -5), atol=0)


def test_look_at_maps_eye_to_origin_target_to_minus_z_and_up_to_plus_y():
    eye, target, up = np.array([3.0, 4.0, 5.0]), np.array([-1.0, 2.0, 0.5]), np.array([0.2, 1.0, -0.3])
    v = look_at(eye, target, up)
    dist = np.linalg.norm(target - eye)
    np.testing.assert_allclose(v @ np.append(eye, 1), [0, 0, 0, 1], atol=1e-14)
    np.testing.assert_allclose(v @ np.append(target, 1), [0, 0, -dist, 1], atol=1e-14)
    # up lands in the y–z plane of eye space with a positive y component
    up_eye = v @ np.append(up, 0)
    assert abs(up_eye[0]) < 1e-15 and up_eye[1] > 0
    # it is a rigid motion: orthonormal with det +1 (a rotation, no mirror)
    r = v[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
    # a point to the right of the view direction (view × up) has x > 0 in eye space
    right = np.cross(target - eye, up)
    assert (v @ np.append(eye + right, 1))[0] > 0


# ---------------------------------------------------------- normal matrix

def test_normal_matrix_is_the_inverse_transpose():
    mv = compose(translate(1, 2, 3), rotate(30, (1, 2, 3)), scale(1, 4, 0.5))
    np.testing.assert_allclose(normal_matrix(mv), np.linalg.inv(mv[:3, :3]).T, atol=1e-14)
    np.testing.assert_allclose(normal_matrix(mv[:3, :3]), normal_matrix(mv), atol=0)
    # a pure rotation is its own normal matrix
    np.testing.assert_allclose(normal_matrix(rotate(40, (0, 1, 1))), rotate(40, (0, 1, 1))[:3, :3], atol=1e-15)


def test_normal_stays_perpendicular_to_the_surface_under_non_uniform_scale():
    # the plane x + y = 0: tangent (1, −1, 0), normal (1, 1, 0)
    mv = compose(rotate_z(10), scale(1, 4, 1))
    tangent, normal = np.array([1.0, -1, 0]), np.array([1.0, 1, 0])
    t2 = mv[:3, :3] @ tangent
    n2 = normal_matrix(mv) @ normal
    assert abs(np.dot(t2, n2)) < 1e-14
    # transforming the normal like a point would not have stayed perpendicular
    assert abs(np.dot(t2, mv[:3, :3] @ normal)) > 1.0


# ------------------------------------------------------------ projections

def gl_frustum(l, r, b, t, n, f):
    """The glFrustum matrix as written on its reference page."""
    return np.array([
        [2 * n / (r - l), 0, (r + l) / (r - l), 0],
        [0, 2 * n / (t - b), (t + b) / (t - b), 0],
        [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
        [0, 0, -1, 0],
    ])


def gl_perspective(fovy, aspect, n, f):
    """The gluPerspective matrix: f = cot(fovy/2)."""
    c = 1 / math.tan(math.radians(fovy) / 2)
    return np.array([
        [c / aspect, 0, 0, 0],
        [0, c, 0, 0],
        [0, 0, (f + n) / (n - f), 2 * f * n / (n - f)],
        [0, 0, -1, 0],
    ])


def gl_ortho(l, r, b, t, n, f):
    return np.array([
        [2 / (r - l), 0, 0, -(r + l) / (r - l)],
        [0, 2 / (t - b), 0, -(t + b) / (t - b)],
        [0, 0, -2 / (f - n), -(f + n) / (f - n)],
        [0, 0, 0, 1],
    ])


def ndc(m, p):
    c = m @ p
    return c[:3] / c[3]


def test_frustum_matches_the_glfrustum_formula():
    args = (-1.0, 3.0, -2.0, 0.5, 0.5, 20.0)
    np.testing.assert_allclose(frustum(*args), gl_frustum(*args), rtol=1e-15, atol=0)


def test_frustum_maps_near_plane_to_minus_one_and_far_to_plus_one():
    l, r, b, t, n, f = -1.0, 3.0, -2.0, 0.5, 0.5, 20.0
    m = frustum(l, r, b, t, n, f)
    # the near rectangle's corners → the front face of the NDC cube
    np.testing.assert_allclose(ndc(m, point(l, b, -n)), [-1, -1, -1], atol=1e-14)
    np.testing.assert_allclose(ndc(m, point(r, t, -n)), [1, 1, -1], atol=1e-14)
    # the far rectangle (near's corners scaled by f/n) → the back face
    s = f / n
    np.testing.assert_allclose(ndc(m, point(l * s, b * s, -f)), [-1, -1, 1], atol=1e-13)
    np.testing.assert_allclose(ndc(m, point(r * s, t * s, -f)), [1, 1, 1], atol=1e-13)
    # w_clip is the distance in front of the eye
    assert (m @ point(0.3, 0.2, -7.0))[3] == 7.0


def test_perspective_matches_the_gluperspective_formula():
    np.testing.assert_allclose(perspective(60.0, 1.5, 0.1, 100.0), gl_perspective(60.0, 1.5, 0.1, 100.0),
                               rtol=1e-14, atol=1e-15)


def test_perspective_maps_the_field_of_view_to_the_ndc_cube():
    fovy, aspect, n, f = 60.0, 2.0, 1.0, 10.0
    m = perspective(fovy, aspect, n, f)
    half = math.tan(math.radians(fovy / 2))
    # a point on the top edge of the field of view at depth 4 → y_ndc = 1
    assert ndc(m, point(0, 4 * half, -4))[1] == pytest.approx(1.0, abs=1e-14)
    assert ndc(m, point(4 * half * aspect, 0, -4))[0] == pytest.approx(1.0, abs=1e-14)
    assert ndc(m, point(0, 0, -n))[2] == pytest.approx(-1.0, abs=1e-14)
    assert ndc(m, point(0, 0, -f))[2] == pytest.approx(1.0, abs=1e-14)
    # depth in NDC is (f+n)/(f−n) − 2fn/((f−n)·d) at distance d: not linear
    d = 2.0
    assert ndc(m, point(0, 0, -d))[2] == pytest.approx((f + n) / (f - n) - 2 * f * n / ((f - n) * d), abs=1e-14)


def test_orthographic_matches_the_glortho_formula_and_maps_near_far():
    args = (-2.0, 6.0, -1.0, 3.0, -1.0, 7.0)
    m = orthographic(*args)
    np.testing.assert_allclose(m, gl_ortho(*args), rtol=1e-15, atol=0)
    l, r, b, t, n, f = args
    np.testing.assert_allclose(ndc(m, point(l, b, -n)), [-1, -1, -1], atol=1e-15)
    np.testing.assert_allclose(ndc(m, point(r, t, -f)), [1, 1, 1], atol=1e-15)
    assert (m @ point(1, 2, 3))[3] == 1.0


# --------------------------------------------------------------- viewport

def test_viewport_maps_the_ndc_cube_onto_the_window_rectangle_and_depth_range():
    vp = Viewport(10, 20, 64, 32, 0.25, 0.75)
    corners = np.array([[-1, -1, -1], [1, 1, 1], [0, 0, 0], [-0.5, 0.5, 0.5]], dtype=float)
    want = np.array([[10, 20, 0.25], [74, 52, 0.75], [42, 36, 0.5], [26, 44, 0.625]])
    assert np.array_equal(vp.apply(corners), want)
    # the matrix form does the same on homogeneous NDC points
    hom = np.hstack([corners, np.ones((4, 1))])
    assert np.array_equal((vp.matrix() @ hom.T).T[:, :3], want)


def test_viewport_pixel_centres_and_a_reversed_depth_range():
    vp = Viewport(0, 0, 4, 4, 1.0, 0.0)             # glDepthRange(1, 0) is allowed
    # NDC x of the centre of pixel 0 is −1 + ½·(2/4) = −0.75
    out = vp.apply(np.array([[-0.75, 0.75, -1.0], [0.25, -0.25, 1.0]]))
    assert np.array_equal(out, [[0.5, 3.5, 1.0], [2.5, 1.5, 0.0]])


def test_viewport_defaults_to_depth_range_zero_one():
    vp = Viewport(0, 0, 8, 8)
    assert (vp.near, vp.far) == (0.0, 1.0)
    assert np.array_equal(vp.apply(np.array([[0, 0, -1.0], [0, 0, 1.0]]))[:, 2], [0.0, 1.0])


# ------------------------------------------------------------- bad input

def test_rotate_about_the_zero_axis_is_an_error():
    with pytest.raises(ValueError, match="axis must not be the zero vector"):
        rotate(30, (0, 0, 0))
    with pytest.raises(ValueError, match=r"axis must be 3 finite numbers"):
        rotate(30, (1, 0))
    with pytest.raises(ValueError, match=r"axis must be 3 finite numbers"):
        rotate(30, (1, 0, float("nan")))


@pytest.mark.parametrize("n, f", [(1.0, 1.0), (2.0, 1.0), (0.0, 1.0), (-1.0, 1.0)])
def test_frustum_and_perspective_need_0_lt_near_lt_far(n, f):
    with pytest.raises(ValueError, match=r"frustum: need 0 < near < far, got near=.*far="):
        frustum(-1, 1, -1, 1, n, f)
    with pytest.raises(ValueError, match=r"need 0 < near < far"):
        perspective(60, 1, n, f)


@pytest.mark.parametrize("fovy", [0.0, 180.0, -10.0, 200.0, float("nan")])
def test_perspective_fovy_out_of_range(fovy):
    with pytest.raises(ValueError, match=r"fovy_degrees"):
        perspective(fovy, 1.0, 0.1, 10.0)


def test_perspective_aspect_must_be_positive():
    with pytest.raises(ValueError, match=r"aspect must be > 0"):
        perspective(60, 0.0, 0.1, 10.0)


def test_degenerate_frustum_and_ortho_boxes():
    with pytest.raises(ValueError, match=r"left == right or bottom == top"):
        frustum(1, 1, -1, 1, 0.1, 10)
    with pytest.raises(ValueError, match=r"near == far"):
        orthographic(-1, 1, -1, 1, 2, 2)


@pytest.mark.parametrize("bad, index, shape", [
    (np.eye(3), 1, r"\(3, 3\)"),
    (np.eye(4)[:, :3], 1, r"\(4, 3\)"),
    (np.zeros(16), 1, r"\(16,\)"),
])
def test_compose_names_the_matrix_that_is_not_4x4(bad, index, shape):
    with pytest.raises(ValueError, match=rf"compose: matrix {index} must be 4×4, got shape {shape}"):
        compose(np.eye(4), bad, np.eye(4))


def test_look_at_degenerate_inputs():
    with pytest.raises(ValueError, match="eye and target are the same point"):
        look_at((1, 2, 3), (1, 2, 3))
    with pytest.raises(ValueError, match="up is parallel to the viewing direction"):
        look_at((0, 0, 0), (0, 5, 0), (0, 1, 0))
    with pytest.raises(ValueError, match="eye must be 3 finite numbers"):
        look_at((0, 0), (0, 0, -1))


def test_normal_matrix_of_a_singular_or_wrong_shaped_matrix():
    with pytest.raises(ValueError, match="singular"):
        normal_matrix(scale(1, 0, 1))
    with pytest.raises(ValueError, match=r"expected a 4×4 or 3×3 matrix, got shape \(2, 2\)"):
        normal_matrix(np.eye(2))


def test_non_finite_transform_arguments():
    with pytest.raises(ValueError, match="must be finite"):
        translate(float("inf"), 0, 0)
    with pytest.raises(ValueError, match="must be finite"):
        scale(1, float("nan"), 1)


def test_viewport_bad_arguments():
    with pytest.raises(TypeError, match=r"Viewport.width must be an integer, got 4.5"):
        Viewport(0, 0, 4.5, 4)
    with pytest.raises(ValueError, match=r"Viewport size must be positive, got 0×4"):
        Viewport(0, 0, 0, 4)
    with pytest.raises(ValueError, match=r"depth range must lie in \[0, 1\]"):
        Viewport(0, 0, 4, 4, -0.5, 1.0)
    assert isinstance(softpipe.Viewport(0, 0, 4, 4), Viewport)


def test_transform_points_is_the_matrix_times_each_homogeneous_point():
    """transform_points(M, P) = (M · (p, 1))[:rows] per point, written out here one point at a time."""
    from softpipe.pipeline.transforms import transform_points
    rng = np.random.default_rng(7)
    m, points = rng.normal(size=(4, 4)), rng.normal(size=(50, 3))
    for rows in (3, 4):
        got = transform_points(m, points, rows)
        assert got.shape == (50, rows)
        for p, q in zip(points, got):
            expected = [m[r, 0] * p[0] + m[r, 1] * p[1] + m[r, 2] * p[2] + m[r, 3] for r in range(rows)]
            assert list(q) == expected           # the same sum in the same order: the same bytes
    with pytest.raises(ValueError, match=r"points \(50, 2\)"):
        transform_points(m, points[:, :2])
    with pytest.raises(ValueError, match="rows 2"):
        transform_points(m, points, 2)
