"""benchmarks.rays: the harness, tiny (a small model, 32² rays, one round), and its rays checked against softpipe's."""
from __future__ import annotations

import json

import numba
import numpy as np
import pytest

from benchmarks import rays
from softpipe.scenes.models import load_model
from softpipe.scenes.scene import Scene

MODEL, SIZE = "suzanne", 32
THREADS = [1, 2] if numba.config.NUMBA_NUM_THREADS >= 2 else [1]


def test_primary_rays_are_the_ray_tracers():
    """The numpy rays are softpipe.tracers.whitted._primary_ray's, pixel for pixel."""
    from softpipe.tracers.whitted import _primary_ray
    camera = Scene.from_model(MODEL, width=SIZE, height=SIZE).view_camera()
    o, d, far = rays.primary_rays(camera, SIZE, SIZE)
    assert o.shape == d.shape == (SIZE * SIZE, 3) and far.shape == (SIZE * SIZE,)
    unproject = np.linalg.inv(camera.projection(1.0) @ camera.view)
    for i, j in [(0, 0), (SIZE - 1, 0), (5, 17), (SIZE - 1, SIZE - 1)]:
        near, direction, length = _primary_ray(unproject, i + 0.5, j + 0.5, SIZE, SIZE)   # the pixel centre
        k = j * SIZE + i
        np.testing.assert_allclose(o[k], near, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(d[k], direction, rtol=1e-12, atol=1e-12)
        assert far[k] == pytest.approx(length, rel=1e-12)


def test_secondary_rays_leave_the_surface():
    mesh = load_model(MODEL)
    v = np.asarray(mesh.positions, np.float64)
    tri = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    camera = Scene.from_model(mesh, width=SIZE, height=SIZE).view_camera()
    o, d, far = rays.primary_rays(camera, SIZE, SIZE)
    bvh = rays.BVH.build(v, tri)
    ids, t, _ = bvh.closest(o, d, 0.0, far)
    light = v.max(axis=0) * 3.0
    s = rays.secondary_rays(v, tri, o, d, ids, t, light)
    n = int((ids >= 0).sum())
    assert n > 0 and s["points"].shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(s["shadow_dir"], axis=1), 1.0)
    np.testing.assert_allclose(np.linalg.norm(s["mirror_dir"], axis=1), 1.0)
    np.testing.assert_allclose(s["points"] + s["shadow_tmax"][:, None] * s["shadow_dir"], np.broadcast_to(light, (n, 3)))
    # a mirror ray goes back to the side the primary ray came from: d·n and r·n have opposite signs
    n_ = rays._geometric_normals(v, tri, ids[ids >= 0])
    assert np.all(np.sum(d[ids >= 0] * n_, axis=1) * np.sum(s["mirror_dir"] * n_, axis=1) <= 1e-12)


def _check(report, embree):
    assert report["size"] == SIZE and report["threads"] == THREADS and report["repeats"] == 1
    for key in ("date", "machine", "source", "embree_skipped", "load_at_end"):
        assert key in report
    (m,) = report["models"]
    assert m["model"] == MODEL and m["triangles"] > 0 and m["size"] == [SIZE, SIZE]
    assert m["rays"]["primary"] == SIZE * SIZE and m["rays"]["shadow"] == m["rays"]["secondary"] > 0
    assert m["rays"]["shadow-closest"] == m["rays"]["shadow"]          # the same rays, closest hit
    assert m["build_ms"]["softpipe"] > 0 and m["epsilon"] > 0 and len(m["light"]) == 3
    assert m["load_before"] is None or len(m["load_before"]) == 3
    for kind in rays.ALL_KINDS:
        r = m["kinds"][kind]
        assert r["rays"] == m["rays"][kind]
        for n in THREADS:
            assert r[f"softpipe_{n}t_mrays_s"] > 0 and len(r[f"softpipe_{n}t_seconds"]) == 1
            assert r[f"softpipe_{n}t_cpu_per_wall"] >= 0
        if embree:
            for n in THREADS:
                assert r[f"embree_{n}t_mrays_s"] > 0
                assert r[f"ratio_{n}t"] > 0 and r[f"ratio_{n}t_paired_median"] > 0
            a = r["agreement"]
            assert a["rays"] == r["rays"]
            differs = a["answer_differs"] if kind == "shadow" else a["triangle_differs"]
            assert differs <= 0.01, (kind, a)                   # ties at shared edges only
            if kind != "shadow":
                assert a["t_diff_max_over_diagonal"] < 1e-4, (kind, a)    # float32 against float64
        else:
            assert "agreement" not in r and "embree_1t_mrays_s" not in r
    table = rays.format_table(report)
    assert MODEL in table and all(k in table for k in rays.ALL_KINDS)
    assert ("Embree 1t M/s" in table) == embree
    json.dumps(report)


def test_harness_without_embree():
    threads = numba.get_num_threads()
    report = rays.run([MODEL], size=SIZE, threads=THREADS, repeats=1, embree=False, log=lambda s: None)
    assert numba.get_num_threads() == threads                  # restored
    assert report["embree_skipped"] == "--no-embree"
    _check(report, embree=False)


def test_harness_with_embree():
    why = rays.embree_status()
    if why is not None:
        pytest.skip(f"Embree part skipped: {why} (pip install embreex, or make bench-rays)")
    report = rays.run([MODEL], size=SIZE, threads=THREADS, repeats=1, embree=True, log=lambda s: None)
    assert report["embree_skipped"] is None
    _check(report, embree=True)


def test_command_line(tmp_path, capsys):
    out = tmp_path / "r.json"
    assert rays.main([MODEL, "--size", str(SIZE), "--repeats", "1", "--threads", "1", "--no-embree",
                      "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["threads"] == [1] and report["models"][0]["model"] == MODEL
    text = capsys.readouterr().out
    assert "softpipe 1t M/s" in text and "skipped" in text
    with pytest.raises(SystemExit):
        rays.main(["--threads", "0"])
