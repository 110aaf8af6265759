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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, FormatError, IbiscapeError
from ibiscape_eval.core.kalibr import ImuNoise

from .errors import ImuStreamError
from .inputs import CameraObservations, ImuData
from .kalibr import errors_against_truth
from .options import ImuCameraOptions, SequenceOptions
from .result import ImuCameraResult, ValueEquality

if TYPE_CHECKING:
    from ibiscape_eval.core.sequence import Sequence as Recording

__all__ = ["SequenceCalibration", "calibrate_imu_camera", "calibrate_sequence", "event_frame_stamps_ns"]

Progress = Callable[[float, str], None]
#: the camera clocks may be this far off the IMU's (the solve's search range of the offset)
MAX_SHIFT_NS = 100_000_000


@dataclass(frozen=True, eq=False)
class SequenceCalibration(ValueEquality):
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
        process CPU seconds (to the millisecond).
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

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> SequenceCalibration:
        """The inverse of :meth:`to_dict` (the result's keys sit at the top level)."""
        return cls(str(doc["sequence"]), ImuCameraResult.from_dict(doc), dict(doc["intrinsics_source"]),
                   dict(doc["truth"]), dict(doc["errors_vs_truth"]), doc["camera_calibration"],
                   dict(doc["detection"]), str(doc["imu_file"]),
                   {k: float(v) for k, v in doc["timing_s"].items()})

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
                       noise: ImuNoise | str | os.PathLike[str] | None = None,
                       options: SequenceOptions | None = None, *,
                       progress: Progress | None = None) -> SequenceCalibration:
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
    options : SequenceOptions, optional
        Camchain, cameras, ``--imu-data``, target, frame step, ``force`` and the solve's weights
        (default: ``SequenceOptions()``).
    progress : callable(fraction, label), optional

    Raises
    ------
    FormatError
        A bad ``imu.yaml``, IMU csv, camchain or sequence file, naming it.
    CalibrationError
        Missing intrinsics, an IMU stream that does not cover the images, an update rate that
        disagrees with the data, too few views, too little excitation (without ``force``).
    """
    from ibiscape_eval.calib.pipeline import sequence_target
    from ibiscape_eval.io.image_sets import pair_views

    t0, cpu0 = time.perf_counter(), time.process_time()
    opts = SequenceOptions() if options is None else options
    step = _Steps(progress)
    opened = _open(sequence, opts.cameras)
    noise, noise_src = _sequence_noise(opened, noise)
    target = sequence_target(opened, opts.target)
    imu, imu_path = _imu_samples(opened, opts.imu_data)  # a bad IMU file should not cost a detection
    frames, recon, stamps = _camera_frames(opened, target)
    names = [f.name for f in frames]
    _check_imu_fits(imu, imu_path, noise, noise_src, dict(zip(names, stamps, strict=True)))
    models: dict[str, CameraModel] = {}
    if opts.camchain is not None:
        models = _camchain_cameras(opts.camchain, names, {c.name: {"resolution": list(c.sensor_size)}
                                                          for c in opened.cameras if c.sensor_size})
        _require_intrinsics(names, models, opts.camchain)
    # the view table pairs simultaneous frames (the camera calibration's stereo views); every
    # frame_step-th instant is detected
    views = pair_views(opened.cameras)[:: opts.frame_step]
    summary, per_cam = _detect(target, frames, views, opts.workers, step)
    t_det = time.perf_counter()
    step(0.45, "intrinsics")
    intr = (_Intrinsics({n: str(opts.camchain) for n in models}, models, None, {})
            if opts.camchain is not None else _intrinsics_from_frames(opened, target, summary))
    t_intr = time.perf_counter()
    obs = [CameraObservations.from_frames(n, intr.models.get(n), stamps[k], per_cam[k])
           for k, n in enumerate(names)]
    _require_intrinsics(names, intr.models, opts.camchain)
    result = _solve(obs, imu, imu_path, noise, target.object_points(), opts.solve_options(),
                    intr.covariance, step)
    truth, errors = _errors_vs_truth(result, dict(opened.doc), names)
    t_end = time.perf_counter()
    detection = {"frame_step": opts.frame_step, "cameras": [
        {"name": n, "frames": int(stamps[k].size), "frames_with_target": int(obs[k].n_frames_with_target),
         "corners": int(obs[k].corner_ids.size), **({"reconstruction": recon[n]} if n in recon else {})}
        for k, n in enumerate(names)]}
    timing = {"detection": t_det - t0, "intrinsics": t_intr - t_det, "imu_camera": t_end - t_intr,
              "total": t_end - t0, "cpu": time.process_time() - cpu0}
    return SequenceCalibration(str(opened.path), result, intr.source, truth, errors, intr.camera_calibration,
                               detection, str(imu_path), {k: round(float(v), 3) for k, v in timing.items()})


@dataclass(frozen=True)
class _Steps:
    """``progress(fraction in [0, 1], label)`` when given."""

    callback: Progress | None

    def __call__(self, frac: float, label: str) -> None:
        if self.callback is not None:
            self.callback(min(1.0, max(0.0, frac)), label)


def _open(sequence: Recording | str | os.PathLike[str], cameras: Sequence[str] | None) -> Recording:
    """The sequence opened (a path by :func:`ibiscape_eval.open_sequence`), cut to ``cameras``."""
    from ibiscape_eval.core.sequence import Sequence as Opened
    from ibiscape_eval.io.open_sequence import open_sequence

    if isinstance(sequence, Opened):
        opened = sequence
    else:
        if not Path(sequence).is_dir() and not Path(sequence).is_file():
            raise IbiscapeError(f"{sequence}: not a sequence folder")
        opened = open_sequence(sequence)
    return opened.select(list(cameras) if cameras else None)


def _imu_samples(opened: Recording, imu_data: str | os.PathLike[str] | None
                 ) -> tuple[ImuData, str | os.PathLike[str]]:
    """The IMU samples (``imu_data``, else the sequence's) and the file they come from."""
    from ibiscape_eval.io.stereo import read_imu_samples

    seq = opened.path
    if imu_data is not None:
        imu_path: str | os.PathLike[str] = Path(imu_data)
        st, gyro, acc = read_imu_samples(imu_path, fmt="ibiscape" if (seq / "vehicle_gt").is_dir() else "euroc")
    elif opened.imu is not None:
        imu_path = opened.imu.source
        st, gyro, acc = opened.imu.samples.get()
    else:
        raise FormatError(seq / "other_sensors", "no IMU file (other_sensors/imu0.csv); give --imu-data "
                          "PATH with the IMU samples of this run")
    try:
        return ImuData(st, gyro, acc), imu_path
    except IbiscapeError as e:
        raise FormatError(imu_path, str(e)) from None


def _camera_frames(opened: Recording, target: Any) -> tuple[list[Any], dict[str, dict[str, Any]],
                                                             list[npt.NDArray[np.int64]]]:
    """Every camera's frames (DVS: reconstructed), the reconstructions and the frame stamps."""
    from ibiscape_eval.calib.pipeline import camera_frames

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
    return frames, recon, stamps


def _check_imu_fits(imu: ImuData, imu_path: str | os.PathLike[str], noise: ImuNoise, noise_src: str,
                    stamps: dict[str, npt.NDArray[np.int64]]) -> None:
    """Refuse what the solve would refuse before the (long) detection: rate and coverage."""
    if abs(imu.rate_hz - noise.update_rate_hz) > 0.05 * noise.update_rate_hz:
        raise CalibrationError(
            f"{noise_src}: update_rate {noise.update_rate_hz:g} Hz disagrees with the IMU data "
            f"({imu_path} runs at {imu.rate_hz:.2f} Hz); fix update_rate or give the imu.yaml of "
            "this IMU")
    for n, stc in stamps.items():
        if stc.size and (stc[0] < imu.stamps_ns[0] - MAX_SHIFT_NS or stc[-1] > imu.stamps_ns[-1] + MAX_SHIFT_NS):
            raise CalibrationError(
                f"{imu_path}: the IMU stream ({imu.stamps_ns[0]}..{imu.stamps_ns[-1]} ns) does not cover "
                f"the images of camera {n} ({stc[0]}..{stc[-1]} ns); give the IMU recording of the same run")


@dataclass
class _DetectionCount:
    """Frames detected out of the total, reported as the first 45 % of the progress."""

    step: _Steps
    total: int
    done: int = 0

    def add(self, n: int) -> None:
        self.done += n
        self.step(0.45 * self.done / self.total, f"detecting {self.done}/{self.total}")

    def set_total(self, n: int) -> None:
        self.total = max(1, n)


def _detect(target: Any, frames: list[Any], views: Any, workers: int | None, step: _Steps
            ) -> tuple[Any, list[list[tuple[Any, Any] | None]]]:
    """The detection summary and, per camera, the detections in frame order (canonical
    checkerboard numbering)."""
    from ibiscape_eval.calib.pipeline import detect_frames

    step(0.0, "detecting")
    count = _DetectionCount(step, max(1, len(views)))
    summary = detect_frames(target, frames, views, max_detect=len(views), workers=workers,
                            progress=count.add, total=count.set_total)
    per_cam: list[list[tuple[Any, Any] | None]] = [[None] * f.n_frames for f in frames]
    for k, o in enumerate(summary.observations):
        for vi, det in enumerate(o.detections):
            if det is None:
                continue
            i = views[summary.views[vi]][k]
            assert i is not None
            per_cam[k][i] = canonical_checkerboard(det.ids, det.corners_px, target)
    return summary, per_cam


@dataclass(frozen=True)
class _Intrinsics:
    """Where each camera's intrinsics come from, the models, the camera calibration's report and
    its intrinsics covariance (propagated into the camera-IMU std)."""

    source: dict[str, str]
    models: dict[str, CameraModel]
    camera_calibration: dict[str, Any] | None
    covariance: dict[str, Any]


def _intrinsics_from_frames(opened: Recording, target: Any, summary: Any) -> _Intrinsics:
    """Calibrate the frame cameras and the event cameras apart (frames reconstructed from events
    are poorer, and one chain would let them bend the frame cameras' intrinsics)."""
    from ibiscape_eval.calib.report import compare_with_truth, truth_from_sequence

    groups: dict[str, list[int]] = {}
    for k, cam in enumerate(opened.cameras):
        groups.setdefault(cam.kind, []).append(k)
    report: dict[str, Any] = {"views": 0, "cameras": [], "ground_truth": None}
    models: dict[str, CameraModel] = {}
    icov: dict[str, Any] = {}
    gts = []
    for kind, idx in groups.items():
        cres = _calibrate_group(opened.path, target, summary, idx, kind)
        models.update({c.name: c.camera for c in cres.cameras})
        icov.update({c.name: c.covariance for c in cres.cameras if c.covariance is not None})
        cmp = compare_with_truth(cres, truth_from_sequence(dict(opened.doc)))
        report["views"] += int(cres.n_views)
        report["cameras"] += [{"name": c.name, "camera": c.camera.to_kalibr(),
                               "reprojection_rms_px": float(c.residuals.rms_px)} for c in cres.cameras]
        if cmp is not None:
            gts.append(cmp.to_dict())
    if gts:
        report["ground_truth"] = _merge_truth(gts)
    return _Intrinsics({n: "camera calibration" for n in models}, models, report, icov)


def _calibrate_group(seq: Path, target: Any, summary: Any, idx: list[int], kind: str) -> Any:
    """The camera calibration of the cameras ``idx`` (one kind) on their detections."""
    from ibiscape_eval.calib.pipeline import DetectionSummary, calibrate_frames

    sub = DetectionSummary(tuple(summary.observations[k] for k in idx), summary.views,
                           tuple(summary.frames_tried[k] for k in idx),
                           tuple(summary.frames_unreadable[k] for k in idx),
                           tuple(summary.frames_detected[k] for k in idx), dict(summary.extra))
    try:
        return calibrate_frames(target, sub, max_views=60)
    except CalibrationError as e:
        what = "event cameras" if kind == "events" else "cameras"
        raise CalibrationError(f"{seq}: the camera calibration of the {what} for the "
                               f"intrinsics failed ({e}); give --cams camchain.yaml") from None


def _solve(obs: list[CameraObservations], imu: ImuData, imu_path: str | os.PathLike[str], noise: ImuNoise,
           corners: Any, options: ImuCameraOptions, icov: dict[str, Any], step: _Steps) -> ImuCameraResult:
    """The camera-IMU solve (the last half of the progress); an IMU that does not fit is named."""
    from .calibrate import calibrate_imu_camera as solve

    def solve_progress(frac: float, label: str) -> None:
        step(0.5 + 0.5 * frac, label)

    try:
        return solve(obs, imu, noise, corners, options, intrinsics_covariance=icov or None,
                     progress=solve_progress)
    except ImuStreamError as e:
        raise e.at(imu_path) from None


def _errors_vs_truth(result: ImuCameraResult, doc: dict[str, Any], names: Sequence[str]
                     ) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, float]]]:
    """``sequence.yaml``'s extrinsics and offsets, and the result's errors (with the refined
    intrinsics' errors where the truth has the camera)."""
    from ibiscape_eval.calib.report import truth_from_sequence

    truth = _truth(doc, names)
    errors = errors_against_truth(result, truth)
    true_cams = truth_from_sequence(doc)
    for cal in result.cameras:
        if cal.name in errors and cal.name in true_cams:
            t_cam = true_cams[cal.name][0]
            errors[cal.name].update({f"{k}_error_px": float(a - b) for k, a, b in zip(
                ("fx", "fy", "cx", "cy"), cal.camera.intrinsics, t_cam.intrinsics, strict=True)})
    return truth, errors


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
