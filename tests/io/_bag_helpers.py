"""Test-only: write pose messages into ROS 1 / ROS 2 bags with rosbags' writers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_typestore


def _msgs(ts, msgtype, stamps_ns, pos, quat_xyzw, frame="map", child="base_link"):
    Time = ts.types["builtin_interfaces/msg/Time"]
    Header = ts.types["std_msgs/msg/Header"]
    Point = ts.types["geometry_msgs/msg/Point"]
    Quaternion = ts.types["geometry_msgs/msg/Quaternion"]
    Pose = ts.types["geometry_msgs/msg/Pose"]
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    Transform = ts.types["geometry_msgs/msg/Transform"]
    TransformStamped = ts.types["geometry_msgs/msg/TransformStamped"]
    for t, p, q in zip(stamps_ns, pos, quat_xyzw, strict=True):
        stamp = Time(sec=int(t) // 10**9, nanosec=int(t) % 10**9)
        if "seq" in Header.__dataclass_fields__:  # ROS 1
            hdr = Header(seq=0, stamp=stamp, frame_id=frame)
        else:
            hdr = Header(stamp=stamp, frame_id=frame)
        pose = Pose(position=Point(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                    orientation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]),
                                           w=float(q[3])))
        tr = TransformStamped(header=hdr, child_frame_id=child, transform=Transform(
            translation=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
            rotation=pose.orientation))
        if msgtype == "geometry_msgs/msg/PoseStamped":
            yield t, ts.types[msgtype](header=hdr, pose=pose)
        elif msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
            pwc = ts.types["geometry_msgs/msg/PoseWithCovariance"](
                pose=pose, covariance=np.zeros(36))
            yield t, ts.types[msgtype](header=hdr, pose=pwc)
        elif msgtype == "nav_msgs/msg/Odometry":
            pwc = ts.types["geometry_msgs/msg/PoseWithCovariance"](
                pose=pose, covariance=np.zeros(36))
            twc = ts.types["geometry_msgs/msg/TwistWithCovariance"](
                twist=ts.types["geometry_msgs/msg/Twist"](
                    linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                covariance=np.zeros(36))
            yield t, ts.types[msgtype](header=hdr, child_frame_id=child, pose=pwc, twist=twc)
        elif msgtype == "geometry_msgs/msg/TransformStamped":
            yield t, tr
        elif msgtype == "tf2_msgs/msg/TFMessage":
            other = TransformStamped(header=hdr, child_frame_id="other", transform=tr.transform)
            yield t, ts.types[msgtype](transforms=[other, tr])
        else:  # pragma: no cover
            raise ValueError(msgtype)


def write_bag(path: Path, ros: int, topics: dict[str, tuple[str, np.ndarray, np.ndarray,
              np.ndarray]]) -> Path:
    """Write ``{topic: (msgtype, stamps_ns, pos, quat_xyzw)}``; receive time = stamp + 1 ms."""
    if ros == 1:
        from rosbags.rosbag1 import Writer as Writer1

        ts = get_typestore(Stores.ROS1_NOETIC)
        if "tf2_msgs/msg/TFMessage" not in ts.types:
            from rosbags.typesys import get_types_from_msg

            ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                           "tf2_msgs/msg/TFMessage"))
        with Writer1(path) as w:
            for topic, (msgtype, st, pos, q) in topics.items():
                conn = w.add_connection(topic, msgtype, typestore=ts)
                for t, msg in _msgs(ts, msgtype, st, pos, q):
                    w.write(conn, int(t) + 1_000_000, ts.serialize_ros1(msg, msgtype))
    else:
        from rosbags.rosbag2 import Writer as Writer2

        ts = get_typestore(Stores.ROS2_HUMBLE)
        with Writer2(path, version=8) as w:
            for topic, (msgtype, st, pos, q) in topics.items():
                conn = w.add_connection(topic, msgtype, typestore=ts)
                for t, msg in _msgs(ts, msgtype, st, pos, q):
                    w.write(conn, int(t) + 1_000_000, ts.serialize_cdr(msg, msgtype))
    return path
