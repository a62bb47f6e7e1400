"""Issue #28, round 3: the golden fixture (update mode rewrites any golden image, golden file
names never collide, an empty mask is an error), damaged kernel cache entries are rebuilt,
and numba-compiled functions stay out of the fuzzer's instrumentation."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from softpipe.testing import assert_pixels_equal, check_golden

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent
PLUGIN = ("-p", "softpipe.testing.plugin", "-p", "no:cacheprovider")


# ------------------------------------------------------------ golden images: update mode


@pytest.mark.parametrize("stored", ["other size", "other channels", "corrupt", "empty file"])
def test_update_mode_rewrites_a_golden_image_of_any_kind(tmp_path, stored):
    path = tmp_path / "golden" / "g.png"
    path.parent.mkdir()
    if stored == "other size":
        Image.fromarray(np.zeros((5, 7, 3), np.uint8)).save(path)
    elif stored == "other channels":
        Image.fromarray(np.zeros((2, 3), np.uint8)).save(path)
    elif stored == "corrupt":
        Image.fromarray(np.zeros((2, 3, 3), np.uint8)).save(path)
        path.write_bytes(path.read_bytes()[:30])
    else:
        path.write_bytes(b"")
    image = np.full((2, 3, 3), 200, np.uint8)
    assert check_golden(image, path, update=True) == "updated"
    assert np.array_equal(np.asarray(Image.open(path)), image)
    assert check_golden(image, path) == "passed"


def test_without_update_a_golden_of_another_size_says_how_to_rewrite_it(tmp_path):
    path = tmp_path / "g.png"
    Image.fromarray(np.zeros((5, 7, 3), np.uint8)).save(path)
    before = path.read_bytes()
    with pytest.raises(ValueError) as info:
        check_golden(np.zeros((2, 3, 3), np.uint8), path, output_dir=tmp_path / "out")
    assert str(info.value) == (f"actual has shape [2, 3, 3] and golden [5, 7, 3]: they cannot be compared pixel by "
                               f"pixel\ngolden image: {path}\n(if the new image is right: pytest "
                               "--softpipe-update-golden rewrites the golden image)")
    assert path.read_bytes() == before


def test_without_update_a_corrupt_golden_says_so(tmp_path):
    path = tmp_path / "g.png"
    path.write_bytes(b"not a png")
    with pytest.raises(ValueError, match=r"^golden: '.*g\.png' is not an image pillow can read .*\n"
                                         r"golden image: .*g\.png\n\(if the new image is right: pytest "
                                         r"--softpipe-update-golden rewrites the golden image\)$"):
        check_golden(np.zeros((2, 3, 3), np.uint8), path)
    assert path.read_bytes() == b"not a png"


SIZE_TEST = '''
import numpy as np
from pathlib import Path

def test_picture(golden):
    h = int(Path(__file__).with_name("height.txt").read_text())
    golden(np.full((h, 4, 3), 9, np.uint8))
'''


def test_the_fixture_in_update_mode_rewrites_a_golden_of_another_size(pytester):
    pytester.makepyfile(test_size=SIZE_TEST)
    (pytester.path / "height.txt").write_text("3")
    pytester.runpytest(*PLUGIN, "--softpipe-update-golden").assert_outcomes(passed=1)
    (pytester.path / "height.txt").write_text("5")
    result = pytester.runpytest(*PLUGIN)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["E *actual has shape [[]5, 4, 3] and golden [[]3, 4, 3]: they cannot be compared*"])
    result = pytester.runpytest(*PLUGIN, "--softpipe-update-golden")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines([f"updated: {pytester.path / 'golden' / 'test_picture.png'}"])
    assert np.asarray(Image.open(pytester.path / "golden" / "test_picture.png")).shape == (5, 4, 3)
    pytester.runpytest(*PLUGIN).assert_outcomes(passed=1)


# ------------------------------------------------------------ golden images: one file per test

IDS_TEST = '''
import numpy as np
import pytest

@pytest.mark.parametrize("v", [1, 2, 3, 4], ids=["a/b", "a-b", "a b", "a_b"])
def test_ids(golden, v):
    golden(np.full((2, 2), v * 10, np.uint8))
'''


def test_parametrize_ids_that_differ_in_replaced_characters_get_files_of_their_own(pytester):
    pytester.makepyfile(test_ids=IDS_TEST)
    pytester.runpytest(*PLUGIN, "--softpipe-update-golden").assert_outcomes(passed=4)
    names = sorted(p.name for p in (pytester.path / "golden").iterdir())
    assert len(names) == 4, names
    assert "test_ids-a-b.png" in names and "test_ids-a_b.png" in names   # plain ids keep their old names
    assert sorted(n for n in names if "~" in n) == sorted(n for n in names if n.startswith("test_ids-a-b~"))
    # each test compares against its own picture: a second run passes without update
    pytester.runpytest(*PLUGIN).assert_outcomes(passed=4)
    values = sorted(int(np.asarray(Image.open(pytester.path / "golden" / n))[0, 0]) for n in names)
    assert values == [10, 20, 30, 40]


SHARED_TEST = '''
import numpy as np

def test_one(golden):
    golden(np.zeros((2, 2), np.uint8), "shared")

def test_two(golden):
    golden(np.ones((2, 2), np.uint8), "shared")
'''


def test_two_tests_using_one_golden_file_is_an_error(pytester):
    pytester.makepyfile(test_shared=SHARED_TEST)
    result = pytester.runpytest(*PLUGIN, "--softpipe-update-golden")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([f"E *ValueError: golden image {pytester.path / 'golden' / 'shared.png'} is already "
                                 "used by test_shared.py::test_one: two tests would overwrite each other's golden "
                                 "image; give one of them its own name="])
    assert np.asarray(Image.open(pytester.path / "golden" / "shared.png")).max() == 0     # test_one's, kept


def test_file_names_are_injective_and_keep_plain_names():
    from softpipe.testing.plugin import _file_name

    assert _file_name("test_x") == "test_x"
    assert _file_name("test_x[a-1]") == "test_x-a-1"
    assert _file_name("second") == "second"
    # a test's name is a Python name with an optional [id]: the first "-" of its file name ends the Python name
    names = ["test_x[a/b]", "test_x[a-b]", "test_x[a b]", "test_x[a:b]", "test_x[a-b~0]", "test_x", "test_x_a[b]",
             "a/b", "a b", "a-b"]
    files = [_file_name(n) for n in names]
    assert len(set(files)) == len(names), files
    assert all(set(f) <= set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.-~") for f in files)


# ------------------------------------------------------------ masks


def test_a_mask_that_compares_no_pixel_is_an_error(tmp_path):
    empty = np.zeros((2, 3), bool)
    message = ("mask is False everywhere: it compares no pixel, so any image would pass (True marks the pixels to "
               "compare; mask=None compares them all)")
    with pytest.raises(ValueError) as info:
        assert_pixels_equal(np.zeros((2, 3)), np.ones((2, 3)), mask=empty)
    assert str(info.value) == message
    path = tmp_path / "g.png"
    Image.fromarray(np.zeros((2, 3), np.uint8)).save(path)
    before = path.read_bytes()
    for update in (False, True):
        with pytest.raises(ValueError) as info:
            check_golden(np.full((2, 3), 255, np.uint8), path, mask=empty, update=update)
        assert str(info.value) == message
    assert path.read_bytes() == before
    with pytest.raises(ValueError):                                   # no golden image: nothing is written either
        check_golden(np.zeros((2, 3), np.uint8), tmp_path / "new.png", mask=empty, update=True)
    assert not (tmp_path / "new.png").exists()


# ------------------------------------------------------------ the fuzzer and numba


def test_numba_compiles_the_original_code_of_an_instrumented_function(tmp_path, monkeypatch):
    """As atheris does, the function's bytecode calls into a module numba cannot type; the hook gives
    numba the source's own bytecode (fuzz/uninstrumented.py)."""
    import types

    import numba
    from numba.core import dispatcher
    from numba.core.errors import TypingError

    monkeypatch.syspath_prepend(str(ROOT / "fuzz"))
    import uninstrumented

    source = tmp_path / "plain.py"
    source.write_text("def add(x):\n    return x + 1\n")
    # "instrumented": the same function, same file and first line, calling a module attribute
    instrumented = compile("def add(x):\n    probe.trace(1)\n    return x + 1\n", str(source), "exec")
    namespace = {"probe": types.SimpleNamespace(trace=lambda n: None)}
    exec(instrumented, namespace)
    with pytest.raises(TypingError):
        numba.njit(namespace["add"])(1)
    monkeypatch.setattr(dispatcher.Dispatcher, "__init__", dispatcher.Dispatcher.__init__)   # undone afterwards
    uninstrumented.keep_numba_uninstrumented()
    exec(instrumented, namespace)
    assert numba.njit(namespace["add"])(1) == 2


@pytest.mark.skipif(sys.platform == "win32", reason="atheris runs on Linux and macOS")
def test_the_scene_target_fuzzes_a_mesh_under_atheris(tmp_path):
    pytest.importorskip("atheris")
    import subprocess

    scene = tmp_path / "cube.toml"
    scene.write_text('[[meshes]]\nshape = "cube"\n')
    run = subprocess.run([sys.executable, str(ROOT / "fuzz" / "fuzz_atheris.py"), "scene", "-runs=1", str(scene)],
                         capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "Executed" in run.stderr and "TypingError" not in run.stderr


# ------------------------------------------------------------ damaged kernel cache entries

DAMAGED_RUN = '''
import numpy as np
from softpipe.language.kernels.cache import load_cached
from softpipe.pipeline.transforms import transform_points

SOURCE = "import numba\\n\\n@numba.njit(cache=True)\\ndef plus_one(x):\\n    return x + 1\\n"
module = load_cached(SOURCE, "softpipe_damaged_probe")            # a generated kernel module, as softpipe's
print(module.plus_one(41))
print(transform_points(np.eye(4) * 2.0, np.array([[1.0, 2.0, 3.0]])).tolist())   # a library function
'''


@pytest.fixture(scope="module")
def warm_caches(tmp_path_factory):
    """Both caches (softpipe's kernel modules, numba's files) after one run, and how to run again."""
    import os
    import shutil
    import subprocess

    root = tmp_path_factory.mktemp("caches")
    live, pristine, script = root / "live", root / "pristine", root / "run.py"
    script.write_text(DAMAGED_RUN)
    env = dict(os.environ, SOFTPIPE_CACHE_DIR=str(live / "kernels"), NUMBA_CACHE_DIR=str(live / "numba"),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))

    def run(*options):
        return subprocess.run([sys.executable, *options, str(script)], env=env, capture_output=True, text=True,
                              timeout=600, cwd=root)

    first = run()
    assert first.returncode == 0 and first.stdout == "42\n[[2.0, 4.0, 6.0]]\n", first.stderr[-3000:]
    shutil.copytree(live, pristine)

    def fresh():
        shutil.rmtree(live)
        shutil.copytree(pristine, live)          # the same paths: numba's cache folders are named after them
        return live

    return fresh, run


@pytest.mark.parametrize("damaged", ["kernel .nbi", "kernel .nbc", "kernel .py", "kernel .pyc", "library .nbi",
                                     "library .nbc"])
def test_a_damaged_cache_entry_is_dropped_and_rebuilt(warm_caches, damaged):
    import py_compile
    from importlib.util import cache_from_source

    fresh, run = warm_caches
    live = fresh()
    where, kind = damaged.split()
    stem = "softpipe_damaged_probe.plus_one" if where == "kernel" else "transforms._transform_points"
    if kind == ".py":
        files = [live / "kernels" / "softpipe_damaged_probe.py"]
    elif kind == ".pyc":
        source = live / "kernels" / "softpipe_damaged_probe.py"
        files = [Path(py_compile.compile(str(source), cfile=cache_from_source(str(source)), doraise=True))]
    else:
        files = list((live / "numba").rglob(f"{stem}-*{kind}"))
    assert files, damaged
    for f in files:
        f.write_bytes(f.read_bytes()[:len(f.read_bytes()) // 2])               # truncated, as by a full disk
    second = run()
    assert second.returncode == 0, second.stderr[-3000:]
    assert second.stdout == "42\n[[2.0, 4.0, 6.0]]\n"
    if kind in (".nbi", ".nbc"):
        name = stem if where == "kernel" else "softpipe.pipeline." + stem
        index = next((live / "numba").rglob(f"{stem}-*.nbi"))
        assert (f"RuntimeWarning: softpipe: numba's cache entry for {name} ({index} and its .nbc files) could not be "
                "read (") in second.stderr, second.stderr[-3000:]
        assert "; it is dropped and the function compiled again" in second.stderr
    else:
        assert "Warning" not in second.stderr, second.stderr[-3000:]
    third = run("-W", "error")                                                # rebuilt: no warning any more
    assert third.returncode == 0 and third.stdout == "42\n[[2.0, 4.0, 6.0]]\n", third.stderr[-3000:]
