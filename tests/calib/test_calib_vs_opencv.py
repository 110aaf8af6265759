"""Our calibration against a careful OpenCV pipeline on identical views (tolerance:
focal within 0.5 %, baseline within 1 %, our RMS not above OpenCV's)."""

from __future__ import annotations

import numpy as np
import pytest
from _calib_scenes import stereo_scene
from _opencv_peer import opencv_stereo

from ibiscape_eval.calib.calibrate import Observations, calibrate


@pytest.mark.parametrize(("kind", "equi"), [("checkerboard", False), ("aprilgrid", False),
                                            ("checkerboard", True)])
def test_same_result_as_opencv_on_identical_views(kind, equi):
    target, cams, _T10, _, _, obs = stereo_scene(kind, equi=equi)
    size = (cams[0].width_px, cams[0].height_px)
    cv = opencv_stereo(target, obs, size, equi=equi)
    # the same views for both: those seen by both cameras
    keep = set(cv["views"])
    same = [Observations(o.name, o.image_size, [d if v in keep else None for v, d in enumerate(o.detections)])
            for o in obs]
    ours = calibrate(target, same, model="pinhole-equi" if equi else "pinhole-radtan")
    assert ours.n_views == cv["n_views"]
    for c, K in zip(ours.cameras, cv["K"], strict=True):
        f = np.array([c.camera.fx, c.camera.fy])
        assert np.all(np.abs(f / np.diag(K)[:2] - 1) < 0.005), (f, np.diag(K))
    assert abs(ours.baselines_m[0] / cv["baseline_m"] - 1) < 0.01
    # OpenCV's RMS is over both cameras' corners like ours; ours rejects no corner on clean views
    assert ours.rms_px <= cv["rms_px"] + 0.005, (ours.rms_px, cv["rms_px"])
