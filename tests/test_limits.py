"""Limits, stated and enforced (issue 7).

The largest framebuffer (``framebuffer.MAX_DIMENSION`` per side,
``framebuffer.MAX_TOTAL_SAMPLES`` in all), the most samples per pixel
(``sampling.MAX_SAMPLES``) and the largest mesh (``vertex.MAX_VERTICES`` per
draw) are refused before anything big is allocated, with the limit named in the
message. "Nothing big was allocated" is shown two ways: tracemalloc (which sees
numpy's allocations) reports a small peak, and numpy's array constructors are
guarded for the duration, so that a regression fails the test instead of
trying to allocate hundreds of gigabytes.

A draw whose fragments would not fit one batch (``pipeline.MAX_FRAGMENTS_PER_BATCH``,
monkeypatched down to a few fragments here) is processed in batches of whole
triangles, in primitive order, and gives exactly the bytes of one batch — with
both paths, with blending (where the order of fragments matters) and with
multisampling (where a pixel's samples are shaded together).

Random scenes come from tests/test_properties.py (its hypothesis profile applies:
SOFTPIPE_HYPOTHESIS_PROFILE=long for many more examples).
"""
import math
import tracemalloc
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import given, note
from hypothesis import strategies as st
from test_properties import assert_same_bytes, describe, examples, render, scenes

import softpipe
import softpipe.pipeline.draw
import softpipe.pipeline.framebuffer
import softpipe.pipeline.transforms
import softpipe.pipeline.vertex
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES
from softpipe.pipeline.sampling import CENTER, MAX_SAMPLES, SamplePattern, grid, random_pattern
from softpipe.pipeline.vertex import MAX_VERTICES

SMALL = 1 << 20          # "nothing big": at most 1 MiB allocated while refusing
BIG_ARRAY = 64 << 20     # the guard refuses arrays over 64 MiB


@contextmanager
def nothing_big_allocated():
    """Guard numpy's array constructors and measure the allocation peak (tracemalloc) of the block."""
    def guard(name, original):
        def guarded(shape, *args, **kwargs):
            dtype = kwargs.get("dtype", args[0] if args and name != "full" else None)
            n = math.prod(shape) if isinstance(shape, (tuple, list)) else int(shape)
            nbytes = n * (np.dtype(dtype).itemsize if dtype is not None else 8)
            assert nbytes <= BIG_ARRAY, f"np.{name} was asked for {nbytes / 2 ** 30:.1f} GiB: the limit was not checked"
            return original(shape, *args, **kwargs)
        return guarded

    with pytest.MonkeyPatch.context() as mp:
        for name in ("empty", "zeros", "ones", "full"):
            mp.setattr(np, name, guard(name, getattr(np, name)))
        tracemalloc.start()
        try:
            yield
        finally:
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
    assert peak < SMALL, f"{peak / 2 ** 20:.1f} MiB were allocated before the refusal"


def refused(make, *words):
    """``make()`` raises ValueError before allocating anything big; its message contains every word."""
    with nothing_big_allocated():
        with pytest.raises(ValueError) as info:
            make()
    message = str(info.value)
    for w in words:
        assert str(w) in message, f"{w!r} is not named in: {message}"
    return message


def pattern_of(n: int) -> SamplePattern:
    return random_pattern(n) if n > 1 else CENTER


# ------------------------------------------------------------------ framebuffer

@pytest.mark.parametrize("width, height", [
    (MAX_DIMENSION + 1, 1), (1, MAX_DIMENSION + 1), (2 ** 40, 2 ** 40), (np.int64(MAX_DIMENSION + 1), 8),
    (2 ** 63, 2 ** 63),
])
def test_a_side_over_MAX_DIMENSION_is_refused_before_allocating(width, height):
    refused(lambda: softpipe.Framebuffer(width, height), "MAX_DIMENSION", MAX_DIMENSION,
            max(int(width), int(height)))


@pytest.mark.parametrize("width, height, samples", [
    (MAX_DIMENSION, MAX_DIMENSION, 1),          # each side allowed, not the product
    (8192, 8193, 1),
    (4096, 4097, 4),
    (1025, 1024, MAX_SAMPLES),
    (MAX_DIMENSION, MAX_DIMENSION, MAX_SAMPLES),
])
def test_more_than_MAX_TOTAL_SAMPLES_is_refused_before_allocating(width, height, samples):
    pattern = pattern_of(samples)
    refused(lambda: softpipe.Framebuffer(width, height, pattern), "MAX_TOTAL_SAMPLES",
            MAX_TOTAL_SAMPLES, width * height * samples)


def test_the_framebuffer_limits_are_inclusive(monkeypatch):
    # The real limits take gigabytes to reach; the same checks with the limits made small.
    monkeypatch.setattr(softpipe.pipeline.framebuffer, "MAX_DIMENSION", 64)
    monkeypatch.setattr(softpipe.pipeline.framebuffer, "MAX_TOTAL_SAMPLES", 64 * 64)
    assert softpipe.Framebuffer(64, 64).samples_depth.size == 64 * 64
    assert softpipe.Framebuffer(8, 8, random_pattern(64)).samples_depth.size == 64 * 64
    with pytest.raises(ValueError, match=r"MAX_DIMENSION\b.*\b64\b"):
        softpipe.Framebuffer(65, 1)
    with pytest.raises(ValueError, match=r"MAX_TOTAL_SAMPLES\b.*\b4096\b"):
        softpipe.Framebuffer(8, 9, random_pattern(64))


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_numpy_integer_sizes_cannot_wrap_around_the_total_samples_check():
    refused(lambda: softpipe.Framebuffer(np.int32(16384), np.int32(16384), random_pattern(64)),
            "MAX_TOTAL_SAMPLES")


# -------------------------------------------------------------- samples per pixel

def test_more_than_MAX_SAMPLES_samples_per_pixel_are_refused_before_allocating():
    assert len(SamplePattern(np.full((MAX_SAMPLES, 2), 0.5))) == MAX_SAMPLES       # the limit itself is allowed
    softpipe.Framebuffer(4, 4, random_pattern(MAX_SAMPLES))
    refused(lambda: SamplePattern(np.full((MAX_SAMPLES + 1, 2), 0.5)), MAX_SAMPLES, MAX_SAMPLES + 1)
    # a billion positions, as a zero-stride array: refused without copying them
    huge = np.broadcast_to(np.array([0.5, 0.5]), (10 ** 9, 2))
    refused(lambda: SamplePattern(huge), MAX_SAMPLES, 10 ** 9)
    refused(lambda: random_pattern(MAX_SAMPLES + 1), MAX_SAMPLES, MAX_SAMPLES + 1)
    refused(lambda: grid(9), "[1, 8]")          # 81 samples: its own parameter limit, 8 = √MAX_SAMPLES


def test_too_many_samples_per_pixel_names_MAX_SAMPLES():
    refused(lambda: SamplePattern(np.full((MAX_SAMPLES + 1, 2), 0.5)), "MAX_SAMPLES")
    refused(lambda: random_pattern(MAX_SAMPLES + 1), "MAX_SAMPLES")


# -------------------------------------------------------------------- vertices

def too_many(columns: int) -> np.ndarray:
    """MAX_VERTICES + 1 rows of zeros without the memory: a zero-stride view."""
    return np.broadcast_to(np.zeros(columns), (MAX_VERTICES + 1, columns))


def test_more_than_MAX_VERTICES_vertices_are_refused_before_allocating():
    fb = softpipe.Framebuffer(4, 4)
    three = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]], float)
    refused(lambda: softpipe.draw(fb, too_many(4), varyings={"color": np.ones((1, 3))}),
            "positions", MAX_VERTICES, MAX_VERTICES + 1)
    refused(lambda: softpipe.draw(fb, three, varyings={"color": too_many(3)}),
            "varyings['color']", MAX_VERTICES, MAX_VERTICES + 1)
    shader = softpipe.standard_vertex
    refused(lambda: softpipe.draw(fb, too_many(3), vertex_shader=shader,
                                               attributes={"normal": np.zeros((3, 3))}),
            "positions", MAX_VERTICES, MAX_VERTICES + 1)
    refused(lambda: softpipe.draw(fb, three[:, :3], vertex_shader=shader,
                                               attributes={"normal": too_many(3)}),
            "attributes['normal']", MAX_VERTICES, MAX_VERTICES + 1)
    assert (fb.color == (0, 0, 0, 1)).all()


def test_the_vertex_limit_is_inclusive(monkeypatch):
    monkeypatch.setattr(softpipe.pipeline.vertex, "MAX_VERTICES", 6)
    fb = softpipe.Framebuffer(8, 8)
    pos = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]] * 3, float)
    softpipe.draw(fb, pos[:6], varyings={"color": np.ones((6, 3))})
    assert (fb.color[..., 0] == 1).any()
    with pytest.raises(ValueError, match=r"positions has 9 rows.*\b6\b"):
        softpipe.draw(fb, pos, varyings={"color": np.ones((9, 3))})


def test_too_many_vertices_names_MAX_VERTICES():
    fb = softpipe.Framebuffer(4, 4)
    refused(lambda: softpipe.draw(fb, too_many(4), varyings={"color": np.ones((1, 3))}),
            "MAX_VERTICES")


def test_a_mesh_over_MAX_VERTICES_is_refused_when_made(monkeypatch):
    from softpipe.scenes import mesh as mesh_module
    for module in (softpipe.pipeline.vertex, mesh_module):
        monkeypatch.setattr(module, "MAX_VERTICES", 6, raising=False)
    with pytest.raises(ValueError, match="MAX_VERTICES"):
        mesh_module.Mesh(positions=np.zeros((9, 3)), indices=[[0, 1, 2]])


# -------------------------------------------------------------------- viewport

def cover_with_viewport(viewport, path):
    """A triangle covering the whole viewport, drawn into 8×8: how many pixels it drew."""
    pos = np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1]], float)
    fb = softpipe.Framebuffer(8, 8)
    softpipe.draw(fb, pos, varyings={"color": np.ones((3, 3))}, path=path, viewport=viewport)
    return int((fb.color[..., 0] == 1).sum())


# Found by this file: Viewport used to accept any size, and beyond about 2^23
# pixels window coordinates overflowed the rasterizer's 64-bit edge functions (a
# triangle covering the framebuffer silently drew nothing). Either is right: the
# viewport is refused with its limit named, or it draws correctly.
@pytest.mark.parametrize("x, size", [(0, 2 ** 15), (0, 2 ** 20), (0, 2 ** 23), (0, 2 ** 24), (-2 ** 24, 2 ** 25),
                                     (-2 ** 40, 2 ** 41)])
@pytest.mark.parametrize("path", ["reference", "fast"])
def test_a_huge_viewport_draws_right_or_is_refused_with_its_limit(x, size, path):
    try:
        viewport = softpipe.Viewport(x, x, size, size)
    except ValueError as e:
        assert "MAX" in str(e), f"refused without naming a limit: {e}"
        return
    assert cover_with_viewport(viewport, path) == 64


MAX_VIEWPORT = softpipe.pipeline.transforms.MAX_VIEWPORT


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_the_largest_viewport_draws_right_and_a_larger_one_is_refused(path):
    m = MAX_VIEWPORT
    assert cover_with_viewport(softpipe.Viewport(0, 0, m, m), path) == 64
    assert cover_with_viewport(softpipe.Viewport(8 - m, 8 - m, m, m), path) == 64    # the framebuffer at its far corner
    for args in ((0, 0, m + 1, 8), (0, 0, 8, m + 1), (-m - 1, 0, 8, 8), (0, m + 1, 8, 8)):
        refused(lambda: softpipe.Viewport(*args), "MAX_VIEWPORT", m)


# ---------------------------------------------------------------------- batches

@contextmanager
def batch_limit(limit: int):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(softpipe.pipeline.draw, "MAX_FRAGMENTS_PER_BATCH", limit)
        yield


BLENDS = [None, "alpha", "additive", ("src_color", "one_minus_dst_alpha"), ("dst_color", "src_alpha")]


@given(scene=scenes(), limit=st.integers(1, 200), blend=st.sampled_from(BLENDS))
@examples()
def test_draws_split_into_tiny_batches_give_the_bytes_of_one_batch(scene, limit, blend):
    note(f"limit {limit}, blend {blend}; {describe(scene)}")
    one = render(scene, "reference", blend=blend)
    with batch_limit(limit):
        batched = render(scene, "reference", blend=blend)
        assert_same_bytes(one, batched, f"batches of ≤ {limit} fragments, blend {blend}")
        if blend is None:                    # the fast path has no batches; it must not care either
            assert_same_bytes(one, render(scene, "fast"), "fast path with a tiny batch limit")


@given(scene=scenes(pattern=st.just("grid(2)")), limit=st.integers(1, 100),
       shading=st.sampled_from(["center", "centroid"]), blend=st.sampled_from([None, "alpha"]))
@examples()
def test_multisampled_draws_split_into_tiny_batches_give_the_bytes_of_one_batch(scene, limit, shading, blend):
    # one shading per pixel and triangle: batches of whole triangles never split a pixel's run
    note(f"limit {limit}, {shading}, blend {blend}; {describe(scene)}")
    one = render(scene, "reference", sample_shading=shading, blend=blend)
    with batch_limit(limit):
        batched = render(scene, "reference", sample_shading=shading, blend=blend)
    assert_same_bytes(one, batched, f"batches of ≤ {limit} fragments, {shading}")


def overlapping_triangles(n: int, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.hstack([rng.uniform(-1.5, 1.5, (3 * n, 2)), rng.uniform(-0.9, 0.9, (3 * n, 1)), np.ones((3 * n, 1))])


def test_batches_are_whole_triangles_in_order_and_at_most_the_limit():
    pos = overlapping_triangles(40)
    fb = softpipe.Framebuffer(24, 24, grid(2))
    colors = np.random.default_rng(1).random((len(pos), 4))
    call = lambda: DrawCall(fb, pos, varyings={"color": colors}, blend="alpha")  # noqa: E731
    everything = [s.output for s in call().steps() if s.name == "raster"]
    assert len(everything) == 1
    total = len(everything[0])
    per_triangle = np.bincount(everything[0].triangle, minlength=40)
    assert per_triangle.max() > 50 and total > 10 * 50
    with batch_limit(50):
        batches = [s.output for s in call().steps() if s.name == "raster"]
    assert len(batches) > 10
    covered = [np.unique(b.triangle) for b in batches]
    assert np.array_equal(np.concatenate(covered), np.unique(everything[0].triangle)), "whole triangles, in order"
    for b, tris in zip(batches, covered):
        assert len(b) <= 50 or len(tris) == 1, f"a batch of {len(b)} fragments from {len(tris)} triangles"
    assert sum(len(b) for b in batches) == total
    assert any(len(b) > 50 for b in batches), "a triangle larger than the limit is a batch of its own"


def test_a_draw_over_the_batch_limit_keeps_its_memory_bounded():
    # 150 overlapping triangles on 64×64, about 300 000 fragments: in one batch the
    # fragment arrays (~70 bytes each) dominate; in batches of 4096 they do not.
    pos = overlapping_triangles(150, seed=3)
    colors = np.random.default_rng(2).random((len(pos), 3))

    def peak(limit):
        fb = softpipe.Framebuffer(64, 64)
        with batch_limit(limit):
            softpipe.draw(fb, pos[:3], varyings={"color": colors[:3]}, path="reference")    # warm up
            tracemalloc.start()
            try:
                softpipe.draw(fb.clear(), pos, varyings={"color": colors}, path="reference")
                return tracemalloc.get_traced_memory()[1], fb
            finally:
                tracemalloc.stop()

    big, fb_big = peak(1 << 22)
    small, fb_small = peak(4096)
    assert_same_bytes(fb_big, fb_small, "batches of 4096")
    print(f"peaks: one batch {big / 2 ** 20:.2f} MiB, batches of 4096 {small / 2 ** 20:.2f} MiB")
    assert big > 4 << 20, f"one batch peaked at only {big / 2 ** 20:.1f} MiB: the scene is too small to tell"
    assert small * 8 < big, (f"batches of 4096 fragments peaked at {small / 2 ** 20:.1f} MiB, "
                             f"one batch at {big / 2 ** 20:.1f} MiB")
