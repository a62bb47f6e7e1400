"""Building a BVH: the binary tree by binned SAH, then the traversal's wide nodes and triangle blocks.

**The binary tree** (:func:`binary_tree`). A node's triangles are split in two by a plane
along x, y or z, chosen by the surface area heuristic (SAH): a ray that meets a box meets a
child box inside it with probability A_child / A_parent, so a split is expected to cost

    C_trav + Σ_children (A_child / A_parent) · N_child · C_isect.

The centroids are sorted into ``bins`` equal bins per axis and the ``bins − 1`` planes
between them are costed on all three axes ("binned SAH", Wald 2007; pbrt §4.3). Ranges of
at most ``leaf_size`` triangles become leaves. Where no plane separates the centroids, or
the tree has grown deep, a range is halved at its median, so every leaf stays shallower
than :data:`~softpipe.rays.layout.MAX_DEPTH`. The build is serial and deterministic.

**The traversal's arrays** (:func:`wide_tree`): the binary tree collapsed into wide nodes of
up to four children, their boxes packed side by side in float32 rounded outward (so each
holds its float64 box), and the leaves' triangles copied into blocks of four
(:mod:`softpipe.rays.layout`). :meth:`~softpipe.rays.bvh.BVH.refit` reuses
:func:`gather_corners`, :func:`refit_boxes`, :func:`fill_blocks` and :func:`pack_boxes` on
the same tree. docs/raytracing.md ("The BVH") explains the shapes; build times are in
benchmarks/README.md ("Rays").
"""
from __future__ import annotations

import numba
import numpy as np

from softpipe.rays.layout import BLOCK, MAX_DEPTH, REF_SHIFT, WIDTH

__all__ = ["binary_tree", "wide_tree", "gather_corners", "refit_boxes", "fill_blocks", "pack_boxes"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _area(dx, dy, dz):
    return 2.0 * (dx * dy + dy * dz + dz * dx)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _select(order, s, e, k, cen, a):
    """Reorder ``order[s:e]`` so that the k-th has the median centroid along axis a: none before it
    larger, none after it smaller (Hoare's quickselect; deterministic)."""
    lo_, hi_ = s, e - 1
    while lo_ < hi_:
        pivot = cen[order[(lo_ + hi_) // 2], a]
        i, j = lo_, hi_
        while i <= j:
            while cen[order[i], a] < pivot:
                i += 1
            while cen[order[j], a] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if k <= j:
            hi_ = j
        elif k >= i:
            lo_ = i
        else:
            return


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _build_kernel(tri_lo, tri_hi, cen, leaf_size, bins, lo, hi, first, count, order):
    """Binned SAH build into preallocated node arrays; returns (node count, deepest leaf's depth)."""
    T = tri_lo.shape[0]
    for i in range(T):
        order[i] = i
    if T == 0:
        return 0, 0
    # past this depth, ranges are halved at the median, so depth < MAX_DEPTH
    levels = 0
    while (1 << levels) < T:
        levels += 1
    median_from = max(0, MAX_DEPTH - 2 - levels)
    # the task stack: (start, end, parent, depth); a right child is pushed under its left sibling
    ts = np.empty(2 * MAX_DEPTH + 4, np.int64)
    te = np.empty(2 * MAX_DEPTH + 4, np.int64)
    tp = np.empty(2 * MAX_DEPTH + 4, np.int64)
    td = np.empty(2 * MAX_DEPTH + 4, np.int64)
    ts[0], te[0], tp[0], td[0] = 0, T, -1, 0
    top = 1
    nodes = 0
    deepest = 0
    bin_count = np.empty((3, bins), np.int64)
    bin_lo = np.empty((3, bins, 3))
    bin_hi = np.empty((3, bins, 3))
    right_area = np.empty(bins)
    right_n = np.empty(bins, np.int64)
    clo, chi = np.empty(3), np.empty(3)
    while top > 0:
        top -= 1
        s, e, parent, depth = ts[top], te[top], tp[top], td[top]
        node = nodes
        nodes += 1
        if parent >= 0:                      # only right children are pushed with a parent
            first[parent] = node
        # the node's box and its centroids' box
        for a in range(3):
            clo[a], chi[a] = np.inf, -np.inf
            lo[node, a] = np.inf
            hi[node, a] = -np.inf
        for i in range(s, e):
            j = order[i]
            for a in range(3):
                lo[node, a] = min(lo[node, a], tri_lo[j, a])
                hi[node, a] = max(hi[node, a], tri_hi[j, a])
                clo[a] = min(clo[a], cen[j, a])
                chi[a] = max(chi[a], cen[j, a])
        n = e - s
        if n <= leaf_size:
            first[node] = s
            count[node] = n
            deepest = max(deepest, depth)
            continue
        count[node] = 0
        best_axis, best_split, best_cost = -1, -1, np.inf
        if depth < median_from:
            # bin the centroids along every axis with extent
            for a in range(3):
                ext = chi[a] - clo[a]
                if not ext > 0.0:
                    continue
                scale = bins / ext
                for b in range(bins):
                    bin_count[a, b] = 0
                    for c in range(3):
                        bin_lo[a, b, c] = np.inf
                        bin_hi[a, b, c] = -np.inf
                for i in range(s, e):
                    j = order[i]
                    b = min(bins - 1, int((cen[j, a] - clo[a]) * scale))
                    bin_count[a, b] += 1
                    for c in range(3):
                        bin_lo[a, b, c] = min(bin_lo[a, b, c], tri_lo[j, c])
                        bin_hi[a, b, c] = max(bin_hi[a, b, c], tri_hi[j, c])
                # sweep from the right: area and count of bins b+1 … bins−1
                rx0, ry0, rz0, rx1, ry1, rz1 = np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf
                rn = 0
                for b in range(bins - 1, 0, -1):
                    if bin_count[a, b] > 0:
                        rx0, ry0, rz0 = min(rx0, bin_lo[a, b, 0]), min(ry0, bin_lo[a, b, 1]), min(rz0, bin_lo[a, b, 2])
                        rx1, ry1, rz1 = max(rx1, bin_hi[a, b, 0]), max(ry1, bin_hi[a, b, 1]), max(rz1, bin_hi[a, b, 2])
                        rn += bin_count[a, b]
                    right_n[b - 1] = rn
                    right_area[b - 1] = _area(rx1 - rx0, ry1 - ry0, rz1 - rz0) if rn > 0 else 0.0
                # sweep from the left: the cost of the plane after bin b
                lx0, ly0, lz0, lx1, ly1, lz1 = np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf
                ln = 0
                for b in range(bins - 1):
                    if bin_count[a, b] > 0:
                        lx0, ly0, lz0 = min(lx0, bin_lo[a, b, 0]), min(ly0, bin_lo[a, b, 1]), min(lz0, bin_lo[a, b, 2])
                        lx1, ly1, lz1 = max(lx1, bin_hi[a, b, 0]), max(ly1, bin_hi[a, b, 1]), max(lz1, bin_hi[a, b, 2])
                        ln += bin_count[a, b]
                    if ln == 0 or right_n[b] == 0:
                        continue
                    # C_trav + (A_L·N_L + A_R·N_R)/A_parent·C_isect: C_trav, C_isect and
                    # 1/A_parent are the same for every plane of this node (and a flat
                    # parent has area 0), so the planes are compared by A_L·N_L + A_R·N_R
                    cost = _area(lx1 - lx0, ly1 - ly0, lz1 - lz0) * ln + right_area[b] * right_n[b]
                    if cost < best_cost:
                        best_axis, best_split, best_cost = a, b, cost
        if best_axis >= 0:
            # partition order[s:e]: bins ≤ best_split to the left (same arithmetic as the binning)
            a = best_axis
            scale = bins / (chi[a] - clo[a])
            i, j = s, e - 1
            while i <= j:
                if min(bins - 1, int((cen[order[i], a] - clo[a]) * scale)) <= best_split:
                    i += 1
                else:
                    order[i], order[j] = order[j], order[i]
                    j -= 1
            mid = i
        else:
            # no plane separates the centroids (or the tree is deep): halve at the median
            # along the centroids' widest axis
            a = 0
            for c in range(1, 3):
                if chi[c] - clo[c] > chi[a] - clo[a]:
                    a = c
            mid = s + n // 2
            _select(order, s, e, mid, cen, a)
        # right child below the left on the stack: the left is built next, at node + 1
        ts[top], te[top], tp[top], td[top] = mid, e, node, depth + 1
        top += 1
        ts[top], te[top], tp[top], td[top] = s, mid, -1, depth + 1
        top += 1
    return nodes, deepest


@numba.njit(cache=True, nogil=True, error_model="numpy")
def gather_corners(vertices: np.ndarray, triangles: np.ndarray, order: np.ndarray, corners: np.ndarray) -> None:
    """The corners of every triangle in leaf order, into ``corners`` [T, 9]: row k is v0, v1, v2 of
    triangle order[k]."""
    for k in range(order.shape[0]):
        t = order[k]
        for c in range(3):
            for a in range(3):
                corners[k, 3 * c + a] = vertices[triangles[t, c], a]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def refit_boxes(lo: np.ndarray, hi: np.ndarray, first: np.ndarray, count: np.ndarray, corners: np.ndarray) -> None:
    """Every node's box (``lo``, ``hi``, in place) from the leaves' ``corners``, bottom-up: children come after
    their parent in depth-first order, so the walk goes backwards."""
    for node in range(lo.shape[0] - 1, -1, -1):
        n = count[node]
        if n > 0:
            f = first[node]
            for a in range(3):
                mn, mx = np.inf, -np.inf
                for k in range(f, f + n):
                    mn = min(mn, corners[k, a], corners[k, 3 + a], corners[k, 6 + a])
                    mx = max(mx, corners[k, a], corners[k, 3 + a], corners[k, 6 + a])
                lo[node, a], hi[node, a] = mn, mx
        else:
            l, r = node + 1, first[node]
            for a in range(3):
                lo[node, a] = min(lo[l, a], lo[r, a])
                hi[node, a] = max(hi[l, a], hi[r, a])


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _leaf_blocks(count, leaf_block):
    """Each leaf's first block of BLOCK triangles (leaves in depth-first order; −1 for an inner node);
    returns the number of blocks."""
    blocks = 0
    for node in range(count.shape[0]):
        n = count[node]
        if n > 0:
            leaf_block[node] = blocks
            blocks += (n + BLOCK - 1) // BLOCK
        else:
            leaf_block[node] = -1
    return blocks


@numba.njit(cache=True, nogil=True, error_model="numpy")
def fill_blocks(first: np.ndarray, count: np.ndarray, leaf_block: np.ndarray, corners: np.ndarray, order: np.ndarray,
                tris: np.ndarray, tri_ids: np.ndarray) -> None:
    """The leaves' triangles in blocks, in place: tris[b, 3c + a, j] is coordinate a of corner c of lane j's
    triangle, tri_ids[b, j] its id; a leaf's last block is padded with NaN corners (never hit) and id −1."""
    for node in range(count.shape[0]):
        n = count[node]
        if n == 0:
            continue
        b0, f = leaf_block[node], first[node]
        for q in range(((n + BLOCK - 1) // BLOCK) * BLOCK):
            b, j = b0 + q // BLOCK, q % BLOCK
            if q < n:
                tri_ids[b, j] = order[f + q]
                for r in range(9):
                    tris[b, r, j] = corners[f + q, r]
            else:
                tri_ids[b, j] = -1
                for r in range(9):
                    tris[b, r, j] = np.nan


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _collapse_kernel(lo, hi, first, count, leaf_block, lane_node, links):
    """The wide nodes from the binary tree; returns their number M (rows filled in ``lane_node``, ``links``).

    A wide node starts from a binary inner node's two children and, while it has
    fewer than WIDTH, replaces its inner child of largest surface area by that
    child's two children (the child most rays that reach the node enter). Each
    inner child left over becomes a wide node in turn, numbered as made (the
    children of one node next to each other). ``lane_node[w, j]`` is the binary
    node of child j of wide node w (−1: an empty lane); ``links[w, j]`` is that
    child as the traversal codes it: ``ref << REF_SHIFT | n`` with n = 0 and ref its wide
    node, or n > 0 triangles from ``ref`` (a leaf).
    """
    N = count.shape[0]
    if N == 0 or count[0] > 0:
        return 0
    pending = np.empty(N, np.int64)          # binary inner nodes waiting to be expanded, and their wide numbers
    pending_w = np.empty(N, np.int64)
    pending[0], pending_w[0] = 0, 0
    top = 1
    made = 1
    kids = np.empty(WIDTH, np.int64)
    while top > 0:
        top -= 1
        node, w = pending[top], pending_w[top]
        kids[0], kids[1] = node + 1, first[node]
        k = 2
        while k < WIDTH:
            best, best_area = -1, -1.0
            for j in range(k):
                c = kids[j]
                if count[c] == 0:
                    ex, ey, ez = hi[c, 0] - lo[c, 0], hi[c, 1] - lo[c, 1], hi[c, 2] - lo[c, 2]
                    area = _area(ex, ey, ez)
                    if area > best_area:
                        best, best_area = j, area
            if best < 0:
                break
            c = kids[best]
            kids[best], kids[k] = c + 1, first[c]
            k += 1
        for j in range(WIDTH):
            if j >= k:
                lane_node[w, j] = -1
                links[w, j] = 0
                continue
            c = kids[j]
            lane_node[w, j] = c
            if count[c] > 0:
                links[w, j] = (leaf_block[c] << REF_SHIFT) | count[c]
            else:
                links[w, j] = made << REF_SHIFT
                pending[top], pending_w[top] = c, made
                top += 1
                made += 1
    return made


@numba.njit(cache=True, nogil=True, error_model="numpy")
def pack_boxes(lo: np.ndarray, hi: np.ndarray, lane_node: np.ndarray, boxes: np.ndarray) -> None:
    """In place, boxes[w, r, j] = coordinate r (lo.x, lo.y, lo.z, hi.x, hi.y, hi.z) of child j's box, in float32
    rounded outward (lo down, hi up) so that every float32 box holds its float64 box; empty lanes
    (lo = +inf, hi = −inf) hold nothing."""
    down, up = np.float32(-np.inf), np.float32(np.inf)
    for w in range(lane_node.shape[0]):
        for j in range(WIDTH):
            c = lane_node[w, j]
            for a in range(3):
                if c < 0:
                    boxes[w, a, j], boxes[w, 3 + a, j] = up, down
                    continue
                f = np.float32(lo[c, a])
                if f > lo[c, a]:                 # rounded up: one float32 step down
                    f = np.nextafter(f, down)
                boxes[w, a, j] = f
                f = np.float32(hi[c, a])
                if f < hi[c, a]:
                    f = np.nextafter(f, up)
                boxes[w, 3 + a, j] = f


def binary_tree(vertices: np.ndarray, triangles: np.ndarray, leaf_size: int, bins: int) -> tuple:
    """The binary SAH tree over checked inputs, flattened depth first.

    Parameters
    ----------
    vertices : float64 [V, 3]
        Finite, C-contiguous.
    triangles : int64 [T, 3]
        C-contiguous indices into ``vertices`` (T may be 0).
    leaf_size, bins : int
        At most this many triangles a leaf; this many bins per axis (≥ 2).

    Returns
    -------
    tuple
        ``(lo, hi, first, count, order, corners, depth)``: the node arrays [N, 3], [N, 3], [N], [N],
        the triangle ids in leaf order [T], their corners in that order [T, 9] (v0, v1, v2) and the
        deepest leaf's depth (root 0). See :class:`~softpipe.rays.bvh.BVH`.
    """
    T = len(triangles)
    corners = vertices[triangles] if T else np.zeros((0, 3, 3))
    tri_lo = np.ascontiguousarray(corners.min(axis=1))
    tri_hi = np.ascontiguousarray(corners.max(axis=1))
    cen = 0.5 * (tri_lo + tri_hi)
    cap = max(2 * T - 1, 0)
    lo, hi = np.empty((cap, 3)), np.empty((cap, 3))
    first, count = np.empty(cap, np.int64), np.empty(cap, np.int64)
    order = np.empty(T, np.int64)
    nodes, depth = _build_kernel(tri_lo, tri_hi, cen, int(leaf_size), int(bins), lo, hi, first, count, order)
    assert depth < MAX_DEPTH, depth
    lo, hi = lo[:nodes].copy(), hi[:nodes].copy()
    first, count = first[:nodes].copy(), count[:nodes].copy()
    leaf_corners = np.empty((T, 9))
    gather_corners(vertices, triangles, order, leaf_corners)
    return lo, hi, first, count, order, leaf_corners, int(depth)


def wide_tree(lo: np.ndarray, hi: np.ndarray, first: np.ndarray, count: np.ndarray, order: np.ndarray,
              corners: np.ndarray) -> tuple:
    """The traversal's arrays from a binary tree (the arrays :func:`binary_tree` returns).

    Returns
    -------
    tuple
        ``(leaf_block, lane_node, links, boxes, tris, tri_ids)``: each binary node's first
        triangle block (−1 for an inner node) [N]; the binary node of each wide node's child
        [M, WIDTH] (−1: empty) — these two are what :meth:`~softpipe.rays.bvh.BVH.refit` needs to
        refill the others —; the children as ``ref << REF_SHIFT | n`` [M, WIDTH]; their boxes,
        float32 [M, 6, WIDTH]; the triangles' corners in blocks, float64 [B, 9, BLOCK]; their ids
        [B, BLOCK] (−1: padding).
    """
    cap = max(count.shape[0], 1)
    lane_node, links = np.empty((cap, WIDTH), np.int64), np.empty((cap, WIDTH), np.int64)
    leaf_block = np.empty(count.shape[0], np.int64)
    blocks = _leaf_blocks(count, leaf_block)
    tris = np.empty((blocks, 9, BLOCK))
    tri_ids = np.empty((blocks, BLOCK), np.int64)
    fill_blocks(first, count, leaf_block, corners, order, tris, tri_ids)
    M = _collapse_kernel(lo, hi, first, count, leaf_block, lane_node, links)
    lane_node, links = lane_node[:M].copy(), links[:M].copy()
    boxes = np.empty((M, 6, WIDTH), np.float32)
    pack_boxes(lo, hi, lane_node, boxes)
    return leaf_block, lane_node, links, boxes, tris, tri_ids
