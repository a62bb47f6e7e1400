"""A colored shadow through glass: the notes' weighted shadow (FORMULAS §21).

    python examples/shadows_glass.py         → out/examples/shadows_glass.png
    python examples/shadows_glass.py --docs  → also docs/images/shadows/glass.png

Three slabs hover over a white floor under a sun: a red glass slab (material
kt = (0.9, 0.3, 0.2)), a gray half-transparent one (opacity 0.5, kt = 0: it
transmits 1 − opacity = 0.5) and an opaque one. §21: "for a transparent occluder,
scale the light by its transmission instead of cutting it off". With shadows on,
the floor behind the red glass gets the sun times (0.9, 0.3, 0.2): a red shadow;
behind the gray one, half the sun; behind the opaque one, none.

The last two pictures are the sun's maps: the depth map of the opaque casters
(only the opaque slab and the floor: the glass is not in it) and the transmission
map, the color of the nearest transparent caster per texel (white where there is
none). One transparent layer only: a second pane behind the first would not dim
the light again.
"""
import sys

import numpy as np
from common import REPO, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject

FLOOR = Material(ka=0.3, kd=(0.85, 0.85, 0.85), ks=0.0)
SLABS = (("red glass, kt (0.9, 0.3, 0.2)", -1.35,
          Material(ka=0.2, kd=(0.55, 0.12, 0.08), ks=0.6, shininess=80.0, kt=(0.9, 0.3, 0.2))),
         ("gray glass, opacity 0.5", 0.0,
          Material(ka=0.2, kd=(0.45, 0.5, 0.55), ks=0.6, shininess=80.0, opacity=0.5)),
         ("opaque", 1.35, Material(ka=0.2, kd=(0.3, 0.4, 0.6), ks=0.3, shininess=30.0)))
CAMERA = Camera(eye=(0.0, 3.9, 4.3), target=(0.0, 0.2, 0.4), fovy=42.0)
DOCS_IMAGES = REPO / "docs" / "images" / "shadows"


def scene(size, shadows):
    width, height = (size, size) if isinstance(size, int) else size
    objects = [SceneObject("floor", shapes.plane(size=8.0, material=FLOOR), np.eye(4))]
    for name, x, material in SLABS:
        objects.append(SceneObject(name, shapes.cube(1.0, material=material),
                                   translate(x, 1.1, -0.3) @ scale(1.0, 0.08, 1.0)))
    sun = Light.directional((0.25, -1.0, 0.7), shadows=shadows, name="sun")
    return Scene(objects, camera=CAMERA, lights=(sun,), ambient=(0.15, 0.15, 0.15), width=width, height=height,
                 background=(0.06, 0.07, 0.09, 1.0))


def _fit(picture, size):
    """A map picture (top row first) at the size of the other pictures, nearest texel."""
    from PIL import Image
    width, height = (size, size) if isinstance(size, int) else size
    return np.asarray(Image.fromarray(picture).convert("RGB").resize((width, height), Image.NEAREST))


def sheet(size=240):
    """No shadows, shadows, and the sun's two maps (opaque depth, transmission)."""
    width, _ = (size, size) if isinstance(size, int) else size
    plain = sp.render_scene(scene(size, False)).to_uint8(alpha=False)
    found = []
    settings = ShadowSettings(resolution=max(64, 2 * width), pcf=1)
    shadowed = sp.render_scene(scene(size, settings), shadow_maps=found).to_uint8(alpha=False)
    sun_map = found[0].maps[0]
    transmission = np.round(255 * np.clip(sun_map.transmission[::-1], 0, 1)).astype(np.uint8)
    return {"no shadows": plain, "shadows: light through the glass": shadowed,
            "sun's depth map (opaque casters)": _fit(sun_map.picture(), size),
            "sun's transmission map": _fit(transmission, size)}


def write_docs_pictures(size=200):
    """docs/images/shadows/glass.png: the four pictures in a row."""
    save_docs_sheet(DOCS_IMAGES / "glass.png", sheet(size), 4)


def main(size=240, out_dir=None):
    return save_sheet("shadows_glass", sheet(size), 4, "Shadows through red glass (kt), gray glass "
                      "(opacity 0.5) and an opaque slab; the sun's depth and transmission maps (FORMULAS 21)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
