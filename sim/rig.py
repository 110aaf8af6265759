"""Sensor rig: extrinsics of every sensor in the body (IMU0) frame and the housing check.

Body frame: x forward, y left, z up (IMU0).  Camera frames are OpenCV's: z along the optical axis
(body +x for the default mount), x right (body -y), y down (body -z), so the forward mount is::

    R_body_cam0 = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]

and a camera's ``rpy_deg`` (roll, pitch, yaw about body x, y, z, applied ZYX) rotates that mount:
``R_body_cam = Rz(yaw) Ry(pitch) Rx(roll) R_body_cam0``.  IMUs: ``R_body_imu = Rz Ry Rx``.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

if TYPE_CHECKING:
    from .config import CameraSpec, ImuSpec, SimConfig

__all__ = ["R_BODY_CAM_FORWARD", "T_body_camera", "T_body_imu", "check_housings", "rotation_rpy"]

FloatArray = npt.NDArray[np.float64]

#: OpenCV camera looking along body +x: columns are the camera's x (right), y (down), z (forward).
R_BODY_CAM_FORWARD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def rotation_rpy(rpy_deg: tuple[float, float, float]) -> FloatArray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` from roll, pitch, yaw in degrees, shape (3, 3)."""
    r, p, y = (math.radians(v) for v in rpy_deg)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _T(R: FloatArray, t: tuple[float, float, float]) -> FloatArray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def T_body_camera(cam: CameraSpec) -> FloatArray:
    """4x4 pose of the camera (OpenCV frame) in the body frame."""
    return _T(rotation_rpy(cam.rpy_deg) @ R_BODY_CAM_FORWARD, cam.position_m)


def T_body_imu(imu: ImuSpec) -> FloatArray:
    """4x4 pose of the IMU frame in the body frame."""
    return _T(rotation_rpy(imu.rpy_deg), imu.position_m)


def check_housings(cfg: SimConfig) -> None:
    """Refuse sensors mounted inside each other.

    Two sensors closer than ``cfg.housing_m`` must share a non-empty ``mount`` name (a deliberate
    common housing: the concentric RGB-D pair, an IMU inside a DVS camera).  IMU0 and the GNSS
    antenna are checked too.

    Raises
    ------
    IbiscapeError
        Naming both sensors, their distance and what to change.
    """
    items: list[tuple[str, tuple[float, float, float], str]] = [
        (f"imus.{s.name}", s.position_m, s.mount) for s in cfg.imus]
    items += [(f"cameras.{c.name}", c.position_m, c.mount) for c in cfg.cameras]
    items.append(("gnss", cfg.gnss.position_m, cfg.gnss.mount))
    for (na, pa, ma), (nb, pb, mb) in itertools.combinations(items, 2):
        d = float(np.linalg.norm(np.subtract(pa, pb)))
        if d < cfg.housing_m and not (ma and ma == mb):
            raise IbiscapeError(
                f"config: sensors {na} and {nb} are mounted inside each other ({d:.3f} m apart, "
                f"housing {cfg.housing_m} m); move one, or give both the same 'mount' if they "
                "deliberately share a housing")
    if cfg.setup == "imu" and cfg.cameras:
        raise IbiscapeError("config: setup imu is a still IMU calibration without cameras")
    if not any(s.name == "imu0" for s in cfg.imus):
        raise IbiscapeError("config: an IMU named imu0 (the body origin of the ground truth) is needed")
