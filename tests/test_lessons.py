"""The lessons (lessons/, issue #33): every notebook passes its checks with the solutions in its
exercise cells; the check helpers' messages (softpipe.testing.lessons); the zoomed pictures a small
framebuffer shows in a notebook (softpipe.views.zoom). The skeletons' runs are in
tests/test_lessons_skeletons.py (another worker under xdist)."""
from __future__ import annotations

import io

import numpy as np
import pytest
from lessons_run import LESSONS, NOTEBOOKS, runner
from PIL import Image

import softpipe as sp
from softpipe.testing import (
    check_camera,
    check_coverage,
    check_depth_test,
    check_interpolation,
    check_line,
    check_triangles,
    covered_pixels,
    reference_line,
    trace_fragments,
)
from softpipe.views.zoom import GRID, INK, PAPER, glyph, zoom_layout, zoom_scale, zoomed

# ------------------------------------------------------------------ the notebooks, with the solutions


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_a_notebook_passes_its_checks_with_the_solutions(name):
    nb = runner().run(LESSONS / f"{name}.ipynb", solutions=True)
    check = [c for c in nb.cells if "check" in c.metadata.get("tags", [])]
    assert len(check) == 1
    text = "".join(o.get("text", "") for o in check[0].outputs if o.output_type == "stream")
    assert "agree" in text, check[0].outputs
    assert not any(o.output_type == "error" for c in nb.cells for o in c.get("outputs", []))


def test_every_lesson_has_one_exercise_cell_and_a_solution():
    found = sorted(p.stem for p in LESSONS.glob("[0-9][0-9]_*.ipynb"))
    assert found == NOTEBOOKS
    for name in NOTEBOOKS:
        nb = runner().load(LESSONS / f"{name}.ipynb", solutions=True)
        exercise = [c for c in nb.cells if "exercise" in c.metadata.get("tags", [])]
        assert len(exercise) == 1 and exercise[0].source == (LESSONS / "solutions" / f"{name}.py").read_text()
        original = runner().load(LESSONS / f"{name}.ipynb")
        assert all(not c.get("outputs") for c in original.cells if c.cell_type == "code"), "commit notebooks cleared"


# ------------------------------------------------------------------ the zoom


def test_zoomed_draws_blocks_grid_lines_and_labels_at_the_stated_pixels():
    img = np.zeros((3, 4, 3), np.uint8)
    img[0, 0] = (255, 0, 0)                 # top-left pixel red: window (0, 2)
    img[2, 3] = (0, 0, 255)                 # bottom-right blue: window (3, 0)
    s = 12                                  # 12 picture pixels a pixel: room for a label under every column
    out = zoomed(img, s)
    left, bottom, _, grid = zoom_layout(4, 3, s)
    assert grid and out.shape == (3 * s + 1 + bottom, 4 * s + 1 + left, 3)
    part = out[:3 * s + 1, left:]
    for r in range(4):                      # grid rows and columns at k·s
        assert (part[r * s] == GRID).all()
    for c in range(5):
        assert (part[:, c * s] == GRID).all()
    assert (part[1:s, 1:s] == (255, 0, 0)).all()                         # nearest neighbour: one color a block
    assert (part[2 * s + 1:3 * s, 3 * s + 1:4 * s] == (0, 0, 255)).all()
    assert (part[s + 1:2 * s, 1:s] == 0).all()
    assert {tuple(c) for c in part.reshape(-1, 3)} == {GRID, (0, 0, 0), (255, 0, 0), (0, 0, 255)}
    # labels: x = 0…3 under the columns, y = 0…2 left of the rows (y up: 0 is the bottom row)
    below = out[3 * s + 1:, left:]
    for x in range(4):
        g = glyph(str(x))
        cx = x * s + 1 + (s - 1) // 2 - g.shape[1] // 2
        assert (below[4:4 + g.shape[0], cx:cx + g.shape[1]][g] == INK).all()
        assert (below[4:4 + g.shape[0], cx:cx + g.shape[1]][~g] == PAPER).all()
    g = glyph("0")
    cy = 2 * s + 1 + (s - 1) // 2 - g.shape[0] // 2          # y = 0 labels the bottom row
    x0 = left - 4 - g.shape[1]
    assert (out[cy:cy + g.shape[0], x0:x0 + g.shape[1]][g] == INK).all()


def test_zoomed_without_grid_or_axes_is_plain_nearest_neighbour():
    img = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    out = zoomed(img, 3, grid=False, axes=False)
    assert np.array_equal(out[:, :, 0], np.kron(img, np.ones((3, 3), np.uint8)))
    assert zoomed(np.ones((2, 2), bool), 2, axes=False).shape == (4, 4, 3)       # scale < 4: no grid
    with pytest.raises(ValueError, match=r"image must be \[H, W\], \[H, W, 3\] or \[H, W, 4\].*shape \(2, 2, 5\)"):
        zoomed(np.zeros((2, 2, 5)))
    with pytest.raises(ValueError, match="scale must be a whole number of picture pixels per pixel in \\[1, 256\\], got 0"):
        zoomed(img, 0)


def test_a_small_framebuffer_shows_zoomed_in_jupyter_a_large_one_as_it_is():
    small = sp.Framebuffer(16, 12)
    small.clear((1.0, 0.0, 0.0))
    bundle = small._repr_mimebundle_()
    shown = np.asarray(Image.open(io.BytesIO(bundle["image/png"])).convert("RGB"))
    assert np.array_equal(shown, zoomed(small))
    assert small._repr_png_() != bundle["image/png"]                     # _repr_png_ stays fb.save's bytes
    large = sp.Framebuffer(64, 8)
    assert large._repr_mimebundle_()["image/png"] == large._repr_png_()


# ------------------------------------------------------------------ the check helpers' messages


def test_check_line_names_the_last_pixel_and_passes_the_reference():
    pa, pb = (0.5, 0.5), (7.5, 3.5)
    assert check_line(reference_line(pa, pb), pa, pb).ok
    with pytest.raises(AssertionError) as info:
        check_line(reference_line(pa, pb) | {(7, 3)}, pa, pb, show=False)
    assert str(info.value).splitlines()[:2] == [
        "the pixels of the line (0.5, 0.5) → (7.5, 3.5) differ from softpipe's at 1 pixel(s) (1 your answer adds, "
        "0 it misses; softpipe draws 7):",
        "  pixel (7, 3): your answer draws it, softpipe does not: it holds the end point pb = (7.5, 3.5): the "
        "diamond-exit rule leaves the last pixel out (a line is half-open, so a strip's joints are drawn once)"]


def test_check_line_explains_a_tie():
    pa, pb = (1.5, 1.5), (5.5, 3.5)            # slope ½: halfway between centres at x = 2 and x = 4
    ref = reference_line(pa, pb)
    assert (2, 2) in ref                        # rising: the upper pixel
    with pytest.raises(AssertionError, match=r"pixel \(2, 1\): your answer draws it, softpipe does not: the line "
                                             r"passes exactly halfway between this pixel's centre and its "
                                             r"neighbour's: GL moves the segment by \(−ε, −ε²\)"):
        check_line(ref - {(2, 2)} | {(2, 1)}, pa, pb, show=False)


def test_check_triangles_names_the_edge_and_the_fill_rule():
    tri = [(1.5, 1.5), (9.5, 1.5), (1.5, 7.5)]
    ref = set(covered_pixels([tri], 12, 10))
    assert check_triangles(ref, [tri], 12, 10).ok
    with pytest.raises(AssertionError) as info:
        check_triangles(ref - {(1, 4)}, [tri], 12, 10, show=False)
    assert ("pixel (1, 4): softpipe draws it, your answer does not: its centre lies exactly on triangle 0's left edge "
            "(1.5, 7.5)→(1.5, 1.5): the fill rule covers it (left edges and bottom edges, y up, own the centres on "
            "them)") in str(info.value)
    with pytest.raises(AssertionError, match=r"pixel \(5, 4\): your answer draws it, softpipe does not: its centre "
                                             r"lies exactly on triangle 0's right edge \(9.5, 1.5\)→\(1.5, 7.5\): "
                                             r"the fill rule leaves it out"):
        check_triangles(ref | {(5, 4)}, [tri], 12, 10, show=False)


def test_check_coverage_draws_the_difference_in_its_colors():
    from softpipe.testing.lessons import COLORS, Difference
    ok = check_coverage({(0, 0), (1, 0)}, {(0, 0), (1, 0)}, width=2, height=1)
    assert isinstance(ok, Difference) and ok.ok
    shown = []
    import softpipe.testing.lessons as lessons
    with pytest.MonkeyPatch.context() as mp, \
            pytest.raises(AssertionError, match=r"differ from softpipe's at 2 pixel\(s\) \(1 your answer adds, 1 it misses"):
        mp.setattr(lessons, "_show", lambda d, show: shown.append(d))      # what Jupyter would display
        check_coverage({(0, 0), (1, 0)}, {(0, 0), (0, 1)}, width=2, height=2)
    d = shown[0]
    assert d.adds == [(1, 0)] and d.misses == [(0, 1)]
    s = zoom_scale(2, 2)
    assert s == 32                               # 320 // 2, at most 32
    left = zoom_layout(2, 2, s)[0]
    part = d.picture[:, left:]
    assert tuple(part[1 + s + 1, 1 + s + 1]) == COLORS["adds"]        # window (1, 0): bottom-right block
    assert tuple(part[2, 2]) == COLORS["misses"]                       # window (0, 1): top-left block
    assert tuple(part[s + 2, 2]) == COLORS["both"]                     # window (0, 0)
    assert "text/html" in d._repr_mimebundle_() and "your answer adds it" in d._repr_mimebundle_()["text/html"]


def test_check_depth_test_names_the_missing_test():
    W, H = 8, 6
    tris = np.array([[(0.5, 0.5, 0.2), (7.5, 0.5, 0.2), (0.5, 5.5, 0.2)],         # near, drawn first
                     [(0.5, 0.5, 0.7), (7.5, 0.5, 0.7), (0.5, 5.5, 0.7)]])        # far, drawn second
    p = tris.reshape(-1, 3)
    clip = np.c_[2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, 2 * p[:, 2] - 1, np.ones(len(p))]
    fb = sp.Framebuffer(W, H)
    trace = sp.draw(fb, clip, varyings={"color": np.ones((6, 3))}, trace=True)
    frags = trace_fragments(trace)
    nearest = {}
    for x, y, z, t in frags:
        if z < nearest.get((x, y), (1.0, None))[0]:
            nearest[(x, y)] = (z, t)
    assert check_depth_test({k: t for k, (z, t) in nearest.items()}, trace).ok
    last = {(x, y): t for x, y, z, t in frags}
    with pytest.raises(AssertionError, match=r"keeps another triangle than softpipe's at \d+ of \d+ pixel\(s\):\n"
                                             r"  pixel \(\d, 0\): you keep triangle 1, softpipe keeps triangle 0 "
                                             r"\(fragments in draw order: triangle 0 at depth 0.2, triangle 1 at depth "
                                             r"0.7\): you keep the fragment drawn last, though it is farther"):
        check_depth_test(last, trace, show=False)


def test_check_interpolation_agrees_with_the_shader_and_names_the_classic_mistakes():
    W, H = 12, 8
    clip = np.array([(-0.9, -0.9, 0.0, 1.0), (3.6, -3.6, 0.0, 4.0), (-0.9, 0.9, 0.0, 1.0)])   # w = 1, 4, 1
    color = np.array([(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)])
    trace = sp.draw(sp.Framebuffer(W, H), clip, varyings={"color": color}, trace=True)

    def smooth(values, inv_w, bary):
        q = bary * inv_w
        return q @ values / q.sum()

    result = check_interpolation(smooth, trace, "color")
    assert result.ok and result.message == (f"the interpolated color: your answer and softpipe's agree at all "
                                            f"{len(trace.fragments)} fragments")
    mistakes = {
        "your answer interpolates linearly in the window (noperspective): v = Σ b_k v_k.":
            lambda values, inv_w, bary: bary @ values,
        "you weight each corner by b_k / w_k but do not divide by the weights' sum":
            lambda values, inv_w, bary: (bary * inv_w) @ values,
        "you weight each corner by b_k · w_k: inv_w[k] is already 1/w_k":
            lambda values, inv_w, bary: (bary / inv_w) @ values / (bary / inv_w).sum(),
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_interpolation(answer, trace, "color", show=False)
        text = str(info.value)
        assert text.startswith("the interpolated color differs from softpipe's at ") and hint in text, text
    with pytest.raises(AssertionError) as info:                   # a wrong answer no classic mistake explains
        check_interpolation(lambda values, inv_w, bary: values[0], trace, "color", show=False)
    assert not any(line.startswith(("your answer interpolates", "you weight")) for line in str(info.value).splitlines())
    with pytest.raises(ValueError, match=r"the draw has no varying 'uv'; its varyings are \['color'\]"):
        check_interpolation(smooth, trace, "uv")
    with pytest.raises(ValueError, match=r"interpolate must return the 3 component\(s\) of 'color' at the fragment, "
                                         r"got an array of shape \(2,\)"):
        check_interpolation(lambda values, inv_w, bary: values[0, :2], trace, "color")


def test_check_camera_passes_softpipes_matrices_and_names_the_classic_mistakes():
    result = check_camera(sp.look_at, sp.perspective, 16, 12)
    assert result.ok and result.message == ("look_at and perspective: your matrices and softpipe's agree on all 3 "
                                            "cameras and 3 projections")

    def left_handed(eye, target, up):                       # Direct3D's LookAtLH
        e = np.asarray(eye, float)
        f = np.asarray(target, float) - e
        f /= np.linalg.norm(f)
        x = np.cross(up, f)
        x /= np.linalg.norm(x)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = x, np.cross(f, x), f
        m[:3, 3] = -m[:3, :3] @ e
        return m

    def depth_01(fovy, aspect, near, far):                  # Direct3D's depth range
        m = sp.perspective(fovy, aspect, near, far)
        m[2, 2], m[2, 3] = -far / (far - near), -far * near / (far - near)
        return m

    mistakes = [
        (lambda *a: sp.look_at(*a).T, sp.perspective, "look_at(eye=(3.0, 2.0, 4.0)",
         "your matrix is the transpose of softpipe's"),
        (left_handed, sp.perspective, "look_at(eye=(3.0, 2.0, 4.0)", "your look_at is left-handed (Direct3D's LookAtLH"),
        (lambda *a: np.diag([1.0, 1.0, -1.0, 1.0]) @ sp.look_at(*a), sp.perspective, "look_at(",
         "your camera looks down +Z"),
        (sp.look_at, depth_01, "perspective(fovy=50, aspect=1.333, near=0.5, far=20)",
         "your projection maps depth to [0, 1] (Direct3D's and Vulkan's clip space)"),
        (sp.look_at, lambda fovy, a, n, f: sp.perspective(2 * fovy, a, n, f),      # c = 1/tan(fovy), not of fovy/2
         "perspective(fovy=50, aspect=1.333, near=0.5, far=20)",
         "your y scale M[1, 1] is 0.8391, softpipe's 2.14451 = 1/tan(fovy/2)"),
    ]
    for look_at, perspective, first, hint in mistakes:
        with pytest.raises(AssertionError) as info:
            check_camera(look_at, perspective, 16, 12, show=False)
        text = str(info.value)
        assert text.startswith(first) and hint in text, text
    shown = []
    import softpipe.testing.lessons as lessons
    with pytest.MonkeyPatch.context() as mp, pytest.raises(AssertionError):
        mp.setattr(lessons, "_show", lambda d, show: shown.append(d))
        check_camera(left_handed, sp.perspective, 16, 12)
    assert shown[0].adds == [] and len(shown[0].misses) > 0             # the left-handed eye looks away: nothing
    with pytest.raises(ValueError, match=r"look_at\(eye=\(3.0, 2.0, 4.0\), target=\(0.0, 0.0, 0.0\), up=\(0.0, 1.0, "
                                         r"0.0\)\) must return a 4×4 matrix, got an array of shape \(3, 3\)"):
        check_camera(lambda *a: np.eye(3), sp.perspective, 16, 12)
