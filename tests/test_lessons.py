"""The lessons (lessons/, issue #33): every notebook passes its checks with the solutions in its
exercise cells; the check helpers' messages (softpipe.testing.lessons); the zoomed pictures a small
framebuffer shows in a notebook (softpipe.views.zoom). The notebooks' runs, as given and with the
solutions, are in tests/test_lessons_skeletons.py (another worker under xdist)."""
from __future__ import annotations

import io

import numpy as np
import pytest
from lessons_run import LESSONS, NOTEBOOKS, runner
from PIL import Image

import softpipe as sp
from softpipe.testing import (
    check_bilinear,
    check_blinn_phong,
    check_camera,
    check_clipping,
    check_coverage,
    check_depth_test,
    check_interpolation,
    check_line,
    check_mip_level,
    check_ray_triangle,
    check_shadow_compare,
    check_triangles,
    covered_pixels,
    reference_line,
    trace_fragments,
)
from softpipe.views.zoom import GRID, INK, PAPER, glyph, zoom_layout, zoom_scale, zoomed

# ------------------------------------------------------------------ the notebooks (their runs: test_lessons_skeletons.py)


def test_every_lesson_has_its_exercise_cells_and_a_solution():
    found = sorted(p.stem for p in LESSONS.glob("[0-9][0-9]_*.ipynb"))
    assert found == NOTEBOOKS
    for name in NOTEBOOKS:
        nb = runner().load(LESSONS / f"{name}.ipynb", solutions=True)
        exercise = [c for c in nb.cells if "exercise" in c.metadata.get("tags", [])]
        # one exercise a lesson, two in lesson 08 (the bilinear filter, the level of detail): the one solution file
        # completes every exercise cell of its lesson
        assert len(exercise) == (2 if name == "08_textures" else 1), name
        assert all(c.source == (LESSONS / "solutions" / f"{name}.py").read_text() for c in exercise)
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


# ------------------------------------------------------------------ clipping, shading, textures


def _clip_polygon(polygon, plane):
    """Sutherland–Hodgman against one plane, the crossing from the inside end (lessons/solutions/06)."""
    d = polygon @ plane
    out = []
    for a in range(len(polygon)):
        b = (a + 1) % len(polygon)
        if d[a] >= 0:
            out.append(polygon[a])
        if (d[a] >= 0) != (d[b] >= 0):
            i, o = (a, b) if d[a] >= 0 else (b, a)
            out.append(polygon[i] + d[i] / (d[i] - d[o]) * (polygon[o] - polygon[i]))
    return np.array(out).reshape(-1, 4)


def _near_trace():
    W, H = 32, 24
    view = sp.look_at(eye=(0.0, 0.6, 2.0), target=(0.0, 0.0, 0.0))
    corners = np.array([[-1.2, 0.0, 0.0], [1.0, -0.2, 0.2], [0.2, 0.3, 1.9]])
    clip = (sp.perspective(60.0, W / H, 0.5, 20.0) @ view @ np.c_[corners, np.ones(3)].T).T
    return clip, sp.draw(sp.Framebuffer(W, H), clip, varyings={"color": np.eye(3)}, trace=True)


def test_check_clipping_agrees_with_the_assembly_and_names_the_classic_mistakes():
    clip, trace = _near_trace()
    assert len(trace.primitives) == 2 and trace.primitives.clipped.all()        # the near plane cuts it in two
    result = check_clipping(_clip_polygon, trace)
    assert result.ok and result.message == ("clipping: your polygons and softpipe's agree on all 6 triangles (1 of "
                                            "the draw, 5 further cases)")
    near = _clip_polygon(clip, np.array([0.0, 0.0, 1.0, 1.0]))
    assert len(near) == 4 and np.allclose(near[2:, 2] + near[2:, 3], 0.0)         # two new corners on the plane

    def strict(polygon, plane):                     # a corner on the plane taken as outside: d > 0, not ≥ 0
        d = polygon @ plane
        out = []
        for a in range(len(polygon)):
            b = (a + 1) % len(polygon)
            if d[a] > 0:
                out.append(polygon[a])
            if (d[a] > 0) != (d[b] > 0):
                out.append(polygon[a] + d[a] / (d[a] - d[b]) * (polygon[b] - polygon[a]))
        return np.array(out).reshape(-1, 4)

    def swapped_t(polygon, plane):                  # t measured from the other end
        d = polygon @ plane
        out = []
        for a in range(len(polygon)):
            b = (a + 1) % len(polygon)
            if d[a] >= 0:
                out.append(polygon[a])
            if (d[a] >= 0) != (d[b] >= 0):
                out.append(polygon[a] + d[b] / (d[b] - d[a]) * (polygon[b] - polygon[a]))
        return np.array(out).reshape(-1, 4)

    mistakes = [
        (lambda p, plane: p[p @ plane >= 0], "clipping the draw's triangle 0 against the plane (0, 0, 1, 1): your "
         "polygon differs from softpipe's (2 corners, softpipe's 4):", "your polygon keeps the corners inside the "
         "plane but not the points where the edges cross it"),
        (lambda p, plane: p, "clipping the draw's triangle 0", "your corner 2, (0.2598, -0.4479, -0.8343, 0.182), is "
         "outside the plane: a·x + b·y + c·z + d·w = -0.6523 < 0 there"),
        (lambda p, plane: _clip_polygon(p, plane)[::-1], "clipping the draw's triangle 0", "your polygon has "
         "softpipe's corners in the opposite order"),
        (strict, "clipping a corner exactly on x = w/2 against the plane (-1, 0, 0, 0.5): your polygon differs from "
         "softpipe's (4 corners, softpipe's 3):", "your polygon holds a corner twice: a corner exactly on the plane "
         "(distance 0) is inside (d ≥ 0)"),
        (swapped_t, "clipping the draw's triangle 0", "your corner 2, (1.113, -0.4343, 0.6942, 1.636), is a new point "
         "but not on the plane (its distance is 2.33, not 0)"),
    ]
    for answer, first, hint in mistakes:
        with pytest.raises(AssertionError) as info:
            check_clipping(answer, trace, show=False)
        text = str(info.value)
        assert text.startswith(first) and hint in text, text
    shown = []
    import softpipe.testing.lessons as lessons
    with pytest.MonkeyPatch.context() as mp, pytest.raises(AssertionError):
        mp.setattr(lessons, "_show", lambda d, show: shown.append(d))
        check_clipping(lambda p, plane: p[p @ plane >= 0], trace)
    assert shown[0].adds == [] and len(shown[0].misses) > 0         # the lost corners' pixels: softpipe's only
    with pytest.raises(ValueError, match=r"clip_polygon must return the clipped polygon's corners as an array "
                                         r"\[m, 4\] of clip coordinates \(x, y, z, w\), got an array of shape "
                                         r"\(3, 3\) for the draw's triangle 0"):
        check_clipping(lambda p, plane: p[:, :3], trace)
    indexed = sp.draw(sp.Framebuffer(32, 24), clip[::-1], indices=[2, 1, 0], varyings={"color": np.eye(3)},
                      trace=True)
    assert check_clipping(_clip_polygon, indexed).ok                 # the same triangle, indexed: the same corners
    lines = sp.draw(sp.Framebuffer(8, 8), clip[:2], varyings={"color": np.eye(2, 3)}, topology="lines", trace=True)
    with pytest.raises(ValueError, match=r"check_clipping needs a trace of a triangle list \(sp.draw\(fb, clip, ..., "
                                         r"trace=True\)\); this one drew 1 lines by the topology 'lines'"):
        check_clipping(_clip_polygon, lines)


def _blinn_phong(P, N, L, m, light, global_ambient, unit=True):
    N, V, L = N / (np.linalg.norm(N) if unit else 1.0), -P / np.linalg.norm(P), np.asarray(L)
    color = np.asarray(m.ke) + np.asarray(m.ka) * (np.asarray(global_ambient) + np.asarray(light.ambient))
    if N @ L > 0:
        H = (L + V) / np.linalg.norm(L + V)
        color = color + np.asarray(m.kd) * np.asarray(light.diffuse) * (N @ L)
        color = color + np.asarray(m.ks) * np.asarray(light.specular) * max(N @ H, 0.0) ** m.shininess
    return color


def _sphere_trace(lights, program="phong"):
    material = sp.Material(ka=(0.1, 0.1, 0.1), kd=(0.8, 0.3, 0.2), ks=(0.6, 0.6, 0.6), shininess=24.0)
    sphere = sp.shapes.uv_sphere(1.0, 16, 8, material=material)
    return sp.draw_mesh(sp.Framebuffer(24, 18), sphere, sp.Camera(eye=(0.0, 0.0, 3.2), fovy=45.0), program,
                        lighting=sp.Lighting(lights), trace=True)


def test_check_blinn_phong_agrees_with_the_phong_program_and_names_the_classic_mistakes():
    trace = _sphere_trace([sp.Light.directional((-1.0, -1.0, -1.0))])
    result = check_blinn_phong(_blinn_phong, trace)
    assert result.ok and result.message == (f"Blinn–Phong: your colors and softpipe's agree at all "
                                            f"{len(trace.fragments)} fragments")

    def phong(P, N, L, m, light, ga):                 # Phong's (R·V)ⁿ
        N, V, L = N / np.linalg.norm(N), -P / np.linalg.norm(P), np.asarray(L)
        color = np.asarray(m.ka) * (np.asarray(ga) + np.asarray(light.ambient))
        if N @ L > 0:
            R = 2 * (N @ L) * N - L
            color = color + np.asarray(m.kd) * (N @ L) + np.asarray(m.ks) * max(R @ V, 0.0) ** m.shininess
        return color

    mistakes = {
        "you compute Phong's specular (R·V)ⁿ (FORMULAS §5)": phong,
        "the interpolated normal N is not of unit length: normalize it first":
            lambda P, N, L, m, light, ga: _blinn_phong(P, N, L, m, light, ga, unit=False),
        "your V points from the eye to the point":
            lambda P, N, L, m, light, ga: _blinn_phong(-P, N, L, m, light, ga),
        "the ambient terms are missing": lambda P, N, L, m, light, ga: _blinn_phong(P, N, L, m, light, ga)
        - np.asarray(m.ka) * (np.asarray(ga) + np.asarray(light.ambient)),
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_blinn_phong(answer, trace, show=False)
        text = str(info.value)
        assert text.startswith("your Blinn–Phong differs from softpipe's at ") and hint in text, text
    with pytest.raises(AssertionError) as info:                   # a wrong answer no classic mistake explains
        check_blinn_phong(lambda *a: (0.5, 0.5, 0.5), trace, show=False)
    assert "FORMULAS" not in str(info.value) and "the largest differences:" in str(info.value)
    with pytest.raises(ValueError, match=r"blinn_phong must return the color \(r, g, b\), got an array of shape "
                                         r"\(2,\)"):
        check_blinn_phong(lambda *a: (0.5, 0.5), trace)
    with pytest.raises(ValueError, match=r"check_blinn_phong compares with the built-in program 'phong' .*; this "
                                         r"draw's fragment shader is softpipe.programs.gouraud.gouraud_fragment"):
        check_blinn_phong(_blinn_phong, _sphere_trace([sp.Light.directional((-1.0, -1.0, -1.0))], "gouraud"))
    with pytest.raises(ValueError, match=r"needs a directional light \(one L everywhere, no attenuation\)"):
        check_blinn_phong(_blinn_phong, _sphere_trace([sp.Light.point((2.0, 2.0, 2.0))]))
    with pytest.raises(ValueError, match=r"with one light and no shadows; this draw has 2 light\(s\)"):
        check_blinn_phong(_blinn_phong, _sphere_trace([sp.Light.directional((-1.0, -1.0, -1.0)),
                                                       sp.Light.directional((1.0, 0.0, -1.0))]))


def _texture_trace(tex):
    from softpipe.light.texture import texture

    def textured(varyings, uniforms, frag):
        c = texture(uniforms.tex, varyings.uv)
        return (c[0], c[1], c[2], 1.0)

    square = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1]], float)
    uv = np.array([[-0.25, -0.25], [1.25, -0.25], [1.25, 1.25], [-0.25, -0.25], [1.25, 1.25], [-0.25, 1.25]])
    return sp.draw(sp.Framebuffer(16, 12), square, varyings={"uv": uv}, fragment_shader=textured,
                   uniforms={"tex": tex}, trace=True)


def _bilinear(image, u, v):
    h, w = image.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    a, b = x - i0, y - j0

    def texel(i, j):
        return image[h - 1 - (j % h), i % w]

    return ((1 - a) * (1 - b) * texel(i0, j0) + a * (1 - b) * texel(i0 + 1, j0) + (1 - a) * b * texel(i0, j0 + 1)
            + a * b * texel(i0 + 1, j0 + 1))


def test_check_bilinear_agrees_with_texture2d_and_names_the_classic_mistakes():
    image = np.array([[[230, 60, 40], [250, 200, 40], [60, 160, 70], [40, 90, 220]],
                      [[40, 90, 220], [240, 240, 240], [30, 30, 30], [250, 200, 40]],
                      [[60, 160, 70], [30, 30, 30], [240, 240, 240], [230, 60, 40]]], np.uint8)
    tex = sp.Texture2D(image, wrap="repeat", filter="bilinear")
    trace = _texture_trace(tex)
    result = check_bilinear(_bilinear, trace, tex)
    assert result.ok and result.message == "bilinear filtering: your colors and softpipe's agree at all 192 fragments"
    assert np.allclose(trace.shaded.color, [tex.sample(*uv) for uv in trace.fragment_varyings(np.arange(192))[0]],
                       rtol=0, atol=1e-6)                    # what the shader's texture() returned is tex.sample

    def nearest(img, u, v):
        h, w = img.shape[:2]
        return img[h - 1 - int(np.floor(v * h)) % h, int(np.floor(u * w)) % w]

    def clamped(img, u, v):
        h, w = img.shape[:2]
        x, y = u * w - 0.5, v * h - 0.5
        i0, j0 = int(np.floor(x)), int(np.floor(y))
        a, b = x - i0, y - j0

        def texel(i, j):
            return img[h - 1 - min(max(j, 0), h - 1), min(max(i, 0), w - 1)]
        return ((1 - a) * (1 - b) * texel(i0, j0) + a * (1 - b) * texel(i0 + 1, j0) + (1 - a) * b * texel(i0, j0 + 1)
                + a * b * texel(i0 + 1, j0 + 1))

    mistakes = {
        "your answer is the nearest texel (GL's NEAREST)": nearest,
        "texel centres sit at (i + ½)/W: subtract ½ before the floor": lambda img, u, v: _bilinear(img, u + 0.5 / 4,
                                                                                                  v + 0.5 / 3),
        "your v runs down the image": lambda img, u, v: _bilinear(img[::-1], u, v),
        "you clamp the texel indices at the edges (CLAMP_TO_EDGE)": clamped,
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_bilinear(answer, trace, tex, show=False)
        text = str(info.value)
        assert text.startswith("your bilinear filter differs from softpipe's at ") and hint in text, text
    with pytest.raises(ValueError, match=r"check_bilinear compares with a texture whose filter is 'bilinear', got "
                                         r"'nearest'"):
        check_bilinear(_bilinear, trace, sp.Texture2D(image, filter="nearest"))
    with pytest.raises(ValueError, match=r"the draw has no varying 'st'; its varyings are \['uv'\]"):
        check_bilinear(_bilinear, trace, tex, "st")
    with pytest.raises(ValueError, match=r"bilinear must return the filtered color \(r, g, b, a\), got an array of "
                                         r"shape \(2,\)"):
        check_bilinear(lambda img, u, v: (u, v), trace, tex)


def _floor_trace(tex):
    """A floor going into the distance (the far edge at w = 4), drawn with texture_grad: λ from about −0.5 to 3."""
    from softpipe.shading import texture_grad

    def mipmapped(varyings, uniforms, frag, derivatives):
        c = texture_grad(uniforms.tex, varyings.uv, derivatives.dx.uv, derivatives.dy.uv)
        return (c[0], c[1], c[2], 1.0)

    floor = np.array([[-1.2, -1, 0, 1], [1.2, -1, 0, 1], [3, 2.8, 0, 4], [-1.2, -1, 0, 1], [3, 2.8, 0, 4],
                      [-3, 2.8, 0, 4]], float)
    uv = np.array([[0, 0], [1, 0], [1, 3], [0, 0], [1, 3], [0, 3]], float)
    return sp.draw(sp.Framebuffer(32, 24), floor, varyings={"uv": uv}, fragment_shader=mipmapped,
                   uniforms={"tex": tex}, trace=True)


def _level_of_detail(duv_dx, duv_dy, width, height):
    return float(np.log2(max(np.hypot(duv_dx[0] * width, duv_dx[1] * height),
                             np.hypot(duv_dy[0] * width, duv_dy[1] * height))))


def test_check_mip_level_agrees_with_texture_grads_level_and_names_the_classic_mistakes():
    checker = np.where(np.add.outer(np.arange(16) // 2, np.arange(32) // 2) % 2 == 0, 230, 40).astype(np.uint8)
    tex = sp.Texture2D(checker, wrap="repeat", filter="trilinear")
    trace = _floor_trace(tex)
    n = len(trace.fragments)
    result = check_mip_level(_level_of_detail, trace, tex)
    assert result.ok and result.message == f"level of detail: your λ and softpipe's agree at all {n} fragments"
    # softpipe's level is the one texture_grad sampled at: the shader's colors are texture_lod at it
    from softpipe.light.texture import mip_level, texture_lod
    for k in range(0, n, 37):
        varyings, _, _, d = trace.fragment_inputs(k)
        lam = mip_level(tex.__softpipe_uniform__(), d.dx.uv, d.dy.uv)
        assert lam == _level_of_detail(d.dx.uv, d.dy.uv, 32, 16)
        assert np.allclose(trace.shaded.color[k], texture_lod(tex.__softpipe_uniform__(), varyings.uv, lam),
                           rtol=0, atol=1e-6)

    def lengths(a, b, w, h):
        return np.hypot(a[0] * w, a[1] * h), np.hypot(b[0] * w, b[1] * h)

    mistakes = {
        "your ρ is in uv units: measure the derivatives in texels of level 0": lambda a, b, w, h: _level_of_detail(
            a, b, 1, 1),
        "you scale u by the height and v by the width": lambda a, b, w, h: _level_of_detail(a, b, h, w),
        "you take log2 of ρ² (the squared lengths)": lambda a, b, w, h: 2 * _level_of_detail(a, b, w, h),
        "your λ is ρ itself (texels per pixel)": lambda a, b, w, h: max(lengths(a, b, w, h)),
        "you take the natural log": lambda a, b, w, h: float(np.log(max(lengths(a, b, w, h)))),
        "you add the two lengths": lambda a, b, w, h: float(np.log2(sum(lengths(a, b, w, h)))),
        "you take the smaller of the two lengths": lambda a, b, w, h: float(np.log2(min(lengths(a, b, w, h)))),
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_mip_level(answer, trace, tex, show=False)
        text = str(info.value)
        assert text.startswith("your level of detail differs from softpipe's at ") and hint in text, text
        assert text.endswith("(the picture: your λ, softpipe's, and where they differ in red; a 32×16 texture, "
                             "level 0 to 5)"), text
    with pytest.raises(ValueError, match=r"^check_mip_level needs a draw whose fragment shader takes derivatives: "
                                         r"def fragment\(varyings, uniforms, frag, derivatives\)$"):
        check_mip_level(_level_of_detail, _texture_trace(tex), tex)
    with pytest.raises(ValueError, match=r"the draw has no varying 'st'; its varyings are \['uv'\]"):
        check_mip_level(_level_of_detail, trace, tex, "st")
    with pytest.raises(ValueError, match=r"^level_of_detail must return the level of detail λ \(a number\), got "
                                         r"tuple \(1, 2\)$"):
        check_mip_level(lambda a, b, w, h: (1, 2), trace, tex)


def _shadow_compare(depth, x, y, ref, r):
    h, w = depth.shape
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    lit = sum(1 for j in range(j0 - r, j0 + r + 1) for i in range(i0 - r, i0 + r + 1)
              if not (0 <= i < w and 0 <= j < h) or ref <= depth[j, i])
    return lit / (2 * r + 1) ** 2


def _shadow_scene(settings):
    from softpipe.scenes.scene import SceneObject
    floor = SceneObject("floor", sp.shapes.plane(4.0, material=sp.Material(kd=(0.8, 0.8, 0.8), ks=(0.0, 0.0, 0.0))),
                        sp.identity())
    slab = SceneObject("slab", sp.shapes.cube(1.0, material=sp.Material(kd=(0.8, 0.3, 0.2))),
                       sp.translate(0.0, 1.2, 0.0) @ sp.rotate_y(30) @ sp.scale(1.2, 0.4, 1.2))
    camera = sp.Camera(eye=(3.0, 4.0, 5.0), target=(0.0, 0.3, 0.0), fovy=45.0)
    sun = sp.Light.directional((-1.0, -1.0, -0.6), shadows=settings, name="sun")
    maps = []
    sp.render_scene(sp.Scene([floor, slab], camera=camera, lights=(sun,), width=40, height=30), shadow_maps=maps)
    trace = sp.draw_mesh(sp.Framebuffer(40, 30), floor.mesh, camera, "phong", lighting=sp.Lighting([sun]), trace=True)
    return trace, maps[0]


def test_check_shadow_compare_agrees_with_the_shadow_lookup_and_names_the_classic_mistakes():
    from softpipe.light.shadowmap import ShadowSettings
    trace, maps = _shadow_scene(ShadowSettings(resolution=32, pcf=1))
    result = check_shadow_compare(_shadow_compare, trace, maps)
    assert result.ok and result.message == ("the shadow compare: your visibility and softpipe's agree at all 270 "
                                            "fragments (37 of them in shadow, wholly or in part)")

    def flipped(depth, x, y, ref, r):
        return _shadow_compare(depth[::-1], x, y, ref, r)

    def average_depths(depth, x, y, ref, r):
        h, w = depth.shape
        i0, j0 = int(np.floor(x)), int(np.floor(y))
        taps = [depth[j, i] if 0 <= i < w and 0 <= j < h else 1.0
                for j in range(j0 - r, j0 + r + 1) for i in range(i0 - r, i0 + r + 1)]
        return float(ref <= np.mean(taps))

    mistakes = {
        "your test is the wrong way round": lambda depth, x, y, ref, r: 1.0 - _shadow_compare(depth, x, y, ref, r),
        "you average the depths and compare once": average_depths,
        "your rows run down the map": flipped,
        "you round x and y to the nearest texel": lambda depth, x, y, ref, r: _shadow_compare(depth, x + 0.5, y + 0.5,
                                                                                              ref, r),
        "you compare one texel: with PCF radius r = 1, compare at each of the (2r+1)² = 9 texels":
            lambda depth, x, y, ref, r: _shadow_compare(depth, x, y, ref, 0),
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_shadow_compare(answer, trace, maps, show=False)
        text = str(info.value)
        assert text.startswith("your shadow compare differs from softpipe's at ") and hint in text, text
    with pytest.raises(AssertionError, match=r"differs from softpipe's at 270 of 270 fragment\(s\) \(PCF radius "
                                             r"r = 1, a 32×32 map\):\n  pixel \(\d+, \d+\): yours 0.5, softpipe's "):
        check_shadow_compare(lambda *a: 0.5, trace, maps, show=False)
    with pytest.raises(ValueError, match=r"shadow_compare must return one number, the share of the light that passes "
                                         r"\(0 to 1\), got an array of shape \(2,\)"):
        check_shadow_compare(lambda *a: (1.0, 1.0), trace, maps)
    with pytest.raises(ValueError, match=r"light 1 is not one of the 1 light\(s\) of these shadow maps"):
        check_shadow_compare(_shadow_compare, trace, maps, light=1)


def _intersect(origin, direction, v0, v1, v2):
    """Möller–Trumbore, both sides, t > 0 (lessons/solutions/10)."""
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(direction, e2)
    det = p @ e1
    if det == 0:
        return None
    s = origin - v0
    q = np.cross(s, e1)
    u, v, t = (s @ p) / det, (direction @ q) / det, (e2 @ q) / det
    return (t, u, v) if u >= 0 and v >= 0 and u + v <= 1 and t > 0 else None


def _ray_scene():
    cube = sp.shapes.cube(1.0)
    turn = sp.rotate_y(35) @ sp.rotate_x(20)
    floor = np.array([[-2, -1, -2], [2, -1, -2], [2, -1, 2], [-2, -1, 2]], float)          # facing down
    wall = np.array([[-9, -9, 6], [9, -9, 6], [9, 9, 6], [-9, 9, 6]], float)              # behind the eye
    vertices = np.vstack([(turn[:3, :3] @ cube.positions.T).T, floor, wall])
    triangles = np.vstack([cube.indices, 24 + np.array([[0, 1, 2], [0, 2, 3]]), 28 + np.array([[0, 1, 2], [0, 2, 3]])])
    return vertices, triangles, sp.Camera(eye=(1.0, 1.5, 4.0), target=(0.0, -0.2, 0.0), fovy=45.0)


def test_check_ray_triangle_agrees_with_the_bvh_and_names_the_classic_mistakes():
    from softpipe.testing.lessons import camera_rays
    vertices, triangles, camera = _ray_scene()
    origins, directions = camera_rays(camera, 16, 12)
    assert origins.shape == directions.shape == (192, 3) and np.allclose(np.linalg.norm(directions, axis=1), 1.0)
    centre = directions[5 * 16 + 8] + directions[6 * 16 + 7]              # the two rays around the centre…
    forward = np.asarray(camera.target) - np.asarray(camera.eye)
    assert np.allclose(np.cross(centre, forward), 0.0, atol=1e-12)          # …straddle the view axis
    result = check_ray_triangle(_intersect, vertices, triangles, camera, 16, 12)
    assert result.ok and result.message == ("the closest hits: yours and softpipe's agree for all 192 rays (91 hit one "
                                            "of the 16 triangles)")

    def culling(o, d, v0, v1, v2):
        return _intersect(o, d, v0, v1, v2) if np.cross(d, v2 - v0) @ (v1 - v0) > 0 else None

    def behind(o, d, v0, v1, v2):                  # t of either sign
        hit = _intersect(o, d, v0, v1, v2)
        back = _intersect(o, -d, v0, v1, v2)
        return hit if hit is not None else (None if back is None else (-back[0], back[1], back[2]))

    mistakes = {
        "your test misses triangles seen from behind (det < 0)": culling,
        "your test counts hits behind the ray's origin: a hit needs t > 0": behind,
        "your barycentrics are swapped": lambda *a: None if _intersect(*a) is None else (_intersect(*a)[0],
                                                                                          _intersect(*a)[2],
                                                                                          _intersect(*a)[1]),
    }
    for hint, answer in mistakes.items():
        with pytest.raises(AssertionError) as info:
            check_ray_triangle(answer, vertices, triangles, camera, 16, 12, show=False)
        text = str(info.value)
        assert text.startswith("your closest hits differ from softpipe's for ") and hint in text, text
    with pytest.raises(AssertionError, match=r"for 91 of 192 ray\(s\) \(one per pixel of a 16×12 picture\):\n  pixel "
                                             r"\(\d+, \d+\): yours no triangle, softpipe's triangle \d+ at t = "):
        check_ray_triangle(lambda *a: None, vertices, triangles, camera, 16, 12, show=False)
    with pytest.raises(ValueError, match=r"intersect must return None for a miss or \(t, b1, b2\) for a hit, got an "
                                         r"array of shape \(2,\)"):
        check_ray_triangle(lambda *a: (1.0, 0.0), vertices, triangles, camera, 16, 12)
    with pytest.raises(ValueError, match=r"triangles must be whole-number indices into the 32 vertices"):
        check_ray_triangle(_intersect, vertices, triangles + 30, camera, 16, 12)
