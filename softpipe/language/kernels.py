"""How shaders run: the generated loops that inline them, numba's compilation and cache, errors.

For each (shader, varying layout) softpipe writes a small Python module: a loop
over the batch with the unpacking of attributes or varyings written out by name
(:func:`kernel_source` shows it), and compiles it with numba; the shader is
inlined into that loop. Under ``NUMBA_DISABLE_JIT=1`` the same loop runs as
Python, so a breakpoint in a shader stops there.

- **Vertex loop** (:func:`vertex_kernel`): attributes in, clip position and varyings out.
- **Fragment loops** (:func:`fragment_module`): ``interpolate`` (the varyings at
  barycentrics, with their qualifiers), ``fragment_loop`` (the reference path: one
  row per fragment) and ``visible_loop`` (the fast path: the samples the
  visibility pass kept, with barycentrics, depth and position from the same
  triangle setup functions the rasterizer uses). The color a fragment shader
  returns goes through :func:`rgba`, which refuses (when numba types it) anything
  but 4 numbers.
- **What a shader is compiled with** (:func:`shader_globals_key`): numba reads a
  function's globals once, when it compiles it. So the module globals a shader
  reads (numbers, bools, strings, tuples, numpy arrays), and those its helpers
  read, are part of the key a compiled loop is kept under: a draw after one of
  them changed compiles a new loop, a draw after none did compiles nothing. The
  loop is compiled from a copy of the shader whose globals are a snapshot, in
  which each plain Python function it calls (recursively, from any module) is
  an ``njit``'ed copy of its own: helpers need no decorator. The user's function
  itself is untouched: ``NUMBA_DISABLE_JIT=1``, ``trace.debug_fragment`` and the
  probes run it as written.
- **The cache**: softpipe's own shaders get their generated module written to
  ``$SOFTPIPE_CACHE_DIR`` (default ``~/.cache/softpipe/kernels``) so numba's
  on-disk cache can find them in the next process (the file's name hashes the
  globals' values too); a user's shader is compiled once per process and set of
  global values.
- **Errors**: :func:`run_compiled` turns numba's errors into a
  :class:`~softpipe.language.contract.ShaderError` that says in a few lines what is wrong
  and names the user's file and line (numba's own text is on
  ``err.numba_message``, and in the message with ``SOFTPIPE_SHADER_DEBUG=1``).
  An exception the shader raises while it runs is reported with the invocation
  it happened on (the fragment's pixel, sample and primitive, or the vertex):
  the compiled loop is re-run on halves of the batch to find it, then that one
  invocation runs as plain Python for the exception and its line.
- **Analysis**: :func:`may_discard` (does a shader return DISCARD: decides the
  fast path), :func:`probe_vertex_shader` (the varyings a vertex shader makes).

A generated module imports only :mod:`softpipe.language.contract` (the contract), this
module (``jit_function``, ``rgba``, ``short_repr``) and, for the fragment loops, the
triangle setup's per-sample functions (:mod:`softpipe.pipeline.setup`:
``pixel_coverage``, ``shading_point``, ``sample_depth``, the ones the rasterizer
calls): ``_HEADER`` and ``_FRAGMENT_IMPORTS`` below are every import it has.
"""
from __future__ import annotations

import difflib
import dis
import hashlib
import importlib
import importlib.util
import linecache
import os
import re
import sys
import threading
import types
import weakref
from pathlib import Path
from typing import Any, Callable, Dict, Sequence, Tuple

import numba
import numpy as np
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.extending import intrinsic, overload

from softpipe.core.files import atomic_write
from softpipe.language.contract import (ShaderError, VaryingLayout, _field_size, _names_from_class_name, python_function, shader_name,
                     wants_derivatives)

__all__ = ["vertex_kernel", "fragment_module", "fragment_kernel", "visible_kernel", "python_fragment_module",
           "kernel_source", "run_compiled", "may_discard", "alpha_is_finite", "may_raise", "probe_vertex_shader", "probe_fragment_shader",
           "jit_function", "rgba", "shader_globals_key", "vertex_site", "fragment_site", "visible_site"]

def borrowed_uniforms(uniforms):
    """The uniforms with every array in them *borrowed*: the same data, no owner attached (plain Python: as they are).

    numba counts references to every array a value holds, with an atomic add and an
    atomic subtract each time the value is bound or passed on; a shader that reads
    ``uniforms.lighting`` once per sample paid that for every array inside it, per
    sample (an empty ShadowUniform's six arrays made the bunny's lit shading 70 %
    slower). A generated loop borrows its uniforms once, before its first sample;
    the draw holds the real ones until the loop returns, so the data stay alive.
    """
    return uniforms


def _borrow_value(context, builder, typ, value):
    """``value`` of numba type ``typ`` with the meminfo of every array in it set to NULL (recursively)."""
    if isinstance(typ, nbtypes.Array):
        array = context.make_array(typ)(context, builder, value=value)
        array.meminfo = cgutils.get_null_value(array.meminfo.type)
        return array._getvalue()
    if isinstance(typ, nbtypes.BaseTuple):
        out = value
        for k, item_type in enumerate(typ.types):
            item = builder.extract_value(value, k)
            out = builder.insert_value(out, _borrow_value(context, builder, item_type, item), k)
        return out
    return value


@intrinsic
def _borrowed_uniforms_intrinsic(typingctx, uniforms):
    def codegen(context, builder, signature, args):
        return _borrow_value(context, builder, signature.args[0], args[0])
    return uniforms(uniforms), codegen


@overload(borrowed_uniforms, inline="always")
def _borrowed_uniforms_numba(uniforms):
    return lambda uniforms: _borrowed_uniforms_intrinsic(uniforms)


def jit_function(fn: Callable) -> Callable:
    """``fn`` as a numba dispatcher (compiling a plain function on first call)."""
    if not callable(fn):
        raise TypeError(f"a shader must be a function, got {type(fn).__name__}")
    if isinstance(fn, numba.core.registry.CPUDispatcher):
        return fn
    if numba.config.DISABLE_JIT:
        return fn
    return numba.njit(fn, inline="always")


# ----------------------------------------------- globals and helpers: the snapshot

def _is_softpipe(fn) -> bool:
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


def _helper_kind(value) -> str | None:
    """"plain" for a Python function numba cannot call as it is, "jit" for a user's njit'ed
    function, None for anything else (numbers, numba's own and softpipe's functions, modules…)."""
    if isinstance(value, numba.core.registry.CPUDispatcher):
        return None if _is_softpipe(value) else "jit"
    if isinstance(value, types.FunctionType):
        if _is_softpipe(value) or _numba_knows(value):
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


def _user_module(value) -> bool:
    """A module of the user's (not softpipe, not installed, not the standard library): its functions
    called as ``module.helper(…)`` are helpers, its numbers globals like the shader's own."""
    if not isinstance(value, types.ModuleType) or _is_softpipe(value) or value.__name__ == "softpipe":
        return False
    file = getattr(value, "__file__", None)
    return bool(file) and not os.path.realpath(file).startswith(_LIBRARY_DIRS)


def _reads(f) -> list:
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
        if _user_module(value):
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
    for name, value in _reads(f):
        key = _global_key(value, seen)
        if key is not None:
            items.append((name, key))
    return tuple(items)


def _global_key(value, seen: set):
    if _helper_kind(value) is not None:
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


def _key_text(key) -> str:
    """The key as text that is the same in every process (for the on-disk cache's file names)."""
    if isinstance(key, types.CodeType):
        return f"{key.co_filename}:{key.co_firstlineno}:{key.co_qualname if hasattr(key, 'co_qualname') else ''}"
    if isinstance(key, tuple):
        return "(" + ",".join(_key_text(k) for k in key) + ")"
    return repr(key)


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
            cells.append(types.CellType(_snapshot_helper(value, memo) if _helper_kind(value) else value))
        cells = tuple(cells)
    copy = types.FunctionType(f.__code__, glob, f.__name__, f.__defaults__, cells)
    copy.__kwdefaults__ = f.__kwdefaults__
    copy.__qualname__, copy.__module__, copy.__doc__ = f.__qualname__, f.__module__, f.__doc__
    result = memo[id(f)] = make(copy)
    names = _global_names(f.__code__)
    for name in names:
        value = glob.get(name)
        if value is None:
            continue
        if _helper_kind(value) is not None:
            glob[name] = _snapshot_helper(value, memo)
        elif _user_module(value) and any(_helper_kind(vars(value).get(a)) for a in names):
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
        if value is not None and _helper_kind(value) is not None:
            setattr(proxy, attr, _snapshot_helper(value, memo))
    return proxy


_JIT_OPTIONS = ("fastmath", "error_model", "inline", "boundscheck", "nogil")


def _snapshot_helper(value, memo: dict) -> Callable:
    """A helper the shader calls, as numba compiles it: an njit'ed copy over a snapshot of its globals."""
    options = {}
    if isinstance(value, numba.core.registry.CPUDispatcher):
        options = {k: v for k, v in value.targetoptions.items() if k in _JIT_OPTIONS}
    return _copy_function(python_function(value), memo, lambda copy: numba.njit(copy, **options))


def shader_snapshot(shader: Callable) -> Callable:
    """The function numba compiles for ``shader``: a copy whose globals are today's values, its plain
    Python helpers njit'ed copies of themselves (recursively). A numba dispatcher stays one."""
    f = python_function(shader)
    if not isinstance(f, types.FunctionType):
        return shader
    if isinstance(shader, numba.core.registry.CPUDispatcher):
        return _snapshot_helper(shader, {})
    return _copy_function(f, {}, lambda copy: copy)


# ------------------------------------------------------------ code generation

def _tuple_expr(array: str, index: str, offset: int, size: int) -> str:
    if size == 1:
        return f"{array}[{index}, {offset}]"
    parts = ", ".join(f"{array}[{index}, {offset + c}]" for c in range(size))
    return f"({parts})"


_KERNELS: Dict[Any, Any] = {}


def _cache_dir() -> Path:
    """Where generated kernel modules (and numba's cache of them) live."""
    root = os.environ.get("SOFTPIPE_CACHE_DIR")
    if root:
        return Path(root)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "softpipe" / "kernels"


def _importable_cache(directory: Path) -> None:
    """Put the kernel directory on sys.path: numba's cache may name a generated module's
    types, and unpickling them imports that module by name."""
    if str(directory) not in sys.path:
        sys.path.append(str(directory))


if _cache_dir().is_dir():       # so even a first cache lookup can import what it names
    _importable_cache(_cache_dir())


_PACKAGE_HASH: list = []


def _package_hash() -> str:
    """A hash of softpipe's own sources: a generated kernel inlines them, so it depends on them."""
    if not _PACKAGE_HASH:
        h = hashlib.sha256()
        pkg = Path(__file__).resolve().parents[1]          # softpipe/: language/ is one of its folders
        for f in sorted(pkg.rglob("*.py")):
            h.update(str(f.relative_to(pkg)).encode())
            h.update(f.read_bytes())
        _PACKAGE_HASH.append(h.hexdigest()[:16])
    return _PACKAGE_HASH[0]


def _importable(shader: Callable) -> Tuple[str, str] | None:
    """(module, name) if the shader is one of softpipe's own module-level functions.

    Only these are cached on disk: numba cannot see when a user's shader (or a
    function it calls in another file) changes, so user shaders are compiled
    once per process instead of risking a stale kernel.
    """
    f = python_function(shader)
    mod, name = getattr(f, "__module__", None) or "", getattr(f, "__qualname__", None) or ""
    if not mod.startswith("softpipe.") or "." in name or "<" in name:
        return None
    try:
        if python_function(getattr(importlib.import_module(mod), name)) is not f:
            return None
    except (ImportError, AttributeError):
        return None
    return mod, name


_HEADER = ("# Generated by softpipe.language.kernels: the loop that runs one shader over a batch.\n"
           "import numba\n"
           "from collections import namedtuple\n"
           "from softpipe.language.contract import Derivatives, FragInfo\n"
           "from softpipe.language.kernels import borrowed_uniforms, jit_function, rgba, short_repr\n")
#: What the fragment loops call besides the shader: the triangle setup's per-sample functions,
#: the very ones the rasterizer calls (a vertex loop does not need them, so they are not in _HEADER).
_FRAGMENT_IMPORTS = "from softpipe.pipeline.setup import pixel_coverage, sample_depth, shading_point\n"


def _module_source(body: str, shader: Callable, preamble: str, cached: bool) -> str:
    """The generated module: header, the shader as global ``shader``, namedtuples, then ``body``.

    Functions in ``body`` are decorated ``@JIT``; the shader is imported by
    name when the module is a cached file, and injected as ``_shader_py`` otherwise.
    """
    where = _importable(shader) if cached else None
    imp = f"from {where[0]} import {where[1]} as _shader_py\n" if where else ""
    jit = f"JIT = numba.njit(cache={bool(where)}, nogil=True)\n"
    # Namedtuple classes get names of their own per module: numba's on-disk cache
    # finds a type by module and name, and two modules' "Varyings" must not meet.
    tag = hashlib.sha256((shader_name(shader) + preamble + body).encode()).hexdigest()[:12]
    return (_HEADER + imp + "shader = jit_function(_shader_py)\n" + jit + preamble.replace("@TAG@", tag)
            + "\n\n" + body)


def _compile_module(body: str, shader: Callable, preamble: str, kind: str, globals_key: tuple = ()):
    """The generated module for a shader: a cached file for softpipe's own shaders, else exec'd.

    A cached file imports the shader by name, and numba reads its globals as they
    are when it compiles; the file's name hashes their values (``globals_key``),
    so a changed value is a new file. An exec'd module gets the shader's snapshot
    (:func:`shader_snapshot`), unless numba is off: then it runs the user's own function.
    """
    if _importable(shader) is not None and not numba.config.DISABLE_JIT:
        source = _module_source(body, shader, preamble, cached=True)
        digest = hashlib.sha256((source + _package_hash() + numba.__version__ + _key_text(globals_key)).encode()
                                ).hexdigest()[:20]
        try:
            return _load_cached(source, f"softpipe_{kind}_{digest}")
        except OSError:
            pass  # an unwritable cache directory: compile in memory instead
    source = _module_source(body, shader, preamble, cached=False)
    compiled = python_function(shader) if numba.config.DISABLE_JIT else shader_snapshot(shader)
    return _exec_module(source, shader, kind, compiled=compiled)


def _exec_module(source: str, shader: Callable, kind: str, python: bool = False, compiled: Callable | None = None):
    """exec a generated module; with ``python``, numba is left out entirely (for debugging).

    ``compiled`` is the function the module's ``shader`` is made from (default: the user's own).
    """
    module = types.ModuleType(f"softpipe_{kind}_loop")
    module._shader_py = python_function(shader) if compiled is None else compiled
    if python:
        # The same source, run as plain Python: JIT and jit_function become no-ops.
        source = source.replace("shader = jit_function(_shader_py)", "shader = _shader_py")
        source = re.sub(r"JIT = numba\.njit\([^)]*\)", "JIT = lambda f: f", source)
        source = re.sub(r"^from \S+ import \S+ as _shader_py\n", "", source, flags=re.M)
    exec(compile(source, f"<softpipe {kind} loop for {shader_name(shader)}>", "exec"), module.__dict__)
    module.__softpipe_source__ = source
    return module


#: How many compiled versions (sets of global values) of one shader and layout are kept.
_VERSIONS_KEPT = 8
_VERSIONS: Dict[Any, list] = {}


#: Held while a kernel module is built, written to the cache or loaded, and while numba
#: compiles a generated loop (:func:`run_compiled`): two threads asking for the same loop
#: build it once, and a fork waits for it (:func:`_before_fork`).
_COMPILE_LOCK = threading.RLock()


def _before_fork() -> None:
    """Before ``os.fork``: wait until no thread builds a kernel or compiles with numba, and hold both
    locks across the fork, so the child does not inherit a lock held by a thread it does not have."""
    _COMPILE_LOCK.acquire()
    numba.core.compiler_lock.global_compiler_lock.acquire()


def _after_fork() -> None:
    numba.core.compiler_lock.global_compiler_lock.release()
    _COMPILE_LOCK.release()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_before_fork, after_in_parent=_after_fork, after_in_child=_after_fork)


def _cached_module(base: tuple, shader: Callable, build: Callable):
    """The module kept for ``base`` and the shader's globals today, built (compiled) when there is none."""
    globals_key = shader_globals_key(shader)
    key = base + (globals_key,)
    module = _KERNELS.get(key)
    if module is not None:
        return module
    with _COMPILE_LOCK:
        module = _KERNELS.get(key)          # another thread may have built it meanwhile
        if module is not None:
            return module
        module = build(globals_key)
        _KERNELS[key] = module
        versions = _VERSIONS.setdefault(base, [])
        versions.append(key)
        while len(versions) > _VERSIONS_KEPT:      # a global animated per frame must not keep every loop
            _KERNELS.pop(versions.pop(0), None)
    return module


def _load_cached(source: str, module_name: str):
    directory = _cache_dir()
    directory.mkdir(parents=True, exist_ok=True)
    _importable_cache(directory)
    path = directory / f"{module_name}.py"
    with _COMPILE_LOCK:                 # one thread of this process at a time
        loaded = sys.modules.get(module_name)
        if loaded is not None and getattr(loaded, "__softpipe_source__", None) == source:
            return loaded
        if not path.exists() or path.read_text() != source:
            # a temporary file of our own (unique across processes and threads), then an atomic
            # rename: a concurrent writer never sees, nor truncates, half a file
            atomic_write(path, lambda f: f.write(source.encode()))
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module   # so numba's cache can find its namedtuple classes
        try:
            spec.loader.exec_module(module)
        except BaseException:
            sys.modules.pop(module_name, None)
            raise
        module.__softpipe_source__ = source
        return module


def kernel_source(kind: str, shader: Callable, layout: "VaryingLayout") -> str:
    """The generated Python source of a fragment (``kind="fragment"``) loop, to read it."""
    if kind != "fragment":
        raise ValueError("kernel_source: only kind='fragment' is supported")
    return fragment_module(shader, layout).__softpipe_source__


def _namedtuple_line(var: str, typename: str, names: Sequence[str]) -> str:
    unique = f"{typename}_@TAG@"
    return (f"{unique} = namedtuple({unique!r}, {list(names)!r})\n{unique}.__repr__ = short_repr\n"
            f"{var} = {unique}\n")


def short_repr(self) -> str:
    """A generated namedtuple's repr without its unique tag: ``Varyings(normal=…)``."""
    name = type(self).__name__.rsplit("_", 1)[0]
    return name + "(" + ", ".join(f"{f}={v!r}" for f, v in zip(self._fields, self)) + ")"


def vertex_kernel(shader: Callable, attr_sizes: Sequence[Tuple[str, int]], out_layout: VaryingLayout):
    """The compiled loop that runs ``shader`` over every vertex."""
    def build(globals_key):
        names = [n for n, _ in attr_sizes]
        attr_exprs = ", ".join(_tuple_expr(f"a_{n}", "i", 0, s) if s > 1 else f"a_{n}[i, 0]"
                               for n, s in attr_sizes)
        lines = [
            "@JIT",
            f"def vertex_loop(lo, hi, {', '.join(f'a_{n}' for n in names)}, uniforms, out_position, out_varyings):",
            "    uniforms = borrowed_uniforms(uniforms)",
            "    for i in range(lo, hi):",
            f"        attributes = Attributes({attr_exprs})",
            "        clip, v = shader(attributes, uniforms)",
        ]
        lines += [f"        out_position[i, {c}] = clip[{c}]" for c in range(4)]
        for j, (n, off, size, _) in enumerate(out_layout.fields):
            if size == 1:
                lines.append(f"        out_varyings[i, {off}] = v[{j}]  # {n}")
            else:
                lines += [f"        out_varyings[i, {off + c}] = v[{j}][{c}]  # {n}.{'xyzw'[c]}"
                          for c in range(size)]
        return _compile_module("\n".join(lines) + "\n", shader,
                               _namedtuple_line("Attributes", "Attributes", names), "vertex", globals_key)

    module = _cached_module(("vertex", python_function(shader), tuple(attr_sizes), out_layout.fields), shader, build)
    return module.vertex_loop


_TRIANGLE_ARGS = "inv_w, corner, front, prim_id, bary_grad"
_FRAGMENT_ARGS = "triangle, frag_x, frag_y, depth, bary, " + _TRIANGLE_ARGS


def _derivative_lines(layout: VaryingLayout, axis: int, name: str) -> list:
    """∂v/∂x (axis 0) or ∂v/∂y (axis 1) of every varying, from the barycentrics' gradients.

    smooth: v = A/B with A = Σ b_k v_k/w_k, B = Σ b_k/w_k, so ∂v = (∂A − v ∂B)/B;
    noperspective: ∂v = Σ ∂b_k v_k; flat: 0.
    """
    g = [f"bary_grad[t, {axis}, {k}]" for k in range(3)]
    lines = []
    if any(q == "smooth" for *_, q in layout.fields):
        lines.append(f"    dq{name} = {g[0]} * inv_w[t, 0] + {g[1]} * inv_w[t, 1] + {g[2]} * inv_w[t, 2]")
    exprs = []
    for n, off, size, q in layout.fields:
        comps = []
        for c, k in enumerate(range(off, off + size)):
            if q == "flat":
                comps.append("0.0")
            elif q == "noperspective":
                comps.append(" + ".join(f"{g[m]} * corner[t, {m}, {k}]" for m in range(3)))
            else:
                v = f"v_{n}" if size == 1 else f"v_{n}[{c}]"
                da = " + ".join(f"{g[m]} * inv_w[t, {m}] * corner[t, {m}, {k}]" for m in range(3))
                comps.append(f"({da} - {v} * dq{name}) / qs")
        lines.append(f"    d{name}_{n} = " + (comps[0] if size == 1 else f"({', '.join(comps)})"))
        exprs.append(f"d{name}_{n}")
    lines.append(f"    d{name} = Varyings({', '.join(exprs) or '0.0'})")
    return lines


def _fragment_body(layout: VaryingLayout, derivatives: bool = False) -> str:
    """Source of ``fragment_inputs`` (interpolation) and ``fragment_loop`` (runs the shader)."""
    lines = [
        "@JIT",
        f"def interpolate(t, b0, b1, b2, fx, fy, z, {_TRIANGLE_ARGS}):",
        '    """The varyings and FragInfo at barycentrics (b0, b1, b2) of triangle t."""',
    ]
    if any(q == "smooth" for *_, q in layout.fields):
        lines += [
            "    q0 = b0 * inv_w[t, 0]",      # perspective-correct weights: b_k / w_k, renormalized
            "    q1 = b1 * inv_w[t, 1]",
            "    q2 = b2 * inv_w[t, 2]",
            "    qs = q0 + q1 + q2",
            "    if not qs > 0.0:",         # an extrapolated pixel centre (multisampling) can make it 0
            "        q0, q1, q2, qs = b0, b1, b2, 1.0",
            # v = (Σ q_k v_k) · (1/qs): one division a fragment, which the sums need not wait for
            # (q_k/qs per weight put three divisions in front of every sum: 5-7 % of a lit sample)
            "    r = 1.0 / qs",
        ]
    exprs = []
    for n, off, size, q in layout.fields:
        comps = []
        for k in range(off, off + size):
            if q == "flat":
                comps.append(f"corner[t, 2, {k}]")
            elif q == "smooth":
                comps.append(f"(q0 * corner[t, 0, {k}] + q1 * corner[t, 1, {k}] + q2 * corner[t, 2, {k}]) * r")
            else:
                comps.append(f"b0 * corner[t, 0, {k}] + b1 * corner[t, 1, {k}] + b2 * corner[t, 2, {k}]")
        value = comps[0] if size == 1 else f"({', '.join(comps)})"
        lines.append(f"    v_{n} = {value}  # {q}")
        exprs.append(f"v_{n}")
    lines += [
        f"    varyings = Varyings({', '.join(exprs) or '0.0'})",
        "    frag = FragInfo(fx, fy, z, front[t], prim_id[t])",
    ]
    if derivatives:
        if not any(q == "smooth" for *_, q in layout.fields):
            lines.append("    qs = 1.0")
        lines += _derivative_lines(layout, 0, "x") + _derivative_lines(layout, 1, "y")
        lines.append("    return varyings, frag, Derivatives(dx, dy)")
    else:
        lines.append("    return varyings, frag")
    inputs = "varyings, frag, derivatives" if derivatives else "varyings, frag"
    call = f"shader({inputs.replace('varyings, frag', 'varyings, uniforms, frag')})"
    lines += [
        "",
        "",
        "@JIT",
        f"def fragment_inputs(i, {_FRAGMENT_ARGS}):",
        '    """The varyings and FragInfo of fragment i, exactly as the shader receives them."""',
        "    return interpolate(triangle[i], bary[i, 0], bary[i, 1], bary[i, 2], frag_x[i], frag_y[i], depth[i],",
        f"                       {_TRIANGLE_ARGS})",
        "",
        "",
        "@JIT",
        f"def fragment_loop({_FRAGMENT_ARGS}, uniforms, out_color):",
        "    uniforms = borrowed_uniforms(uniforms)",
        "    for i in range(triangle.shape[0]):",
        f"        {inputs} = fragment_inputs(i, {_FRAGMENT_ARGS})",
        f"        c = rgba({call})",
        "        out_color[i, 0] = c[0]",
        "        out_color[i, 1] = c[1]",
        "        out_color[i, 2] = c[2]",
        "        out_color[i, 3] = c[3]",
        "",
        "",
    ]
    lines += _visible_loop_lines("visible_loop", inputs, call, at_samples=False)
    lines += ["", ""] + _visible_loop_lines("visible_loop_at_samples", inputs, call, at_samples=True)
    return "\n".join(lines) + "\n"


def _visible_loop_lines(name: str, inputs: str, call: str, at_samples: bool) -> list:
    """Source of the fast path's shading loop ``name``; ``at_samples``: for ``shading`` 0 only."""
    mode = "0" if at_samples else "shading"
    choose = (["                    mask, depth_sample, count = 0, s, 1"] if at_samples else [
        "                    if shading == 0:           # at the sample",
        "                        mask, depth_sample, count = 0, s, 1",
        "                    else:                      # multisampling: once per pixel and triangle",
        "                        earlier = -1",
        "                        for m in range(s):",
        "                            if vis[m, row, i] == t:",
        "                                earlier = m",
        "                                break",
        "                        if earlier >= 0:",
        "                            if status[0] != 0:       # (its color may not have been written)",
        "                                continue",
        "                            for c in range(4):",
        "                                out_color[s, row, i, c] = out_color[earlier, row, i, c]",
        "                            continue",
        "                        mask, depth_sample, count = pixel_coverage(edges, bias, t, i, j, offsets)",
    ])
    return [
        "@JIT",
        f"def {name}(row_lo, row_hi, vis, touched, tile_w, tile_h, edges, bias, plane, offsets, positions,",
        f"                 shading, {_TRIANGLE_ARGS}, uniforms, out_color, saved_color, started, status):",
        '    """Shade the samples the visibility pass kept (visibility.py), image rows row_lo:row_hi.',
        "",
        "    ``visible_loop_at_samples`` is this loop for ``shading`` 0 alone (each visible sample",
        "    shaded at itself): without the multisampling branches, its first compile is a fifth",
        "    shorter, and a draw that shades at the samples compiles only it.",
        "",
        "    Barycentrics, depth and position come from the triangle setup's functions (setup.py), as",
        "    the rasterizer's do. Tiles no triangle touched are skipped; each sample is shaded on its",
        "    own, so the order (tile, sample, column) does not change a byte.",
        "",
        "    ``shading`` 1 or 2 (multisampling at the pixel centre or at the centroid): a triangle is",
        "    shaded once per pixel, as the rasterizer's run of its samples there is, with the depth",
        "    of the first sample it covers (visible or not); its other visible samples copy the color.",
        "",
        "    So that a draw that fails leaves the framebuffer as it was (visibility.shade_visible):",
        "    before a row is shaded, the colors its visible samples hold are copied to saved_color",
        "    (unless it is empty) and started[row] is set; a NaN alpha (DISCARD, which the reference",
        "    path discards) is not written: status[0] = 1 and every band stops at its next row",
        "    (the row under way writes no copy of a color it may not have written).",
        '    """',
        "    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]",
        "    save = saved_color.shape[0] > 0",
        "    uniforms = borrowed_uniforms(uniforms)",
        "    for row in range(row_lo, row_hi):",
        "        if status[0] != 0:",
        "            return",
        "        j = height - 1 - row",
        "        if save:",
        "            for tile_x in range(touched.shape[1]):",
        "                if touched[j // tile_h, tile_x]:",
        "                    for s in range(samples):",
        "                        for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):",
        "                            if vis[s, row, i] >= 0:",
        "                                for c in range(4):",
        "                                    saved_color[s, row, i, c] = out_color[s, row, i, c]",
        "            started[row] = True",
        "        for tile_x in range(touched.shape[1]):",
        "            if not touched[j // tile_h, tile_x]:",
        "                continue",
        "            for s in range(samples):",
        "                for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):",
        "                    t = vis[s, row, i]",
        "                    if t < 0:",
        "                        continue",
        *choose,
        "                    b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets,",
        f"                                                       positions, {mode})",
        "                    z = sample_depth(edges, plane, t, i, j, depth_sample, offsets)",
        f"                    {inputs} = interpolate(t, b0, b1, b2, fx, fy, z, {_TRIANGLE_ARGS})",
        f"                    c = rgba({call})",
        "                    if c[3] == c[3]:",
        "                        out_color[s, row, i, 0] = c[0]",
        "                        out_color[s, row, i, 1] = c[1]",
        "                        out_color[s, row, i, 2] = c[2]",
        "                        out_color[s, row, i, 3] = c[3]",
        "                    else:                      # NaN alpha: the reference path discards it",
        "                        status[0] = 1",
    ]


def _fragment_preamble(layout: VaryingLayout) -> str:
    return _FRAGMENT_IMPORTS + _namedtuple_line("Varyings", "Varyings", list(layout.names) or ["none"])


def fragment_module(shader: Callable, layout: VaryingLayout):
    return _fragment_module(shader, layout, wants_derivatives(shader))


def _fragment_module(shader: Callable, layout: VaryingLayout, derivatives: bool):
    """The generated module holding ``fragment_inputs`` and ``fragment_loop`` for a shader and layout.

    Interpolation (DESIGN.md): ``smooth`` is perspective-correct,
    Σ q_k v_k / Σ q_k with q_k = b_k/w_k; ``noperspective`` uses the window-space barycentrics
    b_k directly; ``flat`` takes the provoking vertex's value, which primitive
    assembly has copied to every corner.
    """
    return _cached_module(("fragment", python_function(shader), layout.fields, derivatives), shader,
                          lambda globals_key: _compile_module(_fragment_body(layout, derivatives), shader,
                                                              _fragment_preamble(layout), "fragment", globals_key))


def fragment_kernel(shader: Callable, layout: VaryingLayout):
    """The compiled loop that interpolates varyings and runs ``shader`` per fragment."""
    return fragment_module(shader, layout).fragment_loop


def visible_kernel(shader: Callable, layout: VaryingLayout, shading: str = "sample"):
    """The compiled loop that shades the samples a visibility pass kept (:mod:`softpipe.pipeline.visibility`).

    ``shading`` "sample" (at each sample) has a loop of its own, ``visible_loop_at_samples``;
    "center" and "centroid" (once per pixel and triangle) share ``visible_loop``.
    """
    module = fragment_module(shader, layout)
    return module.visible_loop_at_samples if shading == "sample" else module.visible_loop


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
    for code in _codes(f.__code__):
        if _NAN_NAMES & set(code.co_names):
            return True
        for const in code.co_consts:
            if _discard_value(const) or (isinstance(const, str) and const.strip().lower().lstrip("+-") == "nan"):
                return True
    for _, value in _reads(f):
        if _discard_value(value):
            return True
        if callable(value) and isinstance(python_function(value), types.FunctionType) and not _is_softpipe(value):
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
    for code in _codes(f.__code__):
        for inst in dis.get_instructions(code):
            if inst.opname in _RAISING_OPNAMES or (inst.opname == "BINARY_OP"
                                                   and inst.argrepr in _RAISING_BINARY):
                return True
    for _, value in _reads(f):
        if isinstance(value, types.ModuleType):
            if value.__name__ not in _QUIET_MODULES and not _is_softpipe(value) and not _user_module(value):
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


def python_fragment_module(shader: Callable, layout: VaryingLayout):
    """The same generated module as plain Python (no numba), for stepping through one fragment."""
    source = _module_source(_fragment_body(layout, wants_derivatives(shader)), shader, _fragment_preamble(layout),
                            cached=False)
    return _exec_module(source, shader, "fragment", python=True)


def probe_vertex_shader(shader: Callable, attributes, uniforms) -> Tuple[Tuple[float, ...], Any]:
    """Run a vertex shader once in plain Python to learn the names and sizes it outputs."""
    f = python_function(shader)
    try:
        out = f(attributes, uniforms)
    except Exception as e:  # the user's code: report where, keep the cause
        raise _raised_error("vertex", shader, e, "vertex 0", e) from _from_shader(e, shader)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ShaderError(f"vertex shader {shader_name(shader)} must return (clip_position, varyings), "
                          f"got {type(out).__name__}", **_def_site(shader))
    clip, varyings = out
    if not (isinstance(clip, tuple) and len(clip) == 4):
        raise ShaderError(f"vertex shader {shader_name(shader)}: clip position must be a tuple of 4 floats, "
                          f"got {clip!r}", **_def_site(shader))
    if not (isinstance(varyings, tuple) and hasattr(varyings, "_fields")):
        raise ShaderError(f"vertex shader {shader_name(shader)}: varyings must be a namedtuple, "
                          f"got {type(varyings).__name__}", **_def_site(shader))
    sizes = [(n, _field_size(n, "varying", v)) for n, v in zip(varyings._fields, varyings)]
    return clip, VaryingLayout.from_sizes(sizes)


def probe_fragment_shader(shader: Callable, varyings, uniforms, frag) -> None:
    """Run a fragment shader once in plain Python and check what it returns (as :func:`rgba` does)."""
    f = python_function(shader)
    try:
        out = f(varyings, uniforms, frag)
    except Exception as e:
        raise _raised_error("fragment", shader, e, None, e) from _from_shader(e, shader)
    try:
        rgba(out)
    except _BadReturn as e:
        raise _return_error("fragment", shader, e) from None


# ------------------------------------------------------------------ return values

class _BadReturn(Exception):
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


def rgba(color):
    """The color a fragment shader returned, checked: a tuple of 4 numbers (DISCARD is one).

    numba checks it once, when it compiles the loop (see the overload below); as
    plain Python (``NUMBA_DISABLE_JIT=1``) it is checked on every call.
    """
    if not (isinstance(color, tuple) and len(color) == 4 and all(isinstance(c, _NUMBERS) for c in color)):
        raise _BadReturn(_python_value_text(color))
    return color


@overload(rgba)
def _rgba_typed(color):
    nt = numba.core.types
    if isinstance(color, nt.BaseTuple) and len(list(color)) == 4 and all(
            isinstance(t, (nt.Number, nt.Boolean)) for t in color):
        return lambda color: color
    raise _BadReturn(_numba_type_text(color))     # not a NumbaError: numba lets it through as it is


def _return_lines(f) -> list:
    """Line numbers of a function's return statements (not of nested functions)."""
    code = getattr(f, "__code__", None)
    if code is None:
        return []
    return sorted({line for inst, line in _instructions(code) if inst.opname in ("RETURN_VALUE", "RETURN_CONST")
                   and line is not None})


def _return_error(kind: str, shader: Callable, e: _BadReturn) -> ShaderError:
    f = python_function(shader)
    lines = _return_lines(f)
    site = {"file": f.__code__.co_filename, "line": lines[0]} if lines else _def_site(shader)
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


def _codes(code):
    yield code
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _codes(const)


def _user_functions(shader: Callable) -> list:
    """The shader and the helpers compiled with it (those that are not numba's or softpipe's), in call order."""
    out, seen = [], set()

    def walk(f):
        f = python_function(f)
        if not isinstance(f, types.FunctionType) or id(f) in seen:
            return
        seen.add(id(f))
        out.append(f)
        for _, value in _reads(f):
            if _helper_kind(value) is not None:
                walk(value)

    walk(shader)
    return out


def _def_site(shader: Callable) -> dict:
    f = python_function(shader)
    code = getattr(f, "__code__", None)
    if code is None:
        return {}
    return {"file": code.co_filename, "line": code.co_firstlineno}


def _frame_text(file: str | None, line: int | None, name: str) -> str:
    """A traceback's two lines for file:line: ``File "…", line N, in name`` and the source line."""
    if file is None:
        return ""
    text = f'  File "{file}", line {line}, in {name}'
    source = linecache.getline(file, line).strip() if line else ""
    return text + (f"\n    {source}" if source else "")


_LOCATION = re.compile(r'File "(?P<f1>[^"]+)", line (?P<l1>\d+)|\bat (?P<f2>[^\s<][^\n]*?) \((?P<l2>\d+)\)')


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
            lines = {n for c in _codes(code) for _, _, n in c.co_lines() if n is not None}
            if line in lines:
                return {"file": code.co_filename, "line": line, "function": f.__name__}
    return None


def _name_site(functions: list, name: str, ops: Tuple[str, ...]) -> dict | None:
    """Where the shader or a helper loads ``name`` (a global, or an attribute), first found."""
    for f in functions:
        for code in _codes(f.__code__):
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
        return "uniforms", tuple(_names_from_class_name(typename))
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


def _explain_compile_error(text: str, kernel, functions: list) -> Tuple[str, dict | None, str]:
    """(what is wrong, where, a hint) from numba's message."""
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
        owner = next((f for f in functions if site and f.__name__ == site["function"]), None)
        if owner is not None and name in owner.__globals__:
            # numba says so of a global it has no type for, inlined into the loop
            return (f"the global {name!r} (a {type(owner.__globals__[name]).__name__}) cannot be used in "
                    "compiled code", site, _GLOBALS_HINT)
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
                _GLOBALS_HINT)
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
        site = dict(_def_site(shader), function=getattr(f, "__name__", "?"))
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

def _from_shader(exc: BaseException, shader: Callable) -> BaseException:
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
    codes = {c for f in _user_functions(shader) for c in _codes(f.__code__)}
    site, tb = None, exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code in codes:
            site = {"file": tb.tb_frame.f_code.co_filename, "line": tb.tb_lineno,
                    "function": tb.tb_frame.f_code.co_name}
        tb = tb.tb_next
    return site


def _raised_error(kind: str, shader: Callable, exc: BaseException, where: str | None,
                  python_exc: BaseException | None) -> ShaderError:
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


def _plain(value):
    """numpy scalars (as the Python loop reads them from arrays) as Python's: 1.0 / 0.0 raises, as compiled."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        items = [_plain(v) for v in value]
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
    twin = _exec_module(func.__globals__["__softpipe_source__"], shader, kind, python=True)
    noted: Dict[str, Any] = {}
    user = python_function(shader)

    def noting(*args):
        try:
            return user(*(_plain(a) for a in args))
        except Exception as e:
            noted.update(exc=e, args=args, locals=dict(sys._getframe(1).f_locals))
            raise

    twin.shader = noting
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
    try:
        if _needs_compiling(kernel):
            with _COMPILE_LOCK:         # one compile at a time; a fork waits for it
                kernel(*args)
        else:
            kernel(*args)
    except _BadReturn as e:
        raise _return_error(kind, shader, e) from None
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
        cause = _from_shader(python_exc, shader) if python_exc is not None else e
        raise _raised_error(kind, shader, shown, where, python_exc) from cause
