"""Transparency three ways (issue #30): the scene renderer's sorting, depth peeling, weighted
blended OIT (softpipe.scenes.transparency), and the exact composite they are measured against
(softpipe.testing.sorted_composite).

The scenes' transparent objects are emissive squares (ke = the color, ka = kd = ks = 0, no
ambient): phong shades each fragment exactly its ke, so every expected color is the "over"
of flat colors, worked out here.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe
from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_x, rotate_y, translate
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_order, eye_depth, render_scene
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.scenes.transparency import (
    MAX_LAYERS,
    OIT_EPSILON,
    depth_peel,
    oit_resolve,
    transparent_traces,
    weighted_oit,
)
from softpipe.testing import sorted_composite

BACKGROUND = (0.1, 0.2, 0.3, 1.0)
CAMERA = Camera(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fovy=40.0)
RED, GREEN, BLUE = (0.9, 0.1, 0.1), (0.1, 0.8, 0.2), (0.2, 0.3, 0.9)


def glow(color, opacity=1.0):
    return Material(ke=color, ka=0.0, kd=0.0, ks=0.0, opacity=opacity)


def square(name, color, opacity, model, side=1.2):
    """A square facing +z (the xz plane turned up), drawn from both sides."""
    return SceneObject(name, shapes.plane(side, material=glow(color, opacity)), model @ rotate_x(90.0), cull="none")


def scene_of(objects, size=(40, 32), **kw):
    return Scene(list(objects), camera=CAMERA, lights=(Light.directional((0.0, 0.0, -1.0)),), ambient=(0.0, 0.0, 0.0),
                 width=size[0], height=size[1], background=BACKGROUND, **kw)


def over(color, alpha, below):
    return alpha * np.asarray(color, np.float64) + (1.0 - alpha) * np.asarray(below, np.float64)


# ------------------------------------------------------------------ 1. the scene renderer sorts

def test_render_scene_draws_the_transparent_objects_after_the_opaque_ones_back_to_front():
    """The near red square (opacity 0.5) is listed first, the far green one (0.75) second, an
    opaque blue wall last: the wall is drawn first, then green, then red, blended "over". Where
    all three overlap the pixel is red over (green over blue), computed here in float64; the
    framebuffer rounds to float32 after each blend, so within 1e-6 (and the same 8 bits).
    On main the red square was drawn opaque and hid everything behind it."""
    near = square("near red", RED, 0.5, translate(-0.2, 0.0, 0.5))
    far = square("far green", GREEN, 0.75, translate(0.2, 0.0, -0.5))
    wall = SceneObject("wall", shapes.plane(6.0, material=glow(BLUE)), translate(0.0, 0.0, -1.5) @ rotate_x(90.0))
    scene = scene_of([near, far, wall])
    assert [o.name for o in draw_order(scene.objects, CAMERA)] == ["wall", "far green", "near red"]
    fb = render_scene(scene)
    centre = fb.color[16, 20, :3]
    expected = over(RED, 0.5, over(GREEN, 0.75, BLUE))
    np.testing.assert_allclose(centre, expected, rtol=0, atol=1e-6)
    # alpha by A ← α + (1 − α)·A (separate alpha factors): 1 over the opaque wall, 0.5 over green over a clear framebuffer
    assert fb.color[16, 20, 3] == 1.0
    assert tuple(fb.to_uint8(alpha=False)[16, 20]) == tuple(int(v) for v in np.round(expected * 255))
    # the wall alone at the corner, and only the green square's edge strip right of the red one
    np.testing.assert_allclose(fb.color[1, 1, :3], BLUE, rtol=0, atol=1e-7)
    assert not np.allclose(fb.color[16, 20, :3], RED)


def test_eye_depth_is_the_bounding_box_centre_in_eye_space():
    """−z in eye space of the world bounding box's centre: a unit plane turned up and moved to
    (1, 2, −3) has its box centre there; the camera on +z at 4 looking at the origin sees it 7 away.
    Equal depths keep the scene's order."""
    obj = square("s", RED, 0.5, translate(1.0, 2.0, -3.0))
    assert eye_depth(obj, CAMERA) == pytest.approx(7.0, abs=1e-12)
    a, b = square("a", RED, 0.5, translate(-1.0, 0.0, 0.0)), square("b", GREEN, 0.5, translate(1.0, 0.0, 0.0))
    assert [o.name for o in draw_order([a, b], CAMERA)] == ["a", "b"]
    assert [o.name for o in draw_order([b, a], CAMERA)] == ["b", "a"]


def test_a_scene_without_transparent_objects_draws_as_before():
    """Only opaque objects: the scene's order, no blending — the same bytes as drawing them one by one."""
    from softpipe.scenes.drawing import draw_mesh
    a = SceneObject("a", shapes.plane(1.0, material=glow(RED)), translate(0.0, 0.0, 0.5) @ rotate_x(90.0))
    b = SceneObject("b", shapes.plane(2.0, material=glow(GREEN)), rotate_x(90.0))
    scene = scene_of([a, b])
    fb = softpipe.Framebuffer(40, 32)
    fb.clear(BACKGROUND)
    lighting = scene.lighting_for(CAMERA).uniform(CAMERA.view)
    for o in (a, b):
        draw_mesh(fb, o.mesh, CAMERA, "phong", model=o.model, lighting=lighting, cull="back")
    assert np.array_equal(render_scene(scene).samples_color, fb.samples_color)


# ------------------------------------------------------------------ 2. the exact composite

def _flat(fb, x0, x1, depth, color, order_after=()):
    """A reference-path trace of one rectangle over window columns x0..x1 (all rows) at ``depth``."""
    corners = [(x0, 0), (x1, 0), (x1, 2), (x0, 0), (x1, 2), (x0, 2)]
    pos = window_to_clip([(x, y, 2 * depth - 1) for x, y in corners], fb.width, fb.height)
    return softpipe.draw(fb, pos, varyings={"color": np.tile(color, (6, 1))}, trace=True, path="reference",
                         depth_test=None, blend=("zero", "one"))


def test_sorted_composite_of_two_fragments_at_one_pixel():
    """Two fragments at pixel (0, 0), the nearer drawn first: the farther goes over the background
    first, the nearer over that (straight alpha); alpha by A ← α + (1 − α)·A. A fragment behind
    the opaque depth (0.5) is left out; at equal depths the one drawn later is in front."""
    bg = softpipe.Framebuffer(2, 2).clear((0.25, 0.5, 0.75, 1.0), depth=0.5)
    scratch = softpipe.Framebuffer(2, 2).clear((0.25, 0.5, 0.75, 1.0), depth=0.5)
    near = _flat(scratch, 0, 1, 0.125, (1.0, 0.0, 0.0, 0.25))
    far = _flat(scratch, 0, 1, 0.375, (0.0, 1.0, 0.0, 0.5))
    hidden = _flat(scratch, 0, 2, 0.75, (0.0, 0.0, 1.0, 1.0))        # behind the opaque surface
    out = sorted_composite([near, far, hidden], bg)
    rgb = over((1.0, 0.0, 0.0), 0.25, over((0.0, 1.0, 0.0), 0.5, (0.25, 0.5, 0.75)))
    alpha = 0.25 + 0.75 * (0.5 + 0.5 * 1.0)
    np.testing.assert_allclose(out.samples_color[0, 1, 0], [*rgb, alpha], rtol=0, atol=1e-7)
    np.testing.assert_array_equal(out.samples_color[0, 1, 1], bg.samples_color[0, 1, 1])   # only `hidden` there
    np.testing.assert_array_equal(out.samples_depth, bg.samples_depth)
    # a tie: the one drawn later goes on top, whichever order the traces come in
    first = _flat(scratch, 0, 1, 0.25, (1.0, 0.0, 0.0, 0.5))
    second = _flat(scratch, 0, 1, 0.25, (0.0, 0.0, 1.0, 0.5))
    tied = sorted_composite([first, second], bg).samples_color[0, 1, 0, :3]
    np.testing.assert_allclose(tied, over((0.0, 0.0, 1.0), 0.5, over((1.0, 0.0, 0.0), 0.5, (0.25, 0.5, 0.75))),
                               rtol=0, atol=1e-7)


def test_sorted_composite_refuses_what_it_cannot_sort():
    bg = softpipe.Framebuffer(2, 2)
    fast = softpipe.draw(softpipe.Framebuffer(2, 2), window_to_clip([(0, 0, 0), (2, 0, 0), (0, 2, 0)], 2, 2),
                         varyings={"color": np.ones((3, 4))}, trace=True, path="fast")
    with pytest.raises(ValueError, match=r"^trace 0 was drawn on the 'fast' path, which keeps only the visible "
                                         r"fragments; draw with path=\"reference\"$"):
        sorted_composite([fast], bg)
    with pytest.raises(ValueError, match=r"^trace 0 is of a 2×2 framebuffer with 1 sample\(s\); the background "
                                         r"is 3×2 with 1$"):
        sorted_composite([_flat(softpipe.Framebuffer(2, 2), 0, 1, 0.5, (1, 1, 1, 1))], softpipe.Framebuffer(3, 2))


# ------------------------------------------------------------------ 3. depth peeling

def crossing_scene(size=(48, 40), **kw):
    """Three squares crossing one another (so no order of objects is right everywhere) over an opaque wall."""
    wall = SceneObject("wall", shapes.plane(6.0, material=glow(BLUE)), translate(0.0, 0.0, -1.5) @ rotate_x(90.0))
    return scene_of([wall,
                     square("red", RED, 0.5, translate(-0.2, 0.0, 0.0) @ rotate_y(-40.0)),
                     square("green", GREEN, 0.6, translate(0.0, 0.1, 0.0) @ rotate_x(-30.0)),
                     square("white", (0.9, 0.9, 0.9), 0.4, translate(0.2, 0.0, 0.0) @ rotate_y(40.0))], size, **kw)


@pytest.fixture(scope="module")
def crossing():
    scene = crossing_scene()
    base, traces = transparent_traces(scene)
    return scene, base, traces, sorted_composite(traces, base.framebuffer)


def tied_pixels(base, traces):
    """Pixels where two transparent fragments in front of the opaque surface have the same float32 depth."""
    h, w = base.framebuffer.height, base.framebuffer.width
    x, y, z = (np.concatenate([getattr(t.fragments, n) for t in traces]) for n in ("x", "y", "depth"))
    z = z.astype(np.float32)
    keep = z < base.framebuffer.depth[y, x]
    key = np.stack([y[keep], x[keep], z[keep].view(np.int32)], axis=1)
    values, counts = np.unique(key, axis=0, return_counts=True)
    out = np.zeros((h, w), bool)
    out[values[counts > 1, 0], values[counts > 1, 1]] = True
    return out


def test_depth_peeling_equals_the_exact_composite(crossing):
    """With as many layers as surfaces (3) depth peeling is the sorted composite: the same 8-bit
    pixels, and float colors within 1e-6 (it composites front to back, the reference back to
    front), at every pixel but those where two squares have the same float32 depth (where they
    cross: peeling removes both with the layer before, the reference keeps both)."""
    scene, base, traces, exact = crossing
    peeled = depth_peel(scene, layers=3)
    tied = tied_pixels(base, traces)
    assert tied.sum() < 5
    a, b = peeled.to_uint8(alpha=False), exact.to_uint8(alpha=False)
    assert np.array_equal(a[~tied], b[~tied])
    np.testing.assert_allclose(peeled.color[..., :3][~tied], exact.color[..., :3][~tied], rtol=0, atol=1e-6)
    # more layers change nothing; sorting by object does not get there
    assert np.array_equal(depth_peel(scene, layers=MAX_LAYERS).samples_color, peeled.samples_color)
    sorted_ = render_scene(scene).to_uint8(alpha=False)
    assert (np.abs(sorted_.astype(int) - b).max(axis=-1) > 1).sum() > 20


def test_depth_peeling_with_one_layer_keeps_the_nearest_surface(crossing):
    """One layer: each pixel shows its nearest transparent fragment over the opaque picture."""
    scene, base, traces, _ = crossing
    layers = []
    one = depth_peel(scene, layers=1, layer_buffers=layers)
    assert len(layers) == 1
    nearest = sorted_composite(traces, layers[0])      # the layer's depth is the nearest surface's: none is in front
    np.testing.assert_array_equal(nearest.samples_color, layers[0].samples_color)
    alpha = layers[0].color[..., 3:4].astype(np.float64)
    expected = alpha * layers[0].color[..., :3] + (1 - alpha) * base.framebuffer.color[..., :3]
    np.testing.assert_allclose(one.color[..., :3], expected, rtol=0, atol=1e-6)


@pytest.mark.parametrize("layers", [0, -1, MAX_LAYERS + 1, 2.5, True, "3"])
def test_depth_peel_says_which_layers_it_takes(layers):
    with pytest.raises(ValueError, match=rf"^layers must be a whole number from 1 to {MAX_LAYERS} \(MAX_LAYERS\), "
                                         rf"got {layers!r}$"):
        depth_peel(crossing_scene(), layers=layers)


def test_depth_peel_takes_one_sample_a_pixel():
    with pytest.raises(ValueError, match=r"^depth_peel draws one sample a pixel \(its shader reads the previous "
                                         r"layer's depth by pixel\); the scene's samples 'rgss4' has 4: give the "
                                         r"scene samples=\"1\"$"):
        depth_peel(crossing_scene(samples="rgss4"))


# ------------------------------------------------------------------ 4. weighted blended OIT

def by_hand(fragments, background):
    """FORMULAS §29 at one pixel: fragments (color, α, window depth); the weight of eq. 10 written out."""
    acc, acc_a, reveal = np.zeros(3), 0.0, 1.0
    for color, a, z in fragments:
        w = a * max(0.01, 3000.0 * (1.0 - z) ** 3)
        acc += np.asarray(color) * a * w
        acc_a += a * w
        reveal *= 1.0 - a
    return acc / max(acc_a, 1e-5) * (1.0 - reveal) + np.asarray(background[:3]) * reveal


def test_the_resolve_at_one_pixel():
    frags = [((0.9, 0.1, 0.1), 0.5, 0.3), ((0.1, 0.8, 0.2), 0.75, 0.9)]
    accum = np.zeros(4)
    for c, a, z in frags:
        w = a * max(0.01, 3000.0 * (1.0 - z) ** 3)
        accum += [c[0] * a * w, c[1] * a * w, c[2] * a * w, a * w]
    out = oit_resolve(accum, (1 - 0.5) * (1 - 0.75), BACKGROUND)
    np.testing.assert_allclose(out[:3], by_hand(frags, BACKGROUND), rtol=1e-14)
    assert out[3] == pytest.approx(1.0)
    # nothing transparent: the background as it is (0/ε · 0 + bg · 1)
    np.testing.assert_array_equal(oit_resolve(np.zeros(4), 1.0, BACKGROUND), BACKGROUND)
    assert OIT_EPSILON == 1e-5


def test_weighted_oit_at_a_pixel_of_the_scene(crossing):
    """At each pixel, weighted_oit's color is FORMULAS §29 of that pixel's fragments (their colors,
    opacities and window depths read from the reference path's traces) over the opaque color:
    within 1e-5 (the two buffers add and multiply in float32). It is not the exact composite
    where squares overlap, and is where there is one square or none."""
    scene, base, traces, exact = crossing
    buffers = {}
    oit = weighted_oit(scene, buffers=buffers)
    bg = base.framebuffer.color
    x, y, z = (np.concatenate([getattr(t.fragments, n) for t in traces]) for n in ("x", "y", "depth"))
    color = np.concatenate([t.shaded.color for t in traces]).astype(np.float64)
    keep = z.astype(np.float32) < base.framebuffer.depth[y, x]
    counts = np.zeros(bg.shape[:2], int)
    np.add.at(counts, (y[keep], x[keep]), 1)
    for row, col in [tuple(np.argwhere(counts == n)[len(np.argwhere(counts == n)) // 2]) for n in (1, 2, 3)]:
        here = keep & (x == col) & (y == row)
        frags = [(color[k, :3], color[k, 3], z[k]) for k in np.flatnonzero(here)]
        np.testing.assert_allclose(oit.color[row, col, :3], by_hand(frags, bg[row, col]), rtol=0, atol=1e-5)
    np.testing.assert_allclose(buffers["revealage"].color[counts == 0], 1.0)
    one = counts <= 1
    np.testing.assert_allclose(oit.color[..., :3][one], exact.color[..., :3][one], rtol=0, atol=1e-5)
    assert np.abs(oit.color[..., :3] - exact.color[..., :3])[counts >= 2].max() > 0.01
