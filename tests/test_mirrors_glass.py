"""Mirrors and glass across both renderers: Fresnel in the ray tracer, rays from the rasterizer's shaders,
Hall's global terms from an environment, and the falloff on shadow rays (FORMULAS §13, §15–§21).

Every expected value is a formula evaluated here: Fresnel's R_s, R_p (§20) and Snell's law (§17) in numpy, at
flat faces where N is exact; a rasterized picture whose mirrors and glasses trace their rays is compared with
the ray tracer's picture of the same scene, pixel by pixel.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import softpipe as sp
from softpipe.light.material import MEDIA, Light, Lighting, Material
from softpipe.light.shadowmap import ShadowSettings
from softpipe.pipeline.transforms import orthographic, rotate, scale, translate
from softpipe.rays.queries import RayScene, ray_visibility
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh
from softpipe.scenes.environment_pass import render_with_environments
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import primary_visibility, ray_tree, raytrace_scene

DARK = dict(ka=0.0, kd=0.0, ks=0.0)
GLOW = (0.2, 0.5, 0.9)
BACKGROUND = (0.05, 0.1, 0.15, 1.0)
GLASS = MEDIA["glass"]


def fresnel_reflectance(c1, n1, n2):
    """F_R = (R_s + R_p)/2 from n1 into n2 at cos θ₁ = c1 (§20), 1 beyond the critical angle (§19)."""
    s2 = (n1 / n2) ** 2 * (1.0 - c1 * c1)
    if s2 >= 1.0:
        return 1.0
    c2 = math.sqrt(1.0 - s2)
    rs = ((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)) ** 2
    rp = ((n1 * c2 - n2 * c1) / (n1 * c2 + n2 * c1)) ** 2
    return (rs + rp) / 2.0


def snell(d, N, n1, n2):
    """The refracted unit direction of unit d meeting a surface of unit normal N (against d), from n1 into n2."""
    c1 = -d @ N
    eta = n1 / n2
    c2 = math.sqrt(1.0 - eta * eta * (1.0 - c1 * c1))
    return eta * d + (eta * c1 - c2) * N


def slab_scene(program, material, eye=(0.0, 3.0, 3.0)):
    """A slab 0.5 thick (top at y = 0) drawn with ``program``, over a floor glowing GLOW; a 9×9 picture whose
    middle pixel looks at the origin, obliquely."""
    slab = shapes.cube(1.0, material=material)
    floor = shapes.plane(40.0, material=Material(ke=GLOW, **DARK))
    camera = sp.Camera(eye=eye, target=(0.0, 0.0, 0.0), fovy=30.0, near=0.5, far=50.0)
    return Scene([SceneObject("slab", slab, translate(0.0, -0.25, 0.0) @ scale(8.0, 0.5, 8.0), program=program),
                  SceneObject("floor", floor, translate(0.0, -1.5, 0.0), program="phong")],
                 camera=camera, lights=(), ambient=(0.0, 0.0, 0.0), background=BACKGROUND, width=9, height=9,
                 cull="none")


# ------------------------------------------------------------------ the ray tracer's glass and mirror

def test_the_tracers_glass_splits_each_ray_by_fresnel_at_both_faces():
    """``glass`` in the ray tracer, as the rasterized program: at the top face F_R(θ₁) of the ray is reflected
    and (1 − F_R)·kt refracted (§20, air into glass); at the bottom face, leaving, F_R(θ_t) from glass into
    air is reflected back inside and (1 − F_R)·kt goes on. The weights are the formulas', the directions
    Snell's law's."""
    kt = np.array((0.9, 0.8, 0.7))
    scene = slab_scene("glass", Material(**DARK, kt=tuple(kt), ior="glass"))
    tree = ray_tree(scene, 4, 4)
    primary = tree[0]
    d = np.array(primary.direction)
    up = np.array((0.0, 1.0, 0.0))
    F1 = fresnel_reflectance(-d @ up, 1.0, GLASS)
    assert 0.04 < F1 < 0.1
    children = {n.kind: n for n in tree if n.parent == 0}
    assert set(children) == {"reflected", "refracted"}
    np.testing.assert_allclose(children["reflected"].weight, (F1,) * 3, rtol=1e-12)
    np.testing.assert_allclose(children["refracted"].weight, (1 - F1) * kt, rtol=1e-12)
    T = snell(d, up, 1.0, GLASS)
    np.testing.assert_allclose(children["refracted"].direction, T, atol=1e-12)
    np.testing.assert_allclose(children["reflected"].direction, d * (1, -1, 1), atol=1e-12)
    inside = children["refracted"]
    F2 = fresnel_reflectance(-T @ up, GLASS, 1.0)        # at the bottom face: cos θ = −T·(+y), +y against T
    below = {n.kind: n for n in tree if n.parent == inside.index}
    np.testing.assert_allclose(below["reflected"].weight, (1 - F1) * kt * F2, rtol=1e-12)
    np.testing.assert_allclose(below["refracted"].weight, (1 - F1) * kt * (1 - F2) * kt, rtol=1e-12)
    np.testing.assert_allclose(below["refracted"].direction, d, atol=1e-12)   # out parallel to itself
    assert below["refracted"].object == "floor"


def test_the_tracers_glass_sends_everything_to_reflection_beyond_the_critical_angle():
    """Seen from inside (the camera under the slab's top, looking up steeply past the critical angle of glass,
    41.1°): F_R = 1 (§19), one ray, along R, of the full weight."""
    scene = slab_scene("glass", Material(**DARK, kt=(1.0, 1.0, 1.0), ior="glass"), eye=(0.0, -0.1, 3.0))
    scene = scene.replace(camera=sp.Camera(eye=(0.0, -0.1, 0.0), target=(0.0, 0.0, -1.0), fovy=30.0, near=0.01,
                                           far=50.0))
    tree = ray_tree(scene, 4, 4)
    d = np.array(tree[0].direction)
    assert -d @ np.array((0.0, -1.0, 0.0)) < math.cos(math.radians(41.2))      # beyond the critical angle
    children = [n for n in tree if n.parent == 0]
    assert [n.kind for n in children] == ["total internal reflection"]
    np.testing.assert_allclose(children[0].weight, (1.0, 1.0, 1.0))


def test_the_tracers_mirror_reflects_kr_and_refracts_nothing():
    kr = (0.9, 0.7, 0.5)
    scene = slab_scene("mirror", Material(**DARK, kr=kr, kt=(0.5, 0.5, 0.5)))
    tree = ray_tree(scene, 4, 4)
    children = [n for n in tree if n.parent == 0]
    assert [n.kind for n in children] == ["reflected"]
    np.testing.assert_allclose(children[0].weight, kr)


# ------------------------------------------------------------------ rays from the rasterizer's shaders

def hybrid_scene():
    """A floor, a mirror ball, a glass ball and a Hall ball with kr and kt; a sun whose shadows both renderers
    take from shadow rays, so the only differences left are where the two sample the surfaces differently."""
    floor = shapes.plane(12.0, material=Material(ka=0.3, kd=(0.7, 0.7, 0.6), ks=0.1, shininess=10.0))
    mirror = shapes.uv_sphere(0.7, 48, 24, material=Material(kd=0.05, ks=0.5, shininess=80.0, kr=(0.85, 0.85, 0.8)))
    glass = shapes.uv_sphere(0.6, 48, 24, material=Material(ka=0.0, kd=0.0, ks=0.5, shininess=100.0,
                                                            kt=(0.9, 0.95, 0.9), ior="glass"))
    hall = shapes.uv_sphere(0.5, 48, 24, material=Material(ka=0.1, kd=(0.3, 0.1, 0.1), ks=0.3, shininess=40.0,
                                                           kr=(0.3, 0.3, 0.3), kt=(0.4, 0.4, 0.5), ior=1.3))
    sun = Light.directional((0.4, -1.0, -0.5), shadows=ShadowSettings(method="ray"))
    return Scene([SceneObject("floor", floor, np.eye(4)),
                  SceneObject("mirror", mirror, translate(-1.0, 0.7, 0.0), program="mirror"),
                  SceneObject("glass", glass, translate(0.6, 0.6, 0.8), program="glass"),
                  SceneObject("hall", hall, translate(0.9, 0.5, -1.0), program="hall")],
                 camera=sp.Camera(eye=(0.0, 2.0, 5.0), target=(0.0, 0.5, 0.0), fovy=40.0), lights=(sun,),
                 ambient=(0.2, 0.2, 0.2), background=(0.5, 0.6, 0.8, 1.0), width=64, height=48)


def test_a_rasterized_mirror_glass_and_hall_ball_tracing_their_rays_is_the_ray_tracers_picture():
    """render_with_environments(scene, "rays"): every fragment of the three balls traces its reflected and
    refracted rays through the scene (softpipe.tracers.whitted.trace_ray), so each pixel is the ray tracer's tree with
    the rasterized fragment as its root. Equal within 1/255 except where the two renderers see different
    surfaces: within a pixel of an object's silhouette (the rasterizer samples a triangle's interpolated P and
    N, the tracer the ray's hit)."""
    scene = hybrid_scene()
    raster = render_with_environments(scene, "rays").to_uint8(alpha=False).astype(int)
    traced = raytrace_scene(scene).to_uint8(alpha=False).astype(int)
    differ = np.abs(raster - traced).max(axis=-1) > 1
    objects, _, _ = primary_visibility(scene)
    padded = np.pad(objects, 1, mode="edge")
    near_edge = np.zeros_like(differ)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_edge |= padded[1 + dy:1 + dy + objects.shape[0], 1 + dx:1 + dx + objects.shape[1]] != objects
    balls = np.isin(objects, [1, 2, 3])
    assert balls.sum() > 300
    assert not np.any(differ & ~near_edge), np.argwhere(differ & ~near_edge)[:10]
    assert differ.sum() <= 0.02 * differ.size
    # and it is not the environment's picture: the mirror shows the floor, which the sky gradient does not have
    sky = render_with_environments(scene, None).to_uint8(alpha=False).astype(int)
    assert np.abs(sky - raster)[balls & ~near_edge].max() > 40


def test_render_with_environments_names_what_it_takes():
    with pytest.raises(ValueError, match="'rays'"):
        render_with_environments(hybrid_scene(), "ray")


# ------------------------------------------------------------------ Hall's global terms from an environment

SIZE = 16


TILT = rotate(35.0, (1.0, 0.3, 0.0)) @ rotate(90.0, (1.0, 0.0, 0.0))        # a plane turned toward the camera


def draw_hall_plane(material, environment, eye=(0.5, 0.3, 4.0), with_environment=True):
    """A flat Hall plane (N exact) under an orthographic camera (V exact): (color, covered, N, V, front) in world."""
    camera = sp.Camera(eye=eye, target=(0.0, 0.0, 0.0))
    fb = sp.Framebuffer(SIZE, SIZE).clear((0.0, 0.0, 0.0, 0.0))
    uniforms = {"projection": orthographic(-1, 1, -1, 1, 1.0, 10.0)}
    if with_environment:
        uniforms["environment"] = environment
    draw_mesh(fb, shapes.plane(2.0, material=material), camera, "hall", model=TILT,
              lighting=Lighting([], global_ambient=(0.0, 0.0, 0.0)), cull="none", uniforms=uniforms)
    N = TILT[:3, :3] @ np.array([0.0, 1.0, 0.0])
    V = camera.view[:3, :3].T @ np.array([0.0, 0.0, 1.0])              # toward the eye, world space
    front = N @ V > 0
    return fb.color, fb.color[..., 3] > 0, (N if front else -N), V, front


def expect(color, covered, rgb):
    assert covered.sum() > 50
    np.testing.assert_allclose(color[covered][:, :3], np.broadcast_to(np.float32(rgb), (covered.sum(), 3)),
                               rtol=2e-6, atol=1e-7)


def test_halls_reflection_of_other_surfaces_alone_is_kr_times_the_environment_in_r(environment):
    """§13's k_r·I_r·F_s with I_r = env(R), R = 2(N·V)N − V (§16); the environment far away in clear air."""
    kr = np.array((0.9, 0.6, 0.3))
    color, covered, N, V, _ = draw_hall_plane(Material(**DARK, kr=tuple(kr)), environment)
    R = 2 * (N @ V) * N - V
    expect(color, covered, kr * np.array(environment.sample(R))[:3])


def test_halls_transmission_of_other_surfaces_alone_is_kt_times_the_environment_in_t(environment):
    """§13's k_t·I_t·F_t with I_t = env(T), T by Snell's law (§17) from air into ior 1.3, computed here."""
    kt = np.array((0.2, 0.7, 0.9))
    color, covered, N, V, front = draw_hall_plane(Material(**DARK, kt=tuple(kt), ior=1.3), environment)
    assert front
    T = snell(-V, N, 1.0, 1.3)
    assert np.degrees(np.arccos(-T @ N)) < np.degrees(np.arccos(V @ N)) - 5      # bent toward the normal
    expect(color, covered, kt * np.array(environment.sample(T))[:3])


def test_hall_seen_from_inside_beyond_the_critical_angle_reflects_kt_as_well(environment):
    """The plane's back face, seen from the denser side (η = ior = 1.52) at 70° from its normal: total internal
    reflection (§19), so k_t's share comes along R too: (k_r + k_t)·env(R)."""
    kr, kt = np.array((0.1, 0.2, 0.3)), np.array((0.5, 0.4, 0.3))
    N_front = TILT[:3, :3] @ np.array([0.0, 1.0, 0.0])
    side = np.cross(N_front, (1.0, 0.0, 0.0))
    side /= np.linalg.norm(side)
    toward_eye = -math.cos(math.radians(70.0)) * N_front + math.sin(math.radians(70.0)) * side
    color, covered, N, V, front = draw_hall_plane(Material(**DARK, kr=tuple(kr), kt=tuple(kt), ior="glass"),
                                                  environment, eye=tuple(4.0 * toward_eye))
    assert not front and GLASS * math.sqrt(1 - (N @ V) ** 2) > 1.0
    R = 2 * (N @ V) * N - V
    expect(color, covered, (kr + kt) * np.array(environment.sample(R))[:3])


def test_hall_without_an_environment_or_a_tracer_is_its_local_terms(environment):
    """§13 with nothing to see: the global terms are 0 (k_r = 0, "a Phong-like local model")."""
    color, covered, _, _, _ = draw_hall_plane(Material(**DARK, kr=(1.0, 1.0, 1.0), kt=(1.0, 1.0, 1.0)),
                                              environment, with_environment=False)
    expect(color, covered, (0.0, 0.0, 0.0))


# ------------------------------------------------------------------ the falloff on shadow rays

def slab_between(material, thickness=0.5):
    slab = SceneObject("slab", shapes.cube(1.0, material=material), scale(6.0, thickness, 6.0))
    return RayScene([slab]).uniform()


@pytest.mark.parametrize("falloff", ["power", "glassner"])
def test_a_shadow_ray_through_glass_keeps_kt_times_the_falloff_over_its_path_inside(falloff):
    """V = kt·T^d (or kt/(1 + a·d), §15) for a shadow ray that crosses d of the glass (§21); from a point inside
    it, d is the way out; a ray that misses the slab keeps 1."""
    kt, T, a = np.array((0.9, 0.8, 0.7)), np.array((0.5, 0.7, 0.9)), 2.0
    scene = slab_between(Material(kt=tuple(kt), transmittance=tuple(T), falloff=falloff, falloff_a=a))

    def fall(d):
        return T ** d if falloff == "power" else np.full(3, 1.0 / (1.0 + a * d))

    up = (0.0, 1.0, 0.0)
    np.testing.assert_allclose(ray_visibility(scene, (0.0, -2.0, 0.0), up, np.inf), kt * fall(0.5), rtol=1e-9)
    slanted = np.array((0.6, 0.8, 0.0))
    np.testing.assert_allclose(ray_visibility(scene, (0.0, -2.0, 0.0), tuple(slanted), np.inf),
                               kt * fall(0.5 / 0.8), rtol=1e-9)
    np.testing.assert_allclose(ray_visibility(scene, (0.0, 0.1, 0.0), up, np.inf), kt * fall(0.15), rtol=1e-9)
    np.testing.assert_allclose(ray_visibility(scene, (10.0, -2.0, 0.0), up, np.inf), np.ones(3))


def test_clear_glass_shadow_rays_are_as_before():
    """T = 1 (the default): kt once per object, whatever the distance inside."""
    scene = slab_between(Material(kt=(0.9, 0.8, 0.7)), thickness=3.0)
    assert ray_visibility(scene, (0.0, -5.0, 0.0), (0.0, 1.0, 0.0), np.inf) == (0.9, 0.8, 0.7)
