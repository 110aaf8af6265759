"""Exports (EuRoC/ASL, TUM RGB-D, ROS 1 bag) read back by the project's readers and by rosbags
equal the source sequence: IMU, ground truth, image stamps and pixels; one test per bad input."""

from __future__ import annotations

import dataclasses
import errno
from pathlib import Path

import cv2
import numpy as np
import pytest
from _sb_motion import START_NS, HelixMotion

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.io import read_ibiscape_groundtruth, read_trajectory
from ibiscape_eval.io.asl import (
    read_asl_groundtruth,
    read_asl_image_list,
    read_asl_sensor_yaml,
    read_imu_samples,
)
from ibiscape_eval.io.images import (
    decode_depth_carla_log,
    read_depth_mm,
    read_png,
    write_depth_carla_log,
    write_depth_mm,
    write_frame_timestamps,
    write_png,
)
from ibiscape_eval.io.imu import read_imu
from ibiscape_eval.io.rosbag_export import read_bag_images, read_bag_imu
from ibiscape_eval.io.sequence import read_sequence_yaml
from ibiscape_eval.io.tum_rgbd import read_tum_list
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.dvs import write_dvs_camera
from ibiscape_eval.sim.dvs.scenes import translating_texture
from ibiscape_eval.sim.export import ExportSummary, export_sequence

W, H = 40, 30


def _make_sequence(root: Path, setup: str, *, render: bool = True, depth_mm: bool = True) -> Path:
    """A generated sequence with fabricated frames laid out like the renderer's (RGB PNG, depth
    as CARLA log depth in frames/ plus 16-bit millimetres in mm/, DVS through the DVS model)."""
    cfg = preset(setup, "calibration", "clear", duration_s=0.5, seed=3)
    cfg = dataclasses.replace(cfg, cameras=tuple(dataclasses.replace(c, width_px=W, height_px=H)
                                                 for c in cfg.cameras))
    seq = root / f"{setup}_seq"
    generate(cfg, seq, motion=HelixMotion(duration_s=0.5, start_ns=cfg.start_ns))
    if not render:
        return seq
    rng = np.random.default_rng(9)
    stamps = cfg.start_ns + 50_000_000 * np.arange(10, dtype=np.int64)
    for c in cfg.cameras:
        folder = seq / c.name
        if c.kind == "dvs":
            write_dvs_camera(translating_texture((H, W), int(stamps[0])), c, stamps, folder)
            continue
        (folder / "frames").mkdir(parents=True)
        if c.kind == "depth" and depth_mm:
            (folder / "mm").mkdir()
        for t in stamps:
            if c.kind == "depth":
                d = rng.uniform(4.0, 60.0, (H, W))
                write_depth_carla_log(folder / "frames" / f"{t}.png", d)
                if depth_mm:
                    write_depth_mm(folder / "mm" / f"{t}.png", d)
            else:
                write_png(folder / "frames" / f"{t}.png", rng.integers(0, 256, (H, W, 3), np.uint8))
        write_frame_timestamps(folder / "timestamps.csv", stamps)
    return seq


@pytest.fixture(scope="module")
def full_seq(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _make_sequence(tmp_path_factory.mktemp("full"), "full")


@pytest.fixture(scope="module")
def svi_seq(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _make_sequence(tmp_path_factory.mktemp("svi"), "svi")


def _source_imu(seq: Path, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    doc = read_sequence_yaml(seq / "sequence.yaml")
    return read_imu_samples(seq / doc["imus"][name]["file"], frame="ibiscape")


def _frames(seq: Path, cam: str) -> tuple[np.ndarray, list[Path]]:
    from ibiscape_eval.io.images import read_frame_timestamps

    st, names = read_frame_timestamps(seq / cam / "timestamps.csv")
    return st, [seq / cam / "frames" / n for n in names]


def test_euroc_round_trip(full_seq: Path, tmp_path: Path) -> None:
    out = tmp_path / "euroc"
    s = export_sequence(full_seq, "euroc", out)
    assert isinstance(s, ExportSummary) and s.cameras == {"rgbL": "cam0", "rgbR": "cam1"}
    assert set(s.imus) == {"imu0", "imu1", "imu2"}
    doc = read_sequence_yaml(full_seq / "sequence.yaml")
    mav = out / "mav0"
    for cam, exp in s.cameras.items():
        st, paths = _frames(full_seq, cam)
        st2, names = read_asl_image_list(mav / exp / "data.csv")
        np.testing.assert_array_equal(st2, st)
        for p, n in zip(paths, names, strict=True):
            src = cv2.cvtColor(read_png(p), cv2.COLOR_RGB2GRAY)
            np.testing.assert_array_equal(read_png(mav / exp / "data" / n), src)
        y = read_asl_sensor_yaml(mav / exp / "sensor.yaml")
        np.testing.assert_allclose(y["T_BS"], np.asarray(doc["cameras"][cam]["T_body_cam"]))
        assert y["intrinsics"] == doc["cameras"][cam]["intrinsics"]
        assert y["resolution"] == [W, H] and y["distortion_model"] == "radial-tangential"
    for name in ("imu0", "imu1", "imu2"):
        st, g, a = _source_imu(full_seq, name)
        st2, g2, a2 = read_imu_samples(mav / name / "data.csv")
        np.testing.assert_array_equal(st2, st)
        np.testing.assert_allclose(g2, g, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(a2, a, rtol=1e-13, atol=1e-15)
        rec = read_imu(mav / name / "data.csv", fmt="euroc")  # the project's IMU reader
        np.testing.assert_allclose(rec.samples, np.concatenate([g, a], axis=1), rtol=1e-13,
                                   atol=1e-15)
        y = read_asl_sensor_yaml(mav / name / "sensor.yaml")
        assert y["gyroscope_noise_density"] == doc["imus"][name]["gyroscope_noise_density"]
    gt = read_ibiscape_groundtruth(full_seq / "vehicle_gt" / "groundtruth_sync.csv")
    traj = read_trajectory(mav / "state_groundtruth_estimate0" / "data.csv", fmt="euroc")
    np.testing.assert_array_equal(traj.stamps_ns, gt.trajectory.stamps_ns)
    np.testing.assert_allclose(traj.pos_m, gt.trajectory.pos_m, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(traj.quat_xyzw * gt.trajectory.quat_xyzw, axis=1)),
                               1.0, atol=1e-12)
    full = read_asl_groundtruth(mav / "state_groundtruth_estimate0" / "data.csv")
    np.testing.assert_allclose(full.vel_m_s, gt.vel_m_s, rtol=1e-13, atol=1e-12)
    assert s.n_images == 20 and s.n_groundtruth == len(gt)


def test_euroc_of_dvs_frames_when_there_is_no_rgb_camera(tmp_path: Path) -> None:
    seq = _make_sequence(tmp_path, "esvi")
    s = export_sequence(seq, "euroc", tmp_path / "e")
    assert s.cameras == {"davisL": "cam0", "davisR": "cam1"}
    st, _ = read_asl_image_list(tmp_path / "e" / "mav0" / "cam0" / "data.csv")
    assert st.size == 9  # one accumulated frame per event window


def test_tum_rgbd_round_trip(full_seq: Path, tmp_path: Path) -> None:
    out = tmp_path / "tum"
    s = export_sequence(full_seq, "tum-rgbd", out)
    assert s.cameras == {"rgb": "rgb", "depth": "depth"}
    st, paths = _frames(full_seq, "rgb")
    st2, files = read_tum_list(out / "rgb.txt")
    np.testing.assert_array_equal(st2, st)
    for p, f in zip(paths, files, strict=True):
        np.testing.assert_array_equal(read_png(out / f), read_png(p))
    dst, dpaths = _frames(full_seq, "depth")
    dst2, dfiles = read_tum_list(out / "depth.txt")
    np.testing.assert_array_equal(dst2, dst)
    for p, f in zip(dpaths, dfiles, strict=True):  # the exact millimetre copy is preferred
        np.testing.assert_array_equal(read_png(out / f), read_png(p.parent.parent / "mm" / p.name))
    assoc = [ln.split() for ln in (out / "association.txt").read_text().splitlines()]
    assert [(a[1], a[3]) for a in assoc] == list(zip(files, dfiles, strict=True))
    doc = read_sequence_yaml(full_seq / "sequence.yaml")
    gt = read_ibiscape_groundtruth(full_seq / "vehicle_gt" / "groundtruth_sync.csv")
    T_bc = np.asarray(doc["cameras"]["rgb"]["T_body_cam"], dtype=np.float64)
    want = gt.trajectory.matrices() @ T_bc
    got = read_trajectory(out / "groundtruth.txt", fmt="tum")
    np.testing.assert_array_equal(got.stamps_ns, gt.trajectory.stamps_ns)
    np.testing.assert_allclose(got.matrices(), want, atol=1e-12)


def test_tum_rgbd_from_carla_log_depth_only(tmp_path: Path) -> None:
    seq = _make_sequence(tmp_path, "rgbd", depth_mm=False)
    out = tmp_path / "tum"
    export_sequence(seq, "tum-rgbd", out)
    _, dpaths = _frames(seq, "depth")
    _, dfiles = read_tum_list(out / "depth.txt")
    for p, f in zip(dpaths, dfiles, strict=True):
        src_m = decode_depth_carla_log(read_png(p)[..., 0])
        np.testing.assert_allclose(read_depth_mm(out / f), np.round(src_m * 1000.0) / 1000.0,
                                   atol=1e-6)


def test_rosbag_round_trip(full_seq: Path, tmp_path: Path) -> None:
    bag = tmp_path / "calib.bag"
    s = export_sequence(full_seq, "rosbag", bag)
    assert s.cameras == {"rgbL": "/cam0/image_raw", "rgbR": "/cam1/image_raw"}
    for cam, topic in s.cameras.items():
        st, paths = _frames(full_seq, cam)
        st2, imgs = read_bag_images(bag, topic)
        np.testing.assert_array_equal(st2, st)
        for p, img in zip(paths, imgs, strict=True):
            np.testing.assert_array_equal(img, read_png(p))
    for name in ("imu0", "imu1"):
        st, g, a = _source_imu(full_seq, name)
        st2, g2, a2 = read_bag_imu(bag, f"/{name}")
        np.testing.assert_array_equal(st2, st)
        np.testing.assert_array_equal(g2, g)
        np.testing.assert_array_equal(a2, a)
        rec = read_imu(bag, fmt="rosbag", rostopic=f"/{name}")  # the project's bag reader
        np.testing.assert_array_equal(rec.samples, np.concatenate([g, a], axis=1))
    n_imu = sum(_source_imu(full_seq, n)[0].size for n in ("imu0", "imu1", "imu2"))
    assert s.n_images == 20 and s.n_imu_samples == n_imu


def _assert_nothing_written(out: Path) -> None:
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.stem}")]


def test_rgbd_export_of_an_svi_sequence_is_refused(svi_seq: Path, tmp_path: Path) -> None:
    out = tmp_path / "tum"
    with pytest.raises(IbiscapeError, match=r"depth camera.*svi sequence"):
        export_sequence(svi_seq, "tum-rgbd", out)
    _assert_nothing_written(out)


def test_export_of_an_unrendered_sequence_is_refused(tmp_path: Path) -> None:
    seq = _make_sequence(tmp_path, "svi", render=False)
    for fmt, out in (("euroc", tmp_path / "e"), ("rosbag", tmp_path / "b.bag")):
        with pytest.raises(IbiscapeError, match="no rendered RGB or DVS frames"):
            export_sequence(seq, fmt, out)
        _assert_nothing_written(out)


def test_not_enough_disk_space(full_seq: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    import ibiscape_eval.sim.export as ex

    monkeypatch.setattr(ex.shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(1, 1, 1000))  # type: ignore[attr-defined]
    for fmt, out in (("euroc", tmp_path / "e"), ("tum-rgbd", tmp_path / "t"),
                     ("rosbag", tmp_path / "b.bag")):
        with pytest.raises(IbiscapeError, match="not enough disk space"):
            export_sequence(full_seq, fmt, out)
        _assert_nothing_written(out)


def test_disk_full_while_writing_leaves_nothing(full_seq: Path, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    import ibiscape_eval.io.images as images

    real = images.write_png
    calls = []

    def failing(path: object, image: object, **kw: object) -> None:
        calls.append(path)
        if len(calls) > 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, image, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(images, "write_png", failing)
    out = tmp_path / "e"
    with pytest.raises(IbiscapeError, match="disk filled up"):
        export_sequence(full_seq, "euroc", out)
    _assert_nothing_written(out)


def test_other_bad_inputs(full_seq: Path, tmp_path: Path) -> None:
    with pytest.raises(IbiscapeError, match="unknown export format"):
        export_sequence(full_seq, "kitti", tmp_path / "k")
    with pytest.raises(IbiscapeError, match=r"sequence\.yaml"):
        export_sequence(tmp_path, "euroc", tmp_path / "x")
    with pytest.raises(IbiscapeError, match="no such sequence folder"):
        export_sequence(tmp_path / "missing", "euroc", tmp_path / "y")
    with pytest.raises(IbiscapeError, match="camera 'nope'"):
        export_sequence(full_seq, "euroc", tmp_path / "z", cameras=["nope"])
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "f").write_text("x")
    with pytest.raises(IbiscapeError, match="not an empty folder"):
        export_sequence(full_seq, "euroc", tmp_path / "busy")
    (tmp_path / "old.bag").write_bytes(b"")
    with pytest.raises(IbiscapeError, match="already exists"):
        export_sequence(full_seq, "rosbag", tmp_path / "old.bag")
    assert (tmp_path / "old.bag").read_bytes() == b""
    export_sequence(full_seq, "rosbag", tmp_path / "old.bag", overwrite=True)
    assert read_bag_imu(tmp_path / "old.bag", "/imu0")[0].size > 0
    assert START_NS > 0


def test_cli_sim_export_euroc_of_a_rendered_sequence(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from ibiscape_eval.cli.main import cli

    seq = tmp_path / "SVI_1_calib"
    exp = tmp_path / "SVI_1_calib_euroc"
    r = CliRunner().invoke(cli, ["sim", "--setup", "svi", "--kind", "calibration", "--resolution",
                                 "48", "--duration-s", "0.5", "--export", "euroc", "--export-out",
                                 str(exp), "--out", str(seq)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    for cam, exp_cam in (("rgbL", "cam0"), ("rgbR", "cam1")):
        st, paths = _frames(seq, cam)
        st2, names = read_asl_image_list(exp / "mav0" / exp_cam / "data.csv")
        np.testing.assert_array_equal(st2, st)
        src = cv2.cvtColor(read_png(paths[-1]), cv2.COLOR_RGB2GRAY)
        np.testing.assert_array_equal(read_png(exp / "mav0" / exp_cam / "data" / names[-1]), src)
    st, g, a = _source_imu(seq, "imu0")
    st2, g2, a2 = read_imu_samples(exp / "mav0" / "imu0" / "data.csv")
    np.testing.assert_array_equal(st2, st)
    np.testing.assert_allclose(np.concatenate([g2, a2], 1), np.concatenate([g, a], 1),
                               rtol=1e-13, atol=1e-15)
