"""softpipe.core.borrow: arrays handed to compiled code without their owner.

- Compiled, a borrowed array reads the same values, and has no owner (meminfo NULL):
  that is what saves numba's reference counting. A tuple or namedtuple is borrowed
  array by array, at any depth; its numbers and Nones stay as they are.
- ``borrowed`` refuses what is not an array when numba compiles it.
- In plain Python both return the very value they are given.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np
import pytest
from numba.core import types
from numba.extending import intrinsic

from softpipe.core.borrow import borrowed, borrowed_tuple

Inner = namedtuple("Inner", ["table", "scale"])
Outer = namedtuple("Outer", ["matrix", "inner", "nothing", "count"])


@intrinsic
def _owner(typingctx, array):
    """The address of an array's owner (its meminfo) in compiled code: 0 when it has none."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, args):
        a = context.make_array(signature.args[0])(context, builder, value=args[0])
        return builder.ptrtoint(a.meminfo, context.get_value_type(types.intp))
    return types.intp(array), codegen


@numba.njit
def _sum_borrowed(a):
    b = borrowed(a)
    total = 0.0
    for i in range(b.shape[0]):
        for j in range(b.shape[1]):
            total += b[i, j] * (i + 1) - j
    return total, b[1, 2], b.shape[0], b.shape[1], _owner(a), _owner(b)


@numba.njit
def _read_borrowed_tuple(u):
    v = borrowed_tuple(u)
    return (v.matrix[2, 1], v.inner.table[3], v.inner.scale, v.count, v.nothing is None,
            _owner(u.matrix), _owner(v.matrix), _owner(u.inner.table), _owner(v.inner.table))


def test_a_borrowed_array_reads_the_same_values_and_has_no_owner():
    a = np.arange(12.0).reshape(3, 4) * 0.5
    total, item, rows, cols, owner, borrowed_owner = _sum_borrowed(a)
    expected = sum(a[i, j] * (i + 1) - j for i in range(3) for j in range(4))
    assert total == expected and item == a[1, 2] and (rows, cols) == (3, 4)
    assert owner != 0 and borrowed_owner == 0


def test_a_borrowed_view_reads_its_own_strides():
    a = np.arange(40.0).reshape(5, 8)[::2, 1::3]        # not contiguous
    total, item, rows, cols, _, borrowed_owner = _sum_borrowed(a)
    assert total == sum(a[i, j] * (i + 1) - j for i in range(a.shape[0]) for j in range(a.shape[1]))
    assert item == a[1, 2] and (rows, cols) == a.shape and borrowed_owner == 0


def test_a_namedtuple_is_borrowed_array_by_array_at_any_depth():
    u = Outer(np.arange(9.0).reshape(3, 3), Inner(np.linspace(0.0, 1.0, 5), 2.5), None, 7)
    m, t, scale, count, none, owner_m, borrowed_m, owner_t, borrowed_t = _read_borrowed_tuple(u)
    assert (m, t, scale, count, none) == (u.matrix[2, 1], u.inner.table[3], 2.5, 7, True)
    assert owner_m != 0 and owner_t != 0
    assert borrowed_m == 0 and borrowed_t == 0


def test_borrowed_tuple_keeps_a_value_that_holds_no_array():
    @numba.njit
    def keep(value):
        return borrowed_tuple(value)

    assert keep((1.0, 2)) == (1.0, 2)
    assert keep(None) is None
    assert keep(Inner(3.0, 4.0)) == Inner(3.0, 4.0)


def test_borrowed_refuses_what_is_not_an_array_when_compiled():
    @numba.njit
    def wrong(x):
        return borrowed(x)

    with pytest.raises(numba.core.errors.TypingError):
        wrong(1.0)


def test_plain_python_gets_the_value_itself():
    a = np.zeros((2, 2))
    u = Outer(a, Inner(a, 1.0), None, 1)
    assert borrowed(a) is a
    assert borrowed_tuple(u) is u
    assert borrowed_tuple(None) is None
