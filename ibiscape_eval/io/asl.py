"""EuRoC / ASL dataset folders (Burri et al., "The EuRoC micro aerial vehicle datasets", IJRR 2016),
the layout ORB-SLAM3, BASALT, VINS-Fusion and OpenVINS read::

    <root>/mav0/cam0/data/<ns>.png    8-bit grey images
    <root>/mav0/cam0/data.csv         #timestamp [ns],filename
    <root>/mav0/cam0/sensor.yaml      sensor_type camera, T_BS, rate_hz, resolution, intrinsics, ...
    <root>/mav0/imu0/data.csv         #timestamp [ns],w_RS_S_x..z [rad s^-1],a_RS_S_x..z [m s^-2]
    <root>/mav0/imu0/sensor.yaml      sensor_type imu, T_BS, rate_hz, noise densities, random walks
    <root>/mav0/state_groundtruth_estimate0/data.csv
                                      #timestamp, p_RS_R (3), q_RS (w, x, y, z), v_RS_R (3),
                                      b_w_RS_S (3), b_a_RS_S (3): 17 columns
    <root>/mav0/state_groundtruth_estimate0/sensor.yaml

``T_BS`` maps sensor coordinates to the body frame (our ``T_body_sensor``), written like EuRoC as
``{cols: 4, rows: 4, data: [16 numbers, row-major]}``.  Every file is written atomically; readers
check the layout and name the file (and line) on errors.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.trajectory import Trajectory

from ._poses import finish_trajectory
from ._text import decimal_to_ns, parse_table, read_bytes, write_table
from .atomic import atomic_write
from .framelists import ns_digits, read_stamped_rows, write_stamped_list
from .yaml_file import read_yaml_mapping

__all__ = [
    "ASL_DISTORTION_MODELS",
    "ASL_GROUNDTRUTH_HEADER",
    "ASL_IMU_HEADER",
    "AslGroundTruth",
    "read_asl_camera",
    "read_asl_groundtruth",
    "read_asl_image_list",
    "read_asl_sensor_yaml",
    "read_imu_samples",
    "write_asl_groundtruth",
    "write_asl_image_list",
    "write_asl_imu",
    "write_asl_sensor_yaml",
]

ASL_IMU_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                  "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
ASL_GROUNDTRUTH_HEADER = (
    "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
    "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
    "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
    "b_a_RS_S_z [m s^-2]")


def write_asl_image_list(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike) -> None:
    """Write a camera ``data.csv``: ``#timestamp [ns],filename`` then ``<ns>,<ns>.png`` rows."""
    st = [int(t) for t in np.asarray(stamps_ns, dtype=np.int64).reshape(-1)]
    write_stamped_list(path, "#timestamp [ns],filename\n", st, [f"{t}.png" for t in st])


def read_asl_image_list(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[str]]:
    """Stamps [ns] and file names of a camera ``data.csv``."""
    stamps, rows = read_stamped_rows(
        path, expected="'timestamp [ns],filename'", parse=ns_digits,
        missing="data.csv not found; is this an ASL camera folder (mav0/camN)?")
    return stamps, [r[1] for r in rows]


def write_asl_imu(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike, gyro_rad_s: npt.ArrayLike,
                  accel_m_s2: npt.ArrayLike) -> None:
    """Write ``imu0/data.csv`` (EuRoC header and column order: gyro, then accelerometer, in the
    IMU's right-handed frame).  Read it back with :func:`ibiscape_eval.io.imu.read_imu`."""
    st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
    vals = np.concatenate([np.asarray(gyro_rad_s, np.float64), np.asarray(accel_m_s2, np.float64)],
                          axis=1)
    if vals.shape != (st.size, 6):
        raise IbiscapeError(f"{path}: expected (N,) stamps and (N, 3) gyro/accel, got {st.shape} "
                            f"and {vals.shape}")
    with atomic_write(path, "wb") as f:
        f.write((ASL_IMU_HEADER + "\n").encode())
        write_table(f, st, vals, stamp="ns", sep=",")


def read_imu_samples(path: str | os.PathLike[str], *, frame: str = "right-handed") -> tuple[
        npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Stamps [ns] (parsed exactly), gyro (N, 3) rad/s and accel (N, 3) m/s^2 of a 7-column
    EuRoC / IBISCape IMU csv (``#timestamp [ns], w_xyz, a_xyz``).

    ``frame="ibiscape"``: the file is in CARLA's left-handed frame (a sequence's
    ``other_sensors/imu*.csv``) and is converted to ours with
    :func:`ibiscape_eval.io.imu.mirror_ibiscape_imu`.
    """
    from .imu import mirror_ibiscape_imu

    if frame not in ("right-handed", "ibiscape"):
        raise IbiscapeError(f"unknown IMU frame {frame!r}; use right-handed or ibiscape")
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=7, ncols_min=7, ncols_max=7,
                     expected="7 columns (timestamp [ns], w_x, w_y, w_z, a_x, a_y, a_z)")
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    if not tb.finite.all():
        bad = int(np.flatnonzero(~tb.finite)[0])
        raise FormatError(path, "non-finite IMU value", line=int(tb.lines[bad]))
    if stamps.size > 1 and np.any(np.diff(stamps) <= 0):
        bad = int(np.flatnonzero(np.diff(stamps) <= 0)[0]) + 1
        raise FormatError(path, "timestamps must increase", line=int(tb.lines[bad]))
    g, a = tb.values[:, 1:4], tb.values[:, 4:7]
    if frame == "ibiscape":
        g, a = mirror_ibiscape_imu(g, a)
    return stamps, np.ascontiguousarray(g), np.ascontiguousarray(a)


class AslGroundTruth:
    """EuRoC ground truth: body poses, world velocity and the IMU biases.

    Attributes
    ----------
    trajectory : Trajectory
        ``T_world_body``.
    vel_m_s : ndarray, shape (N, 3)
    gyro_bias_rad_s, accel_bias_m_s2 : ndarray, shape (N, 3)
    """

    def __init__(self, trajectory: Trajectory, vel_m_s: npt.ArrayLike,
                 gyro_bias_rad_s: npt.ArrayLike, accel_bias_m_s2: npt.ArrayLike) -> None:
        n = len(trajectory)
        self.trajectory = trajectory
        self.vel_m_s = np.asarray(vel_m_s, dtype=np.float64).reshape(n, 3)
        self.gyro_bias_rad_s = np.asarray(gyro_bias_rad_s, dtype=np.float64).reshape(n, 3)
        self.accel_bias_m_s2 = np.asarray(accel_bias_m_s2, dtype=np.float64).reshape(n, 3)

    def __len__(self) -> int:
        return len(self.trajectory)

    def __repr__(self) -> str:
        return f"AslGroundTruth({len(self)} states)"


def write_asl_groundtruth(path: str | os.PathLike[str], gt: AslGroundTruth) -> None:
    """Write ``state_groundtruth_estimate0/data.csv`` (17 columns, quaternion w first)."""
    tr = gt.trajectory
    q = tr.quat_xyzw
    vals = np.concatenate((tr.pos_m, q[:, 3:4], q[:, :3], gt.vel_m_s, gt.gyro_bias_rad_s,
                           gt.accel_bias_m_s2), axis=1)
    with atomic_write(path, "wb") as f:
        f.write((ASL_GROUNDTRUTH_HEADER + "\n").encode())
        write_table(f, tr.stamps_ns, vals, stamp="ns", sep=",")


def read_asl_groundtruth(path: str | os.PathLike[str]) -> AslGroundTruth:
    """Read ``state_groundtruth_estimate0/data.csv`` (17 columns)."""
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=17, ncols_min=17, ncols_max=17,
                     expected="17 columns (timestamp, p, q w x y z, v, b_w, b_a)")
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    v = tb.values
    traj = finish_trajectory(path, stamps, v[:, 1:4], v[:, [5, 6, 7, 4]], tb.finite, tb.lines,
                             Path(path).name)
    keep = np.isin(stamps, traj.stamps_ns)
    return AslGroundTruth(traj, v[keep, 8:11], v[keep, 11:14], v[keep, 14:17])


def _matrix(T: npt.ArrayLike) -> dict[str, Any]:
    m = np.asarray(T, dtype=np.float64).reshape(4, 4)
    return {"cols": 4, "rows": 4, "data": [float(x) for x in m.reshape(-1)]}


def write_asl_sensor_yaml(path: str | os.PathLike[str], *, sensor_type: str, comment: str,
                          T_BS: npt.ArrayLike, fields: dict[str, Any]) -> None:
    """Write a ``sensor.yaml`` like EuRoC's (``sensor_type``, ``comment``, ``T_BS`` as
    cols/rows/data, then ``fields`` in order: ``rate_hz``, ``resolution``, ``camera_model``,
    ``intrinsics``, ``distortion_model``, ``distortion_coefficients`` for cameras; noise densities
    for IMUs)."""
    import yaml

    doc: dict[str, Any] = {"sensor_type": sensor_type, "comment": comment, "T_BS": _matrix(T_BS)}
    doc.update(fields)
    with atomic_write(path) as f:
        f.write(f"# {sensor_type} sensor yaml file (EuRoC layout) written by ibiscape-eval\n")
        f.write(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))


def read_asl_sensor_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a ``sensor.yaml`` (plain or OpenCV ``%YAML:1.0``, as the EuRoC download has it) with
    :func:`ibiscape_eval.io.yaml_file.read_yaml`; ``T_BS`` is returned as a (4, 4) array, checked to
    be a rigid transform.

    Raises
    ------
    FormatError
        Not YAML, no ``T_BS``, or a ``T_BS`` that is not ``{cols: 4, rows: 4, data: [16 numbers]}``
        (or an ``!!opencv-matrix``) of a rigid transform, naming the file.
    """
    from ibiscape_eval.core.kalibr import rigid_transform_problem

    p = Path(path)
    doc = read_yaml_mapping(p, what="EuRoC sensor.yaml")
    if "T_BS" not in doc:
        raise FormatError(p, "missing the key T_BS (EuRoC sensor.yaml expected)")
    T = doc["T_BS"]
    try:
        if isinstance(T, np.ndarray):
            M = T.astype(np.float64).reshape(4, 4)
        else:
            M = np.asarray(T["data"], dtype=np.float64).reshape(int(T["rows"]), int(T["cols"]))
            if M.shape != (4, 4):
                raise ValueError
    except (TypeError, KeyError, ValueError, OverflowError, IndexError):
        raise FormatError(p, "T_BS must be {cols: 4, rows: 4, data: [16 numbers]}") from None
    problem = rigid_transform_problem(M)
    if problem:
        raise FormatError(p, f"T_BS: {problem}; fix the calibration file")
    doc = dict(doc)
    doc["T_BS"] = M
    return doc


#: EuRoC / TUM-VI ``distortion_model`` names -> Kalibr's
ASL_DISTORTION_MODELS = {"radial-tangential": "radtan", "radtan": "radtan", "equidistant": "equidistant"}


def read_asl_camera(path: str | os.PathLike[str]) -> tuple[CameraModel, npt.NDArray[np.float64]]:
    """A camera's ``sensor.yaml`` (EuRoC, TUM-VI) as a :class:`CameraModel` and ``T_BS``
    (``T_body_cam``, 4x4).

    Raises
    ------
    FormatError
        Not a camera ``sensor.yaml`` (no ``intrinsics`` / ``resolution``), an unknown
        ``distortion_model`` (EuRoC's ``radial-tangential`` and ``equidistant`` are read) or bad
        numbers, naming the file and the key.
    """
    doc = read_asl_sensor_yaml(path)
    for key in ("intrinsics", "resolution"):
        if key not in doc:
            raise FormatError(path, f"lacks the key {key!r} (a camera sensor.yaml expected)")
    model = str(doc.get("distortion_model", "radial-tangential"))
    if model not in ASL_DISTORTION_MODELS:
        raise FormatError(path, f"distortion_model {model!r}: use radial-tangential or equidistant")
    coeffs = doc.get("distortion_coefficients", [0.0] * 4)
    if isinstance(coeffs, list) and len(coeffs) == 5 and coeffs[4] == 0:
        coeffs = coeffs[:4]  # OpenCV's k3 = 0
    entry = {"camera_model": doc.get("camera_model", "pinhole"), "intrinsics": doc["intrinsics"],
             "resolution": doc["resolution"], "distortion_model": ASL_DISTORTION_MODELS[model],
             "distortion_coeffs": coeffs}
    try:
        cam = CameraModel.from_kalibr(entry)
    except IbiscapeError as e:
        raise FormatError(path, str(e)) from None
    except OverflowError:
        raise FormatError(path, "intrinsics and resolution must be finite numbers") from None
    return cam, doc["T_BS"]
