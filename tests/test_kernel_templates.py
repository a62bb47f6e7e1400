"""The generated loops are written from templates a linter reads (softpipe/language/kernels/templates/).

- Each template is a Python module whose functions name nothing it does not
  define: a linter (pyflakes, ruff) reads it without an undefined name.
- The rules of kernels/template.py: full-line comments left out, trailing ones
  kept; an ``if`` on constants replaced by its branch; placeholders filled; a
  placeholder or constant the template does not name is an error.
- What the generator writes from them: no placeholder is left, the loop for
  shading at the samples has no multisampling branch.
- The templates are shipped (pyproject's package data) and hashed into the key of
  the on-disk kernel cache: an edited template cannot load a stale kernel.
"""
from __future__ import annotations

import ast
import builtins
import fnmatch
import re
import symtable
import sys

import pytest

from softpipe.language.contract import VaryingLayout
from softpipe.language.kernels import cache, generate, template
from softpipe.language.kernels.template import TEMPLATE_DIR, template_expression, template_files, template_function

ROOT = cache.PACKAGE_DIR.parent


def test_every_template_names_only_what_it_defines():
    files = template_files()
    assert {p.name for p in files} >= {"vertex.py", "fragment.py", "varyings.py"}
    for path in files:
        text = path.read_text()
        module = symtable.symtable(text, str(path), "exec")
        defined = set(module.get_identifiers()) | set(dir(builtins))
        for table in module.get_children():
            for symbol in table.get_symbols():
                if symbol.is_global() and symbol.is_referenced():
                    assert symbol.get_name() in defined, f"{path.name}:{table.get_name()}: {symbol.get_name()}"
        compile(text, str(path), "exec")


@pytest.fixture
def own_templates(tmp_path, monkeypatch):
    """Templates written by the test, read by template.py instead of softpipe's."""
    monkeypatch.setattr(template, "TEMPLATE_DIR", tmp_path)
    template._template.cache_clear()
    template._expression_text.cache_clear()
    yield tmp_path
    template._template.cache_clear()
    template._expression_text.cache_clear()


EXAMPLE = '''\
def JIT(f):
    return f


FLAG = OTHER = BODY = VALUE = None


@JIT
def loop(n, out):
    # a note for the template's reader
    total = 0.0  # kept: part of the code
    if FLAG:
        total = 1.0
    else:
        # not written
        total = 2.0
    for i in range(n):
        BODY(i, total)
        out[i] = VALUE
    if not OTHER:
        out[0] = OTHER
    return total


def expression(t, K):
    """A component."""
    return t[K] * K
'''


def test_the_rules_of_a_template(own_templates):
    (own_templates / "example.py").write_text(EXAMPLE)
    source = template_function("example", "loop", {"FLAG": False, "OTHER": 0}, {"BODY": ["a = i", "b = a"],
                                                                               "VALUE": "a + b"}, rename="done")
    assert source == ("@JIT\n"
                      "def done(n, out):\n"
                      "    total = 0.0  # kept: part of the code\n"
                      "    total = 2.0\n"
                      "    for i in range(n):\n"
                      "        a = i\n"
                      "        b = a\n"
                      "        out[i] = a + b\n"
                      "    out[0] = 0\n"
                      "    return total\n")
    taken = template_function("example", "loop", {"FLAG": True, "OTHER": 1}, {"BODY": [], "VALUE": "0.0"})
    assert "    total = 1.0\n    for i in range(n):\n        out[i] = 0.0\n    return total\n" in taken
    assert template_expression("example", "expression", {"K": 2}) == "t[2] * 2"


def test_a_template_and_its_generator_must_agree(own_templates):
    (own_templates / "example.py").write_text(EXAMPLE)
    fill = {"BODY": [], "VALUE": "0.0"}
    with pytest.raises(ValueError, match="UNKNOWN"):
        template_function("example", "loop", {"FLAG": True, "OTHER": 1}, dict(fill, UNKNOWN="x"))
    with pytest.raises(ValueError, match="SPARE"):
        template_function("example", "loop", {"FLAG": True, "OTHER": 1, "SPARE": 0}, fill)
    with pytest.raises(ValueError, match="statements"):
        template_function("example", "loop", {"FLAG": True, "OTHER": 1}, {"BODY": "x", "VALUE": "0.0"})
    with pytest.raises(KeyError):
        template_function("example", "missing")


SMOOTH_FLAT_NOPERSPECTIVE = VaryingLayout((("n", 0, 3, "smooth"), ("id", 3, 1, "flat"), ("uv", 4, 2, "noperspective")))


@pytest.mark.parametrize("layout", [VaryingLayout(), SMOOTH_FLAT_NOPERSPECTIVE])
@pytest.mark.parametrize("derivatives", [False, True])
def test_the_generated_loops_have_no_placeholder_left(layout, derivatives):
    # the layout's varyings module, then a shader's loops
    body = generate._varyings_body(layout, derivatives) + "\n\n" + generate._fragment_body(derivatives)
    tree = ast.parse(body)
    assert [f.name for f in tree.body] == ["interpolate", "fragment_inputs", "inputs_loop", "fragment_loop",
                                           "visible_loop", "visible_loop_at_samples"]
    assert body.count("out_varyings[r, ") == max(layout.width, 1)     # inputs_loop: a column per component
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    assert {n for n in names if re.fullmatch(r"[A-Z][A-Z0-9_]+", n)} == {"JIT"}
    assert ("derivatives" in names) == derivatives
    at_samples = ast.get_source_segment(body, tree.body[-1])
    assert "shading ==" not in at_samples and "pixel_coverage" not in at_samples
    assert "positions, 0)" in at_samples and "positions, shading)" in ast.get_source_segment(body, tree.body[-2])
    assert not any(line.strip().startswith("#") for line in body.splitlines())     # the notes stay behind
    vertex = generate._vertex_body([("position", 3), ("w", 1)], layout)
    assert "def vertex_loop(lo, hi, a_position, a_w, uniforms, out_position, out_varyings):" in vertex
    assert "Attributes((a_position[i, 0], a_position[i, 1], a_position[i, 2]), a_w[i, 0])" in vertex
    assert vertex.count("out_varyings[i, ") == layout.width


def test_the_templates_are_hashed_into_the_kernel_cache_key(tmp_path, monkeypatch):
    assert set(template_files()) <= set(cache.hashed_sources())
    package = tmp_path / "softpipe"
    templates = package / "language" / "kernels" / "templates"
    templates.mkdir(parents=True)
    (package / "module.py").write_text("X = 1\n")
    (templates / "loop.py").write_text("def loop():\n    pass\n")
    (templates / "notes.txt").write_text("a template of another kind\n")
    monkeypatch.setattr(cache, "PACKAGE_DIR", package)
    monkeypatch.setattr(template, "TEMPLATE_DIR", templates)
    monkeypatch.setattr(cache, "_PACKAGE_HASH", [])

    def fresh_hash():
        cache._PACKAGE_HASH.clear()
        return cache.package_hash()

    first = fresh_hash()
    assert templates / "notes.txt" in cache.hashed_sources()
    (templates / "loop.py").write_text("def loop():\n    return 1\n")
    second = fresh_hash()
    (templates / "notes.txt").write_text("edited\n")
    assert len({first, second, fresh_hash()}) == 3


def test_the_templates_are_package_data():
    tomllib = pytest.importorskip("tomllib") if sys.version_info >= (3, 11) else pytest.importorskip("tomli")
    with open(ROOT / "pyproject.toml", "rb") as f:
        patterns = tomllib.load(f)["tool"]["setuptools"]["package-data"]["softpipe"]
    for path in template_files():
        relative = path.relative_to(cache.PACKAGE_DIR).as_posix()
        assert any(fnmatch.fnmatch(relative, p) for p in patterns), relative
    assert TEMPLATE_DIR == cache.PACKAGE_DIR / "language" / "kernels" / "templates"
