"""Template of the vertex loop: the generator (kernels/generate.py) copies ``vertex_loop``.

``vertex_loop`` runs the vertex shader on vertices lo:hi: vertex i's attributes
in, its clip position and varyings out, each varying component to its column
of ``out_varyings`` (the layout the probe found). How a template becomes code
(full-line comments left out, placeholders in capitals filled): kernels/template.py.

Placeholders, filled per attribute set and varying layout:

- ``ATTRIBUTE_ARRAYS``: the attribute arrays, a parameter each (``a_position, a_normal``).
- ``ATTRIBUTE_VALUES``: vertex i's attributes, a float or a tuple each
  (``(a_position[i, 0], a_position[i, 1], a_position[i, 2]), a_normal[i, 0]``).
- ``STORE_VARYINGS``: a line per varying component (``out_varyings[i, 3] = v[1][0]  # normal.x``).
"""


# Stand-ins for what the generated module's header defines or imports (kernels/generate.py), so that
# a linter, or an import, can read this file; the generator copies only the functions.
def JIT(function):
    return function


shader = borrowed_tuple = Attributes = None
ATTRIBUTE_VALUES = STORE_VARYINGS = None


@JIT
def vertex_loop(lo, hi, ATTRIBUTE_ARRAYS, uniforms, out_position, out_varyings):
    # borrowed once, before the first vertex: numba counts no references to the arrays in them
    uniforms = borrowed_tuple(uniforms)
    for i in range(lo, hi):
        attributes = Attributes(ATTRIBUTE_VALUES)
        clip, v = shader(attributes, uniforms)
        out_position[i, 0] = clip[0]
        out_position[i, 1] = clip[1]
        out_position[i, 2] = clip[2]
        out_position[i, 3] = clip[3]
        STORE_VARYINGS(i, v, out_varyings)
