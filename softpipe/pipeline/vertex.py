"""Stage 1: the vertex stage — one vertex in, a clip position and varyings out.

With no vertex shader, the positions given to a draw already are clip
coordinates ``[N, 4]`` and the varyings are passed on unchanged. With a vertex
shader (:mod:`softpipe.language.contract` is the contract, :mod:`softpipe.language.kernels` how it
runs) softpipe runs it over every vertex. The usual model-view-projection
shader, ``standard_vertex``, is with the built-in programs
(:mod:`softpipe.programs.common`, offered by :mod:`softpipe.shading`).

Output: :class:`VertexOut`.
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import Any, Callable, Dict, Mapping, Optional

import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.language import kernels
from softpipe.language.contract import VaryingLayout, check_name, declared_uniforms

__all__ = ["VertexOut", "run_vertex_stage",
           "MAX_VERTICES"]

MAX_VERTICES = 1 << 26


@dataclass
class VertexOut:
    """What the vertex stage hands to primitive assembly.

    Attributes
    ----------
    position : float64 [N, 4]
        Clip coordinates (x, y, z, w).
    varyings : float64 [N, K]
        Every varying packed side by side, as ``layout`` says.
    layout : VaryingLayout
        Names, offsets, sizes and interpolation qualifiers of the varyings.
    """

    position: np.ndarray
    varyings: np.ndarray
    layout: VaryingLayout

    def varying(self, name: str) -> np.ndarray:
        """One varying as an [N] or [N, k] array."""
        return self.layout.unpack(self.varyings)[name]

    def __repr__(self) -> str:
        names = ", ".join(f"{n}[{s}] {q}" for n, _, s, q in self.layout.fields)
        return f"VertexOut({len(self.position)} vertices; varyings: {names or 'none'})"


def as_float_array(name: str, value, ncols: Optional[tuple] = None, allow_1d: bool = False) -> np.ndarray:
    """``value`` as a float64 [N, k] array, or a TypeError/ValueError naming ``name``."""
    try:
        arr = np.asarray(value)
    except Exception as e:  # ragged lists and the like
        raise TypeError(f"{name} must be a numeric array, got {type(value).__name__}: {e}") from None
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise TypeError(f"{name} must be a numeric (float or int) array, got dtype {arr.dtype}")
    if arr.ndim == 1 and allow_1d:
        arr = arr[:, None]
    if arr.ndim != 2 or (ncols is not None and arr.shape[1] not in ncols):
        want = " or ".join(f"[N, {c}]" for c in ncols) if ncols else "[N, k]"
        if allow_1d:
            want += " or [N]"
        raise ValueError(f"{name} must have shape {want}, got {list(arr.shape)}")
    if arr.shape[0] > MAX_VERTICES:
        raise ValueError(f"{name} has {arr.shape[0]} rows; the limit is MAX_VERTICES = {MAX_VERTICES} vertices per draw")
    return np.ascontiguousarray(arr, dtype=np.float64)


def _varying_arrays(varyings: Optional[Mapping[str, Any]], n: int) -> Dict[str, np.ndarray]:
    if varyings is None:
        return {}
    if not isinstance(varyings, Mapping):
        raise TypeError(f"varyings must be a dict of name → [N, k] array, got {type(varyings).__name__}")
    out = {}
    for name, value in varyings.items():
        check_name("varying", name)
        if name == "clip_distance" and np.ndim(value) == 2 and np.shape(value)[1] > 4:
            raise ValueError(f"varyings['clip_distance'] has {np.shape(value)[1]} components: a varying holds at most "
                             "4, so gl_ClipDistance[4..7] go in a second varying, 'clip_distance2' (8 in all at most, "
                             "GL's MAX_CLIP_DISTANCES)")
        arr = as_float_array(f"varyings[{name!r}]", value, ncols=(1, 2, 3, 4), allow_1d=True)
        if arr.shape[0] != n:
            raise ValueError(f"varyings[{name!r}] has {arr.shape[0]} rows but positions has {n}")
        out[name] = arr
    return out


def _pack(arrays: Dict[str, np.ndarray], n: int):
    layout = VaryingLayout.from_sizes([(k, a.shape[1]) for k, a in arrays.items()])
    packed = np.empty((n, layout.width), dtype=np.float64)
    for (_name, off, size, _), a in zip(layout.fields, arrays.values()):
        packed[:, off:off + size] = a
    return packed, layout


def run_vertex_stage(positions, varyings: Optional[Mapping[str, Any]] = None,
                     vertex_shader: Optional[Callable] = None, uniforms=None,
                     attributes: Optional[Mapping[str, Any]] = None) -> VertexOut:
    """Run the vertex stage.

    Parameters
    ----------
    positions : array [N, 4] (clip coordinates, no shader) or [N, 3|4] (shader input)
    varyings : dict name → [N, k], only without a vertex shader
    vertex_shader : function(attributes, uniforms) → (clip, varyings), optional
    uniforms : the namedtuple from :func:`softpipe.language.contract.make_uniforms`
    attributes : dict name → [N, k], extra per-vertex inputs of the vertex shader
    """
    if vertex_shader is None:
        pos = as_float_array("positions", positions, ncols=(4,))
        if attributes:
            raise ValueError("attributes= are inputs of a vertex shader, but no vertex_shader was given "
                             "(pass per-vertex data to the fragment stage as varyings=)")
        packed, layout = _pack(_varying_arrays(varyings, len(pos)), len(pos))
        return VertexOut(pos, packed, layout)

    if varyings:
        raise ValueError("varyings= cannot be combined with a vertex_shader: the shader computes the varyings; "
                         "pass per-vertex inputs as attributes=")
    pos = as_float_array("positions", positions, ncols=(2, 3, 4))
    inputs = {"position": pos}
    for name, value in (attributes or {}).items():
        if name == "position":
            raise ValueError("attributes must not contain 'position': it is the positions argument")
        check_name("attribute", name)
        arr = as_float_array(f"attributes[{name!r}]", value, ncols=(1, 2, 3, 4), allow_1d=True)
        if arr.shape[0] != len(pos):
            raise ValueError(f"attributes[{name!r}] has {arr.shape[0]} rows but positions has {len(pos)}")
        inputs[name] = arr
    return _run_shader(vertex_shader, inputs, uniforms)


def _run_shader(vertex_shader: Callable, inputs: Dict[str, np.ndarray], uniforms) -> VertexOut:
    uniforms = declared_uniforms(vertex_shader, uniforms)     # (its loop serves every such program)
    n = len(inputs["position"])
    sizes = [(k, a.shape[1]) for k, a in inputs.items()]
    Attributes = namedtuple("Attributes", list(inputs))  # type: ignore[misc]  # the fields are the inputs' names
    if n == 0:
        return VertexOut(np.zeros((0, 4)), np.zeros((0, 0)), VaryingLayout())
    first = Attributes(*(tuple(float(c) for c in a[0]) if a.shape[1] > 1 else float(a[0, 0])
                         for a in inputs.values()))
    _, layout = kernels.probe_vertex_shader(vertex_shader, first, uniforms)
    kernel = kernels.vertex_kernel(vertex_shader, sizes, layout)
    position = np.empty((n, 4), dtype=np.float64)
    packed = np.empty((n, layout.width), dtype=np.float64)
    args = (*inputs.values(), uniforms, position, packed)
    # compile (or load) once, in this thread, where errors are reported clearly; then run in bands
    kernels.run_compiled("vertex", vertex_shader, kernel, 0, 0, *args)
    kernels.run_compiled("vertex", vertex_shader, lambda *a: in_bands(kernel, n, *a, grain=4096), *args,
                         site=kernels.vertex_site(vertex_shader, kernel, n, args))
    return VertexOut(position, packed, layout)

