"""A Whitted ray tracer of the same scene the rasterizer draws (FORMULAS §11, §16–§19, §21–§23).

The rasterizer asks, per triangle, which pixels it covers; a ray tracer asks, per
pixel, which triangle its ray meets first. Given the same :class:`~softpipe.scenes.scene.Scene`
— objects, camera, materials, lights — :func:`raytrace_scene` makes the picture the
second way, so that the two can be put side by side and any pixel asked why:

- :func:`raytrace_scene`: per pixel a primary ray (FORMULAS §23) — or one per sample of a
  sample pattern, the pixel their mean (§24), or adaptively more where neighbours differ —, the local color by
  the *same* functions of :mod:`softpipe.light.lighting` the rasterizer's shaders call,
  V_j by shadow rays (:func:`softpipe.rays.queries.ray_visibility`), and the ray tree
  of reflected and refracted rays (§16–§19, §22) with the falloff of §13 and §15, a
  conductor's (material ``k`` ≠ 0) reflected ray weighted by kr·F_R(N·V) per channel (§30);
- :func:`raytrace_samples`: every sample's color before the pixel filter;
- :func:`ray_tree`: one pixel's tree as data, printed — the ray tracer's pixel history;
- :class:`RayTracer`, :func:`tracer_uniform`, :func:`trace_ray`: the tracer as one
  uniform, so that a rasterized fragment can be a tree's root (the programs
  ``mirror``, ``glass`` and ``hall`` use it: GPUs' ray queries from a fragment shader).

Why it is shaped so: it reuses the rasterizer's lighting functions and the scene
model unchanged, so where both see the same surface the two agree to the rounding
of the snapped vertices; what differs is only what a rasterizer cannot do.

docs/raytracing.md walks through it step by step (the primary ray, the local color,
the ray tree, Fresnel and total internal reflection, falloff in a medium, what is not
there yet); docs/hall.md has Hall's terms, docs/environment.md the rays from a shader.
"""
from __future__ import annotations

import time
from collections import namedtuple
from dataclasses import dataclass
from typing import List, Optional

import numpy as np
from numba import njit

from softpipe.core.parallel import in_bands
from softpipe.core.validation import checked, color
from softpipe.language.glsl import dot, reflect, refract, scale
from softpipe.light.lighting import (
    BLINN_PHONG,
    PHONG,
    cook_torrance_lighting,
    fresnel_directions,
    hall_local,
    opengl_lighting,
    two_sided_lighting,
)
from softpipe.light.material import LightingUniform, MaterialUniform, pack_lights
from softpipe.light.shadowmap import SHADOW_RAY, ShadowUniform
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.sampling import CENTER, SamplePattern, pattern_named
from softpipe.rays.bvh import closest_hit
from softpipe.rays.queries import RayScene, direction_to_world, hit_normal, medium_falloff, point_to_world
from softpipe.tracers.lobes import conductor_fresnel

__all__ = ["raytrace_scene", "raytrace_samples", "ray_tree", "primary_visibility", "tracer_uniform", "trace_ray",
           "RayTracer", "RayTree", "RayNode", "PROGRAM_CODES", "RAY_KINDS", "MAX_DEPTH_LIMIT",
           "ADAPTIVE_THRESHOLD", "ADAPTIVE_DEPTH", "MAX_ADAPTIVE_DEPTH"]

#: How each program's local color is computed in the ray tracer (the others: as "phong", with a note).
PROGRAM_CODES = {"phong": 0, "gouraud": 0, "flat": 0, "textured": 0, "phong_phong_specular": 1,
                 "gouraud_phong_specular": 1, "flat_phong_specular": 1, "hall": 2, "cook_torrance": 3,
                 "two_sided": 4, "mirror": 5, "glass": 6}
#: The kinds of ray in a tree.
RAY_KINDS = ("primary", "reflected", "refracted", "total internal reflection")
#: The deepest tree allowed (2^(depth+1) rays at most per pixel).
MAX_DEPTH_LIMIT = 12
#: Adaptive supersampling (:func:`raytrace_scene`, ``adaptive=True``): a cell is split in four when its
#: sample differs from a neighbour's by this much or more in some channel (linear color, 0…1) …
ADAPTIVE_THRESHOLD = 0.1
#: … down to this many levels (2: at most a 4×4 grid of cells, 16 rays, in a pixel) …
ADAPTIVE_DEPTH = 2
#: … and at most this many (3: an 8×8 grid, 64 rays = the sample patterns' MAX_SAMPLES).
MAX_ADAPTIVE_DEPTH = 3
_MATERIAL_COLUMNS = 35          # MaterialUniform's 23 numbers, then T (RGB), Glassner's form (0/1) and its a,
#                                 a conductor (1: k ≠ 0), its η (RGB) and k (RGB)
_RECORD_COLUMNS = 21


def _pack_material(m) -> np.ndarray:
    return np.array([*m.ke, *m.ka, *m.kd, *m.ks, m.shininess, *m.kr, *m.kt, m.transmission_shininess,
                     m.ior, m.opacity, m.roughness, *m.transmittance, float(m.falloff == "glassner"),
                     m.falloff_a, float(max(m.k) > 0.0), *m.conductor_eta, *m.k], np.float64)


@njit(cache=True, forceinline=True)
def _falloff(rows, k, d):
    """The falloff over distance d inside object k's material (§15): T^d, or Glassner's 1/(1 + a·d)."""
    r = rows[k]
    return medium_falloff((r[23], r[24], r[25]), r[26] != 0.0, r[27], d)


@njit(cache=True, forceinline=True)
def _material(rows, k):
    r = rows[k]
    return MaterialUniform((r[0], r[1], r[2]), (r[3], r[4], r[5]), (r[6], r[7], r[8]), (r[9], r[10], r[11]), r[12],
                           (r[13], r[14], r[15]), (r[16], r[17], r[18]), r[19], r[20], r[21], r[22])


@njit(cache=True)
def _local_color(code, P, N, V, material, lighting, entering):
    """The object's program's lighting at P (§10, §13, §26), every light's V_j from a shadow ray.

    ``entering``: the ray met a front face (the viewer outside, in air); a back face is seen from
    inside the object, where Hall's transmitted highlight takes η = 1/ior (FORMULAS §14)."""
    if code == 2:
        return hall_local(P, N, V, material, lighting, material.ior if entering else 1.0 / material.ior)
    if code == 3:
        return cook_torrance_lighting(P, N, V, material, lighting)
    if code == 4:
        return two_sided_lighting(P, N, V, material, lighting)
    # 0, mirror (5) and glass (6): Blinn-Phong; 1: Phong's (R·V)ⁿ. One call: opengl_lighting is inlined, and
    # numba's pedantic check warned about two inlined copies of its shadow lookups in one function
    return opengl_lighting(P, N, V, material, lighting, PHONG if code == 1 else BLINN_PHONG)


@njit(cache=True)
def _unit(v):
    n = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v[0] / n, v[1] / n, v[2] / n


@njit(cache=True)
def _branches(code, m, N, V, d, entering):
    """The two rays a hit spawns: (R, kind, weight factor), (T, kind, weight factor); §16–§20, §13.

    ``glass`` (6): Fresnel (§20) splits the light, F_R to R and (1 − F_R)·kt to T,
    between air (n = 1) and the material, as the rasterized ``glass`` program; on
    total internal reflection (§19) all of it goes to R. ``mirror`` (5): kr to R,
    nothing refracted, as the ``mirror`` program. Every other program: Hall's kr
    to R and kt to T (§13), T's weight going to R on total internal reflection.
    """
    R = reflect(d, N)                                              # §16
    if code == 6:
        n1, n2 = (1.0, m.ior) if entering else (m.ior, 1.0)
        _, T, F = fresnel_directions(N, V, n1, n2)                 # §18, §19, §20
        if T[0] == 0.0 and T[1] == 0.0 and T[2] == 0.0:
            return R, 3, (1.0, 1.0, 1.0), T, 2, (0.0, 0.0, 0.0)
        return R, 1, (F, F, F), T, 2, scale(m.kt, 1.0 - F)
    if code == 5:
        return R, 1, m.kr, R, 2, (0.0, 0.0, 0.0)
    eta = 1.0 / m.ior if entering else m.ior                       # η = η_i/η_t, air outside
    T = refract(d, N, eta)                                         # §17, §18
    if T[0] == 0.0 and T[1] == 0.0 and T[2] == 0.0:                # §19: all of it reflected
        return R, 1, m.kr, R, 3, m.kt
    return R, 1, m.kr, T, 2, m.kt


@njit(cache=True)
def _conductor_kr(row, kr, N, V):
    """A conductor's reflected weight: kr times its exact Fresnel reflectance F_R(N·V) per channel (FORMULAS §30).

    The metal's colour at normal incidence, white toward grazing; ``row`` the packed material (its η at
    columns 29–31, k at 32–34). The path tracer's mirror lobe weighs a conductor the same way.
    """
    c = N[0] * V[0] + N[1] * V[1] + N[2] * V[2]
    return (kr[0] * conductor_fresnel(c, row[29], row[32]), kr[1] * conductor_fresnel(c, row[30], row[33]),
            kr[2] * conductor_fresnel(c, row[31], row[34]))


@njit(cache=True)
def _trace_tree(tracer, origin, direction, depth0, kind0, weight, far, record):
    """Σ weight × local over the tree of one ray (world space), walked with an explicit stack.

    ``depth0`` 0 is a primary ray (it passes the faces its object culls, to ``far``);
    a shader's ray starts at depth 1. The tree goes into ``record`` if it has rows.
    """
    scene, materials, programs = tracer.scene, tracer.materials, tracer.programs
    air, lighting, max_depth = tracer.air, tracer.lighting, tracer.max_depth
    cap = 1 << (max_depth + 1)
    so = np.empty((cap, 3))
    sd = np.empty((cap, 3))
    sw = np.empty((cap, 3))
    s_depth = np.empty(cap, np.int64)
    s_kind = np.empty(cap, np.int64)
    s_parent = np.empty(cap, np.int64)
    so[0, 0], so[0, 1], so[0, 2] = origin[0], origin[1], origin[2]
    sd[0, 0], sd[0, 1], sd[0, 2] = direction[0], direction[1], direction[2]
    sw[0, 0], sw[0, 1], sw[0, 2] = weight[0], weight[1], weight[2]
    s_depth[0], s_kind[0], s_parent[0] = depth0, kind0, -1
    top = 1
    red, green, blue = 0.0, 0.0, 0.0
    eps = scene.epsilon
    n_recorded = 0
    while top > 0:
        top -= 1
        o = (so[top, 0], so[top, 1], so[top, 2])
        d = (sd[top, 0], sd[top, 1], sd[top, 2])
        w = (sw[top, 0], sw[top, 1], sw[top, 2])
        depth, kind, parent = s_depth[top], s_kind[top], s_parent[top]
        if depth == 0:
            tri, t, b1, b2 = _primary_hit(scene, tracer.cull, o, d, far)
        else:
            tri, t, b1, b2 = closest_hit(scene.bvh, o, d, eps, np.inf)
        falloff = (1.0, 1.0, 1.0)
        if tri < 0:
            local = (tracer.background[0], tracer.background[1], tracer.background[2])
        else:
            obj = scene.triangle_object[tri]
            P = (o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2])
            N = hit_normal(scene, tri, b1, b2)
            # front or back by the triangle's winding, as the rasterizer's gl_FrontFacing: a back face is
            # lit with its normal reversed (facing_normal), and a ray meeting a front face enters the object
            n = scene.face_normals[tri]
            entering = n[0] * d[0] + n[1] * d[1] + n[2] * d[2] < 0.0
            if not entering:
                N = scale(N, -1.0)
            if depth > 0:          # §13's T^d, §15: inside the object it leaves here, else through air
                if entering:
                    falloff = medium_falloff((air[0], air[1], air[2]), False, 0.0, t)
                else:
                    falloff = _falloff(materials, obj, t)
                w = (w[0] * falloff[0], w[1] * falloff[1], w[2] * falloff[2])
            V = (-d[0], -d[1], -d[2])
            m = _material(materials, obj)
            code = programs[obj]
            local = _local_color(code, P, N, V, m, lighting, entering)
        red += w[0] * local[0]
        green += w[1] * local[1]
        blue += w[2] * local[2]
        me = n_recorded
        if n_recorded < record.shape[0]:
            row = record[n_recorded]
            row[0], row[1], row[2] = parent, kind, depth
            row[3], row[4], row[5], row[6], row[7], row[8] = o[0], o[1], o[2], d[0], d[1], d[2]
            row[9] = t if tri >= 0 else np.inf
            row[10] = tri
            row[11] = scene.triangle_object[tri] if tri >= 0 else -1
            row[12], row[13], row[14] = local[0], local[1], local[2]
            row[15], row[16], row[17] = w[0], w[1], w[2]
            row[18], row[19], row[20] = falloff[0], falloff[1], falloff[2]
            n_recorded += 1
        if tri < 0 or depth >= max_depth:
            continue
        R, r_kind, kr, T, t_kind, kt = _branches(code, m, N, V, d, entering)
        if code != 6 and materials[obj, 28] > 0.0:
            kr = _conductor_kr(materials[obj], kr, N, V)
        for branch in range(2):
            nd, nk, k = (R, r_kind, kr) if branch == 0 else (T, t_kind, kt)
            nw = (w[0] * k[0], w[1] * k[1], w[2] * k[2])
            strongest = max(nw[0], nw[1], nw[2])
            if strongest <= 0.0 or strongest < tracer.min_weight or top >= cap:     # a ray that counts for nothing
                continue
            nd = _unit(nd)
            so[top, 0], so[top, 1], so[top, 2] = P[0], P[1], P[2]
            sd[top, 0], sd[top, 1], sd[top, 2] = nd[0], nd[1], nd[2]
            sw[top, 0], sw[top, 1], sw[top, 2] = nw[0], nw[1], nw[2]
            s_depth[top], s_kind[top], s_parent[top] = depth + 1, nk, me
            top += 1
    return red, green, blue, n_recorded


@njit(cache=True)
def trace_ray(tracer, origin, direction, weight):
    """What a ray from a shader brings back: Σ weight × local over its tree, RGB (:class:`RayTracer`).

    The ray starts at ``origin`` (eye space, on a surface) along ``direction`` (eye
    space), ε off the surface, as the ray tracer's secondary rays (depth 1: its
    reflections and refractions go on to the tracer's ``max_depth``); ``weight`` (RGB)
    is what it counts for in the pixel — the ray tracer's k_r, F_R, (1 − F_R)·k_t —
    so its branches stop at the same ``min_weight``. The rasterized fragment is the
    tree's root, so a pixel of a mirror drawn with a tracer is the ray tracer's pixel.
    """
    if max(weight[0], weight[1], weight[2]) < tracer.min_weight or tracer.max_depth < 1:
        return 0.0, 0.0, 0.0
    o = point_to_world(tracer.to_world, origin)
    d = _unit(direction_to_world(tracer.to_world, direction))
    r, g, b, _ = _trace_tree(tracer, o, d, 1, 1, weight, np.inf, np.empty((0, _RECORD_COLUMNS)))
    return r, g, b


@njit(cache=True)
def _primary_hit(scene, cull, o, d, far):
    """The primary ray's nearest hit within the view volume that the rasterizer would have drawn: a face its
    object culls (``cull``: 1 back faces, 2 front faces) is passed through, as culling removed it."""
    normals = scene.face_normals
    t_min = 0.0
    for _ in range(64):
        tri, t, b1, b2 = closest_hit(scene.bvh, o, d, t_min, far)
        if tri < 0:
            return tri, t, b1, b2
        mode = cull[scene.triangle_object[tri]]
        front = dot((normals[tri, 0], normals[tri, 1], normals[tri, 2]), d) < 0.0
        if mode == 0 or (mode == 1 and front) or (mode == 2 and not front):
            return tri, t, b1, b2
        t_min = t                     # the open interval skips this face, and nothing else at t
    return -1, far, 0.0, 0.0


@njit(cache=True)
def _trace_sample(tracer, unproject, px, py, width, height, no_record):
    """The color a primary ray through image point (px, py) brings back: Σ weight × local over its tree."""
    origin, direction, far = _primary_ray(unproject, px, py, width, height)
    r, g, b, _ = _trace_tree(tracer, origin, direction, 0, 0, (1.0, 1.0, 1.0), far, no_record)
    return r, g, b


@njit(cache=True, nogil=True)
def _trace_rows(lo, hi, width, height, unproject, tracer, offsets, out):
    """One ray per sample (``offsets`` [S, 2]: x right, y down from the pixel's top-left corner); the pixel is
    their mean, summed in the pattern's order (the box filter, §24)."""
    count = offsets.shape[0]
    no_record = np.empty((0, _RECORD_COLUMNS))
    for j in range(lo, hi):                 # image rows, top first
        for i in range(width):
            red, green, blue = 0.0, 0.0, 0.0
            for s in range(count):
                r, g, b = _trace_sample(tracer, unproject, i + offsets[s, 0], j + offsets[s, 1], width, height,
                                        no_record)
                red += r
                green += g
                blue += b
            out[j, i, 0], out[j, i, 1], out[j, i, 2], out[j, i, 3] = red / count, green / count, blue / count, 1.0


@njit(cache=True, nogil=True)
def _sample_rows(lo, hi, width, height, unproject, tracer, offsets, out):
    """Every sample's color, unfiltered: ``out`` [H, W, S, 3]."""
    no_record = np.empty((0, _RECORD_COLUMNS))
    for j in range(lo, hi):
        for i in range(width):
            for s in range(offsets.shape[0]):
                r, g, b = _trace_sample(tracer, unproject, i + offsets[s, 0], j + offsets[s, 1], width, height,
                                        no_record)
                out[j, i, s, 0], out[j, i, s, 1], out[j, i, s, 2] = r, g, b


@njit(cache=True)
def _differs(a, b, threshold):
    """Whether two colors differ by ``threshold`` or more in some channel (a NaN counts as a difference)."""
    for c in range(3):
        if not abs(a[c] - b[c]) < threshold:
            return True
    return False


@njit(cache=True, nogil=True)
def _adaptive_rows(lo, hi, width, height, unproject, tracer, centres, threshold, depth, out, rays):
    """Adaptive supersampling (docs/raytracing.md): from the pixel centres (``centres`` [H, W, 3], traced
    first), split a cell in four where its sample differs from a neighbour's by ``threshold`` or more — a
    pixel's neighbours are the four pixels beside it, a smaller cell's its three siblings — down to ``depth``
    levels, each new cell traced at its centre. The pixel is the mean over the 2^depth × 2^depth grid of the
    finest cells, each taking the sample of the smallest traced cell that holds it (a box filter in which
    every sample counts for its cell's area), summed in the order of the sample pattern ``grid`` (2^depth)."""
    side = 1 << depth
    no_record = np.empty((0, _RECORD_COLUMNS))
    values = np.empty((depth + 1, side, side, 3))
    traced = np.zeros((depth + 1, side, side), np.bool_)
    split = np.zeros((depth + 1, side, side), np.bool_)
    for j in range(lo, hi):
        for i in range(width):
            c = centres[j, i]
            whole = depth == 0 or threshold > 0.0
            if whole:
                for dj, di in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                    jj, ii = j + dj, i + di
                    if 0 <= jj < height and 0 <= ii < width and _differs(c, centres[jj, ii], threshold):
                        whole = depth == 0
                        break
            rays[j, i] = 1
            if whole:                        # the centre alone: the one-sample pixel, unchanged
                out[j, i, 0], out[j, i, 1], out[j, i, 2], out[j, i, 3] = c[0], c[1], c[2], 1.0
                continue
            traced[...] = False
            split[...] = False
            values[0, 0, 0, 0], values[0, 0, 0, 1], values[0, 0, 0, 2] = c[0], c[1], c[2]
            traced[0, 0, 0] = split[0, 0, 0] = True
            for k in range(1, depth + 1):
                n = 1 << k
                for b in range(n):           # rows of cells, top first
                    for a in range(n):
                        if not split[k - 1, b >> 1, a >> 1]:
                            continue
                        r, g, bl = _trace_sample(tracer, unproject, i + (a + 0.5) / n, j + (b + 0.5) / n,
                                                 width, height, no_record)
                        values[k, b, a, 0], values[k, b, a, 1], values[k, b, a, 2] = r, g, bl
                        traced[k, b, a] = True
                        rays[j, i] += 1
                if k == depth:
                    break
                for b in range(n):
                    for a in range(n):
                        if not traced[k, b, a]:
                            continue
                        b0, a0 = b & ~1, a & ~1
                        for sb in range(b0, b0 + 2):
                            for sa in range(a0, a0 + 2):
                                if (sb != b or sa != a) and _differs(values[k, b, a], values[k, sb, sa],
                                                                     threshold):
                                    split[k, b, a] = True
            red, green, blue = 0.0, 0.0, 0.0
            for b in range(side):
                for a in range(side):
                    k = depth
                    while not traced[k, b >> (depth - k), a >> (depth - k)]:
                        k -= 1
                    v = values[k, b >> (depth - k), a >> (depth - k)]
                    red += v[0]
                    green += v[1]
                    blue += v[2]
            count = side * side
            out[j, i, 0], out[j, i, 1], out[j, i, 2], out[j, i, 3] = red / count, green / count, blue / count, 1.0


@njit(cache=True, nogil=True)
def _centre_rows(lo, hi, width, height, unproject, tracer, out):
    no_record = np.empty((0, _RECORD_COLUMNS))
    for j in range(lo, hi):
        for i in range(width):
            out[j, i, 0], out[j, i, 1], out[j, i, 2] = _trace_sample(tracer, unproject, i + 0.5, j + 0.5,
                                                                     width, height, no_record)


@njit(cache=True)
def _primary_ray(unproject, px, py, width, height):
    """The ray through image point (px, py) — x right, y down from the image's top-left corner; a pixel's centre
    is (i + ½, j + ½): (origin on the near plane, unit direction, the distance to the far plane) — the
    rasterizer's view volume, so both see the same surfaces (§23, §24)."""
    x = 2.0 * px / width - 1.0
    y = 1.0 - 2.0 * py / height
    near = _unproject(unproject, x, y, -1.0)
    far = _unproject(unproject, x, y, 1.0)
    d = (far[0] - near[0], far[1] - near[1], far[2] - near[2])
    return near, _unit(d), np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


@njit(cache=True)
def _unproject(M, x, y, z):
    v = np.empty(4)
    for r in range(4):
        v[r] = M[r, 0] * x + M[r, 1] * y + M[r, 2] * z + M[r, 3]
    return v[0] / v[3], v[1] / v[3], v[2] / v[3]


RayTracer = namedtuple("RayTracer", ["scene", "lighting", "materials", "programs", "cull", "background", "air",
                                     "max_depth", "min_weight", "to_world"])
RayTracer.__doc__ = """The ray tracer as a uniform: everything a ray needs to bring back a color (:func:`tracer_uniform`).

``scene`` (:class:`~softpipe.rays.queries.RaySceneUniform`, world space), ``lighting``
(:class:`~softpipe.light.material.LightingUniform` in world space, every light with shadow
rays), ``materials`` float64 [objects, 28] (MaterialUniform's numbers, then the
medium's T, Glassner's flag and a), ``programs`` int64 [objects] (:data:`PROGRAM_CODES`),
``cull`` int64 [objects] (0 none, 1 back, 2 front), ``background`` float64 [3], ``air``
float64 [3] (T of air, §15), ``max_depth``, ``min_weight`` (§22), ``to_world`` [4, 4]:
the eye space of the shaders that launch rays (:func:`trace_ray`) → world."""


@dataclass
class _Prepared:
    scene: RayScene
    tracer: RayTracer
    unproject: np.ndarray
    notes: List[str]


def _prepare(scene, camera: Optional[Camera], max_depth: int = 5, min_weight: float = 1e-3,
             air_transmittance=1.0) -> _Prepared:
    _check_limits(max_depth, min_weight)
    camera = camera or scene.view_camera()
    objects = scene.drawn_objects(camera)
    rays = RayScene(objects)
    notes = []
    programs = []
    for obj in objects:
        name = scene.program_of(obj)
        if name not in PROGRAM_CODES:
            notes.append(f"{obj.name}: program {name!r} has no lighting equation for rays; lit as 'phong'")
        elif name == "textured":
            notes.append(f"{obj.name}: textures are not sampled by the ray tracer yet; lit with the material's kd")
        if max(obj.mesh.material.k) > 0.0 and name == "glass":
            notes.append(f"{obj.name}: the glass program's reflection is §20's dielectric Fresnel into ior; the "
                         f"conductor's k (FORMULAS §30) is not read by it")
        programs.append(PROGRAM_CODES.get(name, 0))
    lights = scene.lighting_for(camera)
    packed = pack_lights(lights.lights, np.eye(4))          # world space: the ray tracer's "eye" space
    n = len(lights.lights)
    light_maps = np.zeros((n, 3), np.int64)
    light_maps[:, 2] = SHADOW_RAY                           # every light: shadow rays (§21)
    uniform = rays.uniform()
    # shadow rays meet the shadow casters only (an object with cast_shadows false casts none, as with maps)
    casters = [o for o in objects if getattr(o, "cast_shadows", True)]
    shadow_rays = uniform if len(casters) == len(objects) else RayScene(casters).uniform()
    shadows = ShadowUniform(light_maps, None, None, None, None, None, shadow_rays)     # rays only: no map code
    lighting = LightingUniform(lights.global_ambient, packed, shadows)
    materials = np.array([_pack_material(o.mesh.material) for o in objects], np.float64).reshape(-1, _MATERIAL_COLUMNS)
    cull = np.array([{"none": 0, "back": 1, "front": 2}[obj.cull or scene.cull] for obj in objects], np.int64)
    tracer = RayTracer(uniform, lighting, materials, np.array(programs, np.int64), cull,
                       np.asarray(scene.background[:3], np.float64), _air(air_transmittance), int(max_depth),
                       float(min_weight), np.linalg.inv(camera.view))
    aspect = scene.width / scene.height
    unproject = np.linalg.inv(camera.projection(aspect) @ camera.view)
    return _Prepared(rays, tracer, unproject, notes)


def tracer_uniform(scene, camera: Optional[Camera] = None, *, max_depth: int = 5, min_weight: float = 1e-3,
                   air_transmittance=1.0, notes: Optional[list] = None) -> RayTracer:
    """The scene's ray tracer as a uniform for rasterized draws: ``uniforms={"tracer": ...}``.

    Shaders launch rays into it with :func:`trace_ray` (eye space of ``camera``, the
    scene's view camera by default); the programs ``mirror``, ``glass`` and ``hall``
    do so for their reflected and refracted rays when the draw has it
    (:func:`softpipe.scenes.environment_pass.render_with_environments` with ``"rays"``). Parameters
    as :func:`raytrace_scene`'s.
    """
    p = _prepare(scene, camera, max_depth, min_weight, air_transmittance)
    if notes is not None:
        notes.extend(p.notes)
    return p.tracer


def _check_limits(max_depth, min_weight) -> None:
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, np.integer)) or \
            not 0 <= max_depth <= MAX_DEPTH_LIMIT:
        raise ValueError(f"max_depth must be an integer in 0…{MAX_DEPTH_LIMIT}, got {max_depth!r}")
    if not (isinstance(min_weight, (int, float)) and 0.0 <= min_weight < 1.0):
        raise ValueError(f"min_weight must be a number in [0, 1), got {min_weight!r}")


def _air(air_transmittance) -> np.ndarray:
    """Air's T per unit distance (§15) as RGB in [0, 1]; a number means gray."""
    rgb = checked("raytrace_scene.air_transmittance", color, air_transmittance)
    if max(rgb) > 1.0:
        raise ValueError(f"air_transmittance is a share per unit distance, in [0, 1], got {air_transmittance!r}")
    return np.array(rgb, np.float64)


def _pattern(scene, samples, adaptive: bool, notes: list) -> SamplePattern:
    """The sample pattern the tracer uses: ``samples`` (a name or a SamplePattern), else the scene's."""
    if samples is not None and not isinstance(samples, (str, SamplePattern)):
        raise ValueError(f"samples must be a sample pattern's name ('grid16', 'rgss4', …) or a SamplePattern, "
                         f"got {samples!r}")
    if adaptive:
        if samples is not None:
            raise ValueError("samples does not apply with adaptive=True: adaptive supersampling chooses its own "
                             "samples (the centres of the cells it splits); give one or the other")
        if str(scene.samples).strip().lower() not in ("1", "center", "none"):
            notes.append(f"the scene's samples {scene.samples!r} are not used: adaptive supersampling chooses "
                         "its own")
        return CENTER
    if isinstance(samples, SamplePattern):
        return samples
    pattern = pattern_named(scene.samples if samples is None else samples)
    if len(pattern) > 1 and getattr(scene, "sample_shading", "sample") != "sample":
        notes.append(f"sample_shading {scene.sample_shading!r} (multisampling) is the rasterizer's: the ray "
                     f"tracer traces and shades each of the {len(pattern)} samples")
    return pattern


def _check_adaptive(adaptive, threshold, adaptive_depth):
    if not isinstance(adaptive, (bool, np.bool_)):
        raise ValueError(f"adaptive must be True or False, got {adaptive!r}")
    if not adaptive:
        for name, value in (("threshold", threshold), ("adaptive_depth", adaptive_depth)):
            if value is not None:
                raise ValueError(f"{name} applies only with adaptive=True (adaptive supersampling)")
        return None, None
    threshold = ADAPTIVE_THRESHOLD if threshold is None else threshold
    depth = ADAPTIVE_DEPTH if adaptive_depth is None else adaptive_depth
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float, np.integer, np.floating)) or \
            not threshold >= 0.0:
        raise ValueError(f"threshold must be a number ≥ 0 (a difference of linear color in some channel), "
                         f"got {threshold!r}")
    if isinstance(depth, bool) or not isinstance(depth, (int, np.integer)) or not 0 <= depth <= MAX_ADAPTIVE_DEPTH:
        raise ValueError(f"adaptive_depth must be an integer in 0…{MAX_ADAPTIVE_DEPTH}, got {adaptive_depth!r}")
    return float(threshold), int(depth)


def _offsets(pattern: SamplePattern) -> np.ndarray:
    """A pattern's positions as offsets from the pixel's top-left corner, x right and y down (image rows)."""
    pos = np.asarray(pattern.positions, np.float64)
    return np.ascontiguousarray(np.stack([pos[:, 0], 1.0 - pos[:, 1]], axis=1))


def raytrace_scene(scene, *, camera: Optional[Camera] = None, max_depth: int = 5, min_weight: float = 1e-3,
                   notes: Optional[list] = None, timings: Optional[dict] = None,
                   air_transmittance=1.0, samples=None, adaptive: bool = False,
                   threshold: Optional[float] = None, adaptive_depth: Optional[int] = None) -> Framebuffer:
    """Ray trace ``scene`` (Whitted; docs/raytracing.md has the steps) into a new one-sample framebuffer.

    Parameters
    ----------
    scene : Scene
        As :func:`softpipe.render_scene` takes it; its ground, lights, programs and
        background are used the same way. Every light casts shadows (shadow rays).
    camera : Camera, optional
        Instead of the scene's (or its framing).
    max_depth : int
        The deepest reflected/refracted ray (0: primary rays only).
    min_weight : float
        A branch whose weight is below this in every channel is not traced (§22).
    air_transmittance : float or RGB
        T per unit distance outside the objects (§15), in [0, 1]: a secondary ray
        that travels d through air keeps T^d. 1 (the default): air is clear.
    samples : str or SamplePattern, optional
        Supersampling (FORMULAS §24): one primary ray per sample of the pattern
        (:func:`softpipe.pipeline.sampling.pattern_named`: ``"grid16"``, ``"rgss4"``, …,
        the rasterizer's patterns), the pixel their mean — a box filter over the
        pixel. Default: the scene's ``samples`` (``"1"``: one ray through the centre).
    adaptive : bool
        Adaptive supersampling instead: the pixel centres first, then a cell split
        in four where its sample differs from a neighbour's by ``threshold`` or more,
        down to ``adaptive_depth`` levels (docs/raytracing.md, "Supersampling").
    threshold : float, optional
        With ``adaptive``: the difference of linear color, in some channel, that
        splits a cell (default :data:`ADAPTIVE_THRESHOLD` = 0.1; 0 splits every cell).
    adaptive_depth : int, optional
        With ``adaptive``: the most levels of splitting, 0…:data:`MAX_ADAPTIVE_DEPTH`
        (default :data:`ADAPTIVE_DEPTH` = 2: at most 4×4 cells, 16 rays per pixel).
    notes : list, optional
        Receives a line for each thing the ray tracer does differently from the rasterizer.
    timings : dict, optional
        Receives "build" (the BVH) and "trace" seconds, and "rays": the primary rays traced.
    """
    threshold, adaptive_depth = _check_adaptive(adaptive, threshold, adaptive_depth)
    found: list = []
    pattern = _pattern(scene, samples, adaptive, found)
    start = time.perf_counter()
    p = _prepare(scene, camera, max_depth, min_weight, air_transmittance)
    built = time.perf_counter()
    h, w = scene.height, scene.width
    out = np.zeros((h, w, 4), np.float32)
    if adaptive:
        centres = np.empty((h, w, 3))
        in_bands(_centre_rows, h, w, h, p.unproject, p.tracer, centres, grain=8)
        rays = np.zeros((h, w), np.int64)
        in_bands(_adaptive_rows, h, w, h, p.unproject, p.tracer, centres, threshold, adaptive_depth, out, rays,
                 grain=8)
        traced = int(rays.sum())
    else:
        in_bands(_trace_rows, h, w, h, p.unproject, p.tracer, _offsets(pattern), out, grain=8)
        traced = h * w * len(pattern)
    fb = Framebuffer(w, h, srgb=bool(getattr(scene, "srgb", False)))
    fb.color[...] = out
    if notes is not None:
        notes.extend(p.notes + found)
    if timings is not None:
        timings.update(build=built - start, trace=time.perf_counter() - built, rays=traced)
    return fb


def raytrace_samples(scene, samples, *, camera: Optional[Camera] = None, max_depth: int = 5,
                     min_weight: float = 1e-3, air_transmittance=1.0) -> np.ndarray:
    """Every sample's color before the pixel filter: float64 [H, W, S, 3], S the pattern's samples in its order.

    The same primary rays and trees as :func:`raytrace_scene` with ``samples``, whose
    pixel is the mean of these S colors summed in this order. For small pictures: it
    keeps every sample (H·W·S·24 bytes). Parameters as :func:`raytrace_scene`'s.
    """
    pattern = samples if isinstance(samples, SamplePattern) else _pattern(scene, samples, False, [])
    p = _prepare(scene, camera, max_depth, min_weight, air_transmittance)
    h, w = scene.height, scene.width
    out = np.empty((h, w, len(pattern), 3))
    in_bands(_sample_rows, h, w, h, p.unproject, p.tracer, _offsets(pattern), out, grain=8)
    return out


@njit(cache=True, nogil=True)
def _primary_rows(lo, hi, width, height, unproject, scene, cull, triangle, b):
    for j in range(lo, hi):
        for i in range(width):
            origin, direction, far = _primary_ray(unproject, i + 0.5, j + 0.5, width, height)
            tri, _, b1, b2 = _primary_hit(scene, cull, origin, direction, far)
            triangle[j, i] = tri
            b[j, i, 0], b[j, i, 1] = b1, b2


def primary_visibility(scene, *, camera: Optional[Camera] = None):
    """What each pixel's primary ray meets: (object int64 [H, W], triangle int64 [H, W], barycentrics [H, W, 2]).

    ``object`` indexes ``scene.drawn_objects(camera)`` (−1: nothing), ``triangle`` is
    the triangle's index in that object's mesh — the rasterizer's ``primitive_id`` of
    the fragment a pixel shows — and (b1, b2) the hit's barycentrics in it.
    """
    p = _prepare(scene, camera)
    h, w = scene.height, scene.width
    triangle = np.empty((h, w), np.int64)
    b = np.empty((h, w, 2))
    in_bands(_primary_rows, h, w, h, p.unproject, p.tracer.scene, p.tracer.cull, triangle, b, grain=8)
    hit = triangle >= 0
    obj = np.where(hit, p.scene.triangle_object[np.where(hit, triangle, 0)], -1)
    local = np.where(hit, p.scene.triangle_local[np.where(hit, triangle, 0)], -1)
    return obj, local, b


@dataclass
class RayNode:
    """One ray of a pixel's tree."""

    index: int
    parent: int                 # −1 for the primary ray
    kind: str                   # one of RAY_KINDS
    depth: int
    origin: tuple
    direction: tuple
    t: float                    # inf: it met nothing
    triangle: int               # −1: nothing
    object: str                 # the object's name, or "" for a miss
    local: tuple                # the local color at the hit (the background for a miss)
    weight: tuple               # what the ray's color counts for in the pixel (its falloff included)
    falloff: tuple = (1.0, 1.0, 1.0)   # T^d (or 1/(1 + a·d)) over this ray's path to its hit (§13, §15)


class RayTree(list):
    """A pixel's rays (:class:`RayNode`), in the order traced; prints as an indented tree."""

    def __init__(self, x: int, y: int, nodes: List[RayNode], color: tuple):
        super().__init__(nodes)
        self.x, self.y, self.color = x, y, color

    def __str__(self) -> str:
        f = lambda v: "(" + ", ".join(f"{c:.4g}" for c in v) + ")"  # noqa: E731
        lines = [f"pixel ({self.x}, {self.y}): color {f(self.color)} = Σ weight × local over {len(self)} ray(s)"]
        for node in self:
            hit = (f"hits {node.object} (triangle {node.triangle}) at t = {node.t:.4g}" if node.triangle >= 0
                   else "meets nothing: background")
            fall = f" (falloff T^d {f(node.falloff)})" if node.falloff != (1.0, 1.0, 1.0) else ""
            lines.append(f"{'    ' * node.depth}#{node.index} {node.kind}: {hit}; local {f(node.local)}, "
                         f"weight {f(node.weight)}{fall}")
        return "\n".join(lines)

    def _repr_pretty_(self, p, cycle):
        p.text(str(self))


def ray_tree(scene, x: int, y: int, *, camera: Optional[Camera] = None, max_depth: int = 5,
             min_weight: float = 1e-3, air_transmittance=1.0) -> RayTree:
    """The ray tree of pixel (x, image row y) as :func:`raytrace_scene` traces it: every ray, as data.

    The sum of weight × local over the nodes is the pixel's color (the same float
    operations in the same order, so it equals the framebuffer's value). A node's weight
    is its parent's times k_r or k_t times its own ``falloff`` (§13's T^d, §15).
    """
    _check_limits(max_depth, min_weight)
    if not (0 <= x < scene.width and 0 <= y < scene.height):
        raise ValueError(f"pixel ({x}, {y}) is outside the {scene.width}×{scene.height} image")
    p = _prepare(scene, camera, max_depth, min_weight, air_transmittance)
    origin, direction, far = _primary_ray(p.unproject, x + 0.5, y + 0.5, scene.width, scene.height)
    record = np.zeros((1 << (max_depth + 1), _RECORD_COLUMNS))
    r, g, b, n = _trace_tree(p.tracer, origin, direction, 0, 0, (1.0, 1.0, 1.0), far, record)
    names = [o.name for o in p.scene.objects]
    nodes = []
    for k, row in enumerate(record[:n]):
        obj = int(row[11])
        nodes.append(RayNode(k, int(row[0]), RAY_KINDS[int(row[1])], int(row[2]), tuple(row[3:6]), tuple(row[6:9]),
                             float(row[9]), int(row[10]), names[obj] if obj >= 0 else "", tuple(row[12:15]),
                             tuple(row[15:18]), tuple(row[18:21])))
    return RayTree(x, y, nodes, (float(np.float32(r)), float(np.float32(g)), float(np.float32(b))))
