"""Deferred shading: a G-buffer pass (multiple render targets), then one lighting pass over the screen.

    python examples/deferred.py            → out/examples/deferred.png (320×240)

Forward shading lights every fragment a mesh covers, also those a nearer mesh will cover
later (overdraw). Deferred shading splits the frame in two passes (docs/deferred.md):

1. the **G-buffer pass** draws every mesh with a cheap fragment shader that returns four
   values, one per attachment of the framebuffer (``layout(location = k) out`` in GLSL):
   the material's diffuse color (``albedo``, rgba8), the eye-space point (``position``,
   rgba32f), the unit normal on the viewer's side (``normal``, rgba32f) and which
   material it is (``material``, r32i, −1 where nothing was drawn);
2. the **lighting pass** draws one quad over the whole screen; its fragment shader reads
   the G-buffer at its own pixel, as arrays given as uniforms (GLSL's ``texelFetch``: an
   exact read of one texel, no filtering), and lights the pixel once with the very
   function the forward ``phong`` program calls (``opengl_lighting`` with Blinn-Phong, FORMULAS §10).

The picture equals the forward one within 1/255 at every pixel (tests/test_deferred.py):
the only difference is that the G-buffer keeps P and N as float32. The sheet shows the
forward picture, the deferred one, the G-buffer's attachments and how many fragments forward
shading lit at each pixel (:func:`overdraw`); :func:`shading_counts` measures how many fragments
each way lit.
"""
from collections import namedtuple

import numpy as np
from common import lighting_uniform, picture_size, save_sheet, studio_lighting

import softpipe as sp
from softpipe.light.lighting import BLINN_PHONG, opengl_lighting
from softpipe.light.material import Material, MaterialUniform
from softpipe.pipeline.camera import Camera
from softpipe.programs.common import facing_normal, toward_eye
from softpipe.scenes.drawing import draw_mesh

#: The G-buffer: location 0 is the albedo (the picture the framebuffer shows), then the
#: surface's point and normal in eye space, and the material's row in :data:`MATERIALS`.
GBUFFER = {"albedo": "rgba8", "position": "rgba32f", "normal": "rgba32f", "material": "r32i"}
BACKGROUND = (0.06, 0.07, 0.09, 1.0)
MATERIALS = (
    Material(ka=(0.1, 0.1, 0.1), kd=(0.5, 0.5, 0.55), ks=(0.1, 0.1, 0.1), shininess=8.0),        # floor
    Material(ka=(0.1, 0.03, 0.03), kd=(0.7, 0.15, 0.1), ks=(0.4, 0.4, 0.4), shininess=40.0),     # red plastic
    Material(ka=(0.02, 0.05, 0.1), kd=(0.1, 0.3, 0.7), ks=(0.6, 0.6, 0.6), shininess=90.0),      # blue
    Material(ka=(0.05, 0.08, 0.02), kd=(0.35, 0.6, 0.15), ks=(0.2, 0.2, 0.2), shininess=20.0,
             ke=(0.05, 0.05, 0.0)),                                                             # green, glowing a little
)
Part = namedtuple("Part", ["mesh", "model", "material"])


def translate(x, y, z, scale=1.0):
    m = np.diag([scale, scale, scale, 1.0])
    m[:3, 3] = (x, y, z)
    return m


def scene():
    """A floor and a row of spheres and cubes, listed far to near: each nearer one covers the last
    (the worst order for forward shading, which then lights what is later hidden)."""
    sphere, cube, floor = sp.shapes.uv_sphere(0.6, 24, 12), sp.shapes.cube(1.0), sp.shapes.plane(10.0)
    parts = [Part(floor, translate(0, -0.6, -3.0), 0)]
    for k in range(9):
        mesh = sphere if k % 2 == 0 else cube
        parts.append(Part(mesh, translate(0.3 * (k % 3 - 1), 0.0, -0.9 * (8 - k)), 1 + k % 3))
    return parts


def camera():
    return Camera(eye=(0.7, 0.9, 2.4), target=(0.0, 0.0, -3.0), fovy=45.0)


def gbuffer_fragment(varyings, uniforms, frag):
    """The G-buffer pass: a value per attachment, in GBUFFER's order."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    kd = uniforms.material.kd
    return ((kd[0], kd[1], kd[2], uniforms.material.opacity), (P[0], P[1], P[2], 1.0), (N[0], N[1], N[2], 0.0),
            int(uniforms.material_id))


def lighting_fragment(varyings, uniforms, frag):
    """The lighting pass: the G-buffer at this pixel (texelFetch), lit once as ``phong`` lights a fragment."""
    col, row = int(frag.x), int(uniforms.height) - 1 - int(frag.y)     # gl_FragCoord → image row and column
    k = int(uniforms.material[row, col])
    if k < 0:
        return uniforms.background
    p, n, a = uniforms.position[row, col], uniforms.normal[row, col], uniforms.albedo[row, col]
    P, N = (p[0], p[1], p[2]), (n[0], n[1], n[2])
    t = uniforms.materials[k]            # ke, ka, ks, shininess: what the G-buffer did not keep
    m = MaterialUniform((t[0], t[1], t[2]), (t[3], t[4], t[5]), (a[0], a[1], a[2]), (t[6], t[7], t[8]), t[9],
                        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 1.0, a[3], 0.0)
    color = opengl_lighting(P, N, toward_eye(P, uniforms.projection), m, uniforms.lighting, BLINN_PHONG)
    return (color[0], color[1], color[2], a[3])


def material_table():
    """The materials as rows ke, ka, ks, shininess (float64 [M, 10]) for the lighting pass."""
    return np.array([tuple(m.ke) + tuple(m.ka) + tuple(m.ks) + (m.shininess,) for m in MATERIALS])


def forward(size, path="auto", counts=None, near_first=False):
    """The scene drawn with the ``phong`` program; ``counts`` (a list) receives each draw's Trace.
    ``near_first`` draws the meshes nearest first (the floor last), the order early depth likes."""
    w, h = picture_size(size)
    fb = sp.Framebuffer(w, h).clear(BACKGROUND)
    cam = camera()
    lighting = lighting_uniform(studio_lighting(), cam.view)
    parts = scene()
    for part in (parts[:0:-1] + parts[:1] if near_first else parts):
        mesh = part.mesh.replace(material=MATERIALS[part.material])
        trace = draw_mesh(fb, mesh, cam, "phong", model=part.model, uniforms={"lighting": lighting}, path=path,
                          trace=counts is not None)
        if counts is not None:
            counts.append(trace)
    return fb


def gbuffer(size, path="auto", counts=None):
    """The G-buffer pass: every mesh into the four attachments."""
    w, h = picture_size(size)
    fb = sp.Framebuffer(w, h, attachments=GBUFFER).clear(BACKGROUND, attachments={"material": -1})
    cam = camera()
    for part in scene():
        mesh = part.mesh.replace(material=MATERIALS[part.material])
        trace = draw_mesh(fb, mesh, cam, gbuffer_fragment, model=part.model, uniforms={"material_id": part.material},
                          path=path, trace=counts is not None)
        if counts is not None:
            counts.append(trace)
    return fb


def lighting_pass(g, path="auto", trace=False):
    """One quad over the screen, lit per pixel from the G-buffer ``g``; returns (framebuffer, trace or None)."""
    cam = camera()
    fb = sp.Framebuffer(g.width, g.height).clear(BACKGROUND)
    quad = np.array([(-1, -1, 0, 1), (1, -1, 0, 1), (1, 1, 0, 1), (-1, -1, 0, 1), (1, 1, 0, 1), (-1, 1, 0, 1.0)])
    uniforms = {"albedo": g.attachment("albedo"), "position": g.attachment("position"),
                "normal": g.attachment("normal"), "material": g.attachment("material"),
                "materials": material_table(), "height": g.height, "background": BACKGROUND,
                "projection": cam.projection(g.width / g.height),
                "lighting": lighting_uniform(studio_lighting(), cam.view)}
    out = sp.draw(fb, quad, fragment_shader=lighting_fragment, uniforms=uniforms, depth_test=None, path=path,
                  trace=trace)
    return fb, out


def deferred(size):
    fb, _ = lighting_pass(gbuffer(size))
    return fb


def shading_counts(size):
    """Fragments shaded each way: forward on the reference path (every fragment, overdraw and all), forward on
    the fast path (early depth: the visible samples of each draw) in the scene's order (far first) and nearest
    first, and deferred (the G-buffer pass's cheap shader per fragment, then the lighting shader once per pixel,
    which lights the pixels where a surface is)."""
    ref, fast, near = [], [], []
    g: list = []
    forward(size, "reference", ref)
    forward(size, "fast", fast)
    forward(size, "fast", near, near_first=True)
    buffer = gbuffer(size, "reference", g)
    _, light = lighting_pass(buffer, "reference", trace=True)
    return {"forward lit (reference)": sum(t.shaded.invocations for t in ref),
            "forward lit (fast path)": sum(t.shaded.invocations for t in fast),
            "forward lit (fast path, near first)": sum(t.shaded.invocations for t in near),
            "g-buffer fragments": sum(t.shaded.invocations for t in g),
            "lighting pass invocations": light.shaded.invocations,
            "deferred lit": int((buffer.attachment("material") >= 0).sum())}


def one(varyings, uniforms, frag):
    return (1.0, 1.0, 1.0, 1.0)


def overdraw(size):
    """How many fragments forward shading lights at each pixel (its depth complexity): every mesh drawn
    as the forward pass draws it, adding 1 per fragment, with no depth test."""
    w, h = picture_size(size)
    fb = sp.Framebuffer(w, h).clear((0.0, 0.0, 0.0, 0.0))
    cam = camera()
    for part in scene():
        draw_mesh(fb, part.mesh, cam, one, model=part.model, blend="additive", depth_test=None)
    return fb.color[..., 0]


def sheet(size=(320, 240)):
    g = gbuffer(size)
    lit, _ = lighting_pass(g)
    front = forward(size)
    normal = np.clip(g.attachment("normal")[..., :3] * 0.5 + 0.5, 0, 1)
    depth = -g.attachment("position")[..., 2]
    far = depth[g.attachment("material") >= 0].max(initial=1.0)
    ids = g.attachment("material")
    palette = np.array([(0, 0, 0), (200, 200, 200), (220, 60, 40), (40, 90, 220), (90, 200, 40)], np.uint8)
    count = overdraw(size)
    heat = np.clip(count / max(count.max(), 1.0), 0, 1)
    return {"forward (phong)": front.to_uint8(False), "deferred": lit.to_uint8(False),
            "albedo": g.to_uint8(False), "normal": np.rint(normal * 255).astype(np.uint8),
            "eye depth": np.rint(np.repeat((np.clip(depth / far, 0, 1) * 255)[..., None], 3, 2)).astype(np.uint8),
            "material id": palette[ids + 1],
            "forward: fragments lit per pixel": np.rint(np.stack([heat, heat ** 2, 0.3 * heat], -1) * 255).astype(np.uint8)}


def main(size=(320, 240), out_dir=None):
    return save_sheet("deferred", sheet(size), 4, "Deferred shading: G-buffer (MRT), one lighting pass", out_dir)


if __name__ == "__main__":
    main()
    counts = shading_counts((320, 240))
    for what, n in counts.items():
        print(f"{what:>26}: {n:,}")
