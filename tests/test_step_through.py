"""The fixed-function kernels can be stepped through as plain Python (docs/07-debugging.md).

* With ``NUMBA_DISABLE_JIT=1`` the rasterizer and the output merger (and the
  rest of the pipeline) run as the Python they are written in, and give the
  same bytes as the compiled kernels: the same fragments, verdicts and colors,
  the same framebuffer.
* A scripted ``python -m pdb`` session stops inside ``raster._cover_triangle``
  on one chosen sample of one triangle and prints its edge functions and
  fill-rule biases, which match the values worked out by hand below.
* A breakpoint in a fragment shader stops only in ``Trace.debug_fragment``'s
  re-run, on that one fragment, never in the compiled draw.

Every run is a subprocess (``sys.executable``), since numba reads
``NUMBA_DISABLE_JIT`` once, at import. Line numbers are found from the source
(``inspect.getsourcelines``), so the tests survive edits to raster.py.
"""
from __future__ import annotations

import ast
import inspect
import os
import re
import subprocess
import sys
import textwrap

import numpy as np

from softpipe.pipeline import raster

TIMEOUT = 600


def _env(jit: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "SOFTPIPE_DEBUG")}
    if not jit:
        env["NUMBA_DISABLE_JIT"] = "1"
    return env


def _run(args, jit: bool, cwd, stdin: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], input=stdin, capture_output=True, text=True, cwd=cwd,
                          env=_env(jit), timeout=TIMEOUT)


# --------------------------------------------------- same results with and without the JIT

SCENE = textwrap.dedent('''
    import sys
    import types
    import numba
    import numpy as np
    import softpipe as sp
    from softpipe.pipeline import output
    from softpipe.pipeline import raster
    from softpipe.pipeline.sampling import rotated_grid_4x

    jit = not numba.config.DISABLE_JIT
    kernels = (raster._cover_triangle, raster._emit_kernel, output._merge_kernel, output.blend_channel)
    plain = all(isinstance(k, types.FunctionType) for k in kernels)
    assert plain != jit, ("plain Python functions" if plain else "numba dispatchers", jit)

    calls = {}

    def count(frame, event, arg):
        if event == "call" and frame.f_code.co_name in ("_cover_triangle", "blend_channel"):
            calls[frame.f_code.co_name] = calls.get(frame.f_code.co_name, 0) + 1

    # overlapping triangles in clip space: one crosses the near plane, one is back-facing
    clip = np.array([
        [-0.9, -0.8, 0.2, 1.0], [0.8, -0.7, 0.2, 1.0], [0.1, 0.9, 0.2, 1.0],
        [-0.7, 0.6, -0.5, 1.0], [0.2, -0.9, 0.6, 1.0], [0.9, 0.5, 0.1, 1.0],
        [-0.2, -0.3, 0.0, 1.0], [0.6, -0.1, 0.0, 1.0], [0.1, 0.3, -1.5, 0.5],
        [0.5, 0.7, 0.0, 1.0], [0.9, 0.9, 0.0, 1.0], [0.9, 0.2, 0.0, 1.0],
    ])
    rng = np.random.default_rng(7)
    colors = rng.random((len(clip), 4))
    colors[:, 3] = 0.6
    fb = sp.Framebuffer(37, 29, rotated_grid_4x())
    fb.clear((0.1, 0.2, 0.3, 1.0))
    sys.setprofile(count)
    opaque = sp.draw(fb, clip, varyings={"color": colors[:, :3]}, path="reference", trace=True)
    blended = sp.draw(fb, clip[::-1].copy(), varyings={"color": colors[::-1].copy()}, blend="alpha",
                      depth_test="lequal", depth_write=False, path="reference", trace=True)
    sys.setprofile(None)
    fast = sp.Framebuffer(37, 29, rotated_grid_4x())
    fast.clear((0.1, 0.2, 0.3, 1.0))
    sp.draw(fast, clip, varyings={"color": colors[:, :3]}, path="fast")

    arrays = {"color": fb.samples_color, "depth": fb.samples_depth,
              "fast_color": fast.samples_color, "fast_depth": fast.samples_depth}
    for name, t in (("opaque", opaque), ("blended", blended)):
        f = t.fragments
        for field in ("x", "y", "sample", "depth", "bary", "triangle", "primitive_id"):
            arrays[f"{name}_{field}"] = getattr(f, field)
        arrays[f"{name}_shaded"] = t.shaded.color
        arrays[f"{name}_verdict"] = t.merged.verdict
        arrays[f"{name}_after"] = t.merged.color_after
        arrays[f"{name}_window"] = t.primitives.window
    np.savez(sys.argv[1], **arrays)
    print("calls", calls.get("_cover_triangle", 0), calls.get("blend_channel", 0))
''')


def test_rasterizer_and_merger_run_as_python_with_the_same_bytes(tmp_path):
    script = tmp_path / "scene.py"
    script.write_text(SCENE)
    results = {}
    for jit in (True, False):
        out = tmp_path / f"jit-{jit}.npz"
        run = _run([str(script), str(out)], jit, tmp_path)
        assert run.returncode == 0, run.stderr[-3000:]
        calls = [int(n) for n in re.search(r"calls (\d+) (\d+)", run.stdout).groups()]
        if jit:
            assert calls == [0, 0], "compiled kernels should not be seen by the Python profiler"
        else:
            assert calls[0] > 0 and calls[1] > 0, f"the kernels did not run as Python: {calls}"
        results[jit] = dict(np.load(out))
    compiled, python = results[True], results[False]
    assert compiled.keys() == python.keys()
    assert len(compiled["opaque_x"]) > 500 and len(compiled["blended_x"]) > 500
    assert (compiled["blended_verdict"] == 1).any() and (compiled["blended_verdict"] == 0).any()
    for name in compiled:
        a, b = compiled[name], python[name]
        assert a.dtype == b.dtype and a.shape == b.shape, name
        assert a.tobytes() == b.tobytes(), f"{name} differs between compiled and plain-Python kernels"


# ------------------------------------------------------------ pdb inside _cover_triangle

STEP = textwrap.dedent('''
    import numpy as np
    import softpipe as sp

    # window corners (2.5, 1.5), (13.5, 1.5), (6.5, 10.5) on 16×12: pixel centres, so the
    # snapped corners are (512, 256), (3328, 256), (1536, 2560); triangle 1 shares the edge 1→2
    positions = np.array([[-0.6875, -0.75, 0.0, 1.0], [0.6875, -0.75, 0.0, 1.0], [-0.1875, 0.75, 0.0, 1.0],
                          [0.6875, -0.75, 0.0, 1.0], [0.8125, 0.75, 0.0, 1.0], [-0.1875, 0.75, 0.0, 1.0]])
    colors = np.array([[1.0, 0.3, 0.2]] * 3 + [[0.2, 0.5, 1.0]] * 3)
    fb = sp.Framebuffer(16, 12)
    trace = sp.draw(fb, positions, varyings={"color": colors}, path="reference", trace=True)
    print("done", *np.bincount(trace.fragments.triangle))
''')


def _line_after_edge_functions() -> int:
    """The first line of _cover_triangle after e0, e1, e2 are computed for an emitted sample."""
    src, first = inspect.getsourcelines(raster._cover_triangle)
    for k, line in enumerate(src):
        code = line.split("#")[0].strip()
        if code.startswith("e0, e1, e2") and "edge_values(" in code and code.endswith("px, py)"):
            return first + k + 1
    raise AssertionError("raster._cover_triangle no longer computes 'e0, e1, e2 = edge_values(…, px, py)'; "
                         "update this test and docs/07-debugging.md")


def _pdb_values(out: str, tag: str):
    """The value pdb printed for ``p (tag, …)``: numpy scalar reprs unwrapped, then literal_eval."""
    for line in out.splitlines():
        line = line.replace("(Pdb) ", "")
        if line.startswith(f"('{tag}'"):
            return ast.literal_eval(re.sub(r"np\.\w+\(([^()]*)\)", r"\1", line))
    raise AssertionError(f"pdb printed no {tag!r} line:\n{out}")


def test_pdb_stops_in_cover_triangle_and_shows_the_edge_functions(tmp_path):
    script = tmp_path / "step_raster.py"
    script.write_text(STEP)
    path = raster.__file__
    line = _line_after_edge_functions()
    commands = "\n".join([
        f"break {path}:{line}, t == 0 and i == 5 and j == 1",
        "continue",
        "p ('at', t, i, j, s, emit)",
        "p ('setup', tuple(edges[t].ravel().tolist()), round(1 / plane[t, 3]))",
        "p ('bias', tuple(bias[t].tolist()))",
        "p ('edges', e0, e1, e2)",
        "continue",
        "quit",
    ]) + "\n"
    run = _run(["-m", "pdb", str(script)], False, tmp_path, stdin=commands)
    out = run.stdout
    assert f"raster.py({line})_cover_triangle()" in out, out
    assert out.count("_cover_triangle()") == 1, "the conditional breakpoint should stop exactly once"
    assert "done 55 32" in out, "the script did not run to its end under pdb:\n" + out + run.stderr

    assert _pdb_values(out, "at") == ("at", 0, 5, 1, 0, True)
    # The triangle in fixed point (256 per pixel, pixel i's centre at 256·i), counter-clockwise:
    # corners P0 = (512, 256), P1 = (3328, 256), P2 = (1536, 2560). Edge k runs a→b opposite
    # corner k (a = k+1, b = k+2) and E_k = A·x + B·y + C with A = −(Y_b − Y_a), B = X_b − X_a,
    # C = (Y_b − Y_a)·X_a − (X_b − X_a)·Y_a:
    #   E_0 (P1→P2): A = −2304, B = −1792, C = 2304·3328 + 1792·256   = 8126464
    #   E_1 (P2→P0): A = 2304,  B = −1024, C = −2304·1536 + 1024·2560 = −917504
    #   E_2 (P0→P1): A = 0,     B = 2816,  C = −2816·256              = −720896
    edges = (-2304, -1792, 8126464, 2304, -1024, -917504, 0, 2816, -720896)
    assert _pdb_values(out, "setup") == ("setup", edges, 2816 * 2304)
    # Fill rule, counter-clockwise: E_0 (P1→P2) runs up, a right edge: not an owner, bias −1.
    # E_1 (P2→P0) runs down, a left edge: owner, 0. E_2 (P0→P1) is horizontal, to the right,
    # the bottom edge: owner, 0.
    assert _pdb_values(out, "bias") == ("bias", (-1, 0, 0))
    # The sample: the centre of pixel (5, 1), P = (1280, 256). E(a→b) = (Xb−Xa)(Py−Ya) − (Yb−Ya)(Px−Xa):
    # E_0 = (1536−3328)(256−256) − (2560−256)(1280−3328) = 0 + 2304·2048          = 4718592
    # E_1 = (512−1536)(256−2560) − (256−2560)(1280−1536) = 1024·2304 − 2304·256   = 1769472
    # E_2 = (3328−512)(256−256) − (256−256)(1280−512)                              = 0 (on the bottom edge)
    assert _pdb_values(out, "edges") == ("edges", 4718592, 1769472, 0)
    assert 4718592 + 1769472 + 0 == 2816 * 2304          # E_0 + E_1 + E_2 = twice the area


# ------------------------------------------------------- a breakpoint in a fragment shader

SHADER = textwrap.dedent('''
    import numpy as np
    import softpipe as sp


    def rings(varyings, uniforms, frag):
        c = varyings.color
        r = ((frag.x - 32.0) ** 2 + (frag.y - 24.0) ** 2) ** 0.5
        k = 1.0 if int(r) // 4 % 2 == 0 else 0.4
        return (k * c[0], k * c[1], k * c[2], 1.0)


    fb = sp.Framebuffer(64, 48)
    positions = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
    colors = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    trace = sp.draw(fb, positions, varyings={"color": colors}, fragment_shader=rings, trace=True)
    rgba = trace.debug_fragment(40, 30)
    print("same", bool(np.array_equal(np.float32(rgba), fb.color[30, 40])))
''')


def test_a_breakpoint_in_a_shader_stops_only_in_debug_fragment(tmp_path):
    script = tmp_path / "debug_pixel.py"
    script.write_text(SHADER)
    line = 1 + SHADER.splitlines().index("    k = 1.0 if int(r) // 4 % 2 == 0 else 0.4")
    commands = (f"break {script}:{line}\ncontinue\np ('frag', frag.x, frag.y)\n"
                "up\np ('caller', type(self).__name__)\ncontinue\nquit\n")
    run = _run(["-m", "pdb", str(script)], True, tmp_path, stdin=commands)
    out = run.stdout
    assert out.count(f"debug_pixel.py({line})rings()") == 1, out + run.stderr    # one stop, one fragment
    assert _pdb_values(out, "frag") == ("frag", 40.5, 17.5)    # image (40, 30) is window (40.5, 48 − 30 − ½)
    assert "debug_fragment()" in out                           # the caller: the re-run, not the compiled draw
    assert _pdb_values(out, "caller") == ("caller", "Trace")
    assert "same True" in out
