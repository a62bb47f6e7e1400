"""Depth-only draws (issue #35): a shadow map's opaque pass shades nothing, and its depth is the reference's.

A draw with every color channel masked off and a fragment shader that returns a constant
color (``softpipe.pipeline.visibility.depth_only``) takes the fast path without its shading:
the visibility pass's depth is its result. The oracle is the reference path (every
fragment shaded and merged) and the fast path as it was before, with its shading: every
shadow map is compared with both bit for bit, on a directional light, a spot, a point
light's cube map and transparent casters, and at one and two threads.
"""
import numba
import numpy as np
import pytest

from softpipe import DrawCall, Framebuffer, render_shadow_maps
from softpipe.light.material import Light, Lighting, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.merge_state import MergeState
from softpipe.pipeline.transforms import rotate, scale, translate
from softpipe.pipeline.visibility import constant_color, depth_only, fast_path_blocker
from softpipe.scenes import shadow_pass, shapes
from softpipe.scenes.scene import SceneObject

OFF = (False, False, False, False)


def floor():
    return SceneObject("floor", shapes.plane(8.0), np.eye(4))


def box(model, material=None, name="box"):
    return SceneObject(name, shapes.cube(1.0, material=material), np.asarray(model, np.float64))


def sphere(model, name="sphere"):
    return SceneObject(name, shapes.uv_sphere(1.0, 24, 12), model)


def scenes():
    """name → (objects, lighting): each light kind, and transparent casters among opaque ones."""
    casters = [floor(), box(translate(0.1, 1.5, -0.2) @ rotate(30.0, (1.0, 2.0, 0.5))),
               sphere(translate(-1.2, 0.9, 0.8) @ scale(0.6))]
    glass = box(translate(-0.8, 0.8, 0.5) @ scale(1.0, 0.1, 1.0), Material(kt=(0.2, 0.6, 0.9)), "glass")
    veil = box(translate(1.0, 1.1, 0.6) @ scale(0.8, 0.1, 0.8), Material(opacity=0.25), "veil")
    settings = ShadowSettings(resolution=256)
    return {
        "directional": (casters, Lighting((Light.directional((0.5, -1.0, 0.3), shadows=settings),))),
        "spot": (casters, Lighting((Light.spot((2.0, 4.0, 1.5), (-0.5, -1.0, -0.4), 35.0, 2.0,
                                               shadows=settings),))),
        "point": (casters, Lighting((Light.point((0.2, 2.6, 0.1), shadows=ShadowSettings(resolution=160)),))),
        "transparent": (casters + [glass, veil],
                        Lighting((Light.directional((0.3, -1.0, 0.2), shadows=settings),
                                  Light.spot((1.5, 3.5, 1.0), (-0.4, -1.0, -0.3), 40.0, 1.0, shadows=settings)))),
    }


def maps_by(monkeypatch, objects, lighting, **forced):
    """render_shadow_maps with every DrawCall of the shadow pass given ``forced`` keywords (a color mask
    of None: the keyword left out, as before depth-only draws); returns (maps, the calls made)."""
    made = []

    def call(*args, **kwargs):
        kwargs = dict(kwargs, **forced)
        if kwargs.get("color_mask", ()) is None:
            del kwargs["color_mask"]
        c = DrawCall(*args, **kwargs)
        made.append(c)
        return c

    with monkeypatch.context() as m:
        m.setattr(shadow_pass, "DrawCall", call)
        maps = render_shadow_maps(objects, lighting)
    return maps, made


def same_maps(a, b, what):
    assert len(a.maps) == len(b.maps), what
    for x, y in zip(a.maps, b.maps):
        assert x.depth.tobytes() == y.depth.tobytes(), (what, x.face)
        for name in ("transparent_depth", "transmission"):
            u, v = getattr(x, name), getattr(y, name)
            assert (u is None) == (v is None), (what, name)
            if u is not None:
                assert u.tobytes() == v.tobytes(), (what, name, x.face)


@pytest.mark.parametrize("scene", ["directional", "spot", "point", "transparent"])
def test_depth_only_maps_are_the_reference_paths_bit_for_bit(monkeypatch, scene):
    """Every map (depth, and the transparent casters' depth and transmission) made by the depth-only
    route is the one the reference path makes and the one the fast path with its shading made;
    every opaque pass took the depth-only route, and every transparent one the shading fast path."""
    objects, lighting = scenes()[scene]
    new, calls = maps_by(monkeypatch, objects, lighting)
    assert (np.concatenate([m.depth.ravel() for m in new.maps]) < 1.0).sum() > 1000   # the casters are in them
    opaque = [c for c in calls if not any(c.state.color_mask)]
    assert opaque and all(c.path_taken == "fast" and "depth only" in c.path_reason for c in opaque)
    assert all(constant_color(c.fragment_shader) == (0.0, 0.0, 0.0, 1.0) for c in opaque)
    clear = [c for c in calls if c not in opaque]
    assert all(c.path_taken == "fast" and "depth only" not in c.path_reason for c in clear)
    assert bool(clear) == (scene == "transparent")
    reference, _ = maps_by(monkeypatch, objects, lighting, path="reference")
    shaded, _ = maps_by(monkeypatch, objects, lighting, color_mask=None)
    same_maps(new, reference, "reference path")
    same_maps(new, shaded, "fast path with shading")


@pytest.mark.parametrize("scene", ["directional", "point", "transparent"])
def test_depth_only_maps_are_the_same_on_one_and_two_threads(scene):
    objects, lighting = scenes()[scene]
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_shadow_maps(objects, lighting)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = render_shadow_maps(objects, lighting)
    finally:
        numba.set_num_threads(before)
    same_maps(one, two, "1 vs 2 threads")


def constant(varyings, uniforms, frag):
    return (0.25, 0.5, 0.75, 1.0)


def from_varying(varyings, uniforms, frag):
    return (varyings.color[0], 0.0, 0.0, 1.0)


def triangles(n=60, seed=3):
    rng = np.random.default_rng(seed)
    clip = np.c_[rng.uniform(-1.2, 1.2, (3 * n, 2)), rng.uniform(-0.9, 0.9, 3 * n), np.ones(3 * n)]
    return clip, np.arange(3 * n).reshape(-1, 3), {"color": rng.uniform(0.0, 1.0, (3 * n, 3))}


@pytest.mark.parametrize("record", [False, True])
def test_a_users_depth_only_draw_shades_nothing_and_writes_the_reference_depth(record):
    """color_mask all off with a constant shader: the fast path with no shading (0 invocations), the
    depth (and the visibility record) of the reference path, the color untouched."""
    clip, indices, varyings = triangles()
    out = {}
    for path in ("auto", "reference"):
        fb = Framebuffer(160, 160, record=record).clear((0.1, 0.2, 0.3, 1.0))
        call = DrawCall(fb, clip, indices, varyings, None, constant, None, color_mask=OFF, path=path)
        stages = list(call.steps())
        out[path] = (fb, call, stages)
    fb, call, stages = out["auto"]
    assert call.path_taken == "fast"
    assert call.path_reason.startswith("depth only (every color channel masked off, a constant fragment shader)")
    assert [s.name for s in stages] == ["vertex", "assembly", "visibility", "fragment"]
    assert stages[-1].output.invocations == 0 and stages[-1].output.written.sum() > 10000
    ref = out["reference"][0]
    assert fb.samples_depth.tobytes() == ref.samples_depth.tobytes()
    assert (fb.samples_depth < 1.0).sum() > 10000
    assert fb.samples_color.tobytes() == ref.samples_color.tobytes()
    assert (fb.color == np.float32([0.1, 0.2, 0.3, 1.0])).all()
    if record:
        assert fb.record.tobytes() == ref.record.tobytes()


def test_a_masked_draw_whose_shader_is_not_constant_keeps_to_the_reference_path():
    """Only a constant shader makes a masked draw depth-only: one reading a varying (which could be NaN,
    a discard) or a mask with a channel on keeps the reference path and its reason, as before."""
    clip, indices, varyings = triangles()
    for shader, mask in ((from_varying, OFF), (constant, (False, False, False, True))):
        fb = Framebuffer(160, 160)
        call = DrawCall(fb, clip, indices, varyings, None, shader, None, color_mask=mask)
        call.run()
        assert call.path_taken == "reference"
        assert call.path_reason == f"the color mask {mask} holds back a channel (the fast path writes whole colors)"
    assert fast_path_blocker(MergeState(color_mask=OFF), constant, attachments=2).startswith("the color mask")
    assert not depth_only(MergeState(color_mask=OFF, blend="alpha"), constant)


def test_constant_color_is_a_proof_read_from_the_code():
    def with_work(v, u, f):
        x = u.gain
        return (x, 0.0, 0.0, 1.0)

    def nan_alpha(v, u, f):
        return (0.0, 0.0, 0.0, float("nan"))

    def rgb(v, u, f):
        return (0.0, 0.0, 0.0)

    def two(v, u):
        return (0.0, 0.0, 0.0, 1.0)

    def prologue(v, u, f):
        u.gain  # noqa: B018  (an attribute read: work before the return)
        return (0.0, 0.0, 0.0, 1.0)

    assert constant_color(constant) == (0.25, 0.5, 0.75, 1.0)
    assert constant_color(lambda v, u, f: (0, 0, 0, 1)) == (0.0, 0.0, 0.0, 1.0)
    assert constant_color(numba.njit(constant)) == (0.25, 0.5, 0.75, 1.0)
    for shader in (with_work, nan_alpha, rgb, two, prologue, from_varying, None,
                   lambda v, u, f: (0.0, 0.0, 0.0, float("inf")), lambda v, u, f: (True, 0.0, 0.0, 1.0)):
        assert constant_color(shader) is None, shader


def test_a_caster_outside_a_map_is_not_even_transformed(monkeypatch):
    """A point light's six faces and a small box on its +x axis: the box is transformed (and drawn) for
    the +x face only; the other five faces leave it out by its bounding box. The maps are the
    same as without the cull (the triangle cull would have dropped all its triangles)."""
    light = Light.point((0.0, 0.0, 0.0), shadows=ShadowSettings(resolution=128))
    small = box(translate(5.0, 0.0, 0.0) @ scale(0.8), name="small")
    lighting = Lighting((light,))
    transformed = []
    real = shadow_pass.transform_points

    def counting(matrix, points, *args, **kwargs):
        if len(points) == len(small.mesh.positions):
            transformed.append(1)
        return real(matrix, points, *args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(shadow_pass, "transform_points", counting)
        maps = render_shadow_maps([small], lighting)
    assert [m.face for m in maps.maps] == ["+x", "-x", "+y", "-y", "+z", "-z"]
    # once for the caster into world space (casters_of), once for the +x face's clip coordinates
    assert len(transformed) == 2
    assert (maps.maps[0].depth < 1.0).sum() > 20 and all((m.depth == 1.0).all() for m in maps.maps[1:])
    with monkeypatch.context() as m:
        m.setattr(shadow_pass, "_outside_map", lambda matrix, bounds: False)
        uncut = render_shadow_maps([small], lighting)
    same_maps(maps, uncut, "without the bounding-box cull")


def pcf_as_before(shadows, k, x, y, ref):
    """shadow_compare as it was before its opaque-map shortcut: every tap's bounds and transparency tested."""
    offset, width, height, r = shadows.maps[k, 0], shadows.maps[k, 1], shadows.maps[k, 2], shadows.maps[k, 3]
    clear = shadows.maps[k, 4]
    i0, j0 = int(np.floor(x)), int(np.floor(y))
    red, green, blue = 0.0, 0.0, 0.0
    for j in range(j0 - r, j0 + r + 1):
        for i in range(i0 - r, i0 + r + 1):
            if i < 0 or j < 0 or i >= width or j >= height:
                red += 1.0
                green += 1.0
                blue += 1.0
                continue
            texel = j * width + i
            if ref > shadows.depth[offset + texel]:
                continue
            if clear >= 0 and ref > shadows.transparent_depth[clear + texel]:
                red += shadows.transmission[clear + texel, 0]
                green += shadows.transmission[clear + texel, 1]
                blue += shadows.transmission[clear + texel, 2]
            else:
                red += 1.0
                green += 1.0
                blue += 1.0
    taps = (2 * r + 1) * (2 * r + 1)
    return red / taps, green / taps, blue / taps


def test_the_pcf_lookup_gives_the_bits_it_gave_before():
    """shadow_compare's shortcuts — every tap inside an opaque-only map (the 3×3 of r = 1 written out),
    every tap outside the map — give the same three values, bit for bit, as the general loop,
    compiled both, on maps of PCF r = 0…2 (one with a transparent layer), depths with NaNs and
    ties, points inside, on the border, just and far outside (infinite, NaN)."""
    from softpipe.light.shadowmap import ShadowUniform, shadow_compare

    rng = np.random.default_rng(35)
    sizes, radii = [(16, 12), (9, 20), (24, 24), (16, 16), (20, 14)], [0, 1, 2, 1, 1]
    depth = [rng.choice([0.25, 0.5, 0.75, 1.0], w * h).astype(np.float32) for w, h in sizes]
    depth[2][::7] = np.nan
    depth[4][::5] = np.nan
    offsets = np.cumsum([0] + [w * h for w, h in sizes])
    maps = np.array([[offsets[m], w, h, r, 0 if m == 3 else -1] for m, ((w, h), r) in enumerate(zip(sizes, radii))],
                    np.int64)
    w3, h3 = sizes[3]
    shadows = ShadowUniform(np.zeros((0, 3), np.int64), maps, np.zeros((5, 4, 4)), np.concatenate(depth),
                            rng.choice([0.1, 0.3, 1.0], w3 * h3).astype(np.float32),
                            rng.uniform(0.0, 1.0, (w3 * h3, 3)).astype(np.float32), None)
    before = numba.njit(pcf_as_before)
    checked = 0
    for k, (w, h) in enumerate(sizes):
        r = radii[k]
        edges = [-r - 1.0, -r - 0.5, -r + 0.0, w + r - 0.5, w + r + 0.0, w + r + 0.5]   # the last taps in, the first out
        far = [-1e30, 1e30, -np.inf, np.inf, np.nan, 3.5, 3.5]
        xs = np.r_[rng.uniform(-6.0, w + 6.0, 300), 0.0, 0.5, 1.0, w - 1.0, w - 0.5, float(w), np.nan, edges, far,
                   [3.5] * 7]
        ys = np.r_[rng.uniform(-6.0, h + 6.0, 300), 0.0, 0.5, 1.0, h - 1.0, h - 0.5, float(h), 3.5, edges[::-1],
                   [3.5] * 5, 1e30, np.nan, far]
        refs = np.r_[rng.choice([0.25, 0.5, 0.6, 0.75, 1.0], 306), np.nan, [0.6] * 20]
        for x, y, ref in zip(xs, ys, refs):
            got, want = shadow_compare(shadows, k, x, y, ref), before(shadows, k, x, y, ref)
            assert np.array(got).tobytes() == np.array(want).tobytes(), (k, x, y, ref, got, want)
            checked += 1
    assert checked == 5 * 327


def test_the_casters_bounds_are_numpys_min_and_max():
    """The compiled column bounds that fit the maps (shadow_pass._column_bounds) give numpy's
    min(axis=0) and max(axis=0): on random points, with infinities, signed zeros and a NaN column."""
    rng = np.random.default_rng(7)
    for points in (rng.normal(size=(5000, 3)) * 1e3, rng.integers(-3, 3, (64, 3)).astype(np.float64),
                   np.array([[0.0, -0.0, np.inf], [-0.0, 0.0, -np.inf], [1.0, np.nan, 2.0]]),
                   np.array([[np.nan, 1.0, 2.0], [3.0, 4.0, 5.0]]), np.array([[1.5, -2.5, 0.25]])):
        lo, hi = shadow_pass._column_bounds(np.ascontiguousarray(points))
        np.testing.assert_array_equal(lo, points.min(axis=0))
        np.testing.assert_array_equal(hi, points.max(axis=0))


def shuffled_sphere(seed=5):
    """A sphere's caster with its triangles in a random order (as a scanned mesh's come) and duplicated
    (every texel then has two triangles of the very same depth: a tie the order could decide)."""
    mesh = shapes.uv_sphere(1.0, 40, 20)
    positions = np.asarray(mesh.positions, np.float64) + (0.0, 1.2, 0.0)
    tri = np.asarray(mesh.indices).reshape(-1, 3)
    tri = np.concatenate([tri, tri[:, ::-1]])                  # both windings: the same depths twice
    tri = tri[np.random.default_rng(seed).permutation(len(tri))]
    return shadow_pass.ShadowCaster("sphere", positions, tri)


def test_the_opaque_casters_order_changes_no_map(monkeypatch):
    """The opaque casters reach the depth pass in Morton order (shadow_pass._in_coherent_order): every
    map is the same bytes as with the triangles in the order given, on each light kind, with
    transparent casters (kept in their order), a shuffled mesh with duplicated triangles (ties), and
    through the reference path."""
    cases = dict(scenes())
    cases["shuffled"] = ([shuffled_sphere(), *shadow_pass.casters_of([floor()])],
                         cases["transparent"][1])
    for name, (objects, lighting) in cases.items():
        ordered, _ = maps_by(monkeypatch, objects, lighting)
        reference, _ = maps_by(monkeypatch, objects, lighting, path="reference")
        with monkeypatch.context() as m:
            m.setattr(shadow_pass, "_in_coherent_order", lambda caster: caster)
            given, _ = maps_by(monkeypatch, objects, lighting)
        same_maps(ordered, given, f"{name}: Morton order vs the order given")
        same_maps(ordered, reference, f"{name}: Morton order, reference path")


def test_a_scattered_mesh_is_drawn_in_morton_order_sorted_once(monkeypatch):
    """A mesh in random order reaches the opaque pass with its triangles' Morton codes in increasing
    order (what makes the tiles' lists run through neighbours); the order is made once per mesh, not
    every frame, also when its index array is made anew each frame (as a part of a mesh of several
    materials is); a transparent caster keeps the order it was given."""
    caster = shuffled_sphere()
    glass = shadow_pass.casters_of([box(translate(-0.8, 2.8, 0.5) @ scale(1.0, 0.1, 1.0),
                                        Material(kt=(0.2, 0.6, 0.9)), "glass")])[0]
    lighting = Lighting((Light.directional((0.3, -1.0, 0.2), shadows=ShadowSettings(resolution=128)),))
    sorts = []
    real = shadow_pass._morton_codes

    def counting(positions, indices):
        sorts.append(len(indices))
        return real(positions, indices)

    with monkeypatch.context() as m:
        m.setattr(shadow_pass, "_morton_codes", counting)
        shadow_pass._ORDERS.clear()
        _, calls = maps_by(monkeypatch, [caster, glass], lighting)
        anew = shadow_pass.ShadowCaster(caster.name, caster.positions, caster.indices.copy())   # the same rows
        _, again = maps_by(monkeypatch, [anew, glass], lighting)
    assert sorts == [len(caster.indices)]                      # once, for the opaque caster only
    for made in (calls, again):
        opaque, clear = [c for c in made if not any(c.state.color_mask)], [c for c in made if any(c.state.color_mask)]
        drawn = np.asarray(opaque[0].indices)
        assert sorted(map(tuple, drawn)) == sorted(map(tuple, caster.indices))
        assert (np.diff(real(caster.positions, drawn.astype(np.int64))) >= 0).all()
        assert (np.diff(real(caster.positions, caster.indices.astype(np.int64))) < 0).any()   # it was not
        assert np.array_equal(np.asarray(clear[0].indices), glass.indices)


def test_at_most_ORDERS_KEPT_orders_are_kept_the_newest():
    rng = np.random.default_rng(1)
    shadow_pass._ORDERS.clear()
    casters = [shadow_pass.ShadowCaster("c", rng.normal(size=(30, 3)), rng.integers(0, 30, (10 + k, 3)))
               for k in range(shadow_pass._ORDERS_KEPT + 4)]
    for c in casters:
        shadow_pass._in_coherent_order(c)
    assert len(shadow_pass._ORDERS) == shadow_pass._ORDERS_KEPT
    assert [key[0][0] for key in shadow_pass._ORDERS] == [len(c.indices) for c in casters[4:]]
    shadow_pass._ORDERS.clear()
