"""A user's shader is compiled once, then loaded from the kernel cache in every later process.

Each test runs small scripts in fresh processes (a ``SOFTPIPE_CACHE_DIR`` temporary folder shared by
this file's tests; numba's cache is the suite's own, so softpipe's library kernels are loaded, not
compiled again in every process, and a user's loops cache beside their generated modules) and
counts, with numba's ``numba:compile`` event, the functions each process compiled of the
user's: the generated ``softpipe_user_*`` loops and the shader and helpers of ``__main__``
or ``helpers``. "Loaded" is none of them compiled (not a timing). Each test's shader is
its own (a distinct ``MARK``), so the shared cache never holds it before the test.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: The script's frame: the numba listener, then the user's code ({user}), then one draw whose
#: pixels and compiled functions it prints as JSON.
FRAME = '''
import json, sys, warnings
import numpy as np
from numba.core import event
import softpipe as sp

compiled = []


class Compiles(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        compiled.append(f"{{f.__module__}}.{{f.__qualname__}}")

    def on_end(self, ev):
        pass


event.register("numba:compile", Compiles())
{user}
fb = sp.Framebuffer(16, 12)
positions = np.array([[-0.8, -0.8, 0.0, 1.0], [0.8, -0.8, 0.0, 1.0], [0.0, 0.8, 0.0, 1.0]])
colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    sp.draw(fb, positions, varyings={{"color": colors}}, fragment_shader=shader, uniforms={{"tint": (1.0, 1.0, 1.0)}})
users = [c for c in compiled if c.startswith(("softpipe_user_", "__main__.", "helpers."))]
print(json.dumps({{"pixels": fb.to_uint8(alpha=False).tolist(), "compiled": users,
                  "warnings": [str(w.message) for w in caught]}}))
'''

SHADER = '''
from softpipe.shading import mix

MARK = {mark}
TINT = {tint}


def shader(varyings, uniforms, frag):
    on = int(frag.x) // 4 % 2
    c = mix(varyings.color, uniforms.tint, TINT * on)
    return (c[0], c[1], c[2], MARK)
'''


@pytest.fixture(scope="module")
def caches(tmp_path_factory):
    """The kernel cache, shared by this file's tests."""
    root = tmp_path_factory.mktemp("shader-cache")
    (root / "softpipe").mkdir()
    return root


def numba_files(caches: Path, pattern: str) -> list:
    """numba's cache files of the generated modules matching ``pattern``: beside the modules, or under
    ``$NUMBA_CACHE_DIR`` where the suite sets one."""
    roots = [caches] + ([Path(os.environ["NUMBA_CACHE_DIR"])] if os.environ.get("NUMBA_CACHE_DIR") else [])
    return sorted(p for root in roots for p in root.rglob(pattern))


def run(caches: Path, script_dir: Path, user: str, name: str = "scene.py") -> dict:
    """Run a script drawing with the user's code ``user`` in a fresh process; its JSON report."""
    script_dir.mkdir(parents=True, exist_ok=True)
    script = script_dir / name
    script.write_text(FRAME.format(user=textwrap.dedent(user)))
    return start_done(start(caches, script))


def start(caches: Path, script: Path) -> subprocess.Popen:
    env = dict(os.environ, SOFTPIPE_CACHE_DIR=str(caches / "softpipe"),
               PYTHONPATH=os.pathsep.join([str(ROOT), str(script.parent)]))
    env.pop("NUMBA_DISABLE_JIT", None)
    return subprocess.Popen([sys.executable, str(script)], cwd=script.parent, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def start_done(process: subprocess.Popen) -> dict:
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, err[-3000:]
    return json.loads(out.strip().splitlines()[-1])


def user_modules(caches: Path) -> list:
    return sorted(p.name for p in (caches / "softpipe").glob("softpipe_user_*.py"))


def test_a_second_process_loads_the_shader_instead_of_compiling_it(caches, tmp_path):
    user = SHADER.format(mark=0.501, tint=0.5)
    first = run(caches, tmp_path, user)
    assert any(c.startswith("softpipe_user_fragment_") for c in first["compiled"]), first["compiled"]
    second = run(caches, tmp_path, user)
    assert second["compiled"] == []
    assert second["pixels"] == first["pixels"]
    assert second["warnings"] == []
    # nothing beside the script: the module and numba's files are in the cache folders
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.py"]


def test_a_changed_source_or_global_recompiles_and_the_old_one_is_still_loaded(caches, tmp_path):
    base = SHADER.format(mark=0.502, tint=0.5)
    first = run(caches, tmp_path, base)
    assert first["compiled"]
    # the shader's code changed (a stripe of 2 pixels, not 4)
    changed = run(caches, tmp_path, base.replace("// 4 % 2", "// 2 % 2"))
    assert any(c.startswith("softpipe_user_fragment_") for c in changed["compiled"]), changed["compiled"]
    assert changed["pixels"] != first["pixels"]
    # a global it reads changed
    tinted = run(caches, tmp_path, SHADER.format(mark=0.502, tint=0.25))
    assert any(c.startswith("softpipe_user_fragment_") for c in tinted["compiled"]), tinted["compiled"]
    assert tinted["pixels"] != first["pixels"]
    # a line added above the shader (its line numbers changed, which its errors name): compiled again
    moved = run(caches, tmp_path, "\n" + base)
    assert moved["compiled"] and moved["pixels"] == first["pixels"]
    # and the first version, unchanged, still loads
    again = run(caches, tmp_path, base)
    assert again["compiled"] == [] and again["pixels"] == first["pixels"]


HELPER = '''
def shade(c, x):
    return {body}
'''

CALLER = '''
import helpers

MARK = {mark}


def shader(varyings, uniforms, frag):
    c = varyings.color
    return (helpers.shade(c[0], frag.x), c[1], c[2], MARK)
'''


def test_a_changed_callee_in_another_module_recompiles(caches, tmp_path):
    user = CALLER.format(mark=0.503)
    (tmp_path / "helpers.py").write_text(HELPER.format(body="c"))
    first = run(caches, tmp_path, user)
    assert "helpers.shade" in first["compiled"]
    assert any(c.startswith("softpipe_user_fragment_") for c in first["compiled"]), first["compiled"]
    (tmp_path / "helpers.py").write_text(HELPER.format(body="0.5 * c"))
    changed = run(caches, tmp_path, user)
    assert "helpers.shade" in changed["compiled"], changed["compiled"]
    assert any(c.startswith("softpipe_user_fragment_") for c in changed["compiled"])
    assert changed["pixels"] != first["pixels"]
    loaded = run(caches, tmp_path, user)
    assert loaded["compiled"] == [] and loaded["pixels"] == changed["pixels"]


NOTEBOOK = '''
import linecache
import __main__

# a notebook cell as IPython runs it: source compiled under a synthetic file name that names
# the kernel's process (so it differs in every session), registered with linecache, run in __main__
cell = {cell!r}
filename = "/tmp/ipykernel_{session}/3361874093.py"
linecache.cache[filename] = (len(cell), None, cell.splitlines(True), filename)
exec(compile(cell, filename, "exec"), __main__.__dict__)
'''


def test_a_shader_of_a_notebook_cell_is_loaded_in_the_next_session(caches, tmp_path):
    cell = SHADER.format(mark=0.504, tint=0.5)
    first = run(caches, tmp_path, NOTEBOOK.format(cell=cell, session=1111))
    assert any(c.startswith("softpipe_user_fragment_") for c in first["compiled"]), first["compiled"]
    second = run(caches, tmp_path, NOTEBOOK.format(cell=cell, session=2222))
    assert second["compiled"] == [] and second["pixels"] == first["pixels"]
    changed = run(caches, tmp_path, NOTEBOOK.format(cell=cell.replace("TINT * on", "TINT * on * 0.5"), session=3333))
    assert changed["compiled"] and changed["pixels"] != first["pixels"]


def test_two_processes_compiling_one_new_shader_at_once_both_succeed_with_one_entry(caches, tmp_path):
    user = SHADER.format(mark=0.505, tint=0.5)
    before = set(user_modules(caches))
    scripts = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        script = tmp_path / name / "scene.py"
        script.write_text(FRAME.format(user=user))
        scripts.append(script)
    a, b = [start_done(p) for p in [start(caches, s) for s in scripts]]
    assert a["pixels"] == b["pixels"]
    new = sorted(set(user_modules(caches)) - before)
    assert len(new) == 1, new                  # one module file for the shader
    stem = new[0][:-3]
    indexes = [p.name for p in numba_files(caches, f"{stem}.*.nbi")]
    functions = [name.split(".")[1] for name in indexes]
    assert len(functions) == len(set(functions)), indexes     # one index per compiled loop
    third = run(caches, tmp_path / "c", user)
    assert third["compiled"] == [] and third["pixels"] == a["pixels"]


def test_a_damaged_cache_entry_is_dropped_and_rebuilt(caches, tmp_path):
    user = SHADER.format(mark=0.506, tint=0.5)
    before = set(user_modules(caches))
    first = run(caches, tmp_path, user)
    (stem,) = [name[:-3] for name in set(user_modules(caches)) - before]
    data = numba_files(caches, f"{stem}.*.nbc")
    assert data
    for path in data:
        path.write_bytes(path.read_bytes()[:20])          # truncated
    rebuilt = run(caches, tmp_path, user)
    assert rebuilt["pixels"] == first["pixels"]
    assert any(c.startswith("softpipe_user_fragment_") for c in rebuilt["compiled"])
    assert any("could not be read" in w and stem in w for w in rebuilt["warnings"]), rebuilt["warnings"]
    loaded = run(caches, tmp_path, user)
    assert loaded["compiled"] == [] and loaded["pixels"] == first["pixels"]


def _exec_shader(source: str, filename: str, module_name: str = "__main__"):
    """The function ``shader`` of ``source``, compiled under ``filename`` into a namespace of ``module_name``."""
    namespace = {"__name__": module_name}
    exec(compile(textwrap.dedent(source), filename, "exec"), namespace)
    return namespace["shader"]


def test_the_key_names_the_code_and_values_not_the_file():
    from softpipe.language.kernels.snapshot import shader_source_key
    base = SHADER.format(mark=1.0, tint=0.5)
    key = shader_source_key(_exec_shader(base, "/tmp/ipykernel_1/1.py"))
    assert key is not None and "TINT = ('float','0.5')" in key
    assert shader_source_key(_exec_shader(base, "/tmp/ipykernel_2/9.py")) == key          # another session
    assert shader_source_key(_exec_shader(SHADER.format(mark=1.0, tint=0.25), "/tmp/ipykernel_1/1.py")) != key
    assert shader_source_key(_exec_shader(base.replace("% 2", "% 3"), "/tmp/ipykernel_1/1.py")) != key


def test_a_shader_no_key_can_name_is_compiled_per_process_not_cached():
    from softpipe.language.kernels.snapshot import shader_source_key
    listed = SHADER.format(mark=1.0, tint=0.5).replace("TINT = 0.5", "TINT = [0.5]")
    assert shader_source_key(_exec_shader(listed, "scene.py")) is None               # a list global
    # exec'd in a namespace that is no module: numba's cache could not load it by its module's name
    assert shader_source_key(_exec_shader(SHADER.format(mark=1.0, tint=0.5), "page.md", "__page__")) is None


def test_the_shaders_of_one_varying_layout_share_one_compiled_interpolation():
    """The varyings module is generated once per layout: two shaders' loops import the same ``interpolate``,
    which both draws use at one signature; another layout has its own."""
    import numpy as np

    import softpipe as sp
    from softpipe.language import kernels
    from softpipe.language.contract import VaryingLayout

    def plain(varyings, uniforms, frag):
        c = varyings.shared_layout_color
        return (c[0], c[1], c[2], 1.0)

    def inverted(varyings, uniforms, frag):
        c = varyings.shared_layout_color
        return (1.0 - c[0], 1.0 - c[1], 1.0 - c[2], 1.0)

    layout = VaryingLayout.from_sizes([("shared_layout_color", 3)])
    a, b = kernels.fragment_module(plain, layout), kernels.fragment_module(inverted, layout)
    assert a is not b and a.interpolate is b.interpolate and a.Varyings is b.Varyings
    assert a.fragment_loop is not b.fragment_loop
    assert "def interpolate" not in a.__softpipe_source__ and a.interpolate.__module__.startswith("softpipe_varyings_")
    other = kernels.fragment_module(plain, VaryingLayout.from_sizes([("shared_layout_color", 4)]))
    assert other.interpolate is not a.interpolate

    positions = np.array([[-1.0, -1.0, 0.0, 1.0], [3.0, -1.0, 0.0, 1.0], [-1.0, 3.0, 0.0, 1.0]])
    color = np.full((3, 3), 0.25)
    pictures = []
    for shader in (plain, inverted):
        fb = sp.Framebuffer(4, 3)
        sp.draw(fb, positions, varyings={"shared_layout_color": color}, fragment_shader=shader, path="reference")
        pictures.append(fb.color[..., :3])
    assert np.all(pictures[0] == np.float32(0.25)) and np.all(pictures[1] == np.float32(0.75))
    # one signature, shared: compiled here with the first loop, or none here when both loops came from
    # numba's disk cache (each compiled with interpolate in it, in an earlier run); never a second one
    assert len(a.interpolate.signatures) <= 1
