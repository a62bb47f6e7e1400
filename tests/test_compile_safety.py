"""Compiling is safe across threads and fork (issue #13).

- ``kernels.cache.load_cached`` writes a generated module through a temporary file of
  its own (``tempfile.mkstemp`` in the cache folder, then ``os.replace``), under a
  lock: threads writing the same module never share a temporary file (they did,
  named by the pid alone, and one thread's rename left another with no file, or
  moved half a file into place).
- A fork while another thread compiles waits for the compile (``os.register_at_fork``
  holds softpipe's and numba's compile locks across the fork): the child does not
  inherit a lock held by a thread it does not have, and can compile.
"""
import os
import subprocess
import sys
import textwrap
import threading

import pytest
from patience import PATIENCE

from softpipe.language.kernels import cache

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_threads_writing_the_same_module_share_no_temporary_file(tmp_path, monkeypatch):
    source = "# generated\n" + "X = 1\n" * 50_000 + "def loop():\n    return X\n"
    errors = []
    for round_ in range(12):
        monkeypatch.setenv("SOFTPIPE_CACHE_DIR", str(tmp_path / f"cache{round_}"))
        name = f"softpipe_test_race_{os.getpid()}_{round_}"
        barrier = threading.Barrier(6)
        got = []

        def load():
            try:
                barrier.wait()
                got.append(cache.load_cached(source, name).loop())
            except Exception as e:          # noqa: BLE001  (collected, asserted below)
                errors.append(e)

        workers = [threading.Thread(target=load) for _ in range(6)]
        for t in workers:
            t.start()
        for t in workers:
            t.join()
        sys.modules.pop(name, None)
        assert not errors, errors
        assert got == [1] * 6
        folder = tmp_path / f"cache{round_}"
        assert sorted(p.name for p in folder.iterdir()) == [f"{name}.py"]     # no temporary file left
        assert (folder / f"{name}.py").read_text() == source


FORK_SCRIPT = textwrap.dedent("""
    import os, sys, threading, time
    import numpy as np
    import numba
    import softpipe as sp
    from numba.core.compiler_lock import global_compiler_lock

    def shader(varyings, uniforms, frag):
        return (varyings.color[0], frag.x * 0.01, 0.5, 1.0)

    def compile_in_thread():
        fb = sp.Framebuffer(8, 8)
        clip = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]], float)
        sp.draw(fb, clip, varyings={"color": np.ones((3, 3))}, fragment_shader=shader)

    worker = threading.Thread(target=compile_in_thread)
    worker.start()
    deadline = time.monotonic() + 30
    def held_elsewhere():
        if global_compiler_lock._lock.acquire(False):
            global_compiler_lock._lock.release()
            return False
        return True

    while not held_elsewhere():                       # fork while the other thread compiles
        if time.monotonic() > deadline or not worker.is_alive():
            print("the thread never compiled"); sys.exit(3)
        time.sleep(0.0005)
    pid = os.fork()
    if pid == 0:                                       # the child compiles something of its own
        f = numba.njit(lambda x: x + 1)
        os._exit(0 if f(1) == 2 else 4)
    deadline = time.monotonic() + 40
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            print("the child hung: deadlocked on the compiler lock"); sys.exit(2)
        time.sleep(0.05)
    worker.join()
    sys.exit(os.waitstatus_to_exitcode(status))
""")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_fork_while_another_thread_compiles_does_not_deadlock_the_child(tmp_path):
    env = dict(os.environ, SOFTPIPE_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=ROOT)
    env.pop("NUMBA_DISABLE_JIT", None)
    script = tmp_path / "fork_during_compile.py"
    script.write_text(FORK_SCRIPT)
    result = subprocess.run([sys.executable, "-W", "ignore", str(script)], env=env, capture_output=True,
                            text=True, timeout=PATIENCE)
    assert result.returncode == 0, result.stdout + result.stderr
