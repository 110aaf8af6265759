"""``calibrate_imu_camera``: T_cam_imu and timeshift_cam_imu of every camera of a rig in one problem.

Method (Furgale, Rehder & Siegwart, IROS 2013, as in Kalibr's ``kalibr_calibrate_imu_camera``): the
IMU pose ``T_target_imu(t)`` is a continuous-time cumulative cubic B-spline on SO(3) x R^3
(:mod:`.spline`); gyroscope, accelerometer and reprojection residuals are minimised jointly over the
spline, gravity in the target frame, slowly varying biases, and each camera's ``T_cam_imu`` and time
offset (:mod:`.problem`).  The normal equations are solved by a Levenberg-Marquardt loop with a
banded Cholesky factorisation of the control points and the Schur complement of the other
parameters (a sparse LU where that fails).  The standard deviations come from a sandwich covariance around
``(J^T J)^-1`` with the residuals' measured noise, the bias random walk between knots, a batch-means
check and the propagated intrinsics' covariance (:func:`.problem.estimate_covariance`), the rotation's
then inflated by :data:`ROTATION_STD_INFLATION` (coverage: ``benchmarks/bench_coverage.py --imu``).

Initialisation (:mod:`.initial`): per-frame planar PnP (both IPPE solutions), then the time offset
and ``R_cam_imu`` from the PnP rotations versus the integrated gyroscope (the hand-eye problem
``A X = Y B`` solved linearly for each offset of a grid, frames weighted by their corner spread), then
positions, ``t_cam_imu``, gravity and a constant accelerometer bias by one sparse linear least-squares
solve.  With rotation about one axis only (a flat road, ``force=True``) the hand-eye angle about that
axis is chosen by the accelerometer fit.  The problem is solved with knots at 20 Hz first, then
resampled to ``knot_rate_hz`` (50 Hz by default: the suspension's vertical accelerations need it).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import CalibrationError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.core.kalibr import ImuNoise
from ibiscape_eval.core.so3 import exp_so3

from .errors import ImuCoverageError, ImuRateError
from .initial import FramePoses, align_rotations, frame_poses, integrate_gyro
from .inputs import CameraObservations, ImuData
from .options import ImuCameraOptions
from .problem import (
    CameraBlock,
    Normal,
    Piece,
    Problem,
    State,
    camera_block,
    cost,
    estimate_covariance,
    imu_block,
    normal_equations,
    rows_dot,
    tdot,
)
from .result import CameraImuCalibration, Excitation, ImuCameraResult, ResidualSeries
from .spline import basis, position, rotation

__all__ = ["calibrate_imu_camera"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Progress = Callable[[float, str], None]

#: default thresholds of the observability report (the issue's accuracy targets)
WEAK_ROTATION_STD_DEG = 0.05
WEAK_TRANSLATION_STD_M = 0.005
WEAK_TIMESHIFT_STD_S = 1e-4
#: knots of the first solve; the final knot rate is reached by resampling that solution
COARSE_KNOT_RATE_HZ = 20.0
COARSE_ITERATIONS = 40
ABS_COST_TOL = 0.01
#: a camera whose reprojection RMS exceeds the rig's best by this factor is weighed by its own noise
NOISY_CAMERA_RATIO = 1.5
#: the least corner noise an estimated weight assumes [px]
MIN_SIGMA_PX = 0.02
#: factor on the reported rotation std beyond the sandwich covariance (:func:`.problem.
#: estimate_covariance`): measured by ``benchmarks/bench_coverage.py --imu`` on the simulator's
#: 12 s drives (16 seeds default noise, 8 with misweighted noise, 16 with intrinsics errors; 240
#: rotation errors): the rotation's 1-sigma covered 58-66 % (median |z| / 0.6745 = 1.06, 1.14,
#: 1.10) while translation and time offset were conservative (0.73-1.05, left as they are).  The
#: rotation's remaining excess is not modelled (candidates: the spline's rotation between knots,
#: the linearisation of the gyroscope residuals).
ROTATION_STD_INFLATION = 1.1


def _check_inputs(observations: Sequence[CameraObservations], imu: ImuData,
                  noise: ImuNoise, corners: FloatArray, rate_tolerance: float) -> None:
    if not observations:
        raise IbiscapeError("no camera observations given")
    names = [o.name for o in observations]
    if len(set(names)) != len(names):
        raise IbiscapeError(f"camera names must be unique, got {names}")
    for o in observations:
        if o.camera is None:
            raise CalibrationError(
                f"camera {o.name}: intrinsics are missing; calibrate the camera first or give "
                "--cams camchain.yaml with an entry for it")
        if o.corner_ids.size and (o.corner_ids.min() < 0 or o.corner_ids.max() >= len(corners)):
            raise IbiscapeError(f"camera {o.name}: corner ids outside 0..{len(corners) - 1} of the target")
    rate = imu.rate_hz
    if abs(rate - noise.update_rate_hz) > rate_tolerance * noise.update_rate_hz:
        raise ImuRateError(noise.update_rate_hz, rate)


def _pieces(times: FloatArray, dt: float, gap_s: float, margin_s: float,
            lo: float, hi: float) -> tuple[Piece, ...]:
    """Spline pieces with knots every ``dt`` over the times, cut where the target is absent for
    more than ``gap_s``, ``margin_s`` beyond the first and last time, inside ``[lo, hi]``."""
    t = np.sort(times)
    cuts = np.flatnonzero(np.diff(t) > gap_s)
    out: list[Piece] = []
    off = 0
    for a, b in zip(np.r_[0, cuts + 1], np.r_[cuts + 1, t.size], strict=True):
        t0 = max(lo, t[a] - margin_s)
        t1 = min(hi, t[b - 1] + margin_s)
        n_seg = max(1, math.ceil((t1 - t0) / dt))
        if t0 + n_seg * dt > hi:
            n_seg = max(1, math.floor((hi - t0) / dt))
        out.append(Piece(t0, n_seg, off, dt))
        off += n_seg + 3
    return tuple(out)


def _spline_init(t_s: FloatArray, p: FloatArray, imu_t: FloatArray, R_imu: FloatArray,
                 pieces: Sequence[Piece], dt: float) -> tuple[FloatArray, FloatArray]:
    """Control points: rotations slerped from ``R_imu`` at the IMU stamps, positions interpolated
    from the PnP positions ``p`` at times ``t_s`` (control point k sits near ``t0 + (k - 1) dt``)."""
    from scipy.spatial.transform import Rotation, Slerp

    order = np.argsort(t_s, kind="stable")
    t_s, p = t_s[order], p[order]
    slerp = Slerp(imu_t, Rotation.from_matrix(R_imu))
    Rs, Ps = [], []
    for pc in pieces:
        tau = pc.t0_s + (np.arange(pc.n_seg + 3) - 1) * dt
        Rs.append(slerp(np.clip(tau, imu_t[0], imu_t[-1])).as_matrix())
        Ps.append(np.stack([np.interp(tau, t_s, p[:, a]) for a in range(3)], -1))
    return np.concatenate(Rs), np.concatenate(Ps)


@dataclass
class _LinearRows:
    """A sparse linear least-squares system assembled block by block (COO triplets, the
    right-hand side by rows); local to :func:`_linear_translation_init`.  With ``matrix=False``
    only the right-hand side is kept (the same system with other measurements)."""

    rows: list[IntArray] = field(default_factory=list)
    cols: list[IntArray] = field(default_factory=list)
    vals: list[FloatArray] = field(default_factory=list)
    rhs: list[tuple[IntArray, FloatArray]] = field(default_factory=list)
    n_rows: int = 0
    matrix: bool = True

    def add(self, ri: IntArray, ci: IntArray, v: FloatArray) -> None:
        if self.matrix:
            self.rows.append(ri)
            self.cols.append(ci)
            self.vals.append(v)

    def vector(self) -> FloatArray:
        y = np.zeros(self.n_rows)
        for ri, v in self.rhs:
            y[ri] = v
        return y

    def factor(self, n: int) -> tuple[Any, Any]:
        """The matrix (CSR) and a solver of its slightly damped normal equations."""
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        A = sp.csr_matrix((np.concatenate(self.vals), (np.concatenate(self.rows), np.concatenate(self.cols))),
                          shape=(self.n_rows, n))
        AtA = (A.T @ A).tocsc() + sp.identity(n, format="csc") * 1e-9
        return A, splu(AtA, permc_spec="COLAMD")

    def solve(self, n: int) -> tuple[FloatArray, float]:
        """The least-squares solution (slightly damped normal equations) and its residual SSR."""
        A, lu = self.factor(n)
        y = self.vector()
        x = lu.solve(A.T @ y)
        return x, float(np.sum((A @ x - y) ** 2))


def _pnp_rows(sys: _LinearRows, prob: Problem, st: State, p_cam: list[FloatArray]) -> None:
    """PnP camera positions ``p + R (-R_ci^T t_ci)``, rows weighted by ``1 / (0.05 m + 1e-3 z^2)``."""
    nc = prob.n_ctrl
    for c in range(len(prob.cams)):
        cb = prob.cams[c]
        base, u, inside = prob.locate(cb.t_s + st.shift_s[c])
        R, _ = rotation(st.R_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s, angular_velocity=False)
        b, _, _ = basis(u)
        pc = p_cam[c]
        z = np.linalg.norm(pc, axis=1)
        w = np.where(inside, 1.0 / (0.05 + 1e-3 * z * z), 0.0)
        F = len(u)
        # p_ti + R (-R_ci^T t_ci) = p_tc
        M = -np.einsum("nij,kj->nik", R, st.R_ci[c])  # (F, 3, 3) times t_ci
        for a in range(3):
            ri = sys.n_rows + 3 * np.arange(F) + a
            for j in range(4):
                sys.add(ri, 3 * (base + j) + a, w * b[:, j])
            for k in range(3):
                sys.add(ri, np.full(F, 3 * nc + 3 * c + k), w * M[:, a, k])
            sys.rhs.append((ri, w * pc[:, a]))
        sys.n_rows += 3 * F


def _accel_rows(sys: _LinearRows, prob: Problem, st: State, ig: int, ib: int,
                R: FloatArray | None = None) -> FloatArray:
    """The accelerometer ``R^T (p'' - g) + b_a`` (gravity at column ``ig``, the bias at ``ib``);
    returns the IMU rotations ``R`` at the samples (given: not evaluated again)."""
    base, u, _ = prob.locate(prob.imu_t_s)
    if R is None:
        R, _ = rotation(st.R_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s, angular_velocity=False)
    _, _, ddb = basis(u)
    ddb = ddb / prob.dt_s**2
    N = len(u)
    wa = 1.0 / prob.sigma_accel
    for a in range(3):  # component a of R^T (sum ddb_j P_j - g) + b_a
        ri = sys.n_rows + 3 * np.arange(N) + a
        for j in range(4):
            for k in range(3):
                sys.add(ri, 3 * (base + j) + k, wa * ddb[:, j] * R[:, k, a])
        for k in range(3):
            sys.add(ri, np.full(N, ig + k), -wa * R[:, k, a])
        sys.add(ri, np.full(N, ib + a), np.full(N, wa))
        sys.rhs.append((ri, wa * prob.accel[:, a]))
    sys.n_rows += 3 * N
    return R


def _prior_rows(sys: _LinearRows, prob: Problem, R: FloatArray, ig: int) -> None:
    """Gravity near the mean of ``-R f`` (accelerations average out: keeps a poorly initialised
    trajectory from trading gravity for a large acceleration) and the batch problem's weak prior
    on ``t_ci`` (an unobservable lever arm stays near zero)."""
    N = R.shape[0]
    g_mean = -np.einsum("nij,nj->i", R, prob.accel) / N
    g_mean *= prob.gravity_m_s2 / max(float(np.linalg.norm(g_mean)), 1e-9)
    r0 = sys.n_rows
    for a in range(3):
        sys.add(np.array([r0 + a]), np.array([ig + a]), np.array([1.0 / 0.5]))
        sys.rhs.append((np.array([r0 + a]), np.array([g_mean[a] / 0.5])))
    r0 += 3
    for c in range(len(prob.cams)):
        for a in range(3):
            sys.add(np.array([r0]), np.array([3 * prob.n_ctrl + 3 * c + a]),
                    np.array([1.0 / prob.trans_prior_sigma_m]))
            r0 += 1
    sys.n_rows = r0


def _linear_translation_init(prob: Problem, st: State, p_cam: list[FloatArray]) -> tuple[State, float]:
    """Positions, ``t_ci``, gravity and a constant accelerometer bias by one sparse linear
    least-squares solve with the rotations held: PnP camera positions ``p + R p_imu_cam`` and the
    accelerometer ``R^T (p'' - g) + b_a``.  PnP depth noise grows with the squared distance, so its
    rows are weighted by ``1 / (0.05 m + 1e-3 z^2)``."""
    nc, C = prob.n_ctrl, len(prob.cams)
    ig, ib = 3 * nc + 3 * C, 3 * nc + 3 * C + 3
    sys = _LinearRows()
    _pnp_rows(sys, prob, st, p_cam)
    R = _accel_rows(sys, prob, st, ig, ib)
    _prior_rows(sys, prob, R, ig)
    x, ssr = sys.solve(3 * nc + 3 * C + 3 + 3)
    bias = st.bias.copy()
    bias[:, 3:] = x[ib : ib + 3]
    out = replace(st, P_ctrl=x[: 3 * nc].reshape(nc, 3), t_ci=x[3 * nc : 3 * nc + 3 * C].reshape(C, 3),
                  R_g=_align(np.array([0.0, 0.0, -1.0]), x[ig : ig + 3]), bias=bias)
    return out, ssr


def _resolve_single_axis(prob: Problem, st: State, p_cam: list[FloatArray]) -> State:
    """Rotation about a single axis leaves the hand-eye problem a free angle about that axis:
    ``(X Rk(a), Y Rk(a))`` solves ``A X = Y B`` as well.  Choose it by the accelerometer: the angle
    whose linear translation fit (:func:`_linear_translation_init`) has the smallest residual."""
    w = prob.gyro
    k = np.linalg.eigh(w.T @ w)[1][:, -1]  # the excited axis (IMU frame)
    grid = np.radians(np.arange(-180.0, 180.0, 10.0))
    a0 = float(grid[int(np.argmin(_turned_fit_ssr(prob, st, p_cam, k, grid)))])
    fine = a0 + np.radians(np.arange(-10.0, 10.5, 1.0))
    a = float(fine[int(np.argmin(_turned_fit_ssr(prob, st, p_cam, k, fine)))])
    Rk = exp_so3(k * a)  # R_target_imu -> R_target_imu Rk about the excited axis
    return _linear_translation_init(prob, replace(st, R_ci=st.R_ci @ Rk, R_ctrl=st.R_ctrl @ Rk), p_cam)[0]


def _turned_fit_ssr(prob: Problem, st: State, p_cam: list[FloatArray], k: FloatArray,
                    angles: FloatArray) -> FloatArray:
    """The residual of :func:`_linear_translation_init` with ``R_ctrl`` and ``R_ci`` turned by
    ``Rk(a)`` about the IMU axis ``k``, for every angle.  The turn leaves the PnP rows as they are
    (``R Rk (R_ci Rk)^T = R R_ci^T``) and turns each sample's accelerometer rows by ``Rk^T``:
    the same residual as the unturned system with the accelerometer samples (and the bias) turned
    by ``Rk``, so one factorisation serves every angle and only the right-hand side changes."""
    nc, C = prob.n_ctrl, len(prob.cams)
    ig, ib, n = 3 * nc + 3 * C, 3 * nc + 3 * C + 3, 3 * nc + 3 * C + 6
    full = _LinearRows()
    _pnp_rows(full, prob, st, p_cam)
    R = _accel_rows(full, prob, st, ig, ib)
    _prior_rows(full, prob, R, ig)
    A, lu = full.factor(n)
    out = np.empty(len(angles))
    for i, a in enumerate(angles):
        turned = replace(prob, accel=prob.accel @ exp_so3(k * a).T)
        rows = _LinearRows(matrix=False)
        _pnp_rows(rows, turned, st, p_cam)
        _accel_rows(rows, turned, st, ig, ib, R)
        _prior_rows(rows, turned, R, ig)
        y = rows.vector()
        x = lu.solve(A.T @ y)
        out[i] = float(np.sum((A @ x - y) ** 2))
    return out


def _align(a: FloatArray, b: FloatArray) -> FloatArray:
    """A rotation taking unit direction ``a`` to ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    s, c = np.linalg.norm(v), float(a @ b)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return exp_so3(v / s * math.atan2(s, c))


def _excitation(gyro: FloatArray, accel: FloatArray, duration_s: float,
                min_rate: float) -> Excitation:
    gs = gyro.std(axis=0) if len(gyro) else np.zeros(3)
    as_ = accel.std(axis=0) if len(accel) else np.zeros(3)
    weak = tuple(ax for ax, v in zip("xyz", gs, strict=True) if v < min_rate)
    return Excitation(gs, as_, duration_s, min_rate, weak, len(weak) <= 1)


# ------------------------------------------------------------------------------------------ steps
@dataclass(frozen=True, eq=False)
class _Initial:
    """Per camera, before the batch problem: the PnP poses kept (IPPE candidate ``choices``), the
    frame times on the IMU clock's origin, and the offset and rotations against the gyroscope."""

    imu_t_s: FloatArray  # IMU stamps, s from the first
    R_w_imu: FloatArray  # the integrated gyroscope
    poses: tuple[FramePoses, ...]
    choices: tuple[IntArray, ...]
    cam_t_s: tuple[FloatArray, ...]  # every frame's stamp, s from the first IMU stamp
    shifts_s: tuple[float, ...]
    R_cam_imu: tuple[FloatArray, ...]
    R_target_w: tuple[FloatArray, ...]


def _initial_alignment(observations: Sequence[CameraObservations], imu: ImuData, corners: FloatArray,
                       opts: ImuCameraOptions) -> _Initial:
    """Per-frame PnP, then the offset and rotation of every camera against the integrated gyro."""
    t_ref = int(imu.stamps_ns[0])
    imu_t = ((imu.stamps_ns - t_ref) * 1e-9).astype(np.float64)
    imu_lo, imu_hi = float(imu_t[0]), float(imu_t[-1])
    R_w_imu = integrate_gyro(imu.gyro_rad_s, imu_t)
    poses, choices, cam_t, shifts, R_ci0, R_tw0 = [], [], [], [], [], []
    for o in observations:
        fp = frame_poses(o, corners, min_corners=opts.min_corners)
        if len(fp.frames) < 10:
            raise CalibrationError(
                f"camera {o.name}: the target was found in {len(fp.frames)} frames (with >= "
                f"{opts.min_corners} corners); at least 10 are needed")
        t_c = ((o.stamps_ns - t_ref) * 1e-9).astype(np.float64)
        tf = t_c[fp.frames]
        if tf[0] < imu_lo - opts.max_shift_s or tf[-1] > imu_hi + opts.max_shift_s:
            raise ImuCoverageError(o.name, (imu.stamps_ns[0], imu.stamps_ns[-1]),
                                   (o.stamps_ns[fp.frames[0]], o.stamps_ns[fp.frames[-1]]))
        al = align_rotations(tf, fp, imu_t, R_w_imu, max_shift_s=opts.max_shift_s)
        poses.append(fp.subset(al.inliers))
        choices.append(al.choice[al.inliers])
        shifts.append(al.shift_s)
        R_ci0.append(al.R_cam_imu)
        R_tw0.append(al.R_target_w)
        cam_t.append(t_c)
    return _Initial(imu_t, R_w_imu, tuple(poses), tuple(choices), tuple(cam_t), tuple(shifts),
                    tuple(R_ci0), tuple(R_tw0))


@dataclass(frozen=True, eq=False)
class _Layout:
    """Where the unknowns live in time: the spline pieces (coarse knots) and the bias knots."""

    pieces: tuple[Piece, ...]
    in_piece: npt.NDArray[np.bool_]  # IMU samples inside a piece
    bias_t0_s: float
    bias_dt_s: float
    n_bias: int

    @property
    def n_ctrl(self) -> int:
        return self.pieces[-1].offset + self.pieces[-1].n_seg + 3


def _layout(init: _Initial, opts: ImuCameraOptions) -> _Layout:
    """Spline pieces over the (shifted) frame times, knots at the coarse rate; bias knots
    about ``bias_knot_s`` apart over the pieces' span."""
    dt = 1.0 / min(opts.knot_rate_hz, COARSE_KNOT_RATE_HZ)
    all_t = np.concatenate([init.cam_t_s[c][fp.frames] + init.shifts_s[c] for c, fp in enumerate(init.poses)])
    margin = max(0.1, 3 * dt) + opts.max_shift_s * 0.25
    imu_t = init.imu_t_s
    pieces = _pieces(all_t, dt, opts.gap_s, margin, float(imu_t[0]), float(imu_t[-1]))
    in_piece = np.zeros(imu_t.size, bool)
    for pc in pieces:
        in_piece |= pc.covers(imu_t)
    span_lo, span_hi = pieces[0].t0_s, pieces[-1].t1_s
    n_bias = max(2, math.ceil((span_hi - span_lo) / opts.bias_knot_s) + 1)
    return _Layout(pieces, in_piece, span_lo, (span_hi - span_lo) / (n_bias - 1), n_bias)


def _check_excitation(imu: ImuData, layout: _Layout, opts: ImuCameraOptions) -> tuple[Excitation, str | None]:
    """The excitation over the pieces; refused without two excited rotation axes unless
    ``force`` (then the warning it carries)."""
    pieces = layout.pieces
    exc = _excitation(imu.gyro_rad_s[layout.in_piece], imu.accel_m_s2[layout.in_piece],
                      float(sum(pc.n_seg * pc.dt_s for pc in pieces)), opts.min_rate_std_rad_s)
    if exc.translation_observable:
        return exc, None
    msg = ("too little rotational excitation to observe the translation: angular-rate std "
           + ", ".join(f"{a}={v:.4f}" for a, v in zip("xyz", exc.gyro_std_rad_s, strict=True))
           + f" rad/s about the IMU axes (need >= {opts.min_rate_std_rad_s} on at least two axes)")
    if not opts.force:
        raise CalibrationError(msg + "; excite roll and pitch (bumps, waves) or use --force "
                               "to estimate anyway and mark the weak directions")
    return exc, msg + " (forced: the translation along the weak directions is not determined)"


def _camera_block(o: CameraObservations, fr: IntArray, t_s: FloatArray, corners: FloatArray) -> CameraBlock:
    """The corners of camera ``o`` in the frames ``fr`` padded to one row per frame."""
    sel = np.isin(o.frame_index, fr)
    rows = np.searchsorted(fr, o.frame_index[sel])
    M = int(np.bincount(rows, minlength=len(fr)).max())
    order = np.argsort(rows, kind="stable")
    rows_s = rows[order]
    slot = np.arange(rows_s.size) - np.searchsorted(rows_s, rows_s)
    X = np.zeros((len(fr), M, 3))
    uv = np.zeros((len(fr), M, 2))
    mask = np.zeros((len(fr), M))
    X[rows_s, slot] = corners[o.corner_ids[sel][order]]
    uv[rows_s, slot] = o.pixels_px[sel][order]
    mask[rows_s, slot] = 1.0
    assert o.camera is not None
    return CameraBlock(o.name, o.camera, t_s, X, uv, mask)


def _problem(observations: Sequence[CameraObservations], imu: ImuData, noise: ImuNoise,
             corners: FloatArray, init: _Initial, layout: _Layout, opts: ImuCameraOptions) -> Problem:
    """The batch problem on the coarse knots."""
    rate = imu.rate_hz
    walk = np.array([noise.gyro_random_walk_rad_s2_sqrt_hz] * 3
                    + [noise.accel_random_walk_m_s3_sqrt_hz] * 3) * math.sqrt(layout.bias_dt_s)
    sel = layout.in_piece
    return Problem(
        dt_s=layout.pieces[0].dt_s, pieces=layout.pieces, n_ctrl=layout.n_ctrl,
        bias_t0_s=layout.bias_t0_s, bias_dt_s=layout.bias_dt_s, n_bias=layout.n_bias,
        imu_t_s=init.imu_t_s[sel], gyro=imu.gyro_rad_s[sel], accel=imu.accel_m_s2[sel],
        sigma_gyro=noise.gyro_noise_density_rad_s_sqrt_hz * math.sqrt(rate),
        sigma_accel=noise.accel_noise_density_m_s2_sqrt_hz * math.sqrt(rate),
        bias_walk_sigma=walk, gravity_m_s2=opts.gravity_m_s2,
        cams=tuple(_camera_block(o, fp.frames, init.cam_t_s[c][fp.frames], corners)
                   for c, (o, fp) in enumerate(zip(observations, init.poses, strict=True))),
        sigma_px=opts.sigma_px, n_intr=4 if opts.refine_intrinsics else 0)


def _common_world_frame(init: _Initial, gyro: FloatArray) -> list[FloatArray]:
    """One rotation axis k: each camera's hand-eye solution is free about k; bring them onto
    camera 0's world frame (``Y_c Rk(a) = Y_0``) before choosing the common angle."""
    R_ci0 = list(init.R_cam_imu)
    k = np.linalg.eigh(gyro.T @ gyro)[1][:, -1]
    grid = np.radians(np.arange(-180.0, 180.0, 0.25))
    Rks = exp_so3(grid[:, None] * k)
    for c in range(1, len(R_ci0)):
        a = int(np.argmin(np.linalg.norm(init.R_target_w[c] @ Rks - init.R_target_w[0], axis=(1, 2))))
        R_ci0[c] = R_ci0[c] @ Rks[a]
    return R_ci0


def _initial_state(prob: Problem, init: _Initial, single_axis: bool) -> State:
    """The initial trajectory: rotation from the aligned gyro integral, positions from PnP, then
    positions, lever arms, gravity and accelerometer bias by the linear fit."""
    ts = [cb.t_s + init.shifts_s[c] for c, cb in enumerate(prob.cams)]
    ps = [fp.p_target_cam_m[np.arange(len(fp.frames)), ch] for fp, ch in zip(init.poses, init.choices, strict=True)]
    R_ctrl, P_ctrl = _spline_init(np.concatenate(ts), np.concatenate(ps), init.imu_t_s,
                                  init.R_target_w[0] @ init.R_w_imu, prob.pieces, prob.dt_s)
    R_ci0 = _common_world_frame(init, prob.gyro) if single_axis else list(init.R_cam_imu)
    intr0 = np.array([[b.camera.fx, b.camera.fy, b.camera.cx, b.camera.cy] for b in prob.cams])
    st = State(R_ctrl, P_ctrl, np.zeros((prob.n_bias, 6)), np.eye(3), np.asarray(R_ci0),
               np.zeros((len(prob.cams), 3)), np.asarray(init.shifts_s, dtype=np.float64),
               intr0 if prob.n_intr else None)
    st, _ = _linear_translation_init(prob, st, ps)
    if single_axis:  # rotation about one axis only (a flat road, --force)
        st = _resolve_single_axis(prob, st, ps)
    return st


def calibrate_imu_camera(
    observations: Sequence[CameraObservations],
    imu: ImuData,
    noise: ImuNoise,
    corners_target_m: npt.ArrayLike,
    options: ImuCameraOptions | None = None,
    *,
    intrinsics_covariance: Mapping[str, npt.ArrayLike] | None = None,
    progress: Progress | None = None,
) -> ImuCameraResult:
    """Estimate ``T_cam_imu`` and ``timeshift_cam_imu`` of every camera, jointly.

    Parameters
    ----------
    observations : sequence of CameraObservations
        Target corners per camera (stamps on each camera's clock) with the camera models.
    imu : ImuData
        Gyroscope and accelerometer in the IMU frame; its clock is the reference.
    noise : ImuNoise
        Continuous-time densities (``imu.yaml``); the residual weights.
    corners_target_m : array_like, shape (M, 3)
        The target's corners in its frame, indexed by corner id.
    options : ImuCameraOptions, optional
        Corner noise, knots, search ranges, thresholds, ``force`` and the reweighting (default:
        ``ImuCameraOptions()``).
    intrinsics_covariance : mapping camera name -> (8, 8) array, optional
        Covariance of ``fx, fy, cx, cy`` and the distortion coefficients from the camera
        calibration the intrinsics come from (``CameraCalibration.covariance``); the error of the
        parameters held in the solve is propagated into the reported standard deviations.
    progress : callable(fraction, label), optional

    Raises
    ------
    CalibrationError
        Missing intrinsics, too few target views, too little excitation (without ``force``);
        :class:`~.errors.ImuRateError` (rate mismatch with ``imu.yaml``) and
        :class:`~.errors.ImuCoverageError` (IMU stream not covering the images).
    """
    t_start = time.perf_counter()
    opts = ImuCameraOptions() if options is None else options
    step = _Progress(progress)
    corners = np.asarray(corners_target_m, dtype=np.float64).reshape(-1, 3)
    _check_inputs(observations, imu, noise, corners, opts.rate_tolerance)
    opts.check()
    step(0.0, "initialising")
    init = _initial_alignment(observations, imu, corners, opts)
    step(0.05, "building the problem")
    layout = _layout(init, opts)
    exc, forced_warning = _check_excitation(imu, layout, opts)
    prob = _problem(observations, imu, noise, corners, init, layout, opts)
    st = _initial_state(prob, init, single_axis=len(exc.weak_rotation_axes) >= 2)
    sol, noisy = _reweighted(_coarse_to_fine(prob, st, opts, step), opts, step)
    warn = [] if forced_warning is None else [forced_warning]
    warn += [f"camera {name}: reprojection error {r:.1f}x the rig's best camera's (poor frames, "
             "e.g. reconstructed from events); weighed down accordingly, its extrinsics and "
             "offset may be off by more than their std" for name, r in noisy.items()]
    step(0.95, "covariance")
    icov = {c: np.asarray(intrinsics_covariance[cb.name], dtype=np.float64)
            for c, cb in enumerate(sol.prob.cams)
            if intrinsics_covariance is not None and cb.name in intrinsics_covariance}
    result = _result(sol, _Report(exc, tuple(warn), opts.force, t_start, opts.keep_residuals), icov)
    for text in result.warnings:
        warnings.warn(text, IbiscapeWarning, stacklevel=2)
    step(1.0, "done")
    return result


@dataclass(frozen=True)
class _Progress:
    """``progress(fraction, label)`` when given."""

    callback: Progress | None

    def __call__(self, frac: float, label: str) -> None:
        if self.callback is not None:
            self.callback(frac, label)


@dataclass(frozen=True, eq=False)
class _Solution:
    """A solved problem: the state, the normal matrix there, iterations and convergence."""

    prob: Problem
    st: State
    iterations: int
    converged: bool
    H: Normal


def _coarse_to_fine(prob: Problem, st: State, opts: ImuCameraOptions, step: _Progress) -> _Solution:
    """Levenberg-Marquardt on the sparse normal equations: coarse knots, then the final ones."""
    fine = opts.knot_rate_hz > COARSE_KNOT_RATE_HZ
    sol = _solve(prob, st, COARSE_ITERATIONS if fine else opts.max_iterations, step,
                 (0.1, 0.5 if fine else 0.95), rel_tol=1e-5 if fine else 0.0)
    if not fine:
        return sol
    prob2, st2 = _refine(sol.prob, sol.st, 1.0 / opts.knot_rate_hz)
    sol2 = _solve(prob2, st2, opts.max_iterations, step, (0.5, 0.95))
    return replace(sol2, iterations=sol.iterations + sol2.iterations)


def _camera_noise(prob: Problem, st: State, opts: ImuCameraOptions
                  ) -> tuple[tuple[float, ...] | None, dict[str, float]]:
    """Each camera's corner noise for a second solve (None: keep the weights) and the cameras
    whose reprojection RMS exceeds the best camera's by :data:`NOISY_CAMERA_RATIO` (name -> ratio)."""
    if not (len(prob.cams) > 1 or opts.estimate_corner_noise):
        return None, {}
    rms = np.array([_camera_rms_px(prob, st, c) for c in range(len(prob.cams))])
    best = float(np.nanmin(rms)) if np.any(np.isfinite(rms)) else float("nan")
    ratio = rms / best
    sigmas: tuple[float, ...] | None = None
    if opts.estimate_corner_noise and np.all(np.isfinite(rms)):
        # each camera weighed by its own corner noise (the residual RMS of the first solve):
        # the nominal sigma_px usually overstates a good detector's noise several times, which
        # lets the accelerometer noise bend the trajectory the lever arms are read from
        sigmas = tuple(max(MIN_SIGMA_PX, float(rms[c])) for c in range(len(prob.cams)))
    elif (opts.reweight_cameras and np.all(np.isfinite(ratio)) and best > 0
          and ratio.max() > NOISY_CAMERA_RATIO):
        # cameras of unequal quality (RGB beside frames reconstructed from events): weigh each
        # by its own corner noise relative to the rig's best camera, so a poor camera cannot
        # drag the shared trajectory (and with it the others' extrinsics)
        sigmas = tuple(opts.sigma_px * max(1.0, float(ratio[c])) for c in range(len(prob.cams)))
    noisy: dict[str, float] = {}
    if opts.reweight_cameras and np.all(np.isfinite(ratio)):
        noisy = {cb.name: float(ratio[c]) for c, cb in enumerate(prob.cams) if ratio[c] > NOISY_CAMERA_RATIO}
    return sigmas, noisy


def _reweighted(sol: _Solution, opts: ImuCameraOptions, step: _Progress) -> tuple[_Solution, dict[str, float]]:
    """Solve again with each camera weighed by its own corner noise when :func:`_camera_noise`
    says so; returns the solution and the noisy cameras."""
    sigmas, noisy = _camera_noise(sol.prob, sol.st, opts)
    if sigmas is None:
        return sol, noisy
    prob = replace(sol.prob, cams=tuple(replace(cb, sigma_px=s) for cb, s in zip(sol.prob.cams, sigmas, strict=True)))
    again = _solve(prob, sol.st, opts.max_iterations, step, (0.9, 0.95))
    return replace(again, iterations=sol.iterations + again.iterations), noisy


def _trial_cost(prob: Problem, st: State) -> float:
    """The cost of a trial step; infinite when the step leaves the valid parameters (e.g. a
    refined focal length through zero), so that Levenberg-Marquardt shortens it."""
    try:
        return cost(prob, st)
    except IbiscapeError:
        return float("inf")


def _camera_rms_px(prob: Problem, st: State, c: int) -> float:
    """Reprojection RMS of camera ``c`` [px per coordinate]."""
    rc, _, _, valid = camera_block(prob, st, c, jac=False)
    e = rc[valid] * prob.cam_sigma_px(c)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def _refine(prob: Problem, st: State, dt: float) -> tuple[Problem, State]:
    """The same problem on knots every ``dt``; control points sampled from the coarse spline."""
    pieces, Rs, Ps = [], [], []
    off = 0
    keep = np.zeros(prob.imu_t_s.size, bool)
    for pc in prob.pieces:
        n2 = max(1, math.floor((pc.t1_s - pc.t0_s) / dt + 1e-9))
        # control point k sits near t0 + (k - 1) dt; the first and last lie just outside the
        # piece, where the end segments' polynomials are extended (no clamping: that would kink it)
        x = (pc.t0_s + (np.arange(n2 + 3) - 1) * dt - pc.t0_s) / prob.dt_s
        i = np.clip(np.floor(x).astype(np.int64), 0, pc.n_seg - 1)
        base, u = pc.offset + i, x - i
        R, _ = rotation(st.R_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s, angular_velocity=False)
        p, _, _ = position(st.P_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s)
        Rs.append(R)
        Ps.append(p)
        pieces.append(Piece(pc.t0_s, n2, off, dt))
        off += n2 + 3
        keep |= pieces[-1].covers(prob.imu_t_s)
    new = replace(prob, dt_s=dt, pieces=tuple(pieces), n_ctrl=off, imu_t_s=prob.imu_t_s[keep],
                  gyro=prob.gyro[keep], accel=prob.accel[keep])
    return new, replace(st, R_ctrl=np.concatenate(Rs), P_ctrl=np.concatenate(Ps))


class _BandedSchur:
    """Factorisation of the SPD normal matrix ``H`` (:class:`.problem.Normal`): banded Cholesky of
    the control points (interleaved rotation and position of each knot) plus the Schur complement
    of the small dense border (biases, gravity, cameras): a few ms where a general sparse LU takes
    seconds.  Raises ``numpy.linalg.LinAlgError`` when ``H`` is not positive definite."""

    def __init__(self, H: Normal):
        import scipy.linalg as la

        self.cf = la.cholesky_banded(H.band, lower=True, check_finite=False)
        self.B = H.border
        self.AiB = la.cho_solve_banded((self.cf, True), self.B, check_finite=False)
        self.S = la.cho_factor(H.dense - tdot(self.B, self.AiB), check_finite=False)
        self.ctrl, self.n = H.ctrl, H.n

    def solve(self, rhs: FloatArray) -> FloatArray:
        import scipy.linalg as la

        r = rhs.reshape(self.n, -1)
        nc6 = self.ctrl.size
        ra, rg = r[self.ctrl], r[nc6:]
        Ai_ra = la.cho_solve_banded((self.cf, True), ra, check_finite=False)
        xg = la.cho_solve(self.S, rg - tdot(self.B, Ai_ra), check_finite=False)
        xa = Ai_ra - rows_dot(self.AiB, xg)
        x = np.empty_like(r)
        x[self.ctrl], x[nc6:] = xa, xg
        return x.reshape(rhs.shape)


def _factor(H: Normal) -> Any:
    """A solver of the (damped) normal equations: banded Schur, else a sparse LU."""
    try:
        return _BandedSchur(H)
    except (np.linalg.LinAlgError, ValueError):
        from scipy.sparse.linalg import splu

        return splu(H.sparse(), permc_spec="COLAMD")


def _solve(prob: Problem, st: State, max_iterations: int, step: Callable[[float, str], None],
           span: tuple[float, float] = (0.1, 0.95), rel_tol: float = 0.0) -> _Solution:
    """Levenberg-Marquardt; stops when a step lowers chi^2 / 2 by less than 0.05 (moves no
    parameter by a noticeable fraction of its standard deviation) or by less than ``rel_tol``
    relative."""
    lam = 1e-4
    H, g, c0 = normal_equations(prob, st)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        step(span[0] + (span[1] - span[0]) * it / max_iterations, f"iteration {it}, cost {c0:.8g}")
        improved = False
        for _ in range(12):
            try:
                delta = _factor(H.plus_diagonal(lam * H.diagonal() + 1e-9)).solve(-g)
            except RuntimeError:
                lam *= 10
                continue
            cand = st.retract(prob, delta)
            c1 = _trial_cost(prob, cand)
            if np.isfinite(c1) and c1 < c0:
                improved = True
                break
            lam *= 10
        if not improved:
            converged = True  # no step lowers the cost: at the minimum to numerical precision
            break
        # extrapolate along the step while the cost keeps falling: in the weakly determined
        # directions Gauss-Newton converges linearly with short steps, this shortcut saves iterations
        alpha = 1.0
        while alpha < 64.0:
            cand2 = st.retract(prob, 2.0 * alpha * delta)
            c2 = _trial_cost(prob, cand2)
            if not (np.isfinite(c2) and c2 < c1):
                break
            cand, c1, alpha = cand2, c2, 2.0 * alpha
        decrease = c0 - c1
        st = cand
        lam = max(lam / 10, 1e-9)
        H, g, c0 = normal_equations(prob, st)
        if decrease < max(rel_tol * c0, ABS_COST_TOL):
            converged = True
            break
        # creeping along a weakly determined direction: the last steps moved the parameters by a
        # small fraction of their standard deviations
        converged = decrease < 10 * ABS_COST_TOL
    return _Solution(prob, st, it, converged, H)


@dataclass(frozen=True, eq=False)
class _Report:
    """What the result carries besides the solution: excitation, warnings so far, timing."""

    excitation: Excitation
    warnings: tuple[str, ...]
    forced: bool
    t_start: float
    keep_residuals: bool


def _result(sol: _Solution, rep: _Report, intrinsics_cov: dict[int, FloatArray]) -> ImuCameraResult:
    prob, st = sol.prob, sol.st
    gl = np.r_[prob.i_grav : prob.i_grav + 2 + prob.cam_width * len(prob.cams)]
    cov, plain, scales = _covariances(sol, gl, intrinsics_cov)
    r_imu, _, _, _ = imu_block(prob, st, jac=False)
    n_res = r_imu.size
    chi2 = float(np.sum(r_imu**2))
    cams, reproj = [], {}
    for c in range(len(prob.cams)):
        cal, chi2_c, n_c, series = _camera_result(prob, st, c, cov, plain)
        chi2 += chi2_c
        n_res += n_c
        cams.append(cal)
        if rep.keep_residuals:
            reproj[cal.name] = series
    warn = [*rep.warnings, *_weak_warnings(cams)]
    if not sol.converged:
        warn.append(f"the optimisation stopped after {sol.iterations} iterations without converging")
    res = None
    if rep.keep_residuals:
        res = ResidualSeries(prob.imu_t_s.copy(), r_imu[:, :3] * prob.sigma_gyro,
                             r_imu[:, 3:] * prob.sigma_accel, reproj)
    plain_sd = {prob.cams[c].name: _plain_std(plain, 2 + prob.cam_width * c) for c in range(len(prob.cams))}
    return ImuCameraResult(
        cameras=tuple(cams), gravity_target_m_s2=st.gravity(prob.gravity_m_s2),
        bias_t_s=(prob.bias_t0_s + prob.bias_dt_s * np.arange(prob.n_bias)).astype(np.float64),
        gyro_bias_rad_s=st.bias[:, :3].copy(), accel_bias_m_s2=st.bias[:, 3:].copy(),
        excitation=rep.excitation,
        gyro_rms_rad_s=float(np.sqrt(np.mean((r_imu[:, :3] * prob.sigma_gyro) ** 2))),
        accel_rms_m_s2=float(np.sqrt(np.mean((r_imu[:, 3:] * prob.sigma_accel) ** 2))),
        chi2_per_dof=chi2 / max(n_res - prob.n_params, 1), iterations=sol.iterations,
        converged=sol.converged, forced=rep.forced, warnings=tuple(warn), knot_spacing_s=prob.dt_s,
        runtime_s=time.perf_counter() - rep.t_start, residuals=res,
        uncertainty={"method": "sandwich: per-group residual variance, bias random-walk bridge, batch "
                     "means (1 s), held intrinsics", **scales,
                     "inflation": {"rotation": ROTATION_STD_INFLATION, "translation": 1.0, "timeshift": 1.0},
                     "std_plain": plain_sd})


def _covariances(sol: _Solution, gl: IntArray, intrinsics_cov: dict[int, FloatArray]
                 ) -> tuple[FloatArray, FloatArray, dict[str, Any]]:
    """The sandwich covariance of the parameters ``gl`` (:func:`.problem.estimate_covariance`),
    the plain ``(J^T J)^-1`` block and the covariance's scales."""
    prob = sol.prob
    E = np.zeros((prob.n_params, gl.size))
    E[gl, np.arange(gl.size)] = 1.0
    fac = _factor(sol.H.plus_diagonal(np.full(prob.n_params, 1e-12)))
    plain = fac.solve(E)[gl]
    cov, scales = estimate_covariance(prob, sol.st, fac.solve, gl, intrinsics_cov=intrinsics_cov or None)
    return cov, plain, scales


def _plain_std(plain: FloatArray, k: int) -> list[float]:
    """The plain standard deviations of one camera's 7 parameters from ``k``."""
    return list(np.sqrt(np.clip(np.diag(plain[k : k + 7, k : k + 7]), 0, None)).tolist())


def _camera_result(prob: Problem, st: State, c: int, cov: FloatArray, plain: FloatArray
                   ) -> tuple[CameraImuCalibration, float, int, tuple[FloatArray, FloatArray]]:
    """Camera ``c``'s calibration, its chi^2 and residual count, and its reprojection errors
    over time."""
    rc, _, _, valid = camera_block(prob, st, c, jac=False)
    e_px = rc[valid] * prob.cam_sigma_px(c)
    k = 2 + prob.cam_width * c
    cc = cov[k : k + 7, k : k + 7]
    var = np.clip(np.diag(cc), 0.0, None)
    R_ci = st.R_ci[c]
    cov_pos = R_ci.T @ cc[3:6, 3:6] @ R_ci  # position of the camera in the IMU frame (linear part)
    T = np.eye(4)
    T[:3, :3] = R_ci
    T[:3, 3] = st.t_ci[c]
    cal = CameraImuCalibration(
        prob.cams[c].name, st.camera(prob, c), T, float(st.shift_s[c]),
        ROTATION_STD_INFLATION * np.degrees(np.sqrt(var[:3])), np.sqrt(var[3:6]),
        np.sqrt(np.clip(np.diag(cov_pos), 0.0, None)), float(math.sqrt(var[6])),
        float(np.sqrt(np.mean(np.sum(e_px**2, axis=1)))) if len(e_px) else float("nan"),
        int(valid.any(axis=1).sum()), int(valid.sum()))
    t_obs = np.broadcast_to((prob.cams[c].t_s + st.shift_s[c])[:, None], valid.shape)[valid]
    return cal, float(np.sum(rc**2)), 2 * int(valid.sum()), (t_obs, e_px)


def _weak_warnings(cams: Sequence[CameraImuCalibration]) -> list[str]:
    """The directions whose std exceeds the observability thresholds."""
    warn = []
    for cal in cams:
        for ax, v in zip("xyz", cal.rotation_std_deg, strict=True):
            if v > WEAK_ROTATION_STD_DEG:
                warn.append(f"camera {cal.name}: rotation about IMU {ax} is weakly determined "
                            f"(std {v:.3f} deg > {WEAK_ROTATION_STD_DEG} deg)")
        for ax, v in zip("xyz", cal.position_std_imu_m, strict=True):
            if v > WEAK_TRANSLATION_STD_M:
                warn.append(f"camera {cal.name}: translation along IMU {ax} is weakly determined "
                            f"(std {v * 1e3:.1f} mm > {WEAK_TRANSLATION_STD_M * 1e3:.0f} mm)")
        if cal.timeshift_std_s > WEAK_TIMESHIFT_STD_S:
            warn.append(f"camera {cal.name}: time offset is weakly determined (std "
                        f"{cal.timeshift_std_s * 1e3:.3f} ms > {WEAK_TIMESHIFT_STD_S * 1e3} ms)")
    return warn
