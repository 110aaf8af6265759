"""``ibiscape-eval compare REF EST...``: several estimates against one reference."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ibiscape_eval.io.detect import TRAJECTORY_FORMATS
from ibiscape_eval.metrics.relations import PLANES, POSE_RELATIONS
from ibiscape_eval.metrics.rpe import DELTA_UNITS, PAIR_MODES, PAIRS_FROM
from ibiscape_eval.report.plots import PLOT_PLANES

from ._common import echo_json, info, user_errors
from .ate import ALIGNMENTS

FORMATS = ("auto", *TRAJECTORY_FORMATS)


@click.command()
@click.argument("ref", type=click.Path(path_type=Path))
@click.argument("estimates", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--labels", default=None,
              help="Comma-separated labels, one per estimate (default: the file names).")
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="auto", show_default=True,
              help="Format of every file (auto detects from name and content).")
@click.option("--max-diff-s", type=click.FloatRange(min=0.0), default=0.01, show_default=True,
              help="Largest time difference of an associated pose pair, seconds.")
@click.option("--align", "alignment", type=click.Choice(ALIGNMENTS), default="se3",
              show_default=True, help="Alignment of every estimate for the ATE.")
@click.option("--rpe-align", type=click.Choice(ALIGNMENTS), default=None,
              help="Alignment for the RPE (only sim3 changes it); default sim3 when --align is "
              "sim3 (a monocular scale), else none.")
@click.option("--delta", type=click.FloatRange(min=0.0, min_open=True), default=1.0,
              show_default=True, help="RPE pair distance in --delta-unit.")
@click.option("--delta-unit", type=click.Choice(DELTA_UNITS), default="frames",
              show_default=True)
@click.option("--pairs", type=click.Choice(PAIR_MODES), default="consecutive", show_default=True)
@click.option("--pairs-from", type=click.Choice(PAIRS_FROM), default="est", show_default=True,
              help="Trajectory whose path defines the RPE pairs.")
@click.option("--pose-relation", type=click.Choice(POSE_RELATIONS), default="trans",
              show_default=True, help="Relation of the 'error' columns (evo).")
@click.option("--project-to-plane", type=click.Choice(PLANES), default=None,
              help="Project all trajectories onto this plane after alignment.")
@click.option("--save-results", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Directory for compare.json and per-estimate JSON + CSV results.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write one figure with all trajectories (PNG/PDF/SVG).")
@click.option("--plot-plane", type=click.Choice(PLOT_PLANES), default="xy", show_default=True)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout.")
@user_errors
def compare(ref: Path, estimates: tuple[Path, ...], labels: str | None, fmt: str,
            max_diff_s: float, alignment: str, rpe_align: str | None, delta: float, delta_unit: str,
            pairs: str, pairs_from: str, pose_relation: str, project_to_plane: str | None,
            save_results: Path | None, plot: Path | None, plot_plane: str,
            as_json: bool) -> None:
    """ATE and RPE of several estimates EST... against one reference REF, in one table.

    The reference comes FIRST here (unlike `ate EST REF`).

    \b
    Examples:
      ibiscape-eval compare gt.txt orb.txt vins.txt --labels ORB,VINS
      ibiscape-eval compare gt.csv a.txt b.txt --plot cmp.png --save-results results/
    """
    from ibiscape_eval.io import (
        detect_trajectory_format,
        has_timestamps,
        read_trajectory,
    )
    from ibiscape_eval.metrics import choose_match
    from ibiscape_eval.metrics import compare as compare_fn

    from .ate import swap_warning
    from .startup import numba_startup

    if rpe_align is None:
        rpe_align = "sim3" if alignment == "sim3" else "none"
    names = None
    if labels is not None:
        names = [s.strip() for s in labels.split(",")]
        if len(names) != len(estimates) or not all(names):
            raise click.BadParameter(
                f"got {len(names)} labels for {len(estimates)} estimates", param_hint="--labels")

    def load(path: Path) -> tuple[Any, str]:
        f = fmt
        if f == "auto":
            f = detect_trajectory_format(path)
            info(f"{path}: format {f} (detected; force another with --format)")
        return read_trajectory(path, f, name=path.name), f

    with numba_startup():
        ref_t, ref_fmt = load(ref)
        ests, match = [], None
        for p in estimates:
            t, f = load(p)
            warn = swap_warning(t, ref_t, f, ref_fmt)
            if warn:
                info(warn)
            m = choose_match(has_timestamps(f, None), has_timestamps(ref_fmt, None))
            if match is not None and m != match:
                raise click.UsageError("mixing timed and untimed (KITTI) estimates")
            match = m
            ests.append(t)
        result = compare_fn(
            ref_t, ests, labels=names, ref_file=ref.name, est_files=[p.name for p in estimates],
            align=alignment, rpe_align=rpe_align, delta=delta, delta_unit=delta_unit,
            pairs=pairs, pairs_from=pairs_from, pose_relation=pose_relation,
            project_to_plane=project_to_plane, max_diff_s=max_diff_s, match=match or "time")
    if save_results is not None:
        written = result.save(save_results)
        info(f"wrote {len(written)} files to {save_results}")
    if plot is not None:
        from ibiscape_eval.report.plots import compare_figure, save_figure

        save_figure(compare_figure(result, plane=plot_plane,
                                   title=f"{len(ests)} estimates against the reference"), plot)
    if as_json:
        echo_json(result.to_dict())
        return
    rel = f" {pose_relation}" if pose_relation != "trans" else ""
    click.echo(f"reference {ref.name}; ATE align {alignment}, RPE align {rpe_align}, delta "
               f"{delta:g} {delta_unit} ({pairs} pairs from {pairs_from})")
    head = (f"{'label':<20}{'matched':>8}{'ATE rmse m':>12}{'ATE rot deg':>12}"
            f"{'RPE rmse m':>12}{'RPE rot deg':>12}" + (f"{'ATE' + rel:>16}" if rel else ""))
    click.echo(head)
    for e in result.entries:
        line = (f"{e.label[:19]:<20}{e.ate.n_matched:>8}{e.ate.translation_m.rmse:>12.6g}"
                f"{e.ate.rotation_deg.rmse:>12.6g}{e.rpe.translation_m.rmse:>12.6g}"
                f"{e.rpe.rotation_deg.rmse:>12.6g}")
        if rel:
            line += f"{e.ate.stats.rmse:>16.6g}"
        click.echo(line)


__all__ = ["compare"]
