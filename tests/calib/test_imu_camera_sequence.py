"""``calib SEQ --imu imu.yaml`` end to end on a generated sequence with planted extrinsics and camera
clock offsets, and every bad input (exit 2, one line naming the file, no --yaml).

The sequence is the simulator's own (IMU, ground truth, sequence.yaml with the true T_cam_imu and
timeshift_cam_imu, generated without rendering); its camera frames are the board's texture warped
by the exact homography of the camera pose at ``t_cam + shift`` (``sim.calib_scene.
write_board_frames``: fast and exact, so the test checks the glue: detection, intrinsics, IMU
reading, truth), on the shuttle drive over bumps.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.calib.imu_camera import SequenceCalibration, SequenceOptions, calibrate_sequence
from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError, IbiscapeError
from ibiscape_eval.io.kalibr import read_imu_noise
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import write_board_frames
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.sim.generator import generate

SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0071}


@pytest.fixture(scope="module")
def seq(tmp_path_factory) -> Path:
    # 18 s (24 s until session 10): the CLI's errors 0.06 deg, 11 mm, < 0.05 ms against the limits
    # 0.15 deg, 20 mm, 0.3 ms; the library call's (camera calibration, frame_step 3) 0.25 deg,
    # 15 mm, cx 0.8 px against 0.6 deg, 40 mm, 3 px
    cfg = with_resolution(preset("svi", "calibration", "clear", duration_s=18.0, seed=3), 384, 384)
    cfg = replace(cfg, cameras=tuple(replace(c, rate_hz=10.0, timeshift_cam_imu_s=SHIFTS[c.name])
                                     for c in cfg.cameras))
    out = tmp_path_factory.mktemp("imuseq") / "SVI_1_calib"
    generate(cfg, out, render=False)
    write_board_frames(cfg, out)
    return out


def _imu_yaml(seq: Path, tmp: Path, **change) -> Path:
    entry = yaml.safe_load((seq / "sequence.yaml").read_text())["imus"]["imu0"]
    keys = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
            "gyroscope_random_walk", "update_rate", "rostopic")
    doc = {k: entry[k] for k in keys} | change
    p = tmp / "imu.yaml"
    p.write_text(yaml.safe_dump({k: v for k, v in doc.items() if v is not None}))
    return p


def _truth_chain(seq: Path, tmp: Path, names=("rgbL", "rgbR")) -> Path:
    """A Kalibr camchain with the true intrinsics of ``names`` (from sequence.yaml)."""
    cams = yaml.safe_load((seq / "sequence.yaml").read_text())["cameras"]
    keep = ("camera_model", "intrinsics", "distortion_model", "distortion_coeffs", "resolution", "rostopic")
    doc = {f"cam{i}": {k: cams[n][k] for k in keep} for i, n in enumerate(names)}
    for i, n in enumerate(names[1:], 1):
        doc[f"cam{i}"]["T_cn_cnm1"] = cams[n]["T_cn_cnm1"]
    p = tmp / "camchain.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def _run(*args: str):
    return CliRunner().invoke(cli, ["calib", *args])


def test_cli_recovers_planted_extrinsics_and_offsets(seq, tmp_path):
    out = tmp_path / "camchain-imucam.yaml"
    chain = _truth_chain(seq, tmp_path)
    # the noise densities straight from the sequence's sequence.yaml
    r = _run(str(seq), "--imu", str(seq / "sequence.yaml"), "--cams", str(chain), "--yaml", str(out), "--json",
             "--plot", str(tmp_path / "plots"))
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert [c["name"] for c in doc["cameras"]] == ["rgbL", "rgbR"]
    # the library's value is what --json prints (besides the outputs the command wrote)
    value = {k: v for k, v in doc.items() if k not in ("outputs", "non_finite")}
    assert SequenceCalibration.from_dict(value).to_dict() == value
    for name, shift in SHIFTS.items():
        e = doc["errors_vs_truth"][name]
        assert doc["truth"][name]["timeshift_cam_imu"] == pytest.approx(shift)
        assert e["rotation_error_deg"] < 0.15, e
        assert e["translation_error_m"] < 0.02, e
        assert abs(e["timeshift_error_s"]) < 3e-4, e
    assert doc["intrinsics_source"] == {"rgbL": str(chain), "rgbR": str(chain)}
    assert doc["camera_calibration"] is None
    assert doc["detection"]["cameras"][0]["frames_with_target"] > 0.8 * doc["detection"]["cameras"][0]["frames"]
    back = yaml.safe_load(out.read_text())
    assert set(back) == {"cam0", "cam1"} and back["cam1"]["timeshift_cam_imu"] == pytest.approx(
        doc["cameras"][1]["timeshift_cam_imu_s"])
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == [
        "excitation.png", "imu_residuals.png", "reprojection.png"]


def test_library_call_with_intrinsics_from_the_camera_calibration(seq, tmp_path):
    assert read_imu_noise(_imu_yaml(seq, tmp_path)) == read_imu_noise(seq / "sequence.yaml")
    res = calibrate_sequence(seq, None, SequenceOptions(frame_step=3))  # None: the noise sequence.yaml states
    text = json.dumps(res.to_dict(), allow_nan=False)
    assert "NaN" not in text and res.detection["frame_step"] == 3
    assert res.intrinsics_source == {"rgbL": "camera calibration", "rgbR": "camera calibration"}
    gt = res.camera_calibration["ground_truth"]["cameras"]  # the intrinsics' errors vs the truth
    assert [c["name"] for c in gt] == ["rgbL", "rgbR"] and all(abs(c["error"]["fx"]) < 40 for c in gt)
    for e in res.errors_vs_truth.values():  # intrinsics refined in the joint solve
        assert e["rotation_error_deg"] < 0.6 and e["translation_error_m"] < 0.04, e
        assert abs(e["fx_error_px"]) < 1.0 and abs(e["cx_error_px"]) < 3.0, e
    assert "SequenceCalibration(" in repr(res) and len(repr(res)) < 300
    assert SequenceCalibration.from_dict(res.to_dict()) == res


def _bad(r, *needles: str) -> None:
    assert r.exit_code == 2, r.output
    # a step that runs over 2 s logs progress lines first (a busy machine, parallel test workers);
    # besides them the error is one line
    lines = [s for s in r.stderr.strip().splitlines() if not s.startswith("calib --imu: ")]
    assert len(lines) == 1 and "Traceback" not in r.output, r.stderr
    line = lines[0]
    assert line.startswith("error:")
    for n in needles:
        assert n in line, line


def test_bad_imu_yaml_missing_keys_and_wrong_rate(seq, tmp_path):
    out = tmp_path / "out.yaml"
    imu = _imu_yaml(seq, tmp_path, gyroscope_random_walk=None)
    _bad(_run(str(seq), "--imu", str(imu), "--yaml", str(out)), str(imu), "gyroscope_random_walk")
    imu = _imu_yaml(seq, tmp_path, update_rate=100.0)
    _bad(_run(str(seq), "--imu", str(imu), "--yaml", str(out)), str(imu), "update_rate 100", "200")
    imu.write_text("gyroscope_noise_density: [1,\n")
    _bad(_run(str(seq), "--imu", str(imu), "--yaml", str(out)), str(imu), "YAML")
    _bad(_run(str(seq), "--imu", str(tmp_path / "none.yaml")), "none.yaml")
    assert not out.exists()


def test_imu_stream_that_does_not_cover_the_images(seq, tmp_path):
    lines = next((seq / "other_sensors").glob("imu*.csv")).read_text().splitlines()
    short = tmp_path / "imu_short.csv"
    short.write_text("\n".join(lines[: len(lines) // 3]) + "\n")
    out = tmp_path / "out.yaml"
    _bad(_run(str(seq), "--imu", str(_imu_yaml(seq, tmp_path)), "--imu-data", str(short),
              "--yaml", str(out)), "does not cover", str(short))
    assert not out.exists()


def test_camera_without_intrinsics(seq, tmp_path):
    chain = _truth_chain(seq, tmp_path, names=("rgbL",))
    out = tmp_path / "out.yaml"
    _bad(_run(str(seq), "--imu", str(_imu_yaml(seq, tmp_path)), "--cams", str(chain), "--yaml", str(out)),
         "rgbR", "intrinsics are missing", str(chain))
    assert not out.exists()


def test_camchain_of_another_resolution_and_imu_without_a_file(seq, tmp_path):
    """``--imu`` alone takes the noise from SEQ/sequence.yaml; a camchain whose resolution differs
    from the sequence's cameras is refused before any detection, naming it and both sizes."""
    chain = _truth_chain(seq, tmp_path)
    doc = yaml.safe_load(chain.read_text())
    doc["cam1"]["resolution"] = [752, 480]
    chain.write_text(yaml.safe_dump(doc))
    out = tmp_path / "out.yaml"
    _bad(_run(str(seq), "--imu", "--cams", str(chain), "--yaml", str(out)), str(chain),
         "cam1 is 752x480 px but the sequence's camera rgbR is 384x384 px")
    assert not out.exists()


def test_ideal_sequence_noise_is_refused_by_the_calibration(seq, tmp_path):
    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    doc["imus"]["imu0"]["gyroscope_noise_density"] = 0.0
    ideal = tmp_path / "ideal"
    ideal.mkdir()
    (ideal / "sequence.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(CalibrationError, match=r"sequence\.yaml: states zero IMU noise"):
        calibrate_sequence(ideal)
    with pytest.raises(IbiscapeError, match=r"IBISCape: no sequence\.yaml"):  # in no layout
        calibrate_sequence(tmp_path)


def test_options_that_need_imu(seq):
    _bad(_run(str(seq), "--force"), "--imu")
    _bad(_run("--imu", "imu.yaml"), "SEQ")


def test_flat_road_refused_with_numbers_then_forced_and_marked(tmp_path):
    # 5 frames a second (10 until session 10): the refusal reads the IMU's excitation, and the
    # forced solve is only weaker with fewer frames
    cfg = with_resolution(preset("svi", "calibration", "clear", duration_s=14.0, seed=5), 320, 320)
    cfg = replace(cfg, cameras=tuple(replace(c, rate_hz=5.0) for c in cfg.cameras[:1]),
                  motion=replace(cfg.motion, bumps=False))
    seq = tmp_path / "flat"
    generate(cfg, seq, render=False)
    write_board_frames(cfg, seq)
    imu = _imu_yaml(seq, tmp_path)
    chain = _truth_chain(seq, tmp_path, names=("rgbL",))
    out = tmp_path / "out.yaml"
    r = _run(str(seq), "--imu", str(imu), "--cams", str(chain), "--yaml", str(out))
    _bad(r, "too little rotational excitation", "x=", "rad/s", "--force")
    assert not out.exists()
    with pytest.raises(CalibrationError, match="translation"):
        calibrate_sequence(seq, imu, SequenceOptions(camchain=chain))
    r = _run(str(seq), "--imu", str(imu), "--cams", str(chain), "--yaml", str(out), "--force", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["forced"] is True and any("weakly determined" in w for w in d["warnings"])
    assert out.exists()
