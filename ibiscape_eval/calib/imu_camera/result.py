"""Result types of the camera-IMU calibration: frozen values, ``to_dict()`` in strict JSON and
``from_dict()`` back (``from_dict(r.to_dict()) == r``; equality compares arrays element by element
with NaN equal to NaN; the residual series for the figures is not part of the value)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.numbers import finite_or_none

__all__ = ["CameraImuCalibration", "Excitation", "ImuCameraResult", "ResidualSeries"]

FloatArray = npt.NDArray[np.float64]
AXES = ("x", "y", "z")


def _l(a: Any) -> Any:
    arr = np.asarray(a, dtype=np.float64)
    return [_l(x) for x in arr] if arr.ndim > 0 else finite_or_none(float(arr))


def _a(doc: Any) -> FloatArray:
    """An array back from :func:`_l` (``None`` -> NaN)."""
    return np.asarray(doc, dtype=np.float64)


def _n(v: Any) -> float:
    """A float back from :func:`finite_or_none` (``None`` -> NaN)."""
    return float("nan") if v is None else float(v)


def same(a: Any, b: Any) -> bool:
    """Value equality of results: arrays and floats element by element (NaN equals NaN), lists
    and tuples alike, mappings by key, cameras as their Kalibr entry (no distortion is radtan
    with zero coefficients there), anything else by ``==``."""
    if isinstance(a, CameraModel) and isinstance(b, CameraModel):
        return bool(a.to_kalibr() == b.to_kalibr())
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and bool(np.array_equal(x, y, equal_nan=x.dtype.kind == "f"))
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(a == b)


class ValueEquality:
    """``==`` over the dataclass fields that compare, by :func:`same`."""

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(same(getattr(self, f.name), getattr(other, f.name))
                   for f in fields(self) if f.compare)  # type: ignore[arg-type]

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class CameraImuCalibration(ValueEquality):
    """One camera's extrinsics and time offset relative to the IMU.

    Attributes
    ----------
    name : str
    camera : CameraModel
    T_cam_imu : ndarray (4, 4)
        Maps IMU coordinates to camera coordinates.
    timeshift_cam_imu_s : float
        Kalibr's convention: ``t_imu = t_cam + shift``.
    rotation_std_deg : ndarray (3,)
        Standard deviation of the rotation about the IMU axes (right perturbation of ``R_cam_imu``).
    translation_std_m : ndarray (3,)
        Standard deviation of the translation of ``T_cam_imu`` (camera axes).
    position_std_imu_m : ndarray (3,)
        The same uncertainty as the camera's position along the IMU axes.
    timeshift_std_s : float
    reprojection_rms_px : float
    n_frames, n_corners : int
        Frames and corners used.
    """

    name: str
    camera: CameraModel
    T_cam_imu: FloatArray
    timeshift_cam_imu_s: float
    rotation_std_deg: FloatArray
    translation_std_m: FloatArray
    position_std_imu_m: FloatArray
    timeshift_std_s: float
    reprojection_rms_px: float
    n_frames: int
    n_corners: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "camera": self.camera.to_kalibr(),
            "T_cam_imu": _l(self.T_cam_imu),
            "timeshift_cam_imu_s": finite_or_none(self.timeshift_cam_imu_s),
            "rotation_std_deg": _l(self.rotation_std_deg),
            "translation_std_m": _l(self.translation_std_m),
            "position_std_imu_m": _l(self.position_std_imu_m),
            "timeshift_std_s": finite_or_none(self.timeshift_std_s),
            "reprojection_rms_px": finite_or_none(self.reprojection_rms_px),
            "n_frames": self.n_frames,
            "n_corners": self.n_corners,
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> CameraImuCalibration:
        """The inverse of :meth:`to_dict`."""
        return cls(doc["name"], CameraModel.from_kalibr(doc["camera"]), _a(doc["T_cam_imu"]),
                   _n(doc["timeshift_cam_imu_s"]), _a(doc["rotation_std_deg"]),
                   _a(doc["translation_std_m"]), _a(doc["position_std_imu_m"]),
                   _n(doc["timeshift_std_s"]), _n(doc["reprojection_rms_px"]), int(doc["n_frames"]),
                   int(doc["n_corners"]))

    def __repr__(self) -> str:
        t = self.T_cam_imu[:3, 3]
        return (f"CameraImuCalibration({self.name}: t=({t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}) m, "
                f"shift={self.timeshift_cam_imu_s * 1e3:.3f} ms, rms={self.reprojection_rms_px:.3f} px)")


@dataclass(frozen=True, eq=False)
class Excitation(ValueEquality):
    """How much the recording moved the rig, over the samples used.

    Attributes
    ----------
    gyro_std_rad_s : ndarray (3,)
        Standard deviation of the angular rate about the IMU axes.
    accel_std_m_s2 : ndarray (3,)
        Standard deviation of the specific force along the IMU axes.
    duration_s : float
        Time covered by the spline pieces.
    weak_rotation_axes : tuple of str
        IMU axes whose angular-rate std is below the threshold.
    translation_observable : bool
        At least two rotation axes are excited (a lever arm is seen only through rotation).
    """

    gyro_std_rad_s: FloatArray
    accel_std_m_s2: FloatArray
    duration_s: float
    min_rate_std_rad_s: float
    weak_rotation_axes: tuple[str, ...]
    translation_observable: bool

    def to_dict(self) -> dict[str, Any]:
        return {"gyro_std_rad_s": _l(self.gyro_std_rad_s), "accel_std_m_s2": _l(self.accel_std_m_s2),
                "duration_s": finite_or_none(self.duration_s), "min_rate_std_rad_s": self.min_rate_std_rad_s,
                "weak_rotation_axes": list(self.weak_rotation_axes),
                "translation_observable": self.translation_observable}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> Excitation:
        """The inverse of :meth:`to_dict`."""
        return cls(_a(doc["gyro_std_rad_s"]), _a(doc["accel_std_m_s2"]), _n(doc["duration_s"]),
                   float(doc["min_rate_std_rad_s"]), tuple(doc["weak_rotation_axes"]),
                   bool(doc["translation_observable"]))


@dataclass(frozen=True, eq=False)
class ResidualSeries:
    """Residuals over time for plots (not in ``to_dict``)."""

    imu_t_s: FloatArray
    gyro_rad_s: FloatArray  # (n, 3) estimate minus measurement
    accel_m_s2: FloatArray
    reproj: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict)  # name -> (t, (K,2))


@dataclass(frozen=True, eq=False)
class ImuCameraResult(ValueEquality):
    """Everything the calibration estimated and how well it is determined (``residuals``: the
    series for the figures, neither in :meth:`to_dict` nor compared)."""

    cameras: tuple[CameraImuCalibration, ...]
    gravity_target_m_s2: FloatArray
    bias_t_s: FloatArray
    gyro_bias_rad_s: FloatArray
    accel_bias_m_s2: FloatArray
    excitation: Excitation
    gyro_rms_rad_s: float
    accel_rms_m_s2: float
    chi2_per_dof: float
    iterations: int
    converged: bool
    forced: bool
    warnings: tuple[str, ...]
    knot_spacing_s: float
    runtime_s: float
    residuals: ResidualSeries | None = field(default=None, compare=False)
    #: how the standard deviations were made (method, measured residual scales, inflation)
    uncertainty: dict[str, Any] = field(default_factory=dict)

    def camera(self, name: str) -> CameraImuCalibration:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "cameras": [c.to_dict() for c in self.cameras],
            "gravity_target_m_s2": _l(self.gravity_target_m_s2),
            "bias": {"t_s": _l(self.bias_t_s), "gyro_rad_s": _l(self.gyro_bias_rad_s),
                     "accel_m_s2": _l(self.accel_bias_m_s2)},
            "excitation": self.excitation.to_dict(),
            "gyro_rms_rad_s": finite_or_none(self.gyro_rms_rad_s),
            "accel_rms_m_s2": finite_or_none(self.accel_rms_m_s2),
            "chi2_per_dof": finite_or_none(self.chi2_per_dof),
            "iterations": self.iterations,
            "converged": self.converged,
            "forced": self.forced,
            "warnings": list(self.warnings),
            "knot_spacing_s": self.knot_spacing_s,
            "runtime_s": finite_or_none(self.runtime_s),
            "uncertainty": self.uncertainty,
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> ImuCameraResult:
        """The inverse of :meth:`to_dict` (other keys of ``doc`` are ignored; no residual series)."""
        bias = doc["bias"]
        return cls(
            cameras=tuple(CameraImuCalibration.from_dict(c) for c in doc["cameras"]),
            gravity_target_m_s2=_a(doc["gravity_target_m_s2"]), bias_t_s=_a(bias["t_s"]),
            gyro_bias_rad_s=_a(bias["gyro_rad_s"]), accel_bias_m_s2=_a(bias["accel_m_s2"]),
            excitation=Excitation.from_dict(doc["excitation"]),
            gyro_rms_rad_s=_n(doc["gyro_rms_rad_s"]), accel_rms_m_s2=_n(doc["accel_rms_m_s2"]),
            chi2_per_dof=_n(doc["chi2_per_dof"]), iterations=int(doc["iterations"]),
            converged=bool(doc["converged"]), forced=bool(doc["forced"]),
            warnings=tuple(doc["warnings"]), knot_spacing_s=float(doc["knot_spacing_s"]),
            runtime_s=_n(doc["runtime_s"]), uncertainty=dict(doc["uncertainty"]))

    def __repr__(self) -> str:
        cams = ", ".join(c.name for c in self.cameras)
        return (f"ImuCameraResult([{cams}], {self.iterations} iterations, chi2/dof="
                f"{self.chi2_per_dof:.3f}, {len(self.warnings)} warning(s))")
