"""``ibiscape-eval calib``: camera calibration from image folders (checkerboard / AprilGrid)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ._common import echo_json, info, parse_sensor_size, user_errors

MODEL_CHOICES = ("pinhole-radtan", "pinhole-equi")
RECON_CHOICES = ("auto", "log-intensity", "accumulate-signed", "accumulate", "time-surface")


def _bar(desc: str) -> Any:
    from .progress import progress_bar

    return progress_bar(0, desc, unit="img", unit_scale=False, delay_s=1.0)


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("seq", required=False, type=click.Path(path_type=Path))
@click.option("--target", "target_path", type=click.Path(path_type=Path), default=None,
              help="Kalibr target yaml (default: the 'target' of SEQ/sequence.yaml).")
@click.option("--model", type=click.Choice(MODEL_CHOICES), default="pinhole-radtan", show_default=True,
              help="Camera model (Kalibr's names).")
@click.option("--images", "image_specs", multiple=True, metavar="NAME=GLOB",
              help="An image set per camera, in chain order (repeat), e.g. cam0='left*.jpg'; paired "
              "by a number in the names, else by order.")
@click.option("--cameras", default=None, metavar="A,B",
              help="Camera folders of SEQ to use, in chain order (default: all of rgbL, rgbR, rgb, "
              "davisL, davisR / mav0/camN / the bag's image topics found).")
@click.option("--topic", "topics", multiple=True, metavar="TOPIC",
              help="SEQ is a ROS bag: an image topic per camera, in chain order (repeat), e.g. "
              "--topic /cam0/image_raw --topic /cam1/image_raw.")
@click.option("--imu-topic", default=None, metavar="TOPIC",
              help="SEQ is a ROS bag with several sensor_msgs/Imu topics: the one to use (--imu).")
@click.option("--yaml", "yaml_out", type=click.Path(path_type=Path), default=None,
              help="Write the result as a Kalibr camchain.yaml.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout.")
@click.option("--plot", "plot_dir", type=click.Path(path_type=Path), default=None,
              help="Folder for residual scatter plots and corner-coverage heat maps per camera.")
@click.option("--check", "check_path", type=click.Path(path_type=Path), default=None,
              help="Evaluate this camchain.yaml on the images instead of calibrating.")
@click.option("--max-views", type=click.IntRange(min=3), default=60, show_default=True,
              help="Views kept for the solve (chosen for coverage and pose diversity).")
@click.option("--max-frames", type=click.IntRange(min=3), default=300, show_default=True,
              help="Frames searched for the target (the sharpest of each time slice of long sequences).")
@click.option("--reconstruction", type=click.Choice(RECON_CHOICES), default="auto", show_default=True,
              help="Event cameras: how frames are reconstructed from the events (log-intensity: "
              "leaky integration across windows, for moving cameras; accumulate-signed: one window, "
              "for blinking targets; auto: the one on which most corners are found).")
@click.option("--event-corners", type=click.Choice(["events", "frames"]), default="events", show_default=True,
              help="Event cameras, checkerboards: refine the corners found in the reconstructed frames "
              "from the events' timestamps (events), or keep the frames' corners (frames).")
@click.option("--sensor-size", default=None, metavar="WxH",
              help="Event cameras: sensor size when sequence.yaml does not give it.")
@click.option("--outlier-sigma", type=click.FloatRange(min=1.0), default=5.0, show_default=True,
              help="Corners beyond this many robust standard deviations are rejected.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Detection threads (default: the usable CPUs).")
@click.option("--imu", "imu_yaml", type=str, default=None, is_flag=False, flag_value="",
              metavar="[IMU_YAML]",
              help="Camera-IMU calibration: the IMU's Kalibr imu.yaml (the allan command's output, or a "
              "sequence.yaml); without a file (SEQ first: calib SEQ --imu) the noise SEQ/sequence.yaml "
              "states; estimates T_cam_imu and timeshift_cam_imu of every camera (--yaml writes "
              "camchain-imucam.yaml).")
@click.option("--cams", "cams_path", type=click.Path(path_type=Path), default=None,
              help="With --imu: take the intrinsics from this Kalibr camchain.yaml (default: "
              "calibrate the cameras on the same frames).")
@click.option("--imu-data", "imu_data", type=click.Path(path_type=Path), default=None,
              help="With --imu: IMU csv (#timestamp [ns], w_xyz, a_xyz) instead of SEQ's "
              "other_sensors/imu0.csv.")
@click.option("--force", is_flag=True,
              help="With --imu: estimate even when the rotation excites too few axes to observe the "
              "translation (the weak directions are marked).")
@click.option("--frame-step", type=click.IntRange(min=1), default=1, show_default=True,
              help="With --imu: use every n-th frame.")
@user_errors
def calib(seq: Path | None, target_path: Path | None, model: str, image_specs: tuple[str, ...],
          cameras: str | None, topics: tuple[str, ...], imu_topic: str | None,
          yaml_out: Path | None, as_json: bool, plot_dir: Path | None,
          check_path: Path | None, max_views: int, max_frames: int, reconstruction: str,
          event_corners: str, sensor_size: str | None, outlier_sigma: float, workers: int | None,
          imu_yaml: str | None = None, cams_path: Path | None = None, imu_data: Path | None = None,
          force: bool = False, frame_step: int = 1) -> None:
    """Calibrate cameras from checkerboard or AprilGrid images (mono, stereo, chains; RGB and DVS).

    SEQ is any recording ibiscape-eval opens (README "Sequence layouts"): an IBISCape sequence
    (camera folders rgbL, rgbR, rgb, davisL, davisR with timestamps.csv), an EuRoC/ASL or TUM-VI
    folder (mav0/camN), a ROS 1/2 bag (image topics, --topic).  Without SEQ give --images per
    camera.
    Prints intrinsics with standard deviations, Kalibr's reprojection error
    [mean_x, mean_y] +- [std_x, std_y] px, the RMS and the baselines; when SEQ/sequence.yaml holds
    the true cameras, every estimate beside its truth and error.

    \b
    Examples:
      ibiscape-eval calib SVI_calib_checkerboard --yaml camchain.yaml --plot calib_plots/
      ibiscape-eval calib SVI_calib_aprilgrid --model pinhole-equi --json
      ibiscape-eval calib --target april_6x6.yaml --images cam0='left/*.png' --images cam1='right/*.png'
      ibiscape-eval calib SVI_calib_checkerboard --check camchain.yaml
      ibiscape-eval calib SVI_1_calib --imu imu.yaml --yaml camchain-imucam.yaml --plot imu_plots/
      ibiscape-eval calib SVI_1_calib --imu --yaml camchain-imucam.yaml   (noise from sequence.yaml)
      ibiscape-eval calib calib.bag --target april_6x6.yaml --topic /cam0/image_raw --topic /cam1/image_raw
    """
    _check_options(seq, image_specs, check_path, imu_yaml, cams_path, imu_data, force, frame_step)
    names = [c.strip() for c in cameras.split(",") if c.strip()] if cameras else None
    if imu_yaml is not None:
        assert seq is not None
        from ibiscape_eval.io.kalibr import read_target
        from ibiscape_eval.io.open_sequence import open_sequence

        from .calib_imu import run_sequence

        target = read_target(target_path) if target_path is not None else None
        opened = open_sequence(seq, cameras=names, image_topics=topics or None, imu_topic=imu_topic)
        run_sequence(opened, Path(imu_yaml) if imu_yaml else None, camchain=cams_path,
                     imu_data=imu_data, target=target, force=force, frame_step=frame_step, yaml_path=yaml_out, json_out=as_json,
                     plot_dir=plot_dir, workers=workers)
        return
    from .startup import numba_startup

    # the cameras alone: the collector paused while the stack loads and runs, OpenBLAS loaded
    # single-threaded (the solver's matrices are 22 x 22): 20-30 ms of CPU less on 13 stereo photos
    with numba_startup():
        _calibrate(seq, image_specs, names, topics, imu_topic, target_path, check_path, yaml_out,
                   as_json, plot_dir, dict(model=model, max_views=max_views, max_frames=max_frames,
                                           reconstruction=reconstruction, event_corners=event_corners,
                                           sensor_size=parse_sensor_size(sensor_size),
                                           outlier_sigma=outlier_sigma, workers=workers))


def _calibrate(seq: Path | None, image_specs: tuple[str, ...], names: list[str] | None,
               topics: tuple[str, ...], imu_topic: str | None, target_path: Path | None,
               check_path: Path | None, yaml_out: Path | None, as_json: bool, plot_dir: Path | None,
               options: dict[str, Any]) -> None:
    """Calibrate (or ``--check``) the cameras of SEQ or of the image sets; print and write."""
    from ibiscape_eval.calib.pipeline import calibrate_cameras
    from ibiscape_eval.core.kalibr import CameraChain
    from ibiscape_eval.io.kalibr import read_camchain, read_target, write_camchain
    from ibiscape_eval.io.open_sequence import open_sequence

    target = read_target(target_path) if target_path is not None else None
    opened = open_sequence(seq, images=image_specs or None, cameras=names,
                           image_topics=topics or None, imu_topic=imu_topic)
    check_chain = read_camchain(check_path) if check_path is not None else None
    with _bar("detecting") as bar:
        run = calibrate_cameras(
            opened, target=target, check=check_chain, progress=bar.update,
            total=lambda n: bar.reset(total=n), solve_progress=lambda s: bar.set_description(s),
            **options)
    for name, r in run.reconstruction.items():
        info(f"{name}: frames reconstructed from events by {r['method']}")
    summary, recon_used = run.detection, run.reconstruction
    base: dict[str, Any] = {"input": str(seq) if seq is not None else list(image_specs),
                            "target": run.target.to_kalibr(), "detection": summary.to_dict(),
                            "reconstruction": recon_used}

    if run.check is not None:
        _print_check({**base, "check": str(check_path), **run.check}, check_path, as_json)
        return
    result, truth = run.result, run.truth
    assert result is not None
    topics_out = run.rostopics()
    if yaml_out is not None:
        write_camchain(yaml_out, CameraChain.from_relative(tuple(c.name for c in result.cameras),
                                                           tuple(c.camera for c in result.cameras),
                                                           result.T_cn_cnm1, topics_out))
    plots = _save_plots(plot_dir, result)
    doc = {**base, **result.to_dict(), "ground_truth": None if truth is None else truth.to_dict(),
           "outputs": {"yaml": None if yaml_out is None else str(yaml_out), "plots": plots}}
    if as_json:
        echo_json(doc)
        return
    _print_result(run, yaml_out)


def _check_options(seq: Path | None, image_specs: tuple[str, ...], check_path: Path | None,
                   imu_yaml: str | None, cams_path: Path | None, imu_data: Path | None,
                   force: bool, frame_step: int) -> None:
    """Refuse options that belong to another mode (camera-IMU, images, sequence)."""
    from ibiscape_eval.core.errors import IbiscapeError

    if imu_yaml is None and (cams_path or imu_data or force or frame_step != 1):
        raise IbiscapeError("--cams, --imu-data, --force and --frame-step belong to the camera-IMU "
                            "calibration: add --imu imu.yaml")
    if imu_yaml is not None:
        if seq is None or image_specs or check_path is not None:
            raise IbiscapeError("--imu calibrates a sequence folder: give SEQ (not --images or --check)")
        return
    if seq is None and not image_specs:
        raise IbiscapeError("give a sequence folder SEQ or --images NAME=GLOB per camera")
    if seq is not None and image_specs:
        raise IbiscapeError("give either SEQ or --images, not both")


def _save_plots(plot_dir: Path | None, result: Any) -> list[str]:
    if plot_dir is None:
        return []
    from ibiscape_eval.calib.plots import calibration_figures
    from ibiscape_eval.io.figure import save_figures

    return [str(p) for p in save_figures(plot_dir, calibration_figures(result))]


def _print_check(doc: dict[str, Any], check_path: Path | None, as_json: bool) -> None:
    if as_json:
        echo_json(doc)
        return
    click.echo(f"checking     {check_path} on {doc['n_views']} views")
    for c in doc["cameras"]:
        r = c["reprojection_error"]
        click.echo(f"{c['name']:<12} {c['reprojection_error_kalibr']} px   rms {r['rms_px']:.4f} px "
                   f"({r['n_views']} views, {r['n_corners']} corners)")
    click.echo(f"rms          {doc['rms_px']:.4f} px")
    click.echo(f"outlier views (rms > {doc['outlier_px']} px): {len(doc['outlier_views'])}")
    for o in doc["outlier_views"][:20]:
        click.echo(f"  {o['camera']} view {o['view']}: rms {o['rms_px']:.3f} px")


def _print_result(run: Any, yaml_out: Path | None) -> None:
    from ibiscape_eval.calib.report import format_report

    result, truth, summary, recon_used = run.result, run.truth, run.detection, run.reconstruction
    refined = summary.extra.get("event_corner_refinement") or {}
    for name, r in recon_used.items():
        st = refined.get(name) or {}
        how = (f"; {st['corners_refined']} of {st['corners_detected']} corners refined from the events "
               f"({st['views_kept']} views)" if st.get("method") == "events" else "")
        click.echo(f"{name}: frames reconstructed from events by {r['method']}{how}")
    for line in format_report(result, truth):
        click.echo(line)
    if yaml_out is not None:
        info(f"wrote {yaml_out}")
