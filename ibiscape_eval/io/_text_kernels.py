"""numba kernels of :mod:`ibiscape_eval.io._text` (imported lazily: numba is heavy).

``scan`` walks the bytes of a text table once; see ``_text.py`` for the accepted syntax.
"""

# mypy: ignore-errors
from __future__ import annotations

import numpy as np
from numba import njit

_NCOLS, _NOTNUM, _NUL = 1, 2, 3

NAN_W = np.array([ord(c) for c in "nan"], dtype=np.uint8)
INF_W = np.array([ord(c) for c in "inf"], dtype=np.uint8)
INFTY_W = np.array([ord(c) for c in "infinity"], dtype=np.uint8)
# the largest mantissa that can take one more digit without overflowing int64
MANT_LIMIT = 922337203685477579
EXACT_POW = np.array([10.0**k for k in range(23)])


@njit(cache=True, nogil=True, error_model="numpy")
def is_sep(c):
    return c == 32 or c == 9 or c == 44 or c == 13


@njit(cache=True, nogil=True, error_model="numpy")
def lower(c):
    return c + 32 if 65 <= c <= 90 else c


@njit(cache=True, nogil=True, error_model="numpy")
def word_is(buf, s, e, word):
    if e - s != len(word):
        return False
    for k in range(e - s):  # noqa: SIM110 (numba has no generator expressions)
        if lower(buf[s + k]) != word[k]:
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def parse_number(buf, s, e):
    """Return (ok, value, mantissa, exp10, finite) of the token buf[s:e]."""
    i = s
    neg = False
    if i < e and (buf[i] == 45 or buf[i] == 43):
        neg = buf[i] == 45
        i += 1
    if i < e and (lower(buf[i]) == 110 or lower(buf[i]) == 105):  # n / i
        if word_is(buf, i, e, NAN_W):
            return True, np.nan, 0, 0, False
        if word_is(buf, i, e, INF_W) or word_is(buf, i, e, INFTY_W):
            return True, (-np.inf if neg else np.inf), 0, 0, False
        return False, 0.0, 0, 0, False
    mant = np.int64(0)
    exp10 = 0
    dropped = -1
    d0 = i
    while i < e and 48 <= buf[i] <= 57:
        if mant <= MANT_LIMIT:
            mant = mant * 10 + (buf[i] - 48)
        else:
            if dropped < 0:
                dropped = buf[i] - 48
            exp10 += 1
        i += 1
    ndig = i - d0
    if i < e and buf[i] == 46:  # '.'
        i += 1
        d0 = i
        while i < e and 48 <= buf[i] <= 57:
            if mant <= MANT_LIMIT:
                mant = mant * 10 + (buf[i] - 48)
                exp10 -= 1
            elif dropped < 0:
                dropped = buf[i] - 48
            i += 1
        ndig += i - d0
    seen = ndig > 0
    if not seen:
        return False, 0.0, 0, 0, False
    if i < e and (buf[i] == 101 or buf[i] == 69):  # e / E
        i += 1
        eneg = False
        if i < e and (buf[i] == 45 or buf[i] == 43):
            eneg = buf[i] == 45
            i += 1
        if i >= e:
            return False, 0.0, 0, 0, False
        ev = 0
        while i < e and 48 <= buf[i] <= 57:
            if ev < 100000:
                ev = ev * 10 + (buf[i] - 48)
            i += 1
        exp10 += -ev if eneg else ev
    if i != e:
        return False, 0.0, 0, 0, False
    if dropped >= 5 and mant < 9223372036854775807:
        mant += 1
    if mant == 0:
        v = 0.0
    elif mant < 9007199254740992 and -22 <= exp10 <= 22:
        v = mant * EXACT_POW[exp10] if exp10 >= 0 else mant / EXACT_POW[-exp10]
    elif exp10 < 0:
        v = mant / 10.0 ** (-exp10) if exp10 >= -308 else mant * 1e-300 * 10.0 ** (exp10 + 300)
    else:
        v = mant * 10.0**exp10 if exp10 <= 400 else np.inf
    if neg:
        v = -v
        mant = -mant
    return True, v, mant, exp10, np.isfinite(v)


@njit(cache=True, nogil=True, error_model="numpy")
def scan(buf, nkeep, ncols_min, ncols_max):
    n = buf.shape[0]
    nmax = 1
    for k in range(n):
        if buf[k] == 10:
            nmax += 1
    vals = np.empty((nmax, nkeep))
    mant = np.zeros(nmax, dtype=np.int64)
    exps = np.zeros(nmax, dtype=np.int32)
    finite = np.ones(nmax, dtype=np.bool_)
    lines = np.empty(nmax, dtype=np.int64)
    status = np.zeros(6, dtype=np.int64)  # code, line, column, token start, token end, ncols
    i = 0
    line = 0
    row = 0
    while i < n:
        line += 1
        col = 0
        while i < n:  # one line, single pass over its bytes
            c = buf[i]
            if c == 10:
                break
            if c == 35:  # '#': comment to the end of the line
                while i < n and buf[i] != 10:
                    i += 1
                break
            if c == 32 or c == 44 or c == 9 or c == 13:
                i += 1
                continue
            s = i
            while i < n:
                c = buf[i]
                if c == 32 or c == 44 or c == 10 or c == 9 or c == 13 or c == 35:
                    break
                if c == 0:
                    status[0] = _NUL
                    status[1] = line
                    return 0, vals, mant, exps, finite, lines, status
                i += 1
            col += 1
            if col <= nkeep:
                ok, v, m, ex, fin = parse_number(buf, s, i)
                if not ok:
                    status[0] = _NOTNUM
                    status[1] = line
                    status[2] = col
                    status[3] = s
                    status[4] = i
                    return 0, vals, mant, exps, finite, lines, status
                vals[row, col - 1] = v
                if not fin:
                    finite[row] = False
                if col == 1:
                    mant[row] = m
                    exps[row] = ex
        i += 1  # past the newline
        if col == 0:
            continue
        if col < ncols_min or col > ncols_max:
            status[0] = _NCOLS
            status[1] = line
            status[5] = col
            return 0, vals, mant, exps, finite, lines, status
        lines[row] = line
        row += 1
    return row, vals, mant, exps, finite, lines, status


# -- writing -----------------------------------------------------------------------------------
INT_POW = np.array([10**k for k in range(19)], dtype=np.int64)


@njit(cache=True, nogil=True, error_model="numpy")
def write_uint(out, pos, v, width):
    """Write the non-negative int ``v``, zero-padded to ``width`` digits; return the new pos."""
    nd = 1
    while nd < 19 and v >= INT_POW[nd]:
        nd += 1
    if nd < width:
        for _ in range(width - nd):
            out[pos] = 48
            pos += 1
    for k in range(nd - 1, -1, -1):
        out[pos] = 48 + (v // INT_POW[k]) % 10
        pos += 1
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def write_float(out, pos, x):
    """Write ``x`` with 15 significant digits, trailing zeros stripped (like ``%.15g``, but fixed
    notation for exponents in [-5, 15)); return the new pos."""
    if x == 0.0 or not np.isfinite(x):
        if np.isnan(x):
            out[pos] = 110
            out[pos + 1] = 97
            out[pos + 2] = 110
            return pos + 3
        if np.isinf(x):
            if x < 0:
                out[pos] = 45
                pos += 1
            out[pos] = 105
            out[pos + 1] = 110
            out[pos + 2] = 102
            return pos + 3
        out[pos] = 48
        return pos + 1
    if x < 0.0:
        out[pos] = 45
        pos += 1
        x = -x
    e = int(np.floor(np.log10(x)))
    m = 0
    for _ in range(3):  # log10 may be off by one near powers of ten
        s = 14 - e
        if 0 <= s <= 22:
            f = x * EXACT_POW[s]
        elif -22 <= s < 0:
            f = x / EXACT_POW[-s]
        else:
            f = x * 10.0**s
        m = np.int64(np.rint(f))
        if m >= INT_POW[15]:
            e += 1
        elif m < INT_POW[14]:
            e -= 1
        else:
            break
    if m >= INT_POW[15]:  # rounding carried into a 16th digit
        m = m // 10
        e += 1
    digits = np.empty(15, dtype=np.uint8)
    for k in range(15):
        digits[14 - k] = m % 10
        m //= 10
    nd = 15
    while nd > 1 and digits[nd - 1] == 0:
        nd -= 1
    if -5 <= e < 15:
        if e >= 0:
            for k in range(e + 1):
                out[pos] = 48 + (digits[k] if k < nd else 0)
                pos += 1
            if nd > e + 1:
                out[pos] = 46
                pos += 1
                for k in range(e + 1, nd):
                    out[pos] = 48 + digits[k]
                    pos += 1
        else:
            out[pos] = 48
            out[pos + 1] = 46
            pos += 2
            for _ in range(-e - 1):
                out[pos] = 48
                pos += 1
            for k in range(nd):
                out[pos] = 48 + digits[k]
                pos += 1
    else:
        out[pos] = 48 + digits[0]
        pos += 1
        if nd > 1:
            out[pos] = 46
            pos += 1
            for k in range(1, nd):
                out[pos] = 48 + digits[k]
                pos += 1
        out[pos] = 101
        pos += 1
        out[pos] = 45 if e < 0 else 43
        pos += 1
        pos = write_uint(out, pos, abs(e), 2)
    return pos


@njit(cache=True, nogil=True, error_model="numpy")
def format_rows(stamps_ns, values, stamp_mode, sep, row_end):
    """Format rows as text.

    stamp_mode: 0 none, 1 int ns, 2 seconds ``%d.%09d``, 3 ns as ``%d.000000`` (CARLA's ``%f``).
    ``sep`` is the separator byte, ``row_end`` the bytes that end a row (e.g. `` \\n``).
    """
    n, k = values.shape
    out = np.empty(n * (32 + 26 * k + row_end.shape[0]), dtype=np.uint8)
    pos = 0
    for i in range(n):
        if stamp_mode != 0:
            t = stamps_ns[i]
            if t < 0:
                out[pos] = 45
                pos += 1
                t = -t
            if stamp_mode == 2:
                pos = write_uint(out, pos, t // 1000000000, 1)
                out[pos] = 46
                pos += 1
                pos = write_uint(out, pos, t % 1000000000, 9)
            else:
                pos = write_uint(out, pos, t, 1)
                if stamp_mode == 3:
                    out[pos] = 46
                    pos += 1
                    for _ in range(6):
                        out[pos] = 48
                        pos += 1
        for j in range(k):
            if j > 0 or stamp_mode != 0:
                out[pos] = sep
                pos += 1
            pos = write_float(out, pos, values[i, j])
        for b in range(row_end.shape[0]):
            out[pos] = row_end[b]
            pos += 1
    return out[:pos]
