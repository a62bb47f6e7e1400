"""How long a test waits for another process, or a server, before it calls it hung.

A wait for an event (a line printed, a reply, an exit) is bounded by :data:`PATIENCE`, not by how long the
event takes on an idle machine: a cold numba compile on a loaded machine takes minutes, and a test that
fails then checks the machine, not softpipe. What a test *times* (Ctrl-C stopping a draw, say) it measures
separately, from the moment that matters, and asserts on that.
"""
from __future__ import annotations

import subprocess
import threading

#: Seconds a test waits for a process's or a server's event before it fails as hung.
PATIENCE = 900.0


def read_line(proc: subprocess.Popen, what: str, seconds: float = PATIENCE):
    """The next line ``proc`` writes on its stdout, waited for at most ``seconds``; past that the process is
    killed and the test fails, naming ``what`` it waited for and the end of the process's stderr."""
    got: list = []
    reader = threading.Thread(target=lambda: got.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(seconds)
    if reader.is_alive():
        proc.kill()
        reader.join()
        err = proc.stderr.read() if proc.stderr is not None else ""
        raise AssertionError(f"waited {seconds:.0f} s for {what}, and the process did not print it; its stderr "
                             f"ends: {err[-2000:]!r}")
    return got[0]
