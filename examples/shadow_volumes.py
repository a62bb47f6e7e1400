"""Stencil shadow volumes, z-pass and z-fail, beside shadow rays and shadow maps (FORMULAS §21).

    python examples/shadow_volumes.py          → out/examples/shadow_volumes.png, and the agreement figures printed
    python examples/shadow_volumes.py --docs   → also docs/images/shadow-volumes/figure.png and volume.png

A ball and a box over a floor under one point light, one Scene drawn three ways: ray
traced (shadow rays, §21), rasterized with a shadow map (``ShadowSettings()``, PCF radius
1), and rasterized with stencil shadow volumes (z-fail;
:func:`softpipe.scenes.shadow_volumes.render_shadow_volumes`). Then the pixels each method
puts in shadow, against the shadow rays': white both, red only the rays, blue only the
other method — z-pass, z-fail and the shadow map.

The last row puts the eye *inside* a shadow volume: under a roof, looking out at a ball.
z-pass starts counting at the eye, which is already in the roof's shadow, so every count
is one too low — lit reads as shadowed and shadowed as lit; z-fail counts behind the
visible point, toward infinity, and does not care where the eye is.
"""
import sys

import numpy as np
from common import REPO, picture_size, save_docs_sheet, save_sheet

from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.camera import Camera
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.transforms import compose, rotate_y, scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.drawing import render_scene, standard_uniforms
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.scenes.shadow_masks import compare_masks, shadow_mask
from softpipe.scenes.shadow_volumes import ShadowVolumeResult, render_shadow_volumes, shadow_volume, volume_vertex
from softpipe.scenes.silhouette import light_vector
from softpipe.tracers.whitted import raytrace_scene

DOCS_IMAGES = REPO / "docs" / "images" / "shadow-volumes"
BACKGROUND = (0.06, 0.07, 0.09, 1.0)
FLOOR = Material(ka=0.25, kd=(0.78, 0.76, 0.72), ks=0.0)
BALL = Material(ka=0.2, kd=(0.8, 0.3, 0.2), ks=0.3, shininess=30.0)
BOX = Material(ka=0.2, kd=(0.25, 0.55, 0.85), ks=0.2, shininess=20.0)
ROOF = Material(ka=0.2, kd=(0.7, 0.65, 0.35), ks=0.0)


def outside_scene(size):
    """The ball and the box over a floor, the eye well outside every shadow volume."""
    width, height = picture_size(size)
    objects = [SceneObject("floor", shapes.plane(size=10.0, material=FLOOR), np.eye(4), cast_shadows=False),
               SceneObject("ball", shapes.uv_sphere(0.6, 32, 16, material=BALL), translate(-0.8, 0.9, 0.2)),
               SceneObject("box", shapes.cube(0.9, material=BOX), compose(translate(0.9, 0.45, -0.3), rotate_y(30.0)))]
    camera = Camera(eye=(0.0, 3.5, 5.5), target=(0.0, 0.4, 0.0), fovy=40.0, near=0.5, far=30.0)
    return Scene(objects, camera=camera, lights=(Light.point((1.5, 4.0, 2.0), name="bulb"),),
                 ambient=(0.15, 0.15, 0.15), width=width, height=height, background=BACKGROUND)


def inside_scene(size):
    """The eye under a roof, in the roof's shadow, looking out at a ball on a lit floor."""
    width, height = picture_size(size)
    objects = [SceneObject("floor", shapes.plane(size=16.0, material=FLOOR), np.eye(4), cast_shadows=False),
               SceneObject("roof", shapes.cube(1.0, material=ROOF), compose(translate(0.0, 2.5, 0.0),
                                                                           scale(3.0, 0.2, 3.0))),
               SceneObject("ball", shapes.uv_sphere(0.6, 32, 16, material=BALL), translate(0.6, 0.6, -4.2))]
    camera = Camera(eye=(0.0, 1.2, 0.5), target=(0.0, 0.3, -4.0), fovy=60.0, near=0.1, far=30.0)
    return Scene(objects, camera=camera, lights=(Light.point((0.0, 6.0, 0.5), name="bulb"),),
                 ambient=(0.15, 0.15, 0.15), width=width, height=height, background=BACKGROUND)


def mask_picture(reference, other, covered):
    """White: both in shadow; red: only the reference; blue: only the other; gray: lit floor and objects."""
    out = np.zeros(reference.shape + (3,), np.uint8)
    out[covered] = (70, 70, 70)
    out[reference & other] = (255, 255, 255)
    out[reference & ~other] = (230, 40, 40)
    out[~reference & other & covered] = (60, 110, 255)
    return out


def volume_masks(scene, method):
    """(picture, shadow mask, covered) of ``scene`` drawn with shadow volumes by ``method``."""
    found = ShadowVolumeResult(method)
    picture = render_shadow_volumes(scene, method=method, result=found).to_uint8(alpha=False)
    return picture, found.shadowed[0], found.covered


def sheet(size=200, figures=None):
    """Row 1 the three renderers; row 2 their shadows against the rays'; row 3 the eye inside a volume."""
    scene = outside_scene(size)
    covered, rays = shadow_mask(scene, 0, "ray")
    _, maps = shadow_mask(scene, 0, "map", settings=ShadowSettings())
    zfail_picture, zfail, _ = volume_masks(scene, "zfail")
    _, zpass, _ = volume_masks(scene, "zpass")
    map_scene = scene.replace(lights=(Light.point((1.5, 4.0, 2.0), name="bulb", shadows=True),))
    inside = inside_scene(size)
    in_covered, in_rays = shadow_mask(inside, 0, "ray")
    in_zpass_picture, in_zpass, _ = volume_masks(inside, "zpass")
    in_zfail_picture, in_zfail, _ = volume_masks(inside, "zfail")
    if figures is not None:
        for name, other, cov, ref in (("z-pass", zpass, covered, rays), ("z-fail", zfail, covered, rays),
                                      ("shadow map", maps, covered, rays),
                                      ("eye inside: z-pass", in_zpass, in_covered, in_rays),
                                      ("eye inside: z-fail", in_zfail, in_covered, in_rays)):
            figures[name] = compare_masks(ref, other, cov, width=1)
        figures["covered"] = int(covered.sum())
        figures["in shadow (rays)"] = int(rays.sum())
    return {
        "ray traced (shadow rays)": raytrace_scene(scene, max_depth=0).to_uint8(alpha=False),
        "shadow map (PCF 1)": render_scene(map_scene).to_uint8(alpha=False),
        "shadow volumes (z-fail)": zfail_picture,
        "z-pass vs rays": mask_picture(rays, zpass, covered),
        "z-fail vs rays": mask_picture(rays, zfail, covered),
        "shadow map vs rays": mask_picture(rays, maps, covered),
        "eye inside: z-pass": in_zpass_picture,
        "eye inside: z-fail": in_zfail_picture,
        "eye inside: z-pass vs rays": mask_picture(in_rays, in_zpass, in_covered),
    }


def report(figures):
    """The agreement figures, one line per method."""
    lines = [f"{figures['covered']} covered pixels, {figures['in shadow (rays)']} in shadow by shadow rays"]
    for name, c in figures.items():
        if not hasattr(c, "count"):
            continue
        needed = "no band holds them" if c.needed is None else f"all within {c.needed} px of a shadow edge"
        lines.append(f"{name:>20}: {c.count:5d} pixels differ from the rays, {c.count_outside:5d} outside the "
                     f"1-pixel band; {needed}")
    return "\n".join(lines)


def volume_picture(size, caps=False):
    """The outside scene with its shadow volumes drawn over it, translucent: what the stencil counts."""
    scene = outside_scene(size)
    camera = scene.view_camera()
    fb = render_scene(scene.replace(lights=(Light.point((1.5, 4.0, 2.0), name="bulb", shadows=True),)))
    aspect = scene.width / scene.height
    light = scene.lighting_for(camera).lights[0]

    def tint(varyings, uniforms, frag):
        return (1.0, 0.85, 0.2, 0.22) if frag.front_facing else (0.2, 0.85, 1.0, 0.22)

    for obj in scene.objects:
        if not obj.cast_shadows:
            continue
        volume = shadow_volume(obj.mesh, light_vector(light, obj.model))
        u = standard_uniforms(camera, aspect, obj.model)
        # the camera's own projection, as render_scene drew the depths with: the sides end at its far plane
        DrawCall(fb, volume.positions, volume.triangles(caps=caps), None, volume_vertex, tint,
                 {"model_view": u["model_view"], "projection": u["projection"]}, cull="none", depth_test="less",
                 depth_write=False, blend="alpha").run()
    return fb.to_uint8(alpha=False)


def write_docs_pictures(size=(240, 180)):
    """docs/images/shadow-volumes/figure.png (the sheet) and volume.png; prints the figures the docs page quotes."""
    figures = {}
    pictures = sheet(size, figures)
    save_docs_sheet(DOCS_IMAGES / "figure.png", pictures, 3)
    save_docs_sheet(DOCS_IMAGES / "volume.png", {"the volumes' sides over the scene (front faces yellow, back "
                                                 "faces blue)": volume_picture((480, 360))}, 1)
    print(report(figures))


def main(size=200, out_dir=None):
    figures = {}
    path = save_sheet("shadow_volumes", sheet(size, figures), 3,
                      "Shadow rays, a shadow map, stencil shadow volumes; the eye inside a volume (FORMULAS 21)",
                      out_dir)
    print(report(figures))
    return path


if __name__ == "__main__":
    main()
    if "--docs" in sys.argv[1:]:
        write_docs_pictures()
