"""The job format: a job file read and checked, its sweeps expanded into frames.

A **job** lists frames as a product of models × cameras × programs × materials ×
lights × sizes × sample patterns (``[sweep]``), and/or one by one (``[[frames]]``).
:func:`load_job` reads it from a TOML file, :func:`parse_job` from text and
:func:`job_from_dict` from Python dicts of the same shape; every mistake is a
:class:`JobError` (a :class:`~softpipe.scenes.scenefile.SceneError`) naming the file, the
table and the key. Each :class:`Frame` has a stable, file-system-safe name made from
its parameters (:attr:`Frame.name`: ``bunny-phong-glossy-az030-640x480``).

Why it is shaped so: the tables are read as a scene file's are, by the scene file's
reader (:class:`~softpipe.scenes.scenefile.SceneReader`: models, materials, lights) on
the shared checks of :mod:`softpipe.core.validation`, so the two formats cannot drift
apart. Nothing here renders; :mod:`softpipe.tools.batch.run` does.

docs/batch.md is the guide (every table and key, frame names, running, resuming);
``examples/sweep.toml`` explains every key in comments.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

from softpipe.core.validation import (
    BadValue,
    Table,
    boolean,
    choice,
    color,
    describe,
    integer,
    number,
    numbers,
    positive,
    string,
)
from softpipe.light.material import Light
from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES
from softpipe.pipeline.sampling import pattern_named
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.scenefile import (
    MATERIAL_KEYS,
    SHAPES,
    SceneError,
    SceneReader,
    SceneWarning,
    bundled_model,
    is_bare_word,
    pattern_name,
    program_name,
    shape_params,
)
from softpipe.tracers.pathtrace import MAX_SPP

__all__ = ["Frame", "Job", "JobError", "LightSet", "load_job", "parse_job", "job_from_dict", "as_job", "VIEWS",
           "BUILTIN_LIGHTS", "MAX_JOB_FRAMES", "MAX_NAME_LENGTH"]

#: Named views: (azimuth, elevation) in degrees, as :class:`~softpipe.scenes.scene.FrameSpec` has them.
VIEWS: Dict[str, Tuple[float, float]] = {
    "front": (0.0, 0.0), "back": (180.0, 0.0), "left": (-90.0, 0.0), "right": (90.0, 0.0),
    "top": (0.0, 90.0), "bottom": (0.0, -90.0), "three-quarter": (30.0, 20.0),
}
#: The most frames one job may hold (counted before a sweep's product is made).
MAX_JOB_FRAMES = 100_000
#: The longest frame name: ``NAME.png`` and the temporary file it is written through
#: (``.NAME.png.XXXXXXXX.tmp``) stay well inside a file name's 255 bytes.
MAX_NAME_LENGTH = 160

DEFAULT_AZIMUTH, DEFAULT_ELEVATION, DEFAULT_FOVY = 30.0, 20.0, 35.0
DEFAULT_SIZE = (640, 480)
DEFAULT_BACKGROUND = (0.08, 0.09, 0.12, 1.0)

TOP_KEYS = ("job", "models", "materials", "lights", "sweep", "frames")
JOB_KEYS = ("background", "fovy", "elevation", "outputs")
SWEEP_KEYS = ("models", "cameras", "orbit", "programs", "materials", "lights", "sizes", "samples", "pathtrace", "spp",
              "seed", "background_light")
ORBIT_KEYS = ("frames", "elevation", "start")
CAMERA_KEYS = ("azimuth", "elevation")
FRAME_KEYS = ("model", "view", "azimuth", "elevation", "orbit", "program", "material", "lights", "size",
              "width", "height", "samples", "pathtrace", "spp", "seed", "background_light")
#: Samples per pixel of a path-traced frame when the job does not say (``spp``).
DEFAULT_SPP = 64
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
    pathtrace : bool
        Render with the path tracer (:func:`softpipe.pathtrace`, docs/pathtracing.md) instead
        of the rasterizer: ``spp`` samples per pixel, random numbers from ``seed``.
    spp, seed : int
        The path tracer's samples per pixel and seed (used only with ``pathtrace``).
    background_light : bool
        With ``pathtrace``: the background is also a light the light sample goes to
        (``pathtrace(..., background_light=True)``, docs/pathtracing.md).
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
    pathtrace: bool = False
    spp: int = DEFAULT_SPP
    seed: int = 0
    background_light: bool = False

    def params(self) -> Dict[str, Any]:
        """The parameters as JSON values (the manifest's ``params``); a rasterized frame's leave out the
        path tracer's, and a path-traced frame's ``background_light`` when it is off (so their digests, names
        and manifest lines are what they were before they had them)."""
        params = dataclasses.asdict(self)
        if not self.pathtrace:
            for key in ("pathtrace", "spp", "seed"):
                del params[key]
        if not self.background_light:
            del params["background_light"]
        return params

    def digest(self) -> str:
        """SHA-256 of the canonical JSON of :meth:`params`, in hex."""
        text = json.dumps(self.params(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    @property
    def name(self) -> str:
        """``model-program-material-lights-camera-WxH-samples``, the defaults left out.

        The camera is ``az030`` (and ``el45`` when the elevation is not 20°), ``orbit030``
        for a turntable's, or the view's name. A part that had to be changed to be safe
        in a file name (only ``A-Z a-z 0-9 . _`` are kept in the names given by a job, and
        at most 48 of them) adds ``-`` and 6 hex digits of :meth:`digest`, so names stay
        unique; a name is at most :data:`MAX_NAME_LENGTH` characters (a longer one is cut
        and gets the digest).
        """
        lossless = True

        def word(text: str) -> str:
            nonlocal lossless
            safe = re.sub(r"[^A-Za-z0-9._]+", "_", text).strip("._")[:48].rstrip("._") or "x"  # a long one is cut
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
        if self.pathtrace:
            parts.append(f"pt{self.spp}" + (f"-seed{self.seed}" if self.seed else "")
                         + ("-bglight" if self.background_light else ""))
        name = "-".join(parts)
        if lossless and len(name) <= MAX_NAME_LENGTH:
            return name
        # cut to the limit (a long model name, a huge angle); the digest keeps cut names apart
        return f"{name[:MAX_NAME_LENGTH - 7].rstrip('-')}-{self.digest()[:6]}"


def _number(x: float, digits: int) -> str:
    """An angle as a name shows it: whole degrees zero-padded (``030``, ``-045``), else every digit."""
    if float(x) == int(x) and abs(x) < 1e15:     # beyond, int() would spell out hundreds of digits
        return f"{int(x):0{digits + (x < 0)}d}"
    return repr(float(x))


@dataclass
class Job:
    """Frames to render and what they name: models, materials, light sets, shared settings.

    ``models`` maps a name to a bundled model's name, a model file's path (OBJ, PLY, STL, glTF), a ``{"shape": …}`` table
    or a :class:`~softpipe.scenes.mesh.Mesh`; :meth:`load_models` makes the meshes. ``path``
    names the job in errors and ``base_dir`` resolves its file names.
    """

    frames: List[Frame] = field(default_factory=list)
    models: Dict[str, Any] = field(default_factory=dict)
    materials: Dict[str, Dict[str, Any]] = field(default_factory=dict)
    lights: Dict[str, LightSet] = field(default_factory=lambda: dict(BUILTIN_LIGHTS))
    background: Tuple[float, ...] = DEFAULT_BACKGROUND
    fovy: float = DEFAULT_FOVY
    #: buffers written beside every frame's picture (``[job] outputs``, :data:`softpipe.scenes.outputs.OUTPUTS`)
    outputs: Tuple[str, ...] = ()
    path: str = "<job>"
    base_dir: str = ""

    def load_models(self) -> Dict[str, Mesh]:
        """The mesh of every model the frames use, each loaded once (JobError names a bad one).

        What loading an OBJ warns about (an ``mtllib`` refused or missing, corners without
        normals) is issued once per model as a :class:`~softpipe.scenes.scenefile.SceneWarning`
        naming the job and the entry: ``jobs.toml: [models] 'cup': cup.obj:3: material library …``.
        """
        reader = _JobReader(self.path, self.base_dir)
        meshes = {}
        for name in dict.fromkeys(f.model for f in self.frames):
            reader.warnings = []
            meshes[name] = reader.model_mesh(name, self.models[name])
            for message in dict.fromkeys(reader.warnings):
                warnings.warn(f"{self.path}: [models] {name!r}: {message}", SceneWarning, stacklevel=2)
        return meshes


# ---------------------------------------------------------------------------- reading a job


class _JobReader(SceneReader):
    """The scene-file reader's tables and values, for a job (its errors are JobErrors)."""

    kind = "job file"
    error_class = JobError

    def job(self, doc: Mapping[str, Any]) -> Job:
        top = Table(self, dict(doc), "the top level", TOP_KEYS)
        job = Job(path=self.file, base_dir=self.base_dir)
        settings = Table(self, top.data.get("job", {}), "[job]", JOB_KEYS)
        bg = settings.get("background", numbers(3, 4), job.background)
        job.background = tuple(bg) + ((1.0,) if len(bg) == 3 else ())
        job.fovy = settings.get("fovy", _fovy, job.fovy)
        elevation = settings.get("elevation", number, DEFAULT_ELEVATION)
        job.outputs = settings.get("outputs", _outputs, ())
        models = top.data.get("models", {})
        if not isinstance(models, dict):
            raise self.error(f"'models' must be a table of models by name, got {describe(models)}", key="models")
        job.models = {name: self.model_spec(name, value) for name, value in models.items()}
        self.known_models = job.models
        materials = top.data.get("materials", {})
        if not isinstance(materials, dict):
            raise self.error(f"'materials' must be a table of [materials.NAME] tables, got {describe(materials)}",
                             key="materials")
        for name, data in materials.items():
            if name == "default":
                raise self.error("[materials.default] is the model's own material; give yours another name",
                                 table="[materials.default]")
            job.materials[name] = self.material_fields(data, f"[materials.{name}]")
        lights = top.data.get("lights", {})
        if not isinstance(lights, dict):
            raise self.error(f"'lights' must be a table of [lights.NAME] tables, got {describe(lights)}",
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
                                 f"([{key}] or [[{key}]]), got {describe(value)}", key=key)
        found: List[Frame] = []
        for k, data in enumerate(sweeps, 1):
            found.extend(self.sweep(data, "[sweep]" if len(sweeps) == 1 else f"[[sweep]] #{k}", job, elevation,
                                    len(found)))
        if len(found) + len(frames) > MAX_JOB_FRAMES:      # counted before any entry is read
            raise self.error(f"the job makes {len(found) + len(frames):,} frames ({len(found):,} from sweeps, "
                             f"{len(frames):,} [[frames]] entries), more than the limit MAX_JOB_FRAMES = "
                             f"{MAX_JOB_FRAMES:,}", table="[[frames]]")
        for k, data in enumerate(frames, 1):
            found.append(self.frame(data, f"[[frames]] #{k}", job, elevation))
        if not found:
            raise self.error("the job has no frames; add a [sweep] or [[frames]]", table="[sweep]")
        job.frames = _unique(found)
        _check_names(job.frames, self)
        traced = next((f for f in job.frames if f.pathtrace), None)
        if job.outputs and traced is not None:
            raise self.error(f"outputs are read from the rasterizer's visibility record; frame {traced.name!r} is "
                             "path traced (leave out 'outputs' or 'pathtrace')", table="[job]", key="outputs")
        return job

    # -- the parts

    def model_spec(self, name: str, value: Any) -> Any:
        """A ``[models]`` entry: a bundled name or OBJ path (a string), a table (obj/shape), or a Mesh."""
        label = f"[models] {name!r}"
        if isinstance(value, Mesh) or (hasattr(value, "vertices") and hasattr(value, "faces")):
            return value
        if isinstance(value, str):
            return self.model_source(value, Table(self, {"obj": value}, label, ("obj",)))
        if not isinstance(value, dict):
            raise self.error(f"{label} must be a model's name, an OBJ file or a table (obj = …, or shape = …), "
                             f"got {describe(value)}", table="[models]", key=name)
        params: Dict[str, Any] = {}
        if "shape" in value:
            try:
                params = shape_params(choice(*SHAPES)(value["shape"]))
            except BadValue as e:
                raise self.error(f"key 'shape' in {label} {e}", table=label, key="shape") from None
        t = Table(self, value, label, ("obj", "shape", "fit") + tuple(params))
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

    def model_source(self, value: str, t: Table) -> str:
        """A bundled model's name as it is; a file name resolved against the job's folder (it must exist)."""
        if bundled_model(value) is not None:
            return value
        hint = ""
        if is_bare_word(value):
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
            t = Table(self, data, label, ("shape", "fit") + tuple(shape_params(shape)))
            mesh = self.shape(t, shape, shape_params(shape)).replace(name=name)
        else:
            t = Table(self, data, label, ("obj", "fit"))
            mesh = self.obj(t) if bundled_model(data["obj"]) is not None else self.obj_file(t, data["obj"])
        if "fit" in t:
            size = t.get("fit", positive)
            mesh = t.library("fit", lambda: mesh.normalized(size))
        return mesh

    def obj_file(self, t: Table, path: str) -> Mesh:
        """A model file's mesh: OBJ, or PLY, STL, glTF through trimesh (load_model decides by the suffix)."""
        from softpipe.scenes.formats import FormatError
        from softpipe.scenes.models import load_model
        from softpipe.scenes.obj import OBJError
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                mesh = load_model(path)
        except (OBJError, FormatError, OSError, UnicodeError) as e:
            raise self.error(f"key 'obj' in {t.label}: {e}", table=t.label, key="obj") from None
        self.warnings.extend(str(w.message) for w in caught)      # Job.load_models issues them
        if mesh.triangle_count == 0:
            raise self.error(f"key 'obj' in {t.label}: {path} has no faces", table=t.label, key="obj")
        return mesh

    def material_fields(self, data: Any, label: str) -> Dict[str, Any]:
        """A material's fields, checked by making the Material they describe."""
        keys = tuple(k for k in MATERIAL_KEYS if k != "diffuse_texture")
        t = Table(self, data, label, keys)
        material = self.material(data, label, label)
        return {k: getattr(material, k) for k in keys if k in t}

    def light_set(self, data: Any, label: str) -> LightSet:
        t = Table(self, data, label, LIGHTSET_KEYS)
        lights = t.get("light", lambda v: v, None)
        if lights is not None:
            if not isinstance(lights, list) or not lights:
                raise t.error(f"must be one or more [[{label[1:-1]}.light]] tables, got {describe(lights)}",
                              "light")
            lights = tuple(self.light(k + 1, d) for k, d in enumerate(lights))
        ambient = t.get("ambient", color, (0.2, 0.2, 0.2))
        return LightSet(lights, t.get("shadows", boolean, False), ambient)

    def sweep(self, data: Any, label: str, job: Job, elevation: float, before: int = 0) -> List[Frame]:
        """A sweep's frames, the product of its lists; ``before`` frames came from earlier sweeps."""
        t = Table(self, data, label, SWEEP_KEYS)
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
        traced = self.path_tracing(t, "samples")
        spps = self.axis(t, "spp", _spp, [DEFAULT_SPP])
        axes = {"models": models, "programs": programs, "materials": materials, "lights": lights, "sizes": sizes,
                "samples": samples, "spp": spps, "cameras": cameras + orbit}
        count = math.prod(len(v) for v in axes.values())   # counted before the product is made
        if before + count > MAX_JOB_FRAMES:
            shown = " × ".join(f"{len(v):,} {k}" for k, v in axes.items() if len(v) > 1) or "1"
            earlier = f", after {before:,} from earlier sweeps" if before else ""
            raise t.error(f"makes {count:,} frames ({shown}){earlier}, more than the limit MAX_JOB_FRAMES = "
                          f"{MAX_JOB_FRAMES:,}")
        for (w, h), s, n in itertools.product(sizes, samples, spps):
            self.check_samples(t, "sizes", w, h, s, n if traced else 0)
        return [Frame(model=m, program=p, material=mat, lights=li, width=w, height=h, samples=s, **camera, **traced,
                      **({"spp": n} if traced else {}))
                for m, p, mat, li, (w, h), s, n, camera in
                itertools.product(models, programs, materials, lights, sizes, samples, spps, cameras + orbit)]

    def frame(self, data: Any, label: str, job: Job, elevation: float) -> Frame:
        t = Table(self, data, label, FRAME_KEYS)
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
        kw.update(self.path_tracing(t, "samples"))
        if kw.get("pathtrace"):
            kw["spp"] = t.get("spp", _spp, DEFAULT_SPP)
        self.check_samples(t, "size", kw["width"], kw["height"], kw["samples"], kw.get("spp", 0))
        return Frame(**kw)

    # -- values

    def axis(self, t: Table, key: str, convert: Callable[[Any], Any], default: Any) -> Any:
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
            except BadValue as e:
                raise self.error(f"entry {n} of key {key!r} in {t.label} {e}", table=t.label, key=key) from None
        return list(dict.fromkeys(out)) if all(isinstance(v, (str, tuple, type(None))) for v in out) else out

    def model_name(self, value: Any, t: Table, key: str) -> str:
        """A frame's model: a [models] name, or a bundled model / OBJ file named directly (added to the job's models)."""
        if not isinstance(value, str):
            raise BadValue(f"must be a model's name or an OBJ file, got {describe(value)}") \
                if key != "model" else t.error(f"must be a model's name or an OBJ file, got {describe(value)}", key)
        if value in self.known_models:
            return value
        try:
            source = self.model_source(value, Table(self, {"obj": value}, t.label, ("obj",)))
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

    def camera(self, value: Any, t: Table, elevation: float, key: str = "cameras") -> Dict[str, Any]:  # type: ignore[override]  # a job's, not a scene's [camera] (scene() is not used here)
        """A camera: an azimuth in degrees, a view's name (:data:`VIEWS`) or ``{azimuth, elevation}``."""
        if isinstance(value, str):
            if value not in VIEWS:
                raise BadValue(f"names an unknown view {value!r}; the views are {', '.join(VIEWS)}") \
                    if key == "cameras" else t.error(f"names an unknown view {value!r}; the views are "
                                                     f"{', '.join(VIEWS)}", key)
            az, el = VIEWS[value]
            return dict(azimuth=az, elevation=el, view=value)
        if isinstance(value, dict):
            c = Table(self, value, f"a camera of key {key!r} in {t.label}", CAMERA_KEYS)
            return dict(azimuth=c.get("azimuth", number, DEFAULT_AZIMUTH), elevation=c.get("elevation", number,
                                                                                            elevation))
        return dict(azimuth=_float_angle(value), elevation=elevation)

    def orbit(self, t: Table, elevation: float) -> List[Dict[str, Any]]:
        o = Table(self, t.data["orbit"], f"key 'orbit' in {t.label}", ORBIT_KEYS)
        count = o.get("frames", integer, 36)
        if not 1 <= count <= 3600:
            raise o.error(f"must be 1 to 3600 frames, got {count}", "frames")
        el = o.get("elevation", number, elevation)
        start = o.get("start", number, 0.0)
        return [dict(azimuth=start + 360.0 * i / count, elevation=el, orbit=True) for i in range(count)]

    def known(self, value: Any, t: Table, key: str, names: Mapping[str, Any], extra: Sequence[str]) -> str:
        if not isinstance(value, str):
            raise BadValue(f"must be a name, got {describe(value)}")
        if value not in names and value not in extra:
            raise BadValue(f"names an undefined {key.rstrip('s')} {value!r}; known: {', '.join((*extra, *names))}")
        return value

    def path_tracing(self, t: Table, samples_key: str) -> Dict[str, Any]:
        """A sweep's or frame's ``pathtrace``, ``seed`` and ``background_light`` (``{}`` for a rasterized
        frame); ``spp``, ``seed`` or ``background_light`` without ``pathtrace = true``, or ``samples`` with it,
        are refused rather than ignored."""
        if not t.get("pathtrace", boolean, False):
            for key in ("spp", "seed"):
                if key in t:
                    raise t.error("applies only with pathtrace = true (the path tracer's samples per pixel "
                                  "and seed)", key)
            if "background_light" in t:
                raise t.error("applies only with pathtrace = true (the path tracer's light sample toward the "
                              "background)", "background_light")
            return {}
        if samples_key in t:
            raise t.error("picks the rasterizer's sample pattern; it does not apply with pathtrace = true, whose "
                          "samples are jittered over each pixel (a box filter): use spp = N", samples_key)
        return {"pathtrace": True, "seed": t.get("seed", _seed, 0),
                "background_light": t.get("background_light", boolean, False)}

    def check_samples(self, t: Table, key: str, w: int, h: int, samples: str, spp: int = 0) -> None:
        count = spp or len(pattern_named(samples))
        if w * h * count > MAX_TOTAL_SAMPLES:
            raise t.error(f"{w}×{h} pixels × {count} samples exceeds the limit MAX_TOTAL_SAMPLES = "
                          f"{MAX_TOTAL_SAMPLES}", key)


def _outputs(v: Any) -> Tuple[str, ...]:
    from softpipe.scenes.outputs import OUTPUTS, check_outputs
    if not isinstance(v, list) or not v or not all(isinstance(n, str) for n in v):
        raise BadValue(f"must be a list of output names (any of {', '.join(OUTPUTS)}), got {describe(v)}")
    unknown = [n for n in v if n not in OUTPUTS]
    if unknown:
        raise BadValue(f"must name outputs among {', '.join(OUTPUTS)}; {unknown[0]!r} is not one")
    try:
        return check_outputs(v)
    except ValueError as e:
        message = str(e)
        raise BadValue(message[len("outputs: "):] if message.startswith("outputs: ") else message) from None


def _spp(v: Any) -> int:
    x = integer(v)
    if not 1 <= x <= MAX_SPP:
        raise BadValue(f"must be a whole number of samples per pixel, 1…{MAX_SPP}, got {describe(v)}")
    return x


def _seed(v: Any) -> int:
    x = integer(v)
    if not 0 <= x < 2 ** 64:
        raise BadValue(f"must be a whole number 0…2⁶⁴ − 1, got {describe(v)}")
    return x


def _float_angle(v: Any) -> float:
    return number(v)


def _fovy(v: Any) -> float:
    x = number(v)
    if not 0.0 < x < 180.0:
        raise BadValue(f"must be in (0, 180) degrees, got {describe(v)}")
    return x


def _side(v: Any) -> int:
    x = integer(v)
    if not 1 <= x <= MAX_DIMENSION:
        raise BadValue(f"must be 1 to {MAX_DIMENSION} pixels, got {x}")
    return x


def _size(v: Any) -> Tuple[int, int]:
    """``"640x480"`` or ``[640, 480]``."""
    if isinstance(v, str):
        m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", v)
        if not m:
            raise BadValue(f"must be WIDTHxHEIGHT such as \"640x480\", got {describe(v)}")
        return _side(int(m.group(1))), _side(int(m.group(2)))
    if isinstance(v, (list, tuple)) and len(v) == 2:
        return _side(v[0]), _side(v[1])
    raise BadValue(f"must be WIDTHxHEIGHT such as \"640x480\" or [640, 480], got {describe(v)}")


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
    return _read(reader, reader.parse_toml(text))


def _read(reader: _JobReader, doc: Mapping[str, Any]) -> Job:
    try:
        return reader.job(doc)
    except RecursionError:  # pragma: no cover - nothing here recurses on the input, as in parse_scene
        raise reader.error("the job is nested too deeply") from None


def job_from_dict(doc: Mapping[str, Any], name: str = "<job>", base_dir: Optional[str] = None) -> Job:
    """A job from Python dicts shaped as the TOML file (``{"sweep": {...}, "frames": [...]}``);
    ``[models]`` values may also be :class:`~softpipe.scenes.mesh.Mesh` objects."""
    if not isinstance(doc, Mapping):
        raise TypeError(f"a job is a dict, a Job or a .toml path, got {type(doc).__name__}")
    return _read(_JobReader(name, os.fspath(base_dir) if base_dir is not None else ""), doc)


def load_job(path: Union[str, os.PathLike]) -> Job:
    """Read a job file (TOML); file names in it are relative to its folder."""
    path = os.fspath(path)
    return parse_job(_JobReader(path).read_file(), path, os.path.dirname(os.path.abspath(path)))


def as_job(job: Any) -> Job:
    """A :class:`Job` as it is; a path: :func:`load_job`; dicts: :func:`job_from_dict`."""
    if isinstance(job, Job):
        return job
    if isinstance(job, (str, os.PathLike)):
        return load_job(job)
    return job_from_dict(job)
