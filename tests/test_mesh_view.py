"""The mesh view (issue 34, RenderDoc's mesh viewer): a draw's vertices in object, clip and window
space, as a table and as pictures with the selected pixel's triangle highlighted."""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh
from softpipe.views.mesh_view import MESH_GRAY, mesh_pictures, mesh_table, pixel_winner
from softpipe.views.pictures import MAGENTA, YELLOW, draw_triangle_outlines


@pytest.fixture(scope="module")
def trace():
    fb = sp.Framebuffer(64, 48)
    cam = sp.Camera(eye=(1.5, 1.2, 3.5), target=(0.0, 0.0, 0.0), fovy=45.0)
    results = []
    draw_mesh(fb, shapes.icosphere(1.0, 1), cam, "flat", results=results, trace=True)
    return results[0].trace


def test_the_tables_numbers_are_the_traces_arrays(trace):
    table = trace.mesh_table()
    clip = trace.vertex.position
    given = np.asarray(trace.call.positions, np.float64)
    assert len(table) == len(clip) and table.object_space == "object"
    for v in table:
        assert v.object == tuple(given[v.index].tolist())
        assert v.clip == tuple(clip[v.index].tolist())
        ndc = clip[v.index, :3] / clip[v.index, 3]
        assert v.window == tuple(trace.call.viewport.apply(ndc[None])[0].tolist())
    text = str(table)
    assert text.splitlines()[0] == f"{len(clip)} vertex(es)"
    assert "clip (x, y, z, w)" in text and "window (x, y, depth)" in text
    assert "<table>" in table._repr_html_()
    picked = mesh_table(trace, vertices=[3, 0])
    assert [v.index for v in picked] == [3, 0] and picked[0] == table[3]
    with pytest.raises(IndexError, match=r"mesh_table: vertex 9999 is out of range for the draw's \d+ vertices"):
        mesh_table(trace, vertices=[9999])


def _covered_pixel(trace):
    f, wr = trace.fragments, trace.written()
    k = np.nonzero(wr)[0][len(np.nonzero(wr)[0]) // 2]
    return int(f.x[k]), int(f.y[k])


def test_the_pixels_table_is_the_corners_of_the_triangle_that_won_it(trace):
    x, y = _covered_pixel(trace)
    history = trace.pixel_history(x, y)
    won = [e for e in history if e.verdict == "written"][-1]
    table = trace.mesh_table((x, y))
    assert table.triangle == pixel_winner(trace, x, y) == (won.triangle, won.primitive_id, 0)
    corners = trace.call.indices.reshape(-1, 3)[won.primitive_id]
    assert [v.index for v in table] == corners.tolist()
    assert f"pixel ({x}, {y}): won by post-clip triangle {won.triangle} (primitive {won.primitive_id})" in str(table)
    assert str(mesh_table(trace, (0, 0))) == "pixel (0, 0): no triangle was written there"


def test_the_highlighted_triangle_is_the_pixels_winner(trace):
    x, y = _covered_pixel(trace)
    pics = mesh_pictures(trace, (x, y))
    assert list(pics) == ["mesh, window space", "mesh, object space (front, orthographic)"]
    won = pixel_winner(trace, x, y)
    corners = trace.call.indices.reshape(-1, 3)[won[1]]
    clip = trace.vertex.position[corners]
    window = trace.call.viewport.apply(clip[:, :3] / clip[:, 3:4])
    alone = np.zeros_like(pics["mesh, window space"])
    draw_triangle_outlines(alone, window[None], trace.height, YELLOW)
    want = (alone == YELLOW).all(axis=2)
    want[y, x] = False                                   # the pixel itself is marked magenta
    got = (pics["mesh, window space"] == YELLOW).all(axis=2)
    assert want.sum() > 10 and np.array_equal(got, want)
    assert tuple(pics["mesh, window space"][y, x]) == MAGENTA
    assert (pics["mesh, window space"] == MESH_GRAY).all(axis=2).sum() > 50     # the rest of the mesh, gray
    obj = pics["mesh, object space (front, orthographic)"]
    assert (obj == YELLOW).all(axis=2).sum() > 5 and (obj == MESH_GRAY).all(axis=2).sum() > 50
    # another pixel won by another triangle highlights another one
    f, wr = trace.fragments, trace.written()
    other = next((int(a), int(b)) for a, b, p in zip(f.x[wr], f.y[wr], f.primitive_id[wr]) if p != won[1])
    assert not np.array_equal((mesh_pictures(trace, other)["mesh, window space"] == YELLOW).all(axis=2), got)
