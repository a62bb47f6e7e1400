"""Stage 4: the fragment stage — interpolate the varyings, run the fragment shader.

For each fragment the varyings are interpolated from the triangle's corners
with their qualifiers (:func:`softpipe.shader.fragment_kernel` writes the loop):

* ``smooth`` (the default): perspective-correct,
  ``v = Σ (b_k / w_k) v_k / Σ (b_k / w_k)``;
* ``noperspective``: linear in window space, ``v = Σ b_k v_k``;
* ``flat``: the provoking vertex's value (the triangle's last vertex).

then the fragment shader turns them into an RGBA color (or discards the
fragment). With no fragment shader, the color is the varying ``color`` (RGB,
alpha 1, or RGBA). Output: :class:`ShadedFragments`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from . import shader as _shader
from .assembly import Primitives
from .raster import Fragments
from .shader import FragInfo

__all__ = ["ShadedFragments", "run_fragment_stage", "color_rgb", "color_rgba"]


@dataclass
class ShadedFragments:
    """The fragment shader's outputs, one row per fragment of the :class:`Fragments`.

    Attributes
    ----------
    color : float32 [F, 4]
        RGBA, linear, unclamped.
    discarded : bool [F]
        True where the shader returned DISCARD.
    """

    color: np.ndarray
    discarded: np.ndarray

    def __len__(self) -> int:
        return len(self.color)

    def __repr__(self) -> str:
        return f"ShadedFragments({len(self)} fragments, {int(self.discarded.sum())} discarded)"


def color_rgb(varyings, uniforms, frag):
    """The default fragment shader for an RGB ``color`` varying."""
    c = varyings.color
    return (c[0], c[1], c[2], 1.0)


def color_rgba(varyings, uniforms, frag):
    """The default fragment shader for an RGBA ``color`` varying."""
    c = varyings.color
    return (c[0], c[1], c[2], c[3])


def default_fragment_shader(layout) -> Callable:
    """The shader used when a draw has none: the interpolated ``color`` varying."""
    for name, _, size, _ in layout.fields:
        if name == "color":
            if size == 3:
                return color_rgb
            if size == 4:
                return color_rgba
            raise ValueError(f"with no fragment shader the varying 'color' must be RGB or RGBA, got {size} components")
    raise ValueError("no fragment_shader was given and there is no varying named 'color' to use as the color; "
                     f"the varyings are {list(layout.names)}")


def window_coordinates(frags: Fragments, pattern, height: int):
    """The sample's window position as gl_FragCoord: x right, y up, pixel centres at +½."""
    pos = pattern.positions
    fx = frags.x + pos[frags.sample, 0]
    fy = (height - 1 - frags.y) + pos[frags.sample, 1]
    return fx.astype(np.float64), fy.astype(np.float64)


def run_fragment_stage(frags: Fragments, prims: Primitives, fragment_shader: Optional[Callable], uniforms,
                       pattern, height: int) -> ShadedFragments:
    """Shade every fragment. See the module docstring."""
    shader = fragment_shader or default_fragment_shader(prims.layout)
    n = len(frags)
    color = np.empty((n, 4), dtype=np.float32)
    if n == 0:
        return ShadedFragments(color, np.zeros(0, dtype=bool))
    fx, fy = window_coordinates(frags, pattern, height)
    if fragment_shader is not None:
        _probe(shader, frags, prims, uniforms, fx, fy)
    kernel = _shader.fragment_kernel(shader, prims.layout)
    _shader.run_compiled("fragment", shader, kernel, frags.triangle, fx, fy, frags.depth, frags.bary,
                         prims.inv_w, prims.varyings, prims.front_facing, prims.primitive_id, uniforms, color)
    discarded = np.isnan(color[:, 3])
    return ShadedFragments(color, discarded)


def _probe(shader, frags, prims, uniforms, fx, fy) -> None:
    """Run the shader on the first fragment in Python, for a clear error before numba's."""
    t = int(frags.triangle[0])
    values = prims.layout.unpack(prims.varyings[t, 2])
    import collections
    V = collections.namedtuple("Varyings", list(values) or ["none"])
    args = [float(v) if np.ndim(v) == 0 else tuple(float(c) for c in v) for v in values.values()] or [0.0]
    frag = FragInfo(float(fx[0]), float(fy[0]), float(frags.depth[0]), bool(prims.front_facing[t]),
                    int(prims.primitive_id[t]))
    _shader.probe_fragment_shader(shader, V(*args), uniforms, frag)
