"""The Whitted ray tracer (FORMULAS §11, §16–§23) and ray queries from shaders.

The expected answers are computed here: the rasterizer's picture of the same scene
(the same lighting functions, shadow rays for V_j), mirror geometry by hand, Snell's
law on the recorded rays.
"""
from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
import pytest
from PIL import Image

import softpipe as sp
from softpipe.light.material import Light, Lighting, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.transforms import translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject, studio_lights
from softpipe.tools.cli import main
from softpipe.tracers.whitted import RAY_KINDS, ray_tree, raytrace_scene

RAYS = ShadowSettings(method="ray")


def model_on_ground(model: str, width=96, height=72) -> Scene:
    """A bundled model on the ground under the studio lights, every light's V_j from a shadow ray."""
    scene = Scene.from_model(model, width=width, height=height).replace(ground=True)
    camera = scene.view_camera()
    lights = tuple(dataclasses.replace(light, shadows=RAYS) for light in studio_lights(camera))
    return scene.replace(camera=camera, lights=lights)


@pytest.mark.parametrize("model", ["teapot", "suzanne"])
def test_the_ray_tracer_and_the_rasterizer_make_the_same_picture(model):
    """Same scene, same camera, the same lighting functions and shadow rays: every pixel within 1/255 but for a
    handful (≤ 0.1 %: a pixel centre on a shared edge, a shadow ray grazing a terminator, where the rasterizer's
    point — interpolated from vertices snapped to 1/256 pixel — and the ray's exact hit fall on two sides)."""
    scene = model_on_ground(model)
    raster = sp.render_scene(scene).color[..., :3]
    traced = raytrace_scene(scene).color[..., :3]
    difference = np.abs(raster - traced).max(axis=2)
    assert (difference > 1 / 255).mean() <= 0.001, (difference > 1 / 255).sum()
    assert np.median(difference) < 1e-4


def test_a_pixels_ray_tree_adds_up_to_the_pixel():
    """The tree as data: Σ weight × local over its rays is the framebuffer's value, and the rays are linked
    parent → child with the right kinds and weights (§22)."""
    scene = glass_and_mirror()
    fb = raytrace_scene(scene)
    for x, y in ((30, 40), (70, 42), (50, 10)):
        tree = ray_tree(scene, x, y)
        total = np.sum([np.multiply(n.weight, n.local) for n in tree], axis=0)
        np.testing.assert_array_equal(np.float32(total), fb.color[y, x, :3])
        assert tree[0].kind == "primary" and tree[0].parent == -1 and tree[0].weight == (1.0, 1.0, 1.0)
        for node in tree[1:]:
            parent = tree[node.parent]
            material = {"mirror": MIRROR, "glass": GLASS}[parent.object]
            k = material.kr if node.kind == "reflected" else material.kt
            np.testing.assert_allclose(node.weight, np.multiply(parent.weight, k))
            assert node.depth == parent.depth + 1
    assert "reflected" in str(ray_tree(scene, 30, 40))


MIRROR = Material(ka=0.0, kd=0.0, ks=0.0, kr=(0.9, 0.8, 0.7))
GLASS = Material(ka=0.0, kd=0.0, ks=0.0, kt=(0.9, 0.9, 0.9), ior=1.5)


def glass_and_mirror() -> Scene:
    floor = shapes.plane(8.0, material=Material(kd=(0.6, 0.6, 0.6), ks=0.0))
    return Scene([SceneObject("floor", floor, np.eye(4)),
                  SceneObject("mirror", shapes.uv_sphere(0.8, 32, 16, material=MIRROR), translate(-1.0, 0.8, 0.0)),
                  SceneObject("glass", shapes.uv_sphere(0.8, 32, 16, material=GLASS), translate(1.0, 0.8, 0.0))],
                 camera=sp.Camera(eye=(0.0, 1.5, 5.0), target=(0.0, 0.7, 0.0), fovy=40.0),
                 lights=(Light.directional((0.3, -1.0, -0.4), name="sun"),), width=100, height=60)


def test_a_mirror_shows_what_the_mirror_direction_meets():
    """A mirror floor (kr = 1, nothing else) under a glowing square (ke only), no light: a pixel whose
    reflected ray R = reflect(d, N) (§16), worked out here, passes through the square shows ke, else the
    background times kr."""
    mirror = shapes.plane(20.0, material=Material(ka=0.0, kd=0.0, ks=0.0, kr=(1.0, 1.0, 1.0)))
    glow = shapes.plane(2.0, material=Material(ke=(0.2, 0.5, 0.9), ka=0.0, kd=0.0, ks=0.0))
    flip = np.diag([1.0, -1.0, -1.0, 1.0])                      # face down, toward the mirror
    camera = sp.Camera(eye=(0.0, 1.0, 6.0), target=(0.0, 0.0, 0.0), fovy=50.0, near=0.5, far=50.0)
    scene = Scene([SceneObject("mirror", mirror, np.eye(4)), SceneObject("glow", glow, translate(0.0, 2.0, -2.0) @ flip)],
                  camera=camera, lights=(), ambient=(0.0, 0.0, 0.0), background=(0.05, 0.1, 0.15, 1.0),
                  width=64, height=48, cull="none")
    fb = raytrace_scene(scene)
    unproject = np.linalg.inv(camera.projection(64 / 48) @ camera.view)
    checked = 0
    for j in range(48):
        for i in range(64):
            x, y = 2 * (i + 0.5) / 64 - 1, 1 - 2 * (j + 0.5) / 48
            near, far = (unproject @ (x, y, z, 1.0) for z in (-1.0, 1.0))
            o, d = near[:3] / near[3], far[:3] / far[3] - near[:3] / near[3]
            if d[1] >= 0:
                continue                                         # the ray does not go down to the mirror
            P = o + (-o[1] / d[1]) * d
            if abs(P[0]) > 10 or abs(P[2]) > 10:
                continue
            R = d * (1.0, -1.0, 1.0)                             # reflect(d, (0, 1, 0))
            s = (2.0 - P[1]) / R[1]
            Q = P + s * R
            inside = max(abs(Q[0]), abs(Q[2] + 2.0))
            if abs(inside - 1.0) < 0.03:
                continue                                         # within a hair of the square's edge
            expected = (0.2, 0.5, 0.9) if inside < 1.0 else (0.05, 0.1, 0.15)
            np.testing.assert_allclose(fb.color[j, i, :3], expected, atol=1e-6)
            checked += 1
    assert checked > 1000


def glass_block() -> Scene:
    block = shapes.cube(2.0, material=Material(ka=0.0, kd=0.0, ks=0.0, kt=(1.0, 1.0, 1.0), ior=1.5))
    camera = sp.Camera(eye=(0.0, 2.2, 3.0), target=(0.0, 0.6, 0.0), fovy=40.0, near=0.1, far=20.0)
    return Scene([SceneObject("block", block, np.eye(4))], camera=camera, lights=(), ambient=(0.0, 0.0, 0.0),
                 width=32, height=32, cull="none")


def test_refraction_obeys_snell_and_tir_happens_beyond_the_critical_angle():
    """Into a glass cube (η = 1.5) through its top face: the refracted ray obeys η_i sin θ_i = η_t sin θ_t (§17,
    §18) and is unit length; inside, where it meets a side face it does so at 90° − θ_t ≥ 48.2° > the critical
    angle asin(1/1.5) = 41.8°, so that hit sends everything to reflection (§19) and nothing out."""
    scene = glass_block()
    entered = tirs = 0
    for y in range(2, 32, 4):
        for x in range(2, 32, 4):
            tree = ray_tree(scene, x, y, max_depth=3)
            refracted = [n for n in tree if n.parent == 0 and n.kind == "refracted"]
            if tree[0].object != "block" or not refracted or abs(refracted[0].origin[1] - 1.0) > 1e-9:
                continue                                       # not into the top face
            entered += 1
            d, T = np.array(tree[0].direction), np.array(refracted[0].direction)
            sin_i = np.linalg.norm(np.cross(d, (0.0, 1.0, 0.0)))
            sin_t = np.linalg.norm(np.cross(T, (0.0, 1.0, 0.0)))
            assert np.linalg.norm(T) == pytest.approx(1.0, abs=1e-12)
            assert 1.0 * sin_i == pytest.approx(1.5 * sin_t, rel=1e-9)
            assert sin_t < 1 / 1.5
            for n in tree:
                if n.parent == refracted[0].index:
                    side = max(abs(n.origin[0]), abs(n.origin[2])) > 1.0 - 1e-9
                    if side:
                        assert n.kind == "total internal reflection"
                        tirs += 1
                    else:
                        assert n.kind == "refracted"               # out through the bottom: below critical
    assert entered >= 10 and tirs >= 3, (entered, tirs)
    assert "total internal reflection" in RAY_KINDS


def test_depth_zero_is_primary_rays_only_and_limits_are_checked():
    scene = glass_and_mirror()
    assert [n.kind for n in ray_tree(scene, 30, 40, max_depth=0)] == ["primary"]
    with pytest.raises(ValueError, match="max_depth"):
        raytrace_scene(scene, max_depth=99)
    with pytest.raises(ValueError, match="min_weight"):
        raytrace_scene(scene, min_weight=2.0)
    with pytest.raises(ValueError, match="outside"):
        ray_tree(scene, 500, 5)


def test_the_same_bytes_on_one_thread_and_two():
    scene = glass_and_mirror()
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = raytrace_scene(scene).color.tobytes()
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = raytrace_scene(scene).color.tobytes()
    finally:
        numba.set_num_threads(before)
    assert one == two


def test_render_raytrace_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "t.png"
    assert main(["render", "suzanne", "--raytrace", "--size", "32x24", "-q", "-o", str(out)]) == 0
    assert out.is_file()
    assert main(["render", "suzanne", "--raytrace", "--stages", str(tmp_path / "s"), "-o", str(out)]) == 2
    assert "does not apply with --raytrace" in capsys.readouterr().err


def test_render_with_rays_from_the_shaders_on_the_command_line(tmp_path, capsys):
    """--rays: a scene file's mirror ball rasterized with its rays traced equals render_with_environments(scene,
    "rays") byte for byte; it refuses --raytrace and --stages by name."""
    from softpipe.scenes.environment_pass import render_with_environments
    from softpipe.scenes.scenefile import load_scene
    scene_file = tmp_path / "mirror.toml"
    scene_file.write_text('[render]\nwidth = 32\nheight = 24\n[camera]\neye = [0, 1.5, 4]\ntarget = [0, 0.5, 0]\n'
                          '[[meshes]]\nname = "floor"\nshape = "plane"\nsize = 6.0\n'
                          '[[meshes]]\nname = "ball"\nshape = "uv_sphere"\nradius = 0.6\n'
                          'transform = { translate = [0, 0.6, 0] }\nprogram = "mirror"\n'
                          'material = { kd = 0.0, ks = 0.5, shininess = 60, kr = 0.9 }\n')
    out = tmp_path / "m.png"
    assert main(["render", str(scene_file), "--rays", "-o", str(out)]) == 0
    assert "rays from the shaders" in capsys.readouterr().out
    expected = render_with_environments(load_scene(scene_file), "rays").to_uint8(alpha=False)
    np.testing.assert_array_equal(np.asarray(Image.open(out).convert("RGB")), expected)
    for other in (["--raytrace"], ["--stages", str(tmp_path / "s")]):
        assert main(["render", str(scene_file), "--rays", *other, "-o", str(out)]) == 2
        assert f"does not apply with {other[0]}" in capsys.readouterr().err


def test_a_fragment_shader_can_ask_a_ray_query():
    """trace_any from a user's fragment shader (GLSL's rayQueryEXT in spirit): a floor darkened where a ray
    straight up from the fragment meets the box above it — equal, pixel by pixel, to the BVH asked directly."""
    from softpipe.shading import RayScene, facing_normal, standard_vertex, trace_any
    box = SceneObject("box", shapes.cube(1.0), translate(0.3, 1.5, 0.0))
    scene_rays = RayScene([box])
    camera = sp.Camera(eye=(0.0, 6.0, 0.01), target=(0.0, 0.0, 0.0), fovy=40.0)

    def occlusion(varyings, uniforms, frag):
        P = varyings.position
        up = facing_normal(varyings.normal, frag.front_facing)
        if trace_any(uniforms.scene, P, up, 1e-6, 100.0):
            return (0.0, 0.0, 0.0, 1.0)
        return (1.0, 1.0, 1.0, 1.0)

    program = sp.shading.Program("occlusion test", standard_vertex, occlusion, "")
    fb = sp.Framebuffer(48, 48)
    floor = shapes.plane(4.0)
    view = camera.view
    sp.draw_mesh(fb, floor, camera, program, uniforms={"scene": scene_rays.uniform(view)}, cull="none")
    results = []
    fb2 = sp.Framebuffer(48, 48)
    trace = sp.draw_mesh(fb2, floor, camera, program, uniforms={"scene": scene_rays.uniform(view)}, cull="none",
                         trace=True, results=results)
    f = trace.fragments
    points = []
    for k in range(len(f)):
        P = trace.fragment_inputs(k)[0].position
        points.append(np.linalg.inv(view) @ (*P, 1.0))
    points = np.array(points)[:, :3]
    blocked = scene_rays.bvh.occluded(points, np.tile((0.0, 1.0, 0.0), (len(points), 1)), 1e-6, 100.0)
    shown = fb2.color[f.y, f.x, 0] == 0.0
    assert np.array_equal(shown, blocked) and blocked.any() and (~blocked).any()
    np.testing.assert_array_equal(fb.color, fb2.color)


def test_lights_and_lighting_of_the_tracer_are_the_scenes():
    """The ray tracer lights with the scene's own Lighting (its ambient), not the studio set, when it has lights."""
    scene = glass_and_mirror().replace(ambient=(0.0, 0.0, 0.0), lights=())
    fb = raytrace_scene(scene)
    floor_pixel = fb.color[55, 50, :3]                 # the floor, near the bottom: no light, no ambient
    np.testing.assert_array_equal(floor_pixel, (0.0, 0.0, 0.0))
    assert isinstance(scene.lighting_for(scene.camera), Lighting)


def _edge_distance(scene, camera, obj_index, triangle, i, j) -> float:
    """Window-space distance, in pixels, from pixel (i, j)'s centre to the nearest edge of a triangle."""
    obj = scene.drawn_objects(camera)[obj_index]
    corners = obj.world_positions()[np.asarray(obj.mesh.indices)[triangle]]
    clip = np.c_[corners, np.ones(3)] @ (camera.projection(scene.width / scene.height) @ camera.view).T
    ndc = clip[:, :2] / clip[:, 3:]
    w = np.c_[(ndc[:, 0] + 1) / 2 * scene.width, (1 - ndc[:, 1]) / 2 * scene.height]
    c = np.array((i + 0.5, j + 0.5))
    distances = []
    for k in range(3):
        a, b = w[k], w[(k + 1) % 3]
        e = b - a
        distances.append(abs(e[0] * (c - a)[1] - e[1] * (c - a)[0]) / np.linalg.norm(e))
    return min(distances)


def test_primary_visibility_is_the_rasterizers_at_every_pixel_centre_but_on_edges():
    """The triangle a primary ray meets is the one whose fragment the rasterizer's pixel shows, except where the
    centre lies on an edge within the rasterizer's snapping: vertices are snapped to 1/256 pixel, so a centre
    closer than that to an edge may fall either way (every mismatch is checked to be within 1/256 px)."""
    from softpipe.tracers.whitted import primary_visibility
    scene = model_on_ground("teapot")
    obj, tri, _ = primary_visibility(scene)
    results = []
    sp.render_scene(scene, trace=True, results=results)
    shown_obj = np.full(obj.shape, -1)
    shown_tri = np.full(obj.shape, -1)
    for k, r in enumerate(results):
        f, written = r.trace.fragments, r.trace.written()
        shown_obj[f.y[written], f.x[written]] = k
        shown_tri[f.y[written], f.x[written]] = f.primitive_id[written]
    mismatch = np.argwhere((shown_obj != obj) | (shown_tri != tri))
    assert len(mismatch) <= 0.005 * obj.size
    for j, i in mismatch:
        near = [_edge_distance(scene, scene.camera, o, t, i, j)
                for o, t in ((obj[j, i], tri[j, i]), (shown_obj[j, i], shown_tri[j, i])) if o >= 0]
        assert min(near) < 1 / 256, (i, j, near)


def test_the_tracers_local_shading_is_the_phong_programs():
    """At a primary hit, the tracer's local color equals the phong program's fragment shader given the same
    surface point: P and N interpolated at the hit's barycentrics in eye space, front_facing by winding, the same
    lighting uniform (shadow rays for V_j) — within 1e-5."""
    from softpipe.language.contract import FragInfo
    from softpipe.programs.common import StandardVaryings
    from softpipe.programs.phong import phong_fragment
    from softpipe.tracers.whitted import primary_visibility
    scene = model_on_ground("suzanne")
    camera = scene.camera
    objects = scene.drawn_objects(camera)
    obj, tri, b = primary_visibility(scene)
    lights = scene.lighting_for(camera)
    lighting = sp.render_shadow_maps(objects, lights).lighting_uniform(lights, camera.view)
    view = camera.view
    rng = np.random.default_rng(3)
    covered = np.argwhere(obj >= 0)
    for j, i in covered[rng.choice(len(covered), 25, replace=False)]:
        o = objects[obj[j, i]]
        corners = np.asarray(o.mesh.indices)[tri[j, i]]
        b1, b2 = b[j, i]
        weights = np.array((1 - b1 - b2, b1, b2))
        world = weights @ o.world_positions()[corners]
        normals = o.mesh.normals if o.mesh.normals is not None else o.mesh.vertex_normals()
        n = normals[corners] @ np.linalg.inv(o.model[:3, :3])
        n = weights @ (n / np.linalg.norm(n, axis=1, keepdims=True))
        P = tuple(view[:3, :3] @ world + view[:3, 3])
        N = tuple(np.linalg.inv(view[:3, :3]).T @ n)
        p = o.world_positions()[corners]
        front = np.cross(p[1] - p[0], p[2] - p[0]) @ (world - np.asarray(camera.eye)) < 0
        uniforms = sp.make_uniforms({"projection": camera.projection(scene.width / scene.height),
                                            "material": o.mesh.material, "lighting": lighting})
        expected = phong_fragment(StandardVaryings(P, N), uniforms, FragInfo(i + 0.5, j + 0.5, 0.5, bool(front), 0))
        local = ray_tree(scene, int(i), int(j), max_depth=0)[0].local
        np.testing.assert_allclose(local, expected[:3], atol=1e-5)


def test_two_mirrors_facing_stop_at_the_depth_limit_with_weights_multiplied():
    """A ray between two parallel mirrors (kr = 0.8): the tree is one chain, max_depth + 1 rays long, the k-th
    with weight 0.8^k (§22); a weight cutoff stops it earlier, where 0.8^k falls below it."""
    mirror = Material(ka=0.0, kd=0.0, ks=0.0, kr=(0.8, 0.8, 0.8))
    left = shapes.plane(200.0, material=mirror)
    scene = Scene([SceneObject("left", left, translate(-1.0, 0.0, 0.0) @ sp.rotate_z(-90.0)),
                   SceneObject("right", left, translate(1.0, 0.0, 0.0) @ sp.rotate_z(90.0))],
                  camera=sp.Camera(eye=(0.0, 0.0, 5.0), target=(3.0, 0.0, 0.0), fovy=10.0, near=0.5, far=100.0),
                  lights=(), ambient=(0.0, 0.0, 0.0), width=9, height=9, cull="none")
    tree = ray_tree(scene, 4, 4, max_depth=6, min_weight=0.0)
    assert len(tree) == 7 and [n.depth for n in tree] == list(range(7))
    assert all(n.kind == "reflected" for n in tree[1:]) and all(n.parent == n.index - 1 for n in tree[1:])
    for n in tree:
        np.testing.assert_allclose(n.weight, (0.8 ** n.depth,) * 3)
    assert all(n.object in ("left", "right") for n in tree)
    cut = ray_tree(scene, 4, 4, max_depth=12, min_weight=0.3)       # 0.8^5 = 0.33 ≥ 0.3 > 0.8^6
    assert max(n.depth for n in cut) == 5


def test_inside_a_glass_sphere_grazing_rays_are_totally_reflected():
    """A camera inside a glass ball (η = 1.5 inside, air out) looking along its wall: rays meet the wall from
    inside beyond the critical angle asin(1/1.5) = 41.8°: every such hit reflects all (§19), none refracts out;
    rays meeting it more steeply than that do refract out."""
    ball = shapes.icosphere(1.0, subdivisions=4, material=Material(ka=0.0, kd=0.0, ks=0.0, kt=(1.0, 1.0, 1.0),
                                                                    ior=1.5))
    scene = Scene([SceneObject("ball", ball, np.eye(4))],
                  camera=sp.Camera(eye=(0.85, 0.0, 0.0), target=(0.85, 0.0, -1.0), fovy=150.0, near=0.01, far=10.0),
                  lights=(), ambient=(0.0, 0.0, 0.0), width=15, height=15, cull="none")
    total = refracted = 0
    for j in range(0, 15, 2):
        for i in range(0, 15, 2):
            tree = ray_tree(scene, i, j, max_depth=1)
            first = tree[0]
            assert first.object == "ball"
            hit = np.array(first.origin) + first.t * np.array(first.direction)
            normal = hit / np.linalg.norm(hit)
            cos = abs(np.dot(normal, first.direction))
            kinds = {n.kind for n in tree[1:]}
            if cos < math.cos(math.asin(1 / 1.5)) - 0.02:
                assert kinds == {"total internal reflection"}
                total += 1
            elif cos > math.cos(math.asin(1 / 1.5)) + 0.02:
                assert kinds == {"refracted"}
                refracted += 1
    assert total > 5 and refracted > 5


def test_an_object_that_casts_no_shadow_casts_none_in_the_tracer_either():
    """cast_shadows=False: the shadow rays of the tracer pass it, as the rasterizer's shadows (maps or rays) do;
    with depth 0 the two pictures then agree everywhere."""
    floor = shapes.plane(6.0, material=Material(ka=0.2, kd=0.8, ks=0.0))
    box = shapes.cube(1.0, material=Material(kd=(0.8, 0.3, 0.2)))
    sun = Light.directional((0.0, -1.0, 0.0), shadows=RAYS, name="sun")
    for casts in (True, False):
        scene = Scene([SceneObject("floor", floor, np.eye(4)),
                       SceneObject("box", box, translate(0.0, 1.5, 0.0), cast_shadows=casts)],
                      camera=sp.Camera(eye=(0.0, 5.0, 5.0)), lights=(sun,), width=48, height=48)
        raster = sp.render_scene(scene).color[..., :3]
        traced = raytrace_scene(scene, max_depth=0).color[..., :3]
        assert np.abs(raster - traced).max() < 1 / 255
        under = traced[np.abs(traced[..., 0] - 0.2 * 0.2 * 1.0) < 1e-6]     # floor pixels in the box's shadow
        assert (len(under) > 0) == casts
