"""Built-in shader programs: a vertex shader and a fragment shader that go together.

Each program lives in its own module beside this one and reads like the slide it
comes from. All of them take the standard uniforms (``model_view``,
``projection``, ``normal_matrix``) and the standard attributes (``position``,
``normal``), which :func:`softpipe.standard_uniforms` builds.

``get_program(name)`` looks a program up by name; ``PROGRAMS`` lists them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict

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


def get_program(name: str) -> Program:
    """The built-in program called ``name``; a ValueError lists the known names otherwise."""
    if isinstance(name, Program):
        return name
    if name not in PROGRAMS:
        raise ValueError(f"unknown shading program {name!r}; known programs: {', '.join(sorted(PROGRAMS))}")
    return PROGRAMS[name]


# Importing the modules registers their programs.
from . import basic, cook_torrance, flat, gooch, gouraud, hall, phong, textured, two_sided  # noqa: E402,F401
from . import environment  # noqa: E402,F401  (mirror, glass: cube-map reflection and refraction)
