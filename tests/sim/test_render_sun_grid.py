"""The shadow rays' grid across the sun against open3d's any-hit query on the same rays, the
height-field culling, the rebuild when the sun moves, and a rendered view with and without it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render.scene import box_mesh, tensor
from ibiscape_eval.sim.render.shading import WeatherState, lighting
from ibiscape_eval.sim.render.sun_grid import MAX_DRIFT_RAD, build_sun_grid

SUN = WeatherState(sun_altitude_angle=35.0, sun_azimuth_angle=200.0)


def _street_pose() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T[:3, 3] = (30.0, 78.45, 2.8)
    return T


def _rotate_z(v: np.ndarray, deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ v


def _shadow_rays(r: Renderer, sun: np.ndarray, n: int = 96) -> np.ndarray:
    """Shadow rays (origin a point seen by a town view lifted 2 cm, direction ``sun``)."""
    from ibiscape_eval.sim.render.rays import camera_rays, world_rays

    rays = world_rays(camera_rays(CameraModel.from_fov(n, n, 100.0)).reshape(-1, 3), _street_pose())
    hit = r.static.scene.cast_rays(tensor(rays), nthreads=0)
    t = hit["t_hit"].numpy()
    ok = np.isfinite(t)
    nrm = hit["primitive_normals"].numpy()[ok]
    nrm *= np.where((nrm * rays[ok, 3:]).sum(1) > 0, -1.0, 1.0)[:, None]
    p = rays[ok, :3] + t[ok, None] * rays[ok, 3:] + 0.02 * nrm
    return np.concatenate([p, np.broadcast_to(sun, p.shape)], axis=1).astype(np.float32)


@pytest.mark.parametrize("drift_deg", [0.0, 0.4])
def test_grid_answers_as_open3d_on_town_shadow_rays(town_dynamic: Renderer, drift_deg: float) -> None:
    """Exact up to float rounding: no ray of a town view differs, also for a sun 0.4 deg away from
    the one the grid was built for; about half of them are shaded (the test sees both)."""
    sun0 = np.asarray(lighting(SUN).sun_dir, np.float64)
    r = town_dynamic
    st = r.static
    grid = build_sun_grid(st.occluder_vertices, st.occluder_triangles, sun0)
    sun = _rotate_z(sun0, drift_deg)
    assert grid.covers(sun)
    rays = _shadow_rays(r, sun.astype(np.float32))
    ours = grid.occluded(rays, rays[0, 3:6])
    ref = st.scene.test_occlusions(tensor(rays), nthreads=0).numpy().astype(bool)
    assert 0.2 < ref.mean() < 0.9
    assert np.count_nonzero(ours != ref) <= 1e-4 * len(rays)


def test_box_shades_the_ground_and_terrain_culling_keeps_the_answer() -> None:
    """A 2 m box: ground points in its shadow are shaded, the others lit; a tilted height field
    under them answers the same with its sun-facing triangles culled."""
    V, T, _, _ = box_mesh(np.array([[0.0, 0.0, 0.0]]), np.array([[2.0, 2.0, 2.0]]), np.array([0.0]))
    # a height field: a gentle rise toward the sun (x), a steep step (faces away), a descent
    x = [-40.0, -30.0, -29.0, -20.0]
    z = [0.0, 1.0, 3.0, 0.0]
    hf = np.array([(x[i], y, z[i]) for i in range(4) for y in (-5.0, 5.0)])
    hft = np.array([[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3], [4, 6, 7], [4, 7, 5]]) + len(V)
    verts = np.concatenate([V, hf]).astype(np.float32)
    tris = np.concatenate([T, hft]).astype(np.uint32)
    terrain = np.r_[np.zeros(len(T), bool), np.ones(len(hft), bool)]
    sun = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)  # 45 deg above +x
    p = np.array([[-2.0, 0.0, 0.02], [-1.5, 0.5, 0.02], [2.0, 0.0, 0.02], [5.0, 0.0, 0.02],
                  [-31.0, 0.0, 0.92], [-25.0, 0.0, 1.687], [-35.0, 0.0, 1.0]], np.float32)
    want = np.array([True, True, False, False, True, False, False])
    for mask in (None, terrain):
        grid = build_sun_grid(verts, tris, sun, terrain=mask, cell_m=0.5)
        np.testing.assert_array_equal(grid.occluded(p, sun), want)
    assert not build_sun_grid(verts, tris, sun).covers(_rotate_z(sun, math.degrees(2 * MAX_DRIFT_RAD)))


def test_renderer_rebuilds_for_a_moved_sun_and_renders_as_with_open3d(town_dynamic: Renderer,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A view rendered through the grid equals the one rendered with open3d's any-hit query
    (every pixel); a sun 2 deg away gets a grid of its own."""
    r = Renderer(town_dynamic.world, options=RenderOptions(noise=False, psf_sigma_px=0.0))
    object.__setattr__(r, "static", town_dynamic.static)  # the session's scene, not a second build
    model = CameraModel.from_fov(80, 60, 90.0)
    a = r.render_pose(model, _street_pose(), 1_000_000_000_000, weather=SUN)
    first = r._sun_grid_cache
    assert first is not None
    monkeypatch.setattr(Renderer, "_shadow_grid", lambda self, sun: None)
    b = r.render_pose(model, _street_pose(), 1_000_000_000_000, weather=SUN)
    monkeypatch.undo()
    np.testing.assert_array_equal(a.rgb, b.rgb)
    moved = WeatherState(sun_altitude_angle=35.0, sun_azimuth_angle=202.0)
    r.render_pose(model, _street_pose(), 1_000_000_000_000, weather=moved)
    assert r._sun_grid_cache is not first and r._sun_grid_cache.covers(lighting(moved).sun_dir)


def test_grid_answers_do_not_depend_on_the_rays_order(town_dynamic: Renderer) -> None:
    """A ray first tests the triangle that shaded the ray before it (neighbouring pixels share
    shadows): a shortcut only, so shuffled rays (no neighbour shares anything) get the same answers
    bit for bit, and most rays of the view's own order are shaded by that triangle."""
    sun = np.asarray(lighting(SUN).sun_dir, np.float64)
    st = town_dynamic.static
    grid = build_sun_grid(st.occluder_vertices, st.occluder_triangles, sun)
    rays = _shadow_rays(town_dynamic, sun.astype(np.float32), n=128)
    ordered = grid.occluded(rays, sun)
    order = np.random.default_rng(5).permutation(len(rays))
    shuffled = np.empty_like(ordered)
    shuffled[order] = grid.occluded(np.ascontiguousarray(rays[order]), sun)
    np.testing.assert_array_equal(shuffled, ordered)
    assert 0.2 < ordered.mean() < 0.9
    # neighbours mostly share the answer: the shortcut has work in the view's order
    assert np.mean(ordered[1:] == ordered[:-1]) > 0.9
