"""The pipeline explorer: a traced draw (or a scene's draws) as one self-contained HTML page.

``softpipe explore bunny -o report.html``, ``trace.to_html("report.html")`` or
``write_explorer(results, "report.html")`` write one HTML file that needs no server and
no network: the stage pictures (:mod:`softpipe.views.pictures`) are embedded as PNG data URLs,
the script is plain JavaScript in the page, and the data is one JSON block whose arrays
are little-endian binary, zlib-compressed and base64-encoded (the page inflates them with
the browser's own ``DecompressionStream``).

Click (or hover, with "follow the mouse") a pixel of any picture: the page shows the
pixel's history (every fragment of every draw at that pixel, in order, as
:meth:`softpipe.pipeline.trace.Trace.pixel_history` gives it), outlines the winning triangle in
every picture in window space, and lists its three vertices in object, clip and window
coordinates. Arrow keys move the selected pixel (Shift: by 10); the zoom shows the
pixels around it with their centres, the sample positions and the triangle's edges.

What the page holds
-------------------
``win``          uint32 per pixel: the post-clip triangle (numbered across the draws) of
                 the last fragment written there, + 1 (0: nothing was written): every pixel
``histories``    every fragment of every pixel with at most ``max_fragments`` fragments in
                 all; beyond that, the pixels of a regular grid (every s-th column and row,
                 the smallest s that fits), and the page says so
``triangles``    for every triangle named by ``win`` or a history: its input triangle
                 (primitive id) and that triangle's three vertices in object, clip and
                 window coordinates; and for a piece that clipping cut, its own window corners

Numbers are stored at the precision the pipeline made them where that is small: depth
as float64, the shader's output and the color after as float32 (what the pipeline
holds), the varyings and V_j as float32 (the page prints them to 4 and 3 significant
digits). :func:`read_explorer` reads a page's data back in Python (the tests compare it
with ``pixel_history``).
"""
from __future__ import annotations

import base64
import html
import io
import json
import re
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

__all__ = ["write_explorer", "explorer_html", "read_explorer", "ExplorerData", "ExplorerSummary",
           "MAX_FRAGMENTS"]

#: Fragments whose whole history the page holds, by default (about 140 bytes each, compressed).
MAX_FRAGMENTS = 400_000

#: The verdicts, as :data:`softpipe.pipeline.output.VERDICTS` names them (index = the stored code).
_VERDICTS = ("written", "depth-failed", "discarded")


# ---------------------------------------------------------------------------- inputs


def _traces(traces_or_results) -> List[tuple]:
    """(name, program, trace) for a Trace, a DrawResult or a sequence of either."""
    items = traces_or_results
    if not isinstance(items, (list, tuple)):
        items = [items]
    out = []
    for k, item in enumerate(items):
        trace = getattr(item, "trace", None) if hasattr(item, "program") else item
        if trace is None or not hasattr(trace, "pixel_history"):
            raise TypeError(f"item {k}: expected a Trace or a DrawResult drawn with trace=True, got "
                            f"{type(item).__name__}")
        name = getattr(item, "name", "") or f"draw {k + 1}"
        program = getattr(item, "program", "") or getattr(trace.fragment_shader, "__name__", "")
        out.append((name, program, trace))
    if not out:
        raise ValueError("nothing to explore: no traces")
    w, h = out[0][2].width, out[0][2].height
    for name, _, t in out:
        if (t.width, t.height) != (w, h):
            raise ValueError(f"draw {name!r} is {t.width}×{t.height}, the first {w}×{h}: the draws of one page "
                             "share one framebuffer")
    return out


# ---------------------------------------------------------------------------- arrays


def _array(a: np.ndarray, dtype: str) -> dict:
    """An array as the page stores it: little-endian ``dtype``, zlib, base64, in the smaller of four layouts.

    ``columns``: an [N, ...] array stored component by component (all the x, then all the
    y, …); ``shuffle``: all the items' first bytes, then all their second bytes, … (so a
    float's sign and exponent bytes, which vary little, sit together). Either or both.
    """
    a = np.ascontiguousarray(np.asarray(a).astype("<" + dtype))
    best = None
    for columns in ((False, True) if a.ndim > 1 and a.size else (False,)):
        b = np.ascontiguousarray(a.reshape(len(a), -1).T) if columns else a
        for shuffle in ((False, True) if a.itemsize > 1 else (False,)):
            raw = b.reshape(-1).view(np.uint8)
            raw = raw.reshape(-1, a.itemsize).T.tobytes() if shuffle else raw.tobytes()
            z = zlib.compress(raw, 6)
            if best is None or len(z) < len(best[0]):
                best = (z, columns, shuffle, raw)
    return {"dtype": dtype, "shape": list(a.shape), "columns": best[1], "shuffle": best[2],
            "b64": base64.b64encode(zlib.compress(best[3], 9)).decode("ascii")}


def _unarray(d: dict) -> np.ndarray:
    raw = np.frombuffer(zlib.decompress(base64.b64decode(d["b64"])), np.uint8)
    size = np.dtype(d["dtype"]).itemsize
    if d["shuffle"]:
        raw = raw.reshape(size, -1).T
    a = np.ascontiguousarray(raw).view("<" + d["dtype"]).reshape(-1)
    shape = d["shape"]
    if d["columns"]:
        a = a.reshape(-1, shape[0]).T
    return np.ascontiguousarray(a).reshape(shape)


def _png(img: np.ndarray) -> str:
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", optimize=True)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


# ---------------------------------------------------------------------------- pictures


def _pictures(draws) -> Dict[str, np.ndarray]:
    """The stage pictures of one draw, or of several drawn into one framebuffer, composed."""
    from softpipe.views import pictures as P
    if len(draws) == 1:
        return P.stage_pictures(draws[0][2])
    traces = [t for _, _, t in draws]
    h, w = traces[0].height, traces[0].width
    each = [P.stage_pictures(t) for t in traces]
    pics: Dict[str, np.ndarray] = {}
    img = np.zeros((h, w, 3), np.uint8)
    for p in each:                                      # a later draw's dots over an earlier's
        lit = p["vertices"].any(axis=2)
        img[lit] = p["vertices"][lit]
    pics["vertices"] = img
    img = np.zeros((h, w, 3), np.uint8)                 # layer by layer across the draws, as for one
    for t in traces:
        P._wire(img, t.primitives.culled_window, h, P.RED)
    for t in traces:
        P._wire(img, P._cut_outlines(t), h, P.ORANGE)
    for t in traces:
        P._wire(img, t.primitives.window[~t.primitives.clipped], h, P.WHITE)
    for t in traces:
        P._wire(img, t.primitives.window[t.primitives.clipped], h, P.CYAN)
    pics["primitives"] = img
    img = np.zeros((h, w, 3), np.uint8)                 # the last fragment written, across the draws
    offset = 0
    for t in traces:
        f, wr = t.fragments, t.written()
        if wr.any():
            img[f.y[wr], f.x[wr]] = P._id_colors(offset + f.primitive_id[wr])
        offset += int(t.primitives.input_count)
    pics["coverage"] = img
    pics["depth"] = each[-1]["depth"]                   # one framebuffer: its depth and color after the last
    pics["overdraw"] = P._heat(sum(P.overdraw(t) for t in traces))
    pics["final"] = each[-1]["final"]
    for p in each:
        for name, img in p.items():
            if name not in pics:
                pics[name] = img
    return pics


# ---------------------------------------------------------------------------- the data


def _history_pixels(traces, max_fragments: int):
    """The pixels whose history the page holds, and the grid step s (1: every covered pixel)."""
    w = traces[0].width
    pix = np.concatenate([t.fragments.y.astype(np.int64) * w + t.fragments.x for t in traces]) \
        if traces else np.zeros(0, np.int64)
    uniq, n = np.unique(pix, return_counts=True)
    if n.sum() <= max_fragments:
        return uniq, n, 1
    x, y = uniq % w, uniq // w
    for s in range(2, 1 << 16):
        keep = (x % s == 0) & (y % s == 0)
        if n[keep].sum() <= max_fragments:
            return uniq[keep], n[keep], s
    return uniq[:0], n[:0], 0


def _varyings_flat(v) -> List[float]:
    out: List[float] = []
    for item in v:
        if isinstance(item, tuple):
            out.extend(float(c) for c in item)
        else:
            out.append(float(item))
    return out


def explorer_data(traces_or_results, *, max_fragments: int = MAX_FRAGMENTS, title: Optional[str] = None,
                  progress=None) -> dict:
    """The page's data (see the module docstring) as a JSON-ready dict, with the pictures."""
    from softpipe.language import kernels
    from softpipe.pipeline.assembly import triangle_indices

    draws = _traces(traces_or_results)
    traces = [t for _, _, t in draws]
    w, h = traces[0].width, traces[0].height
    tri_offset = np.cumsum([0] + [len(t.primitives) for t in traces])

    # --- the winning triangle of every pixel: the last fragment written, in draw order
    win = np.zeros(w * h, np.uint32)
    for k, t in enumerate(traces):
        f, wr = t.fragments, t.written()
        pix = (f.y[wr].astype(np.int64) * w + f.x[wr])[::-1]
        tri = f.triangle[wr][::-1]
        uniq, first = np.unique(pix, return_index=True)     # first of the reversed = last written
        win[uniq] = tri_offset[k] + tri[first] + 1

    # --- the histories
    hp, hn, step = _history_pixels(traces, max_fragments)
    keep_pixel = np.zeros(w * h, bool)
    keep_pixel[hp] = True
    layouts = [[(n, s) for n, _, s, _ in t.primitives.layout.fields] for t in traces]
    kmax = max([sum(s for _, s in lay) for lay in layouts] + [1])
    rows = []                                               # (pixel, draw, index) of every held fragment
    for k, t in enumerate(traces):
        f = t.fragments
        pix = f.y.astype(np.int64) * w + f.x
        idx = np.nonzero(keep_pixel[pix])[0]
        rows.append(np.stack([pix[idx], np.full(len(idx), k), idx], axis=1))
    rows = np.concatenate(rows) if rows else np.zeros((0, 3), np.int64)
    rows = rows[np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))]
    F = len(rows)
    vary = np.full((F, kmax), np.nan)
    shadow_cols = []
    shadows: Dict[int, list] = {}
    color = np.zeros((F, 4), np.float32)
    after = np.zeros((F, 4), np.float32)
    depth = np.zeros(F)
    verdict = np.zeros(F, np.uint8)
    prim = np.zeros(F, np.int64)
    tri = np.zeros(F, np.int64)
    sample = np.zeros(F, np.int64)
    done = 0
    for k, t in enumerate(traces):
        sel = np.nonzero(rows[:, 1] == k)[0]
        if not len(sel):
            shadow_cols.append(0)
            continue
        idx = rows[sel, 2]
        f = t.fragments
        depth[sel], prim[sel], tri[sel], sample[sel] = f.depth[idx], f.primitive_id[idx], f.triangle[idx], \
            f.sample[idx]
        color[sel], after[sel], verdict[sel] = t.shaded.color[idx], t.merged.color_after[idx], t.merged.verdict[idx]
        module = kernels.python_fragment_module(t.fragment_shader, t.primitives.layout)
        ncols = 0
        for r, i in zip(sel, idx):                           # the very code pixel_history runs, per fragment
            v = t._inputs(module, int(i))[0]
            flat = _varyings_flat(v)
            vary[r, :len(flat)] = flat
            s = t._shadow_terms(v)
            if s:
                shadows[int(r)] = s
                ncols = max(ncols, len(s))
            done += 1
            if progress is not None and done % 20000 == 0:
                progress(done, F)
        shadow_cols.append(ncols)
    lmax = max(shadow_cols + [0])
    shadow = np.full((F, max(lmax, 1), 3), np.nan, np.float32)
    for r, s in shadows.items():
        shadow[r, :len(s)] = s
    same = (color == after).all(axis=1)                     # the color after is the shader's, mostly: once
    hpix, hstart = np.unique(rows[:, 0], return_index=True)
    hstart = np.append(hstart, F)
    before = np.zeros((len(hpix), 4), np.float32)
    for j, (p, r) in enumerate(zip(hpix, hstart[:-1])):
        t = traces[int(rows[r, 1])]
        before[j] = t.before_color[0, p // w, p % w]

    # --- the triangles named by the map or a history, and their vertices in every space
    gid = np.unique(np.concatenate([win[win > 0].astype(np.int64) - 1, tri_offset[rows[:, 1]] + tri]))
    t_draw = np.searchsorted(tri_offset, gid, side="right") - 1
    t_window = np.zeros((len(gid), 3, 3))
    t_prim = np.zeros(len(gid), np.int64)
    t_clipped = np.zeros(len(gid), np.uint8)
    t_vindex = np.zeros((len(gid), 3), np.int64)
    t_vert = np.zeros((len(gid), 3), np.int64)
    v_obj, v_clip, v_win = [], [], []
    nv = 0
    for k, t in enumerate(traces):
        sel = np.nonzero(t_draw == k)[0]
        if not len(sel):
            continue
        local = gid[sel] - tri_offset[k]
        p = t.primitives
        t_window[sel] = p.window[local]
        t_prim[sel] = p.primitive_id[local]
        t_clipped[sel] = p.clipped[local]
        call = t.call
        corners = triangle_indices(call.topology, call.indices, len(t.vertex.position))[t_prim[sel]]
        t_vindex[sel] = corners
        used, inverse = np.unique(corners, return_inverse=True)
        t_vert[sel] = nv + inverse.reshape(-1, 3)
        nv += len(used)
        obj = np.full((len(used), 4), np.nan)
        given = np.asarray(call.positions, dtype=np.float64)
        obj[:, :given.shape[1]] = given[used][:, :4]
        clip = t.vertex.position[used]
        win_xyz = np.full((len(used), 3), np.nan)
        ok = clip[:, 3] > 0
        if ok.any():
            win_xyz[ok] = call.viewport.apply(clip[ok, :3] / clip[ok, 3:4])
        v_obj.append(obj), v_clip.append(clip), v_win.append(win_xyz)
    cat = lambda parts, n: np.concatenate(parts) if parts else np.zeros((0, n))  # noqa: E731

    pics = _pictures(draws)
    held = len(hpix)
    covered = int(len(np.unique(np.concatenate([t.fragments.y.astype(np.int64) * w + t.fragments.x
                                                for t in traces]))))
    total_fragments = int(sum(len(t) for t in traces))
    if step == 1:
        statement = (f"the history of every covered pixel: {held} pixels, {F} fragments "
                     f"(the limit is {max_fragments} fragments)")
    else:
        statement = (f"the draws made {total_fragments} fragments, more than the limit of {max_fragments}: the "
                     f"page holds the history of the pixels whose column and row are multiples of {step} ({held} of "
                     f"{covered} covered pixels, {F} fragments); every pixel still has its winning triangle")
    pattern = traces[0].pattern
    meta = {
        "format": "softpipe-explorer 1",
        "title": title or " + ".join(n for n, _, _ in draws),
        "width": w, "height": h,
        "pattern": {"name": getattr(pattern, "name", ""), "positions": np.asarray(pattern.positions).tolist()},
        "draws": [{"name": n, "program": prog, "path": t.path, "fragments": int(len(t)),
                   "triangles": int(len(t.primitives)), "input_triangles": int(t.primitives.input_count),
                   "tri_offset": int(tri_offset[k]), "varyings": [[a, int(b)] for a, b in layouts[k]],
                   "shadow_lights": int(shadow_cols[k]),
                   "object_space": "object" if t.call.vertex_shader is not None else "given (clip)",
                   "vertices": int(len(t.vertex.position))}
                  for k, (n, prog, t) in enumerate(draws)],
        "verdicts": list(_VERDICTS),
        "held": {"statement": statement, "step": step, "pixels": int(held), "fragments": int(F),
                 "covered_pixels": covered, "total_fragments": total_fragments, "limit": int(max_fragments)},
        "pictures": [{"name": n, "outline": not n.startswith("shadow map")} for n in pics],
    }
    arrays = {
        "win": _array(win, "u4"),
        "h_pixel": _array(hpix, "u4"), "h_start": _array(hstart, "u4"), "h_before": _array(before, "f4"),
        "f_draw": _array(rows[:, 1], "u2"), "f_index": _array(rows[:, 2], "u4"), "f_prim": _array(prim, "u4"),
        "f_tri": _array(tri, "u4"), "f_sample": _array(sample, "u1"), "f_depth": _array(depth, "f8"),
        "f_verdict": _array(verdict, "u1"), "f_color": _array(color, "f4"), "f_after_same": _array(same, "u1"),
        "f_after": _array(after[~same], "f4"),
        "f_vary": _array(vary, "f4"), "f_shadow": _array(shadow, "f4"),
        "t_id": _array(gid, "u4"), "t_window": _array(t_window[t_clipped == 1], "f4"), "t_prim": _array(t_prim, "u4"),
        "t_clipped": _array(t_clipped, "u1"), "t_vindex": _array(t_vindex, "u4"), "t_vert": _array(t_vert, "u4"),
        "v_obj": _array(cat(v_obj, 4), "f4"), "v_clip": _array(cat(v_clip, 4), "f4"),
        "v_win": _array(cat(v_win, 3), "f4"),
    }
    meta["arrays"] = arrays
    return {"meta": meta, "pictures": pics}


# ---------------------------------------------------------------------------- the page


def explorer_html(traces_or_results, *, max_fragments: int = MAX_FRAGMENTS, title: Optional[str] = None,
                  progress=None) -> str:
    """The page as a string (see :func:`write_explorer`)."""
    data = explorer_data(traces_or_results, max_fragments=max_fragments, title=title, progress=progress)
    meta, pics = data["meta"], data["pictures"]
    images = "\n".join(f'<img id="pic-{k}" alt="{html.escape(name)}" src="{_png(img)}">'
                       for k, (name, img) in enumerate(pics.items()))
    blob = json.dumps(meta, separators=(",", ":")).replace("<", "\\u003c").replace(">", "\\u003e")
    page = _TEMPLATE.replace("__TITLE__", html.escape(meta["title"]))
    page = page.replace("__STYLE__", _STYLE).replace("__SCRIPT__", _SCRIPT)
    page = page.replace("__IMAGES__", images).replace("__DATA__", blob)
    return page


@dataclass
class ExplorerSummary:
    """What :func:`write_explorer` wrote: where, how big, and what the page holds."""

    path: Path
    bytes: int
    held: Dict[str, Any]
    parts: Dict[str, int] = field(default_factory=dict)   # bytes of: pictures, data, script and style

    def __str__(self) -> str:
        parts = ", ".join(f"{k} {v / 1e6:.2f} MB" for k, v in self.parts.items())
        return f"{self.path}: {self.bytes / 1e6:.2f} MB ({parts}); {self.held['statement']}"


def write_explorer(traces_or_results, path, *, max_fragments: int = MAX_FRAGMENTS, title: Optional[str] = None,
                   progress=None) -> ExplorerSummary:
    """Write the explorer page of one draw or of several (a scene) to ``path``.

    Parameters
    ----------
    traces_or_results : Trace, DrawResult, or a sequence of them
        The draws, in the order they were drawn into one framebuffer
        (``softpipe.render(model, trace=True, results=results)`` fills ``results``).
    path : str or path-like
        The HTML file, written whole or not at all (:func:`softpipe.core.files.atomic_write`).
    max_fragments : int
        The page holds every pixel's history while the draws made at most this many
        fragments; beyond it, the pixels of a regular grid (the page says which).
    title : str, optional
    progress : callable, optional
        ``progress(done, total)`` every 20 000 fragments gathered.
    """
    from softpipe.core.files import atomic_write
    page = explorer_html(traces_or_results, max_fragments=max_fragments, title=title, progress=progress)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    raw = page.encode("utf-8")
    atomic_write(path, lambda f: f.write(raw))
    data = re.search(r'<script type="application/json" id="softpipe-data">(.*?)</script>', page, re.S)
    pictures = sum(len(m) for m in re.findall(r'src="data:image/png;base64,[^"]*"', page))
    d = len(data.group(1)) if data else 0
    held = json.loads(data.group(1))["held"] if data else {}
    return ExplorerSummary(path, len(raw), held, {"pictures": pictures, "data": d,
                                                  "script and style": len(raw) - pictures - d})


# ---------------------------------------------------------------------------- reading a page back


class ExplorerData:
    """A page's embedded data, decoded: ``meta`` (the JSON), ``arrays`` (numpy) and :meth:`history`."""

    def __init__(self, meta: dict):
        self.meta = meta
        self.arrays = {k: _unarray(v) for k, v in meta["arrays"].items()}
        same = self.arrays.pop("f_after_same").astype(bool)
        after = np.array(self.arrays["f_color"])
        after[~same] = self.arrays["f_after"]
        self.arrays["f_after"] = after
        self.width, self.height = meta["width"], meta["height"]

    @classmethod
    def from_html(cls, text: str) -> "ExplorerData":
        m = re.search(r'<script type="application/json" id="softpipe-data">(.*?)</script>', text, re.S)
        if not m:
            raise ValueError("not a softpipe explorer page: no softpipe-data block")
        return cls(json.loads(m.group(1)))

    def winner(self, x: int, y: int) -> Optional[tuple]:
        """(draw, post-clip triangle) of the last fragment written at pixel (x, y), or None."""
        g = int(self.arrays["win"][y * self.width + x])
        if g == 0:
            return None
        offsets = [d["tri_offset"] for d in self.meta["draws"]]
        k = int(np.searchsorted(offsets, g - 1, side="right") - 1)
        return k, g - 1 - offsets[k]

    def history(self, x: int, y: int) -> Optional[List[dict]]:
        """The held history of pixel (x, y) (a list of dicts, one per fragment), or None if not held."""
        a = self.arrays
        p = y * self.width + x
        j = int(np.searchsorted(a["h_pixel"], p))
        if j >= len(a["h_pixel"]) or a["h_pixel"][j] != p:
            return None
        out = []
        for r in range(int(a["h_start"][j]), int(a["h_start"][j + 1])):
            k = int(a["f_draw"][r])
            d = self.meta["draws"][k]
            flat, varyings, o = a["f_vary"][r], {}, 0
            for name, size in d["varyings"]:
                varyings[name] = float(flat[o]) if size == 1 else tuple(float(c) for c in flat[o:o + size])
                o += size
            shadow = tuple(tuple(float(c) for c in a["f_shadow"][r, i]) for i in range(d["shadow_lights"]))
            out.append({"draw": k, "name": d["name"], "index": int(a["f_index"][r]),
                        "primitive_id": int(a["f_prim"][r]), "triangle": int(a["f_tri"][r]),
                        "sample": int(a["f_sample"][r]), "depth": float(a["f_depth"][r]), "varyings": varyings,
                        "color": tuple(float(c) for c in a["f_color"][r]),
                        "verdict": self.meta["verdicts"][int(a["f_verdict"][r])],
                        "color_after": tuple(float(c) for c in a["f_after"][r]), "shadow": shadow,
                        "before": tuple(float(c) for c in a["h_before"][j])})
        return out


def read_explorer(path) -> ExplorerData:
    """The data embedded in an explorer page written by :func:`write_explorer`."""
    return ExplorerData.from_html(Path(path).read_text(encoding="utf-8"))


# ---------------------------------------------------------------------------- the page's text

_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>softpipe explorer: __TITLE__</title>
<style>__STYLE__</style>
</head>
<body>
<header>
  <h1>softpipe explorer: <span id="title">__TITLE__</span></h1>
  <p id="summary"></p>
  <p id="held"></p>
</header>
<main>
  <section id="view">
    <nav id="tabs" aria-label="stage pictures"></nav>
    <div id="stage-wrap"><canvas id="stage" tabindex="0" aria-label="the selected stage picture"></canvas></div>
    <p class="hint">Click a pixel (or tick "follow the mouse"); arrow keys move it, Shift+arrow by 10.
      <label><input type="checkbox" id="follow"> follow the mouse</label>
      <span id="hover"></span></p>
  </section>
  <aside id="side">
    <h2 id="pixel" data-x="" data-y="">no pixel selected</h2>
    <div id="zoom-wrap"><canvas id="zoom" width="264" height="264" aria-label="zoom"></canvas>
      <p class="hint">Zoom: 11×11 pixels around the selection. + pixel centre, ○ sample position
        (filled: a fragment written there, red ring: depth-failed); the outline: the triangle.</p></div>
    <h3>Triangle</h3>
    <div id="triangle">—</div>
  </aside>
</main>
<section id="history-section">
  <h2>Pixel history</h2>
  <p id="before"></p>
  <div class="scroll"><table id="history"><thead></thead><tbody></tbody></table></div>
  <p class="hint">One row per fragment, in the order the draws made them. The winner (the last fragment
    written) is marked ★; click a row to outline that fragment's triangle instead.</p>
</section>
<div id="images" hidden>
__IMAGES__
</div>
<script type="application/json" id="softpipe-data">__DATA__</script>
<script>__SCRIPT__</script>
</body>
</html>
"""

_STYLE = """
body{font:14px/1.4 system-ui,-apple-system,"Segoe UI",sans-serif;margin:0;background:#16181d;color:#e4e4e4}
header{padding:8px 16px;border-bottom:1px solid #333}
h1{font-size:18px;margin:4px 0}h2{font-size:16px;margin:8px 0}h3{font-size:14px;margin:8px 0 4px}
#summary,#held,.hint{color:#aaa;margin:2px 0;font-size:12px}
main{display:grid;grid-template-columns:minmax(320px,1fr) 420px;gap:16px;padding:8px 16px;align-items:start}
@media (max-width:800px){main{grid-template-columns:1fr}}
#view{min-width:0}
#tabs{display:flex;flex-wrap:wrap;gap:6px;margin-bottom:6px}
#tabs button{background:#23262e;color:#ddd;border:1px solid #444;border-radius:4px;padding:3px;cursor:pointer;
  display:flex;flex-direction:column;align-items:center;font-size:11px}
#tabs button.active{border-color:#f5c542;color:#fff}
#tabs canvas{display:block;image-rendering:pixelated;margin-bottom:2px}
#stage-wrap{width:100%}
#stage{width:100%;height:auto;image-rendering:pixelated;cursor:crosshair;outline:none;border:1px solid #333}
#stage:focus{border-color:#f5c542}
#side{min-width:0}
#zoom{image-rendering:pixelated;border:1px solid #333;background:#000}
#triangle{overflow-x:auto}
#triangle table,#history{border-collapse:collapse;font:12px ui-monospace,SFMono-Regular,Menlo,monospace}
#triangle td,#triangle th,#history td,#history th{border:1px solid #333;padding:2px 6px;text-align:left;
  white-space:nowrap}
#history th{background:#23262e;position:sticky;top:0}
#history tr.winner td{background:#2e3a24}
#history tr.picked td{outline:1px solid #f5c542}
#history tbody tr{cursor:pointer}
#history-section{padding:0 16px 16px}
.scroll{max-height:360px;overflow:auto}
.sw{display:inline-block;width:.9em;height:.9em;margin-right:.3em;vertical-align:middle;border:1px solid #888}
.muted{color:#888}
"""

_SCRIPT = r"""
"use strict";
const META = JSON.parse(document.getElementById("softpipe-data").textContent);
const W = META.width, H = META.height;
const A = {};
const TYPES = {u1: Uint8Array, u2: Uint16Array, u4: Uint32Array, f4: Float32Array, f8: Float64Array};
let state = {x: -1, y: -1, pic: 0, picked: null};
let zoomPixels = null;

async function inflate(b64) {
  const bin = atob(b64), bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return await new Response(stream).arrayBuffer();
}

function fmtG(v, p) {            // Python's format(v, f".{p}g")
  if (Number.isNaN(v)) return "nan";
  if (!Number.isFinite(v)) return v > 0 ? "inf" : "-inf";
  if (v === 0) return Object.is(v, -0) ? "-0" : "0";
  const s = v.toExponential(p - 1);
  let [m, e] = s.split("e"); e = parseInt(e, 10);
  if (e >= -4 && e < p) {
    let f = v.toFixed(Math.max(p - 1 - e, 0));
    if (f.includes(".")) f = f.replace(/0+$/, "").replace(/\.$/, "");
    return f;
  }
  if (m.includes(".")) m = m.replace(/0+$/, "").replace(/\.$/, "");
  return m + "e" + (e < 0 ? "-" : "+") + String(Math.abs(e)).padStart(2, "0");
}
const tup = (a, p = 4) => "(" + Array.from(a, c => fmtG(c, p)).join(", ") + ")";
function swatch(rgba) {
  if (!Array.from(rgba).every(Number.isFinite)) return "";
  const c = Array.from(rgba).slice(0, 3).map(v => Math.round(Math.min(Math.max(v, 0), 1) * 255));
  return `<span class="sw" style="background:rgb(${c.join(",")})"></span>`;
}
const esc = s => String(s).replace(/[&<>"]/g, c => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;"}[c]));

function row(name, i, n) { return A[name].subarray(i * n, (i + 1) * n); }

function drawOf(g) {             // global post-clip triangle → draw
  let k = 0;
  for (let d = 0; d < META.draws.length; d++) if (META.draws[d].tri_offset <= g) k = d;
  return k;
}
function triRow(g) {             // global triangle id → row in the t_ arrays
  const ids = A.t_id; let lo = 0, hi = ids.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (ids[mid] < g) lo = mid + 1; else hi = mid; }
  return lo < ids.length && ids[lo] === g ? lo : -1;
}
function historyRange(x, y) {
  const p = y * W + x, px = A.h_pixel; let lo = 0, hi = px.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (px[mid] < p) lo = mid + 1; else hi = mid; }
  if (lo < px.length && px[lo] === p) return [lo, A.h_start[lo], A.h_start[lo + 1]];
  return null;
}
function triWindow(r) {          // window corners of a triangle: its vertices', or a clipped piece's own
  if (A.t_clipped[r]) { let m = 0; for (let i = 0; i < r; i++) m += A.t_clipped[i]; return row("t_window", m, 9); }
  const w = new Float32Array(9);
  for (let c = 0; c < 3; c++) w.set(row("v_win", A.t_vert[r * 3 + c], 3), 3 * c);
  return w;
}
function winner(x, y) { const g = A.win[y * W + x]; return g ? g - 1 : -1; }

// ---------------------------------------------------------------- pictures and overlays
const pics = META.pictures.map((p, k) => ({...p, img: document.getElementById("pic-" + k)}));
const stage = document.getElementById("stage");
const SHOW = Math.max(2 * W, Math.min(8 * W, 720));        // at most this wide: small framebuffers magnified
const SCALE = Math.max(1, Math.min(8, Math.floor(SHOW / W)));   // the canvas's pixels per framebuffer pixel
stage.width = W * SCALE; stage.height = H * SCALE; stage.style.maxWidth = SHOW + "px";
const thumbs = [];

function outlineTri() {          // the highlighted triangle's image-space corners, or null
  const g = state.picked !== null ? state.picked : (state.x >= 0 ? winner(state.x, state.y) : -1);
  if (g < 0) return null;
  const r = triRow(g); if (r < 0) return null;
  const w = triWindow(r);
  return [[w[0], H - w[1]], [w[3], H - w[4]], [w[6], H - w[7]]];
}
function paint(ctx, pic, scale) {
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(pic.img, 0, 0, W * scale, H * scale);
  const t = outlineTri();
  if (t && pic.outline) {
    ctx.strokeStyle = "#ff3df5"; ctx.lineWidth = Math.max(1.5, scale * 1.5 > 3 ? 3 : 1.5);
    ctx.beginPath(); ctx.moveTo(t[0][0] * scale, t[0][1] * scale);
    ctx.lineTo(t[1][0] * scale, t[1][1] * scale); ctx.lineTo(t[2][0] * scale, t[2][1] * scale);
    ctx.closePath(); ctx.stroke();
  }
  if (state.x >= 0 && pic.outline) {           // (a shadow map is the light's view: no pixel of ours)
    ctx.strokeStyle = "#f5c542"; ctx.lineWidth = 1;
    const s = Math.max(scale, 1), pad = scale < 2 ? 2 : 0;
    ctx.strokeRect(state.x * scale - pad - 0.5, state.y * scale - pad - 0.5, s + 2 * pad + 1, s + 2 * pad + 1);
  }
}
function paintAll() {
  paint(stage.getContext("2d"), pics[state.pic], SCALE);
  thumbs.forEach((c, k) => paint(c.getContext("2d"), pics[k], c.width / W));
  paintZoom();
}

function buildTabs() {
  const nav = document.getElementById("tabs");
  const tw = 96, th = Math.max(1, Math.round(tw * H / W));
  pics.forEach((p, k) => {
    const b = document.createElement("button");
    b.type = "button"; b.dataset.pic = k; b.title = p.name;
    const c = document.createElement("canvas"); c.width = tw; c.height = th;
    b.appendChild(c); b.appendChild(document.createTextNode(p.name));
    b.addEventListener("click", () => { state.pic = k; setActive(); paintAll(); stage.focus(); });
    nav.appendChild(b); thumbs.push(c);
  });
  setActive();
}
function setActive() {
  document.querySelectorAll("#tabs button").forEach((b, k) => b.classList.toggle("active", k === state.pic));
}

// ---------------------------------------------------------------- the zoom
function paintZoom() {
  const c = document.getElementById("zoom"), ctx = c.getContext("2d");
  const N = 11, S = c.width / N, half = (N - 1) / 2;
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, c.width, c.height);
  if (state.x < 0) return;
  const x0 = state.x - half, y0 = state.y - half;
  for (let j = 0; j < N; j++) for (let i = 0; i < N; i++) {
    const x = x0 + i, y = y0 + j;
    if (x < 0 || y < 0 || x >= W || y >= H) continue;
    const o = (y * W + x) * 4;
    ctx.fillStyle = `rgb(${zoomPixels[o]},${zoomPixels[o + 1]},${zoomPixels[o + 2]})`;
    ctx.fillRect(i * S, j * S, S, S);
  }
  ctx.strokeStyle = "rgba(255,255,255,0.15)"; ctx.lineWidth = 1;
  for (let i = 0; i <= N; i++) {
    ctx.beginPath(); ctx.moveTo(i * S + 0.5, 0); ctx.lineTo(i * S + 0.5, c.height); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(0, i * S + 0.5); ctx.lineTo(c.width, i * S + 0.5); ctx.stroke();
  }
  const pos = META.pattern.positions;
  const hist = historyRange(state.x, state.y);
  const mark = {};
  if (hist) for (let r = hist[1]; r < hist[2]; r++) {
    const s = A.f_sample[r], v = A.f_verdict[r];
    if (v === 0) mark[s] = "w"; else if (!mark[s]) mark[s] = v === 1 ? "f" : "d";
  }
  for (let j = 0; j < N; j++) for (let i = 0; i < N; i++) {
    const cx = (i + 0.5) * S, cy = (j + 0.5) * S, sel = i === half && j === half;
    ctx.strokeStyle = sel ? "#fff" : "rgba(255,255,255,0.55)"; ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(cx - 3, cy); ctx.lineTo(cx + 3, cy); ctx.moveTo(cx, cy - 3); ctx.lineTo(cx, cy + 3); ctx.stroke();
    pos.forEach((p, s) => {           // window y is up: the image row grows down
      const sx = (i + p[0]) * S, sy = (j + 1 - p[1]) * S;
      ctx.beginPath(); ctx.arc(sx, sy, sel ? 3 : 2, 0, 2 * Math.PI);
      if (sel && mark[s] === "w") { ctx.fillStyle = "#f5c542"; ctx.fill(); }
      ctx.strokeStyle = sel && mark[s] === "f" ? "#ff4040" : (sel ? "#f5c542" : "rgba(245,197,66,0.6)");
      ctx.stroke();
    });
  }
  ctx.strokeStyle = "#f5c542"; ctx.lineWidth = 2; ctx.strokeRect(half * S + 1, half * S + 1, S - 2, S - 2);
  const t = outlineTri();
  if (t) {
    ctx.strokeStyle = "#ff3df5"; ctx.lineWidth = 2; ctx.beginPath();
    const P = q => [(q[0] - x0) * S, (q[1] - y0) * S];
    ctx.moveTo(...P(t[0])); ctx.lineTo(...P(t[1])); ctx.lineTo(...P(t[2])); ctx.closePath(); ctx.stroke();
  }
}

// ---------------------------------------------------------------- the tables
function historyTable(x, y) {
  const thead = document.querySelector("#history thead"), tbody = document.querySelector("#history tbody");
  const before = document.getElementById("before");
  const hist = historyRange(x, y);
  thead.innerHTML = ""; tbody.innerHTML = "";
  if (!hist) {
    const g = winner(x, y);
    before.textContent = (META.held.step > 1 && g >= 0)
      ? `The page does not hold this pixel's history (${META.held.statement}); its winning triangle is outlined.`
      : "No fragment reached this pixel.";
    return;
  }
  const [j, r0, r1] = hist;
  const draws = new Set(); for (let r = r0; r < r1; r++) draws.add(A.f_draw[r]);
  const vnames = [];                        // the union of the varyings of the draws here, in order
  draws.forEach(k => META.draws[k].varyings.forEach(([n, s]) => { if (!vnames.some(v => v[0] === n)) vnames.push([n, s]); }));
  const anyShadow = [...draws].some(k => META.draws[k].shadow_lights > 0);
  const cols = ["draw", "#", "prim", "tri", "sample", "depth", ...vnames.map(v => v[0]),
                ...(anyShadow ? ["shadow V_j"] : []), "shader output", "depth test", "color after"];
  thead.innerHTML = "<tr>" + cols.map(c => `<th>${esc(c)}</th>`).join("") + "</tr>";
  const first = A.f_draw[r0];
  before.innerHTML = `${r1 - r0} fragment(s); color before draw ${first + 1} (${esc(META.draws[first].name)}): ` +
    swatch(row("h_before", j, 4)) + esc(tup(row("h_before", j, 4)));
  const g = winner(x, y);
  let win = -1;
  for (let r = r0; r < r1; r++) if (A.f_verdict[r] === 0) win = r;
  const kv = A.f_vary.length / Math.max(A.f_draw.length, 1), ks = A.f_shadow.length / Math.max(A.f_draw.length, 1) / 3;
  let html = "";
  for (let r = r0; r < r1; r++) {
    const k = A.f_draw[r], d = META.draws[k];
    const cells = [[`${k + 1}: ${d.name}`, "draw"], [A.f_index[r], "index"], [A.f_prim[r], "primitive_id"],
                   [A.f_tri[r], "triangle"], [A.f_sample[r], "sample"], [A.f_depth[r].toFixed(6), "depth"]];
    const flat = row("f_vary", r, kv);
    vnames.forEach(([n]) => {
      let o = 0, hit = null;
      for (const [m, s] of d.varyings) { if (m === n) { hit = [o, s]; break; } o += s; }
      cells.push([hit ? (hit[1] === 1 ? fmtG(flat[hit[0]], 4) : tup(flat.subarray(hit[0], hit[0] + hit[1]))) : "", "v:" + n]);
    });
    if (anyShadow) {
      const parts = [];
      for (let l = 0; l < d.shadow_lights; l++) {
        const c = A.f_shadow.subarray((r * ks + l) * 3, (r * ks + l) * 3 + 3);
        parts.push(c[0] === c[1] && c[1] === c[2] ? fmtG(c[0], 3) : tup(c));
      }
      cells.push([parts.join(" "), "shadow"]);
    }
    const color = row("f_color", r, 4), after = row("f_after", r, 4);
    cells.push([swatch(color) + esc(tup(color)), "color", true]);
    cells.push([META.verdicts[A.f_verdict[r]] + (r === win ? " ★" : ""), "verdict"]);
    cells.push([swatch(after) + esc(tup(after)), "color_after", true]);
    const gt = d.tri_offset + A.f_tri[r];
    html += `<tr data-row="${r}" data-tri="${gt}" class="${r === win ? "winner" : ""}${state.picked === gt ? " picked" : ""}">` +
      cells.map(([v, f, raw]) => `<td data-field="${esc(f)}">${raw ? v : esc(v)}</td>`).join("") + "</tr>";
  }
  tbody.innerHTML = html;
}

function triangleTable() {
  const el = document.getElementById("triangle");
  const g = state.picked !== null ? state.picked : (state.x >= 0 ? winner(state.x, state.y) : -1);
  if (g < 0) { el.textContent = "no triangle won this pixel"; return; }
  const r = triRow(g), k = drawOf(g), d = META.draws[k];
  const f3 = a => tup(a, 5);
  let s = `<p>${state.picked !== null ? "picked" : "winning"} triangle: draw ${k + 1} (${esc(d.name)}), ` +
    `post-clip triangle ${g - d.tri_offset}, primitive ${A.t_prim[r]}${A.t_clipped[r] ? " (a piece clipping cut)" : ""}</p>`;
  s += `<table id="vertices"><thead><tr><th>vertex</th><th>space</th><th>position</th></tr></thead><tbody>`;
  for (let c = 0; c < 3; c++) {
    const v = A.t_vert[r * 3 + c];
    const obj = Array.from(row("v_obj", v, 4)).filter(Number.isFinite);
    s += `<tr data-vertex="${c}"><td rowspan="3">${A.t_vindex[r * 3 + c]}</td><td>${esc(d.object_space)}</td>` +
         `<td data-space="object">${f3(obj)}</td></tr>` +
         `<tr><td>clip</td><td data-space="clip">${f3(row("v_clip", v, 4))}</td></tr>` +
         `<tr><td>window</td><td data-space="window">${f3(row("v_win", v, 3))}</td></tr>`;
  }
  s += "</tbody></table>";
  if (A.t_clipped[r]) {
    const w = triWindow(r);
    s += `<p class="muted">after clipping, window: ${[0, 1, 2].map(c => f3(w.subarray(3 * c, 3 * c + 3))).join(" ")}</p>`;
  }
  el.innerHTML = s;
}

function select(x, y, keepPick) {
  x = Math.min(Math.max(x, 0), W - 1); y = Math.min(Math.max(y, 0), H - 1);
  state.x = x; state.y = y;
  if (!keepPick) state.picked = null;
  const h = document.getElementById("pixel");
  h.dataset.x = x; h.dataset.y = y;
  const g = winner(x, y);
  h.textContent = `pixel (${x}, ${y})` + (g >= 0 ? ` — draw ${drawOf(g) + 1}: ${META.draws[drawOf(g)].name}` : "");
  historyTable(x, y); triangleTable(); paintAll();
}

function pixelAt(ev) {
  const r = stage.getBoundingClientRect();
  return [Math.floor((ev.clientX - r.left) * W / r.width), Math.floor((ev.clientY - r.top) * H / r.height)];
}

async function main() {
  try {
    for (const [name, a] of Object.entries(META.arrays)) {
      const T = TYPES[a.dtype], n = T.BYTES_PER_ELEMENT, bytes = new Uint8Array(await inflate(a.b64));
      const count = bytes.length / n;
      let arr;
      if (a.shuffle) {
        const out = new Uint8Array(bytes.length);
        for (let b = 0; b < n; b++) for (let i = 0, o = b * count; i < count; i++) out[i * n + b] = bytes[o + i];
        arr = new T(out.buffer);
      } else arr = new T(bytes.buffer);
      if (a.columns) {
        const N = a.shape[0], m = count / Math.max(N, 1), rowsOut = new T(count);
        for (let j = 0; j < m; j++) for (let i = 0; i < N; i++) rowsOut[i * m + j] = arr[j * N + i];
        arr = rowsOut;
      }
      A[name] = arr;
    }
    const after = Float32Array.from(A.f_color);       // the color after: stored where it is not the shader's
    for (let r = 0, m = 0; r < A.f_after_same.length; r++)
      if (!A.f_after_same[r]) { after.set(A.f_after.subarray(4 * m, 4 * m + 4), 4 * r); m++; }
    A.f_after = after;
  } catch (e) {
    document.getElementById("summary").textContent = "This browser could not read the page's data (" + e +
      "): it needs DecompressionStream (Chrome 80+, Firefox 113+, Safari 16.4+).";
    throw e;
  }
  await Promise.all(pics.map(p => p.img.decode()));
  const d = META.draws;
  document.getElementById("summary").textContent = `${W}×${H}, ${META.pattern.positions.length} sample(s) per pixel` +
    ` (${META.pattern.name}); ${d.length} draw(s): ` + d.map((x, k) =>
      `${k + 1}. ${x.name} (${x.program}, ${x.triangles} triangles after clipping and culling of ${x.input_triangles}, ` +
      `${x.fragments} fragments, ${x.path} path)`).join("; ");
  document.getElementById("held").textContent = "This page holds " + META.held.statement + ".";
  const c = document.createElement("canvas"); c.width = W; c.height = H;
  const final = pics.find(p => p.name === "final") || pics[pics.length - 1];
  const ctx = c.getContext("2d"); ctx.drawImage(final.img, 0, 0);
  zoomPixels = ctx.getImageData(0, 0, W, H).data;
  state.pic = Math.max(0, pics.indexOf(final));
  buildTabs();
  stage.addEventListener("click", ev => { const [x, y] = pixelAt(ev); select(x, y); stage.focus(); });
  stage.addEventListener("mousemove", ev => {
    const [x, y] = pixelAt(ev), g = winner(x, y);
    document.getElementById("hover").textContent = `(${x}, ${y})` + (g >= 0 ? ` ${META.draws[drawOf(g)].name}` : "");
    if (document.getElementById("follow").checked && (x !== state.x || y !== state.y)) select(x, y);
  });
  document.addEventListener("keydown", ev => {
    const step = ev.shiftKey ? 10 : 1;
    const move = {ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step]}[ev.key];
    if (!move || ev.target.tagName === "INPUT") return;
    ev.preventDefault();
    select((state.x < 0 ? W >> 1 : state.x) + move[0], (state.y < 0 ? H >> 1 : state.y) + move[1]);
  });
  document.querySelector("#history tbody").addEventListener("click", ev => {
    const tr = ev.target.closest("tr"); if (!tr) return;
    const g = +tr.dataset.tri;
    state.picked = state.picked === g ? null : g;
    select(state.x, state.y, true);
  });
  let first = -1;                 // start on the middle pixel that a triangle won, if any
  for (let y = H >> 1, x = W >> 1, r = 0; r < Math.max(W, H) && first < 0; r++)
    for (const [dx, dy] of [[r, 0], [-r, 0], [0, r], [0, -r]]) {
      const xx = x + dx, yy = y + dy;
      if (xx >= 0 && yy >= 0 && xx < W && yy < H && A.win[yy * W + xx]) { first = yy * W + xx; break; }
    }
  if (first >= 0) select(first % W, Math.floor(first / W)); else paintAll();
  document.body.dataset.ready = "1";
}
main();
"""
