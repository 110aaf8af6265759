"""Lists of "timestamp, file name" rows: the one reader and writer behind every frame list.

EuRoC ``data.csv`` (``#timestamp [ns],filename``), the renderer's ``timestamps.csv``
(``#timestamp [ns], filename``), a DVS camera's ``frames/timestamps.csv`` (start, end, file),
TUM RGB-D ``rgb.txt`` / ``depth.txt`` (``timestamp filename`` in seconds) and the VIO's frame
lists are all read by :func:`read_stamped_rows`, with the separator, the stamp parser and the
column count as parameters.  Stamps are parsed exactly (never through a float): integer
nanoseconds (:func:`ns_digits`, :func:`ns_integer`), a decimal number of nanoseconds rounded
half-to-even (:func:`ns_number`), or decimal seconds (:func:`seconds_exact`).  Every error is a
:class:`~ibiscape_eval.core.errors.FormatError` naming the file and line.
"""

from __future__ import annotations

import decimal
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError

from .atomic import atomic_write
from .paths import check_input

__all__ = ["StampParser", "ns_digits", "ns_integer", "ns_number", "read_stamped_rows",
           "seconds_exact", "write_stamped_list"]

#: parses one stamp text to integer nanoseconds; raises ValueError when it is not one
StampParser = Callable[[str], int]


def ns_digits(text: str) -> int:
    """A non-negative integer number of nanoseconds (digits only)."""
    if not text.isdigit():
        raise ValueError(text)
    return int(text)


def ns_integer(text: str) -> int:
    """An integer number of nanoseconds, optionally negative."""
    if not text.lstrip("-").isdigit() or text.count("-") > 1:
        raise ValueError(text)
    return int(text)


def ns_number(text: str) -> int:
    """Integer nanoseconds, or a decimal number of nanoseconds (``"5.0"``, ``"1e9"``) rounded
    half-to-even exactly; NaN and infinities raise ValueError."""
    if text.lstrip("+-").isdigit():
        return int(text)
    try:
        d = decimal.Decimal(text)
    except decimal.InvalidOperation:
        raise ValueError(text) from None
    if not d.is_finite() or abs(d) >= 10**30:
        raise ValueError(text)
    return int(d.to_integral_value(rounding=decimal.ROUND_HALF_EVEN))


def seconds_exact(text: str) -> int:
    """Non-negative decimal seconds (at most nine decimals) to integer nanoseconds, exactly."""
    sec, _, frac = text.partition(".")
    if not sec.isdigit() or not (frac.isdigit() or frac == "") or len(frac) > 9:
        raise ValueError(text)
    return int(sec) * 1_000_000_000 + int(frac.ljust(9, "0") or 0)


def read_stamped_rows(path: str | os.PathLike[str], *, expected: str, sep: str | None = ",",
                      ncols: int | tuple[int, int] = 2, stamp_col: int = 0,
                      parse: StampParser = ns_digits, bad_stamp: str | None = None,
                      required: Sequence[int] = (), increasing: bool = False,
                      nonempty: str | None = None, missing: str | None = None,
                      errors: str = "strict") -> tuple[npt.NDArray[np.int64], list[list[str]]]:
    """Stamps [ns] and the stripped fields of each data row of a text list.

    Parameters
    ----------
    expected : the row layout named when a row has the wrong shape (``"'timestamp [ns],filename'"``).
    sep : the field separator (``None``: runs of white space).
    ncols : the number of fields, or the (min, max) range.
    stamp_col, parse : the field holding the stamp and its parser (:data:`StampParser`).
    bad_stamp : the message tail for a stamp ``parse`` refuses (``"is not an integer (ns)"``);
        ``None`` reports it as a row of the wrong shape.
    required : fields that must not be empty.
    increasing : refuse stamps that do not increase strictly.
    nonempty : when given, the message for a list without rows.
    missing : when given, the message for a file that does not exist (else FileNotFoundError).
    errors : the UTF-8 decoding policy (``"strict"`` or ``"replace"``).

    Blank lines and lines starting with ``#`` are skipped.  The path goes through
    :func:`~ibiscape_eval.io.paths.check_input` first.
    """
    p = Path(path)
    if missing is not None and not os.path.lexists(p):
        raise FormatError(p, missing)
    p = check_input(p)
    lo, hi = (ncols, ncols) if isinstance(ncols, int) else ncols
    stamps: list[int] = []
    rows: list[list[str]] = []
    try:
        with open(p, encoding="utf-8", errors=errors) as fh:
            for n, line in enumerate(fh, start=1):
                s = line.strip()
                if not s or s.startswith("#"):
                    continue
                parts = [x.strip() for x in s.split(sep)] if sep is not None else s.split()
                if not lo <= len(parts) <= hi or any(not parts[i] for i in required):
                    raise FormatError(p, f"expected {expected}", line=n)
                try:
                    t = parse(parts[stamp_col])
                except ValueError:
                    msg = f"expected {expected}" if bad_stamp is None else \
                        f"timestamp {parts[stamp_col]!r} {bad_stamp}"
                    raise FormatError(p, msg, line=n) from None
                if increasing and stamps and t <= stamps[-1]:
                    raise FormatError(p, f"timestamps must increase strictly: {t} ns follows "
                                      f"{stamps[-1]} ns; sort the file or remove duplicates "
                                      "(frames must be in increasing time)", line=n)
                stamps.append(t)
                rows.append(parts)
    except UnicodeDecodeError:
        raise FormatError(p, "not UTF-8 text; save the file as UTF-8") from None
    if nonempty is not None and not stamps:
        raise FormatError(p, nonempty)
    return np.asarray(stamps, dtype=np.int64), rows


def write_stamped_list(path: str | os.PathLike[str], header: str, stamps: Iterable[object],
                       names: Iterable[str], *, sep: str = ",", end: str = "\n") -> None:
    """Write ``header`` (its lines, newline-terminated) then ``<stamp><sep><name><end>`` rows,
    atomically; ``stamps`` are written with ``str`` (int64 ns or exact decimal text)."""
    with atomic_write(path) as f:
        f.write(header)
        f.writelines(f"{t}{sep}{n}{end}" for t, n in zip(stamps, names, strict=True))
