"""Stencil shadow volumes, z-pass and z-fail: hard shadows the 1990s-GPU way (FORMULAS §21, rasterized).

A shadow ray asks whether anything lies between a point and the light (§21); a
shadow map answers from a depth picture taken at the light (:mod:`softpipe.scenes.shadow_pass`).
A **shadow volume** answers with geometry: the region of space a caster hides from the
light is bounded by the caster's light-facing triangles (the *light cap*), by its
silhouette edges seen from the light pulled away from the light to infinity (the
*sides*), and by its other triangles projected to infinity (the *dark cap*). A visible
point lies in shadow when it lies inside such a volume, and the stencil buffer counts
that, per pixel, by counting the volume's faces between the eye and the point.

- :func:`shadow_volume`: one caster's volume for one light, in the caster's model space,
  its far vertices at infinity (homogeneous w = 0; Everitt and Kilgard 2002, "Practical
  and Robust Stenciled Shadow Volumes"), drawn with
  :func:`softpipe.pipeline.transforms.perspective_infinite` so nothing of it is far-clipped;
- :func:`render_shadow_volumes`: a scene drawn with them, three passes per the
  classic recipe — the unlit term with depth, then per light the volumes into the
  stencil buffer (color and depth writes off) and the light's term added where the
  stencil stayed 0 — returning the framebuffer; ``method="zpass"`` or ``"zfail"``.

**z-pass** counts the faces the eye ray crosses *in front of* the visible point (front
faces +1, back faces −1, on depth pass): it needs no caps, and it is wrong when the eye
itself is inside a volume (the near plane clips the faces the ray would have entered
by). **z-fail** ("Carmack's reverse") counts the faces *behind* the point (back faces +1,
front faces −1, on depth fail): a ray from the point to infinity, so it needs the volume
closed — both caps, and a far plane that clips nothing, hence the infinite projection
(depth clamp is the other way) — and it does not care where the eye is.

Casters must be closed 2-manifold meshes (:func:`softpipe.scenes.silhouette.edge_adjacency`
refuses others); an object with ``cast_shadows`` false (the ground) receives shadows
and casts none. The walk-through with pictures and the measured agreement with the ray
tracer is docs/shadow-volumes.md.
"""
from __future__ import annotations

import dataclasses
from collections import namedtuple
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np

from softpipe.language.glsl import mat4_mul_vec4
from softpipe.light.material import Light, Lighting
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.merge_state import Stencil
from softpipe.pipeline.sampling import pattern_named
from softpipe.pipeline.transforms import perspective_infinite
from softpipe.scenes.drawing import draw_mesh, standard_uniforms
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.scene import program_for
from softpipe.scenes.silhouette import EdgeAdjacency, edge_adjacency, facing_light, light_vector, silhouette_corners

__all__ = ["ShadowVolume", "shadow_volume", "volume_vertex", "volume_fragment", "METHODS",
           "render_shadow_volumes", "ShadowVolumeResult"]

#: The two ways of counting: faces in front of the visible point, or behind it.
METHODS = ("zpass", "zfail")


@dataclass(frozen=True)
class ShadowVolume:
    """One caster's shadow volume for one light, in the caster's model space.

    Attributes
    ----------
    positions : float64 [2N, 4]
        The mesh's N vertices (w = 1), then each pushed away from the light to infinity:
        row N + i is (p_i·L.w − L.xyz, 0) — for a point light the direction p_i − L, for a
        directional light −L for every vertex (Everitt and Kilgard's extrusion).
    sides : int32 [2S, 3]
        Two triangles per silhouette edge a → b (as it runs in its light-facing
        triangle): (b, a, a∞) and (b, a∞, b∞), wound so that their front is outside the volume.
    light_cap : int32 [F, 3]
        The triangles facing the light, as the mesh winds them.
    dark_cap : int32 [B, 3]
        The triangles facing away, their corners at infinity, the mesh's winding
        (projecting from the light keeps it: their front is outside, away from the light).
    silhouette : int64 [S, 2]
        The silhouette edges (into the mesh's vertices).
    """

    positions: np.ndarray
    sides: np.ndarray
    light_cap: np.ndarray
    dark_cap: np.ndarray
    silhouette: np.ndarray

    def triangles(self, caps: bool) -> np.ndarray:
        """The sides alone (z-pass), or with both caps (z-fail): int32 [K, 3] into ``positions``."""
        parts = [self.sides, self.light_cap, self.dark_cap] if caps else [self.sides]
        return np.ascontiguousarray(np.concatenate(parts), dtype=np.int32)


def shadow_volume(mesh: Mesh, light4, adjacency: Optional[EdgeAdjacency] = None) -> ShadowVolume:
    """The shadow volume of the closed mesh ``mesh`` for the light ``light4`` (model space).

    Parameters
    ----------
    mesh : Mesh
        A closed caster (its lines and points are ignored).
    light4 : array_like [4]
        The light as :func:`softpipe.scenes.silhouette.light_vector` gives it, in the
        mesh's model space: (x, y, z, 1) a point light, (x, y, z, 0) toward a directional one.
    adjacency : EdgeAdjacency, optional
        :func:`~softpipe.scenes.silhouette.edge_adjacency` of ``mesh``, if already made.

    Raises
    ------
    NotClosedError
        From :func:`~softpipe.scenes.silhouette.edge_adjacency`: the mesh is not closed.
    """
    adjacency = adjacency or edge_adjacency(mesh)
    L = np.asarray(light4, np.float64)
    n = mesh.vertex_count
    far = mesh.positions * L[3] - L[:3]
    positions = np.concatenate([np.column_stack([mesh.positions, np.ones(n)]),
                                np.column_stack([far, np.zeros(n)])])
    silhouette = silhouette_corners(adjacency, L)
    a, b = silhouette[:, 0], silhouette[:, 1]
    sides = np.concatenate([np.column_stack([b, a, a + n]), np.column_stack([b, a + n, b + n])])
    lit = facing_light(adjacency, L)
    light_cap = adjacency.corners[lit]
    dark_cap = adjacency.corners[~lit] + n
    as32 = lambda x: np.ascontiguousarray(x.reshape(-1, 3), dtype=np.int32)  # noqa: E731
    return ShadowVolume(positions, as32(sides), as32(light_cap), as32(dark_cap), silhouette)


def volume_vertex(attributes, uniforms):
    """The volumes' vertex shader: clip = projection · model_view · (x, y, z, w), w = 0 at infinity.

    For w = 1 it is the arithmetic of :func:`softpipe.programs.common.eye_space` to the
    bit, so a light cap lands on the caster's own depths (z-fail depends on it).
    """
    p = attributes.position
    P = mat4_mul_vec4(uniforms.model_view, (p[0], p[1], p[2], p[3]))
    return mat4_mul_vec4(uniforms.projection, P), VolumeVaryings((P[0], P[1], P[2]))


VolumeVaryings = namedtuple("VolumeVaryings", ["position"])


def volume_fragment(varyings, uniforms, frag):
    """The volumes' fragment shader: a color nobody sees (the volume pass writes the stencil only)."""
    return (1.0, 1.0, 0.0, 1.0)


@dataclass
class ShadowVolumeResult:
    """What :func:`render_shadow_volumes` leaves besides the picture.

    ``shadowed[j]`` is bool [H, W]: the pixels whose stencil was not 0 after light j's
    volume pass (sample 0), i.e. in light j's shadow by this method; ``covered`` the pixels
    some object covers (depth < 1 after the first pass); ``volumes[j]`` the volumes drawn
    for light j, by object name.
    """

    method: str
    shadowed: List[np.ndarray] = dataclasses.field(default_factory=list)
    covered: Optional[np.ndarray] = None
    volumes: List[Dict[str, ShadowVolume]] = dataclasses.field(default_factory=list)


def _unlit(lighting: Lighting) -> Lighting:
    """The lights with their diffuse and specular off: the scene's ambient and emissive term alone."""
    dark = tuple(dataclasses.replace(light, diffuse=(0.0, 0.0, 0.0), specular=(0.0, 0.0, 0.0), shadows=False)
                 for light in lighting.lights)
    return Lighting(dark, global_ambient=lighting.global_ambient)


def _lit_only(light: Light) -> Lighting:
    """One light's diffuse and specular alone: no ambient anywhere (the first pass drew it)."""
    return Lighting((dataclasses.replace(light, ambient=(0.0, 0.0, 0.0), shadows=False),),
                    global_ambient=(0.0, 0.0, 0.0))


def render_shadow_volumes(scene, *, camera: Optional[Camera] = None, method: str = "zfail",
                          result: Optional[ShadowVolumeResult] = None):
    """Draw ``scene`` with stencil shadow volumes: every light casts hard shadows from the closed casters.

    Parameters
    ----------
    scene : Scene
        Its objects (single-material meshes), lights, ambient, program and size, as
        :func:`softpipe.scenes.drawing.render_scene` draws them; the objects with
        ``cast_shadows`` true must be closed meshes. The lights' own ``shadows`` settings
        are not read: every light casts its shadow by volumes.
    camera : Camera, optional
        Instead of the scene's. Its projection is made infinite
        (:func:`~softpipe.pipeline.transforms.perspective_infinite`: the same near and field
        of view, no far plane) for all three passes, so that their depths agree.
    method : "zpass" or "zfail"
        How the stencil counts (see the module docstring): "zfail" is right wherever the
        eye is; "zpass" needs no caps and is wrong when the eye is inside a volume.
    result : ShadowVolumeResult, optional
        Receives each light's shadow mask and the volumes drawn.

    Returns
    -------
    Framebuffer
        Pass 1: the scene with its ambient and emissive term only (depth written). Then
        per light: its volumes into a cleared stencil (color and depth writes off, the
        depth test "less", no culling, the front and back faces' stencil ops per
        ``method``), then the scene again with that light's diffuse and specular only,
        added (blend "additive") where the stencil is 0 and the depth is equal to pass
        1's: the lit, unshadowed surface (its RGB added, pass 1's alpha kept).

    Raises
    ------
    NotClosedError
        Before anything is drawn, naming the first caster that is not a closed mesh and
        its edge (:func:`~softpipe.scenes.silhouette.edge_adjacency`).
    ValueError
        An unknown ``method``.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}, got {method!r}")
    camera = camera or scene.view_camera()
    aspect = scene.width / scene.height
    projection = perspective_infinite(camera.fovy, aspect, camera.near)
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples))
    fb.clear(scene.background)
    objects = scene.drawn_objects(camera)
    lighting = scene.lighting_for(camera)
    casters = [o for o in objects if o.cast_shadows]
    adjacency = {id(o): edge_adjacency(o.mesh) for o in casters}   # a mesh that is not closed: said before drawing
    result = result if result is not None else ShadowVolumeResult(method)
    result.method = method

    def draw_scene(lights: Lighting, **state) -> None:
        uniform = lights.uniform(camera.view)
        for obj in objects:
            mesh = obj.mesh
            extra = {"projection": projection}
            if state:           # pass 1 keeps the emission; a light's pass adds that light alone
                extra["material"] = dataclasses.replace(mesh.material, ke=(0.0, 0.0, 0.0))
            draw_mesh(fb, mesh, camera, program_for(obj, scene.program), model=obj.model, lighting=uniform,
                      texture=obj.texture, uniforms=extra, cull=obj.cull or scene.cull,
                      sample_shading=scene.sample_shading, **state)

    draw_scene(_unlit(lighting))
    result.covered = fb.depth < 1.0
    if method == "zpass":
        front = Stencil(depth_pass="incr_wrap")
        back = Stencil(depth_pass="decr_wrap")
    else:
        front = Stencil(depth_fail="decr_wrap")
        back = Stencil(depth_fail="incr_wrap")
    for light in lighting.lights:
        fb.samples_stencil.fill(0)
        drawn: Dict[str, ShadowVolume] = {}
        for obj in casters:
            volume = shadow_volume(obj.mesh, light_vector(light, obj.model), adjacency[id(obj)])
            drawn[obj.name] = volume
            triangles = volume.triangles(caps=method == "zfail")
            if not len(triangles):
                continue
            u = standard_uniforms(camera, aspect, obj.model)
            u = {"model_view": u["model_view"], "projection": projection}
            mirrored = np.linalg.det(np.asarray(obj.model, np.float64)[:3, :3]) < 0
            DrawCall(fb, volume.positions, triangles, None, volume_vertex, volume_fragment, u,
                     cull="none", front_face="cw" if mirrored else "ccw", depth_test="less", depth_write=False,
                     color_mask=(False, False, False, False), stencil=front, stencil_back=back).run()
        result.volumes.append(drawn)
        result.shadowed.append(fb.stencil != 0)
        # the light's color added, the alpha pass 1 wrote kept (additive alone would add the alphas up)
        draw_scene(_lit_only(light), stencil=Stencil(func="equal", ref=0), depth_test="equal", depth_write=False,
                   blend=("one", "one", "zero", "one"))
    return fb
