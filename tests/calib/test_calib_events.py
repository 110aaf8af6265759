"""Event cameras: frames reconstructed from events (blinking target) are detected and calibrated."""

from __future__ import annotations

import numpy as np
from _calib_scenes import dvs_scene

from ibiscape_eval.calib.calibrate import Observations, calibrate
from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.calib.events import choose_reconstruction, event_frame, event_frame_loader


def test_reconstruction_is_chosen_and_corners_are_accurate():
    target, cam, poses, windows, events = dvs_scene()
    method, info = choose_reconstruction(lambda i: events[i], np.array(windows), (cam.width_px, cam.height_px),
                                         target, n_probe=4)
    assert method == "accumulate-signed"
    assert info["corners_found"]["accumulate-signed"] >= max(info["corners_found"].values()) > 0
    obj = target.object_points()
    errs = []
    for (a, b), ev, T in zip(windows, events, poses, strict=True):
        det = detect_corners(event_frame(ev, (cam.width_px, cam.height_px), (a, b)), target)
        if det is None:
            continue
        best = min((np.hypot(*(det.corners_px - cam.project(obj[p[det.ids]] @ T[:3, :3].T + T[:3, 3])).T)
                    for p in target.symmetries()), key=lambda e: float(e.mean()))
        errs.append(best)
    assert len(errs) >= 6
    e = np.concatenate(errs)
    assert np.sqrt(np.mean(e**2)) < 0.3


def test_dvs_mono_calibration():
    target, cam, _, windows, events = dvs_scene()
    load = event_frame_loader(lambda i: events[i], np.array(windows), (cam.width_px, cam.height_px),
                              "accumulate-signed")
    dets = [detect_corners(load(i), target) for i in range(len(windows))]
    res = calibrate(target, [Observations("davisL", (cam.width_px, cam.height_px), dets)])
    e = np.array(res.cameras[0].camera.intrinsics) - cam.intrinsics
    assert np.all(np.abs(e) < 1.0), e
    assert res.rms_px < 0.3
