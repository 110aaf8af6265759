"""EuRoC / ASL ``data.csv`` trajectories (Burri et al., IJRR 2016), also BASALT's
``trajectory.csv``.

Columns: ``#timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z`` followed by any number of extra
columns (EuRoC's velocity and bias columns), which are ignored.  Timestamps are nanoseconds,
written as integers by EuRoC and in scientific notation by BASALT (``1.403715273262143e+18``);
both are parsed exactly from their decimal text.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from ibiscape_eval.core.errors import IbiscapeWarning
from ibiscape_eval.core.trajectory import Trajectory

from ._poses import finish_trajectory
from ._text import decimal_to_ns, format_lines, parse_table, read_bytes, write_table
from .atomic import atomic_write

__all__ = ["EUROC_HEADER", "read_euroc", "write_euroc"]

EUROC_HEADER = ("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],"
                "q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []")

_EXPECTED = "at least 8 columns (timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z, ...)"


def read_euroc(path: str | os.PathLike[str], *, name: str | None = None) -> Trajectory:
    """Read an EuRoC/ASL ``data.csv`` (or BASALT ``trajectory.csv``) trajectory.

    Parameters
    ----------
    path
        Comma separated file, ``#`` header; stamps in ns; positions in m; quaternion w first.
    name
        Label; the file name by default.

    Raises
    ------
    FormatError
        Fewer than 8 columns, non-numeric fields in the first 8, non-unit quaternions,
        decreasing timestamps, empty/binary file; the message names the file and line.
    """
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=8, ncols_min=8, ncols_max=10_000, expected=_EXPECTED)
    _note_ragged_rows(path, data, tb.lines)
    del data  # the raw bytes are no longer needed: lower peak memory
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    quat_xyzw = tb.values[:, [5, 6, 7, 4]]
    return finish_trajectory(path, stamps, tb.values[:, 1:4], quat_xyzw, tb.finite, tb.lines,
                             Path(path).name if name is None else name)


_RAGGED_EXACT_BYTES = 64 << 20  # per-line column counts up to this size (EuRoC GT: ~3 MB)


def _note_ragged_rows(path: str | os.PathLike[str], data: bytes, lines: np.ndarray) -> None:
    """Warn when data rows have different numbers of columns (a 17-column ground truth with a
    16- or 18-column row): only the first 8 are read, but the file is damaged."""
    buf = np.frombuffer(data, dtype=np.uint8)
    row_lines = np.asarray(lines, dtype=np.int64)
    if buf.size > _RAGGED_EXACT_BYTES and row_lines.size:
        # Large files: one counting pass; every data row must have the first row's count
        # (a 16- and an 18-column row would cancel out: checked exactly below this size only).
        head = np.flatnonzero(buf[: 1 << 20] == 10)
        if row_lines[0] - 1 < head.size:
            start = 0 if row_lines[0] == 1 else int(head[row_lines[0] - 2]) + 1
            c0 = int(np.count_nonzero(buf[start : int(head[row_lines[0] - 1])] == 44))
            if int(np.count_nonzero(buf[start:] == 44)) == c0 * row_lines.size:
                return
    ends = np.flatnonzero(buf == 10)
    if ends.size == 0 or ends[-1] != buf.size - 1:
        ends = np.append(ends, buf.size)
    per_line = np.diff(np.searchsorted(np.flatnonzero(buf == 44), ends), prepend=0)
    row_lines = row_lines[row_lines <= per_line.size]
    cols = per_line[row_lines - 1] + 1
    if cols.size == 0 or (cols == cols[0]).all():
        return
    usual = int(np.bincount(cols).argmax())
    odd = np.flatnonzero(cols != usual)
    warnings.warn(
        f"{path}: {odd.size} row{'s' * (odd.size != 1)} with another column count than the "
        f"usual {usual} (e.g. {int(cols[odd[0]])} at line {int(row_lines[odd[0]])}; lines "
        f"{format_lines(row_lines[odd])}); read the first 8 columns, check the file",
        IbiscapeWarning, stacklevel=3)


def write_euroc(path: str | os.PathLike[str], traj: Trajectory) -> None:
    """Write ``traj`` as an EuRoC ``data.csv`` (8 columns, integer ns, quaternion w first)."""
    q = traj.quat_xyzw
    values = np.concatenate((traj.pos_m, q[:, 3:4], q[:, :3]), axis=1)
    with atomic_write(path, "wb") as f:
        f.write((EUROC_HEADER + "\n").encode())
        write_table(f, traj.stamps_ns, values, stamp="ns", sep=",")
