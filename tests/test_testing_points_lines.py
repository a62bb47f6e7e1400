"""softpipe.testing's coverage of lines and points (issue 29): built on softpipe's own pipeline, it
gives exactly the pixels of the independent exact references (reference_line, reference_point,
written from the GL specification) on hundreds of random segments and points, including the
rule's corner cases (ends on pixel centres, edges and corners, short, axis-aligned and 45°
segments; sizes below 1), and it is what ``softpipe.draw`` draws.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.testing import coverage, covered_pixels, reference_line, reference_point

W, H = 20, 14


def inside(pixels, w=W, h=H):
    return {(x, y) for x, y in pixels if 0 <= x < w and 0 <= y < h}


def special_coordinate(rng, n):
    """Mostly on the 1/256 grid, often on a centre (k + ½), an edge (k) or a diamond's corner."""
    kind = rng.integers(0, 4, n)
    base = rng.integers(-2, W + 2, n).astype(float)
    return np.where(kind == 0, base + 0.5, np.where(kind == 1, base, np.where(
        kind == 2, base + rng.integers(0, 256, n) / 256, base + rng.random(n))))


def random_segments(seed, n=300):
    rng = np.random.default_rng(seed)
    a = np.column_stack([special_coordinate(rng, n), special_coordinate(rng, n) * H / W])
    d = rng.integers(0, 5, n)
    step = rng.integers(-6, 7, (n, 2)).astype(float)
    b = np.where(d[:, None] == 0, a + np.column_stack([step[:, 0], np.zeros(n)]),            # horizontal
                 np.where(d[:, None] == 1, a + np.column_stack([np.zeros(n), step[:, 1]]),   # vertical
                          np.where(d[:, None] == 2, a + step[:, :1],                          # 45°
                                   np.where(d[:, None] == 3, a + rng.random((n, 2)) * 0.8,    # short
                                            np.column_stack([special_coordinate(rng, n),
                                                             special_coordinate(rng, n) * H / W])))))
    return a, b


@pytest.mark.parametrize("width", [1, 2, 3])
def test_line_coverage_is_the_exact_reference_on_hundreds_of_random_segments(width):
    a, b = random_segments(seed=width)
    for k in range(len(a)):
        got = set(covered_pixels([a[k], b[k]], W, H, topology="lines", line_width=width))
        want = inside(reference_line(tuple(a[k]), tuple(b[k]), width))
        assert got == want, (k, tuple(a[k]), tuple(b[k]), sorted(got ^ want))


def test_point_coverage_is_the_exact_reference_on_hundreds_of_random_points():
    rng = np.random.default_rng(7)
    n = 400
    p = np.column_stack([special_coordinate(rng, n) % W, special_coordinate(rng, n) % H])
    sizes = rng.choice([0.75, 1, 1.5, 2, 2.5, 3, 4.25, 5, 7], n)
    for k in range(n):
        got = set(covered_pixels([p[k]], W, H, topology="points", point_size=sizes[k]))
        want = inside(reference_point(tuple(p[k]), sizes[k]))
        assert got == want, (k, tuple(p[k]), sizes[k], sorted(got ^ want))


def test_a_point_whose_centre_is_outside_the_image_is_discarded_as_draw_does():
    assert covered_pixels([(-0.25, 5.0)], W, H, topology="points", point_size=5) == []
    assert covered_pixels([(0.0, 5.0)], W, H, topology="points", point_size=3) == [(0, 3), (0, 4), (0, 5)]


def test_a_closed_line_loop_covers_every_pixel_once():
    corners = [(1.5, 1.5), (17.5, 2.5), (15.5, 11.5), (3.5, 9.5)]
    cov = coverage(corners, W, H, topology="line_loop")
    assert cov.count.max() == 1 and cov.kind == "lines"
    strip = coverage(corners + corners[:1], W, H, topology="line_strip")
    assert np.array_equal(cov.mask, strip.mask)
    want = set().union(*(reference_line(p, q) for p, q in zip(corners, corners[1:] + corners[:1])))
    assert set(cov.pixels()) == inside(want)
    # the last line drawn at a pixel names it: window pixel (x, y) is row H − 1 − y
    assert cov.primitive_id[H - 1 - 1, 1] == 0 and cov.primitive_id[H - 1 - 2, 17] == 1


@pytest.mark.parametrize("topology, state", [("lines", {}), ("line_strip", {"line_width": 3}),
                                             ("line_loop", {}), ("points", {"point_size": 4})])
def test_clip_space_coverage_of_lines_and_points_is_what_draw_draws(topology, state):
    rng = np.random.default_rng(11)
    clip = np.column_stack([rng.uniform(-1.3, 1.3, (8, 2)), np.zeros(8), np.ones(8)])
    cov = coverage(clip, W, H, space="clip", topology=topology, **state)
    fb = sp.Framebuffer(W, H)
    sp.draw(fb, clip, topology=topology, varyings={"color": np.ones((8, 3))}, depth_test=None, **state)
    assert np.array_equal(cov.mask, fb.color[:, :, 0] > 0)
    assert cov.mask.any()


def test_a_line_covers_every_sample_of_its_pixels():
    cov = coverage([(1.5, 1.5), (12.5, 7.5)], W, H, topology="lines", samples="rgss4")
    assert cov.mask.shape == (H, W, 4)
    assert (cov.mask.all(axis=2) == cov.mask.any(axis=2)).all()
    assert {(x, y) for x, y, _ in cov.pixels()} == inside(reference_line((1.5, 1.5), (12.5, 7.5)))


def test_grouped_and_indexed_lines():
    pairs = np.array([[(1, 1), (9, 5)], [(9, 5), (18, 1)]], dtype=float)
    assert coverage(pairs, W, H, topology="lines").pixels() == \
        coverage(pairs.reshape(-1, 2), W, H, topology="lines").pixels()
    indexed = coverage([(1, 1), (9, 5), (18, 1)], W, H, topology="lines", indices=[0, 1, 1, 2])
    assert indexed.pixels() == coverage(pairs, W, H, topology="lines").pixels()
    assert repr(indexed) == f"Coverage(20×14, {len(indexed.pixels())} pixels covered by 2 lines)"


@pytest.mark.parametrize("call, kind, message", [
    (lambda: coverage([(0, 0), (1, 0), (2, 2)], 4, 4, topology="lines"), ValueError,
     "positions (no indices): a line list needs an even number of vertices, got 3"),
    (lambda: coverage([(0, 0), (1, 0)], 4, 4, topology="polyline"), ValueError,
     "topology must be one of ('points', 'lines', 'line_strip', 'line_loop', 'triangles', 'triangle_strip', "
     "'triangle_fan'), got 'polyline'"),
    (lambda: coverage([(0, 0), (1, 0)], 4, 4, topology="lines", line_width=0), ValueError,
     "line_width must be a finite number of pixels > 0, got 0"),
    (lambda: coverage([(0, 0)], 4, 4, topology="points", point_size="big"), ValueError,
     "point_size must be a number of pixels, got 'big'"),
    (lambda: coverage(np.zeros((2, 3, 2)), 4, 4, topology="lines"), ValueError,
     "positions must have shape [N, 2] or [N, 3] or [L, 2, 2|3] (window coordinates in pixels, space='window'), "
     "got [2, 3, 2]"),
    (lambda: coverage([(0, 0), (1, np.nan)], 4, 4, topology="lines"), ValueError,
     "positions must be finite; row 1 is [1.0, nan]"),
])
def test_bad_line_and_point_input_gets_a_one_line_error_naming_it(call, kind, message):
    with pytest.raises(kind) as info:
        call()
    assert str(info.value) == message
