"""The lessons' checks (lessons/ at the repository's root): a student's answer against softpipe's, pixel for pixel.

Each check takes what the student's function made and what softpipe's stage makes of the
same input, and returns a :class:`Difference` when they agree. When they do not, it shows
the difference as a picture (in Jupyter) and raises an AssertionError whose message says
how many pixels differ, lists the first few, and names the rule most likely broken where
it can tell (a pixel on an edge the fill rule gives away, a line's last pixel, a depth
test the wrong way round).

- :func:`check_coverage`: two sets of pixels (window coordinates (x, y), y up; or bool
  masks, row 0 at the top); ``hint=`` explains a pixel.
- :func:`check_line`: a line drawer's pixels against :func:`~softpipe.testing.reference_line`
  (GL's diamond-exit rule), with hints about the last pixel and ties.
- :func:`check_triangles`: a rasterizer's pixels against softpipe's raster of the same
  triangles (:func:`~softpipe.testing.coverage`), with the fill rule's hints.
- :func:`check_depth_test`: which triangle a depth-test loop kept at each pixel, against
  the output merger's verdicts in a :class:`~softpipe.pipeline.trace.Trace`.
- :func:`check_interpolation`: a varying interpolated from the corners' values, 1/w and the
  barycentrics, against what the fragment shader received at every fragment of a trace, with
  the classic mistakes named (linear in the window: noperspective).
- :func:`check_camera`: a look_at and a perspective matrix against softpipe's, numerically and by
  rendering, with the classic mistakes named (the transpose, a left-handed look_at, depth in [0, 1]).
- :func:`check_clipping`: a polygon clipped against one plane in clip space (Sutherland–Hodgman) against
  the pieces primitive assembly emitted for a trace's triangles and for a few further cases (user clip
  planes), with the classic mistakes named (crossing points left out, a corner on the plane counted out).
- :func:`check_blinn_phong`: the OpenGL lighting equation for one directional light (FORMULAS §10, Blinn–Phong
  specular §6) against the colors the ``phong`` program's fragment shader returned at every fragment of a trace.
- :func:`check_bilinear`: bilinear texture filtering against :meth:`softpipe.Texture2D.sample` at the texture
  coordinates of every fragment of a trace, with the classic mistakes named (the half-texel offset, v not flipped).
- :func:`check_mip_level`: the level of detail λ = log2 ρ from a fragment's uv derivatives against softpipe's
  level selection (:func:`softpipe.light.texture.mip_level`) at every fragment of a trace, with the classic mistakes
  named (uv units instead of texels, log2 of ρ², the sum instead of the larger length).
- :func:`check_shadow_compare`: the shadow-map depth compare with percentage-closer filtering against softpipe's
  shadow lookup (V_j, FORMULAS §21) at every fragment of a trace of the surface that receives the shadow.
- :func:`check_ray_triangle`: a ray–triangle test (Möller–Trumbore), used for the closest hit, against softpipe's
  BVH (:mod:`softpipe.rays`) on a grid of camera rays (:func:`camera_rays`), with the classic mistakes named.

The difference picture (:attr:`Difference.picture`) is zoomed
(:func:`softpipe.views.zoom.zoomed`): gray where both cover a pixel, red where the answer
adds a pixel softpipe does not draw, blue where it misses one softpipe draws.
"""
from __future__ import annotations

import base64
from collections import namedtuple
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Set, Tuple

import numpy as np

from softpipe.testing.coverage import coverage
from softpipe.testing.line_reference import reference_line
from softpipe.views.zoom import png, zoomed

__all__ = ["Difference", "check_coverage", "check_line", "check_triangles", "check_depth_test", "check_interpolation",
           "check_camera", "check_clipping", "check_blinn_phong", "check_bilinear", "check_mip_level",
           "check_shadow_compare", "check_ray_triangle", "camera_rays", "pixel_set", "trace_fragments",
           "reference_winners", "COLORS", "LEGEND", "TOLERANCE", "CLIP_TOLERANCE", "NEAR_PLANE", "CLIP_CASES",
           "SHADING_TOLERANCE", "SHADING_MISTAKES", "LightColors", "TEXTURE_TOLERANCE", "TEXTURE_MISTAKES",
           "MIP_TOLERANCE", "MIP_MISTAKES",
           "SHADOW_TOLERANCE", "SHADOW_MISTAKES", "RAY_TOLERANCE", "RAY_MISTAKES"]

Pixel = Tuple[int, int]
#: The difference picture's colors.
COLORS = {"empty": (24, 24, 28), "both": (190, 190, 190), "adds": (220, 50, 32), "misses": (0, 110, 230)}
#: What each color means.
LEGEND = {"both": "both draw it", "adds": "your answer adds it (softpipe does not draw it)",
          "misses": "your answer misses it (softpipe draws it)", "empty": "neither draws it"}
SHOWN = 5          # how many differing pixels a message lists


def _in_jupyter() -> bool:
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


@dataclass
class Difference:
    """A student's answer beside softpipe's: which pixels it adds, which it misses, and the picture.

    Attributes
    ----------
    adds, misses : list of (x, y)
        Window pixels (y up), sorted: drawn by the answer only / by softpipe only.
    picture : uint8 [H', W', 3]
        The zoomed difference picture (:data:`COLORS`, :data:`LEGEND`).
    message : str
        What the AssertionError says (or "... agree" when they do).
    """

    adds: List[Pixel]
    misses: List[Pixel]
    picture: np.ndarray
    message: str
    legend: Dict[str, str] = field(default_factory=lambda: dict(LEGEND))

    @property
    def ok(self) -> bool:
        return not self.adds and not self.misses

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        data = png(self.picture)
        keys = "".join(
            f'<span style="display:inline-block;width:12px;height:12px;margin:0 4px 0 12px;vertical-align:middle;'
            f'background:rgb{COLORS[k]};border:1px solid #888"></span>{text}' for k, text in self.legend.items())
        html = (f'<div><img src="data:image/png;base64,{base64.b64encode(data).decode()}" '
                f'style="image-rendering:pixelated"/><div style="font:12px sans-serif">{keys}</div>'
                f'<pre>{_escape(self.message)}</pre></div>')
        return {"image/png": data, "text/html": html, "text/plain": self.message}


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def pixel_set(value, name: str = "pixels") -> Set[Pixel]:
    """Window pixels (x, y), y up, from a set/list of pairs, a Coverage, or a bool mask [H, W] (row 0 at the top)."""
    if hasattr(value, "pixels") and callable(value.pixels):
        return {(int(x), int(y)) for x, y in value.pixels()}
    if isinstance(value, np.ndarray) and value.ndim == 2:
        rows, cols = np.nonzero(value)
        h = value.shape[0]
        return {(int(c), int(h - 1 - r)) for r, c in zip(rows, cols)}
    if value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a set of (x, y) pixels, got {type(value).__name__}")
    out = set()
    try:
        items = list(value)
    except TypeError:
        raise TypeError(f"{name} must be a set of (x, y) pixels, got {type(value).__name__}") from None
    for p in items:
        try:
            x, y = p
            out.add((int(x), int(y)))
        except (TypeError, ValueError):
            raise TypeError(f"{name} must hold (x, y) pairs of whole numbers, got {p!r}") from None
    return out


def _picture(answer: Set[Pixel], reference: Set[Pixel], width: int, height: int) -> np.ndarray:
    img = np.empty((height, width, 3), np.uint8)
    img[:] = COLORS["empty"]
    for key, pixels in (("both", answer & reference), ("adds", answer - reference), ("misses", reference - answer)):
        for x, y in pixels:
            if 0 <= x < width and 0 <= y < height:
                img[height - 1 - y, x] = COLORS[key]
    return zoomed(img)


def _show(diff: Difference, show: Optional[bool]) -> None:
    if show or (show is None and _in_jupyter()):
        from IPython.display import display
        display(diff)


def _failed(diff: Difference, show: Optional[bool]) -> AssertionError:
    """A check's failure: its picture shown (in Jupyter, or when asked), and the error to raise with its message."""
    _show(diff, show)
    return AssertionError(diff.message)


def check_coverage(answer, reference, *, width: Optional[int] = None, height: Optional[int] = None,
                   hint: Optional[Callable[[Pixel, str], Optional[str]]] = None, what: str = "pixels",
                   show: Optional[bool] = None) -> Difference:
    """Compare the pixels an answer draws with the pixels softpipe draws; raise where they differ.

    Parameters
    ----------
    answer, reference : set of (x, y), Coverage or bool mask [H, W]
        Window pixels, y up (a mask's row 0 is the top).
    width, height : int, optional
        The picture's size; by default just big enough for every pixel (or the masks' shape).
    hint : callable (pixel, "adds" | "misses") → str or None, optional
        Explains one differing pixel: the rule it shows broken.
    what : str
        What the pixels are, for the message ("the line's pixels", …).
    show : bool, optional
        Display the difference picture (in Jupyter by default) before raising.

    Returns
    -------
    Difference
        When the two agree.

    Raises
    ------
    AssertionError
        ``"<what> differ from softpipe's at N pixels (A your answer adds, M it misses): …"``,
        the first few pixels with hints, and what the picture's colors mean.
    """
    mine, ref = pixel_set(answer, "answer"), pixel_set(reference, "reference")
    for arr in (answer, reference):
        if isinstance(arr, np.ndarray) and arr.ndim == 2:
            height, width = height or arr.shape[0], width or arr.shape[1]
    every = mine | ref
    if width is None:
        width = max([x for x, _ in every if x >= 0] + [0]) + 2
    if height is None:
        height = max([y for _, y in every if y >= 0] + [0]) + 2
    adds, misses = sorted(mine - ref), sorted(ref - mine)
    picture = _picture(mine, ref, width, height)
    if not adds and not misses:
        return Difference([], [], picture, f"{what}: your answer and softpipe's agree at all {len(ref)} pixels")
    lines = [f"{what} differ from softpipe's at {len(adds) + len(misses)} pixel(s) "
             f"({len(adds)} your answer adds, {len(misses)} it misses; softpipe draws {len(ref)}):"]
    listed = [(p, "adds") for p in adds] + [(p, "misses") for p in misses]
    listed.sort(key=lambda pk: (pk[0][1], pk[0][0]))
    for p, kind in listed[:SHOWN]:
        why = hint(p, kind) if hint is not None else None
        verb = "your answer draws it, softpipe does not" if kind == "adds" else "softpipe draws it, your answer does not"
        lines.append(f"  pixel {p}: {verb}" + (f": {why}" if why else ""))
    if len(listed) > SHOWN:
        lines.append(f"  … and {len(listed) - SHOWN} more")
    lines.append("(the picture: red = your answer adds the pixel, blue = it misses it, gray = both draw it; "
                 "pixels are window coordinates (x, y), y up)")
    diff = Difference(adds, misses, picture, "\n".join(lines))
    raise _failed(diff, show)


# ------------------------------------------------------------------------------ lines

def _exact(v) -> Fraction:
    """A window coordinate as softpipe sees it: snapped to 1/256 pixel (round half to even)."""
    return Fraction(round(Fraction(v) * 256), 256)


def _diamond_holds(p, pixel: Pixel) -> bool:
    return abs(p[0] - pixel[0] - Fraction(1, 2)) + abs(p[1] - pixel[1] - Fraction(1, 2)) < Fraction(1, 2)


def _line_hint(pa, pb) -> Callable[[Pixel, str], Optional[str]]:
    a = (_exact(pa[0]), _exact(pa[1]))
    b = (_exact(pb[0]), _exact(pb[1]))
    x_major = abs(b[0] - a[0]) >= abs(b[1] - a[1])

    def hint(p: Pixel, kind: str) -> Optional[str]:
        if kind == "adds" and _diamond_holds(b, p):
            return (f"it holds the end point pb = ({float(b[0])}, {float(b[1])}): the diamond-exit rule "
                    f"leaves the last pixel out (a line is half-open, so a strip's joints are drawn once)")
        if kind == "misses" and _diamond_holds(a, p):
            return f"it holds the start point pa = ({float(a[0])}, {float(a[1])}): the first pixel is drawn"
        major, minor = (0, 1) if x_major else (1, 0)
        if b[major] == a[major]:
            return None
        centre = p[major] + Fraction(1, 2)
        t = (centre - a[major]) / (b[major] - a[major])
        if not 0 <= t <= 1:
            return ("it lies beyond the segment's ends along its major axis "
                    f"({'x' if x_major else 'y'}): one pixel per {'column' if x_major else 'row'} "
                    f"from pa's up to (not including) pb's")
        at = a[minor] + t * (b[minor] - a[minor])           # the line's minor coordinate there
        off = at - (p[minor] + Fraction(1, 2))
        if abs(off) == Fraction(1, 2):
            side = ("the one the shift enters: up for a rising line, down for a falling one" if x_major
                    else "the left one")
            return (f"the line passes exactly halfway between this pixel's centre and its neighbour's: GL "
                    f"moves the segment by (−ε, −ε²) to break the tie, which picks {side}")
        if kind == "adds" and abs(off) > Fraction(1, 2):
            return (f"the line passes {float(abs(off)):g} pixels from its centre along "
                    f"{'y' if x_major else 'x'}: a {'column' if x_major else 'row'} takes the one pixel "
                    f"whose centre is nearest the line")
        if kind == "misses":
            return (f"the line passes {float(abs(off)):g} pixels from its centre: it crosses this pixel's diamond "
                    f"|x − x_c| + |y − y_c| < ½, one pixel per {'column' if x_major else 'row'}")
        return None

    return hint


def check_line(answer, pa, pb, *, show: Optional[bool] = None) -> Difference:
    """A line drawer's pixels for the segment ``pa`` → ``pb`` (window coordinates, y up) against GL's
    diamond-exit rule (:func:`~softpipe.testing.reference_line`, which softpipe's lines match).

    Raises an AssertionError as :func:`check_coverage` does, with hints about the last pixel
    (left out), the first (drawn), and ties (broken by GL's (−ε, −ε²) shift).
    """
    ref = reference_line(pa, pb)
    return check_coverage(answer, ref, hint=_line_hint(pa, pb), show=show,
                          what=f"the pixels of the line ({_num(pa[0])}, {_num(pa[1])}) → ({_num(pb[0])}, {_num(pb[1])})")


def _num(v) -> str:
    return f"{float(v):g}"


# ------------------------------------------------------------------------------ triangles

def _edge_name(dx, dy) -> str:
    if dy < 0:
        return "left edge"
    if dy > 0:
        return "right edge"
    return "bottom edge" if dx > 0 else "top edge"


def _triangle_hint(triangles: np.ndarray) -> Callable[[Pixel, str], Optional[str]]:
    tris = [[(_exact(c[0]), _exact(c[1])) for c in t] for t in triangles]

    def hint(p: Pixel, kind: str) -> Optional[str]:
        cx, cy = p[0] + Fraction(1, 2), p[1] + Fraction(1, 2)
        found = []
        for k, t in enumerate(tris):
            area = (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0])
            if area == 0:
                continue
            if area < 0:                                  # clockwise: walk it counter-clockwise
                t = [t[0], t[2], t[1]]
            on, outside = [], False
            for i in range(3):
                (ax, ay), (bx, by) = t[i], t[(i + 1) % 3]
                e = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
                if e < 0:
                    outside = True
                elif e == 0:
                    on.append(((ax, ay), (bx, by)))
            if outside:
                continue
            cw = " (it is clockwise: walk it the other way, or negate its edge functions)" if area < 0 else ""
            if not on:
                found.append(f"its centre is strictly inside triangle {k}{cw}: every edge function is > 0 there")
                continue
            names = []
            owned = True
            for (ax, ay), (bx, by) in on:
                name = _edge_name(bx - ax, by - ay)
                names.append(f"{name} ({_num(ax)}, {_num(ay)})→({_num(bx)}, {_num(by)})")
                owned = owned and name in ("left edge", "bottom edge")
            where = " and ".join(names)
            rule = ("the fill rule covers it (left edges and bottom edges, y up, own the centres on them)" if owned
                    else "the fill rule leaves it out (only left edges and bottom edges, y up, own the centres "
                         "on them; top and right edges do not)")
            found.append(f"its centre lies exactly on triangle {k}'s {where}: {rule}{cw}")
        if not found:
            return "its centre is outside every triangle (some edge function is < 0 there)" if kind == "adds" else None
        return "; ".join(found)

    return hint


def check_triangles(answer, triangles, width: int, height: int, *, show: Optional[bool] = None) -> Difference:
    """A rasterizer's pixels for ``triangles`` ([T, 3, 2], window coordinates, y up) on a
    ``width``×``height`` framebuffer against softpipe's raster of the same triangles
    (:func:`~softpipe.testing.coverage`: snapped to 1/256 pixel, the fill rule of docs/conventions.md).

    Raises an AssertionError as :func:`check_coverage` does; a hint says when a differing
    pixel's centre lies exactly on an edge, which edge (left, right, top, bottom), and
    whether the fill rule gives it to the triangle.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1] != 3 or tri.shape[2] < 2:
        raise ValueError(f"triangles must be [T, 3, 2] window coordinates, got an array of shape {tri.shape}")
    ref = coverage(tri[:, :, :2], width, height)
    return check_coverage(answer, ref.pixels(), width=width, height=height, hint=_triangle_hint(tri[:, :, :2]),
                          what=f"the pixels of {len(tri)} triangle(s)", show=show)


# ------------------------------------------------------------------------------ the depth test

def reference_winners(trace) -> Tuple[Dict[Pixel, int], List[Tuple[int, int, float, int]]]:
    """The output merger's decisions in a trace: pixel (x, y) → the triangle whose fragment was
    written last there; and the fragments in draw order as (x, y, depth, triangle), y up."""
    from softpipe.pipeline.output import VERDICTS
    frags, verdict = trace.fragments, trace.merged.verdict
    written = VERDICTS.index("written")
    h = trace.height
    order = []
    winners: Dict[Pixel, int] = {}
    for k in range(len(frags)):
        x, y = int(frags.x[k]), h - 1 - int(frags.y[k])
        t = int(frags.primitive_id[k])
        order.append((x, y, float(frags.depth[k]), t))
        if verdict[k] == written:
            winners[(x, y)] = t
    return winners, order


def trace_fragments(trace) -> List[Tuple[int, int, float, int]]:
    """A traced draw's fragments in draw order as (x, y, depth, triangle): window pixel (y up), window
    depth, and the input triangle; what a depth-test loop reads."""
    return reference_winners(trace)[1]


def check_depth_test(answer: Mapping[Pixel, int], trace, *, show: Optional[bool] = None) -> Difference:
    """Which triangle a depth-test loop kept at each pixel (``{(x, y): triangle}``, y up) against the
    output merger's verdicts in ``trace`` (a draw with ``depth_test="less"``, the depth buffer cleared to 1).

    Raises an AssertionError as :func:`check_coverage` does, listing the pixels where the answer
    kept another triangle (or none), with the fragments there and the rule the answer seems to break.
    """
    if not isinstance(answer, Mapping):
        raise TypeError(f"the depth test's answer must be a dict {{(x, y): triangle}}, got {type(answer).__name__}")
    ref, order = reference_winners(trace)
    at: Dict[Pixel, List[Tuple[float, int]]] = {}
    for x, y, z, t in order:
        at.setdefault((x, y), []).append((z, t))
    mine = {(int(p[0]), int(p[1])): int(t) for p, t in answer.items()}
    wrong = sorted((p for p in set(mine) | set(ref) if mine.get(p) != ref.get(p)), key=lambda p: (p[1], p[0]))
    w, h = trace.width, trace.height
    img = np.empty((h, w, 3), np.uint8)
    img[:] = COLORS["empty"]
    for (x, y) in ref:
        img[h - 1 - y, x] = COLORS["both"]
    for (x, y) in wrong:
        if 0 <= x < w and 0 <= y < h:
            img[h - 1 - y, x] = COLORS["adds"] if (x, y) in mine else COLORS["misses"]
    legend = {"both": "you keep the triangle softpipe keeps", "adds": "you keep another triangle",
              "misses": "you keep none, softpipe keeps one", "empty": "no fragment"}
    if not wrong:
        return Difference([], [], zoomed(img), f"the depth test: your answer and softpipe's agree at all {len(ref)} "
                          "pixels", legend)
    lines = [f"the depth test keeps another triangle than softpipe's at {len(wrong)} of {len(ref)} pixel(s):"]
    for p in wrong[:SHOWN]:
        frs = at.get(p, [])
        listing = ", ".join(f"triangle {t} at depth {z:.4g}" for z, t in frs)
        lines.append(f"  pixel {p}: you keep {_tri(mine.get(p))}, softpipe keeps {_tri(ref.get(p))} "
                     f"(fragments in draw order: {listing}): {_depth_hint(mine.get(p), ref.get(p), frs)}")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    lines.append("(the picture: red = you keep another triangle, blue = you keep none, gray = you agree)")
    diff = Difference(sorted(p for p in wrong if p in mine), sorted(p for p in wrong if p not in mine),
                      zoomed(img), "\n".join(lines), legend)
    raise _failed(diff, show)


def _tri(t: Optional[int]) -> str:
    return "no triangle" if t is None else f"triangle {t}"


def _depth_hint(mine: Optional[int], ref: Optional[int], frs: Sequence[Tuple[float, int]]) -> str:
    if not frs:
        return "no fragment covers this pixel: keep nothing there"
    if mine is None:
        return "a fragment passes when its depth is less than the stored one, and the depth buffer starts at 1.0"
    depth = {t: z for z, t in reversed(frs)}                 # the first fragment of each triangle
    if ref is None:
        return "no fragment there is nearer than 1.0, the cleared depth buffer"
    zm, zr = depth.get(mine), depth.get(ref)
    if zm is None:
        return f"triangle {mine} has no fragment here"
    if zm == zr:
        return ("the two are at the same depth: 'less' keeps the one drawn first (the later one is not less, "
                "it is equal)")
    if zm == max(z for z, _ in frs) and len(frs) > 1 and mine == frs[-1][1]:
        return ("you keep the fragment drawn last, though it is farther: write a fragment only when its depth "
                "is less than the depth buffer's, and store its depth when it passes")
    if zm == max(z for z, _ in frs):
        return "you keep the farthest fragment: the comparison is the wrong way round ('less': nearer wins)"
    return (f"triangle {ref}'s fragment is nearer ({zr:.4g} < {zm:.4g}): after a fragment passes, its depth "
            "must be stored, so later farther ones fail")


# ------------------------------------------------------------------------------ interpolation

#: How far an interpolated value may be from the fragment stage's and still agree (float64 both ways).
TOLERANCE = 1e-6


def _checker(values: np.ndarray) -> np.ndarray:
    """A varying as a picture's gray level: two components as a checkerboard of 4 squares per unit
    (a texture's uv), otherwise the first component."""
    if values.shape[1] >= 2:
        squares = np.floor(values[:, 0] * 4) + np.floor(values[:, 1] * 4)
        return np.where(squares % 2 == 0, 0.85, 0.2)
    return np.clip(values[:, 0], 0.0, 1.0)


def _panels(*images: np.ndarray) -> np.ndarray:
    """Zoomed pictures side by side, a white gap between them."""
    shown = [zoomed(img) for img in images]
    height = max(s.shape[0] for s in shown)
    gap = np.full((height, 16, 3), 255, np.uint8)
    parts = []
    for s in shown:
        pad = np.full((height - s.shape[0], s.shape[1], 3), 255, np.uint8)
        parts += [np.concatenate([s, pad]), gap]
    return np.concatenate(parts[:-1], axis=1)


def _interpolation_hint(values, inv_w, bary, mine) -> Optional[str]:
    """The classic mistakes: which wrong formula reproduces the answer at every differing fragment."""
    def close(formula) -> bool:
        return all(np.allclose(m, formula(v, q, b), rtol=0, atol=TOLERANCE)
                   for v, q, b, m in zip(values, inv_w, bary, mine))
    if close(lambda v, q, b: b @ v):
        return ("your answer interpolates linearly in the window (noperspective): v = Σ b_k v_k. A smooth varying is "
                "perspective-correct: weight each corner by b_k / w_k = b_k · inv_w[k] and divide by the weights' "
                "sum, v = Σ (b_k / w_k) v_k / Σ (b_k / w_k)")
    if close(lambda v, q, b: (b * q) @ v):
        return ("you weight each corner by b_k / w_k but do not divide by the weights' sum Σ (b_k / w_k): "
                "the weights must add up to 1")
    if close(lambda v, q, b: (b / q) @ v / (b / q).sum()):
        return "you weight each corner by b_k · w_k: inv_w[k] is already 1/w_k, so the weight is b_k · inv_w[k]"
    return None


def check_interpolation(interpolate: Callable, trace, varying: str, *, show: Optional[bool] = None) -> Difference:
    """A student's interpolation of ``varying`` against the fragment stage's, at every fragment of ``trace``.

    ``interpolate(values, inv_w, bary)`` gets one fragment's triangle: the corners' values
    ``[3, n]``, their 1/w_clip ``[3]`` and the fragment's window-space barycentrics ``[3]``;
    it returns the varying's ``n`` components there. softpipe's value is what the shader
    received (:meth:`~softpipe.pipeline.trace.Trace.fragment_inputs`). The picture shows both
    (a two-component varying as a checkerboard of 4 squares per unit, as a texture's uv) and
    where they differ (red, brighter the larger the difference).

    Raises
    ------
    AssertionError
        ``"the interpolated <varying> differs from softpipe's at N of M fragment(s) …"``, the first
        few fragments, and the mistake when it is a classic one (linear in the window,
        the weights not divided by their sum, weighted by w instead of 1/w).
    ValueError
        When ``varying`` is not one of the draw's varyings, or the answer has another shape.
    """
    f, prims = trace.fragments, trace.primitives
    names = [field[0] for field in prims.layout.fields]
    if varying not in names:
        raise ValueError(f"check_interpolation: the draw has no varying {varying!r}; its varyings are {names}")
    h, w = trace.height, trace.width
    values, inv_w, bary, mine, ref, pixels = [], [], [], [], [], []
    for k in range(len(f)):
        t = int(f.triangle[k])
        v = np.asarray(prims.layout.unpack(prims.varyings[t])[varying], dtype=np.float64).reshape(3, -1)
        q, b = np.array(prims.inv_w[t], dtype=np.float64), np.array(f.bary[k], dtype=np.float64)
        got = np.asarray(interpolate(v.copy(), q.copy(), b.copy()), dtype=np.float64).reshape(-1)
        if got.shape != (v.shape[1],):
            raise ValueError(f"interpolate must return the {v.shape[1]} component(s) of {varying!r} at the fragment, "
                             f"got an array of shape {got.shape}")
        expected = np.asarray(getattr(trace.fragment_inputs(k)[0], varying), dtype=np.float64).reshape(-1)
        values.append(v)
        inv_w.append(q)
        bary.append(b)
        mine.append(got)
        ref.append(expected)
        pixels.append((int(f.x[k]), h - 1 - int(f.y[k])))
    mine_a, ref_a = np.array(mine).reshape(len(f), -1), np.array(ref).reshape(len(f), -1)
    error = np.abs(mine_a - ref_a).max(axis=1) if len(f) else np.zeros(0)
    error = np.where(np.isnan(error), np.inf, error)
    yours, theirs, diff = (np.empty((h, w, 3), np.uint8) for _ in range(3))
    for img in (yours, theirs, diff):
        img[:] = COLORS["empty"]
    g_mine, g_ref = _checker(np.nan_to_num(mine_a)), _checker(ref_a)
    for k, (x, y) in enumerate(pixels):
        yours[h - 1 - y, x] = round(255 * g_mine[k])
        theirs[h - 1 - y, x] = round(255 * g_ref[k])
        diff[h - 1 - y, x] = COLORS["both"] if error[k] <= TOLERANCE else \
            (min(255, 90 + round(1650 * min(error[k], 0.1))), 40, 30)
    picture = _panels(yours, theirs, diff)
    legend = {"empty": "no fragment", "both": "your value agrees with softpipe's",
              "adds": "your value differs (brighter: by more)"}
    wrong = [k for k in range(len(f)) if error[k] > TOLERANCE]
    if not wrong:
        return Difference([], [], picture, f"the interpolated {varying}: your answer and softpipe's agree at all "
                          f"{len(f)} fragments", legend)
    worst = max(wrong, key=lambda k: error[k])
    lines = [f"the interpolated {varying} differs from softpipe's at {len(wrong)} of {len(f)} fragment(s) (by up to "
             f"{error[worst]:.3g}, at pixel {pixels[worst]}):"]
    for k in sorted(wrong, key=lambda k: (pixels[k][1], pixels[k][0]))[:SHOWN]:
        lines.append(f"  pixel {pixels[k]}: yours {_vector(mine_a[k])}, softpipe's {_vector(ref_a[k])} "
                     f"(barycentrics {_vector(bary[k])}, 1/w {_vector(inv_w[k])})")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    hint = _interpolation_hint(*([a[k] for k in wrong] for a in (values, inv_w, bary, mine)))
    if hint:
        lines.append(hint)
    lines.append(f"(the picture: yours, softpipe's, and where they differ in red; {varying} drawn as "
                 + ("a checkerboard of 4 squares per unit)" if ref_a.shape[1] >= 2 else "a gray level)"))
    d = Difference([pixels[k] for k in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)


def _vector(v) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in np.ravel(v)) + ")"


# ------------------------------------------------------------------------------ transforms and the camera

#: The cameras :func:`check_camera` tries: (eye, target, up) and (fovy in degrees, aspect, near, far).
CAMERAS = [((3.0, 2.0, 4.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
           ((-2.0, 1.0, -3.5), (0.5, 0.0, 0.0), (0.0, 1.0, 0.0)),
           ((0.5, 4.0, 0.5), (0.0, 0.0, 0.0), (0.0, 0.0, -1.0))]
PROJECTIONS = [(50.0, 4 / 3, 0.5, 20.0), (90.0, 1.0, 1.0, 10.0), (30.0, 2.0, 0.1, 100.0)]


def _boxes() -> np.ndarray:
    """Two boxes, a big one at the origin and a small one on its right (+x): a picture that shows a
    mirrored camera. Triangles [T, 3, 3], counter-clockwise seen from outside."""
    quads = [((0, 2, 6, 4), 0), ((1, 5, 7, 3), 0), ((0, 4, 5, 1), 1), ((2, 3, 7, 6), 1), ((0, 1, 3, 2), 2),
             ((4, 6, 7, 5), 2)]
    tris = []
    for centre, half in (((0.0, 0.0, 0.0), 0.6), ((1.1, 0.35, 0.0), 0.25)):
        corners = np.array([[(i >> 2) & 1, (i >> 1) & 1, i & 1] for i in range(8)], float)[:, ::-1]
        corners = np.asarray(centre) + (corners * 2 - 1) * half
        for (a, b, c, d), _ in quads:
            tris += [corners[[a, b, c]], corners[[a, c, d]]]
    return np.array(tris)


def _matrix_hint(name: str, mine: np.ndarray, ref: np.ndarray) -> Optional[str]:
    """The classic mistakes: the transpose, a left-handed look_at, Direct3D's depth range [0, 1]."""
    def close(a) -> bool:
        return np.allclose(mine, a, rtol=0, atol=1e-9)
    if close(ref.T):
        return ("your matrix is the transpose of softpipe's: softpipe's matrices act on column vectors "
                "(p' = M @ p), so the translation goes in the last column, M[:3, 3], not the last row "
                "(docs/conventions.md)")
    if close(np.diag([-1.0, 1.0, -1.0, 1.0]) @ ref):
        return ("your look_at is left-handed (Direct3D's LookAtLH: x = up × f, z = f): softpipe's eye space is "
                "right-handed, the camera looking down −Z, so its rows are s = f × up, u = s × f and −f "
                "(docs/conventions.md)")
    if close(np.diag([1.0, 1.0, -1.0, 1.0]) @ ref):
        return ("your camera looks down +Z: in softpipe's eye space it looks down −Z, so the third row is −f, "
                "not f (docs/conventions.md)")
    d3d = ref.copy()
    d3d[2] = (ref[2] + ref[3]) / 2                           # z_ndc' = (z_ndc + 1)/2: near → 0, far → 1
    if close(d3d):
        return ("your projection maps depth to [0, 1] (Direct3D's and Vulkan's clip space): OpenGL's, and "
                "softpipe's, maps the near plane to z_ndc = −1 and the far plane to +1; the viewport makes "
                "window depth [0, 1] later (docs/conventions.md)")
    if name == "perspective" and np.allclose(mine[2:], ref[2:], rtol=0, atol=1e-9) and not np.isclose(
            mine[1, 1], ref[1, 1]):
        return (f"your y scale M[1, 1] is {mine[1, 1]:.6g}, softpipe's {ref[1, 1]:.6g} = 1/tan(fovy/2): fovy is "
                f"the whole vertical angle, in degrees (M[0, 0] is M[1, 1]/aspect)")
    return None


def _depth_picture(depth: np.ndarray, low: float, high: float) -> np.ndarray:
    img = np.empty(depth.shape + (3,), np.uint8)
    img[:] = COLORS["empty"]
    hit = depth < 1.0
    level = 1.0 - (depth[hit] - low) / max(high - low, 1e-12)          # near is bright
    img[hit] = np.round(60 + 195 * np.clip(level, 0.0, 1.0))[:, None].astype(np.uint8)
    return img


def _render_depth(mvp: np.ndarray, width: int, height: int) -> np.ndarray:
    from softpipe.pipeline.draw import draw
    from softpipe.pipeline.framebuffer import Framebuffer
    p = _boxes().reshape(-1, 3)
    clip = (mvp @ np.c_[p, np.ones(len(p))].T).T
    fb = Framebuffer(width, height)
    draw(fb, clip, varyings={"color": np.ones((len(p), 3))}, cull="back")
    return np.asarray(fb.depth, dtype=np.float64)


def check_camera(look_at: Callable, perspective: Callable, width: int = 32, height: int = 24, *,
                 show: Optional[bool] = None) -> Difference:
    """A student's ``look_at(eye, target, up)`` and ``perspective(fovy, aspect, near, far)`` against
    softpipe's (:func:`softpipe.look_at`, :func:`softpipe.perspective`) on the cameras of
    :data:`CAMERAS` and :data:`PROJECTIONS`, numerically (to 1e-9) and by rendering two boxes through
    both cameras: the picture shows the depth buffer with your matrices, with softpipe's, and which
    pixels differ (red: yours draws the pixel, softpipe's does not; blue: the other way; orange:
    both draw it at another depth).

    Raises
    ------
    AssertionError
        ``"look_at(eye=…, target=…, up=…) differs from softpipe's …"`` (or ``perspective(…)``), both
        matrices, and the mistake when it is a classic one (the transpose, a left-handed look_at, a
        camera looking down +Z, the depth range [0, 1], the field of view's angle).
    """
    from softpipe.pipeline.transforms import look_at as ref_look_at
    from softpipe.pipeline.transforms import perspective as ref_perspective
    cases: list = [("look_at", f"look_at(eye={e}, target={t}, up={u})", look_at, ref_look_at, (e, t, u))
                   for e, t, u in CAMERAS]
    cases += [("perspective", f"perspective(fovy={a[0]:g}, aspect={a[1]:.4g}, near={a[2]:g}, far={a[3]:g})",
               perspective, ref_perspective, a) for a in PROJECTIONS]
    failed = None
    for name, call, mine_f, ref_f, args in cases:
        mine = np.asarray(mine_f(*args), dtype=np.float64)
        if mine.shape != (4, 4):
            raise ValueError(f"{call} must return a 4×4 matrix, got an array of shape {mine.shape}")
        ref = ref_f(*args)
        if not np.allclose(mine, ref, rtol=0, atol=1e-9):
            failed = (name, call, mine, ref)
            break
    eye, target, up = CAMERAS[0]
    fovy, _, near, far = PROJECTIONS[0]
    mvp_mine = np.asarray(perspective(fovy, width / height, near, far), np.float64) @ np.asarray(
        look_at(eye, target, up), np.float64)
    mvp_ref = ref_perspective(fovy, width / height, near, far) @ ref_look_at(eye, target, up)
    d_mine, d_ref = _render_depth(mvp_mine, width, height), _render_depth(mvp_ref, width, height)
    hit = np.concatenate([d_mine[d_mine < 1], d_ref[d_ref < 1]])
    low, high = (hit.min(), hit.max()) if len(hit) else (0.0, 1.0)
    diff = np.empty((height, width, 3), np.uint8)
    diff[:] = COLORS["empty"]
    a, b = d_mine < 1, d_ref < 1
    diff[a & b] = COLORS["both"]
    diff[a & b & ~np.isclose(d_mine, d_ref, rtol=0, atol=1e-6)] = (240, 150, 30)
    diff[a & ~b], diff[b & ~a] = COLORS["adds"], COLORS["misses"]
    picture = _panels(_depth_picture(d_mine, low, high), _depth_picture(d_ref, low, high), diff)
    legend = {"both": "the same pixel at the same depth", "adds": "only your camera draws it",
              "misses": "only softpipe's draws it", "empty": "neither draws it"}
    rows, cols = np.nonzero(a != b)
    adds = sorted((int(c), int(height - 1 - r)) for r, c in zip(rows, cols) if a[r, c])
    misses = sorted((int(c), int(height - 1 - r)) for r, c in zip(rows, cols) if b[r, c])
    if failed is None:
        return Difference(adds, misses, picture, f"look_at and perspective: your matrices and softpipe's agree on "
                          f"all {len(CAMERAS)} cameras and {len(PROJECTIONS)} projections", legend)
    name, call, mine, ref = failed
    worst = np.unravel_index(np.argmax(np.abs(mine - ref)), (4, 4))
    with np.printoptions(precision=4, suppress=True):
        lines = [f"{call} differs from softpipe's (by {abs(mine - ref)[worst]:.4g} at row {worst[0]}, column "
                 f"{worst[1]}):", "  yours:      " + str(np.round(mine, 12) + 0.0).replace("\n", "\n              "),
                 "  softpipe's: " + str(np.round(ref, 12) + 0.0).replace("\n", "\n              ")]
    hint = _matrix_hint(name, mine, ref)
    if hint:
        lines.append(hint)
    lines.append("(the picture: two boxes seen through your camera and through softpipe's, near is bright, and "
                 "where they differ: red = only yours draws the pixel, blue = only softpipe's, orange = another depth)")
    d = Difference(adds, misses, picture, "\n".join(lines), legend)
    raise _failed(d, show)


# ------------------------------------------------------------------------------ clipping

#: How far a clipped polygon's corner may be from softpipe's, in clip coordinates, and still agree (the
#: two compute the same crossing points, perhaps in another order of float operations).
CLIP_TOLERANCE = 1e-9
#: The near plane z ≥ −w as a row (a, b, c, d): inside where a·x + b·y + c·z + d·w ≥ 0.
NEAR_PLANE = (0.0, 0.0, 1.0, 1.0)

#: The further cases :func:`check_clipping` tries, each a triangle inside the view volume (clip coordinates
#: [3, 4]) and a plane (a, b, c, d) that softpipe clips it against as a user clip plane: one corner out (a
#: quadrilateral), two out (a smaller triangle), none out, a corner exactly on the plane, every corner out.
CLIP_CASES = [
    ("one corner beyond x = w/2", [(-0.6, -0.5, 0.1, 1.0), (0.8, -0.4, 0.2, 1.0), (0.1, 0.7, 0.0, 1.0)],
     (-1.0, 0.0, 0.0, 0.5)),
    ("two corners below y = −w/5, w varying", [(-0.9, -0.8, 0.0, 1.5), (1.2, -1.5, 0.3, 2.0), (0.3, 0.6, 0.2, 1.0)],
     (0.0, 1.0, 0.0, 0.2)),
    ("no corner beyond x = −w/2", [(-0.4, -0.5, 0.1, 1.0), (0.6, -0.4, 0.2, 1.0), (0.1, 0.7, 0.0, 1.0)],
     (1.0, 0.0, 0.0, 0.5)),
    ("a corner exactly on x = w/2", [(-0.6, -0.5, 0.1, 1.0), (0.5, -0.4, 0.2, 1.0), (0.1, 0.7, 0.0, 1.0)],
     (-1.0, 0.0, 0.0, 0.5)),
    ("every corner beyond y = w/2", [(-0.6, 0.6, 0.1, 1.0), (0.8, 0.7, 0.2, 1.0), (0.1, 0.9, 0.0, 1.0)],
     (0.0, -1.0, 0.0, 0.5)),
]


def _polygon_of_pieces(window: np.ndarray, inv_w: np.ndarray, width: int, height: int) -> np.ndarray:
    """The clip-space polygon [n, 4] whose fan (0, k, k + 1) softpipe's assembly emitted as ``window`` [P, 3, 3]
    and ``inv_w`` [P, 3]: the divide and the viewport (depth range [0, 1]) undone."""
    if not len(window):
        return np.zeros((0, 4))
    corners = [(window[0, 0], inv_w[0, 0]), (window[0, 1], inv_w[0, 1])] + [(window[k, 2], inv_w[k, 2])
                                                                             for k in range(len(window))]
    out = []
    for (xw, yw, zw), q in corners:
        w = 1.0 / q
        out.append((((xw / (width / 2)) - 1.0) * w, ((yw / (height / 2)) - 1.0) * w, (2.0 * zw - 1.0) * w, w))
    return np.array(out)


def _softpipe_polygon(triangle: np.ndarray, plane, width: int, height: int) -> np.ndarray:
    """softpipe's assembly of one clip-space triangle [3, 4] with ``plane`` as a user clip plane, as a polygon."""
    from softpipe.pipeline.draw import draw
    from softpipe.pipeline.framebuffer import Framebuffer
    trace = draw(Framebuffer(width, height), np.asarray(triangle, np.float64), varyings={"color": np.ones((3, 3))},
                 clip_planes=[list(plane)], trace=True)
    p = trace.primitives
    return _polygon_of_pieces(p.window, p.inv_w, width, height)


def _distance(plane, points: np.ndarray) -> np.ndarray:
    return points @ np.asarray(plane, np.float64) if len(points) else np.zeros(0)


def _same_polygon(mine: np.ndarray, ref: np.ndarray) -> bool:
    """The same corners in the same cyclic order (starting anywhere), to :data:`CLIP_TOLERANCE`."""
    if mine.shape != ref.shape:
        return False
    if not len(ref):
        return True
    return any(np.allclose(np.roll(mine, -k, axis=0), ref, rtol=0, atol=CLIP_TOLERANCE) for k in range(len(ref)))


def _without_repeats(poly: np.ndarray) -> np.ndarray:
    keep = [k for k in range(len(poly)) if not np.allclose(poly[k], poly[k - 1], rtol=0, atol=CLIP_TOLERANCE)]
    return poly[keep] if len(poly) > 1 else poly


def _clip_hint(triangle: np.ndarray, plane, mine: np.ndarray, ref: np.ndarray) -> Optional[str]:
    """The classic mistakes of Sutherland–Hodgman: corners outside kept, crossings left out, a corner on the
    plane taken as outside, the crossing's parameter from the wrong formula, the order lost."""
    d_tri, d_mine = _distance(plane, triangle), _distance(plane, mine)
    scale = max(1.0, float(np.abs(triangle).max()))
    if len(mine) and (d_mine < -CLIP_TOLERANCE * scale).any():
        k = int(np.argmin(d_mine))
        return (f"your corner {k}, {_vector(mine[k])}, is outside the plane: a·x + b·y + c·z + d·w = "
                f"{d_mine[k]:.4g} < 0 there. Keep a corner only where that distance is ≥ 0")
    if len(mine) and _same_polygon(_without_repeats(mine), ref):
        return ("your polygon holds a corner twice: a corner exactly on the plane (distance 0) is inside (d ≥ 0), "
                "so it is kept as it is, and no crossing point is added beside it")
    if len(mine) == len(ref) and len(ref) and _same_polygon(mine[::-1], ref):
        return ("your polygon has softpipe's corners in the opposite order: walk the edges in the polygon's "
                "order, k → k + 1, so that the clipped polygon keeps the triangle's winding (its facing)")
    if len(mine) < len(ref):
        inside = [k for k in range(3) if d_tri[k] >= 0]
        if len(mine) == len(inside) and all(any(np.allclose(m, triangle[k], rtol=0, atol=CLIP_TOLERANCE)
                                                for m in mine) for k in inside):
            return ("your polygon keeps the corners inside the plane but not the points where the edges cross it: "
                    "for an edge from corner a to corner b whose distances d_a, d_b have opposite signs, add "
                    "p_a + t·(p_b − p_a) with t = d_a / (d_a − d_b), between the two")
        return f"softpipe's polygon has {len(ref)} corners, yours {len(mine)}"
    if len(mine) == len(ref) and len(ref):
        off = [k for k in range(len(mine)) if abs(d_mine[k]) > CLIP_TOLERANCE * scale
               and not any(np.allclose(mine[k], t, rtol=0, atol=CLIP_TOLERANCE) for t in triangle)]
        if off:
            k = off[0]
            return (f"your corner {k}, {_vector(mine[k])}, is a new point but not on the plane (its distance is "
                    f"{d_mine[k]:.4g}, not 0): the crossing of the edge a → b is p_a + t·(p_b − p_a) with "
                    f"t = d_a / (d_a − d_b), the distances taken before any divide by w")
    return None


def _fan_pixels(poly: np.ndarray, width: int, height: int) -> Set[Pixel]:
    """The pixels the clipped polygon [n, 4] covers, drawn as its fan (0, k, k + 1) in front of the eye."""
    if len(poly) < 3 or not (poly[:, 3] > 0).all() or not np.isfinite(poly).all():
        return set()
    ndc = poly[:, :3] / poly[:, 3:4]
    win = np.c_[(ndc[:, 0] + 1) * width / 2, (ndc[:, 1] + 1) * height / 2]
    tris = np.array([[win[0], win[k], win[k + 1]] for k in range(1, len(win) - 1)])
    return {(int(x), int(y)) for x, y in coverage(tris, width, height).pixels()}


def check_clipping(clip_polygon: Callable, trace, *, plane=NEAR_PLANE, show: Optional[bool] = None) -> Difference:
    """A student's ``clip_polygon(polygon, plane)`` (Sutherland–Hodgman against one plane in clip space)
    against softpipe's primitive assembly.

    ``polygon`` is the corners' clip coordinates (float64 [n, 4], in order), ``plane`` a row (a, b, c, d):
    inside where a·x + b·y + c·z + d·w ≥ 0; the answer is the clipped polygon's corners [m, 4] (m = 0 when
    nothing is left). First every triangle of ``trace`` (a triangle list of clip coordinates) against
    ``plane`` (the near plane z ≥ −w by default: the one that cuts the lesson's triangle), softpipe's
    answer being the clipped pieces it emitted (the fan of its polygon, the divide and the viewport
    undone); then the triangles and planes of :data:`CLIP_CASES`, each drawn with its plane as a user clip
    plane. Corners agree to :data:`CLIP_TOLERANCE`, starting anywhere in the polygon but in its order.
    The picture shows the pixels of your polygon and of softpipe's, as :func:`check_coverage`'s does.

    Raises
    ------
    AssertionError
        ``"clipping <case> against the plane (a, b, c, d): your polygon differs from softpipe's"``, both
        polygons, and the mistake when it is a classic one (a corner outside kept, the crossing points left
        out, a corner on the plane counted out, a crossing off the plane, the order reversed).
    ValueError
        When ``trace`` is not a draw of a triangle list, or the answer is not [m, 4].
    """
    width, height = trace.width, trace.height
    position = np.asarray(trace.vertex.position, np.float64)
    indices = trace.call.indices
    corners = np.arange(len(position)) if indices is None else np.asarray(indices, np.int64).reshape(-1)
    if (trace.call.topology != "triangles" or trace.primitives.kind != "triangles" or len(corners) % 3
            or trace.primitives.input_count != len(corners) // 3):
        raise ValueError("check_clipping needs a trace of a triangle list (sp.draw(fb, clip, ..., trace=True)); this "
                         f"one drew {trace.primitives.input_count} {trace.primitives.kind} by the topology "
                         f"{trace.call.topology!r}")
    cases: List[Tuple[str, np.ndarray, Tuple[float, ...], np.ndarray]] = []
    p = trace.primitives
    for t in range(len(corners) // 3):
        rows = p.primitive_id == t
        cases.append((f"the draw's triangle {t}", position[corners[3 * t:3 * t + 3]], tuple(float(c) for c in plane),
                      _polygon_of_pieces(p.window[rows], p.inv_w[rows], width, height)))
    for case, listed, case_plane in CLIP_CASES:
        corners3 = np.asarray(listed, np.float64)
        cases.append((case, corners3, case_plane, _softpipe_polygon(corners3, case_plane, width, height)))
    results: List[Tuple[str, np.ndarray, Tuple[float, ...], np.ndarray, np.ndarray]] = []
    for name, tri, pl, ref in cases:
        got = clip_polygon(tri.copy(), np.array(pl))
        mine = np.asarray([] if got is None else got, dtype=np.float64)
        if mine.size == 0:
            mine = np.zeros((0, 4))
        if mine.ndim != 2 or mine.shape[1] != 4:
            raise ValueError(f"clip_polygon must return the clipped polygon's corners as an array [m, 4] of clip "
                             f"coordinates (x, y, z, w), got an array of shape {mine.shape} for {name}")
        results.append((name, tri, pl, mine, ref))
        if not _same_polygon(mine, ref):
            break
    name, tri, pl, mine, ref = results[-1] if not _same_polygon(results[-1][3], results[-1][4]) else results[0]
    failed = not _same_polygon(mine, ref)
    yours, theirs = _fan_pixels(mine, width, height), _fan_pixels(ref, width, height)
    adds, misses = sorted(yours - theirs), sorted(theirs - yours)
    picture = _picture(yours, theirs, width, height)
    if not failed:
        return Difference(adds, misses, picture, f"clipping: your polygons and softpipe's agree on all {len(cases)} "
                          f"triangles ({len(cases) - len(CLIP_CASES)} of the draw, {len(CLIP_CASES)} further cases)")
    plane_text = "(" + ", ".join(f"{c:g}" for c in pl) + ")"
    lines = [f"clipping {name} against the plane {plane_text}: your polygon differs from softpipe's "
             f"({len(mine)} corners, softpipe's {len(ref)}):",
             "  the triangle:  " + ", ".join(_vector(c) for c in tri),
             "  its distances: " + _vector(_distance(pl, tri)) + " (a·x + b·y + c·z + d·w; inside where ≥ 0)",
             "  yours:         " + (", ".join(_vector(c) for c in mine) or "nothing"),
             "  softpipe's:    " + (", ".join(_vector(c) for c in ref) or "nothing (every corner is outside)")]
    hint = _clip_hint(tri, pl, mine, ref)
    if hint:
        lines.append(hint)
    lines.append("(the picture: the pixels of your polygon and of softpipe's, drawn as fans: red = only yours covers "
                 "the pixel, blue = only softpipe's, gray = both; window coordinates (x, y), y up)")
    d = Difference(adds, misses, picture, "\n".join(lines))
    raise _failed(d, show)


# ------------------------------------------------------------------------------ shading

#: How far a shaded color may be from the fragment shader's and still agree (the shader's output is
#: float32: colors near 1 keep about 7 digits).
SHADING_TOLERANCE = 1e-5

#: One light's colors as :func:`check_blinn_phong` hands them to the answer: I_a, I_d, I_s (FORMULAS §10).
LightColors = namedtuple("LightColors", ["ambient", "diffuse", "specular"])


def _unit_rows(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _blinn_phong_rows(P, N, L, m, light, global_ambient, *, normalize_n=True, toward_eye=True, blinn=True,
                      b_factor=True, clamp_diffuse=True, with_ambient=True, unit_h=True, l_sign=1.0) -> np.ndarray:
    """FORMULAS §10 for one directional light at many fragments (rows), and its classic mistakes by flag."""
    N = _unit_rows(N) if normalize_n else N
    V = _unit_rows(-P if toward_eye else P)
    L = np.broadcast_to(l_sign * np.asarray(L, np.float64), N.shape)
    n_dot_l = (N * L).sum(axis=1)
    if blinn:
        S = L + V
        H = _unit_rows(S) if unit_h else S
        lobe = (N * H).sum(axis=1)
    else:
        R = 2 * n_dot_l[:, None] * N - L
        lobe = (R * V).sum(axis=1)
    base = np.maximum(lobe, 0.0)
    spec = np.where(base > 0, base ** m.shininess, 0.0) if m.shininess else np.ones_like(base)
    lit = n_dot_l > 0
    diffuse = n_dot_l if not clamp_diffuse else np.where(lit, n_dot_l, 0.0)
    spec = np.where(lit, spec, 0.0) if b_factor else spec
    kd, ks, ka, ke = (np.asarray(c, np.float64) for c in (m.kd, m.ks, m.ka, m.ke))
    color = ke + (ka * (np.asarray(global_ambient) + np.asarray(light.ambient)) if with_ambient else 0.0)
    return (color + diffuse[:, None] * kd * np.asarray(light.diffuse)
            + spec[:, None] * ks * np.asarray(light.specular))


#: The classic mistakes :func:`check_blinn_phong` recognizes: the flags of :func:`_blinn_phong_rows` that
#: reproduce the answer, and what to say.
SHADING_MISTAKES: List[Tuple[Dict[str, Any], str]] = [
    (dict(blinn=False), "you compute Phong's specular (R·V)ⁿ (FORMULAS §5); Blinn–Phong's is (N·H)₊ⁿ with the half "
                        "vector H = normalize(L + V) (FORMULAS §6)"),
    (dict(normalize_n=False), "the interpolated normal N is not of unit length: normalize it first (FORMULAS §12, "
                              "Phong shading: interpolate the normals, renormalize, shade every fragment)"),
    (dict(toward_eye=False), "your V points from the eye to the point: V is the unit vector from the point toward the "
                             "eye, normalize(−P) (the eye sits at the origin of eye space)"),
    (dict(l_sign=-1.0), "your L points the way the light travels: L is the unit vector from the point toward the "
                        "light"),
    (dict(unit_h=False), "your half vector L + V is not normalized: H = (L + V)/|L + V|"),
    (dict(b_factor=False), "your specular shines where N·L ≤ 0: the factor B (FORMULAS §4) is 0 there, for the "
                           "specular term as for the diffuse one"),
    (dict(clamp_diffuse=False), "your diffuse term goes negative where N·L < 0: with B (FORMULAS §4) it is 0 there"),
    (dict(with_ambient=False), "the ambient terms are missing: k_a · I_a,global + k_a · I_a of the light (FORMULAS §2, "
                               "§10)"),
]


def check_blinn_phong(blinn_phong: Callable, trace, *, show: Optional[bool] = None) -> Difference:
    """A student's ``blinn_phong(P, N, L, material, light, global_ambient)`` against the fragment shader's colors
    at every fragment of ``trace``, a draw with a per-fragment Blinn–Phong program (``"phong"``) lit by one
    directional light.

    The answer gets, for each fragment: P and N, the eye-space point and the interpolated (not yet
    unit) normal the shader received (its varyings ``position`` and ``normal``); L, the unit vector
    toward the light, in eye space; the material (``ke``, ``ka``, ``kd``, ``ks``, ``shininess``); the light's
    colors (:class:`LightColors`) and the global ambient light. It returns the color (r, g, b) of FORMULAS
    §10 for that one light. softpipe's is what the shader returned (:attr:`Trace.shaded`), to
    :data:`SHADING_TOLERANCE`. The picture shows your colors, softpipe's, and where they differ (red,
    brighter the larger the difference).

    Raises
    ------
    AssertionError
        ``"your Blinn–Phong differs from softpipe's at N of M fragment(s) …"``, the first few fragments, and
        the mistake when it is a classic one (:data:`SHADING_MISTAKES`: Phong's specular, N not normalized,
        V or L the wrong way, H not normalized, no B, no ambient).
    ValueError
        When the draw is not the ``phong`` program's, not lit by exactly one directional light without
        shadows, or the answer is not 3 (or 4) numbers.
    """
    from softpipe.language.contract import shader_name
    from softpipe.light.lighting import light_at, light_colors
    shader = shader_name(trace.call.fragment_shader) if trace.call.fragment_shader is not None else "the default"
    if shader != "softpipe.programs.phong.phong_fragment":
        raise ValueError(f"check_blinn_phong compares with the built-in program 'phong' (per-fragment Blinn–Phong, "
                         f"sp.draw_mesh(fb, mesh, camera, 'phong', ..., trace=True)); this draw's fragment shader is "
                         f"{shader}")
    uniforms = trace.call.uniforms
    lighting, m = getattr(uniforms, "lighting", None), getattr(uniforms, "material", None)
    if lighting is None or m is None or len(lighting.lights) != 1 or lighting.shadows is not None:
        count = "no" if lighting is None else len(lighting.lights)
        raise ValueError(f"check_blinn_phong needs a draw of a lit program (uniforms material and lighting) with one "
                         f"light and no shadows; this draw has {count} light(s)")
    L, f = light_at((0.0, 0.0, 0.0), lighting.lights, 0)
    probe, _ = light_at((1.0, 2.0, 3.0), lighting.lights, 0)
    if f != 1.0 or tuple(probe) != tuple(L):
        raise ValueError("check_blinn_phong needs a directional light (one L everywhere, no attenuation): "
                         "sp.Light.directional(direction)")
    names = [fld[0] for fld in trace.primitives.layout.fields]
    if "position" not in names or "normal" not in names:
        raise ValueError(f"check_blinn_phong needs the varyings 'position' and 'normal' (eye space, as the built-in "
                         f"programs pass them); the draw's varyings are {names}")
    light = LightColors(*light_colors(lighting.lights, 0))
    f = trace.fragments
    n = len(f)
    varyings, _ = trace.fragment_varyings(np.arange(n))
    layout = trace.primitives.layout
    P, N = varyings[:, layout.slice("position")], varyings[:, layout.slice("normal")]
    L = tuple(float(c) for c in L)
    mine = np.zeros((n, 3))
    for k in range(n):
        got = np.asarray(blinn_phong(P[k].copy(), N[k].copy(), L, m, light, tuple(lighting.global_ambient)),
                         dtype=np.float64).reshape(-1)
        if got.shape not in ((3,), (4,)):
            raise ValueError(f"blinn_phong must return the color (r, g, b), got an array of shape {got.shape}")
        mine[k] = got[:3]
    ref = np.asarray(trace.shaded.color, np.float64)[:, :3]
    error = np.abs(mine - ref).max(axis=1) if n else np.zeros(0)
    error = np.where(np.isnan(error), np.inf, error)
    h, w = trace.height, trace.width
    yours, theirs, diff = (np.empty((h, w, 3), np.uint8) for _ in range(3))
    for img in (yours, theirs, diff):
        img[:] = COLORS["empty"]
    rows, cols = np.asarray(f.y), np.asarray(f.x)
    yours[rows, cols] = np.round(255 * np.clip(np.nan_to_num(mine), 0, 1)).astype(np.uint8)
    theirs[rows, cols] = np.round(255 * np.clip(ref, 0, 1)).astype(np.uint8)
    bad = error > SHADING_TOLERANCE
    diff[rows, cols] = COLORS["both"]
    if bad.any():
        level = np.minimum(255, 90 + np.round(1650 * np.minimum(error[bad], 0.1))).astype(np.uint8)
        diff[rows[bad], cols[bad]] = np.stack([level, np.full_like(level, 40), np.full_like(level, 30)], axis=1)
    picture = _panels(yours, theirs, diff)
    legend = {"empty": "no fragment", "both": "your color agrees with softpipe's",
              "adds": "your color differs (brighter: by more)"}
    pixels = [(int(cols[k]), h - 1 - int(rows[k])) for k in range(n)]
    wrong = np.nonzero(bad)[0]
    if not len(wrong):
        return Difference([], [], picture, f"Blinn–Phong: your colors and softpipe's agree at all {n} fragments", legend)
    worst = int(wrong[np.argmax(error[wrong])])
    lines = [f"your Blinn–Phong differs from softpipe's at {len(wrong)} of {n} fragment(s) (by up to "
             f"{error[worst]:.3g}, at pixel {pixels[worst]}); the largest differences:"]
    for k in sorted(wrong.tolist(), key=lambda k: (-error[k], pixels[k][1], pixels[k][0]))[:SHOWN]:
        nn = N[k] / np.linalg.norm(N[k])
        lines.append(f"  pixel {pixels[k]}: yours {_vector(mine[k])}, softpipe's {_vector(ref[k])} "
                     f"(N·L = {float(nn @ np.asarray(L)):.4g})")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    for flags, text in SHADING_MISTAKES:
        guess = _blinn_phong_rows(P[wrong], N[wrong], L, m, light, lighting.global_ambient, **flags)
        if np.allclose(guess, mine[wrong], rtol=0, atol=SHADING_TOLERANCE):
            lines.append(text)
            break
    lines.append("(the picture: your colors, softpipe's, and where they differ in red)")
    d = Difference([pixels[k] for k in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)


# ------------------------------------------------------------------------------ textures

#: How far a filtered texel may be from softpipe's and still agree (texels are float32).
TEXTURE_TOLERANCE = 1e-5


def _wrap_rows(i: np.ndarray, size: int, mode: str) -> np.ndarray:
    if mode == "repeat":
        return np.mod(i, size)
    if mode == "clamp":
        return np.clip(i, 0, size - 1)
    m = np.mod(i, 2 * size) - size                          # mirrored repeat (GL Table 8.20)
    return size - 1 - np.where(m < 0, -(1 + m), m)


def _bilinear_rows(image: np.ndarray, u: np.ndarray, v: np.ndarray, wrap_s: str, wrap_t: str, *, half=True,
                   flip=True, swap=False, nearest=False) -> np.ndarray:
    """GL's LINEAR (or NEAREST) on one level at many (u, v), and its classic mistakes by flag."""
    h, w = image.shape[:2]
    x, y = u * w - (0.5 if half and not nearest else 0.0), v * h - (0.5 if half and not nearest else 0.0)
    i0, j0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    a, b = x - i0, y - j0
    if swap:
        a, b = 1 - a, 1 - b

    def texel(i, j):
        i, j = _wrap_rows(i, w, wrap_s), _wrap_rows(j, h, wrap_t)
        return image[h - 1 - j, i] if flip else image[j, i]
    if nearest:
        return texel(i0, j0)
    return ((1 - a) * (1 - b))[:, None] * texel(i0, j0) + (a * (1 - b))[:, None] * texel(i0 + 1, j0) + \
        ((1 - a) * b)[:, None] * texel(i0, j0 + 1) + (a * b)[:, None] * texel(i0 + 1, j0 + 1)


#: The classic mistakes :func:`check_bilinear` recognizes: the flags of :func:`_bilinear_rows` (and the wrap)
#: that reproduce the answer, and what to say.
TEXTURE_MISTAKES: List[Tuple[Dict[str, Any], str]] = [
    (dict(nearest=True), "your answer is the nearest texel (GL's NEAREST): bilinear filtering weights the four "
                         "texels around (u·W − ½, v·H − ½) by how near their centres are"),
    (dict(half=False), "texel centres sit at (i + ½)/W: subtract ½ before the floor, x = u·W − ½, i0 = floor(x), "
                       "α = x − i0 (and the same in v)"),
    (dict(flip=False), "your v runs down the image: row 0 of the image is its top, and v = 0 is its bottom, so "
                       "texel row j (counted from the bottom) is image[H − 1 − j]"),
    (dict(swap=True), "your weights are the wrong way round: texel i0 + 1 gets α, texel i0 gets 1 − α"),
    (dict(wrap="clamp"), "you clamp the texel indices at the edges (CLAMP_TO_EDGE): wrap them by the texture's mode "
                         "(repeat: i mod W and j mod H, each of the four texels on its own)"),
]


def check_bilinear(bilinear: Callable, trace, texture, varying: str = "uv", *,
                   show: Optional[bool] = None) -> Difference:
    """A student's ``bilinear(image, u, v)`` against :meth:`softpipe.Texture2D.sample` (GL's LINEAR on
    level 0, the texture's wrap modes) at every fragment of ``trace``.

    ``image`` is the texture's level 0 (float64 [H, W, 4], row 0 the top, as ``texture.levels[0]``); ``(u, v)``
    the texture coordinates the fragment shader received there (the varying ``varying``); the answer is
    the filtered (r, g, b, a). The texture's filter must be ``"bilinear"``. The picture shows your
    colors, softpipe's, and where they differ (red, brighter the larger the difference).

    Raises
    ------
    AssertionError
        ``"your bilinear filter differs from softpipe's at N of M fragment(s) …"``, the first few fragments
        with their uv, and the mistake when it is a classic one (:data:`TEXTURE_MISTAKES`: the nearest
        texel, the half-texel offset, v not flipped, the weights swapped, clamping instead of repeating).
    ValueError
        When the texture does not filter bilinearly, the draw has no such varying, or the answer is not 4
        (or 3) numbers.
    """
    if getattr(texture, "filter", None) != "bilinear":
        raise ValueError(f"check_bilinear compares with a texture whose filter is 'bilinear', got "
                         f"{getattr(texture, 'filter', type(texture).__name__)!r}: Texture2D(image, filter='bilinear')")
    layout = trace.primitives.layout
    if varying not in layout.names:
        raise ValueError(f"check_bilinear: the draw has no varying {varying!r}; its varyings are {list(layout.names)}")
    f = trace.fragments
    n = len(f)
    values, _ = trace.fragment_varyings(np.arange(n))
    uv = values[:, layout.slice(varying)][:, :2]
    image = np.asarray(texture.levels[0], np.float64)
    mine, ref = np.zeros((n, 4)), np.zeros((n, 4))
    for k in range(n):
        u, v = float(uv[k, 0]), float(uv[k, 1])
        got = np.asarray(bilinear(image.copy(), u, v), dtype=np.float64).reshape(-1)
        if got.shape not in ((3,), (4,)):
            raise ValueError(f"bilinear must return the filtered color (r, g, b, a), got an array of shape {got.shape}")
        mine[k, :len(got)] = got
        ref[k] = texture.sample(u, v)
        if len(got) == 3:
            mine[k, 3] = ref[k, 3]
    error = np.abs(mine - ref).max(axis=1) if n else np.zeros(0)
    error = np.where(np.isnan(error), np.inf, error)
    h, w = trace.height, trace.width
    yours, theirs, diff = (np.empty((h, w, 3), np.uint8) for _ in range(3))
    for img in (yours, theirs, diff):
        img[:] = COLORS["empty"]
    rows, cols = np.asarray(f.y), np.asarray(f.x)
    yours[rows, cols] = np.round(255 * np.clip(np.nan_to_num(mine[:, :3]), 0, 1)).astype(np.uint8)
    theirs[rows, cols] = np.round(255 * np.clip(ref[:, :3], 0, 1)).astype(np.uint8)
    bad = error > TEXTURE_TOLERANCE
    diff[rows, cols] = COLORS["both"]
    if bad.any():
        level = np.minimum(255, 90 + np.round(1650 * np.minimum(error[bad], 0.1))).astype(np.uint8)
        diff[rows[bad], cols[bad]] = np.stack([level, np.full_like(level, 40), np.full_like(level, 30)], axis=1)
    picture = _panels(yours, theirs, diff)
    legend = {"empty": "no fragment", "both": "your color agrees with softpipe's",
              "adds": "your color differs (brighter: by more)"}
    pixels = [(int(cols[k]), h - 1 - int(rows[k])) for k in range(n)]
    wrong = np.nonzero(bad)[0]
    if not len(wrong):
        return Difference([], [], picture, f"bilinear filtering: your colors and softpipe's agree at all {n} "
                          "fragments", legend)
    worst = int(wrong[np.argmax(error[wrong])])
    lines = [f"your bilinear filter differs from softpipe's at {len(wrong)} of {n} fragment(s) (by up to "
             f"{error[worst]:.3g}, at pixel {pixels[worst]}):"]
    for k in sorted(wrong.tolist(), key=lambda k: (pixels[k][1], pixels[k][0]))[:SHOWN]:
        lines.append(f"  pixel {pixels[k]}: uv {_vector(uv[k])}: yours {_vector(mine[k])}, softpipe's "
                     f"{_vector(ref[k])}")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    for flags, text in TEXTURE_MISTAKES:
        flags = dict(flags)
        ws = wt = flags.pop("wrap", None)
        if ws is not None and ws == texture.wrap_s and wt == texture.wrap_t:
            continue
        guess = _bilinear_rows(image, uv[wrong, 0], uv[wrong, 1], ws or texture.wrap_s, wt or texture.wrap_t, **flags)
        if np.allclose(guess, mine[wrong], rtol=0, atol=TEXTURE_TOLERANCE):
            lines.append(text)
            break
    lines.append(f"(the picture: your colors, softpipe's, and where they differ in red; a {texture.width}×"
                 f"{texture.height} texture, wrap {texture.wrap_s!r})")
    d = Difference([pixels[k] for k in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)


#: How far a student's level of detail λ may be from softpipe's and still agree (both are float64 log2s).
MIP_TOLERANCE = 1e-9


def _mip_rows(dx: np.ndarray, dy: np.ndarray, width: int, height: int, *, texels=True, sqrt=True, log=True,
              combine="max", swap=False, log2=True) -> np.ndarray:
    """λ = log2 ρ (GL's scale factor, docs/texture-mapping.md) at many derivative pairs, and its classic
    mistakes by flag."""
    sw, sh = (float(height), float(width)) if swap else (float(width), float(height))
    if not texels:
        sw = sh = 1.0
    rx = (dx[:, 0] * sw) ** 2 + (dx[:, 1] * sh) ** 2
    ry = (dy[:, 0] * sw) ** 2 + (dy[:, 1] * sh) ** 2
    if sqrt:
        rx, ry = np.sqrt(rx), np.sqrt(ry)
    rho = {"max": np.maximum, "sum": np.add, "min": np.minimum}[combine](rx, ry)
    if not log:
        return rho
    with np.errstate(divide="ignore"):
        return np.log2(rho) if log2 else np.log(rho)


#: The classic mistakes :func:`check_mip_level` recognizes: the flags of :func:`_mip_rows` that reproduce the
#: answer, and what to say.
MIP_MISTAKES: List[Tuple[Dict[str, Any], str]] = [
    (dict(texels=False), "your ρ is in uv units: measure the derivatives in texels of level 0, ∂u·W and ∂v·H "
                         "(W × H the texture's size), before taking their lengths; λ = log2 ρ then counts halvings "
                         "from level 0"),
    (dict(swap=True), "you scale u by the height and v by the width: u runs across the image, ∂u·W, and v up it, "
                      "∂v·H"),
    (dict(sqrt=False), "you take log2 of ρ² (the squared lengths): ρ is the length sqrt((∂u/∂x·W)² + (∂v/∂x·H)²), "
                       "so λ = log2 ρ = ½·log2(ρ²)"),
    (dict(log=False), "your λ is ρ itself (texels per pixel): the level is its log2, λ = log2 ρ (each level halves "
                      "the texels)"),
    (dict(log2=False), "you take the natural log: λ = log2 ρ (each level halves the texels), ln ρ / ln 2"),
    (dict(combine="sum"), "you add the two lengths: ρ is the larger of the footprint along x and along y, "
                          "max(ρ_x, ρ_y), not their sum"),
    (dict(combine="min"), "you take the smaller of the two lengths: ρ is the larger, max(ρ_x, ρ_y), so the level "
                          "is coarse enough for the longer side of the pixel's footprint"),
]


def check_mip_level(level_of_detail: Callable, trace, texture, varying: str = "uv", *,
                    show: Optional[bool] = None) -> Difference:
    """A student's ``level_of_detail(duv_dx, duv_dy, width, height)`` against softpipe's level selection
    (:func:`softpipe.light.texture.mip_level`, what ``texture_grad`` samples at) at every fragment of ``trace``.

    ``duv_dx`` and ``duv_dy`` are the screen-space derivatives of the varying ``varying`` that the fragment
    shader received there ((∂u/∂x, ∂v/∂x) and (∂u/∂y, ∂v/∂y), ``derivatives.dx.uv``), ``width`` and
    ``height`` level 0's size in texels; the answer is λ = log2 ρ, unclamped (GL's scale factor:
    docs/texture-mapping.md, "Far away: mipmaps and the level of detail"). The draw's fragment shader
    must take derivatives (a fourth parameter). The picture shows your λ, softpipe's (black: λ ≤ 0,
    white: the last level), and where they differ.

    Raises
    ------
    AssertionError
        ``"your level of detail differs from softpipe's at N of M fragment(s) …"``, the first few fragments
        with their derivatives, and the mistake when it is a classic one (:data:`MIP_MISTAKES`: uv units
        instead of texels, W and H swapped, log2 of ρ², ρ without the log, the natural log, the sum or the
        smaller of the two lengths instead of the larger).
    ValueError
        When the draw's fragment shader takes no derivatives, the draw has no such varying, or the answer
        is not a number.
    """
    from softpipe.light.texture import mip_level  # softpipe's own selection, the one texture_grad uses

    layout = trace.primitives.layout
    if varying not in layout.names:
        raise ValueError(f"check_mip_level: the draw has no varying {varying!r}; its varyings are {list(layout.names)}")
    f = trace.fragments
    n = len(f)
    uniform = texture.__softpipe_uniform__()
    width, height = int(texture.width), int(texture.height)
    dx, dy = np.zeros((n, 2)), np.zeros((n, 2))
    mine, ref = np.zeros(n), np.zeros(n)
    for k in range(n):
        inputs = trace.fragment_inputs(k)
        if len(inputs) < 4:
            raise ValueError("check_mip_level needs a draw whose fragment shader takes derivatives: "
                             "def fragment(varyings, uniforms, frag, derivatives)")
        derivatives = inputs[3]
        dx[k] = tuple(getattr(derivatives.dx, varying))[:2]
        dy[k] = tuple(getattr(derivatives.dy, varying))[:2]
        got = level_of_detail((float(dx[k, 0]), float(dx[k, 1])), (float(dy[k, 0]), float(dy[k, 1])), width, height)
        try:
            mine[k] = float(got)
        except (TypeError, ValueError):
            raise ValueError(f"level_of_detail must return the level of detail λ (a number), got "
                             f"{type(got).__name__} {got!r}") from None
        ref[k] = mip_level(uniform, (float(dx[k, 0]), float(dx[k, 1])), (float(dy[k, 0]), float(dy[k, 1])))
    same = (mine == ref) | (np.abs(mine - ref) <= MIP_TOLERANCE)      # equal infinities agree too
    error = np.where(same, 0.0, np.abs(mine - ref))
    error = np.where(np.isnan(error), np.inf, error)
    top = max(len(texture.levels) - 1, 1)
    h, w = trace.height, trace.width
    yours, theirs, diff = (np.empty((h, w, 3), np.uint8) for _ in range(3))
    for img in (yours, theirs, diff):
        img[:] = COLORS["empty"]
    rows, cols = np.asarray(f.y), np.asarray(f.x)

    def gray(lam: np.ndarray) -> np.ndarray:
        g = np.round(255 * np.clip(np.nan_to_num(lam, nan=0.0, posinf=top, neginf=0.0), 0, top) / top)
        return np.repeat(g.astype(np.uint8)[:, None], 3, axis=1)
    yours[rows, cols] = gray(mine)
    theirs[rows, cols] = gray(ref)
    bad = error > MIP_TOLERANCE
    diff[rows, cols] = COLORS["both"]
    if bad.any():
        level = np.minimum(255, 90 + np.round(165 * np.minimum(error[bad], 1.0))).astype(np.uint8)
        diff[rows[bad], cols[bad]] = np.stack([level, np.full_like(level, 40), np.full_like(level, 30)], axis=1)
    picture = _panels(yours, theirs, diff)
    legend = {"empty": "no fragment", "both": "your λ agrees with softpipe's",
              "adds": "your λ differs (brighter: by more)"}
    pixels = [(int(cols[k]), h - 1 - int(rows[k])) for k in range(n)]
    wrong = np.nonzero(bad)[0]
    if not len(wrong):
        return Difference([], [], picture, f"level of detail: your λ and softpipe's agree at all {n} fragments",
                          legend)
    worst = int(wrong[np.argmax(error[wrong])])
    lines = [f"your level of detail differs from softpipe's at {len(wrong)} of {n} fragment(s) (by up to "
             f"{error[worst]:.3g}, at pixel {pixels[worst]}):"]
    for k in sorted(wrong.tolist(), key=lambda k: (pixels[k][1], pixels[k][0]))[:SHOWN]:
        lines.append(f"  pixel {pixels[k]}: duv_dx {_vector(dx[k])}, duv_dy {_vector(dy[k])}: yours "
                     f"{mine[k]:.6g}, softpipe's {ref[k]:.6g}")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    for flags, text in MIP_MISTAKES:
        guess = _mip_rows(dx[wrong], dy[wrong], width, height, **flags)
        if np.allclose(guess, mine[wrong], rtol=0, atol=MIP_TOLERANCE):
            lines.append(text)
            break
    lines.append(f"(the picture: your λ, softpipe's, and where they differ in red; a {width}×{height} texture, "
                 f"level 0 to {len(texture.levels) - 1})")
    d = Difference([pixels[k] for k in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)


# ------------------------------------------------------------------------------ shadows

#: How far a shadow-map visibility may be from softpipe's and still agree (both average whole taps).
SHADOW_TOLERANCE = 1e-9


def _compare_rows(depth: np.ndarray, x: np.ndarray, y: np.ndarray, ref: np.ndarray, r: int, *, reversed_test=False,
                  outside_lit=True, average_depths=False, flip=False, rounded=False) -> np.ndarray:
    """The shadow-map compare with percentage-closer filtering at many points, and its classic mistakes by flag."""
    h, w = depth.shape
    i0 = (np.floor(x + 0.5) if rounded else np.floor(x)).astype(np.int64)
    j0 = (np.floor(y + 0.5) if rounded else np.floor(y)).astype(np.int64)
    lit, depths, inside_taps = np.zeros(len(x)), np.zeros(len(x)), np.zeros(len(x))
    for dj in range(-r, r + 1):
        for di in range(-r, r + 1):
            i, j = i0 + di, j0 + dj
            inside = (i >= 0) & (j >= 0) & (i < w) & (j < h)
            d = np.where(inside, depth[np.clip(h - 1 - j if flip else j, 0, h - 1), np.clip(i, 0, w - 1)], 1.0)
            passes = (ref >= d) if reversed_test else (ref <= d)
            lit += np.where(inside, passes, 1.0 if outside_lit else 0.0)
            depths += d
            inside_taps += 1
    if average_depths:
        return (ref <= depths / inside_taps).astype(np.float64)
    return lit / (2 * r + 1) ** 2


#: The classic mistakes :func:`check_shadow_compare` recognizes: the flags of :func:`_compare_rows` that
#: reproduce the answer, and what to say.
SHADOW_MISTAKES: List[Tuple[Dict[str, Any], str]] = [
    (dict(reversed_test=True), "your test is the wrong way round: a point is lit where its depth from the light is "
                               "less than or equal to the map's (ref ≤ depth, GL_LEQUAL): nothing stands between it "
                               "and the light"),
    (dict(average_depths=True), "you average the depths and compare once: percentage-closer filtering compares "
                                "at each of the (2r+1)² taps and averages the results (0 or 1 each), not the depths"),
    (dict(outside_lit=False), "a tap outside the map must count as lit (GL's CLAMP_TO_BORDER with border depth 1: "
                              "no caster there)"),
    (dict(flip=True), "your rows run down the map: depth[j, i] is texel column i, row j counted from the bottom "
                      "(window coordinates, like x and y)"),
    (dict(rounded=True), "you round x and y to the nearest texel: the point lies in texel (floor(x), floor(y)), "
                         "texel i covering [i, i + 1)"),
]


def check_shadow_compare(shadow_compare: Callable, trace, shadow_maps, light: int = 0, *,
                         show: Optional[bool] = None) -> Difference:
    """A student's ``shadow_compare(depth, x, y, ref, r)`` against softpipe's shadow lookup
    (:meth:`softpipe.ShadowMaps.visibility`'s V_j, FORMULAS §21) at every fragment of ``trace``.

    ``trace`` is a draw of the surface that receives the shadow by a built-in program (its varying
    ``position`` is the eye-space point; its uniform ``view`` the camera's). For each fragment the answer
    gets light ``light``'s shadow map ``depth`` (float64 [res, res], row 0 at the bottom: ``depth[j, i]``
    is texel (i, j)), the point's position (x, y) on the map in texels and its depth ``ref`` from the
    light (as :func:`softpipe.light.shadowmap.map_coordinates` finds them), and the PCF radius ``r``; it
    returns the share of the light that reaches the point, 0 to 1. The picture shows your visibility,
    softpipe's (bright: lit) and where they differ.

    Raises
    ------
    AssertionError
        ``"your shadow compare differs from softpipe's at N of M fragment(s) …"``, the first few fragments,
        and the mistake when it is a classic one (:data:`SHADOW_MISTAKES`).
    ValueError
        When the light has not exactly one opaque shadow map (a directional light, or a spot light up to
        70°), the draw has no varying ``position`` or uniform ``view``, or the answer is not one number.
    """
    from softpipe.light.material import Lighting
    from softpipe.light.shadowmap import light_visibility, map_coordinates
    if not 0 <= light < len(shadow_maps.lights):
        raise ValueError(f"check_shadow_compare: light {light} is not one of the {len(shadow_maps.lights)} light(s) "
                         "of these shadow maps")
    first, count, _ = (int(c) for c in shadow_maps.light_maps[light])
    if count != 1 or shadow_maps.maps[first].transparent_depth is not None:
        raise ValueError(f"check_shadow_compare needs a light with one shadow map and opaque casters only (a directional "
                         f"light, or a spot light up to 70°); light {light} has {count} map(s)"
                         + ("" if count != 1 else " with transparent casters"))
    names = trace.primitives.layout.names
    view = getattr(trace.call.uniforms, "view", None)
    if "position" not in names or view is None:
        raise ValueError(f"check_shadow_compare needs a draw by a built-in program (the eye-space varying 'position' "
                         f"and the uniform 'view'); the draw's varyings are {list(names)}")
    shadow_map = shadow_maps.maps[first]
    depth = np.asarray(shadow_map.depth, np.float64)
    r = shadow_map.settings.pcf
    lighting = shadow_maps.lighting_uniform(Lighting(shadow_maps.lights), np.asarray(view, np.float64))
    f = trace.fragments
    n = len(f)
    varyings, _ = trace.fragment_varyings(np.arange(n))
    P = varyings[:, trace.primitives.layout.slice("position")]
    xs, ys, refs = np.zeros(n), np.zeros(n), np.zeros(n)
    mine, ref = np.ones(n), np.ones(n)
    inside = np.zeros(n, bool)
    for k in range(n):
        p = tuple(float(c) for c in P[k])
        x, y, z, ok = map_coordinates(lighting.shadows, first, p)
        ref[k] = light_visibility(lighting, light, p)[0]
        if not ok:                                        # behind the light: lit, nothing to compare
            continue
        inside[k], xs[k], ys[k], refs[k] = True, x, y, z
        got = np.asarray(shadow_compare(depth.copy(), float(x), float(y), float(z), r), dtype=np.float64)
        if got.size != 1:
            raise ValueError(f"shadow_compare must return one number, the share of the light that passes (0 to 1), "
                             f"got an array of shape {got.shape}")
        mine[k] = float(got.reshape(-1)[0])
    error = np.abs(mine - ref)
    error = np.where(np.isnan(error), np.inf, error)
    h, w = trace.height, trace.width
    yours, theirs, diff = (np.empty((h, w, 3), np.uint8) for _ in range(3))
    for img in (yours, theirs, diff):
        img[:] = COLORS["empty"]
    rows, cols = np.asarray(f.y), np.asarray(f.x)
    yours[rows, cols] = np.round(40 + 200 * np.clip(np.nan_to_num(mine), 0, 1))[:, None].astype(np.uint8)
    theirs[rows, cols] = np.round(40 + 200 * np.clip(ref, 0, 1))[:, None].astype(np.uint8)
    bad = error > SHADOW_TOLERANCE
    diff[rows, cols] = COLORS["both"]
    diff[rows[bad], cols[bad]] = COLORS["adds"]
    picture = _panels(yours, theirs, diff)
    legend = {"empty": "no fragment", "both": "your visibility agrees with softpipe's",
              "adds": "your visibility differs"}
    pixels = [(int(cols[k]), h - 1 - int(rows[k])) for k in range(n)]
    wrong = np.nonzero(bad)[0]
    if not len(wrong):
        return Difference([], [], picture, f"the shadow compare: your visibility and softpipe's agree at all {n} "
                          f"fragments ({int((ref < 1).sum())} of them in shadow, wholly or in part)", legend)
    lines = [f"your shadow compare differs from softpipe's at {len(wrong)} of {n} fragment(s) (PCF radius r = {r}, "
             f"a {depth.shape[1]}×{depth.shape[0]} map):"]
    for k in sorted(wrong.tolist(), key=lambda k: (pixels[k][1], pixels[k][0]))[:SHOWN]:
        i, j = int(np.floor(xs[k])), int(np.floor(ys[k]))
        stored = f"{depth[j, i]:.6g}" if 0 <= i < depth.shape[1] and 0 <= j < depth.shape[0] else "none (outside)"
        lines.append(f"  pixel {pixels[k]}: yours {mine[k]:.4g}, softpipe's {ref[k]:.4g} (x = {xs[k]:.4g}, "
                     f"y = {ys[k]:.4g}, ref = {refs[k]:.6g}; texel ({i}, {j}) holds {stored})")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    for flags, text in SHADOW_MISTAKES:
        guess = _compare_rows(depth, xs[wrong], ys[wrong], refs[wrong], r, **flags)
        if np.allclose(guess, mine[wrong], rtol=0, atol=SHADOW_TOLERANCE):
            lines.append(text)
            break
    else:
        if r and np.allclose(_compare_rows(depth, xs[wrong], ys[wrong], refs[wrong], 0), mine[wrong], rtol=0,
                             atol=SHADOW_TOLERANCE):
            lines.append(f"you compare one texel: with PCF radius r = {r}, compare at each of the (2r+1)² = "
                         f"{(2 * r + 1) ** 2} texels (floor(x) + di, floor(y) + dj), −r ≤ di, dj ≤ r, and average")
    lines.append("(the picture: your visibility, softpipe's (bright: lit, dark: in shadow), and where they differ "
                 "in red)")
    d = Difference([pixels[k] for k in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)


# ------------------------------------------------------------------------------ rays

#: How far a hit's t and barycentrics may be from softpipe's and still agree (Möller–Trumbore and softpipe's
#: watertight test round differently).
RAY_TOLERANCE = 1e-9


def camera_rays(camera, width: int, height: int) -> Tuple[np.ndarray, np.ndarray]:
    """One ray per pixel of a ``width``×``height`` picture seen by ``camera`` (a :class:`softpipe.Camera`):
    (origins [H·W, 3], directions [H·W, 3], unit length), row by row from the top, each from the eye
    through its pixel's centre (x + ½, y + ½) on the near plane (the inverse of projection · view)."""
    view = camera.view
    inverse = np.linalg.inv(camera.projection(width / height) @ view)
    rows, cols = np.mgrid[0:height, 0:width]
    ndc_x = 2 * (cols.ravel() + 0.5) / width - 1
    ndc_y = 1 - 2 * (rows.ravel() + 0.5) / height                  # row 0 is the top
    near = inverse @ np.stack([ndc_x, ndc_y, -np.ones_like(ndc_x), np.ones_like(ndc_x)])
    points = (near[:3] / near[3]).T
    eye = np.asarray(camera.eye, np.float64)
    directions = points - eye
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.tile(eye, (len(points), 1)), directions


def _moller_trumbore_rows(o, d, v0, v1, v2, *, cull=False, behind=False, swap=False, no_sum=False,
                          raw_t=False) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Möller–Trumbore for one triangle and many rays: (hit, t, b1, b2), and its classic mistakes by flag."""
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(d, e2)
    det = p @ e1
    ok = det > 0 if cull else det != 0
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=det != 0)
    s = o - v0
    u = (s * p).sum(axis=1) * inv
    q = np.cross(s, e1)
    v = (d * q).sum(axis=1) * inv
    t = (q @ e2) * (1.0 if raw_t else inv)
    hit = ok & (u >= 0) & (v >= 0) & ((u + v <= 1) | no_sum) & ((t > 0) | behind)
    return (hit, t, v, u) if swap else (hit, t, u, v)


#: The classic mistakes :func:`check_ray_triangle` recognizes: the flags of :func:`_moller_trumbore_rows`
#: that reproduce the answer, and what to say.
RAY_MISTAKES: List[Tuple[Dict[str, Any], str]] = [
    (dict(cull=True), "your test misses triangles seen from behind (det < 0): softpipe's rays hit both sides of a "
                      "triangle, so only det = 0 (the ray parallel to the plane) is no hit"),
    (dict(behind=True), "your test counts hits behind the ray's origin: a hit needs t > 0 (the ray starts at the eye)"),
    (dict(swap=True), "your barycentrics are swapped: b1 is the weight of v1 (Möller–Trumbore's u = (s·p)/det) and b2 "
                      "of v2 (v = (d·q)/det)"),
    (dict(no_sum=True), "your test accepts points beyond the edge v1–v2: a hit needs u ≥ 0, v ≥ 0 and u + v ≤ 1"),
    (dict(raw_t=True), "your t is not divided by det: t = (e2·q)/det"),
]


def check_ray_triangle(intersect: Callable, vertices, triangles, camera, width: int, height: int, *,
                       show: Optional[bool] = None) -> Difference:
    """A student's ray–triangle test ``intersect(origin, direction, v0, v1, v2)`` (Möller–Trumbore), used for
    the closest hit, against softpipe's BVH (:meth:`softpipe.rays.bvh.BVH.closest`) on a grid of rays: one
    per pixel of a ``width``×``height`` picture seen by ``camera`` (:func:`camera_rays`).

    ``intersect`` returns None for a miss or (t, b1, b2): the hit point is origin + t·direction =
    (1 − b1 − b2)·v0 + b1·v1 + b2·v2, t > 0, either side of the triangle. For each ray the check calls it
    on every triangle in order and keeps the nearest hit (the first at equal t, as softpipe does). Triangle,
    t and barycentrics must agree, t and b to :data:`RAY_TOLERANCE`. The picture shows the triangle each
    ray hits, yours and softpipe's (a color per triangle), and the rays that differ in red.

    Raises
    ------
    AssertionError
        ``"your closest hits differ from softpipe's for N of M ray(s) …"``, the first few rays, and the
        mistake when it is a classic one (:data:`RAY_MISTAKES`).
    ValueError
        When ``vertices`` is not [V, 3] or ``triangles`` not [T, 3] indices into it, or the answer is not
        None or three numbers.
    """
    from softpipe.rays.bvh import BVH
    verts = np.asarray(vertices, np.float64)
    tris = np.asarray(triangles)
    if verts.ndim != 2 or verts.shape[1] != 3 or tris.ndim != 2 or tris.shape[1] != 3 or len(tris) == 0:
        raise ValueError(f"check_ray_triangle needs vertices [V, 3] and triangles [T, 3] (T ≥ 1), got arrays of "
                         f"shape {verts.shape} and {tris.shape}")
    if not np.issubdtype(tris.dtype, np.integer) or tris.min() < 0 or tris.max() >= len(verts):
        raise ValueError(f"check_ray_triangle: triangles must be whole-number indices into the {len(verts)} vertices")
    origins, directions = camera_rays(camera, width, height)
    ref_id, ref_t, ref_b = BVH.build(verts, tris).closest(origins, directions)
    n = len(origins)
    mine_id, mine_t, mine_b = np.full(n, -1), np.full(n, np.inf), np.zeros((n, 2))
    corners = verts[tris]
    for r in range(n):
        for k, (a, b, c) in enumerate(corners):
            got = intersect(origins[r].copy(), directions[r].copy(), a.copy(), b.copy(), c.copy())
            if got is None or got is False:
                continue
            values = np.asarray(got, dtype=np.float64).reshape(-1)
            if values.shape != (3,):
                raise ValueError(f"intersect must return None for a miss or (t, b1, b2) for a hit, got an array of "
                                 f"shape {values.shape}")
            if values[0] < mine_t[r]:
                mine_id[r], mine_t[r], mine_b[r] = k, values[0], values[1:]
    same_id = mine_id == ref_id
    hit = ref_id >= 0
    t_mine, t_ref = np.where(hit, mine_t, 0.0), np.where(hit, ref_t, 0.0)       # a miss's t is inf on both sides
    close = same_id & (~hit | ((np.abs(t_mine - t_ref) <= RAY_TOLERANCE * np.maximum(1.0, np.abs(t_ref)))
                               & (np.abs(mine_b - ref_b) <= RAY_TOLERANCE).all(axis=1)))
    palette = np.array([(230, 60, 40), (250, 200, 40), (60, 160, 70), (40, 90, 220), (200, 90, 200), (90, 200, 210),
                        (240, 140, 60), (150, 110, 70), (170, 210, 90), (120, 120, 240), (240, 120, 160),
                        (200, 200, 200)], np.uint8)

    def ids_picture(ids):
        img = np.empty((n, 3), np.uint8)
        img[:] = COLORS["empty"]
        img[ids >= 0] = palette[ids[ids >= 0] % len(palette)]
        return img.reshape(height, width, 3)
    diff = np.empty((n, 3), np.uint8)
    diff[:] = COLORS["empty"]
    diff[hit | (mine_id >= 0)] = COLORS["both"]
    diff[~close] = COLORS["adds"]
    picture = _panels(ids_picture(mine_id), ids_picture(ref_id), diff.reshape(height, width, 3))
    legend = {"empty": "no triangle hit", "both": "your closest hit agrees with softpipe's",
              "adds": "your closest hit differs"}
    pixels = [(r % width, height - 1 - r // width) for r in range(n)]
    wrong = np.nonzero(~close)[0]
    if not len(wrong):
        return Difference([], [], picture, f"the closest hits: yours and softpipe's agree for all {n} rays "
                          f"({int(hit.sum())} hit one of the {len(tris)} triangles)", legend)

    def what(i, t, b):
        return "no triangle" if i < 0 else f"triangle {i} at t = {t:.6g}, b = {_vector(b)}"
    lines = [f"your closest hits differ from softpipe's for {len(wrong)} of {n} ray(s) (one per pixel of a "
             f"{width}×{height} picture):"]
    for r in sorted(wrong.tolist(), key=lambda r: (pixels[r][1], pixels[r][0]))[:SHOWN]:
        lines.append(f"  pixel {pixels[r]}: yours {what(mine_id[r], mine_t[r], mine_b[r])}, softpipe's "
                     f"{what(ref_id[r], ref_t[r], ref_b[r])}")
    if len(wrong) > SHOWN:
        lines.append(f"  … and {len(wrong) - SHOWN} more")
    for flags, text in RAY_MISTAKES:
        best_id, best_t, best_b = np.full(len(wrong), -1), np.full(len(wrong), np.inf), np.zeros((len(wrong), 2))
        for k, (a, b, c) in enumerate(corners):
            h, t, b1, b2 = _moller_trumbore_rows(origins[wrong], directions[wrong], a, b, c, **flags)
            better = h & (t < best_t)
            best_id[better], best_t[better], best_b[better] = k, t[better], np.stack([b1, b2], axis=1)[better]
        if np.array_equal(best_id, mine_id[wrong]) and np.allclose(
                np.where(best_id >= 0, best_t, 0.0), np.where(best_id >= 0, mine_t[wrong], 0.0), rtol=1e-9, atol=1e-9) \
                and np.allclose(best_b, mine_b[wrong], rtol=0, atol=1e-9):
            lines.append(text)
            break
    lines.append("(the picture: the triangle each ray hits first, yours and softpipe's, a color per triangle; the rays "
                 "that differ in red)")
    d = Difference([pixels[r] for r in wrong], [], picture, "\n".join(lines), legend)
    raise _failed(d, show)
