"""Transparency without sorting objects: depth peeling and weighted blended OIT, over a Scene.

:func:`~softpipe.scenes.drawing.render_scene` draws a scene's transparent objects (a material
``opacity`` below 1) sorted back to front, one order per object, which is wrong wherever they
interpenetrate. The two methods here need no order; both draw the opaque objects first, as
``render_scene`` does (:func:`opaque_pass`), then the transparent ones with softpipe's own draws:

- :func:`depth_peel`, **depth peeling** (Everitt 2001, "Interactive order-independent
  transparency"): pass i draws the transparent geometry into a fresh layer whose depth buffer
  starts as the opaque one (test "less"), and its fragment shader discards every fragment not
  behind layer i − 1 at its pixel (float32(z) ≤ the previous layer's depth: the uniform
  ``peel_depth``, the previous layer's depth buffer, read by ``gl_FragCoord``). The nearest
  fragment that is left wins the depth test: layer i is the i-th surface from the eye. Each
  layer is composited *under* the ones before it (front to back), then the whole over the
  opaque picture. With as many layers as the deepest pixel has surfaces it is exact: the
  per-sample sorted composite (:func:`softpipe.testing.sorted_composite`). Fragments at exactly
  the depth of the layer before are peeled away with it (coplanar surfaces show once).
- :func:`weighted_oit`, **weighted blended order-independent transparency** (McGuire and
  Bavoil 2013, JCGT 2(2)): one pass adds w·(α·c, α) of every fragment into a float
  framebuffer (blend ("one", "one")), another multiplies a second one by (1 − α) (blend
  ("zero", "one_minus_src_color")), and a resolve divides: FORMULAS §29, with the weight
  :func:`oit_weight` (the paper's eq. 10). Approximate wherever layers overlap (exact for one).

Both wrap the objects' own fragment shaders (a peeling test before, a weight after), so every
program draws transparently as it draws opaque. One sample a pixel for depth peeling (its
shader reads the previous depth by pixel); weighted OIT takes any pattern.
:func:`transparent_traces` draws the transparent objects on the reference path for
:func:`softpipe.testing.sorted_composite`, the exact composite both are measured against
(docs/transparency.md).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, List, Optional, Tuple

import numba
import numpy as np

from softpipe.language.contract import DISCARD
from softpipe.language.kernels import jit_function
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.sampling import pattern_named
from softpipe.programs import Program, get_program
from softpipe.scenes.drawing import draw_object, is_transparent, scene_lighting
from softpipe.scenes.scene import Scene, SceneObject, program_for

__all__ = ["OpaquePass", "opaque_pass", "depth_peel", "weighted_oit", "oit_weight", "oit_resolve",
           "transparent_traces", "MAX_LAYERS", "OIT_EPSILON"]

#: The most layers :func:`depth_peel` peels (each is one draw of every transparent object).
MAX_LAYERS = 64
#: ε of the weighted OIT resolve (FORMULAS §29): the accumulated Σ α·w is divided by max(Σ α·w, ε).
OIT_EPSILON = 1e-5


@dataclass
class OpaquePass:
    """A scene's opaque objects drawn, and what its transparent ones are drawn with after them.

    Attributes
    ----------
    framebuffer : Framebuffer
        The scene's size and pattern, cleared to its background, the opaque objects drawn in
        the scene's order (:func:`~softpipe.scenes.drawing.render_scene`'s first part).
    transparent : list of SceneObject
        The transparent objects (:func:`~softpipe.scenes.drawing.is_transparent`), in the scene's order.
    lighting
        The ``lighting`` uniform of every draw (:func:`~softpipe.scenes.drawing.scene_lighting`,
        shadow maps from all the objects).
    camera : Camera
    """

    framebuffer: Framebuffer
    transparent: List[SceneObject]
    lighting: Any
    camera: Camera


def opaque_pass(scene: Scene, camera: Optional[Camera] = None) -> OpaquePass:
    """Draw ``scene``'s opaque objects (and the ground) as :func:`~softpipe.scenes.drawing.render_scene` does;
    keep the transparent ones for later. The wireframe is not drawn."""
    camera = camera or scene.view_camera()
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples), srgb=scene.srgb)
    fb.clear(scene.background)
    objects = scene.drawn_objects(camera)
    lighting = scene_lighting(scene, camera, objects)
    for obj in objects:
        if not is_transparent(obj):
            draw_object(fb, scene, obj, camera, lighting)
    return OpaquePass(fb, [o for o in objects if is_transparent(o)], lighting, camera)


def _layer(base: Framebuffer, clear: Tuple[float, float, float, float]) -> Framebuffer:
    """A framebuffer like ``base``, its color cleared to ``clear``, its depth a copy of ``base``'s (the opaque depth)."""
    fb = Framebuffer(base.width, base.height, base.pattern)
    fb.clear(clear)
    fb.samples_depth[...] = base.samples_depth
    return fb


def _put(fb: Framebuffer, color: np.ndarray) -> Framebuffer:
    """Store ``color`` [S, H, W, 4] as ``fb``'s, counted as a write (a trace of an earlier draw then knows)."""
    with fb.lock:
        fb.count_write()
        fb.samples_color[...] = color
    return fb


# ------------------------------------------------------------------------------- depth peeling

def _check_layers(layers) -> int:
    if isinstance(layers, bool) or not isinstance(layers, (int, np.integer)) or not 1 <= layers <= MAX_LAYERS:
        raise ValueError(f"layers must be a whole number from 1 to {MAX_LAYERS} (MAX_LAYERS), got {layers!r}")
    return int(layers)


@functools.lru_cache(maxsize=None)
def _peeled(program: Program) -> Program:
    """``program`` with a peeling test before its fragment shader: a fragment not behind the previous
    layer at its pixel (float32(z) ≤ ``uniforms.peel_depth[row, column]``) is discarded."""
    inner = jit_function(program.fragment)

    def peeled_fragment(varyings, uniforms, frag):
        previous = uniforms.peel_depth
        row = previous.shape[0] - 1 - int(frag.y)       # gl_FragCoord is y up; the depth array's row 0 is the top
        # compared as the depth buffer stores depth (float32): the previous layer's own fragment is peeled
        if np.float32(frag.z) <= previous[row, int(frag.x)]:
            return DISCARD
        return inner(varyings, uniforms, frag)

    return Program(f"{program.name} (peeled)", program.vertex, peeled_fragment, program.description,
                   program.interpolation, program.faceted)


def depth_peel(scene: Scene, *, layers: int = 4, camera: Optional[Camera] = None,
               layer_buffers: Optional[list] = None) -> Framebuffer:
    """``scene`` with its transparent objects drawn by depth peeling, ``layers`` layers (see the module).

    Parameters
    ----------
    scene : Scene
        Drawn at one sample a pixel (``samples="1"``).
    layers : int
        How many layers to peel, 1 to :data:`MAX_LAYERS`; a sample with more transparent
        surfaces in front of the opaque one loses its farthest. Peeling stops early once a
        layer is empty.
    camera : Camera, optional
        Replaces the scene's.
    layer_buffers : list, optional
        Receives each layer peeled: a Framebuffer with the layer's straight (not
        premultiplied) color, alpha 0 where it has no fragment, and its depth.

    Returns
    -------
    Framebuffer
        The opaque picture with every layer composited over it, front to back with the
        "under" operator in float64: C ← C + (1 − A)·α·c, A ← A + (1 − A)·α, then
        C + (1 − A)·background.

    Raises
    ------
    ValueError
        ``layers`` out of range or not a whole number; a scene of more than one sample a pixel.
    """
    layers = _check_layers(layers)
    count = len(pattern_named(scene.samples))
    if count != 1:
        raise ValueError(f"depth_peel draws one sample a pixel (its shader reads the previous layer's depth by "
                         f"pixel); the scene's samples {scene.samples!r} has {count}: give the scene "
                         "samples=\"1\"")
    base = opaque_pass(scene, camera)
    fb = base.framebuffer
    previous = np.full((fb.height, fb.width), -np.inf)          # nothing is in front of layer 0
    under = np.zeros((fb.height, fb.width, 4))                  # premultiplied color and alpha so far
    for _ in range(layers):
        layer = _layer(fb, (0.0, 0.0, 0.0, 0.0))
        for obj in base.transparent:
            draw_object(layer, scene, obj, base.camera, base.lighting,
                        program=_peeled(get_program(program_for(obj, scene.program))),
                        uniforms={"peel_depth": previous}, depth_test="less", depth_write=True, blend=None)
        color = layer.color.astype(np.float64)
        depth = layer.depth.astype(np.float64)
        if not (depth != fb.depth).any():
            break                                               # an empty layer: every later one is empty too
        if layer_buffers is not None:
            layer_buffers.append(layer)
        alpha = color[..., 3:4]
        under[..., :3] += (1.0 - under[..., 3:4]) * alpha * color[..., :3]
        under[..., 3:4] += (1.0 - under[..., 3:4]) * alpha
        previous = depth
    background = fb.samples_color[0].astype(np.float64)
    out = under + (1.0 - under[..., 3:4]) * background
    return _put(fb, out[None].astype(np.float32))


# ------------------------------------------------------------------------------- weighted blended OIT

@numba.njit(cache=True)
def oit_weight(z, alpha):
    """The weight of a fragment in weighted blended OIT, FORMULAS §29 (McGuire and Bavoil 2013, eq. 10):
    w(z, α) = α · max(10⁻², 3·10³ · (1 − z)³), z the window depth (``gl_FragCoord.z``, 0 at the near plane)."""
    d = 1.0 - z
    return alpha * max(1e-2, 3e3 * d * d * d)


@functools.lru_cache(maxsize=None)
def _weighted(program: Program) -> Program:
    """``program`` whose color (c, α) comes out as w·(α·c, α), w = :func:`oit_weight` (the accumulation pass)."""
    inner = jit_function(program.fragment)

    def weighted_fragment(varyings, uniforms, frag):
        c = inner(varyings, uniforms, frag)
        a = c[3]                                    # NaN when discarded: the product stays NaN, still discarded
        w = oit_weight(frag.z, a)
        return (c[0] * a * w, c[1] * a * w, c[2] * a * w, a * w)

    return Program(f"{program.name} (weighted)", program.vertex, weighted_fragment, program.description,
                   program.interpolation, program.faceted)


@functools.lru_cache(maxsize=None)
def _revealage(program: Program) -> Program:
    """``program`` whose color (c, α) comes out as (α, α, α, α) (the revealage pass)."""
    inner = jit_function(program.fragment)

    def revealage_fragment(varyings, uniforms, frag):
        a = inner(varyings, uniforms, frag)[3]
        return (a, a, a, a)

    return Program(f"{program.name} (revealage)", program.vertex, revealage_fragment, program.description,
                   program.interpolation, program.faceted)


def oit_resolve(accum: np.ndarray, revealage: np.ndarray, background: np.ndarray) -> np.ndarray:
    """The weighted OIT resolve, FORMULAS §29, per sample, in float64.

    ``accum`` [..., 4] holds (Σ w·α·c, Σ w·α), ``revealage`` [...] Π(1 − α), ``background``
    [..., 4] the opaque color. Returns [..., 4]: RGB = accum.rgb / max(accum.a, ε)·(1 − R) +
    background.rgb·R and A = (1 − R) + background.a·R, ε = :data:`OIT_EPSILON`.
    """
    accum = np.asarray(accum, np.float64)
    R = np.asarray(revealage, np.float64)[..., None]
    background = np.asarray(background, np.float64)
    average = accum[..., :3] / np.maximum(accum[..., 3:4], OIT_EPSILON)
    return np.concatenate([average * (1.0 - R) + background[..., :3] * R,
                           (1.0 - R) + background[..., 3:4] * R], axis=-1)


def weighted_oit(scene: Scene, *, camera: Optional[Camera] = None,
                 buffers: Optional[dict] = None) -> Framebuffer:
    """``scene`` with its transparent objects drawn by weighted blended OIT (see the module, FORMULAS §29).

    Two draws of each transparent object, both tested "less" against the opaque depth and
    writing none: into ``accum`` (cleared to 0) with blend ("one", "one"), each fragment's
    w·(α·c, α); into ``revealage`` (cleared to 1) with blend ("zero", "one_minus_src_color"),
    each fragment's α, leaving Π(1 − α). Then :func:`oit_resolve` over the opaque picture.
    ``buffers``, if given, receives the two framebuffers (``"accum"``, ``"revealage"``).
    Any sample pattern; the result is per sample.
    """
    base = opaque_pass(scene, camera)
    fb = base.framebuffer
    accum, reveal = _layer(fb, (0.0, 0.0, 0.0, 0.0)), _layer(fb, (1.0, 1.0, 1.0, 1.0))
    for obj in base.transparent:
        program = get_program(program_for(obj, scene.program))
        draw_object(accum, scene, obj, base.camera, base.lighting, program=_weighted(program), blend=("one", "one"),
                    depth_test="less", depth_write=False)
        draw_object(reveal, scene, obj, base.camera, base.lighting, program=_revealage(program),
                    blend=("zero", "one_minus_src_color"), depth_test="less", depth_write=False)
    if buffers is not None:
        buffers.update(accum=accum, revealage=reveal)
    out = oit_resolve(accum.samples_color, reveal.samples_color[..., 0], fb.samples_color)
    return _put(fb, out.astype(np.float32))


# ------------------------------------------------------------------------------- the exact reference's input

def transparent_traces(scene: Scene, camera: Optional[Camera] = None) -> Tuple[OpaquePass, list]:
    """The opaque pass, and a reference-path :class:`~softpipe.pipeline.trace.Trace` of every draw of the
    transparent objects (scene order): every fragment they make, none lost to a depth test (drawn with
    ``depth_test=None`` into a scratch copy), for :func:`softpipe.testing.sorted_composite`::

        base, traces = transparent_traces(scene)
        exact = softpipe.testing.sorted_composite(traces, base.framebuffer)
    """
    base = opaque_pass(scene, camera)
    scratch = _layer(base.framebuffer, (0.0, 0.0, 0.0, 0.0))
    drawn: list = []
    for obj in base.transparent:
        draw_object(scratch, scene, obj, base.camera, base.lighting, trace=True, results=drawn, path="reference",
                    depth_test=None, blend=("zero", "one"))
    return base, [r.trace for r in drawn]
