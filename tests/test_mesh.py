"""Mesh: validation messages, normals (face, area- and angle-weighted), transforms, helpers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.scenes.mesh import Mesh, concatenate

TETRA_POSITIONS = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
# Counter-clockwise seen from outside.
TETRA_INDICES = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def tetra(**kw) -> Mesh:
    return Mesh(np.array(TETRA_POSITIONS, float), np.array(TETRA_INDICES), **kw)


# ---------------------------------------------------------------------------- validation


def test_indices_dtype_and_shape_error_names_array_and_shape():
    with pytest.raises(ValueError, match=r"^Mesh\.indices must be an int array of shape \[M, 3\], got float64 \[10, 4\]$"):
        Mesh(np.zeros((40, 3)), np.zeros((10, 4)))


def test_out_of_range_index_names_value_triangle_and_count():
    indices = np.zeros((5, 3), np.int64)
    indices[3, 1] = 57
    with pytest.raises(ValueError, match=r"^Mesh\.indices: index 57 at triangle 3 is out of range for 40 positions$"):
        Mesh(np.zeros((40, 3)), indices)
    indices[3, 1] = -1
    with pytest.raises(ValueError, match=r"index -1 at triangle 3"):
        Mesh(np.zeros((40, 3)), indices)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"positions": np.zeros((4, 2))}, r"Mesh\.positions must be a float array of shape \[N, 3\], got float64 \[4, 2\]"),
        ({"positions": np.array([["a", "b", "c"]] * 4)}, r"Mesh\.positions must be a float array of shape \[N, 3\], got <U1 \[4, 3\]"),
        ({"normals": np.zeros((3, 3))}, r"Mesh\.normals must have one row per position: shape \[4, 3\], got float64 \[3, 3\]"),
        ({"uvs": np.zeros((4, 3))}, r"Mesh\.uvs must be a float array of shape \[N, 2\], got float64 \[4, 3\]"),
        ({"positions": [[0, 0, 0], [1, 0, 0], [0, np.inf, 0], [0, 0, 1]]}, r"Mesh\.positions has a non-finite value in row 2"),
        ({"material_ids": [0, 0, 0, 0]}, r"Mesh\.material_ids: index 0 at triangle 0 is out of range for 0 materials"),
        ({"materials": (Material(),), "material_ids": [0, 0]}, r"Mesh\.material_ids must have one entry per triangle: shape \[4\], got int32 \[2\]"),
        ({"indices": [[0, 1], [2]]}, r"Mesh\.indices must be a rectangular array"),
    ],
)
def test_constructor_errors(changes, message):
    args = {"positions": TETRA_POSITIONS, "indices": TETRA_INDICES}
    args.update(changes)
    with pytest.raises((ValueError, TypeError), match=message):
        Mesh(**args)


def test_constructor_converts_dtypes():
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.array([[0, 1, 2]], np.uint64))
    assert mesh.positions.dtype == np.float64 and mesh.indices.dtype == np.int32
    assert mesh.triangle_count == 1 and mesh.vertex_count == 3


def test_repr_is_readable():
    text = repr(tetra(name="tet"))
    assert text == ("Mesh('tet', 4 vertices, 4 triangles, no normals, no uvs, material 'default', "
                    "bounds (0, 0, 0)..(1, 1, 1))")


# ---------------------------------------------------------------------------- normals


def test_face_normals_areas_and_signed_volume_of_a_tetrahedron():
    mesh = tetra()
    s = 1 / math.sqrt(3)
    np.testing.assert_allclose(mesh.face_normals(), [[0, 0, -1], [0, -1, 0], [-1, 0, 0], [s, s, s]], atol=1e-15)
    np.testing.assert_allclose(mesh.face_areas(), [0.5, 0.5, 0.5, math.sqrt(3) / 2])
    assert mesh.signed_volume() == pytest.approx(1 / 6)
    assert mesh.flipped().signed_volume() == pytest.approx(-1 / 6)


def test_degenerate_triangle_has_zero_normal_not_nan():
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    np.testing.assert_array_equal(mesh.face_normals(), [[0, 0, 0]])
    np.testing.assert_array_equal(mesh.vertex_normals(), np.zeros((3, 3)))


def two_faces_at_the_origin() -> Mesh:
    """Vertex 0 is shared by A (normal +z, area 2, angle 90°) and B (normal +x, area 1/2, angle 45°)."""
    positions = [[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 1, 0], [0, 1, 1]]
    return Mesh(positions, [[0, 1, 2], [0, 3, 4]])


def test_area_weighting_sums_the_cross_products():
    n = two_faces_at_the_origin().vertex_normals("area")[0]
    # cross products: A = (0, 0, 4), B = (1, 0, 0)
    np.testing.assert_allclose(n, np.array([1, 0, 4]) / math.sqrt(17), rtol=0, atol=1e-15)


def test_angle_weighting_weights_unit_normals_by_corner_angle():
    mesh = two_faces_at_the_origin()
    np.testing.assert_allclose(mesh.corner_angles()[:, 0], [math.pi / 2, math.pi / 4])
    n = mesh.vertex_normals("angle")[0]
    # (π/2)(0, 0, 1) + (π/4)(1, 0, 0) ∝ (1, 0, 2)
    np.testing.assert_allclose(n, np.array([1, 0, 2]) / math.sqrt(5), rtol=0, atol=1e-15)


def test_vertex_normals_rejects_unknown_mode_and_zeroes_unused_vertices():
    with pytest.raises(ValueError, match="mode must be 'area' or 'angle', got 'mean'"):
        tetra().vertex_normals("mean")
    mesh = Mesh(TETRA_POSITIONS + [[5, 5, 5]], TETRA_INDICES)
    np.testing.assert_array_equal(mesh.vertex_normals()[4], [0, 0, 0])
    np.testing.assert_allclose(np.linalg.norm(mesh.vertex_normals()[:4], axis=1), 1.0)


def folded_with_a_split_edge() -> Mesh:
    """Two triangles folded along the edge x = 0 (normals +z and +x), stored with separate
    vertex records on that edge (2, 3 repeat 0, 1) and different uvs there: a UV seam."""
    positions = [[0, 0, 0], [0, 1, 0], [0, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, -1]]
    uvs = [[0, 0], [0, 1], [0.5, 0], [0.5, 1], [1, 0], [1, 1]]
    return Mesh(positions, [[4, 0, 1], [2, 5, 3]], uvs=uvs)


def test_welded_normals_are_shared_by_records_at_one_position_and_keep_their_uvs():
    mesh = folded_with_a_split_edge()
    apart = mesh.vertex_normals(weld=False)
    np.testing.assert_allclose(apart[[0, 1]], [[0, 0, 1]] * 2)    # each record sees only its own face
    np.testing.assert_allclose(apart[[2, 3]], [[1, 0, 0]] * 2)
    welded = mesh.vertex_normals()                                 # weld=True is the default
    np.testing.assert_array_equal(welded[0], welded[2])
    np.testing.assert_array_equal(welded[1], welded[3])
    np.testing.assert_allclose(welded[0], np.array([1, 0, 1]) / math.sqrt(2))  # both faces, area-weighted
    np.testing.assert_array_equal(welded[4], apart[4])             # positions of one record: unchanged
    classes = mesh.position_classes()
    assert classes[0] == classes[2] and classes[1] == classes[3] and len(set(classes.tolist())) == 4
    out = mesh.with_normals()
    assert out.vertex_count == 6 and np.array_equal(out.uvs, mesh.uvs)  # the records (and uvs) stay
    np.testing.assert_array_equal(out.normals, welded)


def test_weld_groups_keep_a_crease_and_minus_zero_is_zero():
    mesh = folded_with_a_split_edge()
    kept = mesh.vertex_normals(groups=np.array([0, 0, 1, 1, 0, 1]))
    np.testing.assert_array_equal(kept, mesh.vertex_normals(weld=False))
    with pytest.raises(ValueError, match=r"groups must be an int array of shape \[6\], got float64 \[2\]"):
        mesh.vertex_normals(groups=np.zeros(2))
    signed = Mesh([[0.0, 0, 0], [-0.0, 0, 0], [1, 0, 0]], [[0, 2, 2]])
    assert signed.position_classes()[0] == signed.position_classes()[1]
    assert Mesh(np.zeros((0, 3)), np.zeros((0, 3), int)).vertex_normals().shape == (0, 3)


def test_with_normals_and_flat_shaded():
    mesh = tetra(uvs=np.arange(8.0).reshape(4, 2))
    assert mesh.with_normals("angle").normals is not None
    flat = mesh.flat_shaded()
    assert flat.vertex_count == 12 and flat.triangle_count == 4
    np.testing.assert_array_equal(flat.indices, np.arange(12).reshape(4, 3))
    np.testing.assert_array_equal(flat.positions, mesh.positions[mesh.indices.ravel()])
    np.testing.assert_array_equal(flat.normals, np.repeat(mesh.face_normals(), 3, axis=0))
    np.testing.assert_array_equal(flat.uvs[3:6], mesh.uvs[[0, 1, 3]])
    assert flat.signed_volume() == pytest.approx(mesh.signed_volume())


# ---------------------------------------------------------------------------- transforms


def test_transformed_normals_use_the_inverse_transpose_under_non_uniform_scale():
    # A triangle in the plane x + y = 1, normal (1, 1, 0)/√2.
    positions = [[1, 0, 0], [0, 1, 0], [0, 1, 1]]
    s = 1 / math.sqrt(2)
    mesh = Mesh(positions, [[0, 1, 2]], normals=[[s, s, 0]] * 3)
    np.testing.assert_allclose(mesh.face_normals()[0], [s, s, 0])
    scale_x = np.diag([2.0, 1.0, 1.0, 1.0])
    out = mesh.transformed(scale_x)
    # The plane becomes x/2 + y = 1: normal (1, 2, 0)/√5, not the naive (2, 1, 0)/√5.
    expected = np.array([1, 2, 0]) / math.sqrt(5)
    np.testing.assert_allclose(out.normals, [expected] * 3, atol=1e-15)
    np.testing.assert_allclose(out.face_normals()[0], expected, atol=1e-15)
    np.testing.assert_allclose(out.positions, [[2, 0, 0], [0, 1, 0], [0, 1, 1]])


def test_transformed_applies_translation_and_rotation_on_column_vectors():
    m = np.array([[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 1, 7], [0, 0, 0, 1]], float)  # 90° about z, then move
    out = tetra(normals=tetra().vertex_normals()).transformed(m)
    np.testing.assert_allclose(out.positions[1], [5, 7, 7])  # (1,0,0) -> (0,1,0) + (5,6,7)
    np.testing.assert_allclose(out.normals, tetra().vertex_normals() @ m[:3, :3].T, atol=1e-15)


def test_mirroring_keeps_triangles_counter_clockwise_outside():
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    out = tetra().transformed(mirror)
    assert out.signed_volume() == pytest.approx(1 / 6)
    np.testing.assert_array_equal(out.indices, np.array(TETRA_INDICES)[:, ::-1])


@pytest.mark.parametrize(
    "matrix, message",
    [
        (np.eye(3), r"needs a 4x4 matrix, got shape \[3, 3\]"),
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, -1, 0]], float), r"needs an affine matrix"),
        (np.diag([1.0, 0.0, 1.0, 1.0]), r"singular"),
    ],
)
def test_transformed_rejects_bad_matrices(matrix, message):
    with pytest.raises(ValueError, match=message):
        tetra().transformed(matrix)


def test_bounds_centered_and_normalized():
    mesh = Mesh([[1, 2, 3], [3, 2, 4], [2, 6, 3]], [[0, 1, 2]])
    lo, hi = mesh.bounds()
    np.testing.assert_array_equal(lo, [1, 2, 3])
    np.testing.assert_array_equal(hi, [3, 6, 4])
    lo, hi = mesh.centered().bounds()
    np.testing.assert_array_equal(lo, [-1, -2, -0.5])
    np.testing.assert_array_equal(hi, [1, 2, 0.5])
    lo, hi = mesh.normalized(size=1.0).bounds()
    np.testing.assert_allclose(hi - lo, [0.5, 1.0, 0.25])
    np.testing.assert_allclose(lo + hi, 0.0)
    lo, hi = mesh.scaled_to_unit().bounds()
    np.testing.assert_allclose([lo[1], hi[1]], [-1, 1])
    with pytest.raises(ValueError, match="has no positions"):
        Mesh(np.zeros((0, 3)), np.zeros((0, 3), int)).bounds()


def test_helpers_return_new_meshes_and_leave_the_input_alone():
    mesh = tetra()
    before = mesh.positions.copy()
    mesh.transformed(np.diag([2.0, 2.0, 2.0, 1.0])).centered().normalized()
    np.testing.assert_array_equal(mesh.positions, before)
    with pytest.raises(AttributeError):
        mesh.positions = before  # frozen


# ---------------------------------------------------------------------------- combining


def test_concatenate_offsets_indices_and_builds_a_material_palette():
    red, blue = Material(kd=(1, 0, 0), name="red"), Material(kd=(0, 0, 1), name="blue")
    a = tetra(material=red)
    b = tetra(material=blue).transformed(np.array([[1, 0, 0, 3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], float))
    c = tetra(material=red)
    both = concatenate([a, b, c], name="three")
    assert both.vertex_count == 12 and both.triangle_count == 12
    np.testing.assert_array_equal(both.indices[4:8], np.array(TETRA_INDICES) + 4)
    assert [m.name for m in both.materials] == ["red", "blue"]
    np.testing.assert_array_equal(both.material_ids, [0] * 4 + [1] * 4 + [0] * 4)
    assert both.signed_volume() == pytest.approx(3 / 6)
    parts = both.by_material()
    assert [(m.name, p.triangle_count, p.vertex_count) for m, p in parts] == [("red", 8, 8), ("blue", 4, 4)]


def test_concatenate_refuses_a_mix_of_meshes_with_and_without_normals():
    with pytest.raises(ValueError, match="only some meshes have normals"):
        concatenate([tetra(normals=np.ones((4, 3))), tetra()])


def test_compacted_drops_unused_vertices_in_order():
    mesh = Mesh([[9, 9, 9], [0, 0, 0], [1, 0, 0], [8, 8, 8], [0, 1, 0]], [[1, 2, 4]])
    small = mesh.compacted()
    np.testing.assert_array_equal(small.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(small.indices, [[0, 1, 2]])
