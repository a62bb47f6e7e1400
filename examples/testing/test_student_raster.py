"""The tests a course would run on a student's rasterizer, with softpipe.testing as the key.

Every test runs on both rasterizers of student_raster.py: "fixed" passes them
all, "naive" (``>= 0`` on every edge) fails three kinds, on purpose; run
``pytest examples/testing`` to read how they fail.
"""
import numpy as np
import pytest
import student_raster

from softpipe.testing import assert_pixels_equal, coverage, covered_pixels, from_ascii, reference_coverage

RASTERIZERS = {"fixed": student_raster.fixed_triangle, "naive": student_raster.naive_triangle}


@pytest.fixture(params=sorted(RASTERIZERS))
def triangle(request):
    return RASTERIZERS[request.param]


def mask_of(pixels, width, height):
    """A set of (x, y) window pixels (y up) as an image mask (row 0 at the top), as coverage gives it."""
    mask = np.zeros((height, width), bool)
    for x, y in pixels:
        mask[height - 1 - y, x] = True
    return mask


def test_a_right_triangle_covers_these_pixels(triangle):
    # The hypotenuse runs through the centres of (3, 0), (2, 1), (1, 2) and (0, 3):
    # a right edge, which does not own them.
    got = mask_of(triangle((0, 0), (4, 0), (0, 4), 5, 5), 5, 5)
    assert_pixels_equal(got, from_ascii("""
        .....
        .....
        #....
        ##...
        ###..
    """))


def test_the_same_pixels_as_a_list(triangle):
    assert sorted(triangle((0, 0), (4, 0), (0, 4), 5, 5)) == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (2, 0)]


def test_two_triangles_sharing_an_edge_draw_every_pixel_once(triangle):
    # A square split along its diagonal, which passes through the centres of (0, 0), (1, 1), (2, 2), (3, 3).
    lower, upper = [(0, 0), (4, 0), (4, 4)], [(0, 0), (4, 4), (0, 4)]
    times = np.zeros((4, 4), np.int64)
    for tri in (lower, upper):
        times += mask_of(triangle(*tri, 4, 4), 4, 4)
    assert_pixels_equal(times, coverage(lower + upper, 4, 4).count)     # 1 everywhere


# Corners on half pixels: many pixel centres lie exactly on edges, where the fill rule decides.
TRIANGLES = [np.random.default_rng(seed).integers(0, 17, size=(3, 2)) / 2 for seed in range(8)]


@pytest.mark.parametrize("tri", TRIANGLES, ids=lambda t: "-".join(f"{x:g},{y:g}" for x, y in t))
def test_random_triangles_cover_what_opengl_covers(triangle, tri):
    got = mask_of(triangle(*tri, 8, 8), 8, 8)
    assert_pixels_equal(got, coverage(tri, 8, 8))


def test_against_the_exact_reference(triangle):
    # reference_coverage does not use softpipe's rasterizer at all: exact fractions, every pixel.
    tri = [(0.75, 0.5), (6.5, 2.5), (2.5, 5.5)]
    got = mask_of(triangle(*tri, 7, 6), 7, 6)
    assert_pixels_equal(got, reference_coverage(tri, 7, 6))
    assert sorted(triangle(*tri, 7, 6)) == covered_pixels(tri, 7, 6)
