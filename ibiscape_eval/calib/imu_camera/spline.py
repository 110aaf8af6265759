"""Uniform cumulative cubic B-splines on SO(3) x R^3, evaluated on batches of local control points.

A trajectory ``T_target_imu(t)`` is a rotation spline and a position spline sharing uniform knots
``t_k = t0 + k dt``.  Segment ``i`` (``u = (t - t_i) / dt`` in [0, 1)) uses control points
``i .. i+3``.

- Position: the standard uniform cubic B-spline ``p(u) = sum_j b_j(u) P_{i+j}``.
- Rotation: the cumulative form (Kim et al. 1995; Sommer et al., CVPR 2020, "Efficient derivative
  computation for cumulative B-splines on Lie groups")::

      R(u) = R_i prod_{j=1..3} Exp(B~_j(u) d_j),   d_j = Log(R_{i+j-1}^T R_{i+j})

  whose body angular velocity (``R^T dR/dt = [w]x``) follows the recursion
  ``w_1 = B~'_1 d_1``, ``w_j = A_j^T w_{j-1} + B~'_j d_j`` with ``A_j = Exp(B~_j d_j)``.

Every function works on *gathered* control points, shape ``(n, 4, ...)`` (one row per sample), so
that the solver can perturb one local control point for all samples at once (vectorised numeric
Jacobians).  ``u`` may leave [0, 1] slightly (a time-offset perturbation): the polynomials extend.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.so3 import exp_so3, hat, left_jacobian_so3, log_so3

__all__ = ["basis", "cumulative_basis", "position", "rotation", "rotation_jacobians"]

FloatArray = npt.NDArray[np.float64]


def basis(u: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cubic B-spline weights and their first two u-derivatives, each (n, 4)."""
    u2, u3 = u * u, u * u * u
    b = np.stack(((1 - u) ** 3, 3 * u3 - 6 * u2 + 4, -3 * u3 + 3 * u2 + 3 * u + 1, u3), -1) / 6.0
    db = np.stack((-3 * (1 - u) ** 2, 9 * u2 - 12 * u, -9 * u2 + 6 * u + 3, 3 * u2), -1) / 6.0
    ddb = np.stack((6 * (1 - u), 18 * u - 12, -18 * u + 6, 6 * u), -1) / 6.0
    return b, db, ddb


def cumulative_basis(u: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Cumulative weights ``B~_1..3`` and their u-derivatives, each (n, 3)."""
    u2, u3 = u * u, u * u * u
    B = np.stack((5 + 3 * u - 3 * u2 + u3, 1 + 3 * u + 3 * u2 - 2 * u3, u3), -1) / 6.0
    dB = np.stack((3 - 6 * u + 3 * u2, 3 + 6 * u - 6 * u2, 3 * u2), -1) / 6.0
    return B, dB


def rotation(R_ctrl: FloatArray, u: FloatArray, dt_s: float, *,
             angular_velocity: bool = True) -> tuple[FloatArray, FloatArray | None]:
    """Rotation (n, 3, 3) and body angular velocity (n, 3) [rad/s] of gathered control points.

    Parameters
    ----------
    R_ctrl : ndarray, shape (n, 4, 3, 3)
        The four control rotations of each sample's segment.
    u : ndarray, shape (n,)
        Position in the segment.
    dt_s : float
        Knot spacing, seconds.
    """
    B, dB = cumulative_basis(u)
    d = log_so3(np.swapaxes(R_ctrl[:, :3], -1, -2) @ R_ctrl[:, 1:])
    A = exp_so3(B[..., None] * d)  # (n, 3, 3, 3)
    R = R_ctrl[:, 0] @ A[:, 0] @ A[:, 1] @ A[:, 2]
    if not angular_velocity:
        return R, None
    w = dB[:, 0, None] * d[:, 0]
    for j in (1, 2):  # three fixed steps of the recursion, vectorised over samples
        w = np.einsum("nki,nk->ni", A[:, j], w) + dB[:, j, None] * d[:, j]
    return R, w / dt_s


def _left_jacobian_inverse(phi: FloatArray) -> FloatArray:
    """``J_l(phi)^-1 = I - [phi]x / 2 + e(t) [phi]x^2``, ``e = 1/t^2 - (1 + cos t) / (2 t sin t)``
    (Taylor series below 0.01 rad), batched (..., 3) -> (..., 3, 3)."""
    th2 = np.einsum("...i,...i->...", phi, phi)
    small = th2 < 1e-4
    th = np.sqrt(np.where(small, 1.0, th2))
    e = np.where(small, 1.0 / 12.0 + th2 / 720.0 + th2 * th2 / 30240.0,
                 1.0 / (th * th) - (1.0 + np.cos(th)) / (2.0 * th * np.sin(th)))
    K = hat(phi)
    return np.eye(3) - 0.5 * K + e[..., None, None] * (K @ K)


def rotation_jacobians(R_ctrl: FloatArray, u: FloatArray, dt_s: float
                       ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Rotation (n, 3, 3), body angular velocity (n, 3) and their exact derivatives by the four
    local control points, each moved on the right (``R_j <- R_j Exp(delta_j)``, ``delta`` stacked
    (12,)): ``J_R`` (n, 3, 12) with ``R(delta) ~ R Exp(J_R delta)`` and ``J_w`` (n, 3, 12) [rad/s].

    Chain rule through ``d_j = Log(R_{j-1}^T R_j)`` (``dd_j = J_r^-1(d_j) delta_j - J_l^-1(d_j)
    delta_{j-1}``), ``A_j = Exp(B~_j d_j)`` (``A_j Exp(J_r(B~_j d_j) B~_j dd_j)``) and the angular
    velocity's recursion (``d(A_j^T w) = [A_j^T w]x J_r(B~_j d_j) B~_j dd_j``): one evaluation
    where central differences took 24.
    """
    B, dB = cumulative_basis(u)
    d = log_so3(np.swapaxes(R_ctrl[:, :3], -1, -2) @ R_ctrl[:, 1:])  # (n, 3, 3): d_1..d_3
    phi = B[..., None] * d
    A = exp_so3(phi)  # (n, 3, 3, 3)
    Jr_phi = np.swapaxes(left_jacobian_so3(phi), -1, -2) * B[..., None, None]  # J_r(B d) B
    Jl_inv = _left_jacobian_inverse(d)
    Jr_inv = np.swapaxes(Jl_inv, -1, -2)  # J_r(d) = J_l(-d) = J_l(d)^T
    # right factors: P_0 = A_1 A_2 A_3, P_1 = A_2 A_3, P_2 = A_3, P_3 = I
    P2 = A[:, 2]
    P1 = A[:, 1] @ P2
    P0 = A[:, 0] @ P1
    R = R_ctrl[:, 0] @ P0
    Pt = np.swapaxes(np.stack((P1, P2), 1), -1, -2)
    K = np.concatenate((Pt @ Jr_phi[:, :2], Jr_phi[:, 2:]), 1)  # (n, 3, 3, 3): K_j, j = 1..3
    n = u.shape[0]
    J_R = np.zeros((n, 3, 12))
    J_R[..., 0:3] = np.swapaxes(P0, -1, -2)
    # angular velocity: w_1 = dB_1 d_1, w_j = A_j^T w_{j-1} + dB_j d_j; Om_j = dw / dd_j
    eye = np.eye(3)
    w = dB[:, 0, None] * d[:, 0]
    Om = [dB[:, 0, None, None] * eye]
    for j in (1, 2):
        At = np.swapaxes(A[:, j], -1, -2)
        v = np.einsum("nij,nj->ni", At, w)
        Om = [At @ o for o in Om]
        Om.append(hat(v) @ Jr_phi[:, j] + dB[:, j, None, None] * eye)
        w = v + dB[:, j, None] * d[:, j]
    J_w = np.zeros((n, 3, 12))
    for j in range(3):  # d_{j+1} depends on control points j (J_l^-1) and j + 1 (J_r^-1)
        J_R[..., 3 * j : 3 * j + 3] -= K[:, j] @ Jl_inv[:, j]
        J_R[..., 3 * j + 3 : 3 * j + 6] += K[:, j] @ Jr_inv[:, j]
        J_w[..., 3 * j : 3 * j + 3] -= Om[j] @ Jl_inv[:, j]
        J_w[..., 3 * j + 3 : 3 * j + 6] += Om[j] @ Jr_inv[:, j]
    return R, w / dt_s, J_R, J_w / dt_s


def position(P_ctrl: FloatArray, u: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Position (n, 3) [m], velocity [m/s] and acceleration [m/s^2] of gathered control points."""
    b, db, ddb = basis(u)
    p = np.einsum("nj,njk->nk", b, P_ctrl)
    v = np.einsum("nj,njk->nk", db, P_ctrl) / dt_s
    a = np.einsum("nj,njk->nk", ddb, P_ctrl) / (dt_s * dt_s)
    return p, v, a
