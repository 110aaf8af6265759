"""Vehicle motion: a C2 (in fact C4) trajectory sampled analytically, and matching controls.

Pipeline (all vectorised):

1. A route polyline (:mod:`.route`) is smoothed into straights and continuous-curvature corners
   (:mod:`._path`), parameterised by arc length ``s``.
2. Speed limits along ``s``: the segment's cap, ``sqrt(a_lat / |kappa|)`` in corners, zero at stops;
   forward/backward passes with acceleration limits (``v^2`` recurrences written as running minima),
   then time from ``dt = 2 ds / (v_k + v_k+1)``, stop holds inserted.
3. ``s(t)`` on a 1 kHz grid, smoothed by a 1 s Hann window (jerk-limited, monotone, exact stops).
4. The body rides the terrain: the four wheel contact points (wheelbase 2.9 m, track 1.6 m) sample
   the height field; heave, pitch and roll inputs pass through a damped spring suspension
   (``H(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``, 1.5 Hz, zeta 0.4, bilinear at 1 kHz).
5. Quintic splines (``make_interp_spline(k=5)``) of x, y, z, yaw, pitch, roll and s over time are the
   trajectory.  Velocity and acceleration are the splines' derivatives, the body angular velocity
   follows from the ZYX Euler rates, ``omega_body = E(roll, pitch) [roll', pitch', yaw']``, and the
   angular acceleration from differentiating that relation, so a perfect IMU integrates back to the
   pose.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from ._path import SmoothPath, smooth_path
from .route import Route, calibration_route, shuttle_route, town_route
from .targets import TARGET_KINDS
from .types import Controls, MotionState
from .world import World

if TYPE_CHECKING:
    from scipy.interpolate import BSpline

__all__ = ["LegPath", "VehicleMotion", "plan_motion"]

FloatArray = npt.NDArray[np.float64]

WHEELBASE_M = 2.9
TRACK_M = 1.6
MAX_STEER_RAD = math.radians(70.0)
SUSPENSION_HZ = 1.5
SUSPENSION_DAMPING = 0.4
LATERAL_ACC_M_S2 = 2.0  # planning limit (the smoothing may exceed it slightly; < 2.5 m/s^2)
ACCEL_M_S2 = 1.5
DECEL_M_S2 = 2.5
START_HOLD_S = 1.0
SMOOTH_WINDOW_S = 1.0
SHUTTLE_LENGTH_M_PER_S = 2.5  # the shuttle drive's distance per second is below this
GRID_HZ = 1000
# controls model
THROTTLE_FULL_M_S2 = 3.5
BRAKE_FULL_M_S2 = 8.0
ROLLING_M_S2 = 0.15
DRAG_1_M = 4e-4


class VehicleMotion:
    """The planned vehicle trajectory between ``start_ns`` and ``end_ns`` (inclusive).

    Build it with :func:`plan_motion`.  ``sample`` and ``controls`` accept any int64 stamps in
    ``[start_ns, end_ns]``.

    Attributes
    ----------
    kind : str
        The world kind it was planned for.
    start_ns, end_ns : int
    wheelbase_m, track_m, max_steer_rad : float
    """

    def __init__(
        self,
        *,
        kind: str,
        start_ns: int,
        end_ns: int,
        spline: BSpline | None = None,
        path: SmoothPath | LegPath | None = None,
    ) -> None:
        self.kind = kind
        self.start_ns = int(start_ns)
        self.end_ns = int(end_ns)
        self.wheelbase_m = WHEELBASE_M
        self.track_m = TRACK_M
        self.max_steer_rad = MAX_STEER_RAD
        self._spl = spline
        self._d1 = spline.derivative(1) if spline is not None else None
        self._d2 = spline.derivative(2) if spline is not None else None
        self._still = spline is None
        self._path = path

    def _times(self, stamps_ns: npt.ArrayLike) -> tuple[npt.NDArray[np.int64], FloatArray]:
        st = np.asarray(stamps_ns)
        if st.ndim != 1 or not np.issubdtype(st.dtype, np.integer):
            raise IbiscapeError("stamps_ns must be a 1-D integer array of nanoseconds")
        st = st.astype(np.int64)
        if st.size and (st.min() < self.start_ns or st.max() > self.end_ns):
            raise IbiscapeError(
                f"stamps {int(st.min())}..{int(st.max())} ns leave the motion's time range "
                f"{self.start_ns}..{self.end_ns} ns"
            )
        return st, (st - self.start_ns).astype(np.float64) * 1e-9

    def sample(self, stamps_ns: npt.ArrayLike) -> MotionState:
        """Exact kinematics of the body frame at ``stamps_ns`` (int64, shape (N,))."""
        st, t = self._times(stamps_ns)
        n = len(st)
        if self._spl is None or self._d1 is None or self._d2 is None:  # still: all zero
            z3 = np.zeros((n, 3))
            quat = np.zeros((n, 4))
            quat[:, 3] = 1.0
            return MotionState(st, z3, quat, z3.copy(), z3.copy(), z3.copy(), z3.copy())
        y0, y1, y2 = self._spl(t), self._d1(t), self._d2(t)
        yaw, pitch, roll = y0[:, 3], y0[:, 4], y0[:, 5]
        dy, dp, dr = y1[:, 3], y1[:, 4], y1[:, 5]
        ddy, ddp, ddr = y2[:, 3], y2[:, 4], y2[:, 5]
        cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
        cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
        cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
        quat = np.stack(
            (
                sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy,
                cr * cp * sy - sr * sp * cy,
                cr * cp * cy + sr * sp * sy,
            ),
            -1,
        )  # q = q_z(yaw) q_y(pitch) q_x(roll)
        sph, cph = np.sin(roll), np.cos(roll)
        sth, cth = np.sin(pitch), np.cos(pitch)
        w = np.stack(
            (
                dr - dy * sth,
                dp * cph + dy * sph * cth,
                -dp * sph + dy * cph * cth,
            ),
            -1,
        )
        alpha = np.stack(
            (
                ddr - ddy * sth - dy * dp * cth,
                ddp * cph - dp * dr * sph + ddy * sph * cth + dy * (dr * cph * cth - dp * sph * sth),
                -ddp * sph - dp * dr * cph + ddy * cph * cth - dy * (dr * sph * cth + dp * cph * sth),
            ),
            -1,
        )
        return MotionState(st, y0[:, :3].copy(), quat, y1[:, :3].copy(), y2[:, :3].copy(), w, alpha)

    def controls(self, stamps_ns: npt.ArrayLike) -> Controls:
        """Throttle, brake in [0, 1] and steer in [-1, 1] consistent with the motion.

        Longitudinal model: ``a_net = s'' + rolling + drag v^2`` (m/s^2); throttle ``a_net / 3.5``
        when positive, brake ``-a_net / 8`` when negative, brake 1 while standing.  Steering: bicycle
        model ``atan(kappa wheelbase)`` over the 70 deg maximum, with CARLA's sign (positive = right
        turn, i.e. negative yaw rate in this right-handed frame).
        """
        st, t = self._times(stamps_ns)
        n = len(st)
        if self._spl is None or self._d1 is None or self._d2 is None:
            return Controls(st, np.zeros(n), np.zeros(n), np.ones(n))
        assert self._path is not None
        s = self._spl(t)[:, 6]
        v = self._d1(t)[:, 6]
        a = self._d2(t)[:, 6]
        moving = v > 0.01
        a_net = a + np.where(moving, ROLLING_M_S2 + DRAG_1_M * v * v, 0.0)
        throttle = np.clip(a_net / THROTTLE_FULL_M_S2, 0.0, 1.0)
        brake = np.clip(-a_net / BRAKE_FULL_M_S2, 0.0, 1.0)
        standing = (~moving) & (a <= 1e-3)
        brake = np.where(standing, 1.0, brake)
        throttle = np.where(standing, 0.0, throttle)
        kappa = self._path.curvature_1_m(s)
        steer = np.clip(-np.arctan(kappa * WHEELBASE_M) / MAX_STEER_RAD, -1.0, 1.0)
        return Controls(st, throttle, steer, brake)

    def path_length_m(self) -> float:
        """Distance driven between ``start_ns`` and ``end_ns``, metres."""
        if self._spl is None:
            return 0.0
        T = (self.end_ns - self.start_ns) * 1e-9
        s = self._spl(np.array([0.0, T]))[:, 6]
        return float(s[1] - s[0])


class LegPath:
    """Smooth paths driven one after the other, each forward or in reverse, stopping between them.

    Arc length ``s`` runs over the legs end to end.  ``heading_rad`` is the car's yaw: the path's
    tangent, plus pi on reverse legs, unwrapped so that it is continuous at every cusp (a reverse
    leg starts exactly against the direction the previous leg ended in).  ``curvature_1_m`` is
    the curvature the steering sees (negated on reverse legs: backing along a left bend needs
    right lock).
    """

    def __init__(self, paths: list[SmoothPath], reverse: list[bool]):
        if not paths or len(paths) != len(reverse):
            raise IbiscapeError("a leg path needs one direction per leg and at least one leg")
        self.paths = list(paths)
        self.reverse = np.asarray(reverse, dtype=bool)
        lengths = np.array([p.total_length_m for p in paths])
        self.s0_m = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
        self.total_length_m = float(lengths.sum())
        offsets = []
        prev: float | None = None
        for p, rev in zip(self.paths, self.reverse, strict=True):
            off = math.pi if rev else 0.0
            h0 = float(p.heading_rad(np.array([0.0]))[0])
            if prev is not None:
                off += 2.0 * math.pi * round((prev - h0 - off) / (2.0 * math.pi))
                if abs(h0 + off - prev) > 1e-6:
                    raise IbiscapeError("a leg does not start in line with the previous one's end")
            offsets.append(off)
            prev = float(p.heading_rad(np.array([p.total_length_m]))[0]) + off
        self.offset_rad = np.array(offsets)

    def _legs(self, s_m: npt.ArrayLike) -> tuple[npt.NDArray[np.intp], FloatArray]:
        s = np.asarray(s_m, dtype=np.float64).ravel()
        idx = np.clip(np.searchsorted(self.s0_m, s, side="right") - 1, 0, len(self.paths) - 1)
        return idx, s - self.s0_m[idx]

    def _per_leg(self, s_m: npt.ArrayLike, fn: str, width: int) -> FloatArray:
        idx, u = self._legs(s_m)
        out = np.empty((u.size, width)) if width > 1 else np.empty(u.size)
        for i in np.unique(idx):
            m = idx == i
            out[m] = getattr(self.paths[i], fn)(u[m])
        return out

    def xy_m(self, s_m: npt.ArrayLike) -> FloatArray:
        """Positions ``(N, 2)`` at arc lengths ``s_m``."""
        return self._per_leg(s_m, "xy_m", 2)

    def heading_rad(self, s_m: npt.ArrayLike) -> FloatArray:
        """The car's (unwrapped) yaw at arc lengths ``s_m``."""
        idx, _ = self._legs(s_m)
        return self._per_leg(s_m, "heading_rad", 1) + self.offset_rad[idx]

    def curvature_1_m(self, s_m: npt.ArrayLike) -> FloatArray:
        """Signed curvature of the car's own motion (> 0: left lock)."""
        idx, _ = self._legs(s_m)
        return self._per_leg(s_m, "curvature_1_m", 1) * np.where(self.reverse[idx], -1.0, 1.0)


def _speed_limits(path: SmoothPath, route: Route, s: npt.NDArray[np.floating]) -> FloatArray:
    idx, _ = path._piece(s)
    seg = path.piece_segment[idx]
    caps = route.speed_cap_m_s
    cap = caps[seg]
    corner = path.is_corner[idx]
    nxt = np.minimum(seg + 1, len(caps) - 1)
    cap = np.where(corner, np.minimum(cap, caps[nxt]), cap)
    kappa = np.abs(path.curvature_1_m(s))
    return np.minimum(cap, np.sqrt(LATERAL_ACC_M_S2 / np.maximum(kappa, 1e-12)))


def _time_profile(path: SmoothPath, route: Route, *, exact_end: bool = False
                  ) -> tuple[FloatArray, FloatArray]:
    """Knots ``(t_s, s_m)`` of a piecewise-linear ``s(t)``: holds, accel-limited speeds.

    ``exact_end``: the grid ends exactly at the path's end (legs stopping at a cusp)."""
    ds = 0.1
    n = int(path.total_length_m / ds)
    if exact_end:
        n = max(1, math.ceil(path.total_length_m / ds))
        ds = path.total_length_m / n
    s = np.arange(n + 1) * ds
    w_lim = _speed_limits(path, route, s) ** 2
    w_lim[0] = 0.0
    w_lim[-1] = 0.0
    stop_k = np.clip(np.round(path.vertex_s_m[route.stop_s > 0] / ds).astype(int), 0, n)
    w_lim[stop_k] = 0.0
    k = np.arange(n + 1)
    fwd = np.minimum.accumulate(w_lim - 2.0 * ACCEL_M_S2 * ds * k) + 2.0 * ACCEL_M_S2 * ds * k
    bwd = (np.minimum.accumulate((w_lim + 2.0 * DECEL_M_S2 * ds * k)[::-1]))[::-1] - 2.0 * DECEL_M_S2 * ds * k
    v = np.sqrt(np.maximum(np.minimum(np.minimum(fwd, bwd), w_lim), 0.0))
    dt = 2.0 * ds / np.maximum(v[1:] + v[:-1], 1e-6)
    t = START_HOLD_S + np.concatenate(([0.0], np.cumsum(dt)))
    holds = np.zeros(n + 1)
    holds[stop_k] = route.stop_s[route.stop_s > 0]
    t = t + np.cumsum(holds) - holds  # time when arriving at each knot
    # knots: (0, 0), then every grid point; at a stop also the departure (t + hold, s)
    t_knots = np.concatenate(([0.0], t, t[stop_k] + holds[stop_k]))
    s_knots = np.concatenate(([0.0], s, s[stop_k]))
    order = np.argsort(t_knots, kind="stable")
    return t_knots[order], s_knots[order]


def _fft_convolve(x: FloatArray, taps: FloatArray) -> FloatArray:
    """Full linear convolution of the columns of ``x (N, C)`` with ``taps (M,)``, via numpy FFTs."""
    n = x.shape[0] + len(taps) - 1
    nfft = 1 << (n - 1).bit_length()
    spec = np.fft.rfft(x, nfft, axis=0) * np.fft.rfft(taps, nfft)[:, None]
    return np.fft.irfft(spec, nfft, axis=0)[:n]


def _suspension(u: FloatArray) -> FloatArray:
    """Body response ``(N, C)`` of the damped spring to road inputs ``u (N, C)`` on the 1 kHz grid.

    Convolution with the sampled impulse response of
    ``H(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``:
    ``h(t) = exp(-zeta w t) (2 zeta w cos(w_d t) + w^2 (1 - 2 zeta^2) / w_d sin(w_d t))``, truncated
    after 12 s (``exp(-zeta w 12 s)`` < 1e-19) and normalised to unit DC gain, so a flat road gives an
    exactly flat body.  The body starts at rest on ``u[0]``.
    """
    w = 2.0 * math.pi * SUSPENSION_HZ
    z = SUSPENSION_DAMPING
    wd = w * math.sqrt(1.0 - z * z)
    t = np.arange(int(12.0 * GRID_HZ)) / GRID_HZ
    h = np.exp(-z * w * t) * (2.0 * z * w * np.cos(wd * t) + w * w * (1.0 - 2.0 * z * z) / wd * np.sin(wd * t))
    h[0] *= 0.5  # trapezoid weight of the first tap
    h /= h.sum()
    du = u - u[:1]
    if not np.any(du):
        return u.copy()
    return u[:1] + _fft_convolve(du, h)[: len(u)]


def plan_motion(
    world: World,
    *,
    duration_s: float,
    start_ns: int = 1_000_000_000_000,
    seed: int,
    max_speed_m_s: float = 10.0,
    target: str = "checkerboard",
    start_distance_m: float = 0.0,
    drive: str = "shuttle",
) -> VehicleMotion:
    """Plan the vehicle's motion through ``world``.

    Parameters
    ----------
    world : World
    duration_s : float
        Length of the motion, seconds (> 0).
    start_ns : int
        Stamp of the first instant, nanoseconds.
    seed : int
        Seeds the route choice (SLAM turns and stops).
    max_speed_m_s : float
        Cruise speed limit, m/s (1..60).  Calibration approaches are capped at 4 m/s.
    target : str
        Calibration: ``"checkerboard"`` or ``"aprilgrid"``, the board to drive toward.
    start_distance_m : float
        Calibration: start on the approach this far in front of the board (0: the loop's start,
        90 m away, as in the paper; see :func:`~ibiscape_eval.sim.route.calibration_route`).
        Loop drive only.
    drive : str
        Calibration: ``"shuttle"`` (forward and reverse legs in front of the board, which stays in
        view; :func:`~ibiscape_eval.sim.route.shuttle_route`) or ``"loop"`` (the paper's approach
        loop, the board detectable only near its end).

    Returns
    -------
    VehicleMotion
        ``end_ns = start_ns + round(duration_s * 1e9)``.
    """
    _check_motion_args(duration_s, max_speed_m_s, seed, target)
    end_ns = int(start_ns) + round(duration_s * 1e9)
    if world.kind == "still":
        return VehicleMotion(kind="still", start_ns=start_ns, end_ns=end_ns)
    if max_speed_m_s < 1.0:
        raise IbiscapeError(
            f"max_speed_m_s = {max_speed_m_s} m/s is too low to reach anything; use at least 1 m/s"
        )
    if max_speed_m_s > 60.0:
        raise IbiscapeError(f"max_speed_m_s = {max_speed_m_s} m/s is beyond a car's; use at most 60")
    if not world.lanes:
        raise IbiscapeError(f"the {world.kind!r} world has no lanes to drive on; cannot build a route")
    rng = np.random.default_rng([int(seed), 3])
    length = max_speed_m_s * (duration_s + SMOOTH_WINDOW_S + 2.0) + 100.0
    if drive not in ("shuttle", "loop"):
        raise IbiscapeError(f"calibration drive {drive!r} is unknown; use shuttle or loop")
    path: SmoothPath | LegPath
    if world.kind == "calibration" and drive == "shuttle":
        if start_distance_m:
            raise IbiscapeError("motion.start_distance_m applies to the loop drive; the shuttle drive "
                                "starts in front of the board (set calibration_drive: loop or remove it)")
        path, t_knots, s_knots = _shuttle_knots(world, target, max_speed_m_s, duration_s)
    else:
        if world.kind == "slam":
            route = town_route(world, length_m=length, rng=rng, max_speed_m_s=max_speed_m_s)
        else:
            route = calibration_route(world, target=target, length_m=length,
                                      max_speed_m_s=max_speed_m_s, start_distance_m=start_distance_m)
        path = smooth_path(route.waypoints_m, route.cut_m)
        t_knots, s_knots = _time_profile(path, route)
    t, s_t = _smoothed_progress(t_knots, s_knots, duration_s)
    from scipy.interpolate import make_interp_spline

    spline = make_interp_spline(t, _body_states(world, path, s_t), k=5)
    return VehicleMotion(kind=world.kind, start_ns=start_ns, end_ns=end_ns, spline=spline, path=path)


def _check_motion_args(duration_s: float, max_speed_m_s: float, seed: int, target: str) -> None:
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
        raise IbiscapeError(f"duration_s must be a positive number of seconds, got {duration_s!r}")
    if not (isinstance(max_speed_m_s, (int, float)) and math.isfinite(max_speed_m_s) and max_speed_m_s > 0):
        raise IbiscapeError(f"max_speed_m_s must be a positive speed, got {max_speed_m_s!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise IbiscapeError(f"seed must be a non-negative integer, got {seed!r}")
    if target not in TARGET_KINDS:
        raise IbiscapeError(f"target {target!r} is unknown; use one of {TARGET_KINDS}")


def _shuttle_knots(world: World, target: str, max_speed_m_s: float, duration_s: float
                   ) -> tuple[LegPath, FloatArray, FloatArray]:
    """The shuttle drive's legs as one path and its time profile: knots ``t [s]`` and ``s [m]``
    along the concatenated legs."""
    legs = shuttle_route(world, target=target, max_speed_m_s=max_speed_m_s,
                         length_m=SHUTTLE_LENGTH_M_PER_S * (duration_s + 2.0) + 20.0)
    paths = [smooth_path(r.waypoints_m, r.cut_m) for r, _ in legs]
    t_parts, s_parts = [], []
    t_off = s_off = 0.0
    for p, (r, _) in zip(paths, legs, strict=True):
        tk, sk = _time_profile(p, r, exact_end=True)
        t_parts.append(tk + t_off)
        s_parts.append(sk + s_off)
        t_off += float(tk[-1])
        s_off += p.total_length_m
    return LegPath(paths, [rev for _, rev in legs]), np.concatenate(t_parts), np.concatenate(s_parts)


def _smoothed_progress(t_knots: FloatArray, s_knots: FloatArray, duration_s: float
                       ) -> tuple[FloatArray, FloatArray]:
    """Times ``t`` [s] of the 1 kHz grid (0.1 s beyond both ends) and the distance along the
    path ``s(t)`` [m] there, smoothed by a Hann window (monotone; stops stay exactly still
    inside)."""
    n = math.ceil(duration_s * GRID_HZ)
    margin = 100  # 0.1 s of fitted spline beyond both ends
    half = int(SMOOTH_WINDOW_S * GRID_HZ) // 2
    k = np.arange(-margin - half, n + margin + half + 1)
    s_raw = np.interp(k / GRID_HZ, t_knots, s_knots)
    kernel = np.hanning(2 * half + 3)[1:-1]
    s_t = _fft_convolve(s_raw[:, None], kernel / kernel.sum())[2 * half : len(s_raw), 0]
    return np.arange(-margin, n + margin + 1) / GRID_HZ, s_t


def _body_states(world: World, path: SmoothPath | LegPath, s_t: FloatArray) -> FloatArray:
    """``(N, 7)`` x, y, z, yaw, pitch, roll, s of the body at path distances ``s_t`` (N,): the
    terrain under the four wheels through the suspension."""
    xy = path.xy_m(s_t)
    yaw = path.heading_rad(s_t)
    # wheel contact points: front/rear at +-wheelbase/2, left/right at +-track/2
    c, sn = np.cos(yaw), np.sin(yaw)
    fwd = np.stack((c, sn), -1)
    left = np.stack((-sn, c), -1)
    wb, tr = 0.5 * WHEELBASE_M, 0.5 * TRACK_M
    contacts = np.concatenate(
        [xy + a * wb * fwd + b * tr * left for a in (1.0, -1.0) for b in (1.0, -1.0)]
    )  # FL, FR, RL, RR
    h = world.terrain.height_m(contacts).reshape(4, -1)
    front, rear = 0.5 * (h[0] + h[1]), 0.5 * (h[2] + h[3])
    lft, rgt = 0.5 * (h[0] + h[2]), 0.5 * (h[1] + h[3])
    u = np.stack(
        (h.mean(axis=0), -np.arctan((front - rear) / WHEELBASE_M), np.arctan((lft - rgt) / TRACK_M)), -1
    )
    body = _suspension(u)
    return np.column_stack((xy, body[:, 0], yaw, body[:, 1], body[:, 2], s_t))
