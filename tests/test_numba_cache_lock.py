"""The test suite's lock on numba's cache index (tests/numba_cache_lock.py): concurrent savers keep every entry.

Each thread stands for a process (an xdist worker) that compiled its own signature of one function: it
has its own ``IndexDataCacheFile`` and saves one entry. Reading the index is slowed down so that all of
them read it before any writes it, as two processes compiling at the same moment would.
"""
import threading
import time

import pytest

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
