"""A perspective camera: where the eye is, what it looks at, and how wide it sees.

``Camera(eye, target, up, fovy, near, far)`` gives the view matrix
(:func:`softpipe.pipeline.transforms.look_at`) and, for an aspect ratio, the projection
(:func:`softpipe.pipeline.transforms.perspective`). :meth:`Camera.frame` places a camera
so that a bounding box fills the view.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence, Tuple

import numpy as np

from softpipe.pipeline.transforms import look_at, perspective, rotate_x, rotate_y

__all__ = ["Camera"]


def _triple(name: str, v) -> Tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"Camera.{name} must be 3 finite numbers, got {v!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True)
class Camera:
    """A perspective camera; angles in degrees, distances in scene units."""

    eye: Tuple[float, float, float] = (0.0, 0.0, 3.0)
    target: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0)
    fovy: float = 40.0
    near: float = 0.1
    far: float = 100.0

    def __post_init__(self):
        for name in ("eye", "target", "up"):
            object.__setattr__(self, name, _triple(name, getattr(self, name)))
        if not 0.0 < float(self.fovy) < 180.0:
            raise ValueError(f"Camera.fovy must be in (0, 180) degrees, got {self.fovy!r}")
        if not 0.0 < float(self.near) < float(self.far) or not math.isfinite(float(self.far)):
            raise ValueError(f"Camera needs 0 < near < far (finite), got near={self.near!r}, far={self.far!r}")
        look_at(self.eye, self.target, self.up)   # validates: distinct points, up not parallel

    @property
    def view(self) -> np.ndarray:
        """World → eye (4×4)."""
        return look_at(self.eye, self.target, self.up)

    def projection(self, aspect: float) -> np.ndarray:
        """Eye → clip (4×4) for a viewport of width/height = ``aspect``."""
        return perspective(self.fovy, aspect, self.near, self.far)

    @classmethod
    def frame(cls, bounds, azimuth: float = 30.0, elevation: float = 20.0, fovy: float = 35.0,
              margin: float = 1.1, aspect: float = 1.0, up: Sequence[float] = (0.0, 1.0, 0.0)) -> "Camera":
        """A camera that sees the whole box ``bounds`` (a (min, max) pair, or a mesh).

        The camera looks at the box's centre from the direction given by
        ``azimuth`` (about +y, from +z toward +x) and ``elevation`` (above the
        xz plane), far enough back that the box's bounding sphere, grown by
        ``margin``, fits in the narrower of the two fields of view.
        """
        if hasattr(bounds, "bounds"):
            bounds = bounds.bounds()
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
        if lo.shape != (3,) or hi.shape != (3,) or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError("Camera.frame: bounds must be two finite 3-vectors (min, max)")
        centre = (lo + hi) / 2
        radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-9) * margin
        half = math.radians(fovy) / 2
        half_narrow = min(half, math.atan(math.tan(half) * aspect))
        distance = radius / math.sin(half_narrow)
        direction = (rotate_y(azimuth) @ rotate_x(-elevation) @ np.array([0.0, 0.0, 1.0, 0.0]))[:3]
        eye = centre + distance * direction
        return cls(eye=tuple(eye), target=tuple(centre), up=_triple("up", up), fovy=fovy,
                   near=max(distance - radius, 1e-3 * distance), far=distance + radius)

    def replace(self, **changes) -> "Camera":
        return replace(self, **changes)
