"""Relative pose error (RPE) over pose pairs chosen by frames, seconds, metres or degrees."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, Trajectory
from ibiscape_eval.core.errors import Remedy
from ibiscape_eval.core.rotations import angle_rad_from_quat, quat_conjugate, quat_multiply

from ._common import (
    MatchedResult,
    check_unit,
    emit,
    frozen,
    prepare,
    relative_errors,
    scaled_stats,
)
from ._pairs import pairs_by_frames, pairs_by_steps
from ._stats import ErrorStats
from .alignment import Alignment, conditioning_warnings
from .relations import check_plane, check_relation, relation_errors
from .relations import project_to_plane as _project
from .summary import summary_html, summary_repr

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["DELTA_UNITS", "PAIRS_FROM", "PAIR_MODES", "RpeResult", "rpe", "select_pairs"]

DELTA_UNITS = ("frames", "seconds", "metres", "degrees")
PAIR_MODES = ("consecutive", "all")
PAIRS_FROM = ("est", "ref")
_UNIT_ALIASES = {"meters": "metres", "m": "metres", "s": "seconds", "deg": "degrees",
                 "f": "frames"}


@dataclass(frozen=True, eq=False)
class RpeResult(MatchedResult):
    """Relative errors over pose pairs ``(i, j)`` of the matched trajectories.

    Attributes
    ----------
    stamps_ns : ndarray, shape (M,), int64
        Reference stamp of each pair's start pose.
    first_index, second_index : ndarray, shape (M,), int
        Rows ``i`` and ``j`` of the pairs in ``est_aligned`` / ``ref``.
    errors_m : ndarray, shape (M,)
        ``||t(E)||`` with ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``, metres.
    errors_deg : ndarray, shape (M,)
        Rotation angle of ``E``, degrees.
    translation_m, rotation_deg : ErrorStats
        Statistics of the two error vectors.
    n_pairs : int
        Number of pairs ``M``.
    delta : float
        Pair distance, in ``delta_unit`` (frames, seconds, metres or degrees).
    pairs : str
        ``"consecutive"`` (non-overlapping, like evo) or ``"all"``.
    pose_relation : str
        The relation of :attr:`errors` / :attr:`stats` (default ``"trans"``).
    project_to_plane : str or None
        Plane both trajectories were projected to after alignment.
    pairs_from : str
        ``"est"`` (evo's default) or ``"ref"``: the trajectory whose path defines the pairs.
    rel_tol : float
        Relative tolerance on ``delta`` of ``pairs="all"`` (evo's ``--delta_tol``).
    alignment, est_aligned, ref, n_matched, n_dropped_est, n_dropped_ref, t_offset_s,
    interpolated
        How the trajectories were matched and aligned: see :class:`MatchedResult`.
    """

    stamps_ns: npt.NDArray[np.int64]
    first_index: npt.NDArray[np.intp]
    second_index: npt.NDArray[np.intp]
    errors_m: npt.NDArray[np.float64]
    errors_deg: npt.NDArray[np.float64]
    translation_m: ErrorStats
    rotation_deg: ErrorStats
    n_pairs: int
    delta: float
    delta_unit: str
    pairs: str
    pose_relation: str = "trans"
    project_to_plane: str | None = None
    pairs_from: str = "est"
    rel_tol: float = 0.1

    @property
    def errors(self) -> npt.NDArray[np.float64]:
        """Per-pair errors of :attr:`pose_relation` (evo's RPE ``error`` array)."""
        pd_m = None
        if self.pose_relation == "point-distance":
            i, j = self.first_index, self.second_index
            dr = np.linalg.norm(self.ref.pos_m[j] - self.ref.pos_m[i], axis=1)
            de = np.linalg.norm(self.est_aligned.pos_m[j] - self.est_aligned.pos_m[i], axis=1)
            pd_m = np.abs(dr - de)
        return relation_errors(self.pose_relation, self.errors_m, self.errors_deg,
                               point_distance_m=pd_m)

    @property
    def stats(self) -> ErrorStats:
        """Statistics of :attr:`errors`."""
        return ErrorStats.from_errors(self.errors)

    def plot(self, **kw: Any) -> Figure:
        """The figure of the relative errors (a new Figure): the trajectory coloured by the error, the error over time and
        distance, the histogram.  ``kw``: ``unit``, ``plane``, ``panels``, ``title``,
        ``gps_xyz_m`` of :func:`ibiscape_eval.report.plots.metric_figure`."""
        from ibiscape_eval.report.plots import metric_figure

        return metric_figure(self, **{"title": "relative pose error", **kw})

    def __repr__(self) -> str:
        return summary_repr(self, "RpeResult")

    def _repr_html_(self) -> str:
        return summary_html(self, "RPE")

    def to_frame(self, *, unit: str = "m") -> pd.DataFrame:
        """Per-pair rows: ``ref_stamp_ns, ref_t_s, first_index, second_index, error_m,
        error_deg`` (and ``error`` for a relation other than ``trans``); the stamp is the
        reference stamp of the pair's first pose.  Synthetic stamps give ``ref_pose_index``
        (of the first pose) instead of the two stamp columns; ``unit`` renames and scales
        ``error_m`` (``error_cm`` ...)."""
        import pandas as pd

        from .relations import RELATION_UNITS

        f = check_unit(unit)
        cols: dict[str, Any] = self._index_columns(self.stamps_ns, self.first_index)
        cols.update({
                "first_index": self.first_index,
                "second_index": self.second_index,
                f"error_{unit}": self.errors_m * f,
                "error_deg": self.errors_deg,
        })
        if self.pose_relation != "trans":
            rf = f if RELATION_UNITS[self.pose_relation] == "m" else 1.0
            cols["error"] = self.errors * rf
        return pd.DataFrame(cols)

    def to_dict(self, *, unit: str = "m") -> dict[str, Any]:
        """The JSON document the CLI prints (ATE's keys plus ``n_pairs, delta, delta_unit,
        pairs, delta_tol``); ``unit`` as in :meth:`AteResult.to_dict`."""
        f = check_unit(unit)
        doc = self._common_dict("rpe")
        doc.update(n_pairs=int(self.n_pairs), delta=float(self.delta),
                   delta_unit=self.delta_unit, pairs=self.pairs, pairs_from=self.pairs_from,
                   delta_tol=float(self.rel_tol))
        doc[f"translation_{unit}"] = scaled_stats(self.translation_m, f)
        doc["rotation_deg"] = self.rotation_deg.to_dict()
        doc.update(self._relation_dict(self.pose_relation, self.project_to_plane, self.stats,
                                       unit))
        if unit != "m":
            doc["length_unit"] = unit
        return doc


def _check_delta(delta: float, delta_unit: str) -> tuple[float, str]:
    unit = _UNIT_ALIASES.get(delta_unit, delta_unit)
    if unit not in DELTA_UNITS:
        raise IbiscapeError(
            f"unknown delta unit {delta_unit!r}; choose one of {', '.join(DELTA_UNITS)}"
        )
    try:
        d = float(delta)
    except (TypeError, ValueError):
        raise IbiscapeError(f"delta must be a number, got {delta!r}") from None
    if not (math.isfinite(d) and d > 0.0):
        raise IbiscapeError(f"delta must be a positive number of {unit}, got {delta!r}")
    if unit == "frames" and not d.is_integer():
        raise IbiscapeError(f"delta in frames must be a whole number, got {delta!r}")
    return d, unit


def select_pairs(
    traj: Trajectory,
    *,
    delta: float,
    delta_unit: str = "frames",
    pairs: str = "consecutive",
    rel_tol: float = 0.1,
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Start and end rows ``(i, j)`` of the pose pairs of ``traj`` ``delta`` apart.

    ``frames``: ``j = i + delta``.  ``seconds`` / ``metres`` / ``degrees``: measured along the
    path, by the time, the distance travelled or the cumulative rotation angle between
    consecutive poses.  ``consecutive``: non-overlapping pairs, each ending at the first pose
    where the accumulated quantity reaches ``delta`` (evo's pairs); ``all``: every start pose,
    ending at the pose whose accumulated quantity is closest to ``delta``, kept when within
    ``rel_tol * delta`` (evo's default tolerance 0.1).  O(n log n), no per-pose Python loop.
    """
    d, unit = _check_delta(delta, delta_unit)
    if pairs not in PAIR_MODES:
        raise IbiscapeError(f"unknown pair mode {pairs!r}; choose 'consecutive' or 'all'")
    all_pairs = pairs == "all"
    n = len(traj)
    if unit == "frames":
        return pairs_by_frames(n, int(d), all_pairs=all_pairs)
    if unit == "metres":
        steps = np.linalg.norm(traj.pos_m[:-1] - traj.pos_m[1:], axis=1)
        return pairs_by_steps(steps, d, all_pairs=all_pairs, rel_tol=rel_tol)
    if unit == "degrees":
        q = traj.quat_xyzw
        steps = angle_rad_from_quat(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
        return pairs_by_steps(steps, math.radians(d), all_pairs=all_pairs, rel_tol=rel_tol)
    steps = np.diff(traj.stamps_ns).astype(np.float64) / 1e9
    return pairs_by_steps(steps, d, all_pairs=all_pairs, rel_tol=rel_tol)


def _check_options(
    delta: float, delta_unit: str, pairs: str, pose_relation: str,
    project_to_plane: str | None, pairs_from: str, rel_tol: float,
) -> tuple[float, str, str | None]:
    """Validate the RPE options; return ``(delta, unit, plane)`` in canonical form."""
    d, unit = _check_delta(delta, delta_unit)
    if pairs not in PAIR_MODES:
        raise IbiscapeError(f"unknown pair mode {pairs!r}; choose 'consecutive' or 'all'")
    check_relation(pose_relation)
    plane = check_plane(project_to_plane)
    if pairs_from not in PAIRS_FROM:
        raise IbiscapeError(f"unknown pairs_from {pairs_from!r}; choose 'est' or 'ref'")
    if not (math.isfinite(rel_tol) and rel_tol >= 0.0):
        raise IbiscapeError(f"rel_tol must be a non-negative number, got {rel_tol!r}")
    return d, unit, plane


def _no_pair_error(delta: float, unit: str, pairs: str, on: Trajectory,
                   who: str) -> DegenerateInputError:
    """The error for a ``delta`` that yields no pose pair on ``on`` (named ``who``)."""
    extent = {
        "frames": f"{len(on)} matched poses",
        "seconds": f"{on.duration_s:.3f} s",
        "metres": f"{on.path_length_m()[-1]:.3f} m of path",
        "degrees": "its rotation",
    }[unit]
    return DegenerateInputError(
        f"delta = {delta:g} {unit} gives no pose pair ({pairs} pairs) on the {who} "
        f"({extent}); use a smaller {{0}}", hint=(Remedy("delta"),)
    )


def rpe(
    est: Trajectory, ref: Trajectory, *,
    delta: float = 1.0, delta_unit: str = "frames", pairs: str = "consecutive",
    align: str | Alignment = "none", n_align: int | None = None,
    max_diff_s: float = 0.01, offset_s: float = 0.0, estimate_offset: bool = False,
    interpolate: bool = False, match: str = "time", rel_tol: float = 0.1,
    pose_relation: str = "trans", project_to_plane: str | None = None, pairs_from: str = "est",
    t_start_s: float | None = None, t_end_s: float | None = None, downsample: int | None = None,
    motion_filter: tuple[float, float] | None = None,
) -> RpeResult:
    """Relative pose error of ``est`` against ``ref`` (evo's RPE).

    For each pair ``(i, j)`` chosen on the (aligned) estimate by :func:`select_pairs`,
    ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with ``Q`` the reference and ``P`` the estimate; the
    errors are ``||t(E)||`` (m) and ``angle(R(E))`` (deg).

    Parameters
    ----------
    est, ref : Trajectory
        Estimate and reference, poses ``T_world_body``.
    delta : float
        Distance between the poses of a pair, in ``delta_unit``.
    delta_unit : {"frames", "seconds", "metres", "degrees"}
        Unit of ``delta``.
    pairs : {"consecutive", "all"}
        Non-overlapping pairs (evo's default) or one pair per start pose.
    align, n_align, max_diff_s, offset_s, estimate_offset, interpolate, match
        As in :func:`ate` (alignment defaults to ``"none"``: RPE does not need one, except
        ``sim3`` for a monocular scale).
    rel_tol : float
        Relative tolerance on ``delta`` for ``pairs="all"`` in continuous units (evo's
        ``--delta_tol``, default 0.1).
    pose_relation : {"trans", "rot-angle", "rot-part", "full", "point-distance"}
        evo's pose relation of :attr:`RpeResult.errors` / ``stats``.
    project_to_plane : {"xy", "xz", "yz"}, optional
        Project both trajectories onto this plane after the alignment (as evo).
    pairs_from : {"est", "ref"}
        Which trajectory's path (distance, angle, time) defines the pairs: the estimate
        (evo's default) or the reference (what most papers mean by "RPE over 100 m").
    t_start_s, t_end_s, downsample, motion_filter
        evo's pose selection, as in :func:`ate`.

    Returns
    -------
    RpeResult

    Raises
    ------
    DegenerateInputError
        When ``delta`` yields no pair (the message gives the trajectory's extent).
    """
    d, unit, plane = _check_options(delta, delta_unit, pairs, pose_relation, project_to_plane,
                                    pairs_from, rel_tol)
    pre = prepare(est, ref, align=align, n_align=n_align, match=match, max_diff_s=max_diff_s,
                  offset_s=offset_s, estimate_offset=estimate_offset, interpolate=interpolate,
                  t_start_s=t_start_s, t_end_s=t_end_s, downsample=downsample,
                  motion_filter=motion_filter)
    m, al = pre.m, pre.al
    notes = emit(conditioning_warnings(al, who=pre.est.describe("estimate")))
    est_al = al.apply(m.est)
    if plane is not None:
        est_al = _project(est_al, plane)
        m = replace(m, ref=_project(m.ref, plane))
    on = est_al if pairs_from == "est" else m.ref
    i, j = select_pairs(on, delta=d, delta_unit=unit, pairs=pairs, rel_tol=rel_tol)
    if i.shape[0] == 0:
        who = pre.est.describe("estimate") if pairs_from == "est" else pre.ref.describe("reference")
        raise _no_pair_error(delta, unit, pairs, on, who)
    trans, rot = relative_errors(est_al, m.ref, i, j)
    rot_deg = np.degrees(rot, out=rot)
    return RpeResult(
        stamps_ns=frozen(m.ref.stamps_ns[i], owned=True), first_index=frozen(i, owned=True),
        second_index=frozen(j, owned=True), errors_m=frozen(trans, owned=True),
        errors_deg=frozen(rot_deg, owned=True), translation_m=ErrorStats.from_errors(trans),
        rotation_deg=ErrorStats.from_errors(rot_deg), n_pairs=int(i.shape[0]),
        delta=d, delta_unit=unit, pairs=pairs, pose_relation=pose_relation,
        project_to_plane=plane, pairs_from=pairs_from, rel_tol=float(rel_tol),
        **pre.fields(est_al, notes, m),
    )
