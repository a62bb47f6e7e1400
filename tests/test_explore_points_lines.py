"""The pipeline explorer of draws of lines and points, and of a wireframe (issue 29).

In the style of tests/test_explore.py: the page's embedded history of a pixel is
``trace.pixel_history`` field by field (with a line's t and a point's gl_PointCoord), the
primitive table names the line or point with its own window corners and size, and
``softpipe explore MODEL --wireframe`` holds the wireframe's draws (their edges' pixels and
histories), not only the shaded surface's. In a real browser (skipped where chromium or
playwright is absent): the page shows a line's t column and the winning line's two vertices.
"""
from __future__ import annotations

import numpy as np
import pytest

import softpipe as sp
from softpipe.tools.cli import main
from softpipe.views.explorer import read_explorer, write_explorer

W, H = 32, 24


def clip(points):
    p = np.asarray(points, dtype=float)
    return np.column_stack([2 * p[:, 0] / W - 1, 2 * p[:, 1] / H - 1, np.linspace(-0.5, 0.5, len(p)),
                            np.ones(len(p))])


def where(varyings, uniforms, frag):
    s, t = frag.point_coord
    return (s, t, varyings.color[0], 1.0)


POINTS = [(3.5, 3.5), (27.3, 19.6), (6.7, 18.2), (24.9, 2.4)]


def draws(kind):
    fb = sp.Framebuffer(W, H)
    fb.clear((0.1, 0.1, 0.1, 1.0))
    color = np.linspace(0.2, 0.8, 4)[:, None] * np.ones((1, 3))
    if kind == "wireframe":     # a filled quad, then its edges in polygon mode over it (as --wireframe)
        quad = [POINTS[0], POINTS[3], POINTS[1], POINTS[0], POINTS[1], POINTS[2]]
        vary = {"color": np.ones((6, 3)) * 0.5}
        first = sp.draw(fb, clip(quad), varyings=vary, trace=True)
        second = sp.draw(fb, clip(quad), varyings=vary, fragment_shader=where, polygon_mode="line",
                         depth_test="lequal", depth_write=False, polygon_offset=(-1.0, -1.0), trace=True)
        return [first, second]
    state = {"points": dict(point_size=6), "line_strip": dict(line_width=2)}[kind]
    return [sp.draw(fb, clip(POINTS), topology=kind, varyings={"color": color}, fragment_shader=where,
                    trace=True, **state)]


@pytest.fixture(scope="module", params=["points", "line_strip", "wireframe"])
def page(request, tmp_path_factory):
    traces = draws(request.param)
    summary = write_explorer(traces, tmp_path_factory.mktemp("explore") / f"{request.param}.html")
    return request.param, traces, read_explorer(summary.path), summary


def test_the_embedded_history_of_lines_and_points_is_pixel_history_field_by_field(page):
    kind, traces, data, _ = page
    checked = 0
    for y in range(H):
        for x in range(W):
            expected = [(k, e) for k, t in enumerate(traces) for e in t.pixel_history(x, y)]
            got = data.history(x, y)
            if not expected:
                assert got is None
                continue
            assert len(got) == len(expected)
            for row, (k, e) in zip(got, expected):
                for f in ("index", "primitive_id", "triangle", "sample", "depth", "verdict"):
                    assert row[f] == getattr(e, f), (x, y, f)
                assert row["color"] == e.color and row["color_after"] == e.color_after
                assert np.array_equal(np.float32(row["point_coord"]), np.float32(e.point_coord)), (x, y)
                if traces[k].primitives.kind != "triangles":
                    assert len(e.point_coord) == 2 and np.float32(e.color[0]) == np.float32(e.point_coord[0])
                checked += 1
    assert checked == sum(len(t) for t in traces)


def test_the_primitive_table_holds_each_lines_or_points_own_corners_and_size(page):
    kind, traces, data, _ = page
    a = data.arrays
    last = traces[-1]
    meta = data.meta["draws"][-1]
    assert meta["kind"] == last.primitives.kind == ("points" if kind == "points" else "lines")
    assert meta["polygon_mode"] == (kind == "wireframe")
    offset = meta["tri_offset"]
    rows = np.nonzero(a["t_id"] >= offset)[0]
    assert len(rows) and a["t_own"][rows].all()
    own = np.cumsum(a["t_own"]) - 1                          # the row's place among t_window's
    for r in rows:
        local = int(a["t_id"][r]) - offset
        assert np.array_equal(a["t_window"][own[r]], np.float32(last.primitives.window[local]))
        assert a["t_size"][r] == np.float32(last.primitives.size[local])
        assert a["t_prim"][r] == last.primitives.primitive_id[local]
    if kind == "wireframe":                                  # the face's three vertices, in polygon mode
        first = int(rows[0])
        assert len(set(a["t_vindex"][first].tolist())) == 3
    else:
        corners = a["t_vindex"][rows]
        assert (corners[:, 1] == corners[:, 2]).all()        # a line (a, b, b), a point (p, p, p)


def test_the_winner_of_each_pixel_is_the_line_or_point_written_last(page):
    kind, traces, data, _ = page
    expected = {}
    for k, t in enumerate(traces):                           # in draw order: the last written wins
        f = t.fragments
        for i in np.nonzero(t.written())[0]:
            expected[int(f.x[i]), int(f.y[i])] = (k, int(f.triangle[i]))
    assert expected
    for y in range(H):
        for x in range(W):
            assert data.winner(x, y) == expected.get((x, y)), (x, y)


def test_softpipe_explore_with_wireframe_holds_the_wireframes_draws(tmp_path, capsys):
    out = tmp_path / "wire.html"
    assert main(["explore", "suzanne", "--wireframe", "-o", str(out), "--size", "40x30", "-q"]) == 0
    data = read_explorer(out)
    names = [d["name"] for d in data.meta["draws"]]
    assert names == ["suzanne", "suzanne (wireframe)"]
    wire = data.meta["draws"][1]
    assert wire["kind"] == "lines" and wire["polygon_mode"] and wire["program"] == "unlit"
    assert wire["fragments"] > 0
    won = data.arrays["win"].astype(np.int64) - 1
    assert (won >= wire["tri_offset"]).any()                 # some pixels show an edge on top


# ---------------------------------------------------------------------------- in a real browser


def test_a_line_draws_page_in_a_real_browser(tmp_path):
    import shutil
    executable = shutil.which("chromium")
    if not executable:
        pytest.skip("chromium is not installed: make test installs it (apt-get install -y chromium, as root)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as e:
        pytest.skip(f"playwright is not installed ({e})")
    traces = draws("line_strip")
    summary = write_explorer(traces, tmp_path / "lines.html")
    t = traces[0]
    written = np.nonzero(t.written())[0]
    k = int(written[len(written) // 2])
    x, y = int(t.fragments.x[k]), int(t.fragments.y[k])
    history = t.pixel_history(x, y)
    with sync_playwright() as pw:
        try:
            browser = pw.chromium.launch(executable_path=executable, args=["--no-sandbox"])
        except Exception as e:  # noqa: BLE001 (any reason the browser does not start is the skip's reason)
            pytest.skip(f"{executable} did not start headless: {str(e).splitlines()[0]}")
        page = browser.new_page(viewport={"width": 1280, "height": 860})
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(summary.path.resolve().as_uri())
        page.wait_for_selector("body[data-ready='1']", timeout=20000)
        box = page.locator("#stage").bounding_box()
        page.mouse.click(box["x"] + (x + 0.5) * box["width"] / W, box["y"] + (y + 0.5) * box["height"] / H)
        head = page.evaluate("() => [...document.querySelectorAll('#history thead th')].map(t => t.textContent)")
        cells = page.evaluate("() => [...document.querySelectorAll('#history tbody tr')].map(tr => "
                              "tr.querySelector('td[data-field=point_coord]').textContent)")
        table = page.locator("#triangle").inner_text()
        vertices = page.locator("#vertices tr[data-vertex]").count()
        browser.close()
    assert not errors, errors
    assert "t" in head and head.index("t") == head.index("depth") + 1
    assert [float(c) for c in cells] == pytest.approx([e.point_coord[0] for e in history], abs=5e-4)
    e = history[-1]
    assert "winning line: draw 1" in table and f"primitive {e.primitive_id}" in table and "width 2" in table
    assert vertices == 2
