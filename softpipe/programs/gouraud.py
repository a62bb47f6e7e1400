"""Gouraud shading (FORMULAS §12): light the vertices, interpolate the colors.

    vertex shader:   N at the vertex → the OpenGL lighting equation (§10) → color
    rasterizer:      color interpolated across the triangle
    fragment shader: the interpolated color

A highlight that falls inside a triangle, away from its vertices, is missed,
and the eye sees Mach bands where the interpolated color's slope jumps at
edges. Programs:

``gouraud``                 Blinn-Phong specular (N·H)₊ⁿ, OpenGL's (§6)
``gouraud_phong_specular``  Phong specular (R·V)₊ⁿ (§5)

Uniforms: ``model_view``, ``projection``, ``normal_matrix``, ``material``,
``lighting`` (see :mod:`softpipe.programs.common`). As OpenGL's fixed function
does, the vertex color is clamped to [0, 1] before it is interpolated.
"""
from collections import namedtuple

from softpipe.language.contract import reads_uniforms
from softpipe.language.glsl import normalize, saturate
from softpipe.light.lighting import BLINN_PHONG, PHONG, opengl_lighting
from softpipe.programs.common import eye_space, rgba, toward_eye
from softpipe.programs.registry import Program, register

GouraudVaryings = namedtuple("GouraudVaryings", ["color"])  # RGBA


@reads_uniforms("model_view", "projection", "normal_matrix", "material", "lighting")
def gouraud_vertex(attributes, uniforms):
    """Light the vertex (§10, Blinn-Phong specular); pass its color on."""
    clip, P, N = eye_space(attributes, uniforms)
    N = normalize(N)
    V = toward_eye(P, uniforms.projection)
    color = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, BLINN_PHONG)
    return clip, GouraudVaryings(rgba(saturate(color), uniforms.material.opacity))


@reads_uniforms("model_view", "projection", "normal_matrix", "material", "lighting")
def gouraud_phong_specular_vertex(attributes, uniforms):
    """Light the vertex (§10 with Phong's (R·V)₊ⁿ specular); pass its color on."""
    clip, P, N = eye_space(attributes, uniforms)
    N = normalize(N)
    V = toward_eye(P, uniforms.projection)
    color = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, PHONG)
    return clip, GouraudVaryings(rgba(saturate(color), uniforms.material.opacity))


def gouraud_fragment(varyings, uniforms, frag):
    """The interpolated vertex color."""
    c = varyings.color
    return (c[0], c[1], c[2], c[3])


gouraud = register(Program(
    "gouraud", gouraud_vertex, gouraud_fragment,
    "Gouraud: Blinn-Phong lighting (§10) per vertex, colors interpolated"))
gouraud_phong_specular = register(Program(
    "gouraud_phong_specular", gouraud_phong_specular_vertex, gouraud_fragment,
    "Gouraud with Phong's (R·V)ⁿ specular: lighting per vertex, colors interpolated"))
