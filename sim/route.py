"""Routes: polylines the vehicle drives, with corner cuts, stops and speed caps.

- SLAM: a seeded random walk over the town's intersections (no U-turns), on the lane centrelines
  for right-hand traffic; the polyline turns at the intersection of the incoming and outgoing lane
  centrelines; some intersections get a stop line 8 m before the crossing.
- Calibration, ``shuttle`` (default): the world's shuttle legs in front of the chosen target,
  forward and in reverse in turn (:func:`shuttle_route`).
- Calibration, ``loop``: laps of the world's approach loop toward the chosen target (slow on the
  approach), the paper's drive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from .world import LANE_OFFSET_M, ROAD_HALF_WIDTH_M, World, loop_cuts

__all__ = ["Route", "calibration_route", "shuttle_route", "town_route"]

FloatArray = npt.NDArray[np.float64]

_DIRS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])  # E, N, W, S
STOP_PROBABILITY = 0.3
APPROACH_SPEED_M_S = 4.0
SHUTTLE_SPEED_M_S = 3.0  # forward legs of the shuttle drive
SHUTTLE_REVERSE_SPEED_M_S = 2.5
SHUTTLE_CUT_M = 2.0
RIGHT_TURN_CUT_M = 6.0
LEFT_TURN_CUT_M = 9.0


@dataclass(frozen=True, eq=False)
class Route:
    """A drivable polyline.

    Attributes
    ----------
    waypoints_m : ndarray, shape (K, 2)
    cut_m : ndarray, shape (K,)
        Wanted corner cut at each vertex, metres.
    stop_s : ndarray, shape (K,)
        Seconds to stand still at each vertex (0 = drive through).
    speed_cap_m_s : ndarray, shape (K - 1,)
        Speed cap on each segment.
    """

    waypoints_m: FloatArray
    cut_m: FloatArray
    stop_s: FloatArray
    speed_cap_m_s: FloatArray


def _right(d: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    return np.array([d[1], -d[0]])


def town_route(world: World, *, length_m: float, rng: np.random.Generator, max_speed_m_s: float) -> Route:
    """Random traffic-aligned route of at least ``length_m`` through the town grid."""
    n = world.town_blocks
    if world.kind != "slam" or n < 1 or not world.lanes:
        raise IbiscapeError("a town route needs a 'slam' world with lanes (build_world(kind='slam'))")
    B = world.block_m
    node = rng.integers(0, n + 1, size=2)
    # a first direction that stays inside the grid
    valid = [k for k in range(4) if np.all((node + _DIRS[k] >= 0) & (node + _DIRS[k] <= n))]
    d = _DIRS[valid[int(rng.integers(len(valid)))]]
    start = node * B + 0.5 * B * d + LANE_OFFSET_M * _right(d)
    node = node + d
    pts: list[FloatArray] = [start.astype(np.float64)]
    cut: list[float] = [0.0]
    stop: list[float] = [0.0]
    total = 0.5 * B
    while total < length_m:
        options, weights = [], []
        for k, w in ((0, 0.5), (1, 0.25), (3, 0.25)):  # straight, left, right (relative)
            nd = _DIRS[(int(np.flatnonzero((d == _DIRS).all(1))[0]) + k) % 4]
            if np.all((node + nd >= 0) & (node + nd <= n)):
                options.append(nd)
                weights.append(w)
        p = np.asarray(weights) / np.sum(weights)
        nd = options[int(rng.choice(len(options), p=p))]
        centre = node * B
        if rng.random() < STOP_PROBABILITY:
            pts.append(centre - (ROAD_HALF_WIDTH_M + 2.0) * d + LANE_OFFSET_M * _right(d))
            cut.append(0.0)
            stop.append(float(rng.uniform(1.5, 4.0)))
        if not np.array_equal(nd, d):
            left = d[0] * nd[1] - d[1] * nd[0] > 0
            pts.append(centre + LANE_OFFSET_M * (_right(d) + _right(nd)))
            cut.append(LEFT_TURN_CUT_M if left else RIGHT_TURN_CUT_M)
            stop.append(0.0)
        d = nd
        node = node + d
        total += B
    pts.append(node * B - (ROAD_HALF_WIDTH_M + 2.0) * d + LANE_OFFSET_M * _right(d))
    cut.append(0.0)
    stop.append(0.0)
    wp = np.asarray(pts, dtype=np.float64)
    return Route(wp, np.asarray(cut), np.asarray(stop), np.full(len(wp) - 1, max_speed_m_s))


def calibration_route(world: World, *, target: str, length_m: float, max_speed_m_s: float,
                      start_distance_m: float = 0.0) -> Route:
    """Laps of the approach loop toward ``target`` until at least ``length_m``.

    ``start_distance_m > 0`` starts the first lap on the approach leg that far (along x) in front
    of the board instead of at the loop's start (90 m away), so that a short sequence sees the
    board near; the laps after it are the full loop.  0 (the default) is the paper's drive.
    """
    if world.kind != "calibration" or target not in world.routes:
        raise IbiscapeError(
            f"a calibration route toward {target!r} needs a 'calibration' world "
            f"(build_world(kind='calibration')); this world is {world.kind!r}"
        )
    world.target_named(target)
    loop = world.routes[target]
    seg = np.diff(loop, axis=0)
    lap_len = float(np.hypot(seg[:, 0], seg[:, 1]).sum())
    laps = max(1, int(np.ceil(length_m / lap_len)))
    wp = np.vstack([loop[:1]] + [loop[1:]] * laps)
    cuts = np.concatenate([[0.0]] + [loop_cuts(loop)[1:]] * laps)
    n_approach = 4  # loop[0] .. loop[4]: the approach leg, ending where the loop turns away
    if start_distance_m:
        board_x = float(world.target_named(target).centre_world_m[0])
        x0 = board_x - float(start_distance_m)
        lo, hi = board_x - loop[n_approach, 0], board_x - loop[0, 0]
        if not lo + 2.0 <= start_distance_m <= hi:
            raise IbiscapeError(
                f"motion.start_distance_m = {start_distance_m} m: use 0 (the full approach) or a "
                f"distance from {lo + 2.0:g} to {hi:g} m (the approach leg)")
        k = int(np.searchsorted(loop[: n_approach + 1, 0], x0, side="right"))  # next vertex
        y0 = float(np.interp(x0, loop[: n_approach + 1, 0], loop[: n_approach + 1, 1]))
        wp = np.vstack(([[x0, y0]], wp[k:]))
        cuts = np.concatenate(([0.0], cuts[k:]))
    cuts[-1] = 0.0
    caps_lap = np.full(len(loop) - 1, max_speed_m_s)
    caps_lap[:n_approach] = min(max_speed_m_s, APPROACH_SPEED_M_S)  # the approach leg
    caps = np.tile(caps_lap, laps)
    if start_distance_m:
        caps = caps[len(caps) - (len(wp) - 1):]
    return Route(wp, cuts, np.zeros(len(wp)), caps)


def shuttle_route(world: World, *, target: str, length_m: float,
                  max_speed_m_s: float) -> list[tuple[Route, bool]]:
    """The shuttle legs in front of ``target`` (:func:`~ibiscape_eval.sim.world.shuttle_legs`),
    repeated until at least ``length_m``: ``(route, reverse)`` per leg, the car stopping at the
    end of each (forward legs at most 3 m/s, reverse legs 2.5 m/s)."""
    shuttles = getattr(world, "shuttles", {})
    if world.kind != "calibration" or target not in shuttles:
        raise IbiscapeError(
            f"a calibration shuttle toward {target!r} needs a 'calibration' world "
            f"(build_world(kind='calibration')); this world is {world.kind!r}"
        )
    world.target_named(target)
    legs = shuttles[target]
    out: list[tuple[Route, bool]] = []
    total = 0.0
    k = 0
    while total < length_m:
        wp = np.asarray(legs[k % len(legs)], dtype=np.float64)
        reverse = k % 2 == 1
        cap = min(max_speed_m_s, SHUTTLE_REVERSE_SPEED_M_S if reverse else SHUTTLE_SPEED_M_S)
        cut = np.full(len(wp), SHUTTLE_CUT_M)
        cut[[0, -1]] = 0.0
        out.append((Route(wp, cut, np.zeros(len(wp)), np.full(len(wp) - 1, cap)), reverse))
        total += float(np.hypot(*np.diff(wp, axis=0).T).sum())
        k += 1
    return out
