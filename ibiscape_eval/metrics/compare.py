"""Several estimates against one reference: ATE and RPE of each, one table, saved results.

``compare(ref, [est1, est2, ...])`` runs :func:`ate` and :func:`rpe` with the same options on
every estimate.  :meth:`CompareResult.save` writes one directory a later report can read back
without this library (like evo's ``--save_results``, but JSON and CSV instead of a zip of
pickles)::

    DIR/compare.json          index: reference, options, one row per estimate (label, files,
                              headline numbers)
    DIR/<label>.ate.json      AteResult.to_dict() plus "label", "est_file", "ref_file"
    DIR/<label>.ate.csv       AteResult.to_frame() (ref_stamp_ns, ref_t_s, est_stamp_ns, ...)
    DIR/<label>.rpe.json      RpeResult.to_dict() plus "label", "est_file", "ref_file"
    DIR/<label>.rpe.csv       RpeResult.to_frame()
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ibiscape_eval.core import IbiscapeError, Trajectory
from ibiscape_eval.core.numbers import finite_or_none

from .ate import AteResult, ate
from .rpe import RpeResult, rpe

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["CompareEntry", "CompareResult", "compare", "safe_label"]


def safe_label(label: str) -> str:
    """``label`` reduced to characters safe in a file name (others become ``_``)."""
    out = re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("._")
    return out or "estimate"


@dataclass(frozen=True, eq=False)
class CompareEntry:
    """One estimate's results: its label, file name and the ATE / RPE results."""

    label: str
    est_file: str
    ate: AteResult
    rpe: RpeResult

    def to_dict(self) -> dict[str, Any]:
        return {
            "label": self.label,
            "est_file": self.est_file,
            "ate_rmse_m": self.ate.translation_m.rmse,
            "ate_rot_rmse_deg": self.ate.rotation_deg.rmse,
            "ate_error_rmse": self.ate.stats.rmse,
            "rpe_rmse_m": self.rpe.translation_m.rmse,
            "rpe_rot_rmse_deg": self.rpe.rotation_deg.rmse,
            "rpe_error_rmse": self.rpe.stats.rmse,
            "n_matched": self.ate.n_matched,
            "n_pairs": self.rpe.n_pairs,
            "stamps": "synthetic" if self.ate.stamps_synthetic else "measured",
            "ate_rotation_sigma_deg": (
                None if self.ate.alignment.conditioning is None
                else self.ate.alignment.conditioning.to_dict()["rotation_sigma_total_deg"]),
            "warnings": list(dict.fromkeys(self.ate.warnings + self.rpe.warnings)),
        }


@dataclass(frozen=True, eq=False)
class CompareResult:
    """ATE and RPE of several estimates against one reference (same options for all)."""

    ref_file: str
    entries: tuple[CompareEntry, ...]
    options: dict[str, Any]

    def to_frame(self) -> pd.DataFrame:
        """One row per estimate, indexed by label: the headline numbers of :meth:`to_dict`."""
        import pandas as pd

        return pd.DataFrame([e.to_dict() for e in self.entries]).set_index("label")

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON index document (what ``compare.json`` holds, without file names)."""
        return {"metric": "compare", "ref_file": self.ref_file, "options": dict(self.options),
                "estimates": [e.to_dict() for e in self.entries]}

    def plot(self, *, plane: str = "xy", title: str = "") -> Figure:
        """Every aligned estimate over the reference and their error bars (a new Figure)."""
        from ibiscape_eval.report.plots import compare_figure

        return compare_figure(self, plane=plane,
                              title=title or f"{len(self.entries)} estimates against the reference")

    def __repr__(self) -> str:
        rows = [f"CompareResult(ref={self.ref_file!r}, {len(self.entries)} estimates"]
        for e in self.entries:
            rows.append(f"  {e.label}: ATE rmse {e.ate.translation_m.rmse:.6g} m, "
                        f"RPE rmse {e.rpe.translation_m.rmse:.6g} m, "
                        f"{e.ate.n_matched} matched")
        return "\n".join(rows) + ")"

    def _repr_html_(self) -> str:
        frame: Any = self.to_frame()
        return str(frame.to_html())

    def save(self, directory: str | os.PathLike[str]) -> list[Path]:
        """Write the layout of the module docstring into ``directory`` (created if needed);
        every file atomically.  Returns the written paths."""
        from ibiscape_eval.io.results import write_result_csv, write_result_json

        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        written: list[Path] = []
        index = self.to_dict()
        for e, row in zip(self.entries, index["estimates"], strict=True):
            stem = safe_label(e.label)
            extra = {"label": e.label, "est_file": e.est_file, "ref_file": self.ref_file}
            for kind, res in (("ate", e.ate), ("rpe", e.rpe)):
                jp, cp = out / f"{stem}.{kind}.json", out / f"{stem}.{kind}.csv"
                write_result_json(jp, {**res.to_dict(), **extra})
                write_result_csv(cp, res.to_frame())
                row[f"{kind}_json"], row[f"{kind}_csv"] = jp.name, cp.name
                written += [jp, cp]
        ip = out / "compare.json"
        write_result_json(ip, _strict_json(index))
        written.append(ip)
        return written


def _strict_json(doc: Any) -> Any:
    """NaN floats as None, recursively (strict JSON)."""
    if isinstance(doc, dict):
        return {k: _strict_json(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_strict_json(v) for v in doc]
    return finite_or_none(doc) if isinstance(doc, float) else doc


def compare(
    ref: Trajectory,
    estimates: Sequence[Trajectory],
    *,
    labels: Sequence[str] | None = None,
    ref_file: str = "",
    est_files: Sequence[str] | None = None,
    align: str = "se3",
    rpe_align: str = "none",
    delta: float = 1.0,
    delta_unit: str = "frames",
    pairs: str = "consecutive",
    pairs_from: str = "est",
    pose_relation: str = "trans",
    project_to_plane: str | None = None,
    rel_tol: float = 0.1,
    **match_kw: Any,
) -> CompareResult:
    """ATE (``align``) and RPE (``rpe_align``, ``delta`` in ``delta_unit``, ``rel_tol``) of every
    estimate against ``ref`` with the same options; ``labels`` default to the trajectories' names
    (made unique).  ``match_kw`` are the matching and selection options :func:`ate` and
    :func:`rpe` share (``max_diff_s``, ``offset_s``, ``estimate_offset``, ``interpolate``,
    ``match``, ``n_align``, ``t_start_s``, ``t_end_s``, ``downsample``, ``motion_filter``).
    Each estimate's warnings (alignment conditioning ...) are in its entry's ``to_dict()``."""
    if not estimates:
        raise IbiscapeError("compare needs at least one estimate")
    if labels is None:
        labels = [e.name or f"est{k + 1}" for k, e in enumerate(estimates)]
    labels = list(labels)
    if len(labels) != len(estimates):
        raise IbiscapeError(f"got {len(labels)} labels for {len(estimates)} estimates")
    stems = [safe_label(lb) for lb in labels]
    if len(set(stems)) != len(stems):
        raise IbiscapeError(f"labels must be distinct (as file names): {', '.join(labels)}")
    files = list(est_files) if est_files is not None else [e.name for e in estimates]
    entries = []
    for est, label, f in zip(estimates, labels, files, strict=True):
        a = ate(est, ref, align=align, pose_relation=pose_relation,
                project_to_plane=project_to_plane, **match_kw)
        r = rpe(est, ref, delta=delta, delta_unit=delta_unit, pairs=pairs, align=rpe_align,
                pose_relation=pose_relation, project_to_plane=project_to_plane,
                pairs_from=pairs_from, rel_tol=rel_tol, **match_kw)
        entries.append(CompareEntry(label=label, est_file=f, ate=a, rpe=r))
    options = {"align": align, "rpe_align": rpe_align, "delta": float(delta),
               "delta_unit": delta_unit, "pairs": pairs, "pairs_from": pairs_from,
               "pose_relation": pose_relation, "project_to_plane": project_to_plane,
               "delta_tol": float(rel_tol),
               **{k: v for k, v in match_kw.items() if isinstance(v, str | int | float | bool)}}
    return CompareResult(ref_file=ref_file or ref.name, entries=tuple(entries), options=options)

