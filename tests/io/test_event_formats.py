"""One real recording (a DVXplorer AEDAT4 file) converted into every event format: the same
events, the same sensor size, the same hot pixels and the same frames whichever file holds them.

The HDF5 (DSEC with ``t_offset``/``ms_to_idx``, event_utils, MVSEC) and bag files are written
here with h5py and rosbags' own serializers, independently of our writers; our writers' output
is compared too."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.events import Events
from ibiscape_eval.io.events import open_events, read_events, write_events

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "tonic_dvxplorer" / "sample.aedat4"
SIZE = (320, 240)


@pytest.fixture(scope="module")
def real() -> Events:
    return read_events(REAL)


def _dsec(path: Path, ev: Events, size: tuple[int, int]) -> None:
    """DSEC's layout as its tools write it: uint32 microseconds after ``t_offset``, and
    ``ms_to_idx[k]`` = index of the first event at or after millisecond k."""
    import h5py

    t_us = ev.t_ns // 1000
    off = int(t_us[0])
    rel = (t_us - off).astype(np.uint32)
    with h5py.File(path, "w") as f:
        f.create_dataset("events/t", data=rel, chunks=(4096,))
        f.create_dataset("events/x", data=ev.x, chunks=(4096,))
        f.create_dataset("events/y", data=ev.y, chunks=(4096,))
        f.create_dataset("events/p", data=ev.p.astype(np.uint8), chunks=(4096,))
        f.create_dataset("t_offset", data=np.int64(off))
        ms = np.arange(int(rel[-1]) // 1000 + 2) * 1000
        f.create_dataset("ms_to_idx", data=np.searchsorted(rel, ms).astype(np.uint64))
        f.attrs["width"], f.attrs["height"] = size


def _event_utils(path: Path, ev: Events, size: tuple[int, int]) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        f.create_dataset("events/xs", data=ev.x.astype(np.int16))
        f.create_dataset("events/ys", data=ev.y.astype(np.int16))
        f.create_dataset("events/ts", data=ev.t_ns.astype(np.float64) / 1e9)
        f.create_dataset("events/ps", data=ev.p)
        f.attrs["sensor_resolution"] = (size[1], size[0])


def _flat(path: Path, ev: Events, size: tuple[int, int]) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        for k, a in (("t", ev.t_ns // 1000), ("x", ev.x), ("y", ev.y), ("p", ev.p.astype(np.int8))):
            f.create_dataset(k, data=a)
        f.attrs["sensor_width"], f.attrs["sensor_height"] = size


def _mvsec(path: Path, ev: Events, size: tuple[int, int]) -> None:
    import h5py

    rows = np.column_stack([ev.x, ev.y, ev.t_ns / 1e9, np.where(ev.p, 1.0, -1.0)])
    with h5py.File(path, "w") as f:
        f.create_dataset("davis/left/events", data=rows)


def _rosbags_bag(path: Path, ev: Events, size: tuple[int, int], ros2: bool) -> None:
    """EventArray messages built as rosbags objects and serialized by rosbags itself."""
    from ibiscape_eval.io.event_bag import EVENT_ARRAY_MSGTYPE, dvs_typestore

    ts = dvs_typestore(ros2=ros2)
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Event, EventArray = T["dvs_msgs/msg/Event"], T[EVENT_ARRAY_MSGTYPE]

    def stamp(v: int):  # type: ignore[no-untyped-def]
        return Time(sec=v // 10**9, nanosec=v % 10**9)

    if ros2:
        from rosbags.rosbag2 import Writer

        writer = Writer(path, version=8)
    else:
        from rosbags.rosbag1 import Writer  # type: ignore[assignment]

        writer = Writer(path)
    t = ev.t_ns.tolist()
    with writer:
        conn = writer.add_connection("/dvs/events", EVENT_ARRAY_MSGTYPE, typestore=ts)
        other = writer.add_connection("/dvs/imu", "sensor_msgs/msg/Imu", typestore=ts)
        del other  # a second topic the reader must ignore
        for k, s in enumerate(range(0, len(ev), 7000)):
            e = min(len(ev), s + 7000)
            evs = [Event(x=int(ev.x[i]), y=int(ev.y[i]), ts=stamp(t[i]), polarity=bool(ev.p[i]))
                   for i in range(s, e)]
            hdr = (Header(stamp=stamp(t[e - 1]), frame_id="dvs") if ros2
                   else Header(seq=k, stamp=stamp(t[e - 1]), frame_id="dvs"))
            msg = EventArray(header=hdr, height=size[1], width=size[0], events=evs)
            raw = (ts.serialize_cdr(msg, EVENT_ARRAY_MSGTYPE) if ros2
                   else ts.serialize_ros1(msg, EVENT_ARRAY_MSGTYPE))
            writer.write(conn, t[e - 1], raw)


def _ours(fmt: str):  # type: ignore[no-untyped-def]
    def build(path: Path, ev: Events, size: tuple[int, int]) -> None:
        write_events(path, ev, fmt=fmt, sensor_size=size)

    return build


# name -> (file name, builder, states the sensor size)
BUILDERS = {
    "aedat4_real": ("rec.aedat4", None, True),
    "aedat4_ours": ("ours.aedat4", _ours("aedat4"), True),
    "hdf5_dsec": ("dsec.h5", _dsec, True),
    "hdf5_ours": ("ours.h5", _ours("hdf5"), True),
    "hdf5_event_utils": ("eu.h5", _event_utils, True),
    "hdf5_flat": ("flat.hdf5", _flat, True),
    "hdf5_mvsec": ("mvsec.hdf5", _mvsec, False),
    "bag_ros1": ("rec.bag", lambda p, e, s: _rosbags_bag(p, e, s, False), True),
    "bag_ros2": ("rec_ros2", lambda p, e, s: _rosbags_bag(p, e, s, True), True),
    "bag_ours_ros1": ("ours.bag", _ours("bag"), True),
    "bag_ours_ros2": ("ours_ros2", _ours("bag"), True),
    "npz": ("rec.npz", _ours("npz"), False),
    "text": ("rec.txt", _ours("text"), True),  # E2VID's "width height" header line
    "ibiscape": ("davisL", _ours("ibiscape"), False),
}


@pytest.fixture(scope="module")
def converted(tmp_path_factory, real) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("formats")
    out = {}
    for name, (fname, build, _) in BUILDERS.items():
        p = d / fname
        if build is None:
            p.write_bytes(REAL.read_bytes())
        else:
            build(p, real, SIZE)
        out[name] = p
    return out


@pytest.mark.parametrize("name", list(BUILDERS))
def test_every_format_reads_the_same_events_and_sensor(converted, real, name):
    src = open_events(converted[name])
    assert src.sensor_size == (SIZE if BUILDERS[name][2] else None), src.size_from
    got = read_events(converted[name])
    for k in ("t_ns", "x", "y", "p"):
        np.testing.assert_array_equal(getattr(got, k), getattr(real, k), err_msg=f"{name}: {k}")


def test_small_chunks_cross_packet_and_message_boundaries(converted, real):
    from ibiscape_eval.io.events import iter_event_chunks

    for name in ("aedat4_real", "bag_ros2", "hdf5_dsec", "hdf5_mvsec"):
        parts = list(iter_event_chunks(open_events(converted[name]), chunk_events=5000))
        assert len(parts) > 5
        assert [c.offset for c in parts] == list(np.cumsum([0] + [len(c.events) for c in parts[:-1]]))
        np.testing.assert_array_equal(np.concatenate([c.events.t_ns for c in parts]), real.t_ns)


def test_same_hot_pixels_and_frames_from_every_format(run_cli_events, converted, tmp_path):
    """The command line on each file: identical hot-pixel reports and byte-identical frames."""
    ref_doc = ref_frames = None
    for name, p in converted.items():
        size = [] if BUILDERS[name][2] else ["--sensor-size", "320x240"]
        res = run_cli_events("hotpix", p, "--top-n", 8, "--n-sigma", 4, "--json", *size)
        assert res.exit_code == 0, (name, res.output)
        doc = json.loads(res.stdout)
        for k in ("input", "format", "sensor_size_from"):
            doc.pop(k)
        assert "inferred" not in res.stderr
        out = tmp_path / f"frames_{name}"
        res = run_cli_events("events", "frames", p, "--out", out, "--rate-hz", 50, *size)
        assert res.exit_code == 0, (name, res.output)
        frames = {f.name: f.read_bytes() for f in sorted(out.iterdir())}
        if ref_doc is None:
            ref_doc, ref_frames = doc, frames
            assert doc["n_events"] == 111954 and len(doc["hot_pixels"]) >= 8
            assert len(frames) > 25
        assert doc == ref_doc, name
        assert frames == ref_frames, name


@pytest.fixture
def run_cli_events():
    from click.testing import CliRunner

    from ibiscape_eval.cli.main import cli

    def run(*args):  # type: ignore[no-untyped-def]
        return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)

    return run


def test_bag_numpy_decoder_matches_rosbags_deserializer():
    """Our byte-level decoder against rosbags' deserializer, for both serializations, messages
    of 0, 1, 2 and many events and frame ids of every length modulo 4 (CDR padding)."""
    from ibiscape_eval.io.event_bag import (
        EVENT_ARRAY_MSGTYPE,
        decode_event_array,
        dvs_typestore,
        encode_event_array,
    )

    rng = np.random.default_rng(3)
    for ros2 in (False, True):
        ts = dvs_typestore(ros2=ros2)
        for n in (0, 1, 2, 3, 257):
            t = np.sort(rng.integers(0, 10**12, n)) + 1_600_000_000 * 10**9
            x, y = rng.integers(0, 640, n).astype(np.uint16), rng.integers(0, 480, n).astype(np.uint16)
            p = rng.random(n) < 0.5
            for fid in ("", "a", "ab", "abc"):
                raw = encode_event_array(t, x, y, p, sensor_size=(640, 480), ros2=ros2, frame_id=fid)
                msg = (ts.deserialize_cdr if ros2 else ts.deserialize_ros1)(raw, EVENT_ARRAY_MSGTYPE)
                assert [e.ts.sec * 10**9 + e.ts.nanosec for e in msg.events] == t.tolist()
                assert [e.x for e in msg.events] == x.tolist() and [e.y for e in msg.events] == y.tolist()
                assert [bool(e.polarity) for e in msg.events] == p.tolist()
                assert (msg.width, msg.height, msg.header.frame_id) == (640, 480, fid)
                again = (ts.serialize_cdr if ros2 else ts.serialize_ros1)(msg, EVENT_ARRAY_MSGTYPE)
                assert bytes(again) == raw
                d = decode_event_array(raw, ros2)
                assert d is not None and d[4:] == (640, 480)
                for a, b in zip(d[:4], (t, x, y, p), strict=True):
                    np.testing.assert_array_equal(a, b)
    # a message that is not the standard layout is left to rosbags (None), never misread
    assert decode_event_array(raw[:-3], True) is None
    assert decode_event_array(b"\x00" * 7, False) is None


def test_aedat4_writer_is_read_by_dv_processing(converted, real):
    """Our AEDAT4 writer (LZ4, as DV writes) read by iniVation's own library, when installed."""
    dv = pytest.importorskip("dv_processing")
    rec = dv.io.MonoCameraRecording(str(converted["aedat4_ours"]))
    assert tuple(rec.getEventResolution()) == SIZE
    parts = []
    while (b := rec.getNextEventBatch()) is not None:
        parts.append(b.numpy())
    a = np.concatenate(parts)
    np.testing.assert_array_equal(a["timestamp"] * 1000, real.t_ns)
    np.testing.assert_array_equal(a["x"], real.x)
    np.testing.assert_array_equal(a["y"], real.y)
    np.testing.assert_array_equal(a["polarity"] != 0, real.p)


def test_aedat4_sorted_check_names_the_event(tmp_path, real):
    from ibiscape_eval.core.errors import FormatError

    t = real.t_ns[:2000].copy()
    t[1500] = t[10]
    bad = Events(t, real.x[:2000], real.y[:2000], real.p[:2000])
    p = tmp_path / "bad.aedat4"
    write_events(p, bad, sensor_size=SIZE)
    with pytest.raises(FormatError, match="timestamps go backwards at event 1500"):
        read_events(p)


@pytest.mark.parametrize("at", [10, 4999, 5000, 5001])
def test_hdf5_order_and_range_checks_in_the_fast_path(tmp_path, real, at):
    """The one-pass HDF5 reader (stamps converted and checked together) names the first event
    out of order, inside a chunk or across a chunk boundary, and refuses stamps beyond int64 ns."""
    import h5py

    from ibiscape_eval.core.errors import FormatError
    from ibiscape_eval.io.events import iter_event_chunks

    ev = Events(real.t_ns[:20000], real.x[:20000], real.y[:20000], real.p[:20000])
    p = tmp_path / "d.h5"
    _dsec(p, ev, SIZE)
    with h5py.File(p, "r+") as f:
        t = f["events/t"][:]
        t[at] = t[at - 1] - 1 if t[at - 1] > 0 else 0
        if at == 10:
            t[at] = 0
        f["events/t"][:] = t
    with pytest.raises(FormatError, match=f"timestamps go backwards at event {at}:"):
        for _ in iter_event_chunks(open_events(p), chunk_events=5000, reuse_buffers=True):
            pass
    q = tmp_path / "far.h5"
    with h5py.File(q, "w") as f:
        for k, a in (("t", np.array([1, 2, 2**62], np.int64)), ("x", np.zeros(3, np.uint16)),
                     ("y", np.zeros(3, np.uint16)), ("p", np.ones(3, np.uint8))):
            f.create_dataset(f"events/{k}", data=a)
    with pytest.raises(FormatError, match=r"events/t\[2\] = 4611686018427387904 us lies beyond int64"):
        read_events(q)
