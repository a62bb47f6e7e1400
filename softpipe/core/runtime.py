"""Process settings softpipe's speed depends on, which a program asks for and a library never imposes.

**Freed memory kept for reuse** (:func:`keep_freed_memory`, glibc's
``mallopt``: ``M_MMAP_THRESHOLD`` and ``M_TRIM_THRESHOLD``). A draw makes
arrays of tens of megabytes (assembled triangles, edge functions, the
visibility buffer) and frees them at its end. By default glibc gives each such
block back to the system and maps a fresh one for the next draw, and the
kernel must zero every page again on first touch, a page fault per page per
frame; with the memory kept, a large draw's assembly makes none
(benchmarks/README.md has the figures). The cost is that the process keeps its peak
memory instead of returning it after a large draw (:func:`release_memory`
returns it).

The setting is the whole process's, not softpipe's: importing softpipe leaves
the allocator as it is, and the programs that are softpipe's own (the
``softpipe`` command, the benchmarks, batch's cluster workers) call
:func:`keep_freed_memory` when they start. A program of yours that draws many
large frames may call it too (``sp.keep_freed_memory()``).
``SOFTPIPE_SYSTEM_MALLOC=1`` makes the call do nothing. It changes no output byte.
"""
from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["KEEP_FREED_BELOW", "keep_freed_memory", "freed_memory_kept", "release_memory", "available_memory",
           "check_memory"]

#: Blocks up to this size come from (and go back to) the heap instead of fresh mappings.
KEEP_FREED_BELOW = 1 << 30
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3   # glibc's malloc.h

_kept = False       # whether keep_freed_memory tuned the allocator in this process


def keep_freed_memory() -> bool:
    """Ask glibc to keep freed blocks below :data:`KEEP_FREED_BELOW` for reuse, for the whole process.

    Call it once, at the start of a program that draws large frames one after
    another (later calls do nothing more). Leaves the allocator alone where
    ``SOFTPIPE_SYSTEM_MALLOC`` is set (to anything but ``0``), off Linux, and
    where the C library is not glibc (musl has no ``mallopt``).

    Returns
    -------
    bool
        Whether the allocator keeps freed memory now (this call's doing or an earlier one's).
    """
    global _kept
    if _kept:
        return True
    if os.environ.get("SOFTPIPE_SYSTEM_MALLOC", "") not in ("", "0") or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    _kept = bool(mallopt(_M_MMAP_THRESHOLD, KEEP_FREED_BELOW)) and bool(mallopt(_M_TRIM_THRESHOLD, KEEP_FREED_BELOW))
    return _kept


def freed_memory_kept() -> bool:
    """Whether :func:`keep_freed_memory` has tuned the allocator in this process."""
    return _kept


def release_memory() -> None:
    """Give the memory glibc keeps for reuse back to the system (``malloc_trim(0)``).

    For measuring one workload's peak memory after another, as the benchmarks
    do before each scene; a no-op where :func:`keep_freed_memory` did not tune the allocator.
    """
    if _kept:
        ctypes.CDLL(None).malloc_trim(0)


def available_memory() -> int | None:
    """Bytes the system can still give this process without swapping (Linux's MemAvailable), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


#: Needs below this are not checked (no machine softpipe runs on has less free).
CHECK_MEMORY_FROM = 64 << 20


def check_memory(what: str, need: int) -> None:
    """Raise MemoryError, with the estimate, when ``what`` needs more than the memory available.

    Called before a large allocation, so that a draw too large for the machine
    fails at once with a sentence instead of deep inside numpy (or the system
    swapping for minutes).
    """
    if need < CHECK_MEMORY_FROM:
        return                          # reading /proc/meminfo costs more than such a draw
    have = available_memory()
    if have is not None and need > have:
        raise MemoryError(f"{what} needs about {need / 2**30:.1f} GiB, and this machine has "
                          f"{have / 2**30:.1f} GiB available")
