"""Rays against triangles: the bounding volume hierarchy (:mod:`.bvh`, the public face, built by
:mod:`.build` and walked by :mod:`.traverse` with the exact triangle test of :mod:`.triangle`; the
arrays they share are described in :mod:`.layout`) and the queries a shader or a tracer asks of a
scene (:mod:`.queries`: closest and any hit).
"""
