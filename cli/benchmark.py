"""``ibiscape-eval benchmark DIR``: the whole paper on generated data, one report."""

from __future__ import annotations

from pathlib import Path

import click

from ._common import echo_json, fail, info, user_errors


@click.command(
    "benchmark",
    epilog="""\b
Examples:
  ibiscape-eval benchmark bench/                       (scale 0.05: minutes on 2 cores)
  ibiscape-eval benchmark bench/ --scale 0.25 --scheduler tcp://10.0.0.5:8786
  ibiscape-eval sim suite --out suite/ --scale 0.1 ; ibiscape-eval benchmark bench/ --suite suite/
""",
)
@click.argument("out_dir", metavar="DIR", type=click.Path(path_type=Path, file_okay=False))
@click.option("--scale", type=float, default=0.05, show_default=True,
              help="Suite scale in (0, 1] (see 'sim suite --help'); ignored with --suite.")
@click.option("--suite", "suite_dir", type=click.Path(path_type=Path, file_okay=False),
              default=None, help="Use this existing suite (written by 'sim suite') instead of "
              "generating DIR/suite.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Base seed of the generated suite.")
@click.option("--only", multiple=True, metavar="NAME",
              help="Only this suite sequence (repeat), e.g. --only SVI_slam_clear_1.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run every job on this Dask scheduler (tcp://host:port) instead of locally.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local worker processes (default: the usable CPUs).")
@click.option("--cache", "cache_dir", type=click.Path(path_type=Path), default=None,
              help="Cache of finished analysis jobs (default ~/.cache/ibiscape-eval/jobs).")
@click.option("--no-cache", is_flag=True, help="Recompute every job, store nothing.")
@click.option("--no-figures", is_flag=True, help="Leave out the VIO figures (top views, box plots).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON document.")
@user_errors
def benchmark(out_dir: Path, scale: float, suite_dir: Path | None, seed: int, only: tuple[str, ...],
              scheduler: str | None, workers: int | None, cache_dir: Path | None, no_cache: bool,
              no_figures: bool, as_json: bool) -> None:
    """Run the whole IBISCape paper on generated data and write one report into DIR/report.

    Generates the paper's 34-sequence suite (scaled), calibrates the cameras of every calibration
    sequence (errors against the true cameras), the camera-IMU extrinsics and time offsets,
    estimates the IMU noise of the still IMU (against the configured densities), filters DVS hot
    pixels (fraction removed, precision/recall against the noisy pixels), runs the VIO baseline on
    every SLAM sequence with stereo RGB and scores it (ATE, RPE).  Every step runs as batch jobs,
    locally or on a Dask cluster; a failing job is reported with its error and the rest continue.
    """
    from ibiscape_eval.batch import ContentCache, default_cache_dir, make_executor
    from ibiscape_eval.benchmark import run_benchmark
    from ibiscape_eval.report.benchmark_report import benchmark_markdown, write_benchmark_report
    from ibiscape_eval.sim.suite import scaled_side_px

    if out_dir.exists() and not out_dir.is_dir():
        fail(f"{out_dir}: exists and is a file; the benchmark needs a folder")
    if suite_dir is None:
        scaled_side_px(scale)  # refuses a scale outside (0, 1] before anything starts
    executor = make_executor(scheduler=scheduler, workers=workers)
    cache = None if no_cache else ContentCache(cache_dir or default_cache_dir())
    info(f"benchmark in {out_dir}" + (f" on the suite {suite_dir}" if suite_dir else
                                      f" (suite at scale {scale:g})")
         + (f" on the Dask scheduler {scheduler}" if scheduler else ""))
    from .progress import BatchBar

    bar = BatchBar("suite", delay_s=0.0)
    try:
        res = run_benchmark(out_dir, scale=scale, suite_dir=suite_dir, seed=seed,
                            executor=executor, cache=cache, progress=bar.step,
                            sequences=list(only) or None, figures=not no_figures)
    finally:
        bar.close()
        executor.close()
    for f in res.failed():
        info(f"warning: {f['step']} {f['key']} failed: {f['error']}")
    files = write_benchmark_report(out_dir / "report", res)
    for step, s in res.wall_s.items():
        info(f"{step:<20} {s:8.1f} s")
    if as_json:
        echo_json(res.to_dict())
    else:
        click.echo(benchmark_markdown(res), nl=False)
    info(f"report: {files[1]} ({res.n_jobs} jobs, {res.n_failed} failed)")
