"""The rasterizer against hand-listed pixels and against the exact reference (tests/reference.py).

Coordinates in these tests are OpenGL window coordinates (y up); softpipe's
Fragments hold image rows (row 0 at the top), so a window row j is image row
height − 1 − j.
"""

import numpy as np
import pytest
import reference
from conftest import window_prims

from softpipe.pipeline.raster import count_fragments, rasterize, snap


def covered(tris, width, height):
    """softpipe's coverage as a set of (i, j_window, triangle)."""
    prims = window_prims(tris)
    f = rasterize(prims, width, height)
    return {(int(x), height - 1 - int(y), int(t)) for x, y, t in zip(f.x, f.y, f.triangle)}


def pixels(tri, width, height):
    return {(i, j) for i, j, _ in covered([tri], width, height)}


def diff_picture(got, want, width, height):
    rows = []
    for j in reversed(range(height)):
        row = ""
        for i in range(width):
            g, w = (i, j) in got, (i, j) in want
            row += "#" if g and w else "+" if g else "-" if w else "."
        rows.append(row)
    return "\n".join(rows) + "\n(# both, + softpipe only, - reference only)"


# ------------------------------------------------------------------ snapping

def test_snap_rounds_half_to_even_on_the_256_grid():
    # pixel centre of pixel i is at fixed point 256 i
    assert snap(0.5) == 0 and snap(3.5) == 768
    # (x − ½)·256 = 0.5 → 0 (even), 1.5 → 2, 2.5 → 2, −0.5 → 0
    assert snap(0.5 + 0.5 / 256) == 0
    assert snap(0.5 + 1.5 / 256) == 2
    assert snap(0.5 + 2.5 / 256) == 2
    assert snap(0.5 - 0.5 / 256) == 0
    assert snap(0.5 + 0.6 / 256) == 1


# ------------------------------------------------------- hand-listed triangles

def test_right_triangle_lists_its_pixels():
    # (0,0), (4,0), (0,4): centres (i+½, j+½) with i + j + 1 < 4 are inside;
    # those with i + j + 1 = 4 lie on the hypotenuse, a right edge: not covered.
    got = pixels([(0, 0), (4, 0), (0, 4)], 4, 4)
    assert got == {(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (0, 2)}


def test_sample_on_bottom_edge_is_covered_and_on_top_edge_is_not():
    # A rectangle 2×1 at y ∈ [0.5, 1.5]: its bottom edge y = 0.5 passes through the
    # centres of row 0, its top edge y = 1.5 through the centres of row 1.
    lower = [(0, 0.5), (2, 0.5), (2, 1.5)]   # bottom edge horizontal, CCW
    upper = [(0, 0.5), (2, 1.5), (0, 1.5)]   # top edge horizontal
    got_lower = pixels(lower, 2, 2)
    got_upper = pixels(upper, 2, 2)
    # lower: centre (0.5,0.5) on bottom edge (owned) and on nothing else → covered;
    # (1.5, 0.5) on the bottom edge and inside the right edge x=2 → covered.
    # Row 1's centres are on y = 1.5, which is outside lower (above its top vertex).
    assert got_lower == {(0, 0), (1, 0)}
    # upper: row 1 centres lie on its top edge (not owned); row 0 centres are
    # below the diagonal except... (0.5, 0.5) is below the diagonal y − 0.5 = x/2.
    assert got_upper == set()


def test_sample_on_left_edge_is_covered_and_on_right_edge_is_not():
    # A tall triangle whose left edge x = 0.5 runs through the centres of column 0.
    tri = [(0.5, 0), (3, 4), (0.5, 4)]          # CCW? (0.5,0)→(3,4)→(0.5,4): yes
    got = pixels(tri, 4, 4)
    assert all(i >= 0 for i, _ in got)
    # column 0 centres are exactly on the left edge: all four rows owned
    assert {(0, j) for j in range(4)} <= got
    # Mirror it so that x = 3.5 is a right edge through column 3's centres.
    mirror = [(3.5, 0), (3.5, 4), (1, 4)]
    got_m = pixels(mirror, 4, 4)
    assert not any(i == 3 for i, _ in got_m)
    # independently: the reference agrees on both
    assert got == {(i, j) for i, j, _ in reference.covered(tri, 4, 4)}
    assert got_m == {(i, j) for i, j, _ in reference.covered(mirror, 4, 4)}


def test_sample_exactly_on_a_vertex():
    # Vertex at the centre of pixel (1, 1). The sample there lies on two edges;
    # it is covered only if both own it.
    # Triangle with the vertex as its bottom-left corner: left edge and bottom edge
    # meet there, both owned → covered.
    bl = [(1.5, 1.5), (3.5, 1.5), (1.5, 3.5)]
    assert (1, 1) in pixels(bl, 4, 4)
    # As the top corner of a triangle below it: the two edges are a left edge
    # (going down from the top) and a right edge → not covered.
    top = [(0.2, 0.2), (3.1, 0.2), (1.5, 1.5)]
    assert (1, 1) not in pixels(top, 4, 4)
    # As the right corner of a triangle to the left: upper edge is top-ish (not owned).
    right = [(0.2, 0.7), (1.5, 1.5), (0.2, 2.3)]
    assert (1, 1) not in pixels(right, 4, 4)


def test_bottom_edge_owned_only_on_the_triangle_above():
    # Two triangles sharing the horizontal edge y = 1.5 through row 1's centres.
    below = [(0, 0), (4, 1.5), (0, 1.5)]     # the edge is its top
    above = [(0, 1.5), (4, 1.5), (0, 3)]     # the edge is its bottom
    on_edge = {(i, 1) for i in range(4)}
    got_below, got_above = pixels(below, 4, 4), pixels(above, 4, 4)
    assert not (on_edge & got_below)
    # (3,1): centre (3.5, 1.5) is on the bottom edge and inside the hypotenuse?
    # hypotenuse from (4,1.5) to (0,3): at y=1.5 x=4 > 3.5 → inside.
    assert on_edge <= got_above


def test_clockwise_triangle_covers_the_same_pixels():
    ccw = [(0.3, 0.2), (3.7, 1.1), (1.2, 3.9)]
    cw = [ccw[0], ccw[2], ccw[1]]
    assert pixels(ccw, 4, 4) == pixels(cw, 4, 4)
    assert len(pixels(ccw, 4, 4)) > 0


def test_zero_area_after_snapping_produces_nothing():
    # These three points are collinear only after snapping to 1/256.
    tri = [(0.5, 0.5), (2.5, 0.5 + 0.1 / 256), (3.5, 0.5)]
    assert snap(0.5 + 0.1 / 256) == snap(0.5)
    assert pixels(tri, 4, 4) == set()
    prims = window_prims([tri])
    assert count_fragments(prims, 4, 4)[0] == 0


def test_triangle_outside_the_framebuffer_is_clamped_not_wrapped():
    tri = [(-10, -10), (20, -10), (-10, 20)]     # covers the whole 4×4 and beyond
    got = pixels(tri, 4, 4)
    assert got == {(i, j) for i in range(4) for j in range(4)}


def test_depth_is_linear_in_window_space():
    tri = [(0, 0, 0.0), (4, 0, 1.0), (0, 4, 0.5)]
    f = rasterize(window_prims([tri]), 4, 4)
    # The pixels of test_right_triangle_lists_its_pixels, one fragment each: a depth
    # check over no fragments (or over some of them) would prove nothing.
    assert len(f) == 6
    assert {(int(x), 3 - int(y)) for x, y in zip(f.x, f.y)} == {(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (0, 2)}
    for x, y, z in zip(f.x, f.y, f.depth):
        i, j = x + 0.5, (3 - y) + 0.5
        b1, b2 = i / 4, j / 4                      # barycentrics of this right triangle
        assert z == pytest.approx(0.0 * (1 - b1 - b2) + 1.0 * b1 + 0.5 * b2, abs=1e-12)


def test_barycentrics_sum_to_one_and_match_the_position():
    tri = [(0.25, 0.5), (7.5, 1.0), (2.0, 6.75)]
    f = rasterize(window_prims([tri]), 8, 8)
    assert len(f) > 0
    np.testing.assert_allclose(f.bary.sum(axis=1), 1.0, atol=1e-12)
    corners = np.array([[snap(x) / 256 + 0.5, snap(y) / 256 + 0.5] for x, y in tri])
    pos = f.bary @ corners
    np.testing.assert_allclose(pos[:, 0], f.x + 0.5, atol=1e-9)
    np.testing.assert_allclose(pos[:, 1], (7 - f.y) + 0.5, atol=1e-9)


# ---------------------------------------------------- random vs the reference

def random_triangle(rng, size):
    # vertices on the 1/256 grid, some exactly on pixel centres and edges
    pts = rng.integers(-64, size * 256 + 64, size=(3, 2)) / 256
    if rng.random() < 0.3:
        pts = np.round(pts * 2) / 2               # on half-pixel positions: many ties
    return [tuple(p) for p in pts]


def test_random_triangles_match_the_exact_reference(rng):
    size = 12
    tris = [random_triangle(rng, size) for _ in range(120)]
    got = covered(tris, size, size)
    for t, tri in enumerate(tris):
        mine = {(i, j) for i, j, k in got if k == t}
        want = {(i, j) for i, j, _ in reference.covered(tri, size, size)}
        assert mine == want, f"triangle {t} {tri}:\n" + diff_picture(mine, want, size, size)


def test_the_fill_rule_answers_alike_at_a_sample_on_edge_values_and_edge_by_edge(rng):
    """setup's one fill rule in its three forms: ``covers`` at a position (the reference rasterizer),
    ``inside`` on a sample's edge values (the fast path's narrow walker, which steps them) and
    ``inside_edge`` edge by edge (its row spans): the same answer at every pixel centre, many on
    edges and corners, and the exact reference's."""
    from softpipe.pipeline.sampling import CENTER
    from softpipe.pipeline.setup import covers, edge_values, inside, inside_edge, pixel_rect, setup_triangles
    size = 12
    tris = [random_triangle(rng, size) for _ in range(80)]
    setup = setup_triangles(window_prims(tris).window, pixel_rect(size, size), CENTER.offsets)
    edges, bias = setup.edges, setup.bias
    on_an_edge = 0
    for t, tri in enumerate(tris):
        want = {(i, j) for i, j, _ in reference.covered(tri, size, size)}
        for j in range(size):
            for i in range(size):
                px, py = 256 * i, 256 * j
                e = edge_values(edges, t, px, py)
                by_edge = all(inside_edge(e[k], bias, t, k) for k in range(3))
                got = {covers(edges, bias, t, px, py), inside(*e, bias, t), by_edge}
                assert got == {(i, j) in want}, (t, tri, i, j, e, bias[t])
                on_an_edge += setup.area[t] != 0 and 0 in e
    assert on_an_edge > 10          # the ties the bias decides are among them (34 to 152 over 40 seeds)


# ----------------------------------------------------------------- watertight

def test_grid_of_quads_covers_every_pixel_exactly_once(rng):
    # a 5×5 grid of quads over an 11×11 framebuffer, with jittered interior
    # vertices on the 1/256 grid, each quad split along a random diagonal
    size, n = 11, 5
    g = np.linspace(0, size, n + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")
    jitter = rng.integers(-80, 80, size=X.shape + (2,)) / 256
    jitter[[0, -1], :, 0] = 0
    jitter[:, [0, -1], 1] = 0
    P = np.stack([X, Y], axis=-1) + jitter
    tris = []
    for a in range(n):
        for b in range(n):
            p00, p10, p01, p11 = P[a, b], P[a + 1, b], P[a, b + 1], P[a + 1, b + 1]
            if rng.random() < 0.5:
                tris += [[p00, p10, p11], [p00, p11, p01]]
            else:
                tris += [[p00, p10, p01], [p10, p11, p01]]
    f = rasterize(window_prims(tris), size, size)
    hits = np.zeros((size, size), int)
    np.add.at(hits, (f.y, f.x), 1)
    assert (hits == 1).all(), f"coverage counts:\n{hits}"


def test_fan_around_a_vertex_at_a_pixel_centre_covers_once():
    # 12 triangles around the centre of pixel (5, 5); the centre sample lies on
    # every triangle's corner and 24 edges meet there.
    size = 11
    c = np.array([5.5, 5.5])
    angles = np.linspace(0, 2 * np.pi, 13)[:-1] + 0.1
    ring = c + 10.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    ring = np.round(ring * 256) / 256
    tris = [[c, ring[k], ring[(k + 1) % 12]] for k in range(12)]
    f = rasterize(window_prims(tris), size, size)
    hits = np.zeros((size, size), int)
    np.add.at(hits, (f.y, f.x), 1)
    assert (hits == 1).all(), f"coverage counts:\n{hits}"
    # the centre pixel is covered by exactly one triangle of the fan
    at_centre = [int(t) for x, y, t in zip(f.x, f.y, f.triangle) if x == 5 and y == size - 1 - 5]
    assert len(at_centre) == 1
