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
from .raster import Fragments, barycentric_gradients
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
    invocations: int = -1

    def __len__(self) -> int:
        return len(self.color)

    def __repr__(self) -> str:
        return (f"ShadedFragments({len(self)} fragments, {self.invocations} shader invocations, "
                f"{int(self.discarded.sum())} discarded)")


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


def pixel_runs(frags: Fragments) -> np.ndarray:
    """Index of the first fragment of each run of one triangle's samples in one pixel.

    The rasterizer emits those samples consecutively, so a multisampled draw
    shades each run once.
    """
    if len(frags) == 0:
        return np.zeros(0, dtype=np.int64)
    new = np.ones(len(frags), dtype=bool)
    new[1:] = ((frags.triangle[1:] != frags.triangle[:-1]) | (frags.x[1:] != frags.x[:-1])
               | (frags.y[1:] != frags.y[:-1]))
    return np.nonzero(new)[0]


def window_coordinates(frags: Fragments, pattern, height: int, shading: str = "sample"):
    """Where each fragment is shaded, as gl_FragCoord: x right, y up, pixel centres at +½.

    The sample's position; with multisampling, the pixel centre ("center") or
    the centroid of the run's covered samples ("centroid").
    """
    row = (height - 1 - frags.y).astype(np.float64)
    if shading == "center":
        return frags.x + 0.5, row + 0.5
    pos = pattern.positions[frags.sample]
    if shading == "centroid" and len(frags):
        heads = pixel_runs(frags)
        sizes = np.diff(np.append(heads, len(frags)))
        mean = np.add.reduceat(pos, heads, axis=0) / sizes[:, None]
        pos = np.repeat(mean, sizes, axis=0)
    return frags.x + pos[:, 0], row + pos[:, 1]


def run_fragment_stage(frags: Fragments, prims: Primitives, fragment_shader: Optional[Callable], uniforms,
                       pattern, height: int, shading: str = "sample") -> ShadedFragments:
    """Shade the fragments: every one (``shading="sample"``), or once per pixel run (multisampling).

    With multisampling the rasterizer has put the shading position's
    barycentrics in every fragment of a run; the first one is shaded and its
    color goes to all the run's samples.
    """
    shader = fragment_shader or default_fragment_shader(prims.layout)
    n = len(frags)
    if n == 0:
        return ShadedFragments(np.empty((0, 4), np.float32), np.zeros(0, dtype=bool), 0)
    fx, fy = window_coordinates(frags, pattern, height, shading)
    if shading == "sample":
        shaded = _shade(shader, fragment_shader is not None, frags, prims, uniforms, fx, fy)
        return ShadedFragments(shaded, np.isnan(shaded[:, 3]), n)
    heads = pixel_runs(frags)
    sub = Fragments(*(a[heads] for a in (frags.x, frags.y, frags.sample, frags.depth, frags.bary,
                                          frags.triangle, frags.primitive_id)))
    shaded = _shade(shader, fragment_shader is not None, sub, prims, uniforms, fx[heads], fy[heads])
    color = np.repeat(shaded, np.diff(np.append(heads, n)), axis=0)
    return ShadedFragments(color, np.isnan(color[:, 3]), len(heads))


def _shade(shader, probe: bool, frags: Fragments, prims: Primitives, uniforms, fx, fy) -> np.ndarray:
    color = np.empty((len(frags), 4), dtype=np.float32)
    kernel = _shader.fragment_kernel(shader, prims.layout)
    explain = (lambda: _probe(shader, frags, prims, uniforms, fx, fy)) if probe else None
    _shader.run_compiled("fragment", shader, kernel, explain, frags.triangle, np.ascontiguousarray(fx),
                         np.ascontiguousarray(fy), frags.depth, np.ascontiguousarray(frags.bary), prims.inv_w,
                         prims.varyings, prims.front_facing, prims.primitive_id, _gradients(shader, prims),
                         uniforms, color)
    return color


def _gradients(shader, prims: Primitives) -> np.ndarray:
    """Barycentric gradients when the shader asks for derivatives (else an empty placeholder)."""
    if _shader.wants_derivatives(shader):
        return barycentric_gradients(prims)
    return np.zeros((0, 2, 3))


def _probe(shader, frags, prims, uniforms, fx, fy) -> None:
    """Run the shader on the first fragment in Python: when numba fails, its error is clearer."""
    t = int(frags.triangle[0])
    values = prims.layout.unpack(prims.varyings[t, 2])
    import collections
    V = collections.namedtuple("Varyings", list(values) or ["none"])
    args = [float(v) if np.ndim(v) == 0 else tuple(float(c) for c in v) for v in values.values()] or [0.0]
    frag = FragInfo(float(fx[0]), float(fy[0]), float(frags.depth[0]), bool(prims.front_facing[t]),
                    int(prims.primitive_id[t]))
    _shader.probe_fragment_shader(shader, V(*args), uniforms, frag)


def visible_loop_args(prims: Primitives, visibility, fb, shader: Callable, uniforms, shading: str = "sample") -> tuple:
    """The arguments of the generated ``visible_loop`` after its rows (row_lo, row_hi).

    ``shading`` as :func:`run_fragment_stage`'s: per "sample", or once per pixel
    and triangle at the pixel "center" or "centroid" (multisampling).
    """
    from .raster import SHADING_POSITIONS
    from .visibility import TILE_H, TILE_W
    if shading not in SHADING_POSITIONS:
        raise ValueError(f"shading must be one of {SHADING_POSITIONS}, got {shading!r}")
    pattern = fb.pattern
    return (visibility.vis, visibility.touched, TILE_W, TILE_H, prims.window, visibility.edges, visibility.bias,
            visibility.plane, pattern.offsets, pattern.positions, SHADING_POSITIONS.index(shading), prims.inv_w,
            prims.varyings, prims.front_facing, prims.primitive_id, _gradients(shader, prims), uniforms,
            fb.samples_color)


def shade_visible(prims: Primitives, visibility, fb, fragment_shader: Optional[Callable], uniforms,
                  shading: str = "sample") -> None:
    """The fast path's shading: run the shader on the samples a :class:`~softpipe.visibility.Visibility` kept."""
    from ._parallel import in_bands
    shader = fragment_shader or default_fragment_shader(prims.layout)
    kernel = _shader.visible_kernel(shader, prims.layout)
    args = visible_loop_args(prims, visibility, fb, shader, uniforms, shading)
    # compile (or load) once, in this thread, where errors are reported clearly
    _shader.run_compiled("fragment", shader, kernel, None, 0, 0, *args)
    _shader.run_compiled("fragment", shader, lambda *a: in_bands(kernel, fb.height, *a), None, *args)
