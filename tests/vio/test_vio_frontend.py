"""Front end on rendered image pairs with known motion: a random texture on a fronto-parallel
plane, imaged through the rig's pinhole cameras by an exact homography (cv2.warpPerspective)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.vio.frontend import StereoFrontEnd
from ibiscape_eval.vio.params import VioParams
from ibiscape_eval.vio.rig import StereoRig

W = 320
DEPTH_M = 8.0
TEX_PX_PER_M = 60.0


def _texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = rng.uniform(0, 255, (1200, 1600)).astype(np.float32)
    t = cv2.GaussianBlur(t, (0, 0), 2.0)
    t = (t - t.min()) / (t.max() - t.min()) * 255
    return t.astype(np.uint8)


def _rig() -> StereoRig:
    cam = CameraModel.from_fov(W, W, 90.0)
    T_b_l = np.eye(4)
    T_b_l[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]  # forward-looking, OpenCV frame
    T_b_r = T_b_l.copy()
    T_b_l[:3, 3] = [0.0, 0.2, 0.0]
    T_b_r[:3, 3] = [0.0, -0.2, 0.0]
    return StereoRig(cam, cam, T_b_l, T_b_r)


def _render(tex: np.ndarray, cam: CameraModel, c_m: np.ndarray) -> np.ndarray:
    """Image of the plane z = DEPTH_M (camera frame at the origin) seen from optical centre c_m
    (no rotation): pixel -> plane point -> texture pixel is affine."""
    z = DEPTH_M - c_m[2]
    s = TEX_PX_PER_M
    ox, oy = tex.shape[1] / 2, tex.shape[0] / 2
    # texture (u_t, v_t) = s * (c_x + (u - cx) z / f) + ox, likewise for v
    A = np.array([[s * z / cam.fx, 0, s * (c_m[0] - cam.cx * z / cam.fx) + ox],
                  [0, s * z / cam.fy, s * (c_m[1] - cam.cy * z / cam.fy) + oy],
                  [0, 0, 1]])
    return cv2.warpPerspective(tex, A, (cam.width_px, cam.height_px),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)


def _project(cam: CameraModel, c_m: np.ndarray, X: np.ndarray) -> np.ndarray:
    return cam.project(X - c_m)


def test_stereo_disparity_and_tracking_match_the_known_geometry():
    rig = _rig()
    tex = _texture()
    cam = rig.left
    fe = StereoFrontEnd(rig, VioParams(max_features=150))
    b = 0.4
    motion = [np.array([0.0, 0.0, 0.0]), np.array([0.05, -0.02, 0.3]), np.array([0.1, -0.03, 0.6])]
    prev = None
    for k, c in enumerate(motion):
        left = _render(tex, cam, c)
        right = _render(tex, cam, c + np.array([b, 0.0, 0.0]))
        obs = fe.process(1_000_000_000 + k * 50_000_000, left, right)
        assert len(obs) > 80
        # every stereo match has the disparity of the plane: f b / z
        d_true = cam.fx * b / (DEPTH_M - c[2])
        assert np.median(np.abs((obs.uL - obs.uR) - d_true)) < 0.1
        assert np.abs((obs.uL - obs.uR) - d_true).max() < 0.5
        if prev is not None:
            # the same ids moved as the plane's points do
            common, i0, i1 = np.intersect1d(prev[0].ids, obs.ids, return_indices=True)
            assert len(common) > 50
            z0 = DEPTH_M - prev[1][2]
            X = np.column_stack([(prev[0].uL[i0] - cam.cx) * z0 / cam.fx + prev[1][0],
                                 (prev[0].v[i0] - cam.cy) * z0 / cam.fy + prev[1][1],
                                 np.full(len(i0), DEPTH_M)])
            uv = _project(cam, c, X)
            err = np.hypot(uv[:, 0] - obs.uL[i1], uv[:, 1] - obs.v[i1])
            assert np.median(err) < 0.15
            assert np.percentile(err, 95) < 0.5
        prev = (obs, c)


def test_gyro_prior_lets_klt_follow_a_fast_rotation():
    """A 6 deg yaw between frames moves the image by ~30 px: the rotation prior recovers it."""
    rig = _rig()
    tex = _texture(1)
    cam = rig.left
    left0 = _render(tex, cam, np.zeros(3))
    # rotate the camera about its y axis (body z): warp by the homography K R K^-1
    yaw = np.radians(6.0)
    R_c1c0 = np.array([[np.cos(yaw), 0, -np.sin(yaw)], [0, 1, 0], [np.sin(yaw), 0, np.cos(yaw)]])
    H = cam.K @ R_c1c0 @ np.linalg.inv(cam.K)
    left1 = cv2.warpPerspective(left0, H, (W, W), flags=cv2.INTER_LINEAR)
    R_bc = rig.T_body_left[:3, :3]
    R_b0b1 = (R_bc @ R_c1c0 @ R_bc.T).T
    fe = StereoFrontEnd(rig, VioParams(max_features=120, klt_levels=1))
    fe.process(0, left0, left0)
    ids0, pts0 = fe.ids.copy(), fe.pts.copy()
    fe.process(50_000_000, left1, left1, R_b0b1)
    common, i0, i1 = np.intersect1d(ids0, fe.ids, return_indices=True)
    assert len(common) > 40
    ph = np.column_stack([pts0[i0], np.ones(len(i0))]) @ H.T
    err = np.linalg.norm(ph[:, :2] / ph[:, 2:] - fe.pts[i1], axis=1)
    assert np.median(err) < 0.3


@pytest.mark.parametrize("value", [0, 128])
def test_textureless_images_give_no_observations(value):
    rig = _rig()
    fe = StereoFrontEnd(rig, VioParams())
    blank = np.full((W, W), value, dtype=np.uint8)
    for k in range(3):
        obs = fe.process(k * 50_000_000, blank, blank)
        assert len(obs) == 0


def test_track_then_match_is_process_and_skipped_frames_keep_the_tracks():
    """``track`` gives every corner held (``uR`` NaN), ``match`` adds the stereo matches: the
    matched subset is what ``process`` gives; frames tracked without the right image keep ids and
    the next ``match`` still finds the plane's disparity (started at the older one)."""
    rig = _rig()
    tex = _texture(2)
    cam = rig.left
    b = 0.4
    centres = [np.array([0.0, 0.0, 0.02 * k]) for k in range(5)]
    pairs = [(_render(tex, cam, c), _render(tex, cam, c + np.array([b, 0.0, 0.0])))
             for c in centres]
    full, lazy = StereoFrontEnd(rig, VioParams()), StereoFrontEnd(rig, VioParams())
    t0 = full.process(0, *pairs[0])
    tracks = lazy.track(0, pairs[0][0])
    assert np.isnan(tracks.uR).all() and len(tracks) >= len(t0) > 80
    m = lazy.match(pairs[0][1])
    assert np.array_equal(m.ids, tracks.ids) and np.array_equal(m.uL, tracks.uL)
    got = m.matched()
    assert np.array_equal(got.ids, t0.ids) and np.allclose(got.uR, t0.uR)
    for k in (1, 2, 3):        # left only
        tr = lazy.track(k * 50_000_000, pairs[k][0])
        assert np.isnan(tr.uR).all()
    lazy.track(4 * 50_000_000, pairs[4][0])
    last = lazy.match(pairs[4][1])
    ok = np.isfinite(last.uR)
    assert ok.sum() > 80 and len(np.intersect1d(last.ids, t0.ids)) > 60
    d_true = cam.fx * b / (DEPTH_M - centres[4][2])
    assert np.median(np.abs(last.uL[ok] - last.uR[ok] - d_true)) < 0.1


def test_match_before_track_is_refused():
    with pytest.raises(RuntimeError, match="before track"):
        StereoFrontEnd(_rig(), VioParams()).match(np.zeros((W, W), np.uint8))


def test_redetect_ratio_skips_detection_until_the_tracks_thin_out(monkeypatch):
    """With ``redetect_ratio`` < 1 the first frame (no corner) is detected on, and frames that
    lost no track are not; below ``redetect_ratio`` of the corners held it detects again."""
    rig = _rig()
    tex = _texture(3)
    left = _render(tex, rig.left, np.zeros(3))
    left[:, W // 2:] = 128                              # half without texture: never fills up
    calls = []
    fe = StereoFrontEnd(rig, VioParams(max_features=400, redetect_ratio=0.9))
    real = fe._detect
    monkeypatch.setattr(fe, "_detect", lambda img, pts: calls.append(len(pts)) or real(img, pts))
    fe.track(0, left)
    assert calls == [0] and 100 < fe.n_tracked < 280   # < 70 % of 400: half the cells empty
    fe.track(50_000_000, left)                          # nothing lost: no detection
    assert calls == [0]
    n = fe.n_tracked
    fe.pts, fe.ids, fe.disp = fe.pts[: int(0.85 * n)], fe.ids[: int(0.85 * n)], fe.disp[: int(0.85 * n)]
    fe.track(100_000_000, left)                         # 85 % of those held: detect again
    assert len(calls) == 2 and fe.n_tracked > int(0.85 * n)
    always = StereoFrontEnd(rig, VioParams(max_features=400))
    always.track(0, left)
    kept = always.n_tracked
    assert kept < 280
    calls2 = []
    real2 = always._detect
    monkeypatch.setattr(always, "_detect", lambda img, pts: calls2.append(len(pts)) or real2(img, pts))
    always.track(50_000_000, left)                      # redetect_ratio 1: below 70 % -> detect
    assert calls2 == [kept]


def test_forward_backward_check_rejects_tracks_into_another_scene():
    """The forward-backward check keeps the true tracks of a moved scene and rejects the tracks
    into an unrelated one, which the forward track alone mostly calls converged.  (A backward
    track over fewer pyramid levels, started at the forward start, let 35 % of them through.)"""
    rig = _rig()
    cam = rig.left
    tex = _texture(4)
    fe = StereoFrontEnd(rig, VioParams(max_features=150))
    img0 = _render(tex, cam, np.zeros(3))
    fe.track(0, img0)
    p0 = fe.pts
    _, ok = fe._lk(img0, _render(tex, cam, np.array([0.1, 0.05, 0.3])), p0, p0)
    assert ok.mean() > 0.9
    loose = StereoFrontEnd(rig, VioParams(max_features=150, fb_max_px=1e9))
    other = _render(_texture(5), cam, np.zeros(3))
    _, ok_fwd = loose._lk(img0, other, p0, p0)
    _, ok = fe._lk(img0, other, p0, p0)
    assert ok_fwd.mean() > 0.5 and ok.mean() < 0.1, (ok_fwd.mean(), ok.mean())


def test_fewer_pyramid_levels_after_small_residuals_track_the_same():
    """``klt_min_levels``: after frames whose tracks landed within a few pixels of the gyro's
    prediction the temporal KLT runs on fewer levels; the tracks are the full pyramid's (within
    0.01 px, the same ids).  A large residual brings the full pyramid back."""
    rig = _rig()
    tex = _texture(2)
    fes = [StereoFrontEnd(rig, VioParams(max_features=150, klt_min_levels=m)) for m in (3, 2)]
    used: list[int] = []
    for k in range(5):
        c = np.array([0.01 * k, 0.0, 0.1 * k])     # slow forward drive: residuals ~1 px
        left = _render(tex, rig.left, c)
        right = _render(tex, rig.left, c + np.array([0.4, 0.0, 0.0]))
        used.append(fes[1]._temporal_levels())
        for fe in fes:
            fe.process(1_000_000_000 + k * 50_000_000, left, right)
        np.testing.assert_array_equal(fes[0].ids, fes[1].ids)
        np.testing.assert_allclose(fes[0].pts, fes[1].pts, atol=0.01)
    assert used[0] == 3 and used[-1] == 2    # the first frames have no residual yet
    assert fes[0]._temporal_levels() == 3
    fes[1]._resid_px = 9.0                   # beyond a quarter of 2 levels' reach (32 px / 4)
    assert fes[1]._temporal_levels() == 3
