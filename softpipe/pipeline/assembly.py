"""Stage 2: primitive assembly — vertices to window-space points, lines and triangles.

In order: topology (points; line lists, strips and loops; triangle lists, strips,
fans; indexed or not) → drop primitives with non-finite positions → homogeneous
clipping → perspective divide → viewport → face culling (triangles only: points
and lines always face the front, as in GL). With a polygon mode of "line" or
"point" (GL's ``glPolygonMode``), the triangles that survive culling are then
drawn as their three edges or their three corners. Output: :class:`Primitives`.

Every primitive is stored with three corners, so that the stages after setup
treat the three kinds alike: a triangle's corners; a line's two ends and its end
again, (a, b, b); a point's vertex three times. The fragment stage interpolates
with barycentrics over those corners (a line fragment's are (1 − t, t, 0), a point
fragment's (1 − s − t, s, t) with (s, t) its ``gl_PointCoord``).

Points are kept or discarded whole, by their vertex: one outside the view volume
(−w ≤ x, y, z ≤ w) is discarded, as the GL specification says (§13.7.1), so a
wide point whose centre leaves the viewport disappears at once; so is one outside
a user clip plane.

Clipping happens in clip space, before the divide, against
``w ≥ W_MIN`` (so nothing with w ≤ 0 is ever divided), the near plane
``z ≥ −w``, the far plane ``z ≤ w``, and a guard band ``|x|, |y| ≤ g·w`` that
keeps window coordinates within ``GUARD_PIXELS`` of the viewport's centre (so the
rasterizer's 64-bit edge functions cannot overflow). Inside the guard band, the
rasterizer's bounding box does the x/y clipping exactly, pixel by pixel. A new
vertex on a clipped edge is always computed from the edge's inside end, so two
triangles sharing the edge get the same new vertex (no cracks).

User clip planes (``clip_planes``: rows (a, b, c, d), kept where
a·x + b·y + c·z + d·w ≥ 0) and the components of the varyings ``clip_distance``
and ``clip_distance2`` (GLSL's ``gl_ClipDistance``: kept where ≥ 0) are clipped
against after those, by the same clipper: a vertex's distances ride beside its
clip position as extra coordinates, interpolated with it, so a distance's plane
is the row selecting its coordinate. With ``depth_clamp`` (GL_DEPTH_CLAMP) the near and far planes are not
clipped against (OpenGL 4.6 §13.7); window depths may then leave the depth
range, and the rasterizer's depth clamps them to [0, 1].

Varyings at a new vertex: ``smooth`` ones are interpolated linearly in clip
space (which is what makes them perspective-correct afterwards),
``noperspective`` ones linearly in window space (the parameter is t·w_b/w_new,
OpenGL 4.6 §13.7), ``flat`` ones carry the provoking vertex's value, which is
copied to every corner before clipping. The provoking vertex is the last one of
each triangle and each line (its second end; a line loop's closing line's is the
first vertex), as OpenGL's default; in polygon mode the edges and corners of a
triangle keep the triangle's.

An instanced draw (:attr:`VertexOut.instances` = N, V vertices each) repeats the
topology once per instance over that instance's vertices (vertex v of instance i
is row i·V + v), as GL's ``glDraw*Instanced`` runs the draw once per instance:
all of instance 0's primitives, then instance 1's, …; a strip, fan or loop starts
afresh in each instance (none joins one instance's last vertex to the next one's
first). Each primitive's ``primitive_id`` counts within its instance, from 0
(``gl_PrimitiveID`` restarts with each instance), and :attr:`Primitives.instance`
names its instance.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Dict, Optional

import numba
import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.language.contract import VaryingLayout
from softpipe.pipeline.transforms import Viewport
from softpipe.pipeline.vertex import VertexOut

__all__ = ["Primitives", "assemble", "triangle_indices", "primitive_indices", "primitive_kind", "TOPOLOGIES",
           "TRIANGLE_TOPOLOGIES", "LINE_TOPOLOGIES", "POLYGON_MODES", "KINDS", "CULL_MODES", "FRONT_FACES",
           "GUARD_PIXELS", "MAX_POINT_SIZE", "MAX_LINE_WIDTH", "check_size", "check_clip_planes",
           "MAX_CLIP_DISTANCES", "CLIP_DISTANCE_VARYINGS"]

TRIANGLE_TOPOLOGIES = ("triangles", "triangle_strip", "triangle_fan")
LINE_TOPOLOGIES = ("lines", "line_strip", "line_loop")
TOPOLOGIES = ("points",) + LINE_TOPOLOGIES + TRIANGLE_TOPOLOGIES
#: GL's glPolygonMode: triangles drawn filled, as their edges (lines) or as their corners (points).
POLYGON_MODES = ("fill", "line", "point")
#: What a draw's primitives are, after the topology and the polygon mode.
KINDS = ("points", "lines", "triangles")
#: The largest point size and line width (llvmpipe's); larger ones are clamped, as GL clamps to its range.
MAX_POINT_SIZE = MAX_LINE_WIDTH = 255.0
CULL_MODES = ("none", "back", "front")
FRONT_FACES = ("ccw", "cw")

#: Window coordinates stay within this many pixels of the viewport's centre.
GUARD_PIXELS = 32768.0
#: The clip plane w ≥ W_MIN: vertices at or behind the eye never reach the divide.
W_MIN = 1e-9
#: GL's minimum MAX_CLIP_DISTANCES: the most user clip planes a draw may have, and the most clip
#: distances (the components of :data:`CLIP_DISTANCE_VARYINGS`, four each).
MAX_CLIP_DISTANCES = 8


@dataclass
class Primitives:
    """Post-clip primitives in window coordinates — the rasterizer's input.

    Attributes
    ----------
    window : float64 [P, 3, 3]
        (x_w, y_w, z_w) of each corner: OpenGL window coordinates (origin at the
        lower-left, y up), depth in the depth range. A line's corners are
        (a, b, b), a point's (p, p, p) (the module docstring says why).
    inv_w : float64 [P, 3]
        1/w_clip of each corner (for perspective-correct interpolation).
    varyings : float64 [P, 3, K]
        The varyings of each corner, packed as ``layout`` says.
    layout : VaryingLayout
    primitive_id : int64 [P]
        Index of the input primitive each comes from (a clipped triangle may give
        several; in polygon mode, an edge or corner has its triangle's), counted
        within its instance in an instanced draw (GLSL's ``gl_PrimitiveID``).
    front_facing : bool [P]
        Always True for points and lines.
    clipped : bool [P]
        True for pieces of a primitive that clipping cut.
    dropped : dict reason → int64 array of primitive ids
        Input primitives that produced nothing here, and why: ``"non-finite"``,
        ``"outside"`` (entirely outside the clip volume), ``"culled"``. In an
        instanced draw these count over the whole draw: i·(input_count / instances) + id
        for primitive ``id`` of instance i.
    input_count : int
        Number of primitives the topology produced (every instance's).
    culled_window : float64 [C, 3, 3]
        Window coordinates of the triangles culled for their facing (kept for pictures).
    kind : "triangles" | "lines" | "points"
        What the rows are (:data:`KINDS`): the topology's kind, or the polygon mode's.
    size : float64 [P]
        A point's size or a line's width in pixels (clamped to [1, 255]); unused for triangles.
    faces : Primitives or None
        In polygon mode "line" or "point": the filled triangles whose edges or corners these
        are (a polygon offset takes their slope, as GL's ``POLYGON_OFFSET_LINE`` does).
    instance : int64 [P] or None
        The instance each comes from (``gl_InstanceID``; all 0 without instancing;
        None in Primitives made by hand).
    instances : int
        How many instances the draw had (1 without instancing).
    source_corners : int64 [input_count / instances, 3] or None
        The vertex indices of each input primitive of one instance, as the topology made them
        (:func:`primitive_indices`; what ``primitive_id`` counts): kept so that what reads a
        primitive id later (the buffers derived from a visibility record) reads the corners
        drawn, not the draw's indices again. None in Primitives made by hand.
    """

    window: np.ndarray
    inv_w: np.ndarray
    varyings: np.ndarray
    layout: VaryingLayout
    primitive_id: np.ndarray
    front_facing: np.ndarray
    clipped: np.ndarray
    dropped: Dict[str, np.ndarray] = field(default_factory=dict)
    input_count: int = 0
    culled_window: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    kind: str = "triangles"
    size: np.ndarray = field(default_factory=lambda: np.zeros(0))
    faces: Optional["Primitives"] = None
    instance: Optional[np.ndarray] = None
    instances: int = 1
    source_corners: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.window)

    def __repr__(self) -> str:
        drops = ", ".join(f"{k}: {len(v)}" for k, v in self.dropped.items() if len(v))
        instances = f" ({self.instances} instances)" if self.instances != 1 else ""
        return (f"Primitives({len(self)} {self.kind} from {self.input_count} input{instances}"
                f"{'; dropped ' + drops if drops else ''}; {int(self.clipped.sum())} clipped pieces)")


def _check_indices(indices, n_vertices: int, per_primitive: int = 3) -> np.ndarray:
    arr = np.asarray(indices)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"indices must be an integer array, got dtype {arr.dtype}")
    if not (arr.ndim == 1 or (arr.ndim == 2 and arr.shape[1] == per_primitive)):
        raise ValueError(f"indices must have shape [M] or [M, {per_primitive}], got {list(np.shape(indices))}")
    flat = arr.reshape(-1)
    if flat.size and flat.dtype.kind == "u" and flat.dtype.itemsize == 8 and int(flat.max()) >= n_vertices:
        # checked before the cast: a uint64 above 2^63 would turn negative in int64 (narrower
        # unsigned integers cast exactly, and the range check below sees them)
        where = int(np.argmax(flat >= n_vertices))
        raise ValueError(f"indices[{where}] = {int(flat[where])} is out of range for {n_vertices} vertices")
    if not flat.size:
        return flat.astype(np.int64)
    arr, lo, hi = _int64_and_range(flat)
    if lo < 0 or hi >= n_vertices:
        bad = lo if lo < 0 else hi
        where = int(np.nonzero(arr == bad)[0][0])
        raise ValueError(f"indices[{where}] = {bad} is out of range for {n_vertices} vertices")
    return arr


def _int64_and_range(flat: np.ndarray):
    """(flat as int64, its min, its max): one compiled pass (numpy's cast, min and max made three)."""
    if not flat.dtype.isnative:                       # (numba reads native byte order only)
        flat = flat.astype(flat.dtype.newbyteorder("="))
    if flat.dtype == np.int64:
        lo, hi = _range_of(flat)
        return flat, int(lo), int(hi)
    out = np.empty(flat.shape, np.int64)
    lo, hi = _copy_range(flat, out)
    return out, int(lo), int(hi)


@numba.njit(cache=True)
def _range_of(flat):
    lo, hi = flat[0], flat[0]
    for v in flat:
        lo, hi = min(lo, v), max(hi, v)
    return lo, hi


@numba.njit(cache=True)
def _copy_range(flat, out):
    lo, hi = np.int64(flat[0]), np.int64(flat[0])
    for k in range(flat.shape[0]):
        v = np.int64(flat[k])
        out[k] = v
        lo, hi = min(lo, v), max(hi, v)
    return lo, hi


def primitive_kind(topology: str, polygon_mode: str = "fill") -> str:
    """What a draw's primitives are (:data:`KINDS`): the topology's kind; triangles in a polygon mode
    of "line" or "point" are drawn as lines or points."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"topology must be one of {TOPOLOGIES}, got {topology!r}")
    if polygon_mode not in POLYGON_MODES:
        raise ValueError(f"polygon_mode must be one of {POLYGON_MODES}, got {polygon_mode!r}")
    if topology == "points":
        return "points"
    if topology in LINE_TOPOLOGIES:
        return "lines"
    return {"fill": "triangles", "line": "lines", "point": "points"}[polygon_mode]


def _vertex_sequence(topology: str, indices, n_vertices: int) -> np.ndarray:
    """The vertices in the order the topology takes them: ``indices`` (checked) or 0 … n − 1."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"topology must be one of {TOPOLOGIES}, got {topology!r}")
    if indices is None:
        return np.arange(n_vertices, dtype=np.int64)
    if topology not in ("triangles", "lines") and np.ndim(indices) != 1:
        what = "points" if topology == "points" else f"a {topology}"
        raise ValueError(f"indices for {what} must be 1-D, got shape {list(np.shape(indices))}")
    return _check_indices(indices, n_vertices, 2 if topology == "lines" else 3)


def triangle_indices(topology: str, indices, n_vertices: int) -> np.ndarray:
    """The vertex indices [T, 3] of each triangle; corner 2 is the provoking vertex.

    Strips: triangle i is (s_i, s_i+1, s_i+2) for even i and (s_i+1, s_i, s_i+2)
    for odd i, so every triangle keeps the winding of the first. Fans: triangle
    i is (s_0, s_i+1, s_i+2). (OpenGL 4.6 §10.1.)
    """
    if topology not in TRIANGLE_TOPOLOGIES:
        raise ValueError(f"topology must be one of {TRIANGLE_TOPOLOGIES}, got {topology!r}")
    seq = _vertex_sequence(topology, indices, n_vertices)
    if topology == "triangles":
        if len(seq) % 3:
            what = "positions (no indices)" if indices is None else "indices"
            raise ValueError(f"{what}: a triangle list needs a multiple of 3 vertices, got {len(seq)}")
        return seq.reshape(-1, 3)
    t = max(len(seq) - 2, 0)
    i = np.arange(t)
    if topology == "triangle_strip":
        odd = (i % 2).astype(bool)
        a = np.where(odd, seq[i + 1], seq[i]) if t else seq[:0]
        b = np.where(odd, seq[i], seq[i + 1]) if t else seq[:0]
        return np.stack([a, b, seq[i + 2]], axis=1) if t else np.zeros((0, 3), np.int64)
    return np.stack([np.full(t, seq[0]), seq[i + 1], seq[i + 2]], axis=1) if t else np.zeros((0, 3), np.int64)


def primitive_indices(topology: str, indices, n_vertices: int) -> np.ndarray:
    """The vertex indices [P, 3] of each primitive's three corners; corner 2 is the provoking vertex.

    Triangles as :func:`triangle_indices`. Lines (a, b, b): a list pairs the
    vertices; a strip joins each to the next, (s_i, s_i+1); a loop adds
    (s_n−1, s_0). Points (p, p, p), one per vertex. (OpenGL 4.6 §10.1.)
    """
    if topology in TRIANGLE_TOPOLOGIES:
        return triangle_indices(topology, indices, n_vertices)
    seq = _vertex_sequence(topology, indices, n_vertices)
    if topology == "points":
        return np.repeat(seq[:, None], 3, axis=1)
    if topology == "lines":
        if len(seq) % 2:
            what = "positions (no indices)" if indices is None else "indices"
            raise ValueError(f"{what}: a line list needs an even number of vertices, got {len(seq)}")
        a, b = seq[0::2], seq[1::2]
    elif len(seq) < 2:
        a = b = seq[:0]
    elif topology == "line_strip":
        a, b = seq[:-1], seq[1:]
    else:                                        # line_loop: back to the first vertex
        a, b = seq, np.roll(seq, -1)
    return np.stack([a, b, b], axis=1)


def _polygon_mode_indices(tri: np.ndarray, kept: np.ndarray, kind: str):
    """Triangles ``kept`` of ``tri`` as their edges (a, b), (b, c), (c, a) or corners: (corners [P, 3],
    provoking [P], the triangle of each), the triangle's provoking vertex (c) kept for flat varyings."""
    t = tri[kept]
    if kind == "lines":
        a = np.stack([t[:, 0], t[:, 1], t[:, 2]], axis=1).reshape(-1)
        b = np.stack([t[:, 1], t[:, 2], t[:, 0]], axis=1).reshape(-1)
        corners = np.stack([a, b, b], axis=1)
    else:
        corners = np.repeat(t.reshape(-1)[:, None], 3, axis=1)
    return corners, np.repeat(t[:, 2], 3), np.repeat(kept, 3)


def _planes(viewport: Viewport, depth_clamp: bool = False) -> np.ndarray:
    """Clip planes as rows (a, b, c, d, e): inside where a·x + b·y + c·z + d·w + e ≥ 0 (without the near
    and far planes when ``depth_clamp``)."""
    gx = max(1.0, GUARD_PIXELS / (viewport.width / 2.0))
    gy = max(1.0, GUARD_PIXELS / (viewport.height / 2.0))
    planes = np.array([
        [0, 0, 0, 1, -W_MIN],   # w ≥ W_MIN, first, so later planes see w > 0
        [0, 0, 1, 1, 0],        # near: z ≥ −w
        [0, 0, -1, 1, 0],       # far:  z ≤ w
        [1, 0, 0, gx, 0],       # guard band left
        [-1, 0, 0, gx, 0],      # guard band right
        [0, 1, 0, gy, 0],       # guard band bottom
        [0, -1, 0, gy, 0],      # guard band top
    ], dtype=np.float64)
    return planes[[0, 3, 4, 5, 6]] if depth_clamp else planes


def check_clip_planes(clip_planes) -> np.ndarray:
    """A draw's ``clip_planes``: None or up to :data:`MAX_CLIP_DISTANCES` rows (a, b, c, d) of finite
    numbers, as float64 [k, 4] (k = 0 for None or an empty list)."""
    if clip_planes is None:
        return np.zeros((0, 4))
    try:
        planes = np.array(clip_planes, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"clip_planes must be an array [k, 4] of numbers, one plane (a, b, c, d) a row, got "
                         f"{clip_planes!r}") from None
    if planes.size == 0:
        return np.zeros((0, 4))
    if planes.ndim != 2 or planes.shape[1] != 4:
        raise ValueError(f"clip_planes must have shape [k, 4], one plane (a, b, c, d) a row (kept where "
                         f"a·x + b·y + c·z + d·w ≥ 0), got shape {list(planes.shape)}")
    if len(planes) > MAX_CLIP_DISTANCES:
        raise ValueError(f"clip_planes has shape {list(planes.shape)}: at most {MAX_CLIP_DISTANCES} planes "
                         "(GL's MAX_CLIP_DISTANCES)")
    if not np.isfinite(planes).all():
        row = int(np.nonzero(~np.isfinite(planes).all(axis=1))[0][0])
        raise ValueError(f"clip_planes (shape {list(planes.shape)}) must be finite, got plane {row} = "
                         f"{planes[row].tolist()}")
    return planes


#: The varyings that are clip distances, GLSL's ``gl_ClipDistance[0..3]`` and ``[4..7]`` (a varying holds
#: at most 4 floats, so 8 distances take two).
CLIP_DISTANCE_VARYINGS = ("clip_distance", "clip_distance2")


def _clip_distance_columns(layout: VaryingLayout) -> np.ndarray:
    """The varyings' columns that are clip distances (:data:`CLIP_DISTANCE_VARYINGS`), in that order."""
    cols = [np.arange(layout.slice(name).start, layout.slice(name).stop) for name in CLIP_DISTANCE_VARYINGS
            if name in layout.names]
    return np.concatenate(cols).astype(np.int64) if cols else np.zeros(0, np.int64)


def _with_user_planes(planes: np.ndarray, user: np.ndarray, vout: VertexOut, distances: np.ndarray):
    """The clip planes and clip positions of a draw with user planes or a ``clip_distance`` varying.

    Each vertex's m distances go beside its clip position, (x, y, z, w, d_1 … d_m), so the
    clipper interpolates them as it does the position; the planes become rows over those
    coordinates (and the constant): the frustum's and the user planes (a, b, c, d) with zeros
    for the distances, then one row a distance, selecting it.
    """
    m = len(distances)
    rows = np.zeros((len(planes) + len(user) + m, 4 + m + 1))
    rows[:len(planes), :4], rows[:len(planes), -1] = planes[:, :4], planes[:, 4]
    rows[len(planes):len(planes) + len(user), :4] = user
    for k in range(m):
        rows[len(planes) + len(user) + k, 4 + k] = 1.0
    position = vout.position if not m else np.hstack([vout.position, vout.varyings[:, distances]])
    return rows, np.ascontiguousarray(position, np.float64)


#: Beyond this magnitude, clip-space coordinates are clipped in exact rational arithmetic.
EXACT_CLIP_ABOVE = float(1 << 20)


def _window_parameter(t, w_out, w_new) -> float:
    """Where the new vertex lies between the edge's ends in window space: t·w_out/w_new.

    Meaningful when both ends are in front of the eye (then it is in [0, 1]); with
    the outside end behind the eye the window position of that end does not
    exist, and the parameter is clamped to [0, 1] so varyings stay finite.
    """
    try:
        value = float(t * w_out / w_new)
    except (OverflowError, ZeroDivisionError):
        value = 1.0 if (w_out > 0) == (w_new > 0) else 0.0
    return min(max(value, 0.0), 1.0) if value == value else 0.0


def _clip_polygon(poly_pos, poly_var, planes, noperspective_cols):
    """Sutherland–Hodgman in homogeneous clip space; returns lists of corners.

    Floating point for ordinary coordinates. For huge ones (|c| > 2^20, e.g.
    1e30) ``x + g·w`` would round to ``x`` and the new vertex land in the wrong
    place, so positions are then clipped exactly with Fractions and rounded
    once at the end.
    """
    exact = max(abs(float(c)) for p in poly_pos for c in p) > EXACT_CLIP_ABOVE
    if exact:
        poly_pos = [[Fraction(float(c)) for c in p] for p in poly_pos]
        planes = [[Fraction(float(c)) for c in plane] for plane in planes]
    for plane in planes:
        if len(poly_pos) < 3:
            break
        d = [sum(plane[k] * p[k] for k in range(len(p))) + plane[-1] for p in poly_pos]
        out_pos, out_var = [], []
        n = len(poly_pos)
        for k in range(n):
            a, b = k, (k + 1) % n
            if d[a] >= 0:
                out_pos.append(poly_pos[a])
                out_var.append(poly_var[a])
            if (d[a] >= 0) != (d[b] >= 0):
                inside, outside = (a, b) if d[a] >= 0 else (b, a)   # always from the inside end
                pos, var = _crossing(poly_pos[inside], poly_pos[outside], poly_var[inside], poly_var[outside],
                                     d[inside], d[outside], noperspective_cols, exact)
                out_pos.append(pos)
                out_var.append(var)
        poly_pos, poly_var = out_pos, out_var
    return [np.array([float(c) for c in p]) for p in poly_pos], poly_var


def _crossing(p_in, p_out, v_in, v_out, d_in, d_out, noperspective_cols, exact: bool):
    """The new vertex where an edge from its inside end ``p_in`` to ``p_out`` crosses a plane (signed
    distances ``d_in`` ≥ 0 > ``d_out``): its clip position and its varyings."""
    t = d_in / (d_in - d_out)
    pos = [p_in[c] + t * (p_out[c] - p_in[c]) for c in range(len(p_in))]
    var = v_in + float(t) * (v_out - v_in)
    if len(noperspective_cols):
        sw = _window_parameter(t, p_out[3], pos[3])
        var[noperspective_cols] = v_in[noperspective_cols] + sw * (v_out[noperspective_cols] - v_in[noperspective_cols])
    return np.array(pos, dtype=object if exact else np.float64), var


def _clip_segment(ends_pos, ends_var, planes, noperspective_cols):
    """Clip a segment (two clip-space ends) against every plane; returns the two new ends or None.

    Each plane cuts the segment at a new end computed from its inside end, as for
    polygons (:func:`_clip_polygon`, with exact arithmetic for huge coordinates).
    """
    exact = max(abs(float(c)) for p in ends_pos for c in p) > EXACT_CLIP_ABOVE
    if exact:
        ends_pos = [[Fraction(float(c)) for c in p] for p in ends_pos]
        planes = [[Fraction(float(c)) for c in plane] for plane in planes]
    ends_pos, ends_var = list(ends_pos), list(ends_var)
    for plane in planes:
        d = [sum(plane[k] * p[k] for k in range(len(p))) + plane[-1] for p in ends_pos]
        if d[0] < 0 and d[1] < 0:
            return None
        if (d[0] >= 0) != (d[1] >= 0):
            inside, outside = (0, 1) if d[0] >= 0 else (1, 0)
            ends_pos[outside], ends_var[outside] = _crossing(ends_pos[inside], ends_pos[outside], ends_var[inside],
                                                             ends_var[outside], d[inside], d[outside],
                                                             noperspective_cols, exact)
    return [np.array([float(c) for c in p]) for p in ends_pos], ends_var


def _columns(layout: VaryingLayout, qualifier: str) -> np.ndarray:
    cols = [off + c for _, off, size, q in layout.fields if q == qualifier for c in range(size)]
    return np.array(cols, dtype=np.int64)


ACCEPTED, NON_FINITE, OUTSIDE, CUT, CULLED = 0, 1, 2, 3, 4


@numba.njit(cache=True)
def _to_window(x, y, z, w, vp):
    """Divide by w and apply the viewport (vp = x, y, width/2, height/2, near, (far − near)/2)."""
    return (vp[0] + (x / w + 1.0) * vp[2],
            vp[1] + (y / w + 1.0) * vp[3],
            vp[4] + (z / w + 1.0) * vp[5])


@numba.njit(cache=True)
def _signed_area(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)


NON_FINITE_BIT = 1 << 7   # beside one bit per clip plane (7 planes; user planes' bits are above it)


@numba.njit(cache=True, nogil=True)
def _vertex_codes(lo, hi, pos, planes, vp, codes, window):
    """Per vertex lo:hi, once (vertices are shared by triangles): a bit per clip plane it is
    outside of (and NON_FINITE_BIT), and its window position when it is inside every plane."""
    for v in range(lo, hi):
        code = 0
        if not (np.isfinite(pos[v, 0]) and np.isfinite(pos[v, 1]) and np.isfinite(pos[v, 2])
                and np.isfinite(pos[v, 3])):
            code = NON_FINITE_BIT
        else:
            for p in range(planes.shape[0]):
                d = (planes[p, 0] * pos[v, 0] + planes[p, 1] * pos[v, 1] + planes[p, 2] * pos[v, 2]
                     + planes[p, 3] * pos[v, 3] + planes[p, 4])
                if d < 0:
                    code |= 1 << p
        codes[v] = code
        if code == 0:
            window[v, 0], window[v, 1], window[v, 2] = _to_window(pos[v, 0], pos[v, 1], pos[v, 2], pos[v, 3], vp)


@numba.njit(cache=True, nogil=True)
def _vertex_codes_user(lo, hi, pos, planes, vp, codes, window):
    """:func:`_vertex_codes` for a draw with user clip planes or a ``clip_distance`` varying (its own
    kernel, so that draws without them do no more work a vertex): ``pos`` [N, 4 + m] carries each
    vertex's m distances beside its position, a row of ``planes`` is 4 + m coefficients and the
    constant, and the planes after the seventh take the bits above NON_FINITE_BIT. A distance that
    is not finite makes the vertex non-finite."""
    m = pos.shape[1]
    for v in range(lo, hi):
        code = 0
        for k in range(m):
            if not np.isfinite(pos[v, k]):
                code = NON_FINITE_BIT
        if code == 0:
            for p in range(planes.shape[0]):
                d = (planes[p, 0] * pos[v, 0] + planes[p, 1] * pos[v, 1] + planes[p, 2] * pos[v, 2]
                     + planes[p, 3] * pos[v, 3])
                for k in range(4, m):          # the order the clipper's sum takes (_clip_polygon)
                    d += planes[p, k] * pos[v, k]
                d += planes[p, m]
                if d < 0:
                    code |= 1 << (p if p < 7 else p + 1)
        codes[v] = code
        if code == 0:
            window[v, 0], window[v, 1], window[v, 2] = _to_window(pos[v, 0], pos[v, 1], pos[v, 2], pos[v, 3], vp)


@numba.njit(cache=True, nogil=True)
def _classify(lo, hi, codes, window, tri, cull, ccw_front, status, front):
    """Per input triangle: ACCEPTED, NON_FINITE, OUTSIDE, CUT or CULLED, and its facing.

    From its corners' codes: any corner non-finite → NON_FINITE; all three outside
    one plane → OUTSIDE; some corner outside some plane → CUT (clipped later);
    else facing from the window-space area, and culling.
    """
    for t in range(lo, hi):
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        any_out = codes[a] | codes[b] | codes[c]
        if any_out & NON_FINITE_BIT:
            status[t] = NON_FINITE
        elif codes[a] & codes[b] & codes[c]:
            status[t] = OUTSIDE
        elif any_out:
            status[t] = CUT           # facing comes from the clipped polygon, later
        else:
            area = _signed_area(window[a, 0], window[a, 1], window[b, 0], window[b, 1], window[c, 0], window[c, 1])
            front[t] = area > 0 if ccw_front else area < 0
            status[t] = CULLED if (cull == 1 and not front[t]) or (cull == 2 and front[t]) else ACCEPTED


@numba.njit(cache=True, nogil=True)
def _classify_lines(lo, hi, codes, tri, status):
    """Per input line: NON_FINITE, OUTSIDE (both ends outside one plane), CUT or ACCEPTED."""
    for t in range(lo, hi):
        a, b = tri[t, 0], tri[t, 1]
        any_out = codes[a] | codes[b]
        if any_out & NON_FINITE_BIT:
            status[t] = NON_FINITE
        elif codes[a] & codes[b]:
            status[t] = OUTSIDE
        else:
            status[t] = CUT if any_out else ACCEPTED


@numba.njit(cache=True, nogil=True)
def _classify_points(lo, hi, pos, codes, tri, status):
    """Per input point: NON_FINITE, OUTSIDE (its vertex is outside the view volume −w ≤ x, y, z ≤ w,
    or behind the eye, or outside a user clip plane; z is free with a depth clamp: the codes say) or
    ACCEPTED; a point is never cut."""
    for t in range(lo, hi):
        v = tri[t, 0]
        if codes[v] & NON_FINITE_BIT:
            status[t] = NON_FINITE
        elif codes[v] or abs(pos[v, 0]) > pos[v, 3] or abs(pos[v, 1]) > pos[v, 3]:
            status[t] = OUTSIDE
        else:
            status[t] = ACCEPTED


@numba.njit(cache=True, nogil=True)
def _emit_accepted(lo, hi, pos, var, tri, provoking, status, offset, vertex_window, flat, window, inv_w, out_var,
                   key):
    """Write the accepted primitives among lo:hi at their output rows (primitive order kept by ``offset``)."""
    for t in range(lo, hi):
        if status[t] != ACCEPTED:
            continue
        o = offset[t]
        key[o] = t
        for c in range(3):
            v = tri[t, c]
            window[o, c, 0] = vertex_window[v, 0]
            window[o, c, 1] = vertex_window[v, 1]
            window[o, c, 2] = vertex_window[v, 2]
            inv_w[o, c] = 1.0 / pos[v, 3]
            for k in range(var.shape[1]):
                out_var[o, c, k] = var[v, k]
            for k in flat:                       # the provoking vertex's value on every corner
                out_var[o, c, k] = var[provoking[t], k]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _pack_line_vertices(lo, hi, pos, vertex_window, var, packed):
    """Vertices lo:hi's corner values in one row each, for :func:`_emit_lines`: window x, y, z, 1/w, then
    the varyings. (The numpy error model: a vertex no accepted line uses may have w = 0, whose 1/w is
    then never read; every used one has w > 0, and its 1/w is the number :func:`_emit_accepted` makes.)"""
    k = var.shape[1]
    for v in range(lo, hi):
        packed[v, 0] = vertex_window[v, 0]
        packed[v, 1] = vertex_window[v, 1]
        packed[v, 2] = vertex_window[v, 2]
        packed[v, 3] = 1.0 / pos[v, 3]
        for c in range(k):
            packed[v, 4 + c] = var[v, c]


@numba.njit(cache=True, nogil=True)
def _emit_lines(lo, hi, packed, tri, provoking, status, offset, flat, window, inv_w, out_var, key):
    """:func:`_emit_accepted` for lines whose vertices are shared (an indexed wireframe's): each end's values
    read once from its packed row (:func:`_pack_line_vertices`), the second written to corners 1 and 2.

    A wireframe's second ends come in no order: reading an end's window position, w and varyings
    from three arrays was three cache misses, and the second end was read twice."""
    k_var = packed.shape[1] - 4
    for t in range(lo, hi):
        if status[t] != ACCEPTED:
            continue
        o = offset[t]
        key[o] = t
        a, b = tri[t, 0], tri[t, 1]
        window[o, 0, 0] = packed[a, 0]
        window[o, 0, 1] = packed[a, 1]
        window[o, 0, 2] = packed[a, 2]
        inv_w[o, 0] = packed[a, 3]
        x, y, z, w = packed[b, 0], packed[b, 1], packed[b, 2], packed[b, 3]
        window[o, 1, 0] = window[o, 2, 0] = x
        window[o, 1, 1] = window[o, 2, 1] = y
        window[o, 1, 2] = window[o, 2, 2] = z
        inv_w[o, 1] = inv_w[o, 2] = w
        for k in range(k_var):
            out_var[o, 0, k] = packed[a, 4 + k]
            value = packed[b, 4 + k]
            out_var[o, 1, k] = out_var[o, 2, k] = value
        for k in flat:                       # the provoking vertex's value on every corner
            value = packed[provoking[t], 4 + k]
            out_var[o, 0, k] = out_var[o, 1, k] = out_var[o, 2, k] = value


@numba.njit(cache=True)
def _windows_of(clip, vp):
    out = np.empty((clip.shape[0], 3))
    for n in range(clip.shape[0]):
        out[n, 0], out[n, 1], out[n, 2] = _to_window(clip[n, 0], clip[n, 1], clip[n, 2], clip[n, 3], vp)
    return out


@numba.njit(cache=True)
def _ids_with(status, code):
    """The triangles whose status is ``code``, in order (two compiled passes over the int8 statuses)."""
    count = 0
    for t in range(status.shape[0]):
        count += status[t] == code
    ids = np.empty(count, np.int64)
    k = 0
    for t in range(status.shape[0]):
        if status[t] == code:
            ids[k] = t
            k += 1
    return ids


@numba.njit(cache=True)
def _output_offsets(status, cut_ids, cut_counts):
    """Each input triangle's first output row [n + 1]: one for an accepted triangle, its pieces for a
    clipped one (``cut_ids`` in increasing order, ``cut_counts`` pieces each), none for the rest."""
    offset = np.empty(status.shape[0] + 1, np.int64)
    offset[0] = 0
    rows, p = 0, 0
    for t in range(status.shape[0]):
        if p < cut_ids.shape[0] and cut_ids[p] == t:
            rows += cut_counts[p]
            p += 1
        elif status[t] == ACCEPTED:
            rows += 1
        offset[t + 1] = rows
    return offset


def _viewport_params(viewport: Viewport) -> np.ndarray:
    return np.array([viewport.x, viewport.y, viewport.width / 2, viewport.height / 2, viewport.near,
                     (viewport.far - viewport.near) / 2], dtype=np.float64)


def _clip_cut_lines(vout, tri, provoking, cut_ids, planes, vp, layout, status, clip_pos):
    """Clip the lines that cross a plane; returns {t: (window [1,3,3], inv_w [1,3], var [1,3,K], True)}.

    ``clip_pos`` is each vertex's clip position, with its clip distances beside it (:func:`_with_user_planes`).
    """
    flat, nopersp = _columns(layout, "flat"), _columns(layout, "noperspective")
    pieces = {}
    for t in cut_ids:
        a, b = tri[t, 0], tri[t, 1]
        ends_var = [vout.varyings[a].copy(), vout.varyings[b].copy()]
        for v in ends_var:
            v[flat] = vout.varyings[provoking[t], flat]
        clipped = _clip_segment([clip_pos[a], clip_pos[b]], ends_var, planes, nopersp)
        if clipped is None:
            status[t] = OUTSIDE
            continue
        (pa, pb), (va, vb) = clipped
        clip = np.array([[pa[:4], pb[:4], pb[:4]]])                                        # [1, 3, 4]
        win = _windows_of(clip.reshape(-1, 4), vp).reshape(-1, 3, 3)
        pieces[int(t)] = (win, 1.0 / clip[:, :, 3], np.array([[va, vb, vb]]), True)
    return pieces


def _clip_cut(vout, tri, cut_ids, planes, vp, layout, cull, ccw_front, status, clip_pos):
    """Clip the triangles that cross a plane; returns {t: (window [n,3,3], inv_w [n,3], var [n,3,K], front)}.

    ``clip_pos`` is each vertex's clip position, with its clip distances beside it (:func:`_with_user_planes`).
    """
    flat, nopersp = _columns(layout, "flat"), _columns(layout, "noperspective")
    pieces = {}
    for t in cut_ids:
        corners = clip_pos[tri[t]]
        cvar = vout.varyings[tri[t]].copy()
        if len(flat):
            cvar[:, flat] = cvar[2, flat]
        ppos, pvar = _clip_polygon(list(corners), list(cvar), planes, nopersp)
        if len(ppos) < 3:
            status[t] = OUTSIDE
            continue
        fan = [(0, k, k + 1) for k in range(1, len(ppos) - 1)]
        clip = np.array([[ppos[i][:4] for i in f] for f in fan])             # [n, 3, 4]
        win = _windows_of(clip.reshape(-1, 4), vp).reshape(-1, 3, 3)
        total = sum(_signed_area(*w[0, :2], *w[1, :2], *w[2, :2]) for w in win)
        front = total > 0 if ccw_front else total < 0
        if (cull == 1 and not front) or (cull == 2 and front):
            status[t] = CULLED
            continue
        pieces[int(t)] = (win, 1.0 / clip[:, :, 3], np.array([[pvar[i] for i in f] for f in fan]), front)
    return pieces


def assemble(vout: VertexOut, topology: str = "triangles", indices=None, *,
             viewport: Viewport, cull: str = "none", front_face: str = "ccw",
             keep_culled: bool = True, polygon_mode: str = "fill", point_size: float = 1.0,
             line_width: float = 1.0, clip_planes=None, depth_clamp: bool = False) -> Primitives:
    """Primitive assembly: see the module docstring for the steps and their order.

    ``keep_culled`` keeps the window coordinates of culled triangles (for pictures).
    ``polygon_mode`` draws triangles as their edges ("line") or corners ("point")
    after culling (:data:`POLYGON_MODES`). ``point_size`` is every point's size, unless
    the vertices carry a one-component varying ``point_size`` (GLSL's ``gl_PointSize``);
    ``line_width`` every line's width; both in pixels, clamped to [1, 255].
    ``clip_planes`` ([k, 4], k ≤ :data:`MAX_CLIP_DISTANCES`, :func:`check_clip_planes`) are
    user clip planes (a, b, c, d) in clip coordinates: what is kept is where
    a·x + b·y + c·z + d·w ≥ 0; the varyings ``clip_distance`` and ``clip_distance2``
    (:data:`CLIP_DISTANCE_VARYINGS`, GLSL's ``gl_ClipDistance[0..3]`` and ``[4..7]``) clip each
    component where its value is < 0, and still reach the fragment shader as ordinary
    varyings. A point outside either is discarded whole.
    ``depth_clamp`` (GL_DEPTH_CLAMP) leaves out the near and far planes.
    """
    if cull not in CULL_MODES:
        raise ValueError(f"cull must be one of {CULL_MODES}, got {cull!r}")
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    point_size, line_width = check_size("point_size", point_size), check_size("line_width", line_width)
    user = check_clip_planes(clip_planes)
    if not isinstance(depth_clamp, (bool, np.bool_)):
        raise ValueError(f"depth_clamp must be True or False, got {depth_clamp!r}")
    clipping = (user, bool(depth_clamp))
    kind = primitive_kind(topology, polygon_mode)
    corners = source = primitive_indices(topology, indices, vout.vertices_per_instance)
    per_instance = len(corners)
    corners = _per_instance(corners, vout)
    whole_list = indices is None and topology == "triangles"
    if topology in TRIANGLE_TOPOLOGIES and kind != "triangles":
        faces = _assemble(vout, corners, corners[:, 2], "triangles", viewport, cull, front_face, keep_culled,
                          whole_list, clipping=clipping)
        kept = np.unique(faces.primitive_id)
        edges, provoking, owner = _polygon_mode_indices(corners, kept, kind)
        prims = _assemble(vout, edges, provoking, kind, viewport, cull, front_face, False, False,
                          point_size, line_width, clipping)
        prims.primitive_id = owner[prims.primitive_id]
        prims.dropped, prims.input_count, prims.culled_window = faces.dropped, faces.input_count, faces.culled_window
        prims.faces = _name_instances(faces, per_instance, vout.instances)
        prims.source_corners = source
        return _name_instances(prims, per_instance, vout.instances)
    prims = _assemble(vout, corners, corners[:, 2], kind, viewport, cull, front_face, keep_culled, whole_list,
                      point_size, line_width, clipping)
    prims.source_corners = source
    return _name_instances(prims, per_instance, vout.instances)


def _per_instance(corners: np.ndarray, vout: VertexOut) -> np.ndarray:
    """One instance's primitives' corners [P, 3] repeated for every instance (instance i's vertices are rows
    i·V … i·V + V − 1), instance by instance: [N·P, 3]."""
    if vout.instance_vertices is None:
        return corners
    shift = np.arange(vout.instances, dtype=np.int64) * vout.instance_vertices
    return (corners[None, :, :] + shift[:, None, None]).reshape(-1, 3)


def _name_instances(prims: Primitives, per_instance: int, instances: int) -> Primitives:
    """Split the draw-wide primitive ids (i·P + id) into the instance i and the id within it."""
    prims.instances = instances
    if instances == 1 or per_instance == 0:
        prims.instance = np.zeros(len(prims), np.int64)
    else:
        prims.instance, prims.primitive_id = np.divmod(prims.primitive_id, per_instance)
    return prims


def check_size(name: str, value) -> float:
    """A draw's ``point_size`` or ``line_width``: a finite number > 0, clamped to [1, 255] (GL's range)."""
    try:
        size = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number of pixels, got {value!r}") from None
    if not (np.isfinite(size) and size > 0):
        raise ValueError(f"{name} must be a finite number of pixels > 0, got {value!r}")
    return min(max(size, 1.0), MAX_POINT_SIZE)


def _sizes(vout: VertexOut, corners: np.ndarray, kind: str, point_size: float, line_width: float,
           status: np.ndarray) -> np.ndarray:
    """Each input primitive's size: the line width, or the point size (per vertex from a varying
    ``point_size``: clamped to [1, 255]; a point whose size is not finite is dropped as non-finite)."""
    if kind == "lines":
        return np.full(len(corners), line_width)
    if kind == "triangles" or "point_size" not in vout.layout.names:
        return np.full(len(corners), point_size)
    column = vout.layout.slice("point_size")
    if column.stop - column.start != 1:
        raise ValueError(f"the varying 'point_size' (gl_PointSize) must be one number per vertex, got "
                         f"{column.stop - column.start} components")
    size = vout.varyings[corners[:, 0], column.start]
    bad = ~np.isfinite(size)
    status[bad & (status != OUTSIDE)] = NON_FINITE
    return np.clip(np.where(bad, 1.0, size), 1.0, MAX_POINT_SIZE)


def _assemble(vout: VertexOut, tri: np.ndarray, provoking: np.ndarray, kind: str, viewport: Viewport, cull: str,
              front_face: str, keep_culled: bool, whole_list: bool, point_size: float = 1.0,
              line_width: float = 1.0, clipping=(np.zeros((0, 4)), False)) -> Primitives:
    """Assemble primitives of one kind: corners ``tri`` [n, 3] and the provoking vertex of each.

    ``clipping`` is (the user clip planes [k, 4], depth clamp).
    """
    layout, n = vout.layout, len(tri)
    user, depth_clamp = clipping
    planes, vp = _planes(viewport, depth_clamp), _viewport_params(viewport)
    distances = _clip_distance_columns(layout)
    clip_pos, codes_of, code_type = vout.position, _vertex_codes, np.uint8
    if len(user) or len(distances):
        planes, clip_pos = _with_user_planes(planes, user, vout, distances)
        codes_of, code_type = _vertex_codes_user, np.uint32
    cull_code, ccw_front = CULL_MODES.index(cull), front_face == "ccw"
    status = np.empty(n, np.int8)
    front = np.zeros(n, bool) if kind == "triangles" else np.ones(n, bool)
    codes = np.empty(len(vout.position), code_type)
    vertex_window = np.empty((len(vout.position), 3))
    if n:
        in_bands(codes_of, len(vout.position), clip_pos, planes, vp, codes, vertex_window, grain=8192)
        if kind == "triangles":
            in_bands(_classify, n, codes, vertex_window, tri, cull_code, ccw_front, status, front, grain=8192)
        elif kind == "lines":
            in_bands(_classify_lines, n, codes, tri, status, grain=8192)
        else:
            in_bands(_classify_points, n, vout.position, codes, tri, status, grain=8192)
    size_in = _sizes(vout, tri, kind, point_size, line_width, status)
    cut_ids = _ids_with(status, CUT)
    if kind == "triangles":
        pieces = _clip_cut(vout, tri, cut_ids, planes, vp, layout, cull_code, ccw_front, status, clip_pos)
    else:
        pieces = _clip_cut_lines(vout, tri, provoking, cut_ids, planes, vp, layout, status, clip_pos)
    for t, (_, _, _, f) in pieces.items():
        front[t] = f
    offset = _output_offsets(status, np.fromiter(pieces, np.int64, len(pieces)),
                             np.array([len(p[0]) for p in pieces.values()], np.int64))
    total = int(offset[-1])
    k, flat = layout.width, _columns(layout, "flat")
    if whole_list and not pieces and total == n and not len(flat):
        # Every triangle kept whole, and vertex 3t + c is corner c of triangle t: the
        # per-vertex arrays already are the per-corner ones (views, not copies).
        window, inv_w = vertex_window.reshape(n, 3, 3), 1.0 / vout.position[:, 3].reshape(n, 3)
        out_var, key = vout.varyings.reshape(n, 3, k), np.arange(n, dtype=np.int64)
    else:
        window, inv_w = np.empty((total, 3, 3)), np.empty((total, 3))
        out_var, key = np.empty((total, 3, k)), np.empty(total, np.int64)
        # the provoking vertices are read only for flat varyings
        provoking = np.ascontiguousarray(provoking) if len(flat) else np.zeros(0, np.int64)
        if n and kind == "lines" and n > len(vout.position):
            # lines sharing their vertices (more lines than vertices: a wireframe's edges), whose ends
            # come in no order: each vertex's values packed in one row first (_emit_lines). Not for
            # triangles and points, which it made slower (benchmarks/README.md, round 3)
            packed = np.empty((len(vout.position), 4 + k))
            in_bands(_pack_line_vertices, len(packed), vout.position, vertex_window, vout.varyings, packed,
                     grain=8192)
            in_bands(_emit_lines, n, packed, tri, provoking, status, offset, flat, window, inv_w, out_var, key,
                     grain=8192)
        elif n:
            in_bands(_emit_accepted, n, vout.position, vout.varyings, tri, provoking, status, offset,
                     vertex_window, flat, window, inv_w, out_var, key, grain=8192)
    clipped = np.zeros(total, bool)
    for t, (win, iw, pv, _) in pieces.items():
        rows = slice(offset[t], offset[t] + len(win))
        window[rows], inv_w[rows], out_var[rows], key[rows], clipped[rows] = win, iw, pv, t, True

    dropped = {"non-finite": _ids_with(status, NON_FINITE), "outside": _ids_with(status, OUTSIDE),
               "culled": _ids_with(status, CULLED)}
    culled_window = np.zeros((0, 3, 3))
    if keep_culled and len(dropped["culled"]):
        culled_window = _culled_windows(vout, tri, dropped["culled"], vp)
    return Primitives(window=window, inv_w=inv_w, varyings=out_var, layout=layout, primitive_id=key,
                      front_facing=front[key], clipped=clipped, dropped=dropped, input_count=n,
                      culled_window=culled_window, kind=kind, size=size_in[key])


def _culled_windows(vout, tri, culled, vp) -> np.ndarray:
    """Window coordinates of culled triangles whose corners are all in front of the eye."""
    corners = vout.position[tri[culled]]
    corners = corners[(corners[:, :, 3] > W_MIN).all(axis=1)]
    return _windows_of(corners.reshape(-1, 4), vp).reshape(-1, 3, 3)
