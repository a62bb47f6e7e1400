"""Deferred shading (issue 31, examples/deferred.py): a G-buffer pass into four attachments, then one lighting
pass over the screen, gives forward shading's picture within 1/255 at every pixel, and lights each pixel once."""
import sys
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SIZE = (64, 48)


@pytest.fixture(scope="module")
def deferred():
    sys.path.insert(0, str(EXAMPLES))
    try:
        import deferred
        yield deferred
    finally:
        sys.path.remove(str(EXAMPLES))


@pytest.fixture(scope="module")
def frames(deferred):
    g = deferred.gbuffer(SIZE)
    lit, _ = deferred.lighting_pass(g)
    return deferred.forward(SIZE), g, lit


def test_the_deferred_picture_equals_forward_shading_within_one_255th_at_every_pixel(frames):
    forward, g, lit = frames
    ids = g.attachment("material")
    assert (ids >= 0).mean() > 0.4 and len(np.unique(ids)) == 5          # the floor, 3 materials, background
    diff = np.abs(forward.color.astype(np.float64) - lit.color.astype(np.float64))
    assert diff.max() <= 1 / 255
    bytes_diff = np.abs(forward.to_uint8().astype(int) - lit.to_uint8().astype(int))
    assert bytes_diff.max() <= 1
    assert forward.to_uint8()[..., :3].std() > 20                       # a picture, not a blank


def test_the_g_buffer_holds_each_surface_and_the_background_its_clear_values(deferred, frames):
    forward, g, _ = frames
    ids = g.attachment("material")
    background = ids < 0
    # where nothing was drawn: the clear values (the albedo: the background color; the others 0, material −1)
    assert (forward.color[background] == np.float32(deferred.BACKGROUND)).all()
    assert (g.color[background] == np.float32(deferred.BACKGROUND)).all()
    assert (g.attachment("position")[background] == 0).all() and (g.attachment("normal")[background] == 0).all()
    # where something was: the material's diffuse color, a unit normal facing the eye, a point in front of it
    kd = np.array([m.kd for m in deferred.MATERIALS], np.float32)
    np.testing.assert_array_equal(g.color[~background][:, :3], kd[ids[~background]])
    n = g.attachment("normal")[~background][:, :3].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    p = g.attachment("position")[~background][:, :3].astype(np.float64)
    assert (p[:, 2] < 0).all() and ((n * -p).sum(axis=1) > -1e-6).all()


def test_the_g_buffer_is_the_same_on_both_paths(deferred):
    reference, fast = deferred.gbuffer(SIZE, "reference"), deferred.gbuffer(SIZE, "fast")
    for name in deferred.GBUFFER:
        assert reference.samples_attachment(name).tobytes() == fast.samples_attachment(name).tobytes(), name


def test_deferred_lights_each_covered_pixel_once_where_forward_lights_the_overdraw_too(deferred):
    counts = deferred.shading_counts(SIZE)
    w, h = SIZE
    assert counts["lighting pass invocations"] == w * h
    assert counts["g-buffer fragments"] == counts["forward lit (reference)"]
    # the scene is drawn far to near: forward shading lights the hidden surfaces too, on either path
    assert counts["forward lit (reference)"] > 1.5 * counts["deferred lit"]
    assert counts["forward lit (fast path)"] > 1.5 * counts["deferred lit"]
    # early depth with the nearest drawn first lights what deferred lights
    assert counts["forward lit (fast path, near first)"] == counts["deferred lit"]
