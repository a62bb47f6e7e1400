"""The lit programs' plumbing: shared helpers, optional uniforms, a user's program, the demo.

The pixel-against-formula tests are in test_shading.py.
"""
import re
from pathlib import Path

import numba
import numpy as np
import pytest

import softpipe as sp
from softpipe.language.contract import make_uniforms
from softpipe.light.material import Light, Lighting, LightingUniform, Material
from softpipe.pipeline.camera import Camera
from softpipe.programs import PROGRAMS, cook_torrance, flat, gooch, gouraud, hall, phong, textured  # noqa: F401
from softpipe.programs.common import DEFAULT_LIGHTING, facing_normal, lighting_uniform, toward_eye, uniform_or
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh

EXAMPLES_README = Path(__file__).resolve().parent.parent / "examples" / "README.md"


def test_uniform_or_takes_the_uniform_or_the_default_compiled_and_in_python():
    u = make_uniforms({"a": 0.3, "b": (1.0, 2.0, 3.0)})

    def pick(u):
        return uniform_or(u, "a", 0.0), uniform_or(u, "c", 5.0), uniform_or(u, "b", (0.0, 0.0, 0.0))

    expected = (0.3, 5.0, (1.0, 2.0, 3.0))
    assert pick(u) == expected
    assert numba.njit(pick)(u) == expected


def test_toward_eye_perspective_and_orthographic():
    P = (0.3, -0.4, -2.0)
    persp = sp.perspective(45.0, 1.0, 0.1, 10.0)
    ortho = sp.orthographic(-1, 1, -1, 1, 0.1, 10.0)
    np.testing.assert_allclose(toward_eye(P, persp), -np.asarray(P) / np.linalg.norm(P), rtol=1e-15)
    assert toward_eye(P, ortho) == (0.0, 0.0, 1.0)


def test_facing_normal_renormalizes_and_turns_back_faces():
    np.testing.assert_allclose(facing_normal((0.0, 0.0, 2.0), True), (0, 0, 1))
    np.testing.assert_allclose(facing_normal((0.0, 0.0, 2.0), False), (0, 0, -1))
    assert facing_normal((0.0, 0.0, 0.0), True) == (0.0, 0.0, 0.0)      # no NaN


def test_n_and_v_are_within_two_ulp_of_normalize_and_the_same_compiled_and_in_python(rng):
    """N and V are v·(1/|v|), one division for normalize's three (issue 18): the same bits compiled
    and in plain Python (both paths and NUMBA_DISABLE_JIT run this code), within two ulp of v/|v|
    (1/|v| and the product are each rounded; one ulp at most in 6 million random components)."""
    from softpipe.language.glsl import normalize

    @numba.njit
    def n_and_v(v, front, projection):
        return facing_normal(v, front), toward_eye(v, projection)

    persp = sp.perspective(45.0, 1.0, 0.1, 10.0)
    for v in rng.normal(size=(300, 3)) * 10.0 ** rng.uniform(-8, 8, (300, 1)):
        v = tuple(float(x) for x in v)
        for front in (True, False):
            N, V = n_and_v(v, front, persp)
            assert (N, V) == n_and_v.py_func(v, front, persp)
            exact = np.asarray(normalize(v)) * (1.0 if front else -1.0)
            assert np.all(np.abs(np.asarray(N) - exact) <= 2 * np.spacing(np.abs(exact)))
            assert np.all(np.abs(np.asarray(V) + np.asarray(normalize(v))) <= 2 * np.spacing(np.abs(exact)))
    assert n_and_v((np.nan, 0.0, 1.0), True, persp) == ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))   # no NaN


def test_lighting_uniform_accepts_lighting_lights_or_none():
    view = sp.look_at((0, 0, 5), (0, 0, 0))
    sun = Light.directional((0, 0, -1))
    for given, count in ((None, len(DEFAULT_LIGHTING.lights)), (sun, 1), ([sun, sun], 2), (Lighting([sun]), 1),
                         (Lighting([]), 0)):
        u = lighting_uniform(given, view)
        assert isinstance(u, LightingUniform) and u.lights.shape == (count, 22)
    assert lighting_uniform([sun], view).global_ambient == (0.2, 0.2, 0.2)   # OpenGL's default
    with pytest.raises(TypeError, match="Light"):
        lighting_uniform(["not a light"], view)


def test_every_lit_program_is_registered():
    for name in ("flat", "flat_phong_specular", "gouraud", "gouraud_phong_specular", "phong",
                 "phong_phong_specular", "hall", "cook_torrance", "gooch", "textured"):
        assert name in PROGRAMS, name
    assert dict(PROGRAMS["flat"].interpolation) == {"color": "flat"}
    assert PROGRAMS["gouraud"].vertex is PROGRAMS["flat"].vertex    # flat = Gouraud + one qualifier


def test_lights_follow_the_camera_into_eye_space():
    # Lights are given in world space and moved into eye space with the view matrix: turning
    # the camera, the sphere and the lights together about the y axis changes no pixel's color.
    sphere = shapes.uv_sphere(radius=1.0, segments=48, rings=24)
    m = Material(kd=(0.6, 0.5, 0.4), ks=0.5, shininess=20)

    def centre_color(turn):
        rot = sp.rotate_y(turn)
        cam = Camera(eye=tuple((rot @ [0, 0, 4, 1])[:3]), fovy=30.0)
        lights = Lighting([Light.point(tuple((rot @ [0, 3, 3, 1])[:3])),
                           Light.spot(tuple((rot @ [1, 1, 3, 1])[:3]), tuple((rot @ [-1, -1, -3, 0])[:3]), 30.0, 2.0),
                           Light.directional(tuple((rot @ [1, -0.5, -1, 0])[:3]))])
        fb = sp.Framebuffer(33, 33)
        draw_mesh(fb, sphere.transformed(rot), cam, "phong",
                  uniforms={"lighting": lights.uniform(cam.view), "material": m})
        return fb.color[10:23, 10:23, :3]

    base = centre_color(0.0)
    assert base.max() > 0.3
    for turn in (90.0, 200.0):
        np.testing.assert_allclose(centre_color(turn), base, rtol=1e-4, atol=1e-5)


def _readme_user_program():
    blocks = re.findall(r"```python\n(.*?)```", EXAMPLES_README.read_text(), flags=re.S)
    block = next(b for b in blocks if "def wrapped_fragment" in b)
    namespace = {}
    exec(compile(block, str(EXAMPLES_README), "exec"), namespace)
    return namespace


def test_the_documented_user_program_runs_and_changes_only_the_diffuse_term(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ns = _readme_user_program()
    assert (tmp_path / "out" / "wrapped.png").exists()
    fb = ns["fb"]
    assert fb.color[..., :3].max() > 0.2
    # with w = 0 the wrapped diffuse is Lambert's: the same picture as the built-in phong
    camera, mesh, lighting = ns["camera"], ns["mesh"], ns["lighting"]
    a, b = sp.Framebuffer(32, 32), sp.Framebuffer(32, 32)
    draw_mesh(a, mesh, camera, ns["wrapped"], uniforms={"lighting": lighting, "wrap": 0.0})
    draw_mesh(b, mesh, camera, "phong", uniforms={"lighting": lighting})
    np.testing.assert_allclose(a.color, b.color, rtol=1e-6, atol=1e-7)
    # with w > 0 the light reaches past the terminator: more pixels are lit
    a = sp.Framebuffer(32, 32)
    draw_mesh(a, mesh, camera, ns["wrapped"], uniforms={"lighting": lighting, "wrap": 1.0})
    assert (a.color[..., 0] > b.color[..., 0] + 1e-3).sum() > 20


def test_demo_is_a_lit_scene():
    from softpipe.tools.demo import demo_lighting, render_demo
    kinds = {light.kind for light in demo_lighting().lights}
    assert kinds == {"directional", "point", "spot"}
    fb = render_demo(80, 60)
    assert fb.width == 80 and fb.height == 60
    img = fb.color[..., :3]
    assert np.isfinite(img).all()
    assert img.std() > 0.05                        # not a flat color: lit objects on a floor
