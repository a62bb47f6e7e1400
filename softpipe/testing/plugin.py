"""softpipe's pytest plugin: the ``golden`` fixture (compare a picture with a stored PNG).

Enabled with ``pytest -p softpipe.testing.plugin``, or by itself when softpipe
is installed (a ``pytest11`` entry point of the same name). In a test::

    def test_teapot(golden):
        golden(sp.render("teapot", width=64, height=48))          # tests/golden/test_teapot.png

- The golden image is ``golden/NAME.png`` in the test file's folder; NAME is the
  test's name (``test_x[param]`` → ``test_x-param``) unless ``name=`` is given; a
  second call in one test needs its own ``name=``. Characters other than letters,
  digits, ``_``, ``.`` and ``-`` become ``-`` and the name gets a hash of the whole
  name (``test_x[a/b]`` → ``test_x-a-b~<8 hex digits>``), so that ids such as
  ``a/b``, ``a-b`` and ``a b`` never share a file; two tests of one pytest process that
  would still use one golden image (two files' ``test_x``, or the same ``name=``) are an
  error.
- It is stored as an 8-bit PNG, and the comparison is of 8-bit values:
  ``tolerance`` (default 0: the same bytes) is in 8-bit levels per channel.
  A Framebuffer is its 8-bit RGB picture (``np.asarray(fb)``).
- A missing golden image is written and the test fails once (look at it, commit it).
- On a difference the test fails with :func:`~softpipe.testing.assert_pixels_equal`'s
  message and writes NAME.actual.png and NAME.diff.png into the test's
  ``tmp_path`` (or ``--softpipe-golden-output DIR``).
- ``pytest --softpipe-update-golden`` rewrites the golden images that differ
  (or have another size or channels, or cannot be read) and writes missing ones,
  and passes; the terminal summary lists them.
- ``mask=`` False everywhere is an error: it would compare no pixel.
"""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest

from softpipe.testing.compare import check_golden

__all__ = ["golden", "Golden"]

_UPDATED = pytest.StashKey[list]()
#: The golden images used in this run: path → the test (node id) that used it.
_OWNERS = pytest.StashKey[dict]()


def pytest_addoption(parser):
    group = parser.getgroup("softpipe", "softpipe golden images")
    group.addoption("--softpipe-update-golden", action="store_true", default=False,
                    help="write the golden images of the tests that use `golden` anew where they differ or are "
                         "missing (then look at the diff before committing)")
    group.addoption("--softpipe-golden-output", default=None, metavar="DIR",
                    help="where failed golden comparisons write NAME.actual.png and NAME.diff.png "
                         "(default: the test's tmp_path)")


def pytest_configure(config):
    config.stash[_UPDATED] = []
    config.stash[_OWNERS] = {}


_PARAMETRIZED = re.compile(r"([A-Za-z0-9_]+)\[([A-Za-z0-9_.-]+)\]")


def _file_name(name: str) -> str:
    """A test's name as a file name: test_x[a-1] → test_x-a-1; test_x[a/b] → test_x-a-b~<hash>.

    Names of letters, digits, ``_.-`` (and a test's name with such an id) keep their
    readable form; any other name gets the first 8 hex digits of the SHA-256 of the whole
    name after a ``~`` (a character the readable forms never hold), so that names
    differing only in the characters replaced have files of their own. Over tests' names
    (a Python name, then maybe ``[id]``) this is one-to-one; a ``name=`` given by hand may
    still equal another test's file name, which :class:`Golden` reports as an error.
    """
    readable = re.sub(r"[^A-Za-z0-9_.-]+", "-", name).strip("-.") or "golden"
    plain = _PARAMETRIZED.fullmatch(name)
    if readable == name or (plain is not None and readable == f"{plain[1]}-{plain[2]}"):
        return readable
    return f"{readable}~{hashlib.sha256(name.encode('utf-8')).hexdigest()[:8]}"


class Golden:
    """The ``golden`` fixture's value: call it with a picture (see the module's docstring)."""

    def __init__(self, request):
        self._request = request
        self._used = set()

    def path(self, name: str | None = None) -> Path:
        """Where the golden image ``name`` (the test's name by default) is stored."""
        name = _file_name(self._request.node.name if name is None else name)
        return Path(self._request.path).parent / "golden" / f"{name}.png"

    def __call__(self, image, name: str | None = None, *, tolerance=0, mask=None) -> str:
        """Compare ``image`` with its golden PNG; returns "passed", "created" or "updated"."""
        __tracebackhide__ = True
        if name is not None and (not isinstance(name, str) or not name.strip()):
            raise ValueError(f"name must be a non-empty str, got {name!r}")
        path = self.path(name)
        if path in self._used:
            raise ValueError(f"golden image {path.name} was already compared in this test: give each call its "
                             "own name=")
        self._used.add(path)
        config = self._request.config
        owners = config.stash[_OWNERS]
        test = self._request.node.nodeid
        other = owners.setdefault(path.resolve(), test)
        if other != test:
            raise ValueError(f"golden image {path} is already used by {other}: two tests would overwrite each "
                             f"other's golden image; give one of them its own name=")
        update = config.getoption("softpipe_update_golden")
        out = config.getoption("softpipe_golden_output")
        out = Path(out) if out else self._request.getfixturevalue("tmp_path")
        result = check_golden(image, path, tolerance=tolerance, mask=mask, update=update, output_dir=out)
        if result != "passed":
            config.stash[_UPDATED].append((result, path))
        return result


@pytest.fixture
def golden(request) -> Golden:
    """Compare a Framebuffer, an array or an image file with ``golden/NAME.png`` next to the test file."""
    return Golden(request)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    changed = config.stash.get(_UPDATED, [])
    if changed:
        terminalreporter.section("softpipe golden images")
        for what, path in changed:
            terminalreporter.write_line(f"{what}: {path}")
