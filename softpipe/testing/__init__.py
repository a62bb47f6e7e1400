"""softpipe.testing: pixel-exact tests of graphics code (a rasterizer, a shader, a renderer).

- :func:`coverage`, :func:`covered_pixels`: the exact pixels (or samples)
  triangles, lines and points cover under OpenGL's rules (``topology=``,
  ``line_width=``, ``point_size=`` as ``softpipe.draw`` takes them), from softpipe's
  own rasterizer.
  ``positions`` are window coordinates in pixels, y up (OpenGL), or clip
  coordinates with ``space="clip"``; result arrays are images (row 0 at the top).
- :func:`reference_coverage`: the same, by a slow exact (Fraction) rasterizer
  written independently of softpipe's, to test a rasterizer of one's own against.
- :func:`reference_line`, :func:`reference_point`, :func:`reference_line_parameter`:
  the exact pixels GL's rules give a line segment (the diamond-exit rule, wide
  lines) and a point, and the parameter t along a segment, in window coordinates.
- :func:`assert_pixels_equal`: arrays, Framebuffers or image files, pixel by
  pixel, with a message that says how many pixels differ, where, the worst one,
  and an ASCII map; ``diff_path=`` writes a diff image.
- :func:`ascii_picture`, :func:`from_ascii`: expectations as pictures in the source.
- :func:`sorted_composite`: the exact transparent composite, every traced fragment sorted
  by depth per sample and composited "over" an opaque picture (docs/transparency.md).
- :func:`check_line`, :func:`check_triangles`, :func:`check_depth_test`, :func:`check_interpolation`,
  :func:`check_camera`, :func:`check_clipping`, :func:`check_blinn_phong`, :func:`check_bilinear`,
  :func:`check_mip_level`, :func:`check_shadow_compare`, :func:`check_ray_triangle`, :func:`check_coverage`:
  the lessons' checks (lessons/): an answer against softpipe's stage, pixel for pixel, with a
  difference picture and a message that names the rule most likely broken.
- :func:`check_golden` and the pytest plugin :mod:`softpipe.testing.plugin`
  (the ``golden`` fixture, ``pytest --softpipe-update-golden``).

docs/testing.md shows them at work.
"""
from softpipe.testing.compare import assert_pixels_equal, check_golden, diff_image, to_8bit
from softpipe.testing.composite import sorted_composite
from softpipe.testing.coverage import Coverage, coverage, covered_pixels
from softpipe.testing.lessons import (
           Difference,
           check_bilinear,
           check_blinn_phong,
           check_camera,
           check_clipping,
           check_coverage,
           check_depth_test,
           check_interpolation,
           check_line,
           check_mip_level,
           check_ray_triangle,
           check_shadow_compare,
           check_triangles,
           trace_fragments,
)
from softpipe.testing.line_reference import reference_line, reference_line_parameter, reference_point
from softpipe.testing.pictures import ascii_picture, from_ascii
from softpipe.testing.reference import reference_coverage

__all__ = ["coverage", "covered_pixels", "Coverage", "reference_coverage", "reference_line", "reference_point",
           "reference_line_parameter", "assert_pixels_equal", "ascii_picture", "from_ascii", "check_golden",
           "diff_image", "to_8bit", "sorted_composite", "check_coverage", "check_line", "check_triangles",
           "check_depth_test", "check_interpolation", "check_camera", "check_clipping", "check_blinn_phong",
           "check_bilinear", "check_mip_level", "check_shadow_compare", "check_ray_triangle", "Difference",
           "trace_fragments"]
