"""Stage 4: the fragment stage — interpolate the varyings, run the fragment shader.

For each fragment the varyings are interpolated from the triangle's corners
with their qualifiers (:func:`softpipe.language.kernels.fragment_kernel` writes the loop):

* ``smooth`` (the default): perspective-correct,
  ``v = Σ (b_k / w_k) v_k / Σ (b_k / w_k)``;
* ``noperspective``: linear in window space, ``v = Σ b_k v_k``;
* ``flat``: the provoking vertex's value (the triangle's last vertex).

then the fragment shader turns them into an RGBA color (or discards the
fragment); into a framebuffer of several color attachments, into one value per
attachment (multiple render targets, :attr:`ShadedFragments.outputs`). With no fragment shader, the color is the varying ``color`` (RGB,
alpha 1, or RGBA). Everything it needs arrives in its input: the
:class:`~softpipe.pipeline.raster.Fragments` (barycentrics, depth, window position, and
the triangle setup for derivatives) and the :class:`~softpipe.pipeline.assembly.Primitives`
(the corners' varyings and 1/w). Output: :class:`ShadedFragments`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from softpipe.language import kernels
from softpipe.language.contract import wants_derivatives
from softpipe.pipeline.assembly import Primitives
from softpipe.pipeline.raster import Fragments

__all__ = ["ShadedFragments", "run_fragment_stage", "default_fragment_shader", "color_rgb", "color_rgba",
           "derivative_gradients"]


@dataclass
class ShadedFragments:
    """The fragment shader's outputs, one row per fragment of the :class:`Fragments`.

    Attributes
    ----------
    color : float32 [F, 4]
        RGBA, linear, unclamped.
    discarded : bool [F]
        True where the shader returned DISCARD.
    outputs : tuple of arrays
        Into a framebuffer of several attachments, the values for locations 1, 2, … in order:
        float32 [F, 4] (``rgba8``, ``rgba32f``), float32 [F] (``r32f``) or int32 [F] (``r32i``)
        (location 0's is ``color``). Empty for one attachment.
    """

    color: np.ndarray
    discarded: np.ndarray
    invocations: int = -1
    outputs: Tuple[np.ndarray, ...] = ()

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


def run_fragment_stage(frags: Fragments, prims: Primitives, fragment_shader: Optional[Callable], uniforms,
                       shading: str = "sample", attachments: Sequence[Tuple[str, str]] = ()) -> ShadedFragments:
    """Shade the fragments: every one (``shading="sample"``), or once per pixel run (multisampling).

    With multisampling the rasterizer has put the shading position's
    barycentrics in every fragment of a run; the first one is shaded and its
    color goes to all the run's samples. ``attachments`` (a framebuffer's (name, format), …):
    with more than one, the shader returns a value per attachment (:attr:`ShadedFragments.outputs`).
    """
    shader = fragment_shader or default_fragment_shader(prims.layout)
    attachments = tuple(attachments) if len(attachments) > 1 else ()
    n = len(frags)
    if n == 0:
        return ShadedFragments(np.empty((0, 4), np.float32), np.zeros(0, dtype=bool), 0, _more_outputs(attachments, 0))
    if shading == "sample":
        shaded, more = _shade(shader, frags, prims, uniforms, attachments)
        return ShadedFragments(shaded, np.isnan(shaded[:, 3]), n, more)
    heads = pixel_runs(frags)
    shaded, more = _shade(shader, frags.take(heads), prims, uniforms, attachments)
    repeats = np.diff(np.append(heads, n))
    color = np.repeat(shaded, repeats, axis=0)
    more = tuple(np.repeat(a, repeats, axis=0) for a in more)
    return ShadedFragments(color, np.isnan(color[:, 3]), len(heads), more)


def _more_outputs(attachments: Sequence[Tuple[str, str]], n: int) -> Tuple[np.ndarray, ...]:
    """Arrays for the values of locations 1, 2, … of ``n`` fragments (each attachment's format's type)."""
    shapes = {"rgba8": ((n, 4), np.float32), "rgba32f": ((n, 4), np.float32), "r32f": ((n,), np.float32),
              "r32i": ((n,), np.int32)}
    return tuple(np.empty(*shapes[fmt]) for _, fmt in attachments[1:])


def derivative_gradients(shader: Callable, setup) -> np.ndarray:
    """The barycentric gradients a shader's derivatives need ([T, 2, 3]), or an empty placeholder."""
    if wants_derivatives(shader):
        return setup.barycentric_gradients()
    return np.zeros((0, 2, 3))


def _shade(shader, frags: Fragments, prims: Primitives, uniforms, attachments=()) -> Tuple[np.ndarray, tuple]:
    color = np.empty((len(frags), 4), dtype=np.float32)
    kernel = kernels.fragment_kernel(shader, prims.layout, attachments)
    more = _more_outputs(attachments, len(frags))
    args: tuple = (frags.triangle, frags.frag_x, frags.frag_y, frags.depth, frags.bary, prims.inv_w, prims.varyings,
                   prims.front_facing, prims.primitive_id, derivative_gradients(shader, frags.setup), uniforms, color)
    if attachments:
        args = args + (more,)
    kernels.run_compiled("fragment", shader, kernel, *args,
                         site=kernels.fragment_site(shader, kernel, args, frags.x, frags.y, frags.sample))
    return color, more
