"""``ibiscape-eval sim``: outputs, --print-config, --json, and every bad input -> exit 2, one
stderr line, no output folder left behind."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from _cli_data import assert_one_error_line

from ibiscape_eval.io.sequence import read_sequence_yaml


def test_help_has_example_and_no_render_note(run_cli) -> None:
    res = run_cli("sim", "--help")
    assert res.exit_code == 0
    assert "Examples:" in res.output and "--no-render" in res.output
    assert "--resolution" in res.output and "--export" in res.output


def test_still_imu_with_json_summary(run_cli, tmp_path: Path) -> None:
    out = tmp_path / "IMU_1_still"
    res = run_cli("sim", "--setup", "imu", "--duration-s", "5", "--seed", "3", "--out", out, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["imu_samples"] == 1001 and doc["setup"] == "imu" and doc["path"] == str(out)
    seq = read_sequence_yaml(out / "sequence.yaml")
    assert seq["generator"]["seed"] == 3 and "imu0" in seq["imus"]


def test_summary_text_with_planner(run_cli, tmp_path: Path) -> None:
    res = run_cli("sim", "--setup", "svi", "--kind", "calibration", "--duration-s", "5",
                  "--target", "aprilgrid", "--ideal", "--no-render", "--out", tmp_path / "s")
    assert res.exit_code == 0, res.output
    for word in ("length", "duration", "frames", "speed", "roll std", "pitch std", "weather"):
        assert word in res.stdout
    doc = read_sequence_yaml(tmp_path / "s" / "sequence.yaml")
    assert doc["target"]["target_type"] == "aprilgrid" and doc["imus"]["imu0"]["noise_model"] == "ideal"


def test_print_config_loads_back(run_cli, tmp_path: Path) -> None:
    res = run_cli("sim", "--setup", "esvi", "--weather", "dynamic", "--seed", "5", "--print-config")
    assert res.exit_code == 0
    doc = yaml.safe_load(res.stdout)
    assert doc["setup"] == "esvi" and doc["seed"] == 5 and "davisL" in doc["cameras"]
    (tmp_path / "c.yaml").write_text(res.stdout)
    res2 = run_cli("sim", "--config", tmp_path / "c.yaml", "--print-config")
    assert res2.stdout == res.stdout


@pytest.mark.parametrize(("yaml_text", "needles"), [
    ("setup: svi\nfoo: 1\n", ["unknown key 'foo'", "duration_s"]),
    ("setup: helicopter\n", ["unknown setup 'helicopter'"]),
    ("gt_rate_hz: 0\n", ["gt_rate_hz must be a positive"]),
    ("cameras: {rgbR: {position_m: [0.0, 0.19, 2.8]}}\n", ["inside each other", "rgbL", "rgbR"]),
])
def test_bad_config_file(run_cli, tmp_path: Path, yaml_text: str, needles: tuple[str, ...]) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml_text)
    out = tmp_path / "out"
    assert_one_error_line(run_cli("sim", "--config", cfg, "--out", out), *needles, "bad.yaml")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


@pytest.mark.parametrize(("args", "needles"), [
    (("--duration-s", "-3"), ["duration_s must be a positive"]),
    (("--duration-s", "0"), ["duration_s must be a positive"]),
    (("--resolution", "0"), ["resolution '0'", "8..8192"]),
    (("--resolution", "64x"), ["resolution '64x'", "WxH"]),
    (("--kind", "calibration", "--scenario", "accident"), ["accident needs kind slam"]),
])
def test_bad_options(run_cli, tmp_path: Path, args: tuple[str, ...], needles: list[str]) -> None:
    out = tmp_path / "out"
    assert_one_error_line(run_cli("sim", "--setup", "svi", *args, "--out", out), *needles)
    assert not out.exists() and not list(tmp_path.iterdir())


def test_unknown_preset_choice_exits_2(run_cli, tmp_path: Path) -> None:
    res = run_cli("sim", "--setup", "stereo", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "stereo" in res.stderr
    assert not list(tmp_path.iterdir())


def test_non_empty_out_needs_overwrite(run_cli, tmp_path: Path) -> None:
    out = tmp_path / "seq"
    out.mkdir()
    (out / "old.txt").write_text("old")
    args = ("sim", "--setup", "imu", "--duration-s", "1", "--out", out)
    assert_one_error_line(run_cli(*args), "not empty", "--overwrite", str(out))
    assert [p.name for p in out.iterdir()] == ["old.txt"]
    res = run_cli(*args, "--overwrite")
    assert res.exit_code == 0, res.output
    assert not (out / "old.txt").exists() and (out / "sequence.yaml").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]


def test_impossible_route(run_cli, tmp_path: Path) -> None:
    cfg = tmp_path / "slow.yaml"
    cfg.write_text("motion: {max_speed_m_s: 0.000001}\n")
    out = tmp_path / "out"
    res = run_cli("sim", "--config", cfg, "--duration-s", "5", "--out", out)
    assert res.exit_code == 2 and "error:" in res.stderr and "Traceback" not in res.output
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["slow.yaml"]
