# Lesson 03, the exercise completed: the depth test (GL's "less") over fragments in draw order.


def depth_test(fragments):
    """Which triangle each pixel keeps: ``fragments`` are (x, y, depth, triangle) in draw order;
    the depth buffer starts cleared to 1.0 (the far plane); a fragment passes when its depth is
    less than the stored one, and then its depth is stored and its triangle kept."""
    depth = {}
    kept = {}
    for x, y, z, triangle in fragments:
        if z < depth.get((x, y), 1.0):
            depth[(x, y)] = z
            kept[(x, y)] = triangle
    return kept
