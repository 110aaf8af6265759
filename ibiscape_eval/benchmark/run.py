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
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ibiscape_eval.core.errors import IbiscapeError

from .steps import CALIBRATION_CAMERAS

if TYPE_CHECKING:
    from ibiscape_eval.batch import ContentCache, Executor, Job
    from ibiscape_eval.sim.suite import SuiteEntry

__all__ = ["STEPS", "BenchmarkResult", "StepProgress", "benchmark_jobs", "run_benchmark"]

STEPS = ("suite", "camera_calibration", "imu_camera", "imu_noise", "hot_pixels", "vio",
         "evaluation")
_MOD = "ibiscape_eval.benchmark.steps"
VIO_ALGORITHM = "vio-baseline"
#: the camera folders the VIO job of each setup reads (its cache inputs)
VIO_CAMERAS = {"svi": ("rgbL", "rgbR"), "esvi": ("davisL", "davisR"), "rgbd": ("rgb", "depth"),
               "full": ("rgb", "depth")}
#: 4-DoF (position + yaw) alignment, the standard for VIO (gravity is observed); a short
#: straight drive is collinear, which leaves SE(3) undetermined.
VIO_ALIGN = "yaw"

#: ``progress(step, done, failed, remaining)`` after every job of every step.
StepProgress = Callable[[str, int, int, int], None]


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
    steps : dict
        Step name -> list of records ``{key, sequence, status, error, seconds, cached, value}``.
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
    steps: dict[str, list[dict[str, Any]]]
    skipped: list[dict[str, str]] = field(default_factory=list)
    evaluation: dict[str, Any] | None = None
    wall_s: dict[str, float] = field(default_factory=dict)
    figures: tuple[tuple[str, str, bytes], ...] = field(default=(), repr=False)

    @property
    def n_failed(self) -> int:
        return sum(r["status"] != "ok" for recs in self.steps.values() for r in recs)

    @property
    def n_jobs(self) -> int:
        return sum(len(recs) for recs in self.steps.values())

    def failed(self) -> list[dict[str, Any]]:
        """``{step, key, error}`` of every failed job."""
        return [{"step": s, "key": r["key"], "error": r["error"]}
                for s, recs in self.steps.items() for r in recs if r["status"] != "ok"]

    def to_dict(self) -> dict[str, Any]:
        return {"out": self.out, "suite": self.suite, "scale": self.scale,
                "steps": {k: [dict(r) for r in v] for k, v in self.steps.items()},
                "skipped": [dict(s) for s in self.skipped], "evaluation": self.evaluation,
                "wall_s": dict(self.wall_s),
                "summary": {"n_jobs": self.n_jobs, "n_failed": self.n_failed}}

    def tables_dict(self) -> dict[str, Any]:
        """The result without timings and cache flags: equal for equal inputs wherever the jobs
        ran (local pool or Dask cluster)."""
        steps = {k: [{"key": r["key"], "status": r["status"], "error": r["error"],
                      "value": r["value"]} for r in v] for k, v in self.steps.items()}
        return {"scale": self.scale, "steps": steps, "skipped": self.skipped,
                "evaluation": self.evaluation}

    def __repr__(self) -> str:
        return (f"BenchmarkResult({self.out}: {self.n_jobs} jobs in {len(self.steps)} steps, "
                f"{self.n_failed} failed)")


def benchmark_jobs(entries: Sequence[SuiteEntry], suite_dir: str | os.PathLike[str]
                   ) -> tuple[dict[str, list[Job]], list[dict[str, str]]]:
    """The analysis jobs of every step (suite and evaluation excluded) and the skipped pairs."""
    from ibiscape_eval.batch import Job

    root = Path(suite_dir)
    jobs: dict[str, list[Job]] = {s: [] for s in STEPS[1:6]}
    skipped: list[dict[str, str]] = []
    for e in entries:
        seq = str(root / e.name)
        if e.setup == "imu":
            jobs["imu_noise"].append(Job(e.name, f"{_MOD}:imu_noise", {"seq": seq}, inputs=(seq,)))
            continue
        if e.kind == "calibration":
            cams = CALIBRATION_CAMERAS[e.setup]
            jobs["camera_calibration"].append(Job(
                e.name, f"{_MOD}:camera_calibration", {"seq": seq, "cameras": list(cams)},
                inputs=(*tuple(str(root / e.name / c) for c in cams), seq + "/sequence.yaml")))
            jobs["imu_camera"].append(Job(
                e.name, f"{_MOD}:imu_camera_calibration", {"seq": seq, "cameras": list(cams)},
                inputs=(*tuple(str(root / e.name / c) for c in cams), seq + "/sequence.yaml",
                        seq + "/other_sensors")))
        else:
            cams = VIO_CAMERAS.get(e.setup, ("rgbL", "rgbR"))
            ins = tuple(str(root / e.name / p) for p in
                        (*cams, "other_sensors", "vehicle_gt", "sequence.yaml"))
            args = {"seq": seq} if e.setup == "svi" else {"seq": seq, "setup": e.setup}
            jobs["vio"].append(Job(e.name, f"{_MOD}:vio", args, inputs=ins))
        if e.setup in ("esvi", "full"):
            for cam in ("davisL", "davisR"):
                d = str(root / e.name / cam)
                jobs["hot_pixels"].append(Job(f"{e.name}/{cam}", f"{_MOD}:hot_pixels",
                                              {"seq": seq, "camera": cam},
                                              inputs=(d, seq + "/sequence.yaml")))
    return jobs, skipped


def _records(jobs: Sequence[Job], results: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    for j in jobs:
        r = results[j.key]
        out.append({"key": j.key, "sequence": j.key.split("/")[0], "status": r.status,
                    "error": r.error, "seconds": round(r.seconds, 3), "cached": r.cached,
                    "value": r.value})
    return out


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
    from ibiscape_eval.batch import LocalExecutor, run_jobs
    from ibiscape_eval.sim.suite import read_manifest, run_suite, suite_entries

    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise IbiscapeError(f"{out}: exists and is not a folder; choose another benchmark folder")
    # refuse what cannot run before anything is written
    known = (read_manifest(suite_dir)[1] if suite_dir is not None
             else suite_entries(scale, seed=seed))
    unknown = sorted(set(sequences or ()) - {e.name for e in known})
    if unknown:
        raise IbiscapeError(f"unknown suite sequence(s) {', '.join(unknown)}; the suite has "
                            f"{', '.join(e.name for e in known)}")
    out.mkdir(parents=True, exist_ok=True)
    own = executor is None
    ex: Executor = LocalExecutor() if executor is None else executor
    steps: dict[str, list[dict[str, Any]]] = {}
    wall: dict[str, float] = {}

    def tick(step: str) -> Callable[[int, int, int], None] | None:
        if progress is None:
            return None
        return lambda d, f, r: progress(step, d, f, r)

    try:
        t0 = time.perf_counter()
        if suite_dir is None:
            sroot = out / "suite"
            res = run_suite(sroot, scale=scale, seed=seed, executor=ex, progress=tick("suite"),
                            only=sequences)
            entries = suite_entries(scale, seed=seed)
            steps["suite"] = [{"key": s["name"], "sequence": s["name"], "status": s["status"],
                               "error": s["error"], "seconds": round(s.get("seconds", 0.0), 3),
                               "cached": bool(s.get("reused")), "value": s.get("summary")}
                              for s in res.sequences]
        else:
            sroot = Path(suite_dir)
            doc, entries = read_manifest(sroot)
            scale = float(doc.get("scale", scale))
            steps["suite"] = [{"key": e.name, "sequence": e.name,
                               "status": "ok" if (sroot / e.name / "sequence.yaml").is_file()
                               else "failed",
                               "error": None if (sroot / e.name / "sequence.yaml").is_file()
                               else f"{sroot / e.name}: sequence missing from the suite folder",
                               "seconds": 0.0, "cached": True, "value": None}
                              for e in entries]
        wall["suite"] = time.perf_counter() - t0
        if sequences is not None:
            entries = tuple(e for e in entries if e.name in set(sequences))
            steps["suite"] = [r for r in steps["suite"] if r["key"] in set(sequences)]
        bad = {r["key"] for r in steps["suite"] if r["status"] != "ok"}
        ready = [e for e in entries if e.name not in bad]
        jobs, skipped = benchmark_jobs(ready, sroot)
        for e in entries:
            if e.name in bad:
                skipped.append({"step": "all", "sequence": e.name,
                                "reason": "the sequence was not generated (see the suite step)"})
        for step in STEPS[1:6]:
            t0 = time.perf_counter()
            results, _ = run_jobs(jobs[step], ex, cache=cache, progress=tick(step))
            steps[step] = _records(jobs[step], results)
            wall[step] = time.perf_counter() - t0
        t0 = time.perf_counter()
        evaluation, figs = _evaluate(out, sroot, steps, ex, cache, tick("evaluation"), figures)
        wall["evaluation"] = time.perf_counter() - t0
    finally:
        if own:
            ex.close()
    return BenchmarkResult(str(out), str(sroot), float(scale), steps, skipped,
                           evaluation, {k: round(v, 3) for k, v in wall.items()}, tuple(figs))


def _evaluate(out: Path, suite_dir: Path, steps: dict[str, list[dict[str, Any]]],
              executor: Executor, cache: ContentCache | None,
              progress: Callable[[int, int, int], None] | None, figures: bool
              ) -> tuple[dict[str, Any] | None, list[tuple[str, str, bytes]]]:
    """Write the VIO estimates as a runs folder and score them with the report's evaluation."""
    from ibiscape_eval.io.atomic import atomic_write
    from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
    from ibiscape_eval.report.paper_table import PaperTable
    from ibiscape_eval.report.runs import discover_runs

    runs = out / "runs"
    n = 0
    for r in steps.get("vio", []):
        if r["status"] != "ok" or not r["value"]:
            continue
        text = r["value"].pop("estimate_tum", "")
        d = runs / r["sequence"] / VIO_ALGORITHM / "1"
        d.mkdir(parents=True, exist_ok=True)
        with atomic_write(d / "estimate.txt") as f:
            f.write(text)
        n += 1
    if n == 0:
        steps["evaluation"] = []
        return None, []
    layout = discover_runs(runs, sequences_dir=suite_dir)
    ev = evaluate_runs(layout, EvaluationOptions(align=VIO_ALIGN, max_diff_s=0.02, rpe_delta=1.0,
                                                 rpe_delta_unit="seconds"),
                       executor=executor, cache=cache, progress=progress)
    steps["evaluation"] = [{"key": f"{r['sequence']}/{r['algorithm']}/{r['trial']}",
                            "sequence": r["sequence"], "status": r["status"], "error": r["error"],
                            "seconds": 0.0, "cached": False,
                            "value": {"ate_rmse_m": _get(r, "ate", "translation_m", "rmse"),
                                      "rpe_m": _get(r, "rpe", "translation_m", "mean"),
                                      "rpe_deg": _get(r, "rpe", "rotation_deg", "mean"),
                                      "n_matched": r.get("n_matched")}}
                           for r in ev.runs]
    figs = []
    if figures:
        import warnings

        from ibiscape_eval.core.errors import IbiscapeWarning
        from ibiscape_eval.report.batch_report import sequence_figures

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IbiscapeWarning)
            figs = sequence_figures(ev)
    table = PaperTable.from_runs(ev.runs)
    return {"table": json.loads(json.dumps(table.to_dict())), "markdown": table.to_markdown(),
            "html": table.to_html(),
            "latex": table.to_latex(caption="Stereo-VIO baseline on the generated SLAM sequences.")}, figs


def _get(doc: Any, *path: str) -> Any:
    for p in path:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(p)
    return doc
