"""Which files a model or scene may name, and outputs written whole or not at all (issue #13)."""
from __future__ import annotations

import os
import stat

import pytest

from softpipe.files import PathPolicyError, atomic_write, check_writable, excerpt, resolve_inside
from softpipe.scenefile import SceneError, load_scene, parse_scene

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.fixture
def tree(tmp_path):
    """models/ (the scene's folder) with a mesh in it and one below; a secret beside it."""
    models = tmp_path / "models"
    (models / "sub").mkdir(parents=True)
    (models / "tri.obj").write_text(TRIANGLE)
    (models / "sub" / "tri.obj").write_text(TRIANGLE)
    (tmp_path / "secret.obj").write_text("SECRET-CONTENT\n" + TRIANGLE)
    return models


def _scene(models, obj: str, **kw):
    path = models / "scene.toml"
    path.write_text(f'[[meshes]]\nobj = "{obj}"\n')
    return load_scene(path, **kw)


@pytest.mark.parametrize("ref", ["tri.obj", "sub/tri.obj", "./sub/../tri.obj"])
def test_files_in_the_folder_and_below_are_read(tree, ref):
    assert _scene(tree, ref).objects[0].mesh.triangle_count == 1


@pytest.mark.parametrize("ref, why", [
    ("../secret.obj", "leads out of the folder"),
    ("sub/../../secret.obj", "leads out of the folder"),
    ("/etc/passwd", "is an absolute path"),
    ("/proc/self/environ", "is an absolute path"),
    ("~/secret.obj", "names a file in a home folder"),
])
def test_files_outside_the_folder_are_refused_without_reading_them(tree, ref, why):
    with pytest.raises(SceneError) as e:
        _scene(tree, ref)
    message = str(e.value)
    assert why in message and "scene.toml" in message and "key 'obj'" in message
    assert "SECRET" not in message and "allow_outside=True" in message
    assert len(message.splitlines()) == 1


def test_a_link_that_points_out_of_the_folder_is_refused(tree):
    os.symlink(tree.parent / "secret.obj", tree / "link.obj")
    with pytest.raises(SceneError, match="leads out of the folder"):
        _scene(tree, "link.obj")


def test_the_answer_is_the_same_whether_or_not_the_outside_file_exists(tree):
    """No probing: a refused path says nothing about the file system beyond the folder."""
    messages = []
    for ref in ("../secret.obj", "../no-such-file.obj"):
        with pytest.raises(SceneError) as e:
            _scene(tree, ref)
        messages.append(str(e.value).replace(ref, "REF"))
    assert messages[0] == messages[1]


def test_allow_outside_lifts_the_folder_rule(tree):
    assert _scene(tree, "../secret.obj", allow_outside=True).objects[0].mesh.triangle_count == 1
    scene = parse_scene('[[meshes]]\nobj = "../secret.obj"\n', base_dir=os.fspath(tree), allow_outside=True)
    assert scene.objects[0].mesh.triangle_count == 1


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_at_once_even_when_outside_files_are_allowed(tree):
    os.mkfifo(tree / "pipe.obj")
    for kw in ({}, {"allow_outside": True}):
        with pytest.raises(SceneError, match="'pipe.obj' is a FIFO, not a regular file"):
            _scene(tree, "pipe.obj", **kw)
    os.mkfifo(tree / "pipe.toml")
    with pytest.raises(SceneError, match="is a FIFO"):
        load_scene(tree / "pipe.toml")                      # the scene file itself


def test_a_texture_outside_the_folder_is_refused(tree):
    path = tree / "scene.toml"
    path.write_text('[materials.m]\ndiffuse_texture = "../secret.png"\n[[meshes]]\nobj = "tri.obj"\nmaterial = "m"\n')
    with pytest.raises(SceneError, match=r"key 'diffuse_texture' in \[materials.m\]: '\.\./secret\.png' leads out"):
        load_scene(path)


def test_resolve_inside_and_a_long_reference_is_quoted_short(tmp_path):
    assert resolve_inside(tmp_path, "a/b.png") == os.path.join(os.path.realpath(tmp_path), "a", "b.png")
    long = "../" + "x" * 10_000
    with pytest.raises(PathPolicyError) as e:
        resolve_inside(tmp_path, long)
    assert len(str(e.value)) < 400 and "10,003 characters" in str(e.value)
    assert excerpt("short") == "'short'"


# ------------------------------------------------------------------------------ outputs

def test_atomic_write_replaces_the_file_only_when_the_write_succeeds(tmp_path):
    out = tmp_path / "picture.png"
    out.write_bytes(b"the good old picture")
    for error in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        def failing(f, error=error):
            f.write(b"half a pic")
            raise error
        with pytest.raises(type(error)):
            atomic_write(out, failing)
        assert out.read_bytes() == b"the good old picture"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["picture.png"]      # no temporary left behind
    atomic_write(out, lambda f: f.write(b"new"))
    assert out.read_bytes() == b"new"
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~_umask()                 # not mkstemp's 0600


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path):
    with pytest.raises(OSError, match="does not exist"):
        check_writable(tmp_path / "no-such-folder" / "x.png")
    with pytest.raises(IsADirectoryError, match="it is a folder"):
        check_writable(tmp_path)
    if os.geteuid() != 0:                                    # root may write anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(PermissionError, match="not writable"):
            check_writable(locked / "x.png")
