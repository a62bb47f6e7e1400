"""The guide in docs/ runs as written and shows what it prints.

* Every ```python block of every page runs, in order, in one namespace per page
  (so a page's blocks build on each other), in a fresh temporary directory.
* A ```python block followed directly by a ```text block must print exactly
  that text: the outputs in the guide are real. After a deliberate change,
  ``SOFTPIPE_UPDATE_DOCS=1 pytest tests/test_docs.py`` rewrites those text
  blocks with what the code prints now (then read the diff).
* Each stage page starts with the scene of ``scripts/make_docs_pictures.py``,
  word for word; the script runs and writes the pictures the pages show, and
  the committed pictures in docs/images are the ones it draws today.
* A ```console block of docs/07-debugging.md that runs ``softpipe ...`` prints
  what it shows, but for the folder of the image it wrote and the seconds it took.
* Every relative link and image in docs/ points at a file that exists, and the
  line numbers docs/07-debugging.md gives for breakpoints in raster.py are right.
"""
from __future__ import annotations

import contextlib
import inspect
import io
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
SCRIPT = ROOT / "scripts" / "make_docs_pictures.py"
PAGES = sorted(p for p in DOCS.glob("*.md") if p.name != "conventions.md")
STAGE_PAGES = [p for p in PAGES if re.match(r"0[1-8]-", p.name)]
UPDATE = os.environ.get("SOFTPIPE_UPDATE_DOCS") == "1"

FENCE = re.compile(r"^```([\w-]*)[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)
PICTURES = ["01-vertices.png", "02-primitives.png", "03-coverage.png", "04-depth.png", "05-overdraw.png",
            "06-final.png", "contact-sheet.png", "eye-space.png"]


@dataclass
class Block:
    code: str
    line: int                       # where the code starts in the page (1-based)
    expected: Optional[str] = None  # the ```text block right after it, if any
    expected_span: Optional[tuple] = None


def python_blocks(text: str) -> List[Block]:
    """The page's ```python blocks, each with the ```text block that follows it directly."""
    fences = list(FENCE.finditer(text))
    blocks = []
    for k, m in enumerate(fences):
        if m.group(1) != "python":
            continue
        block = Block(m.group(2), text.count("\n", 0, m.start(2)) + 1)
        if k + 1 < len(fences):
            nxt = fences[k + 1]
            if nxt.group(1) == "text" and text[m.end():nxt.start()].strip() == "":
                block.expected, block.expected_span = nxt.group(2), nxt.span(2)
        blocks.append(block)
    return blocks


def _normalize(out: str) -> str:
    return "\n".join(line.rstrip() for line in out.strip("\n").splitlines())


def run_page(page: Path) -> List[tuple]:
    """exec the page's python blocks in order in one namespace; returns [(block, printed)]."""
    namespace = {"__name__": "__docs__"}
    results = []
    for block in python_blocks(page.read_text()):
        out = io.StringIO()
        code = compile("\n" * (block.line - 1) + block.code, str(page), "exec")
        with contextlib.redirect_stdout(out):
            exec(code, namespace)
        results.append((block, out.getvalue()))
    return results


@contextlib.contextmanager
def _numpy_print_options():
    saved = np.get_printoptions()
    try:
        yield
    finally:
        np.set_printoptions(**saved)


def _rewrite_outputs(page: Path, results) -> None:
    text = page.read_text()
    for block, printed in sorted(results, key=lambda r: -(r[0].expected_span or (0, 0))[0]):
        if block.expected_span is None:
            continue
        a, b = block.expected_span
        text = text[:a] + _normalize(printed) + "\n" + text[b:]
    page.write_text(text)


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p.read_text())], ids=lambda p: p.name)
def test_page_runs_and_prints_what_it_shows(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with _numpy_print_options():
        results = run_page(page)
    if UPDATE:
        _rewrite_outputs(page, results)
        return
    for block, printed in results:
        if block.expected is not None:
            assert _normalize(printed) == _normalize(block.expected), (
                f"{page.name}:{block.line}: the block prints something else than the page shows "
                "(SOFTPIPE_UPDATE_DOCS=1 pytest tests/test_docs.py rewrites the outputs)")


def _scene_source() -> str:
    text = SCRIPT.read_text()
    m = re.search(r"^# --- the scene.*?\n(.*?)^# --- end of the scene", text, re.S | re.M)
    assert m, "scripts/make_docs_pictures.py lost its scene markers"
    return m.group(1).strip()


def test_every_stage_page_starts_with_the_scene_the_pictures_show():
    scene = _scene_source()
    assert STAGE_PAGES, "no stage pages found in docs/"
    for page in STAGE_PAGES + [DOCS / "README.md"]:
        blocks = python_blocks(page.read_text())
        assert blocks, f"{page.name} has no python blocks"
        assert blocks[0].code.strip() == scene, (
            f"{page.name}: its first python block differs from the scene in scripts/make_docs_pictures.py")


def test_the_picture_script_writes_every_picture(tmp_path, monkeypatch, capsys):
    # the script as `python scripts/make_docs_pictures.py OUT` runs it, here in this process (runpy, as
    # __main__, its argv and a working folder of its own): nothing in it needs a process
    import runpy
    out = tmp_path / "pictures"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", [str(SCRIPT), str(out)])
    with pytest.raises(SystemExit) as end:
        runpy.run_path(str(SCRIPT), run_name="__main__")
    run = subprocess.CompletedProcess(sys.argv, end.value.code, *capsys.readouterr())
    assert run.returncode == 0, run.stderr
    from PIL import Image
    written = sorted(p.name for p in out.iterdir())
    assert written == sorted(PICTURES)
    for name in PICTURES:
        assert f"pictures/{name}" in run.stdout, f"the script did not say it wrote {name}"
    for name in PICTURES[:6]:
        assert Image.open(out / name).size == (160, 120)
    total = sum((out / n).stat().st_size for n in PICTURES)
    assert total < 300_000
    # the back-facing triangle is drawn in red in the primitives picture
    prims = np.asarray(Image.open(out / "02-primitives.png"))
    assert ((prims == (230, 50, 50)).all(axis=2)).sum() > 20
    # the committed pictures are the ones the script draws today
    for name in PICTURES:
        committed = DOCS / "images" / name
        assert committed.exists(), f"docs/images/{name} is missing: run python scripts/make_docs_pictures.py"
        assert np.array_equal(np.asarray(Image.open(committed)), np.asarray(Image.open(out / name))), (
            f"docs/images/{name} is out of date: run python scripts/make_docs_pictures.py")


def _command_blocks(text: str) -> List[tuple]:
    """The ```console blocks that run `softpipe ...`: (line, argv, the lines shown)."""
    out = []
    for m in FENCE.finditer(text):
        lines = m.group(2).splitlines()
        if m.group(1) == "console" and lines and lines[0].startswith("$ softpipe "):
            out.append((text.count("\n", 0, m.start(2)) + 1, shlex.split(lines[0][2:])[1:], lines[1:]))
    return out


def _stable(line: str) -> str:
    """A printed line without what changes from run to run: the folder written to and the seconds."""
    line = re.sub(r"wrote \S*?([^/\s]+) \(", r"wrote \1 (", line)
    return re.sub(r", [0-9.]+ s\)$", ", … s)", line.rstrip())


def test_the_debugging_page_command_lines_print_what_it_shows(tmp_path, monkeypatch, capsys):
    from softpipe.tools.cli import main
    page = DOCS / "07-debugging.md"
    blocks = _command_blocks(page.read_text())
    assert blocks, "07-debugging.md runs no softpipe command"
    monkeypatch.chdir(tmp_path)
    for line, argv, shown in blocks:
        capsys.readouterr()
        assert main(argv) == 0, f"{page.name}:{line}: softpipe {' '.join(argv)} failed"
        printed = capsys.readouterr().out.splitlines()
        assert [_stable(s) for s in printed] == [_stable(s) for s in shown], (
            f"{page.name}:{line}: softpipe {' '.join(argv)} prints something else than the page shows:\n"
            + "\n".join(printed))


LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)|<img [^>]*src=\"([^\"]+)\"")


def test_links_and_images_point_at_files_that_exist():
    for page in PAGES:
        text = FENCE.sub("", page.read_text())
        for m in LINK.finditer(text):
            target = (m.group(1) or m.group(2)).split("#")[0]
            if not target or re.match(r"[a-z]+:", target):
                continue
            assert (page.parent / target).exists(), f"{page.name}: broken link {target}"


def test_the_breakpoint_lines_in_the_debugging_page_are_right():
    from softpipe.pipeline import raster
    path = DOCS / "07-debugging.md"
    text = path.read_text()
    src, first = inspect.getsourcelines(raster._cover_triangle)
    lines = {first + k: s for k, s in enumerate(src)}
    cited = {int(n) for n in re.findall(r"raster\.py:(\d+)", text)}
    assert cited, "07-debugging.md names no line of raster.py"
    for n in cited:
        assert n in lines, f"07-debugging.md cites raster.py:{n}, which is not inside _cover_triangle any more"
    # the line the page stops at to watch e0, e1, e2: right after they are computed for an emitted sample
    watch = [n for n, s in lines.items() if s.strip().startswith("b0, b1, b2, fx, fy = shading_point(")]
    assert watch and watch[0] in cited, (
        f"raster.py's 'b0, b1, b2, fx, fy = shading_point(…' line is now {watch}; update 07-debugging.md")
    assert lines[watch[0] - 1].strip().startswith("e0, e1, e2 = edge_values("), (
        "07-debugging.md stops right after e0, e1, e2 are computed; raster.py no longer computes them there")
