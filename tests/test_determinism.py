"""The same bytes whatever the thread count, and the same pixels with numba turned off.

Each run is a fresh Python process (``sys.executable``), because numba reads
NUMBA_NUM_THREADS and NUMBA_DISABLE_JIT when it is first imported. The child
renders a scene and writes the raw bytes of the color and depth buffers to a
file; the test compares the files byte for byte.
"""
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent

SCENES = r'''
import sys
import numpy as np
import softpipe


def busy():
    """300 random overlapping triangles with per-vertex colors, varied w, depth test on, 48×48."""
    rng = np.random.default_rng(12345)
    n = 300
    w = rng.uniform(0.5, 2.0, size=(3 * n, 1))
    xy = rng.uniform(-1.3, 1.3, size=(3 * n, 2)) * w
    z = rng.uniform(-1.2, 1.2, size=(3 * n, 1)) * w          # some cross the near and far planes
    pos = np.hstack([xy, z, w])
    fb = softpipe.Framebuffer(48, 48)
    softpipe.draw(fb, pos, varyings={"color": rng.random((3 * n, 3))})
    return fb


def shade(varyings, uniforms, frag):
    """A small fragment shader: reads frag.x/y/z, discards a few, writes alpha."""
    if frag.y < 2.0 and frag.x < 6.0:
        return softpipe.DISCARD
    c = varyings.color
    k = 0.25 + frag.x / 32.0
    return (c[0] * k, c[1] * uniforms.gain, c[2] * frag.z, 0.625)


def small(blend=None):
    """A few triangles on 16×16: depth test, a clipped triangle, flat, culling, a shader, discard."""
    fb = softpipe.Framebuffer(16, 16).clear((0.125, 0.25, 0.5, 1.0))
    pos = np.array([
        [-0.9, -0.8, 0.2, 1.0], [0.8, -0.9, -0.3, 1.0], [0.1, 0.9, 0.5, 1.0],
        [-1.5, 0.5, -3.0, 1.0], [0.9, 0.7, 0.9, 1.0], [0.0, -1.0, 0.1, 1.0],     # crosses the near plane
        [0.3, 0.2, 0.0, 2.0], [1.8, 0.4, 0.1, 2.0], [0.8, 1.9, -0.2, 2.0],
    ])
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1],
                       [0.5, 0.5, 0.5], [0.25, 0.75, 0.125], [0.9, 0.1, 0.3]], dtype=float)
    softpipe.draw(fb, pos, varyings={"color": colors})
    softpipe.draw(fb, pos[::-1].copy(), varyings={"color": colors}, interpolation={"color": "flat"},
                  depth_test="lequal", cull="back")
    softpipe.draw(fb, pos * [1.0, -1.0, 1.0, 1.0], varyings={"color": colors}, fragment_shader=shade,
                  uniforms={"gain": 0.75}, blend=blend, depth_test="always", depth_write=False)
    return fb


if __name__ == "__main__":
    fb = {"busy": busy, "small": small, "small_blend": lambda: small("alpha")}[sys.argv[1]]()
    with open(sys.argv[2], "wb") as f:
        f.write(fb.color.tobytes() + fb.depth.tobytes())
'''


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    path = tmp_path_factory.mktemp("determinism") / "scenes.py"
    path.write_text(SCENES)
    return path


def render(scenes, scene, out, **env):
    e = dict(os.environ)
    e.pop("NUMBA_DISABLE_JIT", None)
    e.pop("NUMBA_NUM_THREADS", None)
    e.update(env)
    e["PYTHONPATH"] = str(ROOT) + os.pathsep + e.get("PYTHONPATH", "")
    r = subprocess.run([sys.executable, str(scenes), scene, str(out)], env=e, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, f"child failed ({env}):\n{r.stdout}\n{r.stderr}"
    return out.read_bytes()


def describe(data, size):
    color = np.frombuffer(data[:size * size * 16], np.float32).reshape(size, size, 4)
    return hashlib.sha256(data).hexdigest()[:16], color


def test_busy_scene_is_byte_identical_on_one_and_two_threads(scenes, tmp_path):
    one = render(scenes, "busy", tmp_path / "t1.bin", NUMBA_NUM_THREADS="1")
    two = render(scenes, "busy", tmp_path / "t2.bin", NUMBA_NUM_THREADS="2")
    assert len(one) == 48 * 48 * (16 + 4)
    _, color = describe(one, 48)
    # the scene is busy: most pixels drawn, many different colors
    assert (color[..., :3] != 0).any(axis=2).mean() > 0.8
    assert len(np.unique(color.reshape(-1, 4), axis=0)) > 1000
    assert one == two, f"1 thread: {describe(one, 48)[0]}, 2 threads: {describe(two, 48)[0]}"


def compare_jit_and_python(scenes, tmp_path, scene):
    jit = render(scenes, scene, tmp_path / "jit.bin")
    py = render(scenes, scene, tmp_path / "py.bin", NUMBA_DISABLE_JIT="1")
    _, color = describe(jit, 16)
    assert len(np.unique(color.reshape(-1, 4), axis=0)) > 30
    assert (color == (0.125, 0.25, 0.5, 1.0)).all(axis=2).sum() > 0       # some background is left
    if jit != py:
        _, color_py = describe(py, 16)
        diff = np.argwhere((color != color_py).any(axis=2))
        pytest.fail(f"{len(diff)} pixels differ, e.g. {diff[:5].tolist()}")


def test_pure_python_path_gives_the_same_pixels(scenes, tmp_path):
    compare_jit_and_python(scenes, tmp_path, "small")


def test_pure_python_path_gives_the_same_pixels_with_blending(scenes, tmp_path):
    compare_jit_and_python(scenes, tmp_path, "small_blend")
