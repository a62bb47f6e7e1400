"""The README's Python examples run as written."""
import re
from pathlib import Path

import numpy as np
from PIL import Image

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_examples_run_and_draw(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    fb = namespace["fb"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]          # nothing in the folder itself
    assert (tmp_path / "out" / "triangle.png").exists()
    # From Python: softpipe.render and softpipe.turntable with the command line's defaults
    with Image.open(tmp_path / "out" / "teapot.png") as teapot:
        assert teapot.size == (640, 480)
    pixels = namespace["pixels"]
    assert pixels.shape == (240, 320, 3) and pixels.dtype == np.uint8
    assert tuple(pixels[0, 0]) == (255, 255, 255) and (pixels != 255).any(axis=2).sum() > 5000
    with Image.open(tmp_path / "out" / "spin.gif") as spin:
        assert spin.n_frames == 12 and spin.size == (320, 240)
    # the stripes shader brightened every other 4-pixel column band of the triangle
    lit = fb.color[..., :3].sum(axis=2) > 0
    rows, cols = np.nonzero(lit)
    assert len(rows) > 100
    band = (cols // 4) % 2 == 1
    brightness = fb.color[rows, cols, :3].min(axis=1)
    assert brightness[band].min() >= 0.5 - 1e-6      # mixed halfway to white
    assert brightness[~band].max() < 0.5
