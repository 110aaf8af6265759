"""Absolute trajectory error (ATE / evo's APE) after alignment."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import Trajectory
from ibiscape_eval.core.time import s_from_ns

from ._common import MatchedResult, absolute_errors, aligned_errors, frozen, matched_fields
from ._common import match as _match
from ._stats import ErrorStats
from .alignment import Alignment
from .alignment import align as _align
from .relations import check_plane, check_relation, relation_errors
from .relations import project_to_plane as _project
from .summary import summary_html, summary_repr

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

    def __repr__(self) -> str:
        return summary_repr(self, "AteResult")

    def _repr_html_(self) -> str:
        return summary_html(self, "ATE")

    def to_frame(self) -> pd.DataFrame:
        """Per-pose rows: ``ref_stamp_ns, ref_t_s, est_stamp_ns, error_m, error_deg,
        est_{x,y,z}_m, ref_{x,y,z}_m`` (and ``error`` for a relation other than ``trans``).

        ``ref_stamp_ns`` is the matched reference pose's stamp, ``est_stamp_ns`` the estimate's
        (after any time offset); ``ref_t_s`` is the reference stamp in seconds."""
        import pandas as pd

        e, r = self.est_aligned.pos_m, self.ref.pos_m
        cols: dict[str, Any] = {
                "ref_stamp_ns": self.stamps_ns,
                "ref_t_s": s_from_ns(self.stamps_ns),
                "est_stamp_ns": self.est_aligned.stamps_ns,
                "error_m": self.errors_m,
                "error_deg": self.errors_deg,
                "est_x_m": e[:, 0], "est_y_m": e[:, 1], "est_z_m": e[:, 2],
                "ref_x_m": r[:, 0], "ref_y_m": r[:, 1], "ref_z_m": r[:, 2],
        }
        if self.pose_relation != "trans":
            cols["error"] = self.errors
        return pd.DataFrame(cols)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document the CLI prints (see the package docs for the contract)."""
        doc = self._common_dict("ate")
        doc["n_align"] = int(self.alignment.n_used)
        doc["translation_m"] = self.translation_m.to_dict()
        doc["rotation_deg"] = self.rotation_deg.to_dict()
        doc.update(self._relation_dict(self.pose_relation, self.project_to_plane, self.stats))
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
    pose_relation: str = "trans",
    project_to_plane: str | None = None,
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

    Returns
    -------
    AteResult
    """
    check_relation(pose_relation)
    plane = check_plane(project_to_plane)
    m = _match(est, ref, match=match, max_diff_s=max_diff_s, offset_s=offset_s,
               estimate_offset=estimate_offset, interpolate=interpolate)
    al = _align(m.est, m.ref, method=align, n_align=n_align)
    est_al, trans, rot = aligned_errors(al, m.est, m.ref)
    if plane is not None:
        est_al, ref_p = _project(est_al, plane), _project(m.ref, plane)
        trans, rot = absolute_errors(est_al, ref_p)
        m = replace(m, ref=ref_p)
    rot_deg = np.degrees(rot, out=rot)
    return AteResult(
        stamps_ns=frozen(m.ref.stamps_ns),
        errors_m=frozen(trans, owned=True),
        errors_deg=frozen(rot_deg, owned=True),
        translation_m=ErrorStats.from_errors(trans),
        rotation_deg=ErrorStats.from_errors(rot_deg),
        pose_relation=pose_relation,
        project_to_plane=plane,
        **matched_fields(m, al, est_al),
    )

