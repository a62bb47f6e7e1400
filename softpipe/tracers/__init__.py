"""Renderers that follow rays instead of rasterizing: the Whitted ray tracer
(:mod:`.whitted`) over the same scenes, materials and lights as the rasterizer.
"""
