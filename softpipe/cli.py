"""The command line: ``softpipe render``, ``softpipe turntable``, ``softpipe demo``, ``softpipe programs``.

    softpipe render bunny -o bunny.png              a bundled model (softpipe.models), framed, three studio lights
    softpipe render MODEL.obj -o out.png            any OBJ file, the same way
    softpipe render SCENE.toml -o out.png           a scene file (softpipe.scenefile)
    softpipe turntable MODEL -o spin.gif            an animated GIF, the camera circling the model
    softpipe demo                                   the default scene
    softpipe programs                               the shading programs and sample patterns

Errors are one line on stderr and exit status 2; ``--help`` documents every option.
Every render prints where it wrote and how long it took; progress goes to stderr.

This module only turns options into a :class:`~softpipe.scene.Scene` (a model through
:meth:`Scene.from_model <softpipe.scene.Scene.from_model>`, a scene file through
:func:`softpipe.scenefile.load_scene`) and draws it with
:func:`softpipe.drawing.render_scene`, as the Python API does.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import sys
import time
import warnings
from pathlib import Path
from typing import List, Optional, Sequence, Tuple

__all__ = ["main", "build_parser", "CLIError"]

MAX_FRAMES = 3600


class CLIError(Exception):
    """A user error: printed as one line, exit status 2."""


class _UsageError(CLIError):
    """A bad command line; ``prog`` is the (sub)command whose options were wrong."""

    def __init__(self, prog: str, message: str) -> None:
        self.prog = prog
        super().__init__(message)


class _Parser(argparse.ArgumentParser):
    """argparse, but a bad command line is one line (raised, so that main() can return 2)."""

    def error(self, message: str):  # noqa: D102 (argparse's hook)
        raise _UsageError(self.prog, f"{message} (see '{self.prog} --help')")


# ---------------------------------------------------------------------------- option values


def _size(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of pixels, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of pixels, got {v}")
    return v


def _width_height(text: str) -> Tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX×*]\s*(\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, e.g. 640x480, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive width and height, got {text!r}")
    return w, h


def _color(text: str) -> Tuple[float, ...]:
    """'0.1,0.2,0.3[,1]' (linear 0..1), or a CSS color ('#202830', 'white', 'rgb(20,30,40)')."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if len(parts) in (3, 4) and all(re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", p) for p in parts):
        values = tuple(float(p) for p in parts)
        if not all(0.0 <= v <= 1.0 for v in values):
            raise argparse.ArgumentTypeError(f"color components must be in 0..1, got {text!r}")
        return values
    from PIL import ImageColor
    try:
        rgb = ImageColor.getrgb(text.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a color such as '0.1,0.1,0.12', '#1a1a20' or 'white', "
                                         f"got {text!r}") from None
    return tuple(c / 255.0 for c in rgb)


def _angle(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an angle in degrees, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite angle, got {text!r}")
    return v


def _fovy(text: str) -> float:
    v = _angle(text)
    if not 0.0 < v < 180.0:
        raise argparse.ArgumentTypeError(f"expected a field of view in (0, 180) degrees, got {text!r}")
    return v


def _frames(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of frames, got {text!r}") from None
    if not 1 <= v <= MAX_FRAMES:
        raise argparse.ArgumentTypeError(f"expected 1 to {MAX_FRAMES} frames, got {v}")
    return v


def _fps(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0.1 <= v <= 100.0:
        raise argparse.ArgumentTypeError(f"expected frames per second in 0.1..100, got {text!r}")
    return v


def _pattern(text: str) -> str:
    from .sampling import pattern_named
    try:
        pattern_named(text)
    except (ValueError, TypeError) as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


# ---------------------------------------------------------------------------- the parser


def _programs() -> List[str]:
    from .shaders import PROGRAMS
    return sorted(PROGRAMS)


def _add_view_options(p: argparse.ArgumentParser, default_size: str) -> None:
    from .scene import default_program
    g = p.add_argument_group("image")
    g.add_argument("--size", type=_width_height, metavar="WxH",
                   help=f"image size in pixels, e.g. 640x480 (default {default_size}, or the scene's [render] size)")
    g.add_argument("--width", type=_size, metavar="W", help="image width in pixels (instead of --size)")
    g.add_argument("--height", type=_size, metavar="H", help="image height in pixels (instead of --size)")
    g.add_argument("--background", type=_color, metavar="COLOR",
                   help="clear color: r,g,b[,a] in 0..1 (linear), or #rrggbb, or a CSS name (default 0.08,0.09,0.12)")
    g.add_argument("--samples", type=_pattern, metavar="PATTERN",
                   help="sample pattern: 1 (default), grid4, grid9, grid16, rgss4 (the standard 4x rotated grid), "
                        "jitter16, random8, ...; the samples of a pixel are averaged (supersampling)")
    g.add_argument("--msaa", action="store_true",
                   help="shade once per pixel and triangle at the pixel centre (multisampling) instead of "
                        "once per sample; uses rgss4 unless --samples is given")
    g = p.add_argument_group("shading")
    g.add_argument("--program", metavar="NAME",
                   help=f"shading program, one of: {', '.join(_programs())} (default: 'textured' for a textured "
                        f"mesh when that program is registered, else 'phong' when registered, else 'normals'; "
                        f"now: {default_program()!r}); for a scene file it replaces every mesh's program")
    g.add_argument("--texture", metavar="IMAGE",
                   help="diffuse texture for an OBJ model with texture coordinates (vt), e.g. "
                        "spot_texture.png (the bundled 'spot' has its own); passed to the program as uniform "
                        "'texture'")
    g.add_argument("--cull", choices=("back", "front", "none"),
                   help="which faces to drop: back (default), front or none")
    g.add_argument("--wireframe", action="store_true",
                   help="draw the triangle edges (after clipping and culling) over the image; hidden edges stay hidden")
    g.add_argument("--wire-color", type=_color, metavar="COLOR", help="wireframe color (default white)")
    g = p.add_argument_group("camera (framed: it looks at the centre of everything and sees all of it)")
    g.add_argument("--azimuth", type=_angle, metavar="DEG",
                   help="camera angle about the vertical (y) axis, from +z toward +x (default 30)")
    g.add_argument("--elevation", type=_angle, metavar="DEG",
                   help="camera angle above the horizontal (xz) plane (default 20)")
    g.add_argument("--fovy", type=_fovy, metavar="DEG", help="vertical field of view in degrees (default 35)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")


def build_parser() -> argparse.ArgumentParser:
    from .models import MODELS
    models = ", ".join(MODELS)
    parser = _Parser(
        prog="softpipe",
        description="softpipe: the graphics pipeline of a GPU, on the CPU, in Python.",
        epilog="examples:\n"
               "  softpipe render bunny -o bunny.png\n"
               "  softpipe render spot --azimuth 210 -o spot.png\n"
               "  softpipe render model.obj --texture model.png -o model.png\n"
               "  softpipe render examples/scene.toml -o scene.png --size 1280x960\n"
               "  softpipe render teapot --wireframe --stages out/stages -o teapot.png\n"
               "  softpipe turntable suzanne -o spin.gif --frames 36\n"
               f"\nmodels bundled with softpipe (INPUT may name one): {models}.\n"
               "\nerrors print one line on stderr and exit with status 2.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    render = sub.add_parser(
        "render", help="render an OBJ model or a TOML scene file to an image",
        description="Render INPUT to an image and print where it was written and how long it took.\n\n"
                    "INPUT.obj: a Wavefront OBJ model (with its MTL materials, if any), seen by a camera that "
                    "frames it, under a key/fill/rim set of three directional lights that follow the camera.\n"
                    f"INPUT a bundled model's name ({models}): that model, the same way.\n"
                    "INPUT.toml: a scene file (see examples/scene.toml); the options below override its "
                    "[render] settings, and --azimuth/--elevation its framed camera.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    render.add_argument("input", metavar="INPUT", help="a .obj model, a bundled model's name or a .toml scene file")
    render.add_argument("-o", "--output", metavar="IMAGE",
                        help="image to write; the format follows the extension (.png, .jpg, .bmp, .tif, ...); "
                             "default out/NAME.png")
    _add_view_options(render, "640x480")
    render.add_argument("--stages", metavar="DIR",
                        help="also trace every draw and write each stage's picture (vertices, primitives, coverage, "
                             "depth, overdraw, final) and a contact sheet into DIR (one folder per draw when there "
                             "are several); prints the paths")
    render.set_defaults(run=_render)

    turn = sub.add_parser(
        "turntable", help="render an animation of the camera circling a model (GIF)",
        description="Render INPUT from FRAMES camera positions evenly spaced on one turn about the vertical "
                    "axis and write them as an animated GIF (or an animated PNG for a .png output). Progress "
                    "('frame 12/36') goes to stderr.\n\n"
                    "INPUT is a .obj model, a bundled model's name or a .toml scene file (a scene with its own "
                    "[camera] eye turns that eye about the target). The studio lights follow the camera, so the model is seen turning "
                    "under fixed lights. Frames that come out identical (a symmetric model) are merged by the "
                    "GIF writer.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    turn.add_argument("input", metavar="INPUT", help="a .obj model, a bundled model's name or a .toml scene file")
    turn.add_argument("-o", "--output", metavar="ANIMATION", help="a .gif (or .png) to write; default out/NAME.gif")
    turn.add_argument("--frames", type=_frames, default=36, metavar="N",
                      help=f"number of frames in one turn (default 36, at most {MAX_FRAMES})")
    turn.add_argument("--fps", type=_fps, default=15.0, help="frames per second when played (default 15)")
    _add_view_options(turn, "320x240")
    turn.set_defaults(run=_turntable)

    demo = sub.add_parser("demo", help="render the default scene to a PNG and print its path",
                          description="Render the default scene (a few shapes on a ground plane, in "
                                      "perspective) to a PNG and print where it was written.")
    demo.add_argument("-o", "--output", default="out/demo.png", help="PNG to write (default: out/demo.png)")
    demo.add_argument("--width", type=_size, default=640, help="image width in pixels (default 640)")
    demo.add_argument("--height", type=_size, default=480, help="image height in pixels (default 480)")
    demo.set_defaults(run=_demo)

    programs = sub.add_parser("programs", help="list the shading programs and sample patterns",
                              description="List the registered shading programs (for --program and a scene's "
                                          "program keys) and the sample pattern names (for --samples).")
    programs.set_defaults(run=_list_programs)
    return parser


# ---------------------------------------------------------------------------- commands


def _demo(args) -> int:
    from .demo import render_demo
    start = time.perf_counter()
    fb = render_demo(args.width, args.height)
    path = fb.save(args.output)
    print(f"softpipe demo: wrote {path.resolve()} ({args.width}×{args.height}, "
          f"{time.perf_counter() - start:.2f} s)")
    return 0


def _list_programs(args) -> int:
    from .scene import default_program
    from .shaders import PROGRAMS
    width = max(len(n) for n in PROGRAMS)
    print("shading programs (--program NAME):")
    for name in sorted(PROGRAMS):
        print(f"  {name.ljust(width)}  {PROGRAMS[name].description}")
    print(f"default: {default_program()}")
    print("sample patterns (--samples NAME): 1, grid4, grid9, grid16, rgss4, jitterN (N square), randomN (N ≤ 64)")
    return 0


def _note(args, message: str) -> None:
    print(f"softpipe {args.command}: {message}", file=sys.stderr)


def _progress(args, message: str) -> None:
    if not args.quiet:
        print(message, file=sys.stderr, flush=True)


def _check_input(name: str) -> str:
    """The kind of INPUT (".obj" or ".toml"), after a bundled model's name becomes its file."""
    from .models import model_path
    path = os.fspath(model_path(name))  # a bare word that is neither a model nor a file: ValueError
    if not os.path.exists(path):
        raise CLIError(f"{path}: no such file")
    if os.path.isdir(path):
        raise CLIError(f"{path}: is a directory, not a model or scene file")
    kind = Path(path).suffix.lower()
    if kind not in (".obj", ".toml"):
        raise CLIError(f"{path}: expected a .obj model or a .toml scene file")
    return kind


def _image_format(path: str, animated: bool = False) -> str:
    """The pillow format for an output file name (checked before rendering)."""
    from PIL import Image
    ext = Path(path).suffix.lower()
    if animated:
        if ext not in (".gif", ".png"):
            raise CLIError(f"{path}: an animation is written as .gif or .png (animated PNG), not {ext or 'no extension'!r}")
        return "GIF" if ext == ".gif" else "PNG"
    Image.init()
    fmt = Image.registered_extensions().get(ext)
    if fmt is None or fmt not in Image.SAVE:
        raise CLIError(f"{path}: cannot write images with extension {ext or '(none)'!r}; use .png, .jpg, .bmp, .tif, ...")
    return fmt


def _frame_size(args, default: Tuple[int, int]) -> Tuple[Optional[int], Optional[int]]:
    if args.size and (args.width or args.height):
        raise CLIError("give --size or --width/--height, not both")
    if args.size:
        return args.size
    return args.width or default[0], args.height or default[1]


def _model_scene(args, default_size: Tuple[int, int]):
    """The Scene for one model (Scene.from_model: framed camera, studio lights), the options applied.

    The model is read here rather than by Scene.from_model so that its problems are
    worded for the command line (``--texture``) and its warnings are one line each.
    """
    from .models import load_model
    from .scene import Scene

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            mesh = load_model(args.input)
        except UnicodeError as e:
            raise CLIError(f"{args.input}: cannot read: {e}") from None
    for w in caught:
        _note(args, f"warning: {w.message}")
    if mesh.triangle_count == 0:
        raise CLIError(f"{args.input}: the file has no faces (f lines) to render")
    if args.texture:
        if not os.path.isfile(args.texture):
            raise CLIError(f"--texture: {args.texture}: no such file")
        if mesh.uvs is None:
            raise CLIError(f"{args.input} has no texture coordinates (vt), so --texture cannot be applied")
    width, height = _frame_size(args, default_size)
    with warnings.catch_warnings(record=True) as caught:  # a material's texture that cannot be read
        warnings.simplefilter("always")
        scene = Scene.from_model(mesh, texture=args.texture or None, width=width, height=height,
                                 azimuth=30.0 if args.azimuth is None else args.azimuth,
                                 elevation=20.0 if args.elevation is None else args.elevation,
                                 fovy=35.0 if args.fovy is None else args.fovy, path=args.input)
    for w in caught:
        _note(args, f"warning: {w.message}")
    return _apply_options(args, scene, model=True)


def _load_scene_file(args, default_size):
    from .scenefile import load_scene
    if args.texture:
        raise CLIError("--texture applies to an OBJ model; in a scene file give the material a diffuse_texture")
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        scene = load_scene(args.input)
    for message in scene.warnings:
        _note(args, f"warning: {message}")
    if args.size or args.width or args.height:
        w, h = _frame_size(args, (scene.width, scene.height))
        scene = scene.replace(width=w, height=h)
    if args.fovy is not None:
        if scene.camera is not None:
            scene = scene.replace(camera=scene.camera.replace(fovy=args.fovy))
        else:
            scene = scene.replace(frame=dataclasses.replace(scene.frame, fovy=args.fovy))
    if (args.azimuth is not None or args.elevation is not None) and scene.camera is not None:
        raise CLIError(f"{args.input}: --azimuth/--elevation apply to a framed camera, and this scene's "
                       "[camera] gives an eye")
    if scene.camera is None and (args.azimuth is not None or args.elevation is not None):
        f = scene.frame
        scene = scene.replace(frame=dataclasses.replace(
            f, azimuth=f.azimuth if args.azimuth is None else args.azimuth,
            elevation=f.elevation if args.elevation is None else args.elevation))
    return _apply_options(args, scene, model=False)


def _apply_options(args, scene, model: bool):
    from .framebuffer import MAX_DIMENSION, MAX_TOTAL_SAMPLES
    from .sampling import pattern_named
    from .shaders import PROGRAMS
    changes = {}
    if args.background is not None:
        bg = tuple(args.background)
        changes["background"] = bg + ((1.0,) if len(bg) == 3 else ())
    samples = args.samples or ("rgss4" if args.msaa and scene.samples in ("1", "center", "none") else None)
    if samples:
        changes["samples"] = samples
    if args.msaa:
        changes["sample_shading"] = "center"
    if args.program is not None:
        if args.program not in PROGRAMS:
            raise CLIError(f"--program: unknown program {args.program!r}; registered programs: "
                           f"{', '.join(sorted(PROGRAMS))}")
        changes["program"] = args.program
        for obj in scene.objects:
            obj.program = None
    if args.cull is not None:
        changes["cull"] = args.cull
        for obj in scene.objects:
            obj.cull = None
    if args.wireframe:
        changes["wireframe"] = True
    if args.wire_color is not None:
        changes["wireframe_color"] = tuple(args.wire_color[:3])
    scene = scene.replace(**changes)
    count = len(pattern_named(scene.samples))
    if max(scene.width, scene.height) > MAX_DIMENSION:
        raise CLIError(f"image size {scene.width}×{scene.height}: a side may be at most {MAX_DIMENSION} pixels "
                       "(MAX_DIMENSION)")
    if scene.width * scene.height * count > MAX_TOTAL_SAMPLES:
        raise CLIError(f"image size {scene.width}×{scene.height} × {count} samples exceeds the limit "
                       f"MAX_TOTAL_SAMPLES = {MAX_TOTAL_SAMPLES}")
    if args.texture and "textured" not in PROGRAMS and args.program is None:
        _note(args, "note: no 'textured' program is registered yet, so the texture is passed as uniform "
                    f"'texture' but not shown; drawing with {scene_program(scene)!r}")
    return scene


def scene_program(scene) -> str:
    from .scene import program_for
    return ", ".join(sorted({program_for(o, scene.program) for o in scene.objects}))


def _check_options(args, default_size) -> None:
    """The checks that need no file, before the (possibly slow) loading."""
    from .framebuffer import MAX_DIMENSION
    from .shaders import PROGRAMS
    if args.program is not None and args.program not in PROGRAMS:
        raise CLIError(f"--program: unknown program {args.program!r}; registered programs: "
                       f"{', '.join(sorted(PROGRAMS))}")
    w, h = _frame_size(args, default_size)
    if max(w, h) > MAX_DIMENSION:
        raise CLIError(f"image size {w}×{h}: a side may be at most {MAX_DIMENSION} pixels (MAX_DIMENSION)")
    if args.texture and not os.path.isfile(args.texture):
        raise CLIError(f"--texture: {args.texture}: no such file")


def _prepare(args, default_size):
    kind = _check_input(args.input)
    _check_options(args, default_size)
    if kind == ".obj":
        return _model_scene(args, default_size)
    return _load_scene_file(args, default_size)


def _default_output(args, ext: str) -> str:
    return args.output or os.path.join("out", Path(args.input).stem + ext)


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "draw"


def _render(args) -> int:
    from .pictures import draw_wireframe
    from .drawing import render_scene
    start = time.perf_counter()
    output = _default_output(args, ".png")
    fmt = _image_format(output)
    scene = _prepare(args, (640, 480))
    camera = scene.view_camera()
    n = len(scene.objects)

    def progress(k, total, obj):
        if total > 1:
            _progress(args, f"draw {k + 1}/{total}: {obj.name} ({obj.mesh.triangle_count} triangles)")

    results: list = []
    wire = scene.wireframe
    fb = render_scene(scene.replace(wireframe=False), camera=camera, trace=bool(args.stages), results=results,
                      progress=progress)
    if args.stages:
        stage_dir = Path(args.stages)
        for k, r in enumerate(results):
            folder = stage_dir if n == 1 else stage_dir / f"{k + 1:02d}-{_safe_name(r.name)}"
            paths = r.trace.save_pictures(folder)
            for name, path in paths.items():
                print(f"softpipe render: stage picture {path}")
    if wire:
        draw_wireframe(fb, [r.primitives for r in results], scene.wireframe_color)
    path = Path(output)
    path.parent.mkdir(parents=True, exist_ok=True)
    image = fb.to_image()
    image.save(path, format=fmt)
    programs = ", ".join(dict.fromkeys(r.program for r in results))
    print(f"softpipe render: wrote {path.resolve()} ({scene.width}×{scene.height}, {scene.triangle_count} "
          f"triangles, program {programs}, {time.perf_counter() - start:.2f} s)")
    return 0


def _orbit(camera, degrees: float):
    """The camera with its eye turned about the vertical axis through its target."""
    import numpy as np
    from .transforms import rotate_y
    eye, target = np.asarray(camera.eye), np.asarray(camera.target)
    offset = (rotate_y(degrees) @ np.append(eye - target, 0.0))[:3]
    return camera.replace(eye=tuple(target + offset))


def _turntable(args) -> int:
    from .drawing import render_scene
    start = time.perf_counter()
    output = _default_output(args, ".gif")
    fmt = _image_format(output, animated=True)
    scene = _prepare(args, (320, 240))
    base = scene.view_camera()
    first = scene.frame.azimuth
    images = []
    for i in range(args.frames):
        turn = 360.0 * i / args.frames
        camera = _orbit(base, turn) if scene.camera is not None else scene.view_camera(azimuth=first + turn)
        fb = render_scene(scene, camera=camera)
        images.append(fb.to_image())
        _progress(args, f"frame {i + 1}/{args.frames}")
    path = Path(output)
    path.parent.mkdir(parents=True, exist_ok=True)
    duration = max(int(round(100.0 / args.fps)), 1) * 10  # GIF stores hundredths of a second
    if fmt == "GIF":
        frames = [im.quantize(colors=256, method=_median_cut()) for im in images]
    else:
        frames = images
    frames[0].save(path, format=fmt, save_all=True, append_images=frames[1:], duration=duration, loop=0)
    print(f"softpipe turntable: wrote {path.resolve()} ({args.frames} frames, {scene.width}×{scene.height}, "
          f"{duration} ms each, {time.perf_counter() - start:.2f} s)")
    return 0


def _median_cut():
    from PIL import Image
    return Image.Quantize.MEDIANCUT


# ---------------------------------------------------------------------------- main


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 error, 130 interrupted)."""
    from .obj import OBJError
    from .scenefile import SceneError
    from .shader import ShaderError

    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(None if argv is None else list(argv))
        if extra:
            prog = f"softpipe {args.command}" if getattr(args, "command", None) else "softpipe"
            raise _UsageError(prog, f"unrecognized arguments: {' '.join(extra)} (see '{prog} --help')")
    except _UsageError as e:
        print(f"{e.prog}: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:  # --help, --version
        return int(e.code or 0) if not isinstance(e.code, str) else 2
    if not getattr(args, "command", None):
        print("softpipe: error: a command is required: render, turntable, demo or programs "
              "(see 'softpipe --help')", file=sys.stderr)
        return 2
    try:
        return args.run(args)
    except KeyboardInterrupt:
        print(f"softpipe {args.command}: interrupted", file=sys.stderr)
        return 130
    except (CLIError, SceneError, OBJError, ShaderError, ValueError, OSError) as e:
        message = " ".join(str(e).split()) or type(e).__name__
        if isinstance(e, OSError) and e.filename and str(e.filename) not in message:
            message = f"{e.filename}: {message}"
        print(f"softpipe {args.command}: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
