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
frames whose content key (:func:`frame_params`: a digest of everything the frame's
pixels depend on) is the manifest's and whose file still has the manifest's SHA-256
(:func:`read_manifest`); the folder's files are trusted no further than that (a link or
a special file there is never followed or read). A frame
that raises is reported (its name and the error's line) and the others go on; a
worker that dies has its frames run again by Dask. ``contact-sheet.png`` shows every
frame at the end. docs/batch.md is the guide; ``python -m benchmarks.batch`` measures
the frames per second on 1, 2, … workers.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import json
import logging
import math
import os
import re
import signal
import stat
import threading
import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Collection, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from softpipe.core.files import PathPolicyError
from softpipe.core.runtime import keep_freed_memory
from softpipe.core.version import VERSION
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.scenefile import SceneWarning
from softpipe.tools.batch.job import Frame, Job, LightSet, as_job

__all__ = ["batch", "render_frame", "read_manifest", "frame_params", "local_worker_limit", "check_local_cluster",
           "BatchProgress",
           "BatchResult", "FrameRecord", "ClusterError", "MANIFEST", "CONTACT_SHEET", "CONTACT_SHEET_MAX",
           "CRASH_ONCE_ENV", "MAX_MANIFEST_LINE"]

#: The file, in the output folder, that lists the frames written.
MANIFEST = "manifest.jsonl"
#: The contact sheet of every frame, in the output folder.
CONTACT_SHEET = "contact-sheet.png"
#: Frames on the contact sheet at most (the first ones, in the job's order).
CONTACT_SHEET_MAX = 400
#: Test-only: ``NAME:MARKER`` makes the worker rendering frame NAME exit at once (``os._exit``) when
#: the file MARKER does not exist yet, after creating it: a worker that dies once, mid-run.
CRASH_ONCE_ENV = "SOFTPIPE_BATCH_CRASH_ONCE"
#: The longest manifest line read (bytes); a longer one is skipped, as a line cut short is.
MAX_MANIFEST_LINE = 1 << 16
#: Worker processes of a LocalCluster per core, at most (each draws on one core; more only wait for one).
WORKERS_PER_CORE = 2
#: How long a batch on a cluster whose size it knows waits for its workers before scattering the meshes.
WORKERS_TIMEOUT_S = 30.0


class ClusterError(RuntimeError):
    """The LocalCluster did not start (a dashboard address that cannot be bound, …); one line."""


# ---------------------------------------------------------------------------- one frame


def render_frame(frame: Frame, mesh: Mesh, job: Job) -> bytes:
    """The PNG bytes of one frame of ``job``, ``mesh`` being its model's mesh.

    The model is framed by the camera (:func:`softpipe.scenes.drawing.prepare_scene`; an orbit
    camera with :meth:`~softpipe.scenes.scene.Scene.view_camera`'s turntable fit), drawn with
    :func:`softpipe.scenes.drawing.render`: the same pixels as ``softpipe render`` with the same options;
    a frame with ``pathtrace`` by :func:`softpipe.tracers.pathtrace.pathtrace` (``spp`` samples per pixel,
    ``seed``, ``background_light``): the same bytes for the same seed on any worker and thread count.
    """
    return _render_png(frame, mesh, _frame_material(job, frame), job.lights[frame.lights], job.background,
                       job.fovy)[0]


def _frame_material(job: Job, frame: Frame) -> Optional[Dict[str, Any]]:
    return None if frame.material == "default" else job.materials[frame.material]


def _render_png(frame: Frame, mesh: Mesh, material: Optional[Dict[str, Any]], lights: LightSet,
                background: Tuple[float, ...], fovy: float,
                outputs: Tuple[str, ...] = ()) -> Tuple[bytes, Dict[str, bytes]]:
    """The frame's PNG, and its ``outputs`` encoded as files (:func:`softpipe.scenes.outputs.output_files`:
    ``"NAME.npy"`` and ``"NAME.png"``)."""
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
    if frame.pathtrace:         # the job's background is the sky that lights it: the light sets have no area
        from softpipe.tracers.pathtrace import pathtrace
        pathtrace(scene, frame.spp, frame.seed, camera=camera,
                  background_light=frame.background_light).save(buffer, format="png")
    elif outputs:
        from softpipe.scenes.outputs import output_files
        made = render(scene, camera=camera, outputs=outputs)
        made.framebuffer.save(buffer, format="png")
        return buffer.getvalue(), output_files(made)
    else:
        render(scene, camera=camera).save(buffer, format="png")
    return buffer.getvalue(), {}


def _render_task(frame: Frame, mesh: Mesh, material, lights: LightSet, background, fovy,
                 numba_threads: Optional[int], outputs: Tuple[str, ...] = ()
                 ) -> Tuple[bytes, str, float, float, Dict[str, bytes]]:
    """What a worker runs: the frame's PNG, its SHA-256, the seconds it took (wall clock, CPU) and its
    outputs' files."""
    _maybe_crash(frame)
    if numba_threads:
        import numba
        numba.set_num_threads(max(1, min(int(numba_threads), numba.config.NUMBA_NUM_THREADS)))
    start, cpu = time.perf_counter(), time.process_time()
    png, files = _render_png(frame, mesh, material, lights, background, fovy, outputs)
    return png, hashlib.sha256(png).hexdigest(), time.perf_counter() - start, time.process_time() - cpu, files


def _cluster_task(*args: Any) -> Tuple[Optional[bytes], str, float, float, Dict[str, bytes]]:
    """:func:`_render_task` on a worker; a frame's error comes back as its line (``None, line, 0, 0, {}``),
    so that the worker logs nothing and Dask does not take it for a lost worker."""
    keep_freed_memory()         # a worker process renders frames only: keep their memory (core/runtime.py)
    try:
        return _render_task(*args)
    except Exception as e:  # noqa: BLE001 - the client reports it with the frame's name
        return None, _error_line(e), 0.0, 0.0, {}


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


# ---------------------------------------------------------------------------- the content key


def _canonical(value: Any) -> Any:
    """``value`` as JSON values, exactly: dataclasses by field, arrays by dtype, shape and SHA-256."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if hasattr(value, "dtype") and hasattr(value, "tobytes"):
        a = np.ascontiguousarray(value)
        return {"dtype": a.dtype.str, "shape": list(a.shape), "sha256": hashlib.sha256(a.tobytes()).hexdigest()}
    if isinstance(value, float):
        return repr(value)              # every bit, and nan or inf as JSON cannot
    return value


def _digest(value: Any) -> str:
    text = json.dumps(_canonical(value), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _mesh_digest(mesh: Mesh) -> str:
    """What a mesh draws: its arrays and materials, a texture by its file's bytes (not its path)."""
    def material(m):
        texture = m.diffuse_texture
        return dataclasses.replace(m, diffuse_texture=None), (_sha256_file(Path(texture), follow=True)
                                                              if texture else None)
    parts = {f.name: getattr(mesh, f.name) for f in dataclasses.fields(mesh) if f.name not in ("name", "source")}
    parts["material"] = material(mesh.material)
    parts["materials"] = [material(m) for m in mesh.materials]
    return _digest(parts)


def _softpipe_version() -> str:
    return VERSION


def frame_params(frame: Frame, job: Job, model_digest: str) -> Dict[str, Any]:
    """A frame's manifest ``params``: :meth:`Frame.params`, its ``inputs`` and its content ``key``.

    ``inputs`` are short digests of what the frame's pixels depend on besides its own
    parameters: the model's mesh (``model_digest``: its arrays, materials and the bytes of
    its texture), the material's and the light set's values, ``[job]`` background and
    fovy, and softpipe's version; ``key`` is the SHA-256 of all of it. A run skips a frame
    only when the manifest holds the same ``params`` (docs/batch.md).
    """
    material = None if frame.material == "default" else job.materials[frame.material]
    inputs = {"model": model_digest[:16], "material": _digest(material)[:16],
              "lights": _digest(job.lights[frame.lights])[:16], "background": list(job.background),
              "fovy": job.fovy, "softpipe": _softpipe_version()}
    if job.outputs:         # only then: a job without outputs keeps the keys it had before there were any
        inputs["outputs"] = list(job.outputs)
    params = frame.params()
    params["inputs"] = inputs
    params["key"] = _digest(params)
    return params


def _why_changed(frame: Frame, old: Any, new: Dict[str, Any]) -> str:
    """Why a manifest line's ``params`` no longer hold: the inputs that changed, named as the job names them."""
    if not isinstance(old, dict) or not isinstance(old.get("inputs"), dict):
        return "its manifest line has no content key (an older softpipe wrote it)"
    before = old["inputs"]
    names = {"model": f"model {frame.model!r}", "material": f"material {frame.material!r}",
             "lights": f"light set {frame.lights!r}", "background": "[job] background", "fovy": "[job] fovy"}
    changed = [names[k] for k in names if before.get(k) != new["inputs"][k]]
    if before.get("softpipe") != new["inputs"]["softpipe"]:
        changed.append(f"softpipe {before.get('softpipe')} → {new['inputs']['softpipe']}")
    return ", ".join(changed) if changed else "its parameters"


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
    written) and ``failed`` ((name, error line) pairs), the manifest and the contact sheet.
    ``rerendered`` are the (name, why) of frames in the manifest rendered again because
    what they depend on changed (or their file did)."""

    out_dir: Path
    done: List[FrameRecord] = field(default_factory=list)
    skipped: List[str] = field(default_factory=list)
    failed: List[Tuple[str, str]] = field(default_factory=list)
    rerendered: List[Tuple[str, str]] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    contact_sheet: Optional[Path] = None

    @property
    def manifest(self) -> Path:
        return self.out_dir / MANIFEST

    @property
    def ok(self) -> bool:
        return not self.failed


#: open() flags that never follow a link (ELOOP) nor wait on a FIFO.
_NO_FOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)


def _open_manifest(path: Path, flags: int) -> int:
    """A descriptor of the manifest, which must be a regular file in the folder (not a link, a FIFO, a device)."""
    try:
        fd = os.open(path, flags | _NO_FOLLOW, 0o666)
    except OSError:
        if not os.path.lexists(path) or stat.S_ISREG(os.lstat(path).st_mode):
            raise                               # missing (the caller's case), or unwritable: as it is
        mode = os.lstat(path).st_mode           # a link (ELOOP), a FIFO without a reader (ENXIO), …
    else:
        mode = os.fstat(fd).st_mode
        if stat.S_ISREG(mode):
            return fd
        os.close(fd)
    problem = ("a symbolic link" if stat.S_ISLNK(mode) else "a FIFO" if stat.S_ISFIFO(mode) else
               "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a folder" if stat.S_ISDIR(mode) else
               "not a regular file")
    raise PathPolicyError(f"{path} is {problem}; softpipe batch reads and appends its manifest only as a "
                          "regular file in the output folder (remove it, or write into another folder)")


def read_manifest(out_dir: Union[str, os.PathLike], names: Optional[Collection[str]] = None
                  ) -> Dict[str, Dict[str, Any]]:
    """The manifest's entries by frame name (a later line wins; a line cut short, or longer than
    :data:`MAX_MANIFEST_LINE`, is ignored); only those of ``names`` when given.

    The manifest must be a regular file (a link or a special file there is refused with a
    :class:`~softpipe.core.files.PathPolicyError`, never followed or read).
    """
    entries: Dict[str, Dict[str, Any]] = {}
    try:
        fd = _open_manifest(Path(out_dir) / MANIFEST, os.O_RDONLY)
    except FileNotFoundError:
        return entries
    with os.fdopen(fd, "rb") as f:
        while True:
            raw = f.readline(MAX_MANIFEST_LINE + 1)
            if not raw:
                break
            if len(raw) > MAX_MANIFEST_LINE:            # read past the rest of it, bounded
                while raw and not raw.endswith(b"\n"):
                    raw = f.readline(MAX_MANIFEST_LINE + 1)
                continue
            try:
                entry = json.loads(raw)
            except ValueError:
                continue
            if isinstance(entry, dict) and isinstance(entry.get("name"), str) and \
                    (names is None or entry["name"] in names):
                entries[entry["name"]] = entry
    return entries


def _sha256_file(path: Path, follow: bool = False) -> Optional[str]:
    """SHA-256 of a regular file's bytes; None for what is missing, a link (unless ``follow``) or not a
    regular file (a device such as /dev/zero would never end)."""
    try:
        fd = os.open(path, os.O_RDONLY | (_NO_FOLLOW if not follow else getattr(os, "O_NONBLOCK", 0)))
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        digest = hashlib.sha256()
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
        return digest.hexdigest()


class _Manifest:
    """The manifest, appended one line per frame, each flushed to disk before the next frame."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = os.fdopen(_open_manifest(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT), "ab")
        size = os.fstat(self.file.fileno()).st_size
        if size:                                 # a line cut short (a crash mid-write) ends here
            with os.fdopen(_open_manifest(path, os.O_RDONLY), "rb") as f:
                f.seek(size - 1)
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
    if scheduler is None:
        check_local_cluster(workers, dashboard)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from softpipe.core.files import check_writable
    check_writable(out / MANIFEST)
    entries = {} if force else read_manifest(out, {f.name for f in job.frames})
    start = time.perf_counter()
    result = BatchResult(out_dir=out)
    meshes = _load_models(job, log)
    model_digests = {name: _mesh_digest(mesh) for name, mesh in meshes.items()}
    params = {f.name: frame_params(f, job, model_digests[f.model]) for f in job.frames}
    todo = []
    for frame in job.frames:
        entry = entries.get(frame.name)
        if entry is None:
            todo.append(frame)
            continue
        same = entry.get("params") == params[frame.name]
        if same and entry.get("output") == f"{frame.name}.png" and \
                _sha256_file(out / f"{frame.name}.png") == entry.get("sha256") and _outputs_intact(out, entry):
            result.skipped.append(frame.name)
            continue
        todo.append(frame)
        why = _why_changed(frame, entry.get("params"), params[frame.name]) if not same else \
            "its file is missing or changed"
        result.rerendered.append((frame.name, why))
    if result.rerendered and log is not None:
        reasons = Counter(part for _, why in result.rerendered for part in why.split(", "))
        n = len(result.rerendered)
        log(f"rendering {n} frame{'s' * (n != 1)} again (changed since the manifest): " +
            "; ".join(f"{why} ({k} frame{'s' * (k != 1)})" for why, k in reasons.items()))
    state = _Run(job, out, result, start, progress, params)
    state.report()
    if todo:
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


def _load_models(job: Job, log: Optional[Callable[[str], None]]) -> Dict[str, Mesh]:
    """Every model the frames use, once; what loading one warns about goes to ``log`` (else it is
    issued as a :class:`~softpipe.scenes.scenefile.SceneWarning`), once per model."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        meshes = job.load_models()
    for w in caught:
        if log is not None and issubclass(w.category, SceneWarning):
            log(f"warning: {w.message}")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return meshes


def local_worker_limit() -> int:
    """The most worker processes a LocalCluster takes on this machine: :data:`WORKERS_PER_CORE` per core."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


#: A dashboard's address: ``:PORT``, ``HOST:PORT`` or ``[IPv6]:PORT``, or ``PORT`` alone.
_ADDRESS = re.compile(r"(?:(?:[A-Za-z0-9_.-]*|\[[0-9A-Fa-f:.]+\]):)?([0-9]{1,5})")


def check_local_cluster(workers: Optional[int], dashboard: Optional[str],
                        names: Tuple[str, str] = ("workers=", "dashboard=")) -> None:
    """Refuse, before anything starts, a LocalCluster's size or dashboard address that cannot work
    (a ValueError; ``names`` are how the message names the two: ``("--workers ", "--dashboard ")``)."""
    if workers is not None:
        limit = local_worker_limit()
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"{names[0]}{workers!r}: a LocalCluster needs a whole number of worker processes, 1 "
                             "or more")
        if workers > limit:
            raise ValueError(f"{names[0]}{workers}: this machine has {os.cpu_count() or 1} cores, and a LocalCluster "
                             f"takes at most {limit} worker processes ({WORKERS_PER_CORE} per core; more would only "
                             "wait for a core); for more, start a cluster and give its scheduler's address")
    if dashboard is not None:
        m = _ADDRESS.fullmatch(dashboard) if isinstance(dashboard, str) else None
        if m is None or int(m.group(1)) > 65535:
            raise ValueError(f"{names[1]}{dashboard!r}: expected an address [HOST]:PORT such as ':8787' or "
                             "'localhost:8787' (PORT 0 to 65535)")


@contextlib.contextmanager
def _interrupt_held() -> Iterator[None]:
    """Ctrl-C while a LocalCluster starts is held until it has started, then raised (and the
    cluster closed by the caller): a cluster interrupted half-way is left to Dask's exit hook,
    which fails with a traceback. A second Ctrl-C stops at once."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pressed: List[int] = []

    def hold(signum, _frame) -> None:
        if pressed:
            raise KeyboardInterrupt
        pressed.append(signum)
    old = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old if old is not None else signal.default_int_handler)
    if pressed:
        raise KeyboardInterrupt


def _root_cause(e: BaseException) -> BaseException:
    """The first exception of ``e``'s chain (its cause, or the one it was raised while handling)."""
    seen = {id(e)}
    inner = e.__cause__ or e.__context__
    while inner is not None and id(inner) not in seen:
        e = inner
        seen.add(id(e))
        inner = e.__cause__ or e.__context__
    return e


class _Run:
    """A run's bookkeeping: the result so far, the progress calls, each frame's manifest ``params``."""

    def __init__(self, job: Job, out: Path, result: BatchResult, start: float,
                 progress: Optional[Callable[[BatchProgress], None]], params: Dict[str, Dict[str, Any]]) -> None:
        self.job, self.out, self.result, self.start, self.progress = job, out, result, start, progress
        self.params = params
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

    def wrote(self, frame: Frame, png: bytes, sha: str, seconds: float, cpu: float, manifest: _Manifest,
              files: Optional[Dict[str, bytes]] = None) -> None:
        """Write a frame's files (each whole or not at all: its outputs' ``NAME.OUTPUT.npy`` and
        ``.png`` first, the picture last), then its manifest line, which lists the outputs' files
        with their SHA-256; a file that cannot be written (a folder in its place, a full disk)
        fails the frame alone."""
        from softpipe.core.files import atomic_write_bytes
        path = self.out / f"{frame.name}.png"
        listed: Dict[str, Dict[str, str]] = {}
        try:
            for suffix, data in (files or {}).items():
                atomic_write_bytes(self.out / f"{frame.name}.{suffix}", data)
                listed[suffix] = {"file": f"{frame.name}.{suffix}", "sha256": hashlib.sha256(data).hexdigest()}
            atomic_write_bytes(path, png)
        except OSError as e:
            self.failed(frame, _error_line(e))
            return
        entry = {"name": frame.name, "params": self.params[frame.name], "output": path.name,
                 "sha256": sha, "seconds": round(seconds, 4)}
        if listed:
            entry["outputs"] = listed
        manifest.append(entry)
        self.result.done.append(FrameRecord(frame.name, path, sha, seconds, cpu))
        self.report(frame.name)

    def failed(self, frame: Frame, error: str) -> None:
        self.result.failed.append((frame.name, error))
        self.report(frame.name, self.result.failed[-1][1])


def _error_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _outputs_intact(out: Path, entry: Dict[str, Any]) -> bool:
    """Does every output file a manifest line lists still have its SHA-256?"""
    listed = entry.get("outputs") or {}
    if not isinstance(listed, dict):
        return False
    return all(isinstance(v, dict) and isinstance(v.get("file"), str) and "/" not in v["file"]
               and _sha256_file(out / v["file"]) == v.get("sha256") for v in listed.values())


def _run_serial(todo: List[Frame], meshes: Dict[str, Mesh], job: Job, state: _Run, manifest: _Manifest) -> None:
    for frame in todo:
        try:
            png, sha, seconds, cpu, files = _render_task(frame, meshes[frame.model], _frame_material(job, frame),
                                                         job.lights[frame.lights], job.background, job.fovy, None,
                                                         job.outputs)
        except Exception as e:  # noqa: BLE001 - a frame's error is reported, the others go on
            state.failed(frame, _error_line(e))
            continue
        state.wrote(frame, png, sha, seconds, cpu, manifest, files)


def _run_dask(todo, meshes, job, state, manifest, scheduler, workers, numba_threads, dashboard, log) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise RuntimeError("rendering on a cluster needs Dask: pip install 'softpipe[cluster]' "
                           "(or scheduler='serial')") from None
    import uuid
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            n = workers or os.cpu_count() or 1
            with _interrupt_held():
                try:
                    cluster = stack.enter_context(LocalCluster(
                        n_workers=n, threads_per_worker=1, processes=True,
                        dashboard_address=":0" if dashboard is None else dashboard,   # None would still take :8787
                        silence_logs=logging.ERROR))   # a frame's error is reported once, by the client
                except Exception as e:  # noqa: BLE001 - Dask's "Cluster failed to start", whatever the cause
                    hint = f" (the dashboard address {dashboard!r}?)" if dashboard is not None else ""
                    raise ClusterError(f"the LocalCluster did not start: {_error_line(_root_cause(e))}{hint}") \
                        from None
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
        _wait_for_the_clusters_workers(client)
        state.result.workers = max(len(client.scheduler_info().get("workers", {})), 1)
        # every worker gets a copy of each mesh, so that a worker that dies takes none of them with it
        scattered = {name: client.scatter(mesh, broadcast=True, hash=False) for name, mesh in meshes.items()}
        run = uuid.uuid4().hex[:8]
        futures = {}
        for frame in todo:
            future = client.submit(_cluster_task, frame, scattered[frame.model], _frame_material(job, frame),
                                   job.lights[frame.lights], job.background, job.fovy, numba_threads, job.outputs,
                                   key=f"softpipe-frame-{frame.name}-{run}", pure=False)
            futures[future.key] = (future, frame)
        try:
            for future in as_completed([f for f, _ in futures.values()]):
                frame = futures[future.key][1]
                try:
                    png, sha, seconds, cpu, files = future.result()
                except Exception as e:  # noqa: BLE001 - a lost frame (KilledWorker, ...) is reported too
                    state.failed(frame, _error_line(e))
                else:
                    if png is None:
                        state.failed(frame, sha)
                    else:
                        state.wrote(frame, png, sha, seconds, cpu, manifest, files)
                future.release()
        finally:
            for future, _ in futures.values():
                future.cancel()
            for f in scattered.values():
                f.release()


def _wait_for_the_clusters_workers(client, timeout: float = WORKERS_TIMEOUT_S) -> None:
    """Wait (at most ``timeout`` seconds) until every worker of the client's own cluster has joined, when
    the client knows its cluster (a LocalCluster's workers, as specified). A mesh is broadcast to the
    workers there are: one scattered while a worker was still joining lived on the other alone, and a
    frame that killed that worker lost it, with every frame still to draw (seen under load, in
    tests/test_batch.py's killed worker). A scheduler's cluster of unknown size is taken as it is."""
    spec = getattr(getattr(client, "cluster", None), "worker_spec", None)
    if not spec:
        return
    try:
        client.wait_for_workers(len(spec), timeout=timeout)
    except (TimeoutError, OSError):      # (the workers there are will do; a lost one is reported per frame)
        pass


# ---------------------------------------------------------------------------- the contact sheet


def _write_contact_sheet(job: Job, out: Path, result: BatchResult) -> Optional[Path]:
    """Every written frame, in the job's order, as labelled thumbnails (:func:`softpipe.views.pictures.contact_sheet`)."""
    from PIL import Image

    from softpipe.core.files import atomic_write
    from softpipe.views.pictures import contact_sheet
    written = {r.name for r in result.done} | set(result.skipped)     # files this run wrote or checked
    names = [f.name for f in job.frames if f.name in written and (out / f"{f.name}.png").is_file()]
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
