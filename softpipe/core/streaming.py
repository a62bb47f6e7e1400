"""Streaming stores: writing a large buffer past the processor's caches.

A buffer written once per frame and read later by someone else (the outputs of
:mod:`softpipe.scenes.derive`: 24 MB at 1024² for depth, normals and the two ids)
is the worst case for ordinary stores: each cache line is first read from memory,
to be owned, then written back dirty when it is evicted, so every byte crosses the
memory bus twice and pushes out what the cache held. A *streaming* (non-temporal)
store (x86's ``MOVNT``, LLVM's ``!nontemporal``) sends whole lines through the
write-combining buffers instead, without reading them: 28 MB took 0.8–0.9 ms that
way against 2.3–3.8 ms stored the usual way, on one or two threads
(benchmarks/README.md, "Outputs, round 5").

The pattern is a row at a time: compute the row in a small array that stays in the
cache (written in any order, as often as needed), then copy it out with
:func:`stream_row`, each line of the buffer written once and whole. A kernel that
streamed calls :func:`stream_fence` before it returns: streaming stores are weakly
ordered, and the fence makes them visible before anything stored after it (the
thread that waits for the kernel then reads the buffer).

In plain Python (``NUMBA_DISABLE_JIT=1``) these are ordinary stores and no fence.
"""
from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

__all__ = ["stream_store", "stream_row", "stream_fence"]


def stream_store(array: np.ndarray, index: int, value) -> None:
    """``array[index] = value`` for a 1-D array, as a streaming store when compiled (no bounds check, and
    ``index`` must not be negative: it is not wrapped around)."""
    array[index] = value


def stream_fence() -> None:
    """Make the streaming stores before it visible before every store after it (compiled: a full fence)."""


@intrinsic
def _store_nontemporal(typingctx, array, index, value):
    if not (isinstance(array, types.Array) and array.ndim == 1 and isinstance(index, types.Integer)):
        return None
    sig = types.void(array, index, array.dtype)

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        a, i, v = args
        structure = context.make_array(array_type)(context, builder, a)
        pointer = cgutils.get_item_pointer(context, builder, array_type, structure, [i], wraparound=False)
        store = builder.store(v, pointer)
        store.set_metadata("nontemporal", builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))
        return context.get_dummy_value()
    return sig, codegen


@intrinsic
def _fence(typingctx):
    def codegen(context, builder, signature, args):
        builder.fence("seq_cst")       # x86: MFENCE, which orders streaming stores too (SFENCE would suffice)
        return context.get_dummy_value()
    return types.void(), codegen


@overload(stream_store, inline="always")
def _stream_store_compiled(array, index, value):
    dtype = array.dtype
    return lambda array, index, value: _store_nontemporal(array, index, dtype(value))


@overload(stream_fence, inline="always")
def _stream_fence_compiled():
    return lambda: _fence()


@numba.njit(cache=True, nogil=True, inline="always")
def stream_row(buffer: np.ndarray, start: int, row: np.ndarray) -> None:
    """``buffer[start:start + len(row)] = row`` (1-D arrays of one dtype) by streaming stores."""
    base = np.uint64(start)
    for i in range(np.uint64(len(row))):
        stream_store(buffer, base + i, row[i])
