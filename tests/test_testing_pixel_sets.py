"""softpipe.testing takes what users have: sets and lists of (x, y) pixels, masks, images (issue #32).

A set of (x, y) pixels in window coordinates, y up (as ``covered_pixels`` gives
them), is compared as a mask the size of the other side; the message says how it
was read. A list of two pairs is pixels, never a 2×2 image.
"""
import numpy as np
import pytest

from softpipe.testing import assert_pixels_equal, from_ascii

ORIENTATION = ("(x, y) in window coordinates, y up, as covered_pixels gives them: pixel (x, y) is column x, "
               "row height - 1 - y of the image (for y counted down from the top, pass (x, height - 1 - y))")
TRIANGLE = from_ascii("""
    ..#.
    .##.
    ....
""")
PIXELS = [(2, 2), (1, 1), (2, 1)]                   # y up: (2, 2) is the top row's


@pytest.mark.parametrize("pixels", [set(PIXELS), frozenset(PIXELS), PIXELS, tuple(PIXELS), PIXELS[::-1] + PIXELS,
                                    [list(p) for p in PIXELS], [(np.int64(x), np.int32(y)) for x, y in PIXELS]])
def test_a_set_or_list_of_pixels_equals_its_mask(pixels):
    assert_pixels_equal(pixels, TRIANGLE)
    assert_pixels_equal(TRIANGLE, pixels)
    assert_pixels_equal(pixels, set(PIXELS))


def test_a_missing_pixel_is_shown_with_the_orientation_said():
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal({(2, 2), (1, 1)}, TRIANGLE)      # (2, 1), row 1, is missing
    assert str(info.value) == "\n".join([
        "1 of 12 pixels differ (tolerance 0)",
        f"actual is a set of 2 pixels {ORIENTATION}",
        "differences in x 2, y 1 (x: column from the left, y: row from the top)",
        "first differing pixel x=2, y=1: actual False, expected True",
        "map of x 1..3, y 0..2 (# both, + actual only, - expected only, . neither):",
        "  0 .#.", "  1 #-.", "  2 ..."])


def test_a_list_of_two_pairs_is_pixels_not_a_2x2_image():
    assert_pixels_equal([(0, 1), (1, 0)], from_ascii("#.\n.#"))          # pixels (0, 1) and (1, 0), y up
    with pytest.raises(AssertionError, match=r"^4 of 4 pixels differ"):
        assert_pixels_equal([(0, 1), (1, 0)], from_ascii(".#\n#."))      # as an image it would equal this


def test_a_pixel_outside_the_image_is_named():
    with pytest.raises(ValueError) as info:
        assert_pixels_equal([(5, 0)], TRIANGLE)
    assert str(info.value) == f"actual holds the pixel (5, 0), outside the 4×3 image (x 0..3, y 0..2); pixels are " \
                              f"{ORIENTATION}"


def test_pixels_against_a_color_image_are_refused_with_what_to_pass():
    with pytest.raises(TypeError) as info:
        assert_pixels_equal(set(PIXELS), np.zeros((3, 4, 3), np.uint8))
    assert str(info.value) == ("actual is a set of pixels and expected an image (uint8): a set of pixels is "
                               "compared with a mask: a bool array [H, W], a Coverage, or an ASCII picture of '#' "
                               "and '.'")


def test_a_set_holding_something_else_is_named():
    with pytest.raises(TypeError, match=r"^expected is a set of pixels, each an \(x, y\) pair of integers; "
                                        r"it holds \(1\.5, 2\)$"):
        assert_pixels_equal(TRIANGLE, {(1.5, 2)})


def test_covered_pixels_compare_with_coverage_as_they_are():
    from softpipe.testing import coverage, covered_pixels
    triangle = [(0, 0), (4, 0), (0, 4)]
    assert_pixels_equal(covered_pixels(triangle, 5, 5), coverage(triangle, 5, 5))
    assert_pixels_equal(set(covered_pixels(triangle, 5, 5)), coverage(triangle, 5, 5).mask)


def test_a_mask_may_be_given_as_pixels():
    image = np.zeros((3, 4), np.uint8)
    other = image.copy()
    other[2, 3] = 9                                  # outside the compared pixels
    assert_pixels_equal(image, other, mask=set(PIXELS))
    with pytest.raises(AssertionError, match=r"^1 of 3 pixels differ"):
        other[1, 2] = 9
        assert_pixels_equal(image, other, mask=set(PIXELS))
