"""Camera-IMU calibration of a recorded sequence: frames -> corners -> intrinsics -> extrinsics.

:func:`calibrate_sequence` is the whole ``ibiscape-eval calib SEQ --imu imu.yaml`` in one library
call: it finds the camera folders (RGB frames, or DVS frames reconstructed from events by
:mod:`ibiscape_eval.calib.events`), detects the target in every frame, takes the intrinsics from a
camera calibration of the same frames (or from ``camchain``), reads the IMU samples of the
sequence (or ``imu_data``), runs :func:`~.calibrate.calibrate_imu_camera` and compares everything
with the truth of ``sequence.yaml`` when it holds one.

A square checkerboard has no preferred orientation, so a detector may number its corners from
any corner; every detection is renumbered so that corner ids grow to the right and down in the
image (the camera may roll by up to 45 degrees), which keeps the target frame the same over the
sequence.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, FormatError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.core.kalibr import ImuNoise

from .inputs import CameraObservations, ImuData
from .kalibr import errors_against_truth
from .result import ImuCameraResult

if TYPE_CHECKING:
    from ibiscape_eval.core.sequence import Sequence as Recording

__all__ = ["SequenceCalibration", "calibrate_imu_camera", "calibrate_sequence", "event_frame_stamps_ns"]

Progress = Callable[[float, str], None]
#: the camera clocks may be this far off the IMU's (the solve's search range of the offset)
MAX_SHIFT_NS = 100_000_000


@dataclass(frozen=True, eq=False)
class SequenceCalibration:
    """Everything ``calib SEQ --imu`` found.

    Attributes
    ----------
    sequence : str
    result : ImuCameraResult
        Extrinsics, time offsets, gravity, biases, excitation, residuals.
    intrinsics_source : dict
        Camera name -> where its intrinsics came from (``"camera calibration"`` or the camchain).
    truth : dict
        Camera name -> ``T_cam_imu`` (4x4 list) and ``timeshift_cam_imu`` [s] of ``sequence.yaml``.
    errors_vs_truth : dict
        Camera name -> rotation [deg], translation [m] and time-offset [s] errors.
    camera_calibration : dict or None
        The camera calibration of the same frames (intrinsics, reprojection error and, with a
        truth, its errors) when the intrinsics came from it.
    detection : dict
        Per camera: frames, frames with the target, corners, reconstruction of event cameras.
    imu_file : str
    timing_s : dict
        Wall-clock seconds of detection, camera calibration, camera-IMU solve, total, and the
        process CPU seconds.
    """

    sequence: str
    result: ImuCameraResult
    intrinsics_source: dict[str, str]
    truth: dict[str, dict[str, Any]]
    errors_vs_truth: dict[str, dict[str, float]]
    camera_calibration: dict[str, Any] | None
    detection: dict[str, Any]
    imu_file: str
    timing_s: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON: the result, the truth and the errors, the detection and the timing."""
        return {
            "sequence": self.sequence,
            **self.result.to_dict(),
            "intrinsics_source": dict(self.intrinsics_source),
            "truth": self.truth,
            "errors_vs_truth": self.errors_vs_truth,
            "camera_calibration": self.camera_calibration,
            "detection": self.detection,
            "imu_file": self.imu_file,
            "timing_s": {k: round(float(v), 3) for k, v in self.timing_s.items()},
        }

    def __repr__(self) -> str:
        errs = ", ".join(f"{k}: {v['rotation_error_deg']:.3f} deg {v['translation_error_m'] * 1e3:.1f} mm "
                         f"{v['timeshift_error_s'] * 1e3:.3f} ms" for k, v in self.errors_vs_truth.items())
        return (f"SequenceCalibration({self.sequence}, {len(self.result.cameras)} cameras"
                + (f", errors {errs}" if errs else "") + ")")


# ------------------------------------------------------------------------------------------ helpers
def canonical_checkerboard(ids: npt.ArrayLike, pixels_px: npt.ArrayLike, target: Any
                           ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Renumber a full checkerboard detection so that ids grow to the right along the corner columns
    and down along the rows in the image (among the board's symmetries, :meth:`CalibrationTarget.
    symmetries`); returns ``(ids, pixels)`` sorted by the new ids."""
    ids = np.asarray(ids, dtype=np.int64)
    px = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
    n_r, n_c = target.corner_rows, target.corner_cols
    if target.target_type != "checkerboard" or ids.size != n_r * n_c:
        return ids, px
    best, best_score = None, -np.inf
    for perm in target.symmetries():
        new = perm[ids]
        grid = np.empty((n_r * n_c, 2))
        grid[new] = px
        g = grid.reshape(n_r, n_c, 2)
        col = np.diff(g, axis=1).reshape(-1, 2).mean(axis=0)
        row = np.diff(g, axis=0).reshape(-1, 2).mean(axis=0)
        score = col[0] / (np.linalg.norm(col) + 1e-12) + row[1] / (np.linalg.norm(row) + 1e-12)
        if score > best_score:
            best, best_score = new, score
    assert best is not None
    order = np.argsort(best)
    return best[order], px[order]


def _camchain_cameras(path: str | os.PathLike[str], names: Sequence[str],
                      seq_cams: dict[str, Any]) -> dict[str, CameraModel]:
    """Intrinsics of ``names`` from a Kalibr camchain (:meth:`CameraChain.match`: by the rostopic
    ``/<name>/...`` or the ``cam<i>`` key, else by chain order); a camchain whose resolution differs
    from the one ``sequence.yaml`` states is refused."""
    from ibiscape_eval.core.kalibr import check_camchain_matches
    from ibiscape_eval.io.kalibr import read_camchain

    def size(n: str) -> tuple[int, int] | None:
        res = (seq_cams.get(n) or {}).get("resolution") if isinstance(seq_cams.get(n), dict) else None
        try:
            return (int(res[0]), int(res[1])) if res is not None and len(res) == 2 else None
        except (TypeError, ValueError):
            return None

    chain = read_camchain(path)
    found = check_camchain_matches(chain, {n: size(n) for n in names}, source=str(path),
                                   require_all=False)
    return {name: chain.cameras[i].camera for name, i in found.items()}


def _require_intrinsics(names: Sequence[str], models: dict[str, CameraModel],
                        camchain: str | os.PathLike[str] | None) -> None:
    for n in names:
        if n not in models:
            where = f"{camchain} has no entry for it" if camchain is not None else "the camera calibration gave none"
            raise CalibrationError(f"camera {n}: intrinsics are missing ({where}); give --cams "
                                   "camchain.yaml with an entry for every camera (rostopic "
                                   f"/{n}/image_raw or chain order)")


def _sequence_noise(seq: Recording, noise: Any) -> tuple[ImuNoise, str]:
    """The IMU noise: given, read from an ``imu.yaml`` (:func:`ibiscape_eval.io.kalibr.
    read_imu_noise`), or (None, or the sequence's own ``sequence.yaml``) the densities the
    sequence states; zero densities (an ideal sensor) are refused."""
    from ibiscape_eval.io.kalibr import read_imu_noise

    own = seq.path / "sequence.yaml"
    if isinstance(noise, ImuNoise):
        out, src = noise, "imu.yaml"
    elif noise is not None and not (own.is_file() and Path(noise).resolve() == own.resolve()):
        out, src = read_imu_noise(noise), str(noise)
    elif seq.imu is not None and seq.imu.noise is not None:
        out, src = seq.imu.noise, seq.imu.noise_source
    elif seq.imu is not None and seq.imu.noise_problem:
        raise FormatError(seq.imu.noise_source, seq.imu.noise_problem)
    else:
        raise IbiscapeError(f"{seq.path}: no IMU noise (the recording states none); give --imu "
                            "imu.yaml (Kalibr's format, e.g. from `ibiscape-eval allan`)")
    if out.is_ideal:
        raise CalibrationError(f"{src}: states zero IMU noise (an ideal sensor); the "
                               "camera-IMU calibration weighs the IMU by its noise: give the IMU's "
                               "densities (e.g. `ibiscape-eval allan IMU --yaml imu.yaml`)")
    return out, src


def _truth(doc: dict[str, Any], names: Sequence[str]) -> dict[str, dict[str, Any]]:
    cams = doc.get("cameras") if isinstance(doc.get("cameras"), dict) else {}
    assert isinstance(cams, dict)
    out: dict[str, dict[str, Any]] = {}
    for n in names:
        e = cams.get(n)
        if not isinstance(e, dict) or "T_cam_imu" not in e:
            continue
        try:
            T = np.asarray(e["T_cam_imu"], dtype=np.float64).reshape(4, 4)
            shift = float(e.get("timeshift_cam_imu", 0.0))
        except (TypeError, ValueError):
            continue
        if np.all(np.isfinite(T)) and np.isfinite(shift):
            out[n] = {"T_cam_imu": T.tolist(), "timeshift_cam_imu": shift}
    return out


# ------------------------------------------------------------------------------------------ the call
def calibrate_sequence(sequence: Recording | str | os.PathLike[str],
                       noise: ImuNoise | str | os.PathLike[str] | None = None, *,
                       camchain: str | os.PathLike[str] | None = None,
                       cameras: Sequence[str] | None = None, force: bool = False,
                       progress: Progress | None = None,
                       imu_data: str | os.PathLike[str] | None = None,
                       target: Any = None, frame_step: int = 1, sigma_px: float = 0.3,
                       refine_intrinsics: bool | None = None,
                       estimate_corner_noise: bool = True,
                       workers: int | None = None) -> SequenceCalibration:
    """Calibrate ``T_cam_imu`` and ``timeshift_cam_imu`` of every camera of a sequence.

    Parameters
    ----------
    sequence : Sequence or path
        A sequence from :func:`ibiscape_eval.open_sequence` (a path is opened by it): IBISCape
        (camera folders with ``timestamps.csv``, ``other_sensors/imu0.csv``, ``sequence.yaml`` with
        the target), EuRoC/TUM-VI, a ROS bag with image and IMU topics.
    noise : ImuNoise or path, optional
        The IMU's continuous-time noise (Kalibr ``imu.yaml``, the ``allan`` command's output);
        default (or the sequence's own ``sequence.yaml``): the noise the sequence states.
    camchain : path, optional
        Kalibr ``camchain.yaml`` with the intrinsics (default: calibrate the cameras on the same
        frames first).
    cameras : sequence of str, optional
        Cameras to use, in order (default: every camera of the sequence).
    force : bool
        Estimate even without the rotational excitation the translation needs (marked).
    progress : callable(fraction, label), optional
    imu_data : path, optional
        IMU csv (``#timestamp [ns], w_xyz, a_xyz``; IBISCape's frame inside an IBISCape folder)
        instead of the sequence's ``other_sensors`` file.
    target : CalibrationTarget, optional
        Default: ``sequence.yaml``'s target.
    frame_step : int
        Use every n-th frame of each camera (1: all).
    refine_intrinsics : bool, optional
        Also estimate focal lengths and principal points (default: when they come from the camera
        calibration of the same frames, not with ``camchain``).
    estimate_corner_noise : bool
        Solve with ``sigma_px``, then weigh each camera by its own reprojection RMS and solve again
        (default: a detector's corners are usually several times better than the nominal 0.3 px,
        and the under-weighted cameras let the accelerometer noise bend the lever arms: on the
        60 s drive at -20 ms, translation 8.3 -> 2.6 mm, rotation 0.020 -> 0.014 deg).

    Raises
    ------
    FormatError
        A bad ``imu.yaml``, IMU csv, camchain or sequence file, naming it.
    CalibrationError
        Missing intrinsics, an IMU stream that does not cover the images, an update rate that
        disagrees with the data, too few views, too little excitation (without ``force``).
    """
    from ibiscape_eval.calib.pipeline import (
        DetectionSummary,
        calibrate_frames,
        camera_frames,
        detect_frames,
        sequence_target,
    )
    from ibiscape_eval.core.sequence import Sequence as Opened
    from ibiscape_eval.io.image_sets import pair_views
    from ibiscape_eval.io.open_sequence import open_sequence
    from ibiscape_eval.io.stereo import read_imu_samples

    from .calibrate import calibrate_imu_camera as solve

    t0, cpu0 = time.perf_counter(), time.process_time()

    def step(frac: float, label: str) -> None:
        if progress is not None:
            progress(min(1.0, max(0.0, frac)), label)

    if isinstance(frame_step, bool) or not isinstance(frame_step, int) or frame_step < 1:
        raise IbiscapeError(f"frame_step must be an integer >= 1, got {frame_step!r}")
    if isinstance(sequence, Opened):
        opened = sequence
    else:
        if not Path(sequence).is_dir() and not Path(sequence).is_file():
            raise IbiscapeError(f"{sequence}: not a sequence folder")
        opened = open_sequence(sequence)
    opened = opened.select(list(cameras) if cameras else None)
    seq = opened.path
    noise, noise_src = _sequence_noise(opened, noise)
    doc: dict[str, Any] = dict(opened.doc)
    target = sequence_target(opened, target)
    # the IMU first: a bad IMU file should not cost a detection pass
    if imu_data is not None:
        imu_path = Path(imu_data)
        st, gyro, acc = read_imu_samples(imu_path, fmt="ibiscape" if (seq / "vehicle_gt").is_dir() else "euroc")
    elif opened.imu is not None:
        imu_path = opened.imu.source
        st, gyro, acc = opened.imu.samples.get()
    else:
        raise FormatError(seq / "other_sensors", "no IMU file (other_sensors/imu0.csv); give --imu-data "
                          "PATH with the IMU samples of this run")
    try:
        imu = ImuData(st, gyro, acc)
    except IbiscapeError as e:
        raise FormatError(imu_path, str(e)) from None

    for c in opened.cameras:
        if c.stamps_ns is None:
            raise FormatError(c.root, "frames without time stamps; the camera-IMU calibration needs "
                              "timestamps.csv")
    # causal frames for event cameras: the bidirectional log-intensity frame also shows the future
    # (sharper corners for the camera calibration), which moved the event cameras' estimated
    # offset by 92 ms and their rotation by 112 deg on the test drive (tests/calib/test_imu_camera_dvs.py)
    frames, recon = camera_frames(opened, target, bidirectional=False)
    stamps: list[npt.NDArray[np.int64]] = []
    for c in opened.cameras:
        if c.kind == "frames":
            assert c.stamps_ns is not None
            stamps.append(np.asarray(c.stamps_ns, dtype=np.int64))
        else:
            assert c.windows_ns is not None
            stamps.append(event_frame_stamps_ns(c.windows_ns, recon[c.name]["method"]))
    names = [f.name for f in frames]
    # refuse what the solve would refuse before the (long) detection: rate, coverage, intrinsics
    if abs(imu.rate_hz - noise.update_rate_hz) > 0.05 * noise.update_rate_hz:
        raise CalibrationError(
            f"{noise_src}: update_rate {noise.update_rate_hz:g} Hz disagrees with the IMU data "
            f"({imu_path} runs at {imu.rate_hz:.2f} Hz); fix update_rate or give the imu.yaml of "
            "this IMU")
    for n, stc in zip(names, stamps, strict=True):
        if stc.size and (stc[0] < imu.stamps_ns[0] - MAX_SHIFT_NS or stc[-1] > imu.stamps_ns[-1] + MAX_SHIFT_NS):
            raise CalibrationError(
                f"{imu_path}: the IMU stream ({imu.stamps_ns[0]}..{imu.stamps_ns[-1]} ns) does not cover "
                f"the images of camera {n} ({stc[0]}..{stc[-1]} ns); give the IMU recording of the same run")
    models: dict[str, CameraModel] = {}
    if camchain is not None:
        models = _camchain_cameras(camchain, names, {c.name: {"resolution": list(c.sensor_size)}
                                                     for c in opened.cameras if c.sensor_size})
        _require_intrinsics(names, models, camchain)
    # the view table pairs simultaneous frames (the camera calibration's stereo views); every
    # frame_step-th instant is detected
    views = pair_views(opened.cameras)[::frame_step]
    step(0.0, "detecting")
    total = [max(1, len(views))]
    done = [0]

    def det_progress(n: int) -> None:
        done[0] += n
        step(0.45 * done[0] / total[0], f"detecting {done[0]}/{total[0]}")

    def det_total(n: int) -> None:
        total[0] = max(1, n)

    summary = detect_frames(target, frames, views, max_detect=len(views), workers=workers,
                            progress=det_progress, total=det_total)
    t_det = time.perf_counter()
    # per camera, the detections in frame order (canonical checkerboard numbering)
    per_cam: list[list[tuple[Any, Any] | None]] = [[None] * f.n_frames for f in frames]
    for k, o in enumerate(summary.observations):
        for vi, det in enumerate(o.detections):
            if det is None:
                continue
            i = views[summary.views[vi]][k]
            assert i is not None
            per_cam[k][i] = canonical_checkerboard(det.ids, det.corners_px, target)

    # intrinsics
    step(0.45, "intrinsics")
    source: dict[str, str] = {}
    cam_calib: dict[str, Any] | None = None
    icov: dict[str, Any] = {}  # the camera calibration's intrinsics covariance, propagated
    if camchain is not None:
        source = {n: str(camchain) for n in models}
    else:
        from ibiscape_eval.calib.report import compare_with_truth, truth_from_sequence

        # the frame cameras and the event cameras are calibrated apart: frames reconstructed from
        # events are poorer, and one chain would let them bend the frame cameras' intrinsics
        groups: dict[str, list[int]] = {}
        for k, cam in enumerate(opened.cameras):
            groups.setdefault(cam.kind, []).append(k)
        cam_calib = {"views": 0, "cameras": [], "ground_truth": None}
        gts = []
        for kind, idx in groups.items():
            sub = DetectionSummary(tuple(summary.observations[k] for k in idx), summary.views,
                                   tuple(summary.frames_tried[k] for k in idx),
                                   tuple(summary.frames_unreadable[k] for k in idx),
                                   tuple(summary.frames_detected[k] for k in idx), dict(summary.extra))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", IbiscapeWarning)
                try:
                    cres = calibrate_frames(target, sub, max_views=60)
                except CalibrationError as e:
                    what = "event cameras" if kind == "events" else "cameras"
                    raise CalibrationError(f"{seq}: the camera calibration of the {what} for the "
                                           f"intrinsics failed ({e}); give --cams camchain.yaml") from None
            models.update({c.name: c.camera for c in cres.cameras})
            icov.update({c.name: c.covariance for c in cres.cameras if c.covariance is not None})
            cmp = compare_with_truth(cres, truth_from_sequence(doc))
            cam_calib["views"] += int(cres.n_views)
            cam_calib["cameras"] += [{"name": c.name, "camera": c.camera.to_kalibr(),
                                      "reprojection_rms_px": float(c.residuals.rms_px)}
                                     for c in cres.cameras]
            if cmp is not None:
                gts.append(cmp.to_dict())
        source = {n: "camera calibration" for n in models}
        if gts:
            cam_calib["ground_truth"] = _merge_truth(gts)
    t_intr = time.perf_counter()
    obs = [CameraObservations.from_frames(n, models.get(n), stamps[k], per_cam[k])
           for k, n in enumerate(names)]
    _require_intrinsics(names, models, camchain)

    def solve_progress(frac: float, label: str) -> None:
        step(0.5 + 0.5 * frac, label)

    corners = target.object_points()
    # intrinsics from a calibration on the drive's own (weakly tilted) views are refined with the
    # extrinsics; those of --cams are taken as they are (Kalibr's way)
    refine = camchain is None if refine_intrinsics is None else bool(refine_intrinsics)
    try:
        result = solve(obs, imu, noise, corners, sigma_px=sigma_px, force=force,
                                      refine_intrinsics=refine, progress=solve_progress,
                                      estimate_corner_noise=estimate_corner_noise,
                                      intrinsics_covariance=icov or None)
    except CalibrationError as e:
        msg = str(e)
        if "update_rate" in msg or "IMU stream" in msg:
            raise CalibrationError(f"{imu_path}: {msg}") from None
        raise
    truth = _truth(doc, names)
    errors = errors_against_truth(result, truth)
    from ibiscape_eval.calib.report import truth_from_sequence

    true_cams = truth_from_sequence(doc)
    for cal in result.cameras:
        if cal.name in errors and cal.name in true_cams:
            t_cam = true_cams[cal.name][0]
            errors[cal.name].update({f"{k}_error_px": float(a - b) for k, a, b in zip(
                ("fx", "fy", "cx", "cy"), cal.camera.intrinsics, t_cam.intrinsics, strict=True)})
    t_end = time.perf_counter()
    detection = {"frame_step": frame_step, "cameras": [
        {"name": n, "frames": int(stamps[k].size), "frames_with_target": int(obs[k].n_frames_with_target),
         "corners": int(obs[k].corner_ids.size), **({"reconstruction": recon[n]} if n in recon else {})}
        for k, n in enumerate(names)]}
    return SequenceCalibration(
        str(seq), result, source, truth, errors, cam_calib, detection, str(imu_path),
        {"detection": t_det - t0, "intrinsics": t_intr - t_det, "imu_camera": t_end - t_intr,
         "total": t_end - t0, "cpu": time.process_time() - cpu0})


def _merge_truth(docs: list[dict[str, Any]]) -> dict[str, Any]:
    """The truth comparisons of camera calibrations of disjoint camera groups as one."""
    out: dict[str, Any] = {"cameras": [], "chain": []}
    for d in docs:
        out["cameras"] += d.get("cameras", [])
        out["chain"] += d.get("chain", [])
    for k in ("max_focal_error_px", "max_principal_point_error_px", "max_baseline_error_mm"):
        vals = [float(d[k]) for d in docs if isinstance(d.get(k), int | float)]
        out[k] = max(vals) if vals else None
    return out


def event_frame_stamps_ns(windows_ns: npt.ArrayLike, method: str) -> npt.NDArray[np.int64]:
    """The instant each frame reconstructed from an event window shows, on the camera's clock.

    ``log-intensity`` carries the integrated brightness to the END of its window (the scene as it
    is then, minus a fading past: stamped at the window's middle, the planted offset of the
    simulator's drives came out half a window off); ``accumulate`` and ``accumulate-signed`` pile
    up the window's events evenly (the window's middle); ``time-surface`` weighs the latest events
    with a 10 ms decay (the window's end minus that decay, at most half the window).
    """
    w = np.asarray(windows_ns, dtype=np.int64).reshape(-1, 2)
    half = (w[:, 1] - w[:, 0]) // 2
    if method == "log-intensity":
        return w[:, 1].copy()
    if method == "time-surface":
        from ibiscape_eval.calib.events import TIME_SURFACE_TAU_NS

        return w[:, 1] - np.minimum(half, TIME_SURFACE_TAU_NS)
    return w[:, 0] + half


#: ``ibiscape_eval.calibrate_imu_camera(seq, ...)``: the whole camera-IMU job on a sequence (the
#: solver on observations is :func:`ibiscape_eval.calib.imu_camera.calibrate_imu_camera`)
calibrate_imu_camera = calibrate_sequence
