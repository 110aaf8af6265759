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
    "decode_event_array",
    "dvs_typestore",
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


def iter_bag_event_arrays(path: Path, topic: str, chunk_events: int) -> Iterator[tuple[Events, int]]:
    """Events of ``topic`` in message order, gathered into chunks of about ``chunk_events``;
    yields ``(events, offset of the chunk's first event)``."""
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
                yield _join(parts), offset
                offset += have
                parts, have = [], 0
        if parts:
            yield _join(parts), offset
    except IbiscapeError:
        raise
    except Exception as e:
        raise _damaged(path, e) from None
    finally:
        reader.close()


def _join(parts: list[tuple[Any, ...]]) -> Events:
    return Events(*(np.concatenate([p[k] for p in parts]) for k in range(4)))


def write_event_bag(
    path: str | os.PathLike[str],
    events: Events,
    *,
    topic: str = "/dvs/events",
    sensor_size: tuple[int, int] = (0, 0),
    ros2: bool = False,
    events_per_message: int = 10_000,
) -> None:
    """Write events as ``dvs_msgs/EventArray`` messages (ROS 1 ``.bag`` file, or a ROS 2 bag
    folder), each message stamped with its last event.  The target must not exist (rosbags'
    writers refuse an existing bag)."""
    p = Path(path)
    ts = dvs_typestore(ros2=ros2)
    EventArray = ts.types[EVENT_ARRAY_MSGTYPE]
    Event = ts.types[EVENT_MSGTYPE]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    if ros2:
        from rosbags.rosbag2 import Writer as Writer2

        writer: Any = Writer2(p, version=8)
    else:
        from rosbags.rosbag1 import Writer as Writer1

        writer = Writer1(p)
    t = events.t_ns
    with writer:
        conn = writer.add_connection(topic, EVENT_ARRAY_MSGTYPE, typestore=ts)
        for k, s in enumerate(range(0, len(events), events_per_message)):
            e = min(len(events), s + events_per_message)
            stamp = int(t[e - 1])
            evs = [Event(x=int(events.x[i]), y=int(events.y[i]),
                         ts=Time(sec=int(t[i]) // 1_000_000_000, nanosec=int(t[i]) % 1_000_000_000),
                         polarity=bool(events.p[i])) for i in range(s, e)]
            hdr = (Header(stamp=Time(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000),
                          frame_id="dvs") if ros2 else
                   Header(seq=k, stamp=Time(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000),
                          frame_id="dvs"))
            msg = EventArray(header=hdr, height=int(sensor_size[1]), width=int(sensor_size[0]),
                             events=evs)
            raw = ts.serialize_cdr(msg, EVENT_ARRAY_MSGTYPE) if ros2 else ts.serialize_ros1(
                msg, EVENT_ARRAY_MSGTYPE)
            writer.write(conn, stamp, raw)
