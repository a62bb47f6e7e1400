"""Fresnel over the incidence angle, Brewster's angle, and total internal reflection (FORMULAS §17, §19, §20).

    python examples/fresnel_tir.py           → out/examples/fresnel_tir.png
    python examples/fresnel_tir.py --docs    → also docs/images/hall/fresnel.png, tir.png

Row 1, plots of §20 over θ₁ from 0° to 90° (:func:`softpipe.light.lighting.fresnel_rs_rp`):
R_s (red), R_p (blue) and F_R = (R_s + R_p)/2 (white), from air into water (1.33),
glass (1.52) and diamond (2.417) — the media of §17 (``softpipe.light.material.MEDIA``) —
each with Brewster's angle tan θ_B = n₂/n₁ marked (yellow), where R_p = 0; and from
glass out into air, where everything is reflected beyond the critical angle
sin θ_c = n₂/n₁ (magenta, §19). At θ₁ = 0 all three curves start at
((n₁ − n₂)/(n₁ + n₂))²: 0.02, 0.04, 0.17.

Row 2, ray traced (:func:`softpipe.tracers.whitted.raytrace_scene`): a glass block and a
diamond one on a checkered floor — light that enters the top and meets a side face
beyond the critical angle is reflected inside (§19), so the sides show the floor
and the boxes folded back; then Snell's window, a camera inside a tank of glass and
of water looking up at its flat top: within the critical angle (41.1° for glass,
48.8° for water) the top shows the sky and the balls above, squeezed into a disc;
beyond it the top is a perfect mirror of the checkered floor inside (TIR).
"""
import math
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet
from hall import checkerboard

from softpipe.light.lighting import fresnel_rs_rp
from softpipe.light.material import MEDIA, Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_y, scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "hall"
PLOTS = (("air->water", 1.0, MEDIA["water"]), ("air->glass", 1.0, MEDIA["glass"]),
         ("air->diamond", 1.0, MEDIA["diamond"]), ("glass->air", MEDIA["glass"], 1.0))
LIGHT_TILE = Material(ka=0.3, kd=(0.85, 0.85, 0.8), ks=0.0)
DARK_TILE = Material(ka=0.3, kd=(0.2, 0.28, 0.4), ks=0.0)
RED = Material(ka=0.25, kd=(0.85, 0.15, 0.1), ks=0.2, shininess=20.0)
YELLOW = Material(ka=0.25, kd=(0.9, 0.75, 0.15), ks=0.2, shininess=20.0)
SKY = (0.35, 0.5, 0.75, 1.0)


def brewster(n1, n2):
    """θ_B in degrees: tan θ_B = n₂/n₁ (§20)."""
    return math.degrees(math.atan2(n2, n1))


def critical(n1, n2):
    """θ_c in degrees, sin θ_c = n₂/n₁ (§19), or None going into a denser medium."""
    return math.degrees(math.asin(n2 / n1)) if n1 > n2 else None


def plot(n1, n2, size):
    """R_s, R_p and F_R over θ₁ = 0…90° for light from n1 into n2, Brewster's (and the critical) angle marked."""
    from PIL import Image, ImageDraw
    width, height = picture_size(size)
    image = Image.new("RGB", (width, height), (20, 22, 28))
    draw = ImageDraw.Draw(image)
    left, right, top, bottom = 0.1 * width, 0.96 * width, 0.06 * height, 0.9 * height
    x = lambda theta: left + (right - left) * theta / 90.0          # noqa: E731
    y = lambda r: bottom - (bottom - top) * r                       # noqa: E731
    for r in (0.25, 0.5, 0.75, 1.0):
        draw.line([(left, y(r)), (right, y(r))], fill=(45, 48, 58))
    draw.line([(left, top), (left, bottom), (right, bottom)], fill=(140, 140, 150))
    marks = [(brewster(n1, n2), (235, 200, 40))]
    if critical(n1, n2) is not None:
        marks.append((critical(n1, n2), (220, 60, 220)))
    for theta, color in marks:
        draw.line([(x(theta), top), (x(theta), bottom)], fill=color)
    thetas = np.linspace(0.0, 90.0, max(2, 2 * width))
    curves = np.array([fresnel_rs_rp(math.cos(math.radians(t)), n1, n2) for t in thetas])
    for values, color in ((curves[:, 0], (230, 70, 60)), (curves[:, 1], (80, 140, 240)),
                          (curves.mean(axis=1), (245, 245, 245))):
        draw.line([(x(t), y(v)) for t, v in zip(thetas, values)], fill=color, width=max(1, width // 120))
    if width >= 120:
        draw.text((left + 4, top + 2), "Rs", fill=(230, 70, 60))
        draw.text((left + 24, top + 2), "Rp", fill=(80, 140, 240))
        draw.text((left + 44, top + 2), "FR", fill=(245, 245, 245))
        draw.text((x(marks[0][0]) + 3, y(0.55)), f"{marks[0][0]:.1f}", fill=marks[0][1])
        if len(marks) > 1:
            draw.text((x(marks[1][0]) + 3, y(0.8)), f"{marks[1][0]:.1f}", fill=marks[1][1])
        draw.text((left - 4, bottom + 2), "0", fill=(160, 160, 170))
        draw.text((right - 14, bottom + 2), "90", fill=(160, 160, 170))
    return np.asarray(image)


def plots(size):
    out = {}
    for label, n1, n2 in PLOTS:
        r0 = ((n1 - n2) / (n1 + n2)) ** 2
        marks = f"Brewster {brewster(n1, n2):.1f}°"
        if critical(n1, n2) is not None:
            marks += f", crit. {critical(n1, n2):.1f}°"
        out[f"{label}: F0 {r0:.3f}, {marks}"] = plot(n1, n2, size)
    return out


def block_scene(ior, size):
    """A clear block of index ``ior`` on the checkered floor, a red and a yellow box behind it."""
    width, height = picture_size(size)
    light_tiles, dark_tiles = checkerboard(10.0, 10, LIGHT_TILE, DARK_TILE)
    block = Material(ka=0.0, kd=0.0, ks=0.7, shininess=120.0, kr=0.04, kt=0.96, ior=ior)
    objects = [SceneObject("floor, light tiles", light_tiles, np.eye(4), cast_shadows=False),
               SceneObject("floor, dark tiles", dark_tiles, np.eye(4), cast_shadows=False),
               SceneObject("block", shapes.cube(1.0, material=block),
                           translate(0.0, 0.52, 0.2) @ rotate_y(35.0) @ scale(1.3, 1.0, 1.3), program="hall"),
               SceneObject("red box", shapes.cube(0.6, material=RED), translate(-1.0, 0.3, -1.4)),
               SceneObject("yellow box", shapes.cube(0.6, material=YELLOW), translate(1.1, 0.3, -1.0))]
    return Scene(objects, camera=Camera(eye=(0.0, 2.4, 3.6), target=(0.0, 0.4, 0.0), fovy=40.0),
                 lights=(Light.directional((0.4, -1.0, -0.5), name="sun"),), ambient=(0.25, 0.25, 0.25),
                 width=width, height=height, background=SKY, cull="none")


def window_scene(ior, size):
    """A camera inside a tank of index ``ior`` (top at y = 2) looking up; a checkered floor inside, balls above."""
    width, height = picture_size(size)
    light_tiles, dark_tiles = checkerboard(80.0, 80, LIGHT_TILE, DARK_TILE)
    tank = Material(ka=0.0, kd=0.0, ks=0.0, kt=1.0, ior=ior)
    objects = [SceneObject("tank", shapes.cube(1.0, material=tank), scale(80.0, 4.0, 80.0)),
               SceneObject("floor, light tiles", light_tiles, translate(0.0, -1.5, 0.0)),
               SceneObject("floor, dark tiles", dark_tiles, translate(0.0, -1.5, 0.0))]
    for k, (x, z, material) in enumerate(((-1.2, -2.5, RED), (1.0, -3.2, YELLOW), (0.0, -1.0, RED))):
        glowing = material.replace(ke=tuple(0.6 * np.array(material.kd)))       # seen from below: lit by itself
        objects.append(SceneObject(f"ball {k}", shapes.uv_sphere(0.45, 32, 16, material=glowing),
                                   translate(x, 3.2, z)))
    return Scene(objects, camera=Camera(eye=(0.0, -1.0, 0.5), target=(0.0, 2.0, -1.6), fovy=95.0, near=0.05),
                 lights=(Light.directional((0.3, -1.0, -0.2), name="sun"),), ambient=(0.3, 0.3, 0.3),
                 width=width, height=height, background=SKY, cull="none")


def tir(size):
    out = {}
    for name in ("glass", "diamond"):
        s = block_scene(MEDIA[name], size)
        out[f"{name} block ({MEDIA[name]}): TIR at the sides"] = raytrace_scene(s, max_depth=8).to_uint8(alpha=False)
    for name in ("glass", "water"):
        s = window_scene(MEDIA[name], size)
        out[f"Snell's window, {name}: critical {critical(MEDIA[name], 1.0):.1f}"] = \
            raytrace_scene(s, max_depth=6).to_uint8(alpha=False)
    return out


def sheet(size=200):
    return {**plots(size), **tir(size)}


def write_docs_pictures(size=200):
    """docs/images/hall/fresnel.png (the four plots) and tir.png (the four ray-traced pictures)."""
    for name, pictures in (("fresnel.png", plots(size)), ("tir.png", tir(size))):
        save_docs_sheet(DOCS_IMAGES / name, pictures, 4)


def main(size=200, out_dir=None):
    return save_sheet("fresnel_tir", sheet(size), 4, "Fresnel Rs (red), Rp (blue), FR (white) over the incidence "
                      "angle, Brewster (yellow), critical (magenta); TIR, ray traced (FORMULAS 17, 19, 20)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
