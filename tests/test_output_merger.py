"""The whole output merger (issue 30): scissor, stencil, color mask, blend equations and factors, the
multisample operations, the occlusion query — each against GL's definition, written out here.

Scenes are full-window quads (two triangles with integer window corners), so every pixel centre is
covered exactly once and the expected value at each pixel follows from the state alone. GL's
definitions are restated in this file (``GL_COMPARE``, ``GL_STENCIL_OP``, ``gl_factor``, ``gl_blend``)
independently of softpipe's kernels, from the GL 4.6 specification §17.3 (per-fragment operations).
Colors are multiples of 1/8 so float arithmetic is exact and compared with ==.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
from softpipe.pipeline.merge_state import BLEND_EQUATIONS, BLEND_FACTORS, COMPARE_FUNCS, STENCIL_OPS
from softpipe.pipeline.visibility import fast_path_blocker

GL_COMPARE = {"never": lambda a, b: False, "less": lambda a, b: a < b, "equal": lambda a, b: a == b,
              "lequal": lambda a, b: a <= b, "greater": lambda a, b: a > b, "notequal": lambda a, b: a != b,
              "gequal": lambda a, b: a >= b, "always": lambda a, b: True}
GL_STENCIL_OP = {"keep": lambda s, ref: s, "zero": lambda s, ref: 0, "replace": lambda s, ref: ref,
                 "incr": lambda s, ref: min(s + 1, 255), "incr_wrap": lambda s, ref: (s + 1) % 256,
                 "decr": lambda s, ref: max(s - 1, 0), "decr_wrap": lambda s, ref: (s - 1) % 256,
                 "invert": lambda s, ref: 255 - s}


def quad(width, height, depth=0.5, color=(1.0, 1.0, 1.0, 1.0), x0=0, y0=0, x1=None, y1=None, clockwise=False):
    """(positions, indices, varyings) of two triangles covering window [x0, x1] × [y0, y1] at window depth
    ``depth``, one color: ``draw(fb, *quad(...))``."""
    x1 = width if x1 is None else x1
    y1 = height if y1 is None else y1
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y0), (x1, y1), (x0, y1)]
    if clockwise:
        corners = [corners[0], corners[2], corners[1], corners[3], corners[5], corners[4]]
    pos = window_to_clip([(x, y, 2 * depth - 1) for x, y in corners], width, height)
    return pos, None, {"color": np.tile(np.asarray(color, float), (6, 1))}


# ------------------------------------------------------------------ scissor

@pytest.mark.parametrize("scissor", [(1, 2, 3, 4), (0, 0, 8, 6), (5, 3, 10, 10), (-2, -1, 4, 3), (3, 3, 0, 2),
                                     (20, 20, 5, 5)])
@pytest.mark.parametrize("path", ["reference", "fast"])
def test_the_scissor_writes_exactly_the_pixels_of_its_rectangle(scissor, path):
    W, H = 8, 6
    fb = sp.Framebuffer(W, H).clear((0, 0, 0, 1))
    sp.draw(fb, *quad(W, H), scissor=scissor, path=path)
    x, y, w, h = scissor
    # window (column i, row r) is in the rectangle when x ≤ i < x + w and y ≤ r < y + h; image row = H − 1 − r
    expected = np.zeros((H, W), bool)
    for i in range(W):
        for r in range(H):
            expected[H - 1 - r, i] = x <= i < x + w and y <= r < y + h
    assert np.array_equal(fb.to_uint8()[..., 0] == 255, expected)
    assert np.array_equal(fb.depth == 0.5, expected)


def test_a_traced_draw_names_the_scissored_fragments_and_writes_the_same_pixels():
    W, H = 8, 6
    plain, traced = sp.Framebuffer(W, H), sp.Framebuffer(W, H)
    sp.draw(plain, *quad(W, H), scissor=(2, 1, 3, 2))
    trace = sp.draw(traced, *quad(W, H), scissor=(2, 1, 3, 2), trace=True)
    assert np.array_equal(plain.color, traced.color) and np.array_equal(plain.depth, traced.depth)
    verdicts = trace.verdicts
    assert len(trace.fragments) == W * H          # the trace made them all, and the merger stopped the rest
    assert (verdicts == "written").sum() == 6 and (verdicts == "scissored").sum() == W * H - 6
    assert trace.pixel_history(0, 0)[0].verdict == "scissored"
    assert trace.pixel_history(2, H - 2)[0].verdict == "written"     # window row 1 → image row 4


# ------------------------------------------------------------------ stencil test and ops

@pytest.fixture
def stored():
    """Every 8-bit value once: a 16 × 16 framebuffer whose stencil is 0..255 in image order."""
    return np.arange(256, dtype=np.uint8).reshape(16, 16)


@pytest.mark.parametrize("func", COMPARE_FUNCS)
@pytest.mark.parametrize("ref, mask", [(0, 0xFF), (127, 0xFF), (255, 0xFF), (0x35, 0x0F), (300, 0xF0), (-4, 0xFF)])
def test_every_stencil_func_passes_where_gl_says(func, ref, mask, stored):
    fb = sp.Framebuffer(16, 16).clear((0, 0, 0, 1))
    fb.stencil[...] = stored
    sp.draw(fb, *quad(16, 16), stencil=sp.Stencil(func=func, ref=ref, mask=mask))
    r = min(max(ref, 0), 255)                   # GL clamps ref to the buffer's range
    expected = np.array([[GL_COMPARE[func](r & mask, int(s) & mask) for s in row] for row in stored])
    assert np.array_equal(fb.to_uint8()[..., 0] == 255, expected)
    assert np.array_equal(fb.stencil, stored)           # "keep" everywhere: nothing written


@pytest.mark.parametrize("op", STENCIL_OPS)
@pytest.mark.parametrize("when", ["fail", "depth_fail", "depth_pass"])
@pytest.mark.parametrize("write_mask", [0xFF, 0x0F, 0x81])
def test_every_stencil_op_at_every_value_with_the_write_mask(op, when, write_mask, stored):
    fb = sp.Framebuffer(16, 16).clear((0, 0, 0, 1), depth=0.5)
    fb.stencil[...] = stored
    ref = 0xA7
    func = "never" if when == "fail" else "always"
    depth = 0.75 if when == "depth_fail" else 0.25        # behind / in front of the stored 0.5
    st = sp.Stencil(func=func, ref=ref, **{when: op}, write_mask=write_mask)
    sp.draw(fb, *quad(16, 16, depth=depth), stencil=st)
    expected = [(int(s) & ~write_mask & 255) | (GL_STENCIL_OP[op](int(s), ref) & write_mask)
                for s in stored.ravel()]
    assert fb.stencil.ravel().tolist() == expected
    assert (fb.to_uint8()[..., 0] == 255).all() == (when == "depth_pass")


def test_with_the_depth_test_off_a_passing_fragment_takes_the_depth_pass_op():
    fb = sp.Framebuffer(4, 4).clear(depth=0.0)
    sp.draw(fb, *quad(4, 4, depth=0.75), depth_test=None, stencil=sp.Stencil(depth_pass="incr", depth_fail="zero"))
    assert (fb.stencil == 1).all()


def test_front_and_back_faces_take_their_own_stencil_state():
    fb = sp.Framebuffer(8, 4).clear()
    front = quad(8, 4, x1=4)                              # CCW: front-facing, the left half
    back = quad(8, 4, x0=4, clockwise=True)               # CW: back-facing, the right half
    pos = np.concatenate([front[0], back[0]])
    var = {"color": np.concatenate([front[2]["color"], back[2]["color"]])}
    sp.draw(fb, pos, varyings=var, stencil=sp.Stencil(depth_pass="incr"),
            stencil_back=sp.Stencil(depth_pass="decr_wrap"))
    assert (fb.stencil[:, :4] == 1).all() and (fb.stencil[:, 4:] == 255).all()
    fb.clear()
    sp.draw(fb, pos, varyings=var, stencil=sp.Stencil(depth_pass="incr"))      # no stencil_back: the same state
    assert (fb.stencil == 1).all()


def test_the_stencil_counts_overlapping_draws_and_a_second_draw_tests_it():
    fb = sp.Framebuffer(8, 8).clear((0, 0, 0, 1))
    count = sp.Stencil(depth_pass="incr")
    sp.draw(fb, *quad(8, 8, x1=6), stencil=count, color_mask=(False,) * 4, depth_write=False)
    sp.draw(fb, *quad(8, 8, x0=2), stencil=count, color_mask=(False,) * 4, depth_write=False)
    assert fb.stencil[0].tolist() == [1, 1, 2, 2, 2, 2, 1, 1]
    assert (fb.to_uint8()[..., :3] == 0).all() and (fb.depth == 1.0).all()   # masked: nothing else written
    sp.draw(fb, *quad(8, 8, color=(0.5, 0.25, 1, 1)), stencil=sp.Stencil(func="equal", ref=2))
    assert (fb.to_uint8()[:, :, 0] == 128).tolist() == [[False, False, True, True, True, True, False, False]] * 8


def test_clear_sets_the_stencil_and_refuses_values_outside_eight_bits():
    fb = sp.Framebuffer(3, 2, sp.grid(2)).clear(stencil=7)
    assert fb.samples_stencil.shape == (4, 2, 3) and (fb.samples_stencil == 7).all()
    assert fb.samples_stencil.dtype == np.uint8
    with pytest.raises(ValueError, match=r"clear stencil must be in \[0, 255\]"):
        fb.clear(stencil=256)
    with pytest.raises(TypeError, match="clear stencil must be an integer"):
        fb.clear(stencil=1.5)
    assert (fb.samples_stencil == 7).all()


# ------------------------------------------------------------------ color mask

@pytest.mark.parametrize("mask", [tuple(bool(m >> c & 1) for c in range(4)) for m in range(16)])
def test_the_color_mask_writes_only_its_channels(mask):
    before, color = (0.125, 0.25, 0.375, 0.5), (0.75, 0.625, 0.875, 1.0)
    fb = sp.Framebuffer(4, 4).clear(before)
    sp.draw(fb, *quad(4, 4, color=color), color_mask=mask)
    want = [c if m else b for c, b, m in zip(color, before, mask)]
    assert (fb.color == np.float32(want)).all()
    assert (fb.depth == 0.5).all()                  # the depth mask is depth_write's


# ------------------------------------------------------------------ blending

SRC, DST, CONST = (0.75, 0.25, 0.5, 0.625), (0.125, 0.5, 0.875, 0.25), (0.25, 0.375, 0.625, 0.5)


def gl_factor(name, c, src, dst, const):
    """GL 4.6 table 17.2: the factor for channel c (0..2 RGB, 3 alpha)."""
    sa, da = src[3], dst[3]
    return {"zero": 0.0, "one": 1.0, "src_color": src[c], "one_minus_src_color": 1 - src[c],
            "dst_color": dst[c], "one_minus_dst_color": 1 - dst[c], "src_alpha": sa, "one_minus_src_alpha": 1 - sa,
            "dst_alpha": da, "one_minus_dst_alpha": 1 - da, "constant_color": const[c],
            "one_minus_constant_color": 1 - const[c], "constant_alpha": const[3],
            "one_minus_constant_alpha": 1 - const[3],
            "src_alpha_saturate": min(sa, 1 - da) if c < 3 else 1.0}[name]


def gl_blend(equation, factors, src, dst, const):
    """GL 4.6 table 17.1, RGB with factors[0:2] and equation[0], alpha with factors[2:4] and equation[1]."""
    out = []
    for c in range(4):
        eq = equation[0] if c < 3 else equation[1]
        fs, fd = (factors[0], factors[1]) if c < 3 else (factors[2], factors[3])
        s, d = src[c] * gl_factor(fs, c, src, dst, const), dst[c] * gl_factor(fd, c, src, dst, const)
        out.append({"add": s + d, "subtract": s - d, "reverse_subtract": d - s, "min": min(src[c], dst[c]),
                    "max": max(src[c], dst[c])}[eq])
    return out


def blended(**state):
    fb = sp.Framebuffer(2, 2).clear(DST)
    sp.draw(fb, *quad(2, 2, color=SRC), blend_color=CONST, **state)
    assert (fb.color == fb.color[0, 0]).all()
    return fb.color[0, 0]


@pytest.mark.parametrize("equation", BLEND_EQUATIONS)
@pytest.mark.parametrize("factor", BLEND_FACTORS)
def test_every_blend_factor_as_source_and_as_destination_in_every_equation(equation, factor):
    for factors in ((factor, "one"), (factor, "one_minus_src_alpha"), ("one", factor), ("src_alpha", factor)):
        got = blended(blend=factors, blend_equation=equation)
        want = gl_blend((equation, equation), factors * 2, SRC, DST, CONST)
        assert got.tolist() == np.float32(want).tolist(), (factors, equation)


def test_separate_rgb_and_alpha_factors_and_equations():
    factors = ("src_alpha", "one_minus_src_alpha", "one", "zero")
    got = blended(blend=factors, blend_equation=("add", "max"))
    assert got.tolist() == np.float32(gl_blend(("add", "max"), factors, SRC, DST, CONST)).tolist()
    got = blended(blend="premultiplied")
    assert got.tolist() == np.float32([s + d * (1 - SRC[3]) for s, d in zip(SRC, DST)]).tolist()


def test_blending_happens_before_the_color_mask():
    fb = sp.Framebuffer(2, 2).clear(DST)
    sp.draw(fb, *quad(2, 2, color=SRC), blend="additive", color_mask=(True, False, True, False))
    assert fb.color[0, 0].tolist() == np.float32([SRC[0] + DST[0], DST[1], SRC[2] + DST[2], DST[3]]).tolist()


# ------------------------------------------------------------------ multisample operations

def shader_alpha(v, uniforms, frag):
    return (1.0, 1.0, 1.0, uniforms.alpha)


@pytest.mark.parametrize("alpha, covered", [(0.0, 0), (0.1, 0), (0.125, 0), (0.25, 1), (0.375, 2), (0.5, 2),
                                            (0.625, 2), (0.7, 3), (1.0, 4), (3.0, 4), (-1.0, 0)])
def test_alpha_to_coverage_covers_round_alpha_times_samples_of_a_pixel(alpha, covered):
    fb = sp.Framebuffer(4, 4, sp.grid(2)).clear((0, 0, 0, 0))
    sp.draw(fb, *quad(4, 4), fragment_shader=shader_alpha, uniforms={"alpha": alpha}, alpha_to_coverage=True)
    written = fb.samples_color[:, :, :, 0] == 1.0
    # samples 0 .. round(alpha·4) − 1 (half to even: 0.125·4 = 0.5 → 0, 0.375·4 = 1.5 → 2, 0.625·4 = 2.5 → 2)
    assert [bool(written[m].all()) for m in range(4)] == [m < covered for m in range(4)]
    assert [bool(written[m].any()) for m in range(4)] == [m < covered for m in range(4)]


def test_the_sample_mask_writes_only_its_samples_and_is_ignored_with_one_sample():
    fb = sp.Framebuffer(4, 4, sp.grid(2)).clear()
    sp.draw(fb, *quad(4, 4), sample_mask=0b1010)
    assert [bool((fb.samples_color[m, ..., 0] == 1).all()) for m in range(4)] == [False, True, False, True]
    assert [bool((fb.samples_color[m, ..., 0] == 0).all()) for m in range(4)] == [True, False, True, False]
    one = sp.Framebuffer(4, 4).clear()
    sp.draw(one, *quad(4, 4), sample_mask=0, alpha_to_coverage=True)      # GL: no multisample buffer, no effect
    assert (one.color[..., 0] == 1).all()


# ------------------------------------------------------------------ occlusion query and pixel history

def test_the_occlusion_query_counts_the_samples_that_passed_every_test():
    fb = sp.Framebuffer(8, 8, sp.grid(2)).clear(depth=0.5)
    q = sp.OcclusionQuery()
    sp.draw(fb, *quad(8, 8, depth=0.25, x1=4), query=q)          # 4 × 8 pixels × 4 samples in front
    assert q.samples_passed == 128 and q.draws == 1
    sp.draw(fb, *quad(8, 8, depth=0.75), query=q)                # behind everything: none
    assert q.samples_passed == 128 and q.draws == 2
    sp.draw(fb, *quad(8, 8, depth=0.375), query=q, scissor=(0, 0, 8, 2))   # in front of 0.5 at the right half
    assert q.samples_passed == 128 + 4 * 2 * 4
    trace = sp.draw(fb, *quad(8, 8, depth=0.0), query=q, trace=True)
    assert q.samples_passed - 160 == trace.merged.samples_passed == (trace.verdicts == "written").sum() == 256
    q.reset()
    assert q.samples_passed == 0 and q.draws == 0


def test_pixel_history_names_the_test_that_stopped_each_fragment_and_the_stencil_before_and_after():
    fb = sp.Framebuffer(4, 4).clear(depth=0.5, stencil=3)
    pos = np.concatenate([quad(4, 4, depth=0.25)[0], quad(4, 4, depth=0.75)[0], quad(4, 4, depth=0.125)[0]])
    color = np.tile([1.0, 1, 1, 1], (18, 1))
    trace = sp.draw(fb, pos, varyings={"color": color}, trace=True,
                    stencil=sp.Stencil(func="lequal", ref=3, depth_pass="incr", depth_fail="invert"))
    h = trace.pixel_history(1, 1)
    # quad 1 passes (3 ≤ 3) and increments; quad 2 passes the stencil (3 ≤ 4), fails depth, inverts 4 → 251;
    # quad 3: 3 ≤ 251 passes, depth passes, 251 → 252
    assert [e.verdict for e in h] == ["written", "depth-failed", "written"]
    assert [e.stencil for e in h] == [(3, 4), (4, 251), (251, 252)]
    assert "stencil" in str(h) and "4 → 251" in str(h)
    assert (trace.before_stencil == 3).all() and (fb.stencil == 252).all()
    fb.clear(stencil=9)
    trace = sp.draw(fb, *quad(4, 4), stencil=sp.Stencil(func="equal", ref=1), trace=True)
    assert {e.verdict for e in trace.pixel_history(0, 0)} == {"stencil-failed"}


# ------------------------------------------------------------------ the fast path

@pytest.mark.parametrize("state, reason", [
    (dict(stencil=sp.Stencil()), "the stencil test is on"),
    (dict(color_mask=(True, True, True, False)), "the color mask"),
    (dict(blend="alpha"), "blending is on"),
])
def test_the_fast_path_says_why_it_does_not_take_a_draw(state, reason):
    call = sp.DrawCall(sp.Framebuffer(256, 256), *quad(256, 256), **state)
    path, why = call.choose_path()
    assert path == "reference" and why.startswith(reason)
    with pytest.raises(ValueError, match="path='fast' is not possible"):
        sp.DrawCall(sp.Framebuffer(8, 8), *quad(8, 8), path="fast", **state).run()


def test_multisample_masks_and_the_query_keep_to_the_reference_path():
    from softpipe.pipeline.merge_state import MergeState
    assert "alpha to coverage" in fast_path_blocker(MergeState(alpha_to_coverage=True), None, 4)
    assert fast_path_blocker(MergeState(alpha_to_coverage=True), None, 1) is None
    assert "sample mask" in fast_path_blocker(MergeState(sample_mask=0b0111), None, 4)
    assert fast_path_blocker(MergeState(sample_mask=0b1111), None, 4) is None
    assert "occlusion query" in fast_path_blocker(MergeState(), None, 1, counts_samples=True)
    assert "depth clamp" in fast_path_blocker(MergeState(depth_clamp=True), None, 1)


@pytest.mark.parametrize("topology", ["triangles", "lines", "points"])
def test_a_scissored_draw_gives_the_same_bytes_on_both_paths(topology, rng):
    W = H = 160
    n = 60 * {"triangles": 3, "lines": 2, "points": 1}[topology]
    pos = np.column_stack([rng.uniform(-1.2, 1.2, (n, 2)), rng.uniform(-0.9, 0.9, n), np.ones(n)])
    var = {"color": rng.uniform(0, 1, (n, 4))}
    out = {}
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(W, H)
        call = sp.DrawCall(fb, pos, varyings=var, topology=topology, scissor=(17, 30, 101, 77), path=path,
                           point_size=3.0)
        call.run()
        assert call.path_taken == path
        out[path] = (fb.color.copy(), fb.depth.copy())
    assert np.array_equal(out["reference"][0], out["fast"][0]) and np.array_equal(out["reference"][1], out["fast"][1])
    outside = np.ones((H, W), bool)
    outside[H - 107:H - 30, 17:118] = False
    assert (out["fast"][1][outside] == 1.0).all() and (out["fast"][1][~outside] < 1.0).any()


# ------------------------------------------------------------------ bad state

@pytest.mark.parametrize("state, error, message", [
    (dict(stencil=sp.Stencil), TypeError, "stencil must be a softpipe.Stencil"),
    (dict(stencil_back=sp.Stencil()), ValueError, "stencil_back is given but stencil is None"),
    (dict(color_mask=(True, True, True)), ValueError, "color_mask must be 4 booleans"),
    (dict(color_mask=(1, 1, 1, 1)), ValueError, "color_mask must be 4 booleans"),
    (dict(blend=("one", "one", "zero")), ValueError, "quadruple"),
    (dict(blend=("one", "two")), ValueError, "unknown blend factor 'two'"),
    (dict(blend_equation="plus"), ValueError, "unknown blend equation 'plus'"),
    (dict(blend_color=(1, 0, 0)), ValueError, "blend_color must be 4 finite numbers"),
    (dict(blend_color=(1, 0, 0, np.nan)), ValueError, "blend_color must be 4 finite numbers"),
    (dict(scissor=(0, 0, -1, 4)), ValueError, "scissor width and height must be at least 0"),
    (dict(scissor=(0, 0, 1.5, 4)), ValueError, "scissor must be"),
    (dict(sample_mask=-1), ValueError, "sample_mask must be in"),
    (dict(sample_mask=True), TypeError, "sample_mask must be an integer"),
    (dict(alpha_to_coverage=1), TypeError, "alpha_to_coverage must be True or False"),
    (dict(query=3), TypeError, "query must be a softpipe.OcclusionQuery"),
])
def test_bad_merger_state_is_refused_with_its_name(state, error, message):
    with pytest.raises(error, match=message):
        sp.draw(sp.Framebuffer(2, 2), *quad(2, 2), **state)


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(func="lesser"), ValueError, "Stencil func must be one of"),
    (dict(depth_pass="increment"), ValueError, "Stencil depth_pass must be one of"),
    (dict(ref=1.0), TypeError, "Stencil ref must be an integer"),
    (dict(mask=-1), ValueError, "Stencil mask must be at least 0"),
])
def test_bad_stencil_state_is_refused_with_its_name(kwargs, error, message):
    with pytest.raises(error, match=message):
        sp.Stencil(**kwargs)
