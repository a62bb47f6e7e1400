"""The benchmark harness runs: every scene once, tiny, through the same code as ``make bench``.

Benchmarks are not tests: nothing here looks at a time. This only keeps
``benchmarks/`` from rotting (issue 6): every scene builds and renders, every
result row has its fields, every image shows something.
"""
import json
import os
import re
import subprocess
import sys

import numba
import numpy as np
import pytest
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from benchmarks import run as bench  # noqa: E402
from benchmarks import scenes  # noqa: E402

SCALE = 0.04


def _git_head():
    """The repository's HEAD as 40 hex digits, or None outside a git checkout (or without git)."""
    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    head = done.stdout.strip()
    return head if done.returncode == 0 and re.fullmatch(r"[0-9a-f]{40}", head) else None


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """One run of the command line over all scenes at a tiny size, one warm frame, one thread."""
    out = tmp_path_factory.mktemp("bench")
    threads_before = numba.get_num_threads()
    heads = [_git_head()]  # HEAD before and after the run: someone may commit meanwhile
    built = {}             # each scene's size and clear color as the run built it (not built again to check them)

    def build_scene(name, scale):
        scene = original(name, scale)
        built[name, scale] = (scene.width, scene.height, tuple(scene.clear_color))
        return scene
    original = bench.build_scene
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(bench, "build_scene", build_scene)
        code = bench.main(["--scale", str(SCALE), "--frames", "1", "--threads", "1", "--budget", "0",
                           "--json", str(out / "bench.json"), "--save-images", str(out / "images")])
    heads.append(_git_head())
    data = json.loads((out / "bench.json").read_text())
    data["_heads"], data["_built"] = heads, built
    assert not data["failed"], "\n\n".join(f["traceback"] for f in data["failed"])
    assert code == 0
    assert numba.get_num_threads() == threads_before, "the harness must restore numba's thread count"
    return data, out / "images"


def test_every_scene_runs_and_reports_every_field(report):
    data, _ = report
    assert [r["scene"] for r in data["scenes"]] == list(scenes.SCENES)
    for row in data["scenes"]:
        assert set(bench.ROW_FIELDS) <= set(row), f"{row['scene']}: missing {set(bench.ROW_FIELDS) - set(row)}"
        assert row["triangles"] > 0 and row["fragments"] > 0 and row["pixels_drawn"] > 0, row["scene"]
        assert row["warm_frames"] == 1 and len(row["frames_ms"]) == 1
        assert row["min_ms"] <= row["median_ms"] <= row["max_ms"]
        assert row["first_ms"] > 0 and row["peak_rss_mb"] > 0
        assert row["threads"] == 1
        assert set(bench.STAGES) <= set(row["stages_ms"]), row["stages_ms"]
        assert row["triangles_per_s"] > 0 and row["shaded_pixels_per_s"] > 0
        assert row["target_ms"] is None  # targets apply to the full-size scenes only
    assert data["threads"]["numba_threads"] == 1
    assert data["settings"] == {"frames": 1, "scale": SCALE, "budget_s": None, "scaling": False}
    for key in ("nproc", "cpu_model", "python", "numba"):
        assert data["machine"][key]
    for row in data["scenes"]:
        assert row["shading"] and row["path"] in ("reference", "fast", "fast/reference")


def test_the_source_is_the_checked_out_commit(report):
    """In a git checkout the report names HEAD (abbreviated: ``git rev-parse --short``); elsewhere None."""
    data, _ = report
    source, heads = data["source"], data["_heads"]
    if heads == [None, None]:
        assert source["commit"] is None
        return
    commit = source["commit"]
    assert isinstance(commit, str) and re.fullmatch(r"[0-9a-f]{7,40}", commit), commit
    assert any(head and head.startswith(commit) for head in heads), f"{commit} is not HEAD ({heads})"
    changed = source["softpipe_files_changed_since"]
    assert isinstance(changed, int) and changed >= 0


def test_every_image_shows_something(report):
    data, images = report
    for row in data["scenes"]:
        width, height, clear_color = data["_built"][row["scene"], SCALE]     # as scenes.build_scene made it
        pixels = np.asarray(Image.open(images / f"{row['scene']}.png"))
        assert pixels.shape == (height, width, 3)
        clear = np.rint(np.asarray(clear_color[:3]) * 255).astype(np.uint8)
        drawn = np.any(pixels != clear, axis=-1)
        assert drawn.mean() > 0.05, f"{row['scene']}: only {drawn.sum()} pixels differ from the clear color"


def test_tables_name_every_scene_and_stage(report):
    data, _ = report
    text = bench.format_tables(data["scenes"])
    for name in scenes.SCENES:
        assert name in text
    for title in ("vertex", "assembly+clip", "setup+bin", "raster", "shading", "merge"):
        assert title in text


def test_scenes_are_deterministic_and_scale():
    a, b = scenes.build_scene("fill", SCALE), scenes.build_scene("fill", SCALE)
    assert np.array_equal(a.draws[0]["positions"], b.draws[0]["positions"])
    b2f = scenes.build_scene("fill-b2f", SCALE)
    z = b2f.draws[0]["positions"][::3, 2]
    assert np.all(np.diff(z) < 0), "fill-b2f must draw strictly back to front"
    assert sorted(z.tolist()) == sorted(a.draws[0]["positions"][::3, 2].tolist())
    assert scenes.build_scene("tiny", SCALE).triangles == round(1000 * SCALE) ** 2


def test_a_missing_asset_says_where_it_was_looked_for(monkeypatch):
    monkeypatch.setattr(scenes, "ASSETS", "../no-such-assets")
    with pytest.raises(scenes.AssetMissing, match=r"no-such-assets/stanford-bunny\.obj"):
        scenes.build_scene("bunny", SCALE)


def test_unknown_scene_is_refused():
    with pytest.raises(ValueError, match="sphere200k"):
        bench.run(["no-such-scene"])


def test_lit_scenes_fall_back_to_their_own_shaders(monkeypatch):
    """Without the built-in programs the lit scenes still render, with the shaders of benchmarks.scenes."""
    def missing(name):
        raise ValueError(f"unknown shading program {name!r}")
    monkeypatch.setattr(scenes, "get_program", missing)
    for name in ("sphere200k", "spot-textured"):   # bunny's fallback differs from sphere200k's by one constant
        row = bench.run_scene(name, frames=1, scale=SCALE, budget=None, keep_image=True, log=lambda s: None)
        assert "benchmarks.scenes" in row["shading"]
        assert any("not available" in n for n in row["notes"])
        assert row["pixels_drawn"] > 0 and row["fragments"] > 0
    assert any("not trilinear" in n for n in row["notes"])


def test_shading_cost_splits_the_lit_scenes(capsys):
    """benchmarks.shading_cost runs on both lit scenes, small, and reports each part."""
    from benchmarks import shading_cost
    assert shading_cost.main(["--runs", "1", "--scale", "0.05"]) == 0
    out = capsys.readouterr().out
    for name in shading_cost.LIT_SCENES:
        assert f"\n{name}: " in out
    assert out.count("ns/sample") == 4 * len(shading_cost.LIT_SCENES)
    row = shading_cost.measure("bunny", 1, 0.05)
    assert row["samples"] > 0 and min(row["constant"], row["varyings"], row["own"]) > 0
    with pytest.raises(SystemExit):
        shading_cost.main(["tiny"])        # not a lit scene: refused with a message


def test_the_shadowed_scene_times_its_maps_and_its_lit_pass(report):
    """bunny-shadows makes its shadow maps inside every frame and reports each map and the lit pass;
    bunny-plane is the same scene without them."""
    data, images = report
    rows = {r["scene"]: r for r in data["scenes"]}
    plain, shadowed = rows["bunny-plane"], rows["bunny-shadows"]
    assert plain["parts_ms"] == {} and plain["first_parts_ms"] == {}
    assert "prepare" not in plain["stages_ms"]
    parts = shadowed["parts_ms"]
    assert list(parts) == ["sun", "spot", "prepare (rest)", bench.LIT_PASS]
    assert all(v >= 0 for v in parts.values()) and parts["sun"] > 0 and parts["spot"] > 0
    assert set(shadowed["first_parts_ms"]) == set(parts)
    assert shadowed["stages_ms"]["prepare"] > 0           # the maps are part of the frame
    assert parts["sun"] + parts["spot"] <= shadowed["stages_ms"]["prepare"] * 1.0001 + 1e-6
    assert (plain["triangles"], plain["covered"], plain["fragments"]) == \
        (shadowed["triangles"], shadowed["covered"], shadowed["fragments"])   # the maps' draws are not counted
    text = bench.format_tables(data["scenes"])
    assert "median ms by part" in text and "lit pass" in text
    a = np.asarray(Image.open(images / "bunny-plane.png"), np.int16)
    b = np.asarray(Image.open(images / "bunny-shadows.png"), np.int16)
    darker = (b.sum(axis=-1) < a.sum(axis=-1) - 30).mean()
    assert darker > 0.01, f"bunny-shadows shows no shadow ({darker:.4f} of the pixels darker)"
    assert (b.sum(axis=-1) > a.sum(axis=-1) + 3).mean() == 0      # shadows only take light away


def test_the_shadow_maps_scale_with_the_scene():
    full = scenes.build_scene("bunny-shadows", 1.0)
    small = scenes.build_scene("bunny-shadows", SCALE)
    for scene, res in ((full, scenes.SHADOW_RESOLUTION), (small, round(scenes.SHADOW_RESOLUTION * SCALE))):
        lighting = scene.prepare.lighting
        assert [(l.name, l.kind, l.shadows.resolution, l.shadows.pcf) for l in lighting.lights] == \
            [("sun", "directional", res, 1), ("spot", "spot", res, 1)]
    assert scenes.build_scene("bunny-plane", SCALE).prepare is None


def test_the_cold_start_scripts_run_and_print_their_draws_time(capsys):
    """benchmarks.cold's timed scripts (README's stripes shader, the lit user program) run as written.

    Here in this process (the cold-start figures need fresh processes: ``make bench-cold``);
    each prints one positive number, the seconds of its timed draw.
    """
    from benchmarks import cold
    for script in (cold.STRIPES, cold.LIT.format(examples=os.path.join(ROOT, "examples"))):
        exec(compile(script, "<benchmarks.cold script>", "exec"), {"__name__": "cold_script"})
        assert float(capsys.readouterr().out.split()[-1]) > 0.0


def test_the_cold_start_report_says_which_targets_are_met():
    from benchmarks import cold
    table = cold.report({"render": [9.0, 9.5, 12.0], "stripes": [1.5, 1.6, 1.4], "lit": [1.0]})
    rows = {line.split("  ")[0]: line for line in table.splitlines()[1:]}
    assert rows[cold.LABELS["render"]].endswith("met") and " 9.50 " in rows[cold.LABELS["render"]]
    assert rows[cold.LABELS["stripes"]].endswith("1.50x")
    assert rows[cold.LABELS["lit"]].endswith("met")


def test_the_targets_between_scenes_are_their_medians_ratios_and_say_whether_met():
    def row(scene, median, peak=300.0, scale=1.0):
        return {"scene": scene, "median_ms": median, "peak_rss_mb": peak, "scale": scale}
    rows = [row("bunny", 10.0), row("bunny-outputs", 12.9), row("bunny-plane", 20.0),
            row("bunny-shadows", 32.2, peak=1100.0)]
    targets = {t["target"]: t for t in bench.target_rows(rows)}
    assert targets["bunny-outputs ÷ bunny ≤ 1.3"] == {"issue": 31, "target": "bunny-outputs ÷ bunny ≤ 1.3",
                                                       "measured": "1.29", "met": True}
    shadows = targets["bunny-shadows ÷ bunny-plane ≤ 1.6"]
    assert (shadows["measured"], shadows["met"]) == ("1.61", False)
    memory = targets["peak memory ≤ 1024 MB on every scene run"]
    assert (memory["measured"], memory["met"]) == ("1100 MB (bunny-shadows)", False)
    text = bench.format_targets(bench.target_rows(rows))
    assert "bunny-outputs ÷ bunny ≤ 1.3" in text and "NO" in text and "yes" in text
    # a pair is compared only when both scenes ran, at full size
    assert [t["issue"] for t in bench.target_rows([row("bunny", 10.0), row("bunny-outputs", 12.0, scale=0.5)])] == [35]
    assert bench.format_targets([]) == ""


def test_a_target_between_scenes_is_judged_by_their_frames_drawn_in_turns(monkeypatch):
    """paired_ratio draws the two scenes in turns (A B, then B A), each turn's first frame not counted;
    the target reads the median of the pairs' ratios and shows the medians' ratio beside it."""
    scene, baseline = scenes.build_scene("bunny-outputs", SCALE), scenes.build_scene("bunny", SCALE)
    drawn = []
    real = bench.render_frame

    def counting(sc, fb, *args, **kwargs):
        drawn.append((sc.name, fb.record is not None))
        return real(sc, fb, *args, **kwargs)
    monkeypatch.setattr(bench, "render_frame", counting)
    p = bench.paired_ratio(scene, baseline, pairs=3, block=2)
    # one untimed frame each, then turns of 2: A A B B, B B A A, A A B B; each draws into its own framebuffer
    names = [n for n, _ in drawn]
    assert names == ["bunny-outputs", "bunny"] + ["bunny-outputs"] * 2 + ["bunny"] * 4 + ["bunny-outputs"] * 4 + \
        ["bunny"] * 2
    assert all(record == (n == "bunny-outputs") for n, record in drawn)
    assert (p["scene"], p["baseline"], p["pairs"], p["block"], len(p["ratios"])) == ("bunny-outputs", "bunny", 3, 2, 3)
    assert all(r > 0 for r in p["ratios"]) and p["low"] <= p["ratio"] <= p["high"]
    assert p["ratio"] == float(np.median(p["ratios"]))
    with pytest.raises(ValueError, match="block at least 2"):
        bench.paired_ratio(scene, baseline, pairs=1, block=1)

    def row(name, median):
        return {"scene": name, "median_ms": median, "peak_rss_mb": 300.0, "scale": 1.0}
    paired = [{"scene": "bunny-outputs", "baseline": "bunny", "pairs": 15, "block": 4, "ratio": 1.27, "low": 1.25,
               "high": 1.29, "ratios": []}]
    target = bench.target_rows([row("bunny", 10.0), row("bunny-outputs", 13.4)], paired)[0]
    assert target == {"issue": 31, "target": "bunny-outputs ÷ bunny ≤ 1.3", "met": True,
                      "measured": "1.27 (median of 15 pairs of turns, quartiles 1.25–1.29); medians' ratio 1.34"}


def test_scaling_times_as_many_frames_on_one_thread_and_the_target_names_the_misses():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        row = bench.run_scene("bunny", frames=2, scale=SCALE, budget=None, log=lambda s: None, scaling=True)
        assert numba.get_num_threads() == 2                      # put back after the 1-thread frames
    finally:
        numba.set_num_threads(before)
    assert row["one_thread_ms"] > 0 and row["scaling"] > 0 and row["warm_frames"] == 2
    assert "1 thread ms" in bench.format_tables([row])
    rows = [dict(row, scene="a", scaling=1.9), dict(row, scene="b", scaling=1.2), dict(row, scene="c", scaling=1.5)]
    target = [t for t in bench.target_rows(rows) if t["target"].startswith("2 threads")][0]
    assert target["measured"] == "1 of 3 scenes; below: b 1.20, c 1.50" and target["met"] is False
    plain = bench.run_scene("bunny", frames=1, scale=SCALE, budget=None, log=lambda s: None)
    assert plain["scaling"] is None and "1 thread ms" not in bench.format_tables([plain])
