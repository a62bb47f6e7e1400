"""The program record and the registry of built-in programs by name (``PROGRAMS``).

Each program module registers its pair at import; :mod:`softpipe.programs` imports them all.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from dataclasses import dataclass
from typing import Callable, Dict, Union

__all__ = ["Program", "PROGRAMS", "get_program", "register"]


@dataclass(frozen=True)
class Program:
    """A vertex shader and fragment shader pair with a name and a one-line description."""

    name: str
    vertex: Callable
    fragment: Callable
    description: str = ""
    interpolation: tuple = ()   # (varying, qualifier) pairs, e.g. (("color", "flat"),)
    faceted: bool = False       # draw_mesh gives it Mesh.flat_shaded(): one normal per face


PROGRAMS: Dict[str, Program] = {}


def register(program: Program) -> Program:
    PROGRAMS[program.name] = program
    return program


def get_program(name: Union[str, Program, Callable]) -> Program:
    """The program ``name`` says; a ValueError lists the registered names otherwise.

    ``name`` is a :class:`Program` (taken as it is), a registered program's name,
    a fragment shader function (drawn with :func:`~softpipe.programs.common.standard_vertex`,
    whose varyings it reads), or ``"module:function"`` naming either of those in an
    importable module (or ``"path/to/file.py:function"``): what the command line's
    ``--program`` and a scene file's ``program`` take.
    """
    if isinstance(name, Program):
        return name
    if isinstance(name, str) and name in PROGRAMS:
        return PROGRAMS[name]
    if isinstance(name, str) and ":" in name:
        return get_program(_imported(name))
    if callable(name) and not isinstance(name, type):
        from softpipe.programs.common import standard_vertex
        f = getattr(name, "py_func", name)
        return Program(getattr(f, "__name__", "shader"), standard_vertex, name,
                       "a fragment shader drawn with standard_vertex")
    if isinstance(name, str):
        raise ValueError(f"unknown shading program {name!r}; known programs: {', '.join(sorted(PROGRAMS))} "
                         "(or a Program, a fragment shader function, 'module:function')")
    raise ValueError(f"a program is a name, a Program, a fragment shader function or 'module:function', "
                     f"got {type(name).__name__}")


def _imported(text: str):
    """What ``"module:function"`` (or ``"file.py:function"``) names; a ValueError says what is missing."""
    where, _, attr = text.rpartition(":")
    if not where or not attr:
        raise ValueError(f"{text!r}: give it as module:function")
    try:
        if where.endswith(".py"):
            if not os.path.isfile(where):
                raise ValueError(f"{text!r}: {where}: no such file")
            spec = importlib.util.spec_from_file_location(os.path.splitext(os.path.basename(where))[0], where)
            module = importlib.util.module_from_spec(spec)      # type: ignore[arg-type]
            spec.loader.exec_module(module)                     # type: ignore[union-attr]
        else:
            added = os.getcwd() not in sys.path                 # the console script's path lacks the folder
            if added:
                sys.path.insert(0, os.getcwd())
            try:
                module = importlib.import_module(where)
            finally:
                if added:
                    sys.path.remove(os.getcwd())
    except ImportError as e:
        raise ValueError(f"{text!r}: cannot import {where!r}: {e}") from None
    value = module
    for part in attr.split("."):
        if not hasattr(value, part):
            raise ValueError(f"{text!r}: module {where} has no {attr!r}")
        value = getattr(value, part)
    if not (isinstance(value, (Program, str)) or callable(value)) or isinstance(value, type):
        kind = type(value).__name__
        raise ValueError(f"{text!r} names {'an' if kind[0] in 'aeiou' else 'a'} {kind}, not a Program or a "
                         "fragment shader function")
    return value
