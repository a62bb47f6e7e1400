"""The test models that ship inside the package, by name.

softpipe carries a few well-known meshes in ``softpipe/data/models/`` (byte-for-byte
as published; sources, terms and SHA-256 sums in ``softpipe/data/models/README.md``),
so tests, examples, benchmarks and the command line work in a plain clone or
install, with no asset folder next to the repository:

- ``bunny``: ``stanford-bunny.obj``, the Stanford Bunny, 69,451 triangles (35,947 ``v``
  lines, extent about 0.15, y up). Stanford 3D Scanning Repository terms: credit the
  Stanford Computer Graphics Laboratory; free redistribution and research use; no
  commercial use without Stanford's permission.
- ``teapot``: ``teapot.obj``, the Utah (Newell) teapot, 6,320 triangles (not welded at
  the patch seams). No license stated by its source.
- ``suzanne``: ``suzanne.obj``, Blender's Suzanne, 500 faces (468 quads, 32 triangles)
  = 968 triangles, with per-vertex normals; not centred at the origin. No license
  stated by its source.
- ``spot``: ``spot/spot_triangulated.obj``, Keenan Crane's cow "Spot", 5,856 triangles
  with texture coordinates, and its texture ``spot/spot_texture.png`` (1024x1024 RGB).
  Public domain (its author's statement in ``spot/README.txt``).
- ``armadillo``: ``armadillo.obj``, the Stanford Armadillo decimated to 99,976
  triangles (extent about 150). Stanford terms, as the bunny.

``spot/spot_quadrangulated.obj`` (the same cow in 2,928 quads) is shipped too, for the
loader's tests, but has no name here.

>>> from softpipe.scenes.models import load_model, model_path
>>> model_path("bunny").name
'stanford-bunny.obj'
>>> load_model("teapot").triangle_count
6320

:func:`model_path` turns a model name into the bundled file and leaves anything
else (a path) alone, so every command or function that takes an OBJ path can take
a model name as well.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, List, Optional, Union

__all__ = ["MODELS", "TEXTURES", "MODELS_DIR", "model_names", "model_path", "texture_path", "load_model"]

#: The folder holding the bundled models (inside the installed package).
MODELS_DIR: Path = Path(__file__).resolve().parent.parent / "data" / "models"

#: Model name → OBJ file, relative to :data:`MODELS_DIR`.
MODELS: Dict[str, str] = {
    "bunny": "stanford-bunny.obj",
    "teapot": "teapot.obj",
    "suzanne": "suzanne.obj",
    "spot": "spot/spot_triangulated.obj",
    "armadillo": "armadillo.obj",
}

#: Model name → its diffuse texture, relative to :data:`MODELS_DIR` (only the models that have one).
TEXTURES: Dict[str, str] = {
    "spot": "spot/spot_texture.png",
}

PathLike = Union[str, "os.PathLike[str]"]


def model_names() -> List[str]:
    """The names of the bundled models, in :data:`MODELS` order."""
    return list(MODELS)


def _is_bare_name(text: str) -> bool:
    """A word such as 'bunny': no folder separator and no file suffix."""
    return "/" not in text and os.sep not in text and (os.altsep or "/") not in text \
        and not os.path.splitext(text)[1]


def model_path(name_or_path: PathLike) -> Path:
    """The file of a bundled model (``"bunny"``), or any other path unchanged, as a Path.

    A string that is a key of :data:`MODELS` names the bundled file, even if a file of
    that name exists in the current folder (write ``"./bunny"`` for that one). Any other
    string or path-like object comes back as ``Path(name_or_path)``, whether it exists
    or not, so the caller's usual "no such file" error applies. A bare word (no ``/``,
    no suffix) that is neither a model name nor an existing file raises a ValueError
    listing the models.
    """
    if isinstance(name_or_path, str):
        if name_or_path in MODELS:
            return MODELS_DIR / MODELS[name_or_path]
        if _is_bare_name(name_or_path) and not os.path.exists(name_or_path):
            raise ValueError(f"{name_or_path!r} is neither a file nor a bundled model; "
                             f"the models are: {', '.join(MODELS)}")
        return Path(name_or_path)
    if isinstance(name_or_path, os.PathLike):
        return Path(name_or_path)
    raise TypeError(f"model_path() takes a model name or a path, got {type(name_or_path).__name__}")


def texture_path(name: PathLike) -> Optional[Path]:
    """The bundled diffuse texture of model ``name`` (``"spot"``), or None.

    None for a bundled model without a texture and for any path (an OBJ file's
    textures come from its MTL file). An unknown bare name raises ValueError as in
    :func:`model_path`.
    """
    model_path(name)  # validates the name
    if isinstance(name, str) and name in TEXTURES:
        return MODELS_DIR / TEXTURES[name]
    return None


def load_model(name_or_path: PathLike, *, allow_outside: bool = False, **kwargs):
    """Load a bundled model by name, or a model file by path, as a :class:`~softpipe.scenes.mesh.Mesh`.

    ``model_path(name_or_path)``, then by the file's suffix: a ``.ply``, ``.stl``, ``.gltf`` or
    ``.glb`` file (:data:`softpipe.scenes.formats.FORMATS`) is read by
    :func:`softpipe.scenes.formats.load_mesh` (through trimesh), any other file by
    :func:`softpipe.scenes.obj.load_obj` (``allow_outside`` is passed on to either, and
    ``kwargs`` to ``load_obj``: files the model names outside its folder are refused
    unless ``allow_outside=True``). This is the one place a model file's format is
    decided: ``Scene.from_model``, ``sp.render`` and batch jobs all read through it.
    For a bundled model with a texture (``"spot"``), the mesh's
    material gets ``diffuse_texture`` = the bundled texture's path, as an MTL
    ``map_Kd`` line would give it; the command line and scene files then draw it
    textured. Nothing else is changed: the mesh is as the file holds it (not
    centred or scaled).
    """
    from softpipe.scenes.formats import FORMATS, load_mesh  # trimesh is imported only for such a file
    from softpipe.scenes.obj import load_obj

    path = model_path(name_or_path)
    if path.suffix.lower() in FORMATS:
        if kwargs:
            raise TypeError(f"{path}: {', '.join(sorted(kwargs))} apply to OBJ files; a "
                            f"{FORMATS[path.suffix.lower()]} file takes only allow_outside")
        return load_mesh(path, allow_outside=allow_outside)
    mesh = load_obj(path, allow_outside=allow_outside, **kwargs)
    texture = texture_path(name_or_path)
    if texture is not None and mesh.uvs is not None and not mesh.materials \
            and not mesh.material.diffuse_texture:
        mesh = mesh.replace(material=mesh.material.replace(diffuse_texture=str(texture)))
    return mesh
