"""Atomic output: build a file or folder under a hidden temporary name beside the target, then
rename it into place.

A reader never sees a half-written output, and a failure (bad input found late, Ctrl-C, disk
full) leaves nothing behind.  Every writer of the project goes through these functions (this
module is public: ``cli``, ``report`` and ``sim`` use it too).

Files made by ``mkstemp`` (0600) get the permissions an ordinary ``open`` would have given them.
The process' umask is read without changing it (``/proc/self/status`` on Linux; elsewhere the
value seen once at import), because ``os.umask`` sets and restores a process-wide value, which
races with the library's own writer threads.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from ibiscape_eval.core.errors import IbiscapeError

__all__ = [
    "atomic_output_dir",
    "atomic_output_path",
    "atomic_write",
    "current_umask",
    "discard",
    "publish",
    "publish_permissions",
    "staging_path",
]


def _umask_from_proc() -> int | None:
    """The umask from ``/proc/self/status`` (Linux >= 4.7), or None where that file lacks it."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        return None
    return None


def _umask_at_import() -> int:
    # No /proc: read once, while the module is imported (before any writer thread runs).
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_proc_mask = _umask_from_proc()
_IMPORT_UMASK: int = _umask_at_import() if _proc_mask is None else _proc_mask


def current_umask() -> int:
    """The process' file-creation mask, read without changing it."""
    mask = _umask_from_proc()
    return _IMPORT_UMASK if mask is None else mask


def publish_permissions(path: str | os.PathLike[str], *, folder: bool = False) -> None:
    """Give a file made by ``mkstemp`` (mode 0600) or a folder made by ``mkdtemp`` (0700) the
    permissions an ordinary ``open``/``mkdir`` would have had under the current umask."""
    os.chmod(path, (0o777 if folder else 0o666) & ~current_umask())


def staging_path(target: str | os.PathLike[str], *, folder: bool = False) -> Path:
    """Create and return a hidden temporary sibling of ``target``: an empty file that keeps the
    target's suffix (so format detection by extension still works), or an empty folder."""
    t = Path(target)
    t.parent.mkdir(parents=True, exist_ok=True)
    if folder:
        return Path(tempfile.mkdtemp(prefix=f".{t.name}.", suffix=".partial", dir=t.parent))
    fd, tmp = tempfile.mkstemp(prefix=f".{t.stem}.", suffix=t.suffix, dir=t.parent)
    os.close(fd)
    return Path(tmp)


def publish(
    tmp: str | os.PathLike[str], target: str | os.PathLike[str], *, overwrite: bool = False
) -> None:
    """Rename the staged ``tmp`` onto ``target`` with ordinary permissions.

    A folder target that already exists is replaced if it is empty, or if ``overwrite``; its old
    content is removed only after the new folder is in place.  Otherwise ``tmp`` is discarded and
    :class:`IbiscapeError` raised.
    """
    src, dst = Path(tmp), Path(target)
    folder = src.is_dir()
    publish_permissions(src, folder=folder)
    if not folder or not dst.exists():
        os.replace(src, dst)
        return
    if any(dst.iterdir()) and not overwrite:
        discard(src)
        raise IbiscapeError(
            f"{dst}: output folder exists and is not empty (it appeared while "
            "writing); remove it or choose another output folder"
        )
    old = Path(tempfile.mkdtemp(prefix=f".{dst.name}.", suffix=".old", dir=dst.parent))
    os.replace(dst, old / "x")
    os.replace(src, dst)
    shutil.rmtree(old, ignore_errors=True)


def discard(tmp: str | os.PathLike[str]) -> None:
    """Remove a staged file or folder (nothing happens if it is already gone)."""
    p = Path(tmp)
    if p.is_dir():
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()


@contextlib.contextmanager
def atomic_output_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` for libraries that want a file name (matplotlib,
    numpy, cv2); it is renamed onto ``path`` on success and removed on failure."""
    tmp = staging_path(path)
    try:
        yield tmp
    except BaseException:
        discard(tmp)
        raise
    publish(tmp, path)


@contextlib.contextmanager
def atomic_output_dir(path: str | os.PathLike[str], *, overwrite: bool = False) -> Iterator[Path]:
    """Yield an empty temporary folder beside ``path`` that replaces ``path`` when the block
    finishes without error (see :func:`publish` for an existing ``path``)."""
    tmp = staging_path(path, folder=True)
    try:
        yield tmp
    except BaseException:
        discard(tmp)
        raise
    publish(tmp, path, overwrite=overwrite)


def atomic_write(
    path: str | os.PathLike[str], mode: str = "w"
) -> contextlib.AbstractContextManager[IO[Any]]:
    """Open ``path`` for writing (``"w"`` text, UTF-8, ``\\n`` newlines; or ``"wb"``) through a
    temporary file beside it that replaces ``path`` only when the block finishes without error.

    Examples
    --------
    >>> with atomic_write("out.txt") as f:  # doctest: +SKIP
    ...     f.write("hello")
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_write mode must be 'w' or 'wb', got {mode!r}")
    return _atomic_write(Path(path), mode)


@contextlib.contextmanager
def _atomic_write(path: Path, mode: str) -> Iterator[IO[Any]]:
    with atomic_output_path(path) as tmp:
        text = {} if mode == "wb" else {"encoding": "utf-8", "newline": "\n"}
        with open(tmp, mode, **text) as f:  # type: ignore[call-overload]
            yield f
