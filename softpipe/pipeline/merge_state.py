"""The output merger's state: GL's per-fragment switches, by GL's names, checked once per draw.

Everything a draw can set for the chain of per-fragment operations
(:mod:`softpipe.pipeline.output` runs it), in GL's order:

====================  ==========================================  ==========================
step                  state here                                  GL call
====================  ==========================================  ==========================
scissor               ``scissor=(x, y, width, height)``           ``glScissor``
multisample           ``alpha_to_coverage``, ``sample_mask``      ``GL_SAMPLE_ALPHA_TO_COVERAGE``, ``glSampleMaski``
stencil test          ``stencil=Stencil(...)``, ``stencil_back``  ``glStencilFuncSeparate``, ``glStencilOpSeparate``
depth test            ``depth_test``, ``depth_clamp``             ``glDepthFunc``, ``GL_DEPTH_CLAMP``
blending              ``blend``, ``blend_equation``,              ``glBlendFuncSeparate``, ``glBlendEquationSeparate``,
                      ``blend_color``                             ``glBlendColor``
write masks           ``color_mask``, ``depth_write``,            ``glColorMask``, ``glDepthMask``, ``glStencilMask``
                      ``Stencil.write_mask``
====================  ==========================================  ==========================

(sRGB encoding happens where colors become bytes, :meth:`Framebuffer.to_uint8`.)

A framebuffer of several color attachments takes blending and the color mask per
attachment, GL's ``glBlendFunci`` / ``glColorMaski``: ``blend`` and ``color_mask`` may be a
dict of attachment name → state (:func:`attachment_states` splits them; integer
attachments are never blended). :class:`MergeState` holds location 0's.
:class:`MergeState` checks every value and names the one that is wrong;
:meth:`MergeState.codes` packs the state into the small integer array the merger's
compiled kernel reads (indices ``ST_*``), so the kernel's signature stays one array
however much state GL has. docs/06-output.md walks through the chain.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional, Sequence, Tuple, Union

import numpy as np

__all__ = ["MergeState", "Stencil", "DEPTH_FUNCS", "COMPARE_FUNCS", "STENCIL_OPS", "BLEND_FACTORS",
           "BLEND_EQUATIONS", "BLEND_PRESETS", "ALL_SAMPLES", "STATE_SIZE", "ST_DEPTH_FUNC", "ST_DEPTH_WRITE",
           "ST_DEPTH_CLAMP", "ST_BLEND", "ST_SRC_RGB", "ST_DST_RGB", "ST_SRC_ALPHA", "ST_DST_ALPHA",
           "ST_EQUATION_RGB", "ST_EQUATION_ALPHA", "ST_COLOR_MASK", "ST_STENCIL", "ST_STENCIL_FRONT",
           "ST_STENCIL_BACK", "STENCIL_FIELDS", "ST_SCISSOR", "ST_SAMPLE_MASK", "ST_ALPHA_TO_COVERAGE",
           "attachment_states", "AttachmentState"]

#: OpenGL's eight compare functions, for the depth and the stencil test: the fragment passes if
#: ``z_frag OP z_stored`` (depth) or ``(ref & mask) OP (stored & mask)`` (stencil).
COMPARE_FUNCS = ("never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always")
DEPTH_FUNCS = COMPARE_FUNCS
#: What the stencil test does to the stored value (GL's ``glStencilOp`` names).
STENCIL_OPS = ("keep", "zero", "replace", "incr", "incr_wrap", "decr", "decr_wrap", "invert")
#: GL's blend factors, lower case (``GL_ONE_MINUS_SRC_ALPHA`` is ``"one_minus_src_alpha"``).
BLEND_FACTORS = ("zero", "one", "src_color", "one_minus_src_color", "dst_color", "one_minus_dst_color",
                 "src_alpha", "one_minus_src_alpha", "dst_alpha", "one_minus_dst_alpha", "constant_color",
                 "one_minus_constant_color", "constant_alpha", "one_minus_constant_alpha", "src_alpha_saturate")
#: GL's blend equations: ``src·F_src + dst·F_dst`` ("add"), ``src·F_src − dst·F_dst``
#: ("subtract"), ``dst·F_dst − src·F_src`` ("reverse_subtract"), and the factor-free
#: ``min(src, dst)``, ``max(src, dst)``.
BLEND_EQUATIONS = ("add", "subtract", "reverse_subtract", "min", "max")
#: Named blend modes: ``"alpha"`` (over, straight alpha), ``"premultiplied"`` (over, the color
#: already multiplied by its alpha), ``"additive"``.
BLEND_PRESETS = {"alpha": ("src_alpha", "one_minus_src_alpha"), "additive": ("one", "one"),
                 "premultiplied": ("one", "one_minus_src_alpha")}
#: The default sample mask: every sample (GL's ``glSampleMaski(0, ~0)``).
ALL_SAMPLES = 0xFFFFFFFF

# The packed state (:meth:`MergeState.codes`): one int64 per entry.
ST_DEPTH_FUNC = 0            # index into COMPARE_FUNCS, or -1: the depth test is off
ST_DEPTH_WRITE = 1           # 1: write depth (only when the test is on, as GL)
ST_DEPTH_CLAMP = 2           # 1: clamp the fragment's depth to [0, 1] before the test
ST_BLEND = 3                 # 1: blending on
ST_SRC_RGB, ST_DST_RGB, ST_SRC_ALPHA, ST_DST_ALPHA = 4, 5, 6, 7      # indices into BLEND_FACTORS
ST_EQUATION_RGB, ST_EQUATION_ALPHA = 8, 9                            # indices into BLEND_EQUATIONS
ST_COLOR_MASK = 10           # four entries, R G B A: 1 writes the channel
ST_STENCIL = 14              # 1: the stencil test is on
#: a face's stencil state: func, ref, value mask, fail op, depth-fail op, depth-pass op, write mask
STENCIL_FIELDS = ("func", "ref", "mask", "fail", "depth_fail", "depth_pass", "write_mask")
ST_STENCIL_FRONT = 15        # seven entries (STENCIL_FIELDS), for front-facing primitives
ST_STENCIL_BACK = 22         # seven entries, for back-facing triangles
ST_SCISSOR = 29              # 1: the scissor test is on; then column min, max+1, image row min, max+1
ST_SAMPLE_MASK = 34
ST_ALPHA_TO_COVERAGE = 35
STATE_SIZE = 36


def _byte(name: str, value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"Stencil {name} must be an integer, got {type(value).__name__} {value!r}")
    return int(value)


@dataclass(frozen=True)
class Stencil:
    """One face's stencil state: GL's ``glStencilFunc``, ``glStencilOp`` and ``glStencilMask``.

    The test passes when ``(ref & mask) OP (stored & mask)``, OP being ``func``. Then
    ``fail`` is applied when the stencil test fails, ``depth_fail`` when it passes and
    the depth test fails, ``depth_pass`` when both pass (or the depth test is off).
    An op's result is written through ``write_mask``: ``stored = (stored & ~write_mask)
    | (result & write_mask)``. The buffer holds 8 bits per sample.

    Parameters
    ----------
    func : one of :data:`COMPARE_FUNCS` (default "always")
    ref : int
        The reference value, clamped to [0, 255] as GL clamps it to the buffer's range.
    mask : int
        The value mask, ANDed with both sides of the compare (default 0xFF).
    fail, depth_fail, depth_pass : one of :data:`STENCIL_OPS` (default "keep")
        "replace" writes ``ref``; "incr" and "decr" clamp at 255 and 0; "incr_wrap" and
        "decr_wrap" wrap around (255 + 1 → 0, 0 − 1 → 255); "invert" flips every bit.
    write_mask : int
        The bits the ops may change (default 0xFF).
    """

    func: str = "always"
    ref: int = 0
    mask: int = 0xFF
    fail: str = "keep"
    depth_fail: str = "keep"
    depth_pass: str = "keep"
    write_mask: int = 0xFF

    def __post_init__(self):
        if self.func not in COMPARE_FUNCS:
            raise ValueError(f"Stencil func must be one of {COMPARE_FUNCS}, got {self.func!r}")
        for name in ("fail", "depth_fail", "depth_pass"):
            if getattr(self, name) not in STENCIL_OPS:
                raise ValueError(f"Stencil {name} must be one of {STENCIL_OPS}, got {getattr(self, name)!r}")
        object.__setattr__(self, "ref", min(max(_byte("ref", self.ref), 0), 255))
        for name in ("mask", "write_mask"):
            v = _byte(name, getattr(self, name))
            if v < 0:
                raise ValueError(f"Stencil {name} must be at least 0, got {v}")
            object.__setattr__(self, name, v & 0xFF)     # GL keeps the buffer's 8 low bits

    def codes(self) -> Tuple[int, ...]:
        """The seven packed entries (:data:`STENCIL_FIELDS`)."""
        return (COMPARE_FUNCS.index(self.func), self.ref, self.mask, STENCIL_OPS.index(self.fail),
                STENCIL_OPS.index(self.depth_fail), STENCIL_OPS.index(self.depth_pass), self.write_mask)


BlendSpec = Union[None, str, Tuple[str, str], Tuple[str, str, str, str]]


def _blend_factors(blend) -> Tuple[int, int, int, int]:
    """(src_rgb, dst_rgb, src_alpha, dst_alpha) factor codes, or four -1 when blending is off."""
    if blend is None:
        return -1, -1, -1, -1
    b = blend
    if isinstance(b, str):
        if b not in BLEND_PRESETS:
            raise ValueError(f"blend must be None, one of {tuple(BLEND_PRESETS)}, a (src, dst) pair or a "
                             f"(src_rgb, dst_rgb, src_alpha, dst_alpha) quadruple of {BLEND_FACTORS}, got {b!r}")
        b = BLEND_PRESETS[b]
    if not (isinstance(b, (tuple, list)) and len(b) in (2, 4)):
        raise ValueError(f"blend must be None, a preset name, a (src_factor, dst_factor) pair or a "
                         f"(src_rgb, dst_rgb, src_alpha, dst_alpha) quadruple, got {blend!r}")
    for f in b:
        if f not in BLEND_FACTORS:
            raise ValueError(f"unknown blend factor {f!r}; expected one of {BLEND_FACTORS}")
    b = tuple(b) * 2 if len(b) == 2 else tuple(b)
    return tuple(BLEND_FACTORS.index(f) for f in b)      # type: ignore[return-value]


def _equations(equation) -> Tuple[int, int]:
    eq = (equation, equation) if isinstance(equation, str) else equation
    if not (isinstance(eq, (tuple, list)) and len(eq) == 2 and all(isinstance(e, str) for e in eq)):
        raise ValueError(f"blend_equation must be one of {BLEND_EQUATIONS} or an (rgb, alpha) pair of them, "
                         f"got {equation!r}")
    for e in eq:
        if e not in BLEND_EQUATIONS:
            raise ValueError(f"unknown blend equation {e!r}; expected one of {BLEND_EQUATIONS}")
    return BLEND_EQUATIONS.index(eq[0]), BLEND_EQUATIONS.index(eq[1])


def _bool(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


@dataclass(frozen=True)
class MergeState:
    """The output merger's fixed-function state (the module docstring lists it in GL's order).

    Parameters
    ----------
    depth_test : one of :data:`DEPTH_FUNCS`, or None to turn the test off
        (OpenGL then neither tests nor writes depth).
    depth_write : bool
        GL's depth mask.
    depth_clamp : bool
        GL_DEPTH_CLAMP: assembly does not clip at the near and far planes, and the
        fragment's depth is clamped to [0, 1] before the depth test (and so stored clamped).
    blend : None (off), a name of :data:`BLEND_PRESETS`, (src_factor, dst_factor), or
        (src_rgb, dst_rgb, src_alpha, dst_alpha) with factors from :data:`BLEND_FACTORS`.
    blend_equation : one of :data:`BLEND_EQUATIONS`, or (rgb, alpha) (default "add").
    blend_color : 4 numbers
        The constant color the ``constant_*`` factors read (default (0, 0, 0, 0)).
    color_mask : 4 bools
        Which of R, G, B, A are written (default all).
    stencil : Stencil or None
        The stencil test's state (None: the test is off: every fragment passes it and
        the stencil buffer is not written).
    stencil_back : Stencil or None
        The state for back-facing triangles (GL's ``*Separate``); None: as ``stencil``.
        Lines and points face the front.
    scissor : (x, y, width, height) or None
        Only the pixels x ≤ column < x + width, y ≤ row < y + height in window
        coordinates (row 0 at the bottom, as the viewport's) are written.
    sample_mask : int
        Bit m lets sample m be written (GL's ``glSampleMaski``; default every sample).
    alpha_to_coverage : bool
        A fragment covers the samples m < round(clamp(alpha, 0, 1)·S) of its pixel (S
        samples per pixel; a NaN alpha covers none). As GL's multisample operations,
        this and ``sample_mask`` apply only to a framebuffer with more than one sample.
    """

    depth_test: Optional[str] = "less"
    depth_write: bool = True
    blend: BlendSpec = None
    blend_equation: Union[str, Tuple[str, str]] = "add"
    blend_color: Sequence[float] = (0.0, 0.0, 0.0, 0.0)
    color_mask: Sequence[bool] = (True, True, True, True)
    stencil: Optional[Stencil] = None
    stencil_back: Optional[Stencil] = None
    scissor: Optional[Tuple[int, int, int, int]] = None
    sample_mask: int = ALL_SAMPLES
    alpha_to_coverage: bool = False
    depth_clamp: bool = False

    def __post_init__(self):
        if self.depth_test is not None and self.depth_test not in DEPTH_FUNCS:
            raise ValueError(f"depth_test must be one of {DEPTH_FUNCS} or None, got {self.depth_test!r}")
        _bool("depth_write", self.depth_write)
        _bool("depth_clamp", self.depth_clamp)
        _bool("alpha_to_coverage", self.alpha_to_coverage)
        _blend_factors(self.blend)
        _equations(self.blend_equation)
        try:
            color = tuple(float(c) for c in self.blend_color)
        except (TypeError, ValueError):
            color = ()
        if len(color) != 4 or not all(np.isfinite(color)):
            raise ValueError(f"blend_color must be 4 finite numbers (r, g, b, a), got {self.blend_color!r}")
        object.__setattr__(self, "blend_color", color)
        mask = tuple(self.color_mask) if isinstance(self.color_mask, (tuple, list)) else ()
        if len(mask) != 4 or not all(isinstance(m, (bool, np.bool_)) for m in mask):
            raise ValueError(f"color_mask must be 4 booleans (r, g, b, a), got {self.color_mask!r}")
        object.__setattr__(self, "color_mask", tuple(bool(m) for m in mask))
        for name in ("stencil", "stencil_back"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, Stencil):
                raise TypeError(f"{name} must be a softpipe.Stencil or None, got {type(v).__name__} {v!r}")
        if self.stencil is None and self.stencil_back is not None:
            raise ValueError("stencil_back is given but stencil is None: give stencil= (the front faces' state, "
                             "and the switch that turns the stencil test on) as well")
        if self.scissor is not None:
            s = self.scissor
            if not (isinstance(s, (tuple, list)) and len(s) == 4
                    and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in s)):
                raise ValueError(f"scissor must be (x, y, width, height), four integers, or None, got {s!r}")
            if s[2] < 0 or s[3] < 0:
                raise ValueError(f"scissor width and height must be at least 0, got {s!r}")
            object.__setattr__(self, "scissor", tuple(int(v) for v in s))
        if isinstance(self.sample_mask, (bool, np.bool_)) or not isinstance(self.sample_mask, (int, np.integer)):
            raise TypeError(f"sample_mask must be an integer bit mask, got {self.sample_mask!r}")
        if not 0 <= int(self.sample_mask) <= ALL_SAMPLES:
            raise ValueError(f"sample_mask must be in [0, 0xFFFFFFFF] (a bit per sample), got {self.sample_mask!r}")

    @property
    def blends(self) -> bool:
        """Is blending on?"""
        return self.blend is not None

    @property
    def masks_color(self) -> bool:
        """Does the color mask hold back some channel?"""
        return not all(self.color_mask)

    def scissor_rows(self, height: int) -> Tuple[int, int, int, int]:
        """The scissor as (column min, column max + 1, image row min, image row max + 1) in a
        framebuffer ``height`` pixels high (image row 0 at the top)."""
        assert self.scissor is not None
        x, y, w, h = self.scissor
        return x, x + w, height - (y + h), height - y

    def codes(self, height: int) -> np.ndarray:
        """The state packed for the merger's kernel: int64 [:data:`STATE_SIZE`] (indices ``ST_*``)."""
        st = np.zeros(STATE_SIZE, np.int64)
        st[ST_DEPTH_FUNC] = -1 if self.depth_test is None else DEPTH_FUNCS.index(self.depth_test)
        st[ST_DEPTH_WRITE] = int(self.depth_write and self.depth_test is not None)
        st[ST_DEPTH_CLAMP] = int(self.depth_clamp)
        st[ST_BLEND] = int(self.blends)
        st[ST_SRC_RGB:ST_DST_ALPHA + 1] = _blend_factors(self.blend)
        st[ST_EQUATION_RGB:ST_EQUATION_ALPHA + 1] = _equations(self.blend_equation)
        st[ST_COLOR_MASK:ST_COLOR_MASK + 4] = self.color_mask
        if self.stencil is not None:
            st[ST_STENCIL] = 1
            st[ST_STENCIL_FRONT:ST_STENCIL_FRONT + 7] = self.stencil.codes()
            st[ST_STENCIL_BACK:ST_STENCIL_BACK + 7] = (self.stencil_back or self.stencil).codes()
        if self.scissor is not None:
            st[ST_SCISSOR] = 1
            st[ST_SCISSOR + 1:ST_SCISSOR + 5] = self.scissor_rows(height)
        st[ST_SAMPLE_MASK] = int(self.sample_mask)
        st[ST_ALPHA_TO_COVERAGE] = int(self.alpha_to_coverage)
        return st


# ------------------------------------------------------------------ per attachment (multiple render targets)

@dataclass(frozen=True)
class AttachmentState:
    """Blending and the color mask of one color attachment other than location 0 (GL's
    ``glBlendFunci``, ``glColorMaski``; the blend equation and color are the draw's, shared).

    ``codes`` packs it for the merger's kernel: blending on, the four factors, the two
    equations, then the four mask entries (one-channel formats read R's alone).
    """

    name: str
    format: str
    blend: BlendSpec
    color_mask: Tuple[bool, bool, bool, bool]
    codes: np.ndarray

    @property
    def blends(self) -> bool:
        return self.blend is not None

    @property
    def masks_color(self) -> bool:
        """Does the mask hold back a channel this attachment has?"""
        return not all(self.color_mask[:1] if self.format in ("r32f", "r32i") else self.color_mask)


def _mask(name: Optional[str], value) -> Tuple[bool, bool, bool, bool]:
    mask = tuple(value) if isinstance(value, (tuple, list)) else ()
    if len(mask) != 4 or not all(isinstance(m, (bool, np.bool_)) for m in mask):
        which = "" if name is None else f" for attachment {name!r}"
        raise ValueError(f"color_mask{which} must be 4 booleans (r, g, b, a), got {value!r}")
    return tuple(bool(m) for m in mask)        # type: ignore[return-value]


def _per_attachment(what: str, value, names: Sequence[str], default):
    """``value`` for each attachment: the same for all, or a dict of name → value (the others ``default``)."""
    if not isinstance(value, Mapping):
        return [value] * len(names)
    for key in value:
        if key not in names:
            raise ValueError(f"{what} names attachment {key!r}, but the framebuffer's attachments are {list(names)}")
    return [value.get(n, default) for n in names]


def attachment_states(blend, color_mask, blend_equation, attachments: Sequence[Tuple[str, str]]
                      ) -> Tuple[BlendSpec, Tuple[bool, ...], Tuple[AttachmentState, ...]]:
    """Split a draw's ``blend`` and ``color_mask`` over a framebuffer's attachments ((name, format), …).

    Either may be one state for every attachment or a dict of attachment name → state (those
    not named: blending off, every channel written). Integer attachments (``r32i``) are not
    blended, as GL's are not: one blend state for all leaves them out, and a dict that gives
    one a blend state is refused. Returns location 0's blend and mask (for
    :class:`MergeState`) and the other attachments' :class:`AttachmentState`.
    """
    names = [n for n, _ in attachments]
    blends = _per_attachment("blend", blend, names, None)
    masks = _per_attachment("color_mask", color_mask, names, (True, True, True, True))
    eq = _equations(blend_equation)
    more = []
    for k, ((name, fmt), b, m) in enumerate(zip(attachments, blends, masks)):
        if fmt == "r32i" and b is not None:
            if isinstance(blend, Mapping):
                raise ValueError(f"blend for attachment {name!r} (r32i): integer attachments are not blended "
                                 "(GL's rule); leave it out of blend= or give it None")
            b = None
        if k == 0:
            continue
        factors = _blend_factors(b)
        mask = _mask(name if isinstance(color_mask, Mapping) else None, m)
        codes = np.array((int(b is not None),) + factors + eq + mask, np.int64)
        more.append(AttachmentState(name, fmt, b, mask, codes))
    first_mask = masks[0]
    if isinstance(color_mask, Mapping):
        first_mask = _mask(names[0], first_mask)
    return blends[0], first_mask, tuple(more)
