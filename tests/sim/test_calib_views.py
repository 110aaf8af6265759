"""sim.calib_views: rig poses that show the whole board, varied (no rendering here; the rendered
sequences are calibrated in tests/calib/test_calib_rendered.py)."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.calib_views import calibration_view_poses
from ibiscape_eval.sim.world import build_world

CAM = CameraModel(320, 240, 160.0, 160.0, 159.5, 119.5, "radtan", (0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("kind", ["checkerboard", "aprilgrid"])
def test_poses_show_every_corner_in_both_cameras_and_vary(kind):
    board = build_world(kind="calibration", seed=0, target=kind, bumps=False).target_named(kind)
    T01 = np.eye(4)
    T01[0, 3] = 0.4
    poses = calibration_view_poses(board, {"a": CAM, "b": CAM}, {"a": np.eye(4), "b": T01}, 12,
                                   seed=1, distance_m=(3.0, 15.0), tilt_max_deg=35.0)
    X = board.corners_world_m()
    tilts, dists = [], []
    for T in poses:
        for T_wc in (T, T @ T01):
            pc = (X - T_wc[:3, 3]) @ T_wc[:3, :3]
            uv = CAM.project(pc)
            assert np.all(uv >= 4.0) and np.all(uv <= [315.0, 235.0])
        view = T[:3, 3] - board.centre_world_m
        dists.append(np.linalg.norm(view))
        tilts.append(np.degrees(np.arccos(view @ board.observer_normal_world / dists[-1])))
        assert T[2, 3] >= 0.5
    assert min(dists) >= 3.0 and max(dists) <= 15.0 + 1e-9
    assert max(tilts) > 15.0 and max(tilts) <= 35.0 + 1e-9  # tilted views, not just head-on


def test_impossible_rig_is_refused():
    board = build_world(kind="calibration", seed=0, bumps=False).target_named("checkerboard")
    tiny = CameraModel(40, 40, 400.0, 400.0, 19.5, 19.5, "radtan", (0.0, 0.0, 0.0, 0.0))
    with pytest.raises(IbiscapeError, match="whole board"):
        calibration_view_poses(board, {"a": tiny}, {"a": np.eye(4)}, 3, max_tries=200)
