"""The house rules of the module layout (issue #12), checked on the source.

- No import circle among softpipe's modules.
- The stages import only earlier stages: vertex → assembly → setup → raster →
  fragment → output → visibility (the fast order of the same stages) → pipeline.
  A stage never imports a later one, directly or through another module.
- Generated shader modules import only the contract (softpipe.shader) and the
  module that generated them (softpipe.kernels), which names in its own
  imports everything the generated code calls.
"""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import softpipe as sp
from softpipe import kernels
from softpipe.shader import VaryingLayout

PACKAGE = Path(sp.__file__).parent
#: The pipeline's modules in order; each may import only those before it.
STAGES = ["vertex", "assembly", "setup", "raster", "fragment", "output", "visibility", "pipeline"]


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join(parts)


def _imports(path: Path) -> set:
    """softpipe modules imported by a file, at any depth in it (function-level imports included)."""
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)] if node.level > 1 else package
                mod = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.startswith("softpipe"):
                mod = node.module[len("softpipe."):] if node.module != "softpipe" else ""
            else:
                continue
            if node.module is None or mod == "":     # from . import x, y
                for alias in node.names:
                    found.add(".".join([m for m in (mod, alias.name) if m]))
            else:
                found.add(mod)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("softpipe."):
                    found.add(alias.name[len("softpipe."):])
    return found


def _graph() -> dict:
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in files.items():
        graph[name] = {m for m in _imports(path) if m in files and m != name}
    return graph


def _reachable(graph: dict, start: str) -> set:
    seen, todo = set(), list(graph.get(start, ()))
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph.get(m, ()))
    return seen


def test_the_import_graph_sees_the_imports_it_should():
    graph = _graph()
    assert {"assembly", "setup", "sampling"} <= graph["raster"]
    assert {"raster", "setup", "output", "fragment", "kernels"} <= graph["visibility"]
    assert "kernels" in graph["vertex"]


def test_no_import_circle():
    graph = _graph()
    circles = sorted(m for m in graph if m in _reachable(graph, m) and m != "")
    assert not circles, f"modules that import themselves through others: {circles}"


def test_no_stage_imports_a_later_stage():
    graph = _graph()
    for k, stage in enumerate(STAGES):
        later = set(STAGES[k + 1:])
        reached = _reachable(graph, stage) & later
        assert not reached, f"{stage}.py reaches the later stage(s) {sorted(reached)}"


def test_generated_modules_import_only_the_contract_their_generator_and_the_setup():
    def shader(varyings, uniforms, frag):
        return (varyings.c, 0.0, 0.0, 1.0)

    source = kernels.fragment_module(shader, VaryingLayout.from_sizes([("c", 1)])).__softpipe_source__
    imports = {m for line in source.splitlines() if line.startswith(("import ", "from "))
               for m in [line.split()[1]]}
    assert imports == {"numba", "collections", "softpipe.shader", "softpipe.kernels", "softpipe.setup"}, imports
    from softpipe import raster
    names = {n.strip() for line in source.splitlines() if line.startswith("from softpipe.setup import")
             for n in line.split("import", 1)[1].split(",")}
    assert {"pixel_coverage", "shading_point"} <= names
    for name in {"pixel_coverage", "shading_point"}:       # the rasterizer calls the very same functions
        assert getattr(raster, name) is getattr(sp.setup, name), name


def test_the_fast_path_and_the_reference_share_one_triangle_setup():
    """The setup a draw's fragments carry is the one the visibility pass used: same arrays, same numbers."""
    fb = sp.Framebuffer(192, 160)
    pos = np.array([[-0.9, -0.8, 0.2, 1.0], [0.7, -0.9, -0.1, 1.0], [0.1, 0.95, 0.4, 1.0]])
    col = np.eye(3)
    stages = {}
    call = sp.DrawCall(fb, pos, varyings={"color": col}, path="fast")
    for st in call.steps():
        stages[st.name] = st.output
    ref = sp.DrawCall(sp.Framebuffer(192, 160), pos, varyings={"color": col}, path="reference")
    frags = [st.output for st in ref.steps() if st.name == "raster"][0]
    a, b = stages["visibility"].setup, frags.setup
    for field in ("edges", "bias", "area", "plane", "box"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert call.path_taken == "fast" and ref.path_taken == "reference"
