"""Gooch's cool-to-warm tone shading (FORMULAS §26), for technical illustration.

    k_cool = k_blue + α·kd          k_warm = k_yellow + β·kd
    t = (1 + N·L)/2                 I = t·k_warm + (1 − t)·k_cool

Warm where the surface faces the light, cool where it turns away, and no black:
shape reads from hue rather than from darkness. L is toward the first light of
``lighting`` (with no lights, toward the eye); kd is the material's. Shadows do
not enter: the tone t says which way the surface faces, not how much light arrives,
and the paper draws no shadows (a shadow map, if the lighting carries one, is not read).

Outlines (optional): a rim where the surface turns away from the eye, N·V <
``gooch_outline``, drawn in ``gooch_outline_color``. The rim's width follows the
curvature, as an ink line's does; 0 (the default) draws none.

Program ``gooch``. Uniforms: ``model_view``, ``projection``, ``normal_matrix``,
``material``, ``lighting``, and, each optional with the paper's value as default
(:func:`~softpipe.programs.common.uniform_or`): ``gooch_blue`` (0, 0, 0.4),
``gooch_yellow`` (0.4, 0.4, 0), ``gooch_alpha`` 0.2, ``gooch_beta`` 0.6,
``gooch_outline`` 0, ``gooch_outline_color`` (0, 0, 0).
"""
from softpipe.language.glsl import dot
from softpipe.light.lighting import gooch, light_at
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye, uniform_or
from softpipe.programs.registry import Program, register


def gooch_fragment(varyings, uniforms, frag):
    """Cool-to-warm tone (§26), with an optional silhouette rim."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    lights = uniforms.lighting.lights
    L = V
    if lights.shape[0] > 0:
        L, f = light_at(P, lights, 0)
    k_blue = uniform_or(uniforms, "gooch_blue", (0.0, 0.0, 0.4))
    k_yellow = uniform_or(uniforms, "gooch_yellow", (0.4, 0.4, 0.0))
    alpha = uniform_or(uniforms, "gooch_alpha", 0.2)
    beta = uniform_or(uniforms, "gooch_beta", 0.6)
    color = gooch(N, L, uniforms.material.kd, k_blue, k_yellow, alpha, beta)
    outline = uniform_or(uniforms, "gooch_outline", 0.0)
    if outline > 0.0 and dot(N, V) < outline:
        color = uniform_or(uniforms, "gooch_outline_color", (0.0, 0.0, 0.0))
    return rgba(color, uniforms.material.opacity)


gooch_program = register(Program(
    "gooch", standard_vertex, gooch_fragment,
    "Gooch cool-to-warm tones (§26), t = (1 + N·L)/2 toward the first light; optional rim outline"))
