"""The camera-IMU problem's exact derivatives and its blocked normal matrix, against central
differences and a plain sparse assembly (the solver's speed rests on them; a wrong sign would still
converge, slowly, to the same place, so the derivatives are checked directly)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ibiscape_eval.calib.imu_camera import ImuCameraOptions
from ibiscape_eval.calib.imu_camera.calibrate import (
    _factor,
    _initial_alignment,
    _initial_state,
    _layout,
    _problem,
)
from ibiscape_eval.calib.imu_camera.problem import (
    Problem,
    State,
    camera_block,
    imu_block,
    normal_equations,
    prior_block,
    residuals,
)
from ibiscape_eval.calib.imu_camera.spline import rotation, rotation_jacobians
from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
from ibiscape_eval.core.so3 import exp_so3, log_so3
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration
from ibiscape_eval.sim.config import MotionSpec


def test_rotation_jacobians_match_central_differences():
    rng = np.random.default_rng(0)
    n, dt, h = 40, 0.05, 1e-6
    R_ctrl = exp_so3(rng.normal(size=(n, 4, 3)) * 0.4)
    u = rng.uniform(-0.05, 1.05, n)  # a time-offset step may leave [0, 1] slightly
    R, w, J_R, J_w = rotation_jacobians(R_ctrl, u, dt)
    R0, w0 = rotation(R_ctrl, u, dt)
    assert np.allclose(R, R0, atol=1e-14) and w0 is not None and np.allclose(w, w0, atol=1e-12)
    for col in range(12):
        j, a = divmod(col, 3)
        e = np.zeros(3)
        e[a] = h
        plus, minus = R_ctrl.copy(), R_ctrl.copy()
        plus[:, j] = R_ctrl[:, j] @ exp_so3(e)
        minus[:, j] = R_ctrl[:, j] @ exp_so3(-e)
        (Rp, wp), (Rm, wm) = rotation(plus, u, dt), rotation(minus, u, dt)
        assert wp is not None and wm is not None
        eps = (log_so3(np.swapaxes(R0, 1, 2) @ Rp) - log_so3(np.swapaxes(R0, 1, 2) @ Rm)) / (2 * h)
        assert np.allclose(J_R[..., col], eps, atol=1e-8), col
        assert np.allclose(J_w[..., col], (wp - wm) / (2 * h), atol=1e-7 * np.abs(J_w).max()), col


@pytest.fixture(scope="module")
def problem() -> tuple[Problem, State]:
    """The initial problem of a short simulated drive (two cameras, the intrinsics refined)."""
    cfg = preset("svi", "calibration", "clear", duration_s=6.0, seed=2, motion=MotionSpec(bumps=True))
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=320, height_px=320, rate_hz=10.0)
                                     for c in cfg.cameras))
    sc = calibration_scene(simulate_calibration(cfg, timeshifts_s={"rgbL": 0.01, "rgbR": -0.01}),
                           noise_px=0.2, min_spacing_px=4.0)
    opts = ImuCameraOptions(sigma_px=0.2, refine_intrinsics=True, knot_rate_hz=20.0)
    corners = np.asarray(sc.corners_target_m, np.float64)
    init = _initial_alignment(sc.observations, sc.imu, corners, opts)
    layout = _layout(init, opts)
    prob = _problem(sc.observations, sc.imu, sc.noise, corners, init, layout, opts)
    return prob, _initial_state(prob, init, single_axis=False)


def _stacked(prob: Problem, st: State) -> np.ndarray:
    return np.concatenate([r.ravel() for r in residuals(prob, st).values()])


def test_normal_equations_match_central_differences_of_the_residuals(problem):
    """Along random steps ``d``: ``|J d|^2 = d^T H d`` and ``J^T r . d`` from differences of the
    residuals (every block: IMU, cameras with their intrinsics, priors)."""
    prob, st = problem
    H, g, c0 = normal_equations(prob, st)
    Hs = H.sparse()
    r0 = _stacked(prob, st)
    assert c0 == pytest.approx(0.5 * float(r0 @ r0))
    rng = np.random.default_rng(1)
    for _ in range(3):
        d = rng.normal(size=prob.n_params) * 1e-7
        Jd = (_stacked(prob, st.retract(prob, d)) - _stacked(prob, st.retract(prob, -d))) / 2
        assert float(d @ (Hs @ d)) == pytest.approx(float(Jd @ Jd), rel=1e-5)
        assert float(g @ d) == pytest.approx(float(r0 @ Jd), rel=1e-5)


def test_blocked_normal_matrix_is_the_plain_sum(problem):
    """The band / border / dense blocks hold the same ``J^T J`` as a plain sparse sum of every
    residual's outer product, and the banded Schur solve agrees with a sparse LU."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    prob, st = problem
    H, g, _ = normal_equations(prob, st)
    blocks = [imu_block(prob, st, jac=True)[1:3]]
    for c in range(len(prob.cams)):
        _, Jc, colc, _ = camera_block(prob, st, c, jac=True)
        assert Jc is not None
        blocks.append((Jc.reshape(Jc.shape[0], -1, Jc.shape[-1]), colc))
    _, Jp, colp = prior_block(prob, st)
    blocks.append((Jp[:, None, :], colp))
    rows, cols, vals = [], [], []
    for J, col in blocks:
        assert J is not None and col is not None
        Hb = np.swapaxes(J, 1, 2) @ J
        rows.append(np.broadcast_to(col[:, :, None], Hb.shape).ravel())
        cols.append(np.broadcast_to(col[:, None, :], Hb.shape).ravel())
        vals.append(Hb.ravel())
    n = prob.n_params
    plain = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    assert abs(H.sparse() - plain).max() <= 1e-12 * abs(plain).max()
    assert np.array_equal(H.diagonal(), H.sparse().diagonal())
    damped = H.plus_diagonal(1e-6 * H.diagonal() + 1e-9)
    x = _factor(damped).solve(g)
    ref = splu(damped.sparse(), permc_spec="COLAMD").solve(g)
    assert np.allclose(x, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
