"""Pictures of every stage of a traced draw, and a labelled contact sheet.

Each picture is an [H, W, 3] uint8 array the size of the framebuffer:

``vertices``    every vertex with w > 0 at its window position: a 3×3 dot where its 8×8-pixel cell
                holds at most 4 pixels with a vertex (there dots stay apart), a single dim pixel in a
                denser cell;
                when any cell is dense, a zoomed inset (:func:`density_inset`) shows the densest place
                with dots
``primitives``  wireframe of the triangles that reach the rasterizer (white);
                pieces made by clipping (cyan) over the outline of the triangle
                they were cut from (orange); triangles culled for facing (red,
                drawn first, so the others show over them). A draw of lines shows
                each line as the pixels the pipeline gives it (its width too), a
                clipped one's cut-off segment under it (orange, width 1); a draw
                of points, the outline of each point's square (the pixels at its
                border); a draw in polygon mode ("line" or "point"), the triangles
                whose edges or corners it drew, as a draw of triangles would. When the triangles
                are small (their median area under 24 pixels: edges closer than ~5 pixels run
                together), a zoomed inset shows the wireframe where they are densest
``coverage``    each pixel colored by the primitive of the last fragment written there: of a triangle
                mesh, a few well-separated colors (:data:`PALETTE`) given by a greedy coloring of the
                triangles' adjacency, so two triangles sharing an edge, or whose pixels touch in
                the picture, do not have the same color (:func:`triangle_palette`; past 8 colors,
                which greedy coloring does not need on a mesh, they repeat); of lines and points, a color per id (:func:`id_colors`).
                Small triangles: the same zoomed inset as ``primitives`` (the pixels magnified)
``depth``       the depth buffer after the draw (near = white, cleared = black)
``overdraw``    how many times the pixel was covered: the samples the draw's fragments
                cover there ÷ the samples per pixel, as a heat map (black 0, blue 1,
                green 2, yellow 3, red 4, white 6 or more; in between, a mix). One
                triangle over a whole pixel is 1 with one sample or with ``rgss4``
                alike; at an edge it covers half of, 0.5 (and two triangles sharing the
                edge, 1)
``final``       the color buffer after the draw
``non-finite``  only when the framebuffer holds a NaN or infinite color: the final picture
                with those pixels magenta (a PNG would show them as 0, black)
``stencil``     only for a draw with the stencil test on: the stencil buffer (sample 0) after
                the draw, each value its own color (0 black; :func:`id_colors`)
``tests``       only when a fragment was stopped by the scissor, the stencil test or the
                sample mask: at each pixel, what the merger did with the last fragment there
                (:data:`TEST_COLORS`: written green, depth-failed red, stencil-failed orange,
                scissored blue, sample-masked purple, discarded gray)
``shadow map k``  when the draw's ``lighting`` uniform carries shadow maps, each map's
                depth as the light saw it (near dark, far light, no caster white;
                :mod:`softpipe.scenes.shadow_pass`), scaled to the framebuffer's height; named
                ``shadow map k, light j`` or ``…, light j, face +x`` for a cube map
                (its file: ``07-shadow-map-k-light-j.png``)

:func:`stage_pictures` returns them with a caption each (``.captions``: what the picture shows, and
its inset), which :func:`contact_sheet` writes under each picture's name when given them (the sheet
that ``save_stage_pictures``, ``softpipe render --stages`` and a trace in Jupyter show).

The outlines (and a line's or a point's pixels) are drawn with the pipeline's own lines (``softpipe.draw`` with
topology "lines", GL's diamond-exit rule), as a wireframe over a rendered image is
(:func:`softpipe.scenes.drawing.draw_wireframe`).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, Optional

import numpy as np

from softpipe.pipeline.output import VERDICTS

__all__ = ["stage_pictures", "shadow_map_pictures", "contact_sheet", "save_stage_pictures", "overdraw", "PICTURES",
           "HEAT_STOPS", "OVERDRAW_DEFINITION", "draw_triangle_outlines", "draw_primitive_outlines", "OUTLINE_LAYERS",
           "draw_outline_layer", "draw_window_segments", "cut_outlines", "id_colors", "heat_colors",
           "WHITE", "CYAN", "ORANGE", "RED", "YELLOW", "MAGENTA", "non_finite_pixels", "TEST_COLORS",
           "merger_tests", "PALETTE", "triangle_palette", "greedy_coloring", "triangle_adjacency", "density_inset",
           "StagePictures", "CAPTIONS", "SPARSE_CELL", "SPARSE_MAX", "SMALL_TRIANGLE_AREA"]

PICTURES = ("vertices", "primitives", "coverage", "depth", "overdraw", "final")

WHITE = (235, 235, 235)
CYAN = (60, 200, 230)
ORANGE = (250, 150, 40)
RED = (230, 50, 50)
YELLOW = (250, 230, 80)
MAGENTA = (255, 0, 255)
#: The ``tests`` picture's color for each of the merger's verdicts (VERDICTS order).
TEST_COLORS = {"written": (70, 200, 90), "depth-failed": RED, "discarded": (120, 120, 120),
               "scissored": (70, 110, 240), "stencil-failed": ORANGE, "sample-masked": (170, 80, 220)}


def _to_image_xy(window_xy: np.ndarray, height: int) -> np.ndarray:
    """Window (y up) → image (row 0 at the top) continuous coordinates."""
    out = np.array(window_xy, dtype=np.float64)
    out[..., 1] = height - out[..., 1]
    return out


def draw_triangle_outlines(img, window_tris: np.ndarray, height: int, color) -> None:
    """Draw the outline of each window-space triangle [n, 3, ≥2] into the RGB image ``img`` (``height``
    rows): its three edges as the pipeline's own lines (GL's diamond-exit rule,
    :mod:`softpipe.pipeline.lines`), so the picture shows the pixels a GL line would."""
    if len(window_tris) == 0:
        return
    corners = np.asarray(window_tris, dtype=np.float64)[:, :, :2]
    draw_window_segments(img, corners.reshape(-1, 2), np.roll(corners, -1, axis=1).reshape(-1, 2), color)


def draw_primitive_outlines(img: np.ndarray, window: np.ndarray, kind: str, size, color) -> None:
    """Draw window-space primitives [n, 3, ≥2] of ``kind`` ("triangles" | "lines" | "points",
    :data:`softpipe.pipeline.assembly.KINDS`) into the RGB image ``img``: a triangle's three edges
    (:func:`draw_triangle_outlines`); a line (a, b, b) as the pixels the rasterizer gives it at its
    width ``size[k]`` (GL's diamond-exit rule, wide lines' runs); a point as the border pixels of its
    square of side ``size[k]`` (all of them, for a square of one or two pixels across)."""
    h, w = img.shape[:2]
    if kind == "triangles":
        draw_triangle_outlines(img, window, h, color)
        return
    if len(window) == 0:
        return
    from softpipe.language.contract import VaryingLayout
    from softpipe.pipeline.assembly import Primitives
    from softpipe.pipeline.raster import rasterize
    n = len(window)
    corners = np.zeros((n, 3, 3))
    corners[:, :, :2] = np.asarray(window, dtype=np.float64)[:, :, :2]
    ok = np.isfinite(corners).all(axis=(1, 2))
    n = int(ok.sum())
    prims = Primitives(window=corners[ok], inv_w=np.ones((n, 3)), varyings=np.zeros((n, 3, 0)),
                       layout=VaryingLayout(), primitive_id=np.arange(n, dtype=np.int64),
                       front_facing=np.ones(n, bool), clipped=np.zeros(n, bool), input_count=n, kind=kind,
                       size=np.broadcast_to(np.asarray(size, dtype=np.float64), (len(window),))[ok].copy())
    f = rasterize(prims, w, h)
    keep = np.ones(len(f), bool)
    if kind == "points" and len(f):            # a square's border: its first or last column or row
        t = f.triangle.astype(np.int64)
        lo_x, hi_x = np.full(n, 1 << 30), np.full(n, -1)
        lo_y, hi_y = np.full(n, 1 << 30), np.full(n, -1)
        np.minimum.at(lo_x, t, f.x)
        np.maximum.at(hi_x, t, f.x)
        np.minimum.at(lo_y, t, f.y)
        np.maximum.at(hi_y, t, f.y)
        keep = (f.x == lo_x[t]) | (f.x == hi_x[t]) | (f.y == lo_y[t]) | (f.y == hi_y[t])
    img[f.y[keep], f.x[keep]] = color


def draw_window_segments(img: np.ndarray, a: np.ndarray, b: np.ndarray, color) -> None:
    """Draw the segments a[k]→b[k] (window coordinates, y up, [K, 2]) into the RGB image ``img``: the
    pixels the pipeline's lines cover (assembly and the rasterizer, topology "lines"); segments with
    a non-finite end are left out."""
    from softpipe.pipeline.assembly import assemble
    from softpipe.pipeline.raster import rasterize
    from softpipe.pipeline.transforms import Viewport
    from softpipe.pipeline.vertex import run_vertex_stage

    h, w = img.shape[:2]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    if not ok.any():
        return
    ends = np.stack([a[ok], b[ok]], axis=1).reshape(-1, 2)
    clip = np.zeros((len(ends), 4))
    clip[:, 0], clip[:, 1], clip[:, 3] = 2.0 * ends[:, 0] / w - 1.0, 2.0 * ends[:, 1] / h - 1.0, 1.0
    lines = assemble(run_vertex_stage(clip), "lines", viewport=Viewport(0, 0, w, h))
    frags = rasterize(lines, w, h)
    img[frags.y, frags.x] = color


def id_colors(ids: np.ndarray) -> np.ndarray:
    """A stable, well-spread color per integer id (golden-ratio hues)."""
    hue = (ids.astype(np.float64) * 0.6180339887498949) % 1.0
    k = (np.array([5.0, 3.0, 1.0])[None, :] + hue[:, None] * 6.0) % 6.0
    rgb = 1.0 - np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0) * 0.75
    return (rgb * 255).astype(np.uint8)


#: The coverage picture's colors for a triangle mesh: well apart in hue and lightness, none near black
#: (the cleared background) or white. A greedy coloring of triangles that share at most 3 edges each
#: needs at most 4; the rest are there for non-manifold edges and fans.
PALETTE = np.array([[230, 85, 75], [70, 150, 235], [110, 200, 80], [245, 205, 60], [175, 105, 225],
                    [50, 205, 195], [245, 140, 45], [225, 120, 180]], dtype=np.uint8)


class StagePictures(dict):
    """name → [H, W, 3] uint8 picture, in order, with ``captions``: name → what the picture shows."""

    captions: Dict[str, str]

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.captions = {}


#: Each stage picture's caption on a contact sheet (a dense mesh's inset adds to some).
CAPTIONS = {
    "vertices": "each vertex with w > 0: a dot",
    "primitives": "edges: white drawn, red culled, cyan clipping's piece, orange cut",
    "coverage": "the triangle that won each pixel; touching triangles differ in color",
    "depth": "depth after the draw: near white, far gray, cleared black",
    "overdraw": "fragments per pixel (the key below)",
    "final": "the color buffer after the draw",
    "non-finite": "NaN or infinite pixels in magenta",
    "stencil": "stencil value per pixel (0 black)",
    "tests": "what the merger did with each pixel's last fragment",
}

#: The vertices picture's density rule: a vertex is a 3×3 dot when its SPARSE_CELL × SPARSE_CELL cell
#: of pixels holds at most SPARSE_MAX pixels with a vertex; else a single dim pixel, and an inset shows the place.
SPARSE_CELL = 8
SPARSE_MAX = 4
#: Triangles whose median window area (in pixels) is under this read as a blob drawn as outlines:
#: the primitives and coverage pictures then get a zoomed inset.
SMALL_TRIANGLE_AREA = 24.0
DIM_YELLOW = (150, 135, 50)
INSET_FRAME = (160, 160, 170)


def triangle_adjacency(triangles: np.ndarray) -> np.ndarray:
    """The pairs (a, b), a < b, of triangles (rows of vertex ids [n, 3]) that share an edge (two vertex
    ids), int64 [m, 2], sorted and unique; a degenerate triangle's collapsed edge is no edge."""
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = len(tri)
    if n == 0:
        return np.zeros((0, 2), np.int64)
    e = np.stack([tri, np.roll(tri, -1, axis=1)], axis=2).reshape(-1, 2)        # [3n, 2]
    owner = np.repeat(np.arange(n), 3)
    ok = e[:, 0] != e[:, 1]
    e, owner = np.sort(e[ok], axis=1), owner[ok]
    order = np.lexsort((owner, e[:, 1], e[:, 0]))
    e, owner = e[order], owner[order]
    same = (e[1:] == e[:-1]).all(axis=1)
    starts = np.flatnonzero(np.concatenate([[True], ~same]))
    sizes = np.diff(np.append(starts, len(e)))
    pairs = []
    for k in range(2, int(sizes.max()) + 1 if len(sizes) else 0):   # the edges shared by k triangles, together:
        first = starts[sizes == k]                                  # every pair of each edge's k owners
        i, j = np.triu_indices(k, 1)
        pairs.append(np.stack([owner[first[:, None] + i].ravel(), owner[first[:, None] + j].ravel()], axis=1))
    if not pairs:
        return np.zeros((0, 2), np.int64)
    out = np.concatenate(pairs)
    out = np.sort(out[out[:, 0] != out[:, 1]], axis=1)
    return np.unique(out, axis=0)


def greedy_coloring(n: int, pairs: np.ndarray) -> np.ndarray:
    """int64 [n]: for nodes 0 … n−1 in order, the smallest color no earlier neighbour (``pairs`` [m, 2]) has.

    Nodes with at most d neighbours get colors 0 … d (a triangle mesh's: at most 3 edge
    neighbours, so 0 … 3)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.argsort(both[:, 0], kind="stable")]
    start = np.searchsorted(both[:, 0], np.arange(n + 1))
    nb = both[:, 1].tolist()
    color = [0] * n
    for i in range(n):
        used = {color[j] for j in nb[start[i]:start[i + 1]] if j < i}
        c = 0
        while c in used:
            c += 1
        color[i] = c
    return np.array(color, dtype=np.int64)


def triangle_palette(trace, shown: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
    """uint8 [P, 3]: the coverage color of each input triangle of a draw of triangles (its primitive
    id), from :data:`PALETTE` by :func:`greedy_coloring` of the triangles that share an edge (the
    vertices joined by their given positions: a mesh split at a seam of normals or texture
    coordinates is still one surface) and, given ``shown`` (int [H, W], the primitive id that won
    each pixel, −1 for none), of those whose pixels touch in the picture (a triangle over another).
    None for a draw of lines or points."""
    from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES, primitive_indices
    call = trace.call
    if call.topology not in TRIANGLE_TOPOLOGIES:
        return None
    given = np.asarray(call.positions, dtype=np.float64)
    given = given.reshape(len(given), -1)
    tri = primitive_indices(call.topology, call.indices, len(given))
    _, weld = np.unique(given, axis=0, return_inverse=True)
    pairs = [triangle_adjacency(weld.reshape(-1)[tri])]
    if shown is not None:
        for a, b in ((shown[:, :-1], shown[:, 1:]), (shown[:-1], shown[1:])):
            touch = (a >= 0) & (b >= 0) & (a != b) & (a < len(tri)) & (b < len(tri))
            pairs.append(np.sort(np.stack([a[touch], b[touch]], axis=1), axis=1))
    both = np.unique(np.concatenate(pairs).astype(np.int64).reshape(-1, 2), axis=0)
    colors = greedy_coloring(len(tri), both)
    return PALETTE[colors % len(PALETTE)]


def _window_vertices(trace) -> np.ndarray:
    """Window xy [N, 2] (y up) of the vertices with w > 0."""
    pos = trace.vertex.position
    vis = pos[:, 3] > 0
    if not vis.any():
        return np.zeros((0, 2))
    ndc = pos[vis, :3] / pos[vis, 3:4]
    return trace.call.viewport.apply(ndc)[:, :2]


def density_inset(points_xy: np.ndarray, height: int, width: int, zoom_of) -> Optional[tuple]:
    """Where a zoomed inset goes: (zoom z, source square (x0, y0, side) in image pixels, target corner
    (x0, y0, side)), or None when the picture has no room for one (under 48 pixels across).

    ``points_xy`` (image coordinates) are counted in SPARSE_CELL cells; the source square is
    centred on the fullest cell; ``zoom_of(count)`` gives z (a power of two, 2 … 8) from the fullest
    cell's count. The inset is half the picture's smaller side, in the corner with the fewest points."""
    side = min(height, width) // 2
    if side < 24 or len(points_xy) == 0:
        return None
    cells = np.floor(points_xy / SPARSE_CELL).astype(np.int64)
    key = cells[:, 1] * (width // SPARSE_CELL + 2) + cells[:, 0]
    uniq, counts = np.unique(key, return_counts=True)
    best = int(np.argmax(counts))                     # the first of the fullest cells: deterministic
    cy, cx = divmod(int(uniq[best]), width // SPARSE_CELL + 2)
    z = int(zoom_of(int(counts[best])))
    src = max(side // z, 1)
    sx = int(np.clip((cx + 0.5) * SPARSE_CELL - src / 2, 0, max(width - src, 0)))
    sy = int(np.clip((cy + 0.5) * SPARSE_CELL - src / 2, 0, max(height - src, 0)))
    corners = [(width - side, 0), (0, 0), (width - side, height - side), (0, height - side)]
    fill = [int(((points_xy[:, 0] >= x) & (points_xy[:, 0] < x + side) & (points_xy[:, 1] >= y)
                 & (points_xy[:, 1] < y + side)).sum()) for x, y in corners]
    tx, ty = corners[int(np.argmin(fill))]            # the first of the emptiest: top right, if it ties
    return z, (sx, sy, src), (tx, ty, side)


def _zoom_for(count: int, limit: float) -> int:
    """The smallest of 2, 4, 8 that spreads ``count`` points of a cell to at most ``limit`` per cell."""
    return next((z for z in (2, 4, 8) if count / (z * z) <= limit), 8)


def _frame(img: np.ndarray, x0: int, y0: int, side_w: int, side_h: int, color) -> None:
    """A one-pixel rectangle outline, clipped to the image."""
    h, w = img.shape[:2]
    x1, y1 = min(x0 + side_w - 1, w - 1), min(y0 + side_h - 1, h - 1)
    x0, y0 = max(x0, 0), max(y0, 0)
    img[y0, x0:x1 + 1] = img[y1, x0:x1 + 1] = color
    img[y0:y1 + 1, x0] = img[y0:y1 + 1, x1] = color


def _paste_inset(img: np.ndarray, inset: np.ndarray, place: tuple) -> None:
    """``inset`` (side × side) into ``img`` at the target corner, framed; the source square framed too."""
    z, (sx, sy, src), (tx, ty, side) = place
    _frame(img, sx, sy, src, src, INSET_FRAME)
    img[ty:ty + side, tx:tx + side] = inset
    _frame(img, tx, ty, side, side, INSET_FRAME)


def _dots(img: np.ndarray, p: np.ndarray, color) -> None:
    """3×3 dots centred on the integer pixels p [N, 2] (x, row), clipped to the image."""
    h, w = img.shape[:2]
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            x, y = p[:, 0] + dx, p[:, 1] + dy
            ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            img[y[ok], x[ok]] = color


def _vertices_picture(trace, h: int, w: int) -> tuple:
    """The vertices picture (the density rule of the module docstring) and its caption."""
    img = np.zeros((h, w, 3), np.uint8)
    xy = _to_image_xy(_window_vertices(trace), h)
    p = np.floor(xy).astype(np.int64)
    if len(p) == 0:
        return img, CAPTIONS["vertices"]
    cols = w // SPARSE_CELL + 2
    # counted by the pixels that hold a vertex: a mesh split at its edges (a cube's 3 records per
    # corner) has one dot per corner, not three
    spots = np.unique(p, axis=0)
    key = np.floor_divide(spots[:, 1], SPARSE_CELL) * cols + np.floor_divide(spots[:, 0], SPARSE_CELL)
    cells, counts = np.unique(key, return_counts=True)
    mine = np.floor_divide(p[:, 1], SPARSE_CELL) * cols + np.floor_divide(p[:, 0], SPARSE_CELL)
    sparse = counts[np.searchsorted(cells, mine)] <= SPARSE_MAX
    if sparse.all():
        _dots(img, p, YELLOW)
        return img, CAPTIONS["vertices"]
    dense = p[~sparse]
    ok = (dense[:, 0] >= 0) & (dense[:, 0] < w) & (dense[:, 1] >= 0) & (dense[:, 1] < h)
    img[dense[ok, 1], dense[ok, 0]] = DIM_YELLOW
    _dots(img, p[sparse], YELLOW)
    # (ASCII only: the sheet's default font has no ≤ or ×)
    caption = (f"a dot where <= {SPARSE_MAX} vertices per {SPARSE_CELL}x{SPARSE_CELL} px, "
               "a dim pixel where denser")
    # zoomed until the fullest cell's vertices are about one per cell: dots far apart
    place = density_inset(spots + 0.5, h, w, lambda c: _zoom_for(c, 1))
    if place is not None:
        z, (sx, sy, src), (tx, ty, side) = place
        inset = np.zeros((side, side, 3), np.uint8)
        _dots(inset, np.floor((xy - (sx, sy)) * z).astype(np.int64), YELLOW)
        _paste_inset(img, inset, place)
        caption += f"; inset: the boxed place x{z}"
    return img, caption


def _small_triangles(trace) -> Optional[tuple]:
    """(image-space centroids [n, 2], zoom) of the drawn triangles when their median window area is under
    SMALL_TRIANGLE_AREA pixels (a draw of triangles only), else None."""
    prims = _outlined(trace)
    if getattr(prims, "kind", "triangles") != "triangles" or len(prims.window) == 0:
        return None
    win = np.asarray(prims.window, dtype=np.float64)[:, :, :2]
    ok = np.isfinite(win).all(axis=(1, 2))
    if not ok.any():
        return None
    win = win[ok]
    a, b, c = win[:, 0], win[:, 1], win[:, 2]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    median = float(np.median(area))
    if median >= SMALL_TRIANGLE_AREA:
        return None
    zoom = next((z for z in (2, 4, 8) if median * z * z >= 4 * SMALL_TRIANGLE_AREA), 8)
    return _to_image_xy(win.mean(axis=1), trace.height), zoom


def _wireframe_inset(trace, place: tuple) -> np.ndarray:
    """The primitives picture's layers (culled, whole, clipped pieces) of the triangles in the source
    square, magnified ×z into the inset."""
    z, (sx, sy, src), (tx, ty, side) = place
    h = trace.height
    inset = np.zeros((side, side, 3), np.uint8)
    prims = _outlined(trace)
    # window (y up) → the inset's window: x' = (x − sx)·z, y' = side − (h − y − sy)·z
    def scaled(tris):
        t = np.asarray(tris, dtype=np.float64)[:, :, :2].copy()
        if len(t) == 0:
            return t
        t[:, :, 0] = (t[:, :, 0] - sx) * z
        t[:, :, 1] = side - (h - t[:, :, 1] - sy) * z
        near = ((t[:, :, 0].max(axis=1) >= -1) & (t[:, :, 0].min(axis=1) <= side + 1)
                & (t[:, :, 1].max(axis=1) >= -1) & (t[:, :, 1].min(axis=1) <= side + 1))
        return t[near]
    draw_triangle_outlines(inset, scaled(prims.culled_window), side, RED)
    draw_triangle_outlines(inset, scaled(prims.window[~prims.clipped]), side, WHITE)
    draw_triangle_outlines(inset, scaled(prims.window[prims.clipped]), side, CYAN)
    return inset


def _magnified_inset(img: np.ndarray, place: tuple) -> np.ndarray:
    """The source square of ``img``, each pixel z × z (nearest neighbour), cut to the inset's side."""
    z, (sx, sy, src), (tx, ty, side) = place
    rows = np.minimum(sy + np.arange(side) // z, img.shape[0] - 1)
    cols = np.minimum(sx + np.arange(side) // z, img.shape[1] - 1)
    return img[rows[:, None], cols[None, :]]


#: The overdraw picture's colors at 0, 1, 2, … 6 (and more) coverings of a pixel.
HEAT_STOPS = np.array([[0, 0, 0], [40, 60, 220], [40, 200, 80], [240, 220, 40], [230, 50, 40], [255, 140, 140],
                       [255, 255, 255]], dtype=np.float64)

#: What the overdraw picture counts, as its key on a contact sheet says it.
OVERDRAW_DEFINITION = "overdraw = covered samples / samples per pixel"


def heat_colors(counts: np.ndarray) -> np.ndarray:
    """Black → blue → green → yellow → red → white for 0, 1, 2, 3, 4, ≥ 6 (linear in between)."""
    stops = HEAT_STOPS
    c = np.clip(counts.astype(np.float64), 0, len(stops) - 1)
    lo = np.floor(c).astype(int)
    hi = np.minimum(lo + 1, len(stops) - 1)
    f = (c - lo)[..., None]
    return (stops[lo] * (1 - f) + stops[hi] * f).astype(np.uint8)


def stage_pictures(trace) -> StagePictures:
    """The pictures listed in the module docstring, for a :class:`~softpipe.pipeline.trace.Trace`, in a
    :class:`StagePictures` (a dict, with ``captions``: what each shows, for :func:`contact_sheet`)."""
    h, w = trace.height, trace.width
    f = trace.fragments
    fb = trace.call.framebuffer
    pics = StagePictures()
    captions = pics.captions

    pics["vertices"], captions["vertices"] = _vertices_picture(trace, h, w)

    small = _small_triangles(trace)
    place = None
    if small is not None:
        place = density_inset(small[0], h, w, lambda c: small[1])
    img = np.zeros((h, w, 3), np.uint8)
    for layer in OUTLINE_LAYERS:
        draw_outline_layer(img, trace, layer)
    captions["primitives"] = CAPTIONS["primitives"]
    if place is not None:
        _paste_inset(img, _wireframe_inset(trace, place), place)
        captions["primitives"] += f"; inset: the boxed place x{place[0]}"
    pics["primitives"] = img

    img = np.zeros((h, w, 3), np.uint8)
    written = trace.written()
    captions["coverage"] = CAPTIONS["coverage"]
    if written.any():                                  # fancy assignment: the last written fragment wins
        ids = f.primitive_id[written]
        shown = np.full((h, w), -1, np.int64)
        shown[f.y[written], f.x[written]] = ids             # the last written wins, as in the picture
        palette = triangle_palette(trace, shown)
        if palette is None:
            img[f.y[written], f.x[written]] = id_colors(ids)
            captions["coverage"] = "the primitive that won each pixel, a color per id"
        else:
            img[f.y[written], f.x[written]] = palette[ids % len(palette)]
    if place is not None:
        _paste_inset(img, _magnified_inset(img.copy(), place), place)
        captions["coverage"] += f"; inset x{place[0]}"
    pics["coverage"] = img

    depth = fb.depth
    g = np.where(depth < 1.0, 1.0 - depth, 0.0)
    if (depth < 1.0).any():                            # stretch the used range for contrast
        lo, hi = depth[depth < 1.0].min(), depth[depth < 1.0].max()
        g = np.where(depth < 1.0, 0.25 + 0.75 * (hi - depth) / max(hi - lo, 1e-12), 0.0)
    pics["depth"] = np.repeat((g * 255).astype(np.uint8)[..., None], 3, axis=2)

    pics["overdraw"] = heat_colors(overdraw(trace))

    pics["final"] = fb.to_uint8(alpha=False)
    bad = non_finite_pixels(fb)
    if bad.any():                                      # only then: a draw of finite colors has its usual sheet
        marked = pics["final"].copy()
        marked[bad] = MAGENTA
        pics["non-finite"] = marked
    if trace.call.state.stencil is not None:
        stencil = fb.stencil
        colors = id_colors(stencil.reshape(-1).astype(np.int64)).reshape(h, w, 3)
        pics["stencil"] = np.where(stencil[..., None] > 0, colors, 0).astype(np.uint8)
    verdicts = trace.verdicts
    if np.isin(verdicts, ("scissored", "stencil-failed", "sample-masked")).any():
        pics["tests"] = merger_tests(trace)
    pics.update(shadow_map_pictures(trace.call.uniforms, h, w))
    for name in pics:
        if name not in captions:
            captions[name] = CAPTIONS.get(name, "depth as the light saw it: near dark, far light, none white"
                                          if name.startswith("shadow map") else "")
    return pics


def merger_tests(trace) -> np.ndarray:
    """[H, W, 3] uint8: at each pixel, the verdict of the last fragment the merger saw there, colored by
    :data:`TEST_COLORS` (black: no fragment)."""
    img = np.zeros((trace.height, trace.width, 3), np.uint8)
    f = trace.fragments
    if len(f):
        palette = np.array([TEST_COLORS[v] for v in VERDICTS], np.uint8)
        img[f.y, f.x] = palette[trace.merged.verdict]     # fancy assignment: the last fragment wins
    return img


def non_finite_pixels(fb) -> np.ndarray:
    """bool [H, W]: the pixels with a sample whose color is NaN or infinite (what a PNG shows as 0, and a
    draw warns of: softpipe.NonFiniteColorWarning)."""
    return ~np.isfinite(fb.samples_color).all(axis=(0, 3))


def shadow_map_pictures(uniforms, height: int, width: int) -> Dict[str, np.ndarray]:
    """The shadow maps a draw's ``lighting`` uniform carries, each as a [height, width, 3] picture."""
    shadows = getattr(getattr(uniforms, "lighting", None), "shadows", None)
    if shadows is None or shadows.maps is None or not len(shadows.maps):     # None: shadows from rays only
        return {}
    from softpipe.light.shadowmap import CUBE_FACE_NAMES
    owner = {}
    for j, (first, count, _) in enumerate(shadows.light_maps):
        for k in range(first, first + count):
            owner[k] = f"light {j}" + (f", face {CUBE_FACE_NAMES[k - first]}" if count == 6 else "")
    pics = {}
    for k, (offset, w, h, _, _) in enumerate(shadows.maps):
        depth = shadows.depth[offset:offset + w * h].reshape(h, w)[::-1]      # window rows → image rows
        covered = depth < 1.0
        g = np.full(depth.shape, 255, np.uint8)
        if covered.any():
            lo, hi = depth[covered].min(), depth[covered].max()
            g[covered] = np.round(20 + 200 * (depth[covered] - lo) / max(hi - lo, 1e-12)).astype(np.uint8)
        side = min(height, width)                     # nearest-neighbour scaling into a square, centred
        rows = (np.arange(side) * h // side)
        cols = (np.arange(side) * w // side)
        img = np.full((height, width, 3), 24, np.uint8)
        x0, y0 = (width - side) // 2, (height - side) // 2
        img[y0:y0 + side, x0:x0 + side] = g[rows[:, None], cols[None, :], None]
        pics[f"shadow map {k}, {owner.get(k, 'no light')}"] = img
    return pics


def overdraw(trace) -> np.ndarray:
    """How many times each pixel was covered, float64 [H, W]: covered samples ÷ samples per pixel.

    Each fragment is one covered sample, so with one sample per pixel this is the
    number of fragments at the pixel. With multisampling (``rgss4``) a triangle that
    covers the whole pixel still counts 1 (not its 4 samples), one that covers 2 of
    its 4 samples counts 0.5, and the picture reads on the same key (0, 1, 2, …) as a
    single-sampled one. Depth-failed fragments count: it is the rasterizer's work.
    """
    counts = np.zeros((trace.height, trace.width), np.float64)
    f = trace.fragments
    if len(f):
        np.add.at(counts, (f.y, f.x), 1.0)
    return counts / max(int(getattr(trace.call.framebuffer, "samples", 1)), 1)


#: The primitives picture's layers, in the order they are drawn (each over the ones before).
OUTLINE_LAYERS = ("culled", "cut", "whole", "clipped")


def _outlined(trace):
    """The primitives the picture outlines: the draw's, or in polygon mode the triangles (faces)."""
    prims = trace.primitives
    faces = getattr(prims, "faces", None)
    return prims if faces is None else faces


def draw_outline_layer(img: np.ndarray, trace, layer: str) -> None:
    """Draw one of :data:`OUTLINE_LAYERS` of ``trace``'s primitives picture into ``img``: the triangles
    culled for facing (red), the input primitives clipping cut (orange), the primitives kept whole
    (white), the pieces clipping made (cyan); in polygon mode, of the triangles (the module docstring)."""
    prims = _outlined(trace)
    kind = getattr(prims, "kind", "triangles")
    if layer == "culled":                     # under the rest: the back of a closed mesh
        draw_triangle_outlines(img, prims.culled_window, img.shape[0], RED)
    elif layer == "cut":
        cut = cut_outlines(trace)
        if kind == "lines":                   # the segment as given, width 1, under its clipped piece
            draw_window_segments(img, cut[:, 0, :2], cut[:, 1, :2], ORANGE)
        else:
            draw_triangle_outlines(img, cut, img.shape[0], ORANGE)
    else:
        rows = prims.clipped if layer == "clipped" else ~prims.clipped
        size = getattr(prims, "size", None)
        size = np.ones(len(prims.window)) if size is None else np.asarray(size)
        draw_primitive_outlines(img, prims.window[rows], kind, size[rows], CYAN if layer == "clipped" else WHITE)


def cut_outlines(trace) -> np.ndarray:
    """Window coordinates of the input primitives that clipping cut, where all corners have w > 0: the
    triangles (in polygon mode, the triangles whose edges or corners were drawn), or the lines (a, b, b)."""
    prims = _outlined(trace)
    ids = np.unique(prims.primitive_id[prims.clipped])
    if len(ids) == 0:
        return np.zeros((0, 3, 3))
    from softpipe.pipeline.assembly import primitive_indices
    tri = primitive_indices(trace.call.topology, trace.call.indices, len(trace.vertex.position))[ids]
    pos = trace.vertex.position[tri]
    ok = (pos[:, :, 3] > 0).all(axis=1)
    pos = pos[ok]
    ndc = pos[:, :, :3] / pos[:, :, 3:4]
    return trace.call.viewport.apply(ndc.reshape(-1, 3)).reshape(-1, 3, 3)


def _wrap(draw, text: str, width: float) -> list:
    """``text`` broken at spaces into lines at most ``width`` pixels wide (a word longer stays whole)."""
    lines: list = []
    for word in text.split():
        if lines and draw.textlength(lines[-1] + " " + word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines


def contact_sheet(pictures: Dict[str, np.ndarray], columns: int = 3, label_height: int = 18,
                  background=(24, 24, 28), captions: Optional[Dict[str, str]] = None):
    """One labelled pillow Image with every picture, in order, ``columns`` per row.

    Each picture's label is its name; with ``captions`` (name → text, as a
    :class:`StagePictures`' ``captions``: ``contact_sheet(pics, captions=pics.captions)``), what
    the picture shows follows in gray, wrapped to the picture's width (the label rows
    grow to hold the longest). When one of the pictures is ``overdraw``, a row under
    them is its key: what it counts (:data:`OVERDRAW_DEFINITION`, when the sheet is wide
    enough) and the colors of 0, 1, … 6+.
    """
    from PIL import Image, ImageDraw
    names = list(pictures)
    h, w = next(iter(pictures.values())).shape[:2]
    rows = -(-len(names) // columns)
    gap = 4
    key = label_height if "overdraw" in pictures else 0
    wrapped: Dict[str, list] = {}
    if captions:
        measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        wrapped = {n: _wrap(measure, captions.get(n, ""), w - 4) for n in names}
        label_height += 11 * max(len(v) for v in wrapped.values())
    width, height = columns * (w + gap) + gap, rows * (h + label_height + gap) + gap
    sheet = Image.new("RGB", (width, height + key), background)
    draw = ImageDraw.Draw(sheet)
    for k, name in enumerate(names):
        r, c = divmod(k, columns)
        x0, y0 = gap + c * (w + gap), gap + r * (h + label_height + gap)
        draw.text((x0 + 2, y0 + 3), name, fill=(230, 230, 230))
        for i, line in enumerate(wrapped.get(name, ())):
            draw.text((x0 + 2, y0 + 15 + 11 * i), line, fill=(160, 160, 168))
        sheet.paste(Image.fromarray(pictures[name]), (x0, y0 + label_height))
    if key:
        _overdraw_key(draw, gap + 2, height, width - gap - 2, key)
    return sheet


def _overdraw_key(draw, x: int, y: int, right: int, height: int) -> None:
    """The overdraw picture's key in the row at y: its definition, then a swatch per count."""
    labels = [str(k) for k in range(len(HEAT_STOPS) - 1)] + [f"{len(HEAT_STOPS) - 1}+"]
    swatch = 16
    room = right - x - swatch * len(labels)
    text = next((t for t in (OVERDRAW_DEFINITION + ":", "overdraw:") if draw.textlength(t) + 6 <= room), "")
    draw.text((x, y + 2), text, fill=(230, 230, 230))
    x += int(draw.textlength(text)) + 6 if text else 0
    for k, label in enumerate(labels):
        color = tuple(int(c) for c in HEAT_STOPS[k])
        draw.rectangle([x, y + 1, x + swatch - 2, y + height - 4], fill=color)
        ink = (0, 0, 0) if sum(color) > 380 else (235, 235, 235)
        draw.text((x + 2, y + 2), label, fill=ink)
        x += swatch


def save_stage_pictures(trace, directory) -> Dict[str, Path]:
    """Write each stage picture as ``NN-name.png`` and ``contact-sheet.png`` into ``directory``.

    Each file is written whole or not at all (:func:`softpipe.core.files.atomic_write`).
    """
    from PIL import Image

    from softpipe.core.files import atomic_write
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    pics = stage_pictures(trace)
    paths = {}

    def save(image, path: Path) -> None:
        atomic_write(path, lambda f: image.save(f, format="PNG"))

    for k, (name, img) in enumerate(pics.items()):
        path = directory / f"{k + 1:02d}-{re.sub(r'[^A-Za-z0-9+-]+', '-', name).strip('-')}.png"
        save(Image.fromarray(img), path)
        paths[name] = path
    paths["contact-sheet"] = directory / "contact-sheet.png"
    save(contact_sheet(pics, captions=pics.captions), paths["contact-sheet"])
    return paths
