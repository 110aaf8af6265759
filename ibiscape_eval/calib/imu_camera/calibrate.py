"""``calibrate_imu_camera``: T_cam_imu and timeshift_cam_imu of every camera of a rig in one problem.

Method (Furgale, Rehder & Siegwart, IROS 2013, as in Kalibr's ``kalibr_calibrate_imu_camera``): the
IMU pose ``T_target_imu(t)`` is a continuous-time cumulative cubic B-spline on SO(3) x R^3
(:mod:`.spline`); gyroscope, accelerometer and reprojection residuals are minimised jointly over the
spline, gravity in the target frame, slowly varying biases, and each camera's ``T_cam_imu`` and time
offset (:mod:`.problem`).  The sparse normal equations are solved by a Levenberg-Marquardt loop with
a sparse LU factorisation; the inverse of ``J^T J`` at the solution gives the parameter standard
deviations (the residuals are whitened by the IMU densities and the corner noise).

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
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import CalibrationError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.core.kalibr import ImuNoise

from .initial import FramePoses, align_rotations, frame_poses, integrate_gyro
from .inputs import CameraObservations, ImuData
from .problem import CameraBlock, Problem, State, camera_block, cost, imu_block, normal_equations
from .result import CameraImuCalibration, Excitation, ImuCameraResult, ResidualSeries
from .spline import basis, exp_so3, position, rotation

__all__ = ["calibrate_imu_camera"]

FloatArray = npt.NDArray[np.float64]
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
        raise CalibrationError(
            f"imu.yaml says update_rate {noise.update_rate_hz:g} Hz but the IMU data run at "
            f"{rate:.2f} Hz; fix update_rate or give the imu.yaml of this IMU")


def _pieces(times: FloatArray, dt: float, gap_s: float, margin_s: float,
            lo: float, hi: float) -> list[tuple[float, int, int]]:
    t = np.sort(times)
    cuts = np.flatnonzero(np.diff(t) > gap_s)
    out: list[tuple[float, int, int]] = []
    off = 0
    for a, b in zip(np.r_[0, cuts + 1], np.r_[cuts + 1, t.size], strict=True):
        t0 = max(lo, t[a] - margin_s)
        t1 = min(hi, t[b - 1] + margin_s)
        n_seg = max(1, math.ceil((t1 - t0) / dt))
        if t0 + n_seg * dt > hi:
            n_seg = max(1, math.floor((hi - t0) / dt))
        out.append((t0, n_seg, off))
        off += n_seg + 3
    return out


def _spline_init(t_s: FloatArray, p: FloatArray, imu_t: FloatArray, R_imu: FloatArray,
                 pieces: list[tuple[float, int, int]], dt: float) -> tuple[FloatArray, FloatArray]:
    """Control points: rotations slerped from ``R_imu`` at the IMU stamps, positions interpolated
    from the PnP positions ``p`` at times ``t_s`` (control point k sits near ``t0 + (k - 1) dt``)."""
    from scipy.spatial.transform import Rotation, Slerp

    order = np.argsort(t_s, kind="stable")
    t_s, p = t_s[order], p[order]
    slerp = Slerp(imu_t, Rotation.from_matrix(R_imu))
    Rs, Ps = [], []
    for t0, n_seg, _ in pieces:
        tau = t0 + (np.arange(n_seg + 3) - 1) * dt
        Rs.append(slerp(np.clip(tau, imu_t[0], imu_t[-1])).as_matrix())
        Ps.append(np.stack([np.interp(tau, t_s, p[:, a]) for a in range(3)], -1))
    return np.concatenate(Rs), np.concatenate(Ps)


def _linear_translation_init(prob: Problem, st: State, p_cam: list[FloatArray]) -> tuple[State, float]:
    """Positions, ``t_ci``, gravity and a constant accelerometer bias by one sparse linear
    least-squares solve with the rotations held: PnP camera positions ``p + R p_imu_cam`` and the
    accelerometer ``R^T (p'' - g) + b_a``.  PnP depth noise grows with the squared distance, so its
    rows are weighted by ``1 / (0.05 m + 1e-3 z^2)``."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    nc, C = prob.n_ctrl, len(prob.cams)
    n = 3 * nc + 3 * C + 3 + 3
    rows, cols, vals, rhs = [], [], [], []
    r0 = 0
    for c in range(C):
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
            ri = r0 + 3 * np.arange(F) + a
            for j in range(4):
                rows.append(ri)
                cols.append(3 * (base + j) + a)
                vals.append(w * b[:, j])
            for k in range(3):
                rows.append(ri)
                cols.append(np.full(F, 3 * nc + 3 * c + k))
                vals.append(w * M[:, a, k])
            rhs.append((ri, w * pc[:, a]))
        r0 += 3 * F
    base, u, _ = prob.locate(prob.imu_t_s)
    R, _ = rotation(st.R_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s, angular_velocity=False)
    _, _, ddb = basis(u)
    ddb = ddb / prob.dt_s**2
    N = len(u)
    wa = 1.0 / prob.sigma_accel
    ig, ib = 3 * nc + 3 * C, 3 * nc + 3 * C + 3
    for a in range(3):  # component a of R^T (sum ddb_j P_j - g) + b_a
        ri = r0 + 3 * np.arange(N) + a
        for j in range(4):
            for k in range(3):
                rows.append(ri)
                cols.append(3 * (base + j) + k)
                vals.append(wa * ddb[:, j] * R[:, k, a])
        for k in range(3):
            rows.append(ri)
            cols.append(np.full(N, ig + k))
            vals.append(-wa * R[:, k, a])
        rows.append(ri)
        cols.append(np.full(N, ib + a))
        vals.append(np.full(N, wa))
        rhs.append((ri, wa * prob.accel[:, a]))
    r0 += 3 * N
    # gravity near the mean of -R f (accelerations average out): keeps a poorly initialised
    # trajectory from trading gravity for a large acceleration
    g_mean = -np.einsum("nij,nj->i", R, prob.accel) / N
    g_mean *= prob.gravity_m_s2 / max(float(np.linalg.norm(g_mean)), 1e-9)
    for a in range(3):
        rows.append(np.array([r0 + a]))
        cols.append(np.array([ig + a]))
        vals.append(np.array([1.0 / 0.5]))
        rhs.append((np.array([r0 + a]), np.array([g_mean[a] / 0.5])))
    r0 += 3
    # the weak prior of the batch problem on t_ci (an unobservable lever arm stays near zero)
    for c in range(C):
        for a in range(3):
            rows.append(np.array([r0]))
            cols.append(np.array([3 * nc + 3 * c + a]))
            vals.append(np.array([1.0 / prob.trans_prior_sigma_m]))
            r0 += 1
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(r0, n))
    y = np.zeros(r0)
    for ri, v in rhs:
        y[ri] = v
    AtA = (A.T @ A).tocsc() + sp.identity(n, format="csc") * 1e-9
    x = splu(AtA, permc_spec="COLAMD").solve(A.T @ y)
    out = st.copy()
    out.P_ctrl = x[: 3 * nc].reshape(nc, 3)
    out.t_ci = x[3 * nc : 3 * nc + 3 * C].reshape(C, 3)
    g = x[ig : ig + 3]
    out.R_g = _align(np.array([0.0, 0.0, -1.0]), g)
    out.bias[:, 3:] = x[ib : ib + 3]
    return out, float(np.sum((A @ x - y) ** 2))


def _resolve_single_axis(prob: Problem, st: State, p_cam: list[FloatArray]) -> State:
    """Rotation about a single axis leaves the hand-eye problem a free angle about that axis:
    ``(X Rk(a), Y Rk(a))`` solves ``A X = Y B`` as well.  Choose it by the accelerometer: the angle
    whose linear translation fit (:func:`_linear_translation_init`) has the smallest residual."""
    w = prob.gyro
    k = np.linalg.eigh(w.T @ w)[1][:, -1]  # the excited axis (IMU frame)

    def rot(a: float) -> FloatArray:
        return exp_so3(k * a)

    def trial(a: float) -> tuple[State, float]:
        s2 = st.copy()
        Rk = rot(a)
        s2.R_ci = st.R_ci @ Rk
        s2.R_ctrl = st.R_ctrl @ Rk  # R_target_imu -> R_target_imu Rk about the excited axis
        return _linear_translation_init(prob, s2, p_cam)

    grid = np.radians(np.arange(-180.0, 180.0, 10.0))
    costs = [trial(a)[1] for a in grid]
    a0 = float(grid[int(np.argmin(costs))])
    fine = a0 + np.radians(np.arange(-10.0, 10.5, 1.0))
    costs = [trial(a)[1] for a in fine]
    return trial(float(fine[int(np.argmin(costs))]))[0]


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


def calibrate_imu_camera(
    observations: Sequence[CameraObservations],
    imu: ImuData,
    noise: ImuNoise,
    corners_target_m: npt.ArrayLike,
    *,
    sigma_px: float = 0.3,
    knot_rate_hz: float = 50.0,
    bias_knot_s: float = 10.0,
    max_shift_s: float = 0.1,
    gap_s: float = 1.0,
    min_corners: int = 6,
    min_rate_std_rad_s: float = 0.02,
    gravity_m_s2: float = 9.81,
    force: bool = False,
    refine_intrinsics: bool = False,
    max_iterations: int = 40,
    rate_tolerance: float = 0.05,
    keep_residuals: bool = True,
    reweight_cameras: bool = True,
    estimate_corner_noise: bool = False,
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
    sigma_px : float
        Corner noise [px].
    knot_rate_hz : float
        Knots of the trajectory spline per second.
    bias_knot_s : float
        Spacing of the bias knots [s] (random walk between them).
    max_shift_s : float
        Search range of the coarse time offset, ``+-`` seconds.
    gap_s : float
        Stretches without the target longer than this are cut out of the spline.
    min_corners : int
        Frames with fewer corners are ignored.
    min_rate_std_rad_s : float
        An IMU axis whose angular-rate std is below this counts as not excited.
    force : bool
        Estimate even when fewer than two rotation axes are excited (the translation is then not
        observable); the result carries warnings naming the weak directions.
    refine_intrinsics : bool
        Also estimate each camera's focal lengths and principal point (distortion held), from
        the given intrinsics: for intrinsics from a camera calibration of weakly tilted views.
    reweight_cameras : bool
        When a camera's reprojection RMS is more than 1.5 times the best camera's, weigh every
        camera by its RMS relative to the best one and solve again (a warning names the noisy
        cameras).
    estimate_corner_noise : bool
        Solve once with ``sigma_px``, then weigh every camera by its own reprojection RMS (at
        least 0.02 px) and solve again.
    progress : callable(fraction, label), optional

    Returns
    -------
    ImuCameraResult

    Raises
    ------
    CalibrationError
        Missing intrinsics, IMU stream not covering the images, rate mismatch with ``imu.yaml``,
        too few target views, too little excitation (without ``force``).
    """
    t_start = time.perf_counter()

    def step(frac: float, label: str) -> None:
        if progress is not None:
            progress(frac, label)

    corners = np.asarray(corners_target_m, dtype=np.float64).reshape(-1, 3)
    _check_inputs(observations, imu, noise, corners, rate_tolerance)
    if not (sigma_px > 0 and knot_rate_hz > 0 and bias_knot_s > 0 and max_shift_s >= 0):
        raise IbiscapeError("sigma_px, knot_rate_hz and bias_knot_s must be > 0, max_shift_s >= 0")
    step(0.0, "initialising")
    t_ref = int(imu.stamps_ns[0])
    imu_t = ((imu.stamps_ns - t_ref) * 1e-9).astype(np.float64)
    imu_lo, imu_hi = float(imu_t[0]), float(imu_t[-1])

    # ---- per-frame PnP, then offset and rotation against the integrated gyroscope
    R_w_imu = integrate_gyro(imu.gyro_rad_s, imu_t)
    poses: list[FramePoses] = []
    shifts, R_ci0, R_tw0, cam_t, choices = [], [], [], [], []
    for o in observations:
        fp = frame_poses(o, corners, min_corners=min_corners)
        if len(fp.frames) < 10:
            raise CalibrationError(
                f"camera {o.name}: the target was found in {len(fp.frames)} frames (with >= "
                f"{min_corners} corners); at least 10 are needed")
        t_c = ((o.stamps_ns - t_ref) * 1e-9).astype(np.float64)
        tf = t_c[fp.frames]
        if tf[0] < imu_lo - max_shift_s or tf[-1] > imu_hi + max_shift_s:
            raise CalibrationError(
                f"the IMU stream ({imu.stamps_ns[0]}..{imu.stamps_ns[-1]} ns) does not cover the "
                f"images of camera {o.name} ({o.stamps_ns[fp.frames[0]]}..{o.stamps_ns[fp.frames[-1]]}"
                " ns); give the IMU recording of the same run")
        al = align_rotations(tf, fp, imu_t, R_w_imu, max_shift_s=max_shift_s)
        keep = al.inliers
        fp = fp.subset(keep)
        poses.append(fp)
        choices.append(al.choice[keep])
        shifts.append(al.shift_s)
        R_ci0.append(al.R_cam_imu)
        R_tw0.append(al.R_target_w)
        cam_t.append(t_c)
    step(0.05, "building the problem")

    # ---- spline pieces over the (shifted) frame times
    dt = 1.0 / min(knot_rate_hz, COARSE_KNOT_RATE_HZ)
    all_t = np.concatenate([cam_t[c][poses[c].frames] + shifts[c] for c in range(len(observations))])
    margin = max(0.1, 3 * dt) + max_shift_s * 0.25
    pieces = _pieces(all_t, dt, gap_s, margin, imu_lo, imu_hi)
    n_ctrl = pieces[-1][2] + pieces[-1][1] + 3
    in_piece = np.zeros(imu_t.size, bool)
    for t0, n_seg, _ in pieces:
        in_piece |= (imu_t >= t0) & (imu_t <= t0 + n_seg * dt)
    span_lo = pieces[0][0]
    span_hi = pieces[-1][0] + pieces[-1][1] * dt
    n_bias = max(2, math.ceil((span_hi - span_lo) / bias_knot_s) + 1)
    bias_dt = (span_hi - span_lo) / (n_bias - 1)
    rate = imu.rate_hz
    exc = _excitation(imu.gyro_rad_s[in_piece], imu.accel_m_s2[in_piece],
                      float(sum(n * dt for _, n, _ in pieces)), min_rate_std_rad_s)
    warn: list[str] = []
    if not exc.translation_observable:
        msg = ("too little rotational excitation to observe the translation: angular-rate std "
               + ", ".join(f"{a}={v:.4f}" for a, v in zip("xyz", exc.gyro_std_rad_s, strict=True))
               + f" rad/s about the IMU axes (need >= {min_rate_std_rad_s} on at least two axes)")
        if not force:
            raise CalibrationError(msg + "; excite roll and pitch (bumps, waves) or use --force "
                                   "to estimate anyway and mark the weak directions")
        warn.append(msg + " (forced: the translation along the weak directions is not determined)")

    blocks = []
    for c, o in enumerate(observations):
        fr = poses[c].frames
        sel = np.isin(o.frame_index, fr)
        fi = o.frame_index[sel]
        rows = np.searchsorted(fr, fi)
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
        blocks.append(CameraBlock(o.name, o.camera, cam_t[c][fr], X, uv, mask))

    sg = noise.gyro_noise_density_rad_s_sqrt_hz * math.sqrt(rate)
    sa = noise.accel_noise_density_m_s2_sqrt_hz * math.sqrt(rate)
    walk = np.array([noise.gyro_random_walk_rad_s2_sqrt_hz] * 3
                    + [noise.accel_random_walk_m_s3_sqrt_hz] * 3) * math.sqrt(bias_dt)
    prob = Problem(dt, pieces, n_ctrl, span_lo, bias_dt, n_bias, imu_t[in_piece],
                   imu.gyro_rad_s[in_piece], imu.accel_m_s2[in_piece], sg, sa, walk,
                   gravity_m_s2, blocks, sigma_px, n_intr=4 if refine_intrinsics else 0)

    # ---- initial trajectory: rotation from the aligned gyro integral, positions from PnP (t_ci = 0)
    ts, ps = [], []
    for c in range(len(observations)):
        fp = poses[c]
        ts.append(blocks[c].t_s + shifts[c])
        ps.append(fp.p_target_cam_m[np.arange(len(fp.frames)), choices[c]])
    R_ctrl, P_ctrl = _spline_init(np.concatenate(ts), np.concatenate(ps), imu_t,
                                  R_tw0[0] @ R_w_imu, pieces, dt)
    if len(exc.weak_rotation_axes) >= 2:
        # one rotation axis k: each camera's hand-eye solution is free about k; bring them onto
        # camera 0's world frame (Y_c Rk(a) = Y_0) before choosing the common angle
        w = imu.gyro_rad_s[in_piece]
        k = np.linalg.eigh(w.T @ w)[1][:, -1]
        grid = np.radians(np.arange(-180.0, 180.0, 0.25))
        Rks = exp_so3(grid[:, None] * k)
        for c in range(1, len(observations)):
            a = int(np.argmin(np.linalg.norm(R_tw0[c] @ Rks - R_tw0[0], axis=(1, 2))))
            R_ci0[c] = R_ci0[c] @ Rks[a]
    intr0 = np.array([[b.camera.fx, b.camera.fy, b.camera.cx, b.camera.cy] for b in blocks])
    st = State(R_ctrl, P_ctrl, np.zeros((n_bias, 6)), np.eye(3), np.asarray(R_ci0),
               np.zeros((len(observations), 3)), np.asarray(shifts, dtype=np.float64),
               intr0 if refine_intrinsics else None)
    st, _ = _linear_translation_init(prob, st, ps)
    if len(exc.weak_rotation_axes) >= 2:  # rotation about one axis only (a flat road, --force)
        st = _resolve_single_axis(prob, st, ps)

    # ---- Levenberg-Marquardt on the sparse normal equations: coarse knots, then the final ones
    fine = knot_rate_hz > COARSE_KNOT_RATE_HZ
    st, iterations, converged, H = _solve(prob, st, COARSE_ITERATIONS if fine else max_iterations, step,
                                          (0.1, 0.5 if fine else 0.95), rel_tol=1e-5 if fine else 0.0)
    if fine:
        prob, st = _refine(prob, st, 1.0 / knot_rate_hz)
        st, it2, converged, H = _solve(prob, st, max_iterations, step, (0.5, 0.95))
        iterations += it2
    noisy: dict[str, float] = {}
    if len(prob.cams) > 1 or estimate_corner_noise:
        rms = np.array([_camera_rms_px(prob, st, c) for c in range(len(prob.cams))])
        best = float(np.nanmin(rms)) if np.any(np.isfinite(rms)) else float("nan")
        ratio = rms / best
        again = False
        if estimate_corner_noise and np.all(np.isfinite(rms)):
            # each camera weighed by its own corner noise (the residual RMS of the first solve):
            # the nominal sigma_px usually overstates a good detector's noise several times, which
            # lets the accelerometer noise bend the trajectory the lever arms are read from
            for c, cb in enumerate(prob.cams):
                cb.sigma_px = max(MIN_SIGMA_PX, float(rms[c]))
            again = True
        elif reweight_cameras and np.all(np.isfinite(ratio)) and best > 0 and ratio.max() > NOISY_CAMERA_RATIO:
            # cameras of unequal quality (RGB beside frames reconstructed from events): weigh each
            # by its own corner noise relative to the rig's best camera, so a poor camera cannot
            # drag the shared trajectory (and with it the others' extrinsics)
            for c, cb in enumerate(prob.cams):
                cb.sigma_px = sigma_px * max(1.0, float(ratio[c]))
            again = True
        if reweight_cameras and np.all(np.isfinite(ratio)):
            noisy = {cb.name: float(ratio[c]) for c, cb in enumerate(prob.cams) if ratio[c] > NOISY_CAMERA_RATIO}
        if again:
            st, it3, converged, H = _solve(prob, st, max_iterations, step, (0.9, 0.95))
            iterations += it3
    for name, r in noisy.items():
        warn.append(f"camera {name}: reprojection error {r:.1f}x the rig's best camera's (poor "
                    "frames, e.g. reconstructed from events); weighed down accordingly, its "
                    "extrinsics and offset may be off by more than their std")
    step(0.95, "covariance")
    result = _result(prob, st, H, exc, warn, iterations, converged, force, t_start,
                     observations, keep_residuals)
    for text in result.warnings:
        warnings.warn(text, IbiscapeWarning, stacklevel=2)
    step(1.0, "done")
    return result


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
    for t0, n_seg, off_old in prob.pieces:
        t1 = t0 + n_seg * prob.dt_s
        n2 = max(1, math.floor((t1 - t0) / dt + 1e-9))
        # control point k sits near t0 + (k - 1) dt; the first and last lie just outside the
        # piece, where the end segments' polynomials are extended (no clamping: that would kink it)
        x = (t0 + (np.arange(n2 + 3) - 1) * dt - t0) / prob.dt_s
        i = np.clip(np.floor(x).astype(np.int64), 0, n_seg - 1)
        base, u = off_old + i, x - i
        R, _ = rotation(st.R_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s, angular_velocity=False)
        p, _, _ = position(st.P_ctrl[base[:, None] + np.arange(4)], u, prob.dt_s)
        Rs.append(R)
        Ps.append(p)
        pieces.append((t0, n2, off))
        off += n2 + 3
        keep |= (prob.imu_t_s >= t0) & (prob.imu_t_s <= t0 + n2 * dt)
    new = replace(prob, dt_s=dt, pieces=pieces, n_ctrl=off, imu_t_s=prob.imu_t_s[keep],
                  gyro=prob.gyro[keep], accel=prob.accel[keep])
    st2 = st.copy()
    st2.R_ctrl = np.concatenate(Rs)
    st2.P_ctrl = np.concatenate(Ps)
    return new, st2


class _BandedSchur:
    """Factorisation of the SPD normal matrix ``H``: the control points (interleaved rotation and
    position of each knot) form a banded block, the rest (biases, gravity, cameras) a small dense
    border; banded Cholesky plus the Schur complement of the border (a few ms where a general
    sparse LU takes seconds).  Raises ``numpy.linalg.LinAlgError`` when ``H`` is not positive
    definite."""

    def __init__(self, prob: Problem, H: Any):
        import scipy.linalg as la
        import scipy.sparse as sp

        nc = prob.n_ctrl
        k = np.arange(nc)
        ctrl = np.stack([3 * k, 3 * k + 1, 3 * k + 2, 3 * nc + 3 * k, 3 * nc + 3 * k + 1,
                         3 * nc + 3 * k + 2], -1).ravel()
        glob = np.arange(6 * nc, prob.n_params)
        Hc = sp.csr_matrix(H)
        A = Hc[ctrl][:, ctrl].tocoo()
        lower = A.row >= A.col
        bw = int((A.row[lower] - A.col[lower]).max(initial=0))
        ab = np.zeros((bw + 1, ctrl.size))
        ab[(A.row - A.col)[lower], A.col[lower]] = A.data[lower]
        self.cf = la.cholesky_banded(ab, lower=True, check_finite=False)
        self.B = Hc[ctrl][:, glob].toarray()
        self.AiB = la.cho_solve_banded((self.cf, True), self.B, check_finite=False)
        S = Hc[glob][:, glob].toarray() - self.B.T @ self.AiB
        self.S = la.cho_factor(S, check_finite=False)
        self.ctrl, self.glob, self.n = ctrl, glob, prob.n_params

    def solve(self, rhs: FloatArray) -> FloatArray:
        import scipy.linalg as la

        r = rhs.reshape(self.n, -1)
        ra, rg = r[self.ctrl], r[self.glob]
        Ai_ra = la.cho_solve_banded((self.cf, True), ra, check_finite=False)
        xg = la.cho_solve(self.S, rg - self.B.T @ Ai_ra, check_finite=False)
        xa = Ai_ra - self.AiB @ xg
        x = np.empty_like(r)
        x[self.ctrl], x[self.glob] = xa, xg
        return x.reshape(rhs.shape)


def _factor(prob: Problem, A: Any) -> Any:
    """A solver of the damped normal equations: banded Schur, else a sparse LU."""
    try:
        return _BandedSchur(prob, A)
    except (np.linalg.LinAlgError, ValueError):
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        return splu(sp.csc_matrix(A), permc_spec="COLAMD")


def _solve(prob: Problem, st: State, max_iterations: int, step: Callable[[float, str], None],
           span: tuple[float, float] = (0.1, 0.95), rel_tol: float = 0.0
           ) -> tuple[State, int, bool, Any]:
    """Levenberg-Marquardt; stops when a step lowers chi^2 / 2 by less than 0.05 (moves no
    parameter by a noticeable fraction of its standard deviation) or by less than ``rel_tol``
    relative."""
    import scipy.sparse as sp

    lam = 1e-4
    H, g, c0 = normal_equations(prob, st)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        step(span[0] + (span[1] - span[0]) * it / max_iterations, f"iteration {it}, cost {c0:.8g}")
        improved = False
        for _ in range(12):
            d_h = np.asarray(H.diagonal())
            A = H + sp.diags(lam * d_h + 1e-9, format="csc")
            try:
                delta = _factor(prob, A).solve(-g)
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
    return st, it, converged, H


def _result(prob: Problem, st: State, H: Any, exc: Excitation, warn: list[str], iterations: int,
            converged: bool, forced: bool, t_start: float, observations: Sequence[CameraObservations],
            keep_residuals: bool) -> ImuCameraResult:
    import scipy.sparse as sp

    C = len(prob.cams)
    w = prob.cam_width
    gl = np.r_[prob.i_grav : prob.i_grav + 2 + w * C]
    Hs = sp.csc_matrix(H) + sp.identity(prob.n_params, format="csc") * 1e-12
    E = np.zeros((prob.n_params, gl.size))
    E[gl, np.arange(gl.size)] = 1.0
    cov = _factor(prob, Hs).solve(E)[gl]
    r_imu, _, _, _ = imu_block(prob, st, jac=False)
    n_res = r_imu.size
    chi2 = float(np.sum(r_imu**2))
    cams = []
    reproj = {}
    for c in range(C):
        rc, _, _, valid = camera_block(prob, st, c, jac=False)
        chi2 += float(np.sum(rc**2))
        n_res += 2 * int(valid.sum())
        e_px = rc[valid] * prob.cam_sigma_px(c)
        k = 2 + w * c
        cc = cov[k : k + 7, k : k + 7]
        var = np.clip(np.diag(cc), 0.0, None)
        R_ci = st.R_ci[c]
        cov_pos = R_ci.T @ cc[3:6, 3:6] @ R_ci  # position of the camera in the IMU frame (linear part)
        T = np.eye(4)
        T[:3, :3] = R_ci
        T[:3, 3] = st.t_ci[c]
        cams.append(CameraImuCalibration(
            prob.cams[c].name, st.camera(prob, c), T, float(st.shift_s[c]),
            np.degrees(np.sqrt(var[:3])), np.sqrt(var[3:6]),
            np.sqrt(np.clip(np.diag(cov_pos), 0.0, None)), float(math.sqrt(var[6])),
            float(np.sqrt(np.mean(np.sum(e_px**2, axis=1)))) if len(e_px) else float("nan"),
            int(valid.any(axis=1).sum()), int(valid.sum())))
        if keep_residuals:
            t_obs = np.broadcast_to((prob.cams[c].t_s + st.shift_s[c])[:, None], valid.shape)[valid]
            reproj[prob.cams[c].name] = (t_obs, e_px)
    n_par = prob.n_params
    chi2_dof = chi2 / max(n_res - n_par, 1)
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
    if not converged:
        warn.append(f"the optimisation stopped after {iterations} iterations without converging")
    res = None
    if keep_residuals:
        res = ResidualSeries(prob.imu_t_s.copy(), r_imu[:, :3] * prob.sigma_gyro,
                             r_imu[:, 3:] * prob.sigma_accel, reproj)
    bias_t = (prob.bias_t0_s + prob.bias_dt_s * np.arange(prob.n_bias)).astype(np.float64)
    return ImuCameraResult(
        tuple(cams), st.gravity(prob.gravity_m_s2), bias_t, st.bias[:, :3].copy(),
        st.bias[:, 3:].copy(), exc,
        float(np.sqrt(np.mean((r_imu[:, :3] * prob.sigma_gyro) ** 2))),
        float(np.sqrt(np.mean((r_imu[:, 3:] * prob.sigma_accel) ** 2))),
        chi2_dof, iterations, converged, forced, tuple(warn), prob.dt_s,
        time.perf_counter() - t_start, res)

