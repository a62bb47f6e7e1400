"""The test suite's lock on numba's cache index (tests/numba_cache_lock.py): concurrent savers keep every entry.

Each thread stands for a process (an xdist worker) that compiled its own signature of one function: it
has its own ``IndexDataCacheFile`` and saves one entry. Reading the index is slowed down so that all of
them read it before any writes it, as two processes compiling at the same moment would.
"""
import threading
import time

import pytest
from patience import PATIENCE

numba_cache_lock = pytest.importorskip("numba_cache_lock")
caching = pytest.importorskip("numba.core.caching")

SAVERS = 4


def _save_at_once(folder, save) -> None:
    barrier = threading.Barrier(SAVERS)
    errors = []

    def one(k):
        cache = caching.IndexDataCacheFile(str(folder), "f", source_stamp=(1.0, 10))
        read = cache._load_index

        def slow_read():
            index = read()
            time.sleep(0.2)         # the others read the same index meanwhile
            return index

        cache._load_index = slow_read
        try:
            barrier.wait()
            save(cache, ("signature", k), {"compiled for": k})
        except Exception as e:      # noqa: BLE001 (asserted below)
            errors.append(e)

    threads = [threading.Thread(target=one, args=(k,)) for k in range(SAVERS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors


def _loaded(folder):
    cache = caching.IndexDataCacheFile(str(folder), "f", source_stamp=(1.0, 10))
    return [cache.load(("signature", k)) for k in range(SAVERS)]


@pytest.mark.skipif(not numba_cache_lock.install(), reason="no flock here, or numba's cache has changed")
def test_concurrent_saves_keep_every_signature_with_its_own_code(tmp_path):
    _save_at_once(tmp_path, caching.IndexDataCacheFile.save)
    assert _loaded(tmp_path) == [{"compiled for": k} for k in range(SAVERS)]


@pytest.mark.skipif(not numba_cache_lock.install(), reason="no flock here, or numba's cache has changed")
def test_without_the_lock_they_lose_entries(tmp_path):
    # numba's own save, as the lock found it: what the lock is for
    _save_at_once(tmp_path, caching.IndexDataCacheFile.save.__wrapped__)
    kept = sum(entry is not None for entry in _loaded(tmp_path))
    assert kept < SAVERS, ("numba's own save kept every entry: its index may be safe across processes now, "
                           "and tests/numba_cache_lock.py no longer needed")


COMPILER = r"""
import os, sys, time
sys.path.insert(0, {tests!r})
import numba_cache_lock
if {locked}:
    assert numba_cache_lock.install()
sys.path.insert(0, {folder!r})
import slow_to_compile
open(os.path.join({folder!r}, f"ready-{{os.getpid()}}"), "w").close()
while len([f for f in os.listdir({folder!r}) if f.startswith("ready-")]) < 2:
    time.sleep(0.01)
slow_to_compile.f(1.0)
print(sum(slow_to_compile.f.stats.cache_misses.values()))
"""

# A function that takes numba a second or so to compile: a long chain of statements.
SLOW = "from numba import njit\n\n@njit(cache=True)\ndef f(x):\n" + "".join(
    f"    x = x * 1.0001 + {k}.0\n    if x > 1e300:\n        x = 0.0\n" for k in range(150)) + "    return x\n"


def _compiles_of_two_processes_at_once(folder, locked: bool) -> int:
    import os
    import subprocess
    import sys
    (folder / "slow_to_compile.py").write_text(SLOW)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / "cache"))
    code = COMPILER.format(tests=os.path.dirname(__file__), folder=str(folder), locked=locked)
    runs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True)
            for _ in range(2)]
    outs = [r.communicate(timeout=PATIENCE)[0] for r in runs]
    assert all(r.returncode == 0 for r in runs), outs
    return sum(int(o.split()[-1]) for o in outs)


@pytest.mark.skipif(not numba_cache_lock.install(), reason="no flock here, or numba's cache has changed")
def test_two_workers_compile_a_function_once(tmp_path):
    assert _compiles_of_two_processes_at_once(tmp_path, locked=True) == 1


@pytest.mark.skipif(not numba_cache_lock.install(), reason="no flock here, or numba's cache has changed")
def test_without_the_compile_lock_both_compile_it(tmp_path):
    # what the compile lock is for: both processes start together and neither finds the other's result
    assert _compiles_of_two_processes_at_once(tmp_path, locked=False) == 2
