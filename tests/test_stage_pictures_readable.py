"""Stage pictures that read on real models (issue 34): a palette where neighbours differ, a density
rule for the vertices and the wireframe, and a caption under each picture on the contact sheet."""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.assembly import primitive_indices
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh
from softpipe.views.pictures import (
    CAPTIONS,
    DIM_YELLOW,
    INSET_FRAME,
    PALETTE,
    SPARSE_CELL,
    SPARSE_MAX,
    YELLOW,
    contact_sheet,
    greedy_coloring,
    save_stage_pictures,
    triangle_adjacency,
    triangle_palette,
)


def _trace(mesh, size=96, distance=4.0, **kw):
    fb = sp.Framebuffer(size, size)
    cam = sp.Camera(eye=(1.2, 1.0, distance), target=(0.0, 0.0, 0.0), fovy=45.0)
    results = []
    draw_mesh(fb, mesh, cam, "flat", results=results, trace=True, **kw)
    return results[0].trace


def _welded_pairs(trace):
    given = np.asarray(trace.call.positions, np.float64)
    _, weld = np.unique(given, axis=0, return_inverse=True)
    tri = primitive_indices(trace.call.topology, trace.call.indices, len(given))
    return triangle_adjacency(weld.reshape(-1)[tri])


@pytest.mark.parametrize("mesh", [shapes.icosphere(1.0, 1), shapes.cube(2.0, 2), shapes.torus(1.0, 0.35, 12, 8)],
                         ids=["icosphere", "cube split at its edges", "torus"])
def test_no_two_triangles_sharing_an_edge_have_the_same_color(mesh):
    trace = _trace(mesh, size=160, cull="none")
    pairs = _welded_pairs(trace)
    assert len(pairs) >= len(trace.call.indices) // 3          # a closed mesh: every triangle has neighbours
    f, wr = trace.fragments, trace.written()
    won = np.full((trace.height, trace.width), -1)
    won[f.y[wr], f.x[wr]] = f.primitive_id[wr]                  # the last fragment written at each pixel
    # the mesh's edges: at most 3 neighbours each, 4 colors at most; with the picture's touching pixels
    # (triangles meeting at a corner touch there too), a few more
    for colors, most in ((triangle_palette(trace), 4), (triangle_palette(trace, won), 6)):
        assert not (colors[pairs[:, 0]] == colors[pairs[:, 1]]).all(axis=1).any()
        assert 2 <= len(np.unique(colors, axis=0)) <= most
        assert set(map(tuple, colors)) <= set(map(tuple, PALETTE))
    # and the picture shows them: each written triangle's pixels carry its color, neighbours on screen differ
    pics = trace.pictures()
    assert "inset" not in pics.captions["coverage"]             # big triangles: every pixel is the picture's own
    pic = pics["coverage"]
    ys, xs = np.nonzero(won >= 0)
    assert np.array_equal(pic[ys, xs], colors[won[ys, xs]]) and not pic[won < 0].any()
    shown = {int(won[y, x]): tuple(pic[y, x]) for y, x in zip(ys, xs)}
    on_screen = [(a, b) for a, b in pairs if a in shown and b in shown]
    assert len(on_screen) > 10 and all(shown[a] != shown[b] for a, b in on_screen)
    # pixels side by side won by different triangles differ in color (a triangle over another too)
    side = (won[:, 1:] >= 0) & (won[:, :-1] >= 0) & (won[:, 1:] != won[:, :-1])
    assert side.sum() > 10 and (pic[:, 1:][side] != pic[:, :-1][side]).any(axis=1).all()


def test_triangles_apart_in_the_mesh_but_touching_in_the_picture_differ():
    """Two separate triangles, one in front of the other (no shared edge): not the same color."""
    fb = sp.Framebuffer(48, 48)
    tris = np.array([[-0.9, -0.9, 0.5, 1], [0.9, -0.9, 0.5, 1], [0.0, 0.9, 0.5, 1],
                     [-0.5, -0.5, 0.0, 1], [0.5, -0.5, 0.0, 1], [0.0, 0.5, 0.0, 1]], float)
    trace = sp.draw(fb, tris, varyings={"color": np.ones((6, 3))}, trace=True)
    pic = trace.pictures()["coverage"]
    assert tuple(pic[24, 24]) != tuple(pic[40, 24]) and pic[24, 24].any() and pic[40, 24].any()


def test_the_greedy_coloring_takes_the_smallest_color_free_of_earlier_neighbours():
    # a fan of four triangles around a vertex: 0-1, 1-2, 2-3 share edges (a path), 3-0 too (a cycle of 4)
    pairs = np.array([[0, 1], [1, 2], [2, 3], [0, 3]])
    assert greedy_coloring(4, pairs).tolist() == [0, 1, 0, 1]
    assert greedy_coloring(3, np.array([[0, 1], [1, 2], [0, 2]])).tolist() == [0, 1, 2]
    # an edge shared by three triangles makes all three neighbours; a collapsed edge is none
    tris = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [5, 5, 6]])
    assert triangle_adjacency(tris).tolist() == [[0, 1], [0, 2], [1, 2]]


def _cells(points):
    keys, counts = np.unique(np.floor_divide(points, SPARSE_CELL), axis=0, return_counts=True)
    return {tuple(k): int(c) for k, c in zip(keys, counts)}


def _image_vertices(trace):
    pos = trace.vertex.position
    ok = pos[:, 3] > 0
    win = trace.call.viewport.apply(pos[ok, :3] / pos[ok, 3:4])
    return np.floor(np.stack([win[:, 0], trace.height - win[:, 1]], axis=1)).astype(np.int64)


def test_sparse_vertices_are_dots_and_no_inset():
    trace = _trace(shapes.cube(2.0, 1), size=96)
    p = _image_vertices(trace)
    assert max(_cells(p).values()) > SPARSE_MAX                 # 3 records per corner (split at its edges)...
    assert max(_cells(np.unique(p, axis=0)).values()) <= SPARSE_MAX     # ...at one pixel: sparse
    pics = trace.pictures()
    img = pics["vertices"]
    for x, y in p:                                   # a 3×3 dot on each
        assert (img[y - 1:y + 2, x - 1:x + 2] == YELLOW).all()
    assert not (img == DIM_YELLOW).all(axis=2).any() and not (img == INSET_FRAME).all(axis=2).any()
    assert pics.captions["vertices"] == CAPTIONS["vertices"] and "inset" not in pics.captions["primitives"]


def test_dense_vertices_are_dim_pixels_and_a_zoomed_inset_shows_them():
    trace = _trace(shapes.icosphere(1.0, 4), size=128, distance=9.0)
    p = _image_vertices(trace)
    cells = _cells(np.unique(p, axis=0))
    assert max(cells.values()) > SPARSE_MAX
    pics = trace.pictures()
    img = pics["vertices"]
    dim = (img == DIM_YELLOW).all(axis=2)
    dense = [(x, y) for x, y in p if cells[(x // SPARSE_CELL, y // SPARSE_CELL)] > SPARSE_MAX]
    assert dense and dim.any()
    frame = (img == INSET_FRAME).all(axis=2)
    assert frame.sum() > 4 * 32                       # the inset's frame (64 across) and its source square's
    cap = pics.captions["vertices"]
    assert f"<= {SPARSE_MAX} vertices per {SPARSE_CELL}x{SPARSE_CELL} px" in cap and "inset: the boxed place x" in cap
    # small triangles: the wireframe and the coverage get the inset too
    assert "inset" in pics.captions["primitives"] and "inset" in pics.captions["coverage"]
    assert (pics["primitives"] == INSET_FRAME).all(axis=2).sum() > 4 * 32


def test_each_picture_has_its_caption_on_the_contact_sheet(tmp_path):
    trace = _trace(shapes.cube(2.0, 1), size=64)
    pics = trace.pictures()
    assert list(pics.captions) == list(pics) and all(pics.captions.values())
    assert pics.captions["coverage"] == CAPTIONS["coverage"]
    plain = np.asarray(contact_sheet(pics))
    captioned = np.asarray(contact_sheet(pics, captions=pics.captions))
    assert captioned.shape[0] > plain.shape[0]        # the label rows grew to hold the captions
    top = 4 + 15                                      # under the first row's names: the captions' lines
    band = captioned[top:top + 11]
    for c in range(3):                                # text under each picture of the first row
        assert (band[:, 4 + 68 * c:4 + 68 * c + 64] != (24, 24, 28)).any(axis=2).sum() > 20, c
    paths = save_stage_pictures(trace, tmp_path)
    from PIL import Image
    assert np.array_equal(np.asarray(Image.open(paths["contact-sheet"])), captioned)
