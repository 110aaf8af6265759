"""The renderer against known answers: analytic plane depth, OpenCV corners and calibration on
rendered checkerboards, labels, movers, determinism, and the renderer's input errors."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render.labels import TAG
from ibiscape_eval.sim.render.renderer import GRAY_WEIGHTS, RenderCamera
from ibiscape_eval.sim.render.shading import WeatherState
from ibiscape_eval.sim.world import build_world

DAY = WeatherState(cloudiness=10.0, sun_altitude_angle=50.0, sun_azimuth_angle=200.0)


@pytest.fixture(scope="module")
def calib() -> tuple[Renderer, object]:
    world = build_world(kind="calibration", seed=1, bumps=False)
    return Renderer(world, options=RenderOptions(noise=False)), world.target_named("checkerboard")


def look_at_board(target, dist_m: float, yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """T_world_cam of a camera ``dist_m`` in front of the board centre, turned by yaw/pitch/roll."""
    n = target.observer_normal_world
    z = -n
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R0 = np.stack([x, np.cross(z, x), z], 1)
    R = R0 @ Rotation.from_euler("yxz", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = target.centre_world_m - R[:, 2] * dist_m
    return T


def true_corners(model: CameraModel, target, T_world_cam: np.ndarray) -> np.ndarray:
    T = np.linalg.inv(T_world_cam)
    return model.project(target.corners_world_m() @ T[:3, :3].T + T[:3, 3])


def detect(gray_u8: np.ndarray) -> np.ndarray | None:
    ok, c = cv2.findChessboardCorners(gray_u8, (7, 7))
    if not ok:
        return None
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    return cv2.cornerSubPix(gray_u8, c.reshape(-1, 1, 2), (7, 7), (-1, -1), crit).reshape(-1, 2)


def test_plane_depth_equals_analytic_with_opencv_pixel_centres() -> None:
    r = Renderer(build_world(kind="still", seed=0), options=RenderOptions(noise=False))
    model = CameraModel(96, 80, 70.0, 72.0, 47.3, 39.1, "radtan", (-0.2, 0.05, 0.002, -0.001))
    pitch = math.radians(35.0)  # looking forward and down at the flat ground from 1.7 m
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]) @ np.array(
        [[1, 0, 0], [0, math.cos(pitch), math.sin(pitch)], [0, -math.sin(pitch), math.cos(pitch)]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, (0.0, 0.0, 1.7)
    depth = r.render_pose(model, T, weather=DAY).depth_m
    # analytic: the ray through pixel centre (u, v) (integers, OpenCV) hits z = 0 at z-depth t
    rays, ok = model.unproject(model.pixel_grid())
    dz = rays @ R.T[:, 2]
    with np.errstate(divide="ignore"):
        expect = np.where(dz < 0, -1.7 / dz, np.inf)
    ground = np.isfinite(expect) & (expect < 500)
    assert ok.all() and ground.sum() > 0.5 * depth.size
    np.testing.assert_allclose(depth[ground], expect[ground], rtol=2e-6)
    assert np.isinf(depth[~np.isfinite(expect)]).all()
    # open3d's create_rays_pinhole convention (u + 0.5) would be off by half a pixel: detectably
    shifted, _ = model.unproject(model.pixel_grid() + 0.5)
    dzs = shifted @ R.T[:, 2]
    with np.errstate(divide="ignore"):
        wrong = np.where(dzs < 0, -1.7 / dzs, np.inf)
    assert np.max(np.abs(wrong[ground] - expect[ground]) / expect[ground]) > 1e-3


def test_checkerboard_corners_within_005px(calib) -> None:
    r, board = calib
    model = CameraModel(320, 320, 160.0, 160.0, 159.5, 159.5)
    worst = []
    for view in [(4.0, 0.0, 0.0, 20.0), (4.5, 20.0, -10.0, -15.0), (4.0, -15.0, 10.0, 33.0)]:
        T = look_at_board(board, *view)
        img = r.render_pose(model, T, weather=DAY).rgb
        found = detect(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
        assert found is not None, f"OpenCV found no checkerboard in view {view}"
        truth = true_corners(model, board, T)
        err = np.linalg.norm(found[:, None] - truth[None], axis=2).min(axis=1)
        assert len(found) == 49
        worst.append(err.max())
    assert max(worst) < 0.05, worst


def test_calibrate_camera_recovers_intrinsics(calib) -> None:
    r, board = calib
    noisy = Renderer.__new__(Renderer)  # same scene, sensor noise on (a real camera's images)
    noisy.__dict__.update(r.__dict__)
    noisy.options = RenderOptions(noise=True)
    model = CameraModel(320, 240, 190.0, 188.0, 163.2, 117.6, "radtan", (-0.15, 0.04, 0.001, -0.0008))
    obj, img_pts = [], []
    views = [(d, yaw, pitch, roll) for d, yaw, pitch, roll in
             [(4.5, 0, 0, 10), (5, 25, -8, -5), (5, -25, 10, 15), (4.8, 15, 15, -20), (5.2, -18, -14, 25),
              (5.5, 30, 5, 0), (5.5, -30, -5, -30), (4.6, 5, -18, 40), (5.0, -8, 18, -35), (6.0, 0, 0, 5)]]
    for k, view in enumerate(views):
        T = look_at_board(board, *view)
        img = noisy.render_pose(model, T, noise_key=k, weather=DAY).rgb
        found = detect(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
        if found is None:
            continue
        truth = true_corners(model, board, T)
        order = np.linalg.norm(truth[:, None] - found[None], axis=2).argmin(axis=1)
        obj.append(board.corners_target_m.astype(np.float32))
        img_pts.append(found[order].astype(np.float32))
    assert len(obj) >= 8
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img_pts, (320, 240), None, None,
                                             flags=cv2.CALIB_FIX_K3)
    est = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    assert rms < 0.2
    np.testing.assert_allclose(est, [190.0, 188.0, 163.2, 117.6], atol=0.3)
    np.testing.assert_allclose(dist.ravel()[:2], [-0.15, 0.04], atol=0.02)


def test_labels_of_known_surfaces() -> None:
    r = Renderer(build_world(kind="slam", seed=1), options=RenderOptions(noise=False))
    model = CameraModel.from_fov(160, 120, 90.0)
    T = np.eye(4)
    T[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]  # along +x, level
    T[:3, 3] = (20.0, -1.75, 2.8)  # eastbound lane of the road y = 0
    v = r.render_pose(model, T, weather=DAY)
    assert v.labels[5, 80] == TAG["Sky"] and np.isinf(v.depth_m[5, 80])
    assert v.labels[115, 80] in (TAG["Road"], TAG["RoadLine"])
    assert (v.labels == TAG["Building"]).any() and (v.labels == TAG["RoadLine"]).any()
    assert np.isfinite(v.depth_m[v.labels != TAG["Sky"]]).all()


def test_movers_without_rebuilding_the_static_scene(town_dynamic: Renderer) -> None:
    r = town_dynamic
    world = r.world
    static = r.static
    t0 = 1_000_000_000_000
    pos, yaw = world.agents.poses_at(np.array([t0, t0 + 4_000_000_000]))
    a = int(np.argmax(world.agents.kind_id == 0))  # a car
    target = pos[a, 0] + np.array([0.0, 0.0, 0.7])
    eye = target + np.array([8.0 * math.cos(yaw[a, 0] + 1.2), 8.0 * math.sin(yaw[a, 0] + 1.2), 1.5])
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
    T[:3, 3] = eye
    model = CameraModel.from_fov(64, 64, 60.0)
    first = r.render_pose(model, T, t0, weather=DAY)
    later = r.render_pose(model, T, t0 + 4_000_000_000, weather=DAY)
    assert first.labels[32, 32] == TAG["Vehicles"]
    assert later.labels[32, 32] != TAG["Vehicles"]  # it drove on (>= 7 m/s for 4 s)
    assert r.static is static


def test_gray_is_the_noise_free_rgb_in_luma_weights(calib) -> None:
    _, board = calib
    model = CameraModel.from_fov(64, 48, 80.0)
    r2 = Renderer(build_world(kind="calibration", seed=1, bumps=False),
                  cameras=(RenderCamera("davisL", "dvs", model, np.eye(4)),), motion=_Still(board),
                  options=RenderOptions(noise=True))
    g = r2.gray("davisL", 5)
    v = r2.render("davisL", 5)
    assert g.dtype == np.float32 and g.shape == (48, 64)
    np.testing.assert_allclose(g, v.radiance @ GRAY_WEIGHTS, rtol=1e-5, atol=1e-4)
    assert not np.array_equal(v.rgb, np.clip(np.rint(v.radiance), 0, 255).astype(np.uint8))  # noise


class _Still:
    """A motion standing 6 m in front of the board (body frame = camera frame)."""

    def __init__(self, board) -> None:
        self.T = look_at_board(board, 6.0, 0.0, 0.0, 0.0)

    def sample(self, stamps_ns):
        from ibiscape_eval.core.rotations import quat_from_matrix

        class S:
            pass

        s = S()
        s.pos_m = np.repeat(self.T[None, :3, 3], len(stamps_ns), 0)
        s.quat_xyzw = np.repeat(quat_from_matrix(self.T[:3, :3])[None], len(stamps_ns), 0)
        return s


def test_same_seed_identical_images_other_noise_key_differs(calib) -> None:
    r, board = calib
    noisy = Renderer.__new__(Renderer)
    noisy.__dict__.update(r.__dict__)
    noisy.options = RenderOptions(noise=True)
    model = CameraModel.from_fov(64, 64, 90.0)
    T = look_at_board(board, 6.0, 5.0, 0.0, 0.0)
    a = noisy.render_pose(model, T, 7, weather=DAY)
    b = noisy.render_pose(model, T, 7, weather=DAY)
    c = noisy.render_pose(model, T, 7, noise_key=1, weather=DAY)
    assert a.rgb.tobytes() == b.rgb.tobytes() and a.labels.tobytes() == b.labels.tobytes()
    assert a.rgb.tobytes() != c.rgb.tobytes()


def test_distortion_that_does_not_invert_names_pixels() -> None:
    bad = CameraModel.from_fov(64, 64, 120.0, distortion="radtan", coeffs=(-0.9, 0.0, 0.0, 0.0))
    cam = RenderCamera("rgbL", "rgb", bad, np.eye(4))
    with pytest.raises(IbiscapeError, match=r"does not invert.*\(u=.*v=.*smaller coefficients"):
        Renderer(build_world(kind="still", seed=0), cameras=(cam,))


@pytest.mark.parametrize("bad", [{"target_supersample": 0}, {"target_supersample": 9},
                                 {"psf_sigma_px": -1.0}])
def test_bad_render_options(bad: dict) -> None:
    with pytest.raises(IbiscapeError, match="render:"):
        RenderOptions(**bad)


def test_a_render_warns_nothing(calib) -> None:
    """The renderer no longer filters warnings around each render (#23: the filter list is
    process-global); no kernel runs in parallel, so nothing warns."""
    import warnings

    r, target = calib
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r.render_pose(CameraModel.from_fov(48, 48, 90.0), look_at_board(target, 6.0, 0.0, 0.0, 0.0),
                      weather=DAY)
