"""The output merger through softpipe.draw: depth test, depth write, blending, clears, discard.

Scenes are axis-aligned rectangles with integer corners in window coordinates
(y up), each drawn as two triangles. Every pixel centre is strictly inside or
strictly outside such a rectangle, so the covered pixels are obvious, and the
shared diagonal is watertight (each centre on it is covered exactly once).
Image row = H − 1 − window row.

All depths and colors are dyadic fractions (multiples of 1/8), so float32
arithmetic is exact and the expected values are compared with ==.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe

W = H = 4
RED, GREEN, BLUE = (1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0)


def rect(x0, y0, x1, y1, depth, color):
    """Two CCW triangles covering window [x0, x1] × [y0, y1] at window depth ``depth``."""
    z_ndc = 2 * depth - 1                          # window depth = (z_ndc + 1) / 2 with w = 1
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y0), (x1, y1), (x0, y1)]
    pos = window_to_clip([(x, y, z_ndc) for x, y in corners], W, H)
    return pos, np.tile(np.asarray(color, dtype=float), (6, 1))


def scene(*rects):
    pos = np.concatenate([r[0] for r in rects])
    col = np.concatenate([r[1] for r in rects])
    return pos, {"color": col}


def pixels_of(x0, y0, x1, y1):
    """Image (row, column) of every pixel whose centre is inside the window rectangle."""
    return {(H - 1 - j, i) for i in range(x0, x1) for j in range(y0, y1)}


# --------------------------------------------------------------- depth test
#
# Rectangle A (red, drawn first) covers columns 0–2, B (green, second) columns
# 1–3, both only window rows 1–3, so that window row 0 (image row 3) is
# covered by neither. Regions: "a" = column 0, "ab" = columns 1–2, "b" =
# column 3, "-" = image row 3. The depth buffer is cleared to 0.5 and the
# color to blue ("bg").

A_ONLY, BOTH, B_ONLY, NONE = (1, 0), (1, 1), (1, 3), (3, 0)     # one (row, col) per region


def draw_ab(func, za, zb, depth_write=True):
    fb = softpipe.Framebuffer(W, H).clear(BLUE, depth=0.5)
    pos, var = scene(rect(0, 1, 3, 4, za, RED), rect(1, 1, 4, 4, zb, GREEN))
    softpipe.draw(fb, pos, varyings=var, depth_test=func, depth_write=depth_write)
    return fb


# Expected winner in regions (a, ab, b), worked out by hand from OpenGL's rule
# "the fragment passes if z_frag OP z_stored", A first, stored depth 0.5 at start.
NEAR_FAR = {   # A at 0.25 (in front of the clear depth), B at 0.75 (behind it)
    "never": "- - -", "less": "A A -", "equal": "- - -", "lequal": "A A -",
    "greater": "- B B", "notequal": "A B B", "gequal": "- B B", "always": "A B B",
}
FAR_NEAR = {   # A at 0.75, B at 0.25
    "never": "- - -", "less": "- B B", "equal": "- - -", "lequal": "- B B",
    "greater": "A A -", "notequal": "A B B", "gequal": "A A -", "always": "A B B",
}
ALL_EQUAL = {  # A, B and the clear depth all 0.5
    "never": "- - -", "less": "- - -", "equal": "A B B", "lequal": "A B B",
    "greater": "- - -", "notequal": "- - -", "gequal": "A B B", "always": "A B B",
}
CASES = [("near_far", 0.25, 0.75, NEAR_FAR), ("far_near", 0.75, 0.25, FAR_NEAR), ("equal", 0.5, 0.5, ALL_EQUAL)]


@pytest.mark.parametrize("func", softpipe.pipeline.merge_state.DEPTH_FUNCS)
@pytest.mark.parametrize("case, za, zb, table", CASES, ids=[c[0] for c in CASES])
def test_depth_compare_functions_pick_the_expected_winner(func, case, za, zb, table):
    fb = draw_ab(func, za, zb)
    color = {"A": RED, "B": GREEN, "-": BLUE}
    depth = {"A": za, "B": zb, "-": 0.5}
    for region, winner in zip((A_ONLY, BOTH, B_ONLY), table[func].split()):
        # every pixel of the region, not just one
        cols = {A_ONLY: [0], BOTH: [1, 2], B_ONLY: [3]}[region]
        for row in range(3):
            for col in cols:
                assert tuple(fb.color[row, col]) == color[winner], (func, region, row, col)
                assert fb.depth[row, col] == depth[winner], (func, region, row, col)
    # the row neither rectangle covers keeps the clear values
    assert (fb.color[3] == BLUE).all() and (fb.depth[3] == 0.5).all()


def test_depth_write_off_tests_against_the_cleared_depth_only():
    # less, A at 0.25 then B at 0.375. With writes on, B loses to A where they
    # overlap; with writes off the stored depth stays 0.5 and B wins there.
    on = draw_ab("less", 0.25, 0.375, depth_write=True)
    off = draw_ab("less", 0.25, 0.375, depth_write=False)
    assert tuple(on.color[BOTH]) == RED and on.depth[BOTH] == 0.25
    assert tuple(off.color[BOTH]) == GREEN
    assert tuple(off.color[A_ONLY]) == RED and tuple(off.color[B_ONLY]) == GREEN
    assert (off.depth == 0.5).all()


def test_depth_test_none_draws_everything_in_order_and_writes_no_depth():
    # both behind the cleared depth: "less" would reject them; None neither tests nor writes
    fb = draw_ab(None, 0.75, 0.875, depth_write=True)
    assert tuple(fb.color[A_ONLY]) == RED
    assert tuple(fb.color[BOTH]) == GREEN          # later primitive on top
    assert tuple(fb.color[B_ONLY]) == GREEN
    assert (fb.depth == 0.5).all()


def test_default_state_is_less_with_depth_writes():
    fb = softpipe.Framebuffer(W, H)                 # cleared to depth 1.0
    pos, var = scene(rect(0, 0, 4, 4, 0.5, RED), rect(0, 0, 2, 4, 0.5, GREEN), rect(2, 0, 4, 4, 0.25, BLUE))
    softpipe.draw(fb, pos, varyings=var)
    # green at an equal depth fails "less"; blue is nearer and wins
    assert (fb.color[:, :2] == RED).all() and (fb.color[:, 2:] == BLUE).all()
    assert (fb.depth[:, :2] == 0.5).all() and (fb.depth[:, 2:] == 0.25).all()


def test_depth_is_tested_against_earlier_draws_too():
    fb = softpipe.Framebuffer(W, H)
    pos, var = scene(rect(0, 0, 4, 4, 0.5, RED))
    softpipe.draw(fb, pos, varyings=var)
    pos, var = scene(rect(0, 0, 4, 2, 0.75, GREEN), rect(0, 2, 4, 4, 0.375, BLUE))
    softpipe.draw(fb, pos, varyings=var)
    assert (fb.color[2:] == RED).all() and (fb.depth[2:] == 0.5).all()        # window rows 0–1: green lost
    assert (fb.color[:2] == BLUE).all() and (fb.depth[:2] == 0.375).all()


# ------------------------------------------------------------------ blending
#
# Three overlapping translucent rectangles T0, T1, T2 (drawn in that order):
# T0 covers columns 0–1, T1 columns 1–2, T2 window rows 0–1. Every subset of
# {T0, T1, T2} is some pixel's cover set. The expected color is OpenGL's
# FUNC_ADD equation, result = src·F_src + dst·F_dst per channel (alpha too,
# with the same factors), folded over the cover set in primitive order.

T_COLORS = [(0.5, 0.25, 0.0, 0.5), (0.0, 0.75, 0.5, 0.25), (0.25, 0.0, 1.0, 0.75)]
T_RECTS = [(0, 0, 2, 4), (1, 0, 3, 4), (0, 0, 4, 2)]
CLEAR = (0.125, 0.25, 0.5, 1.0)


def factor(name, src, dst):
    """A blend factor for all four channels, from the OpenGL table."""
    sa, da = src[3], dst[3]
    one = np.ones(4)
    return {
        "zero": 0 * one, "one": one,
        "src_color": np.array(src), "one_minus_src_color": 1 - np.array(src),
        "dst_color": np.array(dst), "one_minus_dst_color": 1 - np.array(dst),
        "src_alpha": sa * one, "one_minus_src_alpha": (1 - sa) * one,
        "dst_alpha": da * one, "one_minus_dst_alpha": (1 - da) * one,
    }[name]


def expected_blend(src_name, dst_name):
    out = np.empty((H, W, 4))
    for row in range(H):
        for col in range(W):
            j = H - 1 - row
            dst = np.array(CLEAR)
            for (x0, y0, x1, y1), src in zip(T_RECTS, T_COLORS):
                if x0 <= col < x1 and y0 <= j < y1:
                    dst = np.array(src) * factor(src_name, src, dst) + dst * factor(dst_name, src, dst)
            out[row, col] = dst
    return out


def draw_translucent(blend):
    fb = softpipe.Framebuffer(W, H).clear(CLEAR)
    pos, var = scene(*(rect(*r, 0.5, c) for r, c in zip(T_RECTS, T_COLORS)))
    softpipe.draw(fb, pos, varyings=var, blend=blend, depth_test=None)
    return fb


@pytest.mark.parametrize("blend, factors", [
    ("alpha", ("src_alpha", "one_minus_src_alpha")),
    ("additive", ("one", "one")),
    (("dst_color", "zero"), ("dst_color", "zero")),                         # modulate
    (("one_minus_dst_color", "one"), ("one_minus_dst_color", "one")),       # screen
    (("one_minus_dst_alpha", "src_color"), ("one_minus_dst_alpha", "src_color")),
    (["dst_alpha", "one_minus_src_color"], ("dst_alpha", "one_minus_src_color")),
])
def test_blending_matches_the_equation_in_primitive_order(blend, factors):
    fb = draw_translucent(blend)
    want = expected_blend(*factors)
    assert np.array_equal(fb.color, want.astype(np.float32)), f"got\n{fb.color}\nwant\n{want}"


def test_alpha_blending_by_hand_at_the_triple_overlap():
    # pixel (row 3, col 1): window row 0, covered by T0, T1 and T2, in that order
    fb = draw_translucent("alpha")
    c = np.array(CLEAR)
    c = np.array([0.5, 0.25, 0.0, 0.5]) * 0.5 + c * 0.5        # (0.3125, 0.25, 0.25, 0.75)
    c = np.array([0.0, 0.75, 0.5, 0.25]) * 0.25 + c * 0.75     # (0.234375, 0.375, 0.3125, 0.625)
    c = np.array([0.25, 0.0, 1.0, 0.75]) * 0.75 + c * 0.25     # (0.24609375, 0.09375, 0.828125, 0.71875)
    assert np.array_equal(c, [0.24609375, 0.09375, 0.828125, 0.71875])
    assert tuple(fb.color[3, 1]) == tuple(c)
    # (row 0, col 1) is window row 3: T0 then T1 only, the second line above
    assert tuple(fb.color[0, 1]) == (0.234375, 0.375, 0.3125, 0.625)


def test_additive_blending_is_not_clamped_in_the_float_buffer():
    fb = draw_translucent("additive")
    # (row 3, col 1): clear + T0 + T1 + T2 in every channel
    assert tuple(fb.color[3, 1]) == (0.875, 1.25, 2.0, 2.5)
    assert tuple(fb.to_uint8()[3, 1]) == (223, 255, 255, 255)       # round(0.875·255) = 223


def test_blending_off_replaces_the_color():
    fb = draw_translucent(None)
    assert tuple(fb.color[3, 1]) == T_COLORS[2]
    assert tuple(fb.color[0, 1]) == T_COLORS[1]
    assert tuple(fb.color[0, 3]) == CLEAR


def test_fragments_that_fail_the_depth_test_are_not_blended():
    fb = softpipe.Framebuffer(W, H).clear(CLEAR, depth=0.5)
    pos, var = scene(rect(0, 0, 2, 4, 0.25, (0.5, 0.5, 0.5, 0.5)), rect(2, 0, 4, 4, 0.75, (0.5, 0.5, 0.5, 0.5)))
    softpipe.draw(fb, pos, varyings=var, blend="additive")
    assert tuple(fb.color[0, 0]) == (0.625, 0.75, 1.0, 1.5)
    assert tuple(fb.color[0, 3]) == CLEAR


# -------------------------------------------------------------------- clears

def test_a_new_framebuffer_is_opaque_black_at_depth_one():
    fb = softpipe.Framebuffer(3, 2)
    assert fb.color.shape == (2, 3, 4) and fb.depth.shape == (2, 3)
    assert fb.color.dtype == np.float32 and fb.depth.dtype == np.float32
    assert (fb.color == (0, 0, 0, 1)).all() and (fb.depth == 1.0).all()


def test_clear_sets_every_pixel_and_rgb_gets_alpha_one():
    fb = softpipe.Framebuffer(W, H)
    pos, var = scene(rect(0, 0, 4, 4, 0.25, RED))
    softpipe.draw(fb, pos, varyings=var)
    assert (fb.color == RED).all()
    assert fb.clear((0.25, 0.5, 0.75), depth=0.125) is fb
    assert (fb.color == (0.25, 0.5, 0.75, 1.0)).all() and (fb.depth == 0.125).all()
    fb.clear((0.25, 0.5, 0.75, 0.0))
    assert (fb.color == (0.25, 0.5, 0.75, 0.0)).all() and (fb.depth == 1.0).all()


def test_clear_rejects_bad_values():
    fb = softpipe.Framebuffer(W, H)
    with pytest.raises(ValueError, match=r"clear color must be 3 or 4 finite numbers"):
        fb.clear((1, 0))
    with pytest.raises(ValueError, match=r"clear color must be 3 or 4 finite numbers"):
        fb.clear((1, 0, float("nan")))
    with pytest.raises(ValueError, match=r"clear depth must be in \[0, 1\]"):
        fb.clear(depth=1.5)


# ------------------------------------------------------------------- discard

def discard_left_half(varyings, uniforms, frag):
    """Discard every fragment with its centre left of x = 2; the rest is yellow."""
    if frag.x < 2.0:
        return softpipe.DISCARD
    return (1.0, 1.0, 0.0, 1.0)


def test_discard_leaves_color_and_depth_untouched():
    fb = softpipe.Framebuffer(W, H)
    pos, var = scene(rect(0, 0, 4, 4, 0.75, RED))
    softpipe.draw(fb, pos, varyings=var)
    # a nearer rectangle over everything: the left half is discarded
    pos, var = scene(rect(0, 0, 4, 4, 0.25, GREEN))
    softpipe.draw(fb, pos, varyings=var, fragment_shader=discard_left_half)
    assert (fb.color[:, :2] == RED).all() and (fb.depth[:, :2] == 0.75).all()
    assert (fb.color[:, 2:] == (1, 1, 0, 1)).all() and (fb.depth[:, 2:] == 0.25).all()
    # a discarded fragment did not write depth: a third rectangle at 0.5 still wins on the left
    pos, var = scene(rect(0, 0, 4, 4, 0.5, BLUE))
    softpipe.draw(fb, pos, varyings=var)
    assert (fb.color[:, :2] == BLUE).all() and (fb.color[:, 2:] == (1, 1, 0, 1)).all()


def test_discard_with_blending_and_no_depth_test():
    fb = softpipe.Framebuffer(W, H).clear(CLEAR)
    pos, var = scene(rect(0, 0, 4, 4, 0.5, GREEN))
    softpipe.draw(fb, pos, varyings=var, fragment_shader=discard_left_half, blend="additive", depth_test=None)
    assert (fb.color[:, :2] == CLEAR).all()
    assert (fb.color[:, 2:] == (1.125, 1.25, 0.5, 2.0)).all()
    assert (fb.depth == 1.0).all()
