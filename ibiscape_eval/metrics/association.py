"""Pairing the poses of an estimate with those of a reference, by time or by index."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, Trajectory
from ibiscape_eval.core.errors import Remedy
from ibiscape_eval.core.rotations import quat_slerp

from ._fast import nearest, take, trusted

__all__ = ["MIN_MATCHES", "Matched", "associate", "associate_by_index", "choose_match"]

#: Fewest matched poses any metric accepts.
MIN_MATCHES = 3


def choose_match(est_timed: bool, ref_timed: bool) -> str:
    """The ``match`` mode of the metrics for two trajectories: ``"time"`` when both carry real
    timestamps, else ``"index"`` (e.g. KITTI poses without a times file, which
    :func:`ibiscape_eval.io.read_trajectory` stamps by index; see
    :func:`ibiscape_eval.io.has_timestamps`)."""
    return "time" if est_timed and ref_timed else "index"

_HINT = (Remedy("max_diff_s"), Remedy("offset_s"), Remedy("estimate_offset", flag=True))
_HINT_TEXT = "try a larger {0}, an {1} or {2}"


@dataclass(frozen=True)
class Matched:
    """Two trajectories paired row by row: row ``i`` of ``est`` belongs to row ``i`` of ``ref``.

    Attributes
    ----------
    est, ref : Trajectory
        The paired poses, same length.  ``est`` stamps are in the reference clock
        (``t_ref = t_est + t_offset_s``); with ``interpolated`` the denser trajectory was
        resampled at the stamps of the sparser one, so both carry the same stamps.
    n_dropped_est, n_dropped_ref : int
        Poses of the original estimate / reference that have no partner.
    t_offset_s : float
        Constant offset added to the estimate's stamps before matching, seconds.
    interpolated : bool
        True when poses were interpolated (lerp of positions, slerp of orientations).
    by_index : bool
        True when rows were paired by position in the file (KITTI style), not by time.
    """

    est: Trajectory
    ref: Trajectory
    n_dropped_est: int
    n_dropped_ref: int
    t_offset_s: float
    interpolated: bool
    by_index: bool

    @property
    def n_matched(self) -> int:
        """Number of pose pairs."""
        return len(self.ref)


def _ns(seconds: float, what: str) -> int:
    if not math.isfinite(seconds):
        raise IbiscapeError(f"{what} must be a finite number of seconds, got {seconds!r}")
    return round(seconds * 1e9)


def _span(stamps_ns: npt.NDArray[np.int64]) -> str:
    return f"[{stamps_ns[0] / 1e9:.6f}, {stamps_ns[-1] / 1e9:.6f}] s"


def _nearest(
    short_ns: npt.NDArray[np.int64], long_ns: npt.NDArray[np.int64], max_diff_ns: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """Nearest stamp of ``long_ns`` for every stamp of ``short_ns`` within ``max_diff_ns``.

    Ties between the neighbour below and above go to the one below, as in evo's
    ``matching_time_indices``.  Returns (short indices, long indices, |difference| ns).
    """
    limit = np.int64(min(max_diff_ns, np.iinfo(np.int64).max))
    rows_s, rows_l, diff = nearest(short_ns, long_ns, limit)
    return rows_s, rows_l, diff


def _one_to_one(
    i_short: npt.NDArray[np.intp], i_long: npt.NDArray[np.intp], diff: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Mask keeping, for each long index used more than once, only its closest short partner.

    Among equally close partners the earliest short stamp wins.  Matched long indices are
    non-decreasing in the short index, so duplicates form contiguous runs.
    """
    if i_long.shape[0] < 2 or bool(np.all(i_long[1:] != i_long[:-1])):
        return np.ones(i_short.shape[0], dtype=bool)  # already one to one (the usual case)
    order = np.lexsort((i_short, diff, i_long))  # by long index, then difference, then time
    first = np.ones(order.shape[0], dtype=bool)
    first[1:] = i_long[order][1:] != i_long[order][:-1]
    keep = np.zeros(i_short.shape[0], dtype=bool)
    keep[order[first]] = True
    return keep


def _interpolate(traj: Trajectory, stamps_ns: npt.NDArray[np.int64]) -> Trajectory:
    """Lerp positions and slerp orientations of ``traj`` at ``stamps_ns`` (inside its span)."""
    t = traj.stamps_ns
    k = np.clip(np.searchsorted(t, stamps_ns, side="right") - 1, 0, max(len(t) - 2, 0))
    if len(t) == 1:
        return trusted(stamps_ns, traj.pos_m[k], traj.quat_xyzw[k], traj.name)
    t0 = t[k]
    # Fractions from integer differences: exact 0 and 1 on the nodes themselves.
    a = (stamps_ns - t0).astype(np.float64) / (t[k + 1] - t0).astype(np.float64)
    p0, p1 = traj.pos_m[k], traj.pos_m[k + 1]
    pos = p0 + a[:, None] * (p1 - p0)
    quat = quat_slerp(traj.quat_xyzw[k], traj.quat_xyzw[k + 1], a)
    return trusted(stamps_ns, pos, quat, traj.name)


def _check_count(n: int, est: Trajectory, ref: Trajectory, how: str) -> None:
    if n < MIN_MATCHES:
        raise DegenerateInputError(
            f"only {n} pose(s) matched {how} ({est.describe('estimate')} has {len(est)}, "
            f"{ref.describe('reference')} {len(ref)}); "
            f"at least {MIN_MATCHES} are needed: {_HINT_TEXT}", hint=_HINT)


def _checked_stamps(est: Trajectory, ref: Trajectory, max_diff_s: float,
                    offset_s: float) -> tuple[int, int, np.ndarray]:
    """``(max_diff_ns, offset_ns, shifted estimate stamps)``; refuses empty trajectories, a bad
    ``max_diff_s`` and time ranges that do not overlap."""
    if len(est) == 0 or len(ref) == 0:
        raise DegenerateInputError(
            f"cannot associate an empty trajectory ({est.describe('estimate')} has {len(est)} poses, "
            f"{ref.describe('reference')} {len(ref)})"
        )
    if not (math.isfinite(max_diff_s) and max_diff_s >= 0.0):
        raise IbiscapeError(f"max_diff_s must be a finite number >= 0, got {max_diff_s!r}")
    max_diff_ns = _ns(max_diff_s, "max_diff_s")
    offset_ns = _ns(offset_s, "offset_s")
    est_ns = est.stamps_ns + np.int64(offset_ns)
    ref_ns = ref.stamps_ns
    if est_ns[-1] + max_diff_ns < ref_ns[0] or est_ns[0] > ref_ns[-1] + max_diff_ns:
        shift = f" after adding offset {offset_s:+.6f} s" if offset_ns else ""
        raise IbiscapeError(
            f"estimate {est.name!r} spans {_span(est_ns)}{shift} and reference {ref.name!r} spans "
            f"{_span(ref_ns)}: the time ranges do not overlap; check the files' time units or "
            "give an {0}", hint=(Remedy("offset_s"),))
    return max_diff_ns, offset_ns, est_ns


def _interpolated_pairs(
    short: Trajectory, long_: Trajectory, i_short: np.ndarray, check: Callable[[int], None]
) -> tuple[Trajectory, Trajectory, int]:
    """The sparser trajectory's poses inside the denser one's span, the denser one resampled at
    their stamps, and the denser poses dropped (``check`` refuses too few pairs)."""
    inside = (short.stamps_ns[i_short] >= long_.stamps_ns[0]) & (
        short.stamps_ns[i_short] <= long_.stamps_ns[-1]
    )
    i_short = i_short[inside]
    check(i_short.shape[0])
    short_m = take(short, i_short)
    long_m = _interpolate(long_, short_m.stamps_ns)
    # No original pose of the denser trajectory is kept: those outside the matched span
    # count as dropped.
    lo, hi = short_m.stamps_ns[0], short_m.stamps_ns[-1]
    drop_long = int(np.count_nonzero((long_.stamps_ns < lo) | (long_.stamps_ns > hi)))
    return short_m, long_m, drop_long


def associate(
    est: Trajectory,
    ref: Trajectory,
    *,
    max_diff_s: float = 0.01,
    offset_s: float = 0.0,
    interpolate: bool = False,
) -> Matched:
    """Pair estimated and reference poses by nearest timestamp, one to one.

    Every pose of the trajectory with fewer poses looks for the nearest stamp of the other one
    (binary search, O(n log n)); pairs further apart than ``max_diff_s`` are dropped, and when
    two poses claim the same partner only the closer one keeps it.  This reproduces evo's
    ``associate_trajectories`` on real data while guaranteeing a one-to-one pairing.

    Parameters
    ----------
    est, ref : Trajectory
        Estimate and reference (ground truth).
    max_diff_s : float
        Largest accepted time difference between paired stamps, seconds.
    offset_s : float
        Constant added to the estimate's stamps first: ``t_ref = t_est + offset_s``, seconds.
    interpolate : bool
        Instead of snapping to the nearest pose, resample the denser trajectory at the stamps of
        the sparser one (lerp of positions, slerp of quaternions).  Only stamps inside the
        denser trajectory's time span that have one of its poses within ``max_diff_s`` are used,
        so gaps in the denser trajectory are never bridged and nothing is extrapolated.

    Returns
    -------
    Matched
        The paired trajectories with the counts of dropped poses.

    Raises
    ------
    IbiscapeError
        When the two time ranges do not overlap (both ranges are named).
    DegenerateInputError
        When fewer than 3 poses are matched.
    """
    max_diff_ns, offset_ns, est_ns = _checked_stamps(est, ref, max_diff_s, offset_s)
    est_shifted = trusted(est_ns, est.pos_m, est.quat_xyzw, est.name)
    # Like evo: start from the trajectory with fewer poses (the estimate on a tie).
    est_is_short = len(est) <= len(ref)
    short, long_ = (est_shifted, ref) if est_is_short else (ref, est_shifted)
    i_short, i_long, diff = _nearest(short.stamps_ns, long_.stamps_ns, max_diff_ns)
    how = f"within {max_diff_s} s" + (f" with offset {offset_s:+.6f} s" if offset_ns else "")
    if interpolate:
        inside = how + " inside the overlap"
        short_m, long_m, drop_long = _interpolated_pairs(
            short, long_, i_short, lambda n: _check_count(n, est, ref, inside))
    else:
        keep = _one_to_one(i_short, i_long, diff)
        i_short, i_long = i_short[keep], i_long[keep]
        _check_count(i_short.shape[0], est, ref, how)
        short_m, long_m = take(short, i_short), take(long_, i_long)
        drop_long = len(long_) - len(long_m)
    drop_short = len(short) - len(short_m)
    if est_is_short:
        est_m, ref_m, drop_est, drop_ref = short_m, long_m, drop_short, drop_long
    else:
        est_m, ref_m, drop_est, drop_ref = long_m, short_m, drop_long, drop_short
    return Matched(
        est=est_m,
        ref=ref_m,
        n_dropped_est=int(drop_est),
        n_dropped_ref=int(drop_ref),
        t_offset_s=float(offset_ns) / 1e9,
        interpolated=bool(interpolate),
        by_index=False,
    )


def associate_by_index(est: Trajectory, ref: Trajectory) -> Matched:
    """Pair row ``i`` of the estimate with row ``i`` of the reference (KITTI files carry no time).

    Raises
    ------
    DegenerateInputError
        When the lengths differ (both are named) or there are fewer than 3 poses.
    """
    if len(est) != len(ref):
        raise DegenerateInputError(
            f"pairing by index needs equally long trajectories, but estimate {est.name!r} has "
            f"{len(est)} poses and reference {ref.name!r} has {len(ref)}; pair by time instead "
            "or trim the files"
        )
    _check_count(len(est), est, ref, "by index")
    return Matched(
        est=est, ref=ref, n_dropped_est=0, n_dropped_ref=0, t_offset_s=0.0,
        interpolated=False, by_index=True,
    )
