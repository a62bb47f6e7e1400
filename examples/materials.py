"""The notes' material table: metal, plastic and planet (FORMULAS §10).

    python examples/materials.py             → out/examples/materials.png

The suggestions of the notes, with k_a + k_d + k_s < 1 and k_a ≈ 0.1:

* metal — large n, small k_d in the metal's color, large k_s in the metal's color;
* plastic — medium n, k_d the plastic's color, medium white k_s;
* planet — n = 0, varying k_d, k_s = 0: the ``textured`` program, whose texture
  (made here from a few lines of numpy) scales k_d across the surface.

Blinn-Phong per fragment (``phong``), lit by a key, a fill and a rim light.
"""
import numpy as np
from common import image, render, save_sheet, studio_lighting

from softpipe.light.material import Material
from softpipe.light.texture import Texture2D
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes


def metal(color, n=50.0):
    c = np.asarray(color)
    return Material(ka=tuple(0.05 * c), kd=tuple(0.1 * c), ks=tuple(0.84 * c), shininess=n)


def plastic(color, n=24.0):
    c = np.asarray(color)
    return Material(ka=tuple(0.1 * c), kd=tuple(0.55 * c), ks=(0.3, 0.3, 0.3), shininess=n)


METALS = {"gold": metal((1.0, 0.78, 0.34)), "silver": metal((0.95, 0.95, 0.97), 70.0),
          "copper": metal((0.95, 0.55, 0.38), 40.0), "bronze": metal((0.8, 0.6, 0.35), 25.0)}
PLASTICS = {"red plastic": plastic((0.9, 0.12, 0.1)), "green plastic": plastic((0.15, 0.75, 0.25)),
            "blue plastic": plastic((0.15, 0.3, 0.95), 40.0), "white plastic": plastic((0.95, 0.95, 0.92), 12.0)}
PLANET = Material(ka=(0.1, 0.1, 0.1), kd=(0.9, 0.9, 0.9), ks=(0.0, 0.0, 0.0), shininess=0.0)


def _noise(shape, octaves, seed):
    """Smooth value noise in [0, 1] that wraps around in u (columns)."""
    rng = np.random.default_rng(seed)
    h, w = shape
    total = np.zeros(shape)
    for k in range(octaves):
        cells = 6 * 2 ** k
        grid = rng.random((cells // 2 + 2, cells + 1))
        grid[:, -1] = grid[:, 0]
        y = np.linspace(0, cells // 2, h)[:, None]
        x = np.linspace(0, cells, w)[None, :]
        y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int) % cells
        fy, fx = y - np.floor(y), x - np.floor(x)
        fy, fx = fy * fy * (3 - 2 * fy), fx * fx * (3 - 2 * fx)
        top = grid[y0, x0] * (1 - fx) + grid[y0, x0 + 1] * fx
        bottom = grid[y0 + 1, x0] * (1 - fx) + grid[y0 + 1, x0 + 1] * fx
        total += (top * (1 - fy) + bottom * fy) / 1.7 ** k
    return (total - total.min()) / (total.max() - total.min())


def planet_textures(width=256, height=128):
    """Four planets' k_d maps as float RGB images (row 0 = north pole)."""
    lat = np.linspace(1, -1, height)[:, None] * np.ones((1, width))
    n = _noise((height, width), 5, 1)
    earth = np.where((n > np.quantile(n, 0.6))[..., None], np.array([0.35, 0.55, 0.2]) * (0.7 + 0.6 * n[..., None]),
                     np.array([0.05, 0.2, 0.55]) * (0.8 + 0.4 * n[..., None]))
    ice = np.abs(lat) > 0.85 - 0.1 * n
    earth[ice] = 0.95
    m = _noise((height, width), 5, 7)
    mars = np.array([0.75, 0.35, 0.15]) * (0.55 + 0.6 * m[..., None])
    bands = 0.5 + 0.5 * np.sin(lat * 14 + 2.5 * _noise((height, width), 3, 3))
    jupiter = np.array([0.85, 0.75, 0.6]) * bands[..., None] + np.array([0.6, 0.35, 0.2]) * (1 - bands[..., None])
    g = _noise((height, width), 6, 11)
    moon = (0.55 + 0.3 * g - 0.2 * (g < np.quantile(g, 0.3)))[..., None] * np.ones(3)
    return {"earth (planet)": earth, "mars (planet)": mars, "gas giant (planet)": jupiter, "moon (planet)": moon}


def sheet(size=150):
    camera = Camera(eye=(0.0, 0.3, 3.4), fovy=38.0)
    sphere = shapes.uv_sphere(segments=64, rings=32)
    lighting = studio_lighting()
    pictures = {}
    for name, material in {**METALS, **PLASTICS}.items():
        pictures[name] = image(render(sphere, camera, "phong", lighting, (size, size), uniforms={"material": material}))
    for name, kd_map in planet_textures().items():
        texture = Texture2D(np.clip(kd_map, 0, 1).astype(np.float32), filter="trilinear", wrap_s="repeat",
                            wrap_t="clamp")
        pictures[name] = image(render(sphere, camera, "textured", lighting, (size, size),
                                      uniforms={"material": PLANET, "texture": texture}))
    return pictures


def main(size=150, out_dir=None):
    return save_sheet("materials", sheet(size), 4, "Materials from the notes: metal, plastic, planet "
                      "(FORMULAS 10)", out_dir)


if __name__ == "__main__":
    main()
