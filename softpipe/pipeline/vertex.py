"""Stage 1: the vertex stage — one vertex in, a clip position and varyings out.

With no vertex shader, the positions given to a draw already are clip
coordinates ``[N, 4]`` and the varyings are passed on unchanged. With a vertex
shader (:mod:`softpipe.language.contract` is the contract, :mod:`softpipe.language.kernels` how it
runs) softpipe runs it over every vertex. The usual model-view-projection
shader, ``standard_vertex``, is with the built-in programs
(:mod:`softpipe.programs.common`, offered by :mod:`softpipe.shading`).

Instancing (GL's ``glDraw*Instanced`` with ``glVertexAttribDivisor(…, 1)``): a draw
of ``instances`` = N copies of its V vertices runs the shader once per vertex
per instance, over the N·V vertices instance by instance (vertex i·V + v is
vertex v of instance i); each instance attribute's row i is beside the
per-vertex attributes of instance i's vertices, and ``attributes.instance_id``
(GLSL's ``gl_InstanceID``, an int) is i. :class:`VertexOut` says how many
instances it holds, so that assembly repeats the topology once per instance.

Output: :class:`VertexOut`.
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import Any, Callable, Dict, Mapping, Optional, Tuple

import numpy as np

from softpipe.core.parallel import in_bands
from softpipe.core.runtime import check_memory
from softpipe.language import kernels
from softpipe.language.contract import VaryingLayout, check_name, declared_uniforms

__all__ = ["VertexOut", "run_vertex_stage", "check_instances",
           "MAX_VERTICES", "INSTANCE_ID"]

MAX_VERTICES = 1 << 26
#: The vertex shader's input that holds GLSL's ``gl_InstanceID`` in an instanced draw.
INSTANCE_ID = "instance_id"


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
    instances : int
        How many instances the rows hold (1 for a draw without instancing; 0 draws nothing).
    instance_vertices : int or None
        The vertices of one instance, V (None: all the rows, one instance); row i·V + v is
        vertex v of instance i.
    """

    position: np.ndarray
    varyings: np.ndarray
    layout: VaryingLayout
    instances: int = 1
    instance_vertices: Optional[int] = None

    @property
    def vertices_per_instance(self) -> int:
        """V: the vertices of one instance (all the rows without instancing)."""
        return len(self.position) if self.instance_vertices is None else self.instance_vertices

    def varying(self, name: str) -> np.ndarray:
        """One varying as an [N] or [N, k] array."""
        return self.layout.unpack(self.varyings)[name]

    def __repr__(self) -> str:
        names = ", ".join(f"{n}[{s}] {q}" for n, _, s, q in self.layout.fields)
        count = (f"{len(self.position)} vertices" if self.instance_vertices is None else
                 f"{len(self.position)} vertices = {self.instances} instances × {self.instance_vertices}")
        return f"VertexOut({count}; varyings: {names or 'none'})"


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


def check_instances(instances, instance_attributes: Optional[Mapping[str, Any]],
                    attributes: Optional[Mapping[str, Any]] = None) -> Tuple[int, Dict[str, np.ndarray]]:
    """A draw's ``instances`` and ``instance_attributes``, checked: (N, name → float64 [N, k]).

    ``instances`` is an int ≥ 0 (0 draws nothing, as GL's ``instancecount`` 0);
    each instance attribute is an [N] or [N, k] array (k 1 to 4) of finite numbers,
    one row per instance, named apart from the per-vertex ``attributes``, ``position``
    and ``instance_id``. A ValueError or TypeError names what is wrong.
    """
    if isinstance(instances, (bool, np.bool_)) or not isinstance(instances, (int, np.integer)):
        raise TypeError(f"instances must be an int ≥ 0 (how many instances to draw), got {instances!r}")
    n = int(instances)
    if n < 0:
        raise ValueError(f"instances must be an int ≥ 0 (how many instances to draw), got {n}")
    if instance_attributes is None:
        return n, {}
    if not isinstance(instance_attributes, Mapping):
        raise TypeError("instance_attributes must be a dict of name → [instances, k] array, got "
                        f"{type(instance_attributes).__name__}")
    out = {}
    for name, value in instance_attributes.items():
        check_name("instance attribute", name)
        if name in ("position", INSTANCE_ID):
            raise ValueError(f"instance_attributes must not contain {name!r}: the vertex shader's "
                             f"attributes.{name} is {'the positions argument' if name == 'position' else 'gl_InstanceID'}")
        if attributes and name in attributes:
            raise ValueError(f"instance_attributes[{name!r}] has the name of a per-vertex attribute "
                             f"(attributes[{name!r}]): the shader would see both as attributes.{name}; rename one")
        what = f"instance_attributes[{name!r}]"
        arr = as_float_array(what, value, allow_1d=True) if np.ndim(value) in (1, 2) else None
        if arr is None or arr.shape[1] not in (1, 2, 3, 4) or arr.shape[0] != n:
            raise ValueError(f"{what} has shape {list(np.shape(value))}: it must be [{n}, k] (one row per instance, "
                             f"instances={n}) with k 1 to 4, or [{n}]")
        if not np.isfinite(arr).all():
            row = int(np.nonzero(~np.isfinite(arr).all(axis=1))[0][0])
            raise ValueError(f"{what} is not finite at row {row} (instance {row}): {arr[row].tolist()}")
        out[name] = arr
    return n, out


def run_vertex_stage(positions, varyings: Optional[Mapping[str, Any]] = None,
                     vertex_shader: Optional[Callable] = None, uniforms=None,
                     attributes: Optional[Mapping[str, Any]] = None, instances: Optional[int] = None,
                     instance_attributes: Optional[Mapping[str, Any]] = None) -> VertexOut:
    """Run the vertex stage.

    Parameters
    ----------
    positions : array [N, 4] (clip coordinates, no shader) or [N, 3|4] (shader input)
    varyings : dict name → [N, k], only without a vertex shader
    vertex_shader : function(attributes, uniforms) → (clip, varyings), optional
    uniforms : the namedtuple from :func:`softpipe.language.contract.make_uniforms`
    attributes : dict name → [N, k], extra per-vertex inputs of the vertex shader
    instances : int, optional
        Draw this many instances (a vertex shader is needed; see the module docstring).
    instance_attributes : dict name → [instances, k], optional
        Per-instance inputs of the vertex shader (:func:`check_instances`).
    """
    if vertex_shader is None:
        if instances is not None or instance_attributes:
            raise ValueError("instances= needs a vertex_shader: without one every instance would draw the same "
                             "clip positions (give a vertex_shader that reads attributes.instance_id or the "
                             "instance_attributes)")
        pos = as_float_array("positions", positions, ncols=(4,))
        if attributes:
            raise ValueError("attributes= are inputs of a vertex shader, but no vertex_shader was given "
                             "(pass per-vertex data to the fragment stage as varyings=)")
        packed, layout = _pack(_varying_arrays(varyings, len(pos)), len(pos))
        return VertexOut(pos, packed, layout)

    if varyings:
        raise ValueError("varyings= cannot be combined with a vertex_shader: the shader computes the varyings; "
                         "pass per-vertex inputs as attributes=")
    if instance_attributes and instances is None:
        raise ValueError("instance_attributes= needs instances=N, the number of instances (their rows)")
    pos = as_float_array("positions", positions, ncols=(2, 3, 4))
    inputs = {"position": pos}
    for name, value in (attributes or {}).items():
        if name == "position":
            raise ValueError("attributes must not contain 'position': it is the positions argument")
        check_name("attribute", name)
        if instances is not None and name == INSTANCE_ID:
            raise ValueError(f"attributes must not contain {INSTANCE_ID!r} in an instanced draw: "
                             f"attributes.{INSTANCE_ID} is gl_InstanceID")
        arr = as_float_array(f"attributes[{name!r}]", value, ncols=(1, 2, 3, 4), allow_1d=True)
        if arr.shape[0] != len(pos):
            raise ValueError(f"attributes[{name!r}] has {arr.shape[0]} rows but positions has {len(pos)}")
        inputs[name] = arr
    if instances is None:
        return _run_shader(vertex_shader, inputs, uniforms)
    n, per_instance = check_instances(instances, instance_attributes, attributes)
    return _run_instanced(vertex_shader, inputs, per_instance, n, uniforms)


def _run_instanced(vertex_shader: Callable, inputs: Dict[str, np.ndarray], per_instance: Dict[str, np.ndarray],
                   instances: int, uniforms) -> VertexOut:
    """The shader over every vertex of every instance: the per-vertex inputs repeated per instance, each
    instance's row of the instance attributes beside its vertices, and its number as ``instance_id``."""
    v = len(inputs["position"])
    total = instances * v
    if total > MAX_VERTICES:
        raise ValueError(f"instances={instances:,} × {v:,} vertices = {total:,} vertices to shade; the limit is "
                         f"MAX_VERTICES = {MAX_VERTICES:,} per draw: draw the instances in several draws")
    width = sum(a.shape[1] for a in inputs.values()) + sum(a.shape[1] for a in per_instance.values()) + 1
    # the inputs, the clip positions and (an estimate, before the shader says) as many varyings as inputs
    check_memory(f"shading {total:,} vertices (instances={instances:,} × {v:,} vertices; "
                 f"{8 * (2 * width + 4)} bytes each)", total * 8 * (2 * width + 4))
    expanded = {name: np.tile(a, (instances, 1)) for name, a in inputs.items()}
    for name, a in per_instance.items():
        expanded[name] = np.repeat(a, v, axis=0)
    expanded[INSTANCE_ID] = np.repeat(np.arange(instances, dtype=np.int64), v)[:, None]
    out = _run_shader(vertex_shader, expanded, uniforms)
    out.instances, out.instance_vertices = instances, v
    return out


def _run_shader(vertex_shader: Callable, inputs: Dict[str, np.ndarray], uniforms) -> VertexOut:
    uniforms = declared_uniforms(vertex_shader, uniforms)     # (its loop serves every such program)
    n = len(inputs["position"])
    sizes = [(k, a.shape[1]) for k, a in inputs.items()]
    Attributes = namedtuple("Attributes", list(inputs))  # type: ignore[misc]  # the fields are the inputs' names
    if n == 0:
        return VertexOut(np.zeros((0, 4)), np.zeros((0, 0)), VaryingLayout())
    first = Attributes(*(tuple(float(c) for c in a[0]) if a.shape[1] > 1 else a[0, 0].item()
                         for a in inputs.values()))    # (.item(): a float, or gl_InstanceID's int)
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

