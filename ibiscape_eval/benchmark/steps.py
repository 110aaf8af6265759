"""The benchmark's job functions: one per step and sequence (JSON in, JSON out).

Each function is a :class:`~ibiscape_eval.batch.Job` target, so it runs in this process, in a
local pool or on a Dask worker and gives the same result everywhere; it returns the JSON form
(``to_dict()``) of its typed result in :mod:`ibiscape_eval.benchmark.results`.  Each
reads one sequence of the suite, calls the library that does the work and compares the result
with the truth the simulator wrote into ``sequence.yaml``:

- :func:`camera_calibration`: ``ibiscape_eval.calib`` on the sequence's images (or events), errors
  of focal length, principal point, distortion, baseline and relative rotation against the true
  cameras (the paper's ``table:camerasintrinsics`` and ``table:baselines``);
- :func:`imu_camera_calibration`: ``T_cam_imu`` and ``timeshift_cam_imu`` per camera against the
  simulator's mounting (rotation deg, translation mm, time offset ms);
- :func:`imu_noise`: the Allan deviation fit against the configured densities (``table:imuvalues``);
- :func:`hot_pixels`: the n-sigma hot-pixel filter on a DVS camera: fraction of events removed,
  precision and recall against the pixels the simulated rain and fog made noisy;
- :func:`vio`: the stereo-VIO baseline; the estimate travels back as TUM text and is scored by
  :mod:`ibiscape_eval.report.evaluate` like any other run.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.numbers import finite_or_none

from .results import (
    CameraCalibrationResult,
    CameraError,
    HotPixelsResult,
    ImuCameraError,
    ImuCameraResult,
    ImuNoiseResult,
    NoiseRow,
    PairError,
    VioResult,
)

__all__ = [
    "camera_calibration",
    "hot_pixels",
    "imu_camera_calibration",
    "imu_noise",
    "vio",
]

#: Cameras calibrated per setup, in chain order (depth and segmentation have no target image).
CALIBRATION_CAMERAS: dict[str, tuple[str, ...]] = {
    "svi": ("rgbL", "rgbR"),
    "esvi": ("davisL", "davisR"),
    "rgbd": ("rgb",),
    "full": ("rgbL", "rgbR"),
}
KALIBR_NOISE_KEYS = ("gyroscope_noise_density", "gyroscope_random_walk",
                     "accelerometer_noise_density", "accelerometer_random_walk")


def _sequence_doc(seq: str) -> dict[str, Any]:
    from ibiscape_eval.io.sequence import read_sequence_yaml

    path = Path(seq) / "sequence.yaml"
    if not path.is_file():
        raise IbiscapeError(f"{path}: not found; the benchmark needs the truth of a simulated "
                            "sequence (generate it with 'ibiscape-eval sim suite')")
    return read_sequence_yaml(path)


# ---------------------------------------------------------------------------------------------
# cameras


def camera_calibration(seq: str, cameras: Sequence[str], model: str = "pinhole-radtan",
                       max_views: int = 40, max_frames: int = 150) -> dict[str, Any]:
    """Calibrate ``cameras`` of the sequence ``seq`` and compare with its true cameras.

    Returns the calibration's summary (``rms_px``, ``n_views``, the reconstruction used for event
    cameras), per camera the errors of ``fx, fy, cx, cy`` [px] and the largest
    distortion-coefficient error, per neighbouring pair the baseline error [mm] and the rotation
    error [deg].  The library's warnings (empty event windows, views dropped) are not repeated:
    the numbers say how well it went.
    """
    from ibiscape_eval.core.errors import IbiscapeWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IbiscapeWarning)
        return _camera_calibration(seq, cameras, model, max_views, max_frames)


def _camera_calibration(seq: str, cameras: Sequence[str], model: str, max_views: int,
                        max_frames: int) -> dict[str, Any]:
    from ibiscape_eval.calib.pipeline import calibrate_cameras
    from ibiscape_eval.io.open_sequence import open_sequence

    _sequence_doc(seq)
    opened = open_sequence(seq).select(list(cameras))
    if opened.target is None:
        raise IbiscapeError(f"{seq}/sequence.yaml has no 'target': not a calibration sequence")
    run = calibrate_cameras(opened, model=model, max_views=max_views, max_frames=max_frames, workers=1)
    result, truth, target = run.result, run.truth, run.target
    assert result is not None
    recon = {k: v["method"] for k, v in run.reconstruction.items()}
    rd = result.to_dict()
    cams = []
    for c in (truth.cameras if truth is not None else []):
        err = c["error"]
        cams.append(CameraError(c["name"], err["fx"], err["fy"], err["cx"], err["cy"],
                                max(abs(v) for v in err["distortion_coeffs"]),
                                c["estimate"]["fx"], c["truth"]["fx"]))
    chain = [PairError(c["from"], c["to"], c["baseline_error_mm"], c["baseline_truth_m"],
                       c["rotation_error_deg"]) for c in (truth.chain if truth is not None else [])]
    return CameraCalibrationResult(
        Path(seq).name, target.to_kalibr().get("target_type"), model, tuple(cams), tuple(chain),
        finite_or_none(rd.get("rms_px")), rd.get("n_views"), recon).to_dict()


def imu_camera_calibration(seq: str, cameras: Sequence[str]) -> dict[str, Any]:
    """Camera-IMU extrinsics and time offsets of a suite calibration drive, against the truth.

    Runs :func:`ibiscape_eval.calib.imu_camera.calibrate_sequence` on the rendered drive (corners
    detected in the images, intrinsics from the camera calibration of the same frames, IMU noise
    weights from the densities ``sequence.yaml`` configures for ``imu0``), as ``ibiscape-eval calib
    SEQ --imu imu.yaml`` does.  Returns per camera ``rotation_error_deg``,
    ``translation_error_mm``, ``timeshift_error_ms``, the reprojection RMS and the estimated and
    true time offsets; the solver's weak-direction warnings are kept in ``warnings``.
    """
    from ibiscape_eval.calib.imu_camera import calibrate_sequence
    from ibiscape_eval.core.errors import IbiscapeWarning
    from ibiscape_eval.io.open_sequence import open_sequence

    _sequence_doc(seq)
    opened = open_sequence(seq).select(list(cameras))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IbiscapeWarning)
        # noise=None: the densities sequence.yaml states for its IMU (imus.imu0)
        res = calibrate_sequence(opened, None)
    rows = []
    for c in res.result.cameras:
        er = res.errors_vs_truth.get(c.name, {})
        rows.append(ImuCameraError(
            c.name, finite_or_none(er.get("rotation_error_deg")),
            finite_or_none(1e3 * er.get("translation_error_m", math.nan)),
            finite_or_none(1e3 * er.get("timeshift_error_s", math.nan)),
            finite_or_none(1e3 * c.timeshift_cam_imu_s),
            finite_or_none(1e3 * res.truth.get(c.name, {}).get("timeshift_cam_imu", math.nan)),
            finite_or_none(c.reprojection_rms_px)))
    return ImuCameraResult(Path(seq).name, tuple(rows), bool(res.result.forced),
                           tuple(res.result.warnings),
                           "calibrate_sequence: detected corners, B-spline camera-IMU solve"
                           ).to_dict()


# ---------------------------------------------------------------------------------------------
# IMU noise


def imu_noise(seq: str) -> dict[str, Any]:
    """Allan-deviation noise fit of IMU0 of a still sequence against its configured densities.

    Returns one row per Kalibr key (``truth``, ``estimate``, ``error_pct``); the estimate is the
    largest of the three axes, as ``allan --yaml`` writes it.
    """
    from ibiscape_eval.imu import allan_deviation, fit_noise_model
    from ibiscape_eval.io.imu import read_imu

    doc = _sequence_doc(seq)
    imu0 = (doc.get("imus") or {}).get("imu0")
    if not isinstance(imu0, dict) or "file" not in imu0:
        raise IbiscapeError(f"{seq}/sequence.yaml: no imu0 with its file and noise densities")
    path = Path(seq) / str(imu0["file"])
    rate = float(imu0.get("update_rate", 200.0))
    rec = read_imu(path, rate_hz=rate if path.suffix == ".npy" else None)
    res = allan_deviation(rec, rec.rate_hz, names=rec.names)
    model = fit_noise_model(res)
    est = model.kalibr(gyro=rec.names[:3], accel=rec.names[3:])
    rows = []
    for key in KALIBR_NOISE_KEYS:
        t, v = finite_or_none(imu0.get(key)), finite_or_none(est.get(key))
        rows.append(NoiseRow(key, t, v, None if t in (None, 0.0) or v is None
                             else 100.0 * (v / t - 1.0)))
    return ImuNoiseResult(Path(seq).name, int(rec.n_samples),
                          rec.n_samples / rec.rate_hz / 3600.0, rec.rate_hz, tuple(rows)).to_dict()


# ---------------------------------------------------------------------------------------------
# DVS hot pixels


def hot_pixels(seq: str, camera: str, n_sigma: float = 5.0) -> dict[str, Any]:
    """The n-sigma hot-pixel filter on one DVS camera of ``seq``.

    Returns the fraction of events removed and, against the pixels the simulator made noisy
    (``sequence.yaml``: ``cameras.<camera>.dvs.noisy_pixels``), precision and recall of the
    detected set (None when there is nothing to compare: clear weather plants no noisy pixel).
    """
    import numpy as np

    from ibiscape_eval.events.hotpix import PixelCounter
    from ibiscape_eval.io.events import iter_event_chunks
    from ibiscape_eval.io.open_sequence import open_sequence

    doc = _sequence_doc(seq)
    cam = (doc.get("cameras") or {}).get(camera)
    if not isinstance(cam, dict):
        raise IbiscapeError(f"{seq}/sequence.yaml: no camera {camera!r}")
    stream = open_sequence(seq).camera(camera)
    if stream.kind != "events" or stream.events is None:
        raise IbiscapeError(f"{seq}/{camera}: not an event camera")
    if stream.sensor_size is None:
        raise IbiscapeError(f"{seq}/sequence.yaml: camera {camera!r} has no resolution (the sensor size)")
    src = stream.events.get()
    counter = PixelCounter(sensor_size=stream.sensor_size)
    for chunk in iter_event_chunks(src):
        counter.add(chunk.events, chunk)
    res = counter.result(n_sigma=n_sigma)
    planted = np.asarray((cam.get("dvs") or {}).get("noisy_pixels") or [], dtype=np.int64)
    found = np.asarray(res.pixels, dtype=np.int64).reshape(-1, 2)
    a = {tuple(p) for p in found.tolist()}
    b = {tuple(p) for p in planted.reshape(-1, 2).tolist()}
    tp = len(a & b)
    return HotPixelsResult(Path(seq).name, camera, int(res.n_events), len(a), len(b),
                           finite_or_none(res.fraction_discarded), tp / len(a) if a and b else None,
                           tp / len(b) if b else None).to_dict()


# ---------------------------------------------------------------------------------------------
# VIO


def vio(seq: str, max_frames: int | None = None, setup: str = "auto") -> dict[str, Any]:
    """The VIO baseline on ``seq`` with the cameras of ``setup``
    (:func:`ibiscape_eval.vio.run_vio`): statistics and the estimate as TUM text."""
    import tempfile

    from ibiscape_eval.io import write_trajectory
    from ibiscape_eval.io.open_sequence import open_sequence
    from ibiscape_eval.vio.pipeline import run_vio

    opened = open_sequence(seq)
    if opened.groundtruth is None:
        gt = Path(seq) / "vehicle_gt" / "groundtruth_sync.csv"
        raise IbiscapeError(f"{gt}: no ground truth; the VIO estimate cannot be scored")
    res = run_vio(opened, max_frames=max_frames, setup=setup)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "est.txt"
        write_trajectory(p, res.trajectory, "tum")
        text = p.read_text(encoding="utf-8")
    stats = res.to_dict()
    keep: dict[str, Any] = {k: stats[k] for k in ("frames", "keyframes", "frames_estimated",
                                                  "failures", "init_method", "cpu_realtime_factor",
                                                  "setup", "usable_frames") if k in stats}
    return VioResult(Path(seq).name, keep, len(res.trajectory), text).to_dict()
