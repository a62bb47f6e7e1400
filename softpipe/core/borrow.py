"""Handing compiled code an array without its owner: :func:`borrowed` and :func:`borrowed_tuple`.

numba counts references to every array compiled code holds: each time an array,
or a tuple with arrays in it, is bound to a variable or passed to a call, the
count of the array's owner (its *meminfo*) goes up, and down again when that is
over, each time with an atomic add or subtract. Code that hands the same arrays
on once per sample or per ray (a shader reading its uniforms, a BVH traversal, a
shadow lookup) can spend more on those atomic operations than on its work, and
two threads counting on the same owners slow each other down.

A *borrowed* array is the same data, shape and strides with no owner attached
(its meminfo NULL), so there is nothing to count. That is only safe while
someone else holds the real array: borrow in a compiled function from the
arguments it was handed, use the borrowed value there and in what it calls, and
never return or store it; the caller's reference keeps the data alive meanwhile.

- :func:`borrowed`: one array (numba refuses anything else: a call site that
  means an array says so).
- :func:`borrowed_tuple`: a tuple or namedtuple, every array in it borrowed, at
  any depth; its other items, and a value that is not a tuple (None), as they are.

Both are compiled inline (``inline="always"``); in plain Python
(``NUMBA_DISABLE_JIT=1``) they hand back what they are given, as there is no
count to save. What borrowing saves, measured: benchmarks/README.md.
"""
from __future__ import annotations

from typing import TypeVar

from numba.core import cgutils, types
from numba.extending import intrinsic, overload

__all__ = ["borrowed", "borrowed_tuple"]

T = TypeVar("T")


def borrowed(array: T) -> T:
    """``array`` without its owner, so compiled code counts no references to it (plain Python: ``array``).

    Parameters
    ----------
    array : numpy.ndarray
        An array the calling function was handed (its caller holds it while it runs).

    Returns
    -------
    numpy.ndarray
        The same data, shape and strides; compiled, with no owner attached.
    """
    return array


def borrowed_tuple(values: T) -> T:
    """``values`` with every array in it borrowed, at any depth (plain Python: ``values``).

    Parameters
    ----------
    values : tuple, namedtuple or any value
        Typically a shader's uniforms or a ShadowUniform: the calling function was
        handed it, and its caller holds it while it runs. Items that are not arrays
        or tuples (numbers, None) are kept as they are, and so is a value that is
        neither a tuple nor an array.

    Returns
    -------
    the same type as ``values``
        Compiled: each array in it with no owner attached.
    """
    return values


def _without_owner(context, builder, typ, value):
    """``value`` of numba type ``typ`` with the meminfo of every array in it set to NULL (recursively)."""
    if isinstance(typ, types.Array):
        array = context.make_array(typ)(context, builder, value=value)
        array.meminfo = cgutils.get_null_value(array.meminfo.type)
        return array._getvalue()
    if isinstance(typ, types.BaseTuple):
        out = value
        for k, item_type in enumerate(typ.types):
            item = builder.extract_value(value, k)
            out = builder.insert_value(out, _without_owner(context, builder, item_type, item), k)
        return out
    return value


@intrinsic
def _borrow(typingctx, value):
    """The intrinsic both functions compile to: the same type in and out, the arrays' owners left behind."""
    def codegen(context, builder, signature, args):
        return _without_owner(context, builder, signature.args[0], args[0])
    return value(value), codegen


@overload(borrowed, inline="always")
def _borrowed_compiled(array):
    if isinstance(array, types.Array):
        return lambda array: _borrow(array)
    return None                     # not an array: numba reports no implementation for this type


@overload(borrowed_tuple, inline="always")
def _borrowed_tuple_compiled(values):
    return lambda values: _borrow(values)
