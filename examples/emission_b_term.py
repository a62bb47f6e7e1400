"""Emission (k_e) and the B term: a light sinking below the horizon (FORMULAS §1, §3, §4, §10, §11).

    python examples/emission_b_term.py       → out/examples/emission_b_term.png
    python examples/emission_b_term.py --docs → also docs/images/hall/emission.png, b_term.png

Row 1, emission (§1, I = k_e, added to §10's sum): a ball with k_e only and no
light is a flat disc of k_e — emission has no direction; the same k_e on a lit
ball adds a constant glow to its shading; an emitting ball over a floor in the
dark lights nothing around it (k_e is the surface's own color, not a light).

Rows 2–3, the B term (§3, §4): a floor and a ball under a sun whose elevation goes
40°, 15°, 3°, 0°, −3°, −20° (it travels toward −x, seen from the front). The floor's
N·L = sin(elevation): at 3° it is lit a little (N·L = 0.05), at 0° N·L = 0 and the
floor goes dark exactly then — B = 0 for N·L ≤ 0, only the ambient term is left —
and stays dark below; on the ball the terminator is where N·L crosses 0.

Row 4, §11's two-sided form (program ``two_sided``) under the same sun at 15°, 0° and
−20°: with |N·L| a light below the horizon lights the floor as much as one the same
angle above it (there is no B in §11).

All rasterized (``softpipe.render_scene``), program ``phong`` (§10) but for row 4.
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

DOCS_IMAGES = REPO / "docs" / "images" / "hall"
CAMERA = Camera(eye=(0.0, 2.2, 5.0), target=(0.0, 0.5, 0.0), fovy=40.0)
FLOOR = Material(ka=0.15, kd=(0.75, 0.72, 0.65), ks=0.1, shininess=10.0)
BALL = Material(ka=0.15, kd=(0.25, 0.5, 0.85), ks=0.5, shininess=40.0)
GLOW = (0.9, 0.55, 0.15)
ELEVATIONS = (40.0, 15.0, 3.0, 0.0, -3.0, -20.0)
TWO_SIDED_ELEVATIONS = (15.0, 0.0, -20.0)
BACKGROUND = (0.06, 0.07, 0.09, 1.0)


def sun(elevation):
    """A directional light at ``elevation`` degrees above the horizon (negative: below), travelling toward −x."""
    e = np.radians(elevation)
    direction = (-np.cos(e), -np.sin(e), -0.25)                # the light travels down (or up) and a little back
    if elevation == 0.0:
        direction = (-1.0, 0.0, -0.25)                         # exactly in the floor's plane: N·L = 0
    return Light.directional(direction, name=f"sun {elevation:g}°")


def scene(objects, lights, size, ambient=(0.2, 0.2, 0.2), program="phong"):
    width, height = picture_size(size)
    return Scene(objects, camera=CAMERA, lights=tuple(lights), ambient=ambient, width=width, height=height,
                 background=BACKGROUND, program=program, cull="none")


def floor_and_ball(ball=BALL):
    return [SceneObject("floor", shapes.plane(8.0, material=FLOOR), np.eye(4)),
            SceneObject("ball", shapes.uv_sphere(0.6, 48, 24, material=ball), translate(0.0, 0.6, 0.0))]


def picture(s):
    return sp.render_scene(s).to_uint8(alpha=False)


def emission(size):
    """Row 1: k_e alone (no light); k_e on a lit ball; an emitting ball in the dark lights nothing."""
    glowing = Material(ke=GLOW, ka=0.0, kd=0.0, ks=0.0)
    ball = [SceneObject("ball", shapes.uv_sphere(0.6, 48, 24, material=glowing), translate(0.0, 0.6, 0.0))]
    key = Light.directional((1.0, -1.0, -1.2), name="key")
    lit = floor_and_ball(BALL.replace(ke=tuple(0.5 * np.array(GLOW))))
    return {"k_e alone, no light: a flat disc": picture(scene(ball, (), size, ambient=(0, 0, 0))),
            "k_e + lit (glow added to (10))": picture(scene(lit, (key,), size)),
            "emitting ball in the dark: lights nothing": picture(scene(floor_and_ball(glowing), (), size,
                                                                        ambient=(0.05, 0.05, 0.05)))}


def b_term(size):
    """Rows 2–3: the sun at each of :data:`ELEVATIONS`, the floor's N·L = sin(elevation) in the label."""
    out = {}
    for e in ELEVATIONS:
        n_dot_l = 0.0 if e == 0.0 else float(np.sin(np.radians(e)))
        out[f"sun {e:+g}°: floor N·L = {n_dot_l:+.2f}"] = picture(scene(floor_and_ball(), (sun(e),), size))
    return out


def two_sided(size):
    """Row 4: §11's |N·L| under the same sun: lit from below as from above."""
    return {f"(11) two-sided, sun {e:+g}°": picture(scene(floor_and_ball(), (sun(e),), size, program="two_sided"))
            for e in TWO_SIDED_ELEVATIONS}


def sheet(size=200):
    return {**emission(size), **b_term(size), **two_sided(size)}


def write_docs_pictures(size=200):
    """docs/images/hall/emission.png (row 1) and b_term.png (rows 2–4)."""
    for name, pictures in (("emission.png", emission(size)), ("b_term.png", {**b_term(size), **two_sided(size)})):
        save_docs_sheet(DOCS_IMAGES / name, pictures, 3)


def main(size=200, out_dir=None):
    return save_sheet("emission_b_term", sheet(size), 3, "Emission k_e; the B term as the sun sets (N·L crosses 0); "
                      "(11)'s two-sided |N·L| (FORMULAS 1, 4, 10, 11)", out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
