"""The simulated world: a town of streets for SLAM, a calibration ground with Kalibr targets, or an
empty flat plane for still IMU recordings.

Geometry is kept as compact numpy arrays the rendering issue turns into meshes:

- :class:`Boxes`: oriented boxes (centre of the base on the ground, size, yaw, kind/texture id) for
  roads, blocks, sidewalks, buildings (facade texture ids), poles, trees and parked cars;
- lanes: traffic-aligned lane centrelines (right-hand traffic), polylines ``(K, 2)`` in metres;
- the road surface :class:`~ibiscape_eval.sim.terrain.Terrain` with bubbles and waves;
- :class:`~ibiscape_eval.sim.targets.Target` boards and moving :class:`~ibiscape_eval.sim.agents.Agents`.

Town layout: a grid of ``town_blocks x town_blocks`` blocks of ``BLOCK_M`` between road centrelines,
roads along ``x = i BLOCK_M`` and ``y = j BLOCK_M``, one 3.5 m lane per direction plus a 2.5 m
parking strip on each side, 3 m sidewalks, buildings set back behind the sidewalks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from ._path import smooth_path
from .agents import AGENT_CAR, AGENT_PEDESTRIAN, Agents
from .targets import TARGET_KINDS, Target, board_pose, make_target
from .terrain import Bump, Terrain

__all__ = ["CALIBRATION_DRIVES", "SCENES", "SHUTTLE_SCALE", "TARGET_LEAN_DEG", "WORLD_KINDS", "Boxes", "World", "build_world", "shuttle_legs"]

FloatArray = npt.NDArray[np.float64]
WORLD_KINDS = ("slam", "calibration", "still")
SCENES = ("clear", "moderate", "dynamic")

BLOCK_M = 80.0
LANE_WIDTH_M = 3.5
LANE_OFFSET_M = 0.5 * LANE_WIDTH_M  # lane centreline from the road centreline
PARKING_WIDTH_M = 2.5
ROAD_HALF_WIDTH_M = LANE_WIDTH_M + PARKING_WIDTH_M
SIDEWALK_M = 3.0
TARGET_X_M = 90.0  # calibration boards stand at this x, facing -x
TARGET_CENTRE_Z_M = 3.0
TARGET_LEAN_DEG = 15.0  # the boards lean back: views from a car then do not all share one rotation axis
TARGET_Y_M = {"checkerboard": -4.0, "aprilgrid": 4.0}
CORNER_CUT_M = {"weave": 6.0, "turn": 9.0}
CALIBRATION_DRIVES = ("shuttle", "loop")
#: the shuttle drive in front of a board (see :func:`shuttle_legs`): sweep of viewing angles off the
#: board's normal [deg], near and far distances [m], straight run-in and run-out [m], legs per lap
SHUTTLE_SWEEP_DEG = (-30.0, -20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 20.0, 10.0, 0.0, -10.0, -20.0)
SHUTTLE_NEAR_M = (4.5, 6.5)
SHUTTLE_AIM_M = 1.6
SHUTTLE_FAR_M = (12.0, 15.0)
SHUTTLE_RUN_IN_M = 2.0
SHUTTLE_RUN_OUT_M = 2.0
SHUTTLE_PAIRS = 24
#: the shuttle's distances (near, far, aim, run-in, run-out) per target, times the constants above:
#: the AprilGrid's tags need the car closer than the checkerboard's squares (0.75: the steering
#: stays below 0.93 of its range on the crossovers)
SHUTTLE_SCALE = {"checkerboard": 1.0, "aprilgrid": 0.75}

# kind ids (documented for the renderer)
ROAD_ASPHALT, ROAD_CALIBRATION_PAD = 0, 1
POLE_STREETLIGHT, POLE_TARGET_STAND = 0, 1
N_FACADES = 8
N_TREE_KINDS = 3
N_CAR_COLOURS = 6


@dataclass(frozen=True, eq=False)
class Boxes:
    """Oriented boxes standing on the ground.

    Attributes
    ----------
    centre_m : ndarray, shape (N, 3)
        Centre of the box's base (z = bottom), world frame, metres.
    size_m : ndarray, shape (N, 3)
        Length along ``yaw_rad``, width across it, height, metres.
    yaw_rad : ndarray, shape (N,)
    kind_id : ndarray, shape (N,), int
        Texture / model variant (see the ``*_`` constants of this module).
    """

    centre_m: FloatArray
    size_m: FloatArray
    yaw_rad: FloatArray
    kind_id: npt.NDArray[np.int64]

    @classmethod
    def from_rows(cls, rows: list[tuple[float, float, float, float, float, float, float, int]]) -> Boxes:
        """Build from ``(x, y, z, length, width, height, yaw, kind)`` tuples."""
        a = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
        return cls(a[:, 0:3].copy(), a[:, 3:6].copy(), a[:, 6].copy(), a[:, 7].astype(np.int64))

    def __len__(self) -> int:
        return int(self.centre_m.shape[0])


@dataclass(frozen=True, eq=False)
class World:
    """Everything static (and the moving agents) of one simulated sequence.

    Attributes
    ----------
    kind : str
        ``"slam"``, ``"calibration"`` or ``"still"``.
    seed : int
    scene : str
        ``"clear"``, ``"moderate"`` or ``"dynamic"`` (how many agents move, how fast).
    terrain : Terrain
    lanes : tuple of ndarray (K, 2)
        Lane centrelines in the driving direction.  Calibration: the closed approach loops.
    roads, blocks, sidewalks, buildings, poles, trees, parked_cars : Boxes
    targets : tuple of Target
    target : str
        The target the calibration motion drives toward.
    agents : Agents
    town_blocks : int
        Blocks per side of the town grid (0 for other kinds).
    block_m : float
        Distance between neighbouring road centrelines, metres.
    routes : dict
        Calibration: target kind -> closed loop polyline ``(K, 2)`` driven toward that target.
    shuttles : dict
        Calibration: target kind -> the legs of the shuttle drive in front of it (polylines
        ``(K, 2)``; even legs are driven forward, odd legs in reverse; the last ends where the
        first starts), see :func:`shuttle_legs`.
    calibration_drive : str
        ``"shuttle"`` or ``"loop"``: which drive the bumps were laid along.
    """

    kind: str
    seed: int
    scene: str
    terrain: Terrain
    lanes: tuple[FloatArray, ...]
    roads: Boxes
    blocks: Boxes
    sidewalks: Boxes
    buildings: Boxes
    poles: Boxes
    trees: Boxes
    parked_cars: Boxes
    targets: tuple[Target, ...]
    target: str
    agents: Agents
    town_blocks: int = 0
    block_m: float = BLOCK_M
    routes: dict[str, FloatArray] = field(default_factory=dict)
    shuttles: dict[str, tuple[FloatArray, ...]] = field(default_factory=dict)
    calibration_drive: str = "shuttle"

    def target_named(self, kind: str) -> Target:
        """The target of the given kind, or an :class:`IbiscapeError` if the world has none."""
        for t in self.targets:
            if t.target_type == kind:
                return t
        raise IbiscapeError(
            f"the {self.kind} world has no {kind!r} target (it has "
            f"{[t.target_type for t in self.targets] or 'none'})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Summary for ``sequence.yaml``: targets, bump list and object counts."""
        return {
            "kind": self.kind,
            "seed": int(self.seed),
            "scene": self.scene,
            "target": self.target if self.targets else None,
            "targets": [t.to_dict() for t in self.targets],
            "terrain": self.terrain.to_dict(),
            "calibration_drive": self.calibration_drive if self.kind == "calibration" else None,
            "town_blocks": int(self.town_blocks),
            "block_m": float(self.block_m),
            "counts": {
                "lanes": len(self.lanes),
                "roads": len(self.roads),
                "blocks": len(self.blocks),
                "sidewalks": len(self.sidewalks),
                "buildings": len(self.buildings),
                "poles": len(self.poles),
                "trees": len(self.trees),
                "parked_cars": len(self.parked_cars),
                **self.agents.to_dict(),
            },
            "conventions": {
                "frame": "world right-handed, z up, metres; lanes for right-hand traffic",
                "boxes": "centre of the base, size = length along yaw, width, height",
            },
        }


# ---------------------------------------------------------------------------------------------
# calibration ground


def calibration_loop(target: str) -> FloatArray:
    """Closed loop ``(K, 2)`` (first == last) that approaches ``target`` and turns away from it.

    The approach leg runs along +x toward the board with gentle S-bends (varying the viewing angle);
    the loop turns 10 m before the board, away from the other board, and returns 22 m to the side.
    """
    yc = TARGET_Y_M[target]
    side = -1.0 if yc < 0 else 1.0
    w = 2.5
    return np.array(
        [
            [0.0, yc],
            [20.0, yc + w],
            [40.0, yc - w],
            [58.0, yc + 0.6 * w],
            [TARGET_X_M - 10.0, yc],
            [TARGET_X_M - 10.0, yc + 22.0 * side],
            [-20.0, yc + 22.0 * side],
            [-20.0, yc],
            [0.0, yc],
        ]
    )


def loop_cuts(loop: FloatArray) -> FloatArray:
    """Corner cut per loop vertex: gentle S-bends 6 m, the 90 degree turns 9 m."""
    cuts = np.full(len(loop), CORNER_CUT_M["weave"])
    cuts[4:8] = CORNER_CUT_M["turn"]
    return cuts


def _loop_bumps(loop: FloatArray, rng: np.random.Generator) -> list[Bump]:
    """Bubbles and waves along a calibration loop (dense on the approach, sparser on the return)."""
    n = len(loop) - 1
    wrap = np.vstack((loop[-2:-1], loop, loop[1:2]))  # B3, A0 .. B3, A0, A1: every corner present
    cuts = np.concatenate((loop_cuts(loop)[-2:-1], loop_cuts(loop), [CORNER_CUT_M["weave"]]))
    path = smooth_path(wrap, cuts)
    s_a0, s_a4, s_end = path.vertex_s_m[1], path.vertex_s_m[5], path.vertex_s_m[n + 1]
    s_cand = np.concatenate(
        (np.arange(s_a0 + 6.0, s_a4 - 8.0, 5.0), np.arange(s_a4 + 20.0, s_end - 6.0, 9.0))
    )
    s_cand = s_cand[np.abs(path.curvature_1_m(s_cand)) < 0.03]
    xy = path.xy_m(s_cand)
    head = path.heading_rad(s_cand)
    bumps: list[Bump] = []
    for k in range(len(s_cand)):
        if k % 2 == 0:
            bumps.append(
                Bump(
                    "wave",
                    (xy[k, 0], xy[k, 1]),
                    float(rng.uniform(0.12, 0.18)),
                    width_m=float(rng.uniform(1.8, 2.6)),
                    length_m=5.0,
                    heading_rad=float(head[k]),
                )
            )
        else:
            side = 1.0 if rng.random() < 0.5 else -1.0
            off = 0.8 * side  # under one side's wheels (track 1.6 m): roll
            c = xy[k] + off * np.array([-math.sin(head[k]), math.cos(head[k])])
            bumps.append(
                Bump(
                    "bubble",
                    (c[0], c[1]),
                    float(rng.uniform(0.16, 0.24)),
                    radius_m=float(rng.uniform(1.0, 1.3)),
                )
            )
    return bumps


def shuttle_legs(target: str, seed: int, pairs: int = SHUTTLE_PAIRS) -> tuple[FloatArray, ...]:
    """The shuttle drive in front of ``target``: ``2 pairs`` polylines, forward and reverse in turn.

    The car keeps the board in view: each forward leg starts ``SHUTTLE_FAR_M`` from the board on
    a line through the board's centre, runs ``SHUTTLE_RUN_IN_M`` straight at it, crosses over to
    the line of the next viewing angle of ``SHUTTLE_SWEEP_DEG`` (off the board's normal, jittered
    +-3 deg) and ends on that line ``SHUTTLE_NEAR_M`` from the board after a straight
    ``SHUTTLE_RUN_OUT_M``; the reverse leg backs straight out along that line to the far distance.
    Each line is aimed up to ``SHUTTLE_AIM_M`` beside the board's centre, so that the board is
    also seen off the image centre (for the camera calibration on the same drive).  The car stops at every end (a cusp: the heading is continuous).
    Distances are drawn per leg from the seed; after ``pairs`` (a multiple of the sweep) the drive
    is back at its start, so the legs can be driven again.
    """
    rng = np.random.default_rng([seed, 7, TARGET_KINDS.index(target)])
    c = np.array([TARGET_X_M, TARGET_Y_M[target]])
    n = len(SHUTTLE_SWEEP_DEG)
    pairs = max(n, n * math.ceil(pairs / n))
    phi = np.radians(np.array([SHUTTLE_SWEEP_DEG[k % n] for k in range(pairs)])
                     + rng.uniform(-3.0, 3.0, pairs))

    def out(a: float) -> FloatArray:  # unit vector from the board toward the observer at angle a
        return np.array([-math.cos(a), math.sin(a)])

    sc = SHUTTLE_SCALE[target]
    far = sc * rng.uniform(*SHUTTLE_FAR_M, pairs)
    near = sc * rng.uniform(*SHUTTLE_NEAR_M, pairs)
    aim = sc * rng.uniform(-SHUTTLE_AIM_M, SHUTTLE_AIM_M, pairs)
    run_in, run_out = sc * SHUTTLE_RUN_IN_M, sc * SHUTTLE_RUN_OUT_M

    def on_line(k: int, r: float) -> FloatArray:
        """``r`` metres out along line ``k``: at angle ``phi[k]``, aimed ``aim[k]`` beside the centre
        (the board then sits off the image centre, which the camera calibration needs)."""
        u = out(phi[k])
        return c + aim[k] * np.array([-u[1], u[0]]) + r * u

    legs: list[FloatArray] = []
    for k in range(pairs):
        j = (k + 1) % pairs
        nk = on_line(j, near[k])
        legs.append(np.array([on_line(k, far[k]), on_line(k, far[k] - run_in),
                              on_line(j, near[k] + run_out), nk]))
        legs.append(np.array([nk, on_line(j, far[j])]))
    return tuple(legs)


def _shuttle_bumps(legs: tuple[FloatArray, ...], rng: np.random.Generator) -> list[Bump]:
    """A bubble under one side's wheels (roll) halfway along every forward leg's cross-over, a wave
    across every reverse leg (pitch) and a bubble further out, skipping any that would overlap an
    earlier bump."""
    bumps: list[Bump] = []
    centres: list[FloatArray] = []

    def free(p: FloatArray) -> bool:
        return all(float(np.hypot(*(p - q))) > 2.2 for q in centres)

    for i, leg in enumerate(legs):
        if i % 2 == 0:
            a, b = leg[1], leg[2]
            d = (b - a) / np.linalg.norm(b - a)
            side = 1.0 if rng.random() < 0.5 else -1.0
            p = 0.5 * (a + b) + 0.8 * side * np.array([-d[1], d[0]])
            if free(p):
                centres.append(p)
                bumps.append(Bump("bubble", (p[0], p[1]), float(rng.uniform(0.16, 0.24)),
                                  radius_m=float(rng.uniform(1.0, 1.3))))
        else:
            a, b = leg[0], leg[1]
            d = (b - a) / np.linalg.norm(b - a)
            p = a + float(rng.uniform(0.25, 0.4)) * (b - a)
            if free(p):
                centres.append(p)
                bumps.append(Bump("wave", (p[0], p[1]), float(rng.uniform(0.14, 0.2)),
                                  width_m=float(rng.uniform(1.8, 2.4)), length_m=2.6,
                                  heading_rad=float(math.atan2(d[1], d[0]))))
            side = 1.0 if rng.random() < 0.5 else -1.0
            p = a + float(rng.uniform(0.65, 0.8)) * (b - a) + 0.8 * side * np.array([-d[1], d[0]])
            if free(p):
                centres.append(p)
                bumps.append(Bump("bubble", (p[0], p[1]), float(rng.uniform(0.16, 0.24)),
                                  radius_m=float(rng.uniform(1.0, 1.3))))
    return bumps


def _calibration_world(seed: int, scene: str, target: str, bumps: bool,
                       drive: str = "shuttle") -> dict[str, Any]:
    rng = np.random.default_rng([seed, 1])
    loops = {k: calibration_loop(k) for k in TARGET_KINDS}
    shuttles = {k: shuttle_legs(k, seed) for k in TARGET_KINDS}
    targets = tuple(
        make_target(k, T_world_target=board_pose(k, [TARGET_X_M, TARGET_Y_M[k], TARGET_CENTRE_Z_M], math.pi,
                                                 math.radians(TARGET_LEAN_DEG)))
        for k in TARGET_KINDS
    )
    bump_list: list[Bump] = []
    if bumps and drive == "loop":
        for k in TARGET_KINDS:
            bump_list += _loop_bumps(loops[k], rng)
    elif bumps:  # the shuttles of the two boards overlap: bumps along the driven one only
        bump_list += _shuttle_bumps(shuttles[target], np.random.default_rng([seed, 8]))
    pad = Boxes.from_rows([(35.0, 0.0, 0.0, 150.0, 80.0, 0.0, 0.0, ROAD_CALIBRATION_PAD)])
    stands = []
    for t in targets:
        c = t.centre_world_m
        half = 0.5 * t.board_size_m[0] + 0.1
        for sgn in (-1.0, 1.0):
            stands.append((c[0] + 0.1, c[1] + sgn * half, 0.0, 0.15, 0.15, c[2] + 0.5 * t.board_size_m[1],
                           0.0, POLE_TARGET_STAND))
    # a row of buildings behind the boards and along the sides, for visual texture
    rows = []
    for i, y in enumerate(np.arange(-40.0, 41.0, 16.0)):
        rows.append((TARGET_X_M + 25.0, float(y), 0.0, 12.0, 14.0, float(rng.uniform(8, 20)),
                     0.0, i % N_FACADES))
    for i, x in enumerate(np.arange(-30.0, 101.0, 20.0)):
        for y in (-52.0, 52.0):
            rows.append((float(x), y, 0.0, 16.0, 10.0, float(rng.uniform(6, 16)), 0.0,
                         (i + 3) % N_FACADES))
    lights = [(float(x), y, 0.0, 0.2, 0.2, 7.0, 0.0, POLE_STREETLIGHT)
              for x in np.arange(-30.0, 101.0, 26.0) for y in (-41.0, 41.0)]
    n_cars, n_ped = {"clear": (0, 0), "moderate": (2, 3), "dynamic": (5, 8)}[scene]
    agents = _agents(rng, scene, n_cars, n_ped, car_loops=[((-32.0, -45.0), (105.0, 45.0))],
                     ped_loops=[((-30.0, -47.0), (102.0, -36.0)), ((-30.0, 36.0), (102.0, 47.0))])
    return {
        "terrain": Terrain(tuple(bump_list)),
        "lanes": tuple(loops[k] for k in TARGET_KINDS),
        "roads": pad,
        "blocks": Boxes.from_rows([]),
        "sidewalks": Boxes.from_rows([]),
        "buildings": Boxes.from_rows(rows),
        "poles": Boxes.from_rows(stands + lights),
        "trees": Boxes.from_rows(
            [(float(x), 60.0, 0.0, 3.0, 3.0, float(rng.uniform(4, 8)), 0.0, int(rng.integers(N_TREE_KINDS)))
             for x in np.arange(-30.0, 101.0, 9.0)]
        ),
        "parked_cars": Boxes.from_rows(
            [(float(x), -30.0, 0.0, 4.5, 1.9, 1.5, 0.5 * math.pi, int(rng.integers(N_CAR_COLOURS)))
             for x in (-10.0, -7.0, -4.0)]
        ),
        "targets": targets,
        "agents": agents,
        "routes": loops,
        "shuttles": shuttles,
        "calibration_drive": drive,
    }


# ---------------------------------------------------------------------------------------------
# town


def _agents(
    rng: np.random.Generator,
    scene: str,
    n_cars: int,
    n_ped: int,
    *,
    car_loops: list[tuple[tuple[float, float], tuple[float, float]]],
    ped_loops: list[tuple[tuple[float, float], tuple[float, float]]],
) -> Agents:
    if n_cars + n_ped == 0:
        return Agents.none()
    fast = scene == "dynamic"
    kinds = np.array([AGENT_CAR] * n_cars + [AGENT_PEDESTRIAN] * n_ped, dtype=np.int64)
    ci = rng.integers(len(car_loops), size=n_cars)
    pi = rng.integers(len(ped_loops), size=n_ped)
    lo = np.array([car_loops[i][0] for i in ci] + [ped_loops[i][0] for i in pi]).reshape(-1, 2)
    hi = np.array([car_loops[i][1] for i in ci] + [ped_loops[i][1] for i in pi]).reshape(-1, 2)
    size = np.array([[4.5, 1.9, 1.5]] * n_cars + [[0.5, 0.6, 1.75]] * n_ped).reshape(-1, 3)
    speed = np.concatenate(
        (
            rng.uniform(7.0, 11.0, n_cars) if fast else rng.uniform(4.0, 7.0, n_cars),
            rng.uniform(1.2, 2.5, n_ped) if fast else rng.uniform(0.9, 1.5, n_ped),
        )
    )
    perim = 2.0 * ((hi - lo).sum(axis=1))
    # cars: clockwise round the block (right-hand traffic, block on the right); pedestrians: either
    cw = np.concatenate((np.ones(n_cars, bool), rng.random(n_ped) < 0.5))
    return Agents(kinds, size, lo, hi, cw, speed, rng.uniform(0.0, 1.0, len(kinds)) * perim)


def _town_world(seed: int, scene: str, n: int, bumps: bool) -> dict[str, Any]:
    rng = np.random.default_rng([seed, 2])
    lanes, roads = _town_lanes_and_roads(n)
    rows: dict[str, list[tuple[Any, ...]]] = {k: [] for k in
                                               ("blocks", "sidewalks", "buildings", "poles", "trees", "parked")}
    inner = BLOCK_M - 2 * ROAD_HALF_WIDTH_M  # block incl. sidewalks
    for bi in range(n):
        for bj in range(n):
            cx, cy = (bi + 0.5) * BLOCK_M, (bj + 0.5) * BLOCK_M
            rows["blocks"].append((cx, cy, 0.0, inner - 2 * SIDEWALK_M, inner - 2 * SIDEWALK_M, 0.15, 0.0, 0))
            for k in range(4):
                _block_edge(rng, rows, cx, cy, 0.5 * math.pi * k, inner)
    bump_list = _town_bumps(rng, n) if bumps else []
    car_loops, ped_loops = [], []
    for bi in range(n):
        for bj in range(n):
            x0, y0 = bi * BLOCK_M, bj * BLOCK_M
            car_loops.append(((x0 + LANE_OFFSET_M, y0 + LANE_OFFSET_M),
                              (x0 + BLOCK_M - LANE_OFFSET_M, y0 + BLOCK_M - LANE_OFFSET_M)))
            off = ROAD_HALF_WIDTH_M + 0.5 * SIDEWALK_M
            ped_loops.append(((x0 + off, y0 + off), (x0 + BLOCK_M - off, y0 + BLOCK_M - off)))
    n_cars, n_ped = {"clear": (0, 0), "moderate": (4, 8), "dynamic": (4 * n, 8 * n)}[scene]
    return {
        "terrain": Terrain(tuple(bump_list)),
        "lanes": tuple(lanes),
        "roads": Boxes.from_rows(roads),
        "blocks": Boxes.from_rows(rows["blocks"]),
        "sidewalks": Boxes.from_rows(rows["sidewalks"]),
        "buildings": Boxes.from_rows(rows["buildings"]),
        "poles": Boxes.from_rows(rows["poles"]),
        "trees": Boxes.from_rows(rows["trees"]),
        "parked_cars": Boxes.from_rows(rows["parked"]),
        "targets": (),
        "agents": _agents(rng, scene, n_cars, n_ped, car_loops=car_loops, ped_loops=ped_loops),
        "routes": {},
    }


def _town_lanes_and_roads(n: int) -> tuple[list[FloatArray], list[tuple[Any, ...]]]:
    """The lanes (two per direction per street) and road boxes of an ``n x n`` block grid."""
    extent = n * BLOCK_M
    lanes: list[FloatArray] = []
    roads = []
    for j in range(n + 1):
        c = j * BLOCK_M
        # along x at y = c: eastbound lane south of the centreline, westbound north of it
        lanes.append(np.array([[0.0, c - LANE_OFFSET_M], [extent, c - LANE_OFFSET_M]]))
        lanes.append(np.array([[extent, c + LANE_OFFSET_M], [0.0, c + LANE_OFFSET_M]]))
        # along y at x = c: northbound lane east of the centreline, southbound west of it
        lanes.append(np.array([[c + LANE_OFFSET_M, 0.0], [c + LANE_OFFSET_M, extent]]))
        lanes.append(np.array([[c - LANE_OFFSET_M, extent], [c - LANE_OFFSET_M, 0.0]]))
        roads.append((0.5 * extent, c, 0.0, extent + 2 * ROAD_HALF_WIDTH_M, 2 * ROAD_HALF_WIDTH_M, 0.0,
                      0.0, ROAD_ASPHALT))
        roads.append((c, 0.5 * extent, 0.0, extent + 2 * ROAD_HALF_WIDTH_M, 2 * ROAD_HALF_WIDTH_M, 0.0,
                      0.5 * math.pi, ROAD_ASPHALT))
    return lanes, roads


def _block_edge(rng: np.random.Generator, rows: dict[str, list[tuple[Any, ...]]], cx: float, cy: float,
                yaw: float, inner: float) -> None:
    """The sidewalk, buildings, street lights, trees and parked cars along one edge of the block
    centred at ``(cx, cy)`` (edge direction ``yaw``), appended to ``rows``."""
    ux, uy = math.cos(yaw), math.sin(yaw)
    nx, ny = -uy, ux  # normal of this block edge, pointing from the block to the road
    ox, oy = cx + (0.5 * inner - 0.5 * SIDEWALK_M) * nx, cy + (0.5 * inner - 0.5 * SIDEWALK_M) * ny
    rows["sidewalks"].append((ox, oy, 0.0, inner, SIDEWALK_M, 0.15, yaw, 0))
    # buildings along this edge, set back behind the sidewalk
    along = -0.5 * inner + SIDEWALK_M + 1.0
    while True:
        front = float(rng.uniform(10.0, 20.0))
        if along + front > 0.5 * inner - SIDEWALK_M - 1.0:
            break
        depth = float(rng.uniform(10.0, 16.0))
        back = 0.5 * inner - SIDEWALK_M - 1.0 - 0.5 * depth
        mid = along + 0.5 * front
        rows["buildings"].append((cx + mid * ux + back * nx, cy + mid * uy + back * ny, 0.0, front, depth,
                                  float(rng.uniform(8.0, 30.0)), yaw, int(rng.integers(N_FACADES))))
        along += front + float(rng.uniform(0.0, 3.0))
    # street lights and trees on the sidewalk's road side
    for a in np.arange(-0.5 * inner + 6.0, 0.5 * inner - 5.0, 22.0):
        d = 0.5 * inner - 0.5
        rows["poles"].append((cx + a * ux + d * nx, cy + a * uy + d * ny, 0.0, 0.2, 0.2, 6.5, 0.0,
                              POLE_STREETLIGHT))
    for a in np.arange(-0.5 * inner + 13.0, 0.5 * inner - 8.0, 15.0):
        if rng.random() < 0.7:
            d = 0.5 * inner - 1.5
            rows["trees"].append((cx + a * ux + d * nx, cy + a * uy + d * ny, 0.0, 2.5, 2.5,
                                  float(rng.uniform(4.0, 8.0)), 0.0, int(rng.integers(N_TREE_KINDS))))
    # parked cars in the parking strip next to this block (traffic-aligned: block on the right of
    # the lane next to it, so they face clockwise round the block)
    for a in np.arange(-0.5 * inner + 8.0, 0.5 * inner - 8.0, 6.5):
        if rng.random() < 0.35:
            d = 0.5 * inner + 0.5 * PARKING_WIDTH_M
            rows["parked"].append((cx + a * ux + d * nx, cy + a * uy + d * ny, 0.0, 4.5, 1.9, 1.5,
                                   yaw, int(rng.integers(N_CAR_COLOURS))))


def _town_bumps(rng: np.random.Generator, n: int) -> list[Bump]:
    """Speed bumps (waves across both lanes) and small bubbles on a quarter of the street edges."""
    bump_list: list[Bump] = []
    for j in range(n + 1):
        for i in range(n):
            for horizontal in (True, False):
                if rng.random() >= 0.25:
                    continue
                a = (i + 0.5) * BLOCK_M + float(rng.uniform(-15.0, 15.0))
                c = j * BLOCK_M
                centre = (a, c) if horizontal else (c, a)
                head = 0.0 if horizontal else 0.5 * math.pi
                if rng.random() < 0.6:
                    bump_list.append(Bump("wave", centre, 0.08, width_m=1.2, length_m=2 * LANE_WIDTH_M,
                                          heading_rad=head))
                else:
                    lane = LANE_OFFSET_M * (1 if rng.random() < 0.5 else -1) + 0.8 * (
                        1 if rng.random() < 0.5 else -1)
                    pos = (a, c + lane) if horizontal else (c + lane, a)
                    bump_list.append(Bump("bubble", pos, 0.07, radius_m=0.8))
    return bump_list


def build_world(
    *,
    kind: str,
    seed: int,
    target: str = "checkerboard",
    scene: str = "clear",
    town_blocks: int = 4,
    bumps: bool = True,
    calibration_drive: str = "shuttle",
) -> World:
    """Build a deterministic world.

    Parameters
    ----------
    kind : str
        ``"slam"`` (town grid), ``"calibration"`` (open ground with a checkerboard and an AprilGrid
        facing the approach loops, bubbles and waves on the loops) or ``"still"`` (flat, empty).
    seed : int
        Seeds every random choice (building sizes, bump heights, agents).
    target : str
        ``"checkerboard"`` or ``"aprilgrid"``: the board a calibration motion drives toward.
    scene : str
        ``"clear"`` (no agents), ``"moderate"`` (a few), ``"dynamic"`` (many, faster).
    town_blocks : int
        SLAM: blocks per side of the town grid (1..20), each ``BLOCK_M`` = 80 m.
    bumps : bool
        Whether the road has bubbles and waves (SLAM: a few speed bumps; calibration: many).
    calibration_drive : str
        Calibration: ``"shuttle"`` (forward and reverse legs in front of the board, which stays in
        view; :func:`shuttle_legs`) or ``"loop"`` (the paper's approach loop); the bumps are laid
        along it.

    Returns
    -------
    World
    """
    if kind not in WORLD_KINDS:
        raise IbiscapeError(f"world kind {kind!r} is unknown; use one of {WORLD_KINDS}")
    if scene not in SCENES:
        raise IbiscapeError(f"scene {scene!r} is unknown; use one of {SCENES}")
    if target not in TARGET_KINDS:
        raise IbiscapeError(f"target {target!r} is unknown; use one of {TARGET_KINDS}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise IbiscapeError(f"seed must be a non-negative integer, got {seed!r}")
    seed = int(seed)
    if kind == "slam":
        if isinstance(town_blocks, bool) or not isinstance(town_blocks, (int, np.integer)) or not (
            1 <= town_blocks <= 20
        ):
            raise IbiscapeError(f"town_blocks must be an integer in 1..20, got {town_blocks!r}")
        parts = _town_world(seed, scene, int(town_blocks), bumps)
        return World(kind, seed, scene, target=target, town_blocks=int(town_blocks), **parts)
    if kind == "calibration":
        if calibration_drive not in CALIBRATION_DRIVES:
            raise IbiscapeError(f"calibration_drive {calibration_drive!r} is unknown; use one of "
                                f"{CALIBRATION_DRIVES}")
        parts = _calibration_world(seed, scene, target, bumps, calibration_drive)
        return World(kind, seed, scene, target=target, **parts)
    empty = Boxes.from_rows([])
    return World(
        kind, seed, scene, Terrain(()), (),
        Boxes.from_rows([(0.0, 0.0, 0.0, 40.0, 40.0, 0.0, 0.0, ROAD_ASPHALT)]),
        empty, empty, empty, empty, empty, empty, (), target, Agents.none(),
    )
