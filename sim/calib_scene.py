"""A camera-IMU calibration scene from the simulator: IMU samples and target corner observations
with a camera clock offset per camera, plus the exact answer (no rendering).

``calibration_scene(cfg, timeshifts_s={"rgbL": 0.012})`` plans the calibration world and motion of
``cfg`` (``kind: calibration``), simulates IMU0 with ``cfg.imu_noise``, and projects the target's
corners into every camera of ``cfg`` at its frame stamps shifted by the camera's clock offset
(``t_imu = t_cam + timeshift``, Kalibr's ``timeshift_cam_imu``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.calib.imu_camera import (
    CameraObservations,
    ImuData,
    ImuNoiseDensities,
    observe_target,
)
from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

from .config import SimConfig
from .imu import noise_parameters, simulate_imu, sub_seed
from .rig import T_body_camera, T_body_imu
from .still import n_samples, uniform_stamps
from .types import GRAVITY_M_S2

__all__ = ["CalibrationScene", "calibration_scene"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class CalibrationScene:
    """Inputs of :func:`ibiscape_eval.calib.imu_camera.calibrate_imu_camera` and the truth."""

    observations: tuple[CameraObservations, ...]
    imu: ImuData
    noise: ImuNoiseDensities
    corners_target_m: FloatArray
    T_cam_imu: dict[str, FloatArray]
    timeshift_cam_imu_s: dict[str, float]
    gravity_target_m_s2: FloatArray
    target: dict[str, Any] = field(default_factory=dict)


def calibration_scene(cfg: SimConfig, *, timeshifts_s: dict[str, float] | None = None,
                      noise_px: float = 0.2, min_spacing_px: float = 6.0,
                      imu_name: str = "imu0") -> CalibrationScene:
    """Simulate IMU ``imu_name`` and the target corners seen by every camera of ``cfg``.

    Camera frames are stamped on each camera's clock at ``rate_hz`` from ``start_ns + 50 ms`` (so
    that shifted frames stay inside the motion for offsets up to +-50 ms).
    """
    from .generate import plan

    if cfg.kind != "calibration":
        raise IbiscapeError("calibration_scene needs a config of kind 'calibration'")
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
    noise = ImuNoiseDensities(max(p.noise_density[0], 1e-6), max(p.noise_density[3], 1e-5),
                              max(p.random_walk[0], 1e-7), max(p.random_walk[3], 1e-6), spec.rate_hz)

    def pose_at(st: npt.NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        s = motion.sample(st)
        return s.pos_m, s.quat_xyzw

    spacing = float(target.kalibr.get("colSpacingMeters", target.kalibr.get("tagSize", 0.5)))
    obs, T_ci, shift_out = [], {}, {}
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
        obs.append(observe_target(cam.name, model, pose_at, T_bc, target.T_world_target,
                                  target.corners_target_m, stamps, timeshift_s=shift,
                                  noise_px=noise_px, seed=sub_seed(cfg.seed, "corners", k),
                                  spacing_m=spacing, min_spacing_px=min_spacing_px,
                                  all_or_none=target.target_type == "checkerboard"))
        T_ci[cam.name] = np.linalg.inv(T_bc) @ T_b_imu
        shift_out[cam.name] = shift
    g_target = target.T_world_target[:3, :3].T @ GRAVITY_M_S2
    imu = ImuData(m.stamps_ns, m.gyro_rad_s, m.accel_m_s2)
    return CalibrationScene(tuple(obs), imu, noise, target.corners_target_m.copy(), T_ci, shift_out,
                            g_target, target.to_dict())
