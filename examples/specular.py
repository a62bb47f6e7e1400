"""Phong vs Blinn-Phong highlights (FORMULAS §5, §6).

    python examples/specular.py              → out/examples/specular.png

Rows: Phong's (R·V)ⁿ with n = 30; Blinn-Phong's (N·H)ⁿ with the same n (a wider
highlight); Blinn-Phong with 4n = 120, which matches Phong's size (§6: "about 4×
Phong's exponent"). Columns: the light at 0°, 40° and 75° from the viewing
direction, and a floor lit at a grazing angle, where Blinn-Phong's highlight
stretches along the floor and Phong's stays round. Specular only, on a dark
diffuse, so that the lobes are what one sees.
"""
import math

from common import image, render, save_sheet

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes

ROWS = (("Phong n=30", "phong_phong_specular", 30.0),
        ("Blinn-Phong n=30", "phong", 30.0),
        ("Blinn-Phong n=120", "phong", 120.0))


def sheet(size=160):
    sphere_camera = Camera(eye=(0.0, 0.0, 3.4), fovy=38.0)
    floor_camera = Camera(eye=(0.0, 1.2, 4.0), target=(0.0, 0.0, -0.5), fovy=45.0)
    floor = shapes.plane(size=10.0)
    sphere = shapes.uv_sphere(segments=64, rings=32)
    pictures = {}
    for label, program, n in ROWS:
        m = Material(ka=0.05, kd=(0.12, 0.1, 0.2), ks=(0.9, 0.9, 0.9), shininess=n)
        for angle in (0.0, 40.0, 75.0):
            a = math.radians(angle)
            toward_light = (-math.sin(a) * 0.8, math.sin(a) * 0.6, math.cos(a))   # L, at `angle` from V
            lights = Lighting([Light.directional(tuple(-c for c in toward_light))], global_ambient=(0.2, 0.2, 0.2))
            fb = render(sphere, sphere_camera, program, lights, (size, size), uniforms={"material": m})
            pictures[f"{label}, light {angle:.0f} deg"] = image(fb)
        grazing = Lighting([Light.point((0.0, 0.35, -4.0), attenuation=(1.0, 0.0, 0.0))],
                           global_ambient=(0.2, 0.2, 0.2))
        fb = render(floor, floor_camera, program, grazing, (size, size), uniforms={"material": m})
        pictures[f"{label}, grazing floor"] = image(fb)
    return pictures


def main(size=160, out_dir=None):
    return save_sheet("specular", sheet(size), 4,
                      "Phong (R.V)^n vs Blinn-Phong (N.H)^n highlights (FORMULAS 5, 6)", out_dir)


if __name__ == "__main__":
    main()
