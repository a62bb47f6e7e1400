"""The live viewer: ``softpipe view MODEL_OR_SCENE`` and ``softpipe.view(scene)`` (docs/viewer.md).

A small HTTP server on loopback (127.0.0.1, a free port) serves one page and a small API; the
page shows the scene rendered live and re-renders as the camera moves:

    GET /                  the page (``softpipe/views/viewer_page/``: page.html, page.css, page.js)
    GET /api/info          JSON: the frame's size, the programs, lights and stage pictures to pick from
    GET /api/frame?...     a PNG: the scene seen by the camera of the query (below), as :func:`softpipe.render`
                           draws it with that camera (the "final" stage: the framebuffer, byte for byte as
                           ``fb.save(f, format="png")`` writes it) or one stage picture of the traced render
    GET /api/history?...   JSON: pixel (x, y)'s history in every draw, ``trace.pixel_history(x, y).table()``

The query of a frame or a history: ``az`` and ``el`` (degrees the camera has orbited from the
scene's own, about its up axis and above it), ``zoom`` (the camera is ``zoom`` times nearer),
``program`` (a registered program, or empty for the scene's own), ``light`` (one of
:data:`LIGHTS`), ``stage`` (one of :data:`STAGES`); a frame also ``seq`` and ``client``, which
coalesce a drag's requests (below); a history ``x`` and ``y``. A bad value is answered 400 with
JSON ``{"error": "..."}`` naming the parameter.

Coalescing: the page keeps one frame request in flight and, while it is, remembers only the
newest camera; the server renders one frame at a time and answers a request that a newer one of
the same page (``client``) has overtaken while it waited ``409 superseded`` without rendering it.
A fast drag so renders the newest camera next, never a queue of stale frames.

Only loopback: :func:`serve` refuses any other host (a page that runs code of the user's on
request is not for the network), and the server answers 403 to a request whose ``Host`` header
names another host (a web page elsewhere cannot reach it through DNS rebinding).
"""
from __future__ import annotations

import dataclasses
import functools
import html
import importlib.resources
import io
import ipaddress
import json
import math
import re
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Callable, Dict, Optional, Tuple
from urllib.parse import parse_qs, urlsplit

import numpy as np

from softpipe.light.material import Light
from softpipe.pipeline.camera import Camera
from softpipe.scenes.drawing import RENDER_SIZE, prepare_scene, render
from softpipe.scenes.scene import Scene, studio_lights

__all__ = ["LiveScene", "ViewState", "ViewerServer", "Viewer", "serve", "view", "orbit_camera", "check_loopback",
           "LIGHTS", "STAGES", "ZOOM_RANGE"]

#: The lights the page offers, by name: what each draws with.
LIGHTS = {
    "scene": "the scene's own lights (a model's: the studio key, fill and rim, which follow the camera)",
    "headlight": "one white directional light shining along the camera's view (it follows the camera)",
    "key": "the studio key light alone (warm, from the upper left; it follows the camera)",
    "overhead": "one white directional light straight down the scene's up axis (fixed in the world)",
}

#: The pictures the page offers: the framebuffer ("final"), or one stage picture of the traced render
#: (softpipe.views.pictures, composed over the draws as the explorer composes them).
STAGES = ("final", "vertices", "primitives", "coverage", "depth", "overdraw")

#: How much nearer (or farther, below 1) the camera may come than the scene's own.
ZOOM_RANGE = (0.05, 20.0)

#: The most degrees the orbit's elevation reaches above or below the horizon (the up axis itself would
#: leave the camera's up undefined).
MAX_ELEVATION = 89.0

#: The parameters of a frame's and a history's query, and what each is.
FRAME_PARAMETERS = ("az", "el", "zoom", "program", "light", "stage", "seq", "client")
HISTORY_PARAMETERS = ("az", "el", "zoom", "program", "light", "stage", "x", "y")


# ---------------------------------------------------------------------------- the camera and the state


def orbit_camera(base: Camera, azimuth: float = 0.0, elevation: float = 0.0, zoom: float = 1.0) -> Camera:
    """``base`` orbited about its target: ``azimuth`` degrees about its up axis, ``elevation`` degrees
    higher (the sum kept within ±89° of the horizon), and ``zoom`` times nearer (its near and far
    planes too, so the depth buffer's precision is the same). (0, 0, 1) is ``base`` itself."""
    if azimuth == 0.0 and elevation == 0.0 and zoom == 1.0:
        return base
    eye, target = np.asarray(base.eye, np.float64), np.asarray(base.target, np.float64)
    up = np.asarray(base.up, np.float64)
    up = up / np.linalg.norm(up)
    d = eye - target
    r = float(np.linalg.norm(d))
    level = d - (d @ up) * up                       # the eye's direction in the horizon's plane
    if np.linalg.norm(level) < 1e-12 * r:           # looking straight along up: any direction in the plane
        level = np.cross(up, (1.0, 0.0, 0.0) if abs(up[0]) < 0.9 else (0.0, 0.0, 1.0))
    a = level / np.linalg.norm(level)
    b = np.cross(up, a)
    start = math.degrees(math.asin(max(-1.0, min(1.0, float(d @ up) / r))))
    el = math.radians(max(-MAX_ELEVATION, min(MAX_ELEVATION, start + elevation)))
    az = math.radians(azimuth)
    offset = (r / zoom) * (math.cos(el) * (math.cos(az) * a + math.sin(az) * b) + math.sin(el) * up)
    return base.replace(eye=tuple(float(c) for c in target + offset), near=base.near / zoom, far=base.far / zoom)


@dataclasses.dataclass(frozen=True)
class ViewState:
    """What the page asks to see: the camera's orbit from the scene's own, the program, the light, the
    picture. ``program`` None: the scene's own (each object's)."""

    azimuth: float = 0.0
    elevation: float = 0.0
    zoom: float = 1.0
    program: Optional[str] = None
    light: str = "scene"
    stage: str = "final"

    def __post_init__(self) -> None:
        from softpipe.programs import PROGRAMS
        for name in ("azimuth", "elevation", "zoom"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number of {'times' if name == 'zoom' else 'degrees'}, "
                                 f"got {v!r}")
        if not ZOOM_RANGE[0] <= self.zoom <= ZOOM_RANGE[1]:
            raise ValueError(f"zoom must be from {ZOOM_RANGE[0]:g} to {ZOOM_RANGE[1]:g} (times nearer than the "
                             f"scene's camera), got {self.zoom!r}")
        if self.program is not None and self.program not in PROGRAMS:
            raise ValueError(f"program: unknown program {self.program!r}; registered programs: "
                             f"{', '.join(sorted(PROGRAMS))}")
        if self.light not in LIGHTS:
            raise ValueError(f"light: unknown light {self.light!r}; the lights: {', '.join(LIGHTS)}")
        if self.stage not in STAGES:
            raise ValueError(f"stage: unknown stage picture {self.stage!r}; the pictures: {', '.join(STAGES)}")

    @classmethod
    def from_query(cls, query: Dict[str, str]) -> "ViewState":
        """The state a frame's or a history's query asks for (absent parameters: the defaults)."""
        numbers = {}
        for key, name in (("az", "azimuth"), ("el", "elevation"), ("zoom", "zoom")):
            if key in query:
                numbers[name] = _number(key, query[key])
        program = query.get("program") or None
        return cls(**numbers, program=program, light=query.get("light") or "scene",
                   stage=query.get("stage") or "final")


def _number(key: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{key}: expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{key}: expected a finite number, got {text!r}")
    return v


def _whole(key: str, text: str, low: int, high: int, what: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise ValueError(f"{key}: expected a whole number, got {text!r}") from None
    if not low <= v <= high:
        raise ValueError(f"{what}")
    return v


# ---------------------------------------------------------------------------- the scene, rendered


def _lights(name: str, scene: Scene, camera: Camera) -> Optional[Tuple[Light, ...]]:
    """The ``lights`` of the scene to draw for light ``name`` (None: the studio set, placed for the camera)."""
    if name == "scene":
        return scene.lights
    if name == "key":
        return studio_lights(camera)[:1]
    if name == "headlight":
        forward = np.asarray(camera.target, np.float64) - np.asarray(camera.eye, np.float64)
        return (Light.directional(tuple(forward / np.linalg.norm(forward)), name="headlight"),)
    up = np.asarray(camera.up, np.float64)
    return (Light.directional(tuple(-up / np.linalg.norm(up)), name="overhead"),)


def _png(image: np.ndarray) -> bytes:
    from PIL import Image
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


class LiveScene:
    """A scene the viewer renders again for each camera the page asks for.

    Parameters
    ----------
    scene : Scene
        As :func:`softpipe.scenes.drawing.prepare_scene` makes it (``softpipe view``'s options applied).
    title : str
        What the page calls it.
    """

    def __init__(self, scene: Scene, title: str = "") -> None:
        self.scene = scene
        self.title = title or scene.path
        self.camera = scene.view_camera()
        self.lock = threading.Lock()            # one render at a time: each already uses every core
        self._traced: Optional[Tuple[ViewState, list]] = None     # the last traced render, for clicks

    @classmethod
    def load(cls, model, **options: Any) -> "LiveScene":
        """A model's name, an OBJ or TOML path, a Mesh or a Scene, with :func:`softpipe.render`'s options."""
        title = model if isinstance(model, str) else getattr(model, "path", "") or type(model).__name__
        return cls(prepare_scene(model, **options), str(title))

    @property
    def size(self) -> Tuple[int, int]:
        return self.scene.width, self.scene.height

    def camera_for(self, state: ViewState) -> Camera:
        """The camera of ``state``: the scene's own, orbited and zoomed (:func:`orbit_camera`)."""
        return orbit_camera(self.camera, state.azimuth, state.elevation, state.zoom)

    def scene_for(self, state: ViewState, camera: Camera) -> Scene:
        """The scene drawn for ``state``: the light it picks in place of the scene's."""
        if state.light == "scene":
            return self.scene
        return self.scene.replace(lights=_lights(state.light, self.scene, camera))

    def framebuffer(self, state: ViewState, *, trace: bool = False, results: Optional[list] = None):
        """The framebuffer of ``state``: :func:`softpipe.render` of the scene with its camera and program."""
        camera = self.camera_for(state)
        return render(self.scene_for(state, camera), camera=camera, program=state.program, trace=trace,
                      results=results)

    def traced(self, state: ViewState) -> list:
        """Every draw of ``state``'s render, traced (``DrawResult`` s), kept for the next click at this state."""
        key = dataclasses.replace(state, stage="final")
        if self._traced is None or self._traced[0] != key:
            results: list = []
            self._traced = None                 # the old traces go before the new are made
            self.framebuffer(key, trace=True, results=results)
            self._traced = (key, results)
        return self._traced[1]

    def frame(self, state: ViewState) -> bytes:
        """The PNG the page shows for ``state``: the framebuffer, or one stage picture of the traced render."""
        if state.stage == "final":
            buffer = io.BytesIO()
            self.framebuffer(state).save(buffer, format="png")
            return buffer.getvalue()
        from softpipe.views.explorer import scene_pictures
        results = self.traced(state)
        pictures = scene_pictures([(r.name, r.program, r.trace) for r in results])
        return _png(pictures[state.stage])

    def check_pixel(self, x: int, y: int) -> None:
        w, h = self.size
        if not (0 <= x < w and 0 <= y < h):
            raise ValueError(f"pixel ({x}, {y}) is outside the {w}×{h} frame: x must be from 0 to {w - 1}, "
                             f"y from 0 to {h - 1}")

    def history(self, state: ViewState, x: int, y: int) -> Dict[str, Any]:
        """Pixel (x, y)'s history in every draw of ``state``'s render, as JSON: each draw that reached it,
        in order, with ``trace.pixel_history(x, y)``'s heading and table (the strings it prints)."""
        self.check_pixel(x, y)
        draws = []
        for k, r in enumerate(self.traced(state)):
            h = r.trace.pixel_history(x, y)
            if not len(h):
                continue
            columns, rows = h.table()
            draws.append({"draw": k, "name": r.name, "program": r.program, "heading": str(h).splitlines()[0],
                          "columns": columns, "rows": rows})
        return {"x": x, "y": y, "draws": draws}

    def info(self) -> Dict[str, Any]:
        from softpipe.programs import PROGRAMS
        w, h = self.size
        return {"title": self.title, "width": w, "height": h, "programs": sorted(PROGRAMS),
                "lights": LIGHTS, "stages": list(STAGES), "zoom": list(ZOOM_RANGE), "max_elevation": MAX_ELEVATION,
                "program": self.scene.program if isinstance(self.scene.program, str) else None}


# ---------------------------------------------------------------------------- the server


def check_loopback(host: str) -> str:
    """``host`` if it is a loopback address (``localhost`` is 127.0.0.1); else a ValueError that says why."""
    if host == "localhost":
        return "127.0.0.1"
    try:
        address = ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        raise ValueError(f"host {host!r}: the viewer serves on loopback only; give 127.0.0.1, ::1 or localhost "
                         "(not a name or an address other machines reach)") from None
    if not address.is_loopback:
        raise ValueError(f"host {host!r} is not a loopback address: the viewer serves on loopback only "
                         "(127.0.0.1, ::1 or localhost), so that no other machine can reach it")
    return str(address)


@functools.lru_cache(maxsize=None)
def _page_text(name: str) -> str:
    """One file of the page (package data, ``softpipe/views/viewer_page/``)."""
    return (importlib.resources.files("softpipe.views") / "viewer_page" / name).read_text(encoding="utf-8")


def page_html(title: str) -> str:
    """The page: ``page.html`` with its style sheet and script in place."""
    page = _page_text("page.html").replace("__TITLE__", html.escape(title))
    return page.replace("__STYLE__", _page_text("page.css")).replace("__SCRIPT__", _page_text("page.js"))


class _Handler(BaseHTTPRequestHandler):
    server: "ViewerServer"
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:     # noqa: A002 (http.server's name)
        if self.server.log is not None:
            self.server.log(format % args)

    def _send(self, status: int, body: bytes, kind: str, headers: Optional[Dict[str, str]] = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, value: Any) -> None:
        self._send(status, json.dumps(value, ensure_ascii=False).encode("utf-8"), "application/json; charset=utf-8")

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        server = self.server
        if not server.host_allowed(self.headers.get("Host", "")):
            self._json(403, {"error": f"the viewer answers only requests to {server.url} (Host "
                                      f"{self.headers.get('Host', '')!r} refused)"})
            return
        parts = urlsplit(self.path)
        try:
            pairs = parse_qs(parts.query, keep_blank_values=True, strict_parsing=False)
            repeated = [k for k, v in pairs.items() if len(v) > 1]
            if repeated:
                raise ValueError(f"{repeated[0]}: given {len(pairs[repeated[0]])} times; give it once")
            query = {k: v[0] for k, v in pairs.items()}
            if parts.path == "/":
                self._send(200, page_html(server.scene.title).encode("utf-8"), "text/html; charset=utf-8")
            elif parts.path == "/api/info":
                self._json(200, server.scene.info())
            elif parts.path == "/api/frame":
                self._frame(query)
            elif parts.path == "/api/history":
                self._history(query)
            else:
                self._json(404, {"error": f"no such page: {parts.path} (the viewer serves /, /api/info, "
                                          "/api/frame and /api/history)"})
        except ValueError as e:
            self._json(400, {"error": str(e)})
        except (BrokenPipeError, ConnectionResetError):
            pass                                # the page went away (a reload) before its answer
        except Exception as e:  # noqa: BLE001 (a render that fails is the page's to show; the server goes on)
            self._json(500, {"error": f"{type(e).__name__}: {' '.join(str(e).split())}"})

    def _frame(self, query: Dict[str, str]) -> None:
        _known(query, FRAME_PARAMETERS)
        state = ViewState.from_query(query)
        seq = _whole("seq", query.get("seq", "0"), 0, 2 ** 53, "seq: expected a whole number from 0 to 2**53")
        client = query.get("client", "")
        if not re.fullmatch(r"[A-Za-z0-9_-]{0,64}", client):
            raise ValueError("client: expected up to 64 letters, digits, '-' or '_'")
        server = self.server
        if not server.newest(client, seq):
            self._json(409, {"error": "superseded: a newer frame of this page was asked for"})
            return
        with server.scene.lock:
            if not server.is_newest(client, seq):     # overtaken while it waited for the render before it
                self._json(409, {"error": "superseded: a newer frame of this page was asked for"})
                return
            start = time.perf_counter()
            png = server.scene.frame(state)
            seconds = time.perf_counter() - start
        self._send(200, png, "image/png", {"X-Softpipe-Seconds": f"{seconds:.4f}", "X-Softpipe-Seq": str(seq)})

    def _history(self, query: Dict[str, str]) -> None:
        _known(query, HISTORY_PARAMETERS)
        for key in ("x", "y"):
            if key not in query:
                raise ValueError(f"{key}: give the pixel's {key} (x from the left, y from the top)")
        state = ViewState.from_query(query)
        scene = self.server.scene
        x = _whole("x", query["x"], -2 ** 31, 2 ** 31, "x: out of range")
        y = _whole("y", query["y"], -2 ** 31, 2 ** 31, "y: out of range")
        scene.check_pixel(x, y)
        with scene.lock:
            self._json(200, scene.history(state, x, y))


def _known(query: Dict[str, str], names: Tuple[str, ...]) -> None:
    unknown = [k for k in query if k not in names]
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r}; the parameters are {', '.join(names)}")


class ViewerServer(ThreadingHTTPServer):
    """The viewer's HTTP server: ``scene`` (a :class:`LiveScene`) served on loopback at :attr:`url`."""

    daemon_threads = True

    def __init__(self, scene: LiveScene, host: str = "127.0.0.1", port: int = 0,
                 log: Optional[Callable[[str], None]] = None) -> None:
        host = check_loopback(host)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port must be a whole number from 0 to 65535 (0: a free one), got {port!r}")
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.scene, self.log = scene, log
        self._seq: Dict[str, int] = {}
        self._seq_lock = threading.Lock()
        try:
            super().__init__((host, port), _Handler)
        except OSError as e:                    # taken, or a port below 1024 without the right to it
            raise OSError(f"cannot serve on {host} port {port}: {e.strerror or e} (port 0, the default, "
                          "takes a free one)") from None
        self.port = int(self.server_address[1])
        shown = f"[{host}]" if ":" in host else host
        self.url = f"http://{shown}:{self.port}/"
        self._hosts = {f"{shown}:{self.port}", f"localhost:{self.port}"}

    def host_allowed(self, host: str) -> bool:
        return host in self._hosts

    def newest(self, client: str, seq: int) -> bool:
        """Note frame ``seq`` of page ``client``; False if a newer one of that page was asked for already."""
        with self._seq_lock:
            if seq < self._seq.get(client, -1):
                return False
            if client not in self._seq and len(self._seq) >= 1024:     # pages long gone: forget them
                self._seq.clear()
            self._seq[client] = seq
            return True

    def is_newest(self, client: str, seq: int) -> bool:
        with self._seq_lock:
            return self._seq.get(client, -1) <= seq


def serve(scene: LiveScene, host: str = "127.0.0.1", port: int = 0,
          log: Optional[Callable[[str], None]] = None) -> ViewerServer:
    """A :class:`ViewerServer` for ``scene``, bound (not yet serving: call ``serve_forever``).

    ``host`` must be a loopback address (ValueError otherwise); ``port`` 0 takes a free port.
    """
    return ViewerServer(scene, host, port, log)


class Viewer:
    """A viewer serving in a background thread: ``softpipe.view(scene)``. In Jupyter it shows the page in
    an IFrame; :meth:`stop` (or leaving a ``with`` block) stops the server."""

    def __init__(self, server: ViewerServer, height: Optional[int] = None) -> None:
        self.server = server
        self.url = server.url
        self._height = height
        self._thread = threading.Thread(target=server.serve_forever, name="softpipe-viewer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop serving and close the port."""
        if self._thread.is_alive():
            self.server.shutdown()
            self._thread.join()
        self.server.server_close()

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = "serving" if self._thread.is_alive() else "stopped"
        return f"Viewer({self.server.scene.title!r}, {state} at {self.url})"

    def _repr_html_(self) -> str:
        w, h = self.server.scene.size
        height = self._height or h + 360
        return (f'<iframe src="{html.escape(self.url)}" width="100%" height="{height}" '
                f'style="border:0;min-width:{w + 40}px" title="softpipe viewer"></iframe>')


def view(model, *, port: int = 0, host: str = "127.0.0.1", iframe_height: Optional[int] = None,
         **options: Any) -> Viewer:
    """Show ``model`` live: serve the viewer's page on loopback in a background thread.

    In Jupyter the returned :class:`Viewer` shows the page in an IFrame (the browser showing the
    notebook must run on the same machine as the kernel: the page is served on its loopback);
    elsewhere open ``viewer.url``. Drag to orbit, scroll to zoom, pick the program, the light and
    the stage picture, click a pixel for its history (docs/viewer.md).

    Parameters
    ----------
    model : str, path-like, Mesh or Scene
        What :func:`softpipe.render` takes.
    port : int
        0 (a free port) by default.
    host : str
        A loopback address: 127.0.0.1 (default), ::1 or localhost; any other is refused (ValueError).
    iframe_height : int, optional
        The IFrame's height in pixels in Jupyter (default: the frame's height and room for the controls).
    **options
        :func:`softpipe.render`'s options (``width``, ``height``, ``program``, ``shadows``, …): the
        scene as first shown.
    """
    check_loopback(host)
    options.setdefault("default_size", RENDER_SIZE)
    scene = LiveScene.load(model, **options)
    return Viewer(serve(scene, host, port), iframe_height)

