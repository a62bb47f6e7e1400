"""The README's Python examples run as written."""
import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_examples_run_and_draw(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    fb = namespace["fb"]
    assert (tmp_path / "triangle.png").exists()
    # the stripes shader brightened every other 4-pixel column band of the triangle
    lit = fb.color[..., :3].sum(axis=2) > 0
    rows, cols = np.nonzero(lit)
    assert len(rows) > 100
    band = (cols // 4) % 2 == 1
    brightness = fb.color[rows, cols, :3].min(axis=1)
    assert brightness[band].min() >= 0.5 - 1e-6      # mixed halfway to white
    assert brightness[~band].max() < 0.5
