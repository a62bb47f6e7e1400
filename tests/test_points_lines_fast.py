"""The fast path of points and lines (issues 29 and 35): their own walk over the triangles' tiles.

On the fast path a draw of points or lines makes no list of fragments: each tile of the
framebuffer walks the points or lines binned to it, in order, with the early depth test,
keeping only the last one written at each sample (``PrimitiveVisibility``); the visible
samples are then shaded. Every test here holds it to the reference path's bytes (color and
depth) — which tests/test_lines_points_exact.py holds to the rational reference — on
random clouds and line sets full of overlaps and depth ties, on 1 and 2 threads.
"""
from __future__ import annotations

import random
from fractions import Fraction

import numba
import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.primitive_visibility import PrimitiveVisibility
from softpipe.pipeline.sampling import pattern_named
from softpipe.testing import reference_line

# several tiles (128 × 32 pixels) each way, the last ones cut short
W, H = 300, 100


def clip(points, z):
    """Window positions (x, y) and depths z in [-1, 1] → clip coordinates (w = 1) for a W × H viewport."""
    p = np.asarray(points, dtype=np.float64)
    return np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, z, np.ones(len(p))])


def shows_inputs(varyings, uniforms, frag):
    """A color made of what the shader is given: a varying, gl_PointCoord (a line's t) and the depth."""
    return (varyings.color[0], frag.point_coord[0], frag.point_coord[1] + frag.z, 1.0)


def _draws(rng, n):
    """A random set of draws of lines, strips and points, crossing tiles and each other, at few depths
    (so that many fragments tie), with the state that decides the winners varied."""
    draws = []
    for k in range(n):
        topology = ["lines", "line_strip", "line_loop", "points"][k % 4]
        count = 2 * int(rng.integers(1, 30))
        # short segments and long ones (across several tiles), in and out of the framebuffer
        spread = rng.choice([3.0, 40.0, 400.0])
        centre = rng.uniform(0, [W, H])
        pos = centre + rng.normal(0, spread, (count, 2))
        pos = np.round(pos * 4) / 4 if k % 3 == 0 else pos        # on quarter pixels: centres, edges, ties
        z = rng.choice([-0.5, 0.0, 0.5], count) if k % 2 else rng.uniform(-1.2, 1.2, count)
        state = dict(depth_test=str(rng.choice(["less", "lequal", "equal", "greater", "always", "gequal"])),
                     depth_write=bool(rng.random() < 0.8))
        if rng.random() < 0.15:
            state["depth_test"] = None
        if topology == "points":
            state["point_size"] = float(rng.choice([0.75, 1.0, 2.0, 3.5, 7.0]))
        else:
            state["line_width"] = float(rng.choice([1.0, 1.0, 2.0, 3.0]))
        if rng.random() < 0.2:
            x, y = (int(v) for v in rng.integers(0, [W - 60, H - 30]))
            state["scissor"] = (x, y, int(rng.integers(10, 200)), int(rng.integers(5, 80)))
        draws.append((clip(pos, z), topology, {"color": rng.uniform(0, 1, (count, 3))}, state))
    return draws


def _render(draws, path, pattern="center", shading="sample", threads=None):
    before = numba.get_num_threads()
    fb = sp.Framebuffer(W, H, pattern=pattern_named(pattern))
    fb.clear((0.1, 0.2, 0.3, 1.0))
    taken = []
    try:
        if threads is not None:
            numba.set_num_threads(threads)
        for pos, topology, varyings, state in draws:
            call = sp.DrawCall(fb, pos, None, varyings, None, shows_inputs, None, topology=topology, path=path,
                               sample_shading=shading, **state)
            call.run()
            taken.append(call.path_taken)
    finally:
        numba.set_num_threads(before)
    return fb, taken


def _two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here (NUMBA_NUM_THREADS=1)")


@pytest.mark.parametrize("seed", range(4))
def test_random_points_and_lines_with_depth_ties_give_the_reference_bytes_on_one_and_two_threads(seed):
    _two_threads()
    draws = _draws(np.random.default_rng(seed), 24)
    reference, _ = _render(draws, "reference")
    for threads in (1, 2):
        fast, taken = _render(draws, "fast", threads=threads)
        assert taken == ["fast"] * len(draws)
        assert fast.samples_color.tobytes() == reference.samples_color.tobytes(), threads
        assert fast.samples_depth.tobytes() == reference.samples_depth.tobytes(), threads


@pytest.mark.parametrize("shading", ["sample", "center", "centroid"])
def test_multisampled_points_and_lines_give_the_reference_bytes_on_one_and_two_threads(shading):
    """With 4 samples a pixel, shaded per sample or once per pixel: the shader reads the depth, which the
    reference path gives a pixel's run at its first sample."""
    _two_threads()
    draws = _draws(np.random.default_rng(11), 16)
    reference, _ = _render(draws, "reference", "rgss4", shading)
    for threads in (1, 2):
        fast, taken = _render(draws, "fast", "rgss4", shading, threads=threads)
        assert taken == ["fast"] * len(draws)
        assert fast.samples_color.tobytes() == reference.samples_color.tobytes(), threads
        assert fast.samples_depth.tobytes() == reference.samples_depth.tobytes(), threads


def test_a_multisampled_line_shaded_at_the_pixel_centre_sees_the_depth_of_its_first_sample():
    """A sloped line at 4 samples a pixel, shaded once per pixel: the reference path shades a pixel's run
    at its first sample, depth included, and copies the color to the others; the fast path now does too
    (it shaded every sample at its own depth)."""
    fb = {}
    for path in ("reference", "fast"):
        fb[path] = sp.Framebuffer(32, 8, pattern=pattern_named("rgss4"))
        sp.draw(fb[path], np.array([[-0.9, -0.5, -0.9, 1.0], [0.9, 0.4, 0.8, 1.0]]), topology="lines",
                varyings={"color": np.ones((2, 3))}, fragment_shader=shows_inputs, path=path,
                sample_shading="center")
    written = fb["reference"].samples_color[..., 3] == 1
    assert written.sum() > 4 * 20
    # every sample of a pixel has its pixel's color
    assert (fb["reference"].samples_color == fb["reference"].samples_color[:1]).all()
    assert fb["fast"].samples_color.tobytes() == fb["reference"].samples_color.tobytes()


def test_a_line_across_every_tile_and_a_scissor_give_the_reference_bytes():
    draws = [(clip([(-20.5, -7.25), (W + 13.0, H + 9.5), (W + 3.0, -4.0), (-8.0, H - 2.0)], [0.3, -0.2, 0.1, 0.9]),
              "lines", {"color": np.eye(4)[:, :3]}, dict(line_width=3.0, scissor=(40, 10, 200, 70)))]
    reference, _ = _render(draws, "reference")
    fast, taken = _render(draws, "fast")
    assert taken == ["fast"]
    assert (reference.samples_color[0, ..., 3] == 1.0).sum() > 200
    assert fast.samples_color.tobytes() == reference.samples_color.tobytes()
    assert fast.samples_depth.tobytes() == reference.samples_depth.tobytes()


@pytest.mark.parametrize("topology, state", [("lines", {"line_width": 2.0}), ("points", {"point_size": 3.0}),
                                             ("triangles", {"polygon_mode": "line"})])
def test_points_and_lines_take_their_tile_walk_and_make_no_fragment_list(monkeypatch, topology, state):
    """The route: the visibility stage is a PrimitiveVisibility, and the reference rasterizer is not called."""
    import softpipe.pipeline.draw as pipeline

    def refused(*args, **kwargs):
        raise AssertionError("the fast path of points and lines made the rasterizer's list of fragments")
    monkeypatch.setattr(pipeline, "count_fragments", refused)
    monkeypatch.setattr(pipeline, "rasterize", refused)
    rng = np.random.default_rng(3)
    pos = clip(rng.uniform(0, [W, H], (30, 2)), rng.uniform(-1, 1, 30))
    fb = sp.Framebuffer(W, H)
    fb.clear((0, 0, 0, 0))
    call = sp.DrawCall(fb, pos, None, {"color": rng.uniform(0, 1, (30, 3))}, topology=topology, path="fast", **state)
    stages = {stage.name: stage.output for stage in call.steps()}
    assert call.path_taken == "fast"
    visibility = stages["visibility"]
    assert isinstance(visibility, PrimitiveVisibility)
    assert repr(visibility).startswith("PrimitiveVisibility(")
    shown = visibility.vis >= 0
    assert shown.sum() == (fb.samples_color[..., 3] == 1.0).sum() > 30
    kind = "points" if topology == "points" else "lines"
    assert f" {kind}, " in repr(visibility)


def gives_up_right_of(v, u, frag):
    if frag.x > u.cut:
        raise ValueError("the shader gave up")
    return (v.color[0], v.color[1], v.color[2], 1.0)


@pytest.mark.parametrize("topology", ["lines", "points"])
def test_a_shader_that_raises_on_the_fast_path_names_the_fragment_and_leaves_the_framebuffer_as_it_was(topology):
    rng = np.random.default_rng(5)
    pos = clip(rng.uniform(0, [W, H], (40, 2)), rng.uniform(-1, 1, 40))
    errors, framebuffers = {}, {}
    for path in ("reference", "fast"):
        fb = framebuffers[path] = sp.Framebuffer(W, H)
        fb.clear((0.1, 0.2, 0.3, 1.0))
        before = (fb.samples_color.tobytes(), fb.samples_depth.tobytes())
        with pytest.raises(sp.ShaderError) as e:
            sp.draw(fb, pos, varyings={"color": rng.uniform(0, 1, (40, 3))}, fragment_shader=gives_up_right_of,
                    uniforms={"cut": 150.0}, topology=topology, point_size=3.0, path=path)
        errors[path] = str(e.value)
        assert (fb.samples_color.tobytes(), fb.samples_depth.tobytes()) == before, path
    for text in errors.values():
        assert "the shader gave up" in text and "the fragment at pixel (" in text, text


@pytest.mark.parametrize("topology, state", [("points", {"point_size": 2.5}), ("lines", {"line_width": 2.0})])
def test_points_and_lines_are_shaded_with_their_inputs_made_in_place(monkeypatch, topology, state):
    """A shader that cannot fail shades the visible samples of points or lines with ``primitive_loop``, which
    makes each sample's inputs where it shades it and writes its color at once: no arrays of inputs
    (which, with the array of colors written afterwards, took most of their shading)."""
    import softpipe.pipeline.primitive_visibility as visibility

    def refused(*args, **kwargs):
        raise AssertionError("the shading made the samples' inputs into arrays")
    rng = np.random.default_rng(8)
    pos = clip(rng.uniform(-3, [W + 3, H + 3], (400, 2)), rng.choice([-0.5, 0.0, 0.5], 400))
    colors = rng.uniform(0, 1, (400, 3))
    fb = {}
    for path in ("reference", "fast"):
        fb[path] = sp.Framebuffer(W, H)
        fb[path].clear((0.1, 0.2, 0.3, 1.0))
        if path == "fast":
            monkeypatch.setattr(visibility, "_shader_inputs", refused)
        call = sp.DrawCall(fb[path], pos, None, {"color": colors}, topology=topology, path=path, **state)
        call.run()
        assert call.path_taken == path
    assert (fb["fast"].samples_color[0, ..., 3] == 1.0).sum() > 1000
    assert fb["fast"].samples_color.tobytes() == fb["reference"].samples_color.tobytes()
    assert fb["fast"].samples_depth.tobytes() == fb["reference"].samples_depth.tobytes()


def point_derivatives(varyings, uniforms, frag, derivatives):
    """Reads a point's derivatives (zero: its corners are one vertex), gl_PointCoord, the depth and the position."""
    return (varyings.color[0] + derivatives.dx.color[0] * 10.0, frag.point_coord[0] + derivatives.dy.color[1],
            frag.point_coord[1] + frag.z + frag.x * 0.01 + frag.y * 0.001, 1.0)


@pytest.mark.parametrize("shading", ["sample", "center", "centroid"])
def test_points_of_sizes_per_vertex_with_derivatives_give_the_reference_bytes_on_one_and_two_threads(shading,
                                                                                                    monkeypatch):
    """Each point its own size (gl_PointSize, a varying), a shader taking derivatives, 4 samples a pixel;
    their inputs made in place (no arrays of them)."""
    import softpipe.pipeline.primitive_visibility as visibility

    def refused(*args, **kwargs):
        raise AssertionError("the shading made the samples' inputs into arrays")
    _two_threads()
    rng = np.random.default_rng(21)
    n = 300
    pos = clip(rng.uniform(-5, [W + 5, H + 5], (n, 2)), rng.uniform(-1.2, 1.2, n))
    varyings = {"color": rng.uniform(0, 1, (n, 3)), "point_size": rng.choice([0.5, 1.0, 2.0, 2.75, 6.0], n)}
    fbs = {}
    for path, threads in (("reference", None), ("fast", 1), ("fast", 2)):
        before = numba.get_num_threads()
        fb = fbs[path, threads] = sp.Framebuffer(W, H, pattern=pattern_named("rgss4"))
        fb.clear((0.1, 0.2, 0.3, 1.0))
        try:
            if threads is not None:
                numba.set_num_threads(threads)
                monkeypatch.setattr(visibility, "_shader_inputs", refused)
            call = sp.DrawCall(fb, pos, None, varyings, None, point_derivatives, None, topology="points", path=path,
                               sample_shading=shading, depth_test="lequal")
            call.run()
        finally:
            numba.set_num_threads(before)
        assert call.path_taken == path
    reference = fbs["reference", None]
    assert len(np.unique(reference.samples_color[..., 1])) > 100
    for threads in (1, 2):
        assert fbs["fast", threads].samples_color.tobytes() == reference.samples_color.tobytes(), threads
        assert fbs["fast", threads].samples_depth.tobytes() == reference.samples_depth.tobytes(), threads


def test_points_written_with_infinite_colors_are_counted_and_the_first_named_on_the_fast_path():
    """The draw says how many visible samples it wrote NaN or infinite and names the first: the lowest image
    row, its first column, and the point shown there."""
    rng = np.random.default_rng(4)
    n = 200
    pos = clip(rng.uniform(0, [W, H], (n, 2)), rng.uniform(-1, 1, n))
    colors = rng.uniform(0, 1, (n, 3))
    colors[::3, 0] = np.inf
    fb = sp.Framebuffer(W, H)
    fb.clear((0.0, 0.0, 0.0, 0.0))
    with pytest.warns(sp.NonFiniteColorWarning) as record:
        call = sp.DrawCall(fb, pos, None, {"color": colors}, topology="points", point_size=3.0, path="fast")
        call.run()
    assert call.path_taken == "fast" and len(record) == 1
    bad = ~np.isfinite(fb.samples_color[0]).all(axis=-1)
    rows, cols = np.nonzero(bad)
    assert 100 < len(rows) == call.non_finite.count
    first = np.lexsort((cols, rows))[0]
    assert (call.non_finite.x, call.non_finite.y) == (cols[first], rows[first])
    # the point there: the last of those whose square holds that pixel, at the nearest depth (LESS)
    x, y = cols[first] + 0.5, H - 1 - rows[first] + 0.5
    window = (pos[:, :2] + 1) / 2 * [W, H]
    holds = (np.abs(window[:, 0] - x) <= 1.5) & (np.abs(window[:, 1] - y) <= 1.5)
    assert call.non_finite.primitive_id in np.flatnonzero(holds & ~np.isfinite(colors[:, 0]))
    assert f"the first at pixel ({cols[first]}, {rows[first]})" in str(record[0].message)


def test_indexed_lines_corners_are_their_vertices_values_and_unused_vertices_are_never_divided():
    """Assembly copies each accepted line's corners (a, b, b) from its vertices: window position, 1/w and
    varyings exactly the vertex's, in any index order; a vertex no line uses, with w = 0 or NaN, is no
    error and changes nothing."""
    rng = np.random.default_rng(11)
    n = 500
    pos = clip(rng.uniform(0, [W, H], (n, 2)), rng.uniform(-0.9, 0.9, n))
    pos *= rng.uniform(0.5, 3.0, (n, 1))                    # w ≠ 1: 1/w is not trivial
    pos[7] = (0.3, 0.2, 0.1, 0.0)                           # never indexed: w = 0
    pos[9] = np.nan                                         # never indexed: not finite
    varyings = {"color": rng.uniform(0, 1, (n, 3))}
    used = np.setdiff1d(np.arange(n), [7, 9])
    indices = rng.choice(used, (3000, 2)).ravel()           # in no order, vertices shared by many lines
    vout = sp.run_vertex_stage(pos, varyings=varyings)
    prims = sp.assemble(vout, "lines", indices, viewport=sp.Viewport(0, 0, W, H))
    corners = indices.reshape(-1, 2)[prims.primitive_id]
    corners = np.column_stack([corners, corners[:, 1]])
    assert len(prims) > 2000 and not prims.clipped.any()
    assert prims.inv_w.tobytes() == (1.0 / pos[corners, 3]).tobytes()
    assert prims.varyings.tobytes() == vout.varyings[corners].tobytes()
    # the window positions: those of the same lines assembled unindexed, their vertices copied in order
    flat = sp.assemble(sp.run_vertex_stage(pos[indices], varyings={"color": varyings["color"][indices]}),
                       "lines", viewport=sp.Viewport(0, 0, W, H))
    assert prims.window.tobytes() == flat.window.tobytes()
    assert prims.window.tobytes() == prims.window[:, [0, 1, 1]].tobytes()


def segment_id(varyings, uniforms, frag):
    """The segment's number as its red (k/1024, exact in float32): which segment each sample shows."""
    return (frag.primitive_id / 1024.0, 0.0, 0.0, 1.0)


def _tie_point(rng, w, h):
    """A window position, a Fraction on the 1/256 grid, often a tie: a pixel centre, edge or corner, a
    diamond vertex or 1/256 beside one, or a tile's border (x a multiple of 128, y of 32)."""
    kind = rng.random()
    if kind < 0.3:
        return Fraction(rng.randint(0, 256 * w), 256), Fraction(rng.randint(0, 256 * h), 256)
    nudge = Fraction(rng.choice((-1, 0, 0, 1)), 256)
    x, y = Fraction(rng.randint(0, 2 * w), 2) + nudge, Fraction(rng.randint(0, 2 * h), 2) + nudge
    if kind < 0.5:
        x = Fraction(128 * rng.randint(0, w // 128)) + rng.choice((Fraction(-1, 2), 0, Fraction(1, 2)))
    elif kind < 0.6:
        y = Fraction(32 * rng.randint(0, h // 32)) + rng.choice((Fraction(-1, 2), 0, Fraction(1, 2)))
    return min(max(x, Fraction(0)), Fraction(w)), min(max(y, Fraction(0)), Fraction(h))


@pytest.mark.parametrize("width, pattern", [(1, "center"), (1, "rgss4"), (3, "center")])
def test_lines_across_tiles_at_ties_give_the_rational_references_pixels_on_the_fast_path(width, pattern):
    """Segments long and short across the tiles (whose walk starts again in each tile, the line's row
    there computed exactly), through ties (slopes ½, 1 and 2 from pixel centres and edges: rows exactly
    halfway between two, ends on diamond borders and tile borders): each sample shows the last segment
    whose pixels by the rational reference (softpipe.testing.reference_line) hold it, on 1 and 2 threads.
    Width 1 on one sample takes the tile walk's loop for thin lines, the others its general loop."""
    _two_threads()
    w, h = 512, 128           # powers of two: window positions on the 1/256 grid are exact in clip space
    rng = random.Random(f"29-tiles-{width}-{pattern}")
    segments = []
    while len(segments) < 160:
        a = _tie_point(rng, w, h)
        if rng.random() < 0.5:
            b = _tie_point(rng, w, h)
        else:
            d = Fraction(rng.randint(-120, 120), 2)
            k = rng.choice((Fraction(1), Fraction(1, 2), Fraction(2), Fraction(-1), Fraction(-1, 2)))
            b = (a[0] + d, a[1] + k * d) if rng.random() < 0.5 else (a[0] + k * d, a[1] + d)
            if not (0 <= b[0] <= w and 0 <= b[1] <= h):
                continue
        if a != b:
            segments.append((a, b))
    pos = np.array([[float(2 * x / w - 1), float(2 * y / h - 1), 0.0, 1.0] for s in segments for x, y in s])
    want = np.full((h, w), -1)
    for k, (a, b) in enumerate(segments):
        for i, j in reference_line(a, b, width):
            if 0 <= i < w and 0 <= j < h:
                want[h - 1 - j, i] = k
    assert (want >= 0).sum() > 8000
    for threads in (1, 2):
        before = numba.get_num_threads()
        fb = sp.Framebuffer(w, h, pattern=pattern_named(pattern))
        fb.clear((0.0, 0.0, 0.0, 0.0))
        try:
            numba.set_num_threads(threads)
            call = sp.DrawCall(fb, pos, None, {"color": np.zeros((len(pos), 3))}, None, segment_id, None,
                               topology="lines", path="fast", depth_test=None, line_width=float(width))
            call.run()
        finally:
            numba.set_num_threads(before)
        assert call.path_taken == "fast"
        have = np.where(fb.samples_color[..., 3] == 1.0, np.rint(fb.samples_color[..., 0] * 1024), -1)
        for s in range(len(have)):
            wrong = np.argwhere(have[s] != want)
            assert len(wrong) == 0, (threads, s, [(int(i), h - 1 - int(r), int(want[r, i]), int(have[s, r, i]))
                                                  for r, i in wrong[:10]])

def test_lines_sharing_vertices_and_wireframe_edges_take_flat_varyings_from_the_provoking_vertex():
    """Lines that share their vertices (more lines than vertices: assembly packs each vertex's values in
    a row first) and a mesh's edges in polygon mode "line": window position, 1/w and varyings are
    exactly those of the same primitives assembled one vertex per corner, and a flat varying is the
    provoking vertex's on every corner (a line's second end; an edge's triangle's third corner)."""
    rng = np.random.default_rng(5)
    n = 300
    pos = clip(rng.uniform(0, [W, H], (n, 2)), rng.uniform(-0.9, 0.9, n)) * rng.uniform(0.5, 3.0, (n, 1))
    color, tint = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 2))
    viewport = sp.Viewport(0, 0, W, H)

    def vertices(rows):
        vout = sp.run_vertex_stage(pos[rows], varyings={"color": color[rows], "tint": tint[rows]})
        vout.layout = vout.layout.with_qualifiers({"tint": "flat"})
        return vout

    def same(a, b):
        return all(getattr(a, k).tobytes() == getattr(b, k).tobytes() for k in ("window", "inv_w", "varyings"))

    indices = rng.choice(n, (2000, 2))
    shared = sp.assemble(vertices(np.arange(n)), "lines", indices.ravel(), viewport=viewport)
    one_each = sp.assemble(vertices(indices.ravel()), "lines", viewport=viewport)
    assert len(shared) == 2000 and same(shared, one_each)
    assert shared.varyings[:, :, 3:].tobytes() == np.repeat(tint[indices[:, 1], None, :], 3, axis=1).tobytes()

    faces = rng.choice(n, (600, 3))
    edges = sp.assemble(vertices(np.arange(n)), "triangles", faces.ravel(), viewport=viewport, polygon_mode="line")
    one_each = sp.assemble(vertices(faces.ravel()), "triangles", viewport=viewport, polygon_mode="line")
    assert len(edges) == 1800 and same(edges, one_each)
    provoking = faces[edges.primitive_id, 2]
    assert edges.varyings[:, :, 3:].tobytes() == np.repeat(tint[provoking, None, :], 3, axis=1).tobytes()


@pytest.mark.parametrize("threads", [1, 2])
def test_visible_samples_are_sorted_by_primitive_then_row_tile_sample_and_column(threads):
    """The shading's counting sort (in bands of rows, each band's places from one running sum over
    (primitive, band)) puts each primitive's visible samples in (image row, tile, sample, column) order,
    whatever the number of bands; tiles no primitive touched are not read (what they hold is left out)."""
    from softpipe.pipeline.primitive_visibility import _sorted_samples
    from softpipe.pipeline.tiles import TILE_H, TILE_W

    rng = np.random.default_rng(3)
    samples, height, width, n_prims = 2, 100, 300, 500
    vis = np.where(rng.random((samples, height, width)) < 0.3, rng.integers(0, n_prims, (samples, height, width)),
                   -1).astype(np.int32)
    touched = rng.random((-(-height // TILE_H), -(-width // TILE_W))) < 0.7
    in_touched = np.zeros(vis.shape, bool)
    for ty, tx in zip(*np.nonzero(touched)):              # a touched tile's rows (image rows, y down)
        rows = slice(max(height - (ty + 1) * TILE_H, 0), height - ty * TILE_H)
        in_touched[:, rows, tx * TILE_W:(tx + 1) * TILE_W] = True
    assert (in_touched & (vis >= 0)).any() and (~in_touched & (vis >= 0)).any()
    visibility = PrimitiveVisibility(vis, None, touched, None)          # type: ignore[arg-type]
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        keys, tri = _sorted_samples(visibility, n_prims, pooled=False)
    finally:
        numba.set_num_threads(before)
    s, row, col = np.nonzero(in_touched & (vis >= 0))
    t = vis[s, row, col]
    order = np.lexsort((col, s, col // TILE_W, row, t))
    assert tri.tolist() == t[order].tolist()
    assert keys.tolist() == ((row * samples + s) * width + col)[order].tolist()


@pytest.mark.parametrize("bands", [2, 3, 4])
def test_the_sort_bands_hold_about_as_many_visible_samples_each(bands):
    """The sort's bands of rows (the threads' work) are cut where the visible samples, counted in every
    8th row, are shared evenly: a screen whose top quarter holds most of them is not cut in halves."""
    from softpipe.pipeline.primitive_visibility import _balanced_bounds

    rng = np.random.default_rng(8)
    samples, height, width = 1, 256, 300
    dense = np.arange(height)[:, None] < 64                  # the top quarter: 9 in 10 samples visible
    vis = np.where(rng.random((samples, height, width)) < np.where(dense, 0.9, 0.05), 7, -1).astype(np.int32)
    touched = np.ones((-(-height // 32), -(-width // 128)), np.bool_)
    bounds = _balanced_bounds(vis, touched, bands)
    assert bounds[0] == 0 and bounds[-1] == height and (np.diff(bounds) >= 0).all() and len(bounds) == bands + 1
    counts = [int((vis[:, bounds[k]:bounds[k + 1]] >= 0).sum()) for k in range(bands)]
    assert max(counts) < 1.15 * min(counts), counts
    assert _balanced_bounds(np.full_like(vis, -1), touched, bands).tolist() == \
        np.linspace(0, height, bands + 1).astype(np.int64).tolist()
