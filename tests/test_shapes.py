"""Generated meshes: counts, outward winding, analytic normals (FORMULAS §25), uvs, speed."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from softpipe.scenes import shapes
from softpipe.scenes.mesh import Mesh

CLOSED = {
    "cube": (lambda: shapes.cube(2.0), 8.0),
    "uv_sphere": (lambda: shapes.uv_sphere(1.0, 64, 32), 4 / 3 * math.pi),
    "icosphere": (lambda: shapes.icosphere(1.0, 3), 4 / 3 * math.pi),
    "cylinder": (lambda: shapes.cylinder(1.0, 2.0, 64), 2 * math.pi),
    "cone": (lambda: shapes.cone(1.0, 2.0, 64), 2 * math.pi / 3),
    "torus": (lambda: shapes.torus(1.0, 0.25, 64, 32), 2 * math.pi**2 * 0.25**2),
}


@pytest.mark.parametrize("name", sorted(CLOSED))
def test_closed_generators_wind_outward(name):
    make, volume = CLOSED[name]
    mesh = make()
    # Positive signed volume: counter-clockwise seen from outside; near the true volume.
    assert mesh.signed_volume() == pytest.approx(volume, rel=0.02)
    # Every triangle agrees with the normals at its own corners and has an area.
    agree = np.einsum("tcj,tj->tc", mesh.normals[mesh.indices], mesh.face_normals())
    assert agree.min() > 0
    assert mesh.face_areas().min() > 0


def test_uv_sphere_normals_are_the_normalized_positions():
    mesh = shapes.uv_sphere(radius=2.5, segments=24, rings=12)
    np.testing.assert_allclose(mesh.normals, mesh.positions / 2.5, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(mesh.positions, axis=1), 2.5, rtol=1e-15)
    lo, hi = mesh.bounds()
    np.testing.assert_allclose([lo[1], hi[1]], [-2.5, 2.5])  # poles on y


def test_uv_sphere_counts_and_poles():
    s, r = 24, 12
    mesh = shapes.uv_sphere(segments=s, rings=r)
    assert mesh.triangle_count == 2 * s * (r - 1)
    # Regular rings have s + 1 vertices (seam doubled for u); each pole has s, one per segment.
    assert mesh.vertex_count == (r - 1) * (s + 1) + 2 * s
    south = mesh.positions[:, 1] == -1.0
    np.testing.assert_allclose(np.sort(mesh.uvs[south, 0]), (np.arange(s) + 0.5) / s)


def test_uv_sphere_uvs_follow_the_angles():
    mesh = shapes.uv_sphere(segments=16, rings=8)
    x, y, z = mesh.positions.T
    u, v = mesh.uvs.T
    on_ring = np.hypot(x, z) > 1e-9
    theta = np.arctan2(x[on_ring], z[on_ring]) % (2 * math.pi)  # θ = 0 at +z, toward +x
    np.testing.assert_allclose(np.cos(theta), np.cos(2 * math.pi * u[on_ring]), atol=1e-12)
    np.testing.assert_allclose(np.sin(theta), np.sin(2 * math.pi * u[on_ring]), atol=1e-12)
    np.testing.assert_allclose(-np.cos(math.pi * v), y, atol=1e-12)  # v = 0 south, 1 north


@pytest.mark.alone          # seconds on the wall clock
def test_large_uv_sphere_is_fast():
    start = time.perf_counter()
    mesh = shapes.uv_sphere(segments=448, rings=224)
    elapsed = time.perf_counter() - start
    assert mesh.triangle_count == 199808
    assert elapsed < 1.0, f"{elapsed:.3f} s"


def formula_normal(theta, dr, dz):
    """FORMULAS §25: (z' cos θ, z' sin θ, -r'), normalized."""
    n = np.stack([dz * np.cos(theta), dz * np.sin(theta), -dr * np.ones_like(theta)], 1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


@pytest.mark.parametrize("kind", ["cone", "cylinder"])
def test_revolution_normals_equal_the_formula_and_point_outward_axis_z(kind):
    radius, height = 1.5, 2.0

    def profile(t):
        if kind == "cone":  # base to apex
            return radius * (1 - t), height * t, -radius * np.ones_like(t), height * np.ones_like(t)
        return radius * np.ones_like(t), height * t, np.zeros_like(t), height * np.ones_like(t)

    t = np.linspace(0, 1, 5)
    mesh = shapes.surface_of_revolution(profile, t, 12, axis="z")
    theta = 2 * math.pi * mesh.uvs[:, 0]
    r, z, dr, dz = profile(mesh.uvs[:, 1])  # v = t here since t runs 0..1
    # Positions: P(t, θ) = (r cos θ, r sin θ, z).
    np.testing.assert_allclose(mesh.positions, np.stack([r * np.cos(theta), r * np.sin(theta), z], 1), atol=1e-12)
    np.testing.assert_allclose(mesh.normals, formula_normal(theta, dr, dz), atol=1e-12)
    outward = np.einsum("ij,ij->i", mesh.normals[:, :2], np.stack([np.cos(theta), np.sin(theta)], 1))
    assert outward.min() > 0
    if kind == "cone":  # the apex ring collapsed: one vertex per segment, normals still per angle
        apex = mesh.positions[:, 2] == height
        assert apex.sum() == 12
        np.testing.assert_allclose(mesh.normals[apex][:, 2], radius / math.hypot(radius, height))
        assert mesh.triangle_count == 2 * 12 * 4 - 12


def test_revolution_y_axis_is_the_z_form_rotated():
    def profile(t):  # a vase-like bulge, bottom to top
        return 1 + 0.3 * np.sin(t), t, 0.3 * np.cos(t), np.ones_like(t)

    t = np.linspace(0, 3, 7)
    along_z = shapes.surface_of_revolution(profile, t, 10, axis="z")
    along_y = shapes.surface_of_revolution(profile, t, 10)
    np.testing.assert_array_equal(along_y.positions, along_z.positions[:, [1, 2, 0]])
    np.testing.assert_array_equal(along_y.normals, along_z.normals[:, [1, 2, 0]])
    np.testing.assert_array_equal(along_y.indices, along_z.indices)
    # Outward from the y axis, and the normals were not taken from the triangles.
    radial = along_y.positions[:, [0, 2]]
    assert np.einsum("ij,ij->i", along_y.normals[:, [0, 2]], radial).min() > 0
    assert not np.allclose(along_y.normals, along_y.vertex_normals(), atol=1e-3)


def test_revolution_accepts_arrays_and_nested_pairs():
    t = np.linspace(0, 1, 4)
    r, z, dr, dz = np.ones(4), t, np.zeros(4), np.ones(4)
    flat = shapes.surface_of_revolution((r, z, dr, dz), t, 8)
    nested = shapes.surface_of_revolution(lambda s: ((np.ones_like(s), s), (np.zeros_like(s), np.ones_like(s))), t, 8)
    no_t = shapes.surface_of_revolution((r, z, dr, dz), None, 8)
    constants = shapes.surface_of_revolution(lambda s: (1.0, s, 0.0, 1.0), t, 8)
    for other in (nested, no_t, constants):
        np.testing.assert_array_equal(flat.positions, other.positions)
        np.testing.assert_array_equal(flat.uvs, other.uvs)


@pytest.mark.parametrize(
    "args, message",
    [
        (((np.ones(3), np.arange(3.0), np.zeros(3), np.zeros(3)), None, 8), "derivative is zero at t=0.0"),
        (((-np.ones(3), np.arange(3.0), np.zeros(3), np.ones(3)), None, 8), "r\\(t\\) must be >= 0"),
        (((np.ones(3), np.arange(3.0), np.zeros(3), np.ones(3)), [0, 2, 1], 8), "t_values must increase"),
        (((np.ones(3), np.arange(3.0), np.ones(3)), None, 8), "must give 4 arrays"),
        (((np.ones(3), np.arange(4.0), 0, 1), None, 8), "must give 4 arrays"),
        ((lambda t: (t, t, t, t), None, 8), "t_values are needed"),
        (((np.ones(3), np.arange(3.0), np.zeros(3), np.ones(3)), None, 2), "segments must be an integer >= 3"),
    ],
)
def test_revolution_errors(args, message):
    with pytest.raises(ValueError, match=message):
        shapes.surface_of_revolution(*args)


def test_torus_normals_point_away_from_the_tube_centre():
    big, small = 2.0, 0.5
    mesh = shapes.torus(big, small, 24, 12)
    p = mesh.positions
    ring = np.hypot(p[:, 0], p[:, 2])
    centre = np.stack([p[:, 0] / ring * big, np.zeros(len(p)), p[:, 2] / ring * big], 1)
    np.testing.assert_allclose(mesh.normals, (p - centre) / small, atol=1e-12)


def test_icosphere_counts_and_normals():
    for level in range(4):
        mesh = shapes.icosphere(radius=3.0, subdivisions=level)
        assert mesh.triangle_count == 20 * 4**level
        assert mesh.vertex_count == 10 * 4**level + 2  # Euler: V - E + F = 2, every vertex shared
        np.testing.assert_allclose(mesh.normals, mesh.positions / 3.0, atol=1e-12)
    edges = np.linalg.norm(mesh.positions[mesh.indices] - mesh.positions[np.roll(mesh.indices, 1, 1)], axis=2)
    assert edges.max() / edges.min() < 1.5  # nearly uniform, unlike a uv sphere


def test_plane_faces_up_with_uvs_along_x_and_minus_z():
    mesh = shapes.plane(size=4.0, subdivisions=3)
    assert mesh.triangle_count == 18 and mesh.vertex_count == 16
    np.testing.assert_array_equal(mesh.face_normals(), np.tile([0.0, 1.0, 0.0], (18, 1)))
    np.testing.assert_array_equal(mesh.normals, np.tile([0.0, 1.0, 0.0], (16, 1)))
    np.testing.assert_allclose(mesh.uvs[:, 0], (mesh.positions[:, 0] + 2) / 4)
    np.testing.assert_allclose(mesh.uvs[:, 1], (2 - mesh.positions[:, 2]) / 4)
    assert mesh.face_areas().sum() == pytest.approx(16.0)


def test_cube_has_flat_outward_normals_per_face():
    mesh = shapes.cube(size=3.0)
    assert mesh.vertex_count == 24 and mesh.triangle_count == 12
    fn = mesh.face_normals()
    centroids = mesh.corners().mean(axis=1)
    # Each triangle's normal is the axis its centroid sits on: outward and flat.
    np.testing.assert_allclose(fn, np.round(centroids / 1.5), atol=1e-15)
    np.testing.assert_array_equal(mesh.normals[mesh.indices], np.repeat(fn[:, None], 3, axis=1))
    lo, hi = mesh.bounds()
    np.testing.assert_array_equal([lo, hi], [[-1.5] * 3, [1.5] * 3])
    # On the +z face, u grows with x and v with y (upright seen from outside).
    front = np.flatnonzero(mesh.normals[:, 2] == 1.0)
    assert len(front) == 4
    np.testing.assert_allclose(mesh.uvs[front], (mesh.positions[front][:, :2] + 1.5) / 3)


def test_cylinder_and_cone_without_caps_are_open():
    assert shapes.cylinder(segments=8, caps=False).triangle_count == 16
    assert shapes.cone(segments=8, cap=False).triangle_count == 8
    assert shapes.cylinder(segments=8).triangle_count == 16 + 2 * 8
    # The top cap comes last: a rim of 9 vertices (seam doubled) and 8 around the centre.
    cap_normals = shapes.cylinder(segments=8).normals[-17:]
    np.testing.assert_array_equal(cap_normals, np.tile([0.0, 1.0, 0.0], (17, 1)))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: shapes.uv_sphere(radius=0), "uv_sphere: radius must be a positive number"),
        (lambda: shapes.uv_sphere(rings=1), "uv_sphere: rings must be an integer >= 2"),
        (lambda: shapes.plane(subdivisions=1.5), "plane: subdivisions must be an integer >= 1"),
        (lambda: shapes.torus(1.0, 1.0), "minor_radius .* must be smaller than major_radius"),
        (lambda: shapes.icosphere(subdivisions=-1), "icosphere: subdivisions must be an integer >= 0"),
    ],
)
def test_argument_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_generators_return_meshes_with_materials_and_names():
    for make in (shapes.plane, shapes.cube, shapes.uv_sphere, shapes.icosphere, shapes.cylinder, shapes.cone,
                 shapes.torus):
        mesh = make()
        assert isinstance(mesh, Mesh) and mesh.name == make.__name__
        assert mesh.material_ids is None


@pytest.mark.parametrize("axis", ["y", "z"])
def test_revolution_walked_either_way_gets_outward_normals(axis):
    """FORMULAS §25: the normals point outward whichever way the profile is walked.

    A vase r = 1 + 0.3 sin(3t), z = t: walked upward (the formula's side is outward) and
    downward (the formula's normal would point in) give the same surface, normals
    pointing away from the axis, and triangles wound counter-clockwise seen from them.
    """
    def vase(up):
        s = 1.0 if up else -1.0
        return lambda t: (1.0 + 0.3 * np.sin(3 * t), s * t, 0.9 * np.cos(3 * t), s * np.ones_like(t))
    up = shapes.surface_of_revolution(vase(True), np.linspace(0.0, 2.0, 9), 12, axis=axis)
    down = shapes.surface_of_revolution(vase(False), np.linspace(0.0, 2.0, 9), 12, axis=axis)      # z = −t: down
    for mesh in (up, down):
        p, n = mesh.positions, mesh.normals
        along = 1 if axis == "y" else 2
        radial = p.copy()
        radial[:, along] = 0.0
        assert np.all(np.einsum("ij,ij->i", n, radial) > 0)              # away from the axis
        face = mesh.face_normals(normalized=True)
        corner = n[mesh.indices].mean(axis=1)
        assert np.all(np.einsum("ij,ij->i", face, corner) > 0)           # winding agrees with the normals


def test_revolution_flat_disc_keeps_the_side_it_was_walked_with():
    t = np.linspace(0.0, 1.0, 5)
    outward = shapes.surface_of_revolution((t, np.zeros_like(t), np.ones_like(t), np.zeros_like(t)), t, 8, axis="z")
    inward = shapes.surface_of_revolution((1 - t, np.zeros_like(t), -np.ones_like(t), np.zeros_like(t)), t, 8,
                                          axis="z")
    assert np.allclose(outward.normals, (0.0, 0.0, -1.0)) and np.allclose(inward.normals, (0.0, 0.0, 1.0))
