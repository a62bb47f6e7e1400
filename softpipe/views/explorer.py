"""The pipeline explorer: a traced draw (or a scene's draws) as one self-contained HTML page.

``softpipe explore bunny -o report.html``, ``trace.to_html("report.html")`` or
``write_explorer(results, "report.html")`` write one HTML file that needs no server and
no network: the stage pictures (:mod:`softpipe.views.pictures`) are embedded as PNG data URLs,
the script is plain JavaScript in the page, and the data is one JSON block whose arrays
are little-endian binary, zlib-compressed and base64-encoded (the page inflates them with
the browser's own ``DecompressionStream``). The page's own text is package data, real files
that an editor and a linter read: ``explorer_page/page.html`` (the skeleton, with
placeholders this module fills), ``page.css`` and ``page.js``.

Click (or hover, with "follow the mouse") a pixel of any picture: the page shows the
pixel's history (every fragment of every draw at that pixel, in order, as
:meth:`softpipe.pipeline.trace.Trace.pixel_history` gives it), outlines the winning triangle in
every picture in window space, and lists its three vertices in object, clip and window
coordinates. A draw of lines or points explores alike: the winning line is drawn as its
segment, a point as its square, the history shows each fragment's t along its line or its
``gl_PointCoord``, and the table lists the line's two vertices or the point's one (in polygon
mode, the three of the triangle whose edge or corner it is). Arrow keys move the selected pixel (Shift: by 10); the zoom shows the
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
                 window coordinates; and for a piece that clipping cut, its own window corners.
                 The same for a line or a point (each draw's ``kind``: "triangles" | "lines" |
                 "points"), with its own window corners (a, b, b) or (p, p, p) always and its
                 width or size (``t_size``); a line's or point's fragments keep their
                 ``frag.point_coord`` (``f_pc``: (t, 0) on a line)
``f_stencil``    of a draw with the stencil test on (its ``stencil``), each fragment's sample's
                 stencil value before and after it (uint8 pairs), as ``pixel_history`` shows them

Numbers are stored at the precision the pipeline made them where that is small: depth
as float64, the shader's output and the color after as float32 (what the pipeline
holds), the varyings and V_j as float32 (the page prints them to 4 and 3 significant
digits). :func:`read_explorer` reads a page's data back in Python (the tests compare it
with ``pixel_history``).
"""
from __future__ import annotations

import base64
import functools
import html
import importlib.resources
import io
import json
import os
import re
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, cast

import numpy as np

from softpipe.core.runtime import check_memory
from softpipe.pipeline.output import VERDICTS
from softpipe.views.draws import traced_draws

__all__ = ["write_explorer", "explorer_html", "read_explorer", "ExplorerData", "ExplorerSummary",
           "MAX_FRAGMENTS", "READ_LIMIT", "scene_pictures"]

#: Fragments whose whole history the page holds, by default (about 140 bytes each, compressed).
MAX_FRAGMENTS = 400_000

#: The most :func:`read_explorer` reads by default: the page's file, and its arrays inflated (bytes).
READ_LIMIT = 1 << 31

#: The verdicts, as the output merger names them (index = the stored code).
_VERDICTS = VERDICTS


def _stencil_pairs(trace, pixels: np.ndarray, idx: np.ndarray, width: int) -> np.ndarray:
    """uint8 [n, 2]: each fragment's sample's stencil (before, after): before is the same sample's previous
    fragment's after, or the framebuffer's before the draw (``idx`` in fragment order per pixel)."""
    f, after = trace.fragments, trace.merged.stencil_after
    out = np.zeros((len(idx), 2), np.uint8)
    last: Dict[tuple, int] = {}
    for r, (p, i) in enumerate(zip(pixels, idx)):
        key = (int(p), int(f.sample[i]))
        if key not in last:
            last[key] = int(trace.stencil_before_at(int(p % width), int(p // width))[key[1]])
        out[r] = (last[key], after[i])
        last[key] = int(after[i])
    return out


# ---------------------------------------------------------------------------- inputs


def _program_name(fragment_shader) -> str:
    """A bare Trace's program as the command line names it: the registered program whose fragment
    shader it is (``phong``, not ``phong_fragment``), else the shader's own name."""
    from softpipe.programs import PROGRAMS
    for name, program in PROGRAMS.items():
        if program.fragment is fragment_shader:
            return name
    return getattr(fragment_shader, "__name__", "")


def _traces(traces_or_results) -> List[tuple]:
    """(name, program, trace) for a Trace, a DrawResult or a sequence of either."""
    out = []
    for k, (item, trace) in enumerate(traced_draws(traces_or_results, "explorer")):
        name = getattr(item, "name", "") or f"draw {k + 1}"
        program = getattr(item, "program", "") or _program_name(trace.fragment_shader)
        out.append((name, program, trace))
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
            octets = b.reshape(-1).view(np.uint8)
            raw = octets.reshape(-1, a.itemsize).T.tobytes() if shuffle else octets.tobytes()
            z = zlib.compress(raw, 6)
            if best is None or len(z) < len(best[0]):
                best = (z, columns, shuffle, raw)
    assert best is not None     # both loops run at least once
    return {"dtype": dtype, "shape": list(a.shape), "columns": best[1], "shuffle": best[2],
            "b64": base64.b64encode(zlib.compress(best[3], 9)).decode("ascii")}


#: The dtypes a page's arrays are stored in (what :func:`_array` is given).
_DTYPES = ("u1", "u2", "u4", "f4", "f8")


def _array_bytes(name: str, d: Any) -> int:
    """The bytes array ``name`` of a page inflates to, as its dtype and shape say (checked to be such)."""
    shape = d.get("shape") if isinstance(d, dict) else None
    if not (isinstance(d, dict) and d.get("dtype") in _DTYPES and isinstance(d.get("b64"), str)
            and isinstance(shape, list) and len(shape) <= 4
            and all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n < 1 << 40 for n in shape)):
        raise ValueError(f"array {name!r} is not one write_explorer stores (a dtype of {', '.join(_DTYPES)}, a "
                         "shape of whole numbers, base64 data)")
    return int(np.prod(shape, dtype=object)) * np.dtype(d["dtype"]).itemsize


def _unarray(d: dict, name: str = "") -> np.ndarray:
    size = np.dtype(d["dtype"]).itemsize
    expected = _array_bytes(name, d)
    try:
        inflate = zlib.decompressobj()
        data = inflate.decompress(base64.b64decode(d["b64"]), expected + 1)   # never more than the shape says
    except (ValueError, zlib.error) as e:
        raise ValueError(f"array {name!r}: its data cannot be decoded ({e})") from None
    if len(data) != expected or not inflate.eof:
        raise ValueError(f"array {name!r}: its data inflates to {'more' if len(data) > expected else 'less'} "
                         f"than the {expected:,} bytes its shape {d['shape']} and dtype {d['dtype']} say")
    raw = np.frombuffer(data, np.uint8)
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


def scene_pictures(draws) -> Dict[str, np.ndarray]:
    """The stage pictures of one draw, or of several drawn into one framebuffer, composed (``draws``: (name,
    program, trace) of each, in the order drawn; the live viewer shows them too, softpipe.tools.viewer)."""
    from softpipe.views import pictures as P
    if len(draws) == 1:
        return P.stage_pictures(draws[0][2])
    traces = [t for _, _, t in draws]
    h, w = traces[0].height, traces[0].width
    # one draw's pictures at a time, folded in: a scene of 1,500 draws would otherwise hold 1,500 sets
    dots = np.zeros((h, w, 3), np.uint8)
    extra: Dict[str, np.ndarray] = {}
    for t in traces:
        p = P.stage_pictures(t)
        lit = p["vertices"].any(axis=2)                 # a later draw's dots over an earlier's
        dots[lit] = p["vertices"][lit]
        for name, img in p.items():
            if name not in P.PICTURES and name not in extra:
                extra[name] = img
        last = p
    pics: Dict[str, np.ndarray] = {"vertices": dots}
    img = np.zeros((h, w, 3), np.uint8)                 # layer by layer across the draws, as for one
    for layer in P.OUTLINE_LAYERS:
        for t in traces:
            P.draw_outline_layer(img, t, layer)
    pics["primitives"] = img
    img = np.zeros((h, w, 3), np.uint8)                 # the last fragment written, across the draws
    offset = 0
    for t in traces:
        f, wr = t.fragments, t.written()
        if wr.any():
            img[f.y[wr], f.x[wr]] = P.id_colors(offset + f.primitive_id[wr])
        offset += int(t.primitives.input_count)
    pics["coverage"] = img
    pics["depth"] = last["depth"]                       # one framebuffer: its depth and color after the last
    pics["overdraw"] = P.heat_colors(cast(np.ndarray, sum(P.overdraw(t) for t in traces)))   # (one draw at least)
    pics["final"] = last["final"]
    pics.update(extra)
    return pics


def _mesh_pictures(traces) -> Dict[str, np.ndarray]:
    """The mesh view's pictures (softpipe.views.mesh_view): every draw's input triangles in window space,
    in one picture; in object space only for a page of one draw (draws' object spaces are their own,
    and each picture fits its own mesh's box, so two of them in one picture would not line up)."""
    from softpipe.views.mesh_view import mesh_pictures
    window, obj = "mesh, window space", "mesh, object space (front, orthographic)"
    out: Dict[str, np.ndarray] = {}
    for t in traces:
        p = mesh_pictures(t)
        if window not in out:
            out[window] = p[window]
        else:
            lit = p[window].any(axis=2)
            out[window][lit] = p[window][lit]
        if len(traces) == 1:
            out[obj] = p[obj]
    return out


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


def _shown(text) -> str:
    """``text`` as the page shows it: a file name's bytes that are not UTF-8 (a Latin-1 'café.obj', which
    Python holds as lone surrogates, and which no UTF-8 page can hold) become U+FFFD, '�'."""
    return str(text).encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def _position_column(layout) -> Optional[int]:
    """The first column of the eye-space ``position`` varying (3 components) in a row of varyings, or None."""
    column = 0
    for name, size in layout:
        if name == "position" and size == 3:
            return column
        column += size
    return None


def explorer_data(traces_or_results, *, max_fragments: int = MAX_FRAGMENTS, title: Optional[str] = None,
                  progress=None, overlays: bool = False) -> dict:
    """The page's data (see the module docstring) as a JSON-ready dict, with the pictures."""
    from softpipe.pipeline.assembly import primitive_indices

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
    held_rows = []                                          # (pixel, draw, index) of every held fragment
    for k, t in enumerate(traces):
        f = t.fragments
        pix = f.y.astype(np.int64) * w + f.x
        idx = np.nonzero(keep_pixel[pix])[0]
        held_rows.append(np.stack([pix[idx], np.full(len(idx), k), idx], axis=1))
    rows = np.concatenate(held_rows) if held_rows else np.zeros((0, 3), np.int64)
    rows = rows[np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))]
    F = len(rows)
    vary = np.full((F, kmax), np.nan)
    shadow_cols = []
    shadows: List[tuple] = []                                # (rows, V_j [rows, L, 3]) of each shadowed draw
    color = np.zeros((F, 4), np.float32)
    after = np.zeros((F, 4), np.float32)
    depth = np.zeros(F)
    verdict = np.zeros(F, np.uint8)
    point_coord = np.full((F, 2), np.nan)                   # a line's or a point's fragments only
    stencil = np.zeros((F, 2), np.uint8)                    # (before, after), of a draw with the stencil test on
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
        if t.call.state.stencil is not None and t.merged.stencil_after is not None:
            stencil[sel] = _stencil_pairs(t, rows[sel, 0], idx, w)
        ncols = 0
        # the varyings and point_coord of all of them in one compiled pass: the generated code pixel_history
        # runs as Python, compiled, so the values are the shader's bit for bit (Trace.fragment_varyings)
        v, pc = t.fragment_varyings(idx)
        vary[sel, :v.shape[1]] = v
        if t.primitives.kind != "triangles":
            point_coord[sel] = pc
        done += len(sel)
        if progress is not None:
            progress(done, F)
        # V_j of all of them in one compiled pass (FORMULAS §21): the values pixel_history shows, per fragment
        position = _position_column(layouts[k])
        terms = t.shadow_terms(v[:, position:position + 3]) if position is not None else None
        if terms is not None and terms.shape[1]:
            shadows.append((sel, terms))
            ncols = terms.shape[1]
        shadow_cols.append(ncols)
    lmax = max(shadow_cols + [0])
    shadow = np.full((F, max(lmax, 1), 3), np.nan, np.float32)
    for lit, terms in shadows:
        shadow[lit, :terms.shape[1]] = terms
    same = (color == after).all(axis=1)                     # the color after is the shader's, mostly: once
    hpix, hstart = np.unique(rows[:, 0], return_index=True)
    hstart = np.append(hstart, F)
    before = np.zeros((len(hpix), 4), np.float32)
    for j, (p, r) in enumerate(zip(hpix, hstart[:-1])):
        t = traces[int(rows[r, 1])]
        before[j] = t.before_at(int(p % w), int(p // w))[0][0]

    # --- the triangles named by the map or a history, and their vertices in every space
    gid = np.unique(np.concatenate([win[win > 0].astype(np.int64) - 1, tri_offset[rows[:, 1]] + tri]))
    t_draw = np.searchsorted(tri_offset, gid, side="right") - 1
    t_window = np.zeros((len(gid), 3, 3))
    t_prim = np.zeros(len(gid), np.int64)
    t_clipped = np.zeros(len(gid), np.uint8)
    t_own = np.zeros(len(gid), np.uint8)                    # its own window corners are stored (t_window)
    t_size = np.ones(len(gid))
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
        t_own[sel] = p.clipped[local] | (p.kind != "triangles")
        if p.kind != "triangles":
            t_size[sel] = p.size[local]
        call = t.call
        corners = primitive_indices(call.topology, call.indices, len(t.vertex.position))[t_prim[sel]]
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
        v_obj.append(obj)
        v_clip.append(clip)
        v_win.append(win_xyz)
    cat = lambda parts, n: np.concatenate(parts) if parts else np.zeros((0, n))  # noqa: E731

    pics = scene_pictures(draws)
    pics.update(_mesh_pictures(traces))
    if overlays:                    # RenderDoc's overlays, after the stage pictures (softpipe.views.overlays)
        from softpipe.views.overlays import overlay_pictures
        pics.update(overlay_pictures(traces))
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
        "title": _shown(title or " + ".join(n for n, _, _ in draws)),
        "width": w, "height": h,
        "pattern": {"name": getattr(pattern, "name", ""), "positions": np.asarray(pattern.positions).tolist()},
        "draws": [{"name": _shown(n), "program": _shown(prog), "path": t.path, "fragments": int(len(t)),
                   "triangles": int(len(t.primitives)), "input_triangles": int(t.primitives.input_count),
                   "kind": t.primitives.kind, "polygon_mode": t.primitives.faces is not None,
                   "stencil": t.call.state.stencil is not None,
                   "tri_offset": int(tri_offset[k]), "varyings": [[a, int(b)] for a, b in layouts[k]],
                   "shadow_lights": int(shadow_cols[k]),
                   "object_space": "object" if t.call.vertex_shader is not None else "given (clip)",
                   "vertices": int(len(t.vertex.position))}
                  for k, (n, prog, t) in enumerate(draws)],
        "verdicts": list(_VERDICTS),
        "held": {"statement": statement, "step": step, "pixels": int(held), "fragments": int(F),
                 "covered_pixels": covered, "total_fragments": total_fragments, "limit": int(max_fragments)},
        # the page outlines the selected pixel's triangle in window space: not on a light's view or on object space
        "pictures": [{"name": n, "outline": not n.startswith(("shadow map", "mesh, object space"))} for n in pics],
    }
    arrays = {
        "win": _array(win, "u4"),
        "h_pixel": _array(hpix, "u4"), "h_start": _array(hstart, "u4"), "h_before": _array(before, "f4"),
        "f_draw": _array(rows[:, 1], "u2"), "f_index": _array(rows[:, 2], "u4"), "f_prim": _array(prim, "u4"),
        "f_tri": _array(tri, "u4"), "f_sample": _array(sample, "u1"), "f_depth": _array(depth, "f8"),
        "f_verdict": _array(verdict, "u1"), "f_color": _array(color, "f4"), "f_after_same": _array(same, "u1"),
        "f_after": _array(after[~same], "f4"),
        "f_vary": _array(vary, "f4"), "f_shadow": _array(shadow, "f4"), "f_pc": _array(point_coord, "f4"),
        "f_stencil": _array(stencil, "u1"),
        "t_id": _array(gid, "u4"), "t_window": _array(t_window[t_own == 1], "f4"), "t_prim": _array(t_prim, "u4"),
        "t_clipped": _array(t_clipped, "u1"), "t_own": _array(t_own, "u1"), "t_size": _array(t_size, "f4"), "t_vindex": _array(t_vindex, "u4"), "t_vert": _array(t_vert, "u4"),
        "v_obj": _array(cat(v_obj, 4), "f4"), "v_clip": _array(cat(v_clip, 4), "f4"),
        "v_win": _array(cat(v_win, 3), "f4"),
    }
    meta["arrays"] = arrays
    return {"meta": meta, "pictures": pics}


# ---------------------------------------------------------------------------- the page

#: The package folder of the page's own text: the HTML skeleton (``page.html``, with the
#: placeholders ``__TITLE__``, ``__STYLE__``, ``__SCRIPT__``, ``__IMAGES__``, ``__DATA__``),
#: its style sheet (``page.css``) and its script (``page.js``).
PAGE_FOLDER = "explorer_page"


@functools.lru_cache(maxsize=None)
def _page_text(name: str) -> str:
    """One file of the page's text, read as package data (so it is found inside an installed wheel too)."""
    return (importlib.resources.files("softpipe.views") / PAGE_FOLDER / name).read_text(encoding="utf-8")


def explorer_html(traces_or_results, *, max_fragments: int = MAX_FRAGMENTS, title: Optional[str] = None,
                  progress=None, overlays: bool = False) -> str:
    """The page as a string (see :func:`write_explorer`)."""
    data = explorer_data(traces_or_results, max_fragments=max_fragments, title=title, progress=progress,
                         overlays=overlays)
    meta, pics = data["meta"], data["pictures"]
    images = "\n".join(f'<img id="pic-{k}" alt="{html.escape(_shown(name))}" src="{_png(img)}">'
                       for k, (name, img) in enumerate(pics.items()))
    blob = json.dumps(meta, separators=(",", ":")).replace("<", "\\u003c").replace(">", "\\u003e")
    page = _page_text("page.html").replace("__TITLE__", html.escape(meta["title"]))    # _shown: UTF-8 safe
    page = page.replace("__STYLE__", _page_text("page.css")).replace("__SCRIPT__", _page_text("page.js"))
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
                   progress=None, overlays: bool = False) -> ExplorerSummary:
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
        ``progress(done, total)`` after each draw's fragments are gathered (done of total fragments).
    overlays : bool
        Add RenderDoc's overlays to the pictures (:func:`softpipe.views.overlays.overlay_pictures`).
    """
    from softpipe.core.files import atomic_write
    page = explorer_html(traces_or_results, max_fragments=max_fragments, title=title, progress=progress,
                         overlays=overlays)
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

    def __init__(self, meta: dict, max_bytes: int = READ_LIMIT):
        self.meta = meta
        arrays = meta.get("arrays") if isinstance(meta, dict) else None
        if not isinstance(arrays, dict):
            raise ValueError("not a softpipe explorer page: its data has no arrays")
        missing = [k for k in ("win", "f_color", "f_after", "f_after_same") if k not in arrays]
        if missing or not all(isinstance(meta.get(k), int) for k in ("width", "height")):
            raise ValueError(f"not a softpipe explorer page: its data lacks {', '.join(missing) or 'its size'}")
        need = sum(_array_bytes(k, v) for k, v in arrays.items())
        if need > max_bytes:
            raise ValueError(f"the page's arrays would inflate to {need:,} bytes, more than the limit of "
                             f"{max_bytes:,} bytes (read_explorer(path, max_bytes=...) raises it)")
        check_memory(f"reading an explorer page's arrays ({need:,} bytes inflated)", need)
        self.arrays = {k: _unarray(v, k) for k, v in arrays.items()}
        same = self.arrays.pop("f_after_same").astype(bool)
        after = np.array(self.arrays["f_color"])
        after[~same] = self.arrays["f_after"]
        self.arrays["f_after"] = after
        self.width, self.height = meta["width"], meta["height"]

    @classmethod
    def from_html(cls, text: str, max_bytes: int = READ_LIMIT) -> "ExplorerData":
        m = re.search(r'<script type="application/json" id="softpipe-data">(.*?)</script>', text, re.S)
        if not m:
            raise ValueError("not a softpipe explorer page: no softpipe-data block")
        return cls(json.loads(m.group(1)), max_bytes)

    def winner(self, x: int, y: int) -> Optional[tuple]:
        """(draw, post-clip triangle) of the last fragment written at pixel (x, y), or None."""
        g = int(self.arrays["win"][y * self.width + x])
        if g == 0:
            return None
        offsets = [d["tri_offset"] for d in self.meta["draws"]]
        k = int(np.searchsorted(offsets, g - 1, side="right") - 1)
        return k, g - 1 - offsets[k]

    def history(self, x: int, y: int) -> Optional[List[dict]]:
        """The held history of pixel (x, y) (a list of dicts, one per fragment), or None if not held.

        A fragment of a line or a point has its ``point_coord`` (float32; (t, 0) on a line), a
        triangle's ``()``, as in :class:`~softpipe.pipeline.trace.PixelEvent`.
        """
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
            pc = () if d.get("kind", "triangles") == "triangles" else tuple(float(c) for c in a["f_pc"][r])
            out.append({"draw": k, "name": d["name"], "index": int(a["f_index"][r]),
                        "primitive_id": int(a["f_prim"][r]), "triangle": int(a["f_tri"][r]),
                        "sample": int(a["f_sample"][r]), "depth": float(a["f_depth"][r]), "varyings": varyings,
                        "color": tuple(float(c) for c in a["f_color"][r]),
                        "verdict": self.meta["verdicts"][int(a["f_verdict"][r])],
                        "color_after": tuple(float(c) for c in a["f_after"][r]), "shadow": shadow,
                        "point_coord": pc,
                        "stencil": (tuple(int(c) for c in a["f_stencil"][r]) if d.get("stencil") else ()),
                        "before": tuple(float(c) for c in a["h_before"][j])})
        return out


def read_explorer(path, *, max_bytes: int = READ_LIMIT) -> ExplorerData:
    """The data embedded in an explorer page written by :func:`write_explorer`.

    Parameters
    ----------
    path : str or path-like
    max_bytes : int
        The most the page (its file) and its arrays, inflated, may take; a page past it is
        refused (ValueError) before anything is inflated, and every array must inflate to
        exactly the bytes its shape says, so a small page cannot fill the memory.
    """
    from softpipe.core.files import check_regular_file, excerpt_path
    check_regular_file(path)
    size = os.path.getsize(path)
    try:
        if size > max_bytes:
            raise ValueError(f"the file is {size:,} bytes, more than the limit of {max_bytes:,} bytes "
                             "(read_explorer(path, max_bytes=...) raises it)")
        return ExplorerData.from_html(Path(path).read_text(encoding="utf-8"), max_bytes)
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f"{excerpt_path(path)}: {e}") from None
