"""The mesh view (RenderDoc's mesh viewer): a draw's vertices before and after the vertex shader.

For each vertex: its position as the draw was given it (object space; for a draw without a
vertex shader the positions are clip coordinates already, and the column says "given"), its
clip coordinates (the vertex shader's ``position``), and its window coordinates (x, y in
pixels with y up, z the depth in [0, 1]; none for a vertex with w ≤ 0, which only clipping
can place). :func:`mesh_table` gives them as rows that print as a table (an HTML table in
Jupyter), like :class:`~softpipe.pipeline.trace.PixelHistory`; with a pixel, the rows are the
corners of the triangle that won it.

:func:`mesh_pictures` draws the mesh twice: in window space (every input triangle with its
corners in front of the eye, as the edges the pipeline's lines give), and in object space
from a fixed orthographic view (looking down −z: x to the right, y up, the mesh's bounding
box fitted into the picture with a margin of 8 pixels). The triangle that won the chosen
pixel is outlined in yellow in both, and the pixel is marked magenta in the window-space one.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from softpipe.views.pictures import MAGENTA, YELLOW, draw_triangle_outlines

__all__ = ["MeshVertex", "MeshTable", "mesh_table", "mesh_pictures", "pixel_winner", "MESH_GRAY",
           "OBJECT_VIEW_MARGIN"]

#: The mesh's edges in the mesh pictures (the highlighted triangle is YELLOW).
MESH_GRAY = (110, 110, 120)
#: Pixels between the object-space picture's edge and the mesh's bounding box.
OBJECT_VIEW_MARGIN = 8


@dataclass
class MeshVertex:
    """One vertex in the three spaces (float64 tuples); ``window`` is () for a vertex with w ≤ 0."""

    index: int                  # the row of the vertex stage's output (instance i's vertex v: i·V + v)
    object: tuple               # as given to the draw (x, y, z[, w])
    clip: tuple                 # (x, y, z, w) the vertex shader output
    window: tuple               # (x, y, depth): the viewport transform of clip / w, when w > 0


class MeshTable(list):
    """:class:`MeshVertex` rows; prints as a table. ``triangle`` is (post-clip triangle, input primitive,
    instance) of the pixel's winner when the table was asked for a pixel, else None; ``object_space`` names
    the first column ("object", or "given (clip)" for a draw without a vertex shader)."""

    def __init__(self, rows: List[MeshVertex], object_space: str, pixel: Optional[Tuple[int, int]] = None,
                 triangle: Optional[Tuple[int, int, int]] = None):
        super().__init__(rows)
        self.object_space, self.pixel, self.triangle = object_space, pixel, triangle

    @staticmethod
    def _fmt(v: tuple) -> str:
        return "(" + ", ".join(f"{c:.6g}" for c in v) + ")" if v else "— (w ≤ 0)"

    def heading(self) -> str:
        if self.pixel is None:
            return f"{len(self)} vertex(es)"
        if self.triangle is None:
            return f"pixel {self.pixel}: no triangle was written there"
        tri, prim, inst = self.triangle
        return (f"pixel {self.pixel}: won by post-clip triangle {tri} (primitive {prim}"
                + (f", instance {inst}" if inst else "") + "); its corners")

    def table(self):
        """(column names, rows of cell strings): what ``str()`` and Jupyter show."""
        cols = ["vertex", self.object_space, "clip (x, y, z, w)", "window (x, y, depth)"]
        return cols, [[str(v.index), self._fmt(v.object), self._fmt(v.clip), self._fmt(v.window)] for v in self]

    def __str__(self) -> str:
        cols, rows = self.table()
        if not rows:
            return self.heading()
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(cols)]
        line = lambda r: "  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip()  # noqa: E731
        return "\n".join([self.heading(), line(cols), line(["-" * w for w in widths])] + [line(r) for r in rows])

    def _repr_pretty_(self, p, cycle):
        p.text(str(self))

    def _repr_html_(self) -> str:
        from html import escape
        cols, rows = self.table()
        out = ['<div class="softpipe-mesh-table">', f"<p>{escape(self.heading())}</p>"]
        if rows:
            out.append("<table><thead><tr>" + "".join(f"<th>{escape(c)}</th>" for c in cols) + "</tr></thead><tbody>")
            out += ["<tr>" + "".join(f"<td>{escape(c)}</td>" for c in r) + "</tr>" for r in rows]
            out.append("</tbody></table>")
        out.append("</div>")
        return "\n".join(out)


def _given(trace) -> np.ndarray:
    """The draw's positions as given, float64 [V, n] (n = 2 … 4)."""
    given = np.asarray(trace.call.positions, dtype=np.float64)
    return given.reshape(len(given), -1)


def _window(trace, clip: np.ndarray) -> np.ndarray:
    """Window (x, y, depth) [N, 3] of clip coordinates [N, 4]; NaN where w ≤ 0."""
    out = np.full((len(clip), 3), np.nan)
    ok = clip[:, 3] > 0
    if ok.any():
        out[ok] = trace.call.viewport.apply(clip[ok, :3] / clip[ok, 3:4])
    return out


def pixel_winner(trace, x: int, y: int) -> Optional[Tuple[int, int, int]]:
    """(post-clip triangle, input primitive id, instance) of the last fragment written at pixel (x, y)
    (image coordinates, row 0 at the top) — the fragment whose color the pixel shows — or None."""
    idx = trace.at(x, y)
    written = idx[trace.merged.verdict[idx] == 0]
    if len(written) == 0:
        return None
    k = int(written[-1])
    tri = int(trace.fragments.triangle[k])
    instance = trace.primitives.instance
    return tri, int(trace.fragments.primitive_id[k]), int(instance[tri]) if instance is not None else 0


def _corners(trace, primitive: int, instance: int) -> np.ndarray:
    """The vertex-stage rows [3] of an input primitive's corners (of one instance)."""
    from softpipe.pipeline.assembly import primitive_indices
    v = len(_given(trace))
    return primitive_indices(trace.call.topology, trace.call.indices, v)[primitive] + instance * v


def mesh_table(trace, pixel: Optional[Tuple[int, int]] = None,
               vertices: Optional[Sequence[int]] = None) -> MeshTable:
    """A draw's vertices in object, clip and window space (the module docstring).

    Parameters
    ----------
    trace : Trace
        A traced draw (``softpipe.draw(..., trace=True)``).
    pixel : (x, y), optional
        Image coordinates (row 0 at the top): the rows are the three corners of the triangle that
        won the pixel (:func:`pixel_winner`; none when nothing was written there).
    vertices : sequence of int, optional
        The vertex-stage rows to list; default every vertex (when no pixel is given).
    """
    clip_all = np.asarray(trace.vertex.position, dtype=np.float64)
    given = _given(trace)
    triangle = None
    if pixel is not None:
        x, y = (int(c) for c in pixel)
        triangle = pixel_winner(trace, x, y)
        rows = [] if triangle is None else [int(i) for i in _corners(trace, triangle[1], triangle[2])]
    elif vertices is None:
        rows = list(range(len(clip_all)))
    else:
        rows = [int(i) for i in vertices]
        bad = [i for i in rows if not 0 <= i < len(clip_all)]
        if bad:
            raise IndexError(f"mesh_table: vertex {bad[0]} is out of range for the draw's {len(clip_all)} vertices")
    idx = np.array(rows, dtype=np.int64)
    clip = clip_all[idx]
    win = _window(trace, clip)
    space = "object" if trace.call.vertex_shader is not None else "given (clip)"
    out = [MeshVertex(int(i), tuple(float(c) for c in given[i % len(given)]), tuple(float(c) for c in cl),
                      tuple(float(c) for c in wi) if np.isfinite(wi).all() else ())
           for i, cl, wi in zip(idx, clip, win)]
    return MeshTable(out, space, None if pixel is None else (int(pixel[0]), int(pixel[1])), triangle)


def _object_view(given: np.ndarray, height: int, width: int) -> np.ndarray:
    """Window xy [V, 2] (y up) of object positions in the fixed orthographic front view, fitted with a margin."""
    xy = given[:, :2] if given.shape[1] >= 2 else np.zeros((len(given), 2))
    finite = np.isfinite(xy).all(axis=1)
    out = np.full((len(xy), 2), np.nan)
    if not finite.any():
        return out
    lo, hi = xy[finite].min(axis=0), xy[finite].max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    m = OBJECT_VIEW_MARGIN
    scale = min((width - 2 * m) / span[0], (height - 2 * m) / span[1])
    centre = (lo + hi) / 2
    out[finite] = (xy[finite] - centre) * scale + (width / 2, height / 2)
    return out


def mesh_pictures(trace, pixel: Optional[Tuple[int, int]] = None) -> Dict[str, np.ndarray]:
    """The mesh in window space and in object space ([H, W, 3] uint8 each, the framebuffer's size), the
    triangle that won ``pixel`` (image coordinates) outlined in yellow (module docstring)."""
    from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES, primitive_indices
    h, w = trace.height, trace.width
    given = _given(trace)
    clip = np.asarray(trace.vertex.position, dtype=np.float64)
    win = _window(trace, clip)
    triangles = trace.call.topology in TRIANGLE_TOPOLOGIES
    tri = primitive_indices(trace.call.topology, trace.call.indices, len(given))
    instances = max(len(clip) // max(len(given), 1), 1)
    rows = np.concatenate([tri + k * len(given) for k in range(instances)]) if len(tri) else tri
    winner = pixel_winner(trace, *pixel) if pixel is not None else None
    hot = _corners(trace, winner[1], winner[2]) if winner is not None else None

    window_pic = np.zeros((h, w, 3), np.uint8)
    corners = win[rows] if len(rows) else np.zeros((0, 3, 3))
    ahead = np.isfinite(corners).all(axis=(1, 2))
    draw_triangle_outlines(window_pic, corners[ahead], h, MESH_GRAY)
    object_pic = np.zeros((h, w, 3), np.uint8)
    view = _object_view(given, h, w)
    flat = view[tri] if len(tri) else np.zeros((0, 3, 2))
    draw_triangle_outlines(object_pic, flat[np.isfinite(flat).all(axis=(1, 2))], h, MESH_GRAY)
    if hot is not None and triangles:
        if np.isfinite(win[hot]).all():
            draw_triangle_outlines(window_pic, win[hot][None], h, YELLOW)
        if np.isfinite(view[hot % len(given)]).all():
            draw_triangle_outlines(object_pic, view[hot % len(given)][None], h, YELLOW)
    if pixel is not None and 0 <= pixel[0] < w and 0 <= pixel[1] < h:
        window_pic[int(pixel[1]), int(pixel[0])] = MAGENTA
    return {"mesh, window space": window_pic, "mesh, object space (front, orthographic)": object_pic}
