"""Phong shading (FORMULAS §12): interpolate the normals, renormalize, light every fragment.

    vertex shader:   eye-space P and N (:func:`~softpipe.programs.common.standard_vertex`)
    rasterizer:      P and N interpolated across the triangle
    fragment shader: N renormalized → the OpenGL lighting equation (§10) → color

Phong *shading* (per-fragment normals) is not Phong *specular* (R·V)ⁿ; the two
are chosen separately:

``phong``                 per-fragment lighting, Blinn-Phong specular (N·H)₊ⁿ (§6, OpenGL's)
``phong_phong_specular``  per-fragment lighting, Phong specular (R·V)₊ⁿ (§5)

Uniforms: ``model_view``, ``projection``, ``normal_matrix``, ``material``,
``lighting`` (see :mod:`softpipe.programs.common`). Lighting is two-sided: a back
face seen with culling off is lit with its normal reversed. The color is not
clamped here; the framebuffer clamps once, when it becomes 8 bits.
"""
from softpipe.light.lighting import BLINN_PHONG, PHONG, opengl_lighting
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye
from softpipe.programs.registry import Program, register


def phong_fragment(varyings, uniforms, frag):
    """Light the fragment (§10) with Blinn-Phong specular."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    color = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, BLINN_PHONG)
    return rgba(color, uniforms.material.opacity)


def phong_phong_specular_fragment(varyings, uniforms, frag):
    """Light the fragment (§10) with Phong's (R·V)₊ⁿ specular."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    color = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, PHONG)
    return rgba(color, uniforms.material.opacity)


phong = register(Program(
    "phong", standard_vertex, phong_fragment,
    "Phong shading: normals interpolated, Blinn-Phong lighting (§10) per fragment"))
phong_phong_specular = register(Program(
    "phong_phong_specular", standard_vertex, phong_phong_specular_fragment,
    "Phong shading with Phong's (R·V)ⁿ specular, per fragment"))
