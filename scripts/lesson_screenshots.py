"""Screenshots of a lesson's check cell failing (the notebook as a student gets it) and passing (with the
solution), as Jupyter shows them: ``python scripts/lesson_screenshots.py [NOTEBOOK] [OUT_DIR]``.

Runs the notebook with lessons/run.py's ``run_both`` (one kernel), lays the exercise and check cells
out as a notebook page (the source, then the outputs: text, the check's HTML and pictures, the error)
and has Debian's chromium (through Playwright) take a picture of each. Writes OUT_DIR/NAME-fails.png and
OUT_DIR/NAME-passes.png (default: lessons/02_triangles, docs/images/lessons).
"""
from __future__ import annotations

import html
import importlib.util
import re
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run_script():
    spec = importlib.util.spec_from_file_location("lessons_run_script", ROOT / "lessons" / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _outputs_html(outputs) -> str:
    parts = []
    for o in outputs:
        if o.output_type == "stream":
            parts.append(f"<pre class=out>{html.escape(o.text)}</pre>")
        elif o.output_type in ("display_data", "execute_result"):
            data = o.get("data", {})
            if "text/html" in data:
                parts.append(f"<div class=out>{data['text/html']}</div>")
            elif "image/png" in data:
                parts.append(f"<div class=out><img src='data:image/png;base64,{data['image/png']}'></div>")
            elif "text/plain" in data:
                parts.append(f"<pre class=out>{html.escape(data['text/plain'])}</pre>")
        elif o.output_type == "error":
            text = re.sub(r"\x1b\[[0-9;]*m", "", "\n".join(o.get("traceback", [])))
            parts.append(f"<pre class='out err'>{html.escape(text[-2500:])}</pre>")
    return "".join(parts)


def _page(cells) -> str:
    body = "".join(f"<div class=cell><pre class=src>{html.escape(c.source)}</pre>{_outputs_html(c.outputs)}</div>"
                   for c in cells)
    return ("<html><head><style>body{font-family:sans-serif;margin:16px;width:1000px}"
            ".cell{margin-bottom:14px}.src{background:#f5f5f5;border:1px solid #ddd;padding:8px;font-size:12px;"
            "white-space:pre-wrap}.out{padding:4px 8px;font-size:12px;white-space:pre-wrap}"
            ".err{background:#fdd}img{image-rendering:pixelated}</style></head>"
            f"<body>{body}</body></html>")


def _tagged(nb, tag):
    return [c for c in nb.cells if tag in c.get("metadata", {}).get("tags", [])]


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    name = args[0] if args else "02_triangles"
    out = Path(args[1]) if len(args) > 1 else ROOT / "docs" / "images" / "lessons"
    chromium = shutil.which("chromium")
    if chromium is None:
        print("chromium is not installed (apt-get install -y chromium)", file=sys.stderr)
        return 1
    from nbclient import NotebookClient
    from playwright.sync_api import sync_playwright

    run = _run_script()
    path = ROOT / "lessons" / f"{name}.ipynb"
    given = run.load(path)                               # as a student gets it, run to its failing check
    NotebookClient(given, timeout=600, kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": str(path.parent)}}).execute()
    failures, solved = run.run_both(path)
    assert failures, f"{name}: the notebook as given did not fail"
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1040, "height": 400})
        for nb, kind in ((given, "fails"), (solved, "passes")):
            page_file = Path(tmp) / f"{kind}.html"
            page_file.write_text(_page(_tagged(nb, "exercise") + _tagged(nb, "check")))
            page.goto(page_file.as_uri())
            target = out / f"{name}-{kind}.png"
            page.screenshot(path=str(target), full_page=True)
            print(f"wrote {target}")
        browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
