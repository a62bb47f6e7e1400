"""The same scene rasterized and ray traced, side by side (FORMULAS §11, §16–§19, §21–§23).

    python examples/raytrace.py              → out/examples/raytrace.png, and one pixel's ray tree printed
    python examples/raytrace.py --docs       → also docs/images/raytracing/figure.png, panes.png

A mirror sphere (kr), a glass sphere (kt, ior 1.5) and a red box on a checkered
floor under a sun, one Scene drawn four ways:

* rasterized, V_j from a shadow map (``ShadowSettings()``, PCF radius 1);
* rasterized, V_j from shadow rays (``ShadowSettings(method="ray")``, §21);
* ray traced (:func:`softpipe.tracers.whitted.raytrace_scene`: primary rays through the
  pixel centres §23, the same lighting with shadow rays, reflected and refracted
  rays §16–§19 to depth 5, the ray tree §22);
* ray traced with ``max_depth=0``: primary and shadow rays only, which is the
  second picture again — the rasterizer with shadow rays *is* a ray tracer of depth 0.

Then the differences, amplified ×4: |shadow map − traced| is the spheres (the
rasterizer has no reflected or refracted light: environment maps are issue #17)
and a thin ring round every shadow (the map's PCF band); |shadow rays − traced|
is the spheres alone.

The last row is §21's transparent occluder: a red and a blue glass pane, one above
the other, over a floor. Where the sun passes both, the shadow map (one
transparent layer) keeps only the nearest pane's transmission, blue; the shadow
rays multiply both, (0.9, 0.3, 0.2)·(0.2, 0.4, 0.9) = (0.18, 0.12, 0.18); the ray
tracer's shadow rays agree, and it sees through the panes besides.

Run, it also prints the ray tree of one pixel on the glass sphere
(:func:`softpipe.tracers.whitted.ray_tree`) and the time each picture took.
"""
import sys
import time

import numpy as np
from common import REPO, checkerboard, picture_size, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_y, scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import ray_tree, raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "raytracing"
BACKGROUND = (0.35, 0.5, 0.7, 1.0)               # a sky: what a reflected ray that meets nothing brings back

LIGHT_TILE = Material(ka=0.25, kd=(0.85, 0.85, 0.82), ks=0.05, shininess=10.0)
DARK_TILE = Material(ka=0.25, kd=(0.22, 0.3, 0.42), ks=0.05, shininess=10.0)
MIRROR = Material(ka=0.0, kd=0.02, ks=0.6, shininess=120.0, kr=(0.85, 0.85, 0.85))
GLASS = Material(ka=0.0, kd=0.03, ks=0.6, shininess=120.0, kr=(0.08, 0.08, 0.08), kt=(0.9, 0.9, 0.9), ior=1.5)
BOX = Material(ka=0.25, kd=(0.8, 0.2, 0.15), ks=0.3, shininess=30.0)
GLASS_CENTRE = (0.75, 0.6, 0.7)
CAMERA = Camera(eye=(0.0, 2.6, 5.2), target=(0.0, 0.5, 0.0), fovy=42.0)
SUN = (0.5, -1.0, -0.6)

FLOOR = Material(ka=0.3, kd=(0.85, 0.85, 0.85), ks=0.0)
RED_PANE = Material(ka=0.1, kd=(0.3, 0.06, 0.04), ks=0.5, shininess=80.0, kt=(0.9, 0.3, 0.2), ior=1.5)
BLUE_PANE = Material(ka=0.1, kd=(0.05, 0.1, 0.3), ks=0.5, shininess=80.0, kt=(0.2, 0.4, 0.9), ior=1.5)
PANES_SUN = (0.55, -1.0, 0.75)
PANES_CAMERA = Camera(eye=(0.4, 3.4, 3.0), target=(-0.2, 0.5, -0.7), fovy=45.0)
#: Floor points (y = 0) whose sun ray passes the red pane only, both panes, the blue pane only.
PANE_POINTS = {"red only": (-0.9, 0.0, 0.25), "both": (-0.05, 0.0, -0.15), "blue only": (0.9425, 0.0, -0.8875)}


def scene(size, shadows=True):
    """The mirror, the glass and the box on the checkered floor, the sun casting shadows by ``shadows``."""
    width, height = picture_size(size)
    light_tiles, dark_tiles = checkerboard(8.0, 8, LIGHT_TILE, DARK_TILE)
    objects = [SceneObject("floor, light tiles", light_tiles, np.eye(4), cast_shadows=False),
               SceneObject("floor, dark tiles", dark_tiles, np.eye(4), cast_shadows=False),
               SceneObject("mirror", shapes.uv_sphere(0.75, 48, 24, material=MIRROR), translate(-1.15, 0.75, -0.3)),
               SceneObject("glass", shapes.uv_sphere(0.6, 48, 24, material=GLASS), translate(*GLASS_CENTRE)),
               SceneObject("box", shapes.cube(0.9, material=BOX), translate(0.7, 0.45, -1.3) @ rotate_y(30.0))]
    sun = Light.directional(SUN, shadows=shadows, name="sun")
    return Scene(objects, camera=CAMERA, lights=(sun,), ambient=(0.15, 0.15, 0.15), width=width, height=height,
                 background=BACKGROUND)


def panes(size, shadows=True):
    """A red glass pane under a blue one, over a white floor, under a low sun."""
    width, height = picture_size(size)
    objects = [SceneObject("floor", shapes.plane(8.0, material=FLOOR), np.eye(4), cast_shadows=False),
               SceneObject("red pane", shapes.cube(1.0, material=RED_PANE),
                           translate(-0.9, 1.0, -0.9) @ scale(1.4, 0.06, 1.4)),
               SceneObject("blue pane", shapes.cube(1.0, material=BLUE_PANE),
                           translate(-0.3, 1.35, -1.35) @ scale(1.4, 0.06, 1.4))]
    sun = Light.directional(PANES_SUN, shadows=shadows, name="sun")
    return Scene(objects, camera=PANES_CAMERA, lights=(sun,), ambient=(0.15, 0.15, 0.15), width=width,
                 height=height, background=(0.06, 0.07, 0.09, 1.0))


def shadow_map(width):
    """A map of about twice the picture's width (at least 64 texels), PCF radius 1, fitted to the casters
    (the floors cast no shadow: nothing lies under them)."""
    return ShadowSettings(resolution=max(64, 2 * width), pcf=1)


def glass_pixel(size):
    """The pixel (x, image row y) a little left of and above the glass sphere's centre."""
    width, height = picture_size(size)
    centre = np.array([*GLASS_CENTRE, 1.0]) + (-0.25, 0.2, 0.0, 0.0)
    clip = CAMERA.projection(width / height) @ CAMERA.view @ centre
    x, y = clip[:2] / clip[3]
    return int((x + 1) / 2 * width), int((1 - y) / 2 * height)


def _amplified(a, b, factor=4.0):
    return np.round(255 * np.clip(factor * np.abs(a.color[..., :3] - b.color[..., :3]), 0, 1)).astype(np.uint8)


def renders(size, timings=None):
    """Every framebuffer of the sheet, by name; seconds per render into ``timings``."""
    width, _ = picture_size(size)
    timings = {} if timings is None else timings
    jobs = {"map": lambda: sp.render_scene(scene(size, shadow_map(width))),
            "rays": lambda: sp.render_scene(scene(size, ShadowSettings(method="ray"))),
            "traced": lambda: raytrace_scene(scene(size)),
            "depth 0": lambda: raytrace_scene(scene(size), max_depth=0),
            "panes map": lambda: sp.render_scene(panes(size, shadow_map(width))),
            "panes rays": lambda: sp.render_scene(panes(size, ShadowSettings(method="ray"))),
            "panes traced": lambda: raytrace_scene(panes(size))}
    out = {}
    for name, job in jobs.items():
        start = time.perf_counter()
        out[name] = job()
        timings[name] = time.perf_counter() - start
    return out


def pictures(fbs):
    """The labelled pictures of the sheet from :func:`renders`' framebuffers."""
    rgb = {name: fb.to_uint8(alpha=False) for name, fb in fbs.items()}
    return {"(a) rasterized, shadow map": rgb["map"],
            "(b) rasterized, shadow rays": rgb["rays"],
            "(c) ray traced, depth 5": rgb["traced"],
            "ray traced, depth 0 (= b)": rgb["depth 0"],
            "|a - c| x 4": _amplified(fbs["map"], fbs["traced"]),
            "|b - c| x 4": _amplified(fbs["rays"], fbs["traced"]),
            "panes: shadow map (1 layer)": rgb["panes map"],
            "panes: shadow rays": rgb["panes rays"],
            "panes: ray traced": rgb["panes traced"]}


def sheet(size=240):
    """Row 1: (a) shadow map, (b) shadow rays, (c) ray traced; row 2: depth 0, |a−c|, |b−c|; row 3: the panes."""
    return pictures(renders(size))


def transmission_numbers():
    """V of the sun at the three floor points of :data:`PANE_POINTS`, by the shadow map and by shadow rays."""
    out = {}
    for method, settings in (("map", shadow_map(200)), ("rays", ShadowSettings(method="ray"))):
        found = []
        sp.render_scene(panes(16, settings), shadow_maps=found)
        out[method] = {name: tuple(round(float(v), 3) for v in found[0].visibility(0, point))
                       for name, point in PANE_POINTS.items()}
    return out


def write_docs_pictures(size=200):
    """docs/images/raytracing/figure.png (the 2×3 comparison) and panes.png (the three panes pictures)."""
    everything = sheet(size)
    names = list(everything)
    save_docs_sheet(DOCS_IMAGES / "figure.png", {k: everything[k] for k in names[:6]}, 3)
    save_docs_sheet(DOCS_IMAGES / "panes.png", {k: everything[k] for k in names[6:]}, 3)


def main(size=240, out_dir=None):
    timings = {}
    fbs = renders(size, timings)
    path = save_sheet("raytrace", pictures(fbs), 3, "Rasterized (shadow map, shadow rays) vs ray traced; the "
                      "rasterizer has no reflections or refractions yet (issue #17) (FORMULAS 16-23)", out_dir)
    print("seconds:", ", ".join(f"{name} {t:.2f}" for name, t in timings.items()))
    x, y = glass_pixel(size)
    print(ray_tree(scene(size), x, y))
    return path


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
