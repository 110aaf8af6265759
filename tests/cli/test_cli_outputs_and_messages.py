"""Command-line options borrowed from evo (pose relation, projection, panels, RPE pairs from the
reference), ``compare``'s table, figure and saved results, full-precision CSVs, and the messages
for swapped arguments, short IMU records, inferred sensor sizes and TF topics named without
their frames."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli_data import assert_one_error_line, write_tum
from shared_data import require_shared


def test_ate_pose_relation_and_projection(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    res = run_cli("ate", est, gt, "--pose-relation", "full", "--project-to-plane", "xy", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["pose_relation"] == "full" and doc["project_to_plane"] == "xy"
    assert doc["error"]["rmse"] > 0
    table = run_cli("ate", est, gt, "--pose-relation", "rot-part")
    assert "rot-part: rmse" in table.stdout


def test_rpe_pairs_from_ref(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    res = run_cli("rpe", est, gt, "--delta", "1", "--delta-unit", "metres", "--pairs-from", "ref",
                  "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["pairs_from"] == "ref"


def test_bad_panel_is_one_error_line(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    res = run_cli("ate", est, gt, "--plot", tmp_path / "a.png", "--plot-panels", "map")
    assert res.exit_code == 2 and "unknown panel" in res.output
    assert not (tmp_path / "a.png").exists()


def test_plot_single_panel_plane(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    res = run_cli("ate", est, gt, "--plot", tmp_path / "a.png", "--plot-panels", "trajectory",
                  "--plot-plane", "xz")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "a.png").stat().st_size > 5_000


def test_csv_time_is_exact(run_cli, tmp_path: Path) -> None:
    n = 50
    stamps_ns = 1_403_715_529_112_143_104 + np.arange(n, dtype=np.int64) * 50_000_001
    t = stamps_ns / 1e9  # what a TUM file holds
    pos = np.c_[np.arange(n) * 0.1, np.sin(np.arange(n)), np.zeros(n)]
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    gt = write_tum(tmp_path / "gt.txt", t, pos, quat)
    est = write_tum(tmp_path / "est.txt", t, pos + 0.01, quat)
    res = run_cli("ate", est, gt, "--save-csv", tmp_path / "e.csv")
    assert res.exit_code == 0, res.output
    df = pd.read_csv(tmp_path / "e.csv", dtype={"ref_t_s": str})
    assert list(df.columns[:3]) == ["ref_stamp_ns", "ref_t_s", "est_stamp_ns"]
    for ns, text in zip(df["ref_stamp_ns"], df["ref_t_s"], strict=True):
        whole, frac = text.split(".")
        assert len(frac) == 9 and int(whole) * 10**9 + int(frac) == ns


def test_swapped_arguments_warning(run_cli, tmp_path: Path) -> None:
    n = 400
    t = 10.0 + np.arange(n) * 0.005
    pos = np.c_[np.sin(t), np.cos(t), 0 * t]
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    dense = write_tum(tmp_path / "gt.txt", t, pos, quat)
    sparse = write_tum(tmp_path / "est.txt", t[::10], pos[::10], quat[::10])
    res = run_cli("ate", dense, sparse)
    assert res.exit_code == 0, res.output
    assert "looks like the ground truth" in res.stderr
    ok = run_cli("ate", sparse, dense)
    assert "looks like the ground truth" not in ok.stderr


def test_compare_table_figure_and_saved_results(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    est2 = tmp_path / "est2.txt"
    rows = np.loadtxt(est)
    rows[:, 1:4] += np.random.default_rng(1).normal(0, 0.05, (len(rows), 3))
    np.savetxt(est2, rows, fmt="%.9f")
    out = tmp_path / "res"
    res = run_cli("compare", est, est2, gt, "--labels", "A,B c", "--plot", tmp_path / "c.png",
                  "--save-results", out)
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    assert lines[1].startswith("label") and lines[2].startswith("A ") and lines[3].startswith("B c")
    index = json.loads((out / "compare.json").read_text())
    assert [e["label"] for e in index["estimates"]] == ["A", "B c"]
    assert index["estimates"][1]["ate_json"] == "B_c.ate.json"
    doc = json.loads((out / "B_c.ate.json").read_text())
    assert doc["label"] == "B c" and doc["est_file"] == "est2.txt" and doc["metric"] == "ate"
    assert doc["translation_m"]["rmse"] > index["estimates"][0]["ate_rmse_m"]
    assert len(pd.read_csv(out / "A.rpe.csv")) == doc["n_matched"] - 1
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_compare_rpe_follows_sim3(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    doc = json.loads(run_cli("compare", est, gt, "--align", "sim3", "--json").stdout)
    assert doc["options"]["rpe_align"] == "sim3"
    doc = json.loads(run_cli("compare", est, gt, "--json").stdout)
    assert doc["options"]["rpe_align"] == "none"


def test_compare_label_count_mismatch(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    res = run_cli("compare", est, gt, "--labels", "a,b")
    assert res.exit_code == 2 and "2 labels for 1 estimates" in res.output


def test_allan_csv_full_precision(run_cli, tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    n = 4000
    stamps = np.arange(n, dtype=np.int64) * 5_000_000
    data = rng.normal(0, 0.01, (n, 6))
    p = tmp_path / "imu.csv"
    with p.open("w") as f:
        f.write("#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n")
        for s, row in zip(stamps, data, strict=True):
            f.write(f"{s}," + ",".join(repr(float(v)) for v in row) + "\n")
    res = run_cli("allan", p, "--csv", tmp_path / "a.csv")
    assert res.exit_code == 0, res.output
    df = pd.read_csv(tmp_path / "a.csv", dtype=str)
    digits = [len(v.replace(".", "").replace("-", "").split("e")[0].lstrip("0"))
              for v in df["adev_w_x"]]
    assert max(digits) >= 16


def _short_imu(tmp_path: Path) -> Path:
    from ibiscape_eval.io.imu import write_imu_csv
    from ibiscape_eval.sim.noise import imu_noise

    n = int(0.1 * 3600 * 20)
    y = imu_noise(n, 20.0, noise_density=[1e-3] * 3 + [2e-2] * 3, random_walk=0.0, seed=1)
    t = 1_600_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 50_000_000
    p = tmp_path / "short.csv"
    write_imu_csv(p, t, y[:, :3], y[:, 3:])
    return p


def test_short_record_refusal_suggests_fallback(run_cli, tmp_path: Path) -> None:
    res = run_cli("allan", _short_imu(tmp_path), "--yaml", tmp_path / "imu.yaml")
    assert_one_error_line(res, "imu.yaml not written", "--random-walk-fallback",
                          stdout_empty=False)
    assert not (tmp_path / "imu.yaml").exists()


def test_short_record_with_fallback_and_inflate_writes_yaml(run_cli, tmp_path: Path) -> None:
    from ibiscape_eval.io.kalibr import read_imu_noise

    out = tmp_path / "imu.yaml"
    res = run_cli("allan", _short_imu(tmp_path), "--yaml", out, "--random-walk-fallback",
                  "2e-5,3e-3", "--inflate", "2", "--json")
    assert res.exit_code == 0, res.output
    doc = read_imu_noise(out).to_kalibr()
    assert doc["gyroscope_random_walk"] == pytest.approx(4e-5)
    assert doc["accelerometer_random_walk"] == pytest.approx(6e-3)
    n_gyro = json.loads(res.stdout)["kalibr"]["gyroscope_noise_density"]
    assert doc["gyroscope_noise_density"] == pytest.approx(2 * n_gyro)
    text = out.read_text()
    assert "fallback" in text and "inflated by a factor 2" in text


def test_bad_fallback_and_inflate(run_cli, tmp_path: Path) -> None:
    p = _short_imu(tmp_path)
    res = run_cli("allan", p, "--yaml", tmp_path / "i.yaml", "--random-walk-fallback", "1e-5")
    assert_one_error_line(res, "--random-walk-fallback", "GYRO,ACCEL")
    res = run_cli("allan", p, "--yaml", tmp_path / "i.yaml", "--inflate", "-1")
    assert_one_error_line(res, "--inflate")


def test_events_frames_sorted_names_and_inferred_size_note(run_cli, tmp_path: Path) -> None:
    from ibiscape_eval.events import synthetic_events
    from ibiscape_eval.io.events import write_events

    ev = synthetic_events(sensor_size=(40, 30), duration_s=1.2, seed=2).events
    src = tmp_path / "ev.txt"
    write_events(src, ev, fmt="text")
    out = tmp_path / "frames"
    res = run_cli("events", "frames", src, "--out", out, "--rate-hz", 10)
    assert res.exit_code == 0, res.output
    assert "inferred from the largest event coordinates" in res.stderr
    names = sorted(p.name for p in out.glob("*.png"))
    stamps = [int(n[:-4]) for n in names]
    assert len(names) >= 10 and all(len(n) == 24 for n in names)
    assert stamps == sorted(stamps)  # glob (name) order is time order
    res = run_cli("events", "frames", src, "--out", tmp_path / "f2", "--sensor-size", "40x30")
    assert "inferred" not in res.stderr


def test_convert_tf_topic_hint_and_json(run_cli, tmp_path: Path) -> None:
    bag = require_shared("trajectories", "tf_example_ros2")
    res = run_cli("convert", bag, tmp_path / "o.txt", "--topic", "/tf")
    assert_one_error_line(res, "/tf:odom.base_footprint", "TOPIC:parent.child")
    assert "unsupported" not in res.stderr
    res = run_cli("convert", bag, tmp_path / "o.txt", "--topic", "/tf:odom.base_footprint",
                  "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["n_poses"] > 100 and doc["to"] == "tum" and doc["start_ns"] < doc["end_ns"]


def test_hotpix_notes_inferred_sensor_size(run_cli, tmp_path: Path) -> None:
    from ibiscape_eval.events import synthetic_events
    from ibiscape_eval.io.events import write_events

    ev = synthetic_events(sensor_size=(40, 30), duration_s=0.2, seed=3).events
    src = tmp_path / "ev.txt"
    write_events(src, ev, fmt="text")
    res = run_cli("hotpix", src, "--top-n", 3, "--plot", tmp_path / "h.png")
    assert res.exit_code == 0, res.output
    assert "inferred from the largest event coordinates" in res.stderr
    res = run_cli("hotpix", src, "--top-n", 3, "--sensor-size", "40x30")
    assert "inferred" not in res.stderr
