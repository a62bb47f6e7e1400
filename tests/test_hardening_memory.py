"""Issue #28, round 3: memory a file or an option sizes, threads sharing a framebuffer, and files.

Each test here failed on main before its fix (the report of the change says how each was checked).
"""
from __future__ import annotations

import base64
import json
import os
import signal
import subprocess
import sys
import threading
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli
from patience import PATIENCE, read_line

import softpipe as sp
from softpipe.core.files import excerpt_path

ROOT = Path(__file__).resolve().parents[1]


def triangle(depth: float, shift: float) -> np.ndarray:
    """A large triangle at one constant depth, moved sideways by ``shift`` (clip coordinates, w = 1)."""
    return np.array([[-0.9 + shift, -0.9, depth, 1.0], [0.9 + shift, -0.7, depth, 1.0],
                     [shift, 0.9, depth, 1.0]])


# ---------------------------------------------------------------------------- item 5: threads, one framebuffer


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_threads_drawing_into_one_framebuffer_give_the_bytes_of_drawing_in_turn(path):
    """Overlapping triangles at distinct depths: with the depth test the result does not depend on the
    order, so any interleaving of whole draws gives the same bytes; a lost depth update does not."""
    rng = np.random.default_rng(5)
    jobs = [[(float(d), float(s), rng.random(3)) for d, s in zip(rng.uniform(-0.9, 0.9, 6),
                                                                    rng.uniform(-0.3, 0.3, 6))]
            for _ in range(4)]

    def draw_all(fb, draws):
        for depth, shift, color in draws:
            sp.draw(fb, triangle(depth, shift), varyings={"color": np.tile(color, (3, 1))}, path=path)

    expected = sp.Framebuffer(160, 120)
    for draws in jobs:
        draw_all(expected, draws)
    for trial in range(12):
        fb = sp.Framebuffer(160, 120)
        threads = [threading.Thread(target=draw_all, args=(fb, draws)) for draws in jobs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert np.array_equal(fb.samples_depth, expected.samples_depth), f"trial {trial}"
        assert np.array_equal(fb.samples_color, expected.samples_color), f"trial {trial}"


def test_a_framebuffer_still_pickles_with_its_lock():
    import pickle
    fb = sp.Framebuffer(6, 4)
    sp.draw(fb, triangle(0.0, 0.0), varyings={"color": np.ones((3, 3))})
    copy = pickle.loads(pickle.dumps(fb))
    assert np.array_equal(copy.samples_color, fb.samples_color)
    sp.draw(copy, triangle(-0.5, 0.1), varyings={"color": np.zeros((3, 3))})   # and it draws


# ---------------------------------------------------------------------------- item 10: a frozen framebuffer


@pytest.mark.parametrize("which", ["color", "depth", "samples_color", "samples_depth"])
def test_a_framebuffer_array_flagged_read_only_is_not_drawn_into(which):
    fb = sp.Framebuffer(8, 6)
    getattr(fb, which).flags.writeable = False
    before = fb.samples_color.copy(), fb.samples_depth.copy()
    with pytest.raises(ValueError, match=rf"Framebuffer\.{which} is read-only \(flags\.writeable is False\): "
                                         rf"softpipe will not draw into it; set fb\.{which}\.flags\.writeable = "
                                         r"True to draw"):
        sp.draw(fb, triangle(0.0, 0.0), varyings={"color": np.ones((3, 3))})
    with pytest.raises(ValueError, match=rf"Framebuffer\.{which} is read-only"):
        fb.clear("red")
    assert np.array_equal(fb.samples_color, before[0]) and np.array_equal(fb.samples_depth, before[1])
    getattr(fb, which).flags.writeable = True
    sp.draw(fb, triangle(0.0, 0.0), varyings={"color": np.ones((3, 3))})
    assert np.asarray(fb).any()


# ---------------------------------------------------------------------------- item 4: what a trace keeps


def small_triangles(n: int, rng) -> list:
    """``n`` small triangles (clip coordinates) scattered over the frame, one draw each."""
    out = []
    for _ in range(n):
        c = rng.uniform(-0.9, 0.9, 2)
        corners = c + rng.uniform(-0.05, 0.05, (3, 2))
        out.append(np.column_stack([corners, rng.uniform(-0.5, 0.5, 3), np.ones(3)]))
    return out


def test_traces_of_many_small_draws_keep_only_the_pixels_they_touched():
    """Main kept a copy of the whole framebuffer (20 bytes a sample) per traced draw: 40 small draws on
    640×480 held about 250 MB. Now each keeps the pixels it touched."""
    import tracemalloc
    rng = np.random.default_rng(3)
    fb = sp.Framebuffer(640, 480)
    draws = small_triangles(40, rng)
    sp.draw(fb, draws[0], varyings={"color": np.ones((3, 3))}, trace=True)       # compile first
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        traces = [sp.draw(fb, t, varyings={"color": rng.random((3, 3))}, trace=True) for t in draws]
        kept = tracemalloc.get_traced_memory()[0] - start
    finally:
        tracemalloc.stop()
    assert len(traces) == 40 and sum(len(t) for t in traces) > 1000
    assert kept < 20 * 2**20, f"40 traces keep {kept / 2**20:.0f} MiB"


@pytest.mark.parametrize("pattern", ["1", "rgss4"])
@pytest.mark.parametrize("path", ["reference", "fast"])
def test_before_the_draw_is_still_exact(pattern, path):
    from softpipe.pipeline.sampling import pattern_named
    rng = np.random.default_rng(11)
    fb = sp.Framebuffer(40, 30, pattern_named(pattern))
    fb.samples_color[...] = rng.random(fb.samples_color.shape)
    fb.samples_depth[...] = rng.uniform(0.5, 1.0, fb.samples_depth.shape)
    color, depth = fb.samples_color.copy(), fb.samples_depth.copy()
    # a triangle crossing the near plane (clipped) and one partly off screen
    pos = np.array([[-0.5, -0.6, 0.2, 1], [0.7, -0.2, 0.9, 1], [0.1, 0.8, -1.3, 1],
                    [-1.4, -1.2, 0.1, 1], [0.2, -0.1, 0.3, 1], [-0.3, 0.9, 0.9, 1]])
    trace = sp.draw(fb, pos, varyings={"color": rng.random((6, 3))}, trace=True, path=path)
    assert np.array_equal(trace.before_color, color) and np.array_equal(trace.before_depth, depth)
    assert len(trace.before.pixels) < fb.width * fb.height
    touched = sorted({(int(x), int(y)) for x, y in zip(trace.fragments.x, trace.fragments.y)})
    sp.draw(fb, pos[::-1], varyings={"color": rng.random((6, 3))})             # the framebuffer moves on
    for x, y in touched:
        c, d = trace.before_at(x, y)
        assert np.array_equal(c, color[:, y, x]) and np.array_equal(d, depth[:, y, x])
        assert trace.pixel_history(x, y).before == tuple(float(v) for v in color[0, y, x])
    with pytest.raises(ValueError, match=r"the whole before_color: the trace keeps the framebuffer as it was "
                                         r"before the draw only at the pixels the draw touched \([\d,]+ of them\), "
                                         r"and the framebuffer has been drawn into or cleared 1 time\(s\) since"):
        _ = trace.before_color


def test_the_explorer_of_many_draws_holds_one_draws_pictures_at_a_time():
    """Main made every draw's stage pictures before composing them: 40 draws on 640×480, about 220 MB."""
    import tracemalloc

    from softpipe.views.explorer import explorer_html
    rng = np.random.default_rng(4)
    fb = sp.Framebuffer(640, 480)
    traces = [sp.draw(fb, t, varyings={"color": rng.random((3, 3))}, trace=True) for t in small_triangles(40, rng)]
    explorer_html(traces[:2])                                                   # compile first
    tracemalloc.start()
    try:
        explorer_html(traces)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 60 * 2**20, f"peak {peak / 2**20:.0f} MiB"


# ---------------------------------------------------------------------------- item 4: read_explorer's budget


def page_with(tmp_path, arrays: dict) -> Path:
    """An explorer page whose data block holds ``arrays`` (name → dict as the page stores them), beside
    empty fragment arrays."""
    empty = {"f_color": stored(b"", "f4", [0, 4]), "f_after": stored(b"", "f4", [0, 4]),
             "f_after_same": stored(b"", "u1", [0])}
    meta = {"format": "softpipe-explorer 1", "width": 2, "height": 2, "draws": [], "arrays": {**empty, **arrays}}
    page = tmp_path / "crafted.html"
    page.write_text('<script type="application/json" id="softpipe-data">' + json.dumps(meta) + "</script>",
                    encoding="utf-8")
    return page


def stored(raw: bytes, dtype: str, shape: list) -> dict:
    return {"dtype": dtype, "shape": shape, "columns": False, "shuffle": False,
            "b64": base64.b64encode(zlib.compress(raw, 9)).decode("ascii")}


def test_read_explorer_refuses_an_array_that_inflates_past_its_shape(tmp_path):
    from softpipe.views.explorer import read_explorer
    bomb = stored(bytes(64 << 20), "u4", [4])           # 64 MiB of zeros, 65 KB compressed, "4 numbers"
    page = page_with(tmp_path, {"win": bomb})
    assert page.stat().st_size < 200_000
    with pytest.raises(ValueError, match=r"crafted\.html': array 'win': its data inflates to more than the 16 "
                                         r"bytes its shape \[4\] and dtype u4 say"):
        read_explorer(page)


def test_read_explorer_refuses_arrays_past_its_limit_before_inflating(tmp_path):
    from softpipe.views.explorer import read_explorer
    page = page_with(tmp_path, {"win": stored(b"", "f8", [1 << 30])})  # says 8 GiB
    with pytest.raises(ValueError, match=r"crafted\.html': the page's arrays would inflate to 8,589,934,592 bytes, "
                                         r"more than the limit of 2,147,483,648 bytes \(read_explorer\(path, "
                                         r"max_bytes=\.\.\.\) raises it\)"):
        read_explorer(page)
    small = page_with(tmp_path, {"win": stored(np.arange(4, dtype="<u4").tobytes(), "u4", [4])})
    assert read_explorer(small).arrays["win"].tolist() == [0, 1, 2, 3]
    size = small.stat().st_size
    with pytest.raises(ValueError, match=rf"the file is {size:,} bytes, more than the limit of 100 bytes"):
        read_explorer(small, max_bytes=100)


# ---------------------------------------------------------------------------- item 9: the command line's texts


def test_texture_that_is_a_fifo_is_named_as_a_fifo(tmp_path, capsys):
    fifo = tmp_path / "texture.png"
    os.mkfifo(fifo)
    code, out, err = run_cli(capsys, "render", ROOT / "tests/data/obj/two_materials.obj", "--texture", fifo,
                             "-o", tmp_path / "out.png")
    assert code == 2
    assert err.strip() == f"softpipe render: error: --texture: {excerpt_path(fifo)} is a FIFO, not a regular file"
    assert not (tmp_path / "out.png").exists()


def test_explore_takes_a_latin1_file_name(tmp_path, capsys):
    from softpipe.views.explorer import read_explorer
    src = (ROOT / "tests/data/obj/two_materials.obj").read_bytes()
    folder = os.fsencode(tmp_path)
    for name in (b"two_materials.mtl",):
        (tmp_path / os.fsdecode(name)).write_bytes((ROOT / "tests/data/obj" / os.fsdecode(name)).read_bytes())
    model = os.fsdecode(folder + b"/caf\xe9.obj")             # not UTF-8: Python holds it as 'caf\udce9.obj'
    Path(model).write_bytes(src)
    page = os.fsdecode(folder + b"/r\xe9sum\xe9.html")
    code, out, err = run_cli(capsys, "explore", model, "-o", page, "--size", "32x24", "-q")
    assert code == 0, err
    assert out.startswith("softpipe explore: wrote ") and "r\ufffdsum\ufffd.html" in out
    text = Path(page).read_text(encoding="utf-8")
    assert "<title>softpipe explorer: caf\ufffd" in text
    assert read_explorer(page).meta["draws"][0]["name"]


def test_running_out_of_memory_is_one_line_naming_the_options(tmp_path, capsys, monkeypatch):
    import softpipe.scenes.drawing as drawing

    def no_room(*args, **kwargs):
        raise MemoryError("Unable to allocate 1.2 GiB for an array with shape (4, 4000, 4000, 5)")
    monkeypatch.setattr(drawing, "render", no_room)
    code, out, err = run_cli(capsys, "render", "bunny", "-o", tmp_path / "out.png", "-q")
    assert code == 1
    assert err == ("softpipe render: error: out of memory: Unable to allocate 1.2 GiB for an array with shape "
                   "(4, 4000, 4000, 5); a smaller --size (or --width/--height) or fewer --samples makes it smaller; "
                   "--stages keeps every draw's fragments\n")
    code, out, err = run_cli(capsys, "explore", "bunny", "-o", tmp_path / "out.html", "-q")
    assert code == 1 and "or a smaller --max-fragments makes it smaller" in err
    assert not list(tmp_path.iterdir())


def test_a_framebuffer_too_large_for_the_memory_left_is_refused_before_it_is_made(monkeypatch, capsys, tmp_path):
    import softpipe.core.runtime as runtime
    monkeypatch.setattr(runtime, "available_memory", lambda: 100 << 20)
    with pytest.raises(MemoryError, match=r"a 4000×3000 framebuffer with 4 sample\(s\) per pixel \(21 bytes a "
                                          r"sample\) needs about 0\.9 GiB, and this machine has 0\.1 GiB available"):
        sp.Framebuffer(4000, 3000, sp.pipeline.sampling.pattern_named("rgss4"))
    code, out, err = run_cli(capsys, "render", "bunny", "--size", "4000x3000", "--samples", "rgss4",
                             "-o", tmp_path / "out.png", "-q")
    assert code == 1 and err.startswith("softpipe render: error: out of memory: a 4000×3000 framebuffer")
    assert err.rstrip().endswith("a smaller --size (or --width/--height) or fewer --samples makes it smaller; "
                                 "--stages keeps every draw's fragments")


# ---------------------------------------------------------------------------- item 10: SIGTERM while writing

SLOW_WRITE = """
import sys, time
from softpipe.core.files import atomic_write
def write(f):
    f.write(b"x" * 100_000)
    f.flush()
    print("writing", flush=True)
    time.sleep(3600)        # the write never ends on its own: only the signal ends it
atomic_write(sys.argv[1], write)
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_during_a_write_leaves_no_temporary_file(tmp_path, sig):
    """Nothing is timed: the test waits for "writing" and for the exit after the signal, each within
    :data:`patience.PATIENCE` (the child imports softpipe, slow on a loaded machine)."""
    target = tmp_path / "picture.png"
    target.write_bytes(b"the previous picture")
    proc = subprocess.Popen([sys.executable, "-c", SLOW_WRITE, str(target)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert read_line(proc, "'writing'") == b"writing\n"
        assert len(list(tmp_path.glob(".picture.png.*.tmp"))) == 1
        proc.send_signal(sig)
        proc.wait(timeout=PATIENCE)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode in ((-signal.SIGTERM,) if sig == signal.SIGTERM else (1, -signal.SIGINT))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["picture.png"]
    assert target.read_bytes() == b"the previous picture"


def test_the_sigterm_handler_is_up_only_while_writing_and_never_over_the_programs_own(tmp_path):
    from softpipe.core.files import atomic_write
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    seen = []
    atomic_write(tmp_path / "a.bin", lambda f: seen.append(signal.getsignal(signal.SIGTERM)))
    assert seen[0] not in (signal.SIG_DFL, None) and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL

    def mine(signum, frame):
        pass
    old = signal.signal(signal.SIGTERM, mine)
    try:
        atomic_write(tmp_path / "b.bin", lambda f: seen.append(signal.getsignal(signal.SIGTERM)))
        assert seen[1] is mine and signal.getsignal(signal.SIGTERM) is mine
    finally:
        signal.signal(signal.SIGTERM, old)


def test_the_history_of_a_pixel_the_draw_did_not_touch_says_so_once_the_framebuffer_moved_on():
    fb = sp.Framebuffer(20, 16)
    fb.clear((0.25, 0.5, 0.75, 1.0))
    trace = sp.draw(fb, triangle(0.0, 0.0) * [0.3, 0.3, 1, 1], varyings={"color": np.ones((3, 3))}, trace=True)
    assert trace.pixel_history(0, 0).before == (0.25, 0.5, 0.75, 1.0)     # unchanged since: known
    fb.clear("black")
    history = trace.pixel_history(0, 0)
    assert len(history) == 0 and history.before is None
    assert str(history) == "pixel (0, 0): 0 fragment(s); the draw did not touch it"
