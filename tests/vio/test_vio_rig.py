"""Stereo rectification: points projected by the raw (distorted, verged) cameras come back as the
true 3-D points after rectification and triangulation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError
from ibiscape_eval.vio.rig import StereoRig

R_FWD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _T(R, t):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


@pytest.mark.parametrize("distortion", ["none", "radtan", "equidistant"])
def test_rectified_triangulation_recovers_points(distortion):
    coeffs = {"none": (0, 0, 0, 0), "radtan": (-0.12, 0.03, 0.001, -0.0005),
              "equidistant": (0.05, -0.01, 0.002, 0.0)}[distortion]
    left = CameraModel(640, 480, 400.0, 402.0, 321.0, 238.0, distortion, coeffs)
    right = CameraModel(640, 480, 398.0, 399.0, 318.0, 242.0, distortion, coeffs)
    R_small = Rotation.from_euler("xyz", [0.4, -0.8, 0.3], degrees=True).as_matrix()
    rig = StereoRig(left, right, _T(R_FWD, [0.0, 0.25, 1.5]),
                    _T(R_FWD @ R_small, [0.01, -0.25, 1.49]))
    rect = rig.rectified()
    assert rect.baseline_m == pytest.approx(0.5, abs=0.01)
    rng = np.random.default_rng(0)
    pts_b = np.column_stack([rng.uniform(4, 30, 200), rng.uniform(-6, 6, 200),
                             rng.uniform(-1, 4, 200)])
    uv = []
    for cam, T in ((left, rig.T_body_left), (right, rig.T_body_right)):
        Ti = np.linalg.inv(T)
        uv.append(cam.project(pts_b @ Ti[:3, :3].T + Ti[:3, 3]))
    inside = np.all([(u[:, 0] > 5) & (u[:, 0] < 635) & (u[:, 1] > 5) & (u[:, 1] < 475) for u in uv],
                    axis=0)
    assert inside.sum() > 50
    rl = rig.rectify_points(uv[0][inside], "left")
    rr = rig.rectify_points(uv[1][inside], "right")
    np.testing.assert_allclose(rl[:, 1], rr[:, 1], atol=0.02)  # rows agree after rectification
    p_rect = rect.triangulate(rl[:, 0], rr[:, 0], rl[:, 1])
    p_b = p_rect @ rect.T_body_rect[:3, :3].T + rect.T_body_rect[:3, 3]
    err = np.linalg.norm(p_b - pts_b[inside], axis=1) / np.linalg.norm(pts_b[inside], axis=1)
    assert err.max() < 2e-3
    uL, uR, v = rect.project(p_rect)
    np.testing.assert_allclose(np.column_stack([uL, uR, v]),
                               np.column_stack([rl[:, 0], rr[:, 0], rl[:, 1]]), atol=1e-9)


def test_parallel_pinhole_pair_is_used_as_it_is():
    cam = CameraModel.from_fov(512, 512, 90.0)
    rig = StereoRig(cam, cam, _T(R_FWD, [0, 0.2, 2.8]), _T(R_FWD, [0, -0.2, 2.8]))
    rect = rig.rectified()
    assert (rect.fx, rect.cx, rect.baseline_m) == (cam.fx, cam.cx, pytest.approx(0.4))
    np.testing.assert_array_equal(rig.rectify_points([[10.5, 20.25]], "right"), [[10.5, 20.25]])


def test_bad_rigs_are_refused():
    cam = CameraModel.from_fov(512, 512, 90.0)
    with pytest.raises(CalibrationError, match="coincide"):
        StereoRig(cam, cam, _T(R_FWD, [0, 0, 0]), _T(R_FWD, [0, 0, 0]))
    with pytest.raises(CalibrationError, match="differ in size"):
        StereoRig(cam, CameraModel.from_fov(640, 480, 90.0), _T(R_FWD, [0, 0.2, 0]),
                  _T(R_FWD, [0, -0.2, 0]))
    with pytest.raises(CalibrationError, match="rotation"):
        StereoRig(cam, cam, _T(2 * R_FWD, [0, 0.2, 0]), _T(R_FWD, [0, -0.2, 0]))
