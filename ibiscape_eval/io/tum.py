"""TUM RGB-D trajectories: ``t x y z qx qy qz qw`` per line (Sturm et al., IROS 2012).

Also reads the outputs of ORB-SLAM3 (``SaveTrajectoryTUM`` in seconds and its EuRoC-named output:
TUM column order with the time in nanoseconds as fixed point, ``1403715273262142976.000000``) and
BASALT's ``trajectory.txt``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ibiscape_eval.core.trajectory import Trajectory

from ._poses import finish_trajectory
from ._text import decimal_to_ns, map_bytes, parse_table, write_table
from .atomic import atomic_write

__all__ = ["NS_STAMP_THRESHOLD", "read_tum", "write_tum"]

#: A first timestamp whose magnitude exceeds this is taken to be in nanoseconds, not seconds
#: (1e14 s is three million years; 1e14 ns is one day after the epoch).
NS_STAMP_THRESHOLD = 1e14

_EXPECTED = "8 columns (t x y z qx qy qz qw)"


def read_tum(path: str | os.PathLike[str], *, name: str | None = None) -> Trajectory:
    """Read a TUM trajectory file.

    Parameters
    ----------
    path
        Text file, one pose per line: ``t x y z qx qy qz qw`` (t in seconds, position in metres,
        Hamilton quaternion x, y, z, w).  Separators may be any mix of spaces, tabs and commas;
        ``#`` starts a comment (whole line or trailing); blank lines are ignored.
    name
        Label of the trajectory; the file name by default.

    Returns
    -------
    Trajectory
        Stamps are exact int64 ns parsed from the decimal text of the first column.  If the first
        stamp's magnitude exceeds 1e14 the column is taken to be in **nanoseconds** already
        (ORB-SLAM3's EuRoC-named output, ``1403715273262142976.000000``), otherwise in seconds.

    Raises
    ------
    FormatError
        Rows without exactly 8 columns, non-numeric fields, non-unit quaternions, decreasing
        timestamps, empty or binary files; the message names the file and line.

    Notes
    -----
    Rows with NaN/inf are skipped with one :class:`~ibiscape_eval.core.IbiscapeWarning`;
    repeated timestamps keep the first row, also with a warning.
    """
    data = map_bytes(path)
    tb = parse_table(path, data, nkeep=8, ncols_min=8, ncols_max=8, expected=_EXPECTED,
                     widths=(1, 3, 4))
    del data  # the raw bytes are no longer needed (unmaps the file): lower peak memory
    t_col, pos, quat = tb.groups  # contiguous (N, 1), (N, 3), (N, 4), adopted without a copy
    first = t_col[:1, 0]
    if not np.isfinite(first).all():
        first = t_col[np.flatnonzero(np.isfinite(t_col[:, 0]))[:1], 0]
    unit_exp = 0 if first.size and abs(first[0]) > NS_STAMP_THRESHOLD else 9
    stamps = decimal_to_ns(path, tb, unit_exp=unit_exp)
    return finish_trajectory(
        path, stamps, pos, quat, tb.finite, tb.lines,
        Path(path).name if name is None else name, owned=True,
    )


def write_tum(path: str | os.PathLike[str], traj: Trajectory) -> None:
    """Write ``traj`` as a TUM file (atomically): a ``#`` header line, then
    ``t x y z qx qy qz qw`` with t in seconds written exactly as ``%d.%09d`` from the int ns."""
    values = np.concatenate((traj.pos_m, traj.quat_xyzw), axis=1)
    with atomic_write(path, "wb") as f:
        f.write(b"# timestamp tx ty tz qx qy qz qw\n")
        write_table(f, traj.stamps_ns, values, stamp="s", sep=" ")
