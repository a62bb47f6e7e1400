"""Wavefront OBJ (and MTL) loading, vectorized with numpy.

:func:`load_obj` reads ``v``, ``vt``, ``vn``, ``f`` (any corner form, negative
indices, polygons fan-triangulated), ``l`` polylines (as their segments, ``Mesh.lines``)
and ``p`` points (``Mesh.points``), ``o``/``g`` names, ``s`` smoothing groups and
materials from ``mtllib`` into a :class:`~softpipe.scenes.mesh.Mesh`, and records
what it read in an :class:`OBJReport` (``Mesh.source``). The mesh has one vertex per
distinct (v, vt, vn) triple a face, line or point uses, ordered by that triple. A malformed
statement is an :class:`OBJError` (``file:line:`` first); a missing MTL or texture
file, or one outside the model's folder (:func:`softpipe.core.files.resolve_inside`),
is an :class:`OBJWarning`.

Why it is shaped so: statements are sorted into per-keyword lists in one pass, then
each keyword's numbers are converted in one numpy call, so every step is linear in
the file's size; anything that fast path is unsure of goes through a per-line path,
which is also the one that words the errors. Smooth normals are not made here but by
:meth:`Mesh.vertex_normals`, so that every way to get them agrees; the loader adds
only what the mesh cannot know, the smoothing groups.

docs/scenes.md ("OBJ models") is the full account: every statement read, vertex
order, normals, errors and warnings, and which files an OBJ may name.
"""
from __future__ import annotations

import errno
import os
import stat
import sys
import types
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from softpipe.core.files import PathPolicyError, check_regular_file, excerpt, excerpt_path, resolve_inside
from softpipe.light.material import Material
from softpipe.scenes.mesh import Mesh

__all__ = ["OBJError", "OBJWarning", "OBJReport", "load_obj", "parse_obj", "load_mtl", "parse_mtl"]

PathLike = Union[str, "os.PathLike[str]"]


class OBJError(ValueError):
    """A malformed OBJ or MTL statement; ``str(e)`` is ``"file:line: what was expected"``."""

    def __init__(self, file: str, line: int, message: str) -> None:
        self.file = file
        self.line = line
        self.reason = message
        super().__init__(f"{file}:{line}: {message}")


class OBJWarning(UserWarning):
    """Something missing that loading can do without (an MTL file, a material, a texture)."""


@dataclass
class OBJReport:
    """What a loaded OBJ file contained, kept in ``Mesh.source`` for debugging.

    ``counts`` are of statements in the file, by keyword (``v``, ``vt``, ``vn``, ``f``; ``l``, ``p`` when present);
    ``triangle_lines`` is the line of each triangle's face (``segment_lines``, ``point_lines``:
    of each line segment's ``l``, each point's ``p``); ``vertex_source`` the 0-based
    (v, vt, vn) file elements of each mesh vertex, -1 where absent; the ``*_ids`` are per
    triangle, -1 where no ``o`` (``g``) statement came before the triangle's face.
    """

    path: str
    lines: int = 0
    counts: Dict[str, int] = field(default_factory=dict)
    triangles: int = 0
    segments: int = 0
    points: int = 0
    skipped: Dict[str, int] = field(default_factory=dict)
    mtl_skipped: Dict[str, int] = field(default_factory=dict)
    mtllibs: Tuple[str, ...] = ()
    objects: Tuple[str, ...] = ()
    object_ids: Optional[np.ndarray] = field(default=None, repr=False)
    groups: Tuple[str, ...] = ()
    group_ids: Optional[np.ndarray] = field(default=None, repr=False)
    triangle_lines: Optional[np.ndarray] = field(default=None, repr=False)
    segment_lines: Optional[np.ndarray] = field(default=None, repr=False)
    point_lines: Optional[np.ndarray] = field(default=None, repr=False)
    vertex_source: Optional[np.ndarray] = field(default=None, repr=False)
    warnings: List[str] = field(default_factory=list)


# ---------------------------------------------------------------------------- public API


def load_obj(path: PathLike, *, allow_outside: bool = False) -> Mesh:
    """Load an OBJ file; MTL and texture paths are relative to the file's folder,
    and must lie in it or below unless ``allow_outside=True`` (docs/scenes.md, "Files the OBJ names").

    Returns a :class:`~softpipe.scenes.mesh.Mesh` whose ``source`` is an :class:`OBJReport`.
    Raises :class:`OBJError` for malformed statements, :class:`~softpipe.core.files.PathPolicyError`
    (a ValueError) if ``path`` is a FIFO, device or socket, and ``OSError`` if the file
    cannot be read.
    """
    path = os.fspath(path)
    text = _read_text(path)
    name = os.path.splitext(os.path.basename(path))[0]
    return _OBJParser(text, path, os.path.dirname(path), allow_outside).mesh(name)


#: Larger indices (and smoothing groups) cannot name anything: refused before numpy's int64 overflows.
_MAX_INDEX = 1 << 40


def parse_obj(text: str, name: str = "<string>", base_dir: Optional[PathLike] = None, *,
              allow_outside: bool = False) -> Mesh:
    """Parse OBJ text; ``name`` labels error messages, ``base_dir`` resolves ``mtllib``
    (files outside it are refused unless ``allow_outside=True``).

    With ``base_dir=None``, MTL files are looked up relative to the current directory.
    """
    text = text[1:] if text.startswith("\ufeff") else text      # a byte-order mark, as load_obj skips it
    return _OBJParser(text, name, os.fspath(base_dir) if base_dir is not None else "", allow_outside).mesh(name)


def load_mtl(path: PathLike, *, allow_outside: bool = False) -> Dict[str, Material]:
    """Load an MTL file into ``{material name: Material}``; ``map_Kd`` files outside its
    folder are refused (a warning) unless ``allow_outside=True``."""
    path = os.fspath(path)
    text = _read_text(path)
    return _parse_mtl(text, path, os.path.dirname(path), [], allow_outside)[0]


def parse_mtl(text: str, name: str = "<string>", base_dir: Optional[PathLike] = None, *,
              allow_outside: bool = False) -> Dict[str, Material]:
    """Parse MTL text into ``{material name: Material}``; ``base_dir`` resolves ``map_Kd``."""
    return _parse_mtl(text, name, os.fspath(base_dir) if base_dir is not None else "", [], allow_outside)[0]


# ---------------------------------------------------------------------------- helpers


def _read_text(path: str) -> str:
    """The text of a regular file (a byte-order mark skipped, bad UTF-8 replaced).

    A FIFO, device or socket raises :class:`PathPolicyError` before it is opened, and
    again if one was put in its place since: the file is opened without blocking and
    checked before it is read.
    """
    check_regular_file(path)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    with os.fdopen(fd, "rb") as f:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), path)
        if not stat.S_ISREG(mode):
            raise PathPolicyError(f"{excerpt_path(path)} is not a regular file")
        data = f.read()
    return data.decode("utf-8-sig", errors="replace")


#: How much of an unknown keyword ``OBJReport.skipped`` keeps.
_KEYWORD_CHARS = 40
#: How much of a library's name ``OBJReport.mtllibs`` keeps (longer ones cannot name a file).
_PATH_CHARS = 4096


def _short(text: str, limit: int = _KEYWORD_CHARS) -> str:
    """``text`` cut to ``limit`` characters (unquoted), for keys and messages."""
    return text if len(text) <= limit else text[:limit] + "…"


def _keyword_key(keyword: str) -> str:
    return _short(keyword)


def _split_lines(text: str) -> List[str]:
    """Lines of the text; a backslash-continued line is joined onto its first line,
    and the lines it swallowed become empty, so list index + 1 stays the line number."""
    # Not str.splitlines(), which also breaks at form feeds and the like and would
    # make line numbers disagree with an editor's.
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if "\\" not in text:
        return lines
    i = 0
    while i < len(lines):
        j, parts = i, []
        while j + 1 < len(lines):
            # Each physical line is judged on its own and the parts are joined once at
            # the end: linear in the run's length (growing one string was quadratic).
            stripped = lines[j].rstrip()
            if not stripped.endswith("\\"):
                break
            parts.append(stripped[:-1])
            if j > i:
                lines[j] = ""
            j += 1
        if parts:
            parts.append(lines[j])
            lines[i], lines[j] = " ".join(parts), ""
        i = j + 1
    return lines


def _strip_comment(text: str) -> str:
    return text.split("#", 1)[0] if "#" in text else text


def _warn(message: str) -> None:
    """Warn with the location of the first caller outside this module."""
    frame: Optional[types.FrameType]
    frame, level = sys._getframe(1), 2
    while frame is not None and frame.f_code.co_filename == __file__:
        frame, level = frame.f_back, level + 1
    warnings.warn(message, OBJWarning, stacklevel=level)


def _event_ids(event_lines: Sequence[int], at_lines: np.ndarray) -> np.ndarray:
    """For each line in ``at_lines``, the index of the latest event before it (-1: none)."""
    return np.searchsorted(np.asarray(event_lines, dtype=np.int64), at_lines) - 1


def _ints_from_string(s: str) -> Optional[np.ndarray]:
    """Whitespace-separated integers in one C call; None if the text does not parse."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # old numpy warns, new numpy raises
        try:
            return np.fromstring(s, dtype=np.int64, sep=" ")
        except ValueError:
            return None


# ---------------------------------------------------------------------------- the OBJ parser

_VECTOR_WIDTHS = {"v": (3, 4, 6), "vt": (2, 3, 1), "vn": (3,)}  # accepted counts, most common first
_VECTOR_KEEP = {"v": 3, "vt": 2, "vn": 3}
_VECTOR_EXPECT = {"v": "3 numbers", "vt": "1 to 3 numbers (u v [w])", "vn": "3 numbers"}
# keyword -> (what the index is, the element in singular and plural)
# keyword -> (the corner forms it takes, the fewest vertices a statement has)
_ELEMENTS = {"l": ("a line vertex v or v/vt", 2), "p": ("a point vertex v", 1)}
_NOUNS = {"v": ("index", "vertex", "vertices"),
          "vt": ("texture index", "texture coordinate (vt)", "texture coordinates (vt)"),
          "vn": ("normal index", "normal (vn)", "normals (vn)")}


class _OBJParser:
    """One parse of one OBJ text: holds the file name and lines for error messages."""

    def __init__(self, text: str, file: str, base_dir: str, allow_outside: bool = False) -> None:
        self.file = file
        self.base_dir = base_dir
        self.allow_outside = allow_outside
        self.lines = _split_lines(text)
        self.report = OBJReport(path=file, lines=len(self.lines))
        #: vertices read as points, in a file of vertices alone (0: none)
        self.cloud = 0

    # -- messages

    def error(self, index: int, message: str) -> OBJError:
        return OBJError(self.file, index + 1, message)

    def quoted(self, index: int) -> str:
        return excerpt(self.lines[index].strip())

    def warn(self, message: str) -> None:
        self.report.warnings.append(message)
        _warn(message)

    # -- pass 1: sort statements by keyword

    def scan(self) -> None:
        """One pass over the lines; the common ``v ``/``f `` prefixes skip the split."""
        self.vec: Dict[str, Tuple[list, list]] = {k: ([], []) for k in ("v", "vt", "vn", "f", "l", "p")}  # keyword -> (texts, line indices)
        self.events: Dict[str, List[Tuple[int, str]]] = {k: [] for k in ("usemtl", "o", "g", "s", "mtllib")}  # keyword -> [(index, rest)]
        skipped: Counter = Counter()
        # Bound methods: this loop runs once per line of the file.
        v_text, v_line = (lst.append for lst in self.vec["v"])
        f_text, f_line = (lst.append for lst in self.vec["f"])
        other = self.scan_other
        for i, line in enumerate(self.lines):
            head = line[:2]
            if head == "v ":
                v_text(line)
                v_line(i)
            elif head == "f ":
                f_text(line)
                f_line(i)
            elif line and head[0] != "#":
                other(i, line, skipped)
        self.report.skipped = dict(skipped)

    def scan_other(self, i: int, line: str, skipped: Counter) -> None:
        parts = _strip_comment(line).split(None, 1)
        if not parts:
            return
        keyword = parts[0]
        if keyword in self.vec:
            self.vec[keyword][0].append(line)
            self.vec[keyword][1].append(i)
        elif keyword in self.events:
            self.events[keyword].append((i, parts[1].strip() if len(parts) > 1 else ""))
        else:
            skipped[_keyword_key(keyword)] += 1

    # -- pass 2: numbers

    def vectors(self, keyword: str) -> np.ndarray:
        """All ``v`` (``vt``, ``vn``) lines as one float64 array [count, 3 (2, 3)]."""
        texts = self.vec[keyword][0]
        keep = _VECTOR_KEEP[keyword]
        if not texts:
            return np.zeros((0, keep))
        joined = " ".join(texts)
        if "#" not in joined:
            tokens = joined.split()
            n = len(texts)
            for width in _VECTOR_WIDTHS[keyword]:
                stride = width + 1
                # Every line is exactly `width` numbers iff the keyword sits at each stride
                # start and nowhere else.
                if len(tokens) == stride * n and tokens.count(keyword) == n and tokens[::stride].count(keyword) == n:
                    del tokens[::stride]
                    try:
                        values = np.array(tokens, dtype=np.float64).reshape(n, width)
                    except ValueError:
                        break
                    if np.isfinite(values).all():
                        return self.pad(values, keep)
                    break
        return self.vectors_slowly(keyword)

    @staticmethod
    def pad(values: np.ndarray, keep: int) -> np.ndarray:
        if values.shape[1] >= keep:
            return np.ascontiguousarray(values[:, :keep])
        return np.hstack([values, np.zeros((values.shape[0], keep - values.shape[1]))])

    def vectors_slowly(self, keyword: str) -> np.ndarray:
        """Line by line: mixed widths, comments, and the error for a bad line."""
        texts, nos = self.vec[keyword]
        keep = _VECTOR_KEEP[keyword]
        out = np.zeros((len(texts), keep))
        for row, (text, i) in enumerate(zip(texts, nos)):
            numbers = _strip_comment(text).split()[1:]
            bad = len(numbers) not in _VECTOR_WIDTHS[keyword]
            try:
                values = [float(x) for x in numbers]
            except ValueError:
                bad = True
            if bad:
                raise self.error(i, f"expected {_VECTOR_EXPECT[keyword]} after {keyword!r}, got {self.quoted(i)}")
            if not all(np.isfinite(values)):
                raise self.error(i, f"expected finite numbers after {keyword!r}, got {self.quoted(i)}")
            out[row, : min(keep, len(values))] = values[:keep]
        return out

    def faces(self) -> Tuple[np.ndarray, np.ndarray]:
        """Corner counts per face [F] and raw (v, vt, vn) per corner [C, 3], 0 = absent."""
        texts = self.vec["f"][0]
        if not texts:
            return np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
        # The bodies after "f "; a line indented by two or more keeps its "f", which
        # the fast path rejects and the per-line path reads correctly.
        parsed = _parse_faces("\n".join([t[2:] for t in texts]), len(texts))
        return parsed if parsed is not None else self.faces_slowly()

    def faces_slowly(self) -> Tuple[np.ndarray, np.ndarray]:
        """Line by line; words the error for the first malformed face."""
        texts, nos = self.vec["f"]
        counts, corners = [], []
        for text, i in zip(texts, nos):
            tokens = _strip_comment(text).split()[1:]
            if len(tokens) < 3:
                raise self.error(i, f"expected at least 3 vertices after 'f', got {self.quoted(i)}")
            for tok in tokens:
                corners.append(self.corner(tok, i))
            counts.append(len(tokens))
        return np.asarray(counts, np.int64), np.asarray(corners, np.int64).reshape(-1, 3)

    def corner(self, tok: str, i: int) -> Tuple[int, int, int]:
        fields = tok.split("/")
        # v, v/vt, v//vn, v/vt/vn: only vt may be empty, and only in the three-field form.
        ok = 1 <= len(fields) <= 3 and fields[0] != "" and fields[-1] != ""
        return self.corner_values(tok, i, fields, ok, "a face corner v, v/vt, v//vn or v/vt/vn")

    def corner_values(self, tok: str, i: int, fields: List[str], ok: bool, expected: str) -> Tuple[int, int, int]:
        """(v, vt, vn) of a corner split into ``fields`` (0 where empty or absent), whose form is ``ok``:
        else, or for an index too large or 0, the error of line ``i`` (``expected`` words the form)."""
        try:
            values = [int(x) if x else 0 for x in fields] if ok else []
        except ValueError:
            ok = False
        if ok and any(abs(x) > _MAX_INDEX for x in values):
            raise self.error(i, f"index in {excerpt(tok)} is beyond any possible vertex count "
                                f"(at most {_MAX_INDEX}): {self.quoted(i)}")
        if not ok:
            raise self.error(i, f"expected {expected}, got {excerpt(tok)} in {self.quoted(i)}")
        if any(x == 0 for x, s in zip(values, fields) if s):
            raise self.error(i, f"index 0 in {excerpt(tok)} is invalid (OBJ indices start at 1): {self.quoted(i)}")
        values += [0] * (3 - len(values))
        return values[0], values[1], values[2]

    def elements(self, keyword: str) -> Tuple[np.ndarray, np.ndarray]:
        """Vertex counts per ``l`` (``p``) statement [S] and raw (v, vt, 0) per vertex [C, 3], 0 = absent."""
        texts, nos = self.vec[keyword]
        forms, least = _ELEMENTS[keyword]
        counts, corners = [], []
        for text, i in zip(texts, nos):
            tokens = _strip_comment(text).split()[1:]
            if len(tokens) < least:
                raise self.error(i, f"expected at least {least} {'vertex' if least == 1 else 'vertices'} "
                                    f"after {keyword!r}, got {self.quoted(i)}")
            ints = None if any("/" in t for t in tokens) else _ints_from_string(" ".join(tokens))
            if ints is not None and ints.size == len(tokens) and ints.all() and (np.abs(ints) <= _MAX_INDEX).all():
                corners.append(np.column_stack([ints, np.zeros((len(ints), 2), np.int64)]))
            else:   # the tokens one by one: the form, or the error that words what is wrong
                corners.append(np.asarray([self.element_corner(tok, i, keyword, forms) for tok in tokens],
                                          np.int64).reshape(-1, 3))
            counts.append(len(tokens))
        if not counts:
            return np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
        return np.asarray(counts, np.int64), np.concatenate(corners)

    def element_corner(self, tok: str, i: int, keyword: str, forms: str) -> Tuple[int, int, int]:
        """(v, vt, 0) of one vertex of an ``l`` (v or v/vt) or ``p`` (v) statement."""
        fields = tok.split("/")
        ok = len(fields) <= (2 if keyword == "l" else 1) and all(fields)
        return self.corner_values(tok, i, fields, ok, f"{forms} after {keyword!r}")

    # -- pass 3: indices

    def resolve(self, keyword: str, raw: np.ndarray, corner_line: np.ndarray) -> np.ndarray:
        """0-based indices (-1 where absent) from raw 1-based or negative ones, checked
        against the number of elements defined before each corner's statement (line
        index ``corner_line``); the first bad one in the file is the error."""
        so_far = np.searchsorted(np.asarray(self.vec[keyword][1], np.int64), corner_line)
        present = raw != 0
        index = np.where(raw > 0, raw - 1, so_far + raw)
        bad = present & ((index < 0) | (index >= so_far))
        if bad.any():
            k = int(np.flatnonzero(bad)[np.argmin(corner_line[bad])])
            i = int(corner_line[k])
            what, one, many = _NOUNS[keyword]
            noun = one if so_far[k] == 1 else many
            raise self.error(i, f"{what} {raw[k]} but only {so_far[k]} {noun} so far: {self.quoted(i)}")
        return np.where(present, index, -1)

    # -- assembly

    def mesh(self, name: str) -> Mesh:
        self.scan()
        self.vertices_as_points()
        self.smoothing_groups()  # checked even when the file's normals make them moot
        data = {k: self.vectors(k) for k in ("v", "vt", "vn")}
        counts, raw = self.faces()
        corner_face = np.repeat(np.arange(len(counts)), counts)
        face_lines = np.asarray(self.vec["f"][1], np.int64)
        # The corners of lines and points follow the faces' in one list, so that one
        # vertex numbering serves all three.
        l_counts, l_raw = self.elements("l")
        p_counts, p_raw = self.elements("p")
        l_lines, p_lines = (np.asarray(self.vec[k][1], np.int64) for k in ("l", "p"))
        corner_line = np.concatenate([face_lines[corner_face], np.repeat(l_lines, l_counts), p_lines[np.repeat(
            np.arange(len(p_counts)), p_counts)]])
        raw = np.concatenate([raw, l_raw, p_raw])
        idx = np.stack([self.resolve(k, raw[:, c], corner_line) for c, k in enumerate(("v", "vt", "vn"))], 1)
        tri_face, tri_corners = _fan(counts)
        seg_statement, seg_corners = _segments(l_counts)
        face_corners = len(corner_face)
        seg_corners += face_corners
        point_corners = face_corners + len(l_raw) + np.arange(len(p_raw))
        vertex_of_corner, first_corner, smoothing = self.vertices(idx, corner_face)
        used = idx[first_corner]  # (v, vt, vn) of each mesh vertex
        on_face = np.zeros(len(first_corner), bool)
        on_face[vertex_of_corner[:face_corners]] = True
        positions, normals, uvs = self.attributes(data, used, on_face)
        element_lines = np.concatenate([face_lines[tri_face], l_lines[seg_statement], corner_line[point_corners]])
        material, materials, ids = self.materials(element_lines)
        ends = np.cumsum([len(tri_face), len(seg_statement)])
        material_ids, line_ids, point_ids = (None, None, None) if ids is None else np.split(ids, ends)
        self.fill_report(data, tri_face, used, element_lines[ends[0]:ends[1]], element_lines[ends[1]:])
        mesh = Mesh(positions, vertex_of_corner[tri_corners], normals, uvs, material=material,
                    materials=materials, material_ids=material_ids, name=name, source=self.report,
                    lines=vertex_of_corner[seg_corners], points=vertex_of_corner[point_corners],
                    line_material_ids=line_ids if len(seg_statement) else None,
                    point_material_ids=point_ids if len(point_corners) else None)
        if normals is not None and (used[:, 2] < 0).any():
            # Corners without a vn get normals from the faces (a warning said so).
            normals = np.where(used[:, 2:] < 0, mesh.vertex_normals(), normals)
            mesh = mesh.replace(normals=normals)
        elif smoothing is not None and len(first_corner):
            # No vn but smoothing groups: welded normals within each group, so a crease
            # between groups (or at an `s off` face) stays, and the rest is smooth.
            mesh = mesh.replace(normals=mesh.vertex_normals(groups=smoothing[first_corner]))
        if self.cloud:
            self.warn(f"{self.file}: no faces, lines or points: its {self.cloud:,} vertices are read as points "
                      "(a point cloud)")
        return mesh

    def vertices_as_points(self) -> None:
        """A file of vertices alone (no ``f``, ``l`` or ``p``: how many tools write a point cloud) reads as
        if a last line ``p 1 2 … N`` named every vertex: its points, with a warning that says so."""
        v_lines = self.vec["v"][1]
        if not v_lines or any(self.vec[k][0] for k in ("f", "l", "p")):
            return
        n = len(v_lines)
        self.vec["p"][0].append("p " + " ".join(map(str, range(1, n + 1))))
        self.vec["p"][1].append(v_lines[-1] + 1)          # after every v: each index is defined by then
        self.cloud = n                                    # said once the file has read without an error

    def fill_report(self, data: dict, tri_face: np.ndarray, used: np.ndarray, segment_lines: np.ndarray,
                    point_lines: np.ndarray) -> None:
        rep = self.report
        rep.counts = {k: len(data[k]) for k in ("v", "vt", "vn")}
        rep.counts["f"] = len(self.vec["f"][0])
        for k in ("l", "p"):    # only when present: the counts of a file of faces are as they were
            if self.vec[k][0]:
                rep.counts[k] = len(self.vec[k][0])
        rep.triangles = len(tri_face)
        rep.segments, rep.points = len(segment_lines), len(point_lines)
        rep.segment_lines = (segment_lines + 1).astype(np.int32)
        rep.point_lines = (point_lines + 1).astype(np.int32)
        if rep.triangles == 0 and rep.segments == 0 and rep.points == 0:
            self.warn(f"{self.file}: no faces, lines or points; the mesh is empty")
        face_lines = np.asarray(self.vec["f"][1], np.int64)
        rep.triangle_lines = (face_lines[tri_face] + 1).astype(np.int32)
        rep.vertex_source = used.astype(np.int32)
        rep.objects, rep.object_ids = self.labels("o", face_lines, tri_face, "")
        rep.groups, rep.group_ids = self.labels("g", face_lines, tri_face, "default")

    def vertices(self, idx: np.ndarray, corner_face: np.ndarray):
        """One vertex per distinct (v, vt, vn[, smoothing group]) of the corners:
        (vertex of each corner, first corner of each vertex, the smoothing key of each
        corner or None when smoothing groups do not matter)."""
        cols = [idx[:, 0]] + [idx[:, c] for c in (1, 2) if (idx[:, c] >= 0).any()]
        smoothing = None
        if (idx[:, 2] < 0).all() and self.events["s"]:
            # a line's or point's corner has no smoothing group (-1)
            smoothing = np.concatenate([self.smoothing_key(corner_face),
                                        np.full(len(idx) - len(corner_face), -1, np.int64)])
            cols.append(smoothing)
        return _unique_rows(cols) + (smoothing,)

    def smoothing_groups(self) -> List[int]:
        """The group number of each ``s`` statement, 0 for ``off``."""
        values = []
        for i, rest in self.events["s"]:
            word = _strip_comment(rest).strip()
            try:
                value = 0 if word == "off" else int(word)
            except ValueError:
                raise self.error(i, f"expected a smoothing group number or 'off' after 's', got {self.quoted(i)}") \
                    from None
            if not 0 <= value <= _MAX_INDEX:
                raise self.error(i, f"expected a smoothing group number in [0, {_MAX_INDEX}] or 'off' after 's', "
                                    f"got {self.quoted(i)}")
            values.append(value)
        return values

    def smoothing_key(self, corner_face: np.ndarray) -> np.ndarray:
        """Per corner: 0 before any ``s``, the group for ``s N``, and a key of its own
        per face for ``s off``/``s 0`` (so that face shares no vertex: flat)."""
        events = self.events["s"]
        values = self.smoothing_groups()
        face_lines = np.asarray(self.vec["f"][1], np.int64)
        ev = _event_ids([i for i, _ in events], face_lines)
        group = np.where(ev >= 0, np.asarray(values, np.int64)[np.maximum(ev, 0)], -1)
        top = max(values) + 1
        faces = np.arange(len(face_lines))
        key = np.where(group == 0, top + faces, np.maximum(group, 0))
        return key[corner_face]

    def attributes(self, data: dict, rep_idx: np.ndarray, on_face: np.ndarray):
        """positions, normals (or None), uvs (or None) of the vertices; ``on_face``: the
        vertices a face uses (only theirs are warned about: a line or point corner never
        has a normal, and often no vt)."""
        positions = data["v"][rep_idx[:, 0]]
        uvs = normals = None
        has_vt, has_vn = rep_idx[:, 1] >= 0, rep_idx[:, 2] >= 0
        if has_vt.any():
            if not has_vt[on_face].all():
                self.warn(f"{self.file}: some face corners have no texture coordinates; they get (0, 0)")
            uvs = np.where(has_vt[:, None], data["vt"][np.maximum(rep_idx[:, 1], 0)], 0.0)
        if has_vn.any():
            if not has_vn[on_face].all():
                self.warn(f"{self.file}: some face corners have no normal; they get area-weighted vertex normals")
            normals = np.where(has_vn[:, None], data["vn"][np.maximum(rep_idx[:, 2], 0)], 0.0)
        return positions, normals, uvs

    def materials(self, element_lines: np.ndarray):
        """(material, materials, material ids) for the Mesh, from usemtl/mtllib: the ids
        per element (triangles, segments, points), given the line index of each.

        Materials are numbered in order of first use in the file; usemtl lines naming
        the same material share one entry, and elements before any usemtl get ``Material()``.
        """
        library = self.load_libraries()
        events = self.events["usemtl"]
        event_materials = [Material()]  # entry 0: before any usemtl
        for i, rest in events:
            name = _strip_comment(rest).strip()
            if not name:
                raise self.error(i, f"expected a material name after 'usemtl', got {self.quoted(i)}")
            if name not in library:
                where = f"in {excerpt(', '.join(self.report.mtllibs), 200)}" if self.report.mtllibs else "(no mtllib)"
                self.warn(f"{self.file}:{i + 1}: material {excerpt(name)} is not defined {where}; using the default")
                library[name] = Material(name=name)
            event_materials.append(library[name])
        tri_event = _event_ids([i for i, _ in events], element_lines) + 1
        # first use by line in the file (triangles alone come in file order already)
        used, first = np.unique(tri_event, return_index=True) if _sorted(element_lines) else \
            np.unique(tri_event[np.argsort(element_lines, kind="stable")], return_index=True)
        slots: Dict[str, int] = {}
        event_slot = np.zeros(len(event_materials), np.int32)
        for e in used[np.argsort(first)]:
            event_slot[e] = slots.setdefault(event_materials[e].name, len(slots))
        if len(slots) <= 1:
            return event_materials[int(used[0])] if len(used) else Material(), (), None
        palette = [None] * len(slots)
        for e in used:
            palette[event_slot[e]] = event_materials[e]
        return palette[0], tuple(palette), event_slot[tri_event]

    def load_libraries(self) -> Dict[str, Material]:
        library: Dict[str, Material] = {}
        libs: List[str] = []
        skipped: Counter = Counter()
        for i, rest in self.events["mtllib"]:
            rest = _strip_comment(rest).strip()
            if not rest:
                raise self.error(i, f"expected a file name after 'mtllib', got {self.quoted(i)}")
            whole = self.inside(rest)
            names = [rest] if whole is not None and os.path.isfile(whole) else rest.split()
            for lib in names:
                # Refused before anything is opened or even looked up: the answer is the
                # same whether or not an outside file exists.
                try:
                    path = resolve_inside(self.base_dir, lib, allow_outside=self.allow_outside)
                except PathPolicyError as e:
                    libs.append(_short(lib, _PATH_CHARS))
                    self.warn(f"{self.file}:{i + 1}: material library {e}; using default materials")
                    continue
                libs.append(_short(os.path.join(self.base_dir, lib), _PATH_CHARS))
                if not os.path.isfile(path):
                    self.warn(f"{self.file}:{i + 1}: material library {excerpt_path(os.path.join(self.base_dir, lib))} "
                              "not found; using default materials")
                    continue
                try:
                    text = _read_text(path)
                except (PathPolicyError, OSError) as e:
                    why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
                    self.warn(f"{self.file}:{i + 1}: material library {excerpt(lib)} cannot be read ({why}); "
                              "using default materials")
                    continue
                mats, sk = _parse_mtl(text, path, os.path.dirname(path), self.report.warnings, self.allow_outside)
                library.update(mats)
                skipped.update(sk)
        self.report.mtllibs = tuple(libs)
        self.report.mtl_skipped = dict(skipped)
        return library

    def inside(self, reference: str) -> Optional[str]:
        """The file ``reference`` names if the policy lets it be read, else None (no error)."""
        try:
            return resolve_inside(self.base_dir, reference, allow_outside=self.allow_outside)
        except PathPolicyError:
            return None

    def labels(self, keyword: str, face_lines: np.ndarray, tri_face: np.ndarray, empty: str):
        """(names, per-triangle id) for ``o`` or ``g``; -1 before the first statement."""
        events = self.events[keyword]
        names = [(_strip_comment(rest).strip() or empty) for _, rest in events]
        number: Dict[str, int] = {}     # name -> its slot, in order of first appearance (linear)
        slot = np.asarray([number.setdefault(n, len(number)) for n in names] + [-1], np.int32)
        unique = list(number)
        ev = _event_ids([i for i, _ in events], face_lines)[tri_face]
        return tuple(unique), slot[ev]  # ev = -1 picks the trailing -1


def _parse_faces(body: str, n: int) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """All face corners at once from the ``n`` face bodies joined by newlines:
    (corners per face [n], raw (v, vt, vn) per corner [C, 3], 0 = absent).

    None when anything is not a well-formed v, v/vt, v//vn or v/vt/vn, or a face has
    fewer than 3 corners; the per-line path then words the error. Works on the bytes:
    per-token slash counts tell each corner's form, and after writing ``//`` as ``/0/``
    and ``/`` as a space every field parses in one numpy call.
    """
    try:
        b = np.frombuffer(body.encode("ascii"), np.uint8)
    except UnicodeEncodeError:
        return None
    if b.size == 0:
        return None
    newline = b == 10
    white = (b == 32) | (b == 9) | newline
    slash = b == 47
    digit = (b >= 48) & (b <= 57)
    sign = (b == 45) | (b == 43)
    if not (white | slash | digit | sign).all():
        return None
    before = np.concatenate(([True], white[:-1]))
    before_slash = np.concatenate(([False], slash[:-1]))
    after_digit = np.concatenate((digit[1:], [False]))
    # A sign only at the start of a field and before a digit, so fields split unambiguously.
    if (sign & ~((before | before_slash) & after_digit)).any():
        return None
    start = ~white & before  # first byte of each corner token
    counts = np.bincount(np.cumsum(newline)[start], minlength=n)
    if counts.min() < 3:
        return None
    token = np.cumsum(start) - 1
    ntok = int(counts.sum())
    slashes = np.bincount(token[slash], minlength=ntok)
    doubles = np.bincount(token[:-1][slash[:-1] & slash[1:]], minlength=ntok)
    if slashes.max() > 2 or doubles.max() > 1:
        return None
    fields = slashes + 1  # after '//' -> '/0/', every form has (slashes + 1) fields
    ints = _ints_from_string(body.replace("//", "/0/").replace("/", " "))
    if ints is None or ints.size != fields.sum():  # a size mismatch means an empty field
        return None
    first = np.cumsum(fields) - fields
    last = ints.size - 1
    has_vt = (slashes >= 1) & (doubles == 0)
    has_vn = slashes == 2
    v = ints[first]
    vt = np.where(has_vt, ints[np.minimum(first + 1, last)], 0)
    vn = np.where(has_vn, ints[np.minimum(first + 2, last)], 0)
    limit = np.iinfo(np.int64).max  # fromstring saturates huge numbers
    if (v == 0).any() or (has_vt & (vt == 0)).any() or (has_vn & (vn == 0)).any() or (np.abs(ints) == limit).any():
        return None
    return counts.astype(np.int64), np.stack([v, vt, vn], 1)


def _unique_rows(cols: List[np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """Distinct rows of the integer columns (each >= -1), in sorted order:
    (row number of each input row, first input row of each distinct row)."""
    key = cols[0] + 1
    room = int(key.max(initial=0)) + 1
    for c in cols[1:]:
        width = int(c.max(initial=0)) + 2
        if room * width >= 2**62:  # no room for one int64 key: sort rows instead
            _, first, inverse = np.unique(np.stack(cols, 1), axis=0, return_index=True, return_inverse=True)
            return inverse.reshape(-1), first
        key, room = key * width + (c + 1), room * width
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return inverse.reshape(-1), first


def _sorted(a: np.ndarray) -> bool:
    return bool((a[1:] >= a[:-1]).all())


def _segments(counts: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """A polyline's segments (c0, c1), (c1, c2), … for polylines with ``counts`` vertices,
    laid out one after another: (polyline of each segment [S], corner numbers [S, 2])."""
    starts = np.cumsum(counts) - counts
    per_line = counts - 1
    seg_line = np.repeat(np.arange(len(counts)), per_line)
    k = np.arange(len(seg_line)) - np.repeat(np.cumsum(per_line) - per_line, per_line)
    a = starts[seg_line] + k
    return seg_line, np.stack([a, a + 1], 1).reshape(-1, 2)


def _fan(counts: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Fan triangulation (c0, ci, ci+1) of polygons with ``counts`` corners, laid out
    one after another: (face of each triangle [T], corner numbers [T, 3])."""
    starts = np.cumsum(counts) - counts
    per_face = counts - 2
    tri_face = np.repeat(np.arange(len(counts)), per_face)
    k = np.arange(len(tri_face)) - np.repeat(np.cumsum(per_face) - per_face, per_face)
    a = starts[tri_face]
    return tri_face, np.stack([a, a + k + 1, a + k + 2], 1)


# ---------------------------------------------------------------------------- MTL

_MTL_COLORS = {"Ka": "ka", "Kd": "kd", "Ks": "ks", "Ke": "ke"}
_MTL_SCALARS = {"Ns": "shininess", "Ni": "ior", "d": "opacity", "Tr": "opacity"}
# map_* options and how many values follow each (-o/-s/-t take 1 to 3).
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
                "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _map_file(args: List[str]) -> str:
    """The file name of a ``map_*`` statement, after its options."""
    k = 0
    while k < len(args) and args[k] in _MAP_OPTIONS:
        n = _MAP_OPTIONS[args[k]]
        k += 1
        if args[k - 1] in ("-o", "-s", "-t"):
            taken = 0
            while taken < n and k < len(args) - 1 and _is_number(args[k]):
                k, taken = k + 1, taken + 1
        else:
            k += n
    return " ".join(args[k:])


class _MTLParser:
    def __init__(self, file: str, base_dir: str, warned: List[str], allow_outside: bool = False) -> None:
        self.file, self.base_dir, self.warned = file, base_dir, warned
        self.allow_outside = allow_outside
        self.materials: Dict[str, Material] = {}
        self.skipped: Counter = Counter()
        self.current: Optional[Material] = None
        self.has_d = False

    def fail(self, line_no: int, message: str) -> OBJError:
        return OBJError(self.file, line_no, message)

    def set(self, line_no: int, **values) -> None:
        assert self.current is not None     # statement() checks it before apply()
        try:
            self.current = self.current.replace(**values)
        except (TypeError, ValueError) as e:
            raise self.fail(line_no, f"material {excerpt(self.current.name)}: {_short(str(e), 200)}") from None

    def numbers(self, line_no: int, keyword: str, args: List[str], counts: Tuple[int, ...], line: str):
        try:
            values = [float(a) for a in args]
        except ValueError:
            values = []
        if len(values) not in counts:
            raise self.fail(line_no, f"expected {counts[-1]} number{'s' if counts[-1] > 1 else ''} "
                                     f"after {keyword!r}, got {excerpt(line.strip())}")
        return values

    def statement(self, line_no: int, keyword: str, args: List[str], line: str) -> None:
        if keyword == "newmtl":
            name = " ".join(args)
            if not name:
                raise self.fail(line_no, f"expected a material name after 'newmtl', got {excerpt(line.strip())}")
            self.current, self.has_d = Material(name=name), False
            self.materials[name] = self.current
            return
        if keyword in _MTL_COLORS or keyword in _MTL_SCALARS or keyword == "map_Kd":
            if self.current is None:
                raise self.fail(line_no, f"expected 'newmtl' before {excerpt(keyword)}")
            if keyword in _MTL_COLORS and args and args[0] in ("spectral", "xyz"):
                self.skipped[_keyword_key(f"{keyword} {args[0]}")] += 1
                return
            self.apply(line_no, keyword, args, line)
            self.materials[self.current.name] = self.current
        else:
            self.skipped[_keyword_key(keyword)] += 1

    def apply(self, line_no: int, keyword: str, args: List[str], line: str) -> None:
        if keyword in _MTL_COLORS:
            values = self.numbers(line_no, keyword, args, (1, 3), line)
            self.set(line_no, **{_MTL_COLORS[keyword]: values * 3 if len(values) == 1 else values})
        elif keyword == "map_Kd":
            self.set(line_no, diffuse_texture=self.texture(line_no, args, line))
        else:
            if keyword == "d" and args[:1] == ["-halo"]:
                args = args[1:]
            (x,) = self.numbers(line_no, keyword, args, (1,), line)
            assert self.current is not None     # statement() checks it before apply()
            if keyword == "Ni" and x <= 0:
                self.warn(f"{self.file}:{line_no}: 'Ni {_short(args[0])}' is not an index of refraction; keeping {self.current.ior}")
            elif keyword == "Tr":
                if not self.has_d:  # d is the standard statement; Tr only when d is absent
                    self.set(line_no, opacity=1.0 - x)
            else:
                self.has_d |= keyword == "d"
                self.set(line_no, **{_MTL_SCALARS[keyword]: x})

    def texture(self, line_no: int, args: List[str], line: str) -> Optional[str]:
        name = _map_file(args)
        if not name:
            raise self.fail(line_no, f"expected a file name after 'map_Kd', got {excerpt(line.strip())}")
        assert self.current is not None     # statement() checks it before apply()
        gets_none = f"material {excerpt(self.current.name)} gets no diffuse texture"
        try:
            # Refused before anything is looked up: the same answer whether or not an outside file exists.
            path = resolve_inside(self.base_dir, name, allow_outside=self.allow_outside)
            if not os.path.isfile(path) and "\\" in name:  # written on Windows
                path = resolve_inside(self.base_dir, name.replace("\\", "/"), allow_outside=self.allow_outside)
        except PathPolicyError as e:
            self.warn(f"{self.file}:{line_no}: texture {e}; {gets_none}")
            return None
        if not os.path.isfile(path):
            self.warn(f"{self.file}:{line_no}: texture {excerpt_path(path)} not found; {gets_none}")
            return None
        return path

    def warn(self, message: str) -> None:
        self.warned.append(message)
        _warn(message)


def _parse_mtl(text: str, file: str, base_dir: str, warned: List[str], allow_outside: bool = False):
    """({name: Material}, skipped statement counts); warnings are appended to ``warned``."""
    parser = _MTLParser(file, base_dir, warned, allow_outside)
    for index, line in enumerate(_split_lines(text)):
        parts = _strip_comment(line).split()
        if parts:
            parser.statement(index + 1, parts[0], parts[1:], line)
    return parser.materials, parser.skipped
