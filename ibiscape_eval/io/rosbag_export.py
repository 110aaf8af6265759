"""ROS 1 bags with camera images and IMU samples (for Kalibr, VINS-Fusion, OpenVINS), written with
``rosbags`` (no ROS installation needed).

Messages: ``sensor_msgs/Image`` (``mono8`` for grey images, ``rgb8`` for colour; ``header.stamp``
= the frame time) on one topic per camera, ``sensor_msgs/Imu`` (orientation unknown:
``orientation_covariance[0] = -1``; covariances otherwise zero) on one topic per IMU.  The
bag's receive time of every message equals its header stamp.  Messages are written in time
order.  The bag is built under a temporary name and renamed into place on success.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from .atomic import discard, publish, staging_path
from .paths import check_input

__all__ = ["RosbagWriter", "read_bag_images", "read_bag_imu"]


class RosbagWriter:
    """Write images and IMU samples into a new ROS 1 bag at ``path`` (atomically; an existing
    file is replaced only with ``overwrite``, once the new bag is complete).

    Use as a context manager; :meth:`add_image` / :meth:`add_imu` in any order of topics but
    increasing time per topic (the caller merges topics by time to keep the bag ordered).
    """

    def __init__(self, path: str | os.PathLike[str], *, overwrite: bool = False) -> None:
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        if self.path.is_dir() or (self.path.exists() and not overwrite):
            raise IbiscapeError(f"{self.path}: already exists; choose a new bag file or remove it")
        self.ts = get_typestore(Stores.ROS1_NOETIC)
        self._dir = staging_path(self.path, folder=True)
        self._tmp = self._dir / self.path.name
        self._w = Writer(self._tmp)
        self._w.open()
        self._conns: dict[str, Any] = {}
        self._seq: dict[str, int] = {}
        self.n_messages = 0

    def __enter__(self) -> RosbagWriter:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _conn(self, topic: str, msgtype: str) -> Any:
        if topic not in self._conns:
            self._conns[topic] = self._w.add_connection(topic, msgtype, typestore=self.ts)
            self._seq[topic] = 0
        return self._conns[topic]

    def _header(self, topic: str, t_ns: int, frame_id: str) -> Any:
        T = self.ts.types
        seq = self._seq[topic]
        self._seq[topic] = seq + 1
        return T["std_msgs/msg/Header"](seq=seq, stamp=T["builtin_interfaces/msg/Time"](
            sec=int(t_ns) // 1_000_000_000, nanosec=int(t_ns) % 1_000_000_000), frame_id=frame_id)

    def add_image(self, topic: str, t_ns: int, image: npt.ArrayLike, *, frame_id: str) -> None:
        """One ``sensor_msgs/Image``: (H, W) uint8 -> ``mono8``, (H, W, 3) uint8 RGB -> ``rgb8``."""
        img = np.ascontiguousarray(image)
        if img.dtype != np.uint8 or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)):
            raise IbiscapeError(f"{topic}: images must be uint8 (H, W) or (H, W, 3), got "
                                f"{img.dtype} {img.shape}")
        msgtype = "sensor_msgs/msg/Image"
        conn = self._conn(topic, msgtype)
        h, w = img.shape[:2]
        ch = 1 if img.ndim == 2 else 3
        msg = self.ts.types[msgtype](header=self._header(topic, t_ns, frame_id), height=h, width=w,
                                     encoding="mono8" if ch == 1 else "rgb8", is_bigendian=0,
                                     step=w * ch, data=img.reshape(-1))
        self._w.write(conn, int(t_ns), self.ts.serialize_ros1(msg, msgtype))
        self.n_messages += 1

    def add_imu(self, topic: str, t_ns: int, gyro_rad_s: npt.ArrayLike, accel_m_s2: npt.ArrayLike,
                *, frame_id: str) -> None:
        """One ``sensor_msgs/Imu`` sample (rad/s, m/s^2, in the IMU frame)."""
        T = self.ts.types
        msgtype = "sensor_msgs/msg/Imu"
        conn = self._conn(topic, msgtype)
        g = np.asarray(gyro_rad_s, dtype=np.float64)
        a = np.asarray(accel_m_s2, dtype=np.float64)
        vec = T["geometry_msgs/msg/Vector3"]
        ocov = np.zeros(9)
        ocov[0] = -1.0  # REP 145: orientation not estimated
        msg = T[msgtype](header=self._header(topic, t_ns, frame_id),
                         orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                         orientation_covariance=ocov,
                         angular_velocity=vec(x=float(g[0]), y=float(g[1]), z=float(g[2])),
                         angular_velocity_covariance=np.zeros(9),
                         linear_acceleration=vec(x=float(a[0]), y=float(a[1]), z=float(a[2])),
                         linear_acceleration_covariance=np.zeros(9))
        self._w.write(conn, int(t_ns), self.ts.serialize_ros1(msg, msgtype))
        self.n_messages += 1

    def close(self) -> None:
        """Finish the bag and rename it onto ``path``."""
        try:
            self._w.close()
            publish(self._tmp, self.path)
        finally:
            discard(self._dir)

    def abort(self) -> None:
        """Drop everything written so far (nothing appears at ``path``)."""
        with contextlib.suppress(Exception):  # the bag is discarded anyway
            self._w.close()
        discard(self._dir)


def read_bag_images(path: str | os.PathLike[str], topic: str) -> tuple[npt.NDArray[np.int64],
                                                                       list[np.ndarray]]:
    """Header stamps [ns] and images ((H, W) or (H, W, 3) uint8) of one image topic."""
    from rosbags.highlevel import AnyReader

    stamps: list[int] = []
    images: list[np.ndarray] = []
    with AnyReader([check_input(path, "any", what="ROS bag")]) as r:
        conns = [c for c in r.connections if c.topic == topic]
        if not conns:
            raise IbiscapeError(f"{path}: no topic {topic}; topics: "
                                f"{', '.join(sorted({c.topic for c in r.connections}))}")
        for conn, _, raw in r.messages(connections=conns):
            m: Any = r.deserialize(raw, conn.msgtype)
            ch = {"mono8": 1, "rgb8": 3}.get(m.encoding)
            if ch is None:
                raise IbiscapeError(f"{path}: {topic} has encoding {m.encoding}; expected mono8/rgb8")
            img = np.asarray(m.data, np.uint8).reshape(m.height, m.width, ch)
            images.append(img[..., 0] if ch == 1 else img)
            stamps.append(int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec))
    return np.asarray(stamps, np.int64), images


def read_bag_imu(path: str | os.PathLike[str], topic: str) -> tuple[npt.NDArray[np.int64],
                                                                    np.ndarray, np.ndarray]:
    """Header stamps [ns], gyro (N, 3) rad/s and accel (N, 3) m/s^2 of one IMU topic."""
    from rosbags.highlevel import AnyReader

    rows: list[tuple[int, float, float, float, float, float, float]] = []
    with AnyReader([check_input(path, "any", what="ROS bag")]) as r:
        conns = [c for c in r.connections if c.topic == topic]
        if not conns:
            raise IbiscapeError(f"{path}: no topic {topic}")
        for conn, _, raw in r.messages(connections=conns):
            m: Any = r.deserialize(raw, conn.msgtype)
            g, a = m.angular_velocity, m.linear_acceleration
            rows.append((int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec),
                         g.x, g.y, g.z, a.x, a.y, a.z))
    arr = np.asarray(rows, dtype=np.float64).reshape(-1, 7)
    st = np.asarray([r[0] for r in rows], dtype=np.int64)
    return st, arr[:, 1:4], arr[:, 4:7]
