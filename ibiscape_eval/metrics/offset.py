"""Estimating a constant time offset between an estimate and a reference."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, Trajectory
from ibiscape_eval.core.errors import Remedy
from ibiscape_eval.core.rotations import angle_rad_from_quat, quat_conjugate, quat_multiply

__all__ = ["estimate_time_offset"]

FloatArray = npt.NDArray[np.float64]

_MAX_GRID = 4_000_000  # samples of the common grid (memory bound for the FFT)


def _angular_rate(traj: Trajectory) -> tuple[FloatArray, FloatArray]:
    """Angular-rate magnitude (rad/s) between consecutive poses, at the interval midpoints (s)."""
    t = traj.stamps_ns
    q = traj.quat_xyzw
    dt_s = np.diff(t).astype(np.float64) / 1e9
    rate = angle_rad_from_quat(quat_multiply(quat_conjugate(q[:-1]), q[1:])) / dt_s
    mid_s = (t[:-1] - t[0]).astype(np.float64) / 1e9 + 0.5 * dt_s
    return mid_s, rate


def _on_grid(
    mid_s: FloatArray, rate: FloatArray, grid_s: FloatArray
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    valid = (grid_s >= mid_s[0]) & (grid_s <= mid_s[-1])
    return np.where(valid, np.interp(grid_s, mid_s, rate), 0.0), valid


def _centred(x: FloatArray, valid: npt.NDArray[np.bool_]) -> FloatArray:
    return np.where(valid, x - x[valid].mean(), 0.0)


def _coarse_offset(
    est: Trajectory, ref: Trajectory, *, center_s: float, max_offset_s: float
) -> tuple[float, float]:
    """Cross-correlate angular-rate magnitudes; returns (offset s, grid step s)."""
    e_mid, e_rate = _angular_rate(est)
    r_mid, r_rate = _angular_rate(ref)
    # Put both on the reference clock, relative to the reference's first stamp.
    e_mid = e_mid + (est.stamps_ns[0] - ref.stamps_ns[0]) / 1e9 + center_s
    for name, rate in (("estimate", e_rate), ("reference", r_rate)):
        if not np.isfinite(rate).all() or float(np.ptp(rate)) < 1e-6:
            raise DegenerateInputError(
                f"cannot estimate the time offset: the {name} has no rotation to correlate "
                "(its angular rate is constant); give the offset with {0} instead",
                hint=(Remedy("offset_s"),))
    h = float(min(np.median(np.diff(e_mid)), np.median(np.diff(r_mid))))
    lo = min(e_mid[0], r_mid[0])
    hi = max(e_mid[-1], r_mid[-1])
    h = max(h, (hi - lo) / _MAX_GRID, 1e-4)
    grid = lo + h * np.arange(math.floor((hi - lo) / h) + 1)
    a, ma = _on_grid(e_mid, e_rate, grid)
    b, mb = _on_grid(r_mid, r_rate, grid)
    if ma.sum() < 3 or mb.sum() < 3:
        raise DegenerateInputError(
            "cannot estimate the time offset: too few poses to resample the angular rate"
        )
    a0, b0 = _centred(a, ma), _centred(b, mb)
    n = grid.shape[0]
    size = 1 << math.ceil(math.log2(2 * n))
    fa = np.fft.rfft(a0, size)
    fb = np.fft.rfft(b0, size)
    fma = np.fft.rfft(ma.astype(np.float64), size)
    fmb = np.fft.rfft(mb.astype(np.float64), size)

    def corr(x: npt.NDArray[np.complex128], y: npt.NDArray[np.complex128]) -> FloatArray:
        # c[L] = sum_k y[k + L] x[k], L negative at the end of the circular buffer.
        return np.fft.irfft(y * np.conj(x), size)

    num = corr(fa, fb)
    ea = corr(np.fft.rfft(a0 * a0, size), fmb)  # sum a0[k]^2 mb[k+L]
    eb = corr(fma, np.fft.rfft(b0 * b0, size))  # sum ma[k] b0[k+L]^2
    overlap = corr(fma, fmb)
    max_lag = min(round(max_offset_s / h), n - 1)
    lags = np.arange(-max_lag, max_lag + 1)
    idx = lags % size
    need = 0.25 * min(ma.sum(), mb.sum())
    with np.errstate(invalid="ignore", divide="ignore"):
        score = num[idx] / np.sqrt(np.maximum(ea[idx], 0.0) * np.maximum(eb[idx], 0.0))
    score = np.where((overlap[idx] > need) & np.isfinite(score), score, -np.inf)
    if not np.isfinite(score).any():
        raise IbiscapeError(
            f"cannot estimate the time offset: the trajectories do not overlap enough in time "
            f"within ±{max_offset_s} s of {center_s:+.6f} s; widen max_offset_s or give "
            "{0}", hint=(Remedy("offset_s"),))
    k = int(np.argmax(score))
    frac = 0.0
    if 0 < k < lags.shape[0] - 1 and np.isfinite(score[k - 1]) and np.isfinite(score[k + 1]):
        y0, y1, y2 = score[k - 1], score[k], score[k + 1]
        den = y0 - 2.0 * y1 + y2
        if den < 0.0:
            frac = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
    return center_s + (float(lags[k]) + frac) * h, h


def estimate_time_offset(
    est: Trajectory,
    ref: Trajectory,
    *,
    max_offset_s: float = 1.0,
    center_s: float = 0.0,
    max_diff_s: float = 0.01,
    refine: bool = True,
) -> float:
    """Constant offset ``t_ref = t_est + offset`` between two trajectories, seconds.

    Two stages: the magnitudes of the angular rates of both trajectories (frame independent)
    are resampled on a common grid and cross-correlated (FFT, normalised over the overlap) for
    offsets within ``center_s ± max_offset_s``, with a parabolic sub-sample peak; then the
    offset is refined by minimising the SE(3)-aligned ATE (interpolated poses) over ±2 grid
    steps around it.

    Parameters
    ----------
    est, ref : Trajectory
        Estimate and reference; both must rotate (the rate magnitude must vary).
    max_offset_s : float
        Largest offset searched, seconds, around ``center_s``.
    center_s : float
        Centre of the search (a prior offset), seconds.
    max_diff_s : float
        Matching tolerance used by the refinement (raised to the poses' spacing if smaller).
    refine : bool
        Run the ATE refinement (otherwise return the correlation peak).

    Returns
    -------
    float
        The offset in seconds.

    Raises
    ------
    DegenerateInputError
        When either trajectory has no rotation to correlate, or too few poses.
    """
    if not (math.isfinite(max_offset_s) and max_offset_s > 0):
        raise IbiscapeError(f"max_offset_s must be a positive number, got {max_offset_s!r}")
    if len(est) < 4 or len(ref) < 4:
        raise DegenerateInputError(
            f"cannot estimate the time offset from {len(est)} estimated and {len(ref)} reference "
            "poses; at least 4 each are needed"
        )
    coarse, h = _coarse_offset(est, ref, center_s=center_s, max_offset_s=max_offset_s)
    if not refine:
        return coarse
    from scipy.optimize import minimize_scalar

    from .alignment import align
    from .association import associate

    dt_e = float(np.median(np.diff(est.stamps_ns))) / 1e9
    dt_r = float(np.median(np.diff(ref.stamps_ns))) / 1e9
    tol = max(max_diff_s, 1.01 * max(dt_e, dt_r))

    def cost(offset: float) -> float:
        try:
            m = associate(est, ref, max_diff_s=tol, offset_s=offset, interpolate=True)
            al = align(m.est, m.ref, method="se3")
        except IbiscapeError:
            return math.inf
        d = al.apply(m.est).pos_m - m.ref.pos_m
        return float(np.mean(np.sum(d * d, axis=1)))

    res = minimize_scalar(
        cost, bounds=(coarse - 2.0 * h, coarse + 2.0 * h), method="bounded",
        options={"xatol": 1e-5},
    )
    best = float(res.x)
    if not math.isfinite(float(res.fun)) or cost(best) > cost(coarse):
        return coarse
    return best
