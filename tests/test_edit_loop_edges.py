"""Small edges of the edit–run loop (issue #32): README commands write into out/, ``softpipe programs |
head`` ends quietly, the package ships ``py.typed``, an explorer page from Python names its program as
the command line does."""
import re
import subprocess
import sys
from pathlib import Path

from patience import PATIENCE

import softpipe as sp
from softpipe.views.explorer import explorer_data

ROOT = Path(__file__).resolve().parent.parent


def test_readme_commands_write_into_out():
    text = (ROOT / "README.md").read_text()
    outputs = re.findall(r"softpipe \w+ .*?-o (\S+)", text) + re.findall(r'\.save\("([^"]+)"\)', text)
    outputs += re.findall(r'sp\.turntable\("\w+", "([^"]+)"', text)
    assert len(outputs) >= 10
    assert [o for o in outputs if not o.startswith(("out/", "-"))] == []


def test_a_closed_pipe_ends_the_command_quietly():
    """``softpipe programs | head``: the reader closes the pipe before softpipe has written."""
    proc = subprocess.Popen([sys.executable, "-m", "softpipe", "programs"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=ROOT)
    proc.stdout.close()                     # the reader is gone before the command writes
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=PATIENCE) == 141
    assert err == ""


def test_the_package_ships_py_typed():
    assert (ROOT / "softpipe" / "py.typed").is_file()
    pyproject = (ROOT / "pyproject.toml").read_text()
    package_data = pyproject.split("[tool.setuptools.package-data]")[1].split("\n[")[0]
    assert '"py.typed"' in package_data


def test_an_explorer_page_from_python_names_the_program_as_the_cli_does():
    fb = sp.Framebuffer(16, 16)
    mesh = sp.shapes.cube()
    camera = sp.Camera(eye=(2.0, 2.0, 3.0))
    trace = sp.draw_mesh(fb, mesh, camera, "phong", trace=True)
    assert [d["program"] for d in explorer_data(trace)["meta"]["draws"]] == ["phong"]      # not "phong_fragment"
