"""AprilGrids in frames reconstructed from events: ``detect_corners(..., event_frame=True)`` reads the
tags that ``cv2.aruco`` rejects, and the frames calibrate; RGB detection does not change."""

from __future__ import annotations

import functools

import numpy as np
from _calib_render import dvs_events, random_poses, render_float, sim_target
from _calib_scenes import stereo_scene

from ibiscape_eval.calib.calibrate import Observations, calibrate
from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.calib.events import EventFrameSource
from ibiscape_eval.calib.pipeline import CameraFrames, detect_frames
from ibiscape_eval.core.camera import CameraModel

# a DAVIS-like sensor: the board 110-150 px wide, tags of 15-20 px (1.5-2 px per code cell)
CAM = CameraModel(240, 180, 165.0, 165.8, 121.3, 88.6, "radtan", (-0.12, 0.03, 0.0008, -0.0005))


@functools.lru_cache(maxsize=1)
def _fading_in_views(n_views: int = 12, renders: int = 9):
    """Per view, the board fading in (contrast 0 -> 1 over 8 renders 5 ms apart) while it slides
    1 cm per render: the events (ESIM model, threshold 0.2) integrated by the log-intensity
    reconstruction give the board with the quantisation and smear of an event camera.  Returns
    the frames at the end of the fade and the true corners there."""
    rng = np.random.default_rng(5)
    target = sim_target("aprilgrid")
    obj = target.object_points()
    frames, truths = [], []
    for T0 in random_poses("aprilgrid", n_views, rng, distance_m=(3.5, 5.0), spread=0.08, tilt_max_deg=30):
        d = rng.normal(size=2)
        d /= np.linalg.norm(d)
        poses = []
        for k in range(renders):
            T = T0.copy()
            T[:2, 3] += 0.01 * (k - renders + 1) * d
            poses.append(T)
        imgs = [render_float(CAM, T, "aprilgrid", ss=2, contrast=min(1.0, k / (renders - 2)))
                + rng.normal(0, 0.3, (CAM.height_px, CAM.width_px)) for k, T in enumerate(poses)]
        t = 1_000_000_000 + 5_000_000 * np.arange(renders)
        windows = np.stack([t[:-1], t[1:]], axis=1)
        events = [dvs_events(imgs[k - 1], imgs[k], int(t[k - 1]), int(t[k])) for k in range(1, renders)]
        src = EventFrameSource(lambda i, ev=events: ev[i], windows, (CAM.width_px, CAM.height_px),
                               "log-intensity", tau_s=1.0, contrast=(0.2, 0.2))
        frames.append(src(renders - 2))
        truths.append(CAM.project(obj @ poses[-1][:3, :3].T + poses[-1][:3, 3]))
    return target, frames, truths


def test_event_frames_of_an_aprilgrid_are_read_and_accurate():
    target, frames, truths = _fading_in_views()
    plain = [detect_corners(f, target) for f in frames]
    dets = [detect_corners(f, target, event_frame=True) for f in frames]
    n_plain = sum(0 if d is None else len(d) for d in plain)
    # aruco's own decoding rejects nearly every tag of these frames
    assert n_plain < 0.1 * len(frames) * target.n_corners
    assert all(d is not None and len(d) >= 0.9 * target.n_corners for d in dets)
    e = np.concatenate([np.linalg.norm(d.corners_px - uv[d.ids], axis=1)
                        for d, uv in zip(dets, truths, strict=True) if d is not None])
    # a misread tag or a corner on the wrong junction would be a tag or a corner square away (> 3 px)
    assert e.max() < 1.5
    assert np.sqrt(np.mean(e**2)) < 0.45


def test_event_frames_of_an_aprilgrid_calibrate():
    target, frames, _ = _fading_in_views()
    size = (CAM.width_px, CAM.height_px)
    summary = detect_frames(target, [CameraFrames("davisL", len(frames), lambda i: frames[i], str,
                                                  reconstruction="log-intensity")],
                            [[i] for i in range(len(frames))], workers=1)
    assert summary.frames_detected == (len(frames),)
    res = calibrate(target, [Observations("davisL", size, list(summary.observations[0].detections))])
    err = np.array(res.cameras[0].camera.intrinsics) - np.array(CAM.intrinsics)
    assert np.all(np.abs(err) < 1.0), err
    assert res.rms_px < 0.45


def test_no_tags_read_in_frames_without_a_board():
    target = sim_target("aprilgrid")
    rng = np.random.default_rng(2)
    blank = np.full((CAM.height_px, CAM.width_px), 128, np.uint8)
    # blobs and edges of every size: the kind of clutter a reconstruction shows around the board
    import cv2

    clutter = cv2.GaussianBlur(rng.normal(128, 60, (CAM.height_px, CAM.width_px)), (0, 0), 1.5)
    clutter = np.clip(clutter, 0, 255).astype(np.uint8)
    blocks = np.kron(rng.integers(0, 2, (18, 24)), np.ones((10, 10))).astype(np.uint8) * 200 + 20
    for img in (blank, clutter, blocks):
        assert detect_corners(img, target, event_frame=True) is None


def test_event_option_leaves_rgb_detection_unchanged():
    """The pipeline asks for event-frame detection only for cameras with a reconstruction, and on
    checkerboards the option changes nothing."""
    for kind in ("aprilgrid", "checkerboard"):
        target, _, _, _, (imgs, _), obs = stereo_scene(kind)
        summary = detect_frames(target, [CameraFrames("cam0", len(imgs), lambda i, im=imgs: im[i], str)],
                                [[i] for i in range(len(imgs))], workers=1)
        for a, b in zip(summary.observations[0].detections, obs[0].detections, strict=True):
            assert (a is None) == (b is None)
            if a is not None and b is not None:
                np.testing.assert_array_equal(a.ids, b.ids)
                np.testing.assert_array_equal(a.corners_px, b.corners_px)
        if kind == "checkerboard":
            for im, b in zip(imgs, obs[0].detections, strict=True):
                a = detect_corners(im, target, event_frame=True)
                assert (a is None) == (b is None)
                if a is not None and b is not None:
                    np.testing.assert_array_equal(a.corners_px, b.corners_px)
