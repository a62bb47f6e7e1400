"""A planar mirror the way 1990s GPUs drew it: the stencil buffer, the scene reflected, a clip plane.

A flat mirror shows the scene reflected in its plane, seen through the mirror's
outline. A rasterizer draws exactly that in four passes (:func:`render_planar_mirror`):

1. **Mark the mirror's pixels.** Draw the mirror with the stencil test "always",
   ``depth_pass="replace"``, ref 1: every sample it covers gets stencil 1. Nothing
   else is written (``color_mask`` all False, ``depth_write=False``): the reflected
   scene lies *behind* the mirror's surface, so a mirror depth written now would hide
   all of it; the depth buffer stays clear for pass 2.
2. **Draw the scene reflected** in the mirror's plane n·x = d, only where the stencil
   is 1 (func "equal", ref 1). Every object's model matrix is preceded by the
   reflection M = I − 2nnᵀ with the translation 2dn (:func:`reflection_matrix`, det −1);
   the lights are reflected too (the eye-space lights of the view V·M). A reflection
   turns a triangle's winding around on the screen, so the front faces arrive wound
   clockwise: :func:`softpipe.scenes.drawing.draw_mesh` flips ``front_face`` for a model
   matrix of negative determinant, and back faces are still the ones culled. What was
   behind the mirror (n·x < d) is reflected in front of it, where it would wrongly
   show in the glass: a user clip plane at the mirror (``clip_planes=``, the world
   plane carried into clip coordinates by the inverse transpose of the view-projection,
   :func:`clip_plane`) cuts it away.
3. **Draw the mirror with its kr** over the reflection, where the stencil is 1: its own
   lighting (FORMULAS §10, Blinn-Phong: the ``mirror`` program's I_local) plus kr × what
   is already there, by blending: src·1 + dst·kr (the factors "one" and
   "constant_color", ``blend_color`` = kr). That is the ``mirror`` program's
   I = kr·I(R) + I_local (FORMULAS §13's k_r term, R from §16), with I(R) the reflected
   scene instead of a cube map. The depth test is "always" here, so the mirror's depth
   replaces the reflection's over exactly its own pixels.
4. **Draw the rest of the scene** normally: the objects in front of the mirror cover it,
   those behind it are hidden by its depth.

Both this and the ray tracer (:mod:`softpipe.tracers.whitted`) reflect exactly, so they
agree inside the mirror except along edges; a cube map
(:mod:`softpipe.scenes.environment_pass`) reflects from one point and is off by the
parallax. docs/planar-mirror.md shows the three side by side, with the numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Optional, Tuple

import numpy as np

from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.merge_state import Stencil
from softpipe.pipeline.sampling import pattern_named
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.scene import Scene, SceneObject, program_for
from softpipe.scenes.shadow_pass import render_shadow_maps

__all__ = ["render_planar_mirror", "MirrorPlane", "find_mirror", "reflection_matrix", "clip_plane",
           "MIRROR_FLATNESS", "MARK", "INSIDE"]

#: How far a mirror's vertices may lie off their plane, as a fraction of the mirror's size (its
#: bounding box's diagonal): rounding, not a bend.
MIRROR_FLATNESS = 1e-6
#: Pass 1's stencil state: every sample the mirror covers gets 1.
MARK = Stencil(func="always", ref=1, depth_pass="replace")
#: Passes 2 and 3: only where pass 1 wrote 1.
INSIDE = Stencil(func="equal", ref=1)


@dataclass(frozen=True)
class MirrorPlane:
    """The mirror's plane n·x = d (world space), n a unit normal toward the camera.

    Attributes
    ----------
    name : str
        The scene object that is the mirror.
    normal : tuple of 3 floats
        n, pointing to the side the camera is on (the mirror is two-sided, as the
        ray tracer's mirrors are).
    offset : float
        d.
    kr : tuple of 3 floats
        The mirror material's reflection coefficient (FORMULAS §13).
    """

    name: str
    normal: Tuple[float, float, float]
    offset: float
    kr: Tuple[float, float, float]

    @property
    def reflection(self) -> np.ndarray:
        """The reflection in this plane, [4, 4] (:func:`reflection_matrix`)."""
        return reflection_matrix(self.normal, self.offset)


def reflection_matrix(normal, offset: float) -> np.ndarray:
    """The reflection in the plane n·x = d: x ↦ x − 2(n·x − d)n, as a 4×4 matrix.

    M = [[I − 2nnᵀ, 2dn], [0, 1]]: a point and its image are the same distance from the
    plane on either side, points of the plane stay, and det M = −1 (it turns
    right-handed into left-handed, which is why a reflected triangle's winding flips).
    ``normal`` need not be unit; it is normalized (a zero normal is a ValueError).
    """
    n = np.asarray(normal, np.float64).reshape(-1)
    length = float(np.linalg.norm(n)) if n.shape == (3,) else 0.0
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"reflection_matrix: the plane's normal must be a non-zero 3-vector, got {normal!r}")
    n = n / length
    d = float(offset) / length
    m = np.eye(4)
    m[:3, :3] -= 2.0 * np.outer(n, n)
    m[:3, 3] = 2.0 * d * n
    return m


def clip_plane(world_plane, view_projection: np.ndarray) -> Tuple[float, float, float, float]:
    """A world-space plane (a, b, c, e: kept where a·x + b·y + c·z + e ≥ 0) in clip coordinates.

    A plane is a row vector p with p·X ≥ 0 inside, X homogeneous. Clip coordinates
    are X_c = (P·V)·X, so p·X = p·(P·V)⁻¹·X_c: the clip-space plane is
    (P·V)⁻ᵀ·p, the inverse transpose of the view-projection (what ``clip_planes=``
    takes; GL's user clip planes are given in eye space and carried the same way, by
    the inverse transpose of the modelview).
    """
    p = np.asarray(world_plane, np.float64).reshape(4)
    a, b, c, e = np.linalg.inv(np.asarray(view_projection, np.float64)).T @ p
    return float(a), float(b), float(c), float(e)


def find_mirror(scene: Scene, camera: Camera, mirror: Optional[str] = None) -> Tuple[SceneObject, MirrorPlane]:
    """The mirror object of ``scene`` and its plane, checked.

    ``mirror`` names the object; None takes the one object drawn with the program
    ``mirror``. It must be flat (every vertex within :data:`MIRROR_FLATNESS` × its size
    of the plane fitted through them), have area, reflect (kr > 0) and not be seen
    edge-on (the camera's eye in its plane). Each failure is a ValueError naming the
    object and what is wrong.
    """
    objects = scene.drawn_objects(camera)
    if mirror is None:
        named = [o for o in objects if program_for(o, scene.program) == "mirror"]
        if len(named) != 1:
            which = ("no object is" if not named else
                     f"{len(named)} objects are ({', '.join(repr(o.name) for o in named)})")
            raise ValueError(f"{scene.path}: {which} drawn with program 'mirror'; name the planar mirror: "
                             "render_planar_mirror(scene, mirror='name')")
        obj = named[0]
    else:
        found = [o for o in objects if o.name == mirror]
        if not found:
            raise ValueError(f"{scene.path}: no object is named {mirror!r} (the objects: "
                             f"{', '.join(repr(o.name) for o in objects) or 'none'})")
        obj = found[0]
    label = f"mirror {obj.name!r}"
    kr_r, kr_g, kr_b = (float(k) for k in obj.mesh.material.kr)
    kr = (kr_r, kr_g, kr_b)
    if not max(kr) > 0.0:
        raise ValueError(f"{label}: its material's kr is {kr}: it reflects nothing (FORMULAS §13's k_r); "
                         "give the material kr > 0")
    if obj.mesh.triangle_count == 0:
        raise ValueError(f"{label} has no triangles to reflect in")
    points = obj.world_positions()[np.unique(np.asarray(obj.mesh.indices).reshape(-1))]
    centre = points.mean(axis=0)
    size = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    _, sigma, axes = np.linalg.svd(points - centre)
    if len(sigma) < 2 or not sigma[1] > MIRROR_FLATNESS * size * math.sqrt(len(points)):
        raise ValueError(f"{label} has no area (its vertices lie on a line or a point)")
    n = axes[2]                                   # the direction the vertices spread least along
    off = float(np.abs((points - centre) @ n).max())
    if off > MIRROR_FLATNESS * size:
        raise ValueError(f"{label} is not planar: its vertices are up to {off:.3g} off their best-fit plane "
                         f"(the limit is MIRROR_FLATNESS = {MIRROR_FLATNESS:g} × its size {size:.3g}); a curved "
                         "mirror is drawn with the 'mirror' program's cube map or the ray tracer")
    d = float(n @ centre)
    side = float(n @ np.asarray(camera.eye, np.float64)) - d
    if abs(side) <= MIRROR_FLATNESS * max(size, 1.0):
        raise ValueError(f"{label}: the camera's eye {tuple(camera.eye)} is in the mirror's plane: it is seen "
                         "edge-on")
    if side < 0.0:                                # n toward the camera: the reflected world is at n·x < d
        n, d = -n, -d
    return obj, MirrorPlane(obj.name, (float(n[0]), float(n[1]), float(n[2])), d, kr)


def _reflected_camera(camera: Camera, objects, reflection: np.ndarray) -> Camera:
    """``camera`` with its far plane moved back past every reflected vertex.

    Seen in a mirror, things are farther away than they are (the way there goes via the
    mirror), and the ray tracer's reflected rays have no far plane: neither may the
    reflection. Only the depth range changes, so x and y on the screen are as before.
    """
    far = camera.far
    for o in objects:
        p = o.world_positions() @ reflection[:3, :3].T + reflection[:3, 3]
        eye_z = p @ camera.view[2, :3] + camera.view[2, 3]
        if len(eye_z):
            far = max(far, 1.05 * float(-eye_z.min()))
    return camera if far == camera.far else camera.replace(far=far)


def render_planar_mirror(scene: Scene, camera: Optional[Camera] = None, *, mirror: Optional[str] = None,
                         steps: Optional[Dict[str, np.ndarray]] = None) -> Framebuffer:
    """Draw ``scene`` with one planar mirror by the stencil buffer (the module docstring's four passes).

    Parameters
    ----------
    scene : Scene
        Its objects, lights (and shadows), background and sample pattern, as
        :func:`softpipe.scenes.drawing.render_scene` draws them.
    camera : Camera, optional
        The scene's view camera by default.
    mirror : str, optional
        The name of the mirror object: a flat mesh (a quad) whose material has kr > 0.
        By default the one object drawn with the program ``mirror``. Whatever its program,
        it is lit as the ``mirror`` program lights it (FORMULAS §10, Blinn-Phong) plus kr ×
        the reflection. Other objects keep their programs (another ``mirror`` or ``glass``
        reflects the sky, as in :func:`~softpipe.scenes.drawing.render_scene`).
    steps : dict, optional
        Receives the framebuffer after each pass: ``"stencil"`` (the stencil, sample 0,
        [H, W] uint8), ``"reflection"``, ``"mirror"`` and ``"scene"`` (RGB uint8 pictures).

    Returns
    -------
    Framebuffer
        The picture; its stencil is still 1 over the mirror's samples and 0 elsewhere.

    Raises
    ------
    ValueError
        A mirror that cannot be found, is not flat, has no area or reflects nothing, or
        is seen edge-on (:func:`find_mirror`).
    """
    camera = camera or scene.view_camera()
    obj, plane = find_mirror(scene, camera, mirror)
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples)).clear(scene.background, stencil=0)
    objects = scene.drawn_objects(camera)
    others = [o for o in objects if o is not obj]
    lights = scene.lighting_for(camera)
    reflection = plane.reflection
    maps = render_shadow_maps(objects, lights) if any(li.shadows is not None for li in lights.lights) else None

    def lighting(view):      # the lights in the eye space of ``view`` (with the shadow maps, if any)
        return maps.lighting_uniform(lights, view) if maps is not None else lights.uniform(view)

    def state(o):
        return dict(texture=o.texture, cull=o.cull or scene.cull, sample_shading=scene.sample_shading,
                    point_size=scene.point_size, line_width=scene.line_width)

    # 1. the mirror's samples get stencil 1; no color, no depth (the reflection lies behind it)
    draw_mesh(fb, obj.mesh, camera, "phong", model=obj.model, lighting=lighting(camera.view), stencil=MARK,
              color_mask=(False, False, False, False), depth_write=False, **state(obj))
    if steps is not None:
        steps["stencil"] = fb.stencil.copy()

    # 2. the scene reflected in the plane n·x = d, inside the mirror only, cut at the plane. The lights
    # are reflected with it: in the eye space of V·M a light at p is where its image M·p is.
    mirrored = _reflected_camera(camera, others, reflection)
    n, d = np.asarray(plane.normal), plane.offset
    behind = clip_plane((-n[0], -n[1], -n[2], d), mirrored.projection(fb.width / fb.height) @ mirrored.view)
    reflected_lights = lighting(camera.view @ reflection)
    for o in others:
        draw_mesh(fb, o.mesh, mirrored, program_for(o, scene.program), model=reflection @ o.model,
                  lighting=reflected_lights, stencil=INSIDE, clip_planes=[behind], **state(o))
    if steps is not None:
        steps["reflection"] = fb.to_uint8(alpha=False)

    # 3. the mirror: its own light (§10) + kr × the reflection under it (FORMULAS §13, §16), over exactly
    # the marked samples, its depth replacing the reflection's
    eye_lighting = lighting(camera.view)
    draw_mesh(fb, obj.mesh, camera, "phong", model=obj.model, lighting=eye_lighting, stencil=INSIDE,
              depth_test="always", blend=("one", "constant_color", "one", "zero"),
              blend_color=(*plane.kr, 0.0), **state(obj))
    if steps is not None:
        steps["mirror"] = fb.to_uint8(alpha=False)

    # 4. everything else, as render_scene draws it
    for o in others:
        draw_mesh(fb, o.mesh, camera, program_for(o, scene.program), model=o.model, lighting=eye_lighting,
                  **state(o))
    if steps is not None:
        steps["scene"] = fb.to_uint8(alpha=False)
    return fb
