"""The scene model: what to draw, from where, under which lights, and how.

A :class:`Scene` holds :class:`SceneObject` s (a single-material mesh each, with its
model matrix and, if textured, its texture), a camera (its own, or a framed one
described by a :class:`FrameSpec`), the lights and the render settings. It is plain
data: :func:`softpipe.scenes.scenefile.load_scene` fills one from a TOML file,
:meth:`Scene.from_model` from one OBJ model (what ``softpipe render MODEL`` draws),
and :func:`softpipe.scenes.drawing.render_scene` draws one.

Also here, because every way of making a scene needs them: :func:`studio_lights`
(the key/fill/rim set a scene without lights gets) and :func:`default_program` /
:func:`program_for` (the shading program an object is drawn with).

This module draws nothing and imports nothing that draws.
"""
from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from softpipe.light.material import Light, Lighting, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import transform_points
from softpipe.programs import PROGRAMS
from softpipe.scenes.mesh import Mesh

__all__ = ["Scene", "SceneObject", "FrameSpec", "framed_camera", "studio_lights", "default_program", "program_for"]


@dataclass(frozen=True)
class FrameSpec:
    """How a framed camera looks at the scene (see :meth:`softpipe.pipeline.camera.Camera.frame`).

    Attributes
    ----------
    azimuth : float
        Degrees about the vertical (y) axis, from +z toward +x.
    elevation : float
        Degrees above the horizontal (xz) plane.
    fovy : float
        Vertical field of view in degrees.
    margin : float
        How much larger than the model's projection the view is (1 = touching): the
        model's farthest vertex from the centre of the picture reaches ``1 / margin``
        of the way to the edge of the frame on its tighter axis (the default 1.1: 91 %).
        See :func:`framed_camera`.
    up : tuple of 3 floats
        The world direction shown as "up".
    """

    azimuth: float = 30.0
    elevation: float = 20.0
    fovy: float = 35.0
    margin: float = 1.1
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass
class SceneObject:
    """One draw: a single-material mesh, its model matrix and how to shade it.

    ``program`` and ``cull`` are None to use the scene's; ``texture`` is the
    :class:`~softpipe.light.texture.Texture2D` of the material's ``diffuse_texture``;
    ``cast_shadows`` false leaves the object out of the shadow maps (it still
    receives shadows).
    """

    name: str
    mesh: Mesh
    model: np.ndarray
    program: Optional[str] = None
    cull: Optional[str] = None
    texture: Any = None
    cast_shadows: bool = True

    def world_positions(self) -> np.ndarray:
        """The mesh's positions after its model matrix (affine: no divide), [N, 3]."""
        return transform_points(self.model, self.mesh.positions)


@dataclass
class Scene:
    """A scene: objects, camera, lights and render settings.

    ``camera`` None means framed (by ``frame``); ``lights`` None means the studio set
    of :func:`studio_lights`, which follows the camera. ``shadows`` true makes every
    light cast shadows (those that have no ShadowSettings of their own get the
    defaults); ``ground`` adds a floor under the objects (:func:`ground_object`) that
    receives shadows but casts none and is left out of the framing. ``point_size`` and
    ``line_width`` (pixels) are those of the meshes' points and line segments. ``srgb`` true
    renders into an sRGB framebuffer (:class:`~softpipe.pipeline.framebuffer.Framebuffer`'s
    ``srgb``: shaded in linear light, encoded by FORMULAS §28 when it becomes bytes). ``path``
    names the scene in error messages; ``warnings`` keeps what loading it warned about.
    """

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
    point_size: float = 1.0
    line_width: float = 1.0
    materials: Dict[str, Material] = field(default_factory=dict)
    shadows: bool = False
    ground: bool = False
    srgb: bool = False
    path: str = "<string>"
    warnings: List[str] = field(default_factory=list)

    @classmethod
    def from_model(cls, model: Union[str, "os.PathLike[str]", Mesh], *, texture: Any = None,
                   azimuth: float = 30.0, elevation: float = 20.0, fovy: float = 35.0,
                   srgb_textures: bool = False, allow_outside: bool = False, **settings: Any) -> "Scene":
        """The scene ``softpipe render MODEL`` draws: one model, framed, under the studio lights.

        Parameters
        ----------
        model : str, path-like or Mesh
            A bundled model's name (``"bunny"``, ``"spot"``, … see :mod:`softpipe.scenes.models`),
            a model file's path (OBJ, or PLY, STL, glTF read through trimesh: the suffix
            decides, in :func:`softpipe.scenes.models.load_model`), or a mesh already loaded.
            A mesh with several materials becomes one object per material. A glTF file's
            parts get their base-color textures and, without one, the program
            ``cook_torrance`` (docs/formats.md); a Mesh given as it is is drawn as any mesh is.
        texture : str, path-like or Texture2D, optional
            A diffuse texture for every part of the model (the mesh needs texture
            coordinates). Without it, a part whose material names a ``diffuse_texture``
            (an MTL ``map_Kd``, or the bundled ``spot``'s texture) gets that one; one
            that cannot be read is warned about and the part drawn without it.
        srgb_textures : bool
            Read the texture image files (``texture`` given as a path, and the materials'
            ``diffuse_texture``) as sRGB-encoded: decoded to linear light when loaded
            (``Texture2D(..., srgb=True)``, FORMULAS §28). An MTL's ``map_Kd`` is sRGB by
            convention in most tools, but the default, False, reads the values as they are
            (as softpipe always has). A ``Texture2D`` given as ``texture`` is used as it is.
        azimuth, elevation, fovy : float
            The framed camera's angles and field of view, in degrees (:class:`FrameSpec`).
        allow_outside : bool
            Let the model file name files (an MTL, a glTF's buffers and images) outside its
            own folder.
        **settings
            Any other :class:`Scene` field: ``width``, ``height``, ``program``, ``cull``,
            ``samples``, ``background``, ``wireframe``, ``path`` (the name in messages;
            the model's name or path by default), …

        Returns
        -------
        Scene
            With no camera (framed), no lights (the studio set of :func:`studio_lights`)
            and no program (:func:`program_for` picks ``textured`` or the default).

        Raises
        ------
        ValueError
            An unknown bare model name, a model without faces, lines or points, or a texture for a mesh
            without texture coordinates (``OBJError`` for a malformed OBJ, ``FormatError``
            for a PLY, STL or glTF that cannot be read, ``OSError`` for a file that cannot be
            opened).
        """
        from softpipe.light.texture import Texture2D  # only a scene that has a texture pays for the image code

        caught: List[str] = []
        categories: Dict[str, type] = {}    # a loader's warnings are re-issued as what they were
        if isinstance(model, Mesh):
            mesh = model
            label = mesh.name or "<mesh>"
            if mesh.triangle_count == 0 and mesh.segment_count == 0 and mesh.point_count == 0:
                raise ValueError(f"{label}: the mesh has no triangles, lines or points to render")
        else:
            label = os.fspath(model)
            mesh = _read_model(model, label, caught, categories, allow_outside)
        settings.setdefault("path", label)
        if mesh.normals is None and len(mesh.materials) > 1:
            # welded smooth normals over the whole model, so the parts meet without a seam
            mesh = mesh.with_normals()
        tex = None
        if texture is not None:
            if mesh.uvs is None:
                raise ValueError(f"{label} has no texture coordinates (vt), so a texture cannot be applied")
            if isinstance(texture, Texture2D):
                tex, source = texture, texture.source
            else:
                if not os.path.isfile(texture):
                    raise FileNotFoundError(f"texture: {os.fspath(texture)}: no such file")
                tex, source = Texture2D(texture, srgb=srgb_textures), os.path.abspath(texture)
        textures: Dict[str, Any] = {}
        objects = []
        for material, part in mesh.by_material():
            part_texture = tex
            if tex is not None:
                # the material names the texture drawn, as if an MTL map_Kd had given it
                part = part.replace(material=material.replace(diffuse_texture=source))
            elif material.diffuse_texture:
                if material.diffuse_texture not in textures:  # parts sharing an image share one Texture2D
                    try:
                        textures[material.diffuse_texture] = Texture2D(material.diffuse_texture,
                                                                       srgb=srgb_textures)
                    except (ValueError, OSError) as e:
                        caught.append(f"{e}; material {material.name!r} drawn without it")
                        textures[material.diffuse_texture] = None
                part_texture = textures[material.diffuse_texture]
            objects.append(SceneObject(part.name or mesh.name, part, np.eye(4), texture=part_texture))
        frame = FrameSpec(azimuth=azimuth, elevation=elevation, fovy=fovy)
        scene = cls(objects=objects, frame=frame, warnings=caught, **settings)
        if not isinstance(model, Mesh) and texture is None:
            _dress_formats(scene.objects, mesh.source)
        for message in caught:
            warnings.warn(message, categories.get(message, UserWarning), stacklevel=2)
        return scene

    def replace(self, **changes: Any) -> "Scene":
        """A copy with ``changes`` (dataclass fields) applied; the objects list is shared."""
        return dataclasses.replace(self, **changes)

    @property
    def triangle_count(self) -> int:
        """The triangles of every object's mesh, in all."""
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

    def world_points(self) -> np.ndarray:
        """Every mesh's positions after its transform, in one float64 array [K, 3]."""
        if not self.objects:
            raise ValueError(f"{self.path}: the scene has no meshes to frame")
        with np.errstate(over="ignore", invalid="ignore"):  # view_camera rejects what overflowed
            points = [o.world_positions() for o in self.objects]
        return np.concatenate(points) if points else np.zeros((0, 3))

    def view_camera(self, azimuth: Optional[float] = None, elevation: Optional[float] = None,
                    orbit: Optional[bool] = None) -> Camera:
        """The camera to render with: the scene's own, or one that frames every mesh.

        ``azimuth``/``elevation`` override the framing angles (a framed camera only).
        ``orbit`` (by default: when ``azimuth`` is given, as a turntable asks for each
        of its frames) fits the model as seen from every azimuth at this elevation, so
        all the frames of a turn share one distance and the model neither grows nor
        shrinks as it turns; without it the fit is for this one view (:func:`framed_camera`).
        """
        if self.camera is not None:
            if azimuth is not None or elevation is not None:
                raise ValueError(f"{self.path}: azimuth/elevation apply only to a framed camera "
                                 "(this scene gives [camera] eye)")
            return self.camera
        f = self.frame
        orbit = azimuth is not None if orbit is None else orbit
        azimuth = f.azimuth if azimuth is None else azimuth
        elevation = f.elevation if elevation is None else elevation
        lo, hi = self.bounds()
        reach = float(max(np.max(np.abs(lo)), np.max(np.abs(hi))))
        if not reach <= 1e100:
            raise ValueError(f"cannot frame meshes that reach {reach:.3g} from the origin (the limit is 1e100); "
                             "give [camera] eye and target")
        return framed_camera(self.world_points(), f, azimuth, elevation, self.width / self.height, orbit=orbit)

    def lighting_for(self, camera: Camera) -> Lighting:
        """The scene's lights (or the studio set, placed for ``camera``) and its global ambient."""
        lights = studio_lights(camera) if self.lights is None else self.lights
        if self.shadows:
            lights = tuple(light if light.shadows else dataclasses.replace(light, shadows=True) for light in lights)
        return Lighting(lights, global_ambient=self.ambient)

    def drawn_objects(self, camera: Camera) -> List[SceneObject]:
        """The objects a render draws: the scene's, and the ground when ``ground`` is set."""
        if not self.ground:
            return list(self.objects)
        return list(self.objects) + [ground_object(self, camera)]

    def program_of(self, obj: SceneObject) -> str:
        """The program ``obj`` is drawn with in this scene (:func:`program_for` with the scene's program)."""
        return program_for(obj, self.program)


#: The ground's material: a light neutral gray, matte, so that shadows read clearly on it.
GROUND_MATERIAL = Material(ka=(0.6, 0.6, 0.6), kd=(0.6, 0.6, 0.6), ks=(0.0, 0.0, 0.0), name="ground")


def ground_object(scene: "Scene", camera: Camera) -> SceneObject:
    """A square floor under the scene's objects, perpendicular to the camera's up.

    It touches the lowest point of the objects (so a model stands on it and its
    contact shadow shows), is ten times their size across, is drawn with ``phong``
    and casts no shadow.
    """
    from softpipe.scenes.shapes import plane
    points = scene.world_points()
    up = np.asarray(camera.up, np.float64)
    up = up / np.linalg.norm(up)
    heights = points @ up
    centre = points.mean(axis=0)
    centre = centre - (centre @ up - heights.min()) * up
    size = 10.0 * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))) or 10.0
    # a rotation taking the plane's +y to ``up``, then the move to ``centre``
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(up, np.cross(helper, up))
    x /= np.linalg.norm(x)
    z = np.cross(x, up)
    model = np.eye(4)
    model[:3, 0], model[:3, 1], model[:3, 2], model[:3, 3] = x, up, z, centre
    return SceneObject("ground", plane(size, material=GROUND_MATERIAL), model, program="phong", cull="none",
                       cast_shadows=False)


def _read_model(model: Union[str, "os.PathLike[str]"], label: str, caught: List[str],
                categories: Dict[str, type], allow_outside: bool = False) -> Mesh:
    """Load a bundled model by name or a model file (OBJ, PLY, STL, glTF: load_model's suffix dispatch);
    its warnings go to ``caught`` (and are re-issued, each as its ``categories`` entry)."""
    from softpipe.scenes.models import load_model  # the bundled models: name → file (and spot's texture)

    with warnings.catch_warnings(record=True) as recorded:
        warnings.simplefilter("always")
        try:
            mesh = load_model(model, allow_outside=allow_outside)
        except UnicodeError as e:
            raise ValueError(f"{label}: cannot read: {e}") from None
    for w in recorded:
        caught.append(str(w.message))
        categories[str(w.message)] = w.category
    if mesh.triangle_count == 0 and mesh.segment_count == 0 and mesh.point_count == 0:
        raise ValueError(f"{label}: the file has no faces (f), lines (l) or points (p) to render")
    return mesh


def _dress_formats(objects: List[SceneObject], source: Any) -> None:
    """Give each part of a model read from a glTF file its base-color texture or, without one, the
    program that reads its metallic-roughness material (formats.GLTF_PROGRAM; docs/formats.md)."""
    from softpipe.scenes.formats import GLTF_PROGRAM, FormatReport

    if not isinstance(source, FormatReport):
        return
    for obj in objects:
        material = obj.mesh.material
        if material.name in source.textures and obj.mesh.uvs is not None:
            obj.texture = source.textures[material.name]
        elif material.name in source.pbr:
            obj.program = GLTF_PROGRAM


def framed_camera(points, f: FrameSpec, azimuth: float, elevation: float, aspect: float, *,
                  orbit: bool = False) -> Camera:
    """A camera that looks at the model from ``azimuth``/``elevation`` and fits it to the frame.

    Parameters
    ----------
    points : array [K, 3], a (min, max) pair, or a Mesh
        The model's world-space vertices (a (min, max) box counts as its 8 corners,
        a mesh as its positions).
    f : FrameSpec
        ``fovy``, ``margin`` and ``up`` (its angles are overridden by the next two).
    azimuth, elevation : float
        Degrees, as :class:`FrameSpec` has them.
    aspect : float
        The picture's width / height.
    orbit : bool
        Fit the model seen from every azimuth (sampled every 5°) at this elevation,
        so that a turntable's frames share one distance.

    The camera looks along the direction the angles give and stands as close as it
    can while every point projects inside ``1 / margin`` of the frame on both axes:
    for a point at (x, y) in eye space and depth D along the view,
    ``|x| ≤ D·tan(fovx/2)/margin`` and ``|y| ≤ D·tan(fovy/2)/margin``. These are
    linear in the eye's position, so the least distance has a closed form per axis;
    the eye is then shifted sideways (the view direction unchanged) so that the
    projection is centred in the picture. So the model fills the frame on its
    tighter axis to the margin (the default 1.1: 91 % of the frame, 4.5 % free on
    each side), whatever its shape; the old fit of the bounding box's circumscribed
    sphere left the teapot at 46 % of the frame's width. With ``orbit`` the view axis
    goes through the centre of the points' bounding box (the turntable turns about
    it) and the distance is the largest any azimuth needs. ``near`` and ``far``
    enclose the points' depths with 5 % to spare.

    Looking straight down (or up) the default up axis, the view direction and "up"
    are parallel and ``look_at`` has no answer, so "up" on the screen becomes the
    direction away from (toward) the azimuth: the picture a camera tilting over the
    top would show.
    """
    from softpipe.pipeline.transforms import look_at, rotate_x, rotate_y

    points = _frame_points(points)
    if not (0.0 < float(f.fovy) < 180.0):
        raise ValueError(f"Camera.fovy must be in (0, 180) degrees, got {f.fovy!r}")
    if not (math.isfinite(f.margin) and f.margin > 0):
        raise ValueError(f"framing margin must be a positive number, got {f.margin!r}")
    if not (math.isfinite(aspect) and aspect > 0):
        raise ValueError(f"framing aspect must be a positive number, got {aspect!r}")
    up = f.up
    if tuple(up) == (0.0, 1.0, 0.0) and abs(math.cos(math.radians(elevation))) < 1e-6:
        s = -1.0 if math.sin(math.radians(elevation)) > 0 else 1.0
        a = math.radians(azimuth)
        up = (s * math.sin(a), 0.0, s * math.cos(a))
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2
    rel = points - centre
    extent = float(np.max(np.linalg.norm(rel, axis=1)))
    ty = math.tan(math.radians(f.fovy) / 2) / f.margin
    tx = ty * aspect

    def basis(az: float):
        back = (rotate_y(az) @ rotate_x(-elevation) @ np.array([0.0, 0.0, 1.0, 0.0]))[:3]  # centre → eye
        view = look_at(centre + back, centre, up)
        return view[0, :3], view[1, :3], back

    def fit(az: float, centred: bool):
        """(distance, sideways shift) for one view; ``centred`` keeps the view axis on the box centre."""
        right, upward, back = basis(az)
        z = rel @ back                                      # toward the eye; a point's depth is t - z
        axes = [(right, tx, rel @ right / tx), (upward, ty, rel @ upward / ty)]
        t = float(z.max()) + 0.01 * extent                  # no point at or behind the eye
        for _, _, a in axes:
            # a point inside the frame on this axis: |a - o| <= t - z, o the eye's shift (in the same units);
            # centred (o = 0) that is t >= |a| + z; with the best shift the two sides meet at (P + Q) / 2
            t = max(t, float((np.abs(a) + z).max()) if centred else (float((a + z).max()) + float((z - a).max())) / 2)
        t = max(t, 1e-9)
        shift = np.zeros(3)
        if not centred:
            depth = t - z
            for axis, tan, a in axes:                       # the shift that centres the projection (bisection)
                lo_o, hi_o = float(a.min()), float(a.max())
                for _ in range(60):
                    o = (lo_o + hi_o) / 2
                    if ((a - o) / depth).max() > ((o - a) / depth).max():
                        lo_o = o
                    else:
                        hi_o = o
                shift += axis * tan * (lo_o + hi_o) / 2
        return t, shift

    if orbit:
        t = max(fit(az, True)[0] for az in np.arange(72) * 5.0)
        shift = np.zeros(3)
    else:
        t, shift = fit(azimuth, False)
    _, _, back = basis(azimuth)
    target = centre + shift
    depth = t - rel @ back
    if float(depth.min()) < _TOO_NEAR:
        warnings.warn(f"the meshes are only {2 * extent:.3g} units across: the framed camera comes within "
                      f"{float(depth.min()):.3g} of them, and the rasterizer drops points nearer the eye than "
                      "1e-09 (softpipe.pipeline.assembly.W_MIN), so they may not be drawn at all. Scale the "
                      "model up (a scene file's fit = 1, or transform = { scale = ... })", UserWarning, stacklevel=2)
    near = max(0.95 * float(depth.min()), 1e-3 * t)
    far = max(1.05 * float(depth.max()), 2.0 * near)
    return Camera(eye=tuple(target + t * back), target=tuple(target), up=up, fovy=f.fovy, near=near,
                  far=far)


#: A framed camera nearer than this to the model (ten times the rasterizer's W_MIN, which clips what
#: is nearer the eye than 1e-9) draws it partly or not at all: framed_camera warns.
_TOO_NEAR = 1e-8


def _frame_points(points) -> np.ndarray:
    """[K, 3] finite float64 points from points, a (min, max) pair, or a mesh."""
    if hasattr(points, "positions"):
        points = points.positions
    if isinstance(points, tuple) and len(points) == 2:
        lo, hi = (np.asarray(b, dtype=np.float64).reshape(-1) for b in points)
        if lo.shape != (3,) or hi.shape != (3,):
            raise ValueError("framed_camera: a box must be two 3-vectors (min, max)")
        points = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                           for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    a = np.asarray(points, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or len(a) == 0 or not np.all(np.isfinite(a)):
        raise ValueError("framed_camera: the points must be a non-empty [K, 3] array of finite numbers")
    return a


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
    """Three directional lights (FORMULAS §9) fixed to the camera.

    A warm key from the upper left, a dim cool fill from the right, and a rim light
    from behind the subject. The directions are given in eye space and turned into
    world space here, so the model is lit the same way from every viewpoint.
    """
    to_world = camera.view[:3, :3].T  # eye → world for directions (the view is a rotation + move)

    def light(toward_eye, diffuse, specular, name):
        v = to_world @ np.asarray(toward_eye, dtype=np.float64)
        return Light.directional(tuple(-v / np.linalg.norm(v)), diffuse=diffuse, specular=specular, name=name)

    return (light((-0.6, 0.7, 0.7), (0.9, 0.85, 0.8), (0.9, 0.9, 0.9), "key"),
            light((0.8, 0.1, 0.5), (0.25, 0.28, 0.35), (0.05, 0.05, 0.05), "fill"),
            light((0.3, 0.6, -1.0), (0.5, 0.5, 0.55), (0.6, 0.6, 0.6), "rim"))
