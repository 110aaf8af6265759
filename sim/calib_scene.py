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

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
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

__all__ = ["SimulatedCalibration", "SimulatedCamera", "simulate_calibration", "write_board_frames"]

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
    from .generator import plan

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


def write_board_frames(cfg: SimConfig, folder: str | os.PathLike[str], *, supersample: int = 3,
                       background: int = 110) -> dict[str, int]:
    """Board-only camera frames of a generated calibration sequence (a fast stand-in for rendering
    when only the target matters: tests, README examples).

    For every camera of ``cfg`` (``kind: calibration``, generated into ``folder`` with
    ``render=False``), the frame stamped ``t_cam`` shows the target's printed texture warped by the
    exact homography of the camera pose at ``t_cam + timeshift_cam_imu_s`` (Kalibr's convention)
    onto a plain grey background, drawn ``supersample`` times larger and averaged down
    (antialiased); ``<camera>/frames/<ns>.png`` and ``timestamps.csv`` as the renderer writes them.
    Distortion is not drawn (pinhole cameras only).  Returns camera name -> frames written.
    """
    import cv2

    from ibiscape_eval.core.rotations import matrix_from_quat
    from ibiscape_eval.io.images import write_frame_timestamps, write_png

    from .generator import plan
    from .render.rays import camera_model
    from .render.sequence import camera_stamps

    if cfg.kind != "calibration":
        raise IbiscapeError("write_board_frames needs a config of kind 'calibration'")
    if any(c.distortion_model != "none" for c in cfg.cameras):
        raise IbiscapeError("write_board_frames draws pinhole cameras only (distortion_model: none)")
    ss = int(supersample)
    world, motion, _ = plan(cfg)
    tgt = world.target_named(cfg.target)
    ppm = 200.0
    tex = tgt.texture(ppm)
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    uv = tgt.texture_px_from_target(xy, ppm)
    A = np.linalg.solve(np.c_[uv, np.ones(3)], np.c_[xy, np.ones(3)]).T  # (x, y, 1) = A (u, v, 1)
    # pixel centres at integers: pixel p of the ss-times larger image is ss (p + 0.5) - 0.5
    S = np.array([[ss, 0.0, 0.5 * (ss - 1)], [0.0, ss, 0.5 * (ss - 1)], [0.0, 0.0, 1.0]])
    out: dict[str, int] = {}
    root = Path(folder)
    for cam in cfg.cameras:
        K = camera_model(cam).K
        st = camera_stamps(cfg, cam)
        s = motion.sample(st + round(cam.timeshift_cam_imu_s * 1e9))
        T_wb = np.tile(np.eye(4), (st.size, 1, 1))
        T_wb[:, :3, :3] = matrix_from_quat(s.quat_xyzw)
        T_wb[:, :3, 3] = s.pos_m
        T_ct = np.linalg.inv(T_wb @ T_body_camera(cam)) @ tgt.T_world_target
        depth = np.einsum("nj,mj->nm", T_ct[:, 2, :3], tgt.corners_target_m) + T_ct[:, 2, 3, None]
        (root / cam.name / "frames").mkdir(parents=True, exist_ok=True)
        for k, t in enumerate(st.tolist()):
            big = np.full((ss * cam.height_px, ss * cam.width_px), background, np.uint8)
            if depth[k].min() > 1.0:
                H = S @ K @ np.c_[T_ct[k, :3, :2], T_ct[k, :3, 3]] @ A
                cv2.warpPerspective(tex, H, big.shape[::-1], dst=big, flags=cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_TRANSPARENT)
            img = cv2.resize(big, (cam.width_px, cam.height_px), interpolation=cv2.INTER_AREA)
            write_png(root / cam.name / "frames" / f"{t}.png", img)
        write_frame_timestamps(root / cam.name / "timestamps.csv", st)
        out[cam.name] = int(st.size)
    return out
