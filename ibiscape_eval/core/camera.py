"""Pinhole camera models with Kalibr's distortion models, shared by the renderer and calibration.

Conventions
-----------
- Camera frame: OpenCV's (z forward, x right, y down).  Points are ``(N, 3)`` in metres.
- Pixel coordinates follow OpenCV: the centre of the top-left pixel is ``(0, 0)``, so the image spans
  ``[-0.5, w - 0.5] x [-0.5, h - 0.5]`` and the principal point of an ideal camera is
  ``((w - 1) / 2, (h - 1) / 2)``.  (open3d's ``create_rays_pinhole`` shoots through ``u + 0.5``; we build
  our own rays from this model so that the two never mix.)
- Distortion acts on normalised coordinates ``(x, y) = (X / Z, Y / Z)``:

  ``radtan`` (OpenCV / Kalibr ``[k1, k2, p1, p2]``)::

      r2 = x^2 + y^2,  s = 1 + k1 r2 + k2 r2^2
      xd = x s + 2 p1 x y + p2 (r2 + 2 x^2),   yd = y s + p1 (r2 + 2 y^2) + 2 p2 x y

  ``equidistant`` (Kannala-Brandt as in Kalibr and ``cv2.fisheye``, ``[k1, k2, k3, k4]``)::

      r = |(x, y)|,  theta = atan(r),  theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
      (xd, yd) = (theta_d / r) (x, y)

  then ``u = fx xd + cx``, ``v = fy yd + cy``.

The inverse (pixel -> ray) is solved by vectorised Newton iterations; :meth:`CameraModel.pixel_rays`
checks the result by distorting it again and refuses, naming the pixels, when the distortion does not
invert over the image (a model whose distortion folds over inside the frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import IbiscapeError
from .jit import lazy_njit

__all__ = ["DISTORTION_MODELS", "INVERSE_TOLERANCE_PX", "NEWTON_ITERATIONS", "CameraModel"]

FloatArray = npt.NDArray[np.float64]

#: Kalibr's names of the supported distortion models ("none" is radtan with zero coefficients).
DISTORTION_MODELS = ("none", "radtan", "equidistant")

#: Newton iterations of the inverse distortion (the iterate repeats exactly well before)
NEWTON_ITERATIONS = 20
#: a ray is accepted when distorting it again lands within this distance of its pixel [px]
INVERSE_TOLERANCE_PX = 1e-6


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera with optional radtan or equidistant distortion.

    Parameters
    ----------
    width_px, height_px
        Image size [px].
    fx, fy, cx, cy
        Focal lengths and principal point [px], OpenCV's pixel-centre convention (see module doc).
    distortion
        ``"none"``, ``"radtan"`` or ``"equidistant"`` (Kalibr's names).
    coeffs
        Four distortion coefficients in Kalibr's order (``[k1, k2, p1, p2]`` or ``[k1, k2, k3, k4]``).
    """

    width_px: int
    height_px: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: str = "none"
    coeffs: tuple[float, float, float, float] = field(default=(0.0, 0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        if self.width_px < 1 or self.height_px < 1:
            raise IbiscapeError(f"camera size {self.width_px}x{self.height_px} px: give positive sizes")
        if not (math.isfinite(self.fx) and math.isfinite(self.fy) and self.fx > 0 and self.fy > 0):
            raise IbiscapeError(f"focal lengths fx={self.fx}, fy={self.fy} px: give positive finite values")
        if not (math.isfinite(self.cx) and math.isfinite(self.cy)):
            raise IbiscapeError(f"principal point ({self.cx}, {self.cy}) px is not finite")
        if self.distortion not in DISTORTION_MODELS:
            raise IbiscapeError(
                f"distortion model {self.distortion!r}: use one of {', '.join(DISTORTION_MODELS)}")
        coeffs = tuple(float(c) for c in self.coeffs)
        if len(coeffs) != 4 or not all(math.isfinite(c) for c in coeffs):
            raise IbiscapeError(f"distortion coefficients {self.coeffs}: give four finite numbers")
        object.__setattr__(self, "coeffs", coeffs)

    # ----------------------------------------------------------------------------------- builders
    @classmethod
    def from_fov(cls, width_px: int, height_px: int, fov_deg: float, *, distortion: str = "none",
                 coeffs: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)) -> CameraModel:
        """Square pixels, horizontal field of view ``fov_deg``, principal point at the image centre."""
        if not 0.0 < fov_deg < 180.0:
            raise IbiscapeError(f"field of view {fov_deg} deg: give a value in (0, 180)")
        f = (width_px / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
        return cls(width_px, height_px, f, f, (width_px - 1) / 2.0, (height_px - 1) / 2.0,
                   distortion, coeffs)

    def scaled(self, width_px: int, height_px: int) -> CameraModel:
        """The same optics on a sensor of another size (same field of view, same distortion).

        Pixel edges map to pixel edges: ``u' + 0.5 = (u + 0.5) * width' / width``.
        """
        sx, sy = width_px / self.width_px, height_px / self.height_px
        return replace(self, width_px=width_px, height_px=height_px, fx=self.fx * sx, fy=self.fy * sy,
                       cx=(self.cx + 0.5) * sx - 0.5, cy=(self.cy + 0.5) * sy - 0.5)

    @property
    def K(self) -> FloatArray:
        """The 3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def intrinsics(self) -> list[float]:
        """Kalibr's ``[fu, fv, pu, pv]``."""
        return [self.fx, self.fy, self.cx, self.cy]

    @property
    def opencv_dist(self) -> FloatArray:
        """Coefficients in OpenCV's layout: radtan ``(k1, k2, p1, p2, 0)``, equidistant ``(k1..k4)``."""
        if self.distortion == "equidistant":
            return np.array(self.coeffs)
        return np.array([*self.coeffs, 0.0])

    # ---------------------------------------------------------------------------------- Kalibr yaml
    def to_kalibr(self) -> dict[str, Any]:
        """The camera's entry of a Kalibr ``camchain.yaml`` (without ``T_cn_cnm1`` / ``rostopic``)."""
        model = "equidistant" if self.distortion == "equidistant" else "radtan"
        return {
            "camera_model": "pinhole",
            "intrinsics": [float(v) for v in self.intrinsics],
            "distortion_model": model,
            "distortion_coeffs": [float(c) for c in self.coeffs],
            "resolution": [int(self.width_px), int(self.height_px)],
        }

    @classmethod
    def from_kalibr(cls, entry: dict[str, Any]) -> CameraModel:
        """Build from a Kalibr camchain entry (``camera_model: pinhole`` only).

        Raises :class:`IbiscapeError` naming the missing or wrong key.
        """
        try:
            if entry.get("camera_model", "pinhole") != "pinhole":
                raise IbiscapeError(f"camera_model {entry['camera_model']!r}: only 'pinhole' is supported")
            fu, fv, pu, pv = (float(v) for v in entry["intrinsics"])
            w, h = (int(v) for v in entry["resolution"])
            model = str(entry.get("distortion_model", "radtan"))
            coeffs = tuple(float(c) for c in entry.get("distortion_coeffs", [0.0] * 4))
        except KeyError as exc:
            raise IbiscapeError(f"camera entry lacks the key {exc.args[0]!r}") from None
        except (TypeError, ValueError):
            raise IbiscapeError(
                "camera entry: intrinsics must be [fu, fv, pu, pv], resolution [w, h]") from None
        if model not in ("radtan", "equidistant"):
            raise IbiscapeError(f"distortion_model {model!r}: use radtan or equidistant")
        if len(coeffs) != 4:
            raise IbiscapeError(f"distortion_coeffs {list(coeffs)}: give four numbers")
        return cls(w, h, fu, fv, pu, pv, model, coeffs)

    # ------------------------------------------------------------------------------- distortion
    def distort(self, xy: npt.ArrayLike) -> FloatArray:
        """Distort normalised coordinates, shape (..., 2) -> (..., 2)."""
        xy = np.asarray(xy, dtype=np.float64)
        x, y = xy[..., 0], xy[..., 1]
        if self.distortion == "equidistant":
            k1, k2, k3, k4 = self.coeffs
            r = np.hypot(x, y)
            th = np.arctan(r)
            th2 = th * th
            thd = th * (1.0 + th2 * (k1 + th2 * (k2 + th2 * (k3 + th2 * k4))))
            # theta_d / r -> 1 as r -> 0
            scale = np.divide(thd, r, out=np.ones_like(r), where=r > 1e-12)
            return np.stack([x * scale, y * scale], axis=-1)
        if self.distortion == "none":
            return xy.copy()
        k1, k2, p1, p2 = self.coeffs
        r2 = x * x + y * y
        s = 1.0 + r2 * (k1 + k2 * r2)
        xd = x * s + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        return np.stack([xd, yd], axis=-1)

    def undistort(self, xy_d: npt.ArrayLike) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Invert :meth:`distort` by Newton iterations.

        Returns
        -------
        xy : (..., 2) normalised undistorted coordinates
        ok : (...,) bool, True where distorting ``xy`` again reproduces the input within 1e-6 px
             and the distortion is locally orientation-preserving (does not fold over).
        """
        xy_d = np.asarray(xy_d, dtype=np.float64)
        if self.distortion == "none":
            return xy_d.copy(), np.ones(xy_d.shape[:-1], dtype=bool)
        if self.distortion == "equidistant":
            return self._undistort_equi(xy_d)
        return self._undistort_radtan(xy_d)

    def _undistort_radtan(self, xy_d: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        flat = np.ascontiguousarray(xy_d.reshape(-1, 2))
        xy = np.empty_like(flat)
        ok = np.empty(len(flat), dtype=bool)
        _radtan_undistort(flat, np.asarray(self.coeffs, dtype=np.float64), float(self.fx), float(self.fy),
                          NEWTON_ITERATIONS, INVERSE_TOLERANCE_PX, xy, ok)
        return xy.reshape(xy_d.shape), ok.reshape(xy_d.shape[:-1])

    def _undistort_equi(self, xy_d: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        k1, k2, k3, k4 = self.coeffs
        rd = np.hypot(xy_d[..., 0], xy_d[..., 1])
        th = np.clip(rd, 0.0, math.pi / 2 - 1e-9)
        with np.errstate(all="ignore"):
            for _ in range(NEWTON_ITERATIONS):
                th2 = th * th
                f = th * (1.0 + th2 * (k1 + th2 * (k2 + th2 * (k3 + th2 * k4)))) - rd
                df = 1.0 + th2 * (3.0 * k1 + th2 * (5.0 * k2 + th2 * (7.0 * k3 + 9.0 * th2 * k4)))
                th = th - f / df
            th2 = th * th
            df = 1.0 + th2 * (3.0 * k1 + th2 * (5.0 * k2 + th2 * (7.0 * k3 + 9.0 * th2 * k4)))
            r = np.tan(th)
            scale = np.divide(r, rd, out=np.ones_like(rd), where=rd > 1e-12)
        xy = xy_d * scale[..., None]
        ok = (th >= 0) & (th < math.pi / 2) & (df > 0)
        return xy, self._check_inverse(xy, xy_d) & ok

    def _check_inverse(self, xy: FloatArray, xy_d: FloatArray) -> npt.NDArray[np.bool_]:
        with np.errstate(all="ignore"):
            err = self.distort(xy) - xy_d
            err_px = np.hypot(err[..., 0] * self.fx, err[..., 1] * self.fy)
        return np.isfinite(err_px) & (err_px < INVERSE_TOLERANCE_PX)

    # ------------------------------------------------------------------------------- projection
    def project(self, points_cam: npt.ArrayLike) -> FloatArray:
        """Project camera-frame points (N, 3) [m] to pixels (N, 2); points with z <= 0 give NaN."""
        p = np.asarray(points_cam, dtype=np.float64)
        z = p[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = p[..., :2] / np.where(z > 0, z, np.nan)[..., None]
        xy_d = self.distort(xy)
        return np.stack([self.fx * xy_d[..., 0] + self.cx, self.fy * xy_d[..., 1] + self.cy], axis=-1)

    def unproject(self, uv: npt.ArrayLike) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Rays ``(x, y, 1)`` (..., 3) of pixel coordinates (..., 2), and where the inversion succeeded."""
        uv = np.asarray(uv, dtype=np.float64)
        xy_d = np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy], axis=-1)
        xy, ok = self.undistort(xy_d)
        return np.concatenate([xy, np.ones((*xy.shape[:-1], 1))], axis=-1), ok

    def pixel_grid(self, supersample: int = 1) -> FloatArray:
        """Pixel coordinates (h*s, w*s, 2) of an s x s grid of sample points inside every pixel.

        With ``supersample = 1`` these are the pixel centres ``(u, v)``; with ``s > 1`` the sample
        points sit at ``u - 0.5 + (i + 0.5) / s`` so that their mean is the pixel centre.
        """
        s = int(supersample)
        if s < 1:
            raise IbiscapeError(f"supersample {supersample}: give an integer >= 1")
        u = (np.arange(self.width_px * s) + 0.5) / s - 0.5
        v = (np.arange(self.height_px * s) + 0.5) / s - 0.5
        uu, vv = np.meshgrid(u, v)
        return np.stack([uu, vv], axis=-1)

    def pixel_rays(self, supersample: int = 1) -> FloatArray:
        """Ray directions ``(x, y, 1)`` (h*s, w*s, 3) in the camera frame through every sample point.

        With ``d = (x, y, 1)`` a ray caster's hit distance ``t`` equals the z-depth.

        Raises
        ------
        IbiscapeError
            When the distortion does not invert over the image; the message names how many pixels
            fail and the first few of them.
        """
        rays, ok = self.unproject(self.pixel_grid(supersample))
        if not ok.all():
            bad = np.argwhere(~ok)
            first = ", ".join(f"(u={c / supersample:.1f}, v={r / supersample:.1f})" for r, c in bad[:3])
            raise IbiscapeError(
                f"the {self.distortion} distortion {list(self.coeffs)} does not invert over the "
                f"{self.width_px}x{self.height_px} image: {len(bad)} of {ok.size} sample points fail, "
                f"e.g. {first}; use smaller coefficients or a smaller field of view")
        return rays

    def __repr__(self) -> str:
        dist = "" if self.distortion == "none" else f", {self.distortion} {list(self.coeffs)}"
        return (f"CameraModel({self.width_px}x{self.height_px}, f=({self.fx:.3f}, {self.fy:.3f}), "
                f"c=({self.cx:.3f}, {self.cy:.3f}){dist})")


@lazy_njit(error_model="numpy")
def _radtan_undistort(xy_d, coeffs, fx, fy, iterations, tol_px, xy, ok):
    """Newton inversion of the radial-tangential distortion of each row of ``xy_d`` (N, 2) into
    ``xy``, stopped once an iterate repeats exactly (later iterations would reproduce it: the
    result equals ``iterations`` full steps bit for bit); ``ok``: re-distorting lands within
    ``tol_px`` of the input and the map does not fold over (positive Jacobian determinant).

    A kernel because the numpy form made ~30 temporaries per iteration: 1.13 s CPU for the 1.1 M
    supersamples of a 384 px calibration-board view, 0.2 s in this form (measured, #25)."""
    k1, k2, p1, p2 = coeffs[0], coeffs[1], coeffs[2], coeffs[3]
    for n in range(xy_d.shape[0]):
        xd, yd = xy_d[n, 0], xy_d[n, 1]
        x, y = xd, yd
        for it in range(iterations + 1):  # the last pass only evaluates the result's residual and Jacobian
            r2 = x * x + y * y
            s = 1.0 + r2 * (k1 + k2 * r2)
            ds = k1 + 2.0 * k2 * r2  # d s / d r2
            ex = x * s + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
            ey = y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
            a = s + 2.0 * x * x * ds + 2.0 * p1 * y + 6.0 * p2 * x
            b = 2.0 * x * y * ds + 2.0 * p1 * x + 2.0 * p2 * y
            d = s + 2.0 * y * y * ds + 6.0 * p1 * y + 2.0 * p2 * x
            if it == iterations:
                break
            det = a * d - b * b
            xn = x - (d * ex - b * ey) / det
            yn = y - (a * ey - b * ex) / det
            if xn == x and yn == y:  # the residual and Jacobian above are those of the result
                break
            x, y = xn, yn
        err = np.hypot(ex * fx, ey * fy)
        xy[n, 0], xy[n, 1] = x, y
        ok[n] = np.isfinite(err) and err < tol_px and a * d - b * b > 0
