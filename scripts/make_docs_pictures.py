"""Draw the guide's scene with a trace and write the pictures that docs/ shows.

    python scripts/make_docs_pictures.py            # into docs/images/
    python scripts/make_docs_pictures.py OUT_DIR    # anywhere else

The scene is four triangles on a 160×120 framebuffer: a red one at the back,
a green one tilted through it, a blue one with a corner nearer than the near
plane (so clipping cuts it) and a yellow clockwise one that ``cull="back"``
removes. Every page of docs/ starts with the same lines (between the markers
below; tests/test_docs.py checks that they match), so what a page prints is
what this script draws.

Writes each stage picture of :meth:`softpipe.pipeline.trace.Trace.save_pictures`
(``01-vertices.png`` … ``06-final.png``, ``contact-sheet.png``) and
``eye-space.png``, a top view of the scene and the view frustum, and prints
each path with its size.
"""
# ruff: noqa: I001  (the scene's imports are the docs' first lines, exactly as a reader types them)
from __future__ import annotations

import sys
from pathlib import Path

# --- the scene (docs/*.md start with exactly these lines) ---
from collections import namedtuple

import numpy as np
import softpipe as sp
from softpipe.shading import mat4_mul_vec4

corners = np.array([                                                # world coordinates
    [[-2.0, -1.4, 0.0], [2.2, -1.4, 0.0], [0.0, 1.9, 0.0]],         # 0 red, at the back
    [[-2.2, 0.9, 1.5], [-1.0, -1.6, -1.5], [1.4, 1.2, -0.5]],       # 1 green, tilted through the red one
    [[0.4, -0.5, 1.0], [1.9, -1.2, 1.0], [0.1, 0.25, 4.6]],         # 2 blue, one corner nearer than the near plane
    [[-1.8, -1.2, 2.0], [-1.2, 0.2, 2.0], [-0.4, -1.2, 2.0]],       # 3 yellow, clockwise: back-facing
])
colors = np.array([
    [[1.0, 0.2, 0.2], [0.8, 0.1, 0.1], [1.0, 0.5, 0.4]],
    [[0.2, 0.9, 0.3], [0.1, 0.6, 0.2], [0.6, 1.0, 0.5]],
    [[0.3, 0.4, 1.0], [0.1, 0.2, 0.8], [0.6, 0.8, 1.0]],
    [[1.0, 0.9, 0.2], [1.0, 0.9, 0.2], [1.0, 0.9, 0.2]],
])
view = sp.look_at(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0))    # the eye on +Z, looking down −Z
projection = sp.perspective(50.0, 160 / 120, 1.0, 10.0)           # fovy, aspect, near, far

Varyings = namedtuple("Varyings", ["color"])


def vertex_shader(attributes, uniforms):
    p = attributes.position
    clip = mat4_mul_vec4(uniforms.mvp, (p[0], p[1], p[2], 1.0))
    return clip, Varyings(attributes.color)


fb = sp.Framebuffer(160, 120)
fb.clear((0.08, 0.08, 0.1))
trace = sp.draw(fb, corners.reshape(-1, 3), vertex_shader=vertex_shader,
                attributes={"color": colors.reshape(-1, 3)},
                uniforms={"mvp": projection @ view}, cull="back", trace=True)
# --- end of the scene ---


def eye_space_picture(size=(200, 150)):
    """A top view of eye space (x to the right, −z up): the frustum, the near plane, the triangles.

    Each triangle is drawn as the outline of its corners' (x, z) projection, in
    its first corner's color; the frustum's sides in grey, the near plane in
    cyan, the eye as a white dot at the bottom.
    """
    from PIL import Image, ImageDraw
    w, h = size
    eye_corners = (view @ np.c_[corners.reshape(-1, 3), np.ones(12)].T).T[:, :3].reshape(4, 3, 3)
    depth = 7.0                                   # how far (−z) the picture reaches
    half_x = 3.2
    to_px = lambda x, z: (w / 2 + x / half_x * (w / 2), h - 8 - (-z) / depth * (h - 16))  # noqa: E731
    img = Image.new("RGB", size, (24, 24, 28))
    d = ImageDraw.Draw(img)
    tan_x = 1.0 / projection[0, 0]                 # x/(−z) at the frustum's side
    near = 1.0
    for sgn in (-1, 1):
        d.line([to_px(0, 0), to_px(sgn * tan_x * depth, -depth)], fill=(120, 120, 130))
    d.line([to_px(-tan_x * near, -near), to_px(tan_x * near, -near)], fill=(60, 200, 230), width=2)
    d.text((4, 4), "top view: x right, -z up", fill=(200, 200, 200))
    d.text(to_px(tan_x * near + 0.1, -near - 0.1), "near", fill=(60, 200, 230))
    for tri, col in zip(eye_corners, colors):
        pts = [to_px(x, z) for x, _, z in tri]
        d.line(pts + pts[:1], fill=tuple(int(255 * c) for c in col[0]), width=1)
    ex, ey = to_px(0, 0)
    d.ellipse([ex - 2, ey - 2, ex + 2, ey + 2], fill=(235, 235, 235))
    return img


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent / "docs" / "images"
    paths = trace.save_pictures(out)
    paths["eye-space"] = out / "eye-space.png"
    eye_space_picture().save(paths["eye-space"], optimize=True)
    total = 0
    for path in paths.values():
        size = path.stat().st_size
        total += size
        shown = path.resolve()
        if shown.is_relative_to(Path.cwd()):
            shown = shown.relative_to(Path.cwd())
        print(f"{shown}  {size / 1024:.1f} KB")
    print(f"{len(paths)} pictures, {total / 1024:.1f} KB in all")
    return 0


if __name__ == "__main__":
    sys.exit(main())
