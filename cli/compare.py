"""``ibiscape-eval compare EST... REF``: several estimates against one reference."""

from __future__ import annotations

from pathlib import Path

import click

from ibiscape_eval.metrics.relations import PLANES, POSE_RELATIONS
from ibiscape_eval.metrics.rpe import DELTA_UNITS, PAIR_MODES, PAIRS_FROM
from ibiscape_eval.report.plots import PLOT_PLANES

from ._common import (
    ALIGNMENTS,
    TrajectoryInputs,
    cli_terms,
    echo_json,
    info,
    read_trajectories,
    trajectory_options,
    user_errors,
)


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(path_type=Path),
                metavar="EST... REF")
@trajectory_options
@click.option("--labels", default=None,
              help="Comma-separated labels, one per estimate (default: the file names).")
@click.option("--align", "alignment", type=click.Choice(ALIGNMENTS), default="se3",
              show_default=True, help="Alignment of every estimate for the ATE.")
@click.option("--rpe-align", type=click.Choice(ALIGNMENTS), default=None,
              help="Alignment for the RPE (only sim3 changes it); default sim3 when --align is "
              "sim3 (a monocular scale), else none.")
@click.option("--delta", type=click.FloatRange(min=0.0, min_open=True), default=1.0,
              show_default=True, help="RPE pair distance in --delta-unit.")
@click.option("--delta-unit", type=click.Choice(DELTA_UNITS), default="frames",
              show_default=True)
@click.option("--delta-tol", type=click.FloatRange(min=0.0), default=0.1, show_default=True,
              help="Relative tolerance on --delta of --pairs all (evo's --delta_tol).")
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
@click.option("--plot-plane", type=click.Choice(PLOT_PLANES), default=None,
              help="Plane of the trajectory panel (default by REF's format: xz for KITTI).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout.")
@user_errors
def compare(paths: tuple[Path, ...], labels: str | None, alignment: str, rpe_align: str | None,
            delta: float, delta_unit: str, delta_tol: float, pairs: str, pairs_from: str,
            pose_relation: str, project_to_plane: str | None, save_results: Path | None,
            plot: Path | None, plot_plane: str | None, as_json: bool,
            inputs: TrajectoryInputs) -> None:
    """ATE and RPE of several estimates EST... against one reference REF, in one table.

    The reference comes LAST, as in `ate EST REF`: the estimates first, then the reference.
    Takes the reading, time and selection options of `ate` (--format-est, --times-ref,
    --offset-s, --t-start, --downsample, ...).

    \b
    Examples:
      ibiscape-eval compare orb.txt vins.txt gt.txt --labels ORB,VINS
      ibiscape-eval compare a.txt b.txt gt.csv --plot cmp.png --save-results results/
      ibiscape-eval compare a.txt b.txt gt.csv --offset-s 0.02 --t-start 1403715280 --json
    """
    from ibiscape_eval.metrics import compare as compare_fn
    from ibiscape_eval.report.plots import default_plot_plane

    from .startup import numba_startup

    if len(paths) < 2:
        raise click.UsageError("give at least one estimate and the reference: EST... REF")
    *estimates, ref = paths
    if rpe_align is None:
        rpe_align = "sim3" if alignment == "sim3" else "none"
    names = None
    if labels is not None:
        names = [s.strip() for s in labels.split(",")]
        if len(names) != len(estimates) or not all(names):
            raise click.BadParameter(
                f"got {len(names)} labels for {len(estimates)} estimates", param_hint="--labels")
    ests, ref_t, match, ref_fmt, notes = read_trajectories(estimates, ref, inputs)
    unit = inputs.unit
    with numba_startup():
        result = compare_fn(
            ref_t, ests, labels=names, ref_file=ref.name, est_files=[p.name for p in estimates],
            align=alignment, rpe_align=rpe_align, delta=delta, delta_unit=delta_unit,
            pairs=pairs, pairs_from=pairs_from, pose_relation=pose_relation,
            project_to_plane=project_to_plane, rel_tol=delta_tol, **inputs.selection(match))
    if save_results is not None:
        written = result.save(save_results)
        info(f"wrote {len(written)} files to {save_results}")
    if plot is not None:
        from ibiscape_eval.report.plots import compare_figure, save_figure

        plane = plot_plane or default_plot_plane(ref_fmt)
        save_figure(compare_figure(result, plane=plane,
                                   title=f"{len(ests)} estimates against the reference"), plot)
    f = {"m": 1.0, "cm": 100.0, "mm": 1000.0}[unit]
    if as_json:
        doc = result.to_dict()
        doc["warnings"] = notes
        for row in doc["estimates"]:
            row["warnings"] = [cli_terms(w) for w in row["warnings"]]
            if unit != "m":
                for key in ("ate_rmse_m", "rpe_rmse_m"):
                    row[key.replace("_m", f"_{unit}")] = row.pop(key) * f
        if unit != "m":
            doc["length_unit"] = unit
        echo_json(doc)
        return
    rel = f" {pose_relation}" if pose_relation != "trans" else ""
    click.echo(f"reference {ref.name}; ATE align {alignment}, RPE align {rpe_align}, delta "
               f"{delta:g} {delta_unit} ({pairs} pairs from {pairs_from})")
    head = (f"{'label':<20}{'matched':>8}{f'ATE rmse {unit}':>12}{'ATE rot deg':>12}"
            f"{f'RPE rmse {unit}':>12}{'RPE rot deg':>12}" + (f"{'ATE' + rel:>16}" if rel else ""))
    click.echo(head)
    for e in result.entries:
        line = (f"{e.label[:19]:<20}{e.ate.n_matched:>8}{e.ate.translation_m.rmse * f:>12.6g}"
                f"{e.ate.rotation_deg.rmse:>12.6g}{e.rpe.translation_m.rmse * f:>12.6g}"
                f"{e.rpe.rotation_deg.rmse:>12.6g}")
        if rel:
            line += f"{e.ate.stats.rmse:>16.6g}"
        click.echo(line)


__all__ = ["compare"]
