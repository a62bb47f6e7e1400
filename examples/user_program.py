"""A user's shading program: Blinn-Phong with one term changed (wrapped diffuse).

    python examples/user_program.py          → out/examples/user_program.png

The fragment shader below is the OpenGL lighting equation (FORMULAS §10) written
out, with Lambert's diffuse factor (N·L) (§3) replaced by "wrap lighting",
((N·L + w)/(1 + w))₊, which lets the light reach around the terminator (a cheap
stand-in for light scattered under a skin or a cloth). w = 0 is Lambert again.
w is an optional uniform (``uniform_or``); everything else is the built-in
lighting's own functions, including the shadow term V_j (``light_visibility``: 1
when the light has no shadow map). Nothing is registered: a Program, or the two
functions given to ``softpipe.draw``, is all softpipe needs.
"""
from common import image, key_light, render, save_sheet

from softpipe.pipeline.camera import Camera
from softpipe.scenes import shapes
from softpipe.shading import (
    LIGHT_AMBIENT,
    LIGHT_DIFFUSE,
    LIGHT_SPECULAR,
    Material,
    Program,
    add,
    ambient,
    blinn_phong_specular,
    dot,
    emission,
    facing_normal,
    light_at,
    light_vec3,
    light_visibility,
    mul,
    scale,
    standard_vertex,
    toward_eye,
    uniform_or,
)


def wrapped_fragment(varyings, uniforms, frag):
    """§10 per fragment, with (N·L) replaced by ((N·L + w)/(1 + w))₊."""
    P = varyings.position
    N = facing_normal(varyings.normal, frag.front_facing)
    V = toward_eye(P, uniforms.projection)
    m = uniforms.material
    lights = uniforms.lighting.lights
    w = uniform_or(uniforms, "wrap", 0.5)
    color = add(emission(m.ke), ambient(m.ka, uniforms.lighting.global_ambient))
    for j in range(lights.shape[0]):
        L, f = light_at(P, lights, j)
        wrapped = max((dot(N, L) + w) / (1.0 + w), 0.0)              # the changed term
        diffuse = scale(mul(m.kd, light_vec3(lights, j, LIGHT_DIFFUSE)), wrapped)
        specular = blinn_phong_specular(m.ks, light_vec3(lights, j, LIGHT_SPECULAR), N, L, V, m.shininess)
        shadowed = mul(add(diffuse, specular), light_visibility(uniforms.lighting, j, P))  # V_j
        term = add(ambient(m.ka, light_vec3(lights, j, LIGHT_AMBIENT)), shadowed)
        color = add(color, scale(term, f))
    return (color[0], color[1], color[2], m.opacity)


wrapped = Program("wrapped", standard_vertex, wrapped_fragment, "Blinn-Phong with wrapped diffuse")


def sheet(size=160):
    camera = Camera(eye=(0.0, 0.0, 3.4), fovy=38.0)
    sphere = shapes.uv_sphere(segments=64, rings=32, material=Material(kd=(0.8, 0.45, 0.35), ks=0.3))
    lighting = key_light()
    pictures = {"built-in phong": image(render(sphere, camera, "phong", lighting, (size, size)))}
    for w in (0.0, 0.5, 1.0):
        fb = render(sphere, camera, wrapped, lighting, (size, size), uniforms={"wrap": w})
        pictures[f"wrapped diffuse, w = {w}"] = image(fb)
    return pictures


def main(size=160, out_dir=None):
    return save_sheet("user_program", sheet(size), 4,
                      "A user program: Blinn-Phong with a wrapped diffuse term (w = 0: Lambert)", out_dir)


if __name__ == "__main__":
    main()
