"""Rays against triangles: the bounding volume hierarchy (BVH) and its two queries (FORMULAS §21, §22).

A ray ``p(t) = origin + t·direction`` asks one of two questions of a scene's triangles:
**closest hit** (which triangle does it meet first in ``t_min < t < t_max``, where, at which
barycentrics: a camera or a reflected ray) and **any hit** (is there any: a shadow ray, which
stops at the first found). Testing every triangle costs T tests a ray; a BVH answers in
about log T steps, since a ray that misses a node's box misses everything below it.

This module is the public face: :class:`BVH` (built by binned SAH, refitted when the
triangles move, its batch queries :meth:`BVH.closest` and :meth:`BVH.occluded` run in
parallel bands), :class:`BVHUniform` (a BVH as a shader receives it), :func:`closest_hit`
and :func:`any_hit` (one ray, from compiled code: a shader, the ray tracer) and
:func:`scene_bvh` (one world-space BVH over a scene's objects: flattened, not instanced).
The parts live beside it:

- :mod:`softpipe.rays.triangle`: the exact, watertight ray/triangle test;
- :mod:`softpipe.rays.build`: the binned SAH tree, and the traversal's wide nodes and blocks;
- :mod:`softpipe.rays.traverse`: the walk, for one ray and for batches;
- :mod:`softpipe.rays.layout`: the sizes and codes the build and the walk share.

Here too: the queries hand the walk its arrays borrowed (:mod:`softpipe.core.borrow`).
Every answer is the same bytes on any thread count. docs/raytracing.md ("The BVH") has the
long explanations; benchmarks/README.md ("Rays") the timings.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from softpipe.core.borrow import borrowed
from softpipe.core.parallel import in_bands
from softpipe.rays.build import binary_tree, fill_blocks, gather_corners, pack_boxes, refit_boxes, wide_tree
from softpipe.rays.traverse import node_stack, query, query_inline, start_row, step, store, t_stack

__all__ = ["BVH", "BVHUniform", "closest_hit", "any_hit", "hit_inline", "scene_bvh"]

BVHUniform = namedtuple("BVHUniform", ["lo", "hi", "first", "count", "order", "v0", "v1", "v2",
                                       "boxes", "links", "tris", "tri_ids"])
BVHUniform.__doc__ = """A BVH as a shader receives it: its numpy arrays (see :class:`BVH`). The queries read
``lo``, ``hi`` (the root's box), ``first``, ``count`` (whether the root is a leaf) and the traversal's
``boxes``, ``links``, ``tris``, ``tri_ids``; ``order`` and ``v0``, ``v1``, ``v2`` are there for shaders."""


# The queries hand the walk *borrowed* arrays (softpipe.core.borrow): per ray, counting references
# to the BVH's eight arrays would cost more than a ray that misses the root box, and two threads
# would contend for the same counters.

# ------------------------------------------------------------------ the queries

@numba.njit(cache=True, nogil=True, error_model="numpy")
def closest_hit(bvh, origin, direction, t_min: float, t_max: float) -> tuple:
    """The nearest triangle on the ray in the open interval (t_min, t_max): (id, t, b1, b2).

    ``bvh`` is a :class:`BVHUniform`; ``origin``, ``direction`` 3-vectors (arrays
    or tuples; the direction need not be unit length, t is in its units). ``id``
    is −1 for a miss (then t = t_max, b1 = b2 = 0). Among hits at exactly the same
    t the lowest triangle id wins, so the answer does not depend on the tree.
    The hit point is (1 − b1 − b2)·v0 + b1·v1 + b2·v2 of triangle ``id``.
    """
    return query(borrowed(bvh.boxes), borrowed(bvh.links), borrowed(bvh.lo), borrowed(bvh.hi),
                 borrowed(bvh.first), borrowed(bvh.count), borrowed(bvh.tris), borrowed(bvh.tri_ids),
                 float(origin[0]), float(origin[1]), float(origin[2]),
                 float(direction[0]), float(direction[1]), float(direction[2]), float(t_min), float(t_max), False)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def any_hit(bvh, origin, direction, t_min: float, t_max: float) -> bool:
    """Whether any triangle lies on the ray in (t_min, t_max): stops at the first one found (shadow rays, §21)."""
    return query(borrowed(bvh.boxes), borrowed(bvh.links), borrowed(bvh.lo), borrowed(bvh.hi),
                 borrowed(bvh.first), borrowed(bvh.count), borrowed(bvh.tris), borrowed(bvh.tri_ids),
                 float(origin[0]), float(origin[1]), float(origin[2]),
                 float(direction[0]), float(direction[1]), float(direction[2]), float(t_min), float(t_max),
                 True)[0] >= 0


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def hit_inline(bvh, origin, direction, t_min: float, t_max: float, any_: bool) -> tuple:
    """:func:`closest_hit` (``any_`` False) or the any-hit walk of :func:`any_hit` (``any_`` True: id ≥ 0 for a
    hit), compiled into the caller: (id, t, b1, b2), the same bits.

    For a kernel that traces many rays per item (the path tracer): no call per ray. Each call site is a
    copy of the walk, so a kernel should have one per kind of ray.
    """
    return query_inline(borrowed(bvh.boxes), borrowed(bvh.links), borrowed(bvh.lo), borrowed(bvh.hi),
                        borrowed(bvh.first), borrowed(bvh.count), borrowed(bvh.tris), borrowed(bvh.tri_ids),
                        float(origin[0]), float(origin[1]), float(origin[2]),
                        float(direction[0]), float(direction[1]), float(direction[2]), float(t_min), float(t_max),
                        any_)


# Why two rays at a time. A ray's traversal is one long chain of dependent steps (a node's
# address comes from its parent's links, which child comes next from the boxes' tests) with
# hard-to-guess branches, so one ray leaves most of the core idle: testing every box and
# triangle twice was measured to add little to the time (benchmarks/README.md, "Rays"). The
# batch kernel therefore walks two rays in turn, a step of one then a step of the other (each
# on its own stack; softpipe.rays.traverse's start_row, step, store), and starts the band's next
# ray where one finishes: the core overlaps the two chains. Each ray's answer is computed
# exactly as alone, so the bytes do not change. The loop lives here, beside the borrowing: in
# one body with it, the compiler sees that the arrays have no owner and drops the reference
# counting of the inlined steps. A loop of its own in traverse.py, called with borrowed arrays,
# ran slower as a call and compiled to other code inlined (benchmarks/README.md, "Rays").

@numba.njit(cache=True, nogil=True, error_model="numpy")
def _batch_kernel(lo_, hi_, bvh, origins, directions, t_min, t_max, any_, ids, ts, bs, occluded):
    """Rays lo_ … hi_ − 1 of a batch, two in flight: closest hits into ids, ts, bs, or (any_) any hits
    into occluded."""
    sa_node, sa_t, sb_node, sb_t = node_stack(), t_stack(), node_stack(), t_stack()
    boxes, links, lo, hi = borrowed(bvh.boxes), borrowed(bvh.links), borrowed(bvh.lo), borrowed(bvh.hi)
    first, count, tris, tri_ids = borrowed(bvh.first), borrowed(bvh.count), borrowed(bvh.tris), \
        borrowed(bvh.tri_ids)
    ia, ib = lo_, lo_ + 1
    ray_a, st_a = start_row(lo, hi, first, count, origins, directions, t_min, t_max, ia)
    if ib < hi_:
        ray_b, st_b = start_row(lo, hi, first, count, origins, directions, t_min, t_max, ib)
    else:
        ib = -1
        ray_b, st_b = ray_a, st_a
    nxt = lo_ + 2
    while ia >= 0 or ib >= 0:
        if ia >= 0:
            if st_a[0]:
                st_a = step(boxes, links, tris, tri_ids, ray_a, st_a, any_, sa_node, sa_t)
            else:
                store(ia, st_a, any_, ids, ts, bs, occluded)
                if nxt < hi_:
                    ia = nxt
                    nxt += 1
                    ray_a, st_a = start_row(lo, hi, first, count, origins, directions, t_min, t_max, ia)
                else:
                    ia = -1
        if ib >= 0:
            if st_b[0]:
                st_b = step(boxes, links, tris, tri_ids, ray_b, st_b, any_, sb_node, sb_t)
            else:
                store(ib, st_b, any_, ids, ts, bs, occluded)
                if nxt < hi_:
                    ib = nxt
                    nxt += 1
                    ray_b, st_b = start_row(lo, hi, first, count, origins, directions, t_min, t_max, ib)
                else:
                    ib = -1


# ------------------------------------------------------------------ the BVH

# the outputs a batch kernel is given but does not write (occluded for closest hits, the rest for any hits)
_NO_IDS, _NO_TS, _NO_BS, _NO_BOOLS = np.empty(0, np.int64), np.empty(0), np.empty((0, 2)), np.empty(0, np.bool_)


def _describe(a: np.ndarray) -> str:
    return f"shape {tuple(a.shape)}, dtype {a.dtype}"


def _vertices(name: str, vertices, rows=None) -> np.ndarray:
    v = np.asarray(vertices)
    if v.dtype == object or not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer)):
        raise TypeError(f"{name} must be a float array [V, 3], got {_describe(v)}")
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"{name} must have shape [V, 3], got {_describe(v)}")
    if rows is not None and v.shape[0] != rows:
        raise ValueError(f"{name} must have the {rows} rows the BVH was built with, got {_describe(v)}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise ValueError(f"{name} ({_describe(v)}) has non-finite values in row(s) {np.flatnonzero(bad)[:5].tolist()}")
    return v


def _rays(name: str, value, rows=None) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype == object or not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise TypeError(f"{name} must be a float array [R, 3], got {_describe(a)}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape [R, 3], got {_describe(a)}")
    if rows is not None and a.shape[0] != rows:
        raise ValueError(f"{name} must have as many rows as origins ({rows}), got {_describe(a)}")
    a = np.ascontiguousarray(a, dtype=np.float64)
    if not np.isfinite(a).all():
        raise ValueError(f"{name} ({_describe(a)}) has non-finite values")
    return a


def _interval(name: str, value, rows: int) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return np.full(rows, float(a))
    if a.shape != (rows,):
        raise ValueError(f"{name} must be a number or an array [R] with R = {rows}, got {_describe(a)}")
    if np.isnan(a).any():
        raise ValueError(f"{name} ({_describe(a)}) has NaN values")
    return np.ascontiguousarray(a)


class BVH:
    """A bounding volume hierarchy over triangles; make one with :meth:`BVH.build`.

    Node arrays (N nodes, depth first, node 0 the root):

    - ``lo``, ``hi`` float64 [N, 3]: the node's box;
    - ``first`` int64 [N]: an inner node's right child (its left child is
      node + 1), a leaf's first index into ``order``;
    - ``count`` int64 [N]: 0 for an inner node, the number of triangles (1 to
      ``leaf_size``) of a leaf.

    Triangle arrays (T triangles, in leaf order):

    - ``order`` int64 [T]: the triangle ids, leaf by leaf;
    - ``corners`` float64 [T, 9]: v0, v1, v2 of triangle ``order[k]``; ``v0``,
      ``v1``, ``v2`` [T, 3] are views of its columns.

    The traversal's arrays (:mod:`softpipe.rays.layout`; made from the above by
    the build, :func:`softpipe.rays.build.wide_tree`, kept up to date by :meth:`refit`):

    - ``boxes`` float32 [M, 6, 4]: wide node w's children's boxes, row r
      (lo.x, lo.y, lo.z, hi.x, hi.y, hi.z) of child j at ``[w, r, j]``, rounded
      outward; an empty child is lo = +inf, hi = −inf;
    - ``links`` int64 [M, 4]: child j of wide node w as ``ref << 32 | n``
      (n = 0: wide node ref; n > 0: a leaf of n triangles from block ref);
    - ``tris`` float64 [B, 9, 4], ``tri_ids`` int64 [B, 4]: the leaves'
      triangles in blocks of four, coordinate ``3c + a`` of corner c of lane j at
      ``[b, 3c + a, j]``, the lane's triangle id (−1 and NaN corners: padding).

    ``triangles`` (int64 [T, 3]) and ``vertex_count`` are the input, kept for
    :meth:`refit`; ``depth`` is the deepest leaf's depth (root 0). ``uniform``
    is a :class:`BVHUniform` of the arrays above, what compiled code (a shader)
    passes to :func:`closest_hit` and :func:`any_hit`.

    Example::

        mesh = load_model("bunny")
        bvh = BVH.build(mesh.positions, mesh.indices)
        ids, t, b = bvh.closest(origins, directions)          # [R], [R], [R, 2]
        lit = ~bvh.occluded(points, to_light, 1e-6, 1.0)      # shadow rays (FORMULAS §21)

        @numba.njit
        def shade(bvh, p, d):                                 # bvh: the BVH passed as a uniform
            tri, t, b1, b2 = closest_hit(bvh, p, d, 0.0, math.inf)
    """

    def __init__(self, lo, hi, first, count, order, corners, triangles, vertex_count, depth, leaf_size, bins):
        self.lo, self.hi, self.first, self.count, self.order = lo, hi, first, count, order
        self.corners = corners
        self.v0, self.v1, self.v2 = corners[:, 0:3], corners[:, 3:6], corners[:, 6:9]
        self.triangles, self.vertex_count, self.depth = triangles, vertex_count, depth
        self.leaf_size, self.bins = leaf_size, bins
        # _leaf_block and _lane_node tie the traversal's arrays to the binary tree, for refit
        self._leaf_block, self._lane_node, self.links, self.boxes, self.tris, self.tri_ids = \
            wide_tree(lo, hi, first, count, order, corners)
        self.uniform = BVHUniform(lo, hi, first, count, order, self.v0, self.v1, self.v2,
                                  self.boxes, self.links, self.tris, self.tri_ids)

    @classmethod
    def build(cls, vertices, triangles, *, leaf_size: int = 4, bins: int = 16) -> "BVH":
        """Build a BVH by binned SAH (:mod:`softpipe.rays.build`) over ``triangles`` [T, 3] into ``vertices`` [V, 3].

        Vertices are in world space (float, finite); triangles index them (any
        integer type). No triangles is allowed: every ray misses. Degenerate
        triangles (zero area) are kept and never hit. The build is serial and
        deterministic: the same input gives the same arrays. ``leaf_size=4``
        traced about as fast as any size from 2 to 8, and 16 bins as fast as 32
        (benchmarks/README.md, "Rays", has the build times and the trials).
        """
        if isinstance(leaf_size, bool) or not isinstance(leaf_size, (int, np.integer)) or leaf_size < 1:
            raise ValueError(f"BVH.build: leaf_size must be an integer ≥ 1, got {leaf_size!r}")
        if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 2:
            raise ValueError(f"BVH.build: bins must be an integer ≥ 2, got {bins!r}")
        v = _vertices("vertices", vertices)
        tri = np.asarray(triangles)
        if tri.size == 0 and tri.dtype == np.float64:     # np.asarray([]) is float
            tri = tri.astype(np.int64)
        if not np.issubdtype(tri.dtype, np.integer):
            raise TypeError(f"triangles must be an integer array [T, 3], got {_describe(tri)}")
        if tri.ndim != 2 or tri.shape[1] != 3:
            if tri.size == 0:
                tri = tri.reshape(0, 3)
            else:
                raise ValueError(f"triangles must have shape [T, 3], got {_describe(tri)}")
        tri = np.ascontiguousarray(tri, dtype=np.int64)
        if tri.size and (tri.min() < 0 or tri.max() >= len(v)):
            bad = np.flatnonzero(((tri < 0) | (tri >= len(v))).any(axis=1))
            raise ValueError(f"triangles ({_describe(tri)}) index outside vertices ({_describe(v)}): "
                             f"row(s) {bad[:5].tolist()}, e.g. {tri[bad[0]].tolist()}; indices must be in [0, {len(v)})")
        T = len(tri)
        if T >= 2 ** 31:
            raise ValueError(f"BVH.build: at most 2³¹ − 1 triangles (the traversal's int32 links), got {T}")
        lo, hi, first, count, order, corners, depth = binary_tree(v, tri, int(leaf_size), int(bins))
        return cls(lo, hi, first, count, order, corners, tri, len(v), depth, int(leaf_size), int(bins))

    def refit(self, vertices) -> None:
        """Move the triangles to new ``vertices`` (same count, same triangles) and refit every box, in place.

        The tree is kept: only the corners and the boxes are recomputed, leaves
        first, each inner box the union of its children's (O(N), much cheaper
        than a build). Results stay exact, but a big motion makes the boxes
        overlap and grow and the traversal slower: rebuild (:meth:`build`) then.
        ``uniform`` keeps pointing at the same, updated arrays.
        """
        v = _vertices("vertices", vertices, rows=self.vertex_count)
        gather_corners(v, self.triangles, self.order, self.corners)
        refit_boxes(self.lo, self.hi, self.first, self.count, self.corners)
        fill_blocks(self.first, self.count, self._leaf_block, self.corners, self.order, self.tris, self.tri_ids)
        pack_boxes(self.lo, self.hi, self._lane_node, self.boxes)

    def __softpipe_uniform__(self) -> BVHUniform:
        """The value a shader receives for this BVH: :attr:`uniform`."""
        return self.uniform

    def __len__(self) -> int:
        return len(self.order)

    def __repr__(self) -> str:
        leaves = int((self.count > 0).sum())
        return f"BVH({len(self)} triangles, {len(self.count)} nodes, {leaves} leaves, depth {self.depth})"

    def closest(self, origins, directions, t_min=0.0, t_max=np.inf):
        """Closest hits of R rays: (ids int64 [R] (−1: miss), t [R] (inf: miss), b [R, 2] (b1, b2)).

        ``origins``, ``directions`` [R, 3]; ``t_min``, ``t_max`` numbers or [R]
        arrays. Runs :func:`closest_hit` in parallel bands; the same bytes for
        any thread count.
        """
        o = _rays("origins", origins)
        d = _rays("directions", directions, rows=len(o))
        R = len(o)
        t0, t1 = _interval("t_min", t_min, R), _interval("t_max", t_max, R)
        ids, ts, bs = np.empty(R, np.int64), np.empty(R), np.empty((R, 2))
        if R:
            in_bands(_batch_kernel, R, self.uniform, o, d, t0, t1, False, ids, ts, bs, _NO_BOOLS, grain=1024)
        return ids, ts, bs

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf):
        """Any-hit queries of R rays: bool [R], true where some triangle lies in (t_min, t_max). See :meth:`closest`."""
        o = _rays("origins", origins)
        d = _rays("directions", directions, rows=len(o))
        R = len(o)
        t0, t1 = _interval("t_min", t_min, R), _interval("t_max", t_max, R)
        out = np.empty(R, np.bool_)
        if R:
            in_bands(_batch_kernel, R, self.uniform, o, d, t0, t1, True, _NO_IDS, _NO_TS, _NO_BS, out, grain=1024)
        return out


def scene_bvh(objects, *, leaf_size: int = 4, bins: int = 16):
    """One world-space BVH over the triangles of SceneObjects: (bvh, triangle_object, triangle_local).

    Each object's mesh positions go through its model matrix
    (``SceneObject.world_positions``); the triangles are numbered object after
    object. ``triangle_object`` int64 [T] is the index in ``objects`` of each BVH
    triangle's object and ``triangle_local`` int64 [T] its index among that
    mesh's triangles. Flattened, not instanced (docs/raytracing.md, "The BVH"): when
    objects move, :meth:`BVH.refit` with the new world positions (concatenated in
    the same order) or build again.
    """
    objects = list(objects)
    positions, triangles, which, local = [], [], [], []
    base = 0
    for k, obj in enumerate(objects):
        p = np.asarray(obj.world_positions(), dtype=np.float64)
        idx = np.asarray(obj.mesh.indices, dtype=np.int64).reshape(-1, 3)
        positions.append(p)
        triangles.append(idx + base)
        which.append(np.full(len(idx), k, np.int64))
        local.append(np.arange(len(idx), dtype=np.int64))
        base += len(p)
    if not objects:
        return BVH.build(np.zeros((0, 3)), np.zeros((0, 3), np.int64), leaf_size=leaf_size, bins=bins), \
            np.zeros(0, np.int64), np.zeros(0, np.int64)
    bvh = BVH.build(np.concatenate(positions), np.concatenate(triangles), leaf_size=leaf_size, bins=bins)
    return bvh, np.concatenate(which), np.concatenate(local)
