"""``ibiscape-eval convert``: rewrite a trajectory in another format."""

from __future__ import annotations

from pathlib import Path

import click

from ibiscape_eval.io.detect import TRAJECTORY_FORMATS
from ibiscape_eval.io.trajectory import WRITABLE_FORMATS

from ._common import check_tf_topic, echo_json, info, user_errors


@click.command()
@click.argument("src", type=click.Path(path_type=Path))
@click.argument("dst", type=click.Path(path_type=Path))
@click.option(
    "--from",
    "src_fmt",
    type=click.Choice(("auto", *TRAJECTORY_FORMATS)),
    default="auto",
    show_default=True,
    help="Format of SRC.",
)
@click.option(
    "--to",
    "dst_fmt",
    type=click.Choice(WRITABLE_FORMATS),
    default="tum",
    show_default=True,
    help="Format of DST.",
)
@click.option("--topic", default=None, help="Bag topic (tf: '/tf:parent.child').")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON document (source, formats, poses, files written) on stdout.")
@click.option(
    "--times",
    type=click.Path(path_type=Path),
    default=None,
    help="KITTI times file for SRC (s, one per line).",
)
@user_errors
def convert(
    src: Path, dst: Path, src_fmt: str, dst_fmt: str, topic: str | None, times: Path | None,
    as_json: bool,
) -> None:
    """Convert the trajectory SRC into DST (written atomically).

    IBISCape files are converted between CARLA's left-handed frame and the right-handed frame used
    everywhere else; a KITTI DST gets its stamps in a times file beside it (``gt.txt`` -> ``gt.times.txt``),
    unless SRC had none (KITTI without --times: its stamps are synthetic, and a warning says so
    when they are written to another format).

    \b
    Examples:
      ibiscape-eval convert vehicle_gt/groundtruth_sync.csv gt_tum.txt --to tum
      ibiscape-eval convert run.bag est.txt --topic /odom
    """
    from ibiscape_eval.io import detect_trajectory_format, read_trajectory, write_trajectory

    if src_fmt == "auto":
        src_fmt = detect_trajectory_format(src)
        info(f"{src}: format {src_fmt} (detected; force another with --from)")
    if src_fmt == "bag" and topic is not None:
        check_tf_topic(src, topic)
    traj = read_trajectory(
        src, src_fmt, topic=topic, times_path=None if times is None else str(times)
    )
    if traj.stamps_synthetic and dst_fmt != "kitti":
        info(f"warning: {src} has no timestamps (KITTI poses without a times file): the stamps "
             f"written to {dst} are synthetic, the pose index x 0.1 s; give --times to write "
             "real ones")
    times = (dst.with_name(dst.stem + ".times.txt")
             if dst_fmt == "kitti" and not traj.stamps_synthetic else None)
    write_trajectory(dst, traj, dst_fmt, times_path=times)
    info(f"wrote {len(traj)} poses to {dst} ({dst_fmt})" + (f" and their stamps to {times}" if times else ""))
    if as_json:
        echo_json({"src": str(src), "from": src_fmt, "dst": str(dst), "to": dst_fmt,
                   "topic": topic, "n_poses": len(traj),
                   "times": None if times is None else str(times),
                   "stamps": "synthetic" if traj.stamps_synthetic else "measured",
                   "start_ns": int(traj.stamps_ns[0]) if len(traj) else None,
                   "end_ns": int(traj.stamps_ns[-1]) if len(traj) else None})
