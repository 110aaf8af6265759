"""Event files: round trips for every format, streaming across files, hot_pixels.txt, bad input."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.events import Events
from ibiscape_eval.events import filter_events, synthetic_events
from ibiscape_eval.io.events import (
    iter_event_chunks,
    open_events,
    read_events,
    read_hot_pixels,
    write_events,
    write_filtered_events,
    write_hot_pixels,
)

SUFFIX = {"ibiscape": "", "npz": ".npz", "text": ".txt", "hdf5": ".h5"}


def same(a: Events, b: Events) -> None:
    for k in ("t_ns", "x", "y", "p"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
        assert getattr(a, k).dtype == getattr(b, k).dtype


@st.composite
def event_streams(draw, us: bool = False):
    n = draw(st.integers(1, 40))
    step = draw(st.lists(st.integers(0, 3 * 10**7), min_size=n, max_size=n))
    t = 10**9 + np.cumsum(np.array(step, np.int64))
    if us:
        t = t // 1000 * 1000
    x = np.array(draw(st.lists(st.integers(0, 65535), min_size=n, max_size=n)), np.uint16)
    y = np.array(draw(st.lists(st.integers(0, 65535), min_size=n, max_size=n)), np.uint16)
    p = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), bool)
    return Events(t, x, y, p)


@pytest.mark.parametrize("fmt", ["ibiscape", "npz", "text", "hdf5"])
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_round_trip(tmp_path_factory, fmt, data):
    ev = data.draw(event_streams(us=fmt == "hdf5"))
    path = tmp_path_factory.mktemp(fmt) / f"rec{SUFFIX[fmt]}"
    write_events(path, ev, fmt=fmt)
    assert open_events(path).fmt == fmt
    same(read_events(path), ev)


def test_text_timestamps_are_exact_to_the_nanosecond(tmp_path):
    path = tmp_path / "ev.txt"
    path.write_text("# t x y p\n1468941032.229165000 5 7 1\n1468941032.229165001 6 8 0\n"
                    "1468941032.3 6 8 -1\n")
    ev = read_events(path)
    assert ev.t_ns.tolist() == [1468941032229165000, 1468941032229165001, 1468941032300000000]
    assert ev.p.tolist() == [True, False, False]


def test_text_width_height_header_gives_the_sensor_size(tmp_path):
    path = tmp_path / "ev.txt"
    path.write_text("240 180\n0.001 5 7 1\n")
    src = open_events(path)
    assert src.sensor_size == (240, 180)
    out = tmp_path / "out.txt"
    write_events(out, read_events(path), like=src)
    assert out.read_text().splitlines()[0] == "240 180"


def test_folder_streams_window_by_window_and_filters_in_place_format(tmp_path):
    s = synthetic_events(sensor_size=(32, 24), duration_s=0.3, edge_rate_hz=20_000, seed=2)
    folder = tmp_path / "davisL"
    write_events(folder, s.events, fmt="ibiscape", window_ns=50_000_000)
    chunks = list(iter_event_chunks(folder))
    assert len(chunks) == 6 and all(c.source.endswith(".npz") for c in chunks)
    same(Events.concatenate([c.events for c in chunks]), s.events)
    src = open_events(folder / "events")  # the events/ subfolder is accepted too
    out = tmp_path / "filtered"
    n_in, n_out = write_filtered_events(
        src, out, lambda e: filter_events(e, s.hot_pixels, sensor_size=(32, 24)))
    expected = filter_events(s.events, s.hot_pixels, sensor_size=(32, 24))
    same(read_events(out), expected)
    assert (n_in, n_out) == (len(s.events), len(expected))
    rows_in = (folder / "timestamps.csv").read_text().splitlines()
    assert (out / "timestamps.csv").read_text().splitlines() == rows_in
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folder left


def test_hdf5_dsec_layout_with_t_offset(tmp_path):
    import h5py

    path = tmp_path / "events.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("events/x", data=np.array([1, 2, 3], np.uint16))
        f.create_dataset("events/y", data=np.array([4, 5, 6], np.uint16))
        f.create_dataset("events/t", data=np.array([0, 1500, 2001], np.uint32))
        f.create_dataset("events/p", data=np.array([1, 0, 1], np.uint8))
        f.create_dataset("t_offset", data=np.int64(1_000_000))
        f.create_dataset("ms_to_idx", data=np.array([0, 1, 2], np.uint64))
    ev = read_events(path)
    assert ev.t_ns.tolist() == [10**9, 10**9 + 1_500_000, 10**9 + 2_001_000]
    out = tmp_path / "out.h5"
    write_filtered_events(open_events(path), out, lambda e: e)
    with h5py.File(out, "r") as f:
        assert f["events/t"].dtype == np.uint32 and f["events/t"][:].tolist() == [0, 1500, 2001]
        assert int(f["t_offset"][()]) == 1_000_000
        assert f["ms_to_idx"][:].tolist()[:3] == [0, 1, 2]  # first event at/after 0, 1, 2 ms
        assert f["events/p"].dtype == np.uint8


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.integers(0, 2000), st.integers(0, 2000)), max_size=30))
def test_hot_pixels_txt_round_trip(tmp_path, pixels):
    path = tmp_path / "hot_pixels.txt"
    px = np.array(pixels, np.int64).reshape(-1, 2)
    write_hot_pixels(path, px)
    np.testing.assert_array_equal(read_hot_pixels(path), px)


def test_hot_pixels_txt_dvs_tools_format(tmp_path):
    path = tmp_path / "hot_pixels.txt"
    write_hot_pixels(path, [[3, 4], [10, 0]])
    assert path.read_text() == "3, 4\n10, 0\n"
    path.write_text("3, 4\n\n# comment\n12 7\n")
    assert read_hot_pixels(path).tolist() == [[3, 4], [12, 7]]
    path.write_text("3, 4\n5, a\n")
    with pytest.raises(FormatError, match=r"hot_pixels.txt:2: expected integer"):
        read_hot_pixels(path)


# ---------------------------------------------------------------- bad input at the reader level


def npz(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


def good(n: int = 4) -> dict:
    return {"t": np.arange(n, dtype=np.int64), "x": np.zeros(n, np.uint16),
            "y": np.zeros(n, np.uint16), "p": np.ones(n, bool)}


def test_npz_arrays_of_different_lengths(tmp_path):
    d = good()
    d["x"] = np.zeros(3, np.uint16)
    path = npz(tmp_path / "a.npz", **d)
    with pytest.raises(FormatError, match=r"a.npz: arrays t, x, y, p must be 1-D and of one length"):
        read_events(path)


def test_npz_missing_keys(tmp_path):
    d = good()
    del d["p"]
    with pytest.raises(FormatError, match=r"missing key\(s\) p; found t, x, y"):
        read_events(npz(tmp_path / "a.npz", **d))


def test_npz_with_pickled_objects_is_refused_without_unpickling(tmp_path, monkeypatch):
    import pickle

    d = good()
    d["p"] = np.array([object(), 1, 2, 3], dtype=object)
    path = npz(tmp_path / "a.npz", **d)

    def boom(*a, **k):  # pragma: no cover - the test fails if this runs
        raise AssertionError("pickle.loads called")

    monkeypatch.setattr(pickle, "loads", boom)
    monkeypatch.setattr(pickle, "load", boom)
    with pytest.raises(FormatError, match="pickled Python objects, which are refused"):
        read_events(path)


def test_unsorted_timestamps_name_file_and_index(tmp_path):
    d = good(5)
    d["t"] = np.array([0, 1, 5, 3, 6], np.int64)
    with pytest.raises(FormatError, match=r"a.npz: timestamps go backwards at event 3"):
        read_events(npz(tmp_path / "a.npz", **d))
    txt = tmp_path / "e.txt"
    txt.write_text("0.1 1 1 1\n0.3 1 1 1\n0.2 1 1 0\n")
    with pytest.raises(FormatError, match=r"e.txt:3: timestamps go backwards at event 2"):
        read_events(txt)


def test_unsorted_across_windows_of_a_folder(tmp_path):
    ev = Events(np.arange(10, dtype=np.int64) * 10**7, np.zeros(10, np.uint16),
                np.zeros(10, np.uint16), np.ones(10, bool))
    folder = tmp_path / "dvs"
    write_events(folder, ev, fmt="ibiscape", window_ns=50_000_000)
    files = sorted((folder / "events").iterdir())
    d = dict(np.load(files[1]))
    d["t"] = d["t"] - 10**9
    np.savez(files[1], **d)
    with pytest.raises(FormatError, match=rf"{files[1].name}: timestamps go backwards at event 0"):
        read_events(folder)


def test_empty_recordings(tmp_path):
    with pytest.raises(FormatError, match="holds no events"):
        read_events(npz(tmp_path / "a.npz", **good(0)))
    txt = tmp_path / "e.txt"
    txt.write_text("# only a comment\n")
    with pytest.raises(FormatError, match="holds no events"):
        read_events(txt)
    folder = tmp_path / "dvs"
    (folder / "events").mkdir(parents=True)
    (folder / "timestamps.csv").write_text("#timestamp_start [ns], timestamp_end [ns], filename\n")
    with pytest.raises(FormatError, match="lists no event windows"):
        open_events(folder)


def test_missing_file_listed_in_timestamps_csv(tmp_path):
    folder = tmp_path / "dvs"
    write_events(folder, Events(np.arange(3) * 10**8, np.zeros(3, np.uint16), np.zeros(3, np.uint16),
                                np.ones(3, bool)), fmt="ibiscape", window_ns=10**8)
    victim = sorted((folder / "events").iterdir())[1]
    victim.unlink()
    with pytest.raises(FormatError, match=rf"timestamps.csv:3: lists {victim.name} but .* does not exist"):
        open_events(folder)


def test_text_syntax_errors_name_the_line(tmp_path):
    txt = tmp_path / "e.txt"
    for body, msg in [
        ("0.1 1 1 1\n0.2 1 1\n", "fewer than four columns"),
        ("0.1 1 1 1 9\n", "more than four columns"),
        ("0.1 -1 1 1\n", "expected x"),
        ("0.1 1 1 2\n", "polarity"),
        ("abc 1 1 1\n", "timestamp"),
    ]:
        txt.write_text(body)
        with pytest.raises(FormatError, match=rf"e.txt:\d+: .*{msg}"):
            read_events(txt)


def test_not_a_zip_npz(tmp_path):
    path = tmp_path / "a.npz"
    path.write_bytes(b"garbage")
    with pytest.raises(FormatError, match=r"not a readable \.npz"):
        read_events(path)
    assert not zipfile.is_zipfile(path)


def test_hdf5_missing_datasets_and_length_mismatch(tmp_path):
    import h5py

    path = tmp_path / "e.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("events/x", data=np.zeros(3, np.uint16))
    with pytest.raises(FormatError, match="missing datasets events/t, events/y, events/p"):
        open_events(path)
    with h5py.File(path, "w") as f:
        for k, n in (("x", 3), ("y", 3), ("t", 2), ("p", 3)):
            f.create_dataset(f"events/{k}", data=np.zeros(n, np.uint16))
    with pytest.raises(FormatError, match="of one length"):
        open_events(path)
