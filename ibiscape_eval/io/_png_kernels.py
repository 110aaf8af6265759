"""numba kernel of :func:`ibiscape_eval.io.images.read_gray`: PNG scanline unfiltering fused with
libpng's RGB-to-grey conversion (imported lazily through a function-level import: numba is heavy).

The grey value is what OpenCV's ``IMREAD_GRAYSCALE`` gives for an RGB PNG: OpenCV asks libpng for
``png_set_rgb_to_gray(png, 1, 0.299, 0.587)``, which libpng turns into the 15-bit fixed-point
weights ``red = 29900 * 32768 / 100000 = 9797``, ``green = 58700 * 32768 / 100000 = 19234``,
``blue = 32768 - red - green = 3737`` and applies with truncation, ``(9797 R + 19234 G + 3737 B)
>> 15`` (without a gamma table: the PNGs decoded here carry no gAMA/sRGB/iCCP chunk).  The
weights sum to 32768, so a pixel with ``R == G == B`` keeps its value, as libpng's shortcut does.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def _paeth(a, b, c):
    p = a + b - c
    pa = abs(p - a)
    pb = abs(p - b)
    pc = abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    if pb <= pc:
        return b
    return c


@njit(inline="always")
def _pred(f, a, b, c):
    """The PNG filter ``f``'s predictor from the left (a), upper (b) and upper-left (c) bytes."""
    if f == 0:
        return 0
    if f == 1:
        return a
    if f == 2:
        return b
    if f == 3:
        return (a + b) >> 1
    return _paeth(a, b, c)


@njit(inline="always")
def _row_rgb(f, raw, pos, prev, cur, out, y, w):
    """Unfilter one RGB row (filter ``f``, a literal after inlining) into ``cur``, grey into
    ``out[y]``; the three channels run side by side (the left-pixel dependency is per channel)."""
    a0 = a1 = a2 = 0
    c0 = c1 = c2 = 0
    for x in range(w):
        i = 3 * x
        b0 = prev[i]
        b1 = prev[i + 1]
        b2 = prev[i + 2]
        v0 = (raw[pos + i] + _pred(f, a0, b0, c0)) & 255
        v1 = (raw[pos + i + 1] + _pred(f, a1, b1, c1)) & 255
        v2 = (raw[pos + i + 2] + _pred(f, a2, b2, c2)) & 255
        cur[i] = v0
        cur[i + 1] = v1
        cur[i + 2] = v2
        out[y, x] = (9797 * v0 + 19234 * v1 + 3737 * v2) >> 15
        a0, a1, a2 = v0, v1, v2
        c0, c1, c2 = b0, b1, b2


@njit(inline="always")
def _row_grey(f, raw, pos, prev, cur, out, y, w):
    a = 0
    c = 0
    for x in range(w):
        b = prev[x]
        v = (raw[pos + x] + _pred(f, a, b, c)) & 255
        cur[x] = v
        out[y, x] = v
        a = v
        c = b


@njit(inline="always")
def _row(f, rgb, raw, pos, prev, cur, out, y, w):
    if rgb:
        _row_rgb(f, raw, pos, prev, cur, out, y, w)
    else:
        _row_grey(f, raw, pos, prev, cur, out, y, w)


@njit(cache=True, nogil=True)
def unfilter_to_grey(raw, h, w, rgb, out):
    """Inflated scanlines ``raw`` (``h`` rows of a filter byte + ``w`` grey or RGB pixels, 8 bit)
    -> ``out`` (h, w) uint8 grey.  Returns the first row with an unknown filter type, or -1."""
    stride = w * (3 if rgb else 1)
    rows = np.zeros((2, stride), np.int32)
    pos = 0
    for y in range(h):
        f = raw[pos]
        pos += 1
        cur = rows[y & 1]
        prev = rows[(y + 1) & 1]
        if f == 0:  # one call per literal filter: each row loop is compiled without a switch
            _row(0, rgb, raw, pos, prev, cur, out, y, w)
        elif f == 1:
            _row(1, rgb, raw, pos, prev, cur, out, y, w)
        elif f == 2:
            _row(2, rgb, raw, pos, prev, cur, out, y, w)
        elif f == 3:
            _row(3, rgb, raw, pos, prev, cur, out, y, w)
        elif f == 4:
            _row(4, rgb, raw, pos, prev, cur, out, y, w)
        else:
            return y
        pos += stride
    return -1
