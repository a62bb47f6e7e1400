"""A mirror and a glass sphere over a checkerboard, rasterized with environment maps (FORMULAS §16–§20).

    python examples/environment.py            → out/examples/environment.png
    python examples/environment.py --docs     → also docs/images/environment/maps.png, figure.png, media.png

A static environment: (a) a sky panorama made here, latitude-longitude
(equirectangular); (b) the cube map made from it (``CubeMap.from_equirectangular``),
unfolded as a cross; (c) the scene, the spheres drawn with the programs ``mirror``
(kr·env(R)) and ``glass`` (F_R·env(R) + (1 − F_R)·kt·env(T)) in that sky, which also
fills the background. The spheres see the sky only: not the floor, not each other.

Dynamic environments: (d) each sphere's cube map drawn from its centre, six
90° draws of the scene (``softpipe.scenes.environment_pass.dynamic_environments``), so the mirror
shows the checkerboard, the box and the glass sphere; (e) the mirror's map
unfolded.

Rays: (f) the scene rasterized, the spheres' fragments tracing their
reflected and refracted rays through the scene (``render_with_environments(scene,
"rays")``: ray queries from the fragment shader); (g) the same scene ray traced
(``softpipe.tracers.whitted``, depth 5), the spheres split by the same formulas (kr for the
mirror, Fresnel for the glass). (f) and (g) differ only along silhouettes and the
sun's shadow edges (a shadow map in (f), shadow rays in (g)); both have a plain
background.

The named media (FORMULAS §17): the glass sphere close up as water (1.33),
glass (1.52) and diamond (2.417): the denser, the more it bends (the floor seen
through it shrinks and turns over) and the more Fresnel reflects at the rim.
"""
import sys

import numpy as np
from common import REPO, checkerboard, picture_size, save_docs_sheet, save_sheet

from softpipe.light.cubemap import MEDIA, CubeMap, sky_gradient
from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_y, translate
from softpipe.scenes import shapes
from softpipe.scenes.environment_pass import dynamic_environments, render_with_environments
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "environment"

LIGHT_TILE = Material(ka=0.3, kd=(0.85, 0.85, 0.82), ks=0.05, shininess=10.0)
DARK_TILE = Material(ka=0.3, kd=(0.2, 0.26, 0.38), ks=0.05, shininess=10.0)
MIRROR = Material(ka=0.0, kd=0.02, ks=0.6, shininess=120.0, kr=(0.9, 0.9, 0.9))
BOX = Material(ka=0.25, kd=(0.8, 0.2, 0.15), ks=0.3, shininess=30.0)
MIRROR_CENTRE = (-1.0, 0.75, -0.2)
GLASS_CENTRE = (0.85, 0.6, 0.6)
CAMERA = Camera(eye=(0.0, 2.4, 5.4), target=(0.0, 0.55, 0.0), fovy=42.0)
CLOSE_UP = Camera(eye=(0.85 + 0.5, 0.6 + 1.6, 0.6 + 3.0), target=GLASS_CENTRE, fovy=30.0)
SUN = (0.5, -1.0, -0.6)
FLAT_SKY = (0.55, 0.65, 0.8, 1.0)          # the ray tracer's background: a constant


def glass(medium):
    """A clear material of the named medium's index (softpipe.light.cubemap.MEDIA)."""
    return Material(ka=0.0, kd=0.0, ks=0.6, shininess=120.0, kr=(0.08, 0.08, 0.08), kt=(0.95, 0.95, 0.95),
                    ior=MEDIA[medium])


def scene(size, medium="glass", background=FLAT_SKY, camera=CAMERA):
    """The floor, a box, the mirror and the glass sphere, drawn with the programs ``mirror`` and ``glass``."""
    width, height = picture_size(size)
    light, dark = checkerboard(10.0, 10, LIGHT_TILE, DARK_TILE)
    objects = [SceneObject("floor, light tiles", light, np.eye(4), cast_shadows=False),
               SceneObject("floor, dark tiles", dark, np.eye(4), cast_shadows=False),
               SceneObject("box", shapes.cube(0.9, material=BOX), translate(0.4, 0.45, -1.6) @ rotate_y(30.0)),
               SceneObject("mirror", shapes.uv_sphere(0.75, 64, 32, material=MIRROR), translate(*MIRROR_CENTRE),
                           program="mirror"),
               SceneObject("glass", shapes.uv_sphere(0.6, 64, 32, material=glass(medium)), translate(*GLASS_CENTRE),
                           program="glass")]
    sun = Light.directional(SUN, shadows=True, name="sun")    # a shadow map (the ray tracer: shadow rays)
    return Scene(objects, camera=camera, lights=(sun,), ambient=(0.2, 0.2, 0.2), width=width, height=height,
                 background=background)


def sky_panorama(width=256):
    """A generated sky, equirectangular (2:1): softpipe.light.cubemap.sky_gradient with a few soft clouds, float RGB."""
    h = width // 2
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = ((np.arange(width) + 0.5) / width - 0.5) * 2.0 * np.pi
    T, F = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(T) * np.sin(F), np.cos(T), -np.sin(T) * np.cos(F)], -1)
    color = sky_gradient(d)
    clouds = np.clip(np.sin(3 * F + 1.0) * np.sin(9 * T) * np.cos(5 * F - 2 * T), 0.0, 1.0) ** 2
    clouds *= (d[..., 1] > 0.05) * np.clip(d[..., 1] * 3.0, 0.0, 1.0)
    return (color + clouds[..., None] * (0.95 - color)).astype(np.float32)


def fit(picture, size, background=24):
    """An RGB float or uint8 picture scaled to fit ``size`` (keeping its shape), centred on a dark square."""
    from PIL import Image
    width, height = picture_size(size)
    if picture.dtype != np.uint8:
        picture = np.round(np.clip(picture[..., :3], 0.0, 1.0) * 255).astype(np.uint8)
    h, w = picture.shape[:2]
    k = min(width / w, height / h)
    new = (max(1, int(round(w * k))), max(1, int(round(h * k))))
    small = np.asarray(Image.fromarray(picture[..., :3]).resize(new, Image.BILINEAR))
    out = np.full((height, width, 3), background, np.uint8)
    top, left = (height - new[1]) // 2, (width - new[0]) // 2
    out[top:top + new[1], left:left + new[0]] = small
    return out


def cube_size(width):
    """Face width of the cube maps: about half the picture's width, at least 16 texels."""
    return max(16, width // 2)


def sheet(size=240, found=None):
    """The ten pictures (static sky; dynamic maps; rays from the shaders, ray traced; three media); maps
    into ``found``."""
    width, _ = picture_size(size)
    n = cube_size(width)
    pano = sky_panorama(max(64, 4 * n))
    sky = CubeMap.from_equirectangular(pano, size=n)
    static = render_with_environments(scene(size), sky, sky=sky)
    maps = dynamic_environments(scene(size), n, sky=sky)
    dynamic = render_with_environments(scene(size), maps, sky=sky)
    hybrid = render_with_environments(scene(size), "rays")
    traced = raytrace_scene(scene(size))
    media = {}
    for letter, medium in zip("hij", ("water", "glass", "diamond")):
        close = scene(size, medium, camera=CLOSE_UP)
        media[f"({letter}) {medium}, ior {MEDIA[medium]}"] = render_with_environments(close, maps, sky=sky)
    if found is not None:
        found.update(sky=sky, maps=maps)
    pictures = {"(a) sky panorama (equirectangular)": fit(pano, size),
                "(b) its cube map, unfolded": fit(sky.cross(), size),
                "(c) mirror and glass in the sky map": static.to_uint8(alpha=False),
                "(d) dynamic maps: 6 draws per sphere": dynamic.to_uint8(alpha=False),
                "(e) the mirror's dynamic map": fit(maps["mirror"].cross(), size),
                "(f) rasterized, rays from the shaders": hybrid.to_uint8(alpha=False),
                "(g) ray traced, depth 5": traced.to_uint8(alpha=False)}
    pictures.update({k: fb.to_uint8(alpha=False) for k, fb in media.items()})
    return pictures


def write_docs_pictures(size=240):
    """docs/images/environment/maps.png (a, b, e), figure.png (c, d, f, g), media.png (the three media)."""
    pictures = sheet(size)
    names = list(pictures)
    for file, keys in (("maps.png", [names[0], names[1], names[4]]),
                       ("figure.png", [names[2], names[3], names[5], names[6]]), ("media.png", names[7:])):
        save_docs_sheet(DOCS_IMAGES / file, {k: pictures[k] for k in keys}, len(keys))


def main(size=240, out_dir=None):
    return save_sheet("environment", sheet(size), 3, "Mirror and glass rasterized with cube maps: a sky map, "
                      "dynamic maps; with rays from the shaders, ray traced; water, glass, diamond (FORMULAS 16-20)",
                      out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
