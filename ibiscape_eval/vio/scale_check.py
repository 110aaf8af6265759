"""The depth unit checked by physics: the IMU measures metric motion, the depth gives it too.

A depth image read in the wrong unit is wrong by a factor (a TUM RGB-D file, 5000 per metre, read
as millimetres: 5x too far; millimetres read as TUM: 5x too near; metres against millimetres:
1000x), and nothing in one image tells.  Over a window of frames the RGB-D odometry (KLT tracks,
their 3D points from the depth, PnP against a keyframe) gives the camera's path at the depth's
scale ``c_k``; the IMU, preintegrated from the window's first frame (``Delta p_0k``, body frame),
gives it in metres.  With the start velocity ``v_0`` and gravity ``g`` (body frame) unknown, the
inverse scale ``lam`` solves the linear least-squares problem

    lam R_bc c_k + (t_bc - R_0k t_bc) = v_0 t_k + g t_k^2 / 2 + Delta p_0k

(the lever arm ``t_bc`` of the camera is metric whatever the depth's unit; Qin and Shen's
visual-inertial alignment, IROS 2017, with the scale of a monocular map in place of the depth's).
``factor = 1 / lam`` is the depth's distance over the true one: 1 for the right unit, 5 for a TUM
file read as millimetres.

The scale is only observable while the acceleration changes (a start, a brake, a turn): a still
platform, or constant velocity along a line, leaves ``lam`` free, and a steady acceleration is
told from a tilted gravity only by a known gravity.  So the window that counts starts where a
standstill ends (the IMU quiet and the image still for ``still_window_s``), with gravity measured
at the standstill's first still frame and carried to its end by the gyro, and ``v_0`` still free;
its uncertainty (``GRAVITY_SIGMA_M_S2``) enters the factor's.  Without a standstill, windows of
``window_s`` (overlapping by half) fit gravity too, and the latest two that can tell must agree.
The odometry's residuals drift along a window, so they are counted as ONE error (their sum of
squares scales the covariance): ``sigma_log``, the 1-sigma of ``ln(factor)``, is a conservative
bound.  A factor ``N_SIGMA`` sigmas outside ``[1/BAND, BAND]`` is ``wrong``; within the band and
``N_SIGMA`` sigmas short of ``DETECT`` either way it is ``ok``; else the window cannot tell.
Factors between 1/2 and 2 are never refused: the units a depth file can be misread in differ by
5x or more, and a calibration error is not the unit's.  When no window tells within the first
``max_s`` the check says so (a warning from :func:`check_depth_scale`), never a refusal.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeWarning

from .backend import GRAVITY_M_S2, StereoObservations, imu_params, integrate_imu
from .depth import DEPTH_STEP_M, DepthFrontEnd, DepthOptions
from .params import VioParams
from .rig import RectifiedStereo

__all__ = ["DepthScale", "check_depth_scale", "measure_depth_scale"]

FloatArray = npt.NDArray[np.float64]

#: seconds of frames per fitted window, and how far into the sequence to look for motion
WINDOW_S = 3.0
MAX_S = 30.0
#: factors within [1 / BAND, BAND] are never refused
BAND = 2.0
#: the smallest factor a misread unit gives (TUM's 5000 per metre against millimetres)
DETECT = 5.0
#: uncertainty of the standstill's gravity per axis [m/s^2]: an accelerometer bias, the tilt of a
#: standstill that is not quite one, the gyro's drift until the window starts
GRAVITY_SIGMA_M_S2 = 0.1
#: a fit whose |g| is further than this from gravity is not trusted
GRAVITY_TOL_M_S2 = 1.0
#: the image is still when the median track moves less than this between frames [px]
STILL_FLOW_PX = 0.2
#: the fewest corners with depth a frame's PnP (and the still image's flow) takes: a 16-bit unit
#: of 0.2 mm ends at 13 m, so outdoors a misread TUM file leaves few corners with a depth
MIN_POINTS = 6
#: a new keyframe when fewer corners than this (or than half of its own) are still tracked
KEYFRAME_POINTS = 24
#: how many sigmas the factor must lie outside the band to be refused
N_SIGMA = 2.0


@dataclass(frozen=True)
class DepthScale:
    """The depth's scale measured against the IMU.

    Attributes
    ----------
    status : str
        ``ok`` (the factor is within the band), ``wrong`` (outside it by ``N_SIGMA``),
        ``not measured`` (no window was conclusive; ``reason`` says why).
    factor : float
        Depth-derived distance over the IMU's (NaN when not measured).
    sigma_log : float
        1-sigma of ``ln(factor)``.
    start_s, end_s : float
        The window that decided, from the first frame.
    motion_m : float
        Path of the camera in that window [m, metric].
    gravity_m_s2 : float
        ``|g|`` of the fit.
    windows : int
        Windows fitted.
    reason : str
    """

    status: str
    factor: float = float("nan")
    sigma_log: float = float("nan")
    start_s: float = float("nan")
    end_s: float = float("nan")
    motion_m: float = float("nan")
    gravity_m_s2: float = float("nan")
    windows: int = 0
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (JSON; NaN as None)."""
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class _Window:
    factor: float
    sigma_log: float
    motion_m: float
    gravity_m_s2: float
    start_ns: int
    end_ns: int
    anchored: bool = False

    @property
    def verdict(self) -> str:
        """``wrong``: the factor lies ``N_SIGMA`` outside ``[1 / BAND, BAND]``; ``ok``: within
        the band, and ``N_SIGMA`` short of ``DETECT`` either way (a misread unit would have shown);
        empty: the window cannot tell (or its fit is not physics: ``|g|`` is not gravity)."""
        if not (math.isfinite(self.sigma_log) and math.isfinite(self.factor)
                and abs(self.gravity_m_s2 - GRAVITY_M_S2) <= GRAVITY_TOL_M_S2):
            return ""
        ln, reach = math.log(self.factor), N_SIGMA * self.sigma_log
        if abs(ln) - reach > math.log(BAND):
            return "wrong"
        if abs(ln) <= math.log(BAND) and abs(ln) + reach < math.log(DETECT):
            return "ok"
        return ""


def _preintegrated(imu: tuple[Any, FloatArray, FloatArray], pim_params: Any, t0: int, t1: int
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(Delta R, Delta v, Delta p)`` of the IMU between two frames (body frame, zero bias)."""
    import gtsam

    pim = gtsam.PreintegratedCombinedMeasurements(pim_params, gtsam.imuBias.ConstantBias())
    integrate_imu(pim, imu[0], imu[1], imu[2], t0, t1)
    return (np.asarray(pim.deltaRij().matrix()), np.asarray(pim.deltaVij()),
            np.asarray(pim.deltaPij()))


def _odometry(frames: list[StereoObservations], rect: RectifiedStereo, min_points: int
              ) -> list[FloatArray] | None:
    """``T_c0_ck`` (rectified camera) of the frames at the depth's scale, by PnP of each frame
    against a keyframe's 3D points (a new keyframe when fewer than half of them or than
    ``KEYFRAME_POINTS`` are seen); up to
    the first frame whose PnP fails (fog, a blank wall)."""
    import cv2

    thr = max(1.0, 2.0 * rect.width_px / 512.0)
    T_c0_cref = np.eye(4)
    ref = frames[0]
    if len(ref) < min_points:
        return None
    # in units of the first frame's median depth: PnP's iterations stop at absolute tolerances,
    # and depth wrong by a factor must give the same path times that factor
    ref_pts = rect.triangulate(ref.uL, ref.uR, ref.v)
    unit = float(np.median(ref_pts[:, 2]))
    ref_pts = ref_pts / unit
    out = [np.eye(4)]
    for fr in frames[1:]:
        common, i0, i1 = np.intersect1d(ref.ids, fr.ids, return_indices=True)
        if len(common) < min_points:
            break
        img = np.stack([fr.uL[i1], fr.v[i1]], axis=1).astype(np.float64)
        ok, rvec, tvec, inl = cv2.solvePnPRansac(ref_pts[i0].astype(np.float64), img, rect.K, None,
                                                 reprojectionError=thr, iterationsCount=100,
                                                 confidence=0.999, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok or inl is None or len(inl) < min_points:
            break
        T_ck_cref = np.eye(4)
        T_ck_cref[:3, :3] = cv2.Rodrigues(rvec)[0]
        T_ck_cref[:3, 3] = np.asarray(tvec).ravel()
        T_c0_ck = T_c0_cref @ np.linalg.inv(T_ck_cref)
        out.append(T_c0_ck)
        if len(common) < max(KEYFRAME_POINTS, len(ref.ids) // 2):
            ref, T_c0_cref = fr, T_c0_ck
            ref_pts = rect.triangulate(ref.uL, ref.uR, ref.v) / unit
    for T in out:
        T[:3, 3] *= unit
    return out


def _fit(frames: list[StereoObservations], deltas: list[tuple[FloatArray, FloatArray, FloatArray]],
         rect: RectifiedStereo, min_points: int, g_body: FloatArray | None = None) -> _Window | None:
    """The factor of one window (module docstring); ``deltas[k]`` is the IMU from frame k-1 to
    k (``deltas[0]`` unused); ``g_body``: gravity in the first frame's body frame when known (a
    standstill before it), else fitted.  None when the odometry fails."""
    poses = _odometry(frames, rect, min_points)
    if poses is None or len(poses) < max(len(frames) // 2, 10):
        return None
    frames = frames[:len(poses)]
    R_bc, t_bc = rect.T_body_rect[:3, :3], rect.T_body_rect[:3, 3]
    t0 = frames[0].stamp_ns
    R, v, p = np.eye(3), np.zeros(3), np.zeros(3)
    k_g = 4 if g_body is None else 0
    rows, rhs = [], []
    for k in range(1, len(frames)):
        dR, dv, dp = deltas[k]
        dt = (frames[k].stamp_ns - frames[k - 1].stamp_ns) * 1e-9
        p = p + v * dt + R @ dp
        v = v + R @ dv
        R = R @ dR
        t = (frames[k].stamp_ns - t0) * 1e-9
        T = poses[k]
        row = np.zeros((3, 4 + 3 * (g_body is None)))
        row[:, 0] = R_bc @ T[:3, 3]
        row[:, 1:4] = -t * np.eye(3)
        b = p - (t_bc - R_bc @ T[:3, :3] @ R_bc.T @ t_bc)
        if g_body is None:
            row[:, 4:] = -0.5 * t * t * np.eye(3)
        else:
            b = b + 0.5 * t * t * g_body
        rows.append(row)
        rhs.append(b)
    A, b = np.concatenate(rows), np.concatenate(rhs)
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    r = b - A @ x
    # the odometry's errors drift (correlated along the window): the residuals are not counted
    # as independent, so the sum of their squares, not its mean, scales the covariance
    try:
        var_lam = float(r @ r) * float(np.linalg.inv(A.T @ A)[0, 0])
    except np.linalg.LinAlgError:
        var_lam = math.inf
    if g_body is not None:  # a gravity off by dg moves lam by (dlam/dg) dg: a steady
        # acceleration is told from a tilt only by the standstill's gravity
        tt = np.repeat([(fr.stamp_ns - t0) * 1e-9 for fr in frames[1:]], 3)
        G = 0.5 * tt[:, None] ** 2 * np.tile(np.eye(3), (len(frames) - 1, 1))
        dlam_dg = np.linalg.lstsq(A, G, rcond=None)[0][0]
        var_lam += GRAVITY_SIGMA_M_S2 ** 2 * float(dlam_dg @ dlam_dg)
    lam = float(x[0])
    sig = math.sqrt(max(var_lam, 0.0)) / lam if lam > 0 else math.inf
    cams = np.array([P[:3, 3] for P in poses]) * (lam if lam > 0 else np.nan)
    motion = float(np.linalg.norm(np.diff(cams, axis=0), axis=1).sum())
    g = float(np.linalg.norm(x[k_g:k_g + 3])) if g_body is None else float(np.linalg.norm(g_body))
    return _Window(1.0 / lam if lam > 0 else math.inf, sig, motion, g, int(t0),
                   int(frames[-1].stamp_ns), g_body is not None)


def measure_depth_scale(seq: Any, params: VioParams | None = None, options: DepthOptions | None = None,
                        *, window_s: float = WINDOW_S, max_s: float = MAX_S,
                        max_frames: int | None = None, scale: float = 1.0) -> DepthScale:
    """The depth's scale against the IMU over the first ``max_s`` of an RGB-D
    :class:`~ibiscape_eval.vio.inputs.StereoSequence` (module docstring).  ``scale`` multiplies
    every depth read (tests and the benchmark: a misread unit without rewriting files);
    ``max_frames`` bounds the frames read."""
    p = params or VioParams.for_setup("rgbd")
    stamps = np.asarray(seq.frame_stamps_ns, np.int64)
    n = int(np.searchsorted(stamps, stamps[0] + int(max_s * 1e9), side="right")) if len(stamps) else 0
    n = n if max_frames is None else min(n, max_frames)
    fps = (len(stamps) - 1) / max((int(stamps[-1]) - int(stamps[0])) * 1e-9, 1e-9) if n > 1 else 0.0
    per = max(round(window_s * fps) + 1, 10)
    if n < per:
        return DepthScale("not measured", reason=f"{n} frames, fewer than a {window_s:g} s window")
    fe = DepthFrontEnd(seq.rig, p, seq.depth_unit or "mm", options)
    rect = seq.rig.rectified()
    pim_params = imu_params(seq.noise, 1.0, seq.T_body_imu)
    w, h = seq.rig.size
    obs: list[StereoObservations] = []
    deltas: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    fitted: list[_Window] = []
    still = _Standstill(max(round(p.still_window_s * fps), 2))
    for i in range(n):
        t = int(stamps[i])
        d = (_preintegrated(seq.imu, pim_params, int(stamps[i - 1]), t) if i
             else (np.eye(3), np.zeros(3), np.zeros(3)))
        left, depth = seq.read_pair(i)
        if left.shape != (h, w) or depth.shape != (h, w):
            break  # the estimator's own pass names the file
        deltas.append(d)
        obs.append(fe.process(t, left, depth if scale == 1.0 else depth * np.float32(scale),
                              d[0] if i else None, gated=False))
        g = _quiet_gravity(seq, p, t)
        first = int(np.searchsorted(stamps, t - int(p.still_window_s * 1e9)))
        still.update(i, g if g is not None and first < i and _image_still(obs, first, MIN_POINTS)
                     else None, d[0])
        wins = []
        if still.anchor is not None and i + 1 - still.anchor[0] >= per:
            a, g_a = still.anchor
            wins.append(_fit(obs[a:], deltas[a:], rect, MIN_POINTS, g_a))
            still.anchor = None
        if i + 1 >= per and (i + 1 - per) % (per // 2) == 0:
            wins.append(_fit(obs[i + 1 - per:], deltas[i + 1 - per:], rect, MIN_POINTS))
        new = [x for x in wins if x is not None]
        fitted += new
        done = _decided(fitted, int(stamps[0])) if new else None
        if done is not None:
            return done
    return _undecided(fitted, stamps[0], n, window_s)


class _Standstill:
    """Where the last standstill ended (the window to fit starts there) and gravity in the body
    frame then: measured at the standstill's FIRST still frame (at its end a departing car may
    already accelerate while the IMU looks quiet and the image still at a low resolution) and
    carried to its end by the gyro.  A standstill counts from ``min_frames`` still frames in a
    row (a still test flickering on for a frame or two while the car pulls away is none)."""

    def __init__(self, min_frames: int) -> None:
        self.min_frames = min_frames
        self.anchor: tuple[int, FloatArray] | None = None
        self._g: FloatArray | None = None  # gravity of the running standstill, at the last frame
        self._run = 0

    def update(self, i: int, g_still: FloatArray | None, dR: FloatArray) -> None:
        """Frame ``i``: gravity when it is still, else None; ``dR`` the rotation since frame i-1."""
        if g_still is None:
            self._g, self._run = None, 0
            return
        self._g = g_still if self._g is None else dR.T @ self._g
        self._run += 1
        if self._run >= self.min_frames:
            self.anchor = (i, self._g)


def _quiet_gravity(seq: Any, p: VioParams, t_ns: int) -> FloatArray | None:
    """Gravity in the body frame (minus the mean specific force) when the IMU was quiet over the
    ``still_window_s`` up to ``t_ns`` (:func:`~ibiscape_eval.vio.initialise.standstill_at`), else
    None.  Quiet is not still: a steady cruise is quiet too (and its mean specific force is
    gravity as well), and so is a smooth start (whose is not: the first window of a quiet run is
    the one to take)."""
    from .initialise import mean_specific_force, standstill_at

    stamps, _, acc = seq.imu
    t0 = t_ns - int(p.still_window_s * 1e9)
    if not standstill_at(stamps, seq.gyro_rad_s, acc, t0, p).still:
        return None
    return -mean_specific_force(stamps, acc, t0, t_ns, np.asarray(seq.T_body_imu, np.float64)[:3, :3])


def _rows(have: npt.NDArray[np.int64], want: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """Where each of ``want`` (all present) sits in ``have``."""
    order = np.argsort(have, kind="stable")
    return np.asarray(order[np.searchsorted(have, want, sorter=order)], np.intp)


def _image_still(obs: list[StereoObservations], first: int, min_points: int) -> bool:
    """The corners seen in every frame from ``first`` to the last did not move beyond their
    jitter: a median displacement within ``STILL_FLOW_PX``, or tracks that wander rather than
    go somewhere (median displacement under half of the path along the frames: motion adds up,
    jitter does not; rain and noise at a low resolution jitter by half a pixel)."""
    ids = obs[first].ids
    for o in obs[first + 1:]:
        ids = np.intersect1d(ids, o.ids)
    if len(ids) < min_points:
        return False
    pts = np.stack([np.column_stack([o.uL, o.v])[_rows(o.ids, ids)] for o in obs[first:]])
    disp = np.linalg.norm(pts[-1] - pts[0], axis=1)
    path = np.linalg.norm(np.diff(pts, axis=0), axis=2).sum(axis=0)
    if float(np.median(disp)) <= STILL_FLOW_PX:
        return True
    return float(np.median(disp / np.maximum(path, 1e-9))) < 0.5


def _result(status: str, w: _Window, t0: int, n: int, reason: str = "") -> DepthScale:
    return DepthScale(status, w.factor, w.sigma_log, float(w.start_ns - t0) * 1e-9, float(w.end_ns - t0) * 1e-9,
                      w.motion_m, w.gravity_m_s2, n, reason)


def _decided(fitted: list[_Window], t0: int) -> DepthScale | None:
    """The verdict of the latest window when it starts at a standstill (gravity known), or that
    of the latest two free windows with a verdict when they agree (a cruise between them tells
    nothing: constant velocity leaves the factor free)."""
    last = fitted[-1]
    if last.anchored and last.verdict:
        return _result(last.verdict, last, t0, len(fitted))
    told = [w for w in fitted if not w.anchored and w.verdict]
    if len(told) >= 2 and told[-1] is last and told[-2].verdict == last.verdict:
        return _result(last.verdict, last, t0, len(fitted))
    return None


def _undecided(fitted: list[_Window], t0: int, n: int, window_s: float) -> DepthScale:
    if not fitted:
        why = "the RGB-D odometry held in no window (too few tracked corners with depth)"
    else:
        best = min(fitted, key=lambda w: w.sigma_log)
        why = (f"too little change of acceleration (a start, a brake, a turn): ln(factor) to "
               f"+-{best.sigma_log:.2f} at best")
    return DepthScale("not measured", windows=len(fitted),
                      reason=f"{why}, in {len(fitted)} windows of {window_s:g} s over {n} frames")


def check_depth_scale(seq: Any, params: VioParams | None = None, options: Any = None, *,
                      max_frames: int | None = None) -> DepthScale:
    """:func:`measure_depth_scale`, acted on: a depth ``wrong`` by a factor is refused, naming
    the depth folder, the factor and the unit that explains it; a check that could not run is a
    warning (so is a median depth outside the front end's range, which holds without motion).
    ``max_frames``: look at no more frames than the run reads.

    Raises
    ------
    FormatError
        The depth is ``wrong`` (:class:`DepthScale`); its ``hint`` is the unit that explains the
        factor, when one does.
    """
    from ibiscape_eval.core.errors import Remedy

    o = options if isinstance(options, DepthOptions) else DepthOptions()
    unit = seq.depth_unit or "mm"
    depth_file = Path(seq.frame_labels(0)[1])
    folder = depth_file.parent
    _check_range(seq, o, depth_file, unit)
    res = measure_depth_scale(seq, params, o, max_frames=max_frames)
    if res.status == "not measured":
        warnings.warn(f"{folder}: the depth unit ({unit}) could not be checked against the IMU: "
                      f"{res.reason}; make sure it is right", IbiscapeWarning, stacklevel=2)
    elif res.status == "wrong":
        f = res.factor
        how = f"{f:.3g}x too far" if f > 1 else f"{1 / f:.3g}x too near"
        seen = (f"(its path over {res.start_s:.1f}-{res.end_s:.1f} s is {f:.3g}x the IMU's, "
                f"sigma of ln {res.sigma_log:.2f})")
        better = _explaining_unit(unit, f)
        if better is None:
            raise FormatError(folder, f"depth looks {how} {seen}; no depth unit explains it: check "
                              "the depth camera's scale (ORB-SLAM3's DepthMapFactor) and the "
                              "calibration")
        raise FormatError(folder, f"depth looks {how} {seen}: the depth unit is probably {better} "
                          f"({UNIT_NAMES[better]}), not {unit}; use {{0}}",
                          hint=(Remedy("depth_unit", better),))
    return res


#: what each depth unit is, for messages
UNIT_NAMES = {"mm": "16-bit millimetres", "tum": "16-bit, 5000 per metre",
              "carla-log": "CARLA's 8-bit logarithmic depth"}


def _explaining_unit(unit: str, factor: float) -> str | None:
    """The 16-bit unit in which the files would give a factor within the band."""
    if unit not in DEPTH_STEP_M:
        return None
    for u, step in DEPTH_STEP_M.items():
        if u != unit and abs(math.log(factor * step / DEPTH_STEP_M[unit])) <= math.log(BAND):
            return u
    return None


def _check_range(seq: Any, o: DepthOptions, depth_file: Path, unit: str) -> None:
    """Warns when the first frame's median depth lies outside the front end's range: almost no
    corner would get a depth (a unit 1000x off, a disparity image)."""
    depth = np.asarray(seq.read_pair(0)[1], np.float64)
    valid = depth[np.isfinite(depth) & (depth > 0)]
    if valid.size == 0:
        return
    med = float(np.median(valid))
    if not o.min_depth_m <= med <= o.max_depth_m:
        warnings.warn(f"{depth_file}: median depth {med:.3g} m, outside the depth front end's "
                      f"{o.min_depth_m:g}-{o.max_depth_m:g} m: few corners will get a depth; is "
                      f"the depth unit ({unit}) right?", IbiscapeWarning, stacklevel=3)
