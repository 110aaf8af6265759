"""EuRoC/IBISCape IMU csv files (and generic CSV with a column mapping): reading and writing."""

from __future__ import annotations

import dataclasses
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.imu import CHUNK_ROWS, ImuRecord

from .._text import write_table
from ..atomic import atomic_write
from .columns import (
    STAMP_UNITS,
    ImuLayout,
    check_rate,
    override_units,
    resolve_layout,
    stamp_unit,
    with_layout,
)
from .frames import check_imu_frame, mirror_ibiscape_imu
from .npy import NpyRows, NpyStreamWriter
from .timing import (
    TimingAccumulator,
    check_samples,
    check_stamp_dtype,
    finish_record,
    no_stamp_timing,
)

__all__ = ["IMU_CSV_HEADER", "read_imu_csv", "resolve_columns", "write_imu_csv",
           "write_imu_csv_chunks"]

#: The one header line of every IMU csv the project writes (EuRoC's, gyro first).
IMU_CSV_HEADER = ("#timestamp [ns],w_x [rad s^-1],w_y [rad s^-1],w_z [rad s^-1],"
                  "a_x [m s^-2],a_y [m s^-2],a_z [m s^-2]")


def _header_lines(p: Path) -> tuple[int, list[str] | None]:
    """Count leading lines that are not numeric rows; return the last one split as names."""
    names = None
    n = 0
    with open(p, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            s = line.strip()
            if not s:
                n += 1
                continue
            first = s.split(",")[0].strip()
            try:
                float(first)
                break
            except ValueError:
                names = [c.strip().lstrip("#").strip() for c in s.split(",")]
                n += 1
            if n > 50:
                break
    return n, names


def _diagnose(p: Path, start_line: int, n_fields: int, used: list[int] | None = None) -> FormatError:
    """Find the first bad line at or after ``start_line`` (1-based) of a CSV; only the ``used``
    columns (default: all) must be numbers."""
    cols = set(range(n_fields) if used is None else used)
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh, start=1):
            if i < start_line or not line.strip():
                continue
            parts = line.rstrip("\r\n").split(",")
            if parts and not parts[-1].strip() and len(parts) == n_fields + 1:
                parts = parts[:-1]  # trailing comma
            if len(parts) != n_fields:
                return FormatError(p, f"expected {n_fields} comma-separated columns, got "
                                   f"{len(parts)}; fix or delete this row", line=i)
            for j, v in enumerate(parts):
                if j not in cols:
                    continue
                try:
                    x = float(v)
                except ValueError:
                    return FormatError(p, f"column {j + 1} is not a number ({v.strip()[:30]!r}); "
                                       "fix or delete this row", line=i)
                if not math.isfinite(x):
                    return FormatError(p, f"column {j + 1} is not finite ({v.strip()[:30]!r})", line=i)
                if abs(x) >= 2.0**63:
                    return FormatError(p, f"column {j + 1} is too large ({v.strip()[:30]!r}); "
                                       "fix or delete this row", line=i)
    return FormatError(p, "unreadable CSV row; check the delimiter (comma expected)", line=start_line)


def resolve_columns(cols: Mapping[str, str | int], names: list[str] | None, n_fields: int,
                    p: Path) -> ImuLayout:
    """The :class:`ImuLayout` of a table (``--columns``, else header names, else EuRoC order)."""
    return resolve_layout(p, cols, names, n_fields)


def _all_numbers(row: str, n_fields: int) -> bool:
    parts = row.rstrip("\r\n").rstrip().rstrip(",").split(",")
    try:
        [float(v) for v in parts[:n_fields]]
    except ValueError:
        return False
    return True


def _first_stamps(p: Path, skip: int, t_col: int, rows: int = 4000) -> np.ndarray:
    """The first ``rows`` values of the time column as float64 (for the unit decision)."""
    import pandas as pd

    try:
        df = pd.read_csv(p, header=None, skiprows=skip, usecols=[t_col], nrows=rows,
                         dtype=np.float64, engine="c", skip_blank_lines=True)
    except (ValueError, OverflowError, pd.errors.ParserError, UnicodeDecodeError):
        return np.zeros(0)
    return df.to_numpy(dtype=np.float64).ravel()


def _time_unit(p: Path, layout: ImuLayout, first: np.ndarray) -> ImuLayout:
    """Fill in (or check) the stamp unit from the first stamps."""
    d = np.diff(first[np.isfinite(first)])
    med = float(np.median(d[d > 0])) if np.any(d > 0) else math.nan
    if layout.time_unit is not None:
        check_rate(p, layout.time_unit, med, layout.time_unit_from or "stated")
        return layout
    unit, how = stamp_unit(first)
    notes = layout.notes
    if unit != "ns":
        notes = (*notes, f"timestamps read as {unit} ({how})")
    return dataclasses.replace(layout, time_unit=unit, time_unit_from=how, notes=notes)


_DECIMAL = re.compile(r"\d+\.\d*")


def _decimal_ns(col: Any, f: int) -> np.ndarray:
    """Decimal text ``"1403636579.758555392"`` in a unit of ``f`` ns to exact int64 ns."""
    parts = col.astype(str).str.strip().str.split(".", n=1, expand=True)
    if parts.shape[1] == 1:
        parts[1] = "0"
    digits = len(str(f)) - 1
    whole = parts[0].astype(np.int64).to_numpy()
    frac = parts[1].fillna("0").str.ljust(digits, "0").str.slice(0, digits).replace("", "0")
    return whole * np.int64(f) + frac.astype(np.int64).to_numpy()


def _stamps_ns(col: Any, unit: str) -> np.ndarray:
    """A parsed time column (int64, float64 or decimal text) to int64 ns."""
    f = STAMP_UNITS[unit]
    a = np.asarray(col)
    if a.dtype.kind == "O":
        return _decimal_ns(col, f)
    if a.dtype.kind in "iu":
        return a.astype(np.int64) * np.int64(f)
    return np.round(a.astype(np.float64) * f)


def _first_row(p: Path, skip: int) -> str:
    """The first data line (after ``skip`` header lines)."""
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh):
            if i == skip:
                return line
    raise FormatError(p, "no data rows; an Allan deviation needs thousands of samples")


def _column_dtypes(first_row: str, t_col: int | None, first_t: np.ndarray,
                   read_cols: list[int]) -> tuple[dict[int, Any], bool]:
    """pandas dtypes of the read columns, and whether the stamps are decimal text."""
    # integer stamps are parsed exactly (float64 would round 1.4e18 ns to 256 ns)
    fields = first_row.split(",")
    t_text = fields[t_col].strip() if t_col is not None else ""
    # (only when the first thousands are all whole: "%g" writes 0, 0.005, ...)
    int_time = (t_col is not None and t_text.isdigit()
                and bool(np.all(first_t == np.round(first_t))))
    # decimal stamps (seconds with 9 decimals) are parsed exactly from their text
    dec_time = t_col is not None and _DECIMAL.fullmatch(t_text) is not None
    dtypes: dict[int, Any] = {i: np.float64 for i in read_cols}
    if int_time:
        dtypes[t_col] = np.int64  # type: ignore[index]
    elif dec_time:
        dtypes[t_col] = str  # type: ignore[index]
    return dtypes, dec_time


def _chunk_arrays(chunk: Any, t_pos: int | None, unit: str,
                  dec_time: bool) -> tuple[np.ndarray | None, np.ndarray]:
    """Stamps (ns) and the float64 table of one pandas chunk (decimal stamp text replaced by 0
    in the table); raises ValueError/TypeError on unparsable values."""
    tcol = None if t_pos is None else _stamps_ns(chunk.iloc[:, t_pos], unit)
    if dec_time:
        chunk = chunk.drop(columns=chunk.columns[t_pos])
        chunk.insert(t_pos, "t", 0.0)
    return tcol, chunk.to_numpy(dtype=np.float64)


def _layout(p: Path, cols: Mapping[str, str | int], names: list[str] | None, n_fields: int,
            skip: int, units: tuple[float, float] | None) -> tuple[ImuLayout, np.ndarray]:
    """The column layout (with the stated units and the stamp unit) and the first stamps."""
    if names is not None and len(names) != n_fields:
        names = None if len(names) < 7 and n_fields >= 7 else names
    layout = resolve_columns(cols, names, n_fields, p)
    if units is not None:
        layout = override_units(layout, units)
    first_t = np.zeros(0)
    if layout.time_column is not None:
        first_t = _first_stamps(p, skip, layout.time_column)
        layout = _time_unit(p, layout, first_t)
    return layout, first_t


def _spill_writer(
    p: Path, spill_bytes: int
) -> tuple[tempfile.TemporaryDirectory[str] | None, NpyStreamWriter | None]:
    """A temporary ``.npy`` writer (and its folder) for files larger than ``spill_bytes``."""
    if p.stat().st_size <= spill_bytes:
        return None, None
    keep = tempfile.TemporaryDirectory(prefix="ibiscape-imu-")
    return keep, NpyStreamWriter(os.path.join(keep.name, "imu.npy"), 6)


def read_imu_csv(p: Path, cols: Mapping[str, str | int], spill_bytes: int,
                 rate_hz: float | None, *, signs: np.ndarray | None = None,
                 units: tuple[float, float] | None = None) -> ImuRecord:
    """Read an IMU table; ``record.layout`` (see :func:`ibiscape_eval.io.imu.read_imu`) says how
    the columns were mapped."""
    import pandas as pd

    skip, names = _header_lines(p)
    first_row = _first_row(p, skip)
    n_fields = len(first_row.rstrip("\r\n").rstrip().rstrip(",").split(","))
    layout, first_t = _layout(p, cols, names, n_fields, skip, units)
    t_col = layout.time_column
    axis_cols = list(layout.axis_columns)
    unit = layout.time_unit or "ns"
    used = sorted(set(layout.used_columns))
    # a file of numbers only is read whole (pandas checks every row's field count); a file with
    # text columns (rostopic's frame_id) is read through the used columns only
    read_cols = list(range(n_fields)) if _all_numbers(first_row, n_fields) else used
    pos = {c: i for i, c in enumerate(read_cols)}
    u_pos = [pos[c] for c in used]
    a_pos = [pos[c] for c in axis_cols]
    timing_acc = None if t_col is None else TimingAccumulator(str(p), first_line=skip + 1)
    keep, writer = _spill_writer(p, spill_bytes)
    parts: list[np.ndarray] = []
    n = 0
    scale = np.array([layout.gyro_scale] * 3 + [layout.accel_scale] * 3)
    if signs is not None:
        scale = scale * signs
    try:
        dtypes, dec_time = _column_dtypes(first_row, t_col, first_t, read_cols)
        reader = pd.read_csv(p, header=None, skiprows=skip,
                             usecols=None if len(read_cols) == n_fields else read_cols,
                             dtype=dtypes, engine="c", chunksize=CHUNK_ROWS, skip_blank_lines=True)
        while True:
            try:
                chunk = next(reader)
            except StopIteration:
                break
            except (ValueError, OverflowError, pd.errors.ParserError, UnicodeDecodeError):
                raise _diagnose(p, skip + 1 + n, n_fields, used) from None
            if chunk.shape[1] != len(read_cols):
                raise _diagnose(p, skip + 1 + n, n_fields, used)
            try:
                tcol, arr = _chunk_arrays(chunk, None if t_col is None else pos[t_col], unit,
                                          dec_time)
            except (ValueError, TypeError):
                raise _diagnose(p, skip + 1 + n, n_fields, used) from None
            if not np.isfinite(arr[:, u_pos]).all():
                raise _diagnose(p, skip + 1 + n, n_fields, used)
            data = arr[:, a_pos]
            check_samples(p, data, skip + 1 + n)
            if timing_acc is not None and tcol is not None:
                if tcol.dtype.kind == "f":
                    check_stamp_dtype(p, tcol)
                timing_acc.add(tcol)
            if np.any(scale != 1.0):
                data = data * scale
            if writer is not None:
                writer.write(data)
            else:
                parts.append(np.ascontiguousarray(data))
            n += arr.shape[0]
    except BaseException:
        if writer is not None:
            writer.close()
        if keep is not None:
            keep.cleanup()
        raise
    timing = timing_acc.result() if timing_acc is not None else no_stamp_timing(str(p), rate_hz, "the CSV")
    if writer is not None:
        writer.close()
        assert keep is not None
        return with_layout(finish_record(str(p), None, n, timing, rate_hz,
                                         _source=NpyRows(writer.path, keep=keep)), layout)
    samples = np.concatenate(parts, axis=0) if parts else np.zeros((0, 6))
    return with_layout(finish_record(str(p), samples, n, timing, rate_hz), layout)


def write_imu_csv(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike, gyro_rad_s: npt.ArrayLike,
                  accel_m_s2: npt.ArrayLike, *, frame: str = "right-handed") -> None:
    """Write the EuRoC/IBISCape IMU csv (gyro first), atomically: :func:`write_imu_csv_chunks`
    with one chunk.

    Parameters
    ----------
    stamps_ns : ndarray of int64, shape (N,)
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        Samples in OUR right-handed frame, rad/s and m/s^2.
    frame : {"right-handed", "ibiscape"}
        ``"ibiscape"`` writes CARLA's left-handed frame like the real dataset (``w_x, w_z, a_y``
        negated; :func:`read_imu` with ``fmt="ibiscape"`` converts back).
    """
    t = np.asarray(stamps_ns, dtype=np.int64)
    g = np.asarray(gyro_rad_s, dtype=np.float64)
    a = np.asarray(accel_m_s2, dtype=np.float64)
    if t.ndim != 1 or g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise IbiscapeError(f"expected (N,) stamps and (N, 3) gyro/accel, got {t.shape}, {g.shape}, {a.shape}")
    write_imu_csv_chunks(path, [(t, g, a)], frame=frame)


def write_imu_csv_chunks(path: str | os.PathLike[str],
                         chunks: Iterable[tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]], *,
                         frame: str = "right-handed") -> int:
    """Stream ``(stamps_ns, gyro_rad_s (n, 3), accel_m_s2 (n, 3))`` chunks into one IMU csv
    (IBISCape/EuRoC layout, gyro first, 15 significant digits, rows ending in a space),
    atomically.  Returns the rows.

    The chunks hold OUR right-handed frame.  ``frame="ibiscape"`` writes CARLA's left-handed
    frame like the real dataset (``w_x, w_z, a_y`` negated, see :mod:`ibiscape_eval.io.imu`);
    ``read_imu`` converts back (by itself inside a sequence folder).
    """
    mirror = check_imu_frame(frame)
    rows = 0
    with atomic_write(path, "wb") as f:
        f.write((IMU_CSV_HEADER + "\n").encode())
        for st, g, a in chunks:
            if mirror:
                g, a = mirror_ibiscape_imu(g, a)
            vals = np.concatenate((np.asarray(g, dtype=np.float64), np.asarray(a, dtype=np.float64)),
                                  axis=1)
            write_table(f, np.asarray(st, dtype=np.int64), vals, stamp="ns", sep=",", row_end=" \n")
            rows += vals.shape[0]
    return rows
