"""The calibration solver's shortcuts give what the long way gives: the initialisation's view
poses beside a PnP of every view, normal equations and per-view sums of rows ordered by view
beside any order, the numbering consensus as one distance matrix beside the pairwise distance,
and a Levenberg-Marquardt solve that leaves the last Jacobian to its caller."""

from __future__ import annotations

import importlib
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from test_calib_speed_jacobian import _problem

from ibiscape_eval.calib._lsq import BlockJacobian, normal_equations
from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.core.so3 import exp_so3
from ibiscape_eval.io.kalibr import read_target

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "opencv_stereo_checkerboard_640x480"

#: the module (``ibiscape_eval.calib.calibrate`` is also the function the package exports)
C = importlib.import_module("ibiscape_eval.calib.calibrate")


@lru_cache(maxsize=1)
def _real_stereo():
    """OpenCV's 13 real stereo photos: the target and both cameras' detections."""
    import cv2

    target = read_target(REAL / "target.yaml")
    obs = [C.Observations(side, (640, 480), [detect_corners(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), target,
                                                            photo=True)
                                             for f in sorted(REAL.glob(f"{side}*.jpg"))])
           for side in ("left", "right")]
    return target, obs


def _rot_deg(A: np.ndarray, B: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(A.T @ B) - 1.0) / 2.0, -1.0, 1.0))))


def test_initial_poses_agree_with_pnp_of_every_view():
    """The poses ``calibrateCamera`` returns for the views it used are what a PnP of each view
    with its camera finds (within 0.05 deg and 0.2 % of the distance on 13 real stereo photos)."""
    target, obs = _real_stereo()
    obj = target.object_points()
    usable = C._usable_views(obs, target, target.n_corners, len(obs[0].detections))
    inits = C._init_cameras(obs, target, usable, "radtan")
    cams = [c for c, _ in inits]
    dets = [list(o.detections) for o in obs]
    given = C._camera_poses(obs, cams, dets, usable, obj, 5.0, [p for _, p in inits])
    solved = C._camera_poses(obs, cams, dets, usable, obj, 5.0)
    for n in range(2):
        assert set(inits[n][1]) == set(usable[n]) and set(given[n]) == set(solved[n])
        for v, T in solved[n].items():
            assert given[n][v] is inits[n][1][v]
            assert _rot_deg(T[:3, :3], given[n][v][:3, :3]) < 0.05
            assert np.linalg.norm(T[:3, 3] - given[n][v][:3, 3]) < 2e-3 * np.linalg.norm(T[:3, 3])


def _by_view(prob):
    order = np.argsort(prob.view_i, kind="stable")
    return C._Problem(prob.cams, prob.obj[order], prob.uv[order], prob.cam_i[order], prob.view_i[order],
                      prob.n_views)


def test_normal_equations_do_not_depend_on_the_row_order():
    prob, intr, chain, poses = _problem("radtan")
    assert np.any(np.diff(prob.view_i) < 0)  # camera by camera: views not in order
    sorted_prob = _by_view(prob)
    a = normal_equations(prob.jacobian(intr, chain, poses), prob.residuals(intr, chain, poses))
    b = normal_equations(sorted_prob.jacobian(intr, chain, poses), sorted_prob.residuals(intr, chain, poses))
    for x, y in zip((a.H_aa, a.H_ap, a.H_pp, a.g_a, a.g_p), (b.H_aa, b.H_ap, b.H_pp, b.g_a, b.g_p), strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-9)


def test_normal_equations_with_a_view_without_rows():
    prob, intr, chain, poses = _by_view(_problem("radtan")[0]), *_problem("radtan")[1:]
    J = prob.jacobian(intr, chain, poses)
    r = prob.residuals(intr, chain, poses)
    keep = prob.view_i != 2
    Jk = BlockJacobian(J.Ja[keep], J.Jp[keep], J.view_i[keep], J.n_views)
    N = normal_equations(Jk, r[keep])
    assert np.all(N.H_pp[2] == 0) and np.all(N.H_ap[2] == 0) and np.all(N.g_p[2] == 0)
    dense = Jk.dense()
    np.testing.assert_allclose(dense.T @ dense[:, :], np.block(
        [[N.H_aa, np.concatenate(list(N.H_ap), axis=1)],
         [np.concatenate(list(N.H_ap), axis=1).T, _block_diag(N.H_pp)]]), rtol=1e-10, atol=1e-8)


def _block_diag(blocks: np.ndarray) -> np.ndarray:
    n = len(blocks)
    out = np.zeros((6 * n, 6 * n))
    for i, b in enumerate(blocks):
        out[6 * i:6 * i + 6, 6 * i:6 * i + 6] = b
    return out


@pytest.mark.parametrize("ordered", [True, False])
def test_per_view_sums_equal_unbuffered_addition(ordered):
    rng = np.random.default_rng(3)
    rows = np.sort(rng.integers(0, 7, 200))
    rows = rows[rows != 4]  # a view without rows
    if not ordered:
        rows = rng.permutation(rows)
    values = rng.normal(size=(len(rows), 2, 3))
    ref = np.zeros((9, 2, 3))
    np.add.at(ref, rows, values)
    np.testing.assert_allclose(C._per_view_sums(values, rows, 9), ref, rtol=1e-12, atol=1e-12)


def test_pose_distance_matrix_is_the_pairwise_distance():
    rng = np.random.default_rng(5)
    R = exp_so3(rng.normal(0, 0.5, (6, 3)))
    t = rng.normal(0, 1.0, (6, 3))
    D = C._pose_distances(R[:2], t[:2], R, t, 2.0)
    for a in range(2):
        for b in range(6):
            want = _rot_deg(R[a], R[b]) + np.linalg.norm(t[a] - t[b]) / 0.02
            assert abs(D[a, b] - want) < 1e-5 + 1e-9 * want  # arccos near 1: 1e-6 deg
    assert np.all(np.abs(np.diag(D[:, :2])) < 1e-5)


def test_the_last_jacobian_is_left_to_the_caller(monkeypatch):
    """A solve that converges returns no Jacobian; the refinement's solution carries the one at
    its parameters (the covariance's)."""
    target, obs = _real_stereo()
    solutions, refined = [], []
    lm, refine = C._levenberg_marquardt, C._refine
    monkeypatch.setattr(C, "_levenberg_marquardt", lambda *a, **k: solutions.append(lm(*a, **k)) or solutions[-1])
    monkeypatch.setattr(C, "_refine", lambda *a, **k: refined.append(refine(*a, **k)) or refined[-1])
    C.calibrate(target, obs)
    assert solutions and all(s.jac is None for s in solutions)
    ref = refined[0]
    J = ref.prob.jacobian(ref.intr, ref.chain, ref.poses)
    np.testing.assert_array_equal(ref.sol.jac.Ja, J.Ja)
    np.testing.assert_array_equal(ref.sol.jac.Jp, J.Jp)
