"""What the VIO reads: a stereo rig, IMU samples and noise, frame lists, optional ground truth.

Two layouts:

- **IBISCape** (``sequence.yaml`` + ``other_sensors/imu*.csv`` + ``rgbL``/``rgbR`` folders with
  ``timestamps.csv`` and ``frames/``): calibration and IMU noise come from ``sequence.yaml``
  unless ``calib`` (Kalibr ``camchain-imucam.yaml``, ``cam0`` = left) or ``imu_yaml`` (Kalibr
  ``imu.yaml``) are given.  Ground truth: ``vehicle_gt/groundtruth_sync.csv``.
- **EuRoC ASL** (``mav0/cam0``, ``mav0/cam1``, ``mav0/imu0`` with ``sensor.yaml`` and
  ``data.csv``): the body frame is EuRoC's (the IMU's).  Ground truth:
  ``state_groundtruth_estimate0/data.csv``.

Everything the issue calls bad input is refused here with a message naming the file: a missing or
inconsistent calibration (image size different from the calibration's), an IMU stream that does
not cover the images, non-monotonic stamps, left and right frame lists that do not pair up.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, FormatError, IbiscapeError
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.core.trajectory import Trajectory

from .rig import StereoRig

__all__ = ["StereoSequence", "load_sequence"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class StereoSequence:
    """Inputs of one run (see the module docstring).

    Attributes
    ----------
    path, layout : str
        The folder and ``"ibiscape"`` or ``"euroc"``.
    rig : StereoRig
    noise : ImuNoise
    imu_stamps_ns, gyro_rad_s, accel_m_s2 : ndarray
        IMU samples (N,), (N, 3), (N, 3) in the IMU frame (right-handed).
    T_body_imu : ndarray, shape (4, 4)
    frame_stamps_ns : ndarray, shape (M,), int64
        Stamps of the stereo pairs (empty when the sequence has no images).
    left_files, right_files : list of Path
    groundtruth : Trajectory or None
    weather : str or None
    """

    path: str
    layout: str
    rig: StereoRig
    noise: ImuNoise
    imu_stamps_ns: npt.NDArray[np.int64]
    gyro_rad_s: FloatArray
    accel_m_s2: FloatArray
    T_body_imu: FloatArray
    frame_stamps_ns: npt.NDArray[np.int64]
    left_files: list[Path]
    right_files: list[Path]
    groundtruth: Trajectory | None
    weather: str | None = None

    @property
    def n_frames(self) -> int:
        return int(self.frame_stamps_ns.shape[0])

    @property
    def imu(self) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
        return self.imu_stamps_ns, self.gyro_rad_s, self.accel_m_s2

    def __repr__(self) -> str:
        return (f"StereoSequence({self.path!r}, {self.layout}, {self.n_frames} frames, "
                f"{len(self.imu_stamps_ns)} IMU samples)")


def load_sequence(path: str | os.PathLike[str], *, calib: str | os.PathLike[str] | None = None,
                  imu_yaml: str | os.PathLike[str] | None = None,
                  require_images: bool = True) -> StereoSequence:
    """Read an IBISCape-layout sequence or an EuRoC ASL folder (module docstring).

    Parameters
    ----------
    path : folder
    calib : Kalibr ``camchain-imucam.yaml``, optional
        Overrides the sequence's own calibration (``cam0`` left, ``cam1`` right).
    imu_yaml : Kalibr ``imu.yaml``, optional
        Overrides the IMU noise densities.
    require_images : bool
        Refuse a sequence without camera frames (False for IMU/ground-truth-only use such as
        synthetic measurements).

    Raises
    ------
    FormatError, CalibrationError, IbiscapeError
        Naming the file and what to do.
    """
    p = Path(path)
    if not p.is_dir():
        raise IbiscapeError(f"{p}: not a folder; give an IBISCape sequence folder or an EuRoC "
                            "ASL folder (with mav0/)")
    if (p / "mav0").is_dir() or (p / "cam0").is_dir():
        seq = _load_euroc(p / "mav0" if (p / "mav0").is_dir() else p, calib, imu_yaml,
                          require_images)
    elif (p / "sequence.yaml").is_file() or (p / "other_sensors").is_dir():
        seq = _load_ibiscape(p, calib, imu_yaml, require_images)
    else:
        raise IbiscapeError(f"{p}: neither an IBISCape sequence (sequence.yaml, other_sensors/) "
                            "nor an EuRoC ASL folder (mav0/cam0, mav0/imu0)")
    _check_coverage(seq)
    return seq


# ---------------------------------------------------------------------------------------------
# IBISCape


def _load_ibiscape(p: Path, calib: Any, imu_yaml: Any, require_images: bool) -> StereoSequence:
    from ibiscape_eval.io import read_trajectory
    from ibiscape_eval.io.kalibr import read_imu_noise
    from ibiscape_eval.io.sequence import read_sequence_yaml
    from ibiscape_eval.io.stereo import read_imu_samples

    doc: dict[str, Any] = {}
    if (p / "sequence.yaml").is_file():
        doc = read_sequence_yaml(p / "sequence.yaml")
    cams = doc.get("cameras") or {}
    imus = doc.get("imus") or {}
    imu_entry = imus.get("imu0") or (next(iter(imus.values())) if imus else {})
    # cameras
    if calib is not None:
        left_name, right_name = _stereo_folders(p, cams)
        rig = _rig_from_camchain(calib)
    else:
        if not cams:
            raise CalibrationError(f"{p}: no calibration (sequence.yaml has no cameras); give "
                                   "--calib camchain-imucam.yaml")
        left_name, right_name = _stereo_names(p, cams)
        rig = _checked_rig(p / "sequence.yaml",
                           _camera(cams[left_name], p / "sequence.yaml", left_name),
                           _camera(cams[right_name], p / "sequence.yaml", right_name),
                           _T(cams[left_name], "T_body_cam", p / "sequence.yaml", left_name),
                           _T(cams[right_name], "T_body_cam", p / "sequence.yaml", right_name))
    # IMU
    imu_file = p / str(imu_entry.get("file", "")) if imu_entry.get("file") else None
    if imu_file is None or not imu_file.is_file():
        cands = sorted((p / "other_sensors").glob("imu*.csv"))
        if not cands:
            raise FormatError(p / "other_sensors", "no IMU file (other_sensors/imu.csv)")
        imu_file = cands[0]
    stamps, gyro, acc = read_imu_samples(
        imu_file, fmt="ibiscape" if (p / "vehicle_gt").is_dir() else "euroc")
    T_body_imu = (_T(imu_entry, "T_body_imu", p / "sequence.yaml", "imus")
                  if "T_body_imu" in imu_entry else np.eye(4))
    if imu_yaml is not None:
        noise = read_imu_noise(imu_yaml)
    elif imu_entry:
        noise = ImuNoise.from_kalibr(imu_entry, source=f"{p / 'sequence.yaml'}: imus")
    else:
        raise IbiscapeError(f"{p}: no IMU noise (sequence.yaml has no imus); give --imu imu.yaml")
    # frames
    frames, lf, rf = _frames(p / left_name, p / right_name, "timestamps.csv", "frames",
                             require_images)
    gt_file = p / "vehicle_gt" / "groundtruth_sync.csv"
    gt = read_trajectory(gt_file, "ibiscape", name="groundtruth") if gt_file.is_file() else None
    weather = (doc.get("weather") or {}).get("preset") if doc else None
    return StereoSequence(str(p), "ibiscape", rig, noise, stamps, gyro, acc, T_body_imu, frames,
                          lf, rf, gt, weather)


def _stereo_names(p: Path, cams: dict[str, Any]) -> tuple[str, str]:
    if "rgbL" in cams and "rgbR" in cams:
        return "rgbL", "rgbR"
    rgb = [n for n, c in cams.items() if isinstance(c, dict) and c.get("kind", "rgb") == "rgb"]
    if len(rgb) < 2:
        raise CalibrationError(f"{p / 'sequence.yaml'}: needs two RGB cameras (rgbL, rgbR) for "
                               f"stereo, found {', '.join(cams) or 'none'}")
    return rgb[0], rgb[1]


def _stereo_folders(p: Path, cams: dict[str, Any]) -> tuple[str, str]:
    if cams:
        return _stereo_names(p, cams)
    return "rgbL", "rgbR"


def _T(entry: Any, key: str, where: Path, name: str) -> FloatArray:
    from ibiscape_eval.core.kalibr import rigid_transform_problem

    if not isinstance(entry, dict) or key not in entry:
        raise CalibrationError(f"{where}: {name} lacks {key}; give --calib")
    try:
        T = np.asarray(entry[key], dtype=float)
    except (TypeError, ValueError, OverflowError):
        T = np.zeros(0)
    problem = ("must be a 4x4 matrix of numbers" if T.shape != (4, 4)
               else rigid_transform_problem(T))
    if problem:
        raise CalibrationError(f"{where}: {name}.{key} {problem}; fix it or give --calib")
    return T


#: the largest image side [px] and distortion coefficient magnitude a calibration may give
MAX_IMAGE_SIDE_PX = 100_000
MAX_DISTORTION_COEFF = 100.0


def _camera_range_problem(cam: CameraModel) -> str | None:
    w, h = cam.width_px, cam.height_px
    if max(w, h) > MAX_IMAGE_SIDE_PX:
        return f"resolution {w}x{h} px is larger than {MAX_IMAGE_SIDE_PX} px a side"
    if not (cam.fx <= 100 * max(w, h) and cam.fy <= 100 * max(w, h)):
        return (f"focal lengths {cam.fx:.6g}, {cam.fy:.6g} px exceed 100 x the image side "
                f"({max(w, h)} px)")
    if not (-w <= cam.cx <= 2 * w and -h <= cam.cy <= 2 * h):
        return f"principal point ({cam.cx:.6g}, {cam.cy:.6g}) px lies far outside the {w}x{h} image"
    if any(abs(c) > MAX_DISTORTION_COEFF for c in cam.coeffs):
        return f"distortion coefficients {list(cam.coeffs)} exceed {MAX_DISTORTION_COEFF:g}"
    return None


def _checked_rig(where: Path, left: CameraModel, right: CameraModel, T_body_left: FloatArray,
                 T_body_right: FloatArray) -> StereoRig:
    """The rig, rectified once here so that a degenerate calibration is refused naming its file."""
    try:
        rig = StereoRig(left, right, T_body_left, T_body_right)
        rig.rectified()
    except CalibrationError as e:
        raise CalibrationError(f"{where}: {e}") from None
    except Exception as e:  # cv2.error on a calibration OpenCV cannot rectify
        if type(e).__module__.split(".")[0] != "cv2":
            raise
        raise CalibrationError(f"{where}: stereo rectification failed ({str(e).strip()[:80]}); "
                               "check the intrinsics and the camera-to-camera transform") from None
    return rig


def _camera(entry: Any, where: Path, name: str) -> CameraModel:
    if isinstance(entry, CameraModel):
        cam = entry
    elif not isinstance(entry, dict):
        raise CalibrationError(f"{where}: camera {name} is not a mapping")
    else:
        try:
            cam = CameraModel.from_kalibr(entry)
        except (IbiscapeError, OverflowError) as e:
            raise CalibrationError(f"{where}: camera {name}: {e}") from None
    problem = _camera_range_problem(cam)
    if problem:
        raise CalibrationError(f"{where}: camera {name}: {problem}; fix the intrinsics")
    return cam


def _rig_from_camchain(calib: str | os.PathLike[str]) -> StereoRig:
    from ibiscape_eval.io.kalibr import read_camchain

    chain = read_camchain(calib)
    if len(chain) < 2:
        raise CalibrationError(f"{calib}: needs cam0 (left) and cam1 (right)")
    c0, c1 = chain.cameras[0], chain.cameras[1]
    if c0.T_cam_imu is None:
        raise CalibrationError(f"{calib}: cam0 lacks T_cam_imu (use camchain-imucam.yaml from "
                               "the camera-IMU calibration)")
    T_b_c0: FloatArray = np.asarray(np.linalg.inv(c0.T_cam_imu), dtype=np.float64)
    if c1.T_cam_imu is not None:
        T_b_c1: FloatArray = np.asarray(np.linalg.inv(c1.T_cam_imu), dtype=np.float64)
    else:
        assert c1.T_cn_cnm1 is not None  # a chain has it from cam1 on
        T_b_c1 = T_b_c0 @ np.linalg.inv(c1.T_cn_cnm1)
    left = _camera(c0.camera, Path(calib), "cam0")
    right = _camera(c1.camera, Path(calib), "cam1")
    return _checked_rig(Path(calib), left, right, T_b_c0, T_b_c1)


# ---------------------------------------------------------------------------------------------
# EuRoC


def _load_euroc(m: Path, calib: Any, imu_yaml: Any, require_images: bool) -> StereoSequence:
    from ibiscape_eval.io import read_trajectory
    from ibiscape_eval.io.asl import read_asl_sensor_yaml
    from ibiscape_eval.io.kalibr import read_imu_noise
    from ibiscape_eval.io.stereo import read_imu_samples

    if calib is not None:
        rig = _rig_from_camchain(calib)
    else:
        cams = []
        for c in ("cam0", "cam1"):
            f = m / c / "sensor.yaml"
            if not f.is_file():
                raise CalibrationError(f"{f}: missing; give --calib camchain-imucam.yaml")
            d = read_asl_sensor_yaml(f)
            model = {"radial-tangential": "radtan", "equidistant": "equidistant"}.get(
                str(d.get("distortion_model", "radial-tangential")), "radtan")
            entry = {"intrinsics": d.get("intrinsics"), "resolution": d.get("resolution"),
                     "distortion_model": model,
                     "distortion_coeffs": d.get("distortion_coefficients", [0.0] * 4)}
            cams.append((_camera(entry, f, c), d["T_BS"]))
        rig = _checked_rig(m / "cam1" / "sensor.yaml", cams[0][0], cams[1][0], cams[0][1],
                           cams[1][1])
    imu_file = m / "imu0" / "data.csv"
    stamps, gyro, acc = read_imu_samples(imu_file, fmt="euroc")
    T_body_imu = np.eye(4)
    sensor = m / "imu0" / "sensor.yaml"
    if imu_yaml is not None:
        noise = read_imu_noise(imu_yaml)
    elif sensor.is_file():
        d = read_asl_sensor_yaml(sensor)
        T_body_imu = d["T_BS"]
        noise = ImuNoise.from_kalibr(d, source=str(sensor))
    else:
        raise IbiscapeError(f"{sensor}: missing; give --imu imu.yaml")
    frames, lf, rf = _frames(m / "cam0", m / "cam1", "data.csv", "data", require_images)
    gt_file = m / "state_groundtruth_estimate0" / "data.csv"
    gt = read_trajectory(gt_file, "euroc", name="groundtruth") if gt_file.is_file() else None
    return StereoSequence(str(m), "euroc", rig, noise, stamps, gyro, acc, T_body_imu, frames, lf,
                          rf, gt, None)


# ---------------------------------------------------------------------------------------------
# shared checks


def _frames(left: Path, right: Path, listname: str, sub: str,
            require_images: bool) -> tuple[npt.NDArray[np.int64], list[Path], list[Path]]:
    from ibiscape_eval.io.stereo import read_frame_list

    if not (left / listname).is_file() or not (right / listname).is_file():
        if require_images:
            raise IbiscapeError(f"{left.parent}: no stereo images ({left.name}/{listname} and "
                                f"{right.name}/{listname}); render the sequence first")
        return np.zeros(0, dtype=np.int64), [], []
    tl, nl = read_frame_list(left / listname)
    tr, nr = read_frame_list(right / listname)
    if len(tl) != len(tr) or not np.array_equal(tl, tr):
        common = np.intersect1d(tl, tr)
        if len(common) < 2:
            raise FormatError(right / listname, f"left ({len(tl)}) and right ({len(tr)}) frames "
                              "share no timestamps; the stereo pair must be synchronised")
        il = np.searchsorted(tl, common)
        ir = np.searchsorted(tr, common)
        nl = [nl[i] for i in il]
        nr = [nr[i] for i in ir]
        tl = common
    return tl, [left / sub / n for n in nl], [right / sub / n for n in nr]


def _check_coverage(seq: StereoSequence) -> None:
    if seq.n_frames == 0:
        return
    t_img0, t_img1 = int(seq.frame_stamps_ns[0]), int(seq.frame_stamps_ns[-1])
    t_imu0, t_imu1 = int(seq.imu_stamps_ns[0]), int(seq.imu_stamps_ns[-1])
    slack = int(2e9 / max(seq.noise.update_rate_hz, 1.0))
    if t_imu0 > t_img0 + slack or t_imu1 < t_img1 - slack:
        raise IbiscapeError(
            f"{seq.path}: the IMU stream ({t_imu0 * 1e-9:.3f}..{t_imu1 * 1e-9:.3f} s) does not "
            f"cover the images ({t_img0 * 1e-9:.3f}..{t_img1 * 1e-9:.3f} s); give the matching "
            "IMU file or trim the frame lists")
    if seq.n_frames and seq.left_files:
        from ibiscape_eval.io.stereo import read_gray_image

        w, h = seq.rig.size
        for files in (seq.left_files, seq.right_files):
            img = read_gray_image(files[0])
            if img.shape != (h, w):
                raise CalibrationError(
                    f"{files[0]}: image is {img.shape[1]}x{img.shape[0]} px but the calibration "
                    f"says {w}x{h}; give the matching --calib (or rescale the intrinsics)")
