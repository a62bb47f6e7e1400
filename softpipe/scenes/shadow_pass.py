"""Shadow maps: a depth pass from every light that casts shadows (FORMULAS §21, rasterized).

A shadow ray asks "is anything between p and the light?" (§21). A rasterizer
answers every such question of a light at once: it draws the scene *from the
light* into a depth-only target, the shadow map, and a fragment shader later
compares a point's depth from the light with what the map holds
(:mod:`softpipe.light.shadowmap`). This module makes the maps; it is a pass that runs
the ordinary pipeline (:class:`softpipe.DrawCall`) with the light as the camera.

Per light kind (FORMULAS §9):

directional
    An orthographic projection along the light's direction, fitted to the bounds
    of the shadow casters (the shadow of anything else cannot fall anywhere).
spot
    A perspective projection from the light's position along S, its field of view
    the cone's 2β (up to β = :data:`~softpipe.light.shadowmap.MAX_SPOT_MAP_CUTOFF`; a
    wider spot is treated as a point light), near and far fitted to the casters.
point
    A cube map: six perspective faces along ±x, ±y, ±z, each a little wider than
    90° so that PCF never reads across a seam
    (:func:`~softpipe.light.shadowmap.cube_face_half_extent`).

Two depth passes per map: the opaque casters, and the transparent ones (a
material with ``kt`` ≠ 0, transmitting kt; or with opacity < 1, transmitting
1 − opacity), whose nearest layer's depth and transmission color give the notes'
weighted shadow (§21): light behind glass is dimmed and tinted, not cut off.

The opaque pass is a depth-only draw (every color channel masked off, a constant
fragment shader: :func:`softpipe.pipeline.visibility.depth_only`): its visibility
pass's depth is the map and no fragment is shaded. A caster whose bounding box lies
outside a map's frustum is not drawn into it (nor transformed).

The depth bias is the depth pass's polygon offset
(:func:`softpipe.pipeline.setup.apply_polygon_offset`), set per light by
:class:`~softpipe.light.shadowmap.ShadowSettings`. The maps have ``cull="none"``: a
caster's faces turned away from the light are drawn too (a plane, an open mesh).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, cast

import numba
import numpy as np

from softpipe.light.material import Light, Lighting, LightingUniform
from softpipe.light.shadowmap import (
    CUBE_FACE_NAMES,
    MAX_SPOT_MAP_CUTOFF,
    SHADOW_MAP,
    SHADOW_RAY,
    ShadowSettings,
    ShadowUniform,
    cube_face_half_extent,
    light_visibility,
)
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.transforms import frustum, look_at, orthographic, transform_points
from softpipe.rays.queries import RayScene, transmission_of

__all__ = ["ShadowCaster", "ShadowMap", "ShadowMaps", "render_shadow_maps", "light_frusta", "casters_of",
           "CUBE_FACES"]

# Directions of a cube map's faces, with an up vector for each (any that is not parallel will do:
# a face is looked up by projecting with its own matrices, not by a face convention).
CUBE_FACES = (((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, -1)),
              ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0)))


@dataclass
class ShadowCaster:
    """A mesh that casts shadows, in world space.

    ``transmission`` is None for an opaque caster, else the RGB share of light it lets through.
    """

    name: str
    positions: np.ndarray   # float64 [N, 3], world space
    indices: np.ndarray     # int [M, 3]
    transmission: Optional[Tuple[float, float, float]] = None

    @property
    def bounds(self) -> np.ndarray:
        """float64 [2, 3]: the lowest and the highest corner of its vertices' box (a box of NaN
        when it has none, which no map's cull then leaves out)."""
        p = np.ascontiguousarray(self.positions, np.float64).reshape(-1, 3)
        if not len(p):
            return np.full((2, 3), np.nan)
        return _column_bounds(p)


def casters_of(objects) -> List[ShadowCaster]:
    """The shadow casters among scene objects (:class:`softpipe.scenes.scene.SceneObject`): those with
    ``cast_shadows`` true, each mesh in world space."""
    out = []
    for obj in objects:
        if not getattr(obj, "cast_shadows", True):
            continue
        mesh = obj.mesh
        for _, part in (mesh.by_material() if len(getattr(mesh, "materials", ()) or ()) > 1 else [(None, mesh)]):
            p = transform_points(obj.model, part.positions)
            out.append(ShadowCaster(obj.name, p,
                                    np.asarray(part.indices).reshape(-1, 3), transmission_of(part.material)))
    return out


# ------------------------------------------------------------------ fitting the light's frusta

@numba.njit(cache=True)
def _column_bounds(points: np.ndarray) -> np.ndarray:
    """[2, k]: each column's least and greatest value, as numpy's ``min(axis=0)``, ``max(axis=0)``
    give them (a NaN makes its column's both NaN), in one pass: numpy's reductions along axis 0 of
    an [N, 3] array took about a millisecond each, a few per map."""
    out = np.empty((2, points.shape[1]))
    for c in range(points.shape[1]):
        lo = hi = points[0, c]
        for n in range(1, points.shape[0]):
            v = points[n, c]
            if v < lo or v != v:
                lo = v if lo == lo else lo
            if v > hi or v != v:
                hi = v if hi == hi else hi
        out[0, c], out[1, c] = lo, hi
    return out


def _view_along(eye: np.ndarray, forward: np.ndarray, up) -> np.ndarray:
    """look_at(eye, eye + forward, up), also where eye is so large that eye + forward rounds to eye."""
    ahead = eye + forward
    if np.allclose(ahead - eye, forward, rtol=1e-6, atol=0.0):
        return look_at(eye, ahead, up)
    view = look_at((0.0, 0.0, 0.0), forward, up)       # the same rotation, then the eye's translation
    view[:3, 3] = -view[:3, :3] @ eye
    return view


def _basis_view(eye: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """A view matrix at ``eye`` looking along ``forward`` (any up not parallel to it)."""
    with np.errstate(over="ignore", under="ignore"):
        n = np.linalg.norm(forward)
    if not 1e-150 < n < 1e150:     # |forward|² under- or overflowed (a direction of 1e-300): scale it first
        forward = forward / np.max(np.abs(forward))
        n = np.linalg.norm(forward)
    forward = forward / n
    up = (0.0, 1.0, 0.0) if abs(forward[1]) < 0.9 else (1.0, 0.0, 0.0)
    return _view_along(eye, forward, up)


def _in_view(view: np.ndarray, points: np.ndarray) -> np.ndarray:
    return transform_points(view, points)


def _depth_range(depths: np.ndarray, near_floor: float) -> Tuple[float, float]:
    """(near, far) around positive distances ``depths``, with a margin; near ≥ near_floor·far."""
    far = float(depths.max()) * 1.01 + 1e-6
    near = max(float(depths.min()) * 0.99, far * near_floor)
    return near, far


def light_frusta(light: Light, settings: ShadowSettings, points: np.ndarray) -> List[Tuple[np.ndarray, np.ndarray]]:
    """The (view, projection) pairs of a light's shadow map(s), fitted to the casters' ``points``.

    One pair for a directional light and a spot of cutoff ≤ MAX_SPOT_MAP_CUTOFF, six
    (a cube map, in the order of :data:`CUBE_FACE_NAMES`) for a point light and a
    wider spot; none when no caster lies where the light can throw its shadow.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if not len(points):
        return []
    if light.kind == "directional":
        d = np.asarray(light.direction, np.float64)
        view = _basis_view(points.mean(axis=0), d)
        (x0, y0, z0), (x1, y1, z1) = _column_bounds(_in_view(view, points))
        # PCF reads r + 1 texels beyond a caster's edge: keep them inside the map
        pad_x = (x1 - x0) * (settings.pcf + 2) / settings.resolution + 1e-6
        pad_y = (y1 - y0) * (settings.pcf + 2) / settings.resolution + 1e-6
        nearest, farthest = -z1, -z0                    # the depths are −z
        span = float(farthest - nearest)
        near, far = float(nearest) - 0.01 * span - 1e-6, float(farthest) + 0.01 * span + 1e-6
        return [(view, orthographic(x0 - pad_x, x1 + pad_x, y0 - pad_y, y1 + pad_y, near, far))]
    eye = np.asarray(light.position, np.float64)
    if light.kind == "spot" and light.cutoff <= MAX_SPOT_MAP_CUTOFF:
        view = _basis_view(eye, np.asarray(light.spot_direction, np.float64))
        depth = -_in_view(view, points)[:, 2]
        depth = depth[depth > 0.0]
        if not len(depth):
            return []
        near, far = _depth_range(depth, 1e-4)
        # the cone's half angle β, widened by the PCF margin in texels
        t = np.tan(np.radians(light.cutoff)) / max(1.0 - 2.0 * (settings.pcf + 2) / settings.resolution, 0.25)
        return [(view, frustum(-t * near, t * near, -t * near, t * near, near, far))]
    a = cube_face_half_extent(settings.resolution, settings.pcf)
    offsets = points - eye
    distance = np.abs(offsets).max(axis=1)             # the major-axis distance, ≤ any face's depth
    if not np.any(distance > 0.0):
        return []
    near, far = _depth_range(distance[distance > 0.0] / a, 1e-4)
    far = max(far, float(np.linalg.norm(offsets, axis=1).max()) * 1.01)
    out = []
    for forward, up in CUBE_FACES:
        view = _view_along(eye, np.asarray(forward, np.float64), up)
        out.append((view, frustum(-a * near, a * near, -a * near, a * near, near, far)))
    return out


# ------------------------------------------------------------------ the depth passes

#: The opaque depth pass's color mask: no channel written, which with :func:`_depth_fragment` (a constant)
#: makes it a depth-only draw.
_DEPTH_ONLY = (False, False, False, False)


def _transmission_fragment(varyings, uniforms, frag):
    t = uniforms.transmission
    return (t[0], t[1], t[2], 1.0)


def _depth_fragment(varyings, uniforms, frag):
    return (0.0, 0.0, 0.0, 1.0)


@dataclass
class ShadowMap:
    """One rendered shadow map (one face of a cube map).

    Attributes
    ----------
    light_index : int
        Which light of the :class:`ShadowMaps` it belongs to.
    face : str
        "" for a single map, else the cube face ("+x", "-x", …).
    view, projection : float64 [4, 4]
        World → light eye, light eye → light clip.
    settings : ShadowSettings
    depth : float32 [res, res]
        The nearest opaque caster's window depth per texel (row 0 at the bottom), 1 where none.
    transparent_depth : float32 [res, res] or None
        The nearest transparent caster's depth, 1 where none (None: the map has no
        transparent caster).
    transmission : float32 [res, res, 3] or None
        That caster's transmission, 1 where none.
    seconds : float
        Time the two depth passes took.
    """

    light_index: int
    face: str
    view: np.ndarray
    projection: np.ndarray
    settings: ShadowSettings
    depth: np.ndarray
    transparent_depth: Optional[np.ndarray]
    transmission: Optional[np.ndarray]
    seconds: float = 0.0

    @property
    def matrix(self) -> np.ndarray:
        """World → the map's clip space."""
        return self.projection @ self.view

    def picture(self) -> np.ndarray:
        """The depth map as an 8-bit gray image [res, res] (top row first): near dark, far light,
        stretched over the depths present; no caster is white."""
        d = self.depth[::-1].astype(np.float64)
        covered = d < 1.0
        out = np.full(d.shape, 255, np.uint8)
        if covered.any():
            lo, hi = d[covered].min(), d[covered].max()
            out[covered] = np.round(20 + 200 * (d[covered] - lo) / max(hi - lo, 1e-12)).astype(np.uint8)
        return out


@numba.njit(cache=True)
def _outside_code(x, y, z, w):
    """A bit for each clip plane the vertex is outside of (x < −w, x > w, y …, z …)."""
    return ((x < -w) * 1 | (x > w) * 2 | (y < -w) * 4 | (y > w) * 8 | (z < -w) * 16 | (z > w) * 32)


@numba.njit(cache=True)
def _in_frustum(clip: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """The triangles not wholly outside one clip plane (the rest cannot reach the map): a cheap
    cull before assembly, which matters for a cube map, where each face sees a sixth of the scene.
    (Compiled: numpy's version made a dozen passes over the vertices; benchmarks/README.md.)"""
    codes = np.empty(clip.shape[0], np.int64)
    for v in range(clip.shape[0]):
        codes[v] = _outside_code(clip[v, 0], clip[v, 1], clip[v, 2], clip[v, 3])
    keep = np.empty(indices.shape[0], np.bool_)
    for t in range(indices.shape[0]):
        keep[t] = (codes[indices[t, 0]] & codes[indices[t, 1]] & codes[indices[t, 2]]) == 0
    return indices[keep]


def _outside_map(matrix: np.ndarray, bounds: np.ndarray) -> bool:
    """Is a caster's bounding box (``bounds``: [2, 3], its lowest and highest corner) wholly outside one
    clip plane of the map's ``matrix``? Then so is each of its vertices (a convex combination of the
    box's corners, and each plane's outside a half-space), and :func:`_in_frustum` would keep none
    of its triangles. "Outside" by a margin far above rounding (10⁻⁹ of the coordinates' size): a
    vertex within rounding of a plane is left to :func:`_in_frustum`."""
    lo, hi = bounds
    corners = np.array([(x, y, z, 1.0) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    with np.errstate(invalid="ignore", over="ignore"):
        clip = corners @ matrix.T
        margin = 1e-9 * float(np.max(np.abs(corners) @ np.abs(matrix).T))
        w = clip[:, 3]
        return bool(any((clip[:, a] - w > margin).all() or (-clip[:, a] - w > margin).all() for a in range(3)))


# ------------------------------------------------------------------ the opaque casters' triangle order

@numba.njit(cache=True, inline="never")
def _spread_bits(q):
    """The 10 low bits of ``q`` spread two zero bits apart (bit b to bit 3b), for a 3D Morton code."""
    q &= 0x3FF
    q = (q | (q << 16)) & 0x030000FF
    q = (q | (q << 8)) & 0x0300F00F
    q = (q | (q << 4)) & 0x030C30C3
    return (q | (q << 2)) & 0x09249249


@numba.njit(cache=True)
def _morton_codes(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Each triangle's 30-bit Morton code: its centroid's place in the casters' box, 10 bits an axis,
    interleaved. A triangle with a corner index out of range or a coordinate not finite gets the
    code of the box's lowest corner (the codes only order the triangles: any value is correct)."""
    n, count = indices.shape[0], positions.shape[0]
    centroids = np.zeros((n, 3))
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for t in range(n):
        a, b, c = indices[t, 0], indices[t, 1], indices[t, 2]
        if not (0 <= a < count and 0 <= b < count and 0 <= c < count):
            continue
        for k in range(3):
            v = (positions[a, k] + positions[b, k] + positions[c, k]) / 3.0
            centroids[t, k] = v
            if v == v and abs(v) < np.inf:
                lo[k] = min(lo[k], v)
                hi[k] = max(hi[k], v)
    codes = np.zeros(n, np.int64)
    for t in range(n):
        code = 0
        for k in range(3):
            q = 0.0
            if hi[k] > lo[k]:
                q = (centroids[t, k] - lo[k]) / (hi[k] - lo[k]) * 1023.0
            q = min(q, 1023.0) if q >= 0.0 else 0.0      # (NaN and below the box: 0)
            code |= _spread_bits(np.int64(q)) << k
        codes[t] = code
    return codes


#: The opaque casters' triangle orders (:func:`_in_coherent_order`), kept per index array, known by its
#: shape, type and a sample of its rows (:func:`_order_key`): made once per mesh, not every frame, also
#: for a mesh whose index arrays are made anew each frame (a part of a mesh of several materials,
#: ``Mesh.by_material``). At most _ORDERS_KEPT of them.
_ORDERS: Dict[tuple, np.ndarray] = {}
_ORDERS_KEPT = 16
#: How many rows, evenly spaced, :func:`_order_key` reads.
_KEY_ROWS = 64


def _order_key(indices: np.ndarray) -> tuple:
    """What a kept order is found by: the array's shape and type and _KEY_ROWS of its rows. Two arrays
    with the same key may differ elsewhere: the order found is then still a permutation of the rows,
    which draws the same map (only perhaps in a worse order), so a cheap key is enough."""
    step = max(1, len(indices) // _KEY_ROWS)
    return indices.shape, indices.dtype.str, np.ascontiguousarray(indices[::step][:_KEY_ROWS]).tobytes()


def _in_coherent_order(caster: ShadowCaster) -> ShadowCaster:
    """An opaque caster with its triangles in a spatially coherent order (the Morton order of their
    centroids, :func:`_morton_codes`); a transparent caster as it is.

    An opaque pass's map does not depend on the order of its triangles: with the depth test LESS
    and nothing but depth kept, each texel ends with the least depth any triangle's fragment has
    there (a minimum of float32 values, whatever the order; the polygon offset, the clipping and
    the fill rule are each triangle's own). A scanned mesh's triangles come in an order far from
    any map's (the bunny's tile lists from its lights jumped between triangles 0.59 and 0.49 of
    the time): its triangles set up all over their arrays cost the tile walk a cache miss each,
    or a copy of the setup into tile order (``tiles.gather_setup``) a map. In Morton order the
    lists run through neighbouring triangles (0.16 and 0.09): no copy, and the walk reads in
    sweeps (benchmarks/README.md, "Shadows, round 3"). The order is kept per index array
    (:func:`_order_key`), so a mesh is sorted once (7.7 ms for the bunny's 69,451 triangles); one kept
    for an array since changed is still a permutation of its rows, so the map is still the same,
    only perhaps drawn in a worse order.
    """
    indices = np.asarray(caster.indices)
    if caster.transmission is not None or not np.issubdtype(indices.dtype, np.integer) \
            or indices.ndim != 2 or indices.shape[1] != 3 or len(indices) < 2:
        return caster               # (a transparent pass keeps the order: its colors depend on it)
    key = _order_key(indices)
    order = _ORDERS.get(key)
    if order is None:
        positions = np.ascontiguousarray(caster.positions, np.float64).reshape(-1, 3)
        order = np.argsort(_morton_codes(positions, np.ascontiguousarray(indices, np.int64)), kind="stable")
        _ORDERS[key] = order
        for old in list(_ORDERS)[:-_ORDERS_KEPT]:     # the oldest go (list(): one step under the GIL)
            _ORDERS.pop(old, None)
    # (np.take: a quarter of the time of indices[order] on the bunny's int32 rows)
    return ShadowCaster(caster.name, caster.positions, np.take(indices, order, axis=0), caster.transmission)


def _render_map(casters: Sequence[ShadowCaster], view: np.ndarray, projection: np.ndarray,
                settings: ShadowSettings, light_index: int, face: str, target: Framebuffer,
                depth_out: np.ndarray) -> ShadowMap:
    """Draw one map into ``target`` (reused: cleared here), its depth into ``depth_out`` (window rows)."""
    start = time.perf_counter()
    res = settings.resolution
    matrix = projection @ view
    # Only the depth of a depth pass is read: its color (16 MB at 1024², four times the depth) is
    # neither cleared nor looked at.
    target.samples_depth.fill(1.0)
    opaque = target
    clear = Framebuffer(res, res).clear((1.0, 1.0, 1.0, 1.0)) if any(c.transmission for c in casters) else None
    for c in casters:
        if _outside_map(matrix, c.bounds):
            continue                    # nothing of it reaches this map: not even transformed
        clip = transform_points(matrix, c.positions, rows=4)
        indices = _in_frustum(clip, c.indices)
        if not len(indices):
            continue
        if c.transmission is None:
            # depth only (every color channel off, a constant shader): the draw's visibility pass is the
            # map, no fragment is shaded (softpipe.pipeline.visibility.depth_only)
            DrawCall(opaque, clip, indices, None, None, _depth_fragment, None, cull="none",
                     polygon_offset=settings.polygon_offset, color_mask=_DEPTH_ONLY).run()
        else:
            assert clear is not None    # made above: this caster lets light through
            DrawCall(clear, clip, indices, None, None, _transmission_fragment, {"transmission": c.transmission},
                     cull="none", polygon_offset=settings.polygon_offset).run()
    # a framebuffer's rows are an image's, top first; a map's are window rows, bottom first
    depth_out[...] = opaque.depth[::-1]
    if clear is None:
        transparent_depth = transmission = None
    else:
        transparent_depth = np.ascontiguousarray(clear.depth[::-1])
        transmission = np.ascontiguousarray(clear.color[::-1, :, :3])
    return ShadowMap(light_index, face, view, projection, settings, depth_out, transparent_depth,
                     transmission, time.perf_counter() - start)


@dataclass
class ShadowMaps:
    """The shadow maps of a set of lights, and the uniform a shader reads them by.

    Attributes
    ----------
    lights : tuple of Light
        The lights, in the order of the ``lighting`` uniform.
    maps : list of ShadowMap
        Every map; light j's are ``maps[first:first + count]`` with
        (first, count, method) = ``light_maps[j]``.
    light_maps : int64 [num_lights, 3]
    rays : RayScene or None
        The casters as a ray scene, for the lights with ``method="ray"``.
    """

    lights: Tuple[Light, ...]
    maps: List[ShadowMap] = field(default_factory=list)
    light_maps: np.ndarray = None  # type: ignore[assignment, unused-ignore]  # always given; a default as maps has one
    rays: Optional[RayScene] = None
    _packed: Optional[tuple] = field(default=None, repr=False, compare=False)
    _depth: Optional[np.ndarray] = field(default=None, repr=False, compare=False)

    @property
    def seconds(self) -> Dict[str, float]:
        """Time per map, keyed by light name (and cube face)."""
        return {f"{self.lights[m.light_index].name}{' ' + m.face if m.face else ''}": m.seconds
                for m in self.maps}

    def uniform(self, view_matrix: np.ndarray) -> ShadowUniform:
        """The maps packed for shaders working in the eye space of ``view_matrix`` (world → eye).

        The texels are packed once and shared by every uniform made (only the matrices
        depend on the view).
        """
        # None without ray lights: a shader then carries no ray scene (numba counts every array it holds)
        rays = self.rays.uniform(view_matrix) if self.rays is not None else None
        if not self.maps and rays is not None:
            # rays only: no map arrays either, so no map lookup is compiled into the shaders
            return ShadowUniform(self.light_maps.copy(), None, None, None, None, None, rays)
        if self._packed is None:
            self._packed = self._pack()
        maps, depth, transparent_depth, transmission = self._packed
        inverse_view = np.linalg.inv(np.asarray(view_matrix, np.float64))
        matrices = np.array([m.matrix @ inverse_view for m in self.maps], np.float64).reshape(-1, 4, 4)
        return ShadowUniform(self.light_maps.copy(), maps, matrices, depth, transparent_depth, transmission, rays)

    def _pack(self):
        """(maps, depth, transparent_depth, transmission) of :class:`~softpipe.light.shadowmap.ShadowUniform`."""
        rows, offset, clear_offset = [], 0, 0
        clear = [m for m in self.maps if m.transparent_depth is not None]
        for m in self.maps:
            height, width = m.depth.shape
            rows.append([offset, width, height, m.settings.pcf, -1 if m.transparent_depth is None else clear_offset])
            offset += m.depth.size
            if m.transparent_depth is not None:
                clear_offset += m.depth.size
        if self._depth is not None and self._depth.size == offset:   # the maps were drawn into it
            depth = self._depth
        else:
            depth = np.concatenate([m.depth.ravel() for m in self.maps]) if self.maps else np.zeros(0, np.float32)
        if clear:
            transparent_depth = np.concatenate([m.transparent_depth.ravel() for m in clear])
            transmission = np.concatenate([m.transmission.reshape(-1, 3) for m in clear])
        else:
            transparent_depth, transmission = np.zeros(0, np.float32), np.zeros((0, 3), np.float32)
        return (np.array(rows, np.int64).reshape(-1, 5), np.ascontiguousarray(depth, np.float32),
                np.ascontiguousarray(transparent_depth, np.float32), np.ascontiguousarray(transmission, np.float32))

    def lighting_uniform(self, lighting: Lighting, view_matrix: np.ndarray) -> LightingUniform:
        """``lighting.uniform(view_matrix)`` with these shadow maps."""
        if tuple(lighting.lights) != tuple(self.lights):
            raise ValueError("these shadow maps were made for other lights than the lighting's")
        return lighting.uniform(view_matrix)._replace(shadows=self.uniform(view_matrix))

    def visibility(self, light_index: int, point: Sequence[float]) -> Tuple[float, float, float]:
        """V_j of light ``light_index`` at a world-space point, as the shaders compute it (RGB)."""
        lighting = self.lighting_uniform(Lighting(self.lights), np.eye(4))   # eye space = world space
        p = tuple(float(v) for v in point)
        r, g, b = light_visibility(lighting, light_index, p)
        return (r, g, b)


#: The most memory all of a scene's shadow maps may take together (bytes); each light's
#: resolution is capped on its own (MAX_SHADOW_RESOLUTION), this caps their sum (300 point
#: lights of 1024² cube maps would take 7 GiB). ``render_shadow_maps(..., max_bytes=...)``
#: raises or lowers it for one call.
MAX_SHADOW_MAP_BYTES = 2 << 30
#: Bytes a map keeps per texel: its float32 depth; with transparent casters also their
#: layer's float32 depth and RGB transmission, kept per map and packed once more for shaders.
SHADOW_BYTES_PER_TEXEL, TRANSPARENT_BYTES_PER_TEXEL = 4, 2 * 16


def _check_total(lighting: Lighting, planned: list, transparent: bool, max_bytes: Optional[int]) -> None:
    """Refuse maps that together need more than ``max_bytes`` (None: MAX_SHADOW_MAP_BYTES), before any is made."""
    limit = MAX_SHADOW_MAP_BYTES if max_bytes is None else max_bytes
    per_texel = SHADOW_BYTES_PER_TEXEL + (TRANSPARENT_BYTES_PER_TEXEL if transparent else 0)
    texels: Dict[int, int] = {}
    for j, *_ in planned:
        texels[j] = texels.get(j, 0) + lighting.lights[j].shadows.resolution ** 2
    need = sum(texels.values()) * per_texel
    if need <= limit:
        return
    j = max(texels, key=lambda k: (texels[k], -k))
    light = lighting.lights[j]
    maps = sum(1 for k, *_ in planned if k == j)
    res = cast(ShadowSettings, light.shadows).resolution      # a planned light casts shadows
    raise ValueError(
        f"shadow maps: {len(texels)} light(s) ask for {len(planned)} maps, about {need / 2**30:.1f} GiB together "
        f"({per_texel} bytes a texel), more than the limit of {limit / 2**30:.1f} GiB; the largest is light {j} "
        f"({light.name}): {maps} map(s) of {res}×{res}. Lower the lights' shadow resolution "
        "(ShadowSettings.resolution; 'resolution' in a scene file's shadows table), let fewer lights cast "
        "shadows, or raise the limit (render_shadow_maps(..., max_bytes=...), "
        "softpipe.scenes.shadow_pass.MAX_SHADOW_MAP_BYTES)")


#: A point or spot light's shadow map tells its casters' depths apart up to this many times
#: their size away (float32 depths over the fitted near…far); farther, it is refused.
MAX_LIGHT_DISTANCE_RATIO = 1e6


def _check_map_light(j: int, light: Light, points: np.ndarray) -> None:
    """Refuse a light whose shadow map could not be made or would say nothing, naming the light and the value."""
    if light.kind == "directional" or not len(points):
        return
    label = f"light {j} ({light.name})"
    if light.kind == "spot" and light.cutoff < 1e-6:        # its map's frustum would have no width
        raise ValueError(f"{label}: a spot with cutoff {light.cutoff!r}° lights nothing, so it has no shadow map; "
                         "give it a cutoff in (0, 90] degrees (at least 1e-6), or no shadows")
    eye = np.asarray(light.position, np.float64)
    lo, hi = _column_bounds(np.ascontiguousarray(points, np.float64))
    size = float(np.linalg.norm(hi - lo))
    distance = float(np.abs(points - eye).max())
    if distance > MAX_LIGHT_DISTANCE_RATIO * size:
        where = ", ".join(f"{v:g}" for v in eye)
        raise ValueError(f"{label} at position ({where}) is {distance:.3g} from the shadow casters, which are "
                         f"{size:.3g} across: its shadow map cannot tell their depths apart from farther than "
                         f"{MAX_LIGHT_DISTANCE_RATIO:g} times their size. Move the light nearer, make it a "
                         "directional light (a far sun), or turn its shadows off")


def render_shadow_maps(objects, lighting: Lighting, *, max_bytes: Optional[int] = None) -> ShadowMaps:
    """Draw the shadow maps of every light of ``lighting`` whose ``shadows`` is set.

    Parameters
    ----------
    objects : list of SceneObject or ShadowCaster
        The scene's objects (those with ``cast_shadows`` false are left out), or
        casters made by :func:`casters_of`.
    lighting : Lighting
    max_bytes : int, optional
        The most memory the maps may take together (default :data:`MAX_SHADOW_MAP_BYTES`),
        checked before any map is made.

    Returns
    -------
    ShadowMaps
    """
    objects = list(objects)
    given_casters = all(isinstance(o, ShadowCaster) for o in objects)
    casters = objects if given_casters else casters_of(objects)
    points = np.concatenate([c.positions for c in casters]) if casters else np.zeros((0, 3))
    out = ShadowMaps(tuple(lighting.lights), [], np.zeros((len(lighting.lights), 3), np.int64))
    planned: list = []                              # (light index, view, projection, face)
    for j, light in enumerate(lighting.lights):
        if not isinstance(light.shadows, ShadowSettings):   # None (True became the settings)
            continue
        if light.shadows.method == "ray":
            if given_casters:
                raise ValueError(f"light {j} ({light.name}) takes its shadows from rays, which need the scene's "
                                 "objects (SceneObjects with meshes), not ShadowCasters")
            if out.rays is None:
                out.rays = RayScene([o for o in objects if getattr(o, "cast_shadows", True)])
            out.light_maps[j] = (0, 0, SHADOW_RAY)
            continue
        _check_map_light(j, light, points)
        frusta = light_frusta(light, light.shadows, points)
        out.light_maps[j] = (len(planned), len(frusta), SHADOW_MAP)
        names = CUBE_FACE_NAMES if len(frusta) == 6 else ("",)
        planned.extend((j, view, projection, face) for (view, projection), face in zip(frusta, names))
    _check_total(lighting, planned, any(c.transmission for c in casters), max_bytes)
    if planned:     # the opaque casters' triangles in an order every map's tiles read in sweeps, once for all maps
        casters = [_in_coherent_order(c) for c in casters]
    # every map's depth goes straight into the one array the shaders read (ShadowMaps.uniform)
    sizes = [lighting.lights[j].shadows.resolution ** 2 for j, *_ in planned]
    depth = np.empty(sum(sizes), np.float32)
    targets: Dict[int, Framebuffer] = {}           # one framebuffer per resolution, cleared for each map
    offset = 0
    try:
        for (j, view, projection, face), size in zip(planned, sizes):
            settings = lighting.lights[j].shadows
            res = settings.resolution
            if res not in targets:                  # (setdefault would make a new one every time)
                targets[res] = _take_target(res)
            out.maps.append(_render_map(casters, view, projection, settings, j, face, targets[res],
                                        depth[offset:offset + size].reshape(res, res)))
            offset += size
    finally:
        for target in targets.values():
            _keep_target(target)
    out._depth = depth
    return out


#: Depth-pass targets kept between calls, one per resolution: a new 1024² framebuffer (20 MB)
#: cost its page faults and a clear in every frame that makes maps (benchmarks/README.md). At most
#: _TARGETS_KEPT of them, none above _TARGET_KEPT_MAX_RES² (an 8192² one is 1.3 GB).
_TARGETS: Dict[int, Framebuffer] = {}
_TARGETS_KEPT, _TARGET_KEPT_MAX_RES = 2, 2048


def _keep_target(target: Framebuffer) -> None:
    if target.width > _TARGET_KEPT_MAX_RES:
        return
    _TARGETS[target.width] = target
    while len(_TARGETS) > _TARGETS_KEPT:          # the oldest resolution goes
        _TARGETS.pop(next(iter(_TARGETS)), None)


def _take_target(res: int) -> Framebuffer:
    """A res × res framebuffer for depth passes: a kept one (each used by one call at a time) or a new one."""
    try:
        return _TARGETS.pop(res)         # atomic under the GIL: two calls at once get two
    except KeyError:
        return Framebuffer(res, res)
