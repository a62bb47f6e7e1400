"""Shadows from the outside: scenes, scene files, the command line, the demo, pixel history and pictures.

The geometry of shadows (which pixels, bias, PCF, cube faces, glass) is tested in
test_shadows.py; here, that each way in turns them on, and that what a user looks at
(the stage pictures, pixel history) shows the shadow term (FORMULAS §21).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject, ground_object
from softpipe.scenes.scenefile import SceneError, parse_scene
from softpipe.tools.cli import main

SUN = (0.3, -1.0, -0.2)


def box_over_floor(shadows: bool, **settings) -> Scene:
    """A box floating over a floor, one sun; a small orthographic-looking view from above."""
    floor = shapes.plane(6.0, material=Material(ka=0.2, kd=0.8, ks=0.0))
    box = shapes.cube(1.0, material=Material(kd=(0.8, 0.3, 0.2)))
    sun = Light.directional(SUN, shadows=ShadowSettings(**settings) if shadows else None, name="sun")
    return Scene([SceneObject("floor", floor, np.eye(4), cast_shadows=False),
                  SceneObject("box", box, translate(0.0, 1.5, 0.0))],
                 camera=sp.Camera(eye=(0.0, 8.0, 0.01), target=(0.0, 0.0, 0.0), fovy=45.0),
                 lights=(sun,), width=64, height=64)


def test_shadows_only_ever_take_light_away():
    """Every pixel with shadows is at most the same pixel without (V_j ≤ 1 multiplies diffuse and specular),
    and the floor under the box is darker: the shadow is there."""
    lit = sp.render_scene(box_over_floor(False)).color
    shadowed = sp.render_scene(box_over_floor(True)).color
    assert np.all(shadowed <= lit)
    darker = (lit - shadowed)[..., :3].max(axis=2) > 0.1
    assert 20 <= darker.sum() <= 64 * 64 // 4, darker.sum()


def test_pixel_history_shows_each_lights_visibility_at_the_fragment():
    """In pixel history, the column 'shadow V_j': 0 for the sun at a floor pixel in the shadow, 1 in the light,
    equal to ShadowMaps.visibility at the fragment's world point."""
    scene = box_over_floor(True, pcf=0)
    results, maps = [], []
    fb = sp.render_scene(scene, trace=True, results=results, shadow_maps=maps)
    floor_trace = results[0].trace
    lit = sp.render_scene(box_over_floor(False)).color
    darker = (lit - fb.color)[..., :3].max(axis=2) > 0.1
    row, col = np.argwhere(darker)[len(np.argwhere(darker)) // 2]
    inside = floor_trace.pixel_history(int(col), int(row))            # (x, image row), as fb.color
    assert [e.shadow for e in inside] == [((0.0, 0.0, 0.0),)]
    assert "shadow V_j" in str(inside)
    floor_lit = np.argwhere(~darker & np.isclose(lit[..., 0], lit[32, 8, 0]))[0]
    outside = floor_trace.pixel_history(int(floor_lit[1]), int(floor_lit[0]))
    assert [e.shadow for e in outside] == [((1.0, 1.0, 1.0),)]
    # the same number from the maps, at the fragment's point in world space
    P = np.append(inside[0].varyings.position, 1.0)
    world = np.linalg.inv(scene.camera.view) @ P
    assert maps[0].visibility(0, world[:3]) == (0.0, 0.0, 0.0)


def test_pixel_history_without_shadow_maps_has_no_shadow_column():
    results = []
    sp.render_scene(box_over_floor(False), trace=True, results=results)
    history = results[0].trace.pixel_history(8, 32)
    assert history[0].shadow == () and "shadow V_j" not in str(history)


def test_stage_pictures_show_each_shadow_map(tmp_path):
    """The trace's pictures gain one per map, named by light (and cube face), showing where casters are."""
    scene = box_over_floor(True)
    scene = scene.replace(lights=scene.lights + (Light.point((0.0, 4.0, 0.0), shadows=True, name="bulb"),))
    results = []
    sp.render_scene(scene, trace=True, results=results)
    pics = results[0].trace.pictures()
    names = [n for n in pics if n.startswith("shadow map")]
    assert names[0] == "shadow map 0, light 0"
    assert names[1:] == [f"shadow map {k}, light 1, face {f}" for k, f in
                         zip(range(1, 7), ("+x", "-x", "+y", "-y", "+z", "-z"))]
    sun_map = pics[names[0]]
    assert sun_map.shape == (64, 64, 3)
    assert (sun_map == 255).any() and ((sun_map > 24) & (sun_map < 255)).any()      # empty texels and the box
    down = pics["shadow map 4, light 1, face -y"]       # the bulb looks down on the box: it fills the middle
    assert down[32, 32, 0] < 255
    written = results[0].trace.save_pictures(tmp_path)
    assert written["shadow map 0, light 0"].name == "07-shadow-map-0-light-0.png"


def test_scene_shadows_turns_on_every_light_and_keeps_their_own_settings():
    own = ShadowSettings(resolution=256, pcf=2)
    scene = Scene(lights=(Light.directional(SUN, name="a"), Light.point((0, 3, 0), shadows=own, name="b")),
                  shadows=True)
    lights = scene.lighting_for(sp.Camera()).lights
    assert lights[0].shadows == ShadowSettings() and lights[1].shadows is own


def test_the_ground_stands_under_the_model_and_is_left_out_of_the_framing():
    scene = Scene.from_model("suzanne", width=64, height=48)
    camera = scene.view_camera()
    ground = ground_object(scene, camera)
    lowest = scene.world_points()[:, 1].min()
    assert np.allclose(ground.world_positions()[:, 1], lowest)
    assert not ground.cast_shadows
    with_ground = scene.replace(ground=True)
    assert with_ground.view_camera() == camera                      # framing ignores the ground
    assert [o.name for o in with_ground.drawn_objects(camera)][-1] == "ground"


SCENE = """
[render]
width = 32
height = 24
shadows = {shadows}
ground = true
[[lights]]
kind = "directional"
direction = [0.3, -1, -0.2]
shadows = {{ resolution = 256, pcf = 0, offset_factor = 3, offset_units = 8 }}
[[lights]]
kind = "point"
position = [0, 3, 0]
[[meshes]]
shape = "cube"
cast_shadows = false
"""


def test_scene_files_read_every_shadow_key():
    scene = parse_scene(SCENE.format(shadows="false"))
    assert scene.lights[0].shadows == ShadowSettings(resolution=256, pcf=0, offset_factor=3.0, offset_units=8.0)
    assert scene.lights[1].shadows is None
    assert scene.ground and not scene.shadows
    assert [o.cast_shadows for o in scene.objects] == [False]
    assert parse_scene(SCENE.format(shadows="true")).shadows


@pytest.mark.parametrize("change, message", [
    (("resolution = 256", "resolution = 0"), "ShadowSettings.resolution must be an integer in 1…8192, got 0"),
    (("pcf = 0", "pfc = 0"), "unknown key 'pfc' in [[lights]] #1 shadows (did you mean 'pcf'?)"),
    (("shadows = {{", "shadows = 'yes' #"), "key 'shadows' in [[lights]] #1 must be true, false or a table"),
    (("cast_shadows = false", "cast_shadows = 1"), "key 'cast_shadows' in [[meshes]] #1"),
    (("ground = true", "ground = 'floor'"), "key 'ground' in [render]"),
])
def test_scene_file_shadow_mistakes_name_the_table_and_key(change, message):
    text = SCENE.replace(*change).format(shadows="false")
    with pytest.raises(SceneError) as e:
        parse_scene(text, "s.toml")
    assert message in str(e.value) and str(e.value).startswith("s.toml")


def test_render_shadows_on_the_command_line(tmp_path, capsys):
    """`softpipe render MODEL --shadows` stands the model on a floor and darkens part of it, never lightening."""
    out_plain, out_shadow = tmp_path / "plain.png", tmp_path / "shadow.png"
    assert main(["render", "suzanne", "--size", "64x48", "-q", "-o", str(out_shadow), "--shadows"]) == 0
    plain = sp.render(Scene.from_model("suzanne", width=64, height=48).replace(ground=True))
    plain.save(out_plain)
    shadowed = sp.render("suzanne", width=64, height=48, shadows=True)
    assert np.array_equal(np.asarray(shadowed), np.asarray(__import__("PIL.Image").Image.open(out_shadow)))
    assert np.all(shadowed.color <= plain.color)
    assert ((plain.color - shadowed.color)[..., :3].max(axis=2) > 0.05).sum() > 10


def test_demo_draws_shadows_unless_told_not_to(tmp_path, capsys):
    from softpipe.tools.demo import render_demo
    with_shadows = render_demo(96, 72)
    without = render_demo(96, 72, shadows=False)
    assert np.all(with_shadows.color <= without.color)
    assert ((without.color - with_shadows.color)[..., :3].max(axis=2) > 0.05).sum() > 20
    assert main(["demo", "--width", "96", "--height", "72", "--no-shadows", "-o", str(tmp_path / "d.png")]) == 0
    assert np.array_equal(np.asarray(without), np.asarray(__import__("PIL.Image").Image.open(tmp_path / "d.png")))


def test_lights_compare_by_their_shadow_settings():
    a = Light.directional(SUN, shadows=True)
    assert a == dataclasses.replace(Light.directional(SUN), shadows=ShadowSettings())
    assert a != Light.directional(SUN)


def test_shadow_rays_and_shadow_maps_agree_away_from_the_edges():
    """ShadowSettings(method="ray") (FORMULAS §21 itself) against the map: the same shadow, except a band of a
    pixel or two at its edge, where the map's PCF softens and its bias moves it."""
    maps = sp.render_scene(box_over_floor(True, pcf=0)).color
    rays = sp.render_scene(box_over_floor(True, method="ray")).color
    lit = sp.render_scene(box_over_floor(False)).color
    dark_maps = (lit - maps)[..., :3].max(axis=2) > 0.1
    dark_rays = (lit - rays)[..., :3].max(axis=2) > 0.1
    assert dark_rays.sum() > 20
    differ = dark_maps != dark_rays
    edge = np.zeros_like(dark_rays)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            edge |= np.roll(np.roll(dark_rays, dy, 0), dx, 1) != dark_rays
    assert not (differ & ~edge).any()


def test_a_shadow_ray_is_dimmed_by_every_transparent_object_it_crosses():
    floor = shapes.plane(4.0, material=Material(ka=0.2, kd=0.8, ks=0.0))
    panes = [shapes.cube(1.0, material=Material(kd=0.1, kt=kt)) for kt in ((0.9, 0.3, 0.2), (0.2, 0.4, 0.9))]
    wall = shapes.cube(1.0, material=Material(kd=0.5))
    sun = Light.directional((0.0, -1.0, 0.0), shadows=ShadowSettings(method="ray"), name="sun")
    flat = np.diag([1.0, 0.1, 1.0, 1.0])
    scene = Scene([SceneObject("floor", floor, np.eye(4), cast_shadows=False),
                   SceneObject("red", panes[0], translate(0.0, 1.0, 0.0) @ flat),
                   SceneObject("blue", panes[1], translate(0.25, 1.5, 0.0) @ flat),
                   SceneObject("wall", wall, translate(-1.5, 1.0, 0.0) @ flat)],
                  camera=sp.Camera(eye=(0.0, 6.0, 0.01)), lights=(sun,), width=8, height=8)
    maps = []
    sp.render_scene(scene, shadow_maps=maps)
    V = maps[0].visibility
    assert V(0, (-0.4, 0.0, 0.0)) == pytest.approx((0.9, 0.3, 0.2))
    assert V(0, (0.0, 0.0, 0.0)) == pytest.approx((0.9 * 0.2, 0.3 * 0.4, 0.2 * 0.9))
    assert V(0, (0.6, 0.0, 0.0)) == pytest.approx((0.2, 0.4, 0.9))
    assert V(0, (-1.5, 0.0, 0.0)) == (0.0, 0.0, 0.0)            # the opaque wall
    assert V(0, (1.5, 0.0, 0.0)) == (1.0, 1.0, 1.0)


def test_ray_shadows_give_the_same_bytes_on_both_paths():
    scene = box_over_floor(True, method="ray")
    camera, lights = scene.camera, scene.lighting_for(scene.camera)
    maps = sp.render_shadow_maps(scene.objects, lights)
    lighting = maps.lighting_uniform(lights, camera.view)
    out = {}
    for path in ("fast", "reference"):
        fb = sp.Framebuffer(64, 64)
        for obj in scene.objects:
            sp.draw_mesh(fb, obj.mesh, camera, "phong", model=obj.model, lighting=lighting, path=path)
        out[path] = (fb.color.tobytes(), fb.depth.tobytes())
    assert out["fast"] == out["reference"]


def test_lighting_without_shadows_compiles_them_out_and_draws_the_same_bytes():
    """shadows=None (the default uniform) and an empty ShadowUniform (every light without a map) are two types, two
    compiled variants; both draw the same picture."""
    from softpipe.light.shadowmap import no_shadows
    scene = box_over_floor(False)
    lighting = scene.lighting_for(scene.camera).uniform(scene.camera.view)
    assert lighting.shadows is None
    pictures = []
    for shadows in (None, no_shadows(1)):
        fb = sp.Framebuffer(64, 64)
        for obj in scene.objects:
            sp.draw_mesh(fb, obj.mesh, scene.camera, "phong", model=obj.model, lighting=lighting._replace(shadows=shadows))
        pictures.append(fb.color.tobytes())
    assert pictures[0] == pictures[1]
