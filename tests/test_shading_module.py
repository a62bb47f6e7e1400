"""softpipe.shading, the one module a shader author imports from, and the standard vertex shader.

* Every name in ``__all__`` resolves, the star import gives exactly those, and
  the module docstring (the shader author's page) lists each of them.
* Nothing is defined twice: shading.py only imports, and every name is the very
  object of its home module (the module that defines it).
* It offers all of the GLSL math, every lighting function and the packed
  lights' columns.
* ``standard_vertex`` (softpipe/programs/common.py, written with ``eye_space``)
  computes the written-out model-view-projection bit for bit, compiled and as
  Python, and is the vertex shader of the built-in programs.
"""
from __future__ import annotations

import ast
import importlib
import inspect
import re
from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest

import softpipe
from softpipe import shading
from softpipe.language import glsl
from softpipe.light import lighting, packed
from softpipe.programs import PROGRAMS, common

ROOT = Path(__file__).resolve().parent.parent


def test_every_name_in_all_resolves_once_and_the_star_import_gives_exactly_those():
    assert len(shading.__all__) == len(set(shading.__all__)), "a name is listed twice in __all__"
    for name in shading.__all__:
        assert hasattr(shading, name), f"softpipe.shading.__all__ names {name!r}, which it does not have"
    namespace = {}
    exec("from softpipe.shading import *", namespace)
    assert set(namespace) - {"__builtins__"} == set(shading.__all__)


def test_the_contract_names_are_offered():
    for name in ("FragInfo", "DISCARD", "Derivatives", "ShaderError", "Program", "standard_vertex",
                 "eye_space", "facing_normal", "toward_eye", "uniform_or", "light_at", "light_vec3"):
        assert name in shading.__all__


def _imports_of_shading():
    """(module, name) of every name shading.py imports; fails on anything but imports, __all__, a docstring."""
    tree = ast.parse(Path(shading.__file__).read_text())
    imported = []
    for k, node in enumerate(tree.body):
        if k == 0 and isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            continue  # the docstring
        if isinstance(node, ast.ImportFrom):
            module = importlib.import_module("." * node.level + (node.module or ""), "softpipe")
            for alias in node.names:
                assert alias.asname is None, f"shading.py renames {alias.name} as {alias.asname}"
                imported.append((module, alias.name))
            continue
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and node.targets[0].id == "__all__"):
            continue
        raise AssertionError(f"shading.py line {node.lineno}: only imports and __all__ belong here "
                             f"(it re-exports; it defines nothing)")
    return imported


def test_nothing_is_defined_twice_every_name_is_its_home_modules_object():
    imported = _imports_of_shading()
    assert sorted(name for _, name in imported) == sorted(shading.__all__), (
        "shading.py imports a name it does not offer, or offers one it does not import")
    for module, name in imported:
        obj = getattr(shading, name)
        assert getattr(module, name) is obj, f"shading.{name} is not {module.__name__}.{name}"
        home = getattr(obj, "__module__", None)
        if isinstance(home, str):      # functions, classes, numba dispatchers: imported from where defined
            assert home != "softpipe.shading"
            assert home == module.__name__, f"shading imports {name} from {module.__name__}, but it lives in {home}"
            assert getattr(importlib.import_module(home), name) is obj
        else:                          # constants: the module it comes from defines them at top level
            source = Path(module.__file__).read_text()
            assert re.search(rf"^{re.escape(name)}\s*=", source, re.M), (
                f"{name} is imported from {module.__name__}, which does not define it")


def test_it_offers_all_the_glsl_math_every_lighting_function_and_the_light_columns():
    offered = set(shading.__all__)
    assert set(glsl.__all__) <= offered
    assert set(lighting.__all__) <= offered
    functions = {name for name, obj in vars(lighting).items()
                 if not name.startswith("_") and getattr(obj, "__module__", None) == "softpipe.light.lighting"
                 and callable(obj) and not inspect.isclass(obj)}
    assert functions <= offered, f"lighting functions not offered: {sorted(functions - offered)}"
    assert {name for name in packed.__all__ if name.startswith("LIGHT_")} <= offered


def test_the_docstring_lists_every_name_and_defines_the_notes_names():
    doc = shading.__doc__
    for name in shading.__all__:
        assert re.search(rf"(?<![\w]){re.escape(name)}(?![\w])", doc), f"the shading docstring does not list {name}"
    names_section = doc.split("Names (")[1].split("What is offered")[0]
    for symbol in ("P", "N", "L", "V", "H", "R", "B", "ke", "ka", "kd", "ks", "kt", "I_a", "I_d", "I_s"):
        assert re.search(rf"(?<![\w′]){re.escape(symbol)}(?![\w′])", names_section), (
            f"the shading docstring does not define {symbol}")
    assert "def vertex(attributes, uniforms)" in doc and "def fragment(varyings, uniforms, frag)" in doc


def test_examples_user_program_imports_its_shader_things_from_softpipe_shading_only():
    source = (ROOT / "examples" / "user_program.py").read_text()
    modules = re.findall(r"^from (softpipe[\w.]*) import", source, re.M)
    shader_modules = [m for m in modules if m in ("softpipe.language.glsl", "softpipe.light.lighting", "softpipe.light.material",
                                                  "softpipe.programs", "softpipe.programs.common",
                                                  "softpipe.pipeline.vertex", "softpipe.language.contract", "softpipe.shading")]
    assert shader_modules == ["softpipe.shading"]


# --------------------------------------------------------------- standard_vertex

def _written_out(p, n, mv, pr, nm):
    """The model-view-projection of one vertex, every product and sum spelled out (left to right)."""
    eye = tuple(mv[i, 0] * p[0] + mv[i, 1] * p[1] + mv[i, 2] * p[2] + mv[i, 3] for i in range(4))
    clip = tuple(pr[i, 0] * eye[0] + pr[i, 1] * eye[1] + pr[i, 2] * eye[2] + pr[i, 3] * eye[3] for i in range(4))
    normal = tuple(nm[i, 0] * n[0] + nm[i, 1] * n[1] + nm[i, 2] * n[2] for i in range(3))
    return clip, eye[:3], normal


def _scene(seed=7, count=257):
    rng = np.random.default_rng(seed)
    positions = rng.normal(size=(count, 3)) * 3.0
    normals = rng.normal(size=(count, 3))
    model = softpipe.rotate(37.0, (0.3, 1.0, -0.2)) @ softpipe.scale(1.3, 0.7, 2.1) @ softpipe.translate(0.1, -0.4, 0.2)
    mv = softpipe.look_at((1.0, 2.0, 5.0), (0.0, 0.0, 0.0)) @ model
    uniforms = {"model_view": mv, "projection": softpipe.perspective(41.0, 1.3, 0.2, 30.0),
                "normal_matrix": softpipe.normal_matrix(mv)}
    return positions, normals, uniforms


def test_standard_vertex_computes_the_written_out_transforms_bit_for_bit_compiled_and_in_python():
    positions, normals, u = _scene()
    uniforms = softpipe.make_uniforms(u)
    out = softpipe.run_vertex_stage(positions, vertex_shader=common.standard_vertex, uniforms=uniforms,
                                    attributes={"normal": normals})
    mv, pr, nm = (np.asarray(u[k], dtype=np.float64) for k in ("model_view", "projection", "normal_matrix"))
    Attributes = namedtuple("Attributes", ["position", "normal"])
    for k in range(len(positions)):
        clip, eye, normal = _written_out(positions[k], normals[k], mv, pr, nm)
        assert out.position[k].tobytes() == np.array(clip).tobytes()
        assert out.varying("position")[k].tobytes() == np.array(eye).tobytes()
        assert out.varying("normal")[k].tobytes() == np.array(normal).tobytes()
        attrs = Attributes(tuple(float(c) for c in positions[k]), tuple(float(c) for c in normals[k]))
        py_clip, py_varyings = common.standard_vertex(attrs, uniforms)              # as plain Python
        assert np.array(py_clip).tobytes() == np.array(clip).tobytes()
        assert np.array(py_varyings.position).tobytes() == np.array(eye).tobytes()
        assert np.array(py_varyings.normal).tobytes() == np.array(normal).tobytes()


def test_the_built_in_programs_use_the_standard_vertex_shader_next_to_them():
    standard = {"unlit", "normals", "depth", "phong", "phong_phong_specular", "hall", "cook_torrance", "gooch"}
    for name in standard:
        assert PROGRAMS[name].vertex is common.standard_vertex is shading.standard_vertex
    source = inspect.getsource(common.standard_vertex)
    assert "eye_space(attributes, uniforms)" in source


@pytest.mark.parametrize("name", ["phong", "gooch"])
def test_a_program_made_from_shading_draws_like_the_built_in_one(name):
    """A Program of the re-exported standard_vertex and a built-in fragment shader is the built-in program."""
    from softpipe.pipeline.camera import Camera
    from softpipe.scenes import shapes

    mesh = shapes.uv_sphere(segments=16, rings=8)
    camera = Camera(eye=(0.5, 0.4, 3.0))
    builtin = PROGRAMS[name]
    mine = shading.Program("mine", shading.standard_vertex, builtin.fragment)
    pictures = []
    for program in (builtin, mine):
        fb = softpipe.Framebuffer(32, 24)
        softpipe.draw_mesh(fb, mesh, camera, program)
        pictures.append(fb.color.tobytes())
    assert pictures[0] == pictures[1]


def test_it_offers_texture_sampling_and_the_guide_and_lesson_import_it_from_here():
    from softpipe.light import texture as home
    for name in ("texture", "texture_grad", "texture_lod", "mip_level", "texture_size", "Texture2D", "TextureUniform"):
        assert getattr(shading, name) is getattr(home, name), name
    for page in ("docs/texture-mapping.md", "lessons/08_textures.ipynb"):
        text = (ROOT / page).read_text()
        assert "from softpipe.light.texture import" not in text, page
        assert "from softpipe.shading import" in text, page
