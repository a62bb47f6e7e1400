"""The lines' walk (softpipe/pipeline/lines.py), issue #29: which columns it visits and the rows it carries.

Both rasterizers of lines — the reference path's ``cover_line`` and the fast path's tile walk
(``primitive_tiles._draw_line``) — go along a segment's major axis column by column (row by
row, for a steep one) and ask the diamond-exit rule only about the diamonds the line passes
nearest. These tests hold that walk to its two promises, in exact rationals: it visits
exactly the columns whose diamonds the segment's major extent reaches (no column more, so no
exact test is spent where no fragment can be), and in each the row it carries, stepped by
integer additions from any starting column (each tile starts at its own), is the row nearest
the line, exactly. That the fragments are the rule's is tests/test_lines_points_exact.py's
(reference path) and tests/test_points_lines_fast.py's (fast path, across tiles).
"""
from __future__ import annotations

import random
from fractions import Fraction
from math import ceil

import numpy as np
import pytest

from softpipe.pipeline.lines import LineSetup, line_walk, minor_start, minor_step
from softpipe.pipeline.primitive_tiles import primitive_boxes
from softpipe.testing import reference_line

SEED = 29


def _point(rng, size):
    """A window position (Fractions) in [−size/4, size], often on a tie: a pixel centre, edge or corner,
    a diamond vertex, 1/256 beside one, or anywhere on the 1/256 grid."""
    kind = rng.random()
    if kind < 0.4:
        return tuple(Fraction(rng.randint(-size // 4 * 256, size * 256), 256) for _ in range(2))
    step = Fraction(1, 2) if kind < 0.8 else Fraction(1, 4)
    nudge = Fraction(rng.choice((-1, 0, 0, 1)), 256)
    return tuple(Fraction(rng.randint(-size // 4 * 4, size * 4), 4) // step * step + nudge for _ in range(2))


def _segments(count, size=300, seed=SEED):
    """Random segments, short and long, with 45° and slope-½ ones (rows exactly halfway between two)."""
    rng = random.Random(f"{seed}-walk")
    out = []
    while len(out) < count:
        a = _point(rng, size)
        shape = rng.random()
        if shape < 0.3:
            b = _point(rng, size)
        elif shape < 0.6:                                   # short: within three pixels
            b = (a[0] + Fraction(rng.randint(-768, 768), 256), a[1] + Fraction(rng.randint(-768, 768), 256))
        else:                                               # 45°, slope ½ or 2, either way
            d = Fraction(rng.randint(-40, 40), 2)
            k = rng.choice((Fraction(1), Fraction(1, 2), Fraction(2), Fraction(-1), Fraction(-1, 2)))
            b = (a[0] + d, a[1] + k * d) if rng.random() < 0.5 else (a[0] + k * d, a[1] + d)
        if a != b:
            out.append((a, b))
    return out


def _ends(segments):
    """The setup's snapped ends in fixed point (pixel i's centre at 256·i): 256·v − 128 (on the 1/256 grid)."""
    return np.array([[int(v * 256) - 128 for v in (*a, *b)] for a, b in segments], np.int64)


def test_the_walk_visits_exactly_the_columns_whose_diamonds_the_segment_moved_by_minus_epsilon_reaches():
    # pixel c's diamonds span the open (c, c + 1) along the major axis; the segment, both ends moved by
    # −ε along it (the rule's perturbation), reaches that slab iff ⌈lo⌉ − 1 ≤ c ≤ ⌈hi⌉ − 1 (lo, hi its
    # ends' major coordinates): an end on a slab's border reaches the slab before it, never the one after.
    # The walk went a column further at each end (every exact test there failing), and its boxes with it.
    segments = _segments(2000)
    ends = _ends(segments)
    bad = []
    for k, (a, b) in enumerate(segments):
        x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])
        ma, mb = (a[0], b[0]) if x_major else (a[1], b[1])
        lo, hi = min(ma, mb), max(ma, mb)
        want = list(range(ceil(lo) - 1, ceil(hi)))
        want = want if mb >= ma else want[::-1]
        walk = line_walk(ends, k)
        step, first, last = walk[6], walk[7], walk[8]
        have = list(range(first, last + step, step))
        if walk[0] != x_major or have != want:
            bad.append(f"segment {k} ({a[0]}, {a[1]}) → ({b[0]}, {b[1]}): x-major {x_major}, columns {want}, "
                       f"the walk's {have}")
    assert not bad, f"{len(bad)} of {len(segments)}:\n" + "\n".join(bad[:10])


def test_the_row_carried_along_the_walk_is_the_nearest_row_exactly_from_any_starting_column():
    # at column c the line's minor coordinate is m = na + (256·c − ma)·nd/md (fixed point); the walk carries
    # it as 256·row + rem/|md| with rem in [−128·|md|, 128·|md|): row is the nearest row, halves down. Stepped
    # from the first column or started at any other (as each tile does), the same numbers.
    rng = random.Random(f"{SEED}-rows")
    segments = _segments(400, size=2000, seed=7)
    ends = _ends(segments)
    checked = 0
    for k in range(len(segments)):
        x_major, ma, mb, na, nd, md, step, first, last = line_walk(ends, k)
        columns = list(range(first, last + step, step))
        start = rng.randrange(len(columns))
        row, rem, inc, span = minor_start(columns[start], ma, na, nd, md)
        for c in columns[start:]:
            exact = na + Fraction((256 * c - ma) * nd, md)
            fresh = minor_start(c, ma, na, nd, md)
            assert (row, rem) == fresh[:2], (k, c)
            assert -128 * abs(md) <= rem < 128 * abs(md), (k, c, rem)
            assert 256 * row + Fraction(rem, abs(md)) == exact, (k, c)
            row, rem = minor_step(row, rem, inc, span)
            checked += 1
    assert checked > 5000


@pytest.mark.parametrize("width", [1, 2, 3])
def test_a_line_box_holds_every_pixel_of_the_rule_and_spans_exactly_the_walks_columns(width):
    # the box a line is binned to the tiles by: every pixel the rule gives it (its runs too) inside, and
    # along the major axis exactly the columns the walk visits (the first test's): the box was 1 column wider
    # at each end, and 2 to 3 rows wider across, more (line, tile) pairs to walk for nothing
    segments = _segments(600, size=120, seed=width)
    rect = np.array([-10_000, 10_000, -10_000, 10_000], np.int64)
    setup = LineSetup(_ends(segments), np.full(len(segments), width, np.int64), np.zeros((len(segments), 2)))
    # the setup moves a wide line by −(w − 1)/2 pixels across: the reference does so itself
    for k, (a, b) in enumerate(segments):
        shift = (width - 1) * 128
        x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])
        setup.ends[k, 1 if x_major else 0] -= shift
        setup.ends[k, 3 if x_major else 2] -= shift
    box = primitive_boxes(setup, rect)
    bad = []
    for k, (a, b) in enumerate(segments):
        i0, i1, j0, j1 = box[k].tolist()
        outside = sorted((i, j) for i, j in reference_line(a, b, width) if not (i0 <= i <= i1 and j0 <= j <= j1))
        x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])
        lo, hi = sorted((a[0], b[0]) if x_major else (a[1], b[1]))
        along = (i0, i1) if x_major else (j0, j1)
        if outside or along != (ceil(lo) - 1, ceil(hi) - 1):
            bad.append(f"segment {k} ({a[0]}, {a[1]}) → ({b[0]}, {b[1]}): box {box[k].tolist()}, pixels outside "
                       f"it {outside}, the columns the segment reaches {ceil(lo) - 1}..{ceil(hi) - 1}")
    assert not bad, f"{len(bad)} of {len(segments)}:\n" + "\n".join(bad[:10])
