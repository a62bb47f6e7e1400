"""Environment maps from the scene: a dynamic cube map (six draws from a point) and a sky behind a picture.

:func:`render_cube_map` is the rasterizer's answer to "what does a mirror at p
see?": draw the scene six times from p, one 90° square view along each of ±x, ±y,
±z, through the ordinary pipeline (:func:`softpipe.draw_mesh`, one
:class:`softpipe.DrawCall` per object and face), and keep the six pictures as the
faces of a :class:`~softpipe.light.cubemap.CubeMap`. It is the shadow pass's cube map
(:mod:`softpipe.scenes.shadow_pass`) with colors instead of depths: the same six cameras,
and the face images arranged by GL's table (:mod:`softpipe.light.cubemap`).

A camera with +y up looking along +x sees +z on its right; GL's +x face has +z
on its *left* (s grows toward −z). So every face is drawn with a look-at camera
(the up vectors of :data:`softpipe.scenes.shadow_pass.CUBE_FACES`: +y for the four side faces,
−z looking up, +z looking down) and stored mirrored left to right. A 90° square
view's pixel centres are then exactly the face's texel centres.

This module is apart from :mod:`softpipe.light.cubemap` because it draws: the programs
that sample cube maps (:mod:`softpipe.programs.environment`) import the cube map
module, and drawing imports the programs.

:func:`fill_background` paints a cube map behind a finished picture: every sample
nothing was drawn on gets the environment in the direction of its view ray (a
sky box without a box).
"""
from __future__ import annotations

import math
from typing import Dict, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from softpipe.light.cubemap import CubeMap, texel_directions
from softpipe.light.material import Lighting
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.sampling import pattern_named
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.scene import Scene, program_for
from softpipe.scenes.shadow_pass import CUBE_FACES, render_shadow_maps

__all__ = ["render_cube_map", "face_cameras", "fill_background", "dynamic_environments", "render_with_environments",
           "ENVIRONMENT_PROGRAMS"]

#: Programs that read the uniform ``environment`` (or ``tracer``) for what they reflect and transmit.
ENVIRONMENT_PROGRAMS = ("mirror", "glass", "hall")
#: Of those, the ones that are drawn with ``phong`` in a cube map's faces when no environment is given.
_NEEDS_ENVIRONMENT = ("mirror", "glass")


def face_cameras(position: Sequence[float], near: float = 0.01, far: float = 100.0):
    """The six 90° cameras at ``position``, in GL's face order (+x, −x, +y, −y, +z, −z)."""
    p = np.asarray(position, np.float64)
    return [Camera(eye=tuple(p), target=tuple(p + np.asarray(forward, np.float64)), up=up, fovy=90.0,
                   near=near, far=far) for forward, up in CUBE_FACES]


def render_cube_map(objects: Union[Scene, Iterable], position: Sequence[float], size: int = 64, *,
                    lighting: Optional[Lighting] = None, background=(0.0, 0.0, 0.0, 1.0),
                    environment: Optional[CubeMap] = None, exclude: Sequence[str] = (),
                    program: Optional[str] = None, near: float = 0.01, far: float = 100.0,
                    filter: str = "trilinear", cull: str = "back") -> CubeMap:
    """Draw the scene into a cube map from ``position``: six draws of ``size`` × ``size``, fovy 90°.

    Parameters
    ----------
    objects : Scene or list of SceneObject
        What is drawn. A Scene gives its objects (and its ground, placed for its view
        camera), lights, program and cull mode.
    position : (x, y, z)
        The cube map's centre, world space (the centre of the mirror that will use it).
    size : int
        Face width in texels.
    lighting : Lighting, optional
        For a list of objects: the lights (default: one key light,
        :data:`softpipe.programs.common.DEFAULT_LIGHTING`). A Scene's own lights are
        used otherwise, the studio set placed for its view camera. Lights with
        ``shadows`` get their shadow maps once, for all six faces.
    background : RGBA or CubeMap
        What the faces show where nothing was drawn: a color, or a cube map (a sky)
        looked up in each texel's direction.
    environment : CubeMap, optional
        The uniform ``environment`` for objects drawn with ``mirror`` or ``glass``;
        without it they are drawn with ``phong``.
    exclude : names
        Objects left out (the mirror the map is for: it would see its own inside).
    program : str, optional
        The program of objects that name none (default: the scene's, else ``phong``).
    near, far : float
        The six cameras' clip distances.
    filter : str
        The cube map's filter (:class:`~softpipe.light.cubemap.CubeMap`).
    cull : str
        For a list of objects, the cull mode of those that name none.
    """
    size = int(size)
    if isinstance(objects, Scene):
        scene = objects
        view_camera = scene.view_camera()
        drawn = scene.drawn_objects(view_camera)
        lights = scene.lighting_for(view_camera)
        program = program or scene.program
        cull = scene.cull
    else:
        from softpipe.programs.common import DEFAULT_LIGHTING
        drawn = list(objects)
        lights = lighting if lighting is not None else DEFAULT_LIGHTING
    drawn = [o for o in drawn if o.name not in set(exclude)]
    maps = render_shadow_maps(drawn, lights) if any(li.shadows is not None for li in lights.lights) else None
    sky = background if isinstance(background, CubeMap) else None
    clear = (0.0, 0.0, 0.0, 1.0) if sky is not None else background
    extra = {"environment": environment} if environment is not None else None
    faces = []
    for camera in face_cameras(position, near, far):
        fb = Framebuffer(size, size).clear(clear)
        lighting_uniform = maps.lighting_uniform(lights, camera.view) if maps else lights.uniform(camera.view)
        for obj in drawn:
            name = program_for(obj, program)
            if name in _NEEDS_ENVIRONMENT and environment is None:
                name = "phong"
            draw_mesh(fb, obj.mesh, camera, name, model=obj.model, lighting=lighting_uniform, texture=obj.texture,
                      cull=obj.cull or cull, uniforms=extra if name in ENVIRONMENT_PROGRAMS else None)
        # GL's faces are mirrored left to right against a camera's picture (module docstring)
        faces.append((np.array(fb.color[:, ::-1], np.float32), fb.depth[:, ::-1] >= 1.0))
    if sky is not None:
        directions = texel_directions(size)
        for f, (color, empty) in enumerate(faces):
            if empty.any():
                color[empty] = sky.sample_many(directions[f][empty]).astype(np.float32)
    return CubeMap([color for color, _ in faces], filter=filter)


def fill_background(framebuffer: Framebuffer, camera: Camera, environment: CubeMap, lod: float = 0.0) -> Framebuffer:
    """Paint ``environment`` into every sample of ``framebuffer`` that nothing was drawn on (depth 1).

    A sample's color is the cube map in the world direction of the camera's ray through
    it (the camera's perspective, the framebuffer's aspect). Returns the framebuffer.
    """
    h, w = framebuffer.height, framebuffer.width
    depth = framebuffer.samples_depth
    color = framebuffer.samples_color
    half = math.tan(math.radians(camera.fovy) / 2.0)
    aspect = w / h
    rotation = camera.view[:3, :3].T                 # eye → world
    rows, cols = np.mgrid[0:h, 0:w]
    for s, (px, py) in enumerate(framebuffer.pattern.positions):
        empty = depth[s] >= 1.0
        if not empty.any():
            continue
        x = 2.0 * (cols[empty] + px) / w - 1.0
        y = 2.0 * ((h - 1 - rows[empty]) + py) / h - 1.0
        d_eye = np.stack([x * half * aspect, y * half, -np.ones_like(x)], axis=-1)
        color[s][empty] = environment.sample_many(d_eye @ rotation.T, lod).astype(np.float32)
    return framebuffer


def _reflective(scene: Scene, camera: Camera):
    """The objects that see their surroundings: mirrors, glasses, and Hall objects with kr or kt."""
    def sees(obj):
        name = program_for(obj, scene.program)
        m = obj.mesh.material
        return name in _NEEDS_ENVIRONMENT or (name == "hall" and max(*m.kr, *m.kt) > 0.0)
    return [o for o in scene.drawn_objects(camera) if sees(o)]


def dynamic_environments(scene: Scene, size: int = 64, *, sky: Optional[CubeMap] = None,
                         filter: str = "trilinear") -> Dict[str, CubeMap]:
    """A dynamic cube map for every object of ``scene`` drawn with ``mirror`` or ``glass``: name → CubeMap.

    Each is :func:`render_cube_map` from the centre of the object's bounding box (world
    space), without the object itself, with ``sky`` (a CubeMap, or the scene's
    background color when None) where nothing was drawn. The other mirrors and glasses
    in it reflect ``sky`` (one bounce: a map drawn from a map would need an order, or
    iterations, to converge).
    """
    out = {}
    for obj in _reflective(scene, scene.view_camera()):
        p = obj.world_positions()
        centre = (p.min(axis=0) + p.max(axis=0)) / 2.0
        out[obj.name] = render_cube_map(scene, centre, size, background=sky if sky is not None else scene.background,
                                        environment=sky, exclude=(obj.name,), filter=filter)
    return out


def render_with_environments(scene: Scene, environments: Union[CubeMap, Mapping[str, CubeMap], str, None], *,
                             camera: Optional[Camera] = None, sky: Optional[CubeMap] = None,
                             uniforms: Optional[Mapping] = None, max_depth: int = 5) -> Framebuffer:
    """:func:`softpipe.render_scene` with what the mirrors, glasses and Hall objects see around them.

    ``environments`` is one CubeMap for every such object, or a dict name → CubeMap
    (:func:`dynamic_environments`); an object it does not name reflects ``sky`` (or
    :func:`softpipe.light.cubemap.sky` without one; a Hall object, nothing). Or it is
    ``"rays"``: the objects are rasterized as always, and their reflected and
    refracted rays are traced through the scene (the uniform ``tracer``,
    :func:`softpipe.tracers.whitted.tracer_uniform`, to ``max_depth``), so their pixels are
    the ray tracer's. With ``sky``, the background is the sky as well
    (:func:`fill_background`). ``uniforms`` go to every draw (e.g. ``outside_ior``,
    ``environment_lod``). Shadows are made as render_scene makes them.
    """
    camera = camera or scene.view_camera()
    tracer = None
    if isinstance(environments, str):
        if environments != "rays":
            raise ValueError(f"environments must be a CubeMap, a dict of them, None or 'rays', got {environments!r}")
        from softpipe.tracers.whitted import tracer_uniform
        tracer = tracer_uniform(scene, camera, max_depth=max_depth)
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples), srgb=scene.srgb).clear(scene.background)
    objects = scene.drawn_objects(camera)
    lights = scene.lighting_for(camera)
    if any(light.shadows is not None for light in lights.lights):
        lighting = render_shadow_maps(objects, lights).lighting_uniform(lights, camera.view)
    else:
        lighting = lights.uniform(camera.view)
    for obj in objects:
        name = program_for(obj, scene.program)
        extra = dict(uniforms or {})
        if name in ENVIRONMENT_PROGRAMS and tracer is not None:
            extra["tracer"] = tracer
        elif name in ENVIRONMENT_PROGRAMS:
            env = environments.get(obj.name) if isinstance(environments, Mapping) else environments
            env = env if env is not None else sky
            if env is not None:
                extra["environment"] = env
        draw_mesh(fb, obj.mesh, camera, name, model=obj.model, lighting=lighting, texture=obj.texture,
                  cull=obj.cull or scene.cull, sample_shading=scene.sample_shading, uniforms=extra or None)
    if sky is not None:
        fill_background(fb, camera, sky)
    return fb
