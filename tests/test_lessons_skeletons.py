"""The lessons' notebooks, run headless twice (issue #33): as a student first gets them (lessons/README.md)
each exercise's check fails (a later exercise's with the ones before it solved), and its message names the
rule the skeleton breaks; with the solutions in the exercise cells every check passes. Both runs share one
kernel (lessons/run.py's ``run_both``: the cells before the first exercise run once). (In a file of its own so that under ``make test``'s --dist loadfile these
runs go to another worker than tests/test_lessons.py's.)"""
from __future__ import annotations

import pytest
from lessons_run import NOTEBOOKS, run_both

CASES = [pytest.param(*case, id=case[0]) for case in [
    ("01_lines", "pixel (13, 6): your answer draws it, softpipe does not: it holds the end point pb = (13.5, 6.5): "
                 "the diamond-exit rule leaves the last pixel out"),
    ("02_triangles", "pixel (5, 4): your answer draws it, softpipe does not: its centre lies exactly on triangle 0's "
                     "right edge (9.5, 1.5)→(1.5, 7.5): the fill rule leaves it out"),
    ("03_zbuffer", "you keep the fragment drawn last, though it is farther: write a fragment only when its depth is "
                   "less than the depth buffer's"),
    ("04_interpolation", "your answer interpolates linearly in the window (noperspective): v = Σ b_k v_k. A smooth "
                         "varying is perspective-correct: weight each corner by b_k / w_k = b_k · inv_w[k]"),
    ("05_camera", "your matrix is the transpose of softpipe's: softpipe's matrices act on column vectors (p' = M @ p), "
                  "so the translation goes in the last column, M[:3, 3], not the last row"),
    ("06_clipping", "your polygon keeps the corners inside the plane but not the points where the edges cross it: "
                    "for an edge from corner a to corner b whose distances d_a, d_b have opposite signs, add "
                    "p_a + t·(p_b − p_a) with t = d_a / (d_a − d_b)"),
    ("07_shading", "you compute Phong's specular (R·V)ⁿ (FORMULAS §5); Blinn–Phong's is (N·H)₊ⁿ with the half "
                   "vector H = normalize(L + V) (FORMULAS §6)"),
    ("08_textures", ("your answer is the nearest texel (GL's NEAREST): bilinear filtering weights the four texels "
                     "around (u·W − ½, v·H − ½)",
                     # the second exercise, met with the first solved: the level of detail
                     "your level of detail differs from softpipe's at ",
                     "your ρ is in uv units: measure the derivatives in texels of level 0, ∂u·W and ∂v·H (W × H the "
                     "texture's size), before taking their lengths")),
    ("09_shadows", "you compare one texel: with PCF radius r = 1, compare at each of the (2r+1)² = 9 texels "
                   "(floor(x) + di, floor(y) + dj), −r ≤ di, dj ≤ r, and average"),
    ("10_rays", "your test misses triangles seen from behind (det < 0): softpipe's rays hit both sides of a triangle, "
                "so only det = 0 (the ray parallel to the plane) is no hit"),
]]


@pytest.mark.parametrize("name, expected", CASES)
def test_each_skeleton_fails_with_a_message_that_names_the_rule_and_the_solution_passes(name, expected):
    failures, nb = run_both(name)
    exercises = [c for c in nb.cells if "exercise" in c.metadata.get("tags", [])]
    checks = [c for c in nb.cells if "check" in c.metadata.get("tags", [])]
    assert len(failures) == len(exercises) == len(checks) >= 1, (
        f"{name}: {len(failures)} check(s) failed as given, for {len(exercises)} exercise(s)")
    per_exercise = [[expected]] if isinstance(expected, str) else [[expected[0]], list(expected[1:])]
    for text, parts in zip(failures, per_exercise):
        assert "AssertionError" in text and all(p in text for p in parts), text[-3000:]
    for cell in checks:                              # with the solutions every check passes
        shown = "".join(o.get("text", "") for o in cell.outputs if o.output_type == "stream")
        assert "agree" in shown, cell.outputs
    assert not any(o.output_type == "error" for c in nb.cells for o in c.get("outputs", []))


def test_every_notebook_is_run():
    assert [p.values[0] for p in CASES] == NOTEBOOKS
