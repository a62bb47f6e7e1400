"""Faceted vs Gouraud vs Phong shading on a coarse and a fine sphere (FORMULAS §12).

    python examples/shading_models.py        → out/examples/shading_models.png

Columns: ``flat`` (one normal, one color per face: drawn on ``mesh.flat_shaded()``),
``gouraud`` (lit per vertex, colors interpolated), ``phong`` (normals interpolated,
lit per fragment). On the coarse sphere Gouraud smears the highlight into the
triangles' shape, or misses it; Phong keeps it round. On the fine sphere the
three converge, and only the facets of flat shading remain visible.
"""
from common import image, key_light, render, save_sheet

from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes

PLASTIC = Material(ka=(0.1, 0.03, 0.03), kd=(0.65, 0.12, 0.1), ks=(0.35, 0.35, 0.35), shininess=40.0)


def sheet(size=200):
    camera = Camera(eye=(0.0, 0.0, 3.4), fovy=38.0)
    pictures = {}
    for label, sphere in (("coarse (12x6)", shapes.uv_sphere(segments=12, rings=6, material=PLASTIC)),
                          ("fine (64x32)", shapes.uv_sphere(segments=64, rings=32, material=PLASTIC))):
        for program in ("flat", "gouraud", "phong"):
            mesh = sphere.flat_shaded() if program == "flat" else sphere
            fb = render(mesh, camera, program, key_light(), (size, size))
            pictures[f"{program}, {label}"] = image(fb)
    return pictures


def main(size=200, out_dir=None):
    return save_sheet("shading_models", sheet(size), 3,
                      "Flat vs Gouraud vs Phong shading (FORMULAS 12), Blinn-Phong lighting", out_dir)


if __name__ == "__main__":
    main()
