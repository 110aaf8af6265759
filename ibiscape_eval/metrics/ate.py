"""Absolute trajectory error (ATE / evo's APE) after alignment."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import Trajectory

from ._common import (
    MatchedResult,
    absolute_errors,
    aligned_errors,
    check_unit,
    emit,
    frozen,
    prepare,
    scaled_stats,
)
from ._stats import ErrorStats
from .alignment import Alignment, conditioning_warnings
from .relations import check_plane, check_relation, relation_errors
from .relations import project_to_plane as _project
from .summary import summary_html, summary_repr

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

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
    pose_relation : str
        The relation of :attr:`errors` / :attr:`stats` (see
        :data:`~ibiscape_eval.metrics.relations.POSE_RELATIONS`; default ``"trans"``).
    project_to_plane : str or None
        Plane both trajectories were projected to after alignment (``xy``, ``xz``, ``yz``).
    alignment, est_aligned, ref, n_matched, n_dropped_est, n_dropped_ref, t_offset_s,
    interpolated
        How the trajectories were matched and aligned: see :class:`MatchedResult`.
    """

    stamps_ns: npt.NDArray[np.int64]
    errors_m: npt.NDArray[np.float64]
    errors_deg: npt.NDArray[np.float64]
    translation_m: ErrorStats
    rotation_deg: ErrorStats
    pose_relation: str = "trans"
    project_to_plane: str | None = None

    @property
    def errors(self) -> npt.NDArray[np.float64]:
        """Per-pose errors of :attr:`pose_relation` (evo's APE ``error`` array)."""
        return relation_errors(self.pose_relation, self.errors_m, self.errors_deg)

    @property
    def stats(self) -> ErrorStats:
        """Statistics of :attr:`errors`."""
        return ErrorStats.from_errors(self.errors)

    def plot(self, **kw: Any) -> Figure:
        """The figure of the absolute errors (a new Figure): the trajectory coloured by the error, the error over time and
        distance, the histogram.  ``kw``: ``unit``, ``plane``, ``panels``, ``title``,
        ``gps_xyz_m`` of :func:`ibiscape_eval.report.plots.metric_figure`."""
        from ibiscape_eval.report.plots import metric_figure

        return metric_figure(self, **{"title": "absolute trajectory error", **kw})

    def __repr__(self) -> str:
        return summary_repr(self, "AteResult")

    def _repr_html_(self) -> str:
        return summary_html(self, "ATE")

    def to_frame(self, *, unit: str = "m") -> pd.DataFrame:
        """Per-pose rows: ``ref_stamp_ns, ref_t_s, est_stamp_ns, error_m, error_deg,
        est_{x,y,z}_m, ref_{x,y,z}_m`` (and ``error`` for a relation other than ``trans``).

        ``ref_stamp_ns`` is the matched reference pose's stamp, ``est_stamp_ns`` the estimate's
        (after any time offset); ``ref_t_s`` is the reference stamp in seconds.  Synthetic stamps
        (:attr:`stamps_synthetic`) give ``ref_pose_index`` instead of these three columns.
        ``unit`` (``m``, ``cm``, ``mm``; evo's ``--change_unit``) renames and scales the length
        columns (``error_cm``, ``est_x_cm`` ...)."""
        import pandas as pd

        from .relations import RELATION_UNITS

        f = check_unit(unit)
        e, r = self.est_aligned.pos_m, self.ref.pos_m
        cols: dict[str, Any] = self._index_columns(self.stamps_ns)
        if not self.stamps_synthetic:
            cols["est_stamp_ns"] = self.est_aligned.stamps_ns
        cols.update({
                f"error_{unit}": self.errors_m * f,
                "error_deg": self.errors_deg,
                f"est_x_{unit}": e[:, 0] * f, f"est_y_{unit}": e[:, 1] * f,
                f"est_z_{unit}": e[:, 2] * f,
                f"ref_x_{unit}": r[:, 0] * f, f"ref_y_{unit}": r[:, 1] * f,
                f"ref_z_{unit}": r[:, 2] * f,
        })
        if self.pose_relation != "trans":
            rf = f if RELATION_UNITS[self.pose_relation] == "m" else 1.0
            cols["error"] = self.errors * rf
        return pd.DataFrame(cols)

    def to_dict(self, *, unit: str = "m") -> dict[str, Any]:
        """The JSON document the CLI prints (see the package docs for the contract);
        ``unit`` other than ``m`` reports ``translation_<unit>`` and adds ``length_unit``."""
        f = check_unit(unit)
        doc = self._common_dict("ate")
        doc["n_align"] = int(self.alignment.n_used)
        doc[f"translation_{unit}"] = scaled_stats(self.translation_m, f)
        doc["rotation_deg"] = self.rotation_deg.to_dict()
        doc.update(self._relation_dict(self.pose_relation, self.project_to_plane, self.stats,
                                       unit))
        if unit != "m":
            doc["length_unit"] = unit
        return doc


def ate(
    est: Trajectory, ref: Trajectory, *,
    align: str | Alignment = "se3", n_align: int | None = None,
    max_diff_s: float = 0.01, offset_s: float = 0.0, estimate_offset: bool = False,
    interpolate: bool = False, match: str = "time",
    pose_relation: str = "trans", project_to_plane: str | None = None,
    t_start_s: float | None = None, t_end_s: float | None = None, downsample: int | None = None,
    motion_filter: tuple[float, float] | None = None,
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
    pose_relation : {"trans", "rot-angle", "rot-part", "full", "point-distance"}
        evo's pose relation of :attr:`AteResult.errors` / ``stats`` (``errors_m`` and
        ``errors_deg`` are always computed).
    project_to_plane : {"xy", "xz", "yz"}, optional
        Project both trajectories onto this plane after the alignment (evo's
        ``--project_to_plane``; :func:`~ibiscape_eval.metrics.relations.project_to_plane`).
    t_start_s, t_end_s : float, optional
        Use only reference poses stamped within this range (absolute seconds, evo's
        ``--t_start``/``--t_end``).
    downsample : int, optional
        Evenly downsample both trajectories to at most this many poses first (evo's
        ``--downsample``).
    motion_filter : (float, float), optional
        ``(distance_m, angle_deg)``: keep a pose only after moving that far or turning that much
        (evo's ``--motion_filter``), applied to both trajectories before matching.

    Returns
    -------
    AteResult
        With ``warnings`` (also issued as :class:`~ibiscape_eval.core.IbiscapeWarning`) when a
        poorly determined alignment dominates the rotation error (:func:`conditioning_warnings`).
    """
    check_relation(pose_relation)
    plane = check_plane(project_to_plane)
    pre = prepare(est, ref, align=align, n_align=n_align, match=match, max_diff_s=max_diff_s,
                  offset_s=offset_s, estimate_offset=estimate_offset, interpolate=interpolate,
                  t_start_s=t_start_s, t_end_s=t_end_s, downsample=downsample,
                  motion_filter=motion_filter)
    m, al = pre.m, pre.al
    est_al, trans, rot = aligned_errors(al, m.est, m.ref)
    if plane is not None:
        est_al, ref_p = _project(est_al, plane), _project(m.ref, plane)
        trans, rot = absolute_errors(est_al, ref_p)
        m = replace(m, ref=ref_p)
    rot_deg = np.degrees(rot, out=rot)
    rot_stats = ErrorStats.from_errors(rot_deg)
    notes = emit(conditioning_warnings(al, rotation_rmse_deg=rot_stats.rmse,
                                       who=pre.est.describe("estimate")))
    return AteResult(
        stamps_ns=frozen(m.ref.stamps_ns),
        errors_m=frozen(trans, owned=True),
        errors_deg=frozen(rot_deg, owned=True),
        translation_m=ErrorStats.from_errors(trans),
        rotation_deg=rot_stats,
        pose_relation=pose_relation,
        project_to_plane=plane,
        **pre.fields(est_al, notes, m),
    )

