"""Building trajectories from already validated data without re-validating them."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import Trajectory

__all__ = ["take", "trusted"]


def trusted(
    stamps_ns: npt.ArrayLike, pos_m: npt.ArrayLike, quat_xyzw: npt.ArrayLike, name: str = ""
) -> Trajectory:
    """A :class:`Trajectory` built from arrays derived from already validated trajectories.

    Skips the constructor's checks (ordering, finiteness, unit norms), which cost several full
    passes over the data on million-pose inputs; only for rows selected, shifted, interpolated
    or rigidly transformed from validated poses.  Arrays are made read-only like the
    constructor does.
    """
    traj = object.__new__(Trajectory)
    for field, value, dtype in (("stamps_ns", stamps_ns, np.int64), ("pos_m", pos_m, np.float64),
                                ("quat_xyzw", quat_xyzw, np.float64)):
        arr = np.ascontiguousarray(value, dtype=dtype)
        if arr.flags.writeable:
            arr = arr.view()
            arr.flags.writeable = False
        object.__setattr__(traj, field, arr)
    object.__setattr__(traj, "name", name)
    return traj


def take(traj: Trajectory, index: npt.ArrayLike) -> Trajectory:
    """Rows of ``traj`` (index array), without re-validation."""
    idx = np.asarray(index)
    if idx.dtype.kind in "iu" and idx.ndim == 1 and idx.shape[0] > 0:
        lo, hi = int(idx[0]), int(idx[-1])
        if hi - lo + 1 == idx.shape[0] and bool(np.all(np.diff(idx) == 1)):
            # A contiguous run (everything matched): views instead of copies.
            s = slice(lo, hi + 1)
            return trusted(traj.stamps_ns[s], traj.pos_m[s], traj.quat_xyzw[s], traj.name)
    return trusted(traj.stamps_ns[idx], traj.pos_m[idx], traj.quat_xyzw[idx], traj.name)
