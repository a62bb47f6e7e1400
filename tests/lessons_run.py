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
    """The notebook as given and with the solutions, in one kernel (lessons/run.py's ``run_both``): the text
    of the error it stops with as given (None if none), without colors, and the solutions' notebook."""
    failure, nb = runner().run_both(LESSONS / f"{name}.ipynb")
    return (None if failure is None else re.sub(r"\x1b\[[0-9;]*m", "", failure)), nb


def failure(name: str) -> str:
    """The text of the error the notebook stops with, run as it is (the skeleton), without colors."""
    from nbclient.exceptions import CellExecutionError
    with pytest.raises(CellExecutionError) as info:
        runner().run(LESSONS / f"{name}.ipynb", solutions=False)
    return re.sub(r"\x1b\[[0-9;]*m", "", str(info.value))
