"""``ibiscape-eval hotpix`` and ``ibiscape-eval events frames`` end to end, and every named bad
input: exit status 2, one stderr line naming the file, no output left behind."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _cli_data import assert_one_error_line

from ibiscape_eval.core.events import Events
from ibiscape_eval.events import filter_events, synthetic_events
from ibiscape_eval.io.events import read_events, read_hot_pixels, write_events

SIZE = (48, 32)


@pytest.fixture(scope="module")
def stream():
    return synthetic_events(sensor_size=SIZE, duration_s=0.5, edge_rate_hz=100_000, n_hot=4,
                            hot_rate_hz=3000.0, seed=11)


def as_set(px) -> set[tuple[int, int]]:
    return {(int(a), int(b)) for a, b in px}


@pytest.mark.parametrize("fmt,name", [("ibiscape", "davisL"), ("npz", "ev.npz"), ("text", "ev.txt")])
def test_detect_write_list_and_filtered_stream(run_cli, tmp_path, stream, fmt, name):
    src = tmp_path / name
    write_events(src, stream.events, fmt=fmt)
    hot = tmp_path / "hot_pixels.txt"
    out = tmp_path / f"filtered_{name}"
    plot = tmp_path / "hotpix.png"
    res = run_cli("hotpix", src, "--n-sigma", 5, "--hot-out", hot, "--filtered-out", out,
                  "--plot", plot, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert as_set(read_hot_pixels(hot)) == as_set(stream.hot_pixels)
    assert {(d["x"], d["y"]) for d in doc["hot_pixels"]} == as_set(stream.hot_pixels)
    expected = filter_events(stream.events, stream.hot_pixels, sensor_size=SIZE)
    got = read_events(out)
    for k in ("t_ns", "x", "y", "p"):
        np.testing.assert_array_equal(getattr(got, k), getattr(expected, k))
    assert doc["n_discarded"] == len(stream.events) - len(expected)
    assert doc["fraction_discarded"] == pytest.approx(doc["n_discarded"] / len(stream.events))
    assert plot.stat().st_size > 10_000


def test_apply_existing_list_and_text_report(run_cli, tmp_path, stream):
    src = tmp_path / "ev.npz"
    write_events(src, stream.events)
    hot = tmp_path / "hot.txt"
    hot.write_text("".join(f"{x}, {y}\n" for x, y in stream.hot_pixels))
    out = tmp_path / "clean.npz"
    res = run_cli("hotpix", src, "--apply", hot, "--filtered-out", out, "--sensor-size", "48x32")
    assert res.exit_code == 0, res.output
    assert "hot pixels   4" in res.stdout and "discarded" in res.stdout
    assert len(read_events(out)) == len(filter_events(stream.events, stream.hot_pixels,
                                                      sensor_size=SIZE))


def test_top_n_and_rate_criteria(run_cli, tmp_path, stream):
    src = tmp_path / "ev.npz"
    write_events(src, stream.events)
    res = run_cli("hotpix", src, "--top-n", 4, "--json")
    assert as_set((d["x"], d["y"]) for d in json.loads(res.stdout)["hot_pixels"]) == as_set(
        stream.hot_pixels)
    res = run_cli("hotpix", src, "--rate-min-events", 30, "--rate-window-ms", 20, "--top-n", 0,
                  "--json")
    assert res.exit_code == 0, res.output
    assert as_set((d["x"], d["y"]) for d in json.loads(res.stdout)["hot_pixels"]) == as_set(
        stream.hot_pixels)


def test_events_frames_cli(run_cli, tmp_path, stream):
    src = tmp_path / "davisL"
    write_events(src, stream.events, fmt="ibiscape")
    out = tmp_path / "frames"
    res = run_cli("events", "frames", src, "--out", out, "--rate-hz", 10, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    pngs = sorted(out.glob("*.png"))
    assert doc["n_frames"] == len(pngs) == 5
    import cv2

    img = cv2.imread(str(pngs[0]), cv2.IMREAD_UNCHANGED)
    assert img.shape == (SIZE[1], SIZE[0]) and img.dtype == np.uint8
    assert len((out / "timestamps.csv").read_text().splitlines()) == 6
    res = run_cli("events", "frames", src, "--out", tmp_path / "ts", "--kind", "time-surface",
                  "--window-ms", 100)
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "ts").glob("*.png"))) == 5


# ------------------------------------------------------------------------------ bad input




def run_bad(run_cli, tmp_path: Path, src: Path, *needles: str) -> None:
    hot, out, plot = tmp_path / "hot.txt", tmp_path / "out_events", tmp_path / "p.png"
    before = set(tmp_path.rglob("*"))
    res = run_cli("hotpix", src, "--hot-out", hot, "--filtered-out", out, "--plot", plot)
    assert_one_error_line(res, *needles)
    assert set(tmp_path.rglob("*")) == before  # nothing written, no temp files left


def good(n: int = 5) -> dict:
    return {"t": np.arange(n, dtype=np.int64) * 1000, "x": np.arange(n, dtype=np.uint16),
            "y": np.zeros(n, np.uint16), "p": np.ones(n, bool)}


def test_bad_arrays_of_different_lengths(run_cli, tmp_path):
    d = good()
    d["y"] = d["y"][:3]
    np.savez(tmp_path / "a.npz", **d)
    run_bad(run_cli, tmp_path, tmp_path / "a.npz", "a.npz", "one length")


def test_bad_coordinates_outside_the_sensor(run_cli, tmp_path):
    np.savez(tmp_path / "a.npz", **good())
    hot = tmp_path / "hot.txt"
    before = set(tmp_path.rglob("*"))
    res = run_cli("hotpix", tmp_path / "a.npz", "--sensor-size", "4x4", "--hot-out", hot)
    assert_one_error_line(res, "a.npz", "event 4", "x=4", "outside the 4x4 sensor", "--sensor-size")
    assert set(tmp_path.rglob("*")) == before
    txt = tmp_path / "e.txt"
    txt.write_text("0.1 1 1 1\n0.2 9 1 0\n")
    res = run_cli("hotpix", txt, "--sensor-size", "4x4")
    assert_one_error_line(res, "e.txt:2", "outside")


def test_bad_unsorted_timestamps(run_cli, tmp_path):
    d = good()
    d["t"][3] = 0
    np.savez(tmp_path / "a.npz", **d)
    run_bad(run_cli, tmp_path, tmp_path / "a.npz", "a.npz", "timestamps go backwards at event 3")
    txt = tmp_path / "e.txt"
    txt.write_text("0.3 1 1 1\n0.2 1 1 0\n")
    run_bad(run_cli, tmp_path, txt, "e.txt:2", "backwards")


def test_bad_empty_recording(run_cli, tmp_path):
    np.savez(tmp_path / "a.npz", **good(0))
    run_bad(run_cli, tmp_path, tmp_path / "a.npz", "a.npz", "no events")
    txt = tmp_path / "e.txt"
    txt.write_text("")
    run_bad(run_cli, tmp_path, txt, "e.txt", "no events")


def test_bad_npz_without_expected_keys(run_cli, tmp_path):
    d = good()
    d["pol"] = d.pop("p")
    np.savez(tmp_path / "a.npz", **d)
    run_bad(run_cli, tmp_path, tmp_path / "a.npz", "a.npz", "missing key(s) p")


def test_bad_npz_with_pickled_objects(run_cli, tmp_path):
    d = good()
    d["t"] = np.array([{"evil": 1}] * 5, dtype=object)
    np.savez(tmp_path / "a.npz", **d)
    run_bad(run_cli, tmp_path, tmp_path / "a.npz", "a.npz", "pickled", "refused")


def test_bad_missing_file_listed_in_timestamps_csv(run_cli, tmp_path):
    folder = tmp_path / "davisL"
    ev = Events(np.arange(4) * 10**8, np.zeros(4, np.uint16), np.zeros(4, np.uint16), np.ones(4, bool))
    write_events(folder, ev, fmt="ibiscape", window_ns=10**8)
    victim = sorted((folder / "events").iterdir())[2]
    victim.unlink()
    run_bad(run_cli, tmp_path, folder, "timestamps.csv:4", victim.name, "does not exist")


def test_bad_options(run_cli, tmp_path):
    np.savez(tmp_path / "a.npz", **good())
    assert_one_error_line(run_cli("hotpix", tmp_path / "a.npz", "--sensor-size", "big"), "WIDTHxHEIGHT")
    hot = tmp_path / "hot.txt"
    hot.write_text("1, 1\n99, 0\n")
    assert_one_error_line(run_cli("hotpix", tmp_path / "a.npz", "--apply", hot), "hot.txt", "outside")
    assert_one_error_line(run_cli("hotpix", tmp_path / "missing.npz"), "missing.npz")
    assert_one_error_line(run_cli("events", "frames", tmp_path / "a.npz", "--out", tmp_path / "f",
                              "--sensor-size", "2x2"), "outside")
    assert not (tmp_path / "f").exists()
