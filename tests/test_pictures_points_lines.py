"""Stage pictures of draws of points and lines, and of triangles in polygon mode (issue 29).

What can be said exactly is tested exactly: the "primitives" picture of a draw of lines lights
the pixels GL's rule gives each segment (softpipe.testing.reference_line, written from the
specification), of points the border of each point's square (reference_point), and in polygon
mode it is the picture the same triangles drawn filled have.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.sampling import pattern_named
from softpipe.testing import reference_line, reference_point
from softpipe.views.pictures import CYAN, ORANGE, WHITE, overdraw

W, H = 48, 32
P = [(4.5, 4.5), (40.3, 27.6), (8.7, 26.2), (36.9, 3.4), (44.2, 16.1), (24.0, 20.0)]


def clip(points, z=None):
    p = np.asarray(points, dtype=float)
    z = np.zeros(len(p)) if z is None else np.asarray(z, dtype=float)
    return np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, z, np.ones(len(p))])


def pictures(points, topology, samples=None, z=None, **state):
    fb = sp.Framebuffer(W, H, pattern_named(samples)) if samples else sp.Framebuffer(W, H)
    trace = sp.draw(fb, clip(points, z), topology=topology, varyings={"color": np.ones((len(points), 3))},
                    trace=True, **state)
    return trace, trace.pictures()


def lit(img, color=None):
    """The window pixels (x, y), y up, of ``img`` that are lit (in ``color``, if given)."""
    mask = img.any(axis=2) if color is None else (img == np.array(color, np.uint8)).all(axis=2)
    rows, cols = np.nonzero(mask)
    return set(zip(cols.tolist(), (H - 1 - rows).tolist()))


def inside(pixels):
    return {(x, y) for x, y in pixels if 0 <= x < W and 0 <= y < H}


@pytest.mark.parametrize("topology, width", [("lines", 1), ("line_strip", 1), ("line_loop", 3), ("lines", 2)])
def test_the_primitives_picture_of_lines_is_gls_pixels_of_each_segment(topology, width):
    trace, pics = pictures(P if topology != "lines" else P[:4], topology, line_width=width)
    pts = P if topology != "lines" else P[:4]
    segments = {"lines": list(zip(pts[0::2], pts[1::2])), "line_strip": list(zip(pts, pts[1:])),
                "line_loop": list(zip(pts, pts[1:] + pts[:1]))}[topology]
    expected = inside(set().union(*(reference_line(a, b, width) for a, b in segments)))
    assert lit(pics["primitives"], WHITE) == expected
    assert lit(pics["primitives"]) == expected            # nothing else: no second pass from b back to a
    assert lit(pics["coverage"]) == expected


@pytest.mark.parametrize("size", [1, 2, 5, 7.5])
def test_the_primitives_picture_of_points_is_the_border_of_each_square(size):
    trace, pics = pictures(P, "points", point_size=size)
    expected = set()
    for p in P:
        square = reference_point(p, size)
        xs, ys = {x for x, _ in square}, {y for _, y in square}
        expected |= {(x, y) for x, y in square if x in (min(xs), max(xs)) or y in (min(ys), max(ys))}
    assert lit(pics["primitives"], WHITE) == inside(expected)
    covered = inside(set().union(*(reference_point(p, size) for p in P)))
    assert lit(pics["coverage"]) == covered and lit(pics["depth"]) == covered and lit(pics["overdraw"]) == covered


@pytest.mark.parametrize("mode", ["line", "point"])
def test_the_primitives_picture_in_polygon_mode_shows_the_triangles_edges(mode):
    tris = [P[0], P[3], P[4], P[0], P[1], P[2]]
    _, filled = pictures(tris, "triangles", cull="back")
    trace, pics = pictures(tris, "triangles", cull="back", polygon_mode=mode, point_size=3)
    assert trace.primitives.kind == ("lines" if mode == "line" else "points")
    assert np.array_equal(pics["primitives"], filled["primitives"])
    assert lit(pics["primitives"], WHITE) and lit(pics["coverage"])


def test_a_line_clipped_by_the_far_plane_is_cyan_over_its_cut_off_segment_in_orange():
    a, b = (4.5, 4.5), (40.5, 27.5)
    trace, pics = pictures([a, b], "lines", z=[0.0, 3.0])          # z = 3w: beyond the far plane
    assert trace.primitives.clipped.all()
    drawn = set(zip(trace.fragments.x.tolist(), (H - 1 - trace.fragments.y).tolist()))
    assert lit(pics["primitives"], CYAN) == drawn
    assert lit(pics["primitives"], ORANGE) == inside(reference_line(a, b)) - drawn
    assert drawn < inside(reference_line(a, b))


def test_the_overdraw_of_a_multisampled_line_counts_one_per_pixel():
    trace, pics = pictures(P[:2], "lines", samples="rgss4")
    counts = overdraw(trace)
    expected = inside(reference_line(P[0], P[1]))
    assert {(x, H - 1 - r) for r, x in zip(*np.nonzero(counts))} == expected
    assert set(counts[counts > 0].tolist()) == {1.0}


def test_the_vertices_picture_of_points_marks_each_vertex():
    trace, pics = pictures(P, "points", point_size=4)
    dots = lit(pics["vertices"])
    for x, y in P:
        assert (int(x), int(np.floor(y))) in dots or (int(x), int(np.ceil(y)) - 1) in dots
