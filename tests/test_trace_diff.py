"""The diff of two draws or traces (issue 34): which pixels a change changed, by how much, and each changed
pixel's first fragment whose record differs. Each expectation is computed from the traces themselves."""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
from softpipe.tools.cli import main
from softpipe.views.diff import FIELDS, TraceDiff, diff_draws, write_diff_page
from softpipe.views.pictures import heat_colors

W, H = 16, 12


def tinted(varyings, uniforms, frag):
    """Triangle 1 in the uniform ``tint``; the others in their varying color."""
    if frag.primitive_id == 1:
        return (uniforms.tint[0], uniforms.tint[1], uniforms.tint[2], 1.0)
    return (varyings.color[0], varyings.color[1], varyings.color[2], 1.0)


def two_triangles(tint):
    """Triangle 0 on the left, triangle 1 on the right (apart), drawn in one draw; triangle 1 in ``tint``."""
    pos = window_to_clip([(1, 1), (7, 1), (1, 10), (9, 1), (15, 1), (15, 10)], W, H)
    color = np.tile([0.2, 0.6, 0.3, 1.0], (6, 1))
    fb = sp.Framebuffer(W, H).clear((0.1, 0.1, 0.1, 1.0))
    return sp.draw(fb, pos, varyings={"color": color}, fragment_shader=tinted,
                   uniforms={"tint": np.array(tint, np.float64)}, trace=True)


def test_one_triangles_color_changed_names_its_pixels_and_its_fragments_shader_output():
    a, b = two_triangles([1.0, 0.0, 0.0]), two_triangles([0.0, 0.0, 1.0])
    d = a.diff(b)
    assert isinstance(d, TraceDiff)
    f = a.fragments
    mine = a.written() & (f.primitive_id == 1)
    want = np.zeros((H, W), bool)
    want[f.y[mine], f.x[mine]] = True
    assert want.sum() > 10 and np.array_equal(d.changed, want)
    assert np.allclose(d.delta[want], [-1.0, 0.0, 1.0, 0.0]) and not d.delta[~want].any()
    for x, y in d.pixels():
        first = d.first_difference(x, y)
        assert first.field == "shader output" and first.position == 0
        assert first.a.primitive_id == first.b.primitive_id == 1
        assert first.value_a == (1.0, 0.0, 0.0, 1.0) and first.value_b == (0.0, 0.0, 1.0, 1.0)
    x0, y0 = int(f.x[f.primitive_id == 0][0]), int(f.y[f.primitive_id == 0][0])
    assert d.first_difference(x0, y0) is None          # triangle 0's pixels: the same history
    assert str(d).endswith(f"{want.sum()} pixel(s) changed ({100 * want.sum() / (W * H):.3g}%); the largest change "
                           "|Δ| = 1 at " + str(d.pixels()[0]).replace(" ", " ") + "; mean |Δ| over the changed "
                           "pixels 1")
    x, y = d.pixels()[0]
    k = int(a.at(x, y)[0])
    assert str(d.first_difference(x, y)) == (
        f"pixel ({x}, {y}): fragment 0 of its history differs in its shader output: A fragment #{k} of draw 0, "
        f"primitive 1: (1, 0, 0, 1); B fragment #{k} of draw 0, primitive 1: (0, 0, 1, 1)")


def test_the_diff_picture_marks_the_changed_pixels_by_how_much():
    a, b = two_triangles([1.0, 0.0, 0.0]), two_triangles([0.8, 0.0, 0.0])
    d = diff_draws(a, b)
    img = d.picture()
    m = np.abs(d.color_b.astype(np.float64) - d.color_a).max(axis=2)[d.changed]     # 1.0 − 0.8 in float32
    assert np.allclose(m, 0.2) and np.array_equal(img[d.changed], heat_colors(1.0 + 5.0 * m))
    dim = np.round(np.clip(d.color_b[..., :3].astype(np.float64), 0, 1) * 255 / 3).astype(np.uint8)
    assert np.array_equal(img[~d.changed], dim[~d.changed])


def quads(depth_test):
    """A near quad over the left two thirds, then a far one over the right two thirds: 4 columns overlap."""
    def quad(x0, x1, depth):
        corners = [(x0, 0), (x1, 0), (x1, H), (x0, 0), (x1, H), (x0, H)]
        return window_to_clip([(x, y, 2 * depth - 1) for x, y in corners], W, H)
    pos = np.concatenate([quad(0, 10, 0.25), quad(6, 16, 0.5)])
    color = np.concatenate([np.tile([1.0, 0.5, 0.0, 1.0], (6, 1)), np.tile([0.0, 0.5, 1.0, 1.0], (6, 1))])
    return sp.draw(sp.Framebuffer(W, H), pos, varyings={"color": color}, depth_test=depth_test, trace=True)


def test_a_depth_state_change_names_the_verdict_of_the_far_quads_fragment():
    a, b = quads("less"), quads("always")
    d = a.diff(b)
    want = np.zeros((H, W), bool)
    want[:, 6:10] = True                               # the overlap: the far quad now wins
    assert np.array_equal(d.changed, want)
    for x, y in d.pixels():
        first = d.first_difference(x, y)
        assert (first.field, first.position) == ("verdict", 1)
        assert (first.value_a, first.value_b) == ("depth-failed", "written")
        assert first.a.primitive_id == first.b.primitive_id and first.a.primitive_id in (2, 3)   # the far quad's
        assert first.a.index == a.at(x, y)[1] and first.b.index == b.at(x, y)[1]


def test_identical_draws_change_nothing():
    d = quads("less").diff(quads("less"))
    assert d.count == 0 and not d.changed.any() and not d.delta.any()
    assert all(d.first_difference(x, y) is None for x in range(0, W, 3) for y in range(0, H, 3))
    assert str(d) == f"1 draw(s) against 1, {W}×{H}: no pixel changed"


def scene(tint):
    """Two draws into one framebuffer: the quads, then the two triangles' right one tinted over them."""
    fb = sp.Framebuffer(W, H)
    pos = window_to_clip([(3, 2), (13, 2), (8, 9)], W, H, z=0.5)        # behind the second draw
    first = sp.draw(fb, pos, varyings={"color": np.tile([0.3, 0.3, 0.3, 1.0], (3, 1))}, trace=True)
    pos = window_to_clip([(1, 1), (7, 1), (1, 10), (9, 1), (15, 1), (15, 10)], W, H, z=-0.5)
    second = sp.draw(fb, pos, varyings={"color": np.tile([0.2, 0.6, 0.3, 1.0], (6, 1))}, fragment_shader=tinted,
                     uniforms={"tint": np.array(tint, np.float64)}, trace=True)
    return [first, second]


def test_a_scene_diff_compares_every_draws_history_in_order():
    a, b = scene([1.0, 0.0, 0.0]), scene([0.0, 1.0, 0.0])
    d = diff_draws(a, b)
    f = a[1].fragments
    mine = f.primitive_id == 1                          # the front triangle 1 of the second draw
    want = np.zeros((H, W), bool)
    want[f.y[mine], f.x[mine]] = True
    assert np.array_equal(d.changed, want)
    both = [(x, y) for x, y in d.pixels() if len(a[0].at(x, y))]
    assert both                                         # some changed pixels have draw 0's fragment first
    first = d.first_difference(*both[0])
    assert (first.field, first.draw_a, first.draw_b, first.position) == ("shader output", 1, 1, 1)
    assert str(d).startswith("2 draw(s) against 2")


def test_a_missing_draw_is_a_fragment_difference():
    a, b = scene([1.0, 0.0, 0.0]), scene([1.0, 0.0, 0.0])[:1]
    d = diff_draws(a, b)
    x, y = d.pixels()[0]
    first = d.first_difference(x, y)
    assert first.field == "fragment" and first.b is None and first.a is not None
    assert FIELDS[-1] == "fragment"


def test_draws_of_different_sizes_or_not_traces_are_named():
    with pytest.raises(ValueError, match=r"diff: A is 16×12, B 8×8: compare draws of the same size"):
        quads("less").diff(sp.draw(sp.Framebuffer(8, 8), window_to_clip([(0, 0), (8, 0), (0, 8)], 8, 8),
                                   varyings={"color": np.ones((3, 4))}, trace=True))
    with pytest.raises(TypeError, match=r"diff: B: item 0: expected a Trace or a DrawResult drawn with "
                                        r"trace=True, got Framebuffer"):
        quads("less").diff(sp.Framebuffer(W, H))
    with pytest.raises(ValueError, match=r"diff: B: no draws \(an empty list\)"):
        diff_draws(quads("less"), [])


def test_the_diff_page_shows_both_histories_of_the_chosen_pixel(tmp_path):
    d = quads("less").diff(quads("always"))
    page = write_diff_page(d, tmp_path / "d.html", pixel=(7, 3)).read_text()
    assert "pixel (7, 3): fragment 1 of its history differs in its verdict" in page
    assert page.count("<table>") == 2 and page.count('class="first"') == 2
    assert "<li>pixel (6, 0): fragment 1" in page
    with pytest.raises(ValueError, match=r"diff page: pixel \(16, 0\) is outside the 16×12 picture"):
        write_diff_page(d, tmp_path / "e.html", pixel=(16, 0))
    assert not (tmp_path / "e.html").exists()


SCENE = """
[camera]
eye = [0, 0.5, 3]
target = [0, 0, 0]
[[meshes]]
name = "ball"
shape = "uv_sphere"
radius = 0.6
segments = 12
rings = 6
transform = {{ translate = [0.5, 0.0, 0.0] }}
material = {{ kd = {ball} }}
[[meshes]]
name = "box"
shape = "cube"
size = 0.8
transform = {{ translate = [-0.6, 0.0, 0.0] }}
material = {{ kd = [0.2, 0.4, 0.8] }}
"""


def test_softpipe_explore_diff_on_the_command_line(tmp_path, capsys):
    (tmp_path / "a.toml").write_text(SCENE.format(ball="[0.8, 0.2, 0.1]"))
    (tmp_path / "b.toml").write_text(SCENE.format(ball="[0.1, 0.8, 0.1]"))
    out = tmp_path / "diff.html"
    assert main(["explore", "--diff", str(tmp_path / "a.toml"), str(tmp_path / "b.toml"), "-o", str(out),
                 "--size", "32x24", "-q"]) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"softpipe explore: wrote {out.resolve()} (2 draw(s) against 2, 32×24: ") and "pixel(s) changed" in said
    page = out.read_text()
    assert "differs in its" in page and page.count("<table>") == 2
    assert main(["explore", str(tmp_path / "a.toml"), "--diff", str(tmp_path / "a.toml"), str(tmp_path / "b.toml"),
                 "-o", str(out)]) == 2
    assert ("softpipe explore: error: --diff A B compares two inputs; give no INPUT beside them"
            in capsys.readouterr().err)
    assert main(["explore", "-o", str(out)]) == 2
    assert "softpipe explore: error: give INPUT (or --diff A B)" in capsys.readouterr().err
    assert main(["explore", str(tmp_path / "a.toml"), "--pixel", "1", "2", "-o", str(out)]) == 2
    assert "softpipe explore: error: --pixel applies only with --diff A B" in capsys.readouterr().err
    assert main(["explore", "--diff", str(tmp_path / "a.toml"), str(tmp_path / "b.toml"), "--pixel", "32", "0",
                 "-o", str(tmp_path / "other.html"), "--size", "32x24", "-q"]) == 2
    assert ("softpipe explore: error: --pixel: diff page: pixel (32, 0) is outside the 32×24 picture"
            in capsys.readouterr().err)
    assert not (tmp_path / "other.html").exists()


def test_softpipe_explore_overlays_on_the_command_line(tmp_path, capsys):
    (tmp_path / "a.toml").write_text(SCENE.format(ball="[0.8, 0.2, 0.1]"))
    out = tmp_path / "page.html"
    assert main(["explore", str(tmp_path / "a.toml"), "--overlays", "-o", str(out), "--size", "32x24", "-q"]) == 0
    page = out.read_text()
    assert all(f'alt="{name}"' in page for name in ("triangle size", "depth test", "clipped and culled"))
