"""Shared by the example scripts: where files are, one render call, labelled contact sheets.

Each example is ``python examples/NAME.py`` from the repository root; it writes one
contact sheet into ``out/examples/`` and prints its path. Each also has a
``sheet(size)`` function that returns the pictures (name → uint8 image), which is
what the tests call at a tiny size.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Dict, Optional

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:          # run from a checkout without installing
    sys.path.insert(0, str(REPO))

import softpipe as sp  # noqa: E402
from softpipe.light.material import Lighting  # noqa: E402

# the lit programs register themselves when imported
from softpipe.programs import cook_torrance, flat, gooch, gouraud, hall, phong, textured  # noqa: E402,F401
from softpipe.programs.common import lighting_uniform  # noqa: E402
from softpipe.scenes.drawing import draw_mesh  # noqa: E402
from softpipe.scenes.mesh import Mesh  # noqa: E402
from softpipe.scenes.models import MODELS_DIR, model_path  # noqa: E402
from softpipe.scenes.obj import load_obj  # noqa: E402
from softpipe.views.pictures import contact_sheet  # noqa: E402

#: The test meshes bundled with softpipe (:mod:`softpipe.scenes.models`, ``softpipe/data/models/``).
ASSETS = MODELS_DIR
#: Where the contact sheets go.
OUT = REPO / "out" / "examples"

BACKGROUND = (0.06, 0.07, 0.09, 1.0)


def render(mesh: Mesh, camera, program: str = "phong", lighting: Optional[Lighting] = None, size=(160, 160),
           model=None, uniforms: Optional[dict] = None, background=BACKGROUND, fb=None, **state) -> sp.Framebuffer:
    """Draw one mesh (or a list of (mesh, model, program) parts) into a new framebuffer.

    ``lighting`` reaches the programs as the ``lighting`` uniform, in the camera's eye space.
    """
    width, height = size
    if fb is None:
        fb = sp.Framebuffer(width, height)
        fb.clear(background)
    parts = mesh if isinstance(mesh, list) else [(mesh, model, program)]
    for part, part_model, part_program in parts:
        u = {"lighting": lighting_uniform(lighting, camera.view)}
        u.update(uniforms or {})
        draw_mesh(fb, part, camera, part_program, model=part_model, uniforms=u, **state)
    return fb


def image(fb: sp.Framebuffer) -> np.ndarray:
    """The framebuffer as an 8-bit RGB picture for a contact sheet."""
    return fb.to_uint8(alpha=False)


def load_asset(name: str, size: float = 2.0) -> Mesh:
    """A bundled model (``"bunny"``) or an OBJ file, centred, scaled to fit a cube of side ``size``, smooth normals.

    Normals are averaged over vertices at the same position, so a mesh whose
    patch seams are not welded (the teapot) still shades smoothly across them.
    """
    mesh = load_obj(model_path(name)).normalized(size)
    return mesh.replace(normals=welded_normals(mesh))


def welded_normals(mesh: Mesh) -> np.ndarray:
    """Area-weighted vertex normals, shared by every vertex record at the same position."""
    _, key, = np.unique(mesh.positions, axis=0, return_inverse=True)
    key = key.ravel()
    face = mesh.face_normals(normalized=False)                  # length = 2 · area
    acc = np.zeros((key.max() + 1, 3))
    for c in range(3):
        np.add.at(acc, key[mesh.indices[:, c]], face)
    n = acc[key]
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.tile([0.0, 1.0, 0.0], (len(n), 1)), where=length > 0)


def save_sheet(name: str, pictures: Dict[str, np.ndarray], columns: int, title: str,
               out_dir: Optional[Path] = None) -> Path:
    """Write the labelled contact sheet ``out/examples/<name>.png`` under a title line; print its path."""
    from PIL import Image, ImageDraw
    body = contact_sheet(pictures, columns=columns)
    title_height = 24
    sheet = Image.new("RGB", (body.width, body.height + title_height), (24, 24, 28))
    ImageDraw.Draw(sheet).text((6, 5), title, fill=(255, 255, 255))
    sheet.paste(body, (0, title_height))
    out_dir = Path(out_dir or OUT)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.png"
    sheet.save(path)
    print(path)
    return path


def picture_size(size):
    """(width, height) of a picture size given as one side or as a pair."""
    return (size, size) if isinstance(size, int) else tuple(size)


def checkerboard(size, cells, a, b):
    """A square floor of ``cells`` × ``cells`` tiles as two meshes, the tiles of material a and of b."""
    plane = sp.shapes.plane(size, subdivisions=cells)
    triangles = np.asarray(plane.indices).reshape(-1, 3)
    i, k = divmod(np.arange(len(triangles)) // 2, cells)      # two triangles per cell, cells in rows of `cells`
    return [Mesh(plane.positions, triangles[(i + k) % 2 == parity], plane.normals, plane.uvs,
                 material=material).compacted() for parity, material in ((0, a), (1, b))]


def save_docs_sheet(path: Path, pictures: Dict[str, np.ndarray], columns: int) -> Path:
    """Write a docs picture: ``pictures`` as a labelled contact sheet at ``path`` (its folder made); print its path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    contact_sheet(pictures, columns=columns).save(path, optimize=True)
    print(path)
    return path


def zoom(picture: np.ndarray, factor: int) -> np.ndarray:
    """Each pixel as a factor × factor block (to see pixels)."""
    return np.repeat(np.repeat(picture, factor, axis=0), factor, axis=1)


def key_light(**kw) -> Lighting:
    """One white directional light from the upper left, in front (its rays travel down, right, back)."""
    from softpipe.light.material import Light
    return Lighting([Light.directional((1.0, -1.0, -1.2), **kw)], global_ambient=(0.15, 0.15, 0.15))


def studio_lighting() -> Lighting:
    """Key, fill and rim lights: a directional key, a dimmer bluish point fill, a spot from behind."""
    from softpipe.light.material import Light
    return Lighting([
        Light.directional((1.0, -1.0, -1.2), name="key"),
        Light.point((3.0, 0.5, 3.0), diffuse=(0.25, 0.3, 0.4), specular=(0.3, 0.3, 0.4), name="fill"),
        Light.spot((0.0, 3.0, -4.0), (0.0, -0.6, 1.0), cutoff=40.0, exponent=2.0, diffuse=0.6, name="rim"),
    ], global_ambient=(0.1, 0.1, 0.1))
