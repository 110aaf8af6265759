"""hypothesis round-trips: write -> read gives the same stamps (exactly) and poses."""

from __future__ import annotations

import warnings

import numpy as np
from _io_helpers import assert_same_poses, trajectories
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ibiscape_eval.io import (
    GnssFixes,
    IbiscapeGroundTruth,
    read_gnss,
    read_ibiscape_groundtruth,
    read_trajectory,
    write_gnss,
    write_ibiscape_groundtruth,
    write_trajectory,
)

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@SETTINGS
@given(traj=trajectories())
def test_tum_roundtrip(tmp_path, traj):
    p = tmp_path / "t.txt"
    write_trajectory(p, traj, "tum")
    assert_same_poses(read_trajectory(p, "tum"), traj)
    assert_same_poses(read_trajectory(p), traj)  # detected as TUM


@SETTINGS
@given(traj=trajectories())
def test_euroc_roundtrip(tmp_path, traj):
    p = tmp_path / "data.csv"
    write_trajectory(p, traj, "euroc")
    assert_same_poses(read_trajectory(p, "euroc"), traj)
    assert_same_poses(read_trajectory(p), traj)


@SETTINGS
@given(traj=trajectories())
def test_kitti_with_times_roundtrip(tmp_path, traj):
    p, t = tmp_path / "poses.txt", tmp_path / "times.txt"
    write_trajectory(p, traj, "kitti", times_path=t)
    back = read_trajectory(p, "kitti", times_path=t)
    assert_same_poses(back, traj)
    # without times: index at 10 Hz, same poses
    idx = read_trajectory(p)
    np.testing.assert_array_equal(idx.stamps_ns, np.arange(len(traj)) * 100_000_000)
    assert_same_poses(idx, traj, stamps=False)


@st.composite
def groundtruths(draw):
    traj = draw(trajectories(epoch=draw(st.booleans())))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = len(traj)
    return IbiscapeGroundTruth(traj, rng.normal(size=(n, 3)) * 10, rng.normal(size=(n, 3)),
                               rng.normal(size=(n, 3)))


@SETTINGS
@given(gt=groundtruths())
def test_ibiscape_groundtruth_roundtrip(tmp_path, gt):
    p = tmp_path / "groundtruth_sync.csv"
    write_ibiscape_groundtruth(p, gt)
    back = read_ibiscape_groundtruth(p)
    assert_same_poses(back.trajectory, gt.trajectory)
    for a, b in ((back.vel_m_s, gt.vel_m_s), (back.acc_m_s2, gt.acc_m_s2),
                 (back.angvel_rad_s, gt.angvel_rad_s)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    assert_same_poses(read_trajectory(p), gt.trajectory)  # detected as ibiscape


def test_ibiscape_file_is_left_handed_carla_layout(tmp_path):
    traj_q = np.array([[0.0, 0.0, np.sin(0.25), np.cos(0.25)]])
    from ibiscape_eval.core.trajectory import Trajectory

    gt = IbiscapeGroundTruth(Trajectory([123456789000], [[1.0, 2.0, 3.0]], traj_q),
                             [[4.0, 5.0, 6.0]], [[7.0, 8.0, 9.0]], [[0.1, 0.2, 0.3]])
    p = tmp_path / "groundtruth_sync.csv"
    write_ibiscape_groundtruth(p, gt)
    raw = p.read_bytes()
    header, row = raw.split(b"\r\n")
    assert header.startswith(b"#timestamp [ns],p_RS_R_x_m_,")
    assert row.endswith(b" \n")
    fields = row[:-2].split(b",")
    assert fields[0] == b"123456789000.000000"
    vals = [float(x) for x in fields[1:]]
    # y of p, v, a mirrored; w = -S w_file -> file w = (-0.1, 0.2, -0.3)
    np.testing.assert_allclose(vals[:9], [1, -2, 3, 4, -5, 6, 7, -8, 9])
    np.testing.assert_allclose(vals[13:], [-0.1, 0.2, -0.3])
    # quaternion (w, x, y, z): ours (0, 0, s, c) -> file (c, 0, 0, -s)
    np.testing.assert_allclose(vals[9:13], [np.cos(0.25), 0, 0, -np.sin(0.25)])


@SETTINGS
@given(data=st.data())
def test_gnss_roundtrip(tmp_path, data):
    n = data.draw(st.integers(1, 30))
    start = data.draw(st.integers(0, 4 * 10**18))
    steps = data.draw(st.lists(st.integers(1, 10**10), min_size=n, max_size=n))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    fixes = GnssFixes(start + np.cumsum(steps), rng.uniform(-90, 90, n),
                      rng.uniform(-180, 180, n), rng.normal(size=n) * 100)
    p = tmp_path / "gnss.csv"
    write_gnss(p, fixes)
    back = read_gnss(p)
    np.testing.assert_array_equal(back.stamps_ns, fixes.stamps_ns)
    for f in ("lat_deg", "lon_deg", "alt_m"):
        np.testing.assert_allclose(getattr(back, f), getattr(fixes, f), rtol=1e-12, atol=1e-12)
    assert list(back.to_frame().columns) == ["stamp_ns", "lat_deg", "lon_deg", "alt_m"]


@SETTINGS
@given(traj=trajectories(min_size=3))
def test_ibiscape_write_trajectory_roundtrip(tmp_path, traj):
    p = tmp_path / "groundtruth_sync.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        write_trajectory(p, traj, "ibiscape")
    assert_same_poses(read_trajectory(p, "ibiscape"), traj)


def test_seconds_with_nine_decimals_are_exact(tmp_path):
    p = tmp_path / "t.txt"
    p.write_text("1305031098.665900001 0 0 0 0 0 0 1\n1305031098.999999999 0 0 0 0 0 0 1\n"
                 "1305031099.1 0 0 0 0 0 0 1\n")
    tr = read_trajectory(p)
    assert tr.stamps_ns.tolist() == [1305031098665900001, 1305031098999999999,
                                     1305031099100000000]
    out = tmp_path / "o.txt"
    write_trajectory(out, tr)
    assert "1305031098.665900001 " in out.read_text()
