"""Antialiasing: the same scene with 1, 4, 4, 16 samples per pixel and with MSAA 4× (FORMULAS §23, §24).

    python examples/antialiasing.py          → out/examples/antialiasing.png

Top row, the whole picture; bottom row, the same edge zoomed so the pixels show.

* 1 sample at the pixel centre (§23): stair steps.
* 4 samples on a regular 2×2 grid (§24, ``softpipe.pipeline.sampling.grid(2)``), every
  sample shaded and the pixel their average: supersampling (SSAA).
* 4 samples on the rotated grid (``rotated_grid_4x()``): the same cost, but
  near-horizontal and near-vertical edges get 4 coverage levels instead of 2.
* 16 jittered samples (``jittered(4)``): one at random in each cell of a 4×4 grid.
* MSAA 4×: the rotated-grid framebuffer, but the fragment shader runs once per
  pixel and triangle, at the pixel centre (``sample_shading="center"``); the
  coverage of the 4 samples still decides how much of that color each pixel gets.

The time each took (after a first, compiling, run) is printed; the benchmark
harness (``make bench``) measures the modes properly.
"""
import time

import numpy as np
from common import image, key_light, render, save_sheet, zoom

import softpipe as sp
from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.sampling import CENTER, grid, jittered, rotated_grid_4x
from softpipe.pipeline.transforms import compose, rotate_x, rotate_y, translate
from softpipe.scenes import shapes

MODES = (("1 sample", CENTER, "sample"),
         ("4 grid SSAA", grid(2), "sample"),
         ("4 rotated SSAA", rotated_grid_4x(), "sample"),
         ("16 jittered SSAA", jittered(4), "sample"),
         ("MSAA 4x (rotated)", rotated_grid_4x(), "center"))
FLOOR = Material(ka=0.1, kd=(0.55, 0.55, 0.6), ks=0.1, shininess=8.0)
CUBE = Material(ka=0.1, kd=(0.9, 0.85, 0.8), ks=0.3, shininess=30.0)
BALL = Material(ka=0.1, kd=(0.8, 0.2, 0.1), ks=0.5, shininess=40.0)
CUBE_MODEL = compose(translate(-0.5, 0.55, 0.0), rotate_y(25.0), rotate_x(12.0))
CAMERA = Camera(eye=(0.0, 1.6, 4.2), target=(0.0, 0.4, 0.0), fovy=38.0)


def scene():
    return [(shapes.plane(size=12.0, material=FLOOR), None, "phong"),
            (shapes.cube(size=1.0, material=CUBE), CUBE_MODEL, "phong"),
            (shapes.uv_sphere(radius=0.5, segments=48, rings=24, material=BALL), translate(0.9, 0.5, 0.3), "phong")]


def window_point(point, size):
    """Where a world point lands in the image (column, row from the top)."""
    w, h = size
    clip = CAMERA.projection(w / h) @ CAMERA.view @ np.append(point, 1.0)
    ndc = clip[:3] / clip[3]
    return (ndc[0] + 1) / 2 * w, (1 - ndc[1]) / 2 * h


def sheet(size=(240, 180), crop=None, timings=None):
    w, h = size
    crop = crop or (max(2, w // 6), max(2, h // 6))
    # the crop: around the top front edge of the cube, against the background
    corner = (CUBE_MODEL @ np.array([0.5, 0.5, 0.5, 1.0]))[:3]
    cx, cy = window_point(corner, size)
    x0 = int(np.clip(cx - crop[0] / 2, 0, w - crop[0]))
    y0 = int(np.clip(cy - crop[1] / 2, 0, h - crop[1]))
    factor = max(1, min(w // crop[0], h // crop[1]))
    full, zoomed = {}, {}
    for label, pattern, shading in MODES:
        for _ in range(2 if timings is not None else 1):    # the first time compiles the shaders
            fb = sp.Framebuffer(w, h, pattern=pattern)
            fb.clear((0.06, 0.07, 0.09, 1.0))
            start = time.perf_counter()
            render(scene(), CAMERA, lighting=key_light(), fb=fb, sample_shading=shading)
            seconds = time.perf_counter() - start
        if timings is not None:
            timings[label] = seconds
        picture = image(fb)
        full[label] = picture
        big = zoom(picture[y0:y0 + crop[1], x0:x0 + crop[0]], factor)
        canvas = np.zeros_like(picture)
        canvas[:big.shape[0], :big.shape[1]] = big
        zoomed[f"{label}, zoomed x{factor}"] = canvas
    return {**full, **zoomed}


def main(size=(240, 180), out_dir=None):
    timings = {}
    pictures = sheet(size, timings=timings)
    for label, seconds in timings.items():
        print(f"{label:>20}: {seconds * 1000:7.1f} ms")
    return save_sheet("antialiasing", pictures, 5,
                      "Antialiasing: 1, 4 (grid), 4 (rotated), 16 (jittered) samples, MSAA 4x; edge zoomed below",
                      out_dir)


if __name__ == "__main__":
    main()
