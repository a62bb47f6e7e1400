"""softpipe against Mesa's llvmpipe: ``python -m benchmarks.peers [SCENE ...]`` (``make bench-peers``).

Renders benchmark scenes (:mod:`benchmarks.scenes`) through softpipe and through
Mesa's llvmpipe (the C software OpenGL driver, via moderngl on a surfaceless EGL
context) in one process, on the same cores, **alternating the two frame by frame**
(ABBA order: softpipe first in even rounds, llvmpipe first in odd ones) so that the
machine's drift lands on both, and prints per scene both medians, softpipe/llvmpipe
and how far the two images differ.

The peer gets the same geometry and camera: the scene's own arrays as vertex buffers
(float32, as GL takes them), the same uniforms, 1 sample per pixel, depth test LESS,
culling as the scene says. Its shaders (GLSL 430, here) are written to compute what
softpipe's do:

* clip-coordinate scenes (``fill``, ``fill-b2f``, ``tiny``): a pass-through vertex
  shader and the color varying as it is;
* ``sphere200k-color``: ``mvp · position`` and the color attribute;
* lit scenes (``sphere200k``, ``bunny``, ``bunny-blinn``): softpipe's ``phong`` /
  ``phong_phong_specular`` programs: eye-space P and N from the vertex shader, per
  fragment N renormalized (reversed on a back face), V toward the eye, the OpenGL
  lighting equation (FORMULAS §10) over the scene's packed lights (directional,
  point, spot) with Blinn-Phong (N·H)₊ⁿ or Phong (R·V)₊ⁿ, no clamping before the
  framebuffer's.
* ``bunny-onelight`` (issue 35's row): the bunny, one directional light and the minimal
  Blinn-Phong a user writes on each side — :data:`ONE_LIGHT_FRAGMENT` in GLSL (N
  normalized, L given, H = normalize(L + V), ambient + kd·max(N·L, 0) + ks·max(N·H, 0)ⁿ)
  and its twin :func:`one_light_fragment` written with :mod:`softpipe.shading`'s words
  (``normalize``, ``dot``, ``pow_``), not softpipe's general light loop; the same
  vertex shaders as the lit scenes.

A frame is, for softpipe, what ``benchmarks.run`` times (clear, build the DrawCalls,
run them); for llvmpipe: clear, draw, ``ctx.finish()`` and reading the color buffer
back into memory. Warm frames only (each side renders two untimed frames first:
compiling). The images are compared in 8-bit RGB: max and mean absolute difference,
the share of pixels that differ at all and by more than 1/255.

Where moderngl or Mesa are missing the peer part is skipped with a message saying
what is missing, exit status 0 (``--install`` first tries to install them: Debian's
packages with apt-get when root, moderngl with pip into this interpreter).
"""
from __future__ import annotations

import os

# Before moderngl (glcontext) loads libEGL, and before numpy (benchmarks.run's reason).
os.environ.setdefault("EGL_PLATFORM", "surfaceless")
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import importlib  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Callable, Dict, List, Optional, Sequence, Tuple  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from softpipe.core.runtime import keep_freed_memory  # noqa: E402
from softpipe.light.material import Light, Lighting  # noqa: E402
from softpipe.light.packed import LIGHT_COLUMNS  # noqa: E402
from softpipe.pipeline.framebuffer import Framebuffer  # noqa: E402
from softpipe.shading import add, dot, neg, normalize, pow_, scale, vec4  # noqa: E402  (a user's import)

from .run import machine_info, render_frame, source_state  # noqa: E402
from .scenes import REPO_ROOT, SCENES, Scene, build_scene, color_vertex  # noqa: E402

__all__ = ["PEER_SCENES", "peer_context", "install_peer", "LlvmpipeScene", "compare_images", "alternate",
           "summarize", "run_peer_scene", "run", "main", "CLIP_VERTEX", "COLOR_FRAGMENT", "MVP_VERTEX",
           "LIT_VERTEX", "LIT_FRAGMENT", "MAX_LIGHTS",
           "ONE_LIGHT_FRAGMENT", "one_light_fragment", "ONE_LIGHT_DIRECTION", "ONE_LIGHT_AMBIENT",
           "DEBIAN_PACKAGES", "MODERNGL_REQUIREMENT"]

#: What the peer needs (ENVIRONMENT-NOTES.md): Debian's EGL + Mesa (llvmpipe) packages, and moderngl.
DEBIAN_PACKAGES = ("libegl1", "libegl-mesa0", "libgl1-mesa-dri", "libgles2")
MODERNGL_REQUIREMENT = "moderngl>=5.8"
DEFAULT_FRAMES = 9
DEFAULT_JSON = REPO_ROOT / "out" / "bench-peers.json"


def _bunny_blinn(scale: float = 1.0) -> Scene:
    """The bunny with softpipe's ``phong`` program (Blinn-Phong) and sphere200k's one directional light."""
    import softpipe.programs.phong  # noqa: F401  (registers the program)
    from softpipe.programs import get_program

    base = build_scene("bunny", scale)
    program = get_program("phong")
    draws = []
    for d in base.draws:
        u = dict(d["uniforms"])
        u["lighting"] = Lighting((Light.directional((-0.4, -1.0, -0.6), ambient=(0.1, 0.1, 0.1)),),
                                 global_ambient=(0.1, 0.1, 0.1)).uniform(u["view"])
        draws.append(dict(d, uniforms=u, vertex_shader=program.vertex, fragment_shader=program.fragment))
    return replace(base, name="bunny-blinn", draws=draws, notes=[],
                   description=f"Stanford bunny ({base.triangles} triangles), softpipe's phong (Blinn-Phong per "
                               "fragment), sphere200k's one directional light, the bunny's material",
                   shading="vertex softpipe.programs.common.standard_vertex, fragment softpipe.programs.phong."
                           "phong_fragment")


def one_light_fragment(varyings, uniforms, frag):
    """One directional light, Blinn-Phong, as a user writes it with :mod:`softpipe.shading` (GLSL's words).

    The twin of :data:`ONE_LIGHT_FRAGMENT`: N renormalized, L given (eye space, unit, toward
    the light), V = normalize(−P), H = normalize(L + V), and
    ambient + kd·max(N·L, 0) + ks·max(N·H, 0)ⁿ (FORMULAS §2, §3, §6 without B), alpha 1.
    """
    N = normalize(varyings.normal)
    L = uniforms.light_dir
    V = normalize(neg(varyings.position))
    H = normalize(add(L, V))
    diffuse = max(dot(N, L), 0.0)
    specular = pow_(max(dot(N, H), 0.0), uniforms.shininess)
    color = add(add(uniforms.ambient, scale(uniforms.kd, diffuse)), scale(uniforms.ks, specular))
    return vec4(color, 1.0)


#: bunny-onelight's light: sphere200k's direction (world space, the way the light travels), white,
#: and the ambient light I_a that ka multiplies (bunny-blinn's global ambient plus its light's).
ONE_LIGHT_DIRECTION = (-0.4, -1.0, -0.6)
ONE_LIGHT_AMBIENT = (0.2, 0.2, 0.2)


def _bunny_one_light(scale: float = 1.0) -> Scene:
    """The bunny with one directional light and the minimal Blinn-Phong on both sides (issue 35's row).

    softpipe runs :func:`one_light_fragment`, llvmpipe :data:`ONE_LIGHT_FRAGMENT`; both get
    the bunny's material and the light as the uniforms a user passes: ``light_dir`` (eye space,
    toward the light), ``ambient`` = ka·I_a, ``kd``, ``ks`` (the light white) and ``shininess``.
    """
    base = build_scene("bunny", scale)
    draws = []
    for d in base.draws:
        u = dict(d["uniforms"])
        m = u.pop("material")
        u.pop("lighting")
        view = np.asarray(u["view"], dtype=np.float64)
        to_light = view[:3, :3] @ -np.asarray(ONE_LIGHT_DIRECTION, dtype=np.float64)
        u.update(light_dir=tuple(float(x) for x in to_light / np.linalg.norm(to_light)),
                 ambient=tuple(float(a * b) for a, b in zip(m.ka, ONE_LIGHT_AMBIENT)),
                 kd=tuple(float(x) for x in m.kd), ks=tuple(float(x) for x in m.ks), shininess=float(m.shininess))
        draws.append(dict(d, uniforms=u, fragment_shader=one_light_fragment))
    return replace(base, name="bunny-onelight", draws=draws, notes=[],
                   description=f"Stanford bunny ({base.triangles} triangles), one directional light, the minimal "
                               "Blinn-Phong a user writes (GLSL for llvmpipe, softpipe.shading for softpipe)",
                   shading="vertex softpipe.programs.common.standard_vertex, fragment benchmarks.peers."
                           "one_light_fragment")


#: softpipe's topologies with a GL peer, and GL's name (moderngl's constant) for each.
PEER_TOPOLOGIES = {"triangles": "TRIANGLES", "lines": "LINES", "points": "POINTS"}

#: The scenes with a peer, in the order they run: name → scene function.
PEER_SCENES: Dict[str, Callable[[float], Scene]] = {
    "sphere200k-color": SCENES["sphere200k-color"],
    "fill": SCENES["fill"],
    "fill-b2f": SCENES["fill-b2f"],
    "tiny": SCENES["tiny"],
    "sphere200k": SCENES["sphere200k"],
    "bunny-blinn": _bunny_blinn,
    "bunny": SCENES["bunny"],
    "bunny-onelight": _bunny_one_light,
    "bunny-wireframe": SCENES["bunny-wireframe"],
    "points200k": SCENES["points200k"],
}


# --------------------------------------------------------------------------
# The peer's shaders (GLSL 430)
# --------------------------------------------------------------------------

CLIP_VERTEX = """#version 430
in vec4 in_position;
in vec3 in_color;
out vec3 v_color;
void main() {
    gl_Position = in_position;      // clip coordinates given (softpipe: no vertex shader)
    v_color = in_color;
}
"""

MVP_VERTEX = """#version 430
uniform mat4 mvp;
in vec3 in_position;
in vec3 in_color;
out vec3 v_color;
void main() {                       // benchmarks.scenes.color_vertex
    gl_Position = mvp * vec4(in_position, 1.0);
    v_color = in_color;
}
"""

COLOR_FRAGMENT = """#version 430
in vec3 v_color;
out vec4 f_color;
void main() {                       // softpipe's default fragment shader for an RGB color varying
    f_color = vec4(v_color, 1.0);
}
"""

LIT_VERTEX = """#version 430
uniform mat4 model_view;
uniform mat4 projection;
uniform mat3 normal_matrix;
in vec3 in_position;
in vec3 in_normal;
out vec3 v_position;
out vec3 v_normal;
void main() {                       // softpipe.programs.common.standard_vertex
    vec4 P = model_view * vec4(in_position, 1.0);
    gl_Position = projection * P;
    v_position = P.xyz;
    v_normal = normal_matrix * in_normal;
}
"""

#: Lights the GLSL program takes (packed as softpipe.light.material.pack_lights packs them).
MAX_LIGHTS = 8

LIT_FRAGMENT = """#version 430
// softpipe.programs.phong: phong_fragment (specular_model 0, Blinn-Phong (N.H)+^n) and
// phong_phong_specular_fragment (1, Phong (R.V)+^n); softpipe.light.lighting.opengl_lighting (FORMULAS 10).
const int MAX_LIGHTS = %(max_lights)d;
const int COLS = %(cols)d;
uniform vec3 ke;
uniform vec3 ka;
uniform vec3 kd;
uniform vec3 ks;
uniform float shininess;
uniform float opacity;
uniform vec3 global_ambient;
uniform int num_lights;
uniform float lights[MAX_LIGHTS * COLS];   // softpipe.light.material.pack_lights' rows (softpipe.light.packed), eye space
uniform int specular_model;
uniform int orthographic;
in vec3 v_position;
in vec3 v_normal;
out vec4 f_color;

vec3 safe_normalize(vec3 v) {       // softpipe.language.glsl.normalize: the zero vector stays zero
    float n = length(v);
    return n > 0.0 ? v / n : vec3(0.0);
}
float positive_power(float x, float n) {   // (x)+^n with 0^0 = 1
    if (x > 0.0) return pow(x, n);
    return n == 0.0 ? 1.0 : 0.0;
}
vec3 col3(int j, int c) {
    int b = j * COLS + c;
    return vec3(lights[b], lights[b + 1], lights[b + 2]);
}

void main() {
    vec3 P = v_position;
    vec3 N = safe_normalize(v_normal);
    if (!gl_FrontFacing) N = -N;                                   // facing_normal
    vec3 V = orthographic != 0 ? vec3(0.0, 0.0, 1.0) : safe_normalize(-P);   // toward_eye
    vec3 color = ke + ka * global_ambient;
    for (int j = 0; j < num_lights; ++j) {
        int b = j * COLS;
        vec3 L;
        float f;
        if (lights[b + %(kind)d] == %(directional)d.0) {            // light_at
            L = col3(j, %(position)d);
            f = 1.0;
        } else {
            vec3 to_light = col3(j, %(position)d) - P;
            float r = length(to_light);
            L = safe_normalize(to_light);
            float d = lights[b + %(att)d] + lights[b + %(att)d + 1] * r + lights[b + %(att)d + 2] * r * r;
            float f_att = 1.0 / max(d, 1e-12);
            float cos_cutoff = lights[b + %(cutoff)d];
            float f_spot = 1.0;
            if (cos_cutoff > -1.0) {
                float cos_angle = -dot(L, col3(j, %(spot_dir)d));
                f_spot = cos_angle < cos_cutoff ? 0.0 : positive_power(cos_angle, lights[b + %(spot_exp)d]);
            }
            f = f_att * f_spot;
        }
        vec3 term = ka * col3(j, %(ambient)d);
        float n_dot_l = dot(N, L);
        if (f > 0.0 && n_dot_l > 0.0) {
            float s;
            if (specular_model == 1) {
                vec3 R = 2.0 * n_dot_l * N - L;
                s = positive_power(dot(R, V), shininess);
            } else {
                s = positive_power(dot(N, safe_normalize(L + V)), shininess);
            }
            term += kd * col3(j, %(diffuse)d) * n_dot_l + ks * col3(j, %(specular)d) * s;
        }
        color += term * f;
    }
    f_color = vec4(color, opacity);                                 // not clamped: the framebuffer does
}
"""


ONE_LIGHT_FRAGMENT = """#version 430
// The minimal one-light Blinn-Phong a user writes (benchmarks.peers.one_light_fragment is its twin).
uniform vec3 light_dir;             // eye space, unit, toward the light
uniform vec3 ambient;
uniform vec3 kd;
uniform vec3 ks;
uniform float shininess;
in vec3 v_position;
in vec3 v_normal;
out vec4 f_color;
void main() {
    vec3 N = normalize(v_normal);
    vec3 L = light_dir;
    vec3 V = normalize(-v_position);
    vec3 H = normalize(L + V);
    float diffuse = max(dot(N, L), 0.0);
    float specular = pow(max(dot(N, H), 0.0), shininess);
    f_color = vec4(ambient + kd * diffuse + ks * specular, 1.0);
}
"""


def _lit_fragment_source() -> str:
    from softpipe.light import packed as m
    return LIT_FRAGMENT % dict(max_lights=MAX_LIGHTS, cols=LIGHT_COLUMNS, kind=m.LIGHT_KIND,
                               directional=m.LIGHT_DIRECTIONAL, position=m.LIGHT_POSITION,
                               att=m.LIGHT_ATTENUATION, cutoff=m.LIGHT_SPOT_COS_CUTOFF,
                               spot_dir=m.LIGHT_SPOT_DIRECTION, spot_exp=m.LIGHT_SPOT_EXPONENT,
                               ambient=m.LIGHT_AMBIENT, diffuse=m.LIGHT_DIFFUSE, specular=m.LIGHT_SPECULAR)


# --------------------------------------------------------------------------
# Installing and opening the peer
# --------------------------------------------------------------------------

def _run_quiet(cmd: List[str]) -> Tuple[bool, str]:
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    except (OSError, subprocess.SubprocessError) as e:
        return False, f"{type(e).__name__}: {e}"
    tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
    return p.returncode == 0, " / ".join(tail)


def install_peer(log: Callable[[str], None] = print) -> List[str]:
    """Install what the peer needs where it is missing; returns what could not be installed (messages)."""
    problems: List[str] = []
    if shutil.which("dpkg-query"):
        missing = [p for p in DEBIAN_PACKAGES
                   if "install ok installed" not in _run_quiet(["dpkg-query", "-W", "-f=${Status}", p])[1]]
        if missing:
            if os.geteuid() != 0 or not shutil.which("apt-get"):
                problems.append(f"Debian packages {' '.join(missing)} are missing and cannot be installed here "
                                f"({'not root' if os.geteuid() != 0 else 'no apt-get'}): "
                                f"apt-get install -y {' '.join(missing)}")
            else:
                log(f"installing {' '.join(missing)} (apt-get) ...")
                ok, out = _run_quiet(["apt-get", "install", "-y", "-q", *missing])
                if not ok:
                    _run_quiet(["apt-get", "update", "-q"])
                    ok, out = _run_quiet(["apt-get", "install", "-y", "-q", *missing])
                if not ok:
                    problems.append(f"apt-get install -y {' '.join(missing)} failed: {out}")
    else:
        log("no dpkg here: not checking Mesa's packages (the context will tell)")
    try:
        import moderngl  # noqa: F401
    except ImportError:
        log(f"installing {MODERNGL_REQUIREMENT} (pip, into {sys.executable}) ...")
        ok, out = _run_quiet([sys.executable, "-m", "pip", "install", "-q", MODERNGL_REQUIREMENT])
        if not ok:
            problems.append(f"pip install {MODERNGL_REQUIREMENT} failed: {out}")
        importlib.invalidate_caches()            # the new package, importable in this process
    return problems


def peer_context() -> Tuple[object, Optional[str]]:
    """(moderngl context on llvmpipe, None), or (None, why not)."""
    try:
        import moderngl
    except ImportError as e:
        return None, (f"moderngl is not installed ({e}); `pip install {MODERNGL_REQUIREMENT}` "
                      "(make bench-peers installs it)")
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=430)
    except Exception as e:  # glcontext raises plain Exceptions for a missing libEGL / driver
        return None, (f"moderngl could not create an OpenGL 4.3 context on surfaceless EGL ({type(e).__name__}: "
                      f"{e}); Mesa's llvmpipe needs Debian's {' '.join(DEBIAN_PACKAGES)}")
    renderer = ctx.info.get("GL_RENDERER", "?")
    if "llvmpipe" not in renderer:
        ctx.release()
        return None, f"the EGL context is not Mesa's llvmpipe but {renderer!r}"
    return ctx, None


def llvmpipe_threads() -> Dict[str, object]:
    """LP_NUM_THREADS as set (or llvmpipe's default: one per CPU) and the llvmpipe threads seen running."""
    seen = 0
    try:
        for task in Path("/proc/self/task").iterdir():
            try:
                if (task / "comm").read_text().startswith("llvmpipe"):
                    seen += 1
            except OSError:
                pass
    except OSError:
        seen = None
    env = os.environ.get("LP_NUM_THREADS")
    return {"LP_NUM_THREADS": env, "threads_running": seen,
            "meaning": f"LP_NUM_THREADS={env}" if env else f"LP_NUM_THREADS unset: llvmpipe's default, one per "
                                                          f"CPU ({os.cpu_count()})"}


# --------------------------------------------------------------------------
# A scene on llvmpipe
# --------------------------------------------------------------------------

class PeerUnsupported(ValueError):
    """A draw this module has no GLSL twin for."""


def _f4(a) -> bytes:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64), dtype="f4").tobytes()


def _mat(m) -> bytes:
    """A numpy matrix (row-major, column vectors) as GL wants it: column-major float32."""
    return _f4(np.asarray(m, dtype=np.float64).T)


def _set(prog, name: str, data: bytes) -> None:
    if name in prog:               # the GLSL compiler drops uniforms a program does not use
        prog[name].write(data)


def _specular_model(fragment) -> int:
    """0 (Blinn-Phong) or 1 (Phong) for the lit fragment shaders the scenes use; PeerUnsupported otherwise."""
    import softpipe.programs.phong  # noqa: F401
    from softpipe.programs import get_program

    from . import scenes
    if fragment is get_program("phong").fragment or fragment is scenes.blinn_phong_fragment:
        return 0
    if fragment is get_program("phong_phong_specular").fragment or fragment is scenes.phong_fragment:
        return 1
    raise PeerUnsupported(f"no GLSL twin for the fragment shader {fragment!r}")


class LlvmpipeScene:
    """A :class:`Scene` uploaded to a moderngl context: ``frame()`` renders it, ``image()`` reads it back."""

    def __init__(self, ctx, scene: Scene):
        self.ctx, self.scene = ctx, scene
        w, h = scene.width, scene.height
        if scene.pattern is not None or scene.prepare is not None:
            raise PeerUnsupported(f"{scene.name}: sample patterns and prepare steps have no peer here")
        self.fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer((w, h), 4, dtype="f1")],
                                   depth_attachment=ctx.depth_renderbuffer((w, h)))
        self.buffer = bytearray(w * h * 4)
        self.draws = []
        self._resources = [self.fbo]
        for d in scene.draws:
            self.draws.append(self._upload(d))

    def _program(self, vertex: str, fragment: str):
        prog = self.ctx.program(vertex_shader=vertex, fragment_shader=fragment)
        self._resources.append(prog)
        return prog

    def _buffer(self, array, dtype="f4"):
        buf = self.ctx.buffer(np.ascontiguousarray(array, dtype=dtype).tobytes())
        self._resources.append(buf)
        return buf

    def _upload(self, d: dict):
        unsupported = {k: d[k] for k in ("blend", "interpolation", "viewport", "polygon_offset", "sample_shading",
                                         "path") if d.get(k) not in (None, "sample", "auto")}
        topology = d.get("topology", "triangles")
        if topology not in PEER_TOPOLOGIES or d.get("depth_test", "less") != "less" \
                or not d.get("depth_write", True) or unsupported or d.get("line_width", 1.0) != 1.0 \
                or d.get("polygon_mode", "fill") != "fill":
            raise PeerUnsupported(f"{self.scene.name}: draw state {unsupported or topology} has no peer")
        vs, fs, u = d.get("vertex_shader"), d.get("fragment_shader"), d.get("uniforms") or {}
        positions = np.asarray(d["positions"], dtype=np.float64)
        if fs is not None and vs is None:
            raise PeerUnsupported(f"{self.scene.name}: a fragment shader without a vertex shader")
        if vs is None:                                   # clip coordinates and a color varying
            prog = self._program(CLIP_VERTEX, COLOR_FRAGMENT)
            content = [(self._buffer(positions), "4f", "in_position"),
                       (self._buffer(d["varyings"]["color"]), "3f", "in_color")]
        elif vs is color_vertex and fs is None:
            prog = self._program(MVP_VERTEX, COLOR_FRAGMENT)
            _set(prog, "mvp", _mat(u["mvp"]))
            content = [(self._buffer(positions[:, :3]), "3f", "in_position"),
                       (self._buffer(d["attributes"]["color"]), "3f", "in_color")]
        elif fs is one_light_fragment:
            prog = self._program(LIT_VERTEX, ONE_LIGHT_FRAGMENT)
            for name in ("model_view", "projection"):
                _set(prog, name, _mat(u[name]))
            _set(prog, "normal_matrix", _mat(np.asarray(u["normal_matrix"])[:3, :3]))
            for name in ("light_dir", "ambient", "kd", "ks"):
                _set(prog, name, _f4(u[name]))
            _set(prog, "shininess", _f4([u["shininess"]]))
            content = [(self._buffer(positions[:, :3]), "3f", "in_position"),
                       (self._buffer(d["attributes"]["normal"]), "3f", "in_normal")]
        else:
            model = _specular_model(fs)
            prog = self._program(LIT_VERTEX, _lit_fragment_source())
            for name in ("model_view", "projection"):
                _set(prog, name, _mat(u[name]))
            _set(prog, "normal_matrix", _mat(np.asarray(u["normal_matrix"])[:3, :3]))
            m = u["material"]
            for name in ("ke", "ka", "kd", "ks"):
                _set(prog, name, _f4(getattr(m, name)))
            _set(prog, "shininess", _f4([m.shininess]))
            _set(prog, "opacity", _f4([m.opacity]))
            lighting = u["lighting"]
            if getattr(lighting, "shadows", None) is not None:
                raise PeerUnsupported(f"{self.scene.name}: shadows have no peer")
            lights = np.asarray(lighting.lights, dtype=np.float64)
            if len(lights) > MAX_LIGHTS:
                raise PeerUnsupported(f"{self.scene.name}: {len(lights)} lights, the GLSL takes {MAX_LIGHTS}")
            packed = np.zeros((MAX_LIGHTS, LIGHT_COLUMNS))
            packed[:len(lights)] = lights
            _set(prog, "lights", _f4(packed.ravel()))
            _set(prog, "num_lights", np.int32(len(lights)).tobytes())
            _set(prog, "global_ambient", _f4(lighting.global_ambient))
            _set(prog, "specular_model", np.int32(model).tobytes())
            P = np.asarray(u["projection"])
            _set(prog, "orthographic", np.int32(bool(np.all(P[3, :3] == 0.0))).tobytes())
            content = [(self._buffer(positions[:, :3]), "3f", "in_position"),
                       (self._buffer(d["attributes"]["normal"]), "3f", "in_normal")]
        indices = d.get("indices")
        ibo = None if indices is None else self._buffer(np.asarray(indices).reshape(-1), "u4")
        content = [(b, f, n) for b, f, n in content if n in prog]
        vao = self.ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4)
        self._resources.append(vao)
        cull = d.get("cull", "none")
        if cull not in ("none", "back", "front"):
            raise PeerUnsupported(f"{self.scene.name}: cull={cull!r}")
        return vao, cull, d.get("front_face", "ccw"), topology, float(d.get("point_size", 1.0))

    def frame(self) -> float:
        """Clear, draw, finish, read back: seconds."""
        import moderngl
        ctx = self.ctx
        start = time.perf_counter()
        self.fbo.use()
        ctx.disable_direct(0x0BD0)                     # GL_DITHER
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        ctx.disable(moderngl.BLEND)
        self.fbo.clear(*self.scene.clear_color, depth=1.0)
        for vao, cull, front, topology, point_size in self.draws:
            if cull == "none":
                ctx.disable(moderngl.CULL_FACE)
            else:
                ctx.enable(moderngl.CULL_FACE)
                ctx.cull_face = cull
            ctx.front_face = front
            ctx.point_size = point_size
            vao.render(getattr(moderngl, PEER_TOPOLOGIES[topology]))
        ctx.finish()
        self.fbo.read_into(self.buffer, components=4, alignment=1)
        return time.perf_counter() - start

    def image(self) -> np.ndarray:
        """The last frame, uint8 [H, W, 4], row 0 at the top (softpipe's orientation)."""
        return np.frombuffer(self.buffer, np.uint8).reshape(self.scene.height, self.scene.width, 4)[::-1]

    def release(self) -> None:
        for r in reversed(self._resources):
            r.release()
        self._resources = []


# --------------------------------------------------------------------------
# Timing and comparing
# --------------------------------------------------------------------------

def alternate(softpipe_frame: Callable[[], float], peer_frame: Callable[[], float], rounds: int
              ) -> Tuple[List[float], List[float], Dict[str, float]]:
    """Run both ``rounds`` times, ABBA: softpipe first in even rounds, the peer first in odd ones.

    Returns (softpipe seconds, peer seconds, {"softpipe_cpu", "softpipe_wall", "peer_cpu", "peer_wall"}).
    """
    times = {"softpipe": [], "peer": []}
    cpu = {"softpipe_cpu": 0.0, "softpipe_wall": 0.0, "peer_cpu": 0.0, "peer_wall": 0.0}
    sides = (("softpipe", softpipe_frame), ("peer", peer_frame))
    for k in range(rounds):
        for name, frame in (sides if k % 2 == 0 else sides[::-1]):
            c0, w0 = time.process_time(), time.perf_counter()
            times[name].append(frame())
            cpu[name + "_cpu"] += time.process_time() - c0
            cpu[name + "_wall"] += time.perf_counter() - w0
    return times["softpipe"], times["peer"], cpu


def summarize(softpipe_s: Sequence[float], peer_s: Sequence[float]) -> Dict[str, float]:
    """Medians (ms), softpipe/peer as the ratio of the medians, and the spread of the per-round ratios."""
    if not softpipe_s or len(softpipe_s) != len(peer_s):
        raise ValueError("need the same number (≥ 1) of frames on each side")
    a, b = statistics.median(softpipe_s), statistics.median(peer_s)
    paired = sorted(x / y for x, y in zip(softpipe_s, peer_s))
    q = np.quantile(paired, [0.25, 0.75]) if len(paired) > 1 else (paired[0], paired[0])
    return {"softpipe_ms": 1e3 * a, "llvmpipe_ms": 1e3 * b, "ratio": a / b,
            "paired_ratio_median": statistics.median(paired), "paired_ratio_q1": float(q[0]),
            "paired_ratio_q3": float(q[1]), "paired_ratio_min": paired[0], "paired_ratio_max": paired[-1]}


def compare_images(a: np.ndarray, b: np.ndarray) -> Dict[str, float]:
    """8-bit RGB images compared: max and mean |difference|, shares of pixels differing at all and by > 1."""
    a, b = np.asarray(a)[..., :3].astype(np.int16), np.asarray(b)[..., :3].astype(np.int16)
    if a.shape != b.shape:
        raise ValueError(f"images of different shapes {a.shape} and {b.shape}")
    d = np.abs(a - b)
    per_pixel = d.max(axis=-1)
    n = per_pixel.size
    return {"max_abs": int(d.max()), "mean_abs": float(d.mean()),
            "pixels_differing": int(np.count_nonzero(per_pixel)),
            "share_differing": float(np.count_nonzero(per_pixel)) / n,
            "share_over_1": float(np.count_nonzero(per_pixel > 1)) / n, "pixels": n}


def _id_colors(n_triangles: int) -> np.ndarray:
    """Triangle t's index as an exact 8-bit RGB color (t + 1: 0 is left for "no triangle"), per corner."""
    t = np.arange(1, n_triangles + 1)
    rgb = np.stack([t & 255, (t >> 8) & 255, (t >> 16) & 255], 1) / 255.0
    return np.repeat(rgb, 3, axis=0)


def _ids(image: np.ndarray) -> np.ndarray:
    i = np.asarray(image)[..., :3].astype(np.int64)
    return i[..., 0] | (i[..., 1] << 8) | (i[..., 2] << 16)


def coverage_check(ctx, scene: Scene) -> Optional[Dict[str, object]]:
    """Which triangle each pixel shows, softpipe vs llvmpipe, for a clip-coordinate scene (None for others).

    One untimed frame each with every triangle a constant color, its index (exact in 8 bits,
    so the interpolation cannot change it): the share of pixels whose triangle differs, with
    softpipe given the scene's float64 positions and given them rounded to float32 (what GL
    is given). Equal ids everywhere means the same coverage, fill rule and depth order.
    """
    if any(d.get("vertex_shader") is not None or d.get("indices") is not None for d in scene.draws):
        return None
    if sum(len(d["positions"]) // 3 for d in scene.draws) >= (1 << 24) - 1:
        return None
    out: Dict[str, object] = {}
    first, draws = 0, []
    for d in scene.draws:
        n = len(d["positions"]) // 3
        draws.append(dict(d, varyings={"color": _id_colors(first + n)[3 * first:]}))
        first += n
    ids_scene = replace(scene, draws=draws, clear_color=(0.0, 0.0, 0.0, 1.0))
    peer = LlvmpipeScene(ctx, ids_scene)
    try:
        peer.frame()
        theirs = _ids(peer.image())
    finally:
        peer.release()
    for label, cast in (("float64", np.float64), ("float32", np.float32)):
        fb = Framebuffer(scene.width, scene.height)
        sc = replace(ids_scene, draws=[dict(d, positions=np.asarray(d["positions"]).astype(cast).astype(np.float64))
                                       for d in ids_scene.draws])
        render_frame(sc, fb)
        ours = _ids(fb.to_uint8())
        differ = ours != theirs
        out[f"positions_{label}"] = {"pixels_other_triangle": int(np.count_nonzero(differ)),
                                     "share_other_triangle": float(np.count_nonzero(differ)) / differ.size,
                                     "pixels_covered": int(np.count_nonzero(theirs))}
    return out


def run_peer_scene(ctx, name: str, frames: int = DEFAULT_FRAMES, scale: float = 1.0,
                   log: Callable[[str], None] = print, keep_images: bool = False) -> dict:
    """One scene, softpipe and llvmpipe alternated: the result row."""
    scene = PEER_SCENES[name](scale)
    fb = Framebuffer(scene.width, scene.height)
    peer = LlvmpipeScene(ctx, scene)
    try:
        first_sp = render_frame(scene, fb)[0]
        first_gl = peer.frame()
        render_frame(scene, fb), peer.frame()                # one more untimed each
        log(f"  {name}: first frames softpipe {first_sp * 1e3:.0f} ms, llvmpipe {first_gl * 1e3:.0f} ms; "
            f"{frames} alternated rounds ...")
        stages: List[dict] = []

        def softpipe_frame() -> float:
            seconds, st = render_frame(scene, fb)
            stages.append(st)
            return seconds

        sp, gl, cpu = alternate(softpipe_frame, peer.frame, frames)
        images = (fb.to_uint8(), peer.image().copy())
    finally:
        peer.release()
    coverage = coverage_check(ctx, scene)
    row = {"scene": name, "description": scene.description, "shading": scene.shading,
           "width": scene.width, "height": scene.height, "triangles": scene.triangles, "scale": scale,
           "rounds": frames, "softpipe_frames_ms": [1e3 * t for t in sp], "llvmpipe_frames_ms": [1e3 * t for t in gl],
           "first_softpipe_ms": 1e3 * first_sp, "first_llvmpipe_ms": 1e3 * first_gl,
           "softpipe_cpu_per_wall": cpu["softpipe_cpu"] / cpu["softpipe_wall"],
           "llvmpipe_cpu_per_wall": cpu["peer_cpu"] / cpu["peer_wall"],
           "softpipe_stages_ms": {k: 1e3 * statistics.median(s.get(k, 0.0) for s in stages)
                                  for k in dict.fromkeys(k for s in stages for k in s)},
           **summarize(sp, gl), "image_difference": compare_images(*images), "coverage": coverage}
    if keep_images:
        row["images"] = images
    return row


# --------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------

def _ms(x: float) -> str:
    return f"{x:.0f}" if x >= 100 else f"{x:.1f}" if x >= 10 else f"{x:.2f}"


def _coverage_cell(coverage: Optional[dict]) -> str:
    if not coverage:
        return "-"
    return "/".join(str(coverage[f"positions_{k}"]["pixels_other_triangle"]) for k in ("float64", "float32"))


#: The issues' targets against llvmpipe (softpipe ÷ llvmpipe, the medians of a run at full size): scene →
#: (issue, at most this ratio).
TARGETS = {
    "sphere200k-color": (35, 0.5), "tiny": (35, 0.35), "bunny": (35, 0.5), "sphere200k": (35, 0.5),
    "bunny-onelight": (35, 0.8), "bunny-wireframe": (29, 1.0), "points200k": (29, 1.0),
}


def target_rows(rows: List[dict]) -> List[dict]:
    """The :data:`TARGETS` this run measured (full-size scenes), each with its ratio and whether it is met."""
    out = []
    for r in rows:
        if r["scene"] in TARGETS and r.get("scale", 1.0) == 1.0:
            issue, most = TARGETS[r["scene"]]
            out.append({"issue": issue, "target": f"{r['scene']} ≤ {most}× llvmpipe", "measured": f"{r['ratio']:.2f}",
                        "met": r["ratio"] <= most})
    return out


def format_table(rows: List[dict]) -> str:
    from .run import _table
    body = []
    for r in rows:
        d = r["image_difference"]
        body.append([r["scene"], f"{r['width']}x{r['height']}", f"{r['triangles']:,}", _ms(r["softpipe_ms"]),
                     _ms(r["llvmpipe_ms"]), f"{r['ratio']:.2f}",
                     f"{r['paired_ratio_q1']:.2f}-{r['paired_ratio_q3']:.2f}", str(r["rounds"]),
                     f"{r['softpipe_cpu_per_wall']:.2f}/{r['llvmpipe_cpu_per_wall']:.2f}",
                     str(d["max_abs"]), f"{d['mean_abs']:.4f}", f"{100 * d['share_differing']:.3f}",
                     f"{100 * d['share_over_1']:.3f}", _coverage_cell(r.get("coverage"))])
    return _table(["scene", "size", "triangles", "softpipe ms", "llvmpipe ms", "sp/llvm", "paired IQR", "n",
                   "cpu/wall sp/llvm", "max diff", "mean diff", "% px differ", "% px > 1/255",
                   "px other tri f64/f32"], body)


def run(names: Sequence[str] = (), frames: int = DEFAULT_FRAMES, scale: float = 1.0, ctx=None,
        log: Callable[[str], None] = print, keep_images: bool = False) -> dict:
    """Every scene of ``names`` (default: all of :data:`PEER_SCENES`) against llvmpipe; the report.

    ``report["skipped"]`` is the reason when there is no llvmpipe context (then no scene ran).
    """
    names = list(names) or list(PEER_SCENES)
    bad = [n for n in names if n not in PEER_SCENES]
    if bad:
        raise ValueError(f"no peer for scene(s) {', '.join(bad)}; the peer scenes are: {', '.join(PEER_SCENES)}")
    report = {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
              "command": " ".join([Path(sys.executable).name, "-m", "benchmarks.peers", *sys.argv[1:]]),
              "machine": machine_info(), "source": source_state(), "settings": {"frames": frames, "scale": scale},
              "scenes": [], "failed": [], "skipped": None}
    own = ctx is None
    if own:
        ctx, why = peer_context()
        if ctx is None:
            report["skipped"] = why
            return report
    try:
        try:
            cpus = sorted(os.sched_getaffinity(0))
        except AttributeError:
            cpus = None
        report["peer"] = {"renderer": ctx.info.get("GL_RENDERER"), "version": ctx.info.get("GL_VERSION"),
                          "moderngl": __import__("moderngl").__version__}
        report["threads"] = {"numba_threads": numba.get_num_threads(), "cpus": cpus, "llvmpipe": llvmpipe_threads()}
        lp = report["threads"]["llvmpipe"]
        log(f"softpipe vs {report['peer']['renderer']} ({report['peer']['version']}), {frames} rounds per scene, "
            f"scale {scale}")
        log(f"threads: numba {numba.get_num_threads()}; llvmpipe {lp['meaning']}, {lp['threads_running']} "
            f"llvmpipe threads running; both on CPUs {cpus}")
        for name in names:
            try:
                report["scenes"].append(run_peer_scene(ctx, name, frames, scale, log, keep_images))
            except Exception as e:
                log(f"  {name}: FAILED: {type(e).__name__}: {e}")
                report["failed"].append({"scene": name, "error": f"{type(e).__name__}: {e}",
                                         "traceback": traceback.format_exc()})
        report["threads"]["llvmpipe"] = llvmpipe_threads()
        report["load_average_at_end"] = list(os.getloadavg())
    finally:
        if own:
            ctx.release()
    return report


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers", description=__doc__.split("\n\n")[0],
                                     epilog="scenes: " + ", ".join(PEER_SCENES))
    parser.add_argument("scenes", nargs="*", metavar="SCENE", help="scenes to run (default: all peer scenes)")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help=f"alternated rounds (one warm frame of each) per scene (default {DEFAULT_FRAMES})")
    parser.add_argument("--scale", type=float, default=1.0, help="scene size, 0 < S <= 1 (default 1)")
    parser.add_argument("--threads", type=int, default=None,
                        help="threads on both sides: numba.set_num_threads(N) and LP_NUM_THREADS=N for llvmpipe "
                             "(unless LP_NUM_THREADS is set); default: numba's default and llvmpipe's, one per core")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON,
                        help=f"where the results go (default {DEFAULT_JSON.relative_to(REPO_ROOT)})")
    parser.add_argument("--install", action="store_true",
                        help="first install what is missing: Debian's Mesa/EGL packages (apt-get, as root) and "
                             "moderngl (pip, into this interpreter)")
    parser.add_argument("--save-images", type=Path, default=None, metavar="DIR",
                        help="write each scene's two last frames as DIR/SCENE-softpipe.png and -llvmpipe.png")
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    if not 0.0 < args.scale <= 1.0:
        parser.error("--scale must be in (0, 1]")
    bad = [n for n in args.scenes if n not in PEER_SCENES]
    if bad:
        parser.error(f"no peer for scene(s) {', '.join(bad)}; the peer scenes are: {', '.join(PEER_SCENES)}")
    if args.threads is not None:
        if not 1 <= args.threads <= numba.config.NUMBA_NUM_THREADS:
            parser.error(f"--threads must be between 1 and {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS)")
        numba.set_num_threads(args.threads)
        os.environ.setdefault("LP_NUM_THREADS", str(args.threads))   # read when llvmpipe starts its threads
    keep_freed_memory()     # a program of softpipe's own, as the softpipe command is (softpipe/core/runtime.py)
    problems = install_peer() if args.install else []
    report = run(args.scenes, frames=args.frames, scale=args.scale, keep_images=args.save_images is not None)
    if report["skipped"]:
        print("SKIPPED the llvmpipe comparison: " + report["skipped"])
        for p in problems:
            print("  could not install: " + p)
        return 0
    print()
    if report["scenes"]:
        print(format_table(report["scenes"]))
        print("\nsp/llvm = softpipe median / llvmpipe median; paired IQR = quartiles of the per-round ratios; "
              "diffs in 8-bit RGB levels; px other tri = pixels showing another triangle than on llvmpipe "
              "(clip-coordinate scenes, an untimed frame of triangle ids; softpipe given the float64 positions / "
              "the float32 ones GL gets)")
        targets = target_rows(report["scenes"])
        report["targets"] = targets
        if targets:
            from .run import format_targets
            print("\n" + format_targets(targets))
    if args.save_images is not None:
        from PIL import Image
        args.save_images.mkdir(parents=True, exist_ok=True)
        for r in report["scenes"]:
            for side, img in zip(("softpipe", "llvmpipe"), r.pop("images")):
                Image.fromarray(np.ascontiguousarray(img[..., :3])).save(args.save_images / f"{r['scene']}-{side}.png")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    print(f"results written to {args.json}")
    return 1 if report["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
