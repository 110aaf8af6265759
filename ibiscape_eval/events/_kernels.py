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
def first_decrease(t, prev):
    """Index of the first ``t[i] < t[i-1]`` (``t[-1]`` taken as ``prev``), or -1."""
    last = prev
    for i in range(t.shape[0]):
        if t[i] < last:
            return i
        last = t[i]
    return -1


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


# --------------------------------------------------------------------------------------------
# rpg / ESIM text: "t x y p" per line, t in decimal seconds, parsed exactly into int64 ns.
# --------------------------------------------------------------------------------------------

TEXT_ERRORS = {
    1: "expected the timestamp in decimal seconds as the first column (t x y p)",
    2: "expected x as a non-negative integer below 65536 in the second column (t x y p)",
    3: "expected y as a non-negative integer below 65536 in the third column (t x y p)",
    4: "expected the polarity 0, 1 or -1 in the fourth column (t x y p)",
    5: "more than four columns; expected t x y p",
    6: "fewer than four columns; expected t x y p",
}


@njit(cache=True, nogil=True)
def _skip_blanks(buf, i, end):
    while i < end and (buf[i] == 32 or buf[i] == 9 or buf[i] == 44 or buf[i] == 13):
        i += 1
    return i


@njit(cache=True, nogil=True)
def _read_uint(buf, i, end):
    """Parse digits at ``i``; returns (value, next index, ok)."""
    v = np.int64(0)
    start = i
    while i < end and 48 <= buf[i] <= 57:
        v = v * 10 + (buf[i] - 48)
        if v > 65535:
            return v, i, False
        i += 1
    return v, i, i > start


@njit(cache=True, nogil=True)
def parse_text(buf, first_line, t_out, x_out, y_out, p_out, line_out):
    """Parse complete lines in ``buf`` (uint8).  Returns ``(n_events, n_lines, err, err_line)``;
    ``err`` is 0 or a key of :data:`TEXT_ERRORS`.  Columns are separated by blanks or commas."""
    n = 0
    line = first_line
    i = 0
    end = buf.shape[0]
    while i < end:
        # one line: [i, eol)
        eol = i
        while eol < end and buf[eol] != 10:
            eol += 1
        j = _skip_blanks(buf, i, eol)
        if j < eol and buf[j] != 35:  # not blank, not a '#' comment
            # timestamp: digits [. digits], exact to the nanosecond (further digits truncated)
            sec = np.int64(0)
            nd = 0
            while j < eol and 48 <= buf[j] <= 57:
                sec = sec * 10 + (buf[j] - 48)
                j += 1
                nd += 1
                if nd > 10:
                    return n, line - first_line, 1, line
            frac = np.int64(0)
            nf = 0
            if j < eol and buf[j] == 46:
                j += 1
                while j < eol and 48 <= buf[j] <= 57:
                    if nf < 9:
                        frac = frac * 10 + (buf[j] - 48)
                    nf += 1
                    j += 1
            if nd + nf == 0 or (j < eol and not (buf[j] == 32 or buf[j] == 9 or buf[j] == 44)):
                return n, line - first_line, 1, line
            for _ in range(9 - min(nf, 9)):
                frac *= 10
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, 6, line
            xv, j, ok = _read_uint(buf, j, eol)
            if not ok or (j < eol and not (buf[j] == 32 or buf[j] == 9 or buf[j] == 44)):
                return n, line - first_line, 2, line
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, 6, line
            yv, j, ok = _read_uint(buf, j, eol)
            if not ok or (j < eol and not (buf[j] == 32 or buf[j] == 9 or buf[j] == 44)):
                return n, line - first_line, 3, line
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, 6, line
            neg = False
            if buf[j] == 45:
                neg = True
                j += 1
            if j >= eol or not (buf[j] == 48 or buf[j] == 49):
                return n, line - first_line, 4, line
            pv = buf[j] == 49 and not neg
            if neg and buf[j] != 49:
                return n, line - first_line, 4, line
            j += 1
            if j < eol and not (buf[j] == 32 or buf[j] == 9 or buf[j] == 44 or buf[j] == 13):
                return n, line - first_line, 4, line
            j = _skip_blanks(buf, j, eol)
            if j < eol:
                return n, line - first_line, 5, line
            t_out[n] = sec * 1_000_000_000 + frac
            x_out[n] = xv
            y_out[n] = yv
            p_out[n] = pv
            line_out[n] = line
            n += 1
        i = eol + 1
        line += 1
    return n, line - first_line, 0, 0


@njit(cache=True, nogil=True)
def _put_uint(out, k, v):
    if v == 0:
        out[k] = 48
        return k + 1
    digits = 0
    w = v
    while w > 0:
        w //= 10
        digits += 1
    for d in range(digits - 1, -1, -1):
        out[k + d] = 48 + v % 10
        v //= 10
    return k + digits


@njit(cache=True, nogil=True)
def format_text(t, x, y, p, out):
    """Write ``"<s>.<9 digits> x y p\\n"`` per event into ``out`` (uint8, large enough:
    41 bytes per event); return the number of bytes written.  ``t`` must be >= 0."""
    k = 0
    for i in range(t.shape[0]):
        sec = t[i] // 1_000_000_000
        frac = t[i] - sec * 1_000_000_000
        k = _put_uint(out, k, sec)
        out[k] = 46
        k += 1
        for d in range(8, -1, -1):
            out[k + d] = 48 + frac % 10
            frac //= 10
        k += 9
        out[k] = 32
        k = _put_uint(out, k + 1, np.int64(x[i]))
        out[k] = 32
        k = _put_uint(out, k + 1, np.int64(y[i]))
        out[k] = 32
        out[k + 1] = 49 if p[i] else 48
        out[k + 2] = 10
        k += 3
    return k
