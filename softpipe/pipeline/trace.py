"""A draw's trace: every stage's output kept, and questions asked of it.

``trace = softpipe.draw(fb, ..., trace=True)`` runs the draw as usual (the same
stages, the same pixels) and keeps:

``vertex``      the vertex stage's :class:`~softpipe.pipeline.vertex.VertexOut`
``primitives``  assembly's :class:`~softpipe.pipeline.assembly.Primitives` (with what was dropped and why)
``fragments``   the rasterizer's :class:`~softpipe.pipeline.raster.Fragments`, all batches
``shaded``      the fragment shader's :class:`~softpipe.pipeline.fragment.ShadedFragments`
``merged``      the output merger's :class:`~softpipe.pipeline.output.MergeResult` (verdicts: which test
                stopped each fragment; the color and stencil after each)
``before``      the framebuffer's color, depth and stencil before the draw (:meth:`Trace.before_at`,
                :attr:`Trace.before_color`, :attr:`Trace.before_stencil`): kept only at the pixels the draw touched
``path``        the path the draw took ("reference" or "fast") and ``path_reason`` why
``visibility``  on the fast path, the visibility pass's :class:`~softpipe.pipeline.visibility.Visibility`

A trace follows the path the draw takes: with ``path="auto"`` that is the
reference path (only it makes every fragment); with ``path="fast"`` the trace
holds the visibility stage, and its fragments are the ones the fast path
shaded (one per visible sample: the fragments that lost the depth test were
never made, so a pixel's history lists only the winner).

and answers: :meth:`Trace.pixel_history` (every fragment that touched a pixel,
in order), :meth:`Trace.fragment_inputs` and :meth:`Trace.debug_fragment`
(re-run the fragment shader as plain Python on exactly one fragment's inputs,
so a breakpoint in the shader stops there), :meth:`Trace.fragment_varyings` (the varyings of
many fragments in one compiled pass, for the explorer page). :mod:`softpipe.views.pictures` draws it.

What was under the draw is kept small: every sample of the pixels the draw's fragments
reached or changed, not a copy of the whole framebuffer (a scene of 1,500 small draws,
each traced, would otherwise keep 1,500 framebuffers). While the framebuffer is
drawn into (or cleared) no more, :attr:`Trace.before_color` and
:attr:`Trace.before_depth` give the whole arrays; after that, only the touched pixels
are known, and those properties say so (ValueError) rather than guess.
"""
from __future__ import annotations

import math
import types
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from softpipe.core.runtime import check_memory
from softpipe.language import kernels
from softpipe.language.contract import python_function
from softpipe.language.kernels.diagnostics import plain_value
from softpipe.pipeline.fragment import ShadedFragments, default_fragment_shader, derivative_gradients
from softpipe.pipeline.framebuffer import Framebuffer
from softpipe.pipeline.output import VERDICTS, MergeResult, merge_more
from softpipe.pipeline.raster import Fragments

__all__ = ["Trace", "PixelEvent", "PixelHistory", "BeforeDraw", "as_compiled_math", "COMPILED_MATH"]


def _concat(parts, cls, fields):
    return cls(**{f: np.concatenate([getattr(p, f) for p in parts]) for f in fields})


@dataclass
class BeforeDraw:
    """What a framebuffer held, before one draw, at the pixels the draw touched.

    ``pixels`` int64 [P], sorted: row · width + column of each pixel kept; ``color``
    float32 [S, P, 4], ``depth`` float32 [S, P] and ``stencil`` uint8 [S, P]: every sample of
    those pixels before the draw; ``writes``: the framebuffer's :attr:`~softpipe.pipeline.framebuffer.Framebuffer.writes`
    right after the draw (while it is unchanged the pixels not kept still hold what they
    held before the draw). ``attachments``: in a framebuffer of several color attachments, the
    others' samples there (name → [S, P, 4] or [S, P]), from which a pixel's history replays them.
    """

    pixels: np.ndarray
    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    writes: int
    attachments: Dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def take(cls, fb, primitives) -> "_Snapshot":
        """Copy, before the draw, the samples of the rectangle of pixels ``primitives`` can reach (a point's
        square and a wide line included)."""
        h, w = fb.height, fb.width
        window = np.asarray(primitives.window, dtype=np.float64)
        if len(window) == 0:
            x0 = x1 = y0 = y1 = 0
        elif not np.isfinite(window[..., :2]).all():
            x0, x1, y0, y1 = 0, w, 0, h
        else:                               # window y up → image rows; one pixel to spare on each side
            xs, ys = window[..., 0], window[..., 1]
            # a point's square and a wide line's runs reach half their size past the corners
            r = 0 if primitives.kind == "triangles" else int(np.ceil(float(np.max(primitives.size)) / 2))
            x0, x1 = int(max(np.floor(xs.min()) - 1 - r, 0)), int(min(np.ceil(xs.max()) + 2 + r, w))
            y0, y1 = int(max(np.floor(h - ys.max()) - 1 - r, 0)), int(min(np.ceil(h - ys.min()) + 2 + r, h))
            x1, y1 = max(x1, x0), max(y1, y0)
        others = list(fb.attachments)[1:]
        per_sample = 21 + sum(fb.samples_attachment(n)[:1, :1, :1].nbytes for n in others)
        need = fb.samples * (y1 - y0) * (x1 - x0) * per_sample
        check_memory(f"tracing a draw over {x1 - x0}×{y1 - y0} pixels ({fb.samples} sample(s), {per_sample} bytes "
                     "each: the framebuffer under it, kept to show each pixel's color before the draw)", need)
        return _Snapshot((y0, y1, x0, x1), fb.samples_color[:, y0:y1, x0:x1].copy(),
                         fb.samples_depth[:, y0:y1, x0:x1].copy(), fb.samples_stencil[:, y0:y1, x0:x1].copy(),
                         {n: fb.samples_attachment(n)[:, y0:y1, x0:x1].copy() for n in others})

    def find(self, x: int, y: int, width: int) -> int:
        """The column of pixel (x, y) in :attr:`pixels`, or -1 when it was not kept."""
        p = y * width + x
        j = int(np.searchsorted(self.pixels, p))
        return j if j < len(self.pixels) and self.pixels[j] == p else -1


@dataclass
class _Snapshot:
    """The rectangle (rows y0:y1, columns x0:x1) a draw can reach, copied before it; :meth:`keep` shrinks it."""

    rect: tuple
    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    attachments: Dict[str, np.ndarray] = field(default_factory=dict)

    def keep(self, fb, fragments) -> BeforeDraw:
        """After the draw: keep the pixels its fragments reached or whose samples it changed."""
        y0, y1, x0, x1 = self.rect
        w = fb.width
        now_c, now_d = fb.samples_color[:, y0:y1, x0:x1], fb.samples_depth[:, y0:y1, x0:x1]
        now_s = fb.samples_stencil[:, y0:y1, x0:x1]
        changed = ((now_c != self.color).any(axis=(0, 3)) | (now_d != self.depth).any(axis=0)
                   | (now_s != self.stencil).any(axis=0))
        mask = changed.copy()
        fx, fy = np.asarray(fragments.x, np.int64), np.asarray(fragments.y, np.int64)
        inside = (fx >= x0) & (fx < x1) & (fy >= y0) & (fy < y1)
        mask[fy[inside] - y0, fx[inside] - x0] = True
        rows, cols = np.nonzero(mask)                       # row-major: the pixels come out sorted
        pixels = (rows + y0).astype(np.int64) * w + (cols + x0)
        return BeforeDraw(pixels, np.ascontiguousarray(self.color[:, rows, cols]),
                          np.ascontiguousarray(self.depth[:, rows, cols]),
                          np.ascontiguousarray(self.stencil[:, rows, cols]), fb.writes,
                          {n: np.ascontiguousarray(a[:, rows, cols]) for n, a in self.attachments.items()})


@dataclass
class PixelEvent:
    """One fragment at one pixel: what it was and what the merger did with it."""

    index: int                  # row in the trace's fragments
    primitive_id: int
    triangle: int
    sample: int
    depth: float
    varyings: Any               # namedtuple, as the shader received them
    color: tuple                # the shader's output (RGBA), NaN alpha = discarded
    verdict: str                # "written", or the test that stopped it: "depth-failed", "stencil-failed", ...
    color_after: tuple          # the sample's color after this fragment
    shadow: tuple = ()          # V_j of each light at the fragment (RGB), when the draw has shadow maps
    point_coord: tuple = ()     # of a line's or a point's fragment: frag.point_coord ((t, 0) on a line)
    stencil: tuple = ()         # (before, after) the sample's stencil value, when the draw's stencil test is on
    instance: int = 0           # the instance its primitive belongs to (gl_InstanceID; 0 without instancing)
    # into several color attachments: ``color`` and ``color_after`` are location 0's; these are the others',
    # attachment name → the shader's value for it, and the sample's value after this fragment
    outputs: Dict[str, Any] = field(default_factory=dict)
    outputs_after: Dict[str, Any] = field(default_factory=dict)


class PixelHistory(list):
    """The :class:`PixelEvent` list of one pixel; prints as a table (an HTML table in Jupyter).

    ``before`` is the pixel's color (sample 0) before the draw; None for a pixel the draw did
    not touch once the framebuffer has been written since (the trace does not keep it).
    ``kind`` is the draw's primitives' (``Primitives.kind``): for "lines" the table names the
    line and shows each fragment's t along it, for "points" the point and its ``gl_PointCoord``;
    with ``polygon_mode`` (a triangle's edges or corners) the "triangle" column names the triangle.
    ``instances`` is the draw's (1 without instancing); with more than one, an "instance" column
    names each fragment's instance beside its primitive (whose id counts within the instance).
    Into a framebuffer of several color attachments, "shader output" and "color after" are
    location 0's, and each other attachment NAME has its columns "NAME output" (the shader's
    value for it) and "NAME after" (the sample's value after the fragment).
    """

    def __init__(self, x: int, y: int, events: List[PixelEvent], before: Optional[tuple], kind: str = "triangles",
                 polygon_mode: bool = False, instances: int = 1):
        super().__init__(events)
        self.x, self.y, self.before, self.kind, self.polygon_mode = x, y, before, kind, polygon_mode
        self.instances = instances

    @staticmethod
    def _fmt(v) -> str:
        if isinstance(v, tuple):
            return "(" + ", ".join(f"{c:.4g}" for c in v) + ")"
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    def _heading(self) -> str:
        if self.before is None:         # a pixel the draw did not touch, asked after the framebuffer changed
            return f"pixel ({self.x}, {self.y}): 0 fragment(s); the draw did not touch it"
        return (f"pixel ({self.x}, {self.y}): {len(self)} fragment(s); color before the draw "
                f"{self._fmt(self.before)}")

    def table(self):
        """(column names, rows of cell strings): the table that ``str()`` and Jupyter show."""
        if not self:
            return [], []
        fmt = self._fmt
        names = list(self[0].varyings._fields)
        shadow = ["shadow V_j"] if self[0].shadow else []
        stencil = ["stencil"] if self[0].stencil else []
        # a line's fragment: t along it; a point's: gl_PointCoord (none for a triangle's)
        where = {"lines": ["t"], "points": ["point coord"]}.get(self.kind, [])
        label = "prim" if not where else ("triangle" if self.polygon_mode else self.kind[:-1])
        instance = ["instance"] if self.instances > 1 else []
        more = list(self[0].outputs)        # the other color attachments, in location order
        cols = (["#"] + instance + [label, "sample", "depth"] + where + names + shadow
                + ["shader output"] + [f"{a} output" for a in more] + ["merger"] + stencil + ["color after"]
                + [f"{a} after" for a in more])
        rows = [[str(e.index)] + ([str(e.instance)] if instance else [])
                + [str(e.primitive_id), str(e.sample), f"{e.depth:.6f}"]
                + ([fmt(e.point_coord[0]) if self.kind == "lines" else fmt(e.point_coord)] if where else [])
                + [fmt(getattr(e.varyings, n)) for n in names]
                + ([self._fmt_shadow(e.shadow)] if shadow else [])
                + [fmt(e.color)] + [fmt(e.outputs[a]) for a in more] + [str(e.verdict)]
                + ([f"{e.stencil[0]} → {e.stencil[1]}"] if stencil else [])
                + [fmt(e.color_after)] + [fmt(e.outputs_after[a]) for a in more] for e in self]
        return cols, rows

    @classmethod
    def _fmt_shadow(cls, shadow) -> str:
        """V_j per light: one number where it is gray, else the RGB triple."""
        return " ".join(f"{c[0]:.3g}" if c[0] == c[1] == c[2] else cls._fmt(c) for c in shadow)

    def __str__(self) -> str:
        head = self._heading()
        cols, rows = self.table()
        if not rows:
            return head
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(cols)]
        line = lambda r: "  ".join(v.ljust(w) for v, w in zip(r, widths))  # noqa: E731
        return "\n".join([head, line(cols), line(["-" * w for w in widths])] + [line(r) for r in rows])

    def _repr_pretty_(self, p, cycle):
        p.text(str(self))

    def _repr_html_(self) -> str:
        """The table as HTML for Jupyter: every value escaped, a color swatch beside each RGBA."""
        from html import escape

        def swatch(value) -> str:
            if not (isinstance(value, tuple) and len(value) == 4
                    and all(isinstance(c, float) and np.isfinite(c) for c in value)):
                return ""
            r, g, b = (int(round(min(max(c, 0.0), 1.0) * 255)) for c in value[:3])
            style = (f"display:inline-block;width:0.9em;height:0.9em;margin-right:0.3em;vertical-align:middle;"
                     f"border:1px solid #888;background:rgb({r},{g},{b})")
            return f'<span style="{escape(style)}"></span>'

        cols, rows = self.table()
        out = ['<div class="softpipe-pixel-history">', f"<p>{escape(self._heading())}</p>"]
        if rows:
            colored = {cols.index("shader output"): "color", cols.index("color after"): "color_after"}
            out.append('<table><thead><tr>' + "".join(f"<th>{escape(c)}</th>" for c in cols) + "</tr></thead><tbody>")
            for event, row in zip(self, rows):
                cells = []
                for i, cell in enumerate(row):
                    mark = swatch(getattr(event, colored[i])) if i in colored else ""
                    cells.append(f"<td>{mark}{escape(cell)}</td>")
                out.append("<tr>" + "".join(cells) + "</tr>")
            out.append("</tbody></table>")
        out.append("</div>")
        return "\n".join(out)


class Trace:
    """Every stage's output of one draw; see the module docstring."""

    #: The framebuffer before the draw, where the draw touched it (set by :meth:`record`).
    before: BeforeDraw

    def __init__(self, call, vertex, primitives, fragments: Fragments, shaded: ShadedFragments,
                 merged: MergeResult, before: Optional[BeforeDraw] = None):
        self.call = call
        self.vertex, self.primitives = vertex, primitives
        self.fragments, self.shaded, self.merged = fragments, shaded, merged
        if before is not None:
            self.before = before
        fb = call.framebuffer
        self.width, self.height, self.pattern = fb.width, fb.height, fb.pattern
        self.path, self.path_reason = call.path_taken, call.path_reason
        self.visibility = None
        self._grad: Optional[np.ndarray] = None
        self._python_module = None     # the plain-Python fragment module, made once (exec of generated source)

    @classmethod
    def record(cls, call) -> "Trace":
        """Run ``call`` (a :class:`~softpipe.pipeline.draw.DrawCall`) and keep what every stage made."""
        fb = call.framebuffer
        out: dict[str, list] = {"raster": [], "fragment": [], "output": [], "visibility": []}
        vertex = primitives = snapshot = None
        with fb.lock:                       # the same as the draw's: the snapshot and the draw are one turn
            for stage in call.steps(record=True):
                if stage.name == "vertex":
                    vertex = stage.output
                elif stage.name == "assembly":
                    primitives = stage.output
                    snapshot = BeforeDraw.take(fb, primitives)      # nothing is written before assembly
                else:
                    out[stage.name].append(stage.output)
            if out["visibility"]:
                trace = cls._fast(call, vertex, primitives, out["visibility"][0], out["fragment"][0])
            else:
                trace = cls._reference(call, vertex, primitives, out)
            assert snapshot is not None, "a draw's steps always include assembly"
            trace.before = snapshot.keep(fb, trace.fragments)
        return trace

    @classmethod
    def _reference(cls, call, vertex, primitives, out) -> "Trace":
        """A trace of the reference path: its batches joined."""
        frag_fields = ("x", "y", "sample", "depth", "bary", "triangle", "primitive_id", "frag_x", "frag_y")
        if out["raster"]:
            fragments = _concat(out["raster"], Fragments, frag_fields)
            fragments.setup = out["raster"][0].setup
            shaded = _concat(out["fragment"], ShadedFragments, ("color", "discarded"))
            shaded.invocations = sum(p.invocations for p in out["fragment"])
            # into several attachments: the other locations' values, every batch's joined
            shaded.outputs = tuple(np.concatenate(parts) for parts in zip(*(p.outputs for p in out["fragment"])))
            merged = _concat(out["output"], MergeResult, ("verdict", "color_after", "stencil_after"))
        else:
            empty = np.zeros(0)
            fragments = Fragments(empty.astype(np.int32), empty.astype(np.int32), empty.astype(np.int32),
                                  empty, np.zeros((0, 3)), empty.astype(np.int32), empty.astype(np.int64),
                                  empty, empty)
            shaded = ShadedFragments(np.zeros((0, 4), np.float32), np.zeros(0, bool))
            merged = MergeResult(np.zeros(0, np.int8), np.zeros((0, 4), np.float32), np.zeros(0, np.uint8))
        return cls(call, vertex, primitives, fragments, shaded, merged)

    @classmethod
    def _fast(cls, call, vertex, primitives, visibility, shaded_samples) -> "Trace":
        """A trace of the fast path: its fragments are those it shaded, each written."""
        fb = call.framebuffer
        fragments = visibility.fragments(primitives, fb.pattern, call.sample_shading)
        color = fb.samples_color[fragments.sample, fragments.y, fragments.x]
        # the other attachments hold the winners' values as they are (the fast path neither blends nor masks them)
        outputs = tuple(fb.samples_attachment(n)[fragments.sample, fragments.y, fragments.x]
                        for n in list(fb.attachments)[1:])
        shaded = ShadedFragments(color, np.zeros(len(fragments), bool), shaded_samples.invocations, outputs)
        merged = MergeResult(np.zeros(len(fragments), np.int8), color.copy(),
                             fb.samples_stencil[fragments.sample, fragments.y, fragments.x])
        trace = cls(call, vertex, primitives, fragments, shaded, merged)
        trace.visibility = visibility
        return trace

    # ------------------------------------------------------------- before the draw

    def before_at(self, x: int, y: int) -> Tuple[np.ndarray, np.ndarray]:
        """The color (float32 [S, 4]) and depth (float32 [S]) of pixel (x, y)'s samples before the draw.

        Known for every pixel the draw's fragments reached or changed; for another
        pixel, while the framebuffer has not been written since (its color then is as
        before the draw), else a ValueError says so.
        """
        self._check_pixel(x, y)
        j = self.before.find(x, y, self.width)
        if j >= 0:
            return self.before.color[:, j].copy(), self.before.depth[:, j].copy()
        fb = self._unchanged_framebuffer(f"pixel ({x}, {y}), which the draw did not touch")
        return fb.samples_color[:, y, x].copy(), fb.samples_depth[:, y, x].copy()

    @property
    def before_color(self) -> np.ndarray:
        """float32 [S, H, W, 4]: every sample's color before the draw (a new array; see the module docstring)."""
        fb = self._unchanged_framebuffer("the whole before_color")
        return self._put_back(fb.samples_color.copy(), self.before.color)

    @property
    def before_depth(self) -> np.ndarray:
        """float32 [S, H, W]: every sample's depth before the draw (a new array; see the module docstring)."""
        fb = self._unchanged_framebuffer("the whole before_depth")
        return self._put_back(fb.samples_depth.copy(), self.before.depth)

    @property
    def before_stencil(self) -> np.ndarray:
        """uint8 [S, H, W]: every sample's stencil before the draw (a new array; see the module docstring)."""
        fb = self._unchanged_framebuffer("the whole before_stencil")
        return self._put_back(fb.samples_stencil.copy(), self.before.stencil)

    def stencil_before_at(self, x: int, y: int) -> np.ndarray:
        """uint8 [S]: the stencil of pixel (x, y)'s samples before the draw (known as :meth:`before_at`'s color)."""
        self._check_pixel(x, y)
        j = self.before.find(x, y, self.width)
        if j >= 0:
            return self.before.stencil[:, j].copy()
        fb = self._unchanged_framebuffer(f"pixel ({x}, {y}), which the draw did not touch")
        return fb.samples_stencil[:, y, x].copy()

    def _put_back(self, now: np.ndarray, kept: np.ndarray) -> np.ndarray:
        rows, cols = np.divmod(self.before.pixels, self.width)
        now[:, rows, cols] = kept
        return now

    def _unchanged_framebuffer(self, what: str):
        """The framebuffer, if nothing wrote into it after this draw (so it shows what the trace did not keep)."""
        fb = self.call.framebuffer
        if fb.writes != self.before.writes:
            raise ValueError(f"{what}: the trace keeps the framebuffer as it was before the draw only at the "
                             f"pixels the draw touched ({len(self.before.pixels):,} of them), and the framebuffer "
                             f"has been drawn into or cleared {fb.writes - self.before.writes} time(s) since; "
                             "ask trace.before_at(x, y) for a touched pixel, or keep fb.samples_color.copy() "
                             "before the draw")
        return fb

    # ------------------------------------------------------------- questions

    def __len__(self) -> int:
        return len(self.fragments)

    def __repr__(self) -> str:
        if self.visibility is not None:
            return (f"Trace(fast path: {self.vertex!r}; {self.primitives!r}; {self.visibility!r}; "
                    f"{self.shaded!r})")
        return (f"Trace({self.vertex!r}; {self.primitives!r}; {self.fragments!r}; {self.shaded!r}; "
                f"{self.merged!r})")

    @property
    def verdicts(self) -> np.ndarray:
        """Each fragment's verdict as a string array."""
        return np.array(VERDICTS)[self.merged.verdict] if len(self) else np.array([], dtype=str)

    def written(self) -> np.ndarray:
        """Boolean [F]: fragments whose color was written."""
        return self.merged.verdict == 0

    def at(self, x: int, y: int) -> np.ndarray:
        """Indices of the fragments at pixel (x, y) (image coordinates, row 0 at the top), in order."""
        self._check_pixel(x, y)
        return np.nonzero((self.fragments.x == x) & (self.fragments.y == y))[0]

    def _check_pixel(self, x, y):
        if not (0 <= x < self.width and 0 <= y < self.height):
            raise ValueError(f"pixel ({x}, {y}) is outside the {self.width}×{self.height} framebuffer")

    @property
    def fragment_shader(self):
        return self.call.fragment_shader or default_fragment_shader(self.primitives.layout)

    def fragment_inputs(self, index: int):
        """The shader's arguments for fragment ``index``: (varyings, uniforms, frag[, derivatives]),
        exactly as the compiled shader received them.

        Computed by the same generated interpolation code, run as plain Python.
        """
        return self._inputs(self._python_inputs(), index)

    def _python_inputs(self):
        """The generated fragment module as plain Python, made on first use: generating and exec-ing it
        takes milliseconds, longer than one fragment's inputs."""
        if self._python_module is None:
            self._python_module = kernels.python_fragment_module(self.fragment_shader, self.primitives.layout)
        return self._python_module

    def _inputs(self, module, index: int):
        f, p = self.fragments, self.primitives
        if not 0 <= index < len(f):
            raise IndexError(f"fragment index {index} out of range for {len(f)} fragments")
        if self._grad is None:
            self._grad = derivative_gradients(self.fragment_shader, f.setup)
        out = module.fragment_inputs(index, f.triangle, f.frag_x, f.frag_y, f.depth, f.bary, p.inv_w, p.varyings,
                                     p.front_facing, p.primitive_id, self._grad)
        return (plain_value(out[0]), self.call.uniforms) + tuple(plain_value(o) for o in out[1:])

    def fragment_varyings(self, indices) -> Tuple[np.ndarray, np.ndarray]:
        """The varyings and ``point_coord`` of many fragments in one compiled pass: (varyings float64
        [n, K], point_coord float64 [n, 2]), row r those of fragment ``indices[r]``.

        The columns are the Varyings' components in order (a tuple's in turn; K is the layout's
        width, or 1 for a layout without varyings: its one field ``none``, 0.0). The values are
        those :meth:`fragment_inputs` gives, bit for bit: the same generated ``fragment_inputs``,
        compiled, as the shader's loop runs it (``inputs_loop``, templates/fragment.py).
        """
        f, p = self.fragments, self.primitives
        rows = np.asarray(indices, dtype=np.int64).reshape(-1)
        bad = (rows < 0) | (rows >= len(f))
        if bad.any():
            raise IndexError(f"fragment index {int(rows[bad][0])} out of range for {len(f)} fragments")
        if self._grad is None:
            self._grad = derivative_gradients(self.fragment_shader, f.setup)
        shader = self.fragment_shader
        varyings = np.zeros((len(rows), max(p.layout.width, 1)))
        point_coord = np.zeros((len(rows), 2))
        if len(rows):
            loop = kernels.fragment_module(shader, p.layout).inputs_loop
            kernels.run_compiled("fragment", shader, loop, rows, f.triangle, f.frag_x, f.frag_y, f.depth, f.bary,
                                 p.inv_w, p.varyings, p.front_facing, p.primitive_id, self._grad, varyings, point_coord)
        return varyings, point_coord

    def debug_fragment(self, x: int, y: int, which: Optional[int] = None, sample: Optional[int] = None,
                       index: Optional[int] = None):
        """Re-run the fragment shader as plain Python on one fragment of pixel (x, y).

        By default the fragment whose color the pixel shows: the last one
        written (or the last one, if none was written). ``which`` picks among the
        pixel's fragments in order instead; ``index`` names a fragment directly
        (the ``#`` column of :meth:`pixel_history`). Put a breakpoint
        (``breakpoint()``) in your shader: it stops here, on this fragment.
        Returns the shader's RGBA, which equals what the compiled shader
        produced for that fragment: the shader's calls of ``math`` give NaN or
        infinity where Python's raise (``math.pow(-1, 0.5)``, ``math.exp(1000)``), as
        compiled code does (:func:`as_compiled_math`).
        """
        if index is None:
            idx = self.at(x, y)
            if sample is not None:
                idx = idx[self.fragments.sample[idx] == sample]
            if len(idx) == 0:
                raise ValueError(f"no fragment reached pixel ({x}, {y})")
            if which is None:
                written = idx[self.merged.verdict[idx] == 0]
                index = int(written[-1] if len(written) else idx[-1])
            else:
                index = int(idx[which])
        return as_compiled_math(python_function(self.fragment_shader))(*self.fragment_inputs(index))

    def pixel_history(self, x: int, y: int) -> PixelHistory:
        """Every fragment that touched pixel (x, y), in order, with what happened to it."""
        idx = self.at(x, y)
        module = self._python_inputs()
        f, s, m = self.fragments, self.shaded, self.merged
        assert m.color_after is not None    # a trace's merge keeps it (recorded)
        events = []
        kind = self.primitives.kind
        instance_of = self.primitives.instance
        stencil_on = self.call.state.stencil is not None and m.stencil_after is not None
        stencil_now = self.stencil_before_at(x, y).astype(int) if stencil_on and len(idx) else None
        more = _Replay(self, x, y) if len(s.outputs) and len(idx) else None
        for k in idx:
            inputs = self._inputs(module, int(k))
            varyings = inputs[0]
            events.append(PixelEvent(
                index=int(k), primitive_id=int(f.primitive_id[k]), triangle=int(f.triangle[k]),
                sample=int(f.sample[k]), depth=float(f.depth[k]), varyings=varyings,
                color=tuple(float(c) for c in s.color[k]), verdict=VERDICTS[m.verdict[k]],
                color_after=tuple(float(c) for c in m.color_after[k]),
                instance=int(instance_of[f.triangle[k]]) if instance_of is not None else 0))
            events[-1].shadow = self._shadow_terms(varyings)
            if stencil_now is not None and m.stencil_after is not None:   # before: the sample's last fragment's after
                sample = int(f.sample[k])
                events[-1].stencil = (int(stencil_now[sample]), int(m.stencil_after[k]))
                stencil_now[sample] = int(m.stencil_after[k])
            if kind != "triangles":         # what the shader saw: the very frag it was given
                events[-1].point_coord = tuple(float(c) for c in inputs[2].point_coord)
            if more is not None:
                events[-1].outputs, events[-1].outputs_after = more.fragment(int(k))
        if self.before.find(x, y, self.width) < 0 and self.call.framebuffer.writes != self.before.writes:
            before = None       # not touched, and the framebuffer has changed since: not kept (module docstring)
        else:
            before = tuple(float(c) for c in self.before_at(x, y)[0][0])
        return PixelHistory(x, y, events, before, kind, self.primitives.faces is not None,
                            self.primitives.instances)

    def _shadow_terms(self, varyings) -> tuple:
        """V_j of every light at the fragment's eye-space ``position`` varying (FORMULAS §21), as the lit
        programs compute it, when the draw's ``lighting`` uniform casts shadows; else ().

        The uniform answers it (``LightingUniform.visibilities``, softpipe.light.material): the
        pipeline knows no lighting, and asks any uniform that has the method.
        """
        visibilities = getattr(getattr(self.call.uniforms, "lighting", None), "visibilities", None)
        P = getattr(varyings, "position", None)
        if visibilities is None or P is None or len(P) != 3:
            return ()
        return visibilities(P)

    def shadow_terms(self, points) -> Optional[np.ndarray]:
        """V_j of every light at many eye-space points [N, 3] in one compiled pass: float64 [N, L, 3], row i
        equal to :meth:`pixel_history`'s ``shadow`` of a fragment whose ``position`` is points[i]; None
        when the draw casts no shadows (the uniform answers, ``LightingUniform.visibilities_at``)."""
        at = getattr(getattr(self.call.uniforms, "lighting", None), "visibilities_at", None)
        return None if at is None else at(np.asarray(points, dtype=np.float64).reshape(-1, 3))

    # ------------------------------------------------------------- pictures

    def pictures(self):
        """Every stage as a picture: a dict of name → [H, W, 3] uint8 (see :mod:`softpipe.views.pictures`)."""
        from softpipe.views.pictures import stage_pictures
        return stage_pictures(self)

    def _repr_png_(self) -> bytes:
        """In Jupyter a trace shows as the labelled contact sheet of its stages."""
        import io

        from softpipe.views.pictures import contact_sheet, stage_pictures
        buf = io.BytesIO()
        pics = stage_pictures(self)
        contact_sheet(pics, captions=pics.captions).save(buf, format="PNG")
        return buf.getvalue()

    def to_html(self, path, **options):
        """Write the pipeline explorer of this draw: one self-contained HTML page (:mod:`softpipe.views.explorer`).

        Point at a pixel to see its history, the winning triangle outlined in every stage
        picture and its vertices in object, clip and window coordinates. ``options`` are
        :func:`softpipe.views.explorer.write_explorer`'s; returns its summary (path, size, what it holds).
        """
        from softpipe.views.explorer import write_explorer
        return write_explorer(self, path, **options)

    def diff(self, other):
        """What changed from this draw to ``other`` (a Trace, a DrawResult, or a scene's list of either): a
        :class:`softpipe.views.diff.TraceDiff` (the pixels changed, by how much, each one's first differing fragment)."""
        from softpipe.views.diff import diff_draws
        return diff_draws(self, other)

    def mesh_table(self, pixel=None, vertices=None):
        """The draw's vertices in object, clip and window space (RenderDoc's mesh viewer); with ``pixel``
        (x, y), the corners of the triangle that won it: :func:`softpipe.views.mesh_view.mesh_table`."""
        from softpipe.views.mesh_view import mesh_table
        return mesh_table(self, pixel, vertices)

    def save_pictures(self, directory) -> dict:
        """Write every stage's picture and a labelled contact sheet as PNGs; returns name → path."""
        from softpipe.views.pictures import save_stage_pictures
        return save_stage_pictures(self, directory)


class _Replay:
    """The other color attachments of one pixel, fragment by fragment: each fragment's values and the sample's
    values after it, for :meth:`Trace.pixel_history`.

    The merger keeps no per-fragment record of locations 1, 2, … (only of location 0's color), so they are
    replayed here: from the pixel's samples before the draw, the merger's own :func:`merge_more` writes each
    fragment in turn into a one-pixel framebuffer of the same attachments and samples (the same blending,
    masks and order, so the same bits). On the fast path every fragment is a winner, written as it is: its
    value is the sample's.
    """

    def __init__(self, trace: "Trace", x: int, y: int):
        self.trace = trace
        self.names = [n for n, _ in trace.call.attachments[1:]]
        self.fast = trace.visibility is not None
        self.pixel = Framebuffer(1, 1, trace.pattern, attachments=dict(trace.call.attachments))
        if not self.fast:
            # a pixel a fragment reached is always kept (BeforeDraw: the pixels the fragments reached)
            j = trace.before.find(x, y, trace.width)
            for n in self.names:
                self.pixel.samples_attachment(n)[:, 0, 0] = trace.before.attachments[n][:, j]

    def fragment(self, k: int) -> Tuple[Dict[str, Any], Dict[str, Any]]:
        """(name → fragment ``k``'s value, name → its sample's value after it)."""
        t = self.trace
        f, s, m = t.fragments, t.shaded, t.merged
        values = {n: _plain(o[k]) for n, o in zip(self.names, s.outputs)}
        if self.fast:
            return values, dict(values)
        one = Fragments(np.zeros(1, f.x.dtype), np.zeros(1, f.y.dtype), f.sample[k:k + 1], f.depth[k:k + 1],
                        f.bary[k:k + 1], f.triangle[k:k + 1], f.primitive_id[k:k + 1])
        shaded = ShadedFragments(s.color[k:k + 1], s.discarded[k:k + 1], 1, tuple(o[k:k + 1] for o in s.outputs))
        merge_more(one, shaded, m.verdict[k:k + 1], self.pixel, t.call.attachment_states, t.call.state.blend_color)
        sample = int(f.sample[k])
        return values, {n: _plain(self.pixel.samples_attachment(n)[sample, 0, 0]) for n in self.names}


def _plain(value) -> Any:
    """An attachment's value as the history shows it: a tuple of 4 floats, a float (r32f) or an int (r32i)."""
    a = np.asarray(value)
    if a.ndim:
        return tuple(float(c) for c in a)
    return int(a) if np.issubdtype(a.dtype, np.integer) else float(a)


class _CompiledMath:
    """``math`` as compiled code has it: a function whose argument is out of its domain gives NaN, and one
    whose result overflows gives infinity, where Python's raise ValueError or OverflowError."""

    def __getattr__(self, name: str):
        value = getattr(math, name)
        if not callable(value):
            return value

        def call(*args):
            try:
                return value(*args)
            except ValueError:
                return math.nan
            except OverflowError:
                return math.inf
        return call


COMPILED_MATH = _CompiledMath()


def as_compiled_math(fn: Callable) -> Callable:
    """``fn`` (a plain function) reading :data:`COMPILED_MATH` for its module's ``math`` (and for the names
    it imported from math), so run as Python it gives the NaN and infinity its compiled loop gives.

    (Its own calls only: a helper it calls keeps Python's ``math``; and ``x ** 0.5`` of a negative
    float is a complex number in Python, NaN compiled.)
    """
    globals_ = dict(fn.__globals__)
    changed = False
    for name, value in fn.__globals__.items():
        if value is math:
            globals_[name], changed = COMPILED_MATH, True
        elif callable(value) and getattr(value, "__module__", None) == "math":
            globals_[name], changed = getattr(COMPILED_MATH, value.__name__), True
    if not changed:
        return fn
    copy = types.FunctionType(fn.__code__, globals_, fn.__name__, fn.__defaults__, fn.__closure__)
    copy.__kwdefaults__ = fn.__kwdefaults__
    return copy

