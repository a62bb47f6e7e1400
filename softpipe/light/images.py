"""A texture's texels before sampling: an image file or array read and checked, and its mip pyramid.

Shared by the 2D textures (:mod:`softpipe.light.texture`) and the cube maps
(:mod:`softpipe.light.cubemap`): both hold float32 RGBA levels [H, W, 4], row 0 at the
top, level 0 first and each next level half the size (floored, at least 1) made by a
box filter. docs/textures.md tells the whole story; sampling is in texture.py.

sRGB textures (``srgb=True``): the 8-bit (or 16-bit) values of an image are sRGB-encoded,
and are decoded to linear light here, once, from the exact integers (FORMULAS §28),
before the mip pyramid is made: filtering (the box filter of the mipmaps, a shader's
bilinear and trilinear taps) averages light, so it must average linear values, as GL's
sRGB textures decode before they filter. Alpha is never decoded.
"""
from __future__ import annotations

import os
import warnings
from typing import Optional, Tuple, Union

import numpy as np

from softpipe.core.colors import srgb_decode

__all__ = ["PEAK_BYTES_PER_TEXEL", "MAX_TEXTURE_BYTES", "texture_bytes", "check_size", "load_image", "to_rgba",
           "check_array", "build_mipmaps", "choose"]


#: Peak memory a texture costs while it is made, per texel of level 0: measured 96 bytes in
#: numpy arrays (float32 RGBA level 0, the mip chain, its packed copy for shaders, float64
#: while halving) for 1024² and 2048² images, plus Pillow's decoded copy; rounded up.
PEAK_BYTES_PER_TEXEL = 110
#: The largest peak a texture may cost (bytes); larger images are refused before they are
#: decoded. ``Texture2D(..., max_bytes=...)`` raises or lowers it for one texture.
MAX_TEXTURE_BYTES = 2 << 30


def texture_bytes(width: int, height: int) -> int:
    """The peak memory (bytes) making a ``width`` × ``height`` texture takes (:data:`PEAK_BYTES_PER_TEXEL`)."""
    return int(width) * int(height) * PEAK_BYTES_PER_TEXEL


def check_size(name: str, width: int, height: int, max_bytes: Optional[int]) -> None:
    """Refuse an image of ``width`` × ``height`` texels whose mipmaps would need more than ``max_bytes``
    (None: :data:`MAX_TEXTURE_BYTES`); ``name`` says which image in the error."""
    limit = MAX_TEXTURE_BYTES if max_bytes is None else max_bytes
    need = texture_bytes(width, height)
    if need > limit:
        raise ValueError(f"Texture2D: {name} is {width}×{height} texels, which needs about {need / 2**30:.1f} GiB "
                         f"while its mipmaps are made ({PEAK_BYTES_PER_TEXEL} bytes a texel), more than the "
                         f"limit of {limit / 2**30:.1f} GiB (Texture2D(..., max_bytes=...) or "
                         "softpipe.light.images.MAX_TEXTURE_BYTES)")


def _from_integers(values: np.ndarray, top: float, srgb: bool) -> np.ndarray:
    """Integer texels (0..``top``) as float32 in 0..1; with ``srgb`` the color channels (not a 4th, alpha)
    decoded from sRGB to linear (FORMULAS §28), computed from the integers in float64."""
    f = values.astype(np.float64) / top
    if srgb:
        color = slice(None) if f.ndim == 2 else slice(0, 3)
        f[..., color] = srgb_decode(f[..., color])
    return f.astype(np.float32)


def load_image(path: Union[str, os.PathLike], max_bytes: Optional[int] = None, srgb: bool = False) -> np.ndarray:
    """Read an image file into float32 RGBA [H, W, 4], row 0 = top; its size is checked before decoding.

    ``srgb``: the image's color values are sRGB-encoded; decode them to linear (module docstring).
    """
    from PIL import Image, UnidentifiedImageError

    name = os.fspath(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)   # the size check below says more
            img_file = Image.open(name)
        with img_file as img:
            check_size(f"image file {name!r}", img.width, img.height, max_bytes)
            img.load()
            mode = img.mode
            if mode.startswith("I;16"):
                return to_rgba(_from_integers(np.asarray(img), 65535.0, srgb))
            if mode in ("I", "F"):
                raise ValueError(
                    f"Texture2D: image file {name!r} has 32-bit pixel mode {mode!r}; expected an "
                    "8-bit grayscale/RGB/RGBA (or palette) image or 16-bit grayscale"
                )
            rgba = np.asarray(img.convert("RGBA"), dtype=np.uint8)
    except FileNotFoundError:
        raise FileNotFoundError(f"Texture2D: image file not found: {name!r}") from None
    except Image.DecompressionBombError as err:
        raise ValueError(f"Texture2D: image file {name!r} is too large to decode safely: {err}") from None
    except (UnidentifiedImageError, OSError, SyntaxError) as err:
        # pillow reports truncated and corrupt files as OSError or SyntaxError
        raise ValueError(f"Texture2D: cannot read image file {name!r}: {err}") from None
    if srgb:
        return _from_integers(rgba, 255.0, True)
    return rgba.astype(np.float32) / np.float32(255.0)     # not through float64: the texels as they always were


def to_rgba(data: np.ndarray) -> np.ndarray:
    """[H, W], [H, W, 3] or [H, W, 4] float32 → [H, W, 4] float32 with alpha 1 where missing."""
    h, w = data.shape[:2]
    out = np.ones((h, w, 4), dtype=np.float32)
    if data.ndim == 2:
        out[..., :3] = data[..., None]
    else:
        out[..., : data.shape[2]] = data
    return out


def check_array(array: np.ndarray, srgb: bool = False) -> np.ndarray:
    """Validate a texture array and return it as float32 RGBA [H, W, 4].

    ``srgb``: a uint8 array holds sRGB-encoded values; decode them to linear (module
    docstring). A float array is taken as linear already, so ``srgb=True`` refuses it.
    """
    a = np.asarray(array)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (3, 4)):
        raise ValueError(
            f"Texture2D: array must have shape [H, W], [H, W, 3] or [H, W, 4], got shape {a.shape}"
        )
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"Texture2D: array must be at least 1×1 texels, got shape {a.shape}")
    if srgb and a.dtype != np.uint8:
        raise ValueError(f"Texture2D: srgb=True decodes 8-bit (uint8) texels, and this array is {a.dtype}; a "
                         "float array is taken as linear already (decode it yourself with "
                         "softpipe.core.colors.srgb_decode, or give srgb=False)")
    if a.dtype == np.uint8:
        f = _from_integers(a, 255.0, True) if srgb else a.astype(np.float32) / np.float32(255.0)
    elif np.issubdtype(a.dtype, np.floating):
        with np.errstate(over="ignore"):  # overflow to inf is reported just below
            f = a.astype(np.float32)
        bad = ~np.isfinite(f)
        if bad.any():
            r, c = np.argwhere(bad)[0][:2]
            raise ValueError(
                f"Texture2D: array has non-finite texels (NaN or inf, or too large for float32), "
                f"first at row {r}, column {c}; texels must be finite"
            )
    else:
        raise TypeError(
            f"Texture2D: array dtype must be uint8 (0..255) or floating point, got {a.dtype}"
        )
    return to_rgba(f)


def _box_taps(n_in: int) -> Tuple[np.ndarray, np.ndarray]:
    """Indices and weights [n_out, 4] of the box filter that halves a size (floored, at least 1).

    Destination texel d covers source interval [d·r, (d+1)·r) with r = n_in/n_out
    (2 for even sizes, 2 + 1/k for odd ones); each source texel weighs by its overlap.
    r ≤ 3, so at most 4 source texels touch one interval.
    """
    n_out = max(1, n_in // 2)
    d = np.arange(n_out)
    lo = d * n_in / n_out
    hi = (d + 1) * n_in / n_out
    idx = np.floor(lo).astype(np.int64)[:, None] + np.arange(4)[None, :]
    overlap = np.minimum(idx + 1, hi[:, None]) - np.maximum(idx, lo[:, None])
    weights = np.clip(overlap, 0.0, None) * (n_out / n_in)
    return np.minimum(idx, n_in - 1), weights


def _halve_axis(level: np.ndarray, axis: int) -> np.ndarray:
    idx, weights = _box_taps(level.shape[axis])
    moved = np.moveaxis(level, axis, 0)
    out = sum(weights[:, t, None, None] * moved[idx[:, t]] for t in range(4))
    return np.moveaxis(out, 0, axis)


def build_mipmaps(level0: np.ndarray) -> list:
    """The mip pyramid of a float32 [H, W, 4] image, level 0 first, down to 1×1.

    See the module docstring ("Mipmaps") for sizes and the box filter.
    """
    levels = [level0]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        prev = levels[-1].astype(np.float64)
        levels.append(_halve_axis(_halve_axis(prev, 0), 1).astype(np.float32))
    return levels


def choose(kind: str, value: str, allowed: dict) -> int:
    """The code of option ``value`` (a wrap mode, a filter) among ``allowed``, or a ValueError naming them."""
    if not isinstance(value, str) or value not in allowed:
        choices = ", ".join(repr(k) for k in allowed)
        raise ValueError(f"Texture2D: {kind} must be one of {choices}; got {value!r}")
    return allowed[value]
