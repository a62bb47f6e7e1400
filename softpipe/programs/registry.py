"""The program record and the registry of built-in programs by name (``PROGRAMS``).

Each program module registers its pair at import; :mod:`softpipe.programs` imports them all.
"""
from __future__ import annotations

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


def get_program(name: Union[str, Program]) -> Program:
    """The built-in program called ``name``; a ValueError lists the known names otherwise."""
    if isinstance(name, Program):
        return name
    if name not in PROGRAMS:
        raise ValueError(f"unknown shading program {name!r}; known programs: {', '.join(sorted(PROGRAMS))}")
    return PROGRAMS[name]
