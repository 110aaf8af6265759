"""RGB-D inputs: depth images as the stereo measurement the estimator already takes.

A depth camera registered to the RGB camera gives, at a tracked corner ``(u, v)`` of depth ``z``,
what a rectified stereo pair with a *virtual* baseline ``b`` would measure:
``(u_L, u_R, v) = (u, u - f b / z, v)``.  The estimator is then unchanged (GTSAM's
``GenericStereoFactor``).  The depth camera's noise model becomes a disparity noise
``sigma_d = f b sigma_z(z) / z^2``; a corner is used only where ``sigma_d`` is within the
estimator's stereo pixel sigma, where ``min_depth_m <= z <= max_depth_m`` and where its 3x3
neighbourhood has one depth (within ``edge_ratio``: no depth edge, so that a corner on an
object's silhouette does not take the background's depth).

Depth files of an IBISCape sequence (``depth/``, ``sim`` writes both):

- ``mm/<ns>.png``: 16-bit millimetres, 0 = none (TUM RGB-D / ORB-SLAM3, ``DepthMapFactor 1000``);
  noise: the 1 mm quantisation, ``sigma_z = 1 mm / sqrt(12)``.  Preferred when present.
- ``frames/<ns>.png``: CARLA's 8-bit logarithmic depth (the published dataset); one code step is a
  factor ``exp(5.70378 / 255)`` (2.26 %), so ``sigma_z = z (5.70378 / 255) / sqrt(12)`` (0.65 %).

A third unit, ``tum`` (``DepthReader(files, "tum", ...)``), reads the TUM RGB-D recordings' 16-bit
files, 5000 per metre (their ``depth/*.png``, Open3D's ``create_from_tum_format``); the noise is the
Kinect v1's rather than the quantisation's, about 4 cm at 5 m (Khoshelham and Elberink, Sensors
2012): ``sigma_z = 1.6e-3 z^2``.  A TUM file read as millimetres would come out 5 times too far
and no check of the image alone can tell, so the unit is the caller's to give.  Checked on real
files (``tests/io/test_depth_real.py``): a TUM frame (``tum``) and a Redwood frame (``mm``), each
decoded as Open3D decodes it.

Registration: when the depth camera's intrinsics or pose differ from the RGB camera's, every depth
pixel is back-projected, moved into the RGB camera with the calibration (``T_body_cam`` of both)
and projected there, keeping the nearest depth per RGB pixel (a z-buffer).  A depth image of
another size than the depth calibration, or in another unit than its folder says, is refused
naming the file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError

from .backend import StereoObservations
from .frontend import StereoFrontEnd
from .params import VioParams
from .rig import StereoRig

__all__ = ["DepthFrontEnd", "DepthOptions", "DepthReader", "depth_sigma_m", "virtual_rig"]

FloatArray = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]

#: CARLA's log-depth scale: depth = 1000 m * exp((code / 255 - 1) * 5.70378)
CARLA_LOG_SCALE = 5.70378
DEPTH_UNITS = ("mm", "carla-log", "tum")
#: metres per count of the 16-bit units
DEPTH_STEP_M = {"mm": 1e-3, "tum": 1.0 / 5000.0}
#: the Kinect v1's depth noise, sigma_z = KINECT_SIGMA_PER_M2 * z^2 (about 4 cm at 5 m)
KINECT_SIGMA_PER_M2 = 1.6e-3


@dataclass(frozen=True)
class DepthOptions:
    """The depth front end's knobs.

    Attributes
    ----------
    baseline_m : float
        Virtual stereo baseline [m] (with the estimator's ``min_disparity_px``, it bounds the
        depth a landmark may have: ``z <= f b / min_disparity``).
    min_depth_m, max_depth_m : float
        The depth camera's usable range.
    edge_ratio : float
        Largest relative depth spread in a corner's 3x3 neighbourhood.
    depth_unit : str or None
        The depth files' unit (``mm``, ``tum`` or ``carla-log``); None: by the folder, ``mm``
        for ``depth/mm/``, ``carla-log`` for ``depth/frames/``.  ``mm`` and ``tum`` read
        ``depth/mm/`` when there is one, else ``depth/frames/``.
    """

    baseline_m: float = 1.0
    min_depth_m: float = 0.3
    max_depth_m: float = 60.0
    edge_ratio: float = 0.05
    depth_unit: str | None = None

    def __post_init__(self) -> None:
        for k in ("baseline_m", "min_depth_m", "max_depth_m", "edge_ratio"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise IbiscapeError(f"depth option {k} = {v!r}: give a positive number")
        if self.max_depth_m <= self.min_depth_m:
            raise IbiscapeError("depth option max_depth_m must exceed min_depth_m")
        if self.depth_unit is not None and self.depth_unit not in DEPTH_UNITS:
            raise IbiscapeError(f"depth unit {self.depth_unit!r}: use one of {', '.join(DEPTH_UNITS)}")


def depth_sigma_m(z_m: npt.ArrayLike, unit: str) -> FloatArray:
    """The depth camera's noise (1 sigma, metres) at depths ``z_m`` for a file ``unit``."""
    z = np.asarray(z_m, dtype=np.float64)
    if unit == "mm":
        return np.full_like(z, 1e-3 / math.sqrt(12.0))
    if unit == "carla-log":
        return z * (CARLA_LOG_SCALE / 255.0) / math.sqrt(12.0)
    if unit == "tum":
        return KINECT_SIGMA_PER_M2 * z * z
    raise IbiscapeError(f"depth unit {unit!r}: use one of {', '.join(DEPTH_UNITS)}")


def virtual_rig(cam: CameraModel, T_body_cam: FloatArray, baseline_m: float) -> StereoRig:
    """The RGB camera and a copy of it ``baseline_m`` to its right (along its x axis)."""
    T_cam_right = np.eye(4)
    T_cam_right[0, 3] = baseline_m
    return StereoRig(cam, cam, np.asarray(T_body_cam, dtype=np.float64),
                     np.asarray(T_body_cam, dtype=np.float64) @ T_cam_right)


class DepthReader:
    """``reader(i)`` -> depth [m] (H, W) float32 of frame ``i`` on the RGB camera's pixel grid
    (NaN: no depth); see the module docstring for the files, units and registration."""

    def __init__(self, files: list[Path], unit: str, depth_cam: CameraModel, T_body_depth: FloatArray,
                 rgb_cam: CameraModel, T_body_rgb: FloatArray) -> None:
        if unit not in DEPTH_UNITS:
            raise IbiscapeError(f"depth unit {unit!r}: use one of {', '.join(DEPTH_UNITS)}")
        self.files, self.unit = files, unit
        self.depth_cam, self.rgb_cam = depth_cam, rgb_cam
        self.T_rgb_depth = np.linalg.inv(np.asarray(T_body_rgb, float)) @ np.asarray(T_body_depth, float)
        same_cam = (depth_cam.width_px, depth_cam.height_px) == (rgb_cam.width_px, rgb_cam.height_px) \
            and np.allclose(depth_cam.K, rgb_cam.K) and tuple(depth_cam.coeffs) == tuple(rgb_cam.coeffs)
        self.identity = same_cam and np.allclose(self.T_rgb_depth, np.eye(4), atol=1e-9)
        self._rays: FloatArray | None = None

    def __len__(self) -> int:
        return len(self.files)

    def raw(self, i: int) -> F32:
        """Depth [m] of file ``i`` on the depth camera's grid, checked against its calibration."""
        from ibiscape_eval.io.images import read_png

        f = self.files[i]
        img = read_png(f)
        w, h = self.depth_cam.width_px, self.depth_cam.height_px
        if img.shape[:2] != (h, w):
            raise FormatError(f, f"depth image is {img.shape[1]}x{img.shape[0]} px, the depth "
                              f"camera's calibration says {w}x{h}")
        if self.unit in DEPTH_STEP_M:
            return _sixteen_bit_depth(f, img, self.unit)
        if img.dtype != np.uint8:
            raise FormatError(f, f"CARLA log depth is 8-bit, got {img.dtype} (16-bit millimetres "
                              "belong in depth/mm/)")
        code = img[..., 0] if img.ndim == 3 else img
        d = (1000.0 * np.exp((code.astype(np.float32) / 255.0 - 1.0) * CARLA_LOG_SCALE)).astype(np.float32)
        d[code >= 255] = np.nan  # sky / beyond 1000 m
        return d

    def __call__(self, i: int) -> F32:
        d = self.raw(i)
        return d if self.identity else self._register(d)

    def _register(self, d: F32) -> F32:
        import cv2

        if self._rays is None:
            h, w = d.shape
            grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 1, 2).astype(np.float64)
            self._rays = np.asarray(cv2.undistortPoints(grid, self.depth_cam.K, self.depth_cam.opencv_dist),
                                    np.float64).reshape(-1, 2)
        z = d.reshape(-1).astype(np.float64)
        ok = np.isfinite(z)
        rays = np.asarray(self._rays)[ok]
        P = np.column_stack([rays * z[ok, None], z[ok]]) @ self.T_rgb_depth[:3, :3].T + self.T_rgb_depth[:3, 3]
        front = P[:, 2] > 1e-6
        P = P[front]
        uv, _ = cv2.projectPoints(P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), self.rgb_cam.K,
                                  self.rgb_cam.opencv_dist)
        px = np.round(np.asarray(uv).reshape(-1, 2)).astype(np.int64)
        W, H = self.rgb_cam.width_px, self.rgb_cam.height_px
        inside = (px[:, 0] >= 0) & (px[:, 0] < W) & (px[:, 1] >= 0) & (px[:, 1] < H)
        idx, zz = px[inside, 1] * W + px[inside, 0], P[inside, 2]
        order = np.argsort(-zz, kind="stable")  # the nearest written last wins (z-buffer)
        out = np.full(H * W, np.nan, np.float32)
        out[idx[order]] = zz[order]
        return out.reshape(H, W)


def _sixteen_bit_depth(f: Path, img: npt.NDArray[Any], unit: str) -> F32:
    """Depth [m] of a 16-bit image in ``unit`` (``mm``: 1 mm per count, ``tum``: 0.2 mm); 0 = none.
    Refuses another bit depth, and a median under 0.1 m (metres written as integers, or a
    disparity image): no depth camera sees most of its pixels that close."""
    name = "millimetre" if unit == "mm" else "TUM (5000 per metre)"
    if img.dtype != np.uint16 or img.ndim != 2:
        raise FormatError(f, f"expected 16-bit {name} depth, got {img.dtype} "
                          f"{'x'.join(map(str, img.shape))}; give the mm/ folder's files")
    step = DEPTH_STEP_M[unit]
    valid = img[img > 0]
    median_m = float(np.median(valid)) * step if valid.size else np.inf
    if median_m < 0.1:
        raise FormatError(f, f"median depth {median_m * 1e3:.0f} mm (< 0.1 m) "
                          f"read as {name}: the file looks like metres or another unit")
    d = img.astype(np.float32) / np.float32(1.0 / step)
    d[img == 0] = np.nan
    return d


class DepthFrontEnd(StereoFrontEnd):
    """KLT tracking in the RGB image (like :class:`StereoFrontEnd`) with the depth image in place
    of the right camera: each tracked corner's registered depth gives its virtual right column."""

    stereo_on_demand = False  # the depth of every frame, through process()

    def __init__(self, rig: StereoRig, params: VioParams, unit: str,
                 options: DepthOptions | None = None) -> None:
        super().__init__(rig, params)
        self.options = options or DepthOptions()
        self.unit = unit
        self.sigma_px = params.pixel_sigma_px * params.scale_px(rig.size[0])

    def process(self, stamp_ns: int, left: npt.NDArray[np.uint8], right: Any,
                R_b0_b1: FloatArray | None = None, *, gated: bool = True) -> StereoObservations:
        """Track into a new RGB frame (:meth:`StereoFrontEnd.track`); ``right`` is the registered
        depth [m] (H, W).  ``gated=False`` keeps every corner with a depth off a depth edge,
        whatever its value and noise (the depth unit's check against the IMU,
        :mod:`ibiscape_eval.vio.scale_check`, must see depths that are wrong by a factor)."""
        tr = self.track(stamp_ns, left, R_b0_b1)
        if len(tr) == 0:
            return StereoObservations.empty(stamp_ns)
        z, ok = self._depth_at(np.asarray(right, np.float32), self.pts, gated)
        with np.errstate(divide="ignore", invalid="ignore"):
            disp = self.rect.fx * self.options.baseline_m / z
            sigma_d = self.rect.fx * self.options.baseline_m * depth_sigma_m(z, self.unit) / (z * z)
        ok &= np.isfinite(disp) & (disp > 0)
        if gated:
            ok &= sigma_d <= self.sigma_px
        sel = np.flatnonzero(ok)
        return StereoObservations(int(stamp_ns), tr.ids[sel], tr.uL[sel], tr.uL[sel] - disp[sel],
                                  tr.v[sel])

    def _depth_at(self, depth: F32, pts: npt.NDArray[np.float32], gated: bool = True
                  ) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Depth at each corner (nearest pixel) and whether its 3x3 neighbourhood is one surface
        (and, ``gated``, within the camera's range)."""
        h, w = depth.shape
        xi = np.clip(np.round(pts[:, 0]).astype(int), 1, w - 2)
        yi = np.clip(np.round(pts[:, 1]).astype(int), 1, h - 2)
        nb = np.stack([depth[yi + dy, xi + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
        z = depth[yi, xi].astype(np.float64)
        o = self.options
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(nb).all(axis=0) & ((nb.max(axis=0) - nb.min(axis=0)) <= o.edge_ratio * z)
            if gated:
                ok &= (z >= o.min_depth_m) & (z <= o.max_depth_m)
        return z, ok
