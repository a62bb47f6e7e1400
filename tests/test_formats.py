"""PLY, STL and glTF 2.0 read through trimesh (softpipe/scenes/formats.py, docs/formats.md).

Every file is written here, small and with known numbers: by hand (ASCII PLY and STL,
glTF's JSON with its buffer inline or in a .glb's binary chunk) or with trimesh's exporters
(binary PLY and STL). The coordinates are exact in float32, so a file's mesh can equal the
same mesh read from OBJ bit for bit, and so can its picture.
"""
from __future__ import annotations

import base64
import io
import json
import struct
import sys
import warnings

import numpy as np
import pytest
from conftest import run_cli
from PIL import Image

import softpipe as sp
from softpipe.scenes.formats import FormatError, FormatWarning, MissingExtraError, load_mesh
from softpipe.scenes.obj import load_obj
from softpipe.scenes.scenefile import SceneError, load_scene

trimesh = pytest.importorskip("trimesh")

W, H = 48, 36

# A tetrahedron whose every coordinate is exact in float32 (PLY's float, glTF's FLOAT).
TETRA_P = np.array([[0, 0, 0], [1.25, 0, 0.125], [0.25, 0.875, 0.25], [0.25, 0.25, 1.375]])
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
TETRA_OBJ = "".join(f"v {x} {y} {z}\n" for x, y, z in TETRA_P) + "".join(
    f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in TETRA_F)


def write_ply(path, positions, faces=(), normals=None, uvs=None, fmt="%r"):
    """An ASCII PLY, written by hand."""
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else []) + (
        ["s", "t"] if uvs is not None else [])
    lines = ["ply", "format ascii 1.0", f"element vertex {len(positions)}"]
    lines += [f"property float {p}" for p in props]
    if len(faces):
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    for i, p in enumerate(positions):
        row = list(p) + (list(normals[i]) if normals is not None else []) + (list(uvs[i]) if uvs is not None else [])
        lines.append(" ".join(fmt % float(v) if isinstance(v, (int, float, np.floating)) else str(v) for v in row))
    lines += [f"{len(f)} " + " ".join(str(int(i)) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_stl(path, positions, faces):
    """An ASCII STL (a facet normal of zeros: softpipe does not read them)."""
    out = ["solid t"]
    for f in faces:
        out += ["facet normal 0 0 0", "outer loop"] + [f"vertex {' '.join(repr(float(c)) for c in positions[i])}"
                                                       for i in f] + ["endloop", "endfacet"]
    path.write_text("\n".join(out + ["endsolid t"]) + "\n")
    return path


def render_bytes(model, **kw):
    return np.asarray(sp.render(model, width=W, height=H, **kw).to_image())


# ---------------------------------------------------------------------------- glTF written by hand


class GLTF:
    """A glTF 2.0 document built up in the test: one buffer, accessors, meshes, nodes."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": [],
                    "meshes": [], "nodes": [], "scenes": [{"nodes": []}], "scene": 0}

    def accessor(self, array, kind):
        a = np.ascontiguousarray(array, np.uint16 if kind == "SCALAR" else np.float32)
        while len(self.bin) % 4:
            self.bin += b"\0"
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": a.nbytes})
        self.bin += a.tobytes()
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": 5123 if kind == "SCALAR" else 5126,
               "count": len(a), "type": kind}
        if kind == "VEC3":
            acc["min"], acc["max"] = a.min(axis=0).tolist(), a.max(axis=0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, positions, faces, normals=None, uvs=None, material=None, name="m"):
        attributes = {"POSITION": self.accessor(positions, "VEC3")}
        if normals is not None:
            attributes["NORMAL"] = self.accessor(normals, "VEC3")
        if uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(uvs, "VEC2")
        prim = {"attributes": attributes, "indices": self.accessor(np.ravel(faces), "SCALAR")}
        if material is not None:
            prim["material"] = material
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def node(self, root=True, **node):
        self.doc["nodes"].append(node)
        if root:
            self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def material(self, name, **pbr):
        self.doc.setdefault("materials", []).append({"name": name, "pbrMetallicRoughness": pbr})
        return len(self.doc["materials"]) - 1

    def image(self, png: bytes, uri=None):
        images = self.doc.setdefault("images", [])
        images.append({"uri": uri or "data:image/png;base64," + base64.b64encode(png).decode()})
        self.doc.setdefault("textures", []).append({"source": len(images) - 1})
        return len(self.doc["textures"]) - 1

    def write(self, path):
        doc = json.loads(json.dumps(self.doc))
        if path.suffix == ".glb":
            doc["buffers"] = [{"byteLength": len(self.bin)}]
            text = json.dumps(doc).encode()
            text += b" " * (-len(text) % 4)
            data = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
            body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
            path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
        else:
            doc["buffers"] = [{"byteLength": len(self.bin),
                               "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
            path.write_text(json.dumps(doc))
        return path


def png(array) -> bytes:
    f = io.BytesIO()
    Image.fromarray(np.asarray(array, np.uint8)).save(f, format="PNG")
    return f.getvalue()


def srgb_decode(byte):
    c = np.asarray(byte, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


QUAD_P = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_N = np.tile([0.0, 0.0, 1.0], (4, 1))
QUAD_GLTF_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float64)   # glTF: (0, 0) is the image's top left
#: Four 4×4-texel quadrants: top left, top right / bottom left, bottom right (as the image is stored).
QUADRANTS = np.array([[[200, 30, 10], [20, 180, 40]], [[10, 60, 220], [250, 250, 120]]], np.uint8)
IMAGE = np.repeat(np.repeat(QUADRANTS, 4, axis=0), 4, axis=1)


# ---------------------------------------------------------------------------- PLY and STL


def test_ply_reads_positions_triangles_normals_and_uvs_exactly(tmp_path):
    normals = np.array([[0, 0, 1], [0, 0.5, 0.5], [0.25, 0, 1], [1, 0, 0]])
    uvs = np.array([[0, 0], [1, 0], [0.5, 1], [0.25, 0.75]])
    mesh = load_mesh(write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F, normals, uvs))
    assert mesh.name == "t" and mesh.positions.dtype == np.float64
    assert np.array_equal(mesh.positions, TETRA_P) and np.array_equal(mesh.indices, TETRA_F)
    assert np.array_equal(mesh.normals, normals) and np.array_equal(mesh.uvs, uvs)
    assert mesh.source.format == "PLY" and mesh.source.counts == {"vertices": 4, "triangles": 4, "points": 0}


def test_a_file_without_normals_or_uvs_has_none(tmp_path):
    mesh = load_mesh(write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F))
    assert mesh.normals is None and mesh.uvs is None      # the renderer's own normals, as for an OBJ


def test_stl_corners_are_welded_where_their_positions_are_equal(tmp_path):
    mesh = load_mesh(write_stl(tmp_path / "t.stl", TETRA_P, TETRA_F))
    assert mesh.vertex_count == 4 and mesh.triangle_count == 4
    # numbered in order of first use: the corners of triangle 0, then the new one of triangle 1
    assert np.array_equal(mesh.positions, TETRA_P[[0, 2, 1, 3]])
    assert np.array_equal(mesh.positions[mesh.indices], TETRA_P[TETRA_F])
    assert mesh.normals is None


def test_binary_ply_and_stl_from_trimeshs_exporters(tmp_path):
    source = trimesh.Trimesh(TETRA_P, TETRA_F, process=False)
    (tmp_path / "b.ply").write_bytes(source.export(file_type="ply", encoding="binary"))
    (tmp_path / "b.stl").write_bytes(source.export(file_type="stl"))
    ply, stl = load_mesh(tmp_path / "b.ply"), load_mesh(tmp_path / "b.stl")
    assert np.array_equal(ply.positions, TETRA_P) and np.array_equal(ply.indices, TETRA_F)
    assert np.array_equal(stl.positions[stl.indices], TETRA_P[TETRA_F]) and stl.vertex_count == 4


def test_polygons_of_a_ply_are_split_into_triangles(tmp_path):
    quad = load_mesh(write_ply(tmp_path / "q.ply", QUAD_P, [[0, 1, 2, 3]]))
    assert quad.indices.tolist() == [[0, 1, 2], [2, 3, 0]]
    five = np.vstack([QUAD_P, [[0, 2, 0]]])
    pent = load_mesh(write_ply(tmp_path / "p.ply", five, [[0, 1, 2, 4, 3]]))
    assert pent.indices.tolist() == [[0, 1, 2], [0, 2, 4], [0, 4, 3]]


@pytest.mark.parametrize("kind", ["ascii.ply", "ascii.stl", "binary.ply", "plain.glb"])
def test_ply_stl_and_gltf_render_byte_for_byte_as_the_same_obj(tmp_path, kind):
    (tmp_path / "t.obj").write_text(TETRA_OBJ)
    path = tmp_path / f"t.{kind.split('.')[1]}"
    if kind == "ascii.ply":
        write_ply(path, TETRA_P, TETRA_F)
    elif kind == "ascii.stl":
        write_stl(path, TETRA_P, TETRA_F)
    elif kind == "binary.ply":
        path.write_bytes(trimesh.Trimesh(TETRA_P, TETRA_F, process=False).export(file_type="ply"))
    else:       # no material, no normals: softpipe's default material and normals, as the OBJ's
        g = GLTF()
        g.node(mesh=g.mesh(TETRA_P, TETRA_F))
        g.write(path)
    assert np.array_equal(load_obj(tmp_path / "t.obj").positions, TETRA_P)
    expected = render_bytes(tmp_path / "t.obj")
    assert len(np.unique(expected.reshape(-1, 3), axis=0)) > 10      # a shaded solid, not a blank
    assert np.array_equal(render_bytes(path), expected)
    assert np.array_equal(render_bytes(str(path), program="flat"), render_bytes(tmp_path / "t.obj", program="flat"))


def test_softpipe_render_takes_a_ply(tmp_path, capsys):
    path = write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F)
    code, _, err = run_cli(capsys, "render", path, "--size", f"{W}x{H}", "-o", tmp_path / "t.png")
    assert code == 0, err
    assert np.array_equal(np.asarray(Image.open(tmp_path / "t.png").convert("RGB")), render_bytes(path))


def test_a_point_cloud_ply_is_drawn_as_points_with_a_warning(tmp_path):
    path = write_ply(tmp_path / "cloud.ply", TETRA_P)
    with pytest.warns(FormatWarning) as caught:
        mesh = load_mesh(path)
    assert [str(w.message) for w in caught] == [f"{path}: no faces: its 4 vertices are read as points (a point cloud)"]
    assert mesh.triangle_count == 0 and mesh.points.tolist() == [0, 1, 2, 3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FormatWarning)
        picture = render_bytes(path, point_size=3)
    background = picture[0, 0]
    assert (picture != background).any(axis=2).sum() >= 4 * 9 - 8   # four 3×3 points (framing may clip a little)


def test_a_file_with_no_vertices_is_an_error(tmp_path):
    path = write_ply(tmp_path / "empty.ply", np.zeros((0, 3)))
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    assert str(e.value) == f"{path}: the file holds no vertices: nothing to draw"
    with pytest.raises(FormatError, match="the file holds no vertices"):
        sp.render(path, width=W, height=H)


def test_a_non_finite_vertex_is_an_error(tmp_path):
    path = write_ply(tmp_path / "nan.ply", np.array([[0, 0, 0], [1, 0, 0], ["nan", 1, 0]], dtype=object),
                     [[0, 1, 2]], fmt="%r")
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    assert str(e.value) == f"{path}: vertex 2 is not finite: [nan, 1.0, 0.0]"
    stl = write_stl(tmp_path / "inf.stl", np.array([[0, 0, 0], [1, 0, 0], [0, float("inf"), 0]]), [[0, 1, 2]])
    with pytest.raises(FormatError, match=r"inf.stl: vertex 2 is not finite: \[0.0, inf, 0.0\]"):
        load_mesh(stl)


def test_an_index_out_of_range_names_the_file(tmp_path):
    path = write_ply(tmp_path / "bad.ply", TETRA_P, [[0, 1, 9]])
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    assert str(e.value) == f"{path}: Mesh.indices: index 9 at triangle 0 is out of range for 4 positions"


@pytest.mark.parametrize("name, data, what", [
    ("junk.ply", b"this is not a ply file\n", "PLY"),
    ("short.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  b"property float z\nend_header\n\x00\x00", "PLY"),
    ("junk.glb", b"glTF\x02\x00\x00\x00" + b"\xff" * 16, "glTF 2.0"),
    ("junk.gltf", b"{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [{\"primitives\": [{\"attributes\": "
                  b"{\"POSITION\": 7}}]}]}", "glTF 2.0"),
])
def test_a_damaged_file_names_the_file_and_what_trimesh_said(tmp_path, capsys, name, data, what):
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    message = str(e.value)
    assert message.startswith(f"{path}: cannot read it as {what} (damaged or unsupported): trimesh says "), message
    assert "Error" in message.split("trimesh says ")[1], message       # trimesh's exception, named
    assert "\n" not in message and "Traceback" not in message
    code, _, err = run_cli(capsys, "render", path, "-o", tmp_path / "x.png")
    assert code == 2 and err.strip() == f"softpipe render: error: {message}"
    assert not (tmp_path / "x.png").exists()


def test_another_suffix_is_refused(tmp_path):
    with pytest.raises(FormatError) as e:
        load_mesh(tmp_path / "model.fbx")
    assert str(e.value) == f"{tmp_path / 'model.fbx'}: expected one of .ply, .stl, .gltf, .glb (PLY, STL, glTF), not '.fbx'"


def test_without_trimesh_the_message_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    path = write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F)
    monkeypatch.setitem(sys.modules, "trimesh", None)     # `import trimesh` now fails, as when it is missing
    expected = f"{path}: reading .ply needs trimesh: pip install 'softpipe[formats]'"
    with pytest.raises(MissingExtraError) as e:
        load_mesh(path)
    assert str(e.value) == expected
    assert isinstance(e.value, ImportError) and isinstance(e.value, ValueError)
    with pytest.raises(ImportError, match=r"pip install 'softpipe\[formats\]'"):
        sp.render(path)
    code, _, err = run_cli(capsys, "render", path, "-o", tmp_path / "t.png")
    assert code == 2 and err.strip() == f"softpipe render: error: {expected}"
    scene = tmp_path / "s.toml"
    scene.write_text('[[meshes]]\nobj = "t.ply"\n')
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert str(e.value).endswith(f"key 'obj' in [[meshes]] #1: {expected}")


# ---------------------------------------------------------------------------- glTF


def textured_quad(path, factor=(0.5, 0.75, 1.0, 1.0), metallic=0.25, roughness=0.5):
    g = GLTF()
    tex = g.image(png(IMAGE))
    mat = g.material("painted", baseColorFactor=list(factor), baseColorTexture={"index": tex},
                     metallicFactor=metallic, roughnessFactor=roughness)
    g.node(mesh=g.mesh(QUAD_P, QUAD_F, QUAD_N, QUAD_GLTF_UV, material=mat, name="quad"))
    return g.write(path)


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_a_gltf_base_color_texture_and_factor_are_kd_and_the_srgb_texture(tmp_path, suffix):
    path = textured_quad(tmp_path / f"quad{suffix}")
    mesh = load_mesh(path)
    assert np.array_equal(mesh.positions, QUAD_P) and np.array_equal(mesh.indices, QUAD_F)
    assert np.array_equal(mesh.normals, QUAD_N)
    assert np.array_equal(mesh.uvs, np.column_stack([QUAD_GLTF_UV[:, 0], 1 - QUAD_GLTF_UV[:, 1]]))  # v up
    kd = np.array([0.5, 0.75, 1.0]) * (1 - 0.25)          # base color × (1 − metallic), linear as glTF has it
    assert mesh.material.kd == tuple(kd)
    texture = mesh.source.textures["painted"]
    assert texture.srgb and (texture.width, texture.height) == (8, 8)

    results = []
    out = sp.render(path, width=W, height=H, azimuth=0, elevation=0, results=results, outputs=("albedo", "uv"))
    assert [r.program for r in results] == ["textured"]
    uv, albedo = out["uv"], out["albedo"]
    checked = 0
    for (row, col), gltf_box in (((0, 0), (0, 0)), ((0, 1), (0.5, 0)), ((1, 0), (0, 0.5)), ((1, 1), (0.5, 0.5))):
        # pixels well inside a quadrant, in glTF's texture coordinates (v down, from the image's top)
        gu, gv = uv[..., 0], 1 - uv[..., 1]
        inside = (gu > gltf_box[0] + 0.1) & (gu < gltf_box[0] + 0.4) & (gv > gltf_box[1] + 0.1) & (
            gv < gltf_box[1] + 0.4)
        assert inside.sum() > 10
        expected = (kd * srgb_decode(QUADRANTS[row, col])).astype(np.float32)
        assert np.allclose(albedo[inside], expected, rtol=1e-6, atol=0), (row, col)
        checked += int(inside.sum())
    assert checked > 40


def test_gltf_metallic_roughness_reach_the_cook_torrance_program(tmp_path):
    g = GLTF()
    base, metallic, rough = (0.8, 0.4, 0.2, 1.0), 0.5, 0.6
    mat = g.material("brass", baseColorFactor=list(base), metallicFactor=metallic, roughnessFactor=rough)
    g.node(mesh=g.mesh(TETRA_P, TETRA_F, material=mat))
    path = g.write(tmp_path / "brass.glb")
    results = []
    sp.render(path, width=W, height=H, results=results, trace=True)
    assert [r.program for r in results] == ["cook_torrance"]
    m = results[0].trace.call.uniforms.material
    c = np.array(base[:3])
    f0 = 0.04 * (1 - metallic) + c * metallic                      # glTF's F0 = mix(0.04, C, M)
    assert np.allclose(m.kd, c * (1 - metallic), rtol=1e-15) and np.allclose(m.ka, m.kd, rtol=1e-15)
    assert np.allclose(m.ks, f0 / f0.max(), rtol=1e-15)                      # the tint; F carries the size
    assert m.roughness == pytest.approx(rough ** 2, rel=1e-15)              # Beckmann m = glTF's α = R²
    n = m.ior                                                               # F(0) of §20 is max F0 exactly
    assert ((n - 1) / (n + 1)) ** 2 == pytest.approx(f0.max(), rel=1e-12)
    assert m.shininess == pytest.approx(2 / rough ** 4 - 2, rel=1e-12)


def test_a_dielectric_gets_index_1_5_and_a_white_specular(tmp_path):
    g = GLTF()
    mat = g.material("plastic", baseColorFactor=[0.2, 0.4, 0.6, 1.0], metallicFactor=0.0, roughnessFactor=1.0)
    g.node(mesh=g.mesh(TETRA_P, TETRA_F, material=mat))
    material = load_mesh(g.write(tmp_path / "p.gltf")).material
    assert material.ior == pytest.approx(1.5, rel=1e-12) and material.ks == (1.0, 1.0, 1.0)
    assert material.kd == (0.2, 0.4, 0.6) and material.roughness == 1.0 and material.shininess == 1.0


def test_emission_and_blended_alpha_are_read(tmp_path):
    g = GLTF()
    mat = g.material("glow", baseColorFactor=[1.0, 1.0, 1.0, 0.25], metallicFactor=0.0)
    g.doc["materials"][mat].update(emissiveFactor=[0.5, 0.25, 0.0], alphaMode="BLEND")
    opaque = g.material("mask", baseColorFactor=[1.0, 1.0, 1.0, 0.25], metallicFactor=0.0)
    g.node(mesh=g.mesh(TETRA_P, TETRA_F, material=mat))
    g.node(mesh=g.mesh(QUAD_P, QUAD_F, material=opaque))
    glow, mask = load_mesh(g.write(tmp_path / "glow.gltf")).materials
    assert glow.ke == (0.5, 0.25, 0.0) and glow.opacity == 0.25
    assert mask.opacity == 1.0                   # alphaMode OPAQUE (the default): alpha is not read


def test_a_texture_without_texture_coordinates_is_warned_about(tmp_path):
    g = GLTF()
    mat = g.material("painted", baseColorTexture={"index": g.image(png(IMAGE))})
    g.node(mesh=g.mesh(QUAD_P, QUAD_F, material=mat))
    path = g.write(tmp_path / "nouv.glb")
    with pytest.warns(FormatWarning) as caught:
        mesh = load_mesh(path)
    assert [str(w.message) for w in caught] == [
        f"{path}: material 'painted' has a base color texture but its mesh no texture coordinates (TEXCOORD_0); "
        "drawn without it"]
    assert mesh.source.textures == {} and mesh.material.ks == (1.0, 1.0, 1.0)   # drawn by cook_torrance


def test_gltf_nodes_are_flattened_with_their_world_transforms(tmp_path):
    g = GLTF()
    red = g.material("red", baseColorFactor=[1.0, 0.0, 0.0, 1.0], metallicFactor=0.0)
    blue = g.material("blue", baseColorFactor=[0.0, 0.0, 1.0, 1.0], metallicFactor=0.0)
    a = g.mesh(TETRA_P, TETRA_F, material=red, name="a")
    b = g.mesh(QUAD_P, QUAD_F, QUAD_N, material=blue, name="b")
    child = g.node(root=False, mesh=a, translation=[0.0, 0.0, -4.0])
    g.node(mesh=a)
    g.node(mesh=b, scale=[2.0, 1.0, 1.0], translation=[1.0, 2.0, 3.0], children=[child])
    mesh = load_mesh(g.write(tmp_path / "nodes.gltf"))
    assert mesh.triangle_count == 4 + 2 + 4 and [m.name for m in mesh.materials] == ["red", "blue"]
    parent = np.array([[2, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1.0]])
    world_child = parent @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -4], [0, 0, 0, 1.0]])
    expected = {tuple(map(tuple, TETRA_P[TETRA_F].reshape(-1, 3))),
                tuple(map(tuple, (QUAD_P[QUAD_F].reshape(-1, 3) * [2, 1, 1] + [1, 2, 3]))),
                tuple(map(tuple, (TETRA_P[TETRA_F].reshape(-1, 3) * [2, 1, 1] + world_child[:3, 3])))}
    corners = mesh.positions[mesh.indices]
    ids = mesh.material_ids
    got = {tuple(map(tuple, corners[ids == 0][:4].reshape(-1, 3))), tuple(map(tuple, corners[ids == 0][4:].reshape(
        -1, 3))), tuple(map(tuple, corners[ids == 1].reshape(-1, 3)))}
    assert got == expected
    quad_normals = mesh.normals[mesh.indices[ids == 1].ravel()]
    assert np.allclose(quad_normals, [0, 0, 1])          # a scale along x leaves +z as it was
    assert mesh.source.counts["nodes"] == 3 and mesh.source.pbr == ("red", "blue")


def test_a_gltf_buffer_outside_its_folder_is_refused_unless_allowed(tmp_path):
    folder = tmp_path / "model"
    folder.mkdir()
    g = GLTF()
    g.node(mesh=g.mesh(TETRA_P, TETRA_F))
    path = g.write(folder / "m.gltf")
    (tmp_path / "data.bin").write_bytes(bytes(g.bin))
    doc = json.loads(path.read_text())
    doc["buffers"][0]["uri"] = "../data.bin"
    path.write_text(json.dumps(doc))
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    assert str(e.value).startswith(f"{path}: cannot read it as glTF 2.0 (damaged or unsupported): trimesh says ")
    assert "leads out of the folder" in str(e.value) and "allow_outside=True" in str(e.value)
    assert np.array_equal(load_mesh(path, allow_outside=True).positions, TETRA_P)


def test_a_gltf_texture_that_cannot_be_read_is_warned_about(tmp_path):
    g = GLTF()
    mat = g.material("lost", baseColorFactor=[1.0, 1.0, 1.0, 1.0], baseColorTexture={"index": g.image(b"", "gone.png")})
    g.node(mesh=g.mesh(QUAD_P, QUAD_F, uvs=QUAD_GLTF_UV, material=mat))
    path = g.write(tmp_path / "lost.gltf")
    with pytest.warns(FormatWarning) as caught:
        mesh = load_mesh(path)
    assert [str(w.message) for w in caught] == [
        f"{path}: material 'lost': its base color texture was not read ('gone.png': No such file or directory); "
        "drawn without it"]
    assert mesh.source.textures == {}


def test_a_non_finite_gltf_position_is_an_error(tmp_path):
    g = GLTF()
    g.node(mesh=g.mesh(np.vstack([TETRA_P[:3], [[0.0, np.nan, 0.0]]]), TETRA_F, name="tet"))
    path = g.write(tmp_path / "nan.glb")
    with pytest.raises(FormatError) as e:
        load_mesh(path)
    assert str(e.value) == f"{path}: mesh 'tet': vertex 3 is not finite: [0.0, nan, 0.0]"


def test_softpipe_render_takes_a_glb(tmp_path, capsys):
    path = textured_quad(tmp_path / "quad.glb")
    code, _, err = run_cli(capsys, "render", path, "--size", f"{W}x{H}", "-o", tmp_path / "q.png")
    assert code == 0, err
    assert np.array_equal(np.asarray(Image.open(tmp_path / "q.png").convert("RGB")), render_bytes(path))


def test_a_scene_file_names_ply_and_glb_models(tmp_path):
    write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F)
    textured_quad(tmp_path / "quad.glb")
    g = GLTF()
    g.node(mesh=g.mesh(TETRA_P, TETRA_F, material=g.material("steel", baseColorFactor=[0.5, 0.5, 0.5, 1.0],
                                                                     roughnessFactor=0.5)))
    g.write(tmp_path / "steel.glb")
    (tmp_path / "s.toml").write_text('[render]\nwidth = 48\nheight = 36\n'
                                     '[[meshes]]\nobj = "t.ply"\n'
                                     '[[meshes]]\nobj = "quad.glb"\ntransform = [{translate = [3, 0, 0]}]\n'
                                     '[[meshes]]\nobj = "steel.glb"\nname = "steel"\n')
    scene = load_scene(tmp_path / "s.toml")
    tetra, quad, steel = scene.objects
    assert np.array_equal(tetra.mesh.positions, TETRA_P) and tetra.program is None and tetra.texture is None
    assert quad.texture is not None and quad.texture.srgb and quad.program is None
    assert steel.program == "cook_torrance" and steel.texture is None
    assert steel.mesh.material.roughness == 0.25
    results = []
    sp.render(tmp_path / "s.toml", results=results)
    assert [r.program for r in results] == ["phong", "textured", "cook_torrance"]


# ---------------------------------------------------------------------------- one dispatch: load_model, from_model, jobs


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".glb"])
def test_load_model_and_scene_from_model_read_the_formats_by_suffix(tmp_path, suffix):
    """models.load_model is the one suffix dispatch: Scene.from_model(path) draws what sp.render(path) does."""
    path = tmp_path / f"t{suffix}"
    if suffix == ".ply":
        write_ply(path, TETRA_P, TETRA_F)
    elif suffix == ".stl":
        write_stl(path, TETRA_P, TETRA_F)
    else:
        g = GLTF()
        g.node(mesh=g.mesh(TETRA_P, TETRA_F))
        g.write(path)
    mesh, expected = sp.load_model(path), load_mesh(path)    # (STL's corners welded: in another order)
    assert np.array_equal(mesh.positions, expected.positions) and np.array_equal(mesh.indices, expected.indices)
    assert np.array_equal(np.sort(mesh.positions, axis=0), np.sort(TETRA_P, axis=0))
    assert mesh.source.format == {".glb": "glTF"}.get(suffix, suffix[1:].upper())
    scene = sp.Scene.from_model(str(path), width=W, height=H)
    assert scene.path == str(path) and np.array_equal(scene.objects[0].mesh.positions, expected.positions)
    assert np.array_equal(np.asarray(sp.render(scene).to_image()), render_bytes(path))
    with pytest.raises(TypeError, match=r"t\.\w+: encoding apply to OBJ files; a \w+ file takes only allow_outside$"):
        sp.load_model(path, encoding="utf-8")


def test_scene_from_model_gives_a_gltf_its_textures_and_programs(tmp_path):
    path = textured_quad(tmp_path / "quad.glb")
    g = GLTF()
    g.node(mesh=g.mesh(TETRA_P, TETRA_F, material=g.material("steel", baseColorFactor=[0.5, 0.5, 0.5, 1.0])))
    g.write(tmp_path / "steel.glb")
    (quad,) = sp.Scene.from_model(path).objects
    assert quad.texture is not None and quad.texture.srgb and quad.program is None
    (steel,) = sp.Scene.from_model(tmp_path / "steel.glb").objects
    assert steel.program == "cook_torrance" and steel.texture is None
    # a Mesh given as it is is drawn as any mesh is (docs/formats.md)
    (plain,) = sp.Scene.from_model(load_mesh(tmp_path / "steel.glb")).objects
    assert plain.program is None and plain.texture is None


def test_scene_from_model_keeps_a_formats_warning_its_kind(tmp_path):
    path = write_ply(tmp_path / "cloud.ply", TETRA_P)
    with pytest.warns(FormatWarning) as caught:
        scene = sp.Scene.from_model(path)
    message = f"{path}: no faces: its 4 vertices are read as points (a point cloud)"
    assert [(w.category, str(w.message)) for w in caught] == [(FormatWarning, message)]
    assert scene.warnings == [message]


def test_a_batch_job_names_ply_stl_and_glb_models(tmp_path):
    from softpipe.tools.batch import job_from_dict
    write_ply(tmp_path / "t.ply", TETRA_P, TETRA_F)
    write_stl(tmp_path / "t.stl", TETRA_P, TETRA_F)
    g = GLTF()
    g.node(mesh=g.mesh(TETRA_P, TETRA_F))
    g.write(tmp_path / "t.glb")
    job = job_from_dict({"models": {"p": "t.ply", "s": {"obj": "t.stl"}, "g": "t.glb"},
                         "sweep": {"models": ["p", "s", "g"]}}, base_dir=tmp_path)
    meshes = job.load_models()
    assert sorted(meshes) == ["g", "p", "s"]
    for name, file in (("p", "t.ply"), ("s", "t.stl"), ("g", "t.glb")):
        expected = load_mesh(tmp_path / file)
        assert np.array_equal(meshes[name].positions, expected.positions), name
        assert np.array_equal(meshes[name].indices, expected.indices), name
        assert np.array_equal(np.sort(meshes[name].positions, axis=0), np.sort(TETRA_P, axis=0)), name
    (tmp_path / "bad.stl").write_text("solid t\nfacet normal 0 0 0\nouter loop\nvertex 1 2\n")
    job = job_from_dict({"models": {"bad": "bad.stl"}, "sweep": {"models": ["bad"]}}, base_dir=tmp_path)
    from softpipe.tools.batch import JobError
    with pytest.raises(JobError, match=r"^<job>: key 'obj' in \[models\] 'bad': .*bad\.stl: the file holds no "
                                       r"vertices: nothing to draw$"):
        job.load_models()
