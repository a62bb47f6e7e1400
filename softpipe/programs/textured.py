"""A texture times the lit diffuse color: the OpenGL lighting equation with kd (and ka) from an image.

    t = texture(uv)                                   (RGBA, trilinear with mipmaps if the texture says so)
    I = ke + t·ka·I_a,global
      + Σ_j f_j·[ t·ka·I_a,j + B_j·( t·kd·I_d,j·(N·L_j) + ks·I_s,j·(N·H_j)₊ⁿ ) ]
    alpha = t.a · material.opacity

The texture scales the ambient and diffuse reflectance, as an MTL ``map_Kd``
does; the specular highlight keeps the light's color (OpenGL's separate
specular color), so a dark texel still shines. Normals are interpolated and
renormalized per fragment (Phong shading, Blinn-Phong specular).

The level of detail comes from the exact screen-space derivatives of uv (the
fragment shader's 4th parameter, GLSL's ``textureGrad``), so a ``"trilinear"``
or ``"nearest_mipmap"`` texture is mipmapped.

Program ``textured``. Attribute ``uv`` (``draw_mesh`` passes the mesh's uvs).
Uniforms: ``model_view``, ``projection``, ``normal_matrix``, ``material``,
``lighting`` (see :mod:`softpipe.programs.common`) and ``texture``, a
:class:`softpipe.light.texture.Texture2D`.
"""
from collections import namedtuple

from softpipe.language.contract import reads_uniforms
from softpipe.language.glsl import mul
from softpipe.light.lighting import BLINN_PHONG, opengl_lighting
from softpipe.light.material import MaterialUniform
from softpipe.light.texture import texture_grad
from softpipe.programs.common import eye_space, facing_normal, rgba, toward_eye
from softpipe.programs.registry import Program, register

TexturedVaryings = namedtuple("TexturedVaryings", ["position", "normal", "uv"])


@reads_uniforms("model_view", "projection", "normal_matrix")
def textured_vertex(attributes, uniforms):
    """Eye-space P and N, and the texture coordinates, for the rasterizer to interpolate."""
    clip, P, N = eye_space(attributes, uniforms)
    return clip, TexturedVaryings(P, N, attributes.uv)


def textured_fragment(varyings, uniforms, frag, derivatives):
    """Sample the texture, let it scale ka and kd, light the fragment (§10)."""
    t = texture_grad(uniforms.texture, varyings.uv, derivatives.dx.uv, derivatives.dy.uv)
    tex = (t[0], t[1], t[2])
    m = uniforms.material
    textured = MaterialUniform(m.ke, mul(m.ka, tex), mul(m.kd, tex), m.ks, m.shininess, m.kr, m.kt,
                               m.transmission_shininess, m.ior, m.opacity, m.roughness)
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    color = opengl_lighting(P, N, V, textured, uniforms.lighting, BLINN_PHONG)
    return rgba(color, t[3] * m.opacity)


textured = register(Program(
    "textured", textured_vertex, textured_fragment,
    "texture × lit diffuse: §10 per fragment with ka, kd scaled by texture(uv) (uniform 'texture')"))
