"""SO(3) in plain numpy, batched over leading axes: skew matrices, the exponential and logarithm
of rotation vectors and the left Jacobian.

numpy only (no scipy: :mod:`scipy.spatial.transform` costs 0.3 s of imports, a third of a whole
camera calibration of 13 stereo photos, ``benchmarks/bench_calib_real.py``), and with the left
Jacobian that scipy does not offer (the exact derivatives of the calibration solvers).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["exp_so3", "hat", "left_jacobian_so3", "log_so3"]

FloatArray = npt.NDArray[np.float64]


def hat(v: npt.ArrayLike) -> FloatArray:
    """Skew matrices ``[v]x`` of vectors (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=np.float64)
    K = np.zeros((*v.shape[:-1], 3, 3))  # filled in place: 4x less time than nested np.stack
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def _coefficients(phi: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``sin t / t``, ``(1 - cos t) / t^2`` and ``(t - sin t) / t^3`` of ``t = |phi|`` (Taylor
    series below 1e-6 rad, and below 1e-4 rad for the third, whose subtraction cancels sooner)."""
    th2 = np.einsum("...i,...i->...", phi, phi)
    small, small_c = th2 < 1e-12, th2 < 1e-8
    safe = np.where(small, 1.0, np.sqrt(th2))
    safe_c = np.where(small_c, 1.0, np.sqrt(th2))
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    c = np.where(small_c, 1.0 / 6.0 - th2 / 120.0, (safe_c - np.sin(safe_c)) / safe_c**3)
    return a, b, c


def exp_so3(phi: npt.ArrayLike) -> FloatArray:
    """Rodrigues' formula for rotation vectors (..., 3) -> matrices (..., 3, 3)."""
    phi = np.asarray(phi, dtype=np.float64)
    a, b, _ = _coefficients(phi)
    K = hat(phi)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def left_jacobian_so3(phi: npt.ArrayLike) -> FloatArray:
    """Left Jacobians (..., 3, 3) of rotation vectors (..., 3):
    ``exp(phi + d) ~ exp([J_l(phi) d]x) exp(phi)``."""
    phi = np.asarray(phi, dtype=np.float64)
    _, b, c = _coefficients(phi)
    K = hat(phi)
    return np.eye(3) + b[..., None, None] * K + c[..., None, None] * (K @ K)


def log_so3(R: npt.ArrayLike) -> FloatArray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3) with angles below pi."""
    R = np.asarray(R, dtype=np.float64)
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) * 0.5, -1.0, 1.0)
    th = np.arccos(cos)
    w = np.stack((R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]), -1)
    s = np.sin(th)
    small = th < 1e-6
    factor = np.where(small, 0.5 + th * th / 12.0, th / (2.0 * np.where(small, 1.0, s)))
    return w * factor[..., None]
