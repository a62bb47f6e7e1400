"""Process-wide behaviour: the allocator setting softpipe applies on import (softpipe/core/runtime.py) and the
way out of it, and its threads in a forked child (softpipe/core/parallel.py)."""
import json
import os
import subprocess
import sys

import pytest

PROBE = ("import json, softpipe.core.runtime as r; r.release_memory(); "
         "print(json.dumps({'tuned': r.malloc_tuned}))")


def probe(**env):
    full = {k: v for k, v in os.environ.items() if k != "SOFTPIPE_SYSTEM_MALLOC"}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", PROBE], env=full, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's")
def test_the_allocator_is_tuned_unless_asked_not_to():
    assert probe() == {"tuned": True}
    assert probe(SOFTPIPE_SYSTEM_MALLOC="1")["tuned"] is False
    assert probe(SOFTPIPE_SYSTEM_MALLOC="0")["tuned"] is True



FORK_SCRIPT = r'''
import json
import multiprocessing as mp
import numpy as np
import softpipe as sp

def render(_):
    fb = sp.Framebuffer(256, 256)                 # big enough for the fast path and its threads
    sp.draw(fb, np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1.0]]), varyings={"color": np.ones((3, 3))})
    return int((fb.depth < 1).sum())

if __name__ == "__main__":
    parent = render(0)
    with mp.get_context("fork").Pool(2) as pool:
        print(json.dumps([parent] + pool.map_async(render, range(2)).get(timeout=60)))
'''


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork here")
def test_a_forked_child_draws_with_threads_of_its_own(tmp_path):
    # The parent's thread pools are copied into a forked child without their threads;
    # softpipe.core.parallel starts new ones there instead of waiting forever.
    script = tmp_path / "fork.py"
    script.write_text(FORK_SCRIPT)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    parent, *children = json.loads(out.stdout)
    assert parent > 0 and children == [parent, parent]      # the children drew, and drew the same
