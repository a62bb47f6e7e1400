"""Spotlight cutoff and exponent sweeps (FORMULAS §8).

    python examples/spotlight.py             → out/examples/spotlight.png

A spot above a floor, pointing straight down: f_spot = (−L·S)ᵉ inside the cone
−L·S ≥ cos β, else 0. Top row: the cutoff β from 10° to 60° with e = 0 (a hard
edge). Bottom row: the exponent e from 0 to 128 with β = 45°: the light falls
off toward the edge, and a large e leaves only a bright core.
"""
from common import image, render, save_sheet

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes

CUTOFFS = (10.0, 20.0, 30.0, 45.0, 60.0)
EXPONENTS = (0.0, 4.0, 16.0, 48.0, 128.0)
FLOOR = Material(ka=0.1, kd=(0.75, 0.72, 0.68), ks=0.15, shininess=10.0)
BALL = Material(ka=0.1, kd=(0.7, 0.2, 0.15), ks=0.5, shininess=40.0)


def scene():
    return [(shapes.plane(size=8.0, material=FLOOR), None, "phong"),
            (shapes.uv_sphere(radius=0.35, segments=32, rings=16, material=BALL), translate(0.5, 0.35, 0.3), "phong")]


def sheet(size=150):
    camera = Camera(eye=(0.0, 3.2, 3.4), target=(0.0, 0.0, 0.0), fovy=45.0)
    pictures = {}
    for label, settings in (("cutoff", [(b, 0.0) for b in CUTOFFS]), ("exponent", [(45.0, e) for e in EXPONENTS])):
        for cutoff, exponent in settings:
            spot = Light.spot((0.0, 2.0, 0.0), (0.0, -1.0, 0.0), cutoff, exponent)
            lighting = Lighting([spot], global_ambient=(0.1, 0.1, 0.1))
            name = f"cutoff {cutoff:.0f} deg, e = 0" if label == "cutoff" else f"e = {exponent:.0f}, cutoff 45 deg"
            pictures[name] = image(render(scene(), camera, lighting=lighting, size=(size, size)))
    return pictures


def main(size=150, out_dir=None):
    return save_sheet("spotlight", sheet(size), 5, "Spotlight: cutoff sweep (top), exponent sweep (bottom) "
                      "(FORMULAS 8)", out_dir)


if __name__ == "__main__":
    main()
