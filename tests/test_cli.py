"""The command line, run in-process with main([...]) on tiny images."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import TETRA_UV_OBJ, run_cli
from PIL import Image

from softpipe.programs import PROGRAMS


def one_error_line(err: str, command: str = "render") -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"softpipe {command}: error: "), err
    return lines[0]


# ---------------------------------------------------------------------------- help


def test_help_lists_every_command(capsys):
    code, out, _ = run_cli(capsys, "--help")
    assert code == 0
    for command in ("render", "turntable", "demo", "programs", "--version"):
        assert command in out


@pytest.mark.parametrize("command, options", [
    ("render", ["--size", "--width", "--height", "--program", "--azimuth", "--elevation", "--background", "--cull",
                "--wireframe", "--samples", "--msaa", "--stages", "--texture", "--fovy", "-o"]),
    ("turntable", ["--frames", "--fps", "--size", "--program", "--elevation", "-o"]),
    ("demo", ["--width", "--height", "-o"]),
    ("programs", []),
])
def test_each_command_has_complete_help(capsys, command, options):
    code, out, _ = run_cli(capsys, command, "--help")
    assert code == 0
    for option in options:
        assert option in out
    if command in ("render", "turntable"):
        assert f"In Python: softpipe.{command}(INPUT" in " ".join(out.split())
    if command == "render":
        assert "'phong' when registered, else 'normals'" in " ".join(out.split())
        for name in PROGRAMS:
            assert name in out


@pytest.mark.parametrize("command", ["render", "turntable", "explore", "view"])
def test_help_names_the_model_formats_input_takes(capsys, command):
    code, out, _ = run_cli(capsys, command, "--help")
    text = " ".join(out.split())
    assert code == 0
    assert ("INPUT a .obj model (or .ply, .stl, .gltf, .glb, read through trimesh), a bundled model's name or a "
            ".toml scene file") in text
    if command == "render":
        assert "INPUT.ply, INPUT.stl, INPUT.gltf, INPUT.glb: a PLY, STL or glTF 2.0 model read through trimesh" in text


def test_help_examples_use_the_bundled_models(capsys):
    out = run_cli(capsys, "--help")[1]
    assert "softpipe render bunny -o bunny.png" in out and "shared" not in out      # no folder a clone lacks
    assert "bunny, teapot, suzanne, spot, armadillo" in out


def test_no_command_is_an_error(capsys):
    code, _, err = run_cli(capsys)
    assert code == 2 and err.strip() == ("softpipe: error: a command is required: render, turntable, demo, explore, "
                                         "view, programs or batch (see 'softpipe --help')")


def test_python_dash_m_softpipe():
    done = subprocess.run([sys.executable, "-m", "softpipe", "--help"], capture_output=True, text=True)
    assert done.returncode == 0 and "turntable" in done.stdout


def test_programs_lists_the_registered_programs(capsys):
    code, out, _ = run_cli(capsys, "programs")
    assert code == 0
    for name in PROGRAMS:
        assert name in out


# ---------------------------------------------------------------------------- render


def test_render_an_obj(capsys, tetra_uv_obj, tmp_path):
    out_png = tmp_path / "out" / "tetra.png"
    code, out, err = run_cli(capsys, "render", tetra_uv_obj, "-o", out_png, "--size", "64x48")
    assert code == 0, err
    assert Image.open(out_png).size == (64, 48)
    assert f"softpipe render: wrote {out_png.resolve()} (64×48, 4 triangles, program " in out
    assert out.rstrip().endswith(" s)")


def test_render_options(capsys, tetra_uv_obj, tmp_path):
    plain, wired = tmp_path / "plain.png", tmp_path / "wired.png"
    common = ["--width", "64", "--height", "48", "--azimuth", "60", "--elevation", "-10", "--cull", "none",
              "--background", "#102030", "--program", "normals", "--fovy", "50"]
    assert run_cli(capsys, "render", tetra_uv_obj, "-o", plain, *common)[0] == 0
    assert run_cli(capsys, "render", tetra_uv_obj, "-o", wired, *common, "--wireframe", "--wire-color", "1,0,1")[0] == 0
    a, b = np.asarray(Image.open(plain)), np.asarray(Image.open(wired))
    assert tuple(a[0, 0]) == (0x10, 0x20, 0x30)
    changed = (a != b).any(axis=2)
    assert changed.sum() > 10 and (b[changed] == (255, 0, 255)).all()


def test_render_with_samples_and_msaa(capsys, tetra_uv_obj, tmp_path):
    for extra in (["--samples", "grid4"], ["--msaa"], ["--samples", "rgss4", "--msaa"]):
        code, _, err = run_cli(capsys, "render", tetra_uv_obj, "-o", tmp_path / "s.png", "--size", "32x24", *extra)
        assert code == 0, err


def test_render_other_image_formats(capsys, tetra_uv_obj, tmp_path):
    code, _, _ = run_cli(capsys, "render", tetra_uv_obj, "-o", tmp_path / "t.jpg", "--size", "32x24")
    assert code == 0 and Image.open(tmp_path / "t.jpg").format == "JPEG"


def test_stages_writes_every_picture(capsys, tetra_uv_obj, tmp_path):
    stages = tmp_path / "stages"
    code, out, err = run_cli(capsys, "render", tetra_uv_obj, "-o", tmp_path / "t.png", "--size", "64x48",
                             "--stages", stages)
    assert code == 0, err
    names = sorted(p.name for p in stages.iterdir())
    assert names == ["01-vertices.png", "02-primitives.png", "03-coverage.png", "04-depth.png",
                     "05-overdraw.png", "06-final.png", "contact-sheet.png"]
    for name in names:
        assert f"stage picture {stages / name}" in out
    assert Image.open(stages / "06-final.png").size == (64, 48)


def test_texture_option(capsys, tetra_uv_obj, tmp_path):
    Image.new("RGB", (8, 8), (200, 30, 30)).save(tmp_path / "red.png")
    code, out, err = run_cli(capsys, "render", tetra_uv_obj, "-o", tmp_path / "t.png", "--size", "32x24",
                         "--texture", tmp_path / "red.png")
    assert code == 0, err
    if "textured" in PROGRAMS:
        assert "program textured" in out
    else:
        assert "no 'textured' program is registered yet" in err


def test_render_a_scene_file(capsys, tetra_uv_obj, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text('[render]\nwidth = 40\nheight = 30\n[[meshes]]\nobj = "tetra.obj"\n'
                     '[[meshes]]\nshape = "cube"\ntransform = { translate = [2, 0, 0] }\n')
    code, out, err = run_cli(capsys, "render", scene, "-o", tmp_path / "a.png")
    assert code == 0, err
    assert Image.open(tmp_path / "a.png").size == (40, 30)
    assert "draw 1/2: tetra" in err and "draw 2/2: cube (12 triangles)" in err
    code, _, _ = run_cli(capsys, "render", scene, "-o", tmp_path / "b.png", "--size", "20x10", "--azimuth", "90", "-q")
    assert code == 0 and Image.open(tmp_path / "b.png").size == (20, 10)
    stages = tmp_path / "stages"
    code, out, _ = run_cli(capsys, "render", scene, "-o", tmp_path / "c.png", "--stages", stages, "-q")
    assert code == 0
    assert sorted(p.name for p in stages.iterdir()) == ["01-tetra", "02-cube"]
    assert (stages / "02-cube" / "contact-sheet.png").exists()


def test_render_a_bundled_model_by_name(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(capsys, "render", "suzanne", "--size", "32x24", "-q")
    assert code == 0, err
    assert Image.open(tmp_path / "out" / "suzanne.png").size == (32, 24)       # named after the model
    assert "(32×24, 968 triangles, program phong, " in out
    code, _, err = run_cli(capsys, "render", "bunnie", "-o", tmp_path / "x.png")
    assert code == 2
    assert "'bunnie' is neither a file nor a bundled model; the models are: bunny, " in one_error_line(err)


def test_demo_still_works(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "demo", "-o", tmp_path / "demo.png", "--width", "64", "--height", "48")
    assert code == 0 and "softpipe demo: wrote" in out
    assert Image.open(tmp_path / "demo.png").size == (64, 48)


# ---------------------------------------------------------------------------- errors: one line, status 2


def test_missing_file(capsys, tmp_path):
    code, _, err = run_cli(capsys, "render", tmp_path / "nope.obj", "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err) == f"softpipe render: error: {tmp_path / 'nope.obj'}: no such file"


def test_bad_obj_names_file_and_line(capsys, tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 x\nf 1 2 3\n")
    code, _, err = run_cli(capsys, "render", bad, "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err) == (f"softpipe render: error: {bad}:3: expected 3 numbers after 'v', "
                                   "got 'v 0 1 x'")
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    code, _, err = run_cli(capsys, "render", bad, "-o", tmp_path / "x.png")
    assert code == 2 and f"{bad}:4: " in one_error_line(err)


def test_bad_scene_file(capsys, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[[meshes]]\nshape = "cube"\n[[lights]]\nkind = "point"\ncolour = 1\n')
    code, _, err = run_cli(capsys, "render", scene, "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err).startswith(f"softpipe render: error: {scene}: unknown key 'colour' in [[lights]] #1")


@pytest.mark.parametrize("options, expected", [
    (["--size", "10"], "argument --size: expected WIDTHxHEIGHT in pixels, e.g. 640x480, got '10'"),
    (["--size", "0x10"], "argument --size: expected a positive width and height"),
    (["--width", "-3"], "argument --width: expected a positive number of pixels, got -3"),
    (["--size", "20000x10"], "image size 20000×10: a side may be at most 16384 pixels"),
    (["--size", "8x8", "--width", "9"], "give --size or --width/--height, not both"),
    (["--program", "nope"], "--program: unknown program 'nope'; registered programs: "),
    (["--cull", "sideways"], "argument --cull: invalid choice: 'sideways'"),
    (["--samples", "grid5"], "argument --samples: sample pattern 'grid5': grid needs a square number"),
    (["--background", "mauve-ish"], "argument --background: unknown color 'mauve-ish': expected a CSS name such as "
                                    "'red', '#rrggbb'"),
    (["--background", "gren"], "argument --background: unknown color 'gren' (did you mean 'green'?)"),
    (["--background", "2,0,0"], "argument --background: color '2,0,0': color components must be in 0..1"),
    (["--wire-color", "0,1"], "argument --wire-color: color '0,1': expected 3 or 4 numbers (r,g,b[,a]), got 2"),
    (["--azimuth", "north"], "argument --azimuth: expected an angle in degrees, got 'north'"),
    (["--fovy", "190"], "argument --fovy: expected a field of view in (0, 180) degrees"),
    (["-o", "x.xyz"], "x.xyz: cannot write images with extension '.xyz'"),
    (["--texture", "nope.png"], "--texture: nope.png: no such file"),
    (["--bogus"], "unrecognized arguments: --bogus"),
])
def test_bad_options(capsys, tetra_uv_obj, tmp_path, options, expected):
    argv = ["render", tetra_uv_obj, *options] if "-o" in options else ["render", tetra_uv_obj, "-o", tmp_path / "x.png",
                                                                 *options]
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert expected in one_error_line(err)


def test_warnings_are_one_line_each(capsys, tmp_path):
    obj = tmp_path / "m.obj"
    obj.write_text("mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _, err = run_cli(capsys, "render", obj, "-o", tmp_path / "m.png", "--size", "16x12")
    assert code == 0
    warning = [line for line in err.splitlines() if "warning" in line]
    assert len(warning) == 1 and warning[0].startswith("softpipe render: warning: ") and "gone.mtl" in warning[0]


def test_texture_needs_uvs(capsys, tmp_path):
    plain = tmp_path / "plain.obj"
    plain.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    Image.new("RGB", (2, 2)).save(tmp_path / "t.png")
    code, _, err = run_cli(capsys, "render", plain, "--texture", tmp_path / "t.png", "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err) == (f"softpipe render: error: {plain} has no texture coordinates (vt), so a texture "
                                   "cannot be applied")


def test_program_textured_needs_uvs(capsys, tmp_path):
    plain = tmp_path / "plain.obj"
    plain.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    for command, output in (("render", "x.png"), ("turntable", "x.gif")):
        code, _, err = run_cli(capsys, command, plain, "--program", "textured", "-o", tmp_path / output)
        assert code == 2
        assert one_error_line(err, command) == (f"softpipe {command}: error: {plain}: the model has no texture "
                                                "coordinates (vt), so program 'textured' cannot draw it")
    scene = tmp_path / "s.toml"
    scene.write_text('[[meshes]]\nobj = "plain.obj"\nprogram = "textured"\n')
    code, _, err = run_cli(capsys, "render", scene, "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err).endswith(f"{scene}: mesh 'plain' has no texture coordinates (vt), so program "
                                        "'textured' cannot draw it")


def test_version(capsys):
    import softpipe
    code, out, err = run_cli(capsys, "--version")
    assert code == 0 and out.strip() == f"softpipe {softpipe.__version__}" and err == ""
    done = subprocess.run([sys.executable, "-m", "softpipe", "--version"], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == f"softpipe {softpipe.__version__}"


def test_named_colors(capsys, tetra_uv_obj, tmp_path):
    out = tmp_path / "c.png"
    code, _, err = run_cli(capsys, "render", tetra_uv_obj, "-o", out, "--size", "16x12", "--background", "red")
    assert code == 0, err
    assert tuple(np.asarray(Image.open(out))[0, 0]) == (255, 0, 0)
    code, _, err = run_cli(capsys, "render", tetra_uv_obj, "-o", out, "--size", "16x12", "--background", "#ff8000")
    assert code == 0 and tuple(np.asarray(Image.open(out))[0, 0]) == (255, 128, 0)


def test_angles_need_a_framed_camera(capsys, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\neye = [0, 0, 5]\n[[meshes]]\nshape = "cube"\n')
    code, _, err = run_cli(capsys, "render", scene, "--azimuth", "10", "-o", tmp_path / "x.png")
    assert code == 2
    assert one_error_line(err) == (f"softpipe render: error: {scene}: azimuth/elevation apply to a framed camera, "
                                   "and this scene's [camera] gives an eye")


def test_not_a_model(capsys, tmp_path):
    (tmp_path / "notes.txt").write_text("hi")
    code, _, err = run_cli(capsys, "render", tmp_path / "notes.txt")
    assert code == 2 and "expected a .obj model or a .toml scene file" in one_error_line(err)
    code, _, err = run_cli(capsys, "render", tmp_path)
    assert code == 2 and "is a directory" in one_error_line(err)


# ---------------------------------------------------------------------------- turntable


def test_turntable_writes_a_gif_with_every_frame(capsys, tetra_uv_obj, tmp_path):
    gif = tmp_path / "spin.gif"
    code, out, err = run_cli(capsys, "turntable", tetra_uv_obj, "-o", gif, "--frames", "4", "--size", "32x24",
                             "--fps", "10")
    assert code == 0, err
    assert [line for line in err.splitlines() if line.startswith("frame")] == [f"frame {i}/4" for i in range(1, 5)]
    with Image.open(gif) as im:
        assert im.n_frames == 4 and im.size == (32, 24)
        assert im.info["duration"] == 100 and im.info["loop"] == 0
    assert f"softpipe turntable: wrote {gif.resolve()} (4 frames, 32×24, 100 ms each, " in out


def test_turntable_of_a_scene_with_its_own_camera(capsys, tetra_uv_obj, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\neye = [0, 1, 4]\n[render]\nwidth = 24\nheight = 16\n'
                     '[[meshes]]\nobj = "tetra.obj"\n')
    apng = tmp_path / "spin.png"
    code, _, err = run_cli(capsys, "turntable", scene, "-o", apng, "--frames", "3", "-q")
    assert code == 0, err
    assert err == ""
    with Image.open(apng) as im:
        assert im.n_frames == 3


@pytest.mark.parametrize("options, expected", [
    (["--frames", "0"], "argument --frames: expected 1 to 3600 frames, got 0"),
    (["--fps", "0"], "argument --fps: expected frames per second in 0.1..100"),
    (["-o", "spin.jpg"], "spin.jpg: an animation is written as .gif or .png (animated PNG), not '.jpg'"),
])
def test_turntable_errors(capsys, tetra_uv_obj, options, expected):
    code, _, err = run_cli(capsys, "turntable", tetra_uv_obj, *options)
    assert code == 2 and expected in one_error_line(err, "turntable")


def test_allow_outside_paths(capsys, tmp_path):
    """Files named outside the model's (scene's) folder are refused unless --allow-outside-paths (issue #13)."""
    models = tmp_path / "models"
    models.mkdir()
    (tmp_path / "beside.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (tmp_path / "outside.obj").write_text(TETRA_UV_OBJ)
    (models / "tetra.obj").write_text("mtllib ../beside.mtl\nusemtl red\n" + TETRA_UV_OBJ)
    (models / "scene.toml").write_text('[[meshes]]\nobj = "../outside.obj"\n')
    code, _, err = run_cli(capsys, "render", models / "tetra.obj", "-o", tmp_path / "refused.png", "--size", "32x24")
    assert code == 0, err
    assert "warning: " in err and "material library '../beside.mtl' leads out of the folder" in err
    code, _, err = run_cli(capsys, "render", models / "tetra.obj", "-o", tmp_path / "allowed.png", "--size", "32x24",
                       "--allow-outside-paths")
    assert code == 0 and "leads out" not in err, err
    refused = np.asarray(Image.open(tmp_path / "refused.png"), np.int32)
    allowed = np.asarray(Image.open(tmp_path / "allowed.png"), np.int32)
    assert (allowed[..., 0] - allowed[..., 1]).max() > (refused[..., 0] - refused[..., 1]).max() + 50  # red
    code, _, err = run_cli(capsys, "render", models / "scene.toml", "-o", tmp_path / "s.png")
    assert code == 2 and "'../outside.obj' leads out of the folder" in one_error_line(err)
    code, _, err = run_cli(capsys, "render", models / "scene.toml", "-o", tmp_path / "s.png", "--size", "32x24",
                       "--allow-outside-paths", "-q")
    assert code == 0, err
    code, _, err = run_cli(capsys, "turntable", models / "scene.toml", "-o", tmp_path / "t.gif", "--frames", "2",
                       "--size", "32x24", "--allow-outside-paths", "-q")
    assert code == 0, err
    code, out, _ = run_cli(capsys, "render", "--help")
    assert "--allow-outside-paths" in out
