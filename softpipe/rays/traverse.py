"""Walking a BVH: one ray's closest or any hit, and the steps a batch of rays is walked by.

The traversal walks the wide tree :mod:`softpipe.rays.build` makes (the arrays are described
in :mod:`softpipe.rays.layout`). Per ray, :func:`_start` computes the ray's constants once
(the watertight test's shear, :func:`~softpipe.rays.triangle.ray_space`; ``1/d``; which box
planes the ray enters by) and tests the root's box; then each :func:`step` visits one node:

- **a wide node**: its four children's boxes in one vector of four float64s
  (:func:`_lane_entries`: pbrt's robust slab test, the far distance padded by ``1 + 2γ(3)``),
  the four entry distances sorted by a five-exchange network, the nearest child entered and
  the others the ray meets put on the stack, farthest first, without a branch;
- **a leaf**: its blocks of four triangles, each filtered in one vector
  (:func:`_block_candidates`), the scalar watertight test
  (:func:`~softpipe.rays.triangle.hit_sheared`) deciding each candidate, so the answer is the
  scalar test's bit for bit.

The closest-hit search skips any box that begins beyond the nearest hit so far (plus
:data:`REACH_PAD`, for ties: the lowest triangle id wins a tie in t); the any-hit search stops
at its first hit. :func:`query` answers one ray; a batch kernel
(:func:`softpipe.rays.bvh._batch_kernel`) walks two rays in turn with :func:`start_row`,
:func:`step` and :func:`store`, each ray on its own stack (:func:`node_stack`,
:func:`t_stack`: arrays in the caller's frame). All of them work on the BVH's arrays
*borrowed* (no owner, so numba counts no references: :func:`softpipe.core.borrow.borrowed`).
Each ray's answer depends on nothing but the ray, so the bytes are the same for any thread
count. docs/raytracing.md ("The BVH") explains why this shape; benchmarks/README.md ("Rays")
has the measurements.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

from softpipe.rays.layout import BLOCK, COUNT_MASK, MAX_DEPTH, REF_SHIFT, WIDTH
from softpipe.rays.triangle import hit_sheared, ray_space

__all__ = ["query", "query_inline", "start_row", "step", "store", "node_stack", "t_stack", "STACK_SIZE", "SLAB_PAD", "REACH_PAD"]

#: The traversal's stack. Why it can never overflow, for any ray :func:`_start` lets in:
#:
#: - only real children are entered or put aside. An empty lane (lo = +inf, hi = −inf) is
#:   missed by every ray with a finite origin and direction: along x, 1/dx is never NaN or 0
#:   (±inf for dx = ±0), so the near plane gives (+inf − ox)·(1/dx) = +inf (the near row is
#:   lo.x when 1/dx > 0, hi.x = −inf times a negative 1/dx otherwise) and the far one −inf:
#:   the entry exceeds the exit. Rays with a NaN or infinite coordinate are refused by
#:   :func:`_start`. Links point to wide nodes made later, so no node is entered twice.
#: - the stack holds, bottom to top, children of ever deeper levels (a visit pushes the
#:   children one level below the node, on top of entries no deeper than it; a pop takes
#:   the deepest), at most WIDTH − 1 of each level 1 … L while a node of wide level L is
#:   visited. A wide node's level is at most its binary depth, and it is an inner node,
#:   so L ≤ MAX_DEPTH − 2 (the build keeps every leaf's depth below MAX_DEPTH).
#:
#: So a visit finds at most (WIDTH − 1)·L entries and writes at most WIDTH − 1 more
#: (each child written at the top before the test that keeps it): index
#: (WIDTH − 1)·(MAX_DEPTH − 1) − 1 at most, below this size.
STACK_SIZE = (WIDTH - 1) * MAX_DEPTH + 1     # + 1: a child the ray misses is written, then overwritten

#: 1 + 2γ(3), pbrt's padding of a box's far distance (3rd ed., §3.9): γ(n) = nu / (1 − nu),
#: u = 2⁻⁵³ the unit roundoff of float64.
_U = 2.0 ** -53
SLAB_PAD = 1.0 + 2.0 * (3.0 * _U / (1.0 - 3.0 * _U))

#: How far (relative) beyond the nearest hit so far the closest-hit search still opens
#: boxes: a box whose rounded entry is an ulp or so past that t may hold a triangle
#: hit at exactly that t with a lower id, which wins the tie (2⁻⁴⁴ ≈ 6·10⁻¹⁴).
REACH_PAD = 2.0 ** -44


# ------------------------------------------------------------------ the stacks

# The traversal's stacks live in the calling function's own frame (an alloca, as C would):
# np.empty would cost a heap allocation, and a reference count, per ray.

def node_stack():
    """The traversal's [STACK_SIZE] int64 stack, in the calling function's frame (plain Python: a new array)."""
    return np.empty(STACK_SIZE, np.int64)


def t_stack():
    """The traversal's [STACK_SIZE] float64 stack, in the calling function's frame (plain Python: a new array)."""
    return np.empty(STACK_SIZE, np.float64)


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


@overload(node_stack, inline="always")
def _node_stack_compiled():
    return lambda: _node_stack_intrinsic()


@overload(t_stack, inline="always")
def _t_stack_compiled():
    return lambda: _t_stack_intrinsic()


# ------------------------------------------------------------------ a node's boxes

@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
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


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
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


# ------------------------------------------------------------------ a leaf's triangles

def _block_candidates(tris, b, kx, ky, kz, okx, oky, okz, sx, sy, sz, t_min, t_max):
    """Which lanes of triangle block ``b`` may be hit: a bit mask (bit j: lane j).

    Compiled (:func:`_block_candidates_intrinsic`), the watertight test of
    :func:`hit_sheared` on the block's four triangles at once, in vectors of four
    float64 with the same IEEE operations in the same order (so the same U, V, W,
    det and t): a lane is a candidate when the test hits it, or when an edge
    function is exactly 0 (there the exact recomputation decides). The caller runs
    :func:`hit_sheared` on the candidates only, so the answer is the scalar test's.
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


# ------------------------------------------------------------------ one ray

@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def _order2(ta, ca, tb, cb):
    """(ta, ca), (tb, cb) with the smaller t first: a compare-exchange of the sorting network, written
    as min, max and selects so that it compiles without a branch (the order of a ray's children is
    what a branch predictor cannot guess)."""
    swap = tb < ta
    return min(ta, tb), cb if swap else ca, max(ta, tb), ca if swap else cb


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def _start(lo, hi, first, count, ox, oy, oz, dx, dy, dz, t_min, t_max):
    """A ray's constants and the traversal's first state: (ray, state); see :func:`step`.

    Once per ray: Woop's axis permutation and shear (:func:`ray_space`), ``1/d``,
    which box planes the ray enters by, and the root's box (a ray that misses it,
    a zero direction or an empty interval starts finished). A ray with a NaN or
    infinite coordinate in its origin or direction, or a NaN t_min or t_max, starts
    finished too: it misses. (Why: the box tests take a NaN as "no constraint", so
    such a ray would enter every box, the empty lanes too, whose link is the root:
    it would loop and overflow the stack. For a finite ray an empty lane always
    misses; see :data:`STACK_SIZE`.)
    """
    kx, ky, kz, sx, sy, sz = ray_space(dx, dy, dz)
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
    finite = (math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)
              and math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz))
    live = count.shape[0] > 0 and finite and sz != 0.0 and t_min < t_max   # NaN t: t_min < t_max is false
    if live:
        live = _box_entry(lo, hi, 0, ox, oy, oz, ix, iy, iz, t_min, reach) != math.inf
    ref, n = 0, 0
    if live and count[0] > 0:                # the root is a leaf (no wide nodes): from block 0
        ref, n = 0, count[0]
    return ray, (live, ref, n, 0, reach, -1, t_max, 0.0, 0.0)


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def step(boxes, links, tris, tri_ids, ray, state, any_, stack_node, stack_t):
    """One step of the stack traversal: a wide node or a leaf visited, then the next one chosen.

    The traversal walks the wide nodes (``boxes``, ``links``; :mod:`softpipe.rays.layout`): a
    visit tests the boxes of all four children (stored side by side in the node),
    goes on into the nearest child the ray meets and puts the others aside,
    farthest deepest. It walks (ref, n) pairs: n = 0 names wide node ref, n > 0 the
    leaf of triangles ``ref … ref + n − 1``. ``stack_node``, ``stack_t``
    [STACK_SIZE]: the children put aside (``ref << REF_SHIFT | n``) and the t where each
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
                hit, t, b1, b2 = hit_sheared(
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
            return True, c0 >> REF_SHIFT, c0 & COUNT_MASK, top, reach, best_id, best_t, best_b1, best_b2
    # pop the next child whose box begins no farther than the best hit
    while top > 0:
        top -= 1
        if stack_t[top] <= reach:
            code = stack_node[top]
            return True, code >> REF_SHIFT, code & COUNT_MASK, top, reach, best_id, best_t, best_b1, best_b2
    return False, ref, n, top, reach, best_id, best_t, best_b1, best_b2


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def _traverse(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max, any_,
              stack_node, stack_t):
    """One ray's query, (id, t, b1, b2), compiled into each caller (``inline="always"``) on borrowed
    arrays: :func:`_start`, then :func:`step` until the answer is known."""
    ray, state = _start(lo, hi, first, count, ox, oy, oz, dx, dy, dz, t_min, t_max)
    while state[0]:
        state = step(boxes, links, tris, tri_ids, ray, state, any_, stack_node, stack_t)
    return state[5], state[6], state[7], state[8]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def query(boxes, links, lo, hi, first, count, tris, tri_ids, ox: float, oy: float, oz: float,
          dx: float, dy: float, dz: float, t_min: float, t_max: float, any_: bool) -> tuple:
    """One ray's closest hit (or with ``any_``, a hit, the first found), with its stack in this frame.

    Parameters
    ----------
    boxes, links, lo, hi, first, count, tris, tri_ids : numpy arrays
        The BVH's arrays (:class:`~softpipe.rays.bvh.BVHUniform`), borrowed by the caller.
    ox, oy, oz, dx, dy, dz : float
        The ray's origin and direction (any length; t is in its units).
    t_min, t_max : float
        The open interval searched.
    any_ : bool
        Stop at the first hit found instead of searching for the nearest.

    Returns
    -------
    tuple
        (id, t, b1, b2): id −1 for a miss (then t = t_max, b1 = b2 = 0).
    """
    return _traverse(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max,
                     any_, node_stack(), t_stack())


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def query_inline(boxes, links, lo, hi, first, count, tris, tri_ids, ox: float, oy: float, oz: float,
                 dx: float, dy: float, dz: float, t_min: float, t_max: float, any_: bool) -> tuple:
    """:func:`query` compiled into the caller (``inline="always"``), its stacks in the caller's frame.

    The same walk and the same answer, bit for bit; for a kernel whose hot loop is its rays (the path
    tracer), where a call per ray, handing on eight arrays, cost about as much as the walk through a small
    scene. Each call site is a copy of the walk: a kernel should have few.
    """
    return _traverse(boxes, links, lo, hi, first, count, tris, tri_ids, ox, oy, oz, dx, dy, dz, t_min, t_max,
                     any_, node_stack(), t_stack())


# ------------------------------------------------------------------ batches of rays
# (the loop over a band is softpipe.rays.bvh._batch_kernel: it borrows the arrays in its own body)

@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def start_row(lo, hi, first, count, origins, directions, t_min, t_max, r):
    """:func:`_start` for ray r of a batch: (ray, state), the arguments of :func:`step`."""
    return _start(lo, hi, first, count, origins[r, 0], origins[r, 1], origins[r, 2],
                  directions[r, 0], directions[r, 1], directions[r, 2], t_min[r], t_max[r])


@numba.njit(cache=True, nogil=True, error_model="numpy", forceinline=True)
def store(r, state, any_, ids, ts, bs, occluded):
    """Ray r's answer from its final state (see :func:`step`)."""
    i = state[5]
    if any_:
        occluded[r] = i >= 0
    else:
        ids[r] = i
        if i >= 0:
            ts[r], bs[r, 0], bs[r, 1] = state[6], state[7], state[8]
        else:
            ts[r], bs[r, 0], bs[r, 1] = np.inf, 0.0, 0.0
