"""Stage 0: model, world and eye transforms, projection and the viewport.

Every matrix is a 4×4 float64 numpy array acting on column vectors, ``p' = M @ p``,
so a chain reads right to left: ``clip = projection @ view @ model @ p``. The
formulas are OpenGL's (the ``glTranslate``/``glRotate``/``gluLookAt``/
``glFrustum``/``glOrtho``/``gluPerspective`` pages of the specification), which is
what the lecture notes use.

Spaces: object (model) → world (by the model matrix) → eye (by the view matrix;
the eye at the origin looking down −Z, +Y up) → clip (by the projection) → NDC
(divide by w, the cube [−1, 1]³) → window (by the viewport: x, y in pixels with
the origin at the lower-left corner, depth in [near, far] of the depth range).
"""
from __future__ import annotations

import math
from typing import Sequence, Union

import numba
import numpy as np

__all__ = [
    "identity", "translate", "scale", "rotate_x", "rotate_y", "rotate_z", "rotate",
    "compose", "look_at", "normal_matrix", "perspective", "perspective_infinite", "frustum", "orthographic",
    "Viewport", "opencv_camera", "transform_points",
]


def _vec3(name: str, v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {v!r}")
    return a


def _finite(name: str, x) -> float:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x!r}")
    return x


def identity() -> np.ndarray:
    """The 4×4 identity."""
    return np.eye(4)


def translate(x: float, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """Translation by (x, y, z); ``translate(v)`` with a 3-vector also works."""
    if np.ndim(x) == 1:
        x, y, z = _vec3("translate offset", x)
    m = np.eye(4)
    m[:3, 3] = (_finite("x", x), _finite("y", y), _finite("z", z))
    return m


def scale(x: float, y: float | None = None, z: float | None = None) -> np.ndarray:
    """Scaling by (x, y, z); one argument scales uniformly."""
    if np.ndim(x) == 1:
        x, y, z = _vec3("scale factors", x)
    y = x if y is None else y
    z = x if z is None else z
    return np.diag([_finite("x", x), _finite("y", y), _finite("z", z), 1.0])


def rotate(angle_degrees: float, axis: Sequence[float]) -> np.ndarray:
    """Rotation by ``angle_degrees`` counter-clockwise about ``axis`` (glRotate).

    Seen from the tip of the axis looking toward the origin, the rotation is
    counter-clockwise (the right-hand rule).
    """
    a = _vec3("axis", axis)
    n = np.linalg.norm(a)
    if n == 0.0:
        raise ValueError("axis must not be the zero vector")
    x, y, z = a / n
    t = math.radians(_finite("angle_degrees", angle_degrees))
    c, s = _exact_cos_sin(t, angle_degrees)
    k = 1.0 - c
    m = np.eye(4)
    m[:3, :3] = [
        [x * x * k + c, x * y * k - z * s, x * z * k + y * s],
        [y * x * k + z * s, y * y * k + c, y * z * k - x * s],
        [z * x * k - y * s, z * y * k + x * s, z * z * k + c],
    ]
    return m


def _axis_rotation(angle_degrees: float, i: int, j: int) -> np.ndarray:
    # Built directly rather than through rotate() so that 90° gives exact zeros.
    t = math.radians(_finite("angle_degrees", angle_degrees))
    c, s = _exact_cos_sin(t, angle_degrees)
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _exact_cos_sin(t: float, degrees: float) -> tuple[float, float]:
    """cos and sin, exact at multiples of 90° (so rotated grids stay on the grid)."""
    if float(degrees) % 90.0 == 0.0:
        quarter = int(float(degrees) // 90.0) % 4
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][quarter]
    return math.cos(t), math.sin(t)


def rotate_x(angle_degrees: float) -> np.ndarray:
    """Rotation about +X (y toward z)."""
    return _axis_rotation(angle_degrees, 1, 2)


def rotate_y(angle_degrees: float) -> np.ndarray:
    """Rotation about +Y (z toward x)."""
    return _axis_rotation(angle_degrees, 2, 0)


def rotate_z(angle_degrees: float) -> np.ndarray:
    """Rotation about +Z (x toward y)."""
    return _axis_rotation(angle_degrees, 0, 1)


def compose(*matrices: np.ndarray) -> np.ndarray:
    """The product of the matrices in the order written: ``compose(A, B, C) = A @ B @ C``.

    With column vectors, C is applied first.
    """
    out = np.eye(4)
    for i, m in enumerate(matrices):
        m = np.asarray(m, dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"compose: matrix {i} must be 4×4, got shape {m.shape}")
        out = out @ m
    return out


def transform_points(matrix: np.ndarray, points, rows: int = 3) -> np.ndarray:
    """``M·(p, 1)`` for every row p of ``points`` [N, 3]: its first ``rows`` components, [N, rows].

    ``rows`` 3: the points an affine matrix (model, view) moves them to; 4: their
    homogeneous coordinates (clip coordinates for a projection · view).

    A compiled loop, not numpy's ``@``: numpy's matrix product runs on OpenBLAS's
    threads, which keep spinning for a while after it, taking the cores from the
    bands that follow (measured on a loaded machine; benchmarks/README.md); and
    the loop gives the same bytes whatever BLAS a machine has.
    """
    m = np.ascontiguousarray(matrix, np.float64)
    p = np.ascontiguousarray(points, np.float64)
    if m.shape != (4, 4) or p.ndim != 2 or p.shape[1] != 3 or rows not in (3, 4):
        raise ValueError(f"transform_points takes a 4×4 matrix, points [N, 3] and rows 3 or 4; got matrix "
                         f"{m.shape}, points {p.shape}, rows {rows!r}")
    out = np.empty((p.shape[0], rows))
    _transform_points(m, p, out)
    return out


@numba.njit(cache=True, nogil=True)
def _transform_points(m, p, out):
    for n in range(p.shape[0]):
        x, y, z = p[n, 0], p[n, 1], p[n, 2]
        for r in range(out.shape[1]):
            out[n, r] = m[r, 0] * x + m[r, 1] * y + m[r, 2] * z + m[r, 3]


def look_at(eye: Union[Sequence[float], np.ndarray], target: Union[Sequence[float], np.ndarray],
            up: Union[Sequence[float], np.ndarray] = (0.0, 1.0, 0.0)) -> np.ndarray:
    """The view matrix of a camera at ``eye`` looking at ``target`` (gluLookAt).

    In eye space the camera sits at the origin looking down −Z with ``up``
    projected onto +Y.
    """
    e, t, u = _vec3("eye", eye), _vec3("target", target), _vec3("up", up)
    f = t - e
    if np.linalg.norm(f) == 0.0:
        raise ValueError("look_at: eye and target are the same point")
    f = f / np.linalg.norm(f)
    s = np.cross(f, u)
    if np.linalg.norm(s) < 1e-12:
        raise ValueError("look_at: up is parallel to the viewing direction")
    s = s / np.linalg.norm(s)
    v = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, v, -f
    m[:3, 3] = -m[:3, :3] @ e
    return m


def normal_matrix(model_view: np.ndarray) -> np.ndarray:
    """The 3×3 inverse transpose of the upper-left of ``model_view``.

    Normals are covectors: under a non-uniform scale they transform by the
    inverse transpose so that they stay perpendicular to the surface.
    """
    m = np.asarray(model_view, dtype=np.float64)
    if m.shape not in ((4, 4), (3, 3)):
        raise ValueError(f"normal_matrix: expected a 4×4 or 3×3 matrix, got shape {m.shape}")
    upper = m[:3, :3]
    if abs(np.linalg.det(upper)) < 1e-300:
        raise ValueError("normal_matrix: the matrix is singular (a zero scale?)")
    return np.linalg.inv(upper).T


def frustum(left: float, right: float, bottom: float, top: float, near: float, far: float) -> np.ndarray:
    """The perspective projection of glFrustum; near and far are positive distances."""
    l, r, b, t, n, f = (_finite(k, v) for k, v in
                        zip(("left", "right", "bottom", "top", "near", "far"), (left, right, bottom, top, near, far)))
    if not 0.0 < n < f:
        raise ValueError(f"frustum: need 0 < near < far, got near={n}, far={f}")
    if l == r or b == t:
        raise ValueError("frustum: left == right or bottom == top")
    m = np.zeros((4, 4))
    m[0, 0] = 2 * n / (r - l)
    m[0, 2] = (r + l) / (r - l)
    m[1, 1] = 2 * n / (t - b)
    m[1, 2] = (t + b) / (t - b)
    m[2, 2] = -(f + n) / (f - n)
    m[2, 3] = -2 * f * n / (f - n)
    m[3, 2] = -1.0
    return m


def perspective(fovy_degrees: float, aspect: float, near: float, far: float) -> np.ndarray:
    """The perspective projection of gluPerspective: vertical field of view in degrees."""
    fovy = _finite("fovy_degrees", fovy_degrees)
    if not 0.0 < fovy < 180.0:
        raise ValueError(f"perspective: fovy_degrees must be in (0, 180), got {fovy}")
    aspect = _finite("aspect", aspect)
    if aspect <= 0.0:
        raise ValueError(f"perspective: aspect must be > 0, got {aspect}")
    top = near * math.tan(math.radians(fovy) / 2.0)
    return frustum(-top * aspect, top * aspect, -top, top, near, far)


def perspective_infinite(fovy_degrees: float, aspect: float, near: float, epsilon: float = 0.0) -> np.ndarray:
    """:func:`perspective` with the far plane at infinity (Everitt and Kilgard 2002, "Practical and
    Robust Stenciled Shadow Volumes", §3).

    The limit of glFrustum's matrix as far → ∞: its z row becomes (0, 0, ε − 1, (ε − 2)·near), so a
    point at eye depth z (< 0) gets z_ndc = (ε − 1) − (ε − 2)·near/z: −1 at the near plane,
    rising toward 1 − ε as z → −∞; a point at infinity, (x, y, z, 0), lands at exactly
    z_ndc = 1 − ε (window depth 1 − ε/2) and is never far-clipped. ε = 0 is the exact limit
    (points at infinity on the far plane z = w); Everitt and Kilgard's small ε > 0 keeps
    them strictly inside on hardware whose arithmetic might round z past w. Shadow
    volumes drawn with it close at infinity (:mod:`softpipe.scenes.shadow_volumes`);
    depth clamp is the other way to keep their far ends.
    """
    fovy = _finite("fovy_degrees", fovy_degrees)
    if not 0.0 < fovy < 180.0:
        raise ValueError(f"perspective_infinite: fovy_degrees must be in (0, 180), got {fovy}")
    aspect, n, eps = _finite("aspect", aspect), _finite("near", near), _finite("epsilon", epsilon)
    if aspect <= 0.0 or n <= 0.0:
        raise ValueError(f"perspective_infinite: need aspect > 0 and near > 0, got aspect={aspect}, near={n}")
    if not 0.0 <= eps < 1.0:
        raise ValueError(f"perspective_infinite: epsilon must be in [0, 1), got {eps}")
    top = n * math.tan(math.radians(fovy) / 2.0)
    m = frustum(-top * aspect, top * aspect, -top, top, n, 2.0 * n)   # rows 0, 1 and 3 do not depend on far
    m[2, 2] = eps - 1.0
    m[2, 3] = (eps - 2.0) * n
    return m


def orthographic(left: float, right: float, bottom: float, top: float, near: float, far: float) -> np.ndarray:
    """The parallel projection of glOrtho (near and far may be negative)."""
    l, r, b, t, n, f = (_finite(k, v) for k, v in
                        zip(("left", "right", "bottom", "top", "near", "far"), (left, right, bottom, top, near, far)))
    if l == r or b == t or n == f:
        raise ValueError("orthographic: left == right, bottom == top or near == far")
    m = np.eye(4)
    m[0, 0], m[0, 3] = 2 / (r - l), -(r + l) / (r - l)
    m[1, 1], m[1, 3] = 2 / (t - b), -(t + b) / (t - b)
    m[2, 2], m[2, 3] = -2 / (f - n), -(f + n) / (f - n)
    return m


def opencv_camera(K, R, t, width: int, height: int, near: float, far: float) -> tuple[np.ndarray, np.ndarray]:
    """softpipe's (view, projection) for a camera given OpenCV-style.

    OpenCV: a world point X maps to the camera frame as ``X_c = R X + t`` (x right,
    y down, z forward), and to pixels as ``u = fx·x_c/z_c + cx``,
    ``v = fy·y_c/z_c + cy`` (plus skew ``s·y_c/z_c`` in u), with the centre of the
    top-left pixel at (0, 0) and v growing downward.

    softpipe (OpenGL): the eye looks down −Z with y up, so the view matrix is
    ``diag(1, −1, −1) · [R | t]``; pixel centres sit at +½, so the principal point
    moves by ½ pixel; and window y grows upward, which the projection's second
    row absorbs. Rendering with the returned matrices and the default viewport
    puts every point at image column u and image row v (row 0 at the top), as
    OpenCV's ``projectPoints`` would (``docs/conventions.md`` derives it).
    """
    K = np.asarray(K, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    if K.shape != (3, 3):
        raise ValueError(f"opencv_camera: K must be 3×3, got shape {K.shape}")
    if R.shape != (3, 3):
        raise ValueError(f"opencv_camera: R must be 3×3, got shape {R.shape}")
    if t.shape != (3,):
        raise ValueError(f"opencv_camera: t must have 3 components, got shape {t.shape}")
    if not 0.0 < near < far:
        raise ValueError(f"opencv_camera: need 0 < near < far, got near={near}, far={far}")
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    w, h = float(width), float(height)
    view = np.eye(4)
    view[:3, :3], view[:3, 3] = R, t
    view = np.diag([1.0, -1.0, -1.0, 1.0]) @ view
    proj = np.zeros((4, 4))
    proj[0, 0], proj[0, 1], proj[0, 2] = 2 * fx / w, -2 * s / w, 1.0 - 2 * (cx + 0.5) / w
    proj[1, 1], proj[1, 2] = 2 * fy / h, 2 * (cy + 0.5) / h - 1.0
    proj[2, 2], proj[2, 3] = -(far + near) / (far - near), -2 * far * near / (far - near)
    proj[3, 2] = -1.0
    return view, proj


#: Largest viewport width, height and |offset|: with the guard band, window
#: coordinates then stay below 2^18 pixels, and the rasterizer's 1/256-pixel edge
#: functions well inside 64 bits.
MAX_VIEWPORT = 1 << 16


class Viewport:
    """The viewport transform NDC → window (glViewport and glDepthRange).

    x_w = x + (x_ndc + 1)·width/2,  y_w = y + (y_ndc + 1)·height/2,
    z_w = near + (z_ndc + 1)·(far − near)/2.

    Window coordinates are OpenGL's: the origin at the lower-left corner, y up,
    pixel (i, j) centred at (i + ½, j + ½). The flip to image rows (row 0 at the
    top) happens once, where the rasterizer emits a fragment.
    """

    def __init__(self, x: int, y: int, width: int, height: int, near: float = 0.0, far: float = 1.0):
        for k, v in (("x", x), ("y", y), ("width", width), ("height", height)):
            if int(v) != v:
                raise TypeError(f"Viewport.{k} must be an integer, got {v!r}")
        if width <= 0 or height <= 0:
            raise ValueError(f"Viewport size must be positive, got {width}×{height}")
        if max(width, height, abs(x), abs(y)) > MAX_VIEWPORT:
            raise ValueError(f"Viewport ({x}, {y}, {width}, {height}) exceeds the limit MAX_VIEWPORT = {MAX_VIEWPORT} "
                             "for its size and offset (window coordinates must fit the rasterizer's fixed point)")
        near, far = _finite("near", near), _finite("far", far)
        if not (0.0 <= near <= 1.0 and 0.0 <= far <= 1.0):
            raise ValueError(f"Viewport depth range must lie in [0, 1], got ({near}, {far})")
        self.x, self.y, self.width, self.height = int(x), int(y), int(width), int(height)
        self.near, self.far = near, far

    def matrix(self) -> np.ndarray:
        """The same transform as a 4×4 matrix on NDC points (w = 1)."""
        m = np.eye(4)
        m[0, 0], m[0, 3] = self.width / 2, self.x + self.width / 2
        m[1, 1], m[1, 3] = self.height / 2, self.y + self.height / 2
        m[2, 2], m[2, 3] = (self.far - self.near) / 2, (self.far + self.near) / 2
        return m

    def apply(self, ndc: np.ndarray) -> np.ndarray:
        """NDC points [N, 3] → window points [N, 3]."""
        ndc = np.asarray(ndc, dtype=np.float64)
        out = np.empty_like(ndc)
        out[:, 0] = self.x + (ndc[:, 0] + 1.0) * (self.width / 2)
        out[:, 1] = self.y + (ndc[:, 1] + 1.0) * (self.height / 2)
        out[:, 2] = self.near + (ndc[:, 2] + 1.0) * ((self.far - self.near) / 2)
        return out

    def __repr__(self) -> str:
        return f"Viewport({self.x}, {self.y}, {self.width}, {self.height}, near={self.near}, far={self.far})"
