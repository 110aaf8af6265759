"""IBISCape's IMU frame: CARLA's left-handed sensor frame and the mirror to ours.

See the derivation in :mod:`ibiscape_eval.io.imu`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from ..ibiscape import _S

__all__ = ["IBISCAPE_IMU_SIGNS", "IMU_FRAMES", "check_imu_frame", "mirror_ibiscape_imu"]

#: Per-axis signs (w_x .. a_z) between CARLA's left-handed IMU frame and ours: gyro ``-S``,
#: accel ``S`` with ``S = diag(1, -1, 1)``, i.e. ``(-1, 1, -1, 1, -1, 1)`` (an involution).
IBISCAPE_IMU_SIGNS = np.concatenate((-_S, _S))
IBISCAPE_IMU_SIGNS.flags.writeable = False
#: ``frame`` values of the writers: as given (right-handed) or mirrored to CARLA's frame.
IMU_FRAMES = ("right-handed", "ibiscape")


def mirror_ibiscape_imu(gyro_rad_s: npt.ArrayLike,
                        accel_m_s2: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Convert IMU samples between CARLA's left-handed frame and our right-handed one.

    The map is its own inverse: ``w -> -S w = (-w_x, w_y, -w_z)``, ``a -> S a = (a_x, -a_y,
    a_z)`` with ``S = diag(1, -1, 1)`` (derivation in the module docstring).

    Parameters
    ----------
    gyro_rad_s : array_like, shape (N, 3)
        Angular rate, rad/s.
    accel_m_s2 : array_like, shape (N, 3)
        Specific force, m/s^2.

    Returns
    -------
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        New float64 arrays (the inputs are not modified).
    """
    g = np.asarray(gyro_rad_s, dtype=np.float64)
    a = np.asarray(accel_m_s2, dtype=np.float64)
    return g * IBISCAPE_IMU_SIGNS[:3], a * IBISCAPE_IMU_SIGNS[3:]


def check_imu_frame(frame: str) -> bool:
    """True when ``frame`` asks for CARLA's (IBISCape) frame."""
    if frame not in IMU_FRAMES:
        raise IbiscapeError(f"unknown IMU frame {frame!r}; use one of {', '.join(IMU_FRAMES)}")
    return frame == "ibiscape"
