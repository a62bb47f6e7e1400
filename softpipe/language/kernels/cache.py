"""Where generated kernel modules are kept: in memory for a process, on disk across processes.

- **In memory** (:func:`cached_module`): one module per (loop, shader, layout) and set
  of global values the shader reads (:func:`~.snapshot.shader_globals_key`); the last
  few versions of a shader are kept, so a global animated per frame does not keep
  every loop it ever compiled.
- **On disk**: a generated module is written to ``$SOFTPIPE_CACHE_DIR`` (default
  ``~/.cache/softpipe/kernels``) so numba's on-disk cache can find it in the next
  process; numba keys its entries by that file (its path, mtime and size), so the
  file's name (:func:`cached_file_name`) hashes all the kernel depends on: its
  source, softpipe's sources and loop templates (:func:`package_hash`: a kernel
  inlines the ones and is written from the others), numba's, numpy's and Python's
  versions, and the shader's globals. softpipe's own shaders
  (:func:`importable_shader`) are imported by the module and keyed by their global
  values; a user's shader (a script's ``__main__``, a notebook cell, a module of
  theirs) is given to the module (``_shader_py``, its snapshot) and keyed by
  :func:`~.snapshot.shader_source_key`: its code and its helpers' code, not their
  files' names, and the values of the globals they read. A user's shader whose
  globals no key can name (an object of the user's) is compiled once per process.
- **Several processes at once**: each writes the module through a temporary file and
  an atomic rename, with one fixed mtime (:data:`_FILE_MTIME`), so whichever rename
  lands last, the stamp numba's index records is the file's; numba writes its own
  files whole. Both processes succeed, and the cache holds one entry.
- **One compile at a time** (:data:`COMPILE_LOCK`): two threads asking for the same
  loop build it once, and a fork waits until no thread is compiling.
- **A damaged entry is rebuilt**: a generated module file that is not the source it
  should hold is written again, and it is run from that source (no ``.pyc`` is read);
  a numba cache file (``.nbi``/``.nbc``) of softpipe's own functions or generated
  kernels that cannot be read (truncated, garbled) is dropped with a
  :class:`RuntimeWarning` and the function compiled again (:func:`_load_or_drop`),
  rather than failing every later render of the program.

More: docs/08-fast-path.md (what is compiled when), docs/batch.md (the cache on a cluster).
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import threading
import types
import warnings
from pathlib import Path
from typing import Any, Callable, Dict, List, Tuple

import numba
import numpy as np

from softpipe.core.files import atomic_write
from softpipe.language.contract import python_function
from softpipe.language.kernels.snapshot import key_text, shader_globals_key
from softpipe.language.kernels.template import template_files

__all__ = ["cached_module", "load_cached", "cached_file_name", "importable_shader", "package_hash",
           "hashed_sources", "COMPILE_LOCK"]

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


#: softpipe/ (this file is softpipe/language/kernels/cache.py)
PACKAGE_DIR = Path(__file__).resolve().parents[2]
_PACKAGE_HASH: list = []


# ------------------------------------------------------------------ damaged numba cache files

_NUMBA_LOAD_OVERLOAD = numba.core.caching.Cache.load_overload


def _is_softpipes(py_file: str) -> bool:
    """Whether numba's cache entry is for a function of softpipe's sources or of its generated kernels."""
    try:
        path = Path(py_file).resolve()
    except (OSError, RuntimeError, TypeError, ValueError):
        return False
    return any(path.is_relative_to(root) for root in (PACKAGE_DIR, _cache_dir().resolve()))


def _load_or_drop(cache, sig, target_context):
    """numba's ``Cache.load_overload``; for softpipe's functions, an entry that cannot be read is a miss.

    A truncated or garbled ``.nbi``/``.nbc`` file makes numba's loader raise (an
    ``UnpicklingError``, an ``EOFError``, …) on every later call, which a render reports
    as a shader that cannot be compiled, in every process from then on. Here the index is
    removed instead (numba writes a new one when it saves the recompiled function), a
    RuntimeWarning says which file, and numba compiles the function again. Others'
    numba functions are left to numba.
    """
    try:
        return _NUMBA_LOAD_OVERLOAD(cache, sig, target_context)
    except Exception as e:           # whatever a damaged pickle raises: compiling anew is always right
        function = getattr(cache, "_py_func", None)
        index = getattr(getattr(cache, "_cache_file", None), "_index_path", None)
        code = getattr(function, "__code__", None)
        if index is None or code is None or not _is_softpipes(code.co_filename):
            raise
        try:
            os.unlink(index)
        except FileNotFoundError:
            pass
        except OSError:
            raise e from None        # a cache entry we can neither read nor remove: numba's error stands
        name = f"{getattr(function, '__module__', '?')}.{getattr(function, '__qualname__', '?')}"
        warnings.warn(f"softpipe: numba's cache entry for {name} ({index} and its .nbc files) could not "
                      f"be read ({type(e).__name__}: {e}); it is dropped and the function compiled again",
                      RuntimeWarning, stacklevel=2)
        return None


numba.core.caching.Cache.load_overload = _load_or_drop


def hashed_sources() -> List[Path]:
    """The files :func:`package_hash` hashes: softpipe's ``.py`` sources (a generated kernel
    inlines them) and every loop template (a kernel is written from them), whatever its suffix."""
    return sorted(set(PACKAGE_DIR.rglob("*.py")) | set(template_files()))


def package_hash() -> str:
    """A hash of softpipe's own sources and templates (:func:`hashed_sources`): a generated kernel depends on them."""
    if not _PACKAGE_HASH:
        h = hashlib.sha256()
        for f in hashed_sources():
            h.update(str(f.relative_to(PACKAGE_DIR)).encode())
            h.update(f.read_bytes())
        _PACKAGE_HASH.append(h.hexdigest()[:16])
    return _PACKAGE_HASH[0]


def importable_shader(shader: Callable) -> Tuple[str, str] | None:
    """(module, name) if the shader is one of softpipe's own module-level functions.

    Its generated module imports it by name (softpipe's sources are in the file's
    key); any other shader is given to the module, keyed by its code
    (:func:`~.snapshot.shader_source_key`).
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


#: How many compiled versions (sets of global values) of one shader and layout are kept.
_VERSIONS_KEPT = 8
_VERSIONS: Dict[Any, list] = {}


#: Held while a kernel module is built, written to the cache or loaded, and while numba
#: compiles a generated loop (:func:`~.diagnostics.run_compiled`): two threads asking for the same loop
#: build it once, and a fork waits for it (:func:`_before_fork`).
COMPILE_LOCK = threading.RLock()


def _before_fork() -> None:
    """Before ``os.fork``: wait until no thread builds a kernel or compiles with numba, and hold both
    locks across the fork, so the child does not inherit a lock held by a thread it does not have."""
    COMPILE_LOCK.acquire()
    numba.core.compiler_lock.global_compiler_lock.acquire()


def _after_fork() -> None:
    numba.core.compiler_lock.global_compiler_lock.release()
    COMPILE_LOCK.release()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_before_fork, after_in_parent=_after_fork, after_in_child=_after_fork)


def cached_module(base: tuple, shader: Callable, build: Callable[[tuple], Any]) -> Any:
    """The module kept for ``base`` and the shader's globals today, built (compiled) when there is none."""
    globals_key = shader_globals_key(shader)
    key = base + (globals_key,)
    module = _KERNELS.get(key)
    if module is not None:
        return module
    with COMPILE_LOCK:
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


def cached_file_name(source: str, kind: str, globals_key: tuple, user_key: str | None = None) -> str:
    """The name of the cached module file for a generated ``source``.

    It hashes the source, softpipe's sources (:func:`package_hash`), numba's,
    numpy's and Python's versions and, for softpipe's own shader, the values of its
    globals (``globals_key``: numba reads them as they are when it compiles, so a
    changed value is a new file). A user's shader gives ``user_key`` instead
    (:func:`~.snapshot.shader_source_key`: its code, its helpers' code, its globals'
    values), and its file is named ``softpipe_user_…``.
    """
    key = key_text(globals_key) if user_key is None else user_key
    digest = hashlib.sha256("\0".join((source, package_hash(), numba.__version__, np.__version__, sys.version,
                                        key)).encode()).hexdigest()[:20]
    return f"softpipe_{kind}_{digest}" if user_key is None else f"softpipe_user_{kind}_{digest}"


#: The modification time every generated module file is given: numba's cache index records its
#: file's (mtime, size), so two processes writing the same module at once must leave the same stamp.
_FILE_MTIME = 1_000_000_000


def _write_module(data: bytes):
    def write(f) -> None:
        f.write(data)
        f.flush()
        os.utime(f.fileno(), (_FILE_MTIME, _FILE_MTIME))
    return write


def load_cached(source: str, module_name: str, names: Dict[str, Any] | None = None) -> types.ModuleType:
    """The generated module ``source``, written to the cache directory as ``module_name``.py and imported.

    The file is written only when it is missing or differs (a damaged one is written
    again), through a temporary file and an atomic rename, with a fixed modification
    time (:data:`_FILE_MTIME`: processes writing the same module at once leave the
    stamp numba's index records); the module is run from ``source`` itself (a stale or
    damaged ``.pyc`` beside the file is never read), with ``names`` defined first (a
    user's shader, ``_shader_py``, which no import can reach), and goes into
    ``sys.modules`` so that numba's cache can find its namedtuple classes by name.
    """
    directory = _cache_dir()
    directory.mkdir(parents=True, exist_ok=True)
    _importable_cache(directory)
    path = directory / f"{module_name}.py"
    with COMPILE_LOCK:                 # one thread of this process at a time
        loaded = sys.modules.get(module_name)
        if loaded is not None and getattr(loaded, "__softpipe_source__", None) == source:
            return loaded
        data = source.encode()
        if not path.is_file() or path.read_bytes() != data:
            # a temporary file of our own (unique across processes and threads), then an atomic
            # rename: a concurrent writer never sees, nor truncates, half a file
            atomic_write(path, _write_module(data))
        spec = importlib.util.spec_from_file_location(module_name, path)
        assert spec is not None and spec.loader is not None, path   # a .py file's spec has its loader
        module = importlib.util.module_from_spec(spec)
        module.__dict__.update(names or {})
        sys.modules[module_name] = module   # so numba's cache can find its namedtuple classes
        try:
            # the source we checked, compiled under the file's name (numba's cache is keyed by that
            # file); not spec.loader.exec_module, which would trust a .pyc in __pycache__
            exec(compile(source, str(path), "exec"), module.__dict__)
        except BaseException:
            sys.modules.pop(module_name, None)
            raise
        module.__softpipe_source__ = source  # type: ignore[attr-defined]  # the mark load_cached reads
        return module
