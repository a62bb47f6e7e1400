# Lesson 01, the exercise completed: a line drawer by GL's diamond-exit rule, for a segment
# from the centre of pixel (x0, y0) to the centre of pixel (x1, y1) (window coordinates, y up).


def draw_line(x0, y0, x1, y1):
    """The pixels GL's diamond-exit rule gives the segment between two pixel centres: one per
    step along the major axis, the last pixel (the end point's) left out."""
    dx, dy = x1 - x0, y1 - y0
    pixels = set()
    if dx == 0 and dy == 0:
        return pixels
    x_major = abs(dx) >= abs(dy)
    steps = abs(dx) if x_major else abs(dy)
    major_step = 1 if (dx if x_major else dy) > 0 else -1
    d_minor = dy if x_major else dx
    for k in range(steps):                      # k = 0 … steps − 1: the end pixel is left out
        # the line's minor offset at this step is k·d_minor/steps pixels: the nearest centre wins
        num = k * d_minor                         # offset = num / steps, exactly
        q, r = divmod(num, steps)                 # q ≤ offset < q + 1
        if 2 * r > steps:
            q += 1
        elif 2 * r == steps:                      # exactly halfway: GL's shift by (−ε, −ε²) decides
            if x_major:
                q += 1 if d_minor * major_step > 0 else 0   # slope > 0: the shifted line is higher
            # y-major: the shift moves the line left, to the smaller x: q as it is
        if x_major:
            pixels.add((x0 + major_step * k, y0 + q))
        else:
            pixels.add((x0 + q, y0 + major_step * k))
    return pixels
