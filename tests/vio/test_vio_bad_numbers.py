"""Every number the VIO reads from sequence.yaml, the Kalibr camchain and imu.yaml is checked: NaN,
infinity, huge, negative or zero values where they make no sense, and rotations that are not
rotations, end in one ``error:`` line naming the file and the key (exit 2, no output file).  A
numerical failure of GTSAM that slips past the checks is a clean error too, not a traceback."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError, DegenerateInputError, FormatError
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.io.asl import read_asl_sensor_yaml
from ibiscape_eval.io.kalibr import read_camchain
from ibiscape_eval.vio import run_vio
from ibiscape_eval.vio.inputs import load_sequence

IMU_YAML = {"accelerometer_noise_density": 0.02, "accelerometer_random_walk": 4e-4,
            "gyroscope_noise_density": 2e-3, "gyroscope_random_walk": 2e-5, "update_rate": 200.0,
            "rostopic": "/imu0"}


def _variant(street: tuple[Path, Path], tmp_path: Path) -> tuple[Path, Path, Path]:
    """A copy of the street sequence whose yaml files may be edited (images are symlinked):
    (folder, camchain-imucam.yaml, imu.yaml)."""
    seq, calib = street
    d = tmp_path / "SVI_bad"
    d.mkdir()
    for e in seq.iterdir():
        if e.name == "sequence.yaml":
            (d / e.name).write_bytes(e.read_bytes())
        elif e.name != calib.name:
            os.symlink(e, d / e.name)
    (d / "camchain-imucam.yaml").write_bytes(calib.read_bytes())
    (d / "imu.yaml").write_text(yaml.safe_dump(IMU_YAML))
    return d, d / "camchain-imucam.yaml", d / "imu.yaml"


def _edit(path: Path, keys: tuple[Any, ...], value: Any) -> None:
    doc = yaml.safe_load(path.read_text())
    node = doc
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    path.write_text(yaml.safe_dump(doc))


def _refused(args: list[Any], out: Path, *words: str, only_line: bool = True) -> str:
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines()
             if ln.strip() and (only_line or ln.startswith("error:"))]
    assert len(lines) == 1 and lines[0].startswith("error:"), res.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]
    return lines[0]


NAN, INF = float("nan"), float("inf")
ROT_NOT_ORTHONORMAL = [[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                       [0.0, 0.0, 0.0, 1.0]]
REFLECTION = [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
              [0.0, 0.0, 0.0, 1.0]]


# --------------------------------------------------------------------------- camchain-imucam.yaml
@pytest.mark.parametrize("keys, value, words", [
    (("cam0", "intrinsics", 0), NAN, ["cam0", "focal"]),
    (("cam1", "intrinsics", 1), -80.0, ["cam1", "focal"]),
    (("cam0", "intrinsics", 0), 1e300, ["cam0", "focal"]),
    (("cam0", "intrinsics", 2), 2.0 ** 64, ["cam0", "principal point"]),
    (("cam1", "intrinsics", 3), -INF, ["cam1", "principal point"]),
    (("cam0", "distortion_coeffs", 1), INF, ["cam0", "distortion"]),
    (("cam1", "distortion_coeffs", 0), 1e6, ["cam1", "distortion"]),
    (("cam0", "resolution", 0), INF, ["cam0"]),
    (("cam1", "resolution", 1), 10 ** 9, ["cam1", "resolution"]),
    (("cam0", "resolution", 0), 0, ["cam0", "size"]),
    (("cam0", "T_cam_imu", 1, 3), NAN, ["cam0.T_cam_imu", "finite"]),
    (("cam1", "T_cam_imu", 0, 3), 1e300, ["cam1.T_cam_imu", "translation"]),
    (("cam0", "T_cam_imu", 0, 1), 0.0, ["cam0.T_cam_imu", "rotation"]),
    (("cam1", "T_cam_imu"), REFLECTION, ["cam1.T_cam_imu", "rotation"]),
], ids=lambda v: str(v)[:30])
def test_camchain_numbers(street, tmp_path, keys, value, words):
    seq, calib, _ = _variant(street, tmp_path)
    _edit(calib, keys, value)
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, "--calib", calib, "--max-frames", 5], out, calib.name,
             *words)


@pytest.mark.parametrize("value, words", [
    (ROT_NOT_ORTHONORMAL, ["T_cn_cnm1", "rotation"]),
    ("nan", ["T_cn_cnm1", "finite"]),
])
def test_camchain_relative_pose(street, tmp_path, value, words):
    """cam1 given by T_cn_cnm1 (relative to cam0) instead of its own T_cam_imu."""
    seq, calib, _ = _variant(street, tmp_path)
    doc = yaml.safe_load(calib.read_text())
    T0, T1 = np.array(doc["cam0"]["T_cam_imu"]), np.array(doc["cam1"].pop("T_cam_imu"))
    rel = (T1 @ np.linalg.inv(T0)).tolist()
    if value == "nan":
        rel[2][3] = NAN
    else:
        rel = (np.array(rel) @ np.array(value)).tolist()
    doc["cam1"]["T_cn_cnm1"] = rel
    calib.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, "--calib", calib, "--max-frames", 5], out, calib.name,
             *words)


def test_cameras_on_top_of_each_other_are_refused_naming_the_file(street, tmp_path):
    """Rectification of a rig whose right camera sits left of the left one fails inside
    :meth:`StereoRig.rectified`; the error still names the camchain (the campaign found it
    without the file name)."""
    seq, calib, _ = _variant(street, tmp_path)
    doc = yaml.safe_load(calib.read_text())
    doc["cam0"]["T_cam_imu"], doc["cam1"]["T_cam_imu"] = (doc["cam1"]["T_cam_imu"],
                                                          doc["cam0"]["T_cam_imu"])
    calib.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, "--calib", calib, "--max-frames", 5], out, calib.name,
             "right")


# ------------------------------------------------------------------------------------- imu.yaml
@pytest.mark.parametrize("key, value, words", [
    ("gyroscope_noise_density", NAN, []),
    ("gyroscope_random_walk", 1e5, ["[0, 1]"]),
    ("accelerometer_noise_density", -0.02, ["out of range"]),
    ("accelerometer_random_walk", -INF, []),
    ("update_rate", 0.0, ["Hz"]),
    ("update_rate", INF, ["Hz"]),
    ("gyroscope_noise_density", "fast", ["not a number"]),
])
def test_imu_yaml_numbers(street, tmp_path, key, value, words):
    seq, calib, imu = _variant(street, tmp_path)
    _edit(imu, (key,), value)
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, "--calib", calib, "--imu", imu, "--max-frames", 5], out,
             imu.name, key, *words)


def test_zero_noise_means_an_ideal_sensor_and_is_floored():
    """Noise-free generated sequences write zeros: read as they are, floored (to a small positive
    value) by the estimator."""
    n = ImuNoise.from_kalibr({**IMU_YAML, "gyroscope_noise_density": 0.0})
    assert n.is_ideal and n.gyro_noise_density_rad_s_sqrt_hz == 0.0
    n = n.floored()
    assert 0.0 < n.gyro_noise_density_rad_s_sqrt_hz <= 1e-5
    assert n.accel_noise_density_m_s2_sqrt_hz == IMU_YAML["accelerometer_noise_density"]


# -------------------------------------------------------------------------------- sequence.yaml
@pytest.mark.parametrize("keys, value, words", [
    (("imus", "imu0", "T_body_imu", 0, 0), -INF, ["T_body_imu", "finite"]),
    (("imus", "imu0", "T_body_imu", 2, 3), NAN, ["T_body_imu", "finite"]),
    (("imus", "imu0", "T_body_imu", 0, 1), 0.5, ["T_body_imu", "rotation"]),
    (("imus", "imu0", "T_body_imu"), [[1.0, 0.0], [0.0, 1.0]], ["T_body_imu", "4x4"]),
    (("imus", "imu0", "gyroscope_random_walk"), INF, ["gyroscope_random_walk"]),
    (("imus", "imu0", "accelerometer_noise_density"), -1.0, ["accelerometer_noise_density"]),
    (("imus", "imu0", "update_rate"), -200.0, ["update_rate"]),
], ids=lambda v: str(v)[:30])
def test_sequence_yaml_imu_numbers(street, tmp_path, keys, value, words):
    _refused_sequence_edit(street, tmp_path, keys, value, words, with_calib=True)


def _refused_sequence_edit(street, tmp_path, keys, value, words, *, with_calib):
    """sequence.yaml with one number changed: the vio command refuses it naming the file."""
    seq, calib, _ = _variant(street, tmp_path)
    _edit(seq / "sequence.yaml", keys, value)
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, *(["--calib", calib] if with_calib else []), "--max-frames", 5],
             out, "sequence.yaml", *words)


@pytest.mark.parametrize("keys, value, words", [
    (("cameras", "rgbL", "intrinsics", 0), INF, ["rgbL", "focal"]),
    (("cameras", "rgbR", "intrinsics", 2), 1e12, ["rgbR", "principal point"]),
    (("cameras", "rgbL", "distortion_coeffs", 3), NAN, ["rgbL", "distortion"]),
    (("cameras", "rgbR", "resolution", 0), -1024, ["rgbR", "size"]),
    (("cameras", "rgbL", "T_body_cam", 1, 3), INF, ["rgbL.T_body_cam", "finite"]),
    (("cameras", "rgbR", "T_body_cam", 0, 0), 3.0, ["rgbR.T_body_cam", "rotation"]),
], ids=lambda v: str(v)[:30])
def test_sequence_yaml_camera_numbers(street, tmp_path, keys, value, words):
    """Without --calib the cameras come from sequence.yaml (checked before the image size)."""
    _refused_sequence_edit(street, tmp_path, keys, value, words, with_calib=False)


# ------------------------------------------------------------------------------- the readers
def test_camchain_reader_refuses_a_non_rotation(tmp_path):
    f = tmp_path / "camchain.yaml"
    cam = {"intrinsics": [80.0, 80.0, 79.5, 79.5], "resolution": [160, 160],
           "T_cam_imu": ROT_NOT_ORTHONORMAL}
    f.write_text(yaml.safe_dump({"cam0": cam}))
    with pytest.raises(FormatError, match=r"camchain\.yaml: cam0\.T_cam_imu: the rotation"):
        read_camchain(f)
    cam["T_cam_imu"] = np.eye(4).tolist()
    f.write_text(yaml.safe_dump({"cam0": cam}))
    T = read_camchain(f).cameras[0].T_cam_imu
    assert T is not None and np.array_equal(T, np.eye(4))


def test_euroc_sensor_yaml_refuses_a_reflection(tmp_path):
    f = tmp_path / "sensor.yaml"
    f.write_text(yaml.safe_dump({"T_BS": {"rows": 4, "cols": 4,
                                          "data": np.ravel(REFLECTION).tolist()}}))
    with pytest.raises(FormatError, match=r"sensor\.yaml: T_BS: the rotation"):
        read_asl_sensor_yaml(f)


# --------------------------------------------------------------------- GTSAM numerical failure
def _unchecked(monkeypatch: pytest.MonkeyPatch) -> None:
    """Switch off the rigid-transform check so that a broken T_body_imu reaches GTSAM."""
    import ibiscape_eval.core.kalibr as kalibr

    monkeypatch.setattr(kalibr, "rigid_transform_problem", lambda T: None)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")  # numpy on the inf pose
def test_gtsam_failure_is_a_clean_library_error(street, monkeypatch):
    """An infinite IMU-to-body rotation makes iSAM2's linear system indeterminate: the library
    raises DegenerateInputError naming the sequence, not GTSAM's RuntimeError."""
    seq_dir, calib = street
    seq = load_sequence(seq_dir, calib=calib)
    T = np.eye(4)
    T[0, 0] = INF
    bad = dataclasses.replace(seq, T_body_imu=T)
    with pytest.raises(DegenerateInputError, match="failed numerically") as e:
        run_vio(bad, max_frames=20)
    assert str(seq_dir) in str(e.value)
    assert "\n" not in str(e.value)


def test_gtsam_failure_through_the_cli(street, tmp_path, monkeypatch):
    _unchecked(monkeypatch)
    seq, calib, _ = _variant(street, tmp_path)
    _edit(seq / "sequence.yaml", ("imus", "imu0", "T_body_imu", 0, 0), -INF)
    out = tmp_path / "out" / "est.txt"
    out.parent.mkdir()
    _refused(["vio", seq, "-o", out, "--calib", calib, "--max-frames", 20], out, seq.name,
             "failed numerically", "Indeterminate", only_line=False)  # + numpy's inf warnings


def test_the_check_is_what_stops_the_broken_pose(street, tmp_path):
    """Without the monkeypatch the same file is refused by the input check (naming the key)."""
    seq, calib, _ = _variant(street, tmp_path)
    _edit(seq / "sequence.yaml", ("imus", "imu0", "T_body_imu", 0, 0), -INF)
    with pytest.raises(CalibrationError, match=r"imus\.T_body_imu must be a finite"):
        load_sequence(seq, calib=calib)
