"""The default scene of ``softpipe demo`` / ``make demo``.

A sphere, a cube and a torus on a ground plane, seen in perspective, shaded by
the ``normals`` program (eye-space normal as color).
"""
from __future__ import annotations

from . import shapes
from .camera import Camera
from .framebuffer import Framebuffer
from .scene import draw_mesh
from .transforms import compose, rotate_x, rotate_y, translate

__all__ = ["render_demo", "demo_camera"]


def demo_camera() -> Camera:
    return Camera(eye=(0.0, 2.2, 6.0), target=(0.0, 0.4, 0.0), fovy=40.0, near=0.5, far=30.0)


def render_demo(width: int = 640, height: int = 480, program: str = "normals") -> Framebuffer:
    """Render the default scene into a new framebuffer."""
    fb = Framebuffer(width, height)
    fb.clear((0.08, 0.09, 0.12, 1.0))
    camera = demo_camera()
    objects = [
        (shapes.plane(size=8.0, subdivisions=8), translate(0.0, -0.6, 0.0)),
        (shapes.uv_sphere(radius=0.8, segments=48, rings=24), translate(-1.6, 0.2, 0.0)),
        (shapes.cube(size=1.1), compose(translate(0.2, -0.05, -0.8), rotate_y(30))),
        (shapes.torus(major_radius=0.65, minor_radius=0.25), compose(translate(1.7, 0.1, 0.3), rotate_x(60))),
    ]
    for mesh, model in objects:
        draw_mesh(fb, mesh, camera, program, model=model)
    return fb
