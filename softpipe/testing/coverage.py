"""Which pixels (or samples) triangles, lines and points cover, under OpenGL's rules: :func:`coverage`.

Built on softpipe's own rasterizer (the triangle setup of :mod:`softpipe.pipeline.setup`,
the lines' of :mod:`softpipe.pipeline.lines`, the points' of :mod:`softpipe.pipeline.points`,
and :func:`softpipe.pipeline.raster.rasterize`), not a copy of it: what :func:`coverage` says is
what ``softpipe.draw`` draws. ``topology=`` takes the draw's names: a line list, strip or
loop is drawn by GL's diamond-exit rule (``line_width=`` for wide lines), points as squares
of ``point_size``; :func:`~softpipe.testing.reference_line` and
:func:`~softpipe.testing.reference_point` are the exact, independent references of the same rules.

Coordinates
-----------
``positions`` are **window coordinates in pixels, y up** (OpenGL's), by default:
x runs right from the image's left edge, y runs *up* from its bottom edge;
pixel (x, y) is the square [x, x+1] × [y, y+1], and its sample is its centre
(x + ½, y + ½). With ``space="clip"`` they are clip coordinates (x, y, z, w),
taken through softpipe's primitive assembly (clipping, divide, the viewport of
the whole image).

The arrays of the result are **images**: row 0 is the *top* row, as in a
Framebuffer, a PNG and :func:`~softpipe.testing.ascii_picture`, so window pixel
(x, y) is ``mask[height − 1 − y, x]``. :meth:`Coverage.pixels` and
:func:`covered_pixels` give (x, y) in window coordinates, y up, like ``positions``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from softpipe.language.contract import VaryingLayout
from softpipe.pipeline.assembly import (
    CULL_MODES,
    FRONT_FACES,
    GUARD_PIXELS,
    TOPOLOGIES,
    Primitives,
    assemble,
    primitive_indices,
    primitive_kind,
)
from softpipe.pipeline.assembly import check_size as check_primitive_size
from softpipe.pipeline.raster import rasterize
from softpipe.pipeline.sampling import CENTER, SamplePattern, pattern_named
from softpipe.pipeline.transforms import Viewport
from softpipe.pipeline.vertex import run_vertex_stage

__all__ = ["Coverage", "coverage", "covered_pixels", "SPACES", "MAX_COVERAGE_SAMPLES", "as_pattern", "check_size",
           "check_samples"]

#: What ``positions`` are: window coordinates in pixels (y up), or clip coordinates.
SPACES = ("window", "clip")


@dataclass
class Coverage:
    """Which pixels (samples) a set of triangles, lines or points covers.

    Attributes
    ----------
    mask : bool [H, W], or [H, W, S] with a sample pattern
        True where covered. Row 0 is the top of the image: window pixel (x, y) is
        ``mask[H − 1 − y, x]``.
    primitive_id : int64, the shape of ``mask``
        The input primitive covering each pixel (its index among the topology's
        triangles, lines or points), −1 where none does. Where several do, the last one
        in primitive order: the one a draw without depth test leaves on top.
    count : int64, the shape of ``mask``
        How many primitives cover each pixel (a closed mesh's interior is 1
        everywhere: shared edges are never drawn twice; a line strip's joints, likewise).
    pattern : SamplePattern or None
        The samples, when ``samples=`` was given.
    kind : "triangles" | "lines" | "points"
        What the primitives are (the topology's kind).
    """

    mask: np.ndarray
    primitive_id: np.ndarray
    count: np.ndarray
    pattern: Optional[SamplePattern] = None
    kind: str = "triangles"

    @property
    def width(self) -> int:
        return self.mask.shape[1]

    @property
    def height(self) -> int:
        return self.mask.shape[0]

    def pixels(self) -> List[Tuple[int, ...]]:
        """The covered pixels as a sorted list of (x, y), window coordinates (y up);
        (x, y, sample) with a sample pattern."""
        where = np.nonzero(self.mask)
        rows, cols = where[0], where[1]
        ys = self.height - 1 - rows
        if self.mask.ndim == 3:
            return sorted(zip(cols.tolist(), ys.tolist(), where[2].tolist()))
        return sorted(zip(cols.tolist(), ys.tolist()))

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        """``np.asarray(coverage)`` is the mask."""
        return self.mask if dtype is None else self.mask.astype(dtype)

    def __repr__(self) -> str:
        covered = int(self.mask.sum())
        ids = np.unique(self.primitive_id[self.primitive_id >= 0])
        unit = "samples" if self.mask.ndim == 3 else "pixels"
        return (f"Coverage({self.width}×{self.height}, {covered} {unit} covered by {len(ids)} "
                f"{self.kind[:-1]}{'s' if len(ids) != 1 else ''})")


def check_size(width, height) -> Tuple[int, int]:
    """``width`` and ``height`` as positive ints, or a one-line error naming the argument."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer number of pixels, got {value!r}")
        if not 1 <= value <= 1 << 15:
            raise ValueError(f"{name} must be in [1, 32768] pixels, got {value}")
    return int(width), int(height)


#: The most samples (width × height × samples per pixel) a coverage is computed for: 2^26 (1.1 GB of arrays).
MAX_COVERAGE_SAMPLES = 1 << 26


def check_samples(width: int, height: int, samples: int) -> None:
    if width * height * samples > MAX_COVERAGE_SAMPLES:
        raise ValueError(f"a coverage of {width}×{height} pixels × {samples} samples is more than "
                         f"MAX_COVERAGE_SAMPLES = 2^26 samples; test on a smaller image")


def as_pattern(samples) -> Optional[SamplePattern]:
    """``samples=``: None (pixel centres), a SamplePattern, a pattern name ("rgss4", "grid16", …)
    or a sequence of (x, y) positions in the pixel, in [0, 1), y up."""
    if samples is None or isinstance(samples, SamplePattern):
        return samples
    try:
        if isinstance(samples, str):
            return pattern_named(samples)
        pos = np.asarray(samples, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2:
            raise ValueError(f"must have shape [S, 2] (positions in the pixel), got {list(pos.shape)}")
        return SamplePattern(pos)
    except (TypeError, ValueError) as e:
        raise type(e)(f"samples: {e}") from None


def _positions(positions, space: str, corners: int = 3) -> np.ndarray:
    """``positions`` as float64 [N, k]: [N, k] as it is, [T, 3, k] (a triangle list's) or [L, 2, k] (a line
    list's, ``corners`` = 2) flattened to [3T, k] or [2L, k]."""
    ncols = (2, 3) if space == "window" else (4,)
    group = "T, 3" if corners == 3 else "L, 2"
    want = " or ".join(f"[N, {c}]" for c in ncols) + (f" or [{group}, " + "|".join(map(str, ncols)) + "]"
                                                      if corners else "")
    what = "window coordinates in pixels" if space == "window" else "clip coordinates"
    try:
        arr = np.asarray(positions)
    except Exception as e:
        raise TypeError(f"positions must be a numeric array, got {type(positions).__name__}: {e}") from None
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise TypeError(f"positions must be a numeric array ({what}), got dtype {arr.dtype}")
    if corners and arr.ndim == 3 and arr.shape[1] == corners and arr.shape[2] in ncols:
        arr = arr.reshape(-1, arr.shape[2])
    if arr.ndim != 2 or arr.shape[1] not in ncols:
        raise ValueError(f"positions must have shape {want} ({what}, space={space!r}), got {list(arr.shape)}")
    return np.ascontiguousarray(arr, dtype=np.float64)


def _window_primitives(pos: np.ndarray, tri: np.ndarray, width: int, height: int, cull: str,
                       front_face: str, kind: str = "triangles", size: float = 1.0) -> Primitives:
    """Window-coordinate primitives straight to the rasterizer's input (no clipping needed, so none done).

    ``tri`` holds each primitive's three corners (a line's (a, b, b), a point's (p, p, p)); a point
    whose centre lies outside the image is discarded, as a draw discards one outside the view volume
    (assembly's rule, GL 4.6 §13.7.1), and ``size`` is the lines' width or the points' size.
    """
    bad = ~np.isfinite(pos[:, :2]).all(axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        raise ValueError(f"positions must be finite; row {row} is {pos[row, :2].tolist()}")
    lo = np.array([-GUARD_PIXELS, -GUARD_PIXELS])
    hi = np.array([width + GUARD_PIXELS, height + GUARD_PIXELS])
    out = ((pos[:, :2] < lo) | (pos[:, :2] > hi)).any(axis=1)
    if out.any():
        row = int(np.argmax(out))
        raise ValueError(f"positions row {row} = {pos[row, :2].tolist()} lies more than {GUARD_PIXELS:g} pixels "
                         f"outside the {width}×{height} image (the rasterizer's guard band); pass clip "
                         "coordinates with space='clip' to have it clipped")
    corners = pos[tri]                                           # [T, 3, k]
    t = len(tri)
    window = np.empty((t, 3, 3))
    window[:, :, :2] = corners[:, :, :2]
    window[:, :, 2] = 0.5
    # facing from the window-space signed area, as primitive assembly decides it
    a, b, c = window[:, 0], window[:, 1], window[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    if kind == "triangles":
        front = area > 0 if front_face == "ccw" else area < 0
        keep = np.ones(t, bool) if cull == "none" else (~front if cull == "front" else front)
    else:                                                        # points and lines face the front (GL)
        front = np.ones(t, bool)
        centre = window[:, 0, :2]
        keep = np.ones(t, bool) if kind == "lines" else (
            (centre[:, 0] >= 0) & (centre[:, 0] <= width) & (centre[:, 1] >= 0) & (centre[:, 1] <= height))
    ids = np.nonzero(keep)[0].astype(np.int64)
    n = len(ids)
    return Primitives(window=window[ids], inv_w=np.ones((n, 3)), varyings=np.zeros((n, 3, 0)),
                      layout=VaryingLayout(), primitive_id=ids, front_facing=front[ids],
                      clipped=np.zeros(n, bool), input_count=t, kind=kind, size=np.full(n, size))


def primitives_for(positions, width: int, height: int, *, indices=None, cull: str = "none",
                   front_face: str = "ccw", space: str = "window", topology: str = "triangles",
                   line_width: float = 1.0, point_size: float = 1.0) -> Primitives:
    """The rasterizer's input for ``positions`` (arguments as :func:`coverage`), checked."""
    if space not in SPACES:
        raise ValueError(f"space must be one of {SPACES}, got {space!r}")
    if topology not in TOPOLOGIES:
        raise ValueError(f"topology must be one of {TOPOLOGIES}, got {topology!r}")
    kind = primitive_kind(topology)
    line_width = check_primitive_size("line_width", line_width)
    point_size = check_primitive_size("point_size", point_size)
    if cull not in CULL_MODES:
        raise ValueError(f"cull must be one of {CULL_MODES}, got {cull!r}")
    if front_face not in FRONT_FACES:
        raise ValueError(f"front_face must be one of {FRONT_FACES}, got {front_face!r}")
    # a list's primitives may come grouped: [T, 3, k] triangles, [L, 2, k] lines
    corners = {"triangles": 3, "lines": 2}.get(topology, 0)
    pos = _positions(positions, space, corners)
    if space == "clip":
        return assemble(run_vertex_stage(pos), topology, indices, viewport=Viewport(0, 0, width, height),
                        cull=cull, front_face=front_face, keep_culled=False, line_width=line_width,
                        point_size=point_size)
    tri = primitive_indices(topology, indices, len(pos))
    return _window_primitives(pos, tri, width, height, cull, front_face, kind,
                              line_width if kind == "lines" else point_size)


def coverage(positions, width: int, height: int, *, indices=None, samples=None, cull: str = "none",
             front_face: str = "ccw", space: str = "window", topology: str = "triangles",
             line_width: float = 1.0, point_size: float = 1.0) -> Coverage:
    """The exact pixels (or samples) triangles, lines or points cover under OpenGL's rules, as softpipe
    draws them.

    Parameters
    ----------
    positions : array [N, 2|3], or [T, 3, 2|3]
        Window coordinates in pixels, y up (OpenGL): pixel (x, y) is the square
        [x, x+1] × [y, y+1] with its sample at the centre (x + ½, y + ½); y = 0 is
        the bottom edge of the image. A z column is allowed and ignored. Without
        ``indices`` every three rows are a triangle (every two a line, with
        ``topology="lines"``: [L, 2, 2|3] too). With ``space="clip"``: clip
        coordinates [N, 4] (or [T, 3, 4]), clipped and mapped by the viewport of
        the whole image, as ``softpipe.draw`` does without a vertex shader.
    width, height : int
        The image, in pixels.
    indices : int array [M, 3] or [3M], optional
        The topology's vertices as indices into ``positions`` (as ``softpipe.draw`` takes them).
    samples : None, SamplePattern, pattern name ("rgss4", "grid4", …) or [S, 2] positions
        None: one sample per pixel at its centre. Otherwise the result has a
        sample axis: [H, W, S].
    cull : "none" | "back" | "front"
    front_face : "ccw" | "cw"
        Which winding (in window coordinates, y up) faces the viewer.
    space : "window" | "clip"
    topology : str
        ``softpipe.draw``'s: "triangles" (the default), "triangle_strip", "triangle_fan",
        "lines", "line_strip", "line_loop" or "points".
    line_width, point_size : float
        Pixels, as ``softpipe.draw`` takes them (clamped to [1, 255]): a line is drawn by GL's
        diamond-exit rule (the last pixel left out), ⌊w + ½⌋ fragments across when wide; a
        point is every pixel centre in the half-open square of side ``point_size`` around it,
        and one whose centre lies outside the image is discarded whole, as a draw does.
        On a sample pattern a line's or point's pixel covers all its samples.

    Returns
    -------
    Coverage
        ``.mask`` bool [H, W] (row 0 at the top), ``.primitive_id``, ``.count``;
        ``.pixels()`` the sorted (x, y) list (y up).
    """
    width, height = check_size(width, height)
    pattern = as_pattern(samples)
    prims = primitives_for(positions, width, height, indices=indices, cull=cull, front_face=front_face,
                           space=space, topology=topology, line_width=line_width, point_size=point_size)
    s = 1 if pattern is None else len(pattern)
    check_samples(width, height, s)
    frags = rasterize(prims, width, height, pattern or CENTER)
    count = np.zeros((height, width, s), np.int64)
    last = np.full((height, width, s), -1, np.int64)
    where = (frags.y, frags.x, frags.sample)
    np.add.at(count, where, 1)
    np.maximum.at(last, where, frags.triangle)          # the last triangle in primitive order
    ids = np.where(last >= 0, prims.primitive_id[np.maximum(last, 0)] if len(prims) else -1, -1)
    if pattern is None:
        count, ids = count[:, :, 0], ids[:, :, 0]
    return Coverage(mask=count > 0, primitive_id=ids, count=count, pattern=pattern, kind=prims.kind)


def covered_pixels(positions, width: int, height: int, **options) -> List[Tuple[int, ...]]:
    """The pixels :func:`coverage` covers, as a sorted list of (x, y) in window coordinates (y up),
    or of (x, y, sample) with ``samples=``: for hand-written expectations."""
    return coverage(positions, width, height, **options).pixels()
