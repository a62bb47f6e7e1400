"""Ray queries: ``python -m benchmarks.rays`` (``make bench-rays``; issue 16, "Speed").

For each model (default: the bunny and the armadillo, :func:`softpipe.scenes.models.load_model`):

* **build**: :meth:`softpipe.rays.bvh.BVH.build` (binned SAH, ``leaf_size=4, bins=16``), warm
  (one untimed build first), median of ``--repeats``;
* **rays** at ``--size`` (default 1024²), three kinds, each a batch query of the whole set:

  - ``primary``: one ray per pixel centre of the framing camera
    (``Scene.from_model(model, width=size, height=size).view_camera()``), from the near
    plane toward the far plane, ``t`` in (0, distance to the far plane): the rays of
    ``softpipe.tracers.whitted._primary_ray``, generated here in numpy. Closest hit
    (:meth:`BVH.closest`). Rays that miss the model count: the figure is pixels/s.
  - ``shadow``: from every primary hit toward a point light (three radii of the model
    from its centre, in the direction of the studio key light), any hit
    (:meth:`BVH.occluded`) with ``t_min = ε`` (1e-4 × the model's diagonal) and
    ``t_max`` = the distance to the light.
  - ``secondary``: from every primary hit in the mirror direction (``d − 2(d·n)n``, n the
    triangle's geometric normal), closest hit, ``t_min = ε``, ``t_max = ∞``.
  - ``shadow-closest``: the shadow rays again, as closest-hit queries (:meth:`BVH.closest`,
    Embree's INTERSECT): any hit against closest hit on the *same* rays. (Shadow and
    secondary rays are different rays: a shadow ray toward the light crosses more of the
    model than a mirror ray, which mostly leaves it, so ``shadow`` below ``secondary`` says
    nothing about the any-hit query itself; this row does.)

  The shadow and secondary rays start at softpipe's primary hits; every side traces the same
  rays. Million rays per second on 1 and 2 numba threads (``numba.set_num_threads``;
  ``--threads``), medians of ``--repeats`` rounds, one untimed run of each query first.

**Embree** (``embreex``, Intel Embree 4 from Python; ``pip install embreex``, or
``make bench-rays``, which installs it): the same BVH builds and the same rays through
``EmbreeScene.run``, **alternated** with softpipe's runs round by round (ABBA: softpipe
first in even rounds, Embree first in odd ones) so that the machine's drift lands on both,
and the ratio softpipe/Embree in rays/s (median of each, and the median of the per-round
ratios). What embreex gives, and what that means for the comparison:

* ``run`` traces its rays one by one on the calling thread, and releases the GIL while it does
  (embreex 4.4: 2 Python threads trace 1024² bunny rays 1.7× faster than one). Embree at n
  threads is therefore ``run`` on n Python threads over bands of the rays (4 bands per thread,
  at least 1024 rays each, taken in turn), as softpipe's :func:`~softpipe.core.parallel.in_bands` does;
  softpipe at n threads is compared with Embree at n threads.
* Embree's build uses its own TBB thread pool (every core); it cannot be limited from
  embreex. Its build time is "scene + geometry + commit", the device made once before.
* Embree works in float32 (softpipe in float64), and ``run`` sets ``tnear = 0``: the shadow and
  secondary rays go to Embree with their origin moved ε along the ray and ``t_max − ε``, the
  same segment.
* ``run(..., output=True)`` (closest hits) returns the triangle, t, u, v and the normal, as
  softpipe's ``closest`` returns the triangle, t and the barycentrics.

**Agreement** (on the last round's results): for closest hits, the share of rays whose hit
triangle differs (a different triangle, or a hit on one side and a miss on the other) and
the largest and median relative difference of t where both hit the same triangle (and the
largest absolute one over the model's diagonal: a secondary ray's t can be tiny); for
shadow rays, the share whose occluded/visible answer differs. Differences are expected to be
tiny: rays through an edge or a vertex two triangles share, and float32 against float64.

The load average (``os.getloadavg()``) is recorded before and after each model: other jobs
on the machine slow both sides; the alternation and the per-round ratios are there for that.
Each run also records its process CPU time: CPU over wall (about n for n threads that had
their cores, less when other jobs took them) and rays per CPU-second, the figure the load
disturbs least.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Callable, Dict, List, Optional, Sequence  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from softpipe.core.runtime import keep_freed_memory  # noqa: E402
from softpipe.rays.bvh import BVH  # noqa: E402
from softpipe.scenes.models import load_model  # noqa: E402
from softpipe.scenes.scene import Scene  # noqa: E402

from .run import machine_info, source_state  # noqa: E402
from .scenes import REPO_ROOT  # noqa: E402

__all__ = ["KINDS", "SAME_RAYS", "ALL_KINDS", "DEFAULT_MODELS", "EMBREE_REQUIREMENT", "primary_rays",
           "secondary_rays", "embree_status",
           "EmbreeSide", "SoftpipeSide", "agreement", "run_model", "run", "format_table", "main"]

KINDS = ("primary", "shadow", "secondary")
#: Measured after KINDS: the shadow rays as closest-hit queries (see the module docstring).
SAME_RAYS = ("shadow-closest",)
ALL_KINDS = KINDS + SAME_RAYS
DEFAULT_MODELS = ("bunny", "armadillo")
DEFAULT_SIZE = 1024
DEFAULT_REPEATS = 7
DEFAULT_THREADS = (1, 2)
DEFAULT_JSON = REPO_ROOT / "out" / "bench-rays.json"
EMBREE_REQUIREMENT = "embreex"
#: ε of the shadow and secondary rays, relative to the model's bounding-box diagonal.
EPSILON_REL = 1e-4
#: The point light: this many bounding-sphere radii from the model's centre, toward the studio key light.
LIGHT_DISTANCE_RADII = 3.0
#: The studio key light's direction toward the light, in eye space (softpipe.scenes.scene.studio_lights).
KEY_TOWARD_LIGHT_EYE = (-0.6, 0.7, 0.7)


# ------------------------------------------------------------------------------ the rays

def primary_rays(camera, width: int, height: int):
    """One ray per pixel centre: (origins [R, 3] on the near plane, unit directions [R, 3], t_max [R]).

    Pixel (i, image row j) is ray ``j * width + i``; numpy's version of
    ``softpipe.tracers.whitted._primary_ray``: NDC (2(i+½)/w − 1, 1 − 2(j+½)/h) unprojected at
    z = −1 (origin) and z = +1, the direction their unit difference, t_max its length.
    """
    unproject = np.linalg.inv(camera.projection(width / height) @ camera.view)
    i = np.arange(width, dtype=np.float64)
    j = np.arange(height, dtype=np.float64)
    x = np.broadcast_to(2.0 * (i + 0.5) / width - 1.0, (height, width)).ravel()
    y = np.broadcast_to((1.0 - 2.0 * (j + 0.5) / height)[:, None], (height, width)).ravel()

    def at(z):
        p = np.stack([x, y, np.full_like(x, z), np.ones_like(x)], axis=1) @ unproject.T
        return p[:, :3] / p[:, 3:4]

    near, far = at(-1.0), at(1.0)
    d = far - near
    length = np.linalg.norm(d, axis=1)
    return np.ascontiguousarray(near), np.ascontiguousarray(d / length[:, None]), length


def _geometric_normals(vertices, triangles, ids):
    tri = triangles[ids]
    n = np.cross(vertices[tri[:, 1]] - vertices[tri[:, 0]], vertices[tri[:, 2]] - vertices[tri[:, 0]])
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


def secondary_rays(vertices, triangles, origins, directions, ids, t, light):
    """From the hits of closest-hit rays (ids ≥ 0): the shadow rays toward ``light`` and the mirror rays.

    Returns ``{"points", "shadow_dir", "shadow_tmax", "mirror_dir"}`` (unit directions).
    """
    hit = ids >= 0
    p = origins[hit] + t[hit, None] * directions[hit]
    to_light = np.asarray(light, np.float64) - p
    dist = np.linalg.norm(to_light, axis=1)
    d = directions[hit]
    n = _geometric_normals(vertices, triangles, ids[hit])
    r = d - 2.0 * np.sum(d * n, axis=1)[:, None] * n
    r /= np.linalg.norm(r, axis=1)[:, None]
    return {"points": np.ascontiguousarray(p), "shadow_dir": np.ascontiguousarray(to_light / dist[:, None]),
            "shadow_tmax": dist, "mirror_dir": np.ascontiguousarray(r)}


def _light(camera, vertices):
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    toward = camera.view[:3, :3].T @ np.asarray(KEY_TOWARD_LIGHT_EYE, np.float64)
    return centre + LIGHT_DISTANCE_RADII * radius * toward / np.linalg.norm(toward), 2.0 * radius


# ------------------------------------------------------------------------------ the two sides

class SoftpipeSide:
    """softpipe's BVH and its batch queries; ``rays`` holds the prepared rays per kind."""

    name = "softpipe"

    def __init__(self, vertices, triangles):
        self.vertices, self.triangles = vertices, triangles
        self.bvh = BVH.build(vertices, triangles)

    def build(self) -> float:
        t0 = time.perf_counter()
        BVH.build(self.vertices, self.triangles)
        return time.perf_counter() - t0

    def trace(self, kind: str, rays: dict):
        if kind == "shadow":
            return self.bvh.occluded(rays["origins"], rays["directions"], rays["t_min"], rays["t_max"])
        ids, t, _ = self.bvh.closest(rays["origins"], rays["directions"], rays["t_min"], rays["t_max"])
        return ids, t


def embree_status() -> Optional[str]:
    """None when embreex imports, else why not (the message of the import error)."""
    try:
        import embreex.mesh_construction  # noqa: F401
        import embreex.rtcore_scene  # noqa: F401
    except Exception as e:       # ImportError, or a missing libembree/libtbb (OSError)
        return f"embreex is not installed or does not load ({type(e).__name__}: {e})"
    return None


def install_embree() -> Optional[str]:
    """pip install embreex into this interpreter; None on success, else what went wrong."""
    if embree_status() is None:
        return None
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "-q", EMBREE_REQUIREMENT],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        return f"pip install {EMBREE_REQUIREMENT} failed: {(proc.stderr or proc.stdout).strip()[-500:]}"
    return embree_status()


class EmbreeSide:
    """The same queries through embreex (float32; origins moved ε along the ray for t_min = ε: run sets tnear = 0)."""

    name = "embree"

    def __init__(self, vertices, triangles):
        from embreex import rtcore
        self.vertices = np.ascontiguousarray(vertices, np.float32)
        self.triangles = np.ascontiguousarray(triangles, np.int32)
        self.device = rtcore.EmbreeDevice()
        self.scene = self._scene()
        self._prepared: Dict[int, dict] = {}
        self._pool = None

    def _scene(self):
        from embreex.mesh_construction import TriangleMesh
        from embreex.rtcore_scene import EmbreeScene
        scene = EmbreeScene(self.device)
        TriangleMesh(scene, self.vertices, self.triangles)
        one = np.zeros((1, 3), np.float32)
        scene.run(one, one + 1.0)         # run commits the scene: builds the BVH
        return scene

    def build(self) -> float:
        t0 = time.perf_counter()
        self._scene()
        return time.perf_counter() - t0

    def _float32(self, rays: dict) -> dict:
        key = id(rays)
        if key not in self._prepared:        # converted once per ray set, outside the timing
            t0 = np.asarray(rays["t_min"], np.float64)
            o = rays["origins"] + t0[:, None] * rays["directions"] if np.any(t0) else rays["origins"]
            tmax = np.asarray(rays["t_max"], np.float64) - t0
            self._prepared[key] = {"o": np.ascontiguousarray(o, np.float32),
                                   "d": np.ascontiguousarray(rays["directions"], np.float32),
                                   "tmax": np.ascontiguousarray(np.minimum(tmax, 1e37), np.float32),
                                   "t0": t0}
        return self._prepared[key]

    def _run(self, kind, o, d, tmax):
        if kind == "shadow":
            return self.scene.run(o, d, tmax, query="OCCLUDED") != -1
        out = self.scene.run(o, d, tmax, query="INTERSECT", output=True)
        ids = out["primID"].astype(np.int64)
        ids[out["geomID"] == -1] = -1
        return ids, out["tfar"]

    def trace(self, kind: str, rays: dict, threads: int = 1):
        r = self._float32(rays)
        tmax = r["tmax"].copy()                   # run writes t into it
        R = len(tmax)
        bands = min(4 * threads, -(-R // 1024))   # bands of at least 1024 rays, as softpipe's (grain=1024)
        if threads <= 1 or bands <= 1:
            out = self._run(kind, r["o"], r["d"], tmax)
        else:
            if self._pool is None or self._pool._max_workers != threads:
                if self._pool is not None:
                    self._pool.shutdown()
                self._pool = ThreadPoolExecutor(max_workers=threads)
            bounds = np.linspace(0, R, bands + 1).astype(np.int64)
            parts = list(self._pool.map(lambda k: self._run(kind, r["o"][bounds[k]:bounds[k + 1]],
                                                             r["d"][bounds[k]:bounds[k + 1]],
                                                             tmax[bounds[k]:bounds[k + 1]]),
                                        range(len(bounds) - 1)))
            if kind == "shadow":
                return np.concatenate(parts)
            out = (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))
        if kind == "shadow":
            return out
        ids, tfar = out
        return ids, np.where(ids >= 0, tfar.astype(np.float64) + r["t0"], np.inf)

    def close(self):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None


def agreement(kind: str, ours, theirs, diagonal: float = 1.0) -> dict:
    """How far softpipe's answers and Embree's differ (see the module docstring)."""
    if kind == "shadow":
        differ = ours != theirs
        return {"rays": int(len(ours)), "answer_differs": float(differ.mean()) if len(ours) else 0.0,
                "occluded_softpipe": float(ours.mean()) if len(ours) else 0.0,
                "occluded_embree": float(theirs.mean()) if len(ours) else 0.0}
    (ids, t), (eids, et) = ours, theirs
    same = (ids == eids) & (ids >= 0)
    diff = np.abs(t[same] - et[same])
    rel = diff / np.maximum(np.abs(t[same]), 1e-30)
    return {"rays": int(len(ids)), "hits_softpipe": int((ids >= 0).sum()), "hits_embree": int((eids >= 0).sum()),
            "triangle_differs": float((ids != eids).mean()) if len(ids) else 0.0,
            "hit_vs_miss": int(((ids >= 0) != (eids >= 0)).sum()),
            "t_rel_diff_max": float(rel.max()) if len(rel) else 0.0,
            "t_rel_diff_median": float(np.median(rel)) if len(rel) else 0.0,
            "t_diff_max_over_diagonal": float(diff.max()) / diagonal if len(diff) else 0.0}


# ------------------------------------------------------------------------------ timing

def _median(xs):
    return float(statistics.median(xs)) if xs else None


def _quartiles(xs):
    if len(xs) < 2:
        return [float(xs[0])] * 2 if xs else None
    q = statistics.quantiles(xs, n=4, method="inclusive")
    return [float(q[0]), float(q[2])]


def _load() -> Optional[List[float]]:
    return [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else None


def _timed(fn):
    """(wall seconds, process CPU seconds, fn's result)."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def run_model(model: str, size: int = DEFAULT_SIZE, threads: Sequence[int] = DEFAULT_THREADS,
              repeats: int = DEFAULT_REPEATS, embree: bool = True, log: Callable[[str], None] = print) -> dict:
    """Build times, rays/s per kind and thread count (and Embree's, alternated), agreement, for one model."""
    mesh = load_model(model)
    vertices = np.ascontiguousarray(mesh.positions, np.float64)
    triangles = np.ascontiguousarray(np.asarray(mesh.indices).reshape(-1, 3), np.int64)
    scene = Scene.from_model(mesh, width=size, height=size)
    camera = scene.view_camera()
    result = {"model": model, "triangles": int(len(triangles)), "size": [size, size], "load_before": _load()}
    numba.set_num_threads(max(threads))
    sp = SoftpipeSide(vertices, triangles)
    result["bvh"] = repr(sp.bvh)
    peer = EmbreeSide(vertices, triangles) if embree else None

    o, d, far = primary_rays(camera, size, size)
    rays = {"primary": {"origins": o, "directions": d, "t_min": np.zeros(len(o)), "t_max": far}}
    ids, t = sp.trace("primary", rays["primary"])
    light, diagonal = _light(camera, vertices)
    eps = EPSILON_REL * diagonal
    sec = secondary_rays(vertices, triangles, o, d, ids, t, light)
    n = len(sec["points"])
    rays["shadow"] = {"origins": sec["points"], "directions": sec["shadow_dir"], "t_min": np.full(n, eps),
                      "t_max": sec["shadow_tmax"]}
    rays["secondary"] = {"origins": sec["points"], "directions": sec["mirror_dir"], "t_min": np.full(n, eps),
                         "t_max": np.full(n, np.inf)}
    rays["shadow-closest"] = rays["shadow"]          # the same rays (and Embree's float32 copy of them)
    result["rays"] = {k: int(len(v["origins"])) for k, v in rays.items()}
    result["epsilon"] = eps
    result["light"] = [float(x) for x in light]

    # warm-up: one untimed build and one untimed run of every query on every side
    sp.build()
    for kind in ALL_KINDS:
        sp.trace(kind, rays[kind])
        if peer is not None:
            peer.build()
            peer.trace(kind, rays[kind])

    sides = [("softpipe", n_) for n_ in threads] + ([("embree", n_) for n_ in threads] if peer is not None else [])
    build = {s: [] for s in sides if s[1] == max(threads)}
    secs = {(kind, s): [] for kind in ALL_KINDS for s in sides}
    cpu = {(kind, s): [] for kind in ALL_KINDS for s in sides}
    last = {}
    for rnd in range(repeats):
        order = sides if rnd % 2 == 0 else sides[::-1]
        # build: softpipe's is serial (threads do not matter), Embree's uses its own pool
        for name, n_ in order:
            if (name, n_) in build:
                build[(name, n_)].append(sp.build() if name == "softpipe" else peer.build())
        for kind in ALL_KINDS:
            for name, n_ in order:
                if name == "softpipe":
                    numba.set_num_threads(n_)
                    fn = lambda: sp.trace(kind, rays[kind])           # noqa: E731
                else:
                    fn = lambda: peer.trace(kind, rays[kind], n_)     # noqa: E731
                dt, dc, out = _timed(fn)
                secs[(kind, (name, n_))].append(dt)
                cpu[(kind, (name, n_))].append(dc)
                if rnd == repeats - 1:
                    last[(kind, name)] = out
    numba.set_num_threads(max(threads))

    result["build_ms"] = {name: 1e3 * _median(v) for (name, _), v in build.items()}
    result["build_ms_all"] = {name: [1e3 * x for x in v] for (name, _), v in build.items()}
    table = {}
    for kind in ALL_KINDS:
        R = result["rays"][kind]
        row = {"rays": R}
        for name, n_ in sides:
            v = secs[(kind, (name, n_))]
            key = f"{name}_{n_}t"
            row[key + "_mrays_s"] = R / _median(v) / 1e6
            q = _quartiles(v)
            row[key + "_mrays_s_iqr"] = [R / q[1] / 1e6, R / q[0] / 1e6]
            row[key + "_seconds"] = v
            # CPU seconds of the process over wall seconds: ~n when the n threads had their cores, less
            # when other jobs took them; rays per CPU-second is the figure the load disturbs least
            c = cpu[(kind, (name, n_))]
            row[key + "_cpu_per_wall"] = _median([a / b for a, b in zip(c, v)])
            row[key + "_mrays_per_cpu_s"] = R / _median(c) / 1e6 if _median(c) > 0 else None
        if peer is not None:
            for n_ in threads:
                s, e = secs[(kind, ("softpipe", n_))], secs[(kind, ("embree", n_))]
                paired = [b / a for a, b in zip(s, e)]          # softpipe rays/s ÷ Embree rays/s, per round
                row[f"ratio_{n_}t"] = _median(e) / _median(s)
                row[f"ratio_{n_}t_paired_median"] = _median(paired)
                row[f"ratio_{n_}t_paired_range"] = [min(paired), max(paired)]
            row["agreement"] = agreement(kind, last[(kind, "softpipe")], last[(kind, "embree")], diagonal)
        table[kind] = row
    result["kinds"] = table
    result["load_after"] = _load()
    if peer is not None:
        peer.close()
    log(f"  {model}: done, load average {result['load_before']} -> {result['load_after']}")
    return result


def run(models: Sequence[str] = DEFAULT_MODELS, size: int = DEFAULT_SIZE, threads: Sequence[int] = DEFAULT_THREADS,
        repeats: int = DEFAULT_REPEATS, embree: bool = True, install: bool = False,
        log: Callable[[str], None] = print) -> dict:
    """Every model; the report (what ``--json`` writes). ``embree_skipped`` says why Embree did not run."""
    skipped = None
    if embree:
        skipped = install_embree() if install else embree_status()
        if skipped:
            log(f"SKIPPED Embree: {skipped}")
    else:
        skipped = "--no-embree"
    report = {"date": datetime.datetime.now().isoformat(timespec="seconds"), "machine": machine_info(),
              "source": source_state(), "size": size, "threads": list(threads), "repeats": repeats,
              "embree_skipped": skipped, "numba_threads_max": numba.config.NUMBA_NUM_THREADS, "models": []}
    if not skipped:
        import importlib.metadata as md
        try:
            report["embreex_version"] = md.version("embreex")
        except md.PackageNotFoundError:
            report["embreex_version"] = None
    before = numba.get_num_threads()
    try:
        for model in models:
            log(f"{model} ...")
            report["models"].append(run_model(model, size=size, threads=threads, repeats=repeats,
                                              embree=not skipped, log=log))
    finally:
        numba.set_num_threads(before)              # as the caller had it
    report["load_at_end"] = _load()
    return report


def format_table(report: dict) -> str:
    """The report as Markdown tables: builds, then rays/s per kind (and the ratios and agreement with Embree)."""
    threads = report["threads"]
    emb = not report["embree_skipped"]
    lines = ["| model | triangles | softpipe build ms |" + (" Embree build ms | softpipe/Embree (time) |" if emb else ""),
             "|---|---:|---:|" + ("---:|---:|" if emb else "")]
    for m in report["models"]:
        b = m["build_ms"]
        row = f"| {m['model']} | {m['triangles']:,} | {b['softpipe']:.1f} |"
        if emb:
            row += f" {b['embree']:.1f} | {b['softpipe'] / b['embree']:.2f}× |"
        lines.append(row)
    lines.append("")
    head = "| model | kind | rays | " + " | ".join(f"softpipe {n}t M/s" for n in threads)
    rule = "|---|---|---:|" + "---:|" * len(threads)
    if emb:
        head += " | " + " | ".join(f"Embree {n}t M/s" for n in threads) + " | " + \
                " | ".join(f"sp/Embree {n}t" for n in threads) + \
                 " | triangle (or answer) differs | t diff max: relative (over diagonal)"
        rule += "---:|" * (2 * len(threads)) + "---:|---:|"
    lines += [head + " |", rule]
    for m in report["models"]:
        for kind in ALL_KINDS:
            r = m["kinds"][kind]
            row = f"| {m['model']} | {kind} | {r['rays']:,} | " + \
                  " | ".join(f"{r[f'softpipe_{n}t_mrays_s']:.2f}" for n in threads)
            if emb:
                a = r["agreement"]
                differs = a["answer_differs"] if kind == "shadow" else a["triangle_differs"]
                row += " | " + " | ".join(f"{r[f'embree_{n}t_mrays_s']:.2f}" for n in threads) + " | " + " | ".join(
                    f"{r[f'ratio_{n}t']:.2f} (paired {r[f'ratio_{n}t_paired_median']:.2f})" for n in threads)
                row += f" | {100 * differs:.4f} % | " + ("–" if kind == "shadow" else
                                                        f"{a['t_rel_diff_max']:.1e} ({a['t_diff_max_over_diagonal']:.1e})")
            lines.append(row + " |")
    sides = [f"softpipe_{n}t" for n in threads] + ([f"embree_{n}t" for n in threads] if emb else [])
    names = [f"sp {n}t" for n in threads] + ([f"Embree {n}t" for n in threads] if emb else [])
    lines += ["", "| model | kind | " + " | ".join(f"{n} CPU/wall" for n in names) + " | " +
              " | ".join(f"{n} M rays/CPU-s" for n in names) + " |",
              "|---|---|" + "---:|" * (2 * len(sides))]
    for m in report["models"]:
        for kind in ALL_KINDS:
            r = m["kinds"][kind]
            per_cpu = [r[f"{s_}_mrays_per_cpu_s"] for s_ in sides]
            lines.append(f"| {m['model']} | {kind} | " + " | ".join(f"{r[f'{s_}_cpu_per_wall']:.2f}" for s_ in sides)
                         + " | " + " | ".join("–" if x is None else f"{x:.2f}" for x in per_cpu) + " |")
    return "\n".join(lines)


def _threads(text: str) -> List[int]:
    try:
        out = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--threads takes numbers separated by commas, got {text!r}") from None
    if not out or any(not 1 <= n <= numba.config.NUMBA_NUM_THREADS for n in out):
        raise argparse.ArgumentTypeError(
            f"--threads: each between 1 and {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS), got {text!r}")
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.rays", description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="*", metavar="MODEL", help="bundled models (default: bunny armadillo)")
    parser.add_argument("--threads", type=_threads, default=list(DEFAULT_THREADS),
                        help="numba thread counts, e.g. 1,2 (default 1,2)")
    parser.add_argument("--repeats", type=int, default=DEFAULT_REPEATS,
                        help=f"alternated rounds per model (default {DEFAULT_REPEATS})")
    parser.add_argument("--size", type=int, default=DEFAULT_SIZE, help=f"image side in pixels (default {DEFAULT_SIZE})")
    parser.add_argument("--embree", action=argparse.BooleanOptionalAction, default=True,
                        help="also trace with Embree (embreex), alternated (default: on; skipped if missing)")
    parser.add_argument("--install", action="store_true", help="first pip install embreex if it is missing")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON,
                        help=f"where the results go (default {DEFAULT_JSON.relative_to(REPO_ROOT)})")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    if args.size < 1:
        parser.error("--size must be at least 1")
    keep_freed_memory()     # a program of softpipe's own, as the softpipe command is (softpipe/core/runtime.py)
    report = run(args.models or DEFAULT_MODELS, size=args.size, threads=args.threads, repeats=args.repeats,
                 embree=args.embree, install=args.install)
    print()
    print(format_table(report))
    if report["embree_skipped"]:
        print(f"\nEmbree: skipped ({report['embree_skipped']})")
    else:
        print("\nM/s = million rays per second (median of the rounds); Embree at n threads = embreex's run on n "
              "Python threads over bands of the rays; sp/Embree n t = softpipe's rays/s over Embree's at n threads "
              "(medians; paired: median of the per-round ratios). shadow-closest = the shadow rays as closest-hit "
              "queries (any hit against closest hit on the same rays).")
    print(f"load average: {report['machine'].get('load_average_at_start')} at start, {report['load_at_end']} at end")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1))
    print(f"results: {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
