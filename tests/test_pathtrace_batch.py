"""Path tracing in batch jobs (softpipe.tools.batch): ``pathtrace = true``, ``spp``, ``seed``; deterministic per seed."""
from __future__ import annotations

import io
from pathlib import Path

import numba
import numpy as np
import pytest
from PIL import Image

from softpipe.scenes.drawing import prepare_scene
from softpipe.tools.batch import JobError, batch, parse_job, read_manifest
from softpipe.tools.batch.run import render_frame
from softpipe.tracers.pathtrace import pathtrace

#: A small ball under a grey sky (the job's background is the path tracer's only light here), two seeds.
JOB = """
[job]
background = [0.6, 0.7, 0.8]

[models]
ball = { shape = "uv_sphere", segments = 12, rings = 6 }

[sweep]
models = ["ball"]
sizes = ["12x10"]
pathtrace = true
spp = 3
seed = {seed}
"""


def job(seed: int = 0, text: str = JOB):
    return parse_job(text.replace("{seed}", str(seed)), "pt.toml")


def png_pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)))


def test_a_path_traced_frame_is_named_and_keeps_its_parameters():
    (frame,) = job(5).frames
    assert (frame.pathtrace, frame.spp, frame.seed, frame.samples) == (True, 3, 5, "1")
    assert frame.name == "ball-az030-12x10-pt3-seed5"
    assert job(0).frames[0].name == "ball-az030-12x10-pt3"
    assert {"pathtrace": True, "spp": 3, "seed": 5}.items() <= frame.params().items()


def test_a_rasterized_frame_has_the_parameters_and_name_it_had_before():
    (frame,) = parse_job('[sweep]\nmodels = ["bunny"]\n', "r.toml").frames
    assert not frame.pathtrace
    assert set(frame.params()) == {"model", "azimuth", "elevation", "view", "orbit", "program", "material", "lights",
                                   "width", "height", "samples"}
    assert frame.name == "bunny-az030-640x480"


def test_the_frame_is_the_path_tracers_image_of_the_frames_scene():
    j = job(2)
    (frame,) = j.frames
    mesh = j.load_models()["ball"]
    png = render_frame(frame, mesh, j)
    scene = prepare_scene(mesh, width=12, height=10, background=j.background, azimuth=frame.azimuth,
                          elevation=frame.elevation, fovy=j.fovy)
    traced = pathtrace(scene, 3, 2)
    expected = np.asarray(Image.open(_saved(traced)))
    assert np.array_equal(png_pixels(png), expected)
    raster = parse_job(JOB.replace("pathtrace = true\nspp = 3\nseed = {seed}\n", ""), "pt.toml")
    assert not np.array_equal(png_pixels(render_frame(raster.frames[0], mesh, raster)), expected)


def _saved(traced) -> io.BytesIO:
    buffer = io.BytesIO()
    traced.save(buffer, format="png")
    buffer.seek(0)
    return buffer


def test_the_same_seed_gives_the_same_bytes_on_any_thread_count_and_another_seed_does_not():
    j = job(0)
    (frame,) = j.frames
    mesh = j.load_models()["ball"]
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_frame(frame, mesh, j)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = render_frame(frame, mesh, j)
    finally:
        numba.set_num_threads(before)
    assert one == many
    other = job(1)
    assert render_frame(other.frames[0], mesh, other) != one


def test_a_serial_batch_writes_the_path_traced_frames(tmp_path: Path):
    j = job(4)
    result = batch(j, tmp_path, scheduler="serial", contact_sheet=False)
    assert result.ok and [f.name for f in result.done] == ["ball-az030-12x10-pt3-seed4"]
    written = (tmp_path / "ball-az030-12x10-pt3-seed4.png").read_bytes()
    assert written == render_frame(j.frames[0], j.load_models()["ball"], j)
    (line,) = read_manifest(tmp_path).values()
    assert (line["params"]["pathtrace"], line["params"]["spp"], line["params"]["seed"]) == (True, 3, 4)
    again = batch(job(4), tmp_path, scheduler="serial", contact_sheet=False)
    assert again.skipped == ["ball-az030-12x10-pt3-seed4"] and not again.done


def test_a_sweep_of_spp_makes_one_frame_per_count():
    j = parse_job(JOB.replace("spp = 3", "spp = [1, 4]").replace("{seed}", "0"), "pt.toml")
    assert [f.name for f in j.frames] == ["ball-az030-12x10-pt1", "ball-az030-12x10-pt4"]


SWEEP = '[models]\nball = { shape = "uv_sphere", segments = 12, rings = 6 }\n[sweep]\nmodels = ["ball"]\n'


@pytest.mark.parametrize("keys,message", [
    ("spp = 3\n", "pt.toml: key 'spp' in [sweep] applies only with pathtrace = true (the path tracer's samples "
                  "per pixel and seed)"),
    ("pathtrace = false\nseed = 3\n", "pt.toml: key 'seed' in [sweep] applies only with pathtrace = true"),
    ("pathtrace = true\nspp = 0\n", "pt.toml: entry 1 of key 'spp' in [sweep] must be a whole number of "
                                     "samples per pixel, 1…1048576, got integer 0"),
    ("pathtrace = true\nseed = -1\n", "pt.toml: key 'seed' in [sweep] must be a whole number 0…2⁶⁴ − 1, got integer -1"),
    ("pathtrace = true\nsamples = \"grid4\"\n",
     "pt.toml: key 'samples' in [sweep] picks the rasterizer's sample pattern; it does not apply with pathtrace = "
     "true, whose samples are jittered over each pixel (a box filter): use spp = N"),
    ("pathtrace = 1\n", "pt.toml: key 'pathtrace' in [sweep] must be"),
    ("background_light = true\n", "pt.toml: key 'background_light' in [sweep] applies only with pathtrace = true "
                                  "(the path tracer's light sample toward the background)"),
    ("pathtrace = true\nbackground_light = \"yes\"\n",
     "pt.toml: key 'background_light' in [sweep] must be true or false, got string 'yes'"),
    ("pathtrace = true\nsizes = [\"2000x2000\"]\nspp = 1000\n",
     "pt.toml: key 'sizes' in [sweep] 2000×2000 pixels × 1000 samples exceeds the limit MAX_TOTAL_SAMPLES"),
])
def test_bad_path_tracing_keys_are_named(keys, message):
    with pytest.raises(JobError) as e:
        parse_job(SWEEP + keys, "pt.toml")
    assert str(e.value).startswith(message), str(e.value)


def test_a_frame_table_takes_the_same_keys():
    text = ('[models]\nball = { shape = "uv_sphere", segments = 12, rings = 6 }\n'
            '[[frames]]\nmodel = "ball"\nsize = "8x8"\npathtrace = true\nspp = 2\nseed = 9\n')
    (frame,) = parse_job(text, "f.toml").frames
    assert (frame.pathtrace, frame.spp, frame.seed, frame.name) == (True, 2, 9, "ball-az030-8x8-pt2-seed9")
    with pytest.raises(JobError, match=r"^f\.toml: key 'spp' in \[\[frames\]\] #1 applies only with pathtrace"):
        parse_job(text.replace("pathtrace = true\n", ""), "f.toml")


def test_background_light_is_the_python_calls_bytes_and_names_the_frame():
    """``background_light = true`` is ``pathtrace(..., background_light=True)``: the same bytes (and not those
    without it, under the job's grey sky); the name ends in ``-bglight`` and ``params`` say so, while a frame
    without it keeps the name, parameters and digest it had before the key existed."""
    text = JOB.replace("{seed}", "2")
    j = parse_job(text.replace("seed = 2\n", "seed = 2\nbackground_light = true\n"), "pt.toml")
    (frame,) = j.frames
    assert frame.background_light and frame.name == "ball-az030-12x10-pt3-seed2-bglight"
    assert frame.params()["background_light"] is True
    mesh = j.load_models()["ball"]
    scene = prepare_scene(mesh, width=12, height=10, background=j.background, azimuth=frame.azimuth,
                          elevation=frame.elevation, fovy=j.fovy)
    png = render_frame(frame, mesh, j)
    assert np.array_equal(png_pixels(png), np.asarray(Image.open(_saved(pathtrace(scene, 3, 2,
                                                                                   background_light=True)))))
    assert not np.array_equal(png_pixels(png), np.asarray(Image.open(_saved(pathtrace(scene, 3, 2)))))
    (plain,) = parse_job(text, "pt.toml").frames
    assert not plain.background_light and "background_light" not in plain.params()
    assert plain.name == "ball-az030-12x10-pt3-seed2"
    with_false = parse_job(text.replace("seed = 2\n", "seed = 2\nbackground_light = false\n"), "pt.toml").frames[0]
    assert with_false.digest() == plain.digest()


def test_a_frame_table_takes_background_light():
    text = ('[models]\nball = { shape = "uv_sphere", segments = 12, rings = 6 }\n'
            '[[frames]]\nmodel = "ball"\nsize = "8x8"\npathtrace = true\nbackground_light = true\n')
    (frame,) = parse_job(text, "f.toml").frames
    assert (frame.background_light, frame.name) == (True, "ball-az030-8x8-pt64-bglight")
    with pytest.raises(JobError, match=r"^f\.toml: key 'background_light' in \[\[frames\]\] #1 must be true or false, "
                                       r"got integer 1"):
        parse_job(text.replace("background_light = true", "background_light = 1"), "f.toml")
    with pytest.raises(JobError, match=r"^f\.toml: key 'background_light' in \[\[frames\]\] #1 applies only with "
                                       r"pathtrace = true"):
        parse_job(text.replace("pathtrace = true\n", ""), "f.toml")
