"""Meshes: the vertex and index arrays that feed the vertex stage (triangles, and lines and points beside them).

A :class:`Mesh` is plain numpy arrays plus a material:

``positions``     float64 ``[N, 3]``, model space (softpipe models are right-handed, y up)
``indices``       int32 ``[M, 3]``, one row per triangle; counter-clockwise seen from
                  outside is front-facing, so ``cross(p1 - p0, p2 - p0)`` points outward
``normals``       optional float64 ``[N, 3]``, one per vertex
``uvs``           optional float64 ``[N, 2]``, OpenGL convention: (0, 0) is the image's
                  bottom-left corner, v grows upward
``material``      the :class:`~softpipe.light.material.Material` of every triangle, unless
``materials`` and ``material_ids`` are given: then triangle ``t`` uses
                  ``materials[material_ids[t]]`` (this is how OBJ ``usemtl`` arrives)
``lines``         int32 ``[L, 2]``, line segments (an OBJ ``l`` polyline arrives as its
                  segments: ``l 1 2 3`` is the rows (0, 1) and (1, 2)), drawn as one
                  ``topology="lines"`` draw
``points``        int32 ``[P]``, vertices drawn as points (OBJ ``p``)
``line_material_ids``, ``point_material_ids``
                  with ``material_ids``: the material of each segment (point), into
                  ``materials``; without it every segment and point has ``material``

Lines and points have no face, so nothing in this module (normals, areas, winding,
volume) reads them, except that they keep their vertices: :meth:`Mesh.compacted`,
:meth:`Mesh.flat_shaded`, :meth:`Mesh.by_material` and :func:`concatenate` carry them.

Meshes are treated as values: every helper returns a new mesh and leaves its
input alone. The dataclass is frozen, and the constructor validates every array,
naming the array and its shape in the error, so a bad array fails where it is
made rather than as a wrong picture three stages later.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Iterable, Literal, Optional, Sequence, Tuple

import numpy as np

from softpipe.light.material import Material

__all__ = ["Mesh", "concatenate"]

NormalWeighting = Literal["area", "angle"]


def _describe(a: np.ndarray) -> str:
    """'float64 [10, 4]': how errors name an array's dtype and shape."""
    return f"{a.dtype} [{', '.join(str(s) for s in a.shape)}]"


def _as_array(name: str, value: Any) -> np.ndarray:
    try:
        return np.asarray(value)
    except (ValueError, TypeError) as e:  # ragged nested lists
        raise TypeError(f"Mesh.{name} must be a rectangular array, got {type(value).__name__}: {e}") from None


def _float_rows(name: str, value: Any, width: int, rows: Optional[int]) -> np.ndarray:
    """Validate a float array of shape [rows, width] (rows=None: any count)."""
    a = _as_array(name, value)
    if a.dtype.kind not in "fiu" or a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"Mesh.{name} must be a float array of shape [N, {width}], got {_describe(a)}")
    if rows is not None and a.shape[0] != rows:
        raise ValueError(
            f"Mesh.{name} must have one row per position: shape [{rows}, {width}], got {_describe(a)}"
        )
    from softpipe.pipeline.vertex import MAX_VERTICES
    if a.shape[0] > MAX_VERTICES:
        raise ValueError(f"Mesh.{name} has {a.shape[0]} rows; the limit is MAX_VERTICES = {MAX_VERTICES}")
    a = np.ascontiguousarray(a, dtype=np.float64)
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"Mesh.{name} has a non-finite value in row {i}: {a[i].tolist()}")
    return a


def _index_array(name: str, value: Any, shape_text: str, ndim: int, count: int, what: str,
                 width: int = 3, row_name: str = "triangle") -> np.ndarray:
    """Validate an integer array whose values index something of length `count`."""
    a = _as_array(name, value)
    shape_ok = a.ndim == ndim and (ndim == 1 or a.shape[1] == width)
    # An empty list arrives as float64; it holds no index, so its dtype does not matter.
    if not shape_ok or (a.dtype.kind not in "iu" and a.size > 0):
        raise ValueError(f"Mesh.{name} must be an int array of shape {shape_text}, got {_describe(a)}")
    if a.size:
        bad = (a < 0) | (a >= count)
        if bad.any():
            flat = int(np.argmax(bad.ravel()))
            row = flat // (width if ndim == 2 else 1)
            value_bad = int(a.ravel()[flat])
            where = f" at {row_name} {row}"
            raise ValueError(f"Mesh.{name}: index {value_bad}{where} is out of range for {count} {what}")
    return np.ascontiguousarray(a, dtype=np.int32)


def _normalize_rows(v: np.ndarray) -> np.ndarray:
    """Unit rows; zero rows stay zero (a degenerate triangle has no direction)."""
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)


@dataclass(frozen=True, eq=False)
class Mesh:
    """An indexed triangle mesh; see the module docstring for the arrays.

    Parameters
    ----------
    positions : array_like, float [N, 3]
    indices : array_like, int [M, 3]
        Counter-clockwise (seen from outside) triangles into ``positions``.
    normals : array_like, float [N, 3], optional
        Per-vertex normals (not re-normalized: the fragment stage normalizes).
    uvs : array_like, float [N, 2], optional
        Per-vertex texture coordinates.
    material : Material
        The material of every triangle when ``material_ids`` is None.
    materials : sequence of Material
        The palette ``material_ids`` indexes into.
    material_ids : array_like, int [M], optional
        Per-triangle index into ``materials``.
    name : str
        For messages and ``repr``.
    lines : array_like, int [L, 2], optional
        Line segments into ``positions`` (a polyline as its segments); none by default.
    points : array_like, int [P], optional
        Vertices drawn as points; none by default.
    line_material_ids, point_material_ids : array_like, int [L] / [P], optional
        Per segment (point) index into ``materials``; given exactly when ``material_ids``
        is and there are segments (points).
    source : object
        Where the mesh came from (e.g. an :class:`softpipe.scenes.obj.OBJReport`); for people
        debugging, never read by the pipeline.
    """

    positions: np.ndarray
    indices: np.ndarray
    normals: Optional[np.ndarray] = None
    uvs: Optional[np.ndarray] = None
    material: Material = field(default_factory=Material)
    materials: Tuple[Material, ...] = ()
    material_ids: Optional[np.ndarray] = None
    name: str = ""
    source: Any = field(default=None, repr=False)
    lines: Any = None
    points: Any = None
    line_material_ids: Optional[np.ndarray] = None
    point_material_ids: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen dataclass)
        positions = _float_rows("positions", self.positions, 3, None)
        set_("positions", positions)
        n = positions.shape[0]
        set_("indices", _index_array("indices", self.indices, "[M, 3]", 2, n, "positions"))
        if self.normals is not None:
            set_("normals", _float_rows("normals", self.normals, 3, n))
        if self.uvs is not None:
            set_("uvs", _float_rows("uvs", self.uvs, 2, n))
        if not isinstance(self.material, Material):
            raise TypeError(f"Mesh.material must be a Material, got {type(self.material).__name__}")
        materials = tuple(self.materials)
        for i, m in enumerate(materials):
            if not isinstance(m, Material):
                raise TypeError(f"Mesh.materials[{i}] must be a Material, got {type(m).__name__}")
        set_("materials", materials)
        if self.material_ids is not None:
            ids = _index_array("material_ids", self.material_ids, "[M]", 1, len(materials), "materials")
            if ids.shape[0] != self.indices.shape[0]:
                raise ValueError(
                    f"Mesh.material_ids must have one entry per triangle: shape [{self.indices.shape[0]}], "
                    f"got {_describe(ids)}"
                )
            set_("material_ids", ids)
        lines = np.zeros((0, 2), np.int32) if self.lines is None else self.lines
        set_("lines", _index_array("lines", lines, "[L, 2]", 2, n, "positions", 2, "segment"))
        points = np.zeros(0, np.int32) if self.points is None else self.points
        set_("points", _index_array("points", points, "[P]", 1, n, "positions", 1, "point"))
        for key, count, what in (("line_material_ids", self.lines.shape[0], "segment"),
                                 ("point_material_ids", self.points.shape[0], "point")):
            value = getattr(self, key)
            if self.material_ids is None or count == 0:
                if value is not None and np.size(value):
                    raise ValueError(f"Mesh.{key} is given only with material_ids and {what}s; "
                                     f"got {_describe(np.asarray(value))}")
                set_(key, None)
                continue
            if value is None:
                raise ValueError(f"Mesh.{key} is needed: the mesh has material_ids and {count} {what}s")
            ids = _index_array(key, value, f"[{count}]", 1, len(materials), "materials", 1, what)
            if ids.shape[0] != count:
                raise ValueError(f"Mesh.{key} must have one entry per {what}: shape [{count}], got {_describe(ids)}")
            set_(key, ids)

    # ------------------------------------------------------------------ basics

    @property
    def vertex_count(self) -> int:
        """N, the number of vertices."""
        return int(self.positions.shape[0])

    @property
    def triangle_count(self) -> int:
        """M, the number of triangles."""
        return int(self.indices.shape[0])

    @property
    def segment_count(self) -> int:
        """L, the number of line segments."""
        return int(self.lines.shape[0])

    @property
    def point_count(self) -> int:
        """P, the number of points."""
        return int(self.points.shape[0])

    def without_lines_and_points(self) -> "Mesh":
        """A copy holding only the triangles (the same vertices)."""
        if not self.segment_count and not self.point_count:
            return self
        return self.replace(lines=None, points=None, line_material_ids=None, point_material_ids=None)

    def segment_material(self, s: int) -> Material:
        """The material of line segment ``s``."""
        if self.line_material_ids is None:
            return self.material
        return self.materials[int(self.line_material_ids[s])]

    def point_material(self, p: int) -> Material:
        """The material of point ``p``."""
        if self.point_material_ids is None:
            return self.material
        return self.materials[int(self.point_material_ids[p])]

    def replace(self, **changes: Any) -> "Mesh":
        """A copy with some fields changed, validated like the constructor."""
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        parts = [f"{self.vertex_count} vertices", f"{self.triangle_count} triangles"]
        if self.segment_count:
            parts.append(f"{self.segment_count} line segment{'s' if self.segment_count != 1 else ''}")
        if self.point_count:
            parts.append(f"{self.point_count} point{'s' if self.point_count != 1 else ''}")
        parts.append("normals" if self.normals is not None else "no normals")
        parts.append("uvs" if self.uvs is not None else "no uvs")
        if self.material_ids is not None:
            parts.append(f"{len(self.materials)} materials ({', '.join(m.name for m in self.materials)})")
        else:
            parts.append(f"material {self.material.name!r}")
        if self.vertex_count:
            lo, hi = self.bounds()
            fmt = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"  # noqa: E731
            parts.append(f"bounds {fmt(lo)}..{fmt(hi)}")
        name = f"{self.name!r}, " if self.name else ""
        return f"Mesh({name}{', '.join(parts)})"

    def triangle_material(self, t: int) -> Material:
        """The material of triangle ``t``."""
        if self.material_ids is None:
            return self.material
        return self.materials[int(self.material_ids[t])]

    # ------------------------------------------------------------------ geometry

    def corners(self) -> np.ndarray:
        """Triangle corner positions, float64 [M, 3 corners, 3]."""
        return self.positions[self.indices]

    def face_normals(self, normalized: bool = True) -> np.ndarray:
        """Per-triangle normals ``cross(p1 - p0, p2 - p0)``, float64 [M, 3].

        With ``normalized=False`` the length is twice the triangle's area. A degenerate
        triangle gets the zero vector either way.
        """
        p = self.corners()
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        return _normalize_rows(n) if normalized else n

    def face_areas(self) -> np.ndarray:
        """Per-triangle areas, float64 [M]."""
        return 0.5 * np.linalg.norm(self.face_normals(normalized=False), axis=1)

    def corner_angles(self) -> np.ndarray:
        """The interior angle at each corner, radians, float64 [M, 3]."""
        p = self.corners()
        angles = np.empty(self.indices.shape, dtype=np.float64)
        for c in range(3):
            a = p[:, (c + 1) % 3] - p[:, c]
            b = p[:, (c + 2) % 3] - p[:, c]
            # atan2(|a×b|, a·b) stays accurate near 0 and π, where acos of a dot product does not.
            angles[:, c] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
        return angles

    def position_classes(self, groups: Any = None) -> np.ndarray:
        """For each vertex, the number of its position: vertices with equal positions share one, int64 [N].

        Equal means bit-for-bit equal coordinates (``-0.0`` counts as ``0.0``): an OBJ file
        that repeats a ``v`` line at a patch border, or a vertex split because its texture
        coordinates differ, shares the number. ``groups`` (int [N], optional) keeps vertices
        of different groups apart even at one position (the OBJ loader's smoothing groups).
        Numbers are ``0 … K-1`` in sorted order of (position, group).
        """
        key = self.positions + 0.0  # -0.0 + 0.0 is 0.0: one position, one key
        if groups is not None:
            g = np.asarray(groups)
            if g.shape != (self.vertex_count,) or g.dtype.kind not in "iu":
                raise ValueError(f"Mesh.position_classes: groups must be an int array of shape "
                                 f"[{self.vertex_count}], got {_describe(g)}")
            key = np.column_stack([key, g.astype(np.float64)])
        if self.vertex_count == 0:
            return np.zeros(0, dtype=np.int64)
        order = np.lexsort(key.T[::-1])  # by x, then y, then z (then group)
        ranked = key[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (ranked[1:] != ranked[:-1]).any(axis=1)
        classes = np.empty(len(order), dtype=np.int64)
        classes[order] = np.cumsum(new) - 1
        return classes

    def vertex_normals(self, mode: NormalWeighting = "area", weld: bool = True, groups: Any = None) -> np.ndarray:
        """Per-vertex unit normals averaged from the faces around each position, float64 [N, 3].

        Parameters
        ----------
        mode : {"area", "angle"}
            ``"area"``: the sum of the unnormalized face normals ``cross(p1 - p0, p2 - p0)``
            of the triangles at the vertex, so each face counts in proportion to its area.
            ``"angle"``: the sum of the unit face normals, each times the triangle's interior
            angle at that vertex (independent of how the surface is cut into triangles).
        weld : bool
            True (the default): the sum runs over every triangle around the vertex's
            *position* (:meth:`position_classes`), so vertex records at one position get
            one normal. A mesh whose vertices are split where their texture coordinates
            differ (a UV seam), or whose file repeats positions at patch borders (the Utah
            teapot), is then smooth across the split; the vertex records themselves, and
            their uvs, stay as they are. False: per vertex record, so a split shows as a
            crease.
        groups : int array [N], optional
            With ``weld``: only vertices of the same group share a normal (a crease
            between groups; the OBJ loader passes its smoothing groups).

        Vertices used by no triangle, or only by degenerate ones, get the zero vector
        (welded: unless another vertex at their position is used by one).
        """
        if mode == "area":
            weighted = np.repeat(self.face_normals(normalized=False)[:, None, :], 3, axis=1)
        elif mode == "angle":
            weighted = self.face_normals()[:, None, :] * self.corner_angles()[:, :, None]
        else:
            raise ValueError(f"Mesh.vertex_normals: mode must be 'area' or 'angle', got {mode!r}")
        if weld:
            cls = self.position_classes(groups)
            count = int(cls.max(initial=-1)) + 1
        else:
            cls, count = np.arange(self.vertex_count), self.vertex_count
        flat_idx = cls[self.indices.ravel()]
        flat_w = weighted.reshape(-1, 3)
        total = np.stack(
            [np.bincount(flat_idx, weights=flat_w[:, k], minlength=count) for k in range(3)],
            axis=1,
        ).reshape(count, 3).astype(np.float64)  # bincount of nothing is an int array
        return _normalize_rows(total)[cls]

    def with_normals(self, mode: NormalWeighting = "area", weld: bool = True) -> "Mesh":
        """A copy whose ``normals`` are :meth:`vertex_normals` (replacing any it had)."""
        return self.replace(normals=self.vertex_normals(mode, weld))

    def signed_volume(self) -> float:
        """Σ p0 · (p1 × p2) / 6 over the triangles.

        For a closed surface this is its enclosed volume, positive when the triangles
        are counter-clockwise seen from outside; a quick test of outward winding.
        """
        p = self.corners()
        return float(np.einsum("ij,ij->", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6.0)

    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """(min, max) corners of the axis-aligned bounding box of all positions."""
        if self.vertex_count == 0:
            raise ValueError(f"Mesh.bounds: mesh {self.name!r} has no positions")
        return self.positions.min(axis=0), self.positions.max(axis=0)

    # ------------------------------------------------------------------ new meshes

    def transformed(self, matrix: Any) -> "Mesh":
        """The mesh under an affine 4×4 matrix acting on column vectors (p' = M @ p).

        Normals go by the inverse transpose of the upper-left 3×3 and are renormalized,
        so they stay perpendicular to the surface under non-uniform scale. A mirroring
        matrix (negative determinant) would turn counter-clockwise triangles clockwise;
        the triangles' corner order is reversed so that front faces stay outward.
        Projections are the vertex stage's job, so the bottom row must be (0, 0, 0, 1).
        """
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"Mesh.transformed needs a 4x4 matrix, got shape {list(m.shape)}")
        if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(f"Mesh.transformed needs an affine matrix (bottom row 0 0 0 1), got {m[3].tolist()}")
        linear, offset = m[:3, :3], m[:3, 3]
        det = np.linalg.det(linear)
        if not np.isfinite(det) or abs(det) < 1e-300:
            raise ValueError("Mesh.transformed: the matrix is singular (it would flatten the mesh)")
        changes: dict = {"positions": self.positions @ linear.T + offset}
        if self.normals is not None:
            changes["normals"] = _normalize_rows(self.normals @ np.linalg.inv(linear))  # (A⁻ᵀ n)ᵀ = nᵀ A⁻¹
        if det < 0:
            changes["indices"] = self.indices[:, ::-1]
        return self.replace(**changes)

    def translated(self, offset: Sequence[float]) -> "Mesh":
        """The mesh moved by ``offset`` (normals unchanged)."""
        return self.replace(positions=self.positions + np.asarray(offset, dtype=np.float64))

    def centered(self) -> "Mesh":
        """The mesh moved so that its bounding box's centre is at the origin."""
        lo, hi = self.bounds()
        return self.translated(-(lo + hi) / 2.0)

    def normalized(self, size: float = 2.0) -> "Mesh":
        """Centered, and scaled uniformly so that the bounding box's largest side is ``size``."""
        if not size > 0:
            raise ValueError(f"Mesh.normalized: size must be > 0, got {size!r}")
        c = self.centered()
        lo, hi = c.bounds()
        extent = float(np.max(hi - lo))
        if extent == 0.0:
            raise ValueError(f"Mesh.normalized: mesh {self.name!r} has zero extent")
        # A uniform scale leaves unit normals unchanged.
        return c.replace(positions=c.positions * (size / extent))

    def scaled_to_unit(self) -> "Mesh":
        """``normalized(2.0)``: centered, and fitting [-1, 1]³ with the largest side touching."""
        return self.normalized(2.0)

    def flipped(self) -> "Mesh":
        """Inside out: corner order reversed and normals negated (e.g. for a sky dome)."""
        normals = None if self.normals is None else -self.normals
        return self.replace(indices=self.indices[:, ::-1], normals=normals)

    def flat_shaded(self) -> "Mesh":
        """Unshared vertices: each triangle gets three of its own, with its face normal.

        Vertex ``3t + c`` is corner ``c`` of triangle ``t``; uvs and materials carry over.
        The vertices of lines and points follow (in their order, normals zero: they
        have no face), so the lines and points are kept.
        """
        corner = self.indices.ravel()
        m = self.triangle_count
        loose = np.unique(np.concatenate([self.lines.ravel(), self.points]))
        order = np.concatenate([corner, loose])
        new_index = np.zeros(self.vertex_count, np.int64)
        new_index[loose] = 3 * m + np.arange(len(loose))
        return Mesh(
            positions=self.positions[order],
            indices=np.arange(3 * m, dtype=np.int32).reshape(m, 3),
            normals=np.concatenate([np.repeat(self.face_normals(), 3, axis=0), np.zeros((len(loose), 3))]),
            uvs=None if self.uvs is None else self.uvs[order],
            material=self.material,
            materials=self.materials,
            material_ids=self.material_ids,
            name=self.name,
            lines=new_index[self.lines],
            points=new_index[self.points],
            line_material_ids=self.line_material_ids,
            point_material_ids=self.point_material_ids,
        )

    def compacted(self) -> "Mesh":
        """The mesh without vertices that no triangle, segment or point uses, keeping their order."""
        used = np.zeros(self.vertex_count, dtype=bool)
        used[self.indices.ravel()] = True
        used[self.lines.ravel()] = True
        used[self.points] = True
        if used.all():
            return self
        new_index = np.cumsum(used) - 1
        return self.replace(
            positions=self.positions[used],
            indices=new_index[self.indices],
            lines=new_index[self.lines],
            points=new_index[self.points],
            normals=None if self.normals is None else self.normals[used],
            uvs=None if self.uvs is None else self.uvs[used],
            source=None,
        )

    def by_material(self) -> list:
        """One single-material mesh per material used, as ``[(material, mesh), ...]``.

        In the order of ``materials``; this is what a renderer draws, one call each.
        """
        if self.material_ids is None:
            return [(self.material, self)]
        out = []
        no_lines, no_points = np.zeros(0, np.int32), np.zeros(0, np.int32)
        for k, mat in enumerate(self.materials):
            mask = self.material_ids == k
            line_mask = no_lines if self.line_material_ids is None else self.line_material_ids == k
            point_mask = no_points if self.point_material_ids is None else self.point_material_ids == k
            if mask.any() or line_mask.any() or point_mask.any():
                sub = Mesh(
                    self.positions, self.indices[mask], self.normals, self.uvs,
                    material=mat, name=f"{self.name}[{mat.name}]" if self.name else mat.name,
                    lines=self.lines[line_mask] if len(line_mask) else None,
                    points=self.points[point_mask] if len(point_mask) else None,
                )
                out.append((mat, sub.compacted()))
        return out


def concatenate(meshes: Iterable[Mesh], name: str = "") -> Mesh:
    """One mesh holding all the triangles (segments, points) of ``meshes``.

    Normals (uvs) are kept when every mesh has them and dropped when none has; a mix
    is an error, since inventing the missing ones would be a silent guess. Different
    materials become ``materials`` + ``material_ids``.
    """
    meshes = list(meshes)
    if not meshes:
        raise ValueError("concatenate: no meshes given")
    attrs = {}
    for attr in ("normals", "uvs"):
        have = [m.name or f"#{i}" for i, m in enumerate(meshes) if getattr(m, attr) is not None]
        if have and len(have) != len(meshes):
            raise ValueError(f"concatenate: only some meshes have {attr} ({', '.join(have)})")
        attrs[attr] = np.concatenate([getattr(m, attr) for m in meshes]) if have else None
    offsets = np.cumsum([0] + [m.vertex_count for m in meshes])
    indices = np.concatenate([m.indices.astype(np.int64) + off for m, off in zip(meshes, offsets)])
    palette: list = []
    ids: list = []
    line_ids: list = []
    point_ids: list = []
    for m in meshes:
        local = [m.material] if m.material_ids is None else list(m.materials)
        remap = []
        for mat in local:
            key = (mat, mat.name)  # equal values under different names stay apart
            found = [i for i, p in enumerate(palette) if (p, p.name) == key]
            if not found:
                palette.append(mat)
            remap.append(found[0] if found else len(palette) - 1)
        local_ids = np.zeros(m.triangle_count, np.int64) if m.material_ids is None else m.material_ids
        ids.append(np.asarray(remap, dtype=np.int64)[local_ids] if m.triangle_count else local_ids)
        for out, count, own in ((line_ids, m.segment_count, m.line_material_ids),
                                (point_ids, m.point_count, m.point_material_ids)):
            local_ids = np.zeros(count, np.int64) if own is None else own
            out.append(np.asarray(remap, dtype=np.int64)[local_ids] if count else np.zeros(0, np.int64))
    single = len(palette) == 1
    lines = np.concatenate([m.lines.astype(np.int64) + off for m, off in zip(meshes, offsets)])
    points = np.concatenate([m.points.astype(np.int64) + off for m, off in zip(meshes, offsets)])
    return Mesh(
        positions=np.concatenate([m.positions for m in meshes]),
        indices=indices,
        normals=attrs["normals"],
        uvs=attrs["uvs"],
        material=palette[0],
        materials=() if single else tuple(palette),
        material_ids=None if single else np.concatenate(ids),
        name=name,
        lines=lines,
        points=points,
        line_material_ids=None if single or not len(lines) else np.concatenate(line_ids),
        point_material_ids=None if single or not len(points) else np.concatenate(point_ids),
    )
