"""``ibiscape-eval hotpix``: detect and remove DVS hot pixels."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import click

from ibiscape_eval.io.events import FORMATS as EVENT_FORMATS

from ._common import echo_json, info, user_errors
from .progress import progress_bar

FORMAT_CHOICES = ("auto", *EVENT_FORMATS)


def parse_sensor_size(text: str | None) -> tuple[int, int] | None:
    """``"346x260"`` -> (346, 260)."""
    from ibiscape_eval.core.errors import IbiscapeError

    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*[xX,]\s*(\d+)\s*", text)
    if not m or int(m.group(1)) == 0 or int(m.group(2)) == 0:
        raise IbiscapeError(f"--sensor-size must look like WIDTHxHEIGHT (e.g. 346x260), got {text!r}")
    return int(m.group(1)), int(m.group(2))


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
@click.option("--format", "fmt", type=click.Choice(FORMAT_CHOICES), default="auto", show_default=True,
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
    import numpy as np

    from ibiscape_eval.core.errors import FormatError, IbiscapeError
    from ibiscape_eval.events.hotpix import PixelCounter, filter_events, hot_pixels_from_counts
    from ibiscape_eval.io.atomic import atomic_output_path
    from ibiscape_eval.io.events import (
        iter_event_chunks,
        open_events,
        read_hot_pixels,
        write_filtered_events,
        write_hot_pixels,
    )

    if apply_path is not None and (top_n is not None or n_sigma is not None or rate_min_events):
        raise IbiscapeError("--apply uses a given hot-pixel list; drop --top-n/--n-sigma/--rate-*")
    if (rate_min_events is None) != (rate_window_ms is None):
        raise IbiscapeError("the rate criterion needs both --rate-min-events and --rate-window-ms")
    size = parse_sensor_size(sensor_size)
    src = open_events(events, fmt=None if fmt == "auto" else fmt, topic=topic)
    size = size or src.sensor_size
    applied = read_hot_pixels(apply_path) if apply_path is not None else None

    counter = PixelCounter(
        sensor_size=size,
        per_polarity=per_polarity,
        rate_min_events=rate_min_events,
        rate_window_ns=None if rate_window_ms is None else round(rate_window_ms * 1e6),
    )
    with progress_bar(src.n_events, "counting", unit="ev") as bar:
        for chunk in iter_event_chunks(src, reuse_buffers=True):  # the counter keeps nothing
            counter.add(chunk.events, chunk)
            bar.update(len(chunk.events))
    size = counter.sensor_size
    if parse_sensor_size(sensor_size) is None and src.sensor_size is None:
        info(f"note: {events}: sensor size {size[0]}x{size[1]} inferred from the largest event "
             "coordinates (the file does not say); give --sensor-size WxH if the sensor is larger")
    if applied is not None:
        w, h = size
        out = (applied[:, 0] >= w) | (applied[:, 1] >= h)
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise FormatError(
                apply_path, f"hot pixel ({applied[i, 0]}, {applied[i, 1]}) lies outside the {w}x{h} "
                "sensor; is it the list of this camera? (or pass --sensor-size WxH)",
                line=None,
            )
        result = hot_pixels_from_counts(counter.count_map, extra_pixels=applied)
    else:
        result = counter.result(top_n=top_n, n_sigma=n_sigma)

    if hot_out is not None:
        write_hot_pixels(hot_out, result.pixels)
    n_written = None
    if filtered_out is not None:
        pixels = result.pixels

        def keep(ev: Any) -> Any:
            return filter_events(ev, pixels, sensor_size=size)

        with progress_bar(counter.n_events, "filtering", unit="ev") as bar:
            _, n_written = write_filtered_events(src, filtered_out, keep, progress=bar.update)
    if plot is not None:
        from ibiscape_eval.events.plots import hot_pixel_figure

        fig = hot_pixel_figure(result, title="events per pixel before and after hot-pixel removal")
        with atomic_output_path(plot) as tmp:
            fig.savefig(tmp, dpi=110)

    doc: dict[str, Any] = {"input": str(events), "format": src.fmt, **result.to_dict()}
    doc["sensor_size"] = list(size)
    doc["sensor_size_from"] = ("--sensor-size" if parse_sensor_size(sensor_size) is not None
                               else src.size_from or "the largest event coordinates")
    doc["criteria"] = {
        "applied_list": None if apply_path is None else str(apply_path),
        **doc["criteria"],
        "per_polarity": per_polarity,
        "rate_min_events": rate_min_events,
        "rate_window_ms": rate_window_ms,
    }
    doc["outputs"] = {
        "hot_pixels": None if hot_out is None else str(hot_out),
        "filtered": None if filtered_out is None else str(filtered_out),
        "n_written": n_written,
        "plot": None if plot is None else str(plot),
    }
    if as_json:
        echo_json(doc)
        return
    w, h = size
    click.echo(f"input        {events} ({src.fmt}, {w}x{h} px)")
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
