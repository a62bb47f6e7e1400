"""Material, Light, Lighting: validation, uniforms, and packing lights into eye space."""
import math

import numba
import numpy as np
import pytest

from softpipe.light.material import Light, Lighting, LightingUniform, Material, MaterialUniform, pack_lights
from softpipe.light.packed import (
    LIGHT_AMBIENT,
    LIGHT_ATTENUATION,
    LIGHT_COLUMNS,
    LIGHT_DIFFUSE,
    LIGHT_KIND,
    LIGHT_POSITION,
    LIGHT_SPECULAR,
    LIGHT_SPOT_COS_CUTOFF,
    LIGHT_SPOT_DIRECTION,
    LIGHT_SPOT_EXPONENT,
)


def look_at(eye, target, up):
    """A world → eye view matrix built here with numpy (the eye looks down −Z)."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    M = np.eye(4)
    M[0, :3], M[1, :3], M[2, :3] = s, u, -f
    M[:3, 3] = -M[:3, :3] @ eye
    return M


VIEW = look_at((3.0, 2.0, 5.0), (0.0, 0.5, 0.0), (0.0, 1.0, 0.0))


# --- Material -------------------------------------------------------------

def test_material_loader_keywords_still_work():
    m = Material(ke=(0, 0, 0), ka=0.1, kd=(0.8, 0.2, 0.1), ks=(0.5, 0.5, 0.5), shininess=50,
                 ior=1.45, opacity=0.5, diffuse_texture="wood.png", name="wood")
    assert m.ka == (0.1, 0.1, 0.1) and m.kd == (0.8, 0.2, 0.1) and m.shininess == 50.0
    assert m.diffuse_texture == "wood.png" and m.name == "wood" and m.roughness == 0.3


@pytest.mark.parametrize("kwargs,error,message", [
    (dict(kd=(-0.1, 0, 0)), ValueError, r"^Material\.kd must hold numbers >= 0, got float -0\.1 in a tuple of 3$"),
    (dict(ks=(math.inf, 0, 0)), ValueError, r"^Material\.ks must hold finite numbers, got float inf in a tuple of 3$"),
    (dict(ka=(1, 2)), ValueError, r"^Material\.ka must be a number \(gray\), an array \[r, g, b\] or a color name "
                                  r"such as \"red\", got a tuple of 2$"),
    (dict(ke=[None, 0, 0]), TypeError, r"^Material\.ke must be an array \[r, g, b\] of numbers, got None in an "
                                       r"array of 3$"),
    (dict(kd=np.array([1.0, 2.0])), ValueError, r"Material\.kd must be a number \(gray\).*got an array of shape \(2,\)"),
    (dict(ke="reed"), ValueError, "^Material.ke must be a color: unknown color 'reed'"),  # softpipe.core.colors
    (dict(shininess=-1), ValueError, "^Material.shininess must be a number >= 0, got integer -1$"),
    (dict(shininess=math.nan), ValueError, "^Material.shininess must be a finite number, got float nan$"),
    (dict(ior=0), ValueError, "^Material.ior must be a positive number, got integer 0$"),
    (dict(opacity=1.5), ValueError, r"Material.opacity must be in \[0, 1\]"),
    (dict(roughness=0.0), ValueError, "^Material.roughness must be a positive number, got float 0.0$"),
    (dict(roughness="rough"), TypeError, "^Material.roughness must be a positive number, got string 'rough'$"),
])
def test_material_validation_names_the_field(kwargs, error, message):
    with pytest.raises(error, match=message):
        Material(**kwargs)


def test_material_uniform_is_numba_friendly_and_one_type():
    a = Material(kd=(0.8, 0.1, 0.1), shininess=10).__softpipe_uniform__()
    b = Material(kd=1, ks=0, shininess=0, roughness=0.5, ior=1.5).__softpipe_uniform__()
    assert isinstance(a, MaterialUniform)
    assert a.kd == (0.8, 0.1, 0.1) and b.kd == (1.0, 1.0, 1.0) and b.roughness == 0.5
    for field in ("ke", "ka", "kd", "ks", "kr", "kt"):
        assert all(type(c) is float for c in getattr(b, field))
    assert numba.typeof(a) == numba.typeof(b)  # every material: one compiled kernel


# --- Light validation ------------------------------------------------------

@pytest.mark.parametrize("make,error,message", [
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=120), ValueError,
     r"^Light.cutoff must be in \[0, 90\] degrees or exactly 180, got 120$"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=-5), ValueError, "Light.cutoff must be in"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=math.nan), ValueError, "Light.cutoff must be in"),
    (lambda: Light.spot((0, 0, 0), (0, 0, -1), cutoff=30, exponent=-1), ValueError,
     "^Light.exponent must be a number >= 0, got integer -1$"),
    (lambda: Light.spot((0, 0, 0), (0, 0, 0), cutoff=30), ValueError,
     "Light.spot_direction must not be the zero vector"),
    (lambda: Light("spot", position=(0, 0, 0), cutoff=30), ValueError, "Light.spot_direction is required"),
    (lambda: Light.directional((0, 0, 0)), ValueError, "Light.direction must not be the zero vector"),
    (lambda: Light.directional((0, math.nan, 1)), ValueError,
     "^Light.direction must hold finite numbers, got float nan in a tuple of 3$"),
    (lambda: Light.point((0, 0, 0), diffuse=(1, -1, 1)), ValueError,
     "^Light.diffuse must hold numbers >= 0, got integer -1 in a tuple of 3$"),
    (lambda: Light.point((0, 0, 0), specular=math.inf), ValueError,
     "^Light.specular must be a finite number, got float inf$"),
    (lambda: Light.point((0, 0, 0), ambient=(1, 1)), ValueError,
     r"^Light.ambient must be a number \(gray\), an array \[r, g, b\] or a color name .* got a tuple of 2$"),
    (lambda: Light.point((0, 0, math.inf)), ValueError,
     "^Light.position must hold finite numbers, got float inf in a tuple of 3$"),
    (lambda: Light.point([0, 0]), ValueError, r"^Light.position must be an array of 3 numbers, got an array of 2$"),
    (lambda: Light.point("origin"), TypeError, r"^Light.position must be an array of 3 numbers, got string 'origin'$"),
    (lambda: Light.point((0, 0, 0), attenuation=(1, -0.1, 0)), ValueError,
     r"^Light.attenuation must hold numbers >= 0, got float -0.1 in a tuple of 3$"),
    (lambda: Light.point((0, 0, 0), attenuation=(0, 0, 0)), ValueError, "Light.attenuation must not be all zero"),
    (lambda: Light.point((0, 0, 0), attenuation=(1, 0)), ValueError,
     r"^Light.attenuation must be an array of 3 numbers \(a, b, c\), got a tuple of 2$"),
    (lambda: Light.point((0, 0, 0), attenuation=1), TypeError,
     r"^Light.attenuation must be an array of 3 numbers \(a, b, c\), got integer 1$"),
    (lambda: Light.directional((0, -1, 0), attenuation=(1, 0, 1)), ValueError,
     "Light.attenuation does not apply to directional lights"),
    (lambda: Light("area", position=(0, 0, 0)), ValueError,
     "Light.kind must be one of 'directional', 'point', 'spot', got 'area'"),
    (lambda: Light(3, position=(0, 0, 0)), TypeError, "Light.kind must be a string"),
    (lambda: Light("point"), ValueError, "Light.position is required for a point light"),
    (lambda: Light("directional", position=(0, 0, 0), direction=(0, 0, -1)), ValueError,
     "Light.position does not apply to a directional light"),
    (lambda: Light("point", position=(0, 0, 0), direction=(0, 0, -1)), ValueError,
     "Light.direction applies only to directional lights"),
    (lambda: Light.point((0, 0, 0), cutoff=30), ValueError, "apply only to spot lights"),
])
def test_light_validation_names_the_field(make, error, message):
    with pytest.raises(error, match=message):
        make()


@pytest.mark.parametrize("cutoff", [0, 45.5, 90, 180])
def test_light_valid_cutoffs(cutoff):
    assert Light.spot((0, 0, 0), (0, 0, -1), cutoff=cutoff).cutoff == float(cutoff)


def test_light_gray_colors_and_defaults():
    light = Light.point((1, 2, 3), diffuse=0.5)
    assert light.diffuse == (0.5, 0.5, 0.5) and light.ambient == (0.0, 0.0, 0.0)
    assert light.specular == (1.0, 1.0, 1.0) and light.attenuation == (1.0, 0.0, 0.0)
    assert light.cutoff == 180.0 and light.exponent == 0.0


# --- packing into eye space ------------------------------------------------

def test_pack_lights_layout_and_eye_space():
    point = Light.point((1.0, 4.0, -2.0), ambient=(0.1, 0.2, 0.3), diffuse=(0.4, 0.5, 0.6),
                        specular=(0.7, 0.8, 0.9), attenuation=(1.0, 0.5, 0.25))
    sun = Light.directional((1.0, -2.0, 0.5))
    spot = Light.spot((0.0, 3.0, 0.0), (0.2, -1.0, 0.1), cutoff=25.0, exponent=8.0)
    rows = pack_lights([point, sun, spot], VIEW)
    assert rows.shape == (3, LIGHT_COLUMNS) == (3, 22)
    assert rows.dtype == np.float64 and rows.flags.c_contiguous
    assert rows[:, LIGHT_KIND].tolist() == [1.0, 0.0, 2.0]

    np.testing.assert_array_equal(rows[0, LIGHT_AMBIENT:LIGHT_AMBIENT + 3], (0.1, 0.2, 0.3))
    np.testing.assert_array_equal(rows[0, LIGHT_DIFFUSE:LIGHT_DIFFUSE + 3], (0.4, 0.5, 0.6))
    np.testing.assert_array_equal(rows[0, LIGHT_SPECULAR:LIGHT_SPECULAR + 3], (0.7, 0.8, 0.9))
    np.testing.assert_array_equal(rows[0, LIGHT_ATTENUATION:LIGHT_ATTENUATION + 3], (1.0, 0.5, 0.25))

    # positions: p_eye = VIEW @ (p, 1), w = 1
    np.testing.assert_allclose(rows[0, LIGHT_POSITION:LIGHT_POSITION + 4], VIEW @ (1.0, 4.0, -2.0, 1.0), atol=1e-14)
    np.testing.assert_allclose(rows[2, LIGHT_POSITION:LIGHT_POSITION + 4], VIEW @ (0.0, 3.0, 0.0, 1.0), atol=1e-14)

    # directional: w = 0, xyz = unit vector toward the light = −(travel direction), rotated into eye space
    toward = VIEW[:3, :3] @ -np.array((1.0, -2.0, 0.5))
    np.testing.assert_allclose(rows[1, LIGHT_POSITION:LIGHT_POSITION + 3], toward / np.linalg.norm(toward), atol=1e-14)
    assert rows[1, LIGHT_POSITION + 3] == 0.0
    np.testing.assert_array_equal(rows[1, LIGHT_ATTENUATION:LIGHT_ATTENUATION + 3], (1.0, 0.0, 0.0))

    # spot: S rotated and normalized, cos β, e; the others are "not a spot"
    S = VIEW[:3, :3] @ np.array((0.2, -1.0, 0.1))
    np.testing.assert_allclose(rows[2, LIGHT_SPOT_DIRECTION:LIGHT_SPOT_DIRECTION + 3], S / np.linalg.norm(S), atol=1e-14)
    assert rows[2, LIGHT_SPOT_COS_CUTOFF] == pytest.approx(math.cos(math.radians(25.0)), abs=1e-15)
    assert rows[2, LIGHT_SPOT_EXPONENT] == 8.0
    assert rows[0, LIGHT_SPOT_COS_CUTOFF] == rows[1, LIGHT_SPOT_COS_CUTOFF] == -1.0


def test_light_at_the_eye_packs_to_the_origin():
    # Eye space: the eye is at the origin, so a light at the camera gives L = V = normalize(−P).
    row = Light.point((3.0, 2.0, 5.0)).pack(VIEW)
    np.testing.assert_allclose(row[LIGHT_POSITION:LIGHT_POSITION + 4], (0.0, 0.0, 0.0, 1.0), atol=1e-14)


def test_directions_stay_unit_under_a_scaled_view():
    scaled = VIEW.copy()
    scaled[:3, :] *= 2.0
    row = Light.directional((0.0, -1.0, 0.0)).pack(scaled)
    assert np.linalg.norm(row[LIGHT_POSITION:LIGHT_POSITION + 3]) == pytest.approx(1.0, abs=1e-15)


def test_special_cutoffs_pack_exactly():
    rows = pack_lights([Light.spot((0, 0, 0), (0, 0, -1), cutoff=c) for c in (0, 90, 180)], np.eye(4))
    assert rows[:, LIGHT_SPOT_COS_CUTOFF].tolist() == [1.0, 0.0, -1.0]


def test_pack_no_lights():
    rows = pack_lights([], np.eye(4))
    assert rows.shape == (0, 22) and rows.dtype == np.float64


@pytest.mark.parametrize("view,message", [
    (np.eye(3), "view_matrix must be 4×4"),
    (np.full((4, 4), np.nan), "view_matrix must be finite"),
    (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, -1, 0]]), "view_matrix must be affine"),
])
def test_pack_rejects_bad_view_matrices(view, message):
    with pytest.raises(ValueError, match=message):
        pack_lights([Light.point((0, 0, 0))], view)


def test_pack_rejects_non_lights():
    with pytest.raises(TypeError, match=r"lights\[1\] must be a Light"):
        pack_lights([Light.point((0, 0, 0)), "lamp"], np.eye(4))


# --- Lighting --------------------------------------------------------------

def test_lighting_container():
    lights = [Light.point((0, 5, 0)), Light.directional((0, -1, 0)), Light.point((2, 0, 0))]
    lighting = Lighting(lights)
    assert lighting.global_ambient == (0.2, 0.2, 0.2)  # OpenGL's default light-model ambient
    u = lighting.uniform(VIEW)
    assert isinstance(u, LightingUniform)
    assert u.global_ambient == (0.2, 0.2, 0.2)
    np.testing.assert_array_equal(u.lights, pack_lights(lights, VIEW))
    assert Lighting(global_ambient=0.05).uniform(VIEW).lights.shape == (0, 22)


def test_lighting_validation():
    with pytest.raises(TypeError, match=r"Lighting.lights\[0\] must be a Light"):
        Lighting([(0, 0, 0)])
    with pytest.raises(ValueError, match="^Lighting.global_ambient must be a number >= 0, got integer -1$"):
        Lighting(global_ambient=-1)
