"""Built-in shader programs: a vertex shader and a fragment shader that go together.

Each program lives in its own module beside this one and reads like the slide it
comes from. All of them take the standard uniforms (``model_view``,
``projection``, ``normal_matrix``) and the standard attributes (``position``,
``normal``), which :func:`softpipe.standard_uniforms` builds.

``get_program(name)`` looks a program up by name; ``PROGRAMS`` lists them.
"""
from softpipe.programs.registry import PROGRAMS, Program, get_program, register

__all__ = ["Program", "PROGRAMS", "get_program", "register"]

# Importing the modules registers their programs.
from softpipe.programs import (  # noqa: E402,F401
    basic,
    cook_torrance,
    environment,  # noqa: E402,F401  (mirror, glass: cube-map reflection and refraction)
    flat,
    gooch,
    gouraud,
    hall,
    phong,
    textured,
    two_sided,
)
