"""Scene files (softpipe.scenes.scenefile): every key, every error message, and a small render (softpipe.scenes.drawing)."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import softpipe.scenes.scenefile as scenefile
from softpipe.light.material import Light
from softpipe.pipeline.camera import Camera
from softpipe.scenes.drawing import render_scene
from softpipe.scenes.models import MODELS, model_path
from softpipe.scenes.scene import Scene, default_program, studio_lights
from softpipe.scenes.scenefile import SceneError, SceneWarning, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "scene.toml"

SMALL = """
[render]
width = 64
height = 48
background = [0.0, 0.0, 0.0]
"""

TRI_OBJ = """v 0 0 0
v 1 0 0
v 0 1 0
vt 0 0
vt 1 0
vt 0 1
f 1/1 2/2 3/3
"""


def write(folder: Path, text: str, name: str = "scene.toml") -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def error_of(text: str, tmp_path: Path, name: str = "scene.toml") -> str:
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, text, name))
    message = str(info.value)
    assert "\n" not in message
    return message


def parse(text: str) -> Scene:
    return parse_scene(text, "scene.toml")


# ---------------------------------------------------------------------------- what loads


def test_minimal_scene_has_defaults_and_a_framed_camera():
    scene = parse('[[meshes]]\nshape = "cube"\n')
    assert (scene.width, scene.height, scene.samples, scene.cull) == (640, 480, "1", "back")
    assert scene.camera is None and scene.lights is None  # framed, studio lights
    cam = scene.view_camera()
    assert isinstance(cam, Camera)
    # framed: the cube's corners project centred in the picture, filling 1 / margin of its height
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    clip = cam.projection(640 / 480) @ cam.view @ corners.T
    ndc = clip[:2] / clip[3]
    np.testing.assert_allclose(ndc.min(axis=1), -ndc.max(axis=1), atol=1e-9)
    assert ndc.max() == pytest.approx(1 / 1.1)
    assert len(scene.lighting_for(cam).lights) == 3


def test_every_section_is_read(tmp_path):
    write(tmp_path, TRI_OBJ, "models/tri.obj")
    scene = load_scene(write(tmp_path, "ambient = 0.3\n" + SMALL + """
[camera]
eye = [0, 0, 4]
target = [0, 0, 0]
fovy = 50
near = 1
far = 10

[[lights]]
kind = "directional"
direction = [0, 0, -1]
color = [1, 0.5, 0.25]

[[lights]]
kind = "spot"
position = [0, 2, 0]
spot_direction = [0, -1, 0]
cutoff = 30
exponent = 2
attenuation = [1, 0.5, 0]

[materials.red]
kd = [1, 0, 0]
shininess = 10

[[meshes]]
name = "tri"
obj = "models/tri.obj"
material = "red"

[[meshes]]
shape = "uv_sphere"
radius = 0.5
segments = 8
rings = 4
material = { kd = 0.5 }
program = "depth"
cull = "none"
"""))
    assert scene.ambient == (0.3, 0.3, 0.3)
    assert scene.camera.fovy == 50 and scene.camera.eye == (0.0, 0.0, 4.0)
    assert [light.kind for light in scene.lights] == ["directional", "spot"]
    assert scene.lights[0].diffuse == scene.lights[0].specular == (1.0, 0.5, 0.25)
    assert scene.lights[1].attenuation == (1.0, 0.5, 0.0)
    assert scene.materials["red"].kd == (1.0, 0.0, 0.0)
    tri, ball = scene.objects
    assert tri.name == "tri" and tri.mesh.material.kd == (1.0, 0.0, 0.0) and tri.mesh.uvs is not None
    assert ball.program == "depth" and ball.cull == "none" and ball.mesh.material.kd == (0.5, 0.5, 0.5)
    assert ball.mesh.triangle_count == 2 * 8 * 3


def test_transform_entries_multiply_left_to_right():
    scene = parse("""[[meshes]]
shape = "cube"
transform = [{ translate = [1, 0, 0] }, { scale = 2 }]
[[meshes]]
shape = "cube"
transform = { translate = [1, 0, 0], rotate_z = 90 }
[[meshes]]
shape = "cube"
transform = [{ rotate = [90, 0, 0, 1] }, { scale = [1, 2, 3] }, { matrix = [[1,0,0,5],[0,1,0,0],[0,0,1,0],[0,0,0,1]] }]
""")
    a, b, c = (o.model for o in scene.objects)
    assert np.allclose(a @ [1, 0, 0, 1], [3, 0, 0, 1])           # scaled first, then moved
    assert np.allclose(b @ [1, 0, 0, 1], [1, 1, 0, 1])           # rotated first, then moved
    assert np.allclose(c @ [1, 0, 0, 1], [0, 6, 0, 1])           # matrix, then scale, then rotate


def test_fit_normals_and_an_obj_with_several_materials(tmp_path):
    write(tmp_path, "newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 0 1\n", "two.mtl")
    write(tmp_path, "mtllib two.mtl\nv 0 0 0\nv 4 0 0\nv 0 2 0\nv 4 2 0\n"
                    "usemtl a\nf 1 2 3\nusemtl b\nf 2 4 3\n", "two.obj")
    scene = load_scene(write(tmp_path, '[[meshes]]\nobj = "two.obj"\nfit = 2\nnormals = "flat"\n'))
    assert [o.mesh.material.kd for o in scene.objects] == [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    lo, hi = scene.bounds()
    assert np.allclose(hi - lo, [2.0, 1.0, 0.0])


def test_a_material_texture_is_loaded(tmp_path):
    from PIL import Image
    Image.new("RGB", (4, 4), (255, 0, 0)).save(tmp_path / "red.png")
    write(tmp_path, TRI_OBJ, "tri.obj")
    scene = load_scene(write(tmp_path, '[materials.m]\ndiffuse_texture = "red.png"\n'
                                       '[[meshes]]\nobj = "tri.obj"\nmaterial = "m"\n'))
    obj = scene.objects[0]
    assert obj.texture is not None and obj.texture.width == 4
    assert obj.mesh.material.diffuse_texture == str(tmp_path / "red.png")


def test_obj_warnings_are_kept_and_issued(tmp_path):
    write(tmp_path, "mtllib missing.mtl\n" + TRI_OBJ, "tri.obj")
    path = write(tmp_path, '[[meshes]]\nobj = "tri.obj"\n')
    with pytest.warns(SceneWarning, match="missing.mtl"):
        scene = load_scene(path)
    assert any("missing.mtl" in w for w in scene.warnings)


@pytest.mark.skipif(not model_path("bunny").exists(), reason="the bundled models are not installed")
def test_the_example_scene_loads():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = load_scene(EXAMPLE)
    names = [o.name for o in scene.objects]
    assert names == ["floor", "bunny", "spot", "teapot", "ball", "ring"]
    assert len(scene.lights) == 3 and {light.kind for light in scene.lights} == {"directional", "point", "spot"}
    assert next(o for o in scene.objects if o.name == "spot").texture is not None


def test_obj_may_name_a_bundled_model(tmp_path):
    scene = load_scene(write(tmp_path, '[[meshes]]\nobj = "suzanne"\n[[meshes]]\nobj = "spot"\n'))
    suzanne, spot = scene.objects
    assert suzanne.mesh.triangle_count == 968 and suzanne.name == "suzanne"
    assert spot.texture is not None and spot.texture.width == 1024       # the bundled cow comes with its texture
    assert spot.mesh.material.diffuse_texture.endswith("spot_texture.png")


def test_a_bare_word_is_a_model_name_only_when_it_is_one(tmp_path):
    write(tmp_path, TRI_OBJ, "suzanne.obj")                              # a suffix: a file, not the model
    write(tmp_path, TRI_OBJ, "models/bunny")                             # a folder: a file, not the model
    write(tmp_path, TRI_OBJ, "tri")                                      # a bare word that names no model
    scene = load_scene(write(tmp_path, '[[meshes]]\nobj = "suzanne.obj"\n[[meshes]]\nobj = "models/bunny"\n'
                                       '[[meshes]]\nobj = "tri"\n'))
    assert [o.mesh.triangle_count for o in scene.objects] == [1, 1, 1]
    message = error_of('[[meshes]]\nobj = "bunnie"\n', tmp_path)
    assert f"key 'obj' in [[meshes]] #1: file not found: {tmp_path / 'bunnie'} (nor is 'bunnie' a bundled " \
           f"model: {', '.join(MODELS)})" in message
    assert "bundled" not in error_of('[[meshes]]\nobj = "nope.obj"\n', tmp_path)


# ---------------------------------------------------------------------------- rendering


def small_scene(extra: str = "") -> Scene:
    return parse(SMALL + extra + '\n[[meshes]]\nshape = "cube"\ntransform = { rotate_y = 30 }\n')


def test_a_small_scene_renders():
    scene = small_scene()
    results = []
    fb = render_scene(scene, results=results)
    assert (fb.width, fb.height) == (64, 48)
    img = fb.to_uint8(alpha=False)
    assert img[24, 32].any() and not img[0, 0].any()      # the cube in the middle, black corners
    assert len(results) == 1 and results[0].program == default_program()
    assert len(results[0].primitives) > 0


def test_wireframe_draws_edges_over_the_image():
    plain = render_scene(small_scene()).to_uint8()
    wired = render_scene(small_scene("wireframe = true\nwireframe_color = [1, 0, 1]\n")).to_uint8()
    changed = (plain != wired).any(axis=2)
    assert changed.sum() > 20
    assert (wired[changed][:, :3] == (255, 0, 255)).all()


def test_the_wireframe_color_is_a_framebuffer_color_and_may_be_negative():
    """Unlike a light's or a material's color (>= 0), it is written to the framebuffer, which is unclamped."""
    assert parse('[render]\nwireframe_color = [-0.5, 0, 2]\n[[meshes]]\nshape = "cube"\n').wireframe_color == \
        (-0.5, 0.0, 2.0)
    assert parse('[render]\nwireframe_color = 0.5\n[[meshes]]\nshape = "cube"\n').wireframe_color == (0.5,) * 3
    with pytest.raises(SceneError, match=r"key 'ambient' in the top level must be a number >= 0, got float -0\.5"):
        parse('ambient = -0.5\n[[meshes]]\nshape = "cube"\n')


def test_a_mirroring_transform_keeps_front_faces():
    def coverage(transform):
        scene = parse(SMALL + f'[camera]\neye = [0, 0, 5]\n[[meshes]]\nshape = "cube"\ntransform = {transform}\n')
        return render_scene(scene).to_uint8()[..., :3].any(axis=2).sum()
    assert coverage("{ scale = 1 }") == coverage("{ scale = [-1, 1, 1] }") > 100


def test_tracing_keeps_every_draw():
    scene = parse(SMALL + '[[meshes]]\nshape = "cube"\n[[meshes]]\nshape = "plane"\n')
    results = []
    render_scene(scene, trace=True, results=results)
    assert [r.trace is not None for r in results] == [True, True]


# ---------------------------------------------------------------------------- errors: each names file, table, key


def test_unknown_key_names_its_table_and_the_allowed_keys(tmp_path):
    message = error_of('[[meshes]]\nshape = "cube"\n[[lights]]\nkind = "point"\nposition = [0, 1, 0]\n'
                       '[[lights]]\nkind = "point"\nposition = [1, 1, 1]\ncolour = [1, 0, 0]\n', tmp_path)
    assert message.startswith(str(tmp_path / "scene.toml") + ": unknown key 'colour' in [[lights]] #2")
    assert "did you mean 'color'?" in message and "expected one of kind, name, color" in message


@pytest.mark.parametrize("text, expected", [
    ('colour = 1\n[[meshes]]\nshape = "cube"\n', "unknown key 'colour' in the top level; expected one of ambient"),
    ('[render]\nsize = 3\n[[meshes]]\nshape = "cube"\n', "unknown key 'size' in [render]"),
    ('[camera]\nfov = 3\n[[meshes]]\nshape = "cube"\n', "unknown key 'fov' in [camera] (did you mean 'fovy'?)"),
    ('[materials.gold]\nkdd = 1\n[[meshes]]\nshape = "cube"\n', "unknown key 'kdd' in [materials.gold]"),
    ('[[meshes]]\nshape = "uv_sphere"\nradiuss = 1\n', "unknown key 'radiuss' in [[meshes]] #1 (did you mean "
                                                        "'radius'?); expected one of name, obj, shape"),
    ('[[meshes]]\nname = "ball"\nshape = "cube"\nradius = 1\n', "unknown key 'radius' in [[meshes]] #1 ('ball')"),
    ('[[meshes]]\nshape = "cube"\nmaterial = { kd = 1, shine = 3 }\n',
     "unknown key 'shine' in [[meshes]] #1 material"),
    ('[[meshes]]\nshape = "cube"\ntransform = [{ spin = 3 }]\n',
     "unknown transform 'spin' in entry 1 of key 'transform' in [[meshes]] #1; expected one of translate"),
])
def test_unknown_keys(text, expected):
    with pytest.raises(SceneError) as info:
        parse(text)
    assert expected in str(info.value)
    assert str(info.value).startswith("scene.toml: ")


@pytest.mark.parametrize("text, expected", [
    ('[render]\nwidth = "big"\n', "key 'width' in [render] must be an integer, got string 'big'"),
    ('[render]\nwidth = 2.5\n', "key 'width' in [render] must be an integer, got float 2.5"),
    ('[render]\nheight = 0\n', "key 'height' in [render] must be between 1 and 16384 pixels, got 0"),
    ('[render]\nbackground = [1, 0]\n', "key 'background' in [render] must be an array of 3 or 4 numbers"),
    ('[render]\nbackground = [inf, 0, 0]\n',
     "key 'background' in [render] must hold finite numbers, got float inf in an array of 3"),
    ('[render]\nwireframe = "yes"\n', "key 'wireframe' in [render] must be true or false, got string 'yes'"),
    ('[render]\ncull = "sideways"\n', "key 'cull' in [render] must be one of 'back', 'front', 'none'"),
    ('[render]\nsamples = "grid5"\n', "key 'samples' in [render] is not a sample pattern"),
    ('[render]\nprogram = "phongy"\n', "key 'program' in [render] names an unknown program 'phongy'; registered"),
    ('[render]\nwidth = 1979-05-27\n', "key 'width' in [render] must be an integer, got date '1979-05-27'"),
    ('[render]\nwidth = 16384\nheight = 16384\nsamples = "grid4"\n', "exceeds the limit MAX_TOTAL_SAMPLES"),
    ('[camera]\neye = [0, 0]\n', "key 'eye' in [camera] must be an array of 3 numbers, got an array of 2"),
    ('[camera]\neye = [0, 0, 0]\n', "[camera]: look_at: eye and target are the same point"),
    ('[camera]\nframe = true\neye = [0, 0, 3]\n', "key 'eye' in [camera] cannot be used here: frame = true"),
    ('[camera]\neye = [0, 0, 3]\nazimuth = 10\n', "key 'azimuth' in [camera] cannot be used here"),
    ('[camera]\nfovy = 200\n', "[camera]: Camera.fovy must be in (0, 180) degrees"),
    ('[camera]\nframe = 1\n', "key 'frame' in [camera] must be true or false, got integer 1"),
    ('ambient = "dim"\n', "key 'ambient' in the top level must be a color: unknown color 'dim'"),
    ('[[lights]]\nposition = [0, 0, 0]\n', "[[lights]] #1: needs key 'kind': 'directional', 'point' or 'spot'"),
    ('[[lights]]\nkind = "laser"\n', "key 'kind' in [[lights]] #1 must be one of 'directional', 'point', 'spot'"),
    ('[[lights]]\nkind = "point"\n', "[[lights]] #1: Light.position is required for a point light"),
    ('[[lights]]\nkind = "point"\nposition = [0, 0, 0]\ncolor = 1\ndiffuse = 1\n',
     "key 'diffuse' in [[lights]] #1 cannot be given with 'color'"),
    ('[[lights]]\nkind = "spot"\nposition = [0, 0, 0]\nspot_direction = [0, -1, 0]\ncutoff = 120\n',
     "[[lights]] #1: Light.cutoff must be in [0, 90] degrees"),
    ('lights = 3\n', "'lights' must be an array of tables ([[lights]]), got integer 3"),
    ('[materials.gold]\nkd = [1, 2]\n', "key 'kd' in [materials.gold] must be a number (gray), an array [r, g, b] or "
                                       "a color name"),
    ('[materials.gold]\nkd = -1\n', "key 'kd' in [materials.gold] must be a number >= 0, got integer -1"),
    ('[materials.gold]\nkd = [1, -1, 1]\n', "key 'kd' in [materials.gold] must hold numbers >= 0, got integer -1 in "
                                             "an array of 3"),
    ('[materials.gold]\nkd = "#ff000080"\n', "key 'kd' in [materials.gold] must be an RGB color (no alpha), got "
                                               "string '#ff000080'"),
    ('materials = 3\n', "'materials' must be a table of [materials.NAME] tables, got integer 3"),
    ('[materials]\ngold = 3\n', "[materials.gold] must be a table, got integer 3"),
])
def test_wrong_values(text, expected):
    with pytest.raises(SceneError) as info:
        parse(text + '\n[[meshes]]\nshape = "cube"\n')
    assert expected in str(info.value)


@pytest.mark.parametrize("mesh, expected", [
    ('shape = "sphere"', "key 'shape' in [[meshes]] #1 must be one of 'plane', 'cube', 'uv_sphere'"),
    ('shape = "cube"\nobj = "x.obj"', "[[meshes]] #1: needs either 'obj' (an OBJ file) or 'shape'"),
    ('name = "x"', "[[meshes]] #1 ('x'): needs either 'obj' (an OBJ file) or 'shape' (one of plane, cube"),
    ('shape = "uv_sphere"\nradius = -1', "key 'shape' in [[meshes]] #1: uv_sphere: radius must be a positive number"),
    ('shape = "uv_sphere"\nsegments = 2.5', "key 'segments' in [[meshes]] #1 must be an integer, got float 2.5"),
    ('shape = "cylinder"\ncaps = 1', "key 'caps' in [[meshes]] #1 must be true or false"),
    ('shape = "uv_sphere"\nsegments = 100000\nrings = 100000',
     "key 'shape' in [[meshes]] #1 makes the scene's meshes hold 20,000,000,000 triangles, more than the limit "
     "MAX_SCENE_TRIANGLES"),
    ('shape = "cube"\nsize = ' + "9" * 400, "key 'size' in [[meshes]] #1 must be a number, got integer 999999999999"),
    ('shape = "cube"\nfit = 0', "key 'fit' in [[meshes]] #1 must be a positive number, got integer 0"),
    ('shape = "cube"\nnormals = "smooth"', "key 'normals' in [[meshes]] #1 must be one of 'auto', 'area', 'angle'"),
    ('shape = "cube"\nmaterial = "gold"', "key 'material' in [[meshes]] #1 names an undefined material 'gold'; "
                                          "[materials] defines: none"),
    ('shape = "cube"\nmaterial = 3', "key 'material' in [[meshes]] #1 must be a material name or an inline table"),
    ('shape = "cube"\nprogram = "nope"', "key 'program' in [[meshes]] #1 names an unknown program 'nope'"),
    ('shape = "cube"\ntransform = 3', "key 'transform' in [[meshes]] #1 must be an array of one-key tables"),
    ('shape = "cube"\ntransform = { scale = 0 }', "key 'transform' in [[meshes]] #1 is singular"),
    ('shape = "cube"\ntransform = [{ scale = 1, translate = [0, 0, 0] }]',
     "entry 1 of key 'transform' in [[meshes]] #1 must be a table with one key"),
    ('shape = "cube"\ntransform = [{ translate = [0, 0] }]',
     "'translate' in entry 1 of key 'transform' in [[meshes]] #1 must be an array of 3 numbers"),
    ('shape = "cube"\ntransform = [{ rotate = [30, 0, 0, 0] }]', "needs a nonzero axis"),
    ('shape = "cube"\ntransform = [{ matrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]] }]',
     "must be affine: its last row must be [0, 0, 0, 1]"),
])
def test_mesh_errors(mesh, expected):
    with pytest.raises(SceneError) as info:
        parse("[[meshes]]\n" + mesh + "\n")
    assert expected in str(info.value)
    assert info.value.table.startswith("[[meshes]] #1")


def test_no_meshes():
    with pytest.raises(SceneError, match=r"the scene has no \[\[meshes\]\]"):
        parse("[render]\nwidth = 64\n")
    with pytest.raises(SceneError, match=r"'meshes' must be an array of tables \(\[\[meshes\]\]\), got a table"):
        parse('[meshes]\nshape = "cube"\n')


def test_the_triangle_limit_counts_every_mesh(monkeypatch):
    monkeypatch.setattr(scenefile, "MAX_SCENE_TRIANGLES", 100)
    text = '[[meshes]]\nshape = "cube"\n' * 8 + '[[meshes]]\nshape = "cube"\nname = "last"\n'  # 9 × 12 triangles
    with pytest.raises(SceneError, match=r"\[\[meshes\]\] #9 \('last'\) makes the scene's meshes hold 108 "):
        parse(text)


def test_missing_and_bad_files(tmp_path):
    message = error_of('[[meshes]]\nobj = "models/nope.obj"\n', tmp_path)
    assert f"key 'obj' in [[meshes]] #1: file not found: {tmp_path / 'models' / 'nope.obj'}" in message
    (tmp_path / "folder.obj").mkdir()
    assert "is a directory, not a file" in error_of('[[meshes]]\nobj = "folder.obj"\n', tmp_path)
    write(tmp_path, "v 0 0 0\nv 1 0 0\nf 1 2 3\n", "bad.obj")
    message = error_of('[[meshes]]\nobj = "bad.obj"\n', tmp_path)
    assert f"key 'obj' in [[meshes]] #1: {tmp_path / 'bad.obj'}:3: " in message
    write(tmp_path, "# nothing\nvt 0 0\n", "empty.obj")     # (vertices alone would be a point cloud)
    assert "empty.obj has no faces" in error_of('[[meshes]]\nobj = "empty.obj"\n', tmp_path)
    message = error_of('[materials.m]\ndiffuse_texture = "nope.png"\n[[meshes]]\nshape = "cube"\n', tmp_path)
    assert "key 'diffuse_texture' in [materials.m]: file not found:" in message
    write(tmp_path, "not an image", "fake.png")
    message = error_of('[materials.m]\ndiffuse_texture = "fake.png"\n[[meshes]]\nshape = "cube"\n', tmp_path)
    assert "key 'diffuse_texture' in [materials.m]: Texture2D: cannot read image file" in message


def test_the_scene_file_itself(tmp_path):
    with pytest.raises(SceneError, match=r"nope\.toml: scene file not found"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(SceneError, match="is a directory, not a scene file"):
        load_scene(tmp_path)
    (tmp_path / "latin1.toml").write_bytes(b'# caf\xe9\n[[meshes]]\nshape = "cube"\n')
    with pytest.raises(SceneError, match=r"latin1\.toml:1: not UTF-8 text \(byte 5\)"):
        load_scene(tmp_path / "latin1.toml")
    (tmp_path / "bom.toml").write_bytes(b'\xef\xbb\xbf[[meshes]]\nshape = "cube"\n')
    assert load_scene(tmp_path / "bom.toml").objects


@pytest.mark.parametrize("text, expected", [
    ('[render]\nwidth = 64\nheight = \n', "scene.toml:3: TOML syntax error: Invalid value"),
    ('[render]\nwidth = 64\n[render]\n', "scene.toml:3: TOML syntax error: Cannot declare ('render',) twice"),
    ('\n\na = [1, 2', "scene.toml:3: TOML syntax error:"),
    ("a = " + "[" * 3000, "scene.toml: TOML error: arrays or tables nested too deeply"),
    ("a = " + "1" * 5000, "scene.toml: TOML error: an integer has too many digits"),
])
def test_toml_errors_name_the_line(text, expected, tmp_path):
    assert error_of(text, tmp_path).startswith(str(tmp_path / expected))


def test_scene_error_is_a_value_error_with_fields():
    with pytest.raises(ValueError) as info:
        parse('[[meshes]]\nshape = "cube"\n[render]\nwidth = "x"\n')
    e = info.value
    assert isinstance(e, SceneError)
    assert (e.file, e.table, e.key) == ("scene.toml", "[render]", "width")


def test_studio_lights_follow_the_camera():
    cam = Camera(eye=(0, 0, 5))
    turned = Camera(eye=(5, 0, 0))
    key, key_turned = studio_lights(cam)[0], studio_lights(turned)[0]
    assert isinstance(key, Light) and key.kind == "directional"
    # the same direction in eye space: rotate the world by 90° about y
    assert np.allclose(cam.view[:3, :3] @ key.direction, turned.view[:3, :3] @ key_turned.direction)


def test_meshes_too_far_away_to_frame():
    with pytest.raises(SceneError, match=r"\[camera\]: cannot frame meshes that reach 1e\+308 from the origin"):
        parse('[[meshes]]\nshape = "cube"\ntransform = { translate = [1e308, 0, 0], scale = 10 }\n')


def test_looking_straight_down_is_framed():
    scene = parse(SMALL + '[camera]\nelevation = 90\n[[meshes]]\nshape = "cube"\n')
    cam = scene.view_camera()
    assert cam.eye[1] > 1 and np.allclose(cam.eye[::2], 0, atol=1e-9)


def test_colors_may_be_named_in_a_scene_file():
    scene = parse_scene('[materials.m]\nkd = "red"\nks = "#808080"\n[[meshes]]\nshape = "cube"\nmaterial = "m"\n')
    m = scene.objects[0].mesh.material
    assert tuple(m.kd) == (1.0, 0.0, 0.0) and tuple(m.ks) == (128 / 255,) * 3
    with pytest.raises(SceneError, match=r"kd.*unknown color 'redd' \(did you mean 'red'\?\)"):
        parse_scene('[materials.m]\nkd = "redd"\n[[meshes]]\nshape = "cube"\nmaterial = "m"\n')


MEDIUM_SCENE = """
[materials.g]
kd = 0.1
kt = [0.9, 0.9, 0.9]
{extra}
[[meshes]]
shape = "cube"
material = "g"
"""


def test_a_material_names_its_medium_and_its_falloff():
    """ior by a medium's name (FORMULAS §17), the falloff inside (§15): T per unit distance, or Glassner's a."""
    m = parse_scene(MEDIUM_SCENE.format(extra='ior = "glass"\ntransmittance = [0.9, 0.5, 0.2]'), "s.toml").materials["g"]
    assert (m.ior, m.transmittance, m.falloff) == (1.52, (0.9, 0.5, 0.2), "power")
    m = parse_scene(MEDIUM_SCENE.format(extra='ior = 1.33\nfalloff = "glassner"\nfalloff_a = 1.5'), "s.toml").materials["g"]
    assert (m.ior, m.falloff, m.falloff_a) == (1.33, "glassner", 1.5)


@pytest.mark.parametrize("extra, message", [
    ('ior = "glas"', "unknown medium 'glas'; the named media (FORMULAS §17) are vacuum 1.0"),
    ('falloff = "linear"', "Material.falloff must be 'power' (T^d) or 'glassner'"),
    ("transmittance = 2", "Material.transmittance is a share per unit distance, in [0, 1]"),
    ("falloff_a = -1", "[materials.g]: Material.falloff_a must be a number >= 0, got float -1.0"),
    ("transmitance = 0.5", "unknown key 'transmitance' in [materials.g] (did you mean 'transmittance'?)"),
])
def test_medium_mistakes_name_the_table_and_the_value(extra, message):
    with pytest.raises(SceneError) as e:
        parse_scene(MEDIUM_SCENE.format(extra=extra), "s.toml")
    assert str(e.value).startswith("s.toml") and "[materials.g]" in str(e.value) and message in str(e.value)
