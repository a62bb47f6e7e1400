"""What a shader is compiled with: the globals it reads, and the snapshot numba compiles.

numba reads a function's globals once, when it compiles it. So the module
globals a shader reads (numbers, bools, strings, tuples, numpy arrays), and
those its helpers read, are part of the key a compiled loop is kept under
(:func:`shader_globals_key`): a draw after one of them changed compiles a new
loop, a draw after none did compiles nothing.

The loop is compiled from :func:`shader_snapshot`: a copy of the shader whose
globals are a snapshot, in which each plain Python function it calls
(recursively, from any module) is an ``njit``'ed copy of its own, so helpers
need no decorator. The user's function itself is untouched:
``NUMBA_DISABLE_JIT=1``, ``trace.debug_fragment`` and the probes run it as written.

The readers of a function's code here (:func:`reads`, :func:`helper_kind`,
:func:`nested_codes`) serve the analysis and the error messages too
(:mod:`.analysis`, :mod:`.diagnostics`). More: docs/shaders.md.
"""
from __future__ import annotations

import dis
import hashlib
import marshal
import os
import sys
import types
import weakref
from typing import Any, Callable, Dict, Iterator, Tuple, cast

import numba
import numpy as np

from softpipe.language.contract import python_function

__all__ = ["shader_globals_key", "shader_snapshot", "shader_source_key", "code_digest", "key_text", "reads", "helper_kind", "is_softpipe",
           "user_module", "nested_codes"]


def is_softpipe(fn: Any) -> bool:
    """Is ``fn`` (a function, a dispatcher, a module) one of softpipe's own?"""
    mod = getattr(python_function(fn), "__module__", None) or ""
    return mod == "softpipe" or mod.startswith("softpipe.")


_NUMBA_KNOWS: "weakref.WeakSet" = weakref.WeakSet()


def _numba_knows(fn) -> bool:
    """Has numba an implementation of this plain function already (``register_jitable``, ``overload``)?"""
    try:
        if fn in _NUMBA_KNOWS:
            return True
    except TypeError:
        return False
    from numba.core.registry import cpu_target
    ctx = cpu_target.typing_context
    ctx.refresh()                       # registrations made since numba last looked
    try:
        ctx.resolve_value_type(fn)
    except Exception:
        return False
    _NUMBA_KNOWS.add(fn)
    return True


def helper_kind(value: Any) -> str | None:
    """"plain" for a Python function numba cannot call as it is, "jit" for a user's njit'ed
    function, None for anything else (numbers, numba's own and softpipe's functions, modules…)."""
    if isinstance(value, numba.core.registry.CPUDispatcher):
        return None if is_softpipe(value) else "jit"
    if isinstance(value, types.FunctionType):
        if is_softpipe(value) or _numba_knows(value):
            return None
        return "plain"
    return None


_NAMES: Dict[Any, Tuple[str, ...]] = {}


def _global_names(code) -> Tuple[str, ...]:
    """The names a code object (and the functions and lambdas nested in it) may read as globals."""
    names = _NAMES.get(code)
    if names is None:
        found = dict.fromkeys(code.co_names)
        for const in code.co_consts:
            if isinstance(const, types.CodeType):
                found.update(dict.fromkeys(_global_names(const)))
        names = _NAMES[code] = tuple(found)
    return names


def _value_key(value):
    """A key for a global value numba freezes into the code it compiles, or None (not such a value)."""
    if isinstance(value, (bool, np.bool_)):
        return ("bool", bool(value))
    if isinstance(value, (int, float, complex, str, np.number)):
        return (type(value).__name__, repr(value))
    if isinstance(value, tuple):
        parts = tuple(_value_key(v) for v in value)
        return (type(value).__qualname__,) + tuple(("?", id(v)) if k is None else k for k, v in zip(parts, value))
    if isinstance(value, np.ndarray) and value.dtype != object:
        digest = hashlib.sha1(np.ascontiguousarray(value).view(np.uint8).reshape(-1)).hexdigest()
        return ("ndarray", value.dtype.str, value.shape, digest)
    return None


_LIBRARY_DIRS = tuple({os.path.join(os.path.realpath(p), "") for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)})


def user_module(value: Any) -> bool:
    """A module of the user's (not softpipe, not installed, not the standard library): its functions
    called as ``module.helper(…)`` are helpers, its numbers globals like the shader's own."""
    if not isinstance(value, types.ModuleType) or is_softpipe(value) or value.__name__ == "softpipe":
        return False
    file = getattr(value, "__file__", None) or ""
    return bool(file) and not os.path.realpath(file).startswith(_LIBRARY_DIRS)


def reads(f: types.FunctionType) -> list:
    """(name, value) of what a function may read besides its arguments: the globals its code names,
    its closure's cells, and (as ``module.name``) the attributes it names of a user's module."""
    code, glob = f.__code__, f.__globals__
    names = _global_names(code)
    out = []
    for name in names:
        if name not in glob:
            continue
        value = glob[name]
        out.append((name, value))
        if user_module(value):
            attrs = vars(value)
            out += [(f"{name}.{attr}", attrs[attr]) for attr in names if attr in attrs]
    for name, cell in zip(code.co_freevars, f.__closure__ or ()):
        try:
            out.append((name, cell.cell_contents))
        except ValueError:              # an empty cell
            pass
    return out


def _function_key(fn, seen: set) -> tuple:
    f = python_function(fn)
    if not isinstance(f, types.FunctionType):
        return ()
    if id(f) in seen:
        return ("recursive",)
    seen.add(id(f))
    items = []
    for name, value in reads(f):
        key = _global_key(value, seen)
        if key is not None:
            items.append((name, key))
    return tuple(items)


def _global_key(value, seen: set):
    if helper_kind(value) is not None:
        f = python_function(value)
        return ("function", f.__code__, _function_key(f, seen))
    return _value_key(value)


def shader_globals_key(shader: Callable) -> tuple:
    """What a shader is compiled for besides its code: the values of the globals it reads.

    The names its code (and the plain Python helpers it calls, recursively)
    reads whose value is a number, bool, string, tuple or numpy array, with
    that value (an array by its bytes). softpipe's own helper functions are
    left out: their globals are constants.
    """
    return _function_key(shader, set())


def key_text(key: Any) -> str:
    """The key as text that is the same in every process (for the on-disk cache's file names)."""
    if isinstance(key, types.CodeType):
        return f"{key.co_filename}:{key.co_firstlineno}:{key.co_qualname if hasattr(key, 'co_qualname') else ''}"
    if isinstance(key, tuple):
        return "(" + ",".join(key_text(k) for k in key) + ")"
    return repr(key)


# ------------------------------------------------------------------ the key of a user's kernel on disk

def code_digest(code: types.CodeType) -> str:
    """A digest of what a code object compiles to (its bytecode, names, constants, line numbers and
    nested functions), the same in every process; its file's name is left out, which a notebook
    cell's changes from one session to the next."""
    def anonymous(c: types.CodeType) -> types.CodeType:
        consts = tuple(anonymous(k) if isinstance(k, types.CodeType) else k for k in c.co_consts)
        return c.replace(co_filename="", co_consts=consts)
    return hashlib.sha256(marshal.dumps(anonymous(code))).hexdigest()


_LOADS = frozenset({"LOAD_GLOBAL", "LOAD_NAME"})


def _loaded_globals(code: types.CodeType) -> Tuple[str, ...]:
    """The names a code object (and those nested in it) loads as globals: not ``frag.x``'s ``x``."""
    return tuple(dict.fromkeys(ins.argval for c in nested_codes(code) for ins in dis.get_instructions(c)
                               if ins.opname in _LOADS))


def _library_name(value: Any) -> str | None:
    """The name of a module, or ``module.qualname`` of a function or class of softpipe, an installed package
    or the standard library (what it is follows from the versions in the key); else None."""
    if isinstance(value, types.ModuleType):     # a user's: the attributes read are keyed as ``module.name``
        return f"module {value.__name__}"
    f = python_function(value)
    qualname = getattr(f, "__qualname__", None)     # an object (a Material, a list) has none: its value matters
    if not isinstance(qualname, str) or not callable(value):
        return None
    if is_softpipe(value):
        return f"softpipe {f.__module__}.{qualname}"
    module = sys.modules.get(getattr(f, "__module__", None) or "")
    if module is None or module.__name__ == "__main__" or user_module(module):
        return None
    return f"library {module.__name__}.{qualname}"


def _source_parts(f: types.FunctionType, seen: set, parts: list) -> bool:
    """Add to ``parts`` the key of ``f`` and of what it reads, recursively; False if one cannot be keyed."""
    if id(f) in seen:
        return True
    seen.add(id(f))
    if sys.modules.get(f.__module__) is None:
        # numba's cache names a function by its module, and loads it by importing that by name: a
        # function exec'd in a namespace of its own (not a module of sys.modules) cannot be loaded
        return False
    parts.append(f"def {f.__qualname__} {code_digest(f.__code__)}")
    for default in (f.__defaults__ or ()) + tuple((f.__kwdefaults__ or {}).values()):
        key = _value_key(default)
        if key is None:
            return False
        parts.append(f"  default {key_text(key)}")
    loaded = set(_loaded_globals(f.__code__)) | set(f.__code__.co_freevars)
    for name, value in reads(f):
        if name.split(".")[0] not in loaded:          # an attribute's name (``frag.x``), not a global
            continue
        kind = helper_kind(value)
        if kind is not None:
            helper = python_function(value)
            if not isinstance(helper, types.FunctionType):
                return False
            options = {k: v for k, v in getattr(value, "targetoptions", {}).items() if k in _JIT_OPTIONS}
            parts.append(f"  {name} = {kind} function {helper.__qualname__} {sorted(options.items())!r}")
            if not _source_parts(helper, seen, parts):
                return False
            continue
        key = _value_key(value)
        text = key_text(key) if key is not None else _library_name(value)
        if text is None or "'?'" in text:            # an object of the user's (a list, a class…), or a tuple of them
            if "." in name:     # ``mytools.x``: a name the shader uses as an attribute, maybe of another object
                continue
            return False
        parts.append(f"  {name} = {text}")
    return True


def shader_source_key(shader: Callable) -> str | None:
    """Everything of the user's a shader's compiled kernel depends on, as text the same in every process.

    The code of the shader and of the plain Python and ``njit`` helpers it calls,
    recursively (:func:`code_digest`: bytecode, constants, line numbers; not the file's
    name), the value of every global they read (numbers, bools, strings, tuples, numpy
    arrays by their bytes) and the name of every function, class or module they read of
    softpipe, the standard library or an installed package (those follow from the
    versions the cache key holds). None when a global is something else (a list, an
    object or a class of the user's), or a function is of no module of ``sys.modules``
    (exec'd in a namespace of its own): such a shader is compiled once per process.
    """
    f = python_function(shader)
    if not isinstance(f, types.FunctionType):
        return None
    options = {k: v for k, v in getattr(shader, "targetoptions", {}).items() if k in _JIT_OPTIONS}
    parts: list = [f"shader {sorted(options.items())!r}"]     # an njit'ed shader is compiled with its options
    return "\n".join(parts) if _source_parts(f, set(), parts) else None


def _copy_function(f: types.FunctionType, memo: dict, make: Callable) -> Callable:
    """``make(copy)`` of ``f`` where the copy's globals are a snapshot with its helpers replaced, recursively."""
    if id(f) in memo:
        return memo[id(f)]
    glob = dict(f.__globals__)
    cells = None
    if f.__closure__:
        cells = []
        for cell in f.__closure__:
            try:
                value = cell.cell_contents
            except ValueError:
                cells.append(cell)
                continue
            cells.append(types.CellType(_snapshot_helper(value, memo) if helper_kind(value) else value))
    copy = types.FunctionType(f.__code__, glob, f.__name__, f.__defaults__, None if cells is None else tuple(cells))
    copy.__kwdefaults__ = f.__kwdefaults__
    copy.__qualname__, copy.__module__, copy.__doc__ = f.__qualname__, f.__module__, f.__doc__
    result = memo[id(f)] = make(copy)
    names = _global_names(f.__code__)
    for name in names:
        value = glob.get(name)
        if value is None:
            continue
        if helper_kind(value) is not None:
            glob[name] = _snapshot_helper(value, memo)
        elif user_module(value) and any(helper_kind(vars(value).get(a)) for a in names):
            glob[name] = _module_snapshot(value, names, memo)
    return result


def _module_snapshot(module: types.ModuleType, names, memo: dict) -> types.ModuleType:
    """A stand-in for a user's module whose helpers (the attributes in ``names``) are njit'ed copies."""
    key = ("module", id(module))
    proxy = memo.get(key)
    if proxy is None:
        proxy = memo[key] = types.ModuleType(module.__name__, module.__doc__)
        proxy.__dict__.update(vars(module))
    for attr in names:
        value = vars(module).get(attr)
        if value is not None and helper_kind(value) is not None:
            setattr(proxy, attr, _snapshot_helper(value, memo))
    return proxy


_JIT_OPTIONS = ("fastmath", "error_model", "inline", "boundscheck", "nogil")


def _snapshot_helper(value, memo: dict) -> Callable:
    """A helper the shader calls, as numba compiles it: an njit'ed copy over a snapshot of its globals."""
    options = {}
    if isinstance(value, numba.core.registry.CPUDispatcher):
        options = {k: v for k, v in value.targetoptions.items() if k in _JIT_OPTIONS}
    return _copy_function(cast(types.FunctionType, python_function(value)), memo, lambda copy: numba.njit(copy, **options))


def shader_snapshot(shader: Callable) -> Callable:
    """The function numba compiles for ``shader``: a copy whose globals are today's values, its plain
    Python helpers njit'ed copies of themselves (recursively). A numba dispatcher stays one."""
    f = python_function(shader)
    if not isinstance(f, types.FunctionType):
        return shader
    if isinstance(shader, numba.core.registry.CPUDispatcher):
        return _snapshot_helper(shader, {})
    return _copy_function(f, {}, lambda copy: copy)


def nested_codes(code: types.CodeType) -> Iterator[types.CodeType]:
    """``code`` and the code objects of the functions, lambdas and comprehensions nested in it, at any depth."""
    yield code
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from nested_codes(const)
