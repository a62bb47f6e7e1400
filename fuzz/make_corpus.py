"""Write the seed corpus: fuzz/corpus/obj/seed-* and fuzz/corpus/scene/seed-*.

    python fuzz/make_corpus.py [--assets softpipe/data/models]

OBJ seeds are small, self-consistent slices of every OBJ among the models bundled with
softpipe in ``softpipe/data/models`` (a run of faces with just the v/vt/vn lines they
use, renumbered, in the file's own index form), the head of each file as it is, and
hand-written files that use every statement the parser knows (and a few it rejects).
Scene seeds are ``examples/scene.toml`` as it is, the same file pointed at the small
files in ``fuzz/data``, and hand-written scenes that use every key. Files the fuzzer found are
``fuzz/corpus/*/cov-*`` (from ``run.py --merge``) and are left alone here.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DEFAULT_ASSETS = ROOT / "softpipe" / "data" / "models"   # the bundled models (softpipe.scenes.models.MODELS_DIR)


def obj_slice(lines, first: int, count: int) -> str:
    """Faces first..first+count of an OBJ, with only the elements they use, renumbered."""
    pools = {"v": [], "vt": [], "vn": []}
    faces = []
    for line in lines:
        head = line.split(None, 1)[0] if line.strip() else ""
        if head in pools:
            pools[head].append(line)
        elif head == "f":
            faces.append(line)
    faces = faces[first:first + count]
    used = {k: {} for k in pools}
    out_faces = []
    for face in faces:
        corners = []
        for token in face.split()[1:]:
            fields = token.split("/")
            new = []
            for kind, field in zip(("v", "vt", "vn"), fields):
                if not field:
                    new.append("")
                    continue
                i = int(field)
                i = i - 1 if i > 0 else len(pools[kind]) + i
                new.append(str(used[kind].setdefault(i, len(used[kind]) + 1)))
            corners.append("/".join(new))
        out_faces.append("f " + " ".join(corners))
    out = []
    for kind in ("v", "vt", "vn"):
        for i in sorted(used[kind], key=used[kind].get):
            out.append(pools[kind][i].rstrip())
    return "\n".join(out + out_faces) + "\n"


HAND_OBJ = {
    "forms": """# every face form, objects, groups, materials, comments, continuation
mtllib tiny.mtl
o first
g part one
v 0 0 0
v 1 0 0 1.0
v 1 1 0 0.5 0.5 0.5
v 0 1 0
vt 0 0
vt 1 0 0
vt 1 1
vt 0.5
vn 0 0 1
vn 0 0 -1
usemtl checker
f 1 2 3
f 1/1 3/3 4/4
g part two
usemtl red
f 1//1 2//1 3//1 # trailing comment
f 1/1/1 2/2/1 \\
  3/3/1 4/4/1
f -4 -3 -2
s 1
f -4/-4/-2 -2/-2/-2 -1/-1/-2
usemtl missing
l 1 2
p 3
cstype bezier
""",
    "negative": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\nv 2 2 0\nf -1 -2 -3\n",
    "smoothing": """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1
s 1
f 1 2 5
f 2 3 5
s off
f 3 4 5
s 2
f 4 1 5
s 0
f 1 4 3 2
""",
    "polygon": "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 2 2 0\nv 0 2 0\nv -1 1 0\nf 1 2 3 4 5 6\n",
    "crlf-bom": "\ufeffv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nvt 0 0\r\nf 1/1 2/1 3/1\r\n",
    "mtl-full": """# an MTL file (the target also runs parse_mtl on every input)
newmtl shiny
Ka 0.1 0.1 0.1
Kd 0.5 0.2 0.1
Ks 1 1 1
Ke 0 0 0
Ns 96
Ni 1.5
d -halo 0.9
Tr 0.2
illum 2
map_Kd -s 1 1 1 -o 0 0 0 -bm 1 checker.png
newmtl glass
Kd spectral glass.rfl
Ka xyz 1 1 1
Tr 0.7
Ni 0
map_Kd missing.png
newmtl win
map_Kd textures\\checker.png
""",
    "bad-face": "v 0 0 0\nv 1 0 0\nf 1 2\n",
    "bad-index": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\nf 0 1 2\n",
    "bad-number": "v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "bad-usemtl": "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl\nf 1 2 3\n",
    "empty": "# nothing but a comment\n",
}

HAND_SCENE = {
    "minimal": '[[meshes]]\nshape = "cube"\n',
    "everything": """ambient = [0.1, 0.1, 0.1]

[camera]
frame = true
azimuth = 45
elevation = 30
fovy = 50
margin = 1.2
up = [0, 1, 0]

[render]
width = 64
height = 48
background = [0, 0, 0, 1]
samples = "grid4"
sample_shading = "centroid"
program = "normals"
cull = "none"
wireframe = true
wireframe_color = 0.5

[[lights]]
kind = "directional"
direction = [0, -1, 0]
ambient = 0.1
diffuse = [1, 1, 1]
specular = 0.5
name = "sun"

[[lights]]
kind = "point"
position = [1, 2, 3]
attenuation = [1, 0.1, 0.01]
color = [1, 0.9, 0.8]

[[lights]]
kind = "spot"
position = [0, 3, 0]
spot_direction = [0, -1, 0]
cutoff = 30
exponent = 8

[materials.checker]
ke = 0
ka = 0.1
kd = [0.9, 0.9, 0.9]
ks = 0.3
shininess = 20
kr = 0.1
kt = 0.0
transmission_shininess = 10
ior = 1.5
opacity = 1.0
roughness = 0.2
diffuse_texture = "checker.png"

[[meshes]]
name = "quad"
obj = "quad.obj"
fit = 2
normals = "flat"
transform = [{ translate = [0, 1, 0] }, { rotate = [30, 0, 1, 0] }, { scale = [1, 2, 1] }]
material = "checker"
cull = "back"

[[meshes]]
obj = "tri.obj"
normals = "angle"
transform = { matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], rotate_x = 10, rotate_z = 5 }

[[meshes]]
shape = "plane"
size = 4
subdivisions = 2
normals = "area"
transform = { scale = -1 }

[[meshes]]
shape = "uv_sphere"
radius = 0.5
segments = 8
rings = 4
material = { kd = [1, 0, 0], ks = 0.5, shininess = 30 }
program = "depth"

[[meshes]]
shape = "icosphere"
subdivisions = 1

[[meshes]]
shape = "cylinder"
radius = 0.3
height = 1
segments = 6
stacks = 2
caps = false

[[meshes]]
shape = "cone"
segments = 5
cap = true

[[meshes]]
shape = "torus"
major_radius = 1
minor_radius = 0.2
segments = 6
tube_segments = 4
""",
    "explicit-camera": """[camera]
eye = [0, 1, 5]
target = [0, 0, 0]
up = [0, 1, 0]
fovy = 40
near = 0.5
far = 50

[[meshes]]
shape = "cube"
size = 1.5
""",
    "errors": """[render]
width = "wide"
[[lights]]
kind = "point"
colour = [1, 0, 0]
[[meshes]]
shape = "sphere"
""",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--assets", type=Path, default=DEFAULT_ASSETS, help="the folder of OBJ files to slice")
    args = ap.parse_args()
    obj_dir, scene_dir = HERE / "corpus" / "obj", HERE / "corpus" / "scene"
    for d in (obj_dir, scene_dir):
        d.mkdir(parents=True, exist_ok=True)
        for old in d.glob("seed-*"):
            old.unlink()
    for path in sorted(args.assets.rglob("*.obj")):
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        stem = path.stem
        nfaces = sum(1 for line in lines if line.startswith("f "))
        (obj_dir / f"seed-{stem}-head.obj").write_text("\n".join(lines[:25]) + "\n")
        (obj_dir / f"seed-{stem}-first.obj").write_text(obj_slice(lines, 0, 24))
        (obj_dir / f"seed-{stem}-middle.obj").write_text(obj_slice(lines, nfaces // 2, 24))
    for name, text in HAND_OBJ.items():
        (obj_dir / f"seed-{name}.obj").write_text(text, encoding="utf-8", newline="")
    example = (ROOT / "examples" / "scene.toml").read_text(encoding="utf-8")
    (scene_dir / "seed-example.toml").write_text(example)
    local = re.sub(r'"[^"]*/spot_texture\.png"', '"checker.png"', example)
    # A model by path or by bundled name ("bunny"): the bunny and the teapot become tri.obj, the rest quad.obj.
    local = re.sub(r'(?m)^obj = "[^"]*(bunny|teapot)(\.obj)?"', 'obj = "tri.obj"', local)
    local = re.sub(r'(?m)^obj = "(?!tri\.obj")[^"]*"', 'obj = "quad.obj"', local)
    local = local.replace("width = 640", "width = 64").replace("height = 480", "height = 48")
    (scene_dir / "seed-example-local.toml").write_text(local)
    for name, text in HAND_SCENE.items():
        (scene_dir / f"seed-{name}.toml").write_text(text)
    for d in (obj_dir, scene_dir):
        files = list(d.iterdir())
        print(f"{d.relative_to(ROOT)}: {len(files)} files, {sum(f.stat().st_size for f in files):,} bytes")


if __name__ == "__main__":
    main()
