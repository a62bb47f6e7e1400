"""Many frames: a job of frames rendered on a Dask cluster (or in this process), resumable.

A **job** lists frames as a product of models × cameras × programs × materials ×
lights × sizes × sample patterns (``[sweep]``), and/or one by one (``[[frames]]``).
:func:`load_job` reads it from a TOML file, :func:`parse_job` from text and
:func:`job_from_dict` from Python dicts of the same shape; every mistake is a
:class:`JobError` (a :class:`~softpipe.scenes.scenefile.SceneError`) naming the file, the
table and the key. ``examples/sweep.toml`` explains every key; in short::

    [job]                               # optional: what every frame shares
    background = [0.08, 0.09, 0.12]
    fovy = 35
    elevation = 20                      # of the cameras given by azimuth alone

    [models]                            # optional: models beyond the bundled ones
    ball = { shape = "uv_sphere", segments = 48, rings = 24 }
    mine = { obj = "meshes/mine.obj" }  # relative to the job file

    [materials.glossy]                  # fields replacing the model's own material's
    ks = [0.9, 0.9, 0.9]
    shininess = 64

    [lights.sun]                        # a named light set; "studio" and "shadows" are built in
    shadows = true
    [[lights.sun.light]]
    kind = "directional"
    direction = [-1, -2, -1]

    [sweep]                             # the product (or [[sweep]], several)
    models = ["ball", "bunny"]
    cameras = [0, 90, "front", { azimuth = 45, elevation = 60 }]
    orbit = { frames = 36, elevation = 20 }   # a turntable's cameras (one distance for all)
    programs = ["phong", "gouraud"]
    materials = ["default", "glossy"]
    lights = ["studio", "shadows", "sun"]
    sizes = ["160x120"]
    samples = ["1", "rgss4"]

    [[frames]]                          # and single frames
    model = "teapot"
    azimuth = 45
    program = "normals"
    size = "320x240"

Each frame has a stable, readable, file-system-safe **name** made from its
parameters (:attr:`Frame.name`: ``bunny-phong-glossy-az030-640x480``; defaults are
left out, and a short hash of the parameters is added when a value had to be
changed to be safe in a file name), and is written to ``NAME.png``.

:func:`batch` renders a job into a folder: on a ``LocalCluster`` sized to this
machine by default (one worker process per core, one thread each, one numba thread
each), on a running cluster given its scheduler's address, or in this process
(``scheduler="serial"``). The same frame makes the same bytes whichever way it is
rendered. Models are loaded once, in the client, and scattered to the workers; the
workers render and encode the PNG, the client writes it (whole or not at all,
:func:`softpipe.core.files.atomic_write`) and appends a line to ``manifest.jsonl`` (name,
parameters, output, SHA-256, seconds), flushed per frame. A second run skips the
frames whose file still has the manifest's SHA-256. A frame that raises is reported
(its name and the error's line) and the others go on; a worker that dies has its
frames run again by Dask. ``contact-sheet.png`` shows every frame at the end.
docs/batch.md is the guide.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import itertools
import json
import logging
import math
import os
import re
import sys
import time
import types
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES
from softpipe.light.material import Light
from softpipe.scenes.mesh import Mesh
from softpipe.pipeline.sampling import pattern_named
from softpipe.scenes.scenefile import (MATERIAL_KEYS, SHAPES, SceneError, _bundled_model, _describe, _is_bare_word,
                        _Bad, _Reader, _shape_params, _Table, _toml, boolean, choice, color, integer,
                        number, numbers, pattern_name, positive, program_name, string)

__all__ = ["Frame", "Job", "JobError", "LightSet", "BatchProgress", "BatchResult", "FrameRecord", "load_job",
           "parse_job", "job_from_dict", "batch", "render_frame", "read_manifest", "VIEWS", "MANIFEST",
           "CONTACT_SHEET"]

#: Named views: (azimuth, elevation) in degrees, as :class:`~softpipe.scenes.scene.FrameSpec` has them.
VIEWS: Dict[str, Tuple[float, float]] = {
    "front": (0.0, 0.0), "back": (180.0, 0.0), "left": (-90.0, 0.0), "right": (90.0, 0.0),
    "top": (0.0, 90.0), "bottom": (0.0, -90.0), "three-quarter": (30.0, 20.0),
}
#: The file, in the output folder, that lists the frames written.
MANIFEST = "manifest.jsonl"
#: The contact sheet of every frame, in the output folder.
CONTACT_SHEET = "contact-sheet.png"
#: Frames on the contact sheet at most (the first ones, in the job's order).
CONTACT_SHEET_MAX = 400
#: The most frames one job may hold.
MAX_JOB_FRAMES = 100_000
#: Test-only: ``NAME:MARKER`` makes the worker rendering frame NAME exit at once (``os._exit``) when
#: the file MARKER does not exist yet, after creating it: a worker that dies once, mid-run.
CRASH_ONCE_ENV = "SOFTPIPE_BATCH_CRASH_ONCE"

DEFAULT_AZIMUTH, DEFAULT_ELEVATION, DEFAULT_FOVY = 30.0, 20.0, 35.0
DEFAULT_SIZE = (640, 480)
DEFAULT_BACKGROUND = (0.08, 0.09, 0.12, 1.0)

TOP_KEYS = ("job", "models", "materials", "lights", "sweep", "frames")
JOB_KEYS = ("background", "fovy", "elevation")
SWEEP_KEYS = ("models", "cameras", "orbit", "programs", "materials", "lights", "sizes", "samples")
ORBIT_KEYS = ("frames", "elevation", "start")
CAMERA_KEYS = ("azimuth", "elevation")
FRAME_KEYS = ("model", "view", "azimuth", "elevation", "orbit", "program", "material", "lights", "size",
              "width", "height", "samples")
LIGHTSET_KEYS = ("light", "shadows", "ambient")


class JobError(SceneError):
    """A mistake in a job (file or dicts); ``str(e)`` starts with the file name and names the table and key."""


# ---------------------------------------------------------------------------- the job


@dataclass(frozen=True)
class LightSet:
    """The lights of a frame: ``lights`` None is the studio set (:func:`softpipe.scenes.scene.studio_lights`,
    following the camera); ``shadows`` makes every light cast shadows (a model alone is stood on a
    floor); ``ambient`` is the global ambient."""

    lights: Optional[Tuple[Light, ...]] = None
    shadows: bool = False
    ambient: Tuple[float, float, float] = (0.2, 0.2, 0.2)


#: The light sets every job knows.
BUILTIN_LIGHTS: Dict[str, LightSet] = {"studio": LightSet(), "shadows": LightSet(shadows=True)}


@dataclass(frozen=True)
class Frame:
    """One picture of a job: a model seen from a camera, shaded, lit, at a size.

    Attributes
    ----------
    model : str
        A name from the job's models (a bundled model's name, a ``[models]`` key, an OBJ's stem).
    azimuth, elevation : float
        The framed camera's angles in degrees (:class:`~softpipe.scenes.scene.FrameSpec`).
    view : str or None
        The named view (:data:`VIEWS`) the angles came from, which names the frame.
    orbit : bool
        Frame the model as seen from every azimuth (a turntable: one distance for all frames).
    program : str or None
        A registered program; None: the default (``textured`` for a textured model, else ``phong``).
    material : str
        ``"default"`` (the model's own) or a name from the job's materials.
    lights : str
        ``"studio"``, ``"shadows"`` or a name from the job's light sets.
    width, height : int
    samples : str
        A sample pattern's name (:func:`softpipe.pipeline.sampling.pattern_named`).
    """

    model: str
    azimuth: float = DEFAULT_AZIMUTH
    elevation: float = DEFAULT_ELEVATION
    view: Optional[str] = None
    orbit: bool = False
    program: Optional[str] = None
    material: str = "default"
    lights: str = "studio"
    width: int = DEFAULT_SIZE[0]
    height: int = DEFAULT_SIZE[1]
    samples: str = "1"

    def params(self) -> Dict[str, Any]:
        """The parameters as JSON values (the manifest's ``params``)."""
        return dataclasses.asdict(self)

    def digest(self) -> str:
        """SHA-256 of the canonical JSON of :meth:`params`, in hex."""
        text = json.dumps(self.params(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    @property
    def name(self) -> str:
        """``model-program-material-lights-camera-WxH-samples``, the defaults left out.

        The camera is ``az030`` (and ``el45`` when the elevation is not 20°), ``orbit030``
        for a turntable's, or the view's name. A part that had to be changed to be safe
        in a file name (only ``A-Z a-z 0-9 . _`` are kept in the names given by a job)
        adds ``-`` and 6 hex digits of :meth:`digest`, so names stay unique.
        """
        lossless = True

        def word(text: str) -> str:
            nonlocal lossless
            safe = re.sub(r"[^A-Za-z0-9._]+", "_", text).strip("._") or "x"
            lossless &= safe == text
            return safe

        parts = [word(self.model)]
        if self.program is not None:
            parts.append(word(self.program))
        if self.material != "default":
            parts.append(word(self.material))
        if self.lights != "studio":
            parts.append(word(self.lights))
        if self.view is not None:
            parts.append(word(self.view))
        else:
            parts.append(("orbit" if self.orbit else "az") + _number(self.azimuth, 3))
            if self.elevation != DEFAULT_ELEVATION:
                parts.append("el" + _number(self.elevation, 0))
        parts.append(f"{self.width}x{self.height}")
        if self.samples != "1":
            parts.append(word(self.samples))
        name = "-".join(parts)
        return name if lossless else f"{name}-{self.digest()[:6]}"


def _number(x: float, digits: int) -> str:
    """An angle as a name shows it: whole degrees zero-padded (``030``, ``-045``), else every digit."""
    if float(x) == int(x):
        return f"{int(x):0{digits + (x < 0)}d}"
    return repr(float(x))


@dataclass
class Job:
    """Frames to render and what they name: models, materials, light sets, shared settings.

    ``models`` maps a name to a bundled model's name, an OBJ path, a ``{"shape": …}`` table
    or a :class:`~softpipe.scenes.mesh.Mesh`; :meth:`load_models` makes the meshes. ``path``
    names the job in errors and ``base_dir`` resolves its file names.
    """

    frames: List[Frame] = field(default_factory=list)
    models: Dict[str, Any] = field(default_factory=dict)
    materials: Dict[str, Dict[str, Any]] = field(default_factory=dict)
    lights: Dict[str, LightSet] = field(default_factory=lambda: dict(BUILTIN_LIGHTS))
    background: Tuple[float, ...] = DEFAULT_BACKGROUND
    fovy: float = DEFAULT_FOVY
    path: str = "<job>"
    base_dir: str = ""

    def load_models(self) -> Dict[str, Mesh]:
        """The mesh of every model the frames use, each loaded once (JobError names a bad one)."""
        reader = _JobReader(self.path, self.base_dir)
        used = dict.fromkeys(f.model for f in self.frames)
        return {name: reader.model_mesh(name, self.models[name]) for name in used}


# ---------------------------------------------------------------------------- reading a job


class _JobReader(_Reader):
    """The scene-file reader's tables and values, for a job (its errors are JobErrors)."""

    def error(self, message: str, table: Optional[str] = None, key: Optional[str] = None,
              line: Optional[int] = None) -> JobError:
        return JobError(message, file=self.file, table=table, key=key, line=line)

    def job(self, doc: Mapping[str, Any]) -> Job:
        top = _Table(self, dict(doc), "the top level", TOP_KEYS)
        job = Job(path=self.file, base_dir=self.base_dir)
        settings = _Table(self, top.data.get("job", {}), "[job]", JOB_KEYS)
        bg = settings.get("background", numbers(3, 4), job.background)
        job.background = tuple(bg) + ((1.0,) if len(bg) == 3 else ())
        job.fovy = settings.get("fovy", _fovy, job.fovy)
        elevation = settings.get("elevation", number, DEFAULT_ELEVATION)
        models = top.data.get("models", {})
        if not isinstance(models, dict):
            raise self.error(f"'models' must be a table of models by name, got {_describe(models)}", key="models")
        job.models = {name: self.model_spec(name, value) for name, value in models.items()}
        self.known_models = job.models
        materials = top.data.get("materials", {})
        if not isinstance(materials, dict):
            raise self.error(f"'materials' must be a table of [materials.NAME] tables, got {_describe(materials)}",
                             key="materials")
        for name, data in materials.items():
            if name == "default":
                raise self.error("[materials.default] is the model's own material; give yours another name",
                                 table="[materials.default]")
            job.materials[name] = self.material_fields(data, f"[materials.{name}]")
        lights = top.data.get("lights", {})
        if not isinstance(lights, dict):
            raise self.error(f"'lights' must be a table of [lights.NAME] tables, got {_describe(lights)}",
                             key="lights")
        for name, data in lights.items():
            if name in BUILTIN_LIGHTS:
                raise self.error(f"[lights.{name}]: {name!r} is a built-in light set; give yours another name",
                                 table=f"[lights.{name}]")
            job.lights[name] = self.light_set(data, f"[lights.{name}]")
        sweeps = top.data.get("sweep", [])
        sweeps = [sweeps] if isinstance(sweeps, dict) else sweeps
        frames = top.data.get("frames", [])
        for key, value in (("sweep", sweeps), ("frames", frames)):
            if not isinstance(value, list):
                raise self.error(f"'{key}' must be {'a table' if key == 'sweep' else 'an array of tables'} "
                                 f"([{key}] or [[{key}]]), got {_describe(value)}", key=key)
        found: List[Frame] = []
        for k, data in enumerate(sweeps, 1):
            found.extend(self.sweep(data, "[sweep]" if len(sweeps) == 1 else f"[[sweep]] #{k}", job, elevation))
            if len(found) > MAX_JOB_FRAMES:
                raise self.error(f"the job makes more than {MAX_JOB_FRAMES:,} frames (MAX_JOB_FRAMES)")
        for k, data in enumerate(frames, 1):
            found.append(self.frame(data, f"[[frames]] #{k}", job, elevation))
        if not found:
            raise self.error("the job has no frames; add a [sweep] or [[frames]]", table="[sweep]")
        job.frames = _unique(found)
        _check_names(job.frames, self)
        return job

    # -- the parts

    def model_spec(self, name: str, value: Any) -> Any:
        """A ``[models]`` entry: a bundled name or OBJ path (a string), a table (obj/shape), or a Mesh."""
        label = f"[models] {name!r}"
        if isinstance(value, Mesh) or (hasattr(value, "vertices") and hasattr(value, "faces")):
            return value
        if isinstance(value, str):
            return self.model_source(value, _Table(self, {"obj": value}, label, ("obj",)))
        if not isinstance(value, dict):
            raise self.error(f"{label} must be a model's name, an OBJ file or a table (obj = …, or shape = …), "
                             f"got {_describe(value)}", table="[models]", key=name)
        params: Dict[str, Any] = {}
        if "shape" in value:
            try:
                params = _shape_params(choice(*SHAPES)(value["shape"]))
            except _Bad as e:
                raise self.error(f"key 'shape' in {label} {e}", table=label, key="shape") from None
        t = _Table(self, value, label, ("obj", "shape", "fit") + tuple(params))
        if ("obj" in t) == ("shape" in t):
            raise t.error(f"needs either 'obj' (an OBJ file or a bundled model) or 'shape' (one of "
                          f"{', '.join(SHAPES)}), {'not both' if 'obj' in t else 'and has neither'}")
        spec = dict(value)
        if "obj" in t:
            spec["obj"] = self.model_source(t.get("obj", string), t)
        if "fit" in t:
            t.get("fit", positive)
        for key, default in params.items():     # checked now; made in load_models
            if key in t:
                t.get(key, boolean if isinstance(default, bool) else integer if isinstance(default, int)
                      else number)
        return spec

    def model_source(self, value: str, t: _Table) -> str:
        """A bundled model's name as it is; a file name resolved against the job's folder (it must exist)."""
        if _bundled_model(value) is not None:
            return value
        hint = ""
        if _is_bare_word(value):
            from softpipe.scenes.models import MODELS
            hint = f" (nor is {value!r} a bundled model: {', '.join(MODELS)})"
        return self.path(t, "obj", hint)

    def model_mesh(self, name: str, spec: Any) -> Mesh:
        """The mesh of a model spec (a name, a path, a table, a Mesh)."""
        from softpipe.scenes.drawing import as_mesh
        label = f"[models] {name!r}"
        if not isinstance(spec, (str, dict)):
            return as_mesh(spec)
        data = {"obj": spec} if isinstance(spec, str) else spec
        if "shape" in data:
            shape = data["shape"]
            t = _Table(self, data, label, ("shape", "fit") + tuple(_shape_params(shape)))
            mesh = self.shape(t, shape, _shape_params(shape)).replace(name=name)
        else:
            t = _Table(self, data, label, ("obj", "fit"))
            mesh = self.obj(t) if _bundled_model(data["obj"]) is not None else self.obj_file(t, data["obj"])
        if "fit" in t:
            size = t.get("fit", positive)
            mesh = t.library("fit", lambda: mesh.normalized(size))
        return mesh

    def obj_file(self, t: _Table, path: str) -> Mesh:
        from softpipe.scenes.obj import OBJError, load_obj
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mesh = load_obj(path)
        except (OBJError, OSError, UnicodeError) as e:
            raise self.error(f"key 'obj' in {t.label}: {e}", table=t.label, key="obj") from None
        if mesh.triangle_count == 0:
            raise self.error(f"key 'obj' in {t.label}: {path} has no faces", table=t.label, key="obj")
        return mesh

    def material_fields(self, data: Any, label: str) -> Dict[str, Any]:
        """A material's fields, checked by making the Material they describe."""
        keys = tuple(k for k in MATERIAL_KEYS if k != "diffuse_texture")
        t = _Table(self, data, label, keys)
        material = self.material(data, label, label)
        return {k: getattr(material, k) for k in keys if k in t}

    def light_set(self, data: Any, label: str) -> LightSet:
        t = _Table(self, data, label, LIGHTSET_KEYS)
        lights = t.get("light", lambda v: v, None)
        if lights is not None:
            if not isinstance(lights, list) or not lights:
                raise t.error(f"must be one or more [[{label[1:-1]}.light]] tables, got {_describe(lights)}",
                              "light")
            lights = tuple(self.light(k + 1, d) for k, d in enumerate(lights))
        ambient = t.get("ambient", color, (0.2, 0.2, 0.2))
        ambient = (ambient,) * 3 if isinstance(ambient, float) else tuple(ambient)
        return LightSet(lights, t.get("shadows", boolean, False), ambient)

    def sweep(self, data: Any, label: str, job: Job, elevation: float) -> List[Frame]:
        t = _Table(self, data, label, SWEEP_KEYS)
        models = self.axis(t, "models", lambda v: self.model_name(v, t, "models"), None)
        if models is None:
            raise t.error("needs key 'models' (bundled models' names, OBJ files or names from [models])")
        cameras = self.axis(t, "cameras", lambda v: self.camera(v, t, elevation), None)
        orbit = self.orbit(t, elevation) if "orbit" in t else []
        if cameras is None:
            cameras = [] if orbit else [dict(azimuth=DEFAULT_AZIMUTH, elevation=elevation)]
        programs = self.axis(t, "programs", program_name, [None])
        materials = self.axis(t, "materials", lambda v: self.known(v, t, "materials", job.materials, ("default",)),
                              ["default"])
        lights = self.axis(t, "lights", lambda v: self.known(v, t, "lights", job.lights, ()), ["studio"])
        samples = self.axis(t, "samples", pattern_name, ["1"])
        sizes = self.axis(t, "sizes", _size, [DEFAULT_SIZE])
        for (w, h), s in itertools.product(sizes, samples):
            self.check_samples(t, "sizes", w, h, s)
        return [Frame(model=m, program=p, material=mat, lights=li, width=w, height=h, samples=s, **camera)
                for m, p, mat, li, (w, h), s, camera in
                itertools.product(models, programs, materials, lights, sizes, samples, cameras + orbit)]

    def frame(self, data: Any, label: str, job: Job, elevation: float) -> Frame:
        t = _Table(self, data, label, FRAME_KEYS)
        if "model" not in t:
            raise t.error("needs key 'model'")
        kw: Dict[str, Any] = {"model": self.model_name(t.data["model"], t, "model")}
        if "view" in t:
            for key in ("azimuth", "elevation", "orbit"):
                if key in t:
                    raise t.error("cannot be given with 'view' (a view sets the angles)", key)
            kw.update(self.camera(t.get("view", string), t, elevation, key="view"))
        else:
            kw["azimuth"] = t.get("azimuth", number, DEFAULT_AZIMUTH)
            kw["elevation"] = t.get("elevation", number, elevation)
            kw["orbit"] = t.get("orbit", boolean, False)
        kw["program"] = t.get("program", program_name, None)
        kw["material"] = t.get("material", lambda v: self.known(v, t, "material", job.materials, ("default",)),
                               "default")
        kw["lights"] = t.get("lights", lambda v: self.known(v, t, "lights", job.lights, ()), "studio")
        if "size" in t and ("width" in t or "height" in t):
            raise t.error("cannot be given with 'width'/'height'", "size")
        w, h = t.get("size", _size, DEFAULT_SIZE)
        kw["width"] = t.get("width", _side, w)
        kw["height"] = t.get("height", _side, h)
        kw["samples"] = t.get("samples", pattern_name, "1")
        self.check_samples(t, "size", kw["width"], kw["height"], kw["samples"])
        return Frame(**kw)

    # -- values

    def axis(self, t: _Table, key: str, convert: Callable[[Any], Any], default: Any) -> Any:
        """A sweep's list of values (one value alone counts as a list of one), each converted."""
        if key not in t:
            return default
        values = t.data[key]
        values = values if isinstance(values, list) else [values]
        if not values:
            raise t.error("must list at least one value (leave the key out for the default)", key)
        out = []
        for n, v in enumerate(values, 1):
            try:
                out.append(convert(v))
            except _Bad as e:
                raise self.error(f"entry {n} of key {key!r} in {t.label} {e}", table=t.label, key=key) from None
        return list(dict.fromkeys(out)) if all(isinstance(v, (str, tuple, type(None))) for v in out) else out

    def model_name(self, value: Any, t: _Table, key: str) -> str:
        """A frame's model: a [models] name, or a bundled model / OBJ file named directly (added to the job's models)."""
        if not isinstance(value, str):
            raise _Bad(f"must be a model's name or an OBJ file, got {_describe(value)}") \
                if key != "model" else t.error(f"must be a model's name or an OBJ file, got {_describe(value)}", key)
        if value in self.known_models:
            return value
        try:
            source = self.model_source(value, _Table(self, {"obj": value}, t.label, ("obj",)))
        except JobError as e:
            raise self.error(f"key {key!r} in {t.label}: {value!r} is not in [models], a bundled model or a file "
                             f"({e.reason.split(': ', 1)[-1]})", table=t.label, key=key) from None
        name = value if source == value else Path(source).stem
        known = self.known_models.get(name, source)
        if not (isinstance(known, str) and known == source):
            raise self.error(f"key {key!r} in {t.label}: two models would be named {name!r}; name them in "
                             "[models]", table=t.label, key=key)
        self.known_models[name] = source
        return name

    def camera(self, value: Any, t: _Table, elevation: float, key: str = "cameras") -> Dict[str, Any]:
        """A camera: an azimuth in degrees, a view's name (:data:`VIEWS`) or ``{azimuth, elevation}``."""
        if isinstance(value, str):
            if value not in VIEWS:
                raise _Bad(f"names an unknown view {value!r}; the views are {', '.join(VIEWS)}") \
                    if key == "cameras" else t.error(f"names an unknown view {value!r}; the views are "
                                                     f"{', '.join(VIEWS)}", key)
            az, el = VIEWS[value]
            return dict(azimuth=az, elevation=el, view=value)
        if isinstance(value, dict):
            c = _Table(self, value, f"a camera of key {key!r} in {t.label}", CAMERA_KEYS)
            return dict(azimuth=c.get("azimuth", number, DEFAULT_AZIMUTH), elevation=c.get("elevation", number,
                                                                                            elevation))
        return dict(azimuth=_float_angle(value), elevation=elevation)

    def orbit(self, t: _Table, elevation: float) -> List[Dict[str, Any]]:
        o = _Table(self, t.data["orbit"], f"key 'orbit' in {t.label}", ORBIT_KEYS)
        count = o.get("frames", integer, 36)
        if not 1 <= count <= 3600:
            raise o.error(f"must be 1 to 3600 frames, got {count}", "frames")
        el = o.get("elevation", number, elevation)
        start = o.get("start", number, 0.0)
        return [dict(azimuth=start + 360.0 * i / count, elevation=el, orbit=True) for i in range(count)]

    def known(self, value: Any, t: _Table, key: str, names: Mapping[str, Any], extra: Sequence[str]) -> str:
        if not isinstance(value, str):
            raise _Bad(f"must be a name, got {_describe(value)}")
        if value not in names and value not in extra:
            raise _Bad(f"names an undefined {key.rstrip('s')} {value!r}; known: {', '.join((*extra, *names))}")
        return value

    def check_samples(self, t: _Table, key: str, w: int, h: int, samples: str) -> None:
        count = len(pattern_named(samples))
        if w * h * count > MAX_TOTAL_SAMPLES:
            raise t.error(f"{w}×{h} pixels × {count} samples exceeds the limit MAX_TOTAL_SAMPLES = "
                          f"{MAX_TOTAL_SAMPLES}", key)


def _float_angle(v: Any) -> float:
    return number(v)


def _fovy(v: Any) -> float:
    x = number(v)
    if not 0.0 < x < 180.0:
        raise _Bad(f"must be in (0, 180) degrees, got {_describe(v)}")
    return x


def _side(v: Any) -> int:
    x = integer(v)
    if not 1 <= x <= MAX_DIMENSION:
        raise _Bad(f"must be 1 to {MAX_DIMENSION} pixels, got {x}")
    return x


def _size(v: Any) -> Tuple[int, int]:
    """``"640x480"`` or ``[640, 480]``."""
    if isinstance(v, str):
        m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", v)
        if not m:
            raise _Bad(f"must be WIDTHxHEIGHT such as \"640x480\", got {_describe(v)}")
        return _side(int(m.group(1))), _side(int(m.group(2)))
    if isinstance(v, (list, tuple)) and len(v) == 2:
        return _side(v[0]), _side(v[1])
    raise _Bad(f"must be WIDTHxHEIGHT such as \"640x480\" or [640, 480], got {_describe(v)}")


def _unique(frames: Iterable[Frame]) -> List[Frame]:
    """The frames in order, a frame listed twice (a sweep and a [[frames]] entry) kept once."""
    return list(dict.fromkeys(frames))


def _check_names(frames: Sequence[Frame], reader: _JobReader) -> None:
    seen: Dict[str, Frame] = {}
    for f in frames:
        other = seen.setdefault(f.name, f)
        if other is not f:  # pragma: no cover - only names given to look like a camera or size can meet
            raise reader.error(f"two different frames are both named {f.name!r}; rename a model, material or "
                               "light set")


def parse_job(text: str, name: str = "<string>", base_dir: Optional[str] = None) -> Job:
    """A job from TOML text; ``name`` labels errors and ``base_dir`` resolves file names."""
    reader = _JobReader(name, os.fspath(base_dir) if base_dir is not None else "")
    if _toml is None:  # pragma: no cover
        raise reader.error("reading job files needs Python 3.11 (tomllib) or the 'tomli' package")
    try:
        doc = _toml.loads(text)
    except ValueError as e:
        from softpipe.scenes.scenefile import _LINE
        message, found = str(e), _LINE.search(str(e))
        line = int(found.group(1)) if found else \
            text.count("\n") + (not text.endswith("\n")) if "end of document" in message else None
        message = _LINE.sub("", message).replace(" (at end of document)", " (at the end of the file)").strip()
        raise reader.error(f"TOML syntax error: {message}", line=max(line, 1) if line is not None else None) from None
    return reader.job(doc)


def job_from_dict(doc: Mapping[str, Any], name: str = "<job>", base_dir: Optional[str] = None) -> Job:
    """A job from Python dicts shaped as the TOML file (``{"sweep": {...}, "frames": [...]}``);
    ``[models]`` values may also be :class:`~softpipe.scenes.mesh.Mesh` objects."""
    if not isinstance(doc, Mapping):
        raise TypeError(f"a job is a dict, a Job or a .toml path, got {type(doc).__name__}")
    return _JobReader(name, os.fspath(base_dir) if base_dir is not None else "").job(doc)


def load_job(path: Union[str, os.PathLike]) -> Job:
    """Read a job file (TOML); file names in it are relative to its folder."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            text = f.read().decode("utf-8-sig")
    except FileNotFoundError:
        raise JobError("job file not found", file=path) from None
    except IsADirectoryError:
        raise JobError("is a directory, not a job file", file=path) from None
    except UnicodeDecodeError as e:
        raise JobError(f"not UTF-8 text (byte {e.start})", file=path) from None
    except OSError as e:
        raise JobError(f"cannot read the job file: {e.strerror or e}", file=path) from None
    return parse_job(text, path, os.path.dirname(os.path.abspath(path)))


def _as_job(job: Any) -> Job:
    if isinstance(job, Job):
        return job
    if isinstance(job, (str, os.PathLike)):
        return load_job(job)
    return job_from_dict(job)


# ---------------------------------------------------------------------------- one frame


def render_frame(frame: Frame, mesh: Mesh, job: Job) -> bytes:
    """The PNG bytes of one frame of ``job``, ``mesh`` being its model's mesh.

    The model is framed by the camera (:func:`softpipe.scenes.drawing.prepare_scene`; an orbit
    camera with :meth:`~softpipe.scenes.scene.Scene.view_camera`'s turntable fit), drawn with
    :func:`softpipe.scenes.drawing.render`: the same pixels as ``softpipe render`` with the same options.
    """
    return _render_png(frame, mesh, _frame_material(job, frame), job.lights[frame.lights], job.background,
                       job.fovy)


def _frame_material(job: Job, frame: Frame) -> Optional[Dict[str, Any]]:
    return None if frame.material == "default" else job.materials[frame.material]


def _render_png(frame: Frame, mesh: Mesh, material: Optional[Dict[str, Any]], lights: LightSet,
                background: Tuple[float, ...], fovy: float) -> bytes:
    from softpipe.scenes.drawing import prepare_scene, render
    if material is not None:
        base = mesh.material
        mesh = mesh.replace(material=base.replace(**material), materials=(), material_ids=None)
    scene = prepare_scene(mesh, width=frame.width, height=frame.height, program=frame.program,
                          samples=frame.samples, background=background, azimuth=frame.azimuth,
                          elevation=frame.elevation, fovy=fovy, shadows=lights.shadows)
    if lights.lights is not None:
        scene = scene.replace(lights=lights.lights, ambient=lights.ambient)
    elif lights.ambient != scene.ambient:
        scene = scene.replace(ambient=lights.ambient)
    camera = scene.view_camera(azimuth=frame.azimuth, orbit=True) if frame.orbit else scene.view_camera()
    buffer = io.BytesIO()
    render(scene, camera=camera).save(buffer, format="png")
    return buffer.getvalue()


def _render_task(frame: Frame, mesh: Mesh, material, lights: LightSet, background, fovy,
                 numba_threads: Optional[int]) -> Tuple[bytes, str, float, float]:
    """What a worker runs: the frame's PNG, its SHA-256, and the seconds it took (wall clock, CPU)."""
    _maybe_crash(frame)
    if numba_threads:
        import numba
        numba.set_num_threads(max(1, min(int(numba_threads), numba.config.NUMBA_NUM_THREADS)))
    start, cpu = time.perf_counter(), time.process_time()
    png = _render_png(frame, mesh, material, lights, background, fovy)
    return png, hashlib.sha256(png).hexdigest(), time.perf_counter() - start, time.process_time() - cpu


def _cluster_task(*args: Any) -> Tuple[Optional[bytes], str, float, float]:
    """:func:`_render_task` on a worker; a frame's error comes back as its line (``None, line, 0, 0``),
    so that the worker logs nothing and Dask does not take it for a lost worker."""
    from softpipe.core.runtime import keep_freed_memory
    keep_freed_memory()         # a worker process renders frames only: keep their memory (core/runtime.py)
    try:
        return _render_task(*args)
    except Exception as e:  # noqa: BLE001 - the client reports it with the frame's name
        return None, _error_line(e), 0.0, 0.0


def _maybe_crash(frame: Frame) -> None:
    """The test hook of :data:`CRASH_ONCE_ENV`: this worker process dies, once."""
    spec = os.environ.get(CRASH_ONCE_ENV)
    if not spec:
        return
    name, _, marker = spec.partition(":")
    if name == frame.name and marker:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return
        os.close(fd)
        os._exit(17)


# ---------------------------------------------------------------------------- results and progress


@dataclass
class FrameRecord:
    """A frame written: its name, file, SHA-256 of the file, and the seconds its render (and PNG
    encoding) took on its worker, on the wall clock and of CPU time (all its threads)."""

    name: str
    output: Path
    sha256: str
    seconds: float
    cpu_seconds: float = 0.0


@dataclass
class BatchProgress:
    """Where a run stands, given to ``progress`` after every frame (and once at the start).

    ``done`` frames were rendered in this run, ``skipped`` were already there, ``failed``
    raised; ``eta`` is the seconds left at this run's pace (None before the first frame);
    ``frame`` is the frame just finished and ``error`` its error line if it failed.
    """

    done: int
    skipped: int
    failed: int
    total: int
    elapsed: float
    eta: Optional[float]
    frame: Optional[str] = None
    error: Optional[str] = None

    @property
    def finished(self) -> int:
        return self.done + self.skipped + self.failed

    def line(self) -> str:
        """``12/24 frames (3 skipped, 1 failed), 4.1 frames/s, ETA 0:03``: the CLI's progress line."""
        rate = self.done / self.elapsed if self.elapsed > 0 and self.done else 0.0
        parts = [f"{self.finished}/{self.total} frames"]
        extra = [f"{n} {what}" for n, what in ((self.skipped, "skipped"), (self.failed, "failed")) if n]
        if extra:
            parts[0] += f" ({', '.join(extra)})"
        if rate:
            parts.append(f"{rate:.2f} frames/s")
        if self.eta is not None and self.finished < self.total:
            parts.append(f"ETA {int(self.eta) // 60}:{int(self.eta) % 60:02d}")
        return ", ".join(parts)


@dataclass
class BatchResult:
    """What :func:`batch` did: frames ``done`` (rendered now), ``skipped`` (names, already
    written) and ``failed`` ((name, error line) pairs), the manifest and the contact sheet."""

    out_dir: Path
    done: List[FrameRecord] = field(default_factory=list)
    skipped: List[str] = field(default_factory=list)
    failed: List[Tuple[str, str]] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    contact_sheet: Optional[Path] = None

    @property
    def manifest(self) -> Path:
        return self.out_dir / MANIFEST

    @property
    def ok(self) -> bool:
        return not self.failed


def read_manifest(out_dir: Union[str, os.PathLike]) -> Dict[str, Dict[str, Any]]:
    """The manifest's entries by frame name (a later line wins; a line cut short is ignored)."""
    entries: Dict[str, Dict[str, Any]] = {}
    try:
        with open(Path(out_dir) / MANIFEST, "rb") as f:
            for raw in f:
                try:
                    entry = json.loads(raw)
                except ValueError:
                    continue
                if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                    entries[entry["name"]] = entry
    except FileNotFoundError:
        pass
    return entries


def _sha256_file(path: Path) -> Optional[str]:
    try:
        with open(path, "rb") as f:
            return hashlib.file_digest(f, "sha256").hexdigest() if hasattr(hashlib, "file_digest") else \
                hashlib.sha256(f.read()).hexdigest()
    except OSError:
        return None


class _Manifest:
    """The manifest, appended one line per frame, each flushed to disk before the next frame."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = open(path, "ab")
        if self.file.tell():                     # a line cut short (a crash mid-write) ends here
            with open(path, "rb") as f:
                f.seek(-1, os.SEEK_END)
                if f.read(1) != b"\n":
                    self.file.write(b"\n")

    def append(self, entry: Dict[str, Any]) -> None:
        self.file.write(json.dumps(entry, sort_keys=True).encode() + b"\n")
        self.file.flush()
        os.fsync(self.file.fileno())

    def close(self) -> None:
        self.file.close()


# ---------------------------------------------------------------------------- the run


def batch(job, out_dir: Union[str, os.PathLike], scheduler=None, *, force: bool = False,
          progress: Optional[Callable[[BatchProgress], None]] = None, workers: Optional[int] = None,
          numba_threads: Optional[int] = 1, dashboard: Optional[str] = None,
          log: Optional[Callable[[str], None]] = None, contact_sheet: bool = True) -> BatchResult:
    """Render every frame of ``job`` into ``out_dir``: ``softpipe batch`` in Python.

    Parameters
    ----------
    job : Job, str, path-like or dict
        A :class:`Job`, a job file (:func:`load_job`) or dicts (:func:`job_from_dict`).
    out_dir : str or path-like
        The folder of the frames (``NAME.png``), ``manifest.jsonl`` and ``contact-sheet.png``;
        made if missing.
    scheduler : None, "serial", str or distributed.Client
        None: a ``LocalCluster`` of ``workers`` processes (default: one per core), one
        thread each, closed at the end. ``"serial"``: every frame in this process, in
        order. ``"tcp://host:8786"``: that cluster's scheduler. A ``distributed.Client``: its cluster.
    force : bool
        Render every frame, even one whose file matches the manifest.
    progress : callable, optional
        ``progress(BatchProgress)`` at the start and after every frame.
    workers : int, optional
        The LocalCluster's worker processes (``scheduler=None`` only).
    numba_threads : int or None
        numba threads per frame on a worker (1: one core per worker process); None leaves them.
    dashboard : str, optional
        The LocalCluster's dashboard address (``":8787"``); its link goes to ``log``. Needs bokeh.
    log : callable, optional
        ``log(message)`` for notes: the cluster started, its dashboard.
    contact_sheet : bool
        Write ``contact-sheet.png`` at the end.

    Returns
    -------
    BatchResult
        Failed frames do not raise: they are in ``failed`` with their error line.
        Ctrl-C (KeyboardInterrupt) is raised after the frames already received were
        written and listed; no file is left half-written.
    """
    job = _as_job(job)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from softpipe.core.files import check_writable
    check_writable(out / MANIFEST)
    start = time.perf_counter()
    result = BatchResult(out_dir=out)
    entries = {} if force else read_manifest(out)
    todo = []
    for frame in job.frames:
        entry = entries.get(frame.name)
        if entry is not None and entry.get("params") == frame.params() and \
                _sha256_file(out / str(entry.get("output", ""))) == entry.get("sha256"):
            result.skipped.append(frame.name)
        else:
            todo.append(frame)
    state = _Run(job, out, result, start, progress)
    state.report()
    if todo:
        meshes = Job(frames=todo, models=job.models, path=job.path, base_dir=job.base_dir).load_models()
        manifest = _Manifest(out / MANIFEST)
        try:
            if scheduler == "serial":
                _run_serial(todo, meshes, job, state, manifest)
            else:
                _run_dask(todo, meshes, job, state, manifest, scheduler, workers, numba_threads, dashboard, log)
        finally:
            manifest.close()
    result.seconds = time.perf_counter() - start
    if contact_sheet:
        result.contact_sheet = _write_contact_sheet(job, out, result)
    return result


class _Run:
    """A run's bookkeeping: the result so far, the progress calls."""

    def __init__(self, job: Job, out: Path, result: BatchResult, start: float,
                 progress: Optional[Callable[[BatchProgress], None]]) -> None:
        self.job, self.out, self.result, self.start, self.progress = job, out, result, start, progress
        self.total = len(job.frames)

    def report(self, frame: Optional[str] = None, error: Optional[str] = None) -> None:
        if self.progress is None:
            return
        r = self.result
        elapsed = time.perf_counter() - self.start
        ran = len(r.done) + len(r.failed)
        left = self.total - ran - len(r.skipped)
        eta = elapsed / ran * left if ran else None
        self.progress(BatchProgress(len(r.done), len(r.skipped), len(r.failed), self.total, elapsed, eta,
                                    frame, error))

    def wrote(self, frame: Frame, png: bytes, sha: str, seconds: float, cpu: float, manifest: _Manifest) -> None:
        """Write a frame's file (whole or not at all), then its manifest line."""
        from softpipe.core.files import atomic_write
        path = self.out / f"{frame.name}.png"
        atomic_write(path, lambda f: f.write(png))
        manifest.append({"name": frame.name, "params": frame.params(), "output": path.name, "sha256": sha,
                         "seconds": round(seconds, 4)})
        self.result.done.append(FrameRecord(frame.name, path, sha, seconds, cpu))
        self.report(frame.name)

    def failed(self, frame: Frame, error: str) -> None:
        self.result.failed.append((frame.name, error))
        self.report(frame.name, self.result.failed[-1][1])


def _error_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _run_serial(todo: List[Frame], meshes: Dict[str, Mesh], job: Job, state: _Run, manifest: _Manifest) -> None:
    for frame in todo:
        try:
            png, sha, seconds, cpu = _render_task(frame, meshes[frame.model], _frame_material(job, frame),
                                             job.lights[frame.lights], job.background, job.fovy, None)
        except Exception as e:  # noqa: BLE001 - a frame's error is reported, the others go on
            state.failed(frame, _error_line(e))
            continue
        state.wrote(frame, png, sha, seconds, cpu, manifest)


def _run_dask(todo, meshes, job, state, manifest, scheduler, workers, numba_threads, dashboard, log) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise RuntimeError("rendering on a cluster needs Dask: pip install 'softpipe[cluster]' "
                           "(or scheduler='serial')") from None
    import contextlib
    import uuid
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            n = workers or os.cpu_count() or 1
            cluster = stack.enter_context(LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True,
                dashboard_address=":0" if dashboard is None else dashboard,   # None would still take :8787
                silence_logs=logging.ERROR))   # a frame's error is reported once, by the client
            client = stack.enter_context(Client(cluster))
            if log is not None:
                link = f", dashboard {cluster.dashboard_link}" if dashboard is not None else ""
                log(f"started a LocalCluster of {n} worker processes{link}")
        elif isinstance(scheduler, str):
            if workers is not None:
                raise ValueError("workers= sizes the LocalCluster; a scheduler's cluster has its own workers")
            client = stack.enter_context(Client(scheduler))
            if log is not None:
                log(f"connected to {scheduler} ({len(client.scheduler_info()['workers'])} workers)")
        else:
            client = scheduler
        state.result.workers = max(len(client.scheduler_info().get("workers", {})), 1)
        scattered = {name: client.scatter(mesh, broadcast=True, hash=False) for name, mesh in meshes.items()}
        run = uuid.uuid4().hex[:8]
        futures = {}
        for frame in todo:
            future = client.submit(_cluster_task, frame, scattered[frame.model], _frame_material(job, frame),
                                   job.lights[frame.lights], job.background, job.fovy, numba_threads,
                                   key=f"softpipe-frame-{frame.name}-{run}", pure=False)
            futures[future.key] = (future, frame)
        try:
            for future in as_completed([f for f, _ in futures.values()]):
                frame = futures[future.key][1]
                try:
                    png, sha, seconds, cpu = future.result()
                except Exception as e:  # noqa: BLE001 - a lost frame (KilledWorker, ...) is reported too
                    state.failed(frame, _error_line(e))
                else:
                    if png is None:
                        state.failed(frame, sha)
                    else:
                        state.wrote(frame, png, sha, seconds, cpu, manifest)
                future.release()
        finally:
            for future, _ in futures.values():
                future.cancel()
            for f in scattered.values():
                f.release()


# ---------------------------------------------------------------------------- the contact sheet


def _write_contact_sheet(job: Job, out: Path, result: BatchResult) -> Optional[Path]:
    """Every written frame, in the job's order, as labelled thumbnails (:func:`softpipe.views.pictures.contact_sheet`)."""
    import numpy as np
    from PIL import Image

    from softpipe.core.files import atomic_write
    from softpipe.views.pictures import contact_sheet
    failed = {name for name, _ in result.failed}
    names = [f.name for f in job.frames if f.name not in failed and (out / f"{f.name}.png").is_file()]
    names = names[:CONTACT_SHEET_MAX]
    if not names:
        return None
    width = int(min(max(6 * max(len(n) for n in names) + 8, 160), 320))
    height = width * 3 // 4
    pictures = {}
    for name in names:
        with Image.open(out / f"{name}.png") as im:
            im = im.convert("RGB")
            im.thumbnail((width, height), Image.Resampling.LANCZOS)
            tile = Image.new("RGB", (width, height), (24, 24, 28))
            tile.paste(im, ((width - im.width) // 2, (height - im.height) // 2))
        pictures[name] = np.asarray(tile)
    columns = max(1, min(len(names), round(math.sqrt(len(names) * 4 / 3)), 8))
    sheet = contact_sheet(pictures, columns=columns)
    path = out / CONTACT_SHEET
    atomic_write(path, lambda f: sheet.save(f, format="PNG"))
    return path


# ---------------------------------------------------------------------------- softpipe.batch(...)


class _CallableModule(types.ModuleType):
    """``import softpipe.tools.batch; softpipe.batch(job, out_dir)`` calls :func:`batch`."""

    def __call__(self, *args: Any, **kwargs: Any) -> BatchResult:
        return batch(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule


# ---------------------------------------------------------------------------- python -m softpipe.tools.batch: scaling


def _warm(job_text: str) -> None:
    """On a worker: render the job's first frame small, so its kernels are loaded before the timing."""
    job = parse_job(job_text)
    frame = dataclasses.replace(job.frames[0], width=64, height=48)
    render_frame(frame, job.load_models()[frame.model], job)


def bench(model: str = "bunny", frames: int = 36, size: str = "640x480", workers: Sequence[int] = (1, 2),
          repeats: int = 5, out: Optional[Callable[[str], None]] = print) -> Dict[int, float]:
    """Frames per second of a ``frames``-frame turntable of ``model`` on LocalClusters of ``workers``.

    Every cluster is started and warmed first (each worker renders one small frame: its
    kernels loaded from the on-disk cache), then the clusters take turns rendering the
    whole turntable (``force``, no contact sheet), ``repeats`` times each, so that a
    change in the machine's load falls on all of them alike; the median time counts.
    Also reported: a frame's median render time on a worker (wall clock, CPU), and the client's CPU time
    (writing the files and the manifest, and the LocalCluster's scheduler, which runs
    in the client process) per frame. Returns workers → frames/s.
    """
    import contextlib
    import statistics
    import tempfile

    from distributed import Client, LocalCluster
    text = f'[sweep]\nmodels = ["{model}"]\norbit = {{ frames = {frames} }}\nsizes = ["{size}"]\n'
    job = parse_job(text, "<bench>")
    times: Dict[int, List[float]] = {n: [] for n in workers}
    per_frame: Dict[int, List[float]] = {n: [] for n in workers}
    cpu_frame: Dict[int, List[float]] = {n: [] for n in workers}
    client_cpu: Dict[int, List[float]] = {n: [] for n in workers}
    with contextlib.ExitStack() as stack:
        clients = {}
        for n in workers:
            cluster = stack.enter_context(LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                       dashboard_address=":0", silence_logs=logging.ERROR))
            clients[n] = stack.enter_context(Client(cluster))
            clients[n].run(_warm, text)
        tmp = stack.enter_context(tempfile.TemporaryDirectory())
        for _ in range(repeats):
            for n in workers:
                cpu = time.process_time()
                result = batch(job, tmp, clients[n], force=True, contact_sheet=False)
                client_cpu[n].append((time.process_time() - cpu) / frames)
                assert not result.failed, result.failed
                times[n].append(result.seconds)
                per_frame[n].extend(r.seconds for r in result.done)
                cpu_frame[n].extend(r.cpu_seconds for r in result.done)
    rates = {n: frames / statistics.median(times[n]) for n in workers}
    if out is not None:
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        out(f"{frames}-frame {model} turntable at {size}, {os.cpu_count()} cores, load average {load:.2f}:")
        for n in workers:
            out(f"  {n} worker{'s' if n > 1 else ' '}: {rates[n]:5.2f} frames/s (median of "
                f"{', '.join(f'{t:.2f}' for t in times[n])} s); a frame renders in "
                f"{statistics.median(per_frame[n]) * 1000:.0f} ms on a worker "
                f"({statistics.median(cpu_frame[n]) * 1000:.0f} ms of CPU); client CPU "
                f"{statistics.median(client_cpu[n]) * 1000:.0f} ms per frame")
        if 1 in rates:
            for n in workers:
                if n > 1:
                    out(f"  efficiency at {n} workers: {rates[n] / (n * rates[1]):.2f} "
                        f"(speed-up {rates[n] / rates[1]:.2f}×)")
    return rates


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(prog="python -m softpipe.tools.batch",
                                     description="Measure softpipe batch's frames/s on LocalClusters of 1, 2, … "
                                                 "workers: a turntable of a bundled model.")
    parser.add_argument("--model", default="bunny")
    parser.add_argument("--frames", type=int, default=36)
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    parser.add_argument("--repeats", type=int, default=5)
    options = parser.parse_args()
    from softpipe.tools.batch import bench as _bench     # the module's own copy: what the workers unpickle
    _bench(options.model, options.frames, options.size, [int(w) for w in options.workers.split(",")],
           options.repeats)
