"""Alignment: Umeyama SE(3)/Sim(3), 4-DoF yaw, origin; known transforms are recovered."""

from __future__ import annotations

import numpy as np
import pytest
from metrics_gen import random_rotation, smooth_trajectory, transformed

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, IbiscapeWarning, Trajectory
from ibiscape_eval.core.rotations import matrix_from_quat, quat_from_rotvec, quat_multiply
from ibiscape_eval.metrics import Alignment, align, ate
from ibiscape_eval.metrics.alignment import umeyama


def _rz(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sim3_recovers_applied_similarity(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ref = smooth_trajectory(200, seed=seed)
    R, t, s = random_rotation(rng), rng.normal(scale=5, size=3), float(rng.uniform(0.2, 5))
    est = transformed(ref, R, t, s)  # est = S ref, so the alignment must be S^-1
    res = ate(est, ref, align="sim3")
    assert res.translation_m.max < 1e-9
    assert res.rotation_deg.max < 1e-6
    al = res.alignment
    assert al.method == "sim3" and al.n_used == 200
    np.testing.assert_allclose(al.scale, 1.0 / s, rtol=1e-12)
    np.testing.assert_allclose(al.transform[:3, :3], R.T, atol=1e-12)
    np.testing.assert_allclose(al.transform[:3, 3], -R.T @ t / s, atol=1e-9)
    inv = al.inverse()
    np.testing.assert_allclose(inv.scale, s, rtol=1e-12)
    np.testing.assert_allclose(inv.transform[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(inv.transform[:3, 3], t, atol=1e-9)


def test_se3_recovers_rigid_motion_and_keeps_scale() -> None:
    rng = np.random.default_rng(7)
    ref = smooth_trajectory(150, seed=7)
    R, t = random_rotation(rng), rng.normal(size=3)
    est = transformed(ref, R, t)
    res = ate(est, ref, align=Alignment.SE3)
    assert res.translation_m.rmse < 1e-9 and res.rotation_deg.max < 1e-6
    assert res.alignment.scale == 1.0
    np.testing.assert_allclose(res.alignment.transform[:3, :3], R.T, atol=1e-12)
    # se3 does not fix a scale error: the residual is the scale error itself.
    scaled = transformed(ref, R, t, 1.1)
    assert ate(scaled, ref, align="se3").translation_m.rmse > 1e-2


def test_umeyama_matches_evo() -> None:
    from evo.core.geometry import umeyama_alignment

    rng = np.random.default_rng(3)
    x = rng.normal(size=(50, 3))
    y = rng.normal(size=(50, 3)) + x @ random_rotation(rng).T
    for scale in (False, True):
        R, t, c = umeyama(x, y, with_scale=scale)
        R2, t2, c2 = umeyama_alignment(x.T, y.T, scale)
        np.testing.assert_allclose(R, R2, atol=1e-12)
        np.testing.assert_allclose(t, t2, atol=1e-12)
        np.testing.assert_allclose(c, c2, rtol=1e-12)


def test_umeyama_reflection_case_gives_a_rotation() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 3))
    y = x * np.array([1.0, 1.0, -1.0])  # a mirror image: the best proper rotation, not -1 det
    R, _, _ = umeyama(x, y, with_scale=False)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_yaw_recovers_yaw_and_translation_and_leaves_roll_error() -> None:
    ref = smooth_trajectory(200, seed=11)
    yaw, t = 0.7, np.array([3.0, -2.0, 0.5])
    roll_deg = 2.5
    q_roll = quat_from_rotvec([np.radians(roll_deg), 0.0, 0.0])
    moved = transformed(ref, _rz(yaw), t)
    # A constant roll offset in the body frame: not removable by a 4-DoF alignment.
    est = Trajectory(moved.stamps_ns, moved.pos_m, quat_multiply(moved.quat_xyzw, q_roll))
    res = ate(est, ref, align="yaw")
    np.testing.assert_allclose(res.alignment.transform[:3, :3], _rz(-yaw), atol=1e-12)
    np.testing.assert_allclose(res.alignment.transform[:3, 3], -_rz(-yaw) @ t, atol=1e-12)
    assert res.translation_m.max < 1e-9
    np.testing.assert_allclose(res.errors_deg, roll_deg, atol=1e-9)
    # A roll of the whole trajectory (world frame) is not removed either.
    tilted = transformed(ref, matrix_from_quat(quat_from_rotvec([0.05, 0.0, 0.0])), t)
    assert ate(tilted, ref, align="yaw").rotation_deg.min > 1.0


def test_origin_maps_first_pose() -> None:
    rng = np.random.default_rng(9)
    ref = smooth_trajectory(100, seed=9)
    R, t = random_rotation(rng), rng.normal(size=3)
    est = transformed(ref, R, t)
    res = ate(est, ref, align="origin")
    assert res.errors_m[0] < 1e-12 and res.errors_deg[0] < 1e-6
    assert res.translation_m.max < 1e-9  # a rigid motion is undone entirely
    np.testing.assert_allclose(res.alignment.transform[:3, :3], R.T, atol=1e-12)
    assert res.alignment.n_used == 1


def test_none_is_identity_and_apply_returns_new_object() -> None:
    ref = smooth_trajectory(50)
    al = align(ref, ref, method="none")
    np.testing.assert_array_equal(al.transform, np.eye(4))
    out = al.apply(ref)
    assert out is not ref
    np.testing.assert_array_equal(out.pos_m, ref.pos_m)
    with pytest.raises(ValueError):
        al.transform[0, 0] = 2.0  # results are frozen


def test_n_align_uses_first_poses_only() -> None:
    rng = np.random.default_rng(4)
    ref = smooth_trajectory(200, seed=4)
    R, t = random_rotation(rng), rng.normal(size=3)
    est = transformed(ref, R, t)
    pos = est.pos_m.copy()
    pos[100:] += 5.0  # the second half is wrong
    est = Trajectory(est.stamps_ns, pos, est.quat_xyzw)
    res = ate(est, ref, align="se3", n_align=100)
    assert res.alignment.n_used == 100
    assert res.errors_m[:100].max() < 1e-9
    np.testing.assert_allclose(res.errors_m[100:], np.sqrt(3) * 5.0, rtol=1e-9)
    with pytest.warns(IbiscapeWarning, match="exceeds"):
        assert align(est, ref, n_align=10_000).n_used == 200
    with pytest.raises(IbiscapeError, match="n_align"):
        align(est, ref, n_align=0)


def _line(n: int = 20, *, vertical: bool = False) -> Trajectory:
    s = np.arange(n, dtype=float)
    pos = np.stack([0 * s, 0 * s, s], 1) if vertical else np.stack([s, 2 * s, 0.5 * s], 1)
    return Trajectory(np.arange(n, dtype=np.int64) * 10**8, pos, np.tile([0, 0, 0, 1.0], (n, 1)))


@pytest.mark.parametrize("method", ["se3", "sim3"])
def test_collinear_positions_are_degenerate(method: str) -> None:
    line = _line()
    with pytest.raises(DegenerateInputError, match=r'collinear.*use align="yaw" or align="origin"'):
        align(line, line, method=method)


def test_all_equal_positions_are_degenerate_for_every_fit() -> None:
    still = Trajectory(np.arange(10, dtype=np.int64), np.ones((10, 3)),
                       np.tile([0, 0, 0, 1.0], (10, 1)))
    for method in ("se3", "sim3", "yaw"):
        with pytest.raises(DegenerateInputError, match="are equal"):
            align(still, still, method=method)
    # origin needs only one pose
    assert align(still, still, method="origin").n_used == 1


def test_yaw_accepts_a_line_but_not_a_vertical_one() -> None:
    line = _line()
    assert align(line, line, method="yaw").transform[0, 0] == pytest.approx(1.0)
    vertical = _line(vertical=True)
    with pytest.raises(DegenerateInputError, match="horizontal positions"):
        align(vertical, vertical, method="yaw")


def test_unknown_method_and_unequal_lengths() -> None:
    ref = smooth_trajectory(20)
    with pytest.raises(IbiscapeError, match="unknown alignment 'affine'"):
        align(ref, ref, method="affine")
    with pytest.raises(IbiscapeError, match="equal length"):
        align(ref, ref.take(np.arange(10)))
