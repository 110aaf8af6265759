"""``calib SEQ --imu imu.yaml``: the camera-IMU part of the calibration command.

``cli/calib.py`` hands ``--imu`` runs to :func:`run_sequence` (the library's
:func:`ibiscape_eval.calib.imu_camera.calibrate_sequence` does the work); :func:`run_imu_camera`
is the same on observations already in memory.  No math here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import click

from ._common import echo_json, info

__all__ = ["print_result", "run_imu_camera", "run_sequence"]


def run_sequence(seq: Any, imu_yaml: Path | None, *, camchain: Path | None, imu_data: Path | None,
                 target: Any, force: bool, frame_step: int, yaml_path: Path | None, json_out: bool,
                 plot_dir: Path | None, workers: int | None) -> Any:
    """``calib SEQ --imu imu.yaml`` on an opened sequence (:func:`ibiscape_eval.io.open_sequence`):
    calibrate, write ``--yaml`` (camchain-imucam) and ``--plot`` figures, print the table (or
    ``--json``).  ``imu_yaml`` None (or ``SEQ/sequence.yaml``): the noise the sequence states."""
    from ibiscape_eval.calib.imu_camera import SequenceOptions, calibrate_sequence, camchain_imucam
    from ibiscape_eval.io.kalibr import read_imu_noise, write_camchain

    from .progress import fraction_callback, progress_bar

    own = Path(seq.path) / "sequence.yaml"
    if imu_yaml is not None and not (own.is_file() and Path(imu_yaml).resolve() == own.resolve()):
        read_imu_noise(imu_yaml)  # a bad imu.yaml fails before anything else is read
    with progress_bar(1000, "calib --imu", unit="‰", unit_scale=False) as bar:
        res = calibrate_sequence(seq, imu_yaml, SequenceOptions(
            camchain=camchain, force=force, imu_data=imu_data, target=target, frame_step=frame_step,
            workers=workers), progress=fraction_callback(bar, "calib --imu"))
    if yaml_path is not None:
        write_camchain(yaml_path, camchain_imucam(res.result),
                              comments=["camera-IMU calibration by ibiscape-eval calib --imu"])
    plots: list[str] = []
    if plot_dir is not None:
        from ibiscape_eval.calib.imu_camera.plots import figures
        from ibiscape_eval.io.figure import save_figures

        plots = [str(p) for p in save_figures(plot_dir, figures(res.result))]
    if json_out:
        echo_json({**res.to_dict(), "outputs": {"yaml": None if yaml_path is None else str(yaml_path),
                                               "plots": plots}})
        return res
    det = res.detection["cameras"]
    click.echo("frames with the target: " + ", ".join(
        f"{d['name']} {d['frames_with_target']}/{d['frames']}" for d in det)
        + "; intrinsics from " + ", ".join(sorted(set(res.intrinsics_source.values()))))
    print_result(res.result, res.errors_vs_truth)
    for w in res.result.warnings:
        click.echo(f"weak: {w}")
    t = res.timing_s
    click.echo(f"time: detection {t['detection']:.1f} s, intrinsics {t['intrinsics']:.1f} s, "
               f"camera-IMU {t['imu_camera']:.1f} s, total {t['total']:.1f} s (CPU {t['cpu']:.1f} s)")
    if yaml_path is not None:
        info(f"wrote {yaml_path}")
    if plots:
        info(f"wrote {len(plots)} figure(s) to {plot_dir}")
    return res


def print_result(result: Any, errors: Mapping[str, Mapping[str, float]]) -> None:
    """One table row per camera (stdout) and the excitation line."""
    import numpy as np

    click.echo(f"{'camera':<10} {'t_cam_imu [m]':<30} {'shift [ms]':>11} {'rot std [deg]':>14} "
               f"{'pos std [mm]':>22} {'rms [px]':>9}")
    for c in result.cameras:
        t = c.T_cam_imu[:3, 3]
        click.echo(f"{c.name:<10} {t[0]:9.4f} {t[1]:9.4f} {t[2]:9.4f}   "
                   f"{c.timeshift_cam_imu_s * 1e3:11.3f} {np.max(c.rotation_std_deg):14.4f} "
                   f"{' '.join(f'{v * 1e3:6.1f}' for v in c.position_std_imu_m):>22} "
                   f"{c.reprojection_rms_px:9.3f}")
        if c.name in errors:
            e = errors[c.name]
            click.echo(f"{'':<10} error vs truth: rotation {e['rotation_error_deg']:.4f} deg, "
                       f"translation {e['translation_error_m'] * 1e3:.2f} mm, "
                       f"time {e['timeshift_error_s'] * 1e3:.4f} ms"
                       + ("; intrinsics " + ", ".join(f"{k} {e[f'{k}_error_px']:+.2f}"
                                                      for k in ("fx", "fy", "cx", "cy")) + " px"
                          if "fx_error_px" in e else ""))
    ex = result.excitation
    click.echo("excitation: angular-rate std "
               + " ".join(f"{a}={v:.3f}" for a, v in zip("xyz", ex.gyro_std_rad_s, strict=True))
               + " rad/s, specific-force std "
               + " ".join(f"{a}={v:.2f}" for a, v in zip("xyz", ex.accel_std_m_s2, strict=True))
               + " m/s^2" + (" (FORCED)" if result.forced else ""))


def run_imu_camera(observations: Sequence[Any], imu: Any, imu_yaml: str, corners_target_m: Any, *,
                   truth: Mapping[str, Mapping[str, Any]] | None = None, force: bool = False,
                   sigma_px: float = 0.3, yaml_path: str | None = None, json_out: bool = False,
                   plot_dir: str | None = None) -> Any:
    """Calibrate, write ``--yaml`` (camchain-imucam) and print (table or ``--json``).

    ``observations`` (one :class:`CameraObservations` per camera, intrinsics filled from the camera
    calibration or ``--cams``), ``imu`` (:class:`ImuData`) and ``truth`` (``sequence.yaml``'s
    cameras) come from the calib command.
    """
    from ibiscape_eval.calib.imu_camera import (
        ImuCameraOptions,
        calibrate_imu_camera,
        camchain_imucam,
        errors_against_truth,
    )
    from ibiscape_eval.io.kalibr import read_imu_noise, write_camchain

    noise = read_imu_noise(imu_yaml)
    from .progress import fraction_callback, progress_bar

    with progress_bar(1000, "imu-camera", unit="‰", unit_scale=False) as bar:
        progress = fraction_callback(bar, "imu-camera")
        result = calibrate_imu_camera(observations, imu, noise, corners_target_m,
                                      ImuCameraOptions(sigma_px=sigma_px, force=force), progress=progress)
    errors = errors_against_truth(result, truth or {})
    if yaml_path:
        write_camchain(yaml_path, camchain_imucam(result),
                              comments=["camera-IMU calibration by ibiscape-eval calib --imu"])
    if plot_dir:
        from ibiscape_eval.calib.imu_camera.plots import figures
        from ibiscape_eval.io.figure import save_figures

        written = save_figures(Path(plot_dir), figures(result))
        info(f"wrote {len(written)} figure(s) to {plot_dir}")
    if json_out:
        doc = result.to_dict()
        doc["errors_vs_truth"] = errors
        echo_json(doc)
    else:
        print_result(result, errors)
    return result
