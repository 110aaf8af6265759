"""Synthetic corner observations: a target projected through an exact trajectory with a camera
clock offset (for known-answer tests, benchmarks and demos without rendering).

``calibration_scene(simulate_calibration(cfg, timeshifts_s=...))`` turns a simulated drive
(:mod:`ibiscape_eval.sim.calib_scene`) into the inputs of :func:`calibrate_imu_camera` and the truth.

The camera stamps a frame ``t_cam``; the image shows the world at ``t_cam + timeshift`` on the
IMU's clock (Kalibr's ``timeshift_cam_imu``).  A corner is kept when it is in front of the camera,
inside the image, and the board is large enough in the image for a detector (``min_spacing_px``
between neighbouring corners, from the farthest corner's depth).  Checkerboards are all-or-nothing like
OpenCV's detector; AprilGrids may be partial.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.core.rotations import matrix_from_quat

from .inputs import CameraObservations, ImuData

__all__ = ["CalibrationScene", "calibration_scene", "observe_target"]

FloatArray = npt.NDArray[np.float64]
PoseAt = Callable[[npt.NDArray[np.int64]], tuple[FloatArray, FloatArray]]


def observe_target(
    name: str,
    camera: CameraModel,
    pose_at: PoseAt,
    T_body_cam: npt.ArrayLike,
    T_world_target: npt.ArrayLike,
    corners_target_m: npt.ArrayLike,
    stamps_ns: npt.ArrayLike,
    *,
    timeshift_s: float = 0.0,
    noise_px: float = 0.2,
    seed: int = 0,
    spacing_m: float = 0.5,
    min_spacing_px: float = 6.0,
    all_or_none: bool = True,
    border_px: float = 2.0,
) -> CameraObservations:
    """Project the target's corners into one camera at its (camera-clock) frame stamps.

    Parameters
    ----------
    pose_at : callable(stamps_ns) -> (pos_m (n, 3), quat_xyzw (n, 4))
        Exact ``T_world_body`` at IMU-clock stamps (e.g. ``motion.sample``).
    T_body_cam : (4, 4)
        Camera (OpenCV frame) in the body frame.
    T_world_target : (4, 4)
    corners_target_m : (M, 3)
    stamps_ns : (F,) int64
        Frame stamps on the camera clock.
    timeshift_s : float
        ``t_imu = t_cam + timeshift_s``.
    noise_px : float
        Standard deviation of the Gaussian corner noise per axis.
    spacing_m, min_spacing_px : float
        Corner spacing on the board and the smallest spacing in the image a detector resolves.
    """
    st = np.asarray(stamps_ns, dtype=np.int64)
    t_true = st + np.int64(round(timeshift_s * 1e9))
    pos, quat = pose_at(t_true)
    R_wb = matrix_from_quat(quat)
    T_bc = np.asarray(T_body_cam, dtype=np.float64)
    T_wt = np.asarray(T_world_target, dtype=np.float64)
    X = np.asarray(corners_target_m, dtype=np.float64) @ T_wt[:3, :3].T + T_wt[:3, 3]
    R_wc = R_wb @ T_bc[:3, :3]
    p_wc = pos + R_wb @ T_bc[:3, 3]
    pc = np.einsum("nji,nmj->nmi", R_wc, X[None] - p_wc[:, None])  # (F, M, 3)
    z = pc[..., 2]
    uv = camera.project(pc)
    with np.errstate(invalid="ignore"):
        inside = ((z > 0.1) & np.all(np.isfinite(uv), axis=-1)
                  & (uv[..., 0] >= border_px) & (uv[..., 0] <= camera.width_px - 1 - border_px)
                  & (uv[..., 1] >= border_px) & (uv[..., 1] <= camera.height_px - 1 - border_px))
    big = camera.fx * spacing_m / np.where(z > 0, z, np.inf).max(axis=1) >= min_spacing_px
    keep = inside & big[:, None]
    if all_or_none:
        keep &= keep.all(axis=1, keepdims=True)
    rng = np.random.default_rng(seed)
    fi, ids = np.nonzero(keep)
    px = uv[fi, ids] + rng.normal(0.0, noise_px, (fi.size, 2))
    return CameraObservations(name, camera, st, fi.astype(np.int64), ids.astype(np.int64), px)


class SimulatedCameraLike(Protocol):
    """One camera of a simulated drive (e.g. :class:`ibiscape_eval.sim.calib_scene.SimulatedCamera`)."""

    @property
    def name(self) -> str: ...
    @property
    def model(self) -> CameraModel: ...
    @property
    def T_body_cam(self) -> FloatArray: ...
    @property
    def stamps_ns(self) -> npt.NDArray[np.int64]: ...
    @property
    def timeshift_cam_imu_s(self) -> float: ...
    @property
    def seed(self) -> int: ...


class SimulatedCalibrationLike(Protocol):
    """What :func:`calibration_scene` reads from a simulated drive (e.g.
    :func:`ibiscape_eval.sim.calib_scene.simulate_calibration`'s result)."""

    @property
    def imu_stamps_ns(self) -> npt.NDArray[np.int64]: ...
    @property
    def gyro_rad_s(self) -> FloatArray: ...
    @property
    def accel_m_s2(self) -> FloatArray: ...
    @property
    def imu_rate_hz(self) -> float: ...
    @property
    def gyro_noise_density_rad_s_sqrt_hz(self) -> float: ...
    @property
    def accel_noise_density_m_s2_sqrt_hz(self) -> float: ...
    @property
    def gyro_random_walk_rad_s2_sqrt_hz(self) -> float: ...
    @property
    def accel_random_walk_m_s3_sqrt_hz(self) -> float: ...
    @property
    def pose_at(self) -> PoseAt: ...
    @property
    def target_type(self) -> str: ...
    @property
    def T_world_target(self) -> FloatArray: ...
    @property
    def corners_target_m(self) -> FloatArray: ...
    @property
    def spacing_m(self) -> float: ...
    @property
    def T_cam_imu(self) -> dict[str, FloatArray]: ...
    @property
    def timeshift_cam_imu_s(self) -> dict[str, float]: ...
    @property
    def gravity_target_m_s2(self) -> FloatArray: ...
    @property
    def target(self) -> dict[str, Any]: ...

    @property
    def cameras(self) -> Sequence[SimulatedCameraLike]: ...


@dataclass(frozen=True, eq=False)
class CalibrationScene:
    """Inputs of :func:`ibiscape_eval.calib.imu_camera.calibrate_imu_camera` and the truth."""

    observations: tuple[CameraObservations, ...]
    imu: ImuData
    noise: ImuNoise
    #: the simulated drive the observations come from: the truth is read from it, not copied
    sim: SimulatedCalibrationLike

    @property
    def corners_target_m(self) -> FloatArray:
        return self.sim.corners_target_m

    @property
    def T_cam_imu(self) -> dict[str, FloatArray]:
        return self.sim.T_cam_imu

    @property
    def timeshift_cam_imu_s(self) -> dict[str, float]:
        return self.sim.timeshift_cam_imu_s

    @property
    def gravity_target_m_s2(self) -> FloatArray:
        return self.sim.gravity_target_m_s2

    @property
    def target(self) -> dict[str, Any]:
        return self.sim.target

    def __repr__(self) -> str:
        return (f"CalibrationScene({len(self.imu)} IMU samples, "
                f"cameras {[o.name for o in self.observations]})")


def calibration_scene(sim: SimulatedCalibrationLike, *, noise_px: float = 0.2,
                      min_spacing_px: float = 6.0) -> CalibrationScene:
    """Corner observations of every camera of a simulated drive (:func:`observe_target`), the IMU
    data and noise densities (floored to small positive values for an ideal IMU) and the truth."""
    obs = tuple(
        observe_target(c.name, c.model, sim.pose_at, c.T_body_cam, sim.T_world_target,
                       sim.corners_target_m, c.stamps_ns, timeshift_s=c.timeshift_cam_imu_s,
                       noise_px=noise_px, seed=c.seed, spacing_m=sim.spacing_m,
                       min_spacing_px=min_spacing_px,
                       all_or_none=sim.target_type == "checkerboard")
        for c in sim.cameras)
    noise = ImuNoise(gyro_noise_density_rad_s_sqrt_hz=max(sim.gyro_noise_density_rad_s_sqrt_hz, 1e-6),
                     accel_noise_density_m_s2_sqrt_hz=max(sim.accel_noise_density_m_s2_sqrt_hz, 1e-5),
                     gyro_random_walk_rad_s2_sqrt_hz=max(sim.gyro_random_walk_rad_s2_sqrt_hz, 1e-7),
                     accel_random_walk_m_s3_sqrt_hz=max(sim.accel_random_walk_m_s3_sqrt_hz, 1e-6),
                     update_rate_hz=sim.imu_rate_hz)
    imu = ImuData(sim.imu_stamps_ns, sim.gyro_rad_s, sim.accel_m_s2)
    return CalibrationScene(obs, imu, noise, sim)
