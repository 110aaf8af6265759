"""One door for a recording: real EuRoC V1_01 and bag excerpts, every layout, the bad inputs."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError, DegenerateInputError, FormatError
from ibiscape_eval.io.open_sequence import NoLayoutError, apply_camchain, open_sequence

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "mutation"))

from _sequence_helpers import BAG_REAL, EUROC_REAL, bag_from_euroc, euroc_from, tumvi_from_euroc


def _one_line_exit_2(res, *words: str) -> str:
    assert res.exit_code == 2, res.output
    line = res.stderr.strip()
    assert line.startswith("error:") and "\n" not in line and "Traceback" not in res.output, res.output
    for w in words:
        assert w in line, line
    return line


# ------------------------------------------------------------------------- the real recordings
def test_real_euroc_v1_01_opens_with_opencv_yaml_and_empty_ground_truth():
    seq = open_sequence(EUROC_REAL)
    assert seq.layout == "euroc" and seq.camera_names == ["cam0", "cam1"]
    assert seq.groundtruth is None and any("ground-truth csv is empty" in n for n in seq.notes)
    c0 = seq.cameras[0]
    assert len(c0) == 4 and c0.sensor_size == (752, 480) and c0.rate_hz == 20.0
    assert seq.imu is not None and seq.imu.rate_hz == 200.0
    assert not seq.imu.samples.loaded and not c0.files.loaded  # lazy: nothing read yet
    # cross-check against OpenCV's own reader of the same %YAML:1.0 files
    for cam in seq.cameras:
        fs = cv2.FileStorage(str(EUROC_REAL / "mav0" / cam.name / "sensor.yaml"), cv2.FILE_STORAGE_READ)
        intr = [fs.getNode("intrinsics").at(i).real() for i in range(4)]
        T = [fs.getNode("T_BS").getNode("data").at(i).real() for i in range(16)]
        fs.release()
        assert cam.camera is not None
        np.testing.assert_array_equal([cam.camera.fx, cam.camera.fy, cam.camera.cx, cam.camera.cy], intr)
        np.testing.assert_array_equal(np.ravel(cam.T_body_cam), T)
    assert seq.imu.noise is not None and seq.imu.noise.gyro_noise_density_rad_s_sqrt_hz == 1.6968e-04
    st, _gyro, acc = seq.imu.samples.get()
    assert st.size == 231 and st[0] == 1403715273262142976 and abs(acc[0, 0] - 9.0874956666666655) < 1e-12
    img = c0.load(0)
    assert img.shape == (480, 752) and img.dtype == np.uint8


def test_vio_on_the_real_euroc_excerpt_refuses_cleanly_and_writes_nothing(tmp_path):
    """The real EuRoC V1_01 excerpt (%YAML:1.0, empty ground truth) is read; its 4 frames are too few
    to initialise, which the one line says."""
    out = tmp_path / "est.txt"
    res = CliRunner().invoke(cli, ["vio", str(EUROC_REAL), "-o", str(out)])
    _one_line_exit_2(res, "only 4 stereo frames", "to initialise")
    assert not out.exists()


def _v1_board(tmp_path: Path) -> Path:
    """The checkerboard on the wall of the EuRoC Vicon room (7 x 8 squares: 6 x 7 inner corners;
    the square size does not matter for the intrinsics)."""
    t = tmp_path / "checker.yaml"
    t.write_text(yaml.safe_dump({"target_type": "checkerboard", "targetRows": 6, "targetCols": 7,
                                 "rowSpacingMeters": 0.06, "colSpacingMeters": 0.06}))
    return t


def test_calib_opens_the_real_euroc_excerpt(tmp_path):
    res = CliRunner().invoke(cli, ["calib", str(EUROC_REAL)])
    _one_line_exit_2(res, "no target description", "--target")
    out = tmp_path / "camchain.yaml"
    res = CliRunner().invoke(cli, ["calib", str(EUROC_REAL), "--target", str(_v1_board(tmp_path)),
                                   "--yaml", str(out), "--json"])
    assert res.exit_code in (0, 2), res.output
    if res.exit_code == 0:  # the board on the wall is found in every real frame of both cameras
        import json

        det = json.loads(res.stdout)["detection"]["cameras"]
        assert [(d["name"], d["frames_tried"], d["target_found"]) for d in det] == [
            ("cam0", 4, 4), ("cam1", 4, 4)]


def test_calib_on_four_near_identical_real_views_refuses_or_covers_the_truth(tmp_path):
    """4 near-identical views of a small wall board once gave fx 1620 +- 29 px (EuRoC's
    calibration: 458.65 px); the views' target orientations differ by 0.05 deg, so calibrate
    refuses them (or, should it solve, its std must cover the truth)."""
    from ibiscape_eval import calibrate_cameras
    from ibiscape_eval.core.errors import CalibrationError
    from ibiscape_eval.core.kalibr import target_from_kalibr

    seq = open_sequence(EUROC_REAL, cameras=["cam0"])
    target = target_from_kalibr(yaml.safe_load(_v1_board(tmp_path).read_text()))
    try:
        run = calibrate_cameras(seq, target=target)
    except CalibrationError as e:
        assert "cam0" in str(e) and "deg" in str(e) and "tilted" in str(e), str(e)
        return
    assert run.result is not None
    c = run.result.cameras[0]
    fx_std = float(c.std["intrinsics"][0])
    assert abs(c.camera.fx - 458.654) < 5 * fx_std, (c.camera.fx, fx_std)


def test_real_bag_frames_and_imu_equal_the_euroc_files():
    seq = open_sequence(BAG_REAL)
    assert seq.layout == "rosbag" and seq.camera_names == ["cam0", "cam1"]
    assert [c.rostopic for c in seq.cameras] == ["/cam0/image_raw", "/cam1/image_raw/compressed"]
    assert seq.cameras[0].sensor_size == (752, 480) and seq.cameras[1].sensor_size == (752, 480)
    ref = open_sequence(EUROC_REAL)
    for k in (0, 1):
        np.testing.assert_array_equal(seq.cameras[k].stamps_ns, ref.cameras[k].stamps_ns[:2])
        for i in (0, 1):
            np.testing.assert_array_equal(seq.cameras[k].load(i), ref.cameras[k].load(i))
    assert seq.imu is not None and seq.imu.rostopic == "/imu0"
    st, g, a = seq.imu.samples.get()
    rst, rg, ra = ref.imu.samples.get()
    np.testing.assert_array_equal(st, rst[: st.size])
    np.testing.assert_array_equal(np.hstack([g, a]), np.hstack([rg, ra])[: st.size])


# -------------------------------------------------------------------------------- bag topics
def test_bag_without_the_named_topic_lists_its_topics(tmp_path):
    out = tmp_path / "est.txt"
    res = CliRunner().invoke(cli, ["vio", str(BAG_REAL), "-o", str(out), "--topic", "/left",
                                   "--topic", "/cam1/image_raw/compressed"])
    line = _one_line_exit_2(res, "no topic '/left'", "/cam0/image_raw (sensor_msgs/Image, 2)",
                            "/imu0 (sensor_msgs/Imu")
    assert str(BAG_REAL) in line and not out.exists()
    with pytest.raises(FormatError, match="carries sensor_msgs/msg/Imu"):
        open_sequence(BAG_REAL, image_topics=["/imu0"])


def test_ambiguous_bag_topics_are_listed_ros1_and_ros2(tmp_path):
    for ros2 in (False, True):
        bag = bag_from_euroc(EUROC_REAL, tmp_path / ("b2" if ros2 else "b1.bag"), ros2=ros2,
                             extra_image_topics=("/cam0/image_rect",), extra_imu_topics=("/imu1",))
        with pytest.raises(FormatError, match=r"3 image topics \(/cam0/image_raw, /cam0/image_rect, "
                                              r"/cam1/image_raw/compressed\); choose the cameras with --topic"):
            open_sequence(bag)
        with pytest.raises(FormatError, match=r"2 sensor_msgs/Imu topics \(/imu0, /imu1\)"):
            open_sequence(bag, image_topics=["/cam0/image_raw", "/cam0/image_rect"])
        seq = open_sequence(bag, image_topics=["/cam0/image_rect", "/cam1/image_raw/compressed"],
                            imu_topic="/imu1")
        assert seq.camera_names == ["cam0", "cam1"] and seq.imu is not None and seq.imu.rostopic == "/imu1"
        assert len(seq.cameras[0]) == 4 and seq.cameras[1].load(3).shape == (480, 752)
        res = CliRunner().invoke(cli, ["calib", str(bag), "--target", str(tmp_path / "none.yaml")])
        assert res.exit_code == 2


# ------------------------------------------------------------------------------ the layouts
def test_folder_in_no_layout_says_what_each_lacked(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(NoLayoutError) as e:
        open_sequence(tmp_path)
    msg = str(e.value)
    for w in ("ROS bag: not a .bag file", "IBISCape: no sequence.yaml", "TUM-VI: no mav0/camN/data.csv",
              "EuRoC/ASL: no mav0/camN/data.csv", "--images NAME=GLOB"):
        assert w in msg, msg
    out = tmp_path / "camchain.yaml"
    res = CliRunner().invoke(cli, ["calib", str(tmp_path), "--yaml", str(out)])
    _one_line_exit_2(res, "in none of the sequence layouts", "IBISCape: no sequence.yaml")
    assert not out.exists()
    # an ASL folder without dso/ is EuRoC, not TUM-VI, and TUM-VI says so when forced
    with pytest.raises(NoLayoutError, match=r"TUM-VI: no dso/camchain\.yaml"):
        open_sequence(EUROC_REAL, layout="tumvi")


def test_tumvi_layout_takes_the_equidistant_camchain(tmp_path):
    tum = tumvi_from_euroc(EUROC_REAL, tmp_path / "dataset-room1_512_16")
    seq = open_sequence(tum)
    assert seq.layout == "tumvi"
    chain = yaml.safe_load((tum / "dso" / "camchain.yaml").read_text())
    for cam in seq.cameras:
        assert cam.camera is not None and cam.camera.distortion == "equidistant"
        np.testing.assert_allclose(np.linalg.inv(cam.T_body_cam), chain[cam.name]["T_cam_imu"], atol=1e-12)
    assert seq.imu is not None and seq.imu.noise is not None and seq.imu.rate_hz == 200.0
    np.testing.assert_array_equal(seq.imu.T_body_imu, np.eye(4))


def test_camchain_that_disagrees_with_the_sequence_says_so(tmp_path):
    seq = open_sequence(EUROC_REAL)
    entry = {"camera_model": "pinhole", "intrinsics": [450.0, 450.0, 320.0, 240.0],
             "distortion_model": "radtan", "distortion_coeffs": [0.0] * 4}
    T = np.eye(4)
    T[0, 3] = -0.11

    def write(doc: dict) -> Path:
        for e in list(doc.values())[1:]:
            e.setdefault("T_cn_cnm1", T.tolist())
        chain = tmp_path / "camchain.yaml"
        chain.write_text(yaml.safe_dump(doc))
        return chain

    chain = write({"cam0": {**entry, "resolution": [640, 480]}, "cam1": {**entry, "resolution": [752, 480]}})
    with pytest.raises(FormatError, match=r"cam0 is 640x480 px but the sequence's camera cam0 is 752x480 px"):
        apply_camchain(seq, chain)
    globs = open_sequence(images=[f"left={EUROC_REAL}/mav0/cam0/data/*.png",
                                  f"right={EUROC_REAL}/mav0/cam1/data/*.png"])
    chain = write({"cam0": {**entry, "resolution": [752, 480], "rostopic": "/left/image_raw"},
                   "cam1": {**entry, "resolution": [752, 480], "rostopic": "/middle/image_raw"}})
    with pytest.raises(FormatError, match=r"has no entry for the sequence's camera\(s\) right .*cam1 "
                                          r"\(/middle/image_raw\); the sequence has left, right"):
        apply_camchain(globs, chain)
    chain = write({c: {**entry, "resolution": [752, 480], "rostopic": f"/{c}/image_raw"} for c in ("cam0", "cam1")})
    fixed = apply_camchain(seq, chain)
    assert fixed.cameras[1].camera is not None and fixed.cameras[1].camera.fx == 450.0
    # the VIO compares a camchain's image size with the images themselves
    chain.write_text(yaml.safe_dump({c: {**entry, "resolution": [640, 480], "T_cam_imu": M.tolist()}
                                     for c, M in (("cam0", np.eye(4)), ("cam1", T))}))
    out = tmp_path / "est.txt"
    res = CliRunner().invoke(cli, ["vio", str(EUROC_REAL), "-o", str(out), "--calib", str(chain)])
    _one_line_exit_2(res, "752x480", "640x480")
    assert not out.exists()


def test_sequence_states_what_hotpix_and_events_need(tmp_path):
    """An IBISCape DVS folder's sensor size comes from sequence.yaml (the helper ev6's commands
    take ``seq.cameras[i].sensor_size``)."""
    from ibiscape_eval.sim import generate, preset
    from ibiscape_eval.sim.config import with_resolution

    cfg = with_resolution(preset("esvi", "slam", "clear", duration_s=0.3, seed=1), 64, 48)
    generate(cfg, tmp_path / "ESVI", render=False)
    seq = open_sequence(tmp_path / "ESVI", layout="ibiscape")
    doc = yaml.safe_load((tmp_path / "ESVI" / "sequence.yaml").read_text())
    assert seq.imu is not None and seq.imu.noise is not None
    assert seq.imu.noise.gyro_noise_density_rad_s_sqrt_hz == doc["imus"]["imu0"]["gyroscope_noise_density"]
    assert seq.target is None or isinstance(seq.target, dict)
    assert seq.groundtruth is not None and len(seq.ground_truth()) > 0


# ------------------------------------------------------------------------- vio end to end
@pytest.fixture(scope="module")
def street_euroc(tmp_path_factory):
    from families import _vio_sequence

    d = tmp_path_factory.mktemp("street")
    seq = _vio_sequence(d)
    return seq, euroc_from(seq, d / "MH_street", seq / "camchain-imucam.yaml")


def test_vio_on_euroc_with_opencv_yaml_and_empty_gt_equals_the_ibiscape_run(street_euroc, tmp_path):
    from ibiscape_eval import open_sequence as door
    from ibiscape_eval import run_vio

    seq_dir, euroc = street_euroc
    a = run_vio(door(seq_dir), calib=seq_dir / "camchain-imucam.yaml", max_frames=20)
    b = run_vio(door(euroc), max_frames=20)
    np.testing.assert_allclose(b.trajectory.pos_m, a.trajectory.pos_m, atol=1e-6)
    out = tmp_path / "est.txt"
    res = CliRunner().invoke(cli, ["vio", str(euroc), "-o", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert out.exists() and '"ate"' not in res.stdout  # no ground truth: no ATE, no failure


def test_vio_on_a_ros2_bag_with_calib_and_imu_yaml(street_euroc, tmp_path):
    from ibiscape_eval import open_sequence as door
    from ibiscape_eval import run_vio

    seq_dir, euroc = street_euroc
    bag = bag_from_euroc(euroc, tmp_path / "street_ros2", ros2=True, compressed_right=False)
    with pytest.raises(CalibrationError, match="the bag holds no calibration; give calib"):
        run_vio(door(bag))
    calib, imu = seq_dir / "camchain-imucam.yaml", seq_dir / "imu.yaml"
    a = run_vio(door(euroc), calib=calib, imu_yaml=imu, max_frames=20)
    b = run_vio(door(bag), calib=calib, imu_yaml=imu, max_frames=20)
    np.testing.assert_allclose(b.trajectory.pos_m, a.trajectory.pos_m, atol=1e-6)
    with pytest.raises(DegenerateInputError, match="only 3 stereo frames"):
        run_vio(door(bag), calib=calib, imu_yaml=imu, max_frames=3)


def test_stated_sensor_size_for_hotpix_and_events_frames(tmp_path):
    """What ``hotpix``/``events frames`` read instead of inferring 256x256: the size sequence.yaml
    states, for the sequence folder (a camera named) and for its DVS camera folder, the same in
    open_sequence and in the events reader."""
    from ibiscape_eval.core.errors import FormatError
    from ibiscape_eval.io.events import open_events
    from ibiscape_eval.sim import generate, preset
    from ibiscape_eval.sim.config import with_resolution

    cfg = with_resolution(preset("esvi", "slam", "clear", duration_s=0.3, seed=2), 64, 48)
    generate(cfg, tmp_path / "ESVI", render=True)
    seq = open_sequence(tmp_path / "ESVI")
    davis = [c for c in seq.cameras if c.kind == "events"]
    assert [c.name for c in davis] == ["davisL", "davisR"]
    assert all(c.sensor_size == (64, 48) and len(c) > 0 for c in davis)
    assert open_events(tmp_path / "ESVI" / "davisR").sensor_size == (64, 48)
    assert open_events(tmp_path / "ESVI" / "davisL").sensor_size == (64, 48)
    assert open_sequence(tmp_path / "ESVI" / "davisL").cameras[0].events.get() is not None
    with pytest.raises(FormatError, match="several DVS cameras"):  # two event cameras: name one
        open_events(tmp_path / "ESVI")
