"""No confident wrong number from ``ate``, ``rpe``, ``drift``, ``compare``: warnings for a poorly
conditioned alignment, synthetic (KITTI) stamps, unreached drift lengths and swapped arguments;
one argument order (estimates, then the reference); the unit and selection options."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli_data import write_tum
from scipy.spatial.transform import Rotation
from shared_data import require_shared

import ibiscape_eval.report.plots as plots


def _cloud(tmp_path: Path, n: int = 600) -> tuple[Path, Path]:
    """A standing vehicle: two independent 1 mm clouds, orientations equal."""
    rng = np.random.default_rng(3)
    t = 10.0 + np.arange(n) * 0.05
    q = np.tile(Rotation.from_euler("z", 30, degrees=True).as_quat(), (n, 1))
    c = np.array([12.0, -4.0, 1.5])
    gt = write_tum(tmp_path / "ref.txt", t, c + rng.normal(0, 0.001, (n, 3)), q)
    est = write_tum(tmp_path / "est.txt", t, c + rng.normal(0, 0.001, (n, 3)), q)
    return est, gt


def test_two_mm_cloud_warns_in_text_and_json(run_cli, tmp_path: Path) -> None:
    est, gt = _cloud(tmp_path)
    res = run_cli("ate", est, gt)
    assert res.exit_code == 0, res.output
    line = [s for s in res.stderr.splitlines() if "poorly determined" in s]
    assert len(line) == 1 and line[0].startswith("warning:")
    assert "--align yaw" in line[0] and 'align="' not in line[0]  # said in CLI terms
    res = run_cli("ate", est, gt, "--json")
    doc = json.loads(res.stdout)
    assert doc["rotation_deg"]["rmse"] > 10  # a confident, wrong rotation error
    assert len(doc["warnings"]) == 1 and "--align yaw" in doc["warnings"][0]
    assert doc["alignment_conditioning"]["rotation_sigma_total_deg"] > 5
    assert max(doc["alignment_conditioning"]["spread_m"]) < 0.002


def test_well_conditioned_run_has_no_warning(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    for cmd in ("ate", "rpe"):
        res = run_cli(cmd, est, gt, "--json")
        assert res.exit_code == 0, res.output
        doc = json.loads(res.stdout)
        assert doc["warnings"] == [] and "warning" not in res.stderr
    assert doc["stamps"] == "measured"


def test_compare_warns_for_the_cloud_only(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = _cloud(tmp_path)
    res = run_cli("compare", est, gt, "--json")
    assert res.exit_code == 0, res.output
    row = json.loads(res.stdout)["estimates"][0]
    assert row["warnings"] and "--align yaw" in row["warnings"][0]
    assert "poorly determined" in res.stderr


# --------------------------------------------------------------------------- KITTI, no times
def _kitti_drive(path: Path, n: int = 680, seed: int = 0, noise: float = 0.0) -> Path:
    """A KITTI file in the camera frame (x right, y down, z forward): a 135.8 m drive on the
    x-z ground plane at 10 Hz, without a times file."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, n)
    yaw = 1.2 * np.sin(2 * np.pi * s)
    step = 135.8 / (n - 1)
    x = np.cumsum(np.sin(yaw)) * step
    z = np.cumsum(np.cos(yaw)) * step
    pos = np.column_stack([x, 0.02 * np.sin(9 * s), z]) + rng.normal(0, noise, (n, 3))
    R = Rotation.from_euler("y", yaw[:, None]).as_matrix()
    M = np.concatenate([R, pos[:, :, None]], axis=2).reshape(n, 12)
    np.savetxt(path, M, fmt="%.9f")
    return path


def test_kitti_without_times_is_marked_synthetic(run_cli, tmp_path: Path, monkeypatch) -> None:
    gt = _kitti_drive(tmp_path / "00.txt")
    est = _kitti_drive(tmp_path / "00_est.txt", seed=1, noise=0.05)
    figs: list = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figs.append(fig))
    res = run_cli("ate", est, gt, "--format", "kitti", "--save-csv", tmp_path / "e.csv",
                  "--plot", tmp_path / "e.png", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["stamps"] == "synthetic"
    df = pd.read_csv(tmp_path / "e.csv")
    assert "ref_pose_index" in df.columns and "ref_t_s" not in df.columns
    assert "est_stamp_ns" not in df.columns
    assert df["ref_pose_index"].tolist() == list(range(680))
    (fig,) = figs
    labels = {ax.get_xlabel() for ax in fig.axes}
    assert "pose index (no timestamps)" in labels and "time since start [s]" not in labels
    traj_ax = next(ax for ax in fig.axes if ax.get_xlabel() == "x [m]")
    assert traj_ax.get_ylabel() == "z [m]"  # KITTI's ground plane by default
    # RPE: same marking, index of each pair's first pose
    res = run_cli("rpe", est, gt, "--format", "kitti", "--save-csv", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    assert "ref_pose_index" in pd.read_csv(tmp_path / "r.csv").columns


def test_timed_kitti_keeps_real_stamps_and_xz_plane_only_by_default(
        run_cli, tmp_path: Path, monkeypatch) -> None:
    gt = _kitti_drive(tmp_path / "00.txt")
    times = tmp_path / "times.txt"
    np.savetxt(times, 1.5 + np.arange(680) * 0.1037, fmt="%.6f")
    figs: list = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: figs.append(fig))
    res = run_cli("ate", gt, gt, "--format", "kitti", "--times-est", times, "--times-ref", times,
                  "--plot", tmp_path / "a.png", "--plot-plane", "xy", "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["stamps"] == "measured"
    labels = {ax.get_xlabel() for ax in figs[0].axes}
    assert "time since start [s]" in labels
    assert next(ax for ax in figs[0].axes if ax.get_xlabel() == "x [m]").get_ylabel() == "y [m]"


def test_convert_kitti_without_times_says_stamps_are_synthetic(run_cli, tmp_path: Path) -> None:
    src = _kitti_drive(tmp_path / "00.txt", n=30)
    res = run_cli("convert", src, tmp_path / "o.txt", "--from", "kitti", "--to", "tum", "--json")
    assert res.exit_code == 0, res.output
    assert "synthetic" in res.stderr and json.loads(res.stdout)["stamps"] == "synthetic"


# --------------------------------------------------------------------------- drift
def test_short_drift_marks_unreached_lengths_with_a_hint(run_cli, tmp_path: Path) -> None:
    gt = _kitti_drive(tmp_path / "00.txt")
    est = _kitti_drive(tmp_path / "00_est.txt", seed=1, noise=0.02)
    res = run_cli("drift", est, gt, "--format", "kitti")
    assert res.exit_code == 0, res.output
    rows = res.stdout.splitlines()
    assert any(r.split()[:1] == ["100.00"] and "not reached" not in r for r in rows)
    for length in ("200.00", "800.00"):
        row = next(r for r in rows if r.strip().startswith(length))
        assert "not reached" in row and "nan" not in row
    assert "--lengths-pct 10,20,30,40,50" in res.stderr and "135.8 m" in res.stderr
    doc = json.loads(run_cli("drift", est, gt, "--format", "kitti", "--json").stdout)
    assert doc["reached"] == [True] + [False] * 7
    assert doc["translation_pct"][1] is None and doc["path_length_m"] == pytest.approx(135.8, 0.01)
    assert "--lengths-pct" in doc["warnings"][0]
    ok = run_cli("drift", est, gt, "--format", "kitti", "--lengths-pct", "10,20,30,40,50")
    assert ok.exit_code == 0 and "not reached" not in ok.stdout and "warning" not in ok.stderr


# --------------------------------------------------------------------------- argument order
def _same_count_pair(tmp_path: Path, est_name: str, gt_name: str) -> tuple[Path, Path]:
    """Ground truth and a noisy estimate with the same number of poses."""
    rng = np.random.default_rng(2)
    n = 300
    t = 5.0 + np.arange(n) * 0.05
    pos = np.column_stack([np.cos(t / 3) * 5, np.sin(t / 2) * 4, 0.3 * np.sin(t)])
    q = np.tile([0, 0, 0, 1.0], (n, 1))
    gt = write_tum(tmp_path / gt_name, t, pos, q)
    est = write_tum(tmp_path / est_name, t, pos + rng.normal(0, 0.02, pos.shape), q)
    return est, gt


@pytest.mark.parametrize("cmd", ["ate", "rpe", "drift"])
def test_swap_warning_with_equal_counts_from_the_name(run_cli, tmp_path: Path, cmd: str) -> None:
    est, gt = _same_count_pair(tmp_path, "orb.txt", "groundtruth.txt")
    extra = ["--lengths-pct", "20,40"] if cmd == "drift" else []
    res = run_cli(cmd, gt, est, *extra)  # swapped: equal counts, the name says ground truth
    assert res.exit_code == 0, res.output
    assert "looks like the ground truth" in res.stderr and "groundtruth.txt" in res.stderr
    ok = run_cli(cmd, est, gt, *extra)
    assert "looks like the ground truth" not in ok.stderr


def test_swap_warning_for_euroc_data_csv(run_cli, tmp_path: Path) -> None:
    folder = tmp_path / "state_groundtruth_estimate0"
    folder.mkdir()
    est, _ = _same_count_pair(tmp_path, "vio.txt", "unused.txt")
    rows = np.loadtxt(est)
    gt = folder / "data.csv"
    body = np.column_stack([(rows[:, 0] * 1e9).round().astype(np.int64), rows[:, 1:4],
                            rows[:, 7], rows[:, 4:7]])
    header = "#timestamp,p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []"
    np.savetxt(gt, body, delimiter=",", header=header, comments="", fmt="%.9f")
    gt.write_text(gt.read_text().replace(".000000000,", ",", 0))
    res = run_cli("ate", gt, est, "--format-est", "euroc", "--format-ref", "tum", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert any("data.csv" in w for w in doc["warnings"])


def test_swap_warning_for_a_denser_smoother_estimate(run_cli, tmp_path: Path) -> None:
    """Equal counts, neutral names: the ground truth is sampled 4x as densely (a shorter span)
    and is smooth, the estimate is noisy."""
    rng = np.random.default_rng(8)
    n = 300
    q = np.tile([0, 0, 0, 1.0], (n, 1))
    t_gt = 5.0 + np.arange(n) * 0.0125
    t_est = 5.0 + np.arange(n) * 0.05

    def path(t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.cos(t / 3) * 5, np.sin(t / 2) * 4, 0.3 * np.sin(t)])

    a = write_tum(tmp_path / "a.txt", t_gt, path(t_gt), q)
    b = write_tum(tmp_path / "b.txt", t_est, path(t_est) + rng.normal(0, 0.01, (n, 3)), q)
    res = run_cli("ate", a, b, "--max-diff-s", "0.007")
    assert res.exit_code == 0, res.output
    assert "denser" in res.stderr and "smoother" in res.stderr
    assert "looks like the ground truth" not in run_cli("ate", b, a, "--max-diff-s", "0.007").stderr


@pytest.mark.parametrize(("est", "gt"), [
    ("freiburg1_xyz-rgbdslam.txt", "freiburg1_xyz-groundtruth.txt"),
    ("freiburg1_xyz-ORB_kf_mono.txt", "freiburg1_xyz-groundtruth.txt"),
    ("V102.txt", "V102_groundtruth.csv"),
])
def test_no_swap_warning_on_real_data_in_the_right_order(run_cli, est: str, gt: str) -> None:
    shared = require_shared("trajectories")
    res = run_cli("ate", shared / est, shared / gt, "--align", "sim3", "--json")
    assert res.exit_code == 0, res.output
    assert "looks like the ground truth" not in res.stderr
    bad = run_cli("ate", shared / gt, shared / est, "--align", "sim3", "--json")
    assert "looks like the ground truth" in bad.stderr


def test_compare_puts_the_reference_last_and_shares_the_ate_options(run_cli, tum_pair,
                                                                      tmp_path: Path) -> None:
    est, gt = tum_pair
    res = run_cli("compare", est, gt, "--json", "--offset-s", "0.0", "--t-start", "105",
                  "--t-end", "110", "--format-est", "tum", "--change-unit", "cm")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["ref_file"] == "gt.txt" and doc["estimates"][0]["est_file"] == "est.txt"
    ate = json.loads(run_cli("ate", est, gt, "--t-start", "105", "--t-end", "110",
                             "--json").stdout)
    row = doc["estimates"][0]
    assert row["n_matched"] == ate["n_matched"] == 101
    assert row["ate_rmse_cm"] == pytest.approx(100 * ate["translation_m"]["rmse"], rel=1e-12)
    old = run_cli("compare", gt, est)  # the old order REF EST: said, not silently swapped
    assert "looks like the ground truth" in old.stderr


# --------------------------------------------------------------------------- evo's options
def test_change_unit_in_table_json_and_csv(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    m = json.loads(run_cli("ate", est, gt, "--json").stdout)
    cm = json.loads(run_cli("ate", est, gt, "--json", "--change-unit", "cm").stdout)
    assert cm["length_unit"] == "cm" and "translation_m" not in cm
    assert cm["translation_cm"]["rmse"] == pytest.approx(100 * m["translation_m"]["rmse"])
    res = run_cli("ate", est, gt, "--change-unit", "mm", "--save-csv", tmp_path / "e.csv")
    assert "translation [mm]" in res.stdout and "translation [m]" not in res.stdout
    assert "error_mm" in pd.read_csv(tmp_path / "e.csv").columns
    bad = run_cli("drift", est, gt, "--change-unit", "cm")
    assert bad.exit_code == 2 and "--change-unit" in bad.stderr


def test_selection_options_reach_the_metrics(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    full = json.loads(run_cli("ate", est, gt, "--json").stdout)
    down = json.loads(run_cli("ate", est, gt, "--downsample", "50", "--json").stdout)
    moved = json.loads(run_cli("ate", est, gt, "--motion-filter", "0.2", "30", "--json").stdout)
    assert full["n_matched"] == 300 and down["n_matched"] == 50
    assert 10 < moved["n_matched"] < 300
    tol = json.loads(run_cli("rpe", est, gt, "--delta", "1", "--delta-unit", "metres", "--pairs",
                             "all", "--delta-tol", "0.01", "--json").stdout)
    loose = json.loads(run_cli("rpe", est, gt, "--delta", "1", "--delta-unit", "metres",
                               "--pairs", "all", "--json").stdout)
    assert tol["delta_tol"] == 0.01 and tol["n_pairs"] < loose["n_pairs"]
    res = run_cli("ate", est, gt, "--t-start", "500", "--save-csv", "x.csv")
    assert res.exit_code == 2 and "no pose" in res.stderr and "Traceback" not in res.output
    res = run_cli("ate", est, gt, "--motion-filter", "-1", "2")
    assert res.exit_code == 2
