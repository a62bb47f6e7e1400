"""What goes wrong in a shader, said plainly: compile errors, exceptions at run time, bad colors.

- **Running a loop** (:func:`run_compiled`): numba's errors become a
  :class:`~softpipe.language.contract.ShaderError` that says in a few lines what is
  wrong and names the user's file and line (numba's own text is on
  ``err.numba_message``, and in the message with ``SOFTPIPE_SHADER_DEBUG=1``).
- **An exception the shader raises while it runs** is reported with the invocation
  it happened on (the fragment's pixel, sample and primitive, or the vertex):
  the compiled loop is re-run on halves of the batch to find it, then that one
  invocation runs as plain Python for the exception and its line
  (:func:`vertex_site`, :func:`fragment_site`, :func:`visible_site` say how).
- **The color a fragment shader returns** goes through :func:`rgba`, which refuses
  anything but 4 numbers: once, when numba types the loop (its overload), or on
  every call as plain Python. Into a framebuffer of several attachments, its values
  go through :func:`outputs`, which checks one per attachment against its format.

The places named are found in the shader's and its helpers' bytecode (the
helpers: those compiled with it, :func:`~.snapshot.helper_kind`). More: docs/shaders.md
(errors a shader author meets), docs/07-debugging.md.
"""
from __future__ import annotations

import difflib
import dis
import inspect
import linecache
import os
import re
import sys
import types
import weakref
from typing import Any, Callable, Dict, Tuple

import numba
import numpy as np
from numba.extending import overload

from softpipe.language.contract import ShaderError, python_function, shader_name, uniforms_class_field_names
from softpipe.language.kernels.cache import COMPILE_LOCK
from softpipe.language.kernels.generate import exec_module
from softpipe.language.kernels.snapshot import helper_kind, nested_codes, reads

__all__ = ["run_compiled", "plain_value", "vertex_site", "fragment_site", "visible_site", "rgba", "finite_rgba", "BadReturn", "return_error",
           "outputs", "BadOutputs",
           "raised_error", "from_shader", "def_site",
           "shown_file", "check_tuple_arithmetic", "check_parameters", "SHADER_PARAMETERS", "users_traceback",
           "hide_internal_frames"]


# ------------------------------------------------------------------ return values

class BadReturn(Exception):
    """A fragment shader's color is not 4 numbers; the message says what it is."""


_NUMBERS = (int, float, np.integer, np.floating, bool, np.bool_)


def _python_value_text(value) -> str:
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, tuple):
        if all(isinstance(c, float) for c in value):
            return f"a tuple of {len(value)} floats"
        return f"a tuple of {len(value)} values"
    if value is None:
        return "None"
    if isinstance(value, np.ndarray):
        return "a numpy array"
    if isinstance(value, _NUMBERS):
        return "a single number"
    return f"a {type(value).__name__}"


def _numba_type_text(ty) -> str:
    nt = numba.core.types
    if isinstance(ty, (nt.UnicodeType, nt.UnicodeCharSeq, nt.CharSeq)):
        return "a string"
    if isinstance(ty, (nt.List, nt.ListType)):
        return "a list"
    if isinstance(ty, nt.Optional):
        return f"{_numba_type_text(ty.type)} or None (a path without a return?)"
    if isinstance(ty, nt.NoneType):
        return "None (no return statement?)"
    if isinstance(ty, nt.BaseTuple):
        parts = list(ty)
        if all(isinstance(t, nt.Float) for t in parts):
            return f"a tuple of {len(parts)} floats"
        return f"a tuple of {len(parts)} values"
    if isinstance(ty, nt.Array):
        return "a numpy array"
    if isinstance(ty, (nt.Number, nt.Boolean)):
        return "a single number"
    return f"a value of type {ty}"


@numba.njit(cache=True, forceinline=True)
def finite_rgba(color, s, row, i):
    """Are the four components of ``color[s, row, i]`` finite? (Their sum, in float64, is NaN or ±inf
    exactly when one is: one test a sample.) The fast path's shading loop counts the samples it writes
    that are not (softpipe.pipeline.visibility)."""
    total = (np.float64(color[s, row, i, 0]) + np.float64(color[s, row, i, 1]) + np.float64(color[s, row, i, 2])
             + np.float64(color[s, row, i, 3]))
    return total - total == 0.0


def rgba(color: Any) -> tuple:
    """The color a fragment shader returned, checked: a tuple of 4 numbers (DISCARD is one).

    numba checks it once, when it compiles the loop (see the overload below); as
    plain Python (``NUMBA_DISABLE_JIT=1``) it is checked on every call.
    """
    if not (isinstance(color, tuple) and len(color) == 4 and all(isinstance(c, _NUMBERS) for c in color)):
        raise BadReturn(_python_value_text(color))
    return color


@overload(rgba)
def _rgba_typed(color):
    nt = numba.core.types
    if isinstance(color, nt.BaseTuple) and len(list(color)) == 4 and all(
            isinstance(t, (nt.Number, nt.Boolean)) for t in color):
        return lambda color: color
    raise BadReturn(_numba_type_text(color))     # not a NumbaError: numba lets it through as it is


class BadOutputs(BadReturn):
    """A fragment shader's values do not fit the framebuffer's attachments; the message says which
    attachment and what it takes, as the end of a sentence that starts with the shader's name."""


def _value_kind(is_rgba: bool, is_int: bool, is_number: bool) -> str:
    return "rgba" if is_rgba else "int" if is_int else "float" if is_number else "other"


_NEEDS = {"rgba8": "a tuple of 4 numbers (r, g, b, a)", "rgba32f": "a tuple of 4 numbers (r, g, b, a)",
          "r32f": "one number", "r32i": "an int (int(...) converts: GL does not convert a float written to an "
                                        "integer target)"}


def _outputs_problem(spec: str, count: int | None, items: list, text: str) -> str | None:
    """What is wrong with a shader's values for the attachments ``spec``, or None.

    ``count`` is how many values the returned tuple holds (None: not a tuple), ``items`` each
    one's (kind of :func:`_value_kind`, text), ``text`` the whole value in words.
    """
    formats = [tuple(part.split(":")) for part in spec.split(",")]
    one_color = count == 4 and all(kind in ("int", "float") for kind, _ in items)   # (location 0 takes 4 numbers)
    if count != len(formats) or one_color:
        listing = ", ".join(f"{n!r}: {f}" for n, f in formats)
        return (f"draws into a framebuffer of {len(formats)} attachments ({listing}): it must return a tuple of "
                f"{len(formats)} values, one per attachment in that order (DISCARD as the first discards), got {text}")
    for k, ((name, fmt), (kind, item_text)) in enumerate(zip(formats, items)):
        fits = kind == "rgba" if fmt in ("rgba8", "rgba32f") else kind == "int" if fmt == "r32i" else kind in (
            "int", "float")
        if not fits:
            shown = "a float" if kind == "float" else item_text
            return f"returns for attachment {name!r} (location {k}, {fmt}) {shown}; it takes {_NEEDS[fmt]}"
    return None


def outputs(values: Any, spec: str) -> tuple:
    """The values a fragment shader returned into a framebuffer of several attachments, checked: a tuple
    of one per attachment of ``spec`` (:func:`~.generate.outputs_spec`), each fit for its format.

    numba checks them once, when it compiles the loop (the overload below, which reads ``spec``
    as a literal); as plain Python they are checked on every call.
    """
    def kind(v):
        is_rgba = isinstance(v, tuple) and len(v) == 4 and all(isinstance(c, _NUMBERS) for c in v)
        is_int = isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))
        return _value_kind(is_rgba, is_int, isinstance(v, _NUMBERS) and not isinstance(v, (bool, np.bool_)))

    count = len(values) if isinstance(values, tuple) else None
    items = [(kind(v), _python_value_text(v)) for v in values] if isinstance(values, tuple) else []
    problem = _outputs_problem(spec, count, items, _python_value_text(values))
    if problem:
        raise BadOutputs(problem)
    return values


@overload(outputs, prefer_literal=True)
def _outputs_typed(values, spec):
    nt = numba.core.types
    if not isinstance(spec, nt.StringLiteral):
        return None

    def kind(t):
        is_rgba = isinstance(t, nt.BaseTuple) and len(list(t)) == 4 and all(
            isinstance(c, (nt.Number, nt.Boolean)) for c in t)
        return _value_kind(is_rgba, isinstance(t, nt.Integer), isinstance(t, (nt.Integer, nt.Float)))

    parts = list(values) if isinstance(values, nt.BaseTuple) else None
    items = [(kind(t), _numba_type_text(t)) for t in parts] if parts is not None else []
    problem = _outputs_problem(spec.literal_value, None if parts is None else len(parts), items,
                               _numba_type_text(values))
    if problem:
        raise BadOutputs(problem)     # not a NumbaError: numba lets it through as it is
    return lambda values, spec: values


def _return_lines(f) -> list:
    """Line numbers of a function's return statements (not of nested functions)."""
    code = getattr(f, "__code__", None)
    if code is None:
        return []
    return sorted({line for inst, line in _instructions(code) if inst.opname in ("RETURN_VALUE", "RETURN_CONST")
                   and line is not None})


def return_error(kind: str, shader: Callable, e: BadReturn) -> ShaderError:
    """The ShaderError for a shader whose color is not 4 numbers (``e`` says what it is), at its first return."""
    f = python_function(shader)
    lines = _return_lines(f)
    site = {"file": f.__code__.co_filename, "line": lines[0]} if lines else def_site(shader)
    if isinstance(e, BadOutputs):
        message = f"{kind} shader {shader_name(shader)} {e}\n{_frame_text(site['file'], site['line'], f.__name__)}"
        return ShaderError(message, numba_message=f"outputs(): {e}", **site)
    message = (f"{kind} shader {shader_name(shader)} must return an RGBA tuple of 4 floats (or DISCARD), "
               f"got {e}\n{_frame_text(site['file'], site['line'], f.__name__)}")
    return ShaderError(message, numba_message=f"rgba(): the shader's return type is {e}", **site)


# ------------------------------------------------------------------ where in the user's code

def _instructions(code):
    """(instruction, line number) of a code object's bytecode."""
    line = None
    for inst in dis.get_instructions(code):
        positions = getattr(inst, "positions", None)
        if positions is not None and positions.lineno is not None:
            line = positions.lineno
        elif inst.starts_line:
            line = inst.starts_line
        yield inst, line


def _user_functions(shader: Callable) -> list:
    """The shader and the helpers compiled with it (those that are not numba's or softpipe's), in call order."""
    out, seen = [], set()

    def walk(f):
        f = python_function(f)
        if not isinstance(f, types.FunctionType) or id(f) in seen:
            return
        seen.add(id(f))
        out.append(f)
        for _, value in reads(f):
            if helper_kind(value) is not None:
                walk(value)

    walk(shader)
    return out


def def_site(shader: Callable) -> dict:
    """``{"file": …, "line": …}`` of the shader's ``def`` (empty for what has no code of its own)."""
    f = python_function(shader)
    code = getattr(f, "__code__", None)
    if code is None:
        return {}
    return {"file": code.co_filename, "line": code.co_firstlineno}


def shown_file(file: str) -> str | None:
    """``Cell In[n]`` for the file IPython compiled notebook cell n into (ipykernel's temporary
    ``…/ipykernel_<pid>/<hash>.py``, the terminal's ``<ipython-input-…>``), as IPython's own
    tracebacks name it; None for any other file (and when IPython is not running)."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return None
    try:
        shell = ipython.get_ipython()
        named = shell.compile.format_code_name(file) if shell is not None else None
    except Exception:           # an older IPython, or none running: the file's own name
        return None
    return " ".join(named) if named else None


def _frame_text(file: str | None, line: int | None, name: str) -> str:
    """A traceback's two lines for file:line: ``File "…", line N, in name`` (``Cell In[n], line N,
    in name`` for a notebook cell) and the source line."""
    if file is None:
        return ""
    cell = shown_file(file)
    text = f"  {cell}, line {line}, in {name}" if cell else f'  File "{file}", line {line}, in {name}'
    source = linecache.getline(file, line).strip() if line else ""
    return text + (f"\n    {source}" if source else "")


_LOCATION = re.compile(r'File "(?P<f1>[^"]+)", line (?P<l1>\d+)|\b(?:at|from) (?P<f2>[^\s<][^\n]*?) \((?P<l2>\d+)\)')


def _same_file(numba_path: str, filename: str) -> bool:
    return (numba_path == filename or filename.endswith(os.sep + numba_path)
            or os.path.abspath(numba_path) == os.path.abspath(filename))


def _numba_site(text: str, functions: list) -> dict | None:
    """The first place numba's text names that is in the shader or one of its helpers."""
    for m in _LOCATION.finditer(text):
        path, line = (m.group("f1"), m.group("l1")) if m.group("f1") else (m.group("f2"), m.group("l2"))
        line = int(line)
        for f in functions:
            code = f.__code__
            if not _same_file(path, code.co_filename):
                continue
            lines = {n for c in nested_codes(code) for _, _, n in c.co_lines() if n is not None}
            if line in lines:
                return {"file": code.co_filename, "line": line, "function": f.__name__}
    return None


def _name_site(functions: list, name: str, ops: Tuple[str, ...]) -> dict | None:
    """Where the shader or a helper loads ``name`` (a global, or an attribute), first found."""
    for f in functions:
        for code in nested_codes(f.__code__):
            for inst, line in _instructions(code):
                if inst.opname in ops and inst.argval == name and line is not None:
                    return {"file": code.co_filename, "line": line, "function": f.__name__}
    return None


# ------------------------------------------------------------------ compile errors

_GLOBAL_OPS = ("LOAD_GLOBAL", "LOAD_NAME")
_ATTR_OPS = ("LOAD_ATTR", "LOAD_METHOD")
_OPERATORS = {"add": "+", "sub": "-", "mul": "*", "truediv": "/", "floordiv": "//", "mod": "%", "pow": "**",
              "neg": "unary -", "iadd": "+=", "isub": "-=", "imul": "*=", "itruediv": "/=", "lt": "<", "gt": ">",
              "le": "<=", "ge": ">=", "eq": "==", "ne": "!="}
_GLOBALS_HINT = "a shader may read globals that are numbers, bools, tuples, numpy arrays or functions"
_VECTOR_HINT = ("vectors are tuples: use the GLSL functions of softpipe.shading (add, sub, scale, mul, dot, "
                "length, normalize, …) rather than operators or numpy")


def _plain_types(text: str) -> str:
    """numba's type names in words: ``UniTuple(float64 x 3)`` → ``tuple of 3 float64``."""
    text = re.sub(r"_[0-9a-f]{12}\b", "", text)
    text = re.sub(r"Literal\[\w+\]\(([^()]*)\)", r"\1", text)
    text = re.sub(r"UniTuple\((\w+) x (\d+)\)", r"tuple of \2 \1", text)
    text = re.sub(r"(reflected )?list\((\w+)\)(<iv=[^>]*>)?", r"list of \2", text)
    text = re.sub(r"array\((\w+), (\d)d, \w\)", r"\2-D array of \1", text)
    return text.replace("unicode_type", "str")


def _namedtuple_fields(typename: str, kernel) -> Tuple[str, Tuple[str, ...] | None]:
    """(what a shader calls it, its fields) for a namedtuple type numba names in an error."""
    if typename.startswith("Uniforms_"):
        return "uniforms", tuple(uniforms_class_field_names(typename))
    owners = {"Varyings": "varyings", "Attributes": "attributes", "FragInfo": "frag", "Derivatives": "derivatives"}
    owner = owners.get(re.sub(r"_[0-9a-f]{12}$", "", typename), typename)
    places = [getattr(getattr(kernel, "py_func", kernel), "__globals__", {})]
    places += [vars(m) for n, m in list(sys.modules.items()) if n.startswith("softpipe") and m is not None]
    for place in places:
        for value in list(place.values()):
            if isinstance(value, type) and value.__name__ == typename and hasattr(value, "_fields"):
                return owner, tuple(value._fields)
    return owner, None


def _what_numba_says(text: str) -> str:
    """numba's first line that says something (not "Failed in nopython mode pipeline")."""
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith(("Failed in", "During:", "File ")) and "- Resolution failure" not in line:
            return line
    return text.strip().splitlines()[0] if text.strip() else "(no message)"


# ------------------------------------------------------------------ the commonest mistakes, by name

_SH = "softpipe.shading."
#: numpy's functions a shader author reaches for → softpipe.shading's function on tuples
_NUMPY_FIXES = {
    "dot": _SH + "dot(a, b)", "vdot": _SH + "dot(a, b)", "inner": _SH + "dot(a, b)",
    "clip": _SH + "clamp(x, lo, hi) (saturate(x) for 0..1)",
    "linalg.norm": _SH + "length(v) (distance(a, b) between two points; normalize(v) for the unit vector)",
    "cross": _SH + "cross(a, b)",
    "maximum": _SH + "vmax(a, b)", "fmax": _SH + "vmax(a, b)",
    "minimum": _SH + "vmin(a, b)", "fmin": _SH + "vmin(a, b)",
    "max": _SH + "max_component(v)", "amax": _SH + "max_component(v)",
    "min": _SH + "min_component(v)", "amin": _SH + "min_component(v)",
    "abs": _SH + "vabs(v)", "absolute": _SH + "vabs(v)", "fabs": _SH + "vabs(v)",
    "sum": _SH + "hsum(v)", "mean": _SH + "hsum(v) / 3.0 (for a vec3)",
    "interp": _SH + "mix(a, b, t)", "power": _SH + "pow_(x, y)",
    "add": _SH + "add(a, b)", "subtract": _SH + "sub(a, b)",
    "multiply": _SH + "mul(a, b) (scale(v, s) by a number)", "divide": _SH + "div(a, b)", "negative": _SH + "neg(v)",
    "sqrt": "math.sqrt on each component: vec3(math.sqrt(v[0]), math.sqrt(v[1]), math.sqrt(v[2]))",
    "array": "a tuple: vec3(x, y, z)", "asarray": "a tuple: vec3(x, y, z)",
}
_NUMPY_HINT = ("use the GLSL-like functions of softpipe.shading on tuples (dot, cross, length, normalize, clamp, "
               "mix, …) and math's on numbers")
#: builtins a shader author calls on a tuple → softpipe.shading's
_BUILTIN_FIXES = {"min": _SH + "vmin(a, b) componentwise, min_component(v) for the smallest",
                  "max": _SH + "vmax(a, b) componentwise, max_component(v) for the largest",
                  "abs": _SH + "vabs(v)", "sum": _SH + "hsum(v)", "round": "round on each component: (round(v[0]), …)"}
#: an operator on tuples → softpipe.shading's function (numba refuses them; + of tuples concatenates)
_OPERATOR_FIXES = {"+": _SH + "add(a, b)", "+=": "a = " + _SH + "add(a, b)",
                   "-": _SH + "sub(a, b)", "-=": "a = " + _SH + "sub(a, b)",
                   "*": _SH + "scale(v, s) by a number, mul(a, b) componentwise",
                   "*=": "v = " + _SH + "scale(v, s) by a number, v = mul(a, b) componentwise",
                   "/": _SH + "scale(v, 1.0 / s) by a number, div(a, b) componentwise",
                   "/=": "v = " + _SH + "scale(v, 1.0 / s)", "unary -": _SH + "neg(v)"}
_DEBUGGERS = ("pdb", "ipdb", "pudb")
_DEBUG_HINT = ("to step through a shader, run it as plain Python: trace.debug_fragment(x, y) on the Trace of "
               "draw(..., trace=True) runs it on one pixel, NUMBA_DISABLE_JIT=1 runs every shader as Python")


def _loads(functions: list):
    """(function, code, instruction, line, the instructions before it) of every instruction of the shader
    and its helpers, nested code included."""
    for f in functions:
        for code in nested_codes(f.__code__):
            seen: list = []
            for inst, line in _instructions(code):
                yield f, code, inst, line, seen
                seen.append(inst)


def _site(f, code, line) -> dict:
    return {"file": code.co_filename, "line": line, "function": f.__name__}


def _numpy_calls(functions: list) -> list:
    """(what the code says, numpy's name, site) of each numpy function the shader or a helper names:
    ``np.linalg.norm`` → ``("np.linalg.norm", "linalg.norm", …)``; ``from numpy import clip`` too."""
    out = []
    for f in functions:
        for code in nested_codes(f.__code__):
            chain: list = []
            for inst, line in _instructions(code):
                if inst.opname in _GLOBAL_OPS:
                    value = f.__globals__.get(inst.argval)
                    if isinstance(value, types.ModuleType) and value.__name__.split(".")[0] == "numpy":
                        chain = [inst.argval, value.__name__[len("numpy."):] if "." in value.__name__ else ""]
                        continue
                    if (callable(value) and not isinstance(value, type)
                            and (getattr(value, "__module__", "") or "").split(".")[0] == "numpy"):
                        out.append((inst.argval, inst.argval, _site(f, code, line)))
                    chain = []
                elif inst.opname in _ATTR_OPS and chain:
                    chain.append(inst.argval)
                    name = ".".join(c for c in chain[1:] if c)
                    if name != "linalg":
                        out.append((".".join([chain[0]] + chain[2:]), name, _site(f, code, line)))
                        chain = []
                elif inst.opname not in ("PUSH_NULL", "PRECALL", "CACHE", "EXTENDED_ARG"):
                    chain = []
    return out


def _names_loaded(functions: list, test: Callable[[str, Any], bool]) -> dict | None:
    """The site of the first global the shader or a helper reads for which ``test(name, value)`` holds."""
    for f, code, inst, line, _ in _loads(functions):
        if inst.opname in _GLOBAL_OPS and line is not None:
            value = f.__globals__.get(inst.argval, _BUILTINS.get(inst.argval))
            if test(inst.argval, value):
                return dict(_site(f, code, line), name=inst.argval)
    return None


_BUILTINS = vars(__import__("builtins"))


def _first_op(functions: list, opname: str) -> dict | None:
    for f, code, inst, line, _ in _loads(functions):
        if inst.opname == opname and line is not None:
            return dict(_site(f, code, line), name=inst.argval)
    return None


def _known_mistake(text: str, functions: list) -> Tuple[str, dict | None, str] | None:
    """(what is wrong, where, the fix) for the mistakes shader authors make most, else None.

    Read from the shader's bytecode as much as from numba's text, so that the line
    named is the user's call (numba's own text may point into its numpy code)."""
    debugger = _names_loaded(functions, lambda n, v: n == "breakpoint" and v is _BUILTINS["breakpoint"]
                             or isinstance(v, types.ModuleType) and v.__name__ in _DEBUGGERS)
    imported = _first_op(functions, "IMPORT_NAME")
    if debugger is None and imported is not None and imported["name"] in _DEBUGGERS:
        debugger = imported
    if debugger is not None:
        name = "breakpoint()" if debugger["name"] == "breakpoint" else f"{debugger['name']} (a debugger)"
        return f"{name} cannot run in compiled code", debugger, _DEBUG_HINT
    if "STORE_GLOBAL" in text:
        site = _first_op(functions, "STORE_GLOBAL")
        name = site["name"] if site else "?"
        return (f"it assigns the module global {name!r} (global {name}): compiled code cannot change a global",
                site, "keep the value in a local variable; what a shader needs from outside, pass as a uniform")
    if imported is not None and "IMPORT_NAME" in text:
        return (f"it imports {imported['name']!r} inside the function: compiled code cannot import", imported,
                f"import {imported['name']} at the top of the module")
    site = _numba_site(text, functions)
    calls = _numpy_calls(functions)
    if site is not None:
        calls = [c for c in calls if c[2]["line"] == site["line"] and c[2]["file"] == site["file"]]
    else:       # numba's text may name only its own code (numpy.linalg's): the call it names, by name
        calls = [c for c in calls if re.search(rf"\b{re.escape(c[1].split('.')[0])}\b", text)
                 or "scipy" in text and c[1].startswith("linalg.")]
        site = calls[0][2] if calls else None
    if calls:
        shown, name, _ = calls[-1] if len(calls) > 1 and calls[-1][1] in _NUMPY_FIXES else calls[0]
        fix = _NUMPY_FIXES.get(name)
        linalg = " (and numpy.linalg needs scipy)" if name.startswith("linalg.") else ""
        return (f"{shown}() does not take a shader's values: vectors are tuples and numbers floats, "
                f"not numpy arrays{linalg}", site,
                _NUMPY_HINT if fix is None else f"use {fix}")
    m = re.search(r"The use of a (?:reflected )?(list|set|dict)\b[^,]*, assigned to variable '(\w+)' in globals", text)
    if m:
        kind, name = m.groups()
        return (f"the global {name!r} is a {kind}, which compiled code cannot read",
                _name_site(functions, name, _GLOBAL_OPS),
                f"make it a tuple ({name} = (…)) or a numpy array; a global a shader reads is fixed at each draw")
    m = re.search(r"No implementation of function Function\(<(?:built-in )?function (\w+)[^>]*>\) found for "
                  r"signature:\s*>>> \w+\(([^\n]*)\)", text)
    if m and "UniTuple" in m.group(2) or m and "Tuple(" in m.group(2):
        fn, args = m.group(1), _plain_types(m.group(2))
        if fn in _OPERATORS:
            op = _OPERATORS[fn]
            fix = _OPERATOR_FIXES.get(op)
            return (f"cannot compute {op} of ({args}): operators do not work on vectors (tuples)", site,
                    f"use {fix}" if fix else _VECTOR_HINT)
        if fn == "setitem":
            return (f"a tuple cannot be changed in place (here a {args.split(',')[0]})", site,
                    "make a new one: v = (x, v[1], v[2])")
        if fn in _BUILTIN_FIXES:
            return (f"{fn}() of a vector (a tuple) cannot be compiled: ({args})", site,
                    f"use {_BUILTIN_FIXES[fn]}")
    m = re.search(r"Unknown attribute '(\w+)' of type Module\(<module '(\w+)'", text)
    if m:
        attr, module = m.groups()
        fix = {"dist": "softpipe.shading.distance(a, b)"}.get(attr, "another function")
        return (f"{module}.{attr} is not available in compiled code", site or _name_site(functions, attr, _ATTR_OPS),
                f"use {fix}")
    return None


def _tuple_literal_operand(seen: list) -> bool:
    """Is an operand of the binary operator that follows ``seen`` (its instructions so far) a literal
    tuple of 2 or more numbers (``c + (0.1, 0.1, 0.1)``, ``(0.1, 0.1, 0.1) + c``), the other not a slice?"""
    def literal(inst):
        return (inst.opname == "LOAD_CONST" and isinstance(inst.argval, tuple) and len(inst.argval) >= 2
                and all(isinstance(c, (int, float)) for c in inst.argval))
    if len(seen) < 2:
        return False
    if literal(seen[-1]):
        return seen[-2].opname not in ("BINARY_SUBSCR", "BINARY_SLICE")
    k = len(seen) - 1
    while k > 0 and seen[k].opname in ("LOAD_ATTR", "LOAD_METHOD", "CACHE"):
        k -= 1
    return seen[k].opname in ("LOAD_FAST", "LOAD_GLOBAL", "LOAD_NAME", "LOAD_DEREF") and literal(seen[k - 1])


_TUPLE_CHECKED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


#: The parameters each kind of shader takes (softpipe.language.contract), and how many it may take.
SHADER_PARAMETERS = {"vertex": ("(attributes, uniforms)", (2,)),
                     "fragment": ("(varyings, uniforms, frag), or (varyings, uniforms, frag, derivatives)", (3, 4))}


def check_parameters(kind: str, shader: Callable) -> None:
    """Refuse a shader whose parameters do not fit its kind, naming them and its ``def`` line (numba would
    say only that it "cannot bind" the arguments)."""
    f = python_function(shader)
    if not isinstance(f, types.FunctionType) or kind not in SHADER_PARAMETERS:
        return
    code = f.__code__
    if code.co_flags & inspect.CO_VARARGS:
        return
    takes, counts = SHADER_PARAMETERS[kind]
    n, required = code.co_argcount, code.co_argcount - len(f.__defaults__ or ())
    if any(required <= c <= n for c in counts):
        return
    names = ", ".join(code.co_varnames[:n])
    raise ShaderError(f"{kind} shader {shader_name(shader)} takes {n} parameter{'s' if n != 1 else ''} ({names}); "
                      f"a {kind} shader takes {takes}\n"
                      f"{_frame_text(code.co_filename, code.co_firstlineno, f.__name__)}",
                      file=code.co_filename, line=code.co_firstlineno)


def check_tuple_arithmetic(kind: str, shader: Callable) -> None:
    """Refuse ``+`` of a vector and a literal tuple: Python and numba concatenate tuples, so
    ``c + (0.1, 0.1, 0.1)`` makes 6 values, not a brighter color (a silent wrong picture).

    Read from the bytecode of the shader and its helpers once per function; a
    literal of one value (``c + (1.0,)``, appending alpha) and a slice's
    (``c[:2] + (0.0, 1.0)``) are left alone."""
    f = python_function(shader)
    if not isinstance(f, types.FunctionType):
        return
    if f not in _TUPLE_CHECKED:
        _TUPLE_CHECKED[f] = next((_site(fn, code, line) for fn, code, inst, line, seen in _loads(_user_functions(f))
                                  if inst.opname == "BINARY_OP" and inst.argrepr in ("+", "+=")
                                  and _tuple_literal_operand(seen)), {})
    found: dict = _TUPLE_CHECKED[f]
    if found:
        raise ShaderError(
            f"{kind} shader {shader_name(shader)} adds a tuple with +, which joins tuples: (r, g, b) + "
            f"(0.1, 0.1, 0.1) is 6 values, not a brighter color\n"
            f"{_frame_text(found['file'], found['line'], found['function'])}\n"
            "  (use softpipe.shading.add(a, b) (scale(v, s) to multiply by a number); to append a "
            "component, write the tuple out: (c[0], c[1], c[2], 1.0))", file=found["file"], line=found["line"])


def _global_hint(kind: str) -> str:
    """The hint for a global of type ``kind`` that compiled code cannot read (a dict, list or set has one of its own)."""
    if kind in ("dict", "list", "set"):
        return f"make it a tuple or a numpy array, or give each value a global (or a uniform) of its own; {_GLOBALS_HINT}"
    return _GLOBALS_HINT


def _explain_compile_error(text: str, kernel, functions: list) -> Tuple[str, dict | None, str]:
    """(what is wrong, where, a hint) from numba's message."""
    known = _known_mistake(text, functions)
    if known is not None:
        return known
    m = re.search(r"Unknown attribute '(\w+)' of type ([\w.]+)", text)
    if m:
        attr, typename = m.groups()
        site = _numba_site(text, functions) or _name_site(functions, attr, _ATTR_OPS)
        if typename in ("UniTuple", "Tuple"):
            return f"a tuple has no attribute {attr!r}", site, _VECTOR_HINT + " (v[0], not v.x)"
        owner, fields = _namedtuple_fields(typename, kernel)
        what = f"{owner} has no field {attr!r}"
        if fields:
            close = difflib.get_close_matches(attr, fields, n=1)
            if close:
                what += f" (did you mean {close[0]!r}?)"
            what += f"; its fields are: {', '.join(fields)}"
        elif fields is not None:
            what += f"; there are no {owner}"
        return what, site, ""
    m = re.search(r"NameError: name '(\w+)' is not defined", text)
    if m:
        name = m.group(1)
        site = _name_site(functions, name, _GLOBAL_OPS)
        function = next((f for f in functions if site and f.__name__ == site["function"]), None)
        if function is not None and name in function.__globals__:
            # numba says so of a global it has no type for, inlined into the loop
            value = function.__globals__[name]
            return (f"the global {name!r} (a {type(value).__name__}) cannot be used in compiled code", site,
                    _global_hint(type(value).__name__))
        return (f"name {name!r} is not defined", site,
                "define it (a plain Python function is compiled with the shader) or import it in the shader's module")
    if "linalg" in text or "scipy" in text:
        site = _name_site(functions, "linalg", _ATTR_OPS)
        return ("numpy.linalg cannot be used in a shader (compiled, it needs scipy; and vectors are tuples)", site,
                "for a vector's length use softpipe.shading.length(v); dot, normalize, cross, distance are there too")
    m = re.search(r"Untyped global name '(\w+)'(?:: Cannot determine Numba type of <class '([\w.]+)'>)?", text)
    if m:
        name, kind = m.groups()
        return (f"the global {name!r}{f' (a {kind})' if kind else ''} cannot be used in compiled code",
                _numba_site(text, functions) or _name_site(functions, name, _GLOBAL_OPS),
                _global_hint(kind or ""))
    m = re.search(r"Can't unify return type from the following types: ([^\n]*)", text)
    if m:
        return (f"its return statements return different types ({_plain_types(m.group(1))})",
                _numba_site(text, functions), "return the same kind of value everywhere: floats, 1.0 not 1")
    m = re.search(r"Cannot unify (.*?) for '(\w+)'", text)
    if m:
        return (f"the variable {m.group(2)!r} holds different types ({_plain_types(m.group(1))})",
                _numba_site(text, functions), "give it one type on every path: floats, 1.0 not 1")
    m = re.search(r"No implementation of function Function\(<(?:built-in )?function (\w+)[^>]*>\) found for "
                  r"signature:\s*>>> \w+\(([^\n]*)\)", text)
    if m:
        fn, args = m.group(1), _plain_types(m.group(2))
        site = _numba_site(text, functions)
        if fn in _OPERATORS:
            return f"cannot compute {_OPERATORS[fn]} of ({args})", site, _VECTOR_HINT
        return f"{fn}() cannot be called with ({args})", site, _VECTOR_HINT if "tuple" in args else ""
    return _plain_types(_what_numba_says(text)), _numba_site(text, functions), ""


def _describe_compile_error(kind: str, shader: Callable, err: Exception, kernel=None) -> ShaderError:
    """One short paragraph: what is wrong, the user's file and line, a hint; numba's text on the side."""
    text = str(err) or type(err).__name__
    if not isinstance(err, numba.core.errors.NumbaError):
        text = f"{type(err).__name__}: {text}"
    functions = _user_functions(shader)
    try:
        what, site, hint = _explain_compile_error(text, kernel, functions)
    except Exception:           # never hide the error behind a bug in explaining it
        what, site, hint = _what_numba_says(text), None, ""
    f = python_function(shader)
    if site is None:
        site = dict(def_site(shader), function=getattr(f, "__name__", "?"))
    lines = [f"{kind} shader {shader_name(shader)} cannot be compiled: {what}"]
    frame = _frame_text(site.get("file"), site.get("line"), site.get("function", "?"))
    if frame:
        lines.append(frame)
    if hint:
        lines.append(f"  ({hint})")
    lines.append("  (the compiler's full text is err.numba_message; SOFTPIPE_SHADER_DEBUG=1 adds it here)")
    message = "\n".join(lines)
    if os.environ.get("SOFTPIPE_SHADER_DEBUG", "") not in ("", "0"):
        message += "\n--- numba's message ---\n" + text
    return ShaderError(message, file=site.get("file"), line=site.get("line"), numba_message=text)


_NUMBA_DIR = os.path.dirname(numba.__file__) + os.sep


def _while_compiling(err: Exception) -> bool:
    """Was ``err`` raised by numba compiling the loop (not by the compiled loop running)?"""
    if isinstance(err, numba.core.errors.NumbaError):
        return True
    tb = err.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename.startswith(_NUMBA_DIR):
            return True
        tb = tb.tb_next
    return False


# ------------------------------------------------------------------ run-time errors

def from_shader(exc: BaseException, shader: Callable) -> BaseException:
    """``exc`` with its traceback starting at the shader's frame (softpipe's own frames left out)."""
    code = getattr(python_function(shader), "__code__", None)
    tb = exc.__traceback__
    while tb is not None and tb.tb_frame.f_code is not code:
        tb = tb.tb_next
    if tb is not None:
        exc.__traceback__ = tb
    return exc


def _raise_site(exc: BaseException, shader: Callable) -> dict | None:
    """The deepest frame of the exception's traceback in the shader or one of its helpers."""
    codes = {c for f in _user_functions(shader) for c in nested_codes(f.__code__)}
    site, tb = None, exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code in codes:
            site = {"file": tb.tb_frame.f_code.co_filename, "line": tb.tb_lineno,
                    "function": tb.tb_frame.f_code.co_name}
        tb = tb.tb_next
    return site


def raised_error(kind: str, shader: Callable, exc: BaseException, where: str | None,
                 python_exc: BaseException | None) -> ShaderError:
    """The ShaderError for an exception ``exc`` the shader raised, on the invocation ``where`` (in words),
    at the line of the user's code ``python_exc`` (the same exception, raised as plain Python) passed."""
    lines = [f"{kind} shader {shader_name(shader)} raised {type(exc).__name__}: {exc}"]
    if where:
        lines[0] += f", on {where}"
    site = _raise_site(python_exc, shader) if python_exc is not None else None
    if site:
        lines.append(_frame_text(site["file"], site["line"], site["function"]))
    site = site or {}
    return ShaderError("\n".join(lines), file=site.get("file"), line=site.get("line"), invocation=where)


def _bisect(run: Callable, count: int) -> int | None:
    """An index in [0, count) on which ``run(lo, hi)`` raises, found by halving the range (None: none does)."""
    lo, hi = 0, count
    while hi - lo > 1:
        mid = (lo + hi) // 2
        try:
            run(lo, mid)
        except Exception:
            hi = mid
            continue
        lo = mid
    if hi <= lo:
        return None
    try:
        run(lo, hi)
    except Exception:
        return lo
    return None


def plain_value(value):
    """numpy scalars in ``value`` (a tuple or named tuple, nested) as Python's, the same values.

    As the Python loop reads them from arrays; as Python's, 1.0 / 0.0 raises, as compiled,
    and they are easier to read in pdb.
    """
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        items = [plain_value(v) for v in value]
        return type(value)(*items) if hasattr(value, "_fields") else tuple(items)
    return value


def _locate(kind: str, shader: Callable, kernel, count: int, run: Callable, describe: Callable):
    """(the invocation in words, the exception it raises as plain Python) for a loop that raised.

    The compiled loop is run on halves of the batch until one invocation (or, for
    the fast path, one image row) is left; that one runs again as plain Python,
    through the generated module executed as Python, the shader wrapped to note
    its arguments and the loop's variables when it raises.
    """
    index = _bisect(lambda lo, hi: run(kernel, lo, hi), count)
    if index is None:
        return None, None
    func = getattr(kernel, "py_func", kernel)
    twin = exec_module(func.__globals__["__softpipe_source__"], shader, kind, python=True)
    noted: Dict[str, Any] = {}
    user = python_function(shader)

    def noting(*args):
        try:
            return user(*(plain_value(a) for a in args))
        except Exception as e:
            noted.update(exc=e, args=args, locals=dict(sys._getframe(1).f_locals))
            raise

    twin.shader = noting  # type: ignore[attr-defined]  # the generated module's global, replaced
    try:
        run(getattr(twin, func.__name__), index, index + 1)
    except Exception:
        pass
    return describe(index, noted), noted.get("exc")


def vertex_site(shader: Callable, kernel, count: int, args: tuple) -> Callable:
    """For :func:`run_compiled`: how to find the vertex a ``vertex_loop(lo, hi, *args)`` raised on."""
    return lambda: _locate("vertex", shader, kernel, count, lambda k, lo, hi: k(lo, hi, *args),
                           lambda i, noted: f"vertex {i}")


def fragment_site(shader: Callable, kernel, args: tuple, x, y, sample) -> Callable:
    """For :func:`run_compiled`: how to find the fragment a reference ``fragment_loop(*args)`` raised on;
    ``x``, ``y``, ``sample``: the fragments' pixels (image coordinates) and samples."""
    def run(k, lo, hi):
        if isinstance(args[-1], tuple):      # fragment_loop_outputs: the color, then the other attachments' arrays
            k(*(a[lo:hi] for a in args[:5]), *args[5:-2], args[-2][lo:hi], tuple(a[lo:hi] for a in args[-1]))
        else:
            k(*(a[lo:hi] for a in args[:5]), *args[5:-1], args[-1][lo:hi])

    def describe(i, noted):
        return (f"the fragment at pixel ({int(x[i])}, {int(y[i])}), sample {int(sample[i])}, "
                f"primitive {int(args[8][args[0][i]])} (fragment #{i})")

    return lambda: _locate("fragment", shader, kernel, len(args[0]), run, describe)


def visible_site(shader: Callable, kernel, rows: int, args: tuple) -> Callable:
    """For :func:`run_compiled`: how to find the sample a fast-path ``visible_loop(lo, hi, *args)`` raised on."""
    def describe(row, noted):
        v = noted.get("locals", {})
        if not {"i", "s", "row"} <= set(v):
            return f"a fragment in image row {row}"
        frag = noted["args"][2]
        return f"the fragment at pixel ({int(v['i'])}, {int(v['row'])}), sample {int(v['s'])}, " \
               f"primitive {int(frag.primitive_id)}"

    return lambda: _locate("fragment", shader, kernel, rows, lambda k, lo, hi: k(lo, hi, *args), describe)


def _needs_compiling(kernel) -> bool:
    """Is ``kernel`` a numba dispatcher with nothing compiled yet (its first call compiles)?"""
    return isinstance(kernel, numba.core.registry.CPUDispatcher) and not kernel.overloads


def run_compiled(kind: str, shader: Callable, kernel: Callable, *args, site: Callable | None = None) -> None:
    """Call a generated loop; turn what goes wrong into a ShaderError naming the shader and the user's line.

    A compile error (numba's, or a color that is not 4 numbers) is described in a
    few lines, numba's text kept on ``numba_message``. An exception the shader
    raised while it ran is reported with the invocation it happened on, which
    ``site`` (:func:`fragment_site`, :func:`visible_site`, :func:`vertex_site`) finds.
    """
    check_parameters(kind, shader)
    check_tuple_arithmetic(kind, shader)
    try:
        if _needs_compiling(kernel):
            with COMPILE_LOCK:         # one compile at a time; a fork waits for it
                kernel(*args)
        else:
            kernel(*args)
    except BadReturn as e:
        raise return_error(kind, shader, e) from None
    except ShaderError:
        raise
    except Exception as e:
        if _while_compiling(e):
            raise _describe_compile_error(kind, shader, e, kernel) from None
        where, python_exc = None, None
        if site is not None:
            try:
                where, python_exc = site()
            except Exception:         # finding the invocation must not hide the error itself
                pass
        shown = python_exc if python_exc is not None else e
        cause = from_shader(python_exc, shader) if python_exc is not None else e
        raise raised_error(kind, shader, shown, where, python_exc) from cause


# ------------------------------------------------------------------ the traceback a user sees

_SOFTPIPE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))) + os.sep


def _debugging() -> bool:
    return os.environ.get("SOFTPIPE_SHADER_DEBUG", "") not in ("", "0")


def users_traceback(tb: types.TracebackType | None) -> types.TracebackType | None:
    """``tb`` without softpipe's and numba's frames: a ShaderError's traceback ends at the user's call.

    The message itself names the shader's file and line; the frames between the
    user's ``draw`` and the error are softpipe's pipeline, of no use to a shader author.
    """
    kept = []
    while tb is not None:
        filename = os.path.abspath(tb.tb_frame.f_code.co_filename)
        if not filename.startswith((_SOFTPIPE_DIR, _NUMBA_DIR)):
            kept.append(tb)
        tb = tb.tb_next
    out = None
    for t in reversed(kept):
        out = types.TracebackType(out, t.tb_frame, t.tb_lasti, t.tb_lineno)
    return out


def _ipython_shader_error(shell, etype, value, tb, tb_offset=None):
    """IPython's custom-exception handler for ShaderError: shows its traceback without softpipe's frames.

    It shows it itself (``shell._showtraceback``, which a Jupyter kernel sends to the notebook):
    IPython does not show what a custom handler returns (IPython 8 and 9 call it and drop the
    result), so a handler that only returned it left a notebook cell's error blank.
    """
    if not _debugging():
        tb = users_traceback(tb) or tb
    stb = shell.InteractiveTB.structured_traceback(etype, value, tb, tb_offset=tb_offset)
    shell._showtraceback(etype, value, stb)
    return stb


def hide_internal_frames() -> None:
    """Show a ShaderError that reaches the top (a script, a notebook cell) with softpipe's frames left out.

    Wraps ``sys.excepthook`` (once) and, in IPython or Jupyter, registers a
    handler for ShaderError (when no custom handler is set there already). Other
    exceptions are shown as before; ``SOFTPIPE_SHADER_DEBUG=1`` shows every frame.
    """
    previous = sys.excepthook
    if not getattr(previous, "__softpipe__", False):
        def excepthook(etype, value, tb):
            if isinstance(value, ShaderError) and not _debugging():
                tb = users_traceback(tb) or tb
                value.__traceback__ = tb     # Python prints the exception's own traceback
            previous(etype, value, tb)

        excepthook.__softpipe__ = True  # type: ignore[attr-defined]
        sys.excepthook = excepthook
    ipython = sys.modules.get("IPython")
    try:
        shell = ipython.get_ipython() if ipython is not None else None
        if shell is not None and not getattr(shell, "custom_exceptions", ()):
            shell.set_custom_exc((ShaderError,), _ipython_shader_error)
    except Exception:           # an IPython without these: its own traceback, as before
        pass
