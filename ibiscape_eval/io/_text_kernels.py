"""numba kernels of :mod:`ibiscape_eval.io._text` (imported lazily: numba is heavy).

``scan`` walks the bytes of a text table once; see ``_text.py`` for the accepted syntax.
"""

# mypy: ignore-errors
# ruff: noqa: SIM109  (chained == on a byte compiles to plain compares in numba; keep them)
from __future__ import annotations

import numpy as np
from numba import njit

_NCOLS, _NOTNUM, _NUL = 1, 2, 3

NAN_W = np.array([ord(c) for c in "nan"], dtype=np.uint8)
INF_W = np.array([ord(c) for c in "inf"], dtype=np.uint8)
INFTY_W = np.array([ord(c) for c in "infinity"], dtype=np.uint8)
# the largest mantissa that can take one more digit without overflowing int64
MANT_LIMIT = 922337203685477579
# Bytes the tokenizer compares against (numba folds these module globals into constants).
TAB, NEWLINE, CR, SPACE, HASH, PLUS, COMMA, MINUS, DOT = (ord(c) for c in "\t\n\r #+,-.")
DIGIT_0, DIGIT_9 = ord("0"), ord("9")
UPPER_A, UPPER_Z, UPPER_E, LOWER_A, LOWER_E = ord("A"), ord("Z"), ord("E"), ord("a"), ord("e")
LOWER_I, LOWER_N = ord("i"), ord("n")

EXACT_POW = np.array([10.0**k for k in range(23)])


@njit(cache=True, nogil=True, error_model="numpy")
def lower(c):
    return c + (LOWER_A - UPPER_A) if UPPER_A <= c <= UPPER_Z else c


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
    if i < e and (buf[i] == MINUS or buf[i] == PLUS):
        neg = buf[i] == MINUS
        i += 1
    if i < e and (lower(buf[i]) == LOWER_N or lower(buf[i]) == LOWER_I):  # n / i
        if word_is(buf, i, e, NAN_W):
            return True, np.nan, 0, 0, False
        if word_is(buf, i, e, INF_W) or word_is(buf, i, e, INFTY_W):
            return True, (-np.inf if neg else np.inf), 0, 0, False
        return False, 0.0, 0, 0, False
    mant = np.int64(0)
    exp10 = 0
    dropped = -1
    d0 = i
    while i < e and DIGIT_0 <= buf[i] <= DIGIT_9:
        if mant <= MANT_LIMIT:
            mant = mant * 10 + (buf[i] - DIGIT_0)
        else:
            if dropped < 0:
                dropped = buf[i] - DIGIT_0
            exp10 += 1
        i += 1
    ndig = i - d0
    if i < e and buf[i] == DOT:  # '.'
        i += 1
        d0 = i
        while i < e and DIGIT_0 <= buf[i] <= DIGIT_9:
            if mant <= MANT_LIMIT:
                mant = mant * 10 + (buf[i] - DIGIT_0)
                exp10 -= 1
            elif dropped < 0:
                dropped = buf[i] - DIGIT_0
            i += 1
        ndig += i - d0
    seen = ndig > 0
    if not seen:
        return False, 0.0, 0, 0, False
    if i < e and (buf[i] == LOWER_E or buf[i] == UPPER_E):  # e / E
        i += 1
        eneg = False
        if i < e and (buf[i] == MINUS or buf[i] == PLUS):
            eneg = buf[i] == MINUS
            i += 1
        if i >= e:
            return False, 0.0, 0, 0, False
        ev = 0
        while i < e and DIGIT_0 <= buf[i] <= DIGIT_9:
            if ev < 100000:
                ev = ev * 10 + (buf[i] - DIGIT_0)
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


_NL8 = np.uint64(0x0A0A0A0A0A0A0A0A)
_LOW7 = np.uint64(0x7F7F7F7F7F7F7F7F)
_EVEN = np.uint64(0x00FF00FF00FF00FF)
_SUM16 = np.uint64(0x0001000100010001)
_U7, _U8, _U48 = np.uint64(7), np.uint64(8), np.uint64(48)


@njit(cache=True, nogil=True, error_model="numpy")
def count_newlines(buf, start, stop):
    """Number of ``\\n`` bytes in ``buf[start:stop]``, eight bytes per step."""
    k = 0
    i = start
    while i < stop and i & 7:
        k += buf[i] == NEWLINE
        i += 1
    nw = (stop - i) >> 3
    if nw > 0:
        words = buf[i:i + 8 * nw].view(np.uint64)
        acc = np.uint64(0)  # eight byte-wide counters
        for j in range(nw):
            x = words[j] ^ _NL8  # a zero byte where there was a newline
            acc += ~(((x & _LOW7) + _LOW7) | x | _LOW7) >> _U7
            if (j & 127) == 127:  # flush before a byte counter can overflow
                acc = (acc & _EVEN) + ((acc >> _U8) & _EVEN)
                k += np.int64((acc * _SUM16) >> _U48)
                acc = np.uint64(0)
        acc = (acc & _EVEN) + ((acc >> _U8) & _EVEN)
        k += np.int64((acc * _SUM16) >> _U48)
    for j in range(i + 8 * nw, stop):
        k += buf[j] == NEWLINE
    return k


@njit(cache=True, nogil=True, error_model="numpy")
def token_end(buf, i, status, line):
    """End of the token starting at ``i`` (a separator, newline or ``#``); -1 on a NUL byte."""
    c = buf[i]
    while not (c == SPACE or c == COMMA or c == NEWLINE or c == TAB or c == CR or c == HASH):
        if c == 0:
            status[0] = _NUL
            status[1] = line
            return -1
        i += 1
        c = buf[i]
    return i


# Long on purpose (numba kernel): one state machine over every byte of the file, the fast
# digit loop, the exact-fallback token and the column routing share the loop's local state
# (position, column, row); split into calls, each byte would pay for passing that state back
# and forth, and a jitted helper cannot return early out of the caller's loop on an error.
@njit(cache=True, nogil=True, error_model="numpy")
def scan_lines(buf, start, stop, nkeep, ncols_min, ncols_max, line0, row0,
               vals, vals2, vals3, mant, exps, finite, lines, status):
    """Parse the lines of ``buf[start:stop]`` into rows ``row0, row0 + 1, ...`` of the outputs.

    The kept columns go to three 2-D arrays one after the other: the first ``vals.shape[1]``
    to ``vals``, the next ``vals2.shape[1]`` to ``vals2``, the rest to ``vals3`` (so that, e.g.,
    positions and quaternions land in their own contiguous arrays).

    ``buf[stop - 1]`` must be a newline (so no loop needs a bounds check: every loop stops at
    it).  Lines are numbered from ``line0 + 1``.  Returns the index after the last row written;
    on an error ``status`` holds code, line, column, token start, token end, column count.

    Tokens of the form ``[+-]digits[.digits]`` (at most 19 significant digits, the usual case)
    are converted while they are scanned; anything else goes through :func:`parse_number`, and
    both give the same bits.
    """
    if start < 0 or stop > buf.shape[0]:  # (also lets the compiler drop index wraparound)
        return row0
    w1 = vals.shape[1]
    w12 = w1 + vals2.shape[1]
    i = start
    line = line0
    row = row0
    while i < stop:
        line += 1
        col = 0
        fin = True
        m1 = np.int64(0)
        e1 = 0
        c = buf[i]
        while True:
            while c == SPACE or c == TAB or c == COMMA or c == CR:
                i += 1
                c = buf[i]
            if c == NEWLINE:
                break
            if c == HASH:  # '#': comment to the end of the line
                while c != NEWLINE:
                    i += 1
                    c = buf[i]
                break
            col += 1
            s = i
            if col > nkeep:  # counted, not converted
                i = token_end(buf, i, status, line)
                if i < 0:
                    return row
                c = buf[i]
                continue
            # fast path: [+-]digits[.digits] ended by a separator
            neg = c == MINUS
            if c == MINUS or c == PLUS:
                i += 1
                c = buf[i]
            m = np.int64(0)
            big = False
            d0 = i
            while DIGIT_0 <= c <= DIGIT_9:
                if m <= MANT_LIMIT:
                    m = m * 10 + (c - DIGIT_0)
                else:
                    big = True
                i += 1
                c = buf[i]
            ndig = i - d0
            nfrac = 0
            if c == DOT:  # '.'
                i += 1
                c = buf[i]
                d0 = i
                while DIGIT_0 <= c <= DIGIT_9:
                    if m <= MANT_LIMIT:
                        m = m * 10 + (c - DIGIT_0)
                    else:
                        big = True
                    i += 1
                    c = buf[i]
                nfrac = i - d0
                ndig += nfrac
            if (ndig > 0 and not big and nfrac <= 22
                    and (c == SPACE or c == TAB or c == COMMA or c == NEWLINE or c == CR or c == HASH)):
                v = m / EXACT_POW[nfrac]
                if neg:
                    v = -v
                    m = -m
                ex = -nfrac
            else:  # exponent, nan/inf, a long mantissa or not a number: the general parser
                i = token_end(buf, s, status, line)
                if i < 0:
                    return row
                c = buf[i]
                ok, v, m, ex, vfin = parse_number(buf, s, i)
                if not ok:
                    status[0] = _NOTNUM
                    status[1] = line
                    status[2] = col
                    status[3] = s
                    status[4] = i
                    return row
                if not vfin:
                    fin = False
            if col <= w1:
                vals[row, col - 1] = v
            elif col <= w12:
                vals2[row, col - 1 - w1] = v
            else:
                vals3[row, col - 1 - w12] = v
            if col == 1:
                m1 = m
                e1 = ex
        i += 1  # past the newline
        if col == 0:
            continue
        if col < ncols_min or col > ncols_max:
            status[0] = _NCOLS
            status[1] = line
            status[5] = col
            return row
        mant[row] = m1
        exps[row] = e1
        finite[row] = fin
        lines[row] = line
        row += 1
    return row


@njit(cache=True, nogil=True, error_model="numpy")
def move_rows(vals, vals2, vals3, mant, exps, finite, lines, src, dst, count):
    """Move ``count`` rows from ``src`` down to ``dst <= src`` (in place, front to back)."""
    for r in range(count):
        a = src + r
        b = dst + r
        for j in range(vals.shape[1]):
            vals[b, j] = vals[a, j]
        for j in range(vals2.shape[1]):
            vals2[b, j] = vals2[a, j]
        for j in range(vals3.shape[1]):
            vals3[b, j] = vals3[a, j]
        mant[b] = mant[a]
        exps[b] = exps[a]
        finite[b] = finite[a]
        lines[b] = lines[a]


# -- poses ------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, error_model="numpy")
def pose_rows(stamps, pos, quat, finite, tol, start, stop, pos_out, quat_out):
    """Rows ``start:stop`` of the poses of a table (see ``_poses.finish_trajectory``).

    Writes contiguous positions and unit quaternions with w >= 0 (the :class:`Trajectory`
    convention) to the outputs; returns whether every row is finite, whether the stamps
    increase strictly (including from the row before ``start``), and the first row whose
    quaternion norm is further than ``tol`` from 1 (-1: none).  Rows that are not finite or
    not unit are not written, so the outputs may be the inputs (normalised in place: the rows
    an error message quotes keep their values).
    """
    all_finite = True
    increasing = True
    bad = -1
    for r in range(start, stop):
        if r > 0 and stamps[r] <= stamps[r - 1]:
            increasing = False
        x, y, z = pos[r, 0], pos[r, 1], pos[r, 2]
        qx, qy, qz, qw = quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3]
        if not (finite[r] and np.isfinite(x) and np.isfinite(y) and np.isfinite(z)
                and np.isfinite(qx) and np.isfinite(qy) and np.isfinite(qz) and np.isfinite(qw)):
            all_finite = False
            continue
        norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if not abs(norm - 1.0) <= tol:
            if bad < 0:
                bad = r
            continue
        d = -norm if qw < 0.0 else norm
        pos_out[r, 0] = x
        pos_out[r, 1] = y
        pos_out[r, 2] = z
        quat_out[r, 0] = qx / d
        quat_out[r, 1] = qy / d
        quat_out[r, 2] = qz / d
        quat_out[r, 3] = qw / d
    return all_finite, increasing, bad


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
            out[pos] = DIGIT_0
            pos += 1
    for k in range(nd - 1, -1, -1):
        out[pos] = DIGIT_0 + (v // INT_POW[k]) % 10
        pos += 1
    return pos


# Long on purpose (numba kernel): the special values, the digit extraction and the fixed or
# exponent layout run once per written number in the writer's hot loop; kept in one function
# so the digits stay in registers instead of going through a scratch array between calls.
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
                out[pos] = MINUS
                pos += 1
            out[pos] = 105
            out[pos + 1] = 110
            out[pos + 2] = 102
            return pos + 3
        out[pos] = DIGIT_0
        return pos + 1
    if x < 0.0:
        out[pos] = MINUS
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
        elif s > 300:  # tiny x: 10**s alone would overflow to inf, so scale in two steps
            f = (x * 1e300) * 10.0 ** (s - 300)
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
                out[pos] = DIGIT_0 + (digits[k] if k < nd else 0)
                pos += 1
            if nd > e + 1:
                out[pos] = DOT
                pos += 1
                for k in range(e + 1, nd):
                    out[pos] = DIGIT_0 + digits[k]
                    pos += 1
        else:
            out[pos] = DIGIT_0
            out[pos + 1] = DOT
            pos += 2
            for _ in range(-e - 1):
                out[pos] = DIGIT_0
                pos += 1
            for k in range(nd):
                out[pos] = DIGIT_0 + digits[k]
                pos += 1
    else:
        out[pos] = DIGIT_0 + digits[0]
        pos += 1
        if nd > 1:
            out[pos] = DOT
            pos += 1
            for k in range(1, nd):
                out[pos] = DIGIT_0 + digits[k]
                pos += 1
        out[pos] = LOWER_E
        pos += 1
        out[pos] = MINUS if e < 0 else PLUS
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
                out[pos] = MINUS
                pos += 1
                t = -t
            if stamp_mode == 2:
                pos = write_uint(out, pos, t // 1000000000, 1)
                out[pos] = DOT
                pos += 1
                pos = write_uint(out, pos, t % 1000000000, 9)
            else:
                pos = write_uint(out, pos, t, 1)
                if stamp_mode == 3:
                    out[pos] = DOT
                    pos += 1
                    for _ in range(6):
                        out[pos] = DIGIT_0
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
