"""The front end's corner detector and gyro rotation against the reference implementations they
replace for speed: ``cv2.goodFeaturesToTrack`` (corner for corner) and scipy's rotation vector."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.so3 import exp_so3
from ibiscape_eval.vio.frontend import _min_eigen, good_features


def _image(h: int, w: int, seed: int, blur: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), blur)
    t = (t - t.min()) / (t.max() - t.min()) * 255
    img = t.astype(np.uint8)
    img[h // 3: h // 2, :] = 90            # a flat band (no corner) and a few bright squares
    for x, y in rng.uniform(20, min(h, w) - 20, (6, 2)).astype(int):
        img[y:y + 7, x:x + 7] = 250
    return img


def _mask(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = np.full((h, w), 255, dtype=np.uint8)
    for x, y in rng.uniform(0, min(h, w), (60, 2)).astype(int):
        cv2.circle(m, (int(x), int(y)), 12, 0, -1)
    m[:8], m[-8:], m[:, :8], m[:, -8:] = 0, 0, 0, 0
    return m


@pytest.mark.parametrize(("h", "w", "blur"), [(96, 128, 1.0), (300, 512, 1.5), (260, 1024, 0.8)])
@pytest.mark.parametrize("max_corners", [1, 40, 400, 5000])
def test_good_features_are_opencvs_corner_for_corner(h: int, w: int, blur: float,
                                                      max_corners: int) -> None:
    """Same corners in the same order as ``cv2.goodFeaturesToTrack`` (with a mask, images taller
    than one strip of the eigenvalue computation, a corner cap that the spacing reaches before the
    candidates run out and one it does not)."""
    img = _image(h, w, seed=h + w, blur=blur)
    mask = _mask(h, w, seed=w)
    for min_dist in (3.0, 12.0, 12.6):
        ref = cv2.goodFeaturesToTrack(img, max_corners, 0.01, min_dist, mask=mask, blockSize=5)
        got = good_features(img, max_corners, 0.01, min_dist, mask, 5)
        assert got.dtype == np.float32
        np.testing.assert_array_equal(got, ref.reshape(-1, 2))


def test_min_eigen_in_strips_is_the_whole_image_value() -> None:
    img = _image(700, 512, seed=3, blur=1.2)
    ref = cv2.cornerMinEigenVal(img, 5)
    np.testing.assert_allclose(_min_eigen(img, 5), ref, rtol=0, atol=1e-7 * float(ref.max()))


def test_good_features_of_a_flat_image_or_a_closed_mask_are_none() -> None:
    flat = np.full((64, 80), 128, dtype=np.uint8)
    open_mask = np.full(flat.shape, 255, dtype=np.uint8)
    assert good_features(flat, 50, 0.01, 5.0, open_mask).shape == (0, 2)
    img = _image(64, 80, seed=1, blur=1.0)
    assert good_features(img, 50, 0.01, 5.0, np.zeros_like(open_mask)).shape == (0, 2)
    assert len(good_features(img, 50, 0.01, 5.0, open_mask)) > 0


@pytest.mark.parametrize("scale", [0.0, 1e-9, 1e-5, 1e-4, 1e-2, 1.0, 3.0])
def test_exp_so3_is_scipys(scale: float) -> None:
    rng = np.random.default_rng(7)
    for _ in range(50):
        rv = rng.normal(size=3) * scale
        np.testing.assert_allclose(exp_so3(rv), Rotation.from_rotvec(rv).as_matrix(),
                                   rtol=0, atol=2e-15)


@pytest.mark.parametrize("r", [3, 12, 13])
def test_disc_stamps_are_cv2_circles_also_at_the_border(r: int) -> None:
    """The detection mask's discs (one numba call) are the pixels ``cv2.circle(..., -1)`` fills,
    clipped at the image border like it."""
    from ibiscape_eval.vio._corner_kernels import clear_discs
    from ibiscape_eval.vio.frontend import disc_offsets

    rng = np.random.default_rng(r)
    c = np.vstack([rng.integers(-5, 90, (40, 2)), [[0, 0], [79, 63], [-r, 10], [85, 70]]])
    ref = np.full((64, 80), 255, dtype=np.uint8)
    for x, y in c:
        cv2.circle(ref, (int(x), int(y)), r, 0, -1)
    got = np.full((64, 80), 255, dtype=np.uint8)
    clear_discs(got, c[:, 0].astype(np.int64), c[:, 1].astype(np.int64), *disc_offsets(r))
    assert (ref == 0).sum() > 0
    np.testing.assert_array_equal(got, ref)
