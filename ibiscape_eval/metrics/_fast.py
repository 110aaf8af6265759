"""Building trajectories from already validated data without re-validating them."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import Trajectory
from ibiscape_eval.core.cpus import usable_cpus as _cpus
from ibiscape_eval.core.jit import LazyKernel, lazy_njit

__all__ = ["aligned_errors", "moments", "nearest", "relative_errors", "run_rows", "take",
           "transform_poses", "trusted"]


def trusted(
    stamps_ns: npt.ArrayLike, pos_m: npt.ArrayLike, quat_xyzw: npt.ArrayLike, name: str = ""
) -> Trajectory:
    """A :class:`Trajectory` built from arrays derived from already validated trajectories.

    Skips the constructor's checks (ordering, finiteness, unit norms), which cost several full
    passes over the data on million-pose inputs; only for rows selected, shifted, interpolated
    or rigidly transformed from validated poses.  Arrays are made read-only like the
    constructor does.
    """
    traj = object.__new__(Trajectory)
    for field, value, dtype in (("stamps_ns", stamps_ns, np.int64), ("pos_m", pos_m, np.float64),
                                ("quat_xyzw", quat_xyzw, np.float64)):
        arr = np.ascontiguousarray(value, dtype=dtype)
        if arr.flags.writeable:
            arr = arr.view()
            arr.flags.writeable = False
        object.__setattr__(traj, field, arr)
    object.__setattr__(traj, "name", name)
    return traj


def take(traj: Trajectory, index: npt.ArrayLike) -> Trajectory:
    """Rows of ``traj`` (index array), without re-validation."""
    idx = np.asarray(index)
    if idx.dtype.kind in "iu" and idx.ndim == 1 and idx.shape[0] > 0:
        lo, hi = int(idx[0]), int(idx[-1])
        if hi - lo + 1 == idx.shape[0] and bool(np.all(np.diff(idx) == 1)):
            # A contiguous run (everything matched): views instead of copies.
            s = slice(lo, hi + 1)
            return trusted(traj.stamps_ns[s], traj.pos_m[s], traj.quat_xyzw[s], traj.name)
    return trusted(traj.stamps_ns[idx], traj.pos_m[idx], traj.quat_xyzw[idx], traj.name)


# -- fused kernels ------------------------------------------------------------------------------
# Plain Python functions compiled by numba on first use (:func:`ibiscape_eval.core.jit.lazy_njit`:
# numba is heavy to import), importable and callable by name.  Each one
# makes a single pass over the poses instead of a dozen full-size numpy temporaries, and uses
# the same formulas, in the same order, as the batched operations of ``core.rotations``.

def run_rows(kernel: LazyKernel, n: int, inputs: tuple[Any, ...], outputs: tuple[Any, ...]) -> None:
    """Call ``kernel(*inputs, start, stop, *outputs)`` over rows ``0:n``; a large ``n`` is
    cut in two halves run in two threads (the kernels release the GIL)."""
    fn = kernel.compiled()
    if n < _SPLIT_ROWS or _cpus() < 2:
        fn(*inputs, 0, n, *outputs)
        return
    import threading

    half = n // 2
    worker = threading.Thread(target=fn, args=(*inputs, half, n, *outputs))
    worker.start()
    try:
        fn(*inputs, 0, half, *outputs)
    finally:
        worker.join()


_SPLIT_ROWS = 200_000


@lazy_njit(error_model="numpy")
def aligned_errors(pos, quat, ref_pos, ref_quat, A, t, qa, start, stop, pos_out, quat_out,
                   trans, rot):
    """Rows ``start:stop``: apply ``p' = A p + t``, ``q' = qa * q`` (w >= 0) to the estimate
    and compare with the reference: ``p'``, ``q'``, ``||p_ref - p'||`` and the angle of
    ``q'^-1 q_ref`` (rad) go to the output arrays."""
    ax, ay, az, aw = qa[0], qa[1], qa[2], qa[3]
    for k in range(start, stop):
        x, y, z = pos[k, 0], pos[k, 1], pos[k, 2]
        px = A[0, 0] * x + A[0, 1] * y + A[0, 2] * z + t[0]
        py = A[1, 0] * x + A[1, 1] * y + A[1, 2] * z + t[1]
        pz = A[2, 0] * x + A[2, 1] * y + A[2, 2] * z + t[2]
        bx, by, bz, bw = quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3]
        qx = aw * bx + ax * bw + ay * bz - az * by
        qy = aw * by - ax * bz + ay * bw + az * bx
        qz = aw * bz + ax * by - ay * bx + az * bw
        qw = aw * bw - ax * bx - ay * by - az * bz
        if qw < 0.0:
            qx, qy, qz, qw = -qx, -qy, -qz, -qw
        pos_out[k, 0], pos_out[k, 1], pos_out[k, 2] = px, py, pz
        quat_out[k, 0], quat_out[k, 1], quat_out[k, 2], quat_out[k, 3] = qx, qy, qz, qw
        dx = ref_pos[k, 0] - px
        dy = ref_pos[k, 1] - py
        dz = ref_pos[k, 2] - pz
        trans[k] = np.sqrt(dx * dx + dy * dy + dz * dz)
        # E = conj(q') * q_ref
        x1, y1, z1, w1 = -qx, -qy, -qz, qw
        x2, y2, z2, w2 = ref_quat[k, 0], ref_quat[k, 1], ref_quat[k, 2], ref_quat[k, 3]
        ex = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
        ey = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
        ez = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
        ew = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
        rot[k] = 2.0 * np.arctan2(np.sqrt(ex * ex + ey * ey + ez * ez), abs(ew))


@lazy_njit(error_model="numpy")
def relative_errors(est_pos, est_quat, ref_pos, ref_quat, first, second, start, stop, trans,
                    rot):
    """Pairs ``start:stop``: translation and rotation angle (rad) of
    ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` go to ``trans`` and ``rot``."""
    for k in range(start, stop):
        i = first[k]
        j = second[k]
        # Relative motions in the start frame: t = R(q_i)^-1 (p_j - p_i), q = q_i^-1 q_j, for
        # the reference (r) and the estimate (e); R(q)^-1 v = v + 2 w (u x v) + 2 u x (u x v)
        # with (u, w) = conj(q_i).
        ux, uy, uz, uw = -ref_quat[i, 0], -ref_quat[i, 1], -ref_quat[i, 2], ref_quat[i, 3]
        vx = ref_pos[j, 0] - ref_pos[i, 0]
        vy = ref_pos[j, 1] - ref_pos[i, 1]
        vz = ref_pos[j, 2] - ref_pos[i, 2]
        cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        rtx = vx + 2.0 * (uw * cx + (uy * cz - uz * cy))
        rty = vy + 2.0 * (uw * cy + (uz * cx - ux * cz))
        rtz = vz + 2.0 * (uw * cz + (ux * cy - uy * cx))
        bx, by, bz, bw = ref_quat[j, 0], ref_quat[j, 1], ref_quat[j, 2], ref_quat[j, 3]
        rqx = uw * bx + ux * bw + uy * bz - uz * by
        rqy = uw * by - ux * bz + uy * bw + uz * bx
        rqz = uw * bz + ux * by - uy * bx + uz * bw
        rqw = uw * bw - ux * bx - uy * by - uz * bz
        ux, uy, uz, uw = -est_quat[i, 0], -est_quat[i, 1], -est_quat[i, 2], est_quat[i, 3]
        vx = est_pos[j, 0] - est_pos[i, 0]
        vy = est_pos[j, 1] - est_pos[i, 1]
        vz = est_pos[j, 2] - est_pos[i, 2]
        cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        etx = vx + 2.0 * (uw * cx + (uy * cz - uz * cy))
        ety = vy + 2.0 * (uw * cy + (uz * cx - ux * cz))
        etz = vz + 2.0 * (uw * cz + (ux * cy - uy * cx))
        bx, by, bz, bw = est_quat[j, 0], est_quat[j, 1], est_quat[j, 2], est_quat[j, 3]
        eqx = uw * bx + ux * bw + uy * bz - uz * by
        eqy = uw * by - ux * bz + uy * bw + uz * bx
        eqz = uw * bz + ux * by - uy * bx + uz * bw
        eqw = uw * bw - ux * bx - uy * by - uz * bz
        dx = etx - rtx
        dy = ety - rty
        dz = etz - rtz
        trans[k] = np.sqrt(dx * dx + dy * dy + dz * dz)
        x1, y1, z1, w1 = -rqx, -rqy, -rqz, rqw
        ex = w1 * eqx + x1 * eqw + y1 * eqz - z1 * eqy
        ey = w1 * eqy - x1 * eqz + y1 * eqw + z1 * eqx
        ez = w1 * eqz + x1 * eqy - y1 * eqx + z1 * eqw
        ew = w1 * eqw - x1 * eqx - y1 * eqy - z1 * eqz
        rot[k] = 2.0 * np.arctan2(np.sqrt(ex * ex + ey * ey + ez * ez), abs(ew))


@lazy_njit(error_model="numpy")
def transform_poses(pos, quat, A, t, qa):
    """``p' = A p + t`` and ``q' = qa * q`` with w >= 0, row by row."""
    n = pos.shape[0]
    pos_out = np.empty((n, 3))
    quat_out = np.empty((n, 4))
    ax, ay, az, aw = qa[0], qa[1], qa[2], qa[3]
    for k in range(n):
        x, y, z = pos[k, 0], pos[k, 1], pos[k, 2]
        pos_out[k, 0] = A[0, 0] * x + A[0, 1] * y + A[0, 2] * z + t[0]
        pos_out[k, 1] = A[1, 0] * x + A[1, 1] * y + A[1, 2] * z + t[1]
        pos_out[k, 2] = A[2, 0] * x + A[2, 1] * y + A[2, 2] * z + t[2]
        bx, by, bz, bw = quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3]
        qx = aw * bx + ax * bw + ay * bz - az * by
        qy = aw * by - ax * bz + ay * bw + az * bx
        qz = aw * bz + ax * by - ay * bx + az * bw
        qw = aw * bw - ax * bx - ay * by - az * bz
        if qw < 0.0:
            qx, qy, qz, qw = -qx, -qy, -qz, -qw
        quat_out[k, 0], quat_out[k, 1], quat_out[k, 2], quat_out[k, 3] = qx, qy, qz, qw
    return pos_out, quat_out


@lazy_njit(error_model="numpy")
def moments(x, y):
    """Means, centred scatter matrices ``X^T X``, ``Y^T Y``, ``Y^T X`` and the largest absolute
    coordinate of two point sets ``(N, 3)``.

    Two passes (the means, then the centred products); sums are accumulated per block of rows
    and the block sums added up, which keeps the rounding error close to numpy's pairwise sums.
    """
    n = x.shape[0]
    block = 256
    tot = np.zeros(6)
    big_x = 0.0
    big_y = 0.0
    for b0 in range(0, n, block):
        sx0 = sx1 = sx2 = sy0 = sy1 = sy2 = 0.0
        for k in range(b0, min(b0 + block, n)):
            x0, x1, x2 = x[k, 0], x[k, 1], x[k, 2]
            y0, y1, y2 = y[k, 0], y[k, 1], y[k, 2]
            sx0 += x0
            sx1 += x1
            sx2 += x2
            sy0 += y0
            sy1 += y1
            sy2 += y2
            big_x = max(big_x, abs(x0), abs(x1), abs(x2))
            big_y = max(big_y, abs(y0), abs(y1), abs(y2))
        tot[0] += sx0
        tot[1] += sx1
        tot[2] += sx2
        tot[3] += sy0
        tot[4] += sy1
        tot[5] += sy2
    mx = tot[:3] / n
    my = tot[3:] / n
    m0, m1, m2 = mx[0], mx[1], mx[2]
    o0, o1, o2 = my[0], my[1], my[2]
    acc = np.zeros(21)
    for b0 in range(0, n, block):
        a00 = a01 = a02 = a11 = a12 = a22 = 0.0  # X^T X
        b00 = b01 = b02 = b11 = b12 = b22 = 0.0  # Y^T Y
        c00 = c01 = c02 = c10 = c11 = c12 = c20 = c21 = c22 = 0.0  # Y^T X
        for k in range(b0, min(b0 + block, n)):
            x0, x1, x2 = x[k, 0] - m0, x[k, 1] - m1, x[k, 2] - m2
            y0, y1, y2 = y[k, 0] - o0, y[k, 1] - o1, y[k, 2] - o2
            a00 += x0 * x0
            a01 += x0 * x1
            a02 += x0 * x2
            a11 += x1 * x1
            a12 += x1 * x2
            a22 += x2 * x2
            b00 += y0 * y0
            b01 += y0 * y1
            b02 += y0 * y2
            b11 += y1 * y1
            b12 += y1 * y2
            b22 += y2 * y2
            c00 += y0 * x0
            c01 += y0 * x1
            c02 += y0 * x2
            c10 += y1 * x0
            c11 += y1 * x1
            c12 += y1 * x2
            c20 += y2 * x0
            c21 += y2 * x1
            c22 += y2 * x2
        part = (a00, a01, a02, a11, a12, a22, b00, b01, b02, b11, b12, b22,
                c00, c01, c02, c10, c11, c12, c20, c21, c22)
        for q in range(21):
            acc[q] += part[q]
    sxx = np.array([[acc[0], acc[1], acc[2]], [acc[1], acc[3], acc[4]], [acc[2], acc[4], acc[5]]])
    syy = np.array([[acc[6], acc[7], acc[8]], [acc[7], acc[9], acc[10]],
                    [acc[8], acc[10], acc[11]]])
    syx = np.array([[acc[12], acc[13], acc[14]], [acc[15], acc[16], acc[17]],
                    [acc[18], acc[19], acc[20]]])
    return mx, my, sxx, syy, syx, big_x, big_y


@lazy_njit(error_model="numpy")
def nearest(short, long_, max_diff):
    """For each stamp of the sorted ``short``, the nearest stamp of the sorted ``long_`` (the
    lower one on a tie), kept when within ``max_diff``: (short rows, long rows, |difference|).

    A merge of the two sorted lists: the same pairs as a binary search from the right side.
    """
    n = short.shape[0]
    m = long_.shape[0]
    rows_s = np.empty(n, dtype=np.intp)
    rows_l = np.empty(n, dtype=np.intp)
    diffs = np.empty(n, dtype=np.int64)
    count = 0
    k = 0  # first index of long_ with a larger stamp (numpy's searchsorted side="right")
    for a in range(n):
        s = short[a]
        while k < m and long_[k] <= s:
            k += 1
        hi = min(k, m - 1)
        d_hi = abs(long_[hi] - s)
        if k > 0:
            d_lo = abs(s - long_[k - 1])
        else:
            d_lo = 9223372036854775807
        if d_hi < d_lo:
            best, diff = hi, d_hi
        else:
            best, diff = max(k - 1, 0), d_lo
        if diff <= max_diff:
            rows_s[count] = a
            rows_l[count] = best
            diffs[count] = diff
            count += 1
    return rows_s[:count], rows_l[:count], diffs[:count]
