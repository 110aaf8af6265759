"""GTSAM back end: IMU preintegration + stereo landmarks in an incremental fixed-lag smoother.

State of keyframe ``k``: pose ``x_k`` (``T_world_body``), velocity ``v_k`` (world) and IMU bias
``b_k``.  Factors:

- ``CombinedImuFactor(x_i, v_i, x_j, v_j, b_i, b_j)`` between consecutive keyframes from
  ``PreintegratedCombinedMeasurements`` (Forster et al., "On-manifold preintegration", T-RO 2017),
  with the continuous-time densities of ``imu.yaml`` (the bias random walk is inside the factor);
- ``GenericStereoFactor3D(x_k, l_j)`` for every rectified stereo observation of a landmark, with
  a Huber-robust isotropic pixel noise and the rectified camera's pose in the body;
- priors on the first pose, velocity and bias (the anchor of the gauge).

``IncrementalFixedLagSmoother`` (iSAM2, ``relinearizeSkip = 1``) keeps ``lag_s`` seconds of
keyframes and marginalises older poses and landmarks.  Each landmark carries the timestamp of its
latest observation, so it is marginalised only after the last pose that sees it; a landmark whose
window has passed is never referenced again (a track seen again later gets a new landmark key).
Factors are never removed from the smoother (removal plus marginalisation trips GTSAM's
bookkeeping, borglab/gtsam#2479).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.kalibr import ImuNoise

from .params import VioParams
from .rig import RectifiedStereo

__all__ = ["Backend", "KeyframeState", "StereoObservations", "integrate_imu"]

FloatArray = npt.NDArray[np.float64]
GRAVITY_M_S2 = 9.81


@dataclass(frozen=True, eq=False)
class StereoObservations:
    """Rectified stereo measurements of one frame.

    Attributes
    ----------
    stamp_ns : int
    ids : ndarray, shape (N,), int64
        Track identifiers (one per physical point, stable across frames).
    uL, uR, v : ndarray, shape (N,)
        Rectified left/right column and the shared row [px].
    """

    stamp_ns: int
    ids: npt.NDArray[np.int64]
    uL: FloatArray
    uR: FloatArray
    v: FloatArray

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def matched(self) -> StereoObservations:
        """The observations with a stereo match (a frame tracked in the left image only has
        ``uR`` NaN where it was not matched, see :meth:`StereoFrontEnd.track`)."""
        ok = np.isfinite(self.uR)
        if ok.all():
            return self
        return StereoObservations(self.stamp_ns, self.ids[ok], self.uL[ok], self.uR[ok],
                                  self.v[ok])

    @classmethod
    def empty(cls, stamp_ns: int) -> StereoObservations:
        z = np.zeros(0)
        return cls(int(stamp_ns), np.zeros(0, dtype=np.int64), z, z, z)


@dataclass(frozen=True, eq=False)
class KeyframeState:
    """Estimated state of one keyframe (latest estimate of the smoother)."""

    stamp_ns: int
    T_world_body: FloatArray
    vel_m_s: FloatArray
    bias_acc_m_s2: FloatArray
    bias_gyro_rad_s: FloatArray


def _sym(c: str, i: int) -> int:
    """``gtsam.symbol(c, i)``: the character in the top byte, the index below (no call into
    GTSAM: this runs for every factor)."""
    return (ord(c) << 56) | int(i)


def imu_params(noise: ImuNoise, scale: float, T_body_imu: FloatArray | None = None) -> Any:
    """``PreintegrationCombinedParams`` (z up) with every covariance set explicitly; an ideal
    (zero-noise) density is raised to :data:`ibiscape_eval.core.kalibr.IMU_NOISE_FLOOR` so that the
    information stays finite."""
    import gtsam

    noise = noise.floored()
    p = gtsam.PreintegrationCombinedParams.MakeSharedU(GRAVITY_M_S2)
    s2 = scale * scale
    eye = np.eye(3)
    p.setAccelerometerCovariance(eye * noise.accel_noise_density_m_s2_sqrt_hz ** 2 * s2)
    p.setGyroscopeCovariance(eye * noise.gyro_noise_density_rad_s_sqrt_hz ** 2 * s2)
    p.setIntegrationCovariance(eye * 1e-8)
    p.setBiasAccCovariance(eye * noise.accel_random_walk_m_s3_sqrt_hz ** 2 * s2)
    p.setBiasOmegaCovariance(eye * noise.gyro_random_walk_rad_s2_sqrt_hz ** 2 * s2)
    if T_body_imu is not None and not np.allclose(T_body_imu, np.eye(4)):
        p.setBodyPSensor(gtsam.Pose3(np.asarray(T_body_imu, dtype=np.float64)))
    return p


def integrate_imu(pim: Any, stamps_ns: npt.NDArray[np.int64], gyro_rad_s: FloatArray,
                  accel_m_s2: FloatArray, t0_ns: int, t1_ns: int) -> None:
    """Integrate the samples covering ``[t0_ns, t1_ns)`` into ``pim`` (zero-order hold: sample
    ``i`` holds until sample ``i + 1``).  GTSAM integrates one sample per call, so this loop over
    the (few) samples of one frame interval cannot be vectorised."""
    if t1_ns <= t0_ns:
        return
    i0 = max(int(np.searchsorted(stamps_ns, t0_ns, side="right")) - 1, 0)
    i1 = int(np.searchsorted(stamps_ns, t1_ns, side="left"))
    edges = np.concatenate(([t0_ns], stamps_ns[i0 + 1:i1], [t1_ns])).astype(np.int64)
    dts = np.diff(edges) * 1e-9
    for k, dt in enumerate(dts):
        if dt > 0:
            j = i0 + k
            pim.integrateMeasurement(accel_m_s2[j], gyro_rad_s[j], float(dt))


class Backend:
    """The fixed-lag smoother over keyframes (see the module docstring).

    Usage: :meth:`start` once, then per keyframe a fresh :meth:`preintegration` filled with
    :func:`integrate_imu` and passed to :meth:`add_keyframe` with the frame's observations.
    """

    def __init__(self, rect: RectifiedStereo, noise: ImuNoise, params: VioParams,
                 T_body_imu: FloatArray | None = None):
        import gtsam

        self.rect = rect
        self.params = params
        self.imu_params = imu_params(noise, params.imu_noise_scale, T_body_imu)
        self.K = gtsam.Cal3_S2Stereo(rect.fx, rect.fy, 0.0, rect.cx, rect.cy, rect.baseline_m)
        self.body_P_cam = gtsam.Pose3(np.asarray(rect.T_body_rect, dtype=np.float64))
        sigma = params.pixel_sigma_px * params.scale_px(rect.width_px)
        self.stereo_noise = gtsam.noiseModel.Robust.Create(
            gtsam.noiseModel.mEstimator.Huber.Create(1.345),
            gtsam.noiseModel.Isotropic.Sigma(3, sigma))
        self.landmark_prior = gtsam.noiseModel.Isotropic.Sigma(3, 20.0)
        self._factor_cls = gtsam.GenericStereoFactor3D
        self._point_cls = gtsam.StereoPoint2
        self.min_disp_px = params.min_disparity_px * params.scale_px(rect.width_px)
        # latest estimate of every keyframe (kept across restarts: keyframe indices never repeat)
        self.states: dict[int, KeyframeState] = {}
        self.resets = 0
        self._reset_state()

    def _reset_state(self) -> None:
        import gtsam

        isam = gtsam.ISAM2Params()
        isam.setRelinearizeThreshold(self.params.relinearize_threshold)
        isam.relinearizeSkip = self.params.relinearize_skip
        self.smoother = gtsam.IncrementalFixedLagSmoother(self.params.lag_s, isam)
        self.k = -1                                # index of the latest keyframe
        self.kf_t: dict[int, int] = {}             # keyframe index -> stamp (ns), in the window
        self.lm_key: dict[int, int] = {}           # track id -> landmark key (live in the window)
        self.lm_last_t: dict[int, int] = {}        # track id -> stamp of its latest factor
        self.lm_first_t: dict[int, int] = {}       # track id -> stamp of its first factor
        self.pending: dict[int, list[tuple[int, float, float, float]]] = {}
        self.n_landmarks = 0
        self.t0_ns = 0

    # ------------------------------------------------------------------------------ public
    def preintegration(self) -> Any:
        """A fresh preintegration with the latest bias estimate."""
        import gtsam

        bias = gtsam.imuBias.ConstantBias()
        if self.k >= 0:
            st = self.latest()
            bias = gtsam.imuBias.ConstantBias(st.bias_acc_m_s2, st.bias_gyro_rad_s)
        return gtsam.PreintegratedCombinedMeasurements(self.imu_params, bias)

    def start(self, t_ns: int, T_world_body: FloatArray, vel_m_s: FloatArray, *,
              bias_acc_m_s2: FloatArray | None = None, bias_gyro_rad_s: FloatArray | None = None,
              sigma_rot_rad: float = 1e-3, sigma_pos_m: float = 1e-3, sigma_vel_m_s: float = 0.05,
              sigma_bias_acc_m_s2: float = 0.1, sigma_bias_gyro_rad_s: float = 5e-3,
              index: int = 0) -> None:
        """Anchor keyframe ``index`` at ``t_ns`` with priors on pose, velocity and bias."""
        import gtsam

        if self.k >= 0:
            self._reset_state()
        ba = np.zeros(3) if bias_acc_m_s2 is None else np.asarray(bias_acc_m_s2, dtype=float)
        bg = np.zeros(3) if bias_gyro_rad_s is None else np.asarray(bias_gyro_rad_s, dtype=float)
        self.t0_ns = int(t_ns)
        k = int(index)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        pose = gtsam.Pose3(np.asarray(T_world_body, dtype=np.float64))
        bias = gtsam.imuBias.ConstantBias(ba, bg)
        graph.add(gtsam.PriorFactorPose3(_sym("x", k), pose, gtsam.noiseModel.Diagonal.Sigmas(
            np.array([sigma_rot_rad] * 3 + [sigma_pos_m] * 3))))
        graph.add(gtsam.PriorFactorVector(_sym("v", k), np.asarray(vel_m_s, dtype=float),
                                          gtsam.noiseModel.Isotropic.Sigma(3, sigma_vel_m_s)))
        graph.add(gtsam.PriorFactorConstantBias(_sym("b", k), bias, gtsam.noiseModel.Diagonal.Sigmas(
            np.array([sigma_bias_acc_m_s2] * 3 + [sigma_bias_gyro_rad_s] * 3))))
        values.insert(_sym("x", k), pose)
        values.insert(_sym("v", k), np.asarray(vel_m_s, dtype=float))
        values.insert(_sym("b", k), bias)
        ts = self._stamps({_sym("x", k): t_ns, _sym("v", k): t_ns, _sym("b", k): t_ns})
        self.smoother.update(graph, values, ts)
        self.k = k
        self.kf_t[k] = int(t_ns)
        self.states[k] = KeyframeState(int(t_ns), np.asarray(T_world_body, dtype=float).copy(),
                                       np.asarray(vel_m_s, dtype=float).copy(), ba, bg)

    def seed(self, obs: StereoObservations) -> None:
        """Remember the observations of the anchor keyframe (landmarks appear at the next one)."""
        obs = obs.matched()
        ok = (obs.uL - obs.uR) >= self.min_disp_px
        self.pending = {int(obs.ids[i]): [(self.k, float(obs.uL[i]), float(obs.uR[i]),
                                           float(obs.v[i]))] for i in np.flatnonzero(ok)}

    def predict(self, pim: Any) -> KeyframeState:
        """The latest keyframe state propagated through ``pim`` (IMU only)."""
        import gtsam

        st = self.latest()
        nav = gtsam.NavState(gtsam.Rot3(st.T_world_body[:3, :3]), st.T_world_body[:3, 3],
                             st.vel_m_s)
        bias = gtsam.imuBias.ConstantBias(st.bias_acc_m_s2, st.bias_gyro_rad_s)
        pred = pim.predict(nav, bias)
        return KeyframeState(st.stamp_ns + round(pim.deltaTij() * 1e9), pred.pose().matrix(),
                             np.asarray(pred.velocity(), dtype=float), st.bias_acc_m_s2,
                             st.bias_gyro_rad_s)

    def add_keyframe(self, t_ns: int, pim: Any, obs: StereoObservations) -> int:
        """Add a keyframe at ``t_ns`` linked to the previous one by ``pim``, with the frame's
        stereo observations; optimise.  Returns the number of landmark observations used."""
        import gtsam

        obs = obs.matched()
        k = self.k + 1
        pred = self.predict(pim)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        stamps: dict[int, float] = {}
        graph.add(gtsam.CombinedImuFactor(_sym("x", k - 1), _sym("v", k - 1), _sym("x", k),
                                          _sym("v", k), _sym("b", k - 1), _sym("b", k), pim))
        values.insert(_sym("x", k), gtsam.Pose3(pred.T_world_body))
        values.insert(_sym("v", k), pred.vel_m_s)
        values.insert(_sym("b", k), gtsam.imuBias.ConstantBias(pred.bias_acc_m_s2,
                                                               pred.bias_gyro_rad_s))
        for c in "xvb":
            stamps[_sym(c, k)] = t_ns
        self.kf_t[k] = int(t_ns)
        used = self._landmark_factors(k, t_ns, pred.T_world_body, obs, graph, values, stamps)
        self.smoother.update(graph, values, self._stamps(stamps))
        self.k = k
        self._refresh(t_ns)
        return used

    def hold_still(self, sigma_vel_m_s: float = 0.01, sigma_rot_rad: float = 1e-3,
                   sigma_pos_m: float = 0.01) -> bool:
        """Zero-velocity update of the newest keyframe (the IMU says the body stands still): its
        velocity is zero and its pose that of the keyframe before.  False when there is no
        keyframe before it in the smoother (right after a start)."""
        import gtsam

        k = self.k
        if k - 1 not in self.kf_t or k not in self.kf_t:
            return False
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.PriorFactorVector(_sym("v", k), np.zeros(3),
                                          gtsam.noiseModel.Isotropic.Sigma(3, sigma_vel_m_s)))
        graph.add(gtsam.BetweenFactorPose3(_sym("x", k - 1), _sym("x", k), gtsam.Pose3(),
                                           gtsam.noiseModel.Diagonal.Sigmas(
                                               np.array([sigma_rot_rad] * 3 + [sigma_pos_m] * 3))))
        self.smoother.update(graph, gtsam.Values(), self._stamps({}))
        self._refresh(self.kf_t[k])
        return True

    def newest(self) -> KeyframeState | None:
        """The newest keyframe's estimate, or None when the smoother dropped it (a numerically
        broken graph, reported as a divergence)."""
        return self.states.get(self.k)

    def latest(self) -> KeyframeState:
        """The newest keyframe's estimate."""
        st = self.newest()
        if st is None:
            # the smoother dropped the newest keyframe (a numerically broken graph)
            raise RuntimeError(f"the smoother has no estimate of keyframe {self.k}")
        return st

    # ------------------------------------------------------------------------------ helpers
    def _stamps(self, d: dict[int, float]) -> Any:
        # seconds relative to the first keyframe: float64 keeps ns resolution
        return {int(key): (int(t) - self.t0_ns) * 1e-9 for key, t in d.items()}

    def _landmark_factors(self, k: int, t_ns: int, T_wb: FloatArray, obs: StereoObservations,
                          graph: Any, values: Any, stamps: dict[int, float]) -> int:
        import gtsam

        lag_ns = int(self.params.lag_s * 1e9)
        # keys older than this may already be marginalised: never reference them again
        horizon = t_ns - lag_ns + int(0.1 * 1e9)
        # landmarks whose window has passed, and landmarks older than the lag, are dropped: a
        # track seen for longer than the lag continues as a new landmark, so no landmark keeps
        # collecting observations against marginals linearised long ago (a car waiting at a
        # light would otherwise pile inconsistent information onto the same points)
        young = t_ns - int(0.8 * lag_ns)
        renew: set[int] = set()
        for tid in [t for t, lt in self.lm_last_t.items()
                    if lt < horizon or self.lm_first_t[t] < young]:
            if self.lm_last_t[tid] >= horizon:
                renew.add(tid)  # still tracked: continue at once with one stereo observation
            del self.lm_last_t[tid]
            del self.lm_key[tid]
            del self.lm_first_t[tid]
        ok = np.flatnonzero((obs.uL - obs.uR) >= self.min_disp_px)
        seen = set()
        used = 0
        T_w_cam = T_wb @ self.rect.T_body_rect
        pts_w = self.rect.triangulate(obs.uL, obs.uR, obs.v) @ T_w_cam[:3, :3].T + T_w_cam[:3, 3]
        # plain Python numbers once per frame (indexing numpy arrays per element is slow)
        ids, uL, uR, vv = (obs.ids[ok].tolist(), obs.uL[ok].tolist(), obs.uR[ok].tolist(),
                           obs.v[ok].tolist())
        for j, i in enumerate(ok.tolist()):
            tid = ids[j]
            seen.add(tid)
            meas = (k, uL[j], uR[j], vv[j])
            if tid in self.lm_key:
                key = self.lm_key[tid]
                self._stereo_factor(graph, meas, key)
                stamps[key] = t_ns
                self.lm_last_t[tid] = t_ns
                used += 1
                continue
            pend = [m for m in self.pending.get(tid, []) if self.kf_t.get(m[0], -1) >= horizon]
            pend.append(meas)
            if len(pend) < self.params.min_landmark_obs and tid not in renew:
                self.pending[tid] = pend
                continue
            key = _sym("l", self.n_landmarks)
            self.n_landmarks += 1
            p_w = pts_w[i]
            values.insert(key, gtsam.Point3(p_w))
            # a weak prior keeps the landmark's block positive definite when its depth is barely
            # observed (far points, Huber-downweighted observations): without it iSAM2 may stop
            # with an IndeterminantLinearSystemException
            graph.add(gtsam.PriorFactorPoint3(key, gtsam.Point3(p_w), self.landmark_prior))
            for m in pend:
                self._stereo_factor(graph, m, key)
            stamps[key] = t_ns
            self.lm_key[tid] = key
            self.lm_last_t[tid] = t_ns
            self.lm_first_t[tid] = min(self.kf_t.get(m[0], t_ns) for m in pend)
            self.pending.pop(tid, None)
            used += 1
        # tracks not seen in this keyframe are gone (the front end never reuses an id)
        self.pending = {t: v for t, v in self.pending.items() if t in seen}
        return used

    def _stereo_factor(self, graph: Any, meas: tuple[int, float, float, float], key: int) -> None:
        kf, uL, uR, v = meas
        graph.add(self._factor_cls(self._point_cls(uL, uR, v), self.stereo_noise,
                                   _sym("x", kf), key, self.K, self.body_P_cam))

    def _refresh(self, t_ns: int) -> None:
        # per-key estimates of the window's keyframes only: calculateEstimate() would retract
        # every variable of the window (thousands of landmarks) into a new Values at each update
        sm = self.smoother
        lag_ns = int(self.params.lag_s * 1e9)
        for kf in [i for i, t in self.kf_t.items() if t < t_ns - lag_ns]:
            del self.kf_t[kf]
        for kf, t in self.kf_t.items():
            try:
                pose = sm.calculateEstimatePose3(_sym("x", kf))
            except (RuntimeError, IndexError, KeyError):
                continue  # not in the smoother (marginalised, or dropped by a broken update)
            b = sm.calculateEstimateConstantBias(_sym("b", kf))
            self.states[kf] = KeyframeState(t, pose.matrix(),
                                            np.asarray(sm.calculateEstimateVector(_sym("v", kf)),
                                                       dtype=float),
                                            np.asarray(b.accelerometer(), dtype=float),
                                            np.asarray(b.gyroscope(), dtype=float))
