"""Comparing pictures pixel by pixel: :func:`assert_pixels_equal` and golden images.

Anything with pixels is taken: a Framebuffer (its 8-bit RGB picture, what
``fb.save`` writes), a :class:`~softpipe.testing.Coverage` (its mask), a numpy
array [H, W] or [H, W, C], a pillow Image, the path of an image file, or a set
of (x, y) pixels (a set, or a list of pairs: what a student's rasterizer
returns) in window coordinates, y up, as ``covered_pixels`` gives them,
compared as a mask the size of the other side.
Coordinates in messages are x = column from the left, y = row from the top
(the array's own indices: ``a[y, x]``).
"""
from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Optional, Union

import numpy as np

from softpipe.testing.pictures import PIXELS_ORIENTATION, as_pixels, pixel_set

__all__ = ["assert_pixels_equal", "diff_image", "to_8bit", "check_golden", "MAP_COLUMNS", "MAP_ROWS"]

#: The ASCII map of a failure shows at most this much of the differing region.
MAP_COLUMNS, MAP_ROWS = 64, 32
#: Pixels of context drawn around the differences.
MAP_MARGIN = 1


# ----------------------------------------------------------- the comparison

def _format_value(v) -> str:
    v = np.asarray(v)
    if v.dtype == bool and v.ndim == 1:                     # the samples of a pixel
        return "samples " + "".join("#" if x else "." for x in v.tolist())
    if v.ndim == 0:
        return _scalar(v.item())
    return "(" + ", ".join(_scalar(x) for x in v.tolist()) + ")"


def _scalar(x) -> str:
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


def _span(lo: int, hi: int) -> str:
    return f"{lo}..{hi}" if hi > lo else f"{lo}"


def _check_mask(mask, shape, name="mask") -> Optional[np.ndarray]:
    if mask is None:
        return None
    m = as_pixels(mask, name, shape)     # a set of (x, y) pixels: the mask of those
    if m.dtype != bool:
        raise TypeError(f"{name} must be a bool array [H, W] (True: compare this pixel), got dtype {m.dtype}")
    if m.shape != shape:
        raise ValueError(f"{name} has shape {list(m.shape)}, the images {list(shape)}")
    if not m.any():
        # A comparison of no pixel passes whatever the images hold: that is never what a test means.
        raise ValueError(f"{name} is False everywhere: it compares no pixel, so any image would pass "
                         "(True marks the pixels to compare; mask=None compares them all)")
    return m


def _check_tolerance(tolerance) -> float:
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.integer, np.floating)) \
            or not np.isfinite(tolerance) or tolerance < 0:
        raise ValueError(f"tolerance must be a finite number ≥ 0, got {tolerance!r}")
    return float(tolerance)


def _difference(a: np.ndarray, b: np.ndarray):
    """Per pixel, the largest difference over its channels (inf where exactly one is NaN)."""
    if a.dtype == bool:
        d = (a != b).astype(np.float64)
    else:
        fa, fb = a.astype(np.float64), b.astype(np.float64)
        with np.errstate(invalid="ignore"):
            d = np.abs(fa - fb)
        nan_a, nan_b = np.isnan(fa), np.isnan(fb)
        d[nan_a & nan_b] = 0.0
        d[nan_a ^ nan_b] = np.inf
        d[np.isinf(fa) & (fa == fb)] = 0.0
    return d.max(axis=2) if d.ndim == 3 else d


def _mask_char(g, w) -> str:
    """A pixel of two masks (or of two masks' samples): # both, + actual only, - expected only, . neither;
    X where the samples differ both ways."""
    g, w = np.atleast_1d(g), np.atleast_1d(w)
    extra, missing = bool((g & ~w).any()), bool((w & ~g).any())
    if extra and missing:
        return "X"
    if extra or missing:
        return "+" if extra else "-"
    return "#" if g.any() else "."


def _map(a, b, differs, compared, y0, y1, x0, x1) -> list:
    """The ASCII map of rows y0..y1, columns x0..x1, each row labelled with its y."""
    width = len(str(y1))
    lines = []
    for y in range(y0, y1 + 1):
        row = []
        for x in range(x0, x1 + 1):
            if compared is not None and not compared[y, x]:
                row.append("~")
            elif a.dtype == bool:
                row.append(_mask_char(a[y, x], b[y, x]))
            else:
                row.append("X" if differs[y, x] else ".")
        lines.append(f"  {y:>{width}} {''.join(row)}")
    return lines


def _both(actual, expected, actual_name: str, expected_name: str):
    """(actual, expected, lines saying how a set of pixels was read) as arrays; a set of (x, y)
    pixels is a mask the size of the other (of both sets' extent when both are sets)."""
    pa, pb = pixel_set(actual, actual_name), pixel_set(expected, expected_name)
    if pa is None and pb is None:
        return as_pixels(actual, actual_name), as_pixels(expected, expected_name), []
    if pa is not None and pb is not None:
        xy = np.array(pa + pb, dtype=np.int64).reshape(-1, 2)
        shape = (max(int(xy[:, 1].max()) + 1, 1), max(int(xy[:, 0].max()) + 1, 1)) if len(xy) else (1, 1)
    else:
        other, other_name = (expected, expected_name) if pa is not None else (actual, actual_name)
        other_array = as_pixels(other, other_name)
        if other_array.dtype != bool:
            which = actual_name if pa is not None else expected_name
            raise TypeError(f"{which} is a set of pixels and {other_name} an image ({other_array.dtype}): a set "
                            f"of pixels is compared with a mask: a bool array [H, W], a Coverage, or an ASCII "
                            "picture of '#' and '.'")
        shape = other_array.shape
    a, b = as_pixels(actual, actual_name, shape), as_pixels(expected, expected_name, shape)
    note = [f"{name} is a set of {len(p)} pixel{'' if len(p) == 1 else 's'} {PIXELS_ORIENTATION}"
            for name, p in ((actual_name, pa), (expected_name, pb)) if p is not None]
    return a, b, note


def compare(actual, expected, *, tolerance=0, mask=None, actual_name="actual", expected_name="expected"):
    """(message or None, actual array, expected array, differing pixels): the work of :func:`assert_pixels_equal`."""
    a, b, note = _both(actual, expected, actual_name, expected_name)
    tolerance = _check_tolerance(tolerance)
    if a.shape != b.shape:
        raise ValueError(f"{actual_name} has shape {list(a.shape)} and {expected_name} {list(b.shape)}: "
                         "they cannot be compared pixel by pixel")
    if (a.dtype == bool) != (b.dtype == bool):
        which, other = (actual_name, expected_name) if a.dtype == bool else (expected_name, actual_name)
        raise TypeError(f"{which} is a mask (bool) and {other} is not ({(b if a.dtype == bool else a).dtype}): "
                        "compare masks with masks")
    compared = _check_mask(mask, a.shape[:2])
    diff = _difference(a, b)
    differs = diff > tolerance
    if compared is not None:
        differs &= compared
    n = int(differs.sum())
    if n == 0:
        return None, a, b, differs
    h, w = differs.shape
    ys, xs = np.nonzero(differs)
    worst = np.where(differs, diff, -1.0)
    wy, wx = np.unravel_index(int(np.argmax(worst)), worst.shape)
    total = h * w if compared is None else int(compared.sum())
    head = f"{n} of {total} pixels differ (tolerance {tolerance:g}"
    head += f"; {h * w - total} pixels masked out)" if compared is not None else ")"
    lines = [head] + note + [
             f"differences in x {_span(xs.min(), xs.max())}, y {_span(ys.min(), ys.max())} "
             "(x: column from the left, y: row from the top)"]
    which = "first differing pixel" if a.dtype == bool else "worst pixel"
    worst_line = f"{which} x={wx}, y={wy}: {actual_name} {_format_value(a[wy, wx])}, " \
                 f"{expected_name} {_format_value(b[wy, wx])}"
    if a.dtype != bool:
        worst_line += f", difference {_scalar(float(diff[wy, wx]))}"
    lines.append(worst_line)
    y0, y1 = max(ys.min() - MAP_MARGIN, 0), min(ys.max() + MAP_MARGIN, h - 1)
    x0, x1 = max(xs.min() - MAP_MARGIN, 0), min(xs.max() + MAP_MARGIN, w - 1)
    shown_y1, shown_x1 = min(y1, y0 + MAP_ROWS - 1), min(x1, x0 + MAP_COLUMNS - 1)
    legend = (f"# both, + {actual_name} only, - {expected_name} only, . neither" if a.dtype == bool
              else "X differs, . equal")
    if a.dtype == bool and a.ndim == 3:
        legend = (f"# same samples, + {actual_name} has more, - {expected_name} has more, X each has samples the "
                  "other lacks, . none")
    if compared is not None:
        legend += ", ~ masked out"
    cut = "" if (shown_y1, shown_x1) == (y1, x1) else f" (the first {shown_y1 - y0 + 1} rows and " \
                                                       f"{shown_x1 - x0 + 1} columns of y {_span(y0, y1)}, " \
                                                       f"x {_span(x0, x1)})"
    lines.append(f"map of x {_span(x0, shown_x1)}, y {_span(y0, shown_y1)}{cut} ({legend}):")
    lines += _map(a, b, differs, compared, y0, shown_y1, x0, shown_x1)
    return "\n".join(lines), a, b, differs


def assert_pixels_equal(actual, expected, *, tolerance=0, mask=None,
                        diff_path: Union[None, str, "os.PathLike[str]"] = None) -> None:
    """Fail unless ``actual`` and ``expected`` hold the same pixels (within ``tolerance``).

    Parameters
    ----------
    actual, expected : array [H, W] or [H, W, C], Framebuffer, Coverage, pillow Image, image file or pixels
        A Framebuffer is its 8-bit RGB picture (``np.asarray(fb)``); a Coverage its mask.
        A set of (x, y) pixels (a set, or a list or tuple of integer pairs) is the mask,
        the size of the other side, True at those pixels, in window coordinates, y up,
        as ``covered_pixels`` gives them: pixel (x, y) is the image's row height - 1 - y.
        Masks (bool) are compared with masks only.
    tolerance : number ≥ 0
        A pixel differs when any channel differs by more than this, in the
        arrays' own units (0…255 for 8-bit images). 0: exactly equal.
    mask : bool [H, W], optional
        The pixels to compare (True); the others are not looked at.
    diff_path : path, optional
        On failure, write a diff image there (PNG): differing pixels red, the
        others the expected image dimmed to gray, masked-out pixels dark blue.

    Raises
    ------
    AssertionError
        Saying how many pixels differ, where (their bounding box), the worst
        pixel with both values, and an ASCII map of the differing region: for
        masks ``#`` both, ``+`` actual only, ``-`` expected only, ``.`` neither;
        for images ``X`` differs, ``.`` equal.
    """
    __tracebackhide__ = True
    message, a, b, differs = compare(actual, expected, tolerance=tolerance, mask=mask)
    if message is None:
        return
    if diff_path is not None:
        path = write_png(diff_image(b, differs, _check_mask(mask, a.shape[:2])), diff_path)
        message += f"\ndiff image: {path}"
    raise AssertionError(message)


def _gray(b: np.ndarray) -> np.ndarray:
    """The expected image as 8-bit gray, [H, W]."""
    if b.dtype == bool:
        return (b.mean(axis=2) if b.ndim == 3 else b.astype(np.float64)) * 255.0
    f = b.astype(np.float64)
    if f.ndim == 3:
        f = f[:, :, :3].mean(axis=2) if f.shape[2] >= 3 else f[:, :, 0]
    if b.dtype != np.uint8:
        hi = np.nanmax(np.abs(f)) if np.isfinite(f).any() else 1.0
        f = f / (hi if hi > 1.0 else 1.0) * 255.0
    return np.nan_to_num(f, nan=0.0, posinf=255.0, neginf=0.0)


def diff_image(expected: np.ndarray, differs: np.ndarray, compared: Optional[np.ndarray] = None) -> np.ndarray:
    """uint8 RGB [H, W, 3]: differing pixels red, the rest the expected picture dimmed to gray,
    pixels not compared dark blue."""
    g = (40 + 0.35 * _gray(expected)).astype(np.uint8)
    out = np.stack([g, g, g], axis=2)
    if compared is not None:
        out[~compared] = (0, 0, 96)
    out[differs] = (255, 0, 0)
    return out


def to_8bit(image, name: str = "image") -> np.ndarray:
    """An image as 8-bit, as stored in a PNG: uint8 [H, W] or [H, W, 2|3|4].

    A Framebuffer is its 8-bit RGB picture; a bool mask 0 and 255; a float array
    ``round(clamp(v, 0, 1)·255)`` (half to even, as Framebuffer.to_uint8); an
    integer array must already lie in 0…255.
    """
    a = as_pixels(image, name)
    if a.dtype == bool:
        return np.where(a, 255, 0).astype(np.uint8)
    if np.issubdtype(a.dtype, np.floating):
        if np.isnan(a).any():
            raise ValueError(f"{name} holds NaN, which has no 8-bit value")
        return np.rint(np.clip(a.astype(np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)
    if a.size and (a.min() < 0 or a.max() > 255):
        raise ValueError(f"{name} holds integers outside 0…255 ({int(a.min())}…{int(a.max())}); "
                         "an 8-bit image cannot store them")
    return a.astype(np.uint8)


def png_bytes(a: np.ndarray) -> bytes:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def write_png(a: np.ndarray, path) -> Path:
    """Write uint8 ``a`` as a PNG at ``path`` (whole or not at all; folders made); returns the path."""
    from softpipe.core.files import atomic_write
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = png_bytes(a)
    atomic_write(path, lambda f: f.write(data))
    return path


# ----------------------------------------------------------- golden images

def check_golden(image, golden_path, *, tolerance=0, mask=None, update: bool = False,
                 output_dir=None) -> str:
    """Compare ``image`` with the PNG at ``golden_path``; the work of the pytest ``golden`` fixture.

    The image is made 8-bit first (:func:`to_8bit`) and compared with the
    stored 8-bit PNG: ``tolerance`` is in 8-bit levels (0: the same bytes).
    Returns "passed", "created" or "updated"; raises AssertionError when the
    golden image is missing (it is written, to be looked at and committed) or
    differs (``output_dir`` then receives NAME.actual.png and NAME.diff.png).
    With ``update`` a missing or different golden image is (re)written instead, and so
    is one of another size or number of channels, or one that is not a readable image.
    """
    __tracebackhide__ = True
    golden_path = Path(golden_path)
    actual = to_8bit(image, "image")
    _check_mask(mask, actual.shape[:2])          # a bad mask is an error in update mode too
    if not golden_path.exists():
        write_png(actual, golden_path)
        if update:
            return "created"
        raise AssertionError(f"golden image {golden_path} did not exist; it is written now from this run: look at "
                             "it, commit it, and run the test again")
    try:
        golden = as_pixels(golden_path, "golden")
        if golden.shape != actual.shape:
            raise ValueError(f"actual has shape {list(actual.shape)} and golden {list(golden.shape)}: "
                             "they cannot be compared pixel by pixel")
    except ValueError as e:                      # unreadable, or another size or number of channels
        if update:
            write_png(actual, golden_path)
            return "updated"
        raise ValueError(f"{e}\ngolden image: {golden_path}\n(if the new image is right: "
                         "pytest --softpipe-update-golden rewrites the golden image)") from None
    message, a, b, differs = compare(actual, golden, tolerance=tolerance, mask=mask,
                                     actual_name="actual", expected_name="golden")
    if message is None:
        return "passed"
    if update:
        write_png(actual, golden_path)
        return "updated"
    out = Path(output_dir) if output_dir is not None else golden_path.parent
    stem = golden_path.stem
    actual_file = write_png(actual, out / f"{stem}.actual.png")
    diff_file = write_png(diff_image(b, differs, _check_mask(mask, a.shape[:2])), out / f"{stem}.diff.png")
    raise AssertionError(f"{message}\n"
                         f"golden image: {golden_path}\n"
                         f"this run:     {actual_file}\n"
                         f"diff:         {diff_file}\n"
                         "(if the new image is right: pytest --softpipe-update-golden rewrites the golden image)")
