"""Synthetic stamps (KITTI without times) and unreached drift lengths, in the library."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ibiscape_eval.core import IbiscapeWarning
from ibiscape_eval.io import read_trajectory
from ibiscape_eval.metrics import ate, compare, drift, rpe
from ibiscape_eval.report.plots import compare_figure, metric_figure


def _kitti(path: Path, n: int = 200, noise: float = 0.0, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, n)
    yaw = np.sin(2 * np.pi * s)
    pos = np.column_stack([np.cumsum(np.sin(yaw)), 0.1 * np.sin(7 * s), np.cumsum(np.cos(yaw))])
    pos += rng.normal(0, noise, pos.shape)
    R = Rotation.from_euler("y", yaw[:, None]).as_matrix()
    np.savetxt(path, np.concatenate([R, pos[:, :, None]], axis=2).reshape(n, 12), fmt="%.9f")
    return path


def test_kitti_without_times_gives_pose_indices(tmp_path: Path) -> None:
    gt = read_trajectory(_kitti(tmp_path / "gt.txt"), "kitti")
    est = read_trajectory(_kitti(tmp_path / "est.txt", noise=0.05, seed=1), "kitti")
    assert gt.stamps_synthetic and "synthetic" in repr(gt)
    assert gt.take(np.arange(5)).stamps_synthetic and gt.with_name("x").stamps_synthetic
    timed = tmp_path / "t.txt"
    np.savetxt(timed, np.arange(200) * 0.1037)
    assert not read_trajectory(tmp_path / "gt.txt", "kitti", times_path=timed).stamps_synthetic
    res = ate(est, gt, match="index")
    assert res.stamps_synthetic and res.to_dict()["stamps"] == "synthetic"
    frame = res.to_frame()
    assert list(frame.columns[:2]) == ["ref_pose_index", "error_m"]
    np.testing.assert_array_equal(frame["ref_pose_index"], np.arange(200))
    r = rpe(est, gt, match="index", delta=5)
    np.testing.assert_array_equal(r.to_frame()["ref_pose_index"], r.first_index)
    fig = metric_figure(r, plane="xz")
    assert "pose index (no timestamps)" in [ax.get_xlabel() for ax in fig.axes]
    c = compare(gt, [est], match="index")
    assert c.to_dict()["estimates"][0]["stamps"] == "synthetic"
    assert "pose index (no timestamps)" in [ax.get_xlabel() for ax in compare_figure(c).axes]
    # measured stamps keep the time axis and the stamp columns
    timed_res = ate(est.with_name("e"), gt, match="time")
    assert timed_res.stamps_synthetic  # synthetic on either side: still not times
    plain = ate(read_trajectory(tmp_path / "est.txt", "kitti", times_path=timed),
                read_trajectory(tmp_path / "gt.txt", "kitti", times_path=timed))
    assert not plain.stamps_synthetic and "ref_t_s" in plain.to_frame().columns
    assert "time since start [s]" in [ax.get_xlabel() for ax in metric_figure(plain).axes]


def test_unreached_drift_lengths_are_marked_with_a_hint(tmp_path: Path) -> None:
    gt = read_trajectory(_kitti(tmp_path / "gt.txt"), "kitti")
    est = read_trajectory(_kitti(tmp_path / "est.txt", noise=0.02, seed=1), "kitti")
    length = float(gt.path_length_m()[-1])
    with pytest.warns(IbiscapeWarning, match=r"lengths_pct=\[10, 20, 30, 40, 50\]"):
        res = drift(est, gt, match="index", lengths_m=(50, 100, 400))
    np.testing.assert_array_equal(res.reached, [True, True, False])
    doc = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert doc["reached"] == [True, True, False] and doc["translation_pct"][2] is None
    assert doc["path_length_m"] == pytest.approx(length)
    assert "400 m" in doc["warnings"][0] and f"{length:.1f} m" in doc["warnings"][0]
    assert res.to_frame()["reached"].tolist() == [True, True, False]
    with warnings.catch_warnings():
        warnings.simplefilter("error", IbiscapeWarning)
        ok = drift(est, gt, match="index", lengths_pct=(10, 50))
    assert ok.warnings == () and ok.reached.all()
