"""Materials and lights: the coefficients of the lighting equations (FORMULAS §1–§15, §26).

:class:`Material` holds one surface's coefficients under the notes' names (ke, ka,
kd, ks, shininess, kr, kt, ior, ...; its docstring gives each with its §);
:class:`Light` one light source (FORMULAS §7–§10); :func:`pack_lights` packs lights
for shaders into the columns of :mod:`softpipe.light.packed`; :data:`MEDIA` names
the notes' indices of refraction (``ior="glass"``).

Colors are linear RGB triples of floats, each finite and non-negative; a single
number means gray, a string a color's name or hex (``"orange"``, ``"#ff8000"``).
The fields are checked by :mod:`softpipe.core.validation`, which scene and job files
share, so a mistake is worded alike: ``Material.kd must hold numbers >= 0, got …``.

Lights are given in **world space**; ``pack_lights(lights, view)`` brings positions
and directions into **eye space** with the view matrix (world → eye), because
softpipe shades in eye space: the eye is at the origin and V = normalize(−P), so a
fragment shader needs the eye-space P and N (the normal matrix's job) and the
packed lights. ``Light.direction`` and ``Light.spot_direction`` (S of §8) are the
direction **the light travels**; L, the unit vector from the surface toward the
light, is −direction for a directional light, which the packed array stores as
OpenGL does: a homogeneous position with w = 0 whose xyz is that L.

Where these coefficients enter the formulas: docs/hall.md (Hall's terms, emission,
Fresnel) and docs/shaders.md (the names a shader reads).
"""
from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass, field, fields
from typing import Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from softpipe.core.validation import checked, color, is_number, nonnegative, nonzero_vec3, numbers, positive, vec3
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
)
from softpipe.light.shadowmap import ShadowSettings, light_visibilities, light_visibility

RGB = Tuple[float, float, float]
Vec3 = Tuple[float, float, float]

__all__ = [
    "Material", "MaterialUniform", "MEDIA", "FALLOFFS", "falloff_factor", "Light", "Lighting", "LightingUniform", "pack_lights",
]


# --------------------------------------------------------------------------
# Material
# --------------------------------------------------------------------------

_COLOR_FIELDS = ("ke", "ka", "kd", "ks", "kr", "kt")

#: Indices of refraction of the notes' named media (FORMULAS §17): ``Material(ior="glass")``.
MEDIA = {"vacuum": 1.0, "air": 1.00029, "water": 1.33, "glass": 1.52, "salt": 1.54, "sapphire": 1.77,
         "diamond": 2.417}

#: The indices of refraction a Material takes (FORMULAS §17): real media lie between about 1
#: and 4. Outside this range η² (the refraction's k = 1 − η²(1 − c²), §18) overflows or
#: underflows for values such as 1e200, and the refracted ray would be NaN.
IOR_RANGE = (1e-3, 1e3)

#: The two forms of falloff in a medium over distance d (FORMULAS §15): T^d, and Glassner's 1/(1 + a·d).
FALLOFFS = ("power", "glassner")


def _ior(value) -> float:
    """An index of refraction: a number > 0 or a name from MEDIA (§17)."""
    if isinstance(value, str):
        key = value.strip().lower()
        if key not in MEDIA:
            known = ", ".join(f"{name} {n}" for name, n in MEDIA.items())
            raise ValueError(f"Material.ior: unknown medium {value!r}; the named media (FORMULAS §17) are {known}")
        return MEDIA[key]
    n = checked("Material.ior", positive, value)
    low, high = IOR_RANGE
    if not low <= n <= high:
        raise ValueError(f"Material.ior must be between {low:g} and {high:g} (real media are about 1 to 4; "
                         f"outside this range the refraction's η² overflows), got {n!r}")
    return n


def falloff_factor(material: "Material", d: float) -> RGB:
    """The share of light (RGB) left after distance d inside ``material`` (FORMULAS §15).

    T^d per channel for ``falloff="power"`` (Hall's T_r^{d_r}, T_t^{d_t} of §13), or
    Glassner's 1/(1 + a·d) for ``falloff="glassner"``. The ray tracer computes the same
    (``softpipe.tracers.whitted``); this is the reference in plain Python.
    """
    if material.falloff == "glassner":
        g = 1.0 / (1.0 + material.falloff_a * d)
        return (g, g, g)
    return tuple(t ** d for t in material.transmittance)

MaterialUniform = namedtuple(
    "MaterialUniform",
    ["ke", "ka", "kd", "ks", "shininess", "kr", "kt", "transmission_shininess",
     "ior", "opacity", "roughness"],
)
MaterialUniform.__doc__ = """A material as a shader sees it: colors as 3-tuples, the rest floats.

Fields as :class:`Material` (without the texture path and the name). A module-level
namedtuple of fixed field types, so every material gives numba the same type
and a cached kernel is reused.
"""


@dataclass(frozen=True)
class Material:
    """The coefficients of one surface, under the notes' names (FORMULAS §1–§15, §26).

    Parameters
    ----------
    ke
        Emission color (§1).
    ka
        Ambient reflectance (§2).
    kd
        Diffuse reflectance (§3).
    ks
        Specular reflectance (§5, §6).
    shininess
        The specular exponent n (§5, §6); 0 is the notes' "planet": (N·H)⁰ = 1.
    kr
        Reflection coefficient of the Hall model (§13).
    kt
        Transmission coefficient of the Hall model (§13).
    transmission_shininess
        The transmission exponent n' (§13, §14).
    ior
        Index of refraction of the material (§17); Fresnel (§20) and Cook-Torrance
        (§26) use it, so ior = 1 means "no specular reflection" there. A name from
        :data:`MEDIA` (``ior="glass"``) gives the notes' index. Between 0.001 and
        1000 (:data:`IOR_RANGE`).
    opacity
        Alpha of the surface (1 = opaque).
    diffuse_texture
        Path of a texture that multiplies kd (MTL ``map_Kd``), or None.
    name
        A label (not compared).
    roughness
        Beckmann's m, the rms slope of the microfacets, for Cook-Torrance (§26).
    transmittance
        T, the share of light (RGB) left after one unit of distance *inside* the
        object (§13's T_r, T_t; §15): a ray that crosses d units of it keeps T^d.
        1 (the default) is clear; air outside objects is taken as T = 1 (§15).
    falloff
        How that share falls with distance d inside: ``"power"`` (the default),
        T^d (§15, Hall's form); ``"glassner"``, Glassner's 1/(1 + a·d) with
        a = ``falloff_a`` (then ``transmittance`` is not used).
    falloff_a
        Glassner's a ≥ 0 (per unit distance); 0 means no falloff.
    k
        The extinction coefficient (RGB, ≥ 0) of a conductor: a metal's index of
        refraction is complex, η + ik, per channel (FORMULAS §30). 0 (the default):
        not a conductor. Where k ≠ 0 the path tracer (:mod:`softpipe.tracers.pathtrace`)
        weights the mirror reflection ``kr`` by the conductor's exact Fresnel
        reflectance, per channel (``kr = 1`` for a bare metal); nothing else reads it.
    eta
        The real part η of that complex index, per channel (RGB, each > 0); None
        (the default): ``ior`` in every channel. Gold and copper need one per
        channel (docs/pathtracing.md, "Conductors").

    ``transmittance``, ``falloff`` and ``falloff_a`` are read by the ray tracer
    (:mod:`softpipe.tracers.whitted`), the only place a distance inside an object is
    known; they are not in :class:`MaterialUniform` (a shader has no such distance).
    """

    ke: RGB = (0.0, 0.0, 0.0)
    ka: RGB = (0.1, 0.1, 0.1)
    kd: RGB = (0.7, 0.7, 0.7)
    ks: RGB = (0.2, 0.2, 0.2)
    shininess: float = 32.0
    kr: RGB = (0.0, 0.0, 0.0)
    kt: RGB = (0.0, 0.0, 0.0)
    transmission_shininess: float = 32.0
    ior: float = 1.0
    opacity: float = 1.0
    diffuse_texture: Optional[str] = None
    name: str = field(default="default", compare=False)
    # Keyword-only, so that the positional order of the fields above is unchanged.
    roughness: float = field(default=0.3, kw_only=True)
    transmittance: RGB = field(default=(1.0, 1.0, 1.0), kw_only=True)
    falloff: str = field(default="power", kw_only=True)
    falloff_a: float = field(default=0.0, kw_only=True)
    k: RGB = field(default=(0.0, 0.0, 0.0), kw_only=True)
    eta: Optional[RGB] = field(default=None, kw_only=True)

    def __post_init__(self) -> None:
        for f in _COLOR_FIELDS:
            object.__setattr__(self, f, checked(f"Material.{f}", color, getattr(self, f)))
        for f in ("shininess", "transmission_shininess"):
            object.__setattr__(self, f, checked(f"Material.{f}", nonnegative, getattr(self, f)))
        object.__setattr__(self, "ior", _ior(self.ior))
        opacity = checked("Material.opacity", nonnegative, self.opacity)
        if opacity > 1.0:
            raise ValueError(f"Material.opacity must be in [0, 1], got {self.opacity!r}")
        object.__setattr__(self, "opacity", opacity)
        object.__setattr__(self, "roughness", checked("Material.roughness", positive, self.roughness))  # Beckmann m
        transmittance = checked("Material.transmittance", color, self.transmittance)
        if max(transmittance) > 1.0:
            raise ValueError(f"Material.transmittance is a share per unit distance, in [0, 1] per channel, "
                             f"got {self.transmittance!r}")
        object.__setattr__(self, "transmittance", transmittance)
        if self.falloff not in FALLOFFS:
            raise ValueError(f"Material.falloff must be 'power' (T^d) or 'glassner' (1/(1 + a·d)), "
                             f"got {self.falloff!r}")
        object.__setattr__(self, "falloff_a", checked("Material.falloff_a", nonnegative, self.falloff_a))
        object.__setattr__(self, "k", checked("Material.k", color, self.k))
        if self.eta is not None:
            eta = checked("Material.eta", color, self.eta)
            if min(eta) <= 0.0:
                raise ValueError(f"Material.eta is the real part of a conductor's complex index η + ik, > 0 in "
                                 f"every channel, got {self.eta!r}")
            object.__setattr__(self, "eta", eta)

    @property
    def conductor_eta(self) -> RGB:
        """η per channel of the complex index η + ik: ``eta``, or ``ior`` in every channel."""
        return self.eta if self.eta is not None else (self.ior, self.ior, self.ior)

    def replace(self, **changes) -> "Material":
        """A copy with some fields changed (validated like the constructor)."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise TypeError(f"Material has no field(s) {sorted(unknown)}")
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return Material(**values)

    def __softpipe_uniform__(self) -> MaterialUniform:
        """The numeric fields as a :class:`MaterialUniform` (colors as 3-tuples of floats)."""
        return MaterialUniform(
            ke=self.ke, ka=self.ka, kd=self.kd, ks=self.ks, shininess=self.shininess,
            kr=self.kr, kt=self.kt, transmission_shininess=self.transmission_shininess,
            ior=self.ior, opacity=self.opacity, roughness=self.roughness,
        )


# --------------------------------------------------------------------------
# Lights
# --------------------------------------------------------------------------

_KIND_CODES = {"directional": LIGHT_DIRECTIONAL, "point": LIGHT_POINT, "spot": LIGHT_SPOT}

#: Light.attenuation's reader: (a, b, c), each finite and >= 0 (FORMULAS §7).
_ATTENUATION = numbers(3, what="numbers (a, b, c)", allow_negative=False)


@dataclass(frozen=True)
class Light:
    """One light source, in world space (FORMULAS §7–§9).

    Parameters
    ----------
    kind
        ``"directional"`` (a direction, no position, no attenuation, no spot),
        ``"point"`` (a position) or ``"spot"`` (a point light with S, β, e).
    ambient, diffuse, specular
        The light's colors I_a, I_d, I_s (§10); a number means gray.
    position
        World-space position; required for point and spot lights, not allowed
        for directional ones.
    direction
        Directional lights only: the direction the light **travels** (so L = −direction).
    attenuation
        (a, b, c) of f_att = 1/(a + b·r + c·r²) (§7), non-negative, not all zero;
        point and spot lights only (default (1, 0, 0): no attenuation).
    spot_direction
        Spot lights only: S, the direction the spot points (the light travels).
    cutoff
        β in degrees, in [0, 90], or exactly 180 ("not a spot": f_spot = 1).
        Lights other than spots keep the default 180.
    exponent
        The spot exponent e ≥ 0 (§8); spot lights only.
    shadows
        False (the default), True, or a :class:`~softpipe.light.shadowmap.ShadowSettings`:
        whether the light casts shadows, through a shadow map
        (:mod:`softpipe.scenes.shadow_pass`). True means the default settings. Read back as
        None or the settings.
    """

    kind: str
    ambient: RGB = (0.0, 0.0, 0.0)
    diffuse: RGB = (1.0, 1.0, 1.0)
    specular: RGB = (1.0, 1.0, 1.0)
    position: Optional[Sequence[float]] = None
    direction: Optional[Sequence[float]] = None
    attenuation: Tuple[float, float, float] = (1.0, 0.0, 0.0)
    spot_direction: Optional[Sequence[float]] = None
    cutoff: float = 180.0
    exponent: float = 0.0
    name: str = field(default="light", compare=False)
    shadows: Union[bool, ShadowSettings, None] = field(default=None, kw_only=True)

    def __post_init__(self) -> None:
        if self.shadows is True:
            object.__setattr__(self, "shadows", ShadowSettings())
        elif self.shadows is False:
            object.__setattr__(self, "shadows", None)
        elif self.shadows is not None and not isinstance(self.shadows, ShadowSettings):
            raise TypeError(f"Light.shadows must be True, False or a ShadowSettings, got {self.shadows!r}")
        if not isinstance(self.kind, str):
            raise TypeError(f"Light.kind must be a string, got {self.kind!r}")
        if self.kind not in _KIND_CODES:
            raise ValueError(f"Light.kind must be one of 'directional', 'point', 'spot', got {self.kind!r}")
        for f in ("ambient", "diffuse", "specular"):
            object.__setattr__(self, f, checked(f"Light.{f}", color, getattr(self, f)))
        self._validate_geometry()
        self._validate_attenuation()
        self._validate_spot()

    def _validate_geometry(self) -> None:
        if self.kind == "directional":
            if self.position is not None:
                raise ValueError("Light.position does not apply to a directional light (give direction)")
            if self.direction is None:
                raise ValueError("Light.direction is required for a directional light")
            object.__setattr__(self, "direction", checked("Light.direction", nonzero_vec3, self.direction))
        else:
            if self.direction is not None:
                raise ValueError(f"Light.direction applies only to directional lights, not to a {self.kind} light "
                                 "(a spot light's axis is spot_direction)")
            if self.position is None:
                raise ValueError(f"Light.position is required for a {self.kind} light")
            object.__setattr__(self, "position", checked("Light.position", vec3, self.position))

    def _validate_attenuation(self) -> None:
        abc = checked("Light.attenuation", _ATTENUATION, self.attenuation)
        if not any(abc):
            raise ValueError("Light.attenuation must not be all zero (f_att = 1/(a + b·r + c·r²))")
        if self.kind == "directional" and abc != (1.0, 0.0, 0.0):
            raise ValueError("Light.attenuation does not apply to directional lights (FORMULAS §7)")
        object.__setattr__(self, "attenuation", abc)

    def _validate_spot(self) -> None:
        if not is_number(self.cutoff):
            raise TypeError(f"Light.cutoff must be a number of degrees, got {self.cutoff!r}")
        cutoff = float(self.cutoff)
        if not (0.0 <= cutoff <= 90.0 or cutoff == 180.0):  # also rejects NaN
            raise ValueError(f"Light.cutoff must be in [0, 90] degrees or exactly 180, got {self.cutoff!r}")
        object.__setattr__(self, "cutoff", cutoff)
        object.__setattr__(self, "exponent", checked("Light.exponent", nonnegative, self.exponent))
        if self.kind == "spot":
            if self.spot_direction is None:
                raise ValueError("Light.spot_direction is required for a spot light")
            object.__setattr__(self, "spot_direction",
                               checked("Light.spot_direction", nonzero_vec3, self.spot_direction))
            return
        if self.spot_direction is not None or self.cutoff != 180.0 or self.exponent != 0.0:
            raise ValueError(f"Light.spot_direction, cutoff and exponent apply only to spot lights, "
                             f"not to a {self.kind} light")

    # Convenience constructors, reading like the notes' three kinds (§9).
    @classmethod
    def directional(cls, direction: Sequence[float], **kw) -> "Light":
        """A directional light whose rays travel along ``direction`` (world space)."""
        return cls("directional", direction=direction, **kw)

    @classmethod
    def point(cls, position: Sequence[float], **kw) -> "Light":
        """A point light at ``position`` (world space)."""
        return cls("point", position=position, **kw)

    @classmethod
    def spot(cls, position: Sequence[float], spot_direction: Sequence[float],
             cutoff: float, exponent: float = 0.0, **kw) -> "Light":
        """A spot light at ``position`` pointing along ``spot_direction``, cutoff β in degrees."""
        return cls("spot", position=position, spot_direction=spot_direction,
                   cutoff=cutoff, exponent=exponent, **kw)

    def pack(self, view_matrix: np.ndarray) -> np.ndarray:
        """This light as one row of the packed array, in eye space (columns: :mod:`softpipe.light.packed`)."""
        return pack_lights([self], view_matrix)[0]


def _check_view_matrix(view_matrix) -> np.ndarray:
    M = np.asarray(view_matrix, dtype=np.float64)
    if M.shape != (4, 4):
        raise ValueError(f"view_matrix must be 4×4, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError("view_matrix must be finite")
    if not np.allclose(M[3], (0.0, 0.0, 0.0, 1.0)):
        # Light positions are points: a projective last row would need a divide and
        # is never a view matrix (world → eye is rigid, perhaps scaled).
        raise ValueError(f"view_matrix must be affine (last row 0, 0, 0, 1), got {M[3].tolist()}")
    return M


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", under="ignore"):
        n = np.linalg.norm(v)
    if not 1e-150 < n < 1e150:     # |v|² under- or overflowed (a direction of 1e-300): scale it first
        v = v / np.max(np.abs(v))
        n = np.linalg.norm(v)
    return v / n


def pack_lights(lights: Iterable[Light], view_matrix: np.ndarray) -> np.ndarray:
    """Pack lights into a float64 array [num_lights, LIGHT_COLUMNS], in eye space.

    Parameters
    ----------
    lights
        Any number of :class:`Light` (world space); none gives shape (0, 22).
    view_matrix
        The 4×4 world → eye matrix (column vectors: p_eye = view @ p_world).

    Returns
    -------
    numpy.ndarray
        C-contiguous float64, one row per light, columns as :mod:`softpipe.light.packed` lays them out.
        Positions are transformed as points (w = 1); directions by the upper-left
        3×3 and renormalized, so a view matrix with uniform scale is fine.
    """
    M = _check_view_matrix(view_matrix)
    lights = list(lights)
    rows = np.zeros((len(lights), LIGHT_COLUMNS), dtype=np.float64)
    for j, light in enumerate(lights):
        if not isinstance(light, Light):
            raise TypeError(f"lights[{j}] must be a Light, got {type(light).__name__}")
        row = rows[j]
        row[LIGHT_KIND] = _KIND_CODES[light.kind]
        row[LIGHT_AMBIENT:LIGHT_AMBIENT + 3] = light.ambient
        row[LIGHT_DIFFUSE:LIGHT_DIFFUSE + 3] = light.diffuse
        row[LIGHT_SPECULAR:LIGHT_SPECULAR + 3] = light.specular
        if light.kind == "directional":
            toward_light = _unit(M[:3, :3] @ -np.asarray(light.direction))
            row[LIGHT_POSITION:LIGHT_POSITION + 4] = (*toward_light, 0.0)
        else:
            p_eye = M[:3, :3] @ np.asarray(light.position) + M[:3, 3]
            row[LIGHT_POSITION:LIGHT_POSITION + 4] = (*p_eye, 1.0)
        row[LIGHT_ATTENUATION:LIGHT_ATTENUATION + 3] = light.attenuation
        row[LIGHT_SPOT_DIRECTION:LIGHT_SPOT_DIRECTION + 3] = (0.0, 0.0, -1.0)
        row[LIGHT_SPOT_COS_CUTOFF] = -1.0
        if light.kind == "spot":
            row[LIGHT_SPOT_DIRECTION:LIGHT_SPOT_DIRECTION + 3] = _unit(M[:3, :3] @ np.asarray(light.spot_direction))
            row[LIGHT_SPOT_COS_CUTOFF] = _cos_degrees(light.cutoff)
            row[LIGHT_SPOT_EXPONENT] = light.exponent
    return rows


def _cos_degrees(beta: float) -> float:
    """cos β, exact at the ends: 0° → 1, 90° → 0 (math.cos gives 6e-17), 180° → −1."""
    if beta == 90.0:
        return 0.0
    if beta == 180.0:
        return -1.0
    return math.cos(math.radians(beta))


class LightingUniform(namedtuple("LightingUniform", ["global_ambient", "lights", "shadows"])):
    """Lighting as a shader sees it: ``global_ambient`` (RGB tuple),
    ``lights``, the packed eye-space array of :func:`pack_lights`, and ``shadows``, their
    shadow maps and shadow-ray scene (a :class:`~softpipe.light.shadowmap.ShadowUniform`), or None when
    no light casts shadows (then a compiled shader leaves the shadow code out).

    A namedtuple, which numba types by its fields (the method below is for plain
    Python: a pixel history asks it, :meth:`softpipe.pipeline.trace.Trace.pixel_history`).
    """

    __slots__ = ()

    def visibilities(self, P) -> tuple:
        """V_j of every light at the eye-space point P, as the lit programs compute it
        (:func:`~softpipe.light.shadowmap.light_visibility`): a tuple of RGB float triples,
        () when no light casts shadows."""
        shadows = self.shadows
        if shadows is None or not shadows.light_maps[:, 1:].any():
            return ()
        point = tuple(float(v) for v in P)
        return tuple(tuple(float(c) for c in light_visibility(self, j, point)) for j in range(len(shadows.light_maps)))

    def visibilities_at(self, points) -> Optional[np.ndarray]:
        """V_j of every light at each eye-space point of ``points`` [N, 3], in one compiled pass
        (:func:`~softpipe.light.shadowmap.light_visibilities`): float64 [N, L, 3], each row equal to
        :meth:`visibilities` of that point; None when no light casts shadows (where that gives ())."""
        shadows = self.shadows
        if shadows is None or not shadows.light_maps[:, 1:].any():
            return None
        return light_visibilities(self, points)


@dataclass(frozen=True)
class Lighting:
    """The lights of a scene: a global ambient light I_a,global and any number of lights (§10).

    ``global_ambient`` defaults to OpenGL's light-model ambient (0.2, 0.2, 0.2).
    It has no ``__softpipe_uniform__``, because its uniform depends on the camera:
    use ``lighting.uniform(view_matrix)``.
    """

    lights: Sequence[Light] = ()
    global_ambient: RGB = (0.2, 0.2, 0.2)

    def __post_init__(self) -> None:
        lights = tuple(self.lights) if not isinstance(self.lights, Light) else (self.lights,)
        for j, light in enumerate(lights):
            if not isinstance(light, Light):
                raise TypeError(f"Lighting.lights[{j}] must be a Light, got {type(light).__name__}")
        object.__setattr__(self, "lights", lights)
        object.__setattr__(self, "global_ambient", checked("Lighting.global_ambient", color, self.global_ambient))

    def uniform(self, view_matrix: np.ndarray) -> LightingUniform:
        """The lights in eye space for this camera, as a :class:`LightingUniform`, without shadow maps.

        :func:`softpipe.scenes.shadow_pass.render_shadow_maps` makes the maps of the lights that cast
        shadows; its ``uniform(view_matrix)`` is this one with them.
        """
        return LightingUniform(self.global_ambient, pack_lights(self.lights, view_matrix), None)
