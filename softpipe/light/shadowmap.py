"""Shadow maps as a shader reads them, and V_j: the depth compare, percentage-closer filtering, shadow rays.

A shadow map is the depth buffer of a draw made from a light (:mod:`softpipe.scenes.shadow_pass`
makes them). Light j's visibility at p, V_j (FORMULAS §11's V_i(p)), is 1 lit, 0 in
shadow, in between at a filtered edge, and an RGB color behind a transparent occluder
(§21). p is lit when its depth in the light's window space, ``ref`` in [0, 1], is ≤
the depth the map stored there: GLSL's ``sampler2DShadow`` with ``GL_LEQUAL``, the
rasterizer's form of the shadow ray of FORMULAS §21, whose ε is the map's depth bias
(a polygon offset, :func:`softpipe.pipeline.setup.apply_polygon_offset`).
Percentage-closer filtering (PCF) compares at the (2r+1)×(2r+1) texels around p's,
r = ``ShadowSettings.pcf``, and averages the results (not the depths).

:func:`light_visibility` (what a shader calls, after :func:`casts_shadows`) looks V_j up
in light j's map(s), or sends a shadow ray through :mod:`softpipe.rays`
(``ShadowSettings(method="ray")``). The lit programs multiply light j's diffuse and
specular terms by it; the ambient term is untouched, as §10 keeps it. A shader receives
``uniforms.lighting.shadows``, a :class:`ShadowUniform`: every map of every light in
flat arrays, so any number of maps of any sizes has one numba type (its docstring has
the layout). The choice of code is made from the uniform's numba type, once: no
shadows compiles no shadow code, rays only no map lookup, maps only no ray code. It is
inlined into every lit sample with its arrays borrowed, because counting their
references made the lit pass several times slower (benchmarks/README.md, "The figures
behind the pipeline's comments").

A point outside a map's square is lit (GL's CLAMP_TO_BORDER, border depth 1); one
beyond the far plane compares with ref = 1. A point light's cube map is seamless for
PCF because each face is drawn a little wider than 90° (:func:`cube_face_half_extent`,
:func:`cube_face`). docs/shadows.md has the why of each: the bias, PCF, the map kinds,
transparent occluders and rays.
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from softpipe.core.borrow import borrowed, borrowed_tuple
from softpipe.language.glsl import length, normalize, sub
from softpipe.light.packed import LIGHT_DIRECTIONAL, LIGHT_KIND, LIGHT_POSITION, light_vec3
from softpipe.rays.queries import ray_visibility

Vec3 = Tuple[float, float, float]
Color = Tuple[float, float, float]

__all__ = ["ShadowSettings", "ShadowUniform", "no_shadows", "light_visibility", "light_visibilities", "casts_shadows",
           "shadow_map_visibility", "shadow_compare",
           "SHADOW_MAP", "SHADOW_RAY", "SHADOW_METHODS",
           "depth_texture", "texture_compare",
           "map_coordinates", "cube_face", "cube_face_half_extent", "CUBE_FACE_NAMES", "MAX_SPOT_MAP_CUTOFF", "MAX_PCF_RADIUS",
           "MAX_SHADOW_RESOLUTION"]

#: A spot light up to this cutoff β (degrees) gets one perspective map of field of view
#: 2β; a wider one gets a cube map, as a point light (a frustum near 180° wastes its texels).
MAX_SPOT_MAP_CUTOFF = 70.0
#: The faces of a cube map, in the order its six maps are packed (:mod:`softpipe.scenes.shadow_pass` draws them).
CUBE_FACE_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")
#: The largest PCF radius r: (2r+1)² = 81 taps.
MAX_PCF_RADIUS = 4
#: The largest shadow map side, in texels (a cube map has six).
MAX_SHADOW_RESOLUTION = 8192

ShadowUniform = namedtuple("ShadowUniform", ["light_maps", "maps", "matrices", "depth", "transparent_depth",
                                             "transmission", "rays"])

#: How a light's V_j is found (``light_maps[j, 2]``): from its shadow map(s), or by a shadow ray.
SHADOW_MAP, SHADOW_RAY = 0, 1
#: ``ShadowSettings.method``'s values, in the order of those codes.
SHADOW_METHODS = ("map", "ray")
ShadowUniform.__doc__ = """Every shadow map of a draw, packed flat: one numba type for any number of maps of
any sizes (a scene with shadows and one without use the same compiled kernel).

``light_maps`` int64 [num_lights, 3]
    Light j's first map, how many it has — 0 (no shadow map), 1 (directional, spot)
    or 6 (a cube map: point lights, and spots wider than :data:`MAX_SPOT_MAP_CUTOFF`) —
    and how its V_j is found: :data:`SHADOW_MAP` or :data:`SHADOW_RAY` (a shadow ray
    through ``rays``, :func:`softpipe.rays.queries.ray_visibility`).
``maps`` int64 [num_maps, 5]
    Each map's offset into ``depth``, width, height, PCF radius r, and offset into
    ``transparent_depth``/``transmission`` (−1: no transparent caster in this map).
``matrices`` float64 [num_maps, 4, 4]
    Eye space → the map's clip space (its light's projection · its view · the
    camera's inverse view): a shader works in eye space.
``depth`` float32 [num_texels]
    Per texel, row 0 at the bottom: the nearest opaque caster's depth (1 where none).
``transparent_depth`` float32 [num_transparent_texels], ``transmission`` float32 [..., 3]
    For the maps that have transparent casters: the nearest one's depth and its
    transmission color (k_t·F_t, its material's ``kt``; 1 where there is none). One
    transparent layer only: a second pane of glass behind the first does not dim the
    light again (a ray tracer does that).
"""


@dataclass(frozen=True)
class ShadowSettings:
    """How one light's shadow map is made and read.

    Parameters
    ----------
    resolution : int
        The map's side in texels (each of six faces for a cube map).
    pcf : int
        The percentage-closer filter's radius r: (2r+1)² compares averaged; 0 is one
        tap, a hard edge. The soft band is 2r+1 texels wide.
    offset_factor, offset_units : float
        The depth pass's polygon offset (``glPolygonOffset(factor, units)``):
        factor·DZ + units·r, the slope-scaled and the constant depth bias. With
        PCF the farthest tap is (r + ½, r + ½) texels from the point looked up, where
        a surface's depth differs by up to (2r + 1)·DZ; a curved mesh's neighbouring
        facet may be less steep than the one looked up from, so the default factor
        is 2r + 2 (2 for the single tap, 4 for r = 1), and the default units 16 (r of
        a float32 depth near 1 is 2⁻²⁴). Too little bias: "acne", a surface
        shadowing itself in dots and stripes; too much: "peter-panning", a shadow
        that comes loose from its caster.
    method : "map" or "ray"
        "map" (the default): V_j from shadow maps, as above. "ray": from a shadow ray
        per shaded point (FORMULAS §21 itself; :func:`softpipe.rays.queries.ray_visibility`):
        exact, hard-edged, through any number of transparent objects; the other
        fields do not apply.
    """

    resolution: int = 1024
    pcf: int = 1
    offset_factor: Optional[float] = None   # None: 2r + 2
    offset_units: float = 16.0
    method: str = "map"

    def __post_init__(self) -> None:
        if self.method not in SHADOW_METHODS:
            raise ValueError(f"ShadowSettings.method must be one of {SHADOW_METHODS}, got {self.method!r}")
        if isinstance(self.resolution, bool) or not isinstance(self.resolution, (int, np.integer)) \
                or not 1 <= self.resolution <= MAX_SHADOW_RESOLUTION:
            raise ValueError(f"ShadowSettings.resolution must be an integer in 1…{MAX_SHADOW_RESOLUTION}, "
                             f"got {self.resolution!r}")
        if isinstance(self.pcf, bool) or not isinstance(self.pcf, (int, np.integer)) \
                or not 0 <= self.pcf <= MAX_PCF_RADIUS:
            raise ValueError(f"ShadowSettings.pcf must be an integer radius in 0…{MAX_PCF_RADIUS}, got {self.pcf!r}")
        object.__setattr__(self, "resolution", int(self.resolution))
        object.__setattr__(self, "pcf", int(self.pcf))
        if self.offset_factor is None:  # the default: enough for the PCF kernel
            object.__setattr__(self, "offset_factor", 2.0 * self.pcf + 2.0)
        for name in ("offset_factor", "offset_units"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not np.isfinite(value):
                raise ValueError(f"ShadowSettings.{name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def polygon_offset(self):
        """(factor, units) for the depth pass."""
        return (self.offset_factor, self.offset_units)


def no_shadows(num_lights: int) -> ShadowUniform:
    """The uniform of a draw without shadow maps: every light has none, V_j = 1."""
    return ShadowUniform(np.zeros((num_lights, 3), np.int64), np.zeros((0, 5), np.int64),
                         np.zeros((0, 4, 4), np.float64), np.zeros(0, np.float32), np.zeros(0, np.float32),
                         np.zeros((0, 3), np.float32), None)


def cube_face_half_extent(resolution: int, pcf: int) -> float:
    """tan of half a cube face's field of view: a little over 1 (45°), so no PCF tap crosses a seam.

    A face spans [−a, a] in the tangent plane over ``resolution`` texels; the
    region |tan| ≤ 1 that the face is looked up for keeps m = r + 2 texels from
    its border when a·(1 − 2m/resolution) = 1.
    """
    margin = pcf + 2
    return 1.0 / max(1.0 - 2.0 * margin / resolution, 0.25)


@njit(cache=True, forceinline=True)
def _project(matrices, k, P):
    """Map k's clip coordinates of the eye-space point P."""
    M = matrices[k]
    x = M[0, 0] * P[0] + M[0, 1] * P[1] + M[0, 2] * P[2] + M[0, 3]
    y = M[1, 0] * P[0] + M[1, 1] * P[1] + M[1, 2] * P[2] + M[1, 3]
    z = M[2, 0] * P[0] + M[2, 1] * P[1] + M[2, 2] * P[2] + M[2, 3]
    w = M[3, 0] * P[0] + M[3, 1] * P[1] + M[3, 2] * P[2] + M[3, 3]
    return x, y, z, w


@njit(cache=True)
def cube_face(shadows, first, P):
    """Which of the six maps first…first+5 to look P up in: the face P is most central in.

    For 90° faces that is the face of P's major axis from the light; the wider
    faces of :func:`cube_face_half_extent` overlap, and the most central wins.
    """
    best, best_k = 1e300, first
    for k in range(first, first + 6):
        x, y, z, w = _project(shadows.matrices, k, P)
        if w > 0.0:
            off_centre = max(abs(x), abs(y)) / w
            if off_centre < best:
                best, best_k = off_centre, k
    return best_k


# map_coordinates, shadow_compare and shadow_map_visibility run per light at every lit sample:
# LLVM inlines them into the shader (forceinline). Called as functions, each call passed the
# ShadowUniform's six arrays on by value, which made bunny-shadows' lighting about three times as
# slow (benchmarks/README.md, "The figures behind the pipeline's comments"). Compiled once on their
# own (not numba's inline="always", which typed them again inside every shader that calls them).
@njit(cache=True, forceinline=True)
def map_coordinates(shadows, k, P):
    """(x, y, ref, inside): P in map k's window space — texels, y up — and its depth ref.

    ``inside`` is False behind the light (w ≤ 0). A point beyond the far plane gets
    ref = 1 (GL's depth clamp): every caster the map holds is nearer, so it is in their
    shadow, and where the map holds none (depth 1) it is lit.
    """
    x, y, z, w = _project(shadows.matrices, k, P)
    if w <= 0.0:
        return 0.0, 0.0, 0.0, False
    ref = min(0.5 * z / w + 0.5, 1.0)
    width, height = shadows.maps[k, 1], shadows.maps[k, 2]
    return (0.5 * x / w + 0.5) * width, (0.5 * y / w + 0.5) * height, ref, True


@njit(cache=True, forceinline=True)
def _lit_taps3(depth, first, width, ref):
    """How many of the 3×3 texels from ``depth[first]`` (the bottom-left tap, ≥ 0; rows ``width`` apart)
    hold a depth ``ref`` is not beyond: each tap's ``not ref > depth`` as 0 or 1, added. (Indexed
    unsigned: numba then adds no test for a negative index to each tap.)"""
    lit = 0
    one, two, step = np.uint64(1), np.uint64(2), np.uint64(width)
    row = np.uint64(first)
    for _ in range(3):
        lit += (np.int64(not ref > depth[row]) + np.int64(not ref > depth[row + one])
                + np.int64(not ref > depth[row + two]))
        row += step
    return lit


@njit(cache=True, forceinline=True)
def shadow_compare(shadows, k, x, y, ref):
    """PCF of map k at window position (x, y) for depth ref: the light that passes, RGB.

    Each tap is 1 where ``ref ≤`` the opaque depth, times the transparent caster's
    transmission where that caster is nearer than ref; taps outside the map are 1.
    """
    offset, width, height, r = shadows.maps[k, 0], shadows.maps[k, 1], shadows.maps[k, 2], shadows.maps[k, 3]
    clear = shadows.maps[k, 4]
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    if i0 < -r or j0 < -r or i0 >= width + r or j0 >= height + r:
        # every tap outside the map: the loop below would add 1.0 per tap to each channel, taps/taps
        # = 1.0 exactly. The common case of a sun's map, fitted to the casters: most of what it
        # lights (the ground around them) lies outside it
        return 1.0, 1.0, 1.0
    if clear < 0 and r <= i0 < width - r and r <= j0 < height - r:
        # the common case: every tap inside a map of opaque casters only. The loop below then adds 1.0
        # per lit tap to each channel, so counting them gives its very sums (whole numbers ≤ 81, exact)
        # without its bounds and transparency tests per tap
        if r == 1:
            # the default 3×3, written out: nine compares summed without a branch per tap (a branch
            # a tap, mispredicted along shadow edges and across acne-free self-shadow, and a loop
            # of runtime length cost twice as much; benchmarks/README.md, "Shadows, round 3")
            lit = _lit_taps3(shadows.depth, offset + (j0 - 1) * width + i0 - 1, width, ref)
        else:
            lit = 0
            for j in range(j0 - r, j0 + r + 1):
                row = offset + j * width
                for i in range(i0 - r, i0 + r + 1):
                    if not ref > shadows.depth[row + i]:
                        lit += 1
        share = lit / ((2 * r + 1) * (2 * r + 1))
        return share, share, share
    red, green, blue = 0.0, 0.0, 0.0
    for j in range(j0 - r, j0 + r + 1):
        for i in range(i0 - r, i0 + r + 1):
            if i < 0 or j < 0 or i >= width or j >= height:
                red += 1.0
                green += 1.0
                blue += 1.0
                continue
            texel = j * width + i
            if ref > shadows.depth[offset + texel]:
                continue                                  # an opaque caster is nearer: no light
            if clear >= 0 and ref > shadows.transparent_depth[clear + texel]:   # through the transparent caster
                red += shadows.transmission[clear + texel, 0]
                green += shadows.transmission[clear + texel, 1]
                blue += shadows.transmission[clear + texel, 2]
            else:
                red += 1.0
                green += 1.0
                blue += 1.0
    taps = (2 * r + 1) * (2 * r + 1)
    return red / taps, green / taps, blue / taps


def depth_texture(framebuffer, pcf: int = 0) -> ShadowUniform:
    """A framebuffer's depth buffer as a depth texture a shader can compare against (render to texture).

    The result is a :class:`ShadowUniform` holding one map (the framebuffer's
    one-sample depth, window rows) with no light; read it with :func:`texture_compare`,
    GLSL's ``texture(sampler2DShadow, vec3(u, v, ref))``, with a PCF radius ``pcf``.
    """
    if framebuffer.samples != 1:
        raise ValueError(f"depth_texture needs a one-sample framebuffer, this one has {framebuffer.samples} samples")
    if isinstance(pcf, bool) or not isinstance(pcf, (int, np.integer)) or not 0 <= pcf <= MAX_PCF_RADIUS:
        raise ValueError(f"pcf must be an integer radius in 0…{MAX_PCF_RADIUS}, got {pcf!r}")
    depth = np.ascontiguousarray(framebuffer.depth[::-1]).ravel()   # image rows → window rows
    return ShadowUniform(np.zeros((0, 3), np.int64),
                         np.array([[0, framebuffer.width, framebuffer.height, pcf, -1]], np.int64),
                         np.eye(4)[None].copy(), depth, np.zeros(0, np.float32), np.zeros((0, 3), np.float32),
                         None)


@njit(cache=True)
def texture_compare(texture, u, v, ref):
    """GLSL's ``texture(sampler2DShadow, vec3(u, v, ref))`` on a :func:`depth_texture`: the share of
    the PCF taps around (u, v) (texture coordinates, [0, 1]², v up) whose depth is ≥ ref."""
    return shadow_compare(texture, 0, u * texture.maps[0, 1], v * texture.maps[0, 2], ref)[0]


@njit(cache=True, forceinline=True)
def shadow_map_visibility(shadows, j, P):
    """V_j from light j's shadow map(s) at the eye-space point P: the RGB share of the light that passes.

    (1, 1, 1) when light j has no shadow map, and for a point outside its map.
    :func:`light_visibility` is what a shader calls: it also takes the lights whose V_j
    comes from shadow rays.
    """
    first, count = shadows.light_maps[j, 0], shadows.light_maps[j, 1]
    if count == 0:
        return 1.0, 1.0, 1.0
    k = first if count == 1 else cube_face(shadows, first, P)
    x, y, ref, inside = map_coordinates(shadows, k, P)
    if not inside:
        return 1.0, 1.0, 1.0
    return shadow_compare(shadows, k, x, y, ref)


def casts_shadows(lighting, j: int) -> bool:
    """Does light j of the ``lighting`` uniform (a LightingUniform) cast shadows (a shadow map or shadow rays)?

    The lighting sums ask it before :func:`light_visibility`. A lighting uniform without
    shadows has ``shadows = None``; compiled, that is known from its type, the
    question is answered False when numba compiles the shader and the shadow code is
    left out of it: a draw without shadows runs the code it ran before shadows existed
    (a ``ShadowUniform`` holds many arrays, and a shader that carried them through
    every sample paid for each of them).
    """
    shadows = lighting.shadows
    if shadows is None:
        return False
    return shadows.light_maps[j, 1] > 0 or shadows.light_maps[j, 2] == SHADOW_RAY


def _shadows_type(lighting):
    """numba's type of ``lighting.shadows`` (a LightingUniform's last field)."""
    return lighting.types[list(lighting.fields).index("shadows")] if hasattr(lighting, "fields") else None


@overload(casts_shadows, jit_options={"forceinline": True})
def _casts_shadows_numba(lighting, j):
    if isinstance(_shadows_type(lighting), (types.NoneType, types.Omitted)):
        return lambda lighting, j: False

    def impl(lighting, j):
        rows = lighting.shadows.light_maps
        return (rows[j, 1] > 0) | (rows[j, 2] == SHADOW_RAY)   # no short-circuit: no branch for the inliner
    return impl


def light_visibility(lighting, j: int, P: Sequence[float]) -> Color:
    """V_j: the RGB share of light j that reaches the eye-space point P past everything else (§11, §21).

    ``lighting`` is the ``lighting`` uniform (a :class:`~softpipe.light.material.LightingUniform`).
    From ``lighting.shadows``: light j's shadow map(s) (:func:`shadow_map_visibility`), or a shadow ray toward the
    light — to its position for a point or spot light, to infinity for a directional
    one — through any transparent objects (:func:`~softpipe.rays.queries.ray_visibility`).
    (1, 1, 1) for a light that casts no shadows, and when ``lighting.shadows`` is None.
    Ambient light is never shadowed (§10).
    """
    if lighting.shadows is None:
        return (1.0, 1.0, 1.0)
    return _shadowed_visibility(lighting.lights, lighting.shadows, j, P)


def light_visibilities(lighting, points: np.ndarray) -> np.ndarray:
    """V_j of every light at many eye-space points in one compiled pass: float64 [N, L, 3], where row i,
    light j is ``light_visibility(lighting, j, points[i])`` — the very function the shaders call, so
    the values are the ones a shader computed (a pixel history shows them, FORMULAS §21).

    ``points`` is [N, 3] (any float dtype; read as float64). Calling :func:`light_visibility` from
    Python once per fragment and light costs a call into compiled code each (and the typing of its
    arguments): the explorer of a shadowed model asked it hundreds of thousands of times.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"light_visibilities: points must be an [N, 3] array of eye-space points, got shape "
                         f"{pts.shape}")
    shadows = lighting.shadows
    lights = 0 if shadows is None else len(shadows.light_maps)
    out = np.ones((len(pts), lights, 3))
    if lights and len(pts):
        _visibility_pass(lighting, pts, out)
    return out


@njit(cache=True)
def _visibility_pass(lighting, points, out):
    for i in range(points.shape[0]):
        P = (points[i, 0], points[i, 1], points[i, 2])
        for j in range(out.shape[1]):
            v = light_visibility(lighting, j, P)
            out[i, j, 0], out[i, j, 1], out[i, j, 2] = v[0], v[1], v[2]


# inlined, as _shadowed_visibility and the map lookups above: per light and lit sample
@overload(light_visibility, jit_options={"forceinline": True})
def _light_visibility_numba(lighting, j, P):
    if isinstance(_shadows_type(lighting), (types.NoneType, types.Omitted)):
        return lambda lighting, j, P: (1.0, 1.0, 1.0)
    # The shadow arrays are handed on *borrowed* (softpipe.core.borrow: no owner, so numba counts no
    # references): otherwise every call that received them would count two atomic operations per array,
    # per light, per sample, more than the lookups themselves (benchmarks/README.md, "Shadows").
    return lambda lighting, j, P: _shadowed_visibility(borrowed(lighting.lights), borrowed_tuple(lighting.shadows),
                                                       j, P)


def _rays_only(shadows_type) -> bool:
    """Is this ShadowUniform's numba type one without maps (``maps`` None: every shadow from rays)?"""
    fields = tuple(getattr(shadows_type, "fields", ()))
    return "maps" in fields and isinstance(shadows_type.types[fields.index("maps")], types.NoneType)


def _shadowed_visibility(lights, shadows, j, P):
    if shadows.light_maps[j, 2] == SHADOW_RAY:
        return _shadow_ray(shadows.rays, lights, j, P)
    return shadow_map_visibility(shadows, j, P)


@overload(_shadowed_visibility, jit_options={"forceinline": True})
def _shadowed_visibility_numba(lights, shadows, j, P):
    # shadows from rays only (maps None, as the ray tracer's): no map lookup compiled; a light that casts
    # shadows then has method SHADOW_RAY (casts_shadows asked first)
    if _rays_only(shadows):
        return lambda lights, shadows, j, P: _shadow_ray(shadows.rays, lights, j, P)
    return _shadowed_visibility


def _shadow_ray(rays, lights, j, P):
    """V_j by a shadow ray toward light j (to its position, or to infinity for a directional light)."""
    if rays is None:
        return (1.0, 1.0, 1.0)
    position = light_vec3(lights, j, LIGHT_POSITION)
    if lights[j, LIGHT_KIND] == LIGHT_DIRECTIONAL:
        return ray_visibility(rays, P, position, np.inf)
    to_light = sub(position, P)
    return ray_visibility(rays, P, normalize(to_light), length(to_light))


@overload(_shadow_ray)
def _shadow_ray_numba(rays, lights, j, P):
    # shadows made with maps only carry rays=None: no ray scene's arrays in the shader, no ray code compiled
    if isinstance(rays, (types.NoneType, types.Omitted)):
        return lambda rays, lights, j, P: (1.0, 1.0, 1.0)
    return _shadow_ray
