"""A renderer's CI test: the scene must come out as the stored picture, byte for byte.

``golden`` (softpipe's pytest plugin) compares with golden/test_scene.png next to
this file; ``pytest --softpipe-update-golden examples/testing`` rewrites it after
a deliberate change.
"""
import numpy as np

import softpipe as sp


def draw_scene():
    fb = sp.Framebuffer(32, 24)
    fb.clear("white")
    positions = np.array([[-0.9, -0.8, 0.5, 1], [0.6, -0.9, 0.5, 1], [-0.2, 0.9, 0.5, 1],
                          [-0.4, -0.2, 0.2, 1], [0.9, 0.1, 0.2, 1], [0.1, 0.8, 0.8, 1]])
    colors = np.array([[1, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 1], [0, 0, 1], [0, 0, 1]], dtype=float)
    sp.draw(fb, positions, varyings={"color": colors})
    return fb


def test_scene(golden):
    golden(draw_scene())                # tolerance 0: every 8-bit value the same
