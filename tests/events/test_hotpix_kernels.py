"""The fast paths of hot-pixel counting and filtering (uint8 counters with wrap-around, AVX-512
compaction, two-pass parallel compaction) against plain numpy on generated data: the same
counts, the same kept events in the same order, the same refusals."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.events import _kernels, count_events, filter_arrays, hot_pixel_mask, hotpix

THREADS = min(2, numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]


@pytest.fixture(params=["1 thread", "parallel"])
def threads(request, monkeypatch):
    """Run the single-thread kernels, or the parallel ones even on short streams."""
    if request.param == "parallel":
        if THREADS < 2:
            pytest.skip("numba has one thread here")
        monkeypatch.setattr(hotpix, "PARALLEL_MIN_EVENTS", 0)
    before = numba.get_num_threads()
    numba.set_num_threads(THREADS if request.param == "parallel" else 1)
    yield request.param
    numba.set_num_threads(before)


@pytest.fixture(params=["simd", "simd, no Bloom filter", "scalar"])
def simd(request, monkeypatch):
    """The AVX-512 kernels where the CPU has them: with the Bloom filter of the hot pixels
    whatever their number (it gives way to looking up every event once more than 1/8 of the
    events are its candidates), or without it; and the scalar kernels everywhere."""
    if request.param != "scalar" and not _kernels.simd_ok(np.int64, np.uint16, np.bool_):
        pytest.skip("no AVX-512 VBMI2 here")
    if request.param == "scalar":
        monkeypatch.setattr(_kernels, "simd_ok", lambda *d: False)
    else:
        monkeypatch.setattr(hotpix, "BLOOM_MAX_HOT", 10**9 if request.param == "simd" else -1)
    return request.param


def reference(t, x, y, p, pixels, w):
    rows = max(int(y.max(initial=0)), int(pixels[:, 1].max(initial=0))) + 1
    hot = np.zeros(rows * w, bool)
    hot[pixels[:, 1].astype(np.int64) * w + pixels[:, 0]] = True
    m = ~hot[y.astype(np.int64) * w + x]
    return t[m], x[m], y[m], p[m]


def stream(n, w, h, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.integers(0, w, n).astype(np.uint16)
    y = rng.integers(0, h, n).astype(np.uint16)
    t = np.cumsum(rng.integers(0, 5, n)).astype(np.int64)
    return t, x, y, rng.random(n) < 0.5


def all_pixels(w, h):
    return np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 2)


@pytest.mark.parametrize("n", [0, 1, 63, 64, 65, 129, 4097, 100_003])
@pytest.mark.parametrize("hot_fraction", [0.0, 0.08, 0.97, 1.0])
def test_filter_keeps_what_numpy_keeps(n, hot_fraction, threads, simd):
    w, h = 37, 23
    t, x, y, p = stream(n, w, h, seed=n)
    px = all_pixels(w, h)
    pixels = px[np.random.default_rng(1).random(len(px)) < hot_fraction]
    out = filter_arrays(t, x, y, p, pixels, sensor_size=(w, h))
    for got, want in zip(out, reference(t, x, y, p, pixels, w), strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(hot_pixel_mask(x, y, pixels, sensor_size=(w, h)),
                                  ~np.isin(y.astype(np.int64) * w + x, pixels[:, 1] * w + pixels[:, 0]))


@pytest.mark.parametrize("size", [(1, 1), (640, 1), (1, 480), (346, 260), (65536, 2)])
def test_every_pixel_of_the_sensor_edge(size, threads, simd):
    """Events on every border pixel (the largest coordinates included), several times over:
    all kept, only the corners dropped, or all dropped."""
    w, h = size
    px = all_pixels(w, h) if w * h < 10_000 else None
    if px is None:
        xs = np.arange(w)
        px = np.concatenate([np.stack([xs, np.zeros_like(xs)], 1), np.stack([xs, np.full_like(xs, h - 1)], 1)])
    edge = px[(px[:, 0] == 0) | (px[:, 0] == w - 1) | (px[:, 1] == 0) | (px[:, 1] == h - 1)]
    rep = np.tile(edge, (3, 1))
    x, y = rep[:, 0].astype(np.uint16), rep[:, 1].astype(np.uint16)
    t, p = np.arange(len(x), dtype=np.int64), np.arange(len(x)) % 3 == 0
    counts = count_events(x, y, sensor_size=size)
    assert counts.sum() == len(x)
    np.testing.assert_array_equal(
        counts.ravel(), np.bincount(y.astype(np.int64) * w + x, minlength=w * h))
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]])
    for pixels in (np.empty((0, 2), np.int64), corners, edge):
        out = filter_arrays(t, x, y, p, pixels, sensor_size=size)
        for got, want in zip(out, reference(t, x, y, p, pixels, w), strict=True):
            np.testing.assert_array_equal(got, want)
    assert len(filter_arrays(t, x, y, p, edge, sensor_size=size)[0]) == 0


def test_any_dtypes_are_kept_exactly(threads, simd):
    """filter_arrays on non-canonical dtypes (float time, int32 / int64 coordinates, uint8
    polarity), into new arrays and in place: the outputs have the input dtypes and values."""
    w, h = 50, 40
    t, x, y, p = stream(5000, w, h, seed=7)
    pixels = all_pixels(w, h)[::7]
    ins = (t.astype(np.float64) / 3, x.astype(np.int32), y.astype(np.int64), p.astype(np.uint8))
    want = reference(*ins, pixels, w)
    for inplace in (False, True):
        cols = [a.copy() for a in ins]
        out = filter_arrays(*cols, pixels, sensor_size=(w, h), inplace=inplace)
        for got, ref in zip(out, want, strict=True):
            assert got.dtype == ref.dtype
            np.testing.assert_array_equal(got, ref)


def test_counters_wrap_around_exactly(threads, simd):
    """More than 65535 events on a pixel (the uint8 counters wrap hundreds of times) and a pixel
    with exactly 65536, pixels with 255, 256, 257 and 512 events: the counts stay exact."""
    w, h = 8, 4
    rng = np.random.default_rng(3)
    edges = [(1, 0, 255), (2, 0, 256), (3, 0, 257), (4, 0, 512)]
    x = np.concatenate([np.full(140_000, 7), np.full(65_536, 0), rng.integers(0, w, 5000),
                        *(np.full(k, px) for px, _, k in edges)])
    y = np.concatenate([np.full(140_000, 3), np.full(65_536, 1), np.full(5000, 2),
                        *(np.full(k, py) for _, py, k in edges)])
    order = rng.permutation(len(x))
    x, y = x[order].astype(np.uint16), y[order].astype(np.uint16)
    counts = count_events(x, y, sensor_size=(w, h))
    assert counts.dtype == np.int64
    np.testing.assert_array_equal(counts.ravel(), np.bincount(y.astype(np.int64) * w + x, minlength=w * h))
    assert counts[3, 7] == 140_000 and counts[1, 0] == 65_536
    assert [counts[py, px] for px, py, _ in edges] == [k for _, _, k in edges]


@pytest.mark.parametrize("bad", [(5, 0), (0, 4), (-1, 0), (0, -3)])
def test_outside_the_sensor_is_refused_naming_the_first(bad, threads):
    w, h = 5, 4
    t, x, y, p = stream(3000, w, h, seed=9)
    x, y = x.astype(np.int32), y.astype(np.int32)
    x[1234], y[1234] = bad
    x[2000] = 99
    pixels = np.array([[1, 1]])
    for call in (lambda: filter_arrays(t, x, y, p, pixels, sensor_size=(w, h)),
                 lambda: hot_pixel_mask(x, y, pixels, sensor_size=(w, h)),
                 lambda: count_events(x, y, sensor_size=(w, h))):
        with pytest.raises(IbiscapeError, match=r"event 1234 at pixel .* outside the 5x4 sensor"):
            call()


@pytest.mark.parametrize("per_polarity", [False, True])
def test_streamed_counter_refuses_a_bad_chunk_and_keeps_its_counts(per_polarity):
    """PixelCounter checks a chunk before counting it: the error names the event, the counts
    so far stay those of the good chunks, and counting goes on."""
    from ibiscape_eval.core.events import Events
    from ibiscape_eval.events import PixelCounter

    w, h = 6, 5
    chunks = [Events(*(a for a in stream(700, w, h, seed=s))) for s in range(3)]
    bad = chunks[1]
    bx = bad.x.copy()
    bx[321] = w
    acc = PixelCounter(sensor_size=(w, h), per_polarity=per_polarity)
    acc.add(chunks[0])
    with pytest.raises(IbiscapeError, match=r"event 1021: pixel \(x=6, y=\d\) lies outside the 6x5"):
        acc.add(Events(bad.t_ns, bx, bad.y, bad.p))
    acc.add(chunks[2])
    both = Events.concatenate([chunks[0], chunks[2]])
    want = np.bincount(both.y.astype(np.int64) * w + both.x, minlength=w * h).reshape(h, w)
    got = acc.count_map.sum(axis=0) if per_polarity else acc.count_map
    np.testing.assert_array_equal(got, want)
    assert acc.n_events == 1400


@pytest.fixture(params=["threads", "last slice first"])
def order(request, monkeypatch):
    """The slices on threads as they come, or one after the other from the last: the order
    in which a slice's output overwrites most of the input of the slices before it."""
    if request.param == "last slice first":
        def backwards(fn, n, parts):
            bd = hotpix._bounds(n, parts)
            return [fn(a, b) for a, b in zip(bd[-2::-1], bd[:0:-1], strict=True)][::-1]

        monkeypatch.setattr(hotpix, "_in_parts", backwards)
    return request.param


@pytest.mark.parametrize("n_threads", [1, 2, 3])
@pytest.mark.parametrize("hot_fraction", [0.0, 0.08, 0.5, 0.97, 1.0])
@pytest.mark.parametrize("n", [0, 1, 64, 4097, 100_003])
def test_in_place_filter_keeps_what_numpy_keeps(n, hot_fraction, n_threads, simd, order):
    """filter_arrays(inplace=True) on one or several threads (one pass, the two slices
    converging on their boundary; on three, the slice tails copied first, or one thread when
    that copy would exceed the kept events): the kept events of numpy, returned as views of K
    contiguous elements of the given arrays, at the same place in all four."""
    w, h = 37, 23
    t, x, y, p = stream(n, w, h, seed=n + 1)
    pixels = all_pixels(w, h)[np.random.default_rng(2).random(w * h) < hot_fraction]
    assert_inplace_is_numpy(t, x, y, p, pixels, w, h, n_threads)


def assert_views_inside(out, cols):
    """``out`` are views of the same K contiguous elements of each of ``cols``."""
    starts = set()
    for got, col in zip(out, cols, strict=True):
        assert got.base is col or got.size == 0
        assert got.flags.c_contiguous and got.dtype == col.dtype
        start, rem = divmod(got.ctypes.data - col.ctypes.data, col.itemsize)
        assert rem == 0 and start >= 0 and start + got.size <= col.size
        starts.add(start if got.size else None)
    assert len(starts) == 1


def assert_inplace_is_numpy(t, x, y, p, pixels, w, h, n_threads):
    """``filter_arrays(..., inplace=True)`` on copies of the stream keeps numpy's events, dtypes
    kept, as views of K contiguous elements of the copies."""
    want = reference(t, x, y, p, pixels, w)
    cols = [a.copy() for a in (t, x, y, p)]
    out = filter_arrays(*cols, pixels, sensor_size=(w, h), threads=n_threads, inplace=True)
    for got, ref in zip(out, want, strict=True):
        assert got.dtype == ref.dtype
        np.testing.assert_array_equal(got, ref)
    assert_views_inside(out, cols)


@pytest.mark.parametrize("n_threads", [2, 3])
def test_in_place_when_later_slices_overwrite_whole_earlier_ones(n_threads, simd, order):
    """The first slices all hot, the last all kept: the later slices' output lands on the
    whole input of the earlier ones (read from their copies); and the reverse."""
    w, h = 16, 8
    n = 6000
    rng = np.random.default_rng(5)
    x = rng.integers(1, w, n).astype(np.uint16)
    y = rng.integers(0, h, n).astype(np.uint16)
    t, p = np.arange(n, dtype=np.int64) * 3, rng.random(n) < 0.5
    for hot_part in (slice(0, 2 * n // 3), slice(n // 3, n)):
        xs = x.copy()
        xs[hot_part] = 0
        pixels = np.stack([np.zeros(h, np.int64), np.arange(h)], 1)
        want = reference(t, xs, y, p, pixels, w)
        cols = [a.copy() for a in (t, xs, y, p)]
        out = filter_arrays(*cols, pixels, sensor_size=(w, h), threads=n_threads, inplace=True)
        for got, ref in zip(out, want, strict=True):
            np.testing.assert_array_equal(got, ref)


def test_in_place_refuses_what_it_cannot_overwrite():
    """Read-only (an Events' arrays), strided or overlapping arrays, and events outside the
    sensor, are refused before anything is written."""
    from ibiscape_eval.core.events import Events

    w, h = 10, 6
    t, x, y, p = stream(500, w, h, seed=4)
    pixels = np.array([[1, 1], [2, 3]])
    ev = Events(t, x, y, p)
    with pytest.raises(IbiscapeError, match=r"t is not one.*read-only"):
        filter_arrays(ev.t_ns, ev.x, ev.y, ev.p, pixels, sensor_size=(w, h), inplace=True)
    xy = np.stack([x, y], 1)
    with pytest.raises(IbiscapeError, match="x is not one"):
        filter_arrays(t.copy(), xy[:, 0], y.copy(), p.copy(), pixels, sensor_size=(w, h), inplace=True)
    both = np.concatenate([x, y])
    with pytest.raises(IbiscapeError, match="x and y overlap"):
        filter_arrays(t.copy(), both[:500], both[:500], p.copy(), pixels, sensor_size=(w, h),
                      inplace=True)
    cols = [a.copy() for a in (t, x, y, p)]
    cols[1][321] = w
    with pytest.raises(IbiscapeError, match="event 321 at pixel"):  # the arrays left unspecified
        filter_arrays(*cols, pixels, sensor_size=(w, h), inplace=True, threads=2)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_threads_must_be_a_whole_number(bad):
    t, x, y, p = stream(100, 5, 5)
    for call in (lambda: count_events(x, y, sensor_size=(5, 5), threads=bad),
                 lambda: hot_pixel_mask(x, y, np.array([[1, 1]]), sensor_size=(5, 5), threads=bad),
                 lambda: filter_arrays(t, x, y, p, np.array([[1, 1]]), sensor_size=(5, 5), threads=bad)):
        with pytest.raises(IbiscapeError, match="threads must be a whole number"):
            call()


@pytest.mark.parametrize("n_threads", [2, 3, 7])
def test_threads_argument_gives_the_one_thread_answers(n_threads, simd):
    """threads= (a pool of the call's own, whatever numba's thread count) on a short stream:
    the counts, mask and kept events of one thread, with counters wrapping around."""
    w, h = 9, 7
    rng = np.random.default_rng(11)
    n = 300_000
    x = np.where(rng.random(n) < 0.5, 4, rng.integers(0, w, n)).astype(np.uint16)
    y = np.where(x == 4, 2, rng.integers(0, h, n)).astype(np.uint16)
    t, p = np.arange(n, dtype=np.int64), rng.random(n) < 0.5
    pixels = np.array([[4, 2], [0, 0], [8, 6]])
    np.testing.assert_array_equal(count_events(x, y, sensor_size=(w, h), threads=n_threads),
                                  count_events(x, y, sensor_size=(w, h), threads=1))
    assert count_events(x, y, sensor_size=(w, h), threads=n_threads)[2, 4] > 2 * 65536
    np.testing.assert_array_equal(hot_pixel_mask(x, y, pixels, sensor_size=(w, h), threads=n_threads),
                                  hot_pixel_mask(x, y, pixels, sensor_size=(w, h), threads=1))
    for got, want in zip(filter_arrays(t, x, y, p, pixels, sensor_size=(w, h), threads=n_threads),
                         reference(t, x, y, p, pixels, w), strict=True):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("where", [0, 63, 64, 1000, 4095, 4096 + 70, 8191])
@pytest.mark.parametrize("n_threads", [1, 2, 3])
def test_uint16_events_outside_the_sensor_are_refused_naming_the_first(where, n_threads, simd):
    """uint16 coordinates (checked by the Bloom pass and the counting kernel themselves, 64 at
    a time, the last partial block one by one): the first event outside is named wherever it
    falls (a block's first or last event, the tail, a later slice), with a second one after it;
    the input arrays untouched (in place: copies, left unspecified)."""
    w, h = 37, 23
    t, x, y, p = stream(8192 - 5, w, h, seed=where)
    where = min(where, len(x) - 1)
    x[where], y[min(where + 5, len(x) - 1)] = w, h
    pixels = all_pixels(w, h)[::5]
    cols = [a.copy() for a in (t, x, y, p)]
    for call in (lambda: filter_arrays(t, x, y, p, pixels, sensor_size=(w, h), threads=n_threads),
                 lambda: hot_pixel_mask(x, y, pixels, sensor_size=(w, h), threads=n_threads),
                 lambda: filter_arrays(*(a.copy() for a in cols), pixels, sensor_size=(w, h),
                                       threads=n_threads, inplace=True),
                 lambda: count_events(x, y, sensor_size=(w, h), threads=n_threads)):
        with pytest.raises(IbiscapeError, match=rf"event {where} at pixel \(x={w}, .* outside the 37x23 sensor"):
            call()
    for a, b in zip(cols, (t, x, y, p), strict=True):
        np.testing.assert_array_equal(a, b)


def test_bloom_filter_passes_every_hot_pixel():
    """The Bloom table of a hot-pixel list: every listed pixel passes both hashes (a miss would
    keep a hot pixel's events); with 200 of a megapixel, few of the others pass."""
    rng = np.random.default_rng(0)
    hot = rng.choice(1024 * 1024, 200, replace=False)
    tab = _kernels.bloom_table(hot)
    j = np.arange(1024 * 1024, dtype=np.uint64)
    hit = np.ones(j.size, bool)
    for q, mult in enumerate(_kernels.BLOOM_MULTIPLIERS):
        hh = ((j * np.uint64(mult)) & np.uint64(0xFFFFFFFF)) >> np.uint64(21)
        hit &= ((tab[q * 64 + (hh >> np.uint64(5)).astype(np.int64)] >> (hh & np.uint64(31)).astype(np.uint32)) & 1) == 1
    assert hit[hot].all()
    assert hit.sum() - 200 < 0.02 * j.size


def test_keep_words_with_and_without_the_bloom_filter_agree():
    """The AVX-512 keep bits (the Bloom filter kept throughout, dropped part-way when the hot
    events become many, or not used) are those of the scalar look-up of every event."""
    if not _kernels.simd_ok():
        pytest.skip("no AVX-512 here")
    w, h = 640, 480
    rng = np.random.default_rng(8)
    n = 300_000 + 37
    hot = rng.choice(w * h, 300, replace=False)
    j = rng.integers(0, w * h, n)
    j[200_000:] = np.where(rng.random(n - 200_000) < 0.6, rng.choice(hot, n - 200_000), j[200_000:])
    x, y = (j % w).astype(np.uint16), (j // w).astype(np.uint16)
    bits = hotpix._keep_bits(hot, w, h)
    want = np.zeros((n + 63) // 64, np.uint64)
    k_want = _kernels.keep_words(x, y, w, bits, want)
    assert k_want == np.count_nonzero(~np.isin(j, hot))
    for use_bloom in (True, False):
        got = np.zeros_like(want)
        assert _kernels.keep_words_simd(x, y, w, h, _kernels.bloom_table(hot), bits, got, use_bloom) == k_want
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("n_threads", [1, 2])
def test_keep_mask_over_several_chunks(n_threads, simd):
    """hot_pixel_mask works through chunks of ``MASK_CHUNK`` events: over three of them (a
    partial last one) the mask is numpy's, and an event outside the sensor in a later chunk is
    named by its index in the whole stream."""
    w, h = 37, 23
    n = 2 * _kernels.MASK_CHUNK + 1000 + 7
    _, x, y, _ = stream(n, w, h, seed=12)
    pixels = all_pixels(w, h)[::9]
    want = ~np.isin(y.astype(np.int64) * w + x, pixels[:, 1] * w + pixels[:, 0])
    np.testing.assert_array_equal(hot_pixel_mask(x, y, pixels, sensor_size=(w, h), threads=n_threads), want)
    bad = _kernels.MASK_CHUNK + 12_345
    y[bad] = h
    with pytest.raises(IbiscapeError, match=rf"event {bad} at pixel"):
        hot_pixel_mask(x, y, pixels, sensor_size=(w, h), threads=n_threads)


def converge(cols, b, w, h, hot):
    """The two one-pass kernels on the slices ``[:b]`` (backwards) and ``[b:]`` (forwards) of
    copies of ``cols``: the kept events ``[start, b + k1)`` and either kernel's outside event."""
    cols = [a.copy() for a in cols]
    bits = hotpix._keep_bits(hot, w, h)
    start, bad0 = _kernels.filter_down(*(a[:b] for a in cols), w, h, bits)
    k1, bad1 = _kernels.filter_up(*(a[b:] for a in cols), w, h, bits)
    return [a[start:b + k1] for a in cols], bad0, bad1


@pytest.mark.parametrize("hot_fraction", [0.0, 0.08, 0.5, 1.0])
@pytest.mark.parametrize("n", [1, 2, 63, 64, 65, 127, 129, 200, 4097])
def test_converging_kernels_keep_what_numpy_keeps(n, hot_fraction):
    """filter_down on the first slice and filter_up on the second, split anywhere (slices of 0
    and 1 element, boundaries off the multiples of 64, lengths not multiples of 64): the kept
    events of numpy, in order, contiguous around the boundary."""
    if not _kernels.simd_ok(np.int64, np.uint16, np.bool_):
        pytest.skip("no AVX-512 VBMI2 here")
    w, h = 37, 23
    t, x, y, p = stream(n, w, h, seed=n + 3)
    hot = np.flatnonzero(np.random.default_rng(n).random(w * h) < hot_fraction)
    pixels = np.stack([hot % w, hot // w], 1)
    want = reference(t, x, y, p, pixels, w)
    for b in sorted({0, 1, n // 2, n // 2 // 64 * 64, n - 1, n}):
        got, bad0, bad1 = converge((t, x, y, p), b, w, h, hot)
        assert bad0 == bad1 == -1
        for g, r in zip(got, want, strict=True):
            assert g.dtype == r.dtype
            np.testing.assert_array_equal(g, r)


@pytest.mark.parametrize("n_threads", [2, 3])
def test_in_place_over_several_chunks_and_dtypes(n_threads, simd):
    """In place on streams of several FILTER_CHUNKs per slice (hot events growing from none to
    most), with float32 times (still AVX-512) and datetime64 times (the two-pass path): numpy's
    kept events, in order."""
    w, h = 64, 32
    n = 5 * _kernels.FILTER_CHUNK + 77
    t, x, y, p = stream(n, w, h, seed=21)
    x[n // 2:] = np.where(np.random.default_rng(4).random(n - n // 2) < 0.9, 3, x[n // 2:])
    pixels = np.array([[3, r] for r in range(h)] + [[5, 5], [60, 31]])
    for times in (t, t.astype(np.float32), t.astype("datetime64[ns]")):
        assert_inplace_is_numpy(times, x, y, p, pixels, w, h, n_threads)


@pytest.mark.parametrize("where", [[5], [5, 90_000], [70_000, 130_000], [129_999], [131_000, 200_000],
                                   [199_999], [64, 65_600, 262_150]])
@pytest.mark.parametrize("n_threads", [1, 2])
def test_in_place_names_the_first_event_outside_in_stream_order(where, n_threads, simd):
    """Events outside the sensor in the first slice (found by the backward pass from its end:
    the first in the stream is then looked for in the untouched part), the second, both, in
    several chunks or at their edges: the error names the first of them, with its pixel."""
    w, h = 50, 40
    n = 4 * _kernels.FILTER_CHUNK + 11
    t, x, y, p = stream(n, w, h, seed=sum(where))
    for i in where:
        x[i] = w + i % 7
    pixels = all_pixels(w, h)[::11]
    cols = [a.copy() for a in (t, x, y, p)]
    with pytest.raises(IbiscapeError, match=rf"event {where[0]} at pixel \(x={w + where[0] % 7}, "):
        filter_arrays(*cols, pixels, sensor_size=(w, h), threads=n_threads, inplace=True)
