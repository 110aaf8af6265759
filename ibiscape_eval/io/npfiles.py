"""Open ``.npy``/``.npz`` files defensively: never unpickle, and turn every way a damaged file can
fail inside numpy or zipfile (bad magic, flipped header bytes, truncation, CRC errors, bad
compression) into one :class:`~ibiscape_eval.core.errors.FormatError` naming the file (and key).
"""

from __future__ import annotations

import os
import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError

__all__ = ["NPY_MAGIC", "ZIP_MAGICS", "check_magic", "load_npz_arrays"]

NPY_MAGIC = b"\x93NUMPY"
ZIP_MAGICS = (b"PK\x03\x04", b"PK\x05\x06")

#: Everything numpy, zipfile and zlib raise on damaged bytes.
DAMAGE_ERRORS: tuple[type[BaseException], ...] = (
    ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error, SyntaxError,
    tokenize.TokenError, KeyError, TypeError, OverflowError, MemoryError, IndexError,
    AttributeError, NotImplementedError, RecursionError, UnicodeDecodeError,
)


def _kind(head: bytes) -> str:
    if head.startswith(NPY_MAGIC):
        return ".npy"
    if any(head.startswith(m) for m in ZIP_MAGICS):
        return ".npz"
    if head.startswith(b"\x80"):
        return "a pickle"
    if not head:
        return "an empty file"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        return "an unknown binary file"
    return "a text file"


def check_magic(path: str | os.PathLike[str], expected: str) -> None:
    """Refuse a file whose first bytes are not those of ``expected`` (``".npy"`` or ``".npz"``)."""
    with open(path, "rb") as fh:
        head = fh.read(8)
    kind = _kind(head)
    if kind != expected:
        raise FormatError(path, f"not a readable {expected} file (its first bytes are those of {kind}); "
                          f"save it with numpy.{'save' if expected == '.npy' else 'savez'}")


def load_npz_arrays(path: str | os.PathLike[str], keys: tuple[str, ...] | None = None
                    ) -> dict[str, np.ndarray[Any, Any]]:
    """Every array (or the given keys that exist) of an ``.npz``, read with ``allow_pickle=False``.

    Raises :class:`FormatError` for a file that is not an .npz, a damaged archive or member, or
    a member holding pickled objects.
    """
    p = Path(path)
    check_magic(p, ".npz")
    out: dict[str, np.ndarray[Any, Any]] = {}
    key = None
    try:
        with np.load(p, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise FormatError(p, "not an .npz archive")
            for key in z.files if keys is None else [k for k in keys if k in z.files]:
                out[key] = z[key]
    except FormatError:
        raise
    except ValueError as e:
        if "pickle" in str(e):
            raise FormatError(p, f"key {key!r} holds pickled Python objects, which are refused "
                              "for safety; save plain numeric arrays") from None
        raise FormatError(p, _damaged(key, e)) from None
    except DAMAGE_ERRORS as e:
        if isinstance(e, FileNotFoundError | PermissionError | IsADirectoryError):
            raise
        raise FormatError(p, _damaged(key, e)) from None
    return out


def _damaged(key: str | None, e: BaseException) -> str:
    what = "archive" if key is None else f"member {key!r}"
    msg = " ".join(str(e).split())[:120] or type(e).__name__
    return f"damaged .npz {what} ({msg}); the file is truncated or corrupt, export it again"
