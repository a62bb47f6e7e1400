"""Pixel history into several color attachments (issue #31's leftover): each fragment's value for every
attachment and the sample's value after it, not location 0's alone.

The expected values come from the scene (each quad's window depth, the clear values, additive blending by
hand), and the history's last values are checked against the attachments' final values at the pixel.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp

W = H = 8
TWO = {"color": "rgba8", "normal": "rgba32f"}
CLEAR_NORMAL = (-1.0, -1.0, -1.0, -1.0)


def quads(*zs):
    """Full-screen quads, one per clip z (window depth (z + 1) / 2), drawn in that order; the varying
    ``tint`` is the quad's number k / 4."""
    corners = [(0, 0), (W, 0), (W, H), (0, 0), (W, H), (0, H)]
    pos = np.concatenate([window_to_clip([(x, y, z) for x, y in corners], W, H) for z in zs])
    tint = np.repeat(np.arange(len(zs), dtype=np.float64) / 4, 6)[:, None].repeat(3, axis=1)
    return pos, {"tint": tint}


def two_outputs(v, u, frag):
    t = v.tint[0]
    return (t, 0.5, 0.25, 1.0), (frag.z, t, 0.125, 0.5)


def framebuffer():
    return sp.Framebuffer(W, H, attachments=TWO).clear((0.0, 0.0, 0.0, 1.0), attachments={"normal": CLEAR_NORMAL})


def test_the_history_shows_every_attachment_and_ends_on_their_final_values():
    """Three quads at window depth 0.5, 0.25, 0.75: written, written (nearer), depth-failed (farther)."""
    fb = framebuffer()
    pos, varyings = quads(0.0, -0.5, 0.5)
    trace = sp.draw(fb, pos, varyings=varyings, fragment_shader=two_outputs, path="reference", trace=True)
    h = trace.pixel_history(3, 4)
    assert [e.verdict for e in h] == ["written", "written", "depth-failed"]
    assert [e.outputs["normal"] for e in h] == [(0.5, 0.0, 0.125, 0.5), (0.25, 0.25, 0.125, 0.5),
                                                (0.75, 0.5, 0.125, 0.5)]
    assert [e.outputs_after["normal"] for e in h] == [(0.5, 0.0, 0.125, 0.5), (0.25, 0.25, 0.125, 0.5),
                                                      (0.25, 0.25, 0.125, 0.5)]
    # the history's values after the last fragment are the attachments' final values at the pixel
    assert h[-1].outputs_after["normal"] == tuple(float(c) for c in fb.attachment("normal")[4, 3])
    assert h[-1].color_after == tuple(float(c) for c in fb.color[4, 3])
    assert list(h[0].outputs) == ["normal"]


def test_a_blended_attachment_is_replayed_fragment_by_fragment():
    """``normal`` blended additively, no depth test: after each fragment the clear value plus the values so far."""
    fb = framebuffer()
    pos, varyings = quads(0.0, -0.5)
    trace = sp.draw(fb, pos, varyings=varyings, fragment_shader=two_outputs, depth_test=None,
                    blend={"normal": "additive"}, trace=True)
    h = trace.pixel_history(6, 1)
    first = tuple(c + d for c, d in zip(CLEAR_NORMAL, (0.5, 0.0, 0.125, 0.5)))
    second = tuple(c + d for c, d in zip(first, (0.25, 0.25, 0.125, 0.5)))
    assert [e.outputs_after["normal"] for e in h] == [first, second]
    assert h[-1].outputs_after["normal"] == tuple(float(c) for c in fb.attachment("normal")[1, 6])
    assert [e.color_after for e in h] == [(0.0, 0.5, 0.25, 1.0), (0.25, 0.5, 0.25, 1.0)]   # location 0: not blended


def test_the_fast_paths_history_shows_the_winners_values():
    fb = framebuffer()
    pos, varyings = quads(0.0, -0.5, 0.5)
    trace = sp.draw(fb, pos, varyings=varyings, fragment_shader=two_outputs, path="fast", trace=True)
    (winner,) = trace.pixel_history(3, 4)
    assert winner.outputs == winner.outputs_after == {"normal": (0.25, 0.25, 0.125, 0.5)}
    assert winner.outputs_after["normal"] == tuple(float(c) for c in fb.attachment("normal")[4, 3])


@pytest.mark.parametrize("ids", [False, True])
def test_the_table_has_a_column_pair_per_attachment(ids):
    attachments = dict(TWO, **({"id": "r32i"} if ids else {}))
    fb = sp.Framebuffer(W, H, attachments=attachments)

    def shader(v, u, frag):
        out = two_outputs(v, u, frag)
        return out + ((7,) if ids else ())
    pos, varyings = quads(0.0)
    h = sp.draw(fb, pos, varyings=varyings, fragment_shader=shader, trace=True, path="reference").pixel_history(0, 0)
    cols, rows = h.table()
    more = ["normal"] + (["id"] if ids else [])
    assert cols[cols.index("shader output"):] == (["shader output"] + [f"{a} output" for a in more] + ["merger",
                                                  "color after"] + [f"{a} after" for a in more])
    assert rows[0][cols.index("normal output")] == "(0.5, 0, 0.125, 0.5)"
    if ids:
        assert rows[0][cols.index("id after")] == "7" and h[0].outputs_after["id"] == 7
    assert "normal after" in str(h) and "normal after" in h._repr_html_()


def test_one_attachment_has_the_columns_it_had():
    fb = sp.Framebuffer(W, H)
    pos, varyings = quads(0.0)
    h = sp.draw(fb, pos, varyings=varyings, fragment_shader=lambda v, u, f: (v.tint[0], 0.0, 0.0, 1.0),
                trace=True, path="reference").pixel_history(0, 0)
    assert h[0].outputs == {} and h.table()[0][-3:] == ["shader output", "merger", "color after"]
