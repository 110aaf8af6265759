"""An analytic test motion (helix-like path, sinusoidal roll/pitch, turning yaw) with exact
derivatives, independent of the world/motion planner: used by the sensor and generator tests."""

from __future__ import annotations

import numpy as np

from ibiscape_eval.core.rotations import matrix_from_quat, quat_from_matrix
from ibiscape_eval.sim.types import Controls, MotionState

START_NS = 1_000_000_000_000


def _euler(t: np.ndarray):
    roll = 0.05 * np.sin(1.3 * t)
    pitch = 0.04 * np.sin(0.9 * t + 0.3)
    yaw = 0.2 * t + 0.3 * np.sin(0.5 * t)
    d_roll = 0.05 * 1.3 * np.cos(1.3 * t)
    d_pitch = 0.04 * 0.9 * np.cos(0.9 * t + 0.3)
    d_yaw = 0.2 + 0.15 * np.cos(0.5 * t)
    return roll, pitch, yaw, d_roll, d_pitch, d_yaw


def _omega(t: np.ndarray) -> np.ndarray:
    r, p, _, dr, dp, dy = _euler(t)
    return np.stack((dr - dy * np.sin(p), dp * np.cos(r) + dy * np.sin(r) * np.cos(p),
                     -dp * np.sin(r) + dy * np.cos(r) * np.cos(p)), axis=1)


def rot_zyx(roll, pitch, yaw) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    R = np.empty((*roll.shape, 3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def pose_at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (N, 3) and rotation matrices (N, 3, 3) at times t [s]."""
    pos = np.stack((20 * np.sin(0.2 * t), 20 * (1 - np.cos(0.2 * t)), 0.3 * np.sin(0.7 * t)), axis=1)
    r, p, y, *_ = _euler(t)
    return pos, rot_zyx(r, p, y)


class HelixMotion:
    """Exact kinematics of the test path; ``fail_after`` makes ``controls`` raise (for tests of
    partial output)."""

    def __init__(self, duration_s: float = 30.0, start_ns: int = START_NS, fail: bool = False):
        self.start_ns = start_ns
        self.end_ns = start_ns + int(duration_s * 1e9)
        self.fail = fail

    def sample(self, stamps_ns: np.ndarray) -> MotionState:
        st = np.asarray(stamps_ns, dtype=np.int64)
        t = (st - self.start_ns) * 1e-9
        pos, R = pose_at(t)
        vel = np.stack((4 * np.cos(0.2 * t), 4 * np.sin(0.2 * t), 0.21 * np.cos(0.7 * t)), axis=1)
        acc = np.stack((-0.8 * np.sin(0.2 * t), 0.8 * np.cos(0.2 * t), -0.147 * np.sin(0.7 * t)),
                       axis=1)
        h = 1e-4
        dw = (_omega(t + h) - _omega(t - h)) / (2 * h)
        return MotionState(st, pos, quat_from_matrix(R), vel, acc, _omega(t), dw)

    def controls(self, stamps_ns: np.ndarray) -> Controls:
        if self.fail:
            raise RuntimeError("planned failure in the middle of the generation")
        n = len(stamps_ns)
        return Controls(np.asarray(stamps_ns, dtype=np.int64), np.full(n, 0.3), np.full(n, -0.1),
                        np.zeros(n))


def integrate_imu(t_s: np.ndarray, gyro: np.ndarray, acc: np.ndarray, p0, v0, R0):
    """RK4 on (R, v, p) with the samples interpolated by 4-point cubics at the half steps."""
    def mid(x: np.ndarray) -> np.ndarray:
        xp = np.concatenate((2 * x[:1] - x[1:2], x, 2 * x[-1:] - x[-2:-1]))
        return (-xp[:-3] + 9 * xp[1:-2] + 9 * xp[2:-1] - xp[3:]) / 16

    gm, am = mid(gyro), mid(acc)
    q = quat_from_matrix(R0[None])[0]
    p, v = p0.copy(), v0.copy()

    def qdot(qq, w):
        x, y, z, s = qq
        wx, wy, wz = w
        return 0.5 * np.array([s * wx + y * wz - z * wy, s * wy + z * wx - x * wz,
                               s * wz + x * wy - y * wx, -x * wx - y * wy - z * wz])

    def f(qq, vv, w, a):
        R = matrix_from_quat(qq[None] / np.linalg.norm(qq))[0]
        return qdot(qq, w), R @ a + np.array([0.0, 0.0, -9.81]), vv

    for k in range(len(t_s) - 1):
        h = t_s[k + 1] - t_s[k]
        k1 = f(q, v, gyro[k], acc[k])
        k2 = f(q + h / 2 * k1[0], v + h / 2 * k1[1], gm[k], am[k])
        k3 = f(q + h / 2 * k2[0], v + h / 2 * k2[1], gm[k], am[k])
        k4 = f(q + h * k3[0], v + h * k3[1], gyro[k + 1], acc[k + 1])
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        q /= np.linalg.norm(q)
        p = p + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
        v = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return p, matrix_from_quat(q[None])[0]
