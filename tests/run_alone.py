"""Tests that must run with no other test beside them when the suite runs in several processes.

``make test`` runs the suite in one pytest-xdist worker per core. A test whose assertion reads the
wall clock (Ctrl-C stops a draw within 4 s, the bunny loads in under a second) would measure the
other worker's test as well, whenever the two run at once. Such a test is marked
``@pytest.mark.alone``: it waits until the other workers have finished the test they are running,
and they start no new test until it is done.

Every test holds a lock file (the gate) shared while it runs, and an ``alone`` test holds it
exclusive. Before asking for the gate a test passes a second lock (the turnstile: taken and at once
released), which an ``alone`` test keeps while it waits and runs, so the others cannot starve it by
taking the gate shared one test after another. The two files are in the run's temporary folder,
which xdist's workers share. Without xdist, or without ``flock``, nothing is locked.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

try:
    import fcntl
except ImportError:                 # not POSIX
    fcntl = None


@contextlib.contextmanager
def turn(alone: bool, run_folder: Path):
    """Run the block as one test: with no other test beside it when ``alone``, else beside others."""
    if fcntl is None or not os.environ.get("PYTEST_XDIST_WORKER"):
        yield
        return
    turnstile = os.open(run_folder / "softpipe-tests.turnstile", os.O_RDWR | os.O_CREAT, 0o600)
    gate = os.open(run_folder / "softpipe-tests.gate", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        if not alone:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        fcntl.flock(gate, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        yield
    finally:
        os.close(gate)              # closing releases the locks
        os.close(turnstile)
