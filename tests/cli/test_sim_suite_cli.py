"""``ibiscape-eval sim suite`` beside ``ibiscape-eval sim [options]``."""

from __future__ import annotations

import json

from click.testing import CliRunner

from ibiscape_eval.cli.main import cli


def test_list_prints_the_34_entries() -> None:
    r = CliRunner().invoke(cli, ["sim", "suite", "--list", "--scale", "0.05"])
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert len(lines) == 34
    assert lines[0].split()[:2] == ["IMU_calib_1", "imu"] and "30240 s" in lines[0]
    assert "320 px" in lines[1] and " 12 s" in lines[1] and "checkerboard" in lines[1]
    slam = next(ln for ln in lines if ln.startswith("SVI_slam_clear_1"))
    assert "224 px" in slam and " 3 s" in slam
    doc = json.loads(CliRunner().invoke(cli, ["sim", "suite", "--list", "--json"]).stdout)
    assert doc["scale"] == 1.0 and len(doc["sequences"]) == 34


def test_suite_writes_sequences_and_manifest(tmp_path) -> None:
    out = tmp_path / "suite"
    args = ["sim", "suite", "--out", str(out), "--scale", "0.002", "--no-render", "--workers", "1",
            "--only", "RGBD_slam_mod_1"]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    assert "RGBD_slam_mod_1" in r.stdout and "1/1 sequences" in r.stdout
    assert (out / "RGBD_slam_mod_1" / "sequence.yaml").is_file()
    man = json.loads((out / "suite.json").read_text())
    assert [s["name"] for s in man["sequences"]] == ["RGBD_slam_mod_1"]
    assert man["sequences"][0]["status"] == "ok" and man["sequences"][0]["reused"] is False
    again = CliRunner().invoke(cli, [*args, "--json"])
    assert again.exit_code == 0, again.output
    assert json.loads(again.stdout)["sequences"][0]["reused"] is True  # kept, not regenerated


def test_bad_options_are_one_line() -> None:
    r = CliRunner().invoke(cli, ["sim", "suite", "--out", "x", "--scale", "0"])
    assert r.exit_code == 2 and "scale must be a number in (0, 1]" in r.stderr
    assert r.stderr.count("\n") == 1
    r = CliRunner().invoke(cli, ["sim", "suite", "--scale", "0.1"])
    assert r.exit_code == 2 and "--out" in r.output
    r = CliRunner().invoke(cli, ["sim", "suite", "--out", "x", "--only", "SVI_calib_7"])
    assert r.exit_code == 2 and "unknown suite sequence(s) SVI_calib_7" in r.stderr


def test_plain_sim_still_works_and_mentions_the_suite(tmp_path) -> None:
    r = CliRunner().invoke(cli, ["sim", "--setup", "svi", "--duration-s", "1", "--no-render",
                                 "--out", str(tmp_path / "s")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "s" / "sequence.yaml").is_file()
    assert "sim suite" in CliRunner().invoke(cli, ["sim", "--help"]).stdout
    top = CliRunner().invoke(cli, ["--help"]).stdout
    assert "sim suite" in top and "benchmark" in top
