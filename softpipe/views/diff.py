"""The diff of two traced draws, or of two traced scenes: what a change did, pixel by pixel.

``trace_a.diff(trace_b)`` (or :func:`diff_draws` of two scenes' ``results``, as
``softpipe.render(..., trace=True, results=results)`` fills them) compares the same
scene drawn before and after a change — a shader, a state, a light — and answers
(:class:`TraceDiff`):

``changed``        bool [H, W]: the pixels where a sample's final color differs (a NaN
                   equals a NaN: a pixel NaN on both sides has not changed)
``delta``          float32 [H, W, 4]: B's final color − A's (the samples averaged, as
                   ``Framebuffer.color`` resolves them)
``first_difference(x, y)``  the first fragment of the pixel's history whose record
                   differs between A and B, the pair of :class:`~softpipe.pipeline.trace.PixelEvent`
                   and the field that differs (:data:`FIELDS`, compared in that order)
``picture()``      [H, W, 3] uint8: B's final picture dimmed, each changed pixel in
                   the overdraw picture's heat colors by how much it changed
                   (blue: a little, … white: 1 or more, or non-finite)

A pixel's history is every fragment of every draw at that pixel, in draw order (a
scene's draws are compared as one history, so the first difference can be a fragment of
a later draw). A trace's "final" color is the color its draws left: at the pixels a draw
touched it is the trace's own record (the color before, then each fragment's color
after); elsewhere the framebuffer's, while it has not been drawn into since; where it has
(a single draw of a scene, diffed after the scene went on), a pixel one side's draws did
not touch has the color the other side's draws started from there: the two are taken to
start from the same picture.

:func:`write_diff_page` writes the diff as one self-contained HTML page (``softpipe explore
--diff A B``): A's, B's and the diff picture, and for a chosen pixel the two histories side
by side.
"""
from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from softpipe.views.draws import traced_draws

__all__ = ["TraceDiff", "FragmentDifference", "FIELDS", "diff_draws", "write_diff_page", "diff_page_html", "PAGE_PIXELS"]

#: The fields of a fragment's record, in the order :meth:`TraceDiff.first_difference` compares them:
#: the draw it belongs to (a scene's), its input primitive, its sample, its depth, the varyings the
#: shader received, the shader's output, the merger's verdict, the stencil before and after it, the
#: sample's color after it. "fragment": one history has a fragment where the other has ended.
FIELDS = ("draw", "primitive", "sample", "depth", "varyings", "shader output", "verdict", "stencil",
          "color after", "fragment")


def _same(a: Any, b: Any) -> bool:
    """Equal, exactly, with NaN equal to NaN; tuples (and namedtuples: their names too) element by element."""
    if isinstance(a, tuple) or isinstance(b, tuple):
        if not (isinstance(a, tuple) and isinstance(b, tuple)) or len(a) != len(b):
            return False
        if getattr(a, "_fields", None) != getattr(b, "_fields", None):
            return False
        return all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (a != a and b != b)
    return bool(a == b)


def _shown(value: Any) -> str:
    """A field's value as the pixel history prints it: floats to 4 significant digits."""
    if isinstance(value, tuple):
        names = getattr(value, "_fields", None)
        items = [_shown(v) for v in value]
        if names:
            return "(" + ", ".join(f"{n}={v}" for n, v in zip(names, items)) + ")"
        return "(" + ", ".join(items) + ")"
    if isinstance(value, (float, np.floating)):
        return f"{value:.4g}"
    return str(value)


def _field_values(draw: int, e) -> dict:
    return {"draw": draw, "primitive": e.primitive_id, "sample": e.sample, "depth": e.depth,
            "varyings": e.varyings, "shader output": e.color, "verdict": e.verdict, "stencil": e.stencil,
            "color after": e.color_after}


@dataclass
class FragmentDifference:
    """The first fragment of pixel (x, y)'s history whose record differs between A and B.

    ``position``: its place in the pixel's history (0: the first fragment); ``draw_a``, ``draw_b``:
    the draw (0 for a single trace) of each; ``a``, ``b``: the two :class:`~softpipe.pipeline.trace.PixelEvent`
    (None on the side whose history has ended: ``field`` is then "fragment"); ``field``: the first of
    :data:`FIELDS` that differs; ``value_a``, ``value_b``: its two values.
    """

    x: int
    y: int
    position: int
    field: str
    a: Any
    b: Any
    draw_a: Optional[int]
    draw_b: Optional[int]
    value_a: Any
    value_b: Any

    def __str__(self) -> str:
        def side(e, draw, value):
            if e is None:
                return "no fragment"
            return f"fragment #{e.index} of draw {draw}, primitive {e.primitive_id}: {_shown(value)}"
        return (f"pixel ({self.x}, {self.y}): fragment {self.position} of its history differs in its "
                f"{self.field}: A {side(self.a, self.draw_a, self.value_a)}; B {side(self.b, self.draw_b, self.value_b)}")


def _as_traces(item, which: str) -> list:
    """The traces of a Trace, a DrawResult, or a sequence of either (a scene's ``results``)."""
    out = [t for _, t in traced_draws(item, f"diff: {which}")]
    w, h, s = out[0].width, out[0].height, out[0].call.framebuffer.samples
    for k, t in enumerate(out):
        if (t.width, t.height, t.call.framebuffer.samples) != (w, h, s):
            raise ValueError(f"diff: {which}, draw {k} is {t.width}×{t.height} with {t.call.framebuffer.samples} "
                             f"sample(s), its first {w}×{h} with {s}: the draws of one side share one framebuffer")
    return out


def _final(traces: list) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every sample's color after the draws, float32 [S, H, W, 4]; bool [H, W] where that is known; the color
    before the first draw that touched each pixel [S, H, W, 4], and bool [H, W] where that is known."""
    t0 = traces[0]
    h, w, s = t0.height, t0.width, t0.call.framebuffer.samples
    color = np.zeros((s, h, w, 4), np.float32)
    known = np.zeros((h, w), bool)
    for t in traces:
        rows, cols = np.divmod(t.before.pixels, w)
        new = ~known[rows, cols]
        color[:, rows[new], cols[new]] = t.before.color[:, new]
        known[rows[new], cols[new]] = True
        f = t.fragments
        if len(f):      # each sample's last fragment's color after (the reversed first of each sample)
            key = ((f.sample.astype(np.int64) * h + f.y) * w + f.x)[::-1]
            _, first = np.unique(key, return_index=True)
            last = len(f) - 1 - first
            color[f.sample[last], f.y[last], f.x[last]] = t.merged.color_after[last]
    start_known = known.copy()
    last_t = traces[-1]
    fb = last_t.call.framebuffer
    start = np.zeros_like(color)
    for t in reversed(traces):          # the first draw's record of a pixel wins: put it last
        rows, cols = np.divmod(t.before.pixels, w)
        start[:, rows, cols] = t.before.color
    if fb.writes == last_t.before.writes:       # unchanged since: it shows every pixel the draws left
        color[:, ~known] = fb.samples_color[:, ~known]
        start[:, ~start_known] = fb.samples_color[:, ~start_known]
        known[:] = True
        start_known[:] = True
    return color, known, start, start_known


def _resolve(samples: np.ndarray) -> np.ndarray:
    return samples.mean(axis=0, dtype=np.float64).astype(np.float32)


class TraceDiff:
    """What changed between two traced draws (or scenes), A and B: see the module docstring.

    Attributes
    ----------
    changed : bool [H, W]
    delta : float32 [H, W, 4]
        B's final color − A's.
    color_a, color_b : float32 [H, W, 4]
        The final colors compared (resolved).
    """

    def __init__(self, a, b) -> None:
        self.traces_a, self.traces_b = _as_traces(a, "A"), _as_traces(b, "B")
        ta, tb = self.traces_a[0], self.traces_b[0]
        if (ta.width, ta.height) != (tb.width, tb.height):
            raise ValueError(f"diff: A is {ta.width}×{ta.height}, B {tb.width}×{tb.height}: compare draws of the "
                             "same size")
        sa, sb = ta.call.framebuffer.samples, tb.call.framebuffer.samples
        if sa != sb:
            raise ValueError(f"diff: A has {sa} sample(s) per pixel, B {sb}: compare draws with the same samples")
        self.width, self.height = ta.width, ta.height
        ca, ka, start_a, sk_a = _final(self.traces_a)
        cb, kb, start_b, sk_b = _final(self.traces_b)
        fill_a = ~ka & sk_b                       # A did not touch it and its framebuffer moved on: B's start
        ca[:, fill_a] = start_b[:, fill_a]
        fill_b = ~kb & sk_a
        cb[:, fill_b] = start_a[:, fill_b]
        both_unknown = ~(ka | fill_a) & ~(kb | fill_b)
        cb[:, both_unknown] = ca[:, both_unknown]
        same = (ca == cb) | (np.isnan(ca) & np.isnan(cb))
        self.changed: np.ndarray = ~same.all(axis=(0, 3))
        self.color_a, self.color_b = _resolve(ca), _resolve(cb)
        with np.errstate(invalid="ignore"):
            self.delta: np.ndarray = np.where(self.changed[..., None], self.color_b - self.color_a,
                                              0.0).astype(np.float32)

    # ------------------------------------------------------------- the numbers

    @property
    def count(self) -> int:
        """How many pixels changed."""
        return int(self.changed.sum())

    def pixels(self) -> List[Tuple[int, int]]:
        """The changed pixels as (x, y), row by row."""
        ys, xs = np.nonzero(self.changed)
        return [(int(x), int(y)) for x, y in zip(xs, ys)]

    def magnitude(self) -> np.ndarray:
        """float64 [H, W]: the largest |Δ| of a pixel's four channels (inf where a side is non-finite)."""
        d = np.abs(self.delta.astype(np.float64))
        return np.nan_to_num(d, nan=np.inf).max(axis=2)

    # ------------------------------------------------------------- histories

    def _history(self, traces: list, x: int, y: int) -> list:
        events: list = []
        for k, t in enumerate(traces):
            if len(t.at(x, y)):
                events.extend((k, e) for e in t.pixel_history(x, y))
        return events

    def histories(self, x: int, y: int) -> Tuple[list, list]:
        """The two histories of pixel (x, y): lists of (draw, :class:`~softpipe.pipeline.trace.PixelEvent`)."""
        if not (0 <= x < self.width and 0 <= y < self.height):
            raise ValueError(f"diff: pixel ({x}, {y}) is outside the {self.width}×{self.height} framebuffer")
        return self._history(self.traces_a, x, y), self._history(self.traces_b, x, y)

    def first_difference(self, x: int, y: int) -> Optional[FragmentDifference]:
        """The first fragment of pixel (x, y)'s history whose record differs (:data:`FIELDS`), or None when
        the two histories are the same, fragment for fragment."""
        ha, hb = self.histories(x, y)
        for k in range(max(len(ha), len(hb))):
            if k >= len(ha) or k >= len(hb):
                da, ea = ha[k] if k < len(ha) else (None, None)
                db, eb = hb[k] if k < len(hb) else (None, None)
                return FragmentDifference(x, y, k, "fragment", ea, eb, da, db,
                                          "present" if ea else "none", "present" if eb else "none")
            (da, ea), (db, eb) = ha[k], hb[k]
            va, vb = _field_values(da, ea), _field_values(db, eb)
            for name in FIELDS[:-1]:
                if not _same(va[name], vb[name]):
                    return FragmentDifference(x, y, k, name, ea, eb, da, db, va[name], vb[name])
        return None

    # ------------------------------------------------------------- showing it

    def picture(self) -> np.ndarray:
        """[H, W, 3] uint8: B's final picture at a third of its brightness, each changed pixel colored by
        :meth:`magnitude` on the overdraw picture's heat colors: 1 + 5·|Δ| (blue a little, green 0.2, yellow
        0.4, red 0.6, pink 0.8, white 1 or more or non-finite)."""
        from softpipe.views.pictures import heat_colors
        c = np.clip(np.nan_to_num(self.color_b[..., :3].astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0), 0, 1)
        img = np.round(c * 255 / 3).astype(np.uint8)
        m = self.magnitude()
        img[self.changed] = heat_colors(1.0 + 5.0 * np.minimum(m[self.changed], 1.0))
        return img

    def summary(self) -> str:
        """One paragraph: how many pixels changed, by how much, and where the largest change is."""
        n, total = self.count, self.width * self.height
        head = (f"{len(self.traces_a)} draw(s) against {len(self.traces_b)}, {self.width}×{self.height}: ")
        if not n:
            return head + "no pixel changed"
        m = self.magnitude()
        y, x = np.unravel_index(int(np.argmax(np.where(self.changed, m, -1.0))), m.shape)
        finite = m[self.changed][np.isfinite(m[self.changed])]
        mean = f"{finite.mean():.4g}" if len(finite) else "non-finite"
        return (head + f"{n} pixel(s) changed ({100.0 * n / total:.3g}%); the largest change |Δ| = {m[y, x]:.4g} "
                f"at ({x}, {y}); mean |Δ| over the changed pixels {mean}")

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        return f"TraceDiff({self.summary()})"

    def _repr_png_(self) -> bytes:
        from PIL import Image
        buf = io.BytesIO()
        Image.fromarray(self.picture()).save(buf, format="PNG")
        return buf.getvalue()


def diff_draws(a, b) -> TraceDiff:
    """The diff of A and B: each a :class:`~softpipe.pipeline.trace.Trace`, a DrawResult drawn with
    ``trace=True``, or a list of either (a scene's draws into one framebuffer, in order).

    Raises TypeError for an item that is no trace, ValueError for sides of different sizes or samples.
    """
    return TraceDiff(a, b)


# ---------------------------------------------------------------------------- the page


def _png(img: np.ndarray) -> str:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _to_uint8(color: np.ndarray) -> np.ndarray:
    c = np.clip(np.nan_to_num(color[..., :3].astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0), 0, 1)
    return np.round(c * 255).astype(np.uint8)


def _history_table(events: list, mark: Optional[int]) -> str:
    if not events:
        return "<p>no fragment</p>"
    names = list(FIELDS[:-1])
    rows = ["<table><tr><th>#</th>" + "".join(f"<th>{html.escape(n)}</th>" for n in names) + "</tr>"]
    for k, (draw, e) in enumerate(events):
        v = _field_values(draw, e)
        style = ' class="first"' if k == mark else ""
        cells = "".join(f"<td>{html.escape(_shown(v[n]))}</td>" for n in names)
        rows.append(f"<tr{style}><td>{e.index}</td>{cells}</tr>")
    return "\n".join(rows + ["</table>"])


#: How many changed pixels the page lists with their first difference (each asks both histories).
PAGE_PIXELS = 12


def diff_page_html(diff: TraceDiff, pixel: Optional[Tuple[int, int]] = None, *, title: str = "softpipe diff",
                   names: Sequence[str] = ("A", "B")) -> str:
    """The diff as one self-contained HTML page (see :func:`write_diff_page`)."""
    if pixel is None:
        changed = diff.pixels()
        pixel = changed[0] if changed else None
    first = diff.first_difference(*pixel) if pixel is not None else None
    esc = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{esc(title)}</title><style>"
             "body{font-family:sans-serif;background:#18181c;color:#ddd}img{image-rendering:pixelated;"
             "width:min(30vw,480px);margin:4px}table{border-collapse:collapse;font-size:12px}"
             "td,th{border:1px solid #444;padding:2px 4px}tr.first{background:#633}"
             ".side{display:inline-block;vertical-align:top;margin:6px}</style></head><body>",
             f"<h1>{esc(title)}</h1><p id='summary'>{esc(diff.summary())}</p>"]
    for label, img in ((f"A: {names[0]}", _to_uint8(diff.color_a)), (f"B: {names[1]}", _to_uint8(diff.color_b)),
                       ("changed pixels", diff.picture())):
        parts.append(f"<figure class='side'><img alt='{esc(label)}' src='{_png(img)}'>"
                     f"<figcaption>{esc(label)}</figcaption></figure>")
    if pixel is not None:
        ha, hb = diff.histories(*pixel)
        mark = first.position if first is not None else None
        parts.append(f"<h2 id='pixel'>pixel {pixel}</h2><p id='first'>"
                     f"{esc(str(first)) if first else 'the two histories are the same'}</p>")
        parts.append(f"<div class='side'><h3>A: {esc(names[0])}</h3>{_history_table(ha, mark)}</div>"
                     f"<div class='side'><h3>B: {esc(names[1])}</h3>{_history_table(hb, mark)}</div>")
    listed = diff.pixels()[:PAGE_PIXELS]
    if listed:
        parts.append(f"<h2>the first {len(listed)} changed pixel(s) of {diff.count}</h2><ul id='changed'>")
        for x, y in listed:
            d = diff.first_difference(x, y)
            parts.append(f"<li>{esc(str(d) if d else f'pixel ({x}, {y}): the same histories')}</li>")
        parts.append("</ul>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_diff_page(diff: TraceDiff, path, pixel: Optional[Tuple[int, int]] = None, *, title: str = "softpipe diff",
                    names: Sequence[str] = ("A", "B")) -> Path:
    """Write the diff's page to ``path`` (whole or not at all): A's and B's final pictures, the changed
    pixels (:meth:`TraceDiff.picture`), the two histories of ``pixel`` (x, y) side by side with the first
    fragment that differs marked (default: the first changed pixel, row by row), and the first difference of
    the first :data:`PAGE_PIXELS` changed pixels. Returns the path."""
    from softpipe.core.files import atomic_write
    if pixel is not None:
        x, y = pixel
        if not (0 <= x < diff.width and 0 <= y < diff.height):
            raise ValueError(f"diff page: pixel ({x}, {y}) is outside the {diff.width}×{diff.height} picture")
    page = diff_page_html(diff, pixel, title=title, names=names).encode("utf-8")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: f.write(page))
    return path
