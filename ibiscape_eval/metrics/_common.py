"""Pieces shared by ATE, RPE and drift: matching options, relative pose errors, array freezing."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, Trajectory

from . import _fast
from ._fast import run_rows, take, trusted
from .alignment import AlignmentResult
from .association import Matched, associate, associate_by_index

__all__ = [
    "MatchedResult",
    "absolute_errors",
    "aligned_errors",
    "frozen",
    "match",
    "matched_fields",
    "relative_errors",
    "take",
    "trusted",
]

FloatArray = npt.NDArray[np.float64]

MATCH_MODES = ("time", "index")


def frozen(a: npt.ArrayLike, dtype: Any = None, *, owned: bool = False) -> np.ndarray:
    """A read-only copy of ``a`` (results are immutable); ``owned``: ``a`` is a new array that
    nothing else holds, so it is made read-only in place instead of copied."""
    out = np.asarray(a, dtype=dtype) if owned else np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out


def match(
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


def nan_to_none(x: float) -> float | None:
    """JSON-friendly float: NaN becomes None."""
    return None if math.isnan(x) else float(x)


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
    """

    alignment: AlignmentResult
    est_aligned: Trajectory
    ref: Trajectory
    n_matched: int
    n_dropped_est: int
    n_dropped_ref: int
    t_offset_s: float
    interpolated: bool

    def _relation_dict(self, relation: str, plane: str | None, stats: Any) -> dict[str, Any]:
        """The keys of the chosen pose relation (ATE and RPE)."""
        from .relations import RELATION_UNITS

        return {"pose_relation": relation, "relation_unit": RELATION_UNITS[relation],
                "project_to_plane": plane, "error": stats.to_dict()}

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
        }


def matched_fields(m: Matched, al: AlignmentResult, est_aligned: Trajectory) -> dict[str, Any]:
    """Keyword arguments of :class:`MatchedResult` from an association and an alignment."""
    return {
        "alignment": al,
        "est_aligned": est_aligned,
        "ref": m.ref,
        "n_matched": m.n_matched,
        "n_dropped_est": m.n_dropped_est,
        "n_dropped_ref": m.n_dropped_ref,
        "t_offset_s": m.t_offset_s,
        "interpolated": m.interpolated,
    }
