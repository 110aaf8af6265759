"""``hotpix`` / ``events frames`` on AEDAT4, HDF5, bags and sequence folders: the sensor size
comes from what the input states, and every named bad input is one line, exit 2, nothing
written."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from _cli_data import assert_one_error_line

from ibiscape_eval.core.events import Events
from ibiscape_eval.events import synthetic_events
from ibiscape_eval.io.events import write_events

SIZE = (48, 32)


@pytest.fixture(scope="module")
def stream():
    return synthetic_events(sensor_size=SIZE, duration_s=0.3, edge_rate_hz=50_000, n_hot=3,
                            hot_rate_hz=3000.0, seed=5)


def _us(ev: Events) -> Events:
    return Events(ev.t_ns // 1000 * 1000, ev.x, ev.y, ev.p)


def _sequence(folder: Path, ev: Events, resolution: list[int]) -> Path:
    """A sequence folder whose sequence.yaml states the DVS camera's resolution; the events use
    only the top-left corner, so the largest coordinates would give a smaller sensor."""
    from ibiscape_eval.io.sequence import write_sequence_yaml

    seq = folder / "seq"
    write_events(seq / "davisL", ev, fmt="ibiscape")
    eye = np.eye(4).tolist()
    doc = {"cameras": {"davisL": {"kind": "dvs", "resolution": resolution, "T_body_cam": eye},
                       "rgbL": {"kind": "rgb", "resolution": [64, 64], "T_body_cam": eye}},
           "imus": {}, "gnss": {}, "conventions": {}, "generator": {}}
    write_sequence_yaml(seq / "sequence.yaml", doc)
    return seq


def test_sequence_yaml_gives_the_sensor_size(run_cli, tmp_path, stream):
    seq = _sequence(tmp_path, stream.events, [64, 40])
    for target in (seq / "davisL", seq):  # the camera folder, or the sequence with one DVS camera
        res = run_cli("hotpix", target, "--json", "--n-sigma", 5)
        assert res.exit_code == 0, res.output
        doc = json.loads(res.stdout)
        assert doc["sensor_size"] == [64, 40] and doc["sensor_size_from"] == "sequence.yaml"
        assert "inferred" not in res.stderr
        out = tmp_path / f"frames_{target.name}"
        res = run_cli("events", "frames", target, "--out", out, "--json")
        assert res.exit_code == 0, res.output
        assert json.loads(res.stdout)["sensor_size"] == [64, 40]
        assert "inferred" not in res.stderr
    # without sequence.yaml the size is inferred, and said so
    bare = tmp_path / "bare"
    write_events(bare, stream.events, fmt="ibiscape")
    res = run_cli("hotpix", bare, "--json")
    assert res.exit_code == 0 and "inferred" in res.stderr
    assert json.loads(res.stdout)["sensor_size"] == list(SIZE)


def test_sequence_yaml_smaller_than_the_events_is_refused(run_cli, tmp_path, stream):
    seq = _sequence(tmp_path, stream.events, [20, 20])
    hot = tmp_path / "hot.txt"
    res = run_cli("hotpix", seq / "davisL", "--hot-out", hot)
    assert_one_error_line(res, "outside the 20x20 sensor")
    assert not hot.exists()


def test_sequence_with_two_dvs_cameras_asks_for_one(run_cli, tmp_path, stream):
    from ibiscape_eval.io.sequence import read_sequence_yaml, write_sequence_yaml

    seq = _sequence(tmp_path, stream.events, [64, 40])
    write_events(seq / "davisR", stream.events, fmt="ibiscape")
    doc = read_sequence_yaml(seq / "sequence.yaml")
    doc["cameras"]["davisR"] = dict(doc["cameras"]["davisL"])
    write_sequence_yaml(seq / "sequence.yaml", doc)
    res = run_cli("hotpix", seq)
    assert_one_error_line(res, "sequence.yaml", "several DVS cameras (davisL, davisR)")
    res = run_cli("hotpix", seq, "--topic", "davisR", "--json")
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize("name", ["ev.aedat4", "ev.h5", "ev.bag", "ev_ros2"])
def test_filtered_output_in_the_input_format(run_cli, tmp_path, stream, name):
    from ibiscape_eval.events import filter_events
    from ibiscape_eval.io.events import open_events, read_events

    ev = _us(stream.events)
    src = tmp_path / name
    write_events(src, ev, fmt="bag" if name == "ev_ros2" else None, sensor_size=SIZE)
    out = tmp_path / f"clean_{name}"
    res = run_cli("hotpix", src, "--n-sigma", 5, "--filtered-out", out, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert {(d["x"], d["y"]) for d in doc["hot_pixels"]} == {tuple(map(int, p)) for p in stream.hot_pixels}
    assert doc["sensor_size_from"] != "the largest event coordinates"
    got = read_events(out)
    want = filter_events(ev, stream.hot_pixels, sensor_size=SIZE)
    np.testing.assert_array_equal(got.t_ns, want.t_ns)
    np.testing.assert_array_equal(got.x, want.x)
    assert open_events(out).fmt == open_events(src).fmt
    assert open_events(out).sensor_size == SIZE
    assert not [f for f in tmp_path.rglob(".*")], "staging files left behind"
    if name == "ev_ros2":  # the storage file is named after the bag folder
        assert sorted(f.name for f in out.iterdir()) == [f"{out.name}.db3", "metadata.yaml"]


# ------------------------------------------------------------------------------------------
# bad inputs
# ------------------------------------------------------------------------------------------


def _aedat4_without_events(path: Path) -> None:
    """An AEDAT4 file by hand (flatbuffer I/O header) whose only streams are IMU and triggers."""
    xml = (b'<dv version="2.0"><node name="outInfo" path="/mainloop/Recorder/outInfo/">'
           b'<node name="2" path="/mainloop/Recorder/outInfo/2/">'
           b'<attr key="compression" type="string">NONE</attr>'
           b'<attr key="typeIdentifier" type="string">IMUS</attr></node>'
           b'<node name="3" path="/mainloop/Recorder/outInfo/3/">'
           b'<attr key="compression" type="string">NONE</attr>'
           b'<attr key="typeIdentifier" type="string">TRIG</attr></node></node></dv>')
    body = (struct.pack("<I4s5H6xiiqI", 24, b"IOHE", 10, 20, 4, 8, 16, 16, 0, -1, 4)
            + struct.pack("<I", len(xml)) + xml + b"\0")
    body += b"\0" * (-len(body) % 8)
    path.write_bytes(b"#!AER-DAT4.0\r\n" + struct.pack("<I", len(body)) + body)


def test_aedat4_without_event_stream_names_its_streams(run_cli, tmp_path):
    p = tmp_path / "imu_only.aedat4"
    _aedat4_without_events(p)
    hot = tmp_path / "hot.txt"
    res = run_cli("hotpix", p, "--hot-out", hot)
    assert_one_error_line(res, str(p), "no polarity-event stream", "2 (imus)", "3 (triggers)")
    assert not hot.exists()
    out = tmp_path / "frames"
    res = run_cli("events", "frames", p, "--out", out)
    assert_one_error_line(res, str(p), "2 (imus)")
    assert not out.exists()


def test_aedat4_damaged_or_not_aedat4(run_cli, tmp_path):
    p = tmp_path / "old.aedat4"
    p.write_bytes(b"#!AER-DAT2.0\r\n" + bytes(100))
    assert_one_error_line(run_cli("hotpix", p), str(p), "AEDAT 2/3")
    real = Path(__file__).resolve().parents[1] / "data" / "real" / "tonic_dvxplorer" / "sample.aedat4"
    cut = tmp_path / "cut.aedat4"
    data = real.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    hot = tmp_path / "hot.txt"
    res = run_cli("hotpix", cut, "--hot-out", hot)
    assert_one_error_line(res, str(cut), "damaged AEDAT4 packet")
    assert not hot.exists()


def test_hdf5_unknown_layout_names_its_datasets(run_cli, tmp_path):
    import h5py

    p = tmp_path / "odd.h5"
    with h5py.File(p, "w") as f:
        f.create_dataset("cd/events", data=np.zeros(5, [("x", "u2"), ("t", "i8")]))
        f.create_dataset("meta/rate", data=np.zeros(3))
    out = tmp_path / "frames"
    res = run_cli("events", "frames", p, "--out", out)
    assert_one_error_line(res, str(p), "unknown HDF5 event layout", "cd/events (5,)", "meta/rate (3,)")
    assert not out.exists()


def test_bag_without_the_topic_lists_its_topics(run_cli, tmp_path, stream):
    ev = _us(stream.events)
    for name in ("ev.bag", "ev_ros2"):
        p = tmp_path / name
        write_events(p, ev, fmt="bag", sensor_size=SIZE)
        hot = tmp_path / f"hot_{name}.txt"
        res = run_cli("hotpix", p, "--topic", "/davis/left/events", "--hot-out", hot)
        assert_one_error_line(res, "no topic '/davis/left/events'", "/dvs/events (dvs_msgs/msg/EventArray)")
        assert not hot.exists()


def test_bag_without_event_topic_and_with_several(run_cli, tmp_path, stream):
    from rosbags.rosbag1 import Writer

    from ibiscape_eval.io.event_bag import EVENT_ARRAY_MSGTYPE, dvs_typestore, encode_event_array

    ts = dvs_typestore()
    p = tmp_path / "two.bag"
    ev = _us(stream.events)
    with Writer(p) as w:
        for topic in ("/cam0/events", "/cam1/events"):
            c = w.add_connection(topic, EVENT_ARRAY_MSGTYPE, typestore=ts)
            w.write(c, int(ev.t_ns[-1]), encode_event_array(ev.t_ns, ev.x, ev.y, ev.p,
                                                            sensor_size=SIZE, ros2=False))
    res = run_cli("hotpix", p)
    assert_one_error_line(res, str(p), "several event topics (/cam0/events, /cam1/events)", "--topic")
    res = run_cli("hotpix", p, "--topic", "/cam1/events", "--json")
    assert res.exit_code == 0 and json.loads(res.stdout)["sensor_size_from"] == "EventArray width/height"
    q = tmp_path / "imu.bag"
    with Writer(q) as w:
        w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
    assert_one_error_line(run_cli("hotpix", q), str(q), "no dvs_msgs/msg/EventArray topic",
                          "/imu (sensor_msgs/msg/Imu)")


def test_aedat4_damaged_header_is_checked_before_the_decoder(tmp_path, capfd):
    """The decoder's XML parser panics on some damaged stream tables (a Rust panic message on
    stderr); the header is checked first, so 60 damaged headers give FormatErrors and stderr
    stays empty."""
    from ibiscape_eval.core.errors import FormatError
    from ibiscape_eval.io.events import read_events

    real = Path(__file__).resolve().parents[1] / "data" / "real" / "tonic_dvxplorer" / "sample.aedat4"
    data = real.read_bytes()
    end = data.index(b"</dv>") + 5
    rng = np.random.default_rng(21)
    refused = 0
    for k in range(60):
        b = bytearray(data[:200_000])
        i = int(rng.integers(14, end))
        if k % 2:
            b[i] ^= int(rng.integers(1, 256))
        else:
            del b[i: i + int(rng.integers(1, 40))]
        p = tmp_path / f"m{k}.aedat4"
        p.write_bytes(bytes(b))
        try:
            read_events(p)
        except FormatError as e:
            refused += 1
            assert str(p) in str(e)
    assert refused >= 40
    assert "panicked" not in capfd.readouterr().err
    bad = tmp_path / "xml.aedat4"
    bad.write_bytes(data.replace(b"</dv>", b"</dx>"))
    with pytest.raises(FormatError, match="damaged AEDAT4 header"):
        read_events(bad)
