"""Bad input to softpipe.draw and softpipe.Framebuffer: the right exception, with a message that
names the argument and says what was expected."""
import tracemalloc

import numpy as np
import pytest

import softpipe
import softpipe.shading
from softpipe import ShaderError
from softpipe.pipeline.framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES

TRI = np.array([[-1.0, -1.0, 0.0, 1.0], [1.0, -1.0, 0.0, 1.0], [-1.0, 1.0, 0.0, 1.0]])
RGB = {"color": np.ones((3, 3))}


def draw(positions=TRI, indices=None, varyings=RGB, **kw):
    softpipe.draw(softpipe.Framebuffer(4, 4), positions, indices, varyings, **kw)


# ---------------------------------------------------------------- positions

def test_positions_with_three_columns_and_no_vertex_shader():
    with pytest.raises(ValueError, match=r"positions must have shape \[N, 4\], got \[3, 3\]"):
        draw(TRI[:, :3])


def test_positions_one_dimensional():
    with pytest.raises(ValueError, match=r"positions must have shape \[N, 4\], got \[12\]"):
        draw(TRI.reshape(-1))


def test_positions_of_strings_or_bools():
    with pytest.raises(TypeError, match=r"positions must be a numeric \(float or int\) array, got dtype <U"):
        draw(TRI.astype(str))
    with pytest.raises(TypeError, match=r"positions must be a numeric \(float or int\) array, got dtype bool"):
        draw(TRI > 0)
    with pytest.raises(TypeError, match=r"positions must be a numeric"):
        draw(TRI.astype(complex))


def test_ragged_positions():
    with pytest.raises(TypeError, match=r"positions must be a numeric array, got list"):
        draw([[0, 0, 0, 1], [1, 0, 0]])


def passthrough(attributes, uniforms):
    p = attributes.position
    return (p[0], p[1], p[2], 1.0), softpipe.shading.StandardVaryings((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))


def test_positions_with_five_columns_for_a_vertex_shader():
    with pytest.raises(ValueError, match=r"positions must have shape \[N, 2\] or \[N, 3\] or \[N, 4\], got \[3, 5\]"):
        draw(np.ones((3, 5)), varyings=None, vertex_shader=passthrough)


# ------------------------------------------------------------------ indices

def test_index_out_of_range():
    with pytest.raises(ValueError, match=r"indices\[4\] = 3 is out of range for 3 vertices"):
        draw(indices=[0, 1, 2, 0, 3, 1])


def test_negative_index():
    with pytest.raises(ValueError, match=r"indices\[1\] = -1 is out of range for 3 vertices"):
        draw(indices=[0, -1, 2])


def test_float_or_bool_indices():
    with pytest.raises(TypeError, match=r"indices must be an integer array, got dtype float64"):
        draw(indices=[0, 1, 2.0])
    with pytest.raises(TypeError, match=r"indices must be an integer array, got dtype bool"):
        draw(indices=[True, False, True])


def test_list_length_not_a_multiple_of_three():
    with pytest.raises(ValueError, match=r"a triangle list needs a multiple of 3 vertices, got 4"):
        draw(indices=[0, 1, 2, 0])
    with pytest.raises(ValueError, match=r"a triangle list needs a multiple of 3 vertices, got 2"):
        draw(TRI[:2], varyings={"color": np.ones((2, 3))})


@pytest.mark.parametrize("argument", ["indices", "positions"])
def test_list_length_error_names_the_argument(argument):
    with pytest.raises(ValueError, match=argument):
        if argument == "indices":
            draw(indices=[0, 1, 2, 0])
        else:
            draw(TRI[:2], varyings={"color": np.ones((2, 3))})


def test_indices_with_three_dimensions():
    with pytest.raises(ValueError, match=r"indices must have shape \[M\] or \[M, 3\], got \[1, 1, 3\]"):
        draw(indices=np.zeros((1, 1, 3), int))


def test_indices_of_shape_m_by_2():
    with pytest.raises(ValueError, match=r"indices must have shape \[M\] or \[M, 3\], got \[3, 2\]"):
        draw(indices=np.array([[0, 1], [2, 0], [1, 2]]))


def test_strip_indices_must_be_one_dimensional():
    with pytest.raises(ValueError, match=r"indices for a triangle_strip must be 1-D, got shape \[1, 3\]"):
        draw(indices=np.array([[0, 1, 2]]), topology="triangle_strip")


# --------------------------------------------------------- fixed-function state

def test_unknown_topology():
    with pytest.raises(ValueError, match=r"topology must be one of \('points', 'lines', 'line_strip', 'line_loop', "
                                         r"'triangles', 'triangle_strip', 'triangle_fan'\), got 'quads'"):
        draw(topology="quads")


def test_unknown_depth_compare_function():
    with pytest.raises(ValueError, match=r"depth_test must be one of \('never', 'less', .*'always'\) or None, "
                                         r"got 'less_equal'"):
        draw(depth_test="less_equal")


def test_depth_write_must_be_a_bool():
    with pytest.raises(TypeError, match=r"depth_write must be True or False, got 1"):
        draw(depth_write=1)


def test_unknown_blend_mode_and_factor():
    with pytest.raises(ValueError, match=r"blend must be None, one of \('alpha', 'additive', 'premultiplied'\), a "
                                         r"\(src, dst\) pair or a \(src_rgb, dst_rgb, src_alpha, dst_alpha\) "
                                         r"quadruple .*got 'multiply'"):
        draw(blend="multiply")
    with pytest.raises(ValueError, match=r"unknown blend factor 'src'; expected one of \('zero', 'one', "):
        draw(blend=("src", "one"))
    with pytest.raises(ValueError, match=r"blend must be None, a preset name, a \(src_factor, dst_factor\) pair or "
                                         r"a \(src_rgb, dst_rgb, src_alpha, dst_alpha\) quadruple, got \('one',\)"):
        draw(blend=("one",))


def test_unknown_cull_mode_and_front_face():
    with pytest.raises(ValueError, match=r"cull must be one of \('none', 'back', 'front'\), got 'both'"):
        draw(cull="both")
    with pytest.raises(ValueError, match=r"front_face must be one of \('ccw', 'cw'\), got 'left'"):
        draw(front_face="left")


def test_viewport_and_framebuffer_types():
    with pytest.raises(TypeError, match=r"viewport must be a softpipe.Viewport, got tuple"):
        draw(viewport=(0, 0, 4, 4))
    with pytest.raises(TypeError, match=r"framebuffer must be a softpipe.Framebuffer, got ndarray"):
        softpipe.draw(np.zeros((4, 4, 4)), TRI, varyings=RGB)


# ----------------------------------------------------------------- varyings

def test_varyings_with_the_wrong_number_of_rows():
    with pytest.raises(ValueError, match=r"varyings\['color'\] has 2 rows but positions has 3"):
        draw(varyings={"color": np.ones((2, 3))})


def test_varyings_of_the_wrong_shape_or_type():
    with pytest.raises(ValueError, match=r"varyings\['color'\] must have shape \[N, 1\] or .*\[N, 4\] or \[N\], "
                                         r"got \[3, 5\]"):
        draw(varyings={"color": np.ones((3, 5))})
    with pytest.raises(TypeError, match=r"varyings\['color'\] must be a numeric"):
        draw(varyings={"color": np.full((3, 3), "red")})
    with pytest.raises(TypeError, match=r"varyings must be a dict of name → \[N, k\] array, got list"):
        draw(varyings=[np.ones((3, 3))])
    with pytest.raises(ValueError, match=r"varying name 'my color' is not a valid Python identifier"):
        draw(varyings={"my color": np.ones((3, 3))})


def test_bad_interpolation_qualifier():
    with pytest.raises(ValueError, match=r"interpolation\['color'\] must be one of \('smooth', 'noperspective', "
                                         r"'flat'\), got 'linear'"):
        draw(interpolation={"color": "linear"})


def test_interpolation_of_an_unknown_varying():
    with pytest.raises(ValueError, match=r"interpolation names varying 'colour', but the varyings are \['color'\]"):
        draw(interpolation={"colour": "flat"})


def test_no_fragment_shader_and_no_color_varying():
    with pytest.raises(ValueError, match=r"no fragment_shader was given and there is no varying named 'color'.*"
                                         r"the varyings are \['colour'\]"):
        draw(varyings={"colour": np.ones((3, 3))})
    with pytest.raises(ValueError, match=r"no fragment_shader was given and there is no varying named 'color'"):
        draw(varyings=None)
    with pytest.raises(ValueError, match=r"the varying 'color' must be RGB or RGBA, got 2 components"):
        draw(varyings={"color": np.ones((3, 2))})


def test_no_color_varying_is_an_error_even_when_nothing_is_visible():
    with pytest.raises(ValueError, match=r"no varying named 'color'"):
        draw(TRI + [0, 0, 5, 0], varyings={"colour": np.ones((3, 3))})     # beyond the far plane


def test_attributes_without_a_vertex_shader_and_varyings_with_one():
    with pytest.raises(ValueError, match=r"attributes= are inputs of a vertex shader, but no vertex_shader"):
        draw(attributes={"normal": np.ones((3, 3))})
    with pytest.raises(ValueError, match=r"varyings= cannot be combined with a vertex_shader"):
        draw(TRI[:, :3], vertex_shader=passthrough)


# -------------------------------------------------------------- framebuffer

@pytest.mark.parametrize("w, h, exc, message", [
    (0, 4, ValueError, r"Framebuffer width must be at least 1, got 0"),
    (4, -3, ValueError, r"Framebuffer height must be at least 1, got -3"),
    (4.5, 4, TypeError, r"Framebuffer width must be an integer, got float 4.5"),
    (4.0, 4, TypeError, r"Framebuffer width must be an integer, got float 4.0"),
    (4, "4", TypeError, r"Framebuffer height must be an integer, got str '4'"),
    (True, 4, TypeError, r"Framebuffer width must be an integer, got bool True"),
])
def test_framebuffer_size_must_be_a_positive_integer(w, h, exc, message):
    with pytest.raises(exc, match=message):
        softpipe.Framebuffer(w, h)


@pytest.mark.parametrize("w, h, message", [
    (100000, 100000, rf"Framebuffer width 100000 exceeds the limit MAX_DIMENSION = {MAX_DIMENSION}"),
    (16384, 16384, rf"Framebuffer 16384×16384×1 samples = 268435456 exceeds the limit "
                   rf"MAX_TOTAL_SAMPLES = {MAX_TOTAL_SAMPLES}"),
])
def test_absurd_framebuffer_fails_before_allocating(w, h, message):
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=message):
            softpipe.Framebuffer(w, h)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20, f"{peak} bytes were allocated before the size was refused"


# ------------------------------------------------------------------ uniforms

def test_uniforms_must_be_a_dict():
    with pytest.raises(TypeError, match=r"uniforms must be a dict of name → value, got list"):
        draw(uniforms=[("gain", 1.0)])
    with pytest.raises(TypeError, match=r"uniform 'tint': cannot pass a str to a shader"):
        draw(uniforms={"tint": "red"})
    with pytest.raises(ValueError, match=r"uniform name 'a b' is not a valid Python identifier"):
        draw(uniforms={"a b": 1.0})


# ------------------------------------------------------------------- shaders

def python_helper(x):
    return 2.0 * x


def uses_python_helper(varyings, uniforms, frag):
    """A plain Python helper: compiled with the shader (issue #14)."""
    return (python_helper(0.25), 0.0, 0.0, 1.0)


def uses_a_dict(varyings, uniforms, frag):
    """Runs in Python, but a dict global cannot be compiled."""
    return (PALETTE["red"], 0.0, 0.0, 1.0)


PALETTE = {"red": 1.0}


def raises_on_the_right(varyings, uniforms, frag):
    if frag.x > 2.0:
        raise ValueError("this fragment is on the right")
    return (1.0, 0.0, 0.0, 1.0)


def returns_rgb(varyings, uniforms, frag):
    return (1.0, 0.0, 0.0)


def test_a_plain_python_helper_compiles():
    fb = softpipe.Framebuffer(4, 4)
    softpipe.draw(fb, TRI, varyings=RGB, fragment_shader=uses_python_helper)
    assert fb.color[3, 0, 0] == 0.5


def test_fragment_shader_numba_cannot_compile():
    with pytest.raises(ShaderError, match=r"fragment shader test_errors\.uses_a_dict cannot be compiled: "
                                          r"the global 'PALETTE' \(a dict\) cannot be used in compiled code\n"
                                          r'  File ".*test_errors\.py", line \d+, in uses_a_dict\n'
                                          r'    return \(PALETTE\["red"\], 0\.0, 0\.0, 1\.0\)') as info:
        draw(fragment_shader=uses_a_dict)
    assert info.value.line == uses_a_dict.__code__.co_firstlineno + 2
    assert "PALETTE" in info.value.numba_message


def test_fragment_shader_that_raises():
    with pytest.raises(ShaderError, match=r"fragment shader test_errors\.raises_on_the_right.*"
                                          r"this fragment is on the right"):
        draw(fragment_shader=raises_on_the_right)


def test_fragment_shader_returning_three_components():
    with pytest.raises(ShaderError, match=r"fragment shader test_errors\.returns_rgb must return an RGBA tuple "
                                          r"of 4 floats"):
        draw(fragment_shader=returns_rgb)


def vertex_shader_that_raises(attributes, uniforms):
    raise RuntimeError("no vertices today")


def vertex_shader_with_2d_clip(attributes, uniforms):
    return (0.0, 0.0), softpipe.shading.StandardVaryings((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))


def test_vertex_shader_errors_name_the_shader():
    with pytest.raises(ShaderError, match=r"vertex shader test_errors\.vertex_shader_that_raises raised "
                                          r"RuntimeError: no vertices today"):
        draw(TRI[:, :3], varyings=None, vertex_shader=vertex_shader_that_raises)
    with pytest.raises(ShaderError, match=r"vertex shader test_errors\.vertex_shader_with_2d_clip: clip position "
                                          r"must be a tuple of 4 floats"):
        draw(TRI[:, :3], varyings=None, vertex_shader=vertex_shader_with_2d_clip)


def test_a_shader_that_is_not_a_function():
    with pytest.raises(TypeError, match=r"shader must be a function \(def or lambda, or a numba.njit one\), got int"):
        draw(fragment_shader=5)


def test_a_partial_shader_is_refused_with_the_way_out():
    import functools

    def tinted(varyings, uniforms, frag, k):
        return (k, 0.0, 0.0, 1.0)
    with pytest.raises(TypeError, match=r"got partial; a shader's extra inputs are uniforms"):
        draw(fragment_shader=functools.partial(tinted, k=0.5))


@pytest.mark.parametrize("what", ["varying", "attribute", "uniform"])
def test_a_keyword_as_an_input_name_is_refused_with_a_rename(what):
    import softpipe as sp
    clip = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [0, 1, 0, 1]], float)
    kw = {"varying": {"varyings": {"lambda": np.ones((3, 3))}},
          "attribute": {"attributes": {"lambda": np.ones(3)}, "vertex_shader": lambda a, u: ((0.0, 0.0, 0.0, 1.0),)},
          "uniform": {"varyings": {"color": np.ones((3, 3))}, "uniforms": {"lambda": 1.0}}}[what]
    with pytest.raises(ValueError, match=rf"{what} name 'lambda' is a Python keyword.*rename it, e.g. 'lambda_'"):
        sp.draw(sp.Framebuffer(8, 8), clip, **kw)


def fragment_shader_that_raises_on_the_right(varyings, uniforms, frag):
    if frag.x > 200.0:
        raise ValueError("too far right")
    return (1.0, 1.0, 1.0, 1.0)


def vertex_shader_that_raises_late(attributes, uniforms):
    p = attributes.position
    if p[0] > 0.9:
        raise ValueError("this vertex is out of bounds")
    return (p[0], p[1], 0.0, 1.0), softpipe.shading.StandardVaryings((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_a_shader_that_raises_on_some_fragments_only_is_reported_from_any_thread(path):
    # the fast path shades in bands on several threads; the error must still arrive, named
    fb = softpipe.Framebuffer(256, 256)
    full = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1.0]])
    with pytest.raises(ShaderError, match=r"fragment shader test_errors\.fragment_shader_that_raises_on_the_right "
                                          r"raised ValueError: too far right"):
        softpipe.draw(fb, full, [0, 1, 2, 0, 2, 3], varyings={"color": np.ones((4, 3))},
                      fragment_shader=fragment_shader_that_raises_on_the_right, path=path)


def test_a_vertex_shader_that_raises_on_late_vertices_only_is_reported():
    rng = np.random.default_rng(1)
    positions = np.c_[rng.uniform(-1, 0.8, (20000, 3))]
    positions[19990, 0] = 0.95                    # one vertex, in the last band
    with pytest.raises(ShaderError, match=r"vertex shader test_errors\.vertex_shader_that_raises_late raised "
                                          r"ValueError: this vertex is out of bounds"):
        softpipe.draw(softpipe.Framebuffer(64, 64), positions, vertex_shader=vertex_shader_that_raises_late,
                      fragment_shader=fragment_shader_that_raises_on_the_right)
