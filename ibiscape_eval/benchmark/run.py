"""``run_benchmark``: the whole paper on generated data, every step as batch jobs.

Steps, in order (each one batch over the suite's sequences; a job that fails is recorded with its
error and the others carry on):

1. ``suite``: the paper's 34 sequences (:mod:`ibiscape_eval.sim.suite`), or an existing suite;
2. ``camera_calibration``: every calibration sequence with cameras;
3. ``imu_camera``: camera-IMU extrinsics and time offsets of the same sequences;
4. ``imu_noise``: the Allan deviation of the still IMU;
5. ``hot_pixels``: every DVS camera (ESVI and FULL sequences);
6. ``vio``: the VIO baseline on every SLAM sequence, with the cameras of its setup (SVI: stereo
   RGB; ESVI: frames reconstructed from the stereo events; RGBD: RGB + depth; FULL: the best
   there is, :func:`ibiscape_eval.vio.inputs.resolve_setup`);
7. ``evaluation``: ATE and RPE (over 1 s) of every VIO estimate
   (:mod:`ibiscape_eval.report.evaluate`) in the layout of the paper's ``table:evaluation``, after
   4-DoF (position + yaw) alignment, the standard for VIO.

The result (:class:`BenchmarkResult`) is written by
:func:`ibiscape_eval.report.benchmark_report.write_benchmark_report` (HTML, Markdown, JSON).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ibiscape_eval.core.errors import IbiscapeError

from . import steps as step_functions
from .results import (
    STEP_VALUES,
    BenchmarkSteps,
    EvaluationScores,
    JsonRecord,
    StepRecord,
    SuiteSequence,
    VioResult,
)
from .steps import CALIBRATION_CAMERAS

if TYPE_CHECKING:
    from ibiscape_eval.batch import ContentCache, Executor, Job, JobResult
    from ibiscape_eval.report.evaluate import RunsEvaluation
    from ibiscape_eval.sim.suite import SuiteEntry

__all__ = ["STEPS", "BenchmarkResult", "StepProgress", "benchmark_jobs", "run_benchmark"]

STEPS = tuple(STEP_VALUES)
VIO_ALGORITHM = "vio-baseline"
#: the camera folders the VIO job of each setup reads (its cache inputs)
VIO_CAMERAS = {"svi": ("rgbL", "rgbR"), "esvi": ("davisL", "davisR"), "rgbd": ("rgb", "depth"),
               "full": ("rgb", "depth")}
#: 4-DoF (position + yaw) alignment, the standard for VIO (gravity is observed); a short
#: straight drive is collinear, which leaves SE(3) undetermined.
VIO_ALIGN = "yaw"

#: ``progress(step, done, failed, remaining)`` after every job of every step.
StepProgress = Callable[[str, int, int, int], None]
_Tick = Callable[[int, int, int], None]


@dataclass(frozen=True)
class BenchmarkResult:
    """Every step's job records, the VIO evaluation table and the wall time per step.

    Attributes
    ----------
    out : str
        The benchmark folder.
    suite : str
        The suite folder used.
    scale : float
    steps : BenchmarkSteps
        Per step, the records of its jobs (:class:`~.results.StepRecord`: key, sequence, status,
        error, seconds, cached and the typed value of :mod:`.results`).
    skipped : list of dict
        ``{step, sequence, reason}`` of sequences a step does not apply to.
    evaluation : dict or None
        The VIO runs in the paper's table (``ibiscape_eval.report.paper_table.PaperTable``):
        ``table`` (its ``to_dict()``), ``markdown``, ``html``, ``latex``; None when no estimate
        could be scored.
    wall_s : dict
        Step name -> wall time [s].
    figures : tuple of (file name, caption, png bytes)
        Top views of the VIO runs over the ground truth and GNSS, and error box plots (the
        ``report`` command's figures); not part of :meth:`to_dict`.
    """

    out: str
    suite: str
    scale: float
    steps: BenchmarkSteps
    skipped: list[dict[str, str]] = field(default_factory=list)
    evaluation: dict[str, Any] | None = None
    wall_s: dict[str, float] = field(default_factory=dict)
    figures: tuple[tuple[str, str, bytes], ...] = field(default=(), repr=False)

    @property
    def n_failed(self) -> int:
        return sum(not r.ok for _, recs in self.steps.items() for r in recs)

    @property
    def n_jobs(self) -> int:
        return sum(len(recs) for _, recs in self.steps.items())

    def failed(self) -> list[dict[str, Any]]:
        """``{step, key, error}`` of every failed job."""
        return [{"step": s, "key": r.key, "error": r.error}
                for s, recs in self.steps.items() for r in recs if not r.ok]

    def to_dict(self) -> dict[str, Any]:
        return {"out": self.out, "suite": self.suite, "scale": self.scale,
                "steps": self.steps.to_dict(),
                "skipped": [dict(s) for s in self.skipped], "evaluation": self.evaluation,
                "wall_s": dict(self.wall_s),
                "summary": {"n_jobs": self.n_jobs, "n_failed": self.n_failed}}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> BenchmarkResult:
        """Read :meth:`to_dict`'s document (``report.json``) back; the figures are not in it."""
        return cls(str(doc["out"]), str(doc["suite"]), float(doc["scale"]),
                   BenchmarkSteps.from_dict(doc["steps"]), [dict(s) for s in doc["skipped"]],
                   doc["evaluation"], dict(doc["wall_s"]))

    def __repr__(self) -> str:
        return (f"BenchmarkResult({self.out}: {self.n_jobs} jobs in {len(STEPS)} steps, "
                f"{self.n_failed} failed)")


def benchmark_jobs(entries: Sequence[SuiteEntry], suite_dir: str | os.PathLike[str]
                   ) -> tuple[dict[str, list[Job]], list[dict[str, str]]]:
    """The analysis jobs of every step (suite and evaluation excluded) and the skipped pairs."""
    from ibiscape_eval.batch import Job

    f = step_functions
    root = Path(suite_dir)
    jobs: dict[str, list[Job]] = {s: [] for s in STEPS[1:6]}
    skipped: list[dict[str, str]] = []
    for e in entries:
        seq = str(root / e.name)
        if e.setup == "imu":
            jobs["imu_noise"].append(Job(e.name, f.imu_noise, {"seq": seq}, inputs=(seq,)))
            continue
        if e.kind == "calibration":
            cams = CALIBRATION_CAMERAS[e.setup]
            jobs["camera_calibration"].append(Job(
                e.name, f.camera_calibration, {"seq": seq, "cameras": list(cams)},
                inputs=(*tuple(str(root / e.name / c) for c in cams), seq + "/sequence.yaml")))
            jobs["imu_camera"].append(Job(
                e.name, f.imu_camera_calibration, {"seq": seq, "cameras": list(cams)},
                inputs=(*tuple(str(root / e.name / c) for c in cams), seq + "/sequence.yaml",
                        seq + "/other_sensors")))
        else:
            cams = VIO_CAMERAS.get(e.setup, ("rgbL", "rgbR"))
            ins = tuple(str(root / e.name / p) for p in
                        (*cams, "other_sensors", "vehicle_gt", "sequence.yaml"))
            args = {"seq": seq} if e.setup == "svi" else {"seq": seq, "setup": e.setup}
            jobs["vio"].append(Job(e.name, f.vio, args, inputs=ins))
        if e.setup in ("esvi", "full"):
            for cam in ("davisL", "davisR"):
                d = str(root / e.name / cam)
                jobs["hot_pixels"].append(Job(f"{e.name}/{cam}", f.hot_pixels,
                                              {"seq": seq, "camera": cam},
                                              inputs=(d, seq + "/sequence.yaml")))
    return jobs, skipped


def _records(jobs: Sequence[Job], results: dict[str, JobResult], value_type: type[JsonRecord]
             ) -> tuple[StepRecord[Any], ...]:
    """The step's records: each job's outcome with its value read into ``value_type``."""
    return tuple(StepRecord(j.key, j.key.split("/")[0], r.status, r.error, round(r.seconds, 3),
                            r.cached, None if r.value is None else value_type.from_dict(r.value))
                 for j in jobs for r in (results[j.key],))


@dataclass(frozen=True)
class _Suite:
    """The suite step's outcome: where the sequences are, which, and their records."""

    root: Path
    scale: float
    entries: tuple[SuiteEntry, ...]
    records: tuple[StepRecord[SuiteSequence], ...]


def _generate_suite(out: Path, scale: float, seed: int, executor: Executor, tick: _Tick | None,
                    sequences: Sequence[str] | None) -> _Suite:
    from ibiscape_eval.sim.suite import run_suite, suite_entries

    root = out / "suite"
    res = run_suite(root, scale=scale, seed=seed, executor=executor, progress=tick, only=sequences)
    recs = tuple(StepRecord(s["name"], s["name"], s["status"], s["error"],
                            round(s.get("seconds", 0.0), 3), bool(s.get("reused")),
                            None if s.get("summary") is None
                            else SuiteSequence.from_dict(s["summary"]))
                 for s in res.sequences)
    return _Suite(root, scale, tuple(suite_entries(scale, seed=seed)), recs)


def _existing_suite(suite_dir: Path, scale: float) -> _Suite:
    from ibiscape_eval.sim.suite import read_manifest

    doc, entries = read_manifest(suite_dir)
    recs = []
    for e in entries:
        here = (suite_dir / e.name / "sequence.yaml").is_file()
        recs.append(StepRecord[SuiteSequence](
            e.name, e.name, "ok" if here else "failed",
            None if here else f"{suite_dir / e.name}: sequence missing from the suite folder",
            0.0, True, None))
    return _Suite(suite_dir, float(doc.get("scale", scale)), tuple(entries), tuple(recs))


def _check_request(out: Path, suite_dir: str | os.PathLike[str] | None, scale: float, seed: int,
                   sequences: Sequence[str] | None) -> None:
    """Refuse what cannot run before anything is written."""
    from ibiscape_eval.sim.suite import read_manifest, suite_entries

    if out.exists() and not out.is_dir():
        raise IbiscapeError(f"{out}: exists and is not a folder; choose another benchmark folder")
    known = (read_manifest(suite_dir)[1] if suite_dir is not None
             else suite_entries(scale, seed=seed))
    unknown = sorted(set(sequences or ()) - {e.name for e in known})
    if unknown:
        raise IbiscapeError(f"unknown suite sequence(s) {', '.join(unknown)}; the suite has "
                            f"{', '.join(e.name for e in known)}")


def run_benchmark(out_dir: str | os.PathLike[str], *, scale: float = 0.05,
                  suite_dir: str | os.PathLike[str] | None = None, seed: int = 0,
                  executor: Executor | None = None, cache: ContentCache | None = None,
                  progress: StepProgress | None = None,
                  sequences: Sequence[str] | None = None, figures: bool = True) -> BenchmarkResult:
    """Generate (or reuse) a suite and run every step of the paper on it.

    Parameters
    ----------
    out_dir : path
        Benchmark folder: ``suite/`` (unless ``suite_dir``), ``runs/`` (the VIO estimates in the
        ``report`` command's layout) and the report files written by the caller.
    scale : float in (0, 1]
        Suite scale (ignored with ``suite_dir``; the manifest's scale is used).
    suite_dir : path, optional
        An existing suite (``sim suite``'s folder with ``suite.json``).
    executor : Executor, optional
        Where every job runs (default: a local process pool).
    cache : ContentCache, optional
        Analysis results are cached by the content of their inputs.
    progress : callable, optional
        ``progress(step, done, failed, remaining)``.
    sequences : sequence of str, optional
        Only these suite sequences (quick runs, tests).
    figures : bool
        Draw the VIO figures (top views, error box plots).

    Returns
    -------
    BenchmarkResult
    """
    from ibiscape_eval.batch import LocalExecutor

    out = Path(out_dir)
    _check_request(out, suite_dir, scale, seed, sequences)
    out.mkdir(parents=True, exist_ok=True)
    ex: Executor = LocalExecutor() if executor is None else executor

    def tick(step: str) -> _Tick | None:
        if progress is None:
            return None
        return lambda d, f, r: progress(step, d, f, r)

    try:
        t0 = time.perf_counter()
        suite = (_generate_suite(out, scale, seed, ex, tick("suite"), sequences)
                 if suite_dir is None else _existing_suite(Path(suite_dir), scale))
        wall = {"suite": time.perf_counter() - t0}
        steps, skipped = _analyse(suite, sequences, ex, cache, tick, wall)
        t0 = time.perf_counter()
        steps, evaluation, figs = _evaluate(out, suite.root, steps, ex, cache,
                                            tick("evaluation"), figures)
        wall["evaluation"] = time.perf_counter() - t0
    finally:
        if executor is None:
            ex.close()
    return BenchmarkResult(str(out), str(suite.root), float(suite.scale), steps, skipped,
                           evaluation, {k: round(v, 3) for k, v in wall.items()}, tuple(figs))


def _analyse(suite: _Suite, sequences: Sequence[str] | None, ex: Executor,
             cache: ContentCache | None, tick: Callable[[str], _Tick | None],
             wall: dict[str, float]) -> tuple[BenchmarkSteps, list[dict[str, str]]]:
    """The analysis steps (camera_calibration ... vio) on the generated sequences of ``suite``;
    their wall times go into ``wall``."""
    from ibiscape_eval.batch import run_jobs

    entries, records = suite.entries, suite.records
    if sequences is not None:
        entries = tuple(e for e in entries if e.name in set(sequences))
        records = tuple(r for r in records if r.key in set(sequences))
    bad = {r.key for r in records if not r.ok}
    jobs, skipped = benchmark_jobs([e for e in entries if e.name not in bad], suite.root)
    skipped += [{"step": "all", "sequence": e.name,
                 "reason": "the sequence was not generated (see the suite step)"}
                for e in entries if e.name in bad]
    done: dict[str, tuple[StepRecord[Any], ...]] = {"suite": records}
    for step in STEPS[1:6]:
        t0 = time.perf_counter()
        results, _ = run_jobs(jobs[step], ex, cache=cache, progress=tick(step))
        done[step] = _records(jobs[step], results, STEP_VALUES[step])
        wall[step] = time.perf_counter() - t0
    return BenchmarkSteps(**done), skipped


def _write_estimates(runs: Path, vio: tuple[StepRecord[VioResult], ...]
                     ) -> tuple[tuple[StepRecord[VioResult], ...], int]:
    """Each VIO estimate as ``runs/<sequence>/vio-baseline/1/estimate.txt``; the records come
    back without the estimate text (it is in the files now), with the number written."""
    from ibiscape_eval.io.atomic import atomic_write

    out, n = [], 0
    for r in vio:
        if r.ok and r.value is not None:
            d = runs / r.sequence / VIO_ALGORITHM / "1"
            d.mkdir(parents=True, exist_ok=True)
            with atomic_write(d / "estimate.txt") as f:
                f.write(r.value.estimate_tum or "")
            n += 1
            r = replace(r, value=replace(r.value, estimate_tum=None))
        out.append(r)
    return tuple(out), n


def _evaluate(out: Path, suite_dir: Path, steps: BenchmarkSteps, executor: Executor,
              cache: ContentCache | None, progress: _Tick | None, figures: bool
              ) -> tuple[BenchmarkSteps, dict[str, Any] | None, list[tuple[str, str, bytes]]]:
    """Write the VIO estimates as a runs folder and score them with the report's evaluation."""
    from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
    from ibiscape_eval.report.paper_table import PaperTable
    from ibiscape_eval.report.runs import discover_runs

    runs = out / "runs"
    vio, n = _write_estimates(runs, steps.vio)
    if n == 0:
        return replace(steps, vio=vio, evaluation=()), None, []
    layout = discover_runs(runs, sequences_dir=suite_dir)
    ev = evaluate_runs(layout, EvaluationOptions(align=VIO_ALIGN, max_diff_s=0.02, rpe_delta=1.0,
                                                 rpe_delta_unit="seconds"),
                       executor=executor, cache=cache, progress=progress)
    scores = tuple(StepRecord(f"{r['sequence']}/{r['algorithm']}/{r['trial']}", r["sequence"],
                              r["status"], r["error"], 0.0, False, _scores(r)) for r in ev.runs)
    figs = _figures(ev) if figures else []
    table = PaperTable.from_runs(ev.runs)
    return replace(steps, vio=vio, evaluation=scores), {
        "table": json.loads(json.dumps(table.to_dict())), "markdown": table.to_markdown(),
        "html": table.to_html(),
        "latex": table.to_latex(caption="Stereo-VIO baseline on the generated SLAM sequences.")
    }, figs


def _scores(run: dict[str, Any]) -> EvaluationScores:
    return EvaluationScores(_get(run, "ate", "translation_m", "rmse"),
                            _get(run, "rpe", "translation_m", "mean"),
                            _get(run, "rpe", "rotation_deg", "mean"), run.get("n_matched"))


def _figures(ev: RunsEvaluation) -> list[tuple[str, str, bytes]]:
    import warnings

    from ibiscape_eval.core.errors import IbiscapeWarning
    from ibiscape_eval.report.batch_report import sequence_figures

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IbiscapeWarning)
        return sequence_figures(ev)


def _get(doc: Any, *path: str) -> Any:
    for p in path:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(p)
    return doc
