"""benchmarks.peers: the harness logic without Mesa, and one small clip-coordinate scene on llvmpipe if it is here."""
from __future__ import annotations

import json
import re
import sys
import types

import numpy as np
import pytest

from benchmarks import peers

# --------------------------------------------------------------------------
# Without Mesa
# --------------------------------------------------------------------------

def test_glsl_sources_are_complete():
    lit = peers._lit_fragment_source()
    for src in (peers.CLIP_VERTEX, peers.MVP_VERTEX, peers.COLOR_FRAGMENT, peers.LIT_VERTEX, lit):
        assert src.startswith("#version 430\n")
        assert src.count("{") == src.count("}")
    assert "%(" not in lit and "%" not in lit.replace("%%", "")
    from softpipe.light import packed as m
    assert f"const int COLS = {m.LIGHT_COLUMNS};" in lit
    assert f"lights[b + {m.LIGHT_KIND}] == {m.LIGHT_DIRECTIONAL}.0" in lit
    assert f"col3(j, {m.LIGHT_POSITION})" in lit and f"col3(j, {m.LIGHT_SPECULAR})" in lit
    for name in ("ke", "ka", "kd", "ks", "shininess", "opacity", "global_ambient", "num_lights", "specular_model",
                 "orthographic"):
        assert re.search(rf"^uniform \w+ {name};$", lit, re.M), name
    for name in ("model_view", "projection", "normal_matrix"):
        assert re.search(rf"^uniform mat[34] {name};$", peers.LIT_VERTEX, re.M), name


def test_one_light_glsl_is_the_minimal_blinn_phong():
    src = peers.ONE_LIGHT_FRAGMENT
    assert src.startswith("#version 430\n") and src.count("{") == src.count("}")
    for name in ("light_dir", "ambient", "kd", "ks"):
        assert re.search(rf"^uniform vec3 {name};", src, re.M), name
    assert re.search(r"^uniform float shininess;$", src, re.M)
    for line in ("vec3 N = normalize(v_normal);", "vec3 V = normalize(-v_position);", "vec3 H = normalize(L + V);",
                 "pow(max(dot(N, H), 0.0), shininess)", "ambient + kd * diffuse + ks * specular"):
        assert line in src, line


def test_one_light_scene_and_shader_compute_the_formula():
    """bunny-onelight's softpipe shader on one fragment (plain Python) against
    ambient + kd·max(N·L, 0) + ks·max(N·H, 0)ⁿ evaluated here with numpy; its uniforms
    are the bunny's material and the light in eye space."""
    scene = peers.PEER_SCENES["bunny-onelight"](0.1)
    (draw,) = scene.draws
    u = draw["uniforms"]
    assert draw["fragment_shader"] is peers.one_light_fragment and "lighting" not in u and "material" not in u
    view = np.asarray(u["view"])
    L = view[:3, :3] @ -np.asarray(peers.ONE_LIGHT_DIRECTION)
    np.testing.assert_allclose(u["light_dir"], L / np.linalg.norm(L), rtol=0, atol=1e-15)
    assert u["kd"] == (0.75, 0.7, 0.6) and u["ks"] == (0.4, 0.4, 0.4) and u["shininess"] == 30.0
    uniforms = types.SimpleNamespace(**u)
    for P, n in (((0.3, -0.2, -4.0), (0.1, 0.9, 0.4)), ((-1.0, 0.5, -3.0), (-0.5, -0.2, 0.3))):
        got = peers.one_light_fragment(types.SimpleNamespace(position=P, normal=n), uniforms, None)
        N = np.asarray(n) / np.linalg.norm(n)
        V = -np.asarray(P) / np.linalg.norm(P)
        H = (L / np.linalg.norm(L) + V) / np.linalg.norm(L / np.linalg.norm(L) + V)
        expected = (np.asarray(u["ambient"]) + np.asarray(u["kd"]) * max(N @ u["light_dir"], 0.0)
                    + np.asarray(u["ks"]) * max(N @ H, 0.0) ** 30)
        np.testing.assert_allclose(got[:3], expected, rtol=1e-12, atol=1e-15)
        assert got[3] == 1.0


def test_alternation_is_abba_and_counts_both_sides():
    order = []
    clock = iter(range(1000))

    def side(name, seconds):
        def frame():
            order.append(name)
            next(clock)
            return seconds
        return frame

    sp, gl, cpu = peers.alternate(side("s", 0.03), side("g", 0.01), 4)
    assert order == ["s", "g", "g", "s", "s", "g", "g", "s"]
    assert sp == [0.03] * 4 and gl == [0.01] * 4
    assert set(cpu) == {"softpipe_cpu", "softpipe_wall", "peer_cpu", "peer_wall"}


def test_summary_arithmetic():
    s = peers.summarize([0.010, 0.030, 0.020], [0.010, 0.010, 0.040])
    assert s["softpipe_ms"] == pytest.approx(20.0) and s["llvmpipe_ms"] == pytest.approx(10.0)
    assert s["ratio"] == pytest.approx(2.0)
    assert s["paired_ratio_median"] == pytest.approx(1.0)          # 1, 3, 0.5
    assert s["paired_ratio_min"] == pytest.approx(0.5) and s["paired_ratio_max"] == pytest.approx(3.0)
    with pytest.raises(ValueError):
        peers.summarize([0.1], [0.1, 0.2])


def test_the_targets_against_llvmpipe_are_the_ratios_of_the_full_size_scenes():
    rows = [{"scene": "bunny", "ratio": 0.49, "scale": 1.0}, {"scene": "tiny", "ratio": 0.48, "scale": 1.0},
            {"scene": "fill", "ratio": 0.08, "scale": 1.0}, {"scene": "sphere200k", "ratio": 0.1, "scale": 0.5}]
    targets = peers.target_rows(rows)
    assert [(t["target"], t["measured"], t["met"]) for t in targets] == [
        ("bunny ≤ 0.5× llvmpipe", "0.49", True), ("tiny ≤ 0.35× llvmpipe", "0.48", False)]
    assert set(peers.TARGETS) <= set(peers.PEER_SCENES)       # every target names a scene the bench runs


def test_compare_images():
    a = np.zeros((2, 2, 4), np.uint8)
    b = a.copy()
    b[0, 0, 0] = 1          # within 1/255
    b[1, 1, 2] = 9          # beyond
    b[1, 0, 3] = 200        # alpha is not compared
    d = peers.compare_images(a, b)
    assert d["max_abs"] == 9 and d["pixels_differing"] == 2
    assert d["share_differing"] == 0.5 and d["share_over_1"] == 0.25
    assert d["mean_abs"] == pytest.approx(10 / 12)


def test_triangle_ids_survive_8_bits():
    rgb = peers._id_colors(70000)[::3]
    image = np.rint(rgb * 255).astype(np.uint8)
    assert np.array_equal(peers._ids(image), np.arange(1, 70001))


def test_no_moderngl_is_a_skip_with_the_reason(monkeypatch):
    monkeypatch.setitem(sys.modules, "moderngl", None)           # import moderngl raises ImportError
    ctx, why = peers.peer_context()
    assert ctx is None and "moderngl is not installed" in why and "pip install" in why


def test_no_context_is_a_skip_with_the_reason(monkeypatch):
    def refuse(**kwargs):
        raise Exception("libEGL.so: cannot open shared object file")
    monkeypatch.setitem(sys.modules, "moderngl", types.SimpleNamespace(create_standalone_context=refuse))
    ctx, why = peers.peer_context()
    assert ctx is None and "libEGL.so" in why and "libgl1-mesa-dri" in why


def test_main_skips_with_exit_status_0(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(peers, "peer_context", lambda: (None, "no Mesa here (test)"))
    out = tmp_path / "peers.json"
    assert peers.main(["fill", "--scale", "0.05", "--frames", "1", "--json", str(out)]) == 0
    assert "SKIPPED the llvmpipe comparison: no Mesa here (test)" in capsys.readouterr().out
    assert not out.exists()


def test_unknown_scene_is_refused():
    with pytest.raises(ValueError, match="no peer for scene"):
        peers.run(["bunny-shadows"])


# --------------------------------------------------------------------------
# With llvmpipe
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def llvmpipe():
    ctx, why = peers.peer_context()
    if ctx is None:
        pytest.skip(f"no llvmpipe peer: {why}")
    yield ctx
    ctx.release()


def test_clip_coordinate_scene_matches_llvmpipe_pixel_for_pixel(llvmpipe):
    """fill at 96x54 (50 triangles, depth LESS): every pixel shows the same triangle on both."""
    scene = peers.PEER_SCENES["fill"](0.05)
    coverage = peers.coverage_check(llvmpipe, scene)
    for label in ("positions_float64", "positions_float32"):
        assert coverage[label]["pixels_covered"] == scene.width * scene.height
        assert coverage[label]["pixels_other_triangle"] == 0, coverage


def test_one_light_row_agrees_with_llvmpipe(llvmpipe):
    """bunny-onelight at 128² on both: the minimal Blinn-Phong in GLSL and softpipe's user shader
    give the same picture to one level of 8 bits (float32 on llvmpipe, float64 here)."""
    report = peers.run(["bunny-onelight"], frames=1, scale=0.125, ctx=llvmpipe, log=lambda s: None)
    assert not report["failed"], report["failed"]
    d = report["scenes"][0]["image_difference"]
    assert d["max_abs"] <= 1 and d["share_over_1"] == 0.0, d


def test_a_round_on_both(llvmpipe, tmp_path):
    report = peers.run(["fill"], frames=2, scale=0.05, ctx=llvmpipe, log=lambda s: None)
    assert not report["failed"] and "llvmpipe" in report["peer"]["renderer"]
    row = report["scenes"][0]
    assert row["rounds"] == 2 and len(row["softpipe_frames_ms"]) == len(row["llvmpipe_frames_ms"]) == 2
    assert row["ratio"] == pytest.approx(row["softpipe_ms"] / row["llvmpipe_ms"])
    assert row["image_difference"]["max_abs"] <= 1       # interpolated colors: float32 vs float64, ±1 level
    json.dumps(report)
    assert "sp/llvm" in peers.format_table(report["scenes"])
