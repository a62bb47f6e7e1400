"""The shader contract: the types a shader receives and returns.

A shader is a per-invocation Python function written like GLSL, compiled by numba
and run over a batch: it sees one vertex or one fragment, small vectors are tuples
of floats, and its inputs arrive as namedtuples so that they read by name
(``varyings.normal``, ``uniforms.light_dir``, ``frag.x``)::

    def vertex(attributes, uniforms):                    # -> clip position, Varyings(...)
    def fragment(varyings, uniforms, frag):              # -> (r, g, b, a) or DISCARD
    def fragment(varyings, uniforms, frag, derivatives): # with exact dFdx / dFdy

Into a framebuffer of several color attachments (multiple render targets, GLSL's
``layout(location = k) out``), a fragment shader returns a tuple of one value per attachment,
in the attachments' order: 4 numbers for ``rgba8`` and ``rgba32f``, a number for ``r32f``, an
int for ``r32i``; ``DISCARD`` as the first value discards (the generated loop checks them,
:func:`softpipe.language.kernels.outputs`). A single-output shader is unchanged.

A vertex shader's ``attributes`` holds, by name, ``position`` (the draw's positions) and
every array given as ``attributes=``: a float for an [N] array, a tuple of k floats for
[N, k]. In an instanced draw (``draw(..., instances=N, instance_attributes={...})``) it
holds too each instance attribute, the row of the instance being drawn, and
``instance_id``, GLSL's ``gl_InstanceID``: an int, 0 for the first instance (so
``uniforms.table[attributes.instance_id]`` picks an instance's row of a uniform table).

Here: :data:`FragInfo` (``x``, ``y`` as ``gl_FragCoord``, ``z``, ``front_facing``,
``primitive_id``, ``point_coord``), :data:`DISCARD`, :class:`Derivatives`, the uniforms
(:func:`make_uniforms`, :func:`reads_uniforms`: GLSL's ``uniform`` declarations, so a
compiled loop serves every draw whose other uniforms differ), the varyings' layout
(:class:`VaryingLayout`, :data:`QUALIFIERS`) and :class:`ShaderError`.

Why it is shaped so: the contract is apart from how a shader runs (the generated
loop, numba's compilation and cache, error reports: :mod:`softpipe.language.kernels`)
and from what it calls (GLSL math, lighting: :mod:`softpipe.shading`), so a shader
author reads only this and that. docs/shaders.md is the guide: every input, what
Python a shader may use, an example, and what to do when it goes wrong.
"""
from __future__ import annotations

import inspect
import keyword
import math
import types
from collections import namedtuple
from dataclasses import dataclass
from typing import Any, Callable, Dict, Mapping, Sequence, Tuple

import numpy as np

__all__ = ["FragInfo", "DISCARD", "Derivatives", "ShaderError", "make_uniforms", "VaryingLayout", "QUALIFIERS",
           "wants_derivatives", "reads_uniforms", "declared_uniforms",
           "check_name", "field_size", "python_function", "shader_name", "uniforms_class_field_names"]

#: The fragment's fixed-function inputs (``gl_FragCoord`` and friends): ``x``, ``y``, ``z`` as
#: ``gl_FragCoord``; ``front_facing`` (always True for points and lines); ``primitive_id``;
#: ``point_coord``, where the fragment lies in its primitive: on a point GLSL's ``gl_PointCoord``
#: (s, t), from (0, 0) at the square's upper-left corner to (1, 1); on a line (t, 0), t from 0 at
#: its first end to 1 at its last; on a triangle its barycentrics (b1, b2) (b0 = 1 − b1 − b2).
#: ``primitive_id`` is ``gl_PrimitiveID``: the primitive's number in the draw, from 0, restarting
#: at 0 in each instance of an instanced draw.
#: (A FragInfo made in Python without ``point_coord``, for calling a shader by hand, gets (0, 0).)
FragInfo = namedtuple("FragInfo", ["x", "y", "z", "front_facing", "primitive_id", "point_coord"],
                      defaults=((0.0, 0.0),))

#: Return this from a fragment shader to discard the fragment (GLSL ``discard``).
#: It is the color whose alpha is NaN; the fragment stage tests for exactly that.
DISCARD = (math.nan, math.nan, math.nan, math.nan)

QUALIFIERS = ("smooth", "noperspective", "flat")


class ShaderError(Exception):
    """A shader could not be compiled or run; the message says what is wrong and names the shader,
    its file and line.

    Attributes: ``file`` and ``line`` (where in the shader's code, when known),
    ``invocation`` (for an error raised while it ran: the fragment or vertex, in
    words) and ``numba_message`` (for a compile error: numba's full text, which
    ``SOFTPIPE_SHADER_DEBUG=1`` adds to the message).
    """

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 invocation: str | None = None, numba_message: str | None = None):
        super().__init__(message)
        self.file, self.line, self.invocation, self.numba_message = file, line, invocation, numba_message


def shader_name(fn: Callable) -> str:
    f = getattr(fn, "py_func", fn)
    return f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', repr(f))}"


def python_function(fn: Callable) -> Callable:
    """The plain-Python function behind a shader (numba dispatcher or not)."""
    return getattr(fn, "py_func", fn)


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


def uniforms_class_field_names(attr: str) -> list:
    """The field names spelled out in a uniforms class's name (the inverse of its naming)."""
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
        cls = globals()[attr] = namedtuple(attr, list(names) or ["empty"])
        cls.__module__ = __name__
    return cls


def __getattr__(attr: str):
    # Unpickling a cached kernel's signature asks for Uniforms_… classes by name.
    if attr.startswith("Uniforms_"):
        return _uniforms_class(uniforms_class_field_names(attr))
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


def reads_uniforms(*names: str) -> Callable[[Callable], Callable]:
    """Declare the uniforms a shader reads: ``@reads_uniforms("model_view", "projection")``.

    As GLSL's ``uniform`` declarations: the compiled loop that runs the shader
    is given only these (:func:`declared_uniforms`), so a program whose other
    uniforms differ (another material, a user's own uniform) reuses the loop
    compiled, and cached, for the first one instead of compiling it again for
    a new uniforms type. A declared shader that reads an undeclared uniform
    fails to compile with an error naming it. Undeclared shaders get every uniform.
    """
    for n in names:
        check_name("uniform", n)

    def declare(shader: Callable) -> Callable:
        python_function(shader).uniforms_read = tuple(names)  # type: ignore[attr-defined]  # a function's attribute
        return shader
    return declare


def declared_uniforms(shader: Callable, uniforms):
    """``uniforms`` (a :func:`make_uniforms` namedtuple) cut down to those ``shader`` declares
    with :func:`reads_uniforms` (the ones given of them), or ``uniforms`` itself."""
    names = getattr(python_function(shader), "uniforms_read", None)
    if names is None or uniforms is None:
        return uniforms
    names = tuple(n for n in names if n in uniforms._fields)
    if names == tuple(uniforms._fields):
        return uniforms
    cls = _uniforms_class(names)
    return cls(*(getattr(uniforms, n) for n in names)) if names else cls(0.0)


def check_name(what: str, name) -> None:
    """A shader reads its inputs by attribute (``varyings.normal``): a name must be a Python
    identifier and not a keyword (``varyings.lambda`` is not Python)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"{what} name {name!r} is not a valid Python identifier")
    if keyword.iskeyword(name):
        raise ValueError(f"{what} name {name!r} is a Python keyword: a shader could not read it "
                         f"(`….{name}` is not Python); rename it, e.g. {name + '_'!r}")


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
        check_name("uniform", n)
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


def field_size(name: str, what: str, value) -> int:
    """How many floats a varying or uniform field holds (1 to 4), or a ShaderError naming it."""
    if isinstance(value, (int, float, np.integer, np.floating, bool)):
        return 1
    if isinstance(value, tuple) and 2 <= len(value) <= 4 and all(
            isinstance(c, (int, float, np.integer, np.floating)) for c in value):
        return len(value)
    raise ShaderError(f"{what} {name!r} must be a float or a tuple of 2–4 floats, got {value!r}")



#: The 4th argument of a fragment shader that asks for it: ``derivatives.dx.uv`` is ∂uv/∂x.
Derivatives = namedtuple("Derivatives", ["dx", "dy"])


def wants_derivatives(shader: Callable) -> bool:
    """Does the fragment shader take a 4th parameter (screen-space derivatives of its varyings)?"""
    f = python_function(shader)
    if isinstance(f, types.FunctionType) and not hasattr(f, "__wrapped__"):
        return f.__code__.co_argcount >= 4      # (what inspect.signature counts, without its cost per draw)
    try:
        params = inspect.signature(f).parameters.values()
    except (TypeError, ValueError):
        return False
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params) >= 4

