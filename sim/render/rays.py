"""Camera rays: one undistorted direction per pixel (or per supersample point), computed once.

The directions come from :meth:`ibiscape_eval.core.camera.CameraModel.pixel_rays`, so pixel centres
sit at integer coordinates (OpenCV's convention; open3d's ``create_rays_pinhole`` would shoot through
``u + 0.5``) and a distorted model renders images exactly distorted by its coefficients.  Directions
are ``(x, y, 1)`` in the camera frame: a ray caster's hit distance along them is the z-depth.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel

__all__ = ["camera_model", "camera_rays", "subpixel_rays", "world_rays"]

F32 = npt.NDArray[np.float32]


@functools.lru_cache(maxsize=32)
def camera_rays(model: CameraModel, supersample: int = 1) -> F32:
    """Camera-frame directions ``(x, y, 1)``, shape ``(H s, W s, 3)`` float32 (read-only, cached).

    Raises :class:`~ibiscape_eval.core.errors.IbiscapeError` naming the pixels where the distortion
    does not invert.
    """
    d = model.pixel_rays(supersample).astype(np.float32)
    d.setflags(write=False)
    return d


def subpixel_rays(model: CameraModel, rows: npt.ArrayLike, cols: npt.ArrayLike, supersample: int) -> F32:
    """Directions ``(K, s*s, 3)`` float32 through an s x s grid inside each pixel (row, col).

    The sample points sit at ``u - 0.5 + (i + 0.5) / s`` so that their mean is the pixel centre
    (like :meth:`CameraModel.pixel_grid`).
    """
    s = int(supersample)
    r = np.asarray(rows, dtype=np.float64)[:, None]
    c = np.asarray(cols, dtype=np.float64)[:, None]
    off = (np.arange(s) + 0.5) / s - 0.5
    if model.distortion == "none":  # one numba pass, the same float64 arithmetic as unproject
        from ._kernels import pinhole_subpixel_dirs

        out = np.empty((len(r), s * s, 3), np.float32)
        return pinhole_subpixel_dirs(r[:, 0], c[:, 0], off, float(model.fx), float(model.fy),
                                     float(model.cx), float(model.cy), out)
    du, dv = np.meshgrid(off, off)
    uv = np.stack([c + du.ravel()[None, :], r + dv.ravel()[None, :]], axis=-1)  # (K, s*s, 2)
    rays, ok = model.unproject(uv)
    if not ok.all():  # pixels whose centre inverts but a sub-sample does not: use the centre ray
        centre, _ = model.unproject(np.concatenate([c, r], axis=-1))
        rays = np.where(ok[..., None], rays, centre[:, None, :])
    return rays.astype(np.float32, copy=False)


def world_rays(dirs_cam: npt.ArrayLike, T_world_cam: npt.ArrayLike, out: F32 | None = None) -> F32:
    """Rays ``(..., 6)`` float32 ``[origin, direction]`` in the world for camera-frame directions
    (into ``out`` when given: a C-contiguous float32 buffer of that shape).

    The rotation keeps ``|d|``, so hit distances stay z-depths.
    """
    from ._kernels import transform_rays

    d = np.asarray(dirs_cam, dtype=np.float32)
    T = np.asarray(T_world_cam, dtype=np.float64)
    if out is None:
        out = np.empty((*d.shape[:-1], 6), dtype=np.float32)
    transform_rays(np.ascontiguousarray(d).reshape(-1, 3), T[:3, :3].astype(np.float32),
                   T[:3, 3].astype(np.float32), out.reshape(-1, 6))
    return out


def camera_model(spec: Any) -> CameraModel:
    """The :class:`CameraModel` of a :class:`~ibiscape_eval.sim.config.CameraSpec`: its Kalibr
    intrinsics (square pixels from the horizontal FOV, principal point at the image centre in
    OpenCV's convention), distortion model and coefficients."""
    fx, fy, cx, cy = spec.intrinsics
    return CameraModel(int(spec.width_px), int(spec.height_px), fx, fy, cx, cy,
                       spec.distortion_model, tuple(spec.distortion_coeffs))
