"""Pieces shared by ATE, RPE and drift: matching options, relative pose errors, array freezing."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, IbiscapeWarning, Trajectory

from . import _fast
from ._fast import run_rows, take, trusted
from .alignment import AlignmentResult
from .association import Matched, associate, associate_by_index

__all__ = [
    "LENGTH_UNITS",
    "MatchedResult",
    "absolute_errors",
    "aligned_errors",
    "emit",
    "frozen",
    "match_poses",
    "matched_fields",
    "prepare",
    "relative_errors",
    "select",
    "take",
    "trusted",
]

FloatArray = npt.NDArray[np.float64]

MATCH_MODES = ("time", "index")

#: Output units of translation errors (evo's ``--change_unit``) and their factor from metres.
LENGTH_UNITS = {"m": 1.0, "cm": 100.0, "mm": 1000.0}


def check_unit(unit: str) -> float:
    """The factor from metres to ``unit`` (``m``, ``cm``, ``mm``)."""
    try:
        return LENGTH_UNITS[unit]
    except KeyError:
        raise IbiscapeError(
            f"unknown length unit {unit!r}; choose one of {', '.join(LENGTH_UNITS)}") from None


def select(
    est: Trajectory,
    ref: Trajectory,
    *,
    t_start_s: float | None,
    t_end_s: float | None,
    downsample: int | None,
    motion_filter: tuple[float, float] | None,
) -> tuple[Trajectory, Trajectory]:
    """evo's pose selection, in evo's order: both trajectories downsampled, then motion-filtered,
    then the reference cut to ``[t_start_s, t_end_s]`` (before association)."""
    from . import select as sel

    if downsample is not None:
        est, ref = sel.downsample(est, downsample), sel.downsample(ref, downsample)
    if motion_filter is not None:
        d, a = motion_filter
        est, ref = sel.motion_filter(est, d, a), sel.motion_filter(ref, d, a)
    ref = sel.time_range(ref, t_start_s, t_end_s)
    return est, ref


def emit(messages: list[str], stacklevel: int = 3) -> tuple[str, ...]:
    """Issue each message as an :class:`IbiscapeWarning` and return them (results keep them for
    their JSON ``warnings`` list)."""
    for msg in messages:
        warnings.warn(msg, IbiscapeWarning, stacklevel=stacklevel)
    return tuple(messages)


def stamps_synthetic(est: Trajectory, ref: Trajectory, m: Matched) -> bool:
    """Whether the stamps of a result are made up: either side has synthetic stamps (KITTI
    without times) or the poses were paired by index."""
    return bool(est.stamps_synthetic or ref.stamps_synthetic or m.by_index)


def pose_index(ref: Trajectory, m: Matched) -> npt.NDArray[np.int64]:
    """Pose index of each matched reference row: the line index for synthetic stamps, else
    the row of the matched reference (pairing by index keeps every row)."""
    from ibiscape_eval.core.trajectory import SYNTHETIC_PERIOD_NS

    if ref.stamps_synthetic:  # matched rows keep their synthetic stamps: index * period
        return m.ref.stamps_ns // SYNTHETIC_PERIOD_NS
    return np.arange(len(m.ref), dtype=np.int64)


def frozen(a: npt.ArrayLike, dtype: Any = None, *, owned: bool = False) -> np.ndarray:
    """A read-only copy of ``a`` (results are immutable); ``owned``: ``a`` is a new array that
    nothing else holds, so it is made read-only in place instead of copied."""
    out = np.asarray(a, dtype=dtype) if owned else np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out


def match_poses(
    est: Trajectory,
    ref: Trajectory,
    *,
    match: str,
    max_diff_s: float,
    offset_s: float,
    estimate_offset: bool,
    interpolate: bool,
) -> Matched:
    """Apply the association options every metric shares."""
    if match not in MATCH_MODES:
        raise IbiscapeError(f"unknown match mode {match!r}; choose 'time' or 'index'")
    if match == "index":
        if estimate_offset or interpolate or offset_s:
            raise IbiscapeError(
                "pairing by index ignores time: do not combine it with an offset, "
                "offset estimation or interpolation"
            )
        return associate_by_index(est, ref)
    if estimate_offset:
        from .offset import estimate_time_offset

        offset_s = estimate_time_offset(est, ref, max_diff_s=max_diff_s, center_s=offset_s)
    return associate(est, ref, max_diff_s=max_diff_s, offset_s=offset_s, interpolate=interpolate)


@dataclass(frozen=True, eq=False)
class Prepared:
    """The selected, matched and aligned pair that ATE, RPE and drift start from.

    ``est`` and ``ref`` are the trajectories after evo's pose selection (their names stay for
    messages), ``m`` the association, ``al`` the alignment of ``m.est`` onto ``m.ref``."""

    est: Trajectory
    ref: Trajectory
    m: Matched
    al: AlignmentResult
    synthetic: bool
    index: npt.NDArray[np.int64]

    def fields(self, est_aligned: Trajectory, warnings: tuple[str, ...],
               m: Matched | None = None) -> dict[str, Any]:
        """Keyword arguments of :class:`MatchedResult` (``m`` replaces the association, e.g.
        with a projected reference)."""
        return matched_fields(self.m if m is None else m, self.al, est_aligned,
                              synthetic=self.synthetic, warnings=warnings,
                              ref_pose_index=self.index)


def prepare(
    est: Trajectory, ref: Trajectory, *, align: Any, n_align: int | None, match: str,
    max_diff_s: float, offset_s: float, estimate_offset: bool, interpolate: bool,
    t_start_s: float | None, t_end_s: float | None, downsample: int | None,
    motion_filter: tuple[float, float] | None,
) -> Prepared:
    """evo's pose selection (:func:`select`), the association (:func:`match_poses`) and the
    alignment (:func:`~ibiscape_eval.metrics.alignment.align`), in that order."""
    from .alignment import align as _align

    est, ref = select(est, ref, t_start_s=t_start_s, t_end_s=t_end_s, downsample=downsample,
                      motion_filter=motion_filter)
    m = match_poses(est, ref, match=match, max_diff_s=max_diff_s, offset_s=offset_s,
                    estimate_offset=estimate_offset, interpolate=interpolate)
    synthetic = stamps_synthetic(est, ref, m)
    index = pose_index(ref, m)
    al = _align(m.est, m.ref, method=align, n_align=n_align)
    return Prepared(est=est, ref=ref, m=m, al=al, synthetic=synthetic, index=index)


def _indices(index: npt.ArrayLike, n: int) -> npt.NDArray[np.intp]:
    """Row indices for the kernels, which do not check bounds: checked here, like numpy would."""
    idx = np.ascontiguousarray(index, dtype=np.intp)
    if idx.size and (int(idx.min()) < -n or int(idx.max()) >= n):
        raise IndexError(f"pose index out of range for {n} poses")
    return idx


def relative_errors(
    est: Trajectory, ref: Trajectory, first: npt.ArrayLike, second: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Translation (m) and rotation angle (rad) of ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``.

    ``Q`` are reference poses, ``P`` estimated poses, ``i = first``, ``j = second`` (evo's RPE
    and the KITTI devkit's segment error, which has the same norms).  One fused pass over the
    pairs (``_fast.relative_errors``).
    """
    n = min(len(est), len(ref))
    i, j = _indices(first, n), _indices(second, n)
    if i.shape != j.shape:
        raise IbiscapeError(f"got {i.shape[0]} first and {j.shape[0]} second pose indices")
    trans, rot = np.empty(i.shape[0]), np.empty(i.shape[0])
    run_rows(_fast.relative_errors, i.shape[0],
             (est.pos_m, est.quat_xyzw, ref.pos_m, ref.quat_xyzw, i, j), (trans, rot))
    return trans, rot


def aligned_errors(
    al: AlignmentResult, est: Trajectory, ref: Trajectory
) -> tuple[Trajectory, FloatArray, FloatArray]:
    """``al.apply(est)`` and, row by row, the translation (m) and rotation angle (rad) of
    ``E_i = P_i^-1 Q_i`` against ``ref``, in one fused pass (``_fast.aligned_errors``)."""
    if len(est) != len(ref):
        raise IbiscapeError(f"expected matched trajectories, got {len(est)} and {len(ref)} poses")
    n = len(est)
    pos, quat, trans, rot = np.empty((n, 3)), np.empty((n, 4)), np.empty(n), np.empty(n)
    run_rows(_fast.aligned_errors, n,
             (est.pos_m, est.quat_xyzw, ref.pos_m, ref.quat_xyzw, *al._coefficients()),
             (pos, quat, trans, rot))
    return trusted(est.stamps_ns, pos, quat, est.name), trans, rot


def absolute_errors(est: Trajectory, ref: Trajectory) -> tuple[FloatArray, FloatArray]:
    """Translation (m) and rotation angle (rad) of ``E_i = P_i^-1 Q_i`` row by row."""
    identity = AlignmentResult("none", np.eye(4), 1.0, 0)
    _, trans, rot = aligned_errors(identity, est, ref)
    return trans, rot


def scaled_stats(stats: Any, factor: float) -> dict[str, float]:
    """``stats.to_dict()`` with lengths multiplied by ``factor`` (``sse`` by its square)."""
    d = stats.to_dict()
    if factor == 1.0:
        return d
    return {k: (v * factor * factor if k == "sse" else v * factor) for k, v in d.items()}


@dataclass(frozen=True, eq=False)
class MatchedResult:
    """What every metric result holds besides its errors: how the two trajectories were matched
    and aligned.

    Attributes
    ----------
    alignment : AlignmentResult
        The transform applied to the estimate.
    est_aligned, ref : Trajectory
        The matched, aligned estimate and the matched reference (row by row).
    n_matched, n_dropped_est, n_dropped_ref : int
        Pose pairs used and poses without a partner.
    t_offset_s : float
        Offset added to the estimate's stamps, seconds (``t_ref = t_est + t_offset_s``).
    interpolated : bool
        Whether poses were interpolated during matching.
    warnings : tuple of str
        Warnings about the numbers (alignment poorly determined, lengths not reached ...), also
        issued as :class:`IbiscapeWarning`; ``to_dict()["warnings"]``.
    stamps_synthetic : bool
        The stamps are made up (KITTI without times, or pairing by index): tables, CSV and
        plots use ``ref_pose_index`` instead of times; ``to_dict()["stamps"]`` is
        ``"synthetic"``.
    ref_pose_index : ndarray, shape (N,), int64
        Pose index of each matched reference row (see :attr:`stamps_synthetic`).
    """

    alignment: AlignmentResult
    est_aligned: Trajectory
    ref: Trajectory
    n_matched: int
    n_dropped_est: int
    n_dropped_ref: int
    t_offset_s: float
    interpolated: bool
    warnings: tuple[str, ...] = field(default=(), kw_only=True)
    stamps_synthetic: bool = field(default=False, kw_only=True)
    ref_pose_index: npt.NDArray[np.int64] | None = field(default=None, kw_only=True)

    def _relation_dict(self, relation: str, plane: str | None, stats: Any,
                       unit: str = "m") -> dict[str, Any]:
        """The keys of the chosen pose relation (ATE and RPE); lengths in ``unit``."""
        from .relations import RELATION_UNITS

        rel_unit = RELATION_UNITS[relation]
        f = check_unit(unit) if rel_unit == "m" else 1.0
        return {"pose_relation": relation, "relation_unit": unit if rel_unit == "m" else rel_unit,
                "project_to_plane": plane, "error": scaled_stats(stats, f)}

    def _index_columns(self, stamps_ns: npt.NDArray[np.int64],
                       rows: npt.NDArray[np.intp] | None = None) -> dict[str, Any]:
        """The leading CSV columns: ``ref_stamp_ns, ref_t_s`` for measured stamps,
        ``ref_pose_index`` for synthetic ones (``rows``: the matched rows they belong to)."""
        from ibiscape_eval.core.time import s_from_ns

        if self.stamps_synthetic:
            idx = (np.arange(len(self.ref), dtype=np.int64) if self.ref_pose_index is None
                   else self.ref_pose_index)
            return {"ref_pose_index": idx if rows is None else idx[rows]}
        return {"ref_stamp_ns": stamps_ns, "ref_t_s": s_from_ns(stamps_ns)}

    def _common_dict(self, metric: str) -> dict[str, Any]:
        """The keys every metric's ``to_dict`` starts with (the JSON contract)."""
        return {
            "metric": metric,
            "n_matched": int(self.n_matched),
            "n_dropped_est": int(self.n_dropped_est),
            "n_dropped_ref": int(self.n_dropped_ref),
            "alignment": self.alignment.method,
            "scale": float(self.alignment.scale),
            "transform": self.alignment.transform.tolist(),
            "t_offset_s": float(self.t_offset_s),
            "interpolated": bool(self.interpolated),
            "stamps": "synthetic" if self.stamps_synthetic else "measured",
            "alignment_conditioning": (None if self.alignment.conditioning is None
                                       else self.alignment.conditioning.to_dict()),
            "warnings": list(self.warnings),
        }


def matched_fields(
    m: Matched, al: AlignmentResult, est_aligned: Trajectory, *,
    synthetic: bool = False, warnings: tuple[str, ...] = (),
    ref_pose_index: npt.NDArray[np.int64] | None = None,
) -> dict[str, Any]:
    """Keyword arguments of :class:`MatchedResult` from an association and an alignment."""
    return {
        "stamps_synthetic": synthetic,
        "warnings": warnings,
        "ref_pose_index": None if ref_pose_index is None else frozen(ref_pose_index),
        "alignment": al,
        "est_aligned": est_aligned,
        "ref": m.ref,
        "n_matched": m.n_matched,
        "n_dropped_est": m.n_dropped_est,
        "n_dropped_ref": m.n_dropped_ref,
        "t_offset_s": m.t_offset_s,
        "interpolated": m.interpolated,
    }
