"""Corner detection of the stereo front end (``StereoFrontEnd._detect``): only in the grid cells
that lack corners, away from the tracked ones and from each other, the cells' strongest
Shi-Tomasi corners as OpenCV's ``goodFeaturesToTrack`` finds them."""

from __future__ import annotations

import cv2
import numpy as np

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.vio.frontend import StereoFrontEnd
from ibiscape_eval.vio.params import VioParams
from ibiscape_eval.vio.rig import StereoRig

W = 256


def _front_end(**kw: float) -> StereoFrontEnd:
    cam = CameraModel.from_fov(W, W, 90.0)
    T_b_l = np.eye(4)
    T_b_r = np.eye(4)
    T_b_r[0, 3] = 0.3
    return StereoFrontEnd(StereoRig(cam, cam, T_b_l, T_b_r), VioParams(**kw))


def _image(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = cv2.GaussianBlur(rng.uniform(0, 255, (W, W)).astype(np.float32), (0, 0), 2.0)
    return cv2.normalize(t, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)


def _cell(q: np.ndarray, g: int) -> np.ndarray:
    return np.minimum((q[:, 1] * g / W).astype(int), g - 1) * g + np.minimum((q[:, 0] * g / W).astype(int), g - 1)


def test_new_corners_fill_the_cells_that_lack_them_only():
    fe = _front_end(max_features=64, grid=4)          # 4 corners per cell of 64 px
    img = _image()
    first = fe._detect(img, np.zeros((0, 2), np.float32))
    assert (np.bincount(_cell(first, 4), minlength=16) == 4).all()
    # keep the corners of the top row of cells and one of the next: the rest is refilled
    c_first = _cell(first, 4)
    held = np.concatenate([first[c_first < 4], first[c_first == 5][:1]])
    new = fe._detect(img, held)
    counts = np.bincount(_cell(new, 4), minlength=16)
    assert (counts[:4] == 0).all() and counts[5] == 3 and (np.delete(counts[4:], 1) == 4).all()
    both = np.concatenate([held, new])
    d = np.linalg.norm(both[:, None] - both[None], axis=2) + np.eye(len(both)) * 1e9
    assert d.min() > fe.min_dist                       # away from the held corners and each other
    border = max(fe.win[0] // 2, 4)
    assert ((new >= border) & (new < W - border)).all()


def test_each_cell_gets_its_strongest_corner_by_opencv():
    """The first corner goodFeaturesToTrack finds in a cell (its strongest, same block size) is
    among the new corners, unless a stronger new corner of the next cell lies within the minimum
    distance (new corners keep it from each other too)."""
    fe = _front_end(max_features=64, grid=4)
    img = _image(1)
    new = fe._detect(img, np.zeros((0, 2), np.float32))
    border = max(fe.win[0] // 2, 4)
    eig = cv2.cornerMinEigenVal(img, 5)
    r = round(fe.min_dist)
    suppressed = 0
    for cy in range(4):
        for cx in range(4):
            mask = np.zeros((W, W), np.uint8)
            mask[cy * 64:(cy + 1) * 64, cx * 64:(cx + 1) * 64] = 255
            mask[:border], mask[-border:], mask[:, :border], mask[:, -border:] = 0, 0, 0, 0
            best = cv2.goodFeaturesToTrack(img, 1, 0.01, fe.min_dist, mask=mask, blockSize=5)
            b = best.reshape(2)
            if np.min(np.linalg.norm(new - b, axis=1)) < 1e-6:
                continue
            near = new[np.abs(new - b).max(axis=1) <= r].astype(int)
            assert len(near) and (eig[near[:, 1], near[:, 0]] > eig[int(b[1]), int(b[0])]).all()
            assert _cell(near, 4)[0] != cy * 4 + cx
            suppressed += 1
    assert suppressed <= 3


def test_a_full_budget_or_a_blank_image_detects_nothing():
    fe = _front_end(max_features=16, grid=2)
    img = _image(2)
    full = fe._detect(img, np.zeros((0, 2), np.float32))
    assert len(full) == 16
    assert len(fe._detect(img, full)) == 0
    assert len(fe._detect(np.full((W, W), 128, np.uint8), np.zeros((0, 2), np.float32))) == 0
