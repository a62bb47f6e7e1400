"""The lit programs, pixel against formula (FORMULAS §1–§14, §26).

Each test renders a scene in which N, L and V at a pixel are known — a large
plane facing the camera, or a sphere centred on the view axis — and compares the
pixel with the formula, evaluated here independently with numpy/math (never by
calling softpipe.light.lighting). The framebuffer holds float32, so the tolerance is
1e-5 relative to the formula.
"""
import math

import numpy as np
import pytest
from conftest import tilt

import softpipe as sp
from softpipe.light.material import Light, Lighting, Material
from softpipe.light.texture import Texture2D
from softpipe.pipeline.camera import Camera
from softpipe.programs import PROGRAMS, Program, cook_torrance, flat, get_program, gooch, gouraud, hall, phong, textured  # noqa: F401
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh, standard_uniforms
from softpipe.scenes.mesh import Mesh

RTOL, ATOL = 1e-5, 1e-6
BLACK = (0.0, 0.0, 0.0)
PLANE_Z = -5.0


# --------------------------------------------------------------------------------- scenes

class OrthoCamera:
    """A parallel projection looking down −z with the identity view: world = eye space.

    Every view ray is along −z, so V = (0, 0, 1) at every pixel.
    """

    def __init__(self, half=1.0, near=1.0, far=20.0):
        self.half, self.near, self.far = half, near, far
        self.view = np.eye(4)

    def projection(self, aspect):
        h = self.half
        return sp.orthographic(-h * aspect, h * aspect, -h, h, self.near, self.far)

    def point(self, i, j, size, z=PLANE_Z):
        """The eye-space point on the plane z = ``z`` seen at pixel column i, row j (row 0 = top)."""
        h = self.half
        return np.array([((i + 0.5) / size * 2 - 1) * h, (1 - (j + 0.5) / size * 2) * h, z])


ORTHO = OrthoCamera()


def quad(half=2.0, z=PLANE_Z, normal=(0.0, 0.0, 1.0), material=None):
    """A square in the plane z = const, facing +z (counter-clockwise seen from +z)."""
    s = half
    positions = [(-s, -s, z), (s, -s, z), (s, s, z), (-s, s, z)]
    return Mesh(positions, [[0, 1, 2], [0, 2, 3]], normals=[normal] * 4, material=material or Material())


def render(mesh, lights=(), material=None, program="phong", size=16, camera=ORTHO, global_ambient=BLACK,
           extra=None, **state):
    """Draw one mesh with ``program`` and the given lights and material; the float RGBA image."""
    fb = sp.Framebuffer(size, size)
    uniforms = {"lighting": Lighting(tuple(lights), global_ambient).uniform(camera.view)}
    if material is not None:
        uniforms["material"] = material
    uniforms.update(extra or {})
    draw_mesh(fb, mesh, camera, program, uniforms=uniforms, **state)
    return fb.color.astype(np.float64)


def plane_pixels(lights, material, program="phong", size=16, global_ambient=BLACK, **kw):
    """Render the plane z = −5 under the orthographic camera: (image, P per pixel)."""
    img = render(quad(), lights, material, program, size, ORTHO, global_ambient, **kw)
    jj, ii = np.mgrid[0:size, 0:size]
    P = np.stack([ORTHO.point(i, j, size) for i, j in zip(ii.ravel(), jj.ravel())]).reshape(size, size, 3)
    return img, P


def close(got, expected):
    np.testing.assert_allclose(np.asarray(got, float), np.asarray(expected, float), rtol=RTOL, atol=ATOL)


# --------------------------------------------------------------- the formulas, independently

def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def dot3(a, b):
    return np.sum(np.asarray(a) * np.asarray(b), axis=-1, keepdims=True)


def light_vectors(light, P, view=np.eye(4)):
    """(L, f_att · f_spot) of a Light at eye-space points P [..., 3] (FORMULAS §7–§9)."""
    M = np.asarray(view)
    if light.kind == "directional":
        L = unit(M[:3, :3] @ -np.asarray(light.direction))
        return np.broadcast_to(L, P.shape), np.ones(P.shape[:-1] + (1,))
    position = M[:3, :3] @ np.asarray(light.position) + M[:3, 3]
    to_light = position - P
    r = np.linalg.norm(to_light, axis=-1, keepdims=True)
    L = to_light / r
    a, b, c = light.attenuation
    f = 1.0 / (a + b * r + c * r * r)
    if light.kind == "spot":
        S = unit(M[:3, :3] @ np.asarray(light.spot_direction))
        cos_angle = dot3(-L, S)
        inside = cos_angle >= math.cos(math.radians(light.cutoff))
        f = f * np.where(inside, np.maximum(cos_angle, 0.0) ** light.exponent, 0.0)
    return L, f


def opengl_reference(P, N, V, m, lights, global_ambient=BLACK, specular="blinn", view=np.eye(4)):
    """FORMULAS §10: I = ke + ka·Ia + Σ f_att·f_spot·[ka·Ia,j + B·(kd·Id·(N·L) + ks·Is·spec)]."""
    P = np.asarray(P, float)
    N = np.broadcast_to(N, P.shape)
    V = np.broadcast_to(V, P.shape)
    color = np.asarray(m.ke) + np.asarray(m.ka) * global_ambient + np.zeros(P.shape)
    for light in lights:
        L, f = light_vectors(light, P, view)
        n_dot_l = dot3(N, L)
        B = (n_dot_l > 0).astype(float)
        if specular == "blinn":
            spec = np.maximum(dot3(N, unit(L + V)), 0.0) ** m.shininess
        else:
            R = 2 * n_dot_l * N - L
            spec = np.maximum(dot3(R, V), 0.0) ** m.shininess
        term = (np.multiply(m.ka, light.ambient)
                + B * (np.multiply(m.kd, light.diffuse) * n_dot_l + np.multiply(m.ks, light.specular) * spec))
        color = color + f * term
    return color


UP = np.array([0.0, 0.0, 1.0])   # the plane's N, and V under the orthographic camera


def sun(toward_light, **kw):
    """A directional light whose L is ``toward_light`` (it travels the other way)."""
    return Light.directional(tuple(-np.asarray(toward_light, float)), **kw)


# --------------------------------------------------------------------- §1, §2: emission, ambient

def test_emission_only():
    ke = (0.3, 0.1, 0.25)
    m = Material(ke=ke, ka=0, kd=0, ks=0)
    img, _ = plane_pixels([sun(UP), Light.point((0, 0, 0), ambient=0.5)], m, global_ambient=(0.4, 0.4, 0.4))
    close(img[..., :3], np.broadcast_to(ke, img[..., :3].shape))
    close(img[..., 3], 1.0)


def test_ambient_only():
    ka, ga, ia = (0.2, 0.4, 0.6), (0.5, 0.25, 0.1), (0.3, 0.2, 0.1)
    m = Material(ka=ka, kd=0, ks=0)
    # global ambient, plus a light's own ambient, attenuated at distance 2 (f_att = 1/(1 + 0.5·2))
    light = Light.point((0.0, 0.0, PLANE_Z + 2.0), ambient=ia, diffuse=0, specular=0, attenuation=(1, 0.5, 0))
    img, P = plane_pixels([], m, global_ambient=ga)
    close(img[..., :3], np.broadcast_to(np.multiply(ka, ga), P.shape))
    img, P = plane_pixels([light], m, global_ambient=ga)
    r = np.linalg.norm(P - light.position, axis=-1, keepdims=True)
    close(img[..., :3], np.multiply(ka, ga) + np.multiply(ka, ia) / (1 + 0.5 * r))
    close(img[8, 8, :3], np.multiply(ka, ga) + np.multiply(ka, ia) / (1 + 0.5 * math.dist(P[8, 8], light.position)))


# --------------------------------------------------------------------------- §3, §4: diffuse and B

@pytest.mark.parametrize("theta", [0.0, 30.0, 60.0, 85.0])
def test_diffuse_at_angles(theta):
    kd, Id = (0.8, 0.5, 0.2), (1.0, 0.9, 0.5)
    m = Material(ka=0, kd=kd, ks=0)
    img, _ = plane_pixels([sun(tilt(theta, 35.0), diffuse=Id)], m)
    expected = np.multiply(kd, Id) * math.cos(math.radians(theta))   # kd·Id·(N·L), FORMULAS §3
    close(img[..., :3], np.broadcast_to(expected, img[..., :3].shape))


@pytest.mark.parametrize("theta", [95.0, 135.0, 180.0])
@pytest.mark.parametrize("program", ["phong", "phong_phong_specular", "gouraud", "flat"])
def test_b_cuts_off_light_from_below(theta, program):
    # Shininess 0 makes the specular lobe 1 wherever B = 1; B = 0 must remove it too (§4).
    ka, ia = (0.1, 0.2, 0.3), (0.5, 0.5, 0.5)
    m = Material(ka=ka, kd=0.9, ks=0.9, shininess=0.0)
    img, _ = plane_pixels([sun(tilt(theta, 20.0), ambient=ia)], m, program)
    close(img[..., :3], np.broadcast_to(np.multiply(ka, ia), img[..., :3].shape))
    # the same light turned to 180° − theta, above the surface, does light it
    lit, _ = plane_pixels([sun(tilt(180.0 - theta + 1e-9, 20.0), ambient=ia)], m, program)
    assert np.all(lit[..., :3] > img[..., :3] + 0.5)


# ----------------------------------------------------------------- §5, §6: Phong vs Blinn-Phong

@pytest.mark.parametrize("theta", [0.0, 20.0, 40.0])
def test_phong_and_blinn_phong_highlight_on_the_sphere_centre(theta):
    # A sphere centred on the view axis: at its central pixel (a vertex of the sphere, on the axis)
    # N = V = (0, 0, 1). With L at theta: R·V = cos θ (Phong) and N·H = cos(θ/2) (Blinn-Phong).
    n, ks, Is = 30.0, (0.6, 0.5, 0.4), (1.0, 1.0, 0.8)
    m = Material(ka=0, kd=0, ks=ks, shininess=n)
    # rings=12: ring 6 is the equator, and its vertex at θ = 0 is on the +z axis
    sphere = shapes.uv_sphere(radius=0.8, segments=24, rings=12).transformed(sp.translate(0, 0, PLANE_Z))
    light = [sun(tilt(theta, 0.0), specular=Is)]
    size, c = 33, 16                                               # odd: pixel 16's centre is on the axis
    blinn = render(sphere, light, m, "phong", size)[c, c, :3]
    phong_ = render(sphere, light, m, "phong_phong_specular", size)[c, c, :3]
    t = math.radians(theta)
    close(blinn, np.multiply(ks, Is) * math.cos(t / 2) ** n)
    close(phong_, np.multiply(ks, Is) * math.cos(t) ** n)
    if theta > 0:
        assert np.all(blinn > phong_)    # the same n gives Blinn-Phong the wider highlight


@pytest.mark.parametrize("path", ["reference", "fast"])
@pytest.mark.parametrize("specular,program", [("blinn", "phong"), ("phong", "phong_phong_specular")])
def test_highlight_across_the_plane(specular, program, path):
    # A point light above the plane: L (and so H, R) changes from pixel to pixel.
    # Both of the pipeline's paths (shade every fragment, or only the visible ones) agree.
    m = Material(ka=0.1, kd=(0.3, 0.2, 0.1), ks=(0.7, 0.7, 0.6), shininess=25.0)
    light = Light.point((0.3, -0.2, PLANE_Z + 1.5), ambient=0.2)
    img, P = plane_pixels([light], m, program, size=24, global_ambient=(0.1, 0.1, 0.1), path=path)
    close(img[..., :3], opengl_reference(P, UP, UP, m, [light], (0.1, 0.1, 0.1), specular))


def test_perspective_camera_uses_v_toward_the_eye():
    # A plane filling a perspective view exactly: V = normalize(−P) changes across it.
    size, fovy, d = 24, 50.0, 3.0
    cam = Camera(eye=(0.0, 0.0, d), target=(0.0, 0.0, 0.0), fovy=fovy, near=0.5, far=10.0)
    half = d * math.tan(math.radians(fovy) / 2)
    plane = Mesh([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)], [[0, 1, 2], [0, 2, 3]],
                 normals=[(0, 0, 1)] * 4)
    m = Material(ka=0.05, kd=(0.5, 0.4, 0.3), ks=(0.8, 0.8, 0.8), shininess=12.0)
    lights = [Light.point((0.4, 0.3, 1.0), attenuation=(1, 0.1, 0.05)), sun((0.3, 0.5, 1.0), diffuse=0.3)]
    for program, specular in (("phong", "blinn"), ("phong_phong_specular", "phong")):
        img = render(plane, lights, m, program, size, cam, global_ambient=(0.2, 0.2, 0.2))
        jj, ii = np.mgrid[0:size, 0:size]
        ndc = np.stack([(ii + 0.5) / size * 2 - 1, 1 - (jj + 0.5) / size * 2], -1)
        P = np.concatenate([ndc * half, np.full((size, size, 1), -d)], -1)   # eye space: the plane is at z = −d
        close(img[..., :3], opengl_reference(P, UP, unit(-P), m, lights, (0.2, 0.2, 0.2), specular, cam.view))


# -------------------------------------------------------------------------- §7: attenuation

@pytest.mark.parametrize("r", [0.5, 1.0, 2.0, 4.0])
def test_attenuation_at_distances(r):
    a, b, c = 1.0, 0.3, 0.2
    kd, Id = (0.9, 0.6, 0.3), (1.0, 1.0, 1.0)
    m = Material(ka=0, kd=kd, ks=0)
    size, i = 16, 8
    p = ORTHO.point(i, i, size)                                 # the light straight above this pixel
    light = Light.point(tuple(p + (0, 0, r)), diffuse=Id, attenuation=(a, b, c))
    img, P = plane_pixels([light], m, size=size)
    close(img[i, i, :3], np.multiply(kd, Id) / (a + b * r + c * r * r))   # N·L = 1 there
    close(img[..., :3], opengl_reference(P, UP, UP, m, [light]))


def test_directional_lights_are_not_attenuated():
    m = Material(ka=0, kd=0.5, ks=0)
    img, _ = plane_pixels([sun(UP)], m)
    close(img[..., :3], 0.5)


# ----------------------------------------------------------------------------- §8: spotlight

@pytest.mark.parametrize("cutoff,exponent", [(20.0, 0.0), (35.0, 4.0), (90.0, 1.0)])
def test_spot_cone_edge(cutoff, exponent):
    size, h = 32, 1.0
    m = Material(ka=0, kd=(0.8, 0.8, 0.8), ks=0)
    spot = Light.spot((0.05, -0.03, PLANE_Z + h), (0.0, 0.0, -1.0), cutoff, exponent)
    img, P = plane_pixels([spot], m, size=size)
    close(img[..., :3], opengl_reference(P, UP, UP, m, [spot]))
    # inside the cone lit, outside dark; the angle from the axis decides
    angle = np.degrees(np.arctan2(np.hypot(P[..., 0] - 0.05, P[..., 1] + 0.03), h))
    inside, outside = angle < cutoff - 0.5, angle > cutoff + 0.5
    assert inside.any() and (outside.any() or cutoff == 90.0)
    assert np.all(img[inside][:, 0] > 0.0)
    assert np.all(img[outside][:, :3] == 0.0)
    if cutoff < 90:
        # the pixels on either side of the edge along row 16: just inside lit, just outside dark
        row = angle[16]
        k = int(np.argmax(row < cutoff))                        # first pixel inside, from the left
        assert img[16, k, 0] > 0 and img[16, k - 1, 0] == 0


# ------------------------------------------------------------------------- §10: several lights

def test_several_lights_add_up():
    m = Material(ke=(0.01, 0.02, 0.03), ka=0.1, kd=(0.6, 0.5, 0.4), ks=0.5, shininess=20)
    ga = (0.2, 0.2, 0.2)
    lights = [sun(tilt(30, 10), diffuse=(1.0, 0.8, 0.6), ambient=0.1),
              Light.point((-0.5, 0.4, PLANE_Z + 1.0), diffuse=(0.2, 0.4, 1.0), attenuation=(1, 0, 0.5)),
              Light.spot((0.3, 0.3, PLANE_Z + 2.0), (0, 0, -1), 25.0, 2.0, specular=(1, 0.5, 0.5))]
    together, P = plane_pixels(lights, m, global_ambient=ga)
    close(together[..., :3], opengl_reference(P, UP, UP, m, lights, ga))
    # each light alone, without the terms outside the sum, adds up to the whole
    base, _ = plane_pixels([], m, global_ambient=ga)
    alone = [plane_pixels([light], m, global_ambient=ga)[0] - base for light in lights]
    close(together[..., :3], base[..., :3] + sum(a[..., :3] for a in alone))


# ------------------------------------------------------------- §12: flat, Gouraud and Phong shading

def _window(points, size, half=1.0):
    """Window coordinates (x right, y up) of eye-space points under ORTHO, snapped to 1/256 pixel."""
    w = (np.asarray(points)[:, :2] / half + 1) / 2 * size
    return np.rint((w - 0.5) * 256) / 256 + 0.5


def _barycentrics(tri_xy, p):
    a, b, c = tri_xy
    area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    w0 = ((b[0] - p[0]) * (c[1] - p[1]) - (b[1] - p[1]) * (c[0] - p[0])) / area
    w1 = ((c[0] - p[0]) * (a[1] - p[1]) - (c[1] - p[1]) * (a[0] - p[0])) / area
    return np.array([w0, w1, 1 - w0 - w1])


def test_gouraud_misses_the_highlight_inside_a_triangle_phong_does_not():
    size = 48
    sphere = shapes.icosphere(radius=0.9, subdivisions=1).transformed(sp.translate(0, 0, PLANE_Z))
    # a front triangle near the middle; put the highlight (N = H) at its centre: L = V mirrored about c
    tri = sphere.indices
    normals = sphere.normals[tri]                          # [M, 3, 3], unit (the icosphere's)
    c = unit(normals.mean(axis=1))
    k = int(np.argmin(np.where(c[:, 2] > 0, np.linalg.norm(c - unit((0.25, 0.3, 1.0)), axis=1), 9)))
    H = c[k]
    L = 2 * H @ UP * H - UP
    n, ks = 150.0, (0.9, 0.9, 0.9)
    m = Material(ka=0, kd=(0.3, 0.1, 0.1), ks=ks, shininess=n)
    light = [sun(L)]
    phong_img = render(sphere, light, m, "phong", size)
    gouraud_img = render(sphere, light, m, "gouraud", size)
    # the pixel nearest the triangle's centre, and the exact interpolation weights there
    corners = sphere.positions[tri[k]]
    xy = _window(corners, size)
    px, py = np.floor(xy.mean(axis=0)).astype(int)
    row, col = size - 1 - py, px
    b = _barycentrics(xy, (px + 0.5, py + 0.5))
    assert np.all(b > 0.05)                                # well inside the triangle
    # Phong: interpolate the normals, renormalize, light (§12)
    N = unit(b @ normals[k])
    expected_phong = opengl_reference(np.zeros(3), N, UP, m, light)
    close(phong_img[row, col, :3], expected_phong)
    # Gouraud: light the three vertices, interpolate the (clamped) colors
    vertex_colors = np.clip([opengl_reference(p, nv, UP, m, light) for p, nv in zip(corners, normals[k])], 0, 1)
    close(gouraud_img[row, col, :3], b @ vertex_colors)
    # the lesson: the highlight is there with Phong shading, and missed by Gouraud's
    assert phong_img[row, col, 1] > 0.8
    assert gouraud_img[row, col, 1] < 0.1
    assert phong_img[..., 1].max() > 0.8 > 0.3 > gouraud_img[..., 1].max()


def _id_fragment(varyings, uniforms, frag):
    return (float(frag.primitive_id), 0.0, 0.0, 1.0)


@pytest.mark.parametrize("program", ["flat", "flat_phong_specular"])
def test_flat_gives_one_color_per_face(program):
    size = 40
    mesh = shapes.icosphere(radius=0.9, subdivisions=1).transformed(sp.translate(0, 0, PLANE_Z)).flat_shaded()
    m = Material(ka=0.1, kd=(0.7, 0.5, 0.3), ks=0.5, shininess=10)
    lights = [Light.point((1.0, 1.5, PLANE_Z + 3.0)), sun((0.2, -0.5, 1.0), diffuse=0.3)]
    img = render(mesh, lights, m, program, size, global_ambient=(0.2, 0.2, 0.2))
    # which face covers each pixel: the same draw with a fragment shader that writes the primitive id
    ids = sp.Framebuffer(size, size).clear((-1, 0, 0, 1))
    uniforms = {"lighting": Lighting(tuple(lights)).uniform(np.eye(4)), "material": m}
    draw_mesh(ids, mesh, ORTHO, Program("ids", get_program(program).vertex, _id_fragment), uniforms=uniforms)
    face = ids.color[..., 0].astype(int)
    seen = np.unique(face[face >= 0])
    assert len(seen) >= 15
    specular = "blinn" if program == "flat" else "phong"
    for f in seen:
        colors = img[face == f][:, :3]
        assert np.all(colors == colors[0]), f"face {f} has {len(np.unique(colors, axis=0))} colors"
        # the color is the face normal's, lit at the provoking (last) vertex
        v = mesh.indices[f, 2]
        expected = opengl_reference(mesh.positions[v], unit(mesh.normals[v]), UP, m, lights, (0.2, 0.2, 0.2),
                                    specular)
        close(colors[0], np.clip(expected, 0, 1))
    # and the faces differ from one another: faceted
    assert len(np.unique(img[face >= 0][:, :3], axis=0)) > 0.9 * len(seen)


def test_gouraud_and_phong_agree_where_the_surface_is_flat():
    m = Material(ka=0.1, kd=(0.5, 0.6, 0.7), ks=0.3, shininess=5)
    lights = [sun(tilt(40, 60), ambient=0.1)]
    a, _ = plane_pixels(lights, m, "phong")
    b, _ = plane_pixels(lights, m, "gouraud")
    close(a, b)


def test_two_sided_lighting_of_a_back_face():
    # seen from behind with culling off, the plane is lit as if its normal faced the viewer
    m = Material(ka=0, kd=0.8, ks=0)
    back = quad(normal=(0.0, 0.0, -1.0))
    back = back.replace(indices=back.indices[:, ::-1])           # clockwise seen from +z: a back face
    img = render(back, [sun(tilt(60))], m, "phong", cull="none")
    close(img[..., :3], 0.8 * 0.5)


# ------------------------------------------------------------------------- §13, §14: Hall

def test_hall_local_terms_on_the_plane():
    m = Material(ke=0.5, ka=(0.1, 0.2, 0.3), kd=(0.6, 0.5, 0.4), ks=(0.3, 0.3, 0.3), shininess=15,
                 kt=(0.4, 0.4, 0.4), ior=1.5)
    ga = (0.2, 0.2, 0.2)
    above = Light.point((0.2, 0.1, PLANE_Z + 1.2), ambient=0.1)
    img, P = plane_pixels([above], m, "hall", global_ambient=ga)
    # §13 has no emission: the same as §10 without ke
    close(img[..., :3], opengl_reference(P, UP, UP, m, [above], ga) - 0.5)


@pytest.mark.parametrize("theta", [0.0, 15.0])
def test_hall_transmission_of_a_light_behind_the_surface(theta):
    # A light behind the plane shines through it (kt, n′) and not by diffuse or reflection (B = 0).
    kt, nt, eta = (0.4, 0.5, 0.6), 8.0, 1.5
    m = Material(ka=0, kd=0.9, ks=0.9, kt=kt, transmission_shininess=nt, ior=eta)
    L = -np.array(tilt(theta, 0.0))                                    # toward the light: below the plane
    img, _ = plane_pixels([sun(L, specular=(1.0, 0.8, 0.6))], m, "hall")
    # H′ is the facet normal that refracts the light's ray (travelling −L, in the medium η) into V (air):
    # Snell's law says it is parallel to η·L + V (Walter et al. 2007), oriented to the light's side.
    Ht = unit(eta * L + UP)
    Ht = Ht if Ht @ L > 0 else -Ht
    lobe = max(-(UP @ Ht), 0.0) ** nt
    if theta == 0.0:
        assert lobe == pytest.approx(1.0)                       # straight through: H′ = −N
    close(img[8, 8, :3], np.multiply(kt, (1.0, 0.8, 0.6)) * lobe)


# -------------------------------------------------------------------------- §26: Cook-Torrance

def _fresnel(cos_i, n1, n2):
    sin_t = n1 / n2 * math.sqrt(1 - cos_i ** 2)
    cos_t = math.sqrt(1 - sin_t ** 2)
    rs = ((n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)) ** 2
    rp = ((n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i)) ** 2
    return (rs + rp) / 2


@pytest.mark.parametrize("theta,roughness", [(0.0, 0.3), (30.0, 0.2), (60.0, 0.5)])
def test_cook_torrance_on_the_plane(theta, roughness):
    kd, ks, ior = (0.3, 0.2, 0.1), (0.9, 0.8, 0.7), 1.8
    m = Material(ke=(0.01, 0, 0), ka=0.1, kd=kd, ks=ks, ior=ior, roughness=roughness)
    L = np.array(tilt(theta, 45.0))
    img, _ = plane_pixels([sun(L, ambient=0.2)], m, "cook_torrance", global_ambient=(0.1, 0.1, 0.1))
    N = V = UP
    H = unit(L + V)
    nl, nv, nh, vh = N @ L, N @ V, N @ H, V @ H
    alpha = math.acos(min(nh, 1.0))
    D = math.exp(-math.tan(alpha) ** 2 / roughness ** 2) / (math.pi * roughness ** 2 * nh ** 4)
    G = min(1.0, 2 * nh * nv / vh, 2 * nh * nl / vh)
    F = _fresnel(vh, 1.0, ior)
    fs = D * G * F / (4.0 * nl * nv)            # FORMULAS §26, normalized
    expected = (np.array((0.01, 0, 0)) + 0.1 * 0.1 + 0.1 * 0.2
                + nl * (np.asarray(kd) + np.asarray(ks) * fs))
    close(img[8, 8, :3], expected)
    close(img[..., :3], np.broadcast_to(expected, img[..., :3].shape))


# ---------------------------------------------------------------------------------- Gooch

@pytest.mark.parametrize("theta", [0.0, 70.0, 120.0, 180.0])
def test_gooch_on_the_plane(theta):
    kd = (0.6, 0.2, 0.4)
    m = Material(kd=kd)
    L = np.array(tilt(theta, 30.0))
    img, _ = plane_pixels([sun(L)], m, "gooch")
    t = (1 + UP @ L) / 2                                         # FORMULAS §26, paper's constants
    k_cool = np.array((0, 0, 0.4)) + 0.2 * np.asarray(kd)
    k_warm = np.array((0.4, 0.4, 0)) + 0.6 * np.asarray(kd)
    close(img[8, 8, :3], t * k_warm + (1 - t) * k_cool)
    # every tuning uniform is optional; given, it is used
    tuned, _ = plane_pixels([sun(L)], m, "gooch", extra={
        "gooch_blue": (0.0, 0.1, 0.5), "gooch_yellow": (0.5, 0.3, 0.0), "gooch_alpha": 0.4, "gooch_beta": 0.3})
    k_cool = np.array((0, 0.1, 0.5)) + 0.4 * np.asarray(kd)
    k_warm = np.array((0.5, 0.3, 0)) + 0.3 * np.asarray(kd)
    close(tuned[8, 8, :3], t * k_warm + (1 - t) * k_cool)


def test_gooch_outline_marks_the_silhouette():
    sphere = shapes.uv_sphere(radius=0.9, segments=32, rings=16).transformed(sp.translate(0, 0, PLANE_Z))
    m = Material(kd=(0.8, 0.8, 0.8))
    extra = {"gooch_outline": 0.3, "gooch_outline_color": (1.0, 0.0, 1.0)}
    img = render(sphere, [sun(UP)], m, "gooch", 48, extra=extra)
    rim = np.all(img[..., :3] == (1.0, 0.0, 1.0), axis=-1)
    plain = render(sphere, [sun(UP)], m, "gooch", 48)
    assert rim.sum() > 50 and not rim[24, 24]
    assert not np.all(plain[..., :3] == (1.0, 0.0, 1.0), axis=-1).any()
    # the rim is where the surface turns away: far from the centre
    jj, ii = np.nonzero(rim)
    assert np.hypot(ii + 0.5 - 24, jj + 0.5 - 24).min() > 0.8 * 0.9 / 1.0 * 24


# -------------------------------------------------------------------------------- textured

def test_textured_scales_ambient_and_diffuse_by_the_texel():
    texels = np.array([[[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]],
                       [[0.0, 0.0, 1.0, 1.0], [1.0, 1.0, 1.0, 0.5]]], dtype=np.float32)
    tex = Texture2D(texels, filter="nearest", wrap="clamp")
    plane = quad(half=1.0)
    plane = plane.replace(uvs=[(0, 0), (1, 0), (1, 1), (0, 1)])
    m = Material(ke=0.05, ka=0.2, kd=(0.8, 0.6, 0.4), ks=(0.3, 0.3, 0.3), shininess=10, opacity=0.8)
    ga = (0.5, 0.5, 0.5)
    light = sun(tilt(30, 0), ambient=0.1)
    img = render(plane, [light], m, "textured", 16, global_ambient=ga, extra={"texture": tex})
    P = np.stack([[ORTHO.point(i, j, 16) for i in range(16)] for j in range(16)])
    # the image's top-left texel (row 0) is at u < ½, v > ½: the top-left quarter of the picture
    for (rows, cols), texel in (((slice(0, 8), slice(0, 8)), texels[0, 0]), ((slice(0, 8), slice(8, 16)), texels[0, 1]),
                                ((slice(8, 16), slice(0, 8)), texels[1, 0]), ((slice(8, 16), slice(8, 16)), texels[1, 1])):
        t = texel[:3].astype(float)
        scaled = Material(ke=0.05, ka=tuple(0.2 * t), kd=tuple(np.multiply((0.8, 0.6, 0.4), t)), ks=0.3, shininess=10)
        close(img[rows, cols, :3], opengl_reference(P[rows, cols], UP, UP, scaled, [light], ga))
        close(img[rows, cols, 3], texel[3] * 0.8)


def test_textured_is_mipmapped_through_the_uv_derivatives():
    # A one-texel checkerboard 256 texels wide over 16 pixels: 16 texels per pixel, λ = log2 16 = 4.
    # Level 4 of its mip pyramid is uniform gray 0.5; sampling level 0 would give 0 or 1 instead.
    checker = (np.indices((256, 256)).sum(axis=0) % 2).astype(np.float32)
    tex = Texture2D(checker, filter="trilinear")
    plane = quad(half=1.0).replace(uvs=[(0, 0), (1, 0), (1, 1), (0, 1)])
    m = Material(ka=0, kd=0.8, ks=0)
    img = render(plane, [sun(UP)], m, "textured", 16, extra={"texture": tex})
    close(img[..., :3], 0.8 * 0.5)


# ------------------------------------------------------------------- every program, and errors

LIT = ["flat", "flat_phong_specular", "gouraud", "gouraud_phong_specular", "phong", "phong_phong_specular",
       "hall", "cook_torrance", "gooch", "textured"]


@pytest.mark.parametrize("program", LIT)
def test_every_program_renders_a_small_sphere(program):
    sphere = shapes.uv_sphere(radius=0.8, segments=12, rings=6).transformed(sp.translate(0, 0, PLANE_Z))
    if program.startswith("flat"):
        sphere = sphere.flat_shaded()
    m = Material(kd=(0.7, 0.4, 0.2), ks=0.5, ior=1.5)
    extra = {"texture": Texture2D(np.full((4, 4, 3), 0.5, np.float32))} if program == "textured" else {}
    img = render(sphere, [sun((0.3, 0.4, 1.0)), Light.point((0, 1, PLANE_Z + 2))], m, program, 24,
                 global_ambient=(0.1, 0.1, 0.1), extra=extra)
    assert np.isfinite(img).all()
    covered = img[..., :3].sum(axis=-1) > 0
    assert 200 < covered.sum() < 24 * 24
    assert img[12, 12, :3].max() > 0.1


def test_programs_are_registered_with_descriptions():
    for name in LIT:
        prog = get_program(name)
        assert prog.name == name and prog.description
        assert PROGRAMS[name] is prog


def test_unknown_program_name_is_an_error():
    fb = sp.Framebuffer(8, 8)
    with pytest.raises(ValueError, match=r"unknown shading program 'phongg'.*phong"):
        draw_mesh(fb, quad(), ORTHO, "phongg")


@pytest.mark.parametrize("program", ["gouraud", "phong"])
def test_missing_lighting_uniform_names_it(program):
    fb = sp.Framebuffer(8, 8)
    prog, mesh = get_program(program), quad()
    uniforms = standard_uniforms(ORTHO, 1.0)
    uniforms["material"] = Material()
    with pytest.raises(sp.ShaderError, match="lighting"):
        sp.draw(fb, mesh.positions, mesh.indices, vertex_shader=prog.vertex, fragment_shader=prog.fragment,
                uniforms=uniforms, attributes={"normal": mesh.normals})


@pytest.mark.parametrize("make,field", [
    (lambda: Material(kd=(0.5, -0.1, 0.2)), "Material.kd"),
    (lambda: Material(ka=math.nan), "Material.ka"),
    (lambda: Material(ks=(1, math.inf, 1)), "Material.ks"),
    (lambda: Material(shininess=-1.0), "Material.shininess"),
    (lambda: Material(shininess=math.nan), "Material.shininess"),
    (lambda: Material(ior=math.inf), "Material.ior"),
    (lambda: Material(roughness=0.0), "Material.roughness"),
    (lambda: Light.point((0, 0, 0), diffuse=(-1, 0, 0)), "Light.diffuse"),
    (lambda: Light.point((0, math.nan, 0)), "Light.position"),
    (lambda: Light.point((0, 0, 0), attenuation=(1, -0.5, 0)), "Light.attenuation"),
    (lambda: Light.point((0, 0, 0), attenuation=(1, 0, math.inf)), "Light.attenuation"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=120.0), "Light.cutoff"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=-5.0), "Light.cutoff"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=math.nan), "Light.cutoff"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=30.0, exponent=-2.0), "Light.exponent"),
    (lambda: Lighting([], global_ambient=(0.1, -0.1, 0.1)), "Lighting.global_ambient"),
])
def test_bad_material_and_light_values_name_the_field(make, field):
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        make()
