"""OBJ ``l`` (polylines) and ``p`` (points): read into Mesh.lines / Mesh.points, drawn after the faces.

The drawings use a window projection (``WINDOW``: model coordinates are window coordinates,
pixel (x, y) centred at (x + ½, y + ½)), so every pixel a test names follows from GL's rules
as docs/points-and-lines.md states them.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import run_cli

import softpipe as sp
from softpipe.light.material import Material
from softpipe.pipeline.camera import Camera
from softpipe.scenes.drawing import draw_mesh, render
from softpipe.scenes.mesh import Mesh, concatenate
from softpipe.scenes.obj import OBJError, OBJWarning, parse_obj
from softpipe.testing import ascii_picture

W, H = 12, 6
WINDOW = np.array([[2 / W, 0, 0, -1], [0, 2 / H, 0, -1], [0, 0, 1, 0], [0, 0, 0, 1.0]])   # z: clip z

CURVE = """\
v 1.5 1.5 0
v 10.5 1.5 0
v 10.5 4.5 0
v 1.5 4.5 0
l 1 2 3 4 1
"""


def parse_quiet(text, name="t.obj"):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return parse_obj(text, name)


def window_draw(mesh, program="phong", **kw):
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 1))
    results = []
    draw_mesh(fb, mesh, Camera(), program, uniforms={"model_view": np.eye(4), "projection": WINDOW},
              results=results, **kw)
    return fb, results


# ---------------------------------------------------------------------------- reading


def test_a_polyline_is_kept_as_its_segments_and_a_point_statement_as_its_points():
    mesh = parse_quiet(CURVE + "p 2 -1\np 3\n")
    assert mesh.triangle_count == 0 and mesh.segment_count == 4 and mesh.point_count == 3
    seg = [tuple(map(tuple, mesh.positions[s, :2])) for s in mesh.lines]
    assert seg == [((1.5, 1.5), (10.5, 1.5)), ((10.5, 1.5), (10.5, 4.5)), ((10.5, 4.5), (1.5, 4.5)),
                   ((1.5, 4.5), (1.5, 1.5))]
    assert [tuple(mesh.positions[p, :2]) for p in mesh.points] == [(10.5, 1.5), (1.5, 4.5), (10.5, 4.5)]
    report = mesh.source
    assert report.counts["l"] == 1 and report.counts["p"] == 2 and report.skipped == {}
    assert report.segment_lines.tolist() == [5, 5, 5, 5] and report.point_lines.tolist() == [6, 6, 7]


def test_a_line_keeps_its_texture_coordinates():
    mesh = parse_quiet("v 0 0 0\nv 1 0 0\nvt 0.25 0.5\nvt 0.75 1\nl 1/1 2/2\n")
    assert mesh.uvs[mesh.lines[0]].tolist() == [[0.25, 0.5], [0.75, 1.0]]


def test_a_file_with_faces_lines_and_points_keeps_all_three_with_their_materials():
    text = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
            "f 1//1 2//1 3//1\nusemtl red\nl 1 3\nusemtl blue\np 4\nusemtl red\nf 1//1 3//1 4//1\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OBJWarning)    # red and blue are not defined: defaults
        mesh = parse_obj(text, "mixed.obj")
    assert (mesh.triangle_count, mesh.segment_count, mesh.point_count) == (2, 1, 1)
    assert [m.name for m in mesh.materials] == ["default", "red", "blue"]
    assert mesh.material_ids.tolist() == [0, 1]
    assert mesh.line_material_ids.tolist() == [1] and mesh.point_material_ids.tolist() == [2]
    assert mesh.source.warnings == [f"mixed.obj:{n}: material {name!r} is not defined (no mtllib); using the default"
                                    for n, name in ((7, "red"), (9, "blue"))]
    parts = {m.name: part for m, part in mesh.by_material()}
    assert (parts["red"].triangle_count, parts["red"].segment_count, parts["red"].point_count) == (1, 1, 0)
    assert (parts["blue"].triangle_count, parts["blue"].point_count) == (0, 1)
    np.testing.assert_array_equal(parts["blue"].positions[parts["blue"].points], [[0, 1, 0]])


def test_faces_alone_read_as_before():
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"
    mesh = parse_quiet(text)
    assert mesh.segment_count == 0 and mesh.point_count == 0 and mesh.line_material_ids is None


def test_flat_shading_compacting_and_concatenating_keep_lines_and_points():
    mesh = parse_quiet("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 5 5 5\nv 6 6 6\nf 1 2 3\nl 4 5\np 5\n")
    flat = mesh.flat_shaded()
    np.testing.assert_array_equal(flat.positions[flat.lines], [[[5, 5, 5], [6, 6, 6]]])
    np.testing.assert_array_equal(flat.positions[flat.points], [[6, 6, 6]])
    both = concatenate([mesh, mesh.replace(material=Material(name="other"))])
    assert both.segment_count == 2 and both.line_material_ids.tolist() == [0, 1]
    assert both.point_material_ids.tolist() == [0, 1]


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nl 1\n", "c.obj:2: expected at least 2 vertices after 'l', got 'l 1'"),
    ("v 0 0 0\np\n", "c.obj:2: expected at least 1 vertex after 'p', got 'p'"),
    ("v 0 0 0\nv 1 0 0\nl 1 3\n", "c.obj:3: index 3 but only 2 vertices so far: 'l 1 3'"),
    ("v 0 0 0\np -2\n", "c.obj:2: index -2 but only 1 vertex so far: 'p -2'"),
    ("v 0 0 0\nl 1 2\nv 1 0 0\n", "c.obj:2: index 2 but only 1 vertex so far: 'l 1 2'"),
    ("v 0 0 0\nv 1 0 0\nl 1/1 2\n", "c.obj:3: texture index 1 but only 0 texture coordinates (vt) so far: "
                                    "'l 1/1 2'"),
    ("v 0 0 0\nv 1 0 0\nl 1//1 2\n", "c.obj:3: expected a line vertex v or v/vt after 'l', got '1//1' in "
                                     "'l 1//1 2'"),
    ("v 0 0 0\np 1/1\n", "c.obj:2: expected a point vertex v after 'p', got '1/1' in 'p 1/1'"),
    ("v 0 0 0\np 0\n", "c.obj:2: index 0 in '0' is invalid (OBJ indices start at 1): 'p 0'"),
    ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\np 1 9\nf 1 2 7\n", "c.obj:5: index 9 but only 3 vertices so far: 'p 1 9'"),
])
def test_a_malformed_line_or_point_names_the_file_and_line(text, message):
    with pytest.raises(OBJError) as e:
        parse_obj(text, "c.obj")
    assert str(e.value) == message


def test_a_file_of_vertices_alone_is_a_point_cloud_and_one_without_vertices_is_refused(tmp_path):
    path = tmp_path / "cloud.obj"
    path.write_text("v 0 0 0\nv 1 0 0\n# a comment\nv 0 1 0\n")
    with pytest.warns(OBJWarning, match="cloud.obj: no faces, lines or points: its 3 vertices are read as points"):
        mesh = parse_obj(path.read_text(), "cloud.obj")
    assert mesh.points.tolist() == [0, 1, 2] and len(mesh.lines) == 0 and mesh.triangle_count == 0
    with pytest.warns(UserWarning, match="its 3 vertices are read as points"):     # (render passes it on)
        img = render(path, width=16, height=16)
    assert np.count_nonzero((img.to_uint8()[..., :3] != img.to_uint8()[0, 0, :3]).any(axis=2)) == 3
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\nvt 0 0\n")
    with pytest.warns(OBJWarning, match="empty.obj: no faces, lines or points; the mesh is empty"):
        parse_obj(empty.read_text(), "empty.obj")
    with pytest.raises(ValueError) as e:
        render(empty, width=8, height=8)
    assert str(e.value) == f"{empty}: the file has no faces (f), lines (l) or points (p) to render"


def test_mesh_checks_its_line_and_point_arrays():
    with pytest.raises(ValueError, match=r"Mesh.lines: index 5 at segment 1 is out of range for 3 positions"):
        Mesh(np.eye(3), np.zeros((0, 3), int), lines=[[0, 1], [1, 5]])
    with pytest.raises(ValueError, match=r"Mesh.points must be an int array of shape \[P\], got float64 \[2\]"):
        Mesh(np.eye(3), np.zeros((0, 3), int), points=[0.0, 1.0])
    with pytest.raises(ValueError, match="Mesh.line_material_ids is needed: the mesh has material_ids and 1 segments"):
        Mesh(np.eye(3), [[0, 1, 2]], materials=(Material(),), material_ids=[0], lines=[[0, 1]])


# ---------------------------------------------------------------------------- drawing


def test_a_closed_polyline_is_drawn_unlit_in_its_color_every_pixel_once():
    # The loop of docs/points-and-lines.md, from an OBJ: the diamond-exit rule hits each pixel once.
    mesh = parse_quiet(CURVE).replace(material=Material(kd=(0.25, 0.5, 1.0)))
    fb, results = window_draw(mesh, blend="additive", depth_test=None)
    assert [r.program for r in results] == ["unlit"]
    assert ascii_picture(np.rint(fb.color[..., 2] * 1).astype(int)) == (
        "000000000000\n"
        "011111111110\n"
        "010000000010\n"
        "010000000010\n"
        "011111111110\n"
        "000000000000")
    lit = fb.color[..., 2] > 0
    np.testing.assert_array_equal(fb.color[lit][:, :3], np.tile(np.float32([0.25, 0.5, 1.0]), (lit.sum(), 1)))


def test_a_curve_draws_the_pixels_softpipe_draw_draws_for_its_segments_with_width():
    mesh = parse_quiet(CURVE)
    fb, _ = window_draw(mesh, line_width=3)
    ref = sp.Framebuffer(W, H)
    ref.clear((0, 0, 0, 1))
    clip = np.column_stack([mesh.positions @ WINDOW[:3, :3].T + WINDOW[:3, 3], np.ones(mesh.vertex_count)])
    sp.draw(ref, clip, mesh.lines, topology="lines", varyings={"color": np.full((mesh.vertex_count, 3), 0.7)},
            line_width=3)
    np.testing.assert_array_equal(fb.color, ref.color)
    assert ascii_picture(fb.color[..., 0] > 0) == (    # runs of 3 up (right, for the steep ones)
        "..#########.\n"
        "###########.\n"
        "############\n"
        "############\n"
        ".###########\n"
        ".#########..")


def test_a_point_cloud_is_drawn_as_squares_of_point_size():
    mesh = parse_quiet("v 2.5 2.5 0\nv 8 3 0\np 1 2\n")
    fb, results = window_draw(mesh, point_size=3)
    assert [r.program for r in results] == ["unlit"]
    assert ascii_picture(fb.color[..., 0] > 0) == (
        "............\n"
        "............\n"
        ".###..###...\n"
        ".###..###...\n"
        ".###..###...\n"
        "............")


def test_faces_then_lines_then_points_the_faces_lit_the_rest_unlit():
    text = ("v 0 0 0\nv 12 0 0\nv 0 6 0\nv 1.5 4.5 -0.5\nv 10.5 4.5 -0.5\nv 9.5 1.5 -0.5\n"
            "f 1 2 3\nl 4 5\np 6\n")
    mesh = parse_quiet(text)
    fb, results = window_draw(mesh, "normals", cull="none")
    assert [r.program for r in results] == ["normals", "unlit", "unlit"]
    assert np.all(fb.color[1, 1:10, :3] == np.float32(0.7))        # the line: row 4 from the bottom
    assert np.all(fb.color[4, 9, :3] == np.float32(0.7))           # the point
    assert not np.all(fb.color[5, 0, :3] == np.float32(0.7))       # the face, shaded as normals


def test_a_program_of_your_own_draws_the_points_and_reads_point_coord():
    def round_point(varyings, uniforms, frag):
        s, t = frag.point_coord
        if (s - 0.5) ** 2 + (t - 0.5) ** 2 > 0.25:
            return sp.DISCARD
        return (1.0, 1.0, 1.0, 1.0)

    mesh = parse_quiet("v 4.5 2.5 0\np 1\n")
    fb, _ = window_draw(mesh, round_point, point_size=5)
    assert ascii_picture(fb.color[..., 0] > 0) == (
        "............\n"
        "...###......\n"
        "..#####.....\n"
        "..#####.....\n"
        "..#####.....\n"
        "...###......")


def test_render_frames_every_point_of_a_cloud(tmp_path):
    # The 8 corners of a box, seen by the framed camera: 8 pixels (and 8 squares of 9 at size 3).
    path = tmp_path / "box.obj"
    corners = [(x, y, z) for x in (0, 2) for y in (0, 1) for z in (0, 3)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in corners) + "p 1 2 3 4 5 6 7 8\n")
    one = render(path, width=64, height=48, background="black")
    assert (one.color[..., 0] > 0).sum() == 8
    three = render(path, width=64, height=48, background="black", point_size=3)
    assert (three.color[..., 0] > 0).sum() == 72
    assert np.all(three.color[three.color[..., 0] > 0][:, :3] == np.float32(0.7))


def test_the_wireframe_leaves_a_meshs_lines_and_points_alone():
    text = CURVE + "f 1 2 3\n"
    mesh = parse_quiet(text)
    plain = render(mesh, width=40, height=30)
    assert render(mesh, width=40, height=30, wireframe=True).color.shape == plain.color.shape
    lines_only = render(parse_quiet(CURVE), width=40, height=30, wireframe=True)
    assert np.array_equal(lines_only.color, render(parse_quiet(CURVE), width=40, height=30).color)


def test_the_command_line_renders_a_curve_with_a_line_width(capsys, tmp_path):
    path = tmp_path / "curve.obj"
    path.write_text(CURVE)
    out = tmp_path / "curve.png"
    code, _, err = run_cli(capsys, "render", path, "-o", out, "--size", "40x30", "--line-width", "2",
                           "--point-size", "3", "-q")
    assert code == 0, err
    expected = render(path, width=40, height=30, line_width=2, point_size=3).to_image()
    from PIL import Image
    assert np.array_equal(np.asarray(Image.open(out)), np.asarray(expected))


def test_the_command_line_refuses_a_size_that_is_not_pixels(capsys, tmp_path):
    path = tmp_path / "curve.obj"
    path.write_text(CURVE)
    code, _, err = run_cli(capsys, "render", path, "-o", tmp_path / "x.png", "--point-size", "0")
    assert code == 2
    assert "argument --point-size: expected a number of pixels > 0, got '0'" in err
    assert not (tmp_path / "x.png").exists()
