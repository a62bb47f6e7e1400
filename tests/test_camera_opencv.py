"""An OpenCV camera (K, R, t) through softpipe lands on OpenCV's pixels."""
import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.transforms import opencv_camera, rotate_y


def opencv_project(K, R, t, X):
    """OpenCV's pinhole model, written out: pixel (u, v), v down, top-left centre at (0, 0)."""
    xc = R @ X + t
    return K[0, 0] * xc[0] / xc[2] + K[0, 1] * xc[1] / xc[2] + K[0, 2], K[1, 1] * xc[1] / xc[2] + K[1, 2]


def softpipe_project(view, proj, vp, X):
    clip = proj @ view @ np.append(X, 1.0)
    win = vp.apply((clip[:3] / clip[3])[None])[0]
    # window (y up, centres at +½) → OpenCV pixel coordinates (v down, centres at 0)
    return win[0] - 0.5, (vp.height - win[1]) - 0.5


def test_points_project_to_the_same_pixels():
    K = np.array([[500.0, 0.0, 310.2], [0.0, 480.0, 245.7], [0.0, 0.0, 1.0]])
    R = rotate_y(20)[:3, :3]
    t = np.array([0.1, -0.2, 3.0])
    view, proj = opencv_camera(K, R, t, 640, 480, 0.1, 100.0)
    vp = sp.Viewport(0, 0, 640, 480)
    for X in ([0, 0, 0], [0.5, 0.3, -0.2], [-0.7, 0.4, 0.9]):
        X = np.array(X, float)
        assert softpipe_project(view, proj, vp, X) == pytest.approx(opencv_project(K, R, t, X), abs=1e-9)


def test_a_point_renders_at_the_opencv_pixel():
    # A tiny triangle around the point's projection lights the pixel that contains it.
    K = np.array([[20.0, 0, 7.0], [0, 20.0, 4.0], [0, 0, 1]])
    view, proj = opencv_camera(K, np.eye(3), np.zeros(3), 16, 12, 0.1, 10.0)
    # camera looks down +z (OpenCV): a point at z = 2 straight ahead projects to (cx, cy) = (7, 4)
    d = 0.01
    tri = np.array([[-d, -d, 2.0], [d, -d, 2.0], [0, d, 2.0]])
    clip = (proj @ view @ np.c_[tri, np.ones(3)].T).T
    fb = sp.Framebuffer(16, 12)
    sp.draw(fb, clip, varyings={"color": np.ones((3, 3))})
    lit = np.argwhere(fb.color[..., 0] > 0)
    assert lit.tolist() == [[4, 7]]          # image row v = 4, column u = 7


def test_bad_intrinsics_are_named():
    with pytest.raises(ValueError, match="K must be 3×3"):
        opencv_camera(np.eye(2), np.eye(3), np.zeros(3), 4, 4, 0.1, 1)
