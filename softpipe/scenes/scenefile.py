"""Scene files: reading and checking the TOML that describes a scene.

``load_scene(path)`` reads a scene file into a :class:`~softpipe.scenes.scene.Scene` (the
scene model, :mod:`softpipe.scenes.scene`); :func:`softpipe.scenes.drawing.render_scene` draws it.
This module only reads: the schema (:class:`SceneReader`), its validation and the
conversion of values into the model's objects. Every mistake is a :class:`SceneError`
naming the file, table and key, in the wording of :mod:`softpipe.core.validation`,
which job files share (:mod:`softpipe.tools.batch.job` reads its tables with
:class:`SceneReader`).

docs/scenes.md is the guide: every table and key, the order of ``transform``
entries, bundled models by name, the errors and :data:`MAX_SCENE_TRIANGLES`;
``examples/scene.toml`` is a full example with every key explained.
"""
from __future__ import annotations

import difflib
import inspect
import math
import os
import warnings
from typing import Any, Dict, List, Optional

import numpy as np

from softpipe.core.validation import (
    BadValue,
    InputError,
    Reader,
    Table,
    boolean,
    choice,
    color,
    describe,
    integer,
    is_number,
    number,
    numbers,
    positive,
    string,
    vec3,
)
from softpipe.light.material import Light, Lighting, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES
from softpipe.pipeline.sampling import pattern_named
from softpipe.pipeline.transforms import compose, rotate, rotate_x, rotate_y, rotate_z, scale, translate
from softpipe.programs import PROGRAMS, get_program
from softpipe.scenes import shapes
from softpipe.scenes.formats import FORMATS, GLTF_PROGRAM, FormatError, FormatReport, load_mesh
from softpipe.scenes.mesh import Mesh
from softpipe.scenes.models import MODELS, load_model, model_path, texture_path
from softpipe.scenes.obj import OBJError, load_obj
from softpipe.scenes.scene import FrameSpec, Scene, SceneObject, framed_camera

__all__ = ["SceneError", "SceneWarning", "load_scene", "parse_scene", "MAX_SCENE_TRIANGLES", "SHAPES",
           # for the readers of other files that name scenes' parts (softpipe.tools.batch's jobs)
           "SceneReader", "program_name", "pattern_name", "shape_params", "bundled_model", "is_bare_word",
           "MATERIAL_KEYS"]

#: The most triangles all the meshes of one scene may hold together.
MAX_SCENE_TRIANGLES = 4_000_000

CULL_MODES = ("back", "front", "none")
SAMPLE_SHADING = ("sample", "center", "centroid")
NORMAL_MODES = ("auto", "area", "angle", "flat")


class SceneError(InputError):
    """A mistake in a scene file; ``str(e)`` starts with the file name (and line, for syntax).

    Attributes: ``file``, ``table`` (e.g. ``"[[lights]] #2"``), ``key``, ``line``
    (TOML syntax errors only) and ``reason`` (the message without the file name).
    """


class SceneWarning(UserWarning):
    """Something a scene can do without (e.g. an OBJ's missing MTL file)."""


# ---------------------------------------------------------------------------- reading values
# The generic readers (numbers, colors, vectors, choices) are softpipe.core.validation's;
# these know the scene's own names.


def program_name(v: Any):
    """A registered program's name (:data:`softpipe.programs.PROGRAMS`), or the Program a
    ``"module:function"`` names (:func:`softpipe.programs.get_program`)."""
    name = string(v)
    if ":" in name and name not in PROGRAMS:
        try:
            return get_program(name)
        except ValueError as e:
            raise BadValue(f"names {e}") from None
    if name not in PROGRAMS:
        raise BadValue(f"names an unknown program {name!r}; registered programs: {', '.join(sorted(PROGRAMS))} "
                       "(or 'module:function')")
    return name


def pattern_name(v: Any) -> str:
    """A sample pattern's name (:func:`softpipe.pipeline.sampling.pattern_named`); a number is its name too."""
    if isinstance(v, int) and not isinstance(v, bool):
        v = str(v)
    name = string(v)
    try:
        pattern_named(name)
    except (ValueError, TypeError) as e:
        raise BadValue(f"is not a sample pattern: {e}") from None
    return name


# ---------------------------------------------------------------------------- the parts


TOP_KEYS = ("ambient", "camera", "render", "lights", "materials", "meshes")
CAMERA_KEYS = ("frame", "eye", "target", "up", "fovy", "near", "far", "azimuth", "elevation", "margin")
RENDER_KEYS = ("width", "height", "background", "samples", "sample_shading", "program", "cull", "wireframe",
               "wireframe_color", "shadows", "ground", "srgb", "srgb_textures")
LIGHT_KEYS = ("kind", "name", "color", "ambient", "diffuse", "specular", "position", "direction",
              "attenuation", "spot_direction", "cutoff", "exponent", "shadows")
SHADOW_KEYS = ("resolution", "pcf", "offset_factor", "offset_units")
MATERIAL_KEYS = ("ke", "ka", "kd", "ks", "shininess", "kr", "kt", "transmission_shininess", "ior", "opacity",
                 "roughness", "diffuse_texture", "transmittance", "falloff", "falloff_a", "k", "eta")
MESH_KEYS = ("name", "obj", "shape", "fit", "normals", "transform", "material", "program", "cull", "cast_shadows")
TRANSFORM_KEYS = ("translate", "rotate", "rotate_x", "rotate_y", "rotate_z", "scale", "matrix")

#: The generators ``shape =`` may name, from :mod:`softpipe.scenes.shapes`.
SHAPES = {name: getattr(shapes, name) for name in
          ("plane", "cube", "uv_sphere", "icosphere", "cylinder", "cone", "torus")}


def shape_params(name: str) -> Dict[str, Any]:
    """A generator's parameters (but ``material``) and their defaults: the keys ``shape = name`` allows."""
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


class SceneReader(Reader):
    """One load of one scene file: the scene's parts read from their tables (and the files
    they name, each loaded once), every mistake a :class:`SceneError`.

    The batch tool's job files (:mod:`softpipe.tools.batch.job`) read their models, materials
    and lights with these methods too.
    """

    kind = "scene file"
    error_class = SceneError

    def __init__(self, file: str = "<string>", base_dir: str = "", allow_outside: bool = False) -> None:
        super().__init__(file, base_dir, allow_outside)
        self.triangles = 0
        self.warnings: List[str] = []
        self._objs: Dict[str, Mesh] = {}
        self._textures: Dict[str, Any] = {}
        self.srgb_textures = False      # [render] srgb_textures: the texture files are sRGB-encoded

    # -- the whole file

    def scene(self, doc: dict) -> Scene:
        """The scene a whole document describes."""
        top = Table(self, doc, "the top level", TOP_KEYS)
        scene = Scene(path=self.file, warnings=self.warnings)
        scene.ambient = top.get("ambient", color, scene.ambient)
        top.library("ambient", lambda: Lighting((), global_ambient=scene.ambient))
        self.render(doc.get("render", {}), scene)
        self.camera(doc.get("camera", {}), scene)
        if "lights" in doc:
            lights = doc["lights"]
            if not isinstance(lights, list):
                raise self.error(f"'lights' must be an array of tables ([[lights]]), got {describe(lights)}",
                                 key="lights")
            scene.lights = tuple(self.light(k + 1, t) for k, t in enumerate(lights))
        materials = doc.get("materials", {})
        if not isinstance(materials, dict):
            raise self.error(f"'materials' must be a table of [materials.NAME] tables, got {describe(materials)}",
                             key="materials")
        for name, data in materials.items():
            scene.materials[name] = self.material(data, f"[materials.{name}]", name)
        meshes = doc.get("meshes", [])
        if not isinstance(meshes, list):
            raise self.error(f"'meshes' must be an array of tables ([[meshes]]), got {describe(meshes)}",
                             key="meshes")
        if not meshes:
            raise self.error("the scene has no [[meshes]]; add at least one (obj = \"file.obj\" or "
                             "shape = \"uv_sphere\")", table="[[meshes]]")
        for k, data in enumerate(meshes):
            scene.objects.extend(self.mesh(k + 1, data, scene))
        if scene.camera is None:  # framed: check now that the framing works
            Table(self, {}, "[camera]", ()).library(None, scene.view_camera)
        return scene

    def render(self, data: Any, scene: Scene) -> None:
        t = Table(self, data, "[render]", RENDER_KEYS)
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
        # a color drawn into the framebuffer, which is unclamped: any finite numbers
        scene.wireframe_color = t.get("wireframe_color", lambda v: color(v, allow_negative=True),
                                      scene.wireframe_color)
        scene.shadows = t.get("shadows", boolean, False)
        scene.ground = t.get("ground", boolean, False)
        scene.srgb = t.get("srgb", boolean, False)
        self.srgb_textures = t.get("srgb_textures", boolean, False)

    def camera(self, data: Any, scene: Scene) -> None:
        t = Table(self, data, "[camera]", CAMERA_KEYS)
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
            t.library(None, lambda: framed_camera(((-1, -1, -1), (1, 1, 1)), f, f.azimuth, f.elevation, 1.0))
            scene.frame, scene.camera = f, None
        else:
            eye = t.get("eye", vec3)
            kw = dict(eye=eye, target=t.get("target", vec3, (0.0, 0.0, 0.0)), up=up,
                      fovy=t.get("fovy", number, 40.0), near=t.get("near", positive, 0.1),
                      far=t.get("far", positive, 100.0))
            scene.camera = t.library(None, lambda: Camera(**kw))

    def light(self, index: int, data: Any) -> Light:
        label = f"[[lights]] #{index}"
        t = Table(self, data, label, LIGHT_KEYS)
        if "kind" not in t:
            raise t.error("needs key 'kind': 'directional', 'point' or 'spot'")
        kind = t.get("kind", choice("directional", "point", "spot"))
        kw: Dict[str, Any] = {"kind": kind, "name": t.get("name", string, f"light {index}")}
        if "color" in t:
            for k in ("diffuse", "specular"):
                if k in t:
                    raise t.error("cannot be given with 'color' (color sets both diffuse and specular)", k)
            kw["diffuse"] = kw["specular"] = t.get("color", color)
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
        if "shadows" in t:
            kw["shadows"] = self.shadows(t)
        return t.library(None, lambda: Light(**kw))

    def shadows(self, light: Table):
        """A light's ``shadows``: true/false, or a table of ShadowSettings fields."""
        value = light.data["shadows"]
        if isinstance(value, bool):
            return value
        if not isinstance(value, dict):
            raise light.error(f"must be true, false or a table of {', '.join(SHADOW_KEYS)}, got {describe(value)}",
                              "shadows")
        t = Table(self, value, f"{light.label} shadows", SHADOW_KEYS)
        kw = {key: t.get(key, integer) for key in ("resolution", "pcf") if key in t}
        kw.update({key: t.get(key, number) for key in ("offset_factor", "offset_units") if key in t})
        return t.library(None, lambda: ShadowSettings(**kw))

    def material(self, data: Any, label: str, name: str) -> Material:
        t = Table(self, data, label, MATERIAL_KEYS)
        kw: Dict[str, Any] = {"name": name}
        for key in ("ke", "ka", "kd", "ks", "kr", "kt"):
            if key in t:
                kw[key] = t.get(key, color)
        for key in ("shininess", "transmission_shininess", "opacity", "roughness", "falloff_a"):
            if key in t:
                kw[key] = t.get(key, number)
        if "ior" in t:          # a number, or a medium's name (softpipe.light.material.MEDIA: "water", "glass", …)
            kw["ior"] = t.get("ior", lambda v: v if isinstance(v, str) else number(v))
        for key in ("transmittance", "k", "eta"):      # k, eta: a conductor's complex index η + ik (Material)
            if key in t:
                kw[key] = t.get(key, color)
        if "falloff" in t:
            kw["falloff"] = t.get("falloff", string)
        if "diffuse_texture" in t:
            bundled = _bundled_texture(t.data["diffuse_texture"])
            kw["diffuse_texture"] = bundled if bundled is not None else self.path(t, "diffuse_texture")
        material = t.library(None, lambda: Material(**kw))
        if material.diffuse_texture:
            self.texture(material.diffuse_texture, t, "diffuse_texture")
        return material

    def texture(self, path: str, table: Table, key: str):
        if path not in self._textures:
            from softpipe.light.texture import Texture2D
            try:
                self._textures[path] = Texture2D(path, srgb=self.srgb_textures)
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
            except BadValue as e:
                raise self.error(f"key 'shape' in {label} {e}", table=label, key="shape") from None
            params = shape_params(shape)
        t = Table(self, data, label, MESH_KEYS + tuple(params))
        if ("obj" in t) == ("shape" in t):
            raise t.error("needs either 'obj' (an OBJ file) or 'shape' (one of "
                          f"{', '.join(SHAPES)}), {'not both' if 'obj' in t else 'and has neither'}")
        if "shape" in t:
            mesh = self.shape(t, shape, params)
        else:
            mesh = self.obj(t)
        # a glTF's base color textures and which materials are its (softpipe.scenes.formats)
        report = mesh.source if isinstance(mesh.source, FormatReport) else FormatReport("", "")
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
                raise t.error(f"must be a material name or an inline table, got {describe(m)}", "material")
            mesh = mesh.replace(material=material, materials=(), material_ids=None)
        program = t.get("program", program_name, None)
        cull = t.get("cull", choice(*CULL_MODES), None)
        cast_shadows = t.get("cast_shadows", boolean, True)
        objects = []
        parts = mesh.by_material()
        for material, part in parts:
            texture = self.texture(material.diffuse_texture, t, "material" if "material" in t else "obj") \
                if material.diffuse_texture else None
            part_program = program
            if "material" not in t and material.name in report.pbr:
                texture = report.textures.get(material.name) if part.uvs is not None else None
                part_program = part_program or (None if texture is not None else GLTF_PROGRAM)
            part_name = name if len(parts) == 1 else part.name
            objects.append(SceneObject(part_name, part.replace(name=part_name), model, part_program, cull, texture,
                                       cast_shadows))
        return objects

    def count(self, t: Table, key: str, triangles: int) -> None:
        self.triangles += triangles
        if self.triangles > MAX_SCENE_TRIANGLES:
            raise t.error(f"makes the scene's meshes hold {self.triangles:,} triangles, more than the limit "
                          f"MAX_SCENE_TRIANGLES = {MAX_SCENE_TRIANGLES:,}", key)

    def shape(self, t: Table, shape: str, params: Dict[str, Any]) -> Mesh:
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

    def obj(self, t: Table) -> Mesh:
        bundled = bundled_model(t.data["obj"])
        if bundled is not None:
            name, path = t.data["obj"], bundled
        else:
            rel = t.data["obj"]
            hint = f" (nor is {rel!r} a bundled model: {', '.join(MODELS)})" \
                if isinstance(rel, str) and is_bare_word(rel) else ""
            name, path = None, self.path(t, "obj", hint)
        if path not in self._objs:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    if name is None and os.path.splitext(path)[1].lower() in FORMATS:
                        # PLY, STL, glTF through trimesh; a glTF's base color textures come with it
                        mesh = load_mesh(path, allow_outside=self.allow_outside)
                    else:
                        # a bundled model by name: load_model also gives "spot" its texture
                        mesh = load_obj(path, allow_outside=self.allow_outside) if name is None else load_model(name)
                except (OBJError, FormatError) as e:
                    raise self.error(f"key 'obj' in {t.label}: {e}", table=t.label, key="obj") from None
                except (OSError, UnicodeError) as e:
                    raise self.error(f"key 'obj' in {t.label}: cannot read {path}: {e}", table=t.label,
                                     key="obj") from None
            self.warnings.extend(str(w.message) for w in caught)
            if mesh.triangle_count == 0 and mesh.segment_count == 0 and mesh.point_count == 0:
                raise self.error(f"key 'obj' in {t.label}: {path} has no faces, lines or points", table=t.label,
                                 key="obj")
            self._objs[path] = mesh
        mesh = self._objs[path]
        self.count(t, "obj", mesh.triangle_count)
        return mesh

    def transform(self, t: Table) -> np.ndarray:
        if "transform" not in t:
            return np.eye(4)
        value = t.data["transform"]
        if isinstance(value, dict):
            entries = [{k: v} for k, v in value.items()]
        elif isinstance(value, list):
            entries = value
        else:
            raise t.error("must be an array of one-key tables or a table of translate/rotate/scale entries, "
                          f"got {describe(value)}", "transform")
        matrices = []
        for n, entry in enumerate(entries, 1):
            where = f"entry {n} of key 'transform' in {t.label}"
            if not isinstance(entry, dict) or len(entry) != 1:
                raise self.error(f"{where} must be a table with one key ({', '.join(TRANSFORM_KEYS)}), "
                                 f"got {describe(entry)}" + (f" with {len(entry)} keys" if isinstance(entry, dict)
                                                              else ""), table=t.label, key="transform")
            (kind, v), = entry.items()
            if kind not in TRANSFORM_KEYS:
                close = difflib.get_close_matches(kind, TRANSFORM_KEYS, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise self.error(f"unknown transform {kind!r} in {where}{hint}; expected one of "
                                 f"{', '.join(TRANSFORM_KEYS)}", table=t.label, key="transform")
            try:
                matrices.append(_transform_entry(kind, v))
            except (ValueError, TypeError) as e:      # BadValue, and the transforms' own checks
                raise self.error(f"{kind!r} in {where} {e}", table=t.label, key="transform") from None
        model = compose(*matrices) if matrices else np.eye(4)
        det = float(np.linalg.det(model[:3, :3]))
        if not np.all(np.isfinite(model)) or not math.isfinite(det) or abs(det) < 1e-12:
            raise t.error("is singular or not finite (a scale of 0 flattens the mesh)", "transform")
        return model


def is_bare_word(text: str) -> bool:
    """No folder and no ``.obj`` suffix: what a bundled model's name looks like."""
    return "/" not in text and "\\" not in text and not text.lower().endswith(".obj")


def _bundled_texture(value: Any) -> Optional[str]:
    """The bundled texture ``diffuse_texture = value`` names (``"spot"``: the texture of the
    model "spot"), or None for a file name."""
    if not isinstance(value, str) or bundled_model(value) is None:
        return None
    found = texture_path(value)
    return None if found is None else os.fspath(found)


def bundled_model(value: Any) -> Optional[str]:
    """The bundled model file ``obj = value`` names (``"bunny"``), or None for a file name.

    Only a bare word is looked up, so ``"models/bunny"`` or ``"bunny.obj"`` stay files
    relative to the scene; :func:`softpipe.scenes.models.model_path` decides whether the word
    is a model's name (it leaves anything else as it was, or refuses it: then the word
    is a file name here, relative to the scene file, not to the current folder).
    """
    if not isinstance(value, str) or not value.strip() or "\0" in value or not is_bare_word(value):
        return None
    try:
        path = model_path(value)
    except (ValueError, TypeError):
        return None
    return os.fspath(path) if os.fspath(path) != value else None


def _in_range(v: int, low: int, high: int, unit: str) -> int:
    if not low <= v <= high:
        raise BadValue(f"must be between {low} and {high} {unit}, got {v}")
    return v


def _transform_entry(kind: str, v: Any) -> np.ndarray:
    if kind == "translate":
        return translate(*vec3(v))
    if kind == "scale":
        if is_number(v):
            s = number(v)
            return scale(s, s, s)
        factors = numbers(1, 3, what="numbers (s or [sx, sy, sz])")(v)
        return scale(*(factors * 3 if len(factors) == 1 else factors))
    if kind == "rotate":
        angle, *axis = numbers(4, what="numbers [degrees, ax, ay, az]")(v)
        if not any(axis):
            raise BadValue("needs a nonzero axis [degrees, ax, ay, az]")
        return rotate(angle, axis)
    if kind in ("rotate_x", "rotate_y", "rotate_z"):
        angle = number(v, "an angle in degrees")
        return {"rotate_x": rotate_x, "rotate_y": rotate_y, "rotate_z": rotate_z}[kind](angle)
    # matrix
    if not isinstance(v, list) or len(v) != 4:
        raise BadValue(f"must be 4 rows of 4 numbers, got {describe(v)}")
    m = np.array([numbers(4)(row) for row in v], dtype=np.float64)
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise BadValue(f"must be affine: its last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    return m


# ---------------------------------------------------------------------------- loading


def parse_scene(text: str, name: str = "<string>", base_dir: Optional[str] = None, *,
                allow_outside: bool = False) -> Scene:
    """A scene from TOML text; ``name`` labels errors, ``base_dir`` resolves file names
    (the current directory by default).

    The files it names must lie in ``base_dir`` or below (:func:`softpipe.core.files.resolve_inside`);
    ``allow_outside=True`` lifts that for a scene you trust.
    """
    if not isinstance(text, str):
        raise TypeError(f"parse_scene: text must be a str, got {type(text).__name__}")
    reader = SceneReader(name, os.fspath(base_dir) if base_dir is not None else "", allow_outside)
    doc = reader.parse_toml(text)
    try:
        return reader.scene(doc)
    except RecursionError:  # pragma: no cover - nothing here recurses on the input
        raise reader.error("the scene is nested too deeply") from None


def load_scene(path, *, allow_outside: bool = False) -> Scene:
    """Read a scene file (TOML); file names in it are relative to its folder, and must lie in
    it or below unless ``allow_outside=True`` (:func:`softpipe.core.files.resolve_inside`).

    Every problem raises :class:`SceneError` naming the file, table and key. Warnings
    (e.g. an OBJ's missing MTL file) are kept in ``Scene.warnings`` and issued as
    :class:`SceneWarning`.
    """
    path = os.fspath(path)
    text = SceneReader(path).read_file()
    scene = parse_scene(text, path, os.path.dirname(os.path.abspath(path)), allow_outside=allow_outside)
    for message in scene.warnings:
        warnings.warn(message, SceneWarning, stacklevel=2)
    return scene
