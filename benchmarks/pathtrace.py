"""Path-tracing samples per second: softpipe's path tracer beside Mitsuba 3's (``make bench-pt``).

Both render Mitsuba's own Cornell box (``mitsuba.cornell_box()``; softpipe reads it as
``examples/cornell_box.toml``, docs/pathtracing.md) at the same size, samples per pixel
and path length (``max_depth`` 8, as the dict), on the same cores: softpipe on numba's
threads (``--threads``), Mitsuba in its ``scalar_rgb`` variant on its own thread pool
(the same count). Each renderer is warmed once (numba's compile, Mitsuba's scene load),
then the two are alternated ``--rounds`` times and the median is kept. Samples per
second is width × height × spp / seconds of rendering (scene loading not counted).

Where ``import mitsuba`` fails (or its scalar_rgb variant is missing) the Mitsuba
column says why and softpipe is timed alone (exit status 0).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numba  # noqa: E402

from softpipe.scenes.scenefile import load_scene  # noqa: E402
from softpipe.tracers.pathtrace import pathtrace  # noqa: E402

SCENE = Path(__file__).resolve().parent.parent / "examples" / "cornell_box.toml"
MAX_DEPTH = 8


def load_mitsuba(size: int, spp: int, threads: int):
    """(mitsuba module, the scene) or (None, why it is missing)."""
    try:
        import mitsuba as mi
    except Exception as e:                      # not installed, or a broken installation
        return None, f"mitsuba is not installed ({type(e).__name__}: {e}); pip install mitsuba"
    try:
        mi.set_variant("scalar_rgb")
    except Exception as e:
        return None, f"Mitsuba's scalar_rgb variant is not available: {e}"
    try:
        import drjit as dr
        dr.set_thread_count(threads)
    except Exception:                           # older Dr.Jit: Mitsuba's own default (one per core)
        pass
    d = mi.cornell_box()
    d["sensor"]["film"].update(width=size, height=size, rfilter={"type": "box"})
    d["sensor"]["sampler"]["sample_count"] = spp
    d["integrator"]["max_depth"] = MAX_DEPTH
    return mi, mi.load_dict(d)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.pathtrace", description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=256, help="image side in pixels (default 256)")
    parser.add_argument("--spp", type=int, default=64, help="samples per pixel per render (default 64)")
    parser.add_argument("--rounds", type=int, default=3, help="timed renders of each, alternated (default 3)")
    parser.add_argument("--threads", type=int, default=numba.config.NUMBA_NUM_THREADS,
                        help="threads for both renderers (default: numba's, one per core)")
    parser.add_argument("--json", default="out/bench-pt.json", help="where the results go")
    args = parser.parse_args(argv)
    if min(args.size, args.spp, args.rounds, args.threads) < 1:
        parser.error("--size, --spp, --rounds and --threads must be at least 1")
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    scene = load_scene(SCENE).replace(width=args.size, height=args.size)
    samples = args.size * args.size * args.spp
    mi, mitsuba_scene = load_mitsuba(args.size, args.spp, args.threads)

    pathtrace(scene.replace(width=4, height=4), spp=1, max_depth=MAX_DEPTH)        # numba's compile, not timed
    if mi is not None:
        mi.render(mitsuba_scene, seed=0)                                           # its warm-up
    ours, theirs = [], []
    for k in range(args.rounds):
        traced = pathtrace(scene, spp=args.spp, seed=k, max_depth=MAX_DEPTH)
        ours.append(traced.timings["trace"])
        if mi is not None:
            start = time.perf_counter()
            mi.render(mitsuba_scene, seed=k + 1)
            theirs.append(time.perf_counter() - start)

    rows = [("softpipe", statistics.median(ours))]
    if mi is not None:
        rows.append((f"Mitsuba {mi.__version__} scalar_rgb", statistics.median(theirs)))
    print(f"Cornell box {args.size}×{args.size}, {args.spp} spp, max_depth {MAX_DEPTH}, {args.threads} thread(s), "
          f"median of {args.rounds}")
    print(f"{'renderer':<28} {'seconds':>9} {'samples/s':>12}")
    for name, seconds in rows:
        print(f"{name:<28} {seconds:9.3f} {samples / seconds:12,.0f}")
    if mi is None:
        print(f"Mitsuba: skipped: {mitsuba_scene}")
    result = {"size": args.size, "spp": args.spp, "threads": args.threads, "rounds": args.rounds,
              "softpipe_seconds": ours, "mitsuba_seconds": theirs,
              "mitsuba": None if mi is None else mi.__version__, "mitsuba_skipped": None if mi else mitsuba_scene}
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
