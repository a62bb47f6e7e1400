"""Shaders behave like Python functions (issue #14).

- The module globals a shader reads (and the helpers it calls read) are the
  ones of the draw: change one and the next draw uses it, on both paths, and
  ``trace.debug_fragment`` agrees with the framebuffer. A draw whose globals did
  not change compiles nothing.
- A plain Python helper (no decorator), a helper of a helper, a helper from
  another module, a recursive helper: compiled with the shader.
- A shader that cannot be compiled says what is wrong and where in one short
  paragraph, numba's text kept on ``err.numba_message``; one that raises while
  it runs names the fragment or vertex; a wrong return value is refused on both
  paths alike.
"""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import shader_python_helpers as other_module
from patience import PATIENCE

import softpipe as sp
from softpipe import ShaderError
from softpipe.language.kernels import generate

FULL = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1.0]])
QUAD = [0, 1, 2, 0, 2, 3]
WHITE = {"color": np.ones((4, 3))}
PATHS = ["reference", "fast"]


def draw_quad(shader, path="reference", size=128, trace=False, **kw):
    fb = sp.Framebuffer(size, size)
    t = sp.draw(fb, FULL, QUAD, varyings=dict(WHITE), fragment_shader=shader, path=path, trace=trace, **kw)
    return fb, t


# ------------------------------------------------------------------ globals

GAIN = 0.5
TINT = (1.0, 0.5, 0.25)
ON = True
TABLE = np.array([0.25, 0.75])


def gain_shader(varyings, uniforms, frag):
    return (GAIN, 0.0, 0.0, 1.0)


def scaled(x):
    return GAIN * x                     # a global read by a helper


def helper_gain_shader(varyings, uniforms, frag):
    return (scaled(1.0), TINT[1], TABLE[1] if ON else 0.0, 1.0)


@pytest.mark.parametrize("path", PATHS)
def test_a_changed_global_is_what_the_next_draw_uses_and_debug_fragment_agrees(path):
    global GAIN
    try:
        for gain in (0.5, 1.0, 0.25):
            GAIN = gain
            fb, trace = draw_quad(gain_shader, path=path, trace=True)
            assert trace.path == path
            assert fb.color[64, 64, 0] == pytest.approx(gain, abs=1e-6)
            assert trace.debug_fragment(64, 64)[0] == gain
    finally:
        GAIN = 0.5


@pytest.mark.parametrize("path", PATHS)
def test_globals_of_helpers_tuples_bools_and_arrays_are_read_at_each_draw(path):
    global GAIN, TINT, ON
    try:
        fb, _ = draw_quad(helper_gain_shader, path=path)
        assert tuple(fb.color[10, 10, :3]) == pytest.approx((0.5, 0.5, 0.75), abs=1e-6)
        GAIN, TINT, ON = 0.75, (1.0, 0.125, 0.0), False
        TABLE[1] = 0.5                  # changed in place: still seen (ON is False, though)
        fb, trace = draw_quad(helper_gain_shader, path=path, trace=True)
        assert tuple(fb.color[10, 10, :3]) == pytest.approx((0.75, 0.125, 0.0), abs=1e-6)
        assert trace.debug_fragment(10, 10)[:3] == (0.75, 0.125, 0.0)
        ON = True
        fb, _ = draw_quad(helper_gain_shader, path=path)
        assert tuple(fb.color[10, 10, :3]) == pytest.approx((0.75, 0.125, 0.5), abs=1e-6)
    finally:
        GAIN, TINT, ON = 0.5, (1.0, 0.5, 0.25), True
        TABLE[1] = 0.75


def test_a_draw_with_unchanged_globals_compiles_nothing(monkeypatch):
    global GAIN
    compiled = []
    original = generate._compile_module

    def counting(*args, **kw):
        compiled.append(args[-1])
        return original(*args, **kw)

    monkeypatch.setattr(generate, "_compile_module", counting)
    try:
        GAIN = 0.375
        for path in PATHS:
            draw_quad(gain_shader, path=path)
        first = len(compiled)
        for path in PATHS:
            draw_quad(gain_shader, path=path)           # the same globals: nothing new
        assert len(compiled) == first
        GAIN = 0.625
        draw_quad(gain_shader)
        assert len(compiled) == first + 1               # a changed one: one new loop
        # the built-in programs stay cached too
        mesh = sp.shapes.uv_sphere(segments=12, rings=6)
        cam = sp.Camera(eye=(0.0, 0.0, 3.0))
        sp.draw_mesh(sp.Framebuffer(32, 32), mesh, cam, "phong")
        before = len(compiled)
        sp.draw_mesh(sp.Framebuffer(32, 32), mesh, cam, "phong")
        assert len(compiled) == before
    finally:
        GAIN = 0.5


# ------------------------------------------------------------------ helpers

def plain_double(x):
    return 2.0 * x


def plain_quarter(x):
    return 0.5 * plain_half(x)           # a helper calling a helper


def plain_half(x):
    return 0.5 * x


def factorial(n):
    if n <= 1.0:
        return 1.0
    return n * factorial(n - 1.0)


def helpers_shader(varyings, uniforms, frag):
    r = plain_double(0.25)                               # 0.5
    g = plain_quarter(1.0)                               # 0.25
    b = other_module.eighth(1.0) + other_module.imported_helper(0.0)   # 0.125 + 0.5
    a = factorial(3.0) / 6.0                             # 1.0
    return (r, g, b, a)


@pytest.mark.parametrize("path", PATHS)
def test_plain_python_helpers_are_compiled_with_the_shader(path):
    fb, trace = draw_quad(helpers_shader, path=path, trace=True)
    assert tuple(fb.color[5, 5]) == (0.5, 0.25, 0.625, 1.0)
    assert trace.debug_fragment(5, 5) == (0.5, 0.25, 0.625, 1.0)


def test_helpers_of_a_vertex_shader_are_compiled_too():
    def vertex(attributes, uniforms):
        p = attributes.position
        return (plain_double(p[0]) * 0.5, p[1], 0.0, 1.0), sp.shading.StandardVaryings(
            (plain_half(1.0), 0.0, 0.0), (0.0, 0.0, 1.0))

    fb = sp.Framebuffer(16, 16)
    sp.draw(fb, FULL[:, :3], QUAD, vertex_shader=vertex,
            fragment_shader=lambda v, u, f: (v.position[0], 0.0, 0.0, 1.0))
    assert fb.color[8, 8, 0] == 0.5


def test_the_users_own_function_runs_under_disable_jit():
    """NUMBA_DISABLE_JIT=1: the shader is the user's function, its helpers and globals live."""
    code = textwrap.dedent("""
        import numpy as np, softpipe as sp
        GAIN = 0.5
        def half(x):
            return GAIN * x
        def shader(varyings, uniforms, frag):
            return (half(1.0), 0.0, 0.0, 1.0)
        full = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1.0]])
        fb = sp.Framebuffer(4, 4)
        sp.draw(fb, full, [0, 1, 2, 0, 2, 3], varyings={"color": np.ones((4, 3))}, fragment_shader=shader)
        GAIN = 1.0
        fb2 = sp.Framebuffer(4, 4)
        sp.draw(fb2, full, [0, 1, 2, 0, 2, 3], varyings={"color": np.ones((4, 3))}, fragment_shader=shader)
        print(fb.color[1, 1, 0], fb2.color[1, 1, 0])
        def listing(varyings, uniforms, frag):
            return [1.0, 0.0, 0.0, 1.0]
        try:
            sp.draw(fb2, full, [0, 1, 2, 0, 2, 3], varyings={"color": np.ones((4, 3))}, fragment_shader=listing)
        except sp.ShaderError as e:
            print(str(e).splitlines()[0])
    """)
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=PATIENCE)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == [
        "0.5 1.0",
        "fragment shader __main__.listing must return an RGBA tuple of 4 floats (or DISCARD), got a list"]


# ------------------------------------------------------------ compile errors

def returns_rgb(varyings, uniforms, frag):
    return (1.0, 0.0, 0.0)


def returns_list(varyings, uniforms, frag):
    return [1.0, 0.0, 0.0, 1.0]


def returns_string(varyings, uniforms, frag):
    return "red"


def misspelt_varying(varyings, uniforms, frag):
    c = varyings.colr
    return (c[0], c[1], c[2], 1.0)


def misspelt_uniform(varyings, uniforms, frag):
    c = uniforms.tnt
    return (c[0], c[1], c[2], 1.0)


def undefined_function(varyings, uniforms, frag):
    c = brighten(varyings.color)  # noqa: F821
    return (c[0], c[1], c[2], 1.0)


def linalg_norm(varyings, uniforms, frag):
    r = np.linalg.norm(varyings.color)
    return (r, r, r, 1.0)


def line_of(fn, text):
    lines, first = __import__("inspect").getsourcelines(fn)
    return first + next(k for k, line in enumerate(lines) if text in line)


def compile_error(shader, path, **kw) -> ShaderError:
    with pytest.raises(ShaderError) as info:
        draw_quad(shader, path=path, **kw)
    return info.value


def assert_short_and_clean(err: ShaderError, shader, text):
    message = str(err)
    assert f'File "{__file__}", line {line_of(shader, text)}' in message, message
    assert len(message.splitlines()) <= 8, message
    for internal in ("numba", "nopython", "During:", "Failed in", "Varyings_", "UniTuple"):
        assert internal not in message.replace("numba_message", ""), (internal, message)
    assert err.__cause__ is None and err.__suppress_context__          # raise ... from None
    assert err.numba_message                                           # numba's text, kept


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("shader, text, what", [
    (returns_rgb, "return (1.0, 0.0, 0.0)", "must return an RGBA tuple of 4 floats (or DISCARD), got a tuple of 3"),
    (returns_list, "return [", "must return an RGBA tuple of 4 floats (or DISCARD), got a list"),
    (returns_string, 'return "red"', "must return an RGBA tuple of 4 floats (or DISCARD), got a string"),
    (misspelt_varying, "varyings.colr", "varyings has no field 'colr' (did you mean 'color'?)"),
    (misspelt_uniform, "uniforms.tnt", "uniforms has no field 'tnt' (did you mean 'tint'?)"),
    (undefined_function, "brighten(", "name 'brighten' is not defined"),
    (linalg_norm, "np.linalg.norm", "use softpipe.shading.length"),
])
def test_a_compile_error_says_what_and_where_in_one_short_paragraph(path, shader, text, what):
    err = compile_error(shader, path, uniforms={"tint": (1.0, 1.0, 1.0)})
    assert f"fragment shader test_shader_python.{shader.__name__}" in str(err)
    assert what in str(err), str(err)
    assert_short_and_clean(err, shader, text)


def test_shader_debug_prints_numba_s_text(monkeypatch):
    monkeypatch.setenv("SOFTPIPE_SHADER_DEBUG", "1")
    err = compile_error(misspelt_varying, "reference")
    assert "Unknown attribute 'colr'" in str(err)
    assert err.numba_message in str(err)


# ------------------------------------------------------------ run-time errors

def divides_by_zero_at_column_100(varyings, uniforms, frag):
    d = frag.x - 100.5
    return (1.0 / d, 0.0, 0.0, 1.0)


def raises_on_primitive_1(varyings, uniforms, frag):
    if frag.primitive_id == 1 and frag.y > 108.0 and frag.x < 20.0:
        raise ValueError("bad corner")
    return (1.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize("path", PATHS)
def test_a_division_by_zero_names_the_fragment(path):
    with pytest.raises(ShaderError) as info:
        draw_quad(divides_by_zero_at_column_100, path=path)
    message = str(info.value)
    assert "divides_by_zero_at_column_100 raised ZeroDivisionError" in message
    assert "at pixel (100, " in message and "sample 0" in message, message
    assert f'File "{__file__}", line {line_of(divides_by_zero_at_column_100, "1.0 / d")}' in message


@pytest.mark.parametrize("path", PATHS)
def test_an_explicit_raise_names_the_fragment(path):
    with pytest.raises(ShaderError) as info:
        draw_quad(raises_on_primitive_1, path=path)
    message = str(info.value)
    assert "raised ValueError: bad corner" in message
    x, y = [int(v) for v in message.split("at pixel (")[1].split(")")[0].split(", ")]
    assert x < 20 and y < 20, message       # image rows count from the top
    assert "primitive 1" in message


def vertex_dividing_by_zero(attributes, uniforms):
    p = attributes.position
    s = 1.0 / (p[0] - 0.25)
    return (p[0], p[1], 0.0, 1.0), sp.shading.StandardVaryings((s, 0.0, 0.0), (0.0, 0.0, 1.0))


def test_a_vertex_error_names_the_vertex():
    positions = np.zeros((30000, 3))
    positions[:, 0] = np.linspace(-1, 0.2, 30000)
    positions[29123, 0] = 0.25
    with pytest.raises(ShaderError) as info:
        sp.draw(sp.Framebuffer(8, 8), positions, vertex_shader=vertex_dividing_by_zero,
                fragment_shader=lambda v, u, f: (1.0, 1.0, 1.0, 1.0))
    message = str(info.value)
    assert "vertex_dividing_by_zero raised ZeroDivisionError" in message
    assert "vertex 29123" in message, message
