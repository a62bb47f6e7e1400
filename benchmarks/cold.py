"""Cold start: how long a first picture takes (issue 18), ``python -m benchmarks.cold`` (``make bench-cold``).

Three measures, each in fresh Python processes so that nothing compiled in
this one counts, medians of ``--runs``:

``render bunny, empty caches``
    ``python -m softpipe render bunny`` (640×480, the built-in ``phong``) with
    empty kernel caches (``NUMBA_CACHE_DIR`` and ``SOFTPIPE_CACHE_DIR`` point at
    new empty folders): the process's wall time, from start to exit. Everything
    the picture needs is compiled: this is a user's very first picture.
``README stripes shader, first draw``
    README's example shader (``stripes``: ``frag.x``, ``mix``, a uniform), its
    first ``softpipe.draw`` in a process: user shaders are compiled once per
    process (never cached on disk, softpipe/language/kernels/cache.py says why), the library's own
    kernels are in the cache (the script's untimed part, run once before,
    fills it; each timed process starts from a copy of that cache).
``new lit user program, first draw``
    ``wrapped`` of examples/user_program.py (the §10 sum written out in the
    shader, with its own diffuse term), drawing a 64×32 sphere at 256² as the
    example does: its first draw, the library cached as for the stripes (its
    uniforms, with ``wrap``, are a new type: the vertex loop of
    ``standard_vertex`` is compiled for them too, as for any new program).

Targets (issue 18): 10 s, 1 s and 2 s.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TARGETS = {"render": 10.0, "stripes": 1.0, "lit": 2.0}

#: README's stripes example, timed around its second draw (the first compiles the library's default shader).
STRIPES = r'''
import sys, time
import numpy as np
import softpipe as sp
from softpipe.language.glsl import mix

fb = sp.Framebuffer(64, 48)
positions = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
sp.draw(fb, positions, varyings={"color": colors})


def stripes(varyings, uniforms, frag):
    on = int(frag.x) // 4 % 2
    c = mix(varyings.color, uniforms.tint, 0.5 * on)
    return (c[0], c[1], c[2], 1.0)


fb.clear()
if "warm" not in sys.argv:
    start = time.perf_counter()
    sp.draw(fb, positions, varyings={"color": colors}, fragment_shader=stripes, uniforms={"tint": (1.0, 1.0, 1.0)})
    print(time.perf_counter() - start)
'''

#: examples/user_program.py's program, timed around its first draw (the built-in phong draws first, untimed).
LIT = r'''
import sys, time
sys.path.insert(0, {examples!r})
from user_program import wrapped
from common import key_light, render
from softpipe.scenes import shapes
from softpipe.pipeline.camera import Camera
from softpipe.shading import Material

camera = Camera(eye=(0.0, 0.0, 3.4), fovy=38.0)
sphere = shapes.uv_sphere(segments=64, rings=32, material=Material(kd=(0.8, 0.45, 0.35), ks=0.3))
render(sphere, camera, "phong", key_light(), (256, 256))
if "warm" not in sys.argv:
    start = time.perf_counter()
    render(sphere, camera, wrapped, key_light(), (256, 256), uniforms={{"wrap": 0.5}})
    print(time.perf_counter() - start)
'''


def _env(numba_cache: str, softpipe_cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=numba_cache, SOFTPIPE_CACHE_DIR=softpipe_cache)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def _run(args: list, env: dict) -> str:
    done = subprocess.run([sys.executable, *args], env=env, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args[:3])} failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    return done.stdout


def render_bunny(out: Path) -> float:
    """Wall seconds of ``softpipe render bunny`` with empty caches."""
    with tempfile.TemporaryDirectory() as numba_cache, tempfile.TemporaryDirectory() as softpipe_cache:
        start = time.perf_counter()
        _run(["-m", "softpipe", "render", "bunny", "-o", str(out)], _env(numba_cache, softpipe_cache))
        return time.perf_counter() - start


def first_draws(script: str, runs: int, work: Path) -> list:
    """Seconds of the script's timed draw in ``runs`` new processes, each with the caches as the
    script's untimed part left them (run once, with "warm", before): the library's kernels
    cached, nothing of the timed draw's own (its vertex loop for a new uniforms type included)."""
    warm = {"NUMBA_CACHE_DIR": work / "numba", "SOFTPIPE_CACHE_DIR": work / "softpipe"}
    for folder in warm.values():
        folder.mkdir()
    _run(["-c", script, "warm"], _env(str(warm["NUMBA_CACHE_DIR"]), str(warm["SOFTPIPE_CACHE_DIR"])))
    times = []
    for k in range(runs):
        fresh = {name: work / f"{name}-{k}" for name in warm}
        for name, folder in warm.items():
            shutil.copytree(folder, fresh[name])
        out = _run(["-c", script], _env(str(fresh["NUMBA_CACHE_DIR"]), str(fresh["SOFTPIPE_CACHE_DIR"])))
        times.append(float(out.split()[-1]))
    return times


def measure(runs: int, which) -> dict:
    results = {}
    scripts = {"stripes": STRIPES, "lit": LIT.format(examples=str(ROOT / "examples"))}
    with tempfile.TemporaryDirectory() as work:
        if "render" in which:
            results["render"] = [render_bunny(Path(work) / "bunny.png") for _ in range(runs)]
        for key in ("stripes", "lit"):
            if key in which:
                (Path(work) / key).mkdir()
                results[key] = first_draws(scripts[key], runs, Path(work) / key)
    return results


LABELS = {"render": "softpipe render bunny, empty caches (wall)", "stripes": "README stripes shader, first draw",
          "lit": "new lit user program (wrapped), first draw"}


def report(results: dict) -> str:
    lines = [f"{'what':46s} {'median s':>9s} {'min s':>7s} {'max s':>7s} {'target s':>9s}  verdict"]
    for key, times in results.items():
        med = statistics.median(times)
        verdict = "met" if med <= TARGETS[key] else f"{med / TARGETS[key]:.2f}x"
        lines.append(f"{LABELS[key]:46s} {med:9.2f} {min(times):7.2f} {max(times):7.2f} {TARGETS[key]:9.1f}  {verdict}")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.cold", description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=3, help="fresh processes per measure (default 3)")
    parser.add_argument("--only", choices=sorted(TARGETS), action="append", help="one measure (repeatable)")
    args = parser.parse_args(argv)
    which = args.only or list(TARGETS)
    print(f"{args.runs} fresh processes per measure, {os.cpu_count()} cores; {sys.executable}")
    print(report(measure(args.runs, which)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
