"""softpipe batch (issue #19): job files, a Dask LocalCluster on loopback, resuming, faults.

The cluster tests share one LocalCluster of 2 worker processes (started once: a worker
process pays softpipe's import and its kernels' load from the on-disk cache once), and
render tiny frames of a small sphere. They are skipped only when Dask cannot be imported
(``make test`` installs it: the ``cluster`` extra).
"""
from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import pytest

from softpipe.scenes.shapes import uv_sphere
from softpipe.tools import cli
from softpipe.tools.batch import (
    CONTACT_SHEET,
    CRASH_ONCE_ENV,
    MANIFEST,
    BatchProgress,
    Frame,
    JobError,
    batch,
    job_from_dict,
    load_job,
    parse_job,
    read_manifest,
)

HAVE_DASK = importlib.util.find_spec("distributed") is not None
needs_dask = pytest.mark.skipif(not HAVE_DASK, reason="dask[distributed] is not installed "
                                                      "(pip install 'softpipe[cluster]'; make test installs it)")

#: 2 programs × 2 materials × 3 cameras = 12 tiny frames of one small sphere.
SWEEP = """
[models]
ball = { shape = "uv_sphere", segments = 16, rings = 8 }

[materials.shiny]
ks = [0.9, 0.9, 0.9]
shininess = 64

[sweep]
models = ["ball"]
programs = ["phong", "normals"]
materials = ["default", "shiny"]
cameras = [0, 120, "top"]
sizes = ["40x30"]
"""
#: The frame whose worker dies once (CRASH_ONCE_ENV), in its own job so that no other test meets it.
CRASH_FRAME = "ball-phong-az200-40x30"
CRASH_JOB = SWEEP.replace('cameras = [0, 120, "top"]', "cameras = [160, 200, 240]")


def _job(text: str = SWEEP, tmp_path: Path | None = None):
    return parse_job(text, "sweep.toml", tmp_path)


def _files(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.png")) if p.name != CONTACT_SHEET}


def _manifest_lines(folder: Path) -> list:
    return [json.loads(line) for line in (folder / MANIFEST).read_text().splitlines()]


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """A LocalCluster of 2 worker processes, one thread each, on loopback; the crash hook armed."""
    if not HAVE_DASK:
        pytest.skip("dask[distributed] is not installed")
    from distributed import Client, LocalCluster
    marker = tmp_path_factory.mktemp("crash") / "crashed"
    old = os.environ.get(CRASH_ONCE_ENV)
    os.environ[CRASH_ONCE_ENV] = f"{CRASH_FRAME}:{marker}"    # inherited by the worker processes
    try:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                          host="127.0.0.1") as cluster, Client(cluster) as c:
            c.crash_marker = marker
            yield c
    finally:
        if old is None:
            os.environ.pop(CRASH_ONCE_ENV, None)
        else:
            os.environ[CRASH_ONCE_ENV] = old


# ---------------------------------------------------------------------------- the job


def test_a_sweep_is_the_product_with_stable_readable_unique_names():
    job = _job()
    names = [f.name for f in job.frames]
    assert len(names) == 12 == len(set(names))
    assert names[:3] == ["ball-phong-az000-40x30", "ball-phong-az120-40x30", "ball-phong-top-40x30"]
    assert "ball-normals-shiny-top-40x30" in names
    assert all(n.replace("-", "").replace("x", "").isalnum() for n in names)
    assert [f.name for f in _job().frames] == names                       # the same job, the same names
    assert Frame("ball", azimuth=30.0, elevation=45.0, samples="rgss4").name == "ball-az030-el45-640x480-rgss4"
    assert Frame("ball", azimuth=-7.5, orbit=True).name == "ball-orbit-7.5-640x480"
    # a name changed to be safe in a file name gets a hash of the parameters: "a b" and "a_b" stay apart
    odd, plain = Frame("a b", width=8, height=8), Frame("a_b", width=8, height=8)
    assert odd.name.startswith("a_b-az030-8x8-") and len(odd.name) == len("a_b-az030-8x8-") + 6
    assert plain.name == "a_b-az030-8x8" != odd.name


def test_orbit_frames_and_single_frames_and_python_dicts():
    job = job_from_dict({"models": {"ball": uv_sphere(segments=8, rings=4)},
                         "sweep": {"models": "ball", "orbit": {"frames": 4, "elevation": 10}, "sizes": [[16, 12]]},
                         "frames": [{"model": "ball", "view": "front", "size": "16x12", "program": "unlit"},
                                    {"model": "ball", "azimuth": 90, "elevation": 10, "orbit": True,
                                     "width": 16, "height": 12}]})       # the last one is in the orbit already
    assert [f.name for f in job.frames] == ["ball-orbit000-el10-16x12", "ball-orbit090-el10-16x12",
                                            "ball-orbit180-el10-16x12", "ball-orbit270-el10-16x12",
                                            "ball-unlit-front-16x12"]


@pytest.mark.parametrize("text, table, key, words", [
    ('[sweep]\nmodels = ["ball"]\nprogramz = ["phong"]', "[sweep]", "programz", "did you mean 'programs'"),
    ('[sweep]\nmodels = ["bunny"]\nprograms = ["phong", "phnog"]', "[sweep]", "programs", "entry 2"),
    ('[sweep]\nmodels = ["nosuchmodel"]', "[sweep]", "models", "bundled model"),
    ('[sweep]\nmodels = ["bunny"]\nmaterials = ["gold"]', "[sweep]", "materials", "undefined material 'gold'"),
    ('[sweep]\nmodels = ["bunny"]\nsizes = ["640by480"]', "[sweep]", "sizes", "WIDTHxHEIGHT"),
    ('[sweep]\nmodels = ["bunny"]\ncameras = ["side"]', "[sweep]", "cameras", "unknown view 'side'"),
    ('[materials.gold]\nshininess = "high"\n[sweep]\nmodels = ["bunny"]', "[materials.gold]", "shininess",
     "must be a number"),
    ('[lights.sun]\nshadows = "yes"\n[sweep]\nmodels = ["bunny"]', "[lights.sun]", "shadows", "true or false"),
    ('[models]\nball = { shape = "uv_sphere", segmnts = 8 }\n[sweep]\nmodels = ["ball"]', "[models] 'ball'",
     "segmnts", "did you mean 'segments'"),
    ('[[frames]]\nmodel = "bunny"\nview = "front"\nazimuth = 30', "[[frames]] #1", "azimuth", "view"),
    ('[job]\nfovy = 200\n[sweep]\nmodels = ["bunny"]', "[job]", "fovy", "(0, 180)"),
])
def test_job_file_errors_name_the_file_table_and_key(tmp_path, text, table, key, words):
    path = tmp_path / "jobs.toml"
    path.write_text(text)
    with pytest.raises(JobError) as e:
        load_job(path)
    assert (e.value.file, e.value.table, e.value.key) == (str(path), table, key)
    assert str(e.value).startswith(f"{path}: ") and words in str(e.value) and "\n" not in str(e.value)


def test_a_jobs_materials_take_the_media_and_falloff_keys():
    """A named medium for ior (FORMULAS §17), transmittance, Glassner's falloff (§15); a bad one names its key."""
    job = parse_job('[materials.hazy]\nior = "water"\nkt = [0.9, 0.9, 0.9]\ntransmittance = [0.5, 0.7, 0.9]\n'
                    'falloff = "glassner"\nfalloff_a = 1.5\n[sweep]\nmodels = ["bunny"]\nprograms = ["glass"]\n'
                    'materials = ["hazy"]')
    assert job.materials["hazy"] == {"kt": (0.9, 0.9, 0.9), "ior": 1.33, "transmittance": (0.5, 0.7, 0.9),
                                     "falloff": "glassner", "falloff_a": 1.5}
    assert [f.name for f in job.frames] == ["bunny-glass-hazy-az030-640x480"]
    with pytest.raises(JobError, match="unknown medium 'jelly'") as e:
        parse_job('[materials.odd]\nior = "jelly"\n[sweep]\nmodels = ["bunny"]')
    assert e.value.table == "[materials.odd]"


def test_job_file_syntax_and_emptiness(tmp_path, capsys):
    path = tmp_path / "jobs.toml"
    path.write_text("[sweep]\nmodels = [\n")
    with pytest.raises(JobError, match=r"jobs.toml:\d+: TOML syntax error"):
        load_job(path)
    path.write_text("[job]\nfovy = 40\n")
    with pytest.raises(JobError, match="no frames"):
        load_job(path)
    assert cli.main(["batch", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("softpipe batch: error: ") and str(path) in err and len(err.splitlines()) == 1


def test_a_job_file_is_read_as_a_scene_file_is(tmp_path):
    """The reading a scene file has (softpipe.core.validation.Reader): the line of a byte that is not UTF-8,
    a FIFO refused before it is opened, TOML nested too deeply: each a JobError naming the file."""
    path = tmp_path / "jobs.toml"
    path.write_bytes(b'[sweep]\nmodels = ["caf\xe9"]\n')
    with pytest.raises(JobError, match=r"jobs\.toml:2: not UTF-8 text \(byte 22\)$") as e:
        load_job(path)
    assert e.value.line == 2
    with pytest.raises(JobError, match=r"^<string>: TOML error: arrays or tables nested too deeply$"):
        parse_job("a = " + "[" * 3000)
    with pytest.raises(JobError, match=r"jobs\.toml: job file not found$"):
        load_job(tmp_path / "nope" / "jobs.toml")
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "pipe.toml")
        with pytest.raises(JobError, match=r"pipe\.toml' is a FIFO, not a regular file$"):
            load_job(tmp_path / "pipe.toml")


# ---------------------------------------------------------------------------- serial: resume, faults, the CLI


def test_an_interrupted_run_resumes_with_only_the_missing_frames(tmp_path):
    job, out = _job(), tmp_path / "out"

    def stop_after_5(p: BatchProgress) -> None:
        if p.done == 5:
            raise KeyboardInterrupt                               # Ctrl-C after the fifth frame
    with pytest.raises(KeyboardInterrupt):
        batch(job, out, "serial", progress=stop_after_5)
    first = _manifest_lines(out)                                  # every line whole, one per frame written
    assert len(first) == 5 and not list(out.glob(".*.tmp")) and len(_files(out)) == 5
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.glob("*.png")}

    result = batch(job, out, "serial")
    assert sorted(result.skipped) == sorted(e["name"] for e in first)
    assert sorted(r.name for r in result.done) == sorted(set(f.name for f in job.frames) - set(result.skipped))
    assert all(out.joinpath(n).stat().st_mtime_ns == t for n, t in mtimes.items())   # not written again
    assert len(_manifest_lines(out)) == 12 and (out / CONTACT_SHEET).is_file()
    for entry in _manifest_lines(out):
        assert set(entry) == {"name", "params", "output", "sha256", "seconds"}
        assert (out / entry["output"]).is_file() and entry["params"]["model"] == "ball"

    # a file changed since: rendered again (and only it); force: every frame
    changed = out / f"{job.frames[0].name}.png"
    changed.write_bytes(b"not the frame")
    again = batch(job, out, "serial", contact_sheet=False)
    assert [r.name for r in again.done] == [job.frames[0].name] and len(again.skipped) == 11
    assert len(batch(job, out, "serial", force=True, contact_sheet=False).done) == 12


def test_a_bad_frame_fails_alone_and_the_cli_counts_it(tmp_path, capsys):
    path = tmp_path / "jobs.toml"
    path.write_text(SWEEP.replace('programs = ["phong", "normals"]', 'programs = ["phong"]') +
                    '\n[[frames]]\nmodel = "suzanne"\nprogram = "textured"\nsize = "40x30"\n')
    status = cli.main(["batch", str(path), "-o", str(tmp_path / "out"), "--scheduler", "serial", "-q"])
    captured = capsys.readouterr()
    assert status == 1                                            # the number of failed frames
    assert "suzanne-textured-az030-40x30: ValueError: suzanne: the model has no texture coordinates" in captured.err
    assert "wrote 6 frames, skipped 0, 1 failed" in captured.out
    assert len(_files(tmp_path / "out")) == 6 and "suzanne-textured-az030-40x30.png" not in _files(tmp_path / "out")
    assert cli.main(["batch", str(path), "-o", str(tmp_path / "out"), "--scheduler", "serial", "-q"]) == 1
    assert "wrote 0 frames, skipped 6, 1 failed" in capsys.readouterr().out


# ---------------------------------------------------------------------------- on a LocalCluster


@needs_dask
def test_a_cluster_of_two_workers_makes_the_serial_bytes(client, tmp_path):
    job = _job()
    serial = batch(job, tmp_path / "serial", "serial")
    seen = []
    cluster = batch(job, tmp_path / "cluster", client, progress=seen.append)
    assert not serial.failed and not cluster.failed and cluster.workers == 2
    assert len(cluster.done) == 12
    a, b = _files(tmp_path / "serial"), _files(tmp_path / "cluster")
    assert len(a) == 12 and a == b                                 # byte for byte
    assert {e["sha256"] for e in _manifest_lines(tmp_path / "cluster")} == \
        {e["sha256"] for e in _manifest_lines(tmp_path / "serial")}
    assert [p.finished for p in seen] == list(range(13)) and seen[-1].eta == 0.0
    assert (tmp_path / "cluster" / CONTACT_SHEET).read_bytes() == (tmp_path / "serial" / CONTACT_SHEET).read_bytes()


@needs_dask
def test_a_worker_killed_mid_run_loses_no_frame(client, tmp_path):
    job = _job(CRASH_JOB)
    assert CRASH_FRAME in [f.name for f in job.frames]
    result = batch(job, tmp_path / "out", client)
    assert client.crash_marker.exists()                           # the worker did die (os._exit) on that frame
    names = [r.name for r in result.done]
    assert not result.failed and sorted(names) == sorted(f.name for f in job.frames)   # every frame, once
    assert sorted(e["name"] for e in _manifest_lines(tmp_path / "out")) == sorted(names)
    reference = batch(_job(CRASH_JOB), tmp_path / "serial", "serial", contact_sheet=False)
    assert not reference.failed and _files(tmp_path / "out") == _files(tmp_path / "serial")


@needs_dask
def test_the_meshes_are_scattered_once_every_worker_of_the_cluster_has_joined(client, tmp_path, monkeypatch):
    # a mesh broadcast while a worker is still joining lives on the other alone: a frame that kills that
    # worker then loses it, with every frame left to draw
    calls = []
    wait, scatter = client.wait_for_workers, client.scatter
    monkeypatch.setattr(client, "wait_for_workers", lambda n, timeout=None: (calls.append(("wait", n)),
                                                                              wait(n, timeout=timeout))[1])
    monkeypatch.setattr(client, "scatter", lambda *a, **k: (calls.append(("scatter", k.get("broadcast"))),
                                                            scatter(*a, **k))[1])
    result = batch(_job(), tmp_path / "out", client)
    assert not result.failed and calls[0] == ("wait", 2) and calls[1:] and set(calls[1:]) == {("scatter", True)}


@needs_dask
def test_interrupted_on_the_cluster_then_resumed(client, tmp_path):
    job, out = _job(), tmp_path / "out"

    def stop_after_3(p: BatchProgress) -> None:
        if p.done == 3:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        batch(job, out, client, progress=stop_after_3)
    written = read_manifest(out)
    assert len(written) == 3 and len(_files(out)) == 3 and not list(out.glob(".*.tmp"))
    result = batch(job, out, client)
    assert sorted(result.skipped) == sorted(written) and len(result.done) == 9 and not result.failed


@needs_dask
def test_a_bad_frame_fails_alone_on_the_cluster(client, tmp_path):
    text = SWEEP.replace('programs = ["phong", "normals"]', 'programs = ["phong"]') + \
        '\n[[frames]]\nmodel = "suzanne"\nprogram = "textured"\nsize = "40x30"\n'
    result = batch(_job(text), tmp_path / "out", client)
    assert len(result.done) == 6 and len(result.failed) == 1
    name, error = result.failed[0]
    assert name == "suzanne-textured-az030-40x30" and error.startswith("ValueError: suzanne: the model has no")
