"""Edge adjacency and silhouette edges of a closed triangle mesh, as shadow volumes need them.

A stencil shadow volume (:mod:`softpipe.scenes.shadow_volumes`) is built from the edges
where a caster turns from facing the light to facing away: its **silhouette** seen from
the light. Finding them needs, for every edge, the two triangles that share it:

- :func:`edge_adjacency` welds the mesh's vertices by position (a mesh splits a
  vertex wherever its normal or texture coordinate changes — at a cube's corners, at a
  uv seam — so the indices alone would show every such seam as an open border), drops the
  triangles that welding made degenerate (a uv sphere's pole row), and pairs every edge
  with its two triangles. A shadow volume is closed only if its caster is, so a mesh
  with an edge used by one triangle (a hole, an open border) or by more than two (a
  non-manifold fin), or whose two triangles at an edge disagree about the winding, is
  refused with a :class:`NotClosedError` that names the mesh and the edge.
- :func:`light_vector` is a :class:`~softpipe.light.material.Light` as the homogeneous
  4-vector L of Everitt and Kilgard (2002): ``(position, 1)`` for a point (or spot)
  light, ``(−direction, 0)`` — toward the light — for a directional one, in the mesh's
  model space.
- :func:`facing_light` tells which triangles face the light: with the plane
  n·x + d = 0 of a triangle (n = (p1 − p0) × (p2 − p0), outward), it faces L when
  n·L.xyz + d·L.w > 0 — one formula for both kinds of light. A triangle edge-on to the
  light (= 0) counts as facing away.
- :func:`silhouette_edges` are the edges with one triangle facing the light and the
  other not, each oriented as it runs (counter-clockwise) in its light-facing triangle.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Union

import numpy as np

from softpipe.light.material import Light
from softpipe.scenes.mesh import Mesh

__all__ = ["EdgeAdjacency", "NotClosedError", "WELD", "edge_adjacency", "light_vector", "facing_light",
           "silhouette_edges", "silhouette_corners"]


#: :func:`edge_adjacency`'s default weld: positions within 1e-9 of the mesh's size are one vertex.
WELD = 1e-9


class NotClosedError(ValueError):
    """A shadow caster that is not a closed, consistently wound (2-manifold) triangle mesh."""


@dataclass(frozen=True)
class EdgeAdjacency:
    """A closed mesh's welded vertices, its triangles and every edge with its two triangles.

    Attributes
    ----------
    name : str
        The mesh's name (for messages).
    positions : float64 [V, 3]
        One row per distinct position of the mesh (model space), in
        :meth:`Mesh.position_classes` order.
    triangles : int64 [T, 3]
        The mesh's non-degenerate triangles (after welding) into ``positions``, wound as
        the mesh winds them.
    triangle_ids : int64 [T]
        Each row of ``triangles``'s index in ``mesh.indices``.
    corners : int64 [T, 3]
        The same triangles into the mesh's own vertices (``mesh.indices[triangle_ids]``):
        what a shadow volume's caps and sides are drawn from, so that they are the
        caster's triangles to the bit.
    edges : int64 [E, 2]
        Every edge once, as (a, b) with a < b, into ``positions``.
    faces : int64 [E, 2]
        The edge's two triangles (into ``triangles``): ``faces[e, 0]`` runs a → b,
        ``faces[e, 1]`` runs b → a. E = 3T/2 for a closed mesh.
    """

    name: str
    positions: np.ndarray
    triangles: np.ndarray
    triangle_ids: np.ndarray
    corners: np.ndarray
    edges: np.ndarray
    faces: np.ndarray

    def plane(self) -> np.ndarray:
        """Every triangle's plane (n, d) with n = (p1 − p0) × (p2 − p0), d = −n·p0: float64 [T, 4]."""
        p = self.positions[self.triangles]
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        return np.column_stack([n, -np.einsum("ij,ij->i", n, p[:, 0])])


def _edge_text(name: str, positions: np.ndarray, a: int, b: int) -> str:
    pa = ", ".join(f"{v:g}" for v in positions[a])
    pb = ", ".join(f"{v:g}" for v in positions[b])
    return f"{name}: the edge ({pa}) – ({pb})"


def edge_adjacency(mesh: Mesh, weld: float = WELD) -> EdgeAdjacency:
    """The edge adjacency of a closed triangle mesh (vertices welded by position).

    Parameters
    ----------
    mesh : Mesh
        Triangles wound counter-clockwise seen from outside. Vertices at the same
        position are one vertex here (:meth:`Mesh.position_classes`): a mesh that splits
        its vertices at normal or uv seams is still closed. Lines and points are ignored.
    weld : float
        How close two positions must be to be one, relative to the mesh's bounding-box
        diagonal: positions are rounded to a grid of that step before they are compared
        (a uv sphere's seam meets itself only to within rounding: sin 2π is not 0). 0
        welds bit-for-bit equal positions only. Two positions closer than the step can
        still round apart when they straddle a grid line; the error then names the edge.

    Returns
    -------
    EdgeAdjacency

    Raises
    ------
    NotClosedError
        Naming the mesh and the first offending edge (by its two positions): an edge
        with one triangle (the mesh has a hole or a border), an edge with more than two,
        or an edge that both its triangles run the same way (their windings disagree, so
        inside and outside are not defined). A mesh with no triangle is refused too.
    """
    name = mesh.name or "the mesh"
    if not (isinstance(weld, (int, float)) and 0.0 <= weld < 1.0):
        raise ValueError(f"weld must be a number in [0, 1) (a fraction of the mesh's size), got {weld!r}")
    keyed = mesh
    if weld > 0.0 and mesh.vertex_count:
        step = weld * max(float(np.linalg.norm(np.ptp(mesh.positions, axis=0))), 1e-300)
        keyed = mesh.replace(positions=np.round(mesh.positions / step) * step)
    classes = keyed.position_classes()
    positions = np.zeros((int(classes.max()) + 1 if len(classes) else 0, 3))
    positions[classes] = mesh.positions + 0.0      # each class at one of its own positions
    tri = classes[mesh.indices.astype(np.int64)] if mesh.triangle_count else np.zeros((0, 3), np.int64)
    # welding closes a uv sphere's poles: the triangles that lost a corner there have no area and no edge of their own
    keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])
    ids = np.flatnonzero(keep)
    tri = tri[keep]
    if len(tri) == 0:
        raise NotClosedError(f"{name}: has no triangles, so it encloses nothing and casts no shadow volume")
    # every directed edge (a → b) of every triangle, and which triangle it belongs to
    start = tri.reshape(-1)
    end = tri[:, [1, 2, 0]].reshape(-1)
    owner = np.repeat(np.arange(len(tri)), 3)
    low, high = np.minimum(start, end), np.maximum(start, end)
    forward = start < end                        # runs low → high
    order = np.lexsort((~forward, high, low))    # by edge, the forward use first
    low, high, forward, owner = low[order], high[order], forward[order], owner[order]
    new = np.ones(len(low), bool)
    new[1:] = (low[1:] != low[:-1]) | (high[1:] != high[:-1])
    first = np.flatnonzero(new)
    counts = np.diff(np.append(first, len(low)))
    for what, bad in (("is used by only one triangle: the mesh has a hole or an open border there",
                       counts == 1),
                      ("is shared by more than two triangles (the mesh is not 2-manifold there)", counts > 2)):
        if bad.any():
            k = first[int(np.argmax(bad))]
            raise NotClosedError(f"{_edge_text(name, positions, low[k], high[k])} {what}; shadow volumes "
                                 f"need closed casters (set cast_shadows=False on an open mesh such as a floor)")
    same = forward[first] == forward[first + 1]
    if same.any():
        k = first[int(np.argmax(same))]
        raise NotClosedError(f"{_edge_text(name, positions, low[k], high[k])} runs the same way in both of its "
                             "triangles: their windings disagree, so the mesh has no consistent outside")
    edges = np.column_stack([low[first], high[first]])
    faces = np.column_stack([owner[first], owner[first + 1]])
    return EdgeAdjacency(name, positions, tri, ids, mesh.indices[ids].astype(np.int64), edges, faces)


def light_vector(light: Union[Light, Sequence[float]], model: Optional[np.ndarray] = None) -> np.ndarray:
    """The light as a homogeneous 4-vector L in model space (Everitt and Kilgard 2002).

    A point or spot light is (x, y, z, 1) at its position, a directional light
    (−direction, 0): the direction toward it, a point at infinity. A 4-sequence is
    taken as L in world space already. ``model`` (model → world, 4×4) takes it into the
    mesh's own space: L_model = model⁻¹ · L (a direction transforms with the same matrix,
    its w = 0 leaving the translation out).
    """
    if isinstance(light, Light):
        if light.kind == "directional":
            world = np.append(-np.asarray(light.direction, np.float64), 0.0)
        else:
            world = np.append(np.asarray(light.position, np.float64), 1.0)
    else:
        world = np.asarray(light, np.float64).reshape(-1)
        if world.shape != (4,) or not np.all(np.isfinite(world)) or world[3] not in (0.0, 1.0):
            raise ValueError(f"light must be a Light or a homogeneous 4-vector (x, y, z, 1) or (x, y, z, 0), "
                             f"got {light!r}")
        if world[3] == 0.0 and not np.any(world[:3]):
            raise ValueError("light: a directional light's vector (x, y, z, 0) must not be zero")
    if model is None:
        return world
    m = np.asarray(model, np.float64)
    if m.shape != (4, 4):
        raise ValueError(f"model must be a 4×4 matrix, got shape {m.shape}")
    return np.linalg.solve(m, world)


def facing_light(adjacency: EdgeAdjacency, light4: np.ndarray) -> np.ndarray:
    """Which triangles face the light L (model space, :func:`light_vector`): bool [T], n·L.xyz + d·L.w > 0."""
    return adjacency.plane() @ np.asarray(light4, np.float64) > 0.0


def silhouette_edges(adjacency: EdgeAdjacency, light4: np.ndarray) -> np.ndarray:
    """The silhouette of the mesh seen from the light L: int64 [S, 2] into ``adjacency.positions``.

    The edges whose two triangles differ in :func:`facing_light`, each as (a, b) in the
    order it runs in its light-facing triangle, so that extruding a → b away from the
    light makes a quad whose outward side is away from the shadow
    (:func:`softpipe.scenes.shadow_volumes.shadow_volume`).
    """
    lit = facing_light(adjacency, light4)
    first, second = lit[adjacency.faces[:, 0]], lit[adjacency.faces[:, 1]]
    edges = adjacency.edges
    # faces[:, 0] runs a → b: when it is the lit one the edge keeps its order, else it turns round
    return np.concatenate([edges[first & ~second], edges[second & ~first][:, ::-1]]).astype(np.int64)


def silhouette_corners(adjacency: EdgeAdjacency, light4: np.ndarray) -> np.ndarray:
    """:func:`silhouette_edges` as the mesh's own vertex indices: int64 [S, 2].

    Each edge (a, b) as its light-facing triangle's two corners (``adjacency.corners``),
    a → b, so that a shadow volume's side shares its vertices with its light cap exactly.
    """
    lit = facing_light(adjacency, light4)
    first, second = lit[adjacency.faces[:, 0]], lit[adjacency.faces[:, 1]]
    edges = adjacency.edges
    start = np.concatenate([edges[first & ~second, 0], edges[second & ~first, 1]])
    face = np.concatenate([adjacency.faces[first & ~second, 0], adjacency.faces[second & ~first, 1]])
    k = np.argmax(adjacency.triangles[face] == start[:, None], axis=1)
    rows = adjacency.corners[face]
    pick = np.arange(len(face))
    return np.column_stack([rows[pick, k], rows[pick, (k + 1) % 3]]).astype(np.int64)
