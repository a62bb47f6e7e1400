"""How shaders run: the generated loops that inline them, numba's compilation and cache, errors.

For each (shader, varying layout) softpipe writes a small Python module: a loop
over the batch with the unpacking of attributes or varyings written out by name
(:func:`kernel_source` shows it), and compiles it with numba; the shader is
inlined into that loop. Under ``NUMBA_DISABLE_JIT=1`` the same loop runs as
Python, so a breakpoint in a shader stops there.

- **Vertex loop** (:func:`vertex_kernel`): attributes in, clip position and varyings out.
- **Fragment loops** (:func:`fragment_module`): ``interpolate`` (the varyings at
  barycentrics, with their qualifiers), ``fragment_loop`` (the reference path: one
  row per fragment) and ``visible_loop`` (the fast path: the samples the
  visibility pass kept, with barycentrics, depth and position from the same
  triangle setup functions the rasterizer uses).
- **The cache**: softpipe's own shaders get their generated module written to
  ``$SOFTPIPE_CACHE_DIR`` (default ``~/.cache/softpipe/kernels``) so numba's
  on-disk cache can find them in the next process; a user's shader is compiled
  once per process.
- **Errors**: :func:`run_compiled` turns numba's errors into a
  :class:`~softpipe.shader.ShaderError` naming the shader, its file and line.
- **Analysis**: :func:`may_discard` (does a shader return DISCARD: decides the
  fast path), :func:`probe_vertex_shader` (the varyings a vertex shader makes).

A generated module imports only :mod:`softpipe.shader` (the contract), this
module (``jit_function``, ``short_repr``) and, for the fragment loops, the
triangle setup's per-sample functions (:mod:`softpipe.setup`:
``pixel_coverage``, ``shading_point``, ``sample_depth``, the ones the rasterizer
calls): ``_HEADER`` and ``_FRAGMENT_IMPORTS`` below are every import it has.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import re
import sys
import types
from pathlib import Path
from typing import Any, Callable, Dict, Sequence, Tuple

import numba

from .shader import ShaderError, VaryingLayout, _field_size, python_function, shader_name, wants_derivatives

__all__ = ["vertex_kernel", "fragment_module", "fragment_kernel", "visible_kernel", "python_fragment_module",
           "kernel_source", "run_compiled", "may_discard", "probe_vertex_shader", "probe_fragment_shader",
           "jit_function"]

def jit_function(fn: Callable) -> Callable:
    """``fn`` as a numba dispatcher (compiling a plain function on first call)."""
    if not callable(fn):
        raise TypeError(f"a shader must be a function, got {type(fn).__name__}")
    if isinstance(fn, numba.core.registry.CPUDispatcher):
        return fn
    if numba.config.DISABLE_JIT:
        return fn
    return numba.njit(fn, inline="always")


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


_HEADER = ("# Generated by softpipe.kernels: the loop that runs one shader over a batch.\n"
           "import numba\n"
           "from collections import namedtuple\n"
           "from softpipe.shader import Derivatives, FragInfo\n"
           "from softpipe.kernels import jit_function, short_repr\n")
#: What the fragment loops call besides the shader: the triangle setup's per-sample functions,
#: the very ones the rasterizer calls (a vertex loop does not need them, so they are not in _HEADER).
_FRAGMENT_IMPORTS = "from softpipe.setup import pixel_coverage, sample_depth, shading_point\n"


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
        "def visible_loop(row_lo, row_hi, vis, touched, tile_w, tile_h, edges, bias, plane, offsets, positions,",
        f"                 shading, {_TRIANGLE_ARGS}, uniforms, out_color):",
        '    """Shade the samples the visibility pass kept (visibility.py), image rows row_lo:row_hi.',
        "",
        "    Barycentrics, depth and position come from the triangle setup's functions (setup.py), as",
        "    the rasterizer's do. Tiles no triangle touched are skipped; each sample is shaded on its",
        "    own, so the order (tile, sample, column) does not change a byte.",
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
        "                    if shading == 0:           # at the sample",
        "                        mask, depth_sample, count = 0, s, 1",
        "                    else:                      # multisampling: once per pixel and triangle",
        "                        earlier = -1",
        "                        for m in range(s):",
        "                            if vis[m, row, i] == t:",
        "                                earlier = m",
        "                                break",
        "                        if earlier >= 0:",
        "                            for c in range(4):",
        "                                out_color[s, row, i, c] = out_color[earlier, row, i, c]",
        "                            continue",
        "                        mask, depth_sample, count = pixel_coverage(edges, bias, t, i, j, offsets)",
        "                    b0, b1, b2, fx, fy = shading_point(edges, plane, t, i, j, s, mask, count, offsets,",
        "                                                       positions, shading)",
        "                    z = sample_depth(edges, plane, t, i, j, depth_sample, offsets)",
        f"                    {inputs} = interpolate(t, b0, b1, b2, fx, fy, z, {_TRIANGLE_ARGS})",
        f"                    c = {call}",
        "                    out_color[s, row, i, 0] = c[0]",
        "                    out_color[s, row, i, 1] = c[1]",
        "                    out_color[s, row, i, 2] = c[2]",
        "                    out_color[s, row, i, 3] = c[3]",
    ]
    return "\n".join(lines) + "\n"


def _fragment_preamble(layout: VaryingLayout) -> str:
    return _FRAGMENT_IMPORTS + _namedtuple_line("Varyings", "Varyings", list(layout.names) or ["none"])


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
    """The compiled loop that shades the samples a visibility pass kept (:mod:`softpipe.visibility`)."""
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
