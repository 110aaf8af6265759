"""Checks shared by every trajectory reader: NaN rows, quaternion norms, timestamp order.

Rules (the same for every format, so a user learns them once):

- rows with a NaN or inf value are skipped, with ONE :class:`IbiscapeWarning` naming the file
  and the line numbers;
- quaternions within 1e-3 of unit norm are renormalised silently, others (all-zero included)
  raise :class:`FormatError` naming the line;
- a timestamp smaller than its predecessor raises :class:`FormatError` naming the line;
- repeated timestamps warn with the line numbers and keep the first row of each run.
"""

from __future__ import annotations

import itertools
import os
import warnings

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeWarning
from ibiscape_eval.core.trajectory import Trajectory

from ._text import _kernels, _Pool, _workers, format_lines

__all__ = ["MAX_ABS_POSITION_M", "QUAT_NORM_TOL", "check_positions", "check_rows",
           "finish_trajectory"]

QUAT_NORM_TOL = 1e-3
#: Largest believable coordinate, m (a million km: ECEF and UTM coordinates fit with room to
#: spare).  Larger values are damaged data, and squared in the alignment they overflow to inf.
MAX_ABS_POSITION_M = 1.0e9
_FUSED_MIN_ROWS = 10_000  # from this size on the usual case is checked by one numba pass
_PARALLEL_ROWS = 200_000  # ... in parallel threads from this size on


def check_rows(
    path: str | os.PathLike[str],
    stamps_ns: npt.NDArray[np.int64],
    finite: npt.NDArray[np.bool_],
    lines: npt.NDArray[np.int64],
    *,
    where: str = "line",
    stacklevel: int = 4,
) -> npt.NDArray[np.intp]:
    """Indices of the rows to keep: finite, in order, first of each repeated timestamp.

    Warns about skipped non-finite rows and duplicates; raises on decreasing timestamps.
    """
    if finite.all():
        keep = np.arange(finite.size)
        st = stamps_ns
    else:
        keep = np.flatnonzero(finite)
        st = stamps_ns[keep]
    if keep.size < finite.size:
        bad = lines[~finite]
        warnings.warn(
            f"{path}: skipped {bad.size} row{'s' * (bad.size != 1)} with NaN/inf values at "
            f"{where}{'s' * (bad.size != 1)} {format_lines(bad)}",
            IbiscapeWarning, stacklevel=stacklevel,
        )
    if keep.size == 0:
        raise FormatError(path, "no valid rows: every row has NaN/inf values")
    d = np.diff(st)
    if (d < 0).any():
        i = int(np.flatnonzero(d < 0)[0])
        msg = (f"timestamp {st[i + 1]} ns is earlier than {st[i]} ns on {where} "
               f"{lines[keep[i]]}; timestamps must not decrease (sort the file)")
        if where == "line":
            raise FormatError(path, msg, line=int(lines[keep[i + 1]]))
        raise FormatError(path, f"{where} {lines[keep[i + 1]]}: {msg}")
    dup = np.flatnonzero(d == 0) + 1
    if dup.size:
        warnings.warn(
            f"{path}: {dup.size} duplicate timestamp{'s' * (dup.size != 1)} at "
            f"{where}{'s' * (dup.size != 1)} {format_lines(lines[keep[dup]])}; "
            "kept the first row of each",
            IbiscapeWarning, stacklevel=stacklevel,
        )
        mask = np.ones(keep.size, dtype=bool)
        mask[dup] = False
        keep = keep[mask]
    return keep


def check_positions(
    path: str | os.PathLike[str],
    pos: npt.NDArray[np.float64],
    lines: npt.NDArray[np.int64],
    *,
    where: str = "line",
) -> None:
    """Refuse a finite coordinate beyond :data:`MAX_ABS_POSITION_M` (NaN rows are left to
    :func:`check_rows`)."""
    if pos.size == 0:
        return
    with np.errstate(invalid="ignore"):
        if max(float(pos.max()), -float(pos.min())) <= MAX_ABS_POSITION_M:
            return  # the usual file: two reductions, no temporaries (NaN falls through)
        big = np.abs(pos) > MAX_ABS_POSITION_M
        big &= np.isfinite(pos)
    if big.any():
        i = int(np.flatnonzero(big.any(axis=1))[0])
        msg = (f"position {np.asarray(pos[i]).tolist()} is beyond {MAX_ABS_POSITION_M:g} m: "
               "damaged data or wrong units; fix or remove the row")
        if where == "line":
            raise FormatError(path, msg, line=int(lines[i]))
        raise FormatError(path, f"{where} {lines[i]}: {msg}")


def check_quaternions(
    path: str | os.PathLike[str],
    quat: npt.NDArray[np.float64],
    lines: npt.NDArray[np.int64],
    *,
    where: str = "line",
    canonical: bool = False,
) -> npt.NDArray[np.float64]:
    """Unit quaternions (any layout, one per row); raises for a norm further than 1e-3 from 1.

    With ``canonical`` the layout must be x, y, z, w and the sign is chosen so that w >= 0 (the
    :class:`Trajectory` convention), in the same single division.
    """
    norms = np.sqrt(np.einsum("ij,ij->i", quat, quat))
    bad = np.abs(norms - 1.0) > QUAT_NORM_TOL
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        msg = (f"quaternion norm is {norms[i]:.6g}, expected a unit quaternion (within "
               f"{QUAT_NORM_TOL:g}); check the column order")
        if where == "line":
            raise FormatError(path, msg, line=int(lines[i]))
        raise FormatError(path, f"{where} {lines[i]}: {msg}")
    if canonical:
        np.negative(norms, out=norms, where=quat[:, 3] < 0.0)
    return quat / norms[:, None]


def _all_finite(a: npt.NDArray[np.float64]) -> bool:
    """Whether every value is finite; a finite sum (one pass, no temporary) proves it."""
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(a.sum()):
            return True
    return bool(np.isfinite(a).all())


def _checked_trajectory(
    stamps_ns: npt.NDArray[np.int64],
    pos_m: npt.NDArray[np.float64],
    quat_xyzw: npt.NDArray[np.float64],
    name: str,
) -> Trajectory:
    """A :class:`Trajectory` from arrays ``pose_rows`` has just checked (finite, strictly
    increasing int64 stamps, unit quaternions with w >= 0, contiguous): the constructor's own
    checks would repeat four full passes over a million-pose file for nothing."""
    traj = object.__new__(Trajectory)
    for field, arr, dtype in (("stamps_ns", stamps_ns, np.int64), ("pos_m", pos_m, np.float64),
                              ("quat_xyzw", quat_xyzw, np.float64)):
        object.__setattr__(traj, field, _read_only(np.ascontiguousarray(arr, dtype=dtype)))
    object.__setattr__(traj, "name", name)
    return traj


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of an array this module made: the :class:`Trajectory` keeps it as is."""
    v = a.view()
    v.flags.writeable = False
    return v


def finish_trajectory(
    path: str | os.PathLike[str],
    stamps_ns: npt.NDArray[np.int64],
    pos_m: npt.NDArray[np.float64],
    quat_xyzw: npt.NDArray[np.float64],
    finite: npt.NDArray[np.bool_],
    lines: npt.NDArray[np.int64],
    name: str,
    *,
    where: str = "line",
    owned: bool = False,
) -> Trajectory:
    """Apply the shared rules and build the :class:`Trajectory`.

    ``owned``: ``pos_m`` and ``quat_xyzw`` are contiguous arrays the caller made for this call
    alone; they are normalised in place and adopted instead of copied.
    """
    n = stamps_ns.size
    check_positions(path, pos_m, lines, where=where)
    if n > _FUSED_MIN_ROWS:
        if owned and pos_m.flags.c_contiguous and quat_xyzw.flags.c_contiguous:
            pos, quat = pos_m, quat_xyzw
        else:
            pos, quat = np.empty((n, 3)), np.empty((n, 4))
        threads = _workers() if n >= _PARALLEL_ROWS else 1
        cuts = [n * k // threads for k in range(threads + 1)]
        with _Pool(threads) as pool:
            parts = pool.map(_kernels().pose_rows, [
                (stamps_ns, pos_m, quat_xyzw, finite, QUAT_NORM_TOL, a, b, pos, quat)
                for a, b in itertools.pairwise(cuts)])
        if all(p[0] and p[1] and p[2] < 0 for p in parts):
            # The usual file, checked in one pass: every row kept, nothing to report.
            return _checked_trajectory(stamps_ns, pos, quat, name)
        # Otherwise the checks below give the warning or the error (the rows they quote were
        # left untouched; the others may have been normalised already, which is harmless).
        del pos, quat
    if not (finite.all() and _all_finite(pos_m) and _all_finite(quat_xyzw)):
        finite = finite & np.isfinite(pos_m).all(axis=1) & np.isfinite(quat_xyzw).all(axis=1)
    keep = check_rows(path, stamps_ns, finite, lines, where=where, stacklevel=5)
    if keep.size == stamps_ns.size:  # the usual case: no copies of the whole table
        quat = check_quaternions(path, quat_xyzw, lines, where=where, canonical=True)
        pos = pos_m if pos_m.flags.c_contiguous else np.ascontiguousarray(pos_m)
    else:
        quat = check_quaternions(path, quat_xyzw[keep], lines[keep], where=where, canonical=True)
        stamps_ns, pos = stamps_ns[keep], pos_m[keep]
    # Read-only arrays are taken over by the Trajectory without another copy; the quaternions
    # are already unit with w >= 0, so it does not normalise them again.
    return Trajectory(_read_only(stamps_ns), _read_only(pos), _read_only(quat), name)
