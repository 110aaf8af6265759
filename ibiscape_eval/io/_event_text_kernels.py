"""numba kernels of :mod:`ibiscape_eval.io.events`: the rpg/ESIM text tokenizer and formatter, and
the time-order check (imported lazily through :func:`ibiscape_eval.core.lazy.load_kernels`:
numba is heavy).
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
def us_to_ns(t_us, off_ns, lim_us, prev, out):
    """``out[i] = t_us[i] * 1000 + off_ns`` (integer microseconds to int64 ns) in one pass,
    with the range and order checks; returns ``(0, -1)``, ``(1, i)`` for the first stamp with
    ``|t_us| > lim_us`` (beyond int64 ns) or ``(2, i)`` for the first ``out[i] < out[i-1]``
    (``out[-1]`` taken as ``prev``)."""
    order = -1
    last = prev
    for i in range(t_us.shape[0]):
        v = np.int64(t_us[i])
        if v > lim_us or v < -lim_us:
            return 1, i
        t = v * 1000 + off_ns
        if t < last and order < 0:
            order = i
        out[i] = t
        last = t
    if order >= 0:
        return 2, order
    return 0, -1



# --------------------------------------------------------------------------------------------
# rpg / ESIM text: "t x y p" per line, t in decimal seconds, parsed exactly into int64 ns.
# --------------------------------------------------------------------------------------------

# Bytes the parser and formatter look at (numba folds these module globals into constants).
TAB, NEWLINE, CR, SPACE, HASH, COMMA, MINUS, DOT = (ord(c) for c in "\t\n\r #,-.")
DIGIT_0, DIGIT_1, DIGIT_9 = ord("0"), ord("1"), ord("9")

# Error codes of :func:`parse_text` (0 is success), with their messages in :data:`TEXT_ERRORS`.
OK, ERR_TIME, ERR_X, ERR_Y, ERR_POLARITY, ERR_TOO_MANY_COLUMNS, ERR_TOO_FEW_COLUMNS = range(7)

TEXT_ERRORS = {
    ERR_TIME: "expected the timestamp in decimal seconds as the first column (t x y p)",
    ERR_X: "expected x as a non-negative integer below 65536 in the second column (t x y p)",
    ERR_Y: "expected y as a non-negative integer below 65536 in the third column (t x y p)",
    ERR_POLARITY: "expected the polarity 0, 1 or -1 in the fourth column (t x y p)",
    ERR_TOO_MANY_COLUMNS: "more than four columns; expected t x y p",
    ERR_TOO_FEW_COLUMNS: "fewer than four columns; expected t x y p",
}


@njit(cache=True, nogil=True)
def _skip_blanks(buf, i, end):
    while i < end and (buf[i] == SPACE or buf[i] == TAB or buf[i] == COMMA or buf[i] == CR):
        i += 1
    return i


@njit(cache=True, nogil=True)
def _read_uint(buf, i, end):
    """Parse digits at ``i``; returns (value, next index, ok)."""
    v = np.int64(0)
    start = i
    while i < end and DIGIT_0 <= buf[i] <= DIGIT_9:
        v = v * 10 + (buf[i] - DIGIT_0)
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
        while eol < end and buf[eol] != NEWLINE:
            eol += 1
        j = _skip_blanks(buf, i, eol)
        if j < eol and buf[j] != HASH:  # not blank, not a '#' comment
            # timestamp: digits [. digits], exact to the nanosecond (further digits truncated)
            sec = np.int64(0)
            nd = 0
            while j < eol and DIGIT_0 <= buf[j] <= DIGIT_9:
                sec = sec * 10 + (buf[j] - DIGIT_0)
                j += 1
                nd += 1
                if nd > 10:
                    return n, line - first_line, ERR_TIME, line
            frac = np.int64(0)
            nf = 0
            if j < eol and buf[j] == DOT:
                j += 1
                while j < eol and DIGIT_0 <= buf[j] <= DIGIT_9:
                    if nf < 9:
                        frac = frac * 10 + (buf[j] - DIGIT_0)
                    nf += 1
                    j += 1
            if nd + nf == 0 or (j < eol and not (buf[j] == SPACE or buf[j] == TAB or buf[j] == COMMA)):
                return n, line - first_line, ERR_TIME, line
            for _ in range(9 - min(nf, 9)):
                frac *= 10
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, ERR_TOO_FEW_COLUMNS, line
            xv, j, ok = _read_uint(buf, j, eol)
            if not ok or (j < eol and not (buf[j] == SPACE or buf[j] == TAB or buf[j] == COMMA)):
                return n, line - first_line, ERR_X, line
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, ERR_TOO_FEW_COLUMNS, line
            yv, j, ok = _read_uint(buf, j, eol)
            if not ok or (j < eol and not (buf[j] == SPACE or buf[j] == TAB or buf[j] == COMMA)):
                return n, line - first_line, ERR_Y, line
            j = _skip_blanks(buf, j, eol)
            if j >= eol:
                return n, line - first_line, ERR_TOO_FEW_COLUMNS, line
            neg = False
            if buf[j] == MINUS:
                neg = True
                j += 1
            if j >= eol or not (buf[j] == DIGIT_0 or buf[j] == DIGIT_1):
                return n, line - first_line, ERR_POLARITY, line
            pv = buf[j] == DIGIT_1 and not neg
            if neg and buf[j] != DIGIT_1:
                return n, line - first_line, ERR_POLARITY, line
            j += 1
            if j < eol and not (buf[j] == SPACE or buf[j] == TAB or buf[j] == COMMA or buf[j] == CR):
                return n, line - first_line, ERR_POLARITY, line
            j = _skip_blanks(buf, j, eol)
            if j < eol:
                return n, line - first_line, ERR_TOO_MANY_COLUMNS, line
            t_out[n] = sec * 1_000_000_000 + frac
            x_out[n] = xv
            y_out[n] = yv
            p_out[n] = pv
            line_out[n] = line
            n += 1
        i = eol + 1
        line += 1
    return n, line - first_line, OK, 0


@njit(cache=True, nogil=True)
def _put_uint(out, k, v):
    if v == 0:
        out[k] = DIGIT_0
        return k + 1
    digits = 0
    w = v
    while w > 0:
        w //= 10
        digits += 1
    for d in range(digits - 1, -1, -1):
        out[k + d] = DIGIT_0 + v % 10
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
        out[k] = DOT
        k += 1
        for d in range(8, -1, -1):
            out[k + d] = DIGIT_0 + frac % 10
            frac //= 10
        k += 9
        out[k] = SPACE
        k = _put_uint(out, k + 1, np.int64(x[i]))
        out[k] = SPACE
        k = _put_uint(out, k + 1, np.int64(y[i]))
        out[k] = SPACE
        out[k + 1] = DIGIT_1 if p[i] else DIGIT_0
        out[k + 2] = NEWLINE
        k += 3
    return k
