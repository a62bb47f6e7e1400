"""softpipe.language.glsl against numpy, as plain Python and jitted, for vec2/vec3/vec4.

Expected values are computed here with numpy/math, never with softpipe.language.glsl.
"""
import math
import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from softpipe.language.glsl import (
    add,
    clamp,
    cross,
    distance,
    div,
    dot,
    faceforward,
    hsum,
    length,
    mat3_mul_vec3,
    mat4_mul_vec4,
    max_component,
    min_component,
    mix,
    mul,
    neg,
    normalize,
    pow_,
    reflect,
    refract,
    saturate,
    scale,
    smoothstep,
    step,
    sub,
    vabs,
    vec2,
    vec3,
    vec4,
    vmax,
    vmin,
)

RNG = np.random.default_rng(20240601)

# Under NUMBA_DISABLE_JIT=1 every kernel below is plain Python: the comparisons
# still run, the checks of compiled code are skipped.
jit_only = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="inspects compiled code")


def py(f):
    """The plain-Python version of a kernel (the kernel itself when JIT is off)."""
    return getattr(f, "py_func", f)


@njit(cache=True)
def componentwise_all(a, b, c, s):
    """Every componentwise function once; a module-level kernel, so numba caches it."""
    return (add(a, b), sub(a, b), mul(a, b), div(a, b), scale(a, s), neg(a), vabs(a),
            vmin(a, b), vmax(a, b), clamp(a, -0.3, 0.4), clamp(a, b, c), saturate(a),
            mix(a, b, s), mix(a, b, c), step(0.1, a), step(b, a), smoothstep(-0.5, 0.5, a),
            pow_(vabs(a), s), pow_(a, 2.0), add(s, a), sub(s, a))


@njit(cache=True)
def geometric_all(a, b):
    return (dot(a, b), length(a), distance(a, b), normalize(a), normalize(scale(a, 0.0)),
            hsum(a), max_component(a), min_component(a), reflect(a, normalize(b)))


@njit(cache=True)
def vec3_only(a, b, eta):
    return (cross(a, b), refract(normalize(a), normalize(b), eta), faceforward(a, b, a))


@njit(cache=True)
def matrices(M, v4, v3):
    return mat4_mul_vec4(M, v4), mat3_mul_vec3(M, v3)


@njit(cache=True)
def constructors(x, v2, v3, v4):
    return (vec2(x, 2.0), vec2(x), vec2(v3), vec3(x, 2, 3.5), vec3(x), vec3(v4), vec3(v2, 7),
            vec4(x, 1.0, 2.0, 3), vec4(x), vec4(v4), vec4(v3, 1.0), vec4(v2, 5.0, 6.0))


def random_vec(n):
    return tuple(float(x) for x in RNG.uniform(-1.0, 1.0, n))


def expected_componentwise(a, b, c, s):
    a, b, c = np.array(a), np.array(b), np.array(c)
    t = np.clip((a + 0.5) / 1.0, 0.0, 1.0)
    return (a + b, a - b, a * b, a / b, a * s, -a, np.abs(a), np.minimum(a, b), np.maximum(a, b),
            np.clip(a, -0.3, 0.4), np.minimum(c, np.maximum(b, a)), np.clip(a, 0.0, 1.0),
            a * (1 - s) + b * s, a * (1 - c) + b * c, np.where(a < 0.1, 0.0, 1.0),
            np.where(a < b, 0.0, 1.0), t * t * (3 - 2 * t),
            np.abs(a) ** s, np.where(a > 0, np.maximum(a, 0) ** 2.0, 0.0), s + a, s - a)


def assert_results_equal(got, expected):
    assert len(got) == len(expected)
    for g, e in zip(got, expected):
        np.testing.assert_allclose(np.array(g, dtype=float), e, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_componentwise_matches_numpy_python_and_jitted(n):
    a, b, c = random_vec(n), random_vec(n), random_vec(n)
    s = 0.3
    expected = expected_componentwise(a, b, c, s)
    python = py(componentwise_all)(a, b, c, s)
    jitted = componentwise_all(a, b, c, s)
    assert_results_equal(python, expected)
    assert_results_equal(jitted, expected)
    assert all(isinstance(r, tuple) and len(r) == n for r in jitted)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_geometric_matches_numpy(n):
    a, b = random_vec(n), random_vec(n)
    A, B = np.array(a), np.array(b)
    nb = B / np.linalg.norm(B)
    expected = (A @ B, np.linalg.norm(A), np.linalg.norm(A - B), A / np.linalg.norm(A), np.zeros(n),
                A.sum(), A.max(), A.min(), A - 2 * (nb @ A) * nb)
    for got in (py(geometric_all)(a, b), geometric_all(a, b)):
        assert_results_equal(got, expected)


def test_jitted_and_python_are_bit_identical():
    for n in (2, 3, 4):
        a, b, c = random_vec(n), random_vec(n), random_vec(n)
        assert repr(componentwise_all(a, b, c, 0.7)) == repr(py(componentwise_all)(a, b, c, 0.7))
        assert repr(geometric_all(a, b)) == repr(py(geometric_all)(a, b))
    a, b = random_vec(3), random_vec(3)
    assert repr(vec3_only(a, b, 0.66)) == repr(py(vec3_only)(a, b, 0.66))


def test_scalar_arguments_give_scalars():
    assert add(1.5, 2.0) == 3.5
    assert clamp(2.0, 0.0, 1.0) == 1.0
    assert mix(2.0, 4.0, 0.25) == 2.5
    assert saturate(-3.0) == 0.0
    assert hsum(2.5) == 2.5


def test_mix_is_exact_at_the_ends():
    a, b = (0.1, 0.7, 0.3), (0.9, 0.2, 0.6)
    assert mix(a, b, 0.0) == a and mix(a, b, 1.0) == b


@njit(cache=True)
def mix_each(a, b, t):
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = mix(a[i], b[i], t[i])
    return out


def test_mix_is_exact_at_both_ends_and_monotone_in_t():
    """The one linear interpolation (a texture's mip levels and a cube map's texels blend with it too).

    mix(a, b, 0) = a, mix(a, b, 1) = b and mix(a, a, t) = a exactly; at neighbouring
    floats t < t′ below 1, mix(a, b, t′) never steps back from mix(a, b, t). Across t = 1,
    and staying in [a, b] for t in [0, 1), wherever a + (b − a) rounds to b (the one
    exception of the docstring is where it does not). The samples are ones on which
    each textbook form fails (checked first); jitted and as plain Python.
    """
    n = 200_000
    a = RNG.random(n) * 10.0 ** RNG.integers(-3, 3, n)
    b = RNG.random(n) * 10.0 ** RNG.integers(-3, 3, n)
    b[::10] = a[::10]                                             # equal ends
    t = np.concatenate([RNG.random(n // 2), RNG.uniform(-1.0, 2.0, n - n // 2)])
    t[:60] = 1.0 - 2.0 ** -np.arange(1, 61)                       # just below 1
    t_next = np.nextafter(t, np.inf)
    step_back = a * (1.0 - t_next) + b * t_next < a * (1.0 - t) + b * t
    assert np.any(step_back & (b > a)), "no sample on which a(1 − t) + bt steps back"
    lands = a + (b - a) == b
    assert not np.all(lands), "no sample on which a + (b − a) misses b"

    now, after = mix_each(a, b, t), mix_each(a, b, t_next)
    assert np.array_equal(mix_each(a, b, np.zeros(n)), a) and np.array_equal(mix_each(a, b, np.ones(n)), b)
    assert np.array_equal(now[::10], a[::10])
    below = (t_next < 1.0) | lands                               # across t = 1 where a + (b − a) lands on b
    up, down = below & (b > a), below & (b < a)
    assert np.all(after[up] >= now[up]) and np.all(after[down] <= now[down])
    inside = (t >= 0.0) & (t < 1.0) & lands
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    assert np.all((now[inside] >= lo[inside]) & (now[inside] <= hi[inside]))
    for i in range(0, n, 997):                                    # plain Python: the same values
        assert mix(float(a[i]), float(b[i]), float(t[i])) == now[i]
    assert mix((0.25, 0.5, 0.75, 1.0), (1.0, 0.5, 0.0, 0.25), 1.0) == (1.0, 0.5, 0.0, 0.25)


def test_normalize_zero_and_nan_give_zero_not_nan():
    assert normalize((0.0, 0.0, 0.0)) == (0.0, 0.0, 0.0)
    assert normalize((math.nan, 0.0)) == (0.0, 0.0)
    assert geometric_all((math.nan, 1.0, 2.0), (1.0, 0.0, 0.0))[4] == (0.0, 0.0, 0.0)
    assert clamp(math.nan, 0.0, 1.0) == 0.0
    assert smoothstep(0.5, 0.5, 0.4) == 0.0 and smoothstep(0.5, 0.5, 0.6) == 1.0


def test_pow_conventions():
    assert pow_(0.0, 0.0) == 1.0           # 0⁰ = 1 (the planet material, FORMULAS §10)
    assert pow_(-0.5, 0.0) == 1.0          # x ≤ 0 counts as 0
    assert pow_(-0.5, 3.0) == 0.0
    assert pow_(0.0, -1.0) == math.inf
    assert pow_(0.25, 0.5) == 0.5


@njit   # not cached: numba's cache would not see softpipe/language/glsl.py change
def pow_jitted(x, y):
    return pow_(x, y)


def test_pow_of_a_whole_exponent_is_repeated_squaring():
    """A whole exponent in 1..128 is raised by repeated squaring, compiled and in plain Python alike:
    the products written out here, which C's pow (``x ** y``) misses by an ulp or more at 0.7."""
    x = 0.7
    x2 = x * x
    x4 = x2 * x2
    x8 = x4 * x4
    x16 = x8 * x8
    x128 = ((x16 * x16) * (x16 * x16)) * ((x16 * x16) * (x16 * x16))
    squared = {1.0: x, 2.0: x2, 3.0: x * x2, 30.0: ((x2 * x4) * x8) * x16, 128.0: x128}
    assert squared[30.0] != x ** 30.0                 # so the test tells squaring from pow
    for y, expected in squared.items():
        assert py(pow_jitted)(x, y) == expected, y
        assert pow_jitted(x, y) == expected, y
    assert pow_jitted(2, 100.0) == 2.0 ** 100         # an int x is squared as a float (as an int it overflows)
    for y in (0.5, 2.5, 129.0, -2.0):                 # not whole, or out of range: C's pow
        assert pow_jitted(x, y) == x ** y and py(pow_jitted)(x, y) == x ** y, y


def test_cross_matches_numpy():
    a, b = random_vec(3), random_vec(3)
    for got in (cross(a, b), vec3_only(a, b, 1.0)[0]):
        np.testing.assert_allclose(got, np.cross(a, b), rtol=1e-14, atol=1e-15)


def test_faceforward():
    N, I = (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)
    assert faceforward(N, I, N) == N
    assert faceforward(N, (0.0, 0.0, 1.0), N) == (-0.0, -0.0, -1.0)


# --- reflect and refract: Snell's law (FORMULAS §16–§19) -----------------

def incident(theta_deg):
    """A unit incident direction at angle theta from the normal (0, 0, 1), pointing down."""
    t = math.radians(theta_deg)
    return (math.sin(t), 0.0, -math.cos(t))


@pytest.mark.parametrize("theta", [0.0, 10.0, 45.0, 80.0])
def test_reflect_keeps_the_angle(theta):
    N = (0.0, 0.0, 1.0)
    I = incident(theta)
    R = reflect(I, N)
    t = math.radians(theta)
    np.testing.assert_allclose(R, (math.sin(t), 0.0, math.cos(t)), atol=1e-15)


@pytest.mark.parametrize("n1,n2", [(1.0, 1.52), (1.0, 1.33), (1.52, 1.0), (2.417, 1.0), (1.0, 1.0)])
@pytest.mark.parametrize("theta", [0.0, 15.0, 30.0, 40.0, 60.0, 85.0])
def test_refract_obeys_snell(n1, n2, theta):
    N = (0.0, 0.0, 1.0)
    I = incident(theta)
    eta = n1 / n2
    T = refract(I, N, eta)
    sin_t_squared = (n1 / n2 * math.sin(math.radians(theta))) ** 2
    if sin_t_squared > 1.0:  # total internal reflection (FORMULAS §19)
        assert T == (0.0, 0.0, 0.0)
        return
    T = np.array(T)
    assert np.linalg.norm(T) == pytest.approx(1.0, abs=1e-14)          # |T| = 1
    sin_t = math.hypot(T[0], T[1])
    assert n1 * math.sin(math.radians(theta)) == pytest.approx(n2 * sin_t, abs=1e-14)  # §17
    assert T[2] < 0.0                                                     # goes through
    assert T[1] == 0.0 and (T[0] >= 0.0)                                  # in the plane of incidence, same side


def test_refract_tir_jitted_gives_zero():
    # glass → air at 60°, beyond the critical angle asin(1/1.52) ≈ 41.1°
    I = incident(60.0)
    assert vec3_only(I, (0.0, 0.0, 1.0), 1.52)[1] == (0.0, 0.0, 0.0)


# --- matrices and constructors -------------------------------------------

def test_matrix_helpers_match_numpy():
    M = RNG.normal(size=(4, 4))
    v4, v3 = random_vec(4), random_vec(3)
    for m4, m3 in (matrices(M, v4, v3), py(matrices)(M, v4, v3)):
        np.testing.assert_allclose(m4, M @ np.array(v4), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(m3, M[:3, :3] @ np.array(v3), rtol=1e-14, atol=1e-15)
        assert all(type(x) is float for x in m4 + m3)
    M3 = np.ascontiguousarray(M[:3, :3])
    np.testing.assert_allclose(mat3_mul_vec3(M3, v3), M3 @ np.array(v3), rtol=1e-14, atol=1e-15)


def test_constructors():
    expected = ((1.0, 2.0), (1.0, 1.0), (5.0, 6.0), (1.0, 2.0, 3.5), (1.0, 1.0, 1.0), (9.0, 8.0, 7.0),
                (3.0, 4.0, 7.0), (1.0, 1.0, 2.0, 3.0), (1.0, 1.0, 1.0, 1.0), (9.0, 8.0, 7.0, 6.0),
                (5.0, 6.0, 7.0, 1.0), (3.0, 4.0, 5.0, 6.0))
    args = (1, (3.0, 4.0), (5.0, 6.0, 7.0), (9.0, 8.0, 7.0, 6.0))
    for got in (constructors(*args), py(constructors)(*args)):
        assert got == expected
        assert all(type(x) is float for v in got for x in v)


@jit_only
def test_length_mismatch_is_an_error_in_both_worlds():
    with pytest.raises(TypeError, match="different lengths"):
        add((1.0, 2.0, 3.0), (1.0, 2.0))

    @njit
    def bad(a, b):
        return add(a, b)

    with pytest.raises(TypingError, match="softpipe.language.glsl.add: vectors of different lengths"):
        bad((1.0, 2.0, 3.0), (1.0, 2.0))


# --- compiled code: cached across processes, and no allocation ---------

# Run in a fresh process: the kernels above must load from numba's disk cache
# (no compile), and calling them must make no NRT (heap) allocation — counted by
# numba's allocation statistics, which see any array a kernel would create.
CACHED_AND_ALLOCATION_FREE = """
import sys
sys.path.insert(0, sys.argv[1])
from numba.core.runtime import rtsys
import test_glsl as t
x = (0.1, 0.2, 0.3)
def run():
    t.componentwise_all(x, x, x, 0.5); t.geometric_all(x, x); t.vec3_only(x, x, 0.5)
run()
before = rtsys.get_allocation_stats().alloc
run()
allocations = rtsys.get_allocation_stats().alloc - before
kernels = (t.componentwise_all, t.geometric_all, t.vec3_only)
print(sum(sum(k.stats.cache_hits.values()) for k in kernels),
      sum(sum(k.stats.cache_misses.values()) for k in kernels), allocations)
"""


@jit_only
def test_kernels_load_from_the_cache_in_a_new_process_and_do_not_allocate():
    x = (0.1, 0.2, 0.3)
    componentwise_all(x, x, x, 0.5), geometric_all(x, x), vec3_only(x, x, 0.5)  # compile and save
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_JIT"}
    env["NUMBA_NRT_STATS"] = "1"
    out = subprocess.run([sys.executable, "-c", CACHED_AND_ALLOCATION_FREE, os.path.dirname(__file__)],
                         capture_output=True, text=True, env=env, check=True).stdout.split()
    hits, misses, allocations = map(int, out)
    assert (hits, misses, allocations) == (3, 0, 0)
