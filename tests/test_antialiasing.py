"""Supersampling and multisampling: one rasterizer, fed sample patterns (FORMULAS §23, §24)."""
from fractions import Fraction

import numpy as np
import pytest
import reference
from conftest import window_to_clip

import softpipe as sp
from softpipe.pipeline.sampling import SUBPIXEL, grid, jittered, pattern_named, random_pattern, rotated_grid_4x

PATTERNS = [sp.CENTER, grid(2), grid(3), grid(4), rotated_grid_4x(), jittered(4, seed=3), random_pattern(8, seed=5)]
IDS = [p.name for p in PATTERNS]


def exact_positions(pattern):
    return [(Fraction(int(ox), SUBPIXEL) + Fraction(1, 2), Fraction(int(oy), SUBPIXEL) + Fraction(1, 2))
            for ox, oy in pattern.offsets]


def white(n):
    return {"color": np.ones((n, 3))}


# ------------------------------------------------------------------ patterns

def test_grid_positions_are_the_notes_positions():
    # FORMULAS §24: ((i + ½)/s, (j + ½)/s); for s = 2: 0.25 and 0.75 (exact on the 1/256 grid)
    pos = grid(2).positions
    assert sorted(map(tuple, pos)) == [(0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)]
    # s = 3: 1/6 is not on the 1/256 grid: it snaps to 43/256 (42.67 rounds to 43)
    assert sorted({p[0] for p in grid(3).positions}) == [43 / 256, 128 / 256, 213 / 256]


def test_rotated_grid_is_the_standard_pattern_with_y_up():
    # D3D's standard 4× pattern, y down from the top-left: (0.375, 0.125), (0.875, 0.375),
    # (0.125, 0.625), (0.625, 0.875); softpipe's pixel space is y up.
    assert [tuple(p) for p in rotated_grid_4x().positions] == [
        (0.375, 0.875), (0.875, 0.625), (0.125, 0.375), (0.625, 0.125)]


def test_jittered_is_stratified_and_seeded():
    a, b, c = jittered(4, seed=1), jittered(4, seed=1), jittered(4, seed=2)
    assert np.array_equal(a.positions, b.positions) and not np.array_equal(a.positions, c.positions)
    cells = {(int(x * 4), int(y * 4)) for x, y in a.positions}
    assert len(cells) == 16                       # one sample per cell of the 4×4 grid


def test_pattern_names_and_errors():
    assert len(pattern_named("grid16")) == 16 and len(pattern_named("rgss4")) == 4
    with pytest.raises(ValueError, match="square number"):
        pattern_named("grid8")
    with pytest.raises(ValueError, match="unknown sample pattern"):
        pattern_named("msaa")
    with pytest.raises(ValueError, match=r"\[0, 1\)"):
        sp.SamplePattern([(1.0, 0.5)])
    with pytest.raises(ValueError, match="at most MAX_SAMPLES = 64"):
        sp.SamplePattern(np.full((65, 2), 0.5))


# --------------------------------------------------------- coverage fraction

@pytest.mark.parametrize("pattern", PATTERNS, ids=IDS)
@pytest.mark.parametrize("slope", [(3, 1), (1, 2), (5, 4)])
def test_resolved_value_is_the_fraction_of_samples_inside(pattern, slope):
    # A big triangle whose hypotenuse crosses the 8×8 framebuffer at a known angle.
    # Vertices on the 1/256 grid, so snapping moves nothing. The expected value per
    # pixel is the count of the pattern's (snapped) sample positions that the exact
    # reference covers, divided by the sample count.
    dx, dy = slope
    a = (Fraction(-3), Fraction(-2))
    b = (a[0] + 4 * dx * Fraction(8, 1), a[1] + 4 * dy * Fraction(8, 1))
    tri = [a, b, (Fraction(-40), Fraction(60))]
    size = 8
    fb = sp.Framebuffer(size, size, pattern=pattern)
    sp.draw(fb, window_to_clip([(float(x), float(y)) for x, y in tri], size, size), varyings=white(3))
    got = fb.color[..., 0]
    want = np.zeros((size, size))
    for i, j, _sample in reference.covered(tri, size, size, samples=exact_positions(pattern)):
        want[size - 1 - j, i] += 1.0 / len(pattern)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    assert 0 < got.sum() < size * size          # the edge really crosses the framebuffer


# ------------------------------------------------- the notes' pseudocode

@pytest.mark.parametrize("s", [2, 4])
def test_grid_supersampling_is_the_average_of_shifted_one_sample_renders(s):
    # FORMULAS §24 as a test: render s² times with one centre sample, the scene
    # shifted so that the centre lands where sample (i, j) is; average.
    size = 16
    rng = np.random.default_rng(11)
    tris = np.round(rng.uniform(-2, size + 2, size=(6, 3, 2)) * 256) / 256
    colors = rng.uniform(0, 1, size=(18, 3))
    depth = rng.uniform(0.1, 0.9, size=(18, 1))

    def render(pattern, shift=(0.0, 0.0)):
        fb = sp.Framebuffer(size, size, pattern=pattern)
        pts = np.c_[tris.reshape(-1, 2) + shift, depth]
        sp.draw(fb, window_to_clip(pts, size, size), varyings={"color": colors})
        return fb

    pattern = grid(s)
    ssaa = render(pattern).color.astype(np.float64)
    total = np.zeros((size, size, 4))
    for sx, sy in pattern.positions:
        total += render(sp.CENTER, (0.5 - sx, 0.5 - sy)).color
    np.testing.assert_allclose(ssaa, (total / s ** 2).astype(np.float32), rtol=0, atol=0)


# ------------------------------------------------------- MSAA vs SSAA

def counting_shader(varyings, uniforms, frag):
    uniforms.counter[0] += 1.0
    c = varyings.color
    return (c[0], c[1], c[2], 1.0)


def test_msaa_and_ssaa_agree_on_coverage_and_msaa_shades_once_per_pixel():
    size = 16
    pts = [(1.3, 0.7), (14.6, 3.2), (5.1, 15.2), (9.9, 9.1), (15.7, 15.4), (2.2, 12.8)]
    clip = window_to_clip(pts, size, size)
    flat_white = {"color": np.ones((6, 3))}
    results = {}
    for mode in ("sample", "center", "centroid"):
        counter = np.zeros(8)
        fb = sp.Framebuffer(size, size, pattern=rotated_grid_4x())
        trace = sp.draw(fb, clip, varyings=flat_white, fragment_shader=counting_shader,
                        uniforms={"counter": counter}, sample_shading=mode, trace=True)
        results[mode] = (fb.color.copy(), int(counter[0]), trace)
    ssaa_img, ssaa_calls, ssaa_trace = results["sample"]
    f = ssaa_trace.fragments
    pixel_prims = {(int(x), int(y), int(t)) for x, y, t in zip(f.x, f.y, f.triangle)}
    assert ssaa_calls == len(f)                  # SSAA: one invocation per covered sample
    for mode in ("center", "centroid"):
        img, calls, trace = results[mode]
        np.testing.assert_array_equal(img, ssaa_img)     # constant color: same coverage, same picture
        assert calls == len(pixel_prims)          # MSAA: once per pixel per primitive
        assert trace.shaded.invocations == calls
    assert len(pixel_prims) < len(f)


def test_msaa_centroid_shades_inside_the_triangle():
    # A sliver covering only the top-right sample of a pixel: shading at the centre
    # extrapolates outside the triangle; the centroid is the covered sample itself.
    def where(varyings, uniforms, frag):
        return (frag.x, frag.y, 0.0, 1.0)

    size = 4
    pattern = rotated_grid_4x()              # sample 0 at (0.375, 0.875) within the pixel
    tri = [(1.3, 2.83), (1.45, 2.83), (1.3, 2.95)]
    for mode, want in (("center", (1.5, 2.5)), ("centroid", (1.375, 2.875))):
        fb = sp.Framebuffer(size, size, pattern=pattern)
        trace = sp.draw(fb, window_to_clip(tri, size, size), varyings=white(3), fragment_shader=where,
                        sample_shading=mode, trace=True)
        assert len(trace.fragments) == 1 and int(trace.fragments.sample[0]) == 0
        assert tuple(trace.shaded.color[0, :2]) == want


def test_depth_test_runs_per_sample():
    # Two triangles crossing in depth inside one pixel: each sample keeps the nearer one.
    size = 1
    pattern = grid(2)
    # a: depth rises left to right 0.2 → 0.8; b: constant 0.5. Left samples (x = 0.25)
    # keep a (depth 0.2 + 0.6·0.25... < 0.5), right samples (x = 0.75) keep b.
    big = [(-4, -4), (8, -4), (-4, 8)]
    za = lambda x: 0.5 + (x - 0.5) * 0.8          # noqa: E731  linear in window x
    pa = window_to_clip([(x, y, 2 * za(x) - 1) for x, y in big], size, size)
    pb = window_to_clip([(x, y, 0.0) for x, y in big], size, size)   # z_ndc 0 → depth 0.5
    fb = sp.Framebuffer(size, size, pattern=pattern)
    sp.draw(fb, pa, varyings={"color": np.tile([1.0, 0, 0], (3, 1))})
    sp.draw(fb, pb, varyings={"color": np.tile([0, 0, 1.0], (3, 1))})
    s = fb.samples_color[:, 0, 0]
    for k, (sx, _sy) in enumerate(pattern.positions):
        nearer_a = za(sx) < 0.5
        assert tuple(s[k, :3]) == ((1.0, 0.0, 0.0) if nearer_a else (0.0, 0.0, 1.0))
    assert fb.color[0, 0, 0] == 0.5 and fb.color[0, 0, 2] == 0.5


# ------------------------------------------------------------ watertight

@pytest.mark.parametrize("pattern", [grid(4), rotated_grid_4x(), jittered(4, seed=9)], ids=lambda p: p.name)
def test_two_triangles_sharing_an_edge_leave_no_seam(pattern):
    size = 8
    quad = [(0, 0), (8, 0), (8, 8), (0, 8)]
    d = (8 * 256 // 3) / 256                       # a diagonal-ish shared edge off the grid lines
    a, b, c, e = quad[0], quad[1], (8, 8), (0, 8)
    tris = [a, b, (d, 8), a, (d, 8), e, b, c, (d, 8)]
    fb = sp.Framebuffer(size, size, pattern=pattern)
    trace = sp.draw(fb, window_to_clip(tris, size, size), varyings=white(9), trace=True)
    f = trace.fragments
    hits = np.zeros((size, size, len(pattern)), int)
    np.add.at(hits, (f.y, f.x, f.sample), 1)
    assert (hits == 1).all()
    assert (fb.color[..., :3] == 1.0).all()


def test_tent_resolve_weights_neighbours_and_box_is_the_mean():
    # 3×3 pixels with a 2×2 grid each; only the centre pixel's samples are white.
    fb = sp.Framebuffer(3, 3, pattern=grid(2))
    fb.clear((0.0, 0.0, 0.0, 0.0))
    fb.samples_color[:, 1, 1] = (1.0, 1.0, 1.0, 1.0)
    box = fb.resolve("box")
    assert box[1, 1, 0] == 1.0 and box[1, 0, 0] == 0.0
    tent = fb.resolve("tent")
    # Sample offsets from a pixel's centre along one axis, over the three columns:
    # −1.25, −0.75, −0.25, 0.25, 0.75, 1.25 with tent weights 0, .25, .75, .75, .25, 0
    # (sum 2 per axis, 4 in all). Centre pixel: its own samples weigh (2·0.75)² = 2.25.
    assert tent[1, 1, 0] == pytest.approx(2.25 / 4, abs=1e-6)
    # Left neighbour: the centre pixel's samples sit at dx = 0.75, 1.25 (weights .25, 0)
    # and dy = ±0.25 (weights .75 each): 0.25 · 1.5 = 0.375.
    assert tent[1, 0, 0] == pytest.approx(0.375 / 4, abs=1e-6)
    # Diagonal neighbour: 0.25 · 0.25.
    assert tent[0, 0, 0] == pytest.approx(0.0625 / 4, abs=1e-6)
    with pytest.raises(ValueError, match="'box' or 'tent'"):
        fb.resolve("gauss")
