"""Which files a model or scene may name, and outputs written whole or not at all (issue #13)."""
from __future__ import annotations

import os
import stat
import threading
import warnings
from pathlib import Path

import pytest
from PIL import Image

from softpipe.core.files import PathPolicyError, atomic_write, check_writable, excerpt, resolve_inside
from softpipe.scenes.models import load_model
from softpipe.scenes.obj import OBJWarning, load_mtl, load_obj, parse_obj
from softpipe.scenes.scenefile import SceneError, load_scene, parse_scene

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


# ------------------------------------------------------------------------------ files an OBJ names

SECRET_MTL = "newmtl leaked\nKd 0.25 0.5 0.75\nSECRET-CONTENT 1\nmap_Kd secret.png\n"
USES = "usemtl leaked\n" + TRIANGLE


@pytest.fixture
def objtree(tmp_path):
    """models/ holding m.obj (and m.mtl, a texture); secret.mtl and secret.png beside the folder."""
    models = tmp_path / "models"
    models.mkdir()
    (models / "inside.png").write_bytes(b"not read here")
    (tmp_path / "secret.mtl").write_text(SECRET_MTL)
    Image.new("RGB", (2, 2), (255, 0, 0)).save(tmp_path / "secret.png")
    return models


def _load(models, obj_text, **kw):
    """load_obj of models/m.obj holding obj_text: (mesh, warning messages)."""
    (models / "m.obj").write_text(obj_text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = _without_blocking(lambda: load_obj(models / "m.obj", **kw), models)
    return mesh, [str(w.message) for w in caught if issubclass(w.category, OBJWarning)]


def _without_blocking(call, folder, seconds=20.0):
    """call(), failing (not hanging) if it blocks on a FIFO in ``folder``: the FIFOs are
    then opened for writing and closed, which lets a blocked reader go."""
    outcome = {}

    def target():
        try:
            outcome["value"] = call()
        except BaseException as e:                          # re-raised below
            outcome["error"] = e

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        for fifo in folder.rglob("*"):
            if stat.S_ISFIFO(fifo.lstat().st_mode):
                try:
                    os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
                except OSError:
                    pass
        thread.join(5)
        pytest.fail(f"blocked for {seconds} s reading a FIFO")
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def _refs(models):
    outside = models.parent
    return {
        "dotdot": ("../secret.mtl", "leads out of the folder"),
        "dotdot-from-below": ("sub/../../secret.mtl", "leads out of the folder"),
        "absolute": (str(outside / "secret.mtl"), "is an absolute path"),
        "proc-environ": ("/proc/self/environ", "is an absolute path"),
        "home": ("~/secret.mtl", "names a file in a home folder"),
    }


@pytest.mark.parametrize("case", ["dotdot", "dotdot-from-below", "absolute", "proc-environ", "home"])
def test_an_mtllib_outside_the_folder_is_refused_unread(objtree, case, monkeypatch):
    monkeypatch.setenv("HOME", os.fspath(objtree.parent))   # "~" is the folder that holds secret.mtl
    ref, why = _refs(objtree)[case]
    mesh, messages = _load(objtree, f"mtllib {ref}\n" + USES)
    refused = [m for m in messages if "material library" in m]
    assert len(refused) == 1, messages
    assert refused[0].startswith("m.obj:1: material library ") or f"{os.sep}m.obj:1: material library " in refused[0]
    assert why in refused[0] and "allow_outside=True" in refused[0] and "using default materials" in refused[0]
    assert mesh.source.mtl_skipped == {}                    # the file was never parsed
    assert mesh.material.kd != (0.25, 0.5, 0.75)           # nor its materials used
    shown = repr(mesh.source) + "\n".join(messages)
    assert "SECRET" not in shown
    if case == "proc-environ":
        with open("/proc/self/environ", "rb") as f:
            names = [v.split(b"=", 1)[0].decode("utf-8", "replace") for v in f.read().split(b"\0") if b"=" in v]
        assert not any(name in mesh.source.mtl_skipped for name in names)


def test_an_mtllib_link_out_of_the_folder_is_refused(objtree):
    os.symlink(objtree.parent / "secret.mtl", objtree / "link.mtl")
    mesh, messages = _load(objtree, "mtllib link.mtl\n" + USES)
    assert any("m.obj:1: material library 'link.mtl' leads out of the folder" in m for m in messages), messages
    assert mesh.source.mtl_skipped == {} and "SECRET" not in repr(mesh.source)


def test_a_refused_mtllib_says_the_same_whether_or_not_the_file_exists(objtree):
    """'not found' versus anything else would tell which files exist outside the folder."""
    seen = []
    for ref in ("../secret.mtl", "../no-such.mtl"):
        _, messages = _load(objtree, f"mtllib {ref}\n" + TRIANGLE)
        seen.append([m.replace(ref, "REF") for m in messages])
    assert seen[0] == seen[1] and "not found" not in " ".join(seen[0])


@pytest.mark.parametrize("ref, why", [
    ("../secret.png", "leads out of the folder"),
    ("/etc/passwd", "is an absolute path"),
    ("~/secret.png", "names a file in a home folder"),
    ("-s 1 1 1 ../secret.png", "leads out of the folder"),       # after map options
    ("..\\secret.png", "leads out of the folder"),               # written on Windows
])
def test_a_map_kd_outside_the_folder_is_refused(objtree, ref, why, monkeypatch):
    monkeypatch.setenv("HOME", os.fspath(objtree.parent))
    (objtree / "m.mtl").write_text(f"newmtl a\nKd 1 0 0\nmap_Kd {ref}\n")
    mesh, messages = _load(objtree, "mtllib m.mtl\nusemtl a\n" + TRIANGLE)
    assert mesh.material.diffuse_texture is None and mesh.material.kd == (1, 0, 0)
    texture = [m for m in messages if "texture" in m]
    assert len(texture) == 1 and "m.mtl:3: texture " in texture[0] and why in texture[0], messages
    assert "material 'a' gets no diffuse texture" in texture[0] and "SECRET" not in texture[0]
    # load_mtl applies the same rule
    with pytest.warns(OBJWarning, match=why):
        assert load_mtl(objtree / "m.mtl")["a"].diffuse_texture is None


def test_a_map_kd_link_out_of_the_folder_is_refused_and_one_inside_is_kept(objtree):
    os.symlink(objtree.parent / "secret.png", objtree / "link.png")
    (objtree / "m.mtl").write_text("newmtl a\nmap_Kd link.png\nnewmtl b\nmap_Kd inside.png\n")
    with pytest.warns(OBJWarning, match=r"m\.mtl:2: texture 'link\.png' leads out of the folder"):
        mats = load_mtl(objtree / "m.mtl")
    assert mats["a"].diffuse_texture is None
    assert mats["b"].diffuse_texture == os.path.join(os.path.realpath(objtree), "inside.png")


@pytest.mark.filterwarnings("ignore:.*material 'leaked' is not defined")
def test_allow_outside_reads_files_outside_the_folder(objtree, monkeypatch):
    monkeypatch.setenv("HOME", os.fspath(objtree.parent))
    outside = os.path.realpath(objtree.parent)
    for ref in ("../secret.mtl", str(objtree.parent / "secret.mtl"), "~/secret.mtl"):
        mesh, messages = _load(objtree, f"mtllib {ref}\n" + USES, allow_outside=True)
        assert messages == [] and mesh.material.kd == (0.25, 0.5, 0.75)
        assert mesh.material.diffuse_texture == os.path.join(outside, "secret.png")
        assert mesh.source.mtl_skipped == {"SECRET-CONTENT": 1}
    (objtree / "m.obj").write_text("mtllib ../secret.mtl\n" + USES)
    assert load_model(objtree / "m.obj", allow_outside=True).material.kd == (0.25, 0.5, 0.75)
    with pytest.warns(OBJWarning, match="leads out of the folder"):
        assert load_model(objtree / "m.obj").material.kd != (0.25, 0.5, 0.75)
    text = "mtllib ../secret.mtl\n" + USES
    assert parse_obj(text, "t.obj", base_dir=objtree, allow_outside=True).material.kd == (0.25, 0.5, 0.75)
    with pytest.warns(OBJWarning, match=r"t\.obj:1: material library '\.\./secret\.mtl' leads out"):
        parse_obj(text, "t.obj", base_dir=objtree)


@pytest.mark.filterwarnings("ignore:.*material 'leaked' is not defined")
def test_a_scene_passes_its_allow_outside_to_the_obj_loader(objtree):
    (objtree / "m.obj").write_text("mtllib ../secret.mtl\n" + USES)
    (objtree / "scene.toml").write_text('[[meshes]]\nobj = "m.obj"\n')
    with pytest.warns(UserWarning, match="material library '../secret.mtl' leads out of the folder"):
        scene = load_scene(objtree / "scene.toml")
    assert scene.objects[0].mesh.material.kd != (0.25, 0.5, 0.75)
    trusted = load_scene(objtree / "scene.toml", allow_outside=True)
    assert trusted.objects[0].mesh.material.kd == (0.25, 0.5, 0.75)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("allow_outside", [False, True])
def test_fifos_named_by_an_obj_or_given_as_the_model_are_refused_at_once(objtree, allow_outside):
    os.mkfifo(objtree / "pipe.mtl")
    os.mkfifo(objtree / "pipe.png")
    kw = {"allow_outside": allow_outside}
    mesh, messages = _load(objtree, "mtllib pipe.mtl\n" + TRIANGLE, **kw)
    assert any("m.obj:1: material library 'pipe.mtl' is a FIFO, not a regular file; using default materials" in m
               for m in messages), messages
    (objtree / "m.mtl").write_text("newmtl a\nmap_Kd pipe.png\n")
    mesh, messages = _load(objtree, "mtllib m.mtl\nusemtl a\n" + TRIANGLE, **kw)
    assert mesh.material.diffuse_texture is None
    assert any("m.mtl:2: texture 'pipe.png' is a FIFO, not a regular file" in m for m in messages), messages
    # the model itself: one line, at once, for load_obj and load_model (a FIFO would block open() forever)
    os.mkfifo(objtree / "model.obj")
    for load in (load_obj, load_model):
        with pytest.raises(PathPolicyError) as e:
            _without_blocking(lambda: load(objtree / "model.obj", **kw), objtree)
        assert str(e.value).endswith("model.obj' is a FIFO, not a regular file")
        assert len(str(e.value).splitlines()) == 1
    os.mkfifo(objtree / "pipe2.mtl")
    with pytest.raises(PathPolicyError, match="is a FIFO"):
        _without_blocking(lambda: load_mtl(objtree / "pipe2.mtl"), objtree)


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="no /dev/null here")
def test_a_device_as_the_model_is_refused():
    with pytest.raises(PathPolicyError, match="'/dev/null' is a device, not a regular file"):
        _without_blocking(lambda: load_obj("/dev/null"), Path("/nonexistent"))
