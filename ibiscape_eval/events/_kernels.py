"""numba kernels for the per-event loops numpy cannot express in one pass.

Imported lazily (numba is heavy): only functions that run over events import this module.
Every kernel is a single pass over the events with O(1) work per event and no allocation
proportional to the number of events, so that counting and filtering run at memory speed.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True)
def count_xy(x, y, width, height, stride, counts):
    """Add one to ``counts[y * stride + x]`` per event; return the index of the first event
    outside the sensor (nothing counted from it on) or -1.

    ``stride`` > ``width`` pads the rows: with power-of-two widths, a row of uint32 counters is a
    multiple of 4 KiB, and a vertical edge (same x, many y) then makes every increment alias the
    previous stores in the CPU's 4K store-forwarding check; padding by a cache line avoids that
    (2-3x faster on such streams).  The coordinates are compared as unsigned 64-bit numbers: a
    negative one wraps to a huge value, so one comparison per axis checks both bounds."""
    w = np.uint64(width)
    h = np.uint64(height)
    st = np.uint64(stride)
    for i in range(x.shape[0]):
        xi = np.uint64(x[i])
        yi = np.uint64(y[i])
        if xi >= w or yi >= h:
            return i
        counts[yi * st + xi] += 1
    return -1


@njit(cache=True, parallel=True)
def count_xy_threads(x, y, width, height, stride, counts, n_parts):
    """:func:`count_xy` in ``n_parts`` contiguous slices counted by the numba threads, each into
    its own row of ``counts`` (shape ``(n_parts, height * stride)``; the caller sums them).
    Returns the first out-of-sensor index or -1 (then the counts are incomplete)."""
    n = x.shape[0]
    bad = np.full(n_parts, -1, np.int64)
    for c in prange(n_parts):
        a = n * c // n_parts
        r = count_xy(x[a : n * (c + 1) // n_parts], y[a : n * (c + 1) // n_parts], width,
                     height, stride, counts[c])
        if r >= 0:
            bad[c] = a + r
    for c in range(n_parts):
        if bad[c] >= 0:
            return bad[c]
    return -1


@njit(cache=True, nogil=True)
def count_xyp(x, y, p, width, height, stride, counts):
    """Per-polarity counts: negative events in ``counts[:plane]``, positive ones in
    ``counts[plane:]`` with ``plane = height * stride`` (see :func:`count_xy`)."""
    plane = height * stride
    for i in range(x.shape[0]):
        xi = np.int64(x[i])
        yi = np.int64(y[i])
        if xi < 0 or yi < 0 or xi >= width or yi >= height:
            return i
        counts[(plane if p[i] else 0) + yi * stride + xi] += 1
    return -1


@njit(cache=True, nogil=True)
def keep_mask(x, y, width, height, hot_lut, out):
    """``out[i] = 1 - hot_lut[pixel of event i]`` (uint8); return the first out-of-sensor index
    or -1.  (Counting the kept events in this loop stops LLVM from vectorising it: 20 % slower
    than the separate :func:`count_kept` pass, measured.)"""
    w = np.uint64(width)
    h = np.uint64(height)
    for i in range(x.shape[0]):
        xi = np.uint64(x[i])
        yi = np.uint64(y[i])
        if xi >= w or yi >= h:
            return i
        out[i] = hot_lut[yi * w + xi] ^ 1
    return -1


@njit(cache=True, nogil=True)
def count_kept(keep):
    """Number of ones in a uint8 keep-mask (a vectorised sum)."""
    k = 0
    for i in range(keep.shape[0]):
        k += keep[i]
    return k


@njit(cache=True, nogil=True)
def compact4(t, x, y, p, keep, to, xo, yo, po):
    """Copy the events with ``keep[i] == 1`` into the output arrays, in order, in one
    branch-free pass: every event is written, the write position advances only for kept ones
    (the outputs need one spare element past the kept events).  Returns the number kept.

    The mask comes from :func:`keep_mask` in a separate pass: fusing the LUT lookup into this
    loop puts its load latency on the loop-carried write position and runs 2-3x slower (also
    block by block through a small buffer, measured)."""
    k = 0
    for i in range(t.shape[0]):
        to[k] = t[i]
        xo[k] = x[i]
        yo[k] = y[i]
        po[k] = p[i]
        k += keep[i]
    return k


@njit(cache=True, parallel=True)
def filter_threads(t, x, y, p, width, height, hot_lut, keep, n_parts):
    """Two-pass parallel filter over ``n_parts`` contiguous slices: the keep-mask and the kept
    count of every slice, then each slice compacted into its place of exactly-sized outputs.
    Returns ``(to, xo, yo, po, bad)`` with ``bad`` the first out-of-sensor index or -1."""
    n = t.shape[0]
    kept = np.zeros(n_parts + 1, np.int64)
    bad = np.full(n_parts, -1, np.int64)
    for c in prange(n_parts):
        a, b = n * c // n_parts, n * (c + 1) // n_parts
        r = keep_mask(x[a:b], y[a:b], width, height, hot_lut, keep[a:b])
        if r >= 0:
            bad[c] = a + r
        else:
            kept[c + 1] = count_kept(keep[a:b])
    for c in range(n_parts):
        if bad[c] >= 0:
            e = np.empty(0, t.dtype), np.empty(0, x.dtype), np.empty(0, y.dtype)
            return e[0], e[1], e[2], np.empty(0, p.dtype), bad[c]
    off = np.cumsum(kept)
    to = np.empty(off[-1] + 1, t.dtype)
    xo = np.empty(off[-1] + 1, x.dtype)
    yo = np.empty(off[-1] + 1, y.dtype)
    po = np.empty(off[-1] + 1, p.dtype)
    for c in prange(n_parts):
        a, b, k = n * c // n_parts, n * (c + 1) // n_parts, off[c]
        compact4(t[a:b], x[a:b], y[a:b], p[a:b], keep[a:b], to[k:], xo[k:], yo[k:], po[k:])
    # a slice's discarded events after its last kept one were written (branch-free) over the
    # first place of the next slice: write each slice's first kept event again
    for c in range(1, n_parts):
        if kept[c + 1] > 0:
            i = n * c // n_parts
            while keep[i] == 0:
                i += 1
            k = off[c]
            to[k] = t[i]
            xo[k] = x[i]
            yo[k] = y[i]
            po[k] = p[i]
    return to, xo, yo, po, np.int64(-1)


@njit(cache=True, nogil=True)
def rate_max(t, x, y, width, t0, window_ns, win_id, cur, best):
    """libcaer-like rate statistic, streamable: for every pixel the largest number of events in
    one of the consecutive windows ``[t0 + k W, t0 + (k+1) W)``.  ``win_id``, ``cur`` (current
    window's count) and ``best`` are per-pixel state arrays carried from chunk to chunk."""
    for i in range(t.shape[0]):
        pix = np.int64(y[i]) * width + np.int64(x[i])
        w = (t[i] - t0) // window_ns
        if win_id[pix] != w:
            win_id[pix] = w
            cur[pix] = 0
        cur[pix] += 1
        if cur[pix] > best[pix]:
            best[pix] = cur[pix]


@njit(cache=True, nogil=True)
def last_time(t, x, y, p, width, last_t, last_p):
    """Latest timestamp (and its polarity) per pixel, updated in place (events sorted by t)."""
    for i in range(t.shape[0]):
        pix = np.int64(y[i]) * width + np.int64(x[i])
        last_t[pix] = t[i]
        last_p[pix] = p[i]
