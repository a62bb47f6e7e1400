"""The command line: ``softpipe render``, ``softpipe turntable``, ``softpipe demo``, ``softpipe programs``.

    softpipe render bunny -o bunny.png              a bundled model (softpipe.scenes.models), framed, three studio lights
    softpipe render MODEL.obj -o out.png            any OBJ file (or .ply, .stl, .gltf, .glb through trimesh), the same way
    softpipe render SCENE.toml -o out.png           a scene file (softpipe.scenes.scenefile)
    softpipe turntable MODEL -o spin.gif            an animated GIF, the camera circling the model
    softpipe explore MODEL -o report.html           the pipeline explorer: every stage, every pixel's history (softpipe.views.explorer)
    softpipe explore --diff A B -o diff.html        what changed from A to B: the changed pixels, each one's first differing fragment
    softpipe view MODEL                             the live viewer: a local page, the scene re-rendered as you turn it (softpipe.tools.viewer)
    softpipe batch JOBS.toml -o DIR                 every frame of a job, on a Dask cluster (softpipe.tools.batch)
    softpipe demo                                   the default scene
    softpipe programs                               the shading programs and sample patterns

Errors are one line on stderr and exit status 2; ``--help`` documents every option. Running out of
memory is one line too, saying what ran out and which options make the job smaller, and exit status 1.
Every render prints where it wrote and how long it took; progress goes to stderr.

Outputs (``-o``): the extension chooses the format (an unknown one is refused), a
missing folder is made, and the folder must be writable and the output not a folder;
all of this is checked before anything is rendered. Files are written whole or not at all
(:func:`softpipe.core.files.atomic_write`): Ctrl-C or a full disk leaves the previous file.
``-o -`` writes the picture to stdout instead (PNG for render and demo, GIF for
turntable) and the "wrote" line goes to stderr.

This module only turns options into the keyword arguments of :func:`softpipe.render`
and :func:`softpipe.turntable` (``softpipe.scenes.drawing``), checks them with messages that
name the options, and calls those: the Python API and the command line make the same
pictures by one code path. Colors (``--background``, ``--wire-color``) are read by
:func:`softpipe.core.colors.parse_color`, as the API reads them.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import stat
import sys
import time
import warnings
from pathlib import Path
from typing import Callable, List, Optional, Sequence, Tuple

from softpipe.core.version import VERSION
from softpipe.scenes.drawing import MAX_FRAMES  # softpipe turntable's limit is softpipe.turntable's

__all__ = ["main", "build_parser", "CLIError"]


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


def _positive_whole(things: str) -> Callable[[str], int]:
    """An option type: a whole number > 0 of ``things`` ("pixels", "worker processes")."""
    def value(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number of {things}, got {text!r}") from None
        if v <= 0:
            raise argparse.ArgumentTypeError(f"expected a positive number of {things}, got {v}")
        return v
    return value


_size = _positive_whole("pixels")
_worker_count = _positive_whole("worker processes")
_spp = _positive_whole("samples per pixel")


def _threshold(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not v >= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number ≥ 0 (a difference of linear color, 0..1), got {text!r}")
    return v


def _adaptive_depth(text: str) -> int:
    from softpipe.tracers.whitted import MAX_ADAPTIVE_DEPTH
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= MAX_ADAPTIVE_DEPTH:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to {MAX_ADAPTIVE_DEPTH}, got {text!r}")
    return v


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to 2**64 - 1, got {text!r}") from None
    if not 0 <= v < 2 ** 64:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to 2**64 - 1, got {v}")
    return v


def _width_height(text: str) -> Tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX×*]\s*(\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, e.g. 640x480, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive width and height, got {text!r}")
    return w, h


def _pixels(text: str) -> float:
    """An option type: a point size or line width, a number of pixels > 0."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a number of pixels > 0, got {text!r}")
    return v


def _color(text: str) -> Tuple[float, ...]:
    """--background, --wire-color: what softpipe.core.colors.parse_color reads ('0.1,0.2,0.3', '#202830', 'white')."""
    from softpipe.core.colors import parse_color
    try:
        return parse_color(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


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
    from softpipe.pipeline.sampling import pattern_named
    try:
        pattern_named(text)
    except (ValueError, TypeError) as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


# ---------------------------------------------------------------------------- the parser


def _programs() -> List[str]:
    from softpipe.programs import PROGRAMS
    return sorted(PROGRAMS)


def _add_view_options(p: argparse.ArgumentParser, default_size: str) -> None:
    from softpipe.scenes.scene import default_program
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
                        f"now: {default_program()!r}), or module:function (file.py:function) naming a Program or a fragment "
                        f"shader of yours; for a scene file it replaces every mesh's program")
    g.add_argument("--texture", metavar="IMAGE",
                   help="diffuse texture for a model with texture coordinates (an OBJ's vt), e.g. "
                        "spot_texture.png (the bundled 'spot' has its own); passed to the program as uniform "
                        "'texture'")
    g.add_argument("--cull", choices=("back", "front", "none"),
                   help="which faces to drop: back (default), front or none")
    g.add_argument("--shadows", action="store_true",
                   help="every light casts shadows (shadow maps); a model alone stands on a floor to show them")
    g.add_argument("--wireframe", action="store_true",
                   help="draw the triangle edges (after clipping and culling) over the image; hidden edges stay hidden")
    g.add_argument("--wire-color", type=_color, metavar="COLOR", help="wireframe color (default white)")
    g.add_argument("--point-size", type=_pixels, metavar="PX",
                   help="size of the model's points (OBJ 'p'), drawn unlit in their material's color (default 1)")
    g.add_argument("--line-width", type=_pixels, metavar="PX",
                   help="width of the model's lines (OBJ 'l'), drawn unlit in their material's color (default 1)")
    g = p.add_argument_group("camera (framed: it looks at the centre of everything and sees all of it)")
    g.add_argument("--azimuth", type=_angle, metavar="DEG",
                   help="camera angle about the vertical (y) axis, from +z toward +x (default 30)")
    g.add_argument("--elevation", type=_angle, metavar="DEG",
                   help="camera angle above the horizontal (xz) plane (default 20)")
    g.add_argument("--fovy", type=_fovy, metavar="DEG", help="vertical field of view in degrees (default 35)")
    p.add_argument("--allow-outside-paths", action="store_true",
                   help="let the model or scene file name files outside its own folder (mtllib, map_Kd, a glTF's buffers, meshes, "
                        "textures: absolute paths, ~, ..); only for files you trust. FIFOs and devices stay refused")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")


def build_parser() -> argparse.ArgumentParser:
    from softpipe.scenes.formats import FORMATS
    from softpipe.scenes.models import MODELS
    models = ", ".join(MODELS)
    # INPUT as every command takes it: the suffixes are those models.load_model reads
    inputs = f"a .obj model (or {', '.join(FORMATS)}, read through trimesh), a bundled model's name or a .toml scene file"
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
    parser.add_argument("--version", action="version", version=f"softpipe {VERSION}",
                        help="print softpipe's version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    render = sub.add_parser(
        "render", help="render a model (OBJ, PLY, STL, glTF) or a TOML scene file to an image",
        description="Render INPUT to an image and print where it was written and how long it took.\n\n"
                    "INPUT.obj: a Wavefront OBJ model (with its MTL materials, if any), seen by a camera that "
                    "frames it, under a key/fill/rim set of three directional lights that follow the camera.\n"
                    f"INPUT{', INPUT'.join(FORMATS)}: a PLY, STL or glTF 2.0 model read through trimesh (pip install "
                    "'softpipe[formats]'; a glTF's base-color textures and metallic-roughness materials come with "
                    "it; docs/formats.md), the same way.\n"
                    f"INPUT a bundled model's name ({models}): that model, the same way.\n"
                    "INPUT.toml: a scene file (see examples/scene.toml); the options below override its "
                    "[render] settings, and --azimuth/--elevation its framed camera.\n\n"
                    "In Python: softpipe.render(INPUT, width=..., program=..., ...).save(IMAGE) makes the same "
                    "image (the options are its keywords).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    render.add_argument("input", metavar="INPUT", help=inputs)
    render.add_argument("-o", "--output", metavar="IMAGE",
                        help="image to write; the format follows the extension (.png, .jpg, .bmp, .tif, ...); "
                             "default out/NAME.png; '-' writes a PNG to stdout")
    _add_view_options(render, "640x480")
    render.add_argument("--raytrace", action="store_true",
                        help="ray trace the scene instead (Whitted: shadow rays, mirrors and glass, FORMULAS §11, "
                             "§16-§22) with the same camera, materials and lights; --samples NAME: one ray per "
                             "sample, the pixel their mean")
    render.add_argument("--adaptive", action="store_true",
                        help="with --raytrace: adaptive supersampling — the pixel centres first, then a cell split in "
                             "four where its color differs from a neighbour's by --threshold or more, down to "
                             "--adaptive-depth levels (docs/raytracing.md)")
    render.add_argument("--threshold", type=_threshold, metavar="T", default=None,
                        help="with --adaptive: the difference in some channel that splits a cell (default 0.1; "
                             "0 splits every cell)")
    render.add_argument("--adaptive-depth", type=_adaptive_depth, metavar="N", default=None,
                        help="with --adaptive: the most levels of splitting, 0-3 (default 2: up to 4x4 rays "
                             "per pixel)")
    render.add_argument("--pathtrace", action="store_true",
                        help="path trace the scene instead (Monte Carlo: light from emissive surfaces, material ke, "
                             "and the background; Lambert, mirror and glass; docs/pathtracing.md)")
    render.add_argument("--spp", type=_spp, metavar="N", default=None,
                        help="with --pathtrace: samples per pixel (default 64)")
    render.add_argument("--seed", type=_seed, metavar="S", default=None,
                        help="with --pathtrace: the random seed (default 0); the same seed gives the same image")
    render.add_argument("--background-light", action="store_true",
                        help="with --pathtrace: the uniform background is a light the light sample can go to, "
                             "beside the emissive surfaces (the same image in expectation; less noisy where what "
                             "hides the sky is much darker than it; docs/pathtracing.md)")
    render.add_argument("--rays", action="store_true",
                        help="rasterize, and let the objects drawn with mirror, glass or hall trace their reflected "
                             "and refracted rays from the fragment shader (ray queries) instead of reading an "
                             "environment map: their pixels are the ray tracer's")
    render.add_argument("--srgb", action="store_true",
                        help="render into an sRGB framebuffer: shade in linear light and sRGB-encode the picture "
                             "as it is written (FORMULAS §28, docs/gamma.md); an OBJ model's textures (--texture, "
                             "map_Kd) are then read as sRGB too; a scene file says so with [render] srgb = true "
                             "and srgb_textures = true")
    render.add_argument("--outputs", type=_output_names, metavar="NAMES", default=None,
                        help="also write these buffers beside the picture, comma-separated, each as IMAGE-STEM.NAME.npy "
                             "and a picture IMAGE-STEM.NAME.png: color, depth, linear_depth, position, normal, "
                             "object_id, triangle_id, barycentrics, uv, albedo (docs/outputs.md)")
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
                    f"INPUT is {inputs} (a scene with its own "
                    "[camera] eye turns that eye about the target). The studio lights follow the camera, so the model is seen turning "
                    "under fixed lights. Frames that come out identical (a symmetric model) are merged by the "
                    "GIF writer. GIF frames get 256 colors each, dithered (Floyd-Steinberg).\n\n"
                    "In Python: softpipe.turntable(INPUT, ANIMATION, frames=..., fps=..., ...) writes the same file.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    turn.add_argument("input", metavar="INPUT", help=inputs)
    turn.add_argument("-o", "--output", metavar="ANIMATION",
                      help="a .gif (or .png) to write; default out/NAME.gif; '-' writes a GIF to stdout")
    turn.add_argument("--frames", type=_frames, default=36, metavar="N",
                      help=f"number of frames in one turn (default 36, at most {MAX_FRAMES})")
    turn.add_argument("--fps", type=_fps, default=15.0, help="frames per second when played (default 15)")
    _add_view_options(turn, "320x240")
    turn.set_defaults(run=_turntable)

    demo = sub.add_parser("demo", help="render the default scene to a PNG and print its path",
                          description="Render the default scene (a few shapes on a ground plane, in "
                                      "perspective) to a PNG and print where it was written.")
    demo.add_argument("-o", "--output", metavar="IMAGE",
                      help="image to write; the format follows the extension (.png, .jpg, .bmp, .tif, ...); "
                           "default out/demo.png; '-' writes a PNG to stdout")
    demo.add_argument("--width", type=_size, default=640, help="image width in pixels (default 640)")
    demo.add_argument("--height", type=_size, default=480, help="image height in pixels (default 480)")
    demo.add_argument("--no-shadows", action="store_true",
                      help="the same scene without shadows (every light reaches every point)")
    demo.set_defaults(run=_demo)

    explore = sub.add_parser(
        "explore", help="write the pipeline explorer: every stage of a render as one HTML page to point at",
        description="Render INPUT with every draw traced and write one self-contained HTML page (no server, no "
                    "network): every stage's picture; click a pixel to see its history (every fragment of every "
                    "draw, its varyings, shader output, depth test and the color after), the winning triangle "
                    "outlined in every picture with its vertices in object, clip and window coordinates, and a "
                    "zoom with the pixel centres and sample positions; arrow keys move the pixel. See "
                    "docs/explorer.md.\n\nIn Python: trace.to_html(PAGE), or "
                    "softpipe.views.explorer.write_explorer(results, PAGE).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    explore.add_argument("input", metavar="INPUT", nargs="?",
                         help=inputs)
    explore.add_argument("-o", "--output", metavar="PAGE", help="the .html page to write; default out/NAME.html")
    explore.add_argument("--diff", nargs=2, metavar=("A", "B"),
                         help="instead of INPUT: render A and B (models or scene files) with the same options and "
                              "write their diff: the changed pixels, and for one pixel (--pixel) the two histories "
                              "side by side with the first fragment that differs (softpipe.views.diff)")
    explore.add_argument("--overlays", action="store_true",
                         help="add RenderDoc's overlays to the pictures: triangle size, depth test pass/fail, "
                              "clipped and culled triangles (softpipe.views.overlays)")
    explore.add_argument("--pixel", nargs=2, type=int, metavar=("X", "Y"),
                         help="with --diff: the pixel whose histories the page shows (default the first changed)")
    explore.add_argument("--max-fragments", type=_fragment_count, metavar="N",
                         help="hold every pixel's history while the draws made at most N fragments (default "
                              "400000); beyond, the history of a regular grid of pixels (the page says which)")
    _add_view_options(explore, "640x480")
    explore.set_defaults(run=_explore)

    live = sub.add_parser(
        "view", help="serve a local page that shows the scene live: drag to orbit, click a pixel for its history",
        description="Serve a page on loopback (127.0.0.1, a free port, printed) that shows INPUT rendered live: "
                    "drag to orbit the camera, scroll to zoom, pick the program, the light and the stage picture "
                    "shown, click a pixel for its history (every fragment of every draw, as trace.pixel_history "
                    "prints it). The scene is rendered again as the camera moves; a fast drag renders the newest "
                    "camera, not every one it passed. Ctrl-C stops it. See docs/viewer.md.\n\n"
                    "In Python (and Jupyter, where it shows in the notebook): softpipe.view(INPUT, ...).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    live.add_argument("input", metavar="INPUT", help=inputs)
    live.add_argument("--port", type=_port, default=0, metavar="N",
                      help="the port to serve on (default 0: a free one, printed)")
    live.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                      help="a loopback address to serve on: 127.0.0.1 (default), ::1 or localhost; any other is "
                           "refused (the page is for this machine only)")
    _add_view_options(live, "640x480")
    live.set_defaults(run=_view)

    programs = sub.add_parser("programs", help="list the shading programs and sample patterns",
                              description="List the registered shading programs (for --program and a scene's "
                                          "program keys) and the sample pattern names (for --samples).")
    programs.set_defaults(run=_list_programs)

    jobs = sub.add_parser(
        "batch", help="render every frame of a job file (a sweep, a turntable) on a Dask cluster",
        description="Render every frame of JOBS.toml (models × cameras × programs × materials × lights × sizes "
                    "× sample patterns; see examples/sweep.toml and docs/batch.md) into DIR as NAME.png, with "
                    "DIR/manifest.jsonl and DIR/contact-sheet.png. Frames already in the manifest with their file "
                    "unchanged are skipped. Without --scheduler: a Dask LocalCluster of one worker process per "
                    "core (pip install 'softpipe[cluster]'). The exit status is the number of failed frames "
                    "(at most 125).\n\nIn Python: softpipe.tools.batch.batch(JOBS, DIR, ...).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    jobs.add_argument("job", metavar="JOBS.toml", help="the job file")
    jobs.add_argument("-o", "--output", metavar="DIR", required=True, help="the folder for the frames")
    jobs.add_argument("--scheduler", metavar="ADDRESS",
                      help="a running Dask scheduler (tcp://host:8786), or 'serial' for this process alone")
    jobs.add_argument("--workers", type=_worker_count, metavar="N",
                      help="worker processes of the LocalCluster (default: one per core; at most two per core)")
    jobs.add_argument("--dashboard", metavar="ADDRESS", nargs="?", const=":8787",
                      help="start the LocalCluster's dashboard (default :8787; needs bokeh) and print its link")
    jobs.add_argument("--force", action="store_true", help="render every frame, even those already written")
    jobs.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    jobs.set_defaults(run=_batch)
    parser.set_defaults(commands=tuple(sub.choices))     # for the message when none is given
    return parser


# ---------------------------------------------------------------------------- commands


def _demo(args) -> int:
    from softpipe.tools.demo import render_demo
    start = time.perf_counter()
    output = _checked_output(args, args.output or os.path.join("out", "demo.png"), _image_format)
    fb = render_demo(args.width, args.height, shadows=not args.no_shadows)
    where = _save_image(fb, output)
    _wrote(args, output, f"wrote {where} ({args.width}×{args.height}, {time.perf_counter() - start:.2f} s)")
    return 0


def _batch(args) -> int:
    from softpipe.tools.batch import ClusterError, batch, check_local_cluster, load_job
    if args.workers is not None and args.scheduler is not None:
        raise CLIError("--workers sizes the LocalCluster; a --scheduler's cluster has its own workers")
    if args.dashboard is not None and args.scheduler is not None:
        raise CLIError("--dashboard applies to the LocalCluster; a --scheduler's cluster has its own")
    if args.scheduler is None:
        check_local_cluster(args.workers, args.dashboard, ("--workers ", "--dashboard "))
    if os.path.exists(args.output) and not os.path.isdir(args.output):
        raise CLIError(f"-o: {args.output} is a file, not a folder")
    job = load_job(args.job)
    if args.scheduler != "serial":
        import importlib.util
        if importlib.util.find_spec("distributed") is None:
            raise CLIError("a cluster needs Dask: pip install 'softpipe[cluster]' (or --scheduler serial)")
    live = sys.stderr.isatty()
    shown = [0.0]

    def progress(p) -> None:
        if p.error is not None:
            print(("\r\033[K" if live else "") + f"softpipe batch: failed: {p.frame}: {p.error}", file=sys.stderr)
        if args.quiet:
            return
        now = time.perf_counter()
        last = p.finished == p.total
        if live:
            print(f"\r\033[K{p.line()}", end="\n" if last else "", file=sys.stderr, flush=True)
        elif last or now - shown[0] >= 2.0:
            print(p.line(), file=sys.stderr, flush=True)
            shown[0] = now

    def log(message: str) -> None:     # warnings (an OBJ's refused mtllib) even with -q
        if not args.quiet or message.startswith("warning: "):
            _note(args, message)

    try:
        result = batch(job, args.output, args.scheduler, force=args.force, progress=progress,
                       workers=args.workers, dashboard=args.dashboard, log=log)
    except ClusterError as e:
        raise CLIError(str(e)) from None
    rate = f", {len(result.done) / result.seconds:.2f} frames/s" if result.done and result.seconds else ""
    print(f"softpipe batch: wrote {len(result.done)} frames, skipped {len(result.skipped)}, "
          f"{len(result.failed)} failed, into {Path(args.output).resolve()} ({result.seconds:.1f} s{rate}); "
          f"manifest {result.manifest.name}" + (f", contact sheet {result.contact_sheet.name}"
                                                 if result.contact_sheet else ""))
    return min(len(result.failed), 125)


def _list_programs(args) -> int:
    from softpipe.programs import PROGRAMS
    from softpipe.scenes.scene import default_program
    width = max(len(n) for n in PROGRAMS)
    print("shading programs (--program NAME):")
    for name in sorted(PROGRAMS):
        print(f"  {name.ljust(width)}  {PROGRAMS[name].description}")
    print(f"default: {default_program()}")
    print("sample patterns (--samples NAME): 1, grid4, grid9, grid16, rgss4, jitterN (N square), randomN (N ≤ 64)")
    return 0


def _printable(text: str) -> str:
    """``text`` with a file name's non-UTF-8 bytes (held as lone surrogates) shown as '�', which any terminal
    prints (a surrogate stops print() under a UTF-8 locale)."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def _note(args, message: str) -> None:
    print(_printable(f"softpipe {args.command}: {message}"), file=sys.stderr)


def _progress(args, message: str) -> None:
    if not args.quiet:
        print(message, file=sys.stderr, flush=True)


def _check_input(name: str) -> str:
    """The kind of INPUT (".obj" or ".toml"), checked before the (possibly slow) options and loading."""
    from softpipe.scenes.drawing import input_kind
    return input_kind(name)


def _image_format(path: str) -> str:
    """The pillow format for an output file name (checked before rendering)."""
    from softpipe.pipeline.framebuffer import image_format
    try:
        return image_format(path)
    except ValueError as e:
        raise CLIError(str(e)) from None


def _frame_size(args, default: Tuple[int, int]) -> Tuple[int, int]:
    if args.size and (args.width or args.height):
        raise CLIError("give --size or --width/--height, not both")
    if args.size:
        return args.size
    return args.width or default[0], args.height or default[1]


def _check_options(args, kind: str, default_size) -> None:
    """The checks that need no file, before the (possibly slow) loading, worded for the command line."""
    from softpipe.pipeline.framebuffer import MAX_DIMENSION
    from softpipe.programs import PROGRAMS
    if isinstance(args.program, str) and args.program not in PROGRAMS and ":" not in args.program:
        raise CLIError(f"--program: unknown program {args.program!r}; registered programs: "
                       f"{', '.join(sorted(PROGRAMS))} (or module:function naming a Program or a fragment shader)")
    if isinstance(args.program, str) and args.program not in PROGRAMS:
        from softpipe.programs import get_program
        try:        # module:function, imported once here: its Program is what is drawn
            args.program = get_program(args.program)
        except ValueError as e:
            raise CLIError(f"--program: {e}") from None
    w, h = _frame_size(args, default_size)
    if max(w, h) > MAX_DIMENSION:
        raise CLIError(f"image size {w}×{h}: a side may be at most {MAX_DIMENSION} pixels (MAX_DIMENSION)")
    if args.texture and not os.path.isfile(args.texture):
        from softpipe.core.files import PathPolicyError, check_regular_file
        if not os.path.exists(args.texture):
            raise CLIError(f"--texture: {args.texture}: no such file")
        if os.path.isdir(args.texture):
            raise CLIError(f"--texture: {args.texture}: is a folder, not an image file")
        try:
            check_regular_file(args.texture)
        except PathPolicyError as e:
            raise CLIError(f"--texture: {e}") from None
    if args.texture and kind == ".toml":
        raise CLIError("--texture applies to an OBJ model; in a scene file give the material a diffuse_texture")


def _options(args) -> dict:
    """The command line's options as the keyword arguments of softpipe.render and softpipe.turntable."""
    width, height = args.size if args.size else (args.width, args.height)
    return dict(width=width, height=height, program=args.program, texture=args.texture or None,
                background=args.background, samples=args.samples, msaa=args.msaa, cull=args.cull,
                wireframe=args.wireframe, wire_color=args.wire_color, azimuth=args.azimuth,
                elevation=args.elevation, fovy=args.fovy, allow_outside=args.allow_outside_paths,
                shadows=args.shadows, point_size=args.point_size, line_width=args.line_width)


def _prepare(args, default_size):
    """The Scene softpipe.render draws for these options (softpipe.scenes.drawing.prepare_scene); warnings one line each."""
    from softpipe.scenes.drawing import prepare_scene
    kind = _check_input(args.input)
    _check_options(args, kind, default_size)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # --srgb is render's alone (turntable and explore have no such option)
        scene = prepare_scene(args.input, default_size=default_size, srgb=getattr(args, "srgb", False),
                              **_options(args))
    for message in dict.fromkeys(str(w.message) for w in caught):
        _note(args, f"warning: {message}")
    from softpipe.programs import PROGRAMS
    if args.texture and "textured" not in PROGRAMS and args.program is None:
        _note(args, "note: no 'textured' program is registered yet, so the texture is passed as uniform "
                    f"'texture' but not shown; drawing with {scene_program(scene)!r}")
    return scene


def scene_program(scene) -> str:
    from softpipe.scenes.scene import program_for
    return ", ".join(sorted({getattr(p, "name", p) for p in (program_for(o, scene.program) for o in scene.objects)}))


def _default_output(args, ext: str) -> str:
    return args.output or os.path.join("out", Path(args.input).stem + ext)


#: ``-o -``: the picture goes to stdout.
STDOUT = "-"


def _checked_output(args, output: str, format_of) -> str:
    """``output``, checked before any rendering: its format (``format_of``), its folder, not a folder itself.

    A missing folder is made (as ``fb.save`` makes it), here, before rendering; one that
    cannot be made (a file in the way) or written is an error.
    """
    if output == STDOUT:
        if sys.stdout.isatty():
            raise CLIError("-o - writes the picture's bytes to stdout; redirect it to a file or a pipe")
        return output
    if os.path.isdir(output):
        raise CLIError(f"-o: cannot write {output}: it is a folder")
    format_of(output)
    from softpipe.core.files import check_writable
    folder = os.path.dirname(os.path.abspath(output))
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        blocking = folder
        while not os.path.lexists(blocking) and os.path.dirname(blocking) != blocking:
            blocking = os.path.dirname(blocking)
        reason = (f"{blocking} is a file, not a folder" if os.path.lexists(blocking) and not os.path.isdir(blocking)
                  else f"cannot make the folder {folder}: {e.strerror}")
        raise CLIError(f"-o: cannot write {output}: {reason}") from None
    try:
        check_writable(output)
    except OSError as e:
        raise CLIError(f"-o: {e}") from None
    return output


def _animation_format(path: str) -> str:
    from softpipe.scenes.drawing import animation_format
    try:
        return animation_format(path)
    except ValueError as e:
        raise CLIError(str(e)) from None


def _to_stdout(data: bytes) -> None:
    sys.stdout.flush()
    sys.stdout.buffer.write(data)
    sys.stdout.buffer.flush()


def _save_image(fb, output: str) -> str:
    """Write ``fb`` to ``output`` (a file, whole or not at all, or stdout as PNG); how to name where it went."""
    if output == STDOUT:
        import io
        buffer = io.BytesIO()
        fb.save(buffer, format="png")
        _to_stdout(buffer.getvalue())
        return "PNG to stdout"
    return str(fb.save(output).resolve())


def _wrote(args, output: str, message: str) -> None:
    """The command's last line: on stdout, or on stderr when stdout holds the picture."""
    print(_printable(f"softpipe {args.command}: {message}"), file=sys.stderr if output == STDOUT else sys.stdout)


def _render(args) -> int:
    from softpipe.scenes.drawing import RENDER_SIZE, render
    from softpipe.scenes.outputs import RenderOutputs, save_outputs
    start = time.perf_counter()
    output = _checked_output(args, _default_output(args, ".png"), _image_format)
    if args.stages and os.path.exists(args.stages) and not os.path.isdir(args.stages):
        raise CLIError(f"--stages: {args.stages} is a file, not a folder")
    _check_raytrace_options(args)
    scene = _prepare(args, RENDER_SIZE)

    def progress(k, total, obj):
        if total > 1:
            _progress(args, f"draw {k + 1}/{total}: {obj.name} ({obj.mesh.triangle_count} triangles)")

    results: list = []
    if (args.spp is not None or args.seed is not None or args.background_light) and not args.pathtrace:
        given = "--spp" if args.spp is not None else "--seed" if args.seed is not None else "--background-light"
        raise CLIError(f"{given} applies only with --pathtrace")
    if args.outputs and (args.pathtrace or args.rays or args.raytrace):
        other = "--pathtrace" if args.pathtrace else "--rays" if args.rays else "--raytrace"
        raise CLIError(f"--outputs reads the rasterizer's visibility record; it does not apply with {other}")
    if args.pathtrace:
        if args.raytrace or args.rays or args.stages:
            other = "--raytrace" if args.raytrace else "--rays" if args.rays else "--stages"
            raise CLIError(f"--pathtrace renders by paths; it does not apply with {other}")
        if args.samples is not None:
            raise CLIError("--samples picks the rasterizer's and the ray tracer's sample pattern; it does not apply "
                           "with --pathtrace, whose samples are jittered over each pixel (a box filter): use --spp N "
                           "for its samples per pixel")
        if args.msaa:
            raise CLIError("--msaa is the rasterizer's multisampling; it does not apply with --pathtrace (use --spp N "
                           "for the path tracer's samples per pixel)")
        from softpipe.tracers.pathtrace import pathtrace
        spp = 64 if args.spp is None else args.spp
        traced = pathtrace(scene, spp=spp, seed=0 if args.seed is None else args.seed,
                           background_light=args.background_light)
        for note in traced.notes:
            _note(args, note)
        where = _save_image(traced.framebuffer(srgb=scene.srgb), output)
        _wrote(args, output, f"wrote {where} ({scene.width}×{scene.height}, {scene.triangle_count} triangles, "
                             f"path traced, {spp} samples per pixel, seed {traced.seed}, "
                             f"{'the background sampled as a light, ' if args.background_light else ''}"
                             f"{time.perf_counter() - start:.2f} s)")
        return 0
    if args.rays:
        if args.raytrace or args.stages:
            raise CLIError(f"--rays rasterizes with rays from the shaders; it does not apply with "
                           f"{'--raytrace' if args.raytrace else '--stages'}")
        from softpipe.scenes.environment_pass import render_with_environments
        fb = render_with_environments(scene, "rays")
        where = _save_image(fb, output)
        _wrote(args, output, f"wrote {where} ({scene.width}×{scene.height}, {scene.triangle_count} triangles, "
                             f"rasterized, rays from the shaders, {time.perf_counter() - start:.2f} s)")
        return 0
    if args.raytrace:
        if args.stages:
            raise CLIError("--stages shows the rasterizer's stages; it does not apply with --raytrace")
        from softpipe.pipeline.sampling import pattern_named
        from softpipe.tracers.whitted import raytrace_scene
        notes: list = []
        timings: dict = {}
        fb = raytrace_scene(scene, notes=notes, timings=timings, adaptive=args.adaptive, threshold=args.threshold,
                            adaptive_depth=args.adaptive_depth)
        for note in notes:
            _note(args, note)
        where = _save_image(fb, output)
        if args.adaptive:
            how = f"ray traced, adaptive: {timings['rays'] / (scene.width * scene.height):.2f} rays per pixel"
        else:
            pattern = pattern_named(scene.samples)
            how = "ray traced" + (f", {len(pattern)} samples per pixel ({pattern.name})" if len(pattern) > 1 else "")
        _wrote(args, output, f"wrote {where} ({scene.width}×{scene.height}, {scene.triangle_count} triangles, "
                             f"{how}, {time.perf_counter() - start:.2f} s)")
        return 0
    if args.outputs and output == STDOUT:
        raise CLIError("--outputs writes files named after -o IMAGE; it does not apply with -o -")
    made = render(scene, stages=args.stages, results=results, progress=progress, outputs=args.outputs)
    for r in results:
        for path in r.pictures.values():
            _wrote(args, output, f"stage picture {path}")
    if isinstance(made, RenderOutputs):
        for path in save_outputs(made, Path(output).with_suffix(""), made.framebuffer):
            _wrote(args, output, f"output {path.resolve()}")
        made = made.framebuffer
    fb = made
    where = _save_image(fb, output)
    programs = ", ".join(dict.fromkeys(r.program for r in results))
    _wrote(args, output, f"wrote {where} ({scene.width}×{scene.height}, {scene.triangle_count} triangles, "
                         f"program {programs}, {time.perf_counter() - start:.2f} s)")
    return 0


def _output_names(text: str) -> tuple:
    from softpipe.scenes.outputs import check_outputs
    try:
        return check_outputs(text)
    except ValueError as e:
        message = str(e)      # argparse names the option itself
        raise argparse.ArgumentTypeError(message[len("outputs: "):] if message.startswith("outputs: ")
                                         else message) from None


def _check_raytrace_options(args) -> None:
    """The ray tracer's own options apply only with --raytrace, and --raytrace refuses the rasterizer's --msaa."""
    if args.threshold is not None and not args.adaptive:
        raise CLIError("--threshold applies only with --adaptive (adaptive supersampling)")
    if args.adaptive_depth is not None and not args.adaptive:
        raise CLIError("--adaptive-depth applies only with --adaptive (adaptive supersampling)")
    if args.adaptive and not args.raytrace:
        raise CLIError("--adaptive applies only with --raytrace (adaptive supersampling of the ray tracer)")
    if args.adaptive and args.samples is not None:
        raise CLIError("--adaptive chooses its own samples (the centres of the cells it splits); it does not apply "
                       "with --samples")
    if args.raytrace and args.msaa:
        raise CLIError("--msaa shades once per pixel and triangle (the rasterizer's multisampling); it does not "
                       "apply with --raytrace (--samples PATTERN supersamples the ray tracer)")


def _fragment_count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive whole number of fragments, got {text!r}")
    return v


def _html_format(path: str) -> str:
    if Path(path).suffix.lower() not in (".html", ".htm"):
        raise CLIError(f"{path}: the explorer is an HTML page: give an .html output")
    return "HTML"


def _traced_render(args, scene) -> list:
    """Every draw of ``scene`` traced (its wireframe's too), as softpipe.render's ``results``."""
    from softpipe.scenes.drawing import draw_wireframe, render

    def progress(k, total, obj):
        if total > 1:
            _progress(args, f"draw {k + 1}/{total}: {obj.name} ({obj.mesh.triangle_count} triangles)")

    results: list = []
    fb = render(dataclasses.replace(scene, wireframe=False), trace=True, results=results, progress=progress)
    if scene.wireframe:     # its draws traced too, so the page shows the edges' pixels and their histories
        draw_wireframe(fb, scene, scene.view_camera(), trace=True, results=results)
    return results


def _explore_diff(args, start: float) -> int:
    """``softpipe explore --diff A B``: A and B rendered with the same options, their diff as a page."""
    from softpipe.scenes.drawing import RENDER_SIZE
    from softpipe.views.diff import diff_draws, write_diff_page
    if args.input:
        raise CLIError("--diff A B compares two inputs; give no INPUT beside them")
    a, b = args.diff
    args.input = a
    output = args.output or os.path.join("out", f"{Path(a).stem}-vs-{Path(b).stem}.html")
    if output == STDOUT:
        raise CLIError("-o -: the diff page is written to a file (give an .html path)")
    output = _checked_output(args, output, _html_format)
    sides = []
    for name in (a, b):
        args.input = name
        sides.append(_traced_render(args, _prepare(args, RENDER_SIZE)))
    diff = diff_draws(*sides)
    try:
        path = write_diff_page(diff, output, tuple(args.pixel) if args.pixel else None, names=(a, b),
                               title=f"softpipe diff: {a} → {b}")
    except ValueError as e:
        raise CLIError(f"--pixel: {e}") from None
    _wrote(args, output, f"wrote {path.resolve()} ({diff.summary()}; {time.perf_counter() - start:.2f} s)")
    return 0


def _explore(args) -> int:
    from softpipe.scenes.drawing import RENDER_SIZE
    from softpipe.views.explorer import MAX_FRAGMENTS, write_explorer
    start = time.perf_counter()
    if args.diff:
        return _explore_diff(args, start)
    if args.pixel:
        raise CLIError("--pixel applies only with --diff A B")
    if not args.input:
        raise CLIError("give INPUT (or --diff A B)")
    output = _default_output(args, ".html")
    if output == STDOUT:
        raise CLIError("-o -: the explorer is written to a file (give an .html path)")
    output = _checked_output(args, output, _html_format)
    scene = _prepare(args, RENDER_SIZE)

    results = _traced_render(args, scene)
    _progress(args, "gathering every pixel's history")
    summary = write_explorer(results, output, max_fragments=args.max_fragments or MAX_FRAGMENTS, overlays=args.overlays,
                             progress=lambda done, total: _progress(args, f"fragment {done}/{total}"))
    _wrote(args, output, f"wrote {summary.path.resolve()} ({summary.bytes / 1e6:.1f} MB, {scene.width}×{scene.height}, "
                         f"{len(results)} draw(s); {summary.held['statement']}; {time.perf_counter() - start:.2f} s)")
    return 0


def _port(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port from 0 to 65535 (0: a free one), got {text!r}")
    return v


def _view(args) -> int:
    """``softpipe view INPUT``: the live viewer, served until Ctrl-C (softpipe.tools.viewer)."""
    from softpipe.scenes.drawing import RENDER_SIZE
    from softpipe.tools.viewer import LiveScene, ViewState, check_loopback, serve
    try:
        check_loopback(args.host)
    except ValueError as e:
        raise CLIError(f"--host: {e}") from None
    scene = LiveScene(_prepare(args, RENDER_SIZE), args.input)
    server = serve(scene, args.host, args.port)         # a taken port is said before the (slow) first frame
    try:
        _progress(args, "rendering the first frame (the first render compiles the shaders)")
        start = time.perf_counter()
        scene.frame(ViewState())
        _wrote(args, "", f"serving {args.input} ({scene.scene.width}×{scene.scene.height}, first frame "
                         f"{time.perf_counter() - start:.2f} s) at {server.url} (Ctrl-C stops it)")
        sys.stdout.flush()
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    _wrote(args, "", "stopped")
    return 0


def _turntable(args) -> int:
    from softpipe.scenes.drawing import TURNTABLE_SIZE, frame_duration, turntable
    start = time.perf_counter()
    output = _checked_output(args, _default_output(args, ".gif"), _animation_format)
    scene = _prepare(args, TURNTABLE_SIZE)
    progress = lambda i, n: _progress(args, f"frame {i}/{n}")  # noqa: E731
    if output == STDOUT:
        import io
        buffer = io.BytesIO()
        turntable(scene, buffer, frames=args.frames, fps=args.fps, progress=progress, format="gif")
        _to_stdout(buffer.getvalue())
        where = "GIF to stdout"
    else:
        where = str(turntable(scene, output, frames=args.frames, fps=args.fps, progress=progress).resolve())
    _wrote(args, output, f"wrote {where} ({args.frames} frames, {scene.width}×{scene.height}, "
                         f"{frame_duration(args.fps)} ms each, {time.perf_counter() - start:.2f} s)")
    return 0


# ---------------------------------------------------------------------------- main


#: What makes a command need less memory, said when it runs out (exit status 1).
MEMORY_HINTS = {
    "render": "a smaller --size (or --width/--height) or fewer --samples makes it smaller; --stages keeps every "
              "draw's fragments",
    "explore": "a smaller --size (or --width/--height), fewer --samples or a smaller --max-fragments makes it "
               "smaller",
    "turntable": "a smaller --size (or --width/--height) or fewer --samples makes it smaller",
    "demo": "a smaller --width/--height makes it smaller",
    "view": "a smaller --size (or --width/--height) or fewer --samples makes it smaller",
}


def _stdout_is_pipe() -> bool:
    try:
        return stat.S_ISFIFO(os.fstat(sys.stdout.fileno()).st_mode)
    except (OSError, ValueError, AttributeError):       # a replaced stdout (pytest's capture) is no pipe
        return False


def _drop_stdout() -> None:
    """Send what is left of stdout to the null device, so that Python's flush at exit does not
    report the closed pipe again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 out of memory, 2 error, 130 interrupted,
    141 when the reader of its output closed the pipe, as ``softpipe programs | head`` does: quietly)."""
    from softpipe.core.runtime import keep_freed_memory
    from softpipe.language.contract import ShaderError
    from softpipe.scenes.obj import OBJError
    from softpipe.scenes.scenefile import SceneError

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
        names = args.commands
        print(f"softpipe: error: a command is required: {', '.join(names[:-1])} or {names[-1]} "
              "(see 'softpipe --help')", file=sys.stderr)
        return 2
    keep_freed_memory()     # a program of softpipe's own: frames' large arrays reuse memory (core/runtime.py)
    try:
        code = args.run(args)
        sys.stdout.flush()      # a reader that closed the pipe (softpipe programs | head) shows here, not at exit
        return code
    except BrokenPipeError as e:
        if not _stdout_is_pipe():
            print(_printable(f"softpipe {args.command}: error: {e}"), file=sys.stderr)
            return 2
        _drop_stdout()
        return 141              # as a command the closed pipe ends (128 + SIGPIPE), quietly
    except KeyboardInterrupt:
        print(f"softpipe {args.command}: interrupted", file=sys.stderr)
        return 130
    except MemoryError as e:
        what = " ".join(str(e).split()) or "an array did not fit in memory"
        hint = MEMORY_HINTS.get(args.command)
        print(f"softpipe {args.command}: error: out of memory: {what}" + (f"; {hint}" if hint else ""),
              file=sys.stderr)
        return 1
    except (CLIError, SceneError, OBJError, ShaderError, ValueError, OSError) as e:
        message = " ".join(str(e).split()) or type(e).__name__
        if isinstance(e, OSError) and e.filename and str(e.filename) not in message:
            message = f"{e.filename}: {message}"
        print(_printable(f"softpipe {args.command}: error: {message}"), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
