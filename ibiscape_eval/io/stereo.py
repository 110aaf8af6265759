"""Camera streams and camera calibration files read by the stereo-VIO baseline.

- Frame lists: IBISCape ``<camera>/timestamps.csv`` and EuRoC ``mav0/cam0/data.csv`` share the
  layout ``#timestamp [ns],filename`` (:func:`read_frame_list`); stamps must increase strictly.
- IMU samples with their stamps (:func:`read_imu_samples`): the EuRoC/IBISCape csv, converted
  from CARLA's left-handed frame for ``fmt="ibiscape"``.
- Images: :func:`read_gray_image` (8-bit grey, any format OpenCV reads; colour is converted).
- Kalibr ``camchain-imucam.yaml`` (:func:`read_kalibr_camchain`): ``cam0``, ``cam1``, ... with
  intrinsics, distortion, resolution, ``T_cam_imu`` and ``T_cn_cnm1``.
- EuRoC ``sensor.yaml`` (:func:`read_euroc_sensor_yaml`): ``T_BS`` as ``{rows, cols, data}``,
  camera intrinsics or IMU noise densities.

Every reader uses ``yaml.safe_load`` and raises :class:`FormatError` naming the file (and line).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError

from .framelists import ns_number, read_stamped_rows
from .paths import check_input, safe_yaml

__all__ = ["read_euroc_sensor_yaml", "read_frame_list", "read_gray_image", "read_imu_samples",
           "read_kalibr_camchain", "rigid_transform_problem"]


def read_frame_list(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[str]]:
    """Read ``#timestamp [ns],filename`` rows.

    Returns
    -------
    stamps_ns : ndarray, shape (N,), int64
    names : list of str
        File names relative to the folder of the images (``frames/`` or ``data/``).

    Raises
    ------
    FormatError
        A row without two fields, a stamp that is not an integer, stamps that do not increase
        strictly, or no rows at all (naming the line).
    """
    stamps, rows = read_stamped_rows(
        path, expected="'<timestamp [ns]>,<filename>'", ncols=(2, 1 << 30), required=(1,),
        parse=ns_number, bad_stamp="is not an integer (ns)", increasing=True,
        nonempty="no frames listed", errors="replace")
    return stamps, [r[1] for r in rows]


def read_imu_samples(path: str | os.PathLike[str], *, fmt: str = "euroc"
                     ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Timestamped IMU samples of an EuRoC/IBISCape csv (``#timestamp [ns], w_xyz, a_xyz``).

    Parameters
    ----------
    fmt : {"euroc", "ibiscape"}
        ``"ibiscape"``: CARLA's left-handed frame, converted to ours
        (:func:`ibiscape_eval.io.imu.mirror_ibiscape_imu`).

    Returns
    -------
    stamps_ns (N,) int64, gyro_rad_s (N, 3), accel_m_s2 (N, 3)

    Raises
    ------
    FormatError
        Fewer than 7 columns, non-numeric values, stamps that do not increase strictly (naming
        the line), fewer than 2 samples.
    """
    import pandas as pd

    from .imu import mirror_ibiscape_imu

    check_input(path, what="IMU csv")
    try:
        df = pd.read_csv(path, header=None, comment="#", skip_blank_lines=True,
                         dtype=str, engine="c")
    except pd.errors.EmptyDataError:
        raise FormatError(path, "no IMU samples") from None
    except UnicodeDecodeError:
        raise FormatError(path, "not UTF-8 text; save the file as UTF-8") from None
    except pd.errors.ParserError as e:
        raise FormatError(path, f"not a 7-column IMU csv ({' '.join(str(e).split())[:200]})") from None
    if df.shape[1] < 7:
        raise FormatError(path, f"expected 7 columns (t [ns], w_x, w_y, w_z, a_x, a_y, a_z), "
                          f"got {df.shape[1]}")
    first = _first_data_line(path)
    try:
        stamps = df.iloc[:, 0].str.strip().astype(np.int64).to_numpy()
    except ValueError:
        bad = int(np.flatnonzero(~df.iloc[:, 0].str.strip().str.fullmatch(r"\d+"))[0])
        raise FormatError(path, "timestamp is not an integer (ns)", line=first + bad) from None
    vals = df.iloc[:, 1:7].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=np.float64)
    if not np.isfinite(vals).all():
        bad = int(np.flatnonzero(~np.isfinite(vals).all(axis=1))[0])
        raise FormatError(path, "non-numeric IMU value", line=first + bad)
    if len(stamps) < 2:
        raise FormatError(path, "fewer than 2 IMU samples")
    dec = np.flatnonzero(np.diff(stamps) <= 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise FormatError(path, f"timestamps must increase strictly: {stamps[i]} ns follows "
                          f"{stamps[i - 1]} ns", line=first + i)
    gyro, acc = vals[:, :3], vals[:, 3:]
    if fmt == "ibiscape":
        gyro, acc = mirror_ibiscape_imu(gyro, acc)
    return (np.asarray(stamps, dtype=np.int64), np.ascontiguousarray(gyro, dtype=np.float64),
            np.ascontiguousarray(acc, dtype=np.float64))


def _first_data_line(path: str | os.PathLike[str]) -> int:
    with open(path, encoding="utf-8", errors="replace") as fh:
        for no, line in enumerate(fh, start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                return no
    return 1


def read_gray_image(path: str | os.PathLike[str]) -> npt.NDArray[np.uint8]:
    """An 8-bit grey image ``(H, W)`` (colour images are converted with OpenCV's weights)."""
    import cv2

    from .images import imread_checked

    img = imread_checked(path, cv2.IMREAD_GRAYSCALE,
                         missing="image file is missing; check the frame list",
                         unreadable="not an image OpenCV can read")
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    return np.asarray(img, dtype=np.uint8)


def _yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    doc = safe_yaml(path)
    if not isinstance(doc, dict):
        raise FormatError(path, "expected a mapping at the top level")
    return doc


def _matrix(path: str | os.PathLike[str], value: Any, key: str) -> npt.NDArray[np.float64]:
    if isinstance(value, dict) and "data" in value:  # EuRoC / OpenCV {rows, cols, data}
        value = np.asarray(value["data"], dtype=object).reshape(-1)
    try:
        T = np.asarray(value, dtype=np.float64).reshape(4, 4)
    except (TypeError, ValueError):
        raise FormatError(path, f"{key} must be a 4x4 matrix (16 numbers)") from None
    if not np.isfinite(T).all() or not np.allclose(T[3], [0, 0, 0, 1]):
        raise FormatError(path, f"{key} must be a finite homogeneous 4x4 matrix")
    problem = rigid_transform_problem(T)
    if problem:
        raise FormatError(path, f"{key}: {problem}; fix the calibration file")
    return T


#: the largest lever arm [m] accepted between two sensors of one rig
MAX_LEVER_ARM_M = 1000.0


def rigid_transform_problem(T: npt.NDArray[np.float64]) -> str | None:
    """What is wrong with a 4x4 rigid transform (None if it is one): finite, last row
    ``0 0 0 1``, an orthonormal rotation with determinant +1 (to 1e-5) and a translation shorter
    than :data:`MAX_LEVER_ARM_M`."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all() or not np.allclose(T[3], [0, 0, 0, 1]):
        return "must be a finite homogeneous 4x4 matrix (last row 0 0 0 1)"
    R, t = T[:3, :3], T[:3, 3]
    if np.abs(R).max() > 1.0 + 1e-5:  # also keeps R @ R.T below from overflowing
        return "the rotation part is not a rotation matrix (orthonormal, determinant +1)"
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        return "the rotation part is not a rotation matrix (orthonormal, determinant +1)"
    if np.abs(t).max() > MAX_LEVER_ARM_M:  # the max norm: no overflow on huge entries
        return (f"translation ({', '.join(f'{v:.3g}' for v in t)}) m reaches beyond "
                f"{MAX_LEVER_ARM_M:g} m")
    return None


def read_kalibr_camchain(path: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """Read a Kalibr ``camchain(-imucam).yaml``: ``{"cam0": {...}, "cam1": {...}}`` with the
    4x4 transforms (``T_cam_imu``, ``T_cn_cnm1``) as arrays."""
    doc = _yaml(path)
    cams = {k: v for k, v in doc.items() if str(k).startswith("cam") and isinstance(v, dict)}
    if not cams:
        raise FormatError(path, "no cam0/cam1 entries (Kalibr camchain format expected)")
    out: dict[str, dict[str, Any]] = {}
    for name in sorted(cams):
        entry = dict(cams[name])
        for key in ("intrinsics", "resolution"):
            if key not in entry:
                raise FormatError(path, f"{name} lacks the key {key!r}")
        for key in ("T_cam_imu", "T_cn_cnm1"):
            if key in entry:
                entry[key] = _matrix(path, entry[key], f"{name}.{key}")
        out[str(name)] = entry
    return out


def read_euroc_sensor_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read an EuRoC ``sensor.yaml`` (``T_BS`` becomes a 4x4 array)."""
    doc = _yaml(path)
    if "T_BS" not in doc:
        raise FormatError(path, "missing the key T_BS (EuRoC sensor.yaml expected)")
    doc = dict(doc)
    doc["T_BS"] = _matrix(path, doc["T_BS"], "T_BS")
    return doc
