"""Triangle setup: the numbers every later step computes a triangle's samples from.

One setup serves everything after assembly, as ``sp_setup.c`` does in Mesa's
softpipe: the reference rasterizer (:mod:`softpipe.pipeline.raster`), the fast path's
tile walk (:mod:`softpipe.pipeline.tiles`) and shading of visible samples
(:mod:`softpipe.pipeline.visibility`), the generated shading loops
(:mod:`softpipe.language.kernels`) and the screen-space derivatives. The rules are
OpenGL's, as Mesa implements them (docs/design.md), one small function each, so no
two callers can disagree about one:

1. **Snapping** (:func:`snap`): fixed point with 8 subpixel bits, pixel i's centre at ``256·i``.
2. **Edge functions** (:attr:`TriangleSetup.edges`), exact in 64-bit integers,
   ``E_k = A_k·P_x + B_k·P_y + C_k``, ≥ 0 inside (a clockwise triangle is turned
   around); ``b_k = E_k / area`` (:attr:`TriangleSetup.area`, twice the snapped area).
3. **The fill rule** (:func:`owns_samples_on_edge`, :func:`inside_edge`, :func:`covers`).
4. **Depth** (:func:`depth_at`: the one expression both paths use) and the
   **polygon offset** (:func:`apply_polygon_offset`: the shadow maps' depth bias).
5. **Bounding box**: the pixels whose samples may lie inside, clamped to the scissor
   rectangle (the viewport within the framebuffer).
6. **Where a fragment is shaded** (:func:`shading_point`, :data:`SHADING_POSITIONS`).

docs/04-raster.md states each rule with its formula (the edge numbering, the fill
rule's bias, the depth expression); docs/08-fast-path.md says what the fast path shares.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.pipeline.sampling import SUBPIXEL

__all__ = ["TriangleSetup", "setup_triangles", "snap", "edge_function", "owns_samples_on_edge", "edge_values",
           "inside_edge", "inside", "covers", "plane_depth", "depth_at", "apply_polygon_offset", "pixel_coverage",
           "shading_point", "SHADING_POSITIONS", "pixel_rect",
           "SHADE_SAMPLE", "SHADE_CENTER", "SHADE_CENTROID", "offset_bounds", "sample_depth"]

#: Where a fragment's barycentrics (its shading inputs) are taken: every sample on
#: its own (ordinary and supersampled rendering), or once per pixel at its centre
#: or at the centroid of its covered samples (multisampling).
SHADING_POSITIONS = ("sample", "center", "centroid")
SHADE_SAMPLE, SHADE_CENTER, SHADE_CENTROID = 0, 1, 2


# ------------------------------------------------------- the rules, one by one

# The rules below run inside setup_kernel; numba inlines them there (inline="always"), so
# each is not compiled and optimized once on its own and again in its caller, which made the
# first (cold-cache) compile of triangle setup markedly slower (benchmarks/README.md).

@numba.njit(cache=True, inline="always")
def snap(v):
    """Window coordinate → fixed point, 1/256 pixel, round half to even; centre of pixel i ↦ 256·i.

    Computed as rint(v·256) − 128, which equals round((v − ½)·256) exactly:
    v·256 is exact in floating point, while v − ½ could round.
    """
    return np.int64(np.rint(v * SUBPIXEL)) - SUBPIXEL // 2


@numba.njit(cache=True, inline="always")
def edge_function(xa, ya, xb, yb, px, py):
    """Twice the signed area of (a, b, p): positive when p is left of a→b (y up)."""
    return (xb - xa) * (py - ya) - (yb - ya) * (px - xa)


@numba.njit(cache=True, inline="always")
def owns_samples_on_edge(dx, dy):
    """The fill rule for a counter-clockwise triangle's edge with direction (dx, dy), y up.

    Going counter-clockwise, a left edge runs downward (dy < 0) and the bottom
    horizontal edge runs to the right (dy = 0, dx > 0): those own their samples.
    """
    return dy < 0 or (dy == 0 and dx > 0)


@numba.njit(cache=True, inline="always")
def _pixel_range(lo, hi, first_pixel, last_pixel):
    """Pixels i with lo ≤ 256·i ≤ hi, clamped to [first_pixel, last_pixel]: (first, last)."""
    first = -((-lo) // SUBPIXEL)            # ceil(lo / 256)
    last = hi // SUBPIXEL                   # floor(hi / 256)
    return max(first, first_pixel), min(last, last_pixel)


@numba.njit(cache=True, inline="always")
def offset_bounds(offsets):
    """(x_lo, x_hi, y_lo, y_hi): the extent of the sample offsets [S, 2], in fixed point.

    A loop, not ``offsets[:, 0].min()``: numpy's reductions cost their own compile.
    """
    x_lo, x_hi, y_lo, y_hi = offsets[0, 0], offsets[0, 0], offsets[0, 1], offsets[0, 1]
    for s in range(1, offsets.shape[0]):
        x_lo, x_hi = min(x_lo, offsets[s, 0]), max(x_hi, offsets[s, 0])
        y_lo, y_hi = min(y_lo, offsets[s, 1]), max(y_hi, offsets[s, 1])
    return x_lo, x_hi, y_lo, y_hi


@numba.njit(cache=True, nogil=True)
def setup_kernel(lo, hi, window, rect, offsets, edges, bias, area, plane, box):
    """Set up triangles lo:hi (run in bands by softpipe.core.parallel); the arrays are :class:`TriangleSetup`'s."""
    ox_lo, ox_hi, oy_lo, oy_hi = offset_bounds(offsets)
    for t in range(lo, hi):
        x = (snap(window[t, 0, 0]), snap(window[t, 1, 0]), snap(window[t, 2, 0]))
        y = (snap(window[t, 0, 1]), snap(window[t, 1, 1]), snap(window[t, 2, 1]))
        signed = edge_function(x[0], y[0], x[1], y[1], x[2], y[2])
        sign = np.int64(1) if signed > 0 else np.int64(-1)      # clockwise: turn it around
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3            # edge a→b, opposite corner k
            dx, dy = sign * (x[b] - x[a]), sign * (y[b] - y[a])
            edges[t, k, 0] = -dy
            edges[t, k, 1] = dx
            edges[t, k, 2] = dy * x[a] - dx * y[a]
            bias[t, k] = 0 if owns_samples_on_edge(dx, dy) else -1
        area[t] = signed * sign
        z0 = window[t, 0, 2]
        plane[t, 0] = z0
        plane[t, 1] = window[t, 1, 2] - z0
        plane[t, 2] = window[t, 2, 2] - z0
        plane[t, 3] = 1.0 / area[t] if signed != 0 else 0.0
        if signed == 0:
            box[t, 0], box[t, 1], box[t, 2], box[t, 3] = 1, 0, 1, 0
            continue
        box[t, 0], box[t, 1] = _pixel_range(min(x[0], x[1], x[2]) - ox_hi, max(x[0], x[1], x[2]) - ox_lo,
                                            rect[0], rect[1])
        box[t, 2], box[t, 3] = _pixel_range(min(y[0], y[1], y[2]) - oy_hi, max(y[0], y[1], y[2]) - oy_lo,
                                            rect[2], rect[3])


@dataclass
class TriangleSetup:
    """Per triangle of the :class:`~softpipe.pipeline.assembly.Primitives`: what coverage, depth and shading need.

    Attributes
    ----------
    edges : int64 [T, 3, 3]
        (A_k, B_k, C_k) of each oriented edge function ``E_k = A_k·x + B_k·y + C_k``
        (x, y in fixed point, pixel i's centre at 256·i).
    bias : int64 [T, 3]
        The fill rule: a sample is covered when every ``E_k + bias_k ≥ 0``.
    area : int64 [T]
        Twice the snapped area (positive; 0: the triangle covers nothing).
    plane : float64 [T, 4]
        The depth plane (z_0, z_1 − z_0, z_2 − z_0, 1/area).
    box : int64 [T, 4]
        Pixels (i_0, i_1, j_0, j_1) that may hold a covered sample, window rows
        (y up), within the scissor; empty when i_0 > i_1.
    """

    edges: np.ndarray
    bias: np.ndarray
    area: np.ndarray
    plane: np.ndarray
    box: np.ndarray

    def __len__(self) -> int:
        return len(self.area)

    def __repr__(self) -> str:
        empty = int(((self.box[:, 0] > self.box[:, 1]) | (self.box[:, 2] > self.box[:, 3])).sum())
        return f"TriangleSetup({len(self)} triangles, {empty} with no pixel in the scissor)"

    def barycentric_gradients(self) -> np.ndarray:
        """∂b_k/∂x and ∂b_k/∂y per window pixel, [T, 2, 3]; zero for zero-area triangles.

        A step of one pixel changes E_k by 256·A_k in x and 256·B_k in y, and
        b_k = E_k / area. (These make screen-space derivatives exact, e.g. for mipmapping.)
        """
        ok = self.area != 0
        scale = np.where(ok, SUBPIXEL / np.where(ok, self.area, 1), 0.0)
        out = np.empty((len(self), 2, 3))
        out[:, 0, :] = self.edges[:, :, 0] * scale[:, None]
        out[:, 1, :] = self.edges[:, :, 1] * scale[:, None]
        return out


def pixel_rect(width: int, height: int, viewport=None) -> np.ndarray:
    """The window pixels a draw may touch, (i_min, i_max, j_min, j_max): the viewport ∩ framebuffer.

    Clipping to the view volume keeps geometry inside the viewport; with a guard
    band the rasterizer does that part, as a scissor rectangle.
    """
    if viewport is None:
        return np.array([0, width - 1, 0, height - 1], np.int64)
    return np.array([max(viewport.x, 0), min(viewport.x + viewport.width, width) - 1,
                     max(viewport.y, 0), min(viewport.y + viewport.height, height) - 1], np.int64)


def setup_triangles(window: np.ndarray, rect: np.ndarray, offsets: np.ndarray) -> TriangleSetup:
    """Set up every triangle: ``window`` [T, 3, 3] window-space corners, ``rect`` the scissor
    (:func:`pixel_rect`), ``offsets`` the sample pattern's fixed-point offsets."""
    n = len(window)
    s = TriangleSetup(np.empty((n, 3, 3), np.int64), np.empty((n, 3), np.int64), np.empty(n, np.int64),
                      np.empty((n, 4), np.float64), np.empty((n, 4), np.int64))
    if n:
        in_bands(setup_kernel, n, window, rect, offsets, s.edges, s.bias, s.area, s.plane, s.box, grain=4096)
    return s


def apply_polygon_offset(setup: TriangleSetup, window: np.ndarray, factor: float, units: float) -> None:
    """Move every triangle's depth plane away from the viewer by OpenGL's polygon offset.

    o = factor·DZ + units·r (the GL 4.6 specification, §14.6.5), where DZ =
    max(|∂z/∂x|, |∂z/∂y|) is the triangle's depth slope per window pixel and r the
    smallest difference the float32 depth buffer resolves at the triangle's
    largest depth: 2^(e − 23) for a largest depth of m·2^e, 1 ≤ m < 2. The
    offset is added to z_0 of the plane, so both paths see it; depth is still
    clamped to [0, 1] where it is evaluated. This is the slope-scaled plus constant
    bias of a shadow map's depth pass (the rasterizer's counterpart of a shadow ray's
    ε, FORMULAS §21).
    """
    if len(setup):
        in_bands(_polygon_offset_kernel, len(setup), window, setup.edges, setup.area, setup.plane, float(factor),
                 float(units), grain=4096)


@numba.njit(cache=True, nogil=True)
def _polygon_offset_kernel(lo, hi, window, edges, area, plane, factor, units):
    """:func:`apply_polygon_offset` for triangles lo:hi, in one pass (numpy's took a dozen over the arrays)."""
    for t in range(lo, hi):
        inv_area = SUBPIXEL / area[t] if area[t] != 0 else 0.0
        dz_dx = (edges[t, 1, 0] * plane[t, 1] + edges[t, 2, 0] * plane[t, 2]) * inv_area
        dz_dy = (edges[t, 1, 1] * plane[t, 1] + edges[t, 2, 1] * plane[t, 2]) * inv_area
        slope = max(abs(dz_dx), abs(dz_dy))
        z_max = min(max(max(window[t, 0, 2], window[t, 1, 2], window[t, 2, 2]), 0.0), 1.0)
        exponent = math.frexp(z_max)[1]                        # z = m·2^E with 0.5 ≤ m < 1
        r = math.ldexp(1.0, max(exponent - 1, -126) - 23)
        plane[t, 0] += factor * slope + units * r


# --------------------------------------------------- per sample, per pixel
#
# These run once per sample inside the hot loops (the rasterizer's, the visibility
# pass's, the generated shading loops'), so LLVM inlines them into their callers
# (forceinline): a call per sample costs as much as the work inside it (the `fill`
# benchmark's figure is in benchmarks/README.md). They are compiled once, on their own, and
# kept in numba's cache; numba's own inlining (inline="always") typed them again inside every
# generated shading loop, which lengthened each loop's first compile.

@numba.njit(cache=True, forceinline=True)
def edge_values(edges, t, px, py):
    """E_0, E_1, E_2 of triangle t at the fixed-point position (px, py)."""
    return (edges[t, 0, 0] * px + edges[t, 0, 1] * py + edges[t, 0, 2],
            edges[t, 1, 0] * px + edges[t, 1, 1] * py + edges[t, 1, 2],
            edges[t, 2, 0] * px + edges[t, 2, 1] * py + edges[t, 2, 2])


@numba.njit(cache=True, forceinline=True)
def inside_edge(e, bias, t, k):
    """The fill rule at one edge: is a sample where E_k of triangle t is ``e`` on its inner side, E_k + bias_k ≥ 0?

    The one statement of the rule; :func:`inside` and :func:`covers` apply it at all three
    edges, the fast path's row spans (:mod:`softpipe.pipeline.tiles`) edge by edge.
    """
    return e + bias[t, k] >= 0


@numba.njit(cache=True, forceinline=True)
def inside(e0, e1, e2, bias, t):
    """Does triangle t cover a sample whose edge values are (e0, e1, e2)? The fill rule at each edge.

    For loops that step the edge values from sample to sample (exact integers) instead
    of evaluating them at each one (:func:`covers`).
    """
    return inside_edge(e0, bias, t, 0) and inside_edge(e1, bias, t, 1) and inside_edge(e2, bias, t, 2)


@numba.njit(cache=True, forceinline=True)
def covers(edges, bias, t, px, py):
    """Does triangle t cover the sample at (px, py)? The fill rule (:func:`inside_edge`) at every edge.

    Edge by edge, stopping at the first it fails, so a sample outside skips the other edges'
    arithmetic: evaluating the three edges first (as :func:`inside` takes them) made the
    reference rasterizer's counting pass slower (benchmarks/README.md).
    """
    for k in range(3):
        if not inside_edge(edges[t, k, 0] * px + edges[t, k, 1] * py + edges[t, k, 2], bias, t, k):
            return False
    return True


@numba.njit(cache=True, forceinline=True)
def plane_depth(z0, dz1, dz2, inv_area, e1, e2):
    """The depth plane (z_0, z_1 − z_0, z_2 − z_0, 1/area) where E_1, E_2 are (e1, e2), clamped to [0, 1].

    ``z_0 + (E_1 (z_1 − z_0) + E_2 (z_2 − z_0)) / area`` = b_0 z_0 + b_1 z_1 + b_2 z_2:
    the one depth expression of softpipe (a loop that steps E along a row
    passes exact float values of E and gets the very same bytes).
    """
    z = z0 + (e1 * dz1 + e2 * dz2) * inv_area
    return min(max(z, 0.0), 1.0)


@numba.njit(cache=True, forceinline=True)
def depth_at(plane, t, e1, e2):
    """Window depth of triangle t where its E_1, E_2 are (e1, e2) (:func:`plane_depth`)."""
    return plane_depth(plane[t, 0], plane[t, 1], plane[t, 2], plane[t, 3], e1, e2)


@numba.njit(cache=True, forceinline=True)
def sample_depth(edges, plane, t, i, j, s, offsets):
    """Window depth of triangle t at sample s of pixel (i, j) (window row j, y up)."""
    _, e1, e2 = edge_values(edges, t, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1])
    return depth_at(plane, t, e1, e2)


@numba.njit(cache=True, forceinline=True)
def pixel_coverage(edges, bias, t, i, j, offsets):
    """Which samples of pixel (i, j) triangle t covers: (bit mask, first sample or −1, count)."""
    mask, first, count = np.int64(0), -1, 0
    for s in range(offsets.shape[0]):
        if covers(edges, bias, t, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1]):
            mask |= np.int64(1) << s
            count += 1
            if first < 0:
                first = s
    return mask, first, count


@numba.njit(cache=True, forceinline=True)
def shading_point(edges, plane, t, i, j, s, mask, count, offsets, positions, mode):
    """Where triangle t's fragment at sample s of pixel (i, j) is shaded: (b0, b1, b2, x, y).

    (b0, b1, b2) are the window-space barycentrics and (x, y) the window
    position (gl_FragCoord: y up, pixel centres at +½). ``mode`` SHADE_SAMPLE:
    at the sample itself; SHADE_CENTER: at the pixel centre; SHADE_CENTROID: at
    the centroid of the covered samples ``mask`` (``count`` of them). The
    centroid's edge functions are the mean of the covered samples' (exact
    integers, one division), its position the mean of their positions.
    """
    inv_area = plane[t, 3]
    if mode == SHADE_SAMPLE:
        e0, e1, e2 = edge_values(edges, t, i * SUBPIXEL + offsets[s, 0], j * SUBPIXEL + offsets[s, 1])
        return e0 * inv_area, e1 * inv_area, e2 * inv_area, i + positions[s, 0], j + positions[s, 1]
    if mode == SHADE_CENTER:
        e0, e1, e2 = edge_values(edges, t, i * SUBPIXEL, j * SUBPIXEL)
        return e0 * inv_area, e1 * inv_area, e2 * inv_area, i + 0.5, j + 0.5
    sum_e0, sum_e1, sum_e2 = np.int64(0), np.int64(0), np.int64(0)
    pos_x, pos_y = 0.0, 0.0
    for m in range(offsets.shape[0]):
        if (mask >> m) & 1:
            e0, e1, e2 = edge_values(edges, t, i * SUBPIXEL + offsets[m, 0], j * SUBPIXEL + offsets[m, 1])
            sum_e0 += e0
            sum_e1 += e1
            sum_e2 += e2
            pos_x += positions[m, 0]
            pos_y += positions[m, 1]
    return (sum_e0 / count * inv_area, sum_e1 / count * inv_area, sum_e2 / count * inv_area,
            i + pos_x / count, j + pos_y / count)
