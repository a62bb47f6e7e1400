"""The trace of a draw of points or lines (issue 29): pixel history, debug_fragment, before_at and the
fast path's trace answer for a line or a point as they do for a triangle.

Every check is exact: the Python re-run of the shader (``debug_fragment``) gives the compiled
shader's output bit for bit (so ``frag.point_coord`` and a line's barycentrics arrive alike),
``before_at`` gives the clear color at every pixel of a point's square and a wide line's runs,
and the history's t and gl_PointCoord are the shader's.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.sampling import pattern_named
from softpipe.testing import reference_line, reference_line_parameter, reference_point

W, H = 24, 16
CLEAR = (0.2, 0.3, 0.4, 1.0)


def clip(points):
    p = np.asarray(points, dtype=float)
    return np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, np.zeros(len(p)), np.ones(len(p))])


def where(varyings, uniforms, frag):
    """Shows what the shader was given: gl_PointCoord (a line's t, 0) and an interpolated varying."""
    s, t = frag.point_coord
    return (s, t, varyings.color[0], 1.0)


DRAWS = {
    "points": ([(4.5, 4.5), (13.2, 9.7), (20.1, 3.3)], dict(point_size=7)),
    "lines": ([(2.5, 2.5), (21.3, 13.6), (3.7, 12.2), (17.9, 1.4)], dict(line_width=3)),
    "line_strip": ([(2.5, 2.5), (21.3, 13.6), (3.7, 12.2), (17.9, 1.4)], dict()),
    "polygon mode line": ([(2.5, 2.5), (21.3, 4.6), (8.7, 14.2)], dict(polygon_mode="line")),
    "polygon mode point": ([(2.5, 2.5), (21.3, 4.6), (8.7, 14.2)], dict(polygon_mode="point", point_size=3)),
}


def traced(name, path="reference", samples=None):
    points, state = DRAWS[name]
    topology = "triangles" if name.startswith("polygon") else name
    fb = sp.Framebuffer(W, H, pattern_named(samples)) if samples else sp.Framebuffer(W, H)
    fb.clear(CLEAR)
    color = np.linspace(0.1, 0.9, len(points))[:, None] * np.ones((1, 3))
    trace = sp.draw(fb, clip(points), topology=topology, varyings={"color": color}, fragment_shader=where,
                    depth_test=None, path=path, trace=True, **state)
    return fb, trace


@pytest.mark.parametrize("name", list(DRAWS))
def test_debug_fragment_is_the_compiled_shader_on_every_fragment_of_points_and_lines(name):
    fb, trace = traced(name)
    assert len(trace) > 0
    for k in range(len(trace)):
        again = np.float32(trace.debug_fragment(0, 0, index=k))
        assert np.array_equal(again, trace.shaded.color[k]), (k, again, trace.shaded.color[k])


@pytest.mark.parametrize("name", ["points", "lines", "polygon mode line"])
def test_the_fast_path_trace_of_points_and_lines_debugs_to_the_framebuffer(name):
    fb, trace = traced(name, path="fast")
    assert trace.path == "fast" and len(trace) > 0
    f = trace.fragments
    for k in range(len(trace)):
        again = np.float32(trace.debug_fragment(0, 0, index=k))
        assert np.array_equal(again, fb.samples_color[f.sample[k], f.y[k], f.x[k]])
    ref_fb, ref = traced(name)
    assert np.array_equal(fb.color, ref_fb.color)
    # the fast path keeps one fragment per written pixel: the reference path's last written there
    written = ref.written()
    assert sorted(zip(f.x.tolist(), f.y.tolist())) == sorted(set(zip(ref.fragments.x[written].tolist(),
                                                                    ref.fragments.y[written].tolist())))


@pytest.mark.parametrize("name", ["points", "lines"])
def test_before_at_a_points_square_and_a_wide_lines_runs_is_the_color_before_the_draw(name):
    fb, trace = traced(name)
    f = trace.fragments
    assert len(f)
    for x, y in set(zip(f.x.tolist(), f.y.tolist())):
        color, depth = trace.before_at(x, y)
        assert np.array_equal(color, np.float32([CLEAR])), (x, y, color)
        assert trace.pixel_history(x, y).before == CLEAR or np.allclose(trace.pixel_history(x, y).before, CLEAR)


def test_pixel_history_of_a_point_names_the_point_and_its_point_coord():
    fb, trace = traced("points")
    # point 0 at (4.5, 4.5), size 7: its square [1, 8) × [1, 8); window pixel (2, 6) → image row H − 1 − 6
    assert (2, 6) in reference_point((4.5, 4.5), 7)
    history = trace.pixel_history(2, H - 1 - 6)
    assert len(history) == 1 and history.kind == "points"
    event = history[0]
    assert event.primitive_id == 0
    # gl_PointCoord: (x − left) / size, (top − y) / size, at the pixel centre (2.5, 6.5)
    assert event.point_coord == pytest.approx((1.5 / 7, 1.5 / 7), abs=1e-15)
    assert event.color[:2] == pytest.approx(event.point_coord)
    text = str(history).splitlines()
    assert text[1].split() == ["#", "point", "sample", "depth", "point", "coord", "color", "shader", "output",
                               "merger", "color", "after"]
    assert "(0.2143, 0.2143)" in text[3]


def test_pixel_history_of_a_line_names_the_line_and_its_t():
    fb, trace = traced("line_strip")
    a, b = DRAWS["line_strip"][0][1:3]             # the strip's second line: (21.3, 13.6) → (3.7, 12.2)
    pixel = sorted(reference_line(a, b) - reference_line(*DRAWS["line_strip"][0][:2]))[5]
    history = trace.pixel_history(pixel[0], H - 1 - pixel[1])
    assert [e.primitive_id for e in history] == [1]
    t = float(reference_line_parameter(a, b, pixel))
    assert history[0].point_coord[0] == pytest.approx(t, abs=1e-12) and history[0].point_coord[1] == 0.0
    head = str(history).splitlines()[1].split()
    assert head[:5] == ["#", "line", "sample", "depth", "t"]


def test_pixel_history_of_a_triangles_edge_in_polygon_mode_names_the_triangle():
    fb, trace = traced("polygon mode line")
    x, y = int(trace.fragments.x[0]), int(trace.fragments.y[0])
    head = str(trace.pixel_history(x, y)).splitlines()[1].split()
    assert head[:5] == ["#", "triangle", "sample", "depth", "t"]


def test_a_triangles_pixel_history_table_is_unchanged():
    fb = sp.Framebuffer(W, H)
    trace = sp.draw(fb, clip([(1, 1), (20, 2), (5, 14)]), varyings={"color": np.ones((3, 3))}, trace=True)
    head = str(trace.pixel_history(5, 10)).splitlines()[1].split()
    assert head[:4] == ["#", "prim", "sample", "depth"] and head[4] == "color"
    assert trace.pixel_history(5, 10)[0].point_coord == ()


def test_a_multisampled_line_trace_has_a_fragment_per_sample():
    fb, trace = traced("lines", samples="rgss4")
    f = trace.fragments
    hits = set(zip(f.x.tolist(), f.y.tolist(), f.triangle.tolist()))
    assert len(trace) == 4 * len(hits)          # GL without MULTISAMPLE: every sample of the line's pixel
    for x, y, line in hits:
        here = trace.at(x, y)
        assert sorted(f.sample[here[f.triangle[here] == line]].tolist()) == [0, 1, 2, 3]


def test_steps_of_a_line_draw_yield_every_stage_and_leave_the_draws_pixels():
    points, state = DRAWS["lines"]
    fb_run, fb_steps = sp.Framebuffer(W, H), sp.Framebuffer(W, H)
    kwargs = dict(topology="lines", varyings={"color": np.ones((4, 3))}, depth_test=None, **state)
    sp.draw(fb_run, clip(points), **kwargs)
    from softpipe.pipeline.draw import DrawCall
    call = DrawCall(fb_steps, clip(points), **kwargs)
    names = [stage.name for stage in call.steps()]
    assert names[:2] == ["vertex", "assembly"] and "raster" in names and names[-1] == "output"
    assert np.array_equal(fb_run.color, fb_steps.color)
