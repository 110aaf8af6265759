"""Analytic Jacobians and the block-sparse normal equations of the calibration problem.

The unknowns are ``a`` (every camera's 8 intrinsics, then the chain's 6-vectors ``T_cn_cnm1``) and
one 6-vector target pose per view (rotation vector, translation).  A corner observation touches
``a`` and its view's pose only, so the normal matrix is ``[[H_aa, H_ap], [H_pa, blockdiag(H_pp)]]``;
the poses are eliminated by their 6x6 blocks (Schur complement, as in bundle adjustment) and the
system left is ``K x K`` (22 for a stereo pair): no sparse factorisation, no large dense one.

Derivatives are exact (chain rule through the projection, the distortion and the rotation
vectors' left Jacobian), so a Jacobian costs one evaluation instead of one per group of columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

__all__ = [
    "BlockJacobian",
    "leading_inverse",
    "normal_equations",
    "project_jacobian",
    "rotvec_from_matrix",
    "solve_damped",
]


# ------------------------------------------------------------------------------------ rotations
def rotvec_from_matrix(R: FloatArray) -> FloatArray:
    """The rotation vector (3,) of one rotation matrix (OpenCV's Rodrigues)."""
    import cv2

    w, _ = cv2.Rodrigues(np.ascontiguousarray(R, np.float64))
    return np.asarray(w, np.float64).ravel()


# ----------------------------------------------------------------------------------- projection
def _distortion_radtan(x: FloatArray, y: FloatArray, k: FloatArray
                       ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Distorted ``xd, yd``, their derivatives by ``(x, y)`` (M, 2, 2) and by the coefficients
    ``k1, k2, p1, p2`` (M, 2, 4).  The derivative arrays are filled in place (nested
    ``np.stack`` of the columns took twice the time of the arithmetic)."""
    k1, k2, p1, p2 = k
    r2 = x * x + y * y
    s = 1.0 + r2 * (k1 + k2 * r2)
    ds = 2.0 * (k1 + 2.0 * k2 * r2)  # d s / d x = ds * x
    xd = x * s + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    off = ds * x * y + 2.0 * p1 * x + 2.0 * p2 * y
    dxy = np.empty((len(x), 2, 2))
    dxy[:, 0, 0] = s + ds * x * x + 2.0 * p1 * y + 6.0 * p2 * x
    dxy[:, 0, 1] = off
    dxy[:, 1, 0] = off
    dxy[:, 1, 1] = s + ds * y * y + 6.0 * p1 * y + 2.0 * p2 * x
    dk = np.empty((len(x), 2, 4))
    xr2, yr2, xy2 = x * r2, y * r2, 2.0 * x * y
    dk[:, 0, 0], dk[:, 0, 1], dk[:, 0, 2], dk[:, 0, 3] = xr2, xr2 * r2, xy2, r2 + 2.0 * x * x
    dk[:, 1, 0], dk[:, 1, 1], dk[:, 1, 2], dk[:, 1, 3] = yr2, yr2 * r2, r2 + 2.0 * y * y, xy2
    return xd, yd, dxy, dk


def _distortion_equi(x: FloatArray, y: FloatArray, k: FloatArray
                     ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """As :func:`_distortion_radtan` for the equidistant model ``theta_d / r``, ``theta = atan r``."""
    k1, k2, k3, k4 = k
    r = np.hypot(x, y)
    tiny = r < 1e-12
    rs = np.where(tiny, 1.0, r)
    th = np.arctan(r)
    t2 = th * th
    thd = th * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    scale = np.where(tiny, 1.0, thd / rs)
    dthd = (1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + 9.0 * t2 * k4)))) / (1.0 + r * r)
    # d scale / d r, divided by r (x and y carry the other factor r)
    g = np.where(tiny, 0.0, (dthd * rs - thd) / rs**3)
    dxy = np.empty((len(x), 2, 2))
    dxy[:, 0, 0] = scale + g * x * x
    dxy[:, 0, 1] = dxy[:, 1, 0] = g * x * y
    dxy[:, 1, 1] = scale + g * y * y
    powers = np.empty((len(x), 4))
    powers[:, 0], powers[:, 1], powers[:, 2], powers[:, 3] = th**3, th**5, th**7, th**9
    powers /= rs[:, None]
    powers[tiny] = 0.0
    dk = np.empty((len(x), 2, 4))
    dk[:, 0], dk[:, 1] = x[:, None] * powers, y[:, None] * powers
    return x * scale, y * scale, dxy, dk


def project_jacobian(distortion: str, intr: FloatArray, p: FloatArray
                     ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pixels (M, 2) of camera-frame points (M, 3) and their derivatives by the 8 intrinsics
    ``fx, fy, cx, cy, d0..d3`` (M, 2, 8) and by the point (M, 2, 3); points behind the camera give
    NaN pixels (as :meth:`CameraModel.project`)."""
    fx, fy, cx, cy = intr[:4]
    z = np.where(p[:, 2] > 0, p[:, 2], np.nan)
    x, y = p[:, 0] / z, p[:, 1] / z
    if distortion == "equidistant":
        xd, yd, dxy, dk = _distortion_equi(x, y, intr[4:])
    elif distortion == "radtan":
        xd, yd, dxy, dk = _distortion_radtan(x, y, intr[4:])
    else:
        xd, yd = x, y
        dxy, dk = np.broadcast_to(np.eye(2), (len(x), 2, 2)), np.zeros((len(x), 2, 4))
    m = len(x)
    uv = np.empty((m, 2))
    uv[:, 0], uv[:, 1] = fx * xd + cx, fy * yd + cy
    J_i = np.zeros((m, 2, 8))
    J_i[:, 0, 0], J_i[:, 1, 1], J_i[:, 0, 2], J_i[:, 1, 3] = xd, yd, 1.0, 1.0
    f = np.array([fx, fy])[None, :, None]
    J_i[:, :, 4:] = f * dk
    # d uv / d p = f * dxy @ d(x, y)/dp, where d(x, y)/dp = [[1/z, 0, -x/z], [0, 1/z, -y/z]]
    inv_z = 1.0 / z
    nx, ny = -x * inv_z, -y * inv_z
    J_p = np.empty((m, 2, 3))
    J_p[:, :, 0] = dxy[:, :, 0] * inv_z[:, None]
    J_p[:, :, 1] = dxy[:, :, 1] * inv_z[:, None]
    J_p[:, :, 2] = dxy[:, :, 0] * nx[:, None] + dxy[:, :, 1] * ny[:, None]
    J_p *= f
    return uv, J_i, J_p


# -------------------------------------------------------------------------- normal equations
@dataclass(frozen=True, eq=False)
class BlockJacobian:
    """The Jacobian of the (M, 2) residuals by ``a`` (M, 2, K) and by their view's pose (M, 2, 6)."""

    Ja: FloatArray
    Jp: FloatArray
    view_i: IntArray
    n_views: int

    @property
    def shape(self) -> tuple[int, int]:
        return 2 * self.Ja.shape[0], self.Ja.shape[2] + 6 * self.n_views

    def view_slices(self) -> tuple[IntArray, IntArray]:
        """The rows sorted by view and every view's start in that order (V + 1)."""
        order = np.argsort(self.view_i, kind="stable")
        return order, np.searchsorted(self.view_i[order], np.arange(self.n_views + 1))

    def dense(self) -> FloatArray:
        """The whole Jacobian (2M, K + 6V) (for the singular fallback only)."""
        m, k = self.Ja.shape[0], self.Ja.shape[2]
        J = np.zeros((m, 2, k + 6 * self.n_views))
        J[:, :, :k] = self.Ja
        cols = k + 6 * self.view_i[:, None] + np.arange(6)
        J[np.arange(m)[:, None, None], np.arange(2)[None, :, None], cols[:, None, :]] = self.Jp
        return J.reshape(2 * m, -1)


@dataclass(frozen=True, eq=False)
class Normal:
    """``J^T J`` and ``J^T r`` in blocks: ``H_aa`` (K, K), ``H_ap`` (V, K, 6), ``H_pp`` (V, 6, 6),
    ``g_a`` (K,), ``g_p`` (V, 6)."""

    H_aa: FloatArray
    H_ap: FloatArray
    H_pp: FloatArray
    g_a: FloatArray
    g_p: FloatArray

    def diagonal(self) -> tuple[FloatArray, FloatArray]:
        return np.diagonal(self.H_aa).copy(), np.diagonal(self.H_pp, axis1=1, axis2=2).copy()


def normal_equations(J: BlockJacobian, r: FloatArray) -> Normal:
    """The blocks of ``J^T J`` and ``J^T r`` for residuals ``r`` (M, 2)."""
    m, k = J.Ja.shape[0], J.Ja.shape[2]
    A = J.Ja.reshape(2 * m, k)
    rr = r.reshape(2 * m)
    P = J.Jp.reshape(2 * m, 6)
    if np.all(J.view_i[1:] >= J.view_i[:-1]):  # rows already by view: slices, no copies
        As, rs = A, rr
        bounds = np.searchsorted(J.view_i, np.arange(J.n_views + 1))
    else:
        order, bounds = J.view_slices()
        rows = (2 * order[:, None] + np.arange(2)).ravel()
        P, As, rs = P[rows], A[rows], rr[rows]
    V = J.n_views
    H_ap, H_pp, g_p = np.zeros((V, k, 6)), np.zeros((V, 6, 6)), np.zeros((V, 6))
    for v in range(V):
        s, e = 2 * bounds[v], 2 * bounds[v + 1]
        Pv = P[s:e]
        H_pp[v] = Pv.T @ Pv
        H_ap[v] = As[s:e].T @ Pv
        g_p[v] = Pv.T @ rs[s:e]
    return Normal(A.T @ A, H_ap, H_pp, A.T @ rr, g_p)


def solve_damped(N: Normal, lam: float, d_a: FloatArray, d_p: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The step ``-(H + lam diag(d))^-1 g`` as ``(dx_a, dx_p (V, 6))`` by eliminating the poses;
    :class:`numpy.linalg.LinAlgError` when a block or the reduced system is singular."""
    D = N.H_pp + lam * (d_p[:, :, None] * np.eye(6))
    D_inv = np.linalg.inv(D)
    W = N.H_ap @ D_inv  # (V, K, 6)
    S = N.H_aa + lam * np.diag(d_a) - np.einsum("vkj,vlj->kl", W, N.H_ap)
    b = N.g_a - np.einsum("vkj,vj->k", W, N.g_p)
    dx_a = -np.linalg.solve(S, b) if len(b) else np.zeros(0)
    rhs = N.g_p + np.einsum("vkj,k->vj", N.H_ap, dx_a)
    dx_p = -np.einsum("vij,vj->vi", D_inv, rhs)
    return dx_a, dx_p


def leading_inverse(N: Normal, J: BlockJacobian) -> tuple[FloatArray, FloatArray]:
    """The columns of ``(J^T J)^-1`` of the ``K`` leading parameters: rows of ``a`` (K, K) and of
    every view's pose (V, 6, K); from the dense pseudo-inverse when ``J^T J`` is singular."""
    k = N.H_aa.shape[0]
    try:
        D_inv = np.linalg.inv(N.H_pp)
        W = N.H_ap @ D_inv
        S = N.H_aa - np.einsum("vkj,vlj->kl", W, N.H_ap)
        X_a = np.linalg.inv(S) if k else np.zeros((0, 0))
        X_p = -np.swapaxes(W, 1, 2) @ X_a  # D_inv H_pa X_a, D_inv symmetric
        if np.all(np.isfinite(X_a)) and np.all(np.isfinite(X_p)):
            return X_a, X_p
    except np.linalg.LinAlgError:
        pass
    Jd = J.dense()
    X = np.asarray(np.linalg.pinv(Jd.T @ Jd, rcond=1e-15, hermitian=True)[:, :k], np.float64)
    return X[:k], X[k:].reshape(J.n_views, 6, k)
