"""Cube maps: six square textures around a point, looked up by direction, seamless at the edges.

A cube map answers "what is seen from here in direction d?": six square images on
the faces of a cube around the point, in GL's order +x, −x, +y, −y, +z, −z
(``FACES``). The lookup picks the face d points at (its major axis) and the texel
where d pierces it, by OpenGL 4.6 §8.13's Table 8.19; row 0 of a face is its top
row and nothing is flipped (RenderMan's convention, which GL kept). It is the
environment of a mirror or a glass object in a rasterizer
(:mod:`softpipe.programs.environment`); a dynamic one is the scene drawn six times
from a point (:func:`softpipe.scenes.environment_pass.render_cube_map`).

Two halves, as :mod:`softpipe.light.texture`: :class:`CubeMap` is the host side
(six images, one equirectangular panorama or a function of the direction → six
float32 RGBA faces with mip pyramids, packed by ``__softpipe_uniform__`` into a
:class:`CubeUniform`); :func:`texture_cube`, :func:`texture_cube_lod` and
:func:`texture_cube_grad` are the shader side (GLSL's ``texture(samplerCube, d)``,
``textureLod``, ``textureGrad``), plain Python under ``NUMBA_DISABLE_JIT=1``.

Seamless: every face, at every mip level, is stored with a 1-texel border copied
from its neighbours (a corner is the mean of the three texels that meet there, as
GL's ``TEXTURE_CUBE_MAP_SEAMLESS``), so every bilinear tap is a stored texel and no
lookup wraps or clamps; interpolation is GLSL's ``mix``, so a constant environment
samples to its color exactly. ``filter`` is :mod:`softpipe.light.texture`'s.

:data:`MEDIA` (:data:`softpipe.light.material.MEDIA`, here too): the notes' indices
of refraction (FORMULAS §17); ``Material(ior="glass")`` takes the names.

docs/environment.md has the face table, the borders, the levels and filters, the
panorama's formulas, and the dynamic maps.
"""
from __future__ import annotations

import math
import os
from collections import namedtuple
from typing import Callable, Optional, Sequence, Tuple, Union

import numpy as np
from numba import njit

from softpipe.language.glsl import mix
from softpipe.light.images import (
    MAX_TEXTURE_BYTES,
    PEAK_BYTES_PER_TEXEL,
    build_mipmaps,
    check_array,
    check_size,
    choose,
    load_image,
    texture_bytes,
)
from softpipe.light.material import MEDIA
from softpipe.light.texture import (
    FILTER_BILINEAR,
    FILTER_NEAREST,
    FILTER_NEAREST_MIPMAP,
    FILTERS,
)

__all__ = ["CubeMap", "CubeUniform", "texture_cube", "texture_cube_lod", "texture_cube_grad", "cube_level_of_detail",
           "face_coordinates", "FACES", "MEDIA",
           "sample_directions", "sky", "sky_gradient", "equirectangular_lookup", "texel_directions"]

#: The faces in GL's order (the index a :class:`CubeUniform` and :func:`face_coordinates` use).
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")


#: The colors of :func:`sky`: straight up, at the horizon, and the ground below it.
SKY_ZENITH = (0.18, 0.36, 0.75)
SKY_HORIZON = (0.80, 0.85, 0.92)
SKY_GROUND = (0.30, 0.27, 0.24)


@njit(cache=True)
def sky(direction):
    """A simple sky in world space (+y up), RGB: horizon to zenith by √y above, to the ground within y > −¼ below.

    What ``mirror`` and ``glass`` reflect when a draw gives no ``environment``;
    :func:`sky_gradient` is the same for arrays (to make a panorama or a cube map of it).
    """
    x, y, z = float(direction[0]), float(direction[1]), float(direction[2])
    n = math.sqrt(x * x + y * y + z * z)
    y = y / n if n > 0.0 else 0.0
    if y >= 0.0:
        a = math.sqrt(y)
        return (SKY_HORIZON[0] + a * (SKY_ZENITH[0] - SKY_HORIZON[0]),
                SKY_HORIZON[1] + a * (SKY_ZENITH[1] - SKY_HORIZON[1]),
                SKY_HORIZON[2] + a * (SKY_ZENITH[2] - SKY_HORIZON[2]))
    a = min(1.0, -4.0 * y) if y == y else 0.0
    return (SKY_HORIZON[0] + a * (SKY_GROUND[0] - SKY_HORIZON[0]),
            SKY_HORIZON[1] + a * (SKY_GROUND[1] - SKY_HORIZON[1]),
            SKY_HORIZON[2] + a * (SKY_GROUND[2] - SKY_HORIZON[2]))


def sky_gradient(directions) -> np.ndarray:
    """:func:`sky` for directions [..., 3] → RGB [..., 3] (float64)."""
    d = np.asarray(directions, np.float64)
    n = np.linalg.norm(d, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        y = np.where(n > 0, d[..., 1] / np.where(n > 0, n, 1.0), 0.0)
    up = np.sqrt(np.clip(y, 0.0, None))[..., None]
    down = np.clip(-4.0 * y, 0.0, 1.0)[..., None]
    horizon, zenith, ground = (np.array(c) for c in (SKY_HORIZON, SKY_ZENITH, SKY_GROUND))
    return np.where((y >= 0)[..., None], horizon + up * (zenith - horizon), horizon + down * (ground - horizon))


CubeUniform = namedtuple("CubeUniform", ["texels", "size", "levels", "filter"])
CubeUniform.__doc__ = """What a shader receives for a :class:`CubeMap`: one array and three ints.

Fields
------
texels : float32 array [total, 4]
    Every level, level 0 first; within a level the six faces in GL's order, each
    (n + 2) × (n + 2) texels (the face and its 1-texel border), row-major, row 0
    the border above the face's top row (t < 0). Level k starts at
    ``Σ_{i<k} 6·(n_i + 2)²`` with n_0 = ``size`` and n_{i+1} = max(1, n_i // 2).
size : int
    n_0, the width of a face at level 0.
levels : int
    Number of mip levels.
filter : int
    :data:`softpipe.light.texture.FILTERS`' code.

One array, not one per level or face: numba counts a reference for every array
a call is handed, so fewer arrays make a lookup cheaper.
"""


# --------------------------------------------------------------------------
# Shader side
# --------------------------------------------------------------------------

@njit(cache=True, forceinline=True)
def _select(x, y, z):
    """(face, s, t) of a direction (the table in the module docstring); face 0's centre for 0 or NaN."""
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax >= ay and ax >= az:
        ma = ax
        if x > 0.0:
            face, sc, tc = 0, -z, -y
        else:
            face, sc, tc = 1, z, -y
    elif ay >= az:
        ma = ay
        if y > 0.0:
            face, sc, tc = 2, x, z
        else:
            face, sc, tc = 3, x, -z
    else:
        ma = az
        if z > 0.0:
            face, sc, tc = 4, x, -y
        else:
            face, sc, tc = 5, -x, -y
    if not (ma > 0.0) or ma == math.inf:      # zero, NaN or infinite: undefined in GL; face +x's centre here
        return 0, 0.5, 0.5
    s = 0.5 * (sc / ma + 1.0)
    t = 0.5 * (tc / ma + 1.0)
    # |sc|, |tc| ≤ |ma| by the choice of face; the clamps only catch NaN components
    s = min(max(s, 0.0), 1.0) if s == s else 0.5
    t = min(max(t, 0.0), 1.0) if t == t else 0.5
    return face, s, t


@njit(cache=True, forceinline=True)
def _level(size, k):
    """(first texel, face width n) of level k."""
    offset = 0
    n = size
    for _ in range(k):
        offset += 6 * (n + 2) * (n + 2)
        n = max(1, n // 2)
    return offset, n


@njit(cache=True, forceinline=True)
def _texel(texels, k):
    return (float(texels[k, 0]), float(texels[k, 1]), float(texels[k, 2]), float(texels[k, 3]))


@njit(cache=True)
def _face_bilinear(texels, base, n, s, t):
    """GL LINEAR on one bordered face: the 2×2 texels around (s, t), seamless through the border."""
    m = n + 2
    x = s * n + 0.5            # (s·n − ½) in face texels, + 1 for the border
    y = t * n + 0.5
    i0 = min(int(math.floor(x)), n)
    j0 = min(int(math.floor(y)), n)
    a = x - i0
    b = y - j0
    k = base + j0 * m + i0
    top = mix(_texel(texels, k), _texel(texels, k + 1), a)
    bottom = mix(_texel(texels, k + m), _texel(texels, k + m + 1), a)
    return mix(top, bottom, b)


@njit(cache=True)
def _face_nearest(texels, base, n, s, t):
    """GL NEAREST on one bordered face."""
    i = min(int(s * n), n - 1) + 1
    j = min(int(t * n), n - 1) + 1
    return _texel(texels, base + j * (n + 2) + i)


@njit(cache=True, forceinline=True)
def _sample_cube(cube, direction, lod):
    face, s, t = _select(float(direction[0]), float(direction[1]), float(direction[2]))
    texels = cube.texels
    f = cube.filter
    size = cube.size
    if f == FILTER_NEAREST:
        return _face_nearest(texels, face * (size + 2) * (size + 2), size, s, t)
    if f == FILTER_BILINEAR:
        return _face_bilinear(texels, face * (size + 2) * (size + 2), size, s, t)
    top = cube.levels - 1
    lam = float(lod)
    if not (lam > 0.0):          # magnification, and NaN: level 0
        lam = 0.0
    if lam > top:
        lam = float(top)
    if f == FILTER_NEAREST_MIPMAP:
        offset, n = _level(size, int(math.ceil(lam + 0.5)) - 1)
        return _face_nearest(texels, offset + face * (n + 2) * (n + 2), n, s, t)
    d = int(math.floor(lam))
    frac = lam - d
    offset, n = _level(size, d)
    near = _face_bilinear(texels, offset + face * (n + 2) * (n + 2), n, s, t)
    if frac == 0.0:
        return near
    offset += 6 * (n + 2) * (n + 2)
    n = max(1, n // 2)
    far = _face_bilinear(texels, offset + face * (n + 2) * (n + 2), n, s, t)
    return mix(near, far, frac)


@njit(cache=True)
def texture_cube(cube, direction):
    """Sample a cube map in ``direction`` at level 0 (GLSL ``texture(samplerCube, d)``).

    Parameters
    ----------
    cube : CubeUniform
        The uniform of a :class:`CubeMap`.
    direction : (float, float, float)
        Any length but 0 (a zero or NaN direction reads face +x's centre).

    Returns
    -------
    (float, float, float, float)
        RGBA, bilinear (or nearest) on the face the direction selects, seamless across edges.
    """
    return _sample_cube(cube, direction, 0.0)


@njit(cache=True)
def texture_cube_lod(cube, direction, lod):
    """Sample at level of detail λ = ``lod`` (GLSL ``textureLod(samplerCube, d, λ)``).

    λ is clamped to [0, levels − 1]; ``"trilinear"`` mixes levels ⌊λ⌋ and ⌊λ⌋ + 1.
    ``"nearest"`` and ``"bilinear"`` cube maps ignore it.
    """
    return _sample_cube(cube, direction, lod)


@njit(cache=True, forceinline=True)
def _face_st_derivative(face, d, dd):
    """(∂s, ∂t) of the face coordinates when the direction d moves by dd, on d's face (GL 4.6 §8.13.4).

    s = ½(sc/|ma| + 1): ∂s = ½(∂sc·ma − sc·∂ma)/ma², with sc, tc, ma the components the
    table picks for the face (signs included), the same for t.
    """
    x, y, z = d[0], d[1], d[2]
    dx, dy, dz = dd[0], dd[1], dd[2]
    if face == 0:
        sc, tc, ma, dsc, dtc, dma = -z, -y, x, -dz, -dy, dx
    elif face == 1:
        sc, tc, ma, dsc, dtc, dma = z, -y, -x, dz, -dy, -dx
    elif face == 2:
        sc, tc, ma, dsc, dtc, dma = x, z, y, dx, dz, dy
    elif face == 3:
        sc, tc, ma, dsc, dtc, dma = x, -z, -y, dx, -dz, -dy
    elif face == 4:
        sc, tc, ma, dsc, dtc, dma = x, -y, z, dx, -dy, dz
    else:
        sc, tc, ma, dsc, dtc, dma = -x, -y, -z, -dx, -dy, -dz
    m2 = ma * ma
    if not (m2 > 0.0):
        return 0.0, 0.0
    return 0.5 * (dsc * ma - sc * dma) / m2, 0.5 * (dtc * ma - tc * dma) / m2


@njit(cache=True)
def cube_level_of_detail(cube, direction, ddx, ddy):
    """λ for a lookup in ``direction`` whose screen-space derivatives are ``ddx``, ``ddy`` (GL 4.6 §8.14.1).

    λ = log₂ ρ, ρ = size · max(|∂(s, t)/∂x|, |∂(s, t)/∂y|): how many level-0 texels one pixel
    step crosses on the face the direction selects. Below 0 (magnification) the
    lookup takes level 0; zero derivatives give −inf, level 0 too.
    """
    face, _, _ = _select(float(direction[0]), float(direction[1]), float(direction[2]))
    sx, tx = _face_st_derivative(face, direction, ddx)
    sy, ty = _face_st_derivative(face, direction, ddy)
    rho = cube.size * max(math.sqrt(sx * sx + tx * tx), math.sqrt(sy * sy + ty * ty))
    if not (rho > 0.0):
        return -math.inf
    return math.log2(rho)


@njit(cache=True)
def texture_cube_grad(cube, direction, ddx, ddy):
    """Sample with the level of detail of the derivatives (GLSL ``textureGrad(samplerCube, d, ddx, ddy)``)."""
    return _sample_cube(cube, direction, cube_level_of_detail(cube, direction, ddx, ddy))


@njit(cache=True)
def _sample_many(cube, directions, lod, out):
    for k in range(directions.shape[0]):
        c = _sample_cube(cube, (directions[k, 0], directions[k, 1], directions[k, 2]), lod)
        out[k, 0] = c[0]
        out[k, 1] = c[1]
        out[k, 2] = c[2]
        out[k, 3] = c[3]


def sample_directions(cube, directions, lod: float = 0.0) -> np.ndarray:
    """:func:`texture_cube_lod` at many directions [..., 3] at once → float64 RGBA [..., 4]."""
    uniform = cube.__softpipe_uniform__() if hasattr(cube, "__softpipe_uniform__") else cube
    d = np.asarray(directions, np.float64)
    flat = np.ascontiguousarray(d.reshape(-1, 3))
    out = np.empty((len(flat), 4), np.float64)
    _sample_many(uniform, flat, float(lod), out)
    return out.reshape(d.shape[:-1] + (4,))


# --------------------------------------------------------------------------
# Host side: the table, vectorized
# --------------------------------------------------------------------------

def face_coordinates(directions) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face, s, t) of directions [..., 3] by GL's table (the module docstring), as the shaders compute them."""
    d = np.asarray(directions, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    on_x = (ax >= ay) & (ax >= az)
    on_y = ~on_x & (ay >= az)
    face = np.where(on_x, np.where(x > 0, 0, 1), np.where(on_y, np.where(y > 0, 2, 3), np.where(z > 0, 4, 5)))
    sc = np.choose(face, [-z, z, x, x, x, -x])
    tc = np.choose(face, [-y, -y, z, -z, -y, -y])
    ma = np.where(on_x, ax, np.where(on_y, ay, az))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = 0.5 * (sc / ma + 1.0)
        t = 0.5 * (tc / ma + 1.0)
    bad = ~(ma > 0) | ~np.isfinite(ma)
    face = np.where(bad, 0, face)
    s = np.where(bad | np.isnan(s), 0.5, np.clip(s, 0.0, 1.0))
    t = np.where(bad | np.isnan(t), 0.5, np.clip(t, 0.0, 1.0))
    return face.astype(np.int64), s, t


def _face_direction(face, s, t) -> np.ndarray:
    """Directions [..., 3] (not normalized) of face coordinates (s, t); the table backwards."""
    face = np.asarray(face)
    sc = 2.0 * np.asarray(s, np.float64) - 1.0
    tc = 2.0 * np.asarray(t, np.float64) - 1.0
    one = np.ones(np.broadcast(face, sc, tc).shape)
    sc, tc, face = sc * one, tc * one, (face * one).astype(np.int64)
    x = np.choose(face, [one, -one, sc, sc, sc, -sc])
    y = np.choose(face, [-tc, -tc, one, -one, -tc, -tc])
    z = np.choose(face, [-sc, sc, tc, -tc, one, -one])
    return np.stack([x, y, z], axis=-1)


def texel_directions(size: int) -> np.ndarray:
    """Unit directions [6, size, size, 3] through the centre of every texel (face, row, column) of level 0."""
    centres = (np.arange(size) + 0.5) / size
    t, s = np.meshgrid(centres, centres, indexing="ij")
    d = np.stack([_face_direction(f, s, t) for f in range(6)])
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _bordered(faces: np.ndarray) -> np.ndarray:
    """Six faces [6, n, n, 4] → [6, n + 2, n + 2, 4] with each border copied from the neighbouring faces."""
    n = faces.shape[1]
    out = np.zeros((6, n + 2, n + 2, 4), np.float32)
    out[:, 1:-1, 1:-1] = faces
    k = np.arange(n)
    edge = [(np.full(n, -1), k), (np.full(n, n), k), (k, np.full(n, -1)), (k, np.full(n, n))]   # (rows, cols)
    for f in range(6):
        for rows, cols in edge:
            # the texel centre beyond the edge lies off the face, on the neighbour's side of the cube's edge
            d = _face_direction(f, (cols + 0.5) / n, (rows + 0.5) / n)
            g, s, t = face_coordinates(d)
            assert np.all(g != f)
            out[f, rows + 1, cols + 1] = faces[g, np.minimum((t * n).astype(np.int64), n - 1),
                                               np.minimum((s * n).astype(np.int64), n - 1)]
        for r, c, dr, dc in ((0, 0, 1, 1), (0, n + 1, 1, -1), (n + 1, 0, -1, 1), (n + 1, n + 1, -1, -1)):
            three = out[f, [r + dr, r, r + dr], [c + dc, c + dc, c]].astype(np.float64)
            out[f, r, c] = (three.sum(axis=0) / 3.0).astype(np.float32)
    return out


def _as_face(source, k: int, max_bytes) -> np.ndarray:
    if isinstance(source, (str, os.PathLike)):
        return load_image(source, max_bytes)
    a = np.asarray(source)
    if a.ndim >= 2:
        check_size(f"face {FACES[k]} (shape {a.shape})", a.shape[1], a.shape[0], max_bytes)
    return check_array(a)


def _face_size(func: str, size, max_bytes: Optional[int]) -> int:
    """``size`` as a face width: an integer ≥ 1 whose faces fit the image budget, checked before anything
    is allocated (:func:`softpipe.light.images.texture_bytes`, per face, as :class:`CubeMap` checks them)."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise ValueError(f"CubeMap.{func}: size must be an integer ≥ 1 (the face width in texels), got {size!r}")
    size = int(size)
    limit = MAX_TEXTURE_BYTES if max_bytes is None else max_bytes
    need = texture_bytes(size, size)
    if need > limit:
        raise ValueError(f"CubeMap.{func}: size={size} makes six {size}×{size} faces, each needing about "
                         f"{need / 2**30:.1f} GiB while its mipmaps are made ({PEAK_BYTES_PER_TEXEL} bytes a texel), "
                         f"more than the limit of {limit / 2**30:.1f} GiB a face: give a smaller size (at most "
                         f"{math.isqrt(limit // PEAK_BYTES_PER_TEXEL)}), or raise max_bytes=... "
                         "(softpipe.light.images.MAX_TEXTURE_BYTES)")
    return size


class CubeMap:
    """Six square RGBA faces with mip pyramids, sampled by direction (the module docstring has the conventions).

    Parameters
    ----------
    faces : sequence of six images
        +x, −x, +y, −y, +z, −z (GL's order), each an image file or an array [n, n],
        [n, n, 3] or [n, n, 4] (uint8 scaled by 1/255, floats taken as they are), all
        the same size; row 0 of each is its top row, t = 0 (GL's table).
    filter : {"nearest", "bilinear", "nearest_mipmap", "trilinear"}
        As :class:`~softpipe.light.texture.Texture2D`'s; default ``"trilinear"``.
    max_bytes : int, optional
        As :class:`~softpipe.light.texture.Texture2D`'s, per face.

    Attributes
    ----------
    size : int
        Face width at level 0.
    levels : list of float32 arrays [6, n, n, 4]
        The faces at every level (no borders), read-only.
    """

    def __init__(self, faces: Sequence[Union[str, os.PathLike, np.ndarray]], *, filter: str = "trilinear",
                 max_bytes: Optional[int] = None) -> None:
        faces = list(faces)
        if len(faces) != 6:
            raise ValueError(f"CubeMap: needs six faces (+x, -x, +y, -y, +z, -z), got {len(faces)}")
        self.filter = filter
        self._filter = choose("filter", filter, FILTERS)
        level0 = [_as_face(f, k, max_bytes) for k, f in enumerate(faces)]
        n = level0[0].shape[0]
        for k, f in enumerate(level0):
            if f.shape[:2] != (n, n):
                raise ValueError(f"CubeMap: every face must be square and the same size; face {FACES[k]} is "
                                 f"{f.shape[1]}×{f.shape[0]}, face +x {level0[0].shape[1]}×{n}")
        pyramids = [build_mipmaps(f) for f in level0]
        self.levels = [np.stack([p[k] for p in pyramids]) for k in range(len(pyramids[0]))]
        for lv in self.levels:
            lv.flags.writeable = False
        self.size = n
        texels = np.concatenate([_bordered(lv).reshape(-1, 4) for lv in self.levels])
        texels.flags.writeable = False
        self._uniform = CubeUniform(texels, n, len(self.levels), self._filter)

    # ------------------------------------------------------------------ other sources

    @classmethod
    def from_function(cls, function: Callable[[np.ndarray], np.ndarray], size: int, **options) -> "CubeMap":
        """A cube map whose texel is ``function(d)`` at its centre's unit direction d.

        ``function`` takes unit directions [..., 3] and returns colors [..., 3] or [..., 4].
        ``size`` (the face width) is checked against the image budget before any texel is made.
        """
        d = texel_directions(_face_size("from_function", size, options.get("max_bytes")))
        colors = np.asarray(function(d), np.float64)
        return cls(list(colors), **options)

    @classmethod
    def from_equirectangular(cls, image, size: Optional[int] = None, **options) -> "CubeMap":
        """A cube map from a latitude-longitude panorama (an image file or an array [H, W(, C)]).

        Each face texel is the panorama sampled bilinearly (wrapping in longitude,
        clamped in latitude) in the direction of the texel's centre; the mapping is the
        module docstring's. ``size`` is the face width (default W/4, at least 1), checked
        against the image budget (``max_bytes``, per face) before the panorama is read.
        """
        if size is not None:
            size = _face_size("from_equirectangular", size, options.get("max_bytes"))
        if isinstance(image, (str, os.PathLike)):
            pano = load_image(image, options.get("max_bytes"))
        else:
            pano = check_array(image)
        h, w = pano.shape[:2]
        size = max(1, w // 4) if size is None else size
        return cls.from_function(lambda d: equirectangular_lookup(pano, d), size, **options)

    # ------------------------------------------------------------------ shader and Python access

    def __softpipe_uniform__(self) -> CubeUniform:
        """The value a shader receives (built once; the array is read-only)."""
        return self._uniform

    @property
    def num_levels(self) -> int:
        return len(self.levels)

    @staticmethod
    def direction(face: Union[int, str], s, t) -> np.ndarray:
        """The unit direction through (s, t) of a face (an index or ``"+x"`` …): GL's table backwards."""
        f = FACES.index(face) if isinstance(face, str) else int(face)
        d = _face_direction(f, s, t)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def sample(self, direction, lod: float = 0.0):
        """RGBA in ``direction`` at level ``lod`` from plain Python (the shaders' own function)."""
        return texture_cube_lod(self._uniform, tuple(float(v) for v in direction), float(lod))

    def sample_many(self, directions, lod: float = 0.0) -> np.ndarray:
        """RGBA [..., 4] for directions [..., 3] (:func:`sample_directions`)."""
        return sample_directions(self._uniform, directions, lod)

    def cross(self, size: Optional[int] = None, level: float = 0.0) -> np.ndarray:
        """The cube unfolded as seen from inside, float32 RGBA [3·size, 4·size, 4]: a horizontal cross.

        Middle row, left to right: −x, −z, +x, +z (turning right from looking along −z);
        +y above −z, −y below it; the rest is black with alpha 0. Every picture reads as
        a camera with +y up would see it, and neighbouring squares join without seams.
        """
        n = self.size if size is None else int(size)
        a = (np.arange(n) + 0.5) / n * 2.0 - 1.0            # left → right
        b = -a                                                # top → bottom: up is +
        B, A = np.meshgrid(b, a, indexing="ij")
        one = np.ones_like(A)
        squares = {(1, 0): (-one, B, -A), (1, 1): (A, B, -one), (1, 2): (one, B, A), (1, 3): (-A, B, one),
                   (0, 1): (A, one, B), (2, 1): (A, -one, -B)}
        out = np.zeros((3 * n, 4 * n, 4), np.float32)
        for (r, c), (x, y, z) in squares.items():
            out[r * n:(r + 1) * n, c * n:(c + 1) * n] = self.sample_many(np.stack([x, y, z], -1), level)
        return out

    def __repr__(self) -> str:
        return f"CubeMap({self.size}×{self.size} ×6, {self.num_levels} levels, filter={self.filter})"


def equirectangular_lookup(pano: np.ndarray, directions) -> np.ndarray:
    """A panorama [H, W, C] sampled bilinearly at unit directions [..., 3] (module docstring's mapping) → [..., C]."""
    d = np.asarray(directions, np.float64)
    h, w = pano.shape[:2]
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    x = u * w - 0.5
    y = v * h - 0.5
    i0 = np.floor(x).astype(np.int64)
    j0 = np.floor(y).astype(np.int64)
    a = (x - i0)[..., None]
    b = (y - j0)[..., None]
    i1 = (i0 + 1) % w
    i0 = i0 % w
    j1 = np.clip(j0 + 1, 0, h - 1)
    j0 = np.clip(j0, 0, h - 1)
    p = pano.astype(np.float64)
    top = p[j0, i0] + a * (p[j0, i1] - p[j0, i0])
    bottom = p[j1, i0] + a * (p[j1, i1] - p[j1, i0])
    return top + b * (bottom - top)
