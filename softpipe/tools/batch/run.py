"""The run: a job's frames rendered on a Dask cluster (or in this process), written, resumable.

:func:`batch` renders a job (:mod:`softpipe.tools.batch.job`) into a folder: on a
``LocalCluster`` sized to this machine by default (one worker process per core, one
thread each, one numba thread each), on a running cluster given its scheduler's
address, or in this process (``scheduler="serial"``). The same frame makes the same
bytes whichever way it is rendered (:func:`render_frame`).

Models are loaded once, in the client, and scattered to the workers; the workers
render and encode the PNG, the client writes it (whole or not at all,
:func:`softpipe.core.files.atomic_write`) and appends a line to ``manifest.jsonl`` (name,
parameters, output, SHA-256, seconds), flushed per frame. A second run skips the
frames whose file still has the manifest's SHA-256 (:func:`read_manifest`). A frame
that raises is reported (its name and the error's line) and the others go on; a
worker that dies has its frames run again by Dask. ``contact-sheet.png`` shows every
frame at the end. docs/batch.md is the guide; ``python -m benchmarks.batch`` measures
the frames per second on 1, 2, … workers.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

from softpipe.core.runtime import keep_freed_memory
from softpipe.scenes.mesh import Mesh
from softpipe.tools.batch.job import Frame, Job, LightSet, as_job

__all__ = ["batch", "render_frame", "read_manifest", "BatchProgress", "BatchResult", "FrameRecord", "MANIFEST",
           "CONTACT_SHEET", "CONTACT_SHEET_MAX", "CRASH_ONCE_ENV"]

#: The file, in the output folder, that lists the frames written.
MANIFEST = "manifest.jsonl"
#: The contact sheet of every frame, in the output folder.
CONTACT_SHEET = "contact-sheet.png"
#: Frames on the contact sheet at most (the first ones, in the job's order).
CONTACT_SHEET_MAX = 400
#: Test-only: ``NAME:MARKER`` makes the worker rendering frame NAME exit at once (``os._exit``) when
#: the file MARKER does not exist yet, after creating it: a worker that dies once, mid-run.
CRASH_ONCE_ENV = "SOFTPIPE_BATCH_CRASH_ONCE"


# ---------------------------------------------------------------------------- one frame


def render_frame(frame: Frame, mesh: Mesh, job: Job) -> bytes:
    """The PNG bytes of one frame of ``job``, ``mesh`` being its model's mesh.

    The model is framed by the camera (:func:`softpipe.scenes.drawing.prepare_scene`; an orbit
    camera with :meth:`~softpipe.scenes.scene.Scene.view_camera`'s turntable fit), drawn with
    :func:`softpipe.scenes.drawing.render`: the same pixels as ``softpipe render`` with the same options.
    """
    return _render_png(frame, mesh, _frame_material(job, frame), job.lights[frame.lights], job.background,
                       job.fovy)


def _frame_material(job: Job, frame: Frame) -> Optional[Dict[str, Any]]:
    return None if frame.material == "default" else job.materials[frame.material]


def _render_png(frame: Frame, mesh: Mesh, material: Optional[Dict[str, Any]], lights: LightSet,
                background: Tuple[float, ...], fovy: float) -> bytes:
    from softpipe.scenes.drawing import prepare_scene, render
    if material is not None:
        base = mesh.material
        mesh = mesh.replace(material=base.replace(**material), materials=(), material_ids=None)
    scene = prepare_scene(mesh, width=frame.width, height=frame.height, program=frame.program,
                          samples=frame.samples, background=background, azimuth=frame.azimuth,
                          elevation=frame.elevation, fovy=fovy, shadows=lights.shadows)
    if lights.lights is not None:
        scene = scene.replace(lights=lights.lights, ambient=lights.ambient)
    elif lights.ambient != scene.ambient:
        scene = scene.replace(ambient=lights.ambient)
    camera = scene.view_camera(azimuth=frame.azimuth, orbit=True) if frame.orbit else scene.view_camera()
    buffer = io.BytesIO()
    render(scene, camera=camera).save(buffer, format="png")
    return buffer.getvalue()


def _render_task(frame: Frame, mesh: Mesh, material, lights: LightSet, background, fovy,
                 numba_threads: Optional[int]) -> Tuple[bytes, str, float, float]:
    """What a worker runs: the frame's PNG, its SHA-256, and the seconds it took (wall clock, CPU)."""
    _maybe_crash(frame)
    if numba_threads:
        import numba
        numba.set_num_threads(max(1, min(int(numba_threads), numba.config.NUMBA_NUM_THREADS)))
    start, cpu = time.perf_counter(), time.process_time()
    png = _render_png(frame, mesh, material, lights, background, fovy)
    return png, hashlib.sha256(png).hexdigest(), time.perf_counter() - start, time.process_time() - cpu


def _cluster_task(*args: Any) -> Tuple[Optional[bytes], str, float, float]:
    """:func:`_render_task` on a worker; a frame's error comes back as its line (``None, line, 0, 0``),
    so that the worker logs nothing and Dask does not take it for a lost worker."""
    keep_freed_memory()         # a worker process renders frames only: keep their memory (core/runtime.py)
    try:
        return _render_task(*args)
    except Exception as e:  # noqa: BLE001 - the client reports it with the frame's name
        return None, _error_line(e), 0.0, 0.0


def _maybe_crash(frame: Frame) -> None:
    """The test hook of :data:`CRASH_ONCE_ENV`: this worker process dies, once."""
    spec = os.environ.get(CRASH_ONCE_ENV)
    if not spec:
        return
    name, _, marker = spec.partition(":")
    if name == frame.name and marker:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return
        os.close(fd)
        os._exit(17)


# ---------------------------------------------------------------------------- results and progress


@dataclass
class FrameRecord:
    """A frame written: its name, file, SHA-256 of the file, and the seconds its render (and PNG
    encoding) took on its worker, on the wall clock and of CPU time (all its threads)."""

    name: str
    output: Path
    sha256: str
    seconds: float
    cpu_seconds: float = 0.0


@dataclass
class BatchProgress:
    """Where a run stands, given to ``progress`` after every frame (and once at the start).

    ``done`` frames were rendered in this run, ``skipped`` were already there, ``failed``
    raised; ``eta`` is the seconds left at this run's pace (None before the first frame);
    ``frame`` is the frame just finished and ``error`` its error line if it failed.
    """

    done: int
    skipped: int
    failed: int
    total: int
    elapsed: float
    eta: Optional[float]
    frame: Optional[str] = None
    error: Optional[str] = None

    @property
    def finished(self) -> int:
        return self.done + self.skipped + self.failed

    def line(self) -> str:
        """``12/24 frames (3 skipped, 1 failed), 4.1 frames/s, ETA 0:03``: the CLI's progress line."""
        rate = self.done / self.elapsed if self.elapsed > 0 and self.done else 0.0
        parts = [f"{self.finished}/{self.total} frames"]
        extra = [f"{n} {what}" for n, what in ((self.skipped, "skipped"), (self.failed, "failed")) if n]
        if extra:
            parts[0] += f" ({', '.join(extra)})"
        if rate:
            parts.append(f"{rate:.2f} frames/s")
        if self.eta is not None and self.finished < self.total:
            parts.append(f"ETA {int(self.eta) // 60}:{int(self.eta) % 60:02d}")
        return ", ".join(parts)


@dataclass
class BatchResult:
    """What :func:`batch` did: frames ``done`` (rendered now), ``skipped`` (names, already
    written) and ``failed`` ((name, error line) pairs), the manifest and the contact sheet."""

    out_dir: Path
    done: List[FrameRecord] = field(default_factory=list)
    skipped: List[str] = field(default_factory=list)
    failed: List[Tuple[str, str]] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    contact_sheet: Optional[Path] = None

    @property
    def manifest(self) -> Path:
        return self.out_dir / MANIFEST

    @property
    def ok(self) -> bool:
        return not self.failed


def read_manifest(out_dir: Union[str, os.PathLike]) -> Dict[str, Dict[str, Any]]:
    """The manifest's entries by frame name (a later line wins; a line cut short is ignored)."""
    entries: Dict[str, Dict[str, Any]] = {}
    try:
        with open(Path(out_dir) / MANIFEST, "rb") as f:
            for raw in f:
                try:
                    entry = json.loads(raw)
                except ValueError:
                    continue
                if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                    entries[entry["name"]] = entry
    except FileNotFoundError:
        pass
    return entries


def _sha256_file(path: Path) -> Optional[str]:
    try:
        with open(path, "rb") as f:
            return hashlib.file_digest(f, "sha256").hexdigest() if hasattr(hashlib, "file_digest") else \
                hashlib.sha256(f.read()).hexdigest()
    except OSError:
        return None


class _Manifest:
    """The manifest, appended one line per frame, each flushed to disk before the next frame."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = open(path, "ab")
        if self.file.tell():                     # a line cut short (a crash mid-write) ends here
            with open(path, "rb") as f:
                f.seek(-1, os.SEEK_END)
                if f.read(1) != b"\n":
                    self.file.write(b"\n")

    def append(self, entry: Dict[str, Any]) -> None:
        self.file.write(json.dumps(entry, sort_keys=True).encode() + b"\n")
        self.file.flush()
        os.fsync(self.file.fileno())

    def close(self) -> None:
        self.file.close()


# ---------------------------------------------------------------------------- the run


def batch(job, out_dir: Union[str, os.PathLike], scheduler=None, *, force: bool = False,
          progress: Optional[Callable[[BatchProgress], None]] = None, workers: Optional[int] = None,
          numba_threads: Optional[int] = 1, dashboard: Optional[str] = None,
          log: Optional[Callable[[str], None]] = None, contact_sheet: bool = True) -> BatchResult:
    """Render every frame of ``job`` into ``out_dir``: ``softpipe batch`` in Python.

    Parameters
    ----------
    job : Job, str, path-like or dict
        A :class:`Job`, a job file (:func:`load_job`) or dicts (:func:`job_from_dict`).
    out_dir : str or path-like
        The folder of the frames (``NAME.png``), ``manifest.jsonl`` and ``contact-sheet.png``;
        made if missing.
    scheduler : None, "serial", str or distributed.Client
        None: a ``LocalCluster`` of ``workers`` processes (default: one per core), one
        thread each, closed at the end. ``"serial"``: every frame in this process, in
        order. ``"tcp://host:8786"``: that cluster's scheduler. A ``distributed.Client``: its cluster.
    force : bool
        Render every frame, even one whose file matches the manifest.
    progress : callable, optional
        ``progress(BatchProgress)`` at the start and after every frame.
    workers : int, optional
        The LocalCluster's worker processes (``scheduler=None`` only).
    numba_threads : int or None
        numba threads per frame on a worker (1: one core per worker process); None leaves them.
    dashboard : str, optional
        The LocalCluster's dashboard address (``":8787"``); its link goes to ``log``. Needs bokeh.
    log : callable, optional
        ``log(message)`` for notes: the cluster started, its dashboard.
    contact_sheet : bool
        Write ``contact-sheet.png`` at the end.

    Returns
    -------
    BatchResult
        Failed frames do not raise: they are in ``failed`` with their error line.
        Ctrl-C (KeyboardInterrupt) is raised after the frames already received were
        written and listed; no file is left half-written.
    """
    job = as_job(job)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from softpipe.core.files import check_writable
    check_writable(out / MANIFEST)
    start = time.perf_counter()
    result = BatchResult(out_dir=out)
    entries = {} if force else read_manifest(out)
    todo = []
    for frame in job.frames:
        entry = entries.get(frame.name)
        if entry is not None and entry.get("params") == frame.params() and \
                _sha256_file(out / str(entry.get("output", ""))) == entry.get("sha256"):
            result.skipped.append(frame.name)
        else:
            todo.append(frame)
    state = _Run(job, out, result, start, progress)
    state.report()
    if todo:
        meshes = Job(frames=todo, models=job.models, path=job.path, base_dir=job.base_dir).load_models()
        manifest = _Manifest(out / MANIFEST)
        try:
            if scheduler == "serial":
                _run_serial(todo, meshes, job, state, manifest)
            else:
                _run_dask(todo, meshes, job, state, manifest, scheduler, workers, numba_threads, dashboard, log)
        finally:
            manifest.close()
    result.seconds = time.perf_counter() - start
    if contact_sheet:
        result.contact_sheet = _write_contact_sheet(job, out, result)
    return result


class _Run:
    """A run's bookkeeping: the result so far, the progress calls."""

    def __init__(self, job: Job, out: Path, result: BatchResult, start: float,
                 progress: Optional[Callable[[BatchProgress], None]]) -> None:
        self.job, self.out, self.result, self.start, self.progress = job, out, result, start, progress
        self.total = len(job.frames)

    def report(self, frame: Optional[str] = None, error: Optional[str] = None) -> None:
        if self.progress is None:
            return
        r = self.result
        elapsed = time.perf_counter() - self.start
        ran = len(r.done) + len(r.failed)
        left = self.total - ran - len(r.skipped)
        eta = elapsed / ran * left if ran else None
        self.progress(BatchProgress(len(r.done), len(r.skipped), len(r.failed), self.total, elapsed, eta,
                                    frame, error))

    def wrote(self, frame: Frame, png: bytes, sha: str, seconds: float, cpu: float, manifest: _Manifest) -> None:
        """Write a frame's file (whole or not at all), then its manifest line."""
        from softpipe.core.files import atomic_write
        path = self.out / f"{frame.name}.png"
        atomic_write(path, lambda f: f.write(png))
        manifest.append({"name": frame.name, "params": frame.params(), "output": path.name, "sha256": sha,
                         "seconds": round(seconds, 4)})
        self.result.done.append(FrameRecord(frame.name, path, sha, seconds, cpu))
        self.report(frame.name)

    def failed(self, frame: Frame, error: str) -> None:
        self.result.failed.append((frame.name, error))
        self.report(frame.name, self.result.failed[-1][1])


def _error_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _run_serial(todo: List[Frame], meshes: Dict[str, Mesh], job: Job, state: _Run, manifest: _Manifest) -> None:
    for frame in todo:
        try:
            png, sha, seconds, cpu = _render_task(frame, meshes[frame.model], _frame_material(job, frame),
                                             job.lights[frame.lights], job.background, job.fovy, None)
        except Exception as e:  # noqa: BLE001 - a frame's error is reported, the others go on
            state.failed(frame, _error_line(e))
            continue
        state.wrote(frame, png, sha, seconds, cpu, manifest)


def _run_dask(todo, meshes, job, state, manifest, scheduler, workers, numba_threads, dashboard, log) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise RuntimeError("rendering on a cluster needs Dask: pip install 'softpipe[cluster]' "
                           "(or scheduler='serial')") from None
    import contextlib
    import uuid
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            n = workers or os.cpu_count() or 1
            cluster = stack.enter_context(LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True,
                dashboard_address=":0" if dashboard is None else dashboard,   # None would still take :8787
                silence_logs=logging.ERROR))   # a frame's error is reported once, by the client
            client = stack.enter_context(Client(cluster))
            if log is not None:
                link = f", dashboard {cluster.dashboard_link}" if dashboard is not None else ""
                log(f"started a LocalCluster of {n} worker processes{link}")
        elif isinstance(scheduler, str):
            if workers is not None:
                raise ValueError("workers= sizes the LocalCluster; a scheduler's cluster has its own workers")
            client = stack.enter_context(Client(scheduler))
            if log is not None:
                log(f"connected to {scheduler} ({len(client.scheduler_info()['workers'])} workers)")
        else:
            client = scheduler
        state.result.workers = max(len(client.scheduler_info().get("workers", {})), 1)
        scattered = {name: client.scatter(mesh, broadcast=True, hash=False) for name, mesh in meshes.items()}
        run = uuid.uuid4().hex[:8]
        futures = {}
        for frame in todo:
            future = client.submit(_cluster_task, frame, scattered[frame.model], _frame_material(job, frame),
                                   job.lights[frame.lights], job.background, job.fovy, numba_threads,
                                   key=f"softpipe-frame-{frame.name}-{run}", pure=False)
            futures[future.key] = (future, frame)
        try:
            for future in as_completed([f for f, _ in futures.values()]):
                frame = futures[future.key][1]
                try:
                    png, sha, seconds, cpu = future.result()
                except Exception as e:  # noqa: BLE001 - a lost frame (KilledWorker, ...) is reported too
                    state.failed(frame, _error_line(e))
                else:
                    if png is None:
                        state.failed(frame, sha)
                    else:
                        state.wrote(frame, png, sha, seconds, cpu, manifest)
                future.release()
        finally:
            for future, _ in futures.values():
                future.cancel()
            for f in scattered.values():
                f.release()


# ---------------------------------------------------------------------------- the contact sheet


def _write_contact_sheet(job: Job, out: Path, result: BatchResult) -> Optional[Path]:
    """Every written frame, in the job's order, as labelled thumbnails (:func:`softpipe.views.pictures.contact_sheet`)."""
    import numpy as np
    from PIL import Image

    from softpipe.core.files import atomic_write
    from softpipe.views.pictures import contact_sheet
    failed = {name for name, _ in result.failed}
    names = [f.name for f in job.frames if f.name not in failed and (out / f"{f.name}.png").is_file()]
    names = names[:CONTACT_SHEET_MAX]
    if not names:
        return None
    width = int(min(max(6 * max(len(n) for n in names) + 8, 160), 320))
    height = width * 3 // 4
    pictures = {}
    for name in names:
        with Image.open(out / f"{name}.png") as im:
            im = im.convert("RGB")
            im.thumbnail((width, height), Image.Resampling.LANCZOS)
            tile = Image.new("RGB", (width, height), (24, 24, 28))
            tile.paste(im, ((width - im.width) // 2, (height - im.height) // 2))
        pictures[name] = np.asarray(tile)
    columns = max(1, min(len(names), round(math.sqrt(len(names) * 4 / 3)), 8))
    sheet = contact_sheet(pictures, columns=columns)
    path = out / CONTACT_SHEET
    atomic_write(path, lambda f: sheet.save(f, format="PNG"))
    return path
