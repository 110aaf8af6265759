"""Absolute trajectory error (ATE / evo's APE) after alignment."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import Trajectory
from ibiscape_eval.core.time import s_from_ns

from ._common import MatchedResult, aligned_errors, frozen, matched_fields
from ._common import match as _match
from ._stats import ErrorStats
from .alignment import Alignment
from .alignment import align as _align

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["AteResult", "ate"]


@dataclass(frozen=True, eq=False)
class AteResult(MatchedResult):
    """Per-pose absolute errors of an aligned estimate.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
        Reference stamps of the matched poses.
    errors_m : ndarray, shape (N,)
        ``||t(E_i)||`` with ``E_i = P_est_i^-1 P_ref_i``, metres.
    errors_deg : ndarray, shape (N,)
        Rotation angle of ``E_i``, degrees.
    translation_m, rotation_deg : ErrorStats
        Statistics of the two error vectors.
    alignment, est_aligned, ref, n_matched, n_dropped_est, n_dropped_ref, t_offset_s,
    interpolated
        How the trajectories were matched and aligned: see :class:`MatchedResult`.
    """

    stamps_ns: npt.NDArray[np.int64]
    errors_m: npt.NDArray[np.float64]
    errors_deg: npt.NDArray[np.float64]
    translation_m: ErrorStats
    rotation_deg: ErrorStats

    def to_frame(self) -> pd.DataFrame:
        """Per-pose rows: ``stamp_ns, t_s, error_m, error_deg, est_{x,y,z}_m, ref_{x,y,z}_m``."""
        import pandas as pd

        e, r = self.est_aligned.pos_m, self.ref.pos_m
        return pd.DataFrame(
            {
                "stamp_ns": self.stamps_ns,
                "t_s": s_from_ns(self.stamps_ns),
                "error_m": self.errors_m,
                "error_deg": self.errors_deg,
                "est_x_m": e[:, 0], "est_y_m": e[:, 1], "est_z_m": e[:, 2],
                "ref_x_m": r[:, 0], "ref_y_m": r[:, 1], "ref_z_m": r[:, 2],
            }
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON document the CLI prints (see the package docs for the contract)."""
        doc = self._common_dict("ate")
        doc["n_align"] = int(self.alignment.n_used)
        doc["translation_m"] = self.translation_m.to_dict()
        doc["rotation_deg"] = self.rotation_deg.to_dict()
        return doc


def ate(
    est: Trajectory,
    ref: Trajectory,
    *,
    align: str | Alignment = "se3",
    n_align: int | None = None,
    max_diff_s: float = 0.01,
    offset_s: float = 0.0,
    estimate_offset: bool = False,
    interpolate: bool = False,
    match: str = "time",
) -> AteResult:
    """Absolute trajectory error of ``est`` against ``ref``.

    The poses are matched (:func:`associate` by time, or :func:`associate_by_index`), the
    estimate is aligned (:func:`align`), and for every pair ``E_i = P_est_i^-1 P_ref_i`` gives a
    translation error ``||t(E_i)||`` (m) and a rotation error ``angle(R(E_i))`` (deg).  Same
    numbers as evo's ``APE`` with the same matching and alignment.

    Parameters
    ----------
    est, ref : Trajectory
        Estimate and reference (ground truth), poses ``T_world_body``.
    align : {"se3", "sim3", "yaw", "origin", "none"}
        Alignment of the estimate (see :func:`align`).
    n_align : int, optional
        Align on the first ``n_align`` matched poses only.
    max_diff_s, offset_s, interpolate
        Matching options of :func:`associate` (seconds).
    estimate_offset : bool
        Estimate the time offset with :func:`estimate_time_offset` (searching around
        ``offset_s``) and use it.
    match : {"time", "index"}
        Pair by timestamp or by row index (KITTI files without times).

    Returns
    -------
    AteResult
    """
    m = _match(est, ref, match=match, max_diff_s=max_diff_s, offset_s=offset_s,
               estimate_offset=estimate_offset, interpolate=interpolate)
    al = _align(m.est, m.ref, method=align, n_align=n_align)
    est_al, trans, rot = aligned_errors(al, m.est, m.ref)
    rot_deg = np.degrees(rot, out=rot)
    return AteResult(
        stamps_ns=frozen(m.ref.stamps_ns),
        errors_m=frozen(trans, owned=True),
        errors_deg=frozen(rot_deg, owned=True),
        translation_m=ErrorStats.from_errors(trans),
        rotation_deg=ErrorStats.from_errors(rot_deg),
        **matched_fields(m, al, est_al),
    )

