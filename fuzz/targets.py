"""The fuzz targets and the contract they check (used by run.py, the fuzzers and tests/test_fuzz.py).

Contract: any input either loads, or raises the library's documented error type with a
non-empty message:

``obj``    :func:`softpipe.scenes.obj.parse_obj` (and :func:`softpipe.scenes.obj.parse_mtl`, the same
           module's MTL parser, on the same text) → a ``Mesh``, or ``OBJError``; ``OSError``
           is allowed for files the text names (``mtllib``).
``scene``  :func:`softpipe.scenes.scenefile.parse_scene` → a ``Scene``, or ``SceneError``.

Anything else (``IndexError``, ``KeyError``, ``RecursionError``, ``TypeError``, …) is a
finding, and so is an input that takes longer than the time bound (a hang), which
run.py enforces per input.

File names in the inputs resolve against ``fuzz/data`` (a triangle, a quad with an MTL
and a 4×4 texture), so that ``mtllib``/``obj =``/``diffuse_texture =`` can succeed.
The scene target lowers ``MAX_SCENE_TRIANGLES`` to :data:`FUZZ_SCENE_TRIANGLES` so that
the fuzzer spends its time on parsing rather than on making large spheres; the limit
is still checked, just smaller. It also loads each bundled model (``obj = "bunny"``) and
its texture (spot's, 1024², with its mipmaps) once per process: those files are fixed
(the ``obj`` target fuzzes the OBJ parser), and loading them again for every input, under
the fuzzer's instrumentation on a busy machine, took longer than the time bound and was
reported as a hang.
"""
from __future__ import annotations

import functools
import os
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
CORPUS = HERE / "corpus"
TARGETS = ("obj", "scene")

#: The triangle budget of one fuzzed scene (the library's default is 4 million).
FUZZ_SCENE_TRIANGLES = 200_000

#: Findings reported to the module's owner and not fixed yet, as (exception class, function
#: in the traceback), with a reproducer each in fuzz/known/. They are counted as "known"
#: so that fuzzing can go on looking for others; SOFTPIPE_FUZZ_STRICT=1 makes them fail
#: again. Remove an entry when its fix lands (tests/test_fuzz.py then reports XPASS).
KNOWN = {
    "obj": [],     # fixed: an index or smoothing group beyond int64 (now in the corpus as regression-*)
    "scene": [],
}
KNOWN_DIR = HERE / "known"


def strict() -> bool:
    return os.environ.get("SOFTPIPE_FUZZ_STRICT", "") not in ("", "0")


def known_issue(target: str, error: BaseException):
    """The KNOWN entry that ``error`` matches, or None."""
    import traceback

    functions = {frame.name for frame in traceback.extract_tb(error.__traceback__)}
    for kind, function in KNOWN[target]:
        if type(error).__name__ == kind and function in functions:
            return kind, function
    return None


class ContractViolation(AssertionError):
    """The target raised its documented error type, but with an empty message."""


def _decode(data: bytes) -> str:
    # load_obj reads files as UTF-8 (a BOM skipped) with errors="replace"; so does every target here.
    return data.decode("utf-8-sig", errors="replace")


def check_obj(data: bytes) -> str:
    """Run the OBJ and MTL parsers on ``data``; returns "ok" or the error class name."""
    from softpipe.scenes.obj import OBJError, parse_mtl, parse_obj

    text = _decode(data)
    outcome = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for parse, name in ((parse_obj, "fuzz.obj"), (parse_mtl, "fuzz.mtl")):
            try:
                result = parse(text, name, base_dir=str(DATA))
            except (OBJError, OSError) as e:
                if not str(e).strip():
                    raise ContractViolation(f"{type(e).__name__} with an empty message") from e
                outcome.append(type(e).__name__)
            except Exception as e:
                if strict() or not known_issue("obj", e):
                    raise
                outcome.append("known-" + type(e).__name__)
            else:
                if parse is parse_obj:
                    _check_mesh(result)
                outcome.append("ok")
    return "/".join(outcome)


def _check_mesh(mesh) -> None:
    import numpy as np

    n = mesh.vertex_count
    assert mesh.indices.ndim == 2 and mesh.indices.shape[1] == 3
    assert mesh.triangle_count == 0 or (0 <= int(mesh.indices.min()) and int(mesh.indices.max()) < n)
    assert np.isfinite(mesh.positions).all()


@functools.lru_cache(maxsize=None)
def _bundled_model(name: str, **kwargs):
    """softpipe.scenes.models.load_model, once per bundled model (a Mesh is a value: sharing it is safe)."""
    import softpipe.scenes.models as models

    return models.load_model(name, **kwargs)


@functools.lru_cache(maxsize=None)
def _bundled_texture(path: str, srgb: bool = False):
    """softpipe's Texture2D of a bundled model's texture file, made once (per sRGB decoding)."""
    return _TEXTURE_2D[0](path, srgb=srgb)


#: softpipe.light.texture.Texture2D, as the library has it.
_TEXTURE_2D: list = []


def _texture(path, *args, **kwargs):
    """Texture2D(path, ...) in the scene target: a bundled model's texture once, other files each time."""
    from softpipe.scenes.models import MODELS_DIR

    if (not args and set(kwargs) <= {"srgb"} and isinstance(path, str)
            and Path(path).resolve().is_relative_to(MODELS_DIR)):
        return _bundled_texture(path, bool(kwargs.get("srgb", False)))
    return _TEXTURE_2D[0](path, *args, **kwargs)


def check_scene(data: bytes) -> str:
    """Run the scene-file parser on ``data``; returns "ok" or "SceneError"."""
    import softpipe.light.texture as texture
    import softpipe.scenes.scenefile as scenefile

    text = _decode(data)
    scenefile.MAX_SCENE_TRIANGLES = FUZZ_SCENE_TRIANGLES
    load_model, scenefile.load_model = scenefile.load_model, _bundled_model
    if not _TEXTURE_2D:
        _TEXTURE_2D.append(texture.Texture2D)
    texture_2d, texture.Texture2D = texture.Texture2D, _texture
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            scenefile.parse_scene(text, "fuzz.toml", base_dir=str(DATA))
        except scenefile.SceneError as e:
            if not str(e).strip() or not e.reason.strip():
                raise ContractViolation("SceneError with an empty message") from e
            return "SceneError"
        except Exception as e:
            if strict() or not known_issue("scene", e):
                raise
            return "known-" + type(e).__name__
        finally:
            scenefile.load_model = load_model      # other users of this process see the library as it is
            texture.Texture2D = texture_2d
    return "ok"


CHECKS = {"obj": check_obj, "scene": check_scene}


def corpus_files(target: str):
    """The committed corpus of a target, sorted by name."""
    folder = CORPUS / target
    return sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))


def run_with_time_limit(check, data: bytes, seconds: float):
    """``check(data)``, raising TimeoutError if it takes longer than ``seconds`` (SIGALRM; main thread)."""
    import signal

    if not hasattr(signal, "setitimer") or os.name != "posix":
        return check(data)

    def expired(signum, frame):
        raise TimeoutError(f"input took longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return check(data)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
