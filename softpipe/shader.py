"""Shaders: per-invocation Python functions, compiled by numba, run over a batch.

A shader is written like GLSL: it sees one vertex or one fragment, small vectors
are tuples of floats, and its inputs arrive as namedtuples so that they read by
name (``varyings.normal``, ``uniforms.light_dir``, ``frag.x``).

Vertex shader::

    def vertex(attributes, uniforms):
        ...
        return clip_position, Varyings(normal=..., color=...)

``attributes`` has one field per vertex attribute (``position`` and the arrays
given as ``attributes=``); a field is a float for an ``[N]`` array and a tuple of
k floats for ``[N, k]``. It returns the clip position (x, y, z, w) and a
namedtuple (any namedtuple class) of varyings; each varying is a float or a
tuple of 2–4 floats. softpipe learns the varyings' names and sizes by running
the vertex shader once as plain Python, on the first vertex.

Fragment shader::

    def fragment(varyings, uniforms, frag):
        return (r, g, b, a)          # or DISCARD

``varyings`` has the interpolated varyings by name, ``frag`` is a
:data:`FragInfo` (``x``, ``y``: the window position of the sample, y up, pixel
centres at +½, as ``gl_FragCoord``; ``z`` its depth; ``front_facing``;
``primitive_id``). Returning :data:`DISCARD` discards the fragment.

A fragment shader that needs screen-space derivatives (GLSL's ``dFdx``/``dFdy``,
e.g. to choose a mipmap level) takes a fourth parameter::

    def fragment(varyings, uniforms, frag, derivatives):
        duv_dx, duv_dy = derivatives.dx.uv, derivatives.dy.uv

They are exact, not finite differences: the derivative of each varying's
interpolation formula at the fragment, per window pixel (y up).

``uniforms`` is built once per draw from a dict by :func:`make_uniforms`.

How it runs: softpipe generates a small loop over the batch for each (shader,
varying layout), with the unpacking written out by name, and compiles it with
numba; the shader is inlined into that loop. :func:`kernel_source` shows the
generated source. Under ``NUMBA_DISABLE_JIT=1`` the same loop runs as Python,
so a breakpoint in a shader stops there.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import math
import re
import sys
import types
from collections import namedtuple
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, Mapping, NamedTuple, Sequence, Tuple

import numba
import numpy as np

from .sampling import SUBPIXEL

__all__ = ["FragInfo", "DISCARD", "ShaderError", "make_uniforms", "VaryingLayout", "QUALIFIERS"]

#: The fragment's fixed-function inputs (``gl_FragCoord`` and friends).
FragInfo = namedtuple("FragInfo", ["x", "y", "z", "front_facing", "primitive_id"])

#: Return this from a fragment shader to discard the fragment (GLSL ``discard``).
#: It is the color whose alpha is NaN; the fragment stage tests for exactly that.
DISCARD = (math.nan, math.nan, math.nan, math.nan)

QUALIFIERS = ("smooth", "noperspective", "flat")


class ShaderError(Exception):
    """A shader could not be compiled or run; the message names the shader and line."""


def shader_name(fn: Callable) -> str:
    f = getattr(fn, "py_func", fn)
    return f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', repr(f))}"


def python_function(fn: Callable) -> Callable:
    """The plain-Python function behind a shader (numba dispatcher or not)."""
    return getattr(fn, "py_func", fn)


def jit_function(fn: Callable) -> Callable:
    """``fn`` as a numba dispatcher (compiling a plain function on first call)."""
    if not callable(fn):
        raise TypeError(f"a shader must be a function, got {type(fn).__name__}")
    if isinstance(fn, numba.core.registry.CPUDispatcher):
        return fn
    if numba.config.DISABLE_JIT:
        return fn
    return numba.njit(fn, inline="always")


# --------------------------------------------------------------------- uniforms

def _uniform_value(name: str, value: Any):
    if hasattr(value, "__softpipe_uniform__"):
        return value.__softpipe_uniform__()
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return value  # already a namedtuple: pass through
    arr = np.asarray(value)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise TypeError(f"uniform {name!r}: cannot pass a {type(value).__name__} to a shader; "
                        "use numbers, sequences, numpy arrays or an object with __softpipe_uniform__")
    if arr.ndim == 1 and arr.size <= 4:
        return tuple(float(c) for c in arr)
    return np.ascontiguousarray(arr, dtype=np.float64)


def _uniforms_class_name(names: Sequence[str]) -> str:
    """A module attribute name that spells out the field names (length-prefixed, unambiguous)."""
    return "Uniforms_" + "_".join(f"{len(n)}{n}" for n in names)


def _names_from_class_name(attr: str) -> list:
    rest, names = attr[len("Uniforms_"):], []
    while rest:
        digits = len(rest) - len(rest.lstrip("0123456789"))
        if digits == 0:
            raise AttributeError(attr)
        n = int(rest[:digits])
        names.append(rest[digits:digits + n])
        rest = rest[digits + n + 1:]
    return names


def _uniforms_class(names: Sequence[str]) -> type:
    """The namedtuple class for a set of uniform names, one per set, as a module attribute.

    numba's on-disk cache finds a kernel by its argument types, and a namedtuple
    type is its class: the class must be the same in every process, which it
    is when pickle can find it here by name (see ``__getattr__``).
    """
    attr = _uniforms_class_name(names)
    cls = globals().get(attr)
    if cls is None:
        cls = namedtuple(attr, list(names) or ["empty"])
        cls.__module__ = __name__
        globals()[attr] = cls
    return cls


def __getattr__(attr: str):
    # Unpickling a cached kernel's signature asks for Uniforms_… classes by name.
    if attr.startswith("Uniforms_"):
        return _uniforms_class(_names_from_class_name(attr))
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


def make_uniforms(uniforms: Mapping[str, Any] | None):
    """The shader's ``uniforms`` namedtuple from a dict.

    Numbers become floats, sequences of up to 4 numbers tuples of floats (vec2–4),
    other arrays float64 arrays (matrices, tables), and objects with a
    ``__softpipe_uniform__`` method (materials, lights, textures) what it returns.
    """
    if uniforms is None:
        uniforms = {}
    if not isinstance(uniforms, Mapping):
        raise TypeError(f"uniforms must be a dict of name → value, got {type(uniforms).__name__}")
    names = tuple(uniforms)
    for n in names:
        if not isinstance(n, str) or not n.isidentifier():
            raise ValueError(f"uniform name {n!r} is not a valid Python identifier")
    cls = _uniforms_class(names)
    if not names:
        return cls(0.0)
    return cls(*(_uniform_value(n, uniforms[n]) for n in names))


# ---------------------------------------------------------------- varying layout

@dataclass(frozen=True)
class VaryingLayout:
    """How named varyings are packed side by side in one float64 array [.., K].

    ``fields`` is a tuple of (name, offset, size, qualifier); size 1 is a float,
    2–4 a tuple.
    """

    fields: Tuple[Tuple[str, int, int, str], ...] = ()

    @property
    def width(self) -> int:
        return sum(f[2] for f in self.fields)

    @property
    def names(self) -> Tuple[str, ...]:
        return tuple(f[0] for f in self.fields)

    def slice(self, name: str) -> slice:
        for n, off, size, _ in self.fields:
            if n == name:
                return slice(off, off + size)
        raise KeyError(name)

    def with_qualifiers(self, qualifiers: Mapping[str, str] | None) -> "VaryingLayout":
        qualifiers = dict(qualifiers or {})
        for name, q in qualifiers.items():
            if name not in self.names:
                raise ValueError(f"interpolation names varying {name!r}, but the varyings are {list(self.names)}")
            if q not in QUALIFIERS:
                raise ValueError(f"interpolation[{name!r}] must be one of {QUALIFIERS}, got {q!r}")
        return VaryingLayout(tuple((n, o, s, qualifiers.get(n, q)) for n, o, s, q in self.fields))

    @staticmethod
    def from_sizes(items: Sequence[Tuple[str, int]]) -> "VaryingLayout":
        fields, off = [], 0
        for name, size in items:
            fields.append((name, off, size, "smooth"))
            off += size
        return VaryingLayout(tuple(fields))

    def unpack(self, packed: np.ndarray) -> Dict[str, np.ndarray]:
        """The packed array [..., K] as a dict of name → [...] or [..., k] arrays."""
        out = {}
        for n, off, size, _ in self.fields:
            out[n] = packed[..., off] if size == 1 else packed[..., off:off + size]
        return out


def _field_size(name: str, what: str, value) -> int:
    if isinstance(value, (int, float, np.integer, np.floating, bool)):
        return 1
    if isinstance(value, tuple) and 2 <= len(value) <= 4 and all(
            isinstance(c, (int, float, np.integer, np.floating)) for c in value):
        return len(value)
    raise ShaderError(f"{what} {name!r} must be a float or a tuple of 2–4 floats, got {value!r}")


# ------------------------------------------------------------ code generation

def _tuple_expr(array: str, index: str, offset: int, size: int) -> str:
    if size == 1:
        return f"{array}[{index}, {offset}]"
    parts = ", ".join(f"{array}[{index}, {offset + c}]" for c in range(size))
    return f"({parts})"


_KERNELS: Dict[Any, Any] = {}


def _cache_dir() -> Path:
    """Where generated kernel modules (and numba's cache of them) live."""
    root = os.environ.get("SOFTPIPE_CACHE_DIR")
    if root:
        return Path(root)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "softpipe" / "kernels"


def _importable_cache(directory: Path) -> None:
    """Put the kernel directory on sys.path: numba's cache may name a generated module's
    types, and unpickling them imports that module by name."""
    if str(directory) not in sys.path:
        sys.path.append(str(directory))


if _cache_dir().is_dir():       # so even a first cache lookup can import what it names
    _importable_cache(_cache_dir())


_PACKAGE_HASH: list = []


def _package_hash() -> str:
    """A hash of softpipe's own sources: a generated kernel inlines them, so it depends on them."""
    if not _PACKAGE_HASH:
        h = hashlib.sha256()
        pkg = Path(__file__).parent
        for f in sorted(pkg.rglob("*.py")):
            h.update(str(f.relative_to(pkg)).encode())
            h.update(f.read_bytes())
        _PACKAGE_HASH.append(h.hexdigest()[:16])
    return _PACKAGE_HASH[0]


def _importable(shader: Callable) -> Tuple[str, str] | None:
    """(module, name) if the shader is one of softpipe's own module-level functions.

    Only these are cached on disk: numba cannot see when a user's shader (or a
    function it calls in another file) changes, so user shaders are compiled
    once per process instead of risking a stale kernel.
    """
    f = python_function(shader)
    mod, name = getattr(f, "__module__", None) or "", getattr(f, "__qualname__", None) or ""
    if not mod.startswith("softpipe.") or "." in name or "<" in name:
        return None
    try:
        if python_function(getattr(importlib.import_module(mod), name)) is not f:
            return None
    except (ImportError, AttributeError):
        return None
    return mod, name


_HEADER = ("# Generated by softpipe.shader: the loop that runs one shader over a batch.\n"
           "import numba\n"
           "from collections import namedtuple\n"
           "from softpipe.shader import Derivatives, FragInfo, jit_function, short_repr\n"
           "from softpipe.visibility import centroid_of_run, first_covered_sample, same_triangle_before\n")


def _module_source(body: str, shader: Callable, preamble: str, cached: bool) -> str:
    """The generated module: header, the shader as global ``shader``, namedtuples, then ``body``.

    Functions in ``body`` are decorated ``@JIT``; the shader is imported by
    name when the module is a cached file, and injected as ``_shader_py`` otherwise.
    """
    where = _importable(shader) if cached else None
    imp = f"from {where[0]} import {where[1]} as _shader_py\n" if where else ""
    jit = f"JIT = numba.njit(cache={bool(where)}, nogil=True)\n"
    # Namedtuple classes get names of their own per module: numba's on-disk cache
    # finds a type by module and name, and two modules' "Varyings" must not meet.
    tag = hashlib.sha256((shader_name(shader) + preamble + body).encode()).hexdigest()[:12]
    return (_HEADER + imp + "shader = jit_function(_shader_py)\n" + jit + preamble.replace("@TAG@", tag)
            + "\n\n" + body)


def _compile_module(body: str, shader: Callable, preamble: str, kind: str):
    """The generated module for a shader: a cached file for softpipe's own shaders, else exec'd."""
    if _importable(shader) is not None and not numba.config.DISABLE_JIT:
        source = _module_source(body, shader, preamble, cached=True)
        digest = hashlib.sha256((source + _package_hash() + numba.__version__).encode()).hexdigest()[:20]
        try:
            return _load_cached(source, f"softpipe_{kind}_{digest}")
        except OSError:
            pass  # an unwritable cache directory: compile in memory instead
    source = _module_source(body, shader, preamble, cached=False)
    return _exec_module(source, shader, kind)


def _exec_module(source: str, shader: Callable, kind: str, python: bool = False):
    """exec a generated module; with ``python``, numba is left out entirely (for debugging)."""
    module = types.ModuleType(f"softpipe_{kind}_loop")
    module._shader_py = python_function(shader)
    if python:
        # The same source, run as plain Python: JIT and jit_function become no-ops.
        source = source.replace("shader = jit_function(_shader_py)", "shader = _shader_py")
        source = source.replace("JIT = numba.njit(cache=False, nogil=True)", "JIT = lambda f: f")
    exec(compile(source, f"<softpipe {kind} loop for {shader_name(shader)}>", "exec"), module.__dict__)
    module.__softpipe_source__ = source
    return module


def _load_cached(source: str, module_name: str):
    directory = _cache_dir()
    directory.mkdir(parents=True, exist_ok=True)
    _importable_cache(directory)
    path = directory / f"{module_name}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)   # atomic: a concurrent process never sees half a file
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module   # so numba's cache can find its namedtuple classes
    spec.loader.exec_module(module)
    module.__softpipe_source__ = source
    return module


def kernel_source(kind: str, shader: Callable, layout: "VaryingLayout") -> str:
    """The generated Python source of a fragment (``kind="fragment"``) loop, to read it."""
    if kind != "fragment":
        raise ValueError("kernel_source: only kind='fragment' is supported")
    return fragment_module(shader, layout).__softpipe_source__


def _describe_compile_error(kind: str, shader: Callable, err: Exception) -> ShaderError:
    """Name the shader, its file and the first meaningful line of numba's complaint."""
    f = python_function(shader)
    try:
        file = inspect.getsourcefile(f)
        line = inspect.getsourcelines(f)[1]
        where = f"{file}:{line}"
    except (OSError, TypeError):
        where = "<unknown file>"
    text = str(err)
    locs = re.findall(r'File "([^"]+)", line (\d+)', text)
    shader_locs = [f"{p}:{n}" for p, n in locs if "<softpipe" not in p and "softpipe_" not in p]
    detail = text.strip().splitlines()
    summary = next((l.strip() for l in detail if l.strip() and not l.startswith("-")), text)
    at = f" (at {shader_locs[0]})" if shader_locs else ""
    return ShaderError(f"{kind} shader {shader_name(shader)} defined at {where} could not be compiled by numba"
                       f"{at}: {summary}\n--- numba said ---\n{text}")


def _namedtuple_line(var: str, typename: str, names: Sequence[str]) -> str:
    unique = f"{typename}_@TAG@"
    return (f"{unique} = namedtuple({unique!r}, {list(names)!r})\n{unique}.__repr__ = short_repr\n"
            f"{var} = {unique}\n")


def short_repr(self) -> str:
    """A generated namedtuple's repr without its unique tag: ``Varyings(normal=…)``."""
    name = type(self).__name__.rsplit("_", 1)[0]
    return name + "(" + ", ".join(f"{f}={v!r}" for f, v in zip(self._fields, self)) + ")"


def vertex_kernel(shader: Callable, attr_sizes: Sequence[Tuple[str, int]], out_layout: VaryingLayout):
    """The compiled loop that runs ``shader`` over every vertex."""
    key = ("vertex", python_function(shader), tuple(attr_sizes), out_layout.fields)
    module = _KERNELS.get(key)
    if module is None:
        names = [n for n, _ in attr_sizes]
        attr_exprs = ", ".join(_tuple_expr(f"a_{n}", "i", 0, s) if s > 1 else f"a_{n}[i, 0]"
                               for n, s in attr_sizes)
        lines = [
            "@JIT",
            f"def vertex_loop(lo, hi, {', '.join(f'a_{n}' for n in names)}, uniforms, out_position, out_varyings):",
            "    for i in range(lo, hi):",
            f"        attributes = Attributes({attr_exprs})",
            "        clip, v = shader(attributes, uniforms)",
        ]
        lines += [f"        out_position[i, {c}] = clip[{c}]" for c in range(4)]
        for j, (n, off, size, _) in enumerate(out_layout.fields):
            if size == 1:
                lines.append(f"        out_varyings[i, {off}] = v[{j}]  # {n}")
            else:
                lines += [f"        out_varyings[i, {off + c}] = v[{j}][{c}]  # {n}.{'xyzw'[c]}"
                          for c in range(size)]
        module = _compile_module("\n".join(lines) + "\n", shader,
                                 _namedtuple_line("Attributes", "Attributes", names), "vertex")
        _KERNELS[key] = module
    return module.vertex_loop


_TRIANGLE_ARGS = "inv_w, corner, front, prim_id, bary_grad"
_FRAGMENT_ARGS = "triangle, frag_x, frag_y, depth, bary, " + _TRIANGLE_ARGS
SUBPIXEL_UNITS = SUBPIXEL

#: The 4th argument of a fragment shader that asks for it: ``derivatives.dx.uv`` is ∂uv/∂x.
Derivatives = namedtuple("Derivatives", ["dx", "dy"])


def wants_derivatives(shader: Callable) -> bool:
    """Does the fragment shader take a 4th parameter (screen-space derivatives of its varyings)?"""
    try:
        params = inspect.signature(python_function(shader)).parameters.values()
    except (TypeError, ValueError):
        return False
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params) >= 4


def _derivative_lines(layout: VaryingLayout, axis: int, name: str) -> list:
    """∂v/∂x (axis 0) or ∂v/∂y (axis 1) of every varying, from the barycentrics' gradients.

    smooth: v = A/B with A = Σ b_k v_k/w_k, B = Σ b_k/w_k, so ∂v = (∂A − v ∂B)/B;
    noperspective: ∂v = Σ ∂b_k v_k; flat: 0.
    """
    g = [f"bary_grad[t, {axis}, {k}]" for k in range(3)]
    lines = []
    if any(q == "smooth" for *_, q in layout.fields):
        lines.append(f"    dq{name} = {g[0]} * inv_w[t, 0] + {g[1]} * inv_w[t, 1] + {g[2]} * inv_w[t, 2]")
    exprs = []
    for n, off, size, q in layout.fields:
        comps = []
        for c, k in enumerate(range(off, off + size)):
            if q == "flat":
                comps.append("0.0")
            elif q == "noperspective":
                comps.append(" + ".join(f"{g[m]} * corner[t, {m}, {k}]" for m in range(3)))
            else:
                v = f"v_{n}" if size == 1 else f"v_{n}[{c}]"
                da = " + ".join(f"{g[m]} * inv_w[t, {m}] * corner[t, {m}, {k}]" for m in range(3))
                comps.append(f"({da} - {v} * dq{name}) / qs")
        lines.append(f"    d{name}_{n} = " + (comps[0] if size == 1 else f"({', '.join(comps)})"))
        exprs.append(f"d{name}_{n}")
    lines.append(f"    d{name} = Varyings({', '.join(exprs) or '0.0'})")
    return lines


def _fragment_body(layout: VaryingLayout, derivatives: bool = False) -> str:
    """Source of ``fragment_inputs`` (interpolation) and ``fragment_loop`` (runs the shader)."""
    lines = [
        "@JIT",
        f"def interpolate(t, b0, b1, b2, fx, fy, z, {_TRIANGLE_ARGS}):",
        '    """The varyings and FragInfo at barycentrics (b0, b1, b2) of triangle t."""',
    ]
    if any(q == "smooth" for *_, q in layout.fields):
        lines += [
            "    q0 = b0 * inv_w[t, 0]",      # perspective-correct weights: b_k / w_k, renormalized
            "    q1 = b1 * inv_w[t, 1]",
            "    q2 = b2 * inv_w[t, 2]",
            "    qs = q0 + q1 + q2",
            "    if not qs > 0.0:",         # an extrapolated pixel centre (multisampling) can make it 0
            "        q0, q1, q2, qs = b0, b1, b2, 1.0",
            "    p0 = q0 / qs",
            "    p1 = q1 / qs",
            "    p2 = q2 / qs",
        ]
    exprs = []
    for n, off, size, q in layout.fields:
        comps = []
        for k in range(off, off + size):
            if q == "flat":
                comps.append(f"corner[t, 2, {k}]")
            elif q == "smooth":
                comps.append(f"p0 * corner[t, 0, {k}] + p1 * corner[t, 1, {k}] + p2 * corner[t, 2, {k}]")
            else:
                comps.append(f"b0 * corner[t, 0, {k}] + b1 * corner[t, 1, {k}] + b2 * corner[t, 2, {k}]")
        value = comps[0] if size == 1 else f"({', '.join(comps)})"
        lines.append(f"    v_{n} = {value}  # {q}")
        exprs.append(f"v_{n}")
    lines += [
        f"    varyings = Varyings({', '.join(exprs) or '0.0'})",
        "    frag = FragInfo(fx, fy, z, front[t], prim_id[t])",
    ]
    if derivatives:
        if not any(q == "smooth" for *_, q in layout.fields):
            lines.append("    qs = 1.0")
        lines += _derivative_lines(layout, 0, "x") + _derivative_lines(layout, 1, "y")
        lines.append("    return varyings, frag, Derivatives(dx, dy)")
    else:
        lines.append("    return varyings, frag")
    inputs = "varyings, frag, derivatives" if derivatives else "varyings, frag"
    call = f"shader({inputs.replace('varyings, frag', 'varyings, uniforms, frag')})"
    lines += [
        "",
        "",
        "@JIT",
        f"def fragment_inputs(i, {_FRAGMENT_ARGS}):",
        '    """The varyings and FragInfo of fragment i, exactly as the shader receives them."""',
        "    return interpolate(triangle[i], bary[i, 0], bary[i, 1], bary[i, 2], frag_x[i], frag_y[i], depth[i],",
        f"                       {_TRIANGLE_ARGS})",
        "",
        "",
        "@JIT",
        f"def fragment_loop({_FRAGMENT_ARGS}, uniforms, out_color):",
        "    for i in range(triangle.shape[0]):",
        f"        {inputs} = fragment_inputs(i, {_FRAGMENT_ARGS})",
        f"        c = {call}",
        "        out_color[i, 0] = c[0]",
        "        out_color[i, 1] = c[1]",
        "        out_color[i, 2] = c[2]",
        "        out_color[i, 3] = c[3]",
        "",
        "",
        "@JIT",
        f"def visible_loop(row_lo, row_hi, vis, touched, tile_w, tile_h, window, edges, bias, plane, offsets,",
        f"                 positions, shading, {_TRIANGLE_ARGS}, uniforms, out_color):",
        '    """Shade the samples the visibility pass kept (visibility.py), image rows row_lo:row_hi.',
        "",
        "    Barycentrics, depth and position are recomputed exactly as the rasterizer computes them.",
        "    Tiles no triangle touched are skipped; each sample is shaded on its own, so the order",
        "    (tile, sample, column) does not change a byte.",
        "",
        "    ``shading`` 1 or 2 (multisampling at the pixel centre or at the centroid): a triangle is",
        "    shaded once per pixel, as the rasterizer's run of its samples there is, with the depth",
        "    of the first sample it covers (visible or not); its other visible samples copy the color.",
        '    """',
        "    samples, height, width = vis.shape[0], vis.shape[1], vis.shape[2]",
        "    for row in range(row_lo, row_hi):",
        "        j = height - 1 - row",
        "        for tile_x in range(touched.shape[1]):",
        "            if not touched[j // tile_h, tile_x]:",
        "                continue",
        "            for s in range(samples):",
        "                for i in range(tile_x * tile_w, min(tile_x * tile_w + tile_w, width)):",
        "                    t = vis[s, row, i]",
        "                    if t < 0:",
        "                        continue",
        "                    inv_area = plane[t, 3]",
        "                    if shading == 0:           # at the sample",
        "                        depth_sample = s",
        f"                        px, py = i * {SUBPIXEL_UNITS} + offsets[s, 0], j * {SUBPIXEL_UNITS} + offsets[s, 1]",
        "                        b0 = (edges[t, 0, 0] * px + edges[t, 0, 1] * py + edges[t, 0, 2]) * inv_area",
        "                        b1 = (edges[t, 1, 0] * px + edges[t, 1, 1] * py + edges[t, 1, 2]) * inv_area",
        "                        b2 = (edges[t, 2, 0] * px + edges[t, 2, 1] * py + edges[t, 2, 2]) * inv_area",
        "                        fx, fy = i + positions[s, 0], j + positions[s, 1]",
        "                    else:                      # multisampling: once per pixel and triangle",
        "                        earlier = same_triangle_before(vis, s, row, i)",
        "                        if earlier >= 0:",
        "                            for c in range(4):",
        "                                out_color[s, row, i, c] = out_color[earlier, row, i, c]",
        "                            continue",
        "                        if shading == 1:       # at the pixel centre",
        "                            depth_sample = first_covered_sample(edges, bias, t, i, j, offsets)",
        f"                            px, py = i * {SUBPIXEL_UNITS}, j * {SUBPIXEL_UNITS}",
        "                            b0 = (edges[t, 0, 0] * px + edges[t, 0, 1] * py + edges[t, 0, 2]) * inv_area",
        "                            b1 = (edges[t, 1, 0] * px + edges[t, 1, 1] * py + edges[t, 1, 2]) * inv_area",
        "                            b2 = (edges[t, 2, 0] * px + edges[t, 2, 1] * py + edges[t, 2, 2]) * inv_area",
        "                            fx, fy = i + 0.5, j + 0.5",
        "                        else:                  # at the centroid of its covered samples",
        "                            depth_sample, c0, c1, c2, mx, my = centroid_of_run(window, edges, bias, t, i, j,",
        "                                                                               offsets, positions)",
        "                            b0, b1, b2 = c0 * inv_area, c1 * inv_area, c2 * inv_area",
        "                            fx, fy = i + mx, j + my",
        f"                    zx = i * {SUBPIXEL_UNITS} + offsets[depth_sample, 0]",
        f"                    zy = j * {SUBPIXEL_UNITS} + offsets[depth_sample, 1]",
        "                    ze1 = edges[t, 1, 0] * zx + edges[t, 1, 1] * zy + edges[t, 1, 2]",
        "                    ze2 = edges[t, 2, 0] * zx + edges[t, 2, 1] * zy + edges[t, 2, 2]",
        "                    z = plane[t, 0] + (ze1 * plane[t, 1] + ze2 * plane[t, 2]) * inv_area",
        "                    z = min(max(z, 0.0), 1.0)",
        f"                    {inputs} = interpolate(t, b0, b1, b2, fx, fy, z, {_TRIANGLE_ARGS})",
        f"                    c = {call}",
        "                    out_color[s, row, i, 0] = c[0]",
        "                    out_color[s, row, i, 1] = c[1]",
        "                    out_color[s, row, i, 2] = c[2]",
        "                    out_color[s, row, i, 3] = c[3]",
    ]
    return "\n".join(lines) + "\n"


def _fragment_preamble(layout: VaryingLayout) -> str:
    return _namedtuple_line("Varyings", "Varyings", list(layout.names) or ["none"])


def fragment_module(shader: Callable, layout: VaryingLayout):
    return _fragment_module(shader, layout, wants_derivatives(shader))


def _fragment_module(shader: Callable, layout: VaryingLayout, derivatives: bool):
    """The generated module holding ``fragment_inputs`` and ``fragment_loop`` for a shader and layout.

    Interpolation (DESIGN.md): ``smooth`` is perspective-correct, weights
    b_k/w_k renormalized; ``noperspective`` uses the window-space barycentrics
    b_k directly; ``flat`` takes the provoking vertex's value, which primitive
    assembly has copied to every corner.
    """
    key = ("fragment", python_function(shader), layout.fields, derivatives)
    module = _KERNELS.get(key)
    if module is None:
        module = _compile_module(_fragment_body(layout, derivatives), shader, _fragment_preamble(layout),
                                 "fragment")
        _KERNELS[key] = module
    return module


def fragment_kernel(shader: Callable, layout: VaryingLayout):
    """The compiled loop that interpolates varyings and runs ``shader`` per fragment."""
    return fragment_module(shader, layout).fragment_loop


def visible_kernel(shader: Callable, layout: VaryingLayout):
    """The compiled loop that shades the samples a visibility pass kept (softpipe.visibility)."""
    return fragment_module(shader, layout).visible_loop


def may_discard(shader: Callable, _seen=None) -> bool:
    """Does the shader (or a Python function it calls) name ``DISCARD``? Decides the fast path.

    A shader that discards must say so by returning softpipe.DISCARD; this
    looks for that name in its code and, recursively, in the functions it calls.
    """
    seen = set() if _seen is None else _seen
    f = python_function(shader)
    code = getattr(f, "__code__", None)
    if code is None or code in seen:
        return False
    seen.add(code)
    names = set(code.co_names)
    for const in code.co_consts:          # nested functions and lambdas
        if hasattr(const, "co_names"):
            names |= set(const.co_names)
    if "DISCARD" in names:
        return True
    glob = getattr(f, "__globals__", {})
    return any(callable(glob.get(n)) and may_discard(glob[n], seen) for n in names if n in glob)


def python_fragment_module(shader: Callable, layout: VaryingLayout):
    """The same generated module as plain Python (no numba), for stepping through one fragment."""
    source = _module_source(_fragment_body(layout, wants_derivatives(shader)), shader, _fragment_preamble(layout),
                            cached=False)
    return _exec_module(source, shader, "fragment", python=True)


def probe_vertex_shader(shader: Callable, attributes, uniforms) -> Tuple[Tuple[float, ...], Any]:
    """Run a vertex shader once in plain Python to learn the names and sizes it outputs."""
    f = python_function(shader)
    try:
        out = f(attributes, uniforms)
    except Exception as e:  # the user's code: report where, keep the cause
        raise ShaderError(f"vertex shader {shader_name(shader)} raised {type(e).__name__}: {e}") from e
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ShaderError(f"vertex shader {shader_name(shader)} must return (clip_position, varyings), "
                          f"got {type(out).__name__}")
    clip, varyings = out
    if not (isinstance(clip, tuple) and len(clip) == 4):
        raise ShaderError(f"vertex shader {shader_name(shader)}: clip position must be a tuple of 4 floats, "
                          f"got {clip!r}")
    if not (isinstance(varyings, tuple) and hasattr(varyings, "_fields")):
        raise ShaderError(f"vertex shader {shader_name(shader)}: varyings must be a namedtuple, "
                          f"got {type(varyings).__name__}")
    sizes = [(n, _field_size(n, "varying", v)) for n, v in zip(varyings._fields, varyings)]
    return clip, VaryingLayout.from_sizes(sizes)


def probe_fragment_shader(shader: Callable, varyings, uniforms, frag) -> None:
    """Run a fragment shader once in plain Python: a clear error beats numba's."""
    f = python_function(shader)
    try:
        out = f(varyings, uniforms, frag)
    except Exception as e:
        raise ShaderError(f"fragment shader {shader_name(shader)} raised {type(e).__name__}: {e}") from e
    if not (isinstance(out, tuple) and len(out) == 4):
        raise ShaderError(f"fragment shader {shader_name(shader)} must return an RGBA tuple of 4 floats "
                          f"(or DISCARD), got {out!r}")


def run_compiled(kind: str, shader: Callable, kernel: Callable, explain: Callable | None, *args) -> None:
    """Call a generated loop; turn numba's errors into a ShaderError naming the shader.

    When numba cannot compile the shader, ``explain`` (if given) first runs it
    once as plain Python, whose error (a wrong return value, a Python
    exception) is usually the clearer one.
    """
    try:
        kernel(*args)
    except (numba.core.errors.TypingError, numba.core.errors.LoweringError,
            numba.core.errors.UnsupportedError) as e:
        if explain is not None:
            explain()
        raise _describe_compile_error(kind, shader, e) from None
    except ShaderError:
        raise
    except Exception as e:   # raised by the shader's own code while it ran
        raise ShaderError(f"{kind} shader {shader_name(shader)} raised {type(e).__name__}: {e}") from e
