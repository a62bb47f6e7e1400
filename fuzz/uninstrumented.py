"""Keep numba-compiled functions out of atheris's coverage instrumentation.

atheris instruments a module by rewriting the bytecode of every function in it, adding
calls such as ``atheris._trace_branch(...)``. numba compiles a function from its
bytecode, and cannot type those calls: the first time a fuzzed input reaches an
``@njit`` function of an instrumented module (``transforms._transform_points`` for any
scene with a mesh), numba raises ``TypingError`` and libFuzzer reports a crash that is
the fuzzer's own doing.

:func:`keep_numba_uninstrumented` makes every numba dispatcher created after it is called
compile the function's *original* bytecode: recompiled from the function's source file
and found there by qualified name and first line. The Python code around the compiled
functions stays instrumented (that is where the parsers are); the compiled code has no
coverage feedback, which libFuzzer could not use inside numba anyway.
"""
from __future__ import annotations

import types

_MODULE_CODE: dict[str, types.CodeType | None] = {}


def _module_code(filename: str) -> types.CodeType | None:
    """The uninstrumented code of the source file ``filename`` (None if it cannot be read)."""
    if filename not in _MODULE_CODE:
        try:
            with open(filename, "rb") as f:
                _MODULE_CODE[filename] = compile(f.read(), filename, "exec", dont_inherit=True)
        except (OSError, SyntaxError, ValueError):
            _MODULE_CODE[filename] = None
    return _MODULE_CODE[filename]


def original_code(code: types.CodeType) -> types.CodeType | None:
    """The code object of the same function compiled from its source file, or None.

    Matched by qualified name and first line (atheris keeps both), searching nested code
    objects too (a function defined inside another).
    """
    module = _module_code(code.co_filename)
    todo = [module] if module is not None else []
    while todo:
        candidate = todo.pop()
        if (candidate.co_qualname == code.co_qualname and candidate.co_firstlineno == code.co_firstlineno
                and candidate is not module):
            return candidate
        todo.extend(c for c in candidate.co_consts if isinstance(c, types.CodeType))
    return None


def keep_numba_uninstrumented() -> None:
    """From now on, numba compiles each function from its source's bytecode, not atheris's.

    Call it before ``atheris.instrument_imports``; functions whose source cannot be found
    (made with ``exec``, for example) are left as they are.
    """
    from numba.core import dispatcher

    init = dispatcher.Dispatcher.__init__
    if getattr(init, "_softpipe_uninstrumented", False):
        return

    def __init__(self, py_func, *args, **kwargs):
        code = getattr(py_func, "__code__", None)
        original = original_code(code) if code is not None else None
        # The free variables must agree, or the function's closure would no longer fit it.
        if original is not None and original.co_freevars == code.co_freevars:
            py_func.__code__ = original
        init(self, py_func, *args, **kwargs)

    __init__._softpipe_uninstrumented = True
    dispatcher.Dispatcher.__init__ = __init__
