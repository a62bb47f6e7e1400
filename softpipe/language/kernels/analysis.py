"""What a shader's code says before it runs: the fast path's questions, and the probes.

- :func:`may_discard`: does the shader look as if it may return DISCARD or a NaN
  alpha? (decides the fast path; a hint, not a proof)
- :func:`may_raise`: can the compiled shader raise? (False is a proof; the fast
  path keeps the colors it overwrites only for a shader that may)
- :func:`alpha_is_finite`: is every alpha it returns a finite literal? (a proof, or False)
- :func:`probe_vertex_shader`, :func:`probe_fragment_shader`: run a shader once as
  plain Python, to learn the varyings a vertex shader makes and to check what it returns.

The first three read the bytecode of the shader and of the functions it calls
(:func:`~.snapshot.reads`), recursively, and run nothing. More:
docs/08-fast-path.md (when the fast path is taken, and why these are safe).
"""
from __future__ import annotations

import dis
import types
from typing import Any, Callable, Tuple

import numba
import numpy as np

from softpipe.language.contract import ShaderError, VaryingLayout, field_size, python_function, shader_name
from softpipe.language.kernels.diagnostics import (
    BadReturn,
    check_parameters,
    def_site,
    from_shader,
    raised_error,
    return_error,
    rgba,
)
from softpipe.language.kernels.snapshot import is_softpipe, nested_codes, reads, user_module

__all__ = ["may_discard", "may_raise", "alpha_is_finite", "probe_vertex_shader", "probe_fragment_shader"]


def _is_nan(value) -> bool:
    return isinstance(value, (float, np.floating)) and value != value


def _discard_value(value) -> bool:
    """Is ``value`` DISCARD, a color with a NaN alpha, or a NaN number (a global, a closure's cell)?"""
    if isinstance(value, tuple):
        return len(value) == 4 and _is_nan(value[3])
    return _is_nan(value)


#: Names that spell NaN in a shader's code: ``math.nan``, ``np.nan``, ``float("nan")`` (a constant).
_NAN_NAMES = {"DISCARD", "nan", "NaN", "NAN"}


def may_discard(shader: Callable, _seen=None) -> bool:
    """Does the shader (or a function it calls) look as if it may return DISCARD or a NaN alpha?

    A hint, not a proof: it names ``DISCARD`` or NaN (``math.nan``, ``np.nan``,
    ``float("nan")``), or reads a global or closure variable holding DISCARD, a
    color with a NaN alpha or a NaN number, here or, recursively, in a Python
    function it calls (whatever the name it is called by). Such a shader takes
    the reference path. The fast path does not rely on it: its shading loop
    checks every alpha, and a NaN one sends the draw back to the reference path
    (see :mod:`softpipe.pipeline.visibility`).
    """
    seen = set() if _seen is None else _seen
    f = python_function(shader)
    if not isinstance(f, types.FunctionType) or id(f) in seen:
        return False
    seen.add(id(f))
    for code in nested_codes(f.__code__):
        if _NAN_NAMES & set(code.co_names):
            return True
        for const in code.co_consts:
            if _discard_value(const) or (isinstance(const, str) and const.strip().lower().lstrip("+-") == "nan"):
                return True
    for _, value in reads(f):
        if _discard_value(value):
            return True
        if callable(value) and isinstance(python_function(value), types.FunctionType) and not is_softpipe(value):
            if may_discard(value, seen):
                return True
    return False


_RAISING_BINARY = ("/", "//", "%", "/=", "//=", "%=")
_RAISING_OPNAMES = ("RAISE_VARARGS", "BINARY_TRUE_DIVIDE", "BINARY_FLOOR_DIVIDE", "BINARY_MODULO",
                    "INPLACE_TRUE_DIVIDE", "INPLACE_FLOOR_DIVIDE", "INPLACE_MODULO")
#: Modules whose functions a compiled shader may call without them raising (numba's math returns NaN).
_QUIET_MODULES = ("math",)


def may_raise(shader: Callable, _seen=None) -> bool:
    """Can the compiled shader raise while it runs? (False is a proof, True may be a false alarm)

    Compiled, a shader raises only where its code says ``raise`` or ``assert``,
    or divides (``/``, ``//``, ``%``: ZeroDivisionError), or in a function it
    calls that does; anything this does not know (a callable that is not a
    Python function, a module other than ``math``) counts as raising, and so
    does everything under ``NUMBA_DISABLE_JIT`` or ``NUMBA_BOUNDSCHECK``. The
    fast path keeps the colors it overwrites only for a shader that may raise.
    """
    if numba.config.DISABLE_JIT or numba.config.BOUNDSCHECK:
        return True
    seen = set() if _seen is None else _seen
    f = python_function(shader)
    if not isinstance(f, types.FunctionType):
        return True
    if id(f) in seen:
        return False
    seen.add(id(f))
    for code in nested_codes(f.__code__):
        for inst in dis.get_instructions(code):
            if inst.opname in _RAISING_OPNAMES or (inst.opname == "BINARY_OP"
                                                   and inst.argrepr in _RAISING_BINARY):
                return True
    for _, value in reads(f):
        if isinstance(value, types.ModuleType):
            if value.__name__ not in _QUIET_MODULES and not is_softpipe(value) and not user_module(value):
                return True
        elif isinstance(value, type) or isinstance(value, types.BuiltinFunctionType):
            continue                # namedtuple classes, float, min, max, abs…
        elif callable(value):
            if may_raise(value, seen):
                return True
    return False


def alpha_is_finite(shader: Callable) -> bool:
    """Is every alpha the shader returns a finite number written in its code? (a proof, or False)

    True when each ``return`` of the shader returns a 4-tuple whose last item is
    a finite number literal, ``return (r, g, b, 1.0)``, or a constant tuple
    with one. Anything else (a variable, a helper's result) is not proven.
    """
    f = python_function(shader)
    code = getattr(f, "__code__", None)
    if code is None:
        return False
    insts = list(dis.get_instructions(code))
    returns = 0
    for k, inst in enumerate(insts):
        if inst.opname == "RETURN_CONST":
            values = [inst.argval]
        elif inst.opname == "RETURN_VALUE":
            prev = insts[k - 1] if k else None
            if prev is None or prev.is_jump_target or inst.is_jump_target:
                return False
            if prev.opname == "LOAD_CONST":
                values = [prev.argval]
            elif prev.opname == "BUILD_TUPLE" and prev.argval == 4 and k >= 2 and \
                    insts[k - 2].opname == "LOAD_CONST":
                values = [(0.0, 0.0, 0.0, insts[k - 2].argval)]
            else:
                return False
        else:
            continue
        returns += 1
        for v in values:
            if not (isinstance(v, tuple) and len(v) == 4 and isinstance(v[3], (int, float))
                    and not isinstance(v[3], bool) and np.isfinite(v[3])):
                return False
    return returns > 0


def probe_vertex_shader(shader: Callable, attributes, uniforms) -> Tuple[Tuple[float, ...], Any]:
    """Run a vertex shader once in plain Python to learn the names and sizes it outputs."""
    check_parameters("vertex", shader)
    f = python_function(shader)
    try:
        out = f(attributes, uniforms)
    except Exception as e:  # the user's code: report where, keep the cause
        raise raised_error("vertex", shader, e, "vertex 0", e) from from_shader(e, shader)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ShaderError(f"vertex shader {shader_name(shader)} must return (clip_position, varyings), "
                          f"got {type(out).__name__}", **def_site(shader))
    clip, varyings = out
    if not (isinstance(clip, tuple) and len(clip) == 4):
        raise ShaderError(f"vertex shader {shader_name(shader)}: clip position must be a tuple of 4 floats, "
                          f"got {clip!r}", **def_site(shader))
    if not (isinstance(varyings, tuple) and hasattr(varyings, "_fields")):
        raise ShaderError(f"vertex shader {shader_name(shader)}: varyings must be a namedtuple, "
                          f"got {type(varyings).__name__}", **def_site(shader))
    sizes = [(n, field_size(n, "varying", v)) for n, v in zip(varyings._fields, varyings)]
    return clip, VaryingLayout.from_sizes(sizes)


def probe_fragment_shader(shader: Callable, varyings, uniforms, frag) -> None:
    """Run a fragment shader once in plain Python and check what it returns (as :func:`rgba` does)."""
    f = python_function(shader)
    try:
        out = f(varyings, uniforms, frag)
    except Exception as e:
        raise raised_error("fragment", shader, e, None, e) from from_shader(e, shader)
    try:
        rgba(out)
    except BadReturn as e:
        raise return_error("fragment", shader, e) from None
