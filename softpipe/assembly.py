"""Stage 2: primitive assembly — vertices to window-space triangles.

In order: topology (lists, strips, fans; indexed or not) → drop primitives with
non-finite positions → homogeneous clipping → perspective divide → viewport →
face culling. Output: :class:`Primitives`.

Clipping happens in clip space, before the divide, against
``w ≥ W_MIN`` (so nothing with w ≤ 0 is ever divided), the near plane
``z ≥ −w``, the far plane ``z ≤ w``, and a guard band ``|x|, |y| ≤ g·w`` that
keeps window coordinates within ``GUARD_PIXELS`` of the viewport's centre (so the
rasterizer's 64-bit edge functions cannot overflow). Inside the guard band, the
rasterizer's bounding box does the x/y clipping exactly, pixel by pixel. A new
vertex on a clipped edge is always computed from the edge's inside end, so two
triangles sharing the edge get the same new vertex (no cracks).

Varyings at a new vertex: ``smooth`` ones are interpolated linearly in clip
space (which is what makes them perspective-correct afterwards),
``noperspective`` ones linearly in window space (the parameter is t·w_b/w_new,
OpenGL 4.6 §13.7), ``flat`` ones carry the provoking vertex's value, which is
copied to every corner before clipping. The provoking vertex is the last one of
each triangle, as OpenGL's default.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

from .shader import VaryingLayout
from .transforms import Viewport
from .vertex import VertexOut

__all__ = ["Primitives", "assemble", "triangle_indices", "TOPOLOGIES", "CULL_MODES", "FRONT_FACES"]

TOPOLOGIES = ("triangles", "triangle_strip", "triangle_fan")
CULL_MODES = ("none", "back", "front")
FRONT_FACES = ("ccw", "cw")

#: Window coordinates stay within this many pixels of the viewport's centre.
GUARD_PIXELS = 32768.0
#: The clip plane w ≥ W_MIN: vertices at or behind the eye never reach the divide.
W_MIN = 1e-9


@dataclass
class Primitives:
    """Post-clip triangles in window coordinates — the rasterizer's input.

    Attributes
    ----------
    window : float64 [P, 3, 3]
        (x_w, y_w, z_w) of each corner: OpenGL window coordinates (origin at the
        lower-left, y up), depth in the depth range.
    inv_w : float64 [P, 3]
        1/w_clip of each corner (for perspective-correct interpolation).
    varyings : float64 [P, 3, K]
        The varyings of each corner, packed as ``layout`` says.
    layout : VaryingLayout
    primitive_id : int64 [P]
        Index of the input triangle each comes from (a clipped triangle may give several).
    front_facing : bool [P]
    clipped : bool [P]
        True for pieces of a triangle that clipping cut.
    dropped : dict reason → int64 array of primitive ids
        Input triangles that produced nothing here, and why: ``"non-finite"``,
        ``"outside"`` (entirely outside the clip volume), ``"culled"``.
    input_count : int
        Number of triangles the topology produced.
    culled_window : float64 [C, 3, 3]
        Window coordinates of the triangles culled for their facing (kept for pictures).
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

    def __len__(self) -> int:
        return len(self.window)

    def __repr__(self) -> str:
        drops = ", ".join(f"{k}: {len(v)}" for k, v in self.dropped.items() if len(v))
        return (f"Primitives({len(self)} triangles from {self.input_count} input"
                f"{'; dropped ' + drops if drops else ''}; {int(self.clipped.sum())} clipped pieces)")


def _check_indices(indices, n_vertices: int) -> np.ndarray:
    arr = np.asarray(indices)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"indices must be an integer array, got dtype {arr.dtype}")
    arr = arr.astype(np.int64, copy=False).reshape(-1) if arr.ndim in (1, 2) else None
    if arr is None:
        raise ValueError(f"indices must have shape [M] or [M, 3], got {list(np.shape(indices))}")
    if arr.size:
        lo, hi = int(arr.min()), int(arr.max())
        if lo < 0 or hi >= n_vertices:
            bad = lo if lo < 0 else hi
            where = int(np.nonzero(arr == bad)[0][0])
            raise ValueError(f"indices[{where}] = {bad} is out of range for {n_vertices} vertices")
    return arr


def triangle_indices(topology: str, indices, n_vertices: int) -> np.ndarray:
    """The vertex indices [T, 3] of each triangle; corner 2 is the provoking vertex.

    Strips: triangle i is (s_i, s_i+1, s_i+2) for even i and (s_i+1, s_i, s_i+2)
    for odd i, so every triangle keeps the winding of the first. Fans: triangle
    i is (s_0, s_i+1, s_i+2). (OpenGL 4.6 §10.1.)
    """
    if topology not in TOPOLOGIES:
        raise ValueError(f"topology must be one of {TOPOLOGIES}, got {topology!r}")
    if indices is None:
        seq = np.arange(n_vertices, dtype=np.int64)
    else:
        if topology != "triangles" and np.ndim(indices) != 1:
            raise ValueError(f"indices for a {topology} must be 1-D, got shape {list(np.shape(indices))}")
        seq = _check_indices(indices, n_vertices)
    if topology == "triangles":
        if len(seq) % 3:
            raise ValueError(f"a triangle list needs a multiple of 3 vertices, got {len(seq)}")
        return seq.reshape(-1, 3)
    t = max(len(seq) - 2, 0)
    i = np.arange(t)
    if topology == "triangle_strip":
        odd = (i % 2).astype(bool)
        a = np.where(odd, seq[i + 1], seq[i]) if t else seq[:0]
        b = np.where(odd, seq[i], seq[i + 1]) if t else seq[:0]
        return np.stack([a, b, seq[i + 2]], axis=1) if t else np.zeros((0, 3), np.int64)
    return np.stack([np.full(t, seq[0]), seq[i + 1], seq[i + 2]], axis=1) if t else np.zeros((0, 3), np.int64)


def _planes(viewport: Viewport) -> np.ndarray:
    """Clip planes as rows (a, b, c, d, e): inside where a·x + b·y + c·z + d·w + e ≥ 0."""
    gx = max(1.0, GUARD_PIXELS / (viewport.width / 2.0))
    gy = max(1.0, GUARD_PIXELS / (viewport.height / 2.0))
    return np.array([
        [0, 0, 0, 1, -W_MIN],   # w ≥ W_MIN, first, so later planes see w > 0
        [0, 0, 1, 1, 0],        # near: z ≥ −w
        [0, 0, -1, 1, 0],       # far:  z ≤ w
        [1, 0, 0, gx, 0],       # guard band left
        [-1, 0, 0, gx, 0],      # guard band right
        [0, 1, 0, gy, 0],       # guard band bottom
        [0, -1, 0, gy, 0],      # guard band top
    ], dtype=np.float64)


def _clip_polygon(poly_pos, poly_var, planes, noperspective_cols):
    """Sutherland–Hodgman in homogeneous clip space; returns lists of corners."""
    for plane in planes:
        if len(poly_pos) < 3:
            break
        d = [plane[:4] @ p + plane[4] for p in poly_pos]
        out_pos, out_var = [], []
        n = len(poly_pos)
        for k in range(n):
            a, b = k, (k + 1) % n
            if d[a] >= 0:
                out_pos.append(poly_pos[a])
                out_var.append(poly_var[a])
            if (d[a] >= 0) != (d[b] >= 0):
                inside, outside = (a, b) if d[a] >= 0 else (b, a)
                t = d[inside] / (d[inside] - d[outside])
                p_in, p_out = poly_pos[inside], poly_pos[outside]
                pos = p_in + t * (p_out - p_in)
                var = poly_var[inside] + t * (poly_var[outside] - poly_var[inside])
                if len(noperspective_cols):
                    s = t * p_out[3] / pos[3]  # the same point's parameter in window space
                    v_in, v_out = poly_var[inside], poly_var[outside]
                    var[noperspective_cols] = v_in[noperspective_cols] + s * (
                        v_out[noperspective_cols] - v_in[noperspective_cols])
                out_pos.append(pos)
                out_var.append(var)
        poly_pos, poly_var = out_pos, out_var
    return poly_pos, poly_var


def _columns(layout: VaryingLayout, qualifier: str) -> np.ndarray:
    cols = [off + c for _, off, size, q in layout.fields if q == qualifier for c in range(size)]
    return np.array(cols, dtype=np.int64)


def assemble(vout: VertexOut, topology: str = "triangles", indices=None, *,
             viewport: Viewport, cull: str = "none", front_face: str = "ccw") -> Primitives:
    """Primitive assembly: see the module docstring for the steps and their order."""
    if cull not in CULL_MODES:
        raise ValueError(f"cull must be one of {CULL_MODES}, got {cull!r}")
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    tri = triangle_indices(topology, indices, len(vout.position))
    layout = vout.layout
    pos = vout.position[tri]                      # [T, 3, 4]
    var = vout.varyings[tri]                      # [T, 3, K]
    flat = _columns(layout, "flat")
    if len(flat):
        var[:, :, flat] = var[:, 2:3, flat]       # the provoking vertex's value on every corner
    ids = np.arange(len(tri), dtype=np.int64)
    dropped: Dict[str, np.ndarray] = {}

    finite = np.isfinite(pos).all(axis=(1, 2))
    dropped["non-finite"] = ids[~finite]

    planes = _planes(viewport)
    dist = pos @ planes[:, :4].T + planes[:, 4]   # [T, 3, planes]
    inside = dist >= 0
    accept = finite & inside.all(axis=(1, 2))
    reject = ~finite | (~inside).all(axis=1).any(axis=1)
    cut = ~accept & ~reject

    out_pos, out_var, out_key = [pos[accept]], [var[accept]], [ids[accept]]
    nopersp = _columns(layout, "noperspective")
    outside = list(ids[reject & finite])
    for t in ids[cut]:
        ppos, pvar = _clip_polygon(list(pos[t]), list(var[t]), planes, nopersp)
        if len(ppos) < 3:
            outside.append(t)
            continue
        for k in range(1, len(ppos) - 1):
            out_pos.append(np.stack([ppos[0], ppos[k], ppos[k + 1]])[None])
            out_var.append(np.stack([pvar[0], pvar[k], pvar[k + 1]])[None])
            out_key.append(np.array([t]))
    dropped["outside"] = np.array(sorted(outside), dtype=np.int64)

    key = np.concatenate(out_key)
    order = np.argsort(key, kind="stable")       # pieces stay where their triangle was
    key = key[order]
    cpos = np.concatenate(out_pos)[order]
    cvar = np.concatenate(out_var)[order]
    clipped = np.isin(key, ids[cut])

    w = cpos[:, :, 3]
    ndc = cpos[:, :, :3] / w[:, :, None]
    window = viewport.apply(ndc.reshape(-1, 3)).reshape(-1, 3, 3)
    front = _front_facing(window, key, len(tri), front_face)

    keep = np.ones(len(key), dtype=bool)
    if cull == "back":
        keep = front
    elif cull == "front":
        keep = ~front
    dropped["culled"] = np.unique(key[~keep])
    return Primitives(window=window[keep], inv_w=(1.0 / w)[keep], varyings=cvar[keep], layout=layout,
                      primitive_id=key[keep], front_facing=front[keep], clipped=clipped[keep],
                      dropped=dropped, input_count=len(tri), culled_window=window[~keep])


def _front_facing(window: np.ndarray, key: np.ndarray, n_input: int, front_face: str) -> np.ndarray:
    """Facing from the signed window-space area of each input triangle (y up).

    A clipped triangle's pieces add up to its clipped polygon, so every piece
    gets the polygon's facing (a thin piece cannot flip on rounding).
    """
    x, y = window[:, :, 0], window[:, :, 1]
    area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    total = np.bincount(key, weights=area, minlength=n_input)[key] if len(key) else area
    ccw = total > 0
    return ccw if front_face == "ccw" else (total < 0)
