"""The full Hall model in the ray tracer (FORMULAS §13, §15), §11's two-sided program, the named media (§17).

Every expected value is the formula evaluated here, at pixels where every vector is known: a mirror floor
reflecting a glowing square (k_r·I_r·T_r^{d_r}, d_r from the mirror geometry worked out here), a glass slab over
a glowing floor (k_t·I_t·T_t^{d_t}, d_t from Snell's law and the slab's thickness; and with Glassner's
1/(1 + a·d)), §11's c = ρ_d·L_a + Σ (ρ_d + ρ_s(N·H))·L_i·V_i·|N·L_i| at the middle of a plane facing the
camera, with a light in front and one behind.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import softpipe as sp
from softpipe.light.lighting import two_sided_lighting
from softpipe.light.material import MEDIA, Light, Lighting, Material, falloff_factor
from softpipe.pipeline.transforms import scale, translate
from softpipe.programs import PROGRAMS
from softpipe.rays.queries import medium_falloff
from softpipe.scenes import shapes
from softpipe.scenes.scene import Scene, SceneObject
from softpipe.tracers.whitted import PROGRAM_CODES, ray_tree, raytrace_scene

DARK = dict(ka=0.0, kd=0.0, ks=0.0)                     # no local terms: only the global ones show
GLOW = (0.2, 0.5, 0.9)
BACKGROUND = (0.05, 0.1, 0.15, 1.0)


def _primary_rays(camera, width, height):
    """(origin, direction) of every pixel's primary ray, worked out here (§23, through the near and far planes)."""
    unproject = np.linalg.inv(camera.projection(width / height) @ camera.view)
    for j in range(height):
        for i in range(width):
            x, y = 2 * (i + 0.5) / width - 1, 1 - 2 * (j + 0.5) / height
            near, far = (unproject @ (x, y, z, 1.0) for z in (-1.0, 1.0))
            o = near[:3] / near[3]
            d = far[:3] / far[3] - o
            yield i, j, o, d / np.linalg.norm(d)


# ------------------------------------------------------------------ k_r·I_r·F_s·T_r^{d_r}

def mirror_scene(kr, air=None):
    """A Hall mirror floor (kr only) and, 2 above it, a square glowing ke = GLOW (phong: §10's k_e), facing down."""
    mirror = shapes.plane(20.0, material=Material(**DARK, kr=kr))
    glow = shapes.plane(2.0, material=Material(ke=GLOW, **DARK))
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    camera = sp.Camera(eye=(0.0, 1.0, 6.0), target=(0.0, 0.0, 0.0), fovy=50.0, near=0.5, far=50.0)
    return Scene([SceneObject("mirror", mirror, np.eye(4), program="hall"),
                  SceneObject("glow", glow, translate(0.0, 2.0, -2.0) @ flip, program="phong")],
                 camera=camera, lights=(), ambient=(0.0, 0.0, 0.0), background=BACKGROUND, width=64, height=48,
                 cull="none")


@pytest.mark.parametrize("air", [1.0, (0.8, 0.9, 0.6)])
def test_reflection_of_other_surfaces_alone_is_kr_times_ir_times_t_to_the_d(air):
    """Only Hall's k_r·I_r·F_s·T_r^{d_r} on (kr = k_r·F_s, RGB): where the mirror direction R = reflect(d, N)
    (§16) meets the square, the pixel is kr·k_e·T^{d_r}, d_r the distance from the mirror point to the square
    along R, T air's (1: clear; or a hazy air, per channel). Where R misses everything, kr × the background (a
    ray that meets nothing has no falloff)."""
    kr = np.array((0.9, 0.7, 0.5))
    T = np.broadcast_to(np.asarray(air, float), 3)
    scene = mirror_scene(tuple(kr))
    fb = raytrace_scene(scene, air_transmittance=air)
    checked = on_square = 0
    for i, j, o, d in _primary_rays(scene.camera, scene.width, scene.height):
        if d[1] >= 0:
            continue
        P = o + (-o[1] / d[1]) * d                              # on the mirror, y = 0
        R = d * (1.0, -1.0, 1.0)                                # reflect(d, (0, 1, 0))
        d_r = (2.0 - P[1]) / R[1]                               # to the square's plane, y = 2
        Q = P + d_r * R
        inside = max(abs(Q[0]), abs(Q[2] + 2.0))
        if abs(P[0]) > 10 or abs(P[2]) > 10 or abs(inside - 1.0) < 0.03:
            continue                                            # off the mirror, or within a hair of the square's edge
        if inside < 1.0:
            expected = kr * np.array(GLOW) * T ** d_r           # k_r·I_r·T_r^{d_r}, I_r = k_e
            on_square += 1
        else:
            expected = kr * np.array(BACKGROUND[:3])
        np.testing.assert_allclose(fb.color[j, i, :3], expected, rtol=1e-5, atol=1e-7)
        checked += 1
    assert checked > 1000 and on_square > 40


# ------------------------------------------------------------------ k_t·I_t·F_t·T_t^{d_t}

SLAB_THICKNESS = 0.5


def slab_scene(material, width=9, height=9, eye=(0.0, 4.0, 0.0), fovy=30.0):
    """A glass slab (hall, kt only), 0.5 thick, its top at y = 0, over a floor glowing GLOW at y = −1.5."""
    slab = shapes.cube(1.0, material=material)
    floor = shapes.plane(40.0, material=Material(ke=GLOW, **DARK))
    camera = sp.Camera(eye=eye, target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fovy=fovy, near=0.5, far=50.0)
    return Scene([SceneObject("slab", slab, translate(0.0, -SLAB_THICKNESS / 2, 0.0) @ scale(8.0, SLAB_THICKNESS, 8.0),
                              program="hall"),
                  SceneObject("floor", floor, translate(0.0, -1.5, 0.0), program="phong")],
                 camera=camera, lights=(), ambient=(0.0, 0.0, 0.0), background=BACKGROUND, width=width,
                 height=height, cull="none")


@pytest.mark.parametrize("falloff", ["power", "glassner"])
def test_transmission_of_other_surfaces_at_normal_incidence(falloff):
    """Looking straight down through the slab (the middle pixel of an odd-sized picture): the refracted ray goes
    straight through, d_t = the slab's thickness, and the pixel is kt·(kt·k_e)·T^{d_t} — Hall's k_t·I_t·T_t^{d_t}
    at the top face, whose I_t is the bottom face's k_t·I_t (air below, T = 1) — or, with Glassner's form,
    kt·kt·k_e/(1 + a·d_t) (§15)."""
    kt = np.array((0.9, 0.8, 0.95))
    T = np.array((0.5, 0.7, 0.9))
    a = 1.5
    glass = Material(**DARK, kt=tuple(kt), ior="glass", transmittance=tuple(T), falloff=falloff, falloff_a=a)
    scene = slab_scene(glass)
    pixel = raytrace_scene(scene).color[4, 4, :3]
    d = SLAB_THICKNESS
    fall = T ** d if falloff == "power" else 1.0 / (1.0 + a * d)
    np.testing.assert_allclose(pixel, kt * kt * np.array(GLOW) * fall, rtol=1e-6)
    np.testing.assert_allclose(falloff_factor(glass, d), fall * np.ones(3), rtol=1e-12)
    tree = ray_tree(scene, 4, 4)
    inside = [n for n in tree if n.kind == "refracted" and n.object == "slab"]
    assert len(inside) == 1 and inside[0].t == pytest.approx(d, rel=1e-9)
    np.testing.assert_allclose(inside[0].falloff, fall * np.ones(3), rtol=1e-9)
    assert "falloff T^d" in str(tree)


def test_transmission_of_other_surfaces_at_every_angle_follows_snell_for_d():
    """Over the whole picture: a ray entering the slab at θ_i refracts to sin θ_t = sin θ_i/1.52 (§17, glass),
    crosses d_t = thickness/cos θ_t inside and leaves parallel to itself toward the floor: every pixel is
    kt²·k_e·T^{d_t}, with d_t computed here."""
    kt = np.array((0.9, 0.9, 0.9))
    T = np.array((0.3, 0.6, 0.9))
    scene = slab_scene(Material(**DARK, kt=tuple(kt), ior=MEDIA["glass"], transmittance=tuple(T)),
                       width=24, height=24, eye=(0.0, 4.0, 0.0), fovy=60.0)
    fb = raytrace_scene(scene)
    checked = 0
    for i, j, _origin, d in _primary_rays(scene.camera, scene.width, scene.height):
        sin_i = math.hypot(d[0], d[2])
        sin_t = sin_i / 1.52
        d_t = SLAB_THICKNESS / math.sqrt(1.0 - sin_t * sin_t)
        np.testing.assert_allclose(fb.color[j, i, :3], kt * kt * np.array(GLOW) * T ** d_t, rtol=1e-6)
        checked += 1
    assert checked == 24 * 24


def test_falloff_defaults_leave_the_tracer_as_it_was():
    """T = 1 (and Glassner's a = 0) multiply by exactly 1: clear glass in clear air is unchanged (§15)."""
    assert medium_falloff((1.0, 1.0, 1.0), False, 0.0, 7.3) == (1.0, 1.0, 1.0)
    assert medium_falloff((1.0, 1.0, 1.0), True, 0.0, 7.3) == (1.0, 1.0, 1.0)
    assert medium_falloff((0.5, 0.25, 1.0), False, 0.0, 2.0) == (0.25, 0.0625, 1.0)
    assert medium_falloff((0.5, 0.5, 0.5), True, 0.5, 2.0) == (0.5, 0.5, 0.5)
    with pytest.raises(ValueError, match="air_transmittance"):
        raytrace_scene(slab_scene(Material()), air_transmittance=1.5)


# ------------------------------------------------------------------ §11, the two-sided program

def two_sided_expected(P, N, V, m: Material, ambient, lights):
    """FORMULAS §11 evaluated in numpy: ρ_d·L_a + Σ (ρ_d + k_s·(N·H)₊ⁿ)·L_i·|N·L_i|, L_i = k_l/r² (V_i = 1)."""
    kd, ks = np.array(m.kd), np.array(m.ks)
    c = kd * np.array(ambient)
    for light in lights:
        to_light = np.array(light.position) - P
        r2 = to_light @ to_light
        L = to_light / math.sqrt(r2)
        H = (L + V) / np.linalg.norm(L + V)
        rho = kd + ks * max(N @ H, 0.0) ** m.shininess
        c = c + rho * np.array(light.diffuse) / r2 * abs(N @ L)
    return c


MATTE_SHINY = Material(ka=0.3, kd=(0.5, 0.3, 0.2), ks=(0.6, 0.6, 0.6), shininess=8.0, ke=(0.4, 0.0, 0.0))
IN_FRONT = Light.point((0.6, 0.4, 2.0), diffuse=(3.0, 2.5, 2.0), attenuation=(1.0, 0.7, 0.0))
BEHIND = Light.point((-0.8, 0.3, -1.5), diffuse=(1.0, 2.0, 3.0))


def facing_plane_scene(lights, program="two_sided", kr=0.0):
    """A plane at z = 0 facing a camera on the +z axis; the middle pixel of a 9×9 picture looks at (0, 0, 0)."""
    wall = shapes.plane(4.0, material=MATTE_SHINY.replace(kr=kr))
    stand_up = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])   # +y → +z
    return Scene([SceneObject("wall", wall, stand_up, program=program)],
                 camera=sp.Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), fovy=20.0), lights=tuple(lights),
                 ambient=(0.1, 0.2, 0.3), background=(0.0, 0.0, 0.0, 1.0), width=9, height=9, cull="none")


@pytest.mark.parametrize("lights", [(IN_FRONT,), (BEHIND,), (IN_FRONT, BEHIND)], ids=["front", "behind", "both"])
def test_the_two_sided_program_is_formulas_11_at_a_pixel(lights):
    """The middle pixel (P = 0, N = V = +z) rasterized with ``two_sided`` and ray traced with it equals §11 in
    numpy: ρ_d·L_a with no k_a nor k_e, |N·L| — a light behind lights it too — the cosine on the specular lobe,
    L_i = k_l/r² (the light's attenuation coefficients are not §11's)."""
    scene = facing_plane_scene(lights)
    P, N, V = np.zeros(3), np.array((0.0, 0.0, 1.0)), np.array((0.0, 0.0, 1.0))
    expected = two_sided_expected(P, N, V, MATTE_SHINY, scene.ambient, lights)
    raster = sp.render_scene(scene).color[4, 4, :3]
    traced = raytrace_scene(scene).color[4, 4, :3]
    np.testing.assert_allclose(raster, expected, rtol=1e-4)
    np.testing.assert_allclose(traced, expected, rtol=1e-5)
    assert np.all(expected > np.array(MATTE_SHINY.kd) * scene.ambient + 1e-3)   # every light adds something


def test_the_two_sided_program_takes_v_i_from_shadow_rays():
    """V_i(p) of §11 from :func:`softpipe.light.lighting.light_visibility`: a small box between the middle point and the
    light (off the camera's line of sight) leaves ρ_d·L_a only, rasterized with shadow rays and ray traced."""
    from softpipe.light.shadowmap import ShadowSettings
    light = dataclasses.replace(IN_FRONT, shadows=ShadowSettings(method="ray"))
    scene = facing_plane_scene((light,))
    blocker = SceneObject("blocker", shapes.cube(0.1), translate(0.3, 0.2, 1.0))
    scene = scene.replace(objects=[*scene.objects, blocker])
    ambient_only = np.array(MATTE_SHINY.kd) * scene.ambient
    np.testing.assert_allclose(sp.render_scene(scene).color[4, 4, :3], ambient_only, rtol=1e-5)
    np.testing.assert_allclose(raytrace_scene(scene).color[4, 4, :3], ambient_only, rtol=1e-5)
    unblocked = raytrace_scene(facing_plane_scene((light,))).color[4, 4, :3]
    assert np.all(unblocked > ambient_only + 0.01)


def test_two_sided_is_not_formula_10_behind_and_on_the_lobe():
    """The two notes of §11: a light behind gives §10 (phong) nothing but §11 its |N·L| share; in front, §11's
    specular term carries the cosine: ks·(N·H)ⁿ·L·(N·L), not ks·(N·H)ⁿ·L."""
    P, N, V = (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)
    lighting = Lighting((BEHIND,), global_ambient=(0.0, 0.0, 0.0)).uniform(np.eye(4))
    m = MATTE_SHINY.replace(ke=0.0).__softpipe_uniform__()
    behind = np.array(two_sided_lighting(P, N, V, m, lighting))
    phong = sp.render_scene(facing_plane_scene((BEHIND,), program="phong").replace(ambient=(0, 0, 0))).color[4, 4, :3]
    np.testing.assert_allclose(phong, MATTE_SHINY.ke, atol=1e-6)          # §10: k_e only, B = 0
    assert np.all(behind > 0.01)
    light = Light.point((0.0, 1.0, 1.0), diffuse=1.0)                     # N·L = cos 45°
    lighting = Lighting((light,), global_ambient=(0.0, 0.0, 0.0)).uniform(np.eye(4))
    only_specular = Material(kd=0.0, ks=1.0, shininess=4.0).__softpipe_uniform__()
    got = two_sided_lighting(P, N, V, only_specular, lighting)
    L = np.array((0.0, 1.0, 1.0)) / math.sqrt(2)
    H = (L + V) / np.linalg.norm(L + V)
    lobe = (H @ N) ** 4 / 2.0                                              # k_l/r², r² = 2
    np.testing.assert_allclose(got, [lobe * L[2]] * 3, rtol=1e-12)         # with the cosine
    assert abs(got[0] - lobe) > 0.1 * lobe                                 # not without it


def test_the_two_sided_program_is_registered_and_the_tracer_adds_kr_trace_r():
    """``two_sided`` is a program and has its own code in the tracer; with kr it adds k_r·trace(p, R) (§11's
    next term): facing the camera head on, R = V goes back to the (black) background, so the pixel grows by
    exactly kr × background = 0 — and with a white background by kr."""
    assert "two_sided" in PROGRAMS and PROGRAM_CODES["two_sided"] not in (PROGRAM_CODES["phong"],
                                                                         PROGRAM_CODES["hall"])
    plain = raytrace_scene(facing_plane_scene((IN_FRONT,))).color[4, 4, :3]
    white = facing_plane_scene((IN_FRONT,), kr=0.25).replace(background=(1.0, 1.0, 1.0, 1.0))
    np.testing.assert_allclose(raytrace_scene(white).color[4, 4, :3], plain + 0.25, rtol=1e-6)


# ------------------------------------------------------------------ §17's named media

def test_the_named_media_are_the_notes_indices():
    assert MEDIA == {"vacuum": 1.0, "air": 1.00029, "water": 1.33, "glass": 1.52, "salt": 1.54, "sapphire": 1.77,
                     "diamond": 2.417}
    for name, n in MEDIA.items():
        assert Material(ior=name).ior == n
    assert Material(ior="Diamond").ior == 2.417
    assert Material(ior="water").replace(kd=0.1).ior == 1.33


def test_an_unknown_medium_is_a_clear_error_listing_the_names():
    with pytest.raises(ValueError, match="unknown medium 'glas'") as e:
        Material(ior="glas")
    for name in MEDIA:
        assert name in str(e.value)
    with pytest.raises(ValueError, match="Material.falloff"):
        Material(falloff="exponential")
    with pytest.raises(ValueError, match="Material.transmittance"):
        Material(transmittance=1.2)
    with pytest.raises(ValueError, match="Material.falloff_a"):
        Material(falloff="glassner", falloff_a=-1.0)


# ------------------------------------------------------------------ §14's η seen from inside

def test_the_transmitted_highlight_seen_from_inside_uses_one_over_ior():
    """FORMULAS §14: η = (far side)/(viewer's side), so a viewer inside glass (a back face, N flipped toward
    the viewer) has η = 1/ior. The viewer 25° from N inside glass (ior 1.52), a directional light placed outside
    by Snell's law (sin θ = 1.52·sin 25°, θ = 39.97°) so that its ray refracts straight toward the viewer: the
    full lobe, k_t·I_s·(−N·H′)ⁿ′ = k_t, evaluated here in numpy — rasterized with ``hall`` and ray traced (the
    middle pixel of a 3×3 picture looks along the camera's axis at the origin). With η = ior it was ~0."""
    kt, ior, n_t = np.array((0.7, 0.6, 0.5)), 1.52, 50.0
    inside = math.radians(25.0)
    outside = math.asin(ior * math.sin(inside))
    assert abs(math.degrees(outside) - 39.97) < 0.005
    V = np.array((math.sin(inside), -math.cos(inside), 0.0))     # toward the viewer, below the plane
    L = np.array((-math.sin(outside), math.cos(outside), 0.0))   # toward the light, above it, across N
    N = np.array((0.0, -1.0, 0.0))                               # the back face's normal, flipped toward V
    eta = 1.0 / ior                                              # air (far side) / glass (viewer's side)
    H = (V + eta * L) / (eta - 1.0)
    H /= np.linalg.norm(H)
    expected = kt * max(-N @ H, 0.0) ** n_t
    np.testing.assert_allclose(expected, kt, rtol=1e-12)        # Snell's placement: the full lobe
    glass = Material(ka=0.0, kd=0.0, ks=0.0, kt=tuple(kt), ior=ior, transmission_shininess=n_t)
    light = Light.directional(tuple(-L), ambient=0.0, diffuse=0.0, specular=1.0)
    scene = Scene([SceneObject("glass", shapes.plane(4.0, material=glass), np.eye(4), program="hall")],
                  camera=sp.Camera(eye=tuple(3.0 * V), target=(0.0, 0.0, 0.0), fovy=10.0), lights=(light,),
                  ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0, 1.0), width=3, height=3, cull="none")
    np.testing.assert_allclose(sp.render_scene(scene).color[1, 1, :3], expected, atol=1e-6)
    np.testing.assert_allclose(raytrace_scene(scene).color[1, 1, :3], expected, atol=1e-6)
