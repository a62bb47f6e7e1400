"""Instancing: a field of bunnies in one draw.

    python examples/instancing.py          → out/examples/instancing.png (10,000 bunnies at 320×240)

One low-poly Stanford bunny (the bundled model reduced by vertex clustering to about a
hundred triangles) drawn ``rows × rows`` times by one ``sp.draw(..., instances=N,
instance_attributes={...})`` (GL's glDrawElementsInstanced): each instance has its own
place on the grid, turn, size and color (the instance attributes), and the vertex
shader reads them, and ``attributes.instance_id`` (gl_InstanceID), beside the bunny's
per-vertex position and normal. Three pictures of the same draw: colored by the
instance attributes (lit per vertex), by ``instance_id``, and by ``frag.primitive_id``
(gl_PrimitiveID), which restarts at 0 in every instance, so every bunny shows the same
gradient. The default is 100 × 100 = 10,000 bunnies; ``sheet(size)`` scales the
field with the picture (the tests draw a small one).
"""
import math
from collections import namedtuple

import numpy as np
from common import load_asset, picture_size, save_sheet

import softpipe as sp
from softpipe.language.glsl import mat4_mul_vec4

Lit = namedtuple("Lit", ["color"])
LIGHT = (0.36, 0.8, 0.48)           # towards the light, unit length
#: the bunny's vertices are merged per cell of a CELLS³ grid over its bounding box
CELLS = 6


def low_poly(mesh, cells=CELLS):
    """The mesh reduced by vertex clustering (Rossignac and Borrel 1993): every vertex moves to the mean
    of the vertices in its cell of a cells³ grid; triangles left with two corners in one cell go."""
    p = mesh.positions
    lo, hi = p.min(axis=0), p.max(axis=0)
    cell = np.minimum(((p - lo) / (hi - lo) * cells).astype(np.int64), cells - 1)
    _, key = np.unique(cell[:, 0] * cells * cells + cell[:, 1] * cells + cell[:, 2], return_inverse=True)
    key = key.ravel()
    count = np.bincount(key).astype(np.float64)
    merged = np.stack([np.bincount(key, p[:, c]) / count for c in range(3)], axis=1)
    tri = key[np.asarray(mesh.indices).reshape(-1, 3)]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])]
    tri = np.unique(tri, axis=0)
    small = sp.Mesh(merged, tri).compacted()
    return small.replace(normals=small.vertex_normals())


def bunny_vertex(attributes, uniforms):
    """Turn, scale and place the bunny by its instance's attributes; light it per vertex."""
    p, n = attributes.position, attributes.normal
    c, s = math.cos(attributes.turn), math.sin(attributes.turn)
    k = attributes.size
    world = (k * (c * p[0] + s * p[2]) + attributes.place[0], k * p[1], k * (c * p[2] - s * p[0]) + attributes.place[1])
    clip = mat4_mul_vec4(uniforms.view_projection, (world[0], world[1], world[2], 1.0))
    lit = 0.25 + 0.75 * max(0.0, (c * n[0] + s * n[2]) * LIGHT[0] + n[1] * LIGHT[1] + (c * n[2] - s * n[0]) * LIGHT[2])
    mode = uniforms.mode
    if mode == 1.0:                 # gl_InstanceID as a hue along the rows
        t = attributes.instance_id / uniforms.instances
        tint = (0.5 + 0.5 * math.cos(6.283 * t), 0.5 + 0.5 * math.cos(6.283 * (t - 0.33)),
                0.5 + 0.5 * math.cos(6.283 * (t - 0.67)))
    else:
        tint = attributes.color
    return clip, Lit((tint[0] * lit, tint[1] * lit, tint[2] * lit))


def primitive_id_fragment(varyings, uniforms, frag):
    """gl_PrimitiveID: the triangle's number within its bunny, dark to bright."""
    t = frag.primitive_id / uniforms.triangles
    return (t, 0.4 + 0.6 * t, 1.0 - t, 1.0)


def field(rows, seed=31):
    """The instance attributes of a rows × rows field: place (x, z), turn, size, color."""
    rng = np.random.default_rng(seed)
    i, k = np.divmod(np.arange(rows * rows), rows)
    place = np.stack([i - (rows - 1) / 2, k - (rows - 1) / 2], axis=1) + rng.uniform(-0.25, 0.25, (rows * rows, 2))
    return {"place": place, "turn": rng.uniform(0, 2 * math.pi, rows * rows),
            "size": rng.uniform(0.7, 1.0, rows * rows), "color": rng.uniform(0.35, 1.0, (rows * rows, 3))}


def rows_for(size):
    """The field's side: 100 (10,000 bunnies) at 320 pixels wide, fewer for a smaller picture."""
    return max(4, min(100, picture_size(size)[0] * 100 // 320))


def draw_field(size, rows, mode=0, fragment_shader=None, bunny=None):
    """One instanced draw of the field into a new framebuffer."""
    width, height = picture_size(size)
    bunny = bunny or low_poly(load_asset("bunny", size=1.0))
    attributes = field(rows)
    half = rows / 2
    # low over the front row, looking along the field: the near bunnies large, the far ones to the horizon
    view = sp.look_at(eye=(0.0, 1.2 + 0.04 * rows, half + 1.5), target=(0.0, 0.0, half - 0.4 * rows))
    projection = sp.perspective(50.0, width / height, 0.1, 2.5 * rows)
    fb = sp.Framebuffer(width, height)
    fb.clear((0.55, 0.7, 0.85))
    sp.draw(fb, bunny.positions, bunny.indices, vertex_shader=bunny_vertex, fragment_shader=fragment_shader,
            attributes={"normal": bunny.normals}, instances=rows * rows, instance_attributes=attributes,
            uniforms={"view_projection": projection @ view, "mode": float(mode), "instances": float(rows * rows),
                      "triangles": float(bunny.triangle_count)}, cull="back")
    return fb


def sheet(size=320):
    rows = rows_for(size)
    bunny = low_poly(load_asset("bunny", size=1.0))
    n = f"{rows * rows:,}"
    return {f"{n} bunnies, one draw": draw_field(size, rows, bunny=bunny).to_uint8(alpha=False),
            "colored by instance_id": draw_field(size, rows, mode=1, bunny=bunny).to_uint8(alpha=False),
            f"primitive_id (0..{bunny.triangle_count - 1} in each)":
                draw_field(size, rows, fragment_shader=primitive_id_fragment, bunny=bunny).to_uint8(alpha=False)}


def main(size=(320, 240), out_dir=None):
    bunny = low_poly(load_asset("bunny", size=1.0))
    print(f"one bunny: {bunny.triangle_count} triangles, {bunny.vertex_count} vertices; "
          f"{rows_for(size) ** 2:,} instances")
    return save_sheet("instancing", sheet(size), 3, "Instancing: a field of bunnies in one draw "
                      "(instance attributes, gl_InstanceID, gl_PrimitiveID)", out_dir)


if __name__ == "__main__":
    main()
