"""The pipeline explorer (softpipe.views.explorer, issue #20): one self-contained HTML page per render.

Without a browser: the page needs nothing from outside itself, its embedded data for a pixel
is ``trace.pixel_history`` field by field (across the draws of a scene, in order), and its
size is bounded (``max_fragments``). In a real browser (Debian's ``chromium``, driven headless
by Playwright; ``make test`` installs it, and the test skips with the reason where it is absent):
the page loads from a file:// URL with the network off, a click on a known pixel of a small
scene shows that pixel's history in the DOM, equal to ``pixel_history`` within the printed
precision, and the arrow keys move the selection.

The screenshot in docs/explorer.md is made by the browser test: run

    SOFTPIPE_EXPLORER_SCREENSHOT=docs/images/explorer.png .venv/bin/python -m pytest tests/test_explore.py -k browser

to regenerate it (otherwise the test writes it to its tmp folder).
"""
from __future__ import annotations

import fnmatch
import html
import importlib.resources
import math
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import softpipe as sp
from softpipe.tools.cli import main
from softpipe.views.explorer import PAGE_FOLDER, read_explorer, write_explorer

ROOT = Path(__file__).resolve().parent.parent


#: A small scene: a ball in front of a box on a floor, 4 samples a pixel, a light with a shadow map.
SCENE = """
[camera]
eye = [0.0, 1.2, 4.0]
target = [0.0, 0.3, 0.0]
fovy = 40.0
[render]
width = 64
height = 48
samples = "rgss4"
sample_shading = "sample"
shadows = true
[[lights]]
kind = "directional"
direction = [-0.3, -1.0, -0.4]
color = 0.9
[[meshes]]
name = "ball"
shape = "uv_sphere"
radius = 0.6
segments = 16
rings = 8
transform = { translate = [0.3, 0.5, 0.8] }
material = { kd = [0.8, 0.2, 0.1], ks = 0.4, shininess = 30 }
[[meshes]]
name = "box"
shape = "cube"
size = 1.2
transform = { translate = [-0.4, 0.3, -0.3], rotate_y = 30 }
material = { kd = [0.2, 0.4, 0.8] }
[[meshes]]
name = "floor"
shape = "plane"
size = 6.0
material = { kd = 0.6 }
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The small scene rendered with every draw traced, and its explorer page."""
    folder = tmp_path_factory.mktemp("explore")
    (folder / "scene.toml").write_text(SCENE)
    results: list = []
    sp.render(str(folder / "scene.toml"), trace=True, results=results)
    summary = write_explorer(results, folder / "scene.html")
    return results, summary, read_explorer(summary.path)


def _histories(results, x, y):
    """(draw, PixelHistory) of every draw at pixel (x, y), in draw order."""
    return [(k, r.trace.pixel_history(x, y)) for k, r in enumerate(results)]


def _known_pixel(results):
    """The pixel with the most fragments among those that several draws reached."""
    w = results[0].trace.width
    per_draw = [np.bincount(r.trace.fragments.y * w + r.trace.fragments.x, minlength=w * results[0].trace.height)
                for r in results]
    draws = sum((c > 0).astype(int) for c in per_draw)
    total = sum(per_draw)
    p = int(np.argmax(np.where(draws >= 2, total, -1)))
    return p % w, p // w


def _sample_pixels(results, n=12, seed=3):
    w, h = results[0].trace.width, results[0].trace.height
    rng = np.random.default_rng(seed)
    return [_known_pixel(results), (0, 0), (w - 1, h - 1)] + [(int(rng.integers(w)), int(rng.integers(h)))
                                                              for _ in range(n)]


# ---------------------------------------------------------------------------- without a browser


def test_the_page_is_self_contained(scene):
    _, summary, _ = scene
    page = summary.path.read_text(encoding="utf-8")
    assert "http://" not in page and "https://" not in page
    for attr, value in re.findall(r'\b(src|href|action|poster)\s*=\s*["\']([^"\']*)["\']', page, re.I):
        assert value.startswith(("data:", "#")), f"{attr}={value[:60]!r} points outside the page"
        assert not value.startswith("//")
    assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.I), "an external script"
    assert not re.search(r"<link\b", page, re.I), "a linked stylesheet, font or icon"
    assert not re.search(r"@import|@font-face|url\(", page, re.I), "CSS that fetches something"
    assert not re.search(r"\b(fetch|XMLHttpRequest|WebSocket|EventSource|importScripts)\b", page)
    assert page.count("<script") == 2      # the JSON data and the page's own script


def _page_file(name: str) -> str:
    return (importlib.resources.files("softpipe.views") / PAGE_FOLDER / name).read_text(encoding="utf-8")


def test_the_page_text_is_the_package_data_files_byte_for_byte(scene):
    _, summary, data = scene
    page = summary.path.read_bytes().decode("utf-8")
    skeleton = re.sub(r'(<script type="application/json" id="softpipe-data">).*?(</script>)', r"\1__DATA__\2",
                      page, count=1, flags=re.S)
    skeleton = re.sub(r'(<div id="images" hidden>\n).*?(\n</div>)', r"\1__IMAGES__\2", skeleton, count=1, flags=re.S)
    title = re.escape(html.escape(data.meta["title"]))
    skeleton = re.sub(rf"(<title>softpipe explorer: ){title}(</title>)", r"\1__TITLE__\2", skeleton, count=1)
    skeleton = re.sub(rf'(<span id="title">){title}(</span>)', r"\1__TITLE__\2", skeleton, count=1)
    files = _page_file("page.html").replace("__STYLE__", _page_file("page.css"))
    assert skeleton == files.replace("__SCRIPT__", _page_file("page.js"))


def test_the_page_files_are_package_data():
    tomllib = pytest.importorskip("tomllib") if sys.version_info >= (3, 11) else pytest.importorskip("tomli")
    with open(ROOT / "pyproject.toml", "rb") as f:
        patterns = tomllib.load(f)["tool"]["setuptools"]["package-data"]["softpipe"]
    folder = ROOT / "softpipe" / "views" / PAGE_FOLDER
    assert sorted(p.name for p in folder.iterdir()) == ["page.css", "page.html", "page.js"]
    for path in folder.iterdir():
        relative = path.relative_to(ROOT / "softpipe").as_posix()
        assert any(fnmatch.fnmatch(relative, p) for p in patterns), relative


def test_the_embedded_history_is_pixel_history_field_by_field(scene):
    results, _, data = scene
    names = [r.name for r in results]
    checked_multi = False
    for x, y in _sample_pixels(results):
        expected = [(k, e, h) for k, h in _histories(results, x, y) for e in h]
        got = data.history(x, y)
        if not expected:
            assert got is None
            continue
        assert got is not None and len(got) == len(expected), (x, y)
        checked_multi |= len({k for k, _, _ in expected}) > 1
        first = expected[0][2]
        for row, (k, e, _) in zip(got, expected):
            assert (row["draw"], row["name"]) == (k, names[k])
            for f in ("index", "primitive_id", "triangle", "sample", "depth", "verdict"):
                assert row[f] == getattr(e, f), (x, y, f)             # depth: float64, exact
            assert row["color"] == e.color and row["color_after"] == e.color_after    # float32, as the pipeline holds them
            assert list(row["varyings"]) == list(e.varyings._fields)
            for name in e.varyings._fields:                           # float32 of the float64 values
                assert np.array_equal(np.float32(row["varyings"][name]), np.float32(getattr(e.varyings, name)))
            assert np.array_equal(np.float32(row["shadow"]).reshape(-1), np.float32(e.shadow).reshape(-1))
            assert row["before"] == first.before
        written = [(k, e.triangle) for k, e, _ in expected if e.verdict == "written"]
        assert data.winner(x, y) == (written[-1] if written else None)
    assert checked_multi, "no pixel with fragments of several draws was checked"


def test_the_shadow_column_and_every_draw_are_in_the_data(scene):
    results, summary, data = scene
    assert [d["name"] for d in data.meta["draws"]] == [r.name for r in results] == ["ball", "box", "floor"]
    assert all(d["shadow_lights"] == 1 for d in data.meta["draws"])
    assert data.meta["held"]["step"] == 1 and data.meta["held"]["fragments"] == sum(len(r.trace) for r in results)
    assert set(data.meta["held"]) >= {"statement", "pixels", "fragments", "limit"}
    names = [p["name"] for p in data.meta["pictures"]]
    assert names[:6] == ["vertices", "primitives", "coverage", "depth", "overdraw", "final"]
    assert any(n.startswith("shadow map 0") for n in names)


def test_the_page_size_is_bounded(scene, tmp_path):
    results, summary, _ = scene
    assert summary.bytes < 1_500_000, str(summary)
    small = write_explorer(results, tmp_path / "small.html", max_fragments=2000)
    data = read_explorer(small.path)
    held = data.meta["held"]
    assert held["fragments"] <= 2000 and held["step"] > 1
    assert f"column and row are multiples of {held['step']}" in held["statement"]
    assert small.bytes < summary.bytes
    w = data.width
    for p in data.arrays["h_pixel"]:          # the grid's pixels, and every pixel keeps its winner
        assert p % w % held["step"] == 0 and p // w % held["step"] == 0
    assert np.array_equal(data.arrays["win"], read_explorer(summary.path).arrays["win"])


def test_trace_to_html_of_one_draw(tmp_path):
    results: list = []
    sp.render("suzanne", width=48, height=36, trace=True, results=results)
    trace = results[0].trace
    summary = trace.to_html(tmp_path / "one.html")
    data = read_explorer(summary.path)
    x, y = 24, 18                               # the middle of the picture: the model
    h = trace.pixel_history(x, y)
    got = data.history(x, y)
    assert [r["index"] for r in got] == [e.index for e in h] and len(h) > 0
    assert [r["depth"] for r in got] == [e.depth for e in h]


def test_softpipe_explore_on_the_command_line(tmp_path, capsys):
    (tmp_path / "scene.toml").write_text(SCENE)
    out = tmp_path / "page.html"
    assert main(["explore", str(tmp_path / "scene.toml"), "-o", str(out), "--size", "32x24", "-q"]) == 0
    said = capsys.readouterr().out
    assert "wrote" in said and "the history of every covered pixel" in said
    data = read_explorer(out)
    assert (data.width, data.height) == (32, 24) and len(data.meta["draws"]) == 3
    assert main(["explore", "bunny", "-o", str(tmp_path / "page.png")]) == 2
    assert "HTML" in capsys.readouterr().err


# ---------------------------------------------------------------------------- in a real browser


# the `browser` fixture (Debian's chromium through Playwright, or a skip with the reason): conftest.py


def _printed_close(text: str, value: float, digits: int) -> bool:
    """``text`` is ``value`` printed to ``digits`` significant digits (the page's float32 of it, rounded)."""
    got = float(text)
    if value == 0 or not math.isfinite(value):
        return got == value or (math.isnan(value) and math.isnan(got))
    unit = 10.0 ** (math.floor(math.log10(abs(value))) - digits + 1)
    return abs(got - value) <= 0.5 * unit * 1.001 + abs(value) * 2.0 ** -23


def _numbers(text: str):
    return [t for t in re.split(r"[(),\s]+", text) if t]


def _check_row(cells: dict, k: int, name: str, e) -> None:
    assert cells["draw"] == f"{k + 1}: {name}"
    assert (cells["#"], cells["prim"], cells["tri"], cells["sample"]) == \
        (str(e.index), str(e.primitive_id), str(e.triangle), str(e.sample))
    assert abs(float(cells["depth"]) - e.depth) <= 5.0e-7 * 1.001, (cells["depth"], e.depth)
    for field in e.varyings._fields:
        want = getattr(e.varyings, field)
        want = want if isinstance(want, tuple) else (want,)
        got = _numbers(cells[field])
        assert len(got) == len(want) and all(_printed_close(g, v, 4) for g, v in zip(got, want)), (field, got, want)
    if e.shadow:
        got = _numbers(cells["shadow V_j"])
        want = [c[0] for c in e.shadow] if all(c[0] == c[1] == c[2] for c in e.shadow) else \
            [v for c in e.shadow for v in c]
        assert len(got) == len(want) and all(_printed_close(g, v, 3) for g, v in zip(got, want)), (got, want)
    for column, want in (("shader output", e.color), ("color after", e.color_after)):
        got = _numbers(cells[column])
        assert len(got) == 4 and all(_printed_close(g, v, 4) for g, v in zip(got, want)), (column, got, want)
    assert cells["merger"].replace("★", "").strip() == e.verdict


def _read_table(page):
    return page.evaluate("""() => {
        const head = [...document.querySelectorAll('#history thead th')].map(t => t.textContent);
        return [...document.querySelectorAll('#history tbody tr')].map(tr =>
            Object.fromEntries([...tr.children].map((td, i) => [head[i], td.textContent])));
    }""")


def test_the_page_in_a_real_browser(scene, browser, tmp_path):
    results, summary, _ = scene
    context = browser.new_context(viewport={"width": 1280, "height": 860}, offline=True)
    requested, refused = [], []

    def route(r):
        requested.append(r.request.url)
        if r.request.url.startswith("file://"):
            r.continue_()
        else:
            refused.append(r.request.url)
            r.abort()

    context.route("**/*", route)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("request", lambda r: requested.append(r.url))
    page.goto(summary.path.resolve().as_uri())
    page.wait_for_selector("body[data-ready='1']", timeout=20000)
    assert not errors, errors

    x, y = _known_pixel(results)
    box = page.locator("#stage").bounding_box()
    w, h = results[0].trace.width, results[0].trace.height
    page.mouse.click(box["x"] + (x + 0.5) * box["width"] / w, box["y"] + (y + 0.5) * box["height"] / h)
    pixel = page.locator("#pixel")
    assert (pixel.get_attribute("data-x"), pixel.get_attribute("data-y")) == (str(x), str(y))
    rows = _read_table(page)
    expected = [(k, e) for k, hist in _histories(results, x, y) for e in hist]
    assert len(rows) == len(expected) > 1 and len({k for k, _ in expected}) > 1
    for cells, (k, e) in zip(rows, expected):
        _check_row(cells, k, results[k].name, e)
    written = [i for i, (_, e) in enumerate(expected) if e.verdict == "written"]
    assert [i for i, c in enumerate(rows) if "★" in c["merger"]] == written[-1:]
    k, e = expected[written[-1]]                # the winner's triangle, with its three vertices
    triangle = page.locator("#triangle").inner_text()
    assert f"draw {k + 1} ({results[k].name})" in triangle and f"primitive {e.primitive_id}" in triangle
    assert page.locator("#vertices tr[data-vertex]").count() == 3
    for space in ("object", "clip", "window"):
        assert page.locator(f'#vertices td[data-space="{space}"]').count() == 3

    page.keyboard.press("ArrowRight")
    assert pixel.get_attribute("data-x") == str(x + 1) and pixel.get_attribute("data-y") == str(y)
    page.keyboard.press("ArrowDown")
    assert pixel.get_attribute("data-y") == str(y + 1)
    after = sum(len(hh) for _, hh in _histories(results, x + 1, y + 1))
    assert len(_read_table(page)) == after

    page.keyboard.press("ArrowUp")
    page.keyboard.press("ArrowLeft")
    shot = Path(os.environ.get("SOFTPIPE_EXPLORER_SCREENSHOT") or tmp_path / "explorer.png")
    _screenshot(page, shot)
    assert shot.stat().st_size < 200_000
    assert not errors, errors
    assert not refused, f"the page asked the network for {refused}"
    assert requested and all(u.startswith(("file://", "data:")) for u in requested), requested
    context.close()


def _screenshot(page, path: Path) -> None:
    """The page as it looks, as a small PNG (256 colors) for the docs."""
    import io

    from PIL import Image
    image = Image.open(io.BytesIO(page.screenshot(full_page=True))).convert("RGB")
    path.parent.mkdir(parents=True, exist_ok=True)
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, format="PNG", optimize=True)
