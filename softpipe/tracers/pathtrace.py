"""A Monte Carlo path tracer: the rendering equation itself, on the same BVH and scenes (FORMULAS §16–§21).

The Whitted tracer (:mod:`.whitted`) solves the notes' simplified equation: point
lights, a constant ambient term for all indirect light, a ray tree for mirrors and
glass. This module solves the equation the notes start from,

    L_o(p, ω_o) = L_e(p, ω_o) + ∫ f(p, ω_i, ω_o) L_i(p, ω_i) (N·ω_i) dω_i,

by following one random path per sample from the eye, so that colour bleeding,
soft shadows and light from emissive surfaces come out of it:

- **lights** are surfaces: any triangle whose material has ``ke`` ≠ 0 emits
  radiance ke from its front face (by its winding); a ray that leaves the scene
  sees the scene's ``background`` as radiance from every direction. The scene's
  point, directional and spot lights have no area and are not used (a note says so);
- **materials** (a material may mix them; one is picked per bounce with probability
  ∝ its strongest channel): Lambert, f = kd/π, sampled by cos θ/π, kd times the
  object's texture at the hit's uv where its program is "textured"; a glossy lobe of
  reflectance ks, normalized to conserve energy and sampled by its own density
  (:mod:`.lobes`, FORMULAS §27): Blinn-Phong, Phong or Cook-Torrance (§26) as the
  object's program says, Cook-Torrance's F a conductor's per channel where k ≠ 0 (§30);
  a perfect mirror of reflectance kr (§16), times a
  conductor's exact Fresnel F_R per channel where the material has an extinction
  coefficient k ≠ 0 (its complex index η + ik, §30); glass when
  kt ≠ 0: reflected with Fresnel's F_R (§20, n = 1 outside, ``ior`` inside), else
  refracted (§18) and tinted by kt, all reflected past the critical angle (§19).
  ka is not used (the path tracer computes the light it stands in for);
- **next-event estimation**: at a diffuse or glossy bounce a point is picked on an
  emissive triangle (the triangle with probability ∝ area × mean ke, the point
  uniformly), a shadow ray (§21) tests it, and its light is combined with the
  light that the sampled direction finds by the power heuristic (multiple
  importance sampling), lobe by lobe: each lobe's share of the light sample is
  weighted against the density with which that lobe draws the same direction; with
  ``background_light``, the uniform background is a light too (a direction ∝ cos θ
  about N, picked beside the triangles by power);
- **Russian roulette** ends a path from its ``rr_depth``-th bounce on with
  probability 1 − min(0.95, strongest channel of its throughput), dividing the
  survivors by the probability that they survived: unbiased;
- **the pixel filter** is a box over the pixel: each sample's ray goes through a
  uniformly jittered point of its pixel and counts only there, with weight 1/spp.

Every random number is :func:`~softpipe.tracers.montecarlo.uniform` of (seed,
pixel, sample, dimension), so the image is the same bytes on any thread count, and
rendering N samples then N more (:meth:`PathTrace.add`) gives the same bytes as
2N at once: the samples are the same numbers, added to the same float64 sums in
the same order. docs/pathtracing.md walks from the equation to the code.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np
from numba import njit

from softpipe.core.borrow import borrowed, borrowed_tuple
from softpipe.core.parallel import in_bands
from softpipe.language.glsl import reflect
from softpipe.light.lighting import fresnel_directions
from softpipe.light.texture import TextureUniform, texture
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.rays.bvh import hit_inline
from softpipe.rays.queries import RayScene, hit_normal
from softpipe.tracers.lobes import (
    COOK_TORRANCE_LOBE,
    LOBE_NAMES,
    NO_LOBE,
    conductor_fresnel,
    cook_torrance_conductor,
    lobe_code,
    lobe_eval,
    lobe_sample,
)
from softpipe.tracers.montecarlo import cosine_hemisphere, sample_key, triangle_point, uniform_of

__all__ = ["pathtrace", "PathTrace", "PathStory", "PathSample", "Bounce", "MAX_STORY_BOUNCES", "BACKGROUND_LIGHT", "STORY_COLUMNS", "MAX_SPP", "PASS_SPP", "DIMENSIONS_PER_BOUNCE", "STRATEGIES"]

#: The most samples per pixel one call renders (a guard against a typo such as 1e9).
MAX_SPP = 1 << 20
#: Samples per pixel in one pass over the image (PathTrace.add renders in passes of at most this many).
PASS_SPP = 16
#: How light is found (:func:`pathtrace`'s ``strategy``): both sampling strategies weighted by MIS, the
#: sampled direction alone (BSDF sampling), or the light sample alone at a non-delta bounce.
STRATEGIES = ("mis", "bsdf", "light")
#: Random numbers one bounce draws (lobe, light, light point ×2, direction ×2, Fresnel, roulette).
DIMENSIONS_PER_BOUNCE = 8
_MATERIAL_COLUMNS = 26           # ke (3), kd (3), kr (3), kt (3), ior, ks (3), shininess, roughness, lobe code,
#                                  conductor (1: k ≠ 0), η (3), k (3)
_INV_PI = 1.0 / math.pi
#: A path story's row (PathTrace.path_story): kind, depth, P (3), triangle, object, lobe, f (3), cos, pdf,
#: throughput (3) after the bounce (and the roulette), roulette q, spare, emission (3) and its MIS weight, NEE Lambert (3), NEE glossy (3),
#: their MIS weights (2), light triangle, NEE outcome, background (3), direction (3), why the path ended.
STORY_COLUMNS = 39
_HIT, _MISS = 0, 1
#: A path story's ``Bounce.light`` when the light sample went toward the background (not a triangle).
BACKGROUND_LIGHT = -2
_END_MORE, _END_DEPTH, _END_BLACK, _END_BELOW, _END_ROULETTE, _END_MISS, _END_DEGENERATE = 0, 1, 2, 3, 4, 5, 6


# ------------------------------------------------------------------ the kernel

@njit(cache=True, forceinline=True)
def _power_heuristic(a, b):
    """Veach's power heuristic (β = 2): the weight a²/(a² + b²) of the strategy whose pdf is a."""
    a2 = a * a
    return a2 / (a2 + b * b)


@njit(cache=True)
def _pick_light(cdf, u):
    """The index k with cdf[k-1] ≤ u·total < cdf[k] (binary search): a light triangle picked ∝ its weight."""
    x = u * cdf[cdf.shape[0] - 1]
    lo, hi = 0, cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, forceinline=True)
def _diffuse(textures, obj, tri, b1, b2, m):
    """kd at the hit: the material's, times the object's texture at the hit's uv where it has one.

    As the rasterizer's ``textured`` program scales kd by ``texture(uv)``; here at level of detail 0 with
    the texture's own filter and wrap modes (:func:`~softpipe.light.texture.texture`): the path tracer's
    jittered samples average the texture over the pixel instead of a mipmap. ``textures`` is (texels
    float32 [total, 4], tex_info int64 [objects, 7]: textured (0/1), offset, width, height, wrap s, wrap t,
    filter; uv_corners float64 [T, 3, 2]), the uv interpolated with the hit's barycentrics as the normal is.
    """
    texels, info, uvs = textures
    if info[obj, 0] == 0:
        return m[3], m[4], m[5]
    b0 = 1.0 - b1 - b2
    u = b0 * uvs[tri, 0, 0] + b1 * uvs[tri, 1, 0] + b2 * uvs[tri, 2, 0]
    v = b0 * uvs[tri, 0, 1] + b1 * uvs[tri, 1, 1] + b2 * uvs[tri, 2, 1]
    level0 = TextureUniform(texels, info[obj, 2:3], info[obj, 3:4], info[obj, 1:2], info[obj, 4], info[obj, 5],
                            info[obj, 6])
    t = texture(level0, (u, v))
    return m[3] * t[0], m[4] * t[1], m[5] * t[2]


@njit(cache=True, forceinline=True)
def _glossy(lobe, N, V, L, m):
    """The glossy lobe's (f/ks per channel, p) toward L: :func:`lobe_eval`'s f in every channel, or for a
    conductor's Cook-Torrance (k ≠ 0) its F per channel (§30, :func:`cook_torrance_conductor`)."""
    if lobe == COOK_TORRANCE_LOBE and m[19] > 0.0:
        return cook_torrance_conductor(N, V, L, m[17], m[20], m[21], m[22], m[23], m[24], m[25])
    fs, pdf = lobe_eval(lobe, N, V, L, m[16], m[17], m[12])
    return fs, fs, fs, pdf


@njit(cache=True, nogil=True, forceinline=True)
def _radiance(scene, mats, textures, light_tris, light_corners, light_cdf, light_pdf, background, o, d, t_far, max_depth,
              rr_depth, key, strategy, record):
    """The radiance one path from ``o`` along the unit ``d`` brings back (RGB): the estimator of the module doc.

    ``record`` [rows, STORY_COLUMNS] (rows 0 when rendering) gets one row per bounce, row k for the k-th
    ray of the path, as :meth:`PathTrace.path_story` reads it; recording changes no arithmetic.
    ``textures`` is (texels, tex_info, uv_corners): :func:`_setup`'s textures, see :func:`_diffuse`.
    ``key`` is the sample's :func:`~softpipe.tracers.montecarlo.sample_key`: its number k is ``uniform_of(key, k)``.
    """
    bvh = scene.bvh
    eps = scene.epsilon
    red, green, blue = 0.0, 0.0, 0.0
    tr, tg, tb = 1.0, 1.0, 1.0                    # the path's throughput
    prev_pdf = 0.0                                # the pdf (solid angle) the last direction was drawn with
    prev_cos = 0.0                                # N·ω of that direction at its vertex (the background's pdf)
    prev_delta = True                             # the eye, or a mirror or glass bounce: no light sampling there
    t_min, t_max = 0.0, t_far
    p_bg = background[3]                          # the probability that a light sample goes to the background
    have_lights = light_tris.shape[0] > 0 or p_bg > 0.0
    depth = 0
    while True:
        row = depth if depth < record.shape[0] else -1
        tri, t, b1, b2 = hit_inline(bvh, o, d, t_min, t_max, False)
        if tri < 0:
            w = 1.0
            if not prev_delta and p_bg > 0.0:     # a direction the background's light sample could have drawn too
                if strategy == 0:
                    w = _power_heuristic(prev_pdf, p_bg * prev_cos * _INV_PI)
                elif strategy == 2:               # light sampling alone: it counts the background
                    w = 0.0
            if row >= 0:
                record[row, 0:2] = (float(_MISS), float(depth))
                record[row, 13:16] = (tr, tg, tb)         # the throughput the ray carried out of the scene
                record[row, 32:35] = (tr * background[0] * w, tg * background[1] * w, tb * background[2] * w)
                record[row, 21] = w
                record[row, 38] = _END_MISS
            red += tr * background[0] * w
            green += tg * background[1] * w
            blue += tb * background[2] * w
            break
        P = (o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2])
        fn = scene.face_normals[tri]
        length = math.sqrt(fn[0] * fn[0] + fn[1] * fn[1] + fn[2] * fn[2])
        if row >= 0:
            record[row, 0:8] = (float(_HIT), float(depth), P[0], P[1], P[2], float(tri),
                                 float(scene.triangle_object[tri]), -1.0)
        if length == 0.0:                         # a degenerate triangle: nothing to shade
            if row >= 0:
                record[row, 38] = _END_DEGENERATE
            break
        ng = (fn[0] / length, fn[1] / length, fn[2] / length)
        cos_o = ng[0] * d[0] + ng[1] * d[1] + ng[2] * d[2]
        front = cos_o < 0.0
        m = mats[scene.triangle_object[tri]]
        if front and (m[0] > 0.0 or m[1] > 0.0 or m[2] > 0.0):      # emission, seen from the front
            w = 1.0
            if not prev_delta:                    # a direction light sampling could have drawn too
                if strategy == 0:
                    w = _power_heuristic(prev_pdf, light_pdf[tri] * t * t / -cos_o)
                elif strategy == 2:               # light sampling alone: it counts this light
                    w = 0.0
            if row >= 0:
                record[row, 18:22] = (tr * m[0] * w, tg * m[1] * w, tb * m[2] * w, w)
            red += tr * m[0] * w
            green += tg * m[1] * w
            blue += tb * m[2] * w
        if max_depth >= 0 and depth + 1 >= max_depth:
            if row >= 0:
                record[row, 38] = _END_DEPTH
            break
        if not front:
            ng = (-ng[0], -ng[1], -ng[2])
        N = hit_normal(scene, tri, b1, b2)
        if not front:
            N = (-N[0], -N[1], -N[2])
        if N[0] * d[0] + N[1] * d[1] + N[2] * d[2] >= 0.0:        # an interpolated normal facing away: the face's
            N = ng
        V = (-d[0], -d[1], -d[2])
        lobe = int(m[18])
        kd = _diffuse(textures, scene.triangle_object[tri], tri, b1, b2, m)
        w_d = max(kd[0], kd[1], kd[2])
        w_s = max(m[13], m[14], m[15]) if lobe != NO_LOBE else 0.0
        w_m = max(m[6], m[7], m[8])
        w_g = max(m[9], m[10], m[11])
        total = w_d + w_s + w_m + w_g
        if total <= 0.0:                          # black: absorbs everything
            if row >= 0:
                record[row, 38] = _END_BLACK
            break
        base = 2 + depth * DIMENSIONS_PER_BOUNCE
        p_d = w_d / total
        p_s = w_s / total
        if (w_d > 0.0 or w_s > 0.0) and have_lights and strategy != 1:    # next-event estimation
            shadow, shadow_far = False, 0.0           # whether a shadow ray is to be traced, and how far
            wi, cos_s, pdf_l, le = (0.0, 0.0, 0.0), 0.0, 1.0, (0.0, 0.0, 0.0)
            u_l = uniform_of(key, base + 1)
            if u_l < p_bg:                        # toward the background: a direction drawn ∝ cos θ about N
                wi, cos_s = cosine_hemisphere(N, uniform_of(key, base + 2),
                                              uniform_of(key, base + 3))
                if row >= 0:
                    record[row, 30:32] = (-2.0, 1.0)            # 1: in shadow or below, until found lit
                if cos_s > 0.0 and ng[0] * wi[0] + ng[1] * wi[1] + ng[2] * wi[2] > 0.0:
                    shadow, shadow_far = True, np.inf
                    pdf_l = p_bg * cos_s * _INV_PI
                    le = (background[0], background[1], background[2])
            else:                                 # toward an emissive triangle, picked ∝ area × mean ke
                li = _pick_light(light_cdf, (u_l - p_bg) / (1.0 - p_bg))
                k = light_tris[li]
                c = light_corners[li]
                Q = triangle_point((c[0], c[1], c[2]), (c[3], c[4], c[5]), (c[6], c[7], c[8]),
                                   uniform_of(key, base + 2), uniform_of(key, base + 3))
                if row >= 0:
                    record[row, 30:32] = (float(k), 1.0)        # 1: in shadow or facing away, until found lit
                lx, ly, lz = Q[0] - P[0], Q[1] - P[1], Q[2] - P[2]
                dist2 = lx * lx + ly * ly + lz * lz
                dist = math.sqrt(dist2)
                if dist > 0.0:
                    wi = (lx / dist, ly / dist, lz / dist)
                    ln = scene.face_normals[k]
                    cos_l = -(ln[0] * wi[0] + ln[1] * wi[1] + ln[2] * wi[2]) / math.sqrt(
                        ln[0] * ln[0] + ln[1] * ln[1] + ln[2] * ln[2])
                    cos_s = N[0] * wi[0] + N[1] * wi[1] + N[2] * wi[2]
                    cos_g = ng[0] * wi[0] + ng[1] * wi[1] + ng[2] * wi[2]
                    if cos_l > 0.0 and cos_s > 0.0 and cos_g > 0.0:
                        shadow, shadow_far = True, dist * (1.0 - 1e-7) - eps
                        pdf_l = light_pdf[k] * dist2 / cos_l
                        e = mats[scene.triangle_object[k]]
                        le = (e[0], e[1], e[2])
            # the shadow ray (§21), any hit: one call site for both kinds of light, as each is a copy of the walk
            lit = shadow and hit_inline(bvh, P, wi, eps, shadow_far, True)[0] < 0
            if lit:
                pdf_b = p_d * cos_s * _INV_PI
                w_l = _power_heuristic(pdf_l, pdf_b) if strategy == 0 else 1.0
                f = w_l * cos_s * _INV_PI / pdf_l
                if row >= 0:
                    record[row, 22:25] = (tr * kd[0] * le[0] * f, tg * kd[1] * le[1] * f, tb * kd[2] * le[2] * f)
                    record[row, 28] = w_l
                    record[row, 31] = 2.0
                red += tr * kd[0] * le[0] * f
                green += tg * kd[1] * le[1] * f
                blue += tb * kd[2] * le[2] * f
                if w_s > 0.0:                     # the glossy lobe's share, weighted against its own sampling
                    fsr, fsg, fsb, pdf_s = _glossy(lobe, N, V, wi, m)
                    if fsr > 0.0 or fsg > 0.0 or fsb > 0.0:
                        w_l = _power_heuristic(pdf_l, p_s * pdf_s) if strategy == 0 else 1.0
                        gr = w_l * fsr * cos_s / pdf_l
                        gg = w_l * fsg * cos_s / pdf_l
                        gb = w_l * fsb * cos_s / pdf_l
                        if row >= 0:
                            record[row, 25:28] = (tr * m[13] * le[0] * gr, tg * m[14] * le[1] * gg,
                                                  tb * m[15] * le[2] * gb)
                            record[row, 29] = w_l
                        red += tr * m[13] * le[0] * gr
                        green += tg * m[14] * le[1] * gg
                        blue += tb * m[15] * le[2] * gb
        u = uniform_of(key, base) * total
        if u < w_d:                               # Lambert: f·cos/pdf = (kd/π)·cos / (p_d·cos/π) = kd/p_d
            wi, cos_s = cosine_hemisphere(N, uniform_of(key, base + 4),
                                          uniform_of(key, base + 5))
            if row >= 0:
                record[row, 7:13] = (0.0, kd[0] * _INV_PI, kd[1] * _INV_PI, kd[2] * _INV_PI, cos_s, p_d * cos_s * _INV_PI)
                record[row, 35:38] = wi
            if cos_s <= 0.0 or ng[0] * wi[0] + ng[1] * wi[1] + ng[2] * wi[2] <= 0.0:
                if row >= 0:
                    record[row, 38] = _END_BELOW
                break                             # below the surface: the interpolated normal leans too far
            tr, tg, tb = tr * kd[0] / p_d, tg * kd[1] / p_d, tb * kd[2] / p_d
            prev_pdf, prev_cos, prev_delta = p_d * cos_s * _INV_PI, cos_s, False
        elif u < w_d + w_s:                       # the glossy lobe: f·cos/(p_s·pdf), ks times the lobe's weight
            wi = lobe_sample(lobe, N, V, m[16], m[17], uniform_of(key, base + 4),
                             uniform_of(key, base + 5))
            cos_s = N[0] * wi[0] + N[1] * wi[1] + N[2] * wi[2]
            fsr, fsg, fsb, pdf_s = _glossy(lobe, N, V, wi, m)
            if row >= 0:
                record[row, 7:13] = (1.0, m[13] * fsr, m[14] * fsg, m[15] * fsb, cos_s, p_s * pdf_s)
                record[row, 35:38] = wi
            if cos_s <= 0.0 or ng[0] * wi[0] + ng[1] * wi[1] + ng[2] * wi[2] <= 0.0 or \
                    (fsr <= 0.0 and fsg <= 0.0 and fsb <= 0.0) or pdf_s <= 0.0:
                if row >= 0:
                    record[row, 38] = _END_BELOW
                break                             # below the surface: f = 0 there
            tr = tr * m[13] * (fsr * cos_s / (p_s * pdf_s))
            tg = tg * m[14] * (fsg * cos_s / (p_s * pdf_s))
            tb = tb * m[15] * (fsb * cos_s / (p_s * pdf_s))
            prev_pdf, prev_cos, prev_delta = p_s * pdf_s, cos_s, False
        else:
            if u < w_d + w_s + w_m:                     # a perfect mirror (§16), weight kr
                p = w_m / total
                wi = reflect(d, N)
                fr, fg, fb = m[6], m[7], m[8]
                if m[19] > 0.0:                   # a conductor: kr times its exact Fresnel F_R per channel (§30)
                    c = N[0] * V[0] + N[1] * V[1] + N[2] * V[2]
                    fr *= conductor_fresnel(c, m[20], m[23])
                    fg *= conductor_fresnel(c, m[21], m[24])
                    fb *= conductor_fresnel(c, m[22], m[25])
                tr, tg, tb = tr * fr / p, tg * fg / p, tb * fb / p
                if row >= 0:
                    record[row, 7:13] = (2.0, fr, fg, fb, 1.0, p)
            else:                                 # glass: Fresnel picks reflection or refraction (§18–§20)
                p = w_g / total
                n1, n2 = (1.0, m[12]) if front else (m[12], 1.0)
                R, T, F = fresnel_directions(N, V, n1, n2)
                if uniform_of(key, base + 6) < F:
                    wi = R                        # F·1 / F: the reflected share, white
                    tr, tg, tb = tr / p, tg / p, tb / p
                    if row >= 0:
                        record[row, 7:13] = (3.0, F, F, F, 1.0, p * F)
                else:
                    wi = T                        # (1 − F)·kt / (1 − F)
                    tr, tg, tb = tr * m[9] / p, tg * m[10] / p, tb * m[11] / p
                    if row >= 0:
                        record[row, 7:13] = (4.0, (1.0 - F) * m[9], (1.0 - F) * m[10], (1.0 - F) * m[11], 1.0,
                                             p * (1.0 - F))
            prev_delta = True
            n = math.sqrt(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2])
            if n == 0.0:
                if row >= 0:
                    record[row, 38] = _END_DEGENERATE
                break
            wi = (wi[0] / n, wi[1] / n, wi[2] / n)
            if row >= 0:
                record[row, 35:38] = wi
        if row >= 0:
            record[row, 13:17] = (tr, tg, tb, 1.0)
        if depth + 1 >= rr_depth:                 # Russian roulette
            q = min(0.95, max(tr, tg, tb))
            if row >= 0:
                record[row, 16] = q
            if uniform_of(key, base + 7) >= q:
                if row >= 0:
                    record[row, 38] = _END_ROULETTE
                break
            tr, tg, tb = tr / q, tg / q, tb / q
            if row >= 0:
                record[row, 13:16] = (tr, tg, tb)
        o, d = P, wi
        t_min, t_max = eps, np.inf
        depth += 1
    return red, green, blue


@njit(cache=True, forceinline=True)
def _unproject(M, x, y, z):
    w = M[3, 0] * x + M[3, 1] * y + M[3, 2] * z + M[3, 3]
    return ((M[0, 0] * x + M[0, 1] * y + M[0, 2] * z + M[0, 3]) / w,
            (M[1, 0] * x + M[1, 1] * y + M[1, 2] * z + M[1, 3]) / w,
            (M[2, 0] * x + M[2, 1] * y + M[2, 2] * z + M[2, 3]) / w)


@njit(cache=True, nogil=True, forceinline=True)
def _sample(i, j, s, width, height, unproject, scene, mats, textures, light_tris, light_corners, light_cdf, light_pdf,
            background, max_depth, rr_depth, seed, strategy, record):
    """Sample s of pixel (i, image row j): its ray through a jittered point of the pixel, and the radiance it brings."""
    pixel = j * width + i
    # the box filter: a uniform point of the pixel (image row j counts down from the top)
    key = sample_key(seed, pixel, s)           # the sample's numbers: uniform(seed, pixel, s, k) = uniform_of(key, k)
    x = 2.0 * (i + uniform_of(key, 0)) / width - 1.0
    y = 1.0 - 2.0 * (j + uniform_of(key, 1)) / height
    near = _unproject(unproject, x, y, -1.0)
    far = _unproject(unproject, x, y, 1.0)
    dx, dy, dz = far[0] - near[0], far[1] - near[1], far[2] - near[2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    d = (dx / length, dy / length, dz / length)
    return _radiance(scene, mats, textures, light_tris, light_corners, light_cdf, light_pdf, background, near, d,
                     length, max_depth, rr_depth, key, strategy, record)


@njit(cache=True, nogil=True)
def _render_rows(lo, hi, width, height, unproject, scene, mats, textures, light_tris, light_corners, light_cdf, light_pdf,
                 background, max_depth, rr_depth, seed, first, count, total, squares, strategy):
    """Samples first … first + count − 1 of every pixel of image rows lo:hi, added to the float64 sums in order."""
    no_record = np.zeros((0, STORY_COLUMNS))
    # borrowed (softpipe.core.borrow): the sample's calls then count no references to these ~25 arrays; counted,
    # the atomic adds cost more than a camera ray, and the two threads fought over the same counters
    unproject, scene, mats, textures = borrowed(unproject), borrowed_tuple(scene), borrowed(mats), \
        borrowed_tuple(textures)
    light_tris, light_corners, light_cdf, light_pdf = borrowed(light_tris), borrowed(light_corners), \
        borrowed(light_cdf), borrowed(light_pdf)
    background = borrowed(background)
    for j in range(lo, hi):
        for i in range(width):
            for s in range(first, first + count):
                r, g, b = _sample(i, j, s, width, height, unproject, scene, mats, textures, light_tris, light_corners,
                                  light_cdf, light_pdf, background, max_depth, rr_depth, seed, strategy, no_record)
                total[j, i, 0] += r
                total[j, i, 1] += g
                total[j, i, 2] += b
                squares[j, i, 0] += r * r
                squares[j, i, 1] += g * g
                squares[j, i, 2] += b * b


# ------------------------------------------------------------------ the Python side

def _whole(name: str, value, least: int, most: Optional[int] = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least or \
            (most is not None and value > most):
        span = f"{least}…{most}" if most is not None else f"≥ {least}"
        raise ValueError(f"pathtrace: {name} must be a whole number {span}, got {value!r}")
    return int(value)


@dataclass
class _Setup:
    scene: RayScene
    uniform: tuple
    mats: np.ndarray
    textures: tuple
    light_tris: np.ndarray
    light_corners: np.ndarray
    light_cdf: np.ndarray
    light_pdf: np.ndarray
    background: np.ndarray
    unproject: np.ndarray


def _setup(scene, camera: Camera, notes: List[str], background_light: bool = False) -> _Setup:
    objects = scene.drawn_objects(camera)
    rays = RayScene(objects)
    uniform_ = rays.uniform()
    mats = np.array([[*m.ke, *m.kd, *m.kr, *m.kt, m.ior, *m.ks, m.shininess, m.roughness,
                      lobe_code(scene.program_of(o)), float(max(m.k) > 0.0), *m.conductor_eta, *m.k]
                     for o, m in ((o, o.mesh.material) for o in objects)],
                    np.float64).reshape(-1, _MATERIAL_COLUMNS)
    for obj in objects:
        m = obj.mesh.material
        if max(m.ks) > 0.0 and m.ior == 1.0 and max(m.k) == 0.0 and \
                lobe_code(scene.program_of(obj)) == COOK_TORRANCE_LOBE:
            notes.append(f"{obj.name}: Cook-Torrance with ior 1 reflects nothing (Fresnel's F is 0): its ks "
                         f"lobe is black")
        rough_metal = max(m.ks) > 0.0 and lobe_code(scene.program_of(obj)) == COOK_TORRANCE_LOBE
        if max(m.k) > 0.0 and max(m.kr) == 0.0 and not rough_metal:
            notes.append(f"{obj.name}: a conductor's k weights the mirror lobe kr by its Fresnel reflectance, "
                         f"but kr is 0: set kr = 1 for a bare metal")
    if scene.lights is None or len(scene.lights):
        notes.append("the scene's point, directional and spot lights have no area and do not light the path "
                     "tracer's image: only emissive surfaces (material ke) and the background do")
    # the lights: every triangle of an emissive object, picked ∝ area × mean ke
    n = len(rays)
    light_pdf = np.zeros(n, np.float64)
    emissive = mats[rays.triangle_object, 0:3].mean(axis=1) if n else np.zeros(0)
    area = 0.5 * np.linalg.norm(rays.face_normals, axis=1) if n else np.zeros(0)
    weight = emissive * area
    light_tris = np.flatnonzero(weight > 0.0).astype(np.int64)
    corners = np.empty((n, 9), np.float64)
    corners[rays.bvh.order] = rays.bvh.corners          # the BVH keeps them in leaf order: back to triangle ids
    # the background as a light: a uniform sky of radiance L sends π·L·4πR² into the sphere of radius R around
    # the scene, as a triangle of area A sends π·ke·A out of its front; so its weight beside theirs is
    # mean(L)·4πR², and a light sample goes to it with probability p_bg (docs/pathtracing.md); without
    # background_light, p_bg = 0: no light sample goes there, and a path that leaves counts in full
    sky = float(np.mean(scene.background[:3]))
    p_bg = 0.0
    if sky > 0.0 and background_light:
        if len(light_tris) and n:
            points = corners.reshape(-1, 3)
            radius = 0.5 * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
            sky_weight = sky * 4.0 * math.pi * radius * radius
            p_bg = sky_weight / (sky_weight + float(weight[light_tris].sum()))
        else:
            p_bg = 1.0
    if len(light_tris):
        light_cdf = np.cumsum(weight[light_tris])
        # (area·power/Σ) / area: per unit area, times the probability that the sample goes to a triangle
        light_pdf[light_tris] = emissive[light_tris] / light_cdf[-1] * (1.0 - p_bg)
    else:
        light_cdf = np.zeros(1, np.float64)
        if sky <= 0.0:
            notes.append("nothing emits light (no material has ke and the background is black): the image is black")
    light_corners = np.ascontiguousarray(corners[light_tris])
    aspect = scene.width / scene.height
    unproject = np.linalg.inv(camera.projection(aspect) @ camera.view)
    background = np.array([*scene.background[:3], p_bg], np.float64)      # RGB radiance, then p_bg
    return _Setup(rays, uniform_, mats, _textures(scene, objects, len(rays)), light_tris, light_corners, light_cdf, light_pdf, background, unproject)

def _textures(scene, objects, triangles: int) -> tuple:
    """(texels, tex_info, uv_corners) for :func:`_diffuse`: the level 0 of each texture an object is drawn with.

    An object's texture counts where its program is ``textured`` (the program that reads it), as in the
    rasterizer; the others' kd is their material's.
    """
    texels = [np.zeros((1, 4), np.float32)]
    info = np.zeros((len(objects), 7), np.int64)
    uvs = np.zeros((triangles, 3, 2), np.float64)
    start = offset = 0
    for k, obj in enumerate(objects):
        corners = np.asarray(obj.mesh.indices).reshape(-1, 3)
        count = len(corners)
        if obj.texture is not None and obj.mesh.uvs is not None and scene.program_of(obj) == "textured":
            tex = obj.texture.__softpipe_uniform__()
            w, h = int(tex.widths[0]), int(tex.heights[0])
            offset += len(texels[-1])
            texels.append(np.asarray(tex.texels[:w * h], np.float32))
            info[k] = (1, offset, w, h, tex.wrap_s, tex.wrap_t, tex.filter)
            uvs[start:start + count] = np.asarray(obj.mesh.uvs, np.float64)[corners]
        start += count
    return np.ascontiguousarray(np.concatenate(texels)), info, uvs


#: The most bounces a path's story records (a longer path's story is cut there, and says so).
MAX_STORY_BOUNCES = 1024
_LOBES = ("Lambert", "", "mirror", "glass, reflected", "glass, refracted")
_ENDS = ("", "max_depth reached", "black: absorbs everything", "drawn below the surface", "Russian roulette",
         "left the scene", "degenerate triangle or direction")
_NEE = ("no light sample", "light sample in shadow or facing away", "light sample lit it")


@dataclass
class Bounce:
    """One ray of a sampled path and what happened where it ended (:meth:`PathTrace.path_story`).

    The light it collected is ``emitted`` (the surface's ke seen along this ray, times the
    throughput and its MIS weight), ``nee_lambert`` and ``nee_glossy`` (the light sample's
    share through each lobe, with their MIS weights) and ``background`` (a ray that left).
    ``f`` is the BRDF of the lobe chosen toward ``direction`` (for a delta lobe: its tint, kr,
    Fresnel's F or (1 − F)·kt), ``pdf`` the density that direction was drawn with, the
    probability of picking the lobe included (for a delta lobe: that probability), and
    ``throughput`` the path's after this bounce (and after the roulette, if it survived); for a ray that
    left the scene, the throughput it carried.
    """

    depth: int
    object: str                  # "" for a ray that left the scene
    triangle: int                # −1: nothing
    point: tuple
    lobe: str                    # "" when the path ended before choosing one
    direction: tuple
    f: tuple
    cos: float
    pdf: float
    throughput: tuple
    roulette: float              # the survival probability q, 1 before rr_depth
    emitted: tuple
    emission_weight: float      # for a ray that left the scene: the background's MIS weight
    light: int                   # the light triangle sampled, −1 for none, −2 the background (BACKGROUND_LIGHT)
    nee: str
    nee_lambert: tuple
    nee_lambert_weight: float
    nee_glossy: tuple
    nee_glossy_weight: float
    background: tuple
    end: str                     # why the path ended here ("" if it went on)

    @property
    def contribution(self) -> tuple:
        """The light this bounce added to the sample, RGB (emitted + NEE + background)."""
        return tuple(a + b + c + d for a, b, c, d in zip(self.emitted, self.nee_lambert, self.nee_glossy,
                                                         self.background))


@dataclass
class PathSample:
    """One sample of a pixel: its bounces and the value (RGB, float64) it added to the pixel's sum."""

    sample: int
    value: tuple
    bounces: List[Bounce]
    truncated: bool = False      # longer than MAX_STORY_BOUNCES: the story stops there

    def total(self) -> tuple:
        """The bounces' collected light summed in the kernel's order: equal to ``value``, to the last bit."""
        acc = [0.0, 0.0, 0.0]
        for b in self.bounces:
            for part in (b.emitted, b.nee_lambert, b.nee_glossy, b.background):
                for c in range(3):
                    acc[c] += part[c]
        return tuple(acc)


class PathStory(list):
    """A pixel's sampled paths (:class:`PathSample`), in sample order; prints as one block per path."""

    def __init__(self, x: int, y: int, samples: List[PathSample]):
        super().__init__(samples)
        self.x, self.y = x, y

    def __str__(self) -> str:
        f = lambda v: "(" + ", ".join(f"{c:.4g}" for c in v) + ")"  # noqa: E731
        lines = [f"pixel ({self.x}, {self.y}): {len(self)} sampled path(s)"]
        for ps in self:
            lines.append(f"sample {ps.sample}: value {f(ps.value)} = Σ collected light over {len(ps.bounces)} "
                         f"ray(s)" + (" (cut at MAX_STORY_BOUNCES)" if ps.truncated else ""))
            for b in ps.bounces:
                pad = "    " * (b.depth + 1)
                if b.triangle < 0:
                    weight = f" (MIS weight {b.emission_weight:.4g})" if b.emission_weight != 1.0 else ""
                    lines.append(f"{pad}#{b.depth} left the scene: background {f(b.background)}{weight}")
                    continue
                text = f"{pad}#{b.depth} hits {b.object} (triangle {b.triangle}) at {f(b.point)}"
                if any(b.emitted):
                    text += f"; emitted {f(b.emitted)} (MIS weight {b.emission_weight:.4g})"
                if b.light != -1:
                    text += f"; {b.nee} ({'the background' if b.light == BACKGROUND_LIGHT else f'triangle {b.light}'})"
                    if any(b.nee_lambert) or any(b.nee_glossy):
                        text += f": Lambert {f(b.nee_lambert)} (w {b.nee_lambert_weight:.4g})"
                    if any(b.nee_glossy):
                        text += f", glossy {f(b.nee_glossy)} (w {b.nee_glossy_weight:.4g})"
                if b.lobe:
                    text += f"; {b.lobe}: f {f(b.f)}, cos {b.cos:.4g}, pdf {b.pdf:.4g}, throughput {f(b.throughput)}"
                    if b.roulette < 1.0:
                        text += f" (roulette q {b.roulette:.4g})"
                if b.end:
                    text += f"; ends: {b.end}"
                lines.append(text)
        return "\n".join(lines)

    def _repr_pretty_(self, p, cycle):
        p.text(str(self))


@dataclass
class PathTrace:
    """A progressive path-traced image of a scene (:func:`pathtrace`): render more samples with :meth:`add`.

    Attributes
    ----------
    spp : int
        Samples per pixel so far.
    seed : int
    width, height : int
    notes : list of str
        What the path tracer leaves out of this scene (the lights it cannot use, textures).
    strategy : str
        How light is found: one of :data:`STRATEGIES` (:func:`pathtrace`).
    background_light : bool
        Whether light samples go to the background too (:func:`pathtrace`).
    timings : dict
        "setup" (the BVH and lights) and "trace" seconds, summed over every call.
    """

    seed: int
    width: int
    height: int
    max_depth: int
    rr_depth: int
    notes: List[str] = field(default_factory=list)
    strategy: str = "mis"
    timings: dict = field(default_factory=dict)
    background_light: bool = False
    spp: int = 0
    _setup: Optional[_Setup] = field(default=None, repr=False)
    _total: Optional[np.ndarray] = field(default=None, repr=False)
    _squares: Optional[np.ndarray] = field(default=None, repr=False)

    def add(self, spp: int) -> "PathTrace":
        """Render ``spp`` more samples per pixel onto the image (samples spp … spp + n − 1 of each pixel).

        The result is the same bytes as rendering all the samples in one call.
        """
        spp = _whole("spp", spp, 1, MAX_SPP)
        s = self._setup
        assert s is not None and self._total is not None and self._squares is not None   # made by pathtrace()
        start = time.perf_counter()
        for first in range(self.spp, self.spp + spp, PASS_SPP):
            # in passes, so that Ctrl-C is heard between them (in_bands starts no band after it); each pixel
            # still adds its samples in order, so the sums are the same bytes as one pass
            count = min(PASS_SPP, self.spp + spp - first)
            in_bands(_render_rows, self.height, self.width, self.height, s.unproject, s.uniform, s.mats, s.textures,
                     s.light_tris, s.light_corners, s.light_cdf, s.light_pdf, s.background, self.max_depth,
                     self.rr_depth, np.uint64(self.seed), first, count, self._total, self._squares,
                     STRATEGIES.index(self.strategy), grain=1)
        self.spp += spp
        self.timings["trace"] = self.timings.get("trace", 0.0) + time.perf_counter() - start
        return self

    @property
    def image(self) -> np.ndarray:
        """Linear radiance, float32 [H, W, 3]: each pixel's mean over its samples (the box filter)."""
        assert self._total is not None
        return (self._total / max(self.spp, 1)).astype(np.float32)

    @property
    def variance(self) -> np.ndarray:
        """The variance of each pixel's mean, float32 [H, W, 3]: s²/n, s² the samples' unbiased variance.

        Its square root is the pixel's standard error; inf before there are 2 samples.
        """
        n = self.spp
        assert self._total is not None and self._squares is not None
        if n < 2:
            return np.full(self._total.shape, np.inf, np.float32)
        mean = self._total / n
        s2 = np.maximum(self._squares - n * mean * mean, 0.0) / (n - 1)
        return (s2 / n).astype(np.float32)

    def framebuffer(self, srgb: bool = False) -> Framebuffer:
        """The image in a one-sample framebuffer (alpha 1), for softpipe's 8-bit conversion and ``save``;
        ``srgb=True``: an sRGB framebuffer, whose bytes are encoded (FORMULAS §28)."""
        fb = Framebuffer(self.width, self.height, srgb=srgb)
        fb.color[..., :3] = self.image
        fb.color[..., 3] = 1.0
        return fb

    def path_story(self, x: int, y: int, sample: Optional[int] = None) -> PathStory:
        """The sampled paths through pixel (x, image row y), bounce by bounce, as the kernel traced them.

        Parameters
        ----------
        x, y : int
            The pixel (y counts image rows down from the top).
        sample : int, optional
            One sample (0 … MAX_SPP − 1, rendered yet or not); None: samples 0 … spp − 1.

        Returns
        -------
        PathStory
            A list of :class:`PathSample`, each with its :class:`Bounce` s: the same random
            numbers and the same float operations as the render, so each sample's ``value``
            is what it added to the pixel's sum, and ``total()`` of its bounces equals it.
        """
        if isinstance(x, bool) or isinstance(y, bool) or not isinstance(x, (int, np.integer)) or \
                not isinstance(y, (int, np.integer)) or not (0 <= x < self.width and 0 <= y < self.height):
            raise ValueError(f"path_story: pixel ({x!r}, {y!r}) is outside the {self.width}×{self.height} image")
        samples = range(self.spp) if sample is None else [_whole("sample", sample, 0, MAX_SPP - 1)]
        s = self._setup
        assert s is not None
        names = [o.name for o in s.scene.objects]
        record = np.empty((MAX_STORY_BOUNCES, STORY_COLUMNS))
        out = []
        for k in samples:
            record.fill(np.nan)
            record[:, 13:38] = 0.0
            record[:, 16] = 1.0
            record[:, 30] = -1.0
            record[:, 38] = _END_MORE
            value = _sample(int(x), int(y), k, self.width, self.height, s.unproject, s.uniform, s.mats, s.textures,
                            s.light_tris,
                            s.light_corners, s.light_cdf, s.light_pdf, s.background, self.max_depth, self.rr_depth,
                            np.uint64(self.seed), STRATEGIES.index(self.strategy), record)
            bounces = []
            for row in record:
                if np.isnan(row[0]):
                    break
                hit = int(row[0]) == _HIT
                obj, code = int(row[6]) if hit else -1, int(row[7]) if hit else -1
                lobe = "" if code < 0 else (_LOBES[code] or LOBE_NAMES[int(s.mats[obj, 18])])
                bounces.append(Bounce(
                    depth=int(row[1]), object=names[obj] if hit else "", triangle=int(row[5]) if hit else -1,
                    point=tuple(row[2:5]) if hit else (), lobe=lobe, direction=tuple(row[35:38]) if lobe else (),
                    f=tuple(row[8:11]) if lobe else (), cos=float(row[11]) if lobe else 0.0,
                    pdf=float(row[12]) if lobe else 0.0, throughput=tuple(row[13:16]), roulette=float(row[16]),
                    emitted=tuple(row[18:21]), emission_weight=float(row[21]),
                    light=int(row[30]), nee=_NEE[0 if int(row[30]) == -1 else int(row[31])],
                    nee_lambert=tuple(row[22:25]), nee_lambert_weight=float(row[28]), nee_glossy=tuple(row[25:28]),
                    nee_glossy_weight=float(row[29]), background=tuple(row[32:35]), end=_ENDS[int(row[38])]))
            truncated = len(bounces) == MAX_STORY_BOUNCES and not bounces[-1].end
            out.append(PathSample(k, tuple(float(v) for v in value), bounces, truncated))
        return PathStory(int(x), int(y), out)

    def save(self, file, **kw) -> None:
        """Save as an image through :meth:`Framebuffer.save` (its one conversion to 8 bits)."""
        self.framebuffer().save(file, **kw)


def pathtrace(scene, spp: int = 64, seed: int = 0, *, camera: Optional[Camera] = None, max_depth: int = -1,
              rr_depth: int = 5, strategy: str = "mis", background_light: bool = False) -> PathTrace:
    """Path trace ``scene`` (docs/pathtracing.md): ``spp`` samples per pixel, deterministic per ``seed``.

    Parameters
    ----------
    scene : Scene
        As :func:`softpipe.render_scene` takes it: its objects (with the ground, if
        set), camera, size and background (the radiance of every ray that leaves).
    spp : int
        Samples per pixel, 1 … :data:`MAX_SPP`; :meth:`PathTrace.add` renders more.
    seed : int
        0 … 2⁶⁴ − 1: the image is a function of the seed (and not of the thread count).
    camera : Camera, optional
        Instead of the scene's (or its framing).
    max_depth : int
        The longest path, counted as Mitsuba's path integrator counts it: 1 sees
        emitters only, 2 adds direct light, …; −1 (the default): no limit but
        Russian roulette.
    rr_depth : int
        The bounce (≥ 1) from which Russian roulette may end a path.
    strategy : str
        "mis" (the default): next-event estimation and BSDF sampling weighted by the
        power heuristic; "bsdf": the sampled directions alone (no light sample);
        "light": the light sample alone wherever one is taken (a light that a
        sampled direction hits counts only after a mirror or glass bounce, or seen
        directly). All three estimate the same image; the last two are noisier, and
        comparing them checks that the lobes' densities match their sampling.
    background_light : bool
        Also sample the background as a light: a light sample goes to it with
        probability ∝ its power beside the emissive triangles', drawing a direction
        ∝ cos θ about the normal, weighted by MIS against the lobes like any light
        sample (a drawn direction that leaves the scene is weighted against it). The
        same image in expectation; less noise where what hides the sky is much darker
        than it, more where it is about as bright (docs/pathtracing.md, "The
        background as a light"). False (the default): the background is found only by
        the paths that leave the scene.

    Returns
    -------
    PathTrace
        ``.image`` (linear radiance, float32 [H, W, 3]), ``.variance``, ``.spp``, ``.add(n)``.
    """
    seed = _whole("seed", seed, 0, 2 ** 64 - 1)
    max_depth = _whole("max_depth", max_depth, -1)
    rr_depth = _whole("rr_depth", rr_depth, 1)
    spp = _whole("spp", spp, 1, MAX_SPP)
    if strategy not in STRATEGIES:
        raise ValueError(f"pathtrace: strategy must be one of {', '.join(map(repr, STRATEGIES))}, got {strategy!r}")
    if not isinstance(background_light, (bool, np.bool_)):
        raise ValueError(f"pathtrace: background_light must be True or False, got {background_light!r}")
    start = time.perf_counter()
    camera = camera or scene.view_camera()
    notes: List[str] = []
    s = _setup(scene, camera, notes, bool(background_light))
    h, w = scene.height, scene.width
    result = PathTrace(seed, w, h, max_depth, rr_depth, notes, strategy, {"setup": time.perf_counter() - start},
                       background_light=bool(background_light), _setup=s, _total=np.zeros((h, w, 3)), _squares=np.zeros((h, w, 3)))
    return result.add(spp)
