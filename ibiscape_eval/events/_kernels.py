"""numba kernels for the per-event loops numpy cannot express in one pass.

Imported lazily (numba is heavy): only functions that run over events import this module.
Every kernel is a single pass over the events with O(1) work per event and no allocation
proportional to the number of events, so that counting and filtering run at memory speed.
"""

from __future__ import annotations

import functools

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


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


@njit(cache=True, nogil=True)
def count_inside(x, y, stride, counts):
    """:func:`count_xy` for coordinates already checked to lie inside the sensor (no test per
    event)."""
    st = np.uint64(stride)
    for i in range(x.shape[0]):
        counts[np.uint64(y[i]) * st + np.uint64(x[i])] += 1


@njit(cache=True, nogil=True)
def count_xy8(x, y, stride, counts, wrapped):
    """:func:`count_xy` into uint8 counters, for coordinates already checked to lie inside the
    sensor (no test per event: 1.4x faster, measured): a quarter of the cache footprint of
    uint32 ones (uint16 ones were 1.4x faster than uint32 on a 1024x1024 sensor, uint8 ones
    1.3x faster again: the 1 MiB of counters stay in the L2 cache).  A counter that wraps
    around to 0 writes its place to the next entry of ``wrapped`` (at most ``len(x) // 256``
    entries), so a count is ``counts`` + 256 x the times its place is listed.  Returns the
    number listed."""
    st = np.uint64(stride)
    n_wraps = 0
    for i in range(x.shape[0]):
        j = np.uint64(y[i]) * st + np.uint64(x[i])
        c = np.uint8(counts[j] + 1)
        counts[j] = c
        if c == 0:
            wrapped[n_wraps] = j
            n_wraps += 1
    return n_wraps


@njit(cache=True, nogil=True)
def fold_rows(counts, width, stride, r0, r1, out):
    """Add the padded counts of every row of ``counts`` (one row of counters per counting
    thread, see :func:`count_xy8`) to rows ``r0:r1`` of the int64 (height, width) ``out``; the
    wrap-arounds are added by :func:`fold_wraps`."""
    for r in range(r0, r1):
        a = r * stride
        for c in range(counts.shape[0]):
            for col in range(width):
                out[r, col] += np.int64(counts[c, a + col])


@njit(cache=True, nogil=True)
def fold_wraps(wrapped, n_wraps, stride, unit, out):
    """Add ``unit`` (the counters' wrap-around: 256 for uint8) to ``out`` for every place
    listed in ``wrapped[c, :n_wraps[c]]``."""
    for c in range(wrapped.shape[0]):
        for k in range(n_wraps[c]):
            j = wrapped[c, k]
            out[j // stride, j % stride] += unit


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
def keep_mask(x, y, width, keep_bits, out):
    """``out[i] = 1`` (uint8) if the pixel of event i is to be kept, else 0, from the bit table
    ``keep_bits`` (uint32 words, bit ``j % 32`` of word ``j // 32`` for pixel ``j = y * width +
    x``; 128 KiB for a megapixel sensor, which stays in the L2 cache where a byte per pixel
    does not: 1.15x faster, measured), for coordinates already checked to lie inside the sensor
    (see :func:`first_outside`): 32-bit pixel indices (``width * height <= 2**32``) and no
    bounds test in the loop, 1.2-1.4x faster than testing every event.  (Counting the kept
    events in this loop stops LLVM from vectorising it: 20 % slower than the separate
    :func:`count_kept` pass, measured.  An AVX-512 gather of the bits, 16 events at a time, is
    1.6x slower than this scalar loop on AMD Zen 4, measured.)"""
    w = np.uint32(width)
    for i in range(x.shape[0]):
        j = np.uint32(y[i]) * w + np.uint32(x[i])
        out[i] = np.uint8((keep_bits[j >> np.uint32(5)] >> (j & np.uint32(31))) & np.uint32(1))


@njit(cache=True, nogil=True)
def first_outside(x, y, width, height):
    """Index of the first event outside the sensor, or -1.  The coordinates are compared as
    unsigned 64-bit numbers: a negative one wraps to a huge value, so one comparison per axis
    checks both bounds."""
    w = np.uint64(width)
    h = np.uint64(height)
    for i in range(x.shape[0]):
        if np.uint64(x[i]) >= w or np.uint64(y[i]) >= h:
            return i
    return -1


@njit(cache=True, nogil=True)
def count_kept(keep):
    """Number of ones in a uint8 keep-mask (a vectorised sum)."""
    k = 0
    for i in range(keep.shape[0]):
        k += keep[i]
    return k


@njit(cache=True, nogil=True)
def compact_into(t, x, y, p, keep, to, xo, yo, po, k, limit):
    """Copy the events with ``keep[i] == 1`` into ``to[k:limit]`` (and the others), in order,
    ``limit - k`` being the number of kept events.  Branch-free: every event is written, the
    write position advances only for kept ones (a place a discarded event took is written again
    by a later kept one; once ``limit`` is reached only discarded events remain).  Returns the
    end.

    The mask comes from :func:`keep_mask` in a separate pass: fusing the LUT lookup into this
    loop puts its load latency on the loop-carried write position and runs 2-3x slower (also
    block by block through a small buffer, measured; with the AVX-512 compaction of
    :func:`compact_simd` too, 2.3x slower in session 8)."""
    n = t.shape[0]
    i = 0
    while i < n and k < limit:
        to[k] = t[i]
        xo[k] = x[i]
        yo[k] = y[i]
        po[k] = p[i]
        k += keep[i]
        i += 1
    return k


def _data_ptr(context, builder, arrty, arr, elem):
    """Pointer to the first element of a numba array, as ``elem*``."""
    data = cgutils.create_struct_proxy(arrty)(context, builder, value=arr).data
    return builder.bitcast(data, elem.as_pointer())


@intrinsic
def _mask64(typingctx, keep, i):
    """The 64 bytes ``keep[i:i + 64]`` as the bits of a uint64 (bit j set if ``keep[i + j]``)."""
    sig = types.uint64(keep, types.int64)

    def codegen(context, builder, signature, args):
        i8 = ir.IntType(8)
        vty = ir.VectorType(i8, 64)
        ptr = builder.gep(_data_ptr(context, builder, signature.args[0], args[0], i8), [args[1]])
        v = builder.load(builder.bitcast(ptr, vty.as_pointer()), align=1)
        m = builder.icmp_unsigned("!=", v, ir.Constant(vty, None))
        return builder.bitcast(m, ir.IntType(64))

    return sig, codegen


@intrinsic
def _compress64(typingctx, src, i, dst, k, bits):
    """AVX-512 compress of ``src[i:i + 64]``: the elements whose bit is set in ``bits`` are
    stored to ``dst[k:]`` in order, as whole 64-byte vectors (``vpcompress{b,w,d,q}`` into a
    register, then a plain store: the memory form is slow on AMD Zen 4), so up to 63 places past
    the kept ones are overwritten.  Returns ``k + popcount(bits)``."""
    sig = types.int64(src, types.int64, dst, types.int64, types.uint64)

    def codegen(context, builder, signature, args):
        srcty, _, dstty, _, _ = signature.args
        s_arr, i_v, d_arr, k, m_v = args
        bits = 8 * context.get_abi_sizeof(context.get_data_type(srcty.dtype))
        lanes = 512 // bits
        ety, i64 = ir.IntType(bits), ir.IntType(64)
        vty, mty = ir.VectorType(ety, lanes), ir.VectorType(ir.IntType(1), lanes)
        sp = _data_ptr(context, builder, srcty, s_arr, ety)
        dp = _data_ptr(context, builder, dstty, d_arr, ety)
        comp = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vty, [vty, vty, mty]),
                                              f"llvm.x86.avx512.mask.compress.v{lanes}i{bits}")
        ctpop = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64]),
                                               "llvm.ctpop.i64")
        for sub in range(64 // lanes):
            ptr = builder.gep(sp, [builder.add(i_v, ir.Constant(i64, sub * lanes))])
            v = builder.load(builder.bitcast(ptr, vty.as_pointer()), align=1)
            sm = m_v
            if lanes < 64:
                sm = builder.lshr(m_v, ir.Constant(i64, sub * lanes))
                sm = builder.and_(sm, ir.Constant(i64, (1 << lanes) - 1))
            mvec = builder.bitcast(builder.trunc(sm, ir.IntType(lanes)) if lanes < 64 else sm, mty)
            c = builder.call(comp, [v, ir.Constant(vty, None), mvec])
            builder.store(c, builder.bitcast(builder.gep(dp, [k]), vty.as_pointer()), align=1)
            k = builder.add(k, builder.call(ctpop, [sm]))
        return k

    return sig, codegen


@njit(cache=True, nogil=True)
def compact_simd(t, x, y, p, keep, to, xo, yo, po, k, limit):
    """:func:`compact_into` with AVX-512 compress stores, 64 events at a time while a whole
    vector still fits before ``limit`` (the rest by :func:`compact_into`).  Only for CPUs with
    AVX512F/BW/VBMI2 and element sizes of 1, 2, 4 or 8 bytes (see :func:`simd_ok`).

    The keep-mask stays a pass of its own: the keep bits of 64 events gathered with AVX-512
    inside this loop (no mask array) ran no faster than the two passes (78 against 83 ms for
    5e7 events, session 9), and the kept count it then needs first took 49 ms on its own.
    In place (outputs = inputs) is safe: every store lands at or before the block just
    loaded."""
    n = t.shape[0]
    i = 0
    while i + 64 <= n and k + 64 <= limit:
        m = _mask64(keep, i)  # type: ignore[call-arg, var-annotated]
        _compress64(t, i, to, k, m)
        _compress64(x, i, xo, k, m)
        _compress64(y, i, yo, k, m)
        k = _compress64(p, i, po, k, m)
        i += 64
    return compact_into(t[i:], x[i:], y[i:], p[i:], keep[i:], to, xo, yo, po, k, limit)


@functools.cache
def _cpu_simd() -> bool:
    import numba
    from llvmlite import binding

    cfg = numba.config
    if getattr(cfg, "CPU_NAME", None) not in (None, "host") or getattr(cfg, "CPU_FEATURES", None):
        return False
    feats = binding.get_host_cpu_features()
    return all(feats.get(f, False) for f in ("avx512f", "avx512bw", "avx512vbmi2"))


def simd_ok(*dtypes: np.dtype) -> bool:
    """Whether :func:`compact_simd` can run here: numba compiles for this CPU (no
    ``NUMBA_CPU_NAME``), the CPU has AVX512F/BW/VBMI2, and every dtype is a plain 1/2/4/8-byte
    number or bool."""
    return _cpu_simd() and all(np.dtype(d).kind in "biuf" and np.dtype(d).itemsize in (1, 2, 4, 8) for d in dtypes)


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
