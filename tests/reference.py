"""The exact reference rasterizer for the tests: softpipe.testing's, the one implementation.

Plain Python and exact rational arithmetic, written independently of
softpipe.pipeline.raster (see softpipe/testing/reference.py). The suite uses
``covered(tri, width, height, samples)`` (a set of (i, j, s), window rows, y up),
``snap`` and ``picture``; users get the same rules as
``softpipe.testing.reference_coverage``.
"""
from softpipe.testing.reference import covered, picture, reference_coverage, snap

__all__ = ["covered", "picture", "reference_coverage", "snap"]
