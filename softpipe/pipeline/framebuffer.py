"""The framebuffer: float RGBA color, float depth and an 8-bit stencil, per sample; more color
attachments if asked for (multiple render targets, GL's ``layout(location = k) out``).

Row 0 is the top of the image, as pillow and numpy expect; the rasterizer
flipped y once when it emitted the fragments. Colors are linear floats and
unclamped until they become 8 bits in :meth:`Framebuffer.to_uint8`, the one
place that conversion happens: ``round(clamp(c, 0, 1)·255)``, rounding half to
even, after the sRGB encode (FORMULAS §28) in an sRGB framebuffer (``srgb=True``).

Color attachments (``Framebuffer(w, h, attachments={"color": "rgba8", "normal": "rgba32f",
"id": "r32i"})``): named, in order (the k-th is location k, the k-th value a fragment
shader returns), each of a format of :data:`ATTACHMENT_FORMATS`. Location 0 is the
framebuffer's color (:attr:`Framebuffer.samples_color`, the picture it shows); the
others are arrays of their own (:meth:`Framebuffer.attachment`). The default is one
attachment, ``{"color": "rgba8"}``: today's framebuffer, byte for byte. docs/06-output.md.
"""
from __future__ import annotations

import io
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numba
import numpy as np

from softpipe.core.colors import rgba, srgb_encode
from softpipe.core.parallel import in_bands
from softpipe.core.runtime import check_memory
from softpipe.pipeline.sampling import CENTER, SamplePattern

__all__ = ["Framebuffer", "MAX_DIMENSION", "MAX_TOTAL_SAMPLES", "image_format", "RecordedDraw", "split_record", "RECORD_MAX",
           "ATTACHMENT_FORMATS", "DEFAULT_ATTACHMENTS"]

#: Largest width or height, in pixels.
MAX_DIMENSION = 16384
#: Largest width × height × samples (about 1.3 GB of color and depth).
MAX_TOTAL_SAMPLES = 1 << 26
#: A color attachment's formats (GL's internal formats, lower case, without ``GL_``), the names
#: ``attachments=`` takes (``sp.ATTACHMENT_FORMATS``). ``rgba8`` is stored as float32, unclamped, as
#: the framebuffer's color always was, and becomes bytes where it is read as a picture
#: (:meth:`Framebuffer.to_uint8`, with the sRGB encode in an sRGB framebuffer); ``rgba32f`` and
#: ``r32f`` are floats to read as numbers; ``r32i`` a 32-bit signed integer per sample
#: (not blended, and resolved by taking sample 0, as GL treats integer targets).
ATTACHMENT_FORMATS: Tuple[str, ...] = ("rgba8", "rgba32f", "r32f", "r32i")
# each format's storage: (channels, numpy dtype), in the order of ATTACHMENT_FORMATS
_STORAGE = dict(zip(ATTACHMENT_FORMATS, ((4, np.float32), (4, np.float32), (1, np.float32), (1, np.int32))))
#: The most primitives (over their instances) the draws of one frame can name in a visibility record:
#: its values are int32 (half the bytes of int64 to clear, write and read at every sample).
RECORD_MAX = int(np.iinfo(np.int32).max)
#: The default framebuffer's one attachment.
DEFAULT_ATTACHMENTS = {"color": "rgba8"}


@numba.njit(cache=True, nogil=True)
def _fill(lo, hi, color, rgba, depth, z, stencil, s):
    """Clear samples lo:hi (run in parallel bands: numpy's fill is single-threaded, a 1080p clear is worth sharing)."""
    for k in range(lo, hi):
        depth[k] = z
        stencil[k] = s
        for c in range(4):
            color[k, c] = rgba[c]


@dataclass
class RecordedDraw:
    """One draw of a frame whose primitives may enter the framebuffer's visibility record.

    The record stores, per sample, ``base + i·per_instance + p`` for primitive ``p`` of
    instance ``i`` of this draw (:func:`split_record` takes it apart), so one int32 names
    the draw, the instance and the source primitive at once.

    Attributes
    ----------
    base : int
        The first record value of this draw (the draws of a frame take consecutive ranges).
    count : int
        How many values it took: its input primitives, over every instance.
    per_instance : int
        Input primitives per instance (``count`` without instancing).
    call : DrawCall
        The draw itself: its positions, indices, topology, attributes and uniforms, as given.
    clip : float64 [V, 4]
        The vertex stage's clip coordinates (every instance's vertices, instance by instance).
    vertices_per_instance : int
        Rows of ``clip`` per instance.
    kind : "triangles" | "lines" | "points"
        What its primitives were.
    tag : object
        Free for the caller (a scene names the object the draw belongs to).
    corners : int64 [per_instance, 3] or None
        The vertex indices of each primitive of one instance, as drawn (assembly's
        :func:`~softpipe.pipeline.assembly.primitive_indices`, not the draw's indices read again:
        the draw owns them); None where the draw did not give them.
    """

    base: int
    count: int
    per_instance: int
    call: Any
    clip: np.ndarray
    vertices_per_instance: int
    kind: str
    tag: Any = None
    corners: Optional[np.ndarray] = None


@numba.njit(cache=True, nogil=True)
def _store_visible(lo, hi, vis, touched, tile_w, tile_h, ids, record):
    """record[s, row, i] = ids[vis[s, row, i]] where vis names a primitive (≥ 0), for the image rows lo:hi,
    in the touched tiles (tile row 0 at the bottom): a fast-path draw's record write
    (:meth:`Framebuffer.defer_visible`)."""
    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]
    for row in range(lo, hi):
        tile_y = (height - 1 - row) // tile_h
        for tile_x in range(touched.shape[1]):
            if not touched[tile_y, tile_x]:
                continue
            for s in range(samples):
                for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):
                    v = vis[s, row, i]
                    if v >= 0:
                        record[s, row, i] = ids[v]


def split_record(record: np.ndarray, draws: Sequence[RecordedDraw]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Take record values apart: (draw index in ``draws``, instance, primitive), each int64 of
    ``record``'s shape, −1 in all three where the record is −1 (nothing written)."""
    record = np.asarray(record, dtype=np.int64)
    shown = record >= 0
    draw = np.full(record.shape, -1, np.int64)
    instance, primitive = draw.copy(), draw.copy()
    if not draws or not shown.any():
        return draw, instance, primitive
    bases = np.array([d.base for d in draws], np.int64)
    per = np.array([max(d.per_instance, 1) for d in draws], np.int64)
    v = record[shown]
    k = np.searchsorted(bases, v, side="right") - 1
    local = v - bases[k]
    draw[shown] = k
    instance[shown], primitive[shown] = np.divmod(local, per[k])
    return draw, instance, primitive


def _check_size(width, height, samples: int) -> None:
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"Framebuffer {name} must be an integer, got {type(v).__name__} {v!r}")
        if v <= 0:
            raise ValueError(f"Framebuffer {name} must be at least 1, got {v}")
        if v > MAX_DIMENSION:
            raise ValueError(f"Framebuffer {name} {v} exceeds the limit MAX_DIMENSION = {MAX_DIMENSION}")
    width, height, samples = int(width), int(height), int(samples)   # no numpy int overflow in the product
    if width * height * samples > MAX_TOTAL_SAMPLES:
        raise ValueError(f"Framebuffer {width}×{height}×{samples} samples = {width * height * samples} exceeds "
                         f"the limit MAX_TOTAL_SAMPLES = {MAX_TOTAL_SAMPLES}")


def image_format(name: Optional[str], format: Optional[str] = None) -> str:
    """The pillow format that writes ``name`` (by its extension) or ``format`` (a name or extension).

    A ValueError names an extension or format pillow cannot write, or says that
    neither was given (a file object with no name needs ``format=``).
    """
    from PIL import Image

    Image.init()
    extensions = Image.registered_extensions()
    if format is not None:
        if not isinstance(format, str):
            raise TypeError(f"format must be a string such as 'png', got {type(format).__name__}")
        key = format.strip().lower()
        fmt = extensions.get(key if key.startswith(".") else "." + key)
        if fmt is None and format.strip().upper() in Image.SAVE:
            fmt = format.strip().upper()
        if fmt is None or fmt not in Image.SAVE:
            raise ValueError(f"cannot write images in format {format!r}; use png, jpeg, bmp, tiff, webp, ...")
        return fmt
    if name is None:
        raise ValueError("saving to a file object needs format=, e.g. fb.save(f, format='png')")
    ext = Path(name).suffix.lower()
    if not ext:
        raise ValueError(f"{name}: no extension to tell the image format; name it .png, .jpg, ... or give format=")
    fmt = extensions.get(ext)
    if fmt is None or fmt not in Image.SAVE:
        raise ValueError(f"{name}: cannot write images with extension {ext!r}; use .png, .jpg, .bmp, .tif, ...")
    return fmt


def _check_attachments(attachments) -> Tuple[Tuple[str, str], ...]:
    """The attachments as ((name, format), ...) in location order, checked (a ValueError or TypeError
    names the one that is wrong)."""
    if attachments is None:
        return tuple(DEFAULT_ATTACHMENTS.items())
    if not isinstance(attachments, Mapping):
        raise TypeError(f"Framebuffer attachments must be a dict of name → format, e.g. {{'color': 'rgba8', "
                        f"'normal': 'rgba32f'}}, got {type(attachments).__name__}")
    if not attachments:
        raise ValueError("Framebuffer attachments is empty: give at least one, e.g. {'color': 'rgba8'}")
    if len(attachments) > MAX_ATTACHMENTS:
        raise ValueError(f"Framebuffer attachments: {len(attachments)} given, at most MAX_ATTACHMENTS = "
                         f"{MAX_ATTACHMENTS} (GL's GL_MAX_DRAW_BUFFERS)")
    out = []
    for name, fmt in attachments.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"Framebuffer attachment name {name!r} must be a Python identifier, such as 'normal'")
        if not isinstance(fmt, str) or fmt not in ATTACHMENT_FORMATS:
            raise ValueError(f"Framebuffer attachment {name!r}: format must be one of {ATTACHMENT_FORMATS}, "
                             f"got {fmt!r}")
        out.append((name, fmt))
    name, fmt = out[0]
    if _STORAGE[fmt][0] != 4:
        raise ValueError(f"Framebuffer attachment {name!r} ({fmt}) is location 0, the framebuffer's color (the "
                         f"picture it shows and saves): it must be 'rgba8' or 'rgba32f'; put a color attachment first")
    return tuple(out)


#: Most color attachments a framebuffer takes (GL guarantees 8 draw buffers).
MAX_ATTACHMENTS = 8


class Framebuffer:
    """Color (RGBA float32), depth (float32) and stencil (uint8) buffers, one value per sample.

    Parameters
    ----------
    width, height : int
        Size in pixels (limits: :data:`MAX_DIMENSION`, :data:`MAX_TOTAL_SAMPLES`).
    pattern : SamplePattern
        Where the samples of a pixel are; one centre sample by default.
    srgb : bool
        An sRGB framebuffer (GL_FRAMEBUFFER_SRGB with an sRGB color format): the colors
        are still linear floats, shaded and blended in linear light; :meth:`to_uint8`
        encodes R, G and B by sRGB's transfer function (FORMULAS §28) before they
        become bytes, and leaves alpha as it is, as GL does. Default False: the floats
        are written as bytes unencoded (softpipe's behaviour before, byte for byte).
        GL stores an sRGB framebuffer as 8-bit encoded values and decodes the
        destination before it blends; softpipe keeps the floats, so its bytes are GL's
        except where GL would have rounded the destination to 8 bits between two
        blended draws (docs/gamma.md).
    record : bool
        Keep a visibility record (docs/outputs.md): per sample, which draw, instance and
        source primitive last wrote its depth (int64, −1 where none did), with the frame's
        :attr:`recorded_draws`, cleared with the frame. Default False: no record, no cost.
    attachments : dict name → format, optional
        The color attachments in location order (multiple render targets), each of a format
        of :data:`ATTACHMENT_FORMATS`: ``{"color": "rgba8", "normal": "rgba32f", "id":
        "r32i"}``. Location 0 must be ``rgba8`` or ``rgba32f``: it is :attr:`color`. A
        fragment shader drawing into a framebuffer of several returns one value per
        attachment (docs/shaders.md). Default: ``{"color": "rgba8"}``, one attachment.

    Attributes
    ----------
    color : float32 [H, W, 4]
        For one sample per pixel, the color buffer itself (writable).
    depth : float32 [H, W]
        For one sample per pixel, the depth buffer itself.
    stencil : uint8 [H, W]
        The stencil buffer of sample 0 (the buffer itself for one sample per pixel).
    samples_color : float32 [S, H, W, 4], samples_depth : float32 [S, H, W], samples_stencil : uint8 [S, H, W]
        Every sample: one image plane per sample, so that a row of one sample is
        contiguous in memory (what the rasterizer's inner loop walks along).
    srgb : bool
        Whether :meth:`to_uint8` encodes (read-only).
    record : int32 [S, H, W] or None
        The visibility record (with ``record=True``): ``split_record(fb.record,
        fb.recorded_draws)`` names the draw, instance and primitive at each sample.
    recorded_draws : list of RecordedDraw
        The draws since the last :meth:`clear` (with ``record=True``).
    width, height, pattern, samples, samples_color, samples_depth, samples_stencil, srgb
        Read-only: assigning them raises AttributeError, because the kernels index the
        arrays without bounds checks. The arrays are written in place
        (``fb.samples_color[...] = c``); each read hands out a checked view of them.

    A new framebuffer is cleared to opaque black, (0, 0, 0, 1), depth 1.0 and stencil 0.

    As a picture: ``np.asarray(fb)`` is 8-bit RGB [H, W, 3] (:meth:`__array__` says
    why), so ``PIL.Image.fromarray(np.asarray(fb))``, ``plt.imshow(fb)`` and
    ``imageio.imwrite("x.png", fb)`` take it as it is; :meth:`save` writes any format
    pillow knows to a path or a binary file; in Jupyter ``fb`` shows the picture.

    Threads may share a framebuffer: the draws into it (and :meth:`clear`) take its
    lock, :attr:`lock`, one at a time, so the bytes are those of the same draws made one
    after another. Flagging one of its arrays read-only (``fb.color.flags.writeable =
    False``) freezes it: a draw or a clear then raises ValueError instead of writing.
    """

    def __init__(self, width: int, height: int, pattern: SamplePattern = CENTER, srgb: bool = False,
                 record: bool = False, attachments: Optional[Mapping[str, str]] = None):
        if not isinstance(pattern, SamplePattern):
            raise TypeError(f"pattern must be a SamplePattern, got {type(pattern).__name__}")
        if not isinstance(srgb, (bool, np.bool_)):
            raise TypeError(f"Framebuffer srgb must be True or False, got {type(srgb).__name__} {srgb!r}")
        if not isinstance(record, (bool, np.bool_)):
            raise TypeError(f"Framebuffer record must be True or False, got {type(record).__name__} {record!r}")
        _check_size(width, height, len(pattern))
        formats = _check_attachments(attachments)
        s = len(pattern)
        per_sample = 25 if record else 21
        per_sample += sum(4 * _STORAGE[f][0] for _, f in formats[1:])
        check_memory(f"a {int(width)}×{int(height)} framebuffer with {s} sample(s) per pixel ({per_sample} bytes "
                     "a sample)", int(width) * int(height) * s * per_sample)
        object.__setattr__(self, "_width", int(width))
        object.__setattr__(self, "_height", int(height))
        object.__setattr__(self, "_pattern", pattern)
        object.__setattr__(self, "_srgb", bool(srgb))
        object.__setattr__(self, "_count", s)
        object.__setattr__(self, "_samples_color", np.empty((s, self._height, self._width, 4), dtype=np.float32))
        object.__setattr__(self, "_samples_depth", np.empty((s, self._height, self._width), dtype=np.float32))
        object.__setattr__(self, "_samples_stencil", np.empty((s, self._height, self._width), dtype=np.uint8))
        object.__setattr__(self, "_record", np.empty((s, self._height, self._width), dtype=np.int32)
                           if record else None)
        object.__setattr__(self, "_recorded_draws", [])
        # the record's lazy parts (:meth:`defer_visible`): the last fast-path draw's visible samples, not yet
        # stored; whether the array is known to hold −1 everywhere; whether it was ever handed out
        object.__setattr__(self, "_pending", None)
        object.__setattr__(self, "_record_clean", False)
        object.__setattr__(self, "_record_shared", False)
        object.__setattr__(self, "_formats", formats)
        object.__setattr__(self, "_extra", {name: np.empty((s, self._height, self._width)
                                                           + ((4,) if _STORAGE[f][0] == 4 else ()),
                                                           dtype=_STORAGE[f][1])
                                            for name, f in formats[1:]})
        object.__setattr__(self, "_views", {})
        object.__setattr__(self, "_lock", threading.RLock())
        object.__setattr__(self, "_writes", 0)
        self.clear()

    # The size, the pattern and the two arrays are read-only: the kernels write into the
    # arrays by index without bounds checks, trusting that they are [S, H, W(, 4)] float32,
    # C-contiguous, with S, H, W those of the pattern, height and width. Every read of
    # ``samples_color`` / ``samples_depth`` checks that the framebuffer's own array still is
    # so and hands out a view of it: writing into it (``fb.samples_color[...] = c``)
    # changes the framebuffer, while changing the view's shape, dtype or strides does not.
    # The view is kept and handed out again while it is intact, so that a flag set on it
    # (``fb.color.flags.writeable = False``, even on the view of one expression) stays
    # and the draws can honour it (:meth:`check_drawable`).

    _READ_ONLY = ("width", "height", "pattern", "samples", "samples_color", "samples_depth", "samples_stencil",
                  "lock", "writes", "srgb", "record", "recorded_draws", "attachments")
    # set once, by __init__ (through object.__setattr__)
    _width: int
    _height: int
    _pattern: SamplePattern
    _srgb: bool
    _count: int
    _samples_color: np.ndarray
    _samples_depth: np.ndarray
    _samples_stencil: np.ndarray
    _record: Optional[np.ndarray]
    _recorded_draws: List[RecordedDraw]
    _pending: Optional[Tuple[np.ndarray, np.ndarray, int, int, np.ndarray]]
    _record_clean: bool
    _record_shared: bool
    _lock: threading.RLock
    _writes: int
    _views: dict
    _formats: Tuple[Tuple[str, str], ...]
    _extra: Dict[str, np.ndarray]

    def __setattr__(self, name, value):
        if name in self._READ_ONLY or name.startswith("_"):
            raise AttributeError(f"Framebuffer.{name} is read-only: the kernels rely on the size, sample pattern "
                                 f"and arrays the framebuffer was made with; make a new Framebuffer("
                                 f"width, height, pattern) instead, or write into the arrays in place "
                                 f"(fb.samples_color[...] = ...)")
        object.__setattr__(self, name, value)

    def __delattr__(self, name):
        raise AttributeError(f"Framebuffer.{name} cannot be deleted")

    @property
    def width(self) -> int:
        """Width in pixels (read-only)."""
        return self._width

    @property
    def height(self) -> int:
        """Height in pixels (read-only)."""
        return self._height

    @property
    def pattern(self) -> SamplePattern:
        """The sample pattern (read-only), checked to still have :attr:`samples` int64 offsets."""
        p, s = self._pattern, self._count
        offsets, positions = getattr(p, "offsets", None), getattr(p, "positions", None)
        if not (isinstance(offsets, np.ndarray) and offsets.shape == (s, 2) and offsets.dtype == np.int64
                and offsets.flags.c_contiguous and isinstance(positions, np.ndarray) and positions.shape == (s, 2)
                and positions.dtype == np.float64 and positions.flags.c_contiguous):
            raise RuntimeError(f"this framebuffer's sample pattern was changed after it was made (it had {s} "
                               "sample(s)); the kernels cannot draw into it safely")
        return p

    @property
    def srgb(self) -> bool:
        """Whether this is an sRGB framebuffer: :meth:`to_uint8` encodes RGB (FORMULAS §28) (read-only)."""
        return self._srgb

    @property
    def samples(self) -> int:
        """Samples per pixel (read-only)."""
        return self._count

    @property
    def samples_color(self) -> np.ndarray:
        """float32 [S, H, W, 4], C-contiguous: every sample's color (a view: write into it in place)."""
        return self._view("samples_color")

    @property
    def samples_depth(self) -> np.ndarray:
        """float32 [S, H, W], C-contiguous: every sample's depth (a view: write into it in place)."""
        return self._view("samples_depth")

    @property
    def samples_stencil(self) -> np.ndarray:
        """uint8 [S, H, W], C-contiguous: every sample's stencil value (a view: write into it in place)."""
        return self._view("samples_stencil")

    @property
    def stencil(self) -> np.ndarray:
        """uint8 [H, W]: the stencil of sample 0 (the buffer itself, writable in place)."""
        return self._view("stencil")

    @property
    def record(self) -> Optional[np.ndarray]:
        """int32 [S, H, W] or None: the visibility record (``Framebuffer(..., record=True)``), −1 where no
        draw wrote the depth since the last clear; :func:`split_record` takes its values apart.

        The array itself, complete: the last fast-path draw's samples are stored first if they were
        not yet (:meth:`defer_visible`)."""
        with self._lock:
            self._store_pending()
            if self._record is not None:
                object.__setattr__(self, "_record_shared", True)   # it may be written from outside from now on
                object.__setattr__(self, "_record_clean", False)
            return self._record

    @property
    def has_record(self) -> bool:
        """Whether the framebuffer keeps a visibility record (``record=True``), without reading it."""
        return self._record is not None

    def record_parts(self) -> Tuple[Optional[np.ndarray], bool,
                                    Optional[Tuple[np.ndarray, np.ndarray, int, int, np.ndarray]]]:
        """The record as it is stored, whether it is known to hold −1 everywhere (nothing stored since a
        clear, and never handed out), and the samples of the last fast-path draw not yet stored in it:
        ``(record, blank, None)``, or ``(record, blank, (vis, touched, tile_w, tile_h, ids))`` as
        :meth:`defer_visible` took them. For a reader that takes that draw's samples itself rather than
        have them stored first (:mod:`softpipe.scenes.derive`): where ``touched[tile]`` and ``vis ≥ 0``
        the record value is ``ids[vis]``, elsewhere ``record``'s (−1 if ``blank``)."""
        return self._record, bool(self._record_clean), self._pending

    def defer_visible(self, vis: np.ndarray, touched: np.ndarray, tile_w: int, tile_h: int,
                      ids: np.ndarray) -> None:
        """A fast-path draw's record write, made when the record is next read or written.

        At every sample where ``vis`` (int32 [S, H, W], a row of the draw's primitives or −1; set only in
        the tiles ``touched`` [tiles_y, tiles_x] of ``tile_w`` × ``tile_h`` pixels, tile row 0 at the
        bottom) names a primitive, the record's value is ``ids[vis]`` (int32). Stored when the next
        draw is recorded (:meth:`add_recorded_draw`), when :attr:`record` hands the array out, or
        never: a clear forgets them. A frame of one draw read only by the derived buffers
        (:meth:`record_parts`) never stores them."""
        with self._lock:
            self._store_pending()
            object.__setattr__(self, "_pending", (vis, touched, int(tile_w), int(tile_h), ids))

    def _store_pending(self) -> None:
        """Store the deferred draw's samples in the record (:meth:`defer_visible`)."""
        pending = self._pending
        if pending is None:
            return
        vis, touched, tile_w, tile_h, ids = pending
        object.__setattr__(self, "_pending", None)
        object.__setattr__(self, "_record_clean", False)
        in_bands(_store_visible, vis.shape[1], vis, touched, tile_w, tile_h, ids, self._record, grain=tile_h)

    @property
    def recorded_draws(self) -> List[RecordedDraw]:
        """The draws made into this framebuffer since the last :meth:`clear`, in order (with a record)."""
        return self._recorded_draws

    @property
    def attachments(self) -> Dict[str, str]:
        """The color attachments, name → format, in location order (a new dict: read-only)."""
        return dict(self._formats)

    def _attachment_array(self, name: str) -> np.ndarray:
        """The storage of attachment ``name`` (all samples), checked as the kernels need it."""
        if not isinstance(name, str) or name not in dict(self._formats):
            raise KeyError(f"this framebuffer has no attachment {name!r}; its attachments are "
                           f"{[n for n, _ in self._formats]}")
        if name == self._formats[0][0]:
            return self._view("samples_color")
        a, fmt = self._extra[name], dict(self._formats)[name]
        channels, dtype = _STORAGE[fmt]
        shape = (self._count, self._height, self._width) + ((4,) if channels == 4 else ())
        if not (a.shape == shape and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable):
            raise RuntimeError(f"Framebuffer attachment {name!r} was changed in place; the kernels cannot draw "
                               "into it safely")
        return a

    def samples_attachment(self, name: str) -> np.ndarray:
        """Every sample of attachment ``name``: [S, H, W, 4] float32 (``rgba8``, ``rgba32f``), [S, H, W]
        float32 (``r32f``) or int32 (``r32i``); a view, to write into in place. Location 0's is
        :attr:`samples_color`. A KeyError names the attachments there are."""
        return self._attachment_array(name)[...]

    def attachment(self, name: str) -> np.ndarray:
        """Attachment ``name`` resolved to one value per pixel: [H, W, 4] or [H, W].

        With one sample per pixel, the buffer itself (writable in place). With several, GL's
        multisample resolve per format: a float format (``rgba8``, ``rgba32f``, ``r32f``) is
        the average of the pixel's samples (as :attr:`color`); an integer one (``r32i``) is
        not averaged: it takes sample 0 (GL takes a single sample of an integer target).
        """
        a = self._attachment_array(name)
        if self._count == 1:
            return a[0]
        if a.dtype.kind == "i":
            return a[0].copy()
        return a.mean(axis=0, dtype=np.float64).astype(np.float32)

    def add_recorded_draw(self, call: Any, clip: np.ndarray, vertices_per_instance: int, count: int,
                          per_instance: int, kind: str, corners: Optional[np.ndarray] = None) -> RecordedDraw:
        """Note a draw about to write (the caller holds :attr:`lock`); its values start after the last draw's.
        ``corners`` as :class:`RecordedDraw` keeps them (the caller's to own: they are not copied)."""
        self._store_pending()                    # (the last draw's samples, before this draw's visibility pass)
        last = self._recorded_draws[-1] if self._recorded_draws else None
        base = 0 if last is None else last.base + max(last.count, 1)
        if base + int(count) > RECORD_MAX:
            raise ValueError(f"the visibility record holds int32 values, at most {RECORD_MAX:,}: this draw's "
                             f"{int(count):,} primitives (over its instances) after the {base:,} of the frame's "
                             "earlier draws do not fit; clear the framebuffer, or draw with a framebuffer "
                             "without record=True")
        entry = RecordedDraw(base, int(count), int(per_instance), call, clip, int(vertices_per_instance), kind,
                             corners=corners)
        self._recorded_draws.append(entry)
        return entry

    @property
    def lock(self) -> threading.RLock:
        """The lock every draw into this framebuffer (and :meth:`clear`) holds while it writes.

        Draws from several threads into one framebuffer take turns whole: hold it
        (``with fb.lock:``) to read the arrays while other threads draw.
        """
        return self._lock

    @property
    def writes(self) -> int:
        """How many draws and clears have written into this framebuffer (a trace tells by it whether
        the framebuffer changed after its draw)."""
        return self._writes

    def count_write(self) -> None:
        """Count a draw or clear about to write (:attr:`writes`); the caller holds :attr:`lock`."""
        object.__setattr__(self, "_writes", self._writes + 1)

    # the views handed out: name → (the array viewed, index into it)
    _VIEWS = {"samples_color": ("_samples_color", ()), "samples_depth": ("_samples_depth", ()),
              "samples_stencil": ("_samples_stencil", ()), "color": ("_samples_color", (0,)),
              "depth": ("_samples_depth", (0,)), "stencil": ("_samples_stencil", (0,))}
    _DTYPES = {"_samples_color": np.float32, "_samples_depth": np.float32, "_samples_stencil": np.uint8}

    def _view(self, name: str) -> np.ndarray:
        """The kept view ``name`` of the framebuffer's array, or a new one if it was reshaped or retyped."""
        owner, index = self._VIEWS[name]
        a = getattr(self, owner)
        shape = (self._count, self._height, self._width) + ((4,) if owner == "_samples_color" else ())
        dtype = self._DTYPES[owner]
        if not (a.shape == shape and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable):
            raise RuntimeError(f"Framebuffer.{owner[1:]} was changed in place (it is {a.dtype} {list(a.shape)}, "
                               f"{'' if a.flags.c_contiguous else 'not '}C-contiguous"
                               f"{'' if a.flags.writeable else ', read-only'}, not {np.dtype(dtype)} {list(shape)}); "
                               "the kernels cannot draw into it safely")
        want = a[index]
        v = self._views.get(name)
        if not (v is not None and v.shape == want.shape and v.dtype == want.dtype and v.strides == want.strides
                and v.ctypes.data == want.ctypes.data):
            v = self._views[name] = want
        return v

    def check_drawable(self) -> None:
        """Refuse (ValueError) to write into a framebuffer one of whose arrays was flagged read-only."""
        for name in self._VIEWS:
            v = self._views.get(name)
            if v is not None and not v.flags.writeable and v is self._view(name):
                raise ValueError(f"Framebuffer.{name} is read-only (flags.writeable is False): softpipe will not "
                                 f"draw into it; set fb.{name}.flags.writeable = True to draw, or draw into "
                                 f"another Framebuffer")

    def __getstate__(self) -> dict:
        """For pickling: the size, pattern and arrays (not the lock, the kept views or the recorded draws,
        which hold the draws' shaders)."""
        with self._lock:
            self._store_pending()
        return {k: v for k, v in self.__dict__.items() if k not in ("_lock", "_views", "_recorded_draws")}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        object.__setattr__(self, "_views", {})
        object.__setattr__(self, "_lock", threading.RLock())
        self.__dict__.setdefault("_writes", 0)
        if "_samples_stencil" not in self.__dict__:       # pickled before the stencil buffer existed
            object.__setattr__(self, "_samples_stencil", np.zeros(self._samples_depth.shape, np.uint8))
        self.__dict__.setdefault("_srgb", False)       # pickled before framebuffers had srgb
        self.__dict__.setdefault("_record", None)      # pickled before framebuffers kept a record
        self.__dict__.setdefault("_pending", None)
        self.__dict__.setdefault("_record_clean", False)
        self.__dict__.setdefault("_record_shared", False)
        self.__dict__.setdefault("_formats", tuple(DEFAULT_ATTACHMENTS.items()))   # before attachments
        self.__dict__.setdefault("_extra", {})
        object.__setattr__(self, "_recorded_draws", [])

    def clear(self, color: Union[str, Sequence[float]] = (0.0, 0.0, 0.0, 1.0), depth: float = 1.0,
              stencil: int = 0, attachments: Optional[Mapping[str, Any]] = None) -> "Framebuffer":
        """Set every sample to ``color``, ``depth`` and ``stencil``; returns the framebuffer.

        ``color`` is anything :func:`softpipe.core.colors.parse_color` reads: 3 or 4 numbers
        (RGB or RGBA, linear, unclamped), a CSS name (``"red"``), hex (``"#ff8000"``) or
        ``"rgb(255, 128, 0)"``. Alpha is 1 when not given. A visibility record (``record=True``)
        is set to −1 and its :attr:`recorded_draws` forgotten.

        ``attachments`` (a framebuffer with several, GL's ``glClearBuffer*``): name → clear value
        of an attachment other than location 0 (whose value is ``color``): a color as ``color``
        for ``rgba8`` and ``rgba32f``, a finite number for ``r32f``, an int32 for ``r32i``. Those
        not named are cleared to 0 ((0, 0, 0, 0) for the RGBA formats).
        """
        extra = self._clear_values(attachments)
        try:
            c = np.asarray(rgba(color), dtype=np.float32)
        except (TypeError, ValueError) as e:
            if isinstance(color, str):
                raise ValueError(f"clear color: {e}") from None
            c = np.full(4, np.nan, np.float32)
        if not np.all(np.isfinite(c)):
            raise ValueError(f"clear color must be 3 or 4 finite numbers, a color name or '#rrggbb', got {color!r}")
        if not 0.0 <= float(depth) <= 1.0:
            raise ValueError(f"clear depth must be in [0, 1], got {depth!r}")
        if isinstance(stencil, (bool, np.bool_)) or not isinstance(stencil, (int, np.integer)):
            raise TypeError(f"clear stencil must be an integer in [0, 255], got {stencil!r}")
        if not 0 <= int(stencil) <= 255:
            raise ValueError(f"clear stencil must be in [0, 255] (8 bits), got {stencil!r}")
        with self._lock:
            self.check_drawable()
            self.count_write()
            in_bands(_fill, self.samples_depth.size, self.samples_color.reshape(-1, 4), c,
                     self.samples_depth.reshape(-1), np.float32(depth), self.samples_stencil.reshape(-1),
                     np.uint8(stencil), grain=65536)
            if self._record is not None:
                object.__setattr__(self, "_pending", None)          # a deferred draw's samples: forgotten
                if self._record_shared or not self._record_clean:
                    # −1 is every bit set: filled as bytes, numpy hands it to memset, which writes a buffer this
                    # large without reading it first (twice as fast as an int64 fill: 0.065 ms at 1024² against
                    # 0.13). Not when nothing was stored since the last fill and the array was never handed out.
                    self._record.view(np.uint8).fill(255)
                    object.__setattr__(self, "_record_clean", True)
                self._recorded_draws.clear()
            for name, value in extra.items():
                self._attachment_array(name)[...] = value
        return self

    def _clear_values(self, attachments: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
        """Each attachment but location 0's clear value, checked (a ValueError names the attachment)."""
        if attachments is not None and not isinstance(attachments, Mapping):
            raise TypeError(f"clear attachments must be a dict of attachment name → value, got "
                            f"{type(attachments).__name__}")
        given = dict(attachments or {})
        formats = dict(self._formats)
        for name in given:
            if name not in formats:
                raise ValueError(f"clear attachments names {name!r}, but the framebuffer's attachments are "
                                 f"{list(formats)}")
            if name == self._formats[0][0]:
                raise ValueError(f"clear attachments names {name!r}, location 0, whose clear value is color=")
        out: Dict[str, Any] = {}
        for name, fmt in self._formats[1:]:
            value = given.get(name, 0)
            if fmt == "r32i":
                if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) \
                        or not -2**31 <= int(value) < 2**31:
                    raise ValueError(f"clear value of attachment {name!r} (r32i) must be an int32, got {value!r}")
                out[name] = np.int32(value)
            elif fmt == "r32f":
                if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
                        or not np.isfinite(value):
                    raise ValueError(f"clear value of attachment {name!r} (r32f) must be a finite number, got {value!r}")
                out[name] = np.float32(value)
            else:
                try:
                    c = np.zeros(4, np.float32) if name not in given else np.asarray(rgba(value), np.float32)
                except (TypeError, ValueError):
                    c = np.full(4, np.nan, np.float32)
                if not np.all(np.isfinite(c)):
                    raise ValueError(f"clear value of attachment {name!r} ({fmt}) must be 3 or 4 finite numbers or "
                                     f"a color name, got {value!r}")
                out[name] = c
        return out

    @property
    def color(self) -> np.ndarray:
        """[H, W, 4]: the buffer itself for one sample, else the box-filtered resolve."""
        if self.samples == 1:
            return self._view("color")
        return self.resolve("box")

    def resolve(self, filter: str = "box") -> np.ndarray:
        """The samples resolved to one color per pixel, [H, W, 4] float32.

        ``"box"``: the average of the pixel's samples (the notes' "sum divided
        by s²", FORMULAS §24). ``"tent"``: every sample within one pixel of the
        pixel's centre, weighted by (1 − |dx|)(1 − |dy|), so neighbouring
        pixels' samples contribute too (a softer result).
        """
        if filter == "box":
            return self.samples_color.mean(axis=0, dtype=np.float64).astype(np.float32)
        if filter != "tent":
            raise ValueError(f"resolve filter must be 'box' or 'tent', got {filter!r}")
        pos = self.pattern.positions                       # y up within the pixel
        acc = np.zeros((self.height, self.width, 4))
        wsum = np.zeros((self.height, self.width, 1))
        padded = np.pad(self.samples_color.astype(np.float64), ((0, 0), (1, 1), (1, 1), (0, 0)), mode="edge")
        for di in (-1, 0, 1):          # neighbour column offset
            for dj in (-1, 0, 1):      # neighbour row offset in the image (row down = window y − 1)
                for s, (sx, sy) in enumerate(pos):
                    dx = di + sx - 0.5
                    dy = -dj + sy - 0.5
                    w = max(0.0, 1 - abs(dx)) * max(0.0, 1 - abs(dy))
                    if w == 0.0:
                        continue
                    acc += w * padded[s, 1 + dj:1 + dj + self.height, 1 + di:1 + di + self.width]
                    wsum += w
        return (acc / wsum).astype(np.float32)

    @property
    def depth(self) -> np.ndarray:
        """[H, W]: the buffer itself for one sample, else the nearest sample's depth."""
        if self.samples == 1:
            return self._view("depth")
        return self.samples_depth.min(axis=0)

    def to_uint8(self, alpha: bool = True, attachment: Optional[str] = None) -> np.ndarray:
        """The color as 8-bit [H, W, 4] (or [H, W, 3]): round(clamp(c, 0, 1)·255), half to even.

        The one place softpipe turns colors into bytes (``np.asarray(fb)``, :meth:`save`,
        the stage pictures, Jupyter), whichever path drew them. A NaN channel (a shader
        that divided 0 by 0, say) becomes 0, +inf 255 and −inf 0, silently (no numpy
        warning): NaN counts as no light. In an sRGB framebuffer (:attr:`srgb`) R, G and
        B are clamped, then encoded (FORMULAS §28: ``srgb_encode``), then rounded the
        same way; alpha is not encoded. Several samples are averaged (:attr:`color`)
        in linear light before the encode.

        ``attachment`` names another ``rgba8`` attachment to turn into bytes the same way
        (the float and integer formats are numbers, read with :meth:`attachment`).
        """
        color = self.color
        if attachment is not None and attachment != self._formats[0][0]:
            fmt = dict(self._formats).get(attachment)
            if fmt is None:
                raise KeyError(f"this framebuffer has no attachment {attachment!r}; its attachments are "
                               f"{[n for n, _ in self._formats]}")
            if fmt != "rgba8":
                raise ValueError(f"attachment {attachment!r} is {fmt}, numbers rather than a picture: read them with "
                                 f"fb.attachment({attachment!r}); only 'rgba8' attachments become bytes")
            color = self.attachment(attachment)
        c = np.nan_to_num(color[..., : 4 if alpha else 3].astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0)
        c = np.clip(c, 0.0, 1.0)
        if self._srgb:
            c[..., :3] = srgb_encode(c[..., :3])
        return np.rint(c * 255.0).astype(np.uint8)

    def to_image(self, alpha: bool = False):
        """A pillow Image (RGB by default, RGBA with ``alpha=True``)."""
        from PIL import Image
        return Image.fromarray(self.to_uint8(alpha), "RGBA" if alpha else "RGB")

    def save(self, file: Union[str, "os.PathLike[str]", BinaryIO], alpha: bool = False,
             format: Optional[str] = None) -> Union[Path, BinaryIO]:
        """Write the picture (8-bit RGB, or RGBA with ``alpha=True``) to a path or a binary file.

        Parameters
        ----------
        file : str, path-like or binary file object
            A path: its extension says the format (``.png``, ``.jpg``, ``.bmp``, ``.tif``,
            ``.webp``, … any format pillow writes) and missing folders are made; the file is
            written whole or not at all (:func:`softpipe.core.files.atomic_write`: a full disk or
            Ctrl-C leaves the previous file of that name as it was). A file
            object opened for writing bytes (``open(…, "wb")``, ``io.BytesIO()``): give
            ``format=`` unless it has a ``name`` with an extension.
        alpha : bool
            Keep the alpha channel (a format without alpha, such as JPEG, refuses it).
        format : str, optional
            ``"png"``, ``"jpeg"``, ``"jpg"``, ``".bmp"``, … (any case); overrides the extension.

        Returns
        -------
        Path or the file object
            Where it was written.

        Raises
        ------
        ValueError
            An extension or format pillow cannot write (naming it), no extension and no
            ``format=``, or ``alpha=True`` for a format without alpha.
        TypeError
            A file object opened in text mode, or something that is neither a path nor a file.
        """
        is_path = isinstance(file, (str, os.PathLike))
        if not is_path and not callable(getattr(file, "write", None)):
            raise TypeError(f"save() takes a path or a binary file object, got {type(file).__name__}")
        if not is_path and isinstance(file, io.TextIOBase):
            raise TypeError(f"save() needs a binary file (opened with 'wb'), got the text file "
                            f"{getattr(file, 'name', file)!r}")
        name = os.fspath(file) if isinstance(file, (str, os.PathLike)) else getattr(file, "name", None)
        fmt = image_format(name if isinstance(name, str) else None, format)
        image = self.to_image(alpha)
        if alpha and fmt in ("JPEG", "PCX", "EPS", "PPM", "MPO"):
            raise ValueError(f"{fmt} images have no alpha channel; save with alpha=False or as .png")
        if isinstance(file, (str, os.PathLike)):
            from softpipe.core.files import atomic_write
            path = Path(file)
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(path, lambda f: image.save(f, format=fmt))
            return path
        image.save(file, format=fmt)
        return file

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        """``np.asarray(fb)``: the picture as 8-bit RGB, [H, W, 3] uint8 (what :meth:`save` writes).

        uint8 RGB because that is what every image library takes as it is:
        ``PIL.Image.fromarray(np.asarray(fb))`` makes an RGB image, ``plt.imshow(fb)``
        shows 0..255 integers without rescaling or clipping warnings, and
        ``imageio.imwrite("x.png", fb)`` writes it without a lossy-conversion warning.
        The float RGBA color (linear, unclamped, with alpha) is :attr:`color`;
        ``fb.to_uint8()`` gives RGBA bytes. The array is a new one each time: writing
        to it does not change the framebuffer.
        """
        if copy is False:
            raise ValueError("np.asarray(framebuffer) makes a new uint8 array; it cannot be had without a copy "
                             "(fb.color is the float buffer itself)")
        a = self.to_uint8(alpha=False)
        return a if dtype is None else a.astype(dtype)

    def _repr_png_(self) -> bytes:
        buf = io.BytesIO()
        self.to_image().save(buf, format="PNG")
        return buf.getvalue()

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        """What Jupyter shows: a small framebuffer (longer side under 64 pixels) zoomed, nearest
        neighbour with a pixel grid and coordinates (:func:`softpipe.views.zoom.zoomed`); a larger
        one as it is (the bytes ``_repr_png_`` and ``save`` write)."""
        from softpipe.views.zoom import fits_as_is, png, zoomed
        picture = self._repr_png_() if fits_as_is(self.width, self.height) else png(zoomed(self))
        return {"image/png": picture, "text/plain": repr(self)}

    def __repr__(self) -> str:
        srgb = ", sRGB" if self._srgb else ""
        more = ("" if len(self._formats) == 1 else
                ", attachments " + ", ".join(f"{n}: {f}" for n, f in self._formats))
        return (f"Framebuffer({self.width}×{self.height}, {self.samples} sample{'s' if self.samples > 1 else ''}"
                f"{srgb}{more})")
