"""softpipe.core.validation: the value readers, their one wording, and the reading of a TOML file."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

import softpipe as sp
from softpipe.core.validation import (
    BadType,
    BadValue,
    InputError,
    Reader,
    Table,
    boolean,
    checked,
    choice,
    color,
    describe,
    integer,
    is_number,
    nonnegative,
    nonzero_vec3,
    number,
    numbers,
    positive,
    string,
    vec3,
)
from softpipe.scenes.scenefile import SceneError, parse_scene


def message(read, value) -> str:
    with pytest.raises(BadValue) as info:
        read(value)
    return str(info.value)


# ---------------------------------------------------------------------------- describing a value


@pytest.mark.parametrize("value, words", [
    (True, "boolean true"),
    (3, "integer 3"),
    (np.int64(-2), "integer -2"),
    (10 ** 40, "integer 100000000000… (41 digits)"),
    (0.5, "float 0.5"),
    (np.float32(0.25), "float 0.25"),
    ("x" * 50, "string '" + "x" * 37 + "...'"),
    ([1, 2], "an array of 2"),
    ((1, 2, 3), "a tuple of 3"),
    ({"a": 1}, "a table"),
    (None, "None"),
    (np.zeros((2, 3)), "an array of shape (2, 3)"),
])
def test_describe_names_the_kind_and_a_short_value(value, words):
    assert describe(value) == words


def test_booleans_are_never_numbers():
    assert is_number(1) and is_number(np.float64(0.5)) and not is_number(True) and not is_number("1")
    assert message(number, True) == "must be a number, got boolean true"
    assert message(integer, False) == "must be an integer, got boolean false"
    assert message(boolean, 1) == "must be true or false, got integer 1"


# ---------------------------------------------------------------------------- the readers


@pytest.mark.parametrize("read, value, words", [
    (number, "1", "must be a number, got string '1'"),
    (number, math.inf, "must be a finite number, got float inf"),
    (number, 10 ** 400, "must be a number, got integer 100000000000… (401 digits) (too large)"),
    (positive, 0, "must be a positive number, got integer 0"),
    (nonnegative, -0.5, "must be a number >= 0, got float -0.5"),
    (integer, 2.0, "must be an integer, got float 2.0"),
    (string, 3, "must be a string, got integer 3"),
    (choice("back", "front"), "side", "must be one of 'back', 'front', got string 'side'"),
    (vec3, [1, 2], "must be an array of 3 numbers, got an array of 2"),
    (vec3, [1, "2", 3], "must be an array of 3 numbers, got string '2' in an array of 3"),
    (vec3, (1, math.nan, 3), "must hold finite numbers, got float nan in a tuple of 3"),
    (nonzero_vec3, (0, 0, 0), "must not be the zero vector"),
    (numbers(3, 4), 7, "must be an array of 3 or 4 numbers, got integer 7"),
    (numbers(3, allow_negative=False), [1, -1, 0], "must hold numbers >= 0, got integer -1 in an array of 3"),
    (color, [1, 0], 'must be a number (gray), an array [r, g, b] or a color name such as "red", got an array of 2'),
    (color, -1, "must be a number >= 0, got integer -1"),
    (color, (0.5, -0.5, 0), "must hold numbers >= 0, got float -0.5 in a tuple of 3"),
    (color, [1, None, 0], "must be an array [r, g, b] of numbers, got None in an array of 3"),
    (color, "#ff000080", "must be an RGB color (no alpha), got string '#ff000080'"),
])
def test_a_reader_says_what_the_value_must_be_and_what_it_got(read, value, words):
    assert message(read, value) == words


def test_a_value_of_the_wrong_kind_is_also_a_type_error():
    for read, value in ((number, "1"), (vec3, "up"), (color, None), (color, [1, "x", 0]), (boolean, 0)):
        with pytest.raises(BadType):
            read(value)
        with pytest.raises(TypeError):
            read(value)
    for read, value in ((positive, -1), (vec3, [1, 2]), (color, "#ff000080")):
        with pytest.raises(BadValue) as info:
            read(value)
        assert not isinstance(info.value, TypeError)


def test_readers_convert():
    assert number(3) == 3.0 and type(number(3)) is float
    assert vec3(np.array([1, 2, 3])) == (1.0, 2.0, 3.0)
    assert color(0.5) == (0.5, 0.5, 0.5) and color("red") == (1.0, 0.0, 0.0)
    assert color([-1, 0, 2], allow_negative=True) == (-1.0, 0.0, 2.0)
    assert numbers(3, 4)([0, 0, 0, 1]) == (0.0, 0.0, 0.0, 1.0)


def test_checked_names_the_subject_and_raises_a_plain_error():
    with pytest.raises(ValueError) as info:
        checked("Thing.size", positive, -2)
    assert type(info.value) is ValueError and str(info.value) == "Thing.size must be a positive number, got integer -2"
    with pytest.raises(TypeError) as info:
        checked("Thing.size", positive, "big")
    assert type(info.value) is TypeError and str(info.value) == "Thing.size must be a positive number, got string 'big'"
    assert checked("Thing.size", positive, 2) == 2.0


def test_one_wording_in_the_python_api_and_in_a_scene_file():
    """The same mistake reads the same after its subject: Material(kd=…) and kd = … in a scene file."""
    for toml, python in (("[1, -1, 1]", [1, -1, 1]), ("[1, 2]", [1, 2]), ('"#ff000080"', "#ff000080"),
                         ("-1", -1), ("[1, inf, 0]", [1, math.inf, 0])):
        with pytest.raises(ValueError) as api:
            sp.Material(kd=python)
        with pytest.raises(SceneError) as scene:
            parse_scene(f'[materials.m]\nkd = {toml}\n[[meshes]]\nshape = "cube"\nmaterial = "m"\n', "s.toml")
        predicate = str(api.value).removeprefix("Material.kd ")
        assert predicate.startswith("must ") and str(scene.value) == f"s.toml: key 'kd' in [materials.m] {predicate}"


# ---------------------------------------------------------------------------- tables and files


def test_a_table_checks_its_keys_and_names_itself():
    reader = Reader("f.toml")
    with pytest.raises(InputError, match=r"^f\.toml: unknown key 'widht' in \[render\] \(did you mean 'width'\?\); "
                                         r"expected one of width, height$") as info:
        Table(reader, {"widht": 3}, "[render]", ("width", "height"))
    assert (info.value.file, info.value.table, info.value.key) == ("f.toml", "[render]", "widht")
    with pytest.raises(InputError, match=r"^f\.toml: \[render\] must be a table, got integer 3$"):
        Table(reader, 3, "[render]", ("width",))
    t = Table(reader, {"width": "3"}, "[render]", ("width", "height"))
    assert "width" in t and t.get("height", integer, 7) == 7
    with pytest.raises(InputError, match=r"^f\.toml: key 'width' in \[render\] must be an integer, got string '3'$"):
        t.get("width", integer)
    with pytest.raises(InputError, match=r"^f\.toml: \[render\] needs key 'height'$"):
        t.get("height", integer)


def test_a_table_turns_the_librarys_errors_into_the_files_and_keeps_its_own():
    reader = Reader("f.toml")
    t = Table(reader, {}, "[camera]", ())

    def bad():
        raise ValueError("Camera.fovy must be in (0, 180) degrees")
    with pytest.raises(InputError, match=r"^f\.toml: \[camera\]: Camera\.fovy must be"):
        t.library(None, bad)
    with pytest.raises(InputError, match=r"^f\.toml: key 'fovy' in \[camera\]: Camera\.fovy must be"):
        t.library("fovy", bad)
    inner = reader.error("already this file's", table="[x]")

    def raise_inner():
        raise inner
    with pytest.raises(InputError) as info:
        t.library("fovy", raise_inner)
    assert info.value is inner


@pytest.mark.parametrize("text, expected", [
    ("a = 1\nb = \n", "f.toml:2: TOML syntax error: Invalid value"),
    ("a = [1,\n2", "f.toml:2: TOML syntax error:"),
    ("a = " + "[" * 3000, "f.toml: TOML error: arrays or tables nested too deeply"),
    ("a = " + "1" * 5000, "f.toml: TOML error: an integer has too many digits"),
])
def test_toml_errors_name_the_line(text, expected):
    with pytest.raises(InputError) as info:
        Reader("f.toml").parse_toml(text)
    assert str(info.value).startswith(expected) and "\n" not in str(info.value)


def test_reading_a_file_names_what_is_wrong(tmp_path):
    class Notes(Reader):
        kind = "notes file"
    with pytest.raises(InputError, match=r"nope\.toml: notes file not found$"):
        Notes(str(tmp_path / "nope.toml")).read_file()
    with pytest.raises(InputError, match=r": is a directory, not a notes file$"):
        Notes(str(tmp_path)).read_file()
    (tmp_path / "latin1.toml").write_bytes(b"a = 1\n# caf\xe9\n")
    with pytest.raises(InputError, match=r"latin1\.toml:2: not UTF-8 text \(byte 11\)$") as info:
        Notes(str(tmp_path / "latin1.toml")).read_file()
    assert info.value.line == 2
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbfa = 1\n")
    assert Notes(str(tmp_path / "bom.toml")).read_file() == "a = 1\n"
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "pipe.toml")
        with pytest.raises(InputError, match="is a FIFO, not a regular file"):
            Notes(str(tmp_path / "pipe.toml")).read_file()


def test_a_file_named_in_a_file_is_resolved_inside_its_folder(tmp_path):
    (tmp_path / "m.obj").write_text("")
    (tmp_path / "sub").mkdir()
    reader = Reader("f.toml", str(tmp_path))
    assert reader.path(Table(reader, {"obj": "m.obj"}, "[a]", ("obj",)), "obj") == str(tmp_path / "m.obj")
    with pytest.raises(InputError, match=r"key 'obj' in \[a\]: '\.\./x\.obj' leads out of the folder"):
        reader.path(Table(reader, {"obj": "../x.obj"}, "[a]", ("obj",)), "obj")
    with pytest.raises(InputError, match=r"key 'obj' in \[a\]: file not found: .*gone\.obj \(a hint\)$"):
        reader.path(Table(reader, {"obj": "gone.obj"}, "[a]", ("obj",)), "obj", " (a hint)")
    with pytest.raises(InputError, match=r"key 'obj' in \[a\]: is a directory, not a file"):
        reader.path(Table(reader, {"obj": "sub"}, "[a]", ("obj",)), "obj")
    with pytest.raises(InputError, match=r"key 'obj' in \[a\] must name a file, got string ' '$"):
        reader.path(Table(reader, {"obj": " "}, "[a]", ("obj",)), "obj")
