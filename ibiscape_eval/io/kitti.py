"""KITTI odometry poses: 12 numbers per line, the row-major 3x4 matrix ``[R | t]`` of
``T_world_body`` (Geiger et al., CVPR 2012), with an optional times file (seconds, one per line).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.rotations import quat_from_matrix
from ibiscape_eval.core.trajectory import SYNTHETIC_PERIOD_NS, Trajectory

from ._poses import check_positions, check_rows
from ._text import decimal_to_ns, parse_table, read_bytes, write_table
from .atomic import atomic_write

__all__ = ["KITTI_PERIOD_NS", "ORTHO_TOL", "read_kitti", "read_times", "write_kitti"]

#: Stamps given to poses without a times file: KITTI's nominal 10 Hz.
KITTI_PERIOD_NS = SYNTHETIC_PERIOD_NS
#: Largest deviation of a singular value of the rotation block from 1 that is repaired.
ORTHO_TOL = 1e-3


def read_times(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Exact int64 ns stamps and their line numbers from a KITTI times file (seconds, one per
    line, ``#`` comments allowed)."""
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=1, ncols_min=1, ncols_max=1,
                     expected="1 column (time in seconds)")
    del data  # the raw bytes are no longer needed: lower peak memory
    if not tb.finite.all():
        i = int(np.flatnonzero(~tb.finite)[0])
        raise FormatError(path, "time is NaN/inf", line=int(tb.lines[i]))
    return decimal_to_ns(path, tb, unit_exp=9), tb.lines


def read_kitti(
    path: str | os.PathLike[str], *, times_path: str | os.PathLike[str] | None = None,
    name: str | None = None,
) -> Trajectory:
    """Read KITTI poses.

    Parameters
    ----------
    path
        Text file with 12 numbers per line: ``r00 r01 r02 tx r10 r11 r12 ty r20 r21 r22 tz``.
    times_path
        Optional times file (seconds, one per line, as many lines as poses).  Without it the
        stamps are the pose index at KITTI's nominal 10 Hz, ``i * 100_000_000`` ns, and the
        trajectory is marked ``stamps_synthetic`` (results and plots then use pose indices);
        the command line pairs such trajectories by index.
    name
        Label; the file name by default.

    Raises
    ------
    FormatError
        Wrong column count, non-numeric field, a rotation block further than 1e-3 from
        orthonormal (or a reflection), a times file of another length.

    Notes
    -----
    Rotation blocks within 1e-3 of orthonormal (largest singular-value deviation) are
    re-orthonormalised by SVD, ``R <- U V^T`` (the nearest rotation in Frobenius norm).
    Rows with NaN/inf are skipped with a warning; their index still counts for the 10 Hz stamps.
    """
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=12, ncols_min=12, ncols_max=12,
                     expected="12 columns (row-major 3x4 [R|t])")
    n = tb.values.shape[0]
    if times_path is not None:
        stamps, tlines = read_times(times_path)
        if stamps.size != n:
            raise FormatError(times_path, f"has {stamps.size} times but {path} has {n} poses; "
                                          "they must match line by line")
        d = np.diff(stamps)
        if (d < 0).any():
            i = int(np.flatnonzero(d < 0)[0]) + 1
            raise FormatError(times_path, "time is earlier than the previous one; times must "
                                          "not decrease", line=int(tlines[i]))
    else:
        stamps = np.arange(n, dtype=np.int64) * KITTI_PERIOD_NS
    keep = check_rows(path, stamps, tb.finite, tb.lines)
    M = tb.values[keep].reshape(-1, 3, 4)
    check_positions(path, M[:, :, 3], tb.lines[keep])
    R = M[:, :, :3]
    U, S, Vt = np.linalg.svd(R)
    det = np.linalg.det(R)
    bad = (np.abs(S - 1.0).max(axis=1) > ORTHO_TOL) | (det <= 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise FormatError(
            path, f"rotation block is not a rotation (singular values {np.round(S[i], 6)}, "
            f"det {det[i]:.6g}); expected an orthonormal 3x3 matrix within {ORTHO_TOL:g}",
            line=int(tb.lines[keep[i]]))
    R_fixed = U @ Vt
    return Trajectory(stamps[keep], M[:, :, 3].copy(), quat_from_matrix(R_fixed),
                      Path(path).name if name is None else name,
                      stamps_synthetic=times_path is None)


def write_kitti(
    path: str | os.PathLike[str], traj: Trajectory, *,
    times_path: str | os.PathLike[str] | None = None,
) -> None:
    """Write ``traj`` as KITTI poses (12 numbers per line) and, if ``times_path`` is given, its
    stamps in seconds (``%d.%09d``, exact) to that file.  Both are written atomically."""
    T = traj.matrices()[:, :3, :].reshape(-1, 12)
    if times_path is not None:
        with atomic_write(times_path, "wb") as f:
            write_table(f, traj.stamps_ns, np.empty((len(traj), 0)), stamp="s", sep=" ")
    with atomic_write(path, "wb") as f:
        write_table(f, None, T, stamp="none", sep=" ")
