"""Replay the fuzz corpus (fuzz/corpus/obj, fuzz/corpus/scene): every input loads or fails
with the documented error, in bounded time. Fuzzing itself is `make fuzz` (fuzz/README.md)."""
from __future__ import annotations

import sys
import time
import traceback
from pathlib import Path

import pytest

FUZZ = Path(__file__).resolve().parents[1] / "fuzz"
sys.path.insert(0, str(FUZZ))

import targets  # noqa: E402

#: Seconds one corpus input may take here (the fuzzer's own bound is 10 s; these are small).
PER_INPUT_SECONDS = 5.0


@pytest.mark.alone          # each input within PER_INPUT_SECONDS on the wall clock
@pytest.mark.parametrize("target", targets.TARGETS)
def test_corpus_replays_within_the_contract(target):
    files = targets.corpus_files(target)
    assert len(files) >= 5, f"the {target} corpus is missing (python fuzz/make_corpus.py)"
    check = targets.CHECKS[target]
    failures, outcomes = [], {}
    for path in files:
        start = time.perf_counter()
        try:
            outcome = targets.run_with_time_limit(check, path.read_bytes(), PER_INPUT_SECONDS)
        except Exception as e:  # the contract allows none but the documented errors, caught in check()
            failures.append(f"{path.name}: {type(e).__name__}: {e}\n{traceback.format_exc(limit=-2)}")
            continue
        outcomes[outcome] = outcomes.get(outcome, 0) + 1
        assert time.perf_counter() - start < PER_INPUT_SECONDS
    assert not failures, "\n".join(failures)
    assert "ok" in " ".join(outcomes), outcomes  # some inputs load: the corpus is not all errors


def test_corpus_stays_small():
    total = sum(p.stat().st_size for t in targets.TARGETS for p in targets.corpus_files(t))
    assert total < 1_000_000, f"the committed fuzz corpus is {total:,} bytes; keep it under 1 MB"


def test_the_contract_rejects_other_exceptions(monkeypatch):
    import softpipe.scenes.obj

    def broken(*args, **kwargs):
        raise IndexError("list index out of range")

    monkeypatch.setattr(softpipe.scenes.obj, "parse_obj", broken)
    with pytest.raises(IndexError):
        targets.check_obj(b"v 1 2 3\n")


def test_the_time_bound():
    with pytest.raises(TimeoutError):
        targets.run_with_time_limit(lambda data: time.sleep(2), b"", 0.2)


# Findings the fuzzer made go into fuzz/known/ with an entry in targets.KNOWN until they
# are fixed, then into the corpus (as regression-*), which the tests above replay.



def test_the_scene_target_parses_a_bundled_model_and_its_texture_once(monkeypatch):
    """Parsing the bunny (and spot's texture's mipmaps) for every input, under atheris's
    instrumentation, outlasted the time bound (a false hang); the files are fixed, so the scene
    target loads each once."""
    import softpipe.light.texture as texture
    import softpipe.scenes.models as models

    loads = []
    real = models.load_model

    def counting(name, **kwargs):
        loads.append(name)
        return real(name, **kwargs)

    monkeypatch.setattr(models, "load_model", counting)
    targets._bundled_model.cache_clear()
    targets._bundled_texture.cache_clear()
    real_texture = texture.Texture2D
    data = b'[[meshes]]\nobj = "spot"\n[meshes.material]\ndiffuse_texture = "spot"\n'
    assert targets.check_scene(data) == "ok"
    assert targets.check_scene(data) == "ok"
    assert loads == ["spot"]
    info = targets._bundled_texture.cache_info()
    assert (info.misses, info.hits) == (1, 1)
    assert texture.Texture2D is real_texture          # the library is left as it was
    targets._bundled_model.cache_clear()
    targets._bundled_texture.cache_clear()
