"""The ``alone`` marker under xdist (tests/run_alone.py): an alone test waits for the tests beside it to end,
and no test starts beside it until it ends. Threads stand for the workers (flock locks conflict between
separately opened files, in one process as in two)."""
import threading
import time

import pytest

run_alone = pytest.importorskip("run_alone")
if run_alone.fcntl is None:
    pytest.skip("no flock here", allow_module_level=True)


def test_an_alone_test_runs_with_no_other_beside_it(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
    events = []
    lock = threading.Lock()

    def note(what):
        with lock:
            events.append(what)

    def test(name, alone, hold):
        with run_alone.turn(alone, tmp_path):
            note(f"{name} starts")
            time.sleep(hold)
            note(f"{name} ends")

    first = threading.Thread(target=test, args=("beside", False, 0.5))
    first.start()
    time.sleep(0.1)                                   # "beside" is running
    lone = threading.Thread(target=test, args=("alone", True, 0.5))
    lone.start()
    time.sleep(0.1)                                   # "alone" waits for the gate
    late = threading.Thread(target=test, args=("late", False, 0.1))
    late.start()                                      # must not slip in beside "alone"
    for t in (first, lone, late):
        t.join(timeout=30)
    assert events == ["beside starts", "beside ends", "alone starts", "alone ends", "late starts", "late ends"]


def test_outside_xdist_nothing_waits(tmp_path, monkeypatch):
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    with run_alone.turn(True, tmp_path):
        with run_alone.turn(True, tmp_path):          # would wait forever if it locked
            pass
    assert not list(tmp_path.iterdir())
