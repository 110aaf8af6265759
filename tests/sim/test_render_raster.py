"""The rasterised primary visibility (``sim.render.raster``) against open3d's ``cast_rays`` of the
same rays: the same triangle, depth, barycentric coordinates and normal at every pixel but for
exact ties between coplanar triangles, for pinhole and distorted cameras, triangles straddling
the camera plane, behind it and spread over many culling chunks; and whole renders with either
primary visibility."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render.raster import cast_camera, raster_mesh
from ibiscape_eval.sim.render.rays import camera_rays, world_rays
from ibiscape_eval.sim.render.scene import box_mesh, open3d, tensor
from ibiscape_eval.sim.world import build_world

CAMERAS = [CameraModel.from_fov(96, 80, 90.0),
           CameraModel(96, 80, 50.0, 52.0, 47.3, 40.6, "radtan", (-0.3, 0.08, 2e-4, -3e-4)),
           CameraModel(96, 80, 45.0, 45.0, 48.2, 39.1, "equidistant", (0.05, -0.01, 0.002, 0.0))]


def _pose(pos: tuple[float, float, float], yaw_deg: float) -> np.ndarray:
    """Camera looking horizontally along ``yaw`` (OpenCV frame: z forward, y down)."""
    y = np.radians(yaw_deg)
    fwd, left = np.array([np.cos(y), np.sin(y), 0.0]), np.array([-np.sin(y), np.cos(y), 0.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([-left, [0.0, 0.0, -1.0], fwd])
    T[:3, 3] = pos
    return T


def _open3d_hits(V: np.ndarray, Tr: np.ndarray, model: CameraModel, T: np.ndarray) -> tuple[np.ndarray, ...]:
    sc = open3d().t.geometry.RaycastingScene()
    sc.add_triangles(tensor(V.astype(np.float32)), tensor(Tr.astype(np.uint32)))
    r = sc.cast_rays(tensor(world_rays(camera_rays(model), T).reshape(-1, 6)), nthreads=0)
    return tuple(r[k].numpy() for k in ("t_hit", "primitive_ids", "primitive_uvs", "primitive_normals"))


def _agree(V: np.ndarray, Tr: np.ndarray, model: CameraModel, T: np.ndarray) -> tuple[int, int]:
    """Assert raster == open3d but at coplanar ties; returns (pixels hit, tie pixels)."""
    t0, p0, b0, n0 = _open3d_hits(V, Tr, model, T)
    t1, p1, b1, n1 = cast_camera(raster_mesh(V, Tr), camera_rays(model), T)
    hit = np.isfinite(t0)
    np.testing.assert_array_equal(np.isfinite(t1), hit)  # nothing dropped, nothing invented
    assert (p1[~hit] == 0xFFFFFFFF).all() and (p1[hit] < len(Tr)).all()
    np.testing.assert_allclose(t1[hit], t0[hit], rtol=2e-5)
    same = p0 == p1
    tie = ~same & hit
    # a pixel may name another triangle only where both lie at the same depth (the depth check
    # above: on a shared edge or coplanar) and the ray meets it inside (barycentric in [0, 1])
    b = b1[tie]
    assert (b >= -1e-6).all() and (b.sum(axis=1) <= 1 + 1e-6).all()
    np.testing.assert_allclose(b1[same & hit], b0[same & hit], atol=2e-4)
    np.testing.assert_allclose(n1[same & hit], n0[same & hit], atol=1e-5)
    return int(hit.sum()), int(tie.sum())


def _boxes() -> tuple[np.ndarray, np.ndarray]:
    """A ground quad, buildings ahead, a car beside and behind the camera (straddling its plane)
    and a pedestrian close in front: 12 boxes, many culling chunks with the grid below."""
    centre = np.array([[12, -3, 0], [20, 4, 0], [9, 1.5, 0], [0.5, 1.2, 0], [-6, 0, 0], [3, -0.4, 0],
                       [30, -10, 0], [25, 9, 0], [15, 0, 3], [6, 3, 0], [-3, -3, 0], [40, 0, 0]], float)
    size = np.array([[4, 3, 8], [6, 5, 12], [4.5, 1.8, 1.5], [4.5, 1.8, 1.5], [3, 3, 3], [0.5, 0.5, 1.8],
                     [8, 8, 20], [5, 5, 6], [1, 1, 1], [2, 2, 2], [2, 2, 4], [3, 30, 10]], float)
    yaw = np.linspace(0.0, 1.3, len(centre))
    V, Tr, _, _ = box_mesh(centre, size, yaw)
    g = np.array([[-500.0, -500, 0], [500, -500, 0], [500, 500, 0], [-500, 500, 0]])
    # a fine grid patch on the ground: hundreds of small triangles in many chunks
    xs = np.linspace(2.0, 14.0, 25)
    X, Y = np.meshgrid(xs, np.linspace(-6.0, 6.0, 25))
    gv = np.column_stack([X.ravel(), Y.ravel(), 0.02 + 0.01 * np.sin(X.ravel() * Y.ravel())])
    i, j = np.meshgrid(np.arange(24), np.arange(24))
    a = (j * 25 + i).ravel()
    gt = np.concatenate([np.stack([a, a + 1, a + 26], -1), np.stack([a, a + 26, a + 25], -1)])
    Vs = np.concatenate([g, V, gv])
    Ts = np.concatenate([[[0, 1, 2], [0, 2, 3]], Tr + 4, gt + 4 + len(V)])
    return Vs, Ts


@pytest.mark.parametrize("model", CAMERAS, ids=["pinhole", "radtan", "equidistant"])
def test_raster_matches_open3d_on_boxes_and_a_mover(model: CameraModel) -> None:
    V, Tr = _boxes()
    for pos, yaw in (((0.0, 0.0, 1.4), 0.0), ((0.0, 0.0, 1.4), 35.0), ((2.0, 1.0, 0.6), -20.0),
                     ((0.5, 1.2, 1.0), 180.0)):  # the last inside the car: everything behind its walls
        hit, ties = _agree(V, Tr, model, _pose(pos, yaw))
        assert hit > 0.5 * model.width_px * model.height_px
        assert ties <= 0.01 * hit  # no coplanar faces here: only rays on a shared edge


def test_raster_keeps_every_triangle_of_a_closed_mesh() -> None:
    """A box around the camera, tessellated into 2 x 24 x 24 triangles per face (over 100 culling
    chunks): every ray hits (no crack at a shared edge, no dropped chunk) the triangle open3d names,
    and shuffling the triangles' order renames the hits exactly (no offset or duplicated id)."""
    n = 24
    s = np.linspace(-1.0, 1.0, n + 1)
    U, W = np.meshgrid(s, s)
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((U.size, 3))
            p[:, axis] = sign * 3.0
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = 3.0 * U.ravel(), 3.0 * W.ravel()
            faces.append(p)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()
    quad = np.concatenate([np.stack([a, a + 1, a + n + 2], -1), np.stack([a, a + n + 2, a + n + 1], -1)])
    V = np.concatenate(faces) + np.array([0.3, -0.2, 1.0])
    Tr = np.concatenate([quad + k * (n + 1) ** 2 for k in range(6)])
    model = CAMERAS[1]
    for yaw in (0.0, 60.0, 135.0):
        T = _pose((0.0, 0.0, 1.0), yaw)
        t0, p0, _, _ = _open3d_hits(V, Tr, model, T)
        t1, p1, _, _ = cast_camera(raster_mesh(V, Tr), camera_rays(model), T)
        assert np.isfinite(t1).all() and np.isfinite(t0).all()
        assert (p1 != p0).mean() < 0.02  # pixels on a shared edge may name either triangle
        ids, counts = np.unique(p0, return_counts=True)
        assert set(ids[counts >= 3].tolist()) <= set(np.unique(p1).tolist())  # none dropped
        perm = np.random.default_rng(int(yaw)).permutation(len(Tr))
        _, q1, _, _ = cast_camera(raster_mesh(V, Tr[perm]), camera_rays(model), T)
        assert (perm[q1] != p1).mean() < 0.02  # renamed exactly, but for which edge triangle wins


@pytest.fixture(scope="module")
def calib_world() -> object:
    return build_world(kind="calibration", seed=1, bumps=True)


def test_raster_matches_open3d_on_the_calibration_scene(calib_world: object) -> None:
    r = Renderer(calib_world)
    st = r.static
    for model in CAMERAS[:2]:
        for pos, yaw in (((70.0, 0.2, 2.8), 180.0), ((60.0, -5.0, 1.5), 150.0)):
            hit, ties = _agree(st.occluder_vertices, st.triangles, model, _pose(pos, yaw))
            assert hit > 0.4 * model.width_px * model.height_px
            assert ties <= 0.01 * hit  # the bumps' flat rim on the ground quad, shared edges


def test_render_raster_against_open3d_primary(calib_world: object) -> None:
    """Whole views: the same labels and depth, radiance within float rounding but at exact ties."""
    model = CAMERAS[1]
    T = _pose((70.0, 0.2, 2.8), 180.0)
    views = [Renderer(calib_world, options=RenderOptions(noise=False, primary=p)).render_pose(model, T, 10**12)
             for p in ("open3d", "raster")]
    a, b = views
    assert (a.labels != b.labels).mean() < 1e-3
    np.testing.assert_allclose(b.depth_m, a.depth_m, rtol=1e-4)
    d = np.abs(a.radiance - b.radiance).max(axis=-1)
    assert (d > 0.5).mean() < 1e-3 and np.median(d) < 1e-3
    with pytest.raises(IbiscapeError, match="primary"):
        replace(RenderOptions(), primary="gpu")


def test_first_index_search_is_numpy_searchsorted() -> None:
    """The z-buffer's pixel-range search from a linear guess equals ``np.searchsorted`` on
    non-decreasing arrays with repeats, outside values and exact hits."""
    import numba as nb

    from ibiscape_eval.sim.render.raster import _first

    first = nb.njit(lambda a, x, right: _first(a, x, right))
    rng = np.random.default_rng(0)
    for trial in range(200):
        n = int(rng.integers(1, 40))
        a = np.sort(rng.choice(np.linspace(-2, 2, 9), n)) if trial % 2 else np.sort(rng.normal(size=n))
        for x in [*rng.normal(size=10) * 2, *a, -np.inf, np.inf]:
            for right in (False, True):
                assert first(a, x, right) == np.searchsorted(a, x, side="right" if right else "left")


def test_depth_cut_leaves_every_hit_as_without_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """The z-buffer skips the rays whose nearest hit so far is nearer than a triangle's nearest
    vertex: on a town street (buildings behind buildings) the hits are bit for bit those of the
    z-buffer testing every ray (a cut 30 % too deep fails here)."""
    from ibiscape_eval.sim.render import raster

    world = build_world(kind="slam", seed=3, scene="clear", town_blocks=2)
    st = Renderer(world).static
    mesh = raster_mesh(st.occluder_vertices, st.triangles)
    model = CameraModel.from_fov(160, 120, 90.0)
    dirs = camera_rays(model)
    T = _pose((30.0, 78.45, 2.8), 0.0)
    cut = [np.array(a, copy=True) for a in cast_camera(mesh, dirs, T)]
    bounds = raster.ray_bounds(dirs)
    assert bounds[6][0]  # the camera's rays have z = 1: the cut is on
    monkeypatch.setattr(raster, "ray_bounds", lambda d: (*bounds[:6], np.array([False])))
    full = cast_camera(mesh, dirs, T)
    for a, b in zip(cut, full, strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(cut[0]).mean() > 0.5
