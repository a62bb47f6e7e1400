"""Colors by name: the one parser the command line and the Python API share.

:func:`parse_color` reads every way softpipe takes a color:

- a CSS color name: ``"red"``, ``"white"``, ``"steelblue"`` (the 148 names pillow knows);
- hex: ``"#ff8000"``, ``"#f80"``, ``"#ff800080"`` (with alpha);
- CSS functions: ``"rgb(255, 128, 0)"``, ``"rgba(255, 128, 0, 0.5)"``, ``"hsl(30, 100%, 50%)"``;
- numbers in a string, linear 0..1: ``"0.1,0.2,0.3"`` or ``"0.1 0.2 0.3 1"``;
- a sequence of 3 or 4 numbers: ``(0.1, 0.2, 0.3)`` (any finite values: the
  framebuffer's colors are unclamped floats).

A named or hex color is its 8-bit values divided by 255 (no sRGB decoding), so
``fb.clear("#ff8000")`` writes exactly the pixel ``#ff8000``. The result is a tuple
of 3 floats (RGB) or 4 (RGBA) as given; :func:`rgba` always gives 4.

It is used by :meth:`Framebuffer.clear <softpipe.pipeline.framebuffer.Framebuffer.clear>`,
:class:`~softpipe.light.material.Material` and :class:`~softpipe.light.material.Light` colors,
:func:`softpipe.render` and :func:`softpipe.turntable` (``background``,
``wire_color``) and the command line's ``--background`` and ``--wire-color``.

:func:`srgb_encode` and :func:`srgb_decode` are sRGB's two transfer functions (IEC
61966-2-1, FORMULAS §28): linear light to the encoded values an 8-bit image stores,
and back. An sRGB framebuffer encodes on the way to bytes, an sRGB texture decodes
its texels once when it is made (docs/gamma.md says why both are needed).
"""
from __future__ import annotations

import difflib
import math
import numbers
import re
from typing import Any, Tuple, cast

import numpy as np

__all__ = ["parse_color", "rgba", "color_names", "srgb_encode", "srgb_decode"]

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
_HELP = "a CSS name such as 'red', '#rrggbb', 'rgb(r, g, b)' or 'r,g,b[,a]' in 0..1"


def color_names() -> Tuple[str, ...]:
    """Every CSS color name :func:`parse_color` knows, sorted."""
    from PIL import ImageColor
    return tuple(sorted(ImageColor.colormap))


def _from_text(text: str) -> Tuple[float, ...]:
    stripped = text.strip()
    parts = [p for p in re.split(r"[,\s]+", stripped) if p]
    if parts and all(_NUMBER.fullmatch(p) for p in parts):
        if len(parts) not in (3, 4):
            raise ValueError(f"color {text!r}: expected 3 or 4 numbers (r,g,b[,a]), got {len(parts)}")
        values = tuple(float(p) for p in parts)
        if not all(0.0 <= v <= 1.0 for v in values):
            raise ValueError(f"color {text!r}: color components must be in 0..1")
        return values
    from PIL import ImageColor
    try:
        rgb = ImageColor.getrgb(stripped)
    except ValueError:
        hint = ""
        if re.fullmatch(r"[A-Za-z ]+", stripped):
            close = difflib.get_close_matches(stripped.lower().replace(" ", ""), color_names(), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ValueError(f"unknown color {text!r}{hint}: expected {_HELP}") from None
    return tuple(c / 255.0 for c in rgb)


def parse_color(value: Any) -> Tuple[float, ...]:
    """A color as a tuple of 3 (RGB) or 4 (RGBA) floats, linear.

    Parameters
    ----------
    value : str or sequence of numbers
        A CSS name (``"red"``), hex (``"#ff8000"``), ``"rgb(…)"``, numbers in a string
        (``"0.1,0.2,0.3"``, each in 0..1), or 3 or 4 finite numbers (any values).

    Raises
    ------
    ValueError
        One line naming the value: an unknown name (with the closest known one), a
        numeric string outside 0..1, a sequence that is not 3 or 4 finite numbers.
    TypeError
        Neither a string nor a sequence of numbers.
    """
    if isinstance(value, str):
        return _from_text(value)
    if isinstance(value, (bytes, bool)) or isinstance(value, numbers.Number):
        raise TypeError(f"expected a color ({_HELP}, or 3 or 4 numbers), got {type(value).__name__} {value!r}")
    try:
        values = tuple(float(c) for c in _flat(value))
    except (TypeError, ValueError):
        raise TypeError(f"expected a color ({_HELP}, or 3 or 4 numbers), got {value!r}") from None
    if len(values) not in (3, 4):
        raise ValueError(f"color {value!r}: expected 3 or 4 numbers (RGB or RGBA), got {len(values)}")
    if not all(math.isfinite(c) for c in values):
        raise ValueError(f"color {value!r}: every component must be finite")
    return values


def _flat(value):
    """The numbers of a sequence or array (a numpy array of shape (3,) or (1, 4) too)."""
    if hasattr(value, "reshape") and hasattr(value, "dtype"):
        return value.reshape(-1).tolist()
    out = []
    for c in value:
        if isinstance(c, (str, bytes, bool)) or not isinstance(c, numbers.Real):
            raise TypeError
        out.append(c)
    return out


def rgba(value: Any) -> Tuple[float, float, float, float]:
    """:func:`parse_color`, with alpha 1 added to an RGB color."""
    c = parse_color(value)
    return cast(Tuple[float, float, float, float], c + (1.0,) if len(c) == 3 else c)  # 3 or 4 numbers: 4


# FORMULAS §28: sRGB's piecewise transfer functions (IEC 61966-2-1), linear segment near black
_ENCODE_KNEE = 0.0031308      # linear values at or below it are encoded by the straight line 12.92·c
_DECODE_KNEE = 0.04045        # = 12.92 × 0.0031308, rounded as the standard gives it


def srgb_encode(linear: Any) -> np.ndarray:
    """Linear light → sRGB-encoded values (FORMULAS §28), element by element.

    ``12.92·c`` for ``c ≤ 0.0031308``, else ``1.055·c^(1/2.4) − 0.055``, computed in
    float64. The formula is for 0 ≤ c ≤ 1; a negative value is taken as 0 and a value
    above 1 as 1 (as GL clamps before it encodes), and NaN stays NaN for the caller to
    decide (:meth:`Framebuffer.to_uint8 <softpipe.pipeline.framebuffer.Framebuffer.to_uint8>`
    makes it 0).

    Parameters
    ----------
    linear : array-like of numbers
        Any shape: a value, a color, an image [H, W, C].

    Returns
    -------
    numpy.ndarray
        float64, the same shape; encoded values in [0, 1].
    """
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    # np.where evaluates both branches: the power of a value below the knee is finite (c ≥ 0), so no warning
    return np.where(c <= _ENCODE_KNEE, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def srgb_decode(encoded: Any) -> np.ndarray:
    """sRGB-encoded values → linear light (FORMULAS §28), element by element: the inverse of :func:`srgb_encode`.

    ``c / 12.92`` for ``c ≤ 0.04045``, else ``((c + 0.055) / 1.055)^2.4``, computed in
    float64; values outside [0, 1] are clamped into it first, NaN stays NaN.

    Parameters
    ----------
    encoded : array-like of numbers
        Any shape, encoded values in 0..1 (an 8-bit image's bytes divided by 255).

    Returns
    -------
    numpy.ndarray
        float64, the same shape; linear values in [0, 1].
    """
    c = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= _DECODE_KNEE, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))
