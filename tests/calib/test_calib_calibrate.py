"""Calibration on rendered targets with known intrinsics, distortion and baseline."""

from __future__ import annotations

import numpy as np
import pytest
from _calib_scenes import CAM_RADTAN, stereo_scene

from ibiscape_eval.calib.calibrate import Observations, calibrate, evaluate
from ibiscape_eval.calib.detect import Detection
from ibiscape_eval.core.errors import CalibrationError


def _check_known_answer(res, cams, T10, *, rms=0.1, focal=0.3, pp=0.5, baseline_mm=1.0):
    for c, truth in zip(res.cameras, cams, strict=True):
        e = np.array(c.camera.intrinsics) - truth.intrinsics
        assert np.all(np.abs(e[:2]) < focal), (c.name, e)
        assert np.all(np.abs(e[2:]) < pp), (c.name, e)
        # the standard deviations are honest: errors within 4 sigma
        assert np.all(np.abs(e) < 4 * np.array(c.std["intrinsics"]) + 1e-3), (e, c.std)
        assert c.residuals.rms_px < rms
        assert c.camera.distortion == truth.distortion
    assert abs(res.baselines_m[0] - np.linalg.norm(T10[:3, 3])) * 1e3 < baseline_mm
    dR = res.T_cn_cnm1[0][:3, :3].T @ T10[:3, :3]
    assert np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))) < 0.1
    assert res.rms_px < rms


@pytest.mark.parametrize("kind", ["checkerboard", "aprilgrid"])
def test_stereo_radtan_known_answer(kind):
    target, cams, T10, _, _, obs = stereo_scene(kind)
    res = calibrate(target, obs, model="pinhole-radtan")
    _check_known_answer(res, cams, T10)
    d = res.to_dict()
    assert d["chain"][0]["from"] == "cam0" and len(d["cameras"]) == 2
    assert "+-" in d["cameras"][0]["reprojection_error_kalibr"]


@pytest.mark.parametrize("kind", ["checkerboard", "aprilgrid"])
def test_stereo_equidistant_known_answer(kind):
    target, cams, T10, _, _, obs = stereo_scene(kind, equi=True)
    res = calibrate(target, obs, model="pinhole-equi")
    _check_known_answer(res, cams, T10)


def _renumber(d: Detection, perm: np.ndarray) -> Detection:
    ids = perm[d.ids]
    o = np.argsort(ids)
    return Detection(ids[o], d.corners_px[o], d.image_size)


def test_checkerboard_numbering_is_made_consistent():
    """OpenCV may start a square board's numbering at any corner, differently per camera."""
    import cv2

    target, cams, T10, _, _, obs = stereo_scene("checkerboard")
    perms = target.symmetries()
    right = [None if d is None else _renumber(d, perms[(v * 3) % len(perms)])
             for v, d in enumerate(obs[1].detections)]
    scrambled = (obs[0], Observations("cam1", obs[1].image_size, right))
    res = calibrate(target, scrambled)
    assert res.renumbered_views >= 3
    _check_known_answer(res, cams, T10)
    # a naive pipeline (corners paired by index) fails on the same views
    obj = target.object_points().astype(np.float32)
    both = [v for v in range(len(right)) if right[v] is not None and obs[0].detections[v] is not None]
    rms, *_ = cv2.stereoCalibrate([obj] * len(both),
                                  [obs[0].detections[v].corners_px.astype(np.float32) for v in both],
                                  [right[v].corners_px.astype(np.float32) for v in both],
                                  cams[0].K, cams[0].opencv_dist, cams[1].K, cams[1].opencv_dist,
                                  (480, 360), flags=cv2.CALIB_FIX_INTRINSIC)
    assert rms > 5.0


def test_same_or_better_than_a_careful_opencv_pipeline():
    import cv2

    target, _cams, _T10, _, _, obs = stereo_scene("aprilgrid")
    res = calibrate(target, obs)
    obj = target.object_points()
    both = [v for v in range(len(obs[0].detections))
            if obs[0].detections[v] is not None and obs[1].detections[v] is not None]
    op, lp, rp = [], [], []
    for v in both:
        a, b = obs[0].detections[v], obs[1].detections[v]
        common, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
        op.append(obj[common].astype(np.float32))
        lp.append(a.corners_px[ia].astype(np.float32))
        rp.append(b.corners_px[ib].astype(np.float32))
    flags = cv2.CALIB_FIX_K3
    _, K1, D1, _, _ = cv2.calibrateCamera(op, lp, (480, 360), None, None, flags=flags)
    _, K2, D2, _, _ = cv2.calibrateCamera(op, rp, (480, 360), None, None, flags=flags)
    out = cv2.stereoCalibrate(op, lp, rp, K1, D1, K2, D2, (480, 360),
                              flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS)
    rms_cv, K1, _, K2, _, _, T = out[:7]
    for c, K in zip(res.cameras, (K1, K2), strict=True):
        assert abs(c.camera.fx / K[0, 0] - 1) < 0.005
    assert abs(res.baselines_m[0] / np.linalg.norm(T) - 1) < 0.01
    # OpenCV's stereo RMS is per coordinate pair like ours
    assert res.rms_px <= rms_cv * 1.02


def test_mono_and_outlier_rejection():
    target, cams, _, _, _, obs = stereo_scene("aprilgrid")
    rng = np.random.default_rng(0)
    dets = []
    n_bad = 0
    for d in obs[0].detections:
        if d is None:
            dets.append(None)
            continue
        c = d.corners_px.copy()
        i = rng.choice(len(c), 2, replace=False)
        c[i] += 3.0
        n_bad += 2
        dets.append(Detection(d.ids, c, d.image_size))
    res = calibrate(target, [Observations("cam0", obs[0].image_size, dets)])
    assert res.cameras[0].n_rejected >= n_bad
    assert res.cameras[0].residuals.max_px < 0.6
    e = np.array(res.cameras[0].camera.intrinsics) - cams[0].intrinsics
    assert np.all(np.abs(e) < 0.5)
    assert res.T_cn_cnm1 == () and res.baselines_m == ()


def test_too_few_views_and_no_common_views():
    target, _, _, _, _, obs = stereo_scene("checkerboard")
    seen = [v for v, d in enumerate(obs[0].detections) if d is not None]
    two = [d if v in seen[:2] else None for v, d in enumerate(obs[0].detections)]
    with pytest.raises(CalibrationError, match="only 2 usable views"):
        calibrate(target, [Observations("cam0", obs[0].image_size, two)])
    half = len(seen) // 2
    left = [d if v in seen[:half] else None for v, d in enumerate(obs[0].detections)]
    right = [d if v in seen[half:] else None for v, d in enumerate(obs[1].detections)]
    with pytest.raises(CalibrationError, match="share no view"):
        calibrate(target, [Observations("cam0", obs[0].image_size, left),
                           Observations("cam1", obs[1].image_size, right)])


def test_evaluate_a_given_calibration():
    from dataclasses import replace

    target, cams, T10, _, _, obs = stereo_scene("checkerboard")
    good = evaluate(target, obs, cams, [T10])
    assert good["rms_px"] < 0.1 and not good["outlier_views"]
    T_bad = T10.copy()
    T_bad[0, 3] -= 0.01  # 1 cm baseline error
    bad = evaluate(target, obs, [cams[0], replace(cams[1], fx=cams[1].fx + 3)], [T_bad], outlier_px=0.3)
    assert bad["rms_px"] > 3 * good["rms_px"]
    assert bad["outlier_views"]
    assert CAM_RADTAN.width_px == obs[0].image_size[0]
