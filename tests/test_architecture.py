"""The house rules of the module layout (issues #12 and #27), checked on the source.

- The folders of softpipe/ are layers, bottom to top (FOLDERS): a module imports only
  modules of its own folder and of the folders below it. The library never imports the
  tools (softpipe.tools): the command line, the demo and batch import the library.
- No import circle among softpipe's modules.
- The stages import only earlier stages (STAGES, the order of softpipe/pipeline/):
  a stage never imports a later one, directly or through another module.
- No private name crosses a module: nothing imports a name that starts with ``_`` from
  another softpipe module, or reaches one as ``module._name``; and a module that lists
  its ``__all__`` lists every name another module imports from it.
- Generated shader modules import only the contract (softpipe.language.contract), the
  module that generated them (softpipe.language.kernels), which names in its own
  imports everything the generated code calls, and the triangle setup.
"""
from __future__ import annotations

import ast
import importlib
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import softpipe as sp
from softpipe.language import kernels
from softpipe.language.contract import VaryingLayout

PACKAGE = Path(sp.__file__).parent
#: softpipe/'s folders, bottom to top: each imports only itself and the folders before it.
FOLDERS = ["core", "language", "pipeline", "rays", "light", "tracers", "programs", "views", "scenes",
           "tools"]
#: The top-level modules and the highest folder each may import: the shader author's one import
#: sits above the programs it re-exports; softpipe.testing needs only the pipeline.
TOP_LEVEL = {"shading": "programs", "testing": "views", "": "scenes", "__main__": "tools"}
#: Imports made at call time that reach *up* a layer, each a convenience on the API, named here
#: so that no other one can creep in: a trace draws its pictures and writes its explorer page
#: with the views, diffs itself against another with them (views.diff) and lists its vertices
#: (views.mesh_view); ``softpipe.batch`` is the batch tool, imported on first use, and so is the live
#: viewer behind ``softpipe.view`` (tools.viewer); a small framebuffer shows itself zoomed in Jupyter (views.zoom).
LATE_UPWARD = {("pipeline.trace", "views.pictures"), ("pipeline.trace", "views.explorer"),
               ("pipeline.trace", "views.diff"), ("pipeline.trace", "views.mesh_view"), ("", "tools.batch"),
               ("pipeline.framebuffer", "views.zoom"), ("", "tools.viewer")}
#: softpipe/pipeline/ in pipeline order; each may import only those before it.
STAGES = ["transforms", "camera", "sampling", "framebuffer", "vertex", "assembly", "setup", "lines", "points",
          "raster", "fragment", "merge_state", "output", "tiles", "primitive_tiles", "visibility", "primitive_visibility",
          "trace", "draw"]


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
            if mod:
                found.add(mod)
            for alias in node.names:                 # from softpipe.language import kernels
                found.add(".".join([m for m in (mod, alias.name) if m]))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("softpipe."):
                    found.add(alias.name[len("softpipe."):])
    return found


def _graph() -> dict:
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in files.items():
        found = {m for m in _imports(path) if m in files and m != name}
        # `from softpipe.tools import batch` imports the module batch; the package is its way there
        graph[name] = {m for m in found if not any(o.startswith(m + ".") for o in found)}
    return graph


def _reachable(graph: dict, start: str) -> set:
    seen, todo = set(), list(graph.get(start, ()))
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph.get(m, ()))
    return seen


def _layer(module: str) -> int:
    """Where a module stands: its folder's place in FOLDERS, or for a top-level module the
    place of the highest folder it may import."""
    head = module.split(".")[0] if module else ""
    if head in FOLDERS:
        return FOLDERS.index(head)
    return FOLDERS.index(TOP_LEVEL[head])


def test_the_import_graph_sees_the_imports_it_should():
    graph = _graph()
    assert {"pipeline.assembly", "pipeline.setup", "pipeline.sampling"} <= graph["pipeline.raster"]
    assert {"pipeline.raster", "pipeline.setup", "pipeline.output", "pipeline.fragment", "pipeline.tiles",
            "language.kernels"} <= graph["pipeline.visibility"]
    assert {"pipeline.setup", "pipeline.output", "pipeline.sampling"} <= graph["pipeline.tiles"]
    assert "language.kernels" in graph["pipeline.vertex"]
    assert "scenes.drawing" in graph["tools.cli"]


def test_every_module_lives_in_a_known_folder():
    for module in _graph():
        head = module.split(".")[0] if module else ""
        assert head in FOLDERS or head in TOP_LEVEL or head == "data", \
            f"softpipe.{module}: put it in one of the folders {FOLDERS} (or name it in TOP_LEVEL)"


def test_a_module_imports_only_its_folder_and_the_folders_below():
    graph = _graph()
    upward = set()
    for module, imported in graph.items():
        for other in imported:
            if _layer(other) > _layer(module):
                upward.add((module, other))
    unexpected = sorted(upward - LATE_UPWARD)
    assert not unexpected, f"imports that reach up a layer (FOLDERS: {FOLDERS}): {unexpected}"
    assert upward == LATE_UPWARD, f"LATE_UPWARD names imports that are gone: {sorted(LATE_UPWARD - upward)}"


def test_the_upward_imports_are_made_at_call_time():
    """The named exceptions import inside a function, so importing a lower layer never loads a higher one."""
    for module, other in LATE_UPWARD:
        path = PACKAGE / (module.replace(".", "/") + ".py") if module else PACKAGE / "__init__.py"
        tree = ast.parse(path.read_text())
        top = {n.module for n in tree.body if isinstance(n, ast.ImportFrom) and n.module}
        assert f"softpipe.{other}" not in top and not any(m.startswith(f"softpipe.{other}") for m in top), \
            (module, other)


def test_no_import_circle():
    graph = _graph()
    circles = sorted(m for m in graph if m in _reachable(graph, m) and m != "")
    assert not circles, f"modules that import themselves through others: {circles}"


def test_no_stage_imports_a_later_stage():
    graph = _graph()
    assert sorted(STAGES) == sorted(m.split(".")[1] for m in graph if m.startswith("pipeline.")), \
        "STAGES lists softpipe/pipeline/'s modules in pipeline order: add the new one where it belongs"
    for k, stage in enumerate(STAGES):
        later = {f"pipeline.{s}" for s in STAGES[k + 1:]}
        reached = _reachable(graph, f"pipeline.{stage}") & later
        if stage == "trace":     # the trace's views (LATE_UPWARD) reach the draw only at call time
            reached -= {"pipeline.draw"}
        assert not reached, f"pipeline/{stage}.py reaches the later stage(s) {sorted(reached)}"


def test_the_fill_rule_is_stated_once_in_the_triangle_setup():
    """No pipeline module but setup.py reads a fill-rule bias: the reference rasterizer and the fast
    path's tile walk hand it to setup's rule (inside_edge, inside, covers, pixel_coverage) instead of
    restating E_k + bias_k ≥ 0, so the two back ends cannot disagree on a sample on an edge."""
    for path in sorted((PACKAGE / "pipeline").glob("*.py")):
        if path.stem == "setup":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "bias":
                raise AssertionError(f"softpipe/pipeline/{path.name}, line {node.lineno}, reads bias[...] itself: "
                                     "ask the triangle setup's fill rule (setup.inside_edge, inside, covers)")
    from softpipe.pipeline import setup, tiles
    for name in ("inside_edge", "inside", "covers"):       # the tile walk calls the very same functions
        assert getattr(tiles, name) is getattr(setup, name), name


def test_generated_modules_import_only_the_contract_their_generator_and_the_setup():
    def shader(varyings, uniforms, frag):
        return (varyings.c, 0.0, 0.0, 1.0)

    source = kernels.fragment_module(shader, VaryingLayout.from_sizes([("c", 1)])).__softpipe_source__
    def imports_of(source):
        return {m for line in source.splitlines() if line.startswith(("import ", "from ")) for m in [line.split()[1]]}

    imports = imports_of(source)
    varyings = {m for m in imports if m.startswith("softpipe_varyings_")}     # its layout's varyings module
    assert len(varyings) == 1 and imports - varyings == {
        "numba", "collections", "softpipe.language.contract", "softpipe.language.kernels",
        "softpipe.pipeline.setup"}, imports
    assert imports_of(sys.modules[varyings.pop()].__softpipe_source__) == {
        "numba", "collections", "softpipe.language.contract", "softpipe.language.kernels"}
    from softpipe.pipeline import raster, setup
    names = {n.strip() for line in source.splitlines() if line.startswith("from softpipe.pipeline.setup import")
             for n in line.split("import", 1)[1].split(",")}
    assert {"pixel_coverage", "shading_point"} <= names
    for name in {"pixel_coverage", "shading_point"}:       # the rasterizer calls the very same functions
        assert getattr(raster, name) is getattr(setup, name), name


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


def _names_crossing_modules(path: Path):
    """(line, module, name) for every name a file takes from another softpipe module: each
    ``from softpipe.x import name`` and each ``alias.name`` where alias is a softpipe module
    imported by the file (``from softpipe.views import pictures as P`` … ``P.name``)."""
    tree = ast.parse(path.read_text())
    modules = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("softpipe") \
                and not node.level:
            for alias in node.names:
                yield node.lineno, node.module, alias.name
                full = f"{node.module}.{alias.name}"
                if importlib.util.find_spec(full.split(".")[0]) and _is_module(full):
                    modules[alias.asname or alias.name] = full
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("softpipe.") and alias.asname:
                    modules[alias.asname] = alias.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules:
            yield node.lineno, modules[node.value.id], node.attr


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def test_no_private_name_crosses_a_module():
    crossing = [f"{path.relative_to(PACKAGE.parent)}:{line}: {module}.{name}"
                for path in sorted(PACKAGE.rglob("*.py"))
                for line, module, name in _names_crossing_modules(path)
                if name.startswith("_") and not name.startswith("__")]
    assert not crossing, "private names used outside their module:\n" + "\n".join(crossing)


def test_a_modules_all_lists_what_the_others_import_from_it():
    missing = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for line, module, name in _names_crossing_modules(path):
            target = importlib.import_module(module)
            public = getattr(target, "__all__", None)
            if public is None or hasattr(target, "__path__") and _is_module(f"{module}.{name}"):
                continue
            if name not in public and not name.startswith("__"):
                missing.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {module}.{name}")
    assert not missing, "imported but not in the module's __all__:\n" + "\n".join(missing)


def test_the_crossing_check_sees_a_private_import_and_a_private_attribute(tmp_path):
    """The check above must be able to fail: on a made-up file it finds both forms."""
    fake = tmp_path / "fake.py"
    fake.write_text("from softpipe.light.texture import _wrap\nfrom softpipe.views import pictures as P\n"
                    "P._to_image_xy(None, 1)\n")
    found = {(module, name) for _, module, name in _names_crossing_modules(fake)}
    assert ("softpipe.light.texture", "_wrap") in found
    assert ("softpipe.views.pictures", "_to_image_xy") in found


def test_the_version_is_the_one_pyproject_states():
    from softpipe.core.version import VERSION
    tomllib = pytest.importorskip("tomllib")     # Python 3.11+
    pyproject = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
    assert VERSION == pyproject["project"]["version"] == sp.__version__
