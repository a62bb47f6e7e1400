"""Sample patterns: where inside a pixel the rasterizer tests coverage.

A pattern is a list of positions in the unit square of one pixel, in OpenGL's
window orientation (x right, y up, (0, 0) the pixel's lower-left corner), each
snapped to the rasterizer's 1/256-pixel grid. One sample at (½, ½) is ordinary
rasterization; more samples are supersampling or multisampling (the same
rasterizer, fed a different pattern).
"""
from __future__ import annotations

from typing import Sequence, Tuple, Union

import numpy as np

__all__ = ["SamplePattern", "CENTER", "MAX_SAMPLES", "grid", "rotated_grid_4x", "jittered", "random_pattern",
           "pattern_named",
           "SUBPIXEL"]

#: Subpixel precision of the rasterizer: 8 bits, 1/256 pixel (docs/design.md, "Rasterization rules").
SUBPIXEL_BITS = 8
SUBPIXEL = 1 << SUBPIXEL_BITS
MAX_SAMPLES = 64


class SamplePattern:
    """Sample positions inside a pixel.

    Parameters
    ----------
    positions : sequence of (x, y) in [0, 1), y up
    name : a label for pictures and traces
    """

    def __init__(self, positions: Union[Sequence[Tuple[float, float]], np.ndarray], name: str = "custom"):
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2 or len(pos) == 0:
            raise ValueError(f"sample positions must have shape [S, 2] with S ≥ 1, got {list(pos.shape)}")
        if len(pos) > MAX_SAMPLES:
            raise ValueError(f"a sample pattern has at most MAX_SAMPLES = {MAX_SAMPLES} samples, got {len(pos)}")
        if not np.all(np.isfinite(pos)) or pos.min() < 0.0 or pos.max() >= 1.0:
            raise ValueError("sample positions must lie in [0, 1) × [0, 1)")
        # Offsets from the pixel centre in 1/256 pixel, rounded half to even as
        # the vertices are, so that sample and vertex grids are the same grid.
        self.offsets = np.rint((pos - 0.5) * SUBPIXEL).astype(np.int64)
        self.positions = self.offsets / SUBPIXEL + 0.5
        self.name = name

    def __len__(self) -> int:
        return len(self.offsets)

    @property
    def count(self) -> int:
        return len(self.offsets)

    def __repr__(self) -> str:
        return f"SamplePattern({self.name!r}, {len(self)} samples)"


CENTER = SamplePattern([(0.5, 0.5)], name="center")


def grid(s: int) -> SamplePattern:
    """The regular s×s grid of the notes (FORMULAS §24): ((i + ½)/s, (j + ½)/s), i, j in 0…s−1.

    Listed row by row from the top of the pixel (the notes' v = 1 − (y + (j + ½)/s)/h
    counts j downward), left to right.
    """
    s = _count("grid size", s, 1, 8)
    pos = [((i + 0.5) / s, 1.0 - (j + 0.5) / s) for j in range(s) for i in range(s)]
    return SamplePattern(pos, name=f"grid {s}x{s}")


def rotated_grid_4x() -> SamplePattern:
    """The standard 4× multisample pattern (rotated grid).

    Direct3D's standard pattern for 4 samples (D3D11_STANDARD_MULTISAMPLE_PATTERN,
    documented in the D3D11 functional specification) gives the offsets from
    the pixel centre in 1/16 pixel, y down: (−2, −6), (6, −2), (−6, 2), (2, 6);
    i.e. (0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875) from the
    top-left corner. softpipe's pixel space has y up, so y becomes 1 − y.
    """
    d3d = [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)]
    return SamplePattern([(x, 1.0 - y) for x, y in d3d], name="rotated grid 4x")


def jittered(s: int, seed: int = 0) -> SamplePattern:
    """Stratified s×s: one sample at a random place in each cell of the s×s grid (seeded)."""
    s = _count("jittered grid size", s, 1, 8)
    rng = np.random.default_rng(seed)
    u = rng.random((s, s, 2)) * (1.0 - 1e-9)
    pos = [((i + u[j, i, 0]) / s, 1.0 - (j + u[j, i, 1]) / s) for j in range(s) for i in range(s)]
    return SamplePattern(np.clip(pos, 0.0, 1.0 - 1.0 / SUBPIXEL), name=f"jittered {s}x{s} (seed {seed})")


def random_pattern(n: int, seed: int = 0) -> SamplePattern:
    """n samples uniformly at random in the pixel (seeded)."""
    n = _count("number of samples (MAX_SAMPLES)", n, 1, MAX_SAMPLES)
    rng = np.random.default_rng(seed)
    return SamplePattern(rng.random((n, 2)) * (1.0 - 1.0 / SUBPIXEL), name=f"random {n} (seed {seed})")


def _count(what: str, value, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{what} must be an integer, got {value!r}")
    if not low <= value <= high:
        raise ValueError(f"{what} must be in [{low}, {high}], got {value}")
    return int(value)


def pattern_named(name: str) -> SamplePattern:
    """A pattern from a short name: ``1``, ``center``, ``grid4`` (= 2×2), ``grid16``, ``rgss4``,
    ``jitter16``, ``random8`` … (used by the command line)."""
    text = str(name).strip().lower()
    if text in ("1", "center", "none"):
        return CENTER
    if text in ("rgss4", "rotated4", "4"):
        return rotated_grid_4x()
    for prefix in ("grid", "jitter", "random"):
        if text.startswith(prefix) and text[len(prefix):].isdigit():
            n = int(text[len(prefix):])
            if prefix == "random":
                return random_pattern(n)
            side = int(round(n ** 0.5))
            if side * side != n:
                raise ValueError(f"sample pattern {name!r}: {prefix} needs a square number of samples, got {n}")
            return grid(side) if prefix == "grid" else jittered(side)
    raise ValueError(f"unknown sample pattern {name!r}; expected 1, grid4, grid9, grid16, rgss4, jitter16, "
                     "random8, …")
