"""Cook-Torrance and Gooch on the Stanford bunny and the Utah teapot (FORMULAS §26).

    python examples/cook_torrance_gooch.py   → out/examples/cook_torrance_gooch.png

Columns: Blinn-Phong for reference (``phong``); Cook-Torrance (``cook_torrance``:
Beckmann D, the geometry term G, exact Fresnel F) for a smooth dielectric
(m = 0.15, index of refraction 1.5: F ≈ 0.04 head-on, rising toward grazing
angles) and a rougher, metal-like surface (m = 0.35, a large real index, 10,
standing in for a metal's complex one: F ≈ 0.67); Gooch's cool-to-warm tones
(``gooch``) with a silhouette rim, on a light background as in the paper.
The meshes are the models bundled with softpipe (:mod:`softpipe.scenes.models`).

Gooch's columns take the paper's set-up (Gooch et al. 1998, §4.2 and Figures 2, 5, 7):
b = 0.4, y = 0.4, α = 0.2, β = 0.6 (the program's defaults), the light perpendicular
to the gaze, up and to the right ("to ensure the image shows this full variation"
of N·L over [−1, 1]: a light from the viewer's side would leave most of the object
warm), and two object colors: the paper's neutral gray (k_d = 0.5, its Figure 5),
k_cool = (0.1, 0.1, 0.5) to k_warm = (0.7, 0.7, 0.3); and the pure red of its Figure 2,
k_cool = (0.2, 0, 0.4) to k_warm = (1, 0.4, 0).
"""
import numpy as np
from common import image, key_light, load_asset, render, save_sheet

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera

BASE = dict(ka=(0.06, 0.05, 0.05), kd=(0.55, 0.45, 0.4), ks=(0.9, 0.9, 0.9))
COLUMNS = (
    ("Blinn-Phong n=40", "phong", Material(**BASE, shininess=40.0), {}),
    ("Cook-Torrance m=0.15 ior 1.5", "cook_torrance", Material(**BASE, ior=1.5, roughness=0.15), {}),
    ("Cook-Torrance m=0.35 ior 10", "cook_torrance", Material(**BASE, ior=10.0, roughness=0.35), {}),
    ("Gooch, gray kd 0.5", "gooch", Material(kd=(0.5, 0.5, 0.5)), {"gooch_outline": 0.3}),   # the paper's Fig. 5
    ("Gooch, red kd (1, 0, 0)", "gooch", Material(kd=(1.0, 0.0, 0.0)), {"gooch_outline": 0.3}),   # its Fig. 2
)
MODELS = (("bunny", 20.0, 10.0), ("teapot", 25.0, 20.0))   # softpipe.scenes.models names


def side_light(camera: Camera) -> Lighting:
    """The paper's light for tone shading: perpendicular to the gaze, from the upper right (world space)."""
    right, up = camera.view[0, :3], camera.view[1, :3]          # the camera's axes, as rows of its rotation
    toward_light = (right + up) / np.linalg.norm(right + up)
    return Lighting([Light.directional(tuple(-toward_light))], global_ambient=(0.0, 0.0, 0.0))


def sheet(size=(200, 170)):
    pictures = {}
    for model_name, azimuth, elevation in MODELS:
        mesh = load_asset(model_name)
        camera = Camera.frame(mesh, azimuth=azimuth, elevation=elevation, fovy=30.0, margin=0.78,
                              aspect=size[0] / size[1])
        for label, program, material, extra in COLUMNS:
            gooch = program == "gooch"
            background = (0.92, 0.92, 0.9, 1.0) if gooch else (0.06, 0.07, 0.09, 1.0)
            lighting = side_light(camera) if gooch else key_light()
            fb = render(mesh, camera, program, lighting, size, uniforms={"material": material, **extra},
                        background=background)
            pictures[f"{model_name}: {label}"] = image(fb)
    return pictures


def main(size=(200, 170), out_dir=None):
    return save_sheet("cook_torrance_gooch", sheet(size), 5,
                      "Blinn-Phong, Cook-Torrance and Gooch on the Stanford bunny and the Utah teapot (FORMULAS 26)",
                      out_dir)


if __name__ == "__main__":
    main()
