"""numba kernels for the per-event loops numpy cannot express in one pass.

Imported lazily (numba is heavy): only functions that run over events import this module.
Every kernel is a single pass over the events with O(1) work per event and no allocation
proportional to the number of events, so that counting and filtering run at memory speed.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def count_xy(x, y, width, height, stride, counts):
    """Add one to ``counts[y * stride + x]`` per event; return the index of the first event
    outside the sensor (nothing counted from it on) or -1.

    ``stride`` > ``width`` pads the rows: with power-of-two widths, a row of uint32 counters is a
    multiple of 4 KiB, and a vertical edge (same x, many y) then makes every increment alias the
    previous stores in the CPU's 4K store-forwarding check; padding by a cache line avoids that
    (2-3x faster on such streams)."""
    for i in range(x.shape[0]):
        xi = np.int64(x[i])
        yi = np.int64(y[i])
        if xi < 0 or yi < 0 or xi >= width or yi >= height:
            return i
        counts[yi * stride + xi] += 1
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
    """``out[i] = not hot_lut[pixel of event i]``; return the first out-of-sensor index or -1."""
    for i in range(x.shape[0]):
        xi = np.int64(x[i])
        yi = np.int64(y[i])
        if xi < 0 or yi < 0 or xi >= width or yi >= height:
            return i
        out[i] = hot_lut[yi * width + xi] == 0
    return -1


@njit(cache=True, nogil=True)
def compact4(t, x, y, p, keep, to, xo, yo, po):
    """Copy the events with ``keep[i] == 1`` (uint8 view of the keep-mask) into the output
    arrays, in order, in one branch-free pass: every event is written, the write position
    advances only for kept ones.  Returns the number kept.

    The mask comes from :func:`keep_mask` in a separate pass: fusing the LUT lookup into this
    loop puts its load latency on the loop-carried write position and runs 2-3x slower."""
    k = 0
    for i in range(t.shape[0]):
        to[k] = t[i]
        xo[k] = x[i]
        yo[k] = y[i]
        po[k] = p[i]
        k += keep[i]
    return k


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
