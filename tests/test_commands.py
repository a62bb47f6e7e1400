"""Every `softpipe ...` command line that README.md and examples/README.md show runs as written
(issue #14), from a folder laid out as a clone: the repository's `examples/` and
`softpipe/` beside the outputs. `make` lines are the suite's own entry point and are not
run from inside it.
"""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from patience import PATIENCE

from softpipe.tools.cli import main

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", REPO / "examples" / "README.md"]
SH_BLOCK = re.compile(r"```sh\n(.*?)```", re.S)


def _commands():
    found = []
    for page in PAGES:
        for block in SH_BLOCK.findall(page.read_text()):
            for line in block.splitlines():
                words = shlex.split(line, comments=True)
                if words and words[0] in ("softpipe", ".venv/bin/softpipe"):
                    found.append(pytest.param(words[1:], id=f"{page.parent.name}/{page.name}: {line[:60]}"))
    return found


COMMANDS = _commands()


def test_the_pages_show_commands():
    assert len(COMMANDS) >= 8


def _view_once(monkeypatch):
    """``softpipe view`` serves until Ctrl-C: instead of serving forever, its server answers the page and
    one frame, then stops as Ctrl-C stops it."""
    import urllib.request

    from softpipe.tools.viewer import ViewerServer

    def serve_once(server):
        import threading
        answered = {}

        def fetch():
            for path in ("/", "/api/frame"):
                with urllib.request.urlopen(server.url.rstrip("/") + path, timeout=PATIENCE) as reply:
                    answered[path] = (reply.status, reply.headers.get_content_type())
        client = threading.Thread(target=fetch)
        client.start()
        server.timeout = 0.2                         # handle_request returns when the client has gone
        while client.is_alive():
            server.handle_request()
        assert answered == {"/": (200, "text/html"), "/api/frame": (200, "image/png")}, answered
        raise KeyboardInterrupt
    monkeypatch.setattr(ViewerServer, "serve_forever", serve_once)


@pytest.mark.parametrize("argv", COMMANDS)
def test_the_command_runs_as_written(argv, tmp_path, monkeypatch, capsys):
    for name in ("examples", "softpipe"):           # inputs as a clone has them; outputs into tmp_path
        (tmp_path / name).symlink_to(REPO / name)
    monkeypatch.chdir(tmp_path)
    if "--frames" in argv:                           # the turntable's frames: fewer, same command otherwise
        argv = argv[:argv.index("--frames") + 1] + ["4"] + argv[argv.index("--frames") + 2:]
    if argv[0] == "batch":                           # the same frames, in this process (no cluster to start)
        argv = argv + ["--scheduler", "serial"]
    if argv[0] in ("render", "explore") and not {"--size", "--width", "--height"} & set(argv):
        argv = argv + ["--size", "96x72"]            # a smaller picture, the same command otherwise
    if argv[0] == "view":                            # serves until Ctrl-C: fetch the page and a frame, then "press" it
        _view_once(monkeypatch)
    assert main(argv + (["-q"] if argv[0] in ("render", "turntable", "batch") else [])) == 0
    out = capsys.readouterr().out
    if argv[0] == "view":
        assert "serving" in out and "stopped" in out, out
        return
    if "-o" in argv:
        written = tmp_path / argv[argv.index("-o") + 1]
        if argv[0] == "batch":                       # a folder of frames, its manifest and contact sheet
            assert (written / "manifest.jsonl").is_file() and (written / "contact-sheet.png").is_file(), written
            return
        assert written.is_file() and written.stat().st_size > 500, written
    else:
        assert out.strip(), "the command printed nothing"
