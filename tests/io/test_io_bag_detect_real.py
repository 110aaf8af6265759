"""Bags (ROS 1/2 round trips via rosbags' writers), format detection, real files vs evo."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from _bag_helpers import write_bag
from _io_helpers import assert_same_poses, require_data, trajectories
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io import detect_trajectory_format, read_trajectory, write_trajectory

MSGTYPES = ["geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
            "geometry_msgs/msg/TransformStamped", "nav_msgs/msg/Odometry"]


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traj=trajectories(epoch=True, max_size=10), ros=st.sampled_from([1, 2]),
       msgtype=st.sampled_from([*MSGTYPES, "tf2_msgs/msg/TFMessage"]))
def test_bag_roundtrip(tmp_path, traj, ros, msgtype):
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    path = folder / ("x.bag" if ros == 1 else "bag2")
    write_bag(path, ros, {"/pose": (msgtype, traj.stamps_ns, traj.pos_m, traj.quat_xyzw)})
    assert detect_trajectory_format(path) == "bag"
    topic = "/pose:map.base_link" if msgtype.startswith("tf2") else None
    back = read_trajectory(path, topic=topic)
    assert_same_poses(back, traj, rtol=0, atol=0)


def test_bag_topic_errors(tmp_path):
    st_ns = np.array([1, 2], dtype=np.int64) * 10**9
    pos, q = np.zeros((2, 3)), np.tile([0.0, 0, 0, 1], (2, 1))
    p = write_bag(tmp_path / "two.bag", 1, {"/a": (MSGTYPES[0], st_ns, pos, q),
                                             "/b": (MSGTYPES[3], st_ns, pos, q)})
    with pytest.raises(FormatError, match=r"several pose topics; choose one with topic: /a, /b"):
        read_trajectory(p)
    with pytest.raises(FormatError, match=r"no topic '/c'"):
        read_trajectory(p, topic="/c")
    assert len(read_trajectory(p, topic="/b")) == 2
    with pytest.raises(FormatError, match=r"no TF topic"):
        read_trajectory(p, topic="/tf:map.base_link")


def test_bag_garbage(tmp_path):
    p = tmp_path / "x.bag"
    p.write_bytes(b"not a bag at all\x00\x01")
    with pytest.raises(FormatError, match=r"x.bag: cannot open as a ROS bag"):
        read_trajectory(p)


@pytest.mark.parametrize(("name", "fmt"), [
    ("freiburg1_xyz-groundtruth.txt", "tum"), ("freiburg1_xyz-rgbdslam.txt", "tum"),
    ("freiburg1_xyz-ORB_kf_mono.txt", "tum"), ("V102.txt", "tum"),
    ("V102_groundtruth.csv", "euroc"), ("ROS_example.bag", "bag"), ("tf_example_ros2", "bag"),
])
def test_detect_real_files(name, fmt):
    assert detect_trajectory_format(require_data() / name) == fmt


def test_detect_generated(tmp_path):
    from ibiscape_eval.core.trajectory import Trajectory

    tr = Trajectory([1, 2], np.zeros((2, 3)), np.tile([0.0, 0, 0, 1], (2, 1)))
    for fmt in ("tum", "kitti", "euroc", "ibiscape"):
        p = tmp_path / f"x.{fmt}"
        write_trajectory(p, tr, fmt)
        assert detect_trajectory_format(p) == fmt
    amb = tmp_path / "amb.csv"
    amb.write_text("1,0,0,0,0,0,0,1\n")
    with pytest.raises(FormatError, match=r"explicitly with fmt \(one of") as ei:
        detect_trajectory_format(amb)
    assert [r.option for r in ei.value.hint] == ["fmt"]
    folder = tmp_path / "folder"
    folder.mkdir()
    with pytest.raises(FormatError, match=r"explicitly with fmt"):
        detect_trajectory_format(folder)


def _evo_equal(ours, evo_traj):
    np.testing.assert_allclose(ours.stamps_s, evo_traj.timestamps, rtol=0, atol=1e-6)
    np.testing.assert_allclose(ours.pos_m, evo_traj.positions_xyz, rtol=1e-12, atol=1e-12)
    wxyz = ours.quat_xyzw[:, [3, 0, 1, 2]]
    dots = np.abs(np.einsum("ij,ij->i", wxyz, evo_traj.orientations_quat_wxyz
                            / np.linalg.norm(evo_traj.orientations_quat_wxyz, axis=1,
                                             keepdims=True)))
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


@pytest.mark.parametrize("name", ["freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt",
                                  "freiburg1_xyz-ORB_kf_mono.txt"])
def test_real_tum_matches_evo(name):
    from evo.tools import file_interface

    p = require_data() / name
    _evo_equal(read_trajectory(p), file_interface.read_tum_trajectory_file(str(p)))


def test_real_tum_with_duplicates_matches_evo():
    from evo.tools import file_interface

    p = require_data() / "V102.txt"
    with pytest.warns(match=r"4 duplicate timestamps at lines 433, 684, 736, 788"):
        ours = read_trajectory(p)
    evo_traj = file_interface.read_tum_trajectory_file(str(p))
    _, first = np.unique(evo_traj.timestamps, return_index=True)
    evo_traj.reduce_to_ids(np.sort(first))
    _evo_equal(ours, evo_traj)


def test_real_euroc_matches_evo():
    from evo.tools import file_interface

    p = require_data() / "V102_groundtruth.csv"
    ours = read_trajectory(p)
    assert ours.stamps_ns[0] == 1403715524907143168  # exact, not via float
    _evo_equal(ours, file_interface.read_euroc_csv_trajectory(str(p)))


def test_real_ros1_bag_matches_evo():
    from evo.tools import file_interface
    from rosbags.rosbag1 import Reader

    p = require_data() / "ROS_example.bag"
    for topic in ("groundtruth", "ORB-SLAM", "S-PTAM"):
        with Reader(p) as reader:
            evo_traj = file_interface.read_bag_trajectory(reader, topic)
        _evo_equal(read_trajectory(p, topic=topic), evo_traj)


def test_real_ros2_tf_bag():
    p = require_data() / "tf_example_ros2"
    with pytest.raises(FormatError, match=r"/tf:odom.base_footprint"):
        read_trajectory(p)
    tr = read_trajectory(p, topic="/tf:odom.base_footprint")
    assert len(tr) == 517 and tr.name == "/tf:odom.base_footprint"
    assert 1714741164e9 < tr.stamps_ns[0] < 1714741217e9
    static = read_trajectory(p, topic="/tf_static:base_footprint.base_link")
    assert len(static) == 1
