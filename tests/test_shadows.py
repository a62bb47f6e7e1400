"""Shadow maps (issue #15) against analytic shadows: FORMULAS §10, §11, §21.

A shadow map is the rasterizer's shadow ray (FORMULAS §21): V_j(p) = 0 where a caster
lies between p and light j, the caster's transmission behind glass, and the lit
programs multiply light j's diffuse and specular terms by V_j (§10 with §11's V_i;
the ambient term is not shadowed).

Every expected answer here is computed in the test, with numpy, from the scene's
geometry: a convex caster's shadow on a plane is the convex hull of its corners
projected along the light's rays onto the plane (parallel rays for a directional
light, rays from the light's position for a point or spot light). Pixels are read
back from orthographic cameras looking straight at the receiver, so a pixel centre's
world point is known exactly. A pixel's visibility is read from its color: with
ks = 0 a receiver's color is A + V·D, A = ka·I_a,global (the ambient of §10) and
D = kd·I_d·(N·L) (the diffuse of light j), both evaluated here, so V = (c − A)/D.

The measured figures (resolutions as set in each test) are stated in the tests'
docstrings and asserted.
"""
import math

import numpy as np
import pytest
from conftest import unit

from softpipe import Camera, DrawCall, Framebuffer, draw_mesh, render_shadow_maps
from softpipe.light.material import Light, Lighting, LightingUniform, Material
from softpipe.light.shadowmap import (
    ShadowSettings,
    depth_texture,
    light_visibility,
    shadow_map_visibility,
    texture_compare,
)
from softpipe.pipeline.transforms import orthographic, rotate, scale, translate
from softpipe.scenes import shapes
from softpipe.scenes.scene import SceneObject
from softpipe.scenes.shadow_pass import casters_of

# A receiver lit by one white light: A = 0.2 (ka = 1 times the global ambient 0.2),
# D = 0.8·(N·L); no specular, so that color = A + V·D exactly.
AMBIENT = 0.2
KD = 0.8
MATTE = Material(ka=(1.0, 1.0, 1.0), kd=(KD, KD, KD), ks=(0.0, 0.0, 0.0))


# ------------------------------------------------------------------ analytic geometry (numpy only)

def convex_hull(points):
    """The convex hull of 2-D points, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(set(map(tuple, np.round(np.asarray(points, np.float64), 12))))

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


def inside(poly, q):
    """Which 2-D points q [..., 2] lie strictly inside the counter-clockwise convex polygon."""
    ok = np.ones(q.shape[:-1], bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        ok &= (b[0] - a[0]) * (q[..., 1] - a[1]) - (b[1] - a[1]) * (q[..., 0] - a[0]) > 0
    return ok


def boundary_distance(poly, q):
    """Each 2-D point's distance to the polygon's boundary."""
    best = np.full(q.shape[:-1], np.inf)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        ab = b - a
        t = np.clip(((q - a) @ ab) / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(q - (a + t[..., None] * ab), axis=-1))
    return best


def box_corners(model):
    """The 8 world corners of the unit cube (shapes.cube(1)) under ``model``."""
    c = np.array([(x, y, z, 1.0) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    return (c @ np.asarray(model, np.float64).T)[:, :3]


def project_along(points, direction, origin, normal):
    """Points moved along the parallel ``direction`` onto the plane (origin, normal)."""
    t = ((origin - points) @ normal) / (direction @ normal)
    return points + t[:, None] * direction


def project_from(points, light, origin, normal):
    """Points moved along the rays from ``light`` through them onto the plane (origin, normal)."""
    d = points - light
    t = ((origin - light) @ normal) / (d @ normal)
    return light + t[:, None] * d


class View:
    """An orthographic camera looking along ``forward`` at a receiver plane; pixel centres → world.

    ``points`` [n, n, 3]: the receiver's world point seen at each pixel centre (image
    rows, top first); ``uv`` [n, n, 2]: the same point in the plane's (right, up)
    coordinates, in which the shadow polygons are built; ``pixel`` the side of a pixel
    on the receiver, in world units.
    """

    def __init__(self, eye, forward, up, half, n, origin, normal):
        eye, forward = np.asarray(eye, np.float64), unit(forward)
        self.camera = Camera(eye=tuple(eye), target=tuple(eye + forward), up=tuple(up))
        self.projection = orthographic(-half, half, -half, half, 0.05, 50.0)
        self.n, self.pixel = n, 2.0 * half / n
        right = unit(np.cross(forward, up))
        true_up = np.cross(right, forward)
        c = (np.arange(n) + 0.5) * self.pixel - half              # window x (and y) of pixel centres
        rays = eye + c[None, :, None] * right + c[::-1, None, None] * true_up     # image row 0 = top
        origin, normal = np.asarray(origin, np.float64), unit(normal)
        t = ((origin - rays) @ normal) / (forward @ normal)
        self.points = rays + t[..., None] * forward
        self.right, self.up, self.eye = right, true_up, eye

    def to_uv(self, world):
        world = np.asarray(world, np.float64)
        return np.stack([(world - self.eye) @ self.right, (world - self.eye) @ self.up], axis=-1)

    @property
    def uv(self):
        return self.to_uv(self.points)

    def draw(self, fb, obj, lighting_uniform, **state):
        draw_mesh(fb, obj.mesh, self.camera, "phong", model=obj.model, lighting=lighting_uniform,
                  uniforms={"projection": self.projection}, **state)


def top_down(n=64, half=2.0):
    """Straight down onto the floor y = 0: image right = +x, image up = −z."""
    return View((0.0, 10.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0), half, n, (0, 0, 0), (0, 1, 0))


def floor(size=6.0, material=MATTE):
    return SceneObject("floor", shapes.plane(size, material=material), np.eye(4))


def box(model, material=MATTE, name="box"):
    return SceneObject(name, shapes.cube(1.0, material=material), np.asarray(model, np.float64))


def visibility_from_color(fb, n_dot_l, channel=0, ambient=AMBIENT, kd=KD):
    """V per pixel, from the color: (c − A) / D (see the module docstring)."""
    return (fb.color[..., channel].astype(np.float64) - ambient) / (kd * n_dot_l)


def render(view, objects, lighting, drawn=None, **state):
    """The shadow maps of ``objects``, then ``drawn`` (default: all) seen by ``view``; (fb, maps)."""
    maps = render_shadow_maps(objects, lighting)
    lu = maps.lighting_uniform(lighting, view.camera.view)
    fb = Framebuffer(view.n, view.n)
    for obj in objects if drawn is None else drawn:
        view.draw(fb, obj, lu, **state)
    return fb, maps


def picture(shadowed, expected):
    """Rows of the comparison, for failure messages: # both, + only rendered, - only expected."""
    chars = np.where(shadowed & expected, "#", np.where(shadowed, "+", np.where(expected, "-", ".")))
    return "\n".join("".join(row) for row in chars)


def check_band(view, V, poly, exclude, band, label):
    """Every pixel outside ``exclude`` is shadowed (V < ½) iff its centre is inside ``poly``,
    except within ``band`` pixels of the polygon's edge; returns the farthest miss (px)."""
    uv = view.uv
    expected = inside(poly, uv)
    shadowed = V < 0.5
    wrong = (shadowed != expected) & ~exclude
    distance = boundary_distance(poly, uv) / view.pixel
    worst = float(distance[wrong].max()) if wrong.any() else 0.0
    assert expected[~exclude].sum() > 50, f"{label}: the analytic shadow is too small to test"
    assert worst <= band, (f"{label}: {int((wrong & (distance > band)).sum())} pixel(s) disagree with the "
                           f"analytic shadow farther than {band} px from its edge (up to {worst:.2f} px)\n"
                           + picture(shadowed & ~exclude, expected & ~exclude))
    return worst


# ------------------------------------------------------------------ 1. a cube above a floor, directional light

@pytest.mark.parametrize("floor_casts", [True, False])
@pytest.mark.parametrize("pcf", [0, 1])
def test_directional_cube_shadow_matches_the_projected_hull(pcf, floor_casts):
    """A unit cube floating 1 above the floor, a slanted directional light (FORMULAS §21).

    The shadow is the hull of the cube's 8 corners moved along the light's direction
    onto y = 0. Seen from straight above (64 px over 4 units; map 512 texels over the
    ~6.4-unit floor, ≈ 5 texels per pixel), every floor pixel not covered by the cube
    is shadowed iff its centre is in the hull, except within 1 px of the hull's edge.
    Measured: with PCF r = 0 and r = 1, no pixel disagrees farther than 0.1 px from the
    edge (the band asserted is 1 px); away from the edge V is exactly 0 or 1. The same
    with a floor that casts no shadow (SceneObject.cast_shadows=False: the map is fitted
    to the cube alone, and the floor lies beyond its far plane).
    """
    d = unit((0.5, -1.0, 0.3))
    light = Light.directional(d, shadows=ShadowSettings(resolution=512, pcf=pcf))
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    cube_model = translate(0.1, 1.5, -0.2)
    view = top_down()
    ground = SceneObject("floor", shapes.plane(6.0, material=MATTE), np.eye(4), cast_shadows=floor_casts)
    fb, _ = render(view, [ground, box(cube_model)], lighting)

    shadow = project_along(box_corners(cube_model), d, np.zeros(3), np.array([0.0, 1.0, 0.0]))
    poly = convex_hull(view.to_uv(shadow))
    x, z = view.points[..., 0], view.points[..., 2]
    on_cube = (np.abs(x - 0.1) < 0.5) & (np.abs(z + 0.2) < 0.5)     # the cube's top face hides the floor
    V = visibility_from_color(fb, -d[1])
    worst = check_band(view, V, poly, on_cube, 1.0, f"pcf={pcf}")
    print(f"pcf={pcf}: farthest disagreeing pixel {worst:.2f} px from the shadow's edge")
    # lit pixels are fully lit, shadowed ones fully dark, away from the edge
    far = boundary_distance(poly, view.uv) / view.pixel > 2.0
    np.testing.assert_allclose(V[far & ~on_cube], np.where(inside(poly, view.uv), 0.0, 1.0)[far & ~on_cube],
                               atol=1e-5)


# ------------------------------------------------------------------ 2. no acne; acne without the bias

def grazing(azimuth_degrees, angle_degrees=80.0):
    """The direction of a light arriving ``angle_degrees`` from the floor's normal."""
    t, p = math.radians(angle_degrees), math.radians(azimuth_degrees)
    return np.array([math.sin(t) * math.cos(p), -math.cos(t), math.sin(t) * math.sin(p)])


@pytest.mark.parametrize("pcf", [0, 1])
@pytest.mark.parametrize("azimuth", [0.0, 30.0, 45.0])
def test_no_acne_on_a_floor_at_grazing_light(pcf, azimuth):
    """A floor alone, lit 80° from its normal, casts no shadow on itself with the default
    bias (FORMULAS §21: ε > 0 prevents "acne"): every pixel is fully lit, V = 1 — with
    PCF r = 0 and r = 1 and a 1024-texel map (the default settings)."""
    d = grazing(azimuth)
    lighting = Lighting((Light.directional(d, shadows=ShadowSettings(pcf=pcf)),), global_ambient=(AMBIENT,) * 3)
    fb, _ = render(top_down(), [floor(4.5)], lighting)
    V = visibility_from_color(fb, -d[1])
    assert V.min() > 1.0 - 1e-5, f"{int((V < 1 - 1e-5).sum())} pixel(s) of {V.size} shadowed by the floor itself"


@pytest.mark.parametrize("pcf", [0, 1])
def test_acne_without_the_bias(pcf):
    """The failure mode the bias prevents: with polygon offset (0, 0) the same floor
    shadows itself in stripes (t_min = 0 of FORMULAS §21). Measured: half the pixels
    (2048 of 4096) have V < ½; the test asks for more than a tenth."""
    d = grazing(30.0)
    settings = ShadowSettings(pcf=pcf, offset_factor=0, offset_units=0)
    lighting = Lighting((Light.directional(d, shadows=settings),), global_ambient=(AMBIENT,) * 3)
    fb, _ = render(top_down(), [floor(4.5)], lighting)
    V = visibility_from_color(fb, -d[1])
    acne = int((V < 0.5).sum())
    print(f"pcf={pcf}: {acne} of {V.size} pixels in acne")
    assert acne > V.size // 10


# ------------------------------------------------------------------ 3. peter-panning

ELEVATION = 35.0      # the light's angle above the floor
WALL = translate(0.0625, 0.5, 0.0) @ scale(0.125, 1.0, 1.0)   # x ∈ [0, 0.125], y ∈ [0, 1], z ∈ [−½, ½]


@pytest.mark.parametrize("offset_factor, least_gap, most_gap", [(None, 0, 1), (100.0, 3, 5), (200.0, 9, 11)])
def test_peter_panning(offset_factor, least_gap, most_gap):
    """A box (a wall 0.125 thick, 1 high, standing on the floor) under a light 35° above
    the floor, travelling along +x: its shadow lies on the floor from the wall's far
    contact edge x = 0.125 to x = 0.125 + 1/tan 35°.

    The depth bias moves the casters away from the light by b (world units along the
    light): b = factor·DZ + units·r, DZ the wall face's depth slope per texel
    (tan 35°, the angle between its normal and the light, times a texel's size) —
    glPolygonOffset in world units. A floor point at x is lit when the wall's lit face
    (x = 0, where the map's depth is) is nearer to it than b along the ray, x / cos 35° < b:
    the shadow starts at max(0.125, b·cos 35°), and the gap is the floor lit between
    the contact edge and the shadow, "peter-panning". With the default settings (map
    512 texels, PCF r = 1: factor 4) b·cos 35° is 0.016, inside the wall: the gap is 0 px
    (measured; asserted ≤ 1 px). With offset_factor 100 and 200 the gap grows to
    4 and 11 px (measured; the analytic shadow starts 4.2 and 10.5 px from the edge).
    Every floor pixel agrees with that analytic shadow except within 1 px of its edge.
    """
    e = math.radians(ELEVATION)
    d = np.array([math.cos(e), -math.sin(e), 0.0])
    settings = ShadowSettings(resolution=512) if offset_factor is None else \
        ShadowSettings(resolution=512, offset_factor=offset_factor)
    lighting = Lighting((Light.directional(d, shadows=settings),), global_ambient=(AMBIENT,) * 3)
    view = top_down()
    fb, maps = render(view, [floor(), box(WALL)], lighting)
    V = visibility_from_color(fb, -d[1])

    # b from the map's texel size (its projection's extent / resolution) and the wall face's slope
    (m,) = maps.maps
    texel = 2.0 / np.abs(np.diag(m.projection)[:2]) / settings.resolution        # light-view x, y
    normal = m.view[:3, :3] @ np.array([-1.0, 0.0, 0.0])                          # the lit face, light view
    slope = max(abs(normal[0] / normal[2]) * texel[0], abs(normal[1] / normal[2]) * texel[1])
    depth_range = 2.0 / abs(m.projection[2, 2])
    # units·r: r ≤ 2⁻²⁴ (the wall's depths are < 1), a bound; it adds < 1e-5 here
    b = settings.offset_factor * slope + settings.offset_units * 2.0 ** -24 * depth_range
    start = max(0.125, b * math.cos(e))
    end = 0.125 + 1.0 / math.tan(e)
    poly = convex_hull([(start, 0.5), (end, 0.5), (end, -0.5), (start, -0.5)])     # (x, −z): view.uv
    x, z = view.points[..., 0], view.points[..., 2]
    on_wall = (x > 0.0) & (x < 0.125) & (np.abs(z) < 0.5)
    check_band(view, V, poly, on_wall, 1.0, f"offset_factor={settings.offset_factor}")

    rows = np.abs(z[:, 0]) < 0.5 - view.pixel
    beyond = x[0] > 0.125
    shadowed = V[rows][:, beyond] < 0.5
    assert shadowed.any(axis=1).all(), "a row of the wall's shadow is missing"
    gaps = np.argmax(shadowed, axis=1)          # lit pixels between the contact edge and the shadow
    print(f"offset_factor={settings.offset_factor}: gap {gaps.min()}…{gaps.max()} px "
          f"(analytic {(start - 0.125) / view.pixel:.2f} px)")
    assert least_gap <= gaps.min() and gaps.max() <= most_gap


# ------------------------------------------------------------------ 4. spot and point lights

def point_visibility(fb, view, light_position, normal):
    """V per pixel under a point or spot light (no attenuation, spot exponent 0): D = kd·(N·L)."""
    L = light_position - view.points
    n_dot_l = (L @ normal) / np.linalg.norm(L, axis=-1)
    return visibility_from_color(fb, n_dot_l)


@pytest.mark.parametrize("cutoff, count", [(45.0, 1), (80.0, 6)])
@pytest.mark.parametrize("pcf", [0, 1])
def test_spot_light_cube_shadow(pcf, cutoff, count):
    """The cube of the first test under a spot light: cutoff 45°, one perspective map of
    1024 texels; cutoff 80° (over MAX_SPOT_MAP_CUTOFF), a cube map of six. The shadow is
    the hull of the corners projected from the light's position onto the floor; the
    whole visible floor is inside the cone. Every floor pixel not covered by the cube
    agrees except within 1 px of the edge (measured: the farthest disagreement is
    0.01 px from it)."""
    position = np.array([0.6, 5.0, 0.4])
    light = Light.spot(position, -position, cutoff, shadows=ShadowSettings(pcf=pcf))
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    cube_model = translate(-0.2, 1.5, 0.1)
    view = top_down()
    fb, maps = render(view, [floor(), box(cube_model)], lighting)
    assert len(maps.maps) == count
    up = np.array([0.0, 1.0, 0.0])
    # every visible floor point is inside the cone, so V alone makes it darker
    to_points = unit(-position)
    cosines = ((view.points - position) @ to_points) / np.linalg.norm(view.points - position, axis=-1)
    assert cosines.min() > math.cos(math.radians(cutoff))
    poly = convex_hull(view.to_uv(project_from(box_corners(cube_model), position, np.zeros(3), up)))
    x, z = view.points[..., 0], view.points[..., 2]
    on_cube = (np.abs(x + 0.2) < 0.5) & (np.abs(z - 0.1) < 0.5)
    V = point_visibility(fb, view, position, up)
    worst = check_band(view, V, poly, on_cube, 1.0, f"spot {cutoff}° pcf={pcf}")
    print(f"spot {cutoff}° pcf={pcf}: farthest disagreeing pixel {worst:.2f} px from the shadow's edge")


AXES = [(axis, sign) for axis in range(3) for sign in (1.0, -1.0)]


def around(axis, sign):
    """(e, u, w): the axis direction and two directions across it, a right-handed (u, e, w) frame."""
    e = np.zeros(3)
    e[axis] = sign
    u = np.zeros(3)
    u[(axis + 1) % 3] = 1.0
    return e, u, np.cross(u, e)


def facing(center, normal, u):
    """The model matrix putting shapes.plane (facing +y) at ``center``, facing ``normal``."""
    w = np.cross(u, normal)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u, normal, w, center
    return m


@pytest.mark.parametrize("pcf", [0, 1])
def test_point_light_shadows_through_all_six_cube_faces(pcf):
    """A point light (a cube map of six 512-texel faces) with six occluder/receiver pairs
    around it, one along each of ±x, ±y, ±z: a 0.5 cube (turned, so that its shadow's
    edges are slanted) 1.5 from the light and a square receiver 3 from it, facing the
    light. Each shadow is the hull of the cube's corners projected from the light onto
    its receiver, and lies wholly within 35° of its axis — in that axis's face. Each
    receiver is drawn alone (the cubes are in the maps, not in the picture), by an
    orthographic camera on the light's side looking along the axis (64 px over 4 units),
    and every pixel agrees except within 1 px of the shadow's edge (measured: 0.07 px)."""
    light_position = np.array([0.1, -0.15, 0.05])
    light = Light.point(light_position, shadows=ShadowSettings(resolution=512, pcf=pcf))
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    pairs = []
    for axis, sign in AXES:
        e, u, w = around(axis, sign)
        receiver = SceneObject(f"receiver{axis}{sign:+}", shapes.plane(4.5, material=MATTE),
                               facing(light_position + 3.0 * e, -e, u))
        occluder = light_position + 1.5 * e + 0.2 * u - 0.15 * w
        pairs.append((e, u, receiver, box(translate(*occluder) @ rotate(25.0, (1.0, 2.0, 3.0)) @ scale(0.5))))
    maps = render_shadow_maps([o for _, _, r, c in pairs for o in (r, c)], lighting)
    assert len(maps.maps) == 6
    worst = 0.0
    for e, u, receiver, cube in pairs:
        view = View(light_position, e, u, 2.0, 64, light_position + 3.0 * e, -e)
        fb = Framebuffer(view.n, view.n)
        view.draw(fb, receiver, maps.lighting_uniform(lighting, view.camera.view))
        shadow = project_from(box_corners(cube.model), light_position, light_position + 3.0 * e, -e)
        off_axis = np.degrees(np.arccos(((shadow - light_position) @ e) / np.linalg.norm(shadow - light_position,
                                                                                            axis=1)))
        assert off_axis.max() < 35.0
        poly = convex_hull(view.to_uv(shadow))
        V = point_visibility(fb, view, light_position, -e)
        worst = max(worst, check_band(view, V, poly, np.zeros(V.shape, bool), 1.0, f"{receiver.name} pcf={pcf}"))
    print(f"point pcf={pcf}: farthest disagreeing pixel {worst:.2f} px from the shadow's edge")


# Proper rotations that carry the seam test's scene (made about the +x/+y seam) to other seams.
SEAMS = {
    "+x/+y": np.eye(3),
    "+y/+z": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),     # x → y, y → z, z → x
    "+z/+x": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),     # x → z, y → x, z → y
    "-x/-y": np.diag([-1.0, -1.0, 1.0]),
    "+x/-y": np.diag([1.0, -1.0, -1.0]),
}


def rotated(R, m):
    out = np.eye(4)
    out[:3, :3] = R
    return out @ m


@pytest.mark.parametrize("seam", sorted(SEAMS))
@pytest.mark.parametrize("pcf", [0, 1])
def test_point_light_shadow_crosses_a_cube_face_seam_without_a_gap(pcf, seam):
    """A long thin rod (0.1 × 2 × 0.1, along y) 1.5 from a point light at the origin, and a
    receiver x = 3 facing the light: the rod's shadow runs from y = 1 to y = 5 on it,
    across y = 3 where the +x and +y faces of the cube map meet (the direction
    (3, 3, z) is on the diagonal); the scene turned by a rotation puts it across the
    +y/+z, +z/+x, −x/−y and +x/−y seams. Every pixel along the shadow's analytic centre
    line (the rod's axis projected from the light, z = 0.6) is fully shadowed, V = 0, on
    both faces and at the seam (the shadow is ~17 texels wide, so every PCF tap there
    falls in it), and so is every point of the line sampled ten times per texel; the
    receiver's pixels 0.5 away from the shadow are fully lit."""
    R = SEAMS[seam]
    light = Light.point((0.0, 0.0, 0.0), shadows=ShadowSettings(resolution=512, pcf=pcf))
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    e, u = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    receiver = SceneObject("receiver", shapes.plane(8.0, material=MATTE),
                           rotated(R, facing((3.0, 2.5, 0.0), -e, u)))
    rod = box(rotated(R, translate(1.5, 1.5, 0.3) @ scale(0.1, 2.0, 0.1)), name="rod")
    maps = render_shadow_maps([receiver, rod], lighting)
    view = View(R @ (0.0, 2.5, 0.0), R @ e, R @ u, 3.0, 96, R @ (3.0, 0.0, 0.0), R @ -e)
    fb = Framebuffer(view.n, view.n)
    view.draw(fb, receiver, maps.lighting_uniform(lighting, view.camera.view))
    V = point_visibility(fb, view, np.zeros(3), R @ -e)

    local = view.points @ R                                          # back in the unturned scene
    y, z = local[..., 1], local[..., 2]
    line = np.abs(z - 0.6) < view.pixel / 2                          # the column on the centre line
    along = (y > 1.0 + 2 * view.pixel) & (y < 5.0 - 2 * view.pixel)
    assert line.any(axis=1).sum() == view.n
    # the line runs through both faces: x's below the seam (y < 3), y's above it
    assert (along & line & (y < 2.9)).sum() > 20 and (along & line & (y > 3.1)).sum() > 20
    on_line = along & line
    gaps = on_line & (V > 1e-6)
    assert not gaps.any(), (f"{int(gaps.sum())} pixel(s) on the shadow's centre line let light through: "
                            f"V = {np.round(V[gaps], 3).tolist()} at y = {np.round(y[gaps], 3).tolist()}")
    beside = along & (np.abs(np.abs(z - 0.6) - 0.5) < view.pixel / 2)  # 0.5 to either side
    assert beside.sum() > 100 and (V[beside] > 1.0 - 1e-5).all()

    # the same line sampled every ~1/10 texel (V_j as the shaders compute it, world = eye space)
    shadows = maps.uniform(np.eye(4))
    ys = np.linspace(1.05, 4.95, 4001)
    fine = np.array([shadow_map_visibility(shadows, 0, tuple(R @ (3.0, y, 0.6))) for y in ys])
    assert (fine < 1e-6).all(), f"light through the shadow at y = {np.round(ys[(fine >= 1e-6).any(1)], 4).tolist()}"


# ------------------------------------------------------------------ 5. glass

KT = (0.2, 0.6, 0.9)


def test_glass_slab_tints_the_shadow_and_opaque_casters_still_cut_the_light():
    """Transparent casters (FORMULAS §21: "scale the light by its transmission"): a slab
    of kt = (0.2, 0.6, 0.9), a slab of opacity 0.25 (transmitting 1 − 0.25 = 0.75) and two
    opaque cubes, one above the kt slab (nearer the light) and one below it, over a
    floor under a colored directional light. Only the floor is drawn. Its color is FORMULAS §10
    evaluated here: ka·I_a,global + V·kd·I_d·(N·L), with V = 0 in an opaque caster's
    shadow (glass or not), kt in the kt slab's, 0.75 in the other slab's, else 1;
    compared as float colors within 1e-6 at every pixel more than 2 px from a shadow's
    edge (PCF r = 1, map 1024 texels)."""
    d = unit((0.3, -1.0, 0.2))
    kd, diffuse = np.array([0.9, 0.7, 0.5]), np.array([1.0, 0.9, 0.8])
    light = Light.directional(d, diffuse=tuple(diffuse), shadows=ShadowSettings())
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    ground = floor(material=Material(ka=(1.0, 1.0, 1.0), kd=tuple(kd), ks=(0.0, 0.0, 0.0)))
    glass = box(translate(-0.5, 1.0, -0.3) @ scale(1.4, 0.1, 2.0), Material(kt=KT), "glass")
    veil = box(translate(1.0, 1.0, 0.6) @ scale(0.8, 0.1, 0.8), Material(opacity=0.25), "veil")
    above = box(translate(-0.6, 1.8, 0.2) @ scale(0.5), name="above")
    below = box(translate(-0.4, 0.35, -0.6) @ scale(0.5), name="below")
    view = top_down()
    fb, _ = render(view, [ground, glass, veil, above, below], lighting, drawn=[ground])

    up, uv = np.array([0.0, 1.0, 0.0]), view.uv
    hulls = {o.name: convex_hull(view.to_uv(project_along(box_corners(o.model), d, np.zeros(3), up)))
             for o in (glass, veil, above, below)}
    region = {name: inside(h, uv) for name, h in hulls.items()}
    V = np.ones(uv.shape[:-1] + (3,))
    V[region["veil"]] = 0.75
    V[region["glass"]] = KT
    V[region["above"] | region["below"]] = 0.0
    near_edge = np.min([boundary_distance(h, uv) for h in hulls.values()], axis=0) / view.pixel <= 2.0
    expected = AMBIENT + V * kd * diffuse * (-d[1])
    # each case is tested: the opaque casters' shadows lie within the glass's, apart from each other
    for case in (region["glass"] & ~region["above"] & ~region["below"], region["veil"],
                 region["above"], region["below"]):
        assert (case & ~near_edge).sum() > 20
    assert not (region["above"] & region["below"]).any()
    assert (region["glass"] | ~(region["above"] | region["below"])).all()
    np.testing.assert_allclose(fb.color[..., :3][~near_edge], expected[~near_edge], rtol=0, atol=1e-6)


def test_the_lighting_uniform_answers_each_lights_visibility_as_the_shaders_compute_it():
    """``LightingUniform.visibilities(P)``, what a pixel history shows (softpipe.pipeline.trace asks the
    uniform; the pipeline imports no lighting): V_j of every light at an eye-space point, the very
    values of ``light_visibility``: 0 under a box's shadow (map), 1 beside it, 1 for a light without
    shadows; () when no light casts shadows. The uniform stays a LightingUniform through ``_replace``."""
    down = Light.directional((0.0, -1.0, 0.0), shadows=ShadowSettings(resolution=256))
    side = Light.point((4.0, 3.0, 0.0))
    lighting = Lighting((down, side))
    view = top_down()
    maps = render_shadow_maps([floor(), box(translate(0.0, 1.0, 0.0))], lighting)
    lu = maps.lighting_uniform(lighting, view.camera.view)
    assert type(lu) is LightingUniform
    eye = lambda world: tuple(view.camera.view[:3, :3] @ np.asarray(world, np.float64) + view.camera.view[:3, 3])  # noqa: E731
    under, beside = eye((0.1, 0.0, -0.1)), eye((2.0, 0.0, 2.0))
    assert lu.visibilities(under) == ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    assert lu.visibilities(beside) == ((1.0, 1.0, 1.0), (1.0, 1.0, 1.0))
    for P in (under, beside):
        assert lu.visibilities(P) == tuple(tuple(light_visibility(lu, j, P)) for j in range(2))
    assert lighting.uniform(view.camera.view).visibilities(under) == ()


# ------------------------------------------------------------------ 6. the fast and the reference path

def depth_only(varyings, uniforms, frag):
    return (0.0, 0.0, 0.0, 1.0)


def test_fast_and_reference_paths_give_the_same_bytes_with_shadows():
    """The first test's scene with a glass slab added, drawn with path="fast" and with
    path="reference": the same color and depth bytes. The shadow maps too: each drawn
    again with DrawCall(path=...) from the casters and the map's matrix gives the
    depth bytes of the map render_shadow_maps made."""
    d = unit((0.5, -1.0, 0.3))
    light = Light.directional(d, shadows=ShadowSettings(resolution=256))
    lighting = Lighting((light,), global_ambient=(AMBIENT,) * 3)
    objects = [floor(), box(translate(0.1, 1.5, -0.2)),
               box(translate(-0.8, 0.8, 0.5) @ scale(1.0, 0.1, 1.0), Material(kt=KT), "glass")]
    view = top_down()
    maps = render_shadow_maps(objects, lighting)
    lu = maps.lighting_uniform(lighting, view.camera.view)
    out = {}
    for path in ("fast", "reference"):
        fb = Framebuffer(view.n, view.n)
        for obj in objects:
            view.draw(fb, obj, lu, path=path)
        out[path] = fb
    V = visibility_from_color(out["reference"], -d[1])
    assert (V < 0.5).sum() > 100 and ((V > 0.1) & (V < 0.9)).sum() > 50    # shadows, and the glass's
    assert out["fast"].samples_color.tobytes() == out["reference"].samples_color.tobytes()
    assert out["fast"].samples_depth.tobytes() == out["reference"].samples_depth.tobytes()

    (m,) = maps.maps
    casters = casters_of(objects)
    for path in ("fast", "reference"):
        fb = Framebuffer(m.settings.resolution, m.settings.resolution)
        for c in casters:
            if c.transmission is None:
                clip = np.c_[c.positions, np.ones(len(c.positions))] @ m.matrix.T
                call = DrawCall(fb, clip, c.indices, None, None, depth_only, None, cull="none",
                                polygon_offset=m.settings.polygon_offset, path=path)
                call.run()
                assert call.path_taken == path
        assert fb.depth[::-1].tobytes() == m.depth.tobytes(), path


# ------------------------------------------------------------------ 7. polygon offset

# triangles in window coordinates on the 1/256 grid, depths exact in binary: counter-clockwise with
# the largest depth 0.4375 = 1.75·2⁻² (e = −2), the same clockwise, and one reaching 0.875 (e = −1)
TRIANGLES = {
    "ccw": np.array([(2.0, 3.0, 0.3125), (29.0, 7.5, 0.4375), (9.25, 28.0, 0.375)]),
    "cw": np.array([(9.25, 28.0, 0.375), (29.0, 7.5, 0.4375), (2.0, 3.0, 0.3125)]),
    "steep": np.array([(1.0, 30.0, 0.875), (4.5, 2.0, 0.0625), (31.0, 20.0, 0.5)]),
}


def white(varyings, uniforms, frag):
    return (1.0, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("path", ["fast", "reference"])
@pytest.mark.parametrize("factor, units", [(0.0, 0.0), (3.0, 0.0), (0.0, 1000.0), (2.5, -300.0), (-4.0, 50.0)])
@pytest.mark.parametrize("shape", sorted(TRIANGLES))
def test_polygon_offset_moves_depth_by_factor_dz_plus_units_r(shape, path, factor, units):
    """glPolygonOffset (GL 4.6 §14.6.5, the depth bias of FORMULAS §21's shadow map):
    every covered pixel's depth is the triangle's plane at the pixel centre plus
    factor·DZ + units·r, DZ = max(|∂z/∂x|, |∂z/∂y|) of the window-space plane (solved
    here from the corners) and r = 2^(e − 23) for the largest depth m·2^e, 1 ≤ m < 2.
    Stored as float32: within one float32 ulp of the exact value."""
    width = height = 32
    TRIANGLE = TRIANGLES[shape]
    clip = np.c_[TRIANGLE[:, 0] / width * 2 - 1, TRIANGLE[:, 1] / height * 2 - 1, TRIANGLE[:, 2] * 2 - 1, np.ones(3)]
    fb = Framebuffer(width, height)
    call = DrawCall(fb, clip, None, None, None, white, None, polygon_offset=(factor, units), path=path)
    call.run()
    assert call.path_taken == path

    a, b, c = np.linalg.solve(np.c_[TRIANGLE[:, :2], np.ones(3)], TRIANGLE[:, 2])    # z = a·x + b·y + c
    dz = max(abs(a), abs(b))
    e = math.floor(math.log2(TRIANGLE[:, 2].max()))
    assert e == (-1 if shape == "steep" else -2)
    offset = factor * dz + units * 2.0 ** (e - 23)
    j, i = np.mgrid[0:height, 0:width]
    z = np.clip(a * (i + 0.5) + b * (j + 0.5) + c + offset, 0.0, 1.0)
    expected = z.astype(np.float32)[::-1]            # window rows → image rows
    covered = fb.color[..., 0] == 1.0
    assert covered.sum() > 200
    stored = fb.depth[covered]
    assert (np.abs(stored - expected[covered]) <= np.spacing(expected[covered])).all(), \
        f"largest difference {np.abs(stored.astype(np.float64) - z[::-1][covered]).max():.3g}"
    assert (fb.depth[~covered] == 1.0).all()


# ------------------------------------------------------------------ 8. bad input

@pytest.mark.parametrize("make, error, match", [
    (lambda: ShadowSettings(resolution=0), ValueError, "resolution"),
    (lambda: ShadowSettings(resolution=2.5), ValueError, "resolution"),
    (lambda: ShadowSettings(pcf=-1), ValueError, "pcf"),
    (lambda: ShadowSettings(pcf=99), ValueError, "pcf"),
    (lambda: ShadowSettings(offset_factor=float("nan")), ValueError, "offset_factor"),
    (lambda: ShadowSettings(offset_units=float("inf")), ValueError, "offset_units"),
    (lambda: Light.directional((0, -1, 0), shadows="yes"), TypeError, "shadows"),
    (lambda: DrawCall(Framebuffer(4, 4), np.zeros((3, 4)), polygon_offset=(1,)), ValueError, "polygon_offset"),
    (lambda: DrawCall(Framebuffer(4, 4), np.zeros((3, 4)), polygon_offset=(1, float("nan"))), ValueError,
     "polygon_offset"),
])
def test_bad_input_is_refused_by_name(make, error, match):
    with pytest.raises(error, match=match):
        make()


# ------------------------------------------------------------------ 9. depth_texture and texture_compare

def test_depth_texture_compare_is_sampler2DShadow():
    """GLSL's texture(sampler2DShadow, (u, v, ref)) with GL_LEQUAL on a framebuffer's depth:
    at each texel centre, 1 when ref ≤ the stored depth, else 0 (outside the triangle
    the cleared depth 1); with PCF r = 1, the share of the 3×3 texels around it whose
    depth is ≥ ref, texels beyond the border counting as lit. Window rows: v up."""
    width, height = 16, 12
    tri = np.array([(1.0, 1.0, 0.25), (15.0, 4.0, 0.75), (5.0, 11.0, 0.5)])
    clip = np.c_[tri[:, 0] / width * 2 - 1, tri[:, 1] / height * 2 - 1, tri[:, 2] * 2 - 1, np.ones(3)]
    fb = Framebuffer(width, height)
    DrawCall(fb, clip, None, None, None, white, None).run()
    stored = fb.depth[::-1].astype(np.float64)          # [j, i], window row j
    inner = stored < 1.0
    assert 40 < inner.sum() < width * height - 40
    hard, soft = depth_texture(fb), depth_texture(fb, pcf=1)
    padded = np.pad(stored, 1, constant_values=np.inf)     # beyond the border: lit
    for j in range(height):
        for i in range(width):
            u, v, s = (i + 0.5) / width, (j + 0.5) / height, stored[j, i]
            assert texture_compare(hard, u, v, s) == 1.0
            above = np.nextafter(np.float32(s), np.float32(2.0))
            assert texture_compare(hard, u, v, float(above)) == 0.0
            assert texture_compare(hard, u, v, s - 1e-3) == 1.0
            share = (padded[j:j + 3, i:i + 3] >= s).mean()
            assert texture_compare(soft, u, v, s) == pytest.approx(share, abs=1e-12)
    with pytest.raises(ValueError, match="pcf"):
        depth_texture(fb, pcf=5)
