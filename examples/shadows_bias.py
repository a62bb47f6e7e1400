"""Shadow-map depth bias and percentage-closer filtering (FORMULAS §21).

    python examples/shadows_bias.py          → out/examples/shadows_bias.png
    python examples/shadows_bias.py --docs   → also docs/images/shadows/bias.png, acne.png,
                                               peter-panning.png, pcf.png

A box rests on a floor under a low sun (20° above the horizon), shadows from a
directional light's 256-texel map. Top row, the depth bias (the depth pass's
polygon offset factor·DZ + units·r, the rasterizer's ε of §21's shadow ray):

* offset (0, 0): "acne": the floor and the box's lit faces shadow themselves in
  stripes, where the map's texel, taken at its centre, lies in front of the point
  looked up;
* units only (0, 16): a constant bias is not enough on a floor the light grazes:
  still acne;
* the default (2r + 2, 16) = (4, 16) for PCF radius r = 1: clean;
* a huge factor (30, 16): "peter-panning": the box's depth pushed so far back that
  its shadow comes loose from its foot.

Bottom row, the PCF radius r = 0, 1, 2, 4 with a coarse 96-texel map (default
bias each): (2r+1)² compares averaged, a soft band 2r+1 texels wide; r = 0 is the
hard one-tap edge, its texels visible as steps. At r = 4 the default factor
2r + 2 = 10 on texels this coarse lifts the shadow off the box's foot.
"""
import sys

import numpy as np
from common import REPO, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_y, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject

FLOOR = Material(ka=0.25, kd=(0.78, 0.76, 0.72), ks=0.0)
BOX = Material(ka=0.2, kd=(0.85, 0.4, 0.22), ks=0.2, shininess=20.0)
CAMERA = Camera(eye=(-1.8, 2.6, 4.6), target=(0.8, 0.2, 0.3), fovy=40.0)
ELEVATION = 20.0     # the sun's height above the horizon, degrees
BIAS = ((("offset (0, 0): acne", "acne"), (0.0, 0.0)),
        (("units only (0, 16): acne", None), (0.0, 16.0)),
        (("default (4, 16)", "default"), (None, 16.0)),         # offset_factor None: 2r + 2
        (("factor 30: peter-panning", "peter-panning"), (30.0, 16.0)))
BIAS_RESOLUTION = 256
PCF = (0, 1, 2, 4)
PCF_RESOLUTION = 96
DOCS_IMAGES = REPO / "docs" / "images" / "shadows"


def sun(settings):
    e = np.radians(ELEVATION)
    return Light.directional((0.95 * np.cos(e), -np.sin(e), 0.31 * np.cos(e)), diffuse=1.6, shadows=settings,
                             name="sun")


def render(settings, size):
    """The box on the floor under the sun with these ShadowSettings: an 8-bit RGB picture."""
    width, height = (size, size) if isinstance(size, int) else size
    objects = [SceneObject("floor", shapes.plane(size=8.0, material=FLOOR), np.eye(4)),
               SceneObject("box", shapes.cube(1.0, material=BOX), translate(0.0, 0.5, 0.0) @ rotate_y(20.0))]
    scene = Scene(objects, camera=CAMERA, lights=(sun(settings),), ambient=(0.15, 0.15, 0.15),
                  width=width, height=height, background=(0.06, 0.07, 0.09, 1.0))
    return sp.render_scene(scene).to_uint8(alpha=False)


def bias_pictures(size):
    return {label: render(ShadowSettings(resolution=BIAS_RESOLUTION, pcf=1, offset_factor=f, offset_units=u), size)
            for (label, _), (f, u) in BIAS}


def pcf_pictures(size):
    return {f"pcf {r}: {(2 * r + 1) ** 2} tap{'s' if r else ''}": render(ShadowSettings(resolution=PCF_RESOLUTION,
                                                                                        pcf=r), size)
            for r in PCF}


def sheet(size=200):
    """Top row the bias sweep, bottom row the PCF sweep."""
    return {**bias_pictures(size), **pcf_pictures(size)}


def write_docs_pictures(size=240):
    """docs/images/shadows/: bias.png and pcf.png (the two rows), acne.png, peter-panning.png."""
    from PIL import Image
    DOCS_IMAGES.mkdir(parents=True, exist_ok=True)
    bias = bias_pictures(size)
    for (label, name), _ in BIAS:
        if name in ("acne", "peter-panning"):
            path = DOCS_IMAGES / f"{name}.png"
            Image.fromarray(bias[label]).save(path, optimize=True)
            print(path)
    for name, pictures in (("bias", bias_pictures(size * 3 // 4)), ("pcf", pcf_pictures(size * 3 // 4))):
        save_docs_sheet(DOCS_IMAGES / f"{name}.png", pictures, 4)


def main(size=200, out_dir=None):
    return save_sheet("shadows_bias", sheet(size), 4, "Depth bias (top: acne, default, peter-panning) and "
                      "PCF radius 0, 1, 2, 4 (bottom) (FORMULAS 21)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
