"""Value types shared by the simulator's parts (world/motion on one side, sensors/writer on the other).

Frames: the world is right-handed, z up, gravity ``(0, 0, -9.81)`` m/s^2; the body frame is the
vehicle's IMU0 frame: x forward, y left, z up.  Files in the IBISCape layout are converted to
CARLA's left-handed frame by ``ibiscape_eval.io`` only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.trajectory import Trajectory

__all__ = ["GRAVITY_M_S2", "Controls", "MotionState"]

GRAVITY_M_S2 = np.array([0.0, 0.0, -9.81])

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class MotionState:
    """Exact kinematics of the body (IMU0) frame at given stamps.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
    pos_m : ndarray, shape (N, 3)
        Body origin in the world frame, metres.
    quat_xyzw : ndarray, shape (N, 4)
        Orientation ``q_world_body`` (x, y, z, w).
    vel_m_s, acc_m_s2 : ndarray, shape (N, 3)
        First and second time derivatives of ``pos_m``, world frame.
    angvel_body_rad_s : ndarray, shape (N, 3)
        Angular velocity of the body relative to the world, in body coordinates (what a gyro reads).
    angacc_body_rad_s2 : ndarray, shape (N, 3)
        Time derivative of ``angvel_body_rad_s`` (for lever-arm accelerations).
    """

    stamps_ns: npt.NDArray[np.int64]
    pos_m: FloatArray
    quat_xyzw: FloatArray
    vel_m_s: FloatArray
    acc_m_s2: FloatArray
    angvel_body_rad_s: FloatArray
    angacc_body_rad_s2: FloatArray

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    def trajectory(self, name: str = "groundtruth") -> Trajectory:
        """The poses as a :class:`Trajectory` (``T_world_body``)."""
        return Trajectory(self.stamps_ns, self.pos_m, self.quat_xyzw, name)


@dataclass(frozen=True, eq=False)
class Controls:
    """Vehicle controls, as CARLA logs them: throttle and brake in [0, 1], steer in [-1, 1]."""

    stamps_ns: npt.NDArray[np.int64]
    throttle: FloatArray
    steer: FloatArray
    brake: FloatArray
