"""softpipe's one way of using both cores: bands of a range, on Python threads, each band a compiled loop.

Every parallel step of the pipeline (assembly's per-vertex and per-triangle
passes, triangle setup, the tiles of the visibility pass, shading, the
reference rasterizer's passes, the clear) is a numba kernel written as
``kernel(lo, hi, *args)`` over items ``lo:hi``, compiled with ``nogil=True``,
and :func:`in_bands` runs it over disjoint bands of the items on a small pool
of Python threads.

Why not numba's ``prange``: a parallel kernel costs seconds more to compile
from an empty cache than the same loop written serially (measured: 3.3 s
against 0.6 s for the tile loop, 3.3 s against 1.3 s for triangle setup), a
shading loop is compiled per shader, and numba's OpenMP workers, spinning after
each parallel loop, took a core from the Python threads that shade. Bands are
disjoint and each item is computed the same whoever computes it, so the result
does not depend on the thread count.
"""
from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

__all__ = ["in_bands", "threads"]


def threads() -> int:
    """How many threads softpipe uses: numba's thread count (``NUMBA_NUM_THREADS``, ``numba.set_num_threads``)."""
    return numba.get_num_threads()


def in_bands(kernel, rows: int, *args, grain: int = 1) -> None:
    """Run the nogil kernel ``kernel(lo, hi, *args)`` over ``rows`` items in parallel bands.

    Up to 8 bands per thread, taken in turn by whichever thread is free (the
    calling thread works too), so that a band heavier than the others does
    not leave a thread idle for long; a band has at least ``grain`` items
    (below that, starting a thread costs more than it saves).
    """
    count = max(1, min(threads(), -(-rows // max(grain, 1))))
    if count == 1 or rows <= 1:
        kernel(0, rows, *args)
        return
    bounds = np.linspace(0, rows, min(rows, count * 8) + 1).astype(np.int64)
    bands = len(bounds) - 1
    next_band = itertools.count().__next__       # atomic under the GIL

    def work() -> None:
        k = next_band()
        while k < bands:
            kernel(bounds[k], bounds[k + 1], *args)
            k = next_band()

    helpers = [_pool(count - 1).submit(work) for _ in range(count - 1)]
    try:
        work()
    finally:
        for helper in helpers:       # every band is done (or failed) before returning or raising
            helper.result()


_POOLS: dict = {}
if hasattr(os, "register_at_fork"):
    # A forked child has the pools but not their threads: it must start its own.
    os.register_at_fork(after_in_child=_POOLS.clear)


def _pool(count: int) -> ThreadPoolExecutor:
    """One long-lived pool of helper threads per size (starting threads per call costs milliseconds)."""
    if count not in _POOLS:
        _POOLS[count] = ThreadPoolExecutor(count, thread_name_prefix="softpipe")
    return _POOLS[count]
