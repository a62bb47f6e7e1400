"""Shaders that declare the uniforms they read (shader.reads_uniforms), as GLSL's ``uniform`` lines.

The vertex stage gives a declared shader only those uniforms, so its compiled loop
serves every program whose other uniforms differ.
"""
import numpy as np
import pytest

import softpipe as sp
from softpipe.language.contract import ShaderError, declared_uniforms, make_uniforms, reads_uniforms
from softpipe.language.kernels import cache
from softpipe.pipeline.camera import Camera
from softpipe.programs.common import standard_vertex
from softpipe.scenes import shapes
from softpipe.scenes.drawing import draw_mesh


def test_declared_uniforms_keeps_the_declared_ones_in_their_order():
    u = make_uniforms({"tint": (1.0, 0.5, 0.25), "projection": np.eye(4), "wrap": 0.5, "model_view": np.eye(4)})
    cut = declared_uniforms(standard_vertex, u)
    assert cut._fields == ("model_view", "projection")          # normal_matrix was not given
    assert cut.model_view is u.model_view and cut.projection is u.projection
    assert declared_uniforms(lambda a, u: None, u) is u               # undeclared: every uniform
    # the same set of names is the same class (one compiled loop for all of them)
    other = declared_uniforms(standard_vertex, make_uniforms({"model_view": np.eye(4), "projection": np.eye(4)}))
    assert type(other) is type(cut)


def test_reads_uniforms_refuses_a_name_no_shader_could_read():
    with pytest.raises(ValueError, match="'lambda'"):
        reads_uniforms("model_view", "lambda")


def test_programs_whose_other_uniforms_differ_share_one_vertex_loop():
    """Two draws with standard_vertex, the second with a uniform of its own: no second vertex loop."""
    mesh = shapes.uv_sphere(segments=12, rings=6)
    camera = Camera(eye=(0.0, 0.0, 3.0))
    fb = sp.Framebuffer(32, 32)
    draw_mesh(fb, mesh, camera, "phong")
    compiled = _vertex_loop_signatures()
    assert compiled >= 1
    draw_mesh(fb, mesh, camera, "phong", uniforms={"wrap": 0.5, "tint": (1.0, 0.0, 0.0)})
    assert _vertex_loop_signatures() == compiled


def _vertex_loop_signatures() -> int:
    """How many argument types standard_vertex's loops (one per attribute set) are compiled for, in all."""
    return sum(len(module.vertex_loop.signatures) for key, module in cache._KERNELS.items()
               if key[0] == "vertex" and key[1] is standard_vertex)


def test_a_declared_shader_reading_an_undeclared_uniform_fails_naming_it():
    @reads_uniforms("scale")
    def vertex(attributes, uniforms):
        p = attributes.position
        return (p[0] * uniforms.scale, p[1] * uniforms.offset, p[2], 1.0), ()

    fb = sp.Framebuffer(8, 8)
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    with pytest.raises((ShaderError, AttributeError), match="offset"):
        sp.draw(fb, positions, vertex_shader=vertex, fragment_shader=lambda v, u, f: (1.0, 1.0, 1.0, 1.0),
                uniforms={"scale": 1.0, "offset": 0.0})
