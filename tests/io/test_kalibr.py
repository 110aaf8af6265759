"""Kalibr yaml: one reader and one writer per file (target, imu.yaml, camchain, camchain-imucam),
hypothesis round trips, real files from Kalibr / OpenVINS / EuRoC, bad files, atomic writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.kalibr import (
    CalibrationTarget,
    CameraChain,
    ChainCamera,
    ImuNoise,
    check_camchain_matches,
)
from ibiscape_eval.io.kalibr import (
    read_camchain,
    read_imu_noise,
    read_target,
    write_camchain,
    write_imu_noise,
    write_json,
    write_target,
)

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "kalibr"
finite = st.floats(-0.5, 0.5, allow_nan=False)


def _pose(draw) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([draw(finite) for _ in range(3)]).as_matrix()
    T[:3, 3] = [draw(st.floats(-2, 2)) for _ in range(3)]
    return T


@st.composite
def chains(draw):
    n = draw(st.integers(1, 4))
    imu = draw(st.booleans())
    cams, Ts, Tci, topics = [], [], [], []
    for i in range(n):
        w, h = draw(st.integers(16, 2048)), draw(st.integers(16, 2048))
        model = draw(st.sampled_from(["radtan", "equidistant"]))
        cams.append(CameraModel(w, h, draw(st.floats(10, 3000)), draw(st.floats(10, 3000)),
                                draw(st.floats(-10, 3000)), draw(st.floats(-10, 3000)), model,
                                tuple(draw(finite) for _ in range(4))))
        Tci.append(_pose(draw))
        topics.append(draw(st.sampled_from([None, f"/cam{i}/image_raw", f"/x{i}/image"])))
        if i:
            Ts.append(_pose(draw))
    names = tuple(f"cam{i}" for i in range(n))
    if imu:
        shifts = [draw(st.floats(-0.1, 0.1)) for _ in range(n)]
        return CameraChain.from_imu_extrinsics(names, cams, Tci, shifts, rostopics=topics)
    return CameraChain.from_relative(names, cams, Ts, topics)


@settings(max_examples=40, deadline=None)
@given(chain=chains())
def test_camchain_round_trip(tmp_path_factory, chain):
    p = tmp_path_factory.mktemp("cc") / "camchain.yaml"
    write_camchain(p, chain, comments=["by a test"])
    back = read_camchain(p)
    assert back.names == chain.names and back.models == chain.models
    # the writer names a missing topic /camN/image_raw (Kalibr needs one)
    assert back.rostopics == tuple(t or f"/cam{i}/image_raw" for i, t in enumerate(chain.rostopics))
    for a, b in zip(back.cameras, chain.cameras, strict=True):
        for key in ("T_cn_cnm1", "T_cam_imu"):
            x, y = getattr(a, key), getattr(b, key)
            assert (x is None) == (y is None)
            if x is not None:
                np.testing.assert_array_equal(x, y)
        assert a.timeshift_cam_imu_s == b.timeshift_cam_imu_s
    assert back.has_imu == chain.has_imu
    doc = yaml.safe_load(p.read_text())
    assert set(doc["cam0"]) >= {"camera_model", "intrinsics", "distortion_model", "distortion_coeffs",
                                "resolution", "rostopic"}
    assert "T_cn_cnm1" in doc.get("cam1", {"T_cn_cnm1": 1}) and "T_cn_cnm1" not in doc["cam0"]
    assert p.read_text().startswith("# by a test\n")


@settings(max_examples=40, deadline=None)
@given(vals=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4),
       rate=st.floats(1.0, 1e5), topic=st.one_of(st.none(), st.from_regex(r"/[a-z][a-z0-9_]{0,10}",
                                                                           fullmatch=True)))
def test_imu_noise_round_trip(tmp_path_factory, vals, rate, topic):
    noise = ImuNoise(gyro_noise_density_rad_s_sqrt_hz=vals[0], gyro_random_walk_rad_s2_sqrt_hz=vals[1],
                     accel_noise_density_m_s2_sqrt_hz=vals[2] * 10, accel_random_walk_m_s3_sqrt_hz=vals[3],
                     update_rate_hz=rate, rostopic=topic)
    p = tmp_path_factory.mktemp("imu") / "imu.yaml"
    write_imu_noise(p, noise, comments=["sigma: 1"])
    back = read_imu_noise(p)
    assert back == (noise if topic else ImuNoise(**{**noise.__dict__, "rostopic": "/imu0"}))
    doc = yaml.safe_load(p.read_text())
    assert list(doc) == ["accelerometer_noise_density", "accelerometer_random_walk",
                         "gyroscope_noise_density", "gyroscope_random_walk", "rostopic", "update_rate"]


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["checkerboard", "aprilgrid"]), rows=st.integers(2, 20),
       cols=st.integers(2, 20), a=st.floats(1e-3, 2.0), b=st.floats(0.2, 5.0))
def test_target_round_trip(tmp_path_factory, kind, rows, cols, a, b):
    t = (CalibrationTarget("checkerboard", rows, cols, spacing_x_m=a, spacing_y_m=a * b) if kind == "checkerboard"
         else CalibrationTarget("aprilgrid", rows, cols, tag_size_m=a, tag_spacing=b))
    p = tmp_path_factory.mktemp("t") / "target.yaml"
    write_target(p, t)
    assert read_target(p) == t


def test_imu_noise_has_one_field_order():
    # keyword-only: the field order of the two deleted copies cannot be mixed up any more
    with pytest.raises(TypeError):
        ImuNoise(1e-4, 1e-5, 1e-3, 1e-4, 200.0)  # type: ignore[misc]


# ------------------------------------------------------------------------------------- real files
def test_real_kalibr_imu_yaml():
    n = read_imu_noise(REAL / "kalibr_imu.yaml")
    assert n == ImuNoise(accel_noise_density_m_s2_sqrt_hz=1.86e-3, accel_random_walk_m_s3_sqrt_hz=4.33e-4,
                         gyro_noise_density_rad_s_sqrt_hz=1.87e-4, gyro_random_walk_rad_s2_sqrt_hz=2.66e-5,
                         update_rate_hz=500.0, rostopic="/imu0")


def test_real_openvins_imu_chain_and_euroc_noise():
    n = read_imu_noise(REAL / "openvins_euroc_kalibr_imu_chain.yaml")  # %YAML:1.0, imu0: nested
    assert (n.gyro_noise_density_rad_s_sqrt_hz, n.accel_random_walk_m_s3_sqrt_hz, n.update_rate_hz) == \
        (1.6968e-4, 3.0e-3, 200.0)


def test_real_kalibr_target():
    t = read_target(REAL / "kalibr_april_6x6_80x80cm.yaml")
    assert t == CalibrationTarget.aprilgrid(6, 6, 0.088, 0.3)
    # 6 tags of 0.088 m with 5 gaps of 0.3 * 0.088 m: the last corner at 0.6600 m
    np.testing.assert_allclose(t.object_points()[-1], [6 * 0.088 + 5 * 0.3 * 0.088] * 2 + [0], atol=1e-12)


def test_real_kalibr_camchains():
    c = read_camchain(REAL / "kalibr_camchain-camera.yaml")
    assert c.names == ("cam0",) and not c.has_imu and c.cameras[0].resolution == (640, 480)
    assert c.models[0].distortion == "equidistant" and c.rostopics == ("/cam0/image_raw",)
    ci = read_camchain(REAL / "kalibr_camchain-imucam-camera_imu.yaml")
    assert ci.has_imu and ci.cameras[0].timeshift_cam_imu_s == pytest.approx(-0.005869528576852833)
    assert ci.cameras[0].T_cam_imu is not None and ci.cameras[0].T_cam_imu[0, 3] == 0.04246317973602691


def test_real_openvins_imucam_chain_matches_euroc_sensor_yaml():
    """OpenVINS' camchain (``%YAML:1.0``, ``T_imu_cam``, no ``T_cn_cnm1``) and EuRoC's cam0/cam1
    ``sensor.yaml`` describe the same rig: the chain read from one equals the other."""
    from ibiscape_eval.io.asl import read_asl_sensor_yaml

    chain = read_camchain(REAL / "openvins_euroc_kalibr_imucam_chain.yaml")
    assert chain.names == ("cam0", "cam1") and chain.has_imu
    s0 = read_asl_sensor_yaml(REAL / "euroc_cam0_sensor.yaml")
    s1 = read_asl_sensor_yaml(REAL / "euroc_cam1_sensor.yaml")
    assert chain.cameras[0].T_cam_imu is not None
    np.testing.assert_allclose(np.linalg.inv(chain.cameras[0].T_cam_imu), s0["T_BS"], atol=1e-12)
    # the stereo baseline, derived by the chain from the two T_cam_imu: 0.110 m on EuRoC
    T10 = chain.cameras[1].T_cn_cnm1
    assert T10 is not None
    np.testing.assert_allclose(T10, np.linalg.inv(s1["T_BS"]) @ s0["T_BS"], atol=1e-12)
    assert np.linalg.norm(T10[:3, 3]) == pytest.approx(0.1101, abs=2e-4)
    assert list(chain.models[1].intrinsics) == s1["intrinsics"]
    # EuRoC's camera sensor.yaml read as a camera: the same model as the Kalibr chain's entry
    from ibiscape_eval.io.asl import read_asl_camera

    for i, name in enumerate(("euroc_cam0_sensor.yaml", "euroc_cam1_sensor.yaml")):
        cam, T_BS = read_asl_camera(REAL / name)
        assert cam == chain.models[i]
        np.testing.assert_array_equal(T_BS, (s0, s1)[i]["T_BS"])


def test_check_camchain_matches_names_and_resolution():
    chain = read_camchain(REAL / "openvins_euroc_kalibr_imucam_chain.yaml")
    src = "kalibr_imucam_chain.yaml"
    assert check_camchain_matches(chain, {"cam0": (752, 480), "cam1": None}, source=src) == {"cam0": 0, "cam1": 1}
    with pytest.raises(FormatError, match=r"cam1 is 752x480 px but the sequence's camera cam1 is 640x480"):
        check_camchain_matches(chain, {"cam0": (752, 480), "cam1": (640, 480)}, source=src)
    with pytest.raises(FormatError, match=r"no entry for the sequence's camera\(s\) davisL"):
        check_camchain_matches(chain, {"cam0": None, "davisL": None}, source=src)
    # a chain of other names is matched in chain order (and refused when it is too short)
    assert check_camchain_matches(chain, {"rgbL": None, "rgbR": None}, source=src) == {"rgbL": 0, "rgbR": 1}
    with pytest.raises(FormatError, match="rgbX"):
        check_camchain_matches(chain, {"rgbL": None, "rgbR": None, "rgbX": None}, source=src)


# -------------------------------------------------------------------------------------- bad files
def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "f.yaml"
    p.write_text(text)
    return p


CAM = ("camera_model: pinhole\nintrinsics: [500, 500, 320, 240]\ndistortion_model: radtan\n"
       "distortion_coeffs: [0, 0, 0, 0]\nresolution: [640, 480]\n")


def _cam(key: str, extra: str = "", cam: str = CAM) -> str:
    return f"{key}:\n" + "".join("  " + ln + "\n" for ln in (cam + extra).splitlines())


@pytest.mark.parametrize("text,match", [
    ("a: [1, 2", "not valid YAML"),
    ("- 1\n- 2\n", "mapping"),
    ("foo: 1\n", "no cam0"),
    ("cam0:\n  intrinsics: [1, 2]\n  resolution: [640, 480]\n", "intrinsics"),
    ("cam0:\n  intrinsics: [1, 2, 3, 4]\n", "cam0: lacks the key 'resolution'"),
    (_cam("cam0") + "cam2: {}\n", "without gaps"),
    (_cam("cam0") + _cam("cam1"), "cam1: lacks T_cn_cnm1"),
    (_cam("cam0") + _cam("cam1", "T_cn_cnm1: [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"),
     "cam1.T_cn_cnm1: the rotation part"),
    (_cam("cam0", "T_cam_imu: [1, 2, 3]"), "cam0.T_cam_imu: must be a 4x4"),
    (_cam("cam0", "timeshift_cam_imu: soon"), "cam0.timeshift_cam_imu"),
    (_cam("cam0") + _cam("cam0"), "duplicate key 'cam0'"),
    (_cam("cam0", cam=CAM.replace("radtan", "fov")), "radtan"),
])
def test_bad_camchain(tmp_path, text, match):
    with pytest.raises(FormatError, match=match) as e:
        read_camchain(_write(tmp_path, text))
    assert "f.yaml" in str(e.value)


@pytest.mark.parametrize("text,match", [
    ("gyroscope_noise_density: 1e-4\n", "missing key.*accelerometer_noise_density.*update_rate"),
    ("accelerometer_noise_density: 1e-3\naccelerometer_random_walk: 1e-4\ngyroscope_noise_density: x\n"
     "gyroscope_random_walk: 1e-5\nupdate_rate: 200\n", "gyroscope_noise_density = 'x' is not a number"),
    ("accelerometer_noise_density: -1e-3\naccelerometer_random_walk: 1e-4\ngyroscope_noise_density: 1e-4\n"
     "gyroscope_random_walk: 1e-5\nupdate_rate: 200\n", r"accelerometer_noise_density = -0.001 is out of range; give"),
    ("accelerometer_noise_density: 1e-3\naccelerometer_random_walk: 1e-4\ngyroscope_noise_density: 1e-4\n"
     "gyroscope_random_walk: .nan\nupdate_rate: 200\n", "gyroscope_random_walk = nan"),
    ("accelerometer_noise_density: 1e-3\naccelerometer_random_walk: 1e-4\ngyroscope_noise_density: 1e-4\n"
     "gyroscope_random_walk: 1e-5\nupdate_rate: 0\n", "update_rate = 0.0"),
    ("imus:\n  a: {gyroscope_noise_density: 1}\n  b: {gyroscope_noise_density: 1}\n", "holds the IMUs a, b"),
    ("imus:\n  imu0: {gyroscope_noise_density: 1}\n", "f.yaml: imus.imu0: missing key"),
])
def test_bad_imu_yaml(tmp_path, text, match):
    with pytest.raises(FormatError, match=match) as e:
        read_imu_noise(_write(tmp_path, text))
    assert "f.yaml" in str(e.value)


def test_imu_noise_from_sequence_yaml_and_euroc_sensor_yaml(tmp_path):
    keys = ("accelerometer_noise_density: 0.0\naccelerometer_random_walk: 0.0\n"
            "gyroscope_noise_density: 0.0\ngyroscope_random_walk: 0.0\n")
    seq = _write(tmp_path, "cameras: {}\nimus:\n  imu0:\n" + "".join(f"    {ln}\n" for ln in keys.splitlines())
                 + "    update_rate: 200.0\n    rostopic: /imu0\n    file: other_sensors/imu.csv\n")
    n = read_imu_noise(seq)  # an ideal sequence states zero noise: read as it is, floored for use
    assert n.is_ideal and n.update_rate_hz == 200.0
    assert n.floored().gyro_noise_density_rad_s_sqrt_hz == 1e-5
    euroc = tmp_path / "sensor.yaml"
    euroc.write_text("%YAML:1.0\nsensor_type: imu\nT_BS:\n  cols: 4\n  rows: 4\n  data: [1, 0, 0, 0, 0, 1, 0, 0,"
                     " 0, 0, 1, 0, 0, 0, 0, 1]\nrate_hz: 200\n" + keys.replace("0.0", "1e-3"))
    assert read_imu_noise(euroc).update_rate_hz == 200.0


def test_no_pickle_tags(tmp_path):
    p = _write(tmp_path, "cam0: !!python/object/apply:os.system ['echo hi']\n")
    with pytest.raises(FormatError, match="not valid YAML"):
        read_camchain(p)


def test_bad_target_yaml(tmp_path):
    with pytest.raises(FormatError, match="target_type"):
        read_target(_write(tmp_path, "tagCols: 6\n"))
    with pytest.raises(FormatError, match=r"f.yaml: a aprilgrid target needs .* missing tagSpacing"):
        read_target(_write(tmp_path, "target_type: aprilgrid\ntagCols: 6\ntagRows: 6\ntagSize: 0.1\n"))


def test_writers_are_atomic(tmp_path):
    one = CameraChain((ChainCamera("cam0", CameraModel(10, 10, 5, 5, 5, 5), rostopic="/c"),))
    out = tmp_path / "sub" / "cc.yaml"
    write_camchain(out, one)
    assert out.exists() and [p.name for p in out.parent.iterdir()] == ["cc.yaml"]
    with pytest.raises(IbiscapeError):
        CameraChain.from_relative(("cam0", "cam1"), (CameraModel(10, 10, 5, 5, 5, 5),) * 2, (), ("/a", "/b"))
    write_json(tmp_path / "r.json", {"a": float("nan"), "b": np.float64(2.0), "c": np.arange(2)})
    assert (tmp_path / "r.json").read_text().split() == ['{', '"a":', 'null,', '"b":', '2.0,', '"c":',
                                                         '[', '0,', '1', ']', '}']


@pytest.mark.parametrize("change,match", [
    (("distortion_model: radial-tangential", "distortion_model: fov"), "distortion_model 'fov'"),
    (("intrinsics: [458.654", "intrinsics_x: [458.654"), "lacks the key 'intrinsics'"),
    (("resolution: [752, 480]", "resolution: [.inf, 480]"), "finite numbers"),
    (("data: [0.0148655429818", "data: [2.0148655429818"), "T_BS: the rotation part"),
])
def test_bad_euroc_camera_sensor_yaml(tmp_path, change, match):
    from ibiscape_eval.io.asl import read_asl_camera

    f = tmp_path / "sensor.yaml"
    text = (REAL / "euroc_cam0_sensor.yaml").read_text()
    assert change[0] in text
    f.write_text("%YAML:1.0\n" + text.replace(*change))
    with pytest.raises(FormatError, match=match) as e:
        read_asl_camera(f)
    assert str(f) in str(e.value)
