"""``ibiscape-eval ate | rpe | drift``: trajectory metrics from two files."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from ibiscape_eval.metrics.relations import PLANES, POSE_RELATIONS
from ibiscape_eval.metrics.rpe import DELTA_UNITS, PAIR_MODES, PAIRS_FROM
from ibiscape_eval.report.plots import PANELS, PLOT_PLANES

from ._common import (
    ALIGNMENTS,
    TrajectoryInputs,
    collect,
    echo_json,
    info,
    read_trajectories,
    show_doc_warnings,
    trajectory_options,
    user_errors,
)


@dataclass(frozen=True)
class Outputs:
    """Where the results of ate, rpe and drift go (besides the table)."""

    as_json: bool
    save_csv: Path | None
    plot: Path | None
    gps: Path | None


@dataclass(frozen=True)
class EvoOptions:
    """evo's pose relation and projection, and the figure's plane and panels (ate, rpe)."""

    pose_relation: str
    project_to_plane: str | None
    plot_plane: str | None
    plot_panels: str | None


@dataclass(frozen=True)
class _Pair:
    """The estimate and the reference as read, their pairing, REF's format and the warnings."""

    est: Any
    ref: Any
    match: str
    ref_fmt: str
    notes: list[str]


def _input_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """EST and REF, the shared reading/association/selection options (``_common``) and the
    outputs of the three trajectory commands."""
    opts: list[Callable[[Callable[..., Any]], Callable[..., Any]]] = [
        click.argument("est", type=click.Path(path_type=Path)),
        click.argument("ref", type=click.Path(path_type=Path)),
        trajectory_options,
        click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout."),
        click.option(
            "--save-csv",
            type=click.Path(path_type=Path),
            default=None,
            help="Write per-pose (or per-pair) errors as CSV.",
        ),
        click.option(
            "--plot",
            type=click.Path(path_type=Path),
            default=None,
            help="Write a figure (PNG/PDF/SVG by extension).",
        ),
        click.option(
            "--gps",
            type=click.Path(path_type=Path),
            default=None,
            help="GNSS csv (IBISCape gnss.csv) to overlay on the plot.",
        ),
    ]
    func = collect(Outputs, "out")(func)
    for opt in reversed(opts):
        func = opt(func)
    return func


def _evo_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """evo's pose relation and projection, and the figure's plane and panels (ate, rpe)."""
    opts = [
        click.option(
            "--pose-relation",
            type=click.Choice(POSE_RELATIONS),
            default="trans",
            show_default=True,
            help="Error of the summary line (evo): translation, rotation angle [deg], "
            "||R-I||, ||E-I|| or point distance.",
        ),
        click.option(
            "--project-to-plane",
            type=click.Choice(PLANES),
            default=None,
            help="Project both trajectories onto this plane after alignment (evo).",
        ),
        click.option(
            "--plot-plane",
            type=click.Choice(PLOT_PLANES),
            default=None,
            help="Plane of the trajectory panel (default by REF's format: xz for KITTI's "
            "camera frame, else xy).",
        ),
        click.option(
            "--plot-panels",
            default=None,
            help=f"Comma-separated panels of the figure, from {','.join(PANELS)} (default all).",
        ),
    ]
    func = collect(EvoOptions, "evo")(func)
    for opt in reversed(opts):
        func = opt(func)
    return func


def _panels(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [p.strip() for p in text.split(",") if p.strip()]
    bad = [p for p in names if p not in PANELS]
    if bad or not names:
        raise click.BadParameter(
            f"unknown panel(s) {', '.join(bad) or text!r}; choose from {', '.join(PANELS)}",
            param_hint="--plot-panels",
        )
    return names


def _read_pair(est: Path, ref: Path, inputs: TrajectoryInputs) -> _Pair:
    """Read both trajectories (``_common.read_trajectories``)."""
    ests, ref_t, match, ref_fmt, notes = read_trajectories([est], ref, inputs)
    return _Pair(ests[0], ref_t, match, ref_fmt, notes)


def _report_counts(doc: dict[str, Any]) -> None:
    info(
        f"matched {doc['n_matched']} poses; dropped {doc['n_dropped_est']} from the estimate and "
        f"{doc['n_dropped_ref']} from the reference"
        + (f"; estimated time offset {doc['t_offset_s']:+.6f} s" if doc.get("t_offset_s") else "")
    )


def _write_csv(path: Path, frame: Any) -> None:
    from ibiscape_eval.io.results import write_result_csv

    write_result_csv(path, frame)


def relation_line(doc: dict[str, Any]) -> str | None:
    """The summary of the chosen pose relation when it is not the translation table's."""
    rel = doc.get("pose_relation", "trans")
    if rel == "trans" and not doc.get("project_to_plane"):
        return None
    e = doc["error"]
    unit = f" {doc['relation_unit']}" if doc["relation_unit"] else ""
    plane = f", projected to {doc['project_to_plane']}" if doc.get("project_to_plane") else ""
    return (f"{rel}{plane}: rmse {e['rmse']:.6g}{unit}, mean {e['mean']:.6g}, "
            f"median {e['median']:.6g}, std {e['std']:.6g}, min {e['min']:.6g}, "
            f"max {e['max']:.6g}")


def _finish(result: Any, est: Path, ref: Path, pair: _Pair, unit: str, out: Outputs, *,
            plot: Callable[[Path], None], table: Callable[[dict[str, Any]], str]) -> None:
    """The ending the three commands share: counts, --save-csv, --plot, then JSON or the table."""
    from ibiscape_eval.report import format_header

    doc = show_doc_warnings(result.to_dict(**({"unit": unit} if unit != "m" else {})),
                            pair.notes)
    if out.as_json:  # the table's header line says the same on stdout
        _report_counts(doc)
    if out.save_csv:
        _write_csv(out.save_csv, result.to_frame(**({"unit": unit} if unit != "m" else {})))
    if out.plot:
        plot(out.plot)
    if out.as_json:
        echo_json(doc)
    else:
        click.echo(format_header(doc, est.name, ref.name))
        click.echo(table(doc))
        line = relation_line(doc)
        if line:
            click.echo(line)


def error_table(doc: dict[str, Any], title: str) -> str:
    """The statistics table of ``report.format_error_table``, in the unit of ``--change-unit``
    (``translation_<unit>`` in ``doc``)."""
    from ibiscape_eval.report import format_error_table

    unit = doc.get("length_unit", "m")
    if unit == "m":
        return format_error_table(doc, title=title)
    text = format_error_table({**doc, "translation_m": doc[f"translation_{unit}"]}, title=title)
    return text.replace("translation [m]", f"translation [{unit}]".ljust(15)).replace(
        " m, ", f" {unit}, ", 1)


def drift_table(doc: dict[str, Any]) -> str:
    """Per-length drift rows; a length no segment reached says so instead of printing nan."""
    lines = [f"{'length [m]':>12}{'segments':>10}{'trans [%]':>12}{'rot [deg/m]':>14}"]
    for L, n, t, r, ok in zip(doc["lengths_m"], doc["n_segments"], doc["translation_pct"],
                              doc["rotation_deg_per_m"], doc["reached"], strict=True):
        if ok:
            lines.append(f"{L:>12.2f}{n:>10d}{t:>12.4f}{r:>14.6f}")
        else:
            lines.append(f"{L:>12.2f}{n:>10d}{'not reached':>26}")
    mt, mr = doc["mean_translation_pct"], doc["mean_rotation_deg_per_m"]
    avg = f"{mt:>12.4f}{mr:>14.6f}" if mt is not None and mr is not None else f"{'-':>26}"
    lines.append(f"{'average':>12}{sum(doc['n_segments']):>10d}{avg}")
    if not all(doc["reached"]):
        lines.append(f"(reference path {doc['path_length_m']:.1f} m: lengths marked 'not reached'"
                     " have no segment; try --lengths-pct 10,20,30,40,50)")
    return "\n".join(lines)


def _gps_positions(path: Path | None, ref: Any) -> Any:
    if path is None:
        return None
    from ibiscape_eval.io import read_gnss
    from ibiscape_eval.metrics.gnss import gnss_in_reference_frame

    fixes = read_gnss(path)
    return gnss_in_reference_frame(fixes.stamps_ns, fixes.lat_deg, fixes.lon_deg, fixes.alt_m, ref)


def _plot_errors(path: Path, result: Any, pair: _Pair, unit: str, gps: Path | None,
                 evo: EvoOptions, title: str) -> None:
    """The error figure; its plane is ``--plot-plane`` or the default of REF's format."""
    from ibiscape_eval.report.plots import default_plot_plane, metric_figure, save_figure

    fig = metric_figure(result, unit=unit, title=title,
                        gps_xyz_m=_gps_positions(gps, pair.ref),
                        plane=evo.plot_plane or default_plot_plane(pair.ref_fmt),
                        panels=_panels(evo.plot_panels))
    save_figure(fig, path)


@click.command()
@_input_options
@_evo_options
@click.option(
    "--align",
    "alignment",
    type=click.Choice(ALIGNMENTS),
    default="se3",
    show_default=True,
    help="Alignment: none, origin (first pose), se3/sim3 (Umeyama), yaw (4-DoF).",
)
@click.option(
    "--save-aligned",
    type=click.Path(path_type=Path),
    default=None,
    help="Write the whole estimate, aligned, as TUM.",
)
@user_errors
def ate(est: Path, ref: Path, alignment: str, save_aligned: Path | None,
        inputs: TrajectoryInputs, out: Outputs, evo: EvoOptions) -> None:
    """Absolute trajectory error of EST against the reference REF.

    Poses are associated by timestamp, EST is aligned to REF (Umeyama on positions), and the
    per-pose translation [m] and rotation [deg] errors are summarised.

    \b
    Examples:
      ibiscape-eval ate est.txt groundtruth.csv
      ibiscape-eval ate orb_kf_mono.txt gt.txt --align sim3 --plot ate.png
      ibiscape-eval ate vio.txt gt.csv --align yaw --estimate-offset --json
      ibiscape-eval ate vio.txt gt.csv --t-start 1403715280 --t-end 1403715300 --change-unit cm
      ibiscape-eval ate kitti_est.txt kitti_gt.txt --format kitti --plot ate.png  # xz plane

    The order is always the estimate first, then the reference (a warning says when they look
    swapped); a warning also says when the alignment leaves the rotation error meaningless.
    """
    from ibiscape_eval.metrics import ate as ate_fn

    _panels(evo.plot_panels)  # checked before any work
    pair = _read_pair(est, ref, inputs)
    result = ate_fn(pair.est, pair.ref, align=alignment, pose_relation=evo.pose_relation,
                    project_to_plane=evo.project_to_plane, **inputs.selection(pair.match))
    if save_aligned:
        from ibiscape_eval.io import write_trajectory

        write_trajectory(save_aligned, result.alignment.apply(pair.est), "tum")
    _finish(
        result, est, ref, pair, inputs.unit, out,
        plot=lambda p: _plot_errors(p, result, pair, inputs.unit, out.gps, evo,
                                    "absolute trajectory error"),
        table=lambda doc: error_table(doc, "absolute trajectory error (ATE)"),
    )


@click.command()
@_input_options
@_evo_options
@click.option(
    "--pairs-from",
    type=click.Choice(PAIRS_FROM),
    default="est",
    show_default=True,
    help="Trajectory whose path defines the pairs in metres/degrees/seconds: est (evo) or "
    "ref (what most papers mean).",
)
@click.option(
    "--delta",
    type=click.FloatRange(min=0.0, min_open=True),
    default=1.0,
    show_default=True,
    help="Distance between the two poses of a pair, in --delta-unit.",
)
@click.option(
    "--delta-unit",
    type=click.Choice((*DELTA_UNITS, "meters")),
    default="frames",
    show_default=True,
)
@click.option(
    "--pairs",
    type=click.Choice(PAIR_MODES),
    default="consecutive",
    show_default=True,
    help="consecutive: non-overlapping pairs (evo); all: every start pose.",
)
@click.option(
    "--delta-tol",
    type=click.FloatRange(min=0.0),
    default=0.1,
    show_default=True,
    help="Relative tolerance on --delta of --pairs all in seconds/metres/degrees (evo's "
    "--delta_tol): a pair is kept when its length is within delta * (1 +- tol).",
)
@click.option(
    "--align",
    "alignment",
    type=click.Choice(ALIGNMENTS),
    default="none",
    show_default=True,
    help="Alignment before RPE (only sim3 changes RPE: it fixes the scale).",
)
@user_errors
def rpe(
    est: Path, ref: Path, delta: float, delta_unit: str, pairs: str, alignment: str,
    pairs_from: str, delta_tol: float, inputs: TrajectoryInputs, out: Outputs, evo: EvoOptions
) -> None:
    """Relative pose error of EST against REF over pose pairs DELTA apart.

    \b
    Examples:
      ibiscape-eval rpe est.txt gt.txt --delta 1 --delta-unit frames
      ibiscape-eval rpe est.txt gt.txt --delta 10 --delta-unit metres --pairs all --json
      ibiscape-eval rpe est.txt gt.txt --delta 1 --delta-unit metres --pairs all --delta-tol 0.3
    """
    from ibiscape_eval.metrics import rpe as rpe_fn

    if delta_unit == "meters":
        delta_unit = "metres"
    if delta_unit == "frames" and delta != int(delta):
        raise click.BadParameter("a delta in frames must be a whole number", param_hint="--delta")
    _panels(evo.plot_panels)  # checked before any work
    pair = _read_pair(est, ref, inputs)
    result = rpe_fn(
        pair.est,
        pair.ref,
        delta=delta,
        delta_unit=delta_unit,
        pairs=pairs,
        align=alignment,
        pose_relation=evo.pose_relation,
        project_to_plane=evo.project_to_plane,
        pairs_from=pairs_from,
        rel_tol=delta_tol,
        **inputs.selection(pair.match),
    )
    _finish(
        result, est, ref, pair, inputs.unit, out,
        plot=lambda p: _plot_errors(
            p, result, pair, inputs.unit, out.gps, evo,
            f"relative pose error, delta {delta:g} {delta_unit} ({pairs} pairs from {pairs_from})"),
        table=lambda doc: error_table(
            doc,
            f"relative pose error (RPE), delta {delta:g} {delta_unit}, {pairs} pairs: "
            f"{doc['n_pairs']} pairs",
        ),
    )


def _float_list(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        vals = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}") from None
    if not vals or any(v <= 0 for v in vals):
        raise click.BadParameter(f"expected positive numbers, got {text!r}")
    return vals


@click.command()
@_input_options
@click.option(
    "--lengths",
    default="100,200,300,400,500,600,700,800",
    show_default=True,
    help="Segment lengths in metres (KITTI).",
)
@click.option(
    "--lengths-pct",
    default=None,
    help="Segment lengths in %% of the reference length, e.g. 10,20,30,40,50 (replaces --lengths).",
)
@click.option(
    "--step-frames",
    type=click.IntRange(min=1),
    default=10,
    show_default=True,
    help="Start a segment every N frames (KITTI uses 10).",
)
@click.option(
    "--align", "alignment", type=click.Choice(ALIGNMENTS), default="none", show_default=True
)
@user_errors
def drift(
    est: Path,
    ref: Path,
    lengths: str,
    lengths_pct: str | None,
    step_frames: int,
    alignment: str,
    inputs: TrajectoryInputs,
    out: Outputs,
) -> None:
    """KITTI-style drift of EST against REF: relative error over segment lengths, in %% and deg/m.

    Lengths no segment reaches (a path shorter than them) are marked "not reached" with a hint
    to use --lengths-pct.

    \b
    Examples:
      ibiscape-eval drift est.txt gt.txt
      ibiscape-eval drift est.txt gt.txt --lengths-pct 10,20,30,40,50 --plot drift.png
    """
    from ibiscape_eval.metrics import drift as drift_fn

    if inputs.unit != "m":
        raise click.BadParameter("drift reports percent and deg/m; --change-unit applies to "
                                 "ate, rpe and compare", param_hint="--change-unit")
    lengths_m = _float_list(lengths)
    pct = _float_list(lengths_pct)
    pair = _read_pair(est, ref, inputs)
    result = drift_fn(
        pair.est,
        pair.ref,
        lengths_m=lengths_m or (),
        lengths_pct=pct,
        step_frames=step_frames,
        align=alignment,
        **inputs.selection(pair.match),
    )

    def plot(path: Path) -> None:
        from ibiscape_eval.report.plots import plot_drift

        plot_drift(path, result, title="drift per segment length")

    _finish(result, est, ref, pair, inputs.unit, out, plot=plot, table=drift_table)


__all__ = ["ate", "drift", "rpe"]
