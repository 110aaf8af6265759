"""The calib --imu entry point (cli/calib_imu.py): imu.yaml reading, outputs, JSON, figures."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
from ibiscape_eval.cli.calib_imu import run_imu_camera
from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.kalibr import read_imu_noise
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration


@pytest.fixture(scope="module")
def small():
    # 12 s at 384 px (half the solve of 24 s at 640 px): rgbL 0.034 deg and 0.07 ms off, well
    # inside the test's 0.2 deg and 0.5 ms
    cfg = preset("svi", "calibration", "clear", duration_s=12.0, seed=2)
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=384, height_px=384) for c in cfg.cameras))
    sim = simulate_calibration(cfg, timeshifts_s={"rgbL": 0.004, "rgbR": -0.008})
    return calibration_scene(sim, min_spacing_px=4.0)


def _imu_yaml(tmp_path, noise, **change):
    doc = {**noise.to_kalibr(), "rostopic": "/imu0", **change}
    doc = {k: v for k, v in doc.items() if v is not None}
    p = tmp_path / "imu.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_imu_yaml_errors_name_the_file(tmp_path, small):
    p = _imu_yaml(tmp_path, small.noise, gyroscope_noise_density=None)
    with pytest.raises(FormatError, match=r"imu\.yaml: missing key\(s\) gyroscope_noise_density"):
        read_imu_noise(str(p))
    p.write_text("accelerometer_noise_density: [1, 2\n")
    with pytest.raises(FormatError, match="not valid YAML"):
        read_imu_noise(str(p))


def test_run_writes_kalibr_yaml_json_and_figures(tmp_path, small, capsys):
    p = _imu_yaml(tmp_path, small.noise)
    truth = {k: {"T_cam_imu": small.T_cam_imu[k], "timeshift_cam_imu": small.timeshift_cam_imu_s[k]}
             for k in small.T_cam_imu}
    out_yaml = tmp_path / "camchain-imucam.yaml"
    with warnings.catch_warnings():  # weak directions are warned about (24 s drive), if any
        warnings.simplefilter("ignore")
        res = run_imu_camera(small.observations, small.imu, str(p), small.corners_target_m,
                             truth=truth, sigma_px=0.2, yaml_path=str(out_yaml), json_out=True,
                             plot_dir=str(tmp_path / "plots"))
    doc = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in doc["cameras"]] == ["rgbL", "rgbR"]
    err = doc["errors_vs_truth"]["rgbL"]
    assert err["rotation_error_deg"] < 0.2 and abs(err["timeshift_error_s"]) < 5e-4
    back = yaml.safe_load(out_yaml.read_text())
    np.testing.assert_allclose(back["cam0"]["T_cam_imu"], res.cameras[0].T_cam_imu)
    assert sorted(f.name for f in (tmp_path / "plots").iterdir()) == [
        "excitation.png", "imu_residuals.png", "reprojection.png"]


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=16, max_size=16),
       st.floats(-0.05, 0.05, allow_nan=False),
       st.floats(1e-6, 1.0, allow_nan=False), st.floats(1e-7, 1.0, allow_nan=False))
def test_camchain_imucam_writer_and_imu_yaml_round_trip(tmp_path_factory, m, shift, nd, rw):
    from scipy.spatial.transform import Rotation

    from ibiscape_eval.core.camera import CameraModel
    from ibiscape_eval.core.kalibr import CameraChain, ImuNoise
    from ibiscape_eval.io.kalibr import read_camchain, write_camchain, write_imu_noise

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.asarray(m[:3]) * 1e-3).as_matrix()
    T[:3, 3] = np.asarray(m[3:6]) * 0.1  # lever arms within the 1000 m a rig may have
    cam = CameraModel(640, 480, 500.0, 500.0, 319.5, 239.5)
    chain = CameraChain.from_imu_extrinsics(["rgbL", "rgbR"], [cam, cam], [T, T @ T], [shift, -shift])
    path = tmp_path_factory.mktemp("y") / "camchain-imucam.yaml"
    write_camchain(path, chain, comments=["x"])
    doc = yaml.safe_load(path.read_text())
    assert doc["cam0"]["T_cam_imu"] == T.tolist() and doc["cam1"]["timeshift_cam_imu"] == -shift
    np.testing.assert_allclose(read_camchain(path).cameras[1].T_cn_cnm1, T, atol=1e-9)
    n = ImuNoise(gyro_noise_density_rad_s_sqrt_hz=nd, accel_noise_density_m_s2_sqrt_hz=2 * nd,
                 gyro_random_walk_rad_s2_sqrt_hz=rw, accel_random_walk_m_s3_sqrt_hz=3 * rw,
                 update_rate_hz=200.0)
    write_imu_noise(path, n)
    assert read_imu_noise(path) == replace(n, rostopic="/imu0")
