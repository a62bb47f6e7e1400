"""Cube maps, and mirrors and glass in the rasterizer (issue #17; FORMULAS §16–§20).

* Seams: a constant environment samples to its color exactly, on a dense set of
  directions along every face edge and corner, at every level of detail, with
  every filter.
* Orientation: GL's table (restated here, not imported): the six face colors come
  back along ±x, ±y, ±z, and a texel comes back in the direction the table gives
  its (s, t); filtering is continuous across every edge.
* from_equirectangular: a smooth function round trips within a stated tolerance.
* reflect / refract on random vectors: §16's mirror, Snell (§17) with |T| = 1 and T
  in the plane of incidence, §18's form, TIR exactly beyond the critical angle.
* The programs: a mirror sphere under an orthographic camera returns the map's
  texel in the mirror direction (N from the sphere's geometry, R and the lookup
  computed here); a flat mirror does so to float32 rounding; glass mixes by
  ``softpipe.light.lighting.fresnel``; TIR sends everything to reflection.
* render_cube_map: boxes around a point show in the faces they should, at the
  (s, t) GL's table gives.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import env_function

import softpipe as sp
from softpipe.language.glsl import reflect, refract
from softpipe.light.cubemap import (
    FACES,
    MEDIA,
    CubeMap,
    face_coordinates,
    sky,
    sky_gradient,
    texture_cube,
    texture_cube_lod,
)
from softpipe.light.lighting import fresnel
from softpipe.light.material import Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import orthographic, rotate, translate
from softpipe.programs.environment import glass_weights
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.environment_pass import fill_background, render_cube_map
from softpipe.scenes.scene import SceneObject

RNG = np.random.default_rng(17)
DARK = Lighting([], global_ambient=(0.0, 0.0, 0.0))

# GL 4.6 Table 8.19, restated: face → (sc, tc, ma) as functions of (x, y, z)
GL_TABLE = {
    "+x": lambda x, y, z: (-z, -y, x), "-x": lambda x, y, z: (z, -y, x),
    "+y": lambda x, y, z: (x, z, y), "-y": lambda x, y, z: (x, -z, y),
    "+z": lambda x, y, z: (x, -y, z), "-z": lambda x, y, z: (-x, -y, z),
}
AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}


def gl_st(face, d):
    sc, tc, ma = GL_TABLE[face](*d)
    return 0.5 * (sc / abs(ma) + 1.0), 0.5 * (tc / abs(ma) + 1.0)


def gl_direction(face, s, t):
    """The direction through (s, t) of a face, solved from GL_TABLE by brute force over the three axes."""
    a = np.array(AXES[face], np.float64)
    sc, tc = 2 * s - 1, 2 * t - 1
    # the two other axes: find unit vectors u, v with GL_TABLE giving sc = u·d, tc = v·d on this face
    basis = np.eye(3)
    u = np.array([GL_TABLE[face](*e)[0] for e in basis], np.float64)
    v = np.array([GL_TABLE[face](*e)[1] for e in basis], np.float64)
    return a + sc * u + tc * v


def edge_directions(n=33, eps=(0.0, 1e-7, 1e-3)):
    """Directions along every edge of the cube and through every corner, a little to either side."""
    out = []
    ts = np.linspace(-1.0, 1.0, n)
    for i in range(3):                       # edges parallel to axis i
        j, k = [a for a in range(3) if a != i]
        for sj in (-1.0, 1.0):
            for sk in (-1.0, 1.0):
                for e_j in eps:
                    for e_k in eps:
                        d = np.zeros((n, 3))
                        d[:, i] = ts
                        d[:, j] = sj * (1.0 - e_j)
                        d[:, k] = sk * (1.0 - e_k)
                        out.append(d)
    corners = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    out.append(corners)
    out.append(corners * (1.0, 1.0 - 1e-9, 1.0 + 1e-9))
    return np.concatenate(out)


# ------------------------------------------------------------------------- seams

@pytest.mark.parametrize("filter", ["nearest", "bilinear", "nearest_mipmap", "trilinear"])
@pytest.mark.parametrize("size", [8, 5, 1])
def test_a_constant_environment_samples_to_its_color_exactly_across_every_edge_corner_and_level(filter, size):
    color = (0.3, 0.7, 0.123456, 0.9)
    c32 = tuple(float(np.float32(v)) for v in color)
    cube = CubeMap([np.full((size, size, 4), color, np.float32)] * 6, filter=filter)
    d = np.concatenate([edge_directions(), RNG.normal(size=(2000, 3))])
    for lod in (0.0, 0.25, 0.5, 1.0, 1.7, cube.num_levels - 1, 50.0):
        out = cube.sample_many(d, lod)
        assert np.all(out == np.array(c32)), (filter, size, lod, np.unique(out, axis=0)[:4])


def test_filtering_is_continuous_across_every_edge():
    """A smooth environment: just on one side of an edge and just on the other give nearly the same color."""
    cube = CubeMap.from_function(lambda d: 0.5 + 0.5 * np.sin(3.0 * d + 1.0), 16)
    for eps in (1e-6,):
        for lod in (0.0, 1.5):
            ts = np.linspace(-0.999, 0.999, 41)
            for i in range(3):
                j, k = [a for a in range(3) if a != i]
                for sj in (-1, 1):
                    for sk in (-1, 1):
                        a = np.zeros((len(ts), 3))
                        a[:, i], a[:, j], a[:, k] = ts, sj * 1.0, sk * (1.0 - eps)    # on face j
                        b = a.copy()
                        b[:, j], b[:, k] = sj * (1.0 - eps), sk * 1.0                 # on face k
                        assert not np.array_equal(face_coordinates(a)[0], face_coordinates(b)[0])
                        jump = np.abs(cube.sample_many(a, lod) - cube.sample_many(b, lod)).max()
                        assert jump < 1e-4, (i, sj, sk, lod, jump)


# ------------------------------------------------------------------------- orientation

FACE_COLORS = [(0.9, 0.1, 0.1), (0.1, 0.9, 0.9), (0.1, 0.9, 0.1), (0.9, 0.1, 0.9), (0.1, 0.1, 0.9), (0.9, 0.9, 0.1)]


def test_each_axis_reads_its_face_in_gl_order():
    cube = CubeMap([np.full((4, 4, 3), c, np.float32) for c in FACE_COLORS], filter="bilinear")
    for k, face in enumerate(FACES):
        got = cube.sample(AXES[face])
        np.testing.assert_array_equal(got[:3], np.float32(FACE_COLORS[k]))
        assert got[3] == 1.0


def test_the_texel_in_a_direction_is_the_one_gl_table_gives():
    n = 8
    faces = RNG.random((6, n, n, 4)).astype(np.float32)
    cube = CubeMap(list(faces), filter="nearest")
    for k, face in enumerate(FACES):
        for _ in range(40):
            s, t = RNG.uniform(0.02, 0.98, size=2)
            d = gl_direction(face, s, t) * RNG.uniform(0.1, 10.0)
            assert gl_st(face, d) == pytest.approx((s, t), abs=1e-12)
            f, s2, t2 = face_coordinates(d)
            assert FACES[int(f)] == face and (float(s2), float(t2)) == pytest.approx((s, t), abs=1e-12)
            row, col = int(t * n), int(s * n)            # row 0 is the image's top row: t = 0
            np.testing.assert_array_equal(cube.sample(d), faces[k, row, col])
            np.testing.assert_allclose(CubeMap.direction(face, s, t), d / np.linalg.norm(d), atol=1e-12)
    # bilinear: at a texel's centre, that texel exactly
    cube = CubeMap(list(faces), filter="bilinear")
    for k, face in enumerate(FACES):
        row, col = 2, 5
        d = gl_direction(face, (col + 0.5) / n, (row + 0.5) / n)
        np.testing.assert_allclose(cube.sample(d), faces[k, row, col], atol=1e-6)


def test_mip_levels_are_box_averages_and_trilinear_mixes_them():
    faces = RNG.random((6, 8, 8, 4)).astype(np.float32)
    cube = CubeMap(list(faces))
    assert cube.num_levels == 4 and cube.levels[1].shape == (6, 4, 4, 4)
    np.testing.assert_allclose(cube.levels[1][2, 1, 3], faces[2, 2:4, 6:8].mean(axis=(0, 1)), atol=1e-6)
    d = gl_direction("+y", 0.3, 0.6)
    a, b = np.array(cube.sample(d, 1.0)), np.array(cube.sample(d, 2.0))
    np.testing.assert_allclose(cube.sample(d, 1.25), 0.75 * a + 0.25 * b, atol=1e-6)
    np.testing.assert_allclose(cube.levels[3][2, 0, 0], faces[2].mean(axis=(0, 1)), atol=1e-6)   # 1×1: the mean


def test_zero_and_nan_directions_are_defined():
    cube = CubeMap([np.full((2, 2, 3), c, np.float32) for c in FACE_COLORS])
    for d in ((0.0, 0.0, 0.0), (math.nan, 1.0, 0.0), (math.inf, 0.0, 0.0)):
        assert np.all(np.isfinite(cube.sample(d)))


def test_bad_faces_are_refused():
    with pytest.raises(ValueError, match="six faces"):
        CubeMap([np.zeros((4, 4, 3), np.float32)] * 5)
    with pytest.raises(ValueError, match="square"):
        CubeMap([np.zeros((4, 4, 3), np.float32)] * 5 + [np.zeros((4, 2, 3), np.float32)])


def test_texture_cube_compiles_inside_a_jitted_function():
    from numba import njit

    @njit
    def look(cube, d):
        return texture_cube(cube, d), texture_cube_lod(cube, d, 1.0)

    cube = CubeMap([np.full((4, 4, 3), c, np.float32) for c in FACE_COLORS])
    a, b = look(cube.__softpipe_uniform__(), (0.0, -2.0, 0.1))
    assert a[:3] == pytest.approx(FACE_COLORS[3]) and b[:3] == pytest.approx(FACE_COLORS[3])


# ------------------------------------------------------------------------- equirectangular

def smooth(d):
    return np.stack([0.5 + 0.4 * d[..., 0], 0.5 + 0.3 * d[..., 1] * d[..., 2], 0.5 + 0.4 * d[..., 1]], -1)


def test_from_equirectangular_round_trips_a_smooth_function():
    """Tolerance 0.01: two bilinear resamplings (panorama 512×256, faces 64²) of a function of slope ≤ 0.4."""
    h, w = 256, 512
    theta = (np.arange(h) + 0.5) / h * np.pi                  # from +y down
    phi = ((np.arange(w) + 0.5) / w - 0.5) * 2.0 * np.pi      # atan2(x, −z)
    T, F = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(T) * np.sin(F), np.cos(T), -np.sin(T) * np.cos(F)], -1)
    cube = CubeMap.from_equirectangular(smooth(d).astype(np.float32))
    assert cube.size == 128
    cube = CubeMap.from_equirectangular(smooth(d).astype(np.float32), size=64)
    q = RNG.normal(size=(5000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    err = np.abs(cube.sample_many(q)[:, :3] - smooth(q)).max()
    assert err < 0.01, err
    # the centre of the panorama looks along −z, a quarter to the right along +x, the top row up
    pano = np.zeros((h, w, 3), np.float32)
    pano[:, w // 2 - 8:w // 2 + 8, 0] = 1.0
    pano[:, 3 * w // 4 - 8:3 * w // 4 + 8, 1] = 1.0
    pano[:8, :, 2] = 1.0
    cube = CubeMap.from_equirectangular(pano, size=32)
    assert cube.sample((0, 0, -1))[:3] == (1.0, 0.0, 0.0)
    assert cube.sample((1, 0, 0))[:3] == (0.0, 1.0, 0.0)
    assert cube.sample((0, 1, 0))[2] == 1.0


# ------------------------------------------------------------------------- reflect and refract

def random_unit(k):
    v = RNG.normal(size=(k, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_reflect_on_random_vectors_is_the_mirror_direction():
    for N, V in zip(random_unit(200), random_unit(200)):
        R = np.array(reflect(tuple(-V), tuple(N)))
        np.testing.assert_allclose(R, 2 * N.dot(V) * N - V, atol=1e-14)           # §16
        assert np.linalg.norm(R) == pytest.approx(1.0, abs=1e-14)
        assert R.dot(N) == pytest.approx(V.dot(N), abs=1e-14)                        # equal angles
        assert np.linalg.det(np.array([N, V, R])) == pytest.approx(0.0, abs=1e-13)  # one plane


@pytest.mark.parametrize("medium", sorted(MEDIA))
def test_refract_on_random_vectors_obeys_snell_both_ways(medium):
    for n1, n2 in ((1.0, MEDIA[medium]), (MEDIA[medium], 1.0)):
        eta = n1 / n2
        for N, V in zip(random_unit(100), random_unit(100)):
            if N.dot(V) < 0:
                N = -N                                     # N on V's side
            c1 = N.dot(V)
            T = np.array(refract(tuple(-V), tuple(N), eta))
            sin2_t = eta * eta * (1 - c1 * c1)
            if sin2_t > 1.0:
                assert tuple(T) == (0.0, 0.0, 0.0)           # §19
                continue
            assert np.linalg.norm(T) == pytest.approx(1.0, abs=1e-13)                # |T| = 1
            sin_i = math.sqrt(max(0.0, 1 - c1 * c1))
            sin_t = np.linalg.norm(np.cross(T, -N))
            assert n1 * sin_i == pytest.approx(n2 * sin_t, abs=1e-12)                 # §17
            assert T.dot(N) < 0 or c1 == 0                                            # goes through
            assert np.linalg.det(np.array([N, V, T])) == pytest.approx(0.0, abs=1e-12)
            c2 = math.sqrt(1 - sin2_t)
            np.testing.assert_allclose(T, (eta * c1 - c2) * N - eta * V, atol=1e-13)  # §18


@pytest.mark.parametrize("n1,n2", [(1.52, 1.0), (1.33, 1.0), (2.417, 1.0), (2.417, 1.52)])
def test_total_internal_reflection_exactly_beyond_the_critical_angle(n1, n2):
    critical = math.asin(n2 / n1)
    N = (0.0, 0.0, 1.0)
    for theta, tir in ((critical * (1 - 1e-9), False), (critical * (1 + 1e-9), True),
                       (critical - 1e-6, False), (critical + 1e-6, True), (math.radians(89.0), True)):
        V = (math.sin(theta), 0.0, math.cos(theta))
        T = refract((-V[0], -V[1], -V[2]), N, n1 / n2)
        assert (T == (0.0, 0.0, 0.0)) == tir, (n1, n2, math.degrees(theta))
        R, T2, F = glass_weights(N, V, n1, n2)
        if tir:
            assert F == 1.0 and T2 == (0.0, 0.0, 0.0)
        else:
            assert F < 1.0 and abs(np.linalg.norm(T2) - 1.0) < 1e-9
        assert F == pytest.approx(fresnel(V[2], n1, n2), abs=1e-15)


def test_the_named_media_are_the_notes_indices():
    assert MEDIA == {"vacuum": 1.0, "air": 1.00029, "water": 1.33, "glass": 1.52, "salt": 1.54,
                     "sapphire": 1.77, "diamond": 2.417}


# ------------------------------------------------------------------------- the programs

SIZE = 64
EXTENT = 1.25
CAMERA = Camera(eye=(3.0, 2.0, 4.0), target=(0.0, 0.0, 0.0))      # turned: the world → eye rotation matters


def draw_sphere(program, material, environment, **uniforms):
    sphere = shapes.uv_sphere(radius=1.0, segments=96, rings=48, material=material)
    fb = sp.Framebuffer(SIZE, SIZE).clear((0.0, 0.0, 0.0, 1.0))
    u = {"projection": orthographic(-EXTENT, EXTENT, -EXTENT, EXTENT, 1.0, 10.0), "environment": environment}
    u.update(uniforms)
    draw_mesh(fb, sphere, CAMERA, program, lighting=DARK, uniforms=u)
    return fb.color


def sphere_pixels(max_radius=0.85, neighbours=False):
    """(row, col, N_eye) of pixels whose centre sees the unit sphere within ``max_radius`` of its middle; with
    ``neighbours``, (row, col, N_eye, [N_eye one pixel right, N_eye one pixel up])."""
    centre = (CAMERA.view @ [0.0, 0.0, 0.0, 1.0])[:3]
    step = 2 * EXTENT / SIZE
    out = []
    for r in range(1, SIZE, 3):
        for c in range(1, SIZE, 3):
            x = ((c + 0.5) / SIZE * 2 - 1) * EXTENT - centre[0]
            y = ((SIZE - 1 - r + 0.5) / SIZE * 2 - 1) * EXTENT - centre[1]
            if x * x + y * y < max_radius ** 2:
                normal = [np.array([u, v, math.sqrt(1 - u * u - v * v)]) for u, v in ((x, y), (x + step, y),
                                                                                    (x, y + step))]
                out.append((r, c, normal[0], normal[1:]) if neighbours else (r, c, normal[0]))
    return out


def level_of_detail(d, neighbours, size):
    """GL's λ for a cube map lookup (4.6 §8.14.1, ρ = size · max |Δ(s, t)| per pixel step), by differences of
    the face coordinates of d and of d at the neighbouring pixels; None where they straddle two faces."""
    faces, s, t = face_coordinates(np.array([d, *neighbours]))
    if len(set(faces.tolist())) > 1:
        return None
    rho = size * max(math.hypot(s[k] - s[0], t[k] - t[0]) for k in (1, 2))
    return max(math.log2(rho), 0.0)


def to_world(d):
    return CAMERA.view[:3, :3].T @ d


# The sphere is 96 × 48 quads: an interpolated normal is off the sphere's by up to ~1e-3 radians,
# and the environment changes by at most 0.45·|Δd| per unit: 2e-3 covers it with room to spare.
FILTERING = 2e-3


def test_a_mirror_sphere_returns_the_maps_texel_in_the_mirror_direction(environment):
    """At the level of detail GL would take: R's change to the next pixel, in texels of the face (computed here
    from the sphere's normals at the neighbouring pixel centres), picks the mip level (§16; GL 4.6 §8.14.1)."""
    color = draw_sphere("mirror", Material(ka=0.0, kd=0.0, ks=0.0, kr=(1.0, 0.8, 0.6)), environment)
    pixels = sphere_pixels(neighbours=True)
    assert len(pixels) > 100
    V = np.array([0.0, 0.0, 1.0])                     # orthographic: every view ray along −z
    levels = []
    for r, c, N, near in pixels:
        R = to_world(2 * N.dot(V) * N - V)             # §16, in world space
        Rs = [to_world(2 * n.dot(V) * n - V) for n in near]
        lod = level_of_detail(R, Rs, environment.size)
        if lod is None:
            continue
        levels.append(lod)
        texel = np.array(environment.sample(R, lod))[:3] * (1.0, 0.8, 0.6)
        np.testing.assert_allclose(color[r, c, :3], texel, atol=FILTERING)
        if lod < 2.0:       # coarser levels average the function over 4+ texels: no longer its point value
            np.testing.assert_allclose(color[r, c, :3], env_function(R) * (1.0, 0.8, 0.6), atol=FILTERING + 3e-3)
    assert len(levels) > 100 and min(levels) > 1.0 and max(levels) > 2.5     # the rim turns R fastest
    assert np.all(color[0, 0] == (0.0, 0.0, 0.0, 1.0))


def test_the_level_of_detail_is_the_faces_texels_crossed_per_pixel():
    """cube_level_of_detail against the texels counted here: a step of δ across the middle of face +z moves s by
    δ/2, so ρ = size·δ/2; along a face's diagonal the step is worked out by differences of its coordinates."""
    from softpipe.light.cubemap import cube_level_of_detail
    cube = CubeMap.from_function(env_function, 64).__softpipe_uniform__()
    for delta in (1 / 32, 1 / 8, 1 / 2):
        assert cube_level_of_detail(cube, (0.0, 0.0, 1.0), (delta, 0.0, 0.0), (0.0, 0.0, 0.0)) == \
            pytest.approx(math.log2(64 * delta / 2), abs=1e-12)
    d, dx, dy = np.array([0.3, -0.4, 1.0]), np.array([1e-4, 2e-5, 0.0]), np.array([0.0, 1e-4, -3e-5])
    expected = level_of_detail(d, [d + dx, d + dy], 64)
    assert cube_level_of_detail(cube, tuple(d), tuple(dx), tuple(dy)) == pytest.approx(
        math.log2(64 * max(np.hypot(*np.subtract(face_coordinates(d + e)[1:], face_coordinates(d)[1:]))
                           for e in (dx, dy))), abs=1e-3)
    assert expected == 0.0                               # such small steps magnify: level 0
    assert cube_level_of_detail(cube, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)) == -math.inf


def test_a_flat_mirror_returns_the_texel_to_float32_rounding(environment):
    """A plane's normal is exact everywhere, so R is too: only the float32 framebuffer rounds."""
    model = rotate(35.0, (1.0, 0.3, 0.0)) @ rotate(90.0, (1.0, 0.0, 0.0))
    camera = Camera(eye=(0.5, 0.3, 4.0), target=(0.0, 0.0, 0.0))
    mirror = shapes.plane(2.0, material=Material(ka=0.0, kd=0.0, ks=0.0, kr=(1.0, 1.0, 1.0)))
    fb = sp.Framebuffer(16, 16).clear((0.0, 0.0, 0.0, 0.0))
    draw_mesh(fb, mirror, camera, "mirror", model=model, lighting=DARK, cull="none",
              uniforms={"projection": orthographic(-1, 1, -1, 1, 1.0, 10.0), "environment": environment})
    N = model[:3, :3] @ np.array([0.0, 1.0, 0.0])
    V = camera.view[:3, :3].T @ np.array([0.0, 0.0, 1.0])       # toward the eye, world space
    if N.dot(V) < 0:
        N = -N
    R = 2 * N.dot(V) * N - V
    expected = np.float32(environment.sample(R)[:3])
    covered = fb.color[..., 3] > 0
    assert covered.sum() > 50
    np.testing.assert_allclose(fb.color[covered][:, :3], np.broadcast_to(expected, (covered.sum(), 3)), rtol=2e-7)
    # without an environment uniform: the built-in sky, in the same direction
    fb.clear((0.0, 0.0, 0.0, 0.0))
    draw_mesh(fb, mirror, camera, "mirror", model=model, lighting=DARK, cull="none",
              uniforms={"projection": orthographic(-1, 1, -1, 1, 1.0, 10.0)})
    expected = np.float32(sky(tuple(R)))
    for d in RNG.normal(size=(50, 3)):
        assert sky(tuple(d)) == pytest.approx(tuple(sky_gradient(d)), abs=1e-12)
    np.testing.assert_allclose(fb.color[covered][:, :3], np.broadcast_to(expected, (covered.sum(), 3)), rtol=2e-7)


def glass_directions(N, V, n1, n2):
    """(R, T) in world space for an eye-space N, V from n1 into n2 (§16, §18); T None on TIR (§19)."""
    c1 = N.dot(V)
    eta = n1 / n2
    R = to_world(2 * c1 * N - V)
    if eta * eta * (1 - c1 * c1) > 1:
        return R, None
    return R, to_world((eta * c1 - math.sqrt(1 - eta * eta * (1 - c1 * c1))) * N - eta * V)


def sampled(environment, d, d_near):
    """The environment in world direction d at the level of detail of d at the neighbouring pixels, and a
    quarter level either side, [3, RGB]; None if those straddle two faces. (λ here comes from the sphere's own
    normals, the shader's from the mesh's interpolated ones: near the rim, where a face is a few texels wide at
    λ ≈ 3, they differ by a tenth of a level.)"""
    lod = level_of_detail(d, d_near, environment.size)
    if lod is None:
        return None
    return np.array([environment.sample(d, max(lod + k, 0.0))[:3] for k in (-0.25, 0.0, 0.25)])


def assert_within(color, candidates, atol=FILTERING):
    """color lies, per channel, within the range of the candidate colors [k, 3], ± atol."""
    lo, hi = candidates.min(axis=0) - atol, candidates.max(axis=0) + atol
    assert np.all((lo <= color) & (color <= hi)), (color, candidates)


def test_glass_mixes_reflection_and_refraction_by_fresnel(environment):
    kt = (0.9, 0.8, 0.7)
    glass = Material(ka=0.0, kd=0.0, ks=0.0, kt=kt, ior=MEDIA["glass"])
    color = draw_sphere("glass", glass, environment)
    V = np.array([0.0, 0.0, 1.0])
    weights = []
    for r, c, N, near in sphere_pixels(neighbours=True):
        F = fresnel(N.dot(V), 1.0, MEDIA["glass"])
        R, T = glass_directions(N, V, 1.0, MEDIA["glass"])
        R_near, T_near = zip(*(glass_directions(n, V, 1.0, MEDIA["glass"]) for n in near))
        reflected, refracted = sampled(environment, R, R_near), sampled(environment, T, T_near)
        if reflected is None or refracted is None:
            continue
        np.testing.assert_allclose(color[r, c, :3], F * reflected[1] + (1 - F) * np.array(kt) * refracted[1],
                                   atol=FILTERING)
        weights.append(F)
    assert len(weights) > 100
    assert min(weights) == pytest.approx(0.0426, abs=2e-3)      # ((1 − 1.52)/(1 + 1.52))² near the middle
    assert max(weights) > 0.06


def test_glass_sends_everything_to_reflection_beyond_the_critical_angle(environment):
    """An air bubble seen from water: η = 1.33 > 1, so TIR outside the cone c₁ < √(1 − 1/1.33²) ≈ 0.659."""
    bubble = Material(ka=0.0, kd=0.0, ks=0.0, kt=(1.0, 1.0, 1.0), ior=MEDIA["vacuum"])
    color = draw_sphere("glass", bubble, environment, outside_ior=MEDIA["water"])
    V = np.array([0.0, 0.0, 1.0])
    critical_c1 = math.sqrt(1 - 1 / MEDIA["water"] ** 2)
    inside = outside = 0
    for r, c, N, near in sphere_pixels(0.95, neighbours=True):
        c1 = N.dot(V)
        R, T = glass_directions(N, V, MEDIA["water"], 1.0)
        R_near, T_near = zip(*(glass_directions(n, V, MEDIA["water"], 1.0) for n in near))
        reflected = sampled(environment, R, R_near)
        if reflected is None:
            continue
        if c1 < critical_c1 - 0.02:                        # TIR: the reflection alone, at full strength
            assert T is None
            assert_within(color[r, c, :3], reflected)
            outside += 1
        elif c1 > critical_c1 + 0.1:                       # (F_R is steep just inside the critical cone)
            F = fresnel(c1, MEDIA["water"], 1.0)
            assert F < 1.0
            refracted = sampled(environment, T, T_near)
            if refracted is None:
                continue
            assert_within(color[r, c, :3], (F * reflected[:, None] + (1 - F) * refracted[None, :]).reshape(-1, 3))
            inside += 1
    assert inside > 20 and outside > 20


def test_the_programs_need_the_view_uniform_and_say_so(environment):
    from softpipe.programs import get_program
    prog = get_program("mirror")
    fb = sp.Framebuffer(8, 8)
    pos = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    uniforms = {"model_view": np.eye(4), "projection": np.eye(4), "normal_matrix": np.eye(3),
                "material": Material(kr=(1.0, 1.0, 1.0)), "lighting": DARK.uniform(np.eye(4)),
                "environment": environment}
    with pytest.raises(sp.ShaderError, match="view"):
        sp.DrawCall(fb, pos, np.array([[0, 1, 2]]), None, prog.vertex, prog.fragment, uniforms,
                    attributes={"normal": np.tile([0.0, 0.0, 1.0], (3, 1))}).run()


# ------------------------------------------------------------------------- the dynamic cube map

def emitter(color):
    return Material(ka=0.0, kd=0.0, ks=0.0, ke=color)


def test_render_cube_map_shows_each_box_in_its_face_at_gl_coordinates():
    P = np.array([0.3, -0.2, 0.5])
    objects = [SceneObject(f"box {face}", shapes.cube(1.0, material=emitter(FACE_COLORS[k])),
                           translate(*(P + 3.0 * np.array(AXES[face])))) for k, face in enumerate(FACES)]
    # on each face a white marker toward (s, t) = (0.25, 0.25): the upper left of the stored image
    markers = {face: gl_direction(face, 0.25, 0.25) for face in FACES}
    for face, d in markers.items():
        objects.append(SceneObject(f"marker {face}", shapes.cube(0.5, material=emitter((1.0, 1.0, 1.0))),
                                   translate(*(P + 3.0 * d))))
    objects.append(SceneObject("mirror", shapes.uv_sphere(0.5, material=emitter((0.0, 0.0, 0.0))), translate(*P)))
    n = 16
    cube = render_cube_map(objects, P, n, lighting=DARK, background=(0.2, 0.2, 0.2, 1.0), filter="bilinear",
                           exclude=("mirror",))
    assert cube.size == n and cube.num_levels == 5
    for k, face in enumerate(FACES):
        image = cube.levels[0][k]
        np.testing.assert_array_equal(image[n // 2, n // 2, :3], np.float32(FACE_COLORS[k]))   # the box ahead
        np.testing.assert_array_equal(image[n // 4, n // 4, :3], (1.0, 1.0, 1.0))              # the marker
        for corner in (image[0, n - 1], image[n - 1, 0], image[n - 1, n - 1]):                  # the background
            np.testing.assert_array_equal(corner[:3], np.float32((0.2, 0.2, 0.2)))
        assert cube.sample(AXES[face])[:3] == pytest.approx(FACE_COLORS[k], abs=1e-6)


def test_render_cube_map_fills_the_empty_texels_from_a_sky_and_fill_background_paints_it():
    sky = CubeMap.from_function(env_function, 16, filter="bilinear")
    ball = SceneObject("ball", shapes.uv_sphere(0.5, material=emitter((1.0, 0.0, 0.0))), translate(2.0, 0.0, 0.0))
    cube = render_cube_map([ball], (0.0, 0.0, 0.0), 16, lighting=DARK, background=sky, filter="bilinear")
    assert cube.sample((1.0, 0.0, 0.0))[:3] == (1.0, 0.0, 0.0)
    for d in ((-1.0, 0.2, 0.1), (0.0, 1.0, 0.0), (0.1, -0.3, -1.0)):
        assert cube.sample(d) == pytest.approx(sky.sample(d), abs=1e-6)
    camera = Camera(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fovy=60.0)
    fb = sp.Framebuffer(12, 8).clear((0.0, 0.0, 0.0, 1.0))
    fill_background(fb, camera, sky)
    # the pixel at the picture's middle looks along −z; the top row's middle looks up by fovy/2 (less half a pixel)
    up = math.tan(math.radians(30.0)) * (1 - 1 / 8)
    np.testing.assert_allclose(fb.color[0, 6, :3], np.array(sky.sample((0.5 / 6 * math.tan(math.radians(30)) * 1.5,
                                                                         up, -1.0)))[:3], atol=1e-6)


def test_dynamic_environments_make_a_map_per_mirror_and_render_with_environments_uses_it():
    from softpipe.scenes.environment_pass import dynamic_environments, render_with_environments
    from softpipe.scenes.scene import Scene
    box = SceneObject("box", shapes.cube(1.0, material=emitter((1.0, 0.5, 0.0))), translate(3.0, 0.0, 0.0))
    ball = SceneObject("ball", shapes.uv_sphere(0.5, 32, 16, material=Material(ka=0.0, kd=0.0, ks=0.0, kr=1.0)),
                       np.eye(4), program="mirror")
    scene = Scene([box, ball], camera=Camera(eye=(0.0, 0.0, 4.0)), lights=(), ambient=(0.0, 0.0, 0.0),
                  width=24, height=24, background=(0.1, 0.2, 0.3, 1.0))
    maps = dynamic_environments(scene, 8, filter="bilinear")
    assert set(maps) == {"ball"}
    assert maps["ball"].sample((1.0, 0.0, 0.0))[:3] == pytest.approx((1.0, 0.5, 0.0), abs=1e-6)   # the box
    assert maps["ball"].sample((-1.0, 0.0, 0.0))[:3] == pytest.approx((0.1, 0.2, 0.3), abs=1e-6)  # background
    fb = render_with_environments(scene, maps)
    # the ball's middle faces the camera: it reflects straight back, +z, where the map holds the background
    np.testing.assert_allclose(fb.color[12, 12, :3], (0.1, 0.2, 0.3), atol=1e-3)


def test_faces_from_image_files_8_bit_in_gl_order(tmp_path):
    from PIL import Image
    paths = []
    for k, face in enumerate(FACES):
        pixels = np.zeros((4, 4, 3), np.uint8)
        pixels[...] = np.round(np.array(FACE_COLORS[k]) * 255).astype(np.uint8)
        pixels[0, 0] = (255, 255, 255)                   # the file's top-left pixel: (s, t) near (0, 0)
        Image.fromarray(pixels).save(tmp_path / f"{face}.png")
        paths.append(tmp_path / f"{face}.png")
    cube = CubeMap(paths, filter="nearest")
    for k, face in enumerate(FACES):
        assert cube.sample(AXES[face])[:3] == pytest.approx(np.round(np.array(FACE_COLORS[k]) * 255) / 255)
        assert cube.sample(gl_direction(face, 0.1, 0.1))[:3] == (1.0, 1.0, 1.0)
