"""What one shaded sample costs on the fast path, split into its parts (issue 6).

    .venv/bin/python -m benchmarks.shading_cost                 # sphere200k, bunny, bunny-plane, bunny-shadows
    .venv/bin/python -m benchmarks.shading_cost bunny --runs 21

For every draw of a scene, the vertex stage, assembly and the visibility pass
run once; then the shading loop alone (the generated ``visible_loop``) is timed
on one thread over the whole framebuffer, with three fragment shaders:

``constant``   returns one color: the loop itself, scanning the visibility
               buffer and storing colors (the compiler drops the barycentrics
               and depth, which this shader does not use)
``varyings``   returns P + N: adds the exact barycentrics and depth and the
               perspective-correct interpolation of ``position`` and ``normal``
the scene's    the scene's own shader (the built-in ``phong`` or
               ``phong_phong_specular``): adds the lighting

It prints nanoseconds per shaded sample (the median over ``--runs``) and what
the scene's shading costs a frame at the ideal 2× of two threads: a floor
under the frame time that no rasterizer work can lower. Only scenes whose
varyings are ``position`` and ``normal`` (the lit mesh scenes) can be split so;
bunny-shadows makes its shadow maps once, before the timing (only the lookups are timed).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numba

from softpipe.core.runtime import keep_freed_memory
from softpipe.language import kernels
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.visibility import visible_loop_args

from .scenes import build_scene

LIT_SCENES = ("sphere200k", "bunny", "bunny-plane", "bunny-shadows")


def constant(varyings, uniforms, frag):
    """The loop alone: nothing interpolated, nothing lit."""
    return (0.5, 0.25, 0.125, 1.0)


def interpolated(varyings, uniforms, frag):
    """The loop and the interpolation of P and N."""
    P, N = varyings.position, varyings.normal
    return (P[0] + N[0], P[1] + N[1], P[2] + N[2], 1.0)


def _median_seconds(kernel, height: int, args: tuple, runs: int) -> float:
    kernel(0, height, *args)                 # compile, or load from the cache
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        kernel(0, height, *args)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure(scene_name: str, runs: int, scale: float = 1.0) -> dict:
    """Seconds per shader (one thread, all draws) and the number of shaded samples."""
    scene = build_scene(scene_name, scale)
    fb = Framebuffer(scene.width, scene.height)
    fb.clear(scene.clear_color)
    if scene.prepare is not None:        # bunny-shadows: its shadow maps, once (they are not timed here)
        scene.prepare()
    seconds = {"constant": 0.0, "varyings": 0.0, "own": 0.0}
    samples = 0
    for draw in scene.draws:
        call = DrawCall(fb, **{**draw, "path": "fast"})
        stages = {}
        for stage in call.steps():               # up to the visibility stage; shading is timed below
            stages[stage.name] = stage.output
            if stage.name == "visibility":
                break
        prims, visibility = stages["assembly"], stages["visibility"]
        if set(prims.layout.names) != {"position", "normal"}:
            raise SystemExit(f"{scene_name}: varyings {prims.layout.names}, not (position, normal): cannot split")
        samples += int((visibility.vis >= 0).sum())
        for key, shader in (("constant", constant), ("varyings", interpolated), ("own", call.fragment_shader)):
            kernel = kernels.visible_kernel(shader, prims.layout)
            args = visible_loop_args(prims, visibility, fb, shader, call.uniforms)
            seconds[key] += _median_seconds(kernel, fb.height, args, runs)
    return {"scene": scene_name, "samples": samples, "shader": scene.shading, **seconds}


def report(row: dict) -> str:
    n = row["samples"]
    ns = {k: row[k] / n * 1e9 for k in ("constant", "varyings", "own")}
    lines = [
        f"{row['scene']}: {n:,} shaded samples; {row['shader']}",
        f"  scanning the visibility buffer, storing    {ns['constant']:6.1f} ns/sample",
        f"  + barycentrics, depth, P and N             {ns['varyings'] - ns['constant']:6.1f} ns/sample",
        f"  + lighting (the scene's shader)            {ns['own'] - ns['varyings']:6.1f} ns/sample",
        f"  = the scene's shading                      {ns['own']:6.1f} ns/sample; a frame: {row['own'] * 1e3:.1f} ms "
        f"on one thread, {row['own'] * 1e3 / 2:.1f} ms on two at a perfect 2x",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.shading_cost", description=__doc__.split("\n")[0])
    parser.add_argument("scenes", nargs="*", metavar="SCENE", help=f"of {', '.join(LIT_SCENES)} (default: all)")
    parser.add_argument("--runs", type=int, default=11, help="timed runs per shader and draw (default 11)")
    parser.add_argument("--scale", type=float, default=1.0, help="the scene's scale, as in benchmarks.run (default 1)")
    args = parser.parse_args(argv)
    for name in args.scenes:
        if name not in LIT_SCENES:
            parser.error(f"scene {name!r} cannot be split into loop, interpolation and lighting; "
                         f"choose from {', '.join(LIT_SCENES)}")
    keep_freed_memory()     # a program of softpipe's own, as the softpipe command is (softpipe/core/runtime.py)
    print(f"one thread (of numba's {numba.get_num_threads()}), median of {args.runs} runs per draw and shader")
    for name in args.scenes or LIT_SCENES:
        print(report(measure(name, args.runs, args.scale)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
