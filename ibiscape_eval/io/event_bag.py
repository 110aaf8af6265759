"""DVS events in ROS 1 and ROS 2 bags: ``dvs_msgs/EventArray`` (rpg_dvs_ros), through ``rosbags``
(no ROS install).

The message types are registered from their ``.msg`` definitions (:data:`DVS_MSGS_ROS1`,
:data:`DVS_MSGS_ROS2`).  Reading does not build one Python object per event: each message's
serialized bytes are decoded with numpy (ROS 1: packed 13-byte events; ROS 2 CDR: the first
event packed, the others on a 16-byte stride because of CDR alignment).  The decoded length is
checked against the message size; a message that does not match falls back to ``rosbags``'
deserializer, so an unusual definition is read slowly but never misread.

``EventArray.width`` / ``height`` give the sensor size; event stamps are ``Event.ts``
(``header.stamp`` is the message's, not the events').
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.events import Events

__all__ = [
    "DVS_MSGS_ROS1",
    "DVS_MSGS_ROS2",
    "EVENT_ARRAY_MSGTYPE",
    "BagEventWriter",
    "decode_event_array",
    "dvs_typestore",
    "encode_event_array",
    "iter_bag_event_arrays",
    "list_event_topics",
    "open_bag_events",
    "write_event_bag",
]

EVENT_ARRAY_MSGTYPE = "dvs_msgs/msg/EventArray"
EVENT_MSGTYPE = "dvs_msgs/msg/Event"

# rpg_dvs_ros' definitions (ROS 1) and their ROS 2 port (builtin_interfaces/Time stamps)
DVS_MSGS_ROS1 = {
    EVENT_MSGTYPE: "uint16 x\nuint16 y\ntime ts\nbool polarity\n",
    EVENT_ARRAY_MSGTYPE: "Header header\nuint32 height\nuint32 width\ndvs_msgs/Event[] events\n",
}
DVS_MSGS_ROS2 = {
    EVENT_MSGTYPE: "uint16 x\nuint16 y\nbuiltin_interfaces/Time ts\nbool polarity\n",
    EVENT_ARRAY_MSGTYPE: "std_msgs/Header header\nuint32 height\nuint32 width\n"
                         "dvs_msgs/Event[] events\n",
}

_ROS1_EVENT = np.dtype({"names": ["x", "y", "s", "ns", "p"],
                        "formats": ["<u2", "<u2", "<u4", "<u4", "u1"],
                        "offsets": [0, 2, 4, 8, 12], "itemsize": 13})
_CDR_EVENT0 = _ROS1_EVENT  # the first event starts 4-aligned: no padding inside it
_CDR_EVENT = np.dtype({"names": ["x", "y", "s", "ns", "p"],
                       "formats": ["<u2", "<u2", "<i4", "<u4", "u1"],
                       "offsets": [0, 2, 6, 10, 14], "itemsize": 15})  # on a 16-byte stride


def dvs_typestore(ros2: bool = False) -> Any:
    """A rosbags typestore (Noetic or Humble) with the ``dvs_msgs`` types registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    types: dict[str, Any] = {}
    for name, text in (DVS_MSGS_ROS2 if ros2 else DVS_MSGS_ROS1).items():
        types.update(get_types_from_msg(text, name))
    ts.register(types)
    return ts


def _columns(rec: np.ndarray) -> tuple[np.ndarray, ...]:
    t = rec["s"].astype(np.int64) * 1_000_000_000 + rec["ns"].astype(np.int64)
    return t, rec["x"], rec["y"], rec["p"] != 0


def decode_event_array(raw: bytes | memoryview, ros2: bool) -> tuple[
        npt.NDArray[np.int64], np.ndarray, np.ndarray, np.ndarray, int, int] | None:
    """Decode one serialized ``dvs_msgs/EventArray`` into ``(t_ns, x, y, p, width, height)``,
    or None when the bytes do not have the standard layout (the caller then deserializes)."""
    buf = np.frombuffer(raw, np.uint8)
    size = buf.size
    try:
        if not ros2:
            flen = int(buf[12:16].view("<u4")[0])
            pos = 16 + flen
            h, w, n = (int(v) for v in buf[pos: pos + 12].view("<u4"))
            pos += 12
            if pos + 13 * n != size:
                return None
            rec = np.frombuffer(buf, _ROS1_EVENT, count=n, offset=pos)
            return (*_columns(rec), w, h)  # type: ignore[return-value]
        if size < 4 or buf[1] != 1:  # CDR little-endian only
            return None
        data = buf[4:]
        flen = int(data[8:12].view("<u4")[0])
        pos = 12 + flen
        pos += -pos % 4
        h, w, n = (int(v) for v in data[pos: pos + 12].view("<u4"))
        pos += 12
        end = pos if n == 0 else pos + 13 + 16 * (n - 1)
        if not (end <= data.size <= end + 3):
            return None
        first = np.frombuffer(data, _CDR_EVENT0, count=min(n, 1), offset=pos)
        rest = np.ndarray((max(n - 1, 0),), _CDR_EVENT, buffer=data, offset=pos + 14 if n > 1 else 0,
                          strides=(16,))
        cols = [np.concatenate([a, b]) for a, b in zip(_columns(first), _columns(rest), strict=True)]
        return (*cols, w, h)  # type: ignore[return-value]
    except (ValueError, IndexError):
        return None


def _slow(reader: Any, raw: bytes, msgtype: str) -> tuple[Any, ...]:
    msg = reader.deserialize(raw, msgtype)
    ev = msg.events
    t = np.array([int(e.ts.sec) * 1_000_000_000 + int(e.ts.nanosec) for e in ev], np.int64)
    x = np.array([e.x for e in ev], np.uint16)
    y = np.array([e.y for e in ev], np.uint16)
    p = np.array([bool(e.polarity) for e in ev], np.bool_)
    return t, x, y, p, int(msg.width), int(msg.height)


def _open_reader(p: Path) -> Any:
    from rosbags.highlevel import AnyReader

    from .bag import _damaged

    try:
        reader = AnyReader([p], default_typestore=dvs_typestore(ros2=False))
        reader.open()
    except IbiscapeError:
        raise
    except Exception as e:  # rosbags raises several unrelated types for broken bags
        raise _damaged(p, e) from None
    if reader.is2:
        reader.close()
        reader = AnyReader([p], default_typestore=dvs_typestore(ros2=True))
        reader.open()
    return reader


def list_event_topics(reader: Any) -> list[str]:
    """Topics of ``dvs_msgs/EventArray`` messages in an opened reader."""
    return sorted({c.topic for c in reader.connections if c.msgtype == EVENT_ARRAY_MSGTYPE})


def _pick_topic(p: Path, reader: Any, topic: str | None) -> str:
    ev_topics = list_event_topics(reader)
    all_topics = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
    if topic is not None:
        if topic not in {c.topic for c in reader.connections}:
            raise FormatError(p, f"no topic {topic!r}; the bag has: {', '.join(all_topics) or 'no topics'}")
        if topic not in ev_topics:
            have = next(c.msgtype for c in reader.connections if c.topic == topic)
            raise FormatError(p, f"topic {topic!r} holds {have}, not {EVENT_ARRAY_MSGTYPE}; event "
                              f"topics: {', '.join(ev_topics) or 'none'}")
        return topic
    if not ev_topics:
        raise FormatError(p, f"no {EVENT_ARRAY_MSGTYPE} topic; the bag has: "
                          f"{', '.join(all_topics) or 'no topics'}")
    if len(ev_topics) > 1:
        raise FormatError(p, f"several event topics ({', '.join(ev_topics)}); choose one with "
                          "--topic")
    return ev_topics[0]


def open_bag_events(path: Path, topic: str | None) -> dict[str, Any]:
    """Check the bag and choose the event topic; returns the :class:`EventSource` fields
    (``sensor_size`` from the first message's width/height when non-zero)."""
    from .bag import _damaged

    reader = _open_reader(path)
    try:
        chosen = _pick_topic(path, reader, topic)
        conns = [c for c in reader.connections if c.topic == chosen]
        n_msgs = sum(int(c.msgcount) for c in conns)
        size = None
        for c, _, raw in reader.messages(connections=conns):
            got = decode_event_array(raw, reader.is2) or _slow(reader, raw, c.msgtype)
            if got[4] > 0 and got[5] > 0:
                size = (int(got[4]), int(got[5]))
            break
    except IbiscapeError:
        raise
    except Exception as e:
        raise _damaged(path, e) from None
    finally:
        reader.close()
    return {"sensor_size": size, "meta": {"topic": chosen, "n_messages": n_msgs}}


def iter_bag_event_arrays(path: Path, topic: str,
                          chunk_events: int) -> Iterator[tuple[Events, int, bool]]:
    """Events of ``topic`` in message order, gathered into chunks of about ``chunk_events``;
    yields ``(events, offset of the chunk's first event, False)`` (the caller checks the
    order)."""
    from .bag import _damaged

    reader = _open_reader(path)
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        parts: list[tuple[Any, ...]] = []
        have = 0
        offset = 0
        for c, _, raw in reader.messages(connections=conns):
            got = decode_event_array(raw, reader.is2) or _slow(reader, raw, c.msgtype)
            parts.append(got[:4])
            have += got[0].size
            if have >= chunk_events:
                yield _join(parts), offset, False
                offset += have
                parts, have = [], 0
        if parts:
            yield _join(parts), offset, False
    except IbiscapeError:
        raise
    except Exception as e:
        raise _damaged(path, e) from None
    finally:
        reader.close()


def _join(parts: list[tuple[Any, ...]]) -> Events:
    return Events(*(np.concatenate([p[k] for p in parts]) for k in range(4)))


def encode_event_array(t_ns: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray, *,
                       sensor_size: tuple[int, int], ros2: bool, seq: int = 0,
                       frame_id: str = "dvs") -> bytes:
    """Serialize one ``dvs_msgs/EventArray`` (ROS 1 or ROS 2 CDR) with numpy, the inverse of
    :func:`decode_event_array`; the header is stamped with the last event."""
    n = int(t_ns.size)
    stamp = int(t_ns[-1]) if n else 0
    fid = frame_id.encode()
    w, h = (int(v) for v in sensor_size)
    sec, nsec = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
    if ros2:
        head = bytearray(b"\x00\x01\x00\x00")
        body = bytearray(struct.pack("<iII", stamp // 1_000_000_000, stamp % 1_000_000_000,
                                     len(fid) + 1) + fid + b"\0")
        body += b"\0" * (-len(body) % 4)
        body += struct.pack("<III", h, w, n)
        size = 0 if n == 0 else 13 + 16 * (n - 1)
        out = np.zeros(size, np.uint8)
        if n:
            first = np.ndarray((1,), _CDR_EVENT0, buffer=out, offset=0)
            rest = np.ndarray((n - 1,), _CDR_EVENT, buffer=out, offset=14 if n > 1 else 0,
                              strides=(16,))
            for view, sl in ((first, slice(0, 1)), (rest, slice(1, n))):
                view["x"], view["y"] = x[sl], y[sl]
                view["s"], view["ns"], view["p"] = sec[sl], nsec[sl], p[sl]
        return bytes(head + body) + out.tobytes()
    body = bytearray(struct.pack("<IIII", seq, stamp // 1_000_000_000, stamp % 1_000_000_000,
                                 len(fid)) + fid)
    body += struct.pack("<III", h, w, n)
    rec = np.zeros(n, _ROS1_EVENT)
    rec["x"], rec["y"], rec["s"], rec["ns"], rec["p"] = x, y, sec, nsec, p
    return bytes(body) + rec.tobytes()


class BagEventWriter:
    """Streaming writer of ``dvs_msgs/EventArray`` messages on one topic (ROS 1 ``.bag`` file or
    ROS 2 bag folder); each message holds up to ``events_per_message`` events and is stamped
    with its last event.  The target must not exist (rosbags' writers refuse it)."""

    def __init__(self, path: str | os.PathLike[str], *, topic: str = "/dvs/events",
                 sensor_size: tuple[int, int] = (0, 0), ros2: bool = False,
                 events_per_message: int = 10_000) -> None:
        self.ts = dvs_typestore(ros2=ros2)
        self.ros2, self.size, self.per_msg = ros2, sensor_size, int(events_per_message)
        if ros2:
            from rosbags.rosbag2 import Writer as Writer2

            self.writer: Any = Writer2(Path(path), version=8)
        else:
            from rosbags.rosbag1 import Writer as Writer1

            self.writer = Writer1(Path(path))
        self.writer.open()
        self.conn = self.writer.add_connection(topic, EVENT_ARRAY_MSGTYPE, typestore=self.ts)
        self.seq = 0

    def add(self, ev: Events) -> None:
        t = ev.t_ns
        if len(ev) and int(t[0]) < 0:
            raise IbiscapeError("ROS stamps cannot be negative; shift the events to t >= 0")
        for s in range(0, len(ev), self.per_msg):
            e = min(len(ev), s + self.per_msg)
            raw = encode_event_array(t[s:e], ev.x[s:e], ev.y[s:e], ev.p[s:e],
                                     sensor_size=self.size, ros2=self.ros2, seq=self.seq)
            self.writer.write(self.conn, int(t[e - 1]), raw)
            self.seq += 1

    def close(self) -> None:
        self.writer.close()


def write_event_bag(
    path: str | os.PathLike[str],
    events: Events,
    *,
    topic: str = "/dvs/events",
    sensor_size: tuple[int, int] = (0, 0),
    ros2: bool = False,
    events_per_message: int = 10_000,
) -> None:
    """Write events as ``dvs_msgs/EventArray`` messages (see :class:`BagEventWriter`)."""
    w = BagEventWriter(path, topic=topic, sensor_size=sensor_size, ros2=ros2,
                       events_per_message=events_per_message)
    try:
        w.add(events)
    finally:
        w.close()
