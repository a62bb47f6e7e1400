"""The default scene of ``softpipe demo`` / ``make demo``: a lit scene, Phong shading.

The Utah teapot and the Stanford bunny (bundled with softpipe, :mod:`softpipe.scenes.models`),
a sphere and a torus on a ground plane, lit by three kinds of light (FORMULAS §9):

* a directional "sun", warm, from the upper left;
* a bluish point light on the right, attenuated with distance (§7);
* a white spot light above the teapot, with a soft edge (cutoff 28°, exponent 6, §8);

and OpenGL's global ambient. Every object is shaded per fragment with the
``phong`` program (normals interpolated, Blinn-Phong, FORMULAS §10, §12). All three
lights cast shadows (shadow maps, :mod:`softpipe.scenes.shadow_pass`: the sun's orthographic
map, the spot's perspective one and the lamp's cube map); the ground receives them
and casts none. ``render_demo(shadows=False)`` (``softpipe demo --no-shadows``) is the
same scene with every light reaching every point.
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from typing import List, Tuple

import numpy as np

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.transforms import compose, rotate_x, rotate_y, scale, translate
from softpipe.programs import cook_torrance, flat, gooch, gouraud, hall, phong, textured  # noqa: F401  (register)
from softpipe.programs.common import lighting_uniform
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.models import load_model
from softpipe.scenes.scene import SceneObject
from softpipe.scenes.shadow_pass import render_shadow_maps

__all__ = ["render_demo", "demo_camera", "demo_lighting", "demo_objects"]

GROUND = Material(ka=(0.1, 0.1, 0.1), kd=(0.55, 0.56, 0.52), ks=(0.12, 0.12, 0.12), shininess=12.0, name="ground")
PORCELAIN = Material(ka=(0.1, 0.1, 0.1), kd=(0.78, 0.76, 0.7), ks=(0.5, 0.5, 0.5), shininess=60.0, name="porcelain")
CLAY = Material(ka=(0.1, 0.08, 0.06), kd=(0.72, 0.5, 0.32), ks=(0.15, 0.15, 0.15), shininess=10.0, name="clay")
RED_PLASTIC = Material(ka=(0.1, 0.02, 0.02), kd=(0.7, 0.1, 0.08), ks=(0.35, 0.35, 0.35), shininess=40.0,
                       name="red plastic")
GOLD = Material(ka=(0.06, 0.05, 0.02), kd=(0.2, 0.15, 0.05), ks=(0.75, 0.6, 0.25), shininess=70.0, name="gold")


def demo_camera() -> Camera:
    return Camera(eye=(0.0, 2.4, 6.4), target=(0.0, 0.55, 0.0), fovy=38.0, near=0.5, far=40.0)


def demo_lighting() -> Lighting:
    """A sun, a point light and a spot light, and OpenGL's global ambient."""
    return Lighting([
        Light.directional((0.6, -1.0, -0.5), diffuse=(0.75, 0.68, 0.55), specular=(0.8, 0.75, 0.6), name="sun"),
        Light.point((2.6, 1.6, 1.8), diffuse=(0.35, 0.45, 0.8), specular=(0.5, 0.6, 1.0),
                    attenuation=(1.0, 0.1, 0.08), name="blue lamp"),
        Light.spot((-0.3, 4.0, 0.9), (0.15, -1.0, -0.25), cutoff=28.0, exponent=6.0,
                   diffuse=(0.9, 0.9, 0.85), specular=(1.0, 1.0, 1.0), name="spot"),
    ], global_ambient=(0.12, 0.12, 0.14))


def _smooth_normals(mesh: Mesh) -> Mesh:
    """Vertex normals shared by all vertices at one position (the teapot's seams are not welded)."""
    _, key = np.unique(mesh.positions, axis=0, return_inverse=True)
    key = key.ravel()
    face = mesh.face_normals(normalized=False)
    acc = np.zeros((key.max() + 1, 3))
    for c in range(3):
        np.add.at(acc, key[mesh.indices[:, c]], face)
    n = acc[key]
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return mesh.replace(normals=np.divide(n, length, out=np.tile([0.0, 1.0, 0.0], (len(n), 1)), where=length > 0))


@lru_cache(maxsize=4)
def _model(name: str, height: float) -> Mesh:
    """A bundled model standing on y = 0, ``height`` tall, centred on the y axis."""
    mesh = load_model(name)
    lo, hi = mesh.bounds()
    s = height / (hi[1] - lo[1])
    centre = (lo + hi) / 2
    mesh = mesh.transformed(compose(scale(s), translate(-centre[0], -lo[1], -centre[2])))
    return _smooth_normals(mesh)


def demo_objects() -> List[Tuple[Mesh, np.ndarray]]:
    """(mesh with its material, model matrix) for every object of the scene."""
    objects = [(shapes.plane(size=14.0, subdivisions=4, material=GROUND), translate(0.0, 0.0, 0.0))]
    teapot = _model("teapot", 1.2)
    objects.append((teapot.replace(material=PORCELAIN), compose(translate(-0.3, 0.0, 0.2), rotate_y(-25.0))))
    bunny = _model("bunny", 1.3)
    objects.append((bunny.replace(material=CLAY), compose(translate(-2.2, 0.0, -0.6), rotate_y(25.0))))
    objects.append((shapes.uv_sphere(radius=0.55, segments=48, rings=24, material=RED_PLASTIC),
                    translate(2.0, 0.55, -0.4)))
    objects.append((shapes.torus(major_radius=0.42, minor_radius=0.15, material=GOLD),
                    compose(translate(1.05, 0.36, 1.7), rotate_y(-30.0), rotate_x(55.0))))
    return objects


def render_demo(width: int = 640, height: int = 480, program: str = "phong", shadows: bool = True) -> Framebuffer:
    """Render the default scene into a new framebuffer (with every light's shadows unless ``shadows`` is False)."""
    fb = Framebuffer(width, height)
    fb.clear((0.05, 0.06, 0.09, 1.0))
    camera = demo_camera()
    lights = demo_lighting()
    if shadows:
        lights = Lighting([dataclasses.replace(light, shadows=True) for light in lights.lights],
                          global_ambient=lights.global_ambient)
        casters = [SceneObject(mesh.name, mesh, model, cast_shadows=k > 0)      # the ground (first) casts none
                   for k, (mesh, model) in enumerate(demo_objects())]
        lighting = render_shadow_maps(casters, lights).lighting_uniform(lights, camera.view)
    else:
        lighting = lighting_uniform(lights, camera.view)  # in eye space once, for every draw
    for mesh, model in demo_objects():
        draw_mesh(fb, mesh, camera, program, model=model, lighting=lighting)
    return fb
