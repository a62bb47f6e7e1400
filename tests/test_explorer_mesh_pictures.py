"""The mesh view's pictures in the explorer's picture list (issue 34).

A page of one draw holds ``mesh_pictures(trace)``'s two pictures as they are, the object-space
one without the page's window-space outline of the selected triangle; a page of several draws
holds one window-space picture with every draw's mesh (a later draw's edges over an earlier's),
and no object-space one (each draw's object space, and its picture's fit, are its own).
"""
from __future__ import annotations

import numpy as np

import softpipe as sp
from softpipe.views.explorer import explorer_data
from softpipe.views.mesh_view import mesh_pictures

W, H = 40, 32
WINDOW, OBJECT = "mesh, window space", "mesh, object space (front, orthographic)"


def _draw(fb, corners, shift):
    p = np.asarray(corners, dtype=float)
    clip = np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, np.full(len(p), shift), np.ones(len(p))])
    return sp.draw(fb, clip, varyings={"color": np.full((len(p), 3), 0.5)}, trace=True)


def _traces():
    fb = sp.Framebuffer(W, H)
    return [_draw(fb, [(2.5, 3.0), (37.0, 5.5), (20.3, 29.0)], 0.2),
            _draw(fb, [(5.0, 27.0), (19.0, 2.0), (35.2, 26.1), (5.0, 27.0), (35.2, 26.1), (30.0, 31.0)], -0.2)]


def test_a_page_of_one_draw_holds_both_mesh_pictures():
    trace = _traces()[0]
    data = explorer_data([trace])
    expected = mesh_pictures(trace)
    assert set(expected) == {WINDOW, OBJECT}
    for name, img in expected.items():
        assert np.array_equal(data["pictures"][name], img), name
        assert img.any(), name
    outline = {p["name"]: p["outline"] for p in data["meta"]["pictures"]}
    assert outline[WINDOW] is True and outline[OBJECT] is False and outline["final"] is True


def test_a_page_of_several_draws_holds_one_window_space_mesh_picture():
    traces = _traces()
    data = explorer_data(traces)
    names = [p["name"] for p in data["meta"]["pictures"]]
    assert WINDOW in names and OBJECT not in names
    first, second = (mesh_pictures(t)[WINDOW] for t in traces)
    lit = second.any(axis=2)
    expected = first.copy()
    expected[lit] = second[lit]
    assert first.any() and lit.any() and not np.array_equal(expected, first)
    assert np.array_equal(data["pictures"][WINDOW], expected)
