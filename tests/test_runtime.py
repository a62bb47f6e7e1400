"""Process-wide behaviour: the allocator setting softpipe's own programs ask for (softpipe/core/runtime.py), which
importing softpipe does not, and softpipe's threads in a forked child (softpipe/core/parallel.py)."""
import json
import os
import subprocess
import sys

import pytest
from patience import PATIENCE

import softpipe as sp
from softpipe.core import runtime

# In a fresh process: does a freed 64 MiB block stay in the process (the allocator keeps freed memory), after
# importing softpipe, and again after sp.keep_freed_memory() when "call" is given? glibc maps a block that size
# on its own and unmaps it when freed (its mmap threshold never rises above 32 MiB), unless told otherwise.
PROBE = """
import json, os, sys
import numpy as np
import softpipe as sp

def kept():
    def rss():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    before = rss()
    block = np.ones(64 << 20, np.uint8)         # every page touched
    del block
    return rss() - before > (32 << 20)

out = {"after_import": kept(), "tuned_after_import": sp.core.runtime.freed_memory_kept()}
if "call" in sys.argv:
    out["returned"] = sp.keep_freed_memory()
    out["after_call"] = kept()
    out["again"] = sp.keep_freed_memory()
    sp.core.runtime.release_memory()
print(json.dumps(out))
"""


def probe(*argv, **env):
    full = {k: v for k, v in os.environ.items() if k != "SOFTPIPE_SYSTEM_MALLOC"}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", PROBE, *argv], env=full, capture_output=True, text=True,
                         timeout=PATIENCE)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


glibc_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's")


@glibc_only
def test_importing_softpipe_leaves_the_allocator_alone():
    assert probe() == {"after_import": False, "tuned_after_import": False}


@glibc_only
def test_keep_freed_memory_tunes_the_allocator_once_called():
    assert probe("call") == {"after_import": False, "tuned_after_import": False,
                             "returned": True, "after_call": True, "again": True}


@glibc_only
@pytest.mark.parametrize("value, tuned", [("1", False), ("yes", False), ("0", True)])
def test_softpipe_system_malloc_makes_the_call_leave_the_allocator_alone(value, tuned):
    got = probe("call", SOFTPIPE_SYSTEM_MALLOC=value)
    assert got == {"after_import": False, "tuned_after_import": False,
                   "returned": tuned, "after_call": tuned, "again": tuned}


def test_the_command_line_asks_for_it_and_sp_exports_it(monkeypatch, capsys):
    from softpipe.tools.cli import main
    assert sp.keep_freed_memory is runtime.keep_freed_memory
    calls = []
    monkeypatch.setattr(runtime, "keep_freed_memory", lambda: calls.append(1) or True)
    assert main(["programs"]) == 0
    assert calls == [1]
    assert main(["--version"]) == 0 and calls == [1]     # nothing to draw: not asked for


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
        print(json.dumps([parent] + pool.map_async(render, range(2)).get(timeout=PATIENCE)))
'''


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork here")
def test_a_forked_child_draws_with_threads_of_its_own(tmp_path):
    # The parent's thread pools are copied into a forked child without their threads;
    # softpipe.core.parallel starts new ones there instead of waiting forever.
    script = tmp_path / "fork.py"
    script.write_text(FORK_SCRIPT.replace("PATIENCE", repr(PATIENCE)))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=PATIENCE)
    assert out.returncode == 0, out.stderr
    parent, *children = json.loads(out.stdout)
    assert parent > 0 and children == [parent, parent]      # the children drew, and drew the same
