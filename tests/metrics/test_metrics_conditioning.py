"""Alignment conditioning: how well the alignment is determined, and the warning when the rotation
error is the alignment's (a 2 mm cloud must not print a 34 deg rotation error without a word)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from metrics_gen import random_rotation, smooth_trajectory, transformed
from scipy.spatial.transform import Rotation

from ibiscape_eval.core import IbiscapeWarning, Trajectory, ns_from_s
from ibiscape_eval.metrics import ate, compare, rpe
from ibiscape_eval.metrics.alignment import align


def _still_cloud(n: int = 600, seed: int = 3) -> tuple[Trajectory, Trajectory]:
    """A standing vehicle: ground truth and estimate are two independent ~1 mm clouds around one
    point, the estimate's orientation equal to the truth's (its real rotation error is 0)."""
    rng = np.random.default_rng(seed)
    t = ns_from_s(10.0 + np.arange(n) * 0.05)
    centre = np.array([12.0, -4.0, 1.5])
    q = np.tile(Rotation.from_euler("z", 30, degrees=True).as_quat(), (n, 1))
    gt = Trajectory(t, centre + rng.normal(0, 0.001, (n, 3)), q, "gt")
    est = Trajectory(t, centre + rng.normal(0, 0.001, (n, 3)), q, "est")
    return est, gt


def _with_rotation_noise(traj: Trajectory, deg: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = Rotation.from_rotvec(rng.normal(0, math.radians(deg), (len(traj), 3)))
    return (d * Rotation.from_quat(traj.quat_xyzw)).as_quat()


def test_two_mm_cloud_warns_and_reports_its_conditioning() -> None:
    est, gt = _still_cloud()
    with pytest.warns(IbiscapeWarning, match="rotation of the se3 alignment is poorly determined"):
        res = ate(est, gt, align="se3")
    # the confident wrong number: a large rotation error that is all alignment
    assert res.rotation_deg.rmse > 10.0
    cond = res.alignment.conditioning
    assert cond is not None and cond.method == "se3"
    assert np.all(cond.spread_m < 0.002)  # a 2 mm cloud
    assert cond.rotation_sigma_total_deg > 5.0
    assert len(res.warnings) == 1 and 'align="yaw"' in res.warnings[0]
    doc = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert doc["warnings"] == list(res.warnings)
    assert doc["alignment_conditioning"]["rotation_sigma_total_deg"] > 5.0
    assert len(doc["alignment_conditioning"]["rotation_sigma_deg"]) == 3


def test_well_conditioned_trajectory_does_not_warn() -> None:
    ref = smooth_trajectory(400, seed=2)
    rng = np.random.default_rng(4)
    R = random_rotation(rng)
    moved = transformed(ref, R, np.array([3.0, -1.0, 2.0]))
    est = Trajectory(moved.stamps_ns, moved.pos_m + rng.normal(0, 0.02, (len(ref), 3)),
                     _with_rotation_noise(moved, 1.0, 5), "est")
    with warnings.catch_warnings():
        warnings.simplefilter("error", IbiscapeWarning)
        res = ate(est, ref, align="se3")
        assert rpe(est, ref, align="sim3").warnings == ()
    assert res.warnings == () and res.to_dict()["warnings"] == []
    cond = res.alignment.conditioning
    assert cond is not None and cond.rotation_sigma_total_deg < 0.1
    assert 0.015 < cond.sigma_pos_m < 0.025  # the 2 cm position noise per axis


def _line(n: int, seed: int) -> tuple[Trajectory, Trajectory]:
    """A 40 m straight drive with 1 cm estimate noise and 1 deg orientation noise."""
    rng = np.random.default_rng(seed)
    t = ns_from_s(np.arange(n) * 0.1)
    pos = np.column_stack([np.linspace(0, 40, n), 0.001 * np.sin(np.arange(n)), np.zeros(n)])
    q = np.tile([0, 0, 0, 1.0], (n, 1))
    gt = Trajectory(t, pos, q, "gt")
    est = Trajectory(t, pos + rng.normal(0, 0.01, (n, 3)), _with_rotation_noise(gt, 1.0, seed),
                     "est")
    return est, gt


def test_straight_line_yaw_alignment_does_not_warn() -> None:
    est, gt = _line(400, 7)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IbiscapeWarning)
        res = ate(est, gt, align="yaw")
    cond = res.alignment.conditioning
    assert cond is not None and cond.rotation_sigma_total_deg < 0.01
    assert res.warnings == ()


def test_straight_line_se3_warns_about_the_roll_about_the_line() -> None:
    est, gt = _line(400, 7)
    with pytest.warns(IbiscapeWarning, match="about the x axis"):
        res = ate(est, gt, align="se3")
    cond = res.alignment.conditioning
    assert cond is not None
    # undetermined about the line, well determined about the two other axes
    assert cond.rotation_sigma_deg[0] > 5.0 and cond.rotation_sigma_deg[1] < 0.05
    assert abs(cond.rotation_axes[0][0]) > 0.99


def test_rotation_sigma_covers_the_truth_over_seeds() -> None:
    """The reported 1-sigma of the rotation, translation and scale covers the true alignment
    error as often as a Gaussian says (68 % / 95 %), over 300 seeded noise draws."""
    base = smooth_trajectory(40, seed=1)
    R0 = random_rotation(np.random.default_rng(0))
    t0 = np.array([1.0, 2.0, -0.5])
    s0 = 1.3
    truth = transformed(base, R0, t0, s0)
    z_rot, z_t, z_s = [], [], []
    for seed in range(300):
        rng = np.random.default_rng(100 + seed)
        est = Trajectory(base.stamps_ns, base.pos_m, base.quat_xyzw)
        ref = Trajectory(truth.stamps_ns, truth.pos_m + rng.normal(0, 0.1, truth.pos_m.shape),
                         truth.quat_xyzw)
        al = align(est, ref, method="sim3")
        c = al.conditioning
        assert c is not None and c.scale_sigma is not None
        d = Rotation.from_matrix(al.rotation @ R0.T).as_rotvec()  # in the reference frame
        z_rot.append(float(d @ np.linalg.solve(c.rotation_cov_rad2, d)))
        z_t.append(np.abs(al.translation_m - t0) / c.translation_sigma_m)
        z_s.append(abs(al.scale - s0) / c.scale_sigma)
    z_rot_a, z_t_a, z_s_a = np.array(z_rot), np.concatenate(z_t), np.array(z_s)
    # chi-square with 3 dof: P(<= 3.527) = 0.683, P(<= 8.025) = 0.954
    assert 0.60 < np.mean(z_rot_a <= 3.527) < 0.76
    assert 0.90 < np.mean(z_rot_a <= 8.025) < 0.985
    for z in (z_t_a, z_s_a):
        assert 0.60 < np.mean(z <= 1.0) < 0.76
        assert 0.90 < np.mean(z <= 2.0) < 0.985


def test_correlated_residuals_inflate_the_sigma_not_undercover() -> None:
    """Drift-like AR(1) residuals (rho 0.9): the sigma of independent noise covered the true
    rotation 4 % of the time; inflated by the residuals' autocorrelation it covers at least as
    often as it says (conservative: ~78 % / 98 %)."""
    base = smooth_trajectory(400, rate_hz=20.0, seed=1)
    R0 = random_rotation(np.random.default_rng(0))
    truth = transformed(base, R0, np.array([1.0, 2.0, -0.5]))
    z = []
    for seed in range(200):
        e = np.random.default_rng(7000 + seed).normal(0, 0.05, (400, 3))
        noise = np.zeros_like(e)
        for i in range(400):  # AR(1): 400 rows, a test-side loop
            noise[i] = (0.9 * noise[i - 1] if i else 0.0) + e[i]
        al = align(base, Trajectory(truth.stamps_ns, truth.pos_m + noise, truth.quat_xyzw))
        c = al.conditioning
        assert c is not None and c.residual_rho > 0.7 and c.variance_inflation > 5
        d = Rotation.from_matrix(al.rotation @ R0.T).as_rotvec()
        z.append(float(d @ np.linalg.solve(c.rotation_cov_rad2, d)))
    za = np.array(z)
    assert 0.65 < np.mean(za <= 3.527) < 0.88 and 0.93 < np.mean(za <= 8.025) <= 1.0


def test_yaw_sigma_covers_the_truth_over_seeds() -> None:
    base = smooth_trajectory(40, seed=6)
    yaw = math.radians(35.0)
    R0 = Rotation.from_euler("z", yaw).as_matrix()
    truth = transformed(base, R0, np.array([0.5, 0.0, 1.0]))
    z = []
    for seed in range(300):
        rng = np.random.default_rng(500 + seed)
        ref = Trajectory(truth.stamps_ns, truth.pos_m + rng.normal(0, 0.1, truth.pos_m.shape),
                         truth.quat_xyzw)
        al = align(base, ref, method="yaw")
        c = al.conditioning
        assert c is not None
        err = math.atan2(al.rotation[1, 0], al.rotation[0, 0]) - yaw
        z.append(abs(err) / math.sqrt(c.rotation_cov_rad2[2, 2]))
    za = np.array(z)
    assert 0.60 < np.mean(za <= 1.0) < 0.76 and 0.90 < np.mean(za <= 2.0) < 0.985


def test_none_and_origin_have_no_conditioning() -> None:
    est, gt = _still_cloud(50)
    for method in ("none", "origin"):
        res = ate(est, gt, align=method)
        assert res.alignment.conditioning is None
        assert res.to_dict()["alignment_conditioning"] is None


def test_compare_entries_carry_the_warning() -> None:
    est, gt = _still_cloud(200)
    with pytest.warns(IbiscapeWarning, match="poorly determined"):
        res = compare(gt, [est], labels=["still"])
    row = res.to_dict()["estimates"][0]
    assert row["warnings"] and "est" in row["warnings"][0]
    assert row["ate_rotation_sigma_deg"] > 5.0


def test_sim3_on_a_cloud_warns_about_the_scale() -> None:
    est, gt = _still_cloud(300)
    with pytest.warns(IbiscapeWarning) as rec:
        res = rpe(est, gt, align="sim3")
    assert any("scale of the sim3 alignment is poorly determined" in str(w.message) for w in rec)
    assert all("rotation of the" not in w for w in res.warnings)  # RPE ignores that rotation
