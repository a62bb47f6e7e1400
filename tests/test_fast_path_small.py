"""The triangles' visibility pass on a mesh of small triangles (issue 35): the same bytes as the reference path.

A mesh drawn in an order far from the screen's (a bunny from its light) has its triangle setup
copied into the bins' order before the tile walk (``tiles.gather_setup``, chosen by
``tiles.scattered``); one in order is walked through the item lists as before (here: with the
gathering turned off). Both routes are
held here to the reference path's color and depth: small triangles (boxes of 1 to 16 pixels, and
some wider, walked by row spans) whose boxes sit on the 128×32 tiles' borders and on 8-pixel
block borders, overlapping at random depths, at 1 and 4 samples, under every depth function.
"""
import numpy as np
import pytest
from conftest import window_to_clip

import softpipe as sp
import softpipe.pipeline.tiles as tiles
import softpipe.pipeline.visibility as visibility
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.merge_state import DEPTH_FUNCS
from softpipe.pipeline.sampling import rotated_grid_4x
from softpipe.pipeline.tiles import NARROW, SCATTERED, TILE_H, TILE_W, scattered

W, H = 2 * TILE_W + 21, 3 * TILE_H + 5          # not multiples of the tiles: the last ones are partial


def small_triangles(seed: int, n: int = 700) -> np.ndarray:
    """``n`` small triangles [n, 3, 3] (window x, y, depth in [−0.9, 0.9]) around tile and block borders."""
    rng = np.random.default_rng(seed)
    xs = np.r_[np.arange(0, W, 8), [TILE_W, 2 * TILE_W, W - 1]]        # block borders, tile borders, the edge
    ys = np.r_[np.arange(0, H, 8), [TILE_H, 2 * TILE_H, 3 * TILE_H, H - 1]]
    centre = np.c_[rng.choice(xs, n), rng.choice(ys, n)] + rng.uniform(-2.5, 2.5, (n, 2))
    size = rng.choice([0.6, 1.5, 3.0, 5.0, 8.0, NARROW - 1.0, NARROW + 2.0, 30.0], n,
                      p=[0.1, 0.15, 0.2, 0.2, 0.15, 0.1, 0.05, 0.05])
    corners = centre[:, None, :] + rng.uniform(-0.5, 0.5, (n, 3, 2)) * size[:, None, None]
    corners = np.round(corners * 8) / 8                         # corners on ties with the samples, too
    depth = rng.uniform(-0.9, 0.9, (n, 1)) + rng.uniform(-0.05, 0.05, (n, 3))
    return np.concatenate([corners, depth[..., None]], axis=-1)


def both_paths(tris: np.ndarray, pattern, func: str, write: bool, monkeypatch) -> tuple:
    """Color and depth of the triangles drawn on each path, and how often the fast path gathered the setup."""
    gathered = []

    def spy(*args):
        gathered.append(len(args[-1]))
        return gather(*args)

    gather = visibility.gather_setup
    monkeypatch.setattr(visibility, "gather_setup", spy)
    colors = np.random.default_rng(3).uniform(0.1, 1.0, (3 * len(tris), 3))
    out = []
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(W, H, pattern=pattern)
        fb.clear((0.0, 0.0, 0.0, 1.0), depth=0.5)
        DrawCall(fb, window_to_clip(tris.reshape(-1, 3), W, H), varyings={"color": colors}, depth_test=func,
                 depth_write=write, cull="none", path=path).run()
        out.append((fb.samples_color.copy(), fb.samples_depth.copy()))
    return out, gathered


@pytest.mark.parametrize("pattern", [sp.CENTER, rotated_grid_4x()], ids=lambda p: p.name)
@pytest.mark.parametrize("func", DEPTH_FUNCS)
def test_small_triangles_scattered_over_the_tiles_give_the_reference_bytes(pattern, func, monkeypatch):
    """In random order (each tile's list jumps about the mesh): the setup is gathered into the bins'
    order, and every sample's color and depth are the reference path's."""
    tris = small_triangles(5)
    # notequal with depth writes needs a shader whose alpha is a literal (choose_path), the default's is not
    write = func != "notequal"
    (ref, fast), gathered = both_paths(tris, pattern, func, write, monkeypatch)
    assert len(gathered) == 1 and gathered[0] > 500           # the gathered route was taken, once
    assert np.array_equal(ref[1], fast[1])
    assert np.array_equal(ref[0], fast[0])
    if func not in ("never", "equal"):
        assert (fast[0][..., 3] > 0).sum() > 3000            # much was drawn
    if func == "less" and pattern.count == 4:
        partial = (fast[0][..., 0] != fast[0][:1, ..., 0]).any(axis=0).sum()
        assert partial > 300                                  # pixels whose samples show different triangles


@pytest.mark.parametrize("pattern", [sp.CENTER, rotated_grid_4x()], ids=lambda p: p.name)
@pytest.mark.parametrize("func", ["less", "lequal", "greater", "always"])
def test_small_triangles_walked_through_the_lists_give_the_reference_bytes(pattern, func, monkeypatch):
    """The same kind of scene with the gathering turned off (as for a mesh in the screen's order): the tile
    walk reads the setup through the item lists, and gives the same bytes."""
    monkeypatch.setattr(tiles, "SCATTERED", 1.0)               # no list is that scattered
    (ref, fast), gathered = both_paths(small_triangles(6), pattern, func, True, monkeypatch)
    assert gathered == []
    assert np.array_equal(ref[1], fast[1])
    assert np.array_equal(ref[0], fast[0])
    assert (fast[0][..., 3] > 0).sum() > 3000


def with_breaks(breaks: int, n: int = 1001) -> np.ndarray:
    """``n`` triangle numbers in runs of consecutive ones, ``breaks`` jumps between runs."""
    jump = np.zeros(n, np.int64)
    jump[1:breaks + 1] = 10_000                       # entries 1 .. breaks each start a new run
    return (np.arange(n) + np.cumsum(jump)).astype(np.int32)


def test_scattered_measures_how_far_the_tile_lists_jump():
    """A list of consecutive triangles is in order, a shuffled one is not; the limit is SCATTERED of the
    neighbours."""
    assert not scattered(np.arange(1000, dtype=np.int32))
    assert not scattered(np.zeros(0, np.int32)) and not scattered(np.zeros(1, np.int32))
    assert scattered(np.random.default_rng(1).permutation(1000).astype(np.int32))
    limit = int(SCATTERED * 1000)                 # of the 1000 neighbours of 1001 entries
    assert int((np.diff(with_breaks(limit)) != 1).sum()) == limit
    assert not scattered(with_breaks(limit))
    assert scattered(with_breaks(limit + 1))
