"""The output merger's new state in the debugger's views (issue 30, "everywhere"): the stencil buffer as a
stage picture, a picture of which test stopped the fragments, and the explorer's stencil column.

Each expectation is computed from the trace (the verdicts, the stencil buffer), not read back from the
picture code.
"""
import numpy as np
from conftest import window_to_clip

import softpipe as sp
from softpipe.views.explorer import read_explorer, write_explorer
from softpipe.views.pictures import TEST_COLORS, id_colors, stage_pictures

W, H = 12, 8


def two_quads():
    """A quad over the left two thirds, then one over the right two thirds: 4 columns overlap."""
    def quad(x0, x1, depth):
        corners = [(x0, 0), (x1, 0), (x1, H), (x0, 0), (x1, H), (x0, H)]
        return window_to_clip([(x, y, 2 * depth - 1) for x, y in corners], W, H)
    pos = np.concatenate([quad(0, 8, 0.5), quad(4, 12, 0.25)])
    return pos, {"color": np.tile([0.5, 0.75, 1.0, 1.0], (12, 1))}


def traced_stencil_draw():
    fb = sp.Framebuffer(W, H).clear(stencil=1)
    fb.stencil[:, 10:] = 5                        # the last two columns fail "equal 1"
    pos, var = two_quads()
    trace = sp.draw(fb, pos, varyings=var, trace=True, scissor=(0, 2, W, H - 2),
                    stencil=sp.Stencil(func="equal", ref=1, depth_pass="incr", fail="zero"))
    return fb, trace


def test_the_stencil_picture_shows_each_stencil_value_in_its_own_color():
    fb, trace = traced_stencil_draw()
    pics = stage_pictures(trace)
    s = fb.stencil
    # rows 0–5 (window rows 2–7) inside the scissor: columns 0–3 the first quad (1 → 2); 4–7 both (the
    # second fails "equal 1" against 2: fail → zero); 8–9 the second (1 → 2); 10–11 stored 5 fail: zero;
    # rows 6–7 scissored: unchanged
    assert s[:6].tolist() == [[2] * 4 + [0] * 4 + [2] * 2 + [0] * 2] * 6
    assert (s[6:, :10] == 1).all() and (s[6:, 10:] == 5).all()
    want = np.where(s[..., None] > 0, id_colors(s.reshape(-1).astype(np.int64)).reshape(H, W, 3), 0)
    assert np.array_equal(pics["stencil"], want)


def test_the_tests_picture_shows_the_last_verdict_at_each_pixel():
    fb, trace = traced_stencil_draw()
    pics = stage_pictures(trace)
    f, v = trace.fragments, trace.verdicts
    for x in range(W):
        for y in range(H):
            here = np.flatnonzero((f.x == x) & (f.y == y))
            assert len(here), (x, y)                          # both quads together cover every pixel
            assert tuple(pics["tests"][y, x]) == TEST_COLORS[v[here[-1]]], (x, y)
    assert set(v) == {"written", "scissored", "stencil-failed"}


def test_a_draw_without_the_new_tests_keeps_its_usual_sheet():
    fb = sp.Framebuffer(W, H)
    pos, var = two_quads()
    pics = stage_pictures(sp.draw(fb, pos, varyings=var, trace=True))
    assert "stencil" not in pics and "tests" not in pics


def test_the_explorer_holds_each_fragments_stencil_before_and_after_as_pixel_history(tmp_path):
    fb, trace = traced_stencil_draw()
    data = read_explorer(write_explorer(trace, tmp_path / "page.html").path)
    assert data.meta["draws"][0]["stencil"] is True
    assert "stencil" in [p["name"] for p in data.meta["pictures"]]
    checked = 0
    for x in range(W):
        for y in range(H):
            history = trace.pixel_history(x, y)
            rows = data.history(x, y)
            assert [r["stencil"] for r in rows] == [e.stencil for e in history], (x, y)
            assert [r["verdict"] for r in rows] == [e.verdict for e in history]
            checked += len(rows)
    assert checked == len(trace.fragments)
    page = (tmp_path / "page.html").read_text()
    assert "anyStencil" in page                              # the page draws the column
