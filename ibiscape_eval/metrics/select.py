"""Choosing the poses a metric uses: a time range, an even downsampling, a motion filter (evo's
``--t_start/--t_end``, ``--downsample`` and ``--motion_filter``)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, Trajectory
from ibiscape_eval.core.jit import lazy_njit
from ibiscape_eval.core.time import ns_from_s

__all__ = ["downsample", "motion_filter", "time_range"]


def _keep(traj: Trajectory, idx: npt.NDArray[np.intp]) -> Trajectory:
    if idx.shape[0] == len(traj):
        return traj
    return traj.take(idx)


def time_range(
    traj: Trajectory, t_start_s: float | None = None, t_end_s: float | None = None
) -> Trajectory:
    """The poses with ``t_start_s <= t <= t_end_s`` (seconds in the file's clock, like evo's
    ``reduce_to_time_range``; either bound may be None).

    Raises
    ------
    IbiscapeError
        Synthetic stamps (they are not times), ``t_start_s > t_end_s``, or no pose in the range
        (the message gives the trajectory's time span).
    """
    if t_start_s is None and t_end_s is None:
        return traj
    if traj.stamps_synthetic:
        raise IbiscapeError(
            f"{traj.describe('trajectory')} has no real timestamps (KITTI poses without a times "
            "file), so a time range cannot select its poses; give its times file"
        )
    if t_start_s is not None and t_end_s is not None and t_start_s > t_end_s:
        raise IbiscapeError(f"the time range starts after it ends ({t_start_s} > {t_end_s} s)")
    lo = np.iinfo(np.int64).min if t_start_s is None else int(ns_from_s(float(t_start_s)))
    hi = np.iinfo(np.int64).max if t_end_s is None else int(ns_from_s(float(t_end_s)))
    s = traj.stamps_ns
    i0, i1 = int(np.searchsorted(s, lo, side="left")), int(np.searchsorted(s, hi, side="right"))
    if i1 <= i0:
        span = f"{s[0] / 1e9:.9f} .. {s[-1] / 1e9:.9f} s" if len(s) else "no poses"
        raise IbiscapeError(
            f"no pose of the {traj.describe('trajectory')} lies in the time range "
            f"{t_start_s} .. {t_end_s} s (its stamps span {span}, absolute times like evo's)"
        )
    return _keep(traj, np.arange(i0, i1, dtype=np.intp))


def downsample(traj: Trajectory, n_poses: int) -> Trajectory:
    """At most ``n_poses`` poses, evenly spaced by index (evo's ``downsample``: rows
    ``linspace(0, N - 1, n_poses)`` truncated to integers); unchanged when it has fewer."""
    if int(n_poses) != n_poses or n_poses < 1:
        raise IbiscapeError(f"downsample needs a positive number of poses, got {n_poses!r}")
    n = len(traj)
    if n <= n_poses:
        return traj
    idx = np.linspace(0, n - 1, int(n_poses)).astype(np.intp)
    return _keep(traj, idx)


@lazy_njit(error_model="numpy")
def _motion_kernel(pos, quat, dist_m, angle_rad):  # pragma: no cover - compiled
    n = pos.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = True
    cum = 0.0
    last_cum = 0.0
    a = 0  # last kept pose (rotation reference)
    for i in range(1, n):
        d0 = pos[i, 0] - pos[i - 1, 0]
        d1 = pos[i, 1] - pos[i - 1, 1]
        d2 = pos[i, 2] - pos[i - 1, 2]
        cum += math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if cum - last_cum >= dist_m:
            keep[i] = True
            a = i
            last_cum = cum
            continue
        # angle of q_a^-1 q_i: |w| of the product is |<q_a, q_i>|
        dot = (quat[a, 0] * quat[i, 0] + quat[a, 1] * quat[i, 1] + quat[a, 2] * quat[i, 2]
               + quat[a, 3] * quat[i, 3])
        dot = min(abs(dot), 1.0)
        # 2 asin(|v|) is accurate for small angles where 2 acos(|w|) is not
        v = math.sqrt(max(0.0, 1.0 - dot * dot))
        ang = 2.0 * math.atan2(v, dot)
        if ang >= angle_rad:
            keep[i] = True
            a = i
            last_cum = cum
    return keep


def motion_filter(traj: Trajectory, distance_m: float, angle_deg: float) -> Trajectory:
    """The first pose and every pose after which the trajectory has moved at least
    ``distance_m`` along its path or turned at least ``angle_deg`` since the last kept pose
    (evo's ``motion_filter``, same rule and order: distance first, then angle).

    One compiled pass (the rule is sequential: each kept pose resets the reference).
    """
    d, a = float(distance_m), float(angle_deg)
    if not (math.isfinite(d) and math.isfinite(a)) or d < 0 or a < 0:
        raise IbiscapeError(
            f"motion filter thresholds must be >= 0, got {distance_m!r} m and {angle_deg!r} deg"
        )
    if len(traj) < 2:
        raise IbiscapeError(f"the motion filter needs at least 2 poses, "
                            f"{traj.describe('trajectory')} has {len(traj)}")
    keep = _motion_kernel(np.ascontiguousarray(traj.pos_m), np.ascontiguousarray(traj.quat_xyzw),
                          d, math.radians(a))
    return _keep(traj, np.flatnonzero(keep).astype(np.intp))
