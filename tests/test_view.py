"""The live viewer (softpipe.tools.viewer, ``softpipe view``, ``sp.view``; issue #33).

Without a browser: the frame API returns the bytes ``sp.render(...).save(f, format="png")``
writes for the same camera and program; the history API is ``trace.pixel_history(x, y).table()``
of every draw; bad queries get a 400 whose message names the parameter; the server binds to
loopback only and answers only requests addressed to it; a drag's overtaken frame requests are
not rendered; ``softpipe view`` stops cleanly on Ctrl-C.

In a real browser (Debian's ``chromium``, driven headless by Playwright, as tests/test_explore.py
does; skipped with the reason where either is absent): the page loads ``softpipe view bunny``'s
frame, a drag orbits the camera and changes the picture (to the bytes ``sp.render`` makes with the
camera the page reports), scrolling zooms, and a click on a pixel shows that pixel's history,
equal to ``pixel_history``'s table cell for cell.

The screenshot in docs/viewer.md is made by the browser test: run

    SOFTPIPE_VIEWER_SCREENSHOT=docs/images/viewer.png .venv/bin/python -m pytest tests/test_view.py -k browser

to regenerate it (otherwise the test writes it to its tmp folder).
"""
from __future__ import annotations

import fnmatch
import io
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from patience import PATIENCE, read_line

import softpipe as sp
from softpipe.tools.cli import main
from softpipe.tools.viewer import LiveScene, check_loopback, orbit_camera, page_html, serve

ROOT = Path(__file__).resolve().parent.parent
SIZE = (160, 120)


@pytest.fixture(scope="module")
def viewer():
    """``sp.view("bunny")`` at 160×120, serving in a background thread."""
    v = sp.view("bunny", width=SIZE[0], height=SIZE[1])
    yield v
    v.stop()


def _get(url: str, headers=None):
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=PATIENCE) as r:     # a reply may wait for a cold compile
            return r.status, r.read(), r.headers
    except urllib.error.HTTPError as e:
        return e.code, e.read(), e.headers


def _api(viewer, path: str):
    return _get(viewer.url.rstrip("/") + path)


def _png_of(fb) -> bytes:
    buffer = io.BytesIO()
    fb.save(buffer, format="png")
    return buffer.getvalue()


def _expected_frame(viewer, az=0.0, el=0.0, zoom=1.0, program=None) -> bytes:
    """What ``sp.render`` makes of the viewer's scene with the camera of (az, el, zoom)."""
    scene = viewer.server.scene
    camera = orbit_camera(scene.scene.view_camera(), az, el, zoom)
    return _png_of(sp.render(scene.scene, camera=camera, program=program))


# ---------------------------------------------------------------------------- the Python side


def test_the_frame_api_returns_the_bytes_of_sp_render_with_the_same_camera(viewer):
    status, body, headers = _api(viewer, "/api/frame")
    assert (status, headers["Content-Type"]) == (200, "image/png")
    own = _png_of(sp.render("bunny", width=SIZE[0], height=SIZE[1]))
    assert body == own                                                                # the scene's own camera
    status, body, _ = _api(viewer, "/api/frame?az=40&el=-15&zoom=1.5&program=gouraud")
    assert status == 200
    expected = _expected_frame(viewer, 40.0, -15.0, 1.5, "gouraud")
    assert body == expected and body != own


def test_orbit_camera_turns_about_the_up_axis_and_zooms():
    base = sp.Camera(eye=(0.0, 1.0, 4.0), target=(0.0, 1.0, 0.0), fovy=40.0, near=0.5, far=50.0)
    assert orbit_camera(base) is base
    turned = orbit_camera(base, azimuth=90.0)
    np.testing.assert_allclose(turned.eye, (4.0, 1.0, 0.0), atol=1e-12)
    high = orbit_camera(base, elevation=30.0, zoom=2.0)        # half as far, 30° above the target
    offset = np.subtract(high.eye, high.target)
    assert np.linalg.norm(offset) == pytest.approx(2.0)
    assert np.degrees(np.arcsin(offset[1] / 2.0)) == pytest.approx(30.0)
    assert (high.near, high.far) == (0.25, 25.0)
    top = orbit_camera(base, elevation=500.0)                  # kept below the pole: the up stays defined
    assert np.degrees(np.arcsin((top.eye[1] - 1.0) / 4.0)) == pytest.approx(89.0)


def test_the_history_api_is_pixel_history_of_every_draw(viewer):
    results: list = []
    camera = orbit_camera(viewer.server.scene.scene.view_camera(), 25.0, 10.0, 1.0)
    sp.render(viewer.server.scene.scene, camera=camera, trace=True, results=results)
    trace = results[0].trace
    x, y = int(trace.fragments.x[len(trace) // 2]), int(trace.fragments.y[len(trace) // 2])
    status, body, _ = _api(viewer, f"/api/history?az=25&el=10&x={x}&y={y}")
    assert status == 200
    got = json.loads(body)
    history = trace.pixel_history(x, y)
    columns, rows = history.table()
    assert got == {"x": x, "y": y, "draws": [{"draw": 0, "name": "stanford-bunny", "program": "phong",
                                              "heading": str(history).splitlines()[0], "columns": columns,
                                              "rows": rows}]}
    assert len(rows) >= 1
    status, body, _ = _api(viewer, "/api/history?x=0&y=0")      # the background: no fragment reached it
    assert (status, json.loads(body)["draws"]) == (200, [])


@pytest.mark.parametrize("query, message", [
    ("/api/history?x=160&y=5", "pixel (160, 5) is outside the 160×120 frame: x must be from 0 to 159, y from 0 to 119"),
    ("/api/history?x=3&y=-1", "pixel (3, -1) is outside the 160×120 frame: x must be from 0 to 159, y from 0 to 119"),
    ("/api/history?x=3", "y: give the pixel's y (x from the left, y from the top)"),
    ("/api/history?x=a&y=1", "x: expected a whole number, got 'a'"),
    ("/api/frame?program=nope", "program: unknown program 'nope'; registered programs: " + ", ".join(
        sorted(__import__("softpipe.programs", fromlist=["PROGRAMS"]).PROGRAMS))),
    ("/api/frame?light=sun", "light: unknown light 'sun'; the lights: scene, headlight, key, overhead"),
    ("/api/frame?stage=wires", "stage: unknown stage picture 'wires'; the pictures: final, vertices, primitives, "
                               "coverage, depth, overdraw"),
    ("/api/frame?zoom=abc", "zoom: expected a number, got 'abc'"),
    ("/api/frame?az=nan", "az: expected a finite number, got 'nan'"),
    ("/api/frame?zoom=0", "zoom must be from 0.05 to 20 (times nearer than the scene's camera), got 0.0"),
    ("/api/frame?az=1&az=2", "az: given 2 times; give it once"),
    ("/api/frame?x=1", "unknown parameter 'x'; the parameters are az, el, zoom, program, light, stage, seq, client"),
    ("/api/frame?program=textured", "bunny: mesh 'stanford-bunny' has no texture coordinates (vt), so program 'textured' "
                                    "cannot draw it"),
])
def test_the_api_refuses_bad_inputs_with_a_message_naming_them(viewer, query, message):
    status, body, headers = _api(viewer, query)
    assert (status, headers["Content-Type"]) == (400, "application/json; charset=utf-8")
    assert json.loads(body) == {"error": message}


def test_an_unknown_page_is_404(viewer):
    status, body, _ = _api(viewer, "/etc/passwd")
    assert status == 404 and "no such page: /etc/passwd" in json.loads(body)["error"]


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.20", "::", "example.com", ""])
def test_the_server_refuses_a_non_loopback_bind(host):
    scene = LiveScene.load("bunny", width=8, height=6)
    with pytest.raises(ValueError, match="loopback only"):
        serve(scene, host=host)
    with pytest.raises(ValueError, match="loopback only"):
        sp.view("bunny", host=host, width=8, height=6)


def test_a_taken_port_is_named(viewer, capsys):
    port = viewer.server.port
    assert main(["view", "bunny", "--size", "8x6", "--port", str(port), "-q"]) == 2
    assert capsys.readouterr().err.strip() == (f"softpipe view: error: cannot serve on 127.0.0.1 port {port}: "
                                               "Address already in use (port 0, the default, takes a free one)")
    assert main(["view", "bunny", "--port", "70000"]) == 2
    assert "--port: expected a port from 0 to 65535 (0: a free one), got '70000'" in capsys.readouterr().err
    with pytest.raises(ValueError, match=r"port must be a whole number from 0 to 65535 \(0: a free one\), got -1"):
        sp.view("bunny", port=-1, width=8, height=6)


def test_loopback_hosts_are_taken():
    assert check_loopback("localhost") == "127.0.0.1"
    assert check_loopback("127.0.0.1") == "127.0.0.1" and check_loopback("::1") == "::1"
    assert check_loopback("127.0.0.2") == "127.0.0.2"


def test_softpipe_view_refuses_another_host_before_rendering(capsys):
    assert main(["view", "bunny", "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == ("softpipe view: error: --host: host '0.0.0.0' is not a loopback address: the viewer "
                           "serves on loopback only (127.0.0.1, ::1 or localhost), so that no other machine can "
                           "reach it")


def test_a_request_for_another_host_is_refused(viewer):
    """A page elsewhere reaching the port through DNS rebinding names its own host: 403, nothing rendered."""
    status, body, _ = _get(viewer.url + "api/frame", headers={"Host": f"attacker.example:{viewer.server.port}"})
    assert status == 403
    assert json.loads(body)["error"] == (f"the viewer answers only requests to {viewer.url} "
                                         f"(Host 'attacker.example:{viewer.server.port}' refused)")


def test_a_frame_overtaken_while_it_waits_is_not_rendered(viewer, monkeypatch):
    """The server coalesces: a page's frame request overtaken by a newer one of the same page (client)
    while it waited for the render before it is answered 409, and only the newest is rendered."""
    scene = viewer.server.scene
    rendered = []
    frame = scene.frame
    monkeypatch.setattr(scene, "frame", lambda state: rendered.append(state.azimuth) or frame(state))
    answers = {}

    def ask(seq, az):
        answers[seq] = _api(viewer, f"/api/frame?client=drag&seq={seq}&az={az}")[0]

    def registered(seq):
        deadline = time.monotonic() + PATIENCE
        while viewer.server._seq.get("drag") != seq:
            assert time.monotonic() < deadline
            time.sleep(0.01)

    with scene.lock:                                        # a render under way
        threads = []
        for seq, az in ((1, 10.0), (2, 20.0), (3, 30.0)):
            threads.append(threading.Thread(target=ask, args=(seq, az)))
            threads[-1].start()
            registered(seq)
    for t in threads:
        t.join(PATIENCE)
    assert answers == {1: 409, 2: 409, 3: 200}
    assert rendered == [30.0]
    assert _api(viewer, "/api/frame?client=drag&seq=2")[0] == 409      # older than the newest seen: stale
    assert _api(viewer, "/api/frame?client=other&seq=2")[0] == 200     # another page is its own


def test_sp_view_shows_an_iframe_and_stops(tmp_path):
    v = sp.view("bunny", width=16, height=12)
    try:
        assert v.url.startswith("http://127.0.0.1:") and v.url.endswith("/")
        assert f'<iframe src="{v.url}"' in v._repr_html_()
        status, body, _ = _get(v.url)
        assert status == 200 and b"softpipe viewer: bunny" in body
    finally:
        v.stop()
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", v.server.port), timeout=2).close()
    assert "stopped" in repr(v)


def test_the_page_is_the_package_data_files(viewer):
    status, body, headers = _api(viewer, "/")
    assert (status, headers["Content-Type"]) == (200, "text/html; charset=utf-8")
    assert body.decode("utf-8") == page_html("bunny")
    page = body.decode("utf-8")
    assert "__STYLE__" not in page and "__SCRIPT__" not in page
    assert "http://" not in page and "https://" not in page        # nothing from elsewhere: the API is relative
    tomllib = pytest.importorskip("tomllib") if sys.version_info >= (3, 11) else pytest.importorskip("tomli")
    with open(ROOT / "pyproject.toml", "rb") as f:
        patterns = tomllib.load(f)["tool"]["setuptools"]["package-data"]["softpipe"]
    folder = ROOT / "softpipe" / "views" / "viewer_page"
    assert sorted(p.name for p in folder.iterdir()) == ["page.css", "page.html", "page.js"]
    for path in folder.iterdir():
        assert any(fnmatch.fnmatch(path.relative_to(ROOT / "softpipe").as_posix(), p) for p in patterns)


def test_stage_pictures_are_the_traced_renders(viewer):
    from PIL import Image

    from softpipe.views.explorer import scene_pictures
    results: list = []
    sp.render(viewer.server.scene.scene, trace=True, results=results)
    pictures = scene_pictures([(r.name, r.program, r.trace) for r in results])
    for stage in ("coverage", "depth"):
        status, body, _ = _api(viewer, f"/api/frame?stage={stage}")
        assert status == 200
        assert np.array_equal(np.asarray(Image.open(io.BytesIO(body))), pictures[stage]), stage


def test_softpipe_view_serves_until_ctrl_c():
    """The command prints its address, serves the page, and Ctrl-C stops it: exit status 0, the port closed.

    Nothing here is timed: the test waits for the address line (the server is up), the frame and the exit,
    each within :data:`patience.PATIENCE` (the first frame may be a cold compile on a loaded machine)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "softpipe", "view", "bunny", "--size", "32x24", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        line = read_line(proc, "the line 'softpipe view: serving bunny ...'")
        assert line.startswith("softpipe view: serving bunny (32×24, first frame "), (line, proc.stderr.read()
                                                                                       if proc.poll() is not None
                                                                                       else "")
        url = line.split(" at ")[1].split()[0]
        assert url.startswith("http://127.0.0.1:") and line.rstrip().endswith("(Ctrl-C stops it)")
        status, body, _ = _get(url + "api/frame")
        assert status == 200 and body[:8] == b"\x89PNG\r\n\x1a\n"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=PATIENCE)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert out == "softpipe view: stopped\n" and "Traceback" not in err
    port = int(url.rsplit(":", 1)[1].strip("/"))
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()


# ---------------------------------------------------------------------------- in a real browser


# the `browser` fixture (Debian's chromium through Playwright, or a skip with the reason): conftest.py


def _shown_frame(page) -> bytes:
    """The PNG the page shows, byte for byte (its blob)."""
    return bytes(page.evaluate("""async () => Array.from(new Uint8Array(
        await (await fetch(document.getElementById('frame').src)).arrayBuffer()))"""))


def _wait_for_state(page, **want) -> dict:
    """Wait until the frame shown is the one of the state ``want`` (and no frame is in flight after it)."""
    page.wait_for_function("""(want) => {
        const s = document.getElementById('frame').dataset.state;
        if (!s) return false;
        const got = JSON.parse(s);
        return Object.entries(want).every(([k, v]) => Math.abs(got[k] - v) < 1e-9);
    }""", arg=want, timeout=120000)
    return json.loads(page.locator("#frame").get_attribute("data-state"))


def _read_history(page):
    return page.evaluate("""() => [...document.querySelectorAll('#history .draw')].map(d => ({
        title: d.querySelector('h3').textContent, heading: d.querySelector('p.heading').textContent,
        columns: [...d.querySelectorAll('thead th')].map(t => t.textContent),
        rows: [...d.querySelectorAll('tbody tr')].map(tr => [...tr.children].map(td => td.textContent))}))""")


def test_the_viewer_in_a_real_browser(viewer, browser, tmp_path):
    context = browser.new_context(viewport={"width": 1100, "height": 760})
    refused = []

    def route(r):
        if r.request.url.startswith((viewer.url, "blob:", "data:")):
            r.continue_()
        else:
            refused.append(r.request.url)
            r.abort()

    context.route("**/*", route)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(viewer.url)
    page.wait_for_selector("body[data-ready='1']", timeout=120000)
    assert not errors, errors
    first = _shown_frame(page)
    assert first == _expected_frame(viewer)                 # the scene's own camera, as sp.render draws it

    # drag: 60 px right and 20 px down orbits the camera 30° (the scene turns right) and 10° higher
    frame = page.locator("#frame")
    box = frame.bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 60, cy + 20, steps=12)
    page.mouse.up()
    state = _wait_for_state(page, az=-30.0, el=10.0)
    dragged = _shown_frame(page)
    assert dragged != first
    assert dragged == _expected_frame(viewer, -30.0, 10.0, 1.0, state["program"] or None)

    # scroll: nearer
    page.mouse.wheel(0, -300)
    page.wait_for_function("() => JSON.parse(document.getElementById('frame').dataset.state).zoom > 1.2",
                           timeout=120000)
    assert _shown_frame(page) not in (first, dragged)

    # click a pixel: its history, as pixel_history prints it, in every draw
    zoom = float(f"{json.loads(frame.get_attribute('data-state'))['zoom']:.4f}")    # as the page sends it
    results: list = []
    camera = orbit_camera(viewer.server.scene.scene.view_camera(), -30.0, 10.0, zoom)
    sp.render(viewer.server.scene.scene, camera=camera, trace=True, results=results)
    trace = results[0].trace
    counts = np.bincount(trace.fragments.y.astype(np.int64) * SIZE[0] + trace.fragments.x, minlength=SIZE[0] * SIZE[1])
    p = int(np.argmax(counts))                              # the pixel most fragments reached
    x, y = p % SIZE[0], p // SIZE[0]
    page.mouse.click(box["x"] + (x + 0.5) * box["width"] / SIZE[0], box["y"] + (y + 0.5) * box["height"] / SIZE[1])
    page.wait_for_selector(f"#pixel[data-x='{x}'][data-y='{y}'][data-ready='1']", timeout=120000)
    shown = _read_history(page)
    history = trace.pixel_history(x, y)
    columns, rows = history.table()
    assert len(rows) == counts[p] >= 1
    assert shown == [{"title": f"draw 1: {results[0].name} ({results[0].program})",
                      "heading": str(history).splitlines()[0], "columns": columns, "rows": rows}]
    written = [i for i, r in enumerate(rows) if r[columns.index("merger")] == "written"]
    assert page.locator("#history tbody tr.winner").count() == (1 if written else 0)

    # pick a program: the picture is that program's
    page.select_option("#program", "normals")
    _wait_for_state(page, az=-30.0, el=10.0)
    page.wait_for_function("() => JSON.parse(document.getElementById('frame').dataset.state).program === 'normals'",
                           timeout=120000)
    assert _shown_frame(page) == _expected_frame(viewer, -30.0, 10.0, zoom, "normals")
    page.wait_for_selector(f"#pixel[data-x='{x}'][data-y='{y}'][data-ready='1']", timeout=120000)

    shot = Path(os.environ.get("SOFTPIPE_VIEWER_SCREENSHOT") or tmp_path / "viewer.png")
    _screenshot(page, shot)
    assert not errors, errors
    assert not refused, f"the page asked for {refused}"
    context.close()


def _screenshot(page, path: Path) -> None:
    """The page as it looks, as a small PNG (256 colors) for the docs."""
    from PIL import Image
    image = Image.open(io.BytesIO(page.screenshot(full_page=True))).convert("RGB")
    path.parent.mkdir(parents=True, exist_ok=True)
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, format="PNG", optimize=True)
