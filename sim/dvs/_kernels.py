"""numba kernel of the DVS pixel model (one pass over the pixels per internal render interval).

Imported lazily by :mod:`ibiscape_eval.sim.dvs` (numba is heavy).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: ``last_t`` of a pixel that has not fired yet (no refractory period applies).
NEVER = np.iinfo(np.int64).min


@njit(cache=True, nogil=True)
def _n_crossings(it, itdt, ref, c):
    """Crossings of ``ref + k * pol * c`` (k = 1, 2, ...) strictly past ``it`` and up to ``itdt``."""
    n = 0
    if itdt >= it:
        cross = ref + c
        while cross > it and cross <= itdt:
            n += 1
            cross += c
    else:
        cross = ref - c
        while cross < it and cross >= itdt:
            n += 1
            cross -= c
    return n


@njit(cache=True, nogil=True)
def crossings(l0, l1, ref, last_t, t0_ns, dt_ns, c_pos, c_neg, c_noise, sigma_pos, sigma_neg,
              tolerance, refractory_ns):
    """Events of one interval ``[t0, t0 + dt]`` over which ``L`` moves linearly from ``l0`` to ``l1``.

    Per pixel (ESIM / CARLA DVS): the polarity is the sign of ``l1 - l0``; the threshold ``C``
    (``c_pos`` or ``c_neg``, plus ``sigma * c_noise[i]`` when a sigma is set, clamped at 0.01)
    is fixed for the interval; every level ``ref + k pol C`` crossed strictly after ``l0`` and
    up to ``l1`` emits an event at the linearly interpolated time and becomes the new reference;
    an event closer than ``refractory_ns`` to the pixel's previous event is dropped (its level
    still becomes the reference).  ``ref`` and ``last_t`` are updated in place.

    Returns ``(t_ns, pixel index, polarity)`` in pixel-major order (time-ordered per pixel) and
    the number of events dropped by the refractory period.
    """
    n_pix = l0.shape[0]
    noisy = c_noise.shape[0] == n_pix
    total = 0
    for i in range(n_pix):
        it = l0[i]
        itdt = l1[i]
        if abs(itdt - it) > tolerance:
            pos = itdt >= it
            c = c_pos if pos else c_neg
            if noisy:
                c += (sigma_pos if pos else sigma_neg) * c_noise[i]
                c = max(c, 0.01)
            total += _n_crossings(it, itdt, ref[i], c)
    out_t = np.empty(total, np.int64)
    out_i = np.empty(total, np.int64)
    out_p = np.empty(total, np.bool_)
    k = 0
    dropped = 0
    for i in range(n_pix):
        it = l0[i]
        itdt = l1[i]
        if abs(itdt - it) <= tolerance:
            continue
        pos = itdt >= it
        c = c_pos if pos else c_neg
        if noisy:
            c += (sigma_pos if pos else sigma_neg) * c_noise[i]
            c = max(c, 0.01)
        step = c if pos else -c
        cross = ref[i] + step
        span = itdt - it
        while (pos and cross > it and cross <= itdt) or (not pos and cross < it and cross >= itdt):
            t = t0_ns + np.int64(np.floor((cross - it) / span * dt_ns + 0.5))
            if last_t[i] == NEVER or t - last_t[i] >= refractory_ns:
                out_t[k] = t
                out_i[k] = i
                out_p[k] = pos
                k += 1
                last_t[i] = t
            else:
                dropped += 1
            ref[i] = cross
            cross += step
    return out_t[:k], out_i[:k], out_p[:k], dropped


@njit(cache=True, nogil=True)
def _exponent(x):
    """The biased IEEE exponent of a float64 >= 0 (the order of the values is the order of their
    bit patterns, so the exponent buckets are ordered)."""
    return (x >> np.uint64(52)) & np.uint64(0x7FF)


@njit(cache=True, nogil=True)
def abs_diff_kth(l0, l1, k):
    """The exact ``k``-th smallest (0-based) of ``|l1 - l0|`` (what ``np.partition(d, k)[k]``
    gives), without the full partition: a histogram of the binary exponents finds the bucket that
    holds the ``k``-th value, and only that bucket is partitioned."""
    n = l0.shape[0]
    d = np.empty(n, np.float64)
    for i in range(n):
        d[i] = abs(l1[i] - l0[i])
    bits = d.view(np.uint64)
    hist = np.zeros(2048, np.int64)
    for i in range(n):
        hist[_exponent(bits[i])] += 1
    below = 0
    b = 0
    while below + hist[b] <= k:
        below += hist[b]
        b += 1
    bucket = np.empty(hist[b], np.float64)
    m = 0
    for i in range(n):
        if _exponent(bits[i]) == b:
            bucket[m] = d[i]
            m += 1
    r = k - below
    return np.partition(bucket, r)[r]
