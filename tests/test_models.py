"""The bundled models (softpipe/scenes/models.py, softpipe/data/models/): present, unchanged, found by name."""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest

import softpipe
from softpipe.scenes import models
from softpipe.scenes.models import MODELS, MODELS_DIR, TEXTURES, load_model, model_path, texture_path

README = MODELS_DIR / "README.md"


def readme_checksums():
    """{relative path: sha256} from the README's SHA-256 block."""
    text = README.read_text(encoding="utf-8")
    block = text.split("SHA-256:", 1)[1].split("```")[1]
    sums = {}
    for line in block.strip().splitlines():
        m = re.fullmatch(r"([0-9a-f]{64})  (\S+)", line.strip())
        assert m, f"not a checksum line: {line!r}"
        sums[m.group(2)] = m.group(1)
    return sums


def shipped_files():
    """Every file in the models folder but the README and .gitattributes, as relative paths."""
    return sorted(p.relative_to(MODELS_DIR).as_posix() for p in MODELS_DIR.rglob("*")
                  if p.is_file() and p.name not in ("README.md", ".gitattributes"))


def test_every_shipped_file_has_the_readme_checksum():
    sums = readme_checksums()
    files = shipped_files()
    assert files == sorted(sums), "the README's checksum list and the shipped files differ"
    for rel in files:
        digest = hashlib.sha256((MODELS_DIR / rel).read_bytes()).hexdigest()
        assert digest == sums[rel], f"{rel}: SHA-256 {digest}, README says {sums[rel]}"


def test_every_model_and_texture_is_a_shipped_file():
    files = set(shipped_files())
    assert set(MODELS.values()) <= files
    assert set(TEXTURES.values()) <= files
    assert set(TEXTURES) <= set(MODELS)
    assert sorted(MODELS) == sorted(["bunny", "teapot", "suzanne", "spot", "armadillo"])


def test_the_package_exports_the_two_functions():
    assert softpipe.load_model is load_model
    assert softpipe.model_path is model_path


def test_model_path_names_the_bundled_file():
    for name, rel in MODELS.items():
        path = model_path(name)
        assert isinstance(path, Path)
        assert path == MODELS_DIR / rel and path.is_file()
    assert model_path("bunny").name == "stanford-bunny.obj"


def test_model_path_leaves_paths_alone(tmp_path, monkeypatch):
    assert model_path("some/dir/bunny") == Path("some/dir/bunny")
    assert model_path("missing.obj") == Path("missing.obj")       # a suffix: a path, even if absent
    assert model_path(tmp_path / "bunny") == tmp_path / "bunny"     # PathLike: always a path
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mymesh").write_text("v 0 0 0\n")
    assert model_path("mymesh") == Path("mymesh")                   # a bare word that is a file
    (tmp_path / "bunny").write_text("v 0 0 0\n")
    assert model_path("bunny") == MODELS_DIR / MODELS["bunny"]      # a model name wins
    assert model_path("./bunny") == Path("./bunny")


def test_an_unknown_bare_name_lists_the_models():
    with pytest.raises(ValueError, match=r"'bunnie'.*bunny, teapot, suzanne, spot"):
        model_path("bunnie")
    with pytest.raises(ValueError, match="bunny"):
        load_model("bunnie")
    with pytest.raises(TypeError):
        model_path(3)


def test_texture_path():
    assert texture_path("spot") == MODELS_DIR / "spot" / "spot_texture.png"
    assert texture_path("spot").is_file()
    assert texture_path("bunny") is None
    assert texture_path(str(model_path("spot"))) is None            # a path: textures come from its MTL
    with pytest.raises(ValueError):
        texture_path("cow")


@pytest.mark.parametrize("name, triangles", [("teapot", 6320), ("suzanne", 968), ("spot", 5856)])
def test_load_model_loads_the_obj(name, triangles):
    mesh = load_model(name)
    assert isinstance(mesh, softpipe.Mesh)
    assert mesh.triangle_count == triangles
    assert mesh.triangle_count == softpipe.load_obj(model_path(name)).triangle_count


def test_load_model_gives_spot_its_texture_and_others_none():
    spot = load_model("spot")
    assert spot.material.diffuse_texture == str(texture_path("spot"))
    assert load_model("teapot").material.diffuse_texture is None
    # By path it is a plain OBJ load: no texture without an MTL file.
    assert load_model(model_path("spot")).material.diffuse_texture is None


def test_the_docstring_lists_every_model():
    for name, rel in MODELS.items():
        assert f"``{name}``: ``{rel}``" in models.__doc__
