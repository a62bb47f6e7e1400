"""The code generator: for each (shader, varying layout), the small module that runs the shader.

For each (shader, varying layout) softpipe writes a small Python module: a loop
over the batch with the unpacking of attributes or varyings written out by name
(:func:`kernel_source` shows it), and compiles it with numba; the shader is
inlined into that loop. Under ``NUMBA_DISABLE_JIT=1`` the same loop runs as
Python, so a breakpoint in a shader stops there.

The loops' fixed parts are Python files a linter reads, ``templates/vertex.py``
and ``templates/fragment.py``, and the interpolation of one varying component
``templates/varyings.py``; this module writes what depends on the layout (a
line per varying, the attributes' unpacking) into them (:mod:`.template` says how).

- **Vertex loop** (:func:`vertex_kernel`): attributes in, clip position and varyings out.
- **Varyings** (:func:`varyings_module`): one module per varying layout, shared by
  every shader of that layout: the ``Varyings`` namedtuple, ``interpolate`` (the
  varyings at barycentrics, with their qualifiers) and ``fragment_inputs``;
  compiled once, however many shaders run on it.
- **Fragment loops** (:func:`fragment_module`): ``fragment_loop`` (the reference
  path: one row per fragment) and ``visible_loop`` (the fast path: the samples the
  visibility pass kept, with barycentrics, depth and position from the same
  triangle setup functions the rasterizer uses), importing their layout's varyings. The color a fragment shader
  returns goes through :func:`~.diagnostics.rgba`, which refuses (when numba types
  it) anything but 4 numbers. For a framebuffer of several attachments the module
  has ``fragment_loop_outputs`` too (its values through :func:`~.diagnostics.outputs`);
  a framebuffer of one gets the module it always got, character for character.
- **The points' and lines' loops** (:func:`primitive_kernel`): ``primitive_loop``, the fast path's
  points or lines shaded in primitive order, in a module of its own (a shader drawing triangles
  never compiles it).

A generated module imports only :mod:`softpipe.language.contract` (the contract), the
kernels package (``borrowed_tuple``, ``jit_function``, ``rgba``, ``short_repr``) and,
for the fragment loops, the triangle setup's per-sample functions
(:mod:`softpipe.pipeline.setup`: ``pixel_coverage``, ``shading_point``,
``sample_depth``, the ones the rasterizer calls) and its layout's varyings module:
``_HEADER``, ``_FRAGMENT_IMPORTS`` and ``_fragment_preamble`` below are every import it has
(the points' and lines' loops: their setup's functions instead, ``_PRIMITIVE_IMPORTS``). Where it is kept:
:mod:`.cache`. More: docs/05-fragment.md (a generated loop), docs/08-fast-path.md.
"""
from __future__ import annotations

import hashlib
import re
import sys
import types
from typing import Callable, Dict, NamedTuple, Optional, Sequence, Tuple

import numba

from softpipe.language.contract import VaryingLayout, python_function, shader_name, wants_derivatives
from softpipe.language.kernels.cache import (
    COMPILE_LOCK,
    cached_file_name,
    cached_module,
    importable_shader,
    load_cached,
)
from softpipe.language.kernels.snapshot import shader_snapshot, shader_source_key
from softpipe.language.kernels.template import template_expression, template_function

#: A framebuffer's color attachments, ((name, format), ...) in location order.
Attachments = Tuple[Tuple[str, str], ...]

__all__ = ["outputs_spec", "vertex_kernel", "varyings_module", "fragment_module", "fragment_kernel", "visible_kernel",
           "primitive_kernel", "python_fragment_module", "kernel_source", "exec_module", "jit_function", "short_repr"]


#: softpipe's own shaders as dispatchers, one each per process: every loop that runs one links the same
#: compiled function (jit_function).
_OWN_SHADERS: Dict[Callable, Callable] = {}


def jit_function(fn: Callable) -> Callable:
    """``fn`` as a numba dispatcher (compiling a plain function on first call).

    The shader is compiled on its own, once for all the loops that run it (a module's
    ``fragment_loop`` and ``visible_loop``), and marked for LLVM to inline into each
    (``forceinline``: the loops run as if it were written in them). numba's own
    inlining (``inline="always"``) would type the shader, and everything it calls,
    again inside every loop: a lit program's loops took several times as long to
    compile (docs/08-fast-path.md). softpipe's own shaders are one dispatcher each per
    process, shared by every module that runs them.
    """
    if not callable(fn):
        raise TypeError(f"a shader must be a function, got {type(fn).__name__}")
    if isinstance(fn, numba.core.registry.CPUDispatcher):
        return fn
    if numba.config.DISABLE_JIT:
        return fn
    if importable_shader(fn) is None:
        return numba.njit(fn, forceinline=True)
    if fn not in _OWN_SHADERS:
        # not numba's on-disk cache: the shader's signature names the generated module's Varyings
        # class, which another process cannot unpickle; the loops that inline it are cached instead
        _OWN_SHADERS[fn] = numba.njit(fn, forceinline=True)
    return _OWN_SHADERS[fn]


_HEADER = ("# Generated by softpipe.language.kernels.generate: the loop that runs one shader over a batch.\n"
           "import numba\n"
           "from collections import namedtuple\n"
           "from softpipe.language.contract import Derivatives, FragInfo\n"
           "from softpipe.language.kernels import borrowed_tuple, jit_function, rgba, short_repr\n")
#: What the fragment loops call besides the shader: the triangle setup's per-sample functions,
#: the very ones the rasterizer calls (a vertex loop does not need them, so they are not in _HEADER).
_FRAGMENT_IMPORTS = ("from softpipe.pipeline.setup import pixel_coverage, sample_depth, shading_point\n"
                     "from softpipe.language.kernels import finite_rgba\n")
#: What the points' and lines' loops call besides the shader: the inputs of a point's or line's sample, made
#: by the very functions the reference path's fragments of them are.
_PRIMITIVE_IMPORTS = ("from softpipe.pipeline.points import point_sample_inputs\n"
                      "from softpipe.pipeline.lines import line_sample_inputs, sample_means\n"
                      "from softpipe.language.kernels import finite_rgba\n")
#: What a module for several attachments imports besides: the check of the shader's values.
_OUTPUTS_IMPORT = "from softpipe.language.kernels import outputs\n"


def _module_source(body: str, shader: Callable, preamble: str, cached: bool) -> str:
    """The generated module: header, the shader as global ``shader``, namedtuples, then ``body``.

    Functions in ``body`` are decorated ``@JIT`` (``cache=True`` when the module is a
    cached file); softpipe's own shader is imported by name when the module is a cached
    file, any other is given to the module as ``_shader_py``.
    """
    where = importable_shader(shader) if cached else None
    imp = f"from {where[0]} import {where[1]} as _shader_py\n" if where else ""
    jit = f"JIT = numba.njit(cache={bool(cached)}, nogil=True)\n"
    # Namedtuple classes get names of their own per module: numba's on-disk cache
    # finds a type by module and name, and two modules' "Varyings" must not meet.
    tag = hashlib.sha256((shader_name(shader) + preamble + body).encode()).hexdigest()[:12]
    return (_HEADER + imp + "shader = jit_function(_shader_py)\n" + jit + preamble.replace("@TAG@", tag)
            + "\n\n" + body)


def _compile_module(body: str, shader: Callable, preamble: str, kind: str, globals_key: tuple = ()):
    """The generated module for a shader: a file of the kernel cache, where numba's cache can keep it, else exec'd.

    softpipe's own shader is imported by name, and numba reads its globals as they
    are when it compiles; the file's name hashes their values (``globals_key``), so a
    changed value is a new file. A user's shader is given to the module as its
    snapshot (:func:`shader_snapshot`), and the file's name hashes its code, its
    helpers' and its globals' values (:func:`shader_source_key`), so a changed one is a
    new file too; a user's shader that reads a global no key can name (an object of
    its own) is exec'd, compiled once per process. Unless numba is off: then the
    module runs the user's own function.
    """
    if not numba.config.DISABLE_JIT:
        cached: Optional[Tuple[str, Optional[Dict[str, Callable]]]] = None
        if importable_shader(shader) is not None:
            source = _module_source(body, shader, preamble, cached=True)
            cached = (cached_file_name(source, kind, globals_key), None)
        else:
            user_key = shader_source_key(shader)
            if user_key is not None:
                source = _module_source(body, shader, preamble, cached=True)
                cached = (cached_file_name(source, kind, globals_key, user_key), {"_shader_py": shader_snapshot(shader)})
        if cached is not None:
            try:
                return load_cached(source, *cached)
            except OSError:
                pass  # an unwritable cache directory: compile in memory instead
    source = _module_source(body, shader, preamble, cached=False)
    compiled = python_function(shader) if numba.config.DISABLE_JIT else shader_snapshot(shader)
    return exec_module(source, shader, kind, compiled=compiled)


def exec_module(source: str, shader: Callable, kind: str, python: bool = False,
                compiled: Callable | None = None) -> types.ModuleType:
    """exec a generated module; with ``python``, numba is left out entirely (for debugging).

    Parameters
    ----------
    source : str
        The generated module's source (``__softpipe_source__`` of one).
    shader : callable
        The user's shader, whose name the module's file name shows.
    kind : str
        ``"vertex"`` or ``"fragment"``.
    python : bool
        Run it as plain Python: ``JIT`` and ``jit_function`` become no-ops.
    compiled : callable, optional
        The function the module's ``shader`` is made from (default: the user's own).
    """
    module = types.ModuleType(f"softpipe_{kind}_loop")
    module._shader_py = python_function(shader) if compiled is None else compiled  # type: ignore[attr-defined]  # the source reads it
    if python:
        # The same source, run as plain Python: JIT and jit_function become no-ops.
        source = source.replace("shader = jit_function(_shader_py)", "shader = _shader_py")
        source = re.sub(r"JIT = numba\.njit\([^)]*\)", "JIT = lambda f: f", source)
        source = re.sub(r"^from \S+ import \S+ as _shader_py\n", "", source, flags=re.M)
    exec(compile(source, f"<softpipe {kind} loop for {shader_name(shader)}>", "exec"), module.__dict__)
    module.__softpipe_source__ = source  # type: ignore[attr-defined]  # as cached_module's
    return module


def kernel_source(kind: str, shader: Callable, layout: VaryingLayout) -> str:
    """The generated Python source, to read it: ``kind="fragment"``, the shader's loops; ``"varyings"``,
    its layout's varyings module (``interpolate``, ``fragment_inputs``), which the loops import."""
    if kind == "varyings":
        return varyings_module(layout, wants_derivatives(shader)).__softpipe_source__
    if kind != "fragment":
        raise ValueError(f"kernel_source: kind must be 'fragment' or 'varyings', got {kind!r}")
    return fragment_module(shader, layout).__softpipe_source__


def _namedtuple_line(var: str, typename: str, names: Sequence[str]) -> str:
    unique = f"{typename}_@TAG@"
    return (f"{unique} = namedtuple({unique!r}, {list(names)!r})\n{unique}.__repr__ = short_repr\n"
            f"{var} = {unique}\n")


def short_repr(self: NamedTuple) -> str:
    """A generated namedtuple's repr without its unique tag: ``Varyings(normal=…)``."""
    name = type(self).__name__.rsplit("_", 1)[0]
    return name + "(" + ", ".join(f"{f}={v!r}" for f, v in zip(self._fields, self)) + ")"


def vertex_kernel(shader: Callable, attr_sizes: Sequence[Tuple[str, int]], out_layout: VaryingLayout) -> Callable:
    """The compiled loop that runs ``shader`` over every vertex."""
    def build(globals_key):
        names = [n for n, _ in attr_sizes]
        return _compile_module(_vertex_body(attr_sizes, out_layout), shader,
                               _namedtuple_line("Attributes", "Attributes", names), "vertex", globals_key)

    module = cached_module(("vertex", python_function(shader), tuple(attr_sizes), out_layout.fields), shader, build)
    return module.vertex_loop


def _vertex_body(attr_sizes: Sequence[Tuple[str, int]], out_layout: VaryingLayout) -> str:
    """Source of ``vertex_loop`` (templates/vertex.py) for these attributes and varyings."""
    values = ", ".join(f"a_{n}[i, 0]" if size == 1 else "(" + ", ".join(f"a_{n}[i, {c}]" for c in range(size)) + ")"
                       for n, size in attr_sizes)
    stores = []
    for j, (n, off, size, _) in enumerate(out_layout.fields):
        if size == 1:
            stores.append(f"out_varyings[i, {off}] = v[{j}]  # {n}")
        else:
            stores += [f"out_varyings[i, {off + c}] = v[{j}][{c}]  # {n}.{'xyzw'[c]}" for c in range(size)]
    return template_function("vertex", "vertex_loop", fill={
        "ATTRIBUTE_ARRAYS": ", ".join(f"a_{n}" for n, _ in attr_sizes),
        "ATTRIBUTE_VALUES": values,
        "STORE_VARYINGS": stores,
    })


def _components(layout: VaryingLayout, prefix: str, component: Callable[[str, int, int, int, str], str]) -> tuple:
    """(a line ``{prefix}{name} = …`` per varying, the names joined), each component's expression
    ``component(name, size, c, column, qualifier)``: its index c in the varying, its column in ``corner``.

    A varying of one component is a float, of more a tuple; a layout without varyings
    is written as a single ``0.0`` (the namedtuple's one field ``none``).
    """
    lines, names = [], []
    for n, off, size, q in layout.fields:
        comps = [component(n, size, c, off + c, q) for c in range(size)]
        lines.append(f"{prefix}{n} = " + (comps[0] if size == 1 else f"({', '.join(comps)})"))
        names.append(f"{prefix}{n}")
    return lines, ", ".join(names) or "0.0"


def _varying_lines(layout: VaryingLayout) -> tuple:
    """``VARYINGS_AT_BARYCENTRICS`` and ``VARYING_VALUES`` of templates/fragment.py (templates/varyings.py)."""
    lines, names = _components(layout, "v_", lambda n, size, c, k, q: template_expression("varyings", q, {"K": k}))
    return [f"{line}  # {q}" for line, (*_, q) in zip(lines, layout.fields)], names


def _store_lines(layout: VaryingLayout) -> list:
    """``STORE_VARYINGS`` of templates/fragment.py: the Varyings' components in order, a column each.

    The order of the namedtuple, flattened (a tuple's components in turn), which is what
    the explorer page holds; a layout without varyings stores its one field ``none`` (0.0).
    """
    if not layout.fields:
        return ["out_varyings[r, 0] = v[0]  # none"]
    lines, column = [], 0
    for j, (n, _, size, _) in enumerate(layout.fields):
        if size == 1:
            lines.append(f"out_varyings[r, {column}] = v[{j}]  # {n}")
        else:
            lines += [f"out_varyings[r, {column + c}] = v[{j}][{c}]  # {n}.{'xyzw'[c]}" for c in range(size)]
        column += size
    return lines


def _derivative_lines(layout: VaryingLayout, axis: int) -> tuple:
    """``DERIVATIVES_X`` and ``DX_VALUES`` (axis 0) or ``DERIVATIVES_Y`` and ``DY_VALUES`` (axis 1).

    ∂v/∂x or ∂v/∂y of every varying, from the barycentrics' gradients (templates/varyings.py).
    """
    name = "xy"[axis]

    def component(n, size, c, k, q):
        fill = {"AXIS": axis, "K": k}
        if q == "smooth":
            fill.update(V=f"v_{n}" if size == 1 else f"v_{n}[{c}]", DQ=f"dq{name}")
        elif q == "flat":
            fill = {}
        return template_expression("varyings", f"{q}_derivative", fill)

    lines, names = _components(layout, f"d{name}_", component)
    if any(q == "smooth" for *_, q in layout.fields):
        lines.insert(0, f"dq{name} = " + template_expression("varyings", "weights_derivative", {"AXIS": axis}))
    return lines, names


def outputs_spec(attachments: Attachments) -> str:
    """The attachments written as the text the generated loop gives ``outputs`` to check the shader's
    values against (:func:`~.diagnostics.outputs`): ``"color:rgba8,id:r32i"``."""
    return ",".join(f"{name}:{fmt}" for name, fmt in attachments)


def _output_lines(attachments: Attachments) -> list:
    """``STORE_OUTPUTS`` of templates/fragment.py: each value's components to its attachment's array."""
    lines = []
    for k, (name, fmt) in enumerate(attachments):
        target = "out_color" if k == 0 else f"out_more[{k - 1}]"
        if fmt in ("r32f", "r32i"):
            lines.append(f"{target}[i] = values[{k}]  # {name}")
        else:
            lines += [f"{target}[i, {c}] = values[{k}][{c}]  # {name}.{'rgba'[c]}" for c in range(4)]
    return lines


def _varyings_body(layout: VaryingLayout, derivatives: bool) -> str:
    """Source of ``interpolate``, ``fragment_inputs`` and ``inputs_loop`` (templates/fragment.py) for a
    varying layout, for shaders that take ``derivatives`` or not: the varyings module's functions."""
    smooth = any(q == "smooth" for *_, q in layout.fields)
    varyings, values = _varying_lines(layout)
    fill = {"VARYINGS_AT_BARYCENTRICS": varyings, "VARYING_VALUES": values}
    if derivatives:
        (dx, dx_values), (dy, dy_values) = _derivative_lines(layout, 0), _derivative_lines(layout, 1)
        fill.update(DERIVATIVES_X=dx, DX_VALUES=dx_values, DERIVATIVES_Y=dy, DY_VALUES=dy_values)
    flags = {"DERIVATIVES": derivatives}
    return "\n\n".join([
        template_function("fragment", "interpolate", dict(flags, SMOOTH=smooth), fill),
        template_function("fragment", "fragment_inputs"),
        template_function("fragment", "inputs_loop", flags, {"STORE_VARYINGS": _store_lines(layout)}),
    ])


def _fragment_body(derivatives: bool = False, attachments: Attachments = ()) -> str:
    """Source of ``fragment_loop`` and the two visible loops (templates/fragment.py), for a shader that takes
    ``derivatives`` or not; and of ``fragment_loop_outputs`` for ``attachments`` of more than one."""
    flags = {"DERIVATIVES": derivatives}
    functions = [
        template_function("fragment", "fragment_loop", flags),
        template_function("fragment", "visible_loop", flags),
        # shading 0 (at the samples) alone: the multisampling branches left out
        template_function("fragment", "visible_loop", dict(flags, shading=0), rename="visible_loop_at_samples"),
    ]
    if len(attachments) > 1:
        functions.append(template_function("fragment", "fragment_loop_outputs", flags, {
            "OUTPUT_FORMATS": repr(outputs_spec(attachments)), "STORE_OUTPUTS": _output_lines(attachments)}))
    return "\n\n".join(functions)


#: What a varyings module imports: numba, the contract's FragInfo and Derivatives, and the repr of its Varyings.
_VARYINGS_HEADER = ("# Generated by softpipe.language.kernels.generate: the varyings of one layout at a fragment.\n"
                    "import numba\n"
                    "from collections import namedtuple\n"
                    "from softpipe.language.contract import Derivatives, FragInfo\n"
                    "from softpipe.language.kernels import short_repr\n")
#: The names a shader's module imports from its layout's varyings module.
_VARYINGS_NAMES = "Varyings, interpolate, fragment_inputs, inputs_loop"
#: The varyings modules of this process, by (layout fields, derivatives, plain Python).
_VARYINGS_MODULES: Dict[tuple, types.ModuleType] = {}


def _varyings_source(layout: VaryingLayout, derivatives: bool, cached: bool) -> str:
    body = _varyings_body(layout, derivatives)
    tag = hashlib.sha256(body.encode()).hexdigest()[:12]
    return (_VARYINGS_HEADER + f"JIT = numba.njit(cache={bool(cached)}, nogil=True)\n"
            + _namedtuple_line("Varyings", "Varyings", list(layout.names) or ["none"]).replace("@TAG@", tag)
            + "\n\n" + body)


def varyings_module(layout: VaryingLayout, derivatives: bool, python: bool = False) -> types.ModuleType:
    """The module of one varying layout's ``Varyings``, ``interpolate``, ``fragment_inputs`` and ``inputs_loop``.

    Every shader of a layout runs on the same varyings: its module imports them from
    here, so they are compiled once for all of them (per process, and kept in numba's
    on-disk cache) and every shader of the layout is typed with one ``Varyings`` class.
    The module is named for its source (``softpipe_varyings_…``) and is in
    ``sys.modules``, where the shader modules' imports and numba's cache find it. With
    ``python``, the same source as plain Python (``softpipe_varyings_…_python``), for
    :func:`python_fragment_module`.
    """
    key = (layout.fields, bool(derivatives), bool(python))
    module = _VARYINGS_MODULES.get(key)
    if module is not None:
        return module
    with COMPILE_LOCK:
        module = _VARYINGS_MODULES.get(key)
        if module is not None:
            return module
        source = _varyings_source(layout, derivatives, cached=True)
        name = cached_file_name(source, "varyings", ())
        module = None
        if not python and not numba.config.DISABLE_JIT:
            try:
                module = load_cached(source, name)
            except OSError:
                pass  # an unwritable cache directory: compile in memory instead
        if module is None:
            if python:
                name += "_python"
            source = _varyings_source(layout, derivatives, cached=False)
            module = types.ModuleType(name)
            if python:
                source = re.sub(r"JIT = numba\.njit\([^)]*\)", "JIT = lambda f: f", source)
            exec(compile(source, f"<softpipe varyings {name}>", "exec"), module.__dict__)
            module.__softpipe_source__ = source  # type: ignore[attr-defined]  # as load_cached's
            sys.modules[name] = module     # where the shader modules' imports find it
        _VARYINGS_MODULES[key] = module
    return module


def _fragment_preamble(layout: VaryingLayout, derivatives: bool, attachments: Attachments = (),
                       python: bool = False) -> str:
    varyings = varyings_module(layout, derivatives, python).__name__
    return (_FRAGMENT_IMPORTS + (_OUTPUTS_IMPORT if len(attachments) > 1 else "")
            + f"from {varyings} import {_VARYINGS_NAMES}\n")


def fragment_module(shader: Callable, layout: VaryingLayout, attachments: Attachments = ()) -> types.ModuleType:
    """The generated module of ``shader``'s fragment loops for ``layout`` (built and compiled once per
    set of its globals' values): ``interpolate``, ``fragment_inputs``, ``inputs_loop``, ``fragment_loop``, the
    visible loops; and ``fragment_loop_outputs`` for ``attachments`` ((name, format), … of a
    framebuffer) when there are more than one."""
    return _fragment_module(shader, layout, wants_derivatives(shader), tuple(attachments) if len(attachments) > 1
                            else ())


def _fragment_module(shader: Callable, layout: VaryingLayout, derivatives: bool, attachments: Attachments = ()):
    """The generated module holding ``fragment_inputs`` and ``fragment_loop`` for a shader and layout.

    Interpolation (docs/design.md, templates/varyings.py): ``smooth`` is perspective-correct,
    Σ q_k v_k / Σ q_k with q_k = b_k/w_k; ``noperspective`` uses the window-space barycentrics
    b_k directly; ``flat`` takes the provoking vertex's value, which primitive
    assembly has copied to every corner.
    """
    key = ("fragment", python_function(shader), layout.fields, derivatives) + ((attachments,) if attachments else ())
    return cached_module(key, shader,
                         lambda globals_key: _compile_module(_fragment_body(derivatives, attachments), shader,
                                                             _fragment_preamble(layout, derivatives, attachments),
                                                             "fragment", globals_key))


def fragment_kernel(shader: Callable, layout: VaryingLayout, attachments: Attachments = ()) -> Callable:
    """The compiled loop that interpolates varyings and runs ``shader`` per fragment: ``fragment_loop``, or
    ``fragment_loop_outputs`` for ``attachments`` of more than one (a framebuffer's (name, format), …)."""
    if len(attachments) > 1:
        return fragment_module(shader, layout, attachments).fragment_loop_outputs
    return fragment_module(shader, layout).fragment_loop


def visible_kernel(shader: Callable, layout: VaryingLayout, shading: str = "sample") -> Callable:
    """The compiled loop that shades the samples a visibility pass kept (:mod:`softpipe.pipeline.visibility`).

    ``shading`` "sample" (at each sample) has a loop of its own, ``visible_loop_at_samples``;
    "center" and "centroid" (once per pixel and triangle) share ``visible_loop``.
    """
    module = fragment_module(shader, layout)
    return module.visible_loop_at_samples if shading == "sample" else module.visible_loop


def primitive_kernel(shader: Callable, layout: VaryingLayout, kind: str) -> Callable:
    """The compiled loop that shades the visible samples of points or lines (``kind``), sorted by primitive
    (``primitive_loop``, :func:`~softpipe.pipeline.primitive_visibility.shade_primitives`): a module of its own,
    built and compiled once per set of the shader's globals' values, importing its layout's varyings."""
    if kind not in ("points", "lines"):
        raise ValueError(f"primitive_kernel: kind must be 'points' or 'lines', got {kind!r}")
    derivatives = wants_derivatives(shader)
    key = (kind, python_function(shader), layout.fields, derivatives)

    def build(globals_key):
        # the loop's source made only when the module is built (filling the template took a
        # quarter of a millisecond, in every draw)
        varyings = varyings_module(layout, derivatives).__name__
        preamble = _PRIMITIVE_IMPORTS + f"from {varyings} import {_VARYINGS_NAMES}\n"
        body = template_function("fragment", "primitive_loop", {"DERIVATIVES": derivatives, "LINES": kind == "lines"})
        return _compile_module(body, shader, preamble, kind, globals_key)

    return cached_module(key, shader, build).primitive_loop


def python_fragment_module(shader: Callable, layout: VaryingLayout) -> types.ModuleType:
    """The same generated module as plain Python (no numba), for stepping through one fragment."""
    derivatives = wants_derivatives(shader)
    source = _module_source(_fragment_body(derivatives), shader, _fragment_preamble(layout, derivatives, python=True),
                            cached=False)
    return exec_module(source, shader, "fragment", python=True)
