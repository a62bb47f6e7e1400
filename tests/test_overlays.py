"""RenderDoc's overlays (issue 34): triangle size, depth test pass/fail, clipped and culled triangles. Each
is checked against counts computed here from the trace's fragments, pixel by pixel."""
import numpy as np
import pytest
from conftest import window_to_clip
from test_trace import scene_call

import softpipe as sp
from softpipe.views.explorer import write_explorer
from softpipe.views.overlays import (
    DEPTH_TEST_COLORS,
    OVERLAYS,
    SIZE_STOPS,
    clipped_and_culled,
    depth_test_counts,
    depth_test_picture,
    overlay_pictures,
    size_colors,
    triangle_size,
)
from softpipe.views.pictures import CYAN, RED, draw_triangle_outlines, stage_pictures


@pytest.fixture(scope="module")
def trace():
    """Two spheres and a ground plane crossing the near plane, back faces culled: clipped pieces, culled
    triangles, depth-failed fragments."""
    t = scene_call(sp.Framebuffer(64, 48)).run(trace=True)
    assert t.primitives.clipped.any() and len(t.primitives.culled_window) and (t.verdicts == "depth-failed").any()
    return t


def _last_written(trace, x, y):
    idx = trace.at(x, y)
    idx = idx[trace.merged.verdict[idx] == 0]
    return int(idx[-1]) if len(idx) else None


def test_triangle_size_is_the_fragment_count_of_the_triangle_last_written(trace):
    size = triangle_size(trace)
    f = trace.fragments
    seen = set()
    for y in range(trace.height):
        for x in range(trace.width):
            k = _last_written(trace, x, y)
            want = 0 if k is None else int((f.primitive_id == f.primitive_id[k]).sum())
            assert size[y, x] == want, (x, y)
            seen.add(want)
    assert len(seen) > 5                        # triangles of many sizes
    assert np.array_equal(overlay_pictures(trace)["triangle size"], size_colors(size))


def test_triangle_size_counts_pixels_not_samples():
    pos = window_to_clip([(0, 0), (8, 0), (0, 8)], 8, 8)
    one = sp.draw(sp.Framebuffer(8, 8), pos, varyings={"color": np.ones((3, 4))}, trace=True)
    four = sp.draw(sp.Framebuffer(8, 8, sp.rotated_grid_4x()), pos, varyings={"color": np.ones((3, 4))},
                   trace=True)
    assert len(four) > 3 * len(one)
    assert triangle_size(four).max() == len(four) / 4 and triangle_size(one).max() == len(one)


def test_size_colors_are_the_stops_on_a_log_scale():
    got = size_colors(np.array([0.0, 0.5, 1.0, 4.0, 8.0, 1024.0, 5000.0]))
    stops = dict(SIZE_STOPS)
    assert got[0].tolist() == [0, 0, 0]
    assert got[1].tolist() == list(stops[1]) == got[2].tolist()
    assert got[3].tolist() == list(stops[4])
    assert got[4].tolist() == [round((a + b) / 2) for a, b in zip(stops[4], stops[16])]   # halfway in log2
    assert got[5].tolist() == got[6].tolist() == list(stops[1024])


def test_depth_test_counts_and_colors_each_pixels_fragments(trace):
    passed, failed = depth_test_counts(trace)
    img = depth_test_picture(trace)
    v = trace.verdicts
    colors = {(True, False): DEPTH_TEST_COLORS["passed"], (False, True): DEPTH_TEST_COLORS["failed"],
              (True, True): DEPTH_TEST_COLORS["both"], (False, False): (0, 0, 0)}
    kinds = set()
    for y in range(trace.height):
        for x in range(trace.width):
            here = v[trace.at(x, y)]
            p, q = int((here == "written").sum()), int((here == "depth-failed").sum())
            assert (passed[y, x], failed[y, x]) == (p, q), (x, y)
            assert tuple(img[y, x]) == colors[(p > 0, q > 0)], (x, y)
            kinds.add((p > 0, q > 0))
    assert kinds == set(colors) - {(False, True)}     # a draw into a cleared depth buffer: some fragment passes


def test_clipped_pieces_are_cyan_and_culled_triangles_red_over_the_final_picture(trace):
    img = clipped_and_culled(trace)
    outline = np.zeros_like(img)
    draw_triangle_outlines(outline, trace.primitives.culled_window, trace.height, RED)
    nothing = np.ones(outline.shape[:2], bool)
    cyan = np.zeros(nothing.shape, bool)
    for y in range(trace.height):
        for x in range(trace.width):
            k = _last_written(trace, x, y)
            nothing[y, x] = k is None
            cyan[y, x] = k is not None and trace.primitives.clipped[trace.fragments.triangle[k]]
    red = outline.any(axis=2) & nothing                 # culled outlines only where nothing was written
    assert red.sum() > 20 and (outline.any(axis=2) & ~nothing).any()
    assert np.array_equal((img == RED).all(axis=2), red)
    assert cyan.sum() > 20 and np.array_equal((img == CYAN).all(axis=2), cyan)
    rest = ~red & ~cyan
    assert np.array_equal(img[rest], trace.call.framebuffer.to_uint8(alpha=False)[rest] // 2)


def two_draws():
    """A near quad over the left two thirds, then a far one over the right two thirds, two draws."""
    W, H = 12, 8
    fb = sp.Framebuffer(W, H)

    def quad(x0, x1, depth):
        corners = [(x0, 0), (x1, 0), (x1, H), (x0, 0), (x1, H), (x0, H)]
        pos = window_to_clip([(x, y, 2 * depth - 1) for x, y in corners], W, H)
        return sp.draw(fb, pos, varyings={"color": np.ones((6, 4))}, trace=True)
    return [quad(0, 8, 0.25), quad(4, 12, 0.5)]


def test_a_scenes_overlays_count_over_its_draws():
    draws = two_draws()
    passed, failed = depth_test_counts(draws)
    assert (passed == 1).all()                              # each pixel: one fragment written
    assert (failed[:, 4:8] == 1).all() and not failed[:, :4].any() and not failed[:, 8:].any()
    size = triangle_size(draws)
    assert (size[:, :8] > 0).all() and (size[:, 8:] > 0).all()
    pics = overlay_pictures(draws)
    assert list(pics) == list(OVERLAYS)
    assert (pics["depth test"][:, 4:8] == DEPTH_TEST_COLORS["both"]).all()
    alone = depth_test_picture(draws[1])                    # the far quad's draw: only failed where they overlap
    assert (alone[:, 4:8] == DEPTH_TEST_COLORS["failed"]).all() and (alone[:, 8:] == DEPTH_TEST_COLORS["passed"]).all()
    assert not alone[:, :4].any()


def test_overlays_are_in_the_explorer_when_asked_and_not_on_the_default_sheet(tmp_path):
    draws = two_draws()
    assert not set(OVERLAYS) & set(stage_pictures(draws[0]))
    with_them = write_explorer(draws, tmp_path / "a.html", overlays=True).path.read_text()
    without = write_explorer(draws, tmp_path / "b.html").path.read_text()
    for name in OVERLAYS:
        assert f'alt="{name}"' in with_them and f'alt="{name}"' not in without
    with pytest.raises(TypeError, match="overlays: item 0: expected a Trace or a DrawResult drawn with trace=True, "
                                        "got str"):
        overlay_pictures(["trace"])
