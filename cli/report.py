"""``ibiscape-eval report``: evaluate every run of a runs folder and write the paper-style table."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ._common import ALIGNMENTS, echo_json, fail, info, user_errors

_PLANES = ("xy", "xz", "yz")


def _alignments(values: tuple[str, ...]) -> tuple[str, tuple[tuple[str, str], ...]]:
    """``--align`` values: at most one plain ALIGNMENT (every algorithm's default) and any
    number of NAME=ALIGNMENT."""
    default: str | None = None
    named: list[tuple[str, str]] = []
    for v in values:
        name, eq, al = v.rpartition("=")
        if al not in ALIGNMENTS:
            raise click.BadParameter(f"{al!r} in {v!r} is not one of {', '.join(ALIGNMENTS)}",
                                     param_hint="--align")
        if not eq:
            if default is not None:
                raise click.BadParameter(f"one plain alignment for every algorithm, got "
                                         f"{default} and {al}; name the others: NAME={al}",
                                         param_hint="--align")
            default = al
        elif not name:
            raise click.BadParameter(f"{v!r}: expected NAME=ALIGNMENT", param_hint="--align")
        else:
            named.append((name, al))
    return default or "se3", tuple(named)


def _pct_list(text: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated percentages, got {text!r}") from None
    if not vals or any(not 0 < v <= 100 for v in vals):
        raise click.BadParameter(f"expected percentages in (0, 100], got {text!r}")
    return vals


@click.command(
    "report",
    epilog="""\b
Layout of RUNS_DIR:
  <sequence>/groundtruth.<ext>           (or --sequences DIR/<sequence>/vehicle_gt/groundtruth_sync.csv)
  <sequence>/gnss.csv                    optional, drawn on the trajectory figure
  <sequence>/<algorithm>/<trial>/<one trajectory file, any format the readers know>
  <sequence>/<algorithm>/[<trial>/]run.yaml  optional: "align: sim3" (e.g. a monocular run)

\b
Alignment of an algorithm: --align NAME=A, else its run.yaml, else the plain --align A (se3).

\b
Examples:
  ibiscape-eval report runs/ --out report/
  ibiscape-eval report runs/ --align ORB_mono=sim3 --align yaw --out report/
  ibiscape-eval report runs/ --sequences IBISCape/ --align sim3 --json > runs.json
  ibiscape-eval report runs/ --out report/ --scheduler tcp://10.0.0.5:8786
""",
)
@click.argument("runs_dir", type=click.Path(path_type=Path))
@click.option("--sequences", "sequences_dir", type=click.Path(path_type=Path), default=None,
              help="Folder of IBISCape-layout sequences holding the ground truth "
                   "(<sequence>/vehicle_gt/groundtruth_sync.csv, other_sensors/gnss.csv).")
@click.option("--align", "alignment", multiple=True, metavar="[NAME=]ALIGNMENT",
              help="Alignment (none, origin, se3, sim3, yaw) of ATE, RPE and drift: plain for "
                   "every algorithm (default se3), NAME=A for one (repeatable; e.g. "
                   "ORB_mono=sim3 for a monocular run). Wins over a run's run.yaml.")
@click.option("--plot-plane", type=click.Choice(_PLANES), default=None,
              help="Plane of the trajectory figures [default: per ground-truth format, KITTI "
                   "xz, others xy].")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON document (runs, table, summary) on stdout.")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="Write table.md/.tex/.csv, runs.csv, report.json, report.html and figures/ "
                   "here (replaces an earlier report in that folder).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the jobs on this Dask scheduler (tcp://host:port) instead of locally.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local worker processes (default: the usable CPUs).")
@click.option("--cache", "cache_dir", type=click.Path(path_type=Path), default=None,
              help="Cache of finished runs (default ~/.cache/ibiscape-eval/jobs).")
@click.option("--no-cache", is_flag=True, help="Recompute every run, store nothing.")
@click.option("--max-diff-s", type=click.FloatRange(min=0.0), default=0.01, show_default=True,
              help="Largest timestamp difference of associated poses.")
@click.option("--rpe-delta", type=click.FloatRange(min=0.0, min_open=True), default=1.0,
              show_default=True, help="RPE pair distance, in --rpe-delta-unit.")
@click.option("--rpe-delta-unit", type=click.Choice(("frames", "seconds", "metres", "degrees")),
              default="frames", show_default=True)
@click.option("--rpe-pairs", type=click.Choice(("consecutive", "all")), default="consecutive",
              show_default=True)
@click.option("--drift-lengths-pct", default="10,20,30,40,50", show_default=True,
              help="Drift segment lengths in % of each reference path.")
@click.option("--no-figures", is_flag=True, help="Write the tables without figures.")
@user_errors
def report(
    runs_dir: Path,
    sequences_dir: Path | None,
    alignment: tuple[str, ...],
    plot_plane: str | None,
    as_json: bool,
    out: Path | None,
    scheduler: str | None,
    workers: int | None,
    cache_dir: Path | None,
    no_cache: bool,
    max_diff_s: float,
    rpe_delta: float,
    rpe_delta_unit: str,
    rpe_pairs: str,
    drift_lengths_pct: str,
    no_figures: bool,
) -> None:
    """Evaluate every run of RUNS_DIR (ATE, RPE, drift) and write the paper-style table.

    Runs execute as batch jobs: locally on a pool of processes, or on an existing Dask cluster
    with --scheduler.  Finished runs are cached by content and skipped on a re-run; a run that
    fails is reported with its error and the others carry on.
    """
    from ibiscape_eval.batch import ContentCache, default_cache_dir, make_executor
    from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
    from ibiscape_eval.report.paper_table import PaperTable
    from ibiscape_eval.report.runs import discover_runs

    if rpe_delta_unit == "frames" and rpe_delta != int(rpe_delta):
        raise click.BadParameter("a delta in frames must be a whole number",
                                 param_hint="--rpe-delta")
    default_align, named = _alignments(alignment)
    options = EvaluationOptions(align=default_align, max_diff_s=max_diff_s, rpe_delta=rpe_delta,
                                rpe_delta_unit=rpe_delta_unit, rpe_pairs=rpe_pairs,
                                drift_lengths_pct=_pct_list(drift_lengths_pct),
                                align_by_algorithm=named)
    if out is not None and out.exists() and not out.is_dir():
        fail(f"{out}: exists and is a file; --out needs a folder")
    layout = discover_runs(runs_dir, sequences_dir=sequences_dir)
    _print_plan(layout, options, scheduler)
    executor = make_executor(scheduler=scheduler, workers=workers)
    cache = None if no_cache else ContentCache(cache_dir or default_cache_dir())
    from .progress import BatchBar

    bar = BatchBar("report", unit="run")
    try:
        evaluation = evaluate_runs(layout, options, executor=executor, cache=cache,
                                   progress=bar)
    finally:
        bar.close()
        executor.close()
    _print_outcome(evaluation)
    table = PaperTable.from_runs(evaluation.runs)
    if out is not None:
        from ibiscape_eval.report.batch_report import write_report

        files = write_report(out, evaluation, figures=not no_figures, plot_plane=plot_plane)
        info(f"wrote {len(files)} files to {out} (open {out / 'report.html'})")
    if as_json:
        doc = evaluation.to_dict()
        doc["table"] = table.to_dict()
        echo_json(doc)
    else:
        click.echo(table.to_markdown(), nl=False)


def _print_plan(layout: Any, options: Any, scheduler: str | None) -> None:
    """Say what is ignored, the alignment of each algorithm (refusing unknown names before any
    work) and how many runs go where."""
    from ibiscape_eval.report.evaluate import resolve_alignments

    for path, why in layout.ignored:
        info(f"ignored {path}: {why}")
    aligns = resolve_alignments(layout, options)
    if len({a for a, _ in aligns.values()}) > 1 or any(s != "default" for _, s in aligns.values()):
        info("alignment: " + ", ".join(f"{alg} {a} ({s})" for alg, (a, s) in aligns.items()))
    info(f"{len(layout.runs)} runs: {len(layout.sequences)} sequences x "
         f"{len(layout.algorithms)} algorithms"
         + (f" on the Dask scheduler {scheduler}" if scheduler else ""))


def _print_outcome(evaluation: Any) -> None:
    """One line of counts, one per warning or failed run; exit 2 when every run failed."""
    s = evaluation.summary
    info(f"{s['n_ok']} runs evaluated ({s['n_cached']} from the cache), {s['n_failed']} failed")
    for r in evaluation.runs:
        for w in r.get("warnings") or ():
            info(f"warning: run {r['sequence']}/{r['algorithm']}/{r['trial']}: {w}")
        if r["status"] != "ok":
            info(f"warning: run {r['sequence']}/{r['algorithm']}/{r['trial']} failed: "
                 f"{r['error']}")
    if s["n_ok"] == 0:
        first = evaluation.runs[0]
        fail(f"every run failed (first: {first['path']}: {first['error']}); nothing written")
