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

import os
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError

__all__ = ["Table", "decimal_to_ns", "format_lines", "parse_table", "read_bytes", "write_table"]

_NCOLS, _NOTNUM, _NUL = 1, 2, 3  # status codes of the tokenizer
_POW10_INT = np.array([10**k for k in range(19)], dtype=np.int64)
_INT64_MAX = np.iinfo(np.int64).max


@dataclass(frozen=True)
class Table:
    """Rows of a numeric text file.

    ``values`` is ``(N, K)`` float64 (the first K columns), ``stamp_mant``/``stamp_exp`` hold the
    first column as the exact decimal ``mant * 10**exp``, ``finite`` flags rows whose kept
    columns are all finite, ``lines`` the 1-based line number of each row.
    """

    values: npt.NDArray[np.float64]
    stamp_mant: npt.NDArray[np.int64]
    stamp_exp: npt.NDArray[np.int32]
    finite: npt.NDArray[np.bool_]
    lines: npt.NDArray[np.int64]


def read_bytes(path: str | os.PathLike[str]) -> bytes:
    """The raw content of a file; a folder is reported as a FormatError."""
    p = Path(path)
    if p.is_dir():
        raise FormatError(p, "is a folder, expected a text file (a ROS 2 bag? use --format bag)")
    with open(p, "rb") as f:
        return f.read()


def parse_table(
    path: str | os.PathLike[str],
    data: bytes,
    *,
    nkeep: int,
    ncols_min: int,
    ncols_max: int,
    expected: str,
) -> Table:
    """Tokenize ``data`` (the content of ``path``) into a :class:`Table`.

    Parameters
    ----------
    nkeep
        Number of leading columns converted to numbers (the others are only counted).
    ncols_min, ncols_max
        Allowed number of columns per data row.
    expected
        Human description of the columns for error messages, e.g. ``"8 columns (t x y z qx qy qz
        qw)"``.

    Raises
    ------
    FormatError
        Empty file, header only, wrong column count, a non-numeric field, binary content.
    """
    if not data.strip():
        raise FormatError(path, f"file is empty; expected {expected}")
    from ._text_kernels import scan

    buf = np.frombuffer(data, dtype=np.uint8)
    nrows, vals, mant, exps, finite, lines, status = scan(buf, nkeep, ncols_min, ncols_max)
    code, line = int(status[0]), int(status[1])
    if code == _NUL:
        raise FormatError(path, "binary data (NUL byte); expected a text file", line=line)
    if code == _NOTNUM:
        col = int(status[2])
        raw = data[int(status[3]):int(status[4])]
        token = raw.decode("utf-8", errors="backslashreplace")
        printable = all(32 <= b < 127 for b in raw)
        if not printable:
            raise FormatError(
                path, f"column {col}: binary or non-text data {token[:20]!r}; expected a text file "
                f"with {expected}", line=line)
        if len(token) > 40:
            token = token[:37] + "..."
        raise FormatError(path, f"column {col}: {token!r} is not a number", line=line)
    if code == _NCOLS:
        got = int(status[5])
        raise FormatError(path, f"expected {expected}, got {got} column{'s' * (got != 1)}",
                          line=line)
    if nrows == 0:
        raise FormatError(path, f"no data rows (only comments or a header); expected {expected}")
    return Table(vals[:nrows], mant[:nrows], exps[:nrows], finite[:nrows].copy(),
                 lines[:nrows])


def decimal_to_ns(
    path: str | os.PathLike[str], table: Table, *, unit_exp: int
) -> npt.NDArray[np.int64]:
    """Exact int64 nanoseconds from the first column's decimal digits.

    ``unit_exp`` is 9 for a column in seconds and 0 for nanoseconds.  Digits below 1 ns are
    rounded half away from zero.  Non-finite stamps give 0 (their rows are dropped later).
    """
    mant = table.stamp_mant
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
    from ._text_kernels import format_rows

    vals = np.ascontiguousarray(values, dtype=np.float64)
    mode = {"none": 0, "ns": 1, "s": 2, "ns_f": 3}[stamp]
    st = (np.zeros(len(vals), dtype=np.int64) if stamps_ns is None
          else np.ascontiguousarray(stamps_ns, dtype=np.int64))
    end = np.frombuffer(row_end.encode(), dtype=np.uint8)
    for a in range(0, len(vals), chunk_rows):
        b = a + chunk_rows
        f.write(format_rows(st[a:b], vals[a:b], mode, ord(sep), end).tobytes())
