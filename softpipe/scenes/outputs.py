"""The buffers users read beside the picture: depth, normals, ids, barycentrics, … (``render(outputs=...)``).

Nothing here is shaded. A scene is drawn into a framebuffer that keeps a
visibility record (``Framebuffer(..., record=True)``, :mod:`softpipe.pipeline.output`):
per sample, which draw, instance and source primitive last wrote the depth. Every
buffer is derived from that record afterwards, vectorized over the covered pixels
(the "visibility buffer" idea):

- the pixel's sample: the one of least depth (the first of them), so ``depth`` is
  :attr:`Framebuffer.depth`, the nearest sample's;
- barycentrics at the pixel centre, from the source triangle's clip-space corners
  (the vertex stage's, before clipping): the point of the triangle on the pixel's
  ray is Σ b_i·clip_i with b_i ∝ e_i/w_i normalized — perspective-correct, and
  relative to the mesh's own triangle even where clipping cut it;
- position, normal and uv interpolated with them from the draw's vertex attributes
  through its indices; albedo the material's kd (× the texture at that uv when the
  draw has one); linear depth −z in eye space.

docs/outputs.md gives each buffer's space, units and background; :func:`save_outputs`
writes them as ``.npy`` files with a PNG picture of each.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numba
import numpy as np

from softpipe.light.texture import texture_lod
from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES, primitive_indices
from softpipe.pipeline.framebuffer import Framebuffer, RecordedDraw, split_record
from softpipe.pipeline.transforms import normal_matrix

__all__ = ["OUTPUTS", "RenderOutputs", "check_outputs", "derive_outputs", "save_outputs", "output_picture",
           "output_files",
           "ID_PALETTE"]

#: The buffers :func:`softpipe.render` can return (``outputs=``), in this order.
OUTPUTS = ("color", "depth", "linear_depth", "position", "normal", "object_id", "triangle_id", "barycentrics",
           "uv", "albedo")

#: The colors of ids in the pictures (id k has color k mod 12); the background is black.
ID_PALETTE = np.array([
    [230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48], [145, 30, 180],
    [70, 240, 240], [240, 50, 230], [210, 245, 60], [250, 190, 212], [0, 128, 128], [170, 110, 40]], np.uint8)


def check_outputs(outputs: Union[str, Sequence[str]]) -> Tuple[str, ...]:
    """The output names asked for, checked: a sequence of names of :data:`OUTPUTS` (or one string of
    them joined by commas, as ``--outputs`` takes them), each once, in the order given.

    Raises
    ------
    ValueError
        An unknown name (naming it and the accepted names), a repeated name, or no name.
    """
    names = [n.strip() for n in outputs.split(",")] if isinstance(outputs, str) else list(outputs)
    if not names or any(not isinstance(n, str) for n in names):
        raise ValueError(f"outputs must name one or more of: {', '.join(OUTPUTS)}; got {outputs!r}")
    for n in names:
        if n not in OUTPUTS:
            raise ValueError(f"outputs: unknown output {n!r}; the outputs are {', '.join(OUTPUTS)}")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"outputs: {', '.join(repeated)} named more than once")
    return tuple(names)


class RenderOutputs(Mapping):
    """What ``softpipe.render(..., outputs=...)`` returns: the buffers by name, and the framebuffer.

    ``out["depth"]`` is a numpy array of the image's size (docs/outputs.md gives each
    buffer's space, units and background); ``out.framebuffer`` is the Framebuffer
    ``render`` returns without ``outputs`` (the same picture, byte for byte);
    ``out.names`` the buffers in the order asked for.
    """

    def __init__(self, framebuffer: Framebuffer, buffers: Dict[str, np.ndarray]):
        self.framebuffer = framebuffer
        self._buffers = dict(buffers)

    @property
    def names(self) -> Tuple[str, ...]:
        return tuple(self._buffers)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._buffers[name]
        except KeyError:
            raise KeyError(f"{name!r} was not asked for: this render has {', '.join(self._buffers)} "
                           f"(render(..., outputs=...) takes any of {', '.join(OUTPUTS)})") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._buffers)

    def __len__(self) -> int:
        return len(self._buffers)

    def __repr__(self) -> str:
        parts = ", ".join(f"{n}: {a.dtype} {list(a.shape)}" for n, a in self._buffers.items())
        return f"RenderOutputs({self.framebuffer.width}×{self.framebuffer.height}; {parts})"


# ------------------------------------------------------------------ from the record to the buffers

def _pixel_sample(fb: Framebuffer) -> Tuple[np.ndarray, np.ndarray]:
    """Each pixel's record value and depth, from its sample of least depth (the first of equals)."""
    depth, record = fb.samples_depth, fb.record
    assert record is not None                   # render made the framebuffer with record=True
    if fb.samples == 1:
        return record[0].copy(), depth[0].copy()
    pick = np.argmin(depth, axis=0)[None]
    return (np.take_along_axis(record, pick, axis=0)[0],
            np.take_along_axis(depth, pick, axis=0)[0].copy())


def _uniform_matrix(call, name: str) -> np.ndarray:
    value = getattr(call.uniforms, name, None)
    m = np.eye(4) if value is None else np.asarray(value, np.float64)
    return m if m.shape == (4, 4) else np.eye(4)


def _albedo_of(call) -> np.ndarray:
    """The draw's kd: its ``material`` uniform's, else its ``color`` uniform, else white."""
    material = getattr(call.uniforms, "material", None)
    kd = getattr(material, "kd", None)
    if kd is None:
        kd = getattr(call.uniforms, "color", (1.0, 1.0, 1.0))
    kd = np.asarray(kd, np.float64).ravel()
    return kd[:3] if kd.size >= 3 else np.ones(3)


@numba.njit(cache=True)
def _sample_texture(tex, uv, out):
    """The texture at each uv, level of detail 0 (what ``texture(uv)`` gives without derivatives)."""
    for k in range(uv.shape[0]):
        c = texture_lod(tex, (uv[k, 0], uv[k, 1]), 0.0)
        out[k, 0], out[k, 1], out[k, 2] = c[0], c[1], c[2]


def _barycentrics(clip: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Perspective-correct barycentrics [n, 3] at NDC points (x, y) of triangles with clip corners [n, 3, 4].

    The point Σ b_i·clip_i lies on the pixel's ray when Σ b_i (x_i − X·w_i) = 0 and
    Σ b_i (y_i − Y·w_i) = 0: b is the cross product of those two rows, normalized to sum 1
    (b_i ∝ e_i/w_i). NaN for a triangle seen edge-on.
    """
    r1 = clip[:, :, 0] - x[:, None] * clip[:, :, 3]
    r2 = clip[:, :, 1] - y[:, None] * clip[:, :, 3]
    b = np.cross(r1, r2)
    total = b.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total != 0, b / np.where(total != 0, total, 1.0), np.nan)


def _triangle_maps(objects: Sequence, draws: Sequence[RecordedDraw]) -> Dict[int, np.ndarray]:
    """For each recorded draw of triangles, its triangles' indices in its object's whole mesh: a mesh of
    several materials is drawn once per material (``Mesh.by_material``), each draw numbering its own."""
    maps: Dict[int, np.ndarray] = {}
    for k, obj in enumerate(objects):
        mesh = obj.mesh
        mine = [i for i, d in enumerate(draws) if d.tag == k and d.kind == "triangles"
                and d.call.topology in TRIANGLE_TOPOLOGIES]
        if getattr(mesh, "material_ids", None) is None:
            continue
        parts = [np.flatnonzero(mesh.material_ids == m) for m in range(len(mesh.materials))]
        parts = [p for p in parts if len(p)]
        for i, part in zip(mine, parts):
            maps[i] = part
    return maps


def derive_outputs(fb: Framebuffer, names: Sequence[str], objects: Sequence = ()) -> Dict[str, np.ndarray]:
    """The buffers ``names`` (:data:`OUTPUTS`) of a framebuffer drawn with a visibility record.

    Parameters
    ----------
    fb : Framebuffer
        Drawn with ``record=True``; its :attr:`~Framebuffer.recorded_draws` carry the draws'
        inputs, and their ``tag`` the index of the object each draw belongs to (a draw
        without one is object k, k its place among the frame's draws).
    names : sequence of str
        Checked by :func:`check_outputs`.
    objects : sequence of SceneObject
        The scene's drawn objects, in the order of the tags (for a mesh of several
        materials, the triangle ids count over the whole mesh).

    Returns
    -------
    dict name → array, in the order of ``names`` (docs/outputs.md).
    """
    names = check_outputs(names)
    if fb.record is None:
        raise ValueError("derive_outputs needs a framebuffer drawn with a visibility record: "
                         "Framebuffer(width, height, record=True)")
    h, w = fb.height, fb.width
    value, depth = _pixel_sample(fb)
    draws = fb.recorded_draws
    which, instance, primitive = split_record(value, draws)
    shown = which >= 0
    want = set(names)
    out: Dict[str, np.ndarray] = {}
    nan3 = np.full((h, w, 3), np.nan, np.float32)
    object_id = np.full((h, w), -1, np.int32)
    triangle_id = np.full((h, w), -1, np.int64)
    bary, position, normal, albedo = nan3.copy(), nan3.copy(), nan3.copy(), nan3.copy()
    uv = np.full((h, w, 2), np.nan, np.float32)
    linear = np.full((h, w), np.nan, np.float32)
    maps = _triangle_maps(objects, draws) if objects else {}
    geometric = want & {"barycentrics", "position", "normal", "uv", "albedo", "linear_depth"}
    # the covered pixels grouped by draw (one sort, not one pass over the image per draw)
    flat = np.flatnonzero(shown)
    flat = flat[np.argsort(which.reshape(-1)[flat], kind="stable")]
    kinds, starts = np.unique(which.reshape(-1)[flat], return_index=True)
    for k, group in zip(kinds, np.split(flat, starts[1:])):
        d = draws[int(k)]
        rows, cols = np.divmod(group, w)
        # a scene's draws name their object; a draw made by hand is its own object, by its place in the frame
        tag = int(d.tag) if isinstance(d.tag, (int, np.integer)) else int(k)
        object_id[rows, cols] = tag
        triangles = d.kind == "triangles" and d.call.topology in TRIANGLE_TOPOLOGIES
        prim = primitive[rows, cols]
        if d.call.topology in TRIANGLE_TOPOLOGIES:       # edges and corners in a polygon mode name their triangle
            triangle_id[rows, cols] = maps[int(k)][prim] if int(k) in maps else prim
        if not geometric:
            continue
        call = d.call
        kd = _albedo_of(call)
        albedo[rows, cols] = kd
        model_view = _uniform_matrix(call, "model_view")
        corners = primitive_indices(call.topology, call.indices, d.vertices_per_instance)[prim]
        inst = instance[rows, cols]
        clip = d.clip[inst[:, None] * d.vertices_per_instance + corners]      # [n, 3, 4]
        if not triangles:
            # a line or point has no surface: its eye depth from the clip w of its first corner
            linear[rows, cols] = clip[:, 0, 3]
            continue
        vp = call.viewport
        x = 2.0 * (cols + 0.5 - vp.x) / vp.width - 1.0
        y = 2.0 * (h - rows - 0.5 - vp.y) / vp.height - 1.0
        b = _barycentrics(clip, x, y)
        bary[rows, cols] = b
        p = np.asarray(call.positions, np.float64)
        p = np.concatenate([p[:, :3], np.ones((len(p), 1))], axis=1) if p.shape[1] >= 3 else \
            np.concatenate([p, np.zeros((len(p), 3 - p.shape[1])), np.ones((len(p), 1))], axis=1)
        local = np.einsum("nc,ncj->nj", b, p[corners])                       # object space, w = 1
        view = _uniform_matrix(call, "view")
        model = np.linalg.solve(view, model_view)
        eye = local @ model_view.T
        linear[rows, cols] = -eye[:, 2]
        position[rows, cols] = (local @ model.T)[:, :3]
        attributes = call.attributes or {}
        if "normal" in attributes:
            n = np.einsum("nc,ncj->nj", b, np.asarray(attributes["normal"], np.float64)[corners])
            n = n @ normal_matrix(model).T
            length = np.linalg.norm(n, axis=1, keepdims=True)
            with np.errstate(divide="ignore", invalid="ignore"):
                normal[rows, cols] = n / length
        if "uv" in attributes:
            t = np.einsum("nc,ncj->nj", b, np.asarray(attributes["uv"], np.float64)[corners])
            uv[rows, cols] = t
            texture = getattr(call.uniforms, "texture", None)
            if texture is not None and hasattr(texture, "texels") and "albedo" in want:
                sampled = np.zeros((len(t), 3))
                good = np.isfinite(t).all(axis=1)
                _sample_texture(texture, np.ascontiguousarray(t[good]), sampled[: int(good.sum())])
                albedo[rows[good], cols[good]] = kd * sampled[: int(good.sum())]
    depth = np.where(shown, depth, np.float32(1.0)).astype(np.float32)
    made = {"color": lambda: fb.color.copy(), "depth": lambda: depth, "linear_depth": lambda: linear,
            "position": lambda: position, "normal": lambda: normal, "object_id": lambda: object_id,
            "triangle_id": lambda: triangle_id, "barycentrics": lambda: bary, "uv": lambda: uv,
            "albedo": lambda: albedo}
    for n in names:
        out[n] = made[n]()
    return out


# ------------------------------------------------------------------ writing them

def _normalized(a: np.ndarray, shown: np.ndarray) -> np.ndarray:
    """``a`` over the covered pixels mapped to [0, 1] (a constant to 0.5), per last axis if it has one."""
    out = np.zeros(a.shape, np.float64)
    if not shown.any():
        return out
    v = a[shown].astype(np.float64)
    lo, hi = np.nanmin(v, axis=0), np.nanmax(v, axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    out[shown] = np.where(hi > lo, (v - lo) / span, 0.5)
    return out


def output_picture(name: str, buffer: np.ndarray, framebuffer: Optional[Framebuffer] = None) -> np.ndarray:
    """A picture of one output, 8-bit RGB [H, W, 3]; the background (no surface) black.

    ``color`` is the framebuffer's picture; ``depth`` and ``linear_depth`` gray,
    normalized over the covered pixels from white (nearest) to 20 % gray (farthest);
    ``normal`` 0.5·N + 0.5; ``object_id``, ``triangle_id`` by :data:`ID_PALETTE`;
    ``barycentrics`` and ``albedo`` as RGB (clamped to [0, 1]); ``uv`` as (u, v, 0), each
    wrapped to [0, 1); ``position`` each axis normalized over the covered pixels.
    """
    if name == "color":
        if framebuffer is not None:
            return framebuffer.to_uint8(alpha=False)
        return np.rint(np.clip(np.nan_to_num(buffer[..., :3]), 0, 1) * 255).astype(np.uint8)
    if name in ("object_id", "triangle_id"):
        shown = buffer >= 0
        ids = np.zeros(buffer.shape + (3,), np.uint8)
        ids[shown] = ID_PALETTE[buffer[shown] % len(ID_PALETTE)]
        return ids
    if name in ("depth", "linear_depth"):
        shown = np.isfinite(buffer) & ((buffer < 1.0) if name == "depth" else True)
        gray = np.where(shown, 1.0 - 0.8 * _normalized(buffer, shown), 0.0)
        return np.repeat(np.rint(gray * 255)[..., None], 3, axis=2).astype(np.uint8)
    shown = np.isfinite(buffer).all(axis=-1)
    if name == "normal":
        rgb = 0.5 * buffer + 0.5
    elif name == "position":
        rgb = _normalized(buffer, shown)
    elif name == "uv":
        rgb = np.concatenate([np.mod(buffer, 1.0), np.zeros(buffer.shape[:2] + (1,))], axis=2)
    else:
        rgb = buffer
    rgb = np.where(shown[..., None], np.clip(np.nan_to_num(rgb), 0.0, 1.0), 0.0)
    return np.rint(rgb * 255).astype(np.uint8)


def output_files(outputs: Mapping[str, np.ndarray], framebuffer: Optional[Framebuffer] = None) -> Dict[str, bytes]:
    """Each output encoded as files: ``"NAME.npy"`` (the array, ``np.save``) and ``"NAME.png"`` (its
    picture, :func:`output_picture`), in the order of ``outputs``."""
    import io

    from PIL import Image
    fb = framebuffer if framebuffer is not None else getattr(outputs, "framebuffer", None)
    files: Dict[str, bytes] = {}
    for name, buffer in outputs.items():
        npy, png = io.BytesIO(), io.BytesIO()
        np.save(npy, buffer, allow_pickle=False)
        Image.fromarray(output_picture(name, buffer, fb), "RGB").save(png, format="PNG")
        files[f"{name}.npy"], files[f"{name}.png"] = npy.getvalue(), png.getvalue()
    return files


def save_outputs(outputs: Mapping[str, np.ndarray], stem: Union[str, "os.PathLike[str]"],
                 framebuffer: Optional[Framebuffer] = None) -> List[Path]:
    """Write each output as ``STEM.NAME.npy`` and its picture (:func:`output_picture`) as ``STEM.NAME.png``.

    Each file is written whole or not at all (:func:`softpipe.core.files.atomic_write`); a missing
    folder is made. Returns the paths written, two per output, in order.
    """
    from softpipe.core.files import atomic_write_bytes
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    written: List[Path] = []
    for suffix, data in output_files(outputs, framebuffer).items():
        path = stem.with_name(f"{stem.name}.{suffix}")
        atomic_write_bytes(path, data)
        written.append(path)
    return written
