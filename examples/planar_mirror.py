"""A wall mirror drawn three ways: the stencil buffer, a cube map, the ray tracer (FORMULAS §10, §13, §16, §21).

    python examples/planar_mirror.py           → out/examples/planar_mirror.png
    python examples/planar_mirror.py --docs    → also docs/images/planar-mirror/steps.png, methods.png

Two balls and a ring in front of a wall mirror (kr 0.85, no diffuse or specular
light of its own, so no shadow can fall on it). (a)–(d) the four passes of
:func:`softpipe.scenes.planar_mirror.render_planar_mirror`: the stencil after the mirror
is marked, the reflected scene drawn through it, the mirror blended over it with kr,
the scene drawn normally. (e) the same scene ray traced (:func:`softpipe.tracers.whitted.raytrace_scene`);
(f) the ``mirror`` program with the mirror's dynamic cube map
(:func:`softpipe.scenes.environment_pass.dynamic_environments`, drawn from the mirror's
centre); (g), (h) where the stencil mirror differs from them by more than 1/255, ×8,
the edge band (:func:`edge_band`) drawn dark blue. The numbers are printed
(:func:`measure`) and stated in docs/planar-mirror.md.
"""
import dataclasses
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet

from softpipe.light.material import Light, Material
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.transforms import rotate_x, scale, translate
from softpipe.programs import environment  # noqa: F401  (registers the programs mirror and glass)
from softpipe.scenes import shapes
from softpipe.scenes.environment_pass import dynamic_environments, render_with_environments
from softpipe.scenes.planar_mirror import render_planar_mirror
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "planar-mirror"

#: The mirror: kr only, and a little ambient so its glass has a tint (no kd, ks: no shadow can fall on it).
MIRROR = Material(ka=0.1, kd=0.0, ks=0.0, kr=(0.85, 0.85, 0.85))
RED = Material(ka=0.2, kd=(0.85, 0.15, 0.1), ks=0.5, shininess=40.0)
BLUE = Material(ka=0.2, kd=(0.15, 0.3, 0.9), ks=0.5, shininess=40.0)
GOLD = Material(ka=0.2, kd=(0.9, 0.7, 0.15), ks=0.4, shininess=30.0)
MIRROR_CENTRE = (0.0, 1.0, -1.5)
SKY = (0.55, 0.65, 0.8, 1.0)
CAMERA = Camera(eye=(1.6, 1.7, 5.5), target=(0.0, 0.9, -1.0), fovy=40.0)


def scene(size=(160, 120)) -> Scene:
    """The wall mirror (a 4.8 × 2.4 quad in the plane z = −1.5, drawn with the program ``mirror``), two balls and
    a ring in front of it."""
    width, height = picture_size(size)
    wall = translate(0.0, 1.0, -1.5) @ rotate_x(90.0) @ scale(1.2, 1.0, 0.6)
    objects = [SceneObject("mirror", shapes.plane(4.0, material=MIRROR), wall, program="mirror"),
               SceneObject("red ball", shapes.uv_sphere(0.5, 48, 24, material=RED), translate(-0.9, 0.8, 0.3)),
               SceneObject("blue ball", shapes.uv_sphere(0.4, 48, 24, material=BLUE), translate(1.1, 0.5, 1.2)),
               SceneObject("gold ring", shapes.torus(0.45, 0.15, 48, 24, material=GOLD),
                           translate(0.4, 1.5, -0.4) @ rotate_x(70.0))]
    sun = Light.directional((-0.5, -0.6, -0.6), name="sun")
    lamp = Light.point((2.0, 2.5, 3.0), diffuse=(0.5, 0.5, 0.5), specular=(0.5, 0.5, 0.5), name="lamp")
    return Scene(objects, camera=CAMERA, lights=(sun, lamp), width=width, height=height, background=SKY)


def id_scene(s: Scene) -> Scene:
    """``s`` with every object glowing one flat color (ke only) and the mirror a perfect one (kr 1, nothing else).

    Rendered, each pixel shows which object its (reflected) ray meets: the edges of
    that picture are the silhouettes, seen directly or in the mirror."""
    colors = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0), (1.0, 0.0, 1.0), (0.0, 1.0, 1.0)]
    objects = []
    for k, o in enumerate(s.objects):
        flat = (Material(ka=0.0, kd=0.0, ks=0.0, kr=(1.0, 1.0, 1.0)) if o.program == "mirror" else
                Material(ka=0.0, kd=0.0, ks=0.0, ke=colors[k % len(colors)]))
        objects.append(dataclasses.replace(o, mesh=o.mesh.replace(material=flat)))
    return s.replace(objects=objects, background=(0.5, 0.5, 0.5, 1.0))


def _changes_nearby(a: np.ndarray) -> np.ndarray:
    """True where a pixel's 3 × 3 neighbourhood holds another value than the pixel's."""
    h, w = a.shape
    p = np.pad(a, 1, mode="edge")
    out = np.zeros(a.shape, bool)
    for dy in range(3):
        for dx in range(3):
            out |= p[dy:dy + h, dx:dx + w] != a
    return out


def object_ids(s: Scene) -> np.ndarray:
    """[H, W] int: which object each pixel's (reflected) ray meets, as a packed color of :func:`id_scene`."""
    ids = render_planar_mirror(id_scene(s)).to_uint8(alpha=False).astype(np.int64)
    return (ids[..., 0] << 16) | (ids[..., 1] << 8) | ids[..., 2]


#: :func:`object_ids` where a ray meets nothing (id_scene's background, 0.5 gray).
NOTHING = (128 << 16) | (128 << 8) | 128


def edge_band(s: Scene, stencil: np.ndarray, ids=None) -> np.ndarray:
    """The pixels within one pixel of an edge: the mirror's outline (``stencil``'s) or a silhouette (:func:`id_scene`)."""
    key = object_ids(s) if ids is None else ids
    return _changes_nearby(key) | _changes_nearby(stencil == 1)


def measure(s: Scene, cube_size: int = 128) -> dict:
    """The three pictures, the mirror's pixels, the edge band and the differences (in 1/255), as a dict."""
    steps = {}
    stencil = render_planar_mirror(s, steps=steps)
    traced = raytrace_scene(s)
    cube = render_with_environments(s, dynamic_environments(s, cube_size))
    a, b, c = (fb.to_uint8(alpha=False).astype(np.int64) for fb in (stencil, traced, cube))
    inside = steps["stencil"] == 1
    ids = object_ids(s)
    band = edge_band(s, steps["stencil"], ids)
    out = {"steps": steps, "stencil": a, "traced": b, "cube": c, "inside": inside, "band": band}
    for name, other in (("traced", b), ("cube", c)):
        d = np.abs(a - other).max(axis=-1)
        out[f"diff_{name}"] = d
        out[f"{name}_inside"] = int((d[inside] > 1).sum())
        out[f"{name}_off_band"] = int((d[inside & ~band] > 1).sum())
        out[f"{name}_max"] = int(d[inside].max())
        out[f"{name}_max_off_band"] = int(d[inside & ~band].max())
        out[f"{name}_outside"] = int((d[~inside] > 1).sum())
    sky = inside & ~band & (ids == NOTHING)          # the reflected ray meets nothing: the sky, infinitely far
    near = inside & ~band & (ids != NOTHING)         # it meets an object, 1 to 3 units away
    d = out["diff_cube"]
    out["cube_sky"], out["cube_sky_differ"] = int(sky.sum()), int((d[sky] > 1).sum())
    out["cube_near"], out["cube_near_differ"] = int(near.sum()), int((d[near] > 1).sum())
    out["by_distance"] = parallax(s, d, inside)
    return out


def parallax(s: Scene, diff: np.ndarray, inside: np.ndarray, rings=(0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 3.0)):
    """The cube map's error against the distance of the mirror point (where the pixel's ray meets the
    mirror) from the map's centre (the mirror's centre): [(from, to, pixels, share differing by > 1/255, mean)]."""
    cam = s.camera
    unproject = np.linalg.inv(cam.projection(s.width / s.height) @ cam.view)
    rows, cols = np.nonzero(inside)
    x = 2.0 * (cols + 0.5) / s.width - 1.0
    y = 1.0 - 2.0 * (rows + 0.5) / s.height
    far = np.stack([x, y, np.ones_like(x), np.ones_like(x)], -1) @ unproject.T
    d = far[:, :3] / far[:, 3:] - np.asarray(cam.eye)
    t = (-1.5 - cam.eye[2]) / d[:, 2]                 # the mirror is z = -1.5
    r = np.linalg.norm(np.asarray(cam.eye) + t[:, None] * d - MIRROR_CENTRE, axis=1)
    e = diff[rows, cols]
    table = []
    for lo, hi in zip(rings[:-1], rings[1:]):
        sel = (r >= lo) & (r < hi)
        if sel.any():
            table.append((lo, hi, int(sel.sum()), float((e[sel] > 1).mean()), float(e[sel].mean())))
    return table


def differences(m: dict, name: str) -> np.ndarray:
    """|stencil − other| × 8 (gray), the edge band dark blue where nothing differs there."""
    d = np.clip(m[f"diff_{name}"] * 8, 0, 255).astype(np.uint8)
    picture = np.repeat(d[..., None], 3, axis=-1)
    picture[m["band"] & (d == 0)] = (0, 0, 90)
    return picture


def sheet(size=(160, 120), found=None):
    """The eight pictures: the four passes, the ray tracer, the cube map, the two differences."""
    m = measure(scene(size), cube_size=max(16, picture_size(size)[0] // 2))
    if found is not None:
        found.update(m)
    stencil = np.repeat((m["steps"]["stencil"] == 1)[..., None] * np.uint8(255), 3, axis=-1)
    return {"(a) 1: stencil = 1 on the mirror": stencil,
            "(b) 2: reflected scene, stencil = 1": m["steps"]["reflection"],
            "(c) 3: mirror, src + kr * dst": m["steps"]["mirror"],
            "(d) 4: the scene: stencil mirror": m["steps"]["scene"],
            "(e) ray traced (Whitted)": m["traced"].astype(np.uint8),
            "(f) mirror program, cube map": m["cube"].astype(np.uint8),
            "(g) |d - e| x 8": differences(m, "traced"),
            "(h) |d - f| x 8": differences(m, "cube")}


def report(m: dict) -> str:
    lines = [f"mirror pixels: {int(m['inside'].sum())}, of them in the edge band: {int((m['inside'] & m['band']).sum())}"]
    for name in ("traced", "cube"):
        lines.append(f"{name}: {m[f'{name}_inside']} mirror pixels differ by > 1/255 (at most "
                     f"{m[f'{name}_max']}/255); off the edge band {m[f'{name}_off_band']} (at most "
                     f"{m[f'{name}_max_off_band']}/255); outside the mirror {m[f'{name}_outside']}")
    lines.append(f"cube map off the edge band: where the reflection is the sky {m['cube_sky_differ']} of "
                 f"{m['cube_sky']} pixels differ; where it is an object {m['cube_near_differ']} of {m['cube_near']}")
    for lo, hi, n, share, mean in m["by_distance"]:
        lines.append(f"cube map, mirror points {lo:g}-{hi:g} from its centre: {n} pixels, {100 * share:.0f} % "
                     f"differ, mean {mean:.1f}/255")
    return "\n".join(lines)


def write_docs_pictures(size=(160, 120)):
    """docs/images/planar-mirror/steps.png (a–d) and methods.png (d–h); prints the numbers."""
    found = {}
    pictures = sheet(size, found)
    names = list(pictures)
    save_docs_sheet(DOCS_IMAGES / "steps.png", {k: pictures[k] for k in names[:4]}, 4)
    save_docs_sheet(DOCS_IMAGES / "methods.png", {k: pictures[k] for k in names[3:]}, 5)
    print(report(found))


def main(size=(160, 120), out_dir=None):
    found = {}
    path = save_sheet("planar_mirror", sheet(size, found), 4, "A wall mirror: the stencil buffer's four passes; "
                      "ray traced; cube map; differences x8 (FORMULAS 10, 13, 16)", out_dir)
    print(report(found))
    return path


if __name__ == "__main__":
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
    else:
        main()
