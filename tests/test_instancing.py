"""Instancing (issue 31): ``draw(..., instances=N, instance_attributes={...})`` is GL's
glDraw*Instanced with divisor-1 attributes.

An instanced draw equals its N draws one after another, byte for byte (color and depth, on
both paths); the shader sees ``attributes.instance_id`` (gl_InstanceID) and each instance's row
of the instance attributes; ``frag.primitive_id`` restarts in each instance (the GL 4 reference
pages: gl_PrimitiveID(In) counts the primitives processed by the drawing command from zero, and
glDrawArraysInstanced "has the same effect as" one glDrawArrays per instance); strips do not run
from one instance into the
next; the trace names each fragment's instance; bad input is refused with a message.
"""
from collections import namedtuple

import numpy as np
import pytest

import softpipe as sp
from softpipe.pipeline.draw import DrawCall
from softpipe.pipeline.vertex import MAX_VERTICES

Varyings = namedtuple("Varyings", ["color"])
SIZE = 128


def vertex_shader(attributes, uniforms):
    """Each instance moved by its offset, scaled by its scale; colored by its id."""
    p = attributes.position
    o = attributes.offset
    s = attributes.scale
    k = attributes.instance_id * 1.0
    clip = (p[0] * s + o[0], p[1] * s + o[1], p[2] + o[2], 1.0)
    return clip, Varyings((0.2 + 0.15 * k, 0.5 * p[0] + 0.5, o[2] * 0.5 + 0.5))


def fragment_shader(varyings, uniforms, frag):
    """The color, with the primitive's id in blue (so a wrong gl_PrimitiveID shows)."""
    c = varyings.color
    return (c[0], c[1], 0.1 + 0.2 * frag.primitive_id, 1.0)


#: five instances, overlapping, at several depths (two at the same depth: the order decides)
OFFSETS = np.array([[-0.3, -0.2, 0.1], [0.0, 0.0, -0.2], [0.25, 0.1, 0.1], [0.1, -0.3, 0.5], [-0.2, 0.3, -0.4]])
SCALES = np.array([0.5, 0.4, 0.6, 0.3, 0.45])


def two_ways(positions, path, **state):
    """(color, depth) of the instanced draw and of its instances drawn one by one."""
    n = len(OFFSETS)
    one = sp.Framebuffer(SIZE, SIZE)
    sp.draw(one, positions, vertex_shader=vertex_shader, fragment_shader=fragment_shader, path=path,
            instances=n, instance_attributes={"offset": OFFSETS, "scale": SCALES}, **state)
    many = sp.Framebuffer(SIZE, SIZE)
    v = len(positions)
    for i in range(n):
        sp.draw(many, positions, vertex_shader=vertex_shader, fragment_shader=fragment_shader, path=path,
                attributes={"offset": np.repeat(OFFSETS[i:i + 1], v, 0), "scale": np.full(v, SCALES[i]),
                            "instance_id": np.full(v, float(i))}, **state)
    return (one.samples_color, one.samples_depth), (many.samples_color, many.samples_depth)


RNG = np.random.default_rng(31)
TRIANGLES = RNG.uniform(-1, 1, (12, 3)) * [1, 1, 0.3]
STRIP = np.array([[-1, -1, 0], [-1, 1, 0.1], [0, -1, -0.1], [0.2, 1, 0.2], [1, -0.8, 0], [1, 1, -0.2]])


@pytest.mark.parametrize("path", ["reference", "fast"])
@pytest.mark.parametrize("case", ["triangles", "indexed strip", "lines", "points", "polygon mode line"])
def test_instancing_equals_the_instances_drawn_one_by_one(case, path):
    state = {
        "triangles": dict(positions=TRIANGLES),
        "indexed strip": dict(positions=STRIP, indices=np.array([0, 1, 2, 3, 4, 5, 3]), topology="triangle_strip"),
        "lines": dict(positions=TRIANGLES, topology="lines", line_width=3.0),
        "points": dict(positions=TRIANGLES, topology="points", point_size=5.0),
        "polygon mode line": dict(positions=TRIANGLES, polygon_mode="line", polygon_offset=(1.0, 2.0)),
    }[case]
    (c1, d1), (c2, d2) = two_ways(path=path, depth_test="lequal", **state)
    assert c1.tobytes() == c2.tobytes()
    assert d1.tobytes() == d2.tobytes()
    assert len(np.unique(c1.reshape(-1, 4), axis=0)) > 5       # (something was drawn, by several instances)


def test_the_shader_sees_gl_instance_id_and_each_instances_row():
    def shader(attributes, uniforms):
        p = attributes.position
        x = -0.75 + 0.5 * attributes.instance_id          # an int: 0, 1, 2, 3
        return (p[0] * 0.2 + x, p[1] * 0.2, 0.0, 1.0), Varyings(attributes.tint)

    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, -1, 0], [1, 1, 0], [-1, 1, 0.]])
    tints = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0.]])
    fb = sp.Framebuffer(SIZE, SIZE)
    sp.draw(fb, square, vertex_shader=shader, instances=4, instance_attributes={"tint": tints})
    img = fb.to_uint8(alpha=False)
    for i, tint in enumerate(tints):
        x = int(round((-0.75 + 0.5 * i + 1) / 2 * SIZE))
        assert img[SIZE // 2, x].tolist() == (tint * 255).astype(int).tolist(), i
    assert img[SIZE // 2, SIZE // 2].tolist() == [0, 0, 0]      # between the instances: nothing


def test_the_primitive_id_restarts_in_each_instance():
    def shader(attributes, uniforms):
        p = attributes.position
        return (p[0] * 0.3 + attributes.x, p[1] * 0.3, 0.0, 1.0), Varyings((0.0, 0.0, 0.0))

    def by_id(varyings, uniforms, frag):
        return (0.25 * frag.primitive_id, 0.0, 0.0, 1.0)

    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, -1, 0], [1, 1, 0], [-1, 1, 0.]])
    fb = sp.Framebuffer(SIZE, SIZE)
    trace = sp.draw(fb, square, vertex_shader=shader, fragment_shader=by_id, instances=3,
                    instance_attributes={"x": [-0.6, 0.0, 0.6]}, trace=True)
    assert trace.primitives.primitive_id.tolist() == [0, 1, 0, 1, 0, 1]
    assert trace.primitives.instance.tolist() == [0, 0, 1, 1, 2, 2]
    assert trace.primitives.input_count == 6 and trace.primitives.instances == 3
    img = fb.to_uint8(alpha=False)
    for i in range(3):
        x = int(round((-0.6 + 0.6 * i + 1) / 2 * SIZE))
        assert img[SIZE // 2 + 8, x + 8, 0] == 0, i           # lower-right half: triangle 0 of every instance
        assert img[SIZE // 2 - 8, x - 8, 0] == 64, i          # upper-left half: triangle 1


def line_shader(attributes, uniforms):
    p = attributes.position
    return (p[0] * 0.4 + attributes.x, p[1] * 0.8, 0.0, 1.0), Varyings((1.0, 1.0, 1.0))


@pytest.mark.parametrize("topology, per_instance", [("line_strip", 2), ("line_loop", 3), ("triangle_strip", 1),
                                                    ("triangle_fan", 1)])
def test_strips_fans_and_loops_restart_in_each_instance(topology, per_instance):
    """Two instances, left and right: nothing joins the left one's last vertex to the right one's first."""
    zigzag = np.array([[-1, -1, 0], [0, 1, 0], [1, -1, 0.]])
    fb = sp.Framebuffer(SIZE, SIZE)
    trace = sp.draw(fb, zigzag, vertex_shader=line_shader, topology=topology, instances=2,
                    instance_attributes={"x": [-0.5, 0.5]}, trace=True)
    assert trace.primitives.input_count == 2 * per_instance
    assert trace.primitives.instance.tolist() == [0] * per_instance + [1] * per_instance
    img = fb.to_uint8(alpha=False)
    # a strip joining the instances would cross the middle column, from (-0.1, -0.8) to (0.1, -0.8)
    assert not img[:, SIZE // 2 - 3:SIZE // 2 + 3].any()
    assert img[:, :SIZE // 2].any() and img[:, SIZE // 2:].any()


def test_the_pixel_history_names_the_instance():
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, -1, 0], [1, 1, 0], [-1, 1, 0.]])
    fb = sp.Framebuffer(SIZE, SIZE)
    trace = sp.draw(fb, square, vertex_shader=line_shader, instances=3, instance_attributes={"x": [-0.1, 0.0, 0.1]},
                    depth_test="lequal", trace=True)
    history = trace.pixel_history(SIZE // 2 - 10, SIZE // 2 - 30)      # in every instance's triangle 1
    assert [(e.instance, e.primitive_id) for e in history] == [(0, 1), (1, 1), (2, 1)]
    cols, rows = history.table()
    assert cols[:3] == ["#", "instance", "prim"]
    assert [r[1] for r in rows] == ["0", "1", "2"]
    text = str(history).splitlines()
    assert text[1].split()[:3] == ["#", "instance", "prim"]
    # a draw without instancing (or with one instance) has no such column
    for extra in ({}, {"instances": 1, "instance_attributes": {"x": [0.0]}}):
        attributes = {} if extra else {"attributes": {"x": np.zeros(6)}}
        t = sp.draw(sp.Framebuffer(SIZE, SIZE), square, vertex_shader=line_shader, trace=True, **extra, **attributes)
        h = t.pixel_history(SIZE // 2 - 10, SIZE // 2 - 30)
        assert "instance" not in h.table()[0] and [(e.instance, e.primitive_id) for e in h] == [(0, 1)]


def test_no_instances_draws_nothing():
    fb = sp.Framebuffer(SIZE, SIZE)
    fb.clear((0.1, 0.2, 0.3))
    before = fb.samples_color.copy(), fb.samples_depth.copy()
    sp.draw(fb, TRIANGLES, vertex_shader=vertex_shader, fragment_shader=fragment_shader, instances=0,
            instance_attributes={"offset": np.zeros((0, 3)), "scale": np.zeros(0)})
    assert fb.samples_color.tobytes() == before[0].tobytes() and fb.samples_depth.tobytes() == before[1].tobytes()


def draw_call(**kw):
    args = dict(framebuffer=sp.Framebuffer(8, 8), positions=TRIANGLES, vertex_shader=vertex_shader,
                fragment_shader=fragment_shader, instances=2,
                instance_attributes={"offset": np.zeros((2, 3)), "scale": np.ones(2)})
    args.update(kw)
    return DrawCall(**args)


@pytest.mark.parametrize("kw, error, message", [
    (dict(instances=-1), ValueError, "instances must be an int ≥ 0 (how many instances to draw), got -1"),
    (dict(instances=2.0), TypeError, "instances must be an int ≥ 0 (how many instances to draw), got 2.0"),
    (dict(instances=True), TypeError, "instances must be an int ≥ 0 (how many instances to draw), got True"),
    (dict(instance_attributes={"offset": np.zeros((3, 3)), "scale": np.ones(2)}), ValueError,
     "instance_attributes['offset'] has shape [3, 3]: it must be [2, k] (one row per instance, instances=2) "
     "with k 1 to 4, or [2]"),
    (dict(instance_attributes={"offset": np.zeros((2, 5)), "scale": np.ones(2)}), ValueError,
     "instance_attributes['offset'] has shape [2, 5]: it must be [2, k] (one row per instance, instances=2) "
     "with k 1 to 4, or [2]"),
    (dict(instance_attributes={"offset": np.zeros((2, 1, 3)), "scale": np.ones(2)}), ValueError,
     "instance_attributes['offset'] has shape [2, 1, 3]: it must be [2, k] (one row per instance, instances=2) "
     "with k 1 to 4, or [2]"),
    (dict(instance_attributes={"offset": [[0, 0, 0], [0, np.nan, 0]], "scale": np.ones(2)}), ValueError,
     "instance_attributes['offset'] is not finite at row 1 (instance 1): [0.0, nan, 0.0]"),
    (dict(attributes={"scale": np.ones(12)}), ValueError,
     "instance_attributes['scale'] has the name of a per-vertex attribute (attributes['scale']): the shader would "
     "see both as attributes.scale; rename one"),
    (dict(instance_attributes={"instance_id": np.zeros(2)}), ValueError,
     "instance_attributes must not contain 'instance_id': the vertex shader's attributes.instance_id is "
     "gl_InstanceID"),
    (dict(instance_attributes={"offset": np.zeros((2, 3)), "scale": np.ones(2), "class": np.ones(2)}), ValueError,
     "instance attribute name 'class' is a Python keyword"),
    (dict(instance_attributes=[1, 2]), TypeError,
     "instance_attributes must be a dict of name → [instances, k] array, got list"),
])
def test_bad_instancing_is_refused_with_a_message(kw, error, message):
    with pytest.raises(error) as e:
        draw_call(**kw)
    assert message in str(e.value)


@pytest.mark.parametrize("kw, message", [
    (dict(vertex_shader=None, positions=np.ones((3, 4))),
     "instances= needs a vertex_shader: without one every instance would draw the same clip positions"),
    (dict(instances=None), "instance_attributes= needs instances=N, the number of instances (their rows)"),
    (dict(attributes={"instance_id": np.zeros(12)}),
     "attributes must not contain 'instance_id' in an instanced draw: attributes.instance_id is gl_InstanceID"),
    (dict(instances=MAX_VERTICES // 12 + 1, instance_attributes=None),
     f"instances={MAX_VERTICES // 12 + 1:,} × 12 vertices = {(MAX_VERTICES // 12 + 1) * 12:,} vertices to shade; "
     f"the limit is MAX_VERTICES = {MAX_VERTICES:,} per draw: draw the instances in several draws"),
])
def test_instancing_refused_when_the_draw_runs(kw, message):
    fb = sp.Framebuffer(8, 8)
    fb.clear((0.5, 0.5, 0.5))
    before = fb.samples_color.copy()
    with pytest.raises(ValueError) as e:
        draw_call(framebuffer=fb, **kw).run()
    assert message in str(e.value)
    assert fb.samples_color.tobytes() == before.tobytes()
