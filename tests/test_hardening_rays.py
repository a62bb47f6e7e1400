"""Hardening of rays and lights (issue #28, round 3): inputs that crashed the process, asked for
gigabytes, or answered with a misleading message.

The crashes are tested in a subprocess each, so that a segmentation fault fails the test
instead of ending pytest.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from softpipe.light.material import Material
from softpipe.rays.build import binary_tree, wide_tree
from softpipe.rays.layout import MAX_DEPTH, WIDTH
from softpipe.rays.traverse import STACK_SIZE

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_python(code: str, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """``code`` in a fresh Python with this softpipe; a crash is a return code, not pytest's end."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *args], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


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


def test_a_non_finite_ray_misses_instead_of_crashing_closest_hit_and_any_hit():
    """A NaN ray entered every box (NaN compares false: no constraint), the empty lanes too, whose link is
    the root: the traversal looped until its fixed stack overflowed (SIGSEGV). Now it misses."""
    lines = ok(run_python(_ONE_RAY)).splitlines()
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
def test_a_non_finite_ray_from_a_fragment_shader_misses(shader):
    """trace_any / trace_closest from a fragment shader with a NaN uniform, inf·0 or a NaN literal: every
    fragment's ray misses (the floor drawn white), where the process used to die."""
    white, black = map(int, ok(run_python(_SHADER_RAY, shader)).split())
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


@pytest.mark.parametrize("how, program", [("--raytrace", ""), ("--rays", 'program = "hall"')])
def test_a_scene_file_with_ior_1e200_is_refused_by_name(tmp_path, how, program):
    """The scene file of the issue: `softpipe render --raytrace` (and the hall program with --rays) died
    with SIGSEGV; now the file's material is refused, naming the file, the bound and the value."""
    scene = tmp_path / "glass.toml"
    scene.write_text(_IOR_SCENE.format(program=program))
    out = tmp_path / "out.png"
    done = run_python("import sys\nfrom softpipe.tools.cli import main\nsys.exit(main(sys.argv[1:]))",
                      "render", str(scene), how, "-o", str(out))
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


def test_the_ray_tracer_survives_an_ior_that_makes_nan_rays():
    """Should an ior of 1e200 reach the tracer anyway (here past the check), its NaN refracted rays miss."""
    assert ok(run_python(_FORCED_IOR)).split()[-1] in ("True", "False")
