"""Small pictures made big enough to read: nearest-neighbour zoom, a pixel grid, coordinates on the axes.

A 16×12 framebuffer shown as it is is a dot on a notebook's page. :func:`zoomed` draws
every pixel as a ``scale``×``scale`` block (nearest neighbour: no blur, a pixel stays one
color), a one-pixel grid line between the blocks, and the pixels' coordinates along the
bottom (x) and the left (y, window coordinates: y = 0 is the bottom row, as in
``pixel_history`` and ``softpipe.testing``). The digits are drawn from a 3×5 bitmap font
kept here, so the picture is the same bytes with every pillow and on every machine.

The layout, exactly (what ``tests/test_lessons.py`` checks): with the grid on, the
picture part is ``(H·s + 1) × (W·s + 1)``; grid lines are its rows ``r·s`` and columns
``c·s`` (r = 0…H, c = 0…W) in :data:`GRID`; image pixel (row r, column c) fills the
``(s − 1)×(s − 1)`` block below and right of the crossing (r·s, c·s). Without the grid
(or when ``s < 4``, where a line would eat most of the block), the picture part is
``H·s × W·s`` of plain blocks. With axes, a margin of :data:`PAPER` on the left (y
labels) and at the bottom (x labels) surrounds the picture part; its top-left corner is
at ``(0, left_margin)``.

:func:`fits_as_is` is the rule the notebook display uses: a picture at least
:data:`SMALL` pixels on its longer side is shown as it is.

This module imports nothing of softpipe's, so the pipeline's Framebuffer may call it
(from its Jupyter display, at call time).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

__all__ = ["zoomed", "zoom_scale", "fits_as_is", "zoom_layout", "glyph", "png", "SMALL", "GRID", "PAPER", "INK", "GLYPH"]

#: A picture whose longer side is shorter than this shows zoomed in a notebook.
SMALL = 64
#: The grid lines' color, the margins' and the digits'.
GRID = (128, 128, 128)
PAPER = (255, 255, 255)
INK = (0, 0, 0)
#: Each digit glyph is 3 wide and 5 tall, drawn GLYPH times bigger, with one (scaled) column between digits.
GLYPH = 2
_FONT = {
    "0": ("111", "101", "101", "101", "111"),
    "1": ("010", "110", "010", "010", "111"),
    "2": ("111", "001", "111", "100", "111"),
    "3": ("111", "001", "111", "001", "111"),
    "4": ("101", "101", "111", "001", "001"),
    "5": ("111", "100", "111", "001", "111"),
    "6": ("111", "100", "111", "101", "111"),
    "7": ("111", "001", "010", "010", "010"),
    "8": ("111", "101", "111", "101", "111"),
    "9": ("111", "101", "111", "001", "111"),
}
_STEPS = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000)


def zoom_scale(width: int, height: int, target: int = 320) -> int:
    """The default zoom: the longer side near ``target`` picture pixels, at most 32 per pixel, at least 1."""
    return int(max(1, min(32, target // max(int(width), int(height), 1))))


def fits_as_is(width: int, height: int) -> bool:
    """True when a picture is big enough to show as it is (its longer side at least :data:`SMALL`)."""
    return max(int(width), int(height)) >= SMALL


def glyph(text: str) -> np.ndarray:
    """The bool bitmap of a row of digits, GLYPH times the 3×5 font (one scaled column between digits)."""
    cols = []
    for k, ch in enumerate(text):
        rows = _FONT[ch]
        bits = np.array([[c == "1" for c in row] for row in rows], dtype=bool)
        if k:
            cols.append(np.zeros((5, 1), bool))
        cols.append(bits)
    small = np.concatenate(cols, axis=1) if cols else np.zeros((5, 0), bool)
    return np.repeat(np.repeat(small, GLYPH, axis=0), GLYPH, axis=1)


def _as_rgb(image) -> np.ndarray:
    """[H, W, 3] uint8 from a Framebuffer (anything with ``to_uint8``), a bool mask (covered white on
    black), a gray [H, W] or an RGB(A) [H, W, 3|4] array (uint8 as it is; floats in [0, 1], clipped)."""
    if hasattr(image, "to_uint8") and not isinstance(image, np.ndarray):
        return np.asarray(image.to_uint8(False))[..., :3]
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"zoomed: image must be [H, W], [H, W, 3] or [H, W, 4] with H, W ≥ 1, "
                         f"got an array of shape {a.shape}")
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    elif a.dtype != np.uint8:
        if not np.issubdtype(a.dtype, np.number):
            raise ValueError(f"zoomed: image must hold numbers or bools, got dtype {a.dtype}")
        f = np.nan_to_num(a.astype(np.float64), nan=0.0)
        a = np.rint(np.clip(f, 0.0, 1.0) * 255.0).astype(np.uint8)
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    return np.ascontiguousarray(a[:, :, :3])


def _label_step(count: int, scale: int, widest: int) -> int:
    """Label every ``step`` pixels: the smallest step whose labels (``widest`` picture pixels) do not touch."""
    for step in _STEPS:
        if step * scale >= widest + GLYPH * 2:
            return step
    return max(count, 1)


def zoom_layout(width: int, height: int, scale: int, grid: bool = True, axes: bool = True) -> Tuple[int, int, int, bool]:
    """(left margin, bottom margin, the picture part's size per pixel, grid drawn) of :func:`zoomed`."""
    grid = bool(grid) and scale >= 4
    left = (len(str(max(height - 1, 0))) * 4 * GLYPH - GLYPH + 3 * GLYPH) if axes else 0
    bottom = (5 * GLYPH + 3 * GLYPH) if axes else 0
    return left, bottom, scale, grid


def zoomed(image, scale: Optional[int] = None, *, grid: bool = True, axes: bool = True) -> np.ndarray:
    """A picture to read pixel by pixel: nearest-neighbour zoom, a pixel grid, coordinates on the axes.

    Parameters
    ----------
    image : Framebuffer, or array [H, W] | [H, W, 3] | [H, W, 4]
        Bool (True white, False black), uint8, or floats in [0, 1] (clipped). Row 0 is the
        top of the picture (an image, as ``Framebuffer.to_uint8`` gives it).
    scale : int, optional
        Picture pixels per image pixel; by default :func:`zoom_scale` (the longer side near 320).
    grid : bool
        A line of :data:`GRID` between the pixels (drawn only where ``scale`` ≥ 4).
    axes : bool
        The pixels' coordinates: x under the columns, y (window coordinates, 0 at the
        bottom row) left of the rows; every pixel, or every 2nd, 5th, 10th… where the
        digits would touch.

    Returns
    -------
    uint8 [H', W', 3]
        The module docstring gives the layout exactly.
    """
    rgb = _as_rgb(image)
    h, w = rgb.shape[:2]
    if scale is None:
        scale = zoom_scale(w, h)
    if isinstance(scale, bool) or not isinstance(scale, (int, np.integer)) or not 1 <= scale <= 256:
        raise ValueError(f"zoomed: scale must be a whole number of picture pixels per pixel in [1, 256], got {scale!r}")
    s = int(scale)
    left, bottom, _, grid = zoom_layout(w, h, s, grid, axes)
    if grid:
        ph, pw = h * s + 1, w * s + 1
        part = np.empty((ph, pw, 3), np.uint8)
        part[:] = GRID
        block = np.repeat(np.repeat(rgb, s, axis=0), s, axis=1).reshape(h, s, w, s, 3)
        part[:-1, :-1].reshape(h, s, w, s, 3)[:, 1:, :, 1:] = block[:, 1:, :, 1:]
    else:
        ph, pw = h * s, w * s
        part = np.repeat(np.repeat(rgb, s, axis=0), s, axis=1)
    if not axes:
        return np.ascontiguousarray(part)
    out = np.empty((ph + bottom, pw + left, 3), np.uint8)
    out[:] = PAPER
    out[:ph, left:] = part
    off = 1 if grid else 0                      # a block's first picture pixel after its grid line
    inner = s - off
    widest_x = len(str(w - 1)) * 4 * GLYPH - GLYPH
    for x in range(0, w, _label_step(w, s, widest_x)):
        g = glyph(str(x))
        cx = left + x * s + off + inner // 2            # the column's centre
        x0 = min(max(cx - g.shape[1] // 2, left), out.shape[1] - g.shape[1])
        y0 = ph + 2 * GLYPH
        out[y0:y0 + g.shape[0], x0:x0 + g.shape[1]][g] = INK
    for y in range(0, h, _label_step(h, s, 5 * GLYPH)):
        g = glyph(str(y))
        row = h - 1 - y                                  # window y up: y = 0 is the bottom row
        cy = row * s + off + inner // 2
        y0 = min(max(cy - g.shape[0] // 2, 0), ph - g.shape[0]) if ph >= g.shape[0] else 0
        x0 = left - 2 * GLYPH - g.shape[1]
        region = out[y0:y0 + g.shape[0], x0:x0 + g.shape[1]]
        region[g[:region.shape[0], :region.shape[1]]] = INK
    return out


def png(image) -> bytes:
    """PNG bytes of an [H, W, 3] uint8 picture (for a notebook's display)."""
    import io

    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image), "RGB").save(buf, format="PNG")
    return buf.getvalue()
