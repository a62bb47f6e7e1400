"""Pixels as ASCII pictures, and back: expectations written as pictures in a test's source.

A picture has one line per image row, **top row first** (row 0 of an array, of
a Framebuffer, of a PNG), one character per pixel. ``#`` is a covered pixel
(True) and ``.`` an empty one (False); integer arrays (primitive ids, counts)
are drawn with ``.`` for −1, ``0``–``9`` and ``a``–``z`` for 0…35; images and
other values through a legend ``{character: value}``.

:func:`as_pixels` is how every function of softpipe.testing takes pixels: a
Framebuffer (its 8-bit RGB picture), a Coverage (its mask), an array, a pillow
Image, an image file, or an ASCII picture (a str with line breaks); and, where
there is an image to give it a size, a set of (x, y) pixels (a set, or a list of
pairs) in window coordinates, y up, as ``covered_pixels`` gives them.
"""
from __future__ import annotations

import os
import string
import textwrap
from pathlib import Path
from typing import Mapping, Optional

import numpy as np

__all__ = ["ascii_picture", "from_ascii", "as_pixels", "DIGITS", "pixel_set", "pixels_mask", "PIXELS_ORIENTATION"]

#: The characters of integer pictures: value k is DIGITS[k] (0…35); −1 (no primitive) is ".".
DIGITS = string.digits + string.ascii_lowercase


def ascii_picture(image, legend: Optional[Mapping[str, object]] = None) -> str:
    """An array, Coverage, Framebuffer or image file as an ASCII picture (top row first).

    - bool [H, W] (a mask, a :class:`~softpipe.testing.Coverage`): ``#`` True, ``.`` False;
    - integers [H, W]: ``.`` for −1 and below, ``0``–``9``, ``a``–``z`` for 0…35;
    - with ``legend`` ({character: value}, as :func:`from_ascii` takes it), any
      array or image: each pixel's character is the one whose value it equals
      (all channels), ``?`` where none does;
    - an image ([H, W, C], a Framebuffer, a file) without a legend: ``.`` where the
      pixel is black (every color channel 0), ``#`` elsewhere.
    """
    a = as_pixels(image, "image")
    if legend is not None:
        return _with_legend(a, _check_legend(legend))
    if a.ndim == 3:
        if a.dtype == bool:
            raise ValueError(f"image must be [H, W] to draw; a mask with samples has shape {list(a.shape)}: "
                             "draw one sample (mask[:, :, s]) or mask.any(axis=2)")
        a = (a[:, :, :3] != 0).any(axis=2)
    if a.dtype == bool:
        return "\n".join("".join("#" if v else "." for v in row) for row in a)
    if np.issubdtype(a.dtype, np.integer):
        if a.size and a.max() >= len(DIGITS):
            raise ValueError(f"image holds the integer {int(a.max())}; an integer picture shows 0…{len(DIGITS) - 1} "
                             "(pass legend= for other values)")
        return "\n".join("".join(DIGITS[v] if v >= 0 else "." for v in row.tolist()) for row in a)
    raise ValueError(f"image of dtype {a.dtype} needs legend={{character: value}} to be drawn")


def _check_legend(legend) -> dict:
    if not isinstance(legend, Mapping) or not legend:
        raise TypeError(f"legend must be a non-empty dict {{character: value}}, got {legend!r}")
    for ch in legend:
        if not isinstance(ch, str) or len(ch) != 1 or ch.isspace():
            raise ValueError(f"legend keys must be single visible characters, got {ch!r}")
    return dict(legend)


def _with_legend(a: np.ndarray, legend: dict) -> str:
    rows = []
    for row in a:
        line = []
        for v in row:
            for ch, value in legend.items():
                if np.array_equal(np.asarray(v), np.asarray(value)):
                    line.append(ch)
                    break
            else:
                line.append("?")
        rows.append("".join(line))
    return "\n".join(rows)


def from_ascii(picture: str, legend: Optional[Mapping[str, object]] = None, dtype=None) -> np.ndarray:
    """An ASCII picture (top row first) back to an array: the inverse of :func:`ascii_picture`.

    The text may be indented and start or end with blank lines (a triple-quoted
    string in a test): it is dedented and trimmed. Without ``legend``, a picture
    of ``#`` and ``.`` is a bool mask [H, W]; one of digits, letters and ``.`` an
    int64 array (``.`` is −1). With ``legend`` ({character: value}), each
    character becomes its value: [H, W] for scalars, [H, W, C] for colors.
    """
    if not isinstance(picture, str):
        raise TypeError(f"picture must be a str, got {type(picture).__name__}")
    lines = [line.rstrip() for line in textwrap.dedent(picture).splitlines()]
    while lines and not lines[0]:
        lines.pop(0)
    while lines and not lines[-1]:
        lines.pop()
    if not lines:
        raise ValueError("picture is empty: it needs at least one row of characters")
    for k, line in enumerate(lines):
        if len(line) != len(lines[0]):
            raise ValueError(f"picture row {k} has {len(line)} characters and row 0 has {len(lines[0])}: "
                             "every row must be as long")
    chars = set("".join(lines))
    if legend is not None:
        legend = _check_legend(legend)
        missing = sorted(chars - set(legend))
        if missing:
            raise ValueError(f"picture uses {''.join(missing)!r}, which legend does not list")
        values = {ch: np.asarray(v) for ch, v in legend.items()}
        shapes = {v.shape for v in values.values()}
        if len(shapes) != 1:
            raise ValueError(f"legend values must all have one shape, got {sorted(map(list, shapes))}")
        out = np.array([[values[ch] for ch in line] for line in lines])
        return out if dtype is None else out.astype(dtype)
    if chars <= set("#."):
        out = np.array([[ch == "#" for ch in line] for line in lines], dtype=bool)
    elif chars <= set(DIGITS + "."):
        out = np.array([[DIGITS.index(ch) if ch != "." else -1 for ch in line] for line in lines], np.int64)
    else:
        raise ValueError(f"picture uses {''.join(sorted(chars))!r}: without legend= a picture is '#' and '.' "
                         "(a mask) or digits, letters and '.' (integers)")
    return out if dtype is None else out.astype(dtype)


# ------------------------------------------------- pixels in any form, as arrays

#: How a set of pixels is read, said in the messages about one.
PIXELS_ORIENTATION = ("(x, y) in window coordinates, y up, as covered_pixels gives them: pixel (x, y) is "
                      "column x, row height - 1 - y of the image (for y counted down from the top, pass "
                      "(x, height - 1 - y))")


def _is_pair(p) -> bool:
    return (isinstance(p, (tuple, list)) and len(p) == 2
            and all(isinstance(c, (int, np.integer)) and not isinstance(c, (bool, np.bool_)) for c in p))


def pixel_set(value, name: str) -> Optional[list]:
    """The (x, y) pairs of a set of pixels, or None for anything else.

    A set (or frozenset) is a set of pixels; so is a list or tuple whose items are
    all (x, y) pairs of integers, what a student's rasterizer returns. Such a list
    is never read as an image (a list of two pairs is not a 2×2 array): pass an
    image as a numpy array. The pairs are window coordinates, y up, as
    :func:`~softpipe.testing.coverage.covered_pixels` and ``positions`` have them
    (:data:`PIXELS_ORIENTATION`).
    """
    if isinstance(value, (set, frozenset)):
        items = list(value)
        for p in items:
            if not _is_pair(p):
                raise TypeError(f"{name} is a set of pixels, each an (x, y) pair of integers; it holds {p!r}")
        return items
    if isinstance(value, (list, tuple)) and value and all(_is_pair(p) for p in value):
        return list(value)
    return None


def pixels_mask(pixels: list, shape, name: str) -> np.ndarray:
    """The bool mask [H, W] (``shape``'s first two) of a set of (x, y) pixels, y up (window pixel (x, y) is
    ``mask[H - 1 - y, x]``); a pixel outside is named."""
    h, w = int(shape[0]), int(shape[1])
    mask = np.zeros((h, w), dtype=bool)
    for x, y in pixels:
        if not (0 <= x < w and 0 <= y < h):
            raise ValueError(f"{name} holds the pixel ({int(x)}, {int(y)}), outside the {w}×{h} image "
                             f"(x 0..{w - 1}, y 0..{h - 1}); pixels are {PIXELS_ORIENTATION}")
        mask[h - 1 - y, x] = True         # window y up → image row
    return mask


def as_pixels(value, name: str, shape=None) -> np.ndarray:
    """``value`` as an array [H, W] or [H, W, C] (C ≤ 4), or a one-line error naming ``name``.

    A set of (x, y) pixels (:func:`pixel_set`) becomes a bool mask of ``shape``
    ([H, W], the image it is compared with); without ``shape`` it is refused, as
    it says no size.
    """
    from softpipe.pipeline.framebuffer import Framebuffer
    from softpipe.testing.coverage import Coverage

    pixels = pixel_set(value, name)
    if pixels is not None:
        if shape is None:
            raise ValueError(f"{name} is a set of {len(pixels)} pixels, which says no image size: compare it "
                             "with an image or mask, or pass it as a bool mask [H, W]")
        return pixels_mask(pixels, shape, name)
    if isinstance(value, Framebuffer):
        return np.asarray(value)
    if isinstance(value, Coverage):
        return value.mask
    if isinstance(value, str) and "\n" in value:          # an ASCII picture, written in the test
        return from_ascii(value)
    if isinstance(value, (str, os.PathLike)):
        path = Path(value)
        if not path.is_file():
            raise FileNotFoundError(f"{name}: no image file at {str(path)!r}")
        value = _open_image(path, name)
    try:
        from PIL import Image
        if isinstance(value, Image.Image):
            value = _image_array(value)
    except ImportError:   # pragma: no cover - pillow is a dependency
        pass
    try:
        a = np.asarray(value)
    except Exception as e:
        raise TypeError(f"{name} must be an image (array, Framebuffer, file), got {type(value).__name__}: {e}") \
            from None
    if not (a.dtype == bool or np.issubdtype(a.dtype, np.number)):
        raise TypeError(f"{name} must hold numbers or booleans, got dtype {a.dtype}")
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    channels_ok = a.ndim == 3 and (2 <= a.shape[2] <= 4 or (a.dtype == bool and a.shape[2] >= 1))
    if not (a.ndim == 2 or channels_ok) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{name} must be an image [H, W] or [H, W, C] with C ≤ 4 (or a mask [H, W, samples]), "
                         f"got shape {list(a.shape)}")
    return a


def _open_image(path: Path, name: str):
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as im:
            im.load()
            return im
    except (UnidentifiedImageError, OSError) as e:
        raise ValueError(f"{name}: {str(path)!r} is not an image pillow can read ({e})") from None


def _image_array(im) -> np.ndarray:
    if im.mode == "P":
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
    elif im.mode == "1":
        im = im.convert("L")
    return np.asarray(im)
