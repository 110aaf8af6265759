"""``ibiscape-eval calib`` on real stereo checkerboard photos
(tests/data/real/opencv_stereo_checkerboard_640x480: OpenCV's 13 real 640x480 stereo sample pairs,
9x6 inner corners, no ground truth) against a plain OpenCV pipeline on the same images."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli

DATA = Path(__file__).resolve().parents[1] / "data" / "real" / "opencv_stereo_checkerboard_640x480"


@pytest.fixture(scope="module")
def ours() -> dict:
    res = CliRunner().invoke(cli, ["calib", "--target", str(DATA / "target.yaml"), "--images",
                                   f"cam0={DATA}/left*.jpg", "--images", f"cam1={DATA}/right*.jpg",
                                   "--json"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def _opencv() -> dict:
    """findChessboardCorners + cornerSubPix, calibrateCamera per camera, stereoCalibrate.

    cornerSubPix's half-window is 5 px: the squares are 29-45 px here, and the usual 11 (a 23 px
    window) reaches across most of a square and pulls the corners (RMS 0.45 px instead of 0.22,
    right focal length 1 % higher)."""
    t = yaml.safe_load((DATA / "target.yaml").read_text())
    cols, rows = t["targetCols"], t["targetRows"]
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * t["colSpacingMeters"]
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)
    pts: list[list[np.ndarray]] = [[], []]
    for fl in sorted(DATA.glob("left*.jpg")):
        imgs = []
        for f in (fl, DATA / fl.name.replace("left", "right")):
            g = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
            assert g is not None, f
            imgs.append(g)
        found = [cv2.findChessboardCorners(g, (cols, rows)) for g in imgs]
        assert all(ok for ok, _ in found)
        for k, (g, (_, c)) in enumerate(zip(imgs, found, strict=True)):
            pts[k].append(cv2.cornerSubPix(g, c, (5, 5), (-1, -1), crit))
    size = imgs[0].shape[::-1]
    objs = [obj] * len(pts[0])
    cams = [cv2.calibrateCamera(objs, p, size, None, None)[1:3] for p in pts]
    rms, *_, T, _, _ = cv2.stereoCalibrate(objs, pts[0], pts[1], *cams[0], *cams[1], size,
                                           flags=cv2.CALIB_FIX_INTRINSIC)
    return {"K": [K for K, _ in cams], "baseline": float(np.linalg.norm(T)), "rms_px": rms}


def test_real_stereo_photos_agree_with_opencv(ours):
    """All 13 views used; focal lengths within 1 % of OpenCV's and within 2 of our std of each
    other (fx = fy: square pixels), the baseline within 2 %, our RMS not above OpenCV's."""
    assert ours["n_views"] == 13
    assert [c["frames_tried"] for c in ours["detection"]["cameras"]] == [13, 13]
    assert [c["target_found"] for c in ours["detection"]["cameras"]] == [13, 13]
    peer = _opencv()
    for cam, K in zip(ours["cameras"], peer["K"], strict=True):
        fx, fy = cam["intrinsics"][:2]
        sx, sy = cam["intrinsics_std"][:2]
        assert abs(fx - K[0, 0]) < 0.01 * K[0, 0] and abs(fy - K[1, 1]) < 0.01 * K[1, 1]
        assert abs(fx - fy) < 2 * np.hypot(sx, sy)
        assert cam["resolution"] == [640, 480]
    b = ours["chain"][0]["baseline_m"]
    assert abs(b - peer["baseline"]) < 0.02 * peer["baseline"]
    assert ours["rms_px"] <= peer["rms_px"]
