"""The example scripts run, at a tiny size, and write labelled contact sheets."""
import copy
import importlib
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = {   # name: (tiny size, pictures on the sheet)
    "shading_models": (24, 6),
    "specular": (24, 12),
    "shininess": (24, 8),
    "spotlight": (24, 10),
    "attenuation": ((32, 20), 10),
    "materials": (24, 12),
    "cook_torrance_gooch": ((32, 24), 10),
    "antialiasing": ((36, 24), 10),
    "user_program": (24, 4),
    "shadows": (24, 9),
    "shadows_bias": (24, 8),
    "shadows_glass": ((32, 24), 4),
    "shadow_volumes": ((32, 24), 9),
    "raytrace": (24, 9),
    "hall": (24, 9),
    "emission_b_term": (24, 12),
    "fresnel_tir": (24, 8),
    "environment": (24, 10),
    "planar_mirror": ((32, 24), 8),
    "transparency": ((32, 24), 7),
    "instancing": ((32, 24), 3),
    "deferred": ((32, 24), 7),
    "three_ways": (24, 14),
}


@pytest.fixture(scope="module")
def examples():
    sys.path.insert(0, str(EXAMPLES))
    try:
        yield {name: importlib.import_module(name) for name in SCRIPTS}
    finally:
        sys.path.remove(str(EXAMPLES))


def test_every_example_script_is_listed():
    scripts = {p.stem for p in EXAMPLES.glob("*.py")} - {"common"}
    assert scripts == set(SCRIPTS)


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_example_writes_its_contact_sheet(name, examples, tmp_path, capsys, monkeypatch):
    size, count = SCRIPTS[name]
    module = examples[name]
    made = {}       # what sheet(size) returned when main called it (a copy): not rendered a second time below

    def sheet(*args, **kwargs):
        pictures = original(*args, **kwargs)
        made[repr((args, kwargs))] = copy.deepcopy(pictures)
        return pictures
    original = module.sheet
    monkeypatch.setattr(module, "sheet", sheet)
    path = module.main(size, out_dir=tmp_path)
    assert path == tmp_path / f"{name}.png" and path.exists()
    assert str(path) in capsys.readouterr().out
    pictures = made.get(repr(((size,), {}))) or original(size)
    assert len(pictures) == count
    w, h = (size, size) if isinstance(size, int) else size
    for label, picture in pictures.items():
        assert picture.shape == (h, w, 3) and picture.dtype == np.uint8, label
        assert picture.std() > 0, f"{name}: {label!r} is blank"
    sheet = Image.open(path)
    assert sheet.width >= w and sheet.height > h


def test_examples_readme_lists_every_script():
    text = (EXAMPLES / "README.md").read_text()
    for name in SCRIPTS:
        assert f"python examples/{name}.py" in text and f"out/examples/{name}.png" in text
