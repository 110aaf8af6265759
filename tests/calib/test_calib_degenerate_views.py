"""Views that do not constrain the focal length are refused, not solved into a confident wrong
number: known answers from projected boards, and the real EuRoC excerpt."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from _calib_render import board_pose, sim_target
from _calib_scenes import CAM_RADTAN
from click.testing import CliRunner

from ibiscape_eval.calib.calibrate import MIN_VIEW_SPREAD_DEG, Observations, calibrate
from ibiscape_eval.calib.detect import Detection
from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError

EUROC_REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "euroc_v1_01_kimera"


def _projected_views(tilt_jitter_deg: float, n: int = 6, seed: int = 3):
    """``n`` checkerboard views 4-5.5 m away, all tilted by (15, 10) deg plus a uniform jitter of
    +-``tilt_jitter_deg`` / 2 about both board axes; corners projected with 0.1 px noise."""
    rng = np.random.default_rng(seed)
    target = sim_target("checkerboard")
    obj = target.object_points()
    size = (CAM_RADTAN.width_px, CAM_RADTAN.height_px)
    dets, normals = [], []
    for _ in range(n):
        z = rng.uniform(4.0, 5.5)
        T = board_pose("checkerboard", distance_m=z,
                       tilt_deg=(15 + rng.uniform(-0.5, 0.5) * tilt_jitter_deg,
                                 10 + rng.uniform(-0.5, 0.5) * tilt_jitter_deg),
                       roll_deg=0.0, offset_m=(rng.uniform(-0.04, 0.04) * z, rng.uniform(-0.04, 0.04) * z))
        uv = CAM_RADTAN.project(obj @ T[:3, :3].T + T[:3, 3]) + rng.normal(0, 0.1, (len(obj), 2))
        assert np.all((uv > 0) & (uv < np.array(size) - 1))
        dets.append(Detection(np.arange(len(obj)), uv, size))
        normals.append(T[:3, 2])
    nn = np.array(normals)
    spread = float(np.degrees(np.arccos(np.clip(nn @ nn.T, -1, 1).min())))
    return target, [Observations("cam0", size, dets)], spread


def test_views_of_one_orientation_are_refused_with_the_spread_and_what_to_do():
    target, obs, spread = _projected_views(1.5)
    assert spread < 2.0
    with pytest.raises(CalibrationError) as e:
        calibrate(target, obs)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("cam0: ")
    measured = float(msg.split("varies by only ")[1].split(" deg")[0])
    assert abs(measured - spread) < 0.05, (measured, spread)  # the spread is measured, not guessed
    assert "tilted by 20-40 deg" in msg and "--check" in msg


def test_the_same_board_tilted_30_deg_apart_is_calibrated_within_its_std():
    target, obs, spread = _projected_views(30.0)
    assert spread > 4 * MIN_VIEW_SPREAD_DEG
    res = calibrate(target, obs)
    c = res.cameras[0]
    e = np.array(c.camera.intrinsics) - CAM_RADTAN.intrinsics
    assert np.all(np.abs(e) < 3 * np.array(c.std["intrinsics"])), (e, c.std["intrinsics"])
    assert abs(e[0]) < 3.0  # and the std is not vacuous: fx within 1 % of 330 px


def test_the_threshold_is_a_parameter():
    """A caller who knows better (e.g. a fixed rig with a known principal point) may lower it."""
    target, obs, _ = _projected_views(1.5)
    res = calibrate(target, obs, min_view_spread_deg=0.0)
    assert res.n_views == 6


def test_calib_cli_on_the_real_near_identical_views_exits_2_naming_the_camera(tmp_path):
    board = tmp_path / "checker.yaml"  # the EuRoC Vicon-room wall board, 6 x 7 inner corners
    board.write_text(yaml.safe_dump({"target_type": "checkerboard", "targetRows": 6, "targetCols": 7,
                                     "rowSpacingMeters": 0.06, "colSpacingMeters": 0.06}))
    out = tmp_path / "camchain.yaml"
    res = CliRunner().invoke(cli, ["calib", str(EUROC_REAL), "--target", str(board), "--yaml", str(out),
                                   "--plot", str(tmp_path / "plots")])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "cam0" in lines[0] and "deg" in lines[0] and "Traceback" not in res.stderr, \
        res.stderr
    assert not out.exists() and not (tmp_path / "plots").exists()
