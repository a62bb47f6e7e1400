"""Multiple render targets (issue 31): a framebuffer of named color attachments, a fragment shader that
returns one value per attachment, and each attachment blended, masked, cleared and resolved by its own state.

Every expected value is computed here from the scene's geometry (which triangle covers a pixel centre,
the fragment's window position and depth), not read back from softpipe. Scenes are quads with integer
window corners, so no pixel centre lies on an edge.
"""
import numba
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
from softpipe.language.contract import ShaderError
from softpipe.language.kernels import kernel_source
from softpipe.pipeline.sampling import grid

W, H = 16, 12
GBUFFER = {"color": "rgba8", "pos": "rgba32f", "normal": "rgba32f", "id": "r32i", "depth": "r32f"}
N0, N1 = (0.0, 0.0, 1.0), (0.6, 0.0, 0.8)


def two_triangles():
    """Two triangles splitting window [2, 14] × [2, 10] along its diagonal: 0 below it at window depth 0.5,
    1 above it at 0.75; varyings: a normal per triangle and a color."""
    corners = [(2, 2, 0.0), (14, 2, 0.0), (14, 10, 0.0), (2, 2, 0.5), (14, 10, 0.5), (2, 10, 0.5)]
    pos = window_to_clip(corners, W, H)
    normal = np.array([N0] * 3 + [N1] * 3)
    color = np.array([(1.0, 0.5, 0.25)] * 3 + [(0.25, 0.5, 1.0)] * 3)
    return pos, {"normal": normal, "color": color}


def gbuffer_shader(v, u, frag):
    n = v.normal
    return ((v.color[0], v.color[1], v.color[2], 1.0), (frag.x, frag.y, frag.z, 1.0), (n[0], n[1], n[2], 0.0),
            frag.primitive_id + 10, frag.z)


def expected_coverage():
    """Per pixel (image rows): -1 where no triangle covers the centre, else the triangle (0 below the diagonal)."""
    cols, rows = np.meshgrid(np.arange(W), np.arange(H))
    cx, cy = cols + 0.5, (H - 1 - rows) + 0.5
    inside = (cx > 2) & (cx < 14) & (cy > 2) & (cy < 10)
    below = (cy - 2) * 12 < (cx - 2) * 8
    return np.where(inside, np.where(below, 0, 1), -1), cx, cy


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_each_attachment_holds_what_the_shader_wrote_and_the_background_its_clear_value(path):
    fb = sp.Framebuffer(W, H, attachments=GBUFFER)
    fb.clear((0.0, 0.0, 0.0, 1.0), attachments={"pos": (-1.0, -1.0, -1.0, -1.0), "id": -1, "depth": 2.0})
    pos, varyings = two_triangles()
    sp.draw(fb, pos, varyings=varyings, fragment_shader=gbuffer_shader, path=path)
    tri, cx, cy = expected_coverage()
    covered = tri >= 0
    assert covered.sum() > 50 and (tri == 0).sum() > 20 and (tri == 1).sum() > 20
    p, n, ids, depth = fb.attachment("pos"), fb.attachment("normal"), fb.attachment("id"), fb.attachment("depth")
    assert p.dtype == np.float32 and p.shape == (H, W, 4) and ids.dtype == np.int32 and ids.shape == (H, W)
    want_z = np.where(tri == 0, 0.5, 0.75).astype(np.float32)
    np.testing.assert_array_equal(p[covered], np.stack([cx, cy, want_z, np.ones((H, W))], -1)[covered].astype(np.float32))
    np.testing.assert_array_equal(n[covered][:, :3], np.where((tri == 0)[..., None], N0, N1)[covered].astype(np.float32))
    np.testing.assert_array_equal(ids[covered], (tri + 10)[covered])
    np.testing.assert_array_equal(depth[covered], want_z[covered])
    color = np.where((tri == 0)[..., None], (1.0, 0.5, 0.25, 1.0), (0.25, 0.5, 1.0, 1.0)).astype(np.float32)
    np.testing.assert_array_equal(fb.color[covered], color[covered])
    # the background: each attachment's clear value (the unnamed normal: 0)
    assert (p[~covered] == -1).all() and (ids[~covered] == -1).all() and (depth[~covered] == 2.0).all()
    assert (n[~covered] == 0).all() and (fb.color[~covered] == (0, 0, 0, 1)).all()


def test_the_default_framebuffer_is_one_rgba8_attachment_and_its_loop_is_unchanged():
    fb = sp.Framebuffer(4, 4)
    assert fb.attachments == {"color": "rgba8"} and repr(fb) == "Framebuffer(4×4, 1 sample)"
    assert fb.samples_attachment("color").base is fb.samples_color.base
    pos, varyings = two_triangles()
    from softpipe.pipeline.vertex import run_vertex_stage
    layout = run_vertex_stage(pos, varyings, None, sp.language.contract.make_uniforms(None)).layout
    source = kernel_source("fragment", gbuffer_shader, layout)
    assert "fragment_loop_outputs" not in source and "outputs" not in source.split("\n@")[0]


def shade_both(shader, attachments, pattern=sp.CENTER, shading="sample", threads=None, tilted=False, **state):
    """The framebuffer after a busy scene (overlapping triangles at random depths, each at one depth or,
    ``tilted``, each corner at its own) on each path."""
    rng = np.random.default_rng(3)
    n = 40
    corners = rng.uniform(-1.2, 1.2, (n * 3, 2))
    z = rng.uniform(-0.9, 0.9, n * 3) if tilted else np.repeat(rng.uniform(-0.9, 0.9, n), 3)
    pos = np.column_stack([corners, z, np.ones(n * 3)])
    varyings = {"normal": rng.uniform(-1, 1, (n * 3, 3)), "color": rng.uniform(0, 1, (n * 3, 3))}
    out = {}
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(64, 48, pattern, attachments=attachments).clear(attachments={"id": -1})
        sp.draw(fb, pos, varyings=varyings, fragment_shader=shader, path=path, sample_shading=shading, **state)
        out[path] = {name: fb.samples_attachment(name).copy() for name in attachments}
    return out


@pytest.mark.parametrize("pattern, shading", [(sp.CENTER, "sample"), (grid(2), "sample"), (grid(2), "center"),
                                              (grid(2), "centroid")])
def test_both_paths_write_the_same_bytes_into_every_attachment(pattern, shading):
    out = shade_both(gbuffer_shader, GBUFFER, pattern, shading)
    for name in GBUFFER:
        assert out["reference"][name].tobytes() == out["fast"][name].tobytes(), name
    assert len(np.unique(out["fast"]["id"])) > 20


@pytest.mark.parametrize("shading", ["center", "centroid"])
def test_shaded_once_a_pixel_the_shader_gets_the_depth_of_the_first_sample_the_triangle_covers(shading):
    """Multisampling shaded at the centre or centroid: the reference path shades a pixel's run of a
    triangle's samples once, with the depth of the first sample it covers, whether or not that sample
    then passes the depth test. Tilted triangles give each sample its own depth, and where an earlier
    triangle hides that first sample the fast path must still give the shader its depth (it gave the
    first visible sample's: 485 samples of ``pos`` and ``depth`` differed)."""
    out = shade_both(gbuffer_shader, GBUFFER, grid(2), shading, tilted=True)
    for name in GBUFFER:
        assert out["reference"][name].tobytes() == out["fast"][name].tobytes(), name


def test_one_and_two_threads_write_the_same_bytes():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = shade_both(gbuffer_shader, GBUFFER)
        numba.set_num_threads(2)
        two = shade_both(gbuffer_shader, GBUFFER)
    finally:
        numba.set_num_threads(before)
    for path in one:
        for name in GBUFFER:
            assert one[path][name].tobytes() == two[path][name].tobytes(), (path, name)


# ------------------------------------------------------------------ per-attachment state

ACCUM = {"color": "rgba8", "accum": "rgba32f", "id": "r32i", "weight": "r32f"}


def accum_shader(v, u, frag):
    c = u.value
    return ((c[0], c[1], c[2], c[3]), (c[0], c[1], c[2], c[3]), int(u.id), c[0])


def two_draws(**state):
    fb = sp.Framebuffer(8, 8, attachments=ACCUM).clear((0.125, 0.125, 0.125, 0.5),
                                                       attachments={"accum": (0.125, 0.125, 0.125, 0.5), "id": 7,
                                                                    "weight": 0.125})
    pos = window_to_clip([(0, 0, 0), (8, 0, 0), (8, 8, 0), (0, 0, 0), (8, 8, 0), (0, 8, 0)], 8, 8)
    for value, ident in (((0.25, 0.5, 0.75, 0.5), 3), ((0.5, 0.25, 0.125, 0.25), 5)):
        sp.draw(fb, pos, fragment_shader=accum_shader, uniforms={"value": value, "id": ident}, depth_test=None,
                **state)
    return fb


def test_blending_per_attachment_blends_one_and_replaces_in_the_others():
    fb = two_draws(blend={"accum": "additive", "weight": "additive"})
    assert (fb.color == np.float32((0.5, 0.25, 0.125, 0.25))).all()              # not blended: the last draw
    assert (fb.attachment("accum") == np.float32((0.875, 0.875, 1.0, 1.25))).all()   # 1/8 + both draws
    assert (fb.attachment("weight") == np.float32(0.875)).all()
    assert (fb.attachment("id") == 5).all()


def test_one_blend_state_blends_every_float_attachment_and_no_integer_one():
    fb = two_draws(blend=("src_alpha", "one_minus_src_alpha"))
    # over, twice: c = s·a + d·(1 − a) per channel (alpha too, with its own alpha as factor)
    def over(d, s):
        return tuple(sc * s[3] + dc * (1 - s[3]) for sc, dc in zip(s, d))
    first = over((0.125, 0.125, 0.125, 0.5), (0.25, 0.5, 0.75, 0.5))
    want = np.float32(over(first, (0.5, 0.25, 0.125, 0.25)))
    np.testing.assert_allclose(fb.color, np.broadcast_to(want, (8, 8, 4)), rtol=0, atol=1e-7)
    assert fb.attachment("accum").tobytes() == fb.color.tobytes()
    # a one-channel float blends as (r, 0, 0, 1): alpha 1 on both sides, so "over" keeps the source
    assert (fb.attachment("weight") == np.float32(0.5)).all()
    assert (fb.attachment("id") == 5).all()


def test_color_mask_per_attachment():
    fb = two_draws(color_mask={"accum": (True, False, True, False), "id": (False, True, True, True)})
    assert (fb.color == np.float32((0.5, 0.25, 0.125, 0.25))).all()
    assert (fb.attachment("accum") == np.float32((0.5, 0.125, 0.125, 0.5))).all()
    assert (fb.attachment("id") == 7).all()                  # R masked: the clear value stays
    assert (fb.attachment("weight") == np.float32(0.5)).all()


def test_blending_or_masking_another_attachment_keeps_to_the_reference_path():
    call = sp.DrawCall(sp.Framebuffer(8, 8, attachments=ACCUM), np.zeros((3, 4)), fragment_shader=accum_shader,
                       blend={"accum": "additive"})
    assert call.choose_path() == ("reference", "attachment 'accum' is blended (the fast path writes whole values, "
                                               "unblended)")
    with pytest.raises(ValueError) as e:
        sp.draw(sp.Framebuffer(8, 8, attachments=ACCUM), np.zeros((3, 4)), fragment_shader=accum_shader,
                color_mask={"weight": (False, True, True, True)}, path="fast")
    assert str(e.value) == ("path='fast' is not possible for this draw: attachment 'weight' has the color mask "
                            "(False, True, True, True) (the fast path writes whole values, unblended)")


def coordinate_shader(v, u, frag):
    return ((1.0, 1.0, 1.0, 1.0), frag.x, int(frag.x * 1000.0), (frag.x, frag.y, 0.0, 1.0))


def test_multisample_resolve_averages_float_attachments_and_takes_sample_0_of_integer_ones():
    pattern = grid(2)
    fb = sp.Framebuffer(W, H, pattern, attachments={"color": "rgba8", "x": "r32f", "ix": "r32i", "xy": "rgba32f"})
    fb.clear(attachments={"ix": -5, "x": 0.0})
    pos = window_to_clip([(1, 1, 0), (15, 2, 0), (3, 11, 0)], W, H)          # slanted edges: partly covered pixels
    sp.draw(fb, pos, fragment_shader=coordinate_shader)
    cols = np.arange(W)[None, :]
    sx = cols + pattern.positions[:, 0][:, None, None]                         # each sample's window x
    covered = fb.samples_attachment("ix") != -5
    assert covered.any(axis=0).sum() > covered.all(axis=0).sum() > 20          # some pixels partly covered
    want_x = np.where(covered, sx, 0.0).astype(np.float32)
    np.testing.assert_array_equal(fb.samples_attachment("x"), want_x)
    np.testing.assert_array_equal(fb.attachment("x"), want_x.astype(np.float64).mean(axis=0).astype(np.float32))
    np.testing.assert_array_equal(fb.attachment("xy"), fb.samples_attachment("xy").astype(np.float64).mean(axis=0)
                                  .astype(np.float32))
    want_ix = np.where(covered, np.floor(sx * 1000.0), -5).astype(np.int32)
    np.testing.assert_array_equal(fb.samples_attachment("ix"), want_ix)
    np.testing.assert_array_equal(fb.attachment("ix"), want_ix[0])             # sample 0, not an average
    assert fb.attachment("ix").dtype == np.int32


# ------------------------------------------------------------------ mistakes, and what they say

def two_values(v, u, frag):
    return ((1.0, 0.0, 0.0, 1.0), (frag.x, frag.y, frag.z, 1.0))


def three_floats_for_rgba(v, u, frag):
    return ((1.0, 0.0, 0.0, 1.0), (frag.x, frag.y, frag.z), 3, 0.5)


def float_for_int(v, u, frag):
    return ((1.0, 0.0, 0.0, 1.0), (frag.x, frag.y, frag.z, 1.0), frag.z, 0.5)


def one_color(v, u, frag):
    return (1.0, 0.0, 0.0, 1.0)


MISTAKES = {
    two_values: "draws into a framebuffer of 4 attachments ('color': rgba8, 'pos': rgba32f, 'id': r32i, 'z': r32f): "
                "it must return a tuple of 4 values, one per attachment in that order (DISCARD as the first "
                "discards), got a tuple of 2 values",
    three_floats_for_rgba: "returns for attachment 'pos' (location 1, rgba32f) a tuple of 3 floats; it takes a tuple "
                           "of 4 numbers (r, g, b, a)",
    float_for_int: "returns for attachment 'id' (location 2, r32i) a float; it takes an int (int(...) converts: GL "
                   "does not convert a float written to an integer target)",
    one_color: "draws into a framebuffer of 4 attachments ('color': rgba8, 'pos': rgba32f, 'id': r32i, 'z': r32f): "
               "it must return a tuple of 4 values, one per attachment in that order (DISCARD as the first "
               "discards), got a tuple of 4 floats",
}


@pytest.mark.parametrize("path", ["reference", "fast"])
@pytest.mark.parametrize("shader", list(MISTAKES), ids=lambda f: f.__name__)
def test_values_that_do_not_fit_the_attachments_are_a_shader_error_naming_the_attachment(shader, path):
    fb = sp.Framebuffer(8, 8, attachments={"color": "rgba8", "pos": "rgba32f", "id": "r32i", "z": "r32f"})
    before = {n: fb.samples_attachment(n).copy() for n in fb.attachments}
    depth = fb.samples_depth.copy()
    with pytest.raises(ShaderError) as e:
        sp.draw(fb, window_to_clip([(0, 0, 0), (8, 0, 0), (0, 8, 0)], 8, 8), fragment_shader=shader, path=path)
    first = str(e.value).splitlines()[0]
    assert first == f"fragment shader {__name__}.{shader.__name__} {MISTAKES[shader]}"
    assert e.value.line == shader.__code__.co_firstlineno + 1
    for n in fb.attachments:                                   # nothing written
        assert fb.samples_attachment(n).tobytes() == before[n].tobytes()
    assert fb.samples_depth.tobytes() == depth.tobytes()


def test_discard_as_the_first_value_discards_in_every_attachment():
    def shader(v, u, frag):
        if frag.x < 4.0:
            return (sp.DISCARD, (1.0, 1.0, 1.0, 1.0), 1, 1.0)
        return ((1.0, 1.0, 1.0, 1.0), (2.0, 2.0, 2.0, 2.0), 2, 2.0)
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(8, 8, attachments={"color": "rgba8", "pos": "rgba32f", "id": "r32i", "z": "r32f"})
        sp.draw(fb, window_to_clip([(0, 0, 0), (8, 0, 0), (8, 8, 0), (0, 0, 0), (8, 8, 0), (0, 8, 0)], 8, 8),
                fragment_shader=shader, path=path if path == "reference" else "auto")
        ids = fb.attachment("id")
        assert (ids[:, :4] == 0).all() and (ids[:, 4:] == 2).all(), path
        assert (fb.attachment("pos")[:, :4] == 0).all() and (fb.attachment("z")[:, 4:] == 2).all()


@pytest.mark.parametrize("attachments, error, message", [
    ({"id": "r32i", "color": "rgba8"}, ValueError,
     "Framebuffer attachment 'id' (r32i) is location 0, the framebuffer's color (the picture it shows and saves): "
     "it must be 'rgba8' or 'rgba32f'; put a color attachment first"),
    ({"color": "rgba8", "n": "rgb32f"}, ValueError,
     "Framebuffer attachment 'n': format must be one of ('rgba8', 'rgba32f', 'r32f', 'r32i'), got 'rgb32f'"),
    ({"color": "rgba8", "my id": "r32i"}, ValueError,
     "Framebuffer attachment name 'my id' must be a Python identifier, such as 'normal'"),
    ({}, ValueError, "Framebuffer attachments is empty: give at least one, e.g. {'color': 'rgba8'}"),
    (["color"], TypeError, "Framebuffer attachments must be a dict of name → format, e.g. {'color': 'rgba8', "
                           "'normal': 'rgba32f'}, got list"),
])
def test_framebuffer_attachments_that_are_wrong_say_so(attachments, error, message):
    with pytest.raises(error) as e:
        sp.Framebuffer(4, 4, attachments=attachments)
    assert str(e.value) == message


def test_reading_clearing_and_drawing_attachments_wrongly_says_so():
    fb = sp.Framebuffer(4, 4, attachments={"color": "rgba8", "n": "rgba32f", "id": "r32i", "z": "r32f"})
    with pytest.raises(KeyError) as e:
        fb.attachment("normal")
    assert e.value.args[0] == "this framebuffer has no attachment 'normal'; its attachments are ['color', 'n', 'id', 'z']"
    cases = [({"id": 1.5}, "clear value of attachment 'id' (r32i) must be an int32, got 1.5"),
             ({"id": 2**31}, "clear value of attachment 'id' (r32i) must be an int32, got 2147483648"),
             ({"z": float("nan")}, "clear value of attachment 'z' (r32f) must be a finite number, got nan"),
             ({"n": (1, 2)}, "clear value of attachment 'n' (rgba32f) must be 3 or 4 finite numbers or a color name, "
                             "got (1, 2)"),
             ({"normal": 0}, "clear attachments names 'normal', but the framebuffer's attachments are "
                             "['color', 'n', 'id', 'z']"),
             ({"color": 0}, "clear attachments names 'color', location 0, whose clear value is color=")]
    for value, message in cases:
        with pytest.raises(ValueError) as e:
            fb.clear(attachments=value)
        assert str(e.value) == message
    with pytest.raises(ValueError) as e:
        fb.to_uint8(attachment="n")
    assert str(e.value) == ("attachment 'n' is rgba32f, numbers rather than a picture: read them with "
                            "fb.attachment('n'); only 'rgba8' attachments become bytes")
    pos = np.zeros((3, 4))
    with pytest.raises(ValueError) as e:
        sp.draw(fb, pos, varyings={"color": np.ones((3, 3))})
    assert str(e.value) == ("a framebuffer of 4 attachments (color, n, id, z) needs a fragment_shader that returns "
                            "one value per attachment; with none, a draw writes only the varying 'color'")
    with pytest.raises(ValueError) as e:
        sp.draw(fb, pos, fragment_shader=one_color, blend={"id": "additive"})
    assert str(e.value) == ("blend for attachment 'id' (r32i): integer attachments are not blended (GL's rule); "
                            "leave it out of blend= or give it None")
    with pytest.raises(ValueError) as e:
        sp.draw(fb, pos, fragment_shader=one_color, blend={"normal": "additive"})
    assert str(e.value) == ("blend names attachment 'normal', but the framebuffer's attachments are "
                            "['color', 'n', 'id', 'z']")
    with pytest.raises(ValueError) as e:
        sp.draw(fb, pos, fragment_shader=one_color, color_mask={"z": (True,)})
    assert str(e.value) == "color_mask for attachment 'z' must be 4 booleans (r, g, b, a), got (True,)"


def test_an_rgba8_attachment_becomes_bytes_as_the_color_does():
    fb = sp.Framebuffer(2, 1, attachments={"color": "rgba8", "albedo": "rgba8"}, srgb=True)
    fb.clear((0.5, 0.25, 1.5, 1.0), attachments={"albedo": (0.5, 0.25, 1.5, 1.0)})
    assert fb.to_uint8(attachment="albedo").tobytes() == fb.to_uint8().tobytes()
    assert fb.to_uint8(attachment="albedo")[0, 0].tolist() == [188, 137, 255, 255]


@pytest.mark.parametrize("topology", ["lines", "points"])
def test_lines_and_points_write_every_attachment_the_same_on_both_paths(topology):
    rng = np.random.default_rng(5)
    pos = np.column_stack([rng.uniform(-1, 1, (60, 2)), rng.uniform(-0.9, 0.9, 60), np.ones(60)])
    varyings = {"normal": rng.uniform(-1, 1, (60, 3)), "color": rng.uniform(0, 1, (60, 3))}
    out = []
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(32, 24, attachments=GBUFFER).clear(attachments={"id": -1})
        sp.draw(fb, pos, varyings=varyings, fragment_shader=gbuffer_shader, topology=topology, path=path,
                point_size=3.0, line_width=2.0)
        out.append({name: fb.samples_attachment(name).tobytes() for name in GBUFFER})
        assert (fb.attachment("id") >= 10).sum() > 30
    assert out[0] == out[1]
