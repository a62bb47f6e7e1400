"""No shadows vs shadows, under each light kind (FORMULAS §9, §10, §21).

    python examples/shadows.py               → out/examples/shadows.png
    python examples/shadows.py --docs        → also docs/images/shadows/figure.png, maps.png

Three balls hover over a floor. Top row: lit by a directional light, a spot and a
point light, with no shadows: every light reaches every point (§10 as written),
so nothing tells how high the balls float. Middle row: the same lights casting
shadows through shadow maps, V_j multiplying each light's diffuse and specular
terms (§11, §21). Bottom row: what each light saw, its shadow map as a depth
picture (near dark, far light, no caster white): the directional light's
orthographic map fitted to the casters, the spot's perspective map of field of
view 2β, and the point light's cube map, its six faces ±x, ±y, ±z laid out as
+x −x +y over −y +z −z.
"""
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject

FLOOR = Material(ka=0.25, kd=(0.78, 0.76, 0.72), ks=0.1, shininess=10.0)
BALLS = (((-1.1, 0.75, 0.3), 0.45, (0.80, 0.25, 0.20)),
         ((0.15, 1.25, -0.4), 0.5, (0.25, 0.55, 0.85)),
         ((1.2, 0.55, 0.6), 0.35, (0.90, 0.75, 0.25)))
CAMERA = Camera(eye=(0.0, 4.2, 6.0), target=(0.0, 0.3, 0.0), fovy=40.0)
DOCS_IMAGES = REPO / "docs" / "images" / "shadows"


def lights(shadows=False):
    """The three lights of the figure, each alone: name → Light."""
    return {
        "directional": Light.directional((0.45, -1.0, -0.35), shadows=shadows, name="sun"),
        "spot": Light.spot((-1.2, 4.0, 1.6), (0.3, -1.0, -0.45), 40.0, 2.0, shadows=shadows, name="spot"),
        "point": Light.point((0.4, 2.7, 1.2), attenuation=(0.5, 0.1, 0.04), shadows=shadows, name="bulb"),
    }


def objects():
    out = [SceneObject("floor", shapes.plane(size=7.0, material=FLOOR), np.eye(4))]
    for k, (centre, radius, color) in enumerate(BALLS):
        ball = shapes.uv_sphere(radius=radius, segments=32, rings=16,
                                material=Material(ka=0.2, kd=color, ks=0.4, shininess=40.0))
        out.append(SceneObject(f"ball {k}", ball, translate(*centre)))
    return out


def render(light, size, shadow_maps=None):
    """The scene under one light, an 8-bit RGB picture (and its ShadowMaps into ``shadow_maps``)."""
    width, height = picture_size(size)
    scene = Scene(objects(), camera=CAMERA, lights=(light,), ambient=(0.12, 0.12, 0.12), width=width,
                  height=height, background=(0.06, 0.07, 0.09, 1.0))
    return sp.render_scene(scene, shadow_maps=shadow_maps).to_uint8(alpha=False)


def gray(picture, size):
    """A map's 8-bit depth picture as an RGB picture of ``size`` (nearest texel)."""
    from PIL import Image
    width, height = picture_size(size)
    return np.asarray(Image.fromarray(picture).convert("RGB").resize((width, height), Image.NEAREST))


def cube_mosaic(maps):
    """The six faces of a cube map, +x −x +y over −y +z −z, 2-texel gaps, in a square picture."""
    faces = [m.picture() for m in maps]
    n = faces[0].shape[0]
    width = 3 * n + 4
    top = (width - (2 * n + 2)) // 2               # centred in a square, so it keeps its shape
    out = np.full((width, width), 24, np.uint8)
    for k, face in enumerate(faces):
        r, c = divmod(k, 3)
        out[top + r * (n + 2):top + r * (n + 2) + n, c * (n + 2):c * (n + 2) + n] = face
    return out


def sheet(size=200, maps_out=None):
    """Row 1 without shadows, row 2 with, row 3 each light's shadow map."""
    width, height = picture_size(size)
    plain, shadowed, depth = {}, {}, {}
    for kind, light in lights(False).items():
        plain[f"{kind}, no shadows"] = render(light, size)
    for kind, light in lights(shadow_settings(width)).items():
        found = []
        shadowed[f"{kind}, shadows"] = render(light, size, found)
        maps = found[0].maps
        if maps_out is not None:
            maps_out[kind] = maps
        if len(maps) == 6:
            depth[f"{kind}: cube map, 6 faces"] = gray(cube_mosaic(maps), size)
        else:
            depth[f"{kind}: shadow map"] = gray(maps[0].picture(), size)
    return {**plain, **shadowed, **depth}


def shadow_settings(width):
    """A map of about twice the picture's width (at least 32 texels), PCF radius 1."""
    from softpipe.light.shadowmap import ShadowSettings
    return ShadowSettings(resolution=max(32, 2 * width), pcf=1)


def write_docs_pictures(size=200):
    """docs/images/shadows/figure.png (the 2×3 figure) and maps.png (the maps, faces labelled)."""
    from PIL import Image

    from softpipe.views.pictures import contact_sheet
    DOCS_IMAGES.mkdir(parents=True, exist_ok=True)
    found = {}
    pictures = sheet(size, maps_out=found)
    figure = {k: v for k, v in pictures.items() if "map" not in k}
    save_docs_sheet(DOCS_IMAGES / "figure.png", figure, 3)
    side = 128
    faces = {"directional": gray(found["directional"][0].picture(), side),
             "spot": gray(found["spot"][0].picture(), side),
             " ": np.full((side, side, 3), 24, np.uint8)}
    for m in found["point"]:
        faces[f"point, face {m.face}"] = gray(m.picture(), side)
    path = DOCS_IMAGES / "maps.png"
    Image.fromarray(np.asarray(contact_sheet(faces, columns=3))).convert("L").save(path, optimize=True)
    print(path)


def main(size=200, out_dir=None):
    return save_sheet("shadows", sheet(size), 3, "No shadows vs shadows, three light kinds; their shadow maps "
                      "(FORMULAS 21)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
