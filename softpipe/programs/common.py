"""What the built-in programs share: the standard vertex shader, the surface vectors N and V, lights.

Every lit program shades in **eye space** (``softpipe.light.material``: the eye at the
origin looking down −z). P, N, V and the other names are those of docs/formulas.md,
defined once in :mod:`softpipe.shading` (the module a shader author imports from,
which re-exports the functions here).

The vertex side is one slide::

    P    = model_view · (x, y, z, 1)        eye space
    N    = normal_matrix · n                eye space, not normalized
    clip = projection · P

:func:`eye_space` computes it; :func:`standard_vertex`, the vertex shader of
most built-in programs, passes P and N on as the varyings ``position`` and
``normal``.

Uniforms every lit program reads
--------------------------------
``model_view``, ``projection``, ``normal_matrix``
    As :func:`softpipe.standard_uniforms` builds them.
``material``
    A :class:`~softpipe.light.material.Material` (the shader sees its
    :class:`~softpipe.light.material.MaterialUniform`); :func:`softpipe.draw_mesh`
    passes the mesh's.
``lighting``
    ``Lighting(lights, global_ambient).uniform(view)``: the global ambient light and
    the lights packed in eye space (a :class:`~softpipe.light.material.LightingUniform`).
    :func:`lighting_uniform` builds it from a Lighting, a list of Lights or None
    (:data:`DEFAULT_LIGHTING`).

A program may read further uniforms with a default, :func:`uniform_or`
(``uniform_or(uniforms, "gooch_alpha", 0.2)``), so that a draw needs to name
only the ones it changes.
"""
from __future__ import annotations

from collections import namedtuple
from typing import Iterable, Union

import numpy as np
from numba import types
from numba.core.errors import TypingError
from numba.extending import overload, register_jitable

from softpipe.language.contract import reads_uniforms
from softpipe.language.glsl import length, mat3_mul_vec3, mat4_mul_vec4, scale
from softpipe.light.material import Light, Lighting, LightingUniform

__all__ = ["eye_space", "standard_vertex", "StandardVaryings", "toward_eye", "facing_normal",
           "uniform_or", "rgba", "DEFAULT_LIGHTING", "lighting_uniform"]


# --------------------------------------------------------------------------
# Vertex side: object space → eye space → clip space
# --------------------------------------------------------------------------

@register_jitable
def eye_space(attributes, uniforms):
    """(clip, P, N) of one vertex: clip position, eye-space point and (unnormalized) normal.

    P = model_view · (x, y, z, 1), clip = projection · P, N = normal_matrix · n.
    Reads the attributes ``position`` and ``normal`` and the uniforms
    ``model_view``, ``projection`` and ``normal_matrix``.
    """
    p = attributes.position
    P = mat4_mul_vec4(uniforms.model_view, (p[0], p[1], p[2], 1.0))
    clip = mat4_mul_vec4(uniforms.projection, P)
    N = mat3_mul_vec3(uniforms.normal_matrix, attributes.normal)
    return clip, (P[0], P[1], P[2]), N


StandardVaryings = namedtuple("StandardVaryings", ["position", "normal"])


@reads_uniforms("model_view", "projection", "normal_matrix")
def standard_vertex(attributes, uniforms):
    """The usual vertex shader: model-view-projection, eye-space P and N as varyings.

    Uniforms: ``model_view`` (4×4), ``projection`` (4×4) and ``normal_matrix``
    (3×3, the inverse transpose of model_view's upper-left;
    :func:`softpipe.pipeline.transforms.normal_matrix`), as
    :func:`softpipe.standard_uniforms` builds them. Attributes:
    ``position`` (x, y, z) and ``normal`` (x, y, z). Varyings: ``position`` = P
    and ``normal`` = N, both eye space.
    """
    clip, P, N = eye_space(attributes, uniforms)
    return clip, StandardVaryings(P, N)


# --------------------------------------------------------------------------
# The surface vectors
# --------------------------------------------------------------------------

@register_jitable
def _unit(v):
    """v/|v| as v · (1/|v|), the zero vector for a zero (or NaN) v: N and V of every lit sample.

    One division where :func:`~softpipe.language.glsl.normalize` (v/|v| per component) has three;
    within two ulp of it (1/|v| and the product are each rounded). With it for N and V
    (and light_at's L) a lit sample costs measurably less (issue 18; the figures are in
    benchmarks/README.md, "The figures behind the pipeline's comments").
    """
    n = length(v)
    if n > 0.0:
        return scale(v, 1.0 / n)
    return (0.0, 0.0, 0.0)


@register_jitable
def toward_eye(P, projection):
    """V, the unit vector from the eye-space point P toward the eye.

    A perspective projection has its centre at the eye-space origin: V = normalize(−P)
    (the notes' V). A parallel (orthographic) projection — last row (0, 0, 0, 1) —
    has every view ray along −z: V = (0, 0, 1) everywhere (OpenGL's non-local viewer).
    """
    if projection[3, 0] == 0.0 and projection[3, 1] == 0.0 and projection[3, 2] == 0.0:
        return (0.0, 0.0, 1.0)
    return _unit((-P[0], -P[1], -P[2]))


@register_jitable
def facing_normal(normal, front_facing):
    """N: the interpolated normal renormalized (FORMULAS §12), and reversed on a back face.

    Reversing it on back faces is OpenGL's two-sided lighting: the side of a
    surface one looks at is lit as the front (seen only when culling is off).
    """
    N = _unit(normal)
    if front_facing:
        return N
    return scale(N, -1.0)


@register_jitable
def rgba(color, alpha):
    """(r, g, b, a) from an RGB color and an alpha."""
    return (color[0], color[1], color[2], alpha)


# --------------------------------------------------------------------------
# Uniforms with a default
# --------------------------------------------------------------------------

def uniform_or(uniforms, name, default):
    """``uniforms.<name>`` if the draw gave that uniform, else ``default``.

    ``name`` must be a string constant in the shader. Compiled, the choice is made
    once, when numba types the shader (the uniforms' names are part of its type),
    so it costs nothing per fragment. The default must have the uniform's type:
    a float for a number, a tuple of floats for a vector.
    """
    return getattr(uniforms, name, default)


@overload(uniform_or, prefer_literal=True)
def _uniform_or_numba(uniforms, name, default):
    if not isinstance(name, types.StringLiteral):
        raise TypingError("uniform_or: the uniform's name must be a string constant")
    fields = tuple(getattr(uniforms, "fields", ()))
    if name.literal_value in fields:
        index = fields.index(name.literal_value)
        return lambda uniforms, name, default: uniforms[index]
    return lambda uniforms, name, default: default


# --------------------------------------------------------------------------
# Lights
# --------------------------------------------------------------------------

#: The lighting used when a draw names none: OpenGL's global ambient (0.2) and one
#: white directional light from the upper left, behind the viewer of a camera on +z.
DEFAULT_LIGHTING = Lighting([Light.directional((1.0, -1.0, -1.0), name="key")])


def lighting_uniform(lighting: Union[Lighting, Light, Iterable[Light], None], view) -> LightingUniform:
    """The ``lighting`` uniform for a camera's view matrix (world → eye).

    ``lighting`` is a :class:`~softpipe.light.material.Lighting`, one Light, a list of
    Lights (with the default global ambient), or None for :data:`DEFAULT_LIGHTING`.
    """
    if lighting is None:
        lighting = DEFAULT_LIGHTING
    elif isinstance(lighting, Light):
        lighting = Lighting([lighting])
    elif not isinstance(lighting, Lighting):
        lighting = Lighting(tuple(lighting))
    return lighting.uniform(np.asarray(view, dtype=np.float64))
