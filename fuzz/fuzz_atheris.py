"""Coverage-guided fuzzing of one target with atheris (libFuzzer for Python).

    python fuzz/fuzz_atheris.py TARGET [libFuzzer options] [CORPUS_DIR ...]

TARGET is ``obj`` or ``scene`` (see targets.py). softpipe (and, for the scene target,
the standard library's tomllib) is instrumented for coverage; numpy and numba are not,
nor are softpipe's numba-compiled functions (numba cannot compile atheris's calls;
see uninstrumented.py).
Usually started by run.py, which passes the time budget, the per-input timeout, the
dictionary and the corpus folders.
"""
from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import atheris  # noqa: E402

# The target comes first; it is also put in the environment, because libFuzzer's -merge
# and -fork modes run this script again with the options alone.
if len(sys.argv) >= 2 and sys.argv[1] in ("obj", "scene"):
    os.environ["SOFTPIPE_FUZZ_TARGET"] = sys.argv.pop(1)
TARGET = os.environ.get("SOFTPIPE_FUZZ_TARGET")
if TARGET not in ("obj", "scene"):
    sys.exit("usage: fuzz_atheris.py obj|scene [libFuzzer options] [corpus dirs]")
# libFuzzer re-runs argv[0] through the shell: make it "python this-script".
sys.argv[0] = f"{sys.executable} {os.path.abspath(__file__)}"

# Heavy dependencies first, uninstrumented; then softpipe (and tomllib) under instrumentation.
import numba  # noqa: E402,F401
import numpy  # noqa: E402,F401
import PIL.Image  # noqa: E402,F401
from uninstrumented import keep_numba_uninstrumented  # noqa: E402

keep_numba_uninstrumented()
with atheris.instrument_imports(include=["softpipe", "tomllib"]):
    import tomllib  # noqa: F401

    import softpipe.scenes.obj  # noqa: F401
    import softpipe.scenes.scenefile  # noqa: F401

import targets  # noqa: E402

check = targets.CHECKS[TARGET]


def test_one_input(data: bytes) -> None:
    check(data)


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
