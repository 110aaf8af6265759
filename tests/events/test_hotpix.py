"""Hot-pixel detection and filtering on synthetic streams with planted hot pixels."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval import detect_hot_pixels, hot_pixel_mask
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events
from ibiscape_eval.events import (
    PixelCounter,
    count_events,
    filter_arrays,
    filter_events,
    hot_pixels_from_counts,
    rate_hot_pixels,
    synthetic_events,
)

SIZE = (64, 48)


@pytest.fixture(scope="module")
def stream():
    return synthetic_events(sensor_size=SIZE, n_hot=6, hot_rate_hz=2500.0, seed=3)


def as_set(px: np.ndarray) -> set[tuple[int, int]]:
    return {(int(a), int(b)) for a, b in px}


def test_n_sigma_finds_exactly_the_planted_pixels(stream):
    res = detect_hot_pixels(stream.events.x, stream.events.y, sensor_size=SIZE, n_sigma=5)
    assert as_set(res.pixels) == as_set(stream.hot_pixels)
    assert res.pixels.dtype == np.int64 and res.pixels.shape == (6, 2)
    # counts are the true per-pixel counts, sorted decreasing
    x, y = stream.events.x, stream.events.y
    for (px, py), c in zip(res.pixels, res.counts, strict=True):
        assert c == np.count_nonzero((x == px) & (y == py))
    assert np.all(np.diff(res.counts) <= 0)


def test_default_criterion_is_five_sigma(stream):
    res = detect_hot_pixels(stream.events.x, stream.events.y, sensor_size=SIZE)
    assert res.n_sigma == 5.0 and as_set(res.pixels) == as_set(stream.hot_pixels)


def test_top_n_finds_exactly_the_planted_pixels(stream):
    res = detect_hot_pixels(stream.events.x, stream.events.y, sensor_size=SIZE, top_n=6)
    assert as_set(res.pixels) == as_set(stream.hot_pixels)
    assert np.isnan(res.threshold)


def test_both_criteria_give_the_union(stream):
    ev = stream.events
    a = detect_hot_pixels(ev.x, ev.y, sensor_size=SIZE, top_n=10)
    b = detect_hot_pixels(ev.x, ev.y, sensor_size=SIZE, n_sigma=5)
    both = detect_hot_pixels(ev.x, ev.y, sensor_size=SIZE, top_n=10, n_sigma=5)
    assert as_set(both.pixels) == as_set(a.pixels) | as_set(b.pixels)
    assert len(a.pixels) == 10


def test_threshold_uses_population_std_over_fired_pixels():
    # counts 1, 2, 3, 10 on four pixels, others silent: mean 4, population std sqrt(12.5)
    x = np.repeat(np.array([0, 1, 2, 3], np.uint16), [1, 2, 3, 10])
    y = np.zeros_like(x)
    res = detect_hot_pixels(x, y, sensor_size=(8, 2), n_sigma=1.0)
    assert res.mean == pytest.approx(4.0)
    assert res.std == pytest.approx(np.sqrt(12.5))
    assert res.threshold == pytest.approx(4.0 + np.sqrt(12.5))
    assert as_set(res.pixels) == {(3, 0)}


def test_top_n_ties_go_to_the_lower_row_major_index():
    x = np.array([5, 1, 3, 3], np.uint16)
    y = np.array([0, 1, 0, 0], np.uint16)  # pixel (3,0) has 2; (5,0) and (1,1) have 1 each
    res = detect_hot_pixels(x, y, sensor_size=(6, 2), top_n=2)
    assert res.pixels.tolist() == [[3, 0], [5, 0]]
    # never more than the pixels that fired
    assert len(detect_hot_pixels(x, y, sensor_size=(6, 2), top_n=50).pixels) == 3


def test_filtered_stream_is_input_minus_hot_pixel_events(stream):
    ev = stream.events
    res = detect_hot_pixels(ev.x, ev.y, sensor_size=SIZE)
    keep = hot_pixel_mask(ev.x, ev.y, res.pixels, sensor_size=SIZE)
    hot = np.zeros(SIZE[::-1], bool)
    hot[stream.hot_pixels[:, 1], stream.hot_pixels[:, 0]] = True
    expected = ~hot[ev.y, ev.x]
    np.testing.assert_array_equal(keep, expected)
    out = filter_events(ev, res.pixels, sensor_size=SIZE)
    for name in ("t_ns", "x", "y", "p"):
        np.testing.assert_array_equal(getattr(out, name), getattr(ev, name)[expected])
    assert len(ev) - len(out) == res.n_discarded
    assert res.fraction_discarded == pytest.approx(res.n_discarded / len(ev))


def test_filter_keeps_dtypes_and_does_not_touch_inputs():
    rng = np.random.default_rng(0)
    t = np.arange(100, dtype=np.uint32)
    x = rng.integers(0, 4, 100).astype(np.int32)
    y = rng.integers(0, 3, 100).astype(np.uint8)
    p = rng.integers(0, 2, 100).astype(np.int8)
    copies = [a.copy() for a in (t, x, y, p)]
    out = filter_arrays(t, x, y, p, [[1, 2]], sensor_size=(4, 3))
    assert [o.dtype for o in out] == [a.dtype for a in (t, x, y, p)]
    keep = ~((x == 1) & (y == 2))
    for o, a in zip(out, (t, x, y, p), strict=True):
        np.testing.assert_array_equal(o, a[keep])
    for a, c in zip((t, x, y, p), copies, strict=True):
        np.testing.assert_array_equal(a, c)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 9), st.integers(1, 7),
    st.lists(st.tuples(st.integers(0, 8), st.integers(0, 6)), max_size=60),
    st.lists(st.tuples(st.integers(0, 8), st.integers(0, 6)), max_size=5),
)
def test_mask_and_filter_match_numpy(w, h, coords, hot):
    xy = np.array([(a % w, b % h) for a, b in coords], dtype=np.uint16).reshape(-1, 2)
    hot_px = np.array([(a % w, b % h) for a, b in hot], dtype=np.int64).reshape(-1, 2)
    x, y = xy[:, 0], xy[:, 1]
    hot_map = np.zeros((h, w), bool)
    hot_map[hot_px[:, 1], hot_px[:, 0]] = True
    expected = ~hot_map[y, x]
    np.testing.assert_array_equal(hot_pixel_mask(x, y, hot_px, sensor_size=(w, h)), expected)
    t = np.arange(len(x), dtype=np.int64)
    ev = filter_events(Events(t, x, y, t % 2 == 0), hot_px, sensor_size=(w, h))
    np.testing.assert_array_equal(ev.t_ns, t[expected])
    counts = count_events(x, y, sensor_size=(w, h))
    np.testing.assert_array_equal(counts.ravel(), np.bincount(y.astype(int) * w + x, minlength=w * h))


def test_per_polarity_counts_and_detection():
    x = np.array([0, 0, 0, 1, 1], np.uint16)
    y = np.zeros(5, np.uint16)
    p = np.array([True, True, False, False, False])
    c = count_events(x, y, sensor_size=(2, 1), p=p)
    assert c.shape == (2, 1, 2)
    assert c[1, 0].tolist() == [2, 0] and c[0, 0].tolist() == [1, 2]
    res = hot_pixels_from_counts(c, top_n=1)
    assert as_set(res.pixels) == {(0, 0), (1, 0)}  # top of positive, top of negative


def test_rate_criterion_finds_the_planted_pixels(stream):
    ev = stream.events
    # a hot pixel fires ~50 events per 20 ms, an edge pixel at most ~10
    px = rate_hot_pixels(ev.t_ns, ev.x, ev.y, sensor_size=SIZE, min_events=25, window_ns=20_000_000)
    assert as_set(px) == as_set(stream.hot_pixels)


def test_streaming_counter_matches_in_memory(stream):
    ev = stream.events
    counter = PixelCounter(sensor_size=None, rate_min_events=25, rate_window_ns=20_000_000)
    for s in range(0, len(ev), 10_007):
        counter.add(Events(ev.t_ns[s : s + 10_007], ev.x[s : s + 10_007], ev.y[s : s + 10_007],
                           ev.p[s : s + 10_007]))
    np.testing.assert_array_equal(counter.count_map, count_events(ev.x, ev.y, sensor_size=SIZE))
    assert counter.sensor_size == SIZE  # grown from the data: every pixel fires here
    res = counter.result(n_sigma=5)
    assert as_set(res.pixels) == as_set(stream.hot_pixels)


def test_coordinates_outside_the_sensor_are_refused():
    x = np.array([1, 70], np.uint16)
    y = np.array([1, 1], np.uint16)
    with pytest.raises(IbiscapeError, match=r"event 1 at pixel \(x=70, y=1\).*64x48"):
        detect_hot_pixels(x, y, sensor_size=SIZE)
    with pytest.raises(IbiscapeError, match="outside"):
        hot_pixel_mask(x, y, [[0, 0]], sensor_size=SIZE)
    with pytest.raises(IbiscapeError, match="outside"):
        filter_events(Events(np.arange(2), x, y, np.ones(2, bool)), [[0, 0]], sensor_size=SIZE)
    with pytest.raises(IbiscapeError, match="hot pixel 0"):
        hot_pixel_mask(x[:1], y[:1], [[64, 0]], sensor_size=SIZE)


def test_bad_arguments_are_refused():
    with pytest.raises(IbiscapeError, match="one length"):
        detect_hot_pixels(np.zeros(3, np.uint16), np.zeros(2, np.uint16), sensor_size=SIZE)
    with pytest.raises(IbiscapeError, match="integer"):
        detect_hot_pixels(np.zeros(3), np.zeros(3), sensor_size=SIZE)
    with pytest.raises(IbiscapeError, match="sensor_size"):
        detect_hot_pixels(np.zeros(3, np.uint16), np.zeros(3, np.uint16), sensor_size=(0, 5))
    with pytest.raises(IbiscapeError, match="top_n"):
        detect_hot_pixels(np.zeros(3, np.uint16), np.zeros(3, np.uint16), sensor_size=SIZE, top_n=-1)


def test_result_to_dict_is_strict_json() -> None:
    import json

    from ibiscape_eval.events import detect_hot_pixels, synthetic_events

    s = synthetic_events(sensor_size=(64, 48), duration_s=0.2, n_hot=4, seed=3)
    for kw in ({"top_n": 4}, {"n_sigma": 5.0}):
        res = detect_hot_pixels(s.events.x, s.events.y, sensor_size=(64, 48), **kw)
        doc = json.loads(json.dumps(res.to_dict(), allow_nan=False))
        assert doc["n_hot_pixels"] == len(doc["hot_pixels"]) == len(res.pixels)
        assert doc["n_events"] == len(s.events) and doc["sensor_size"] == [64, 48]
        assert sum(p["count"] for p in doc["hot_pixels"]) == doc["n_discarded"]
        assert (doc["criteria"]["threshold"] is None) == ("n_sigma" not in kw)
        assert "hot pixels" in repr(res)


@pytest.mark.parametrize("hot_fraction", [0.0, 0.3, 1.0])
def test_threaded_count_and_filter_equal_the_one_thread_results(hot_fraction):
    """Counting into per-thread histograms and filtering slice by slice (the path of long
    streams) give exactly the one-thread counts and filtered events, also when a slice ends
    in discarded events or keeps none."""
    rng = np.random.default_rng(7)
    n, w, h = 10_007, 37, 23
    x = rng.integers(0, w, n).astype(np.uint16)
    y = rng.integers(0, h, n).astype(np.uint16)
    ev = Events(np.arange(n, dtype=np.int64) * 10, x, y, rng.random(n) < 0.5)
    flat = np.unique(y.astype(np.int64) * w + x)
    hot_flat = flat[rng.random(flat.size) < hot_fraction]
    hot = np.stack([hot_flat % w, hot_flat // w], axis=1)
    one_counts = count_events(x, y, sensor_size=(w, h))
    one = filter_events(ev, hot, sensor_size=(w, h))
    counts = count_events(x, y, sensor_size=(w, h), threads=3)
    many = filter_events(ev, hot, sensor_size=(w, h), threads=3)
    assert np.array_equal(counts, one_counts)
    for f in ("t_ns", "x", "y", "p"):
        assert np.array_equal(getattr(many, f), getattr(one, f))
    keep = ~np.isin(y.astype(np.int64) * w + x, hot_flat)
    assert np.array_equal(many.t_ns, ev.t_ns[keep])
    bad_x = x.copy()
    bad_x[n - 5] = w
    with pytest.raises(IbiscapeError, match=f"event {n - 5} "):
        count_events(bad_x, y, sensor_size=(w, h))
    with pytest.raises(IbiscapeError, match=f"event {n - 5} "):
        filter_events(Events(ev.t_ns, bad_x, y, ev.p), hot, sensor_size=(w, h))
