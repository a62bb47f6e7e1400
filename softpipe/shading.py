"""Everything a shader author needs, in one import: ``from softpipe.shading import *``.

This module defines nothing; it gathers, under one name, what the shader
contract (:mod:`softpipe.language.contract`), the GLSL math (:mod:`softpipe.language.glsl`), the
lighting equations (:mod:`softpipe.light.lighting`), the packed lights
(:mod:`softpipe.light.packed`, :mod:`softpipe.light.material`), their shadows
(:mod:`softpipe.light.shadowmap`) and the built-in programs (:mod:`softpipe.programs`)
offer. Each name here *is* the object of its home module. A walk through
writing one: ``docs/shaders.md``.

The contract
------------
A shader is a plain Python function, written like GLSL and compiled by numba::

    def vertex(attributes, uniforms):                 # once per vertex
        ...
        return clip, Varyings(position=P, normal=N)  # clip = (x, y, z, w)

    def fragment(varyings, uniforms, frag):           # once per fragment (sample)
        ...
        return (r, g, b, a)                           # or DISCARD

    def fragment(varyings, uniforms, frag, derivatives):   # when it needs dFdx/dFdy
        ...

``attributes``
    The vertex's inputs by name: ``position`` (the ``positions`` of the draw)
    and every array given as ``attributes=`` (``normal``, ``uv``, …). A field
    is a float for an ``[N]`` array, a tuple of k floats for ``[N, k]``. An
    instanced draw adds its ``instance_attributes=`` (the instance's row) and
    ``instance_id`` (``gl_InstanceID``, an int).
``uniforms``
    The draw's ``uniforms=`` dict, the same for every invocation, by name:
    numbers become floats, short vectors tuples, matrices numpy arrays,
    a :class:`Material` its :class:`MaterialUniform` (``uniforms.material.kd``),
    the ``lighting`` uniform a :class:`LightingUniform` (``global_ambient``
    and ``lights``, the packed eye-space lights, one row per light).
    :func:`uniform_or` reads an optional one with a default. A vertex shader
    may declare the ones it reads, ``@reads_uniforms("model_view", …)``, as
    GLSL's ``uniform`` lines: its compiled loop then serves every program.
``Varyings``
    Any namedtuple class; its fields (a float or a tuple of 2–4 floats each)
    are what the rasterizer interpolates, and the fragment shader receives
    them by the same names in ``varyings``.
``frag``
    A :data:`FragInfo`: ``x``, ``y`` (window position of the sample, y up,
    pixel centres at +½, as ``gl_FragCoord``), ``z`` (its depth in [0, 1]),
    ``front_facing``, ``primitive_id``, ``point_coord`` (on a point, ``gl_PointCoord``:
    (s, t) from (0, 0) at its square's upper-left corner to (1, 1), for round points
    and sprites; on a line, (t, 0) along it; on a triangle, the barycentrics (b1, b2)).
``derivatives``
    A :data:`Derivatives`: ``dx`` and ``dy``, each with every varying's exact
    screen-space derivative by name (``derivatives.dx.uv``), GLSL's ``dFdx``/``dFdy``.
Return value
    The fragment's RGBA (floats, not clamped: the framebuffer clamps once, when
    it becomes 8 bits), or :data:`DISCARD` (GLSL ``discard``). A shader that
    cannot compile or run raises :class:`ShaderError` naming it and its line.

What Python a shader may use (the subset numba compiles: tuples for vectors, the
functions below for their arithmetic, no numpy): docs/shaders.md.

Names (the notes', docs/formulas.md; used by every function below)
------------------------------------------------------------------
All vectors are in **eye space** (the eye at the origin, looking down −z) and
of unit length unless said.

P        the surface point (the varying ``position`` of :func:`standard_vertex`)
N        the surface normal, on the viewer's side (:func:`facing_normal`)
L        from P toward the light (:func:`light_at`)
V        from P toward the eye: normalize(−P) (:func:`toward_eye`)
H        the half vector normalize(L + V)                                   (§6)
R        L mirrored about N: R = 2(N·L)N − L                                (§5)
H′       the transmitted half vector of the Hall model                     (§14)
B        1 if N·L > 0, else 0: no light from below the surface              (§4)
(x)₊     max(0, x)
ke, ka, kd, ks, kr, kt   the material's emission, ambient, diffuse, specular,
         reflection and transmission colors (:class:`MaterialUniform` fields)
n, n′    the shininess and the transmission shininess
I_a, I_d, I_s        a light's ambient, diffuse and specular colors;
         I_a,global the global ambient light (``uniforms.lighting.global_ambient``)
f_att, f_spot        the attenuation (§7) and spotlight (§8) factors
η        a ratio of refractive indices, defined where used
m        Beckmann's roughness (Cook-Torrance, §26)

Colors are RGB 3-tuples, multiplied per channel (``mul(kd, I_d)``).

What is offered
---------------
The contract (:mod:`softpipe.language.contract`)
    FragInfo, DISCARD, Derivatives, ShaderError
Programs and the vertex side (:mod:`softpipe.programs`, :mod:`softpipe.programs.common`)
    Program                  a vertex and a fragment shader with a name, for ``draw_mesh``
    standard_vertex          the usual vertex shader: varyings P (``position``) and N (``normal``)
    StandardVaryings         its varyings
    eye_space                (clip, P, N) of a vertex: model_view · p, projection · P, normal_matrix · n
Surface vectors and helpers (:mod:`softpipe.programs.common`)
    facing_normal            N: the interpolated normal renormalized, reversed on back faces (§12)
    toward_eye               V, also for an orthographic projection
    uniform_or               an optional uniform with its default
    rgba                     (r, g, b, a) from a color and an alpha
GLSL math on tuples (:mod:`softpipe.language.glsl`)
    vec2, vec3, vec4                                 constructors
    add, sub, mul, div, scale, neg                   arithmetic, per component
    dot, cross, length, distance, normalize          geometry
    faceforward, reflect, refract                    GLSL's (§16–§19)
    mix, clamp, saturate, step, smoothstep, pow_     per component
    vmin, vmax, vabs                                 GLSL's min, max, abs
    hsum, max_component, min_component               reductions
    mat4_mul_vec4, mat3_mul_vec3                     M · v
The lighting equations (:mod:`softpipe.light.lighting`; FORMULAS §n)
    emission (§1), ambient (§2), lambert (§3), b_factor (§4),
    phong_specular (§5), blinn_phong_specular (§6), half_vector (§6),
    positive_power (§5, §6), attenuation (§7), spot_factor (§8),
    opengl_lighting (§10) with BLINN_PHONG or PHONG,
    hall_local (§13), hall_transmission (§13, §14), transmitted_half_vector (§14),
    two_sided_lighting (§11),
    fresnel_rs_rp, fresnel, fresnel_schlick (§20), fresnel_directions (R, T, F_R: §16–§20),
    beckmann_d, geometry_g, cook_torrance, cook_torrance_lighting, gooch (§26)
The packed lights (:mod:`softpipe.light.lighting`, :mod:`softpipe.light.packed`, :mod:`softpipe.light.shadowmap`)
    light_at                 (L, f_att · f_spot) of light j at P (§7–§9)
    light_vec3               three columns of light j: ``light_vec3(lights, j, LIGHT_DIFFUSE)`` is I_d
    light_colors             (I_a, I_d, I_s) of light j
    sum_over_lights          color + Σ_j f_j·(ambient_j + V_j·direct_j), given one light's
                             part of a model: opengl_light, hall_light, two_sided_light,
                             cook_torrance_light, or a function of your own with their arguments
    light_visibility         V_j: the RGB share of light j that reaches P past the
                             shadow casters (shadow maps or shadow rays, §11, §21):
                             ``light_visibility(uniforms.lighting, j, P)``
    casts_shadows            does light j cast shadows? (False, known when the shader
                             compiles, for lighting without shadows: ask it first)
    LIGHT_KIND, LIGHT_AMBIENT, LIGHT_DIFFUSE, LIGHT_SPECULAR, LIGHT_POSITION,
    LIGHT_ATTENUATION, LIGHT_SPOT_DIRECTION, LIGHT_SPOT_COS_CUTOFF,
    LIGHT_SPOT_EXPONENT, LIGHT_COLUMNS     the columns of a packed light
    LIGHT_DIRECTIONAL, LIGHT_POINT, LIGHT_SPOT             the values of LIGHT_KIND
Textures (:mod:`softpipe.light.texture`; docs/texture-mapping.md, docs/textures.md)
    texture                  RGBA of a texture uniform at uv, level 0 (GLSL ``texture``)
    texture_grad             sampled at the level λ its uv derivatives give: ``texture_grad(uniforms.tex,
                             varyings.uv, derivatives.dx.uv, derivatives.dy.uv)`` (GLSL ``textureGrad``)
    texture_lod              sampled at a level λ given (GLSL ``textureLod``)
    mip_level                λ = log2 ρ of the derivatives, ρ in texels of level 0 per pixel
    texture_size             (width, height) of a level (GLSL ``textureSize``)
    Texture2D, TextureUniform   the image and mipmaps, and its uniform: ``uniforms={"tex": Texture2D(...)}``
Ray queries (:mod:`softpipe.rays.queries`; GLSL's ``rayQueryEXT`` in spirit)
    RayScene                 the scene as a uniform: ``uniforms={"scene": RayScene(objects)}``
                             (the draw's ``view`` turns it to eye space: ``scene.uniform(view)``)
    trace_closest            (triangle or −1, t, b1, b2) of the nearest hit on an eye-space ray
    trace_any                whether anything lies on it (a shadow ray)
    hit_position, hit_normal the hit's point and interpolated normal, eye space
    ray_visibility           §21's shadow ray through transparent objects: V of a light
    medium_falloff           §15: T^d or Glassner's 1/(1 + a·d) over a distance in a medium
The ray tracer from a shader (:mod:`softpipe.tracers.whitted`)
    tracer_uniform           the scene's ray tracer as a uniform: ``uniforms={"tracer": tracer_uniform(scene)}``
    trace_ray                the color a ray brings back (Σ weight × local over its tree), eye space
What the uniforms are made from (:mod:`softpipe.light.material`, :mod:`softpipe.programs.common`)
    Material, MaterialUniform, Light, Lighting, LightingUniform, ShadowSettings,
    lighting_uniform         the ``lighting`` uniform for a camera's view matrix
"""
from softpipe.language.contract import DISCARD, Derivatives, FragInfo, ShaderError, reads_uniforms
from softpipe.language.glsl import (
                   add,
                   clamp,
                   cross,
                   distance,
                   div,
                   dot,
                   faceforward,
                   hsum,
                   length,
                   mat3_mul_vec3,
                   mat4_mul_vec4,
                   max_component,
                   min_component,
                   mix,
                   mul,
                   neg,
                   normalize,
                   pow_,
                   reflect,
                   refract,
                   saturate,
                   scale,
                   smoothstep,
                   step,
                   sub,
                   vabs,
                   vec2,
                   vec3,
                   vec4,
                   vmax,
                   vmin,
)
from softpipe.light.lighting import (
                   BLINN_PHONG,
                   PHONG,
                   ambient,
                   attenuation,
                   b_factor,
                   beckmann_d,
                   blinn_phong_specular,
                   cook_torrance,
                   cook_torrance_light,
                   cook_torrance_lighting,
                   emission,
                   fresnel,
                   fresnel_directions,
                   fresnel_rs_rp,
                   fresnel_schlick,
                   geometry_g,
                   gooch,
                   half_vector,
                   hall_light,
                   hall_local,
                   hall_transmission,
                   lambert,
                   light_at,
                   light_colors,
                   opengl_light,
                   opengl_lighting,
                   phong_specular,
                   positive_power,
                   spot_factor,
                   sum_over_lights,
                   transmitted_half_vector,
                   two_sided_light,
                   two_sided_lighting,
)
from softpipe.light.material import Light, Lighting, LightingUniform, Material, MaterialUniform
from softpipe.light.packed import (
                   LIGHT_AMBIENT,
                   LIGHT_ATTENUATION,
                   LIGHT_COLUMNS,
                   LIGHT_DIFFUSE,
                   LIGHT_DIRECTIONAL,
                   LIGHT_KIND,
                   LIGHT_POINT,
                   LIGHT_POSITION,
                   LIGHT_SPECULAR,
                   LIGHT_SPOT,
                   LIGHT_SPOT_COS_CUTOFF,
                   LIGHT_SPOT_DIRECTION,
                   LIGHT_SPOT_EXPONENT,
                   light_vec3,
)
from softpipe.light.shadowmap import ShadowSettings, casts_shadows, light_visibility
from softpipe.light.texture import (
    Texture2D,
    TextureUniform,
    mip_level,
    texture,
    texture_grad,
    texture_lod,
    texture_size,
)
from softpipe.programs.common import (
                   StandardVaryings,
                   eye_space,
                   facing_normal,
                   lighting_uniform,
                   rgba,
                   standard_vertex,
                   toward_eye,
                   uniform_or,
)
from softpipe.programs.registry import Program
from softpipe.rays.queries import (
                   RayScene,
                   hit_normal,
                   hit_position,
                   medium_falloff,
                   ray_visibility,
                   trace_any,
                   trace_closest,
)
from softpipe.tracers.whitted import trace_ray, tracer_uniform

__all__ = [
    # the contract
    "FragInfo", "DISCARD", "Derivatives", "ShaderError", "reads_uniforms",
    # programs and the vertex side
    "Program", "standard_vertex", "StandardVaryings", "eye_space",
    # surface vectors and helpers
    "facing_normal", "toward_eye", "uniform_or", "rgba",
    # GLSL math
    "vec2", "vec3", "vec4",
    "add", "sub", "mul", "div", "scale", "neg",
    "dot", "cross", "length", "distance", "normalize",
    "faceforward", "reflect", "refract",
    "mix", "clamp", "saturate", "step", "smoothstep", "pow_",
    "vmin", "vmax", "vabs",
    "hsum", "max_component", "min_component",
    "mat4_mul_vec4", "mat3_mul_vec3",
    # the lighting equations
    "emission", "ambient", "lambert", "b_factor", "phong_specular", "blinn_phong_specular", "half_vector",
    "positive_power", "attenuation", "spot_factor", "opengl_lighting", "BLINN_PHONG", "PHONG",
    "hall_local", "hall_transmission", "transmitted_half_vector", "two_sided_lighting",
    "fresnel_rs_rp", "fresnel", "fresnel_schlick", "fresnel_directions",
    "beckmann_d", "geometry_g", "cook_torrance", "cook_torrance_lighting", "gooch",
    # the packed lights
    "light_at", "light_vec3", "light_colors", "sum_over_lights",
    "opengl_light", "hall_light", "two_sided_light", "cook_torrance_light", "light_visibility", "casts_shadows",
    "LIGHT_KIND", "LIGHT_AMBIENT", "LIGHT_DIFFUSE", "LIGHT_SPECULAR", "LIGHT_POSITION",
    "LIGHT_ATTENUATION", "LIGHT_SPOT_DIRECTION", "LIGHT_SPOT_COS_CUTOFF", "LIGHT_SPOT_EXPONENT",
    "LIGHT_COLUMNS", "LIGHT_DIRECTIONAL", "LIGHT_POINT", "LIGHT_SPOT",
    # textures
    "texture", "texture_grad", "texture_lod", "mip_level", "texture_size", "Texture2D", "TextureUniform",
    # ray queries
    "RayScene", "trace_closest", "trace_any", "hit_position", "hit_normal", "ray_visibility", "medium_falloff",
    "tracer_uniform", "trace_ray",
    # what the uniforms are made from
    "Material", "MaterialUniform", "Light", "Lighting", "LightingUniform", "ShadowSettings", "lighting_uniform",
]
