"""Random numbers and sample warps for Monte Carlo rendering (the path tracer, :mod:`.pathtrace`).

:func:`uniform` is a *counter-based* random number: a hash of (seed, pixel,
sample, dimension), not the next value of a stream. So a pixel's samples are the
same whichever thread computes them, in whatever order and however the image is
split into bands, and sample k of a pixel is the same whether it is rendered in
the first call or in a later :meth:`~softpipe.tracers.pathtrace.PathTrace.add`:
the image is a function of the seed alone (docs/pathtracing.md, "Random numbers").

The hash is splitmix64's finalizer (Steele, Lea and Flood 2014), a bijection of
64-bit words that mixes every input bit into every output bit, applied once per key
word; a sample hashes its first three words once (:func:`sample_key`) and each of its
numbers adds the last (:func:`uniform_of`), the same bits as :func:`uniform`. The warps turn uniform numbers in [0, 1) into the distributions the tracer
draws from: a cosine-weighted direction about a normal (pdf cos θ/π), a uniform
point on a triangle (pdf 1/area), and an orthonormal basis around a normal.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["uniform", "sample_key", "uniform_of", "cosine_hemisphere", "triangle_point", "basis"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)       # 2⁶⁴/φ: keeps a zero key word from mapping to zero
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_TO_UNIT = 2.0 ** -53


@njit(cache=True, forceinline=True)
def _mix(x):
    """splitmix64's finalizer: a bijection of uint64 with full avalanche."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@njit(cache=True, nogil=True)
def uniform(seed, pixel, sample, dimension):
    """A uniform number in [0, 1) that is a function of (seed, pixel, sample, dimension) only.

    Each argument is a whole number ≥ 0 (seed below 2⁶⁴); the 53 high bits of the
    hash become the float's mantissa, so the value is a multiple of 2⁻⁵³.
    ``uniform_of(sample_key(seed, pixel, sample), dimension)`` is the same number.
    """
    return uniform_of(sample_key(seed, pixel, sample), dimension)


@njit(cache=True, nogil=True, forceinline=True)
def sample_key(seed, pixel, sample):
    """The hash of (seed, pixel, sample): the first three of :func:`uniform`'s four key words, mixed.

    A sample draws all its numbers from one key (:func:`uniform_of`), so the three
    mixes it shares are done once per sample instead of once per number.
    """
    h = _mix(np.uint64(seed) + _GOLDEN)
    h = _mix(h ^ (np.uint64(pixel) + _GOLDEN))
    return _mix(h ^ (np.uint64(sample) + _GOLDEN))


@njit(cache=True, nogil=True, forceinline=True)
def uniform_of(key, dimension):
    """:func:`uniform` of the sample whose :func:`sample_key` is ``key``, at ``dimension``: the same bits."""
    h = _mix(key ^ (np.uint64(dimension) + _GOLDEN))
    return float(h >> _S11) * _TO_UNIT


@njit(cache=True, forceinline=True)
def basis(n):
    """Two unit vectors (t, b) with (t, b, n) a right-handed orthonormal basis; n unit.

    Duff et al. 2017, "Building an orthonormal basis, revisited": no branch but the sign.
    """
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    bt = (b, sign + n[1] * n[1] * a, -n[1])
    return t, bt


@njit(cache=True, forceinline=True)
def cosine_hemisphere(n, u1, u2):
    """A unit direction about the unit normal n with pdf cos θ / π (Malley's method): (direction, cos θ).

    A uniform point on the unit disk (r = √u1, φ = 2π·u2) lifted to the hemisphere.
    """
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    x, y = r * math.cos(phi), r * math.sin(phi)
    z = math.sqrt(max(0.0, 1.0 - u1))
    t, b = basis(n)
    return (x * t[0] + y * b[0] + z * n[0], x * t[1] + y * b[1] + z * n[1], x * t[2] + y * b[2] + z * n[2]), z


@njit(cache=True, forceinline=True)
def triangle_point(v0, v1, v2, u1, u2):
    """A uniform point on the triangle (v0, v1, v2): pdf 1/area over its surface.

    Barycentrics (1 − √u1, √u1·(1 − u2), √u1·u2), the square root making the density even.
    """
    s = math.sqrt(u1)
    b0, b1, b2 = 1.0 - s, s * (1.0 - u2), s * u2
    return (b0 * v0[0] + b1 * v1[0] + b2 * v2[0], b0 * v0[1] + b1 * v1[1] + b2 * v2[1],
            b0 * v0[2] + b1 * v1[2] + b2 * v2[2])
