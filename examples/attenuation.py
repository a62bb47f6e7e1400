"""An attenuation sweep: f_att = 1/(a + b·r + c·r²) (FORMULAS §7).

    python examples/attenuation.py           → out/examples/attenuation.png

A point light above and in front of the left end of a row of spheres on a
floor; the spheres are farther from it from left to right. Top row: linear b from 0 to 2 (a = 1,
c = 0). Bottom row: quadratic c from 0 to 2 (a = 1, b = 0), ending with the
physical 1/r² (a = b = 0, c = 1). The diffuse color of the light is scaled in
each picture so that a surface at r = 1 facing the light gets the same light.
"""
from common import image, render, save_sheet

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes

LINEAR = ((1, 0, 0), (1, 0.25, 0), (1, 0.5, 0), (1, 1, 0), (1, 2, 0))
QUADRATIC = ((1, 0, 0.1), (1, 0, 0.25), (1, 0, 0.5), (1, 0, 2), (0, 0, 1))
FLOOR = Material(ka=0.1, kd=(0.6, 0.6, 0.6), ks=0.0)
BALL = Material(ka=0.1, kd=(0.2, 0.45, 0.8), ks=0.4, shininess=30.0)
LIGHT_AT = (-2.6, 1.0, 1.0)


def scene():
    parts = [(shapes.plane(size=30.0, material=FLOOR), None, "phong")]
    ball = shapes.uv_sphere(radius=0.42, segments=32, rings=16, material=BALL)
    for r in (1.0, 2.0, 3.0, 4.0):
        parts.append((ball, translate(LIGHT_AT[0] + 1.2 * r, 0.42, 0.0), "phong"))
    return parts


def sheet(size=(190, 120)):
    camera = Camera(eye=(0.0, 2.6, 4.6), target=(0.0, 0.0, 0.0), fovy=40.0)
    pictures = {}
    for a, b, c in LINEAR + QUADRATIC:
        at_one = a + b + c                                   # 1/f_att at r = 1
        light = Light.point(LIGHT_AT, diffuse=at_one, specular=at_one, attenuation=(a, b, c))
        lighting = Lighting([light], global_ambient=(0.05, 0.05, 0.05))
        pictures[f"a={a} b={b} c={c}"] = image(render(scene(), camera, lighting=lighting, size=size))
    return pictures


def main(size=(190, 120), out_dir=None):
    return save_sheet("attenuation", sheet(size), 5,
                      "Attenuation 1/(a + b r + c r^2): linear (top) and quadratic (bottom) (FORMULAS 7)", out_dir)


if __name__ == "__main__":
    main()
