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
tuple of 2–4 floats.

Fragment shader::

    def fragment(varyings, uniforms, frag):
        return (r, g, b, a)          # or DISCARD

``varyings`` has the interpolated varyings by name, ``frag`` is a
:data:`FragInfo` (``x``, ``y``: the window position of the sample, y up, pixel
centres at +½, as ``gl_FragCoord``; ``z`` its depth; ``front_facing``;
``primitive_id``). Returning :data:`DISCARD` discards the fragment.

``uniforms`` is built once per draw from a dict by :func:`make_uniforms`.

How it runs: softpipe generates a small loop over the batch for each (shader,
varying layout), with the unpacking written out by name, and compiles it with
numba; the shader is inlined into that loop. :func:`kernel_source` shows the
generated source. Under ``NUMBA_DISABLE_JIT=1`` the same loop runs as Python,
so a breakpoint in a shader stops there.
"""
from __future__ import annotations

import inspect
import math
import re
from collections import namedtuple
from dataclasses import dataclass
from typing import Any, Callable, Dict, Mapping, NamedTuple, Sequence, Tuple

import numba
import numpy as np

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
    return numba.njit(fn)


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


_UNIFORM_CLASSES: Dict[Tuple[str, ...], type] = {}


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
    cls = _UNIFORM_CLASSES.get(names)
    if cls is None:
        # numba needs one class per set of names; an empty set still needs a field.
        cls = namedtuple("Uniforms", names or ("empty",))
        _UNIFORM_CLASSES[names] = cls
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


def _compile_source(source: str, namespace: Dict[str, Any], entry: str, name: str):
    """exec the generated module and jit its entry point (numba is the shader compiler)."""
    code = compile(source, f"<softpipe {name}>", "exec")
    exec(code, namespace)
    fn = namespace[entry]
    fn.__softpipe_source__ = source
    if numba.config.DISABLE_JIT:
        return fn
    return numba.njit(fn, nogil=True)


def kernel_source(kernel: Callable) -> str:
    """The generated Python source of a shading loop (for reading and debugging)."""
    return python_function(kernel).__softpipe_source__


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
    shader_locs = [f"{p}:{n}" for p, n in locs if "<softpipe" not in p]
    detail = text.strip().splitlines()
    summary = next((l.strip() for l in detail if l.strip() and not l.startswith("-")), text)
    at = f" (at {shader_locs[0]})" if shader_locs else ""
    return ShaderError(f"{kind} shader {shader_name(shader)} defined at {where} could not be compiled by numba"
                       f"{at}: {summary}\n--- numba said ---\n{text}")


def vertex_kernel(shader: Callable, attr_sizes: Sequence[Tuple[str, int]], out_layout: VaryingLayout):
    """The compiled loop that runs ``shader`` over every vertex."""
    key = ("vertex", python_function(shader), tuple(attr_sizes), out_layout.fields)
    kern = _KERNELS.get(key)
    if kern is not None:
        return kern
    names = [n for n, _ in attr_sizes]
    args = ", ".join(f"a_{n}" for n in names)
    lines = [
        f"def vertex_loop({args}, uniforms, out_position, out_varyings):",
        f"    for i in range(out_position.shape[0]):",
    ]
    attr_exprs = ", ".join(_tuple_expr(f"a_{n}", "i", 0, s) if s > 1 else f"a_{n}[i, 0]" for n, s in attr_sizes)
    lines.append(f"        attributes = Attributes({attr_exprs})")
    lines.append(f"        clip, v = shader(attributes, uniforms)")
    for c in range(4):
        lines.append(f"        out_position[i, {c}] = clip[{c}]")
    for j, (n, off, size, _) in enumerate(out_layout.fields):
        if size == 1:
            lines.append(f"        out_varyings[i, {off}] = v[{j}]  # {n}")
        else:
            for c in range(size):
                lines.append(f"        out_varyings[i, {off + c}] = v[{j}][{c}]  # {n}.{'xyzw'[c]}")
    source = "\n".join(lines) + "\n"
    namespace = {"shader": jit_function(shader), "Attributes": namedtuple("Attributes", names)}
    kern = _compile_source(source, namespace, "vertex_loop", "vertex loop")
    _KERNELS[key] = kern
    return kern


def fragment_kernel(shader: Callable, layout: VaryingLayout):
    """The compiled loop that interpolates varyings and runs ``shader`` per fragment.

    Interpolation (DESIGN.md): ``smooth`` is perspective-correct, weights
    b_i/w_i renormalized; ``noperspective`` uses the window-space barycentrics
    b_i directly; ``flat`` takes the provoking vertex's value, which primitive
    assembly has copied to every corner.
    """
    key = ("fragment", python_function(shader), layout.fields)
    kern = _KERNELS.get(key)
    if kern is not None:
        return kern
    lines = [
        "def fragment_loop(triangle, frag_x, frag_y, depth, bary, inv_w, corner, front, prim_id, uniforms, out_color):",
        "    for i in range(triangle.shape[0]):",
        "        t = triangle[i]",
        "        b0 = bary[i, 0]",
        "        b1 = bary[i, 1]",
        "        b2 = bary[i, 2]",
    ]
    quals = {q for *_, q in layout.fields}
    if "smooth" in quals:
        lines += [
            "        q0 = b0 * inv_w[t, 0]",
            "        q1 = b1 * inv_w[t, 1]",
            "        q2 = b2 * inv_w[t, 2]",
            "        qs = q0 + q1 + q2",
            "        p0 = q0 / qs",
            "        p1 = q1 / qs",
            "        p2 = q2 / qs",
        ]
    exprs = []
    for n, off, size, q in layout.fields:
        comps = []
        for c in range(size):
            k = off + c
            if q == "flat":
                comps.append(f"corner[t, 2, {k}]")
            elif q == "smooth":
                comps.append(f"p0 * corner[t, 0, {k}] + p1 * corner[t, 1, {k}] + p2 * corner[t, 2, {k}]")
            else:
                comps.append(f"b0 * corner[t, 0, {k}] + b1 * corner[t, 1, {k}] + b2 * corner[t, 2, {k}]")
        var = f"v_{n}"
        if size == 1:
            lines.append(f"        {var} = {comps[0]}  # {q}")
        else:
            lines.append(f"        {var} = ({', '.join(comps)})  # {q}")
        exprs.append(var)
    lines += [
        f"        varyings = Varyings({', '.join(exprs)})",
        "        frag = FragInfo(frag_x[i], frag_y[i], depth[i], front[t], prim_id[t])",
        "        c = shader(varyings, uniforms, frag)",
        "        out_color[i, 0] = c[0]",
        "        out_color[i, 1] = c[1]",
        "        out_color[i, 2] = c[2]",
        "        out_color[i, 3] = c[3]",
    ]
    source = "\n".join(lines) + "\n"
    names = list(layout.names) or ["none"]
    if not layout.fields:
        source = source.replace("Varyings()", "Varyings(0.0)")
    namespace = {"shader": jit_function(shader), "Varyings": namedtuple("Varyings", names), "FragInfo": FragInfo}
    kern = _compile_source(source, namespace, "fragment_loop", "fragment loop")
    _KERNELS[key] = kern
    return kern


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


def run_compiled(kind: str, shader: Callable, kernel: Callable, *args) -> None:
    """Call a generated loop; turn numba's typing errors into a ShaderError naming the shader."""
    try:
        kernel(*args)
    except (numba.core.errors.TypingError, numba.core.errors.LoweringError,
            numba.core.errors.UnsupportedError) as e:
        raise _describe_compile_error(kind, shader, e) from None
