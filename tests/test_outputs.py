"""Outputs that fit numpy, PIL, matplotlib and imageio, named colors, and the CLI's Python equivalents (issue #14)."""
from __future__ import annotations

import html.parser
import io
import re

import numpy as np
import pytest
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.core.colors import color_names, parse_color
from softpipe.light.material import Lighting
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.trace import PixelEvent, PixelHistory
from softpipe.scenes.drawing import as_mesh, draw_mesh, gif_frame, prepare_scene
from softpipe.scenes.scene import Scene, studio_lights


class TinyMesh:
    """A trimesh-like object: only .vertices and .faces (not trimesh, not a softpipe Mesh)."""

    def __init__(self, vertices, faces):
        self.vertices = vertices
        self.faces = faces


def tetra_mesh() -> sp.Mesh:
    positions = np.array([[0, 0, 0], [1.2, 0, 0.1], [0.2, 0.9, 0.3], [0.3, 0.2, 1.4]], dtype=np.float64)
    return sp.Mesh(positions, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), name="tetra")


def drawn() -> sp.Framebuffer:
    fb = sp.Framebuffer(20, 14)
    positions = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
    sp.draw(fb, positions, varyings={"color": np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)})
    return fb


# ---------------------------------------------------------------------------- np.asarray, PIL, matplotlib, imageio


def test_asarray_is_the_saved_rgb_picture(tmp_path):
    fb = drawn()
    a = np.asarray(fb)
    assert a.shape == (14, 20, 3) and a.dtype == np.uint8
    assert np.array_equal(a, fb.to_uint8(alpha=False))
    fb.save(tmp_path / "t.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "t.png")), a)
    a[...] = 0                                            # a copy: the framebuffer is unchanged
    assert np.asarray(fb).any()
    assert np.asarray(fb, dtype=np.float64).dtype == np.float64
    with pytest.raises(ValueError, match="cannot be had without a copy"):
        np.asarray(fb, copy=False)


def test_pil_fromarray_takes_it_as_it_is():
    fb = drawn()
    image = Image.fromarray(np.asarray(fb))
    assert image.mode == "RGB" and image.size == (20, 14)
    assert np.array_equal(np.asarray(image), np.asarray(fb.to_image()))


def test_matplotlib_imshow_shows_the_picture():
    pytest.importorskip("matplotlib", reason="matplotlib is not installed (not a softpipe dependency)")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fb = drawn()
    fig, ax = plt.subplots()
    shown = ax.imshow(fb)
    assert np.array_equal(np.asarray(shown.get_array()), np.asarray(fb))
    plt.close(fig)


def test_imageio_writes_it(tmp_path):
    imageio = pytest.importorskip("imageio", reason="imageio is not installed (not a softpipe dependency)")
    fb = drawn()
    imageio.imwrite(tmp_path / "x.png", fb)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "x.png").convert("RGB")), np.asarray(fb))


# ---------------------------------------------------------------------------- save


@pytest.mark.parametrize("name, pil_format", [("a.png", "PNG"), ("a.jpg", "JPEG"), ("a.JPEG", "JPEG"),
                                              ("a.bmp", "BMP"), ("a.tif", "TIFF"), ("a.webp", "WEBP")])
def test_save_picks_the_format_from_the_extension(tmp_path, name, pil_format):
    path = drawn().save(tmp_path / "sub" / name)
    assert path == tmp_path / "sub" / name
    with Image.open(path) as im:
        assert im.format == pil_format and im.size == (20, 14)


def test_save_to_file_objects(tmp_path):
    fb = drawn()
    buf = io.BytesIO()
    assert fb.save(buf, format="png") is buf
    fb.save(tmp_path / "a.png")
    assert buf.getvalue() == (tmp_path / "a.png").read_bytes()          # the same bytes as to a path
    for fmt in ("PNG", ".png", "jpeg", "jpg"):
        out = io.BytesIO()
        fb.save(out, format=fmt)
        assert Image.open(io.BytesIO(out.getvalue())).size == (20, 14)
    with open(tmp_path / "b.bmp", "wb") as f:                            # a named file: its extension
        fb.save(f)
    assert Image.open(tmp_path / "b.bmp").format == "BMP"
    out = io.BytesIO()
    fb.save(out, format="png", alpha=True)
    assert Image.open(io.BytesIO(out.getvalue())).mode == "RGBA"


@pytest.mark.parametrize("call, error, message", [
    (lambda fb, d: fb.save(d / "x.xyz"), ValueError, r"x\.xyz: cannot write images with extension '\.xyz'"),
    (lambda fb, d: fb.save(d / "noext"), ValueError, r"noext: no extension to tell the image format"),
    (lambda fb, d: fb.save(io.BytesIO()), ValueError, r"saving to a file object needs format=, e\.g\."),
    (lambda fb, d: fb.save(io.BytesIO(), format="nope"), ValueError, r"cannot write images in format 'nope'"),
    (lambda fb, d: fb.save(io.StringIO(), format="png"), TypeError, r"needs a binary file \(opened with 'wb'\)"),
    (lambda fb, d: fb.save(42), TypeError, r"save\(\) takes a path or a binary file object, got int"),
    (lambda fb, d: fb.save(d / "a.jpg", alpha=True), ValueError, r"JPEG images have no alpha channel"),
])
def test_save_errors_name_the_problem(tmp_path, call, error, message):
    with pytest.raises(error, match=message) as e:
        call(drawn(), tmp_path)
    assert "\n" not in str(e.value)


# ---------------------------------------------------------------------------- colors


@pytest.mark.parametrize("text, expected", [
    ("red", (1.0, 0.0, 0.0)),
    ("White", (1.0, 1.0, 1.0)),
    ("#ff8000", (1.0, 128 / 255, 0.0)),
    ("#f80", (1.0, 136 / 255, 0.0)),
    ("#ff800080", (1.0, 128 / 255, 0.0, 128 / 255)),
    ("rgb(255, 128, 0)", (1.0, 128 / 255, 0.0)),
    ("0.1,0.2,0.3", (0.1, 0.2, 0.3)),
    (" 0.1 0.2 0.3 0.5 ", (0.1, 0.2, 0.3, 0.5)),
    ((0.5, 2.0, 0.0), (0.5, 2.0, 0.0)),                  # numbers as they are (unclamped)
    (np.array([0.25, 0.5, 0.75, 1.0]), (0.25, 0.5, 0.75, 1.0)),
])
def test_parse_color(text, expected):
    assert parse_color(text) == pytest.approx(expected)


@pytest.mark.parametrize("value, error, message", [
    ("redd", ValueError, r"^unknown color 'redd' \(did you mean 'red'\?\): expected a CSS name such as 'red'"),
    ("mauve-ish", ValueError, r"^unknown color 'mauve-ish': expected"),
    ("2,0,0", ValueError, r"^color '2,0,0': color components must be in 0\.\.1$"),
    ("0.1,0.2", ValueError, r"^color '0\.1,0\.2': expected 3 or 4 numbers \(r,g,b\[,a\]\), got 2$"),
    ((1, 0), ValueError, r"^color \(1, 0\): expected 3 or 4 numbers \(RGB or RGBA\), got 2$"),
    ((1, 0, float("inf")), ValueError, r"every component must be finite"),
    (3, TypeError, r"^expected a color .* got int 3$"),
    (("r", "g", "b"), TypeError, r"got \('r', 'g', 'b'\)"),
])
def test_parse_color_errors(value, error, message):
    with pytest.raises(error, match=message):
        parse_color(value)


def test_the_command_line_uses_the_same_parser():
    from softpipe.tools import cli
    for text in ("red", "#102030", "0.1,0.2,0.3", "rgb(1,2,3)"):
        assert cli._color(text) == parse_color(text)
    assert "steelblue" in color_names() and len(color_names()) > 100


def test_clear_takes_named_colors():
    fb = sp.Framebuffer(3, 2)
    assert tuple(np.asarray(fb.clear("red"))[0, 0]) == (255, 0, 0)
    assert tuple(fb.clear("#ff8000").to_uint8()[1, 2]) == (255, 128, 0, 255)
    assert tuple(fb.clear("#ff800040").to_uint8()[0, 0]) == (255, 128, 0, 64)
    assert tuple(np.asarray(fb.clear("0,0.5,1"))[0, 0]) == (0, 128, 255)
    with pytest.raises(ValueError, match=r"^clear color: unknown color 'bleu' \(did you mean 'blue'\?\)"):
        fb.clear("bleu")
    with pytest.raises(ValueError, match=r"clear color must be 3 or 4 finite numbers"):
        fb.clear((1, 0))


def test_materials_and_lights_take_named_colors():
    m = sp.Material(kd="orange", ks="#ffffff")
    assert m.kd == pytest.approx((1.0, 165 / 255, 0.0)) and m.ks == (1.0, 1.0, 1.0)
    assert sp.Light.directional((0, 0, -1), diffuse="white").diffuse == (1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match=r"^Material\.kd must be a color: unknown color 'oragne' \(did you mean "
                                         r"'orange'\?\)"):
        sp.Material(kd="oragne")
    with pytest.raises(ValueError, match=r"^Material\.kd must be an RGB color \(no alpha\), got string '#ff000080'$"):
        sp.Material(kd="#ff000080")


# ---------------------------------------------------------------------------- trimesh-like meshes


CAMERA = Camera(eye=(2.0, 1.5, 3.0), target=(0.4, 0.3, 0.5), fovy=40.0)


def test_draw_mesh_takes_a_trimesh_like_object():
    mesh = tetra_mesh()
    tiny = TinyMesh(mesh.positions.tolist(), mesh.indices.tolist())
    a, b = sp.Framebuffer(40, 30), sp.Framebuffer(40, 30)
    draw_mesh(a, mesh, CAMERA, "phong")
    draw_mesh(b, tiny, CAMERA, "phong")
    assert (a.depth < 1).sum() > 50
    assert a.color.tobytes() == b.color.tobytes()
    converted = as_mesh(tiny)
    assert isinstance(converted, sp.Mesh) and converted.name == "TinyMesh" and converted.triangle_count == 4
    assert as_mesh(mesh) is mesh


def test_a_trimesh_like_object_brings_its_normals_and_uvs():
    class WithMore(TinyMesh):
        name = "more"

        class visual:
            uv = [[0, 0], [1, 0], [0, 1], [1, 1]]

    thing = WithMore(tetra_mesh().positions, tetra_mesh().indices)
    thing.vertex_normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    m = as_mesh(thing)
    assert m.name == "more" and m.uvs.shape == (4, 2) and np.array_equal(m.normals, thing.vertex_normals)


@pytest.mark.parametrize("thing, error, message", [
    (42, TypeError, r"expected a softpipe Mesh or an object with \.vertices and \.faces \(like a trimesh\.Trimesh\), "
                    r"got int"),
    (TinyMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2, 3]]), ValueError,
     r"TinyMesh: faces must be triangles, an \[M, 3\] array of vertex indices, got shape \(1, 4\)"),
])
def test_not_a_mesh(thing, error, message):
    with pytest.raises(error, match=message):
        draw_mesh(sp.Framebuffer(4, 4), thing, CAMERA)


def test_textured_needs_texture_coordinates():
    with pytest.raises(ValueError, match=r"^tetra has no texture coordinates \(uv\), so program 'textured' cannot "
                                         r"draw it$"):
        draw_mesh(sp.Framebuffer(4, 4), tetra_mesh(), CAMERA, "textured")
    with pytest.raises(ValueError, match=r"^tetra: the model has no texture coordinates \(vt\), so program "
                                         r"'textured' cannot draw it$"):
        sp.render(tetra_mesh(), program="textured", width=8, height=8)


# ---------------------------------------------------------------------------- draw_mesh's default lights


def test_draw_mesh_lights_like_the_command_line_by_default():
    mesh = tetra_mesh()
    default, studio, old = (sp.Framebuffer(40, 30) for _ in range(3))
    draw_mesh(default, mesh, CAMERA, "phong")
    draw_mesh(studio, mesh, CAMERA, "phong", lighting=Lighting(studio_lights(CAMERA)))
    draw_mesh(old, mesh, CAMERA, "phong", lighting=sp.Light.directional((1.0, -1.0, -1.0)))
    assert default.color.tobytes() == studio.color.tobytes()
    assert default.color.tobytes() != old.color.tobytes()
    # and that is what softpipe.render draws for a framed mesh
    scene = Scene.from_model(mesh, width=40, height=30)
    camera = scene.view_camera()
    by_hand = sp.Framebuffer(40, 30).clear(scene.background)
    draw_mesh(by_hand, mesh, camera, "phong")
    assert np.array_equal(np.asarray(by_hand), np.asarray(sp.render(mesh, width=40, height=30)))


# ---------------------------------------------------------------------------- softpipe.render, softpipe.turntable


def test_render_is_the_command_line_byte_for_byte(capsys, tmp_path):
    cli = tmp_path / "cli.png"
    code, out, err = run_cli(capsys, "render", "teapot", "-o", cli, "--size", "64x48", "-q")
    assert code == 0, err
    api = sp.render("teapot", width=64, height=48).save(tmp_path / "api.png")
    assert cli.read_bytes() == api.read_bytes()
    # the defaults: 640×480, framed, studio lights, phong
    fb = sp.render("teapot")
    assert (fb.width, fb.height) == (640, 480)
    code, _, err = run_cli(capsys, "render", "teapot", "-o", tmp_path / "full.png", "-q")
    assert code == 0, err
    assert (tmp_path / "full.png").read_bytes() == fb.save(tmp_path / "api-full.png").read_bytes()


def test_render_options_are_the_command_line_options(capsys, tetra_obj, tmp_path):
    argv = ["--size", "48x36", "--azimuth", "120", "--elevation", "-10", "--fovy", "50", "--background", "white",
            "--program", "gooch", "--cull", "none", "--wireframe", "--wire-color", "red", "--samples", "grid4"]
    code, _, err = run_cli(capsys, "render", tetra_obj, "-o", tmp_path / "cli.png", "-q", *argv)
    assert code == 0, err
    fb = sp.render(tetra_obj, width=48, height=36, azimuth=120, elevation=-10, fovy=50, background="white",
                   program="gooch", cull="none", wireframe=True, wire_color="red", samples="grid4")
    assert (tmp_path / "cli.png").read_bytes() == fb.save(tmp_path / "api.png").read_bytes()
    assert tuple(np.asarray(fb)[0, 0]) == (255, 255, 255)


def test_render_takes_every_kind_of_model(tetra_obj, tmp_path):
    reference = np.asarray(sp.render(tetra_obj, width=32, height=24))
    assert (reference != reference[0, 0]).any(axis=2).sum() > 30
    mesh = tetra_mesh()
    for model in (str(tetra_obj), mesh, TinyMesh(mesh.positions, mesh.indices),
                  Scene.from_model(tetra_obj, width=32, height=24)):
        assert np.array_equal(np.asarray(sp.render(model, width=32, height=24)), reference), type(model)
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 32\nheight = 24\n[[meshes]]\nobj = "tetra.obj"\n')
    assert np.array_equal(np.asarray(sp.render(scene)), reference)


def test_render_leaves_a_given_scene_alone(tetra_obj):
    scene = Scene.from_model(tetra_obj, width=16, height=12)
    sp.render(scene, program="normals", cull="none", width=8)
    assert scene.objects[0].program is None and scene.width == 16
    assert prepare_scene(scene, program="normals").program == "normals"


def test_render_with_stages_writes_the_pictures(tetra_obj, tmp_path, capsys):
    results = []
    sp.render(tetra_obj, width=24, height=18, stages=tmp_path / "api", results=results)
    assert sorted(results[0].pictures) == ["contact-sheet", "coverage", "depth", "final", "overdraw", "primitives",
                                           "vertices"]
    code, _, _ = run_cli(capsys, "render", tetra_obj, "-o", tmp_path / "x.png", "--size", "24x18",
                         "--stages", tmp_path / "cli")
    assert code == 0
    for name in ("06-final.png", "contact-sheet.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


@pytest.mark.parametrize("model, kwargs, error, message", [
    ("bunnie", {}, ValueError, r"^'bunnie' is neither a file nor a bundled model; the models are: bunny, "),
    ("nope/x.obj", {}, FileNotFoundError, r"^nope/x\.obj: no such file$"),
    (42, {}, TypeError, r"expected a softpipe Mesh or an object with \.vertices and \.faces"),
    ("teapot", {"program": "nope"}, ValueError, r"^program: unknown program 'nope'; registered programs: "),
    ("teapot", {"cull": "sideways"}, ValueError, r"^cull must be one of back, front, none, got 'sideways'$"),
    ("teapot", {"background": "mauve"}, ValueError, r"^background: unknown color 'mauve'"),
    ("teapot", {"wire_color": (1, 0)}, ValueError, r"^wire_color: color \(1, 0\): expected 3 or 4 numbers"),
    ("teapot", {"width": 0}, ValueError, r"^width must be 1 to 16384 pixels \(MAX_DIMENSION\), got 0$"),
    ("teapot", {"height": 2.5}, TypeError, r"^height must be a whole number of pixels, got float 2\.5$"),
    ("teapot", {"fovy": 180}, ValueError, r"^fovy must be in \(0, 180\) degrees, got 180$"),
    ("teapot", {"samples": "grid5"}, ValueError, r"grid needs a square number"),
    ("teapot", {"texture": "nope.png"}, FileNotFoundError, r"^texture: nope\.png: no such file$"),
])
def test_render_errors_are_one_line(model, kwargs, error, message):
    with pytest.raises(error, match=message) as e:
        sp.render(model, **kwargs)
    assert "\n" not in str(e.value)


def test_turntable_is_the_command_line_byte_for_byte(capsys, tetra_obj, tmp_path):
    for name in ("cli.gif", "cli.png"):
        code, _, err = run_cli(capsys, "turntable", tetra_obj, "-o", tmp_path / name, "--frames", "3", "--fps", "10",
                               "-q")
        assert code == 0, err
    steps = []
    gif = sp.turntable(tetra_obj, tmp_path / "api.gif", frames=3, fps=10, progress=lambda i, n: steps.append((i, n)))
    apng = sp.turntable(tetra_obj, tmp_path / "api.png", frames=3, fps=10)
    assert steps == [(1, 3), (2, 3), (3, 3)]
    assert gif.read_bytes() == (tmp_path / "cli.gif").read_bytes()
    assert apng.read_bytes() == (tmp_path / "cli.png").read_bytes()
    with Image.open(gif) as im:
        assert im.n_frames == 3 and im.size == (320, 240) and im.info["duration"] == 100


@pytest.mark.parametrize("path, kwargs, message", [
    ("spin.jpg", {}, r"spin\.jpg: an animation is written as \.gif or \.png \(animated PNG\), not '\.jpg'$"),
    ("spin.gif", {"frames": 0}, r"^frames must be a whole number from 1 to 3600, got 0$"),
    ("spin.gif", {"fps": 0}, r"^fps must be in 0\.1\.\.100 frames per second, got 0$"),
])
def test_turntable_errors(tmp_path, path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        sp.turntable("teapot", tmp_path / path, **kwargs)


# ---------------------------------------------------------------------------- GIF banding


def _banding(image: Image.Image, frame: Image.Image, block: int = 8) -> float:
    """Mean error of block averages: what the eye sees as bands (dithering keeps local means)."""
    a = np.asarray(image.convert("RGB"), dtype=np.float64)
    b = np.asarray(frame.convert("RGB"), dtype=np.float64)
    h, w = (a.shape[0] // block) * block, (a.shape[1] // block) * block

    def means(x):
        return x[:h, :w].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))

    return float(np.abs(means(a) - means(b)).mean())


def test_gif_frames_are_dithered_and_band_less():
    # a smooth two-way gradient with far more than 256 colors, as shading makes
    y, x = np.mgrid[0:128, 0:256]
    rgb = np.stack([x / 255.0, y / 127.0 * 0.6 + 0.2, 0.5 + 0.4 * np.sin(x / 40.0)], axis=-1)
    image = Image.fromarray(np.rint(rgb * 255).astype(np.uint8), "RGB")
    assert len(np.unique(np.asarray(image).reshape(-1, 3), axis=0)) > 2000
    before = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT)       # what turntable did
    after = gif_frame(image)
    assert after.mode == "P" and len(after.getcolors(256)) <= 256
    print(f"banding (mean error of 8x8 block means): before {_banding(image, before):.3f}, "
          f"after {_banding(image, after):.3f}")
    assert _banding(image, after) < 0.5 * _banding(image, before)


# ---------------------------------------------------------------------------- pixel history in Jupyter


class _Cells(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.rows, self.paragraphs, self._cell, self._text = [], [], None, None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "p":
            self._text = []

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.rows[-1].append("".join(self._cell))
            self._cell = None
        elif tag == "p":
            self.paragraphs.append("".join(self._text))
            self._text = None

    def handle_data(self, data):
        for sink in (self._cell, self._text):
            if sink is not None:
                sink.append(data)


def _numbers(cell: str):
    return [float(v) for v in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|nan|inf", cell)]


def test_pixel_history_is_an_html_table():
    fb = sp.Framebuffer(16, 16)
    pos = np.array([[-1, -1, 0.5, 1], [1, -1, 0.5, 1], [0, 1, 0.5, 1],
                    [-1, -1, 0.2, 1], [1, -1, 0.2, 1], [0, 1, 0.2, 1],
                    [-1, -1, 0.8, 1], [1, -1, 0.8, 1], [0, 1, 0.8, 1]], dtype=float)
    colors = np.repeat(np.eye(3), 3, axis=0)
    trace = sp.draw(fb, pos, varyings={"color": colors}, trace=True)
    history = trace.pixel_history(8, 8)
    assert [e.verdict for e in history] == ["written", "written", "depth-failed"]
    parsed = _Cells()
    parsed.feed(history._repr_html_())
    assert parsed.paragraphs == [str(history).splitlines()[0]]
    header, *rows = parsed.rows
    assert header == ["#", "prim", "sample", "depth", "color", "shader output", "merger", "color after"]
    assert len(rows) == len(history)
    for event, row in zip(history, rows):
        assert int(row[0]) == event.index and int(row[1]) == event.primitive_id and int(row[2]) == event.sample
        assert float(row[3]) == pytest.approx(event.depth, abs=1e-6)
        np.testing.assert_allclose(_numbers(row[4]), event.varyings.color, rtol=1e-3, atol=1e-6)
        np.testing.assert_allclose(_numbers(row[5]), event.color, rtol=1e-3, atol=1e-6)
        assert row[6] == event.verdict
        np.testing.assert_allclose(_numbers(row[7]), event.color_after, rtol=1e-3, atol=1e-6)
    assert 'background:rgb(255,0,0)' in history._repr_html_()       # a swatch beside the red output


def test_pixel_history_html_escapes_every_value():
    from collections import namedtuple
    V = namedtuple("V", ["label"])
    evil = "<script>alert('x')</script> & \"q\""
    event = PixelEvent(index=0, primitive_id=1, triangle=1, sample=0, depth=0.5, varyings=V(evil),
                       color=(1.0, 0.0, 0.0, 1.0), verdict="<b>written</b>", color_after=(1.0, 0.0, 0.0, 1.0))
    history = PixelHistory(3, 4, [event], (0.0, 0.0, 0.0, 1.0))
    text = history._repr_html_()
    assert "<script>" not in text and "<b>" not in text
    parsed = _Cells()
    parsed.feed(text)
    header, row = parsed.rows
    assert row[4] == evil and row[6] == "<b>written</b>"
    empty = PixelHistory(0, 0, [], (0.0, 0.0, 0.0, 1.0))
    assert "<table>" not in empty._repr_html_() and "0 fragment(s)" in empty._repr_html_()
