"""Issue #13: outputs written whole or not at all, NaN colors, and a framebuffer the kernels can trust."""
from __future__ import annotations

import errno
import io
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import softpipe as sp
from softpipe.cli import main

TETRA = """v 0 0 0
v 1.2 0 0.1
v 0.2 0.9 0.3
v 0.3 0.2 1.4
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""

TRIANGLE = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
COLORS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)


@pytest.fixture
def obj(tmp_path) -> Path:
    path = tmp_path / "tetra.obj"
    path.write_text(TETRA)
    return path


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------------------- the framebuffer's fields


@pytest.mark.parametrize("name, value", [
    ("width", 10_000), ("height", 3), ("pattern", sp.sampling.pattern_named("grid16")),
    ("samples_color", np.zeros((1, 100, 100, 4), np.float32)),
    ("samples_depth", np.zeros((1, 6, 8), np.float64)),
    ("samples_color", np.zeros((1, 8, 6, 4), np.float32)[:, ::-1]),
])
def test_assigning_the_size_pattern_or_arrays_is_refused(name, value):
    fb = sp.Framebuffer(8, 6)
    with pytest.raises(AttributeError, match=rf"Framebuffer\.{name} is read-only.*in place"):
        setattr(fb, name, value)
    assert (fb.width, fb.height, fb.samples) == (8, 6, 1)
    assert fb.samples_color.shape == (1, 6, 8, 4) and fb.samples_depth.shape == (1, 6, 8)
    sp.draw(fb, TRIANGLE, varyings={"color": COLORS})        # and it still draws
    assert np.asarray(fb).any()


def test_the_arrays_are_written_in_place():
    fb = sp.Framebuffer(8, 6, sp.sampling.pattern_named("rgss4"))
    fb.samples_color[...] = (0.5, 0.25, 1.0, 1.0)
    fb.samples_depth[:, 2, 3] = 0.25
    fb.samples_color[2, 1, 1] = (1.0, 1.0, 1.0, 1.0)
    assert np.asarray(fb)[0, 0].tolist() == [128, 64, 255]
    assert fb.depth[2, 3] == np.float32(0.25) and fb.samples_depth[0, 0, 0] == 1.0
    assert fb.samples_color[2, 1, 1].tolist() == [1.0, 1.0, 1.0, 1.0]
    one = sp.Framebuffer(4, 3)
    one.color[1, 2] = (1, 0, 0, 1)                              # fb.color is the buffer for one sample
    assert np.asarray(one)[1, 2].tolist() == [255, 0, 0]


@pytest.mark.parametrize("path", ["fast", "reference"])
def test_changing_a_handed_out_array_cannot_reach_a_kernel(path):
    """Shape or dtype of the array fb.samples_* gave out change that array only."""
    fb = sp.Framebuffer(8, 6)
    color, depth = fb.samples_color, fb.samples_depth
    color.shape = (1, 8, 6, 4)                                  # the same bytes, another shape
    depth.dtype = np.int32
    fb.samples_depth.shape = (48,)
    sp.draw(fb, TRIANGLE, varyings={"color": COLORS}, path=path)
    assert fb.samples_color.shape == (1, 6, 8, 4) and fb.samples_color.dtype == np.float32
    assert fb.samples_color.flags.c_contiguous and fb.samples_depth.flags.c_contiguous
    reference = sp.Framebuffer(8, 6)
    sp.draw(reference, TRIANGLE, varyings={"color": COLORS}, path=path)
    assert np.array_equal(np.asarray(fb), np.asarray(reference))


CORRUPT = """
import numpy as np, softpipe as sp
fb = sp.Framebuffer(40, 8)
base = fb.samples_color.base if fb.samples_color.base is not None else fb.samples_color
{change}
pos = np.array([[-1, -1, 0, 1], [3, -1, 0, 1], [-1, 3, 0, 1]], float)
try:
    sp.draw(fb, pos, varyings={{"color": np.ones((3, 3))}}, path="{path}")
except RuntimeError as e:
    print("refused:", e)
else:
    print("drawn")
"""


@pytest.mark.parametrize("path", ["fast", "reference"])
@pytest.mark.parametrize("change", ["base.shape = (1, 40, 8, 4)", "base.dtype = np.float64",
                                    "base.shape = (2, 4, 40, 4)"])
def test_a_changed_buffer_is_refused_before_any_kernel_runs(change, path):
    """Even the framebuffer's own array, reached through .base, changed in place: an error, never a crash."""
    done = subprocess.run([sys.executable, "-c", CORRUPT.format(change=change, path=path)], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("refused: Framebuffer.samples_color was changed in place"), done.stdout


# ---------------------------------------------------------------------------- NaN colors


def nan_green(varyings, uniforms, frag):
    nan = np.nan
    return (nan, 0.5, -nan, 1.0)


def test_nan_becomes_0_without_a_warning_on_both_paths(tmp_path):
    pictures = []
    for path in ("fast", "reference"):
        fb = sp.Framebuffer(12, 10)
        sp.draw(fb, TRIANGLE, fragment_shader=nan_green, path=path)
        assert np.isnan(fb.color[..., 0]).any()
        with warnings.catch_warnings():
            warnings.simplefilter("error")                      # numpy's "invalid value encountered in cast"
            rgb = np.asarray(fb)
            fb.save(tmp_path / f"{path}.png")
            rgba = fb.to_uint8()
        covered = np.isnan(fb.color[..., 0])
        assert rgb[covered].tolist() == [[0, 128, 0]] * int(covered.sum())
        assert (rgba[covered][:, 3] == 255).all()
        assert np.array_equal(np.asarray(Image.open(tmp_path / f"{path}.png")), rgb)
        pictures.append(rgb)
    assert np.array_equal(*pictures)
    fb = sp.Framebuffer(3, 1)
    fb.color[0] = [(np.inf, -np.inf, 0.5, 1.0), (2.0, -1.0, np.nan, np.nan), (0.5, 0.5, 0.5, 1.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fb.to_uint8().tolist() == [[[255, 0, 128, 255], [255, 0, 0, 0], [128, 128, 128, 255]]]
