"""Evaluate every run of a runs folder (ATE, RPE, drift) as batch jobs.

:func:`evaluate_run` is the job function (JSON in, JSON out, so it runs anywhere: this process, a
local pool, a Dask worker); :func:`evaluate_runs` builds one job per run, runs them through
:mod:`ibiscape_eval.batch` and collects a :class:`RunsEvaluation`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.batch import ContentCache, Executor, Job, Progress, run_jobs
from ibiscape_eval.core.errors import IbiscapeError, IbiscapeWarning, Remedy
from ibiscape_eval.core.numbers import finite_or_none

from .runs import RunsLayout, RunSpec

__all__ = [
    "EvaluationOptions",
    "RunsEvaluation",
    "box_stats",
    "evaluate_run",
    "evaluate_runs",
    "resolve_alignments",
    "run_job_for",
]

ALIGNMENTS = ("none", "origin", "se3", "sim3", "yaw")
TRACK_POINTS = 400  # aligned estimate positions kept per run for the trajectory figures


@dataclass(frozen=True)
class EvaluationOptions:
    """Metric options shared by every run (the ``report`` command's options).

    ``align`` applies to ATE, RPE and drift alike (only ``sim3`` changes RPE and drift: it fixes
    the scale); it is the default of every algorithm that neither ``align_by_algorithm`` (name,
    alignment pairs, the command line's ``--align NAME=A``) nor a ``run.yaml`` of its runs names
    (see :func:`resolve_alignments`).  RPE pairs are ``rpe_delta`` ``rpe_delta_unit`` apart;
    drift segments are ``drift_lengths_pct`` percent of each reference path
    (rpg_trajectory_evaluation's choice).
    """

    align: str = "se3"
    max_diff_s: float = 0.01
    rpe_delta: float = 1.0
    rpe_delta_unit: str = "frames"
    rpe_pairs: str = "consecutive"
    drift_lengths_pct: tuple[float, ...] = (10.0, 20.0, 30.0, 40.0, 50.0)
    align_by_algorithm: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        for a in (self.align, *(a for _, a in self.align_by_algorithm)):
            if a not in ALIGNMENTS:
                raise IbiscapeError(f"unknown alignment {a!r}; use one of "
                                    f"{', '.join(ALIGNMENTS)}")
        names = [n for n, _ in self.align_by_algorithm]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise IbiscapeError(f"alignment of {', '.join(dup)} given more than once")

    def to_dict(self) -> dict[str, Any]:
        doc = {"align": self.align, "max_diff_s": self.max_diff_s, "rpe_delta": self.rpe_delta,
               "rpe_delta_unit": self.rpe_delta_unit, "rpe_pairs": self.rpe_pairs,
               "drift_lengths_pct": list(self.drift_lengths_pct)}
        if self.align_by_algorithm:
            doc["align_by_algorithm"] = dict(self.align_by_algorithm)
        return doc

    def for_run(self, align: str) -> EvaluationOptions:
        """These options with ``align`` for one run (what its batch job gets)."""
        return EvaluationOptions(align, self.max_diff_s, self.rpe_delta, self.rpe_delta_unit,
                                 self.rpe_pairs, self.drift_lengths_pct)


def resolve_alignments(
    layout: RunsLayout, options: EvaluationOptions
) -> dict[str, tuple[str, str]]:
    """The alignment of every algorithm of ``layout`` and where it comes from.

    In order: ``options.align_by_algorithm`` (``--align NAME=A``), the ``run.yaml`` of its runs
    (:mod:`ibiscape_eval.io.run_meta`), ``options.align``.

    Returns
    -------
    dict
        Algorithm -> (alignment, source): ``"--align NAME=A"``, the ``run.yaml`` path, or
        ``"default"``.

    Raises
    ------
    IbiscapeError
        ``align_by_algorithm`` names an algorithm the layout does not have (a misspelt name would
        otherwise leave the run with the default), or the runs of one algorithm ask for different
        alignments (the table gives one number per algorithm and its caption one alignment).
    """
    algs = layout.algorithms
    by_name = dict(options.align_by_algorithm)
    unknown = [n for n in by_name if n not in algs]
    if unknown:
        raise IbiscapeError(
            f"{{0}}: no algorithm {unknown[0]!r} in {layout.root} (algorithms: {', '.join(algs)})",
            hint=(Remedy("align_by_algorithm", f"{unknown[0]}={by_name[unknown[0]]}"),))
    out: dict[str, tuple[str, str]] = {}
    for alg in algs:
        if alg in by_name:
            out[alg] = (by_name[alg], f"--align {alg}={by_name[alg]}")
            continue
        asked: dict[str, list[RunSpec]] = {}
        for r in layout.runs:
            if r.algorithm == alg:
                asked.setdefault(r.align or options.align, []).append(r)
        if len(asked) > 1:
            what = "; ".join(
                f"{a} for {len(rs)} run{'s' if len(rs) > 1 else ''} (e.g. "
                f"{rs[0].meta_path or rs[0].key + ', the default'})" for a, rs in asked.items())
            raise IbiscapeError(
                f"algorithm {alg}: its runs ask for different alignments ({what}); one alignment "
                "per algorithm: fix the run.yaml files or give {0}",
                hint=(Remedy("align_by_algorithm", f"{alg}=A"),))
        ((align, runs),) = asked.items()
        meta = next((r.meta_path for r in runs if r.align is not None and r.meta_path), None)
        out[alg] = (align, meta or "default")
    return out


def box_stats(values: npt.ArrayLike) -> dict[str, float] | None:
    """Tukey box-plot statistics: quartiles and whiskers at the furthest data within 1.5 IQR
    (the keys matplotlib's ``Axes.bxp`` takes: ``med, q1, q3, whislo, whishi``)."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return None
    q1, med, q3 = (float(v) for v in np.percentile(x, [25.0, 50.0, 75.0]))
    iqr = q3 - q1
    lo = x[x >= q1 - 1.5 * iqr]
    hi = x[x <= q3 + 1.5 * iqr]
    return {"med": med, "q1": q1, "q3": q3, "whislo": float(lo.min()), "whishi": float(hi.max())}


def evaluate_run(
    *,
    est: str,
    ref: str,
    times_est: str | None = None,
    options: dict[str, Any],
) -> dict[str, Any]:
    """ATE, RPE and drift of one estimate against its ground truth (a batch job function).

    Parameters
    ----------
    est, ref : str
        Trajectory files (format detected as by ``ibiscape-eval ate``).
    times_est : str, optional
        KITTI times file of ``est``; KITTI poses without one are paired by index.
    options : dict
        :meth:`EvaluationOptions.to_dict`.

    Returns
    -------
    dict
        ``format`` (of ``est``), ``warnings`` (of the readers), ``n_matched``, ``ate`` and ``rpe`` (the ``ate``/``rpe`` commands' JSON), ``drift`` (its
        averages, or None with ``drift_error`` when no segment fits), ``track_xyz_m`` (at most
        400 aligned estimate positions, for figures) and ``box`` (box-plot statistics of the
        per-pose ATE and per-pair RPE errors).
    """
    from ibiscape_eval.io import detect_trajectory_format, read_trajectory
    from ibiscape_eval.metrics import ate, drift, rpe

    o = EvaluationOptions(**{**options, "drift_lengths_pct": tuple(options["drift_lengths_pct"])})
    fmt_est = detect_trajectory_format(est)
    # Reader and alignment warnings (rows skipped, duplicate stamps, an alignment that dominates
    # the rotation error) travel with the result, so they reach the user from a pool or cluster
    # worker too, instead of being printed raw by the worker.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IbiscapeWarning)
        est_t = read_trajectory(est, fmt_est, times_path=times_est)
        ref_t = read_trajectory(ref)
        match = "index" if fmt_est == "kitti" and times_est is None else "time"
        common: dict[str, Any] = {"align": o.align, "max_diff_s": o.max_diff_s, "match": match}
        a = ate(est_t, ref_t, **common)
        r = rpe(est_t, ref_t, delta=o.rpe_delta, delta_unit=o.rpe_delta_unit, pairs=o.rpe_pairs,
                **common)
    doc: dict[str, Any] = {
        "format": fmt_est,
        "warnings": [" ".join(str(w.message).split()) for w in caught
                     if issubclass(w.category, IbiscapeWarning)],
        "n_matched": int(a.n_matched),
        "ate": a.to_dict(),
        "rpe": r.to_dict(),
    }
    try:
        d = drift(est_t, ref_t, lengths_m=None, lengths_pct=o.drift_lengths_pct, **common)
    except IbiscapeError as e:
        doc["drift"], doc["drift_error"] = None, " ".join(str(e).split())
    else:
        doc["drift"] = {
            "lengths_m": [float(x) for x in d.lengths_m],
            "n_segments": [int(x) for x in d.n_segments],
            "mean_translation_pct": finite_or_none(float(d.mean_translation_pct)),
            "mean_rotation_deg_per_m": finite_or_none(float(d.mean_rotation_deg_per_m)),
        }
    pos = a.est_aligned.pos_m
    keep = np.unique(np.linspace(0, len(pos) - 1, min(len(pos), TRACK_POINTS)).round().astype(int))
    doc["track_xyz_m"] = np.round(pos[keep], 4).tolist()  # 0.1 mm is plenty for a figure
    doc["box"] = {
        "ate_m": box_stats(a.errors_m),
        "rpe_m": box_stats(r.errors_m),
        "rpe_deg": box_stats(r.errors_deg),
    }
    return doc  # strict JSON: the metrics' to_dict() hold no NaN; drift's means are mapped


def run_job_for(run: RunSpec, groundtruth: str, options: EvaluationOptions) -> Job:
    """The batch job that evaluates ``run`` against ``groundtruth`` with ``options`` (give it
    :meth:`EvaluationOptions.for_run` of the run's alignment)."""
    inputs = [run.path, groundtruth] + ([run.times_path] if run.times_path else [])
    return Job(
        key=run.key,
        func=evaluate_run,
        params={"est": run.path, "ref": groundtruth, "times_est": run.times_path,
                "options": options.to_dict()},
        inputs=tuple(inputs),
    )


@dataclass(frozen=True)
class RunsEvaluation:
    """Every run's result.

    Attributes
    ----------
    layout : RunsLayout
        What was evaluated.
    options : EvaluationOptions
    runs : tuple of dict
        Per run, in layout order: ``sequence, algorithm, trial, path, align, status
        ("ok"/"failed"), error, cached, n_matched, ate, rpe, drift`` and the figure data
        (``track_xyz_m``, ``box``).
    alignments : dict
        Algorithm -> (alignment, source), see :func:`resolve_alignments`.
    """

    layout: RunsLayout
    options: EvaluationOptions
    runs: tuple[dict[str, Any], ...]
    summary: dict[str, int] = field(default_factory=dict)
    alignments: dict[str, tuple[str, str]] = field(default_factory=dict)

    @property
    def n_failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.runs)

    def to_dict(self) -> dict[str, Any]:
        """The ``report --json`` document: ``runs`` (without figure data and cache flags, so
        it does not depend on where or whether a run was computed), ``options``,
        ``alignments`` (algorithm -> ``{"align", "source"}``), ``summary``, ``ignored``."""
        slim = [{k: v for k, v in r.items() if k not in ("track_xyz_m", "box", "cached")}
                for r in self.runs]
        return {
            "runs_dir": self.layout.root,
            "options": self.options.to_dict(),
            "alignments": {a: {"align": al, "source": src}
                           for a, (al, src) in self.alignments.items()},
            "summary": dict(self.summary),
            "runs": slim,
            "ignored": [{"path": p, "reason": why} for p, why in self.layout.ignored],
        }

    def __repr__(self) -> str:
        return f"RunsEvaluation({len(self.runs)} runs, {self.n_failed} failed)"


def evaluate_runs(
    layout: RunsLayout,
    options: EvaluationOptions | None = None,
    *,
    executor: Executor | None = None,
    cache: ContentCache | None = None,
    progress: Progress | None = None,
) -> RunsEvaluation:
    """Evaluate every run of ``layout`` (one batch job each; failed runs are recorded, not raised).

    Parameters
    ----------
    layout : RunsLayout
        From :func:`~ibiscape_eval.report.runs.discover_runs`.
    options : EvaluationOptions, optional
    executor, cache, progress
        See :func:`ibiscape_eval.batch.run_jobs` (default: a local process pool, no cache).
    """
    o = options or EvaluationOptions()
    aligns = resolve_alignments(layout, o)
    jobs = [run_job_for(r, layout.truths[r.sequence].groundtruth,
                        o.for_run(aligns[r.algorithm][0])) for r in layout.runs]
    results, summary = run_jobs(jobs, executor, cache=cache, progress=progress)
    runs: list[dict[str, Any]] = []
    for spec in layout.runs:
        res = results[spec.key]
        rec: dict[str, Any] = {
            "sequence": spec.sequence,
            "algorithm": spec.algorithm,
            "trial": spec.trial,
            "path": spec.path,
            "align": aligns[spec.algorithm][0],
            "status": res.status,
            "error": res.error,
            "cached": res.cached,
            "n_matched": None,
            "ate": None,
            "rpe": None,
            "drift": None,
        }
        if res.ok and res.value is not None:
            rec.update(res.value)
        runs.append(rec)
    return RunsEvaluation(layout, o, tuple(runs), summary.to_dict(), aligns)

