"""softpipe's one way of using both cores: bands of a range, on Python threads, each band a compiled loop.

Every parallel step of the pipeline (assembly's per-vertex and per-triangle
passes, triangle setup, the tiles of the visibility pass, shading, the
reference rasterizer's passes, the clear) is a numba kernel written as
``kernel(lo, hi, *args)`` over items ``lo:hi``, compiled with ``nogil=True``,
and :func:`in_bands` runs it over disjoint bands of the items on a small pool
of Python threads.

Why not numba's ``prange``: a parallel kernel costs seconds more to compile
from an empty cache than the same loop written serially (benchmarks/README.md), a
shading loop is compiled per shader, and numba's OpenMP workers, spinning after
each parallel loop, took a core from the Python threads that shade. Bands are
disjoint and each item is computed the same whoever computes it, so the result
does not depend on the thread count.
"""
from __future__ import annotations

import itertools
import os
import queue
import sys
import threading

import numba
import numpy as np

__all__ = ["in_bands", "threads"]


def threads() -> int:
    """How many threads softpipe uses: numba's thread count (``NUMBA_NUM_THREADS``, ``numba.set_num_threads``)."""
    return numba.get_num_threads()


#: How long an interrupted call waits for the bands under way before it gives up on
#: their threads (a shader in an endless loop never ends its band).
INTERRUPT_GRACE_S = 1.0


def in_bands(kernel, rows: int, *args, grain: int = 1) -> None:
    """Run the nogil kernel ``kernel(lo, hi, *args)`` over ``rows`` items in parallel bands.

    Up to 8 bands per thread, taken in turn by whichever thread is free, so
    that a band heavier than the others does not leave a thread idle for long;
    a band has at least ``grain`` items (below that, starting a thread costs
    more than it saves; less work than one band runs in the calling thread).
    The kernels run on helper threads while the calling thread waits, so Ctrl-C (or any signal) is handled at once: no band is
    started after it, the bands under way are given
    :data:`INTERRUPT_GRACE_S` to end, and the KeyboardInterrupt is raised.
    An error in a band stops the others from starting new bands and is
    raised here, once every band under way has ended. Under
    ``NUMBA_DISABLE_JIT=1``, or with a debugger or profiler on the calling
    thread, the kernel runs in the calling thread instead, in one piece.
    """
    if rows <= max(grain, 1) or numba.config.DISABLE_JIT or sys.gettrace() is not None \
            or sys.getprofile() is not None:
        # Less than one band of work (a thread would cost more than it saves), or Python kernels
        # (or a debugger or profiler watching this thread): run here, where a breakpoint stops
        # and a profiler counts; Python kernels would hold the GIL anyway.
        kernel(0, rows, *args)
        return
    count = max(1, min(threads(), -(-rows // max(grain, 1))))
    bands = min(rows, count * 8)
    bounds = np.linspace(0, rows, bands + 1).astype(np.int64)
    next_band = itertools.count().__next__       # atomic under the GIL
    next_ended = itertools.count(1).__next__
    stop, errors = [False], []
    done = threading.Lock()                      # released by the last worker to end
    done.acquire()

    def work() -> None:
        try:
            k = next_band()
            while k < bands and not stop[0]:
                kernel(bounds[k], bounds[k + 1], *args)
                k = next_band()
        except BaseException as e:  # noqa: B036  (handed to the calling thread, which raises it)
            stop[0] = True
            errors.append(e)
        finally:
            if next_ended() == count:
                done.release()

    pool = _pool(count)
    for _ in range(count):
        pool.submit(work)
    try:
        while not done.acquire(timeout=0.25):     # a timed wait lets signals through
            pass
    except BaseException:
        stop[0] = True
        if not done.acquire(timeout=INTERRUPT_GRACE_S):
            pool.abandon()                        # a band that never ends: leave its threads behind
        raise
    if errors:
        raise errors[0]


class _Workers:
    """Daemon helper threads taking functions from a queue (daemon: a thread stuck in a
    shader's endless loop must not keep the process from exiting)."""

    def __init__(self, count: int):
        self.count = count
        self.tasks: "queue.SimpleQueue" = queue.SimpleQueue()
        for k in range(count):
            threading.Thread(target=self._run, name=f"softpipe-{k}", daemon=True).start()

    def _run(self) -> None:
        while True:
            task = self.tasks.get()
            if task is None:
                return
            task()

    def submit(self, task) -> None:
        self.tasks.put(task)

    def abandon(self) -> None:
        """Stop using these threads: the free ones end, the busy ones are left to finish alone."""
        if _POOLS.get(self.count) is self:
            del _POOLS[self.count]
        for _ in range(self.count):
            self.tasks.put(None)


_POOLS: dict = {}
if hasattr(os, "register_at_fork"):
    # A forked child has the pools but not their threads: it must start its own.
    os.register_at_fork(after_in_child=_POOLS.clear)


def _pool(count: int) -> _Workers:
    """One long-lived set of helper threads per size (starting threads per call costs milliseconds)."""
    if count not in _POOLS:
        _POOLS[count] = _Workers(count)
    return _POOLS[count]
