"""The process setting softpipe applies on import (softpipe/_runtime.py), and the way out of it."""
import json
import os
import subprocess
import sys

import pytest

PROBE = ("import json, softpipe._runtime as r; r.release_memory(); "
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

