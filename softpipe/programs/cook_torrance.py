"""Cook-Torrance microfacet shading (FORMULAS §26), per fragment.

    I = ke + ka·I_a,global
      + Σ_j f_j·[ ka·I_a,j + V_j·B_j·(N·L_j)·( kd·I_d,j + ks·I_s,j·f_s,j ) ]

    f_s = D·G·F / (4 (N·L)(N·V))                      (the normalized microfacet form)
    D   = exp(−tan²α/m²) / (π m² cos⁴α)               Beckmann, normalized; cos α = N·H, m = material.roughness
    G   = min(1, 2(N·H)(N·V)/(V·H), 2(N·H)(N·L)/(V·H))
    F   = (R_s + R_p)/2 at cos θ = V·H, from air into material.ior (exact Fresnel, §20)

:func:`softpipe.light.lighting.cook_torrance_lighting` evaluates it (V_j: light j's shadow term,
:mod:`softpipe.light.shadowmap`; the 1982 paper's own π-denominator form and its value are
in :func:`softpipe.light.lighting.cook_torrance`). F is 0 for
``ior = 1`` (the Material default), so give a Cook-Torrance material its ior —
e.g. 1.5 for a plastic or glass; metals have a complex index, which a large
real one (≈ 3–20) stands in for.

Program ``cook_torrance``. Uniforms: ``model_view``, ``projection``,
``normal_matrix``, ``material``, ``lighting`` (see :mod:`softpipe.programs.common`).
"""
from softpipe.light.lighting import cook_torrance_lighting
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye
from softpipe.programs.registry import Program, register


def cook_torrance_fragment(varyings, uniforms, frag):
    """§10 with the Cook-Torrance lobe in place of (N·H)ⁿ, at the fragment."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    color = cook_torrance_lighting(P, N, V, m, uniforms.lighting)
    return rgba(color, m.opacity)


cook_torrance = register(Program(
    "cook_torrance", standard_vertex, cook_torrance_fragment,
    "Cook-Torrance (§26): Beckmann D, G, exact Fresnel F (material.roughness, material.ior), per fragment"))
