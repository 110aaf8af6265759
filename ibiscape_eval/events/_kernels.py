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


@intrinsic
def _index64(typingctx, x, y, i, width, height, stride, buf):
    """AVX-512: the counter places ``y * stride + x`` of the uint16 events ``i:i + 64`` into the
    uint32 ``buf[:64]``; returns the events outside the sensor as the bits of a uint64."""
    sig = types.uint64(x, y, types.int64, types.int64, types.int64, types.int64, buf)

    def codegen(context, builder, signature, args):
        xa, ya, iv, wv, hv, sv, ba = args
        i16, i32, i64 = ir.IntType(16), ir.IntType(32), ir.IntType(64)
        v16, v32 = ir.VectorType(i16, 16), ir.VectorType(i32, 16)
        xp = _data_ptr(context, builder, signature.args[0], xa, i16)
        yp = _data_ptr(context, builder, signature.args[1], ya, i16)
        bp = _data_ptr(context, builder, signature.args[6], ba, i32)
        wvec, hvec, svec = (_splat(builder, v32, builder.trunc(v, i32)) for v in (wv, hv, sv))
        out = ir.Constant(i64, 0)
        for g in range(4):
            off = builder.add(iv, ir.Constant(i64, 16 * g))
            xv, yv = (builder.zext(builder.load(builder.bitcast(builder.gep(pt, [off]), v16.as_pointer()),
                                                align=2), v32) for pt in (xp, yp))
            j = builder.add(builder.mul(yv, svec), xv)
            builder.store(j, builder.bitcast(builder.gep(bp, [ir.Constant(i64, 16 * g)]), v32.as_pointer()),
                          align=4)
            bad = builder.or_(builder.icmp_unsigned(">=", xv, wvec), builder.icmp_unsigned(">=", yv, hvec))
            out = builder.or_(out, builder.shl(builder.zext(builder.bitcast(bad, i16), i64),
                                               ir.Constant(i64, 16 * g)))
        return out

    return sig, codegen


@njit(cache=True, nogil=True)
def count_xy8_simd(x, y, width, height, stride, counts, wrapped):
    """:func:`count_xy8` for uint16 coordinates not yet checked: the places and the bounds
    test of 64 events at a time with AVX-512 (:func:`_index64`), then the scalar increments
    (1.3x faster than numpy's bounds check plus :func:`count_xy8`, measured).  Returns the
    index of the first event outside the sensor (or -1) and the number of wrap-arounds listed;
    what was counted before an event outside is left in ``counts``.  Needs AVX-512."""
    n = x.shape[0]
    n_wraps = 0
    buf = np.empty(1024, np.uint32)[512:576]  # 1 KiB either side: no cache line shared with another thread
    nb = n // 64
    for b in range(nb):
        bad = _index64(x, y, b * 64, width, height, stride, buf)  # type: ignore[call-arg, var-annotated]
        if bad:
            return b * 64 + np.int64(_lowest_bit(bad)), n_wraps
        for e in range(64):
            j = buf[e]
            c = np.uint8(counts[j] + 1)
            counts[j] = c
            if c == 0:
                wrapped[n_wraps] = j
                n_wraps += 1
    first = first_outside(x[nb * 64:], y[nb * 64:], width, height)
    if first >= 0:
        return nb * 64 + first, n_wraps
    return -1, n_wraps + count_xy8(x[nb * 64:], y[nb * 64:], stride, counts, wrapped[n_wraps:])


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


def _data_ptr(context, builder, arrty, arr, elem):
    """Pointer to the first element of a numba array, as ``elem*``."""
    data = cgutils.create_struct_proxy(arrty)(context, builder, value=arr).data
    return builder.bitcast(data, elem.as_pointer())


class _CompressVectors:
    """What the two compress codegens (:func:`_compress64`, :func:`_compress64_down`) share:
    the vector and mask types of ``src``'s element size (64 elements = 512 // bits lanes per
    vector, 64 // lanes vectors), the data pointers, and the compress of one vector."""

    def __init__(self, context, builder, signature, args):
        srcty, _, dstty, _, _ = signature.args
        s_arr, self.i_v, d_arr, self.k, self.m_v = args
        bits = 8 * context.get_abi_sizeof(context.get_data_type(srcty.dtype))
        self.builder, self.lanes = builder, 512 // bits
        ety, self.i64 = ir.IntType(bits), ir.IntType(64)
        self.vty, self.mty = ir.VectorType(ety, self.lanes), ir.VectorType(ir.IntType(1), self.lanes)
        self.sp = _data_ptr(context, builder, srcty, s_arr, ety)
        self.dp = _data_ptr(context, builder, dstty, d_arr, ety)
        self.comp = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(self.vty, [self.vty, self.vty, self.mty]),
            f"llvm.x86.avx512.mask.compress.v{self.lanes}i{bits}")
        self.ctpop = cgutils.get_or_insert_function(builder.module, ir.FunctionType(self.i64, [self.i64]),
                                                    "llvm.ctpop.i64")

    def compressed(self, sub):
        """Vector ``sub`` of ``src[i:i + 64]`` compressed in a register by its bits of the mask,
        and those bits (``sm``, an i64)."""
        b, lanes, i64 = self.builder, self.lanes, self.i64
        ptr = b.gep(self.sp, [b.add(self.i_v, ir.Constant(i64, sub * lanes))])
        v = b.load(b.bitcast(ptr, self.vty.as_pointer()), align=1)
        sm = self.m_v
        if lanes < 64:
            sm = b.lshr(self.m_v, ir.Constant(i64, sub * lanes))
            sm = b.and_(sm, ir.Constant(i64, (1 << lanes) - 1))
        mvec = b.bitcast(b.trunc(sm, ir.IntType(lanes)) if lanes < 64 else sm, self.mty)
        return b.call(self.comp, [v, ir.Constant(self.vty, None), mvec]), sm


@intrinsic
def _compress64(typingctx, src, i, dst, k, bits):
    """AVX-512 compress of ``src[i:i + 64]``: the elements whose bit is set in ``bits`` are
    stored to ``dst[k:]`` in order, as whole 64-byte vectors (``vpcompress{b,w,d,q}`` into a
    register, then a plain store: the memory form is slow on AMD Zen 4), so up to 63 places past
    the kept ones are overwritten.  Returns ``k + popcount(bits)``."""
    sig = types.int64(src, types.int64, dst, types.int64, types.uint64)

    def codegen(context, builder, signature, args):
        v = _CompressVectors(context, builder, signature, args)
        vty, dp, k, ctpop = v.vty, v.dp, v.k, v.ctpop
        for sub in range(64 // v.lanes):
            c, sm = v.compressed(sub)
            builder.store(c, builder.bitcast(builder.gep(dp, [k]), vty.as_pointer()), align=1)
            k = builder.add(k, builder.call(ctpop, [sm]))
        return k

    return sig, codegen


@intrinsic
def _popcount(typingctx, v):
    """Set bits of a uint64 (``llvm.ctpop``: one ``popcnt``)."""
    sig = types.int64(types.uint64)

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        f = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64]), "llvm.ctpop.i64")
        return builder.call(f, [args[0]])

    return sig, codegen


@intrinsic
def _lowest_bit(typingctx, v):
    """Index of the lowest set bit of a non-zero uint64 (``llvm.cttz``: one ``tzcnt``)."""
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        f = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64, ir.IntType(1)]),
                                           "llvm.cttz.i64")
        return builder.call(f, [args[0], ir.Constant(ir.IntType(1), 1)])

    return sig, codegen


@njit(cache=True, nogil=True, inline="always")
def _keep_bit(keep_bits, j):
    """Bit ``j`` (uint32, a pixel index ``y * width + x``) of the bit table ``keep_bits`` (uint32
    words, bit ``j % 32`` of word ``j // 32``: 128 KiB for a megapixel sensor, which stays in the
    L2 cache where a byte per pixel does not), as a uint64 0 or 1: 1 if the pixel is kept."""
    return np.uint64((keep_bits[j >> np.uint32(5)] >> (j & np.uint32(31))) & np.uint32(1))


@njit(cache=True, nogil=True)
def keep_words(x, y, width, keep_bits, words):
    """The keep bits of the events (see :func:`_keep_bit`), 64 to a uint64 word: bit ``e`` of
    ``words[b]`` for event ``64 b + e`` (a byte per event costs 8x the memory traffic and a
    pass of its own to count them), for coordinates already checked to lie inside the sensor.
    Returns the number of events kept."""
    w = np.uint32(width)
    n = x.shape[0]
    k = 0
    for b in range((n + 63) // 64):
        i0 = b * 64
        m = np.uint64(0)
        for e in range(min(64, n - i0)):
            m |= _keep_bit(keep_bits, np.uint32(y[i0 + e]) * w + np.uint32(x[i0 + e])) << np.uint64(e)
        words[b] = m
        k += _popcount(m)  # type: ignore[call-arg]
    return k


#: The two multiplicative hashes of a pixel index into the 2048-bit tables of the Bloom filter
#: of :func:`bloom_table` (odd 32-bit constants; the top 11 bits of the product).
BLOOM_MULTIPLIERS = (0x9E3779B1, 0x85EBCA77)


def bloom_table(hot_flat: np.ndarray) -> np.ndarray:
    """The Bloom filter of the pixel indices ``hot_flat`` (``y * width + x``) for
    :func:`keep_words_simd`: two 2048-bit tables, one per hash of :data:`BLOOM_MULTIPLIERS`,
    as 128 uint32 words (two 64-word halves: 8 AVX-512 registers)."""
    j = np.asarray(hot_flat, np.uint64) & np.uint64(0xFFFFFFFF)
    tab = np.zeros(128, np.uint32)
    for q, mult in enumerate(BLOOM_MULTIPLIERS):
        h = ((j * np.uint64(mult)) & np.uint64(0xFFFFFFFF)) >> np.uint64(21)
        np.bitwise_or.at(tab, q * 64 + (h >> np.uint64(5)).astype(np.int64),
                         np.left_shift(np.uint32(1), (h & np.uint64(31)).astype(np.uint32)))
    return tab


def _splat(builder, vty, v):
    u = builder.insert_element(ir.Constant(vty, ir.Undefined), v, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(u, ir.Constant(vty, ir.Undefined), ir.Constant(vty, None))


def _bloom_hit(builder, perm, j, mult, tab4):
    """Lanes whose hash ``(j * mult) >> 21`` hits its bit of the 2048-bit table in the four
    registers ``tab4`` (two ``vpermi2d`` table look-ups and a select, no memory access)."""
    v32 = j.type

    def c(k):
        return ir.Constant(v32, [ir.Constant(ir.IntType(32), k)] * 16)

    h = builder.lshr(builder.mul(j, c(mult)), c(21))
    idx = builder.lshr(h, c(5))
    lo = builder.call(perm, [tab4[0], idx, tab4[1]])
    hi = builder.call(perm, [tab4[2], idx, tab4[3]])
    word = builder.select(builder.icmp_unsigned("!=", builder.and_(idx, c(32)), c(0)), hi, lo)
    bit = builder.and_(builder.lshr(word, builder.and_(h, c(31))), c(1))
    return builder.icmp_unsigned("!=", bit, c(0))


@intrinsic
def _bloom64(typingctx, x, y, i, width, height, tab):
    """AVX-512 test of the uint16 events ``i:i + 64``: bit ``e`` of the uint64 set if event
    ``i + e`` lies outside the sensor or its pixel passes the Bloom filter ``tab`` (see
    :func:`bloom_table`): the events that may be hot, to be checked one by one."""
    sig = types.uint64(x, y, types.int64, types.int64, types.int64, tab)

    def codegen(context, builder, signature, args):
        xa, ya, iv, wv, hv, ta = args
        i16, i32, i64 = ir.IntType(16), ir.IntType(32), ir.IntType(64)
        v16, v32 = ir.VectorType(i16, 16), ir.VectorType(i32, 16)
        xp = _data_ptr(context, builder, signature.args[0], xa, i16)
        yp = _data_ptr(context, builder, signature.args[1], ya, i16)
        tp = _data_ptr(context, builder, signature.args[5], ta, i32)
        perm = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v32, [v32, v32, v32]),
                                              "llvm.x86.avx512.vpermi2var.d.512")
        wvec, hvec = (_splat(builder, v32, builder.trunc(v, i32)) for v in (wv, hv))
        tabs = [builder.load(builder.bitcast(builder.gep(tp, [ir.Constant(i64, 16 * q)]), v32.as_pointer()),
                             align=4) for q in range(8)]
        out = ir.Constant(i64, 0)
        for g in range(4):
            off = builder.add(iv, ir.Constant(i64, 16 * g))
            xv, yv = (builder.zext(builder.load(builder.bitcast(builder.gep(pt, [off]), v16.as_pointer()),
                                                align=2), v32) for pt in (xp, yp))
            j = builder.add(builder.mul(yv, wvec), xv)
            bad = builder.or_(builder.icmp_unsigned(">=", xv, wvec), builder.icmp_unsigned(">=", yv, hvec))
            hit = builder.and_(_bloom_hit(builder, perm, j, BLOOM_MULTIPLIERS[0], tabs[:4]),
                               _bloom_hit(builder, perm, j, BLOOM_MULTIPLIERS[1], tabs[4:]))
            m16 = builder.zext(builder.bitcast(builder.or_(bad, hit), i16), i64)
            out = builder.or_(out, builder.shl(m16, ir.Constant(i64, 16 * g)))
        return out

    return sig, codegen


@njit(cache=True, nogil=True)
def _checked_bits(x, y, i, cand, width, height, keep_bits):
    """The keep bits of the events ``i + e`` for the bits ``e`` set in ``cand`` (one table
    look-up each) and -1, or (0, the index of the first of them outside the sensor)."""
    w = np.uint64(width)
    h = np.uint64(height)
    keep = np.uint64(0)
    while cand:
        e = _lowest_bit(cand)  # type: ignore[call-arg, var-annotated]
        xi = np.uint64(x[i + e])
        yi = np.uint64(y[i + e])
        if xi >= w or yi >= h:
            return np.uint64(0), i + np.int64(e)
        keep |= _keep_bit(keep_bits, np.uint32(yi * w + xi)) << e  # < width * height <= 2**32
        cand &= cand - np.uint64(1)
    return keep, -1


@njit(cache=True, nogil=True)
def _looked_up(buf, keep_bits):
    """The keep bits of the 64 pixel indices ``buf`` (see :func:`_index64`) as a uint64."""
    m = np.uint64(0)
    for e in range(64):
        m |= _keep_bit(keep_bits, buf[e]) << np.uint64(e)
    return m


@njit(cache=True, nogil=True)
def keep_words_simd(x, y, width, height, bloom, keep_bits, words, use_bloom):
    """:func:`keep_words` for uint16 coordinates, not yet checked (``width * height <=
    2**32``), 64 events at a time.  With ``use_bloom``, through the AVX-512 Bloom filter of
    the hot pixels (:func:`_bloom64`, no memory access): only its candidates (the hot events
    and ~1 % of the others with 200 hot pixels) are looked up in ``keep_bits``.  Otherwise, or
    once more than 1/8 of the events so far were candidates (many hot events: their look-ups
    one by one then cost more; checked every 1024 blocks), the places and bounds of the events
    in AVX-512 (:func:`_index64`) and every event looked up.  Both: 1.2x faster than the
    look-up of every event plus numpy's bounds check, measured (the Bloom filter 5 % faster
    still with 8 % hot events).  Returns the number of events kept, or ``-1 - i`` for the
    first event ``i`` outside the sensor.  Needs AVX-512 (see :func:`simd_ok`)."""
    n = x.shape[0]
    k = n_cand = 0
    nb = n // 64
    buf = np.empty(1024, np.uint32)[512:576]  # 1 KiB either side: no cache line shared with another thread
    for b in range(nb + (nb * 64 < n)):
        i = b * 64
        if b == nb:  # the last, partial block: every event looked up
            cand = (np.uint64(1) << np.uint64(n - i)) - np.uint64(1)
            keep, bad = _checked_bits(x, y, i, cand, width, height, keep_bits)
        elif use_bloom:
            cand = _bloom64(x, y, i, width, height, bloom)  # type: ignore[call-arg]
            keep, bad = _checked_bits(x, y, i, cand, width, height, keep_bits)
            keep |= ~cand
            n_cand += _popcount(cand)
            use_bloom = (b & 1023) != 1023 or n_cand * 8 <= i + 64
        else:
            outside = _index64(x, y, i, width, height, width, buf)  # type: ignore[call-arg, var-annotated]
            bad = i + np.int64(_lowest_bit(outside)) if outside else -1
            keep = _looked_up(buf, keep_bits)
        if bad >= 0:
            return -1 - bad
        words[b] = keep
        k += _popcount(keep)  # type: ignore[call-arg]
    return k


@intrinsic
def _store_bytes64(typingctx, out, i, bits):
    """``out[i + e] = 1`` (uint8) where bit ``e`` of ``bits`` is set, else 0, for e < 64 (one
    mask-to-bytes AVX-512 instruction and a 64-byte store)."""
    sig = types.void(out, types.int64, types.uint64)

    def codegen(context, builder, signature, args):
        i8 = ir.IntType(8)
        vty = ir.VectorType(i8, 64)
        ptr = builder.gep(_data_ptr(context, builder, signature.args[0], args[0], i8), [args[1]])
        v = builder.zext(builder.bitcast(args[2], ir.VectorType(ir.IntType(1), 64)), vty)
        builder.store(v, builder.bitcast(ptr, vty.as_pointer()), align=1)
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True, nogil=True)
def words_to_bytes(words, out, simd):
    """``out[i] = 1`` (uint8) if bit ``i % 64`` of ``words[i // 64]`` is set, else 0 (64 at a
    time with AVX-512 if ``simd``, see :func:`simd_ok`)."""
    n = out.shape[0]
    i = 0
    if simd:
        while i + 64 <= n:
            _store_bytes64(out, i, words[i >> 6])  # type: ignore[call-arg]
            i += 64
    while i < n:
        out[i] = np.uint8((words[i >> 6] >> np.uint64(i & 63)) & np.uint64(1))
        i += 1


#: Events per chunk of :func:`keep_bytes_simd` / :func:`keep_bytes` (their keep words: 128 KiB).
MASK_CHUNK = 1 << 20


@njit(cache=True, nogil=True)
def keep_bytes_simd(x, y, width, height, bloom, keep_bits, out, use_bloom):
    """``out[i] = 1`` (uint8) if event ``i`` is kept, else 0: :func:`keep_words_simd` chunk by
    chunk of :data:`MASK_CHUNK` events into a small buffer, expanded by
    :func:`words_to_bytes` (no keep words for the whole stream).  Returns the number kept or
    ``-1 - i`` for the first event ``i`` outside the sensor.  Needs AVX-512."""
    n = x.shape[0]
    buf = np.empty(MASK_CHUNK // 64, np.uint64)
    k = 0
    for a in range(0, n, MASK_CHUNK):
        b = min(a + MASK_CHUNK, n)
        kk = keep_words_simd(x[a:b], y[a:b], width, height, bloom, keep_bits, buf, use_bloom)
        if kk < 0:
            return kk - a
        words_to_bytes(buf, out[a:b], True)
        k += kk
    return k


@njit(cache=True, nogil=True)
def keep_bytes(x, y, width, keep_bits, out):
    """:func:`keep_bytes_simd` with :func:`keep_words` (coordinates already checked)."""
    n = x.shape[0]
    buf = np.empty(MASK_CHUNK // 64, np.uint64)
    k = 0
    for a in range(0, n, MASK_CHUNK):
        b = min(a + MASK_CHUNK, n)
        k += keep_words(x[a:b], y[a:b], width, keep_bits, buf)
        words_to_bytes(buf, out[a:b], False)
    return k


@njit(cache=True, nogil=True)
def compact_into(t, x, y, p, words, to, xo, yo, po, k, limit):
    """Copy the events whose keep bit is set (bit ``i % 64`` of ``words[i // 64]``, see
    :func:`keep_words`) into ``to[k:limit]`` (and the others), in order, ``limit - k`` being
    the number of kept events.  Branch-free: every event is written, the write position
    advances only for kept ones (a place a discarded event took is written again by a later
    kept one; once ``limit`` is reached only discarded events remain).  Returns the end."""
    n = t.shape[0]
    i = 0
    while i < n and k < limit:
        to[k] = t[i]
        xo[k] = x[i]
        yo[k] = y[i]
        po[k] = p[i]
        k += np.int64((words[i >> 6] >> np.uint64(i & 63)) & np.uint64(1))
        i += 1
    return k


@njit(cache=True, nogil=True)
def compact_simd(t, x, y, p, words, to, xo, yo, po, k, limit):
    """:func:`compact_into` with AVX-512 compress stores, 64 events (one keep word) at a time
    while a whole vector still fits before ``limit`` (the rest by :func:`compact_into`).  Only
    for CPUs with AVX512F/BW/VBMI2 and element sizes of 1, 2, 4 or 8 bytes (see
    :func:`simd_ok`).  In place (outputs = inputs) is safe: every store lands at or before the
    block just loaded.  (The keep bits stay a pass of their own: the offsets of the slices on
    several threads need the kept counts first, and their look-ups in this loop put their
    latency on the write position.)"""
    n = t.shape[0]
    i = 0
    while i + 64 <= n and k + 64 <= limit:
        m = words[i >> 6]
        _compress64(t, i, to, k, m)  # type: ignore[call-arg]
        _compress64(x, i, xo, k, m)
        _compress64(y, i, yo, k, m)
        k = _compress64(p, i, po, k, m)
        i += 64
    return compact_into(t[i:], x[i:], y[i:], p[i:], words[i >> 6:], to, xo, yo, po, k, limit)


@intrinsic
def _compress64_down(typingctx, src, i, dst, k, bits):
    """:func:`_compress64` packing downwards: the elements of ``src[i:i + 64]`` whose bit is set
    in ``bits`` are stored in order to ``dst[k - popcount(bits):k]``, exactly (the vectors from
    the last down, each compressed in a register and written with a masked store: nothing at or
    past ``k`` is touched, nor below the kept elements).  In place (``dst`` = ``src``, ``k >=
    i + 64``) is safe: every store lands at or after the vector just loaded.  Returns ``k -
    popcount(bits)``."""
    sig = types.int64(src, types.int64, dst, types.int64, types.uint64)

    def codegen(context, builder, signature, args):
        v = _CompressVectors(context, builder, signature, args)
        lanes, i64, vty, mty, dp, k, ctpop = v.lanes, v.i64, v.vty, v.mty, v.dp, v.k, v.ctpop
        store = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [vty, dp.type, ir.IntType(32), mty]),
            f"llvm.masked.store.v{lanes}i{512 // lanes}.p0")
        ones = ir.Constant(i64, -1)
        for sub in reversed(range(64 // lanes)):
            c, sm = v.compressed(sub)
            pop = builder.call(ctpop, [sm])
            k = builder.sub(k, pop)
            # the low ``pop`` lanes: ~0 >> (64 - pop), none when pop = 0 (a shift by 64 is undefined)
            low = builder.select(builder.icmp_unsigned("==", pop, ir.Constant(i64, 0)), ir.Constant(i64, 0),
                                 builder.lshr(ones, builder.sub(ir.Constant(i64, 64), pop)))
            low = builder.bitcast(builder.trunc(low, ir.IntType(lanes)) if lanes < 64 else low, mty)
            builder.call(store, [c, builder.gep(dp, [k]), ir.Constant(ir.IntType(32), 1), low])
        return k

    return sig, codegen


#: Events per chunk of :func:`filter_up` / :func:`filter_down`: the keep bits of a chunk (its
#: coordinates, 256 KiB, stay in the L2 cache for the compaction after them).  Measured on one
#: thread: 4096 events 1.2x, 512 1.6x the CPU time of 65536 (switching between the look-ups
#: and the compaction often costs more than the coordinates read twice); one block at a time
#: with the look-ups inline, 1.07x.
FILTER_CHUNK = 65536


@intrinsic
def _gather64(typingctx, x, y, i, width, height, keep_bits):
    """AVX-512 keep bits of the uint16 events ``i:i + 64``: their pixels' words of the bit
    table ``keep_bits`` (see :func:`keep_words`) fetched by four 16-lane gathers (the events
    outside the sensor masked off), their bits tested in the registers.  Returns the keep bits
    and the events outside the sensor, as the bits of two uint64s (no branch, whatever the
    number of hot pixels: 6 % less CPU than the Bloom filter and its candidates' look-ups one
    by one in :func:`filter_up`, measured on AMD Zen 4; gathers are slower on Intel CPUs with
    the GDS microcode mitigation)."""
    sig = types.UniTuple(types.uint64, 2)(x, y, types.int64, types.int64, types.int64, keep_bits)

    def codegen(context, builder, signature, args):
        xa, ya, iv, wv, hv, ka = args
        i16, i32, i64 = ir.IntType(16), ir.IntType(32), ir.IntType(64)
        v16, v32 = ir.VectorType(i16, 16), ir.VectorType(i32, 16)
        xp = _data_ptr(context, builder, signature.args[0], xa, i16)
        yp = _data_ptr(context, builder, signature.args[1], ya, i16)
        kp = _data_ptr(context, builder, signature.args[5], ka, ir.IntType(8))
        gather = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(v32, [v32, kp.type, v32, ir.VectorType(ir.IntType(1), 16), i32]),
            "llvm.x86.avx512.mask.gather.dpi.512")
        wvec, hvec = (_splat(builder, v32, builder.trunc(v, i32)) for v in (wv, hv))

        def c(k):
            return ir.Constant(v32, [ir.Constant(i32, k)] * 16)

        keep, bad = ir.Constant(i64, 0), ir.Constant(i64, 0)
        for g in range(4):
            off = builder.add(iv, ir.Constant(i64, 16 * g))
            xv, yv = (builder.zext(builder.load(builder.bitcast(builder.gep(pt, [off]), v16.as_pointer()),
                                                align=2), v32) for pt in (xp, yp))
            j = builder.add(builder.mul(yv, wvec), xv)
            out = builder.or_(builder.icmp_unsigned(">=", xv, wvec), builder.icmp_unsigned(">=", yv, hvec))
            word = builder.call(gather, [c(0), kp, builder.lshr(j, c(5)), builder.not_(out), ir.Constant(i32, 4)])
            kb = builder.icmp_unsigned("!=", builder.and_(builder.lshr(word, builder.and_(j, c(31))), c(1)), c(0))
            sh = ir.Constant(i64, 16 * g)
            keep = builder.or_(keep, builder.shl(builder.zext(builder.bitcast(kb, i16), i64), sh))
            bad = builder.or_(bad, builder.shl(builder.zext(builder.bitcast(out, i16), i64), sh))
        return context.make_tuple(builder, signature.return_type, [keep, bad])

    return sig, codegen


@njit(cache=True, nogil=True)
def _chunk_keep(x, y, a, nb, width, height, keep_bits, words):
    """The keep words of the ``nb`` blocks of 64 uint16 events from ``a`` on into ``words``
    (:func:`_gather64`).  Returns the index of the first event outside the sensor in the
    first block holding one, or -1."""
    for b in range(nb):
        keep, out = _gather64(x, y, a + 64 * b, width, height, keep_bits)  # type: ignore[call-arg, var-annotated]
        if out:
            return a + 64 * b + np.int64(_lowest_bit(out))
        words[b] = keep
    return -1


@njit(cache=True, nogil=True)
def filter_up(t, x, y, p, width, height, keep_bits):
    """Filter the events in place in one pass, packed from index 0 on, chunk by chunk of
    :data:`FILTER_CHUNK` events: the keep bits of its blocks of 64 (:func:`_chunk_keep`: bit
    table look-ups by AVX-512 gathers), then their AVX-512 compress stores (:func:`_compress64`: each lands at or before the block just
    read) while the chunk is in the cache; the last partial block one by one.  Returns the
    number kept and -1, or, at the first chunk with an event outside the sensor (nothing of it
    written; the events from that chunk on untouched), the events kept before it and the
    index of that event.  uint16 coordinates, dtypes of :func:`simd_ok`; needs AVX-512."""
    n = t.shape[0]
    k = 0
    nb = n // 64
    words = np.empty(FILTER_CHUNK // 64, np.uint64)
    for c in range(0, nb, FILTER_CHUNK // 64):
        m = min(FILTER_CHUNK // 64, nb - c)
        bad = _chunk_keep(x, y, 64 * c, m, width, height, keep_bits, words)
        if bad >= 0:
            return k, bad
        for b in range(m):
            i, keep = 64 * (c + b), words[b]
            _compress64(t, i, t, k, keep)  # type: ignore[call-arg]
            _compress64(x, i, x, k, keep)
            _compress64(y, i, y, k, keep)
            k = _compress64(p, i, p, k, keep)
    i = nb * 64
    keep, bad = _checked_bits(x, y, i, (np.uint64(1) << np.uint64(n - i)) - np.uint64(1), width, height,
                              keep_bits)
    if bad >= 0:
        return k, bad
    for e in range(n - i):
        if (keep >> np.uint64(e)) & np.uint64(1):
            t[k], x[k], y[k], p[k] = t[i + e], x[i + e], y[i + e], p[i + e]
            k += 1
    return k, -1


@njit(cache=True, nogil=True)
def filter_down(t, x, y, p, width, height, keep_bits):
    """:func:`filter_up` backwards: the kept events packed against the end, in order, chunk by
    chunk from the last block of 64 down (:func:`_compress64_down`; the first ``n % 64``
    events one by one).  Returns the index where the kept events start (``n - kept``) and -1,
    or, at the first chunk down with an event outside the sensor (nothing of it written; the
    events before its end untouched), the start so far and the index of an event outside in
    that chunk (not necessarily the first in the stream)."""
    n = t.shape[0]
    k = n
    nb = n // 64
    r = n - 64 * nb
    words = np.empty(FILTER_CHUNK // 64, np.uint64)
    for c in range(nb, 0, -(FILTER_CHUNK // 64)):
        m = min(FILTER_CHUNK // 64, c)
        a = r + 64 * (c - m)
        bad = _chunk_keep(x, y, a, m, width, height, keep_bits, words)
        if bad >= 0:
            return k, bad
        for b in range(m - 1, -1, -1):
            i, keep = a + 64 * b, words[b]
            _compress64_down(t, i, t, k, keep)  # type: ignore[call-arg]
            _compress64_down(x, i, x, k, keep)
            _compress64_down(y, i, y, k, keep)
            k = _compress64_down(p, i, p, k, keep)
    keep, bad = _checked_bits(x, y, 0, (np.uint64(1) << np.uint64(r)) - np.uint64(1), width, height,
                              keep_bits)
    if bad >= 0:
        return k, bad
    for e in range(r - 1, -1, -1):
        if (keep >> np.uint64(e)) & np.uint64(1):
            k -= 1
            t[k], x[k], y[k], p[k] = t[e], x[e], y[e], p[e]
    return k, -1


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
