"""``ibiscape-eval events ...``: event-camera utilities (accumulation frames, time surfaces)."""

from __future__ import annotations

from pathlib import Path

import click

from ibiscape_eval.events.frames import KINDS as FRAME_KINDS

from ._common import EVENT_FORMAT_CHOICES, echo_json, info, parse_sensor_size, user_errors
from .progress import progress_bar


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def events() -> None:
    """Event-camera utilities.

    \b
    Examples:
      ibiscape-eval events frames davisL --out frames/ --rate-hz 20
      ibiscape-eval events frames events.txt --out ts/ --kind time-surface --window-ms 10
    """


@events.command("frames")
@click.argument("events_path", metavar="EVENTS", type=click.Path(path_type=Path))
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Folder for <t_end_ns>.png frames and their timestamps.csv.")
@click.option("--rate-hz", type=click.FloatRange(min=0.0, min_open=True), default=None,
              help="One frame every 1/R s (default 20 Hz when --window-ms is not given).")
@click.option("--window-ms", type=click.FloatRange(min=0.0, min_open=True), default=None,
              help="Events integrated per frame, ms (default one frame period); alone, frames "
              "follow each other window after window.")
@click.option("--kind", type=click.Choice(FRAME_KINDS), default="accumulate",
              show_default=True, help="Accumulation frame or exponential-decay time surface.")
@click.option("--unsigned", is_flag=True,
              help="Ignore polarity (count all events; time surface in [0, 1]).")
@click.option("--tau-ms", type=click.FloatRange(min=0.0, min_open=True), default=30.0,
              show_default=True, help="Time-surface decay constant, ms.")
@click.option("--sensor-size", default=None, metavar="WxH",
              help="Sensor size in pixels (default: from the file or the data).")
@click.option("--format", "fmt", type=click.Choice(EVENT_FORMAT_CHOICES), default="auto", show_default=True,
              help="Input format.")
@click.option("--topic", default=None, metavar="NAME",
              help="ROS bag: the dvs_msgs/EventArray topic; AEDAT4: the event stream id; "
              "sequence folder: the DVS camera.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout.")
@user_errors
def frames(
    events_path: Path,
    out_dir: Path,
    rate_hz: float | None,
    window_ms: float | None,
    kind: str,
    unsigned: bool,
    tau_ms: float,
    sensor_size: str | None,
    fmt: str,
    topic: str | None,
    as_json: bool,
) -> None:
    """Render EVENTS as accumulation frames or time surfaces (PNG, one per window).

    Accumulation frames map zero to grey (signed) or black (--unsigned); time surfaces show
    exp(-(t_frame - t_last) / tau) of each pixel's latest event.

    \b
    Examples:
      ibiscape-eval events frames FULL_Dynamic_1/davisL --out frames/ --rate-hz 20
      ibiscape-eval events frames events.h5 --out ts/ --kind time-surface --tau-ms 50
      ibiscape-eval events frames dvxplorer.aedat4 --out frames/ --rate-hz 30
    """
    from functools import partial

    from ibiscape_eval.core.events import Events
    from ibiscape_eval.events.frames import frame_to_uint8, iter_frames
    from ibiscape_eval.io.events import iter_event_chunks, open_events, write_frames_png

    size = parse_sensor_size(sensor_size)
    src = open_events(events_path, fmt=None if fmt == "auto" else fmt, topic=topic)
    ev = Events.concatenate([c.events for c in iter_event_chunks(src)])
    if size is None and src.sensor_size is None:
        size = (int(ev.x.max()) + 1, int(ev.y.max()) + 1) if len(ev) else (1, 1)
        info(f"note: {events_path}: sensor size {size[0]}x{size[1]} inferred from the largest "
             "event coordinates (the file does not say); give --sensor-size WxH if the sensor "
             "is larger")
    size = size or src.sensor_size
    assert size is not None
    if rate_hz is None and window_ms is None:
        rate_hz = 20.0
    signed = not unsigned
    it = iter_frames(
        ev, sensor_size=size, kind=kind, rate_hz=rate_hz,
        window_ns=None if window_ms is None else round(window_ms * 1e6),
        signed=signed, tau_ns=round(tau_ms * 1e6),
    )
    with progress_bar(None, "frames", unit="ev") as bar:
        n = write_frames_png(out_dir, it, to_uint8=partial(frame_to_uint8, kind=kind, signed=signed),
                             progress=bar.update)
    doc = {"input": str(events_path), "format": src.fmt, "sensor_size": list(size),
           "n_events": len(ev), "n_frames": n, "kind": kind, "signed": signed,
           "rate_hz": rate_hz, "window_ms": window_ms, "out": str(out_dir)}
    if as_json:
        echo_json(doc)
    else:
        click.echo(f"wrote {n} {kind} frames ({size[0]}x{size[1]}) from {len(ev):,} events to {out_dir}")
