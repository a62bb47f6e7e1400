"""Issue #13: outputs written whole or not at all, NaN colors, and a framebuffer the kernels can trust."""
from __future__ import annotations

import errno
import io
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from case_process import Cases
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.tools.cli import main

TRIANGLE = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
COLORS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)


# ---------------------------------------------------------------------------- the framebuffer's fields


@pytest.mark.parametrize("name, value", [
    ("width", 10_000), ("height", 3), ("pattern", sp.pipeline.sampling.pattern_named("grid16")),
    ("samples_color", np.zeros((1, 100, 100, 4), np.float32)),
    ("samples_depth", np.zeros((1, 6, 8), np.float64)),
    ("samples_color", np.zeros((1, 8, 6, 4), np.float32)[:, ::-1]),
])
def test_assigning_the_size_pattern_or_arrays_is_refused(name, value):
    fb = sp.Framebuffer(8, 6)
    with pytest.raises(AttributeError, match=rf"Framebuffer\.{name} is read-only.*in place"):
        setattr(fb, name, value)
    assert (fb.width, fb.height, fb.samples) == (8, 6, 1)
    assert fb.samples_color.shape == (1, 6, 8, 4) and fb.samples_depth.shape == (1, 6, 8)
    sp.draw(fb, TRIANGLE, varyings={"color": COLORS})        # and it still draws
    assert np.asarray(fb).any()


def test_the_arrays_are_written_in_place():
    fb = sp.Framebuffer(8, 6, sp.pipeline.sampling.pattern_named("rgss4"))
    fb.samples_color[...] = (0.5, 0.25, 1.0, 1.0)
    fb.samples_depth[:, 2, 3] = 0.25
    fb.samples_color[2, 1, 1] = (1.0, 1.0, 1.0, 1.0)
    assert np.asarray(fb)[0, 0].tolist() == [128, 64, 255]
    assert fb.depth[2, 3] == np.float32(0.25) and fb.samples_depth[0, 0, 0] == 1.0
    assert fb.samples_color[2, 1, 1].tolist() == [1.0, 1.0, 1.0, 1.0]
    one = sp.Framebuffer(4, 3)
    one.color[1, 2] = (1, 0, 0, 1)                              # fb.color is the buffer for one sample
    assert np.asarray(one)[1, 2].tolist() == [255, 0, 0]
    with pytest.raises(AttributeError, match="in place"):       # even an array of the right kind: write into it
        one.samples_color = one.samples_color.copy()


@pytest.mark.parametrize("path", ["fast", "reference"])
def test_changing_a_handed_out_array_cannot_reach_a_kernel(path):
    """Shape or dtype of the array fb.samples_* gave out change that array only."""
    fb = sp.Framebuffer(8, 6)
    color, depth = fb.samples_color, fb.samples_depth
    color.shape = (1, 8, 6, 4)                                  # the same bytes, another shape
    depth.dtype = np.int32
    fb.samples_depth.shape = (48,)
    sp.draw(fb, TRIANGLE, varyings={"color": COLORS}, path=path)
    assert fb.samples_color.shape == (1, 6, 8, 4) and fb.samples_color.dtype == np.float32
    assert fb.samples_color.flags.c_contiguous and fb.samples_depth.flags.c_contiguous
    reference = sp.Framebuffer(8, 6)
    sp.draw(reference, TRIANGLE, varyings={"color": COLORS}, path=path)
    assert np.array_equal(np.asarray(fb), np.asarray(reference))


CORRUPT = """
import numpy as np, softpipe as sp
fb = sp.Framebuffer(40, 8)
base = fb.samples_color.base if fb.samples_color.base is not None else fb.samples_color
{change}
pos = np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1]], float)
try:
    sp.draw(fb, pos, varyings={{"color": np.ones((3, 3))}}, path="{path}")
except RuntimeError as e:
    print("refused:", e)
else:
    print("drawn")
"""


_CHANGES = ["base.shape = (1, 40, 8, 4)", "base.dtype = np.float64", "base.shape = (2, 4, 40, 4)",
            "fb.pattern.offsets = np.zeros((16, 2), np.int64)"]
_PATHS = ["fast", "reference"]


def _case_of(item):
    """The case of ``corrupt_cases`` a collected test of this file reads, or None."""
    if item.originalname == "test_a_changed_buffer_is_refused_before_any_kernel_runs":
        return f"{item.callspec.params['change']} ({item.callspec.params['path']})"
    return None


@pytest.fixture(scope="module")
def corrupt_cases(request):
    """Each change on each path, in a fresh Python (a crash must fail the case, not end pytest): one process
    for them all while none crashes (case_process.py)."""
    cases = {f"{change} ({path})": (CORRUPT.format(change=change, path=path), ())
             for change in _CHANGES for path in _PATHS}
    # a changed pattern is the default one, which every later framebuffer of the process would share: such a
    # case ends its process
    return Cases(request, cases, _case_of, last=[name for name in cases if name.startswith("fb.pattern")])


@pytest.mark.parametrize("path", _PATHS)
@pytest.mark.parametrize("change", _CHANGES)
def test_a_changed_buffer_is_refused_before_any_kernel_runs(corrupt_cases, change, path):
    """Even the framebuffer's own array (reached through .base) or its pattern changed in place: an error,
    never a crash or a write out of bounds."""
    done = corrupt_cases(f"{change} ({path})")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("refused: ") and " changed " in done.stdout, done.stdout


# ---------------------------------------------------------------------------- NaN colors


def nan_green(varyings, uniforms, frag):
    return (uniforms.red, 0.5, -uniforms.red, 1.0)         # red is NaN: a uniform, so the fast path can take it


def test_nan_becomes_0_without_a_warning_on_both_paths(tmp_path):
    pictures = []
    for path in ("fast", "reference"):
        fb = sp.Framebuffer(12, 10)
        with pytest.warns(sp.NonFiniteColorWarning, match="NaN or infinite"):   # the draw says so (issue 32)
            sp.draw(fb, TRIANGLE, fragment_shader=nan_green, uniforms={"red": np.nan}, path=path)
        assert np.isnan(fb.color[..., 0]).any()
        with warnings.catch_warnings():
            warnings.simplefilter("error")                      # numpy's "invalid value encountered in cast"
            rgb = np.asarray(fb)
            fb.save(tmp_path / f"{path}.png")
            rgba = fb.to_uint8()
        covered = np.isnan(fb.color[..., 0])
        assert rgb[covered].tolist() == [[0, 128, 0]] * int(covered.sum())
        assert (rgba[covered][:, 3] == 255).all()
        assert np.array_equal(np.asarray(Image.open(tmp_path / f"{path}.png")), rgb)
        pictures.append(rgb)
    assert np.array_equal(*pictures)
    fb = sp.Framebuffer(3, 1)
    fb.color[0] = [(np.inf, -np.inf, 0.5, 1.0), (2.0, -1.0, np.nan, np.nan), (0.5, 0.5, 0.5, 1.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fb.to_uint8().tolist() == [[[255, 0, 128, 255], [255, 0, 0, 0], [128, 128, 128, 255]]]


# ---------------------------------------------------------------------------- outputs: whole or not at all


def breaking_save(exception):
    """A PIL Image.save that writes the first half of the file, then raises ``exception`` (Ctrl-C, a full disk)."""
    original = Image.Image.save

    def save(self, fp, format=None, **params):
        if format is None:
            format = Image.registered_extensions()[Path(os.fspath(fp)).suffix.lower()]
        buffer = io.BytesIO()
        original(self, buffer, format=format, **params)
        half = buffer.getvalue()[: len(buffer.getvalue()) // 2]
        if isinstance(fp, (str, os.PathLike)):
            with open(fp, "wb") as f:
                f.write(half)
        else:
            fp.write(half)
        raise exception

    return save


def write_fb_save(tmp_path, obj, capsys):
    fb = sp.Framebuffer(8, 6)
    fb.save(tmp_path / "out.png")


def write_turntable_gif(tmp_path, obj, capsys):
    sp.turntable(obj, tmp_path / "out.gif", frames=2, width=16, height=12)


def write_turntable_apng(tmp_path, obj, capsys):
    sp.turntable(obj, tmp_path / "out.png", frames=2, width=16, height=12)


def write_stage_pictures(tmp_path, obj, capsys):
    sp.render(obj, width=16, height=12, stages=tmp_path)


def write_cli(command, *options):
    def write(tmp_path, obj, capsys):
        argv = [command] + ([] if command == "demo" else [str(obj)]) + [str(o).format(tmp=tmp_path) for o in options]
        code = main(argv)
        err = capsys.readouterr().err
        assert code in (2, 130), err
        assert "interrupted" in err or "No space left on device" in err, err
    return write


WRITERS = {
    "fb.save": (write_fb_save, "out.png"),
    "turntable .gif": (write_turntable_gif, "out.gif"),
    "turntable .png": (write_turntable_apng, "out.png"),
    "stage pictures": (write_stage_pictures, "01-vertices.png"),
    "cli render": (write_cli("render", "-o", "{tmp}/out.png", "--size", "16x12"), "out.png"),
    "cli render --stages": (write_cli("render", "-o", "{tmp}/x.png", "--size", "16x12", "--stages", "{tmp}"),
                            "01-vertices.png"),
    "cli turntable": (write_cli("turntable", "-o", "{tmp}/out.gif", "--size", "16x12", "--frames", "2", "-q"),
                      "out.gif"),
    "cli demo": (write_cli("demo", "-o", "{tmp}/out.jpg", "--width", "16", "--height", "12"), "out.jpg"),
}


@pytest.mark.parametrize("exception", [KeyboardInterrupt(), OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))],
                         ids=["ctrl-c", "disk-full"])
@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_broken_save_leaves_the_previous_file_and_no_temporary_file(writer, exception, tmp_path, tetra_obj,
                                                                       monkeypatch, capsys):
    write, name = WRITERS[writer]
    folder = tmp_path / "outputs"
    folder.mkdir()
    previous = b"the previous good file"
    (folder / name).write_bytes(previous)
    monkeypatch.setattr(Image.Image, "save", breaking_save(exception))
    try:
        write(folder, tetra_obj, capsys)
    except (KeyboardInterrupt, OSError) as e:
        assert e is exception
    else:
        assert writer.startswith("cli"), "the save did not fail"
    assert (folder / name).read_bytes() == previous
    assert sorted(p.name for p in folder.iterdir()) == [name]      # no temporary file left


def test_after_a_failed_save_a_good_one_writes_the_usual_bytes_and_mode(tmp_path, monkeypatch):
    fb = sp.Framebuffer(8, 6)
    sp.draw(fb, TRIANGLE, varyings={"color": COLORS})
    (tmp_path / "x.png").write_bytes(b"old")
    with monkeypatch.context() as m:
        m.setattr(Image.Image, "save", breaking_save(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))))
        with pytest.raises(OSError, match="No space left"):
            fb.save(tmp_path / "x.png")
    assert (tmp_path / "x.png").read_bytes() == b"old"
    fb.save(tmp_path / "x.png")
    buffer = io.BytesIO()
    fb.to_image().save(buffer, format="PNG")
    assert (tmp_path / "x.png").read_bytes() == buffer.getvalue()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.png"]
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "x.png").stat().st_mode & 0o777 == 0o666 & ~umask


# ---------------------------------------------------------------------------- the command line's -o


def test_dash_o_dash_writes_the_picture_to_stdout(capsysbinary, tetra_obj, tmp_path):
    for argv, expected in [
        (["render", str(tetra_obj), "-o", "-", "--size", "16x12"], "PNG"),
        (["demo", "-o", "-", "--width", "16", "--height", "12"], "PNG"),
        (["turntable", str(tetra_obj), "-o", "-", "--size", "16x12", "--frames", "2", "-q"], "GIF"),
    ]:
        assert main(argv) == 0
        out, err = capsysbinary.readouterr()
        with Image.open(io.BytesIO(out)) as im:
            assert im.format == expected and im.size == (16, 12)
        assert f"softpipe {argv[0]}: wrote {expected} to stdout (".encode() in err
        assert not (tmp_path / "-").exists() and not Path("-").exists()
    main(["render", str(tetra_obj), "-o", "-", "--size", "16x12"])
    out, _ = capsysbinary.readouterr()
    assert out == sp.render(tetra_obj, width=16, height=12)._repr_png_()          # the same bytes fb.save writes
    main(["turntable", str(tetra_obj), "-o", "-", "--size", "16x12", "--frames", "2", "-q"])
    out, _ = capsysbinary.readouterr()
    sp.turntable(tetra_obj, tmp_path / "spin.gif", frames=2, width=16, height=12)
    assert out == (tmp_path / "spin.gif").read_bytes()


@pytest.fixture
def no_rendering(monkeypatch):
    """Rendering fails the test: what is checked must be checked before it."""
    def rendered(*args, **kwargs):
        raise AssertionError("rendered before the output was checked")
    monkeypatch.setattr("softpipe.scenes.drawing.render_scene", rendered)
    monkeypatch.setattr("softpipe.tools.demo.render_demo", rendered)


def test_demo_writes_a_real_jpeg_or_refuses_the_extension_before_rendering(capsys, tmp_path, monkeypatch):
    code, out, err = run_cli(capsys, "demo", "-o", tmp_path / "x.jpg", "--width", "16", "--height", "12")
    assert code == 0, err
    with Image.open(tmp_path / "x.jpg") as im:
        assert im.format == "JPEG" and im.size == (16, 12)
    monkeypatch.setattr("softpipe.tools.demo.render_demo", lambda *a: pytest.fail("rendered before the check"))
    code, _, err = run_cli(capsys, "demo", "-o", tmp_path / "x.foo")
    assert code == 2
    assert err.strip() == ("softpipe demo: error: " + str(tmp_path / "x.foo") +
                           ": cannot write images with extension '.foo'; use .png, .jpg, .bmp, .tif, ...")
    assert not (tmp_path / "x.foo").exists()


@pytest.mark.parametrize("command", ["render", "turntable", "demo"])
def test_a_bad_output_folder_is_refused_before_rendering(command, capsys, tetra_obj, tmp_path, no_rendering):
    (tmp_path / "a-file").write_text("not a folder")
    (tmp_path / "a-folder.png").mkdir()
    (tmp_path / "a-folder.gif").mkdir()
    ext = ".gif" if command == "turntable" else ".png"
    model = [] if command == "demo" else [tetra_obj]
    for output, message in [(tmp_path / "a-file" / "missing" / f"x{ext}", f"{tmp_path / 'a-file'} is a file, "
                                                                           "not a folder"),
                            (tmp_path / f"a-folder{ext}", "it is a folder")]:
        code, out, err = run_cli(capsys, command, *model, "-o", output)
        assert code == 2 and out == ""
        assert err.strip() == f"softpipe {command}: error: -o: cannot write {output}: {message}"


def test_turntable_in_python_checks_its_folder_before_drawing(tmp_path, tetra_obj, no_rendering):
    (tmp_path / "a-file").write_text("not a folder")
    with pytest.raises(OSError):
        sp.turntable(tetra_obj, tmp_path / "a-file" / "spin.gif", frames=2, width=16, height=12)
