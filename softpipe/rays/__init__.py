"""Rays against triangles: the bounding volume hierarchy (:mod:`.bvh`) and the
queries a shader or a tracer asks of a scene (:mod:`.queries`: closest and any hit).
"""
