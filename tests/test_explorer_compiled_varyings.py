"""The explorer's varyings in one compiled pass (issue 34): ``Trace.fragment_varyings``.

The generated module's ``inputs_loop`` runs the same ``fragment_inputs`` the shader's
loop runs, compiled, over many fragments at once. Its values must be those the per-fragment
Python path (``trace.fragment_inputs``, which ``pixel_history`` and ``debug_fragment`` use)
gives, bit for bit: smooth (perspective-correct), noperspective and flat varyings, on
triangles (with multisampling, and a shader that takes derivatives), lines and points, and a
draw without varyings; and the explorer page holds exactly them.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.sampling import rotated_grid_4x
from softpipe.views.explorer import ExplorerData, explorer_data

W, H = 40, 32
QUALIFIERS = {"uv": "noperspective", "tag": "flat"}


def _clip(window_xy, w):
    """Clip-space positions of window points (x, y), at clip w ``w`` (a perspective divide to undo)."""
    p = np.asarray(window_xy, dtype=float)
    w = np.asarray(w, dtype=float)
    ndc = np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, np.linspace(-0.4, 0.4, len(p))])
    return np.column_stack([ndc * w[:, None], w])


def shows_all(varyings, uniforms, frag):
    s, t = frag.point_coord
    return (varyings.color[0] * s, varyings.uv[1] + t, varyings.tag, 1.0)


def with_derivatives(varyings, uniforms, frag, derivatives):
    return (varyings.color[0] + derivatives.dx.uv[0], varyings.uv[1], varyings.tag, 1.0)


def no_varyings(varyings, uniforms, frag):
    return (frag.point_coord[0], frag.point_coord[1], 0.5, 1.0)


def _varyings(n):
    k = np.arange(n, dtype=float)
    return {"color": np.column_stack([0.1 + 0.2 * k, 0.9 - 0.1 * k, np.sqrt(k + 1) / 3]),
            "uv": np.column_stack([k / 7, (k * k) / 11]), "tag": 1.0 + k}


def _traces():
    """Draws with smooth, noperspective and flat varyings: triangles (in perspective, multisampled, and a
    shader with derivatives), a line strip, points, and a draw without varyings."""
    corners = [(2.5, 3.0), (37.0, 5.5), (20.3, 29.0), (5.0, 27.0), (35.2, 26.1), (19.0, 2.0)]
    w = [1.0, 2.5, 0.7, 1.8, 1.2, 3.1]
    out = []
    fb = sp.Framebuffer(W, H)
    out.append(sp.draw(fb, _clip(corners, w), varyings=_varyings(6), interpolation=QUALIFIERS,
                       fragment_shader=shows_all, trace=True))
    out.append(sp.draw(fb, _clip(corners, w), varyings=_varyings(6), interpolation=QUALIFIERS,
                       fragment_shader=with_derivatives, depth_test="always", trace=True))
    fb4 = sp.Framebuffer(W, H, pattern=rotated_grid_4x())
    out.append(sp.draw(fb4, _clip(corners, w), varyings=_varyings(6), interpolation=QUALIFIERS,
                       fragment_shader=shows_all, trace=True))
    out.append(sp.draw(fb, _clip(corners, w), topology="line_strip", line_width=2, varyings=_varyings(6),
                       interpolation=QUALIFIERS, fragment_shader=shows_all, depth_test="always", trace=True))
    out.append(sp.draw(fb, _clip(corners, w), topology="points", point_size=5, varyings=_varyings(6),
                       interpolation=QUALIFIERS, fragment_shader=shows_all, depth_test="always", trace=True))
    out.append(sp.draw(sp.Framebuffer(W, H), _clip(corners[:3], w[:3]), fragment_shader=no_varyings, trace=True))
    return out


@pytest.fixture(scope="module")
def traces():
    return _traces()


def _flat(varyings) -> list:
    """The Varyings' components in order, as the shader received them (float64)."""
    out = []
    for item in varyings:
        out.extend(item if isinstance(item, tuple) else (item,))
    return out


def _bits(a) -> bytes:
    return np.asarray(a, dtype=np.float64).tobytes()


def test_the_scene_has_every_qualifier_and_kind(traces):
    kinds = [t.primitives.kind for t in traces]
    assert kinds.count("triangles") == 4 and "lines" in kinds and "points" in kinds
    qualifiers = {q for t in traces for *_, q in t.primitives.layout.fields}
    assert qualifiers == {"smooth", "noperspective", "flat"}
    assert traces[-1].primitives.layout.fields == ()
    assert all(len(t) > 20 for t in traces)


def test_compiled_varyings_equal_the_per_fragment_python_path_bit_for_bit(traces):
    for k, t in enumerate(traces):
        n = len(t)
        rows = np.arange(n)[::-1]                   # any order, as the page's rows are
        varyings, point_coord = t.fragment_varyings(rows)
        assert varyings.dtype == np.float64 and varyings.shape == (n, max(t.primitives.layout.width, 1))
        assert point_coord.shape == (n, 2)
        for r, i in enumerate(rows):
            v, _, frag = t.fragment_inputs(int(i))[:3]
            assert _bits(varyings[r]) == _bits(_flat(v)), (k, int(i))
            assert _bits(point_coord[r]) == _bits(frag.point_coord), (k, int(i))


def test_no_rows_and_a_bad_index(traces):
    t = traces[0]
    varyings, point_coord = t.fragment_varyings([])
    assert varyings.shape == (0, 6) and point_coord.shape == (0, 2)
    with pytest.raises(IndexError, match=f"fragment index {len(t)} out of range for {len(t)} fragments"):
        t.fragment_varyings([0, len(t)])
    with pytest.raises(IndexError, match=f"fragment index -1 out of range for {len(t)} fragments"):
        t.fragment_varyings([-1])


def test_the_page_holds_the_compiled_values(traces):
    """The page's f_vary and f_pc are the Python path's values, as float32 (one draw at a time: the
    draws here are on framebuffers of their own)."""
    for t in traces:
        arrays = ExplorerData(explorer_data([t])["meta"]).arrays
        index = arrays["f_index"]
        assert len(index) == len(t)
        width = t.primitives.layout.width
        for r, i in enumerate(index):
            v, _, frag = t.fragment_inputs(int(i))[:3]
            expected = np.float32(_flat(v))[:width]
            assert arrays["f_vary"][r, :width].tobytes() == expected.tobytes()
            if t.primitives.kind != "triangles":
                assert arrays["f_pc"][r].tobytes() == np.float32(frag.point_coord).tobytes()
            else:
                assert np.isnan(arrays["f_pc"][r]).all()
