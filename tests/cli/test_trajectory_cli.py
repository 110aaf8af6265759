"""``ibiscape-eval ate | rpe | drift | convert``: the command-line contract and every bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _cli_data import EXAMPLES, write_tum

STAT_KEYS = {"rmse", "mean", "median", "std", "min", "max", "sse"}


def test_ate_json_contract(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    res = run_cli("ate", est, gt, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    for key in (
        "n_matched",
        "n_dropped_est",
        "n_dropped_ref",
        "alignment",
        "scale",
        "transform",
        "t_offset_s",
        "translation_m",
        "rotation_deg",
    ):
        assert key in doc
    assert set(doc["translation_m"]) == STAT_KEYS and set(doc["rotation_deg"]) == STAT_KEYS
    assert doc["n_matched"] == 300 and doc["alignment"] == "se3"
    assert np.asarray(doc["transform"]).shape == (4, 4)
    # noise sigma 0.02 m per axis -> rmse close to 0.02*sqrt(3)
    assert 0.025 < doc["translation_m"]["rmse"] < 0.045


def test_ate_table_and_outputs(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    res = run_cli(
        "ate",
        est,
        gt,
        "--save-csv",
        tmp_path / "e.csv",
        "--plot",
        tmp_path / "e.png",
        "--save-aligned",
        tmp_path / "aligned.txt",
    )
    assert res.exit_code == 0, res.output
    assert "mean ± std" in res.stdout and "translation [m]" in res.stdout
    assert "300 poses matched, dropped 0 est / 0 ref" in res.stdout
    assert (tmp_path / "e.png").stat().st_size > 10_000
    assert len((tmp_path / "e.csv").read_text().splitlines()) == 301
    aligned = (tmp_path / "aligned.txt").read_text().splitlines()
    assert len([ln for ln in aligned if not ln.startswith("#")]) == 300
    assert not list(tmp_path.glob(".*tmp*")), "temporary files left behind"


def test_rpe_json_has_pair_fields(run_cli, tum_pair) -> None:
    est, gt = tum_pair
    res = run_cli(
        "rpe", est, gt, "--delta", "2", "--delta-unit", "metres", "--pairs", "all", "--json"
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["delta"] == 2.0 and doc["delta_unit"] == "metres" and doc["n_pairs"] > 100


def test_drift_lengths_pct(run_cli, tum_pair, tmp_path: Path) -> None:
    est, gt = tum_pair
    res = run_cli("drift", est, gt, "--lengths-pct", "10,20,30", "--plot", tmp_path / "d.png")
    assert res.exit_code == 0, res.output
    assert "average" in res.stdout and (tmp_path / "d.png").exists()


def test_convert_roundtrip_through_kitti(run_cli, tum_pair, tmp_path: Path) -> None:
    est, _ = tum_pair
    res = run_cli("convert", est, tmp_path / "k.txt", "--to", "euroc")
    assert res.exit_code == 0, res.output
    res = run_cli(
        "ate", est, tmp_path / "k.txt", "--format-ref", "euroc", "--align", "none", "--json"
    )
    assert json.loads(res.stdout)["translation_m"]["max"] < 1e-6


def test_kitti_without_times_pairs_by_index(run_cli, tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    T = np.tile(np.eye(4)[:3].reshape(1, 12), (50, 1))
    T[:, 3] = np.arange(50) * 1.0
    T[:, 7] = np.sin(np.arange(50))
    np.savetxt(tmp_path / "gt.txt", T)
    T2 = T.copy()
    T2[:, [3, 7, 11]] += rng.normal(0, 0.01, (50, 3))
    np.savetxt(tmp_path / "est.txt", T2)
    res = run_cli("ate", tmp_path / "est.txt", tmp_path / "gt.txt", "--format", "kitti", "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["n_matched"] == 50
    assert "by index" in res.stderr
    np.savetxt(tmp_path / "short.txt", T2[:40])
    res = run_cli("ate", tmp_path / "short.txt", tmp_path / "gt.txt", "--format", "kitti")
    assert res.exit_code == 2 and "40" in res.stderr and "50" in res.stderr


def test_real_data_formats_detected(run_cli) -> None:
    res = run_cli(
        "ate", EXAMPLES / "V102.txt", EXAMPLES / "V102_groundtruth.csv", "--align", "yaw", "--json"
    )
    assert res.exit_code == 0, res.output
    assert "format tum (detected" in res.stderr and "format euroc (detected" in res.stderr
    assert json.loads(res.stdout)["n_matched"] > 700


def test_help_does_not_import_heavy_modules() -> None:
    code = (
        "import sys\nfrom ibiscape_eval.cli.main import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "heavy = [m for m in ('numpy', 'pandas', 'matplotlib', 'scipy', 'cv2', 'gtsam', 'open3d') if m in sys.modules]\n"
        "print('HEAVY', heavy)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert "HEAVY []" in out


# --------------------------------------------------------------------------- bad input
def _gt(tmp_path: Path) -> Path:
    t = np.arange(20) * 0.1
    pos = np.column_stack([t, np.sin(t), np.cos(t) * 0.1])
    return write_tum(tmp_path / "gt.txt", t, pos, np.tile([0, 0, 0, 1.0], (20, 1)))


BAD_FILES = {
    "empty": ("", "empty"),
    "header_only": ("# timestamp tx ty tz qx qy qz qw\n", "no data"),
    "wrong_columns": ("0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1 9\n", "est.txt:2:"),
    "non_numeric": ("0.0 1 2 3 0 0 0 1\n0.1 1 abc 3 0 0 0 1\n", "est.txt:2:"),
    "binary": ("\x00\x01\x02garbage\xff\xfe" * 20, "est.txt"),
    "non_monotonic": ("0.2 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1\n0.3 1 2 3 0 0 0 1\n", "est.txt:2:"),
    "zero_quaternion": ("0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 0\n0.2 1 2 3 0 0 0 1\n", "est.txt:2:"),
    "non_unit_quaternion": (
        "0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1.5\n0.2 1 2 3 0 0 0 1\n",
        "est.txt:2:",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_estimate_files(run_cli, tmp_path: Path, case: str) -> None:
    content, expected = BAD_FILES[case]
    est = tmp_path / "est.txt"
    est.write_bytes(content.encode("latin-1"))
    out_csv, out_png = tmp_path / "o.csv", tmp_path / "o.png"
    res = run_cli(
        "ate", est, _gt(tmp_path), "--format-est", "tum", "--save-csv", out_csv, "--plot", out_png
    )
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len([ln for ln in lines if ln.startswith("error")]) == 1
    assert "est.txt" in res.stderr and expected in res.stderr
    assert "Traceback" not in res.output
    assert not out_csv.exists() and not out_png.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_nonexistent_path(run_cli, tmp_path: Path) -> None:
    res = run_cli("ate", tmp_path / "nope.txt", _gt(tmp_path))
    assert res.exit_code == 2 and "nope.txt" in res.stderr and "Traceback" not in res.output


def test_no_temporal_overlap(run_cli, tmp_path: Path) -> None:
    t = 1000 + np.arange(20) * 0.1
    est = write_tum(
        tmp_path / "est.txt",
        t,
        np.random.default_rng(0).normal(size=(20, 3)),
        np.tile([0, 0, 0, 1.0], (20, 1)),
    )
    res = run_cli("ate", est, _gt(tmp_path), "--save-csv", tmp_path / "o.csv")
    assert res.exit_code == 2 and "overlap" in res.stderr and not (tmp_path / "o.csv").exists()


def test_fewer_than_three_matches(run_cli, tmp_path: Path) -> None:
    t = np.array([0.0, 0.1, 5.0, 6.0])
    est = write_tum(
        tmp_path / "est.txt",
        t,
        np.random.default_rng(0).normal(size=(4, 3)),
        np.tile([0, 0, 0, 1.0], (4, 1)),
    )
    res = run_cli(
        "ate", est, _gt(tmp_path), "--save-csv", tmp_path / "o.csv", "--plot", tmp_path / "o.png"
    )
    assert res.exit_code == 2 and "2" in res.stderr and "--max-diff-s" in res.stderr
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "o.png").exists()


def test_degenerate_geometry(run_cli, tmp_path: Path) -> None:
    t = np.arange(20) * 0.1
    line = np.column_stack([t, np.zeros(20), np.zeros(20)])
    q = np.tile([0, 0, 0, 1.0], (20, 1))
    est = write_tum(tmp_path / "est.txt", t, line, q)
    gt = write_tum(tmp_path / "gt.txt", t, line * 2, q)
    res = run_cli("ate", est, gt, "--align", "se3", "--save-csv", tmp_path / "o.csv")
    assert res.exit_code == 2 and "collinear" in res.stderr.lower()
    assert not (tmp_path / "o.csv").exists()
    res = run_cli("ate", est, gt, "--align", "yaw", "--json")
    assert res.exit_code == 0, res.output


def test_nan_rows_and_duplicates_warn_with_line_numbers(run_cli, tmp_path: Path) -> None:
    gt = _gt(tmp_path)
    lines = gt.read_text().splitlines()
    lines[3] = "0.3 nan 0 0 0 0 0 1"
    lines.insert(6, lines[5])  # duplicate stamp of line 6 at line 7
    est = tmp_path / "est.txt"
    est.write_text("\n".join(lines) + "\n")
    res = run_cli("ate", est, gt, "--json")
    assert res.exit_code == 0, res.output
    assert "4" in res.stderr and "nan" in res.stderr.lower()
    assert "7" in res.stderr and "duplicate" in res.stderr.lower()
