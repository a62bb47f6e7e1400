"""Meshes from other formats: PLY, STL and glTF 2.0 (.gltf, .glb), read through trimesh.

softpipe parses OBJ itself (:mod:`softpipe.scenes.obj`); the other formats people have are
read by trimesh (an optional extra: ``pip install 'softpipe[formats]'``), a well-kept library,
rather than by parsers of softpipe's own. This module turns what trimesh read into a
:class:`~softpipe.scenes.mesh.Mesh`, checked as a Mesh is, with every problem named with
the file:

- :func:`load_mesh` reads one file into one Mesh (a glTF scene's nodes flattened: each
  node's mesh moved by its world transform, the materials kept per triangle);
- :meth:`Scene.from_model <softpipe.scenes.scene.Scene.from_model>` of such a file's path
  (which reads it through :func:`softpipe.scenes.models.load_model`, the one suffix
  dispatch) is what ``softpipe render model.glb`` draws: the glTF base-color textures
  attached and each part given the program that reads its material (:data:`GLTF_PROGRAM`);
- :func:`glb_material` is the mapping of a glTF metallic-roughness material onto
  :class:`~softpipe.light.material.Material` (FORMULAS §26, §20; docs/formats.md).

Decided here, and said in docs/formats.md: a file with vertices but no faces (a point-cloud
PLY) is drawn as points, with a :class:`FormatWarning`, as an OBJ of vertices alone is; a
file with no vertices, or a non-finite coordinate, normal or texture coordinate, is a
:class:`FormatError`; STL's separate corners are welded where their positions are equal
(exactly), so the mesh is indexed as the solid is.
"""
from __future__ import annotations

import json
import math
import os
import struct
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from softpipe.core.files import PathPolicyError, check_regular_file, excerpt, resolve_inside
from softpipe.light.material import Material
from softpipe.scenes.mesh import Mesh, concatenate

__all__ = ["FORMATS", "FormatError", "MissingExtraError", "FormatWarning", "FormatReport", "load_mesh",
           "glb_material", "GLTF_PROGRAM"]

PathLike = Union[str, "os.PathLike[str]"]

#: Suffix → the format's name: the files :func:`load_mesh` reads.
FORMATS: Dict[str, str] = {".ply": "PLY", ".stl": "STL", ".gltf": "glTF", ".glb": "glTF"}

#: The program a glTF material's part is drawn with when it has no base-color texture
#: (a textured part is drawn with ``textured``, since ``cook_torrance`` reads no texture).
GLTF_PROGRAM = "cook_torrance"

#: The least Beckmann m a glTF roughness maps to: Material.roughness must be > 0, and
#: below this the lobe is narrower than a pixel sees (glTF's roughness 0 is a mirror).
MIN_ROUGHNESS = 1e-3

#: The largest index a metal's F0 maps to: the top of the range Material.ior takes
#: (softpipe.light.material.IOR_RANGE), where F(0) = (999/1001)² ≈ 0.996.
MAX_IOR = 1e3

#: glTF's normal-incidence reflectance of a dielectric (the spec's F0 = 0.04, index 1.5).
DIELECTRIC_F0 = 0.04

# glTF primitive modes trimesh reads (POINTS, LINES, TRIANGLES, TRIANGLE_STRIP), in the
# order it makes one geometry per primitive: used to find each geometry's material.
_TRIMESH_MODES = (0, 1, 4, 5)


class FormatError(ValueError):
    """A PLY, STL or glTF file that cannot be read as a mesh; ``str(e)`` starts with the file."""


class MissingExtraError(FormatError, ImportError):
    """trimesh, which reads these formats, is not installed (a FormatError and an ImportError)."""


class FormatWarning(UserWarning):
    """Something in the file that is read otherwise or left out (a point cloud, a texture)."""


@dataclass
class FormatReport:
    """What :func:`load_mesh` read, kept in ``Mesh.source``.

    ``format`` is ``"PLY"``, ``"STL"`` or ``"glTF"``; ``counts`` what the file held
    (``vertices``, ``triangles``, ``points``; for glTF the ``primitives`` trimesh read and
    the ``nodes`` drawn);
    ``textures`` the base-color texture of each glTF material that has one, by the
    material's name (a :class:`~softpipe.light.texture.Texture2D`, sRGB-decoded);
    ``pbr`` the names of the materials that came from glTF materials;
    ``warnings`` what loading warned about.
    """

    path: str
    format: str
    counts: Dict[str, int] = field(default_factory=dict)
    textures: Dict[str, Any] = field(default_factory=dict, repr=False)
    pbr: Tuple[str, ...] = ()
    warnings: List[str] = field(default_factory=list)


# ---------------------------------------------------------------------------- public API


def load_mesh(path: PathLike, *, allow_outside: bool = False) -> Mesh:
    """Read a PLY, STL or glTF 2.0 file (``.ply``, ``.stl``, ``.gltf``, ``.glb``) into a Mesh.

    Parameters
    ----------
    path : str or path-like
    allow_outside : bool
        Let a ``.gltf`` name buffers and images outside its own folder (they must be in
        it or below otherwise: :func:`softpipe.core.files.resolve_inside`).

    Returns
    -------
    Mesh
        Positions, triangles, and the file's normals and texture coordinates when it has
        them (else None: the renderer computes smooth normals, as for an OBJ). A file
        without faces gives its vertices as ``points``. A glTF file gives every node that
        holds a mesh, moved by the node's world transform, in one mesh whose materials
        are the glTF materials (:func:`glb_material`); ``source`` is a :class:`FormatReport`.

    Raises
    ------
    MissingExtraError
        trimesh is not installed: ``reading .ply needs trimesh: pip install 'softpipe[formats]'``.
    FormatError
        Another suffix; a damaged or unsupported file (with what trimesh said); a file
        with no vertices; a non-finite value; an index out of range.
    OSError
        The file cannot be opened (FileNotFoundError names it).
    """
    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in FORMATS:
        raise FormatError(f"{path}: expected one of {', '.join(FORMATS)} (PLY, STL, glTF), not "
                          f"{suffix or 'no extension'!r}")
    trimesh = _trimesh(path, suffix)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path}: is a directory, not a model file")
    check_regular_file(path)        # a FIFO or device: refused before it is opened
    name = os.path.splitext(os.path.basename(path))[0]
    report = FormatReport(path=path, format=FORMATS[suffix])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if suffix == ".ply":
            mesh = _from_arrays(_read(trimesh.exchange.ply.load_ply, path, "PLY"), path, name, report)
        elif suffix == ".stl":
            mesh = _from_arrays(_welded(_read(trimesh.exchange.stl.load_stl, path, "STL")), path, name, report)
        else:
            mesh = _from_gltf(trimesh, path, suffix, name, report, allow_outside)
    for w in caught:   # re-issued from here, so they point at the caller; kept in the report
        if issubclass(w.category, FormatWarning):
            report.warnings.append(str(w.message))
        warnings.warn(w.message, w.category, stacklevel=2)
    return mesh


def glb_material(spec: Dict[str, Any], name: str, textured: bool = False) -> Material:
    """A glTF 2.0 material (its JSON object) as a :class:`~softpipe.light.material.Material`.

    With C = ``baseColorFactor`` (linear RGB; its alpha a), M = ``metallicFactor`` and
    R = ``roughnessFactor`` (glTF's defaults 1, 1, 1), and F0 = mix(0.04, C, M), glTF's
    reflectance at normal incidence:

    - ``kd = ka = C·(1 − M)`` (a metal has no diffuse part; ambient as the diffuse);
    - ``roughness = max(R², 0.001)``: Beckmann's m taken as glTF's α = R²;
    - ``ior = (1 + √F)/(1 − √F)`` with F = max(F0), the real index whose exact Fresnel
      (§20) reflects F at normal incidence (1.5 for a dielectric; clamped to 1000 for F → 1);
    - ``ks``: for an untextured material (drawn with ``cook_torrance``, where §26's F
      carries the reflection's size) the tint F0 / max(F0); for a textured one (drawn with
      ``textured``, Blinn-Phong, which has no Fresnel term) F0 itself;
    - ``shininess = max(2/m² − 2, 1)``, the Blinn-Phong exponent equivalent to Beckmann's m
      (Walter et al. 2007, eq. 30), for the programs that read it;
    - ``ke = emissiveFactor``; ``opacity = a`` when ``alphaMode`` is ``"BLEND"``, else 1.

    Texture maps other than the base color (metallic-roughness, normal, occlusion,
    emissive) are not read.
    """
    pbr = _table(spec.get("pbrMetallicRoughness"))
    base = _floats(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), 4, f"material {name!r} baseColorFactor")
    metallic = _unit(pbr.get("metallicFactor", 1.0), f"material {name!r} metallicFactor")
    rough = _unit(pbr.get("roughnessFactor", 1.0), f"material {name!r} roughnessFactor")
    emissive = _floats(spec.get("emissiveFactor", [0.0, 0.0, 0.0]), 3, f"material {name!r} emissiveFactor")
    color = np.clip(base[:3], 0.0, None)
    kd = _rgb(color * (1.0 - metallic))
    f0 = DIELECTRIC_F0 * (1.0 - metallic) + color * metallic
    top = float(np.max(f0))
    root = math.sqrt(min(top, 1.0))
    ior = MAX_IOR if root >= 1.0 else min((1.0 + root) / (1.0 - root), MAX_IOR)
    if textured:
        ks = _rgb(f0)
    else:
        ks = _rgb(f0 / top) if top > 0 else (0.0, 0.0, 0.0)
    m = max(rough * rough, MIN_ROUGHNESS)
    opacity = float(min(max(base[3], 0.0), 1.0)) if spec.get("alphaMode") == "BLEND" else 1.0
    return Material(ke=_rgb(np.clip(emissive, 0.0, None)), ka=kd, kd=kd, ks=ks,
                    shininess=max(2.0 / (m * m) - 2.0, 1.0), ior=max(ior, 1.0), opacity=opacity, name=name,
                    roughness=m)


# ---------------------------------------------------------------------------- trimesh


def _trimesh(path: str, suffix: str):
    """The trimesh module, or the error that says how to install it."""
    try:
        import trimesh
        import trimesh.exchange.gltf  # noqa: F401  (the readers are submodules)
        import trimesh.exchange.ply  # noqa: F401
        import trimesh.exchange.stl  # noqa: F401
        import trimesh.scene.transforms  # noqa: F401
    except ImportError as e:     # the cause stays chained, for a trimesh that is there but broken
        raise MissingExtraError(f"{path}: reading {suffix} needs trimesh: pip install 'softpipe[formats]'") from e
    return trimesh


def _said(e: BaseException) -> str:
    """What trimesh said, on one line: its message, or its exception's name."""
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _read(loader, path: str, what: str) -> Dict[str, Any]:
    """``loader(file)`` (a trimesh.exchange reader), its failures as FormatErrors naming the file."""
    with open(path, "rb") as f:
        try:
            return loader(f)
        except MemoryError:
            raise
        except Exception as e:  # noqa: BLE001 - whatever trimesh raised, worded with the file
            raise FormatError(f"{path}: cannot read it as {what} (damaged or unsupported): trimesh says "
                              f"{excerpt(_said(e), 300)}") from None


def _welded(data: Dict[str, Any]) -> Dict[str, Any]:
    """An STL's triangle soup indexed: corners at the same position (exactly) share a vertex,
    numbered in order of first use. The facet normals are not kept (often wrong in STL files;
    the renderer computes the normals, as for an OBJ without ``vn``)."""
    vertices = np.asarray(data.get("vertices", np.zeros((0, 3))), np.float64).reshape(-1, 3)
    faces = np.asarray(data.get("faces", np.zeros((0, 3), np.int64)), np.int64).reshape(-1, 3)
    if not len(vertices) or not np.isfinite(vertices).all():
        return {"vertices": vertices, "faces": faces}   # the checks of _from_arrays name the problem
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")            # unique rows in order of first appearance
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    return {"vertices": vertices[np.sort(first)], "faces": rank[inverse.ravel()][faces]}


def _finite(path: str, what: str, a: np.ndarray) -> None:
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise FormatError(f"{path}: {what} {i} is not finite: {a[i].tolist()}")


def _arrays(data: Dict[str, Any], path: str, where: str = "") -> Tuple[np.ndarray, np.ndarray, Any, Any]:
    """positions, triangles, normals (or None), uvs (or None) of one trimesh geometry, checked."""
    vertices = np.asarray(data.get("vertices", np.zeros((0, 3))), np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise FormatError(f"{path}: {where}vertices must be [N, 3], got shape {vertices.shape}")
    faces = data.get("faces")
    faces = np.zeros((0, 3), np.int64) if faces is None else np.asarray(faces)
    if faces.size and faces.ndim == 2 and faces.shape[1] > 3 and faces.dtype.kind in "iu":
        # polygons of one size (a PLY of quads): split as trimesh splits a mixed file's
        # quads, (0 1 2) (2 3 0); larger ones as a fan from their first corner
        k = faces.shape[1]
        fan = [[0, 1, 2], [2, 3, 0]] if k == 4 else [[0, j, j + 1] for j in range(1, k - 1)]
        faces = faces[:, fan].reshape(-1, 3)
    if faces.size and (faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu"):
        raise FormatError(f"{path}: {where}faces must be polygons of vertex indices, got {faces.dtype} array of "
                          f"shape {faces.shape}")
    faces = faces.reshape(-1, 3).astype(np.int64)
    _finite(path, f"{where}vertex", vertices)
    normals = data.get("vertex_normals")
    if normals is not None:
        normals = np.asarray(normals, np.float64)
        if normals.shape != vertices.shape:
            normals = None      # not one per vertex: not the file's per-vertex normals
        else:
            _finite(path, f"{where}normal of vertex", normals)
    visual = data.get("visual")
    uvs = getattr(visual, "uv", None)
    if uvs is not None:
        uvs = np.asarray(uvs, np.float64)
        if uvs.shape != (len(vertices), 2):
            uvs = None
        else:
            _finite(path, f"{where}texture coordinate of vertex", uvs)
    return vertices, faces, normals, uvs


def _from_arrays(data: Dict[str, Any], path: str, name: str, report: FormatReport) -> Mesh:
    """The Mesh of a PLY or STL file (one geometry)."""
    vertices, faces, normals, uvs = _arrays(data, path)
    if not len(vertices):
        raise FormatError(f"{path}: the file holds no vertices: nothing to draw")
    points = None
    if not len(faces):
        warnings.warn(f"{path}: no faces: its {len(vertices):,} vertices are read as points (a point cloud)",
                      FormatWarning, stacklevel=2)
        points = np.arange(len(vertices))
    report.counts = {"vertices": len(vertices), "triangles": len(faces), "points": 0 if points is None else
                     len(points)}
    return _mesh(path, positions=vertices, indices=faces, normals=normals, uvs=uvs, points=points, name=name,
                 source=report)


def _mesh(path: str, **kw: Any) -> Mesh:
    """Mesh(**kw), a ValueError of its checks (an index out of range, …) prefixed with the file."""
    try:
        return Mesh(**kw)
    except (ValueError, TypeError) as e:
        raise FormatError(f"{path}: {e}") from None


# ---------------------------------------------------------------------------- glTF


class _Resolver:
    """What a ``.gltf`` names (buffers, images), read from its folder under softpipe's policy
    (:func:`softpipe.core.files.resolve_inside`); the reasons a file was not read are kept,
    since trimesh leaves out an image it cannot read without saying why."""

    def __init__(self, folder: str, allow_outside: bool) -> None:
        self.folder, self.allow_outside = folder, allow_outside
        self.refused: List[str] = []

    def get(self, name: str) -> bytes:
        try:
            path = resolve_inside(self.folder, name, allow_outside=self.allow_outside)
            with open(path, "rb") as f:
                return f.read()
        except (PathPolicyError, OSError) as e:
            why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
            self.refused.append(f"{excerpt(name)}: {why}")
            raise FileNotFoundError(f"{name}: {why}") from None

    __getitem__ = get

    def get_base(self) -> bytes:     # trimesh's Resolver interface; a .gltf is read from its file object
        raise FileNotFoundError("no base file")

    def namespaced(self, namespace: str) -> "_Resolver":
        return _Resolver(os.path.join(self.folder, namespace), self.allow_outside)

    def keys(self):
        return iter(())

    def __contains__(self, name: str) -> bool:
        return False


def _gltf_json(path: str, suffix: str) -> Dict[str, Any]:
    """The glTF's JSON (for a .glb its first chunk): trimesh keeps a material's colors as bytes,
    so the factors are read as the file gives them, in floats, from here."""
    with open(path, "rb") as f:
        data = f.read()
    if suffix == ".glb":
        _, _, _, length, _kind = struct.unpack_from("<4sIIII", data, 0)   # trimesh checked it already
        data = data[20:20 + length]
    tree = json.loads(data.decode("utf-8-sig"))
    return tree if isinstance(tree, dict) else {}


def _rgb(a: np.ndarray) -> Tuple[float, float, float]:
    return float(a[0]), float(a[1]), float(a[2])


def _table(value: Any) -> Dict[str, Any]:
    """A JSON object as a dict; anything else as an empty one (glTF's defaults then apply)."""
    return value if isinstance(value, dict) else {}


def _unit(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise FormatError(f"{what} must be a number in [0, 1], got {excerpt(repr(value), 60)}")
    return float(value)


def _floats(value: Any, n: int, what: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise FormatError(f"{what} must be {n} finite numbers, got {excerpt(repr(value), 60)}")
    return np.asarray(value, np.float64)


def _primitive_materials(tree: Dict[str, Any]) -> List[Optional[int]]:
    """The material index of each primitive trimesh made a geometry of, in its order."""
    out: List[Optional[int]] = []
    for m in tree.get("meshes", []) or []:
        for p in (m.get("primitives", []) if isinstance(m, dict) else []) or []:
            if isinstance(p, dict) and p.get("mode", 4) in _TRIMESH_MODES:
                index = p.get("material")
                out.append(index if isinstance(index, int) and not isinstance(index, bool) else None)
    return out


def _texture_of(visual, path: str, name: str):
    """The base-color texture trimesh decoded for a material, as an sRGB Texture2D (or None)."""
    image = getattr(getattr(visual, "material", None), "baseColorTexture", None)
    if image is None:
        return None
    from softpipe.light.texture import Texture2D  # only a textured model pays for the image code
    if image.mode not in ("L", "RGB", "RGBA"):
        image = image.convert("RGBA")
    try:
        return Texture2D(np.asarray(image), srgb=True)      # glTF: base color textures are sRGB-encoded
    except (ValueError, TypeError) as e:
        raise FormatError(f"{path}: the base color texture of material {name!r}: {e}") from None


def _from_gltf(trimesh, path: str, suffix: str, name: str, report: FormatReport, allow_outside: bool) -> Mesh:
    resolver = _Resolver(os.path.dirname(os.path.abspath(path)), allow_outside)
    loader = trimesh.exchange.gltf.load_glb if suffix == ".glb" else trimesh.exchange.gltf.load_gltf
    kwargs = _read(lambda f: loader(f, resolver=resolver), path, "glTF 2.0")
    try:
        tree = _gltf_json(path, suffix)
    except (ValueError, struct.error):
        tree = {}
    geometry: Dict[str, Dict[str, Any]] = dict(kwargs.get("geometry") or {})
    prim_materials = _primitive_materials(tree)
    if len(prim_materials) != len(geometry):     # trimesh read the primitives otherwise than expected
        if any(i is not None for i in prim_materials):
            warnings.warn(f"{path}: the materials could not be matched with the {len(geometry)} primitives trimesh "
                          "read; drawn with the default material", FormatWarning, stacklevel=3)
        prim_materials = [None] * len(geometry)
    material_of = dict(zip(geometry, prim_materials))
    specs = tree.get("materials", []) if isinstance(tree.get("materials"), list) else []
    arrays = {}
    for gname, data in geometry.items():
        if "faces" in data or "entities" not in data:      # triangles or points; not lines (Path)
            arrays[gname] = _arrays(data, path, f"mesh {gname!r}: ")
    try:
        graph = trimesh.scene.transforms.SceneGraph(base_frame=kwargs.get("base_frame", "world"))
        for edge in kwargs.get("graph") or []:
            graph.update(**edge)
        nodes = [(node, *graph[node]) for node in graph.nodes_geometry]
        # in the order of the file's meshes (a mesh's instances in trimesh's order of its nodes)
        rank = {gname: k for k, gname in enumerate(geometry)}
        nodes.sort(key=lambda n: rank.get(n[2], len(rank)))
    except MemoryError:
        raise
    except Exception as e:  # noqa: BLE001 - the node graph, as trimesh builds it
        raise FormatError(f"{path}: cannot read it as glTF 2.0 (damaged or unsupported): trimesh says "
                          f"{excerpt(_said(e), 300)}") from None
    slots: Dict[Any, Material] = {}        # material index (None: no material) -> Material
    skipped = set()
    parts = []
    for _node, matrix, gname in nodes:
        if gname not in arrays:
            skipped.add(gname)
            continue
        vertices, faces, normals, uvs = arrays[gname]
        index = material_of.get(gname)
        visual = geometry[gname].get("visual")
        if index not in slots:
            slots[index] = _part_material(index, specs, visual, uvs, path, report, resolver.refused, tree)
        part = _mesh(path, positions=vertices, indices=faces, normals=normals, uvs=uvs,
                     points=None if len(faces) else np.arange(len(vertices)), material=slots[index],
                     name=str(gname))
        matrix = np.asarray(matrix, np.float64)
        if not np.array_equal(matrix, np.eye(4)):
            try:
                part = part.transformed(matrix)
            except ValueError as e:
                raise FormatError(f"{path}: node transform of mesh {gname!r}: {e}") from None
            _finite(path, f"mesh {gname!r}: transformed vertex", part.positions)
        parts.append(part)
    for gname in sorted(skipped):
        warnings.warn(f"{path}: mesh {gname!r} is lines, which are not read; left out", FormatWarning, stacklevel=3)
    if not parts or not any(p.vertex_count for p in parts):
        raise FormatError(f"{path}: the file holds no meshes with vertices: nothing to draw")
    mesh = _joined(parts, name, path)
    report.counts = {"vertices": mesh.vertex_count, "triangles": mesh.triangle_count, "points": mesh.point_count,
                     "primitives": len(geometry), "nodes": len(parts)}
    return mesh.replace(source=report)


def _image_uri(tree: Dict[str, Any], spec: Dict[str, Any]) -> Optional[str]:
    """The ``uri`` of the image a material's base color texture names, if it names one."""
    try:
        texture = tree["textures"][spec["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
        uri = tree["images"][texture["source"]].get("uri")
    except (KeyError, IndexError, TypeError, AttributeError):
        return None
    return uri if isinstance(uri, str) else None


def _part_material(index: Optional[int], specs: Sequence[Any], visual, uvs, path: str,
                   report: FormatReport, refused: Sequence[str], tree: Dict[str, Any]) -> Material:
    """The Material of glTF material ``index`` (None: the primitive has none: softpipe's default),
    its texture put in the report."""
    if index is None:
        return Material()
    spec = _table(specs[index]) if 0 <= index < len(specs) else {}
    given = spec.get("name")
    label: str = given if isinstance(given, str) and given else f"material {index}"
    label = f"{label} #{index}" if label in report.pbr or label == Material().name else label
    texture = _texture_of(visual, path, label)
    wants = isinstance(_table(spec.get("pbrMetallicRoughness")).get("baseColorTexture"), dict)
    if wants and texture is None:
        uri = _image_uri(tree, spec)
        why = "; ".join(r for r in dict.fromkeys(refused) if uri is None or r.startswith(excerpt(uri))) \
            or "trimesh could not decode it"
        warnings.warn(f"{path}: material {label!r}: its base color texture was not read ({why}); drawn without it",
                      FormatWarning, stacklevel=4)
    elif texture is not None and uvs is None:
        warnings.warn(f"{path}: material {label!r} has a base color texture but its mesh no texture coordinates "
                      "(TEXCOORD_0); drawn without it", FormatWarning, stacklevel=4)
        texture = None
    material = glb_material(spec, label, textured=texture is not None)
    if texture is not None:
        report.textures[label] = texture
    report.pbr = report.pbr + (label,)
    return material


def _joined(parts: List[Mesh], name: str, path: str) -> Mesh:
    """One mesh of the nodes' parts: normals (uvs) kept when some part has them, the others'
    computed (set to 0, 0); the materials per triangle."""
    if any(p.normals is not None for p in parts):
        parts = [p if p.normals is not None else p.replace(normals=p.vertex_normals()) for p in parts]
    if any(p.uvs is not None for p in parts):
        parts = [p if p.uvs is not None else p.replace(uvs=np.zeros((p.vertex_count, 2))) for p in parts]
    try:
        return concatenate(parts, name=name)
    except ValueError as e:
        raise FormatError(f"{path}: {e}") from None

