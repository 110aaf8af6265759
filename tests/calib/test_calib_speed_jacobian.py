"""The calibration solver's exact Jacobian and its block elimination against plain references:
central finite differences of the residuals, a dense solve of the same damped normal equations,
the dense inverse of ``J^T J``, and scipy's rotation vectors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ibiscape_eval.calib._lsq import (
    leading_inverse,
    normal_equations,
    rotvec_from_matrix,
    solve_damped,
)
from ibiscape_eval.calib.calibrate import _Problem
from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.so3 import exp_so3

MODELS = {"radtan": (-0.1, 0.02, 0.001, -0.002), "equidistant": (0.01, -0.02, 0.003, 0.001)}


def _problem(distortion: str, free: bool = True) -> tuple[_Problem, np.ndarray, np.ndarray, np.ndarray]:
    """Three chained cameras, four views of 30 board points each, arbitrary detected corners."""
    rng = np.random.default_rng(0)
    c = MODELS[distortion]
    cams = [CameraModel(640, 480, 500, 505, 320, 240, distortion, c),
            CameraModel(640, 480, 510, 500, 330, 235, distortion, c),
            CameraModel(640, 480, 490, 495, 310, 250, distortion, c)]
    n_views, n_pts = 4, 30
    obj = np.c_[rng.uniform(-0.5, 0.5, (n_pts, 2)), np.zeros(n_pts)]
    grid = [(n, v) for n in range(3) for v in range(n_views)]
    O = np.concatenate([obj] * len(grid))
    cam_i = np.repeat([n for n, _ in grid], n_pts).astype(np.int64)
    view_i = np.repeat([v for _, v in grid], n_pts).astype(np.int64)
    uv = rng.normal(300.0, 50.0, (len(O), 2))
    prob = _Problem(cams, O, uv, cam_i, view_i, n_views, free_intrinsics=free, free_chain=free)
    intr = np.array([[k.fx, k.fy, k.cx, k.cy, *k.coeffs] for k in cams])
    chain = np.array([[0.01, -0.02, 0.03, -0.2, 0.01, 0.02], [0.02, 0.01, -0.01, -0.25, -0.01, 0.0]])
    poses = np.c_[rng.normal(0, 0.3, (n_views, 3)), rng.normal(0, 0.2, (n_views, 2)), rng.uniform(2, 3, n_views)]
    return prob, intr, chain, poses


@pytest.mark.parametrize("distortion", ["radtan", "equidistant"])
@pytest.mark.parametrize("free", [True, False])
def test_exact_jacobian_matches_finite_differences(distortion, free):
    prob, intr, chain, poses = _problem(distortion, free)
    parts = [intr.ravel(), chain.ravel()] if free else []
    x0 = np.concatenate([*parts, poses.ravel()])

    def f(x):
        i, c, p = prob.split(x, intr, chain)
        return prob.residuals(i, c, p).ravel()

    J = prob.jacobian(intr, chain, poses).dense()
    num = np.zeros_like(J)
    for j in range(len(x0)):
        h = 1e-6 * max(abs(x0[j]), 1.0)
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        num[:, j] = (f(xp) - f(xm)) / (2 * h)
    assert J.shape == num.shape
    scale = np.abs(num).max(axis=0) + 1e-9
    assert np.max(np.abs(J - num).max(axis=0) / scale) < 1e-5


def test_block_elimination_equals_dense_solve():
    prob, intr, chain, poses = _problem("radtan")
    J = prob.jacobian(intr, chain, poses)
    r = prob.residuals(intr, chain, poses)
    N = normal_equations(J, r)
    d_a, d_p = N.diagonal()
    dx_a, dx_p = solve_damped(N, 0.1, d_a, d_p)
    Jd = J.dense()
    H = Jd.T @ Jd
    dense = -np.linalg.solve(H + 0.1 * np.diag(np.diag(H)), Jd.T @ r.ravel())
    np.testing.assert_allclose(np.concatenate([dx_a, dx_p.ravel()]), dense, rtol=1e-7, atol=1e-10)
    X_a, X_p = leading_inverse(N, J)
    k = len(dx_a)
    inv = np.linalg.inv(H)[:, :k]
    np.testing.assert_allclose(X_a, inv[:k], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(X_p.reshape(-1, k), inv[k:], rtol=1e-6, atol=1e-12)


def test_rotation_vectors_agree_with_scipy():
    rng = np.random.default_rng(1)
    w = np.r_[rng.normal(0, 1.0, (50, 3)), rng.normal(0, 1e-6, (5, 3)), [[0.0, 0.0, 0.0], [3.1, 0.0, 0.0]]]
    np.testing.assert_allclose(exp_so3(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
    for v in w[:20]:
        R = Rotation.from_rotvec(v).as_matrix()
        np.testing.assert_allclose(rotvec_from_matrix(R), Rotation.from_matrix(R).as_rotvec(), atol=1e-12)
