"""Transparency three ways, each against the exact per-sample sorted composite.

    python examples/transparency.py         → out/examples/transparency.png (and prints the numbers)
    python examples/transparency.py --docs  → also docs/images/transparency/methods.png

Three half-transparent panes (red, green, blue) cross one another in front of an opaque
wall, and an opaque ball pokes through them. Drawn

- by sorting objects back to front (``render_scene``: one order per object, the panes'
  box centres in eye space), wrong where the panes interpenetrate;
- by depth peeling (``depth_peel``, Everitt 2001), exact with enough layers;
- by weighted blended OIT (``weighted_oit``, McGuire and Bavoil 2013; FORMULAS §29),
  approximate wherever panes overlap;

beside the exact composite (``softpipe.testing.sorted_composite``: every fragment of the
reference path sorted per pixel) and each method's difference from it, ×4 (dark gray where
a pane is and the method is exact).
"""
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_x, rotate_y, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.scenes.transparency import depth_peel, transparent_traces, weighted_oit
from softpipe.testing import sorted_composite

WALL = Material(ka=0.3, kd=(0.8, 0.78, 0.72), ks=0.0)
BALL = Material(ka=0.2, kd=(0.85, 0.7, 0.2), ks=0.5, shininess=40.0)
#: (name, color, opacity, model matrix): three panes crossing about the vertical axis, tilted apart
PANES = (("red pane", (0.9, 0.15, 0.1), 0.5, translate(-0.35, 0.0, 0.0) @ rotate_y(-40.0) @ rotate_x(90.0)),
         ("green pane", (0.1, 0.8, 0.2), 0.5, translate(0.0, 0.25, 0.0) @ rotate_x(70.0)),
         ("blue pane", (0.15, 0.3, 0.95), 0.6, translate(0.35, 0.0, 0.0) @ rotate_y(40.0) @ rotate_x(90.0)))
CAMERA = Camera(eye=(0.0, 0.4, 4.2), target=(0.0, 0.0, 0.0), fovy=40.0)
LAYERS = 6
DOCS_IMAGES = REPO / "docs" / "images" / "transparency"


def scene(size):
    """The wall, the ball and the three panes (drawn from both sides: cull "none")."""
    width, height = picture_size(size)
    objects = [SceneObject("wall", shapes.plane(6.0, material=WALL), translate(0.0, 0.0, -1.4) @ rotate_x(90.0)),
               SceneObject("ball", shapes.icosphere(0.45, 3, material=BALL), translate(0.25, -0.3, 0.2))]
    for name, color, opacity, model in PANES:
        material = Material(ka=0.3, kd=color, ks=0.4, shininess=60.0, opacity=opacity)
        objects.append(SceneObject(name, shapes.plane(1.6, material=material), model,
                                   cull="none"))
    sun = Light.directional((0.4, -0.6, -1.0), name="sun")
    return Scene(objects, camera=CAMERA, lights=(sun,), ambient=(0.25, 0.25, 0.25), width=width, height=height,
                 background=(0.06, 0.07, 0.09, 1.0))


def exact(s):
    """The exact composite of scene ``s`` (the reference path's fragments sorted per pixel), and the
    pixels where a transparent surface is in front of the opaque one."""
    base, traces = transparent_traces(s)
    fb = base.framebuffer
    covered = np.zeros((fb.height, fb.width), bool)
    for t in traces:
        f = t.fragments
        front = f.depth.astype(np.float32) < fb.depth[f.y, f.x]
        covered[f.y[front], f.x[front]] = True
    return sorted_composite(traces, fb), covered


def difference(a, b):
    """(pixels whose RGB differs by more than 1/255, pixels that differ at all, the largest difference in 1/255)."""
    d = np.abs(a[..., :3].astype(np.int16) - b[..., :3].astype(np.int16)).max(axis=-1)
    return int((d > 1).sum()), int((d > 0).sum()), int(d.max())


def pictures(size=240):
    """The three methods, the exact composite, each method's difference from it; and the numbers."""
    s = scene(size)
    composite, covered = exact(s)
    reference = composite.to_uint8(alpha=False)
    methods = {"sorted by object": sp.render_scene(s).to_uint8(alpha=False),
               f"depth peeling, {LAYERS} layers": depth_peel(s, layers=LAYERS).to_uint8(alpha=False),
               "weighted blended OIT": weighted_oit(s).to_uint8(alpha=False)}
    shown = dict(methods)
    shown["exact: fragments sorted per pixel"] = reference
    numbers = {}
    for name, picture in methods.items():
        numbers[name] = difference(picture, reference)
        gap = np.clip(np.abs(picture.astype(np.int16) - reference.astype(np.int16)) * 4, 0, 255).astype(np.uint8)
        gap[covered & (gap.max(axis=-1) == 0)] = 40      # dark gray: a pane is there, and no difference
        shown[f"|{name.split(',')[0]} - exact| x4"] = gap
    return shown, numbers


def sheet(size=240):
    return pictures(size)[0]


def report(numbers, size):
    """The numbers as the docs page gives them."""
    w, h = picture_size(size)
    lines = [f"{w}×{h} pixels; against the exact composite:"]
    for name, (over, any_, worst) in numbers.items():
        lines.append(f"  {name}: {over} pixels differ by more than 1/255 ({any_} at all), the largest by {worst}/255")
    return "\n".join(lines)


def write_docs_pictures(size=(200, 150)):
    """docs/images/transparency/methods.png: the four pictures over the three differences."""
    shown, numbers = pictures(size)
    save_docs_sheet(DOCS_IMAGES / "methods.png", shown, 4)
    print(report(numbers, size))


def main(size=240, out_dir=None):
    shown, numbers = pictures(size)
    print(report(numbers, size))
    return save_sheet("transparency", shown, 4, "Transparency: sorted, depth peeling, weighted OIT, exact composite "
                      "(FORMULAS 29)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
