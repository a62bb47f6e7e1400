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


def failure(name: str, solved: int = 0) -> str:
    """The text of the error the notebook stops with, run as it is (the skeleton), without colors; with
    ``solved`` = n, its first n exercise cells completed by the solution (to reach a later exercise's check)."""
    from nbclient.exceptions import CellExecutionError
    path = LESSONS / f"{name}.ipynb"
    with pytest.raises(CellExecutionError) as info:
        if not solved:
            runner().run(path, solutions=False)
        else:
            from nbclient import NotebookClient
            nb = runner().load(path)
            exercises = [c for c in nb.cells if "exercise" in c.metadata.get("tags", [])]
            assert len(exercises) > solved, f"{name} has {len(exercises)} exercise cell(s)"
            for cell in exercises[:solved]:
                cell.source = (LESSONS / "solutions" / f"{name}.py").read_text()
            NotebookClient(nb, timeout=600, kernel_name="python3",
                           resources={"metadata": {"path": str(LESSONS)}}).execute()
    return re.sub(r"\x1b\[[0-9;]*m", "", str(info.value))
