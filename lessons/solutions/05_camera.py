# Lesson 05, the exercise completed: gluLookAt and gluPerspective, as softpipe (OpenGL) has them.

import math

import numpy as np


def look_at(eye, target, up):
    """The view matrix: rows s, u, −f (right-handed, the eye looking down −Z), the translation −R·eye
    in the last column (column vectors)."""
    e, t, u = (np.asarray(v, dtype=float) for v in (eye, target, up))
    f = (t - e) / np.linalg.norm(t - e)
    s = np.cross(f, u)
    s = s / np.linalg.norm(s)
    v = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, v, -f
    m[:3, 3] = -m[:3, :3] @ e
    return m


def perspective(fovy, aspect, near, far):
    """The projection: c = 1/tan(fovy/2), w_clip = −z, the near plane at z_ndc = −1, the far at +1."""
    c = 1.0 / math.tan(math.radians(fovy) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = c / aspect, c
    m[2, 2], m[2, 3] = -(far + near) / (far - near), -2.0 * far * near / (far - near)
    m[3, 2] = -1.0
    return m
