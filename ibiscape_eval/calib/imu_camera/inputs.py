"""Inputs of the camera-IMU calibration: target corner observations and IMU samples (the IMU noise
is :class:`ibiscape_eval.core.kalibr.ImuNoise`).

The estimator depends on nothing but these types, so detections from images, from event frames or
from the simulator's exact projection (:mod:`.synthetic`) all enter the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["CameraObservations", "ImuData"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class CameraObservations:
    """Target corners seen by one camera, flattened over frames.

    Attributes
    ----------
    name : str
        Camera name (``rgbL``, ``cam0`` ...).
    camera : CameraModel or None
        Intrinsics and distortion; ``None`` when unknown (refused by the calibration).
    stamps_ns : ndarray, shape (F,), int64
        Frame stamps on the camera's clock, increasing.
    frame_index : ndarray, shape (K,), int64
        Frame (row of ``stamps_ns``) of every observed corner.
    corner_ids : ndarray, shape (K,), int64
        Corner id in the target's numbering (row of ``corners_target_m``).
    pixels_px : ndarray, shape (K, 2)
        Observed pixel coordinates (OpenCV convention: pixel centres at integers).
    """

    name: str
    camera: CameraModel | None
    stamps_ns: IntArray
    frame_index: IntArray
    corner_ids: IntArray
    pixels_px: FloatArray

    def __post_init__(self) -> None:
        st = np.asarray(self.stamps_ns)
        if st.ndim != 1 or not np.issubdtype(st.dtype, np.integer):
            raise IbiscapeError(f"camera {self.name}: stamps_ns must be a 1-D integer array of ns")
        if st.size > 1 and np.any(np.diff(st) <= 0):
            raise IbiscapeError(f"camera {self.name}: frame stamps are not strictly increasing")
        fi = np.asarray(self.frame_index, dtype=np.int64)
        ids = np.asarray(self.corner_ids, dtype=np.int64)
        px = np.asarray(self.pixels_px, dtype=np.float64).reshape(-1, 2)
        if not (fi.shape == ids.shape == (px.shape[0],)):
            raise IbiscapeError(
                f"camera {self.name}: frame_index {fi.shape}, corner_ids {ids.shape} and pixels_px "
                f"{px.shape} must have one row per observed corner")
        if fi.size and (fi.min() < 0 or fi.max() >= st.size):
            raise IbiscapeError(f"camera {self.name}: frame_index outside 0..{st.size - 1}")
        if not np.all(np.isfinite(px)):
            raise IbiscapeError(f"camera {self.name}: pixel coordinates must be finite")
        object.__setattr__(self, "stamps_ns", st.astype(np.int64))
        object.__setattr__(self, "frame_index", fi)
        object.__setattr__(self, "corner_ids", ids)
        object.__setattr__(self, "pixels_px", px)

    @classmethod
    def from_frames(cls, name: str, camera: CameraModel | None, stamps_ns: npt.ArrayLike,
                    frames: Sequence[tuple[npt.ArrayLike, npt.ArrayLike] | None]) -> CameraObservations:
        """Build from one ``(corner_ids (k,), pixels_px (k, 2))`` pair per frame (``None``: no target)."""
        st = np.asarray(stamps_ns, dtype=np.int64)
        if len(frames) != st.size:
            raise IbiscapeError(f"camera {name}: {len(frames)} detections for {st.size} stamps")
        fi, ids, px = [], [], []
        for k, fr in enumerate(frames):
            if fr is None:
                continue
            i = np.asarray(fr[0], dtype=np.int64).ravel()
            fi.append(np.full(i.size, k, dtype=np.int64))
            ids.append(i)
            px.append(np.asarray(fr[1], dtype=np.float64).reshape(-1, 2))
        if not fi:
            return cls(name, camera, st, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)))
        return cls(name, camera, st, np.concatenate(fi), np.concatenate(ids), np.concatenate(px))

    @property
    def n_frames_with_target(self) -> int:
        return int(np.unique(self.frame_index).size)

    def __repr__(self) -> str:
        return (f"CameraObservations({self.name}: {self.stamps_ns.size} frames, "
                f"{self.n_frames_with_target} with the target, {self.corner_ids.size} corners)")


@dataclass(frozen=True, eq=False)
class ImuData:
    """IMU samples in the IMU's (right-handed) frame.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
    gyro_rad_s : ndarray, shape (N, 3)
    accel_m_s2 : ndarray, shape (N, 3)
        Specific force.
    """

    stamps_ns: IntArray
    gyro_rad_s: FloatArray
    accel_m_s2: FloatArray

    def __post_init__(self) -> None:
        st = np.asarray(self.stamps_ns)
        g = np.asarray(self.gyro_rad_s, dtype=np.float64)
        a = np.asarray(self.accel_m_s2, dtype=np.float64)
        if st.ndim != 1 or g.shape != (st.size, 3) or a.shape != (st.size, 3):
            raise IbiscapeError(f"IMU: expected (N,) stamps and (N, 3) gyro/accel, got {st.shape}, "
                                f"{g.shape}, {a.shape}")
        if st.size < 2 or np.any(np.diff(st) <= 0):
            raise IbiscapeError("IMU: need at least two samples with strictly increasing stamps")
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(a))):
            raise IbiscapeError("IMU: samples must be finite")
        object.__setattr__(self, "stamps_ns", st.astype(np.int64))
        object.__setattr__(self, "gyro_rad_s", g)
        object.__setattr__(self, "accel_m_s2", a)

    @property
    def rate_hz(self) -> float:
        """From the median interval."""
        return float(1e9 / np.median(np.diff(self.stamps_ns)))

    def __len__(self) -> int:
        return int(self.stamps_ns.size)

    def __repr__(self) -> str:
        return f"ImuData({len(self)} samples, {self.rate_hz:.1f} Hz)"
