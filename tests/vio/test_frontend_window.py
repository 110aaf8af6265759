"""The KLT window of the stereo front end: ``klt_window_px`` at 512 px, scaled with the square root
of the width and rounded to a multiple of 8 px (OpenCV's KLT takes each window row 8 pixels at a
time), at least 12 px."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.vio.frontend import StereoFrontEnd
from ibiscape_eval.vio.params import VioParams
from ibiscape_eval.vio.rig import StereoRig


def _front_end(width: int, **kw: int) -> StereoFrontEnd:
    cam = CameraModel.from_fov(width, width, 90.0)
    T_b_r = np.eye(4)
    T_b_r[0, 3] = 0.3
    return StereoFrontEnd(StereoRig(cam, cam, np.eye(4), T_b_r), VioParams(**kw))


@pytest.mark.parametrize(("width", "win"), [(128, 12), (256, 12), (346, 16), (512, 16),
                                            (1024, 24), (2048, 32)])
def test_default_window_by_width(width: int, win: int) -> None:
    assert _front_end(width).win == (win, win)


@pytest.mark.parametrize(("klt_window_px", "win"), [(21, 24), (19, 16), (27, 24), (29, 32)])
def test_the_option_is_rounded_to_a_multiple_of_8(klt_window_px: int, win: int) -> None:
    assert _front_end(512, klt_window_px=klt_window_px).win == (win, win)
