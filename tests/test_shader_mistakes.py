"""The mistakes shader authors make most, each with the exact message it gets (issue #32).

Each message names the user's file (``Cell In[n]`` for a notebook cell) and the
line of the offending call, not the shader's ``def`` nor numba's own code, and
says the fix: numpy calls → the GLSL-like function of ``softpipe.shading``,
``breakpoint()``/``pdb`` → ``debug_fragment`` or ``NUMBA_DISABLE_JIT=1``,
operators on tuples → ``add``/``scale``/…, list and dict globals, ``global``
statements, imports. ``c + (0.1, 0.1, 0.1)``, which compiles and joins the
tuples, is refused before the draw.
"""
import inspect
import linecache
import math
import os
import subprocess
import sys
import types

import numpy as np
import pytest

import softpipe as sp
from softpipe import ShaderError

FULL = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1.0]])
QUAD = [0, 1, 2, 0, 2, 3]
FULL_TEXT = "  (the compiler's full text is err.numba_message; SOFTPIPE_SHADER_DEBUG=1 adds it here)"
DEBUG_HINT = ("to step through a shader, run it as plain Python: trace.debug_fragment(x, y) on the Trace of "
              "draw(..., trace=True) runs it on one pixel, NUMBA_DISABLE_JIT=1 runs every shader as Python")
LIST = [1.0, 0.5]
DICT = {"red": 1.0}


def draw(shader):
    fb = sp.Framebuffer(8, 8)
    sp.draw(fb, FULL, QUAD, varyings={"color": np.ones((4, 3))}, fragment_shader=shader)
    return fb


# ------------------------------------------------------------------ the mistakes

def np_dot(varyings, uniforms, frag):
    c = varyings.color
    d = np.dot(c, (1, 1, 1))
    return (d, d, d, 1.0)


def np_clip(varyings, uniforms, frag):
    r = np.clip(varyings.color[0] * 2.0, 0.0, 1.0)
    return (r, r, r, 1.0)


def np_clip_vector(varyings, uniforms, frag):
    c = np.clip(varyings.color, 0.0, 1.0)
    return (c[0], c[1], c[2], 1.0)


def np_norm(varyings, uniforms, frag):
    r = np.linalg.norm(varyings.color)
    return (r, r, r, 1.0)


def np_normalize(varyings, uniforms, frag):
    n = varyings.color / np.linalg.norm(varyings.color)
    return (n[0], n[1], n[2], 1.0)


def np_max(varyings, uniforms, frag):
    r = np.max(varyings.color)
    return (r, r, r, 1.0)


def np_mean(varyings, uniforms, frag):
    r = np.mean(varyings.color)
    return (r, r, r, 1.0)


def np_sqrt(varyings, uniforms, frag):
    r = np.sqrt(varyings.color)
    return (r[0], r[1], r[2], 1.0)


def np_round(varyings, uniforms, frag):
    c = np.round(varyings.color, 2)
    return (c[0], c[1], c[2], 1.0)


def dot_helper(c):
    return np.dot(c, c)


def np_in_a_helper(varyings, uniforms, frag):
    r = dot_helper(varyings.color)
    return (r, r, r, 1.0)


def calls_breakpoint(varyings, uniforms, frag):
    breakpoint()
    return (1.0, 1.0, 1.0, 1.0)


def imports_pdb(varyings, uniforms, frag):
    import pdb
    pdb.set_trace()
    return (1.0, 1.0, 1.0, 1.0)


def imports_math(varyings, uniforms, frag):
    import math
    return (math.sqrt(0.25), 0.0, 0.0, 1.0)


def global_statement(varyings, uniforms, frag):
    global COUNT
    COUNT = 1
    return (1.0, 0.0, 0.0, 1.0)


def list_global(varyings, uniforms, frag):
    return (LIST[0], 0.0, 0.0, 1.0)


def dict_global(varyings, uniforms, frag):
    return (DICT["red"], 0.0, 0.0, 1.0)


def scales_with_star(varyings, uniforms, frag):
    c = varyings.color * 0.5
    return (c[0], c[1], c[2], 1.0)


def repeats_with_star(varyings, uniforms, frag):
    c = varyings.color * 2
    return (c[0], c[1], c[2], 1.0)


def subtracts_tuples(varyings, uniforms, frag):
    c = varyings.color - (0.5, 0.5, 0.5)
    return (c[0], c[1], c[2], 1.0)


def negates_a_tuple(varyings, uniforms, frag):
    c = -varyings.color
    return (c[0], c[1], c[2], 1.0)


def sets_an_item(varyings, uniforms, frag):
    c = varyings.color
    c[0] = 1.0
    return (c[0], c[1], c[2], 1.0)


def min_of_tuples(varyings, uniforms, frag):
    c = min(varyings.color, (0.5, 0.5, 0.5))
    return (c[0], c[1], c[2], 1.0)


def abs_of_a_tuple(varyings, uniforms, frag):
    c = abs(varyings.color)
    return (c[0], c[1], c[2], 1.0)


def math_dist(varyings, uniforms, frag):
    r = math.dist(varyings.color, (0.0, 0.0, 0.0))
    return (r, r, r, 1.0)


def dot_x(varyings, uniforms, frag):
    return (varyings.color.x, 0.0, 0.0, 1.0)


def misspelt_varying(varyings, uniforms, frag):
    c = varyings.colour
    return (c[0], c[1], c[2], 1.0)


def returns_rgb(varyings, uniforms, frag):
    c = varyings.color
    return (c[0], c[1], c[2])


SH = "softpipe.shading."
NUMPY_WHAT = "does not take a shader's values: vectors are tuples and numbers floats, not numpy arrays"
OPERATOR = "operators do not work on vectors (tuples)"

MISTAKES = [
    (np_dot, "d = np.dot(c, (1, 1, 1))", f"np.dot() {NUMPY_WHAT}", f"use {SH}dot(a, b)"),
    (np_clip, "r = np.clip(varyings.color[0] * 2.0, 0.0, 1.0)", f"np.clip() {NUMPY_WHAT}",
     f"use {SH}clamp(x, lo, hi) (saturate(x) for 0..1)"),
    (np_clip_vector, "c = np.clip(varyings.color, 0.0, 1.0)", f"np.clip() {NUMPY_WHAT}",
     f"use {SH}clamp(x, lo, hi) (saturate(x) for 0..1)"),
    (np_norm, "r = np.linalg.norm(varyings.color)", f"np.linalg.norm() {NUMPY_WHAT} (and numpy.linalg needs scipy)",
     f"use {SH}length(v) (distance(a, b) between two points; normalize(v) for the unit vector)"),
    (np_normalize, "n = varyings.color / np.linalg.norm(varyings.color)",
     f"np.linalg.norm() {NUMPY_WHAT} (and numpy.linalg needs scipy)",
     f"use {SH}length(v) (distance(a, b) between two points; normalize(v) for the unit vector)"),
    (np_max, "r = np.max(varyings.color)", f"np.max() {NUMPY_WHAT}", f"use {SH}max_component(v)"),
    (np_mean, "r = np.mean(varyings.color)", f"np.mean() {NUMPY_WHAT}", f"use {SH}hsum(v) / 3.0 (for a vec3)"),
    (np_sqrt, "r = np.sqrt(varyings.color)", f"np.sqrt() {NUMPY_WHAT}",
     "use math.sqrt on each component: vec3(math.sqrt(v[0]), math.sqrt(v[1]), math.sqrt(v[2]))"),
    (np_round, "c = np.round(varyings.color, 2)", f"np.round() {NUMPY_WHAT}",
     "use the GLSL-like functions of softpipe.shading on tuples (dot, cross, length, normalize, clamp, mix, …) "
     "and math's on numbers"),
    (np_in_a_helper, "return np.dot(c, c)", f"np.dot() {NUMPY_WHAT}", f"use {SH}dot(a, b)"),
    (calls_breakpoint, "breakpoint()", "breakpoint() cannot run in compiled code", DEBUG_HINT),
    (imports_pdb, "import pdb", "pdb (a debugger) cannot run in compiled code", DEBUG_HINT),
    (imports_math, "import math", "it imports 'math' inside the function: compiled code cannot import",
     "import math at the top of the module"),
    (global_statement, "COUNT = 1",
     "it assigns the module global 'COUNT' (global COUNT): compiled code cannot change a global",
     "keep the value in a local variable; what a shader needs from outside, pass as a uniform"),
    (list_global, "return (LIST[0], 0.0, 0.0, 1.0)", "the global 'LIST' is a list, which compiled code cannot read",
     "make it a tuple (LIST = (…)) or a numpy array; a global a shader reads is fixed at each draw"),
    (dict_global, 'return (DICT["red"], 0.0, 0.0, 1.0)',
     "the global 'DICT' (a dict) cannot be used in compiled code",
     "make it a tuple or a numpy array, or give each value a global (or a uniform) of its own; a shader may read "
     "globals that are numbers, bools, tuples, numpy arrays or functions"),
    (scales_with_star, "c = varyings.color * 0.5", f"cannot compute * of (tuple of 3 float64, float64): {OPERATOR}",
     f"use {SH}scale(v, s) by a number, mul(a, b) componentwise"),
    (repeats_with_star, "c = varyings.color * 2", f"cannot compute * of (tuple of 3 float64, 2): {OPERATOR}",
     f"use {SH}scale(v, s) by a number, mul(a, b) componentwise"),
    (subtracts_tuples, "c = varyings.color - (0.5, 0.5, 0.5)",
     f"cannot compute - of (tuple of 3 float64, tuple of 3 float64): {OPERATOR}", f"use {SH}sub(a, b)"),
    (negates_a_tuple, "c = -varyings.color", f"cannot compute unary - of (tuple of 3 float64): {OPERATOR}",
     f"use {SH}neg(v)"),
    (sets_an_item, "c[0] = 1.0", "a tuple cannot be changed in place (here a tuple of 3 float64)",
     "make a new one: v = (x, v[1], v[2])"),
    (min_of_tuples, "c = min(varyings.color, (0.5, 0.5, 0.5))",
     "min() of a vector (a tuple) cannot be compiled: (tuple of 3 float64, tuple of 3 float64)",
     f"use {SH}vmin(a, b) componentwise, min_component(v) for the smallest"),
    (abs_of_a_tuple, "c = abs(varyings.color)", "abs() of a vector (a tuple) cannot be compiled: (tuple of 3 float64)",
     f"use {SH}vabs(v)"),
    (math_dist, "r = math.dist(varyings.color, (0.0, 0.0, 0.0))", "math.dist is not available in compiled code",
     f"use {SH}distance(a, b)"),
    (dot_x, "return (varyings.color.x, 0.0, 0.0, 1.0)", "a tuple has no attribute 'x'",
     "vectors are tuples: use the GLSL functions of softpipe.shading (add, sub, scale, mul, dot, length, "
     "normalize, …) rather than operators or numpy (v[0], not v.x)"),
    (misspelt_varying, "c = varyings.colour", "varyings has no field 'colour' (did you mean 'color'?); "
     "its fields are: color", None),
]


def line_of(fn, text):
    lines, first = inspect.getsourcelines(fn)
    return first + next(k for k, line in enumerate(lines) if line.strip() == text)


@pytest.mark.parametrize("shader, text, what, hint", MISTAKES, ids=[m[0].__name__ for m in MISTAKES])
def test_each_mistake_gets_its_message_at_the_users_line(shader, text, what, hint):
    with pytest.raises(ShaderError) as info:
        draw(shader)
    function = dot_helper if shader is np_in_a_helper else shader
    line = line_of(function, text)
    expected = [f"fragment shader test_shader_mistakes.{shader.__name__} cannot be compiled: {what}",
                f'  File "{__file__}", line {line}, in {function.__name__}', f"    {text}"]
    expected += [f"  ({hint})"] if hint else []
    assert str(info.value) == "\n".join(expected + [FULL_TEXT])
    assert (info.value.file, info.value.line) == (__file__, line)


def test_a_wrong_return_names_the_return():
    with pytest.raises(ShaderError) as info:
        draw(returns_rgb)
    line = line_of(returns_rgb, "return (c[0], c[1], c[2])")
    assert str(info.value) == (
        "fragment shader test_shader_mistakes.returns_rgb must return an RGBA tuple of 4 floats (or DISCARD), "
        f'got a tuple of 3 floats\n  File "{__file__}", line {line}, in returns_rgb\n    return (c[0], c[1], c[2])')


# ------------------------------------------------------------------ + of tuples: compiles, and is wrong

def brightens_with_plus(varyings, uniforms, frag):
    c = varyings.color
    c = c + (0.1, 0.1, 0.1)
    return (c[0], c[1], c[2], 1.0)


def brightens_with_plus_equals(varyings, uniforms, frag):
    c = (0.5, 0.5, 0.5)
    c += (0.1, 0.1, 0.1)
    return (c[0], c[1], c[2], 1.0)


def appends_alpha(varyings, uniforms, frag):
    c = varyings.color
    return c + (1.0,)


def appends_two(varyings, uniforms, frag):
    c = varyings.color
    return c[:2] + (0.0, 1.0)


@pytest.mark.parametrize("shader, text", [(brightens_with_plus, "c = c + (0.1, 0.1, 0.1)"),
                                          (brightens_with_plus_equals, "c += (0.1, 0.1, 0.1)")])
def test_plus_of_a_literal_tuple_is_refused_before_the_draw(shader, text):
    fb = sp.Framebuffer(8, 8)
    before = fb.color.copy()
    with pytest.raises(ShaderError) as info:
        sp.draw(fb, FULL, QUAD, varyings={"color": np.ones((4, 3))}, fragment_shader=shader)
    assert str(info.value) == (
        f"fragment shader test_shader_mistakes.{shader.__name__} adds a tuple with +, which joins tuples: "
        "(r, g, b) + (0.1, 0.1, 0.1) is 6 values, not a brighter color\n"
        f'  File "{__file__}", line {line_of(shader, text)}, in {shader.__name__}\n    {text}\n'
        "  (use softpipe.shading.add(a, b) (scale(v, s) to multiply by a number); to append a component, "
        "write the tuple out: (c[0], c[1], c[2], 1.0))")
    assert np.array_equal(fb.color, before)                 # nothing drawn


def test_appending_components_with_plus_is_left_alone():
    assert draw(appends_alpha).color[0, 0].tolist() == [1.0, 1.0, 1.0, 1.0]
    assert draw(appends_two).color[0, 0].tolist() == [1.0, 1.0, 0.0, 1.0]


# ------------------------------------------------------------------ the parameters a shader takes

def fragment_of_two(frag, uniforms):
    return (1.0, 1.0, 1.0, 1.0)


def vertex_of_three(attributes, uniforms, frag):
    return (attributes.position[0], attributes.position[1], 0.0, 1.0), ()


def fragment_with_a_default(varyings, uniforms, frag, derivatives=None, extra=1.0):
    return (1.0, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("stage, shader, names, takes", [
    ("fragment", fragment_of_two, "frag, uniforms",
     "(varyings, uniforms, frag), or (varyings, uniforms, frag, derivatives)"),
    ("vertex", vertex_of_three, "attributes, uniforms, frag", "(attributes, uniforms)"),
])
def test_a_shader_with_the_wrong_parameters_is_named_at_its_def(stage, shader, names, takes):
    fb = sp.Framebuffer(8, 8)
    before = fb.color.copy()
    with pytest.raises(ShaderError) as info:
        if stage == "vertex":
            sp.draw(fb, FULL[:, :2], QUAD, vertex_shader=shader)
        else:
            sp.draw(fb, FULL, QUAD, varyings={"color": np.ones((4, 3))}, fragment_shader=shader)
    n = len(names.split(", "))
    assert str(info.value) == (
        f"{stage} shader test_shader_mistakes.{shader.__name__} takes {n} parameters ({names}); a {stage} shader "
        f"takes {takes}\n"
        f'  File "{__file__}", line {shader.__code__.co_firstlineno}, in {shader.__name__}\n'
        f"    def {shader.__name__}({names}):")
    assert (info.value.file, info.value.line) == (__file__, shader.__code__.co_firstlineno)
    assert np.array_equal(fb.color, before)


def test_a_shader_whose_extra_parameters_have_defaults_is_taken():
    assert draw(fragment_with_a_default).color[0, 0].tolist() == [1.0, 1.0, 1.0, 1.0]


# ------------------------------------------------------------------ a notebook cell

CELL = '''\
import numpy as np
def cell_shader(varyings, uniforms, frag):
    c = varyings.color
    d = np.dot(c, (1, 1, 1))
    return (d, d, d, 1.0)
'''


def test_a_shader_in_a_notebook_cell_is_named_as_ipython_names_the_cell(monkeypatch, tmp_path):
    """ipykernel compiles cell 7 into a temporary file and registers its text with linecache;
    IPython's compiler maps the file back to its cell (``format_code_name``)."""
    filename = str(tmp_path / "ipykernel_4242" / "2715303548.py")
    linecache.cache[filename] = (len(CELL), None, CELL.splitlines(keepends=True), filename)
    namespace = {"__name__": "__main__"}
    exec(compile(CELL, filename, "exec"), namespace)

    class Compiler:
        def format_code_name(self, name):
            return ("Cell", "In[7]") if name == filename else None

    shell = types.SimpleNamespace(compile=Compiler())
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    try:
        with pytest.raises(ShaderError) as info:
            draw(namespace["cell_shader"])
    finally:
        linecache.cache.pop(filename, None)
    assert str(info.value) == "\n".join([
        f"fragment shader __main__.cell_shader cannot be compiled: np.dot() {NUMPY_WHAT}",
        "  Cell In[7], line 4, in cell_shader", "    d = np.dot(c, (1, 1, 1))", f"  (use {SH}dot(a, b))", FULL_TEXT])
    assert (info.value.file, info.value.line) == (filename, 4)


# ------------------------------------------------------------------ the traceback ends in the user's code

SCRIPT = '''\
import numpy as np
import softpipe as sp


def bad(varyings, uniforms, frag):
    return (np.dot(varyings.color, varyings.color), 0.0, 0.0, 1.0)


fb = sp.Framebuffer(8, 8)
sp.draw(fb, np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1.0]]), [0, 1, 2],
        varyings={"color": np.ones((3, 3))}, fragment_shader=bad)
'''


@pytest.mark.parametrize("debug", ["", "1"])
def test_a_script_s_traceback_ends_at_the_users_call(tmp_path, debug):
    script = tmp_path / "scene.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, SOFTPIPE_SHADER_DEBUG=debug)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 1
    frames = [line for line in run.stderr.splitlines() if line.startswith('  File "')]
    if debug:           # every frame, softpipe's included
        assert any(os.sep + "softpipe" + os.sep in line for line in frames), run.stderr
        return
    assert run.stderr.startswith(
        "Traceback (most recent call last):\n"
        f'  File "{script}", line 10, in <module>\n'
        "    sp.draw(fb, np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1.0]]), [0, 1, 2],\n"
        "softpipe.language.contract.ShaderError: fragment shader __main__.bad cannot be compiled: "
        f"np.dot() {NUMPY_WHAT}\n"
        f'  File "{script}", line 6, in bad\n'), run.stderr


def test_in_ipython_a_shader_error_is_shown_without_softpipe_s_frames(monkeypatch):
    """IPython's custom-exception handler gets the traceback without softpipe's frames."""
    from softpipe.language.kernels import diagnostics

    shown = {}

    class TB:
        def structured_traceback(self, etype, value, tb, tb_offset=None):
            shown["files"] = []
            while tb is not None:
                shown["files"].append(tb.tb_frame.f_code.co_filename)
                tb = tb.tb_next
            return ["the traceback"]

    class Shell:
        custom_exceptions = ()
        InteractiveTB = TB()

        def set_custom_exc(self, types_, handler):
            self.custom_exceptions, self.handler = types_, handler

        def _showtraceback(self, etype, value, stb):
            # IPython shows nothing a custom handler returns: the handler must show it (a Jupyter
            # kernel's _showtraceback sends it to the notebook)
            shown["displayed"] = stb

    shell = Shell()
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    monkeypatch.delenv("SOFTPIPE_SHADER_DEBUG", raising=False)
    diagnostics.hide_internal_frames()
    assert shell.custom_exceptions == (ShaderError,)
    try:
        draw(np_dot)
    except ShaderError as e:
        error, tb = e, e.__traceback__
    assert shell.handler(shell, ShaderError, error, tb) == ["the traceback"]
    assert shown["displayed"] == ["the traceback"]
    assert shown["files"] == [__file__, __file__]          # this test, then draw() above: nothing of softpipe's
    monkeypatch.setenv("SOFTPIPE_SHADER_DEBUG", "1")
    shell.handler(shell, ShaderError, error, tb)
    assert any("softpipe" + os.sep + "pipeline" in f for f in shown["files"])

