"""A small GLSL-like math library on tuples, for shaders.

Small vectors are tuples of floats: ``vec2 = (x, y)``, ``vec3 = (x, y, z)``,
``vec4 = (x, y, z, w)``; matrices are 4×4 (or 3×3) float64 numpy arrays acting on
column vectors, ``p' = M @ p`` (docs/design.md). Every function here has the same
name, meaning and results called from plain Python, inside ``@njit`` code
(kernels and shaders, ``cache=True`` included), and under ``NUMBA_DISABLE_JIT=1``.

Why it is shaped so: numba cannot build a tuple whose length depends on a loop, so
each function is written once in plain Python and numba is given an implementation
of the same name. Componentwise functions (``add``, ``mul``, ``clamp``, ``mix``, …)
are written as their *scalar* formula under :func:`_componentwise`, which maps it
over the components in Python and registers (``numba.extending.overload``) one
implementation per argument kinds and length 2, 3 or 4, a scalar broadcast as in
GLSL; the reductions (``hsum``, ``max_component``, ``min_component``) likewise;
everything else (``dot``, ``normalize``, ``reflect``, ``refract``, the matrix
helpers, …) is ordinary code on those, ``register_jitable``. Both paths do the same
floating-point operations in the same order: bit-identical results (tested), and
compiled kernels of straight-line code with every call inlined and no allocation.

Where GLSL leaves a case undefined, softpipe defines it: ``normalize`` of a zero or
NaN vector is the zero vector; ``pow_(x, y)`` takes x ≤ 0 as 0 (0⁰ = 1);
``smoothstep`` with e0 = e1 is the step at e0; ``clamp`` of NaN is ``lo``. Use
floats in vectors (an int tuple compiles a second specialization).

numba decides whether a cached kernel is stale from the kernel's own source file
only: after editing *this* file, delete the callers' ``__pycache__/*.nbi/*.nbc``.
docs/shaders.md ("The math library") has it at length.
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Optional, Tuple, Union

from numba import types
from numba.core.errors import TypingError
from numba.extending import overload, register_jitable

if TYPE_CHECKING:  # only for the annotations
    import numpy as np

Vec2 = Tuple[float, float]
Vec3 = Tuple[float, float, float]
Vec4 = Tuple[float, float, float, float]
Vec = Union[Vec2, Vec3, Vec4]
VecOrScalar = Union[float, Vec]

__all__ = [
    "vec2", "vec3", "vec4",
    "add", "sub", "mul", "div", "scale", "neg",
    "dot", "cross", "length", "distance", "normalize", "faceforward",
    "reflect", "refract",
    "mix", "clamp", "saturate", "step", "smoothstep", "pow_",
    "vmin", "vmax", "vabs", "hsum", "max_component", "min_component",
    "mat4_mul_vec4", "mat3_mul_vec3",
]

_LENGTHS = (2, 3, 4)


# --------------------------------------------------------------------------
# Machinery: from a scalar formula to a function on numbers and vec2/3/4.
# --------------------------------------------------------------------------

def _py_vector_length(name: str, args) -> int:
    """Common tuple length of ``args`` (0 if all are scalars), as in Python."""
    n = 0
    for a in args:
        if isinstance(a, tuple):
            if len(a) not in _LENGTHS:
                raise TypeError(f"{name}: vectors must have 2, 3 or 4 components, got {a!r}")
            if n and len(a) != n:
                raise TypeError(f"{name}: vectors of different lengths ({n} and {len(a)})")
            n = len(a)
    return n


def _nb_vector_length(name: str, ty) -> int:
    """0 for a numba number type, 2/3/4 for a tuple of numbers; else a typing error."""
    if isinstance(ty, types.Number):
        return 0
    if (isinstance(ty, types.BaseTuple) and len(ty.types) in _LENGTHS
            and all(isinstance(t, types.Number) for t in ty.types)):
        return len(ty.types)
    raise TypingError(f"softpipe.language.glsl.{name}: expected a number or a vec2/vec3/vec4 "
                      f"tuple of numbers, got {ty}")


def _nb_common_length(name: str, *tys) -> int:
    n = 0
    for ty in tys:
        m = _nb_vector_length(name, ty)
        if m and n and m != n:
            raise TypingError(f"softpipe.language.glsl.{name}: vectors of different lengths ({n} and {m})")
        n = n or m
    return n


@register_jitable
def _splat2(s):
    return (s, s)


@register_jitable
def _splat3(s):
    return (s, s, s)


@register_jitable
def _splat4(s):
    return (s, s, s, s)


@register_jitable
def _same(v):
    return v


_SPLAT = {2: _splat2, 3: _splat3, 4: _splat4}


def _as_vector(ty, n: int):
    """The jitable function that turns an argument of type ``ty`` into an n-tuple."""
    return _same if _nb_vector_length("", ty) else _SPLAT[n]


# The numba implementations, written out per length so that numba sees plain
# tuple constructions (no loops, no allocation). f is the scalar formula; X, Y, Z
# turn each argument into a tuple of the common length (broadcasting scalars).

def _impl_1(f, n):
    if n == 0:
        def impl(a):
            return f(a)
    elif n == 2:
        def impl(a):
            return (f(a[0]), f(a[1]))
    elif n == 3:
        def impl(a):
            return (f(a[0]), f(a[1]), f(a[2]))
    else:
        def impl(a):
            return (f(a[0]), f(a[1]), f(a[2]), f(a[3]))
    return impl


def _impl_2(f, n, X, Y):
    if n == 0:
        def impl(a, b):
            return f(a, b)
    elif n == 2:
        def impl(a, b):
            x, y = X(a), Y(b)
            return (f(x[0], y[0]), f(x[1], y[1]))
    elif n == 3:
        def impl(a, b):
            x, y = X(a), Y(b)
            return (f(x[0], y[0]), f(x[1], y[1]), f(x[2], y[2]))
    else:
        def impl(a, b):
            x, y = X(a), Y(b)
            return (f(x[0], y[0]), f(x[1], y[1]), f(x[2], y[2]), f(x[3], y[3]))
    return impl


def _impl_3(f, n, X, Y, Z):
    if n == 0:
        def impl(a, b, c):
            return f(a, b, c)
    elif n == 2:
        def impl(a, b, c):
            x, y, z = X(a), Y(b), Z(c)
            return (f(x[0], y[0], z[0]), f(x[1], y[1], z[1]))
    elif n == 3:
        def impl(a, b, c):
            x, y, z = X(a), Y(b), Z(c)
            return (f(x[0], y[0], z[0]), f(x[1], y[1], z[1]), f(x[2], y[2], z[2]))
    else:
        def impl(a, b, c):
            x, y, z = X(a), Y(b), Z(c)
            return (f(x[0], y[0], z[0]), f(x[1], y[1], z[1]), f(x[2], y[2], z[2]),
                    f(x[3], y[3], z[3]))
    return impl


def _componentwise(f):
    """Turn a scalar formula ``f`` into the GLSL-style function of the same name.

    The result applies ``f`` to each component of its vector arguments (all of the
    same length), broadcasting scalar arguments; with only scalars it is ``f``.
    """
    register_jitable(f)  # the numba implementations call f itself
    name = f.__name__
    arity = f.__code__.co_argcount

    @functools.wraps(f)
    def generic(*args):
        n = _py_vector_length(name, args)
        if n == 0:
            return f(*args)
        return tuple(f(*[a[i] if isinstance(a, tuple) else a for a in args]) for i in range(n))

    if arity == 1:
        @overload(generic)
        def _ov(a):
            return _impl_1(f, _nb_common_length(name, a))
    elif arity == 2:
        @overload(generic)
        def _ov(a, b):
            n = _nb_common_length(name, a, b)
            return _impl_2(f, n, *(_as_vector(t, n) if n else None for t in (a, b)))
    elif arity == 3:
        @overload(generic)
        def _ov(a, b, c):
            n = _nb_common_length(name, a, b, c)
            return _impl_3(f, n, *(_as_vector(t, n) if n else None for t in (a, b, c)))
    else:  # pragma: no cover - a programming error in this module
        raise TypeError(f"_componentwise supports 1 to 3 arguments, {name} has {arity}")
    return generic


def _reduction(f):
    """Turn a binary scalar formula into a fold over a vector's components, left to right.

    ``hsum((a, b, c)) == (a + b) + c``; a scalar is returned unchanged.
    """
    register_jitable(f)

    def decorate(generic):
        name = generic.__name__

        @functools.wraps(generic)
        def py_reduce(v):
            if not isinstance(v, tuple):
                return v
            _py_vector_length(name, (v,))
            return functools.reduce(f, v)

        @overload(py_reduce)
        def _ov(v):
            n = _nb_vector_length(name, v)
            if n == 0:
                return lambda v: v
            if n == 2:
                return lambda v: f(v[0], v[1])
            if n == 3:
                return lambda v: f(f(v[0], v[1]), v[2])
            return lambda v: f(f(f(v[0], v[1]), v[2]), v[3])

        return py_reduce

    return decorate


# --------------------------------------------------------------------------
# Constructors
# --------------------------------------------------------------------------

def _absent(ty) -> bool:
    """True for an optional argument that was not given (numba type or Python value)."""
    return ty is None or isinstance(ty, (types.Omitted, types.NoneType))


def vec2(x: Union[float, Vec], y: Optional[float] = None) -> Vec2:
    """``vec2(x, y)``, ``vec2(s)`` = (s, s), or ``vec2(v)`` = v's first two components."""
    if y is None:
        if isinstance(x, tuple):
            return (float(x[0]), float(x[1]))
        return (float(x), float(x))
    return (float(x), float(y))


def vec3(x: Union[float, Vec], y: Optional[float] = None, z: Optional[float] = None) -> Vec3:
    """``vec3(x, y, z)``, ``vec3(s)``, ``vec3(v)`` (xyz of a vec3/vec4), ``vec3(v2, z)``."""
    if y is None:
        if isinstance(x, tuple):
            return (float(x[0]), float(x[1]), float(x[2]))
        return (float(x), float(x), float(x))
    if z is None:
        return (float(x[0]), float(x[1]), float(y))
    return (float(x), float(y), float(z))


def vec4(x: Union[float, Vec], y: Optional[float] = None, z: Optional[float] = None,
         w: Optional[float] = None) -> Vec4:
    """``vec4(x, y, z, w)``, ``vec4(s)``, ``vec4(v4)``, ``vec4(v3, w)``, ``vec4(v2, z, w)``."""
    if y is None:
        if isinstance(x, tuple):
            return (float(x[0]), float(x[1]), float(x[2]), float(x[3]))
        return (float(x), float(x), float(x), float(x))
    if z is None:
        return (float(x[0]), float(x[1]), float(x[2]), float(y))
    if w is None:
        return (float(x[0]), float(x[1]), float(y), float(z))
    return (float(x), float(y), float(z), float(w))


def _check_tuple(name, ty, lengths):
    n = _nb_vector_length(name, ty)
    if n not in lengths:
        raise TypingError(f"softpipe.language.glsl.{name}: expected a vec{'/vec'.join(map(str, lengths))}, got {ty}")


@overload(vec2)
def _ov_vec2(x, y=None):
    if not _absent(y):
        return lambda x, y=None: (float(x), float(y))
    if _nb_vector_length("vec2", x) == 0:
        return lambda x, y=None: (float(x), float(x))
    return lambda x, y=None: (float(x[0]), float(x[1]))


@overload(vec3)
def _ov_vec3(x, y=None, z=None):
    if _absent(y):
        if _nb_vector_length("vec3", x) == 0:
            return lambda x, y=None, z=None: (float(x), float(x), float(x))
        _check_tuple("vec3", x, (3, 4))
        return lambda x, y=None, z=None: (float(x[0]), float(x[1]), float(x[2]))
    if _absent(z):
        _check_tuple("vec3", x, (2,))
        return lambda x, y=None, z=None: (float(x[0]), float(x[1]), float(y))
    return lambda x, y=None, z=None: (float(x), float(y), float(z))


@overload(vec4)
def _ov_vec4(x, y=None, z=None, w=None):
    if _absent(y):
        if _nb_vector_length("vec4", x) == 0:
            return lambda x, y=None, z=None, w=None: (float(x), float(x), float(x), float(x))
        _check_tuple("vec4", x, (4,))
        return lambda x, y=None, z=None, w=None: (float(x[0]), float(x[1]), float(x[2]), float(x[3]))
    if _absent(z):
        _check_tuple("vec4", x, (3,))
        return lambda x, y=None, z=None, w=None: (float(x[0]), float(x[1]), float(x[2]), float(y))
    if _absent(w):
        _check_tuple("vec4", x, (2,))
        return lambda x, y=None, z=None, w=None: (float(x[0]), float(x[1]), float(y), float(z))
    return lambda x, y=None, z=None, w=None: (float(x), float(y), float(z), float(w))


# --------------------------------------------------------------------------
# Componentwise functions: each defined by its scalar formula
# --------------------------------------------------------------------------

@_componentwise
def add(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """a + b, per component (GLSL ``a + b``); either may be a scalar."""
    return a + b


@_componentwise
def sub(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """a − b, per component (GLSL ``a - b``); either may be a scalar."""
    return a - b


@_componentwise
def mul(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """a · b, per component (GLSL ``a * b`` on vectors: colors multiply per channel)."""
    return a * b


@_componentwise
def div(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """a / b, per component (GLSL ``a / b``). Division by zero is the caller's to avoid."""
    return a / b


@_componentwise
def scale(v: Vec, s: float) -> Vec:
    """The vector v times the scalar s (GLSL ``v * s``)."""
    return v * s


@_componentwise
def neg(v: VecOrScalar) -> VecOrScalar:
    """−v (GLSL ``-v``)."""
    return -v


@_componentwise
def vabs(v: VecOrScalar) -> VecOrScalar:
    """|v| per component (GLSL ``abs``)."""
    return abs(v)


@_componentwise
def vmin(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """The smaller of a and b per component (GLSL ``min``)."""
    return min(a, b)


@_componentwise
def vmax(a: VecOrScalar, b: VecOrScalar) -> VecOrScalar:
    """The larger of a and b per component (GLSL ``max``)."""
    return max(a, b)


@_componentwise
def clamp(x: VecOrScalar, lo: VecOrScalar, hi: VecOrScalar) -> VecOrScalar:
    """min(max(x, lo), hi) per component (GLSL ``clamp``); NaN gives ``lo``."""
    # Builtin min/max, not conditional expressions: numba turns these into
    # branch-free selects (much faster in a loop: benchmarks/README.md), with
    # Python's exact semantics; lo first so that max(lo, NaN) is lo.
    return min(hi, max(lo, x))


@_componentwise
def saturate(x: VecOrScalar) -> VecOrScalar:
    """clamp(x, 0, 1) (HLSL's name): a color or weight limited to [0, 1]."""
    return min(1.0, max(0.0, x))


@_componentwise
def mix(a: VecOrScalar, b: VecOrScalar, t: VecOrScalar) -> VecOrScalar:
    """a + t·(b − a), and b itself at t = 1 (GLSL ``mix``): exact at both ends, monotone in t.

    The one linear interpolation of softpipe: shaders, a texture's mip levels and a
    cube map's texels blend with it. mix(a, b, 0) = a, mix(a, b, 1) = b and
    mix(a, a, t) = a exactly, and as t grows the value only moves toward b (each
    rounding in a + t·(b − a) is monotone). The textbook a·(1 − t) + b·t is exact at
    both ends too, but its two rounded products can step back an ulp as t grows and
    miss a for a = b. One exception remains, where b − a itself rounds (a and b far
    apart in magnitude; never within a factor 2 of each other, nor for the texels of
    an 8-bit image): just below t = 1 the value may pass b by an ulp. Holding it to b,
    as C++20's ``std::lerp`` does, doubled the cost of a cube-map lookup's blends.
    ``tests/test_glsl.py`` states each property.
    """
    x = a + t * (b - a)
    return b if t == 1.0 else x


@_componentwise
def step(edge: VecOrScalar, x: VecOrScalar) -> VecOrScalar:
    """0 if x < edge else 1 (GLSL ``step``)."""
    return 0.0 if x < edge else 1.0


@_componentwise
def smoothstep(edge0: VecOrScalar, edge1: VecOrScalar, x: VecOrScalar) -> VecOrScalar:
    """Hermite 0→1 as x goes edge0→edge1: t²(3 − 2t), t = clamp((x − e0)/(e1 − e0), 0, 1)."""
    if edge1 == edge0:  # GLSL: undefined; take the step, never divide by zero
        return 0.0 if x < edge0 else 1.0
    t = min(1.0, max(0.0, (x - edge0) / (edge1 - edge0)))
    return t * t * (3.0 - 2.0 * t)


# Whole exponents up to this are raised by repeated squaring: the usual shininess values
# (8, 30, 48, …) then cost a few multiplications instead of a call to C's pow, about a third
# of a one-light Blinn-Phong sample's time (issue 18 for the built-in programs, issue 35 for a
# user's shader). Each product's rounding is raised to the power still to come, so the result
# is within about (n − 1) ulp of xⁿ (1.4·10⁻¹⁴ relative at n = 128), where pow is within 1:
# far below every tolerance, and the same in plain Python.
MAX_SQUARING_EXPONENT = 128.0


@_componentwise
def pow_(x: VecOrScalar, y: VecOrScalar) -> VecOrScalar:
    """xʸ per component for x > 0; x ≤ 0 counts as 0: 0⁰ = 1, 0ʸ = 0 (y > 0), +inf (y < 0).

    GLSL leaves x < 0 undefined; this form is the clamped power (x)₊ʸ of the
    specular terms (FORMULAS §5, §6), with 0⁰ = 1 as C's ``pow``. A whole y in
    1..MAX_SQUARING_EXPONENT is raised by repeated squaring (at most 2·log₂ y
    products; within about (y − 1) ulp of xʸ), any other y by ``x ** y`` (C's pow).
    """
    if x > 0.0:
        if 1.0 <= y <= MAX_SQUARING_EXPONENT and y == math.floor(y):
            k = int(y)
            result = 1.0
            base = float(x)             # an int x squared as an int would overflow, compiled
            while True:
                if k & 1:
                    result *= base
                k >>= 1
                if k == 0:
                    return result
                base *= base
        return x ** y
    if y == 0.0:
        return 1.0
    return 0.0 if y > 0.0 else math.inf


@_componentwise
def _zero(x):
    """0.0 per component: a zero vector of x's length (``scale(x, 0.0)`` would keep NaN)."""
    return 0.0


# --------------------------------------------------------------------------
# Reductions
# --------------------------------------------------------------------------

def _plus(a, b):
    return a + b


def _larger(a, b):
    return max(a, b)


def _smaller(a, b):
    return min(a, b)


@_reduction(_plus)
def hsum(v: Vec) -> float:
    """The sum of v's components, left to right: ((x + y) + z) + w."""


@_reduction(_larger)
def max_component(v: Vec) -> float:
    """The largest component of v (e.g. the brightest channel of a color)."""


@_reduction(_smaller)
def min_component(v: Vec) -> float:
    """The smallest component of v."""


# --------------------------------------------------------------------------
# Geometry, built on the above (one source for Python and numba)
# --------------------------------------------------------------------------

@register_jitable
def dot(a: Vec, b: Vec) -> float:
    """a · b = Σ aᵢbᵢ, summed left to right."""
    return hsum(mul(a, b))


@register_jitable
def cross(a: Vec3, b: Vec3) -> Vec3:
    """a × b, for vec3."""
    return (a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


@register_jitable
def length(v: Vec) -> float:
    """|v| = √(v·v)."""
    return math.sqrt(dot(v, v))


@register_jitable
def distance(a: Vec, b: Vec) -> float:
    """|a − b|."""
    return length(sub(a, b))


@register_jitable
def normalize(v: Vec) -> Vec:
    """v / |v|; the zero vector (or a NaN one) gives the zero vector instead of NaN."""
    n = length(v)
    if n > 0.0:
        return div(v, n)
    return _zero(v)


@register_jitable
def faceforward(N: Vec, I: Vec, Nref: Vec) -> Vec:
    """N if Nref·I < 0 else −N (GLSL): N turned to face against the incident I."""
    if dot(Nref, I) < 0.0:
        return scale(N, 1.0)
    return scale(N, -1.0)  # not neg(N): both branches must be float tuples for numba


@register_jitable
def reflect(I: Vec, N: Vec) -> Vec:
    """I − 2(N·I)N (GLSL ``reflect``): I mirrored about the unit normal N.

    I is the *incident* direction (pointing at the surface). FORMULAS §16's
    R = 2(N·V)N − V is ``reflect(neg(V), N)``.
    """
    return sub(I, scale(N, 2.0 * dot(N, I)))


@register_jitable
def refract(I: Vec, N: Vec, eta: float) -> Vec:
    """The refracted direction (GLSL ``refract``), or the zero vector on total internal reflection.

    I is the unit incident direction (pointing at the surface), N the unit normal
    on the incident side (N·I ≤ 0), eta = η_i/η_t. With k = 1 − η²(1 − (N·I)²):
    T = η·I − (η(N·I) + √k)·N, a unit vector obeying Snell's law η_i sin θ_i =
    η_t sin θ_t (FORMULAS §17). With I = −V and c₁ = N·V this is FORMULAS §18's
    T = (η·c₁ − c₂)·N − η·V; k < 0 is §19's total internal reflection.
    """
    d = dot(N, I)
    k = 1.0 - eta * eta * (1.0 - d * d)
    if k < 0.0:
        return _zero(I)
    return sub(scale(I, eta), scale(N, eta * d + math.sqrt(k)))


# --------------------------------------------------------------------------
# Matrices: 4×4 (or 3×3) float arrays acting on column vectors
# --------------------------------------------------------------------------

@register_jitable
def mat4_mul_vec4(M: np.ndarray, v: Vec4) -> Vec4:
    """M @ v for a 4×4 array M and a vec4 v, as a vec4 of floats."""
    return (float(M[0, 0] * v[0] + M[0, 1] * v[1] + M[0, 2] * v[2] + M[0, 3] * v[3]),
            float(M[1, 0] * v[0] + M[1, 1] * v[1] + M[1, 2] * v[2] + M[1, 3] * v[3]),
            float(M[2, 0] * v[0] + M[2, 1] * v[1] + M[2, 2] * v[2] + M[2, 3] * v[3]),
            float(M[3, 0] * v[0] + M[3, 1] * v[1] + M[3, 2] * v[2] + M[3, 3] * v[3]))


@register_jitable
def mat3_mul_vec3(M: np.ndarray, v: Vec3) -> Vec3:
    """M₃ @ v for a 3×3 array M, or the upper-left 3×3 of a 4×4 one (directions, normals)."""
    return (float(M[0, 0] * v[0] + M[0, 1] * v[1] + M[0, 2] * v[2]),
            float(M[1, 0] * v[0] + M[1, 1] * v[1] + M[1, 2] * v[2]),
            float(M[2, 0] * v[0] + M[2, 1] * v[1] + M[2, 2] * v[2]))
