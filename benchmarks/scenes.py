"""The standard benchmark scenes of issue 6, built from code and the bundled models (``softpipe.scenes.models``).

Each scene is a function ``scene(scale=1.0) -> Scene``. ``scale`` 1 is the size
the issue specifies; a smaller scale shrinks the framebuffer by ``scale`` on
each side and the generated geometry to match (so that ``make test`` can run
every scene in a fraction of a second); meshes loaded from files keep their
triangles. A :class:`Scene` is plain data: a framebuffer size, a clear color and
a list of draws, each the keyword arguments of :class:`softpipe.pipeline.draw.DrawCall`
(without the framebuffer). Everything random is seeded: a scene is the same
bytes in every process.

=================== ===================================================================
``sphere200k``       UV sphere (448 × 224: 199,808 triangles) on a ground plane (2),
                     perspective camera, Blinn-Phong per fragment, one directional light
``sphere200k-color`` the same geometry, a color per vertex, no lighting
``bunny``            Stanford bunny (69,451 triangles), Phong per fragment, three lights
``bunny-outputs``    the same with five outputs (color, depth, normal, object_id,
                     triangle_id) derived from its visibility record each frame (issue 31)
``spot-textured``    Spot (5,856 triangles) with its 1024² texture, trilinear, one light
``fill``             1000 large triangles, 30–60 % of 1920×1080 each, constant random depth
                     each, random order, depth LESS, a color per vertex
``fill-b2f``         the same triangles drawn back to front (every fragment passes)
``tiny``             1,000,000 triangles of one pixel² each at 1024×1024
``bunny-plane``      the bunny standing on a ground plane, Blinn-Phong, a sun and a spot
``bunny-shadows``    the same, both lights casting shadows (1024² maps, PCF r = 1, made
                     in every frame by the scene's ``prepare``; the ground casts none)
``bunny-wireframe``  the bunny's 104,288 edges (each once) as ``lines`` at 1024², a color
                     per vertex (issue 29)
``points200k``       200,000 points of size 2 on and around a sphere at 1024², a color per
                     vertex (issue 29)
``field10k``         10,000 instances of an 80-triangle ball on a 100 × 100 field at 1024², in
                     one instanced draw: each instance's place, size and color are instance
                     attributes (issue 31)
=================== ===================================================================

The lit scenes use softpipe's built-in programs when they are there
(``phong``, ``phong_phong_specular`` and ``textured`` of ``softpipe.programs``,
with the uniforms of :mod:`softpipe.programs.common`); if one is missing, the
scene falls back to a shader written here (module-level functions, so numba
compiles each once per process) with :mod:`softpipe.language.glsl` and
:mod:`softpipe.light.lighting`, and says so in its notes. :attr:`Scene.shading`
names the shaders a scene ran.
"""
from __future__ import annotations

import importlib
import math
from collections import namedtuple
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from softpipe.language.glsl import dot, mat3_mul_vec3, mat4_mul_vec4, neg, normalize
from softpipe.light.lighting import BLINN_PHONG, PHONG, opengl_lighting
from softpipe.light.material import Light, Lighting, Material
from softpipe.light.texture import Texture2D, texture
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import compose
from softpipe.programs import get_program
from softpipe.scenes.drawing import standard_uniforms
from softpipe.scenes.models import MODELS_DIR
from softpipe.scenes.obj import load_obj
from softpipe.scenes.shapes import icosphere, plane, uv_sphere
from softpipe.shading import standard_vertex

__all__ = ["Scene", "SCENES", "build_scene", "AssetMissing", "ASSETS", "asset_path", "TEXTURE_NOTE"]

#: Where the meshes are: the models bundled with softpipe (:mod:`softpipe.scenes.models`). A relative
#: path here would be taken from the repository root (the folder holding ``benchmarks/``).
ASSETS = MODELS_DIR
REPO_ROOT = Path(__file__).resolve().parent.parent

#: What ``spot-textured`` samples with when the built-in ``textured`` program is missing.
TEXTURE_NOTE = ("spot-textured: the built-in 'textured' program is missing, so the fallback shader samples with "
                "softpipe.light.texture.texture(), i.e. level of detail 0 (bilinear from mip level 0), not trilinear")


class AssetMissing(FileNotFoundError):
    """A scene's mesh or texture is not where the benchmarks expect it."""


def asset_path(relative: str, scene: str) -> Path:
    """``ASSETS/relative`` resolved from the repository root, or :class:`AssetMissing`."""
    path = (REPO_ROOT / ASSETS / relative).resolve()
    if not path.is_file():
        raise AssetMissing(f"benchmark scene {scene!r} needs {ASSETS}/{relative} (resolved from the repository "
                           f"root {REPO_ROOT} to {path}), which does not exist; the test meshes ship with "
                           f"softpipe in softpipe/data/models (see its README.md)")
    return path


@dataclass
class Scene:
    """One benchmark frame: clear the framebuffer, then run ``draws`` in order.

    ``draws`` are keyword arguments of :class:`softpipe.pipeline.draw.DrawCall` (all but
    the framebuffer). ``triangles`` counts the primitives submitted per frame (lines, points).
    """

    name: str
    width: int
    height: int
    draws: List[dict]
    triangles: int
    description: str
    clear_color: Tuple[float, float, float, float] = (0.05, 0.05, 0.08, 1.0)
    notes: List[str] = field(default_factory=list)
    scale: float = 1.0
    shading: str = ""
    pattern: object = None      # the framebuffer's SamplePattern (None: one centre sample)
    #: Run at the start of every frame, inside its time, before the draws (None: nothing). It
    #: may update the draws' uniforms in place (``bunny-shadows`` renders its shadow maps
    #: and puts them into the lighting uniform: they depend on the scene, as when things
    #: move) and returns {part name: seconds} of what it did (each map's time); the
    #: harness reports those parts, the rest of ``prepare`` and the draws ("lit pass").
    prepare: Optional[Callable[[], Dict[str, float]]] = None
    #: Draw into a framebuffer that keeps a visibility record (``Framebuffer(..., record=True)``).
    record: bool = False
    #: Run at the end of every frame, inside its time, after the draws, with the framebuffer
    #: (None: nothing); the harness times it as the stage ``outputs`` (``bunny-outputs``
    #: derives its buffers from the record there).
    finish: Optional[Callable[[Any], None]] = None


def _size(width: int, height: int, scale: float) -> Tuple[int, int]:
    if not (isinstance(scale, (int, float)) and 0.0 < scale <= 1.0):
        raise ValueError(f"scale must be in (0, 1], got {scale!r}")
    return max(16, round(width * scale)), max(16, round(height * scale))


# --------------------------------------------------------------------------
# Shaders (module level: numba compiles each once per process)
# --------------------------------------------------------------------------

ColorVaryings = namedtuple("BenchColorVaryings", ["color"])
TexturedVaryings = namedtuple("BenchTexturedVaryings", ["position", "normal", "uv"])


def color_vertex(attributes, uniforms):
    """Model-view-projection (uniform ``mvp``); the vertex's ``color`` attribute as the varying."""
    p = attributes.position
    clip = mat4_mul_vec4(uniforms.mvp, (p[0], p[1], p[2], 1.0))
    return clip, ColorVaryings(attributes.color)


def instanced_vertex(attributes, uniforms):
    """An instance's place and size (instance attributes ``place``, ``size``), then MVP (uniform ``mvp``);
    its ``color``, shaded by the vertex's height in the ball, as the varying."""
    p, o, k = attributes.position, attributes.place, attributes.size
    clip = mat4_mul_vec4(uniforms.mvp, (k * p[0] + o[0], k * p[1] + o[1], k * p[2] + o[2], 1.0))
    c, light = attributes.color, 0.6 + 0.4 * p[1]
    return clip, ColorVaryings((c[0] * light, c[1] * light, c[2] * light))


def blinn_phong_fragment(varyings, uniforms, frag):
    """The OpenGL lighting equation per fragment with Blinn-Phong's (N·H)ⁿ, in eye space."""
    P = varyings.position
    N = normalize(varyings.normal)
    V = normalize(neg(P))
    c = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, BLINN_PHONG)
    return (c[0], c[1], c[2], 1.0)


def phong_fragment(varyings, uniforms, frag):
    """The OpenGL lighting equation per fragment with Phong's (R·V)ⁿ, in eye space."""
    P = varyings.position
    N = normalize(varyings.normal)
    V = normalize(neg(P))
    c = opengl_lighting(P, N, V, uniforms.material, uniforms.lighting, PHONG)
    return (c[0], c[1], c[2], 1.0)


def textured_vertex(attributes, uniforms):
    """:func:`softpipe.shading.standard_vertex` plus the ``uv`` attribute as a varying."""
    p = attributes.position
    eye = mat4_mul_vec4(uniforms.model_view, (p[0], p[1], p[2], 1.0))
    clip = mat4_mul_vec4(uniforms.projection, eye)
    normal = mat3_mul_vec3(uniforms.normal_matrix, attributes.normal)
    return clip, TexturedVaryings((eye[0], eye[1], eye[2]), normal, attributes.uv)


def textured_fragment(varyings, uniforms, frag):
    """The texture's color (``uniforms.texture``) lit by a headlight: × (0.25 + 0.75 (N·V)₊)."""
    N = normalize(varyings.normal)
    V = normalize(neg(varyings.position))
    k = 0.25 + 0.75 * max(dot(N, V), 0.0)
    t = texture(uniforms.texture, varyings.uv)
    return (t[0] * k, t[1] * k, t[2] * k, 1.0)


# --------------------------------------------------------------------------
# The sphere scenes
# --------------------------------------------------------------------------

SPHERE_SEGMENTS, SPHERE_RINGS = 448, 224     # 2 · 448 · 223 = 199,808 triangles
SPHERE_CAMERA = Camera(eye=(0.0, 1.1, 3.4), target=(0.0, -0.1, 0.0), fovy=45.0, near=0.1, far=50.0)


def _sphere_meshes(scale: float):
    segments = max(8, round(SPHERE_SEGMENTS * scale))
    rings = max(4, round(SPHERE_RINGS * scale))
    sphere = uv_sphere(1.0, segments, rings, material=Material(kd=(0.8, 0.25, 0.2), ks=(0.6, 0.6, 0.6),
                                                              shininess=48.0))
    ground = plane(12.0, 1, material=Material(kd=(0.45, 0.45, 0.4), ks=(0.05, 0.05, 0.05), shininess=8.0))
    ground = ground.transformed(np.array([[1, 0, 0, 0], [0, 1, 0, -1.0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    return sphere, ground


def _program(name: str, module: str, fallback_vertex: Callable, fallback_fragment: Callable, scene: str):
    """(vertex, fragment, notes) of built-in program ``name``, else of the fallback shaders here.

    ``softpipe.programs.<module>`` is imported first (importing it registers the program).
    """
    try:
        importlib.import_module(f"softpipe.programs.{module}")
        program = get_program(name)
        return program.vertex, program.fragment, []
    except (ImportError, ValueError) as err:
        return fallback_vertex, fallback_fragment, [
            f"{scene}: the built-in program {name!r} is not available ({err}); using "
            f"{fallback_fragment.__module__}.{fallback_fragment.__name__} instead"]


def _shader_names(vertex: Callable, fragment: Optional[Callable]) -> str:
    def name(f):
        f = getattr(f, "py_func", f)
        return f"{f.__module__}.{f.__qualname__}"
    return f"vertex {name(vertex)}, fragment " + (name(fragment) if fragment else "softpipe default (varying color)")


def sphere200k(scale: float = 1.0) -> Scene:
    w, h = _size(1024, 1024, scale)
    sphere, ground = _sphere_meshes(scale)
    vertex, fragment, notes = _program("phong", "phong", standard_vertex, blinn_phong_fragment, "sphere200k")
    base = standard_uniforms(SPHERE_CAMERA, w / h)
    lighting = Lighting((Light.directional((-0.4, -1.0, -0.6), ambient=(0.1, 0.1, 0.1)),),
                        global_ambient=(0.1, 0.1, 0.1)).uniform(base["view"])
    draws = []
    for mesh in (sphere, ground):
        u = dict(base, material=mesh.material, lighting=lighting)
        draws.append(dict(positions=mesh.positions, indices=mesh.indices, attributes={"normal": mesh.normals},
                          vertex_shader=vertex, fragment_shader=fragment, uniforms=u, cull="back"))
    return Scene("sphere200k", w, h, draws, sphere.triangle_count + ground.triangle_count,
                 f"UV sphere ({sphere.triangle_count} triangles) + ground plane (2), Blinn-Phong per fragment, "
                 "1 directional light", notes=notes, scale=scale, shading=_shader_names(vertex, fragment))


def _vertex_colors(positions: np.ndarray) -> np.ndarray:
    """A smooth color per vertex from its position (a pure function of the geometry)."""
    p = positions
    return np.stack([0.5 + 0.5 * np.sin(3.0 * p[:, 0] + 1.0), 0.5 + 0.5 * np.sin(4.0 * p[:, 1]),
                     0.5 + 0.5 * np.cos(5.0 * p[:, 2])], 1)


def sphere200k_color(scale: float = 1.0) -> Scene:
    w, h = _size(1024, 1024, scale)
    sphere, ground = _sphere_meshes(scale)
    base = standard_uniforms(SPHERE_CAMERA, w / h)
    mvp = compose(base["projection"], base["model_view"])
    draws = [dict(positions=m.positions, indices=m.indices, attributes={"color": _vertex_colors(m.positions)},
                  vertex_shader=color_vertex, uniforms={"mvp": mvp}, cull="back") for m in (sphere, ground)]
    return Scene("sphere200k-color", w, h, draws, sphere.triangle_count + ground.triangle_count,
                 f"the sphere200k geometry ({sphere.triangle_count + 2} triangles), a color per vertex, no lighting",
                 scale=scale, shading=_shader_names(color_vertex, None))


# --------------------------------------------------------------------------
# The meshes bundled with softpipe (softpipe/data/models)
# --------------------------------------------------------------------------

def bunny(scale: float = 1.0) -> Scene:
    w, h = _size(1024, 1024, scale)
    mesh = load_obj(asset_path("stanford-bunny.obj", "bunny"))
    vertex, fragment, notes = _program("phong_phong_specular", "phong", standard_vertex, phong_fragment, "bunny")
    camera = Camera.frame(mesh, azimuth=20.0, elevation=15.0, fovy=35.0, margin=1.05)
    base = standard_uniforms(camera, w / h)
    lo, hi = mesh.bounds()
    extent, centre = float(np.linalg.norm(hi - lo)), (lo + hi) / 2
    lighting = Lighting((
        Light.directional((-0.5, -0.7, -0.5), diffuse=(0.8, 0.8, 0.75)),                          # key
        Light.directional((0.8, -0.2, -0.3), diffuse=(0.25, 0.3, 0.4), specular=(0.2, 0.2, 0.2)),  # fill
        Light.point(tuple(centre + extent * np.array([0.3, 0.8, -1.2])), diffuse=(0.5, 0.5, 0.5)),  # rim
    ), global_ambient=(0.08, 0.08, 0.08)).uniform(base["view"])
    material = Material(kd=(0.75, 0.7, 0.6), ks=(0.4, 0.4, 0.4), shininess=30.0)
    u = dict(base, material=material, lighting=lighting)
    draws = [dict(positions=mesh.positions, indices=mesh.indices, attributes={"normal": mesh.vertex_normals()},
                  vertex_shader=vertex, fragment_shader=fragment, uniforms=u, cull="back")]
    return Scene("bunny", w, h, draws, mesh.triangle_count,
                 f"Stanford bunny ({mesh.triangle_count} triangles), Phong per fragment with Phong's (R.V)^n "
                 "specular, 3 lights", notes=notes, scale=scale, shading=_shader_names(vertex, fragment))


def spot_textured(scale: float = 1.0) -> Scene:
    w, h = _size(1024, 1024, scale)
    mesh = load_obj(asset_path("spot/spot_triangulated.obj", "spot-textured"))
    albedo = Texture2D(asset_path("spot/spot_texture.png", "spot-textured"), wrap="repeat", filter="trilinear")
    vertex, fragment, notes = _program("textured", "textured", textured_vertex, textured_fragment, "spot-textured")
    if notes:
        notes.append(TEXTURE_NOTE)
    camera = Camera.frame(mesh, azimuth=145.0, elevation=15.0, fovy=35.0, margin=1.05)
    base = standard_uniforms(camera, w / h)
    lighting = Lighting((Light.directional((-0.5, -0.6, 0.7), diffuse=(0.85, 0.85, 0.85),
                                           specular=(0.3, 0.3, 0.3)),),
                        global_ambient=(0.3, 0.3, 0.3)).uniform(base["view"])
    material = Material(ka=(1.0, 1.0, 1.0), kd=(0.9, 0.9, 0.9), ks=(0.15, 0.15, 0.15), shininess=24.0)
    u = dict(base, texture=albedo, material=material, lighting=lighting)
    draws = [dict(positions=mesh.positions, indices=mesh.indices,
                  attributes={"normal": mesh.vertex_normals(), "uv": mesh.uvs},
                  vertex_shader=vertex, fragment_shader=fragment, uniforms=u, cull="back")]
    return Scene("spot-textured", w, h, draws, mesh.triangle_count,
                 f"Spot ({mesh.triangle_count} triangles) with its 1024x1024 texture, trilinear (level of detail "
                 "from the exact screen-space derivatives of uv), Blinn-Phong per fragment, 1 light",
                 notes=notes, scale=scale, shading=_shader_names(vertex, fragment))


# --------------------------------------------------------------------------
# Synthetic fill-rate scenes: clip coordinates given directly (no vertex shader)
# --------------------------------------------------------------------------

FILL_SEED, TINY_SEED = 6, 66


def _to_clip(xy: np.ndarray, depth: np.ndarray, width: int, height: int) -> np.ndarray:
    """Window positions [..., 2] (pixels, y up) and window depths [...] → clip coordinates [..., 4], w = 1."""
    out = np.ones(xy.shape[:-1] + (4,))
    out[..., 0] = 2.0 * xy[..., 0] / width - 1.0
    out[..., 1] = 2.0 * xy[..., 1] / height - 1.0
    out[..., 2] = 2.0 * depth - 1.0
    return out


def _fill_triangles(scale: float):
    """Window-space corners [T, 3, 2], depths [T] and corner colors [T, 3, 3] of the fill scenes.

    Each triangle's area is a uniform 30–60 % of the screen's; its centroid is
    uniform over the screen and its corners sit at random angles around it
    (at least 50° apart, so no slivers), so parts of it may lie off screen and
    are clipped. Depths are distinct (a shuffled even spacing in [0.01, 0.99]),
    so the drawing order is random with respect to depth.
    """
    w, h = _size(1920, 1080, scale)
    n = max(10, round(1000 * scale))
    rng = np.random.default_rng(FILL_SEED)
    area = rng.uniform(0.30, 0.60, n) * w * h
    centre = rng.uniform((0.0, 0.0), (w, h), (n, 2))
    angles = np.empty((n, 3))
    k = 0
    while k < n:  # rejection: three angles at least 50° apart (every gap, around the circle)
        a = np.sort(rng.uniform(0.0, 2.0 * np.pi, 3))
        gaps = np.diff(np.append(a, a[0] + 2.0 * np.pi))
        if gaps.min() >= math.radians(50.0):
            angles[k] = a
            k += 1
    unit = np.stack([np.cos(angles), np.sin(angles)], -1)                # [n, 3, 2], counter-clockwise
    e1, e2 = unit[:, 1] - unit[:, 0], unit[:, 2] - unit[:, 0]
    unit_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    aspect = np.array([w / h, 1.0]) / math.sqrt(w / h)                   # stretch with the screen, same area
    corners = centre[:, None, :] + unit * aspect * np.sqrt(area / unit_area)[:, None, None]
    depth = 0.01 + 0.98 * (rng.permutation(n) + 0.5) / n
    colors = rng.uniform(0.15, 1.0, (n, 3, 3))
    return w, h, corners, depth, colors


def _fill_scene(name: str, scale: float, back_to_front: bool) -> Scene:
    w, h, corners, depth, colors = _fill_triangles(scale)
    if back_to_front:
        order = np.argsort(-depth, kind="stable")
        corners, depth, colors = corners[order], depth[order], colors[order]
    n = len(depth)
    positions = _to_clip(corners, np.repeat(depth[:, None], 3, 1), w, h).reshape(-1, 4)
    draws = [dict(positions=positions, varyings={"color": colors.reshape(-1, 3)}, depth_test="less",
                  cull="none")]
    what = "back to front (every fragment passes the depth test)" if back_to_front else "in random depth order"
    return Scene(name, w, h, draws, n,
                 f"{n} triangles of 30-60 % of the screen each, constant random depth, {what}, depth LESS, "
                 "vertex colors", scale=scale, shading="no vertex shader (clip coordinates given), "
                 "fragment softpipe default (varying color)")


def fill(scale: float = 1.0) -> Scene:
    return _fill_scene("fill", scale, back_to_front=False)


def fill_b2f(scale: float = 1.0) -> Scene:
    return _fill_scene("fill-b2f", scale, back_to_front=True)


def tiny(scale: float = 1.0) -> Scene:
    """1000 × 1000 cells over the screen, in rows, each holding one triangle of area 1 pixel².

    Equilateral triangles at a random angle, jittered inside their cell (1.024 px
    on a side at full size), a random depth and a random color per corner.
    """
    w, h = _size(1024, 1024, scale)
    cells = max(8, round(1000 * scale))
    rng = np.random.default_rng(TINY_SEED)
    n = cells * cells
    jy, jx = np.divmod(np.arange(n), cells)
    cell_w, cell_h = w / cells, h / cells
    centre = np.stack([(jx + rng.uniform(0.3, 0.7, n)) * cell_w, (jy + rng.uniform(0.3, 0.7, n)) * cell_h], 1)
    side = math.sqrt(4.0 / math.sqrt(3.0))                               # equilateral, area 1 pixel²
    radius = side / math.sqrt(3.0)
    theta = rng.uniform(0.0, 2.0 * np.pi, n)[:, None] + np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
    corners = centre[:, None, :] + radius * np.stack([np.cos(theta), np.sin(theta)], -1)
    depth = rng.uniform(0.05, 0.95, n)
    positions = _to_clip(corners, np.repeat(depth[:, None], 3, 1), w, h).reshape(-1, 4)
    colors = rng.uniform(0.15, 1.0, (n * 3, 3))
    draws = [dict(positions=positions, varyings={"color": colors}, depth_test="less", cull="none")]
    return Scene("tiny", w, h, draws, n, f"{n} triangles of 1 pixel^2 each, in rows, random depth, vertex colors",
                 scale=scale, shading="no vertex shader (clip coordinates given), "
                 "fragment softpipe default (varying color)")


# --------------------------------------------------------------------------
# The bunny on a plane, with and without shadow maps (issue 15)
# --------------------------------------------------------------------------

#: The shadow maps' side at scale 1 (ShadowSettings' default); it scales with the scene.
SHADOW_RESOLUTION = 1024


def _bunny_on_plane(name: str, shadows: bool) -> Callable[[float], Scene]:
    """The bunny standing on a ground plane under a sun and a spot, 1024×1024, ``phong``.

    With ``shadows`` both lights cast shadows (default :class:`ShadowSettings`: 1024²
    maps at scale 1, PCF r = 1; the ground casts none), and the scene's ``prepare``
    renders both maps in every frame and hands them to the draws' lighting uniform.
    """
    def scene(scale: float = 1.0) -> Scene:
        from softpipe.light.shadowmap import ShadowSettings
        from softpipe.scenes.scene import SceneObject
        from softpipe.scenes.shadow_pass import render_shadow_maps

        w, h = _size(1024, 1024, scale)
        mesh = load_obj(asset_path("stanford-bunny.obj", name))
        lo, hi = mesh.bounds()
        extent, centre = float(np.linalg.norm(hi - lo)), (lo + hi) / 2
        bunny_material = Material(kd=(0.75, 0.7, 0.6), ks=(0.4, 0.4, 0.4), shininess=30.0)
        ground = plane(8.0 * extent, 1, material=Material(kd=(0.55, 0.55, 0.5), ks=(0.05, 0.05, 0.05),
                                                          shininess=8.0))
        floor = np.eye(4)
        floor[:3, 3] = (centre[0], lo[1], centre[2])         # the bunny's feet touch it
        ground = ground.transformed(floor)
        vertex, fragment, notes = _program("phong", "phong", standard_vertex, blinn_phong_fragment, name)
        # frame the bunny and the ground around it, where the shadows fall
        around = np.array([extent, 0.0, extent]) * 0.6
        camera = Camera.frame((np.minimum(lo, centre - around), np.maximum(hi, centre + around)),
                              azimuth=25.0, elevation=30.0, fovy=35.0, margin=1.0)
        base = standard_uniforms(camera, w / h)
        settings = ShadowSettings(resolution=max(16, round(SHADOW_RESOLUTION * scale))) if shadows else False
        spot_at = centre + extent * np.array([-0.9, 1.7, 1.1])
        lighting = Lighting((
            Light.directional((0.5, -1.0, -0.45), diffuse=(0.75, 0.75, 0.7), specular=(0.6, 0.6, 0.6),
                              name="sun", shadows=settings),
            Light.spot(tuple(spot_at), tuple(centre - spot_at), 28.0, 2.0, diffuse=(0.6, 0.6, 0.65),
                       name="spot", shadows=settings),
        ), global_ambient=(0.12, 0.12, 0.12))
        draws = []
        for mesh_, material in ((mesh, bunny_material), (ground, ground.material)):
            u = dict(base, material=material, lighting=lighting.uniform(base["view"]))
            normals = mesh_.vertex_normals() if mesh_ is mesh else mesh_.normals
            draws.append(dict(positions=mesh_.positions, indices=mesh_.indices, attributes={"normal": normals},
                              vertex_shader=vertex, fragment_shader=fragment, uniforms=u, cull="back"))
        prepare, what = None, "no shadows"
        if shadows:
            objects = [SceneObject("bunny", mesh, np.eye(4)), SceneObject("ground", ground, np.eye(4),
                                                                          cast_shadows=False)]

            def prepare() -> Dict[str, float]:
                maps = render_shadow_maps(objects, lighting)
                lit = maps.lighting_uniform(lighting, base["view"])
                for d in draws:
                    d["uniforms"]["lighting"] = lit
                return maps.seconds                       # {"sun": s, "spot": s}
            prepare.objects, prepare.lighting = objects, lighting   # for benchmarks that take it apart
            what = (f"both casting shadows ({settings.resolution}x{settings.resolution} maps, PCF r={settings.pcf}, "
                    "made every frame; the ground casts none)")
        return Scene(name, w, h, draws, mesh.triangle_count + ground.triangle_count,
                     f"Stanford bunny ({mesh.triangle_count} triangles) on a ground plane (2), Blinn-Phong per "
                     f"fragment, a sun and a spot, {what}", notes=notes, scale=scale,
                     shading=_shader_names(vertex, fragment), prepare=prepare)
    return scene


#: name → scene function, in the issue's order.
def _bunny_aa(name: str, pattern_name: str, sample_shading: str) -> Callable[[float], Scene]:
    """The bunny at 512×512 with a sample pattern: the cost of each antialiasing mode (issue 8)."""
    from softpipe.pipeline.sampling import pattern_named

    def scene(scale: float = 1.0) -> Scene:
        base = bunny(scale * 0.5)
        pattern = pattern_named(pattern_name)
        for d in base.draws:
            d["sample_shading"] = sample_shading
        mode = "MSAA (shaded once per pixel)" if sample_shading != "sample" else "SSAA (every sample shaded)"
        return replace(base, name=name, pattern=pattern,
                       description=f"bunny at 512x512, {pattern.name}, {len(pattern)} samples, "
                                   f"{mode if len(pattern) > 1 else 'no antialiasing'}")
    return scene


# --------------------------------------------------------------------------
# Points and lines (issue 29)
# --------------------------------------------------------------------------

def unique_edges(triangles: np.ndarray) -> np.ndarray:
    """Each edge of the triangles [T, 3] once, as vertex pairs [E, 2] (lower index first), sorted."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return np.unique(np.sort(edges, axis=1), axis=0)


def bunny_wireframe(scale: float = 1.0) -> Scene:
    """The bunny's edges (each once) as ``lines`` at 1024², a color per vertex, depth LESS."""
    w, h = _size(1024, 1024, scale)
    mesh = load_obj(asset_path("stanford-bunny.obj", "bunny-wireframe"))
    camera = Camera.frame(mesh, azimuth=20.0, elevation=15.0, fovy=35.0, margin=1.05)
    base = standard_uniforms(camera, w / h)
    edges = unique_edges(mesh.indices.reshape(-1, 3))
    draws = [dict(positions=mesh.positions, indices=edges, attributes={"color": _vertex_colors(mesh.positions)},
                  vertex_shader=color_vertex, uniforms={"mvp": compose(base["projection"], base["model_view"])},
                  topology="lines")]
    return Scene("bunny-wireframe", w, h, draws, len(edges),
                 f"the bunny's {len(edges):,} edges as lines (width 1), a color per vertex", scale=scale,
                 shading=_shader_names(color_vertex, None))


POINT_CLOUD_SIZE = 200_000


def points200k(scale: float = 1.0) -> Scene:
    """200,000 points (fewer at a smaller scale) on the sphere200k sphere and in the box around it,
    size 2, a color per vertex, depth LESS, at 1024²."""
    w, h = _size(1024, 1024, scale)
    n = max(1000, round(POINT_CLOUD_SIZE * scale * scale))
    rng = np.random.default_rng(29)
    on_sphere = rng.normal(size=(n // 2, 3))
    on_sphere /= np.linalg.norm(on_sphere, axis=1, keepdims=True)
    in_box = rng.uniform(-1.6, 1.6, (n - n // 2, 3))
    positions = np.concatenate([on_sphere, in_box])
    base = standard_uniforms(SPHERE_CAMERA, w / h)
    draws = [dict(positions=positions, attributes={"color": _vertex_colors(positions)}, vertex_shader=color_vertex,
                  uniforms={"mvp": compose(base["projection"], base["model_view"])}, topology="points",
                  point_size=2.0)]
    return Scene("points200k", w, h, draws, n, f"a cloud of {n:,} points of size 2, a color per vertex",
                 scale=scale, shading=_shader_names(color_vertex, None))


FIELD_INSTANCES = 10_000


def field10k(scale: float = 1.0) -> Scene:
    """10,000 instances (fewer at a smaller scale, 100 at least) of an icosphere of 80 triangles on a square
    field, seen from above and in front, in one instanced draw (issue 31); depth LESS, back faces culled."""
    w, h = _size(1024, 1024, scale)
    side = max(10, round(math.sqrt(FIELD_INSTANCES) * scale))
    n = side * side
    ball = icosphere(0.5, 1)
    rng = np.random.default_rng(31)
    i, k = np.divmod(np.arange(n), side)
    place = np.stack([i - (side - 1) / 2, np.zeros(n), k - (side - 1) / 2], 1) + rng.uniform(-0.2, 0.2, (n, 3))
    camera = Camera(eye=(0.0, 0.55 * side, 0.85 * side), target=(0.0, 0.0, 0.05 * side), fovy=50.0, near=0.1,
                    far=3.0 * side)
    base = standard_uniforms(camera, w / h)
    draws = [dict(positions=ball.positions, indices=ball.indices, vertex_shader=instanced_vertex,
                  uniforms={"mvp": compose(base["projection"], base["model_view"])}, cull="back", instances=n,
                  instance_attributes={"place": place, "size": rng.uniform(0.6, 1.0, n),
                                       "color": rng.uniform(0.3, 1.0, (n, 3))})]
    return Scene("field10k", w, h, draws, n * ball.triangle_count,
                 f"{n:,} instances of an {ball.triangle_count}-triangle ball in one instanced draw, each placed, "
                 "sized and colored by its instance attributes", scale=scale,
                 shading=_shader_names(instanced_vertex, None))


#: The buffers ``bunny-outputs`` derives every frame (issue 31's "render with five outputs").
BENCH_OUTPUTS = ("color", "depth", "normal", "object_id", "triangle_id")


def bunny_outputs(scale: float = 1.0) -> Scene:
    """``bunny`` drawn into a framebuffer with a visibility record, then five outputs derived from it
    (:func:`softpipe.scenes.outputs.derive_outputs`: color, depth, normal, object_id, triangle_id):
    what ``render(..., outputs=...)`` adds to a frame, beside ``bunny`` for the cost. As ``bunny`` draws
    every frame into the same framebuffer, the buffers are written every frame into the same arrays
    (``out=``, the last frame's), and ``color`` is handed out uncopied, as ``render`` does."""
    from softpipe.scenes.outputs import derive_outputs
    base = bunny(scale)
    kept: Dict[str, np.ndarray] = {}

    def finish(fb) -> None:
        kept.update(derive_outputs(fb, BENCH_OUTPUTS, copy_color=False, out=kept))
    return replace(base, name="bunny-outputs", record=True, finish=finish,
                   description=base.description + "; five outputs from the visibility record: "
                   + ", ".join(BENCH_OUTPUTS))


SCENES: Dict[str, Callable[[float], Scene]] = {
    "sphere200k": sphere200k,
    "sphere200k-color": sphere200k_color,
    "bunny": bunny,
    "bunny-outputs": bunny_outputs,
    "spot-textured": spot_textured,
    "fill": fill,
    "fill-b2f": fill_b2f,
    "tiny": tiny,
    "aa-1": _bunny_aa("aa-1", "1", "sample"),
    "aa-grid4": _bunny_aa("aa-grid4", "grid4", "sample"),
    "aa-rgss4": _bunny_aa("aa-rgss4", "rgss4", "sample"),
    "aa-jitter16": _bunny_aa("aa-jitter16", "jitter16", "sample"),
    "aa-msaa4": _bunny_aa("aa-msaa4", "rgss4", "center"),
    "bunny-plane": _bunny_on_plane("bunny-plane", shadows=False),
    "bunny-shadows": _bunny_on_plane("bunny-shadows", shadows=True),
    "bunny-wireframe": bunny_wireframe,
    "points200k": points200k,
    "field10k": field10k,
}


def build_scene(name: str, scale: float = 1.0) -> Scene:
    """The scene called ``name`` at ``scale``; a ValueError lists the names otherwise."""
    if name not in SCENES:
        raise ValueError(f"unknown benchmark scene {name!r}; the scenes are: {', '.join(SCENES)}")
    return SCENES[name](scale)
