"""AEDAT4 event files (iniVation DV, DVXplorer / DAVIS recordings), read with the ``aedat``
decoder (neuromorphicsystems, Rust; ``benchmarks/bench_event_io.py`` measured it against
iniVation's ``dv-processing``) and written by hand from the format's description.

Reading
    The file's stream table (the XML description of the I/O header) lists its streams; the
    polarity-event stream (``EVTS``) gives the sensor size (``sizeX``, ``sizeY``).  Event stamps
    are microseconds (int64), returned as int64 nanoseconds.  Packets are gathered into chunks
    of about ``chunk_events`` events, so memory stays bounded whatever the file's length.
Writing
    ``#!AER-DAT4.0\\r\\n``, the size-prefixed ``IOHE`` header (compression, no data table,
    the XML stream table with one ``EVTS`` stream), then one packet per block of events:
    ``int32 stream id, int32 byte count``, a size-prefixed ``EVTS`` flatbuffer (``EventPacket``
    with a vector of 16-byte ``Event`` structs: int64 t, int16 x, int16 y, bool on), optionally
    LZ4-frame compressed (what DV writes by default).
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.events import Events

__all__ = ["AEDAT4_MAGIC", "Aedat4Writer", "iter_aedat4_events", "open_aedat4"]

AEDAT4_MAGIC = b"#!AER-DAT4.0\r\n"
_COMPRESSION = {"none": 0, "lz4": 1}
_EVENT = np.dtype({"names": ["t", "x", "y", "on"], "formats": ["<i8", "<i2", "<i2", "u1"],
                   "offsets": [0, 8, 10, 12], "itemsize": 16})
_MAX_US = np.iinfo(np.int64).max // 1000


def _decoder_error(e: BaseException) -> bool:
    """The decoder's failures: plain exceptions, and Rust panics (pyo3's ``PanicException``
    derives from BaseException; other BaseExceptions, e.g. KeyboardInterrupt, propagate)."""
    return isinstance(e, Exception) or type(e).__name__ == "PanicException"


def _decoder(path: Path) -> Any:
    import aedat

    try:
        return aedat.Decoder(str(path))
    except BaseException as e:  # the decoder raises plain exceptions with its parser's message
        if not _decoder_error(e):
            raise
        msg = " ".join(str(e).split())[:160]
        raise FormatError(path, f"not a readable AEDAT4 file ({msg}); is it an .aedat4 recording "
                          "from DV?") from None


def _description_xml(path: Path, buf: bytes) -> str:
    """The XML stream table of the I/O header flatbuffer ``buf``, bounds-checked (the decoder's
    XML parser panics on damaged text, so the header is checked here first)."""

    def u32(at: int) -> int:
        if at < 0 or at + 4 > len(buf):
            raise ValueError("offset outside the header")
        return int.from_bytes(buf[at:at + 4], "little")

    table = u32(0)
    vtable = table - int.from_bytes(buf[table:table + 4], "little", signed=True)
    if vtable < 0 or vtable + 10 > len(buf):
        raise ValueError("vtable outside the header")
    field = int.from_bytes(buf[vtable + 8:vtable + 10], "little")  # field 2: description
    if field == 0:
        raise ValueError("no description")
    at = table + field
    start = at + u32(at)
    n = u32(start)
    if start + 4 + n > len(buf):
        raise ValueError("description outside the header")
    return buf[start + 4:start + 4 + n].decode("utf-8")


def _check_header(path: Path) -> None:
    import xml.etree.ElementTree as ET

    with open(path, "rb") as f:
        head = f.read(len(AEDAT4_MAGIC))
        if head != AEDAT4_MAGIC:
            what = "AEDAT 2/3 (jAER / cAER)" if head.startswith(b"#!AER-DAT") else "not AEDAT"
            raise FormatError(path, f"expected an AEDAT4 file (#!AER-DAT4.0), found {what}; convert "
                              "it with DV or give an AEDAT4 recording")
        raw = f.read(4)
        size = int.from_bytes(raw, "little") if len(raw) == 4 else -1
        buf = f.read(size) if 0 < size <= 1 << 24 else b""
    try:
        if len(buf) != size:
            raise ValueError(f"header of {size} bytes cut off")
        ET.fromstring(_description_xml(path, buf))
    except (ValueError, ET.ParseError) as e:
        raise FormatError(path, f"damaged AEDAT4 header ({e}); the file was cut off or corrupted "
                          "at its start") from None


def open_aedat4(path: Path, stream: str | None = None) -> dict[str, Any]:
    """Check the file's stream table and choose its polarity-event stream; returns the
    :class:`EventSource` fields (``sensor_size`` from the stream's ``sizeX``/``sizeY``)."""
    _check_header(path)
    streams = _decoder(path).id_to_stream()
    found = ", ".join(f"{sid} ({s.get('type')})" for sid, s in sorted(streams.items())) or "none"
    ev = sorted(sid for sid, s in streams.items() if s.get("type") == "events")
    if stream is not None:
        if not str(stream).isdigit() or int(stream) not in streams:
            raise FormatError(path, f"no stream {stream!r}; the file's streams: {found}")
        if int(stream) not in ev:
            raise FormatError(path, f"stream {stream} holds no polarity events; the file's "
                              f"streams: {found}")
        sid = int(stream)
    elif not ev:
        raise FormatError(path, f"no polarity-event stream (EVTS); the file's streams: {found}")
    elif len(ev) > 1:
        raise FormatError(path, f"several event streams ({', '.join(map(str, ev))}); choose one "
                          "with {0}", hint=(Remedy("topic_id"),))
    else:
        sid = ev[0]
    w, h = int(streams[sid].get("width", 0)), int(streams[sid].get("height", 0))
    return {"sensor_size": (w, h) if w > 0 and h > 0 else None,
            "meta": {"stream_id": sid, "streams": found}}


def iter_aedat4_events(path: Path, stream_id: int,
                       chunk_events: int) -> Iterator[tuple[Events, int, bool]]:
    """Events of one stream, gathered into chunks of about ``chunk_events``; yields
    ``(events, offset of the chunk's first event, in time order)`` (the order is checked while
    the stamps are converted; a chunk out of order is left to the caller to report)."""
    dec = _decoder(path)
    state = [np.iinfo(np.int64).min]
    parts: list[np.ndarray] = []
    have = 0
    offset = 0
    it = iter(dec)
    while True:
        try:
            pk = next(it)
        except StopIteration:
            break
        except BaseException as e:
            if not _decoder_error(e):
                raise
            msg = " ".join(str(e).split())[:160]
            raise FormatError(path, f"damaged AEDAT4 packet after event {offset + have} ({msg}); "
                              "the recording was cut off or corrupted") from None
        if pk.get("stream_id") != stream_id or "events" not in pk:
            continue
        parts.append(pk["events"])
        have += len(pk["events"])
        if have >= chunk_events:
            ev, ok = _to_events(path, parts, state, offset)
            yield ev, offset, ok
            offset += have
            parts, have = [], 0
    if parts:
        ev, ok = _to_events(path, parts, state, offset)
        yield ev, offset, ok


def _to_events(path: Path, parts: list[np.ndarray], state: list[int], offset: int) -> tuple[Events, bool]:
    from . import _event_text_kernels as _kernels

    if len(parts) == 1:
        a = parts[0]
    else:  # byte copies: concatenating or assigning structured arrays is ~10x slower
        dt = parts[0].dtype
        raw = np.empty(sum(len(q) for q in parts) * dt.itemsize, np.uint8)
        k = 0
        for q in parts:
            b = np.ascontiguousarray(q).view(np.uint8)
            raw[k:k + b.size] = b
            k += b.size
        a = raw.view(dt)
    t_ns = np.empty(a.shape[0], np.int64)
    code, bad = (int(v) for v in _kernels.us_to_ns(a["t"], 0, _MAX_US, state[0], t_ns))
    if code == 1:
        raise FormatError(path, f"event {offset + bad}: stamp {int(a['t'][bad])} us lies beyond int64 "
                          "nanoseconds (year 2262); the file is damaged")
    if t_ns.size:
        state[0] = int(t_ns[-1])
    return Events(t_ns, a["x"], a["y"], a["on"]), code == 0


def _description(sensor_size: tuple[int, int], source: str, compression: str) -> bytes:
    w, h = sensor_size
    root = "/mainloop/Recorder/outInfo/"
    attrs = (("compression", "string", compression.upper()),
             ("originalModuleName", "string", "ibiscape-eval"),
             ("originalOutputName", "string", "events"),
             ("typeDescription", "string", "Array of events (polarity ON/OFF)."),
             ("typeIdentifier", "string", "EVTS"))
    info = (("sizeX", "int", str(w)), ("sizeY", "int", str(h)), ("source", "string", source),
            ("tsOffset", "long", "0"))

    def attr(k: str, ty: str, v: str) -> str:
        return f'<attr key="{k}" type="{ty}">{v}</attr>'

    xml = (f'<dv version="2.0"><node name="outInfo" path="{root}"><node name="0" path="{root}0/">'
           + "".join(attr(*a) for a in attrs)
           + f'<node name="info" path="{root}0/info/">' + "".join(attr(*a) for a in info)
           + "</node></node></node></dv>")
    return xml.encode("utf-8")


def _ioheader(compression: int, description: bytes) -> bytes:
    """The size-prefixed IOHE flatbuffer: root table {compression int32, file_data_position
    int64 = -1, description string}."""
    body = bytearray()
    body += struct.pack("<I", 24)  # root table offset
    body += b"IOHE"
    body += struct.pack("<5H", 10, 20, 4, 8, 16)  # vtable: size, table size, field offsets
    body += b"\0" * 6  # pad to the 8-aligned table at 24
    body += struct.pack("<iiqI", 24 - 8, compression, -1, 44 - 40)  # soffset to vtable, fields
    body += struct.pack("<I", len(description)) + description + b"\0"
    body += b"\0" * (-len(body) % 8)
    return struct.pack("<I", len(body)) + bytes(body)


def _packet(t_us: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray) -> bytes:
    """A size-prefixed EVTS flatbuffer holding one EventPacket."""
    n = t_us.size
    rec = np.zeros(n, _EVENT)
    rec["t"], rec["x"], rec["y"], rec["on"] = t_us, x, y, p
    head = struct.pack("<I4s3H2xiII", 16, b"EVTS", 6, 8, 4, 8, 4, n)
    body = head + rec.tobytes()
    return struct.pack("<I", len(body)) + body


class Aedat4Writer:
    """Streaming AEDAT4 writer of one polarity-event stream (see the module docstring); events
    must carry whole microseconds.  ``add`` appends; ``close`` finishes the file."""

    def __init__(self, path: str | os.PathLike[str], sensor_size: tuple[int, int], *,
                 compression: str = "lz4", source: str = "ibiscape-eval",
                 events_per_packet: int = 1 << 14) -> None:
        if compression not in _COMPRESSION:
            raise IbiscapeError(f"AEDAT4 compression must be one of {', '.join(_COMPRESSION)}")
        w, h = (int(v) for v in sensor_size)
        if not (0 < w <= 32767 and 0 < h <= 32767):
            raise IbiscapeError(f"AEDAT4 needs a sensor size in 1..32767, got {w}x{h}")
        self.size = (w, h)
        self.compression = compression
        self.per_packet = int(events_per_packet)
        self._f = open(path, "wb")  # noqa: SIM115 (closed in close)
        self._f.write(AEDAT4_MAGIC)
        self._f.write(_ioheader(_COMPRESSION[compression], _description(self.size, source, compression)))

    def add(self, ev: Events) -> None:
        if len(ev) == 0:
            return
        if (ev.t_ns % 1000).any():
            raise IbiscapeError("AEDAT4 stores microseconds; these events have ns digits")
        w, h = self.size
        if int(ev.x.max()) >= w or int(ev.y.max()) >= h:
            raise IbiscapeError(f"events lie outside the {w}x{h} sensor of the AEDAT4 stream")
        t_us = ev.t_ns // 1000
        for s in range(0, len(ev), self.per_packet):
            e = min(len(ev), s + self.per_packet)
            buf = _packet(t_us[s:e], ev.x[s:e], ev.y[s:e], ev.p[s:e])
            if self.compression == "lz4":
                import lz4.frame

                buf = lz4.frame.compress(buf)
            self._f.write(struct.pack("<iI", 0, len(buf)))
            self._f.write(buf)

    def close(self) -> None:
        self._f.close()
