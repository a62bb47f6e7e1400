"""softpipe.testing: coverage against the rasterizer and the exact reference, the failure
messages word for word, ASCII pictures, the golden fixture in a pytest run, and the
examples in examples/testing (whose naive rasterizer must fail, and fail readably)."""
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from conftest import window_prims
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

import softpipe as sp
from softpipe.pipeline.raster import rasterize
from softpipe.pipeline.sampling import pattern_named
from softpipe.testing import (
    Coverage,
    ascii_picture,
    assert_pixels_equal,
    check_golden,
    coverage,
    covered_pixels,
    from_ascii,
    reference_coverage,
    to_8bit,
)

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples" / "testing"
QUICK = settings(max_examples=40, derandomize=True, deadline=None, database=None)

RIGHT = [(0, 0), (4, 0), (0, 4)]
RIGHT_PICTURE = """
    ....
    #...
    ##..
    ###.
"""


# ------------------------------------------------------------------ coverage

def test_coverage_of_a_right_triangle_by_hand():
    cov = coverage(RIGHT, 4, 4)
    assert isinstance(cov, Coverage) and cov.mask.shape == (4, 4) and cov.mask.dtype == bool
    assert cov.pixels() == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (2, 0)]      # window (x, y), y up
    assert covered_pixels(RIGHT, 4, 4) == cov.pixels()
    assert ascii_picture(cov) == "....\n#...\n##..\n###."
    assert np.array_equal(cov.mask, from_ascii(RIGHT_PICTURE))                    # row 0 is the top
    assert cov.mask[4 - 1 - 0, 2] and not cov.mask[0, 0]                          # window (2, 0) is row 3
    assert np.array_equal(np.asarray(cov), cov.mask)
    assert repr(cov) == "Coverage(4×4, 6 pixels covered by 1 triangle)"
    assert cov.primitive_id[cov.mask].tolist() == [0] * 6 and (cov.primitive_id[~cov.mask] == -1).all()


def test_a_mesh_gives_primitive_ids_and_covers_shared_edges_once():
    # a square split along the diagonal through the pixel centres; then a third triangle over it all
    square = [(0, 0), (4, 0), (4, 4), (0, 0), (4, 4), (0, 4)]
    cov = coverage(square, 4, 4)
    assert (cov.count == 1).all()
    assert ascii_picture(cov.primitive_id) == "1110\n1100\n1000\n0000"
    over = coverage(square + [(-1, -1), (9, -1), (-1, 9)], 4, 4)
    assert (over.primitive_id == 2).all() and (over.count == 2).all()
    indexed = coverage([(0, 0), (4, 0), (4, 4), (0, 4)], 4, 4, indices=[[0, 1, 2], [0, 2, 3]])
    assert np.array_equal(indexed.primitive_id, cov.primitive_id)
    nested = coverage(np.array(square).reshape(2, 3, 2), 4, 4)
    assert np.array_equal(nested.primitive_id, cov.primitive_id)


def test_samples_cull_and_clip_space():
    cov = coverage(RIGHT, 4, 4, samples="rgss4")
    assert cov.mask.shape == (4, 4, 4) and cov.pixels()[0] == (0, 0, 0)
    assert len(covered_pixels(RIGHT, 4, 4, samples=[(0.5, 0.5)])) == 6
    clockwise = RIGHT[::-1]
    assert not coverage(clockwise, 4, 4, cull="back").mask.any()
    assert coverage(clockwise, 4, 4, cull="front").pixels() == covered_pixels(RIGHT, 4, 4)
    assert not coverage(RIGHT, 4, 4, cull="back", front_face="cw").mask.any()
    # clip coordinates: the viewport of the whole image, as softpipe.draw
    clip = [(-1, -1, 0, 1), (1, -1, 0, 1), (-1, 1, 0, 1)]
    assert coverage(clip, 4, 4, space="clip").pixels() == covered_pixels(RIGHT, 4, 4)


def test_clip_space_pieces_keep_their_triangles_id():
    clip = [(-1, -1, -2, 1), (1, -1, 0, 1), (0, 1, 0, 1),     # cut by the near plane into two pieces
            (-1, -1, 0, 1), (1, -1, 0, 1), (-1, 1, 0, 1)]
    cov = coverage(clip, 8, 8, space="clip")
    second = coverage(clip[3:], 8, 8, space="clip").mask
    only_first = cov.mask & ~second
    assert second.any() and only_first.any()
    assert (cov.primitive_id[second] == 1).all() and (cov.primitive_id[only_first] == 0).all()
    assert (cov.primitive_id[~cov.mask] == -1).all()


coordinate = st.one_of(st.integers(-3 * 256, 14 * 256).map(lambda v: v / 256),     # on the snapping grid
                       st.integers(-6, 28).map(lambda v: v / 2),                   # pixel corners and centres
                       st.floats(-3.0, 14.0, allow_nan=False))                     # anything
triangle = st.lists(st.tuples(coordinate, coordinate), min_size=3, max_size=3)


@settings(QUICK, max_examples=150)
@given(tris=st.lists(triangle, min_size=1, max_size=3), w=st.integers(1, 11), h=st.integers(1, 11),
       samples=st.sampled_from([None, "rgss4", "grid4"]))
def test_coverage_is_the_rasterizers_and_the_exact_references(tris, w, h, samples):
    cov = coverage(np.array(tris), w, h, samples=samples)
    pattern = pattern_named(samples) if samples else sp.CENTER
    frags = rasterize(window_prims(tris), w, h, pattern)
    count = np.zeros((h, w, len(pattern)), np.int64)
    np.add.at(count, (frags.y, frags.x, frags.sample), 1)
    assert np.array_equal(cov.count, count if samples else count[:, :, 0])
    ref = reference_coverage([[Fraction(v) for v in p] for tri in tris for p in tri], w, h, samples=samples)
    assert np.array_equal(cov.mask, ref.mask)
    assert np.array_equal(cov.count, ref.count)
    assert np.array_equal(cov.primitive_id, ref.primitive_id)


grid_triangle = st.lists(st.tuples(*[st.integers(-3 * 256, 14 * 256).map(lambda v: v / 256)] * 2),
                         min_size=3, max_size=3)


@QUICK
@given(tris=st.lists(grid_triangle, min_size=1, max_size=4), cull=st.sampled_from(["back", "front"]),
       front_face=st.sampled_from(["ccw", "cw"]))
def test_culling_is_the_exact_references(tris, cull, front_face):
    # corners on the 1/256 grid: the float signed area coverage takes the facing from is exact there
    cov = coverage(np.array(tris), 9, 8, cull=cull, front_face=front_face)
    ref = reference_coverage(np.array(tris), 9, 8, cull=cull, front_face=front_face)
    assert np.array_equal(cov.count, ref.count) and np.array_equal(cov.primitive_id, ref.primitive_id)


@QUICK
@given(tri=st.lists(st.tuples(st.integers(-300, 300), st.integers(-300, 300)), min_size=3, max_size=3),
       cull=st.sampled_from(["none", "back"]))
def test_clip_space_coverage_is_what_draw_draws(tri, cull):
    clip = [(x / 256, y / 256, 0.0, 1.0) for x, y in tri]
    cov = coverage(clip, 9, 7, space="clip", cull=cull)
    fb = sp.Framebuffer(9, 7)
    sp.draw(fb, np.array(clip), varyings={"color": np.ones((3, 3))}, cull=cull)
    assert np.array_equal(cov.mask, fb.color[:, :, 0] > 0)


BAD_CALLS = [
    (lambda: coverage([(0, 0), (1, 0)], 4, 4), ValueError,
     "positions (no indices): a triangle list needs a multiple of 3 vertices, got 2"),
    (lambda: coverage([0, 1, 2], 4, 4), ValueError,
     "positions must have shape [N, 2] or [N, 3] or [T, 3, 2|3] (window coordinates in pixels, space='window'), "
     "got [3]"),
    (lambda: coverage(np.zeros((3, 4)), 4, 4), ValueError,
     "positions must have shape [N, 2] or [N, 3] or [T, 3, 2|3] (window coordinates in pixels, space='window'), "
     "got [3, 4]"),
    (lambda: coverage(np.zeros((3, 2)), 4, 4, space="clip"), ValueError,
     "positions must have shape [N, 4] or [T, 3, 4] (clip coordinates, space='clip'), got [3, 2]"),
    (lambda: coverage([["a", "b"]] * 3, 4, 4), TypeError,
     "positions must be a numeric array (window coordinates in pixels), got dtype <U1"),
    (lambda: coverage([(0, 0), (1, np.nan), (0, 1)], 4, 4), ValueError,
     "positions must be finite; row 1 is [1.0, nan]"),
    (lambda: coverage([(0, 0), (1e6, 0), (0, 1)], 4, 4), ValueError,
     "positions row 1 = [1000000.0, 0.0] lies more than 32768 pixels outside the 4×4 image (the rasterizer's "
     "guard band); pass clip coordinates with space='clip' to have it clipped"),
    (lambda: coverage(RIGHT, 0, 4), ValueError, "width must be in [1, 32768] pixels, got 0"),
    (lambda: coverage(RIGHT, 4, 2.5), TypeError, "height must be an integer number of pixels, got 2.5"),
    (lambda: coverage(RIGHT, 4, 4, cull="back_faces"), ValueError,
     "cull must be one of ('none', 'back', 'front'), got 'back_faces'"),
    (lambda: coverage(RIGHT, 4, 4, space="screen"), ValueError,
     "space must be one of ('window', 'clip'), got 'screen'"),
    (lambda: coverage(RIGHT, 4, 4, samples=[0.5, 0.5]), ValueError,
     "samples: must have shape [S, 2] (positions in the pixel), got [2]"),
    (lambda: coverage(RIGHT, 4, 4, samples="grid5"), ValueError,
     "samples: sample pattern 'grid5': grid needs a square number of samples, got 5"),
    (lambda: coverage(RIGHT, 4, 4, samples=[(0.5, 1.5)]), ValueError,
     "samples: sample positions must lie in [0, 1) × [0, 1)"),
    (lambda: coverage(RIGHT, 8192, 8192, samples="rgss4"), ValueError,
     "a coverage of 8192×8192 pixels × 4 samples is more than MAX_COVERAGE_SAMPLES = 2^26 samples; test on a "
     "smaller image"),
    (lambda: coverage(RIGHT, 4, 4, indices=[[0, 1, 5]]), ValueError,
     "indices[2] = 5 is out of range for 3 vertices"),
    (lambda: reference_coverage([(0, 0), (1, 0)], 4, 4), ValueError,
     "positions (no indices): a triangle list needs a multiple of 3 vertices, got 2"),
    (lambda: reference_coverage([(0, 0, 0, 1)] * 3, 4, 4), ValueError,
     "positions must have shape [N, 2] or [N, 3] or [T, 3, 2|3] (window coordinates in pixels), got [3, 4]"),
    (lambda: reference_coverage([(0, 0), (float("inf"), 0), (0, 1)], 4, 4), ValueError,
     "positions must be finite numbers, got inf"),
    (lambda: assert_pixels_equal(np.zeros((2, 3)), np.zeros((3, 2))), ValueError,
     "actual has shape [2, 3] and expected [3, 2]: they cannot be compared pixel by pixel"),
    (lambda: assert_pixels_equal(np.zeros((2, 2), bool), np.zeros((2, 2), np.uint8)), TypeError,
     "actual is a mask (bool) and expected is not (uint8): compare masks with masks"),
    (lambda: assert_pixels_equal(np.zeros(5), np.zeros(5)), ValueError,
     "actual must be an image [H, W] or [H, W, C] with C ≤ 4 (or a mask [H, W, samples]), got shape [5]"),
    (lambda: assert_pixels_equal(np.zeros((2, 2)), "no/such.png"), FileNotFoundError,
     "expected: no image file at 'no/such.png'"),
    (lambda: assert_pixels_equal(np.zeros((2, 2)), np.zeros((2, 2)), tolerance=-1), ValueError,
     "tolerance must be a finite number ≥ 0, got -1"),
    (lambda: assert_pixels_equal(np.zeros((2, 2)), np.zeros((2, 2)), mask=np.ones((2, 3), bool)), ValueError,
     "mask has shape [2, 3], the images [2, 2]"),
    (lambda: assert_pixels_equal(np.zeros((2, 2)), np.zeros((2, 2)), mask=np.ones((2, 2))), TypeError,
     "mask must be a bool array [H, W] (True: compare this pixel), got dtype float64"),
    (lambda: from_ascii("##.\n#."), ValueError, "picture row 1 has 2 characters and row 0 has 3: every row must "
                                                "be as long"),
    (lambda: from_ascii("#x"), ValueError, "picture uses '#x': without legend= a picture is '#' and '.' (a mask) "
                                           "or digits, letters and '.' (integers)"),
    (lambda: from_ascii("\n  \n"), ValueError, "picture is empty: it needs at least one row of characters"),
    (lambda: from_ascii("#r", legend={"#": 1}), ValueError, "picture uses 'r', which legend does not list"),
    (lambda: ascii_picture(np.full((1, 1), 36)), ValueError,
     "image holds the integer 36; an integer picture shows 0…35 (pass legend= for other values)"),
    (lambda: to_8bit(np.full((1, 1), 300)), ValueError,
     "image holds integers outside 0…255 (300…300); an 8-bit image cannot store them"),
]


@pytest.mark.parametrize("call, kind, message", BAD_CALLS, ids=[m[:40] for _, _, m in BAD_CALLS])
def test_bad_input_gets_a_one_line_error_naming_it(call, kind, message):
    with pytest.raises(kind) as info:
        call()
    assert str(info.value) == message
    assert "\n" not in message


# ------------------------------------------------------- assert_pixels_equal

def test_a_mask_that_differs_is_reported_word_for_word(tmp_path):
    got = coverage(RIGHT, 6, 5)
    want = from_ascii("""
        ......
        #.....
        ##....
        ###...
        ####..
    """)
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal(got, want, diff_path=tmp_path / "diff.png")
    assert str(info.value) == f"""\
4 of 30 pixels differ (tolerance 0)
differences in x 0..3, y 1..4 (x: column from the left, y: row from the top)
first differing pixel x=0, y=1: actual False, expected True
map of x 0..4, y 0..4 (# both, + actual only, - expected only, . neither):
  0 .....
  1 -....
  2 #-...
  3 ##-..
  4 ###-.
diff image: {tmp_path / 'diff.png'}"""
    diff = np.asarray(Image.open(tmp_path / "diff.png"))
    assert diff.shape == (5, 6, 3) and (diff[1, 0] == (255, 0, 0)).all() and (diff[0, 0] != (255, 0, 0)).any()


def test_an_image_that_differs_is_reported_word_for_word():
    actual = np.zeros((4, 5, 3), np.uint8)
    expected = actual.copy()
    expected[2, 3] = (200, 10, 0)
    expected[1, 1] = (0, 2, 0)          # within the tolerance
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal(actual, expected, tolerance=2)
    assert str(info.value) == """\
1 of 20 pixels differ (tolerance 2)
differences in x 3, y 2 (x: column from the left, y: row from the top)
worst pixel x=3, y=2: actual (0, 0, 0), expected (200, 10, 0), difference 200
map of x 2..4, y 1..3 (X differs, . equal):
  1 ...
  2 .X.
  3 ..."""
    assert_pixels_equal(actual, expected, tolerance=200)
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal(actual, expected, mask=from_ascii("#####\n#####\n##...\n#####"))
    assert str(info.value) == """\
1 of 17 pixels differ (tolerance 0; 3 pixels masked out)
differences in x 1, y 1 (x: column from the left, y: row from the top)
worst pixel x=1, y=1: actual (0, 0, 0), expected (0, 2, 0), difference 2
map of x 0..2, y 0..2 (X differs, . equal, ~ masked out):
  0 ...
  1 .X.
  2 ..~"""


def test_sample_masks_and_pictures_as_expectations():
    assert_pixels_equal(coverage(RIGHT, 4, 4), RIGHT_PICTURE)            # a str with line breaks is a picture
    a = coverage(RIGHT, 5, 4, samples="grid16")
    b = coverage([(0, 0.1), (4.3, 0), (0, 3.7)], 5, 4, samples="grid16")
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal(a, b)
    assert str(info.value) == """\
4 of 20 pixels differ (tolerance 0)
differences in x 0..4, y 0..3 (x: column from the left, y: row from the top)
first differing pixel x=0, y=0: actual samples ....#...##..###., expected samples ........##..###.
map of x 0..4, y 0..3 (# same samples, + actual has more, - expected has more, X each has samples the other \
lacks, . none):
  0 +....
  1 ##...
  2 ##-..
  3 ###--"""


def test_framebuffers_files_and_floats_compare():
    fb = sp.Framebuffer(6, 4)
    fb.clear("red")
    path = fb.save(Path(pytest.importorskip("tempfile").mkdtemp()) / "red.png")
    assert_pixels_equal(fb, path)
    assert_pixels_equal(fb, Image.open(path))
    assert_pixels_equal(fb.color[:, :, :3], np.tile([1.0, 0, 0], (4, 6, 1)))
    nan = np.full((1, 2), np.nan)
    assert_pixels_equal(nan, nan)
    with pytest.raises(AssertionError, match="worst pixel x=1, y=0: actual nan, expected 0, difference inf"):
        assert_pixels_equal(nan, np.array([[np.nan, 0.0]]))


def test_a_large_difference_shows_the_start_of_its_region():
    with pytest.raises(AssertionError) as info:
        assert_pixels_equal(np.ones((50, 100), bool), np.zeros((50, 100), bool))
    lines = str(info.value).splitlines()
    assert lines[3] == ("map of x 0..63, y 0..31 (the first 32 rows and 64 columns of y 0..49, x 0..99) "
                        "(# both, + actual only, - expected only, . neither):")
    assert len(lines) == 4 + 32 and lines[4] == "   0 " + "+" * 64


# ------------------------------------------------------------ ASCII pictures

def test_pictures_and_back():
    mask = from_ascii(RIGHT_PICTURE)
    assert ascii_picture(mask) == "....\n#...\n##..\n###."
    assert np.array_equal(from_ascii(ascii_picture(mask)), mask)
    ids = np.array([[-1, 0, 9], [10, 35, -1]])
    assert ascii_picture(ids) == ".09\naz."
    assert np.array_equal(from_ascii(".09\naz."), ids)
    legend = {".": (0, 0, 0), "r": (255, 0, 0)}
    image = from_ascii("r.\n.r", legend=legend, dtype=np.uint8)
    assert image.shape == (2, 2, 3) and image.dtype == np.uint8 and tuple(image[0, 0]) == (255, 0, 0)
    assert ascii_picture(image, legend=legend) == "r.\n.r"
    assert ascii_picture(image, legend={".": (0, 0, 0)}) == "?.\n.?"
    assert ascii_picture(image) == "#.\n.#"                  # an image without legend: black or not
    fb = sp.Framebuffer(3, 2)
    fb.clear("black")
    assert ascii_picture(fb) == "...\n..."


# ------------------------------------------------------------------- golden

GOLDEN_TEST = '''
import numpy as np
from pathlib import Path

def test_picture(golden):
    level = int(Path(__file__).with_name("level.txt").read_text())
    image = np.zeros((3, 4, 3), np.uint8)
    image[1, 2] = (level, 0, 0)
    golden(image, tolerance=1)
'''


def test_the_golden_fixture_creates_passes_fails_with_a_diff_and_updates(pytester):
    pytester.makepyfile(test_golden=GOLDEN_TEST)
    level = pytester.path / "level.txt"
    stored = pytester.path / "golden" / "test_picture.png"
    out = pytester.path / "out"
    run = lambda *args: pytester.runpytest("-p", "softpipe.testing.plugin", "-p", "no:cacheprovider",  # noqa: E731
                                           "--softpipe-golden-output", str(out), *args)
    level.write_text("100")
    result = run()                                    # no golden image yet: written, and the test fails once
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*golden image *test_picture.png did not exist; it is written now from this "
                                 "run: look at it, commit it, and run the test again"])
    assert Image.open(stored).mode == "RGB" and np.asarray(Image.open(stored))[1, 2, 0] == 100
    run().assert_outcomes(passed=1)                   # the same picture
    level.write_text("101")
    run().assert_outcomes(passed=1)                   # within tolerance 1 (8-bit levels)
    level.write_text("140")
    result = run()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "E * 1 of 12 pixels differ (tolerance 1)",
        "E * worst pixel x=2, y=1: actual (140, 0, 0), golden (100, 0, 0), difference 40",
        "E *map of x 1..3, y 0..2 (X differs, . equal):",
        "E *  1 .X.",
        f"E *golden image: {stored}",
        f"E *this run:     {out / 'test_picture.actual.png'}",
        f"E *diff:         {out / 'test_picture.diff.png'}",
        "E *pytest --softpipe-update-golden rewrites the golden image*"])
    assert np.asarray(Image.open(out / "test_picture.actual.png"))[1, 2, 0] == 140
    assert tuple(np.asarray(Image.open(out / "test_picture.diff.png"))[1, 2]) == (255, 0, 0)
    result = run("--softpipe-update-golden")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*softpipe golden images*", f"updated: {stored}"])
    assert np.asarray(Image.open(stored))[1, 2, 0] == 140
    run().assert_outcomes(passed=1)


NAMING_TEST = '''
import numpy as np
import pytest

@pytest.mark.parametrize("n", [1])
def test_named(golden, n):
    assert golden(np.zeros((2, 2), bool)) == "created"
    assert golden(np.ones((2, 2), bool), "second") == "created"
    with pytest.raises(ValueError) as info:
        golden(np.ones((2, 2), bool), "second")
    assert str(info.value) == "golden image second.png was already compared in this test: give each call its own name="
'''


def test_golden_images_are_named_after_the_test(pytester):
    pytester.makepyfile(test_naming=NAMING_TEST)
    pytester.runpytest("-p", "softpipe.testing.plugin", "-p", "no:cacheprovider",
                       "--softpipe-update-golden").assert_outcomes(passed=1)
    assert sorted(p.name for p in (pytester.path / "golden").iterdir()) == ["second.png", "test_named-1.png"]


def test_check_golden_stores_8_bit_and_says_what_it_did(tmp_path):
    mask = from_ascii(RIGHT_PICTURE)
    path = tmp_path / "g" / "mask.png"
    assert check_golden(mask, path, update=True) == "created"
    assert Image.open(path).mode == "L" and path.stat().st_size < 200
    assert check_golden(mask, path) == "passed"
    assert check_golden(~mask, path, update=True) == "updated"
    floats = np.full((2, 2, 3), 0.5)
    check_golden(floats, tmp_path / "f.png", update=True)
    assert np.asarray(Image.open(tmp_path / "f.png"))[0, 0, 0] == 128     # rint(0.5·255) = 128 (half to even)


# ----------------------------------------------------------------- examples

def test_the_examples_catch_the_naive_rasterizer(pytester):
    result = pytester.runpytest(str(EXAMPLES), "-p", "softpipe.testing.plugin", "-p", "no:cacheprovider",
                                "-o", "addopts=")
    outcomes = result.parseoutcomes()
    failed = sorted(line.split("::")[1].split(" ")[0] for line in result.outlines if line.startswith("FAILED"))
    assert all("[naive" in name for name in failed), failed
    assert "test_a_right_triangle_covers_these_pixels[naive]" in failed
    assert "test_two_triangles_sharing_an_edge_draw_every_pixel_once[naive]" in failed
    assert "test_against_the_exact_reference[naive]" in failed
    assert sum(name.startswith("test_random_triangles_cover_what_opengl_covers[naive") for name in failed) == 5
    # every "fixed" test and the golden scene pass (a warning, if any, is pytest's: the plugin's module was
    # imported by this run already, when softpipe is installed with the plugin's entry point)
    assert (outcomes.get("failed"), outcomes.get("passed")) == (9, 16), outcomes
    result.stdout.fnmatch_lines([
        "E * 4 of 25 pixels differ (tolerance 0)",
        "E * first differing pixel x=0, y=1: actual True, expected False",
        "E * map of x 0..4, y 0..4 (# both, + actual only, - expected only, . neither):",
        "E *  0 .....",
        "E *  1 +....",
        "E *  2 #+...",
        "E *  3 ##+..",
        "E *  4 ###+.",
    ])
    result.stdout.fnmatch_lines(["E * worst pixel x=3, y=0: actual 2, expected 1, difference 1"])
