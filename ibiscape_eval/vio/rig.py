"""The stereo rig: two calibrated cameras in the body (IMU0) frame and their rectification.

Features are detected and tracked in the raw images; only their coordinates are rectified
(``cv2.undistortPoints`` with the rectifying rotation and projection), which is far cheaper than
remapping whole images.  In the rectified pair both cameras share the intrinsics
``(f_x, f_y, c_x, c_y)``, the right camera sits ``baseline_m`` along the left one's x axis, and a
point at depth ``z`` has disparity ``u_L - u_R = f_x b / z`` (GTSAM's ``Cal3_S2Stereo``).

A pair that is already rectified (pinhole without distortion, parallel axes, the same
intrinsics, baseline along x) is used as it is: rectification is then the identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError

__all__ = ["RectifiedStereo", "StereoRig"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RectifiedStereo:
    """The rectified pair: shared intrinsics, baseline, and the rectified left camera in the body.

    Attributes
    ----------
    fx, fy, cx, cy : float
        Rectified intrinsics [px] (OpenCV pixel centres).
    baseline_m : float
        Distance between the optical centres [m].
    width_px, height_px : int
    T_body_rect : ndarray, shape (4, 4)
        Pose of the rectified left camera frame in the body frame.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    baseline_m: float
    width_px: int
    height_px: int
    T_body_rect: FloatArray

    @property
    def K(self) -> FloatArray:
        """3x3 rectified intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def triangulate(self, uL: npt.ArrayLike, uR: npt.ArrayLike, v: npt.ArrayLike) -> FloatArray:
        """Points (N, 3) in the rectified left frame from rectified stereo pixels (disparity > 0)."""
        uL, uR, v = (np.asarray(a, dtype=np.float64) for a in (uL, uR, v))
        with np.errstate(divide="ignore"):
            z = self.fx * self.baseline_m / (uL - uR)
        return np.stack([(uL - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z], axis=-1)

    def project(self, points_rect: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Rectified ``(uL, uR, v)`` of points (N, 3) in the rectified left frame."""
        p = np.asarray(points_rect, dtype=np.float64)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        uL = self.fx * x / z + self.cx
        return uL, uL - self.fx * self.baseline_m / z, self.fy * y / z + self.cy


@dataclass(frozen=True, eq=False)
class StereoRig:
    """Two cameras with their poses in the body (IMU0) frame.

    Parameters
    ----------
    left, right : CameraModel
    T_body_left, T_body_right : ndarray, shape (4, 4)
        Camera (OpenCV frame) poses in the body frame.
    """

    left: CameraModel
    right: CameraModel
    T_body_left: FloatArray
    T_body_right: FloatArray
    _rect: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for name in ("T_body_left", "T_body_right"):
            T = np.asarray(getattr(self, name), dtype=np.float64)
            if T.shape != (4, 4) or not np.isfinite(T).all():
                raise CalibrationError(f"stereo rig: {name} must be a finite 4x4 matrix")
            R = T[:3, :3]
            if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
                raise CalibrationError(f"stereo rig: the rotation of {name} is not a rotation "
                                       "matrix; check the calibration file")
            object.__setattr__(self, name, T)
        if (self.left.width_px, self.left.height_px) != (self.right.width_px, self.right.height_px):
            raise CalibrationError(
                f"stereo rig: left {self.left.width_px}x{self.left.height_px} and right "
                f"{self.right.width_px}x{self.right.height_px} images differ in size")
        b = float(np.linalg.norm(self.T_right_left[:3, 3]))
        if b < 1e-3:
            raise CalibrationError(f"stereo rig: baseline {b:.4f} m; the two cameras coincide")

    @property
    def T_right_left(self) -> FloatArray:
        """``T_camR_camL``: left camera coordinates to right camera coordinates."""
        return np.linalg.inv(self.T_body_right) @ self.T_body_left

    @property
    def size(self) -> tuple[int, int]:
        """``(width_px, height_px)``."""
        return self.left.width_px, self.left.height_px

    def _already_rectified(self) -> bool:
        T = self.T_right_left
        same = (self.left.distortion == self.right.distortion == "none"
                or (not any(self.left.coeffs) and not any(self.right.coeffs)))
        return (same and np.allclose(T[:3, :3], np.eye(3), atol=1e-9)
                and abs(T[1, 3]) < 1e-9 and abs(T[2, 3]) < 1e-9 and T[0, 3] < 0
                and np.allclose(self.left.K, self.right.K, atol=1e-9))

    def rectified(self) -> RectifiedStereo:
        """The rectified pair (computed once, with ``cv2.stereoRectify`` unless already rectified)."""
        if "rect" not in self._rect:
            self._rect.update(self._rectify())
        out: RectifiedStereo = self._rect["rect"]
        return out

    def _rectify(self) -> dict[str, Any]:
        w, h = self.size
        T = self.T_right_left
        if self._already_rectified():
            L = self.left
            rect = RectifiedStereo(L.fx, L.fy, L.cx, L.cy, float(-T[0, 3]), w, h,
                                   self.T_body_left.copy())
            return {"rect": rect, "maps": None}
        import cv2

        R_rl = np.ascontiguousarray(T[:3, :3])
        t_rl = np.ascontiguousarray(T[:3, 3]).reshape(3, 1)
        if self.left.distortion == "equidistant" or self.right.distortion == "equidistant":
            R1, R2, P1, P2, _ = cv2.fisheye.stereoRectify(
                self.left.K, self.left.opencv_dist[:4], self.right.K, self.right.opencv_dist[:4],
                (w, h), R_rl, t_rl, flags=cv2.CALIB_ZERO_DISPARITY, balance=0.0)
        else:
            R1, R2, P1, P2, *_ = cv2.stereoRectify(
                self.left.K, self.left.opencv_dist, self.right.K, self.right.opencv_dist, (w, h),
                R_rl, t_rl, flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
        fx, fy, cx, cy = P1[0, 0], P1[1, 1], P1[0, 2], P1[1, 2]
        baseline = -P2[0, 3] / P2[0, 0]
        if not (np.isfinite([fx, fy, cx, cy, baseline]).all() and fx > 0 and baseline > 0):
            raise CalibrationError("stereo rectification failed: the right camera must be to the "
                                   "right of the left one (check T_cn_cnm1 / camera order)")
        T_body_rect = self.T_body_left.copy()
        T_body_rect[:3, :3] = self.T_body_left[:3, :3] @ R1.T
        rect = RectifiedStereo(float(fx), float(fy), float(cx), float(cy), float(baseline), w, h,
                               T_body_rect)
        return {"rect": rect, "maps": (R1, R2, P1, P2)}

    def rectify_points(self, uv: npt.ArrayLike, side: str) -> FloatArray:
        """Raw pixel coordinates (N, 2) of the ``side`` ("left"/"right") camera -> rectified."""
        self.rectified()
        pts = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        maps = self._rect["maps"]
        if maps is None or len(pts) == 0:
            return pts.copy()
        import cv2

        cam = self.left if side == "left" else self.right
        R, P = (maps[0], maps[2]) if side == "left" else (maps[1], maps[3])
        src = pts.reshape(-1, 1, 2)
        if cam.distortion == "equidistant":
            out = cv2.fisheye.undistortPoints(src, cam.K, cam.opencv_dist[:4], R=R, P=P)
        else:
            out = cv2.undistortPoints(src, cam.K, cam.opencv_dist, R=R, P=P)
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)

    def __repr__(self) -> str:
        return (f"StereoRig({self.left.width_px}x{self.left.height_px}, baseline "
                f"{np.linalg.norm(self.T_right_left[:3, 3]):.3f} m)")
