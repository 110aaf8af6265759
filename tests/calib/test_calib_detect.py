"""Corner detection on rendered targets: sub-pixel accuracy, Kalibr ids, partial AprilGrids."""

from __future__ import annotations

import numpy as np
from _calib_render import board_pose, render, sim_target
from _calib_scenes import CAM_RADTAN, stereo_scene

from ibiscape_eval.calib.detect import detect_corners, detect_many, sharpness


def _errors(det, cam, T, target, symmetric):
    obj = target.object_points()
    perms = target.symmetries() if symmetric else [np.arange(target.n_corners)]
    errs = [np.hypot(*(det.corners_px - cam.project(obj[p[det.ids]] @ T[:3, :3].T + T[:3, 3])).T)
            for p in perms]
    return min(errs, key=lambda e: float(np.mean(e)))


def test_checkerboard_corners_are_subpixel_accurate():
    target, cams, _, poses, (_imgs, _), obs = stereo_scene("checkerboard")
    found = [(d, T) for d, T in zip(obs[0].detections, poses, strict=True) if d is not None]
    assert len(found) >= 6
    e = np.concatenate([_errors(d, cams[0], T, target, True) for d, T in found])
    assert len(e) == 49 * len(found)
    assert np.sqrt(np.mean(e**2)) < 0.1 and e.max() < 0.4


def test_aprilgrid_ids_and_corners():
    target, cams, _, poses, _, obs = stereo_scene("aprilgrid")
    e = np.concatenate([_errors(d, cams[0], T, target, False)
                        for d, T in zip(obs[0].detections, poses, strict=True) if d is not None])
    # a wrong id mapping would give errors of a tag size (tens of px)
    assert len(e) > 1000
    assert np.sqrt(np.mean(e**2)) < 0.15 and e.max() < 0.5


def test_partially_visible_aprilgrid_is_used():
    target = sim_target("aprilgrid")
    T = board_pose("aprilgrid", distance_m=4.0, tilt_deg=(10, -15), roll_deg=5, offset_m=(1.7, 0.3))
    img = render(CAM_RADTAN, T, "aprilgrid", rng=np.random.default_rng(3))
    det = detect_corners(img, target)
    assert det is not None and 16 <= len(det) < target.n_corners
    e = _errors(det, CAM_RADTAN, T, target, False)
    assert e.max() < 0.5


def test_no_target_and_parallel_detection():
    target = sim_target("checkerboard")
    blank = np.full((240, 320), 128, np.uint8)
    assert detect_corners(blank, target) is None
    _, _, _, _, (imgs, _), obs = stereo_scene("checkerboard")
    dets = detect_many(lambda i: imgs[i] if i < len(imgs) else None, len(imgs) + 1, target, workers=2)
    assert dets[-1] is None
    for a, b in zip(dets, obs[0].detections, strict=False):
        assert (a is None) == (b is None)
        if a is not None and b is not None:
            np.testing.assert_array_equal(a.corners_px, b.corners_px)


def test_sharpness_ranks_blur():
    import cv2

    _, _, _, _, (imgs, _), _ = stereo_scene("checkerboard")
    assert sharpness(imgs[0]) > 2 * sharpness(cv2.GaussianBlur(imgs[0], (0, 0), 3))


def _moving_board(kind: str, n: int = 8) -> list[tuple[np.ndarray, np.ndarray]]:
    """A board drifting across the image, 20 Hz-like steps (a few px per frame)."""
    out = []
    d0 = 9.0 if kind == "checkerboard" else 7.0  # small enough that a box around it saves time
    for k in range(n):
        T = board_pose(kind, distance_m=d0 - 0.1 * k, tilt_deg=(5 + k, -20 + 2 * k), roll_deg=3,
                       offset_m=(-1.5 + 0.12 * k, 0.1 - 0.03 * k))
        out.append((T, render(CAM_RADTAN, T, kind, rng=np.random.default_rng(k))))
    return out


def test_sequence_mode_finds_the_same_corners_as_single_images():
    for kind in ("checkerboard", "aprilgrid"):
        target = sim_target(kind)
        prev = None
        n_near = 0
        for T, img in _moving_board(kind):
            alone = detect_corners(img, target)
            near = detect_corners(img, target, near=prev, exhaustive=False)
            assert alone is not None and near is not None
            np.testing.assert_array_equal(alone.ids, near.ids)
            np.testing.assert_allclose(near.corners_px, alone.corners_px, atol=1e-3)
            assert _errors(near, CAM_RADTAN, T, target, kind == "checkerboard").max() < 0.5
            n_near += prev is not None
            prev = near
        assert n_near == 7


def test_a_stale_neighbour_falls_back_to_the_whole_image():
    for kind in ("checkerboard", "aprilgrid"):
        target = sim_target(kind)
        frames = _moving_board(kind, 2)
        far = detect_corners(frames[0][1], target)
        assert far is not None
        # the neighbour's board moved to the other side of the image: the box around it is empty
        moved = type(far)(far.ids, far.corners_px * 0.25, far.image_size)
        T = board_pose(kind, distance_m=5.0, tilt_deg=(5, 10), roll_deg=0, offset_m=(0.9, 0.3))
        img = render(CAM_RADTAN, T, kind, rng=np.random.default_rng(9))
        det = detect_corners(img, target, near=moved, exhaustive=False)
        ref = detect_corners(img, target)
        assert det is not None and ref is not None and len(det) == len(ref)
        np.testing.assert_allclose(det.corners_px, ref.corners_px, atol=1e-3)
