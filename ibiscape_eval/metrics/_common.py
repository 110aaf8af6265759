"""Pieces shared by ATE, RPE and drift: matching options, relative pose errors, array freezing."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, Trajectory
from ibiscape_eval.core.rotations import (
    angle_rad_from_quat,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
)

from ._fast import take, trusted
from .association import Matched, associate, associate_by_index

__all__ = ["absolute_errors", "common_dict", "frozen", "match", "relative_errors", "take",
           "trusted"]

FloatArray = npt.NDArray[np.float64]

MATCH_MODES = ("time", "index")


def frozen(a: npt.ArrayLike, dtype: Any = None) -> np.ndarray:
    """A read-only copy of ``a`` (results are immutable)."""
    out = np.array(a, dtype=dtype)
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


def relative_errors(
    est: Trajectory, ref: Trajectory, first: npt.ArrayLike, second: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Translation (m) and rotation angle (rad) of ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``.

    ``Q`` are reference poses, ``P`` estimated poses, ``i = first``, ``j = second`` (evo's RPE
    and the KITTI devkit's segment error, which has the same norms).  Vectorised over pairs.
    """
    i = np.asarray(first, dtype=np.intp)
    j = np.asarray(second, dtype=np.intp)
    qi_ref_inv = quat_conjugate(ref.quat_xyzw[i])
    qi_est_inv = quat_conjugate(est.quat_xyzw[i])
    # Relative motions expressed in the start frame.
    t_ref = quat_rotate(qi_ref_inv, ref.pos_m[j] - ref.pos_m[i])
    t_est = quat_rotate(qi_est_inv, est.pos_m[j] - est.pos_m[i])
    q_ref = quat_multiply(qi_ref_inv, ref.quat_xyzw[j])
    q_est = quat_multiply(qi_est_inv, est.quat_xyzw[j])
    # E = Q_rel^-1 P_rel: translation R_Qrel^T (t_P - t_Q), rotation q_Q^-1 q_P.
    trans = np.linalg.norm(t_est - t_ref, axis=1)
    rot = angle_rad_from_quat(quat_multiply(quat_conjugate(q_ref), q_est))
    return trans, rot


def absolute_errors(est: Trajectory, ref: Trajectory) -> tuple[FloatArray, FloatArray]:
    """Translation (m) and rotation angle (rad) of ``E_i = P_i^-1 Q_i`` row by row."""
    trans = np.linalg.norm(ref.pos_m - est.pos_m, axis=1)
    rot = angle_rad_from_quat(quat_multiply(quat_conjugate(est.quat_xyzw), ref.quat_xyzw))
    return trans, rot


def nan_to_none(x: float) -> float | None:
    """JSON-friendly float: NaN becomes None."""
    return None if math.isnan(x) else float(x)


def common_dict(res: Any, *, metric: str) -> dict[str, Any]:
    """The keys every metric's ``to_dict`` starts with (the JSON contract)."""
    return {
        "metric": metric,
        "n_matched": int(res.n_matched),
        "n_dropped_est": int(res.n_dropped_est),
        "n_dropped_ref": int(res.n_dropped_ref),
        "alignment": res.alignment.method,
        "scale": float(res.alignment.scale),
        "transform": res.alignment.transform.tolist(),
        "t_offset_s": float(res.t_offset_s),
        "interpolated": bool(res.interpolated),
    }
