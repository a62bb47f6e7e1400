"""softpipe's lines and points against the exact reference (softpipe.testing.line_reference), issue #29.

Thousands of random segments — on the 1/256 grid, on pixel centres, on pixel edges and
corners, short, horizontal, vertical, 45° — and points of sizes 0.75 to 7 are drawn with
``sp.draw`` into a framebuffer whose viewport is the whole of it, and each primitive's
fragments (from the trace, grouped by primitive) must be exactly the reference's pixels
inside the framebuffer, each once.

Window ↔ clip: with w = 1, x_clip = 2·x_win/W − 1 and y_clip = 2·y_win/H − 1; W and H are
powers of two and every window coordinate a binary fraction (k/256 or k/1024), so x_clip
is exact in float32 and the viewport transform (x_clip + 1)·W/2 gives x_win back exactly
(checked below). Endpoints stay inside [0, W] × [0, H], so nothing is clipped, except in
the test of segments that leave the framebuffer (there the pixels inside must be the whole
segment's). Ties are sought out: endpoints on pixel centres, edges, corners, diamond
vertices and 1/256 beside them, on a 1/8 grid, and points whose square's edges fall on centres.

On a mismatch the message names the primitive, its exact window endpoints (as
Fractions), the reference's pixels and softpipe's.
"""
from __future__ import annotations

import random
import sys
from collections import Counter
from fractions import Fraction

import numpy as np
import pytest

import softpipe as sp
from softpipe.testing import reference_line, reference_line_parameter, reference_point

W, H = 64, 32
SEED = 29


# --------------------------------------------------------------------- window → clip

def _clip(p):
    """Exact window (x, y) → clip (x, y, 0, 1) as float64 (binary fractions: exact)."""
    x, y = Fraction(p[0]), Fraction(p[1])
    return [float(2 * x / W - 1), float(2 * y / H - 1), 0.0, 1.0]


def _clip_array(points):
    arr = np.array([_clip(p) for p in points], np.float64)
    # the round trip is exact in float32 and float64: (x_clip / 1 + 1) · W/2 == x_win
    for dtype in (np.float32, np.float64):
        a = arr.astype(dtype)
        assert np.array_equal(a.astype(np.float64), arr), "a window coordinate is not exact in float32"
        back_x = (a[:, 0] / dtype(1) + dtype(1)) * dtype(W / 2)
        back_y = (a[:, 1] / dtype(1) + dtype(1)) * dtype(H / 2)
        want = np.array([[float(Fraction(p[0])), float(Fraction(p[1]))] for p in points])
        assert np.array_equal(back_x.astype(np.float64), want[:, 0])
        assert np.array_equal(back_y.astype(np.float64), want[:, 1])
    return arr


def _inside(pixels):
    return {(i, j) for i, j in pixels if 0 <= i < W and 0 <= j < H}


def _fragments_by_primitive(trace, count):
    """{primitive: Counter of window pixels (x, y up)} from a trace."""
    f = trace.fragments
    prim = np.asarray(f.primitive_id)
    assert len(prim) == 0 or (prim.min() >= 0 and prim.max() < count), \
        f"primitive ids run {prim.min()}..{prim.max()}, expected 0..{count - 1}"
    out = {k: Counter() for k in range(count)}
    for x, row, k in zip(np.asarray(f.x).tolist(), np.asarray(f.y).tolist(), prim.tolist()):
        out[k][(x, H - 1 - row)] += 1
    return out


def _draw(positions, topology, varyings=None, depth=None, **state):
    fb = sp.Framebuffer(W, H)
    n = len(positions)
    clip = _clip_array(positions)
    if depth is not None:
        clip[:, 2] = depth
    if varyings is None:
        varyings = {"color": np.full((n, 4), 0.25, np.float32)}
    return sp.draw(fb, clip, topology=topology, varyings=varyings, depth_test=None, blend="additive",
                   trace=True, **state)


def _fmt(p):
    return f"({Fraction(p[0])}, {Fraction(p[1])})"


def _compare_segments(segments, width=1.0):
    """Draw ``segments`` as "lines"; return a list of mismatch descriptions (empty when all agree)."""
    flat = [p for s in segments for p in s]
    trace = _draw(flat, "lines", line_width=width)
    got = _fragments_by_primitive(trace, len(segments))
    bad = []
    for k, (a, b) in enumerate(segments):
        want = _inside(reference_line(a, b, width))
        have = got[k]
        twice = sorted(p for p, c in have.items() if c > 1)
        if set(have) != want or twice:
            bad.append(f"segment {k} {_fmt(a)} → {_fmt(b)} width {width}: reference {sorted(want)}, "
                       f"softpipe {sorted(have)}" + (f", twice: {twice}" if twice else "")
                       + f"; only reference {sorted(want - set(have))}, only softpipe {sorted(set(have) - want)}")
    return bad


def _check(bad, total):
    assert not bad, f"{len(bad)} of {total} disagree with the reference:\n" + "\n".join(bad[:20])


# --------------------------------------------------------------------- random segments

def _grid(rng, step, lo, hi):
    """A multiple of ``step`` in [lo, hi]."""
    return Fraction(rng.randint(int(lo / step), int(hi / step))) * step


def _on_1_256(rng):
    return _grid(rng, Fraction(1, 256), 0, W), _grid(rng, Fraction(1, 256), 0, H)


def _centre(rng):
    return Fraction(rng.randint(0, W - 1)) + Fraction(1, 2), Fraction(rng.randint(0, H - 1)) + Fraction(1, 2)


def _edge_or_corner(rng):
    """x and y each an integer or a half-integer, at least one an integer: on a pixel edge or corner."""
    while True:
        x, y = _grid(rng, Fraction(1, 2), 0, W), _grid(rng, Fraction(1, 2), 0, H)
        if x.denominator == 1 or y.denominator == 1:
            return x, y


def _near_vertex(rng):
    """A diamond vertex (one coordinate whole, the other a half: (k, j + ½) or (i + ½, k)), or 1/256 off it."""
    whole, half = Fraction(rng.randint(0, W)), Fraction(rng.randint(0, H - 1)) + Fraction(1, 2)
    if rng.random() < 0.5:
        x, y = whole, half
    else:
        x, y = Fraction(rng.randint(0, W - 1)) + Fraction(1, 2), Fraction(rng.randint(0, H))
    nudge = Fraction(1, 256)
    return _clamp((x + rng.choice((-1, 0, 0, 1)) * nudge, y + rng.choice((-1, 0, 0, 1)) * nudge))


def _clamp(p):
    return min(max(p[0], Fraction(0)), Fraction(W)), min(max(p[1], Fraction(0)), Fraction(H))


def _segments(kind, count, seed=SEED):
    rng = random.Random(f"{seed}-{kind}")
    out = []
    while len(out) < count:
        if kind == "grid_1_256":
            a, b = _on_1_256(rng), _on_1_256(rng)
        elif kind == "centres":
            a, b = _centre(rng), _centre(rng)
        elif kind == "edges_corners":
            a, b = _edge_or_corner(rng), _edge_or_corner(rng)
        elif kind == "grid_1_8":                       # ties with diamond vertices are common
            a = _grid(rng, Fraction(1, 8), 0, W), _grid(rng, Fraction(1, 8), 0, H)
            b = _grid(rng, Fraction(1, 8), 0, W), _grid(rng, Fraction(1, 8), 0, H)
        elif kind == "near_vertices":                  # a diamond vertex, or 1/256 beside it, at both ends
            a, b = _near_vertex(rng), _near_vertex(rng)
            if rng.random() < 0.5:                     # and short ones, within two pixels
                b = _clamp((a[0] + _grid(rng, Fraction(1, 2), -2, 2) + rng.choice((-1, 0, 1)) * Fraction(1, 256),
                            a[1] + _grid(rng, Fraction(1, 2), -2, 2) + rng.choice((-1, 0, 1)) * Fraction(1, 256)))
        elif kind == "short":                          # within two pixels, often inside one diamond
            a = _on_1_256(rng) if rng.random() < 0.5 else (_grid(rng, Fraction(1, 8), 0, W),
                                                           _grid(rng, Fraction(1, 8), 0, H))
            step = Fraction(1, 256) if rng.random() < 0.5 else Fraction(1, 8)
            b = _clamp((a[0] + _grid(rng, step, -2, 2), a[1] + _grid(rng, step, -2, 2)))
        elif kind == "horizontal":
            a = rng.choice([_on_1_256, _centre, _edge_or_corner])(rng)
            b = (rng.choice([_on_1_256, _centre, _edge_or_corner])(rng)[0], a[1])
        elif kind == "vertical":
            a = rng.choice([_on_1_256, _centre, _edge_or_corner])(rng)
            b = (a[0], rng.choice([_on_1_256, _centre, _edge_or_corner])(rng)[1])
        elif kind == "diagonal_45":
            a = rng.choice([_on_1_256, _centre, _edge_or_corner])(rng)
            d = _grid(rng, Fraction(1, 8) if rng.random() < 0.5 else Fraction(1, 256), -H, H)
            b = (a[0] + d, a[1] + rng.choice((d, -d)))
            if not (0 <= b[0] <= W and 0 <= b[1] <= H):
                continue
        else:
            raise AssertionError(kind)
        out.append((a, b))
    return out


KINDS = {"grid_1_256": 800, "centres": 400, "edges_corners": 600, "near_vertices": 600, "grid_1_8": 600,
         "short": 800, "horizontal": 300, "vertical": 300, "diagonal_45": 400}


@pytest.mark.parametrize("kind", list(KINDS))
def test_random_segments_match_the_diamond_exit_reference(kind):
    segments = _segments(kind, KINDS[kind])
    _check(_compare_segments(segments), len(segments))


def test_segments_leaving_the_framebuffer_keep_the_whole_segments_rule_inside_it():
    # clipped segments: inside the framebuffer, exactly the pixels the unclipped segment's rule gives (so a
    # segment along pixel centres that leaves through the right edge keeps its last column: the clipped end
    # is not a new half-open end)
    rng = random.Random(f"{SEED}-leaving")
    segments = []
    for _ in range(400):
        a = _on_1_256(rng) if rng.random() < 0.7 else _edge_or_corner(rng)
        b = (_grid(rng, Fraction(1, 256), -16, W + 16), _grid(rng, Fraction(1, 256), -16, H + 16))
        segments.append((a, b) if rng.random() < 0.5 else (b, a))
    half = Fraction(1, 2)
    segments += [((half + k, half + k), (Fraction(W + 3), half + k)) for k in range(8)]        # out the right
    segments += [((half + k, half + k), (half + k, Fraction(H + 3))) for k in range(8)]        # out the top
    segments += [((Fraction(-3), half + k), (half + 9 + k, half + k)) for k in range(8)]       # in from the left
    segments += [((Fraction(W - 5) + half, half + k), (Fraction(-2), half + k)) for k in range(8)]   # out the left
    _check(_compare_segments(segments), len(segments))


def test_long_segments_on_a_large_framebuffer_match_the_reference(monkeypatch):
    # 2048×1024: snapped coordinates up to 2¹⁹, their products up to 2³⁸ (no 32-bit arithmetic may overflow)
    monkeypatch.setattr(sys.modules[__name__], "W", 2048)
    monkeypatch.setattr(sys.modules[__name__], "H", 1024)
    segments = (_segments("grid_1_256", 40, seed=11) + _segments("near_vertices", 20, seed=11)
                + _segments("diagonal_45", 20, seed=11))
    assert max(max(a[0], b[0]) for a, b in segments) > 1024       # the segments do reach far
    _check(_compare_segments(segments), len(segments))


@pytest.mark.parametrize("width", [1, 2, 3, 4, 5])
def test_wide_lines_match_the_reference_runs_along_the_minor_axis(width):
    segments = (_segments("grid_1_256", 60, seed=width) + _segments("centres", 40, seed=width)
                + _segments("near_vertices", 40, seed=width) + _segments("grid_1_8", 40, seed=width)
                + _segments("edges_corners", 40, seed=width) + _segments("diagonal_45", 40, seed=width)
                + _segments("horizontal", 20, seed=width) + _segments("vertical", 20, seed=width))
    _check(_compare_segments(segments, width), len(segments))


@pytest.mark.parametrize("width", [0.25, 1.4, 1.5, 2.5, 3.7])
def test_fractional_line_widths_round_to_the_nearest_whole_halves_up(width):
    # GL: "the width rounded to the nearest integer (if w = 0, then it is as if w = 1)"; the
    # reference rounds k + ½ up (the spec leaves ties open): 1.5 and 2.5 test that convention
    segments = _segments("grid_1_256", 60, seed=7) + _segments("centres", 30, seed=7)
    _check(_compare_segments(segments, width), len(segments))


def test_color_and_depth_along_a_line_follow_the_parameter_t_at_every_fragment():
    # t = ((p_c − p_a)·(p_b − p_a)) / |p_b − p_a|² at the fragment's centre (GL 4.6 eq. 14.1), clamped
    # to [0, 1]; the color goes 0 → 1 and the depth z_w from (z_a + 1)/2 to (z_b + 1)/2 (w = 1
    # everywhere, so perspective-correct and linear are the same). Endpoints on the 1/256 grid: the
    # snapped segment is the given one.
    segments = _segments("grid_1_256", 150, seed=3) + _segments("diagonal_45", 50, seed=3)
    rng = random.Random(f"{SEED}-depth")
    flat = [p for s in segments for p in s]
    n = len(flat)
    color = np.zeros((n, 4), np.float32)
    color[1::2] = 1.0
    z = np.array([float(_grid(rng, Fraction(1, 64), -1, 1)) for _ in range(n)])
    trace = _draw(flat, "lines", varyings={"color": color}, depth=z)
    f = trace.fragments
    prim = np.asarray(f.primitive_id).tolist()
    bad = []
    for k, x, row, r, d in zip(range(len(prim)), np.asarray(f.x).tolist(), np.asarray(f.y).tolist(),
                               np.asarray(trace.shaded.color)[:, 0].tolist(), np.asarray(f.depth).tolist()):
        a, b = segments[prim[k]]
        t = reference_line_parameter(a, b, (x, H - 1 - row))
        za, zb = (z[2 * prim[k]] + 1) / 2, (z[2 * prim[k] + 1] + 1) / 2
        want_d = float((1 - t) * Fraction(za) + t * Fraction(zb))
        if abs(r - float(t)) > 1e-6 or abs(d - want_d) > 1e-6:
            bad.append(f"segment {prim[k]} {_fmt(a)} → {_fmt(b)} at pixel ({x}, {H - 1 - row}): t = {t} "
                       f"({float(t):.7f}), color {r:.7f}; depth want {want_d:.7f}, softpipe {d:.7f}")
    _check(bad, len(prim))


# --------------------------------------------------------------------- strips and loops

def _polyline(rng, n):
    maker = rng.choice([_on_1_256, _centre, _edge_or_corner])
    return [maker(rng) for _ in range(n)]


@pytest.mark.parametrize("topology", ["line_strip", "line_loop"])
def test_strips_and_loops_hit_each_pixel_as_often_as_their_segments_do(topology):
    rng = random.Random(f"{SEED}-{topology}")
    bad = []
    for case in range(40):
        pts = _polyline(rng, rng.randint(2, 9))
        pairs = list(zip(pts, pts[1:])) + ([(pts[-1], pts[0])] if topology == "line_loop" else [])
        want = Counter()
        for a, b in pairs:
            want.update(_inside(reference_line(a, b)))
        trace = _draw(pts, topology)
        have = Counter((x, H - 1 - row) for x, row in zip(np.asarray(trace.fragments.x).tolist(),
                                                          np.asarray(trace.fragments.y).tolist()))
        if have != want:
            bad.append(f"{topology} {case} through {[_fmt(p) for p in pts]}: only reference "
                       f"{sorted((want - have).items())}, only softpipe {sorted((have - want).items())}")
    _check(bad, 40)


def test_closed_loop_of_pixel_centres_hits_every_pixel_once_joints_included():
    # a rectangle outline through centres: every pixel once, by the rule and (additive) in the picture
    pts = [(Fraction(5, 2), Fraction(3, 2)), (Fraction(41, 2), Fraction(3, 2)),
           (Fraction(41, 2), Fraction(25, 2)), (Fraction(5, 2), Fraction(25, 2))]
    trace = _draw(pts, "line_loop")
    have = Counter((x, H - 1 - row) for x, row in zip(np.asarray(trace.fragments.x).tolist(),
                                                      np.asarray(trace.fragments.y).tolist()))
    outline = ({(i, 1) for i in range(2, 21)} | {(i, 12) for i in range(2, 21)}
               | {(2, j) for j in range(1, 13)} | {(20, j) for j in range(1, 13)})
    assert set(have) == outline and set(have.values()) == {1}


def test_strip_turning_at_a_joint_in_a_gap_hits_the_joint_twice_as_the_rule_does():
    # left, then up from a joint in the gap below (2,0)'s diamond: both segments cross that diamond
    # (tests/test_line_reference.py works it by hand); additive blending shows the pixel twice
    pts = [(Fraction(9, 2), Fraction(1, 8)), (Fraction(19, 8), Fraction(1, 8)), (Fraction(19, 8), Fraction(5, 2))]
    trace = _draw(pts, "line_strip")
    have = Counter((x, H - 1 - row) for x, row in zip(np.asarray(trace.fragments.x).tolist(),
                                                      np.asarray(trace.fragments.y).tolist()))
    assert have == Counter({(2, 0): 2, (3, 0): 1, (4, 0): 1, (2, 1): 1})


# --------------------------------------------------------------------- points

POINT_SIZES = [0.75, 1, 1.5, 2, 2.5, 3, 7]


def _point_positions(rng, count):
    makers = [_on_1_256, _centre, _edge_or_corner, _near_vertex,
              lambda r: (_grid(r, Fraction(1, 8), 0, W), _grid(r, Fraction(1, 8), 0, H)),  # square edges on centres
              lambda r: (_grid(r, Fraction(1, 1024), 0, W), _grid(r, Fraction(1, 1024), 0, H))]  # snapping
    return [rng.choice(makers)(rng) for _ in range(count)]


@pytest.mark.parametrize("size", POINT_SIZES + ["random"])
def test_points_match_the_reference_square(size):
    rng = random.Random(f"{SEED}-points-{size}")
    bad = []
    sizes = ([size] if size != "random" else [float(_grid(rng, Fraction(1, 64), Fraction(3, 4), 7))
                                              for _ in range(6)])
    total = 0
    for s in sizes:
        pts = _point_positions(rng, 300 if size != "random" else 60)
        total += len(pts)
        got = _fragments_by_primitive(_draw(pts, "points", point_size=s), len(pts))
        for k, p in enumerate(pts):
            want = _inside(reference_point(p, s))
            twice = sorted(q for q, c in got[k].items() if c > 1)
            if set(got[k]) != want or twice:
                bad.append(f"point {k} at {_fmt(p)} size {s}: reference {sorted(want)}, softpipe "
                           f"{sorted(got[k])}" + (f", twice: {twice}" if twice else ""))
    _check(bad, total)
