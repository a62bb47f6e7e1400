"""Flat (faceted) shading (FORMULAS §12): one normal per face, one color per face.

Flat shading is Gouraud shading with one word changed: the color is computed
per vertex by the same vertex shader (:mod:`softpipe.programs.gouraud`), and
declared ``flat`` instead of ``smooth`` (the fragment shader passes it on, as Gouraud's does), so every fragment of a triangle gets the
color of its provoking vertex (the last one, as in OpenGL) — OpenGL's
``glShadeModel(GL_FLAT)``.

One normal per face: the provoking vertex's normal is the face's own when the
mesh has a vertex per corner carrying the face normal, which is what
``mesh.flat_shaded()`` makes. Draw ``mesh.flat_shaded()`` with this program for
the faceted look of the notes; drawn on a mesh with shared smooth normals it is
still one color per face, lit with one corner's normal.

Programs: ``flat`` (Blinn-Phong specular, §6) and ``flat_phong_specular``
(Phong specular, §5). Uniforms as :mod:`softpipe.programs.gouraud`.
"""
from softpipe.programs.gouraud import gouraud_phong_specular_vertex, gouraud_vertex
from softpipe.programs.registry import Program, register

FLAT = (("color", "flat"),)


def flat_fragment(varyings, uniforms, frag):
    """The provoking vertex's color, the same on every fragment of the triangle."""
    c = varyings.color
    return (c[0], c[1], c[2], c[3])


flat = register(Program(
    "flat", gouraud_vertex, flat_fragment,
    "flat: one color per face, lit (§10, Blinn-Phong) at the provoking vertex; draw mesh.flat_shaded()",
    interpolation=FLAT, faceted=True))
flat_phong_specular = register(Program(
    "flat_phong_specular", gouraud_phong_specular_vertex, flat_fragment,
    "flat with Phong's (R·V)ⁿ specular; draw mesh.flat_shaded()",
    interpolation=FLAT, faceted=True))
