"""Camera streams and camera calibration files read by the stereo-VIO baseline.

- Frame lists: IBISCape ``<camera>/timestamps.csv`` and EuRoC ``mav0/cam0/data.csv`` share the
  layout ``#timestamp [ns],filename`` (:func:`read_frame_list`); stamps must increase strictly.
- IMU samples with their stamps (:func:`read_imu_samples`): the EuRoC/IBISCape csv, converted
  from CARLA's left-handed frame for ``fmt="ibiscape"``.
- Images: :func:`read_gray_image` (8-bit grey, any format OpenCV reads; colour is converted).

Kalibr's camchain is read by :func:`ibiscape_eval.io.kalibr.read_camchain` and EuRoC's
``sensor.yaml`` by :func:`ibiscape_eval.io.asl.read_asl_sensor_yaml`.  Every reader raises
:class:`FormatError` naming the file (and line).
"""

from __future__ import annotations

import os

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError

from .framelists import ns_number, read_stamped_rows
from .paths import check_input

__all__ = ["read_frame_list", "read_gray_image", "read_imu_samples"]


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

    from .images import read_grey

    img = read_grey(path, missing="image file is missing; check the frame list",
                    unreadable="not an image OpenCV can read")
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    return np.asarray(img, dtype=np.uint8)
