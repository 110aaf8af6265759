"""Check an input path before opening it: refuse what would hang, loop or mislead a reader.

``open()`` on a named pipe blocks until a writer appears, a symbolic-link loop fails with ELOOP
deep inside a reader, and a folder where a file is expected (or a device, a socket) gives
confusing errors.  :func:`check_input` looks at the path with one ``stat`` and raises a
:class:`~ibiscape_eval.core.errors.FormatError` with a one-line message naming the path instead.
Every reader of the project calls it first.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import Literal

from ibiscape_eval.core.errors import FormatError

__all__ = ["check_input", "os_error_message", "read_text"]

Kind = Literal["file", "folder", "any"]

_NOT_REGULAR = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def os_error_message(e: OSError) -> str:
    """One line for an OS error on a user's path: the path, what happened, what to do."""
    name = e.filename if e.filename is not None else "input"
    if e.errno == errno.ELOOP:
        return f"{name}: symbolic link loop; give the real file"
    if e.errno == errno.ENOENT:
        return f"{name}: no such file or directory; check the path"
    if e.errno == errno.EACCES or e.errno == errno.EPERM:
        return f"{name}: permission denied"
    if e.errno == errno.EISDIR:
        return f"{name}: is a folder, expected a file"
    if e.errno == errno.ENOTDIR:
        return f"{name}: a part of the path is not a folder; check the path"
    if e.errno == errno.ENAMETOOLONG:
        return f"{name}: path too long"
    if e.errno == errno.ENOSPC:
        return f"{name}: no space left on the device; free some space or write elsewhere"
    return f"{name}: {e.strerror or type(e).__name__}"


def check_input(path: str | os.PathLike[str], kind: Kind = "file", *, what: str = "") -> Path:
    """Return ``path`` as a :class:`~pathlib.Path` if it is an existing regular file (``kind="file"``),
    folder (``"folder"``) or either (``"any"``); raise :class:`FormatError` otherwise
    (:class:`FileNotFoundError` when it does not exist).

    ``what`` names the input in the message (``"--config"``, ``"IMU file"``...).
    """
    p = Path(path)
    label = f" ({what})" if what else ""
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise  # the readers' documented error; the command line names the path
    except OSError as e:
        if e.filename is None:
            e.filename = str(p)
        raise FormatError(None, os_error_message(e) + label) from None
    mode = st.st_mode
    for test, name in _NOT_REGULAR:
        if test(mode):
            raise FormatError(p, f"is {name}, not a regular file{label}; give a file")
    if stat.S_ISDIR(mode):
        if kind == "file":
            raise FormatError(p, f"is a folder, expected a file{label}")
        return p
    if kind == "folder":
        raise FormatError(p, f"is a file, expected a folder{label}")
    return p


def read_text(path: str | os.PathLike[str], *, what: str = "", max_bytes: int | None = None) -> str:
    """The content of a small UTF-8 text file (a BOM is dropped) after :func:`check_input`;
    non-UTF-8 bytes raise :class:`FormatError` naming the line."""
    p = check_input(path, what=what)
    with open(p, "rb") as fh:
        raw = fh.read() if max_bytes is None else fh.read(max_bytes + 1)
    if max_bytes is not None and len(raw) > max_bytes:
        raise FormatError(p, f"larger than {max_bytes} bytes: not the expected {what or 'file'}")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise FormatError(p, f"not UTF-8 text (byte 0x{raw[e.start]:02x}); save the file as UTF-8",
                          line=raw[: e.start].count(b"\n") + 1) from None
