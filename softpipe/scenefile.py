"""Scene files: a camera, lights, materials and meshes, written in TOML.

``load_scene(path)`` reads a scene file into a :class:`Scene`;
``render_scene(scene)`` draws it into a new :class:`~softpipe.framebuffer.Framebuffer`.
``examples/scene.toml`` is a full example with every key explained; in short::

    ambient = [0.1, 0.1, 0.1]         # global ambient light (optional)

    [camera]                          # optional; without it the camera frames every mesh
    eye = [0, 1.5, 5]                 # or: frame = true, azimuth, elevation, fovy, margin, up
    target = [0, 0.5, 0]
    fovy = 40                         # also up, near, far

    [render]                          # all optional
    width = 640
    height = 480
    background = [0.08, 0.09, 0.12]   # RGB or RGBA, linear, 0..1
    samples = "rgss4"                 # a sample pattern name (softpipe.sampling.pattern_named)
    sample_shading = "sample"         # "sample" (supersampling), "center"/"centroid" (MSAA)
    program = "normals"               # the default shading program of every mesh
    cull = "back"                     # "back", "front" or "none"
    wireframe = false                 # draw the triangle edges over the image
    wireframe_color = [1, 1, 1]

    [[lights]]                        # any number; without any, a key/fill/rim studio set
    kind = "point"                    # "directional", "point" or "spot"
    position = [2, 3, 2]              # and the other Light fields; color = diffuse and specular

    [materials.gold]                  # Material fields by name; diffuse_texture = "file.png"
    kd = [0.8, 0.6, 0.2]

    [[meshes]]
    obj = "model.obj"                 # relative to this file; or shape = "uv_sphere" + its parameters
    material = "gold"                 # a name from [materials], or an inline table
    transform = [{ translate = [0, 1, 0] }, { rotate_y = 30 }, { scale = 0.5 }]

Transforms
----------
``transform`` is a list of one-key tables, or one table whose keys are taken in the
order written. The entries multiply left to right as :func:`softpipe.transforms.compose`
does: ``M = E1 · E2 · … · En``, so the **last** entry acts on the mesh first, and
``translate, rotate, scale`` is the usual "scale, then rotate, then move". Entries:
``translate = [x, y, z]``, ``scale = s`` or ``[sx, sy, sz]``, ``rotate = [degrees, ax, ay, az]``
(about an axis), ``rotate_x``/``rotate_y``/``rotate_z = degrees``, and
``matrix = [[...], [...], [...], [...]]`` (4×4, rows, affine). A mirroring transform
(negative determinant) is drawn with clockwise front faces, so culling still removes
the back faces.

Errors
------
Every mistake raises :class:`SceneError` (a ``ValueError``) whose message starts with
the file name and names the table and the key: an unknown key (with the keys that are
allowed there), a value of the wrong type, a missing file, a TOML syntax error (with
its line: ``scene.toml:7: TOML syntax error: …``), or a value the library rejects
(``Camera``, ``Light``, ``Material``, a shape generator).

Limits
------
The meshes of one scene may hold at most :data:`MAX_SCENE_TRIANGLES` triangles in all
(a generated shape is counted before it is made); the image obeys the framebuffer's
limits (``MAX_DIMENSION``, ``MAX_TOTAL_SAMPLES``).

Uniforms
--------
Each mesh is drawn with the standard uniforms of :func:`softpipe.scene.standard_uniforms`
plus ``material`` (its :class:`~softpipe.material.Material`), ``color`` (its ``kd``),
``lighting`` (the scene's :class:`~softpipe.material.Lighting` in eye space, a
``LightingUniform``: ``global_ambient`` and the packed ``lights``) and, when its material
has a diffuse texture, ``texture`` (a :class:`~softpipe.texture.Texture2D`).
"""
from __future__ import annotations

import dataclasses
import difflib
import inspect
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

try:  # Python 3.11+
    import tomllib as _toml
except ModuleNotFoundError:  # pragma: no cover - Python 3.10 with the tomli backport
    try:
        import tomli as _toml
    except ModuleNotFoundError:
        _toml = None

from . import shapes
from .camera import Camera
from .framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES, Framebuffer
from .material import Light, Lighting, Material
from .mesh import Mesh
from .obj import OBJError, load_obj
from .sampling import pattern_named
from .shaders import PROGRAMS, get_program
from .transforms import compose, rotate, rotate_x, rotate_y, rotate_z, scale, translate

__all__ = ["SceneError", "SceneWarning", "Scene", "SceneObject", "FrameSpec", "DrawResult",
           "load_scene", "parse_scene", "render_scene", "draw_object", "draw_wireframe",
           "studio_lights", "default_program", "program_for", "MAX_SCENE_TRIANGLES", "SHAPES"]

#: The most triangles all the meshes of one scene may hold together.
MAX_SCENE_TRIANGLES = 4_000_000

CULL_MODES = ("back", "front", "none")
SAMPLE_SHADING = ("sample", "center", "centroid")
NORMAL_MODES = ("auto", "area", "angle", "flat")


class SceneError(ValueError):
    """A mistake in a scene file; ``str(e)`` starts with the file name (and line, for syntax).

    Attributes: ``file``, ``table`` (e.g. ``"[[lights]] #2"``), ``key``, ``line``
    (TOML syntax errors only) and ``reason`` (the message without the file name).
    """

    def __init__(self, message: str, file: str = "<string>", table: Optional[str] = None,
                 key: Optional[str] = None, line: Optional[int] = None) -> None:
        self.file, self.table, self.key, self.line, self.reason = file, table, key, line, message
        super().__init__(f"{file}:{line}: {message}" if line else f"{file}: {message}")


class SceneWarning(UserWarning):
    """Something a scene can do without (e.g. an OBJ's missing MTL file)."""


# ---------------------------------------------------------------------------- the scene


@dataclass(frozen=True)
class FrameSpec:
    """How a framed camera looks at the scene (see :meth:`softpipe.camera.Camera.frame`)."""

    azimuth: float = 30.0
    elevation: float = 20.0
    fovy: float = 35.0
    margin: float = 1.1
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass
class SceneObject:
    """One draw: a single-material mesh, its model matrix and how to shade it.

    ``program`` and ``cull`` are None to use the scene's; ``texture`` is the
    :class:`~softpipe.texture.Texture2D` of the material's ``diffuse_texture``.
    """

    name: str
    mesh: Mesh
    model: np.ndarray
    program: Optional[str] = None
    cull: Optional[str] = None
    texture: Any = None

    def world_positions(self) -> np.ndarray:
        p = self.mesh.positions
        return p @ self.model[:3, :3].T + self.model[:3, 3]


@dataclass
class Scene:
    """A loaded scene. ``camera`` None means framed (by ``frame``); ``lights`` None means
    the studio set of :func:`studio_lights`, which follows the camera."""

    objects: List[SceneObject] = field(default_factory=list)
    camera: Optional[Camera] = None
    frame: FrameSpec = field(default_factory=FrameSpec)
    lights: Optional[Tuple[Light, ...]] = None
    ambient: Tuple[float, float, float] = (0.2, 0.2, 0.2)
    width: int = 640
    height: int = 480
    background: Tuple[float, ...] = (0.08, 0.09, 0.12, 1.0)
    samples: str = "1"
    sample_shading: str = "sample"
    program: Optional[str] = None
    cull: str = "back"
    wireframe: bool = False
    wireframe_color: Tuple[float, float, float] = (0.95, 0.95, 0.95)
    materials: Dict[str, Material] = field(default_factory=dict)
    path: str = "<string>"
    warnings: List[str] = field(default_factory=list)

    def replace(self, **changes) -> "Scene":
        return dataclasses.replace(self, **changes)

    @property
    def triangle_count(self) -> int:
        return sum(o.mesh.triangle_count for o in self.objects)

    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """World-space (min, max) of every mesh (after its transform)."""
        if not self.objects:
            raise ValueError(f"{self.path}: the scene has no meshes to frame")
        los, his = [], []
        for o in self.objects:
            with np.errstate(over="ignore", invalid="ignore"):  # Camera.frame rejects what overflowed
                w = o.world_positions()
            if len(w):
                los.append(w.min(axis=0))
                his.append(w.max(axis=0))
        if not los:
            raise ValueError(f"{self.path}: the scene's meshes have no vertices to frame")
        return np.min(los, axis=0), np.max(his, axis=0)

    def view_camera(self, azimuth: Optional[float] = None, elevation: Optional[float] = None) -> Camera:
        """The camera to render with: the scene's own, or one that frames every mesh.

        ``azimuth``/``elevation`` override the framing angles (a framed camera only).
        """
        if self.camera is not None:
            if azimuth is not None or elevation is not None:
                raise ValueError(f"{self.path}: azimuth/elevation apply only to a framed camera "
                                 "(this scene gives [camera] eye)")
            return self.camera
        f = self.frame
        azimuth = f.azimuth if azimuth is None else azimuth
        elevation = f.elevation if elevation is None else elevation
        lo, hi = self.bounds()
        reach = float(max(np.max(np.abs(lo)), np.max(np.abs(hi))))
        if not reach <= 1e100:
            raise ValueError(f"cannot frame meshes that reach {reach:.3g} from the origin (the limit is 1e100); "
                             "give [camera] eye and target")
        return _framed((lo, hi), f, azimuth, elevation, self.width / self.height)

    def lighting_for(self, camera: Camera) -> Lighting:
        lights = studio_lights(camera) if self.lights is None else self.lights
        return Lighting(lights, global_ambient=self.ambient)


def _framed(bounds, f: FrameSpec, azimuth: float, elevation: float, aspect: float) -> Camera:
    """Camera.frame with ``f``'s settings; looking straight down (or up) the default up
    axis, "up" on the screen becomes the direction away from (toward) the azimuth."""
    up = f.up
    if tuple(up) == (0.0, 1.0, 0.0) and abs(math.cos(math.radians(elevation))) < 1e-6:
        s = -1.0 if math.sin(math.radians(elevation)) > 0 else 1.0
        a = math.radians(azimuth)
        up = (s * math.sin(a), 0.0, s * math.cos(a))
    return Camera.frame(bounds, azimuth=azimuth, elevation=elevation, fovy=f.fovy, margin=f.margin,
                        aspect=aspect, up=up)


# ---------------------------------------------------------------------------- defaults


def default_program() -> str:
    """``"phong"`` when a program of that name is registered, else ``"normals"``."""
    return "phong" if "phong" in PROGRAMS else "normals"


def program_for(obj: SceneObject, scene_program: Optional[str] = None) -> str:
    """The program an object is drawn with: its own, else the scene's, else
    ``"textured"`` for a textured mesh when registered, else :func:`default_program`."""
    if obj.program:
        return obj.program
    if scene_program:
        return scene_program
    if obj.texture is not None and "textured" in PROGRAMS:
        return "textured"
    return default_program()


def studio_lights(camera: Camera) -> Tuple[Light, ...]:
    """Three directional lights fixed to the camera: a warm key from the upper left, a
    dim cool fill from the right, and a rim light from behind the subject."""
    to_world = camera.view[:3, :3].T  # eye → world for directions (the view is a rotation + move)

    def light(toward_eye, diffuse, specular, name):
        v = to_world @ np.asarray(toward_eye, dtype=np.float64)
        return Light.directional(tuple(-v / np.linalg.norm(v)), diffuse=diffuse, specular=specular, name=name)

    return (light((-0.6, 0.7, 0.7), (0.9, 0.85, 0.8), (0.9, 0.9, 0.9), "key"),
            light((0.8, 0.1, 0.5), (0.25, 0.28, 0.35), (0.05, 0.05, 0.05), "fill"),
            light((0.3, 0.6, -1.0), (0.5, 0.5, 0.55), (0.6, 0.6, 0.6), "rim"))


# ---------------------------------------------------------------------------- reading values

_MISSING = object()


class _Bad(Exception):
    """A value's problem, worded to follow "key 'k' in [table]"."""


def _describe(v: Any) -> str:
    if isinstance(v, bool):
        return f"boolean {str(v).lower()}"
    if isinstance(v, int):
        text = str(v) if abs(v) < 10 ** 30 else f"{str(v)[:12]}… ({len(str(abs(v)))} digits)"
        return f"integer {text}"
    if isinstance(v, float):
        return f"float {v!r}"
    if isinstance(v, str):
        text = v if len(v) <= 40 else v[:37] + "..."
        return f"string {text!r}"
    if isinstance(v, list):
        return f"an array of {len(v)}"
    if isinstance(v, dict):
        return "a table"
    return f"{type(v).__name__} {str(v)[:40]!r}"  # TOML dates and times


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _float(v: Any, what: str = "a number") -> float:
    if not _is_number(v):
        raise _Bad(f"must be {what}, got {_describe(v)}")
    try:
        x = float(v)
    except OverflowError:
        raise _Bad(f"must be {what}, got {_describe(v)} (too large)") from None
    if not math.isfinite(x):
        raise _Bad(f"must be a finite number, got {_describe(v)}")
    return x


def number(v: Any) -> float:
    return _float(v)


def positive(v: Any) -> float:
    x = _float(v, "a positive number")
    if x <= 0:
        raise _Bad(f"must be a positive number, got {_describe(v)}")
    return x


def integer(v: Any) -> int:
    if not isinstance(v, int) or isinstance(v, bool):
        raise _Bad(f"must be an integer, got {_describe(v)}")
    return v


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise _Bad(f"must be true or false, got {_describe(v)}")
    return v


def string(v: Any) -> str:
    if not isinstance(v, str):
        raise _Bad(f"must be a string, got {_describe(v)}")
    return v


def choice(*options: str) -> Callable[[Any], str]:
    def convert(v: Any) -> str:
        if not isinstance(v, str) or v not in options:
            raise _Bad(f"must be one of {', '.join(repr(o) for o in options)}, got {_describe(v)}")
        return v
    return convert


def numbers(*counts: int, what: str = "numbers") -> Callable[[Any], Tuple[float, ...]]:
    def convert(v: Any) -> Tuple[float, ...]:
        n = " or ".join(str(c) for c in counts)
        if not isinstance(v, list) or len(v) not in counts:
            raise _Bad(f"must be an array of {n} {what}, got {_describe(v)}")
        return tuple(_float(c, f"an array of {n} {what}") for c in v)
    return convert


vec3 = numbers(3)


def color(v: Any) -> Any:
    """A color: one number (gray) or [r, g, b]."""
    if _is_number(v):
        return _float(v)
    if not isinstance(v, list) or len(v) != 3:
        raise _Bad(f"must be a number (gray) or an array [r, g, b], got {_describe(v)}")
    return tuple(_float(c, "a number (gray) or an array [r, g, b]") for c in v)


def program_name(v: Any) -> str:
    name = string(v)
    if name not in PROGRAMS:
        raise _Bad(f"names an unknown program {name!r}; registered programs: {', '.join(sorted(PROGRAMS))}")
    return name


def pattern_name(v: Any) -> str:
    if isinstance(v, int) and not isinstance(v, bool):
        v = str(v)
    name = string(v)
    try:
        pattern_named(name)
    except (ValueError, TypeError) as e:
        raise _Bad(f"is not a sample pattern: {e}") from None
    return name


class _Table:
    """One TOML table being read: checks its keys and converts values, naming itself in errors."""

    def __init__(self, reader: "_Reader", data: Any, label: str, allowed: Sequence[str],
                 what: str = "a table") -> None:
        self.reader, self.label, self.allowed = reader, label, list(allowed)
        if not isinstance(data, dict):
            raise reader.error(f"{label} must be {what}, got {_describe(data)}", table=label)
        self.data = data
        for key in data:
            if key not in self.allowed:
                close = difflib.get_close_matches(key, self.allowed, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise reader.error(f"unknown key {key!r} in {label}{hint}; expected one of "
                                   f"{', '.join(self.allowed)}", table=label, key=key)

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def error(self, message: str, key: Optional[str] = None) -> SceneError:
        if key is None:
            return self.reader.error(f"{self.label}: {message}", table=self.label)
        return self.reader.error(f"key {key!r} in {self.label} {message}", table=self.label, key=key)

    def get(self, key: str, convert: Callable[[Any], Any], default: Any = _MISSING) -> Any:
        if key not in self.data:
            if default is _MISSING:
                raise self.reader.error(f"{self.label} needs key {key!r}", table=self.label, key=key)
            return default
        try:
            return convert(self.data[key])
        except _Bad as e:
            raise self.error(str(e), key) from None

    def library(self, key: Optional[str], make: Callable[[], Any]) -> Any:
        """Call the library (Camera, Light, …); its ValueError/TypeError becomes a SceneError."""
        try:
            return make()
        except (ValueError, TypeError) as e:
            if isinstance(e, SceneError):
                raise
            raise (self.error(str(e)) if key is None else
                   self.reader.error(f"key {key!r} in {self.label}: {e}", table=self.label, key=key)) from None


# ---------------------------------------------------------------------------- the parts


TOP_KEYS = ("ambient", "camera", "render", "lights", "materials", "meshes")
CAMERA_KEYS = ("frame", "eye", "target", "up", "fovy", "near", "far", "azimuth", "elevation", "margin")
RENDER_KEYS = ("width", "height", "background", "samples", "sample_shading", "program", "cull", "wireframe",
               "wireframe_color")
LIGHT_KEYS = ("kind", "name", "color", "ambient", "diffuse", "specular", "position", "direction",
              "attenuation", "spot_direction", "cutoff", "exponent")
MATERIAL_KEYS = ("ke", "ka", "kd", "ks", "shininess", "kr", "kt", "transmission_shininess", "ior", "opacity",
                 "roughness", "diffuse_texture")
MESH_KEYS = ("name", "obj", "shape", "fit", "normals", "transform", "material", "program", "cull")
TRANSFORM_KEYS = ("translate", "rotate", "rotate_x", "rotate_y", "rotate_z", "scale", "matrix")

#: The generators ``shape =`` may name, from :mod:`softpipe.shapes`.
SHAPES = {name: getattr(shapes, name) for name in
          ("plane", "cube", "uv_sphere", "icosphere", "cylinder", "cone", "torus")}


def _shape_params(name: str) -> Dict[str, Any]:
    """A generator's parameters (but ``material``) and their defaults."""
    sig = inspect.signature(SHAPES[name])
    return {p.name: p.default for p in sig.parameters.values() if p.name != "material"}


def _estimate_triangles(shape: str, p: Dict[str, Any]) -> int:
    """An upper bound of the triangles a generator will make, computed before making them."""
    g = lambda k: max(int(p[k]), 0)  # noqa: E731
    if shape == "plane":
        return 2 * g("subdivisions") ** 2
    if shape == "cube":
        return 12 * g("subdivisions") ** 2
    if shape == "icosphere":
        return 20 * 4 ** min(g("subdivisions"), 40)
    if shape == "uv_sphere":
        return 2 * g("segments") * g("rings")
    if shape == "torus":
        return 2 * g("segments") * g("tube_segments")
    return 2 * g("segments") * (g("stacks") + 2)  # cylinder, cone (with caps)


class _Reader:
    """One load of one scene file."""

    def __init__(self, file: str, base_dir: str) -> None:
        self.file, self.base_dir = file, base_dir
        self.triangles = 0
        self.warnings: List[str] = []
        self._objs: Dict[str, Mesh] = {}
        self._textures: Dict[str, Any] = {}

    def error(self, message: str, table: Optional[str] = None, key: Optional[str] = None,
              line: Optional[int] = None) -> SceneError:
        return SceneError(message, file=self.file, table=table, key=key, line=line)

    def path(self, table: _Table, key: str) -> str:
        """A file named by ``key``, relative to the scene file; it must exist."""
        rel = table.get(key, string)
        if not rel.strip() or "\0" in rel:
            raise table.error(f"must name a file, got {_describe(rel)}", key)
        path = os.path.normpath(os.path.join(self.base_dir, os.path.expanduser(rel)))
        if not os.path.isfile(path):
            what = "is a directory, not a file" if os.path.isdir(path) else "file not found"
            raise self.error(f"key {key!r} in {table.label}: {what}: {path}", table=table.label, key=key)
        return path

    # -- the whole file

    def scene(self, doc: dict) -> Scene:
        top = _Table(self, doc, "the top level", TOP_KEYS)
        scene = Scene(path=self.file, warnings=self.warnings)
        ambient = top.get("ambient", color, scene.ambient)
        scene.ambient = (ambient,) * 3 if isinstance(ambient, float) else ambient
        top.library("ambient", lambda: Lighting((), global_ambient=scene.ambient))
        self.render(doc.get("render", {}), scene)
        self.camera(doc.get("camera", {}), scene)
        lights = doc.get("lights", _MISSING)
        if lights is not _MISSING:
            if not isinstance(lights, list):
                raise self.error(f"'lights' must be an array of tables ([[lights]]), got {_describe(lights)}",
                                 key="lights")
            scene.lights = tuple(self.light(k + 1, t) for k, t in enumerate(lights))
        materials = doc.get("materials", {})
        if not isinstance(materials, dict):
            raise self.error(f"'materials' must be a table of [materials.NAME] tables, got {_describe(materials)}",
                             key="materials")
        for name, data in materials.items():
            scene.materials[name] = self.material(data, f"[materials.{name}]", name)
        meshes = doc.get("meshes", [])
        if not isinstance(meshes, list):
            raise self.error(f"'meshes' must be an array of tables ([[meshes]]), got {_describe(meshes)}",
                             key="meshes")
        if not meshes:
            raise self.error("the scene has no [[meshes]]; add at least one (obj = \"file.obj\" or "
                             "shape = \"uv_sphere\")", table="[[meshes]]")
        for k, data in enumerate(meshes):
            scene.objects.extend(self.mesh(k + 1, data, scene))
        if scene.camera is None:  # framed: check now that the framing works
            _Table(self, {}, "[camera]", ()).library(None, scene.view_camera)
        return scene

    def render(self, data: Any, scene: Scene) -> None:
        t = _Table(self, data, "[render]", RENDER_KEYS)
        size = lambda v: _in_range(integer(v), 1, MAX_DIMENSION, "pixels")  # noqa: E731
        scene.width = t.get("width", size, scene.width)
        scene.height = t.get("height", size, scene.height)
        bg = t.get("background", numbers(3, 4), scene.background)
        scene.background = tuple(bg) + ((1.0,) if len(bg) == 3 else ())
        scene.samples = t.get("samples", pattern_name, scene.samples)
        count = len(pattern_named(scene.samples))
        if scene.width * scene.height * count > MAX_TOTAL_SAMPLES:
            raise t.error(f"{scene.width}×{scene.height} pixels × {count} samples exceeds the limit "
                          f"MAX_TOTAL_SAMPLES = {MAX_TOTAL_SAMPLES}")
        scene.sample_shading = t.get("sample_shading", choice(*SAMPLE_SHADING), scene.sample_shading)
        scene.program = t.get("program", program_name, None)
        scene.cull = t.get("cull", choice(*CULL_MODES), scene.cull)
        scene.wireframe = t.get("wireframe", boolean, False)
        wc = t.get("wireframe_color", color, scene.wireframe_color)
        scene.wireframe_color = (wc,) * 3 if isinstance(wc, float) else wc

    def camera(self, data: Any, scene: Scene) -> None:
        t = _Table(self, data, "[camera]", CAMERA_KEYS)
        framed = t.get("frame", boolean, "eye" not in t)
        own, frame_only = ("eye", "target", "near", "far"), ("azimuth", "elevation", "margin")
        for key in own if framed else frame_only:
            if key in t:
                why = ("frame = true places the camera to see every mesh" if framed else
                       "it applies only to a framed camera (frame = true, no eye)")
                raise t.error(f"cannot be used here: {why}", key)
        up = t.get("up", vec3, (0.0, 1.0, 0.0))
        if framed:
            f = FrameSpec(azimuth=t.get("azimuth", number, 30.0), elevation=t.get("elevation", number, 20.0),
                          fovy=t.get("fovy", number, 35.0), margin=t.get("margin", positive, 1.1), up=up)
            t.library(None, lambda: _framed(((-1, -1, -1), (1, 1, 1)), f, f.azimuth, f.elevation, 1.0))
            scene.frame, scene.camera = f, None
        else:
            eye = t.get("eye", vec3)
            kw = dict(eye=eye, target=t.get("target", vec3, (0.0, 0.0, 0.0)), up=up,
                      fovy=t.get("fovy", number, 40.0), near=t.get("near", positive, 0.1),
                      far=t.get("far", positive, 100.0))
            scene.camera = t.library(None, lambda: Camera(**kw))

    def light(self, index: int, data: Any) -> Light:
        label = f"[[lights]] #{index}"
        t = _Table(self, data, label, LIGHT_KEYS)
        if "kind" not in t:
            raise t.error("needs key 'kind': 'directional', 'point' or 'spot'")
        kind = t.get("kind", choice("directional", "point", "spot"))
        kw: Dict[str, Any] = {"kind": kind, "name": t.get("name", string, f"light {index}")}
        if "color" in t:
            for k in ("diffuse", "specular"):
                if k in t:
                    raise t.error("cannot be given with 'color' (color sets both diffuse and specular)", k)
            c = t.get("color", color)
            kw["diffuse"] = kw["specular"] = c
        for key in ("ambient", "diffuse", "specular"):
            if key in t:
                kw[key] = t.get(key, color)
        for key in ("position", "direction", "spot_direction"):
            if key in t:
                kw[key] = t.get(key, vec3)
        if "attenuation" in t:
            kw["attenuation"] = t.get("attenuation", numbers(3))
        for key in ("cutoff", "exponent"):
            if key in t:
                kw[key] = t.get(key, number)
        return t.library(None, lambda: Light(**kw))

    def material(self, data: Any, label: str, name: str) -> Material:
        t = _Table(self, data, label, MATERIAL_KEYS)
        kw: Dict[str, Any] = {"name": name}
        for key in ("ke", "ka", "kd", "ks", "kr", "kt"):
            if key in t:
                kw[key] = t.get(key, color)
        for key in ("shininess", "transmission_shininess", "ior", "opacity", "roughness"):
            if key in t:
                kw[key] = t.get(key, number)
        if "diffuse_texture" in t:
            kw["diffuse_texture"] = self.path(t, "diffuse_texture")
        material = t.library(None, lambda: Material(**kw))
        if material.diffuse_texture:
            self.texture(material.diffuse_texture, t, "diffuse_texture")
        return material

    def texture(self, path: str, table: _Table, key: str):
        if path not in self._textures:
            from .texture import Texture2D
            try:
                self._textures[path] = Texture2D(path)
            except (ValueError, TypeError, OSError) as e:
                raise self.error(f"key {key!r} in {table.label}: {e}", table=table.label, key=key) from None
        return self._textures[path]

    # -- meshes

    def mesh(self, index: int, data: Any, scene: Scene) -> List[SceneObject]:
        label = f"[[meshes]] #{index}"
        if isinstance(data, dict) and isinstance(data.get("name"), str):
            label += f" ({data['name'][:40]!r})"
        params: Dict[str, Any] = {}
        if isinstance(data, dict) and "shape" in data:  # before the keys: they depend on the shape
            try:
                shape = choice(*SHAPES)(data["shape"])
            except _Bad as e:
                raise self.error(f"key 'shape' in {label} {e}", table=label, key="shape") from None
            params = _shape_params(shape)
        t = _Table(self, data, label, MESH_KEYS + tuple(params))
        if ("obj" in t) == ("shape" in t):
            raise t.error("needs either 'obj' (an OBJ file) or 'shape' (one of "
                          f"{', '.join(SHAPES)}), {'not both' if 'obj' in t else 'and has neither'}")
        if "shape" in t:
            mesh = self.shape(t, shape, params)
        else:
            mesh = self.obj(t)
        name = t.get("name", string, mesh.name or f"mesh {index}")
        mesh = mesh.replace(name=name)
        if "fit" in t:
            size = t.get("fit", positive)
            mesh = t.library("fit", lambda: mesh.normalized(size))
        mode = t.get("normals", choice(*NORMAL_MODES), "auto")
        if mode == "flat":
            mesh = mesh.flat_shaded()
        elif mode != "auto":
            mesh = t.library("normals", lambda: mesh.with_normals(mode))
        model = self.transform(t)
        if "material" in t:
            m = t.data["material"]
            if isinstance(m, str):
                if m not in scene.materials:
                    known = ", ".join(scene.materials) or "none"
                    raise t.error(f"names an undefined material {m!r}; [materials] defines: {known}", "material")
                material = scene.materials[m]
            elif isinstance(m, dict):
                material = self.material(m, f"{label} material", f"{name} material")
            else:
                raise t.error(f"must be a material name or an inline table, got {_describe(m)}", "material")
            mesh = mesh.replace(material=material, materials=(), material_ids=None)
        program = t.get("program", program_name, None)
        cull = t.get("cull", choice(*CULL_MODES), None)
        objects = []
        parts = mesh.by_material()
        for material, part in parts:
            texture = self.texture(material.diffuse_texture, t, "material" if "material" in t else "obj") \
                if material.diffuse_texture else None
            part_name = name if len(parts) == 1 else part.name
            objects.append(SceneObject(part_name, part.replace(name=part_name), model, program, cull, texture))
        return objects

    def count(self, t: _Table, key: str, triangles: int) -> None:
        self.triangles += triangles
        if self.triangles > MAX_SCENE_TRIANGLES:
            raise t.error(f"makes the scene's meshes hold {self.triangles:,} triangles, more than the limit "
                          f"MAX_SCENE_TRIANGLES = {MAX_SCENE_TRIANGLES:,}", key)

    def shape(self, t: _Table, shape: str, params: Dict[str, Any]) -> Mesh:
        kw = {}
        for key, default in params.items():
            if key not in t:
                continue
            if isinstance(default, bool):
                kw[key] = t.get(key, boolean)
            elif isinstance(default, int):
                kw[key] = t.get(key, integer)
            else:
                kw[key] = t.get(key, number)
        self.count(t, "shape", _estimate_triangles(shape, {**params, **kw}))
        with np.errstate(all="ignore"):  # a huge size overflows; Mesh then names the bad array
            return t.library("shape", lambda: SHAPES[shape](**kw))

    def obj(self, t: _Table) -> Mesh:
        path = self.path(t, "obj")
        if path not in self._objs:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    mesh = load_obj(path)
                except OBJError as e:
                    raise self.error(f"key 'obj' in {t.label}: {e}", table=t.label, key="obj") from None
                except (OSError, UnicodeError) as e:
                    raise self.error(f"key 'obj' in {t.label}: cannot read {path}: {e}", table=t.label,
                                     key="obj") from None
            self.warnings.extend(str(w.message) for w in caught)
            if mesh.triangle_count == 0:
                raise self.error(f"key 'obj' in {t.label}: {path} has no faces", table=t.label, key="obj")
            self._objs[path] = mesh
        mesh = self._objs[path]
        self.count(t, "obj", mesh.triangle_count)
        return mesh

    def transform(self, t: _Table) -> np.ndarray:
        if "transform" not in t:
            return np.eye(4)
        value = t.data["transform"]
        if isinstance(value, dict):
            entries = [{k: v} for k, v in value.items()]
        elif isinstance(value, list):
            entries = value
        else:
            raise t.error("must be an array of one-key tables or a table of translate/rotate/scale entries, "
                          f"got {_describe(value)}", "transform")
        matrices = []
        for n, entry in enumerate(entries, 1):
            where = f"entry {n} of key 'transform' in {t.label}"
            if not isinstance(entry, dict) or len(entry) != 1:
                raise self.error(f"{where} must be a table with one key ({', '.join(TRANSFORM_KEYS)}), "
                                 f"got {_describe(entry)}" + (f" with {len(entry)} keys" if isinstance(entry, dict)
                                                              else ""), table=t.label, key="transform")
            (kind, v), = entry.items()
            if kind not in TRANSFORM_KEYS:
                close = difflib.get_close_matches(kind, TRANSFORM_KEYS, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise self.error(f"unknown transform {kind!r} in {where}{hint}; expected one of "
                                 f"{', '.join(TRANSFORM_KEYS)}", table=t.label, key="transform")
            try:
                matrices.append(_transform_entry(kind, v))
            except (_Bad, ValueError, TypeError) as e:
                raise self.error(f"{kind!r} in {where} {e}", table=t.label, key="transform") from None
        model = compose(*matrices) if matrices else np.eye(4)
        det = float(np.linalg.det(model[:3, :3]))
        if not np.all(np.isfinite(model)) or not math.isfinite(det) or abs(det) < 1e-12:
            raise t.error("is singular or not finite (a scale of 0 flattens the mesh)", "transform")
        return model


def _in_range(v: int, low: int, high: int, unit: str) -> int:
    if not low <= v <= high:
        raise _Bad(f"must be between {low} and {high} {unit}, got {v}")
    return v


def _transform_entry(kind: str, v: Any) -> np.ndarray:
    if kind == "translate":
        return translate(*vec3(v))
    if kind == "scale":
        if _is_number(v):
            s = _float(v)
            return scale(s, s, s)
        s = numbers(1, 3, what="numbers (s or [sx, sy, sz])")(v)
        return scale(*(s * 3 if len(s) == 1 else s))
    if kind == "rotate":
        angle, *axis = numbers(4, what="numbers [degrees, ax, ay, az]")(v)
        if not any(axis):
            raise _Bad("needs a nonzero axis [degrees, ax, ay, az]")
        return rotate(angle, axis)
    if kind in ("rotate_x", "rotate_y", "rotate_z"):
        angle = _float(v, "an angle in degrees")
        return {"rotate_x": rotate_x, "rotate_y": rotate_y, "rotate_z": rotate_z}[kind](angle)
    # matrix
    if not isinstance(v, list) or len(v) != 4:
        raise _Bad(f"must be 4 rows of 4 numbers, got {_describe(v)}")
    m = np.array([numbers(4)(row) for row in v], dtype=np.float64)
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise _Bad(f"must be affine: its last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    return m


# ---------------------------------------------------------------------------- loading

_LINE = re.compile(r"\(at line (\d+), column (\d+)\)")


def parse_scene(text: str, name: str = "<string>", base_dir: Optional[str] = None) -> Scene:
    """A scene from TOML text; ``name`` labels errors, ``base_dir`` resolves file names
    (the current directory by default)."""
    reader = _Reader(name, os.fspath(base_dir) if base_dir is not None else "")
    if _toml is None:  # pragma: no cover
        raise reader.error("reading scene files needs Python 3.11 (tomllib) or the 'tomli' package")
    if not isinstance(text, str):
        raise TypeError(f"parse_scene: text must be a str, got {type(text).__name__}")
    try:
        doc = _toml.loads(text)
    except RecursionError:
        raise reader.error("TOML error: arrays or tables nested too deeply") from None
    except ValueError as e:  # TOMLDecodeError, and int() of a number with too many digits
        message = str(e)
        found = _LINE.search(message)
        if found:
            line = int(found.group(1))
        elif "end of document" in message:
            line = text.count("\n") + (0 if text.endswith("\n") else 1)
        else:
            line = None
        message = _LINE.sub("", message).replace(" (at end of document)", " (at the end of the file)").strip()
        if "integer string conversion" in message:  # int() refuses more than sys.get_int_max_str_digits()
            message = "an integer has too many digits"
        kind = "TOML syntax error" if isinstance(e, getattr(_toml, "TOMLDecodeError", ())) else "TOML error"
        raise reader.error(f"{kind}: {message}", line=max(line, 1) if line is not None else None) from None
    try:
        return reader.scene(doc)
    except RecursionError:  # pragma: no cover - nothing here recurses on the input
        raise reader.error("the scene is nested too deeply") from None


def load_scene(path) -> Scene:
    """Read a scene file (TOML); file names in it are relative to its folder.

    Every problem raises :class:`SceneError` naming the file, table and key. Warnings
    (e.g. an OBJ's missing MTL file) are kept in ``Scene.warnings`` and issued as
    :class:`SceneWarning`.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise SceneError("scene file not found", file=path) from None
    except IsADirectoryError:
        raise SceneError("is a directory, not a scene file", file=path) from None
    except OSError as e:
        raise SceneError(f"cannot read the scene file: {e.strerror or e}", file=path) from None
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark is skipped
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise SceneError(f"not UTF-8 text (byte {e.start})", file=path, line=line) from None
    scene = parse_scene(text, path, os.path.dirname(os.path.abspath(path)))
    for message in scene.warnings:
        warnings.warn(message, SceneWarning, stacklevel=2)
    return scene


# ---------------------------------------------------------------------------- rendering


@dataclass
class DrawResult:
    """What one draw of :func:`render_scene` left: its post-clip primitives (for a wireframe),
    its :class:`~softpipe.trace.Trace` when traced, and its stage timings."""

    name: str
    program: str
    primitives: Any
    trace: Any = None
    timings: Dict[str, float] = field(default_factory=dict)


def draw_object(fb: Framebuffer, obj: SceneObject, camera: Camera, lighting, *, program: str,
                cull: str = "back", sample_shading: str = "sample", trace: bool = False) -> DrawResult:
    """Draw one object with a built-in program (the uniforms are listed in the module docstring)."""
    from .pipeline import DrawCall
    from .scene import standard_uniforms

    prog = get_program(program)
    mesh = obj.mesh
    u = standard_uniforms(camera, fb.width / fb.height, obj.model)
    u["material"] = mesh.material
    u["color"] = mesh.material.kd
    u["lighting"] = lighting.uniform(camera.view) if isinstance(lighting, Lighting) else lighting
    if obj.texture is not None:
        u["texture"] = obj.texture
    attributes = {"normal": mesh.normals if mesh.normals is not None else mesh.vertex_normals()}
    if mesh.uvs is not None:
        attributes["uv"] = mesh.uvs
    mirrored = np.linalg.det(obj.model[:3, :3]) < 0
    call = DrawCall(fb, mesh.positions, mesh.indices, None, prog.vertex, prog.fragment, u,
                    attributes=attributes, interpolation=dict(prog.interpolation) or None, cull=cull,
                    front_face="cw" if mirrored else "ccw", sample_shading=sample_shading)
    if trace:
        t = call.run(trace=True)
        return DrawResult(obj.name, prog.name, t.primitives, t, dict(call.timings))
    call.run()
    return DrawResult(obj.name, prog.name, call.primitives, None, dict(call.timings))


def render_scene(scene: Scene, *, camera: Optional[Camera] = None, trace: bool = False,
                 results: Optional[list] = None,
                 progress: Optional[Callable[[int, int, SceneObject], None]] = None) -> Framebuffer:
    """Draw every object of ``scene`` into a new framebuffer (and the wireframe, if asked).

    ``camera`` replaces the scene's; ``trace`` keeps each draw's Trace; ``results``, a
    list, receives one :class:`DrawResult` per draw; ``progress(k, n, object)`` is
    called before draw k of n.
    """
    camera = camera or scene.view_camera()
    fb = Framebuffer(scene.width, scene.height, pattern_named(scene.samples))
    fb.clear(scene.background)
    lighting = scene.lighting_for(camera).uniform(camera.view)
    drawn = []
    for k, obj in enumerate(scene.objects):
        if progress is not None:
            progress(k, len(scene.objects), obj)
        r = draw_object(fb, obj, camera, lighting, program=program_for(obj, scene.program),
                        cull=obj.cull or scene.cull, sample_shading=scene.sample_shading, trace=trace)
        drawn.append(r)
    if results is not None:
        results.extend(drawn)
    if scene.wireframe:
        draw_wireframe(fb, [r.primitives for r in drawn], scene.wireframe_color)
    return fb


def draw_wireframe(fb: Framebuffer, primitives: Sequence[Any], color=(0.95, 0.95, 0.95)) -> None:
    """Draw the edges of post-clip triangles over ``fb``, hiding those behind the surface.

    An edge pixel is drawn when its window depth (linear along the edge, as depth is in
    window space) is no farther than the farthest depth in the 3×3 pixels around it,
    so edges on the visible surface and on silhouettes show and edges behind it do not.
    Every sample of the pixel gets the color.
    """
    rgba = np.array(tuple(color)[:3] + (1.0,), dtype=np.float32)
    h, w = fb.height, fb.width
    depth = fb.depth
    padded = np.pad(depth, 1, mode="edge")
    far = np.max([padded[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)
    for prims in primitives:
        if prims is None or len(prims.window) == 0:
            continue
        tri = prims.window
        for k in range(3):
            x, y, z = _segment_pixels(tri[:, k], tri[:, (k + 1) % 3], w, h)
            keep = z <= far[y, x] + 1e-6
            fb.samples_color[:, y[keep], x[keep]] = rgba  # every sample plane [S, H, W, 4]


def _segment_pixels(a: np.ndarray, b: np.ndarray, w: int, h: int):
    """Pixels (column, row, window depth) along window-space segments a→b, one step per pixel."""
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[ok], b[ok]
    if len(a) == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0)
    steps = np.ceil(np.abs(b[:, :2] - a[:, :2]).max(axis=1)).astype(np.int64) + 1
    seg = np.repeat(np.arange(len(a)), steps)
    start = np.repeat(np.cumsum(steps) - steps, steps)
    t = (np.arange(len(seg)) - start) / np.maximum(np.repeat(steps, steps) - 1, 1)
    p = a[seg] + (b[seg] - a[seg]) * t[:, None]
    x = np.floor(p[:, 0]).astype(np.int64)
    y = np.floor(h - p[:, 1]).astype(np.int64)  # window y up → image row down
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    return x[inside], y[inside], p[inside, 2]
