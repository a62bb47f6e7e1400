"""``program=`` takes a Program or a shader function wherever a program name is taken (issue #32).

``softpipe.render``, ``turntable``, ``draw_mesh``, a scene file's ``program`` and the
command line's ``--program`` take a registered name as before, a Program, a
fragment shader function (drawn with ``standard_vertex``) or ``"module:function"``
(``"file.py:function"``), each drawing the same pixels; what cannot be found is
named.
"""
import sys
import textwrap

import numpy as np
import pytest
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.shading import Program, dot, normalize, standard_vertex

SIZE = dict(width=24, height=24)


def toon(varyings, uniforms, frag):
    d = dot(normalize(varyings.normal), (0.0, 0.0, 1.0))
    b = 0.9 if d > 0.5 else 0.4
    return (b, b * 0.5, 0.2, 1.0)


TOON = Program("toon", standard_vertex, toon)
MODULE = textwrap.dedent('''
    from softpipe.shading import Program, dot, normalize, standard_vertex


    def toon(varyings, uniforms, frag):
        d = dot(normalize(varyings.normal), (0.0, 0.0, 1.0))
        b = 0.9 if d > 0.5 else 0.4
        return (b, b * 0.5, 0.2, 1.0)


    TOON = Program("toon", standard_vertex, toon)
    NUMBER = 3
''')


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    """``my_shaders.py`` in the current folder, as a student's script has it."""
    (tmp_path / "my_shaders.py").write_text(MODULE)
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    sys.modules.pop("my_shaders", None)


@pytest.fixture(scope="module")
def expected():
    fb = sp.render("bunny", program=TOON, **SIZE)
    pixels = fb.to_uint8(alpha=False)
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) == 3      # the background and two bands
    return pixels


@pytest.mark.parametrize("program", [TOON, toon, "my_shaders:toon", "my_shaders:TOON", "my_shaders.py:toon"])
def test_render_takes_a_program_a_function_or_module_function(user_module, expected, program):
    fb = sp.render("bunny", program=program, **SIZE)
    assert np.array_equal(fb.to_uint8(alpha=False), expected)


def test_draw_mesh_takes_a_shader_function(expected):
    scene = sp.Scene.from_model("bunny", program=TOON, **SIZE)
    fb = sp.render(scene)
    assert np.array_equal(fb.to_uint8(alpha=False), expected)
    fb2 = sp.Framebuffer(24, 24)
    fb2.clear(scene.background)
    camera = scene.view_camera()
    for obj in scene.drawn_objects(camera):
        sp.draw_mesh(fb2, obj.mesh, camera, toon, model=obj.model, lighting=scene.lighting_for(camera))
    assert np.array_equal(fb2.to_uint8(alpha=False), expected)


def test_turntable_takes_a_shader_function(tmp_path):
    sp.turntable("bunny", tmp_path / "a.gif", frames=2, program=toon, **SIZE)
    sp.turntable("bunny", tmp_path / "b.gif", frames=2, program=TOON, **SIZE)
    assert (tmp_path / "a.gif").read_bytes() == (tmp_path / "b.gif").read_bytes()


def test_a_scene_file_names_module_function(user_module, expected):
    (user_module / "scene.toml").write_text('[render]\nprogram = "my_shaders:toon"\nwidth = 24\nheight = 24\n'
                                            '[[meshes]]\nobj = "bunny"\n')
    fb = sp.render(str(user_module / "scene.toml"))
    reference = sp.render(str(user_module / "scene.toml"), program=TOON)
    assert np.array_equal(fb.to_uint8(alpha=False), reference.to_uint8(alpha=False))
    assert len(np.unique(fb.to_uint8(alpha=False).reshape(-1, 3), axis=0)) == 3


def test_the_command_line_takes_module_function(user_module, expected, capsys):
    code, out, err = run_cli(capsys, "render", "bunny", "--size", "24x24", "--program", "my_shaders:toon",
                             "-o", user_module / "out.png")
    assert code == 0, err
    assert "program toon" in out
    assert np.array_equal(np.asarray(Image.open(user_module / "out.png").convert("RGB")), expected)


@pytest.mark.parametrize("program, message", [
    ("my_shaders:nope", "program: 'my_shaders:nope': module my_shaders has no 'nope'"),
    ("no_such_module:toon", "program: 'no_such_module:toon': cannot import 'no_such_module': "
                            "No module named 'no_such_module'"),
    ("my_shaders:NUMBER", "program: 'my_shaders:NUMBER' names an int, not a Program or a fragment shader function"),
    ("missing.py:toon", "program: 'missing.py:toon': missing.py: no such file"),
])
def test_what_cannot_be_found_is_named(user_module, program, message):
    with pytest.raises(ValueError) as info:
        sp.render("bunny", program=program, **SIZE)
    assert str(info.value) == message


def test_the_command_line_names_what_cannot_be_found(user_module, capsys):
    code, out, err = run_cli(capsys, "render", "bunny", "--program", "my_shaders:nope", "-o", user_module / "x.png")
    assert code != 0
    assert "--program: 'my_shaders:nope': module my_shaders has no 'nope'" in err
    assert not (user_module / "x.png").exists()
