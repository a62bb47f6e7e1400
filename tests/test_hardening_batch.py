"""softpipe batch, hardened (issue #28): resume that notices what changed, bounded jobs and names,
an output folder that is not trusted, one-line usage errors, OBJ warnings that reach the user.

Each test renders a few 8×6 frames in this process (``scheduler="serial"``); the few that need
Dask either fake its LocalCluster (nothing starts) or start one of a single worker.
"""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from patience import PATIENCE

import softpipe.tools.batch.job as job_module
from softpipe.core.files import PathPolicyError
from softpipe.tools import cli
from softpipe.tools.batch import MANIFEST, JobError, batch, load_job, parse_job

ROOT = Path(__file__).resolve().parents[1]
HAVE_DASK = importlib.util.find_spec("distributed") is not None

#: 2 models × 2 materials, 8×6 pixels; ``{...}`` are what the resume test edits.
JOB = """
[job]
background = {background}
fovy = {fovy}

[models]
ball = {{ shape = "{shape}" }}
tri = "tri.obj"

[materials.tint]
kd = {kd}

[lights.sun]
[[lights.sun.light]]
kind = "directional"
direction = {sun}

[sweep]
models = ["ball", "tri"]
materials = ["default", "tint"]
lights = ["sun"]
sizes = ["8x6"]
"""
BASE = dict(background="[0.1, 0.1, 0.1]", fovy=35, shape="cube", kd="[0.9, 0.2, 0.2]", sun="[0, -1, -1]")
TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _write_job(folder: Path, **changes) -> Path:
    path = folder / "jobs.toml"
    path.write_text(JOB.format(**{**BASE, **changes}))
    return path


def _lines(folder: Path) -> list:
    return [json.loads(line) for line in (folder / MANIFEST).read_text().splitlines()]


def _run(path: Path, out: Path):
    notes: list = []
    result = batch(load_job(path), out, "serial", log=notes.append, contact_sheet=False)
    return result, notes


# ---------------------------------------------------------------------------- 2: resume compares what a frame depends on


@pytest.mark.parametrize("change, rendered, why", [
    (dict(shape="icosphere"), 2, "model 'ball'"),               # cube → sphere
    (dict(kd="[0.2, 0.9, 0.2]"), 2, "material 'tint'"),
    (dict(sun="[0, -1, 1]"), 4, "light set 'sun'"),
    (dict(background="[0.5, 0.1, 0.1]"), 4, "[job] background"),
    (dict(fovy=50), 4, "[job] fovy"),
    ("obj", 2, "model 'tri'"),
])
def test_resume_renders_again_a_frame_whose_inputs_changed(tmp_path, change, rendered, why):
    (tmp_path / "tri.obj").write_text(TRIANGLE)
    out = tmp_path / "out"
    first, _ = _run(_write_job(tmp_path), out)
    assert len(first.done) == 4 and not first.failed
    again, notes = _run(_write_job(tmp_path), out)                # nothing changed: every frame skipped
    assert len(again.skipped) == 4 and not again.done and notes == []

    if change == "obj":                                          # the OBJ file's bytes, not its name
        (tmp_path / "tri.obj").write_text(TRIANGLE.replace("v 0 1 0", "v 0 2 0"))
        change = {}
    result, notes = _run(_write_job(tmp_path, **change), out)
    assert len(result.done) == rendered and len(result.skipped) == 4 - rendered
    assert not again.rerendered and len(result.rerendered) == rendered and {w for _, w in result.rerendered} == {why}
    assert notes == [f"rendering {rendered} frames again (changed since the manifest): {why} ({rendered} frames)"]
    latest = {e["name"]: e for e in _lines(out)}
    for record in result.done:                                  # the new lines hold the new key
        assert latest[record.name]["sha256"] == record.sha256 and len(latest[record.name]["params"]["key"]) == 64
    assert len(_run(_write_job(tmp_path, **change), out)[0].skipped) == 4     # and then it holds


def test_a_manifest_line_without_a_content_key_is_rendered_again(tmp_path):
    """A line of the manifest as main wrote it (params without inputs): the frame is not trusted."""
    (tmp_path / "tri.obj").write_text(TRIANGLE)
    out = tmp_path / "out"
    _run(_write_job(tmp_path), out)
    lines = _lines(out)
    for entry in lines:
        del entry["params"]["inputs"], entry["params"]["key"]
    (out / MANIFEST).write_text("".join(json.dumps(e) + "\n" for e in lines))
    result, notes = _run(_write_job(tmp_path), out)
    assert len(result.done) == 4 and notes == [
        "rendering 4 frames again (changed since the manifest): its manifest line has no content key (an older "
        "softpipe wrote it) (4 frames)"]


def test_the_cli_says_how_many_frames_it_renders_again_and_why(tmp_path, capsys):
    (tmp_path / "tri.obj").write_text(TRIANGLE)
    out = tmp_path / "out"
    assert cli.main(["batch", str(_write_job(tmp_path)), "-o", str(out), "--scheduler", "serial", "-q"]) == 0
    capsys.readouterr()
    assert cli.main(["batch", str(_write_job(tmp_path, fovy=20)), "-o", str(out), "--scheduler", "serial"]) == 0
    captured = capsys.readouterr()
    assert "softpipe batch: rendering 4 frames again (changed since the manifest): [job] fovy (4 frames)\n" \
        in captured.err
    assert "wrote 4 frames, skipped 0, 0 failed" in captured.out


# ---------------------------------------------------------------------------- 3: frames counted before they are made


def test_a_sweep_is_counted_before_its_product_is_made(monkeypatch):
    made = []

    class Counted(job_module.Frame):
        def __post_init__(self) -> None:
            made.append(self)
    monkeypatch.setattr(job_module, "Frame", Counted)
    monkeypatch.setattr(job_module, "MAX_JOB_FRAMES", 100)
    text = ('[sweep]\nmodels = ["bunny", "spot"]\ncameras = [%s]\nsizes = ["8x8", "9x9", "10x10"]'
            % ", ".join(str(a) for a in range(20)))
    with pytest.raises(JobError) as e:
        parse_job(text, "jobs.toml")
    assert str(e.value) == ("jobs.toml: [sweep]: makes 120 frames (2 models × 3 sizes × 20 cameras), more than the "
                            "limit MAX_JOB_FRAMES = 100")
    assert made == []                                            # refused before one frame was made
    with pytest.raises(JobError) as e:                           # a second sweep counts the first's frames
        parse_job('[[sweep]]\nmodels = "bunny"\ncameras = [%s]\n[[sweep]]\nmodels = "spot"\ncameras = [%s]'
                  % (", ".join(str(a) for a in range(60)), ", ".join(str(a) for a in range(50))), "jobs.toml")
    assert str(e.value) == ("jobs.toml: [[sweep]] #2: makes 50 frames (50 cameras), after 60 from earlier sweeps, "
                            "more than the limit MAX_JOB_FRAMES = 100")


def test_frames_entries_are_counted(monkeypatch):
    monkeypatch.setattr(job_module, "MAX_JOB_FRAMES", 10)
    entries = "".join(f'[[frames]]\nmodel = "spot"\nazimuth = {k}\n' for k in range(9))
    text = '[sweep]\nmodels = "bunny"\ncameras = [0, 90]\n' + entries
    with pytest.raises(JobError) as e:
        parse_job(text, "jobs.toml")
    assert str(e.value) == ("jobs.toml: the job makes 11 frames (2 from sweeps, 9 [[frames]] entries), more than "
                            "the limit MAX_JOB_FRAMES = 10")
    assert len(parse_job(text.replace("cameras = [0, 90]", "cameras = [0]"), "jobs.toml").frames) == 10


# ---------------------------------------------------------------------------- 6: the output folder is not trusted


def _ball_job(tmp_path: Path) -> Path:
    path = tmp_path / "jobs.toml"
    path.write_text('[models]\nball = { shape = "uv_sphere", segments = 8, rings = 4 }\n'
                    '[sweep]\nmodels = "ball"\ncameras = [0, 90]\nsizes = "8x6"\n')
    return path


def test_a_manifest_that_is_a_link_is_refused_and_not_appended_to(tmp_path, capsys):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / MANIFEST).symlink_to(victim)
    with pytest.raises(PathPolicyError) as e:
        batch(_ball_job(tmp_path), out, "serial")
    assert str(e.value) == (f"{out / MANIFEST} is a symbolic link; softpipe batch reads and appends its manifest "
                            "only as a regular file in the output folder (remove it, or write into another folder)")
    assert cli.main(["batch", str(_ball_job(tmp_path)), "-o", str(out), "--scheduler", "serial", "-q"]) == 2
    assert capsys.readouterr().err == f"softpipe batch: error: {e.value}\n"
    assert victim.read_text() == "precious\n" and not list(out.glob("*.png"))     # nothing rendered, nothing written


def test_a_manifest_linked_to_dev_zero_is_refused_at_once(tmp_path):
    """Read through the link, /dev/zero would grow memory until MemoryError: the run is a child
    process whose memory is capped (so that a regression fails instead of eating the machine)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / MANIFEST).symlink_to("/dev/zero")
    code = ("import resource, sys\nresource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))\n"
            "from softpipe.tools import cli\nsys.exit(cli.main(sys.argv[1:]))\n")
    done = subprocess.run([sys.executable, "-c", code, "batch", str(_ball_job(tmp_path)), "-o", str(out),
                           "--scheduler", "serial"], capture_output=True, text=True, timeout=PATIENCE,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr == (f"softpipe batch: error: {out / MANIFEST} is a symbolic link; softpipe batch reads and "
                           "appends its manifest only as a regular file in the output folder (remove it, or write "
                           "into another folder)\n")


def test_a_manifest_entry_is_checked_against_the_frames_own_file_only(tmp_path):
    """An entry whose output is /dev/zero is not read (the run would never end), and a frame's file
    that is a link to a matching file elsewhere is not trusted: the frame is rendered again, the
    link replaced by the frame's own file, the file it pointed to untouched."""
    job_path = _ball_job(tmp_path)
    out = tmp_path / "out"
    first = batch(job_path, out, "serial", contact_sheet=False)
    a, b = (r.name for r in first.done)
    lines = _lines(out)
    outside = tmp_path / "elsewhere.png"
    outside.write_bytes((out / f"{b}.png").read_bytes())
    (out / f"{b}.png").unlink()
    (out / f"{b}.png").symlink_to(outside)
    for entry in lines:
        if entry["name"] == a:
            entry["output"] = "/dev/zero"
    (out / MANIFEST).write_text("".join(json.dumps(e) + "\n" for e in lines))

    ran = []
    worker = threading.Thread(target=lambda: ran.append(batch(job_path, out, "serial", contact_sheet=False)),
                              daemon=True)
    worker.start()
    worker.join(120)
    assert not worker.is_alive(), "the run read /dev/zero"
    result = ran[0]
    assert sorted(r.name for r in result.done) == sorted([a, b]) and not result.skipped
    assert dict(result.rerendered) == {a: "its file is missing or changed", b: "its file is missing or changed"}
    assert not (out / f"{b}.png").is_symlink() and outside.read_bytes() == (out / f"{b}.png").read_bytes()
    assert {e["output"] for e in _lines(out)[-2:]} == {f"{a}.png", f"{b}.png"}


def test_frame_params_are_the_manifests(tmp_path):
    from softpipe.tools.batch import frame_params
    job = load_job(_ball_job(tmp_path))
    out = tmp_path / "out"
    batch(job, out, "serial", contact_sheet=False)
    entry = _lines(out)[0]
    params = frame_params(job.frames[0], job, "x" * 64)
    assert set(params) == set(entry["params"]) and params["inputs"]["model"] == "x" * 16
    assert {k: v for k, v in entry["params"].items() if k not in ("inputs", "key")} == job.frames[0].params()


# ---------------------------------------------------------------------------- 7: bounded names, a bad frame alone


def test_long_names_are_bounded_and_a_frame_that_cannot_be_written_fails_alone(tmp_path, capsys):
    from softpipe.tools.batch import MAX_NAME_LENGTH
    path = tmp_path / "jobs.toml"
    long = "m" * 300
    path.write_text(f'[models]\n{long} = {{ shape = "uv_sphere", segments = 8, rings = 4 }}\n'
                    f'ball = {{ shape = "cube" }}\n'
                    f'[sweep]\nmodels = ["{long}", "ball"]\ncameras = [30, 1e300]\nsizes = "8x6"\n')
    job = load_job(path)
    names = [f.name for f in job.frames]
    assert max(len(n) for n in names) <= MAX_NAME_LENGTH and len(set(names)) == 4
    assert names[0] == "m" * 48 + "-az030-8x6-" + job.frames[0].digest()[:6]
    assert names[3] == "ball-az1e+300-8x6"
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "ball-az030-8x6.png").mkdir()           # a folder where a frame's file goes
    status = cli.main(["batch", str(path), "-o", str(tmp_path / "out"), "--scheduler", "serial", "-q"])
    captured = capsys.readouterr()
    assert status == 1
    failed = [line for line in captured.err.splitlines() if line.startswith("softpipe batch: failed: ")]
    assert len(failed) == 1 and failed[0].startswith("softpipe batch: failed: ball-az030-8x6: IsADirectoryError: "
                                                     "cannot write '") and failed[0].endswith(": it is a folder")
    assert "wrote 3 frames, skipped 0, 1 failed" in captured.out
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png") if p.is_file() and "contact" not in p.name) == \
        sorted(f"{n}.png" for n in names if n != "ball-az030-8x6")


# ---------------------------------------------------------------------------- 9: one line, exit 2 (or 130)


class _NoCluster:
    """Stands for distributed.LocalCluster in a test that must not start one."""

    def __init__(self, *args, **kwargs) -> None:
        raise AssertionError("a LocalCluster was started")


@pytest.mark.parametrize("options, message", [
    (["--workers", "0"], "softpipe batch: error: argument --workers: expected a positive number of worker "
                         "processes, got 0 (see 'softpipe batch --help')"),
    (["--workers", "64"], "softpipe batch: error: --workers 64: this machine has 2 cores, and a LocalCluster takes "
                          "at most 4 worker processes (2 per core; more would only wait for a core); for more, start "
                          "a cluster and give its scheduler's address"),
    (["--dashboard", "garbage"], "softpipe batch: error: --dashboard 'garbage': expected an address [HOST]:PORT "
                                 "such as ':8787' or 'localhost:8787' (PORT 0 to 65535)"),
    (["--dashboard", ":99999"], "softpipe batch: error: --dashboard ':99999': expected an address [HOST]:PORT "
                                "such as ':8787' or 'localhost:8787' (PORT 0 to 65535)"),
])
def test_bad_cluster_options_are_one_line_before_anything_starts(tmp_path, capsys, monkeypatch, options, message):
    if HAVE_DASK:
        import distributed
        monkeypatch.setattr(distributed, "LocalCluster", _NoCluster)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    status = cli.main(["batch", str(_ball_job(tmp_path)), "-o", str(tmp_path / "out"), *options])
    assert (status, capsys.readouterr().err) == (2, message + "\n")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


@pytest.mark.skipif(not HAVE_DASK, reason="dask[distributed] is not installed")
def test_a_cluster_that_does_not_start_is_one_line(tmp_path, capsys, monkeypatch):
    import socket

    import distributed

    class Unresolvable:
        def __init__(self, *args, **kwargs) -> None:
            try:
                raise socket.gaierror(-2, "Name or service not known")
            except OSError as e:
                raise RuntimeError(f"Cluster failed to start: {e}") from e
    monkeypatch.setattr(distributed, "LocalCluster", Unresolvable)
    status = cli.main(["batch", str(_ball_job(tmp_path)), "-o", str(tmp_path / "out"), "--workers", "1",
                       "--dashboard", "nosuchhost.invalid:8787", "-q"])
    assert (status, capsys.readouterr().err) == (2, "softpipe batch: error: the LocalCluster did not start: "
                                                    "gaierror: [Errno -2] Name or service not known (the dashboard "
                                                    "address 'nosuchhost.invalid:8787'?)\n")


@pytest.mark.skipif(not HAVE_DASK, reason="dask[distributed] is not installed")
def test_ctrl_c_while_the_cluster_starts_is_one_line_and_130(tmp_path):
    """Ctrl-C arrives (SIGINT to the process) while the LocalCluster's worker is starting: the run
    waits for it to start, closes it, and says "interrupted", with no traceback from Dask's exit
    hook (which fails on a worker left half-started)."""
    code = ("import os, signal, sys\nfrom distributed.nanny import Nanny\nstart = Nanny.start_unsafe\n"
            "async def interrupted(self):\n    os.kill(os.getpid(), signal.SIGINT)\n    return await start(self)\n"
            "Nanny.start_unsafe = interrupted\nfrom softpipe.tools import cli\nsys.exit(cli.main(sys.argv[1:]))\n")
    done = subprocess.run([sys.executable, "-c", code, "batch", str(_ball_job(tmp_path)), "-o", str(tmp_path / "out"),
                           "--workers", "1", "-q"], capture_output=True, text=True, timeout=PATIENCE,
                          env={**os.environ, "PYTHONPATH": str(ROOT)},
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert (done.returncode, done.stderr) == (130, "softpipe batch: interrupted\n")
    assert not list((tmp_path / "out").glob("*.png"))


def test_a_job_nested_100000_deep_is_one_line(tmp_path, capsys):
    path = tmp_path / "jobs.toml"
    path.write_text('[sweep]\nmodels = ' + "[" * 100_000 + "]" * 100_000 + "\n")
    assert cli.main(["batch", str(path), "-o", str(tmp_path / "out"), "--scheduler", "serial"]) == 2
    assert capsys.readouterr().err == f"softpipe batch: error: {path}: TOML error: arrays or tables nested too deeply\n"


# ---------------------------------------------------------------------------- 10: OBJ warnings reach the user


def test_an_objs_warnings_reach_the_user_once_per_model_naming_the_entry(tmp_path, capsys):
    (tmp_path / "red.mtl").write_text("newmtl red\nKd 1 0 0\n")
    sub = tmp_path / "job"
    sub.mkdir()
    (sub / "tri.obj").write_text("mtllib ../red.mtl\n" + TRIANGLE)
    path = sub / "jobs.toml"
    path.write_text('[models]\ncup = "tri.obj"\n[sweep]\nmodels = "cup"\ncameras = [0, 90, 180]\nsizes = "8x6"\n')
    assert cli.main(["batch", str(path), "-o", str(tmp_path / "out"), "--scheduler", "serial", "-q"]) == 0
    err = capsys.readouterr().err
    assert err == (f"softpipe batch: warning: {path}: [models] 'cup': {sub / 'tri.obj'}:1: material library "
                   f"'../red.mtl' leads out of the folder '{sub}'; a model's files must be in its own folder or "
                   "below (allow_outside=True for files you trust); using default materials\n")
    from softpipe.scenes.scenefile import SceneWarning
    with pytest.warns(SceneWarning, match=r"\[models\] 'cup': .*tri\.obj:1: material library '\.\./red\.mtl'"):
        batch(path, tmp_path / "out2", "serial", contact_sheet=False)     # from Python: a warning
