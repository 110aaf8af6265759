"""``ibiscape-eval ate | rpe | drift``: trajectory metrics from two files."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from ibiscape_eval.io.detect import TRAJECTORY_FORMATS
from ibiscape_eval.metrics.alignment import Alignment
from ibiscape_eval.metrics.relations import PLANES, POSE_RELATIONS
from ibiscape_eval.metrics.rpe import DELTA_UNITS, PAIR_MODES, PAIRS_FROM
from ibiscape_eval.report.plots import PANELS, PLOT_PLANES

from ._common import echo_json, info, user_errors

ALIGNMENTS = tuple(a.value for a in Alignment)
FORMATS = ("auto", *TRAJECTORY_FORMATS)


def _input_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Options shared by the three trajectory commands (reading, association, alignment, output)."""
    opts = [
        click.argument("est", type=click.Path(path_type=Path)),
        click.argument("ref", type=click.Path(path_type=Path)),
        click.option(
            "--format",
            "fmt",
            type=click.Choice(FORMATS),
            default="auto",
            show_default=True,
            help="Format of both files (auto detects from name and content).",
        ),
        click.option(
            "--format-est",
            type=click.Choice(FORMATS),
            default=None,
            help="Format of EST, overrides --format.",
        ),
        click.option(
            "--format-ref",
            type=click.Choice(FORMATS),
            default=None,
            help="Format of REF, overrides --format.",
        ),
        click.option(
            "--topic", default=None, help="Bag topic for both files (tf: '/tf:parent.child')."
        ),
        click.option("--topic-est", default=None, help="Bag topic of EST."),
        click.option("--topic-ref", default=None, help="Bag topic of REF."),
        click.option(
            "--times-est",
            type=click.Path(path_type=Path),
            default=None,
            help="KITTI times file (s, one per line) for EST.",
        ),
        click.option(
            "--times-ref",
            type=click.Path(path_type=Path),
            default=None,
            help="KITTI times file (s, one per line) for REF.",
        ),
        click.option(
            "--max-diff-s",
            type=click.FloatRange(min=0.0),
            default=0.01,
            show_default=True,
            help="Largest time difference of an associated pose pair, seconds.",
        ),
        click.option(
            "--offset-s",
            type=float,
            default=0.0,
            show_default=True,
            help="Constant time offset added to EST stamps, seconds.",
        ),
        click.option(
            "--estimate-offset",
            is_flag=True,
            help="Estimate the time offset between EST and REF and report it.",
        ),
        click.option(
            "--interpolate",
            is_flag=True,
            help="Interpolate the denser trajectory at the sparser one's stamps.",
        ),
        click.option(
            "--n-align",
            type=click.IntRange(min=1),
            default=None,
            help="Align on the first N matched poses only.",
        ),
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
            default="xy",
            show_default=True,
            help="Plane of the trajectory panel (KITTI's camera frame: xz).",
        ),
        click.option(
            "--plot-panels",
            default=None,
            help=f"Comma-separated panels of the figure, from {','.join(PANELS)} (default all).",
        ),
    ]
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


def swap_warning(est: Any, ref: Any, fmt_est: str, fmt_ref: str) -> str | None:
    """A warning when EST looks like the reference: much denser than REF and in a ground-truth
    format (EuRoC's) or the reference's own format, e.g. EuRoC ground truth given as EST."""
    if len(ref) == 0 or len(est) < 4 * len(ref):
        return None
    if fmt_est != "euroc" and fmt_est != fmt_ref:
        return None
    return (
        f"warning: EST {est.name} has {len(est)} poses, {len(est) / len(ref):.0f}x as many as "
        f"REF {ref.name} ({len(ref)}), in format {fmt_est}: it looks like the ground truth. "
        "The order is EST then REF; swap them if so"
    )


def _read_pair(est: Path, ref: Path, o: dict[str, Any]) -> tuple[Any, Any, str]:
    """Read both trajectories, say which formats were used, and choose time or index pairing."""
    from ibiscape_eval.io import detect_trajectory_format, has_timestamps, read_trajectory
    from ibiscape_eval.metrics import choose_match

    from .startup import numba_startup

    trajs, timed, fmts = [], [], []
    with numba_startup():
        for path, side in ((est, "est"), (ref, "ref")):
            fmt = o[f"format_{side}"] or o["fmt"]
            if fmt == "auto":
                fmt = detect_trajectory_format(path)
                info(f"{path}: format {fmt} (detected; force another with --format-{side})")
            times = o[f"times_{side}"]
            topic = o[f"topic_{side}"] or o["topic"]
            if fmt == "bag" and topic is not None:
                from .convert import tf_hint

                tf_hint(path, topic)
            trajs.append(
                read_trajectory(
                    path,
                    fmt,
                    topic=topic,
                    times_path=None if times is None else str(times),
                    name=path.name,
                )
            )
            timed.append(has_timestamps(fmt, times))
            fmts.append(fmt)
    warn = swap_warning(trajs[0], trajs[1], fmts[0], fmts[1])
    if warn:
        info(warn)
    match = choose_match(*timed)
    if match == "index":
        info("KITTI poses without a times file: pairing poses by index")
    return trajs[0], trajs[1], match


def _assoc_kwargs(o: dict[str, Any], match: str) -> dict[str, Any]:
    return {
        "max_diff_s": o["max_diff_s"],
        "offset_s": o["offset_s"],
        "estimate_offset": o["estimate_offset"],
        "interpolate": o["interpolate"],
        "match": match,
        "n_align": o["n_align"],
    }


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


def _finish(result: Any, est: Path, ref: Path, o: dict[str, Any], *,
            plot: Callable[[Path], None], table: Callable[[dict[str, Any]], str]) -> None:
    """The ending the three commands share: counts, --save-csv, --plot, then JSON or the table."""
    from ibiscape_eval.report import format_header

    doc = result.to_dict()
    if o["as_json"]:  # the table's header line says the same on stdout
        _report_counts(doc)
    if o["save_csv"]:
        _write_csv(o["save_csv"], result.to_frame())
    if o["plot"]:
        plot(o["plot"])
    if o["as_json"]:
        echo_json(doc)
    else:
        click.echo(format_header(doc, est.name, ref.name))
        click.echo(table(doc))
        line = relation_line(doc)
        if line:
            click.echo(line)


def _gps_positions(path: Path | None, ref: Any) -> Any:
    if path is None:
        return None
    from ibiscape_eval.io import read_gnss
    from ibiscape_eval.metrics.gnss import gnss_in_reference_frame

    fixes = read_gnss(path)
    return gnss_in_reference_frame(fixes.stamps_ns, fixes.lat_deg, fixes.lon_deg, fixes.alt_m, ref)


def _plot_errors(path: Path, result: Any, ref_full: Any, o: dict[str, Any], title: str) -> None:
    from ibiscape_eval.metrics.relations import RELATION_UNITS
    from ibiscape_eval.report.plots import plot_trajectory_errors

    ref = result.ref
    idx = getattr(result, "first_index", None)
    path_len = ref.path_length_m()
    dist = path_len if idx is None else path_len[idx]
    rel = result.pose_relation
    labels = {"trans": "translation error", "rot-angle": "rotation error",
              "rot-part": "rotation part ||R-I||", "full": "full ||E-I||",
              "point-distance": "point distance error"}
    plot_trajectory_errors(
        path,
        est_aligned=result.est_aligned,
        ref=ref,
        stamps_ns=result.stamps_ns,
        errors_m=result.errors_m,
        errors_deg=result.errors_deg,
        errors=result.errors,
        error_label=labels[rel],
        error_unit=RELATION_UNITS[rel],
        title=title,
        gps_xyz_m=_gps_positions(o["gps"], ref_full),
        distance_m=dist,
        plane=o["plot_plane"],
        panels=_panels(o["plot_panels"]),
        aligned=result.alignment.method,
        color_index=idx,
    )


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
def ate(est: Path, ref: Path, alignment: str, save_aligned: Path | None, **o: Any) -> None:
    """Absolute trajectory error of EST against the reference REF.

    Poses are associated by timestamp, EST is aligned to REF (Umeyama on positions), and the
    per-pose translation [m] and rotation [deg] errors are summarised.

    \b
    Examples:
      ibiscape-eval ate est.txt groundtruth.csv
      ibiscape-eval ate orb_kf_mono.txt gt.txt --align sim3 --plot ate.png
      ibiscape-eval ate vio.txt gt.csv --align yaw --estimate-offset --json
    """
    from ibiscape_eval.metrics import ate as ate_fn
    from ibiscape_eval.report import format_error_table

    _panels(o["plot_panels"])  # checked before any work
    est_t, ref_t, match = _read_pair(est, ref, o)
    result = ate_fn(est_t, ref_t, align=alignment, pose_relation=o["pose_relation"],
                    project_to_plane=o["project_to_plane"], **_assoc_kwargs(o, match))
    if save_aligned:
        from ibiscape_eval.io import write_trajectory

        write_trajectory(save_aligned, result.alignment.apply(est_t), "tum")
    _finish(
        result, est, ref, o,
        plot=lambda p: _plot_errors(p, result, ref_t, o, "absolute trajectory error"),
        table=lambda doc: format_error_table(doc, title="absolute trajectory error (ATE)"),
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
    pairs_from: str, **o: Any
) -> None:
    """Relative pose error of EST against REF over pose pairs DELTA apart.

    \b
    Examples:
      ibiscape-eval rpe est.txt gt.txt --delta 1 --delta-unit frames
      ibiscape-eval rpe est.txt gt.txt --delta 10 --delta-unit metres --pairs all --json
    """
    from ibiscape_eval.metrics import rpe as rpe_fn
    from ibiscape_eval.report import format_error_table

    if delta_unit == "meters":
        delta_unit = "metres"
    if delta_unit == "frames" and delta != int(delta):
        raise click.BadParameter("a delta in frames must be a whole number", param_hint="--delta")
    _panels(o["plot_panels"])  # checked before any work
    est_t, ref_t, match = _read_pair(est, ref, o)
    result = rpe_fn(
        est_t,
        ref_t,
        delta=delta,
        delta_unit=delta_unit,
        pairs=pairs,
        align=alignment,
        pose_relation=o["pose_relation"],
        project_to_plane=o["project_to_plane"],
        pairs_from=pairs_from,
        **_assoc_kwargs(o, match),
    )
    _finish(
        result, est, ref, o,
        plot=lambda p: _plot_errors(
            p, result, ref_t, o,
            f"relative pose error, delta {delta:g} {delta_unit} ({pairs} pairs from {pairs_from})"),
        table=lambda doc: format_error_table(
            doc,
            title=f"relative pose error (RPE), delta {delta:g} {delta_unit}, {pairs} pairs: "
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
    **o: Any,
) -> None:
    """KITTI-style drift of EST against REF: relative error over segment lengths, in %% and deg/m.

    \b
    Examples:
      ibiscape-eval drift est.txt gt.txt
      ibiscape-eval drift est.txt gt.txt --lengths-pct 10,20,30,40,50 --plot drift.png
    """
    from ibiscape_eval.metrics import drift as drift_fn
    from ibiscape_eval.report import format_drift_table

    lengths_m = _float_list(lengths)
    pct = _float_list(lengths_pct)
    est_t, ref_t, match = _read_pair(est, ref, o)
    result = drift_fn(
        est_t,
        ref_t,
        lengths_m=lengths_m or (),
        lengths_pct=pct,
        step_frames=step_frames,
        align=alignment,
        **_assoc_kwargs(o, match),
    )
    def plot(path: Path) -> None:
        from ibiscape_eval.report.plots import plot_drift

        plot_drift(path, result, title="drift per segment length")

    _finish(result, est, ref, o, plot=plot, table=format_drift_table)


__all__ = ["ate", "drift", "rpe"]
