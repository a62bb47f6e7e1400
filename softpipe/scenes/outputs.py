"""The buffers users read beside the picture: depth, normals, ids, barycentrics, … (``render(outputs=...)``).

Nothing here is shaded. A scene is drawn into a framebuffer that keeps a
visibility record (``Framebuffer(..., record=True)``, :mod:`softpipe.pipeline.output`):
per sample, which draw, instance and source primitive last wrote the depth. Every
buffer is derived from that record afterwards, in one compiled pass over the pixels
(:mod:`softpipe.scenes.derive`; the "visibility buffer" idea):

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

import numpy as np

from softpipe.pipeline.assembly import TRIANGLE_TOPOLOGIES
from softpipe.pipeline.framebuffer import Framebuffer, RecordedDraw
from softpipe.scenes.derive import check_out_array, derive_buffers

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


def derive_outputs(fb: Framebuffer, names: Sequence[str], objects: Sequence = (),
                   copy_color: bool = True, out: Optional[Mapping[str, np.ndarray]] = None) -> Dict[str, np.ndarray]:
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
    copy_color : bool
        Whether ``color`` is a copy of the framebuffer's color (the default: a framebuffer
        cleared and drawn into again must not change the buffers already returned). False
        hands out :attr:`Framebuffer.color` itself, for a caller that draws into ``fb`` no
        more (``render`` makes a new framebuffer per call). With several samples per pixel
        ``color`` is the resolve, a new array either way.
    out : dict name → array, optional
        Arrays to write buffers into instead of new ones, as numpy's ``out=`` (a caller deriving
        frame after frame passes the last frame's: new arrays are fresh memory, which the system
        zeroes page by page, 1.1 ms of a 3.3 ms derive at 1024²). Each must have its buffer's shape
        and dtype, be C-contiguous and writeable; every pixel is written. ``out["color"]`` gets a copy
        of the color (nothing to do if it is the framebuffer's own). Names not asked for are ignored.

    Returns
    -------
    dict name → array, in the order of ``names`` (docs/outputs.md); those in ``out`` are its arrays.

    Raises
    ------
    ValueError
        No visibility record; an array of ``out`` of the wrong shape or dtype (naming it and what
        its buffer is); and what :func:`~softpipe.scenes.derive.derive_buffers` raises.
    """
    names = check_outputs(names)
    out = dict(out or {})
    if not fb.has_record and any(n != "color" for n in names):
        raise ValueError("derive_outputs needs a framebuffer drawn with a visibility record: "
                         "Framebuffer(width, height, record=True)")
    maps = _triangle_maps(objects, fb.recorded_draws) if objects else {}
    buffers = derive_buffers(fb, [n for n in names if n != "color"], maps, out)
    if "color" in names:
        # one sample: fb.color is the framebuffer's own buffer; several: a new resolved array, not copied again
        color = fb.color
        if "color" in out:
            given = check_out_array(out, "color", color.shape, color.dtype)
            if given is not color:
                np.copyto(given, color)
            color = given
        elif copy_color and fb.samples == 1:
            color = color.copy()
        buffers["color"] = color
    return {n: buffers[n] for n in names}


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
