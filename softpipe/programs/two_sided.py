"""The ray-tracing course's two-sided lighting (FORMULAS §11), per fragment.

    c = ρ_d·L_a + Σ_i (ρ_d + ρ_s(N·H_i)) · L_i · V_i(p) · |N·L_i|      ρ_s(N·H) = k_s·(N·H)₊ⁿ

ρ_d = ``material.kd``, k_s = ``material.ks``, n = ``material.shininess``; L_a the
global ambient light; L_i light i's response, its diffuse color k_l over r² for a
point light (k_l for a directional one); V_i its visibility (shadow maps or shadow
rays, :func:`softpipe.light.lighting.light_visibility`). :func:`softpipe.light.lighting.two_sided_lighting`
evaluates it; normals are interpolated and renormalized per fragment as in
:mod:`softpipe.programs.phong`.

**note** (§11): |N·L_i| — a light behind the surface lights it as one in front does,
there is no B factor — and the cosine multiplies the specular lobe too. §10 (the
``phong`` program) does neither; this is its own program rather than a switch on
that one. The last two terms of §11, k_r·trace(p, R) + k_t·trace(p, T), need rays:
:func:`softpipe.tracers.whitted.raytrace_scene` adds them for objects drawn with this
program (``PROGRAM_CODES["two_sided"]``); rasterized, there are none.

Program ``two_sided``. Uniforms: ``model_view``, ``projection``, ``normal_matrix``,
``material``, ``lighting`` (see :mod:`softpipe.programs.common`).
"""
from softpipe.light.lighting import two_sided_lighting
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye
from softpipe.programs.registry import Program, register


def two_sided_fragment(varyings, uniforms, frag):
    """§11's direct light at the fragment: |N·L|, the cosine on the specular lobe, V_i per light."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    return rgba(two_sided_lighting(P, N, V, m, uniforms.lighting), m.opacity)


two_sided = register(Program(
    "two_sided", standard_vertex, two_sided_fragment,
    "The ray-tracing course's two-sided form (§11): (ρ_d + ρ_s)·L_i·V_i·|N·L_i|, L_i = k_l/r²"))
