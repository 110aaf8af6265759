"""``ibiscape-eval sim`` rendering options: --render/--no-render, --resolution, --export, and the
camera errors (exit 2, one stderr line, no output folder)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from _cli_data import assert_one_error_line

from ibiscape_eval.io.images import read_png


def test_cli_renders_by_default_with_resolution(run_cli, tmp_path: Path) -> None:
    out = tmp_path / "s"
    res = run_cli("sim", "--setup", "svi", "--kind", "calibration", "--duration-s", "0.2",
                  "--resolution", "40x30", "--out", out, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["rendered_cameras"] == ["rgbL", "rgbR"] and doc["frames"] == 5
    assert read_png(next((out / "rgbL" / "frames").iterdir())).shape == (30, 40, 3)
    res = run_cli("sim", "--setup", "svi", "--duration-s", "0.2", "--no-render", "--out", tmp_path / "n")
    assert res.exit_code == 0 and "not rendered" in res.stdout and not (tmp_path / "n" / "rgbL").exists()


def test_cli_export_tum_rgbd(run_cli, tmp_path: Path) -> None:
    out = tmp_path / "r"
    res = run_cli("sim", "--setup", "rgbd", "--duration-s", "0.2", "--resolution", "32",
                  "--export", "tum-rgbd", "--out", out)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "r_tum-rgbd" / "association.txt").is_file() and "export" in res.stdout


@pytest.mark.parametrize(("args", "needles"), [
    (("--setup", "svi", "--export", "tum-rgbd"), ["tum-rgbd", "depth"]),
    (("--setup", "svi", "--no-render", "--export", "euroc"), ["--export euroc", "--no-render"]),
    (("--setup", "svi", "--resolution", "640x"), ["resolution '640x'"]),
])
def test_cli_bad_render_options_write_nothing(run_cli, tmp_path: Path, args: tuple[str, ...],
                                              needles: list[str]) -> None:
    out = tmp_path / "o"
    assert_one_error_line(run_cli("sim", "--duration-s", "0.2", *args, "--out", out), *needles)
    assert not list(tmp_path.iterdir())


def test_cli_distortion_that_does_not_invert(run_cli, tmp_path: Path) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("setup: svi\ncameras:\n  rgbL: {fov_deg: 120.0, distortion_model: radtan, "
                   "distortion_coeffs: [-0.9, 0.0, 0.0, 0.0]}\n")
    out = tmp_path / "o"
    assert_one_error_line(run_cli("sim", "--config", cfg, "--duration-s", "0.2", "--resolution", "48",
                                  "--out", out), "does not invert", "u=", "smaller coefficients")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml"]


@pytest.mark.parametrize(("yaml_text", "needles"), [
    ("cameras: {rgbL: {distortion_model: fisheye}}\n", ["distortion_model", "fisheye"]),
    ("cameras: {rgbL: {distortion_coeffs: [0.1, 0, 0, 0]}}\n", ["need a distortion_model"]),
    ("cameras: {rgbL: {width_px: 100, height_px: 4000, fov_deg: 150.0}}\n", ["vertical FOV"]),
    ("cameras: {rgbL: {width_px: 4}}\n", ["width_px", "8..8192"]),
    ("render: {target_supersample: 0}\n", ["target_supersample"]),
])
def test_cli_bad_camera_config(run_cli, tmp_path: Path, yaml_text: str, needles: list[str]) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("setup: svi\n" + yaml_text)
    out = tmp_path / "o"
    assert_one_error_line(run_cli("sim", "--config", cfg, "--out", out), *needles)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml"]
