"""softpipe.core.streaming: rows copied by streaming stores land exactly where ordinary stores would."""
from __future__ import annotations

import numba
import numpy as np
import pytest

from softpipe.core.streaming import stream_fence, stream_row


@numba.njit(cache=True, nogil=True)
def _rows_out(buffer, starts, rows):
    for k in range(len(starts)):
        stream_row(buffer, starts[k], rows[k])
    stream_fence()


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int32, np.int64, np.uint8])
def test_rows_streamed_at_any_offset_and_length_are_the_rows_and_nothing_else(dtype):
    # offsets and lengths that are not multiples of a cache line or a vector: the copy must not
    # round them (the buffers of a 1023-pixel-wide frame start rows anywhere)
    rng = np.random.default_rng(7)
    size = 5000
    buffer = np.full(size, 3, dtype)
    starts = np.array([0, 1, 17, 999, 4000, 4993], np.int64)
    lengths = [1, 15, 100, 1023, 7, 7]
    rows = np.zeros((len(starts), max(lengths)), dtype)
    expected = buffer.copy()
    for k, (start, length) in enumerate(zip(starts, lengths)):
        rows[k, :length] = rng.integers(0, 100, length).astype(dtype)
        expected[start:start + length] = rows[k, :length]
    for k, length in enumerate(lengths):
        _rows_out(buffer, starts[k:k + 1], rows[k:k + 1, :length])
    assert buffer.tobytes() == expected.tobytes()


def test_without_the_compiler_the_rows_are_plain_stores():
    buffer = np.zeros(10, np.float32)
    stream_row.py_func(buffer, 3, np.arange(4, dtype=np.float32))
    assert buffer.tolist() == [0, 0, 0, 0, 1, 2, 3, 0, 0, 0]
