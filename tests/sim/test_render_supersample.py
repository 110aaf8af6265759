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
    flat_counts: list[int] = []
    real = kernels.board_footprints_flat

    def counted(*a: Any) -> Any:
        out = real(*a)
        flat_counts.append(int(out.sum()))
        return out

    real_seen = Renderer._lit_side_seen
    seen_by_codes: list[int] = []

    def seen(self: Renderer, *a: Any) -> Any:
        out = real_seen(self, *a)
        seen_by_codes.append(int(out.sum()))
        return out

    monkeypatch.setattr(kernels, "board_footprints_flat", counted)
    monkeypatch.setattr(Renderer, "_lit_side_seen", seen)
    fast = r.render_pose(model, T, weather=DAY).radiance
    assert flat_counts and flat_counts[0] > 100  # the skip is taken
    assert seen_by_codes[0] > 100  # pixels whose coarse rays were only cast, not shaded

    def never(*a: Any) -> Any:
        out = a[-1]
        out[:] = False
        return out

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

    monkeypatch.setattr(kernels, "board_footprints_flat", never)
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


def test_footprint_crossing_a_printed_edge_is_not_flat(calib: Any) -> None:
    """Rays straddling a square's edge are not flat; the same rays moved inside a square are."""
    from ibiscape_eval.sim.render.textures import board_footprint_tables, board_tables

    r, target = calib
    k = r.static.targets.index(target)
    poses, diffs = board_footprint_tables(r.static.targets)
    tex, x0, y0, sign, ppm = board_tables(r.static.targets)[k]
    # a texel row in the middle of a row of squares and a column where the print changes along it
    col = tex[:, tex.shape[1] // 2]
    edges = np.flatnonzero(col[1:] != col[:-1]) + 1
    r_mid = (edges[2] + edges[3]) // 2
    c_edge = int(np.flatnonzero(tex[r_mid, 1:] != tex[r_mid, :-1])[2]) + 1
    y = y0 + sign * (r_mid + 0.5) / ppm
    P = poses[k]

    def rays_at(xs: np.ndarray) -> np.ndarray:
        pts = np.stack([xs, np.full_like(xs, y), np.zeros_like(xs)], -1) @ P[:3, :3].T + P[:3, 3]
        origin = P[:3, 3] + 3.0 * P[:3, 2]
        d = pts - origin
        return np.concatenate([np.broadcast_to(origin, d.shape), d], -1).astype(np.float32)

    x_edge = x0 + c_edge / ppm
    straddle = rays_at(x_edge + np.linspace(-2.0, 2.0, 4) / ppm)
    inside = rays_at(x_edge + np.linspace(3.0, 6.0, 4) / ppm)
    out = np.empty(2, np.bool_)
    kernels.board_footprints_flat(np.concatenate([straddle, inside]), 4, np.array([True, True]),
                                  np.array([k, k], np.intp), poses, board_tables(r.static.targets), diffs, out)
    assert out.tolist() == [False, True]
