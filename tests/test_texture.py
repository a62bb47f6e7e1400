"""Textures: wrap modes, filters, orientation, mipmaps, level of detail, bad input.

Every expected value is worked out by hand in the test from the GL rules quoted
in softpipe/light/texture.py: texel i covers [i/W, (i+1)/W); nearest takes
floor(u·W); bilinear takes i0 = floor(u·W − ½) with weight frac(u·W − ½) on i0 + 1.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from collections import namedtuple

import numba
import numpy as np
import pytest
from patience import PATIENCE
from PIL import Image

from softpipe.light.texture import (
    Texture2D,
    TextureUniform,
    mip_level,
    texture,
    texture_grad,
    texture_lod,
    texture_size,
)

WRAPS = ("repeat", "clamp", "mirror")


def red(tex: Texture2D, u: float, v: float, lod: float = 0.0) -> float:
    return tex.sample(u, v, lod)[0]


def tex2(**kw) -> Texture2D:
    """2×2, image rows (top first) [10, 20] / [30, 40]; so the BOTTOM row (v < ½) is 30, 40."""
    return Texture2D(np.array([[10.0, 20.0], [30.0, 40.0]], dtype=np.float32), **kw)


def tex4(**kw) -> Texture2D:
    """4×4 whose texel (column i, row j counted from the bottom) holds i + 10·j."""
    img = np.array([[c + 10.0 * (3 - r) for c in range(4)] for r in range(4)], dtype=np.float32)
    return Texture2D(img, **kw)


# ---------------------------------------------------------------- nearest


# (u, expected texel column per wrap mode) for a 2-texel row; x = u·2, i = floor(x)
NEAREST_2 = [
    (0.25, {"repeat": 0, "clamp": 0, "mirror": 0}),  # texel centre
    (0.75, {"repeat": 1, "clamp": 1, "mirror": 1}),  # texel centre
    (0.0, {"repeat": 0, "clamp": 0, "mirror": 0}),  # left edge
    (0.5, {"repeat": 1, "clamp": 1, "mirror": 1}),  # shared edge belongs to the right texel
    (1.0, {"repeat": 0, "clamp": 1, "mirror": 1}),  # i = 2: 2 mod 2 = 0; clamped 1; mirrored 1
    (-0.25, {"repeat": 1, "clamp": 0, "mirror": 0}),  # i = -1
    (1.25, {"repeat": 0, "clamp": 1, "mirror": 1}),  # i = 2
    (-0.75, {"repeat": 0, "clamp": 0, "mirror": 1}),  # i = -2: mirror of -2 is texel 1
]


@pytest.mark.parametrize("wrap", WRAPS)
@pytest.mark.parametrize("u, cols", NEAREST_2)
def test_nearest_2x2_wrap(u, cols, wrap):
    bottom_row = (30.0, 40.0)
    top_row = (10.0, 20.0)
    tex = tex2(wrap=wrap, filter="nearest")
    assert red(tex, u, 0.25) == bottom_row[cols[wrap]]
    assert red(tex, u, 0.75) == top_row[cols[wrap]]


# 4 texels: mirrored repeat reads 0 1 2 3 | 3 2 1 0 | 0 1 ..., and -1 → 0, -3 → 2
NEAREST_4 = [
    (0.125, {"repeat": 0, "clamp": 0, "mirror": 0}),
    (0.625, {"repeat": 2, "clamp": 2, "mirror": 2}),
    (-0.25, {"repeat": 3, "clamp": 0, "mirror": 0}),  # i = -1
    (1.25, {"repeat": 1, "clamp": 3, "mirror": 2}),  # i = 5
    (-0.6, {"repeat": 1, "clamp": 0, "mirror": 2}),  # x = -2.4, i = -3
    (1.0, {"repeat": 0, "clamp": 3, "mirror": 3}),  # i = 4
    (2.1, {"repeat": 0, "clamp": 3, "mirror": 0}),  # x = 8.4, i = 8: a full mirrored period
]


@pytest.mark.parametrize("wrap", WRAPS)
@pytest.mark.parametrize("u, cols", NEAREST_4)
def test_nearest_4x4_wrap_s(u, cols, wrap):
    tex = tex4(wrap=wrap, filter="nearest")
    assert red(tex, u, 0.125) == cols[wrap]  # row j = 0 holds i


@pytest.mark.parametrize("v, rows", [(-0.25, (3, 0, 0)), (1.25, (1, 3, 2))])
def test_nearest_4x4_wrap_t(v, rows):
    for wrap, j in zip(WRAPS, rows):
        assert red(tex4(wrap=wrap, filter="nearest"), 0.125, v) == 10.0 * j


def test_separate_wrap_s_and_t():
    tex = tex4(wrap="repeat", wrap_t="clamp", filter="nearest")
    assert (tex.wrap_s, tex.wrap_t) == ("repeat", "clamp")
    assert red(tex, -0.25, 1.25) == 3 + 10 * 3  # u repeats to column 3, v clamps to row 3


# ---------------------------------------------------------------- bilinear


def test_bilinear_at_texel_centres_is_the_texel():
    tex = tex4(filter="bilinear", wrap="repeat")
    for i in range(4):
        for j in range(4):
            assert red(tex, (i + 0.5) / 4, (j + 0.5) / 4) == i + 10 * j


def test_bilinear_halfway_between_centres_is_the_average():
    tex = tex2(filter="bilinear")
    assert red(tex, 0.5, 0.25) == (30 + 40) / 2
    assert red(tex, 0.25, 0.5) == (30 + 10) / 2
    assert red(tex, 0.5, 0.5) == (10 + 20 + 30 + 40) / 4
    rng = np.random.default_rng(1)
    img = rng.random((1, 2, 4), dtype=np.float32)
    mid = Texture2D(img, filter="bilinear", wrap="clamp").sample(0.5, 0.5)
    assert mid == pytest.approx(tuple((img[0, 0] + img[0, 1]) / 2), rel=1e-7)


def test_bilinear_weights_follow_the_fraction():
    # u = 0.375 on 2 texels: x − ½ = 0.25, so ¾ of texel 0 and ¼ of texel 1
    assert red(tex2(filter="bilinear"), 0.375, 0.25) == 0.75 * 30 + 0.25 * 40
    # v = 0.625: y − ½ = 0.75, so ¼ of the bottom row (30) and ¾ of the top (10)
    assert red(tex2(filter="bilinear"), 0.25, 0.625) == 0.25 * 30 + 0.75 * 10


# u → expected on row j = 0 of the 4×4 (texel i holds i); x − ½ = 4u − ½ gives i0 and the weight
BILINEAR_4 = [
    (0.5, {"repeat": 1.5, "clamp": 1.5, "mirror": 1.5}),  # between texels 1 and 2
    (0.0, {"repeat": 1.5, "clamp": 0.0, "mirror": 0.0}),  # i0 = -1, ½: texels (3, 0) | (0, 0) | (0, 0)
    (1.0, {"repeat": 1.5, "clamp": 3.0, "mirror": 3.0}),  # i0 = 3: texels (3, 0) | (3, 3) | (3, 3)
    (-0.25, {"repeat": 2.5, "clamp": 0.0, "mirror": 0.5}),  # i0 = -2: (2, 3) | (0, 0) | (1, 0)
    (1.25, {"repeat": 0.5, "clamp": 3.0, "mirror": 2.5}),  # i0 = 4: (0, 1) | (3, 3) | (3, 2)
    (0.9375, {"repeat": 2.25, "clamp": 3.0, "mirror": 3.0}),  # i0 = 3, ¼: ¾·3 + ¼·texel 4 (0 | 3 | 3)
]


@pytest.mark.parametrize("wrap", WRAPS)
@pytest.mark.parametrize("u, expected", BILINEAR_4)
def test_bilinear_4x4_wrap(u, expected, wrap):
    assert red(tex4(filter="bilinear", wrap=wrap), u, 0.125) == expected[wrap]


def test_bilinear_4x4_both_axes():
    # (0.5, 0.5) is between columns 1, 2 and rows 1, 2: i-part 1.5, j-part 15
    assert red(tex4(filter="bilinear"), 0.5, 0.5) == 16.5


# ---------------------------------------------------------------- orientation and texel values


def test_v_zero_is_the_bottom_row_of_the_image():
    img = np.zeros((4, 1, 3), dtype=np.uint8)
    img[0] = (255, 0, 0)  # row 0: the top of the image
    img[3] = (0, 0, 255)  # last row: the bottom
    tex = Texture2D(img, filter="nearest")
    assert tex.sample(0.5, 0.1) == (0.0, 0.0, 1.0, 1.0)  # v near 0: bottom, blue
    assert tex.sample(0.5, 0.9) == (1.0, 0.0, 0.0, 1.0)  # v near 1: top, red


def test_v_flip_from_an_image_file(tmp_path):
    img = np.zeros((2, 2, 3), dtype=np.uint8)
    img[0, 0] = (255, 0, 0)  # top-left
    img[1, 1] = (0, 51, 0)  # bottom-right
    path = tmp_path / "corners.png"
    Image.fromarray(img).save(path)
    tex = Texture2D(path, filter="nearest")
    assert tex.sample(0.25, 0.75) == (1.0, 0.0, 0.0, 1.0)  # (u, v) = upper-left
    g = float(np.float32(51) / np.float32(255))
    assert tex.sample(0.75, 0.25) == (0.0, g, 0.0, 1.0)  # lower-right
    assert tex.sample(0.25, 0.25) == (0.0, 0.0, 0.0, 1.0)


G = float(np.float32(51) / np.float32(255))  # 8-bit 51 as a texel
A = float(np.float32(102) / np.float32(255))


def _palette_image():
    img = Image.new("P", (1, 1), 0)
    img.putpalette([255, 51, 0])
    return img


@pytest.mark.parametrize(
    "make, expected",
    [
        (lambda: Image.new("L", (1, 1), 51), (G, G, G, 1.0)),
        (lambda: Image.new("LA", (1, 1), (51, 102)), (G, G, G, A)),
        (lambda: Image.new("RGB", (1, 1), (255, 51, 0)), (1.0, G, 0.0, 1.0)),
        (lambda: Image.new("RGBA", (1, 1), (255, 51, 0, 102)), (1.0, G, 0.0, A)),
        (_palette_image, (1.0, G, 0.0, 1.0)),
    ],
    ids=["L", "LA", "RGB", "RGBA", "P"],
)
def test_image_modes_become_rgba(tmp_path, make, expected):
    path = tmp_path / "px.png"
    make().save(path)
    assert Texture2D(path).sample(0.5, 0.5) == expected


def test_16bit_grayscale_file(tmp_path):
    path = tmp_path / "g16.png"
    Image.fromarray(np.array([[0, 65535]], dtype=np.uint16)).save(path)
    tex = Texture2D(path, filter="nearest")
    assert tex.sample(0.25, 0.5) == (0.0, 0.0, 0.0, 1.0)
    assert tex.sample(0.75, 0.5) == (1.0, 1.0, 1.0, 1.0)


def test_array_kinds_become_rgba():
    assert Texture2D(np.array([[255]], np.uint8)).sample(0.5, 0.5) == (1.0, 1.0, 1.0, 1.0)
    gray = Texture2D(np.array([[0.25]])).sample(0.5, 0.5)
    assert gray == (0.25, 0.25, 0.25, 1.0)
    rgb = Texture2D(np.array([[[0.5, 0.25, 2.0]]], np.float64)).sample(0.5, 0.5)
    assert rgb == (0.5, 0.25, 2.0, 1.0)  # floats kept as they are, even above 1
    rgba = Texture2D(np.array([[[0.0, 0.5, 1.0, 0.125]]], np.float32)).sample(0.5, 0.5)
    assert rgba == (0.0, 0.5, 1.0, 0.125)


# ---------------------------------------------------------------- mipmaps


def test_mip_pyramid_of_4x4():
    img = np.arange(16, dtype=np.float32).reshape(4, 4)
    tex = Texture2D(img)
    assert tex.num_levels == 3
    assert [lv.shape for lv in tex.levels] == [(4, 4, 4), (2, 2, 4), (1, 1, 4)]
    # level 1 texel = mean of its 2×2 block of level 0, e.g. (0 + 1 + 4 + 5)/4
    assert tex.levels[1][..., 0].tolist() == [[2.5, 4.5], [10.5, 12.5]]
    assert tex.levels[2][..., 0].tolist() == [[7.5]]
    assert tex.levels[1][..., 3].tolist() == [[1.0, 1.0], [1.0, 1.0]]


def test_mip_sizes_non_square_and_odd():
    tex = Texture2D(np.zeros((3, 5)))  # H = 3, W = 5
    assert [lv.shape[:2] for lv in tex.levels] == [(3, 5), (1, 2), (1, 1)]
    tex = Texture2D(np.zeros((1, 8)))
    assert [lv.shape[:2] for lv in tex.levels] == [(1, 8), (1, 4), (1, 2), (1, 1)]


def test_mip_odd_width_is_area_weighted_box():
    # 5 → 2: each new texel covers 2.5 old ones; texel 2 is shared half and half
    tex = Texture2D(np.array([[0.0, 1.0, 2.0, 3.0, 4.0]]))
    assert tex.levels[1][0, :, 0] == pytest.approx([(0 + 1 + 0.5 * 2) / 2.5, (0.5 * 2 + 3 + 4) / 2.5])
    assert tex.levels[2][0, 0, 0] == pytest.approx(2.0)  # the mean survives
    tex = Texture2D(np.array([[0.0, 3.0, 6.0]]))  # 3 → 1: plain mean of three
    assert tex.levels[1][0, 0, 0] == pytest.approx(3.0)


def test_uniform_layout():
    img = np.arange(16, dtype=np.float32).reshape(4, 4)
    u = Texture2D(img, wrap="mirror", filter="trilinear").__softpipe_uniform__()
    assert isinstance(u, TextureUniform)
    assert u.texels.dtype == np.float32 and u.texels.shape == (16 + 4 + 1, 4)
    assert u.widths.tolist() == [4, 2, 1] and u.heights.tolist() == [4, 2, 1]
    assert u.offsets.tolist() == [0, 16, 20]
    assert (u.wrap_s, u.wrap_t, u.filter) == (2, 2, 3)
    assert u.texels[16 + 1, 0] == 4.5  # level 1, image row 0, column 1
    assert texture_size(u, 1) == (2, 2)
    with pytest.raises(ValueError):
        u.texels[0, 0] = 1.0  # read-only: every draw shares it


# ---------------------------------------------------------------- level of detail


def test_mip_level_head_on():
    u = Texture2D(np.zeros((256, 256), np.float32)).__softpipe_uniform__()
    # 256 texels across a square 64 pixels wide: 4 texels per pixel, λ = 2
    assert mip_level(u, (1 / 64, 0.0), (0.0, 1 / 64)) == 2.0
    # the larger axis wins: 16 texels per pixel along y
    assert mip_level(u, (1 / 64, 0.0), (0.0, 1 / 16)) == 4.0
    assert mip_level(u, (0.0, 1 / 16), (1 / 64, 0.0)) == 4.0
    # rotated in screen: the length of each derivative counts, not its direction
    c, s = math.cos(0.5), math.sin(0.5)
    assert mip_level(u, (c / 64, s / 64), (-s / 64, c / 64)) == pytest.approx(2.0, abs=1e-12)
    assert mip_level(u, (1 / 512, 0.0), (0.0, 1 / 512)) == -1.0  # magnification
    assert mip_level(u, (0.0, 0.0), (0.0, 0.0)) == -math.inf


def test_mip_level_scales_u_and_v_by_their_own_sizes():
    u = Texture2D(np.zeros((64, 256), np.float32)).__softpipe_uniform__()  # W 256, H 64
    assert mip_level(u, (1 / 64, 0.0), (0.0, 0.0)) == 2.0  # 256/64
    assert mip_level(u, (0.0, 0.0), (0.0, 1 / 64)) == 0.0  # 64/64


def _projected_duv(f, d, s, theta):
    """∂(u,v)/∂(x,y) at the centre of a square (side s, distance d, tilted θ about x), focal f px."""

    def screen(u, v):
        x = s * (u - 0.5)
        y = s * (v - 0.5) * math.cos(theta)
        z = -d + s * (v - 0.5) * math.sin(theta)
        return np.array([f * x / -z, f * y / -z])

    h = 1e-5
    jac = np.column_stack(
        [(screen(0.5 + h, 0.5) - screen(0.5 - h, 0.5)) / (2 * h),
         (screen(0.5, 0.5 + h) - screen(0.5, 0.5 - h)) / (2 * h)]
    )
    inv = np.linalg.inv(jac)  # columns: ∂(u,v)/∂x, ∂(u,v)/∂y
    return tuple(inv[:, 0]), tuple(inv[:, 1])


@pytest.mark.parametrize("theta_deg", [0.0, 60.0, 75.0])
def test_mip_level_of_a_plane_seen_in_perspective(theta_deg):
    theta = math.radians(theta_deg)
    f, d, s, texels = 256.0, 4.0, 1.0, 256
    u = Texture2D(np.zeros((texels, texels), np.float32)).__softpipe_uniform__()
    dx, dy = _projected_duv(f, d, s, theta)
    # head-on the square spans f·s/d = 64 pixels; tilting shrinks its height by cos θ
    rho = max(texels * d / (f * s), texels * d / (f * s * math.cos(theta)))
    assert mip_level(u, dx, dy) == pytest.approx(math.log2(rho), abs=1e-6)
    if theta_deg == 60.0:
        assert math.log2(rho) == pytest.approx(3.0)


def test_trilinear_mixes_levels():
    # uv (⅛, ⅛) is the centre of level 0's bottom-left texel (image row 3, col 0 = 12) and,
    # clamped, reads level 1's bottom-left texel alone (10.5); level 2 is 7.5
    tex = Texture2D(np.arange(16, dtype=np.float32).reshape(4, 4), filter="trilinear", wrap="clamp")
    assert red(tex, 0.125, 0.125, 0.0) == 12.0
    assert red(tex, 0.125, 0.125, 0.5) == 0.5 * 12.0 + 0.5 * 10.5
    assert red(tex, 0.125, 0.125, 0.25) == 0.75 * 12.0 + 0.25 * 10.5
    assert red(tex, 0.125, 0.125, 1.0) == 10.5
    assert red(tex, 0.125, 0.125, 1.5) == 0.5 * 10.5 + 0.5 * 7.5
    assert red(tex, 0.125, 0.125, 9.0) == 7.5  # clamped to the last level
    assert red(tex, 0.125, 0.125, -3.0) == 12.0  # magnification: level 0
    assert red(tex, 0.125, 0.125, math.nan) == 12.0


def test_nearest_mipmap_picks_the_nearest_level():
    tex = Texture2D(np.arange(16, dtype=np.float32).reshape(4, 4), filter="nearest_mipmap")
    # ceil(λ + ½) − 1: halves round down
    for lod, expected in [(0.0, 12.0), (0.5, 12.0), (0.51, 10.5), (1.5, 10.5), (1.6, 7.5), (7.0, 7.5)]:
        assert red(tex, 0.1, 0.1, lod) == expected, lod


@pytest.mark.parametrize("flt", ["nearest", "bilinear"])
def test_non_mipmap_filters_ignore_lod(flt):
    tex = Texture2D(np.arange(16, dtype=np.float32).reshape(4, 4), filter=flt)
    assert tex.sample(0.3, 0.4, 2.0) == tex.sample(0.3, 0.4, 0.0)


def test_texture_grad_and_texture_in_a_shader():
    tex = Texture2D(np.arange(16, dtype=np.float32).reshape(4, 4), filter="trilinear", wrap="clamp")
    Uniforms = namedtuple("Uniforms", ["tex", "gain"])
    uniforms = Uniforms(tex.__softpipe_uniform__(), 2.0)

    @numba.njit
    def shader(uv, duv_dx, duv_dy, un):
        a = texture_grad(un.tex, uv, duv_dx, duv_dy)
        b = texture(un.tex, uv)
        c = texture_lod(un.tex, uv, 2.0)
        return (un.gain * a[0], b[0], c[0])

    uv = (0.125, 0.125)
    # du/dx = ½ on 4 texels: ρ = 2, λ = 1 → level 1 alone; texture() has no derivatives: level 0
    assert shader(uv, (0.5, 0.0), (0.0, 0.25), uniforms) == (2 * 10.5, 12.0, 7.5)
    # λ = log2(4·0.25) = 0 along the larger axis: level 0
    assert shader(uv, (0.25, 0.0), (0.0, 0.125), uniforms)[0] == 2 * 12.0
    assert shader(uv, (0.0, 0.0), (0.0, 0.0), uniforms)[0] == 2 * 12.0  # λ = −∞ → level 0


# ---------------------------------------------------------------- jitted == plain Python


def _reference_samples() -> list:
    """Samples over every filter and wrap on an odd-sized texture, for comparing runs."""
    rng = np.random.default_rng(7)
    img = rng.random((3, 5, 4)).astype(np.float32)
    uvs = [(0.0, 0.0), (0.37, 0.81), (-0.25, 1.25), (1.0, 1.0), (-3.3, 2.7), (0.5, math.nan),
           (1e30, -1e30), (math.inf, 0.2)]
    out = []
    for flt in ("nearest", "bilinear", "nearest_mipmap", "trilinear"):
        for wrap in WRAPS:
            u = Texture2D(img, filter=flt, wrap=wrap).__softpipe_uniform__()
            for uv in uvs:
                out.append(list(texture(u, uv)))
                for lod in (0.3, 1.7, 5.0):
                    out.append(list(texture_lod(u, uv, lod)))
                out.append(list(texture_grad(u, uv, (0.3, 0.1), (0.05, 0.2))))
    out.append([mip_level(u, (0.3, 0.1), (0.05, 0.2)), mip_level(u, (0.0, 0.0), (0.0, 0.0))])
    return out


def test_same_results_with_numba_disabled():
    here = os.path.dirname(os.path.abspath(__file__))
    code = (
        "import json, sys; sys.path.insert(0, %r); import test_texture as t; "
        "print(json.dumps(t._reference_samples()))" % here
    )
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=PATIENCE)
    assert run.returncode == 0, run.stderr
    plain = json.loads(run.stdout)
    jitted = json.loads(json.dumps(_reference_samples()))
    assert len(plain) == len(jitted) > 100
    assert plain == jitted  # bit for bit: the same float64 operations in the same order


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize("shape", [(2, 2, 2), (2, 2, 5), (4,), (2, 2, 3, 1)])
def test_bad_array_shape(shape):
    with pytest.raises(ValueError, match=r"shape \[H, W\], \[H, W, 3\] or \[H, W, 4\], got shape"):
        Texture2D(np.zeros(shape, np.float32))


def test_empty_array():
    with pytest.raises(ValueError, match="at least 1×1"):
        Texture2D(np.zeros((0, 3), np.float32))


@pytest.mark.parametrize("dtype", [np.int32, np.uint16, bool])
def test_bad_array_dtype(dtype):
    with pytest.raises(TypeError, match=f"uint8 .* or floating point, got {np.dtype(dtype)}"):
        Texture2D(np.zeros((2, 2), dtype))


def test_non_finite_texels():
    img = np.zeros((3, 2, 3))
    img[1, 0, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite texels .* row 1, column 0"):
        Texture2D(img)
    with pytest.raises(ValueError, match="non-finite"):
        Texture2D(np.full((1, 1), 1e300))  # overflows float32


def test_unknown_wrap_and_filter():
    with pytest.raises(ValueError, match=r"wrap must be one of 'repeat', 'clamp', 'mirror'; got 'wrap'"):
        tex2(wrap="wrap")
    with pytest.raises(ValueError, match=r"wrap_t must be one of .*; got 'border'"):
        tex2(wrap_t="border")
    with pytest.raises(ValueError, match=r"filter must be one of 'nearest', 'bilinear', .*; got 'linear'"):
        tex2(filter="linear")


def test_bad_source(tmp_path):
    missing = tmp_path / "nope.png"
    with pytest.raises(FileNotFoundError, match="nope.png"):
        Texture2D(missing)
    junk = tmp_path / "junk.png"
    junk.write_text("not an image")
    with pytest.raises(ValueError, match="cannot read image file .*junk.png"):
        Texture2D(junk)
    floats = tmp_path / "f.tif"
    Image.fromarray(np.zeros((2, 2), np.float32)).save(floats)
    with pytest.raises(ValueError, match="f.tif.*32-bit pixel mode 'F'"):
        Texture2D(floats)
    with pytest.raises(TypeError, match="image file path or a numpy array, got list"):
        Texture2D([[0.0]])


def test_render_to_texture_the_framebuffers_bottom_row_is_v_0():
    """Texture2D.from_framebuffer: what a draw made, sampled as a texture (OpenGL's render to texture):
    texel (i, j) of window row j (y up) is the framebuffer's pixel there, v = 0 its bottom row."""
    from softpipe import Framebuffer
    fb = Framebuffer(4, 3)
    rng = np.random.default_rng(7)
    fb.color[...] = rng.random((3, 4, 4)).astype(np.float32)
    tex = Texture2D.from_framebuffer(fb, filter="nearest", wrap="clamp")
    assert (tex.width, tex.height) == (4, 3)
    for j in range(3):              # window row, y up
        for i in range(4):
            got = tex.sample((i + 0.5) / 4, (j + 0.5) / 3)
            np.testing.assert_array_equal(got, fb.color[2 - j, i])
