"""Meshes of the world for open3d's ``RaycastingScene``, with per-triangle material, label and
texture coordinates.

- Everything static goes into ONE geometry, so a hit's ``primitive_id`` indexes the tables of
  :class:`TriangleTables` directly.  The last table row is a sentinel for rays that hit nothing.
- Boxes (buildings, blocks, sidewalks, poles, trees, parked cars, the accident obstacle) get five
  faces (no bottom).  Texture coordinates are metres on the face: sides ``u`` along the face, ``v``
  height above the base; tops ``u, v`` along the box's length and width.
- The ground is one large quad plus a fine height-field patch over every bump of the terrain (the
  patch lies on or above the quad, so the bump wins; both use world ``x, y`` as texture coordinates).
  Roads, the calibration pad and lane markings are not geometry: they are painted on the ground
  from a raster :class:`GroundMap` (asphalt, pad and marking coverage, antialiased).
- Targets are one quad each whose texture coordinates are the target-frame ``x, y`` [m].
- Movers (cars, pedestrians) are rebuilt per time in a second small scene (:func:`mover_mesh`);
  the renderer keeps the nearer of the two hits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..agents import AGENT_CAR
from ..world import (
    LANE_WIDTH_M,
    POLE_TARGET_STAND,
    ROAD_CALIBRATION_PAD,
    Boxes,
    World,
)
from .labels import TAG

__all__ = ["MAT", "GroundMap", "StaticScene", "TriangleTables", "box_mesh", "build_static_scene",
           "mover_mesh", "open3d", "tensor"]

F32 = npt.NDArray[np.float32]

#: material ids (row of the texture tables in ``textures.py``)
MAT = {"sky": 0, "ground": 1, "block": 2, "sidewalk": 3, "facade": 4, "roof": 5, "pole": 6,
       "crown": 7, "trunk": 8, "car": 9, "pedestrian": 10, "target": 11, "stand": 12, "car_roof": 13}

_BUMP_GRID_M = 0.08  # height-field resolution over a bump
_GROUND_HALF_M = 3000.0


@dataclass(frozen=True, eq=False)
class TriangleTables:
    """Per-triangle attributes; row ``T`` (the last) is the 'nothing hit' sentinel.

    Attributes
    ----------
    material, variant, label : ndarray (T + 1,) uint8
    uv_m : ndarray (T + 1, 3, 2) float32
        Texture coordinates of the three vertices, metres.
    """

    material: npt.NDArray[np.uint8]
    variant: npt.NDArray[np.uint8]
    label: npt.NDArray[np.uint8]
    uv_m: F32

    @classmethod
    def concat(cls, parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]) -> TriangleTables:
        mats = [p[0] for p in parts] + [np.array([MAT["sky"]])]
        var = [p[1] for p in parts] + [np.zeros(1)]
        lab = [p[2] for p in parts] + [np.array([TAG["Sky"]])]
        uv = [p[3] for p in parts] + [np.zeros((1, 3, 2))]
        return cls(np.concatenate(mats).astype(np.uint8), np.concatenate(var).astype(np.uint8),
                   np.concatenate(lab).astype(np.uint8), np.concatenate(uv).astype(np.float32))


def open3d() -> Any:
    """The ``open3d`` module (imported on first use: it takes a second to load)."""
    import importlib

    return importlib.import_module("open3d")


def tensor(a: np.ndarray) -> Any:
    """A zero-copy open3d tensor of a numpy array."""
    return open3d().core.Tensor.from_numpy(np.ascontiguousarray(a))


# ------------------------------------------------------------------------------------------ boxes
# face corners in the unit box (x, y in [-0.5, 0.5], z in [0, 1]), counter-clockwise from outside
_FACES = np.array([
    [(0.5, -0.5, 0), (0.5, 0.5, 0), (0.5, 0.5, 1), (0.5, -0.5, 1)],      # +x
    [(-0.5, 0.5, 0), (-0.5, -0.5, 0), (-0.5, -0.5, 1), (-0.5, 0.5, 1)],  # -x
    [(0.5, 0.5, 0), (-0.5, 0.5, 0), (-0.5, 0.5, 1), (0.5, 0.5, 1)],      # +y
    [(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, -0.5, 1), (-0.5, -0.5, 1)],  # -y
    [(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)],    # top
], dtype=np.float64)
_QUAD_TRIS = np.array([[0, 1, 2], [0, 2, 3]])


def box_mesh(centre_m: np.ndarray, size_m: np.ndarray, yaw_rad: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Vertices ``(20 N, 3)``, triangles ``(10 N, 3)``, per-triangle vertex uv ``(10 N, 3, 2)`` [m]
    and a per-triangle top-face flag ``(10 N,)`` of ``N`` oriented boxes standing on their base."""
    n = len(centre_m)
    loc = _FACES[None] * size_m[:, None, None, :]  # (N, 5, 4, 3)
    c, s = np.cos(yaw_rad)[:, None, None], np.sin(yaw_rad)[:, None, None]
    x = c * loc[..., 0] - s * loc[..., 1] + centre_m[:, None, None, 0]
    y = s * loc[..., 0] + c * loc[..., 1] + centre_m[:, None, None, 1]
    z = loc[..., 2] + centre_m[:, None, None, 2]
    verts = np.stack([x, y, z], -1).reshape(-1, 3)
    L, W = size_m[:, 0, None], size_m[:, 1, None]
    f = _FACES
    u = np.stack([(f[0, :, 1] + 0.5) * W, (0.5 - f[1, :, 1]) * W, (0.5 - f[2, :, 0]) * L,
                  (f[3, :, 0] + 0.5) * L, (f[4, :, 0] + 0.5) * L], axis=1)  # (N, 5, 4)
    v = np.concatenate([f[None, :4, :, 2] * size_m[:, None, None, 2],
                        ((f[4, :, 1] + 0.5)[None, :] * W)[:, None, :]], axis=1)
    uv_v = np.stack([u, v], -1).reshape(n, 5, 4, 2)
    base = (np.arange(n * 5) * 4)[:, None, None]
    tris = (base + _QUAD_TRIS[None]).reshape(-1, 3)
    uv = uv_v[:, :, _QUAD_TRIS, :].reshape(-1, 3, 2)
    top = np.broadcast_to(np.array([0, 0, 0, 0, 1], bool)[None, :, None], (n, 5, 2)).reshape(-1)
    return verts, tris, uv, top


@dataclass(frozen=True, eq=False)
class GroundMap:
    """Raster of what is painted on the ground: channels asphalt, calibration pad, marking
    coverage (0..255), texel centres at ``origin_m + (i + 0.5) res_m``."""

    image: npt.NDArray[np.uint8]
    origin_m: tuple[float, float]
    res_m: float


def _ground_map(world: World) -> GroundMap:
    import cv2

    pts = [np.zeros((1, 2))]
    for b in (world.roads, world.blocks, world.buildings):
        if len(b):
            pts.append(b.centre_m[:, :2] - np.linalg.norm(b.size_m[:, :2], axis=1)[:, None])
            pts.append(b.centre_m[:, :2] + np.linalg.norm(b.size_m[:, :2], axis=1)[:, None])
    for lane in world.lanes:
        pts.append(lane)
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0) - 10.0, allp.max(axis=0) + 10.0
    res = max(0.05, float(np.max(hi - lo)) / 4096.0)
    w, h = (np.ceil((hi - lo) / res)).astype(int)
    img = np.zeros((h, w, 3), np.uint8)
    shift = 4  # cv2 fixed-point: coordinates in 1/16 texel

    def px(xy: np.ndarray) -> np.ndarray:
        return np.round(((np.asarray(xy) - lo) / res - 0.5) * (1 << shift)).astype(np.int32)

    r = world.roads
    count = np.zeros((h, w), np.uint8)
    mark = np.zeros((h, w), np.uint8)
    for i in range(len(r)):
        cx, cy, _ = r.centre_m[i]
        L, W, _ = r.size_m[i]
        c, s = math.cos(r.yaw_rad[i]), math.sin(r.yaw_rad[i])
        ax, ay = np.array([c, s]), np.array([-s, c])
        sl = 0.5 * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
        corners = np.array([cx, cy]) + (sl[:, :1] * L) * ax + (sl[:, 1:] * W) * ay
        ch = 1 if r.kind_id[i] == ROAD_CALIBRATION_PAD else 0
        layer = np.ascontiguousarray(img[..., ch])
        cv2.fillPoly(layer, [px(corners)], 255, cv2.LINE_AA, shift)
        img[..., ch] = layer
        if ch == 0:
            one = np.zeros((h, w), np.uint8)
            cv2.fillPoly(one, [px(corners)], 1, cv2.LINE_8, shift)
            count += one
            # dashed centre line (3 m of every 6 m) and solid lines between lanes and parking strips
            a = np.arange(-0.5 * L, 0.5 * L - 3.0, 6.0)
            dash = [px(np.stack([np.array([cx, cy]) + (a0 * ax), np.array([cx, cy]) + ((a0 + 3.0) * ax)]))
                    for a0 in a]
            side = [px(np.stack([np.array([cx, cy]) - 0.5 * L * ax + k * LANE_WIDTH_M * ay,
                                 np.array([cx, cy]) + 0.5 * L * ax + k * LANE_WIDTH_M * ay]))
                    for k in (-1.0, 1.0)]
            thick = max(1, round(0.15 / res))
            cv2.polylines(mark, dash + side, False, 255, thick, cv2.LINE_AA, shift)
    if len(r):
        mark[count >= 2] = 0  # no markings across intersections
    if world.kind == "calibration":
        thick = max(1, round(0.12 / res))
        cv2.polylines(mark, [px(lane) for lane in world.lanes], True, 255, thick, cv2.LINE_AA, shift)
    img[..., 2] = mark
    img.setflags(write=False)
    return GroundMap(img, (float(lo[0]), float(lo[1])), res)


# ------------------------------------------------------------------------------------ the scene
@dataclass(frozen=True, eq=False)
class StaticScene:
    """The static world: one open3d geometry, its triangle tables, the ground map, the targets."""

    scene: Any  # open3d.t.geometry.RaycastingScene
    tables: TriangleTables
    ground: GroundMap
    targets: tuple[Any, ...]
    n_triangles: int
    #: the scene's vertices (V, 3) and triangles (T, 3) without the ground quad (the first two
    #: triangles of ``scene``): what can shade a point above the ground
    occluder_vertices: F32 | None = None
    occluder_triangles: npt.NDArray[np.uint32] | None = None
    #: every triangle (T, 3) of ``scene`` (rows = primitive ids; vertices ``occluder_vertices``)
    triangles: npt.NDArray[np.uint32] | None = None


def _part(verts: np.ndarray, tris: np.ndarray, uv: np.ndarray, material: np.ndarray | int,
          variant: np.ndarray | int, label: np.ndarray | int) -> tuple[np.ndarray, ...]:
    n = len(tris)
    return (verts, tris, np.broadcast_to(material, (n,)), np.broadcast_to(variant, (n,)),
            np.broadcast_to(label, (n,)), uv)


def _boxes(b: Boxes, material: int, label: int, *, top_material: int | None = None,
           variant: np.ndarray | None = None) -> list[tuple[np.ndarray, ...]]:
    if len(b) == 0:
        return []
    v, t, uv, top = box_mesh(b.centre_m, b.size_m, b.yaw_rad)
    mat = np.where(top, material if top_material is None else top_material, material)
    var = np.repeat(b.kind_id if variant is None else variant, 10)
    return [_part(v, t, uv, mat, var, label)]


def _trees(b: Boxes) -> list[tuple[np.ndarray, ...]]:
    if len(b) == 0:
        return []
    h = b.size_m[:, 2]
    trunk = Boxes(b.centre_m, np.stack([np.full(len(b), 0.35), np.full(len(b), 0.35), 0.45 * h], -1),
                  b.yaw_rad, b.kind_id)
    crown_c = b.centre_m.copy()
    crown_c[:, 2] += 0.4 * h
    crown = Boxes(crown_c, np.stack([b.size_m[:, 0], b.size_m[:, 1], 0.6 * h], -1), b.yaw_rad + 0.3,
                  b.kind_id)
    return _boxes(trunk, MAT["trunk"], TAG["Vegetation"]) + _boxes(crown, MAT["crown"], TAG["Vegetation"])


def _cars(b: Boxes, label: int = TAG["Vehicles"]) -> list[tuple[np.ndarray, ...]]:
    """A car: lower body (full footprint, 60 % of the height) and a shorter cabin on top."""
    if len(b) == 0:
        return []
    h = b.size_m[:, 2]
    body = Boxes(b.centre_m, np.stack([b.size_m[:, 0], b.size_m[:, 1], 0.55 * h], -1), b.yaw_rad, b.kind_id)
    cab_c = b.centre_m.copy()
    cab_c[:, 2] += 0.55 * h
    cab = Boxes(cab_c, np.stack([0.55 * b.size_m[:, 0], 0.9 * b.size_m[:, 1], 0.45 * h], -1), b.yaw_rad,
                b.kind_id)
    return (_boxes(body, MAT["car"], label, top_material=MAT["car_roof"])
            + _boxes(cab, MAT["car"], label, top_material=MAT["car_roof"], variant=b.kind_id + 100))


def _bumps(world: World) -> list[tuple[np.ndarray, ...]]:
    out = []
    for bump in world.terrain.bumps:
        e = bump.extent_m
        n = max(2, math.ceil(2 * e / _BUMP_GRID_M))
        g = np.linspace(-e, e, n + 1)
        X, Y = np.meshgrid(g + bump.centre_m[0], g + bump.centre_m[1])
        xy = np.stack([X.ravel(), Y.ravel()], -1)
        z = world.terrain.height_m(xy)
        verts = np.column_stack([xy, z])
        i, j = np.meshgrid(np.arange(n), np.arange(n))
        a = (j * (n + 1) + i).ravel()
        tris = np.concatenate([np.stack([a, a + 1, a + n + 2], -1), np.stack([a, a + n + 2, a + n + 1], -1)])
        uv = xy[tris]
        out.append(_part(verts, tris, uv, MAT["ground"], 0, TAG["Road"]))
    return out


def _targets(world: World) -> list[tuple[np.ndarray, ...]]:
    out = []
    for k, t in enumerate(world.targets):
        lo, hi = t.board_min_m, t.board_max_m
        q = np.array([[lo[0], lo[1], 0.0], [hi[0], lo[1], 0.0], [hi[0], hi[1], 0.0], [lo[0], hi[1], 0.0]])
        verts = q @ t.T_world_target[:3, :3].T + t.T_world_target[:3, 3]
        uv = q[:, :2][_QUAD_TRIS]
        out.append(_part(verts, _QUAD_TRIS.copy(), uv, MAT["target"], k, TAG["Static"]))
    return out


def _assemble(parts: list[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, np.ndarray, TriangleTables]:
    verts, tris, rows = [], [], []
    off = 0
    for v, t, m, var, lab, uv in parts:
        verts.append(v)
        tris.append(t + off)
        off += len(v)
        rows.append((m, var, lab, uv))
    V = np.concatenate(verts).astype(np.float32) if verts else np.zeros((0, 3), np.float32)
    T = np.concatenate(tris).astype(np.uint32) if tris else np.zeros((0, 3), np.uint32)
    return V, T, TriangleTables.concat(rows)


def build_static_scene(world: World, *, extra_cars: Boxes | None = None) -> StaticScene:
    """Build the static open3d scene of ``world`` (plus, e.g., the accident's obstacle car)."""
    g = _GROUND_HALF_M
    ground_q = np.array([[-g, -g, 0.0], [g, -g, 0.0], [g, g, 0.0], [-g, g, 0.0]])
    parts = [_part(ground_q, _QUAD_TRIS.copy(), ground_q[:, :2][_QUAD_TRIS], MAT["ground"], 0, TAG["Road"])]
    parts += _bumps(world)
    parts += _boxes(world.blocks, MAT["block"], TAG["Terrain"])
    parts += _boxes(world.sidewalks, MAT["sidewalk"], TAG["SideWalk"])
    parts += _boxes(world.buildings, MAT["facade"], TAG["Building"], top_material=MAT["roof"])
    stands = world.poles.kind_id == POLE_TARGET_STAND
    poles = world.poles
    parts += _boxes(Boxes(poles.centre_m[~stands], poles.size_m[~stands], poles.yaw_rad[~stands],
                          poles.kind_id[~stands]), MAT["pole"], TAG["Pole"])
    parts += _boxes(Boxes(poles.centre_m[stands], poles.size_m[stands], poles.yaw_rad[stands],
                          poles.kind_id[stands]), MAT["stand"], TAG["Static"])
    parts += _trees(world.trees)
    parts += _cars(world.parked_cars)
    if extra_cars is not None:
        parts += _cars(extra_cars)
    parts += _targets(world)
    V, T, tables = _assemble(parts)
    scene = open3d().t.geometry.RaycastingScene()
    scene.add_triangles(tensor(V), tensor(T))
    return StaticScene(scene, tables, _ground_map(world), tuple(world.targets), len(T), V, T[len(_QUAD_TRIS):], T)


def mover_mesh(world: World, t_ns: int) -> tuple[F32, npt.NDArray[np.uint32], TriangleTables]:
    """Meshes of the moving agents at ``t_ns`` (cars: body and cabin; pedestrians: a box)."""
    ag = world.agents
    if len(ag) == 0:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32), TriangleTables.concat([])
    pos, yaw = ag.poses_at(np.array([t_ns], dtype=np.int64))
    car = ag.kind_id == AGENT_CAR
    idx = np.arange(len(ag))
    cars = Boxes(pos[car, 0], ag.size_m[car], yaw[car, 0], idx[car] % 6)
    ped = Boxes(pos[~car, 0], ag.size_m[~car], yaw[~car, 0], idx[~car] % 6)
    parts = _cars(cars) + _boxes(ped, MAT["pedestrian"], TAG["Pedestrian"])
    V, T, tables = _assemble(parts)
    return V, T, tables
