"""No silent NaN (issue 32): a draw that writes a NaN or infinite color says so once, on both paths,
naming how many samples, the first pixel and its primitive; debug_fragment there gives what the
compiled shader gave (NaN), not Python's exception."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp

W = H = 16
#: two triangles covering the framebuffer: the left half (x < 8) first, then the right half
QUAD = window_to_clip(np.array([[0, 0, 0.5], [8, 0, 0.5], [8, 16, 0.5], [8, 0, 0.5], [16, 0, 0.5], [16, 16, 0.5],
                                [0, 0, 0.5], [8, 16, 0.5], [0, 16, 0.5], [8, 0, 0.5], [16, 16, 0.5], [8, 16, 0.5]]),
                      W, H)


def sqrt_of_x_less_10(varyings, uniforms, frag):
    """math.pow of a negative number where x < 10: NaN in compiled code, ValueError in Python."""
    g = math.pow(frag.x - 10.0, 0.5)
    return (g, 0.5, 0.5, 1.0)


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_a_draw_that_writes_nan_says_so_once_with_the_first_pixel(path):
    fb = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning) as record:
        call = sp.DrawCall(fb, QUAD, fragment_shader=sqrt_of_x_less_10, path=path)
        call.run()
    assert len(record) == 1
    # pixels x = 0 … 9 have centres x + ½ < 10: 10 columns × 16 rows
    assert call.non_finite.count == 160
    message = str(record[0].message)
    assert message.startswith("the draw wrote 160 samples whose color is NaN or infinite, the first at pixel (0, ")
    assert "trace.debug_fragment(0, " in message
    assert np.isnan(fb.color[:, :10, 0]).all() and np.isfinite(fb.color[:, 10:]).all()


def test_the_first_pixel_named_is_the_first_row_and_column_and_its_primitive():
    fb = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning):
        call = sp.DrawCall(fb, QUAD, fragment_shader=sqrt_of_x_less_10, path="reference")
        call.run()
    # the reference path names its first such fragment: primitive 0, (0,0)-(8,0)-(8,16), walks from the
    # bottom window row (image row 15) left to right, and covers pixel 0 there (centre 0.5 > 0.25)
    nf = call.non_finite
    assert (nf.x, nf.y, nf.primitive_id) == (0, 15, 0)
    fast = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning):
        call = sp.DrawCall(fast, QUAD, fragment_shader=sqrt_of_x_less_10, path="fast")
        call.run()
    assert (call.non_finite.x, call.non_finite.y) == (0, 0)          # the fast path: image row 0 first
    assert call.non_finite.primitive_id == 2                        # the top-left triangle holds (0, 0)


def test_a_finite_draw_says_nothing():
    fb = sp.Framebuffer(W, H)
    with warnings.catch_warnings():
        warnings.simplefilter("error", sp.NonFiniteColorWarning)
        call = sp.DrawCall(fb, QUAD, varyings={"color": np.ones((12, 3))})
        call.run()
    assert call.non_finite is None


def test_debug_fragment_gives_the_nan_the_compiled_shader_gave():
    fb = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning):
        trace = sp.draw(fb, QUAD, fragment_shader=sqrt_of_x_less_10, trace=True)
    r, g, b, a = trace.debug_fragment(3, 5)
    assert math.isnan(r) and (g, b, a) == (0.5, 0.5, 1.0)
    assert trace.debug_fragment(12, 5)[0] == pytest.approx(math.sqrt(12.5 - 10.0))
    # the shader itself, called as Python, still raises: only debug_fragment runs it as compiled
    with pytest.raises(ValueError):
        sqrt_of_x_less_10(None, None, sp.FragInfo(3.5, 5.5, 0.5, True, 0))


def test_an_overflow_is_infinity_in_debug_fragment_as_compiled():
    def overflow(varyings, uniforms, frag):
        return (math.exp(frag.x * 1000.0), 0.0, 0.0, 1.0)

    fb = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning, match="the draw wrote 256 samples"):
        trace = sp.draw(fb, QUAD, fragment_shader=overflow, trace=True)
    assert trace.debug_fragment(4, 4)[0] == math.inf


def test_the_stage_pictures_mark_the_non_finite_pixels_only_when_there_are_some():
    from softpipe.views.pictures import stage_pictures
    fb = sp.Framebuffer(W, H)
    with pytest.warns(sp.NonFiniteColorWarning):
        trace = sp.draw(fb, QUAD, fragment_shader=sqrt_of_x_less_10, trace=True)
    pics = stage_pictures(trace)
    marked = (pics["non-finite"] == (255, 0, 255)).all(axis=2)
    assert marked[:, :10].all() and not marked[:, 10:].any()           # the columns whose centre x < 10
    assert (pics["non-finite"][:, 10:] == pics["final"][:, 10:]).all()
    finite = sp.draw(sp.Framebuffer(W, H), QUAD, varyings={"color": np.ones((12, 3))}, trace=True)
    assert "non-finite" not in stage_pictures(finite)


@pytest.mark.parametrize("mask, warns", [((False, False, False, False), False), ((False, True, True, True), False),
                                         ((True, False, False, False), True)])
def test_only_the_channels_the_color_mask_writes_count_as_written(mask, warns):
    """The shader's NaN is in red alone: masked off (a depth-only pass, or red held back), nothing NaN is
    written and nothing is said; red written, the draw says so. The fast path draws a masked color only
    depth-only, where no shader runs: the reference path is the one that shades under a mask."""
    fb = sp.Framebuffer(W, H).clear((0.25, 0.25, 0.25, 1.0))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        call = sp.DrawCall(fb, QUAD, fragment_shader=sqrt_of_x_less_10, color_mask=mask, path="reference")
        call.run()
    said = [w for w in record if issubclass(w.category, sp.NonFiniteColorWarning)]
    assert len(said) == (1 if warns else 0)
    assert (call.non_finite is not None) == warns
    assert np.isnan(fb.color[:, :10, 0]).all() == warns
    if warns:
        assert call.non_finite.count == 160
