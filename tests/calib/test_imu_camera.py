"""Camera-IMU calibration: known answers on simulated corner observations, the spline, bad input."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ibiscape_eval.calib.imu_camera import (
    CameraObservations,
    ImuCameraOptions,
    ImuCameraResult,
    ImuCoverageError,
    ImuData,
    ImuRateError,
    calibrate_imu_camera,
)
from ibiscape_eval.calib.imu_camera.spline import position, rotation
from ibiscape_eval.calib.imu_camera.synthetic import CalibrationScene, calibration_scene
from ibiscape_eval.core.errors import CalibrationError, FormatError
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.core.so3 import exp_so3, log_so3
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration
from ibiscape_eval.sim.config import MotionSpec

SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0171}


def _scene(*, bumps: bool = True, duration_s: float = 24.0, size: int = 768) -> CalibrationScene:
    cfg = preset("svi", "calibration", "clear", duration_s=duration_s, seed=1,
                 motion=MotionSpec(bumps=bumps))
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=size, height_px=size) for c in cfg.cameras))
    return calibration_scene(simulate_calibration(cfg, timeshifts_s=SHIFTS), noise_px=0.2,
                             min_spacing_px=4.0)


@pytest.fixture(scope="module")
def bumpy() -> CalibrationScene:
    return _scene()


@pytest.fixture(scope="module")
def bumpy_result(bumpy):
    return calibrate_imu_camera(bumpy.observations, bumpy.imu, bumpy.noise, bumpy.corners_target_m,
                                ImuCameraOptions(sigma_px=0.2))


def _errors(scene, cal):
    T = scene.T_cam_imu[cal.name]
    rot_deg = np.degrees(np.linalg.norm(log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3])))
    trans_m = np.linalg.norm(cal.T_cam_imu[:3, 3] - T[:3, 3])
    shift_s = cal.timeshift_cam_imu_s - scene.timeshift_cam_imu_s[cal.name]
    return rot_deg, trans_m, shift_s


# ------------------------------------------------------------------------------------------ spline


def test_spline_angular_velocity_matches_finite_differences():
    rng = np.random.default_rng(3)
    R = exp_so3(rng.normal(scale=0.4, size=(5, 4, 3)))
    u = rng.uniform(0, 1, 5)
    dt, h = 0.1, 1e-6
    _, w = rotation(R, u, dt)
    Rm, _ = rotation(R, u - h / dt, dt)
    Rp, _ = rotation(R, u + h / dt, dt)
    w_fd = log_so3(np.swapaxes(Rm, 1, 2) @ Rp) / (2 * h)
    np.testing.assert_allclose(w, w_fd, atol=1e-6)
    P = rng.normal(size=(5, 4, 3))
    _, v, a = position(P, u, dt)
    pm, vm, _ = position(P, u - h / dt, dt)
    pp, vp, _ = position(P, u + h / dt, dt)
    np.testing.assert_allclose(v, (pp - pm) / (2 * h), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(a, (vp - vm) / (2 * h), rtol=1e-5, atol=1e-4)


# ----------------------------------------------------------------------------------- known answers


def test_recovers_planted_extrinsics_and_time_offsets(bumpy, bumpy_result):
    res = bumpy_result
    assert [c.name for c in res.cameras] == ["rgbL", "rgbR"]
    for cal in res.cameras:
        rot_deg, trans_m, shift_s = _errors(bumpy, cal)
        assert rot_deg < 0.05, rot_deg
        assert trans_m < 0.03, trans_m
        assert abs(shift_s) < 2e-4, shift_s
        # the errors agree with the reported uncertainty
        assert rot_deg < 4 * np.linalg.norm(cal.rotation_std_deg)
        assert trans_m < 4 * np.linalg.norm(cal.translation_std_m)
        assert abs(shift_s) < 4 * cal.timeshift_std_s
        assert 0.2 < cal.reprojection_rms_px < 0.4  # 0.2 px per axis
    np.testing.assert_allclose(res.gravity_target_m_s2, bumpy.gravity_target_m_s2, atol=0.05)
    assert 0.8 < res.chi2_per_dof < 1.5
    assert res.converged
    # the stereo pair's relative extrinsics stay consistent
    T_lr = res.cameras[1].T_cam_imu @ np.linalg.inv(res.cameras[0].T_cam_imu)
    T_true = bumpy.T_cam_imu["rgbR"] @ np.linalg.inv(bumpy.T_cam_imu["rgbL"])
    assert np.linalg.norm(T_lr[:3, 3] - T_true[:3, 3]) < 0.01


def test_result_to_dict_is_strict_json(bumpy_result):
    import json

    doc = bumpy_result.to_dict()
    text = json.dumps(doc, allow_nan=False)
    assert "timeshift_cam_imu_s" in text
    assert repr(bumpy_result).startswith("ImuCameraResult([rgbL, rgbR]")


def test_result_round_trips_through_its_dict(bumpy_result):
    import json

    back = ImuCameraResult.from_dict(bumpy_result.to_dict())
    assert back == bumpy_result and back.residuals is None  # the figures' series is not the value
    doc = json.loads(json.dumps(bumpy_result.to_dict(), allow_nan=False))
    assert ImuCameraResult.from_dict(doc).to_dict() == doc
    cam = bumpy_result.cameras[0]
    moved = cam.T_cam_imu.copy()
    moved[0, 3] += 1e-12
    other = replace(bumpy_result, cameras=(replace(cam, T_cam_imu=moved), *bumpy_result.cameras[1:]))
    assert other != bumpy_result


def test_flat_road_is_refused_then_flagged_by_the_standard_deviations(bumpy_result):
    flat = _scene(bumps=False)
    with pytest.raises(CalibrationError, match=r"too little rotational excitation.*x=0\.00[0-9]{2}, y=0\.00"):
        calibrate_imu_camera(flat.observations, flat.imu, flat.noise, flat.corners_target_m,
                             ImuCameraOptions(sigma_px=0.2))
    with pytest.warns(UserWarning, match="forced"):
        res = calibrate_imu_camera(flat.observations, flat.imu, flat.noise, flat.corners_target_m,
                                   ImuCameraOptions(sigma_px=0.2, force=True))
    assert res.forced and not res.excitation.translation_observable
    assert set(res.excitation.weak_rotation_axes) == {"x", "y"}
    assert res.excitation.gyro_std_rad_s[:2].max() < 0.01 < res.excitation.gyro_std_rad_s[2]
    assert bumpy_result.excitation.translation_observable
    assert bumpy_result.excitation.gyro_std_rad_s.min() > 0.05  # the shuttle: pitch rate std ~0.09
    for fl, bu in zip(res.cameras, bumpy_result.cameras, strict=True):
        # without roll and pitch the lever arm along the vertical (IMU z) is not observable ...
        assert fl.position_std_imu_m[2] > 0.5 > 20 * bu.position_std_imu_m[2]
        # ... and the rotation about the vertical rests on the accelerometer alone (the shuttle's
        # turns and stops still give it lateral and longitudinal accelerations)
        assert fl.rotation_std_deg[2] > 1.3 * bu.rotation_std_deg[2]
        assert bu.timeshift_std_s < fl.timeshift_std_s
        assert any(f"camera {fl.name}: translation along IMU z" in w for w in res.warnings)
        assert not any(f"camera {bu.name}: rotation" in w for w in bumpy_result.warnings)
        # what is observable is still found: roll and pitch of the camera mount, the offset
        rot_deg, _, shift_s = _errors(flat, fl)
        assert rot_deg < 4 * np.linalg.norm(fl.rotation_std_deg)
        assert abs(shift_s) < 4 * fl.timeshift_std_s


# ------------------------------------------------------------------------------------- bad input


def test_imu_that_does_not_cover_the_images_is_refused(bumpy):
    imu = bumpy.imu
    cut = imu.stamps_ns.size // 3
    short = ImuData(imu.stamps_ns[:cut], imu.gyro_rad_s[:cut], imu.accel_m_s2[:cut])
    with pytest.raises(ImuCoverageError, match="does not cover the images") as e:
        calibrate_imu_camera(bumpy.observations, short, bumpy.noise, bumpy.corners_target_m)
    assert isinstance(e.value, CalibrationError) and e.value.camera == "rgbL" and e.value.source is None
    assert e.value.imu_ns == (int(short.stamps_ns[0]), int(short.stamps_ns[-1]))


def test_imu_yaml_with_missing_keys_or_wrong_rate():
    doc = {"accelerometer_noise_density": 2e-3, "accelerometer_random_walk": 3e-3,
           "gyroscope_noise_density": 1.7e-4, "update_rate": 200.0}
    with pytest.raises(FormatError, match=r"imu\.yaml: missing key.*gyroscope_random_walk"):
        ImuNoise.from_kalibr(doc)
    with pytest.raises(FormatError, match="gyroscope_random_walk = 'x' is not a number"):
        ImuNoise.from_kalibr({**doc, "gyroscope_random_walk": "x"})


def test_rate_mismatch_with_imu_yaml(bumpy):
    n = bumpy.noise
    wrong = replace(n, update_rate_hz=100.0)
    with pytest.raises(ImuRateError, match=r"update_rate 100 Hz but the IMU data run at 200\.00 Hz") as e:
        calibrate_imu_camera(bumpy.observations, bumpy.imu, wrong, bumpy.corners_target_m)
    assert (e.value.update_rate_hz, round(e.value.data_rate_hz)) == (100.0, 200)


def test_camera_without_intrinsics_is_refused(bumpy):
    o = bumpy.observations[0]
    bare = CameraObservations(o.name, None, o.stamps_ns, o.frame_index, o.corner_ids, o.pixels_px)
    with pytest.raises(CalibrationError, match="camera rgbL: intrinsics are missing"):
        calibrate_imu_camera([bare], bumpy.imu, bumpy.noise, bumpy.corners_target_m)


def test_camchain_imucam_yaml_round_trip(tmp_path, bumpy, bumpy_result):
    import yaml

    from ibiscape_eval.calib.imu_camera import camchain_imucam, errors_against_truth
    from ibiscape_eval.io.kalibr import read_camchain, write_camchain

    path = tmp_path / "camchain-imucam.yaml"
    write_camchain(path, camchain_imucam(bumpy_result))
    chain = read_camchain(path)
    assert chain.has_imu and chain.rostopics == ("/rgbL/image_raw", "/rgbR/image_raw")
    back = yaml.safe_load(path.read_text())
    assert list(back) == ["cam0", "cam1"]
    assert "T_cn_cnm1" in back["cam1"] and "T_cn_cnm1" not in back["cam0"]
    T0 = np.array(back["cam0"]["T_cam_imu"])
    np.testing.assert_allclose(T0, bumpy_result.cameras[0].T_cam_imu)
    T10 = np.array(back["cam1"]["T_cn_cnm1"])
    np.testing.assert_allclose(T10 @ T0, bumpy_result.cameras[1].T_cam_imu, atol=1e-12)
    assert back["cam1"]["timeshift_cam_imu"] == pytest.approx(bumpy_result.cameras[1].timeshift_cam_imu_s)
    assert back["cam0"]["intrinsics"] == pytest.approx(bumpy.observations[0].camera.intrinsics)
    truth = {k: {"T_cam_imu": bumpy.T_cam_imu[k], "timeshift_cam_imu": bumpy.timeshift_cam_imu_s[k]}
             for k in bumpy.T_cam_imu}
    err = errors_against_truth(bumpy_result, truth)
    assert set(err) == {"rgbL", "rgbR"} and err["rgbL"]["rotation_error_deg"] < 0.1
