"""What the VIO reads: a stereo rig, IMU samples and noise, frame lists, optional ground truth.

Taken from a sequence opened by :func:`ibiscape_eval.io.open_sequence` (:func:`stereo_inputs`;
:func:`load_sequence` opens and takes in one call):

- **IBISCape** (``sequence.yaml`` + ``other_sensors/imu*.csv`` + ``rgbL``/``rgbR`` folders with
  ``timestamps.csv`` and ``frames/``): calibration and IMU noise come from ``sequence.yaml``
  unless ``calib`` (Kalibr ``camchain-imucam.yaml``, ``cam0`` = left) or ``imu_yaml`` (Kalibr
  ``imu.yaml``) are given.  Ground truth: ``vehicle_gt/groundtruth_sync.csv``.
- **EuRoC ASL** (``mav0/cam0``, ``mav0/cam1``, ``mav0/imu0`` with ``sensor.yaml`` and
  ``data.csv``): the body frame is EuRoC's (the IMU's).  Ground truth:
  ``state_groundtruth_estimate0/data.csv`` (optional; an empty file counts as none).
- **TUM-VI** (the ASL layout with ``dso/camchain.yaml``, equidistant cameras) and **ROS bags**
  (the first two image topics, the ``Imu`` topic; give ``--calib`` and ``--imu``): like EuRoC.

Everything the issue calls bad input is refused here with a message naming the file: a missing or
inconsistent calibration (image size different from the calibration's), an IMU stream that does
not cover the images, non-monotonic stamps, left and right frame lists that do not pair up.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.core.sequence import Sequence
from ibiscape_eval.core.trajectory import Trajectory

from .rig import StereoRig

__all__ = ["SETUPS", "StereoSequence", "load_sequence", "resolve_setup", "stereo_inputs"]

FloatArray = npt.NDArray[np.float64]
#: reader(i) -> (left, right) grey images of stereo pair i
FrameReader = Callable[[int], tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]]

# the options that supply what a sequence lacks (an error's hint)
_CALIB = (Remedy("calib"),)
_IMU = (Remedy("imu_yaml"),)


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
        Empty for frames inside a bag (``frame_reader`` reads them).
    groundtruth : Trajectory or None
    weather : str or None
    frame_reader : callable, optional
        ``frame_reader(i)`` -> (left, right) grey images, for frames that are not files (ESVI:
        frames reconstructed from the events; RGB-D: the grey RGB image and the registered
        depth [m], float32).
    setup : str
        ``svi``, ``esvi`` or ``rgbd`` (:func:`resolve_setup`).
    labeler : callable, optional
        ``labeler(i)`` -> the files of pair ``i`` for messages.
    depth_unit : str
        RGB-D: ``mm`` or ``carla-log`` (the depth files read; :mod:`ibiscape_eval.vio.depth`).
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
    frame_reader: FrameReader | None = None
    setup: str = "svi"
    labeler: Callable[[int], tuple[str, str]] | None = None
    depth_unit: str = ""

    @property
    def n_frames(self) -> int:
        return int(self.frame_stamps_ns.shape[0])

    def read_pair(self, i: int) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]:
        """Stereo pair ``i`` as 8-bit grey images (files, or frames decoded from a bag)."""
        if self.frame_reader is not None:
            return self.frame_reader(i)
        from ibiscape_eval.io.stereo import read_gray_image

        return read_gray_image(self.left_files[i]), read_gray_image(self.right_files[i])

    def frame_labels(self, i: int) -> tuple[str, str]:
        """Names of pair ``i``'s images for messages."""
        if self.labeler is not None:
            return self.labeler(i)
        if self.frame_reader is not None or not self.left_files:
            return f"{self.path} left frame {i}", f"{self.path} right frame {i}"
        return str(self.left_files[i]), str(self.right_files[i])

    @property
    def imu(self) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
        return self.imu_stamps_ns, self.gyro_rad_s, self.accel_m_s2

    def __repr__(self) -> str:
        return (f"StereoSequence({self.path!r}, {self.layout}, {self.n_frames} frames, "
                f"{len(self.imu_stamps_ns)} IMU samples)")


def load_sequence(path: str | os.PathLike[str], *, calib: str | os.PathLike[str] | None = None,
                  imu_yaml: str | os.PathLike[str] | None = None,
                  require_images: bool = True, setup: str = "auto",
                  options: Any = None) -> StereoSequence:
    """Open a recording (:func:`ibiscape_eval.io.open_sequence`) and take the VIO's inputs from it
    (:func:`stereo_inputs`).

    Raises
    ------
    FormatError, CalibrationError, IbiscapeError
        Naming the file and what to do.
    """
    from ibiscape_eval.io.open_sequence import open_sequence

    p = Path(path)
    if not p.exists():
        raise IbiscapeError(f"{p}: not a folder; give an IBISCape sequence folder or an EuRoC "
                            "ASL folder (with mav0/)")
    return stereo_inputs(open_sequence(p), calib=calib, imu_yaml=imu_yaml,
                         require_images=require_images, setup=setup, options=options)


def stereo_inputs(seq: Sequence, *, calib: str | os.PathLike[str] | None = None,
                  imu_yaml: str | os.PathLike[str] | None = None,
                  require_images: bool = True, setup: str = "auto",
                  options: Any = None) -> StereoSequence:
    """The VIO's inputs from an opened sequence (module docstring): the stereo rig (the first two
    cameras: ``rgbL``/``rgbR`` of ``sequence.yaml``, ``cam0``/``cam1`` otherwise), the IMU
    samples and noise, the stereo frames and the ground truth when there is one.

    Parameters
    ----------
    seq : Sequence
        From :func:`ibiscape_eval.io.open_sequence` (IBISCape, EuRoC, TUM-VI, ROS bag).
    calib : Kalibr ``camchain-imucam.yaml``, optional
        Overrides the sequence's own calibration (``cam0`` left, ``cam1`` right).
    imu_yaml : Kalibr ``imu.yaml``, optional
        Overrides the IMU noise densities.
    require_images : bool
        Refuse a sequence without camera frames (False for IMU/ground-truth-only use such as
        synthetic measurements).
    setup : {"auto", "svi", "esvi", "rgbd", "full"}
        Which cameras the VIO uses (:func:`resolve_setup`); ESVI and RGB-D need the IBISCape
        layout.
    options : EsviOptions or DepthOptions, optional
        The ESVI reconstruction (:mod:`ibiscape_eval.vio.events_input`) or the depth front end's
        options (:mod:`ibiscape_eval.vio.depth`).
    """
    chosen = resolve_setup(seq, setup)
    if seq.layout == "ibiscape":
        out = _load_ibiscape(seq, calib, imu_yaml, require_images or chosen != "svi", chosen, options)
    elif chosen != "svi":
        raise IbiscapeError(f"{seq.path}: the {chosen.upper()} setup needs an IBISCape sequence "
                            f"(sequence.yaml with its cameras), not {seq.layout}")
    elif seq.layout in ("euroc", "tumvi", "rosbag"):
        out = _load_asl(seq, calib, imu_yaml, require_images)
    else:
        raise IbiscapeError(f"{seq.path}: the VIO needs a stereo sequence with an IMU (IBISCape, "
                            f"EuRoC, TUM-VI or a ROS bag), not {seq.layout}")
    _check_coverage(out)
    return out


# ---------------------------------------------------------------------------------------------
# IBISCape


#: the VIO setups (the paper's): stereo RGB, stereo events, RGB + depth, every sensor
SETUPS = ("auto", "svi", "esvi", "rgbd", "full")


def resolve_setup(seq: Sequence, setup: str = "auto") -> str:
    """The setup a sequence is run as: ``svi``, ``esvi`` or ``rgbd``.  ``auto``: stereo RGB
    (``rgbL``/``rgbR`` or any two RGB cameras) -> svi, an RGB camera with a depth camera -> rgbd,
    two event cameras -> esvi; ``full`` (every sensor there is) -> rgbd when the sequence has an
    RGB-D pair (the most accurate measurement, see the README), else svi, else esvi."""
    if setup not in SETUPS:
        raise IbiscapeError(f"setup {setup!r}: use one of {', '.join(SETUPS)}")
    if setup not in ("auto", "full"):
        return setup
    doc = dict(seq.doc) if seq.layout == "ibiscape" else {}
    kinds = {n: (c.get("kind", "rgb") if isinstance(c, dict) else "rgb")
             for n, c in (doc.get("cameras") or {}).items()}
    n_rgb = sum(k == "rgb" for k in kinds.values())
    has_depth = "depth" in kinds.values() and n_rgb >= 1
    n_ev = sum(c.kind == "events" for c in seq.cameras)
    stereo_rgb = ("rgbL" in kinds and "rgbR" in kinds) or (not doc and len(seq.cameras) >= 2)
    order = (("rgbd", has_depth), ("svi", stereo_rgb), ("esvi", n_ev >= 2)) if setup == "full" \
        else (("svi", stereo_rgb), ("rgbd", has_depth), ("esvi", n_ev >= 2))
    return next((name for name, ok in order if ok), "svi")


def _ibiscape_imu(seq: Sequence, imu_yaml: Any) -> tuple[Any, ...]:
    """IMU samples, ``T_body_imu`` and noise of an IBISCape sequence."""
    from ibiscape_eval.io.kalibr import read_imu_noise

    p = seq.path
    imus = dict(seq.doc).get("imus") or {}
    imu_entry = imus.get("imu0") or (next(iter(imus.values())) if imus else {})
    if seq.imu is None:
        raise FormatError(p / "other_sensors", "no IMU file (other_sensors/imu.csv)")
    stamps, gyro, acc = seq.imu.samples.get()
    T_body_imu = (_T(imu_entry, "T_body_imu", p / "sequence.yaml", "imus")
                  if "T_body_imu" in imu_entry else np.eye(4))
    if imu_yaml is not None:
        noise = read_imu_noise(imu_yaml)
    elif imu_entry:
        noise = ImuNoise.from_kalibr(imu_entry, source=f"{p / 'sequence.yaml'}: imus")
    else:
        raise IbiscapeError(f"{p}: no IMU noise (sequence.yaml has no imus); give {0}", hint=_IMU)
    return stamps, gyro, acc, T_body_imu, noise


def _load_ibiscape(seq: Sequence, calib: Any, imu_yaml: Any, require_images: bool,
                   setup: str = "svi", options: Any = None) -> StereoSequence:
    p = seq.path
    doc: dict[str, Any] = dict(seq.doc)
    cams = doc.get("cameras") or {}
    if setup == "rgbd":
        from .depth_input import rgbd_parts

        rig, frames, reader, labeler, unit = rgbd_parts(seq, cams, calib, options)
        lf: list[Path] = []
        rf: list[Path] = []
    elif setup == "esvi":
        from .events_input import event_pair_names, event_stereo_frames

        left_name, right_name = event_pair_names(seq)
        rig = _rig_from_camchain(calib) if calib is not None else _doc_rig(p, cams, left_name, right_name)
        frames, reader, labeler = event_stereo_frames(seq, left_name, right_name, options)
        lf, rf, unit = [], [], ""
    else:
        if calib is not None:
            left_name, right_name = _stereo_folders(p, cams)
            rig = _rig_from_camchain(calib)
        else:
            if not cams:
                raise CalibrationError(f"{p}: no calibration (sequence.yaml has no cameras); give "
                                       "{0}", hint=_CALIB)
            left_name, right_name = _stereo_names(p, cams)
            rig = _doc_rig(p, cams, left_name, right_name)
        frames, lf, rf, reader = _frames(seq, left_name, right_name, "timestamps.csv", require_images)
        labeler, unit = None, ""
    stamps, gyro, acc, T_body_imu, noise = _ibiscape_imu(seq, imu_yaml)
    weather = (doc.get("weather") or {}).get("preset") if doc else None
    return StereoSequence(str(p), "ibiscape", rig, noise, stamps, gyro, acc, T_body_imu, frames,
                          lf, rf, seq.ground_truth(), weather, reader, setup, labeler, unit)


def _doc_rig(p: Path, cams: dict[str, Any], left_name: str, right_name: str) -> StereoRig:
    """The stereo rig of two ``sequence.yaml`` cameras."""
    where = p / "sequence.yaml"
    for n in (left_name, right_name):
        if n not in cams:
            raise CalibrationError(f"{where}: no calibration of camera {n}; give {0}", hint=_CALIB)
    return _checked_rig(where, _camera(cams[left_name], where, left_name),
                        _camera(cams[right_name], where, right_name),
                        _T(cams[left_name], "T_body_cam", where, left_name),
                        _T(cams[right_name], "T_body_cam", where, right_name))


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
        raise CalibrationError(f"{where}: {name} lacks {key}; give {{0}}", hint=_CALIB)
    try:
        T = np.asarray(entry[key], dtype=float)
    except (TypeError, ValueError, OverflowError):
        T = np.zeros(0)
    problem = ("must be a 4x4 matrix of numbers" if T.shape != (4, 4)
               else rigid_transform_problem(T))
    if problem:
        raise CalibrationError(f"{where}: {name}.{key} {problem}; fix it or give {{0}}", hint=_CALIB)
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


def _load_asl(seq: Sequence, calib: Any, imu_yaml: Any, require_images: bool) -> StereoSequence:
    """EuRoC / TUM-VI / ROS bag: the first two cameras are the stereo pair (``cam0`` left)."""
    from ibiscape_eval.io.kalibr import read_imu_noise

    m = seq.path / "mav0" if (seq.path / "mav0").is_dir() else seq.path
    if len(seq.cameras) < 2:
        raise CalibrationError(f"{seq.path}: the stereo VIO needs two cameras, the sequence has "
                               f"{', '.join(seq.camera_names) or 'none'}")
    left, right = seq.cameras[0], seq.cameras[1]
    if calib is not None:
        rig = _rig_from_camchain(calib)
    else:
        cams = []
        for c in (left, right):
            f = (Path(c.calibration_source) if c.calibration_source
                 else c.root if seq.layout == "rosbag" else c.root / "sensor.yaml")
            if not c.entry or c.T_body_cam is None:
                what = "missing" if seq.layout != "rosbag" else "the bag holds no calibration"
                raise CalibrationError(f"{f}: {what}; give {{0}}", hint=_CALIB)
            cams.append((_camera(c.entry, f, c.name), np.asarray(c.T_body_cam, dtype=np.float64)))
        where = Path(right.calibration_source) if right.calibration_source else right.root
        rig = _checked_rig(where, cams[0][0], cams[1][0], cams[0][1], cams[1][1])
    if seq.imu is None:
        raise FormatError(m / "imu0" / "data.csv", "no IMU samples (imu0/data.csv); the VIO needs the IMU")
    stamps, gyro, acc = seq.imu.samples.get()
    T_body_imu = np.eye(4) if seq.imu.T_body_imu is None else np.asarray(seq.imu.T_body_imu, dtype=np.float64)
    if imu_yaml is not None:
        noise = read_imu_noise(imu_yaml)
    elif seq.imu.noise is not None:
        noise = seq.imu.noise
    elif seq.imu.noise_problem:
        raise FormatError(seq.imu.noise_source, seq.imu.noise_problem)
    else:
        where = m / "imu0" / "sensor.yaml" if seq.layout != "rosbag" else seq.path
        raise IbiscapeError(f"{where}: {'missing' if seq.layout != 'rosbag' else 'no IMU noise'}; "
                            "give {0}", hint=_IMU)
    frames, lf, rf, reader = _frames(seq, left.name, right.name, "data.csv", require_images)
    return StereoSequence(str(m), seq.layout, rig, noise, stamps, gyro, acc, T_body_imu, frames, lf,
                          rf, seq.ground_truth(), None, reader)


# ---------------------------------------------------------------------------------------------
# shared checks


def _frames(seq: Sequence, left_name: str, right_name: str, listname: str, require_images: bool
            ) -> tuple[npt.NDArray[np.int64], list[Path], list[Path], FrameReader | None]:
    """The stereo pairs: stamps both cameras share, their files (or a reader of bag frames)."""
    names = seq.camera_names
    if left_name not in names or right_name not in names:
        gone = [n for n in (left_name, right_name) if n not in names]
        if require_images and len(gone) == 1:  # one camera of the pair
            raise FormatError(seq.path / gone[0] / listname, f"camera {gone[0]} of the stereo pair "
                              f"{left_name}/{right_name} has no frames; record both or use --setup")
        if require_images:
            raise IbiscapeError(f"{seq.path}: no stereo images ({left_name}/{listname} and "
                                f"{right_name}/{listname}); render the sequence first")
        return np.zeros(0, dtype=np.int64), [], [], None
    left, right = seq.camera(left_name), seq.camera(right_name)
    tl, tr = left.stamps_ns, right.stamps_ns
    assert tl is not None and tr is not None
    il = ir = np.arange(tl.size)
    if len(tl) != len(tr) or not np.array_equal(tl, tr):
        common = np.intersect1d(tl, tr)
        if len(common) < 2:
            raise FormatError(right.root / listname, f"left ({len(tl)}) and right ({len(tr)}) frames "
                              "share no timestamps; the stereo pair must be synchronised")
        il, ir = np.searchsorted(tl, common), np.searchsorted(tr, common)
        tl = common
    if left.files is None or right.files is None:  # frames inside a bag: decoded on demand
        def read(i: int) -> tuple[Any, Any]:
            return _gray(left.load(int(il[i])), left.label(int(il[i]))), \
                _gray(right.load(int(ir[i])), right.label(int(ir[i])))

        return np.asarray(tl, dtype=np.int64), [], [], read
    lp, rp = left.paths, right.paths
    return (np.asarray(tl, dtype=np.int64), [lp[i] for i in il], [rp[i] for i in ir], None)


def _gray(img: Any, label: str) -> npt.NDArray[np.uint8]:
    import cv2

    if img is None:
        raise FormatError(label, "not an image OpenCV can read")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    return np.asarray(img, dtype=np.uint8)


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
    if seq.n_frames:
        w, h = seq.rig.size
        first = seq.read_pair(0)
        for img, label in zip(first, seq.frame_labels(0), strict=True):
            if img.shape != (h, w):
                raise CalibrationError(
                    f"{label}: image is {img.shape[1]}x{img.shape[0]} px but the calibration "
                    f"says {w}x{h}; give the matching {{0}} (or rescale the intrinsics)", hint=_CALIB)
