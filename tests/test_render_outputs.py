"""render(..., outputs=...): the buffers users read, each against geometry computed here (docs/outputs.md)."""
from __future__ import annotations

from collections import namedtuple
from typing import Dict, Sequence, Tuple

import numba
import numpy as np
import pytest
from conftest import run_cli

import softpipe as sp
from softpipe.light.texture import texture_lod
from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES, primitive_indices
from softpipe.pipeline.framebuffer import Framebuffer, RecordedDraw, split_record
from softpipe.pipeline.transforms import normal_matrix
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.outputs import OUTPUTS, check_outputs, derive_outputs
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


def test_the_colour_alone_derives_nothing(monkeypatch):
    """outputs=("color",) is the framebuffer's color: no record is kept, and the pass over it does not run."""
    import softpipe.scenes.derive as derive

    def refused(*args, **kwargs):
        raise AssertionError("the derive pass ran for the color alone")
    plain = sp.render("suzanne", width=W, height=H)
    monkeypatch.setattr(derive, "_derive_rows", refused)
    out = sp.render("suzanne", width=W, height=H, outputs=("color",))
    assert out.names == ("color",) and out.framebuffer.record is None
    np.testing.assert_array_equal(out["color"], plain.color)


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


# ------------------------------------------------------------------ the compiled pass against the numpy one
#
# The oracle: the numpy derivation the compiled pass replaced (softpipe/scenes/outputs.py at a716091),
# kept here as it was (only renamed), to check that every buffer keeps its bits. It lives in the tests,
# not as a reference= mode of the module: the pipeline's reference path teaches the stages, while
# this one's only job now is to hold the compiled pass to the old values.

def _oracle_pixel_sample(fb: Framebuffer) -> Tuple[np.ndarray, np.ndarray]:
    """Each pixel's record value and depth, from its sample of least depth (the first of equals)."""
    depth, record = fb.samples_depth, fb.record
    assert record is not None                   # render made the framebuffer with record=True
    if fb.samples == 1:
        return record[0].copy(), depth[0].copy()
    pick = np.argmin(depth, axis=0)[None]
    return (np.take_along_axis(record, pick, axis=0)[0],
            np.take_along_axis(depth, pick, axis=0)[0].copy())


def _oracle_uniform_matrix(call, name: str) -> np.ndarray:
    value = getattr(call.uniforms, name, None)
    m = np.eye(4) if value is None else np.asarray(value, np.float64)
    return m if m.shape == (4, 4) else np.eye(4)


def _oracle_albedo_of(call) -> np.ndarray:
    """The draw's kd: its ``material`` uniform's, else its ``color`` uniform, else white."""
    material = getattr(call.uniforms, "material", None)
    kd = getattr(material, "kd", None)
    if kd is None:
        kd = getattr(call.uniforms, "color", (1.0, 1.0, 1.0))
    kd = np.asarray(kd, np.float64).ravel()
    return kd[:3] if kd.size >= 3 else np.ones(3)


@numba.njit
def _oracle_sample_texture(tex, uv, out):
    """The texture at each uv, level of detail 0 (what ``texture(uv)`` gives without derivatives)."""
    for k in range(uv.shape[0]):
        c = texture_lod(tex, (uv[k, 0], uv[k, 1]), 0.0)
        out[k, 0], out[k, 1], out[k, 2] = c[0], c[1], c[2]


def _oracle_barycentrics(clip: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Perspective-correct barycentrics [n, 3] at NDC points (x, y) of triangles with clip corners [n, 3, 4].

    The point Σ b_i·clip_i lies on the pixel's ray when Σ b_i (x_i − X·w_i) = 0 and
    Σ b_i (y_i − Y·w_i) = 0: b is the cross product of those two rows, normalized to sum 1
    (b_i ∝ e_i/w_i). NaN for a triangle seen edge-on.
    """
    r1 = clip[:, :, 0] - x[:, None] * clip[:, :, 3]
    r2 = clip[:, :, 1] - y[:, None] * clip[:, :, 3]
    b = np.cross(r1, r2)
    total = b.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total != 0, b / np.where(total != 0, total, 1.0), np.nan)


def _oracle_triangle_maps(objects: Sequence, draws: Sequence[RecordedDraw]) -> Dict[int, np.ndarray]:
    """For each recorded draw of triangles, its triangles' indices in its object's whole mesh: a mesh of
    several materials is drawn once per material (``Mesh.by_material``), each draw numbering its own."""
    maps: Dict[int, np.ndarray] = {}
    for k, obj in enumerate(objects):
        mesh = obj.mesh
        mine = [i for i, d in enumerate(draws) if d.tag == k and d.kind == "triangles"
                and d.call.topology in TRIANGLE_TOPOLOGIES]
        if getattr(mesh, "material_ids", None) is None:
            continue
        parts = [np.flatnonzero(mesh.material_ids == m) for m in range(len(mesh.materials))]
        parts = [p for p in parts if len(p)]
        for i, part in zip(mine, parts):
            maps[i] = part
    return maps


def _numpy_derive_outputs(fb: Framebuffer, names: Sequence[str], objects: Sequence = ()) -> Dict[str, np.ndarray]:
    """The buffers ``names`` (:data:`OUTPUTS`) of a framebuffer drawn with a visibility record.

    Parameters
    ----------
    fb : Framebuffer
        Drawn with ``record=True``; its :attr:`~Framebuffer.recorded_draws` carry the draws'
        inputs, and their ``tag`` the index of the object each draw belongs to (a draw
        without one is object k, k its place among the frame's draws).
    names : sequence of str
        Checked by :func:`check_outputs`.
    objects : sequence of SceneObject
        The scene's drawn objects, in the order of the tags (for a mesh of several
        materials, the triangle ids count over the whole mesh).

    Returns
    -------
    dict name → array, in the order of ``names`` (docs/outputs.md).
    """
    names = check_outputs(names)
    if fb.record is None:
        raise ValueError("derive_outputs needs a framebuffer drawn with a visibility record: "
                         "Framebuffer(width, height, record=True)")
    h, w = fb.height, fb.width
    value, depth = _oracle_pixel_sample(fb)
    draws = fb.recorded_draws
    which, instance, primitive = split_record(value, draws)
    shown = which >= 0
    want = set(names)
    out: Dict[str, np.ndarray] = {}
    nan3 = np.full((h, w, 3), np.nan, np.float32)
    object_id = np.full((h, w), -1, np.int32)
    triangle_id = np.full((h, w), -1, np.int32)
    bary, position, normal, albedo = nan3.copy(), nan3.copy(), nan3.copy(), nan3.copy()
    uv = np.full((h, w, 2), np.nan, np.float32)
    linear = np.full((h, w), np.nan, np.float32)
    maps = _oracle_triangle_maps(objects, draws) if objects else {}
    geometric = want & {"barycentrics", "position", "normal", "uv", "albedo", "linear_depth"}
    # the covered pixels grouped by draw (one sort, not one pass over the image per draw)
    flat = np.flatnonzero(shown)
    flat = flat[np.argsort(which.reshape(-1)[flat], kind="stable")]
    kinds, starts = np.unique(which.reshape(-1)[flat], return_index=True)
    for k, group in zip(kinds, np.split(flat, starts[1:])):
        d = draws[int(k)]
        rows, cols = np.divmod(group, w)
        # a scene's draws name their object; a draw made by hand is its own object, by its place in the frame
        tag = int(d.tag) if isinstance(d.tag, (int, np.integer)) else int(k)
        object_id[rows, cols] = tag
        triangles = d.kind == "triangles" and d.call.topology in TRIANGLE_TOPOLOGIES
        prim = primitive[rows, cols]
        if d.call.topology in TRIANGLE_TOPOLOGIES:       # edges and corners in a polygon mode name their triangle
            triangle_id[rows, cols] = maps[int(k)][prim] if int(k) in maps else prim
        if not geometric:
            continue
        call = d.call
        kd = _oracle_albedo_of(call)
        albedo[rows, cols] = kd
        model_view = _oracle_uniform_matrix(call, "model_view")
        corners = primitive_indices(call.topology, call.indices, d.vertices_per_instance)[prim]
        inst = instance[rows, cols]
        clip = d.clip[inst[:, None] * d.vertices_per_instance + corners]      # [n, 3, 4]
        if not triangles:
            # a line or point has no surface: its eye depth from the clip w of its first corner
            linear[rows, cols] = clip[:, 0, 3]
            continue
        vp = call.viewport
        x = 2.0 * (cols + 0.5 - vp.x) / vp.width - 1.0
        y = 2.0 * (h - rows - 0.5 - vp.y) / vp.height - 1.0
        b = _oracle_barycentrics(clip, x, y)
        bary[rows, cols] = b
        p = np.asarray(call.positions, np.float64)
        p = np.concatenate([p[:, :3], np.ones((len(p), 1))], axis=1) if p.shape[1] >= 3 else \
            np.concatenate([p, np.zeros((len(p), 3 - p.shape[1])), np.ones((len(p), 1))], axis=1)
        local = np.einsum("nc,ncj->nj", b, p[corners])                       # object space, w = 1
        view = _oracle_uniform_matrix(call, "view")
        model = np.linalg.solve(view, model_view)
        eye = local @ model_view.T
        linear[rows, cols] = -eye[:, 2]
        position[rows, cols] = (local @ model.T)[:, :3]
        attributes = call.attributes or {}
        if "normal" in attributes:
            n = np.einsum("nc,ncj->nj", b, np.asarray(attributes["normal"], np.float64)[corners])
            n = n @ normal_matrix(model).T
            length = np.linalg.norm(n, axis=1, keepdims=True)
            with np.errstate(divide="ignore", invalid="ignore"):
                normal[rows, cols] = n / length
        if "uv" in attributes:
            t = np.einsum("nc,ncj->nj", b, np.asarray(attributes["uv"], np.float64)[corners])
            uv[rows, cols] = t
            texture = getattr(call.uniforms, "texture", None)
            if texture is not None and hasattr(texture, "texels") and "albedo" in want:
                sampled = np.zeros((len(t), 3))
                good = np.isfinite(t).all(axis=1)
                _oracle_sample_texture(texture, np.ascontiguousarray(t[good]), sampled[: int(good.sum())])
                albedo[rows[good], cols[good]] = kd * sampled[: int(good.sum())]
    depth = np.where(shown, depth, np.float32(1.0)).astype(np.float32)
    made = {"color": lambda: fb.color.copy(), "depth": lambda: depth, "linear_depth": lambda: linear,
            "position": lambda: position, "normal": lambda: normal, "object_id": lambda: object_id,
            "triangle_id": lambda: triangle_id, "barycentrics": lambda: bary, "uv": lambda: uv,
            "albedo": lambda: albedo}
    for n in names:
        out[n] = made[n]()
    return out


def _assert_same_bits(name: str, got: np.ndarray, expected: np.ndarray) -> None:
    """The same dtype, shape and bytes: every number's bits, the sign of a zero and a NaN's included."""
    assert (got.dtype, got.shape) == (expected.dtype, expected.shape), name
    if got.tobytes() != expected.tobytes():
        differ = np.argwhere((got != expected) & ~(np.isnan(got) & np.isnan(expected)) if got.dtype.kind == "f"
                             else got != expected)
        where = tuple(differ[0]) if len(differ) else "(bits of equal numbers)"
        raise AssertionError(f"{name}: {len(differ)} values differ from the numpy derivation's, first at {where}")


@pytest.fixture
def derived_twice(monkeypatch):
    """render(..., outputs=...) with each frame's buffers derived twice, on the same framebuffer and
    objects: by the compiled pass (what render returns) and by the numpy oracle. Yields the pairs."""
    import softpipe.scenes.drawing as drawing
    pairs = _Pairs()

    def both(fb, names, objects=(), **options):
        deferred.append(fb.record_parts()[2] is not None)       # the last draw's samples not yet in fb.record
        got = derive_outputs(fb, names, objects, **options)
        pairs.append((got, _numpy_derive_outputs(fb, names, objects)))      # (reads fb.record: stores them)
        return got
    deferred: list = []
    pairs.deferred = deferred                    # type: ignore[attr-defined]
    monkeypatch.setattr(drawing, "derive_outputs", both)
    return pairs


class _Pairs(list):
    """The pairs of :func:`derived_twice`, and whether each frame's last draw was deferred."""


def _assert_pairs_agree(pairs) -> None:
    assert pairs
    for got, expected in pairs:
        assert list(got) == list(expected)
        for name in expected:
            _assert_same_bits(name, got[name], expected[name])


def _lines_and_points():
    camera = sp.Camera(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fovy=40.0)
    positions = np.array([[-2, -2, 0], [2, -2, 0], [-2, 2, 0], [-1, 0, 1], [1, 0, 1.0], [0.5, 0.5, 1.2]])
    mesh = sp.Mesh(positions, np.array([[0, 1, 2]]), lines=np.array([[3, 4]]), points=np.array([5]))
    return _scene(SceneObject("tri", mesh, np.eye(4)), camera=camera)


def _clipped():
    camera = sp.Camera(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fovy=60.0, near=0.5, far=50.0)
    mesh = sp.Mesh(np.array([[-6.0, -1.0, 2.0], [6.0, -1.0, 2.0], [0.0, 0.5, -30.0]]), np.array([[0, 1, 2]]))
    return _scene(SceneObject("tri", mesh, np.eye(4)), camera=camera)


def _objects(samples="1"):
    camera = sp.Camera(eye=(0.0, 0.5, 5.0), target=(0.0, 0.0, 0.0), fovy=45.0)
    cube = sp.shapes.cube(1.2)
    two = sp.Mesh(cube.positions, cube.indices, materials=(sp.Material(kd=(0.9, 0.1, 0.1)), sp.Material()),
                  material_ids=np.arange(len(cube.indices)) % 2)                # a mesh of two materials
    a = SceneObject("cube", two, sp.translate(-0.5, 0.0, 0.0) @ sp.rotate_y(30.0) @ sp.scale(1.0, 1.5, 0.7))
    b = SceneObject("ball", sp.shapes.icosphere(0.8, 3), sp.translate(0.6, 0.1, 0.6))
    c = SceneObject("floor", sp.shapes.plane(6.0), sp.translate(0.0, -0.8, 0.0))
    return _scene(a, b, c, camera=camera, samples=samples)


def _empty():
    camera = sp.Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 10.0), fovy=40.0)     # looking away
    return _scene(SceneObject("ball", sp.shapes.icosphere(1.0, 2), np.eye(4)), camera=camera)


RENDERS = {
    "bunny": lambda: sp.render("bunny", width=64, height=48, outputs=OUTPUTS),
    "clipped triangle": lambda: sp.render(_clipped(), outputs=OUTPUTS),
    "objects, two materials, a scaled model": lambda: sp.render(_objects(), outputs=OUTPUTS),
    "multisampling": lambda: sp.render(_objects("rgss4"), outputs=OUTPUTS),
    "teapot, 4 samples": lambda: sp.render("teapot", width=W, height=H, samples="rgss4", outputs=OUTPUTS),
    # rows of 16-pixel blocks and a part block (the pass lists a row's covered pixels a block at a time)
    "teapot, 4 samples, 45 wide": lambda: sp.render("teapot", width=45, height=29, samples="rgss4", outputs=OUTPUTS),
    "lines and points": lambda: sp.render(_lines_and_points(), outputs=OUTPUTS),
    "textured": lambda: sp.render("spot", width=W, height=H, outputs=OUTPUTS),
    "empty frame": lambda: sp.render(_empty(), outputs=OUTPUTS),
    "some outputs, in another order": lambda: sp.render("suzanne", width=W, height=H,
                                                        outputs=("normal", "object_id", "depth", "albedo")),
}


@pytest.mark.parametrize("path", ["auto", "fast"])
@pytest.mark.parametrize("case", list(RENDERS))
def test_the_compiled_pass_gives_the_numpy_derivations_bits(case, path, derived_twice, monkeypatch):
    # at these sizes "auto" draws on the reference path; with the fast path for every size, the last fast
    # draw's samples are not yet in the record when the pass runs (Framebuffer.defer_visible): it reads them
    if path == "fast":
        import softpipe.pipeline.visibility as visibility
        monkeypatch.setattr(visibility, "FAST_PATH_MIN_SAMPLES", 0)
    out = RENDERS[case]()
    _assert_pairs_agree(derived_twice)
    deferred = list(derived_twice.deferred)
    assert any(deferred) == (path == "fast"), deferred
    if case == "empty frame":
        assert (out["object_id"] == -1).all() and np.isnan(out["normal"]).all()
    else:
        assert (out["object_id"] >= 0).sum() > 20


def test_instances_and_draws_by_hand_give_the_numpy_derivations_bits():
    # draws made by hand: one instanced (its instances shifted by an attribute), with normals and
    # uv; one in a polygon mode of lines (its edges name their triangles); one of points
    fb = Framebuffer(40, 24, record=True)
    quad = np.array([[-1, -1, 0.5], [-0.5, -1, 0.1], [-1, 1, 0.2], [-0.5, 1, 0.4]])

    def vs(attributes, uniforms):
        p = attributes.position
        w = 1.0 + 0.5 * p[2]
        return (w * (p[0] + attributes.shift), w * p[1], w * p[2], w), Varyings((1.0, 1.0, 1.0))

    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.6, 0.8], [0.36, 0.48, 0.8]])
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    sp.draw(fb, quad, np.array([[0, 1, 2], [2, 1, 3]]), vertex_shader=vs, instances=3,
            instance_attributes={"shift": np.array([[0.0], [0.6], [1.2]])},
            attributes={"normal": normals, "uv": uvs}, uniforms={"color": (0.2, 0.4, 0.6)})
    tri = np.array([[0.2, -0.9, 0.3, 1.0], [0.9, -0.8, -0.2, 1.0], [0.5, 0.9, 0.0, 1.0]])
    sp.draw(fb, tri, varyings={"color": np.ones((3, 3))}, polygon_mode="line", depth_test="less")
    sp.draw(fb, np.array([[0.7, 0.7, -0.5, 1.0], [0.8, 0.2, -0.6, 1.0]]), varyings={"color": np.ones((2, 3))},
            topology="points", point_size=3.0, depth_test="less")
    got, expected = derive_outputs(fb, OUTPUTS), _numpy_derive_outputs(fb, OUTPUTS)
    for name in OUTPUTS:
        _assert_same_bits(name, got[name], expected[name])
    _, instance, _ = split_record(fb.record[0], fb.recorded_draws)
    assert set(np.unique(instance)) >= {0, 1, 2}
    assert {0, 1, 2} <= set(np.unique(got["object_id"]))
    assert np.isfinite(got["uv"]).any() and np.isfinite(got["normal"]).any()


def test_a_frame_with_no_draws_gives_the_numpy_derivations_bits():
    fb = Framebuffer(8, 6, record=True)
    fb.clear()
    got, expected = derive_outputs(fb, OUTPUTS), _numpy_derive_outputs(fb, OUTPUTS)
    for name in OUTPUTS:
        _assert_same_bits(name, got[name], expected[name])
    assert (got["triangle_id"] == -1).all() and (got["depth"] == 1.0).all()


def test_ten_thousand_instances_give_the_numpy_derivations_bits():
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from benchmarks.run import render_frame
    from benchmarks.scenes import build_scene
    scene = build_scene("field10k", 0.125)
    fb = Framebuffer(scene.width, scene.height, record=True)
    render_frame(scene, fb)
    names = ("depth", "linear_depth", "object_id", "triangle_id", "barycentrics", "position")
    got, expected = derive_outputs(fb, names), _numpy_derive_outputs(fb, names)
    for name in names:
        _assert_same_bits(name, got[name], expected[name])
    _, instance, _ = split_record(fb.record, fb.recorded_draws)
    assert len(np.unique(instance)) > 100


def _banded_frame() -> Framebuffer:
    """A 512×96 frame, three bands of rows for the pass (grain 32 rows at this width): rows 40–59 hold a
    quad of normals and uv (draw 0); the other rows hold no geometry but pixel (300, 80), the one
    centre inside a triangle smaller than a pixel (draw 1)."""
    w, h = 512, 96
    fb = Framebuffer(w, h, record=True)

    def vs(attributes, uniforms):
        p = attributes.position
        return (p[0], p[1], p[2], 1.0), Varyings((1.0, 1.0, 1.0))

    top, bottom = 1 - 2 * 40.0 / h, 1 - 2 * 60.0 / h        # the edges of rows 40 and 59
    quad = np.array([[-0.9, bottom, 0.5], [0.8, bottom, 0.1], [-0.7, top, 0.2], [0.9, top, 0.4]])
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.6, 0.8], [0.36, 0.48, 0.8]])
    sp.draw(fb, quad, np.array([[0, 1, 2], [2, 1, 3]]), vertex_shader=vs,
            attributes={"normal": normals, "uv": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])})
    x, y = 2 * 300.5 / w - 1, 1 - 2 * 80.5 / h                # pixel (300, 80)'s centre, and 0.3–0.4 pixel round it
    tiny = np.array([[x - 0.6 / w, y - 0.6 / h, 0.0], [x + 0.8 / w, y - 0.6 / h, 0.0], [x - 0.6 / w, y + 0.8 / h, 0.0]])
    sp.draw(fb, tiny, np.array([[0, 1, 2]]), vertex_shader=vs, attributes={"normal": np.tile([0.0, 0.0, 1.0], (3, 1))})
    return fb


def test_empty_bands_and_a_single_covered_pixel_give_the_numpy_derivations_bits():
    # the pass writes each row as background first and then only its covered pixels: rows of no
    # geometry, a row of one covered pixel and rows of a surface all as the numpy derivation
    fb = _banded_frame()
    got, expected = derive_outputs(fb, OUTPUTS), _numpy_derive_outputs(fb, OUTPUTS)
    for name in OUTPUTS:
        _assert_same_bits(name, got[name], expected[name])
    rows, cols = np.nonzero(got["object_id"] >= 0)
    assert set(rows[got["object_id"][rows, cols] == 0]) == set(range(40, 60))
    assert list(zip(rows[got["object_id"][rows, cols] == 1], cols[got["object_id"][rows, cols] == 1])) == [(80, 300)]
    assert np.isfinite(got["normal"][80, 300]).all() and np.isnan(got["normal"][81]).all()
    assert (got["depth"][:40] == 1.0).all() and (got["triangle_id"][60:80] == -1).all()


def _side_by_side_frame() -> Framebuffer:
    """A 40×16 frame where each row runs through several draws whose pixels name the same primitive:
    draw 0 (two instances of triangle 0, side by side, shifted by an attribute), draw 1 (triangle 0
    of other corners, normals and uv, in a viewport of its own), touching draw 0 in the same rows, and
    draw 2, two lines (no surface) that end some rows after the last surface pixel, among them rows of
    draw 1 alone followed by a row that starts with draw 1."""
    fb = Framebuffer(40, 16, record=True)

    def vs(attributes, uniforms):
        p = attributes.position
        w = 1.0 + 0.3 * p[2]
        return (w * (p[0] + attributes.shift), w * p[1], w * p[2], w), Varyings((1.0, 1.0, 1.0))

    def flat(attributes, uniforms):
        p = attributes.position
        return (p[0], p[1], p[2], 1.0), Varyings((1.0, 1.0, 1.0))

    left = np.array([[-1.0, -1.0, 0.4], [-0.5, -1.0, 0.1], [-1.0, 0.4, 0.3]])
    sp.draw(fb, left, np.array([[0, 1, 2]]), vertex_shader=vs, instances=2,
            instance_attributes={"shift": np.array([[0.0], [0.45]])},
            attributes={"normal": np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.6, 0.8]]),
                        "uv": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])})
    right = np.array([[-1.0, -1.0, 0.2], [1.0, -1.0, 0.5], [-1.0, 1.0, 0.0]])
    sp.draw(fb, right, np.array([[0, 1, 2]]), vertex_shader=flat, viewport=sp.Viewport(18, 0, 22, 16),
            attributes={"normal": np.array([[0.0, 0.8, 0.6], [-0.6, 0.0, 0.8], [0.0, 0.0, -1.0]]),
                        "uv": np.array([[0.5, 0.5], [0.25, 1.0], [1.0, 0.25]])})
    sp.draw(fb, np.array([[-1.0, -0.9, -0.5, 1.0], [1.0, 0.2, -0.5, 1.0], [0.3, 0.95, -0.5, 1.0],
                          [1.0, 0.6, -0.5, 1.0]]), varyings={"color": np.ones((4, 3))}, topology="lines",
            depth_test="less")
    return fb


def test_neighbouring_pixels_of_the_same_primitive_in_other_draws_and_instances_give_the_numpy_bits():
    # a row's covered pixels are taken apart in one loop and their surfaces computed in loops after it,
    # each keeping the draw it last read: pixels side by side that name triangle 0 of another instance,
    # another draw or another viewport, and rows whose last covered pixel is a line's, all as the numpy
    # derivation
    fb = _side_by_side_frame()
    got, expected = derive_outputs(fb, OUTPUTS), _numpy_derive_outputs(fb, OUTPUTS)
    for name in OUTPUTS:
        _assert_same_bits(name, got[name], expected[name])
    draw, instance, primitive = split_record(fb.record[0], fb.recorded_draws)
    surface = (draw >= 0) & (draw <= 1)
    assert (primitive[surface] == 0).all() and {0, 1} <= set(np.unique(instance[draw == 0]))
    # in some row the two instances touch, and draw 0 touches draw 1
    key = np.where(draw == 0, instance, np.where(draw == 1, 2, -1))
    touching = {(int(a), int(b)) for a, b in zip(key[:, :-1].ravel(), key[:, 1:].ravel()) if a != b}
    assert {(0, 1), (1, 2)} <= touching
    # a row of draw 1 ending in the line, and the next row starting with draw 1
    ends = [j for j in range(fb.height - 1) if set(draw[j][draw[j] >= 0]) == {1, 2} and draw[j][draw[j] >= 0][-1] == 2
            and draw[j + 1][draw[j + 1] >= 0][0] == 1]
    assert ends
    assert np.isfinite(got["normal"][surface]).all() and np.isnan(got["normal"][draw == 2]).all()


def test_the_buffers_do_not_depend_on_the_thread_count():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    fb = _banded_frame()
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = derive_outputs(fb, OUTPUTS)
        numba.set_num_threads(2)
        two = derive_outputs(fb, OUTPUTS)
    finally:
        numba.set_num_threads(before)
    for name in OUTPUTS:
        assert one[name].tobytes() == two[name].tobytes(), name


def test_render_hands_out_its_framebuffers_color_and_derive_outputs_copies_it():
    out = sp.render("suzanne", width=W, height=H, outputs=("color", "depth"))
    fb = out.framebuffer
    # render's framebuffer is made for the call and drawn into no more: its color is handed out, not copied
    assert np.shares_memory(out["color"], fb.color)
    np.testing.assert_array_equal(out["color"], fb.color)
    # derive_outputs on a framebuffer that may be drawn into again copies it (unless told not to)
    kept = derive_outputs(fb, ("color",))["color"]
    before = kept.copy()
    fb.clear("red")
    np.testing.assert_array_equal(kept, before)
    assert np.shares_memory(derive_outputs(fb, ("color",), copy_color=False)["color"], fb.color)
    # with several samples, color is the resolve: a new array, copied or not
    msaa = sp.render("suzanne", width=W, height=H, samples="rgss4", outputs=("color",))
    assert not np.shares_memory(msaa["color"], msaa.framebuffer.samples_color)
    np.testing.assert_array_equal(msaa["color"], msaa.framebuffer.color)


def test_a_record_changed_after_drawing_is_refused_naming_the_pixel():
    fb = Framebuffer(8, 6, record=True)
    sp.draw(fb, np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1.0]]), varyings={"color": np.ones((3, 3))})
    fb.record[0, 2, 5] = 7                       # the draw took the value 0 only
    with pytest.raises(ValueError) as e:
        derive_outputs(fb, ("object_id",))
    assert str(e.value) == ("derive_outputs: the visibility record at pixel (5, 2) holds [7], which no recorded "
                            "draw of this frame made (its 1 draws took the values 0 to 0); was fb.record changed "
                            "after drawing?")


def _one_triangle_with_normals(normals: np.ndarray) -> Framebuffer:
    """A 16 × 12 framebuffer with a visibility record, covered by one triangle with these vertex normals."""
    fb = Framebuffer(16, 12, record=True)

    def vs(attributes, uniforms):
        p = attributes.position
        return (p[0], p[1], p[2], 1.0), Varyings((1.0, 1.0, 1.0))

    sp.draw(fb, np.array([[-1, -1, 0.2], [3, -1, 0.2], [-1, 3, 0.2]]), vertex_shader=vs, attributes={"normal": normals})
    return fb


def test_a_zero_normal_gives_nan_as_the_numpy_derivation_did():
    # the normals interpolate to (0, 0, 0): the numpy derivation divided by the zero length (NaN);
    # the compiled pass must do the same, not raise ZeroDivisionError
    fb = _one_triangle_with_normals(np.zeros((3, 3)))
    got, expected = derive_outputs(fb, ("normal", "object_id")), _numpy_derive_outputs(fb, ("normal", "object_id"))
    for name in ("normal", "object_id"):
        _assert_same_bits(name, got[name], expected[name])
    assert (got["object_id"] == 0).all() and np.isnan(got["normal"]).all()


def test_buffers_written_into_the_arrays_given_are_the_new_arrays_bits_with_nothing_left_of_before():
    # derive_outputs(..., out=...) writes each buffer into the array given (numpy's out=): the
    # arrays come back, every pixel rewritten: a frame of other objects derived into the last
    # frame's arrays gives the bits of new ones, background included
    first = sp.render(_objects(), outputs=OUTPUTS)
    second = sp.render(_lines_and_points(), outputs=OUTPUTS)
    fb = second.framebuffer
    assert (fb.width, fb.height) == (first.framebuffer.width, first.framebuffer.height)
    given = {name: first[name] for name in OUTPUTS}
    kept = {name: a.copy() for name, a in given.items()}
    got = derive_outputs(fb, OUTPUTS, out=given)
    fresh = derive_outputs(fb, OUTPUTS)
    for name in OUTPUTS:
        assert got[name] is given[name], name
        _assert_same_bits(name, got[name], fresh[name])
        assert got[name].tobytes() != kept[name].tobytes(), name          # it was written
    # out["color"] gets a copy of the color; the framebuffer's own color is left as it is
    assert not np.shares_memory(got["color"], fb.color)
    own = derive_outputs(fb, ("color", "depth"), copy_color=False, out={"color": fb.color})
    assert own["color"] is fb.color


@pytest.mark.parametrize("name, bad, message", [
    ("depth", np.zeros((H, W), np.float64), f"out['depth'] is float64 [{H}, {W}]; the depth buffer of this frame "
                                            f"is float32 [{H}, {W}], C-contiguous and writeable"),
    ("normal", np.zeros((H, W, 4), np.float32), f"out['normal'] is float32 [{H}, {W}, 4]; the normal buffer"),
    ("object_id", np.zeros((W, H), np.int32).T, "not C-contiguous"),
    ("triangle_id", np.broadcast_to(np.int32(0), (H, W)), "read-only"),
    ("color", [[0.0]], "out['color'] is a list, not an array"),
])
def test_an_array_given_for_a_buffer_that_does_not_fit_is_refused_naming_it(name, bad, message):
    fb = sp.render("suzanne", width=W, height=H, outputs=("color", "depth")).framebuffer
    with pytest.raises(ValueError) as e:
        derive_outputs(fb, ("color", "depth", "normal", "object_id", "triangle_id"), out={name: bad})
    assert message in str(e.value)


def test_too_few_positions_for_the_indices_are_refused_where_positions_are_read():
    fb = _one_triangle_with_normals(np.tile([0.0, 0.0, 1.0], (3, 1)))
    fb.recorded_draws[0].call.positions = np.zeros((2, 3))        # changed after drawing: index 2 is gone
    normal = derive_outputs(fb, ("normal",))["normal"]            # the normal does not read the positions
    assert (normal == np.float32([0, 0, 1])).all()
    for name in ("position", "linear_depth"):
        with pytest.raises(ValueError, match="recorded draw 0 has 2 positions; its indices reach 2"):
            derive_outputs(fb, (name,))


@pytest.mark.parametrize("normals, shape", [(np.zeros((2, 3)), r"\(2, 3\)"), (np.zeros((3, 2)), r"\(3, 2\)")])
def test_a_vertex_attribute_too_short_or_too_narrow_for_the_drawn_corners_is_refused_naming_the_draw(normals, shape):
    fb = _one_triangle_with_normals(np.tile([0.0, 0.0, 1.0], (3, 1)))
    fb.recorded_draws[0].call.attributes["normal"] = normals      # changed after drawing
    with pytest.raises(ValueError, match=r"recorded draw 0's attribute 'normal' has shape " + shape +
                       r"; the outputs read it as \[vertices, 3\] with at least 3 rows"):
        derive_outputs(fb, ("normal",))
    assert (derive_outputs(fb, ("triangle_id",))["triangle_id"] == 0).all()    # the ids do not read it


def test_the_buffers_read_the_corners_as_drawn_when_the_indices_change_after_drawing():
    # the barycentrics follow the corners' order: a pass that read the indices again would give the permuted
    # indices' barycentrics (it did, before the draw kept its corners), or refuse the replaced ones
    clip = np.array([[-1, -1, 0.2, 1], [3, -1, 0.2, 1], [-1, 3, 0.2, 1.0], [0, 0, 0, 1.0]])
    for indices in (np.array([[0, 1, 2]], np.int64), np.array([[0, 1, 2]], np.int32)):
        fb = Framebuffer(16, 12, record=True)
        sp.draw(fb, clip, indices=indices, varyings={"color": np.ones((4, 3))})
        drawn = derive_outputs(fb, ("barycentrics", "triangle_id"))
        indices[0] = (1, 2, 0)                   # changed in place after drawing (the int64 array was given as is)
        again = derive_outputs(fb, ("barycentrics", "triangle_id"))
        fb.recorded_draws[0].call.indices = np.array([[0, 1, 3]])     # and replaced: vertex 3 was not drawn
        replaced = derive_outputs(fb, ("barycentrics", "triangle_id"))
        for name in ("barycentrics", "triangle_id"):
            assert drawn[name].tobytes() == again[name].tobytes() == replaced[name].tobytes(), (indices.dtype, name)
        assert (drawn["triangle_id"] == 0).all()


def test_a_draw_recorded_without_its_corners_whose_indices_reach_past_the_vertices_is_refused_naming_it():
    # a RecordedDraw made by hand has no corners: the pass makes them from the draw's indices, checked
    fb = Framebuffer(16, 12, record=True)
    sp.draw(fb, np.array([[-1, -1, 0.2, 1], [3, -1, 0.2, 1], [-1, 3, 0.2, 1.0]]), indices=np.array([[0, 1, 2]]),
            varyings={"color": np.ones((3, 3))})
    fb.recorded_draws[0].corners = None
    assert (derive_outputs(fb, ("triangle_id",))["triangle_id"] == 0).all()
    fb.recorded_draws[0].call.indices = np.array([[0, 1, 3]])     # changed after drawing: vertex 3 is not there
    with pytest.raises(ValueError, match=r"recorded draw 0 does not match its record: indices\[2\] = 3 is out of "
                                         r"range for 3 vertices"):
        derive_outputs(fb, ("normal",))


def test_a_frame_whose_draws_name_more_primitives_than_the_int32_record_holds_is_refused():
    from softpipe.pipeline.framebuffer import RECORD_MAX
    fb = Framebuffer(8, 6, record=True)
    sp.draw(fb, np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1.0]]), varyings={"color": np.ones((3, 3))})
    assert fb.record.dtype == np.int32 and (fb.record == 0).all()
    # the frame's next values start at 1: RECORD_MAX − 1 more primitives fit, RECORD_MAX do not
    fb.add_recorded_draw(None, np.zeros((0, 4)), 3, RECORD_MAX - 1, RECORD_MAX - 1, "triangles")
    with pytest.raises(ValueError, match=r"at most 2,147,483,647: this draw's 1 primitives .* after the "
                                         r"2,147,483,647 of the frame's earlier draws do not fit"):
        fb.add_recorded_draw(None, np.zeros((0, 4)), 3, 1, 1, "triangles")
    fb.clear()                                   # a clear forgets the draws: the values start at 0 again
    fb.add_recorded_draw(None, np.zeros((0, 4)), 3, RECORD_MAX, RECORD_MAX, "triangles")
