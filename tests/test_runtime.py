"""The process settings softpipe applies on import (softpipe/_runtime.py), and the way out of them."""
import json
import os
import subprocess
import sys

import pytest

PROBE = ("import json, os, softpipe._runtime as r; r.release_memory(); "
         "print(json.dumps({'tuned': r.malloc_tuned, 'omp': os.environ.get('OMP_WAIT_POLICY')}))")


def probe(**env):
    full = {k: v for k, v in os.environ.items() if k not in ("SOFTPIPE_SYSTEM_MALLOC", "OMP_WAIT_POLICY")}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", PROBE], env=full, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's")
def test_the_allocator_is_tuned_unless_asked_not_to():
    assert probe() == {"tuned": True, "omp": "PASSIVE"}
    assert probe(SOFTPIPE_SYSTEM_MALLOC="1")["tuned"] is False
    assert probe(SOFTPIPE_SYSTEM_MALLOC="0")["tuned"] is True


def test_a_wait_policy_already_set_is_left_alone():
    assert probe(OMP_WAIT_POLICY="ACTIVE")["omp"] == "ACTIVE"
