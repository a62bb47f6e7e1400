"""Drawing (softpipe.scenes.drawing): one draw_mesh for the API, scene files and the command line.

Also the scene model's Scene.from_model (what ``softpipe render MODEL`` draws), the
wireframe overlay (softpipe.scenes.drawing.draw_wireframe), and which module may import which.
"""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import softpipe as sp
from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes
from softpipe.scenes.drawing import DrawResult, draw_mesh, render_scene, standard_uniforms
from softpipe.scenes.scene import Scene, program_for
from softpipe.scenes.scenefile import parse_scene
from softpipe.tools.cli import main

SOFTPIPE = Path(sp.__file__).resolve().parent

QUAD = sp.Mesh(np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]]),
               np.array([[0, 1, 2], [0, 2, 3]]), name="quad")   # counter-clockwise seen from +z: its front
FRONT = Camera(eye=(0.0, 0.0, 4.0), fovy=40.0)


def covered(fb: sp.Framebuffer) -> int:
    return int((fb.depth < 1.0).sum())


# ---------------------------------------------------------------------------- draw_mesh


@pytest.mark.parametrize("mirror", [sp.scale(-1.0, 1.0, 1.0), sp.scale(1.0, -1.0, 1.0), sp.scale(1.0, 1.0, -1.0),
                                    sp.compose(sp.rotate_y(30.0), sp.scale(-2.0, 1.0, 1.0))])
def test_a_mirroring_model_matrix_keeps_the_front_faces(mirror):
    # A mirror turns the quad's corners round the other way on the screen. Mirrored in x
    # or y its front (the side its normal shows) still faces the camera, so culling back
    # faces must keep it and culling front faces drop it; mirrored in z its front faces
    # away (the same corners, the normal turned round): the other way about.
    def draw(model, cull, **kw):
        fb = sp.Framebuffer(32, 32)
        draw_mesh(fb, QUAD, FRONT, "normals", model=model, cull=cull, **kw)
        return covered(fb)

    assert np.linalg.det(mirror[:3, :3]) < 0
    everything = draw(mirror, "none")
    assert everything > 100
    if mirror[2, 2] > 0:   # the mirrored normal (0, 0, 1) · M⁻¹ still points at the camera
        assert (draw(mirror, "back"), draw(mirror, "front")) == (everything, 0)
    else:
        assert (draw(mirror, "back"), draw(mirror, "front")) == (0, everything)
    # the mesh's own winding given as clockwise: every answer turns round
    assert draw(mirror, "back", front_face="cw") == draw(mirror, "front")
    assert draw(mirror, "front", front_face="cw") == draw(mirror, "back")


def test_a_mirrored_closed_mesh_shows_its_outside():
    # A cube mirrored in x is the same cube: with back faces culled, the same pixels.
    cube = shapes.cube()
    cam = Camera(eye=(2.0, 1.5, 3.0), fovy=40.0)

    def draw(model):
        fb = sp.Framebuffer(40, 30)
        draw_mesh(fb, cube, cam, "normals", model=model)
        return fb.to_uint8()

    plain, mirrored = draw(None), draw(sp.scale(-1.0, 1.0, 1.0))
    assert (plain[..., :3].any(axis=2) == mirrored[..., :3].any(axis=2)).all()


def test_draw_mesh_returns_a_trace_and_reports_each_draw():
    two = sp.concatenate_meshes([QUAD.replace(material=sp.Material(kd=(1.0, 0.0, 0.0), name="red")),
                                 QUAD.transformed(sp.translate(0.5, 0.5, -1.0))
                                 .replace(material=sp.Material(kd=(0.0, 0.0, 1.0), name="blue"))])
    fb, results = sp.Framebuffer(24, 24), []
    trace = draw_mesh(fb, two, FRONT, "phong", results=results, trace=True)
    assert isinstance(trace, sp.Trace)
    assert [type(r) for r in results] == [DrawResult, DrawResult]     # one draw per material
    assert [r.program for r in results] == ["phong", "phong"] and results[1].trace is trace
    assert len(results[0].primitives) == 2 and "vertex" in results[0].timings
    assert draw_mesh(sp.Framebuffer(8, 8), QUAD, FRONT) is None


def test_draw_mesh_takes_a_texture():
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    red = np.zeros((4, 4, 3), np.uint8)
    red[..., 0] = 255
    fb = sp.Framebuffer(16, 16)
    draw_mesh(fb, QUAD.replace(uvs=uvs), FRONT, "textured", texture=sp.Texture2D(red),
              lighting=sp.Light.directional((0.0, 0.0, -1.0), specular=(0.0, 0.0, 0.0)))
    r, g, b, _ = fb.color[8, 8]
    assert r > 0.3 and g == b == 0                                  # the texture scales kd: only red is left


def test_standard_uniforms_and_lighting_in_eye_space():
    u = standard_uniforms(FRONT, 1.0, sp.translate(1.0, 0.0, 0.0))
    np.testing.assert_allclose(u["model_view"], FRONT.view @ sp.translate(1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="front_face"):
        draw_mesh(sp.Framebuffer(4, 4), QUAD, FRONT, front_face="clockwise")


# ---------------------------------------------------------------------------- the wireframe

WIRE_SCENE = """[render]
width = 24
height = 18
background = [0, 0, 0]
wireframe = true
wireframe_color = [1, 0, 1]
program = "normals"
cull = "none"
[camera]
eye = [0, 0, 5]
fovy = 40
[[meshes]]
shape = "cube"
transform = [{ rotate_y = 30 }, { rotate_x = 20 }]
"""

# The wireframe as the pipeline's own lines draw it ('#': the wire color, '+': the cube, '.': the
# background): the cube's triangles again in polygon mode "line", pulled toward the viewer by a
# polygon offset and tested "lequal" against the surface (softpipe.scenes.drawing.draw_wireframe).
# The cube's back edges (cull = "none" keeps its back faces) are hidden by the depth test; the
# diagonals of the visible faces show. (Until the lines were the pipeline's, a DDA drew them: a few pixels along
# the edges differ from the diamond-exit rule's.) Regenerate by printing
# picture(render_scene(parse_scene(WIRE_SCENE, "wire.toml")).to_uint8()) and checking it by eye.
WIRE_PIXELS = """
........................
........................
......###...............
......#########.........
......#++#####+###......
.....#+++##+++#######...
.....#+++##++++++++##...
.....#++##++++++++##....
.....#+#+#+++++++#+#....
.....##++#++++++#++#....
.....##++#+++++#+++#....
.....#+++#++++#+++#.....
.....#+++#+++#++++#.....
......#++#++#+++++#.....
.......##++#++++###.....
.......####+++####......
........######..........
........................
"""


def picture(img: np.ndarray) -> str:
    wire = (img[..., :3] == (255, 0, 255)).all(axis=2)
    lit = img[..., :3].any(axis=2)
    return "\n" + "\n".join("".join("#" if wire[r, c] else "+" if lit[r, c] else "." for c in range(img.shape[1]))
                            for r in range(img.shape[0])) + "\n"


def test_the_wireframe_is_the_pipelines_lines_over_the_surface():
    img = render_scene(parse_scene(WIRE_SCENE, "wire.toml")).to_uint8()
    assert picture(img) == WIRE_PIXELS


def test_the_command_line_wireframe_is_the_scene_wireframe(tmp_path, capsys):
    path = tmp_path / "wire.toml"
    path.write_text(WIRE_SCENE)
    assert main(["render", str(path), "-o", str(tmp_path / "w.png"), "-q"]) == 0
    capsys.readouterr()
    cli = np.asarray(Image.open(tmp_path / "w.png"))
    assert picture(cli) == WIRE_PIXELS
    assert (cli == np.asarray(render_scene(parse_scene(WIRE_SCENE, "wire.toml")).to_image())).all()


# ---------------------------------------------------------------------------- Scene.from_model


@pytest.mark.parametrize("argv, kwargs", [
    (["suzanne"], {}),
    (["suzanne", "--azimuth", "120", "--elevation", "-15", "--fovy", "50"],
     {"azimuth": 120.0, "elevation": -15.0, "fovy": 50.0}),
])
def test_scene_from_model_is_what_the_command_line_renders(tmp_path, capsys, argv, kwargs):
    out = tmp_path / "cli.png"
    assert main(["render", *argv, "-o", str(out), "--size", "40x30", "-q"]) == 0
    assert "program phong" in capsys.readouterr().out
    scene = Scene.from_model(argv[0], width=40, height=30, **kwargs)
    assert scene.camera is None and scene.lights is None and scene.path == "suzanne"
    assert (np.asarray(Image.open(out)) == np.asarray(render_scene(scene).to_image())).all()


def test_scene_from_model_takes_a_path_a_mesh_and_a_texture(tmp_path):
    obj = tmp_path / "quad.obj"
    obj.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                   "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    Image.new("RGB", (4, 4), (0, 200, 0)).save(tmp_path / "green.png")
    scene = Scene.from_model(obj, texture=tmp_path / "green.png", width=20, height=20, program="normals")
    (quad,) = scene.objects
    assert quad.name == "quad" and quad.texture.width == 4 and scene.program == "normals"
    assert quad.mesh.material.diffuse_texture == str(tmp_path / "green.png")
    assert program_for(quad) == "textured" and program_for(quad, scene.program) == "normals"
    assert Scene.from_model(QUAD).objects[0].texture is None and Scene.from_model(QUAD).path == "quad"
    with pytest.raises(ValueError, match="has no texture coordinates"):
        Scene.from_model(QUAD, texture=tmp_path / "green.png")
    with pytest.raises(ValueError, match="neither a file nor a bundled model"):
        Scene.from_model("bunnie")


def test_scene_from_model_warns_about_an_unreadable_texture(tmp_path):
    (tmp_path / "bad.png").write_text("not an image")
    (tmp_path / "m.mtl").write_text("newmtl m\nmap_Kd bad.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "usemtl m\nf 1/1 2/2 3/3\n")
    with pytest.warns(UserWarning, match="drawn without it"):
        scene = Scene.from_model(tmp_path / "m.obj")
    assert scene.objects[0].texture is None and any("drawn without it" in w for w in scene.warnings)


def test_the_bundled_spot_is_drawn_textured():
    scene = Scene.from_model("spot", width=8, height=8)
    assert program_for(scene.objects[0]) == "textured" and scene.objects[0].texture.width == 1024


# ---------------------------------------------------------------------------- modules


def test_each_name_has_one_home():
    import softpipe.scenes.scene
    import softpipe.scenes.scenefile
    from softpipe.scenes import drawing
    assert sp.draw_mesh is drawing.draw_mesh and sp.Scene is Scene
    for name in ("render_scene", "DrawResult", "draw_wireframe", "draw_object"):
        assert not hasattr(softpipe.scenes.scenefile, name), name         # the reader draws nothing
    assert not hasattr(softpipe.scenes.scene, "draw_mesh")      # the model holds no drawing, not even an alias


def _module_imports(name: str, anywhere: bool) -> set:
    """The softpipe modules ``softpipe/NAME.py`` imports (NAME dotted: ``scenes.scene``), as dotted names
    below softpipe: at import time, or ``anywhere`` (in functions too)."""
    tree = ast.parse((SOFTPIPE / f"{name.replace('.', '/')}.py").read_text())
    found = set()
    for node in (ast.walk(tree) if anywhere else tree.body):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("softpipe."):
            found.add(node.module[len("softpipe."):])
    return found


@pytest.mark.parametrize("module, anywhere, never", [
    # the model draws nothing
    ("scenes.scene", True, {"scenes.drawing", "pipeline.draw", "views.pictures", "scenes.scenefile",
                            "tools.cli", "tools.demo"}),
    # reading draws nothing
    ("scenes.scenefile", False, {"scenes.drawing", "pipeline.draw", "views.pictures", "tools.cli", "tools.demo"}),
    ("scenes.drawing", True, {"tools.cli", "tools.demo"}),
    ("scenes.drawing", False, {"scenes.scenefile"}),
])
def test_lower_modules_do_not_import_higher_ones(module, anywhere, never):
    imports = _module_imports(module, anywhere)
    assert imports, f"{module}: no imports found (is the parser reading the right file?)"
    assert not imports & never


def test_drawing_reads_a_scene_file_only_for_render():
    """draw_mesh and render_scene read no files; softpipe.render(PATH.toml) reads one, in one function."""
    tree = ast.parse((SOFTPIPE / "scenes" / "drawing.py").read_text())
    readers = {fn.name for fn in ast.walk(tree) if isinstance(fn, ast.FunctionDef)
               for node in ast.walk(fn) if isinstance(node, ast.ImportFrom)
               and node.module == "softpipe.scenes.scenefile"}
    assert readers == {"_load_input"}
