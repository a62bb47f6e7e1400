"""numba's on-disk cache, made safe for the test suite's worker processes compiling at the same time.

``make test`` runs the suite in two processes (pytest-xdist), and with ``cache=True`` both read and
write the same cache files (``__pycache__`` beside softpipe's sources, or ``$NUMBA_CACHE_DIR``;
softpipe's generated kernels, ``$SOFTPIPE_CACHE_DIR``, are cached the same way). numba writes each
file whole (a temporary file, then a rename), but adding a compiled signature to a function's index
(``*.nbi``) is a read, a change and a write that nothing locks: two processes that compile two
signatures of one function at once both read the same index, both pick the first free data file
(``*.1.nbc``), and the index written last may name the data the other process wrote, so that a
later process loads machine code compiled for other argument types (numba issues #10128, #2028).

:func:`install` wraps numba's ``IndexDataCacheFile.save`` and ``load`` in an ``flock`` on a lock file
beside the index (exclusive to save, shared to load): the read-change-write of one index is then
one step for every process that has it installed. It reaches into numba's internals, so it checks
their shape first and leaves numba as it is (with a warning) where they differ. Processes that a
test starts (``python -c ...``, Dask workers) do not install it; they compile little.

It also makes each function compile once for the whole run (:func:`_compile_once`). From empty
caches both workers start on the same pipeline kernels and numba's cache is only read before a
compile, so each worker compiled nearly every kernel itself: the cold suite's CPU time was about
twice the one-worker suite's. ``Dispatcher.compile`` now holds an ``flock`` on a second lock file
beside the function's cache index while it looks in the cache and compiles: a worker that asks for
a function the other is compiling waits, then loads what the other saved.
"""
from __future__ import annotations

import contextlib
import functools
import os
import warnings

try:
    import fcntl
except ImportError:                 # not POSIX: no flock, and nothing to install
    fcntl = None


@contextlib.contextmanager
def _locked(cache_file, mode: int):
    """Hold ``mode`` (``LOCK_EX`` or ``LOCK_SH``) on ``INDEX.lock`` while the block runs.

    Where the cache folder does not exist yet (nothing cached, nothing to read) or cannot be
    written, or numba's cache file has no index path, the block runs without the lock, as numba
    would run it.
    """
    index_path = getattr(cache_file, "_index_path", None)
    if not isinstance(index_path, str):
        yield
        return
    try:
        fd = os.open(index_path + ".lock", os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        yield
        return
    try:
        fcntl.flock(fd, mode)
        yield
    finally:
        os.close(fd)                # closing releases the lock


def install() -> bool:
    """Lock numba's cache index in this process; True when installed (now or before)."""
    if fcntl is None:
        return False
    from numba.core import caching
    cls = getattr(caching, "IndexDataCacheFile", None)
    if cls is None or not all(callable(getattr(cls, name, None)) for name in ("save", "load")):
        warnings.warn("numba's IndexDataCacheFile has changed: its cache index is not locked", stacklevel=2)
        return False
    if getattr(cls, "_softpipe_tests_locked", False):
        return True
    save, load = cls.save, cls.load

    @functools.wraps(save)
    def locked_save(self, key, data):
        with _locked(self, fcntl.LOCK_EX):
            return save(self, key, data)

    @functools.wraps(load)
    def locked_load(self, key):
        with _locked(self, fcntl.LOCK_SH):
            return load(self, key)

    cls.save, cls.load = locked_save, locked_load
    cls._softpipe_tests_locked = True
    from numba.core.dispatcher import Dispatcher
    if callable(getattr(Dispatcher, "compile", None)):
        Dispatcher.compile = _compile_once(Dispatcher.compile)
    else:
        warnings.warn("numba's Dispatcher.compile has changed: workers may compile a function twice", stacklevel=2)
    return True


def _compile_once(compile):
    """``Dispatcher.compile`` holding ``INDEX.compile-lock`` exclusive: one process compiles a function at a time.

    The others wait and then find it in the cache. A function whose compile needs another one takes
    that one's lock inside its own (the locks follow the call graph, which has no cycles, so no two
    processes wait on each other); a lock this process already holds (recursion, a second thread)
    is not taken again, since an ``flock`` on a new descriptor would wait on itself.
    """
    held = set()

    @functools.wraps(compile)
    def compile_once(self, sig):
        index_path = getattr(getattr(getattr(self, "_cache", None), "_cache_file", None), "_index_path", None)
        if not isinstance(index_path, str) or index_path in held:     # cache=False, or already ours
            return compile(self, sig)
        try:
            fd = os.open(index_path + ".compile-lock", os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:
            return compile(self, sig)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            held.add(index_path)
            try:
                return compile(self, sig)
            finally:
                held.discard(index_path)
        finally:
            os.close(fd)

    return compile_once
