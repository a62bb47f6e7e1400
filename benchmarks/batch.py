r"""softpipe batch's scaling: ``python -m benchmarks.batch`` (``make bench-batch``; docs/batch.md, "Scaling").

A ``--frames``-frame turntable of a bundled model (``--model``, default the bunny) at
``--size``, rendered by :func:`softpipe.tools.batch.batch` on ``LocalCluster``\ s of 1, 2, …
worker processes (``--workers 1,2``), one thread each. Every cluster is started and
warmed first; then the clusters take turns, ``--repeats`` times, so that a change in the
machine's load falls on all of them alike, and the median counts. It prints frames/s per
cluster, a frame's render time on a worker (wall clock and CPU), the client's CPU time per
frame, and the efficiency n workers reach against one. Needs Dask (the ``cluster`` extra).
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import sys
import time
from typing import Callable, Dict, List, Optional, Sequence

from softpipe.tools.batch import batch, parse_job, render_frame


def _warm(job_text: str) -> None:
    """On a worker: render the job's first frame small, so its kernels are loaded before the timing."""
    job = parse_job(job_text)
    frame = dataclasses.replace(job.frames[0], width=64, height=48)
    render_frame(frame, job.load_models()[frame.model], job)


def bench(model: str = "bunny", frames: int = 36, size: str = "640x480", workers: Sequence[int] = (1, 2),
          repeats: int = 5, out: Optional[Callable[[str], None]] = print) -> Dict[int, float]:
    """Frames per second of a ``frames``-frame turntable of ``model`` on LocalClusters of ``workers``.

    Every cluster is started and warmed first (each worker renders one small frame: its
    kernels loaded from the on-disk cache), then the clusters take turns rendering the
    whole turntable (``force``, no contact sheet), ``repeats`` times each, so that a
    change in the machine's load falls on all of them alike; the median time counts.
    Also reported: a frame's median render time on a worker (wall clock, CPU), and the client's CPU time
    (writing the files and the manifest, and the LocalCluster's scheduler, which runs
    in the client process) per frame. Returns workers → frames/s.
    """
    import contextlib
    import statistics
    import tempfile

    from distributed import Client, LocalCluster
    text = f'[sweep]\nmodels = ["{model}"]\norbit = {{ frames = {frames} }}\nsizes = ["{size}"]\n'
    job = parse_job(text, "<bench>")
    times: Dict[int, List[float]] = {n: [] for n in workers}
    per_frame: Dict[int, List[float]] = {n: [] for n in workers}
    cpu_frame: Dict[int, List[float]] = {n: [] for n in workers}
    client_cpu: Dict[int, List[float]] = {n: [] for n in workers}
    with contextlib.ExitStack() as stack:
        clients = {}
        for n in workers:
            cluster = stack.enter_context(LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                       dashboard_address=":0", silence_logs=logging.ERROR))
            clients[n] = stack.enter_context(Client(cluster))
            clients[n].run(_warm, text)
        tmp = stack.enter_context(tempfile.TemporaryDirectory())
        for _ in range(repeats):
            for n in workers:
                cpu = time.process_time()
                result = batch(job, tmp, clients[n], force=True, contact_sheet=False)
                client_cpu[n].append((time.process_time() - cpu) / frames)
                assert not result.failed, result.failed
                times[n].append(result.seconds)
                per_frame[n].extend(r.seconds for r in result.done)
                cpu_frame[n].extend(r.cpu_seconds for r in result.done)
    rates = {n: frames / statistics.median(times[n]) for n in workers}
    if out is not None:
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        out(f"{frames}-frame {model} turntable at {size}, {os.cpu_count()} cores, load average {load:.2f}:")
        for n in workers:
            out(f"  {n} worker{'s' if n > 1 else ' '}: {rates[n]:5.2f} frames/s (median of "
                f"{', '.join(f'{t:.2f}' for t in times[n])} s); a frame renders in "
                f"{statistics.median(per_frame[n]) * 1000:.0f} ms on a worker "
                f"({statistics.median(cpu_frame[n]) * 1000:.0f} ms of CPU); client CPU "
                f"{statistics.median(client_cpu[n]) * 1000:.0f} ms per frame")
        if 1 in rates:
            for n in workers:
                if n > 1:
                    out(f"  efficiency at {n} workers: {rates[n] / (n * rates[1]):.2f} "
                        f"(speed-up {rates[n] / rates[1]:.2f}×)")
    return rates


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The command line: ``python -m benchmarks.batch [--model M] [--frames N] [--size WxH] [--workers 1,2]``."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.batch",
                                     description="Measure softpipe batch's frames/s on LocalClusters of 1, 2, … "
                                                 "workers: a turntable of a bundled model.")
    parser.add_argument("--model", default="bunny")
    parser.add_argument("--frames", type=int, default=36)
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    parser.add_argument("--repeats", type=int, default=5)
    options = parser.parse_args(argv)
    bench(options.model, options.frames, options.size, [int(w) for w in options.workers.split(",")],
          options.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
