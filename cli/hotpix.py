"""``ibiscape-eval hotpix``: detect and remove DVS hot pixels."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ._common import EVENT_FORMAT_CHOICES, echo_json, info, parse_sensor_size, user_errors
from .progress import progress_bar


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("events", type=click.Path(path_type=Path))
@click.option("--top-n", type=click.IntRange(min=0), default=None,
              help="Hot if among the N pixels with the most events.")
@click.option("--n-sigma", type=float, default=None,
              help="Hot if count > mean + S x std over the pixels that fired (population std). "
              "Default 5 when no other criterion is given; with --top-n, the union.")
@click.option("--rate-min-events", type=click.IntRange(min=1), default=None,
              help="libcaer-like rate criterion: hot if >= K events within one --rate-window-ms.")
@click.option("--rate-window-ms", type=click.FloatRange(min=0.0, min_open=True), default=None,
              help="Window of the rate criterion, milliseconds.")
@click.option("--per-polarity", is_flag=True,
              help="Judge positive and negative events separately (hot if hot in either).")
@click.option("--sensor-size", default=None, metavar="WxH",
              help="Sensor size in pixels, e.g. 346x260 (default: from the file or the data).")
@click.option("--apply", "apply_path", type=click.Path(path_type=Path), default=None,
              help="Use this hot_pixels.txt (x, y per line) instead of detecting.")
@click.option("--hot-out", type=click.Path(path_type=Path), default=None,
              help="Write the hot pixels here (hot_pixels.txt format: 'x, y' per line).")
@click.option("--filtered-out", type=click.Path(path_type=Path), default=None,
              help="Write the events without the hot pixels here, in the input's format "
              "(a new folder for an IBISCape DVS folder).")
@click.option("--format", "fmt", type=click.Choice(EVENT_FORMAT_CHOICES), default="auto", show_default=True,
              help="Input format (auto: folder -> ibiscape (a ROS 2 bag folder -> bag), .npz, "
              ".txt -> text, .h5 -> hdf5, .aedat4, .bag/.db3/.mcap -> bag).")
@click.option("--topic", default=None, metavar="NAME",
              help="ROS bag: the dvs_msgs/EventArray topic; AEDAT4: the event stream id; "
              "sequence folder: the DVS camera (needed when there are several).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout.")
@click.option("--plot", type=click.Path(path_type=Path), default=None,
              help="Save count histograms before/after (log scale) and a sensor heat map.")
@user_errors
def hotpix(
    events: Path,
    top_n: int | None,
    n_sigma: float | None,
    rate_min_events: int | None,
    rate_window_ms: float | None,
    per_polarity: bool,
    sensor_size: str | None,
    apply_path: Path | None,
    hot_out: Path | None,
    filtered_out: Path | None,
    fmt: str,
    topic: str | None,
    as_json: bool,
    plot: Path | None,
) -> None:
    """Detect and remove DVS hot pixels in EVENTS.

    EVENTS is an IBISCape DVS folder (timestamps.csv + events/<ns>.npz) or a sequence folder
    with one DVS camera, an .npz file, an rpg/ESIM text file (t x y p, seconds), an .h5 file
    (DSEC/E2CALIB, event_utils), an AEDAT4 file (iniVation DV) or a ROS 1/2 bag with
    dvs_msgs/EventArray.  The sensor size is taken from the file or sequence.yaml when they
    state it.  Per-pixel event counts
    over the whole recording decide: the --top-n N largest counts, counts above
    mean + --n-sigma S x std (default S = 5, as dvs_tools), and/or a rate criterion.  Files larger
    than memory are streamed.

    \b
    Examples:
      ibiscape-eval hotpix FULL_Dynamic_1/davisL --n-sigma 5 --hot-out hot_pixels.txt \\
          --filtered-out davisL_filtered --plot hotpix.png
      ibiscape-eval hotpix events.txt --top-n 20 --sensor-size 346x260 --json
      ibiscape-eval hotpix events.h5 --apply hot_pixels.txt --filtered-out events_clean.h5
      ibiscape-eval hotpix dvxplorer.aedat4 --top-n 10 --hot-out hot_pixels.txt
      ibiscape-eval hotpix recording.bag --topic /dvs/events --n-sigma 5
    """
    from ibiscape_eval.events.pipeline import HotPixelCriteria, hot_pixels
    from ibiscape_eval.io.events import open_events

    criteria = HotPixelCriteria(top_n=top_n, n_sigma=n_sigma, rate_min_events=rate_min_events,
                                rate_window_ms=rate_window_ms, per_polarity=per_polarity)
    criteria.check(applied=apply_path is not None)
    size = parse_sensor_size(sensor_size)
    src = open_events(events, fmt=None if fmt == "auto" else fmt, topic=topic)
    with progress_bar(src.n_events, "counting", unit="ev") as bar:
        run = hot_pixels(src, criteria, sensor_size=size, apply_path=apply_path,
                         progress=bar.update)
    w, h = run.sensor_size
    if run.size_inferred:
        info(f"note: {events}: sensor size {w}x{h} inferred from the largest event "
             "coordinates (the file does not say); give --sensor-size WxH if the sensor is larger")
    outputs = _write_outputs(run, hot_out, filtered_out, plot)
    doc: dict[str, Any] = {"input": str(events), "format": src.fmt, **run.result.to_dict()}
    doc["sensor_size"] = [w, h]
    doc["sensor_size_from"] = "--sensor-size" if size is not None else run.size_from
    doc["criteria"] = {
        "applied_list": None if apply_path is None else str(apply_path),
        **doc["criteria"],
        "per_polarity": per_polarity,
        "rate_min_events": rate_min_events,
        "rate_window_ms": rate_window_ms,
    }
    doc["outputs"] = outputs
    if as_json:
        echo_json(doc)
    else:
        _print_table(events, run, doc)


def _write_outputs(run: Any, hot_out: Path | None, filtered_out: Path | None,
                   plot: Path | None) -> dict[str, Any]:
    """Write the hot-pixel list, the filtered events and the figure that were asked for."""
    from ibiscape_eval.events.hotpix import filter_events
    from ibiscape_eval.io.events import write_filtered_events, write_hot_pixels
    from ibiscape_eval.io.figure import save_figure

    result = run.result
    if hot_out is not None:
        write_hot_pixels(hot_out, result.pixels)
    n_written = None
    if filtered_out is not None:
        def keep(ev: Any) -> Any:
            return filter_events(ev, result.pixels, sensor_size=run.sensor_size)

        with progress_bar(result.n_events, "filtering", unit="ev") as bar:
            _, n_written = write_filtered_events(run.source, filtered_out, keep,
                                                 progress=bar.update)
    if plot is not None:
        save_figure(run.plot(), plot)
    return {
        "hot_pixels": None if hot_out is None else str(hot_out),
        "filtered": None if filtered_out is None else str(filtered_out),
        "n_written": n_written,
        "plot": None if plot is None else str(plot),
    }


def _print_table(events: Path, run: Any, doc: dict[str, Any]) -> None:
    import numpy as np

    result, (w, h) = run.result, run.sensor_size
    click.echo(f"input        {events} ({run.source.fmt}, {w}x{h} px)")
    click.echo(f"events       {result.n_events:,} on {doc['n_pixels_fired']:,} pixels")
    if np.isfinite(result.threshold):
        click.echo(f"threshold    {result.threshold:.1f} events (mean {result.mean:.1f} + "
                   f"{result.n_sigma:g} x std {result.std:.1f})")
    click.echo(f"hot pixels   {len(result.pixels)}")
    click.echo(f"discarded    {result.n_discarded:,} events ({100 * result.fraction_discarded:.2f} %)")
    shown = 20
    if len(result.pixels):
        click.echo("     x      y    events")
        for (x, y), c in list(zip(result.pixels, result.counts, strict=True))[:shown]:
            click.echo(f"{int(x):6d} {int(y):6d} {int(c):9d}")
        if len(result.pixels) > shown:
            info(f"... {len(result.pixels) - shown} more hot pixels (use --hot-out or --json)")
