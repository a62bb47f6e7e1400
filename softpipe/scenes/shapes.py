"""Procedural meshes with outward counter-clockwise triangles, analytic normals and uvs.

Axis conventions
----------------
softpipe is right-handed, and models are **y up**:

- :func:`plane` lies in the xz plane and faces +y; u runs along +x and v along -z,
  so a texture reads upright on a floor seen from +z.
- :func:`cube` is axis-aligned; each face has its own four vertices and flat normal,
  and uvs (0, 0)..(1, 1) upright when the face is seen from outside with +y up
  (the ±y faces: as the plane).
- Round shapes turn about the **y axis** and are centred on the origin: a point of a
  profile at radius r and height z, turned by θ, lands at (r sin θ, z, r cos θ), so
  θ = 0 is +z and θ grows toward +x (counter-clockwise seen from above). u = θ / 2π,
  v runs along the profile from 0 to 1 (for the sphere: south pole to north pole).
  :func:`surface_of_revolution` with ``axis="z"`` gives FORMULAS §25 literally,
  (r cos θ, r sin θ, z); the y-up form is the same surface under the rotation
  (x, y, z) → (y, z, x).

Sizes default to the [-1, 1]³ box: plane and cube of side 2, radius 1, height 2.
All generators are vectorized; a ~200k-triangle :func:`uv_sphere` takes a few tens
of milliseconds.
"""
from __future__ import annotations

import itertools
from typing import Callable, Optional, Sequence, Tuple, Union

import numpy as np

from softpipe.light.material import Material
from softpipe.scenes.mesh import Mesh, concatenate

__all__ = [
    "plane", "cube", "uv_sphere", "icosphere", "cylinder", "cone", "torus", "surface_of_revolution",
]

Profile = Union[Callable[[np.ndarray], Sequence], Sequence]


def _count(func: str, name: str, value: int, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{func}: {name} must be an integer >= {least}, got {value!r}")
    return int(value)


def _positive(func: str, name: str, value: float) -> float:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
        raise ValueError(f"{func}: {name} must be a positive number, got {value!r}")
    return float(value)


# ---------------------------------------------------------------------------- flat patches


def _grid_patch(center, u_axis, v_axis, cells: int, name: str, material: Material) -> Mesh:
    """A cells × cells grid spanning center ± u_axis/2 ± v_axis/2, facing u_axis × v_axis.

    uv = (0, 0) at center - (u_axis + v_axis)/2, growing along u_axis and v_axis.
    """
    center, u_axis, v_axis = (np.asarray(x, dtype=np.float64) for x in (center, u_axis, v_axis))
    a = np.linspace(0.0, 1.0, cells + 1)
    ua, va = (g.ravel() for g in np.meshgrid(a, a, indexing="ij"))  # [i, k]: i along u, k along v
    positions = center + (ua[:, None] - 0.5) * u_axis + (va[:, None] - 0.5) * v_axis
    normal = np.cross(u_axis, v_axis)
    normals = np.broadcast_to(normal / np.linalg.norm(normal), positions.shape)
    i, k = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    p00 = (i * (cells + 1) + k).ravel()
    p10, p01 = p00 + cells + 1, p00 + 1
    p11 = p10 + 1
    # (p00, p10, p11) and (p00, p11, p01) turn from u toward v: counter-clockwise seen from u × v.
    indices = np.stack([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)], 1).reshape(-1, 3)
    return Mesh(positions, indices, normals, np.stack([ua, va], 1), material=material, name=name)


def plane(size: float = 2.0, subdivisions: int = 1, material: Optional[Material] = None) -> Mesh:
    """A square of side ``size`` in the xz plane, centred on the origin, facing +y.

    ``subdivisions`` cells per side (2 triangles each). u runs along +x, v along -z.
    """
    size = _positive("plane", "size", size)
    cells = _count("plane", "subdivisions", subdivisions, 1)
    # +x × -z = +y: the patch faces up.
    return _grid_patch((0, 0, 0), (size, 0, 0), (0, 0, -size), cells, "plane", material or Material())


# (outward normal, u axis, v axis) per face, with u × v = normal and v = +y on the sides.
_CUBE_FACES = (
    ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
    ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
    ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    ((0, 0, -1), (-1, 0, 0), (0, 1, 0)),
)


def cube(size: float = 2.0, subdivisions: int = 1, material: Optional[Material] = None) -> Mesh:
    """An axis-aligned cube of side ``size`` centred on the origin, with flat normals.

    Faces in the order +x, -x, +y, -y, +z, -z; each has its own vertices (24 for
    ``subdivisions=1``, 12 triangles).
    """
    size = _positive("cube", "size", size)
    cells = _count("cube", "subdivisions", subdivisions, 1)
    material = material or Material()
    faces = [
        _grid_patch(np.multiply(n, size / 2), np.multiply(u, size), np.multiply(v, size), cells, "cube", material)
        for n, u, v in _CUBE_FACES
    ]
    return concatenate(faces, name="cube")


# ---------------------------------------------------------------------------- surfaces of revolution


def _evaluate_profile(profile: Profile, t_values) -> Tuple[np.ndarray, ...]:
    """(t, r, z, dr, dz) as float arrays [K] from a callable or from arrays; a constant
    (say dr = 0) may be given as a plain number."""
    t = None if t_values is None else np.asarray(t_values, dtype=np.float64)
    if callable(profile):
        if t is None:
            raise ValueError("surface_of_revolution: t_values are needed with a callable profile")
        profile = profile(t)
    shape_error = ValueError("surface_of_revolution: the profile must give 4 arrays (r, z, dr, dz) "
                             "or ((r, z), (dr, dz)) of numbers, one value per t")
    try:
        parts = list(profile)
        if len(parts) == 2:
            parts = [*parts[0], *parts[1]]
        arrays: Sequence[np.ndarray] = [np.asarray(p, dtype=np.float64) for p in parts]
        if len(arrays) != 4:
            raise shape_error
        arrays = np.broadcast_arrays(*arrays, *([] if t is None else [t]))
    except (TypeError, ValueError):
        raise shape_error from None
    r, z, dr, dz = arrays[:4]
    if r.ndim != 1:
        raise shape_error
    k = r.shape[0]
    t = np.linspace(0.0, 1.0, k) if t is None else arrays[4]
    if k < 2:
        raise ValueError(f"surface_of_revolution: need at least 2 profile samples, got {k}")
    if not all(np.isfinite(a).all() for a in (t, r, z, dr, dz)):
        raise ValueError("surface_of_revolution: the profile has non-finite values")
    if np.any(np.diff(t) <= 0):
        raise ValueError("surface_of_revolution: t_values must increase")
    return t, r, z, dr, dz


def surface_of_revolution(
    profile: Profile,
    t_values=None,
    segments: int = 32,
    *,
    axis: str = "y",
    material: Optional[Material] = None,
    name: str = "revolution",
) -> Mesh:
    """The surface swept by the profile (r(t), z(t)) turning about an axis (FORMULAS §25).

    Parameters
    ----------
    profile : callable or arrays
        ``profile(t)`` returning ``(r, z, dr, dz)`` (or ``((r, z), (dr, dz))``) for an
        array ``t``, where ``dr, dz`` are the derivatives r'(t), z'(t); or those four
        arrays directly, sampled at ``t_values``.
    t_values : array_like [K], increasing
        The profile samples, one ring of vertices each (v = 0 at the first, 1 at the last).
        Optional with arrays (then evenly spaced).
    segments : int
        Steps around the axis.
    axis : {"y", "z"}
        ``"z"``: P(t, θ) = (r cos θ, r sin θ, z) as in FORMULAS §25. ``"y"`` (default,
        for y-up models): P = (r sin θ, z, r cos θ), the same surface rotated.

    The normal at each vertex is the formula's (z' cos θ, z' sin θ, -r'), normalized
    (in the y-up form: (z' sin θ, -r', z' cos θ)), from the profile's derivative, not
    the triangles, **oriented outward** (FORMULAS §25): the formula's normal points to
    the right of the profile's direction of travel in the (r, z) half-plane, which is
    outward for a vase walked upward, a sphere walked south to north, a closed profile
    walked counter-clockwise. A profile walked the other way (a vase from rim to foot)
    would get inward normals, so when the normals point toward the axis on the whole —
    Σ z'·r over the profile, their radial part weighted by the area each sample sweeps,
    is negative — every normal is reversed and every triangle turned around. A profile
    whose normals have no radial part at all (a flat disc) keeps the side it was walked
    with. The triangles are wound counter-clockwise seen from the normals' side.

    Where r = 0 (a pole or an apex) the ring collapses to a point: it gets one vertex
    per segment, at the segment's middle angle (so each keeps its own normal and u),
    and the triangles that would have no area are left out.
    """
    segments = _count("surface_of_revolution", "segments", segments, 3)
    if axis not in ("y", "z"):
        raise ValueError(f"surface_of_revolution: axis must be 'y' or 'z', got {axis!r}")
    t, r, z, dr, dz = _evaluate_profile(profile, t_values)
    scale = max(float(np.max(np.abs(r))), float(np.ptp(z)), 1e-300)
    if np.any(r < -1e-12 * scale):
        raise ValueError(f"surface_of_revolution: r(t) must be >= 0, got {float(r.min())!r}")
    pole = np.abs(r) <= 1e-12 * scale  # sin(π) is 1e-16, not 0: snap to the axis
    r = np.where(pole, 0.0, r)
    length = np.hypot(dz, dr)
    if np.any(length == 0):
        k = int(np.argmax(length == 0))
        raise ValueError(f"surface_of_revolution: the profile's derivative is zero at t={float(t[k])!r}, "
                         "so the normal is undefined")
    n_radial, n_axial = dz / length, -dr / length  # FORMULAS §25: (z', -r') in the (r, z) plane
    inward = _walked_inward(t, r, dz)
    if inward:
        n_radial, n_axial = -n_radial, -n_axial

    # Vertex grid [ring, column]: columns 0..segments at θ_j; a pole ring drops the
    # last column and sits at the middle angles θ_j + Δθ/2.
    step = 2.0 * np.pi / segments
    col = np.arange(segments + 1)
    theta = (col[None, :] + np.where(pole, 0.5, 0.0)[:, None]) * step
    keep = ~(pole[:, None] & (col[None, :] == segments))
    vertex_id = np.cumsum(keep).reshape(keep.shape) - 1
    ring = np.broadcast_to(np.arange(len(t))[:, None], keep.shape)[keep]
    th = theta[keep]
    cos, sin = np.cos(th), np.sin(th)
    positions = np.stack([r[ring] * cos, r[ring] * sin, z[ring]], 1)
    normals = np.stack([n_radial[ring] * cos, n_radial[ring] * sin, n_axial[ring]], 1)
    uvs = np.stack([th / (2.0 * np.pi), (t[ring] - t[0]) / (t[-1] - t[0])], 1)
    indices = _revolution_triangles(vertex_id, pole)
    if inward:
        indices = indices[:, [0, 2, 1]]     # counter-clockwise seen from the reversed normals
    if axis == "y":  # (x, y, z) -> (y, z, x): a rotation, so winding and normals stay outward
        positions, normals = positions[:, [1, 2, 0]], normals[:, [1, 2, 0]]
    return Mesh(positions, indices, normals, uvs, material=material or Material(), name=name)


def _walked_inward(t: np.ndarray, r: np.ndarray, dz: np.ndarray) -> bool:
    """Do the §25 normals point toward the axis on the whole? The area-weighted radial part
    Σ z'(t)·r(t)·Δt (trapezoids over the samples) is negative, beyond rounding."""
    if len(t) < 2:
        return False
    f = dz * r
    score = float(np.sum((f[1:] + f[:-1]) * np.diff(t)))
    scale = float(np.sum((np.abs(f[1:]) + np.abs(f[:-1])) * np.abs(np.diff(t))))
    return score < -1e-9 * scale


def _revolution_triangles(vertex_id: np.ndarray, pole: np.ndarray) -> np.ndarray:
    """Two triangles per quad between rings i and i+1, columns j and j+1:
    (i j, i j+1, i+1 j) and (i j+1, i+1 j+1, i+1 j), counter-clockwise seen from the
    §25 normal. At a pole ring the triangle with two corners on the pole is dropped,
    and the other takes pole vertex j."""
    below, above = vertex_id[:-1], vertex_id[1:]
    left_below, right_below = below[:, :-1], below[:, 1:]
    left_above, right_above = above[:, :-1], above[:, 1:]
    pole_below, pole_above = pole[:-1, None], pole[1:, None]
    first = np.stack([left_below, right_below, left_above], -1)
    b = np.where(pole_below, left_below, right_below)  # on a collapsed ring, column j is pole vertex j
    second = np.stack([b, right_above, left_above], -1)
    tris = np.stack([first, second], 2)  # [ring gap, column, which triangle, corner]
    shape = left_below.shape
    keep = np.stack([np.broadcast_to(~pole_below, shape), np.broadcast_to(~pole_above, shape)], 2)
    return tris[keep]


def uv_sphere(radius: float = 1.0, segments: int = 32, rings: int = 16,
              material: Optional[Material] = None) -> Mesh:
    """A latitude-longitude sphere about the y axis: ``segments`` around, ``rings`` pole to pole.

    Normals equal position / radius; 2 · segments · (rings - 1) triangles.
    """
    radius = _positive("uv_sphere", "radius", radius)
    rings = _count("uv_sphere", "rings", rings, 2)
    t = np.linspace(0.0, np.pi, rings + 1)
    # South pole to north: (R sin t, -R cos t), derivative (R cos t, R sin t).
    profile = (radius * np.sin(t), -radius * np.cos(t), radius * np.cos(t), radius * np.sin(t))
    return surface_of_revolution(profile, t, segments, material=material, name="uv_sphere")


def cylinder(radius: float = 1.0, height: float = 2.0, segments: int = 32, stacks: int = 1,
             caps: bool = True, material: Optional[Material] = None) -> Mesh:
    """A cylinder about the y axis from y = -height/2 to height/2, with flat caps."""
    radius = _positive("cylinder", "radius", radius)
    height = _positive("cylinder", "height", height)
    stacks = _count("cylinder", "stacks", stacks, 1)
    t = np.linspace(0.0, 1.0, stacks + 1)
    one = np.ones_like(t)
    side = surface_of_revolution((radius * one, height * (t - 0.5), 0 * one, height * one), t, segments,
                                 material=material, name="cylinder")
    if not caps:
        return side
    parts = [side, _cap(radius, -height / 2, segments, material, up=False),
             _cap(radius, height / 2, segments, material, up=True)]
    return concatenate(parts, name="cylinder")


def _cap(radius: float, z: float, segments: int, material, up: bool) -> Mesh:
    """A disc at height z, facing up (+axis) or down, as a profile along the radius:
    outward from the centre faces down (§25 normal (0, -r')), inward faces up."""
    t = np.array([0.0, 1.0])
    r = radius * (1.0 - t) if up else radius * t
    dr = np.full(2, -radius if up else radius)
    return surface_of_revolution((r, np.full(2, z), dr, np.zeros(2)), t, segments,
                                 material=material, name="cap")


def cone(radius: float = 1.0, height: float = 2.0, segments: int = 32, stacks: int = 1,
         cap: bool = True, material: Optional[Material] = None) -> Mesh:
    """A cone about the y axis: base of ``radius`` at y = -height/2, apex at height/2."""
    radius = _positive("cone", "radius", radius)
    height = _positive("cone", "height", height)
    stacks = _count("cone", "stacks", stacks, 1)
    t = np.linspace(0.0, 1.0, stacks + 1)
    one = np.ones_like(t)
    side = surface_of_revolution((radius * (1.0 - t), height * (t - 0.5), -radius * one, height * one), t,
                                 segments, material=material, name="cone")
    if not cap:
        return side
    return concatenate([side, _cap(radius, -height / 2, segments, material, up=False)], name="cone")


def torus(major_radius: float = 1.0, minor_radius: float = 0.25, segments: int = 48,
          tube_segments: int = 24, material: Optional[Material] = None) -> Mesh:
    """A ring torus about the y axis: tube of ``minor_radius`` around a circle of ``major_radius``.

    The tube's profile starts at the outer equator and turns counter-clockwise in the
    (r, z) plane, so the §25 normal points out of the tube.
    """
    big = _positive("torus", "major_radius", major_radius)
    small = _positive("torus", "minor_radius", minor_radius)
    if small >= big:
        raise ValueError(f"torus: minor_radius ({small}) must be smaller than major_radius ({big})")
    tube_segments = _count("torus", "tube_segments", tube_segments, 3)
    t = np.linspace(0.0, 2.0 * np.pi, tube_segments + 1)
    profile = (big + small * np.cos(t), small * np.sin(t), -small * np.sin(t), small * np.cos(t))
    return surface_of_revolution(profile, t, segments, material=material, name="torus")


# ---------------------------------------------------------------------------- icosphere


def _icosahedron() -> Tuple[np.ndarray, np.ndarray]:
    """Unit icosahedron: the 12 cyclic permutations of (0, ±1, ±φ), and as faces the 20
    triples of mutually nearest vertices, each ordered to turn counter-clockwise outside."""
    phi = (1.0 + 5.0 ** 0.5) / 2.0
    base = [(0.0, s1, s2 * phi) for s1 in (-1.0, 1.0) for s2 in (-1.0, 1.0)]
    points = np.array([p[k:] + p[:k] for k in range(3) for p in base])
    edge = 2.0  # the shortest distance between these points
    near = np.isclose(np.linalg.norm(points[:, None] - points[None], axis=2), edge)
    faces = np.array([f for f in itertools.combinations(range(12), 3)
                      if near[f[0], f[1]] and near[f[1], f[2]] and near[f[0], f[2]]])
    p = points[faces]
    inward = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p.sum(axis=1)) < 0
    faces[inward] = faces[inward][:, ::-1]
    return points / np.linalg.norm(points, axis=1, keepdims=True), faces


def icosphere(radius: float = 1.0, subdivisions: int = 2, material: Optional[Material] = None) -> Mesh:
    """A sphere from an icosahedron whose triangles are split in four ``subdivisions``
    times, new vertices pushed out to the sphere: 20 · 4^subdivisions triangles of
    nearly equal size. Normals equal position / radius; no uvs (there is no seam-free
    way to give them).
    """
    radius = _positive("icosphere", "radius", radius)
    levels = _count("icosphere", "subdivisions", subdivisions, 0)
    points, faces = _icosahedron()
    for _ in range(levels):
        edges = np.sort(faces[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = points[unique[:, 0]] + points[unique[:, 1]]
        points = np.vstack([points, mid / np.linalg.norm(mid, axis=1, keepdims=True)])
        m01, m12, m20 = (len(points) - len(unique) + inverse.reshape(-1, 3)).T
        a, b, c = faces.T
        faces = np.concatenate([np.stack(x, 1) for x in
                                ((a, m01, m20), (b, m12, m01), (c, m20, m12), (m01, m12, m20))])
    return Mesh(points * radius, faces, normals=points, material=material or Material(), name="icosphere")
