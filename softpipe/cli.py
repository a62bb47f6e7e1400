"""The command line: ``softpipe demo``, ``softpipe render``.

Errors are one clear line on stderr and exit status 2; ``--help`` documents
every option.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import List, Optional

__all__ = ["main"]


class CLIError(Exception):
    """A user error: printed as one line, exit status 2."""


def _demo(args) -> int:
    from .demo import render_demo
    start = time.perf_counter()
    fb = render_demo(args.width, args.height)
    path = fb.save(args.output)
    print(f"softpipe demo: wrote {path.resolve()} ({args.width}×{args.height}, "
          f"{time.perf_counter() - start:.2f} s)")
    return 0


def _size(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of pixels, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of pixels, got {v}")
    return v


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="softpipe",
        description="softpipe: the graphics pipeline of a GPU, on the CPU, in Python.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser("demo", help="render the default scene to a PNG and print its path",
                          description="Render the default scene (a few shapes on a ground plane, in "
                                      "perspective) to a PNG and print where it was written.")
    demo.add_argument("-o", "--output", default="out/demo.png", help="PNG to write (default: out/demo.png)")
    demo.add_argument("--width", type=_size, default=640, help="image width in pixels (default 640)")
    demo.add_argument("--height", type=_size, default=480, help="image height in pixels (default 480)")
    demo.set_defaults(run=_demo)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return args.run(args)
    except (CLIError, ValueError, TypeError, OSError) as e:
        print(f"softpipe {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
