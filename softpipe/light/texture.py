"""2D textures: images with mipmaps, and the GLSL-like functions shaders sample them with.

Two halves, as on a GPU: :class:`Texture2D` is the host side (loads an image file
or array, checks it, converts it to linear float RGBA, builds the mip pyramid
once, hands shaders a :class:`TextureUniform` through ``__softpipe_uniform__``);
:func:`texture`, :func:`texture_lod`, :func:`texture_grad`, :func:`mip_level` and
:func:`texture_size` are the shader side, numba functions named after GLSL's
``texture``, ``textureLod``, ``textureGrad``, ``textureQueryLod`` and
``textureSize`` (the same as plain Python under ``NUMBA_DISABLE_JIT=1``).

Texture coordinates follow OpenGL, ``(0, 0)`` the image's lower-left corner, v up;
images are stored top row first, as numpy and pillow store them. The flip happens
in one place, :func:`_fetch`. Texel addressing, wrap modes and filters follow
OpenGL 4.6 §8.14: ``filter`` is one of ``"nearest"``, ``"bilinear"`` (level 0
only), ``"nearest_mipmap"`` and ``"trilinear"``; λ = log2 ρ from the derivatives a
shader passes (:func:`texture` has none and samples level 0). Every texture gets a
box-filtered pyramid down to 1×1, summed in float64 and stored as float32. NaN and
infinite coordinates are defined, so that jitted and plain-Python runs agree.

docs/textures.md has it all: the orientation, the addressing and wrap formulas,
the filter table and λ, how odd-sized levels are averaged, how 8-, 16-bit and
float texels are read, and why the sampling helpers are shaped as they are.
"""
from __future__ import annotations

import math
import os
from collections import namedtuple
from typing import Optional, Tuple, Union

import numpy as np
from numba import njit

from softpipe.language.glsl import mix
from softpipe.light.images import build_mipmaps, check_array, check_size, choose, load_image

__all__ = [
    "Texture2D",
    "TextureUniform",
    "texture",
    "texture_lod",
    "texture_grad",
    "mip_level",
    "texture_size",
    "WRAP_MODES",
    "FILTERS",
    "FILTER_BILINEAR", "FILTER_NEAREST", "FILTER_NEAREST_MIPMAP",
]

RGBA = Tuple[float, float, float, float]

# Codes stored in TextureUniform; module-level ints so numba folds them as constants.
WRAP_REPEAT = 0
WRAP_CLAMP = 1
WRAP_MIRROR = 2
WRAP_MODES = {"repeat": WRAP_REPEAT, "clamp": WRAP_CLAMP, "mirror": WRAP_MIRROR}

FILTER_NEAREST = 0
FILTER_BILINEAR = 1
FILTER_NEAREST_MIPMAP = 2
FILTER_TRILINEAR = 3
FILTERS = {
    "nearest": FILTER_NEAREST,
    "bilinear": FILTER_BILINEAR,
    "nearest_mipmap": FILTER_NEAREST_MIPMAP,
    "trilinear": FILTER_TRILINEAR,
}

# Far beyond any meaningful texel coordinate, yet small enough that int64 index
# arithmetic (i mod 2W) cannot overflow in compiled code.
_COORD_LIMIT = 2.0**40

TextureUniform = namedtuple(
    "TextureUniform", ["texels", "widths", "heights", "offsets", "wrap_s", "wrap_t", "filter"]
)
TextureUniform.__doc__ = """What a shader receives for a :class:`Texture2D`.

Fields
------
texels : float32 array [total, 4]
    All mip levels, level 0 first, each in image order (row 0 = top) and row-major:
    texel (column c, image row r) of level k is ``texels[offsets[k] + r * widths[k] + c]``.
widths, heights, offsets : int64 arrays [levels]
    Size of each level and the index of its first texel in ``texels``.
wrap_s, wrap_t : int
    Wrap codes for u and v (0 repeat, 1 clamp, 2 mirror).
filter : int
    0 nearest, 1 bilinear, 2 nearest_mipmap, 3 trilinear.
"""


# --------------------------------------------------------------------------
# Shader side: numba functions (plain Python under NUMBA_DISABLE_JIT=1)
# --------------------------------------------------------------------------


@njit(cache=True, forceinline=True)
def _wrap(i, size, mode):
    """Map an integer texel index into [0, size) by wrap mode (GL Table 8.20)."""
    if 0 <= i < size:  # the common case; every mode leaves it alone, and skips an int division
        return i
    if mode == WRAP_REPEAT:
        return i % size  # Python's and numba's % are both non-negative for size > 0
    if mode == WRAP_CLAMP:
        return min(max(i, 0), size - 1)
    m = i % (2 * size) - size
    if m < 0:
        m = -(1 + m)
    return size - 1 - m


@njit(cache=True, forceinline=True)
def _floor_frac(x):
    """Split a texel coordinate into (integer floor, fraction), safe for any float."""
    if x != x:  # NaN: int() of it would raise in Python and be undefined in numba
        x = 0.0
    elif x > _COORD_LIMIT:
        x = _COORD_LIMIT
    elif x < -_COORD_LIMIT:
        x = -_COORD_LIMIT
    f = math.floor(x)
    return f, x - f


# Speed: each array handed to a (non-inlined) numba call costs an atomic
# reference-count increment and decrement, and with the four arrays of a
# TextureUniform that dominated the cost of a sample. So the per-level helpers
# take one array and plain ints, the tiny helpers and _sample are inlined (all
# inside this module, so the on-disk cache keeps them), and only the public
# functions take the whole uniform. Inlining the public functions too would be
# faster still but lengthens the compile of every user shader that calls them,
# so they are left as calls (figures: benchmarks/README.md, "The figures behind
# the pipeline's comments").


@njit(cache=True, forceinline=True)
def _fetch(texels, offset, w, h, i, j):
    """Texel (i, j) of a level, j counted from the BOTTOM row (the v-flip lives here)."""
    k = offset + (h - 1 - j) * w + i
    return (float(texels[k, 0]), float(texels[k, 1]), float(texels[k, 2]), float(texels[k, 3]))


@njit(cache=True)
def _nearest(texels, offset, w, h, wrap_s, wrap_t, u, v):
    """GL NEAREST on one level: the texel whose square contains (u, v)."""
    # float() keeps plain-Python results Python floats rather than numpy scalars
    i, _ = _floor_frac(u * float(w))
    j, _ = _floor_frac(v * float(h))
    return _fetch(texels, offset, w, h, _wrap(i, w, wrap_s), _wrap(j, h, wrap_t))


@njit(cache=True)
def _bilinear(texels, offset, w, h, wrap_s, wrap_t, u, v):
    """GL LINEAR on one level: the 2×2 texels around (u, v), weighted by distance to their centres."""
    i0, a = _floor_frac(u * float(w) - 0.5)
    j0, b = _floor_frac(v * float(h) - 0.5)
    i1 = _wrap(i0 + 1, w, wrap_s)
    j1 = _wrap(j0 + 1, h, wrap_t)
    i0 = _wrap(i0, w, wrap_s)
    j0 = _wrap(j0, h, wrap_t)
    t00 = _fetch(texels, offset, w, h, i0, j0)
    t10 = _fetch(texels, offset, w, h, i1, j0)
    t01 = _fetch(texels, offset, w, h, i0, j1)
    t11 = _fetch(texels, offset, w, h, i1, j1)
    w00 = (1.0 - a) * (1.0 - b)
    w10 = a * (1.0 - b)
    w01 = (1.0 - a) * b
    w11 = a * b
    return (
        w00 * t00[0] + w10 * t10[0] + w01 * t01[0] + w11 * t11[0],
        w00 * t00[1] + w10 * t10[1] + w01 * t01[1] + w11 * t11[1],
        w00 * t00[2] + w10 * t10[2] + w01 * t01[2] + w11 * t11[2],
        w00 * t00[3] + w10 * t10[3] + w01 * t01[3] + w11 * t11[3],
    )


@njit(cache=True, forceinline=True)
def _sample(tex, u, v, lod):
    """Sample at level of detail ``lod`` by the texture's filter (see the module docstring).

    Inlined into texture / texture_lod / texture_grad so that they unpack the
    uniform once instead of passing it on.
    """
    f = tex.filter
    texels = tex.texels
    widths = tex.widths
    heights = tex.heights
    offsets = tex.offsets
    ws = tex.wrap_s
    wt = tex.wrap_t
    if f == FILTER_NEAREST:
        return _nearest(texels, offsets[0], widths[0], heights[0], ws, wt, u, v)
    if f == FILTER_BILINEAR:
        return _bilinear(texels, offsets[0], widths[0], heights[0], ws, wt, u, v)
    top = widths.shape[0] - 1
    lam = float(lod)
    if not (lam > 0.0):  # magnification, and NaN, use level 0
        lam = 0.0
    if lam > top:
        lam = float(top)
    if f == FILTER_NEAREST_MIPMAP:
        d = int(math.ceil(lam + 0.5)) - 1
        return _nearest(texels, offsets[d], widths[d], heights[d], ws, wt, u, v)
    d = int(math.floor(lam))
    t = lam - d
    near = _bilinear(texels, offsets[d], widths[d], heights[d], ws, wt, u, v)
    if t == 0.0:  # also covers d == top, where there is no level d + 1
        return near
    d += 1
    far = _bilinear(texels, offsets[d], widths[d], heights[d], ws, wt, u, v)
    return mix(near, far, t)


@njit(cache=True)
def texture(tex, uv):
    """Sample a texture at ``uv`` with level of detail 0 (GLSL ``texture`` without derivatives).

    Parameters
    ----------
    tex : TextureUniform
        The uniform of a :class:`Texture2D`.
    uv : (float, float)
        Texture coordinates; (0, 0) is the lower-left corner of the image.

    Returns
    -------
    (float, float, float, float)
        RGBA. Mipmapping filters sample level 0 here (no derivatives are known);
        use :func:`texture_grad` or :func:`texture_lod` to select levels.
    """
    return _sample(tex, uv[0], uv[1], 0.0)


@njit(cache=True)
def texture_lod(tex, uv, lod):
    """Sample at an explicit level of detail λ (GLSL ``textureLod``).

    ``lod`` is clamped to ``[0, levels − 1]``; 0.5 with ``"trilinear"`` is the
    even mix of levels 0 and 1. ``"nearest"`` and ``"bilinear"`` ignore it.
    """
    return _sample(tex, uv[0], uv[1], lod)


@njit(cache=True)
def mip_level(tex, duv_dx, duv_dy):
    """The level of detail λ = log2 ρ for the given derivatives (GLSL ``textureQueryLod``'s raw λ).

    Parameters
    ----------
    tex : TextureUniform
    duv_dx, duv_dy : (float, float)
        (∂u/∂x, ∂v/∂x) and (∂u/∂y, ∂v/∂y): change of uv per pixel along window x and y.

    Returns
    -------
    float
        ``log2(max(|duv_dx|, |duv_dy|))`` with u measured in texels of level 0
        (scaled by its width) and v in texels (scaled by its height). Not
        clamped: negative means magnification; ``-inf`` for zero derivatives.
    """
    w = float(tex.widths[0])
    h = float(tex.heights[0])
    rx = math.sqrt((duv_dx[0] * w) ** 2 + (duv_dx[1] * h) ** 2)
    ry = math.sqrt((duv_dy[0] * w) ** 2 + (duv_dy[1] * h) ** 2)
    rho = rx if rx > ry else ry
    if rho > 0.0:
        return math.log2(rho)
    return -math.inf  # math.log2(0) raises in Python; numba would give -inf


@njit(cache=True)
def texture_grad(tex, uv, duv_dx, duv_dy):
    """Sample with the level of detail given by screen-space derivatives (GLSL ``textureGrad``).

    λ is :func:`mip_level` of the derivatives, then sampled as :func:`texture_lod`.
    """
    return _sample(tex, uv[0], uv[1], mip_level(tex, duv_dx, duv_dy))


@njit(cache=True)
def texture_size(tex, level):
    """(width, height) of a mip level, as ints (GLSL ``textureSize``)."""
    return (int(tex.widths[level]), int(tex.heights[level]))


# --------------------------------------------------------------------------
# Host side: loading, checking, mipmaps
# --------------------------------------------------------------------------


class Texture2D:
    """A 2D RGBA texture with mipmaps, loaded from an image file or a numpy array.

    Parameters
    ----------
    source : str, os.PathLike or numpy.ndarray
        An image file readable by pillow (8-bit grayscale, RGB, RGBA or palette;
        16-bit grayscale) or an array [H, W], [H, W, 3] or [H, W, 4] of uint8
        (scaled by 1/255) or floats (taken as they are; must be finite).
        Row 0 is the top of the image; texture coordinate v = 0 is its bottom.
    wrap : {"repeat", "clamp", "mirror"}
        Wrap mode for both coordinates: GL's REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT.
    filter : {"nearest", "bilinear", "nearest_mipmap", "trilinear"}
        See the module docstring for what each does with the level of detail.
    wrap_s, wrap_t : str, optional
        Wrap mode for u (s) or v (t) alone, overriding ``wrap``.
    max_bytes : int, optional
        The most memory making this texture may take (default
        :data:`softpipe.light.images.MAX_TEXTURE_BYTES`, 2 GiB); a larger image is refused before it
        is decoded, with the estimate (:func:`softpipe.light.images.texture_bytes`) in the message.
    srgb : bool
        An sRGB texture (GL's SRGB8 / SRGB8_ALPHA8): the image file's or uint8 array's color
        values are sRGB-encoded, and are decoded to linear light once, here, before the
        mipmaps are made (FORMULAS §28), so that every filter averages light, as GL's sRGB
        textures decode before they filter; alpha is not decoded. Default False: the
        values are taken as they are (byte/255), as before. A float array is linear
        already: ``srgb=True`` refuses it (ValueError). Most photographs and painted
        color maps (an MTL's ``map_Kd``) are sRGB.

    Attributes
    ----------
    width, height : int
        Size of level 0 in texels.
    levels : list of numpy.ndarray
        The mip pyramid, float32 [h, w, 4] each, row 0 = top, read-only.
    wrap_s, wrap_t, filter : str
    srgb : bool
    """

    def __init__(
        self,
        source: Union[str, os.PathLike, np.ndarray],
        *,
        wrap: str = "repeat",
        filter: str = "bilinear",
        wrap_s: Optional[str] = None,
        wrap_t: Optional[str] = None,
        max_bytes: Optional[int] = None,
        srgb: bool = False,
    ) -> None:
        if not isinstance(srgb, (bool, np.bool_)):
            raise TypeError(f"Texture2D: srgb must be True or False, got {type(srgb).__name__} {srgb!r}")
        self.srgb = bool(srgb)
        self.wrap_s = wrap if wrap_s is None else wrap_s
        self.wrap_t = wrap if wrap_t is None else wrap_t
        self.filter = filter
        self._wrap_s = choose("wrap" if wrap_s is None else "wrap_s", self.wrap_s, WRAP_MODES)
        self._wrap_t = choose("wrap" if wrap_t is None else "wrap_t", self.wrap_t, WRAP_MODES)
        self._filter = choose("filter", filter, FILTERS)
        if isinstance(source, (str, os.PathLike)):
            self.source = os.fspath(source)
            level0 = load_image(source, max_bytes, srgb=self.srgb)
        elif isinstance(source, np.ndarray):
            self.source = "array"
            if source.ndim >= 2:
                check_size(f"the array of shape {source.shape}", source.shape[1], source.shape[0], max_bytes)
            level0 = check_array(source, srgb=self.srgb)
        else:
            raise TypeError(
                "Texture2D: source must be an image file path or a numpy array, "
                f"got {type(source).__name__}"
            )
        self.levels = build_mipmaps(level0)
        for lv in self.levels:
            lv.flags.writeable = False
        self.height, self.width = level0.shape[:2]
        self._uniform = self._pack()

    @classmethod
    def from_framebuffer(cls, framebuffer, **options) -> "Texture2D":
        """Render to texture: a framebuffer's (resolved) color as a texture, ``options`` as the constructor's.

        The framebuffer's top row becomes the image's top row, so texture coordinate
        v = 0 is the framebuffer's bottom row (window row 0), as in OpenGL.
        """
        return cls(np.ascontiguousarray(framebuffer.resolve()), **options)

    def _pack(self) -> TextureUniform:
        widths = np.array([lv.shape[1] for lv in self.levels], dtype=np.int64)
        heights = np.array([lv.shape[0] for lv in self.levels], dtype=np.int64)
        counts = widths * heights
        offsets = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
        texels = np.concatenate([lv.reshape(-1, 4) for lv in self.levels])
        for a in (texels, widths, heights, offsets):
            a.flags.writeable = False  # shared by every draw that uses the texture
        return TextureUniform(texels, widths, heights, offsets, self._wrap_s, self._wrap_t, self._filter)

    def __softpipe_uniform__(self) -> TextureUniform:
        """The value a shader receives for this texture (built once; arrays are read-only)."""
        return self._uniform

    @property
    def num_levels(self) -> int:
        """Number of mip levels, ``floor(log2(max(width, height))) + 1``."""
        return len(self.levels)

    def sample(self, u: float, v: float, lod: float = 0.0) -> RGBA:
        """Sample at (u, v) and level of detail ``lod`` from plain Python.

        Runs the same code as :func:`texture_lod` in a shader, so it is the
        easy way to look at what a shader would get.
        """
        return texture_lod(self._uniform, (float(u), float(v)), float(lod))

    def __repr__(self) -> str:
        wrap = self.wrap_s if self.wrap_s == self.wrap_t else f"({self.wrap_s}, {self.wrap_t})"
        return (
            f"Texture2D({self.source!r}, {self.width}×{self.height}, {self.num_levels} levels, "
            f"wrap={wrap}, filter={self.filter}{', srgb' if self.srgb else ''})"
        )
