"""Mirrors and glass in a rasterizer: the reflected and refracted directions look up an environment.

    vertex shader:   eye-space P and N (:func:`~softpipe.programs.common.standard_vertex`)
    fragment shader: N renormalized, V toward the eye,
                     R = 2(N·V)N − V                          (§16)
                     T = (η·c₁ − c₂)·N − η·V, c₁ = N·V        (§18), η = η_outside/η_material
                     looked up in a cube map (uniform ``environment``)

``mirror``
    I = kr·env(R) + I_local, I_local the OpenGL lighting equation (§10, Blinn-Phong).
``glass``
    I = F_R·env(R) + (1 − F_R)·kt·env(T) + I_local, F_R the exact Fresnel
    reflectance (§20) from ``outside_ior`` into ``material.ior``; F_R = 1 on total
    internal reflection (§19).

Uniforms: those of :mod:`softpipe.programs.common`, ``view`` (world → eye, to turn R
and T into the world-space map's directions), ``environment``
(a :class:`softpipe.light.cubemap.CubeMap`; :func:`softpipe.light.cubemap.sky` without
it), ``outside_ior`` (1.0) and ``environment_lod`` (a level-of-detail bias, 0); or
``tracer``, and then R and T are traced through the scene
(:func:`softpipe.tracers.whitted.trace_ray`) instead of looked up.

Why it is shaped so: a rasterizer sees only the first surface, so R and T look the
environment up at once, at GL's level of detail for a samplerCube (R and T worked out
at the neighbouring pixel too, from the fragment shader's 4th parameter, so a curved
mirror's rim does not alias). docs/environment.md explains the programs, their
uniforms, the level of detail and what a rasterizer cannot do.
"""
from numba.core.errors import TypingError
from numba.extending import overload, register_jitable

from softpipe.language.glsl import add, mul, reflect, scale, sub
from softpipe.light.cubemap import cube_level_of_detail, sky, texture_cube_lod
from softpipe.light.lighting import BLINN_PHONG, fresnel_directions, opengl_lighting
from softpipe.programs.common import facing_normal, rgba, standard_vertex, toward_eye, uniform_or
from softpipe.programs.registry import Program, register
from softpipe.tracers.whitted import trace_ray


def view_matrix(uniforms):
    """The uniform ``view`` (world → eye). Compiled, it is read by its index: numba takes
    ``x.view`` for numpy's ``ndarray.view`` and refuses it on a namedtuple."""
    return uniforms.view


@overload(view_matrix)
def _view_matrix_numba(uniforms):
    fields = tuple(getattr(uniforms, "fields", ()))
    if "view" not in fields:
        raise TypingError("the programs mirror and glass need the uniform 'view' (world → eye), which "
                          "softpipe.draw_mesh passes; give it in the uniforms of a draw of your own")
    index = fields.index("view")
    return lambda uniforms: uniforms[index]


@register_jitable
def to_world(view, d):
    """A direction from eye space to world space: view₃ᵀ · d (view is world → eye, a rotation there)."""
    return (float(view[0, 0] * d[0] + view[1, 0] * d[1] + view[2, 0] * d[2]),
            float(view[0, 1] * d[0] + view[1, 1] * d[1] + view[2, 1] * d[2]),
            float(view[0, 2] * d[0] + view[1, 2] * d[1] + view[2, 2] * d[2]))


def lookup(uniforms, d_world, dx_world, dy_world):
    """The environment's RGB in a world direction: the cube map ``environment``, or :func:`softpipe.light.cubemap.sky`.

    ``dx_world``, ``dy_world`` are the direction's screen-space derivatives: the cube map is
    read at their level of detail (:func:`softpipe.light.cubemap.cube_level_of_detail`, as GLSL's
    ``texture`` picks it for a samplerCube), at least 0, plus the uniform ``environment_lod``.
    """
    if not hasattr(uniforms, "environment"):
        return sky(d_world)
    return _from_cube_map(uniforms, d_world, dx_world, dy_world)


@overload(lookup)
def _lookup_numba(uniforms, d_world, dx_world, dy_world):
    if "environment" not in tuple(getattr(uniforms, "fields", ())):   # decided once, when the shader is typed
        return lambda uniforms, d_world, dx_world, dy_world: sky(d_world)
    return lambda uniforms, d_world, dx_world, dy_world: _from_cube_map(uniforms, d_world, dx_world, dy_world)


@register_jitable
def _from_cube_map(uniforms, d, dx, dy):
    env = uniforms.environment
    lod = max(cube_level_of_detail(env, d, dx, dy), 0.0) + uniform_or(uniforms, "environment_lod", 0.0)
    c = texture_cube_lod(env, d, lod)
    return (c[0], c[1], c[2])


@register_jitable
def environment(uniforms, d_eye, dx_eye, dy_eye):
    """The environment's RGB in the eye-space direction ``d_eye`` whose screen-space derivatives are ``dx_eye``,
    ``dy_eye`` (all turned to world space by ``view``); zero derivatives read level 0."""
    view = view_matrix(uniforms)
    return lookup(uniforms, to_world(view, d_eye), to_world(view, dx_eye), to_world(view, dy_eye))


def incoming(uniforms, P, d_eye, dx_eye, dy_eye, weight):
    """weight × the light that arrives at P from the eye-space direction ``d_eye`` (RGB).

    With the uniform ``tracer`` (:func:`softpipe.tracers.whitted.tracer_uniform`) a ray is
    traced from P through the scene, recursively (:func:`softpipe.tracers.whitted.trace_ray`:
    the ray tracer's own tree, so the pixel is the ray tracer's); without it, the
    environment in that direction (:func:`environment`, at the level of detail of the
    direction's derivatives ``dx_eye``, ``dy_eye``), as if everything were far away.
    """
    if hasattr(uniforms, "tracer"):
        return trace_ray(uniforms.tracer, P, d_eye, weight)
    return mul(weight, environment(uniforms, d_eye, dx_eye, dy_eye))


@overload(incoming)
def _incoming_numba(uniforms, P, d_eye, dx_eye, dy_eye, weight):
    if "tracer" in tuple(getattr(uniforms, "fields", ())):     # decided once, when the shader is typed
        return lambda uniforms, P, d_eye, dx_eye, dy_eye, weight: trace_ray(uniforms.tracer, P, d_eye, weight)
    return lambda uniforms, P, d_eye, dx_eye, dy_eye, weight: mul(weight, environment(uniforms, d_eye, dx_eye,
                                                                                        dy_eye))


#: (R, T, F_R) for unit N (on V's side) and V, from the medium ``outside_ior`` into ``ior`` (§16, §18–§20;
#: T = 0 and F_R = 1 on total internal reflection): :func:`softpipe.light.lighting.fresnel_directions`.
glass_weights = fresnel_directions


@register_jitable
def surface_at(varyings, step, uniforms, front_facing):
    """(N, V) where the varyings are ``varyings + step``: at the neighbouring pixel, for a derivative."""
    P = add(varyings.position, step.position)
    return facing_normal(add(varyings.normal, step.normal), front_facing), toward_eye(P, uniforms.projection)


@register_jitable
def media(uniforms, m, front_facing):
    """(n₁, n₂): from the viewer's medium into the glass, or out of it for a back face (seen from inside)."""
    outside = uniform_or(uniforms, "outside_ior", 1.0)
    return (outside, m.ior) if front_facing else (m.ior, outside)


def mirror_fragment(varyings, uniforms, frag, derivatives):
    """kr·I(R) plus the local lighting (§10); I from the environment, or a traced ray."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    R = reflect(scale(V, -1.0), N)                 # = 2(N·V)N − V (§16)
    Nx, Vx = surface_at(varyings, derivatives.dx, uniforms, frag.front_facing)
    Ny, Vy = surface_at(varyings, derivatives.dy, uniforms, frag.front_facing)
    dRx = sub(reflect(scale(Vx, -1.0), Nx), R)     # R's change to the next pixel, for the level of detail
    dRy = sub(reflect(scale(Vy, -1.0), Ny), R)
    local = opengl_lighting(P, N, V, m, uniforms.lighting, BLINN_PHONG)
    color = add(incoming(uniforms, P, R, dRx, dRy, m.kr), local)
    return rgba(color, m.opacity)


def glass_fragment(varyings, uniforms, frag, derivatives):
    """F_R·I(R) + (1 − F_R)·kt·I(T) plus the local lighting (§10, §16–§20)."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    n1, n2 = media(uniforms, m, frag.front_facing)
    R, T, F = glass_weights(N, V, n1, n2)
    Nx, Vx = surface_at(varyings, derivatives.dx, uniforms, frag.front_facing)
    Ny, Vy = surface_at(varyings, derivatives.dy, uniforms, frag.front_facing)
    Rx, Tx, _ = glass_weights(Nx, Vx, n1, n2)
    Ry, Ty, _ = glass_weights(Ny, Vy, n1, n2)
    color = add(incoming(uniforms, P, R, sub(Rx, R), sub(Ry, R), (F, F, F)),
                opengl_lighting(P, N, V, m, uniforms.lighting, BLINN_PHONG))
    if F < 1.0:
        color = add(color, incoming(uniforms, P, T, sub(Tx, T), sub(Ty, T), scale(m.kt, 1.0 - F)))
    return rgba(color, m.opacity)


mirror = register(Program(
    "mirror", standard_vertex, mirror_fragment,
    "a mirror: kr × the environment (uniform 'environment', a CubeMap) in R (§16), plus §10's local lighting"))
glass = register(Program(
    "glass", standard_vertex, glass_fragment,
    "glass: Fresnel (§20) mixes env(R) and kt·env(T) (§16, §18; TIR §19 → all R), plus §10; first surface only"))

__all__ = ["mirror", "glass", "to_world", "environment", "lookup", "incoming", "glass_weights", "view_matrix"]
