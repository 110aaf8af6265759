"""Target supersampling that skips the pixels whose footprint lies in one printed patch, the
shadow rays of supersamples whose neighbourhood is one lit board side, the shading of coarse rays
that see that side and the casts of pixels whose coarse rays all see one board side (also beside
the board's outline) (#25): the image equals the one that casts every candidate's rays with their
shadow rays, and the skips are really taken."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render import _board_kernels as board_kernels
from ibiscape_eval.sim.render import _kernels as kernels
from ibiscape_eval.sim.render.shading import WeatherState
from ibiscape_eval.sim.world import build_world

DAY = WeatherState(cloudiness=10.0, sun_altitude_angle=50.0, sun_azimuth_angle=200.0)


def look_at_board(target: Any, dist_m: float, yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """T_world_cam of a camera ``dist_m`` in front of the board centre, turned by yaw/pitch/roll."""
    from scipy.spatial.transform import Rotation

    z = -target.observer_normal_world
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], 1) @ Rotation.from_euler(
        "yxz", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, target.centre_world_m - R[:, 2] * dist_m
    return T


@pytest.fixture(scope="module")
def calib() -> tuple[Renderer, object]:
    world = build_world(kind="calibration", seed=1, bumps=False)
    return Renderer(world, options=RenderOptions(noise=False)), world.target_named("checkerboard")


@pytest.mark.parametrize(("dist", "yaw", "pitch", "roll"), [(5.0, 20.0, -10.0, 5.0), (9.0, -35.0, 8.0, -12.0)])
def test_skipped_footprints_equal_casting_every_candidate(calib: Any, monkeypatch: pytest.MonkeyPatch, dist: float,
                                                          yaw: float, pitch: float, roll: float) -> None:
    r, target = calib
    model = CameraModel.from_fov(192, 160, 80.0)
    T = look_at_board(target, dist, yaw, pitch, roll)
    states: list[np.ndarray] = []

    def counted(real: Any) -> Any:
        def run(*a: Any) -> Any:
            out = real(*a)
            states.append(out.copy())
            return out
        return run

    for name in ("uniform_board_pixels", "uniform_board_pixels_pinhole"):
        monkeypatch.setattr(board_kernels, name, counted(getattr(board_kernels, name)))
    fast = r.render_pose(model, T, weather=DAY).radiance
    counts = np.bincount(states[0], minlength=3)
    assert counts[board_kernels.FLAT] > 100  # pixels keeping their centre sample
    assert counts[board_kernels.PLANE] > 100  # pixels decided on the board's plane without a cast

    real_radiance = Renderer._radiance
    shadow_skips: list[int] = []

    def every_shadow_ray(self: Renderer, *a: Any, lit_code: Any = None, **k: Any) -> Any:
        shadow_skips.append(0 if lit_code is None else int(np.count_nonzero(lit_code)))
        return real_radiance(self, *a, **k)

    real_plane = Renderer._plane_supersamples
    plane_pixels: list[int] = []
    outline_pixels: list[int] = []
    keep_clear = [True]

    def no_plane(self: Renderer, *a: Any) -> Any:  # every candidate casts all its rays
        means, decided, clear, coarse, idx = real_plane(self, *a)
        plane_pixels.append(int(decided.sum()))
        outline_pixels.append(int((decided & ~a[3]).sum()))  # a neighbour off the board side
        return means, np.zeros_like(decided), clear & keep_clear[0], coarse, idx

    monkeypatch.setattr(Renderer, "_uniform_board_pixels", lambda self, *a: np.ones(len(a[5]), bool))
    monkeypatch.setattr(Renderer, "_radiance", every_shadow_ray)
    monkeypatch.setattr(Renderer, "_plane_supersamples", no_plane)
    monkeypatch.setattr(Renderer, "_lit_side_seen", lambda self, rays, lit_c, *a: np.zeros(len(lit_c), bool))
    ref_clear = r.render_pose(model, T, weather=DAY).radiance  # every skip but the coarse mean
    keep_clear[0] = False
    ref = r.render_pose(model, T, weather=DAY).radiance  # every candidate's s x s rays cast
    assert max(shadow_skips) > 1000  # lit supersamples without shadow rays in the fast image
    assert plane_pixels and plane_pixels[0] > 100  # pixels whose supersamples met the plane
    assert outline_pixels[0] > 20  # ... also beside the board's outline
    assert np.abs(fast - ref_clear).max() < 0.05  # 0..255 scale: float rounding of the 36-ray mean only
    # pixels beside the outline whose 3 x 3 coarse rays see no board take their mean: the ground's
    # texture there is antialiased with 9 rays instead of 36 (measured at these two poses: 3 % of
    # the image differs by more than 0.05 of 255, 1.1-1.5 % by more than 0.5, 0.2-0.35 % by more
    # than 2, at most by 9.8 and 20.5)
    diff = np.abs(ref_clear - ref).max(axis=-1)
    assert diff.max() < 30.0
    assert 0 < np.count_nonzero(diff > 0.5) < 0.02 * diff.size
    assert np.count_nonzero(diff > 2.0) < 0.005 * diff.size


def test_texel_diff_table_counts_changes() -> None:
    tex = np.zeros((6, 7), np.float32)
    tex[2:4, 3:6] = 1.0
    S = kernels.texel_diff_table(tex)
    brute = np.zeros_like(tex, dtype=bool)
    brute[:, 1:] |= tex[:, 1:] != tex[:, :-1]
    brute[1:, :] |= tex[1:, :] != tex[:-1, :]
    for r0, r1, c0, c1 in [(0, 5, 0, 6), (0, 1, 0, 6), (3, 5, 0, 2), (2, 3, 3, 5), (4, 5, 4, 6)]:
        got = S[r1 + 1, c1 + 1] - S[r0, c1 + 1] - S[r1 + 1, c0] + S[r0, c0]
        assert got == brute[r0:r1 + 1, c0:c1 + 1].sum()


def test_uniform_board_pixels_flat_plane_and_cast(calib: Any) -> None:
    """The fused kernel keeps the centre sample of a footprint inside one printed patch, gives a
    footprint straddling a printed edge board_plane_means' mean, and leaves a footprint off the
    print (or a sunward side in shadow) to the casts."""
    from ibiscape_eval.sim.render.textures import board_footprint_tables, board_tables

    r, target = calib
    k = r.static.targets.index(target)
    poses, diffs = board_footprint_tables(r.static.targets)
    tex, x0, y0, sign, ppm = board_tables(r.static.targets)[k]
    col = tex[:, tex.shape[1] // 2]
    edges = np.flatnonzero(col[1:] != col[:-1]) + 1
    r_mid = (edges[2] + edges[3]) // 2
    c_edge = int(np.flatnonzero(tex[r_mid, 1:] != tex[r_mid, :-1])[2]) + 1
    y = y0 + sign * (r_mid + 0.5) / ppm
    P = poses[k]
    origin = P[:3, 3] + 3.0 * P[:3, 2]

    def rays_at(xs: np.ndarray) -> np.ndarray:  # a 2 x 2 grid: two columns, two rows a texel apart
        xy = np.array([[x, y + dy] for dy in (0.0, 1.0 / ppm) for x in xs])
        pts = np.concatenate([xy, np.zeros((4, 1))], 1) @ P[:3, :3].T + P[:3, 3]
        d = pts - origin
        return np.concatenate([np.broadcast_to(origin, d.shape), d], -1).astype(np.float32)

    x_edge = x0 + c_edge / ppm
    rays = np.concatenate([rays_at(x_edge + np.array([-2.0, 2.0]) / ppm), rays_at(x_edge + np.array([3.0, 6.0]) / ppm),
                           rays_at(np.array([x0 + 0.2 / ppm, x0 + 3.0 / ppm]))])
    sun = np.asarray(P[:3, 2], np.float64)  # toward the camera's side of the board
    lit = 1 + 4 * k + 2 + 1
    sky = (np.float32(1.0), np.float32(0.2))
    optics = (np.float32(0), np.float32(np.inf), np.float32(0.0), np.zeros(3, np.float32), np.float32(1000.0))
    args = (poses, board_tables(r.static.targets), diffs, sun, sky, optics, np.float32(255.0))
    out = np.zeros((3, 3), np.float32)
    state = board_kernels.uniform_board_pixels(rays, 4, np.array([lit] * 3, np.uint16), *args, np.arange(3), out,
                                               np.empty(3, np.uint8))
    assert state.tolist() == [board_kernels.PLANE, board_kernels.FLAT, board_kernels.CAST]
    ref = kernels.board_plane_means(rays[:4], 4, np.array([lit], np.uint16), poses, args[1], sun, sky, optics,
                                    np.float32(255.0), np.array([0]), np.zeros((1, 3), np.float32))
    assert np.array_equal(out[0], ref[0]) and 0.0 < out[0, 0] < 255.0
    shade = board_kernels.uniform_board_pixels(rays[:4], 4, np.array([lit - 1], np.uint16), *args, np.arange(1),
                                               out, np.empty(1, np.uint8))
    assert shade.tolist() == [board_kernels.CAST]  # faces the sun but unlit: a shadow may end inside
    away = board_kernels.uniform_board_pixels(rays[:4], 4, np.array([lit - 1], np.uint16), poses, args[1], diffs, -sun,
                                              *args[4:], np.arange(1), out, np.empty(1, np.uint8))
    assert away.tolist() == [board_kernels.PLANE]  # unlit because it faces away from the sun: no shadow to find


def test_pinhole_kernel_makes_the_same_rays(calib: Any) -> None:
    """The pinhole kernel's rays made per pixel decide every pixel as the general kernel does on
    subpixel_rays + world_rays, to the bit."""
    from ibiscape_eval.sim.render.rays import subpixel_rays, world_rays
    from ibiscape_eval.sim.render.textures import board_footprint_tables, board_tables

    r, target = calib
    k = r.static.targets.index(target)
    model = CameraModel.from_fov(192, 160, 80.0)
    T = look_at_board(target, 5.0, 20.0, -10.0, 5.0)
    rows, cols = np.mgrid[40:120, 50:150]
    rows, cols = rows.ravel(), cols.ravel()
    poses, diffs = board_footprint_tables(r.static.targets)
    sky = (np.float32(1.0), np.float32(0.2))
    optics = (np.float32(0), np.float32(np.inf), np.float32(0.002), np.full(3, 0.5, np.float32), np.float32(1000.0))
    code = np.full(len(rows), 1 + 4 * k + 2 + 1, np.uint16)
    args = (code, poses, board_tables(r.static.targets), diffs, np.array([0.3, -0.2, 0.93]), sky, optics,
            np.float32(255.0), np.arange(len(rows)))
    s = 6
    out_a, out_b = np.zeros((len(rows), 3), np.float32), np.zeros((len(rows), 3), np.float32)
    a = board_kernels.uniform_board_pixels(world_rays(subpixel_rays(model, rows, cols, s), T).reshape(-1, 6), s * s,
                                           *args, out_a, np.empty(len(rows), np.uint8))
    b = board_kernels.uniform_board_pixels_pinhole(
        rows.astype(np.float64), cols.astype(np.float64), (np.arange(s) + 0.5) / s - 0.5,
        (model.fx, model.fy, model.cx, model.cy), T[:3, :3].astype(np.float32), T[:3, 3].astype(np.float32), *args,
        out_b, np.empty(len(rows), np.uint8))
    assert np.array_equal(a, b) and np.array_equal(out_a, out_b)
    assert min(np.bincount(a, minlength=3)) > 50  # flat, plane and cast pixels all compared
