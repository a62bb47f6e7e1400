"""The same scenes three ways: the notes' simplified model, the path tracer, and what lies between them.

    python examples/three_ways.py         → out/examples/three_ways.png
    python examples/three_ways.py --docs  → also docs/images/three-ways/cornell.png, spheres.png (and the numbers)

Two scenes: Mitsuba's Cornell box (examples/cornell_box.toml), and the same box with
a mirror ball and a glass ball in place of its boxes. Each is rendered

- by the **Whitted tracer** (``raytrace_scene``, the notes' model: FORMULAS §10's
  diffuse term, §21's shadow rays, §22's ray tree), lit by the one point light the
  notes allow in place of the lamp: a spot at the lamp's centre pointing down with
  exponent 1 and cutoff 90° (so f_spot = cos θ at the lamp, as a Lambertian emitter's
  intensity falls), attenuation 1/r² (§7) and I_d = L_e·A/π (A the lamp's area; the 1/π
  because §3 has none where the BRDF kd/π has), first with no ambient term and then
  with the global ambient I_a that makes its mean equal the path tracer's;
- by the **path tracer** with paths of length 2 (``max_depth=2``: the lamp's direct
  light, soft shadows, nothing indirect) and of any length (the rendering equation);
- and as **differences**, |a − b| × 4: direct path-traced − Whitted (soft shadows and
  a lamp with area), full − direct (the indirect light: colour bleeding, the ceiling
  lit from below — what §10's and §13's ambient k_a·I_a stands in for), full − Whitted
  with the fitted ambient (what a constant cannot be).

docs/three-ways.md walks through it term by term with these pictures and the numbers
:func:`measure` prints.
"""
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import SceneObject
from softpipe.scenes.scenefile import load_scene
from softpipe.tracers.whitted import raytrace_scene

CORNELL = REPO / "examples" / "cornell_box.toml"
DOCS_IMAGES = REPO / "docs" / "images" / "three-ways"
GAIN = 4.0


def cornell(size, spheres=False):
    """The Cornell box at ``size``; ``spheres``: a mirror ball and a glass ball (ior 1.5) in place of its boxes."""
    w, h = picture_size(size)
    box = load_scene(CORNELL).replace(width=w, height=h)
    if not spheres:
        return box
    mirror = SceneObject("mirror ball", shapes.icosphere(0.35, 3, material=Material(kd=0.0, ks=0.0, kr=1.0)),
                         translate(-0.4, -0.65, -0.35))
    glass = SceneObject("glass ball", shapes.icosphere(0.35, 3, material=Material(kd=0.0, ks=0.0, kt=1.0, ior=1.5)),
                        translate(0.4, -0.65, 0.3))
    return box.replace(objects=[o for o in box.objects if "box" not in o.name] + [mirror, glass])


def lamp_as_spot(scene) -> Light:
    """The emissive objects as the notes' one point light: a spot at their centre, I_d = L_e·A/π, f_spot = cos θ."""
    area, centre, normal, power = 0.0, np.zeros(3), np.zeros(3), np.zeros(3)
    for obj in scene.objects:
        ke = np.asarray(obj.mesh.material.ke)
        if not ke.any():
            continue
        p = obj.mesh.positions @ obj.model[:3, :3].T + obj.model[:3, 3]
        t = p[np.asarray(obj.mesh.indices).reshape(-1, 3)]
        cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        a = 0.5 * np.linalg.norm(cross, axis=1)
        area += a.sum()
        centre += (a[:, None] * t.mean(axis=1)).sum(axis=0)
        normal += cross.sum(axis=0)
        power += ke * a.sum()
    centre /= area
    intensity = power / np.pi                   # L_e·A/π per channel
    # a hair below the lamp, so that the lamp itself does not shadow its light
    return Light.spot(tuple(centre + 1e-4 * normal / np.linalg.norm(normal)), tuple(normal / np.linalg.norm(normal)),
                      cutoff=90.0, exponent=1.0, diffuse=tuple(intensity), specular=(0.0, 0.0, 0.0),
                      attenuation=(0.0, 0.0, 1.0), name="lamp as a spot")


def renders(size, spp, spheres=False):
    """Linear float images [H, W, 3]: Whitted (no ambient), its ka map, the path tracer direct and full."""
    scene = cornell(size, spheres)
    whitted_scene = scene.replace(lights=(lamp_as_spot(scene),), ambient=(0.0, 0.0, 0.0))
    whitted = raytrace_scene(whitted_scene).color[..., :3].astype(np.float64)
    with_ambient = raytrace_scene(whitted_scene.replace(ambient=(1.0, 1.0, 1.0))).color[..., :3]
    ka_map = with_ambient.astype(np.float64) - whitted            # the ambient term is linear in I_a
    direct = sp.pathtrace(scene, spp, seed=1, max_depth=2)
    full = sp.pathtrace(scene, spp, seed=2)
    return {"whitted": whitted, "ka": ka_map, "direct": direct.image.astype(np.float64),
            "full": full.image.astype(np.float64), "traced": full}


def lamp_pixels(r):
    """The lamp seen directly and its edge, a pixel around (radiance ~18 there, and a pixel partly lamp
    differs by the pixel filter alone: a box over the pixel against the Whitted tracer's one ray)."""
    lamp = np.pad((r["full"].max(axis=2) > 1.5) | (r["whitted"].max(axis=2) > 1.5), 1)
    return lamp[:-2, 1:-1] | lamp[2:, 1:-1] | lamp[1:-1, :-2] | lamp[1:-1, 2:] | lamp[1:-1, 1:-1]


def fitted_ambient(r):
    """The global ambient I_a (RGB) that makes the Whitted image's mean equal the path tracer's (lamp left out)."""
    keep = ~lamp_pixels(r)
    ka = r["ka"][keep].mean(axis=0)
    return np.where(ka > 0, (r["full"][keep].mean(axis=0) - r["whitted"][keep].mean(axis=0)) / np.maximum(ka, 1e-12),
                    0.0)


def _bytes(x):
    return np.round(255.0 * np.clip(x, 0.0, 1.0)).astype(np.uint8)


def pictures(r, prefix=""):
    ambient = fitted_ambient(r)
    fitted = r["whitted"] + ambient * r["ka"]
    return {f"{prefix}Whitted, no ambient": _bytes(r["whitted"]),
            f"{prefix}Whitted + ambient": _bytes(fitted),
            f"{prefix}path traced, direct": _bytes(r["direct"]),
            f"{prefix}path traced": _bytes(r["full"]),
            f"{prefix}|direct-Whitted| x4": _bytes(GAIN * np.abs(r["direct"] - r["whitted"])),
            f"{prefix}|full-direct| x4": _bytes(GAIN * np.abs(r["full"] - r["direct"])),
            f"{prefix}|full-W+ambient| x4": _bytes(GAIN * np.abs(r["full"] - fitted))}


def measure(r):
    """The numbers docs/three-ways.md quotes: mean differences per channel and where each is largest."""
    fitted = r["whitted"] + fitted_ambient(r) * r["ka"]
    # where a difference is largest: over blocks of pixels (single pixels are Monte Carlo noise); every figure
    # leaves the lamp out (lamp_pixels)
    h, w = r["full"].shape[:2]
    b = max(2, min(h, w) // 16)
    lamp = lamp_pixels(r)
    keep = ~lamp
    lines = [f"means over the {int(keep.sum())} of {h * w} pixels off the lamp: Whitted "
             f"{_rgb(r['whitted'][keep].mean(axis=0))}, path traced direct {_rgb(r['direct'][keep].mean(axis=0))}, "
             f"full {_rgb(r['full'][keep].mean(axis=0))}; fitted ambient I_a {_rgb(fitted_ambient(r))}"]
    for label, a, c in (("direct - Whitted", r["direct"], r["whitted"]), ("full - direct", r["full"], r["direct"]),
                        ("full - (Whitted + ambient)", r["full"], fitted)):
        d = np.where(lamp[..., None], 0.0, a - c)       # 0 on the lamp, for the blocks
        blocks = d[:h - h % b, :w - w % b].reshape(h // b, b, w // b, b, 3).mean(axis=(1, 3))
        j, i = np.unravel_index(np.argmax(np.abs(blocks).sum(axis=2)), blocks.shape[:2])
        x, y = int(i * b + b // 2), int(j * b + b // 2)
        where = r["traced"].path_story(x, y, sample=0)[0].bounces[0].object or "background"
        lines.append(f"{label}: mean {_rgb(d[keep].mean(axis=0))}, mean |d| {_rgb(np.abs(d[keep]).mean(axis=0))}; "
                     f"largest {b}×{b} block around pixel ({x}, {y}), on {where!r}: "
                     f"{_rgb(blocks[j, i])}")
    return lines


def _rgb(v):
    return "(" + ", ".join(f"{c:+.4f}" for c in v) + ")"


def sheet(size=96, spp=None):
    """Seven pictures per scene (the Cornell box, then the balls); ``spp`` defaults to 4 below 64 pixels, else 64."""
    spp = spp or (4 if min(picture_size(size)) < 64 else 64)
    out = pictures(renders(size, spp))
    out.update(pictures(renders(size, spp, spheres=True), prefix="balls: "))
    return out


def write_docs_pictures(size=128, spp=256):
    """docs/images/three-ways/{cornell,spheres}.png, and the numbers for docs/three-ways.md printed."""
    for name, spheres in (("cornell", False), ("spheres", True)):
        r = renders(size, spp, spheres)
        save_docs_sheet(DOCS_IMAGES / f"{name}.png", pictures(r), 4)
        print(f"{name}, {size}×{size}, {spp} spp:")
        for line in measure(r):
            print("  " + line)


def main(size=96, out_dir=None):
    return save_sheet("three_ways", sheet(size), 7, "The notes' model (Whitted, a point light, an ambient term), "
                      "the path tracer, and their differences x4: the Cornell box, then a mirror and a glass ball",
                      out_dir)


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
