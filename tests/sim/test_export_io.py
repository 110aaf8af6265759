"""Property round trips of the export writers and their readers (io.asl, io.tum_rgbd,
io.rosbag_export, io.dvs_folder)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs
from hypothesis.extra import numpy as hnp

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.events import Events
from ibiscape_eval.core.trajectory import Trajectory
from ibiscape_eval.io.asl import (
    AslGroundTruth,
    read_asl_groundtruth,
    read_asl_image_list,
    read_asl_sensor_yaml,
    read_imu_samples,
    write_asl_groundtruth,
    write_asl_image_list,
    write_asl_imu,
    write_asl_sensor_yaml,
)
from ibiscape_eval.io.dvs_folder import DvsFolderWriter, read_dvs_frame_list
from ibiscape_eval.io.events import open_events, read_events
from ibiscape_eval.io.imu import mirror_ibiscape_imu
from ibiscape_eval.io.rosbag_export import RosbagWriter, read_bag_images, read_bag_imu
from ibiscape_eval.io.tum_rgbd import read_tum_list, stamp_text, write_tum_list

_f = hs.floats(-1e4, 1e4, allow_nan=False, width=64)


def _stamps(data: hs.DataObject, n: int) -> np.ndarray:
    steps = data.draw(hnp.arrays(np.int64, n, elements=hs.integers(1, 10**10)))
    return np.cumsum(steps) + data.draw(hs.integers(0, 10**18))


@settings(max_examples=30)
@given(n=hs.integers(1, 50), data=hs.data())
def test_asl_imu_round_trip(n: int, data: hs.DataObject) -> None:
    st = _stamps(data, n)
    g = data.draw(hnp.arrays(np.float64, (n, 3), elements=_f))
    a = data.draw(hnp.arrays(np.float64, (n, 3), elements=_f))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "data.csv"
        write_asl_imu(p, st, g, a)
        st2, g2, a2 = read_imu_samples(p)
        _, g3, a3 = read_imu_samples(p, frame="ibiscape")
    np.testing.assert_array_equal(st2, st)
    np.testing.assert_allclose(g2, g, rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(a2, a, rtol=1e-14, atol=1e-300)
    gm, am = mirror_ibiscape_imu(g2, a2)
    np.testing.assert_array_equal(g3, gm)
    np.testing.assert_array_equal(a3, am)


@settings(max_examples=30)
@given(n=hs.integers(1, 40), data=hs.data())
def test_asl_groundtruth_round_trip(n: int, data: hs.DataObject) -> None:
    st = _stamps(data, n)
    pos = data.draw(hnp.arrays(np.float64, (n, 3), elements=_f))
    q = data.draw(hnp.arrays(np.float64, (n, 4), elements=hs.floats(-1, 1, width=64)))
    q[np.linalg.norm(q, axis=1) < 0.1] = [0.0, 0.0, 0.0, 1.0]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    v, bg, ba = (data.draw(hnp.arrays(np.float64, (n, 3), elements=_f)) for _ in range(3))
    gt = AslGroundTruth(Trajectory(st, pos, q, "gt"), v, bg, ba)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "data.csv"
        write_asl_groundtruth(p, gt)
        back = read_asl_groundtruth(p)
    np.testing.assert_array_equal(back.trajectory.stamps_ns, st)
    np.testing.assert_allclose(back.trajectory.pos_m, pos, rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(np.abs(np.sum(back.trajectory.quat_xyzw * q, axis=1)), 1.0,
                               atol=1e-13)
    for x, y in ((back.vel_m_s, v), (back.gyro_bias_rad_s, bg), (back.accel_bias_m_s2, ba)):
        np.testing.assert_allclose(x, y, rtol=1e-14, atol=1e-300)
    assert repr(back) == f"AslGroundTruth({n} states)"


@settings(max_examples=30)
@given(n=hs.integers(0, 30), data=hs.data())
def test_image_lists_round_trip(n: int, data: hs.DataObject) -> None:
    st = _stamps(data, n)
    with tempfile.TemporaryDirectory() as d:
        write_asl_image_list(Path(d) / "data.csv", st)
        st2, names = read_asl_image_list(Path(d) / "data.csv")
        files = [f"rgb/{s}.png" for s in stamp_text(st)]
        write_tum_list(Path(d) / "rgb.txt", st, files, what="color images")
        st3, files3 = read_tum_list(Path(d) / "rgb.txt")
    np.testing.assert_array_equal(st2, st)
    assert names == [f"{int(t)}.png" for t in st]
    np.testing.assert_array_equal(st3, st)  # exact: 9 decimals unless whole microseconds
    assert files3 == files


def test_stamp_text_uses_microseconds_like_tum_when_exact() -> None:
    assert stamp_text([1_305_031_102_175_304_000]) == ["1305031102.175304"]
    assert stamp_text([1_000_000_001]) == ["1.000000001"]


@settings(max_examples=15)
@given(data=hs.data())
def test_sensor_yaml_round_trip(data: hs.DataObject) -> None:
    from scipy.spatial.transform import Rotation

    # the reader checks T_BS is rigid (one sensor.yaml reader for export and VIO)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(data.draw(hnp.arrays(np.float64, 3, elements=hs.floats(-3, 3)))).as_matrix()
    T[:3, 3] = data.draw(hnp.arrays(np.float64, 3, elements=hs.floats(-100, 100)))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "sensor.yaml"
        write_asl_sensor_yaml(p, sensor_type="camera", comment="c", T_BS=T,
                              fields={"rate_hz": 20.0, "resolution": [40, 30]})
        y = read_asl_sensor_yaml(p)
    np.testing.assert_array_equal(y["T_BS"], T)
    assert y["rate_hz"] == 20.0 and y["resolution"] == [40, 30] and y["sensor_type"] == "camera"


@settings(max_examples=10)
@given(n=hs.integers(1, 20), data=hs.data())
def test_rosbag_round_trip(n: int, data: hs.DataObject) -> None:
    st = _stamps(data, n)
    g = data.draw(hnp.arrays(np.float64, (n, 3), elements=_f))
    a = data.draw(hnp.arrays(np.float64, (n, 3), elements=_f))
    h, w = data.draw(hs.integers(1, 6)), data.draw(hs.integers(1, 6))
    gray = data.draw(hnp.arrays(np.uint8, (2, h, w)))
    rgb = data.draw(hnp.arrays(np.uint8, (2, h, w, 3)))
    with tempfile.TemporaryDirectory() as d:
        bag = Path(d) / "x.bag"
        with RosbagWriter(bag) as wr:
            for k in range(n):
                wr.add_imu("/imu0", int(st[k]), g[k], a[k], frame_id="imu0")
            for k in range(2):
                wr.add_image("/cam0/image_raw", int(st[0]) + k, gray[k], frame_id="cam0")
                wr.add_image("/cam1/image_raw", int(st[0]) + k, rgb[k], frame_id="cam1")
        st2, g2, a2 = read_bag_imu(bag, "/imu0")
        s0, im0 = read_bag_images(bag, "/cam0/image_raw")
        _, im1 = read_bag_images(bag, "/cam1/image_raw")
    np.testing.assert_array_equal(st2, st)
    np.testing.assert_array_equal(g2, g)
    np.testing.assert_array_equal(a2, a)
    np.testing.assert_array_equal(np.stack(im0), gray)
    np.testing.assert_array_equal(np.stack(im1), rgb)
    np.testing.assert_array_equal(s0, int(st[0]) + np.arange(2))


def test_rosbag_writer_is_atomic_and_refuses_bad_images(tmp_path: Path) -> None:
    bag = tmp_path / "x.bag"
    with pytest.raises(IbiscapeError, match="uint8"), RosbagWriter(bag) as wr:
        wr.add_image("/cam0/image_raw", 1, np.zeros((2, 2), np.float32), frame_id="cam0")
    assert list(tmp_path.iterdir()) == []
    bag.write_bytes(b"")
    with pytest.raises(IbiscapeError, match="already exists"):
        RosbagWriter(bag)


@settings(max_examples=20)
@given(data=hs.data())
def test_dvs_folder_round_trip(data: hs.DataObject) -> None:
    n_win = data.draw(hs.integers(1, 5))
    edges = _stamps(data, n_win + 1)
    windows = []
    for k in range(n_win):
        a, b = int(edges[k]), int(edges[k + 1])
        m = data.draw(hs.integers(0, 30))
        t = np.sort(data.draw(hnp.arrays(np.int64, m, elements=hs.integers(a, b))))
        x = data.draw(hnp.arrays(np.uint16, m))
        y = data.draw(hnp.arrays(np.uint16, m))
        p = data.draw(hnp.arrays(np.bool_, m))
        windows.append((a, b, Events(t, x, y, p)))
    with tempfile.TemporaryDirectory() as d:
        w = DvsFolderWriter(Path(d) / "davisL")
        for a, b, ev in windows:
            w.add(a, b, ev, np.zeros((2, 3), np.uint8))
        assert w.close() == n_win
        src = open_events(Path(d) / "davisL")
        got = [(a, b) for a, b, _ in src.windows]
        total = sum(len(ev) for _, _, ev in windows)
        ev_all = read_events(Path(d) / "davisL") if total else None
        fst, fpaths = read_dvs_frame_list(Path(d) / "davisL")
    assert got == [(a, b) for a, b, _ in windows]
    np.testing.assert_array_equal(fst, [b for _, b, _ in windows])
    assert [p.name for p in fpaths] == [f"{b}.png" for _, b, _ in windows]
    if ev_all is not None:
        cat = Events.concatenate([ev for _, _, ev in windows])
        for k in ("t_ns", "x", "y", "p"):
            np.testing.assert_array_equal(getattr(ev_all, k), getattr(cat, k))


def test_dvs_folder_refuses_windows_out_of_order(tmp_path: Path) -> None:
    w = DvsFolderWriter(tmp_path / "d", frames=False)
    w.add(10, 20, Events.empty())
    with pytest.raises(IbiscapeError, match="out of order"):
        w.add(5, 30, Events.empty())


def test_readers_name_the_file_and_line(tmp_path: Path) -> None:
    p = tmp_path / "data.csv"
    p.write_text("#timestamp [ns],filename\n1,1.png\nabc,2.png\n")
    with pytest.raises(FormatError, match=r"data\.csv:3:"):
        read_asl_image_list(p)
    q = tmp_path / "rgb.txt"
    q.write_text("# x\n1.5 rgb/a.png\nnot-a-time rgb/b.png\n")
    with pytest.raises(FormatError, match=r"rgb\.txt:3:"):
        read_tum_list(q)
    r = tmp_path / "imu.csv"
    r.write_text("#t,wx,wy,wz,ax,ay,az\n2,0,0,0,0,0,0\n1,0,0,0,0,0,0\n")
    with pytest.raises(FormatError, match="increase"):
        read_imu_samples(r)
    s = tmp_path / "sensor.yaml"
    s.write_text("sensor_type: camera\nT_BS: [1, 2]\n")
    with pytest.raises(FormatError, match="T_BS"):
        read_asl_sensor_yaml(s)


def test_dvs_folder_disk_full_is_one_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    import ibiscape_eval.io.dvs_folder as dvs_folder

    def full(*args: object, **kw: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(dvs_folder, "write_events", full)
    w = DvsFolderWriter(tmp_path / "d", frames=False)
    with pytest.raises(IbiscapeError, match="disk filled up"):
        w.add(1, 2, Events.empty())
