"""The truth of a camera-IMU calibration drive from the simulator: IMU samples, camera frame stamps
with a clock offset per camera, the exact motion and the target (no rendering, no calibration code).

``simulate_calibration(cfg, timeshifts_s={"rgbL": 0.012})`` plans the calibration world and motion
of ``cfg`` (``kind: calibration``), simulates IMU0 with ``cfg.imu_noise`` and stamps the frames of
every camera of ``cfg`` on its own clock (``t_imu = t_cam + timeshift``, Kalibr's
``timeshift_cam_imu``).  The corner observations are made on the calibration side
(``calib.imu_camera.synthetic.calibration_scene``): the simulator sits below the domain packages
and does not import them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

from .config import SimConfig
from .imu import noise_parameters, simulate_imu, sub_seed
from .rig import T_body_camera, T_body_imu
from .still import n_samples, uniform_stamps
from .types import GRAVITY_M_S2

__all__ = ["SimulatedCalibration", "SimulatedCamera", "simulate_calibration"]

FloatArray = npt.NDArray[np.float64]
PoseAt = Callable[[npt.NDArray[np.int64]], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True, eq=False)
class SimulatedCamera:
    """One camera of the drive: model, mounting, frame stamps on its own clock and its clock offset."""

    name: str
    model: CameraModel
    T_body_cam: FloatArray
    stamps_ns: npt.NDArray[np.int64]
    timeshift_cam_imu_s: float
    seed: int

    def __repr__(self) -> str:
        return (f"SimulatedCamera({self.name}, {self.model.width_px}x{self.model.height_px}, "
                f"{self.stamps_ns.size} frames, shift {self.timeshift_cam_imu_s:+.4f} s)")


@dataclass(frozen=True, eq=False)
class SimulatedCalibration:
    """IMU measurements, noise densities (Kalibr's continuous-time convention), cameras, the exact
    ``T_world_body`` as ``pose_at(stamps_ns) -> (pos_m, quat_xyzw)`` and the target, plus the truth."""

    imu_name: str
    imu_stamps_ns: npt.NDArray[np.int64]
    gyro_rad_s: FloatArray
    accel_m_s2: FloatArray
    imu_rate_hz: float
    gyro_noise_density_rad_s_sqrt_hz: float
    accel_noise_density_m_s2_sqrt_hz: float
    gyro_random_walk_rad_s2_sqrt_hz: float
    accel_random_walk_m_s3_sqrt_hz: float
    cameras: tuple[SimulatedCamera, ...]
    pose_at: PoseAt
    target_type: str
    T_world_target: FloatArray
    corners_target_m: FloatArray
    spacing_m: float
    T_cam_imu: dict[str, FloatArray]
    timeshift_cam_imu_s: dict[str, float]
    gravity_target_m_s2: FloatArray
    target: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"SimulatedCalibration({self.target_type}, {self.imu_stamps_ns.size} IMU samples, "
                f"cameras {[c.name for c in self.cameras]})")


def simulate_calibration(cfg: SimConfig, *, timeshifts_s: dict[str, float] | None = None,
                         imu_name: str = "imu0") -> SimulatedCalibration:
    """Simulate IMU ``imu_name`` and stamp the frames of every camera of ``cfg``.

    Camera frames are stamped on each camera's clock at ``rate_hz`` from ``start_ns + 50 ms`` (so
    that shifted frames stay inside the motion for offsets up to +-50 ms).
    """
    from .generate import plan

    if cfg.kind != "calibration":
        raise IbiscapeError("simulate_calibration needs a config of kind 'calibration'")
    shifts = dict(timeshifts_s or {})
    unknown = set(shifts) - {c.name for c in cfg.cameras}
    if unknown:
        raise IbiscapeError(f"timeshifts for unknown cameras {sorted(unknown)}")
    world, motion, _ = plan(cfg)
    target = next(t for t in world.targets if t.target_type == cfg.target)
    spec = next(s for s in cfg.imus if s.name == imu_name)
    T_b_imu = T_body_imu(spec)
    n = n_samples(cfg.duration_s, spec.rate_hz)
    state = motion.sample(uniform_stamps(cfg.start_ns, spec.rate_hz, 0, n))
    m = simulate_imu(state, T_b_imu, cfg.imu_noise, rate_hz=spec.rate_hz,
                     seed=sub_seed(cfg.seed, "imu", 0), ideal=cfg.ideal, name=spec.name)
    p = noise_parameters(cfg.imu_noise, spec.rate_hz)

    def pose_at(st: npt.NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        s = motion.sample(st)
        return s.pos_m, s.quat_xyzw

    spacing = float(target.kalibr.get("colSpacingMeters", target.kalibr.get("tagSize", 0.5)))
    cams, T_ci, shift_out = [], {}, {}
    for k, cam in enumerate(cfg.cameras):
        model = CameraModel.from_fov(cam.width_px, cam.height_px, cam.fov_deg)
        # a CameraSpec.timeshift_cam_imu_s field (the simulator's camera clock offset) is the default
        shift = float(shifts.get(cam.name, getattr(cam, "timeshift_cam_imu_s", 0.0)))
        if abs(shift) > 0.05:
            raise IbiscapeError(f"timeshift {shift} s of {cam.name}: keep it within +-50 ms")
        period_ns = round(1e9 / cam.rate_hz)
        first = motion.start_ns + 50_000_000
        nf = int((motion.end_ns - 50_000_000 - first) // period_ns) + 1
        stamps = first + period_ns * np.arange(nf, dtype=np.int64)
        T_bc = T_body_camera(cam)
        cams.append(SimulatedCamera(cam.name, model, T_bc, stamps, shift,
                                    sub_seed(cfg.seed, "corners", k)))
        T_ci[cam.name] = np.linalg.inv(T_bc) @ T_b_imu
        shift_out[cam.name] = shift
    g_target = target.T_world_target[:3, :3].T @ GRAVITY_M_S2
    return SimulatedCalibration(
        spec.name, m.stamps_ns, m.gyro_rad_s, m.accel_m_s2, float(spec.rate_hz),
        float(p.noise_density[0]), float(p.noise_density[3]),
        float(p.random_walk[0]), float(p.random_walk[3]),
        tuple(cams), pose_at, target.target_type, np.asarray(target.T_world_target, float),
        target.corners_target_m.copy(), spacing, T_ci, shift_out, g_target, target.to_dict())
