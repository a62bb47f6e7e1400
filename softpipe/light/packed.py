"""The packed lights: the layout of the array a shader reads its lights from (FORMULAS §7–§10).

``softpipe.light.material.pack_lights`` writes it, one row per light, in eye space; the
lighting formulas (:mod:`softpipe.light.lighting`) and the shadow lookups
(:mod:`softpipe.light.shadowmap`, whose shadow rays go toward a light's position) read it.
The layout lives here, below all three, so that each reads the same columns without
importing another (``material`` imports the shadow settings, so the shadow lookups
cannot import ``material``).

The packed array, one row per light (column indices are the ``LIGHT_*`` names):

======  =====================  ==========================================================
column  name                   meaning (eye space)
======  =====================  ==========================================================
0       LIGHT_KIND             0 directional, 1 point, 2 spot (LIGHT_DIRECTIONAL, …)
1–3     LIGHT_AMBIENT          ambient color I_a,j (RGB)
4–6     LIGHT_DIFFUSE          diffuse color I_d,j (RGB)
7–9     LIGHT_SPECULAR         specular color I_s,j (RGB)
10–13   LIGHT_POSITION         homogeneous position (x, y, z, w): w = 1 point/spot, the
                               light's position; w = 0 directional, xyz = unit vector
                               toward the light (as OpenGL stores it)
14–16   LIGHT_ATTENUATION      a, b, c of f_att = 1/(a + b·r + c·r²) (§7); (1, 0, 0) for
                               directional lights, which are never attenuated
17–19   LIGHT_SPOT_DIRECTION   S, unit, the direction the spot points (§8); (0, 0, −1)
                               when not a spot
20      LIGHT_SPOT_COS_CUTOFF  cos β; −1 means "not a spotlight" (β = 180°, point and
                               directional lights): f_spot = 1
21      LIGHT_SPOT_EXPONENT    e (§8); 0 when not a spot
======  =====================  ==========================================================

``LIGHT_COLUMNS`` = 22 is the row length.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np
from numba import njit

__all__ = [
    "LIGHT_COLUMNS", "LIGHT_KIND", "LIGHT_AMBIENT", "LIGHT_DIFFUSE", "LIGHT_SPECULAR",
    "LIGHT_POSITION", "LIGHT_ATTENUATION", "LIGHT_SPOT_DIRECTION", "LIGHT_SPOT_COS_CUTOFF",
    "LIGHT_SPOT_EXPONENT", "LIGHT_DIRECTIONAL", "LIGHT_POINT", "LIGHT_SPOT", "light_vec3",
]

# The values of LIGHT_KIND
LIGHT_DIRECTIONAL = 0
LIGHT_POINT = 1
LIGHT_SPOT = 2

# The columns
LIGHT_KIND = 0
LIGHT_AMBIENT = 1
LIGHT_DIFFUSE = 4
LIGHT_SPECULAR = 7
LIGHT_POSITION = 10
LIGHT_ATTENUATION = 14
LIGHT_SPOT_DIRECTION = 17
LIGHT_SPOT_COS_CUTOFF = 20
LIGHT_SPOT_EXPONENT = 21
LIGHT_COLUMNS = 22


@njit(cache=True, forceinline=True)
def light_vec3(lights: np.ndarray, j: int, column: int) -> Tuple[float, float, float]:
    """The three values at ``lights[j, column:column + 3]``: a color, a position or a direction."""
    return (lights[j, column], lights[j, column + 1], lights[j, column + 2])
