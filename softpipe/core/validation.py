"""Validation: reading values someone wrote, and saying exactly what is wrong with one.

Two kinds of callers share these checks, so that a mistake is worded the same wherever
it is made:

- the **files** softpipe reads (scene files, batch job files). A :class:`Reader` reads
  one file (:meth:`Reader.read_file`) and its TOML (:meth:`Reader.parse_toml`: a syntax
  error names the line); a :class:`Table` checks a table's keys (an unknown key is named
  with the keys allowed there and the closest one) and converts each value. Every
  mistake is an :class:`InputError` whose message starts with the file name and names
  the table and the key: ``scene.toml: key 'kd' in [materials.gold] must be …``.
- the **Python API** (``Material(kd=…)``, ``Light(position=…)``): :func:`checked` names
  the field: ``Material.kd must hold numbers >= 0, got float -0.1 in a tuple of 3``.

A *value reader* is a function of one value that returns it converted (:func:`number`,
:func:`color`, :func:`vec3`, …, or one that a factory makes: ``choice("back", "front")``,
``numbers(3, 4)``) or raises :class:`BadValue`. Its message is the predicate alone
("must be a number, got string 'x'"), so that each caller puts its own subject in
front; :func:`describe` words the value that was given. A value of the wrong kind (a
string for a number) raises :class:`BadType`, which is also a ``TypeError``, so the
Python API keeps raising ``TypeError`` for it and ``ValueError`` for a bad value.

This module knows no scene: the readers of program names, sample patterns, shapes and
bundled models are in :mod:`softpipe.scenes.scenefile`.
"""
from __future__ import annotations

import difflib
import math
import os
import re
from collections.abc import Sequence as _SequenceABC
from numbers import Integral, Real
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, TypeVar, cast

try:  # Python 3.11+
    import tomllib as _toml
except ModuleNotFoundError:  # pragma: no cover - Python 3.10 with the tomli backport
    try:
        import tomli as _toml
    except ModuleNotFoundError:
        _toml = None

from softpipe.core.colors import parse_color
from softpipe.core.files import PathPolicyError, check_regular_file, resolve_inside

__all__ = ["BadValue", "BadType", "InputError", "checked", "describe", "is_number", "number", "positive",
           "nonnegative", "integer", "boolean", "string", "choice", "numbers", "vec3", "nonzero_vec3", "color",
           "Table", "Reader"]

T = TypeVar("T")

#: How :func:`color` words what it takes.
COLOR_FORMS = 'a number (gray), an array [r, g, b] or a color name such as "red"'


# ---------------------------------------------------------------------------- the errors


class BadValue(ValueError):
    """A value's problem, worded to follow its subject: ``str(e)`` is "must be …, got …"."""

    def named(self, subject: str) -> Exception:
        """The error the Python API raises: ``subject`` and this message, a plain ``ValueError``."""
        return ValueError(f"{subject} {self}")


class BadType(BadValue, TypeError):
    """A value of the wrong kind (a string where a number belongs); a ``TypeError`` too."""

    def named(self, subject: str) -> Exception:
        """As :meth:`BadValue.named`, a plain ``TypeError``."""
        return TypeError(f"{subject} {self}")


class InputError(ValueError):
    """A mistake in a file softpipe reads; ``str(e)`` starts with the file name (and line, for syntax).

    Attributes: ``file``, ``table`` (e.g. ``"[[lights]] #2"``), ``key``, ``line``
    (TOML syntax errors and text that is not UTF-8) and ``reason`` (the message
    without the file name).
    """

    def __init__(self, message: str, file: str = "<string>", table: Optional[str] = None,
                 key: Optional[str] = None, line: Optional[int] = None) -> None:
        self.file, self.table, self.key, self.line, self.reason = file, table, key, line, message
        super().__init__(f"{file}:{line}: {message}" if line else f"{file}: {message}")


def checked(subject: str, read: Callable[[Any], T], value: Any) -> T:
    """``read(value)``, its :class:`BadValue` raised as a plain ``ValueError`` (``TypeError`` for a
    value of the wrong kind) that starts with ``subject``: ``checked("Material.kd", color, v)``."""
    try:
        return read(value)
    except BadValue as e:
        raise e.named(subject) from None


def describe(v: Any) -> str:
    """A value as a message shows it: its kind, and the value itself when it is short."""
    if isinstance(v, bool):
        return f"boolean {str(v).lower()}"
    if isinstance(v, Integral):
        v = int(v)
        text = str(v) if abs(v) < 10 ** 30 else f"{str(v)[:12]}… ({len(str(abs(v)))} digits)"
        return f"integer {text}"
    if isinstance(v, Real):
        return f"float {float(v)!r}"
    if isinstance(v, str):
        text = v if len(v) <= 40 else v[:37] + "..."
        return f"string {text!r}"
    if isinstance(v, list):
        return f"an array of {len(v)}"
    if isinstance(v, tuple):
        return f"a tuple of {len(v)}"
    if isinstance(v, dict):
        return "a table"
    if v is None:
        return "None"
    if hasattr(v, "shape") and hasattr(v, "dtype"):
        return f"an array of shape {tuple(v.shape)}"
    return f"{type(v).__name__} {str(v)[:40]!r}"  # TOML dates and times


# ---------------------------------------------------------------------------- value readers


def is_number(v: Any) -> bool:
    """A real number, and not a boolean (``True`` is an ``int`` to Python, never a number here)."""
    return isinstance(v, Real) and not isinstance(v, bool)


def number(v: Any, what: str = "a number") -> float:
    """A finite number, as a float; ``what`` words it in messages ("an angle in degrees")."""
    if not is_number(v):
        raise BadType(f"must be {what}, got {describe(v)}")
    try:
        x = float(v)
    except OverflowError:
        raise BadValue(f"must be {what}, got {describe(v)} (too large)") from None
    if not math.isfinite(x):
        raise BadValue(f"must be a finite number, got {describe(v)}")
    return x


def positive(v: Any) -> float:
    """A finite number > 0."""
    x = number(v, "a positive number")
    if x <= 0:
        raise BadValue(f"must be a positive number, got {describe(v)}")
    return x


def nonnegative(v: Any) -> float:
    """A finite number >= 0."""
    x = number(v, "a number >= 0")
    if x < 0:
        raise BadValue(f"must be a number >= 0, got {describe(v)}")
    return x


def integer(v: Any) -> int:
    """An ``int`` (not a float with no fraction, not a boolean)."""
    if not isinstance(v, int) or isinstance(v, bool):
        raise BadType(f"must be an integer, got {describe(v)}")
    return v


def boolean(v: Any) -> bool:
    """``True`` or ``False`` (not 0 or 1)."""
    if not isinstance(v, bool):
        raise BadType(f"must be true or false, got {describe(v)}")
    return v


def string(v: Any) -> str:
    """A string."""
    if not isinstance(v, str):
        raise BadType(f"must be a string, got {describe(v)}")
    return v


def choice(*options: str) -> Callable[[Any], str]:
    """A reader of one of the strings ``options``."""
    def read(v: Any) -> str:
        if not isinstance(v, str) or v not in options:
            raise BadValue(f"must be one of {', '.join(repr(o) for o in options)}, got {describe(v)}")
        return v
    return read


def _items(v: Any) -> Optional[List[Any]]:
    """The entries of a list, tuple or one-dimensional array; None for anything else."""
    if isinstance(v, (str, bytes, dict)):
        return None
    if hasattr(v, "shape") and hasattr(v, "dtype"):      # a numpy array, without importing numpy
        return v.tolist() if len(v.shape) == 1 else None
    return list(v) if isinstance(v, _SequenceABC) else None


def _entry(c: Any, whole: Any, expected: str, allow_negative: bool) -> float:
    """One entry of an array of numbers; the message names the entry and the array it is in."""
    where = f"{describe(c)} in {describe(whole)}"
    if not is_number(c):
        raise BadType(f"must be {expected}, got {where}")
    try:
        x = float(c)
    except OverflowError:
        raise BadValue(f"must be {expected}, got {describe(c)} (too large) in {describe(whole)}") from None
    if not math.isfinite(x):
        raise BadValue(f"must hold finite numbers, got {where}")
    if not allow_negative and x < 0:
        raise BadValue(f"must hold numbers >= 0, got {where}")
    return x


def numbers(*counts: int, what: str = "numbers",
            allow_negative: bool = True) -> Callable[[Any], Tuple[float, ...]]:
    """A reader of an array of ``counts`` (3, or 3 or 4, …) finite numbers (>= 0 unless
    ``allow_negative``), as a tuple of floats; ``what`` names them in messages."""
    n = " or ".join(str(c) for c in counts)
    expected = f"an array of {n} {what}"

    def read(v: Any) -> Tuple[float, ...]:
        items = _items(v)
        if items is None:
            raise BadType(f"must be {expected}, got {describe(v)}")
        if len(items) not in counts:
            raise BadValue(f"must be {expected}, got {describe(v)}")
        return tuple(_entry(c, v, expected, allow_negative) for c in items)
    return read


#: A position or a direction: an array of 3 finite numbers.
vec3 = numbers(3)


def nonzero_vec3(v: Any) -> Tuple[float, float, float]:
    """A direction: :data:`vec3`, not (0, 0, 0)."""
    x = cast(Tuple[float, float, float], vec3(v))
    if not any(x):
        raise BadValue("must not be the zero vector")
    return x


def color(v: Any, *, allow_negative: bool = False) -> Tuple[float, float, float]:
    """An RGB color as a tuple of 3 floats: one number (gray), three numbers, or a name or hex
    string (:func:`softpipe.core.colors.parse_color`, without alpha).

    The components must be >= 0 (the colors of lights and materials) unless ``allow_negative``
    (a color written to the framebuffer, which is unclamped).
    """
    if is_number(v):
        x = number(v) if allow_negative else nonnegative(v)
        return (x, x, x)
    if isinstance(v, str):
        try:
            c = parse_color(v)
        except ValueError as e:
            raise BadValue(f"must be a color: {e}") from None
        if len(c) != 3:
            raise BadValue(f"must be an RGB color (no alpha), got {describe(v)}")
        return c
    items = _items(v)
    if items is None or len(items) != 3:
        raise (BadType if items is None else BadValue)(f"must be {COLOR_FORMS}, got {describe(v)}")
    return cast(Tuple[float, float, float],
                tuple(_entry(c, v, "an array [r, g, b] of numbers", allow_negative) for c in items))


# ---------------------------------------------------------------------------- reading a file


_MISSING = object()
#: Where tomllib's messages say the line: "(at line 7, column 3)".
_LINE = re.compile(r"\(at line (\d+), column (\d+)\)")


class Table:
    """One table of a file being read: checks its keys and converts its values, naming itself in errors.

    Parameters
    ----------
    reader : Reader
        The file's reader, which makes the errors (they name the file).
    data : Any
        The table as TOML gave it; anything but a dict is refused (``what`` says what it must be).
    label : str
        How messages name the table: ``"[render]"``, ``"[[lights]] #2"``.
    allowed : sequence of str
        The keys it may hold; any other is an error naming the closest allowed key.
    """

    def __init__(self, reader: "Reader", data: Any, label: str, allowed: Sequence[str],
                 what: str = "a table") -> None:
        self.reader, self.label, self.allowed = reader, label, list(allowed)
        if not isinstance(data, dict):
            raise reader.error(f"{label} must be {what}, got {describe(data)}", table=label)
        self.data: Dict[str, Any] = data
        for key in data:
            if key not in self.allowed:
                close = difflib.get_close_matches(key, self.allowed, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise reader.error(f"unknown key {key!r} in {label}{hint}; expected one of "
                                   f"{', '.join(self.allowed)}", table=label, key=key)

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def error(self, message: str, key: Optional[str] = None) -> InputError:
        """An error about the table ("[render]: …") or, with ``key``, about one key ("key 'k' in [render] …")."""
        if key is None:
            return self.reader.error(f"{self.label}: {message}", table=self.label)
        return self.reader.error(f"key {key!r} in {self.label} {message}", table=self.label, key=key)

    def get(self, key: str, read: Callable[[Any], Any], default: Any = _MISSING) -> Any:
        """The value of ``key`` converted by the reader ``read``; ``default`` when it is absent
        (without a default, an absent key is an error)."""
        if key not in self.data:
            if default is _MISSING:
                raise self.reader.error(f"{self.label} needs key {key!r}", table=self.label, key=key)
            return default
        try:
            return read(self.data[key])
        except BadValue as e:
            raise self.error(str(e), key) from None

    def library(self, key: Optional[str], make: Callable[[], T]) -> T:
        """Call the library (``Camera(…)``, ``Light(…)``, …); its ValueError or TypeError becomes
        this file's error, naming the table (and ``key``)."""
        try:
            return make()
        except (ValueError, TypeError) as e:
            if isinstance(e, InputError):
                raise
            raise (self.error(str(e)) if key is None else
                   self.reader.error(f"key {key!r} in {self.label}: {e}", table=self.label, key=key)) from None


class Reader:
    """One reading of one TOML file: names it in every error and resolves the files it names.

    Subclasses read a kind of file (:class:`softpipe.scenes.scenefile.SceneReader`) and set
    :attr:`kind` and :attr:`error_class`.

    Parameters
    ----------
    file : str
        How errors name the file (its path, or ``"<string>"``).
    base_dir : str
        The folder the file names files in ("" is the current folder).
    allow_outside : bool
        Let it name files outside ``base_dir`` (:func:`softpipe.core.files.resolve_inside`).
    """

    #: What the file is, in messages: "scene file not found".
    kind = "file"
    #: The error the reader raises (a subclass of :class:`InputError`).
    error_class = InputError

    def __init__(self, file: str = "<string>", base_dir: str = "", allow_outside: bool = False) -> None:
        self.file, self.base_dir, self.allow_outside = file, base_dir, allow_outside

    def error(self, message: str, table: Optional[str] = None, key: Optional[str] = None,
              line: Optional[int] = None) -> InputError:
        """This file's error (not raised: the caller raises it)."""
        return self.error_class(message, file=self.file, table=table, key=key, line=line)

    def read_file(self) -> str:
        """The text of the file named by ``file`` (UTF-8, a byte-order mark skipped); refuses a
        FIFO or a device (:func:`softpipe.core.files.check_regular_file`)."""
        try:
            check_regular_file(self.file)
            with open(self.file, "rb") as f:
                raw = f.read()
        except PathPolicyError as e:
            raise self.error(str(e)) from None
        except FileNotFoundError:
            raise self.error(f"{self.kind} not found") from None
        except IsADirectoryError:
            raise self.error(f"is a directory, not a {self.kind}") from None
        except OSError as e:
            raise self.error(f"cannot read the {self.kind}: {e.strerror or e}") from None
        try:
            return raw.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            line = raw[:e.start].count(b"\n") + 1
            raise self.error(f"not UTF-8 text (byte {e.start})", line=line) from None

    def parse_toml(self, text: str) -> Dict[str, Any]:
        """The document ``text`` holds; a syntax error names its line (``file:7: TOML syntax error: …``)."""
        if _toml is None:  # pragma: no cover
            raise self.error(f"reading {self.kind}s needs Python 3.11 (tomllib) or the 'tomli' package")
        try:
            return _toml.loads(text)
        except RecursionError:
            raise self.error("TOML error: arrays or tables nested too deeply") from None
        except ValueError as e:  # TOMLDecodeError, and int() of a number with too many digits
            message = str(e)
            found = _LINE.search(message)
            if found:
                line: Optional[int] = int(found.group(1))
            elif "end of document" in message:
                line = text.count("\n") + (0 if text.endswith("\n") else 1)
            else:
                line = None
            message = _LINE.sub("", message).replace(" (at end of document)", " (at the end of the file)").strip()
            if "integer string conversion" in message:  # int() refuses more than sys.get_int_max_str_digits()
                message = "an integer has too many digits"
            kind = "TOML syntax error" if isinstance(e, getattr(_toml, "TOMLDecodeError", ())) else "TOML error"
            raise self.error(f"{kind}: {message}", line=max(line, 1) if line is not None else None) from None

    def path(self, table: Table, key: str, hint: str = "") -> str:
        """The file named by ``key`` of ``table``, relative to ``base_dir``; it must exist
        (``hint`` follows "file not found")."""
        rel = table.get(key, string)
        if not rel.strip() or "\0" in rel:
            raise table.error(f"must name a file, got {describe(rel)}", key)
        try:
            path = resolve_inside(self.base_dir, rel, allow_outside=self.allow_outside)
        except PathPolicyError as e:
            raise self.error(f"key {key!r} in {table.label}: {e}", table=table.label, key=key) from None
        if not os.path.isfile(path):
            problem = (f"is a directory, not a file: {path}" if os.path.isdir(path) else
                       f"file not found: {path}{hint}")
            raise self.error(f"key {key!r} in {table.label}: {problem}", table=table.label, key=key)
        return path
