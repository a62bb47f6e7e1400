"""Hall's illumination model, term by term, on one glass ball, ray traced (FORMULAS §13, §14, §15).

    python examples/hall.py                  → out/examples/hall.png
    python examples/hall.py --docs           → also docs/images/hall/terms.png

One ball (program ``hall``) on a checkered floor beside a red box and a blue one,
lit by a key light in front and a back light behind the ball. Each picture gives
the ball one of Hall's terms alone (the floor and boxes stay as they are):

    k_a·I_a·F_d                  ambient                         (ka)
    k_d Σ I_j F_d (N·L_j)        diffuse                         (kd)
    k_s Σ I_j F_s (N·H_j)ⁿ       specular reflection of lights   (ks, n)
    k_t Σ I_j F_t (−N·H′_j)ⁿ′    specular transmission of lights (kt, n′: the back light's glow, §14)
    k_r·I_r·F_s·T_r^{d_r}        reflection of other surfaces    (kr: the reflected ray)
    k_t·I_t·F_t·T_t^{d_t}        transmission of other surfaces  (kt: the refracted ray)
    all together

then the falloff inside the ball (§15): T^d with T = (0.35, 0.6, 0.9) per unit
distance (the thick middle darkest, blue left), and Glassner's 1/(1 + a·d), a = 1.5.
Every picture is :func:`softpipe.tracers.whitted.raytrace_scene`: the local terms with
``max_depth=0`` (no secondary rays), the global ones to depth 5. kt drives both
transmission terms, so "transmission of other surfaces" is the depth-5 picture minus
the depth-0 one on the ball's pixels (the back light's lobe taken out). The colors
``ka``, ``kd``, ``ks``, ``kt``, ``kr`` are Hall's products k·F (RGB).
"""
import sys

import numpy as np
from common import REPO, checkerboard, picture_size, save_docs_sheet, save_sheet

from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_y, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import primary_visibility, raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "hall"
BACKGROUND = (0.3, 0.42, 0.6, 1.0)
CAMERA = Camera(eye=(0.0, 1.6, 4.8), target=(0.0, 0.6, -0.2), fovy=38.0)
LIGHT_TILE = Material(ka=0.25, kd=(0.85, 0.85, 0.8), ks=0.0)
DARK_TILE = Material(ka=0.25, kd=(0.25, 0.3, 0.38), ks=0.0)
RED = Material(ka=0.2, kd=(0.8, 0.15, 0.1), ks=0.2, shininess=20.0)
BLUE = Material(ka=0.2, kd=(0.15, 0.35, 0.85), ks=0.2, shininess=20.0)
NONE = dict(ka=0.0, kd=0.0, ks=0.0, kr=0.0, kt=0.0)
GLASS = dict(ior="glass", transmission_shininess=12.0)

#: (label, the ball's material, max_depth): Hall's terms one by one, then all, then the falloff forms.
TERMS = (
    ("ambient ka·Ia", Material(**{**NONE, "ka": (0.6, 0.75, 1.0)}), 0),
    ("diffuse kd·I·(N·L)", Material(**{**NONE, "kd": (0.3, 0.5, 0.85)}), 0),
    ("spec. reflection of lights ks·I·(N·H)^n", Material(**{**NONE, "ks": 0.9}, shininess=60.0), 0),
    ("spec. transmission of lights kt·I·(-N·H')^n'", Material(**{**NONE, "kt": 0.9}, **GLASS), 0),
    ("reflection of surfaces kr·Ir·T^d", Material(**{**NONE, "kr": 0.85}), 5),
    ("transmission of surfaces kt·It·T^d", Material(**{**NONE, "kt": 0.9}, **GLASS), 5),
    ("all together", Material(ka=0.03, kd=0.04, ks=0.8, shininess=60.0, kr=0.12, kt=0.85, **GLASS), 5),
    ("falloff T^d, T = (0.35, 0.6, 0.9)",
     Material(ka=0.03, kd=0.04, ks=0.8, shininess=60.0, kr=0.12, kt=0.85, **GLASS, transmittance=(0.35, 0.6, 0.9)),
     5),
    ("Glassner 1/(1 + a·d), a = 1.5",
     Material(ka=0.03, kd=0.04, ks=0.8, shininess=60.0, kr=0.12, kt=0.85, **GLASS, falloff="glassner",
              falloff_a=1.5), 5),
)
GLOBAL_TRANSMISSION = "transmission of surfaces kt·It·T^d"


def scene(ball: Material, size) -> Scene:
    """The ball (``hall``) of material ``ball`` on the checkered floor between a red and a blue box."""
    width, height = picture_size(size)
    light_tiles, dark_tiles = checkerboard(10.0, 10, LIGHT_TILE, DARK_TILE)
    objects = [SceneObject("floor, light tiles", light_tiles, np.eye(4), cast_shadows=False),
               SceneObject("floor, dark tiles", dark_tiles, np.eye(4), cast_shadows=False),
               SceneObject("ball", shapes.uv_sphere(0.7, 64, 32, material=ball), translate(0.0, 0.7, 0.0),
                           program="hall"),
               SceneObject("red box", shapes.cube(0.8, material=RED), translate(-1.3, 0.4, -1.2) @ rotate_y(25.0)),
               SceneObject("blue box", shapes.cube(0.7, material=BLUE), translate(1.2, 0.35, -0.6) @ rotate_y(-20.0))]
    lights = (Light.point((-2.5, 3.5, 3.0), diffuse=0.9, specular=1.0, name="key"),
              Light.point((0.25, 1.0, -3.5), diffuse=0.5, specular=1.0, name="back"))
    return Scene(objects, camera=CAMERA, lights=lights, ambient=(0.35, 0.35, 0.35), width=width, height=height,
                 background=BACKGROUND, program="phong")


def sheet(size=200):
    """The nine pictures of :data:`TERMS`, in order."""
    pictures = {}
    for label, material, depth in TERMS:
        s = scene(material, size)
        color = raytrace_scene(s, max_depth=depth).color[..., :3]
        if label == GLOBAL_TRANSMISSION:                         # the global term alone: minus the local lobe
            obj, _, _ = primary_visibility(s)
            local = raytrace_scene(s, max_depth=0).color[..., :3]
            on_ball = (obj == 2)[..., None]
            color = np.where(on_ball, color - local, color)
        pictures[label] = np.round(255 * np.clip(color, 0.0, 1.0)).astype(np.uint8)
    return pictures


def write_docs_pictures(size=200):
    """docs/images/hall/terms.png: the nine pictures, three to a row."""
    save_docs_sheet(DOCS_IMAGES / "terms.png", sheet(size), 3)


def main(size=200, out_dir=None):
    return save_sheet("hall", sheet(size), 3, "Hall's terms one by one on one ball, ray traced; the falloff T^d and "
                      "Glassner's (FORMULAS 13-15)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
