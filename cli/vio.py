"""``ibiscape-eval vio``: the GTSAM stereo-VIO baseline on any sequence ``open_sequence`` opens."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ._common import cli_flag, echo_json, info, user_errors


def _summary(res: Any, ate_res: Any, out: Path) -> str:
    s = res.stats
    lines = [
        f"estimate   {out}  ({len(res.trajectory)} of {s.frames} frames, TUM, IMU0 in the world)",
        f"init       {s.init_method or 'never'}   keyframes {s.keyframes}   "
        f"tracked {s.mean_tracked:.0f} per frame (min {s.min_tracked})",
        f"speed      {s.mean_ms_per_frame:.1f} ms per frame, x{s.realtime_factor:.2f} real time "
        f"(CPU time: x{s.cpu_realtime_factor:.2f})",
    ]
    if s.failures:
        for f in s.failures:
            t0 = (f.start_ns - int(res.trajectory.stamps_ns[0])) * 1e-9 if len(res.trajectory) else 0
            lines.append(f"failure    {f.kind:8s} {f.duration_s:6.2f} s from t = {t0:.2f} s")
    else:
        lines.append("failures   none")
    if ate_res is not None:
        length = float(ate_res.ref.path_length_m()[-1])
        rmse = ate_res.translation_m.rmse
        lines.append(f"ATE (se3)  {rmse:.3f} m rmse over {length:.1f} m "
                     f"({100 * rmse / max(length, 1e-9):.2f} %), {ate_res.rotation_deg.rmse:.2f} deg")
    return "\n".join(lines)


@click.command(
    "vio",
    epilog="""\b
Examples:
  ibiscape-eval vio SVI_1_town -o est.txt
  ibiscape-eval vio SVI_1_town -o est.txt --json --plot top.png
  ibiscape-eval vio ESVI_1_town -o est.txt      (stereo events; RGBD_1_town: RGB + depth)
  ibiscape-eval vio MH_01_easy -o est.txt --calib camchain-imucam.yaml --imu imu.yaml
  ibiscape-eval vio run.bag -o est.txt --topic /cam0/image_raw --topic /cam1/image_raw \
      --imu-topic /imu0 --calib camchain-imucam.yaml --imu imu.yaml
  ibiscape-eval ate est.txt SVI_1_town/vehicle_gt/groundtruth_sync.csv --align se3
""",
)
@click.argument("sequence", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out", type=click.Path(path_type=Path, dir_okay=False), required=True,
              help="Estimate in TUM format (seconds): IMU0/body pose in the world per frame.")
@click.option("--calib", type=click.Path(path_type=Path), default=None,
              help="Kalibr camchain-imucam.yaml (cam0 left, cam1 right); default: the "
              "sequence's own sequence.yaml (EuRoC: cam0/cam1 sensor.yaml).")
@click.option("--imu", "imu_yaml", type=click.Path(path_type=Path), default=None,
              help="Kalibr imu.yaml with the noise densities (e.g. from `ibiscape-eval allan`).")
@click.option("--topic", "topics", multiple=True, metavar="TOPIC",
              help="SEQUENCE is a ROS bag: the left then the right image topic (give both).")
@click.option("--imu-topic", default=None, metavar="TOPIC",
              help="SEQUENCE is a ROS bag with several sensor_msgs/Imu topics: the one to use.")
@click.option("--setup", type=click.Choice(["auto", "svi", "esvi", "rgbd", "full"]), default="auto",
              show_default=True, help="Cameras: stereo RGB, stereo events, RGB + depth, or the best there is.")
@click.option("--depth-unit", type=click.Choice(["mm", "tum", "carla-log"]), default=None,
              help="RGB-D: the depth files' unit (tum: 16-bit, 5000 per metre); default by the "
              "folder: depth/mm/ millimetres, depth/frames/ CARLA's 8-bit log depth.")
@click.option("--max-frames", type=click.IntRange(min=2), default=None,
              help="Process only the first N stereo frames.")
@click.option("--lag-s", type=click.FloatRange(min=0.5), default=None,
              help="Window of the fixed-lag smoother, seconds (default 3).")
@click.option("--max-features", type=click.IntRange(min=20), default=None,
              help="Features tracked per frame (default 200).")
@click.option("--cv-threads", type=click.IntRange(min=0), default=1, show_default=True,
              help="OpenCV threads for the run (0: OpenCV's default). One is cheaper: the "
              "per-frame calls are too small to share (x real time by CPU 2.83 -> 3.43 in rain).")
@click.option("--json", "as_json", is_flag=True,
              help="Print statistics (frames, keyframes, tracked features, failures, time per "
              "frame, ATE if ground truth exists) as one JSON document.")
@click.option("--plot", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Top view of the estimate with the ground truth (PNG/PDF/SVG).")
@user_errors
def vio(sequence: Path, out: Path, calib: Path | None, imu_yaml: Path | None,
        topics: tuple[str, ...], imu_topic: str | None, setup: str, depth_unit: str | None,
        max_frames: int | None, lag_s: float | None, max_features: int | None, cv_threads: int,
        as_json: bool, plot: Path | None) -> None:
    """Stereo visual-inertial odometry (OpenCV front end, GTSAM fixed-lag smoother).

    SEQUENCE is an IBISCape-layout folder (rgbL/rgbR frames, other_sensors/imu.csv,
    sequence.yaml), an EuRoC ASL or TUM-VI folder (mav0/cam0, cam1, imu0; ground truth
    optional), or a ROS 1/2 bag (two image topics and an Imu topic).  Tracking failures (fog,
    night, a blank wall) are bridged on the IMU for a bounded time and reported with their spans.
    """
    from ibiscape_eval.io import write_trajectory
    from ibiscape_eval.io.open_sequence import open_sequence
    from ibiscape_eval.vio.inputs import stereo_inputs
    from ibiscape_eval.vio.params import VioParams
    from ibiscape_eval.vio.pipeline import run_vio

    opened = open_sequence(sequence, image_topics=topics or None, imu_topic=imu_topic)
    depth = None
    if depth_unit is not None:
        from ibiscape_eval.core.errors import IbiscapeError
        from ibiscape_eval.vio.depth import DepthOptions
        from ibiscape_eval.vio.inputs import resolve_setup

        if (chosen := resolve_setup(opened, setup)) != "rgbd":
            raise IbiscapeError(f"{sequence}: --depth-unit is for RGB + depth; this run is {chosen} "
                                "(give --setup rgbd on a sequence with a depth camera)")
        depth = DepthOptions(depth_unit=depth_unit)
    seq = stereo_inputs(opened, calib=calib, imu_yaml=imu_yaml, setup=setup, options=depth)
    kw: dict[str, Any] = {k: v for k, v in (("lag_s", lag_s), ("max_features", max_features)) if v is not None}
    params = VioParams.for_setup(seq.setup, **kw)

    from .progress import progress_bar

    total = seq.n_frames if max_frames is None else min(max_frames, seq.n_frames)
    bar = progress_bar(total, "vio", unit="frame", unit_scale=False)

    def progress(done: int, n: int, speed_up: float) -> None:
        bar.set_postfix_str(f"x{speed_up:.2f} real time", refresh=False)
        bar.update(done - bar.n)

    from ibiscape_eval.core.cpus import opencv_threads

    try:
        with opencv_threads(cv_threads):
            res = run_vio(seq, params, max_frames=max_frames, progress=progress, options=depth)
    finally:
        bar.close()
    write_trajectory(out, res.trajectory, "tum")
    ate_res = None
    if seq.groundtruth is not None and len(res.trajectory) >= 3:
        from ibiscape_eval.core.errors import IbiscapeError
        from ibiscape_eval.metrics import ate

        try:
            ate_res = ate(res.trajectory, seq.groundtruth, align="se3", max_diff_s=0.02)
        except IbiscapeError as e:  # degenerate alignment (a straight path): report, go on
            why = " ".join(e.spelt(cli_flag).split())
            info(f"note: no ATE ({why}: score {out} with `ibiscape-eval ate`)")
    if plot is not None:
        from ibiscape_eval.io.figure import save_figure
        from ibiscape_eval.vio.plots import top_view_figure

        est = ate_res.est_aligned if ate_res is not None else res.trajectory
        fig = top_view_figure(est, seq.groundtruth, res.stats.failures,
                              title=f"{Path(seq.path).name}: VIO top view")
        save_figure(fig, plot)
    if as_json:
        doc = res.to_dict()
        doc["estimate"] = str(out)
        if ate_res is not None:
            doc["ate"] = {"rmse_m": ate_res.translation_m.rmse,
                          "path_length_m": float(ate_res.ref.path_length_m()[-1]),
                          "rotation_rmse_deg": ate_res.rotation_deg.rmse,
                          "n_matched": ate_res.n_matched}
        echo_json(doc)
    else:
        click.echo(_summary(res, ate_res, out))
