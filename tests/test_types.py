"""The public API's annotations hold (issue #27): mypy, configured in pyproject.toml ([tool.mypy]),
finds no error in the package.

mypy runs as ``make test`` installs it (the test extra pins its version), from the repository root
so that it reads that configuration, with its cache in a temporary folder of its own: the suite runs
under pytest-xdist, and parallel runs must not share one cache.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def mypy_cache(tmp_path_factory) -> Path:
    """One cache for this file's runs (the second reuses the standard library's), in no other's way."""
    return tmp_path_factory.mktemp("mypy_cache")


def run_mypy(cache: Path, *files: str) -> subprocess.CompletedProcess:
    """``python -m mypy`` in the repository root: the package (pyproject's ``files``), or ``files``."""
    try:
        import mypy  # noqa: F401
    except ImportError:
        pytest.fail(f"mypy is not installed in {sys.executable}'s environment: pip install -e '.[test]' "
                    "(make test does) or pip install mypy (its version is pinned in pyproject.toml)")
    return subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(cache), *files], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)


def test_the_package_type_checks(mypy_cache):
    result = run_mypy(mypy_cache)
    assert result.returncode == 0, (f"mypy (exit status {result.returncode}) finds errors in softpipe's "
                                    f"annotations:\n{result.stdout}{result.stderr}")
    assert result.stdout.startswith("Success: no issues found"), result.stdout


def test_the_type_check_can_fail(mypy_cache, tmp_path):
    # a wrong annotation, and an ignore comment with nothing to ignore (an error only because
    # pyproject's [tool.mypy] sets warn_unused_ignores: the check reads that configuration)
    wrong = tmp_path / "wrong.py"
    wrong.write_text('def half(n: int) -> str:\n    return n / 2\n\n\nNAME: str = "x"  # type: ignore[assignment]\n')
    result = run_mypy(mypy_cache, str(wrong))
    assert result.returncode == 1, result.stdout + result.stderr
    assert (f'{wrong}:2: error: Incompatible return value type (got "float", expected "str")  [return-value]'
            in result.stdout.splitlines()), result.stdout
    assert f'{wrong}:5: error: Unused "type: ignore" comment  [unused-ignore]' in result.stdout.splitlines(), \
        result.stdout
