"""The camera-IMU calibration's typed pieces: spline pieces, options, typed errors, frozen problem."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ibiscape_eval.calib.imu_camera import (
    ImuCameraOptions,
    ImuCoverageError,
    ImuRateError,
    ImuStreamError,
    SequenceOptions,
)
from ibiscape_eval.calib.imu_camera.calibrate import _pieces
from ibiscape_eval.calib.imu_camera.problem import CameraBlock, Piece, Problem
from ibiscape_eval.calib.imu_camera.result import CameraImuCalibration, Excitation, same
from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, IbiscapeError


def test_piece_ends_at_its_last_knot():
    p = Piece(2.0, 5, 8, 0.05)
    assert p.t1_s == pytest.approx(2.25) and p.t1_s != p.t0_s
    assert p.n_ctrl == 8
    t = np.array([1.99, 2.0, 2.1, 2.25, 2.2501])
    assert p.covers(t).tolist() == [False, True, True, True, False]


def test_pieces_cut_at_gaps_and_stay_inside_the_imu_span():
    t = np.r_[np.arange(1.0, 3.0, 0.1), np.arange(6.0, 7.0, 0.1)]  # a 3 s gap without the target
    pieces = _pieces(t, 0.05, 1.0, 0.2, 0.0, 7.0)
    assert len(pieces) == 2
    a, b = pieces
    assert a.offset == 0 and b.offset == a.n_ctrl  # control points follow each other
    assert a.t0_s == pytest.approx(0.8) and a.t1_s >= 2.9 + 0.2 - 1e-9
    assert b.t0_s == pytest.approx(5.8) and b.t1_s <= 7.0
    cam = CameraModel(64, 64, 50.0, 50.0, 31.5, 31.5)
    block = CameraBlock("c", cam, np.zeros(1), np.zeros((1, 1, 3)), np.zeros((1, 1, 2)), np.ones((1, 1)))
    prob = Problem(dt_s=0.05, pieces=pieces, n_ctrl=b.offset + b.n_ctrl, bias_t0_s=a.t0_s, bias_dt_s=1.0,
                   n_bias=2, imu_t_s=np.zeros(0), gyro=np.zeros((0, 3)), accel=np.zeros((0, 3)),
                   sigma_gyro=1.0, sigma_accel=1.0, bias_walk_sigma=np.ones(6), gravity_m_s2=9.81,
                   cams=(block,), sigma_px=0.3)
    base, u, ok = prob.locate(np.array([a.t1_s - 1e-9, 4.0, b.t0_s + 0.025]))
    assert ok.tolist() == [True, False, True]
    assert base[0] == a.offset + a.n_seg - 1 and u[0] == pytest.approx(1.0)  # the last segment's end
    assert base[2] == b.offset and u[2] == pytest.approx(0.5)
    with pytest.raises(dataclasses.FrozenInstanceError):  # a changed problem is a new value
        prob.sigma_px = 1.0  # type: ignore[misc]


def test_typed_imu_errors_carry_their_fields_and_name_the_file():
    e = ImuRateError(100.0, 200.0)
    assert isinstance(e, ImuStreamError) and isinstance(e, CalibrationError)
    assert str(e) == ("imu.yaml says update_rate 100 Hz but the IMU data run at 200.00 Hz; fix "
                      "update_rate or give the imu.yaml of this IMU")
    named = e.at("/d/imu0.csv")
    assert isinstance(named, ImuRateError) and named.source == "/d/imu0.csv"
    assert str(named) == f"/d/imu0.csv: {e}" and named.update_rate_hz == 100.0
    c = ImuCoverageError("rgbL", (1, 2), (3, 4))
    assert c.camera == "rgbL" and c.imu_ns == (1, 2) and c.images_ns == (3, 4)
    assert "does not cover the images of camera rgbL (3..4 ns)" in str(c)
    assert str(c.at("x.csv")).startswith("x.csv: the IMU stream (1..2 ns)")


def test_options_are_checked():
    with pytest.raises(IbiscapeError, match="frame_step must be an integer >= 1, got 0"):
        SequenceOptions(frame_step=0)
    with pytest.raises(IbiscapeError, match="sigma_px, knot_rate_hz and bias_knot_s must be > 0"):
        ImuCameraOptions(sigma_px=0.0).check()
    assert SequenceOptions().solve_options().refine_intrinsics  # own intrinsics are refined
    assert not SequenceOptions(camchain="c.yaml").solve_options().refine_intrinsics


def test_value_equality_of_results():
    e = Excitation(np.array([0.1, np.nan, 0.2]), np.ones(3), 12.0, 0.02, ("y",), True)
    back = Excitation.from_dict(e.to_dict())
    assert back == e and back.to_dict() == e.to_dict()
    assert dataclasses.replace(e, duration_s=12.5) != e
    assert same([1.0, float("nan")], (1.0, float("nan"))) and not same({"a": 1}, {"b": 1})
    # a camera without distortion reads back as radtan with zero coefficients: the same camera
    cam = CameraModel(64, 48, 50.0, 51.0, 31.5, 23.5)
    cal = CameraImuCalibration("c", cam, np.eye(4), 0.01, np.full(3, 0.1), np.full(3, 0.002),
                               np.full(3, 0.003), 1e-4, float("nan"), 12, 480)
    back_cal = CameraImuCalibration.from_dict(cal.to_dict())
    assert back_cal == cal and back_cal.camera.distortion == "radtan"
    assert dataclasses.replace(cal, camera=dataclasses.replace(cam, fx=50.5)) != cal
