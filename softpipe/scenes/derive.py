"""The one compiled pass from a visibility record to the buffers users read (docs/outputs.md).

:func:`softpipe.scenes.outputs.derive_outputs` hands this module a framebuffer drawn
with ``record=True`` and the names of the buffers asked for. Three steps:

1. **the draws, packed** (:func:`pack_draws`): the frame has few draws (a scene's
   objects; ``field10k``'s one draw of 10,000 instances), each with its own arrays.
   They become a table of numbers per draw (where its record values start, its
   object id, the offsets of its arrays, kd and matrices), the NDC coordinates of the
   pixel centres per viewport, and one array each of corner indices, triangle maps,
   clip corners, positions, normals and uv, the draws' arrays end to end (a frame of
   one draw uses its arrays as they are).
2. **the pass** (:func:`_derive_rows`): a numba kernel over image rows, run in bands
   on both cores (:func:`softpipe.core.parallel.in_bands`, softpipe's one way of using
   both, rather than numba's ``prange``: that module says why); each pixel is computed and
   written by the band of its row, from its own record value alone, so the buffers do not
   depend on the thread count. A row is made in arrays of one row, which stay in the
   cache: the background's values written over it (:func:`_fill_background`, one short
   loop per buffer), then the row's covered pixels listed (record value ≥ 0; read in
   blocks of 16, a block of background passed over after one test), and only those
   computed: the sample of least depth (the first of equals), the record value taken
   apart (draw, instance, primitive) and the ids, in one loop that also lists the
   pixels of a surface; then, each in a loop of its own over that list, their corners,
   the perspective-correct barycentrics at the pixel centre from the source clip corners,
   position and eye depth, normal, and uv (short loops whose pixels do not wait for each
   other, where one loop doing it all made each pixel wait on the last). Then the row
   is copied into each buffer asked for by streaming stores
   (:mod:`softpipe.core.streaming`): the buffers, 24 MB at 1024² for depth, normal and
   the ids, are written once in whole lines and never read, which made the pass 0.7×
   its time. (A frame is mostly background: the bunny at 1024² covers 22 % of its
   pixels.) A caller deriving frame after frame passes the last frame's arrays
   (``out=``): new ones are fresh pages the system zeroes first.
3. **the textures** (:func:`_sample_textures`): a textured draw's albedo is kd times
   :func:`softpipe.light.texture.texture_lod` at the pixel's uv, level 0 — the
   texture is a different numba type per draw, so the pass leaves the uv of those
   pixels (float64) and the lookup runs once per textured draw afterwards.

The arithmetic is the numpy derivation's, operation for operation, so the buffers are
the same bits: the 3-term sums in order ((0 + t0) + t1) + t2 (``np.einsum``'s), the cross
product and its sum as ``np.cross`` and ``sum``, the matrix products as fused
multiply-adds in the order k = 0…3 from +0 (what OpenBLAS's dgemm does on a machine
with FMA, where numpy's ``@`` went; :func:`fma` is exact everywhere, so the pass gives
the same bytes on every machine). Where the numpy derivation's values depended on
more than the pixel, the pass does not follow it: numpy multiplied a draw's covered
pixels as one matrix, and a draw covering a single pixel went to BLAS's gemv, which
sums in another order (a last-bit difference in float64, rarely in the float32 buffers).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Dict, List, Mapping, Optional, Sequence

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

from softpipe.core.parallel import in_bands
from softpipe.core.streaming import stream_fence, stream_row
from softpipe.light.texture import texture_lod
from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES, primitive_indices
from softpipe.pipeline.framebuffer import Framebuffer, RecordedDraw
from softpipe.pipeline.transforms import normal_matrix

__all__ = ["DrawTable", "pack_draws", "derive_buffers", "check_out_array", "fma", "BUFFER_NAMES"]

#: The buffers the pass writes (``color`` is the framebuffer's own, copied by the caller).
BUFFER_NAMES = ("depth", "linear_depth", "position", "normal", "object_id", "triangle_id", "barycentrics", "uv",
                "albedo")

# The columns of the per-draw integer table (one row per recorded draw). Offsets are rows of the joined
# arrays; −1 where the draw has none.
I_BASE, I_COUNT, I_PER, I_OBJECT, I_TRIANGLE_TOPOLOGY, I_SURFACE, I_MAP, I_MAP_LENGTH, I_CORNERS, \
    I_PRIMITIVES, I_VERTICES, I_CLIP, I_POSITIONS, I_NORMALS, I_UVS, I_TEXTURED, I_VIEWPORT, I_COLUMNS = range(18)
# The columns of the per-draw float table: kd, model_view, model (row-major 4×4 each) and the normal
# matrix (3×3).
F_KD, F_MODEL_VIEW, F_MODEL, F_NORMAL_MATRIX, F_COLUMNS = 0, 3, 19, 35, 44

# Which buffers the pass writes: flags, one per entry of BUFFER_NAMES, then the textures' uv.
W_DEPTH, W_LINEAR, W_POSITION, W_NORMAL, W_OBJECT, W_TRIANGLE, W_BARY, W_UV, W_ALBEDO, W_TEXTURE_UV = range(10)


# ------------------------------------------------------------------ a fused multiply-add

def fma(a: float, b: float, c: float) -> float:
    """a·b + c rounded once (IEEE 754 fusedMultiplyAdd): compiled, LLVM's ``llvm.fma``; in plain Python
    (``NUMBA_DISABLE_JIT=1``) exactly, through fractions (a non-finite operand gives a·b + c)."""
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return a * b + c
    return float(Fraction(a) * Fraction(b) + Fraction(c))


@intrinsic
def _fma_intrinsic(typingctx, a, b, c):
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(fn, args)
    return sig, codegen


@overload(fma, inline="always")
def _fma_compiled(a, b, c):
    return lambda a, b, c: _fma_intrinsic(np.float64(a), np.float64(b), np.float64(c))


# ------------------------------------------------------------------ the draws, packed

@dataclass
class DrawTable:
    """A frame's recorded draws as the pass reads them (:func:`pack_draws`).

    Attributes
    ----------
    ints : int64 [D, I_COLUMNS]
        Per draw: the first record value, how many it took, primitives per instance, the object id,
        whether its topology is of triangles (it has triangle ids) and whether its primitives are
        (it has a surface), then offsets and sizes into the joined arrays below (−1: none).
    floats : float64 [D, F_COLUMNS]
        Per draw: kd, model_view, model, normal matrix.
    ndc_x, ndc_y : float64 [V, W], [V, H]
        Per viewport of the frame's draws (``ints[:, I_VIEWPORT]``), the NDC x of each column's and the
        NDC y of each row's pixel centre: computed once here, not per pixel (a division each).
    corners : int64 [P, 3]
        Each draw's primitives' vertex indices (:func:`~softpipe.pipeline.assembly.primitive_indices`).
    maps : int64 [M]
        Triangle index in the object's whole mesh, per triangle of a draw of one material.
    clip, positions, normals, uvs : float64 [·, 4], [·, 4], [·, 3], [·, 2]
        The vertex stage's clip coordinates, the positions as (x, y, z, 1), the normals and uv.
    failed : list of (Exception or None)
        Per draw, what computing its matrices raised (raised only if the draw covers a pixel).
    textures : list
        Per draw, the texture its albedo is multiplied by, or None.
    """

    ints: np.ndarray
    floats: np.ndarray
    corners: np.ndarray
    maps: np.ndarray
    clip: np.ndarray
    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    ndc_x: np.ndarray
    ndc_y: np.ndarray
    failed: List[Optional[Exception]]
    textures: List[object]


def _uniform_matrix(call, name: str) -> np.ndarray:
    value = getattr(call.uniforms, name, None)
    m = np.eye(4) if value is None else np.asarray(value, np.float64)
    return m if m.shape == (4, 4) else np.eye(4)


def _albedo_of(call) -> np.ndarray:
    """The draw's kd: its ``material`` uniform's, else its ``color`` uniform, else white."""
    material = getattr(call.uniforms, "material", None)
    kd = getattr(material, "kd", None)
    if kd is None:
        kd = getattr(call.uniforms, "color", (1.0, 1.0, 1.0))
    kd = np.asarray(kd, np.float64).ravel()
    return kd[:3] if kd.size >= 3 else np.ones(3)


def _homogeneous(positions) -> np.ndarray:
    """Positions [V, c] as (x, y, z, 1) float64 [V, 4] (missing coordinates 0)."""
    p = np.asarray(positions, np.float64)
    p = p.reshape(len(p), -1)
    out = np.zeros((len(p), 4), np.float64)        # one array written in place (concatenating copied twice)
    c = min(p.shape[1], 3)
    out[:, :c] = p[:, :c]
    out[:, 3] = 1.0
    return out


def _rows_read(rows: int, vertices: int, corners: np.ndarray) -> int:
    """How many rows ``corners`` read from an array of ``rows`` rows: ``vertices`` bounds every index
    (assembly checked them), so the greatest index is looked for only when the array is shorter."""
    if not len(corners):
        return 0
    return vertices if rows >= vertices else int(corners.max()) + 1


def _attribute(call, name: str, width: int, k: int, vertices: int, corners: np.ndarray) -> Optional[np.ndarray]:
    """The draw's vertex attribute ``name`` as float64 [V, width], or None when it has none; it must have a
    row for every index of ``corners`` (:func:`_rows_read`)."""
    attributes = call.attributes or {}
    if name not in attributes:
        return None
    a = np.asarray(attributes[name], np.float64)
    needed_rows = _rows_read(len(a) if a.ndim == 2 else 0, vertices, corners)
    if a.ndim != 2 or a.shape[1] != width or len(a) < needed_rows:
        raise ValueError(f"derive_outputs: recorded draw {k}'s attribute {name!r} has shape {a.shape}; the "
                         f"outputs read it as [vertices, {width}] with at least {needed_rows} rows")
    return a


class _Joined:
    """Arrays of one kind, end to end, with each one's first row (a single array is used as it is)."""

    def __init__(self, width: int, dtype):
        self.parts: List[np.ndarray] = []
        self.rows = 0
        self.width, self.dtype = width, dtype

    def add(self, a: Optional[np.ndarray]) -> int:
        if a is None:
            return -1
        self.parts.append(a)
        self.rows += len(a)
        return self.rows - len(a)

    def array(self) -> np.ndarray:
        shape = (0,) if self.width == 0 else (0, self.width)
        if not self.parts:
            return np.zeros(shape, self.dtype)
        if len(self.parts) == 1:
            return np.ascontiguousarray(self.parts[0], self.dtype)
        return np.ascontiguousarray(np.concatenate(self.parts), self.dtype)


def pack_draws(draws: Sequence[RecordedDraw], maps: Dict[int, np.ndarray], geometric: bool,
               textured: bool, width: int, height: int, positional: bool = True) -> DrawTable:
    """The recorded draws of a ``width`` × ``height`` frame as the pass reads them.

    ``maps`` gives, for a draw of one material of a mesh of several, its triangles' indices in
    the whole mesh. With ``geometric`` (a buffer that needs the surface is asked for) the clip
    corners, attributes and matrices are packed too, and with ``positional`` (position or
    linear depth asked for) the positions as (x, y, z, 1); with ``textured`` the draws' textures
    are noted (albedo asked for).
    """
    d_count = len(draws)
    ints = np.full((d_count, I_COLUMNS), -1, np.int64)
    floats = np.zeros((d_count, F_COLUMNS), np.float64)
    corners, mapped = _Joined(3, np.int64), _Joined(0, np.int64)
    clip, positions, normals, uvs = _Joined(4, np.float64), _Joined(4, np.float64), _Joined(3, np.float64), \
        _Joined(2, np.float64)
    failed: List[Optional[Exception]] = [None] * d_count
    textures: List[object] = [None] * d_count
    viewports: Dict[tuple, int] = {}
    ndc_x: List[np.ndarray] = []
    ndc_y: List[np.ndarray] = []
    for k, d in enumerate(draws):
        call = d.call
        row = ints[k]
        row[I_BASE], row[I_COUNT], row[I_PER] = d.base, d.count, max(d.per_instance, 1)
        # a scene's draws name their object; a draw made by hand is its own object, by its place in the frame
        row[I_OBJECT] = int(d.tag) if isinstance(d.tag, (int, np.integer)) else k
        row[I_TRIANGLE_TOPOLOGY] = call.topology in TRIANGLE_TOPOLOGIES
        row[I_SURFACE] = d.kind == "triangles" and call.topology in TRIANGLE_TOPOLOGIES
        if k in maps:
            row[I_MAP] = mapped.add(np.asarray(maps[k], np.int64))
            row[I_MAP_LENGTH] = len(maps[k])
        if not geometric:
            continue
        floats[k, F_KD:F_KD + 3] = _albedo_of(call)
        vp = call.viewport
        key = (vp.x, vp.y, vp.width, vp.height)
        if key not in viewports:
            # the pixel centres in NDC, as the numpy pass computed them (integers first, then the halves)
            cols, rows = np.arange(width, dtype=np.int64), np.arange(height, dtype=np.int64)
            viewports[key] = len(ndc_x)
            ndc_x.append(2.0 * (cols + 0.5 - vp.x) / vp.width - 1.0)
            ndc_y.append(2.0 * (height - rows - 0.5 - vp.y) / vp.height - 1.0)
        row[I_VIEWPORT] = viewports[key]
        vertices = int(d.vertices_per_instance)
        # the corners as drawn (assembly made them, int64, each checked to lie in [0, vertices)); a draw recorded
        # without them has them made again from its indices, checked the same way
        corner = d.corners
        if corner is None:
            try:
                corner = np.asarray(primitive_indices(call.topology, call.indices, vertices), np.int64).reshape(-1, 3)
            except (ValueError, TypeError) as e:
                raise ValueError(f"derive_outputs: recorded draw {k} does not match its record: {e}") from e
        instances = d.count // max(d.per_instance, 1)
        # what the pass indexes must exist: it does not check bounds per pixel
        if len(corner) < d.per_instance or len(d.clip) < vertices * instances:
            raise ValueError(f"derive_outputs: recorded draw {k} does not match its record: {len(corner)} primitives "
                             f"of corners in [0, {vertices}) for {d.per_instance} per instance, and {len(d.clip)} "
                             f"clip rows for {instances} instances of {vertices} vertices")
        row[I_CORNERS], row[I_PRIMITIVES], row[I_VERTICES] = corners.add(corner), len(corner), vertices
        row[I_CLIP] = clip.add(np.asarray(d.clip, np.float64))
        if not row[I_SURFACE]:
            continue
        if positional:                           # (a copy of every position: only where they are read)
            p = _homogeneous(call.positions)
            needed = _rows_read(len(p), vertices, corner)
            if len(p) < needed:
                raise ValueError(f"derive_outputs: recorded draw {k} has {len(p)} positions; its indices reach "
                                 f"{needed - 1}")
            row[I_POSITIONS] = positions.add(p)
        normal = _attribute(call, "normal", 3, k, vertices, corner)
        uv = _attribute(call, "uv", 2, k, vertices, corner)
        row[I_NORMALS], row[I_UVS] = normals.add(normal), uvs.add(uv)
        try:
            model_view = _uniform_matrix(call, "model_view")
            model = np.linalg.solve(_uniform_matrix(call, "view"), model_view)
            floats[k, F_MODEL_VIEW:F_MODEL_VIEW + 16] = model_view.ravel()
            floats[k, F_MODEL:F_MODEL + 16] = model.ravel()
            if normal is not None:
                floats[k, F_NORMAL_MATRIX:F_NORMAL_MATRIX + 9] = normal_matrix(model).ravel()
        except (np.linalg.LinAlgError, ValueError) as e:     # raised if the draw shows (as the numpy pass did)
            failed[k] = e
        texture = getattr(call.uniforms, "texture", None)
        if textured and uv is not None and texture is not None and hasattr(texture, "texels"):
            textures[k] = texture
            row[I_TEXTURED] = 1
    return DrawTable(ints, floats, corners.array(), mapped.array(), clip.array(), positions.array(),
                     normals.array(), uvs.array(),
                     np.array(ndc_x, np.float64).reshape(len(ndc_x), width),
                     np.array(ndc_y, np.float64).reshape(len(ndc_y), height), failed, textures)


# ------------------------------------------------------------------ the pass

@numba.njit(cache=True, nogil=True, inline="always")
def _matrix_row(floats, k, offset, row, columns, a0, a1, a2, a3):
    """Σ_c a_c·M[row, c] of the row-major matrix M of draw k stored at floats[k, offset:], as fused
    multiply-adds in the order c = 0, 1, … from +0 (OpenBLAS's dgemm on a machine with FMA, where
    numpy's ``a @ M.T`` went). (No ``floats[k]`` view: a view per pixel counts references atomically,
    and two threads counting on one array queue for its cache line.)"""
    base = offset + row * columns
    s = fma(a0, floats[k, base], 0.0)
    s = fma(a1, floats[k, base + 1], s)
    s = fma(a2, floats[k, base + 2], s)
    if columns == 4:
        s = fma(a3, floats[k, base + 3], s)
    return s


@numba.njit(cache=True, nogil=True, inline="always")
def _interpolated(b0, b1, b2, a, r0, r1, r2, c):
    """b0·a[r0, c] + b1·a[r1, c] + b2·a[r2, c], summed as ``np.einsum`` sums: ((0 + t0) + t1) + t2."""
    return ((0.0 + b0 * a[r0, c]) + b1 * a[r1, c]) + b2 * a[r2, c]


@numba.njit(cache=True, nogil=True, inline="always")
def _fill_background(a, b, w_depth, w_linear, w_position, w_normal, w_object, w_triangle, w_bary, w_uv, w_albedo,
                     out_depth, out_linear, out_position, out_normal, out_object, out_triangle, out_bary, out_uv,
                     out_albedo):
    """Pixels a:b of the buffers asked for, as where no recorded surface is: depth 1, ids −1, NaN
    elsewhere (docs/outputs.md's "no surface" column). The pass writes a whole row so before its
    covered pixels: one tight loop per buffer, rather than a chain of tests per background pixel."""
    nan = np.float32(np.nan)
    if w_depth:
        for p in range(a, b):
            out_depth[p] = np.float32(1.0)
    if w_linear:
        for p in range(a, b):
            out_linear[p] = nan
    if w_object:
        for p in range(a, b):
            out_object[p] = np.int32(-1)
    if w_triangle:
        for p in range(a, b):
            out_triangle[p] = np.int32(-1)
    if w_position:
        for p in range(a, b):
            out_position[p, 0] = out_position[p, 1] = out_position[p, 2] = nan
    if w_normal:
        for p in range(a, b):
            out_normal[p, 0] = out_normal[p, 1] = out_normal[p, 2] = nan
    if w_bary:
        for p in range(a, b):
            out_bary[p, 0] = out_bary[p, 1] = out_bary[p, 2] = nan
    if w_albedo:
        for p in range(a, b):
            out_albedo[p, 0] = out_albedo[p, 1] = out_albedo[p, 2] = nan
    if w_uv:
        for p in range(a, b):
            out_uv[p, 0] = out_uv[p, 1] = nan


# error_model="numpy": a division by zero gives IEEE's inf or NaN, as the numpy derivation's did (a zero
# normal's length), not a ZeroDivisionError
@numba.njit(cache=True, nogil=True, error_model="numpy")
def _derive_rows(lo, hi, width, record, blank, depth, vis, touched, tile_w, tile_h, pending_ids, ints, floats, corners,
                 maps, clip, positions, normals, uvs, ndc_x, ndc_y, want, whole_depth, whole_linear, whole_position,
                 whole_normal, whole_object, whole_triangle, whole_bary, whole_uv, whole_albedo, texture_uv,
                 texture_draw, present, bad):
    """Rows lo:hi of the buffers. The pixel arrays are flat (pixel p = row·width + column): record and
    depth [S, H·W], the buffers [H·W] or [H·W, c]; a buffer not asked for is empty and not written. With
    ``vis`` not empty, the last fast-path draw's samples are not yet in ``record`` (``Framebuffer.record_parts``):
    a sample's value is ``pending_ids[vis]`` where its tile of ``tile_w`` × ``tile_h`` pixels is ``touched`` and
    ``vis`` ≥ 0 (int32 [S, H·W]), ``record``'s elsewhere, or −1 without reading it if ``blank`` (it holds −1
    everywhere: a frame of one fast draw reads only the tiles that draw touched).

    Each row is made in arrays of one row (``out_*``, indexed by column, in the cache): first written
    as background (:func:`_fill_background`); then its covered pixels (a record value ≥ 0) are listed
    in a loop of nothing else, and only they are computed, overwriting the fill where they have a value
    (a line's normal stays the fill's NaN). Then the row is copied into each buffer by streaming stores
    (:mod:`softpipe.core.streaming`: each buffer is written once, in whole lines, and never read)."""
    samples = depth.shape[0]
    draws = ints.shape[0]
    # the flags read once into scalars: a flag in an array would be loaded again after every store to a
    # buffer (numba cannot tell that the buffers do not overlap it)
    w_depth, w_linear, w_position, w_normal = want[W_DEPTH], want[W_LINEAR], want[W_POSITION], want[W_NORMAL]
    w_object, w_triangle, w_bary, w_uv = want[W_OBJECT], want[W_TRIANGLE], want[W_BARY], want[W_UV]
    w_albedo, w_texture = want[W_ALBEDO], want[W_TEXTURE_UV]
    geometric = w_linear or w_position or w_normal or w_bary or w_uv or w_albedo
    # the current draw's numbers, read again only where the draw changes (neighbours mostly share one)
    current = seen = -1
    base = count = per = object_id = map_at = map_length = corner_at = primitives = vertices = clip_at = \
        positions_at = normals_at = uvs_at = viewport = np.int64(0)
    triangle_topology = surface = textured = False
    kd0 = kd1 = kd2 = np.float32(0.0)
    covered, picks = np.empty(width, np.int64), np.empty(width, np.int64)    # a row's covered pixels, samples
    values = np.empty(width, np.int64)                                       # and their record values
    pending = vis.shape[0] > 0
    height = depth.shape[1] // width if width > 0 else 0
    # a row's pixels of a surface, listed by step 1 for the steps after it: column, draw, the first clip row of
    # its instance, its primitive's corners (first the primitive's row of `corners`), barycentrics
    at, drawn, first = np.empty(width, np.int64), np.empty(width, np.int64), np.empty(width, np.int64)
    corner0, corner1, corner2 = np.empty(width, np.int64), np.empty(width, np.int64), np.empty(width, np.int64)
    bary0, bary1, bary2 = np.empty(width), np.empty(width), np.empty(width)
    # one row of each buffer asked for (empty if not), indexed by column; and the rows and the buffers with
    # their channels in one axis, for the streaming copy
    out_depth = np.empty(width if w_depth else 0, np.float32)
    out_linear = np.empty(width if w_linear else 0, np.float32)
    out_position = np.empty((width if w_position else 0, 3), np.float32)
    out_normal = np.empty((width if w_normal else 0, 3), np.float32)
    out_object = np.empty(width if w_object else 0, np.int32)
    out_triangle = np.empty(width if w_triangle else 0, np.int32)
    out_bary = np.empty((width if w_bary else 0, 3), np.float32)
    out_uv = np.empty((width if w_uv else 0, 2), np.float32)
    out_albedo = np.empty((width if w_albedo else 0, 3), np.float32)
    row_position, row_normal = out_position.reshape(out_position.size), out_normal.reshape(out_normal.size)
    row_bary, row_uv, row_albedo = out_bary.reshape(out_bary.size), out_uv.reshape(out_uv.size), \
        out_albedo.reshape(out_albedo.size)
    all_position, all_normal = whole_position.reshape(whole_position.size), whole_normal.reshape(whole_normal.size)
    all_bary, all_uv, all_albedo = whole_bary.reshape(whole_bary.size), whole_uv.reshape(whole_uv.size), \
        whole_albedo.reshape(whole_albedo.size)
    for j in range(lo, hi):
        bad[j] = -1
        row_start = j * width
        _fill_background(0, width, w_depth, w_linear, w_position, w_normal, w_object, w_triangle, w_bary, w_uv,
                         w_albedo, out_depth, out_linear, out_position, out_normal, out_object, out_triangle, out_bary,
                         out_uv, out_albedo)
        if w_texture:                            # (no texture lookup where no textured draw shows)
            for p in range(row_start, row_start + width):
                texture_draw[p] = -1
        # the row's covered pixels first, in a loop of nothing else (a record value < 0: no surface, the
        # fill's values), with each one's sample: the one of least depth, the first of equals (np.argmin:
        # a NaN first); a frame of no draws has none. The row is read in blocks of 16 pixels: a block whose every
        # record value is −1 (the background, most of a frame) is passed over after one vectorized test (the OR
        # of the values' complements is 0), the others pixel by pixel (the kernel took 0.16 ms less in a bunny
        # frame at 1024²: benchmarks/README.md, "Outputs, round 7").
        # (a block lies in one tile: the caller checked that tile_w is a multiple of 16)
        m = 0
        block = row_start
        tile_y = (height - 1 - j) // tile_h              # (tile row 0 at the bottom, as the visibility pass's)
        while draws > 0 and block < row_start + width:
            block_end = min(block + 16, row_start + width)
            anything = np.int32(0)
            if not blank:
                for s in range(samples):
                    for p in range(block, block_end):
                        anything |= ~record[s, np.uint64(p)]
            deferred = False
            if pending:
                deferred = touched[tile_y, (block - row_start) // tile_w]
            if deferred:
                for s in range(samples):
                    for p in range(block, block_end):
                        anything |= ~vis[s, np.uint64(p)]
            if anything == 0:
                pass
            elif samples == 1:
                for p in range(block, block_end):
                    value = np.int32(-1) if blank else record[0, np.uint64(p)]
                    if deferred and vis[0, np.uint64(p)] >= 0:
                        value = pending_ids[vis[0, np.uint64(p)]]
                    if value >= 0:
                        covered[m], values[m] = p, value
                        m += 1
            else:
                for p in range(block, block_end):
                    pick, least = 0, depth[0, p]
                    if not math.isnan(least):
                        for s in range(1, samples):
                            z = depth[s, p]
                            if math.isnan(z):
                                pick = s
                                break
                            if z < least:
                                pick, least = s, z
                    value = np.int32(-1) if blank else record[pick, p]
                    if deferred and vis[pick, p] >= 0:
                        value = pending_ids[vis[pick, p]]
                    if value >= 0:
                        covered[m], picks[m], values[m] = p, pick, value
                        m += 1
            block = block_end
        # 1. each covered pixel's record value taken apart: its ids and depth written, and a pixel of a
        # surface listed with its draw and corners for the steps after (a short loop of integers)
        n = 0
        for c in range(m):
            p = covered[c]
            u = np.uint64(p)                     # (p as an unsigned index: see the steps below)
            column = p - row_start
            cu = np.uint64(column)
            pick = picks[c] if samples > 1 else 0
            value = values[c]
            # the record value taken apart: the last draw whose range starts at or below it
            k = 0
            if draws > 1:
                a, b = 0, draws
                while a < b:
                    mid = (a + b) // 2
                    if ints[mid, I_BASE] <= value:
                        a = mid + 1
                    else:
                        b = mid
                k = a - 1
            if k < 0:                            # (the first draw's values start at 0: not reached)
                continue
            if k != current:
                current = k
                base, count, per, object_id = ints[k, I_BASE], ints[k, I_COUNT], ints[k, I_PER], ints[k, I_OBJECT]
                triangle_topology, surface = ints[k, I_TRIANGLE_TOPOLOGY] > 0, ints[k, I_SURFACE] > 0
                map_at, map_length, corner_at, primitives = ints[k, I_MAP], ints[k, I_MAP_LENGTH], \
                    ints[k, I_CORNERS], ints[k, I_PRIMITIVES]
                vertices, clip_at = ints[k, I_VERTICES], ints[k, I_CLIP]
                kd0, kd1, kd2 = np.float32(floats[k, F_KD]), np.float32(floats[k, F_KD + 1]), \
                    np.float32(floats[k, F_KD + 2])
                if present[k] == 0:              # (a store per pixel would bounce the line between cores)
                    present[k] = 1               # every writer stores the same 1
            local = value - base
            if local >= count:
                if bad[j] < 0:
                    bad[j] = column              # no draw of this frame made it: the caller raises
                continue
            if local < per:                      # the first instance (every draw without instancing): no division
                instance, primitive = np.int64(0), local
            else:
                instance, primitive = local // per, local % per
            if w_depth:
                out_depth[cu] = depth[pick, u]
            if w_object:
                out_object[cu] = np.int32(object_id)
            if w_triangle:
                triangle = np.int64(-1)
                if triangle_topology:            # edges and corners in a polygon mode name their triangle
                    triangle = primitive
                    if map_at >= 0:
                        if primitive < map_length:
                            triangle = maps[map_at + primitive]
                        elif bad[j] < 0:
                            bad[j] = column
                out_triangle[cu] = np.int32(triangle)  # (< 2³¹: docs/outputs.md)
            if not geometric:
                continue
            if w_albedo:
                out_albedo[cu, 0], out_albedo[cu, 1], out_albedo[cu, 2] = kd0, kd1, kd2
            if primitive >= primitives:
                if bad[j] < 0:
                    bad[j] = column
                continue
            if not surface:
                # a line or point has no surface: its eye depth from the clip w of its first corner
                if w_linear:
                    v0 = corners[corner_at + primitive, 0]
                    out_linear[cu] = np.float32(clip[clip_at + instance * vertices + v0, 3])
                continue
            at[n], drawn[n], first[n], corner0[n] = column, k, clip_at + instance * vertices, corner_at + primitive
            n += 1
        # Below, an index into an array is unsigned (np.uint64) where it is only an index: numba wraps a
        # negative signed index around (a compare and an add per index per access), an unsigned one it takes
        # as it is; none of these is ever negative (the pass took 0.82–0.94× its time: benchmarks/README.md,
        # "Outputs, round 4").
        # the listed pixels' corners, in a loop of nothing else: a frame's triangles are spread over the
        # corner array, and in this loop the reads of many pixels wait for memory at once
        for s in range(n):
            corner = np.uint64(corner0[s])
            corner0[s], corner1[s], corner2[s] = corners[corner, 0], corners[corner, 1], corners[corner, 2]
        # 2. the listed pixels' barycentrics: the cross product of the rows x_i − X·w_i and y_i − Y·w_i (in
        # np.cross's order), normalized to sum 1 (docs/outputs.md). This step and each after it is a loop of
        # its own over the listed pixels, whose iterations do not wait for each other: in the one loop that
        # did everything, a pixel's long chain of dependent steps (record value, corners, clip rows, cross
        # product, divisions, interpolation, matrix, square root, division) left the processor little to do
        # beside it (split, the pass took 0.87–0.99 of its time: docs/outputs.md, "Cost"). Each step keeps
        # its own current draw (`seen`): step 1's `current` goes with the draw numbers it read.
        seen = -1
        for s in range(n):
            k = drawn[s]
            if k != seen:
                seen, viewport = k, ints[k, I_VIEWPORT]
            p = at[s]
            x, y = ndc_x[viewport, p], ndc_y[viewport, j]          # the pixel centre in NDC
            q0, q1, q2 = np.uint64(first[s] + corner0[s]), np.uint64(first[s] + corner1[s]), \
                np.uint64(first[s] + corner2[s])
            a0, a1, a2 = clip[q0, 0] - x * clip[q0, 3], clip[q1, 0] - x * clip[q1, 3], clip[q2, 0] - x * clip[q2, 3]
            c0, c1, c2 = clip[q0, 1] - y * clip[q0, 3], clip[q1, 1] - y * clip[q1, 3], clip[q2, 1] - y * clip[q2, 3]
            e0 = a1 * c2 - a2 * c1
            e1 = a2 * c0 - a0 * c2
            e2 = a0 * c1 - a1 * c0
            total = (e0 + e1) + e2
            if total != 0:
                b0, b1, b2 = e0 / total, e1 / total, e2 / total
            else:
                b0 = b1 = b2 = np.nan             # a triangle seen edge-on
            bary0[s], bary1[s], bary2[s] = b0, b1, b2
            if w_bary:
                u = np.uint64(p)
                out_bary[u, 0], out_bary[u, 1], out_bary[u, 2] = b0, b1, b2
        # 3. position and eye depth
        if w_linear or w_position:
            seen = -1
            for s in range(n):
                k = drawn[s]
                if k != seen:
                    seen, positions_at = k, ints[k, I_POSITIONS]
                p, b0, b1, b2 = np.uint64(at[s]), bary0[s], bary1[s], bary2[s]
                r0, r1, r2 = np.uint64(positions_at + corner0[s]), np.uint64(positions_at + corner1[s]), \
                    np.uint64(positions_at + corner2[s])
                l0 = _interpolated(b0, b1, b2, positions, r0, r1, r2, 0)
                l1 = _interpolated(b0, b1, b2, positions, r0, r1, r2, 1)
                l2 = _interpolated(b0, b1, b2, positions, r0, r1, r2, 2)
                l3 = _interpolated(b0, b1, b2, positions, r0, r1, r2, 3)
                if w_linear:
                    out_linear[p] = np.float32(-_matrix_row(floats, k, F_MODEL_VIEW, 2, 4, l0, l1, l2, l3))
                if w_position:
                    out_position[p, 0] = _matrix_row(floats, k, F_MODEL, 0, 4, l0, l1, l2, l3)
                    out_position[p, 1] = _matrix_row(floats, k, F_MODEL, 1, 4, l0, l1, l2, l3)
                    out_position[p, 2] = _matrix_row(floats, k, F_MODEL, 2, 4, l0, l1, l2, l3)
        # 4. the normal
        if w_normal:
            seen = -1
            for s in range(n):
                k = drawn[s]
                if k != seen:
                    seen, normals_at = k, ints[k, I_NORMALS]
                if normals_at < 0:
                    continue
                p, b0, b1, b2 = np.uint64(at[s]), bary0[s], bary1[s], bary2[s]
                r0, r1, r2 = np.uint64(normals_at + corner0[s]), np.uint64(normals_at + corner1[s]), \
                    np.uint64(normals_at + corner2[s])
                n0 = _interpolated(b0, b1, b2, normals, r0, r1, r2, 0)
                n1 = _interpolated(b0, b1, b2, normals, r0, r1, r2, 1)
                n2 = _interpolated(b0, b1, b2, normals, r0, r1, r2, 2)
                m0 = _matrix_row(floats, k, F_NORMAL_MATRIX, 0, 3, n0, n1, n2, 0.0)
                m1 = _matrix_row(floats, k, F_NORMAL_MATRIX, 1, 3, n0, n1, n2, 0.0)
                m2 = _matrix_row(floats, k, F_NORMAL_MATRIX, 2, 3, n0, n1, n2, 0.0)
                # np.linalg.norm's sum; a float64 scalar so that plain Python (NUMBA_DISABLE_JIT) divides
                # by a zero length as IEEE does, too
                length = np.float64(np.sqrt((m0 * m0 + m1 * m1) + m2 * m2))
                out_normal[p, 0], out_normal[p, 1], out_normal[p, 2] = m0 / length, m1 / length, m2 / length
        # 5. uv, and the textures' uv
        if w_uv or w_texture:
            seen = -1
            for s in range(n):
                k = drawn[s]
                if k != seen:
                    seen, uvs_at, textured = k, ints[k, I_UVS], ints[k, I_TEXTURED] > 0
                if uvs_at < 0:
                    continue
                p, b0, b1, b2 = np.uint64(at[s]), bary0[s], bary1[s], bary2[s]
                r0, r1, r2 = np.uint64(uvs_at + corner0[s]), np.uint64(uvs_at + corner1[s]), \
                    np.uint64(uvs_at + corner2[s])
                t0 = _interpolated(b0, b1, b2, uvs, r0, r1, r2, 0)
                t1 = _interpolated(b0, b1, b2, uvs, r0, r1, r2, 1)
                if w_uv:
                    out_uv[p, 0], out_uv[p, 1] = t0, t1
                if w_texture and textured:
                    q = p + np.uint64(row_start)
                    texture_uv[q, 0], texture_uv[q, 1] = t0, t1
                    texture_draw[q] = k
        # the row, out
        if w_depth:
            stream_row(whole_depth, row_start, out_depth)
        if w_linear:
            stream_row(whole_linear, row_start, out_linear)
        if w_position:
            stream_row(all_position, 3 * row_start, row_position)
        if w_normal:
            stream_row(all_normal, 3 * row_start, row_normal)
        if w_object:
            stream_row(whole_object, row_start, out_object)
        if w_triangle:
            stream_row(whole_triangle, row_start, out_triangle)
        if w_bary:
            stream_row(all_bary, 3 * row_start, row_bary)
        if w_uv:
            stream_row(all_uv, 2 * row_start, row_uv)
        if w_albedo:
            stream_row(all_albedo, 3 * row_start, row_albedo)
    stream_fence()


@numba.njit(cache=True, nogil=True)
def _touch(a) -> float:
    """Read one value of every 64-byte line of the array ``a`` of 8-byte values (C order), in order."""
    flat = a.reshape(a.size)
    total = 0.0
    for i in range(0, flat.size, 8):
        total += flat[i]
    return total


def _warm(*arrays: np.ndarray) -> float:
    """The vertex arrays the pass gathers from, read once in order before it (:func:`_touch`).

    At the end of a frame they are out of the cache: the frame's buffers (color, depth, the
    visibility record and buffer, 33 MB at 1024²) have passed through it since the vertex stage
    wrote them. Read in order, the hardware's prefetcher brings them back in one sweep (~2 MB for
    the bunny's clip corners and normals); gathered a corner at a time by the pass, each line was a
    miss to memory."""
    return sum(_touch(a) for a in arrays if a.size)


@numba.njit(cache=True)
def _sample_texture(tex, uv, out):
    """The texture at each uv, level of detail 0 (what ``texture(uv)`` gives without derivatives)."""
    for k in range(uv.shape[0]):
        c = texture_lod(tex, (uv[k, 0], uv[k, 1]), 0.0)
        out[k, 0], out[k, 1], out[k, 2] = c[0], c[1], c[2]


def _sample_textures(table: DrawTable, texture_uv: np.ndarray, texture_draw: np.ndarray,
                     albedo: np.ndarray) -> None:
    """A textured draw's albedo: kd × its texture at the pixel's uv (level 0), where the uv is finite."""
    for k, texture in enumerate(table.textures):
        if texture is None:
            continue
        rows, cols = np.nonzero(texture_draw == k)
        if not len(rows):
            continue
        t = texture_uv[rows, cols]
        good = np.isfinite(t).all(axis=1)
        sampled = np.zeros((int(good.sum()), 3))
        _sample_texture(texture, np.ascontiguousarray(t[good]), sampled)
        albedo[rows[good], cols[good]] = table.floats[k, F_KD:F_KD + 3] * sampled


_NONE1, _NONE2, _NONE3 = np.zeros(0, np.float32), np.zeros((0, 0), np.float32), np.zeros((0, 0, 0), np.float32)
# no deferred draw (Framebuffer.record_parts): an empty vis, one untouched tile, no ids
_NO_VIS, _NO_TOUCHED, _NO_IDS = np.zeros((0, 0), np.int32), np.zeros((1, 1), np.bool_), np.zeros(0, np.int32)


def check_out_array(out: Mapping[str, np.ndarray], name: str, shape: tuple, dtype) -> np.ndarray:
    """``out[name]``, checked to be a writeable C-contiguous array of ``shape`` and ``dtype`` (the buffer
    it stands in for); a ValueError naming it and what it should be otherwise."""
    a = out[name]
    if isinstance(a, np.ndarray) and a.shape == tuple(shape) and a.dtype == dtype and a.flags.c_contiguous and \
            a.flags.writeable:
        return a                                 # (before the messages: a frame's arrays are checked every frame)
    want = f"{np.dtype(dtype)} {list(shape)}, C-contiguous and writeable"
    if not isinstance(a, np.ndarray):
        raise ValueError(f"derive_outputs: out[{name!r}] is a {type(a).__name__}, not an array; the {name} "
                         f"buffer is {want}")
    what = f"{a.dtype} {list(a.shape)}" + ("" if a.flags.c_contiguous else ", not C-contiguous") + \
        ("" if a.flags.writeable else ", read-only")
    raise ValueError(f"derive_outputs: out[{name!r}] is {what}; the {name} buffer of this frame is {want}")


def derive_buffers(fb: Framebuffer, names: Sequence[str], maps: Dict[int, np.ndarray],
                   out: Optional[Mapping[str, np.ndarray]] = None) -> Dict[str, np.ndarray]:
    """The buffers ``names`` (of :data:`BUFFER_NAMES`) of a framebuffer drawn with a visibility record,
    in one compiled pass over its pixels (module docstring); ``maps`` as :func:`pack_draws` takes it;
    a buffer named in ``out`` is written into its array there (checked by :func:`check_out_array`).

    Raises
    ------
    ValueError
        The record holds a value no recorded draw made (it was changed after drawing), or a draw's
        inputs do not match its record (an attribute of the wrong shape), or an array of ``out`` is
        not its buffer's shape and dtype.
    """
    want_names = set(names)
    if not want_names:          # (the color alone: it is the framebuffer's, nothing to derive)
        return {}
    h, w = fb.height, fb.width
    want = np.array([n in want_names for n in BUFFER_NAMES] + [False], np.bool_)
    geometric = bool(want_names & {"linear_depth", "position", "normal", "barycentrics", "uv", "albedo"})
    draws = fb.recorded_draws
    table = pack_draws(draws, maps, geometric, "albedo" in want_names, w, h,
                       positional=bool(want_names & {"linear_depth", "position"}))
    textured = any(t is not None for t in table.textures)
    want[W_TEXTURE_UV] = textured

    def buffer(name, shape, dtype):
        if name not in want_names:
            return np.zeros((0,) * len(shape), dtype)
        if out is not None and name in out:
            return check_out_array(out, name, shape, dtype)
        return np.empty(shape, dtype)

    buffers = {"depth": buffer("depth", (h, w), np.float32), "linear_depth": buffer("linear_depth", (h, w), np.float32),
           "position": buffer("position", (h, w, 3), np.float32), "normal": buffer("normal", (h, w, 3), np.float32),
           "object_id": buffer("object_id", (h, w), np.int32), "triangle_id": buffer("triangle_id", (h, w), np.int32),
           "barycentrics": buffer("barycentrics", (h, w, 3), np.float32), "uv": buffer("uv", (h, w, 2), np.float32),
           "albedo": buffer("albedo", (h, w, 3), np.float32)}
    texture_uv = np.empty((h, w, 2)) if textured else np.zeros((0, 0, 2))
    texture_draw = np.empty((h, w), np.int64) if textured else np.zeros((0, 0), np.int64)
    present = np.zeros(len(draws), np.int8)
    bad = np.empty(h, np.int64)
    record, blank, deferred = fb.record_parts()
    if deferred is not None and deferred[2] % 16:
        record, blank, deferred = fb.record, False, None   # (tiles the blocks of 16 would straddle: stored first)
    assert record is not None                    # the caller checked
    samples = record.shape[0]
    if deferred is None:
        vis, touched, tile_w, tile_h, pending_ids = _NO_VIS, _NO_TOUCHED, 16, 1, _NO_IDS
    else:
        vis, touched, tile_w, tile_h, pending_ids = deferred
        vis = vis.reshape(samples, h * w)

    def flat(a: np.ndarray) -> np.ndarray:
        """A buffer with its pixels in one axis (a view: the buffers are made C-contiguous above)."""
        return a.reshape((a.shape[0] * a.shape[1],) + a.shape[2:])

    _warm(table.corners, table.clip, table.normals, table.positions, table.uvs)
    in_bands(_derive_rows, h, w, record.reshape(samples, h * w), blank, fb.samples_depth.reshape(samples, h * w),
             vis, touched, tile_w, tile_h, pending_ids, table.ints, table.floats, table.corners, table.maps, table.clip, table.positions, table.normals,
             table.uvs, table.ndc_x, table.ndc_y, want, *(flat(buffers[n]) for n in BUFFER_NAMES), flat(texture_uv),
             flat(texture_draw), present, bad,
             grain=max(1, 16384 // w))
    broken = np.flatnonzero(bad >= 0)
    if len(broken):
        j = int(broken[0])
        i = int(bad[j])
        end = int(table.ints[-1, I_BASE] + table.ints[-1, I_COUNT]) if len(draws) else 0
        stored = fb.record                       # (with the last draw's samples in it)
        assert stored is not None
        raise ValueError(f"derive_outputs: the visibility record at pixel ({i}, {j}) holds "
                         f"{stored[:, j, i].tolist()}, which no recorded draw of this frame made (its "
                         f"{len(draws)} draws took the values 0 to {end - 1}); was fb.record changed after drawing?")
    for k, e in enumerate(table.failed):
        if e is not None and present[k]:
            raise e
    if textured:
        _sample_textures(table, texture_uv, texture_draw, buffers["albedo"])
    return {n: buffers[n] for n in names}
