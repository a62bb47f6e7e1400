"""What several test files share: scenes and shapes built by hand, and the fixtures and helpers they use;
and, for every test process, the lock on numba's cache index (numba_cache_lock.py) and the
``alone`` marker of tests that must have no other test beside them (run_alone.py).

Helpers are plain functions, imported by name (``from conftest import window_to_clip``: this folder is on
``sys.path``); fixtures are found by pytest. A helper that one file alone uses stays in that file.
"""
import math
import os
import shutil
import sys
from pathlib import Path
from typing import Tuple

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

import numba_cache_lock  # noqa: E402
import run_alone  # noqa: E402

from softpipe.language.contract import VaryingLayout  # noqa: E402
from softpipe.pipeline.assembly import Primitives  # noqa: E402

# make test runs the suite in two processes that share numba's on-disk cache: its index is locked
# (numba_cache_lock.py says why).
numba_cache_lock.install()


def pytest_configure(config):
    config.addinivalue_line("markers", "alone: run with no other test beside it under xdist (the test reads the "
                                       "wall clock); tests/run_alone.py")


@pytest.fixture(autouse=True)
def _one_at_a_time_where_marked(request, tmp_path_factory):
    """Every test under xdist: beside the others, or alone where marked ``alone`` (run_alone.py)."""
    alone = request.node.get_closest_marker("alone") is not None
    with run_alone.turn(alone, tmp_path_factory.getbasetemp().parent):      # the folder the workers share
        yield


def window_prims(tris, z=0.5):
    """Primitives straight from window coordinates: tris is [T, 3, 2] (or [T, 3, 3] with z)."""
    tris = np.asarray(tris, dtype=np.float64)
    t = len(tris)
    window = np.empty((t, 3, 3))
    window[:, :, :2] = tris[:, :, :2]
    window[:, :, 2] = tris[:, :, 2] if tris.shape[2] == 3 else z
    return Primitives(window=window, inv_w=np.ones((t, 3)), varyings=np.zeros((t, 3, 0)),
                      layout=VaryingLayout(), primitive_id=np.arange(t), front_facing=np.ones(t, bool),
                      clipped=np.zeros(t, bool), input_count=t)


def window_to_clip(points, width, height, z=0.0):
    """Clip coordinates (w = 1) that the default viewport maps to the given window points."""
    p = np.asarray(points, dtype=np.float64)
    out = np.empty((len(p), 4))
    out[:, 0] = p[:, 0] / width * 2 - 1
    out[:, 1] = p[:, 1] / height * 2 - 1
    out[:, 2] = p[:, 2] if p.shape[1] > 2 else z
    out[:, 3] = 1.0
    return out


@pytest.fixture
def rng(request):
    seed = int(os.environ.get("SOFTPIPE_TEST_SEED", "20261122"))
    print(f"random seed: {seed} (set SOFTPIPE_TEST_SEED to replay)")
    return np.random.default_rng(seed)


# ---------------------------------------------------------------------------- vectors


def unit(v) -> np.ndarray:
    """``v`` (one vector) scaled to length 1, in float64."""
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def tilt(theta_deg: float, phi_deg: float = 0.0) -> Tuple[float, float, float]:
    """The unit vector at angle theta from +z, turned by phi about z (degrees), as a tuple of floats."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))


# ---------------------------------------------------------------------------- a model file and the command line

#: A small tetrahedron, asymmetric (no two faces alike), positions only: the model file of the output tests.
TETRA_OBJ = """v 0 0 0
v 1.2 0 0.1
v 0.2 0.9 0.3
v 0.3 0.2 1.4
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""

#: The same tetrahedron with texture coordinates: every turntable frame differs, so a GIF keeps them all.
TETRA_UV_OBJ = """# tetrahedron
v 0 0 0
v 1.2 0 0.1
v 0.2 0.9 0.3
v 0.3 0.2 1.4
vt 0 0
vt 1 0
vt 0 1
f 1/1 3/3 2/2
f 1/1 2/2 4/3
f 1/1 4/3 3/3
f 2/2 3/3 4/1
"""


@pytest.fixture
def tetra_obj(tmp_path) -> Path:
    """:data:`TETRA_OBJ` written to ``tmp_path/tetra.obj``."""
    path = tmp_path / "tetra.obj"
    path.write_text(TETRA_OBJ)
    return path


@pytest.fixture
def tetra_uv_obj(tmp_path) -> Path:
    """:data:`TETRA_UV_OBJ` written to ``tmp_path/tetra.obj``."""
    path = tmp_path / "tetra.obj"
    path.write_text(TETRA_UV_OBJ)
    return path


def run_cli(capsys, *argv) -> Tuple[int, str, str]:
    """``softpipe ARGV...`` run in this process: (exit status, stdout, stderr). Arguments may be paths."""
    from softpipe.tools.cli import main
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------------------- an environment


def env_function(d):
    """A smooth environment: the color in world direction ``d`` (a gradient, every channel its own axis)."""
    return 0.5 + 0.45 * d


@pytest.fixture(scope="module")
def environment():
    """:func:`env_function` as a 64² cube map, built once per test module."""
    from softpipe.light.cubemap import CubeMap
    return CubeMap.from_function(env_function, 64)


# ---------------------------------------------------------------------------- a real browser (explorer, viewer)


def _chromium() -> str:
    """Debian's chromium; skips with the reason where it is not installed (``make test`` installs it)."""
    found = shutil.which("chromium")
    if not found:
        pytest.skip("chromium is not installed: make test installs it (apt-get install -y chromium, as root)")
    return found


def _playwright():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as e:
        pytest.skip(f"playwright is not installed ({e}): pip install -e '.[test]' (make test installs it)")
    return sync_playwright


@pytest.fixture(scope="module")
def browser():
    executable = _chromium()
    sync_playwright = _playwright()
    with sync_playwright() as pw:
        try:
            b = pw.chromium.launch(executable_path=executable, args=["--no-sandbox"])
        except Exception as e:  # noqa: BLE001 (any reason the browser does not start is the skip's reason)
            pytest.skip(f"{executable} did not start headless: {str(e).splitlines()[0]}")
        yield b
        b.close()
