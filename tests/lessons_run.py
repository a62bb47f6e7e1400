"""Runs a lesson notebook headless for tests/test_lessons*.py (lessons/run.py does the work)."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

LESSONS = Path(__file__).resolve().parent.parent / "lessons"
NOTEBOOKS = ["01_lines", "02_triangles", "03_zbuffer", "04_interpolation", "05_camera", "06_clipping", "07_shading",
             "08_textures", "09_shadows", "10_rays"]


def runner():
    for name in ("nbclient", "nbformat", "ipykernel"):
        pytest.importorskip(name, reason=f"{name} runs the lessons' notebooks: pip install -e '.[test]'")
    spec = importlib.util.spec_from_file_location("lessons_run_script", LESSONS / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_both(name: str):
    """The notebook as given and with the solutions, in one kernel (lessons/run.py's ``run_both``): the texts
    of the errors its exercises' skeletons stop with, in order, without colors, and the solutions' notebook."""
    failures, nb = runner().run_both(LESSONS / f"{name}.ipynb")
    return [re.sub(r"\x1b\[[0-9;]*m", "", text) for text in failures], nb
