"""Programs for looking at geometry: ``unlit``, ``normals``, ``depth``.

Varyings from :func:`~softpipe.programs.common.standard_vertex`: ``position`` (eye space)
and ``normal`` (eye space, not normalized after interpolation).
"""
from softpipe.language.glsl import add, normalize, scale
from softpipe.programs.common import standard_vertex
from softpipe.programs.registry import Program, register


def unlit_fragment(varyings, uniforms, frag):
    """A constant color: ``uniforms.color`` (RGB)."""
    c = uniforms.color
    return (c[0], c[1], c[2], 1.0)


def normals_fragment(varyings, uniforms, frag):
    """The eye-space normal N as a color: (N + 1) / 2."""
    N = normalize(varyings.normal)
    c = add(scale(N, 0.5), (0.5, 0.5, 0.5))
    return (c[0], c[1], c[2], 1.0)


def depth_fragment(varyings, uniforms, frag):
    """Window depth as gray: near is white, far is black."""
    g = 1.0 - frag.z
    return (g, g, g, 1.0)


unlit = register(Program("unlit", standard_vertex, unlit_fragment, "a constant color (uniform 'color')"))
normals = register(Program("normals", standard_vertex, normals_fragment, "the eye-space normal as a color"))
depth = register(Program("depth", standard_vertex, depth_fragment, "window depth as gray, near = white"))
