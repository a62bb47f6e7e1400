"""Rays against triangles: a bounding volume hierarchy (BVH) and its two queries.

A ray ``p(t) = origin + t·direction`` asks one of two questions of a scene's
triangles (FORMULAS §21, §22):

- **closest hit**: which triangle does the ray meet first in ``t_min < t < t_max``,
  where, and at which barycentrics? (What a camera ray or a reflected ray needs.)
- **any hit**: is there *any* triangle in ``t_min < t < t_max``? (What a shadow ray
  needs: the first hit found answers it, so the search stops there, and a
  blocked ray is cheaper than its closest hit.)

Testing every triangle answers both, at T tests per ray (69,451 for the bunny).
A **BVH** answers them in about log T steps: a binary tree whose every node holds
an axis-aligned box around all the triangles below it, each leaf a few
triangles. A ray that misses a node's box misses everything in it, so one box
test skips a whole subtree; the closest-hit search also visits the nearer child
first and skips any box that begins beyond the nearest hit found so far.

**Building it: the surface area heuristic (SAH).** A node's triangles are split
in two by a plane along x, y or z; a random ray that meets a box meets a child box
inside it with probability A_child / A_parent (the ratio of surface areas), so the
expected cost of a split is

    cost = C_trav + Σ_children (A_child / A_parent) · N_child · C_isect

(N_child triangles in the child, C_trav the price of a box test, C_isect of a
triangle test). The build sorts the triangles' centroids into ``bins`` equal bins
along each axis, evaluates the cost of the ``bins − 1`` planes between bins on all
three axes, and splits at the cheapest ("binned SAH", Wald 2007; pbrt §4.3).
Ranges of at most ``leaf_size`` triangles become leaves, so no leaf holds more.
If the centroids of a range coincide (no plane separates them), or the tree has
become deep, the range is halved at its median instead: the depth stays below
:data:`MAX_DEPTH`, the size of the traversal's fixed stack.

**Flattened, depth first** (pbrt's LinearBVHNode): node 0 is the
root; an inner node's left child is the next node, ``first[node]`` its right child;
a leaf's triangles are ``order[first : first + count]``. The triangles' corners
are stored in that leaf order (``v0[k]`` is a corner of triangle ``order[k]``), so
a leaf reads contiguous memory. This binary tree is the BVH's definition (its
invariants are tested, :meth:`BVH.refit` works on it); the traversal walks a
copy made for speed:

**The traversal's tree: four children per node** (multi-branching BVHs: Wald,
Benthin and Boulos 2008, Dammertz et al. 2008; Embree's BVH4), collapsed from the
binary SAH tree. A wide node starts
from a binary node's two children and, while it has fewer than four, replaces
the inner child of largest surface area by that child's two; every inner child
left over becomes a wide node in turn. A wide node stores its four children's
boxes side by side (``boxes`` [M, 6, 4]: a row per coordinate, a column per
child) in float32 *rounded outward* (lo down, hi up, so each holds its float64
box and the test below stays conservative), and its children as
``ref << 32 | n`` (n = 0: wide node ref; n > 0: a leaf of n triangles from block
ref). A visit tests the four boxes in one vector of four float64s (the same
IEEE operations as the scalar slab test, written as LLVM vector code because
numba's vectorizer leaves them scalar), sorts the four entry distances by a
five-exchange network, goes on into the nearest child and pushes the others the
ray meets, farthest first, without a branch. A leaf's triangles are stored in
blocks of four (``tris`` [B, 9, 4], ``tri_ids`` [B, 4], NaN-padded): one
vector computation of the watertight test on the block's four triangles names
the candidates (a hit, or an edge function exactly 0), and the scalar test
below decides each candidate, so the answers are the scalar test's, bit for bit.

Why this shape (measured on the bunny's and the armadillo's shadow and mirror
rays): a ray's traversal is a chain of dependent steps with branches a
predictor cannot guess (which child is nearer, which edge rejects the ray), and
the arithmetic is nearly free: testing every box and every triangle twice added
10-15 % to the time. So the levers were fewer, branch-free steps: four boxes
per visit halve the visits (25 binary nodes per shadow ray → 12.5 wide ones), the
triangle test's sign checks are combined with ``|`` and ``&`` (one branch, not one
per sign), the block filter leaves one branch per four triangles, and the batch
kernels walk two rays in turn so that the core overlaps their chains. The
per-triangle test had also been an out-of-line call for every triangle (its 17
arguments spilled to memory); now the block filter runs inline and the scalar
test is called only for its candidates. Leaf sizes 2 to 8 traced within 5-10 % of each
other; 3-4 was best. float64 boxes instead of float32 gained nothing measurable.

**Watertight triangle test.** A ray that passes exactly through the edge two
triangles share must hit at least one of them; otherwise a closed mesh leaks:
a shadow ray escapes a closed box, a camera ray shows the background through a
sphere, a point inside reads as outside. The classic Möller-Trumbore test
computes each triangle's edge tests with its own rounding, so both triangles can
reject a ray through their edge. :func:`intersect_triangle` follows Woop, Benthin
and Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013): translate the
vertices to the ray origin and shear them so that the ray becomes the +z axis;
then the 2D edge functions U, V, W of the sheared vertices are computed from the
*same* numbers for an edge both triangles share, so they are exact negatives of
each other, and the ray lands on one side of every edge, or on it (0 counts as
inside for both). When an edge function is exactly 0 the three are recomputed
exactly (an error-free product and sum: the paper's fallback to higher precision,
here above float64) so that 0 means "exactly on the edge". Both sides hit: no
face is culled.

**Robust traversal.** A box is tested by the slab method with ``1/direction``
(±inf for a zero component, and the NaN of ``0·inf`` when the origin lies on a
slab's plane leaves that slab unconstrained), and the far distance is enlarged by
``1 + 2γ(3)`` (pbrt's robust slab test, 3rd ed. §3.9), so rounding in the box test never
drops a box that holds the hit the triangle test would find. The wide nodes pick
each slab's near and far plane once per ray from the sign of ``1/direction``
instead of swapping per slab: the same numbers (for a finite 1/d the products
keep their order; ±0 gives ±inf and the NaN rule above). Their float32 boxes
contain the float64 ones, so they can only let more boxes through.

**Scenes: flattened, not instanced.** :func:`scene_bvh` puts every object's
triangles, moved to world space by its model matrix, into one BVH. Instancing (a
top-level BVH over per-mesh BVHs, each ray moved into an object's space) saves
memory when a mesh is drawn many times; softpipe's scenes draw each mesh once or
a few times, and one flat BVH is simpler to read, takes one traversal, and has
one t for all objects. When the scene moves: :meth:`BVH.refit` for small motion,
:meth:`BVH.build` again for large.

Speed (measured on this kind of 2-core machine, warm, while other jobs shared
it; benchmarks/README.md, "Rays", has the side-by-side figures with Embree): the
bunny's 69,451 triangles build in about 60 ms, the armadillo's 99,976 in about
99 ms (5 and 8 ms of that for the wide nodes and the blocks), and refit in about
5.5 and 8.7 ms; one thread answers about 6.4 M closest-hit camera rays a second on
the bunny, 4.0 M shadow rays (any hit) from its surface and 4.4 M mirror rays.
:func:`closest_hit` and :func:`any_hit` called once per ray (a shader, the ray
tracer) are 1.1-1.35× faster than before the wide nodes; the batch queries, with
two rays in flight, 1.5-1.8× on shadow and mirror rays.

Numba: :func:`intersect_triangle`, :func:`closest_hit` and :func:`any_hit` are
``@njit(cache=True)`` functions: other compiled code, a shader among them, calls
them with ``bvh.uniform`` (a :class:`BVHUniform`, or the :class:`BVH` itself when
it is a shader uniform: ``__softpipe_uniform__``). :meth:`BVH.closest` and
:meth:`BVH.occluded` run them on arrays of rays from Python, in parallel bands
(:func:`softpipe.core.parallel.in_bands`), two rays in flight per band; each ray's
answer does not depend on which thread computes it nor on which ray shares its
band, so the result is the same bytes for any thread count.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from llvmlite import ir
from numba.extending import intrinsic, overload

from softpipe.core.parallel import in_bands

__all__ = ["BVH", "BVHUniform", "intersect_triangle", "closest_hit", "any_hit", "scene_bvh", "MAX_DEPTH"]

#: The traversal's stack holds one pending node per level: the build keeps every
#: leaf's depth below this (root at depth 0).
MAX_DEPTH = 64

#: Children of a traversal node (a "wide" node, see :class:`BVH`): the binary tree is collapsed
#: into nodes of up to this many children, whose boxes are tested together.
WIDTH = 4

#: Triangles are tested in blocks of this many (a leaf's triangles fill one or more blocks).
BLOCK = 4

#: The traversal's stack: a wide node's level is at most its binary depth, and a visit puts
#: aside at most WIDTH − 1 children.
STACK_SIZE = (WIDTH - 1) * MAX_DEPTH + 1     # + 1: a child the ray misses is written, then overwritten

#: 1 + 2γ(3), pbrt's padding of a box's far distance (3rd ed., §3.9): γ(n) = nu / (1 − nu),
#: u = 2⁻⁵³ the unit roundoff of float64.
_U = 2.0 ** -53
SLAB_PAD = 1.0 + 2.0 * (3.0 * _U / (1.0 - 3.0 * _U))

#: How far (relative) beyond the nearest hit so far the closest-hit search still opens
#: boxes: a box whose rounded entry is an ulp or so past that t may hold a triangle
#: hit at exactly that t with a lower id, which wins the tie (2⁻⁴⁴ ≈ 6·10⁻¹⁴).
REACH_PAD = 2.0 ** -44

BVHUniform = namedtuple("BVHUniform", ["lo", "hi", "first", "count", "order", "v0", "v1", "v2",
                                       "boxes", "links", "tris", "tri_ids"])
BVHUniform.__doc__ = """A BVH as a shader receives it: its numpy arrays (see :class:`BVH`). The queries read
``lo``, ``hi`` (the root's box), ``first``, ``count`` (whether the root is a leaf) and the traversal's
``boxes``, ``links``, ``tris``, ``tri_ids``; ``order`` and ``v0``, ``v1``, ``v2`` are there for shaders."""


# ----------------------------------------------------------- the triangle test

@numba.njit(cache=True, nogil=True, error_model="numpy")
def _two_product(a, b):
    """a·b = p + e exactly (Dekker's product with Veltkamp's split; no overflow or underflow assumed)."""
    p = a * b
    c = 134217729.0 * a                      # 2^27 + 1
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = al * bl - (((p - ah * bh) - al * bh) - ah * bl)
    return p, e


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _two_sum(a, b):
    """a + b = s + e exactly (Knuth)."""
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)
    return s, e


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _exact_cross(a, b, c, d):
    """a·b − c·d with the exact sign (0 only when it is exactly 0), and nearly its value.

    The four doubles of two error-free products (a·b = p1 + e1, c·d = p2 + e2)
    are summed exactly into a nonoverlapping expansion (Shewchuk 1997,
    Grow-Expansion); its largest component has the sign of the exact sum, and the
    components summed from the smallest up give its value to within an ulp.
    """
    p1, e1 = _two_product(a, b)
    p2, e2 = _two_product(c, d)
    # grow the expansion by e1, −e2, p1, −p2 (each step: TwoSum through the components, smallest first)
    h0 = e1
    q, h0 = _two_sum(-e2, h0)
    h1 = q
    q, h0 = _two_sum(p1, h0)
    q, h1 = _two_sum(q, h1)
    h2 = q
    q, h0 = _two_sum(-p2, h0)
    q, h1 = _two_sum(q, h1)
    q, h2 = _two_sum(q, h2)
    h3 = q
    s = ((h0 + h1) + h2) + h3
    if s == 0.0:                             # the rounded sum cancelled: the largest nonzero part decides
        if h3 != 0.0:
            return h3
        if h2 != 0.0:
            return h2
        if h1 != 0.0:
            return h1
        return h0
    return s


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _ray_space(dx, dy, dz):
    """The shear of Woop et al. for direction (dx, dy, dz): (kx, ky, kz, Sx, Sy, Sz).

    kz is the axis where the direction is largest in magnitude; kx, ky the two
    others, swapped when d[kz] < 0 so that the shear keeps the winding. A point q
    becomes q' = (q[kx] − Sx·q[kz], q[ky] − Sy·q[kz], Sz·q[kz]) (after subtracting the
    origin): the ray is then the +z axis, and z' is the ray's t.
    """
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax > ay and ax > az:
        kz = 0
    elif ay > az:
        kz = 1
    else:
        kz = 2
    kx = kz + 1 if kz < 2 else 0
    ky = kx + 1 if kx < 2 else 0
    d = (dx, dy, dz)
    dkz = d[kz]
    if dkz < 0.0:
        kx, ky = ky, kx
    if dkz == 0.0:                           # a zero (or NaN) direction: no ray
        return kx, ky, kz, 0.0, 0.0, 0.0
    return kx, ky, kz, d[kx] / dkz, d[ky] / dkz, 1.0 / dkz


# Not inlined into the traversal: it runs only on the block filter's candidates (about once per
# hit), and inlining it into every caller had cost 0.5-1 s of cold compilation for nothing.
@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hit_sheared(ax, ay, az, bx, by, bz, cx, cy, cz, kx, ky, kz, sx, sy, sz, t_min, t_max):
    """The watertight test on corners already relative to the origin, in axis order (kx, ky, kz)."""
    # shear the corners into ray space (x', y'); z' scaled below
    Ax = ax - sx * az
    Ay = ay - sy * az
    Bx = bx - sx * bz
    By = by - sy * bz
    Cx = cx - sx * cz
    Cy = cy - sy * cz
    # edge functions: U opposite corner a (edge b→c), V opposite b, W opposite c
    U = Cx * By - Cy * Bx
    V = Ax * Cy - Ay * Cx
    W = Bx * Ay - By * Ax
    # (the tests below combine their comparisons with | and &, not "or" and "and": one branch
    # each, where short-circuits would branch on every sign, which a predictor cannot guess)
    if (U == 0.0) | (V == 0.0) | (W == 0.0):  # on an edge in float64: decide exactly
        U = _exact_cross(Cx, By, Cy, Bx)
        V = _exact_cross(Ax, Cy, Ay, Cx)
        W = _exact_cross(Bx, Ay, By, Ax)
    if ((U < 0.0) | (V < 0.0) | (W < 0.0)) & ((U > 0.0) | (V > 0.0) | (W > 0.0)):
        return False, 0.0, 0.0, 0.0          # the ray passes outside an edge
    det = U + V + W
    if det == 0.0:                           # seen edge-on, or a degenerate triangle
        return False, 0.0, 0.0, 0.0
    T = U * (sz * az) + V * (sz * bz) + W * (sz * cz)
    t = T / det
    if not ((t > t_min) & (t < t_max)):
        return False, 0.0, 0.0, 0.0
    return True, t, V / det, W / det


@numba.njit(cache=True, nogil=True, error_model="numpy")
def intersect_triangle(v0, v1, v2, origin, direction, t_min, t_max):
    """Watertight ray/triangle test (Woop, Benthin and Wald 2013): (hit, t, b1, b2).

    ``v0, v1, v2, origin, direction`` are 3-vectors (arrays or tuples). A hit
    has ``t_min < t < t_max`` and the point ``origin + t·direction`` equals
    ``(1 − b1 − b2)·v0 + b1·v1 + b2·v2``; either side of the triangle is hit.
    A ray through an edge or corner shared by two triangles hits at least one of
    them (see the module docstring). A zero direction or a degenerate triangle
    never hits.
    """
    dx, dy, dz = float(direction[0]), float(direction[1]), float(direction[2])
    kx, ky, kz, sx, sy, sz = _ray_space(dx, dy, dz)
    if sz == 0.0:
        return False, 0.0, 0.0, 0.0
    o = (float(origin[0]), float(origin[1]), float(origin[2]))
    p0 = (v0[0] - o[0], v0[1] - o[1], v0[2] - o[2])
    p1 = (v1[0] - o[0], v1[1] - o[1], v1[2] - o[2])
    p2 = (v2[0] - o[0], v2[1] - o[1], v2[2] - o[2])
    return _hit_sheared(p0[kx], p0[ky], p0[kz], p1[kx], p1[ky], p1[kz], p2[kx], p2[ky], p2[kz],
                        kx, ky, kz, sx, sy, sz, float(t_min), float(t_max))


# ------------------------------------------------------------------ traversal

# Why two intrinsics. numba counts references to every array a compiled function
# receives: an atomic add on entry and an atomic subtract on exit, per array, per
# call. For a ray that is 16 atomic operations on the BVH's 8 arrays (measured: 70
# of the 120 ns a ray that misses the root box cost; two threads contend for the
# same counters), and np.empty for the traversal stack costs a heap allocation per
# ray. So the traversal works on *borrowed* arrays (the same data with no owner
# attached, so there is nothing to count; only used while the caller holds the
# BVH) and on a stack in the function's own frame (an alloca, as C would).

def _borrowed(arr):
    """The array ``arr`` without its owner (meminfo NULL), so numba counts no references to it.

    Only for use inside the call that received ``arr``: the data stay alive
    because the caller holds the original. In plain Python (NUMBA_DISABLE_JIT=1)
    the array itself.
    """
    return arr


def _node_stack():
    """The traversal's [STACK_SIZE] int64 stack, in the calling function's frame (plain Python: a new array)."""
    return np.empty(STACK_SIZE, np.int64)


def _t_stack():
    """The traversal's [STACK_SIZE] float64 stack, in the calling function's frame (plain Python: a new array)."""
    return np.empty(STACK_SIZE, np.float64)


@intrinsic
def _borrowed_intrinsic(typingctx, arr):
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        a = context.make_array(arr)(context, builder, value=args[0])
        a.meminfo = cgutils.get_null_value(a.meminfo.type)
        return a._getvalue()
    return arr(arr), codegen


def _frame_stack_intrinsic(dtype):
    """An intrinsic making a [STACK_SIZE] array of ``dtype`` in the calling function's stack frame (an alloca)."""
    array_type = types.Array(dtype, 1, "C")

    @intrinsic
    def stack(typingctx):
        def codegen(context, builder, signature, args):
            item = context.get_data_type(dtype)
            size = context.get_abi_sizeof(item)
            data = cgutils.alloca_once(builder, item, size=STACK_SIZE)
            out = context.make_array(array_type)(context, builder)
            intp = lambda v: context.get_constant(types.intp, v)  # noqa: E731
            context.populate_array(out, data=data, shape=cgutils.pack_array(builder, [intp(STACK_SIZE)]),
                                   strides=cgutils.pack_array(builder, [intp(size)]), itemsize=intp(size),
                                   meminfo=None)
            return out._getvalue()
        return array_type(), codegen
    return stack


_node_stack_intrinsic = _frame_stack_intrinsic(types.int64)
_t_stack_intrinsic = _frame_stack_intrinsic(types.float64)


@overload(_borrowed, inline="always")
def _borrowed_compiled(arr):
    if isinstance(arr, types.Array):
        return lambda arr: _borrowed_intrinsic(arr)


@overload(_node_stack, inline="always")
def _node_stack_compiled():
    return lambda: _node_stack_intrinsic()


@overload(_t_stack, inline="always")
def _t_stack_compiled():
    return lambda: _t_stack_intrinsic()

@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _inverse(d):
    """1/d, with ±inf for ±0 (the sign of the zero kept)."""
    if d == 0.0:
        return math.copysign(math.inf, d)
    return 1.0 / d


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _slab(lo, hi, o, inv, t0, t1):
    """One slab of pbrt's robust test: the ray's [t0, t1] narrowed to lo ≤ o + t·d ≤ hi.

    ``(lo − o)·inv`` is NaN when the origin lies on the slab's plane and the
    direction is 0 along it: ``t > t0 ? t : t0`` then keeps t0 (a ray lying in the
    plane is not constrained by it), as in pbrt.
    """
    lo, hi, o, inv = float(lo), float(hi), float(o), float(inv)   # plain floats in Python: NaN without a warning
    tn = (lo - o) * inv
    tf = (hi - o) * inv
    if tn > tf:
        tn, tf = tf, tn
    tf *= SLAB_PAD
    t0 = tn if tn > t0 else t0
    t1 = tf if tf < t1 else t1
    return t0, t1


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _box_entry(lo, hi, node, ox, oy, oz, ix, iy, iz, t0, t1):
    """pbrt's robust slab test of node's box on [t0, t1]: the entry t, or +inf for a miss."""
    t0, t1 = _slab(lo[node, 0], hi[node, 0], ox, ix, t0, t1)
    t0, t1 = _slab(lo[node, 1], hi[node, 1], oy, iy, t0, t1)
    t0, t1 = _slab(lo[node, 2], hi[node, 2], oz, iz, t0, t1)
    return t0 if t0 <= t1 else math.inf


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lane_entry(boxes, i, lane, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1):
    """The robust slab test of child ``lane`` of wide node ``i``: its entry t, or +inf for a miss.

    The same test as :func:`_box_entry`, with the plane the ray enters each slab by
    chosen once per ray from the sign of ``1/d`` (``nx`` is 0, the row of lo.x, when
    the ray goes +x, else 3, the row of hi.x; the far plane is the other one), so no
    compare-and-swap per slab, and the four children's tests are the same
    arithmetic on neighbouring numbers (a row of ``boxes`` holds one coordinate of
    all four). A float32 corner is read as the float64 it holds exactly. An empty
    lane (lo = +inf, hi = −inf) always misses.
    """
    tn = (float(boxes[i, nx, lane]) - ox) * ix          # float(): plain floats in Python, NaN without a warning
    tf = (float(boxes[i, 3 - nx, lane]) - ox) * ix * SLAB_PAD
    t0 = tn if tn > t0 else t0
    t1 = tf if tf < t1 else t1
    tn = (float(boxes[i, ny, lane]) - oy) * iy
    tf = (float(boxes[i, 5 - ny, lane]) - oy) * iy * SLAB_PAD
    t0 = tn if tn > t0 else t0
    t1 = tf if tf < t1 else t1
    tn = (float(boxes[i, nz, lane]) - oz) * iz
    tf = (float(boxes[i, 7 - nz, lane]) - oz) * iz * SLAB_PAD
    t0 = tn if tn > t0 else t0
    t1 = tf if tf < t1 else t1
    return t0 if t0 <= t1 else math.inf


def _lane_entries(boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1):
    """The entry t (or +inf) of each of wide node ``i``'s WIDTH children: :func:`_lane_entry` for every lane.

    Compiled, the lanes are computed together, in one vector of WIDTH float64
    (:func:`_lane_entries_intrinsic`): the same IEEE operations, in the same order,
    as :func:`_lane_entry`, so the same bits; in plain Python, lane after lane.
    """
    return tuple(_lane_entry(boxes, i, j, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1) for j in range(WIDTH))


@intrinsic
def _lane_entries_intrinsic(typingctx, boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1):
    # numba's loop vectorizer leaves the four lanes' arithmetic scalar (four chains of 30
    # instructions; its SLP vectorizer is off), so the LLVM vector code is written out here:
    # per axis a <WIDTH x float> load of the near and of the far row, widened to double
    # (exact), then fsub, fmul, fmul by SLAB_PAD, and the ordered compares and selects of
    # _lane_entry (NaN > t0 is false, so a NaN leaves t0, as there). No fast-math flags.
    if not (isinstance(boxes, types.Array) and boxes.dtype == types.float32 and boxes.ndim == 3
            and boxes.layout == "C"):
        return None
    sig = types.UniTuple(types.float64, WIDTH)(boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1)

    def codegen(context, builder, signature, args):
        boxes_v, i_v, nx_v, ny_v, nz_v, ox_v, oy_v, oz_v, ix_v, iy_v, iz_v, t0_v, t1_v = args
        ary = context.make_array(signature.args[0])(context, builder, boxes_v)
        i64, i32, f64 = ir.IntType(64), ir.IntType(32), ir.DoubleType()
        f32v, f64v = ir.VectorType(ir.FloatType(), WIDTH), ir.VectorType(f64, WIDTH)

        def as_i64(v, ty):
            return context.cast(builder, v, ty, types.int64)

        def as_f64(v, ty):
            return context.cast(builder, v, ty, types.float64)

        def splat(x):
            v = ir.Constant(f64v, ir.Undefined)
            for k in range(WIDTH):
                v = builder.insert_element(v, x, ir.Constant(i32, k))
            return v

        base = builder.mul(as_i64(i_v, signature.args[1]), ir.Constant(i64, 6 * WIDTH))

        def row(r):                                  # boxes[i, r, :] as <WIDTH x double>
            p = builder.gep(ary.data, [builder.add(base, builder.mul(r, ir.Constant(i64, WIDTH)))])
            return builder.fpext(builder.load(builder.bitcast(p, f32v.as_pointer()), align=4), f64v)

        pad = splat(ir.Constant(f64, SLAB_PAD))
        enter, leave = splat(as_f64(t0_v, signature.args[11])), splat(as_f64(t1_v, signature.args[12]))
        for k, far_sum in ((0, 3), (1, 5), (2, 7)):
            n = as_i64(args[2 + k], signature.args[2 + k])
            o = splat(as_f64(args[5 + k], signature.args[5 + k]))
            inv = splat(as_f64(args[8 + k], signature.args[8 + k]))
            tn = builder.fmul(builder.fsub(row(n), o), inv)
            tf = builder.fmul(builder.fmul(builder.fsub(row(builder.sub(ir.Constant(i64, far_sum), n)), o), inv), pad)
            enter = builder.select(builder.fcmp_ordered(">", tn, enter), tn, enter)
            leave = builder.select(builder.fcmp_ordered("<", tf, leave), tf, leave)
        out = builder.select(builder.fcmp_ordered("<=", enter, leave), enter, splat(ir.Constant(f64, math.inf)))
        lanes = [builder.extract_element(out, ir.Constant(i32, k)) for k in range(WIDTH)]
        return context.make_tuple(builder, signature.return_type, lanes)
    return sig, codegen


@overload(_lane_entries, inline="always")
def _lane_entries_compiled(boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1):
    return lambda boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1: \
        _lane_entries_intrinsic(boxes, i, nx, ny, nz, ox, oy, oz, ix, iy, iz, t0, t1)


def _block_candidates(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max):
    """Which lanes of triangle block ``b`` may be hit: a bit mask (bit j: lane j).

    Compiled (:func:`_block_candidates_intrinsic`), the watertight test of
    :func:`_hit_sheared` on the block's four triangles at once, in vectors of four
    float64 with the same IEEE operations in the same order (so the same U, V, W,
    det and t): a lane is a candidate when the test hits it, or when an edge
    function is exactly 0 (there the exact recomputation decides). The caller runs
    :func:`_hit_sheared` on the candidates only, so the answer is the scalar test's.
    In plain Python every lane is a candidate.
    """
    return (1 << BLOCK) - 1


@intrinsic
def _block_candidates_intrinsic(typingctx, tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max):
    # Why: the per-triangle test's branches (which edge rejects the ray, is it in range) are
    # what a predictor cannot guess, and a leaf's triangles are tested one after another; here
    # the four are one vector computation and one branch (any candidate?). Written in LLVM
    # vector IR as _lane_entries_intrinsic is (numba does not vectorize it); no fast-math
    # flags, so nothing is fused or reordered.
    if not (isinstance(tris, types.Array) and tris.dtype == types.float64 and tris.ndim == 3
            and tris.layout == "C"):
        return None
    sig = types.int64(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        i64, i32, f64 = ir.IntType(64), ir.IntType(32), ir.DoubleType()
        f64v = ir.VectorType(f64, BLOCK)

        def arg_i64(k):
            return context.cast(builder, args[k], signature.args[k], types.int64)

        def splat(k):
            x = context.cast(builder, args[k], signature.args[k], types.float64)
            v = ir.Constant(f64v, ir.Undefined)
            for j in range(BLOCK):
                v = builder.insert_element(v, x, ir.Constant(i32, j))
            return v

        base = builder.mul(arg_i64(1), ir.Constant(i64, 9 * BLOCK))
        axes = [arg_i64(2), arg_i64(3), arg_i64(4)]
        origin = [splat(5), splat(6), splat(7)]
        sx_, sy_, sz_, lo_t, hi_t = splat(8), splat(9), splat(10), splat(11), splat(12)

        def corner(c, a):                         # tris[b, 3c + k_a, :] − o[k_a]
            r = builder.add(ir.Constant(i64, 3 * c), axes[a])
            p = builder.gep(ary.data, [builder.add(base, builder.mul(r, ir.Constant(i64, BLOCK)))])
            v = builder.load(builder.bitcast(p, f64v.as_pointer()), align=8)
            return builder.fsub(v, origin[a])

        fsub, fmul, fadd = builder.fsub, builder.fmul, builder.fadd
        ax, ay, az = corner(0, 0), corner(0, 1), corner(0, 2)
        bx, by, bz = corner(1, 0), corner(1, 1), corner(1, 2)
        cx, cy, cz = corner(2, 0), corner(2, 1), corner(2, 2)
        Ax, Ay = fsub(ax, fmul(sx_, az)), fsub(ay, fmul(sy_, az))
        Bx, By = fsub(bx, fmul(sx_, bz)), fsub(by, fmul(sy_, bz))
        Cx, Cy = fsub(cx, fmul(sx_, cz)), fsub(cy, fmul(sy_, cz))
        U = fsub(fmul(Cx, By), fmul(Cy, Bx))
        V = fsub(fmul(Ax, Cy), fmul(Ay, Cx))
        W = fsub(fmul(Bx, Ay), fmul(By, Ax))
        zero = ir.Constant(f64v, [0.0] * BLOCK)

        def cmp(op, x, y):
            return builder.fcmp_ordered(op, x, y)

        or_, and_ = builder.or_, builder.and_
        on_edge = or_(or_(cmp("==", U, zero), cmp("==", V, zero)), cmp("==", W, zero))
        neg = or_(or_(cmp("<", U, zero), cmp("<", V, zero)), cmp("<", W, zero))
        pos = or_(or_(cmp(">", U, zero), cmp(">", V, zero)), cmp(">", W, zero))
        det = fadd(fadd(U, V), W)
        T = fadd(fadd(fmul(U, fmul(sz_, az)), fmul(V, fmul(sz_, bz))), fmul(W, fmul(sz_, cz)))
        t = builder.fdiv(T, det)
        ok = and_(and_(builder.not_(and_(neg, pos)), builder.fcmp_unordered("!=", det, zero)),
                  and_(cmp(">", t, lo_t), cmp("<", t, hi_t)))
        mask = builder.bitcast(or_(on_edge, ok), ir.IntType(BLOCK))
        return builder.zext(mask, i64)
    return sig, codegen


@overload(_block_candidates, inline="always")
def _block_candidates_compiled(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max):
    return lambda tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max: \
        _block_candidates_intrinsic(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max)


#: A child on the traversal's stack is one int64: ``ref << 32 | n`` (see :func:`_traverse`).
_REF_SHIFT = 32
_COUNT_MASK = (1 << 32) - 1


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _order2(ta, ca, tb, cb):
    """(ta, ca), (tb, cb) with the smaller t first: a compare-exchange of the sorting network, written
    as min, max and selects so that it compiles without a branch (the order of a ray's children is
    what a branch predictor cannot guess)."""
    swap = tb < ta
    return min(ta, tb), cb if swap else ca, max(ta, tb), ca if swap else cb


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _start(lo, hi, first, count, ox, oy, oz, dx, dy, dz, t_min, t_max):
    """A ray's constants and the traversal's first state: (ray, state); see :func:`_step`.

    Once per ray: Woop's axis permutation and shear (:func:`_ray_space`), ``1/d``,
    which box planes the ray enters by, and the root's box (a ray that misses it,
    a zero direction or an empty interval starts finished).
    """
    kx, ky, kz, sx, sy, sz = _ray_space(dx, dy, dz)
    o3 = (ox, oy, oz)
    okx, oky, okz = o3[kx], o3[ky], o3[kz]
    ix, iy, iz = _inverse(dx), _inverse(dy), _inverse(dz)
    # rows of a wide node's boxes: lo.x, lo.y, lo.z, hi.x, hi.y, hi.z. The ray enters the x slab
    # through lo.x when it goes +x (1/dx = +inf for dx = +0 counts as +), through hi.x when −x
    nx = 3 if ix < 0.0 else 0
    ny = 4 if iy < 0.0 else 1
    nz = 5 if iz < 0.0 else 2
    ray = (ox, oy, oz, ix, iy, iz, nx, ny, nz, okx, oky, okz, kx, ky, kz, sx, sy, sz, t_min, t_max)
    reach = t_max + abs(t_max) * REACH_PAD   # boxes are searched a hair beyond the best t (ties)
    live = count.shape[0] > 0 and sz != 0.0 and t_min < t_max
    if live:
        live = _box_entry(lo, hi, 0, ox, oy, oz, ix, iy, iz, t_min, reach) != math.inf
    ref, n = 0, 0
    if live and count[0] > 0:                # the root is a leaf (no wide nodes): from block 0
        ref, n = 0, count[0]
    return ray, (live, ref, n, 0, reach, -1, t_max, 0.0, 0.0)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _step(boxes, links, tris, tri_ids, ray, state, any_, stack_node, stack_t):
    """One step of the stack traversal: a wide node or a leaf visited, then the next one chosen.

    The traversal walks the wide nodes (``boxes``, ``links``; see :class:`BVH`): a
    visit tests the boxes of all four children (stored side by side in the node),
    goes on into the nearest child the ray meets and puts the others aside,
    farthest deepest. It walks (ref, n) pairs: n = 0 names wide node ref, n > 0 the
    leaf of triangles ``ref … ref + n − 1``. ``stack_node``, ``stack_t``
    [STACK_SIZE]: the children put aside (``ref << 32 | n``) and the t where each
    one's box begins (one that begins beyond the nearest hit is skipped).
    ``state`` = (live, ref, n, top, reach, best id, t, b1, b2); live turns False
    when the answer is known.
    """
    ox, oy, oz, ix, iy, iz, nx, ny, nz, okx, oky, okz, kx, ky, kz, sx, sy, sz, t_min, t_max = ray
    live, ref, n, top, reach, best_id, best_t, best_b1, best_b2 = state
    if n > 0:                                # a leaf: its blocks of triangles, from block ref
        for b in range(ref, ref + (n + BLOCK - 1) // BLOCK):
            lanes = _block_candidates(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max)
            if lanes == 0:
                continue
            for j in range(BLOCK):           # rare: the scalar test decides each candidate
                tri = tri_ids[b, j]
                if (lanes >> j) & 1 == 0 or tri < 0:
                    continue
                hit, t, b1, b2 = _hit_sheared(
                    tris[b, kx, j] - okx, tris[b, ky, j] - oky, tris[b, kz, j] - okz,
                    tris[b, 3 + kx, j] - okx, tris[b, 3 + ky, j] - oky, tris[b, 3 + kz, j] - okz,
                    tris[b, 6 + kx, j] - okx, tris[b, 6 + ky, j] - oky, tris[b, 6 + kz, j] - okz,
                    kx, ky, kz, sx, sy, sz, t_min, t_max)
                if hit:
                    if any_:
                        return False, ref, n, top, reach, tri, t, b1, b2
                    if t < best_t or (t == best_t and tri < best_id):
                        best_id, best_t, best_b1, best_b2 = tri, t, b1, b2
                        reach = t + abs(t) * REACH_PAD
    else:                                    # a wide node: its four boxes, then the nearest child first
        t0, t1, t2, t3 = _lane_entries(boxes, ref, nx, ny, nz, ox, oy, oz, ix, iy, iz, t_min, reach)
        c0, c1, c2, c3 = links[ref, 0], links[ref, 1], links[ref, 2], links[ref, 3]
        # sort the four (t, child) by t (a 5-exchange network); misses (+inf) go last
        t0, c0, t1, c1 = _order2(t0, c0, t1, c1)
        t2, c2, t3, c3 = _order2(t2, c2, t3, c3)
        t0, c0, t2, c2 = _order2(t0, c0, t2, c2)
        t1, c1, t3, c3 = _order2(t1, c1, t3, c3)
        t1, c1, t2, c2 = _order2(t1, c1, t2, c2)
        # put aside children 3, 2, 1, farthest first, without a branch: each is written at the
        # top and kept (top moves up) only if the ray meets it; a miss is overwritten
        stack_node[top], stack_t[top] = c3, t3
        top += t3 != math.inf
        stack_node[top], stack_t[top] = c2, t2
        top += t2 != math.inf
        stack_node[top], stack_t[top] = c1, t1
        top += t1 != math.inf
        if t0 != math.inf:
            return True, c0 >> _REF_SHIFT, c0 & _COUNT_MASK, top, reach, best_id, best_t, best_b1, best_b2
    # pop the next child whose box begins no farther than the best hit
    while top > 0:
        top -= 1
        if stack_t[top] <= reach:
            code = stack_node[top]
            return True, code >> _REF_SHIFT, code & _COUNT_MASK, top, reach, best_id, best_t, best_b1, best_b2
    return False, ref, n, top, reach, best_id, best_t, best_b1, best_b2


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _traverse(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max, any_,
              stack_node, stack_t):
    """One ray's query, (id, t, b1, b2), compiled into each caller (``inline="always"``) on borrowed
    arrays: :func:`_start`, then :func:`_step` until the answer is known."""
    ray, state = _start(lo, hi, first, count, ox, oy, oz, dx, dy, dz, t_min, t_max)
    while state[0]:
        state = _step(boxes, links, tris, tri_ids, ray, state, any_, stack_node, stack_t)
    return state[5], state[6], state[7], state[8]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _query(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max, any_):
    """One ray on borrowed arrays, with its stack in this frame."""
    return _traverse(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max,
                     any_, _node_stack(), _t_stack())


@numba.njit(cache=True, nogil=True, error_model="numpy")
def closest_hit(bvh, origin, direction, t_min, t_max):
    """The nearest triangle on the ray in the open interval (t_min, t_max): (id, t, b1, b2).

    ``bvh`` is a :class:`BVHUniform`; ``origin``, ``direction`` 3-vectors (arrays
    or tuples; the direction need not be unit length, t is in its units). ``id``
    is −1 for a miss (then t = t_max, b1 = b2 = 0). Among hits at exactly the same
    t the lowest triangle id wins, so the answer does not depend on the tree.
    The hit point is (1 − b1 − b2)·v0 + b1·v1 + b2·v2 of triangle ``id``.
    """
    return _query(_borrowed(bvh.boxes), _borrowed(bvh.links), _borrowed(bvh.lo), _borrowed(bvh.hi),
                  _borrowed(bvh.first), _borrowed(bvh.count), _borrowed(bvh.tris), _borrowed(bvh.tri_ids),
                  float(origin[0]), float(origin[1]), float(origin[2]),
                  float(direction[0]), float(direction[1]), float(direction[2]), float(t_min), float(t_max), False)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def any_hit(bvh, origin, direction, t_min, t_max):
    """Whether any triangle lies on the ray in (t_min, t_max): stops at the first one found (shadow rays, §21)."""
    return _query(_borrowed(bvh.boxes), _borrowed(bvh.links), _borrowed(bvh.lo), _borrowed(bvh.hi),
                  _borrowed(bvh.first), _borrowed(bvh.count), _borrowed(bvh.tris), _borrowed(bvh.tri_ids),
                  float(origin[0]), float(origin[1]), float(origin[2]),
                  float(direction[0]), float(direction[1]), float(direction[2]), float(t_min), float(t_max),
                  True)[0] >= 0


# ------------------------------------------------------------------ the build

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
def _gather_kernel(vertices, triangles, order, corners):
    """The corners of every triangle, in leaf order: row k of ``corners`` is v0, v1, v2 of triangle order[k]."""
    for k in range(order.shape[0]):
        t = order[k]
        for c in range(3):
            for a in range(3):
                corners[k, 3 * c + a] = vertices[triangles[t, c], a]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _refit_kernel(lo, hi, first, count, corners):
    """Node boxes bottom-up: children come after their parent in depth-first order, so walk backwards."""
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
def _fill_blocks(first, count, leaf_block, corners, order, tris, tri_ids):
    """The leaves' triangles in blocks: tris[b, 3c + a, j] is coordinate a of corner c of lane j's
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
    child as the traversal codes it: ``ref << 32 | n`` with n = 0 and ref its wide
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
                links[w, j] = (leaf_block[c] << _REF_SHIFT) | count[c]
            else:
                links[w, j] = made << _REF_SHIFT
                pending[top], pending_w[top] = c, made
                top += 1
                made += 1
    return made


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _pack_boxes(lo, hi, lane_node, boxes):
    """boxes[w, r, j] = coordinate r (lo.x, lo.y, lo.z, hi.x, hi.y, hi.z) of child j's box, in float32
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


# ------------------------------------------------------------- batches of rays

@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _start_row(lo, hi, first, count, origins, directions, t_min, t_max, r):
    """:func:`_start` for ray r of a batch."""
    return _start(lo, hi, first, count, origins[r, 0], origins[r, 1], origins[r, 2],
                  directions[r, 0], directions[r, 1], directions[r, 2], t_min[r], t_max[r])


# Why two rays at a time. A ray's traversal is one long chain of dependent steps (a node's
# address comes from its parent's links, which child comes next from the boxes' tests) with
# hard-to-guess branches, so one ray leaves most of the core idle: measured on the bunny's
# shadow rays, testing every box and triangle twice added only 15 % to the time. The batch
# kernels therefore walk two rays in turn, a step of one then a step of the other (each on its
# own stack), and start the band's next ray where one finishes: the core overlaps the two
# chains. Each ray's answer is computed exactly as alone, so the bytes do not change.

@numba.njit(cache=True, nogil=True, error_model="numpy")
def _batch_kernel(lo_, hi_, bvh, origins, directions, t_min, t_max, any_, ids, ts, bs, occluded):
    """Rays lo_ … hi_ − 1 of a batch, two in flight: closest hits into ids, ts, bs, or (any_) any hits
    into occluded."""
    sa_node, sa_t, sb_node, sb_t = _node_stack(), _t_stack(), _node_stack(), _t_stack()
    boxes, links, lo, hi = _borrowed(bvh.boxes), _borrowed(bvh.links), _borrowed(bvh.lo), _borrowed(bvh.hi)
    first, count, tris, tri_ids = _borrowed(bvh.first), _borrowed(bvh.count), _borrowed(bvh.tris), \
        _borrowed(bvh.tri_ids)
    ia, ib = lo_, lo_ + 1
    ray_a, st_a = _start_row(lo, hi, first, count, origins, directions, t_min, t_max, ia)
    if ib < hi_:
        ray_b, st_b = _start_row(lo, hi, first, count, origins, directions, t_min, t_max, ib)
    else:
        ib = -1
        ray_b, st_b = ray_a, st_a
    nxt = lo_ + 2
    while ia >= 0 or ib >= 0:
        if ia >= 0:
            if st_a[0]:
                st_a = _step(boxes, links, tris, tri_ids, ray_a, st_a, any_, sa_node, sa_t)
            else:
                _store(ia, st_a, any_, ids, ts, bs, occluded)
                if nxt < hi_:
                    ia = nxt
                    nxt += 1
                    ray_a, st_a = _start_row(lo, hi, first, count, origins, directions, t_min, t_max, ia)
                else:
                    ia = -1
        if ib >= 0:
            if st_b[0]:
                st_b = _step(boxes, links, tris, tri_ids, ray_b, st_b, any_, sb_node, sb_t)
            else:
                _store(ib, st_b, any_, ids, ts, bs, occluded)
                if nxt < hi_:
                    ib = nxt
                    nxt += 1
                    ray_b, st_b = _start_row(lo, hi, first, count, origins, directions, t_min, t_max, ib)
                else:
                    ib = -1


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _store(r, state, any_, ids, ts, bs, occluded):
    """Ray r's answer from its final state (see :func:`_step`)."""
    i = state[5]
    if any_:
        occluded[r] = i >= 0
    else:
        ids[r] = i
        if i >= 0:
            ts[r], bs[r, 0], bs[r, 1] = state[6], state[7], state[8]
        else:
            ts[r], bs[r, 0], bs[r, 1] = np.inf, 0.0, 0.0



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

    The traversal's arrays (see the module docstring; made from the above by
    the build, kept up to date by :meth:`refit`):

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
        cap = max(count.shape[0], 1)
        lane_node, links = np.empty((cap, WIDTH), np.int64), np.empty((cap, WIDTH), np.int64)
        self._leaf_block = np.empty(count.shape[0], np.int64)
        blocks = _leaf_blocks(count, self._leaf_block)
        self.tris = np.empty((blocks, 9, BLOCK))
        self.tri_ids = np.empty((blocks, BLOCK), np.int64)
        _fill_blocks(first, count, self._leaf_block, corners, order, self.tris, self.tri_ids)
        M = _collapse_kernel(lo, hi, first, count, self._leaf_block, lane_node, links)
        self._lane_node, self.links = lane_node[:M].copy(), links[:M].copy()
        self.boxes = np.empty((M, 6, WIDTH), np.float32)
        _pack_boxes(lo, hi, self._lane_node, self.boxes)
        self.uniform = BVHUniform(lo, hi, first, count, order, self.v0, self.v1, self.v2,
                                  self.boxes, self.links, self.tris, self.tri_ids)

    @classmethod
    def build(cls, vertices, triangles, *, leaf_size: int = 4, bins: int = 16) -> "BVH":
        """Build a BVH by binned SAH (see the module docstring) over ``triangles`` [T, 3] into ``vertices`` [V, 3].

        Vertices are in world space (float, finite); triangles index them (any
        integer type). No triangles is allowed: every ray misses. Degenerate
        triangles (zero area) are kept and never hit.

        Measured (warm, 2-core machine): the bunny (69,451 triangles) builds in
        about 60 ms, the armadillo (99,976) in about 99 ms (``leaf_size=4,
        bins=16``; 5 and 8 ms of it the wide nodes and the triangle blocks). The build is serial and deterministic: the
        same input gives the same arrays. With the wide nodes, leaf sizes 2 to
        8 traced the bunny and the armadillo within 5-10 % of each other, 3
        and 4 fastest (with binary nodes 4 had been 10-20 % ahead).
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
        corners = v[tri] if T else np.zeros((0, 3, 3))
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
        if T >= 2 ** 31:
            raise ValueError(f"BVH.build: at most 2³¹ − 1 triangles (the traversal's int32 links), got {T}")
        leaf_corners = np.empty((T, 9))
        _gather_kernel(v, tri, order, leaf_corners)
        return cls(lo, hi, first, count, order, leaf_corners, tri, len(v), int(depth), int(leaf_size), int(bins))

    def refit(self, vertices) -> None:
        """Move the triangles to new ``vertices`` (same count, same triangles) and refit every box, in place.

        The tree is kept: only the corners and the boxes are recomputed, leaves
        first, each inner box the union of its children's (O(N), much cheaper
        than a build). Results stay exact, but a big motion makes the boxes
        overlap and grow and the traversal slower: rebuild (:meth:`build`) then.
        ``uniform`` keeps pointing at the same, updated arrays.
        """
        v = _vertices("vertices", vertices, rows=self.vertex_count)
        _gather_kernel(v, self.triangles, self.order, self.corners)
        _refit_kernel(self.lo, self.hi, self.first, self.count, self.corners)
        _fill_blocks(self.first, self.count, self._leaf_block, self.corners, self.order, self.tris, self.tri_ids)
        _pack_boxes(self.lo, self.hi, self._lane_node, self.boxes)

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
    mesh's triangles. Flattened, not instanced (see the module docstring): when
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
