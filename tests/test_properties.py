"""Properties of the pipeline on scenes nobody chose (hypothesis): issue 7.

Every test here states one property and checks it on random scenes: small
framebuffers (8×8 to 32×32 unless the property needs larger), vertices on the
rasterizer's 1/256-pixel grid (often on coarser grids too, so that samples land
exactly on edges and vertices and the fill rule is exercised).

Coordinates: "fixed" units are 1/256 pixel with the centre of pixel i at 256·i,
so the window coordinate of fixed X is (X + 128)/256 and softpipe snaps it back
to exactly X. Window rows j count from the bottom (y up); the framebuffer's
image rows from the top.

Profiles (registered here, selected by SOFTPIPE_HYPOTHESIS_PROFILE)
------------------------------------------------------------------
``ci`` (the default): 30 examples per property, derandomized — every run tries
the same examples, so CI is deterministic — and no example database. The
subprocess tests (thread counts, pure Python) render 3 and 2 fixed seeds.

``long``: 2000 examples per property, random, with hypothesis' example database
(``.hypothesis/``) so that a failure found once is replayed first next time;
the subprocess tests render 20 and 6 seeds::

    SOFTPIPE_HYPOTHESIS_PROFILE=long .venv/bin/python -m pytest tests/test_properties.py tests/test_limits.py

``--hypothesis-show-statistics`` shows what the examples were like (how many
samples they covered, how many corners clipping made, …).

Reproducing a failure
---------------------
hypothesis prints the shrunk falsifying example (every value it drew) and a
``@reproduce_failure(...)`` line; the ``note`` lines above it show the scene
and a picture of the difference. Under ``ci`` just re-run the test
(``-k test_name``): the examples are derandomized. Under ``long`` re-running
replays the failure from ``.hypothesis/``; or paste the printed
``@reproduce_failure`` decorator above the test; or run with
``--hypothesis-seed=N`` (the seed pytest printed).
"""
import os
import subprocess
import sys
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
import reference
from conftest import window_prims, window_to_clip
from hypothesis import HealthCheck, assume, event, example, given, note, settings
from hypothesis import strategies as st

import softpipe
from softpipe.pipeline.assembly import GUARD_PIXELS, W_MIN
from softpipe.pipeline.merge_state import DEPTH_FUNCS
from softpipe.pipeline.raster import rasterize
from softpipe.pipeline.sampling import CENTER, grid, rotated_grid_4x
from softpipe.pipeline.tiles import TILE_H, TILE_W

# ------------------------------------------------------------ hypothesis profiles

_COMMON = dict(deadline=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("ci", max_examples=30, derandomize=True, database=None, **_COMMON)
settings.register_profile("long", max_examples=2000, **_COMMON)
PROFILE_NAME = os.environ.get("SOFTPIPE_HYPOTHESIS_PROFILE", "ci")
settings.load_profile(PROFILE_NAME)
PROFILE = settings.get_profile(PROFILE_NAME)
LONG = PROFILE_NAME == "long"


def examples(fraction: float = 1.0) -> settings:
    """This module's profile, with ``fraction`` of its examples (for a property that costs more)."""
    return settings(PROFILE, max_examples=max(3, int(PROFILE.max_examples * fraction)))


@pytest.fixture(autouse=True)
def _how_to_reproduce(request):
    # printed with a failing test's captured output
    print(f"hypothesis profile {PROFILE_NAME!r} ({PROFILE.max_examples} examples, "
          f"derandomize={PROFILE.derandomize}); reproduce: SOFTPIPE_HYPOTHESIS_PROFILE={PROFILE_NAME} "
          f"{sys.executable} -m pytest {request.node.nodeid!r}")


# ------------------------------------------------------------------- helpers

SUB = 256
PATTERNS = {"1": CENTER, "grid(2)": grid(2), "rotated_grid_4x": rotated_grid_4x()}
pattern_names = st.sampled_from(list(PATTERNS))
sizes = st.integers(8, 32)
#: grid steps (fixed units) for coordinates: any 1/256, odd, the 4× pattern's 1/8, grid(2)'s 1/4,
#: pixel corners and centres
quanta = st.sampled_from([1, 7, 32, 64, 128, 256])


def on_grid(v: int, q: int) -> int:
    return v - v % q


def points(xs, ys, n: int) -> st.SearchStrategy:
    """n distinct points (x, y): left alone, hypothesis likes to make every corner the same."""
    return st.lists(st.tuples(xs, ys), min_size=n, max_size=n, unique=True)


def window_of(X) -> float:
    """The window coordinate that softpipe snaps to fixed X."""
    return (X + SUB // 2) / SUB


def id_shader(varyings, uniforms, frag):
    """The primitive id + 1 in red (exact in float32), so 0 means "not drawn"."""
    return (frag.primitive_id + 1.0, 0.0, 0.0, 1.0)


def planes(a: np.ndarray, fb) -> np.ndarray:
    """A per-sample buffer ([H, W, S, …] or [S, H, W, …], whichever softpipe stores) as [S, H, W, …]."""
    if a.shape[:3] == (fb.samples, fb.height, fb.width):
        return a
    assert a.shape[:3] == (fb.height, fb.width, fb.samples), a.shape
    return np.moveaxis(a, 2, 0)


def sample_grid(width: int, height: int, pattern):
    """Fixed coordinates of every sample as arrays [S, J, I] (J = window row, from the bottom)."""
    off = pattern.offsets
    j, i = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    px = SUB * i[None] + off[:, 0, None, None]
    py = SUB * j[None] + off[:, 1, None, None]
    return px.astype(np.int64), py.astype(np.int64)


def fragment_counts(frags, width: int, height: int, samples: int) -> np.ndarray:
    """How many fragments each sample got: int [S, J, I] (window rows)."""
    counts = np.zeros((samples, height, width), np.int64)
    np.add.at(counts, (frags.sample, height - 1 - frags.y, frags.x), 1)
    return counts


def perturbed_winding(poly, px, py) -> np.ndarray:
    """Winding number of the polygon around each sample p moved to p + (ε, δ), 0 < δ ≪ ε ≪ 1/256.

    This is the fill rule stated geometrically: a sample exactly on an edge
    belongs to the side that the nudge right (and, on a horizontal edge, up)
    takes it to — left edges and bottom edges own their samples. The moved
    point is on no edge, so it is inside or outside, never on the boundary,
    and a tiling of the polygon covers it exactly once if inside and never if
    outside. Exact: integer arithmetic on fixed coordinates.
    """
    wn = np.zeros(px.shape, np.int64)
    n = len(poly)
    for k in range(n):
        (ax, ay), (bx, by) = poly[k], poly[(k + 1) % n]
        dx, dy = bx - ax, by - ay
        if dy == 0:
            continue                     # horizontal: never crosses the line y = p_y + δ
        cross = dx * (py - ay) - dy * (px - ax)
        # cross(b − a, p' − a) = cross + dx·δ − dy·ε: a zero cross takes the sign of −dy
        left = (cross > 0) | ((cross == 0) & (dy < 0))
        right = (cross < 0) | ((cross == 0) & (dy > 0))
        upward = (ay <= py) & (by > py)
        downward = (by <= py) & (ay > py)
        wn += (upward & left).astype(np.int64) - (downward & right).astype(np.int64)
    return wn


def picture(diff: np.ndarray) -> str:
    """[J, I] int array (window rows) as text, top row first: '.' 0, digits otherwise."""
    return "\n".join("".join("." if v == 0 else "#" if v > 9 else str(v) if v > 0 else "-" for v in row)
                     for row in diff[::-1])


def bucket(n: int) -> str:
    """A count, coarsely, for hypothesis' statistics (--hypothesis-show-statistics)."""
    return "0" if n == 0 else "1-9" if n < 10 else "10-99" if n < 100 else "100+"


def orient(a, b, c) -> int:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def reorder(tri, rotation: int, flip: bool):
    """The same triangle with its corners rotated and, with ``flip``, its winding reversed."""
    tri = list(tri[rotation:]) + list(tri[:rotation])
    return [tri[0], tri[2], tri[1]] if flip else tri


# ========================================================== 1. watertight

@st.composite
def fans(draw):
    """A closed fan: a centre and a ring of 3–12 corners around it, in fixed units.

    Angular gaps are 0.3 rad to 0.95π and radii at least 2 px, so that snapping
    the ring to its grid cannot fold a triangle over (checked exactly below);
    the ring may leave the framebuffer.
    """
    w, h = draw(sizes), draw(sizes)
    q, q_ring = draw(quanta), draw(st.sampled_from([1, 32, 64]))
    c = (on_grid(draw(st.integers(0, SUB * w - 1)), q), on_grid(draw(st.integers(0, SUB * h - 1)), q))
    n = draw(st.integers(3, 12))
    g = np.array(draw(st.lists(st.floats(1.0, 1.8), min_size=n, max_size=n)))
    angles = draw(st.floats(0, 2 * np.pi)) + 2 * np.pi * np.concatenate([[0], np.cumsum(g[:-1])]) / g.sum()
    radii = draw(st.lists(st.floats(2.0, 1.5 * max(w, h)), min_size=n, max_size=n))
    ring = [(on_grid(int(round(c[0] + SUB * r * np.cos(a))), q_ring),
             on_grid(int(round(c[1] + SUB * r * np.sin(a))), q_ring)) for a, r in zip(angles, radii)]
    assume(all(orient(c, ring[k], ring[(k + 1) % n]) > 0 for k in range(n)))
    tris = [reorder([c, ring[k], ring[(k + 1) % n]], draw(st.integers(0, 2)), draw(st.booleans()))
            for k in range(n)]
    return w, h, ring, tris


def convex_hull(points):
    """Strictly convex hull, counter-clockwise (monotone chain, exact)."""
    pts = sorted(set(points))
    if len(pts) < 3:
        return pts
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and orient(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and orient(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


@st.composite
def convex_triangulations(draw):
    """A random triangulation of a random convex polygon (any of its triangulations can come out)."""
    w, h = draw(sizes), draw(sizes)
    q = draw(quanta)
    coord = lambda n: st.integers(-2 * SUB, SUB * (n + 2)).map(lambda v: on_grid(v, q))  # noqa: E731
    hull = convex_hull(draw(st.lists(st.tuples(coord(w), coord(h)), min_size=3, max_size=14)))
    assume(len(hull) >= 3)
    start = draw(st.integers(0, len(hull) - 1))
    hull = hull[start:] + hull[:start]
    tris = []

    def split(poly):            # the edge poly[0]–poly[-1] lies in exactly one triangle: pick its apex
        if len(poly) < 3:
            return
        k = draw(st.integers(1, len(poly) - 2))
        tris.append(reorder([poly[0], poly[k], poly[-1]], draw(st.integers(0, 2)), draw(st.booleans())))
        split(poly[:k + 1])
        split(poly[k:])

    split(hull)
    order = draw(st.permutations(range(len(tris))))
    return w, h, hull, [tris[k] for k in order]


def check_covers_interior_once(w, h, polygon, tris, pattern_name):
    pattern = PATTERNS[pattern_name]
    win = np.array([[[window_of(x), window_of(y)] for x, y in t] for t in tris])
    frags = rasterize(window_prims(win), w, h, pattern)
    counts = fragment_counts(frags, w, h, len(pattern))
    px, py = sample_grid(w, h, pattern)
    want = perturbed_winding(polygon, px, py)
    assert set(np.unique(want)) <= {0, 1}, "test bug: the polygon is not simple and counter-clockwise"
    event(f"inside samples: {bucket(int(want.sum()))}")
    note(f"{w}×{h}, {pattern_name}, polygon {polygon}, triangles {tris}")
    for s in range(len(pattern)):
        if not np.array_equal(counts[s], want[s]):
            note(f"sample {s}: coverage count minus expected (window rows, top first):\n"
                 + picture(counts[s] - want[s]))
    assert np.array_equal(counts, want), "some samples were covered twice or missed"
    # the fast path's coverage (row spans solved per edge) agrees: the covering triangle is visible
    fb = softpipe.Framebuffer(w, h, pattern).clear((0, 0, 0, 0))
    pos = window_to_clip(win.reshape(-1, 2), w, h)
    softpipe.draw(fb, pos, fragment_shader=id_shader, depth_test="always", path="fast")
    owner = np.zeros((len(pattern), h, w))
    owner[frags.sample, h - 1 - frags.y, frags.x] = frags.triangle + 1.0
    got = planes(fb.samples_color, fb)[..., 0][:, ::-1]          # window rows
    assert np.array_equal(got, owner), "the fast path's coverage differs from the rasterizer's"


@given(fan=fans(), pattern_name=pattern_names)
@examples()
def test_closed_fans_cover_every_sample_of_their_interior_exactly_once(fan, pattern_name):
    w, h, ring, tris = fan
    check_covers_interior_once(w, h, ring, tris, pattern_name)


@given(case=convex_triangulations(), pattern_name=pattern_names)
@examples()
def test_triangulated_convex_polygons_cover_every_sample_of_their_interior_exactly_once(case, pattern_name):
    w, h, hull, tris = case
    check_covers_interior_once(w, h, hull, tris, pattern_name)


# ================================================== 2. coverage = geometry

@st.composite
def triangles(draw, w, h, margin=2):
    q = draw(quanta)
    coord = lambda n: st.integers(-margin * SUB, SUB * (n + margin)).map(lambda v: on_grid(v, q))  # noqa: E731
    return draw(points(coord(w), coord(h), 3))


@st.composite
def one_triangle(draw):
    w, h = draw(sizes), draw(sizes)
    return w, h, draw(triangles(w, h))


@given(case=one_triangle(), pattern_name=pattern_names)
@examples()
def test_covered_samples_are_exactly_those_of_the_exact_rational_reference(case, pattern_name):
    # tests/reference.py decides every sample of the framebuffer with Fractions,
    # fill rule included; softpipe's rasterizer and its fast path must agree sample for sample.
    w, h, tri = case
    pattern = PATTERNS[pattern_name]
    win = [(window_of(x), window_of(y)) for x, y in tri]
    samples = [(F(x), F(y)) for x, y in pattern.positions]
    want = reference.covered([(F(x), F(y)) for x, y in win], w, h, samples)
    frags = rasterize(window_prims([win]), w, h, pattern)
    got = [(int(i), h - 1 - int(r), int(s)) for i, r, s in zip(frags.x, frags.y, frags.sample)]
    note(f"{w}×{h}, {pattern_name}, fixed corners {tri}: {len(want)} samples expected, {len(got)} covered")
    event(f"covered samples: {bucket(len(want))}")
    assert len(got) == len(set(got)), "a sample was emitted twice"
    assert set(got) == want, (f"softpipe only: {sorted(set(got) - want)[:20]}, "
                              f"reference only: {sorted(want - set(got))[:20]}")
    fb = softpipe.Framebuffer(w, h, pattern).clear((0, 0, 0, 0))
    softpipe.draw(fb, window_to_clip(win, w, h), fragment_shader=id_shader, depth_test=None, path="fast")
    red = planes(fb.samples_color, fb)[..., 0]
    fast = {(int(i), h - 1 - int(r), int(s)) for s, r, i in zip(*np.nonzero(red))}
    assert fast == want, f"fast path only: {sorted(fast - want)[:20]}, reference only: {sorted(want - fast)[:20]}"


# ============================================================ 3. translation

@st.composite
def plain_scenes(draw, max_triangles=6):
    """Triangles well inside the clip volume (nothing is clipped but by the framebuffer's edges)."""
    w, h = draw(sizes), draw(sizes)
    n = draw(st.integers(1, max_triangles))
    q = draw(quanta)
    coord = lambda m: st.integers(-4 * SUB, SUB * (m + 4)).map(lambda v: on_grid(v, q))  # noqa: E731
    xy = draw(points(coord(w), coord(h), 3 * n))
    z = draw(st.lists(st.sampled_from([-0.5, 0.0, 0.25]) | st.floats(-0.9, 0.9), min_size=3 * n, max_size=3 * n))
    ws = draw(st.lists(st.sampled_from([1.0]) | st.floats(0.25, 4.0), min_size=3 * n, max_size=3 * n))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    return w, h, np.array(xy, np.int64), np.array(z), np.array(ws), seed


def clip_positions(xy_fixed, z_ndc, w_clip, width, height):
    """Clip coordinates whose window position is exactly the fixed point (after softpipe's snapping)."""
    win = np.stack([window_of(xy_fixed[:, 0]), window_of(xy_fixed[:, 1])], axis=1)
    pos = window_to_clip(win, width, height)
    pos[:, 2] = z_ndc
    return pos * np.asarray(w_clip, float)[:, None]


@st.composite
def shifted(draw, scenes_):
    scene = draw(scenes_)
    w, h = scene[0], scene[1]
    return scene, (draw(st.integers(-(w - 1), w - 1)), draw(st.integers(-(h - 1), h - 1)))


@given(case=shifted(plain_scenes()), pattern_name=st.sampled_from(["1", "grid(2)"]),
       path=st.sampled_from(["reference", "fast"]))
@examples()
def test_moving_a_scene_by_whole_pixels_moves_its_image_exactly(case, pattern_name, path):
    # Edge functions, barycentrics and depth are computed from differences of
    # fixed-point coordinates, so every sample value must move unchanged.
    (w, h, xy, z, ws, seed), (dx, dy) = case
    colors = np.random.default_rng(seed).random((len(xy), 3))
    fbs = []
    for offset in ((0, 0), (dx, dy)):
        fb = softpipe.Framebuffer(w, h, PATTERNS[pattern_name]).clear((0.25, 0.5, 0.75, 1.0))
        pos = clip_positions(xy + SUB * np.array(offset), z, ws, w, h)
        softpipe.draw(fb, pos, varyings={"color": colors}, path=path)
        fbs.append((planes(fb.samples_color, fb), planes(fb.samples_depth, fb)))
    (c0, d0), (c1, d1) = fbs
    # window (i, j) → (i + dx, j + dy); image rows run the other way
    rows0 = slice(max(0, dy), h + min(0, dy))
    rows1 = slice(max(0, -dy), h + min(0, -dy))
    cols0 = slice(max(0, -dx), w + min(0, -dx))
    cols1 = slice(max(0, dx), w + min(0, dx))
    note(f"{w}×{h}, shift ({dx}, {dy}), {pattern_name}, {path}; fixed xy {xy.tolist()}")
    event(f"samples drawn: {bucket(int((c0[..., 2] != np.float32(0.75)).sum()))}")
    assert np.array_equal(c0[:, rows0, cols0], c1[:, rows1, cols1]), "colors did not move exactly"
    assert np.array_equal(d0[:, rows0, cols0], d1[:, rows1, cols1]), "depths did not move exactly"


# ============================== 4 and 5. fast path = reference path, determinism

def scene_shader(varyings, uniforms, frag):
    """Uses every varying (smooth s, noperspective n, flat f) and every FragInfo field."""
    ff = 1.0 if frag.front_facing else 0.0
    return (varyings.s[0] * 0.5 + frag.x * 0.0625,
            varyings.n[1] + frag.y * 0.03125,
            varyings.f * frag.z + 0.25 * ff,
            0.125 * (frag.primitive_id % 8) + varyings.s[2] * 0.1)


SCENE_INTERPOLATION = {"s": "smooth", "n": "noperspective", "f": "flat"}


@st.composite
def draw_states(draw):
    return dict(depth_test=draw(st.sampled_from((None,) + DEPTH_FUNCS)), depth_write=draw(st.booleans()),
                cull=draw(st.sampled_from(["none", "back", "front"])), front_face=draw(st.sampled_from(["ccw", "cw"])))


@st.composite
def scenes(draw, size=(sizes, sizes), pattern=st.sampled_from(["1", "grid(2)"])):
    """1–3 draws into one framebuffer: shared vertices, perspective w, some triangles crossing the
    near/far planes or the framebuffer's edges, ties on the pixel grid, random state, an optional
    viewport (a scissor when it is smaller than the framebuffer) with a depth range."""
    w, h = draw(size[0]), draw(size[1])
    q = draw(quanta)
    if draw(st.booleans()):
        # drawn value by value: edge cases, and failures shrink to a few small numbers
        n_vertices = draw(st.integers(3, 12))
        coord = lambda m: st.integers(-3 * SUB, SUB * (m + 3)).map(lambda v: on_grid(v, q))  # noqa: E731
        xy = np.array(draw(points(coord(w), coord(h), n_vertices)), np.int64)
        z = np.array(draw(st.lists(st.sampled_from([-0.5, 0.0, 0.5]) | st.floats(-1.4, 1.4),
                                   min_size=n_vertices, max_size=n_vertices)))
        ws = np.array(draw(st.lists(st.sampled_from([1.0]) | st.floats(0.25, 4.0),
                                    min_size=n_vertices, max_size=n_vertices)))
    else:
        # from a seed: busy scenes, which hypothesis alone draws rarely in a few dozen examples
        rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
        n_vertices = int(rng.integers(3, 40))
        xy = np.stack([rng.integers(-3 * SUB, SUB * (m + 3), n_vertices) for m in (w, h)], axis=1)
        xy -= xy % q
        z = np.where(rng.random(n_vertices) < 0.3, rng.choice([-0.5, 0.0, 0.5], n_vertices),
                     rng.uniform(-1.4, 1.4, n_vertices))
        ws = np.where(rng.random(n_vertices) < 0.3, 1.0, rng.uniform(0.25, 4.0, n_vertices))
    draws = []
    for _ in range(draw(st.integers(1, 3))):
        n = draw(st.integers(1, 10 if n_vertices <= 12 else 30))
        corner = st.integers(0, n_vertices - 1)
        distinct = st.lists(corner, min_size=3, max_size=3, unique=True)
        any3 = st.lists(corner, min_size=3, max_size=3)          # now and then a degenerate one
        indices = np.array([draw(st.one_of(distinct, distinct, distinct, any3)) for _ in range(n)]).reshape(-1)
        draws.append((indices, draw(draw_states())))
    viewport = None
    if draw(st.booleans()):
        vw, vh = draw(st.integers(1, 2 * w)), draw(st.integers(1, 2 * h))
        near, far = draw(st.sampled_from([(0.0, 1.0), (0.25, 0.75), (1.0, 0.0), (0.5, 0.5)]))
        viewport = softpipe.Viewport(draw(st.integers(-w // 2, w)), draw(st.integers(-h // 2, h)), vw, vh, near, far)
    clear_depth = draw(st.sampled_from([1.0, 1.0, 0.5, 0.0]))
    return dict(w=w, h=h, xy=xy, z=z, ws=ws, draws=draws, viewport=viewport, clear_depth=clear_depth,
                pattern=draw(pattern), shader=draw(st.sampled_from(["scene", "default"])),
                seed=draw(st.integers(0, 2 ** 32 - 1)))


def render(scene, path, **extra):
    """Draw a scene from :func:`scenes` into a new framebuffer; ``extra`` is added to every draw's state."""
    w, h = scene["w"], scene["h"]
    rng = np.random.default_rng(scene["seed"])
    n = len(scene["xy"])
    fb = softpipe.Framebuffer(w, h, PATTERNS[scene["pattern"]]).clear((0.1, 0.2, 0.3, 0.4), scene["clear_depth"])
    pos = clip_positions(scene["xy"], scene["z"], scene["ws"], w, h)
    if scene["shader"] == "scene":
        kw = dict(varyings={"s": rng.random((n, 3)), "n": rng.random((n, 2)), "f": rng.random(n)},
                  fragment_shader=scene_shader, interpolation=SCENE_INTERPOLATION)
    else:
        kw = dict(varyings={"color": rng.random((n, 3))})
    for indices, state in scene["draws"]:
        state = {**state, **extra}
        draw_kw = kw
        if state.get("depth_test") == "notequal" and state.get("depth_write", True):
            # the fast path takes "notequal" with depth writes only for a shader with a literal alpha
            # (a discarded hidden fragment could change which one shows): on both paths, such a shader
            draw_kw = dict(kw, fragment_shader=LITERAL_ALPHA[scene["shader"]])
        softpipe.draw(fb, pos, indices, viewport=scene["viewport"], path=path, **draw_kw, **state)
    return fb


def scene_shader_literal_alpha(varyings, uniforms, frag):
    """:func:`scene_shader` with an alpha the fast path can read as finite."""
    ff = 1.0 if frag.front_facing else 0.0
    return (varyings.s[0] * 0.5 + frag.x * 0.0625,
            varyings.n[1] + frag.y * 0.03125,
            varyings.f * frag.z + 0.25 * ff,
            0.625)


def color_literal_alpha(varyings, uniforms, frag):
    c = varyings.color
    return (c[0], c[1], c[2], 1.0)


LITERAL_ALPHA = {"scene": scene_shader_literal_alpha, "default": color_literal_alpha}


def assert_same_bytes(a, b, what):
    ca, cb = planes(a.samples_color, a), planes(b.samples_color, b)
    da, db = planes(a.samples_depth, a), planes(b.samples_depth, b)
    if ca.tobytes() != cb.tobytes() or da.tobytes() != db.tobytes():
        bad = np.argwhere((ca != cb).any(axis=-1) | (da != db))
        s, r, i = bad[0]
        pytest.fail(f"{what}: {len(bad)} samples differ, first at sample {s}, image row {r}, column {i}: "
                    f"color {ca[s, r, i]} vs {cb[s, r, i]}, depth {da[s, r, i]!r} vs {db[s, r, i]!r}")


def describe(scene) -> str:
    return (f"{scene['w']}×{scene['h']} {scene['pattern']} shader={scene['shader']} viewport={scene['viewport']} "
            f"clear depth {scene['clear_depth']}; draws "
            + "; ".join(f"{ix.tolist()} {st_}" for ix, st_ in scene["draws"]))


@given(scene=scenes())
@examples()
def test_fast_path_gives_the_bytes_of_the_reference_path(scene):
    # path="fast": tiled visibility pass with early depth, then shading of the
    # visible samples only; path="reference": every fragment shaded and merged
    # in order. All eight depth functions (and none), depth writes on/off,
    # culling, both windings, 1 or 4 samples, smooth/noperspective/flat, a
    # shader reading frag.x/y/z/front_facing/primitive_id.
    note(describe(scene))
    reference_fb = render(scene, "reference")
    changed = planes(reference_fb.samples_color, reference_fb)[..., 0] != np.float32(0.1)
    event(f"samples changed: {bucket(int(changed.sum()))}")
    assert_same_bytes(reference_fb, render(scene, "fast"), "fast vs reference")



@given(scene=scenes(pattern=st.sampled_from(["grid(2)", "grid(2)", "1"])),
       shading=st.sampled_from(["center", "centroid"]))
@examples()
def test_multisampled_fast_path_gives_the_bytes_of_the_reference_path(scene, shading):
    # Multisampling: the reference shades each run of a triangle's samples in
    # a pixel once, at the centre or the run's centroid, with the run's first
    # sample's depth; the fast path shades each (pixel, triangle) of the
    # visibility buffer so, and copies the color to the triangle's other
    # visible samples there.
    note(describe(scene) + f"; sample_shading={shading}")
    assert_same_bytes(render(scene, "reference", sample_shading=shading),
                      render(scene, "fast", sample_shading=shading), f"fast vs reference, {shading}")


def around_tiles(tile: int) -> st.SearchStrategy:
    """Sizes of up to 2½ tiles, often one pixel either side of a multiple of the tile."""
    return st.integers(1, 5 * tile // 2) | st.sampled_from([tile - 1, tile, tile + 1, 2 * tile - 1, 2 * tile + 1])


@given(scene=scenes(size=(around_tiles(TILE_W), around_tiles(TILE_H)),
                    pattern=st.sampled_from(["1", "1", "grid(2)"])))
@examples()
def test_fast_path_gives_the_bytes_of_the_reference_path_across_tiles(scene):
    # Determinism across tile sizes. The fast path's tile size is compiled into
    # its numba kernels, so it cannot be changed from a test; instead the tiled
    # traversal (binning, per-tile hierarchical depth, parallel tiles) is held
    # to the reference path — one whole-framebuffer loop per triangle, an
    # entirely different order — on framebuffers of several tiles, with partial
    # tiles at the right and top, and sizes on either side of the tile size.
    note(describe(scene))
    assert_same_bytes(render(scene, "reference"), render(scene, "fast"), "fast vs reference")


DETERMINISM_SCRIPT = r'''
import sys
import numpy as np
import softpipe
from softpipe.pipeline.sampling import CENTER, grid

DEPTH = ("never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always", None)


def opaque(varyings, uniforms, frag):
    c = varyings.color
    return (c[0], c[1], c[2], 1.0)


def scene(seed, w, h, pattern, path, most):
    """Three draws of random overlapping triangles (some clipped), random state."""
    rng = np.random.default_rng(seed)
    fb = softpipe.Framebuffer(w, h, pattern).clear((0.1, 0.2, 0.3, 0.4), float(rng.choice([1.0, 0.5])))
    for k in range(3):
        n = int(rng.integers(most // 3, most + 1))
        ws = rng.uniform(0.5, 2.0, (3 * n, 1))
        xy = np.round(rng.uniform(-1.2, 1.2, (3 * n, 2)) * 16) / 16 * ws
        z = rng.uniform(-1.2, 1.2, (3 * n, 1)) * ws
        depth_test, depth_write = DEPTH[int(rng.integers(len(DEPTH)))], bool(rng.integers(2))
        # the fast path takes "notequal" with depth writes only for a shader with a literal alpha
        shader = opaque if depth_test == "notequal" and depth_write else None
        softpipe.draw(fb, np.hstack([xy, z, ws]), varyings={"color": rng.random((3 * n, 3))}, path=path,
                      depth_test=depth_test, depth_write=depth_write, fragment_shader=shader,
                      cull=("none", "back", "front")[int(rng.integers(3))])
    return fb.samples_color.tobytes() + fb.samples_depth.tobytes()


if __name__ == "__main__":
    out, w, h, most = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[5])
    seeds = [int(s) for s in sys.argv[4].split(",")]
    with open(out, "wb") as f:
        for seed in seeds:
            for pattern in (CENTER, grid(2)):
                ref, fast = scene(seed, w, h, pattern, "reference", most), scene(seed, w, h, pattern, "fast", most)
                assert ref == fast, f"seed {seed}, {pattern}: fast path differs from reference"
                f.write(ref)
'''

ROOT = Path(__file__).resolve().parent.parent
#: fixed seeds (more under the long profile); one subprocess per configuration renders all of them
DETERMINISM_SEEDS = list(range(20)) if LONG else [0, 1, 2]


def run_scenes(tmp_path, w, h, most, seeds, **env):
    """Render the seeds' scenes (both paths, 1 and 4 samples) in a fresh process with ``env``; the bytes.

    Without ``env`` (numba compiling, its threads as they are) the scenes are rendered in this process,
    as the script's ``__main__`` would: a process of its own would change nothing but the cost."""
    script = tmp_path / "scenes.py"
    script.write_text(DETERMINISM_SCRIPT)
    out = tmp_path / ("out_" + "_".join(f"{k}{v}" for k, v in env.items()) + ".bin")
    if not env and not os.environ.get("NUMBA_DISABLE_JIT") and not os.environ.get("NUMBA_NUM_THREADS"):
        argv = sys.argv
        sys.argv = [str(script), str(out), str(w), str(h), ",".join(map(str, seeds)), str(most)]
        try:
            exec(compile(DETERMINISM_SCRIPT, str(script), "exec"), {"__name__": "__main__"})
        finally:
            sys.argv = argv
        return out.read_bytes()
    e = {k: v for k, v in os.environ.items() if k not in ("NUMBA_NUM_THREADS", "NUMBA_DISABLE_JIT")}
    e.update(env)
    e["PYTHONPATH"] = str(ROOT) + os.pathsep + e.get("PYTHONPATH", "")
    r = subprocess.run([sys.executable, str(script), str(out), str(w), str(h), ",".join(map(str, seeds)),
                        str(most)], env=e,
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, f"child failed ({env}):\n{r.stdout}\n{r.stderr}"
    return out.read_bytes()


def first_difference(a: bytes, b: bytes) -> str:
    if len(a) != len(b):
        return f"lengths {len(a)} and {len(b)}"
    x, y = np.frombuffer(a, np.uint8), np.frombuffer(b, np.uint8)
    k = np.nonzero(x != y)[0]
    return f"{len(k)} bytes differ, first at byte {k[0]}"


def test_same_bytes_on_one_and_two_threads_on_fixed_seeds(tmp_path):
    # Several tiles, the right and top ones partial; both paths, 1 and 4 samples
    # per pixel, and inside each child the fast path equals the reference.
    w, h = TILE_W + TILE_W // 2 + 3, 3 * TILE_H + 1
    one = run_scenes(tmp_path, w, h, 60, DETERMINISM_SEEDS, NUMBA_NUM_THREADS="1")
    two = run_scenes(tmp_path, w, h, 60, DETERMINISM_SEEDS, NUMBA_NUM_THREADS="2")
    assert len(one) == len(DETERMINISM_SEEDS) * w * h * 20 * (1 + 4)      # color + depth, 1 and 4 samples
    assert one == two, first_difference(one, two)


def test_compiled_and_pure_python_kernels_give_the_same_bytes_on_fixed_seeds(tmp_path):
    # NUMBA_DISABLE_JIT=1 runs every kernel (rasterizer, visibility pass over
    # two tiles, shader loops, merger) as plain Python; a small scene keeps that quick.
    seeds = DETERMINISM_SEEDS[:2] if not LONG else DETERMINISM_SEEDS[:6]
    w, h = TILE_W + 6, 23
    jit = run_scenes(tmp_path, w, h, 8, seeds)
    python = run_scenes(tmp_path, w, h, 8, seeds, NUMBA_DISABLE_JIT="1")
    assert jit == python, first_difference(jit, python)


# ================================================================ 6. clipping

def counting_draw(w, h, pattern, pos, path="reference"):
    """Alpha = how many fragments each sample got (additive blending, no depth test): [S, J, I]."""
    fb = softpipe.Framebuffer(w, h, pattern).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, varyings={"color": np.ones((len(pos), 4))}, blend=("one", "one"), depth_test=None,
                  path=path)
    return planes(fb.samples_color, fb)[..., 3][:, ::-1].astype(np.int64), fb


def dist2_to_segment(p, a, b):
    """Squared distance from p to the segment a–b, exactly (Fractions)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    den = dx * dx + dy * dy
    t = F(0) if den == 0 else min(max(((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / den, F(0)), F(1))
    qx, qy = a[0] + t * dx - p[0], a[1] + t * dy - p[1]
    return qx * qx + qy * qy


@st.composite
def grid_splits(draw):
    """A triangle with corners on a coarse grid (2^k fixed units), its w per corner, and a split whose new
    vertices land exactly on the 1/256 grid and exactly on the triangle's edges."""
    w, h = draw(sizes), draw(sizes)
    k = draw(st.integers(1, 6))
    step = 1 << k
    coord = lambda m: st.integers(-SUB // step, SUB * (m + 1) // step).map(lambda v: v * step)  # noqa: E731
    tri = draw(points(coord(w), coord(h), 3))
    assume(orient(*tri) != 0)
    ws = [F(draw(st.integers(4, 16)), 8) for _ in range(3)]
    zs = [F(draw(st.integers(-7, 7)), 8) for _ in range(3)]
    t1, t2 = F(draw(st.integers(1, step - 1)), step), F(draw(st.integers(1, step - 1)), step)
    through_vertex = draw(st.booleans())
    return w, h, tri, ws, zs, t1, t2, through_vertex, draw(st.booleans()), draw(pattern_names)


def exact_clip_corner(fixed, z_ndc, w_clip, width, height):
    """Exact clip coordinates (Fractions) of a window point given in fixed units."""
    x_ndc = F(2 * (fixed[0] + 128), SUB * width) - 1
    y_ndc = F(2 * (fixed[1] + 128), SUB * height) - 1
    return (x_ndc * w_clip, y_ndc * w_clip, z_ndc * w_clip, w_clip)


def split_point(a, b, t):
    """The clip-space point of edge a→b whose window position is at parameter t (window-linear)."""
    s = t * a[3] / (t * a[3] + (1 - t) * b[3])
    return tuple(pa + s * (pb - pa) for pa, pb in zip(a, b))


@given(case=grid_splits())
@examples()
def test_a_triangle_split_by_a_plane_gives_exactly_its_pixels(case):
    # The split points P (and Q) are computed in clip space with Fractions and
    # chosen so that their window positions are points of the 1/256 grid on the
    # triangle's edges: the pieces are then exactly a partition of the snapped
    # triangle, and the fill rule makes the partition invisible. Asserted: every
    # sample (including those on the split edge) gets exactly as many fragments
    # from the pieces as from the whole (0 or 1), and the same depth up to float
    # rounding. A plane through P and Q in clip space (e.g. through the eye)
    # makes this split.
    w, h, tri, ws, zs, t1, t2, through_vertex, diagonal, pattern_name = case
    pattern = PATTERNS[pattern_name]
    A, B, C = (exact_clip_corner(p, z, wc, w, h) for p, z, wc in zip(tri, zs, ws))
    if through_vertex:                     # the plane through A and a point P of BC
        P = split_point(B, C, t1)
        pieces = [(A, B, P), (A, P, C)]
    else:                                  # through P on AB and Q on AC
        P, Q = split_point(A, B, t1), split_point(A, C, t2)
        pieces = [(A, P, Q)] + ([(P, B, C), (P, C, Q)] if diagonal else [(P, B, Q), (Q, B, C)])
    as_float = lambda tris: np.array([[float(c) for c in v] for t in tris for v in t])  # noqa: E731
    note(f"{w}×{h} {pattern_name}; fixed corners {tri}, w {ws}, t {t1}, {t2}, through vertex {through_vertex}")
    whole, fb_whole = counting_draw(w, h, pattern, as_float([(A, B, C)]))
    split, fb_split = counting_draw(w, h, pattern, as_float(pieces))
    for s in range(len(pattern)):
        if not np.array_equal(whole[s], split[s]):
            note(f"sample {s}: pieces minus whole:\n" + picture(split[s] - whole[s]))
    event(f"covered samples: {bucket(int(whole.sum()))}")
    assert whole.max() <= 1
    assert np.array_equal(whole, split)
    for fb, pos in ((fb_whole, [(A, B, C)]), (fb_split, pieces)):
        fb.clear((0, 0, 0, 0), 1.0)
        softpipe.draw(fb, as_float(pos), varyings={"color": np.ones((3 * len(pos), 4))}, depth_test="always")
    d_whole, d_split = planes(fb_whole.samples_depth, fb_whole), planes(fb_split.samples_depth, fb_split)
    np.testing.assert_allclose(d_split, d_whole, rtol=0, atol=1e-6)


@st.composite
def plane_splits(draw):
    """A triangle with corners on the 1/256 grid and a random split in clip space: new vertices at
    random rational parameters of two edges (0.1–0.9), rounded to float64 once (so, off the grid)."""
    w, h = draw(sizes), draw(sizes)
    tri = draw(triangles(w, h, margin=1))
    # pieces at least ~1/80 px thick, so that snapping P and Q (≤ √2/512 px) cannot turn one over
    longest = max(np.hypot(tri[k][0] - tri[k - 1][0], tri[k][1] - tri[k - 1][1]) for k in range(3))
    assume(abs(orient(*tri)) >= SUB * longest / 2)      # height ≥ ½ px
    ws = [F(draw(st.floats(0.5, 2.0))) for _ in range(3)]
    zs = [F(draw(st.floats(-0.9, 0.9))) for _ in range(3)]
    s1 = F(draw(st.integers(100, 900)), 1000)
    s2 = F(draw(st.integers(100, 900)), 1000)
    rotation = draw(st.integers(0, 2))
    return w, h, reorder(tri, rotation, False), ws, zs, s1, s2, draw(st.booleans()), draw(pattern_names)


@given(case=plane_splits())
@examples()
def test_a_triangle_split_anywhere_differs_only_beside_the_cut_edges(case):
    # P on AB and Q on AC at random clip-space parameters, exactly, then rounded
    # to float64 and snapped by softpipe like any vertex: the pieces' outline
    # bends by at most √2/512 px at P and Q. Asserted: the pieces never cover a
    # sample twice (the new edge PQ is shared), and a sample covered by the
    # whole but not the pieces (or the reverse) lies within 1/256 px of AB or
    # AC, the edges the plane cuts (distance computed exactly). Nothing may
    # differ along the split edge itself, away from the outline.
    w, h, tri, ws, zs, s1, s2, diagonal, pattern_name = case
    pattern = PATTERNS[pattern_name]
    A, B, C = (exact_clip_corner(p, z, wc, w, h) for p, z, wc in zip(tri, zs, ws))
    P = tuple(a + s1 * (b - a) for a, b in zip(A, B))
    Q = tuple(a + s2 * (c - a) for a, c in zip(A, C))
    pieces = [(A, P, Q)] + ([(P, B, C), (P, C, Q)] if diagonal else [(P, B, Q), (Q, B, C)])
    as_float = lambda tris: np.array([[float(c) for c in v] for t in tris for v in t])  # noqa: E731
    note(f"{w}×{h} {pattern_name}; fixed corners {tri}, w {ws}, s {s1}, {s2}")
    whole, _ = counting_draw(w, h, pattern, as_float([(A, B, C)]))
    split, _ = counting_draw(w, h, pattern, as_float(pieces))
    event(f"covered samples: {bucket(int(whole.sum()))}; differing: {bucket(int((whole != split).sum()))}")
    assert split.max() <= 1, "a sample on the shared new edge was covered twice"
    cut_edges = [(tri[0], tri[1]), (tri[0], tri[2])]
    limit2 = F(1, 256) ** 2 * SUB ** 2              # in fixed units
    bad = []
    for s, j, i in np.argwhere(whole != split):
        p = (SUB * int(i) + int(pattern.offsets[s, 0]), SUB * int(j) + int(pattern.offsets[s, 1]))
        if not any(dist2_to_segment(p, a, b) <= limit2 for a, b in cut_edges):
            bad.append((int(s), int(i), int(j)))
    for s in range(len(pattern)):
        if not np.array_equal(whole[s], split[s]):
            note(f"sample {s}: pieces minus whole:\n" + picture(split[s] - whole[s]))
    assert not bad, f"samples (s, i, j) differ away from the cut edges: {bad[:20]}"


NEAR = lambda p: p[2] + p[3]          # noqa: E731  z ≥ −w
FAR = lambda p: p[3] - p[2]           # noqa: E731  z ≤ w


def clip_exact(poly, width, height):
    """Sutherland–Hodgman with Fractions against softpipe's clip volume: w ≥ W_MIN, near, far, guard band."""
    gx = max(F(1), F(GUARD_PIXELS) / (F(width) / 2))
    gy = max(F(1), F(GUARD_PIXELS) / (F(height) / 2))
    clip_planes = [lambda p: p[3] - F(W_MIN), NEAR, FAR, lambda p: p[0] + gx * p[3], lambda p: gx * p[3] - p[0],
                   lambda p: p[1] + gy * p[3], lambda p: gy * p[3] - p[1]]
    for plane in clip_planes:
        out = []
        for k in range(len(poly)):
            a, b = poly[k], poly[(k + 1) % len(poly)]
            da, db = plane(a), plane(b)
            if da >= 0:
                out.append(a)
            if (da >= 0) != (db >= 0):
                t = da / (da - db)
                out.append(tuple(pa + t * (pb - pa) for pa, pb in zip(a, b)))
        poly = out
    return poly


@st.composite
def crossing_triangles(draw):
    """A clip-space triangle (dyadic coordinates, exact as floats) whose first corner is in front of the
    eye but nearer than the near plane (z < −w, w > 0), or at or behind the eye (w ≤ 0)."""
    w, h = draw(sizes), draw(sizes)
    d = lambda lo, hi: st.integers(lo * 16, hi * 16).map(lambda v: F(v, 16))  # noqa: E731
    if draw(st.booleans()):
        w0 = draw(d(0, 3).filter(lambda v: v > 0))
        first = (draw(d(-3, 3)), draw(d(-3, 3)), -w0 - draw(d(0, 3)) - F(1, 16), w0)
    else:
        first = (draw(d(-3, 3)), draw(d(-3, 3)), draw(d(-3, 3)), draw(d(-3, 0)))
    others = []
    for _ in range(2):
        wc = draw(d(1, 3) | d(-2, 3))
        u = lambda: draw(d(-2, 2)) * (abs(wc) if draw(st.booleans()) else 1)  # noqa: E731  often in view
        others.append((u(), u(), draw(d(-3, 3)), wc))
    corners = [first] + others
    rotation = draw(st.integers(0, 2))
    return w, h, corners[rotation:] + corners[:rotation]


def centres_against_polygon(win, w, h):
    """For every pixel centre [J, I]: inside the closed convex polygon (CCW), and whether it lies within
    1/256 px of its boundary. Float64 first; the centres within 1e-9 px of that distance are redone
    with Fractions. A polygon of zero area has no inside."""
    j, i = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    px, py = i + 0.5, j + 0.5
    fw = [(float(x), float(y)) for x, y in win]
    inside = np.ones((h, w), bool)
    dist = np.full((h, w), np.inf)
    for (ax, ay), (bx, by) in zip(fw, fw[1:] + fw[:1]):
        dx, dy = bx - ax, by - ay
        inside &= dx * (py - ay) - dy * (px - ax) >= 0
        den = dx * dx + dy * dy
        t = np.clip(((px - ax) * dx + (py - ay) * dy) / den, 0, 1) if den else np.zeros_like(px)
        dist = np.minimum(dist, np.hypot(ax + t * dx - px, ay + t * dy - py))
    if sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(win, win[1:] + win[:1])) == 0:
        inside[:] = False
    limit = 1 / 256
    near = dist <= limit
    unsure = np.abs(dist - limit) < 1e-9
    for jj, ii in zip(*np.nonzero(unsure | (np.abs(dist) < 1e-9))):
        p = (F(2 * int(ii) + 1, 2), F(2 * int(jj) + 1, 2))
        edges = list(zip(win, win[1:] + win[:1]))
        inside[jj, ii] &= all((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= 0 for a, b in edges)
        near[jj, ii] = any(dist2_to_segment(p, a, b) <= F(1, 256) ** 2 for a, b in edges)
    return inside, near


@given(case=crossing_triangles())
@examples()
@example(case=(16, 16, [(F(-1), F(-1), F(-2), F(1)), (F(2), F(-1), F(0), F(2)), (F(0), F(2), F(1), F(2))]))
def test_triangles_crossing_the_near_plane_or_the_eye_stay_inside_the_exact_clipped_polygon(case):
    # The clipped polygon is computed exactly (Fractions, against the clip
    # volume softpipe documents: w ≥ W_MIN, near, far, guard band) and mapped
    # exactly to the window. softpipe computes new vertices in float64 and
    # snaps every vertex to 1/256 px, which moves it by at most √2/512 px, so
    # its polygon lies within that distance of the exact one. Asserted for
    # every pixel centre: drawn ⇒ inside the exact polygon or within 1/256 px of
    # its boundary; inside and farther than 1/256 px from the boundary ⇒ drawn;
    # drawn at most once. The fast path draws the same pixels.
    w, h, corners = case
    poly = clip_exact(list(corners), w, h)
    pos = np.array([[float(c) for c in v] for v in corners])
    note(f"{w}×{h}: clip corners {pos.tolist()}, clipped polygon has {len(poly)} corners")
    counts, _ = counting_draw(w, h, CENTER, pos)
    counts = counts[0]
    event(f"clipped polygon corners: {len(poly)}; drawn pixels: {bucket(int(counts.sum()))}")
    note(f"drawn (window rows, top first):\n{picture(counts)}")
    assert counts.max() <= 1, "a pixel was drawn twice"
    fb = softpipe.Framebuffer(w, h).clear((0, 0, 0, 0))
    softpipe.draw(fb, pos, fragment_shader=id_shader, depth_test="always", path="fast")
    assert np.array_equal(fb.color[::-1, :, 0] > 0, counts > 0), "the fast path drew other pixels"
    if len(poly) < 3:
        assert counts.sum() == 0
        return
    win = [((x / ww + 1) * w / 2, (y / ww + 1) * h / 2) for x, y, _, ww in poly]
    area = sum(win[k][0] * win[k - 1][1] - win[k - 1][0] * win[k][1] for k in range(len(win)))
    if area > 0:                          # the sum above is −2·area: make the polygon counter-clockwise
        win = win[::-1]
    inside, near = centres_against_polygon(win, w, h)
    wrong = (counts > 0) != inside
    bad = [(int(i), int(j), "drawn outside" if counts[j, i] else "missed inside")
           for j, i in zip(*np.nonzero(wrong & ~near))]
    assert not bad, f"pixels (i, j) wrong by more than 1/256 px: {bad[:20]}"


# ============================================================ 7. never crash

SPECIAL = [0.0, -0.0, 1e30, -1e30, 1e-30, -1e-30, 1e300, -1e300, 5e-324, -5e-324, 1.7e308, -1.7e308,
           np.nan, np.inf, -np.inf, 1.0, -1.0, 0.5, 2.0 ** 20, 2.0 ** 20 + 1, 1e9]
W_SPECIAL = [0.0, -0.0, W_MIN, np.nextafter(W_MIN, 0), np.nextafter(W_MIN, 1), -W_MIN, 1e-12, -1e-12, 1e-300,
             -1e-300, 5e-324, -1.0, -1e30, 1e30, np.inf, np.nan]
any_float = st.floats(allow_nan=True, allow_infinity=True)
wild_coordinates = st.sampled_from(SPECIAL) | any_float
wild_w = st.sampled_from(W_SPECIAL) | st.floats(-2, 0.25) | any_float


@st.composite
def wild_triangles(draw, qualifiers=("smooth", "noperspective", "flat")):
    """1–4 triangles: ordinary corners (in view, w in [0.25, 3]) with 0–4 components replaced by wild
    values, then every coordinate of a triangle scaled by one factor (1, 1e±30, 1e±300, 5e-324: the
    same points when nothing overflows)."""
    rows = []
    for _ in range(draw(st.integers(1, 4))):
        tri = []
        for _ in range(3):
            w = draw(st.floats(0.25, 3.0))
            tri.append([draw(st.floats(-1.5, 1.5)) * w, draw(st.floats(-1.5, 1.5)) * w,
                        draw(st.floats(-1.0, 1.0)) * w, w])
        for _ in range(draw(st.integers(0, 4))):
            v, c = draw(st.integers(0, 2)), draw(st.integers(0, 3))
            tri[v][c] = draw(wild_w if c == 3 else wild_coordinates)
        scale = draw(st.sampled_from([1.0, 1.0, 1.0, 1e-30, 1e30, 1e-300, 1e300, 5e-324]))
        with np.errstate(all="ignore"):
            rows += (np.array(tri) * scale).tolist()
    return dict(pos=np.array(rows), size=(draw(sizes), draw(sizes)), pattern=draw(st.sampled_from(["1", "grid(2)"])),
                path=draw(st.sampled_from(["reference", "fast"])), qualifier=draw(st.sampled_from(qualifiers)),
                cull=draw(st.sampled_from(["none", "back", "front"])), seed=draw(st.integers(0, 2 ** 32 - 1)))


def draw_wild(case, check_range: bool):
    w, h = case["size"]
    pos = case["pos"]
    fb = softpipe.Framebuffer(w, h, PATTERNS[case["pattern"]]).clear((0.5, 0.5, 0.5, 0.5))
    colors = np.random.default_rng(case["seed"]).random((len(pos), 4))
    note(f"positions {pos.tolist()}, {case}")
    with np.errstate(all="ignore"):
        softpipe.draw(fb, pos, varyings={"color": colors}, interpolation={"color": case["qualifier"]},
                      depth_test="always", cull=case["cull"], path=case["path"])
    depth, color = fb.samples_depth, fb.samples_color
    event("drew something" if (color != np.float32(0.5)).any() else "drew nothing")
    assert np.isfinite(depth).all() and depth.min() >= 0.0 and depth.max() <= 1.0, "a depth outside [0, 1]"
    assert np.isfinite(color).all(), "a non-finite color from finite varyings"
    if check_range:
        assert color.min() >= -1e-6 and color.max() <= 1 + 1e-6, (color.min(), color.max())


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@given(case=wild_triangles())
@examples()
# found by this property: exact (Fraction) clipping of huge coordinates computed the noperspective
# parameter t·w_out/w_new with w_new = W_MIN; float() of it raised OverflowError
@example(case=dict(pos=np.array([[0.0, 0.0, 0.0, -1e300], [0.0, 0.0, 0.0, 1e300], [0.5, 0.5, 0.0, 1.0]]),
                   size=(8, 8), pattern="1", path="reference", qualifier="noperspective", cull="none", seed=0))
def test_wild_coordinates_finish_with_finite_depth_and_color(case):
    # huge (±1e30, ±1e300, ±1.7e308), tiny, denormal, degenerate, NaN and ±inf
    # coordinates; w at, near, or below 0 and at W_MIN; smooth, noperspective
    # and flat varyings. Every value a shader sees is a convex combination of
    # the corners' (in [0, 1]), so the colors stay in [0, 1].
    draw_wild(case, check_range=True)


# found by test_limits.py's multisampled batches: a pixel centre outside the triangle (its samples
# partly inside) can lie on the vanishing line of the triangle's plane, where Σ b_k/w_k = 0
CENTER_ON_THE_HORIZON = np.array([[-1.0, -1.0, 0.0, 1.0], [-0.875, -0.75, 0.0, 1.0], [-0.5, -0.4375, 0.0, 0.5]])


def test_center_shading_at_a_centre_on_the_triangles_horizon_finishes_with_finite_colors():
    # window corners (0, 0), (0.5, 1), (0, 0.5) with w = 1, 1, 0.5 on 8×8 with grid(2): pixel (0, 0)
    # has covered samples, and its centre has b = (1, 1, −1), so Σ b_k/w_k = 1 + 1 − 2 = 0
    fb = softpipe.Framebuffer(8, 8, grid(2))
    softpipe.draw(fb, CENTER_ON_THE_HORIZON, varyings={"color": np.eye(3)}, sample_shading="center")
    assert np.isfinite(fb.samples_color).all()
