"""A shininess sweep: the specular exponent n from 1 to 200 (FORMULAS §6, §10).

    python examples/shininess.py             → out/examples/shininess.png

Blinn-Phong, one light; the highlight shrinks and sharpens as n grows, while its
peak ks·I_s stays the same. n = 0 is left out: (N·H)⁰ = 1 lights the whole lit
side with ks (the notes' "planet" uses it with ks = 0).
"""
from common import image, key_light, render, save_sheet

from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes

SHININESS = (1, 3, 8, 16, 32, 64, 128, 200)


def sheet(size=140):
    camera = Camera(eye=(0.0, 0.0, 3.4), fovy=38.0)
    sphere = shapes.uv_sphere(segments=64, rings=32)
    pictures = {}
    for n in SHININESS:
        m = Material(ka=(0.1, 0.1, 0.1), kd=(0.1, 0.25, 0.55), ks=(0.6, 0.6, 0.6), shininess=float(n))
        pictures[f"n = {n}"] = image(render(sphere, camera, "phong", key_light(), (size, size),
                                            uniforms={"material": m}))
    return pictures


def main(size=140, out_dir=None):
    return save_sheet("shininess", sheet(size), 4, "Shininess sweep, Blinn-Phong (FORMULAS 6, 10)", out_dir)


if __name__ == "__main__":
    main()
