"""The benchmark harness: ``python -m benchmarks.run [SCENE ...] [options]`` (``make bench``).

For each scene (all of :data:`benchmarks.scenes.SCENES` by default) it renders
one cold frame, whose time includes numba's compilation and is reported on its
own, then ``--frames`` warm frames (7 by default), and reports:

* median, min and max milliseconds of the warm frames;
* triangles/s (triangles submitted per frame / median) and shaded pixels/s
  (fragments shaded per frame / median), and the covered samples per frame;
* the median time of each pipeline stage, from :attr:`DrawCall.timings`, summed
  over the scene's draws (``other`` is the rest of the frame: clearing the
  framebuffer and building the DrawCalls; ``prepare`` is the scene's per-frame
  preparation, e.g. drawing shadow maps, when it has one);
* for a scene with a ``prepare`` (:attr:`Scene.prepare`), the median of each part
  of the frame: the parts ``prepare`` names (each shadow map), the rest of
  ``prepare``, and ``lit pass`` (the draws);
* peak memory (resident set) of the process while the scene ran;
* the numba thread count it ran with, and CPU time / wall time (how much of
  the machine the frames actually got).

After the scenes, each pair of scenes an issue's target compares (:data:`RATIO_TARGETS`, such as
``bunny-outputs ÷ bunny``) is drawn again, in turns of a few frames each (:func:`paired_ratio`), and
the target is judged by the median of the pairs' ratios, which a machine drifting during the run
does not move as it moves two medians measured one after the other.

It prints two aligned tables and writes everything as JSON (``out/bench.json``
by default; ``out/`` is git-ignored). See ``benchmarks/README.md`` for what each
column means and for measured figures.

Counting does not touch the timed frames: after them, one more, untimed frame
runs with three of ``softpipe.pipeline.draw``'s functions wrapped: ``assemble`` (its
triangles' covered samples, by ``count_fragments``: "covered"),
``run_fragment_stage`` on the reference path (its shader invocations) and
``shade_visible`` on the fast path (the samples its visibility pass left to
shade): "shaded px".

BLAS is kept to one thread (``OPENBLAS_NUM_THREADS=1``, ``MKL_NUM_THREADS=1``,
set here before numpy is imported, unless already set), as NUMBA-NOTES.md asks;
the pipeline's own threads are numba's, set with ``--threads`` through
:func:`numba.set_num_threads`.
"""
from __future__ import annotations

import os

# Before numpy is imported (benchmarks/__init__.py imports nothing): OpenBLAS
# threads compete with numba's for the two cores (NUMBA-NOTES.md). Not
# OMP_NUM_THREADS: numba's own threads may be OpenMP's.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import datetime  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Callable, Dict, List, Optional, Sequence  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

import softpipe.pipeline.draw as _pipeline  # noqa: E402
from softpipe.core.runtime import keep_freed_memory, release_memory  # noqa: E402
from softpipe.pipeline.draw import DrawCall  # noqa: E402
from softpipe.pipeline.framebuffer import Framebuffer  # noqa: E402
from softpipe.pipeline.raster import count_fragments  # noqa: E402

from .scenes import REPO_ROOT, SCENES, Scene, build_scene  # noqa: E402

__all__ = ["run_scene", "run", "main", "render_frame", "count_fragments_of", "TARGETS_MS", "STAGES", "ROW_FIELDS"]

#: DrawCall.timings keys, in pipeline order, and the names the issue gives them.
STAGES = ("vertex", "assembly", "setup", "raster", "fragment", "output")
STAGE_TITLES = {"vertex": "vertex", "assembly": "assembly+clip", "setup": "setup+bin", "raster": "raster",
                "fragment": "shading", "output": "merge", "other": "other", "prepare": "prepare",
                "outputs": "outputs"}
#: The part of a frame that runs the scene's draws (the parts table, for scenes with a ``prepare``).
LIT_PASS = "lit pass"

#: The issue's targets (median of warm frames, 2 threads, 2 cores), in ms.
TARGETS_MS = {"sphere200k": 25.0, "sphere200k-color": 20.0, "bunny": 12.0, "fill": 200.0, "fill-b2f": 450.0,
              "tiny": 150.0}

#: The issues' targets that compare scenes of one run: (issue, scene, baseline scene, at most this ratio of
#: their medians). The scene's frame costs at most (ratio − 1) × the baseline's more.
RATIO_TARGETS = (
    (31, "bunny-outputs", "bunny", 1.3),            # five outputs cost at most 30 % over color alone
    (35, "bunny-shadows", "bunny-plane", 1.6),      # shadows add at most 60 % to bunny-plane
)
#: Issue 35: peak memory on every scene (VmHWM), in MB; and a whole frame on 2 threads at least this many
#: times as fast as on 1 (``--scaling``).
PEAK_MEMORY_TARGET_MB = 1024.0
SCALING_TARGET = 1.8

DEFAULT_FRAMES = 7
#: Frames per turn when two scenes are drawn in turns (:func:`paired_ratio`); the first is not counted.
PAIR_BLOCK = 4
DEFAULT_BUDGET_S = 30.0
DEFAULT_JSON = REPO_ROOT / "out" / "bench.json"

#: The fields of every result row (the JSON's ``scenes`` entries).
ROW_FIELDS = ("scene", "description", "shading", "path", "width", "height", "scale", "threads",
              "triangles", "covered", "fragments", "pixels_drawn",
              "first_ms", "median_ms", "min_ms", "max_ms", "frames_ms", "warm_frames", "frames_requested",
              "triangles_per_s", "shaded_pixels_per_s", "covered_per_s", "cpu_per_wall",
              "stages_ms", "first_stages_ms", "parts_ms", "first_parts_ms",
              "peak_rss_mb", "start_rss_mb", "memory_method", "build_s",
              "target_ms", "vs_target", "one_thread_ms", "scaling", "notes")


# --------------------------------------------------------------------------
# Memory: the resident set's high-water mark, reset per scene
# --------------------------------------------------------------------------

def _status_kb(field: str) -> Optional[int]:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def _reset_peak_rss() -> bool:
    """Reset VmHWM to the current RSS (Linux ≥ 4.0: ``echo 5 > /proc/self/clear_refs``)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _peak_rss_mb(reset_worked: bool):
    if reset_worked:
        hwm = _status_kb("VmHWM")
        if hwm is not None:
            return hwm / 1024.0, "VmHWM (peak RSS) of this process, reset before the scene's first frame"
    # ru_maxrss is in KiB on Linux, bytes on macOS; it cannot be reset.
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    peak = peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0
    return peak, "ru_maxrss: peak RSS of the whole process so far (could not reset it per scene)"


def _rss_mb() -> Optional[float]:
    kb = _status_kb("VmRSS")
    return None if kb is None else kb / 1024.0


# --------------------------------------------------------------------------
# One frame, and the untimed count
# --------------------------------------------------------------------------

def render_frame(scene: Scene, fb: Framebuffer, paths: Optional[list] = None, parts: Optional[dict] = None,
                 prepare: bool = True) -> tuple:
    """Clear ``fb``, run the scene's ``prepare`` (if any, and ``prepare``) and every draw of ``scene``:
    (seconds, {stage: seconds} summed over draws, plus ``prepare``).

    ``paths``, if given, gets each draw's path ("fast" or "reference") appended.
    ``parts``, if given, gets the parts of the frame of a scene with a ``prepare``:
    the parts it returned (each shadow map's seconds), ``prepare (rest)`` (the rest
    of its time) and ``lit pass`` (the draws).
    """
    stages: Dict[str, float] = {}
    start = time.perf_counter()
    fb.clear(scene.clear_color)
    if prepare and scene.prepare is not None:
        t0 = time.perf_counter()
        named = dict(scene.prepare() or {})
        stages["prepare"] = time.perf_counter() - t0
        if parts is not None:
            parts.update(named)
            parts["prepare (rest)"] = max(0.0, stages["prepare"] - sum(named.values()))
    draws_start = time.perf_counter()
    for kwargs in scene.draws:
        call = DrawCall(fb, **kwargs)
        call.run()
        for name, seconds in call.timings.items():
            stages[name] = stages.get(name, 0.0) + seconds
        if paths is not None:
            uses_fast = getattr(call, "uses_fast_path", None)
            paths.append("reference" if uses_fast is None else "fast" if uses_fast() else "reference")
    finish = getattr(scene, "finish", None)
    if finish is not None:
        t0 = time.perf_counter()
        finish(fb)
        stages["outputs"] = time.perf_counter() - t0
    end = time.perf_counter()
    if parts is not None and scene.prepare is not None and prepare:
        parts[LIT_PASS] = end - draws_start
    total = end - start
    stages["other"] = max(0.0, total - sum(stages.values()))
    return total, stages


@contextlib.contextmanager
def _counting(fb: Framebuffer):
    """Wrap the pipeline's assembly and shading entry points to count what they handle.

    Yields a dict: ``covered`` (samples the assembled triangles cover, by the
    rasterizer's counting pass), ``shaded`` (fragments handed to the fragment
    shader) and ``calls`` (how many times a shading function ran). The
    functions are put back on exit.
    """
    counter = {"covered": 0, "shaded": 0, "calls": 0}

    def assembly(f):
        def counted(*args, **kwargs):
            prims = f(*args, **kwargs)
            counter["covered"] += int(count_fragments(prims, fb.width, fb.height, fb.pattern).sum())
            return prims
        return counted

    def reference(f):
        def counted(frags, *args, **kwargs):
            out = f(frags, *args, **kwargs)
            n = getattr(out, "invocations", -1)
            counter["shaded"] += n if isinstance(n, int) and n >= 0 else len(frags)
            counter["calls"] += 1
            return out
        return counted

    def fast(f):
        def counted(prims, visibility, *args, **kwargs):
            vis = np.asarray(getattr(visibility, "vis", visibility))     # a Visibility (or, before it, the array)
            shading = kwargs.get("shading", args[3] if len(args) > 3 else "sample")
            if shading == "center":     # multisampling: one invocation per pixel and triangle there
                ordered = np.sort(vis, axis=0)
                first = np.ones((1,) + ordered.shape[1:], bool)
                distinct = np.concatenate([first, ordered[1:] != ordered[:-1]], axis=0) & (ordered >= 0)
                counter["shaded"] += int(np.count_nonzero(distinct))
            else:
                counter["shaded"] += int(np.count_nonzero(vis >= 0))
            counter["calls"] += 1
            return f(prims, visibility, *args, **kwargs)
        return counted

    saved = {}
    for name, wrap in (("assemble", assembly), ("run_fragment_stage", reference), ("shade_visible", fast),
                       ("shade_primitives", fast)):      # points and lines on the fast path
        if hasattr(_pipeline, name):
            saved[name] = getattr(_pipeline, name)
            setattr(_pipeline, name, wrap(saved[name]))
    try:
        yield counter
    finally:
        for name, f in saved.items():
            setattr(_pipeline, name, f)


def count_fragments_of(scene: Scene, fb: Framebuffer) -> tuple:
    """(covered, shaded) fragments of one frame of ``scene``, from an untimed frame with counting wrappers.

    ``shaded`` is None if the pipeline ran none of the wrapped shading
    functions (they were renamed): then the harness cannot count, and says so.
    """
    if scene.prepare is not None:       # its draws (shadow maps) are not the frame's, so not counted
        scene.prepare()
    with _counting(fb) as counter:
        render_frame(scene, fb, prepare=False)
    shaded = None if counter["calls"] == 0 and scene.draws else counter["shaded"]
    return counter["covered"], shaded


# --------------------------------------------------------------------------
# One scene
# --------------------------------------------------------------------------

def _median_stages(frames: List[Dict[str, float]]) -> Dict[str, float]:
    names = [s for s in STAGES if any(s in f for f in frames)]
    names += sorted({k for f in frames for k in f} - set(names) - {"other"}) + ["other"]
    return {n: 1e3 * statistics.median(f.get(n, 0.0) for f in frames) for n in names}


def _median_parts(frames: List[Dict[str, float]]) -> Dict[str, float]:
    """Per part, the median ms over frames, in the order the parts came (``lit pass`` last)."""
    names: List[str] = []
    for f in frames:
        names += [n for n in f if n not in names]
    names = [n for n in names if n != LIT_PASS] + ([LIT_PASS] if LIT_PASS in names else [])
    return {n: 1e3 * statistics.median(f.get(n, 0.0) for f in frames) for n in names}


def framebuffer_for(scene: Scene) -> Framebuffer:
    """The framebuffer a scene draws into: its size, its sample pattern, a visibility record if it keeps one."""
    record = bool(getattr(scene, "record", False))
    if scene.pattern:
        return Framebuffer(scene.width, scene.height, pattern=scene.pattern, record=record)
    return Framebuffer(scene.width, scene.height, record=record)


def paired_ratio(scene: Scene, baseline: Scene, pairs: int = DEFAULT_FRAMES, block: int = PAIR_BLOCK) -> dict:
    """``scene`` and ``baseline`` drawn in turns of ``block`` frames, each into its own framebuffer, the
    order turned every pair of turns (A B, then B A): each pair's ratio (the median frame of the
    scene's turn ÷ that of the baseline's), their median and quartiles. A turn's first frame is not
    counted: it starts with the other scene's data in the cache, where a renderer's frames follow
    frames of the same scene.

    The targets that compare two scenes (:data:`RATIO_TARGETS`) read this rather than the ratio of the
    scenes' medians, which were measured one after the other: a machine whose speed drifts during a
    run moves both turns of a pair alike, but the two medians by the whole drift between them. (On
    the machine of benchmarks/README.md's "Outputs, round 6", one tree's ratio of medians read 1.26 in
    one run and 1.39 in another.)

    Returns
    -------
    dict with ``scene``, ``baseline``, ``pairs``, ``block``, ``ratio`` (the median), ``low`` and ``high``
    (the quartiles) and ``ratios`` (each pair's, in order).
    """
    if pairs < 1 or block < 2:
        raise ValueError(f"pairs must be at least 1 and block at least 2, got {pairs} and {block}")
    both = (scene, baseline)
    buffers = [framebuffer_for(s) for s in both]
    for s, fb in zip(both, buffers):
        render_frame(s, fb)                     # untimed: compiled and warm
    ratios = []
    for i in range(pairs):
        turn = [0.0, 0.0]
        for k in ((0, 1) if i % 2 == 0 else (1, 0)):
            frames = [render_frame(both[k], buffers[k])[0] for _ in range(block)]
            turn[k] = statistics.median(frames[1:])
        ratios.append(turn[0] / turn[1])
    low, median, high = (float(q) for q in np.percentile(ratios, [25, 50, 75]))
    return {"scene": scene.name, "baseline": baseline.name, "pairs": pairs, "block": block, "ratio": median,
            "low": low, "high": high, "ratios": ratios}


def run_scene(scene, frames: int = DEFAULT_FRAMES, scale: float = 1.0, budget: Optional[float] = DEFAULT_BUDGET_S,
              keep_image: bool = False, log: Callable[[str], None] = print, scaling: bool = False) -> dict:
    """Benchmark one scene (a name or a :class:`Scene`); returns its result row (see :data:`ROW_FIELDS`).

    ``budget`` (seconds, None = no limit) caps the time spent on warm frames:
    when the next frame would overrun it, the scene stops early (after at
    least one warm frame) and says so in ``notes``. With ``keep_image`` the
    row also has ``image``, the last frame as uint8 [H, W, 4] (not JSON).
    With ``scaling`` as many frames are then drawn on 1 thread (after one
    untimed): the row's ``one_thread_ms`` is their median and ``scaling`` the
    ratio of the medians, 1 thread ÷ the run's threads (issue 35's target: ≥ 1.8
    on 2). A block after the others, not frames alternated one by one: switching
    the thread count at every frame slowed the frames on 2 threads by up to a
    third (aa-grid4 20.3 ms against 14.8), and the scene's seconds drift little.
    """
    if frames < 1:
        raise ValueError(f"frames must be at least 1, got {frames}")
    t0 = time.perf_counter()
    if isinstance(scene, str):
        scene = build_scene(scene, scale)
    build_s = time.perf_counter() - t0
    fb = framebuffer_for(scene)
    notes = list(scene.notes)
    gc.collect()
    release_memory()        # what earlier scenes left for reuse (softpipe.core.runtime) is not this scene's
    start_rss = _rss_mb()
    reset = _reset_peak_rss()

    paths: List[str] = []
    first_parts: Dict[str, float] = {}
    first_s, first_stages = render_frame(scene, fb, paths, first_parts)
    log(f"  {scene.name}: first frame {first_s * 1e3:.0f} ms (includes compiling); warm frames ...")
    times, stage_frames, part_frames, one_thread = [], [], [], []
    warm_start = time.perf_counter()
    wall = cpu = 0.0                    # of the frames on the run's threads (cpu: every thread of the process)
    while len(times) < frames:
        parts: Dict[str, float] = {}
        wall_0, cpu_0 = time.perf_counter(), time.process_time()
        seconds, stages = render_frame(scene, fb, parts=parts)
        wall, cpu = wall + time.perf_counter() - wall_0, cpu + time.process_time() - cpu_0
        times.append(seconds)
        stage_frames.append(stages)
        part_frames.append(parts)
        spent = time.perf_counter() - warm_start
        if budget and len(times) < frames and spent + seconds > budget:
            notes.append(f"{scene.name}: only {len(times)} warm frame(s) of {frames}: a frame takes about "
                         f"{seconds:.1f} s and the warm-frame budget is {budget:.0f} s per scene (--budget)")
            break
    peak_rss, memory_method = _peak_rss_mb(reset)
    if scaling:     # (after the peak is read: what one thread's bands keep is not the run's threads' frame)
        threads_now = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            render_frame(scene, fb)     # (untimed: the first frame on one thread)
            one_thread = [render_frame(scene, fb)[0] for _ in times]
        finally:
            numba.set_num_threads(threads_now)

    covered, fragments = count_fragments_of(scene, fb)
    if fragments is None:
        notes.append(f"{scene.name}: could not count shaded fragments (softpipe.pipeline.draw has none of "
                     "run_fragment_stage, shade_visible, shade_primitives any more); shaded px/s left out")
    image = fb.to_uint8()
    clear = np.rint(np.clip(np.asarray(scene.clear_color, np.float64), 0, 1) * 255).astype(np.uint8)
    pixels_drawn = int(np.any(image != clear, axis=-1).sum())

    median = statistics.median(times)
    target = TARGETS_MS.get(scene.name) if scene.scale == 1.0 else None
    row = {
        "scene": scene.name,
        "description": scene.description,
        "shading": scene.shading,
        "path": "/".join(sorted(set(paths))),
        "width": scene.width,
        "height": scene.height,
        "scale": scene.scale,
        "triangles": scene.triangles,
        "fragments": fragments,
        "covered": covered,
        "pixels_drawn": pixels_drawn,
        "threads": numba.get_num_threads(),
        "first_ms": first_s * 1e3,
        "median_ms": median * 1e3,
        "min_ms": min(times) * 1e3,
        "max_ms": max(times) * 1e3,
        "frames_ms": [t * 1e3 for t in times],
        "warm_frames": len(times),
        "frames_requested": frames,
        "triangles_per_s": scene.triangles / median,
        "shaded_pixels_per_s": None if fragments is None else fragments / median,
        "covered_per_s": covered / median,
        "cpu_per_wall": cpu / wall if wall > 0 else None,
        "stages_ms": _median_stages(stage_frames),
        "first_stages_ms": {k: v * 1e3 for k, v in first_stages.items()},
        "parts_ms": _median_parts(part_frames),
        "first_parts_ms": {k: v * 1e3 for k, v in first_parts.items()},
        "peak_rss_mb": peak_rss,
        "start_rss_mb": start_rss,
        "memory_method": memory_method,
        "build_s": build_s,
        "target_ms": target,
        "vs_target": None if target is None else median * 1e3 / target,
        "one_thread_ms": statistics.median(one_thread) * 1e3 if one_thread else None,
        "scaling": statistics.median(one_thread) / median if one_thread else None,
        "notes": notes,
    }
    if keep_image:
        row["image"] = image
    return row


# --------------------------------------------------------------------------
# Reporting
# --------------------------------------------------------------------------

def _ms(x: Optional[float]) -> str:
    if x is None:
        return "-"
    return f"{x:.0f}" if x >= 100 else f"{x:.1f}" if x >= 10 else f"{x:.2f}"


def _rate(x: Optional[float]) -> str:
    """A per-second rate with three significant digits and a unit: 812 k, 12.3 M, 1.05 G."""
    if x is None:
        return "-"
    for div, unit in ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, "")):
        if x >= div or unit == "":
            v = x / div
            return f"{v:.0f} {unit}" if v >= 100 else f"{v:.1f} {unit}" if v >= 10 else f"{v:.2f} {unit}"
    return str(x)


def _table(header: Sequence[str], rows: List[Sequence[str]], left: int = 1) -> str:
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows)]
    lines = []
    for k, r in enumerate([header, *rows]):
        cells = [str(c).ljust(w) if i < left else str(c).rjust(w) for i, (c, w) in enumerate(zip(r, widths))]
        lines.append("  ".join(cells).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def format_tables(rows: List[dict]) -> str:
    """The two tables: timings and rates, then the per-stage medians."""
    main_rows = []
    for r in rows:
        target = "-" if r["target_ms"] is None else f"{r['target_ms']:.0f}"
        vs = "-" if r["vs_target"] is None else ("met" if r["vs_target"] <= 1.0 else f"{r['vs_target']:.1f}x")
        main_rows.append([r["scene"], r["path"], f"{r['width']}x{r['height']}", f"{r['triangles']:,}", f"{r['covered']:,}", "-" if r["fragments"] is None else f"{r['fragments']:,}",
                          _ms(r["first_ms"]), _ms(r["median_ms"]), _ms(r["min_ms"]), _ms(r["max_ms"]),
                          f"{r['warm_frames']}", _rate(r["triangles_per_s"]), _rate(r["shaded_pixels_per_s"]),
                          f"{r['peak_rss_mb']:.0f}", f"{r['threads']}",
                          "-" if r["cpu_per_wall"] is None else f"{r['cpu_per_wall']:.2f}", target, vs])
    t1 = _table(["scene", "path", "size", "triangles", "covered", "shaded px", "first ms", "median ms", "min ms",
                 "max ms", "n", "tris/s", "shaded px/s", "peak MB", "thr", "cpu/wall", "target ms", "vs target"],
                main_rows)
    names: List[str] = []
    for r in rows:
        names += [n for n in r["stages_ms"] if n not in names]
    names = [n for n in STAGES if n in names] + [n for n in names if n not in STAGES and n != "other"] + ["other"]
    stage_rows = []
    for r in rows:
        st = r["stages_ms"]
        total = sum(st.values()) or 1.0
        biggest = max(st, key=st.get)
        stage_rows.append([r["scene"], *(_ms(st.get(n)) if n in st else "-" for n in names),
                           f"{STAGE_TITLES.get(biggest, biggest)} {100 * st[biggest] / total:.0f}%"])
    t2 = _table(["median ms by stage", *(STAGE_TITLES.get(n, n) for n in names), "largest"], stage_rows)
    tables = [t1, t2]
    scaled = [r for r in rows if r.get("scaling") is not None]
    if scaled:
        tables.append(_table(["threads", "1 thread ms", "threads", "ms", "1 ÷ threads"],
                             [[r["scene"], _ms(r["one_thread_ms"]), str(r["threads"]), _ms(r["median_ms"]),
                               f"{r['scaling']:.2f}"] for r in scaled]))
    with_parts = [r for r in rows if r.get("parts_ms")]
    if not with_parts:
        return "\n\n".join(tables)
    part_names: List[str] = []
    for r in with_parts:
        part_names += [n for n in r["parts_ms"] if n not in part_names and n != LIT_PASS]
    part_names.append(LIT_PASS)
    part_rows = [[r["scene"], *(_ms(r["parts_ms"].get(n)) if n in r["parts_ms"] else "-" for n in part_names),
                  _ms(r["median_ms"])] for r in with_parts]
    tables.append(_table(["median ms by part", *part_names, "frame"], part_rows))
    return "\n\n".join(tables)


def target_rows(rows: List[dict], paired: Sequence[dict] = ()) -> List[dict]:
    """The issues' targets this run's scenes measure (:data:`RATIO_TARGETS`, full-size scenes only, and
    :data:`PEAK_MEMORY_TARGET_MB` over every scene): each with what was measured and whether it is met.

    A ratio target is judged by its scenes' frames drawn in pairs (``paired``, :func:`paired_ratio`)
    when the run drew them so, and by the ratio of their medians otherwise; both are shown."""
    by_name = {r["scene"]: r for r in rows if r["scale"] == 1.0}
    pairs = {(p["scene"], p["baseline"]): p for p in paired}
    out = []
    for issue, scene, baseline, most in RATIO_TARGETS:
        if scene in by_name and baseline in by_name:
            ratio = by_name[scene]["median_ms"] / by_name[baseline]["median_ms"]
            measured = f"{ratio:.2f}"
            p = pairs.get((scene, baseline))
            if p is not None:
                measured = (f"{p['ratio']:.2f} (median of {p['pairs']} pairs of turns, quartiles {p['low']:.2f}–"
                            f"{p['high']:.2f}); medians' ratio {ratio:.2f}")
                ratio = p["ratio"]
            out.append({"issue": issue, "target": f"{scene} ÷ {baseline} ≤ {most}", "measured": measured,
                        "met": ratio <= most})
    scaled = [r for r in rows if r.get("scaling") is not None and r["threads"] == 2]
    if scaled:
        missed = sorted((r for r in scaled if r["scaling"] < SCALING_TARGET), key=lambda r: r["scaling"])
        measured = f"{len(scaled) - len(missed)} of {len(scaled)} scenes" + \
            ("" if not missed else "; below: " + ", ".join(f"{r['scene']} {r['scaling']:.2f}" for r in missed))
        out.append({"issue": 35, "target": f"2 threads ≥ {SCALING_TARGET}× 1 thread, whole frames", "measured": measured,
                    "met": not missed})
    if rows:
        peak = max(rows, key=lambda r: r["peak_rss_mb"])
        out.append({"issue": 35, "target": f"peak memory ≤ {PEAK_MEMORY_TARGET_MB:.0f} MB on every scene run",
                    "measured": f"{peak['peak_rss_mb']:.0f} MB ({peak['scene']})",
                    "met": peak["peak_rss_mb"] <= PEAK_MEMORY_TARGET_MB})
    return out


def format_targets(targets: List[dict]) -> str:
    """The targets of :func:`target_rows` as a table (empty string: none measured)."""
    if not targets:
        return ""
    return _table(["target (this run)", "issue", "met", "measured"],
                  [[t["target"], f"#{t['issue']}", "yes" if t["met"] else "NO", t["measured"]] for t in targets],
                  left=4)


def machine_info() -> dict:
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        cpu = platform.processor() or "unknown"
    try:
        nproc = len(os.sched_getaffinity(0))
    except AttributeError:
        nproc = os.cpu_count()
    return {"nproc": nproc, "cpu_model": cpu, "python": platform.python_version(), "numba": numba.__version__,
            "numpy": np.__version__, "platform": platform.platform(),
            "load_average_at_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None}


def source_state() -> dict:
    """The commit the figures were measured on, and how many files differed from it."""
    import subprocess
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO_ROOT, capture_output=True,
                              text=True, timeout=10).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain", "--", "softpipe"], cwd=REPO_ROOT,
                                capture_output=True, text=True, timeout=10).stdout
        return {"commit": head or None, "softpipe_files_changed_since": len(status.splitlines())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "softpipe_files_changed_since": None}


def _threading_layer() -> str:
    """numba's threading layer, if some parallel kernel started it (softpipe's own run none: softpipe.core.parallel)."""
    try:
        return numba.threading_layer()
    except ValueError:
        return "not started"


def run(names: Sequence[str] = (), frames: int = DEFAULT_FRAMES, scale: float = 1.0, threads: Optional[int] = None,
        budget: Optional[float] = DEFAULT_BUDGET_S, keep_images: bool = False,
        log: Callable[[str], None] = print, scaling: bool = False) -> dict:
    """Benchmark ``names`` (all scenes if empty); returns the report (what ``--json`` writes, plus images)."""
    names = list(names) or list(SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        raise ValueError(f"unknown scene(s) {', '.join(unknown)}; the scenes are: {', '.join(SCENES)}")
    previous_threads = numba.get_num_threads()
    if threads is not None:
        limit = numba.config.NUMBA_NUM_THREADS
        if not 1 <= threads <= limit:
            raise ValueError(f"--threads must be between 1 and {limit} (numba's NUMBA_NUM_THREADS; set that "
                             f"environment variable to allow more), got {threads}")
        numba.set_num_threads(threads)
    try:
        info = machine_info()
        log(f"softpipe benchmarks: {', '.join(names)}; scale {scale}, {frames} warm frames "
            f"(budget {budget or 'unlimited'} s per scene), numba threads {numba.get_num_threads()} "
            f"of {numba.config.NUMBA_NUM_THREADS}, BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS')}")
        log(f"machine: {info['nproc']} cores, {info['cpu_model']}, Python {info['python']}, numba {info['numba']}, "
            f"load average {', '.join(f'{x:.2f}' for x in info['load_average_at_start'] or [])}")
        rows, started = [], time.perf_counter()
        failed = []
        for name in names:
            try:
                rows.append(run_scene(name, frames=frames, scale=scale, budget=budget, keep_image=keep_images,
                                      log=log, scaling=scaling))
            except Exception as err:  # one broken scene must not hide the others' figures
                log(f"  {name}: FAILED: {type(err).__name__}: {err}")
                failed.append({"scene": name, "error": f"{type(err).__name__}: {err}",
                               "traceback": traceback.format_exc()})
            gc.collect()
        # the targets between two scenes: their frames again, in alternated pairs (paired_ratio)
        paired = []
        ran = {r["scene"] for r in rows}
        for _, scene_name, baseline_name, _ in RATIO_TARGETS if scale == 1.0 else ():
            if scene_name in ran and baseline_name in ran:
                log(f"  {scene_name} with {baseline_name}: {frames} pairs of turns of {PAIR_BLOCK} frames ...")
                try:
                    paired.append(paired_ratio(build_scene(scene_name, scale), build_scene(baseline_name, scale),
                                               frames))
                except Exception as err:  # the scenes' own figures stand without it
                    log(f"  {scene_name} with {baseline_name}: FAILED: {type(err).__name__}: {err}")
                    failed.append({"scene": f"{scene_name} with {baseline_name}",
                                   "error": f"{type(err).__name__}: {err}", "traceback": traceback.format_exc()})
                gc.collect()
        report = {
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "command": " ".join([Path(sys.executable).name, "-m", "benchmarks.run", *sys.argv[1:]]),
            "machine": info,
            "source": source_state(),
            "load_average_at_end": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            "threads": {"numba_threads": numba.get_num_threads(), "numba_max_threads": numba.config.NUMBA_NUM_THREADS,
                        "threading_layer": _threading_layer(),
                        "blas_env": {v: os.environ.get(v) for v in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                                                     "OMP_NUM_THREADS")}},
            "settings": {"frames": frames, "scale": scale, "budget_s": budget, "scaling": scaling},
            "total_s": time.perf_counter() - started,
            "scenes": rows,
            "paired": paired,
            "targets": target_rows(rows, paired),
            "failed": failed,
            "notes": [n for r in rows for n in r["notes"]] + [f"{f['scene']}: FAILED: {f['error']}" for f in failed],
        }
        return report
    finally:
        if threads is not None:
            numba.set_num_threads(previous_threads)


def _jsonable(report: dict) -> dict:
    out = dict(report)
    out["scenes"] = [{k: v for k, v in r.items() if k != "image"} for r in report["scenes"]]
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="scenes: " + ", ".join(SCENES))
    parser.add_argument("scenes", nargs="*", metavar="SCENE", help="scenes to run (default: all)")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help=f"warm frames per scene (default {DEFAULT_FRAMES})")
    parser.add_argument("--threads", type=int, default=None,
                        help="numba threads (numba.set_num_threads); default: numba's default, one per core")
    parser.add_argument("--scale", type=float, default=1.0,
                        help="scene size, 0 < S <= 1: framebuffer sides times S, geometry to match (default 1)")
    parser.add_argument("--budget", type=float, default=DEFAULT_BUDGET_S,
                        help=f"seconds of warm frames per scene before stopping early, with a note "
                             f"(default {DEFAULT_BUDGET_S:.0f}; 0 = no limit)")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON,
                        help=f"where to write the results (default {DEFAULT_JSON.relative_to(REPO_ROOT)})")
    parser.add_argument("--scaling", action="store_true",
                        help="then draw as many frames on 1 thread and report the ratio of the medians (issue 35's "
                             "target: 2 threads at least 1.8x as fast)")
    parser.add_argument("--save-images", type=Path, default=None, metavar="DIR",
                        help="also write each scene's last frame as DIR/SCENE.png")
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    if not 0.0 < args.scale <= 1.0:
        parser.error("--scale must be in (0, 1]")
    bad = [n for n in args.scenes if n not in SCENES]
    if bad:
        parser.error(f"unknown scene(s) {', '.join(bad)}; the scenes are: {', '.join(SCENES)}")
    keep_freed_memory()     # a program of softpipe's own, as the softpipe command is (softpipe/core/runtime.py)
    try:
        report = run(args.scenes, frames=args.frames, scale=args.scale, threads=args.threads,
                     budget=args.budget or None, keep_images=args.save_images is not None, scaling=args.scaling)
    except ValueError as e:
        parser.error(str(e))
    print()
    if report["scenes"]:
        print(format_tables(report["scenes"]))
    if report["targets"]:
        print("\n" + format_targets(report["targets"]))
    if report["notes"]:
        print("\nnotes:")
        for note in report["notes"]:
            print(f"  - {note}")
    memory = report["scenes"][0]["memory_method"] if report["scenes"] else "-"
    print(f"\n{report['total_s']:.0f} s in all; threads {report['threads']['numba_threads']} "
          f"(softpipe's bands on Python threads; numba's threading layer: {report['threads']['threading_layer']}); "
          f"peak MB = {memory}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(_jsonable(report), indent=1) + "\n")
    print(f"results written to {args.json}")
    if args.save_images is not None:
        from PIL import Image
        args.save_images.mkdir(parents=True, exist_ok=True)
        for r in report["scenes"]:
            Image.fromarray(r["image"][..., :3]).save(args.save_images / f"{r['scene']}.png")
        print(f"images written to {args.save_images}/")
    return 1 if report["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
