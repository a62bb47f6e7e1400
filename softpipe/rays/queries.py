"""Ray queries from shaders: the scene as a uniform, closest and any hits, shadow rays (FORMULAS §21).

GPUs now trace rays from inside the raster pipeline: a fragment shader asks "what
does this ray hit?" (GLSL's ``GL_EXT_ray_query``). softpipe offers the same two
questions to any numba-compiled shader, on a :class:`RayScene` passed like a
uniform (``uniforms={"scene": RayScene(objects)}``):

``trace_closest(scene, origin, direction, t_min, t_max)`` → ``(triangle, t, b1, b2)``
    the nearest hit in (t_min, t_max), triangle −1 for a miss;
``trace_any(scene, origin, direction, t_min, t_max)`` → bool
    whether anything lies there (a shadow ray needs no more).

Origins and directions are in the shader's **eye space**, as everything a built-in
program computes: the scene uniform is made for a camera's view matrix and turns
rays into the BVH's world space itself. t is the same in both spaces (the point
origin + t·direction maps to itself). :func:`hit_position` and :func:`hit_normal`
give a hit's point and interpolated normal back in eye space.

:func:`ray_visibility` is the notes' shadow ray (§21): from P toward the light, over
t ∈ (ε, t_max), with ε = :attr:`RayScene.epsilon`; an opaque hit gives V = 0, a
transparent object (material ``kt`` ≠ 0, or opacity < 1) multiplies V by its
transmission once per object crossed, and by the falloff of its medium over the
distance inside it (§15, :func:`medium_falloff`: T^d or Glassner's 1/(1 + a·d)), through
any number of them — what one shadow map layer cannot do (:mod:`softpipe.light.shadowmap`).

The BVH is :mod:`softpipe.rays.bvh`'s: one flattened world-space tree over every
object's triangles (``scene_bvh``).
"""
from __future__ import annotations

from collections import namedtuple
from typing import Optional, Sequence, Tuple

import numpy as np
from numba import njit

from softpipe.rays.bvh import closest_hit, scene_bvh

__all__ = ["RayScene", "RaySceneUniform", "transmission_of", "trace_closest", "trace_any",
           "hit_position", "hit_normal", "ray_visibility", "medium_falloff", "MAX_TRANSPARENT_LAYERS", "EPSILON_SCALE",
           "point_to_world", "direction_to_world"]

#: A shadow ray passes at most this many transparent surfaces before it counts as blocked.
MAX_TRANSPARENT_LAYERS = 64
#: ε of §21 as a share of the scene's size (its bounding box diagonal).
EPSILON_SCALE = 1e-6

RaySceneUniform = namedtuple("RaySceneUniform", ["bvh", "triangle_object", "normals", "transmission",
                                                 "to_world", "normal_to_eye", "epsilon", "face_normals", "media"])
RaySceneUniform.__doc__ = """A :class:`RayScene` as a shader receives it.

``bvh`` (:class:`~softpipe.rays.bvh.BVHUniform`, world space), ``triangle_object`` int64 [T],
``normals`` float64 [T, 3, 3] (each triangle's corner normals, world space),
``transmission`` float64 [objects, 3] (−1 for an opaque object), ``to_world`` [4, 4] eye →
world, ``normal_to_eye`` [3, 3] world normals → eye, ``epsilon`` (§21's ε, world units),
``face_normals`` float64 [T, 3] (toward each triangle's front, world space, not unit),
``media`` float64 [objects, 5] (the falloff inside each object, §15: T as RGB, 1 for
Glassner's form, its a)."""


def transmission_of(material) -> Optional[Tuple[float, float, float]]:
    """What a surface of this material lets through: kt when nonzero, 1 − opacity when < 1, else None (opaque)."""
    if any(c > 0.0 for c in material.kt):
        return (float(material.kt[0]), float(material.kt[1]), float(material.kt[2]))
    if material.opacity < 1.0:
        return (1.0 - material.opacity,) * 3
    return None


def _corner_normals(obj) -> np.ndarray:
    """An object's normal at each corner of each triangle, world space, [M, 3, 3]."""
    mesh = obj.mesh
    n = mesh.normals if mesh.normals is not None else mesh.vertex_normals()
    m = np.asarray(obj.model, np.float64)[:3, :3]
    n = np.asarray(n, np.float64) @ np.linalg.inv(m)        # (M⁻¹)ᵀ n, as rows
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    return n[np.asarray(mesh.indices).reshape(-1, 3)]


def _face_normals(obj) -> np.ndarray:
    """An object's triangles' normals by winding, world space, [M, 3], toward the front (see RayScene)."""
    p = obj.world_positions()
    tri = np.asarray(obj.mesh.indices).reshape(-1, 3)
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    return -n if np.linalg.det(np.asarray(obj.model, np.float64)[:3, :3]) < 0 else n


def _medium(material) -> Tuple[float, float, float, float, float]:
    """The falloff inside an object of this material (§15), as RaySceneUniform.media's row."""
    return (*material.transmittance, float(material.falloff == "glassner"), material.falloff_a)


class RayScene:
    """The objects of a scene as rays see them: one BVH and what a hit needs to be shaded.

    Parameters
    ----------
    objects : sequence of SceneObject
        Each with ``mesh`` (single material), ``model``; in world space after it.

    Attributes
    ----------
    bvh : BVH
    triangle_object, triangle_local : int64 [T]
        Which object, and which of its triangles, each BVH triangle is.
    normals : float64 [T, 3, 3]
        Each triangle's corner normals (world space, unit): what shading interpolates.
    face_normals : float64 [T, 3]
        Each triangle's normal by its winding, toward its front (world space, not unit):
        a mirroring model matrix turns it around, as the rasterizer turns the front face.
        A ray with d·n < 0 meets the front: it enters the (closed) object.
    media : float64 [objects, 5]
        The medium inside each object (§15): transmittance T (RGB), 1 for Glassner's
        form (else 0), its a — :attr:`Material.transmittance`, ``falloff``, ``falloff_a``.
    transmission : float64 [objects, 3]
        Per object: −1 opaque, else its transmission (:func:`transmission_of`).
    epsilon : float
        §21's ε: :data:`EPSILON_SCALE` × the scene's bounding-box diagonal.
    """

    def __init__(self, objects: Sequence, *, leaf_size: int = 4):
        self.objects = list(objects)
        self.bvh, self.triangle_object, self.triangle_local = scene_bvh(self.objects, leaf_size=leaf_size)
        normals = [_corner_normals(o) for o in self.objects]
        self.normals = (np.ascontiguousarray(np.concatenate(normals)) if normals
                        else np.zeros((0, 3, 3), np.float64))
        faces = [_face_normals(o) for o in self.objects]
        self.face_normals = (np.ascontiguousarray(np.concatenate(faces)) if faces
                             else np.zeros((0, 3), np.float64))
        self.media = np.array([_medium(o.mesh.material) for o in self.objects], np.float64).reshape(-1, 5)
        self.transmission = np.array([transmission_of(o.mesh.material) or (-1.0, -1.0, -1.0)
                                      for o in self.objects], np.float64).reshape(-1, 3)
        if len(self.bvh):
            corners = np.concatenate([self.bvh.v0, self.bvh.v1, self.bvh.v2])
            diagonal = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
        else:
            diagonal = 1.0
        self.epsilon = EPSILON_SCALE * max(diagonal, 1e-300)

    def __len__(self) -> int:
        return len(self.bvh)

    def __repr__(self) -> str:
        return f"RayScene({len(self.objects)} objects, {len(self)} triangles)"

    def uniform(self, view_matrix=None) -> RaySceneUniform:
        """The scene for shaders working in the eye space of ``view_matrix`` (world → eye; default: world)."""
        view = np.eye(4) if view_matrix is None else np.asarray(view_matrix, np.float64)
        if view.shape != (4, 4) or not np.all(np.isfinite(view)):
            raise ValueError(f"view_matrix must be a finite 4×4 matrix, got shape {view.shape}")
        to_world = np.linalg.inv(view)
        normal_to_eye = np.ascontiguousarray(np.linalg.inv(view[:3, :3]).T)
        return RaySceneUniform(self.bvh.__softpipe_uniform__(), self.triangle_object, self.normals,
                               self.transmission, np.ascontiguousarray(to_world), normal_to_eye, float(self.epsilon),
                               self.face_normals, self.media)

    def __softpipe_uniform__(self) -> RaySceneUniform:
        """In world space: for a shader whose P is world space (the ray tracer's)."""
        return self.uniform()


# ------------------------------------------------------------------ in shaders

@njit(cache=True, forceinline=True)
def point_to_world(M, p):
    """The 3-D point M·(p, 1) for a 4×4 (or 3×4) matrix M: a point carried by an affine map."""
    return (M[0, 0] * p[0] + M[0, 1] * p[1] + M[0, 2] * p[2] + M[0, 3],
            M[1, 0] * p[0] + M[1, 1] * p[1] + M[1, 2] * p[2] + M[1, 3],
            M[2, 0] * p[0] + M[2, 1] * p[1] + M[2, 2] * p[2] + M[2, 3])


@njit(cache=True, forceinline=True)
def direction_to_world(M, d):
    """The 3-D direction M·(d, 0): a direction carried by an affine map (no translation, not renormalized)."""
    return (M[0, 0] * d[0] + M[0, 1] * d[1] + M[0, 2] * d[2],
            M[1, 0] * d[0] + M[1, 1] * d[1] + M[1, 2] * d[2],
            M[2, 0] * d[0] + M[2, 1] * d[1] + M[2, 2] * d[2])


@njit(cache=True)
def trace_closest(scene, origin, direction, t_min, t_max):
    """The nearest hit on the eye-space ray origin + t·direction, t in (t_min, t_max): (triangle, t, b1, b2).

    ``triangle`` is −1 for a miss. The hit point is :func:`hit_position`.
    """
    M = scene.to_world
    return closest_hit(scene.bvh, point_to_world(M, origin), direction_to_world(M, direction), t_min, t_max)


@njit(cache=True)
def trace_any(scene, origin, direction, t_min, t_max):
    """Does anything lie on the eye-space ray for t in (t_min, t_max)?"""
    return trace_closest(scene, origin, direction, t_min, t_max)[0] >= 0


@njit(cache=True)
def hit_position(origin, direction, t):
    """origin + t·direction (in the ray's space)."""
    return (origin[0] + t * direction[0], origin[1] + t * direction[1], origin[2] + t * direction[2])


@njit(cache=True)
def hit_normal(scene, triangle, b1, b2):
    """The triangle's corner normals interpolated at (b1, b2) and normalized, in eye space."""
    n = scene.normals
    b0 = 1.0 - b1 - b2
    x = b0 * n[triangle, 0, 0] + b1 * n[triangle, 1, 0] + b2 * n[triangle, 2, 0]
    y = b0 * n[triangle, 0, 1] + b1 * n[triangle, 1, 1] + b2 * n[triangle, 2, 1]
    z = b0 * n[triangle, 0, 2] + b1 * n[triangle, 1, 2] + b2 * n[triangle, 2, 2]
    M = scene.normal_to_eye
    ex = M[0, 0] * x + M[0, 1] * y + M[0, 2] * z
    ey = M[1, 0] * x + M[1, 1] * y + M[1, 2] * z
    ez = M[2, 0] * x + M[2, 1] * y + M[2, 2] * z
    length = np.sqrt(ex * ex + ey * ey + ez * ez)
    if length == 0.0:
        return 0.0, 0.0, 0.0
    return ex / length, ey / length, ez / length


@njit(cache=True)
def medium_falloff(transmittance, glassner, a, d):
    """The share of light (RGB) left after distance d in a medium (FORMULAS §15).

    T^d per channel (Hall's T_r^{d_r} and T_t^{d_t}, §13), T = ``transmittance`` per
    unit distance; or, with ``glassner`` True, Glassner's 1/(1 + a·d), the same in
    every channel. T ≈ 1 for air in small scenes (§15): 1^d = 1, and a = 0 gives 1.
    """
    if glassner:
        g = 1.0 / (1.0 + a * d)
        return (g, g, g)
    return (transmittance[0] ** d, transmittance[1] ** d, transmittance[2] ** d)


@njit(cache=True)
def ray_visibility(scene, P, L, t_max):
    """V of a light seen from the eye-space point P along the unit vector L, up to distance t_max (§21).

    The shadow ray p + t·L, t ∈ (ε, t_max − ε): each opaque hit ends it (V = 0); each
    transparent object it passes multiplies V by that object's transmission, once
    per object (entering and leaving a glass ball is one object crossed), and by the
    falloff of the object's medium over the distance the ray travels inside it
    (§15, :func:`medium_falloff`; a ray leaving an object it started in counts from
    P). An object is inside between a hit on its front (by the winding) and the next
    hit on its back, so objects are taken as closed; air outside is clear (T = 1).
    """
    M = scene.to_world
    o, d = point_to_world(M, P), direction_to_world(M, L)
    eps = scene.epsilon
    red, green, blue = 1.0, 1.0, 1.0
    t0, last, entered = eps, -1, 0.0
    for _ in range(MAX_TRANSPARENT_LAYERS):
        tri, t, _b1, _b2 = closest_hit(scene.bvh, o, d, t0, t_max - eps)
        if tri < 0:
            return red, green, blue
        obj = scene.triangle_object[tri]
        if scene.transmission[obj, 0] < 0.0:
            return 0.0, 0.0, 0.0
        if obj != last:
            red *= scene.transmission[obj, 0]
            green *= scene.transmission[obj, 1]
            blue *= scene.transmission[obj, 2]
            last = obj
            entered = 0.0                  # a first hit on its back: the ray started inside, at P
        n = scene.face_normals[tri]
        if n[0] * d[0] + n[1] * d[1] + n[2] * d[2] < 0.0:
            entered = t
        else:
            m = scene.media[obj]
            f = medium_falloff((m[0], m[1], m[2]), m[3] != 0.0, m[4], t - entered)
            red, green, blue = red * f[0], green * f[1], blue * f[2]
        t0 = t + eps
    return 0.0, 0.0, 0.0
