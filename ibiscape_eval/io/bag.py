"""Trajectories from ROS 1 bags and ROS 2 bags (sqlite3 / mcap folders) through ``rosbags``.

Supported messages: ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped``,
``TransformStamped``, ``nav_msgs/Odometry`` and ``tf2_msgs/TFMessage``.  For a TF topic the
transform is chosen like evo does, ``topic="/tf:parent.child"`` (evo's syntax
``<tf topic>:<parent frame>.<child frame>``); here only transforms published directly from
``parent`` to ``child`` are read (no chaining through intermediate frames, no interpolation).

Stamps come from the message headers (``header.stamp``), not from the bag's receive times;
messages are sorted by header stamp when they were recorded out of order (with a warning).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError, IbiscapeError, IbiscapeWarning, Remedy
from ibiscape_eval.core.trajectory import Trajectory

from ._poses import finish_trajectory

__all__ = ["BAG_SUFFIXES", "EVENT_MSGTYPE", "IMAGE_MSGTYPES", "IMU_MSGTYPE", "POSE_MSGTYPES", "BagImageTopic",
           "bag_topics", "list_pose_topics", "read_bag",
           "read_imu_bag"]

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
POSE_MSGTYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
    "nav_msgs/msg/Odometry",
)
TF_MSGTYPE = "tf2_msgs/msg/TFMessage"
IMU_MSGTYPE = "sensor_msgs/msg/Imu"


def _damaged(p: Path, e: BaseException) -> FormatError:
    """rosbags raises many unrelated types (AssertionError, ReaderError, UnicodeDecodeError,
    struct.error ...) on damaged bags: one message for all of them."""
    msg = " ".join(str(e).split())[:120]
    return FormatError(p, f"damaged ROS bag ({type(e).__name__}{': ' + msg if msg else ''}); "
                       "the recording was cut off or corrupted: re-record it, or repair it "
                       "(rosbag reindex / ros2 bag reindex)")


def _bag_path(path: str | os.PathLike[str]) -> Path:
    from .paths import check_input

    p = check_input(path, "any")
    if p.is_file():
        check_input(p, "file")
    if p.is_file() and p.suffix in (".db3", ".mcap"):
        p = p.parent  # a ROS 2 storage file: the bag is its folder (with metadata.yaml)
    return p


def _open(path: Path) -> Any:
    from rosbags.highlevel import AnyReader

    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as e:  # rosbags raises several unrelated types for broken bags
        raise FormatError(path, f"cannot open as a ROS bag: {e}") from None
    return reader


@contextlib.contextmanager
def _reading(path: str | os.PathLike[str]) -> Iterator[tuple[Any, Path]]:
    """Open the bag at ``path`` (checked, a ROS 2 storage file resolved to its folder) and yield
    ``(reader, bag path)``; any rosbags failure while reading becomes one "damaged ROS bag"
    FormatError, and the reader is closed whatever happens."""
    p = _bag_path(path)
    reader = _open(p)
    try:
        yield reader, p
    except IbiscapeError:
        raise
    except Exception as e:  # rosbags raises many unrelated types on damaged bags
        raise _damaged(p, e) from None
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def _frame(name: str) -> str:
    return name.lstrip("/")


def _tf_pairs(reader: Any) -> list[str]:
    """``/tf:parent.child`` identifiers of every transform published on TF topics."""
    out: set[str] = set()
    for conn in reader.connections:
        if conn.msgtype != TF_MSGTYPE:
            continue
        for c, _, raw in reader.messages(connections=[conn]):
            msg = reader.deserialize(raw, c.msgtype)
            for tr in msg.transforms:
                out.add(f"{c.topic}:{_frame(tr.header.frame_id)}.{_frame(tr.child_frame_id)}")
    return sorted(out)


def list_pose_topics(path: str | os.PathLike[str]) -> list[str]:
    """Topics of supported pose messages, then ``/tf:parent.child`` ids of TF transforms."""
    with _reading(path) as (reader, _p):
        topics = sorted({c.topic for c in reader.connections
                         if c.msgtype in POSE_MSGTYPES and c.msgcount > 0})
        return topics + _tf_pairs(reader)


def _split_tf_id(topic: str) -> tuple[str, str, str] | None:
    """evo's ``/tf:parent.child`` -> (tf topic, parent, child), or None for a plain topic."""
    tf_topic, sep, rest = topic.partition(":")
    if not sep:
        return None
    parent, dot, child = rest.partition(".")
    if not dot or not parent or not child:
        return None
    return tf_topic, _frame(parent), _frame(child)


def read_bag(
    path: str | os.PathLike[str], *, topic: str | None = None, name: str | None = None
) -> Trajectory:
    """Read one trajectory from a ROS 1 or ROS 2 bag.

    Parameters
    ----------
    path
        A ROS 1 ``.bag`` file, a ROS 2 bag folder (with ``metadata.yaml``) or its ``.db3`` /
        ``.mcap`` file.
    topic
        A topic of a supported pose message, or ``"/tf:parent.child"`` for a TF transform.
        Required when the bag has more than one pose-like topic (the error lists them).
    name
        Label; the topic by default.

    Returns
    -------
    Trajectory
        Stamps from ``header.stamp`` (int64 ns, exact), positions in m, quaternions x, y, z, w.

    Raises
    ------
    FormatError
        Unreadable bag, unknown or ambiguous topic, unsupported message type, no messages,
        non-unit quaternions; the message names the bag and the message index.
    """
    with _reading(path) as (reader, p):
        return _read(reader, p, topic, name)


def _read(reader: Any, p: Path, topic: str | None, name: str | None) -> Trajectory:
    pose_topics = sorted({c.topic for c in reader.connections
                          if c.msgtype in POSE_MSGTYPES and c.msgcount > 0})
    if topic is None:
        if len(pose_topics) == 1:
            topic = pose_topics[0]
        else:
            choices = pose_topics + _tf_pairs(reader)
            if not choices:
                raise FormatError(p, "no pose topics (PoseStamped, PoseWithCovarianceStamped, "
                                     "TransformStamped, Odometry, TFMessage) in the bag")
            raise FormatError(p, "several pose topics; choose one with {0}: "
                                 + ", ".join(choices), hint=(Remedy("topic"),))
    tf = _split_tf_id(topic) if topic not in reader.topics else None
    rows: list[tuple[int, float, float, float, float, float, float, float]] = []
    if tf is not None:
        tf_topic, parent, child = tf
        conns = [c for c in reader.connections if c.topic == tf_topic]
        if not conns or any(c.msgtype != TF_MSGTYPE for c in conns):
            raise FormatError(p, f"no TF topic {tf_topic!r} in the bag; TF ids: "
                                 + (", ".join(_tf_pairs(reader)) or "none"))
        for c, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, c.msgtype)
            for tr in msg.transforms:
                if _frame(tr.header.frame_id) == parent and _frame(tr.child_frame_id) == child:
                    rows.append(_row_from_transform(tr))
        if not rows:
            raise FormatError(p, f"no transform from {parent!r} to {child!r} on {tf_topic}; "
                                 "TF ids: " + (", ".join(_tf_pairs(reader)) or "none"))
    else:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            raise FormatError(p, f"no topic {topic!r} in the bag; pose topics: "
                                 + (", ".join(pose_topics + _tf_pairs(reader)) or "none"))
        msgtype = conns[0].msgtype
        if msgtype not in POSE_MSGTYPES:
            raise FormatError(p, f"topic {topic!r} has unsupported type {msgtype}; supported: "
                                 + ", ".join((*POSE_MSGTYPES, TF_MSGTYPE)))
        for c, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, c.msgtype)
            if msgtype == "geometry_msgs/msg/TransformStamped":
                rows.append(_row_from_transform(msg))
            else:
                pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
                rows.append((_stamp_ns(msg.header.stamp), pose.position.x, pose.position.y,
                             pose.position.z, pose.orientation.x, pose.orientation.y,
                             pose.orientation.z, pose.orientation.w))
        if not rows:
            raise FormatError(p, f"no messages on topic {topic!r}")
    stamps = np.array([r[0] for r in rows], dtype=np.int64)
    vals = np.array([r[1:] for r in rows], dtype=np.float64)
    index = np.arange(1, len(rows) + 1, dtype=np.int64)  # 1-based message numbers for errors
    order = np.argsort(stamps, kind="stable")
    if (np.diff(stamps) < 0).any():
        warnings.warn(f"{p}: {topic}: messages were recorded out of header-stamp order; "
                      "sorted by header stamp", IbiscapeWarning, stacklevel=3)
        stamps, vals, index = stamps[order], vals[order], index[order]
    finite = np.asarray(np.isfinite(vals).all(axis=1), dtype=bool)
    return finish_trajectory(p, stamps, vals[:, :3], vals[:, 3:], finite, index,
                             topic if name is None else name, where=f"{topic} message")


def _stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _row_from_transform(tr: Any) -> tuple[int, float, float, float, float, float, float, float]:
    t, q = tr.transform.translation, tr.transform.rotation
    return (_stamp_ns(tr.header.stamp), t.x, t.y, t.z, q.x, q.y, q.z, q.w)


def read_imu_bag(path: str | os.PathLike[str],
                 rostopic: str | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """``sensor_msgs/Imu`` messages of one topic: ``(stamps_ns (N,), samples (N, 6) gyro then
    accel, topic)``; the topic defaults to the bag's only IMU topic.

    :func:`ibiscape_eval.io.imu.read_imu` builds the record (timing checks) from these arrays.
    """
    with _reading(path) as (reader, p):
        imu_topics = sorted({c.topic for c in reader.connections if c.msgtype == IMU_MSGTYPE})
        if rostopic is None:
            if len(imu_topics) != 1:
                raise FormatError(p, f"{len(imu_topics)} sensor_msgs/Imu topics "
                                  f"({', '.join(imu_topics) or 'none'}); choose one with {{0}}",
                                  hint=(Remedy("rostopic"),))
            rostopic = imu_topics[0]
        conns = [c for c in reader.connections if c.topic == rostopic]
        if not conns:
            raise FormatError(p, f"topic {rostopic!r} not in the bag (IMU topics: "
                              f"{', '.join(imu_topics) or 'none'})")
        if conns[0].msgtype != IMU_MSGTYPE:
            raise FormatError(p, f"topic {rostopic!r} carries {conns[0].msgtype}, not sensor_msgs/Imu")
        n = sum(c.msgcount for c in conns)
        stamps = np.empty(n, dtype=np.int64)
        data = np.empty((n, 6))
        i = 0
        # one deserialisation per message is inherent to the bag format
        for conn, _t, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            st = msg.header.stamp
            stamps[i] = _stamp_ns(st)
            w, a = msg.angular_velocity, msg.linear_acceleration
            data[i] = (w.x, w.y, w.z, a.x, a.y, a.z)
            i += 1
    return stamps[:i], data[:i], rostopic


# ------------------------------------------------------------------------------ images and topics
IMAGE_MSGTYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
EVENT_MSGTYPE = "dvs_msgs/msg/EventArray"


def bag_topics(path: str | os.PathLike[str]) -> list[tuple[str, str, int]]:
    """Every topic of a bag: ``(topic, message type, message count)``, sorted by topic."""
    with _reading(path) as (reader, _p):
        out: dict[str, tuple[str, int]] = {}
        for c in reader.connections:
            ty, n = out.get(c.topic, (c.msgtype, 0))
            out[c.topic] = (ty, n + int(c.msgcount))
    return [(t, ty, n) for t, (ty, n) in sorted(out.items())]


def _decode_image(msg: Any, msgtype: str) -> np.ndarray | None:
    """A ``sensor_msgs/Image`` (mono8/16, rgb8, bgr8, rgba8, bgra8, 8UC1, 16UC1) or
    ``CompressedImage`` as an array (colour in OpenCV's BGR order); None when undecodable."""
    import cv2

    if msgtype.endswith("CompressedImage"):
        return cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    enc = str(msg.encoding).lower()
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    chans = {"mono8": 1, "8uc1": 1, "mono16": 1, "16uc1": 1, "rgb8": 3, "bgr8": 3, "8uc3": 3,
             "rgba8": 4, "bgra8": 4}.get(enc)
    if chans is None or h < 1 or w < 1:
        return None
    depth = np.uint16 if enc in ("mono16", "16uc1") else np.uint8
    raw = np.asarray(msg.data, dtype=np.uint8)
    if raw.size < h * step:
        return None
    rows = raw[: h * step].reshape(h, step)[:, : w * chans * np.dtype(depth).itemsize]
    img = np.ascontiguousarray(rows).view(depth)
    if depth == np.uint16 and bool(msg.is_bigendian) != (np.little_endian is False):
        img = img.byteswap()
    img = img.reshape(h, w) if chans == 1 else img.reshape(h, w, chans)
    if enc == "rgb8":
        img = img[..., ::-1]
    elif enc == "rgba8":
        img = img[..., [2, 1, 0, 3]]
    return np.ascontiguousarray(img)


class BagImageTopic:
    """The frames of one image topic, indexed once (header stamps, bag times), decoded on demand.

    :meth:`load` reads message ``i`` through the bag's time index (``messages(start, stop)``), so
    a calibration touches only the frames it detects on.
    """

    def __init__(self, path: Path, topic: str, msgtype: str, stamps_ns: np.ndarray,
                 bag_ns: np.ndarray, sensor_size: tuple[int, int] | None):
        import threading

        self.path, self.topic, self.msgtype = path, topic, msgtype
        self.stamps_ns, self.bag_ns, self.sensor_size = stamps_ns, bag_ns, sensor_size
        self._lock = threading.Lock()

    @classmethod
    def index(cls, path: str | os.PathLike[str], topic: str) -> BagImageTopic:
        """Read the header stamps of every message of ``topic`` (sorted by header stamp)."""
        with _reading(path) as (reader, p):
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns or conns[0].msgtype not in IMAGE_MSGTYPES:
                raise FormatError(p, f"no image topic {topic!r} in the bag")
            msgtype = conns[0].msgtype
            st, bt, size = [], [], None
            for c, t, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, c.msgtype)
                st.append(_stamp_ns(msg.header.stamp))
                bt.append(int(t))
                if size is None:
                    if msgtype.endswith("CompressedImage"):
                        img = _decode_image(msg, msgtype)
                        size = None if img is None else (int(img.shape[1]), int(img.shape[0]))
                    else:
                        size = (int(msg.width), int(msg.height))
        if not st:
            raise FormatError(p, f"no messages on topic {topic!r}")
        stamps, bag_ns = np.asarray(st, np.int64), np.asarray(bt, np.int64)
        order = np.argsort(stamps, kind="stable")
        return cls(p, topic, msgtype, stamps[order], bag_ns[order], size)

    def load(self, i: int) -> np.ndarray | None:
        """Frame ``i`` (None with a warning when it cannot be decoded)."""
        want = int(self.stamps_ns[i])
        t = int(self.bag_ns[i])
        with self._lock, _reading(self.path) as (reader, p):
            conns = [c for c in reader.connections if c.topic == self.topic]
            for c, _t, raw in reader.messages(connections=conns, start=t, stop=t + 1):
                msg = reader.deserialize(raw, c.msgtype)
                if _stamp_ns(msg.header.stamp) == want:
                    img = _decode_image(msg, c.msgtype)
                    if img is None:
                        break
                    return img
        warnings.warn(f"{p}: {self.topic} message {i}: not a decodable image; skipped",
                      IbiscapeWarning, stacklevel=2)
        return None
