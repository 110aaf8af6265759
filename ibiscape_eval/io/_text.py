"""Fast, exact parsing of numeric text tables (TUM, KITTI, EuRoC, IBISCape, GNSS).

One numba tokenizer walks the raw bytes once.  It accepts any run of spaces, tabs, commas and
carriage returns as a separator, skips blank lines and ``#`` comments (whole-line and trailing),
and keeps the 1-based line number of every data row, so every error can name its line.

Floats are parsed from their decimal digits (up to 19 significant digits kept, the rest rounded):
a value with at most 15-16 digits and a small exponent is converted with a single rounding
(Clinger's fast path), longer ones are off by at most one unit in the last place.

The first column (the timestamp) is additionally kept as an exact decimal ``mantissa * 10**exp``
with an int64 mantissa, so that ``1305031098.665900001`` s or ``1.403715273262143e+18`` ns convert
to int64 nanoseconds without passing through float64 (which cannot hold 1.3e9 s to 1 ns).
"""

from __future__ import annotations

import itertools
import mmap
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.cpus import usable_cpus
from ibiscape_eval.core.errors import FormatError, Remedy

__all__ = ["Table", "decimal_to_ns", "format_lines", "map_bytes", "parse_table", "read_bytes",
           "write_table"]

_NCOLS, _NOTNUM, _NUL = 1, 2, 3  # status codes of the tokenizer
_NOT_BLANK = re.compile(rb"[^ \t\n\r\x0b\x0c]")  # what bytes.strip() would keep
_HEAD_BYTES = 1 << 16  # parsed first, alone: the header lines of a file
_PARALLEL_BYTES = 4 << 20  # inputs above this are tokenized in parallel threads
_MAX_THREADS = 4
_PIECES_PER_THREAD = 4  # smaller pieces balance threads that other processes slow down
_MMAP_BYTES = 1 << 20  # files from this size on are memory-mapped instead of read
_POW10_INT = np.array([10**k for k in range(19)], dtype=np.int64)
_INT64_MAX = np.iinfo(np.int64).max


@dataclass(frozen=True)
class Table:
    """Rows of a numeric text file.

    ``values`` is ``(N, K)`` float64 (the first K columns), ``stamp_mant``/``stamp_exp`` hold the
    first column as the exact decimal ``mant * 10**exp``, ``finite`` flags rows whose kept
    columns are all finite, ``lines`` the 1-based line number of each row.  When
    :func:`parse_table` was given column ``widths``, ``groups`` holds the kept columns as one
    contiguous ``(N, width)`` array per group and ``values`` is the first group.
    """

    values: npt.NDArray[np.float64]
    stamp_mant: npt.NDArray[np.int64]
    stamp_exp: npt.NDArray[np.int32]
    finite: npt.NDArray[np.bool_]
    lines: npt.NDArray[np.int64]
    groups: tuple[npt.NDArray[np.float64], ...] = ()


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    """The raw content of a file; a folder is reported as a FormatError."""
    p = _text_path(path)
    with open(p, "rb") as f:
        return _strip_bom(f.read())


def map_bytes(path: str | os.PathLike[str]) -> bytes | mmap.mmap:
    """The content of a file for :func:`parse_table`: a large regular file is memory-mapped
    read-only (no copy: the tokenizer reads the page cache directly), anything else is read.

    The mapping is released when the returned object is no longer referenced.
    """
    p = _text_path(path)
    with open(p, "rb") as f:
        st = os.fstat(f.fileno())
        if stat.S_ISREG(st.st_mode) and st.st_size >= _MMAP_BYTES:
            if f.read(len(UTF8_BOM)) == UTF8_BOM:  # rare: copy rather than map
                return f.read()
            try:
                return mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
            except (OSError, ValueError):  # pragma: no cover (a file system without mmap)
                f.seek(0)
        return _strip_bom(f.read())


#: The UTF-8 byte-order mark some editors (Notepad, Excel) put at the start of a text file.
UTF8_BOM = b"\xef\xbb\xbf"


def _strip_bom(data: bytes) -> bytes:
    return data[len(UTF8_BOM):] if data.startswith(UTF8_BOM) else data


def _text_path(path: str | os.PathLike[str]) -> Path:
    """``path`` if it is a regular file; FIFOs, devices, loops and folders are refused."""
    from .paths import check_input

    p = Path(path)
    if p.is_dir():
        raise FormatError(p, "is a folder, expected a text file (a ROS 2 bag? use {0})",
                          hint=(Remedy("fmt", "bag"),))
    return check_input(p)


_kernel_module: Any = None  # set once the kernels are imported and numba's runtime started


def _kernels() -> Any:
    """The numba kernels (:mod:`._text_kernels`), imported and started on first use.

    (The command line pauses the garbage collector around this start-up: see
    :mod:`ibiscape_eval.cli.startup`; the library leaves process-wide state alone.)
    """
    global _kernel_module
    if _kernel_module is not None:
        return _kernel_module
    from . import _text_kernels

    _text_kernels.count_newlines(np.frombuffer(b"\n" * 8, dtype=np.uint8), 0, 8)
    _kernel_module = _text_kernels
    return _text_kernels


def _is_blank(data: bytes | mmap.mmap) -> bool:
    """True when ``data`` holds nothing but ASCII whitespace (stops at the first other byte)."""
    return _NOT_BLANK.search(data) is None


def _workers() -> int:
    return min(usable_cpus(), _MAX_THREADS)


class _Pool:
    """Runs calls in ``threads`` worker threads, or inline when there is one."""

    def __init__(self, threads: int) -> None:
        self._ex = None
        if threads > 1:
            from concurrent.futures import ThreadPoolExecutor

            self._ex = ThreadPoolExecutor(threads)

    def __enter__(self) -> _Pool:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._ex is not None:
            self._ex.shutdown()

    def map(self, func: Any, args: list[tuple[Any, ...]]) -> list[Any]:
        """``[func(*a) for a in args]``, in parallel; a free thread takes the next call, so a
        thread slowed down by other processes gets fewer pieces."""
        if self._ex is None:
            return [func(*a) for a in args]
        futures = [self._ex.submit(func, *a) for a in args]
        return [f.result() for f in futures]


def _split(data: bytes | mmap.mmap, start: int, stop: int, parts: int) -> list[int]:
    """Boundaries ``start = b0 < b1 < ... = stop``, each just after a newline (``data[stop - 1]``
    is one), cutting ``data[start:stop]`` into at most ``parts`` pieces of similar size."""
    bounds = [start]
    for k in range(1, parts):
        cut = data.find(b"\n", start + (stop - start) * k // parts, stop) + 1
        if cut > bounds[-1] and cut < stop:
            bounds.append(cut)
    bounds.append(stop)
    return bounds


def _status_error(
    path: str | os.PathLike[str],
    status: npt.NDArray[np.int64],
    text: bytes | mmap.mmap,
    expected: str,
) -> FormatError:
    """The :class:`FormatError` described by a tokenizer ``status`` (``text``: its buffer)."""
    code, line = int(status[0]), int(status[1])
    if code == _NUL:
        return FormatError(path, "binary data (NUL byte); expected a text file", line=line)
    if code == _NOTNUM:
        col = int(status[2])
        raw = text[int(status[3]):int(status[4])]
        token = raw.decode("utf-8", errors="backslashreplace")
        printable = all(32 <= b < 127 for b in raw)
        if not printable:
            return FormatError(
                path, f"column {col}: binary or non-text data {token[:20]!r}; expected a text "
                f"file with {expected}", line=line)
        if len(token) > 40:
            token = token[:37] + "..."
        return FormatError(path, f"column {col}: {token!r} is not a number", line=line)
    got = int(status[5])
    return FormatError(path, f"expected {expected}, got {got} column{'s' * (got != 1)}",
                       line=line)


def _outputs(cap: int, widths: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """The kernels' output arrays for ``cap`` rows: three value groups (unused ones empty),
    mantissa, exponent, finite, line."""
    groups = tuple(np.empty((cap, w)) for w in widths)
    groups += tuple(np.empty((0, 0)) for _ in range(3 - len(widths)))
    return (*groups, np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int32),
            np.empty(cap, dtype=np.bool_), np.empty(cap, dtype=np.int64))


def parse_table(
    path: str | os.PathLike[str], data: bytes | mmap.mmap, *,
    nkeep: int, ncols_min: int, ncols_max: int, expected: str,
    widths: tuple[int, ...] | None = None,
) -> Table:
    """Tokenize ``data`` (the content of ``path``) into a :class:`Table`.

    Large inputs are cut at line boundaries and the pieces are tokenized in parallel threads
    (the numba kernels release the GIL); the first error in file order is reported.

    Parameters
    ----------
    nkeep
        Number of leading columns converted to numbers (the others are only counted).
    ncols_min, ncols_max
        Allowed number of columns per data row.
    expected
        Human description of the columns for error messages, e.g. ``"8 columns (t x y z qx qy qz
        qw)"``.
    widths
        Up to three group widths adding up to ``nkeep``, e.g. ``(1, 3, 4)``: the kept columns
        are written straight into one contiguous array per group (``Table.groups``), which a
        reader can adopt without copying.

    Raises
    ------
    FormatError
        Empty file, header only, wrong column count, a non-numeric field, binary content.
    """
    if widths is None:
        widths = (nkeep,)
    if not 1 <= len(widths) <= 3 or sum(widths) != nkeep or min(widths) < 0:
        raise ValueError(f"column widths {widths} do not split {nkeep} columns in 1 to 3 groups")
    if _is_blank(data):
        raise FormatError(path, f"file is empty; expected {expected}")
    kernels = _kernels()
    count_newlines, move_rows, scan_lines = (kernels.count_newlines, kernels.move_rows,
                                             kernels.scan_lines)

    buf = np.frombuffer(data, dtype=np.uint8)
    body = data.rfind(b"\n") + 1  # the kernels need each piece to end with a newline
    # The small head (a header, usually) is parsed first, so that the parallel pieces after it
    # can be written in place: they only move when a comment or blank line sits between them.
    head = data.find(b"\n", min(_HEAD_BYTES, body - 1)) + 1 if body else 0
    workers = _workers() if body - head >= _PARALLEL_BYTES else 1
    parts = 1 if workers == 1 else _PIECES_PER_THREAD * workers
    pieces = list(itertools.pairwise(_split(data, head, body, parts)))
    with _Pool(workers) as pool:
        counts = pool.map(count_newlines, [(buf, a, b) for a, b in pieces])
        n_head = count_newlines(buf, 0, head)
        cap = n_head + sum(counts) + (body < len(data))
        out = _outputs(cap, widths)
        status = np.zeros((len(pieces) + 2, 6), dtype=np.int64)
        rows = scan_lines(buf, 0, head, nkeep, ncols_min, ncols_max, 0, 0, *out, status[0])
        if status[0, 0]:
            raise _status_error(path, status[0], data, expected)
        line0 = np.cumsum([n_head, *counts])  # lines before each piece
        row0 = rows + line0 - n_head  # where each piece writes its rows
        ends = pool.map(scan_lines, [
            (buf, a, b, nkeep, ncols_min, ncols_max, int(line0[k]), int(row0[k]), *out,
             status[k + 1]) for k, (a, b) in enumerate(pieces)])
    for k, end in enumerate(ends):
        if status[k + 1, 0]:
            raise _status_error(path, status[k + 1], data, expected)
        if row0[k] > rows:  # a comment or blank line left a gap before this piece
            move_rows(*out, int(row0[k]), rows, end - int(row0[k]))
        rows += end - int(row0[k])
    if body < len(data):  # a last line without a newline
        tail = data[body:] + b"\n"
        rows = scan_lines(np.frombuffer(tail, dtype=np.uint8), 0, len(tail), nkeep, ncols_min,
                          ncols_max, int(line0[-1]), rows, *out, status[-1])
        if status[-1, 0]:
            raise _status_error(path, status[-1], tail, expected)
    if rows == 0:
        raise FormatError(path, f"no data rows (only comments or a header); expected {expected}")
    kept = tuple(g[:rows] for g in out[:len(widths)])
    mant, exps, finite, lines = (a[:rows] for a in out[3:])
    return Table(kept[0], mant, exps, finite, lines, kept if len(widths) > 1 else ())


def decimal_to_ns(
    path: str | os.PathLike[str], table: Table, *, unit_exp: int
) -> npt.NDArray[np.int64]:
    """Exact int64 nanoseconds from the first column's decimal digits.

    ``unit_exp`` is 9 for a column in seconds and 0 for nanoseconds.  Digits below 1 ns are
    rounded half away from zero.  Non-finite stamps give 0 (their rows are dropped later).
    """
    mant = table.stamp_mant
    if mant.size and 0 <= int(table.stamp_exp[0]) + unit_exp <= 18:
        # The usual file: every stamp written with the same number of decimals.
        e0 = int(table.stamp_exp[0])
        if bool((table.stamp_exp == e0).all()):
            p0 = int(_POW10_INT[e0 + unit_exp])
            if p0 == 1:
                return mant.copy()
            lim = _INT64_MAX // p0
            if int(mant.max()) <= lim and int(mant.min()) >= -lim:
                return mant * p0
    shift = table.stamp_exp.astype(np.int64) + unit_exp
    out = np.zeros(mant.shape, dtype=np.int64)
    up = shift >= 0
    if up.any():
        too_big = up & (mant != 0) & (shift > 18)
        s_up = np.clip(shift, 0, 18)
        p = _POW10_INT[s_up]
        too_big |= up & (np.abs(mant) > _INT64_MAX // p)
        if too_big.any():
            i = int(np.flatnonzero(too_big)[0])
            raise FormatError(path, "timestamp is too large for int64 nanoseconds",
                              line=int(table.lines[i]))
        out = np.where(up, mant * p, out)
    down = ~up
    if down.any():
        k = np.clip(-shift, 0, 18)
        p = _POW10_INT[k]
        q = (np.abs(mant) + p // 2) // p
        q = np.where(-shift > 18, 0, q)
        out = np.where(down, np.sign(mant) * q, out)
    return out


def format_lines(lines: npt.ArrayLike, limit: int = 5) -> str:
    """``"3, 7, 9"`` or ``"3, 7, 9, 12, 15 and 40 more"`` for warning messages."""
    arr = np.asarray(lines)
    head = ", ".join(str(int(v)) for v in arr[:limit])
    return head if arr.size <= limit else f"{head} and {arr.size - limit} more"


def write_table(
    f: IO[bytes],
    stamps_ns: npt.NDArray[np.int64] | None,
    values: npt.ArrayLike,
    *,
    stamp: str,
    sep: str,
    row_end: str = "\n",
    chunk_rows: int = 100_000,
) -> None:
    """Write rows ``stamp sep v0 sep v1 ... row_end`` to a binary file, in chunks.

    ``stamp`` is ``"none"``, ``"ns"`` (integer), ``"s"`` (``%d.%09d``, exact) or ``"ns_f"``
    (integer ns followed by ``.000000`` like the IBISCape scripts' ``%f``).  Floats are written
    with 15 significant digits (relative error below 5e-15).
    """
    format_rows = _kernels().format_rows
    vals = np.ascontiguousarray(values, dtype=np.float64)
    mode = {"none": 0, "ns": 1, "s": 2, "ns_f": 3}[stamp]
    st = (np.zeros(len(vals), dtype=np.int64) if stamps_ns is None
          else np.ascontiguousarray(stamps_ns, dtype=np.int64))
    end = np.frombuffer(row_end.encode(), dtype=np.uint8)
    for a in range(0, len(vals), chunk_rows):
        b = a + chunk_rows
        f.write(format_rows(st[a:b], vals[a:b], mode, ord(sep), end).tobytes())
