"""The OBJ/MTL loader: every index form, vertex splitting, materials, errors, and the test assets."""
from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.scenes.models import MODELS_DIR
from softpipe.scenes.obj import OBJError, OBJWarning, _OBJParser, _parse_faces, load_mtl, load_obj, parse_mtl, parse_obj

ASSETS = MODELS_DIR  # the bundled models (softpipe/data/models/README.md)
DATA = Path(__file__).parent / "data" / "obj"

SQUARE = """\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
"""


def triangles_as_positions(mesh):
    """Each triangle as a tuple of corner positions: independent of vertex numbering."""
    return [tuple(map(tuple, mesh.positions[t])) for t in mesh.indices]


def parse_quiet(text, name="t.obj", **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning expected unless a test says so
        return parse_obj(text, name, **kw)


# ---------------------------------------------------------------------------- index forms


def test_v_form_keeps_file_order_and_exact_triangles():
    mesh = parse_quiet(SQUARE + "f 1 2 3\nf 1 3 4\n")
    np.testing.assert_array_equal(mesh.positions, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2], [0, 2, 3]])
    assert mesh.normals is None and mesh.uvs is None
    assert mesh.indices.dtype == np.int32 and mesh.positions.dtype == np.float64


def test_v_vt_form_splits_a_position_used_with_two_uvs():
    text = SQUARE + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0.5 0.5\nf 1/1 2/2 3/3\nf 1/4 3/3 4/4\n"
    mesh = parse_quiet(text)
    # Position 1 appears as (1, vt1) and (1, vt4): two vertices; (3, vt3) is shared.
    assert mesh.vertex_count == 5
    np.testing.assert_array_equal(mesh.source.vertex_source[:, :2], [[0, 0], [0, 3], [1, 1], [2, 2], [3, 3]])
    np.testing.assert_array_equal(mesh.indices, [[0, 2, 3], [1, 3, 4]])
    np.testing.assert_array_equal(mesh.uvs[[0, 1]], [[0, 0], [0.5, 0.5]])
    np.testing.assert_array_equal(mesh.positions[0], mesh.positions[1])


def test_v_double_slash_vn_form():
    text = SQUARE + "vn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//1 4//1\n"
    mesh = parse_quiet(text)
    assert mesh.uvs is None
    assert mesh.vertex_count == 5  # position 1 with normal 1 and with normal 2
    np.testing.assert_array_equal(mesh.normals[mesh.indices[1, 0]], [0, 0, -1])
    np.testing.assert_array_equal(mesh.normals[mesh.indices[0, 0]], [0, 0, 1])
    np.testing.assert_array_equal(mesh.source.vertex_source[:, 1], -1)


def test_v_vt_vn_form():
    text = SQUARE + "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\n"
    mesh = parse_quiet(text)
    np.testing.assert_array_equal(mesh.uvs[mesh.indices[0]], [[0, 0], [1, 0], [1, 1]])
    np.testing.assert_array_equal(mesh.normals, np.tile([0, 0, 1.0], (3, 1)))
    np.testing.assert_array_equal(mesh.positions[mesh.indices[0]], [[0, 0, 0], [1, 0, 0], [1, 1, 0]])


def test_negative_indices_count_back_from_the_latest_element_so_far():
    text = (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0\nvn 0 0 1\n"
        "f -3/-1/-1 -2/-1/-1 -1/-1/-1\n"
        "v 5 0 0\nv 6 0 0\nv 5 1 0\nvt 0.75 0\n"
        "f -3/-1/-1 -2/-1/-1 -1/-1/-1\n"  # now -1 means v6 and vt2
    )
    mesh = parse_quiet(text)
    assert triangles_as_positions(mesh) == [
        ((0, 0, 0), (1, 0, 0), (0, 1, 0)),
        ((5, 0, 0), (6, 0, 0), (5, 1, 0)),
    ]
    np.testing.assert_array_equal(mesh.uvs[mesh.indices[:, 0], 0], [0.25, 0.75])


def test_quads_and_polygons_are_fan_triangulated_in_order():
    text = SQUARE + "v 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3 4\n"
    mesh = parse_quiet(text)
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2], [1, 2, 3]])
    assert mesh.source.counts == {"v": 6, "vt": 0, "vn": 0, "f": 2} and mesh.source.triangles == 5
    np.testing.assert_array_equal(mesh.source.triangle_lines, [7, 7, 8, 8, 8])


def test_mixed_forms_in_one_file_fast_and_per_line_paths_agree():
    text = (
        SQUARE + "vt 0 0\nvt 1 1\nvn 0 0 1\n"
        "f 1 2 3\nf 1/1 3/2 4/1\nf 1//1 2//1 3//1 4//1\nf 2/2/1 -2/1/-1 -1/-1/1\n"
    )
    parser = _OBJParser(text, "t.obj", "")
    parser.scan()
    assert _parse_faces("\n".join(t[2:] for t in parser.vec["f"][0]), 4) is not None  # no fallback
    fast_counts, fast_corners = parser.faces()
    slow_counts, slow_corners = parser.faces_slowly()
    np.testing.assert_array_equal(fast_counts, [3, 3, 4, 3])
    np.testing.assert_array_equal(fast_counts, slow_counts)
    np.testing.assert_array_equal(fast_corners, slow_corners)
    np.testing.assert_array_equal(fast_corners[[0, 3, 6, 10, 11, 12]],
                                  [[1, 0, 0], [1, 1, 0], [1, 0, 1], [2, 2, 1], [-2, 1, -1], [-1, -1, 1]])


def test_whitespace_comments_crlf_and_line_continuation():
    text = (
        "# a comment\r\n"
        "v 0 0 0 # trailing comment\r\n"
        "\tv 1 0 0\r\n"
        "  v 0 1 0\r\n"
        "v 0 0 1 1.0\r\n"  # optional w is ignored
        "f 1 2 \\\r\n"
        "  3\r\n"
        "f\t1  3\t4 # comment\r\n"
    )
    mesh = parse_quiet(text)
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(mesh.positions[3], [0, 0, 1])
    np.testing.assert_array_equal(mesh.source.triangle_lines, [6, 8])


def test_vt_with_one_or_three_numbers():
    mesh = parse_quiet(SQUARE + "vt 0.5\nvt 0.25 0.75 0.0\nvt 1 1\nf 1/1 2/2 3/3\n")
    np.testing.assert_array_equal(mesh.uvs, [[0.5, 0.0], [0.25, 0.75], [1, 1]])


def test_smoothing_groups_split_vertices_only_without_normals():
    # Two triangles sharing the edge 1-3.
    smooth = parse_quiet(SQUARE + "s 1\nf 1 2 3\nf 1 3 4\n")
    assert smooth.vertex_count == 4
    split = parse_quiet(SQUARE + "s 1\nf 1 2 3\ns 2\nf 1 3 4\n")
    assert split.vertex_count == 6
    flat = parse_quiet(SQUARE + "s off\nf 1 2 3\nf 1 3 4\n")
    assert flat.vertex_count == 6
    with_normals = parse_quiet(SQUARE + "vn 0 0 1\ns off\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n")
    assert with_normals.vertex_count == 4


def test_smoothing_groups_without_normals_give_welded_normals_with_the_crease():
    # Two triangles folded along the edge 1-2 (normals +z and +x).
    folded = "v 0 0 0\nv 0 1 0\nv -1 0 0\nv 0 0 -1\n"
    one_group = parse_quiet(folded + "s 1\nf 3 1 2\nf 1 4 2\n")
    two_groups = parse_quiet(folded + "s 1\nf 3 1 2\ns 2\nf 1 4 2\n")
    assert one_group.vertex_count == 4 and two_groups.vertex_count == 6
    edge = [np.flatnonzero(m.source.vertex_source[:, 0] == 0) for m in (one_group, two_groups)]
    np.testing.assert_allclose(one_group.normals[edge[0]], [np.array([1, 0, 1]) / np.sqrt(2)])  # smooth
    crease = two_groups.normals[edge[1]]                      # one record per group, each its face's normal
    np.testing.assert_allclose(sorted(map(tuple, crease)), [(0, 0, 1), (1, 0, 0)], atol=1e-15)
    assert parse_quiet(folded + "f 3 1 2\nf 1 4 2\n").normals is None  # no s: left to Mesh.vertex_normals


def test_corners_without_vn_or_vt_are_filled_with_a_warning():
    text = SQUARE + "vt 0.5 0.5\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf 1 3 4\n"
    with pytest.warns(OBJWarning) as record:
        mesh = parse_obj(text, "part.obj")
    assert sorted(str(w.message) for w in record) == [
        "part.obj: some face corners have no normal; they get area-weighted vertex normals",
        "part.obj: some face corners have no texture coordinates; they get (0, 0)",
    ]
    plain = mesh.indices[1]  # the second face's vertices: (v, no vt, no vn)
    np.testing.assert_array_equal(mesh.source.vertex_source[plain, 1:], -1)
    np.testing.assert_array_equal(mesh.uvs[plain], 0.0)
    np.testing.assert_allclose(mesh.normals[plain], np.tile([0, 0, 1.0], (3, 1)))


def test_a_file_of_vertices_alone_reads_as_a_point_cloud_with_a_warning():
    with pytest.warns(OBJWarning, match="pts.obj: no faces, lines or points: its 4 vertices are read as points"):
        mesh = parse_obj(SQUARE, "pts.obj")
    assert mesh.triangle_count == 0 and mesh.vertex_count == 4 and mesh.points.tolist() == [0, 1, 2, 3]


def test_unknown_and_unsupported_statements_are_skipped_and_counted():
    text = SQUARE + "vp 0.5\nl 1 2\nl 2 3\ncstype bezier\nf 1 2 3\nfoo bar\n"
    mesh = parse_quiet(text)
    assert mesh.source.skipped == {"vp": 1, "cstype": 1, "foo": 1}   # l is read (tests/test_obj_lines_points.py)
    assert mesh.triangle_count == 1 and mesh.segment_count == 2


def test_objects_and_groups_per_triangle():
    text = SQUARE + "f 1 2 3\no thing\ng a b\nf 1 3 4\ng\nf 1 2 4\ng a b\nf 2 3 4\n"
    report = parse_quiet(text).source
    assert report.objects == ("thing",)
    np.testing.assert_array_equal(report.object_ids, [-1, 0, 0, 0])
    assert report.groups == ("a b", "default")
    np.testing.assert_array_equal(report.group_ids, [-1, 0, 1, 0])


# ---------------------------------------------------------------------------- materials


def test_mtl_values_map_onto_material():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mats = load_mtl(DATA / "two_materials.mtl")
    red, glass = mats["red"], mats["glass"]
    assert (red.ka, red.kd, red.ks, red.ke) == ((0.1, 0, 0), (0.8, 0.1, 0.1), (0.5, 0.5, 0.5), (0, 0.2, 0))
    assert (red.shininess, red.ior, red.opacity) == (96.0, 1.5, 0.75)
    assert red.diffuse_texture == os.path.normpath(str(DATA / "textures" / "checker.png"))
    assert glass.kd == (0.2, 0.2, 0.2)  # one number is gray
    assert glass.opacity == pytest.approx(0.1)  # Tr = 1 - d
    assert glass.ior == 1.52 and glass.diffuse_texture is None
    assert glass.ks == Material().ks  # unset fields keep the defaults
    assert red.name == "red"


def test_d_wins_over_tr_in_either_order():
    mats = parse_mtl("newmtl a\nd 0.5\nTr 0.9\nnewmtl b\nTr 0.9\nd 0.25\n")
    assert mats["a"].opacity == 0.5 and mats["b"].opacity == 0.25


def test_usemtl_gives_per_triangle_materials():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = load_obj(DATA / "two_materials.obj")
    assert [m.name for m in mesh.materials] == ["red", "glass"]
    np.testing.assert_array_equal(mesh.material_ids, [0, 1])
    assert mesh.material.name == "red"
    assert mesh.triangle_material(1).opacity == pytest.approx(0.1)
    report = mesh.source
    assert report.groups == ("lower", "upper") and report.objects == ("square",)
    assert report.mtl_skipped == {"illum": 1}
    assert report.mtllibs == (str(DATA / "two_materials.mtl"),)
    parts = mesh.by_material()
    assert [(m.name, sub.triangle_count, sub.vertex_count) for m, sub in parts] == [("red", 1, 3), ("glass", 1, 3)]


def test_usemtl_lines_naming_one_material_share_an_entry(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\n")
    text = "mtllib m.mtl\n" + SQUARE + "usemtl a\nf 1 2 3\nusemtl b\nf 1 3 4\nusemtl a\nf 2 3 4\n"
    mesh = parse_quiet(text, base_dir=tmp_path)
    assert [m.name for m in mesh.materials] == ["a", "b"]
    np.testing.assert_array_equal(mesh.material_ids, [0, 1, 0])
    single = parse_quiet("mtllib m.mtl\n" + SQUARE + "usemtl b\nf 1 2 3\n", base_dir=tmp_path)
    assert single.material_ids is None and single.material.kd == (0, 1, 0)


def test_faces_before_usemtl_get_the_default_material(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 0 0\n")
    mesh = parse_quiet("mtllib m.mtl\n" + SQUARE + "f 1 2 3\nusemtl a\nf 1 3 4\n", base_dir=tmp_path)
    assert [m.name for m in mesh.materials] == ["default", "a"]
    assert mesh.materials[0] == Material()


def test_missing_mtl_file_warns_with_its_name_and_loads(tmp_path, monkeypatch):
    # loaded by a short relative name: the message cuts a path past 80 characters (files.excerpt), and
    # tmp_path is longer under xdist (.../popen-gw0/...)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m.obj").write_text("mtllib nowhere.mtl\n" + SQUARE + "usemtl a\nf 1 2 3\n")
    with pytest.warns(OBJWarning) as record:
        mesh = load_obj("m.obj")
    messages = [str(w.message) for w in record]
    assert any("nowhere.mtl" in m and "m.obj:1" in m for m in messages)
    assert any("'a' is not defined" in m for m in messages)
    assert mesh.triangle_count == 1 and mesh.material.name == "a"
    assert mesh.material.kd == Material().kd
    assert len(mesh.source.warnings) == 2


def test_missing_texture_warns_with_its_name_and_drops_it(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 1 0 0\nmap_Kd gone.png\n")
    with pytest.warns(OBJWarning, match=r"m\.mtl:3: texture .*gone\.png.* not found"):
        mats = load_mtl(tmp_path / "m.mtl")
    assert mats["a"].diffuse_texture is None and mats["a"].kd == (1, 0, 0)


def test_mtl_without_base_dir_resolves_from_the_current_directory(tmp_path, monkeypatch):
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 0 0 1\n")
    monkeypatch.chdir(tmp_path)
    mesh = parse_quiet("mtllib m.mtl\n" + SQUARE + "usemtl a\nf 1 2 3\n")
    assert mesh.material.kd == (0, 0, 1)


# ---------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "text, message",
    [
        ("v 0 0 0\nv 1.0 abc\n", "bad.obj:2: expected 3 numbers after 'v', got 'v 1.0 abc'"),
        ("v 0 0\n", "bad.obj:1: expected 3 numbers after 'v', got 'v 0 0'"),
        ("v 0 0 0\nv 1 2 3 4 5\n", "bad.obj:2: expected 3 numbers after 'v'"),
        ("v nan 0 0\n", "bad.obj:1: expected finite numbers after 'v', got 'v nan 0 0'"),
        ("vn 0 1\n", "bad.obj:1: expected 3 numbers after 'vn', got 'vn 0 1'"),
        ("vt x\n", "bad.obj:1: expected 1 to 3 numbers (u v [w]) after 'vt', got 'vt x'"),
        (SQUARE + "f 1 2\n", "bad.obj:5: expected at least 3 vertices after 'f', got 'f 1 2'"),
        (SQUARE + "f 1 2 3\nf 1 2 99\n", "bad.obj:6: index 99 but only 4 vertices so far: 'f 1 2 99'"),
        ("v 0 0 0\nf 1 1 2\nv 1 1 1\n", "bad.obj:2: index 2 but only 1 vertex so far: 'f 1 1 2'"),
        (SQUARE + "f -5 1 2\n", "bad.obj:5: index -5 but only 4 vertices so far: 'f -5 1 2'"),
        (SQUARE + "vt 0 0\nf 1/1 2/2 3/1\n",
         "bad.obj:6: texture index 2 but only 1 texture coordinate (vt) so far: 'f 1/1 2/2 3/1'"),
        (SQUARE + "f 1//1 2//1 3//1\n", "bad.obj:5: normal index 1 but only 0 normals (vn) so far"),
        (SQUARE + "f 1 0 2\n", "bad.obj:5: index 0 in '0' is invalid (OBJ indices start at 1)"),
        (SQUARE + "f 1 2 3/\n", "bad.obj:5: expected a face corner v, v/vt, v//vn or v/vt/vn, got '3/'"),
        (SQUARE + "f 1 2 3/1/1/1\n", "bad.obj:5: expected a face corner v, v/vt, v//vn or v/vt/vn"),
        (SQUARE + "f 1 2 a\n", "bad.obj:5: expected a face corner v, v/vt, v//vn or v/vt/vn, got 'a'"),
        (SQUARE + "s smooth\nf 1 2 3\n", "bad.obj:5: expected a smoothing group number or 'off' after 's'"),
        (SQUARE + "usemtl\nf 1 2 3\n", "bad.obj:5: expected a material name after 'usemtl'"),
    ],
)
def test_obj_errors_name_file_line_and_expectation(text, message):
    with pytest.raises(OBJError) as info:
        parse_obj(text, "bad.obj")
    assert str(info.value).startswith(message), str(info.value)
    assert isinstance(info.value, ValueError)
    assert info.value.file == "bad.obj" and info.value.line == int(message.split(":")[1])


@pytest.mark.parametrize(
    "text, message",
    [
        ("Kd 1 0 0\n", "bad.mtl:1: expected 'newmtl' before 'Kd'"),
        ("newmtl a\nKd 1 x 0\n", "bad.mtl:2: expected 3 numbers after 'Kd', got 'Kd 1 x 0'"),
        ("newmtl a\nNs\n", "bad.mtl:2: expected 1 number after 'Ns', got 'Ns'"),
        ("newmtl a\n\nd 1.5\n", "bad.mtl:3: material 'a': Material.opacity must be in [0, 1]"),
        ("newmtl a\nKd -1 0 0\n", "bad.mtl:2: material 'a': Material.kd must hold numbers >= 0, got float -1.0 in an "
                                   "array of 3"),
        ("newmtl\n", "bad.mtl:1: expected a material name after 'newmtl'"),
    ],
)
def test_mtl_errors_name_file_line_and_expectation(text, message):
    with pytest.raises(OBJError) as info:
        parse_mtl(text, "bad.mtl")
    assert str(info.value).startswith(message), str(info.value)


def test_errors_from_load_obj_carry_the_path(tmp_path):
    path = tmp_path / "broken.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    with pytest.raises(OBJError, match=r"broken\.obj:4: index 4 but only 3 vertices so far"):
        load_obj(path)


# ---------------------------------------------------------------------------- the bundled models

# file, triangles, 'v' lines, mesh vertices, has normals, has uvs
ASSET_TABLE = [
    ("stanford-bunny.obj", 69451, 35947, 34834, False, False),
    ("teapot.obj", 6320, 3644, 3644, False, False),
    ("suzanne.obj", 968, 507, 507, True, False),
    ("spot/spot_triangulated.obj", 5856, 2930, None, False, True),
    ("spot/spot_quadrangulated.obj", 5856, 2930, None, False, True),
    ("armadillo.obj", 99976, 49990, 49990, False, False),
]


@pytest.mark.parametrize("name, triangles, v_lines, vertices, has_normals, has_uvs", ASSET_TABLE)
def test_every_asset_loads_with_the_readme_counts(name, triangles, v_lines, vertices, has_normals, has_uvs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = load_obj(ASSETS / name)
    assert mesh.triangle_count == triangles
    assert mesh.source.counts["v"] == v_lines
    if vertices is not None:
        assert mesh.vertex_count == vertices
    assert (mesh.normals is not None) == has_normals
    assert (mesh.uvs is not None) == has_uvs
    assert mesh.source.skipped == {}
    assert mesh.signed_volume() > 0  # README: counter-clockwise outward


def test_spot_splits_vertices_per_position_uv_pair_and_both_versions_agree():
    tri = load_obj(ASSETS / "spot/spot_triangulated.obj")
    quad = load_obj(ASSETS / "spot/spot_quadrangulated.obj")
    pairs = {tuple(p) for p in tri.source.vertex_source[:, :2]}
    assert len(pairs) == tri.vertex_count  # one vertex per distinct (v, vt)
    assert tri.source.counts["vt"] == 3225
    rows = lambda m: {tuple(r) for r in np.hstack([m.positions, m.uvs])}  # noqa: E731
    assert rows(tri) == rows(quad)  # the same (position, uv) vertices, however the faces are cut
    assert tri.signed_volume() == pytest.approx(quad.signed_volume(), rel=1e-3)
    lo, hi = tri.bounds()
    np.testing.assert_allclose(lo, [-0.471552, -0.736784, -0.668909])
    np.testing.assert_allclose(hi, [0.471552, 0.953646, 1.049])


def _max_angle_between_records_at_one_position(mesh, normals):
    """The largest angle (degrees) between the normals of two vertex records at one position."""
    classes = mesh.position_classes()
    order = np.argsort(classes, kind="stable")
    starts = np.flatnonzero(np.diff(classes[order], prepend=-1))
    worst = 0.0
    for a, b in zip(starts, np.append(starts[1:], len(order))):
        if b - a > 1:
            n = normals[order[a:b]]
            worst = max(worst, float(np.degrees(np.arccos(np.clip(n @ n.T, -1, 1)).max())))
    return worst


def test_teapot_vertices_at_one_position_share_one_smooth_normal():
    """Issue 14: the teapot repeats 403 `v` lines at its patch borders (3,644 records, 3,241
    positions). Normals per record made a seam along every border, up to 117° apart at the
    handle's joint (median 9.7° over the 393 shared positions); welded, they are equal."""
    mesh = load_obj(ASSETS / "teapot.obj")
    assert mesh.normals is None and mesh.vertex_count == 3644
    classes = mesh.position_classes()
    assert classes.max() + 1 == 3241
    before = mesh.vertex_normals(weld=False)
    assert _max_angle_between_records_at_one_position(mesh, before) > 110
    normals = mesh.vertex_normals()             # what drawing computes for a mesh without normals
    first = np.zeros(classes.max() + 1, np.int64)
    first[classes[::-1]] = np.arange(len(classes))[::-1]   # the first record of each position
    np.testing.assert_array_equal(normals, normals[first[classes]])
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_spot_keeps_its_uv_seam_records_but_shades_smoothly_across_them():
    mesh = load_obj(ASSETS / "spot/spot_triangulated.obj")
    classes = mesh.position_classes()
    assert classes.max() + 1 == 2930 < mesh.vertex_count      # split only where the uvs differ
    normals = mesh.with_normals().normals
    assert _max_angle_between_records_at_one_position(mesh, mesh.vertex_normals(weld=False)) > 5
    assert _max_angle_between_records_at_one_position(mesh, normals) < 1e-5


def test_a_rendered_row_across_a_teapot_seam_has_no_step():
    """The seam in pixels: drawn with the `normals` program (the eye-space normal as a color),
    the step between two neighbouring pixels of one row on the surface (the largest of the
    three channels). Take the pair of pixels where per-record normals made the largest step
    (a patch border): there it was 0.077, twelve times the row's median step (0.0065), and
    welded it is 0.0067, like its neighbours."""
    from softpipe.pipeline.camera import Camera
    from softpipe.scenes.drawing import render_scene
    from softpipe.scenes.scene import Scene

    mesh = load_obj(ASSETS / "teapot.obj")
    camera = Camera(eye=(4.33, 3.99, 5.99), target=(0.74, 1.38, -0.22), fovy=35.0, near=5.0, far=12.0)
    drawn = {}
    for name, m in (("before", mesh.with_normals(weld=False)), ("after", mesh)):
        fb = render_scene(Scene.from_model(m, width=200, height=150, program="normals"), camera=camera)
        drawn[name] = fb.color[..., :3].astype(np.float64), fb.depth
    depth = drawn["after"][1]
    covered = depth < 1.0
    # neighbours on one surface: both covered, nearly the same depth (no silhouette between)
    same_surface = covered[:, 1:] & covered[:, :-1] & (np.abs(np.diff(depth, axis=1)) < 2e-3)
    step = {k: np.abs(np.diff(c, axis=1)).max(axis=2) * same_surface for k, (c, _) in drawn.items()}
    y, x = np.unravel_index(np.argmax(step["before"] - step["after"]), same_surface.shape)
    row = step["after"][y][same_surface[y]]
    median = np.median(row)
    assert step["before"][y, x] > 0.05 and step["before"][y, x] > 6 * median   # the seam was there
    assert step["after"][y, x] < 2 * median                                    # and is gone
    assert row.max() < 3 * median                                              # the whole row is smooth


def test_suzanne_normals_follow_their_v_double_slash_vn_indices():
    mesh = load_obj(ASSETS / "suzanne.obj")
    # The file's first two lines are "vn 0.744549 -0.641131 0.186007" then "v -2.056562 ...":
    # vertex 1 is used with normal 1.
    v1 = np.flatnonzero(mesh.source.vertex_source[:, 0] == 0)
    np.testing.assert_array_equal(mesh.source.vertex_source[v1], [[0, -1, 0]])
    np.testing.assert_array_equal(mesh.normals[v1[0]], [0.744549, -0.641131, 0.186007])
    np.testing.assert_array_equal(mesh.positions[v1[0]], [-2.056562, 1.415748, 4.869517])


@pytest.mark.alone          # seconds on the wall clock
def test_bunny_loads_well_under_a_second():
    best = min(_timed_load(ASSETS / "stanford-bunny.obj") for _ in range(2))
    assert best < 1.0, f"bunny took {best:.3f} s"


def _timed_load(path):
    start = time.perf_counter()
    load_obj(path)
    return time.perf_counter() - start


# ---------------------------------------------------------------------------- size and complexity


def _seconds(call, repeats=3):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def _named_objects(n):
    return "v 0 0 0\nv 1 0 0\nv 0 1 0\n" + "".join(f"o part{k}\nf 1 2 3\n" for k in range(n))


@pytest.mark.alone          # a ratio of two wall-clock times
def test_object_names_load_in_linear_time():
    """10⁵ `o` names: five times the names must not take (about) 25 times as long.

    A complexity check, not a speed one (speed is the benchmarks' business): the
    label list was quadratic, and 10⁵ names took most of a minute."""
    small, large = _named_objects(20_000), _named_objects(100_000)
    mesh = parse_obj(large, "many.obj")
    assert len(mesh.source.objects) == 100_000 and mesh.source.objects[-1] == "part99999"
    np.testing.assert_array_equal(mesh.source.object_ids[:3], [0, 1, 2])
    ratio = _seconds(lambda: parse_obj(large, "many.obj")) / _seconds(lambda: parse_obj(small, "many.obj"))
    assert ratio < 10, f"5x the names took {ratio:.1f}x as long: quadratic"
    # a name that comes back keeps its first entry
    report = parse_quiet(SQUARE + "o a\ng x\nf 1 2 3\no b\ng y\nf 1 3 4\no a\ng x\nf 2 3 4\n").source
    assert report.objects == ("a", "b") and report.groups == ("x", "y")
    np.testing.assert_array_equal(report.object_ids, [0, 1, 0])
    np.testing.assert_array_equal(report.group_ids, [0, 1, 0])


def test_long_backslash_continuations_load_in_linear_time():
    def text(n):
        return SQUARE + "f 1 2 \\\n" + "\\\n" * n + "3\n"

    mesh = parse_quiet(text(10))
    np.testing.assert_array_equal(mesh.indices, [[0, 1, 2]])
    assert mesh.source.triangle_lines.tolist() == [5]
    small, large = text(200_000), text(1_000_000)
    ratio = _seconds(lambda: parse_obj(large)) / _seconds(lambda: parse_obj(small))
    assert ratio < 10, f"5x the continued lines took {ratio:.1f}x as long: quadratic"


HUGE = "x" * 10_000_000


@pytest.mark.parametrize("text, parse, start", [
    ("v 0 0 " + HUGE + "\n", parse_obj, "big.obj:1: expected 3 numbers after 'v', got 'v 0 0 xxx"),
    (SQUARE + "f 1 2 " + HUGE + "\n", parse_obj, "big.obj:5: expected a face corner v, v/vt, v//vn or v/vt/vn, got"),
    (SQUARE + "f 1 2 3/" + HUGE + "\n", parse_obj, "big.obj:5: expected a face corner"),
    (SQUARE + "s " + HUGE + "\n", parse_obj, "big.obj:5: expected a smoothing group number"),
    ("newmtl a\nKd 1 " + HUGE + "\n", parse_mtl, "big.obj:2: expected 3 numbers after 'Kd', got 'Kd 1 xxx"),
    ("newmtl a\nd " + HUGE + "\n", parse_mtl, "big.obj:2: expected 1 number after 'd', got 'd xxx"),
])
def test_a_10_mb_line_gives_a_short_error(text, parse, start):
    with pytest.raises(OBJError) as info:
        parse(text, "big.obj")
    message = str(info.value)
    assert message.startswith(start) and len(message) < 500, message[:300]
    assert "10,000,0" in message                                     # says how long the line was


def test_a_10_mb_name_gives_short_warnings_and_a_short_report(tmp_path):
    text = "mtllib " + HUGE + "\n" + SQUARE + HUGE + " 1\nusemtl " + HUGE + "\nf 1 2 3\n"
    with pytest.warns(OBJWarning) as record:
        mesh = parse_obj(text, "big.obj", base_dir=tmp_path)
    assert record and all(len(str(w.message)) < 1000 for w in record)
    assert len(repr(mesh.source)) < 50_000                           # the skipped keyword is cut short
    (tmp_path / "m.mtl").write_text("newmtl " + HUGE + "\nmap_Kd gone.png\n")
    with pytest.warns(OBJWarning) as record:
        load_mtl(tmp_path / "m.mtl")
    assert all(len(str(w.message)) < 1000 for w in record)
