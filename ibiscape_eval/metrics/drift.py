"""KITTI-style drift: relative error of path segments of fixed lengths, per metre travelled."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, Trajectory
from ibiscape_eval.core.numbers import finite_or_none

from ._common import (
    MatchedResult,
    emit,
    frozen,
    prepare,
    relative_errors,
)
from ._stats import ErrorStats
from .alignment import Alignment
from .summary import summary_html, summary_repr

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["KITTI_LENGTHS_M", "DriftResult", "drift"]

#: Segment lengths of the KITTI odometry devkit, metres.
KITTI_LENGTHS_M = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)


@dataclass(frozen=True, eq=False)
class DriftResult(MatchedResult):
    """Drift per segment length (KITTI odometry devkit definition).

    Attributes
    ----------
    lengths_m : ndarray, shape (K,)
        Segment lengths along the reference path, metres.
    translation_pct : ndarray, shape (K,)
        Mean translation error / length per length, percent (NaN where ``n_segments`` is 0).
    rotation_deg_per_m : ndarray, shape (K,)
        Mean rotation error / length per length, degrees per metre (NaN where no segment).
    n_segments : ndarray, shape (K,), int
        Segments found for each length.
    mean_translation_pct, mean_rotation_deg_per_m : float
        Averages over all segments of all lengths, as the KITTI devkit reports them.
    segment_first_index, segment_second_index : ndarray, shape (S,), int
        Start and end rows of every segment in ``est_aligned`` / ``ref``.
    segment_length_m : ndarray, shape (S,)
        Nominal length of each segment, metres.
    segment_translation_pct, segment_rotation_deg_per_m : ndarray, shape (S,)
        Per-segment errors divided by the nominal length.
    translation_m, rotation_deg : ErrorStats
        Statistics of the per-segment errors in metres and degrees (not divided by length).
    step_frames : int
        Distance between segment start frames.
    alignment, est_aligned, ref, n_matched, n_dropped_est, n_dropped_ref, t_offset_s,
    interpolated
        How the trajectories were matched and aligned: see :class:`MatchedResult`.
    """

    lengths_m: npt.NDArray[np.float64]
    translation_pct: npt.NDArray[np.float64]
    rotation_deg_per_m: npt.NDArray[np.float64]
    n_segments: npt.NDArray[np.int64]
    mean_translation_pct: float
    mean_rotation_deg_per_m: float
    segment_first_index: npt.NDArray[np.intp]
    segment_second_index: npt.NDArray[np.intp]
    segment_length_m: npt.NDArray[np.float64]
    segment_translation_pct: npt.NDArray[np.float64]
    segment_rotation_deg_per_m: npt.NDArray[np.float64]
    translation_m: ErrorStats
    rotation_deg: ErrorStats
    step_frames: int

    def plot(self, *, title: str = "drift per segment length") -> Figure:
        """Translation [%] and rotation [deg/m] drift per segment length (a new Figure)."""
        from ibiscape_eval.report.plots import drift_figure

        return drift_figure(self, title=title)

    def __repr__(self) -> str:
        return summary_repr(self, "DriftResult")

    def _repr_html_(self) -> str:
        return summary_html(self, "drift")

    @property
    def reached(self) -> npt.NDArray[np.bool_]:
        """Per length: whether any segment of that length fits on the reference path (False
        rows have no errors, not a zero drift)."""
        return np.asarray(self.n_segments) > 0

    @property
    def path_length_m(self) -> float:
        """Length of the matched reference path, metres."""
        return float(self.ref.path_length_m()[-1]) if len(self.ref) else 0.0

    def to_frame(self) -> pd.DataFrame:
        """One row per length: ``length_m, reached, n_segments, translation_pct,
        rotation_deg_per_m`` (the errors empty where ``reached`` is False)."""
        import pandas as pd

        return pd.DataFrame(
            {
                "length_m": self.lengths_m,
                "reached": self.reached,
                "n_segments": self.n_segments,
                "translation_pct": self.translation_pct,
                "rotation_deg_per_m": self.rotation_deg_per_m,
            }
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON document: ATE's keys plus per-length lists and the averages (NaN -> null)."""
        doc = self._common_dict("drift")
        doc["step_frames"] = int(self.step_frames)
        doc["lengths_m"] = [float(x) for x in self.lengths_m]
        doc["n_segments"] = [int(x) for x in self.n_segments]
        doc["reached"] = [bool(x) for x in self.reached]
        doc["path_length_m"] = self.path_length_m
        doc["translation_pct"] = [finite_or_none(float(x)) for x in self.translation_pct]
        doc["rotation_deg_per_m"] = [finite_or_none(float(x)) for x in self.rotation_deg_per_m]
        doc["mean_translation_pct"] = finite_or_none(self.mean_translation_pct)
        doc["mean_rotation_deg_per_m"] = finite_or_none(self.mean_rotation_deg_per_m)
        doc["translation_m"] = {k: finite_or_none(v) for k, v in self.translation_m.to_dict().items()}
        doc["rotation_deg"] = {k: finite_or_none(v) for k, v in self.rotation_deg.to_dict().items()}
        return doc


def _lengths(
    lengths_m: Sequence[float] | None, lengths_pct: Sequence[float] | None, total_m: float
) -> npt.NDArray[np.float64]:
    if lengths_pct is not None:
        pct = np.asarray(lengths_pct, dtype=np.float64).ravel()
        if pct.size == 0 or not np.all(np.isfinite(pct)) or np.any(pct <= 0) or np.any(pct > 100):
            raise IbiscapeError(
                f"lengths_pct must be percentages in (0, 100], got {list(pct)}"
            )
        return pct / 100.0 * total_m
    lengths = np.asarray(KITTI_LENGTHS_M if lengths_m is None else lengths_m, dtype=np.float64)
    lengths = lengths.ravel()
    if lengths.size == 0 or not np.all(np.isfinite(lengths)) or np.any(lengths <= 0):
        raise IbiscapeError(f"lengths_m must be positive lengths in metres, got {list(lengths)}")
    return lengths


def _segment_ends(
    cum: npt.NDArray[np.float64], first: npt.NDArray[np.intp], length: float
) -> npt.NDArray[np.intp]:
    """First row ``j`` with ``cum[j] - cum[i] >= length`` for each ``i`` in ``first``; -1 if none."""
    n = cum.shape[0]
    k = np.searchsorted(cum, cum[first] + length, side="left")
    end = np.full(first.shape[0], -1, dtype=np.intp)
    # The sum cum[i] + length is rounded; settle the exact condition among k-1, k, k+1,
    # scanning from the back so the first qualifying index wins.
    for shift in (1, 0, -1):
        j = k + shift
        valid = (j > first) & (j < n)
        jj = np.where(valid, j, 0)
        ok = valid & ((cum[jj] - cum[first]) >= length)
        end = np.where(ok, jj, end)
    return end


def _segments(
    cum: np.ndarray, lengths: np.ndarray, step_frames: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """First and last rows, length and length index of every segment that fits, length by
    length (K lengths, a handful; each is vectorised over the start frames)."""
    starts = np.arange(0, cum.shape[0], step_frames, dtype=np.intp)
    firsts, seconds, seg_len = [], [], []
    for L in lengths:
        end = _segment_ends(cum, starts, float(L))
        ok = end >= 0
        firsts.append(starts[ok])
        seconds.append(end[ok])
        seg_len.append(np.full(int(ok.sum()), L))
    which = np.repeat(np.arange(lengths.shape[0]), [f.shape[0] for f in firsts])
    return np.concatenate(firsts), np.concatenate(seconds), np.concatenate(seg_len), which


def _per_length(
    which: np.ndarray, t_pct: np.ndarray, r_deg_m: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segments per length and their mean errors (NaN where no segment fits)."""
    counts = np.bincount(which, minlength=k).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_t = np.bincount(which, weights=t_pct, minlength=k) / counts
        per_r = np.bincount(which, weights=r_deg_m, minlength=k) / counts
    per_t[counts == 0] = math.nan
    per_r[counts == 0] = math.nan
    return counts, per_t, per_r


def _unreached_notes(lengths: np.ndarray, counts: np.ndarray, path_m: float,
                     none_fits: bool) -> list[str]:
    """The warning naming the lengths no segment reaches (empty when all are reached)."""
    unreached = lengths[counts == 0]
    if not unreached.size:
        return []
    which_l = ", ".join(f"{v:g}" for v in unreached)
    head = ("no drift segment fits" if none_fits
            else f"{unreached.size} of {lengths.size} segment lengths were not reached")
    return [
        f"{head}: the matched reference path is {path_m:.1f} m long, so no segment spans "
        f"{which_l} m (those rows have no errors, not a zero drift); use shorter lengths_m or "
        "lengths relative to the path, e.g. lengths_pct=[10, 20, 30, 40, 50]"
    ]


def drift(
    est: Trajectory, ref: Trajectory, *,
    lengths_m: Sequence[float] | None = KITTI_LENGTHS_M,
    lengths_pct: Sequence[float] | None = None, step_frames: int = 10,
    align: str | Alignment = "none", n_align: int | None = None,
    max_diff_s: float = 0.01, offset_s: float = 0.0, estimate_offset: bool = False,
    interpolate: bool = False, match: str = "time",
    t_start_s: float | None = None, t_end_s: float | None = None, downsample: int | None = None,
    motion_filter: tuple[float, float] | None = None,
) -> DriftResult:
    """Translation and rotation drift over segments of the reference path (KITTI devkit).

    From every ``step_frames``-th matched pose ``i`` and for every length ``L``, the segment
    ends at the first pose ``j`` with ``path_length[j] - path_length[i] >= L`` on the
    reference; its error is the relative pose error of the pair ``(i, j)`` (see :func:`rpe`),
    reported as translation / L in percent and rotation / L in degrees per metre.

    Parameters
    ----------
    est, ref : Trajectory
        Estimate and reference.
    lengths_m : sequence of float
        Segment lengths, metres (KITTI: 100, 200, ..., 800).
    lengths_pct : sequence of float, optional
        Lengths as percentages of the total reference path (rpg_trajectory_evaluation style);
        replaces ``lengths_m`` when given.
    step_frames : int
        Distance between start frames (KITTI uses 10).
    align, n_align, max_diff_s, offset_s, estimate_offset, interpolate, match
        As in :func:`ate`.
    t_start_s, t_end_s, downsample, motion_filter
        evo's pose selection, as in :func:`ate`.

    Returns
    -------
    DriftResult
        Lengths without any segment have ``n_segments`` 0, ``reached`` False and NaN errors; the
        averages skip them, and a warning names them and proposes ``lengths_pct``.
    """
    if int(step_frames) != step_frames or step_frames < 1:
        raise IbiscapeError(f"step_frames must be a positive integer, got {step_frames!r}")
    pre = prepare(est, ref, align=align, n_align=n_align, match=match, max_diff_s=max_diff_s,
                  offset_s=offset_s, estimate_offset=estimate_offset, interpolate=interpolate,
                  t_start_s=t_start_s, t_end_s=t_end_s, downsample=downsample,
                  motion_filter=motion_filter)
    m = pre.m
    est_al = pre.al.apply(m.est)
    cum = m.ref.path_length_m()
    lengths = _lengths(lengths_m, lengths_pct, float(cum[-1]))
    i, j, seg_l, which = _segments(cum, lengths, int(step_frames))
    trans, rot = relative_errors(est_al, m.ref, i, j)
    rot_deg = np.degrees(rot)
    t_pct = trans / seg_l * 100.0
    r_deg_m = rot_deg / seg_l
    counts, per_t, per_r = _per_length(which, t_pct, r_deg_m, lengths.shape[0])
    warned = emit(_unreached_notes(lengths, counts, float(cum[-1]), i.shape[0] == 0))
    if i.shape[0] == 0:
        mean_t = mean_r = math.nan
    else:
        mean_t, mean_r = float(np.mean(t_pct)), float(np.mean(r_deg_m))
    return DriftResult(
        lengths_m=frozen(lengths),
        translation_pct=frozen(per_t),
        rotation_deg_per_m=frozen(per_r),
        n_segments=frozen(counts),
        mean_translation_pct=mean_t,
        mean_rotation_deg_per_m=mean_r,
        segment_first_index=frozen(i),
        segment_second_index=frozen(j),
        segment_length_m=frozen(seg_l),
        segment_translation_pct=frozen(t_pct),
        segment_rotation_deg_per_m=frozen(r_deg_m),
        translation_m=ErrorStats.from_errors(trans),
        rotation_deg=ErrorStats.from_errors(rot_deg),
        step_frames=int(step_frames),
        **pre.fields(est_al, warned),
    )
