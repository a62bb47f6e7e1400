"""The Hall illumination model's local terms (FORMULAS §13, §14), per fragment.

    I = ka·I_a                                        ambient
      + Σ_j f_j·[ ks·I_s,j·B_j·(N·H_j)₊ⁿ              specular reflection of the lights
                + kt·I_s,j·B′_j·(−N·H′_j)₊ⁿ′          specular transmission of the lights (§14)
                + kd·I_d,j·B_j·(N·L_j) ]              diffuse

H′_j is the transmitted half vector for η = ``material.ior`` (a viewer in air),
n′ = ``material.transmission_shininess``; B′_j = 1 for a light *behind* the
surface. The terms that need other surfaces (k_r·I_r, k_t·I_t: reflected and
refracted rays) belong to a ray tracer and are left out, so ``kr`` is unused
here. :func:`softpipe.lighting.hall_local` evaluates it; normals are
interpolated and renormalized per fragment as in :mod:`softpipe.shaders.phong`.

Program ``hall``. Uniforms: ``model_view``, ``projection``, ``normal_matrix``,
``material``, ``lighting`` (see :mod:`softpipe.shaders.common`).
"""
from ..lighting import hall_local
from . import Program, register
from .common import facing_normal, rgba, standard_vertex, toward_eye


def hall_fragment(varyings, uniforms, frag):
    """The local Hall terms (§13) at the fragment."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    color = hall_local(P, N, V, m, uniforms.lighting, m.ior)
    return rgba(color, m.opacity)


hall = register(Program(
    "hall", standard_vertex, hall_fragment,
    "Hall's local terms (§13): diffuse, specular reflection and transmission (H′, n′) of lights, ambient"))
