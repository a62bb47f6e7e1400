"""The Hall illumination model (FORMULAS §13, §14, §15), per fragment.

    I = ka·I_a                                        ambient
      + Σ_j f_j·[ ks·I_s,j·B_j·(N·H_j)₊ⁿ              specular reflection of the lights
                + kt·I_s,j·B′_j·(−N·H′_j)₊ⁿ′          specular transmission of the lights (§14)
                + kd·I_d,j·B_j·(N·L_j) ]              diffuse
      + kr·I_r·T_r^{d_r}                              reflection of other surfaces   (global)
      + kt·I_t·T_t^{d_t}                              transmission of other surfaces (global)

H′_j is the transmitted half vector for η = ``material.ior`` on a front face (a viewer
in air) and 1/``material.ior`` on a back face (seen from inside, FORMULAS §14), n′ = ``material.transmission_shininess``; B′_j = 1 for a light *behind* the
surface. :func:`softpipe.light.lighting.hall_local` evaluates the local terms; normals
are interpolated and renormalized per fragment as in :mod:`softpipe.programs.phong`.
The material's kr, kt are Hall's k_r·F_s and k_t·F_t (a coefficient times a color).

The global terms need something to see. I_r comes along R = 2(N·V)N − V (§16),
I_t along the refracted T (§18; η = 1/ior on a front face, ior on a back face,
seen from inside; on total internal reflection, §19, kt's share goes along R
too, as in the ray tracer), from what the draw gives (:func:`softpipe.programs.
environment.incoming`):

- the uniform ``tracer`` (:func:`softpipe.tracers.whitted.tracer_uniform`): rays traced
  through the scene, recursively; T_r^{d_r}, T_t^{d_t} are the falloff over the
  distance each ray travels (§15), so the pixel is the ray tracer's;
- the uniform ``environment`` (a cube map): I_r = env(R), I_t = env(T), the
  environment taken as far away in clear air (T^d = 1), read at its level 0 (this
  program takes no derivatives; ``mirror`` and ``glass`` do);
- neither: the global terms are 0 — Hall's model with k_r = 0, "a Phong-like local
  model" (§13). They are compiled out.

Program ``hall``. Uniforms: ``model_view``, ``projection``, ``normal_matrix``,
``material``, ``lighting`` (see :mod:`softpipe.programs.common`); optional
``environment`` with ``view``, or ``tracer``.
"""
from numba.extending import overload, register_jitable

from softpipe.language.glsl import add, reflect, refract, scale
from softpipe.light.lighting import hall_local
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye
from softpipe.programs.environment import incoming
from softpipe.programs.registry import Program, register


def hall_global(uniforms, P, N, V, m, front_facing):
    """kr·I_r + kt·I_t (§13's global terms, with their falloff when traced); 0 when the draw gives nothing to see."""
    if not (hasattr(uniforms, "tracer") or hasattr(uniforms, "environment")):
        return (0.0, 0.0, 0.0)
    return _global_terms(uniforms, P, N, V, m, front_facing)


@overload(hall_global)
def _hall_global_numba(uniforms, P, N, V, m, front_facing):
    fields = tuple(getattr(uniforms, "fields", ()))
    if "tracer" not in fields and "environment" not in fields:      # decided once, when the shader is typed
        return lambda uniforms, P, N, V, m, front_facing: (0.0, 0.0, 0.0)
    return lambda uniforms, P, N, V, m, front_facing: _global_terms(uniforms, P, N, V, m, front_facing)


@register_jitable
def _global_terms(uniforms, P, N, V, m, front_facing):
    R = reflect(scale(V, -1.0), N)                                   # §16
    eta = 1.0 / m.ior if front_facing else m.ior                     # air outside, as the ray tracer
    T = refract(scale(V, -1.0), N, eta)                              # §18
    if T[0] == 0.0 and T[1] == 0.0 and T[2] == 0.0:                  # §19: kt's share is reflected too
        T = R
    still = (0.0, 0.0, 0.0)        # no derivatives taken: the environment's level 0
    return add(incoming(uniforms, P, R, still, still, m.kr), incoming(uniforms, P, T, still, still, m.kt))


def hall_fragment(varyings, uniforms, frag):
    """Hall's model (§13) at the fragment: the local terms, plus the global ones when the draw gives them."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    # §14: η = (far side)/(viewer's side): ior from air, 1/ior seen from inside (a back face)
    color = hall_local(P, N, V, m, uniforms.lighting, m.ior if frag.front_facing else 1.0 / m.ior)
    color = add(color, hall_global(uniforms, P, N, V, m, frag.front_facing))
    return rgba(color, m.opacity)


hall = register(Program(
    "hall", standard_vertex, hall_fragment,
    "Hall (§13): diffuse, specular reflection and transmission (H′, n′) of lights, ambient; kr·I_r and kt·I_t "
    "from a traced ray (uniform 'tracer') or a cube map ('environment')"))
