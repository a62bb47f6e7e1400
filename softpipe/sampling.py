"""Sample patterns: where inside a pixel the rasterizer tests coverage.

A pattern is a list of positions in the unit square of one pixel, in OpenGL's
window orientation (x right, y up, (0, 0) the pixel's lower-left corner), each
snapped to the rasterizer's 1/256-pixel grid. One sample at (½, ½) is ordinary
rasterization; more samples are supersampling or multisampling (the same
rasterizer, fed a different pattern).
"""
from __future__ import annotations

from typing import Iterable, Sequence, Tuple

import numpy as np

__all__ = ["SamplePattern", "CENTER", "MAX_SAMPLES"]

#: Subpixel precision of the rasterizer: 8 bits, 1/256 pixel (DESIGN.md).
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

    def __init__(self, positions: Sequence[Tuple[float, float]], name: str = "custom"):
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2 or len(pos) == 0:
            raise ValueError(f"sample positions must have shape [S, 2] with S ≥ 1, got {list(pos.shape)}")
        if len(pos) > MAX_SAMPLES:
            raise ValueError(f"a sample pattern has at most {MAX_SAMPLES} samples, got {len(pos)}")
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
