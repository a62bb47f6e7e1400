import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

from softpipe.pipeline.assembly import Primitives  # noqa: E402
from softpipe.language.contract import VaryingLayout  # noqa: E402


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
