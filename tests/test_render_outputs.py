"""render(..., outputs=...): the buffers users read, each against geometry computed here (docs/outputs.md)."""
from __future__ import annotations

from collections import namedtuple

import numpy as np
import pytest
from conftest import run_cli

import softpipe as sp
from softpipe.pipeline.assembly import primitive_indices
from softpipe.pipeline.framebuffer import split_record
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.outputs import OUTPUTS, check_outputs
from softpipe.scenes.scene import Scene, SceneObject

W, H = 48, 36
Varyings = namedtuple("Varyings", ["color"])


def _pixel_rays(camera: sp.Camera, width: int, height: int):
    """Eye-space directions through every pixel centre [H, W, 3], and the projection."""
    proj = camera.projection(width / height)
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    x, y = 2 * cols / width - 1, 1 - 2 * rows / height
    far = np.stack([x, y, np.ones_like(x), np.ones_like(x)], axis=-1) @ np.linalg.inv(proj).T
    d = far[..., :3] / far[..., 3:]
    return d / np.linalg.norm(d, axis=-1, keepdims=True), proj


def _scene(*objects, camera, samples="1"):
    return Scene(objects=list(objects), camera=camera, width=W, height=H, samples=samples, cull="none")


def test_depth_of_a_tilted_plane_at_every_pixel():
    camera = sp.Camera(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fovy=40.0, near=0.5, far=20.0)
    model = sp.rotate_x(35.0) @ sp.rotate_x(90.0)       # the xz plane stood up (facing +z), then tilted
    plane = SceneObject("plane", sp.shapes.plane(size=40.0), model)
    out = sp.render(_scene(plane, camera=camera), outputs=("depth", "linear_depth"))
    # the plane in eye space: through the origin (3 in front of the eye) with the model's normal
    normal = (camera.view @ model @ np.array([0.0, 1.0, 0.0, 0.0]))[:3]
    point = (camera.view @ np.array([0.0, 0.0, 0.0, 1.0]))[:3]
    rays, proj = _pixel_rays(camera, W, H)
    t = (point @ normal) / (rays @ normal)
    eye = rays * t[..., None]
    clip = np.concatenate([eye, np.ones((H, W, 1))], axis=-1) @ proj.T
    window = 0.5 * clip[..., 2] / clip[..., 3] + 0.5
    assert out["depth"].shape == (H, W) and out["depth"].dtype == np.float32
    np.testing.assert_allclose(out["depth"], window, rtol=0, atol=1e-5)      # every pixel; a row is 2e-3
    np.testing.assert_allclose(out["linear_depth"], -eye[..., 2], rtol=1e-5)
    np.testing.assert_array_equal(out["depth"], out.framebuffer.depth)


def test_normals_of_a_sphere():
    camera = sp.Camera(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fovy=40.0)
    sphere = SceneObject("ball", sp.shapes.uv_sphere(1.0, segments=96, rings=48), np.eye(4))
    out = sp.render(_scene(sphere, camera=camera), outputs=("normal", "position", "object_id"))
    rays, _ = _pixel_rays(camera, W, H)
    # the ray from the eye (0, 0, 4) in world space (the view has no rotation) against the unit sphere
    eye = np.array([0.0, 0.0, 4.0])
    b = rays @ eye
    disc = b * b - (eye @ eye - 1.0)
    hit = disc > 0.05                                   # well inside the silhouette
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    expected = eye + rays * t[..., None]
    covered = out["object_id"] == 0
    assert (covered[hit]).all() and hit.sum() > 300
    np.testing.assert_allclose(out["normal"][hit], expected[hit], atol=0.02)
    np.testing.assert_allclose(np.linalg.norm(out["normal"][covered], axis=-1), 1.0, atol=1e-5)
    np.testing.assert_allclose(out["position"][hit], expected[hit], atol=0.01)
    assert np.isnan(out["normal"][~covered]).all() and (out["object_id"][~covered] == -1).all()


def _projected(fb, draws, which, instance, primitive, rows, cols, bary):
    """Σ b_i·clip_i of the recorded source triangle at pixels (rows, cols), in window coordinates."""
    got = []
    for r, c in zip(rows, cols):
        d = draws[which[r, c]]
        corners = primitive_indices(d.call.topology, d.call.indices, d.vertices_per_instance)[primitive[r, c]]
        clip = d.clip[instance[r, c] * d.vertices_per_instance + corners]
        p = bary[r, c].astype(np.float64) @ clip
        got.append(((p[0] / p[3] + 1) * fb.width / 2, (p[1] / p[3] + 1) * fb.height / 2))
    return np.array(got)


def test_barycentrics_reproduce_the_pixel_centre():
    out = sp.render("teapot", width=W, height=H, outputs=("barycentrics", "triangle_id"))
    fb = out.framebuffer
    which, instance, primitive = split_record(fb.record[0], fb.recorded_draws)
    rows, cols = np.nonzero(out["triangle_id"] >= 0)
    assert len(rows) > 200
    b = out["barycentrics"]
    np.testing.assert_allclose(b[rows, cols].sum(axis=1), 1.0, atol=1e-5)
    got = _projected(fb, fb.recorded_draws, which, instance, primitive, rows, cols, b)
    np.testing.assert_allclose(got, np.stack([cols + 0.5, H - rows - 0.5], axis=1), atol=1e-3)
    assert np.isnan(b[out["triangle_id"] < 0]).all()


def test_a_clipped_triangle_keeps_its_source_barycentrics():
    # one triangle from behind the eye to far in front: the near plane cuts it into pieces
    camera = sp.Camera(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fovy=60.0, near=0.5, far=50.0)
    mesh = sp.Mesh(np.array([[-6.0, -1.0, 2.0], [6.0, -1.0, 2.0], [0.0, 0.5, -30.0]]), np.array([[0, 1, 2]]))
    results: list = []
    out = sp.render(_scene(SceneObject("tri", mesh, np.eye(4)), camera=camera), results=results,
                    outputs=("barycentrics", "triangle_id", "position"))
    assert results[0].primitives.clipped.any()          # the triangle was cut
    fb = out.framebuffer
    which, instance, primitive = split_record(fb.record[0], fb.recorded_draws)
    rows, cols = np.nonzero(out["triangle_id"] == 0)
    assert len(rows) > 100
    b = out["barycentrics"][rows, cols].astype(np.float64)
    np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-5)
    got = _projected(fb, fb.recorded_draws, which, instance, primitive, rows, cols, out["barycentrics"])
    np.testing.assert_allclose(got, np.stack([cols + 0.5, H - rows - 0.5], axis=1), atol=1e-3)
    # relative to the mesh's own corners: they give the position back
    np.testing.assert_allclose(b @ mesh.positions, out["position"][rows, cols], atol=1e-3)


def test_object_ids_equal_each_objects_own_coverage():
    camera = sp.Camera(eye=(0.0, 0.5, 5.0), target=(0.0, 0.0, 0.0), fovy=45.0)
    a = SceneObject("cube", sp.shapes.cube(1.2), sp.translate(-0.5, 0.0, 0.0) @ sp.rotate_y(30.0))
    b = SceneObject("ball", sp.shapes.icosphere(0.8, 3), sp.translate(0.6, 0.1, 0.6))
    c = SceneObject("floor", sp.shapes.plane(6.0), sp.translate(0.0, -0.8, 0.0))
    ids = sp.render(_scene(a, b, c, camera=camera), outputs=("object_id",))["object_id"]
    depths = np.stack([sp.render(_scene(o, camera=camera)).depth for o in (a, b, c)])
    expected = np.where(depths.min(axis=0) < 1.0, np.argmin(depths, axis=0), -1)
    np.testing.assert_array_equal(ids, expected)
    assert set(np.unique(ids)) == {-1, 0, 1, 2}


def test_triangle_ids_equal_the_traces_winner():
    results: list = []
    out = sp.render("teapot", width=W, height=H, trace=True, results=results, outputs=("triangle_id",))
    trace = results[0].trace
    expected = np.full((H, W), -1)
    written = trace.written()
    for y in range(H):
        for x in range(W):
            here = trace.at(x, y)
            won = here[written[here]]
            if len(won):
                expected[y, x] = trace.fragments.primitive_id[won[-1]]
    np.testing.assert_array_equal(out["triangle_id"], expected)
    assert (expected >= 0).sum() > 200


@pytest.mark.parametrize("samples", ["1", "rgss4"])
def test_both_back_ends_give_the_same_record(samples):
    from softpipe.pipeline.sampling import pattern_named
    camera = sp.Camera(eye=(0.3, 0.4, 3.0), target=(0.0, 0.0, 0.0))
    mesh = sp.shapes.icosphere(1.0, 2)
    records = []
    for path in ("reference", "fast"):
        fb = sp.Framebuffer(W, H, pattern_named(samples), record=True)
        draw_mesh(fb, sp.shapes.plane(3.0), camera, "phong", model=sp.rotate_x(70.0), path=path, cull="none")
        draw_mesh(fb, mesh, camera, "phong", path=path)
        records.append(fb.record.copy())
    np.testing.assert_array_equal(records[0], records[1])
    assert (records[0] >= 0).any() and (records[0] == -1).any()


def test_a_framebuffer_without_a_record_keeps_none_and_a_clear_forgets_it():
    fb = sp.Framebuffer(4, 4)
    assert fb.record is None and fb.recorded_draws == []
    fb = sp.Framebuffer(4, 4, record=True)
    sp.draw(fb, np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1.0]]), varyings={"color": np.ones((3, 3))})
    assert (fb.record == 0).all() and len(fb.recorded_draws) == 1
    fb.clear()
    assert (fb.record == -1).all() and fb.recorded_draws == []


def test_instances_are_named_in_the_record():
    fb = sp.Framebuffer(8, 4, record=True)
    quad = np.array([[-1, -1, 0], [0, -1, 0], [-1, 1, 0], [0, 1, 0.0]])

    def vs(attributes, uniforms):
        p = attributes.position
        return (p[0] + attributes.shift, p[1], p[2], 1.0), Varyings((1.0, 1.0, 1.0))

    sp.draw(fb, quad, np.array([[0, 1, 2], [2, 1, 3]]), vertex_shader=vs, instances=2,
            instance_attributes={"shift": np.array([[0.0], [1.0]])})
    _, instance, primitive = split_record(fb.record[0], fb.recorded_draws)
    assert (instance[:, :4] == 0).all() and (instance[:, 4:] == 1).all()
    assert set(np.unique(primitive)) == {0, 1}


def test_render_without_outputs_is_unchanged_and_the_colour_is_the_pictures():
    plain = sp.render("suzanne", width=W, height=H)
    out = sp.render("suzanne", width=W, height=H, outputs=OUTPUTS)
    assert isinstance(plain, sp.Framebuffer) and plain.record is None
    np.testing.assert_array_equal(np.asarray(out.framebuffer), np.asarray(plain))
    np.testing.assert_array_equal(out["color"], plain.color)
    assert out.names == OUTPUTS
    shown = out["object_id"] >= 0
    np.testing.assert_array_equal(out["depth"][~shown], 1.0)
    np.testing.assert_allclose(out["albedo"][shown], np.broadcast_to(sp.Material().kd, (shown.sum(), 3)), atol=1e-6)
    assert np.isnan(out["uv"][~shown]).all()


def test_bad_output_names_are_refused_with_the_accepted_ones():
    with pytest.raises(ValueError) as e:
        sp.render("cube", width=8, height=8, outputs=("depth", "foo"))
    assert str(e.value) == ("outputs: unknown output 'foo'; the outputs are color, depth, linear_depth, position, "
                            "normal, object_id, triangle_id, barycentrics, uv, albedo")
    with pytest.raises(ValueError, match="depth named more than once"):
        check_outputs("depth,depth")


def test_the_cli_writes_every_output_and_they_load(capsys, tmp_path):
    from PIL import Image
    image = tmp_path / "suzanne.png"
    code, out, err = run_cli(capsys, "render", "suzanne", "--size", f"{W}x{H}", "--outputs", "depth,normal,object_id",
                             "-o", image)
    assert code == 0, err
    expected = sp.render("suzanne", width=W, height=H, outputs=("depth", "normal", "object_id"))
    for name in ("depth", "normal", "object_id"):
        a = np.load(tmp_path / f"suzanne.{name}.npy")
        np.testing.assert_array_equal(a, expected[name])
        picture = np.asarray(Image.open(tmp_path / f"suzanne.{name}.png"))
        assert picture.shape == (H, W, 3)
        assert (picture[expected["object_id"] < 0] == 0).all()         # the background is black
        assert f"suzanne.{name}.npy" in out and f"suzanne.{name}.png" in out
    assert image.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []   # no temporary files left


def test_the_cli_refuses_an_unknown_output_before_rendering(capsys, tmp_path):
    code, out, err = run_cli(capsys, "render", "cube", "--outputs", "depth,foo", "-o", tmp_path / "x.png")
    assert code == 2
    assert ("argument --outputs: unknown output 'foo'; the outputs are color, depth, linear_depth, position, "
            "normal, object_id, triangle_id, barycentrics, uv, albedo") in err
    assert list(tmp_path.iterdir()) == []


def test_a_batch_job_writes_its_outputs_and_lists_them_in_the_manifest(tmp_path):
    import json

    from softpipe.tools.batch import batch, parse_job
    job = parse_job('[job]\noutputs = ["depth", "object_id"]\n[sweep]\nmodels = ["suzanne"]\n'
                    'cameras = [0, 90]\nsizes = ["32x24"]\n', "job.toml")
    result = batch(job, tmp_path, scheduler="serial", contact_sheet=False)
    assert result.ok and len(result.done) == 2
    lines = [json.loads(line) for line in (tmp_path / "manifest.jsonl").read_text().splitlines()]
    for frame, line in zip(job.frames, lines):
        assert sorted(line["outputs"]) == ["depth.npy", "depth.png", "object_id.npy", "object_id.png"]
        expected = sp.render("suzanne", width=32, height=24, azimuth=frame.azimuth, outputs=("depth", "object_id"))
        for name in ("depth", "object_id"):
            listed = line["outputs"][f"{name}.npy"]
            assert listed["file"] == f"{frame.name}.{name}.npy"
            np.testing.assert_array_equal(np.load(tmp_path / listed["file"]), expected[name])
    again = batch(job, tmp_path, scheduler="serial", contact_sheet=False)
    assert len(again.skipped) == 2
    (tmp_path / f"{job.frames[0].name}.depth.npy").unlink()          # a missing output renders its frame again
    assert [n for n, _ in batch(job, tmp_path, scheduler="serial", contact_sheet=False).rerendered] == \
        [job.frames[0].name]


def test_a_batch_job_refuses_unknown_outputs():
    from softpipe.tools.batch import JobError, parse_job
    with pytest.raises(JobError) as e:
        parse_job('[job]\noutputs = ["depth", "segmentation"]\n[sweep]\nmodels = ["suzanne"]\n', "job.toml")
    assert str(e.value) == ("job.toml: key 'outputs' in [job] must name outputs among color, depth, linear_depth, "
                            "position, normal, object_id, triangle_id, barycentrics, uv, albedo; 'segmentation' is "
                            "not one")


def test_albedo_of_a_textured_model_is_kd_times_the_texture_at_uv():
    from softpipe.light.texture import texture_lod
    out = sp.render("spot", width=W, height=H, outputs=("albedo", "uv", "object_id"))
    draw = out.framebuffer.recorded_draws[0]
    kd = np.asarray(draw.call.uniforms.material.kd)
    rows, cols = np.nonzero(out["object_id"] == 0)
    assert len(rows) > 200
    for r, c in zip(rows[::7], cols[::7]):
        u, v = (float(t) for t in out["uv"][r, c])
        expected = kd * np.asarray(texture_lod(draw.call.uniforms.texture, (u, v), 0.0))[:3]
        np.testing.assert_allclose(out["albedo"][r, c], expected, rtol=1e-6)
    assert len(np.unique(out["albedo"][rows, cols], axis=0)) > 20       # the texture shows, not kd alone


def test_lines_have_ids_and_depth_but_no_surface():
    camera = sp.Camera(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fovy=40.0)
    positions = np.array([[-2, -2, 0], [2, -2, 0], [-2, 2, 0], [-1, 0, 1], [1, 0, 1.0]])
    mesh = sp.Mesh(positions, np.array([[0, 1, 2]]), lines=np.array([[3, 4]]))
    out = sp.render(_scene(SceneObject("tri", mesh, np.eye(4)), camera=camera),
                    outputs=("object_id", "triangle_id", "barycentrics", "linear_depth", "albedo"))
    line = (out["object_id"] == 0) & (out["triangle_id"] == -1)
    assert line.sum() >= 20                              # the segment's pixels, in front of the triangle
    assert np.isnan(out["barycentrics"][line]).all()
    np.testing.assert_allclose(out["linear_depth"][line], 2.0, rtol=1e-6)    # 1 in front of the origin
    np.testing.assert_allclose(out["albedo"][line], np.broadcast_to(mesh.material.kd, (line.sum(), 3)))
    assert (out["triangle_id"] == 0).sum() > 100
