"""The same bytes whatever the thread count, and the same pixels with numba turned off.

Each run is a fresh Python process (``sys.executable``), because numba reads
NUMBA_NUM_THREADS and NUMBA_DISABLE_JIT when it is first imported. The child
renders scenes and writes the raw bytes of each one's color and depth buffers to
a file; the test compares the files byte for byte. One child renders every scene
this file's tests ask of its environment (each child costs an interpreter, numba
and softpipe, and the kernels loaded again).
"""
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from patience import PATIENCE

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
    for scene, out in zip(sys.argv[1::2], sys.argv[2::2]):          # scene, file, scene, file, ...
        fb = {"busy": busy, "small": small, "small_blend": lambda: small("alpha")}[scene]()
        with open(out, "wb") as f:
            f.write(fb.color.tobytes() + fb.depth.tobytes())
'''


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    path = tmp_path_factory.mktemp("determinism") / "scenes.py"
    path.write_text(SCENES)
    return path


#: The scenes one child renders in each environment the tests ask for (by the environment's settings).
SCENES_OF = {(): ("small", "small_blend"), (("NUMBA_DISABLE_JIT", "1"),): ("small", "small_blend"),
             (("NUMBA_NUM_THREADS", "1"),): ("busy",), (("NUMBA_NUM_THREADS", "2"),): ("busy",)}


@pytest.fixture(scope="module")
def rendered(scenes):
    """The bytes of ``scene`` rendered in a child with ``env``, as ``rendered[scene, (("NAME", "value"),)]``:
    the first ask of an environment renders all its scenes in SCENES_OF in one child."""
    class Rendered(dict):
        def __missing__(self, key):
            scene, env = key
            names = SCENES_OF[env] if scene in SCENES_OF.get(env, ()) else (scene,)
            outs = [scenes.parent / ("_".join([name, *(f"{k}{v}" for k, v in env)]) + ".bin") for name in names]
            e = dict(os.environ)
            e.pop("NUMBA_DISABLE_JIT", None)
            e.pop("NUMBA_NUM_THREADS", None)
            e.update(env)
            e["PYTHONPATH"] = str(ROOT) + os.pathsep + e.get("PYTHONPATH", "")
            args = [str(a) for pair in zip(names, outs) for a in pair]
            r = subprocess.run([sys.executable, str(scenes), *args], env=e, capture_output=True, text=True,
                               timeout=PATIENCE)
            assert r.returncode == 0, f"child failed ({dict(env)}):\n{r.stdout}\n{r.stderr}"
            for name, out in zip(names, outs):
                self[name, env] = out.read_bytes()
            return self[key]
    return Rendered()


def render(rendered, scene, **env):
    """The bytes of ``scene`` rendered in a fresh process with the environment variables ``env``."""
    return rendered[scene, tuple(sorted(env.items()))]


def describe(data, size):
    color = np.frombuffer(data[:size * size * 16], np.float32).reshape(size, size, 4)
    return hashlib.sha256(data).hexdigest()[:16], color


def test_busy_scene_is_byte_identical_on_one_and_two_threads(rendered):
    one = render(rendered, "busy", NUMBA_NUM_THREADS="1")
    two = render(rendered, "busy", NUMBA_NUM_THREADS="2")
    assert len(one) == 48 * 48 * (16 + 4)
    _, color = describe(one, 48)
    # the scene is busy: most pixels drawn, many different colors
    assert (color[..., :3] != 0).any(axis=2).mean() > 0.8
    assert len(np.unique(color.reshape(-1, 4), axis=0)) > 1000
    assert one == two, f"1 thread: {describe(one, 48)[0]}, 2 threads: {describe(two, 48)[0]}"


def compare_jit_and_python(rendered, scene):
    jit = render(rendered, scene)
    py = render(rendered, scene, NUMBA_DISABLE_JIT="1")
    _, color = describe(jit, 16)
    assert len(np.unique(color.reshape(-1, 4), axis=0)) > 30
    assert (color == (0.125, 0.25, 0.5, 1.0)).all(axis=2).sum() > 0       # some background is left
    if jit != py:
        _, color_py = describe(py, 16)
        diff = np.argwhere((color != color_py).any(axis=2))
        pytest.fail(f"{len(diff)} pixels differ, e.g. {diff[:5].tolist()}")


def test_pure_python_path_gives_the_same_pixels(rendered):
    compare_jit_and_python(rendered, "small")


def test_pure_python_path_gives_the_same_pixels_with_blending(rendered):
    compare_jit_and_python(rendered, "small_blend")
