"""Hardening of rays and lights (issue #28, round 3): inputs that crashed the process, asked for
gigabytes, or answered with a misleading message.

The crashes are tested in a subprocess, so that a segmentation fault fails the test instead of
ending pytest: one process runs every such case of this file (the ``crash_cases`` fixture), each as
``python -c`` would, and a crash in one case fails that case and the next process runs the rest.
"""
from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
from case_process import Cases

from softpipe.light.material import Material
from softpipe.rays.build import binary_tree, wide_tree
from softpipe.rays.layout import MAX_DEPTH, WIDTH
from softpipe.rays.traverse import STACK_SIZE


def ok(done: subprocess.CompletedProcess) -> str:
    assert done.returncode == 0, f"return code {done.returncode}\n{done.stderr[-3000:]}"
    return done.stdout


# ------------------------------------------------------------------ 1. non-finite rays

_ONE_RAY = """
import math, sys
import numpy as np
from softpipe.rays.bvh import BVH, any_hit, closest_hit
from softpipe.scenes import shapes
ball = shapes.icosphere(1.0, 3)
bvh = BVH.build(ball.positions, np.asarray(ball.indices).reshape(-1, 3))
nan, inf = math.nan, math.inf
rays = {
    "nan origin": ((nan, nan, nan), (0.0, 0.0, -1.0), 0.0, inf),
    "nan direction": ((0.0, 0.0, 5.0), (nan, nan, nan), 0.0, inf),
    "one nan": ((0.0, nan, 5.0), (0.0, 0.0, -1.0), 0.0, inf),
    "inf direction": ((0.0, 0.0, 5.0), (inf, inf, -inf), 0.0, inf),
    "inf times zero": ((0.0, 0.0, 5.0), (inf * 0.0, 0.0, -1.0), 0.0, inf),
    "inf origin": ((inf, 0.0, 5.0), (0.0, 0.0, -1.0), 0.0, inf),
    "zero direction": ((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), 0.0, inf),
    "nan t range": ((0.0, 0.0, 5.0), (0.0, 0.0, -1.0), nan, nan),
    "nan t_max": ((0.0, 0.0, 5.0), (0.0, 0.0, -1.0), 0.0, nan),
    "huge origin": ((1e300, -1e300, 1e308), (-1.0, 1.0, -1.0), 0.0, inf),
    "tiny direction": ((0.0, 0.0, 5.0), (5e-324, -5e-324, -5e-324), 0.0, inf),
    "plain": ((0.0, 0.0, 5.0), (0.0, 0.0, -1.0), 0.0, inf),
}
for name, (o, d, t0, t1) in rays.items():
    tri, t, b1, b2 = closest_hit(bvh.uniform, np.array(o), np.array(d), t0, t1)
    hit = any_hit(bvh.uniform, np.array(o), np.array(d), t0, t1)
    print(name, tri >= 0, hit, sep=";")
# the deepest tree the build makes (see the stack test below), walked by a ray along all of it and a ray
# crossing one triangle near its far end
n = 1000
s = 2.0 ** np.arange(n)
v = np.zeros((3 * n, 3))
v[0::3, 0], v[1::3, 0], v[2::3, 1] = s, s * 1.0001, 1.0
deep = BVH.build(v, np.arange(3 * n).reshape(n, 3), leaf_size=1)
along = closest_hit(deep.uniform, (-1.0, 1e-9, 0.0), (1.0, 0.0, 0.0), 0.0, inf)
across = closest_hit(deep.uniform, (2.0 ** 900 * 1.00005, 1e-9, 1.0), (0.0, 0.0, -1.0), 0.0, inf)
print("deep", along[0] >= 0, across[0] == 900 and across[1] == 1.0, sep=";")
"""


def test_a_non_finite_ray_misses_instead_of_crashing_closest_hit_and_any_hit(crash_cases):
    """A NaN ray entered every box (NaN compares false: no constraint), the empty lanes too, whose link is
    the root: the traversal looped until its fixed stack overflowed (SIGSEGV). Now it misses."""
    lines = ok(crash_cases("one ray")).splitlines()
    answers = {name: (hit, any_) for name, hit, any_ in (line.split(";") for line in lines)}
    misses = ["nan origin", "nan direction", "one nan", "inf direction", "inf times zero", "inf origin",
              "zero direction", "nan t range", "nan t_max"]
    assert {name: answers[name] for name in misses} == {name: ("False", "False") for name in misses}
    assert answers["plain"] == ("True", "True")
    assert answers["deep"] == ("False", "True")             # edge-on along the chain: no hit, the whole depth walked
    assert set(answers) == set(misses) | {"plain", "huge origin", "tiny direction", "deep"}   # two: no crash


_SHADER_RAY = """
import math, sys
import numpy as np
import softpipe as sp
from softpipe.scenes import shapes
from softpipe.scenes.scene import SceneObject
from softpipe.shading import RayScene, standard_vertex, trace_any, trace_closest
from softpipe.pipeline.transforms import translate

box = SceneObject("box", shapes.cube(1.0), translate(0.0, 1.5, 0.0))
scene = RayScene([box])
camera = sp.Camera(eye=(0.0, 6.0, 0.01), target=(0.0, 0.0, 0.0), fovy=40.0)

def nan_uniform(varyings, uniforms, frag):       # a NaN handed in as a uniform
    d = (0.0, uniforms.up, 0.0)
    if trace_any(uniforms.scene, varyings.position, d, 1e-6, 100.0):
        return (0.0, 0.0, 0.0, 1.0)
    return (1.0, 1.0, 1.0, 1.0)

def inf_times_zero(varyings, uniforms, frag):    # inf·0 computed in the shader
    d = (uniforms.big * 0.0, 1.0, 0.0)
    tri, t, b1, b2 = trace_closest(uniforms.scene, varyings.position, d, 1e-6, 100.0)
    if tri >= 0:
        return (0.0, 0.0, 0.0, 1.0)
    return (1.0, 1.0, 1.0, 1.0)

def nan_literal(varyings, uniforms, frag):       # a NaN literal
    if trace_any(uniforms.scene, (math.nan, 0.0, 0.0), (0.0, 1.0, 0.0), 1e-6, 100.0):
        return (0.0, 0.0, 0.0, 1.0)
    return (1.0, 1.0, 1.0, 1.0)

shaders = {"nan_uniform": nan_uniform, "inf_times_zero": inf_times_zero, "nan_literal": nan_literal}
fb = sp.Framebuffer(24, 24)
fb.clear((0.5, 0.5, 0.5, 1.0))
program = sp.shading.Program("nan rays", standard_vertex, shaders[sys.argv[1]], "")
sp.draw_mesh(fb, shapes.plane(4.0), camera, program, cull="none",
             uniforms={"scene": scene.uniform(camera.view), "up": math.nan, "big": math.inf})
print(int((fb.color[..., 0] == 1.0).sum()), int((fb.color[..., 0] == 0.0).sum()))
"""


@pytest.mark.parametrize("shader", ["nan_uniform", "inf_times_zero", "nan_literal"])
def test_a_non_finite_ray_from_a_fragment_shader_misses(crash_cases, shader):
    """trace_any / trace_closest from a fragment shader with a NaN uniform, inf·0 or a NaN literal: every
    fragment's ray misses (the floor drawn white), where the process used to die."""
    white, black = map(int, ok(crash_cases(shader)).split())
    assert white > 100 and black == 0


def test_the_traversal_stack_holds_the_deepest_tree_the_build_makes():
    """The bound STACK_SIZE's comment proves: a wide node's level is at most MAX_DEPTH − 2, and a visit finds
    at most (WIDTH − 1)·level entries and writes WIDTH − 1 more. Checked on a tree forced to its deepest
    (every triangle at a different scale: the SAH splits off one at a time, until the median split)."""
    assert (WIDTH - 1) * (MAX_DEPTH - 2) + (WIDTH - 1) <= STACK_SIZE
    n = 1000
    s = 2.0 ** np.arange(n)                                   # gaps doubling: the SAH cuts one off at a time
    v = np.zeros((3 * n, 3))
    v[0::3, 0], v[1::3, 0], v[2::3, 1] = s, s * 1.0001, 1.0
    tri = np.arange(3 * n).reshape(n, 3)
    lo, hi, first, count, order, corners, depth = binary_tree(v, tri, 1, 16)
    assert depth < MAX_DEPTH
    _leaf_block, lane_node, links, _boxes, _tris, _ids = wide_tree(lo, hi, first, count, order, corners)
    level = np.zeros(len(links), np.int64)                # wide nodes are made parent before child
    for w in range(len(links)):
        for j in range(WIDTH):
            code = links[w, j]
            if lane_node[w, j] >= 0 and code & 0xFFFFFFFF == 0:
                level[code >> 32] = level[w] + 1
    assert MAX_DEPTH - 6 <= level.max() <= MAX_DEPTH - 2
    assert (WIDTH - 1) * level.max() + (WIDTH - 1) <= STACK_SIZE


# ------------------------------------------------------------------ 1. the ior that made NaN rays

@pytest.mark.parametrize("ior", [1e200, 1e4, 1e-200, 1e-4, math.inf])
def test_an_index_of_refraction_outside_its_range_is_refused(ior):
    """ior = 1e200 made η² overflow to inf and the refracted ray NaN (then the crash above)."""
    with pytest.raises(ValueError) as e:
        Material(ior=ior)
    if math.isinf(ior):
        assert str(e.value) == "Material.ior must be a finite number, got float inf"
    else:
        assert str(e.value) == ("Material.ior must be between 0.001 and 1000 (real media are about 1 to 4; "
                                f"outside this range the refraction's η² overflows), got {ior!r}")


def test_the_ends_of_the_ior_range_are_taken():
    assert Material(ior=1e-3).ior == 1e-3 and Material(ior=1000).ior == 1000.0


_IOR_SCENE = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
[render]
width = 24
height = 16
samples = "1"
{program}
[[lights]]
kind = "point"
position = [2.0, 3.0, 4.0]
[[meshes]]
shape = "icosphere"
radius = 1.0
material = {{ kd = 0.2, kt = 0.8, ior = 1e200 }}
"""


_CLI = "import sys\nfrom softpipe.tools.cli import main\nsys.exit(main(sys.argv[1:]))"   # `softpipe ARGS`
_IOR_PROGRAMS = {"--raytrace": "", "--rays": 'program = "hall"'}     # the scene file's [render] line, by option


@pytest.mark.parametrize("how, program", list(_IOR_PROGRAMS.items()))
def test_a_scene_file_with_ior_1e200_is_refused_by_name(crash_cases, how, program):
    """The scene file of the issue: `softpipe render --raytrace` (and the hall program with --rays) died
    with SIGSEGV; now the file's material is refused, naming the file, the bound and the value."""
    done = crash_cases(f"render {how}")
    out = crash_cases.folder / how / "out.png"          # the scene file glass.toml beside it
    assert done.returncode == 2, done.stderr[-3000:]
    assert "glass.toml: [[meshes]] #1" in done.stderr or "glass.toml:" in done.stderr
    assert ("Material.ior must be between 0.001 and 1000 (real media are about 1 to 4; outside this range "
            "the refraction's η² overflows), got 1e+200") in done.stderr
    assert not out.exists()


_FORCED_IOR = """
import numpy as np
import softpipe as sp
from softpipe.light.material import Light, Material
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import raytrace_scene
glass = Material(kd=0.2, kt=0.8, ior=1.5)
object.__setattr__(glass, "ior", 1e200)          # past the Material's check: the tracer must still not crash
scene = Scene(objects=[SceneObject("ball", shapes.icosphere(1.0, 2, material=glass), np.eye(4))],
              camera=sp.Camera(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0)), width=24, height=16,
              lights=(Light.point((2.0, 3.0, 4.0)),))
fb = raytrace_scene(scene)
print(bool(np.isfinite(fb.color).all()))
"""


def test_the_ray_tracer_survives_an_ior_that_makes_nan_rays(crash_cases):
    """Should an ior of 1e200 reach the tracer anyway (here past the check), its NaN refracted rays miss."""
    assert ok(crash_cases("forced ior")).split()[-1] in ("True", "False")


# ------------------------------------------------------------------ the process of the cases above

def _case_of(item):
    """The case of :func:`crash_cases` a collected test of this file reads, or None."""
    params = item.callspec.params if hasattr(item, "callspec") else {}
    return {"test_a_non_finite_ray_misses_instead_of_crashing_closest_hit_and_any_hit": "one ray",
            "test_a_non_finite_ray_from_a_fragment_shader_misses": params.get("shader"),
            "test_a_scene_file_with_ior_1e200_is_refused_by_name": f"render {params.get('how')}",
            "test_the_ray_tracer_survives_an_ior_that_makes_nan_rays": "forced ior"}.get(item.originalname)


@pytest.fixture(scope="module")
def crash_cases(request, tmp_path_factory):
    """``crash_cases(name)``: the CompletedProcess of case ``name``, run (on first use) in one process with
    the cases of every test of this file that this session runs (case_process.py)."""
    folder = tmp_path_factory.mktemp("crash-cases")
    cases = {"one ray": (_ONE_RAY, ()), "forced ior": (_FORCED_IOR, ())}
    cases.update({shader: (_SHADER_RAY, (shader,)) for shader in ("nan_uniform", "inf_times_zero", "nan_literal")})
    for how, program in _IOR_PROGRAMS.items():
        (folder / how).mkdir()
        scene = folder / how / "glass.toml"
        scene.write_text(_IOR_SCENE.format(program=program))
        cases[f"render {how}"] = (_CLI, ("render", str(scene), how, "-o", str(folder / how / "out.png")))
    crash_cases = Cases(request, cases, _case_of)
    crash_cases.folder = folder
    return crash_cases


# ------------------------------------------------------------------ 2. memory asked for before it is taken

def _many_point_lights(n: int, resolution: int = 1024):
    from softpipe.light.material import Light, Lighting
    from softpipe.light.shadowmap import ShadowSettings
    return Lighting([Light.point((float(k % 7), 2.0 + k // 7, 3.0), name=f"lamp {k}",
                                 shadows=ShadowSettings(resolution=resolution)) for k in range(n)])


def test_shadow_maps_are_capped_in_total_before_any_is_made(monkeypatch):
    """300 shadowed point lights ask for 1800 maps of 1024² (7 GiB): refused before the first map's memory."""
    from softpipe.scenes import shadow_pass, shapes
    from softpipe.scenes.scene import SceneObject

    def made(*args, **kwargs):
        raise AssertionError("a shadow map was made")
    monkeypatch.setattr(shadow_pass, "_render_map", made)
    ball = SceneObject("ball", shapes.icosphere(1.0, 1), np.eye(4))
    with pytest.raises(ValueError) as e:
        shadow_pass.render_shadow_maps([ball], _many_point_lights(300))
    assert str(e.value) == (
        "shadow maps: 300 light(s) ask for 1800 maps, about 7.0 GiB together (4 bytes a texel), more than the "
        "limit of 2.0 GiB; the largest is light 0 (lamp 0): 6 map(s) of 1024×1024. Lower the lights' shadow "
        "resolution (ShadowSettings.resolution; 'resolution' in a scene file's shadows table), let fewer lights "
        "cast shadows, or raise the limit (render_shadow_maps(..., max_bytes=...), "
        "softpipe.scenes.shadow_pass.MAX_SHADOW_MAP_BYTES)")
    with pytest.raises(ValueError, match=r"^shadow maps: 2 light\(s\) ask for 12 maps, about 0.0 GiB together "):
        shadow_pass.render_shadow_maps([ball], _many_point_lights(2, 64), max_bytes=1000)


def test_transparent_casters_count_their_layers_in_the_total(monkeypatch):
    from softpipe.scenes import shadow_pass, shapes
    from softpipe.scenes.scene import SceneObject
    glass = SceneObject("glass", shapes.icosphere(1.0, 1, material=Material(kt=0.5)), np.eye(4))
    monkeypatch.setattr(shadow_pass, "MAX_SHADOW_MAP_BYTES", 6 * 1024 ** 2 * 36 - 1)
    with pytest.raises(ValueError, match=r"1 light\(s\) ask for 6 maps, .* \(36 bytes a texel\)"):
        shadow_pass.render_shadow_maps([glass], _many_point_lights(1))


def test_a_scene_file_with_300_shadowed_lights_is_refused_by_the_command_line(tmp_path, capsys):
    """The issue's 15 KB scene: 300 point lights that cast shadows. The command says what to change."""
    from softpipe.tools.cli import main
    lights = "".join(f'[[lights]]\nkind = "point"\nposition = [{k % 7}.0, 3.0, {k // 7}.0]\nshadows = true\n\n'
                     for k in range(300))
    scene = tmp_path / "lamps.toml"
    scene.write_text('[render]\nwidth = 16\nheight = 16\n\n' + lights + '[[meshes]]\nshape = "cube"\n')
    out = tmp_path / "lamps.png"
    assert main(["render", str(scene), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "shadow maps: 300 light(s) ask for 1800 maps, about 7.0 GiB together" in err
    assert "'resolution' in a scene file's shadows table" in err
    assert not out.exists()


def test_a_cube_map_face_size_is_checked_before_anything_is_allocated(monkeypatch):
    """from_equirectangular(size=30000) made [6, 30000, 30000, 3] float64 directions (130 GB) first."""
    from softpipe.light import cubemap
    from softpipe.light.cubemap import CubeMap

    def made(size):
        raise AssertionError("texel directions were made")
    monkeypatch.setattr(cubemap, "texel_directions", made)
    pano = np.zeros((8, 16, 3), np.float32)
    message = ("CubeMap.from_equirectangular: size=30000 makes six 30000×30000 faces, each needing about 92.2 GiB "
               "while its mipmaps are made (110 bytes a texel), more than the limit of 2.0 GiB a face: give a "
               "smaller size (at most 4418), or raise max_bytes=... (softpipe.light.images.MAX_TEXTURE_BYTES)")
    with pytest.raises(ValueError) as e:
        CubeMap.from_equirectangular(pano, size=30000)
    assert str(e.value) == message
    with pytest.raises(ValueError, match=r"^CubeMap.from_function: size=30000 makes six"):
        CubeMap.from_function(lambda d: d, 30000)
    with pytest.raises(ValueError, match=r"^CubeMap.from_function: size=64 .* limit of 0.0 GiB"):
        CubeMap.from_function(lambda d: d, 64, max_bytes=1000)
    for bad in (0, -3, 2.5, True, "64"):
        with pytest.raises(ValueError, match=r"^CubeMap.from_equirectangular: size must be an integer ≥ 1 "
                                             r"\(the face width in texels\), got "):
            CubeMap.from_equirectangular(pano, size=bad)


def test_a_cube_map_within_the_budget_is_made_as_before():
    from softpipe.light.cubemap import CubeMap
    pano = np.linspace(0.0, 1.0, 8 * 16 * 3, dtype=np.float32).reshape(8, 16, 3)
    assert CubeMap.from_equirectangular(pano).size == 4 and CubeMap.from_equirectangular(pano, size=3).size == 3


# ------------------------------------------------------------------ 3. messages that say what is wrong

def _ball():
    from softpipe.scenes import shapes
    from softpipe.scenes.scene import SceneObject
    return SceneObject("ball", shapes.icosphere(1.0, 1), np.eye(4))


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_a_light_too_far_for_its_shadow_map_is_named_with_its_distance(kind):
    """A light at 1e30 said "look_at: eye and target are the same point"."""
    from softpipe.light.material import Light, Lighting
    from softpipe.light.shadowmap import ShadowSettings
    from softpipe.scenes.shadow_pass import render_shadow_maps
    where = (1e30, 0.0, 0.0)
    light = (Light.point(where, name="sun lamp", shadows=ShadowSettings()) if kind == "point" else
             Light.spot(where, (-1.0, 0.0, 0.0), 20.0, name="sun lamp", shadows=ShadowSettings()))
    with pytest.raises(ValueError) as e:
        render_shadow_maps([_ball()], Lighting([Light.directional((0, -1, 0)), light]))
    assert str(e.value) == (
        "light 1 (sun lamp) at position (1e+30, 0, 0) is 1e+30 from the shadow casters, which are 3.46 across: "
        "its shadow map cannot tell their depths apart from farther than 1e+06 times their size. Move the light "
        "nearer, make it a directional light (a far sun), or turn its shadows off")


def test_a_model_1e20_across_gets_its_shadow_maps():
    """A model 1e20 across, its light as far: eye + 1 rounded to eye ("eye and target are the same point");
    the map's view is now made from the direction itself."""
    from softpipe.light.material import Light, Lighting
    from softpipe.light.shadowmap import ShadowSettings
    from softpipe.scenes import shapes
    from softpipe.scenes.scene import SceneObject
    from softpipe.scenes.shadow_pass import render_shadow_maps
    big = SceneObject("big", shapes.icosphere(1e20, 1), np.eye(4))
    for light in (Light.point((3e20, 1e20, 0.0), shadows=ShadowSettings(resolution=32)),
                  Light.spot((3e20, 0.0, 0.0), (-1.0, 0.0, 0.0), 30.0, shadows=ShadowSettings(resolution=32))):
        maps = render_shadow_maps([big], Lighting([light]))
        assert any((m.depth < 1.0).any() for m in maps.maps)        # the ball is in the map
        assert all(np.isfinite(m.matrix).all() for m in maps.maps)


def test_a_spot_with_cutoff_0_is_named_when_it_casts_shadows():
    """cutoff = 0 said "frustum: left == right or bottom == top"."""
    from softpipe.light.material import Light, Lighting
    from softpipe.light.shadowmap import ShadowSettings
    from softpipe.scenes.shadow_pass import render_shadow_maps
    spot = Light.spot((0.0, 5.0, 0.0), (0.0, -1.0, 0.0), 0.0, name="pin", shadows=ShadowSettings())
    with pytest.raises(ValueError) as e:
        render_shadow_maps([_ball()], Lighting([spot]))
    assert str(e.value) == ("light 0 (pin): a spot with cutoff 0.0° lights nothing, so it has no shadow map; "
                            "give it a cutoff in (0, 90] degrees (at least 1e-6), or no shadows")


def test_a_tiny_light_direction_is_a_direction_without_numpy_warnings(recwarn):
    """A direction of 1e-300 printed numpy's divide warnings and packed NaN; it is the direction it names."""
    from softpipe.light.material import Light, Lighting, pack_lights
    from softpipe.light.shadowmap import ShadowSettings
    from softpipe.scenes.shadow_pass import render_shadow_maps
    tiny = Light.directional((1e-300, -1e-300, 0.0), shadows=ShadowSettings(resolution=16))
    plain = Light.directional((1.0, -1.0, 0.0), shadows=ShadowSettings(resolution=16))
    huge = Light.directional((1e300, -1e300, 0.0), shadows=ShadowSettings(resolution=16))
    rows = [pack_lights([light], np.eye(4)) for light in (tiny, plain, huge)]
    np.testing.assert_array_equal(rows[0], rows[1])
    np.testing.assert_array_equal(rows[2], rows[1])
    maps = [render_shadow_maps([_ball()], Lighting([light])).maps[0] for light in (tiny, plain)]
    np.testing.assert_array_equal(maps[0].depth, maps[1].depth)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


# ------------------------------------------------------------------ 4. a model too small to draw

def test_framing_a_model_1e_10_across_warns_with_its_size():
    """A model ~1e-10 across rendered blank without a word (the framed camera came nearer than the
    rasterizer's W_MIN)."""
    from softpipe.scenes import shapes
    from softpipe.scenes.scene import Scene
    scene = Scene.from_model(shapes.icosphere(1e-10, 1), width=16, height=16)
    with pytest.warns(UserWarning) as caught:
        scene.view_camera()
    assert [str(w.message) for w in caught] == [
        "the meshes are only 2e-10 units across: the framed camera comes within 9e-10 of them, and the "
        "rasterizer drops points nearer the eye than 1e-09 (softpipe.pipeline.assembly.W_MIN), so they may not "
        "be drawn at all. Scale the model up (a scene file's fit = 1, or transform = { scale = ... })"]


def test_framing_a_small_model_that_draws_does_not_warn(recwarn):
    from softpipe.scenes import shapes
    from softpipe.scenes.scene import Scene
    Scene.from_model(shapes.icosphere(1e-6, 1), width=16, height=16).view_camera()
    assert not [w for w in recwarn if issubclass(w.category, UserWarning)]
