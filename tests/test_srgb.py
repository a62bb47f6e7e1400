"""sRGB (FORMULAS §28): the transfer functions, the sRGB framebuffer, sRGB textures, scene keys and --srgb.

The expected values are computed here from the standard's piecewise formula
(IEC 61966-2-1) with Python's own floats, independently of softpipe's numpy code.
"""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.core.colors import srgb_decode, srgb_encode
from softpipe.light.texture import Texture2D
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.sampling import pattern_named

BYTES = range(256)


def encode(c: float) -> float:
    """FORMULAS §28, linear → encoded, for c in [0, 1]."""
    return 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055


def decode(c: float) -> float:
    """FORMULAS §28, encoded → linear, for c in [0, 1]."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def to_byte(c: float) -> int:
    """round(c·255), half to even (as numpy's rint, which to_uint8 uses)."""
    return int(round(c * 255.0))


# ---------------------------------------------------------------------------- the transfer functions


def test_encode_and_decode_match_the_piecewise_formula_at_every_8_bit_value():
    values = np.arange(256) / 255.0
    enc, dec = srgb_encode(values), srgb_decode(values)
    assert enc.dtype == np.float64 and dec.dtype == np.float64 and enc.shape == dec.shape == (256,)
    for i in BYTES:
        assert enc[i] == pytest.approx(encode(i / 255), rel=1e-14, abs=1e-16), i
        assert dec[i] == pytest.approx(decode(i / 255), rel=1e-14, abs=1e-16), i
        assert to_byte(enc[i]) == to_byte(encode(i / 255)), i


def test_both_branches_and_the_knees():
    assert srgb_encode(0.0031308) == pytest.approx(12.92 * 0.0031308, rel=1e-15)      # the linear segment
    assert srgb_encode(0.0031309) == pytest.approx(1.055 * 0.0031309 ** (1 / 2.4) - 0.055, rel=1e-15)
    assert srgb_decode(0.04045) == pytest.approx(0.04045 / 12.92, rel=1e-15)
    assert srgb_decode(0.04046) == pytest.approx(((0.04046 + 0.055) / 1.055) ** 2.4, rel=1e-15)
    assert srgb_encode(0.0) == 0.0 and srgb_encode(1.0) == pytest.approx(1.0, abs=1e-15)
    assert srgb_decode(0.0) == 0.0 and srgb_decode(1.0) == pytest.approx(1.0, abs=1e-15)
    assert to_byte(float(srgb_encode(0.5))) == 188                  # docs/gamma.md's worked example


def test_decode_then_encode_gives_every_byte_back():
    b = np.arange(256)
    back = np.rint(srgb_encode(srgb_decode(b / 255.0)) * 255.0).astype(int)
    assert back.tolist() == b.tolist()


def test_vectorized_any_shape_out_of_range_clamped_nan_kept():
    image = np.full((2, 3, 3), 0.5, np.float32)
    assert srgb_encode(image).shape == (2, 3, 3) and srgb_encode(image).dtype == np.float64
    with np.errstate(all="raise"):              # no warning from the branch np.where does not take
        out = srgb_encode(np.array([-1.0, 2.0, np.nan, 0.0]))
        dec = srgb_decode(np.array([-1.0, 2.0, np.nan]))
    assert out[0] == 0.0 and out[1] == pytest.approx(1.0) and math.isnan(out[2]) and out[3] == 0.0
    assert dec[0] == 0.0 and dec[1] == pytest.approx(1.0) and math.isnan(dec[2])


# ---------------------------------------------------------------------------- the sRGB framebuffer


def test_srgb_framebuffer_bytes_at_known_linear_values():
    values = [0.0, 1.0, 0.0031308, 0.5, 0.2, 0.04, -0.5, 2.0, np.nan, np.inf, -np.inf]
    expected = [0, 255, 10, 188, 124, to_byte(encode(0.04)), 0, 255, 0, 255, 0]
    fb = Framebuffer(len(values), 1, srgb=True)
    fb.color[0, :, 0] = values
    fb.color[0, :, 1] = 0.25
    fb.color[0, :, 2] = values
    fb.color[0, :, 3] = 0.5
    out = fb.to_uint8()
    assert out[0, :, 0].tolist() == expected
    assert out[0, :, 2].tolist() == expected
    assert out[0, :, 1].tolist() == [to_byte(encode(0.25))] * len(values) == [137] * len(values)
    assert out[0, :, 3].tolist() == [128] * len(values)               # alpha is not encoded
    assert np.asarray(fb).tolist() == out[..., :3].tolist()           # what save() and np.asarray write
    assert to_byte(encode(0.0031308)) == 10


def test_srgb_framebuffer_encodes_every_8_bit_level():
    fb = Framebuffer(256, 1, srgb=True)
    fb.color[0, :, :3] = (np.arange(256, dtype=np.float32) / np.float32(255.0))[:, None]
    got = fb.to_uint8(alpha=False)[0, :, 0].tolist()
    assert got == [to_byte(encode(float(np.float32(i) / np.float32(255.0)))) for i in BYTES]


def test_samples_are_averaged_in_linear_light_then_encoded():
    fb = Framebuffer(1, 1, pattern_named("grid4"), srgb=True)
    fb.samples_color[:2] = (0.0, 0.0, 0.0, 1.0)
    fb.samples_color[2:] = (1.0, 1.0, 1.0, 1.0)
    assert fb.to_uint8()[0, 0].tolist() == [188, 188, 188, 255]      # not the mean of 0 and 255


def test_default_framebuffer_is_unchanged():
    fb = Framebuffer(3, 1)
    assert fb.srgb is False and repr(fb) == "Framebuffer(3×1, 1 sample)"
    fb.color[0, :, :3] = np.array([0.5, 0.2, 0.0031308])[:, None]
    assert fb.to_uint8(alpha=False)[0, :, 0].tolist() == [128, 51, 1]


def test_srgb_is_read_only_shown_and_pickled():
    fb = Framebuffer(2, 2, pattern_named("grid4"), srgb=True)
    assert fb.srgb is True and repr(fb) == "Framebuffer(2×2, 4 samples, sRGB)"
    with pytest.raises(AttributeError, match="Framebuffer.srgb is read-only"):
        fb.srgb = False
    fb.clear((0.5, 0.5, 0.5))
    back = pickle.loads(pickle.dumps(fb))
    assert back.srgb is True and back.to_uint8().tolist() == fb.to_uint8().tolist()
    assert pickle.loads(pickle.dumps(Framebuffer(1, 1))).srgb is False
    # a framebuffer pickled before it had srgb loads as a linear one
    state = fb.__getstate__()
    del state["_srgb"]
    old = Framebuffer.__new__(Framebuffer)
    old.__setstate__(state)
    assert old.srgb is False and old.to_uint8()[0, 0, 0] == 128


@pytest.mark.parametrize("bad", [1, 0, "yes", None, 1.0])
def test_srgb_must_be_a_bool(bad):
    with pytest.raises(TypeError) as e:
        Framebuffer(2, 2, srgb=bad)
    assert str(e.value) == f"Framebuffer srgb must be True or False, got {type(bad).__name__} {bad!r}"
    with pytest.raises(TypeError) as e:
        Texture2D(np.zeros((2, 2), np.uint8), srgb=bad)
    assert str(e.value) == f"Texture2D: srgb must be True or False, got {type(bad).__name__} {bad!r}"
    with pytest.raises(TypeError, match=r"^srgb must be True or False, got "):
        sp.render("tetra-not-read.obj", srgb=bad)


def test_numpy_bools_are_bools():
    assert Framebuffer(1, 1, srgb=np.bool_(True)).srgb is True


# ---------------------------------------------------------------------------- sRGB textures


def test_uint8_array_texture_decoded_once_at_load():
    texels = np.array([[[0, 50, 128, 77], [188, 200, 255, 255]]], dtype=np.uint8)
    tex = Texture2D(texels, filter="nearest", srgb=True)
    level0 = tex.levels[0]
    assert level0.dtype == np.float32
    for k in range(2):
        for c in range(3):
            assert level0[0, k, c] == np.float32(decode(texels[0, k, c] / 255)), (k, c)
        assert level0[0, k, 3] == np.float32(texels[0, k, 3] / 255)     # alpha is not decoded
    assert level0[0, 1, 0] == np.float32(0.5028864580325687)            # byte 188 is half the light
    assert tex.sample(0.25, 0.5) == tuple(float(v) for v in level0[0, 0])
    assert tex.srgb and repr(tex).endswith("filter=nearest, srgb)")
    # the mipmaps average the decoded (linear) values
    assert tex.levels[1][0, 0, 0] == np.float32((float(level0[0, 0, 0]) + float(level0[0, 1, 0])) / 2)


def test_image_file_texture_decoded(tmp_path):
    rgb = np.array([[[10, 100, 250], [0, 255, 30]]], dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "t.png")
    level0 = Texture2D(tmp_path / "t.png", srgb=True).levels[0]
    expected = np.array([[[decode(v / 255) for v in px] + [1.0] for px in rgb[0]]], dtype=np.float32)
    assert level0.tolist() == expected.tolist()
    assert level0[0, 0, 0] == np.float32(10 / 255 / 12.92)           # below the knee: the straight line
    Image.fromarray(np.array([[0, 30000, 65535]], dtype=np.uint16)).save(tmp_path / "g16.png")
    gray = Texture2D(tmp_path / "g16.png", srgb=True).levels[0]
    assert gray[0, :, 0].tolist() == [np.float32(decode(v / 65535)) for v in (0, 30000, 65535)]
    assert gray[0, 1, 3] == 1.0


def test_default_texture_is_unchanged(tmp_path):
    rgb = np.array([[[10, 100, 250], [0, 255, 30]]], dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "t.png")
    for tex in (Texture2D(tmp_path / "t.png"), Texture2D(rgb)):
        assert tex.srgb is False and "srgb" not in repr(tex)
        assert tex.levels[0][..., :3].tolist() == (rgb.astype(np.float32) / np.float32(255.0)).tolist()


def test_srgb_refuses_a_float_array():
    with pytest.raises(ValueError) as e:
        Texture2D(np.zeros((2, 2, 3), np.float32), srgb=True)
    assert str(e.value) == ("Texture2D: srgb=True decodes 8-bit (uint8) texels, and this array is float32; a "
                            "float array is taken as linear already (decode it yourself with "
                            "softpipe.core.colors.srgb_decode, or give srgb=False)")


# ---------------------------------------------------------------------------- scenes and the command line

OBJ = """mtllib m.mtl
v -1 -1 0
v 1 -1 0
v 0 1 0
vt 0 0
vt 1 0
vt 0 1
usemtl tex
f 1/1 2/2 3/3
"""


def _textured_obj(folder):
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(folder / "t.png")
    (folder / "m.mtl").write_text("newmtl tex\nmap_Kd t.png\n")
    (folder / "tri.obj").write_text(OBJ)
    return folder / "tri.obj"


def test_scene_file_keys(tmp_path):
    from softpipe.scenes.drawing import render_scene
    from softpipe.scenes.scenefile import SceneError, parse_scene
    obj = _textured_obj(tmp_path)
    base = '[render]\nwidth = 4\nheight = 4\nbackground = [0.5, 0.5, 0.5]\n{}\n[[meshes]]\nobj = "tri.obj"\n'
    plain = parse_scene(base.format(""), "s.toml", tmp_path)
    assert plain.srgb is False and plain.objects[0].texture.srgb is False
    assert render_scene(plain).to_uint8()[0, 0].tolist() == [128, 128, 128, 255]
    scene = parse_scene(base.format("srgb = true\nsrgb_textures = true"), "s.toml", tmp_path)
    assert scene.srgb is True and scene.objects[0].texture.srgb is True
    assert scene.objects[0].texture.levels[0][0, 0, 0] == np.float32(decode(128 / 255))
    fb = render_scene(scene)
    assert fb.srgb is True and fb.to_uint8()[0, 0].tolist() == [188, 188, 188, 255]
    with pytest.raises(SceneError) as e:
        parse_scene(base.format('srgb = "yes"'), "s.toml", tmp_path)
    assert "key 'srgb' in [render] must be true or false" in str(e.value)
    assert obj.exists()


def test_model_textures_read_as_srgb_with_srgb(tmp_path):
    from softpipe.scenes.drawing import prepare_scene
    obj = _textured_obj(tmp_path)
    assert prepare_scene(obj).objects[0].texture.srgb is False
    scene = prepare_scene(obj, srgb=True)
    assert scene.srgb is True and scene.objects[0].texture.srgb is True


def test_cli_srgb_writes_an_encoded_png(capsys, tmp_path):
    obj = _textured_obj(tmp_path)
    for flag, name in (([], "plain.png"), (["--srgb"], "srgb.png")):
        code, out, err = run_cli(capsys, "render", obj, "--size", "8x8", "--background", "0.5,0.2,0.0031308",
                                 "-o", tmp_path / name, *flag)
        assert code == 0, err
    plain = np.asarray(Image.open(tmp_path / "plain.png"))
    srgb = np.asarray(Image.open(tmp_path / "srgb.png"))
    assert plain[0, 0].tolist() == [128, 51, 1]
    assert srgb[0, 0].tolist() == [188, 124, 10]                    # the background, encoded
    # every pixel is the linear render's colors encoded (the texture decoded first)
    linear = sp.render(str(obj), width=8, height=8, background=(0.5, 0.2, 0.0031308), srgb=True)
    expected = [[[to_byte(encode(min(max(float(c), 0.0), 1.0))) for c in px[:3]] for px in row]
                for row in linear.color]
    assert srgb.tolist() == expected
    assert (srgb != plain).any(axis=2).all()


def test_ray_tracer_renders_into_the_scenes_srgb_framebuffer(tmp_path):
    from softpipe.scenes.drawing import prepare_scene, render_scene
    from softpipe.tracers.whitted import raytrace_scene
    obj = _textured_obj(tmp_path)
    scene = prepare_scene(obj, width=6, height=6, background=(0.5, 0.5, 0.5), srgb=True)
    traced, drawn = raytrace_scene(scene), render_scene(scene)
    assert traced.srgb is True and drawn.srgb is True
    assert traced.to_uint8()[0, 0].tolist() == drawn.to_uint8()[0, 0].tolist() == [188, 188, 188, 255]


def test_transparency_methods_keep_the_scenes_srgb(tmp_path):
    """The opaque pass (depth peeling and weighted OIT composite into it) and the exact composite
    are sRGB framebuffers when the scene's or the background's is."""
    from softpipe.scenes.drawing import prepare_scene
    from softpipe.scenes.transparency import opaque_pass
    from softpipe.testing.composite import sorted_composite
    scene = prepare_scene(_textured_obj(tmp_path), width=4, height=4, background=(0.5, 0.5, 0.5), srgb=True)
    base = opaque_pass(scene).framebuffer
    assert base.srgb is True and base.to_uint8()[0, 0].tolist() == [188, 188, 188, 255]
    exact = sorted_composite([], base)
    assert exact.srgb is True and exact.to_uint8().tolist() == base.to_uint8().tolist()
    assert sorted_composite([], Framebuffer(2, 2)).srgb is False
