"""Surface materials: the coefficients of the lighting equations (FORMULAS §1–§15).

Names follow the notes:

ke          emission color (FORMULAS §1)
ka          ambient reflectance (§2)
kd          diffuse reflectance (§3)
ks          specular reflectance (§5, §6)
shininess   the specular exponent n (§5, §6)
kr          reflection coefficient of the Hall model (§13)
kt          transmission coefficient of the Hall model (§13)
transmission_shininess   the transmission exponent n' (§13, §14)
ior         index of refraction of the material (§17)
opacity     alpha of the surface (1 = opaque)
diffuse_texture  path of a texture that multiplies kd (MTL ``map_Kd``), or None

Colors are linear RGB triples of floats; each must be finite and non-negative.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Optional, Tuple

RGB = Tuple[float, float, float]


def _rgb(name: str, value) -> RGB:
    """Validate one RGB color field; a single number means gray."""
    if isinstance(value, (int, float)):
        value = (value, value, value)
    try:
        triple = tuple(float(c) for c in value)
    except (TypeError, ValueError):
        raise TypeError(f"Material.{name} must be an RGB triple of numbers, got {value!r}") from None
    if len(triple) != 3:
        raise ValueError(f"Material.{name} must have 3 components (RGB), got {len(triple)}: {value!r}")
    for c in triple:
        if not math.isfinite(c) or c < 0.0:
            raise ValueError(f"Material.{name} must be finite and non-negative, got {value!r}")
    return triple


def _scalar(name: str, value, low: float = 0.0) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"Material.{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x < low:
        raise ValueError(f"Material.{name} must be finite and >= {low}, got {value!r}")
    return x


_COLOR_FIELDS = ("ke", "ka", "kd", "ks", "kr", "kt")


@dataclass(frozen=True)
class Material:
    """The coefficients of one surface; see the module docstring for each name."""

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

    def __post_init__(self) -> None:
        for f in _COLOR_FIELDS:
            object.__setattr__(self, f, _rgb(f, getattr(self, f)))
        object.__setattr__(self, "shininess", _scalar("shininess", self.shininess))
        object.__setattr__(
            self, "transmission_shininess", _scalar("transmission_shininess", self.transmission_shininess)
        )
        ior = _scalar("ior", self.ior)
        if ior <= 0.0:
            raise ValueError(f"Material.ior must be > 0, got {self.ior!r}")
        object.__setattr__(self, "ior", ior)
        opacity = _scalar("opacity", self.opacity)
        if opacity > 1.0:
            raise ValueError(f"Material.opacity must be in [0, 1], got {self.opacity!r}")
        object.__setattr__(self, "opacity", opacity)

    def replace(self, **changes) -> "Material":
        """A copy with some fields changed (validated like the constructor)."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise TypeError(f"Material has no field(s) {sorted(unknown)}")
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return Material(**values)
