"""Traces: every stage kept, and the questions asked of them agree with the framebuffer (issue 5)."""
import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.draw import DrawCall
from softpipe.programs import get_program
from softpipe.scenes import shapes
from softpipe.scenes.drawing import standard_uniforms
from softpipe.scenes.mesh import concatenate
from softpipe.views.pictures import PICTURES, RED


def scene_call(fb, cull="back", **state):
    """Two overlapping spheres and a plane crossing the near plane, drawn as one mesh."""
    a = shapes.uv_sphere(0.8, 12, 8).transformed(sp.translate(-0.4, 0, 0))
    b = shapes.uv_sphere(0.7, 12, 8).transformed(sp.translate(0.5, 0.1, -0.3))
    ground = shapes.plane(size=8.0, subdivisions=2).transformed(sp.translate(0, -0.8, 0))
    mesh = concatenate([a, b, ground])
    cam = Camera(eye=(0, 0.3, 2.2), target=(0, 0, 0), fovy=50, near=0.5, far=10)
    u = standard_uniforms(cam, fb.width / fb.height)
    prog = get_program("normals")
    return DrawCall(fb, mesh.positions, mesh.indices, vertex_shader=prog.vertex, fragment_shader=prog.fragment,
                    uniforms=u, attributes={"normal": mesh.normals}, cull=cull, **state)


def test_traced_and_untraced_draws_give_identical_bytes():
    for path in ("reference", "fast"):
        a, b = sp.Framebuffer(48, 40), sp.Framebuffer(48, 40)
        scene_call(a, path=path).run()
        trace = scene_call(b).run(trace=True)
        assert trace is not None and len(trace.fragments) > 0
        assert np.array_equal(a.samples_color, b.samples_color), path
        assert np.array_equal(a.samples_depth, b.samples_depth), path


def test_written_pixels_are_the_fragments_whose_verdict_is_written():
    fb = sp.Framebuffer(48, 40)
    fb.clear((0.25, 0.5, 0.75, 1.0))
    trace = scene_call(fb).run(trace=True)
    f, verdicts = trace.fragments, trace.verdicts
    assert set(np.unique(verdicts)) <= {"written", "depth-failed"}
    assert (verdicts == "depth-failed").any()          # the spheres overlap
    written = {(int(x), int(y)) for x, y in zip(f.x[trace.written()], f.y[trace.written()])}
    changed = {(int(x), int(y)) for y, x in np.argwhere((fb.color != trace.before_color[0]).any(axis=2))}
    assert changed <= written
    # every written pixel holds the color its last written fragment left
    last = {}
    for k in np.nonzero(trace.written())[0]:
        last[(int(f.x[k]), int(f.y[k]))] = k
    for (x, y), k in last.items():
        assert np.array_equal(fb.color[y, x], trace.merged.color_after[k])
        assert np.array_equal(fb.color[y, x], trace.shaded.color[k])


def test_pixel_history_ends_with_the_framebuffer_color(rng):
    fb = sp.Framebuffer(48, 40)
    trace = scene_call(fb).run(trace=True)
    f = trace.fragments
    touched = sorted({(int(x), int(y)) for x, y in zip(f.x, f.y)})
    picks = [touched[i] for i in rng.choice(len(touched), size=25, replace=False)]
    overdrawn = [p for p in touched if len(trace.at(*p)) > 1]
    picks += overdrawn[:5]
    assert overdrawn, "the scene should overdraw some pixels"
    for x, y in picks:
        history = trace.pixel_history(x, y)
        assert len(history) >= 1
        assert history[-1].color_after == tuple(float(c) for c in fb.color[y, x])
        # events are in primitive order and a failed test leaves the color as it was
        ids = [e.index for e in history]
        assert ids == sorted(ids)
        previous = history.before
        for e in history:
            if e.verdict == "depth-failed":
                assert e.color_after == previous
            else:
                assert e.color_after == e.color
            previous = e.color_after
    text = str(trace.pixel_history(*overdrawn[0]))
    assert "merger" in text and "written" in text and f"pixel ({overdrawn[0][0]}, {overdrawn[0][1]})" in text


def test_pixel_history_outside_the_framebuffer_is_an_error():
    trace = scene_call(sp.Framebuffer(8, 8)).run(trace=True)
    with pytest.raises(ValueError, match="outside the 8×8 framebuffer"):
        trace.pixel_history(8, 0)


def test_debug_fragment_reruns_the_shader_in_python_and_agrees():
    fb = sp.Framebuffer(48, 40)
    trace = scene_call(fb).run(trace=True)
    f = trace.fragments
    written = np.nonzero(trace.written())[0]
    # The spheres and the ground cover most of the 48×40 frame: with nothing written the
    # loop below would check nothing.
    assert len(written) >= fb.width * fb.height // 2
    checked = 0
    for k in written[::97]:
        x, y = int(f.x[k]), int(f.y[k])
        which = list(trace.at(x, y)).index(k)
        out = trace.debug_fragment(x, y, which)
        assert np.array_equal(np.float32(out), trace.shaded.color[k])
        checked += 1
    assert checked >= 10


def logging_shader(varyings, uniforms, frag):
    uniforms.log[0] = frag.x          # a side effect we can see from the test, jitted or not
    uniforms.log[1] = frag.y
    return (frag.x / 8, frag.y / 8, 0.0, 1.0)


def test_debug_fragment_runs_the_users_shader_on_that_fragment():
    log = np.zeros(8)
    fb = sp.Framebuffer(8, 8)
    pos = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [-1, 1, 0, 1]], float)
    trace = sp.draw(fb, pos, fragment_shader=logging_shader, varyings={"color": np.ones((3, 3))},
                    uniforms={"log": log}, trace=True)
    log[:] = 0.0
    out = trace.debug_fragment(2, 6)              # image row 6 of 8 is window row 1
    assert tuple(log[:2]) == (2.5, 1.5)           # the Python shader ran, on that fragment
    assert tuple(float(c) for c in out) == (2.5 / 8, 1.5 / 8, 0.0, 1.0)
    assert tuple(fb.color[6, 2]) == (np.float32(2.5 / 8), np.float32(1.5 / 8), 0.0, 1.0)
    with pytest.raises(ValueError, match="no fragment reached pixel"):
        trace.debug_fragment(7, 0)


def test_steps_yield_every_stage_in_order_and_finish_like_run():
    a, b = sp.Framebuffer(32, 24), sp.Framebuffer(32, 24)
    names = [s.name for s in scene_call(a, path="reference").steps()]
    assert names[:2] == ["vertex", "assembly"]
    assert names[2:] == ["raster", "fragment", "output"] * ((len(names) - 2) // 3)
    scene_call(b, path="reference").run()
    assert np.array_equal(a.samples_color, b.samples_color)


def test_stage_outputs_are_the_stage_types():
    stages = {s.name: s.output for s in scene_call(sp.Framebuffer(32, 24)).steps()}
    assert isinstance(stages["vertex"], sp.VertexOut)
    assert isinstance(stages["assembly"], sp.Primitives)
    assert isinstance(stages["raster"], sp.Fragments)
    assert isinstance(stages["fragment"], sp.ShadedFragments)
    assert len(stages["output"].verdict) == len(stages["raster"])


def test_stage_pictures_have_the_framebuffer_size_and_mark_culled_triangles(tmp_path):
    fb = sp.Framebuffer(40, 30)
    trace = scene_call(fb, cull="back").run(trace=True)
    pics = trace.pictures()
    assert list(pics) == list(PICTURES)
    for name, img in pics.items():
        assert img.shape == (30, 40, 3) and img.dtype == np.uint8, name
    assert len(trace.primitives.dropped["culled"]) > 0
    assert (pics["primitives"] == RED).all(axis=2).any()          # culled triangles drawn in red
    no_cull = scene_call(sp.Framebuffer(40, 30), cull="none").run(trace=True).pictures()
    assert not (no_cull["primitives"] == RED).all(axis=2).any()
    assert np.array_equal(pics["final"], fb.to_uint8(alpha=False))
    # overdraw: pixels with two fragments differ from those with one
    paths = trace.save_pictures(tmp_path)
    assert set(paths) == set(PICTURES) | {"contact-sheet"}
    from PIL import Image
    assert Image.open(paths["contact-sheet"]).size[0] > 3 * 40
    import io
    inline = Image.open(io.BytesIO(trace._repr_png_()))            # what Jupyter shows for a trace
    assert inline.size == Image.open(paths["contact-sheet"]).size


def test_debug_switch_prints_the_stages(capsys, monkeypatch):
    monkeypatch.setenv("SOFTPIPE_DEBUG", "assembly,output")
    scene_call(sp.Framebuffer(16, 12), path="reference").run()
    err = capsys.readouterr().err
    assert "[softpipe assembly] Primitives(" in err and "[softpipe output] MergeResult(" in err
    assert "[softpipe vertex]" not in err


def test_trace_of_a_multisampled_draw_shows_samples():
    from softpipe.pipeline.sampling import rotated_grid_4x
    fb = sp.Framebuffer(24, 18, pattern=rotated_grid_4x())
    trace = scene_call(fb, sample_shading="center").run(trace=True)
    f = trace.fragments
    assert set(np.unique(f.sample)) == {0, 1, 2, 3}
    x, y = int(f.x[0]), int(f.y[0])
    samples = {e.sample for e in trace.pixel_history(x, y)}
    assert samples and samples <= {0, 1, 2, 3}
    assert trace.shaded.invocations < len(f)


def test_overdraw_counts_coverings_not_samples_so_multisampling_reads_on_the_same_key():
    """Issue 14: the overdraw picture counted fragments, so under rgss4 one triangle read as 4 (red)."""
    from softpipe.pipeline.sampling import rotated_grid_4x
    from softpipe.views.pictures import HEAT_STOPS, OVERDRAW_DEFINITION, contact_sheet, overdraw
    quad = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1]], float)
    small = np.array([[-0.5, -0.5, 0, 1], [0.6, -0.4, 0, 1], [0.1, 0.7, 0, 1]], float)  # over the quad
    for pattern in (None, rotated_grid_4x()):
        fb = sp.Framebuffer(24, 18) if pattern is None else sp.Framebuffer(24, 18, pattern=pattern)
        positions = np.concatenate([quad, small])
        trace = sp.draw(fb, positions, varyings={"color": np.ones((9, 3))}, depth_test="always", trace=True)
        if pattern is not None:
            assert len(trace.fragments) > 4 * 24 * 18                   # four samples a pixel...
        counts = overdraw(trace)
        # ...but the quad covers every pixel once: its two triangles share the diagonal, and
        # the samples of an edge pixel split between them add up to one covering
        inside = np.zeros((18, 24), bool)
        inside[trace.fragments.y[trace.fragments.triangle == 2], trace.fragments.x[trace.fragments.triangle == 2]] = True
        full = inside & (counts == 2.0)
        assert ((counts >= 1.0) & (counts <= 2.0)).all()
        assert (counts[~inside] == 1.0).all() and full.sum() > 40
        pic = trace.pictures()["overdraw"]
        assert (pic[~inside] == HEAT_STOPS[1]).all() and (pic[full] == HEAT_STOPS[2]).all()
    # the key under the pictures says what is counted and shows the colors
    sheet = np.asarray(contact_sheet(trace.pictures()))
    key = sheet[-18:]
    for color in HEAT_STOPS[1:5]:
        assert (key == color.astype(np.uint8)).all(axis=2).sum() > 50
    assert "covered samples / samples per pixel" in OVERDRAW_DEFINITION
    assert sheet.shape[0] == np.asarray(contact_sheet({k: v for k, v in trace.pictures().items()
                                                         if k != "overdraw"})).shape[0] + 18
