"""Calibration targets: Kalibr geometry and numbering, textures found by OpenCV."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget
from ibiscape_eval.sim.targets import board_pose, make_target


def test_checkerboard_geometry_and_detection():
    t = make_target("checkerboard", T_world_target=board_pose("checkerboard", [90, -4, 3], math.pi))
    k = t.kalibr
    assert (k["targetRows"], k["targetCols"]) == (7, 7)
    assert t.corners_target_m.shape == (49, 3)
    # row-major: corner 8 is row 1, column 1
    assert np.allclose(t.corners_target_m[8], [k["colSpacingMeters"], k["rowSpacingMeters"], 0])
    img = t.texture(60.0)
    ok, found = cv2.findChessboardCorners(img, (7, 7))
    assert ok
    expected = t.texture_px_from_target(t.corners_target_m[:, :2], 60.0)
    found = found.reshape(-1, 2)
    # OpenCV may start from either end of the symmetric board: compare as sets of points
    d = np.linalg.norm(found[:, None] - expected[None], axis=-1).min(1)
    assert d.max() < 1.0
    # z points away from the observer, centre where asked
    assert np.allclose(t.centre_world_m, [90, -4, 3])
    assert np.allclose(t.observer_normal_world, [-1, 0, 0], atol=1e-12)
    assert np.allclose(t.T_world_target[:3, 2], [1, 0, 0], atol=1e-12)


def test_aprilgrid_numbering_matches_kalibr():
    c = CalibrationTarget.aprilgrid(6, 6, 0.4, 0.3).object_points()
    assert c.shape == (144, 3)
    # corner (r, c) = (1, 3): x = 1 * 1.3 * 0.4 + 0.4, y = 0.4
    assert np.allclose(c[1 * 12 + 3], [0.92, 0.4, 0.0])
    # tag 7 -> base = 1*4*6 + 1*2 = 26: corners base, base+1, base+13, base+12 form its square
    sq = c[[26, 27, 39, 38], :2]
    assert np.allclose(np.diff(np.vstack((sq, sq[:1])), axis=0), [[0.4, 0], [0, 0.4], [-0.4, 0], [0, -0.4]])


def test_aprilgrid_texture_detected_with_kalibr_corner_order():
    t = make_target("aprilgrid", T_world_target=board_pose("aprilgrid", [90, 4, 3], math.pi))
    assert t.kalibr == {"target_type": "aprilgrid", "tagRows": 6, "tagCols": 6, "tagSize": 0.55, "tagSpacing": 0.3}
    ppm = 100.0
    img = t.texture(ppm)
    assert img.dtype == np.uint8 and set(np.unique(img)) == {0, 255}
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = 2
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params)
    corners, ids, _ = det.detectMarkers(img)
    assert ids is not None and sorted(ids.ravel().tolist()) == list(range(36))
    for quad, tag in zip(corners, ids.ravel(), strict=True):
        base = (tag // 6) * 24 + (tag % 6) * 2
        # OpenCV's first corner is the tag's bottom-right corner on the board, then BL, TL, TR
        order = [base + 1, base, base + 12, base + 13]
        expected = t.texture_px_from_target(t.corners_target_m[order, :2], ppm)
        assert np.abs(quad.reshape(4, 2) - expected).max() < 2.5  # tags are 40 px wide
    # printed face toward the observer (at smaller x); Kalibr's y axis points up
    assert np.allclose(t.observer_normal_world, [-1, 0, 0], atol=1e-12)
    assert np.allclose(t.T_world_target[:3, 1], [0, 0, 1], atol=1e-12)
    assert np.allclose(t.centre_world_m, [90, 4, 3])


def test_corners_world_and_to_dict():
    T = board_pose("checkerboard", [10, 0, 2], 0.3)
    t = make_target("checkerboard", T_world_target=T)
    w = t.corners_world_m()
    assert np.allclose(w, t.corners_target_m @ T[:3, :3].T + T[:3, 3])
    d = t.to_dict()
    assert d["targetRows"] == 7 and np.allclose(d["T_world_target"], T)
    assert d["board_size_m"][0] > 4.0


@pytest.mark.parametrize(
    "kind, T, match",
    [
        ("circles", np.eye(4), "unknown"),
        ("checkerboard", np.eye(3), "4x4"),
        ("aprilgrid", np.diag([1.0, 1.0, -1.0, 1.0]), "rotation"),
    ],
)
def test_bad_targets(kind, T, match):
    with pytest.raises(IbiscapeError, match=match):
        make_target(kind, T_world_target=T)
