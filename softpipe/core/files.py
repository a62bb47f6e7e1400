"""softpipe and the file system: which files a model may name, and how outputs are written.

**Files named inside a file** (an OBJ's ``mtllib``, a material's ``map_Kd``, a
scene file's meshes and textures) are resolved inside the naming file's folder
and below (:func:`resolve_inside`). Absolute paths, ``~``, ``..`` that leaves the
folder and links that point out of it are refused, and so are special files
(FIFOs, devices, sockets), which could block a reader forever: a model someone
else wrote cannot make softpipe read ``/proc/self/environ`` or say which files
exist on the machine. Errors name the reference, shortened, never what the
target holds. ``allow_outside=True`` (``--allow-outside-paths`` on the command
line) lifts the folder rule for files you trust; special files stay refused.

**Outputs** are written whole or not at all (:func:`atomic_write`): to a
temporary file in the same folder, then renamed over the target, so a full disk,
a crash or Ctrl-C never leaves half a PNG and never destroys the previous file.
SIGTERM (``kill``, a job scheduler stopping the program) removes the temporary file
too: while the main thread writes one, softpipe's handler stands in for the default
one, removes every temporary file being written and ends the process by SIGTERM as
the default would (a handler of the program's own is left as it is).
"""
from __future__ import annotations

import os
import signal
import stat
import tempfile
import threading
from pathlib import Path
from typing import IO, Callable, Union

__all__ = ["PathPolicyError", "resolve_inside", "check_regular_file", "atomic_write", "atomic_write_bytes", "check_writable", "excerpt",
           "excerpt_path"]

PathLike = Union[str, os.PathLike]

#: How much of an offending input an error message quotes.
EXCERPT_CHARS = 80


class PathPolicyError(ValueError):
    """A file named inside a model or scene file is not one softpipe will read."""


def excerpt(text: str, limit: int = EXCERPT_CHARS) -> str:
    """``text`` quoted (repr) and cut to about ``limit`` characters, for error messages."""
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"… ({len(text):,} characters)"


def excerpt_path(path: PathLike, limit: int = EXCERPT_CHARS) -> str:
    """A path quoted (repr) for error messages; a long one keeps its end, the file's name ('…/models/a.obj')."""
    text = os.fspath(path)
    if len(text) <= limit:
        return repr(text)
    return repr("…" + text[-(limit - 1):])


def check_regular_file(path: PathLike, shown: str | None = None) -> None:
    """Refuse what is not a regular file (a FIFO or device would block or never end), before opening it.

    ``shown`` is how the message names the file (default: ``path``).
    """
    shown = os.fspath(path) if shown is None else shown
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return          # the caller's own "not found" is clearer
    except OSError as e:
        raise PathPolicyError(f"cannot read {excerpt_path(shown)}: {e.strerror}") from None
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise PathPolicyError(f"{excerpt_path(shown)} is {kind}, not a regular file")


def resolve_inside(base_dir: PathLike, reference: str, *, allow_outside: bool = False) -> str:
    """The file ``reference`` (as written in a file in ``base_dir``) names, if softpipe may read it.

    Raises :class:`PathPolicyError` (one short sentence, the reference shortened)
    for an absolute path, ``~``, a path that leaves ``base_dir`` (``..`` or a link),
    or a special file; with ``allow_outside`` only special files are refused.
    Whether the file exists is left to the caller.
    """
    if not isinstance(reference, str) or not reference.strip() or "\0" in reference:
        raise PathPolicyError(f"{excerpt(reference)} does not name a file")
    base = os.path.realpath(os.fspath(base_dir) or ".")
    if allow_outside:
        path = os.path.normpath(os.path.join(base, os.path.expanduser(reference)))
    else:
        if reference.startswith("~"):
            raise PathPolicyError(f"{excerpt(reference)} names a file in a home folder; a model's files must be "
                                  "in its own folder or below (allow_outside=True for files you trust)")
        if os.path.isabs(reference) or Path(reference).drive:
            raise PathPolicyError(f"{excerpt(reference)} is an absolute path; a model's files must be in its own "
                                  "folder or below (allow_outside=True for files you trust)")
        path = os.path.normpath(os.path.join(base, reference))
        real = os.path.realpath(path)
        if os.path.commonpath([real, base]) != base:
            raise PathPolicyError(f"{excerpt(reference)} leads out of the folder {excerpt(base)}; a model's files "
                                  "must be in its own folder or below (allow_outside=True for files you trust)")
    check_regular_file(path, reference)
    return path


def check_writable(path: PathLike) -> None:
    """Refuse, before any work, an output whose folder does not exist or cannot be written."""
    folder = os.path.dirname(os.path.abspath(os.fspath(path))) or "."
    if not os.path.isdir(folder):
        raise OSError(f"cannot write {excerpt(os.fspath(path))}: the folder {excerpt(folder)} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"cannot write {excerpt(os.fspath(path))}: the folder {excerpt(folder)} is not "
                              "writable")
    if os.path.isdir(path):
        raise IsADirectoryError(f"cannot write {excerpt(os.fspath(path))}: it is a folder")


def atomic_write(path: PathLike, write: Callable[[IO[bytes]], object]) -> None:
    """Write ``path`` whole or not at all: ``write(file)`` fills a temporary file in the same
    folder, which then replaces ``path`` (``os.replace``, atomic on one file system).

    If ``write`` raises (a full disk, Ctrl-C), the temporary file is removed and
    ``path`` is left as it was.
    """
    path = os.fspath(path)
    check_writable(path)
    folder = os.path.dirname(os.path.abspath(path))
    with _removed_on_sigterm() as pending:
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
        pending.add(tmp)
        try:
            with os.fdopen(fd, "wb") as f:
                write(f)
                f.flush()
                os.fsync(f.fileno())
            mode = 0o666 & ~_umask()
            os.chmod(tmp, mode)             # mkstemp's 0600 would make outputs private
            os.replace(tmp, path)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
        finally:
            pending.discard(tmp)


def atomic_write_bytes(path: PathLike, data: bytes) -> None:
    """:func:`atomic_write` of ``data``: ``path`` holds all of it or is left as it was."""
    atomic_write(path, lambda f: f.write(data))


# The temporary files being written, and how many writes of the main thread have SIGTERM's handler up.
_pending: set = set()
_pending_lock = threading.Lock()
_handler_users = 0


def _on_sigterm(signum, frame) -> None:
    """Remove the temporary files being written, then die of SIGTERM as the default handler does."""
    for tmp in list(_pending):
        try:
            os.unlink(tmp)
        except OSError:
            pass
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGTERM)


class _removed_on_sigterm:
    """While it is entered: the temporary files added to it are removed if SIGTERM comes.

    The handler goes up only from the main thread (the only one that may set one) and only over
    the default handler; the first write to enter puts it up and the last to leave takes it down.
    """

    def __enter__(self) -> set:
        global _handler_users
        self.installed = False
        if threading.current_thread() is threading.main_thread():
            with _pending_lock:
                if _handler_users or signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
                    if not _handler_users:
                        signal.signal(signal.SIGTERM, _on_sigterm)
                    _handler_users += 1
                    self.installed = True
        return _pending

    def __exit__(self, *exc) -> None:
        global _handler_users
        if self.installed:
            with _pending_lock:
                _handler_users -= 1
                if not _handler_users and signal.getsignal(signal.SIGTERM) is _on_sigterm:
                    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _umask() -> int:
    """The process's umask, read without changing it (os.umask would, for every thread)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o022
