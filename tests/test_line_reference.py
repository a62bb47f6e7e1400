"""The line and point reference (softpipe.testing.line_reference) against cases worked by hand.

Every expected set below is reasoned from the specification's words (quoted in the
module's docstring), not computed: window coordinates, y up, pixel (i, j)'s centre at
(i + ½, j + ½), its diamond |x − i − ½| + |y − j − ½| < ½; a segment a → b is drawn as
a' → b' with a' = a − (ε, ε²), b' = b − (ε, ε²), and the diamond holding b' is left out.
Coordinates are binary fractions (on the 1/256 grid), so snapping leaves them alone
unless a test says otherwise.
"""
from __future__ import annotations

from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softpipe.testing import reference_line, reference_line_parameter, reference_point


def row(j, i0, i1):
    """Pixels (i0..i1, j)."""
    return {(i, j) for i in range(i0, i1 + 1)}


def col(i, j0, j1):
    """Pixels (i, j0..j1)."""
    return {(i, j) for j in range(j0, j1 + 1)}


# ------------------------------------------------------------------ width 1, by hand

def test_horizontal_centre_to_centre_is_half_open_the_last_pixel_is_not_produced():
    # a' = (0.5 − ε, …) is inside (0,0)'s diamond; b' = (4.5 − ε, …) is inside (4,0)'s: left out
    assert reference_line((0.5, 0.5), (4.5, 0.5)) == row(0, 0, 3)


def test_reversed_direction_differs_only_at_the_ends_first_pixel_swapped_for_last():
    # b → a: the same perturbed segment (both ends move by the same (ε, ε²)); now a' is the end left out
    forward = reference_line((0.5, 0.5), (4.5, 0.5))
    backward = reference_line((4.5, 0.5), (0.5, 0.5))
    assert backward == row(0, 1, 4)
    assert forward ^ backward == {(0, 0), (4, 0)}


def test_ending_on_a_diamonds_right_vertex_drops_that_diamond_because_b_prime_lies_inside():
    # (3.0, 0.5) is the right vertex of (2,0)'s diamond; b' = (3 − ε, 0.5 − ε²): |0.5 − ε| + ε² < ½
    assert reference_line((0.5, 0.5), (3.0, 0.5)) == {(0, 0), (1, 0)}


def test_ending_leftwards_on_a_diamonds_left_vertex_keeps_it_b_prime_lies_in_the_left_neighbour():
    # (2.0, 0.5) is the left vertex of (2,0); b' = (2 − ε, …) is inside (1,0)'s diamond, which is left out,
    # and (2,0)'s diamond is crossed (at x = 2.5 the segment is at its centre)
    assert reference_line((4.5, 0.5), (2.0, 0.5)) == row(0, 2, 4)


def test_ending_rightwards_on_a_left_vertex_drops_the_diamond_to_its_left():
    # (2.0, 0.5) is also the right vertex of (1,0): b' is inside (1,0)
    assert reference_line((0.5, 0.5), (2.0, 0.5)) == {(0, 0)}


def test_ending_upwards_on_a_diamonds_top_vertex_keeps_it_b_prime_lies_in_no_diamond():
    # (0.5, 3.0) is the top vertex of (0,2); b' = (0.5 − ε, 3 − ε²) is ε + ½ − ε² > ½ from (0,2)'s centre
    # and ε + ½ + ε² from (0,3)'s: in no diamond, so nothing is left out; (0,2) is crossed at its centre
    assert reference_line((0.5, 0.5), (0.5, 3.0)) == col(0, 0, 2)


def test_ending_downwards_on_a_diamonds_bottom_vertex_keeps_it_and_never_reaches_below():
    # (0.5, 2.0) is the bottom vertex of (0,2); the segment stops at y = 2 − ε², (0,1)'s diamond at
    # x = 0.5 − ε begins below y = 2 − ε
    assert reference_line((0.5, 4.5), (0.5, 2.0)) == col(0, 2, 4)


def test_horizontal_along_the_row_boundary_through_vertices_goes_to_the_row_below():
    # y = 1.0 holds the top vertices of row 0; a' − (ε, ε²) puts the segment at y = 1 − ε², inside
    # row 0's diamonds where x is within ε² of a centre. The last one, (3,0), needs x > 3.5 − ε², but the
    # segment stops at 3.5 − ε; b' is in no diamond.
    assert reference_line((0.5, 1.0), (3.5, 1.0)) == row(0, 0, 2)


def test_vertical_along_the_column_boundary_through_vertices_goes_to_the_column_left():
    # x = 1.0 holds the right vertices of column 0; the segment runs at x = 1 − ε; b' = (1 − ε, 3.5 − ε²)
    # is inside (0,3)'s diamond (½ − ε + ε² < ½): left out
    assert reference_line((1.0, 0.5), (1.0, 3.5)) == col(0, 0, 2)


def test_rising_segment_through_a_diamond_corner_takes_the_upper_pixel():
    # slope ¼: at x = 2.5 the line is at y = 1.0, the corner shared by (2,0) and (2,1). Moved by
    # −(ε, ε²) the line at x = 2.5 is at 1 + ε/4 − ε² > 1: inside (2,1), not (2,0).
    # Columns 1 and 3: y = 0.75 → (1,0), y = 1.25 → (3,1); (4,1) holds b': left out.
    assert reference_line((0.5, 0.5), (4.5, 1.5)) == {(0, 0), (1, 0), (2, 1), (3, 1)}


def test_falling_segment_through_a_diamond_corner_takes_the_lower_pixel():
    # slope −¼: at x = 2.5, y = 1 − ε/4 − ε² < 1 after the perturbation: (2,0)
    assert reference_line((0.5, 1.5), (4.5, 0.5)) == {(0, 1), (1, 1), (2, 0), (3, 0)}


def test_45_degree_diagonal_through_centres_is_half_open():
    # y = x meets a diamond only within ¼ of its centre: (0,0), (1,1), (2,2); (3,3) holds b'
    assert reference_line((0.5, 0.5), (3.5, 3.5)) == {(0, 0), (1, 1), (2, 2)}
    assert reference_line((0.5, 3.5), (3.5, 0.5)) == {(0, 3), (1, 2), (2, 1)}


def test_45_degree_diagonal_along_diamond_edges_falls_inside_the_upper_left_ones():
    # x − y = ½ runs along the upper-left edges of (1,0), (2,1) and the lower-right edges of (1,1), (2,2).
    # Perturbed, x − y = ½ − ε + ε² < ½: inside (1,1) and (2,2), outside (1,0) and (2,1). a' = (1 − ε, ½ − ε²)
    # is inside (0,0) (½ − ε + ε² < ½); b' = (3 − ε, 2.5 − ε²) is inside (2,2): left out.
    assert reference_line((1.0, 0.5), (3.0, 2.5)) == {(0, 0), (1, 1)}


def test_vertical_centre_to_centre_up_and_down():
    assert reference_line((2.5, 0.5), (2.5, 3.5)) == col(2, 0, 2)
    assert reference_line((2.5, 3.5), (2.5, 0.5)) == col(2, 1, 3)


def test_short_segment_inside_one_diamond_produces_nothing():
    # both ends inside (0,0)'s diamond: the only diamond met holds b'
    assert reference_line((0.375, 0.5), (0.625, 0.5)) == set()
    # from the gap between diamonds into (1,1)'s: it holds b'
    assert reference_line((0.875, 0.875), (1.25, 1.25)) == set()


def test_short_segment_that_exits_its_diamond_produces_one_fragment():
    # from (0,0)'s centre into (1,0)'s diamond (which holds b')
    assert reference_line((0.5, 0.5), (1.25, 0.5)) == {(0, 0)}
    # from (0,0)'s centre out into the gap at (0.875, 0.875): |.375| + |.375| > ½, no diamond holds b'
    assert reference_line((0.5, 0.5), (0.875, 0.875)) == {(0, 0)}


def test_segment_wholly_in_the_gap_between_diamonds_produces_nothing():
    # around the pixel corner (1, 1): every point is ≥ ½ (L1) from every centre
    assert reference_line((0.9375, 1.0), (1.0625, 1.0)) == set()


def test_zero_length_segment_and_one_that_snaps_to_zero_length_produce_nothing():
    assert reference_line((2.5, 2.5), (2.5, 2.5)) == set()
    # 1/1024 apart: both snap to the same 1/256 point
    assert reference_line((2.5, 2.5), (2.5 + 1 / 1024, 2.5)) == set()


def test_endpoints_snap_to_the_1_256_grid_before_the_rule():
    # 3.0 + 1/1024 snaps to 3.0, the right vertex of (2,0): b' is inside (2,0), left out
    assert reference_line((0.5, 0.5), (3.0 + 1 / 1024, 0.5)) == {(0, 0), (1, 0)}
    # 3.0 + 1/128 stays: b' is inside (3,0)'s diamond now, and (2,0) is crossed
    assert reference_line((0.5, 0.5), (3.0 + 1 / 128, 0.5)) == row(0, 0, 2)


# ------------------------------------------------------------------ strips and loops

def test_strip_joint_pixel_is_produced_once_by_the_second_segment():
    # right then up; (3,0) holds the joint: left out of the first, produced by the second
    first = reference_line((0.5, 0.5), (3.5, 0.5))
    second = reference_line((3.5, 0.5), (3.5, 3.5))
    assert first == row(0, 0, 2) and second == col(3, 0, 2)
    assert not first & second


def test_strip_joint_through_a_corner_no_double_hit_no_gap():
    # (0.5,0.5) → (3.5,0.5) → (6.5,2.0): second segment has slope ½; at x = 4.5 it is at y = 1.0, a corner,
    # moved to 1 + ε/2 − ε² > 1: (4,1). x = 5.5: y = 1.5 → (5,1). b' = (6.5 − ε, 2 − ε²) is in no diamond and
    # the segment never enters (6,1) or (6,2) (it would need to be below 2 − ε or above 2 + ε at x ≈ 6.5)
    first = reference_line((0.5, 0.5), (3.5, 0.5))
    second = reference_line((3.5, 0.5), (6.5, 2.0))
    assert second == {(3, 0), (4, 1), (5, 1)}
    assert not first & second
    assert sorted(i for i, _ in first | second) == [0, 1, 2, 3, 4, 5]


def test_strip_turning_90_degrees_at_a_joint_in_a_gap_hits_the_joint_pixel_twice():
    # The spec's promise of no duplicate is for two x-major (or two y-major) segments going the same way.
    # Left along y = 0.125 to b = (2.375, 0.125), then up: b is in the gap below (2,0)'s diamond
    # (|−.125| + |−.375| = ½, and b' is ε + ε² farther), so the first segment, crossing (2,0)'s diamond at
    # x = 2.5 (L1 .375), keeps it; the second, at x = 2.375 − ε, crosses it at y = .5 (L1 .125 + ε) too.
    first = reference_line((4.5, 0.125), (2.375, 0.125))
    second = reference_line((2.375, 0.125), (2.375, 2.5))
    assert first == row(0, 2, 4)
    assert second == col(2, 0, 1)          # (2,2)'s diamond holds c' = (2.375 − ε, 2.5 − ε²): left out
    assert first & second == {(2, 0)}


def test_closed_loop_covers_each_pixel_of_the_rectangle_outline_once():
    corners = [(0.5, 0.5), (3.5, 0.5), (3.5, 2.5), (0.5, 2.5)]
    parts = [reference_line(corners[k], corners[(k + 1) % 4]) for k in range(4)]
    assert parts == [row(0, 0, 2), col(3, 0, 1), row(2, 1, 3), col(0, 1, 2)]
    counts = {}
    for part in parts:
        for p in part:
            counts[p] = counts.get(p, 0) + 1
    outline = row(0, 0, 3) | row(2, 0, 3) | {(0, 1), (3, 1)}
    assert set(counts) == outline and set(counts.values()) == {1}


# ------------------------------------------------------------------ wide lines

@pytest.mark.parametrize("width, expected", [
    (1, row(2, 0, 2)),
    # moved down ½ onto y = 2.0, the row boundary: the perturbation puts it in row 1; runs of 2 upwards
    (2, row(1, 0, 2) | row(2, 0, 2)),
    (3, row(1, 0, 2) | row(2, 0, 2) | row(3, 0, 2)),
    # moved down 1½ onto y = 1.0: row 0, runs of 4
    (4, row(0, 0, 2) | row(1, 0, 2) | row(2, 0, 2) | row(3, 0, 2)),
    (5, row(0, 0, 2) | row(1, 0, 2) | row(2, 0, 2) | row(3, 0, 2) | row(4, 0, 2)),
])
def test_wide_horizontal_x_major_line_is_offset_down_and_runs_go_up(width, expected):
    assert reference_line((0.5, 2.5), (3.5, 2.5), width) == expected


@pytest.mark.parametrize("width, expected", [
    (1, col(2, 0, 2)),
    # moved left ½ onto x = 2.0, the column boundary: the perturbation puts it in column 1; runs go right
    (2, col(1, 0, 2) | col(2, 0, 2)),
    (3, col(1, 0, 2) | col(2, 0, 2) | col(3, 0, 2)),
    (4, col(0, 0, 2) | col(1, 0, 2) | col(2, 0, 2) | col(3, 0, 2)),
    (5, col(0, 0, 2) | col(1, 0, 2) | col(2, 0, 2) | col(3, 0, 2) | col(4, 0, 2)),
])
def test_wide_vertical_y_major_line_is_offset_left_and_runs_go_right(width, expected):
    assert reference_line((2.5, 0.5), (2.5, 3.5), width) == expected


def test_wide_45_degree_line_is_x_major_columns_of_three():
    # |Δx| = |Δy|: x-major (slope in [−1, 1]); moved down 1: (0,−1), (1,0), (2,1), each a column of 3
    assert reference_line((0.5, 0.5), (3.5, 3.5), 3) == col(0, -1, 1) | col(1, 0, 2) | col(2, 1, 3)


@pytest.mark.parametrize("width, same_as", [(0.25, 1), (1.4, 1), (1.5, 2), (1.6, 2), (2.5, 3), (4.49, 4)])
def test_width_rounds_to_nearest_whole_halves_up_and_never_below_one(width, same_as):
    assert reference_line((0.5, 2.5), (3.5, 2.5), width) == reference_line((0.5, 2.5), (3.5, 2.5), same_as)


# ------------------------------------------------------------------ points

@pytest.mark.parametrize("size, expected", [
    (0.75, {(2, 2)}),                                        # clamped to 1
    (1, {(2, 2)}),                                           # [2, 3): centre 2.5
    (1.5, {(2, 2)}),                                         # [1.75, 3.25): 2.5 only
    (2, {(i, j) for i in (1, 2) for j in (1, 2)}),           # [1.5, 3.5): 1.5 in, 3.5 out (half-open)
    (2.5, {(i, j) for i in (1, 2, 3) for j in (1, 2, 3)}),   # [1.25, 3.75)
    (3, {(i, j) for i in (1, 2, 3) for j in (1, 2, 3)}),     # [1, 4)
])
def test_point_at_a_pixel_centre(size, expected):
    assert reference_point((2.5, 2.5), size) == expected


def test_point_size_7_at_a_centre_is_7_by_7():
    assert reference_point((5.5, 5.5), 7) == {(i, j) for i in range(2, 9) for j in range(2, 9)}


@pytest.mark.parametrize("size, axis", [
    (0.75, [2]),                 # [2.5, 3.5): 2.5 in (closed), 3.5 out (open)
    (1, [2]),
    (1.5, [2, 3]),               # [2.25, 3.75)
    (2, [2, 3]),                 # [2, 4)
    (2.5, [2, 3]),               # [1.75, 4.25)
    (3, [1, 2, 3]),              # [1.5, 4.5): 1.5 in, 4.5 out
    (7, [-1, 0, 1, 2, 3, 4, 5]),  # [-0.5, 6.5): centre -0.5 in (pixel -1), 6.5 out
])
def test_point_at_a_pixel_corner_takes_the_lower_left_side_of_ties(size, axis):
    assert reference_point((3.0, 3.0), size) == {(i, j) for i in axis for j in axis}


@pytest.mark.parametrize("size, xs, ys", [
    (1, [2], [2]),
    (2, [2, 3], [1, 2]),
    (3, [1, 2, 3], [1, 2, 3]),
])
def test_point_on_a_vertical_pixel_edge(size, xs, ys):
    assert reference_point((3.0, 2.5), size) == {(i, j) for i in xs for j in ys}


def test_point_position_is_snapped_to_the_1_256_grid_the_size_is_not():
    # x = 3 + 1/1024 snaps to 3.0: [2.5, 3.5) holds centre 2.5; unsnapped it would hold 3.5 instead
    assert reference_point((3.0 + 1 / 1024, 2.5), 1) == {(2, 2)}
    # a size of 2 + 1/1024 is used as given: [1.5 − 1/2048, 3.5 + 1/2048) reaches centre 3.5 too
    assert reference_point((2.5, 2.5), 2 + 1 / 1024) == {(i, j) for i in (1, 2, 3) for j in (1, 2, 3)}


# ------------------------------------------------------------------ the parameter t

def test_line_parameter_is_the_projection_of_the_pixel_centre_clamped():
    a, b = (0.5, 0.5), (4.5, 0.5)
    assert reference_line_parameter(a, b, (1, 0)) == Fraction(1, 4)
    assert reference_line_parameter(a, b, (2, 3)) == Fraction(1, 2)     # off the line: projected
    assert reference_line_parameter(a, b, (-3, 0)) == 0
    assert reference_line_parameter(a, b, (7, 0)) == 1
    # (1.5, 1.5) − (0.5, 0.5) = (1, 1); · (2, 1) = 3; |(2, 1)|² = 5
    assert reference_line_parameter((0.5, 0.5), (2.5, 1.5), (1, 1)) == Fraction(3, 5)


# ------------------------------------------------------------------ bad input

@pytest.mark.parametrize("call, message", [
    (lambda: reference_line((0, 0), (float("nan"), 1)), "pb[0] must be a finite number, got nan"),
    (lambda: reference_line((0, 0), (1,)), "pb must be a window position (x, y), got (1,)"),
    (lambda: reference_line((0, 0), (1, 1), 0), "width must be > 0 (pixels), got 0"),
    (lambda: reference_point((0, float("inf")), 1), "p[1] must be a finite number, got inf"),
    (lambda: reference_point((0, 0), -1), "size must be > 0 (pixels), got -1"),
    (lambda: reference_line_parameter((1, 1), (1, 1), (0, 0)), "has zero length after snapping"),
    (lambda: reference_line_parameter((0, 0), (1, 1), (0.5, "a")), "pixel must be a pair of integers"),
])
def test_bad_input_is_a_value_error_that_names_it(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value)


# ------------------------------------------------------------------ properties

# positions on a coarse binary grid (1/8 pixel) hit centres, edges, corners and diamond vertices often
coord = st.integers(0, 12 * 8).map(lambda k: Fraction(k, 8))
point = st.tuples(coord, coord)


def _centre_l1(pixel, p):
    return abs(pixel[0] + Fraction(1, 2) - p[0]) + abs(pixel[1] + Fraction(1, 2) - p[1])


@settings(max_examples=300, deadline=None)
@given(point, point)
def test_property_one_fragment_per_column_x_major_one_per_row_y_major(a, b):
    frags = reference_line(a, b)
    x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])
    major = [i if x_major else j for i, j in frags]
    assert len(major) == len(set(major))
    if frags:           # and the columns (rows) are contiguous: no gap along the line
        assert sorted(major) == list(range(min(major), max(major) + 1))


@settings(max_examples=300, deadline=None)
@given(point, point)
def test_property_every_column_well_inside_the_ends_has_its_fragment(a, b):
    # x-major: a column whose centre is more than one pixel from both ends' x is crossed, and the
    # diamond that holds b' is not in it; a column whose diamond lies wholly beyond the segment's
    # x-range [lo − ε, hi − ε] is never reached (y-major: the same with x and y swapped)
    frags = reference_line(a, b)
    if abs(b[0] - a[0]) < abs(b[1] - a[1]):
        frags = {(j, i) for i, j in frags}
        a, b = (a[1], a[0]), (b[1], b[0])
    lo, hi = min(a[0], b[0]), max(a[0], b[0])
    columns = {i for i, _ in frags}
    for i in range(int(lo) - 2, int(hi) + 3):
        c = i + Fraction(1, 2)
        if lo + 1 < c < hi - 1:
            assert i in columns
        if c < lo - Fraction(1, 2) or c >= hi + Fraction(1, 2):
            assert i not in columns


@settings(max_examples=300, deadline=None)
@given(point, point)
def test_property_reversing_differs_by_at_most_one_pixel_at_each_end(a, b):
    forward, backward = reference_line(a, b), reference_line(b, a)
    only_forward, only_backward = forward - backward, backward - forward
    assert len(only_forward) <= 1 and len(only_backward) <= 1
    # what a → b has and b → a lacks is b → a's end pixel: its diamond holds a' (within ½ of a)
    assert all(_centre_l1(p, a) <= Fraction(1, 2) for p in only_forward)
    assert all(_centre_l1(p, b) <= Fraction(1, 2) for p in only_backward)


@settings(max_examples=300, deadline=None)
@given(point, point, st.integers(-3, 3), st.integers(-3, 3))
def test_property_whole_pixel_translation_moves_the_fragments(a, b, di, dj):
    moved = reference_line((a[0] + di, a[1] + dj), (b[0] + di, b[1] + dj))
    assert moved == {(i + di, j + dj) for i, j in reference_line(a, b)}


@settings(max_examples=300, deadline=None)
@given(point, st.integers(1, 48), st.integers(-48, 48), st.integers(1, 48), st.integers(-48, 48))
def test_property_strip_joint_is_never_double_hit_nor_a_gap(a, dx1, dy1, dx2, dy2):
    # the spec's guarantee: two segments sharing an endpoint, both x-major and both left-to-right,
    # produce no fragment twice and leave no column out
    d1 = (Fraction(dx1, 8), Fraction(max(-dx1, min(dx1, dy1)), 8))
    d2 = (Fraction(dx2, 8), Fraction(max(-dx2, min(dx2, dy2)), 8))
    b = (a[0] + d1[0], a[1] + d1[1])
    c = (b[0] + d2[0], b[1] + d2[1])
    first, second = reference_line(a, b), reference_line(b, c)
    assert not first & second
    columns = sorted(i for i, _ in first | second)
    if columns:
        assert columns == list(range(columns[0], columns[-1] + 1))


@settings(max_examples=200, deadline=None)
@given(point, point, st.integers(1, 5))
def test_property_wide_line_is_the_offset_thin_line_in_runs_of_w(a, b, w):
    wide = reference_line(a, b, w)
    if abs(b[0] - a[0]) >= abs(b[1] - a[1]):
        h = Fraction(w - 1, 2)
        thin = reference_line((a[0], a[1] - h), (b[0], b[1] - h))
        assert wide == {(i, j + k) for i, j in thin for k in range(w)}
    else:
        h = Fraction(w - 1, 2)
        thin = reference_line((a[0] - h, a[1]), (b[0] - h, b[1]))
        assert wide == {(i + k, j) for i, j in thin for k in range(w)}
    assert len(wide) == w * len(thin)


@settings(max_examples=300, deadline=None)
@given(point, st.integers(1, 8 * 7).map(lambda k: Fraction(k, 8)))
def test_property_point_is_a_square_of_floor_or_ceil_size(p, size):
    frags = reference_point(p, size)
    s = max(size, 1)
    xs, ys = {i for i, _ in frags}, {j for _, j in frags}
    assert frags == {(i, j) for i in xs for j in ys}
    for axis in (xs, ys):
        assert len(axis) in ({int(s)} if s.denominator == 1 else {int(s), int(s) + 1})
        assert sorted(axis) == list(range(min(axis), max(axis) + 1))


def _by_concrete_epsilon(a, b, eps=Fraction(1, 2 ** 30)):
    """The diamond-exit rule another way: a concrete tiny ε, and the segment's least L1 distance to a centre.

    The L1 distance from a centre along the segment is convex and piecewise linear in t, so its
    least value is at t = 0, t = 1 or where x(t) or y(t) passes the centre's x or y. For these
    1/8-pixel coordinates ε = 2⁻³⁰ is "small enough" (no constant term the ε terms could outweigh).
    """
    a0 = (a[0] - eps, a[1] - eps * eps)
    b0 = (b[0] - eps, b[1] - eps * eps)
    d = (b0[0] - a0[0], b0[1] - a0[1])
    half = Fraction(1, 2)

    def l1(t, c):
        return abs(a0[0] + t * d[0] - c[0]) + abs(a0[1] + t * d[1] - c[1])

    out = set()
    for i in range(int(min(a[0], b[0])) - 2, int(max(a[0], b[0])) + 3):
        for j in range(int(min(a[1], b[1])) - 2, int(max(a[1], b[1])) + 3):
            c = (i + half, j + half)
            ts = [Fraction(0), Fraction(1)]
            for k in (0, 1):
                if d[k]:
                    t = (c[k] - a0[k]) / d[k]
                    if 0 <= t <= 1:
                        ts.append(t)
            if min(l1(t, c) for t in ts) < half and not l1(Fraction(1), c) < half:
                out.add((i, j))
    return out


@settings(max_examples=300, deadline=None)
@given(point, point)
def test_property_symbolic_epsilon_agrees_with_a_concrete_tiny_epsilon(a, b):
    assert reference_line(a, b) == _by_concrete_epsilon(a, b)
