"""Hot-pixel detection and removal for DVS event streams.

Two criteria from the IBISCape paper (section "Event-based evaluation", figure
``fig:histo_hot_pixel``), as implemented by dvs_tools' ``dvs_hot_pixel_filter``:

* ranking: the ``top_n`` pixels with the largest event counts over the whole recording;
* threshold: pixels whose count exceeds ``mean + n_sigma * std``, where mean and the population
  standard deviation (``cv::meanStdDev``, divisor N) are taken over the pixels that fired at least
  once.  dvs_tools uses ``n_sigma = 5`` when no count is given, and so do we.

Plus libcaer's rate criterion (hot if a pixel fires at least K events within a time window).

Counting and filtering run in numba kernels over the raw ``uint16`` coordinates: one pass, a flat
``uint8`` count array per thread (with a list of wrap-arounds); then the keep bits of the events,
64 to a word (an AVX-512 Bloom filter of the hot pixels in registers, its candidates looked up in
a bit table of the pixels to keep), and single-pass compaction; the sensor bounds are checked
inside both passes; ``threads=`` splits the events into contiguous slices.  In place on one or
two threads, one pass: the bit table looked up by AVX-512 gathers as the events are compacted,
two slices converging on their boundary.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.events import EventChunk, Events
from ibiscape_eval.core.numbers import finite_or_none

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = [
    "HotPixelResult",
    "PixelCounter",
    "count_events",
    "detect_hot_pixels",
    "filter_events",
    "hot_pixel_mask",
    "hot_pixels_from_counts",
    "rate_hot_pixels",
]

_T = TypeVar("_T")

DEFAULT_N_SIGMA = 5.0  # dvs_tools' default (--n_std)


def _check_sensor_size(sensor_size: tuple[int, int]) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in sensor_size)
    except (TypeError, ValueError):
        raise IbiscapeError(
            f"sensor_size must be (width, height) in pixels, got {sensor_size!r}"
        ) from None
    if not (0 < w <= 65536 and 0 < h <= 65536):
        raise IbiscapeError(f"sensor_size must be positive and at most 65536, got {w}x{h}")
    return w, h


def _coords(x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    xa = np.ascontiguousarray(x)
    ya = np.ascontiguousarray(y)
    if xa.ndim != 1 or ya.ndim != 1 or xa.shape != ya.shape:
        raise IbiscapeError(
            f"x and y must be 1-D arrays of one length, got shapes {xa.shape} and {ya.shape}"
        )
    if xa.dtype.kind not in "iu" or ya.dtype.kind not in "iu":
        raise IbiscapeError(f"x and y must be integer pixel coordinates, got {xa.dtype}, {ya.dtype}")
    return xa, ya


def _outside(x: np.ndarray, y: np.ndarray, i: int, w: int, h: int) -> IbiscapeError:
    return IbiscapeError(
        f"event {i} at pixel (x={int(x[i])}, y={int(y[i])}) lies outside the {w}x{h} sensor; "
        "pass the right sensor size ({0})", hint=(Remedy("sensor_size"),)
    )


def _first_outside(x: np.ndarray, y: np.ndarray, w: int, h: int) -> int:
    """Index of the first event outside the sensor or -1 (numpy's vectorised min / max first:
    the per-event kernels then need no test)."""
    if not x.shape[0]:
        return -1
    lo = min(int(x.min()), int(y.min())) if "i" in (x.dtype.kind, y.dtype.kind) else 0
    if lo < 0 or int(x.max()) >= w or int(y.max()) >= h:
        from . import _kernels

        return int(_kernels.first_outside(x, y, w, h))
    return -1


def _check_inside(x: np.ndarray, y: np.ndarray, w: int, h: int, parts: int = 1) -> None:
    """Refuse events outside the sensor, naming the first (slices on ``parts`` threads: numpy
    releases the GIL in its min / max)."""
    def first(a: int, b: int) -> int:
        i = _first_outside(x[a:b], y[a:b], w, h)
        return a + i if i >= 0 else -1

    found = [i for i in _in_parts(first, x.shape[0], parts) if i >= 0]
    bad = found[0] if found else -1
    if bad >= 0:
        raise _outside(x, y, bad, w, h)


def count_events(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    *,
    sensor_size: tuple[int, int],
    p: npt.ArrayLike | None = None,
    threads: int | None = None,
) -> npt.NDArray[np.int64]:
    """Number of events per pixel.

    Parameters
    ----------
    x, y : array_like, shape (N,), integer
        Pixel coordinates of the events (uint16 is the fast path).
    sensor_size : (int, int)
        Sensor width and height in pixels.
    p : array_like, shape (N,), bool, optional
        Polarities; if given, the counts are split by polarity.
    threads : int, optional
        Threads to count on (without ``p``): each counts a contiguous slice into counters of its
        own.  Default: numba's thread count (``NUMBA_NUM_THREADS``) for streams of at least
        :data:`PARALLEL_MIN_EVENTS` events, else 1.

    Returns
    -------
    ndarray, int64
        Shape (H, W), or (2, H, W) with ``[0]`` negative and ``[1]`` positive events if ``p`` is
        given.

    Raises
    ------
    IbiscapeError
        If an event lies outside the sensor (the message names its index).
    """
    w, h = _check_sensor_size(sensor_size)
    xa, ya = _coords(x, y)
    pa = None
    if p is not None:
        pa = np.ascontiguousarray(p, dtype=np.bool_)
        if pa.shape != xa.shape:
            raise IbiscapeError(f"p has shape {pa.shape}, x and y have {xa.shape}")
    parts = _threads(xa.shape[0], threads)  # checked with p too
    if pa is None:
        total = np.zeros((h, w), np.int64)
        _count8(xa, ya, w, h, total, parts)
        return total
    # uint32 cannot overflow: a pixel holds at most N events; split larger inputs.
    step = 2**31
    total3: np.ndarray | None = None
    for s in range(0, max(xa.shape[0], 1), step):
        part = _count_padded(xa[s : s + step], ya[s : s + step], pa[s : s + step], w, h)
        if isinstance(part, int):
            raise _outside(xa, ya, s + part, w, h)
        total3 = part.astype(np.int64) if total3 is None else total3 + part
    assert total3 is not None
    return total3


#: Streams shorter than this run on one thread unless ``threads`` says otherwise (starting the
#: threads costs more).
PARALLEL_MIN_EVENTS = 4_000_000


def _threads(n: int, threads: int | None = None) -> int:
    """Threads to use for ``n`` events: ``threads`` if given, else numba's thread count for the
    calling thread (``NUMBA_NUM_THREADS`` / ``numba.set_num_threads`` set the most), and 1 for
    streams shorter than :data:`PARALLEL_MIN_EVENTS`."""
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise IbiscapeError(f"threads must be a whole number >= 1, got {threads!r}")
        want = int(threads)
    elif n < PARALLEL_MIN_EVENTS:
        return 1
    else:
        import numba

        want = int(numba.get_num_threads())
    return max(1, min(want, n))  # no empty slices


def _bounds(n: int, parts: int, align: int = 1) -> list[int]:
    """Start of each of ``parts`` contiguous slices of ``n`` items (a multiple of ``align``),
    and ``n``."""
    return [n * c // parts // align * align for c in range(parts)] + [n]


def _in_parts(fn: Callable[[int, int], _T], n: int, parts: int) -> list[_T]:
    """``fn(a, b)`` on every slice ``[a, b)`` of :func:`_bounds`, on ``parts`` threads of a
    pool of this call's own (the kernels release the GIL; nothing process-wide changes)."""
    bd = _bounds(n, parts)
    if parts == 1:
        return [fn(0, n)]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(parts) as pool:
        return list(pool.map(fn, bd[:-1], bd[1:]))


_PAD = 16  # uint32 counters = one 64-byte cache line of row padding (see _kernels.count_xy)
_PAD8 = 64  # the same for uint8 counters


def _simd_coords(x: np.ndarray, y: np.ndarray, places: int, *dtypes: np.dtype[Any]) -> bool:
    """Whether the AVX-512 kernels take these events: uint16 coordinates, ``places`` counters or
    pixels indexed in 32 bits, and (for the compaction) columns of ``dtypes`` (see
    ``_kernels.simd_ok``)."""
    from . import _kernels

    return x.dtype == np.uint16 and y.dtype == np.uint16 and places <= 2**32 and _kernels.simd_ok(*dtypes)


def _count8(x: np.ndarray, y: np.ndarray, w: int, h: int, out: np.ndarray, parts: int) -> None:
    """Add the events per pixel to the int64 (H, W) ``out`` through uint8 counters, one set per
    thread (see ``_kernels.count_xy8``), then fold them (rows split over the threads too).  The
    events are checked to lie inside the sensor (the first outside is refused by name): uint16
    ones by the AVX-512 counting kernel itself, others by :func:`_check_inside` first."""
    from . import _kernels

    stride = w + _PAD8
    n = x.shape[0]
    simd = _simd_coords(x, y, h * stride)
    if not simd:
        _check_inside(x, y, w, h, parts)
    counts = np.zeros((parts, h * stride), np.uint8)
    wrapped = np.empty((parts, (n // parts + 1) // 256 + 1), np.int64)  # touched only where used
    bd = _bounds(n, parts, 64)  # slices on 64 events: 2T 1.3x less CPU time than unaligned, measured

    def count(c: int, _: int) -> tuple[int, int]:
        a, b = bd[c], bd[c + 1]
        if simd:
            bad, nw = _kernels.count_xy8_simd(x[a:b], y[a:b], w, h, stride, counts[c], wrapped[c])
            return (a + int(bad) if bad >= 0 else -1), int(nw)
        return -1, int(_kernels.count_xy8(x[a:b], y[a:b], stride, counts[c], wrapped[c]))

    res = _in_parts(count, parts, parts)
    bad = [i for i, _ in res if i >= 0]
    if bad:
        raise _outside(x, y, bad[0], w, h)
    n_wraps = np.array([nw for _, nw in res], np.int64)
    _in_parts(lambda r0, r1: _kernels.fold_rows(counts, w, stride, r0, r1, out), h, parts)
    _kernels.fold_wraps(wrapped, n_wraps, stride, 256, out)


def _count_padded(
    x: np.ndarray, y: np.ndarray, p: np.ndarray | None, w: int, h: int
) -> np.ndarray | int:
    """(planes, H, W) uint32 counts of one piece, or the index of its first out-of-sensor event."""
    from . import _kernels

    stride = w + _PAD
    planes = 1 if p is None else 2
    buf = np.zeros(planes * h * stride, np.uint32)
    if p is None:
        bad = _kernels.count_xy(x, y, w, h, stride, buf)
    else:
        bad = _kernels.count_xyp(x, y, p, w, h, stride, buf)
    if bad >= 0:
        return int(bad)
    return buf.reshape(planes, h, stride)[:, :, :w]


@dataclass(frozen=True, eq=False)
class HotPixelResult:
    """Hot pixels of a recording and the statistics they were chosen from.

    Attributes
    ----------
    pixels : ndarray, shape (K, 2), int64
        Hot pixels as (x, y), sorted by decreasing count (ties by row-major pixel index).
    counts : ndarray, shape (K,), int64
        Events of each hot pixel over the whole recording.
    count_map : ndarray, shape (H, W), int64
        Events per pixel (all polarities), the histogram the criteria work on.
    sensor_size : (int, int)
        Width, height in pixels.
    threshold : float
        ``mean + n_sigma * std`` when the n-sigma criterion was used, else NaN.
    mean, std : float
        Mean and population standard deviation of the counts of the pixels that fired.
    top_n, n_sigma
        The criteria used (None when not used).
    """

    pixels: npt.NDArray[np.int64]
    counts: npt.NDArray[np.int64]
    count_map: npt.NDArray[np.int64]
    sensor_size: tuple[int, int]
    threshold: float
    mean: float
    std: float
    top_n: int | None
    n_sigma: float | None

    @property
    def n_events(self) -> int:
        """Events in the recording."""
        return int(self.count_map.sum())

    @property
    def n_discarded(self) -> int:
        """Events that removing the hot pixels discards."""
        return int(self.counts.sum())

    @property
    def fraction_discarded(self) -> float:
        """``n_discarded / n_events`` (0 for an empty recording)."""
        n = self.n_events
        return self.n_discarded / n if n else 0.0

    @property
    def n_pixels_fired(self) -> int:
        """Pixels with at least one event."""
        return int(np.count_nonzero(self.count_map))

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON (NaN as None): counts, criteria and every hot pixel with its count."""

        return {
            "sensor_size": [int(v) for v in self.sensor_size],
            "n_events": self.n_events,
            "n_pixels_fired": self.n_pixels_fired,
            "n_hot_pixels": len(self.pixels),
            "n_discarded": self.n_discarded,
            "fraction_discarded": self.fraction_discarded,
            "criteria": {
                "top_n": self.top_n,
                "n_sigma": None if self.n_sigma is None else float(self.n_sigma),
                "threshold": finite_or_none(self.threshold),
                "mean": finite_or_none(self.mean),
                "std": finite_or_none(self.std),
            },
            "hot_pixels": [
                {"x": int(x), "y": int(y), "count": int(c)}
                for (x, y), c in zip(self.pixels, self.counts, strict=True)
            ],
        }

    def plot(self, *, title: str = "") -> Figure:
        """Count histograms before / after removal and the sensor heat map (a new Figure)."""
        from .plots import hot_pixel_figure

        return hot_pixel_figure(self, title=title)

    def __repr__(self) -> str:
        w, h = self.sensor_size
        return (f"HotPixelResult({len(self.pixels)} hot pixels on {w}x{h}, "
                f"{100 * self.fraction_discarded:.2f} % of {self.n_events} events discarded)")

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><td>{int(x)}</td><td>{int(y)}</td><td>{int(c)}</td></tr>"
                       for (x, y), c in zip(self.pixels[:20], self.counts[:20], strict=True))
        more = (f"<tr><td colspan='3'>... {len(self.pixels) - 20} more</td></tr>"
                if len(self.pixels) > 20 else "")
        w, h = self.sensor_size
        cap = (f"{len(self.pixels)} hot pixels on {w}x{h}, {100 * self.fraction_discarded:.2f} % "
               f"of {self.n_events} events discarded")
        return (f"<table><caption>{cap}</caption><tr><th>x</th><th>y</th><th>count</th></tr>"
                f"{rows}{more}</table>")

    def to_frame(self) -> pd.DataFrame:
        """The hot pixels as a table with columns ``x, y, count``."""
        import pandas as pd

        return pd.DataFrame(
            {"x": self.pixels[:, 0], "y": self.pixels[:, 1], "count": self.counts}
        )


def _union_sorted(flat: np.ndarray, counts_flat: np.ndarray) -> np.ndarray:
    """Unique flat indices ordered by decreasing count, then increasing index."""
    flat = np.unique(flat)
    order = np.lexsort((flat, -counts_flat[flat]))
    return flat[order]


def _fired_stats(counts: np.ndarray) -> tuple[float, float]:
    """Mean and population standard deviation (``cv::meanStdDev``) of the counts of the pixels
    that fired (NaN if none did)."""
    fired = counts[counts > 0]
    if not fired.size:
        return float("nan"), float("nan")
    return float(fired.mean()), float(fired.std())


def _plane_hot(plane: np.ndarray, top_n: int | None,
               n_sigma: float | None) -> tuple[float, list[np.ndarray]]:
    """The n-sigma threshold (NaN if unused) and the flat indices each criterion marks in one
    count plane."""
    m, s = _fired_stats(plane)
    n_fired = int(np.count_nonzero(plane > 0))
    chosen: list[np.ndarray] = []
    thr = float("nan")
    if n_sigma is not None and n_fired:
        thr = m + float(n_sigma) * s
        chosen.append(np.flatnonzero(plane > thr))
    k = min(int(top_n), n_fired) if top_n is not None else 0
    if k > 0:
        # partial selection, then a stable order: count desc, index asc (dvs_tools'
        # repeated minMaxLoc scans row-major, so ties go to the lower index too)
        cand = np.argpartition(-plane, k - 1)[:k]
        kth = plane[cand].min()
        above = np.flatnonzero(plane > kth)
        ties = np.flatnonzero(plane == kth)[: k - above.size]
        chosen.append(np.concatenate([above, ties]))
    return thr, chosen


def _extra_flat(extra_pixels: npt.ArrayLike, w: int, h: int) -> np.ndarray:
    """Flat indices of further hot pixels (x, y), refused outside the sensor."""
    ep = np.asarray(extra_pixels, dtype=np.int64).reshape(-1, 2)
    if ep.size and ((ep[:, 0] < 0) | (ep[:, 0] >= w) | (ep[:, 1] < 0) | (ep[:, 1] >= h)).any():
        raise IbiscapeError(f"extra hot pixels lie outside the {w}x{h} sensor")
    return ep[:, 1] * w + ep[:, 0]


def hot_pixels_from_counts(
    count_map: npt.ArrayLike,
    *,
    top_n: int | None = None,
    n_sigma: float | None = None,
    extra_pixels: npt.ArrayLike | None = None,
) -> HotPixelResult:
    """Apply the ranking and/or threshold criteria to a per-pixel count map.

    Parameters
    ----------
    count_map : array_like, shape (H, W) or (2, H, W), integer
        Events per pixel; with a polarity axis, each polarity is judged on its own and a pixel is
        hot if it is hot in either (the "per polarity" mode).
    top_n : int, optional
        Mark the ``top_n`` pixels with the largest counts (pixels that never fired are never hot).
    n_sigma : float, optional
        Mark pixels with ``count > mean + n_sigma * std`` over the pixels that fired (population
        std).  If neither criterion is given, ``n_sigma = 5`` (dvs_tools' default).  If both are
        given, a pixel is hot if either criterion marks it.
    extra_pixels : array_like, shape (M, 2), optional
        Further hot pixels (x, y) found by another criterion (e.g. :func:`rate_hot_pixels`).

    Returns
    -------
    HotPixelResult
    """
    cm = np.asarray(count_map)
    if cm.ndim not in (2, 3) or (cm.ndim == 3 and cm.shape[0] != 2) or cm.dtype.kind not in "iu":
        raise IbiscapeError(f"count_map must be integer (H, W) or (2, H, W), got {cm.shape} {cm.dtype}")
    if top_n is not None and int(top_n) < 0:
        raise IbiscapeError(f"top_n must be >= 0, got {top_n}")
    if n_sigma is not None and not np.isfinite(n_sigma):
        raise IbiscapeError(f"n_sigma must be a finite number, got {n_sigma}")
    if top_n is None and n_sigma is None and extra_pixels is None:
        n_sigma = DEFAULT_N_SIGMA
    planes = cm.reshape(-1, cm.shape[-2] * cm.shape[-1]).astype(np.int64, copy=False)
    h, w = cm.shape[-2:]
    total = planes.sum(axis=0)
    chosen: list[np.ndarray] = []
    threshold = float("nan")
    for plane in planes:
        thr, picked = _plane_hot(plane, top_n, n_sigma)
        chosen += picked
        if planes.shape[0] == 1:
            threshold = thr
    mean, std = _fired_stats(total)
    if extra_pixels is not None:
        chosen.append(_extra_flat(extra_pixels, w, h))
    flat = _union_sorted(np.concatenate(chosen) if chosen else np.empty(0, np.int64), total)
    pixels = np.stack([flat % w, flat // w], axis=1).astype(np.int64)
    return HotPixelResult(
        pixels=pixels,
        counts=total[flat],
        count_map=total.reshape(h, w),
        sensor_size=(int(w), int(h)),
        threshold=threshold,
        mean=mean,
        std=std,
        top_n=None if top_n is None else int(top_n),
        n_sigma=None if n_sigma is None else float(n_sigma),
    )


def detect_hot_pixels(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    *,
    sensor_size: tuple[int, int],
    top_n: int | None = None,
    n_sigma: float | None = None,
    threads: int | None = None,
) -> HotPixelResult:
    """Find the hot pixels of a recording from its per-pixel event counts.

    Parameters
    ----------
    x, y : array_like, shape (N,), integer
        Pixel coordinates of all events of the recording.
    sensor_size : (int, int)
        Sensor width and height in pixels.
    top_n : int, optional
        Ranking criterion: the ``top_n`` pixels with the most events.
    n_sigma : float, optional
        Threshold criterion: ``count > mean + n_sigma * std`` over the pixels that fired
        (population std).  Default 5 when neither criterion is given; with both, their union.
    threads : int, optional
        Threads to count on (see :func:`count_events`).

    Returns
    -------
    HotPixelResult
        ``pixels`` (K, 2) as x, y and their ``counts`` (K,).

    Examples
    --------
    >>> res = detect_hot_pixels(x, y, sensor_size=(346, 260), n_sigma=5)  # doctest: +SKIP
    >>> keep = hot_pixel_mask(x, y, res.pixels, sensor_size=(346, 260))  # doctest: +SKIP
    """
    counts = count_events(x, y, sensor_size=sensor_size, threads=threads)
    return hot_pixels_from_counts(counts, top_n=top_n, n_sigma=n_sigma)


def _hot_flat(pixels: npt.ArrayLike, w: int, h: int) -> np.ndarray:
    """The hot pixels (K, 2) x, y as row-major indices ``y * w + x`` (int64), checked."""
    px = np.asarray(pixels)
    if not px.size:
        return np.empty(0, np.int64)
    if px.ndim != 2 or px.shape[1] != 2 or px.dtype.kind not in "iu":
        raise IbiscapeError(
            f"pixels must be an integer (K, 2) array of x, y; got {px.shape} {px.dtype}")
    px = px.astype(np.int64)
    bad = (px[:, 0] < 0) | (px[:, 0] >= w) | (px[:, 1] < 0) | (px[:, 1] >= h)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise IbiscapeError(
            f"hot pixel {i} (x={px[i, 0]}, y={px[i, 1]}) lies outside the {w}x{h} sensor; "
            "check the hot-pixel list and the sensor size"
        )
    return np.asarray(px[:, 1] * w + px[:, 0])


def _keep_bits(hot: np.ndarray, w: int, h: int) -> np.ndarray:
    """The pixels to keep as a bit table (see ``_kernels.keep_words``): uint32 words, bit
    ``j % 32`` of word ``j // 32`` set for pixel ``j = y * w + x`` unless ``j`` is in ``hot``
    (128 KiB for a megapixel sensor: it stays in the L2 cache where a byte per pixel does
    not)."""
    keep = np.ones(w * h, np.bool_)
    keep[hot] = False
    packed = np.packbits(keep, bitorder="little")
    packed = np.concatenate([packed, np.zeros(-packed.size % 4, np.uint8)])
    return packed.view("<u4").astype(np.uint32, copy=False)


#: The AVX-512 Bloom filter of the hot pixels (``_kernels.keep_words_simd``) is used up to this
#: many hot pixels (then ~15 % of the other events pass it and are looked up one by one);
#: beyond, every event is looked up in the bit table.
BLOOM_MAX_HOT = 1024


def _keep_words(x: np.ndarray, y: np.ndarray, pixels: npt.ArrayLike, w: int, h: int, parts: int,
                mask: np.ndarray | None = None) -> tuple[np.ndarray, list[int], list[int]]:
    """The keep bits of every event, 64 to a uint64 word (see ``_kernels.keep_words``), the
    kept events before each of ``parts`` slices (and in all), and the slices' bounds (multiples
    of 64, so that a slice starts on a word); the events are checked to lie inside the sensor
    (the first outside is refused by name).  Each slice on a thread of its own.  With ``mask``
    (uint8, one per event), the keep bits go there as bytes instead, chunk by chunk (the words
    returned are then empty)."""
    from . import _kernels

    hot = _hot_flat(pixels, w, h)
    bits = _keep_bits(hot, w, h)
    n = x.shape[0]
    bd = _bounds(n, parts, 64)
    words = np.empty(0 if mask is not None else (n + 63) // 64, np.uint64)
    simd = _simd_coords(x, y, w * h)
    tab, use_bloom = _kernels.bloom_table(hot), hot.size <= BLOOM_MAX_HOT
    if not simd:
        _check_inside(x, y, w, h, parts)

    def run(c: int, _: int) -> int:
        a, b = bd[c], bd[c + 1]
        if mask is not None and simd:
            k = int(_kernels.keep_bytes_simd(x[a:b], y[a:b], w, h, tab, bits, mask[a:b], use_bloom))
        elif mask is not None:
            k = int(_kernels.keep_bytes(x[a:b], y[a:b], w, bits, mask[a:b]))
        elif simd:
            k = int(_kernels.keep_words_simd(x[a:b], y[a:b], w, h, tab, bits, words[a // 64:], use_bloom))
        else:
            k = int(_kernels.keep_words(x[a:b], y[a:b], w, bits, words[a // 64:]))
        return k if k >= 0 else k - a  # -1 - (the event's index in the whole stream)

    kept = _in_parts(run, parts, parts)
    bad = [-1 - k for k in kept if k < 0]
    if bad:
        raise _outside(x, y, bad[0], w, h)
    return words, [0, *np.cumsum(kept).tolist()], bd


def hot_pixel_mask(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    pixels: npt.ArrayLike,
    *,
    sensor_size: tuple[int, int],
    threads: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Boolean keep-mask: True for events that do not come from a hot pixel.

    Parameters
    ----------
    x, y : array_like, shape (N,), integer
        Pixel coordinates of the events.
    pixels : array_like, shape (K, 2), integer
        Hot pixels as x, y (e.g. ``HotPixelResult.pixels`` or a ``hot_pixels.txt``).
    sensor_size : (int, int)
        Sensor width and height in pixels.
    threads : int, optional
        Threads to work on, each on a contiguous slice (default as in :func:`count_events`).

    Returns
    -------
    ndarray, shape (N,), bool
    """
    w, h = _check_sensor_size(sensor_size)
    xa, ya = _coords(x, y)
    n = xa.shape[0]
    parts = _threads(n, threads)
    out = np.empty(n, np.bool_)
    _keep_words(xa, ya, pixels, w, h, parts, mask=out.view(np.uint8))
    return out


def filter_events(
    events: Events, pixels: npt.ArrayLike, *, sensor_size: tuple[int, int],
    threads: int | None = None,
) -> Events:
    """The events that do not come from a hot pixel, in their order (new arrays; see
    :func:`filter_arrays` for the filter in place).

    Parameters
    ----------
    events
        The stream; its coordinates must lie inside the sensor.
    pixels : array_like, shape (K, 2), integer
        Hot pixels as x, y.
    sensor_size : (int, int)
        Sensor width and height in pixels.
    threads : int, optional
        Threads to filter on, each on a contiguous slice (default as in :func:`count_events`).
    """
    t, x, y, p = filter_arrays(events.t_ns, events.x, events.y, events.p, pixels,
                               sensor_size=sensor_size, threads=threads)
    return Events(t, x, y, p)


def _check_inplace(cols: tuple[Any, ...]) -> None:
    """Refuse ``inplace=True`` on what cannot be overwritten in place."""
    for name, a in zip(("t", "x", "y", "p"), cols, strict=True):
        if not isinstance(a, np.ndarray) or not a.flags.c_contiguous or not a.flags.writeable:
            raise IbiscapeError(
                f"inplace=True needs writeable C-contiguous numpy arrays, and {name} is not one "
                "(an Events' arrays are read-only): use inplace=False or pass copies")
    for i in range(4):
        for j in range(i + 1, 4):
            if np.may_share_memory(cols[i], cols[j]):
                raise IbiscapeError(
                    "inplace=True needs four arrays that share no memory; "
                    f"{'txyp'[i]} and {'txyp'[j]} overlap: use inplace=False")


def filter_arrays(
    t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray, pixels: npt.ArrayLike,
    *, sensor_size: tuple[int, int], threads: int | None = None, inplace: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`filter_events` on plain arrays of any dtypes (kept exactly, as are the inputs).

    Two passes over the events, each split over ``threads`` threads (contiguous slices; default
    as in :func:`count_events`): the keep bits (one bit per event, through an AVX-512 Bloom
    filter of the hot pixels for uint16 coordinates, which checks the sensor bounds on the
    way) with the number of kept events per slice, then every slice compacted to its place in
    the output (AVX-512 compress stores where the CPU has them, else a scalar loop; the same
    events either way).

    ``inplace=True`` compacts into the given arrays themselves and returns views of K
    contiguous elements of them (the kept events, in order; the same place in all four, not
    necessarily from index 0), the other elements left unspecified.  It needs writeable,
    C-contiguous numpy arrays that share no memory (so not an :class:`Events`' read-only
    arrays), and spares the new output arrays: their allocation and first-touch page faults
    cost as much as the compaction itself.  On one or two threads, with uint16 coordinates and
    AVX-512 dtypes, it is one pass with no extra memory: the hot pixels and sensor bounds are
    tested as the events are compacted, and two slices converge on their boundary (the first
    compacted backwards, its kept events packed against the boundary, the second forwards from
    it).  Otherwise the two passes above; extra memory: the keep bits (N / 8 bytes) and, on
    several threads, a copy of the events that the later slices' output overwrites before the
    earlier slices have read them (one thread is used when that copy would exceed the kept
    events).  An event outside the sensor is refused by name (the first in the stream); in
    place, the arrays may then be part compacted.

    Examples
    --------
    >>> t, x, y, p = (np.array(a) for a in (ev.t_ns, ev.x, ev.y, ev.p))  # doctest: +SKIP
    >>> t, x, y, p = filter_arrays(t, x, y, p, hot, sensor_size=(346, 260), inplace=True)  # doctest: +SKIP
    """
    from . import _kernels

    w, h = _check_sensor_size(sensor_size)
    if inplace:
        _check_inplace((t, x, y, p))
    xa, ya = _coords(x, y)
    ta, pa = np.ascontiguousarray(t), np.ascontiguousarray(p)
    if ta.shape != xa.shape or pa.shape != xa.shape:
        raise IbiscapeError(f"t, x, y, p lengths differ: {ta.shape}, {xa.shape}, {ya.shape}, {pa.shape}")
    n = xa.shape[0]
    parts = _threads(n, threads)
    cols = (ta, xa, ya, pa)
    if inplace and parts <= 2 and _simd_coords(xa, ya, w * h, *(a.dtype for a in cols)):
        return _filter_converging(cols, pixels, w, h, parts)
    words, off, bd = _keep_words(xa, ya, pixels, w, h, parts)
    compact: Any = (_kernels.compact_simd if _kernels.simd_ok(*(a.dtype for a in cols))
                    else _kernels.compact_into)
    if inplace:
        return _compact_inplace(cols, words, off, bd, compact)
    # exactly sized outputs, allocated by numpy, which asks for transparent huge pages: their
    # first write costs 57-74 ms per 600 MB against 280 ms for 4 KiB pages (numba's allocator),
    # though where memory is fragmented it can stall in page compaction (median 590 ms at load
    # 22 in session 8, numba's 330 ms: numpy's own filtering pays the same); the first write
    # happens in the threads, which share that cost
    outs = tuple(np.empty(off[-1], a.dtype) for a in cols)

    def run(c: int, _: int) -> None:
        a, b = bd[c], bd[c + 1]
        compact(*(col[a:b] for col in cols), words[a // 64:], *outs, off[c], off[c + 1])

    _in_parts(run, parts, parts)
    to, xo, yo, po = outs
    return to, xo, yo, po


def _filter_converging(cols: tuple[np.ndarray, ...], pixels: npt.ArrayLike, w: int, h: int,
                       parts: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Filter ``cols`` in place in one pass (no keep bits of the whole stream, no copies): on
    one thread packed from index 0 on (``_kernels.filter_up``); on two, the slices converge on
    their boundary ``b`` (a multiple of 64): the first is compacted backwards, its kept events
    packed against ``b`` (``_kernels.filter_down``), the second forwards from ``b`` on, so the
    kept events lie contiguous in ``[b - k0, b + k1)``, in order.  Each kernel tests the hot
    pixels and the sensor bounds as it goes, 64 events at a time, and stops before writing the
    chunk of an event outside the sensor: the first in the stream is then found in the
    untouched part and refused by name (the arrays are left part compacted)."""
    from . import _kernels

    bits = _keep_bits(_hot_flat(pixels, w, h), w, h)
    n = cols[0].shape[0]
    b = _bounds(n, 2, 64)[1] if parts == 2 else 0

    def run(c: int, _: int) -> tuple[int, int]:
        if c == 0:
            return _kernels.filter_down(*(a[:b] for a in cols), w, h, bits)  # type: ignore[call-arg]
        return _kernels.filter_up(*(a[b:] for a in cols), w, h, bits)  # type: ignore[call-arg]

    (start, bad0), (k1, bad1) = _in_parts(run, 2, 2) if b else [(0, -1), run(1, 2)]
    if bad0 >= 0:  # events [0, bad0] untouched: the first outside is among them
        raise _outside(cols[1], cols[2], _first_outside(cols[1][:bad0 + 1], cols[2][:bad0 + 1], w, h), w, h)
    if bad1 >= 0:
        raise _outside(cols[1], cols[2], b + int(bad1), w, h)
    to, xo, yo, po = (a[int(start):b + int(k1)] for a in cols)
    return to, xo, yo, po


def _compact_inplace(cols: tuple[np.ndarray, ...], words: np.ndarray, off: list[int],
                     bd: list[int], compact: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Compact ``cols`` into themselves: slice ``c`` (``[bd[c], bd[c + 1])``, see
    :func:`_keep_words`) to ``[off[c], off[c + 1])``.  A slice writes at or before the places
    it reads, so one slice alone is safe; but the slices after ``c`` write from ``off[c + 1]``
    on, over slice ``c``'s own input ``[off[c + 1], end of slice c)`` before slice ``c`` may
    have read it: that tail (from a multiple of 64 on, where a keep word starts) is copied
    first and slice ``c`` reads it from the copy."""
    n, k, parts = cols[0].shape[0], off[-1], len(off) - 1
    cut = [max(off[c + 1], bd[c]) // 64 * 64 for c in range(parts - 1)] + [n]
    n_saved = sum(bd[c + 1] - cut[c] for c in range(parts))
    if parts == 1 or n_saved > k:
        compact(*cols, words, *cols, 0, k)
    else:
        tails = [tuple(a[cut[c]:bd[c + 1]].copy() for a in cols) for c in range(parts - 1)]

        def run(c: int, _: int) -> None:
            end = off[c + 1]
            kk = compact(*(col[bd[c]:cut[c]] for col in cols), words[bd[c] // 64:], *cols, off[c], end)
            if c < parts - 1:
                compact(*tails[c], words[cut[c] // 64:], *cols, kk, end)

        _in_parts(run, parts, parts)
    to, xo, yo, po = (a[:k] for a in cols)
    return to, xo, yo, po


def rate_hot_pixels(
    t_ns: npt.ArrayLike,
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    *,
    sensor_size: tuple[int, int],
    min_events: int,
    window_ns: int,
) -> npt.NDArray[np.int64]:
    """libcaer's rate criterion: pixels that fire at least ``min_events`` events within one
    window of ``window_ns`` ns (consecutive windows from the first event; libcaer learns over
    one window, here every window of the recording counts).

    Returns
    -------
    ndarray, shape (K, 2), int64
        Hot pixels as x, y, in row-major order.
    """
    acc = PixelCounter(sensor_size=sensor_size, rate_min_events=min_events, rate_window_ns=window_ns)
    acc.add(Events(np.asarray(t_ns), np.asarray(x), np.asarray(y), np.zeros(np.shape(x), bool)))
    return acc.rate_pixels()


class PixelCounter:
    """Streaming per-pixel counts (and the rate statistic) over a recording read in chunks.

    Parameters
    ----------
    sensor_size : (int, int), optional
        Width, height.  If None the sensor grows to the largest coordinate seen.
    per_polarity : bool
        Keep one count map per polarity.
    rate_min_events, rate_window_ns : int, optional
        Enable the libcaer-like rate criterion.
    """

    def __init__(
        self,
        *,
        sensor_size: tuple[int, int] | None = None,
        per_polarity: bool = False,
        rate_min_events: int | None = None,
        rate_window_ns: int | None = None,
    ) -> None:
        self.fixed = sensor_size is not None
        self.w, self.h = _check_sensor_size(sensor_size) if sensor_size is not None else (0, 0)
        self.per_polarity = per_polarity
        if (rate_min_events is None) != (rate_window_ns is None):
            raise IbiscapeError("the rate criterion needs both a minimum event count and a window")
        if rate_window_ns is not None and (int(rate_window_ns) <= 0 or int(rate_min_events or 0) < 1):
            raise IbiscapeError(
                f"rate criterion: window must be > 0 ns and min events >= 1, got "
                f"{rate_window_ns} ns, {rate_min_events}"
            )
        self.rate_min = rate_min_events
        self.rate_window_ns = rate_window_ns
        self.n_events = 0
        self._planes = 2 if per_polarity else 1
        self._counts = np.zeros((self._planes, self.h, self.w), np.int64)
        # chunks are counted into one padded uint32 accumulator (no allocation per chunk),
        # folded into the int64 counts before it could overflow
        self._acc = np.zeros(self._planes * self.h * (self.w + _PAD), np.uint32)
        self._acc_n = 0
        self._t0: int | None = None
        self._rate_state: list[np.ndarray] = []
        if rate_window_ns is not None:
            self._rate_state = self._new_rate_state(self.h, self.w)

    @staticmethod
    def _new_rate_state(h: int, w: int) -> list[np.ndarray]:
        return [np.full(h * w, -1, np.int64), np.zeros(h * w, np.int64), np.zeros(h * w, np.int64)]

    def _flush(self) -> None:
        if self._acc_n:
            self._counts += self._acc.reshape(self._planes, self.h, self.w + _PAD)[:, :, : self.w]
            self._acc[:] = 0
            self._acc_n = 0

    def _grow(self, w: int, h: int) -> None:
        self._flush()
        self._acc = np.zeros(self._planes * h * (w + _PAD), np.uint32)
        counts = np.zeros((self._planes, h, w), np.int64)
        counts[:, : self.h, : self.w] = self._counts
        if self._rate_state:
            new = self._new_rate_state(h, w)
            for old, nw in zip(self._rate_state, new, strict=True):
                nw.reshape(h, w)[: self.h, : self.w] = old.reshape(self.h, self.w)
            self._rate_state = new
        self._counts, self.w, self.h = counts, w, h

    def _outside(self, events: Events, i: int, chunk: EventChunk | None) -> IbiscapeError:
        msg = (f"pixel (x={int(events.x[i])}, y={int(events.y[i])}) lies outside the "
               f"{self.w}x{self.h} sensor; pass the right {{0}}")
        hint = (Remedy("sensor_size"),)
        if chunk is not None:
            path, line, what = chunk.where(i)
            return FormatError(path, f"{what}: {msg}", line=line, hint=hint)
        return IbiscapeError(f"event {self.n_events + i}: {msg}", hint=hint)

    def add(self, events: Events, chunk: EventChunk | None = None) -> None:
        """Count a chunk.  Out-of-sensor coordinates raise :class:`FormatError` naming the file
        (and line) when ``chunk`` is given (and nothing of the chunk is counted)."""
        from . import _kernels

        n = len(events)
        if n == 0:
            return
        if not self.fixed:
            mw, mh = int(events.x.max()) + 1, int(events.y.max()) + 1
            if mw > self.w or mh > self.h:
                self._grow(max(mw, self.w), max(mh, self.h))
        bad = _first_outside(events.x, events.y, self.w, self.h)
        if bad >= 0:
            raise self._outside(events, bad, chunk)
        if self._acc_n + n >= 2**32 - 1:
            self._flush()
        stride = self.w + _PAD
        if n >= 2**32 - 1:  # one chunk beyond uint32: count it apart
            part = _count_padded(events.x, events.y, events.p if self.per_polarity else None,
                                 self.w, self.h)
            assert not isinstance(part, int)
            self._counts += part
        elif self.per_polarity:
            _kernels.count_xyp(events.x, events.y, events.p, self.w, self.h, stride, self._acc)
            self._acc_n += n
        else:
            _kernels.count_inside(events.x, events.y, stride, self._acc)
            self._acc_n += n
        if self._rate_state:
            if self._t0 is None:
                self._t0 = int(events.t_ns[0])
            _kernels.rate_max(events.t_ns, events.x, events.y, self.w, self._t0,
                              int(self.rate_window_ns or 1), *self._rate_state)
        self.n_events += n

    @property
    def count_map(self) -> npt.NDArray[np.int64]:
        """(H, W) or, per polarity, (2, H, W) counts so far."""
        self._flush()
        return self._counts[0] if self._planes == 1 else self._counts

    @property
    def sensor_size(self) -> tuple[int, int]:
        return self.w, self.h

    def rate_pixels(self) -> npt.NDArray[np.int64]:
        """Pixels meeting the rate criterion so far, as (K, 2) x, y."""
        if not self._rate_state:
            return np.empty((0, 2), np.int64)
        flat = np.flatnonzero(self._rate_state[2] >= int(self.rate_min or 0))
        return np.stack([flat % self.w, flat // self.w], axis=1).astype(np.int64)

    def result(self, *, top_n: int | None = None, n_sigma: float | None = None) -> HotPixelResult:
        """Hot pixels from everything counted (ranking / threshold / rate criteria, union)."""
        extra = self.rate_pixels() if self._rate_state else None
        return hot_pixels_from_counts(self.count_map, top_n=top_n, n_sigma=n_sigma, extra_pixels=extra)


def iter_filtered(
    chunks: Iterable[EventChunk], pixels: npt.ArrayLike, *, sensor_size: tuple[int, int]
) -> Iterable[tuple[EventChunk, Events]]:
    """Filter a stream chunk by chunk: yields each input chunk with its filtered events."""
    for chunk in chunks:
        yield chunk, filter_events(chunk.events, pixels, sensor_size=sensor_size)
