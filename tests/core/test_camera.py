"""CameraModel: projection equals OpenCV's, inverse distortion, pixel-centre convention, Kalibr entries."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

RADTAN = CameraModel(640, 480, 410.0, 405.0, 318.2, 241.7, "radtan", (-0.28, 0.07, 1e-3, -5e-4))
EQUI = CameraModel(640, 480, 300.0, 301.0, 320.5, 239.0, "equidistant", (0.02, -0.01, 0.003, -0.001))


def _points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-1.0, 1.0, n), rng.uniform(-0.8, 0.8, n), rng.uniform(1.5, 5, n)])


def test_radtan_projection_equals_opencv() -> None:
    p = _points(500)
    ours = RADTAN.project(p)
    ref, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), RADTAN.K, RADTAN.opencv_dist)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-9)


def test_equidistant_projection_equals_opencv_fisheye() -> None:
    p = _points(500, 1)
    ours = EQUI.project(p)
    ref, _ = cv2.fisheye.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), EQUI.K,
                                       EQUI.opencv_dist)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-9)


@pytest.mark.parametrize("cam", [RADTAN, EQUI], ids=["radtan", "equi"])
def test_pixel_rays_project_back_to_pixel_centres(cam: CameraModel) -> None:
    rays = cam.pixel_rays()
    assert rays.shape == (cam.height_px, cam.width_px, 3)
    uv = cam.project(rays.reshape(-1, 3)).reshape(cam.height_px, cam.width_px, 2)
    np.testing.assert_allclose(uv, cam.pixel_grid(), atol=1e-6)
    # OpenCV's convention: the top-left pixel's centre is (0, 0)
    assert tuple(cam.pixel_grid()[0, 0]) == (0.0, 0.0)


def test_supersampled_grid_averages_to_centres() -> None:
    cam = CameraModel.from_fov(8, 6, 90.0)
    g = cam.pixel_grid(4).reshape(6, 4, 8, 4, 2).mean(axis=(1, 3))
    np.testing.assert_allclose(g, cam.pixel_grid(), atol=1e-12)


def test_folding_distortion_is_refused_with_pixels() -> None:
    cam = CameraModel.from_fov(200, 200, 120.0, distortion="radtan", coeffs=(-0.9, 0.0, 0.0, 0.0))
    with pytest.raises(IbiscapeError, match=r"does not invert over the 200x200 image: \d+ of"):
        cam.pixel_rays()


def test_scaled_keeps_field_of_view() -> None:
    cam = CameraModel.from_fov(1024, 1024, 90.0)
    assert cam.fx == pytest.approx(512.0) and cam.cx == 511.5
    small = cam.scaled(256, 256)
    assert small.fx == pytest.approx(128.0) and small.cx == pytest.approx(127.5)
    # the image edge stays at the same angle
    edge = np.array([[-0.5, 127.5]])
    assert small.unproject(edge)[0][0, 0] == pytest.approx(cam.unproject(np.array([[-0.5, 511.5]]))[0][0, 0])


@settings(max_examples=60)
@given(fx=st.floats(50, 2000), cx=st.floats(-10, 700), k=st.lists(st.floats(-0.05, 0.05), min_size=4, max_size=4),
       model=st.sampled_from(["radtan", "equidistant", "none"]))
def test_kalibr_entry_round_trip(fx: float, cx: float, k: list[float], model: str) -> None:
    cam = CameraModel(640, 480, fx, fx * 1.01, cx, 200.0, model, tuple(k))  # type: ignore[arg-type]
    back = CameraModel.from_kalibr(cam.to_kalibr())
    assert back.intrinsics == cam.intrinsics and back.coeffs == cam.coeffs
    assert back.distortion == ("radtan" if model == "none" else model)


@pytest.mark.parametrize("entry, msg", [
    ({"intrinsics": [1, 2, 3, 4]}, "resolution"),
    ({"intrinsics": [1, 2, 3], "resolution": [4, 4]}, "intrinsics must be"),
    ({"intrinsics": [1, 1, 3, 4], "resolution": [4, 4], "distortion_model": "fov"}, "radtan or equidistant"),
    ({"camera_model": "omni", "intrinsics": [1, 1, 3, 4], "resolution": [4, 4]}, "only 'pinhole'"),
    ({"intrinsics": [-1, 1, 3, 4], "resolution": [4, 4]}, "positive finite"),
])
def test_bad_kalibr_entries(entry: dict, msg: str) -> None:
    with pytest.raises(IbiscapeError, match=msg):
        CameraModel.from_kalibr(entry)


def _newton_radtan_numpy(model: CameraModel, xy_d: np.ndarray, iterations: int = 20):
    """The reference: the full Newton iterations in numpy (the form the kernel replaced), with
    the re-distortion and fold-over checks."""
    k1, k2, p1, p2 = model.coeffs
    xd, yd = xy_d[..., 0], xy_d[..., 1]
    x, y = xd.copy(), yd.copy()
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            r2 = x * x + y * y
            s = 1.0 + r2 * (k1 + k2 * r2)
            ds = k1 + 2.0 * k2 * r2
            fx = x * s + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
            fy = y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
            a = s + 2.0 * x * x * ds + 2.0 * p1 * y + 6.0 * p2 * x
            b = 2.0 * x * y * ds + 2.0 * p1 * x + 2.0 * p2 * y
            d = s + 2.0 * y * y * ds + 6.0 * p1 * y + 2.0 * p2 * x
            det = a * d - b * b
            x, y = x - (d * fx - b * fy) / det, y - (a * fy - b * fx) / det
        r2 = x * x + y * y
        s = 1.0 + r2 * (k1 + k2 * r2)
        ds = k1 + 2.0 * k2 * r2
        det = (s + 2.0 * x * x * ds + 2.0 * p1 * y + 6.0 * p2 * x) * (s + 2.0 * y * y * ds + 6.0 * p1 * y
                                                                      + 2.0 * p2 * x) \
            - (2.0 * x * y * ds + 2.0 * p1 * x + 2.0 * p2 * y) ** 2
        xy = np.stack([x, y], axis=-1)
        err = model.distort(xy) - xy_d
        err_px = np.hypot(err[..., 0] * model.fx, err[..., 1] * model.fy)
    return xy, np.isfinite(err_px) & (err_px < 1e-6) & (det > 0)


@pytest.mark.parametrize("coeffs", [(-0.28, 0.07, 1e-4, -2e-4), (-0.09, 0.0, 0.002, -0.001), (0.4, 0.1, 0.0, 0.0)])
def test_radtan_undistort_equals_the_full_newton_bit_for_bit(coeffs) -> None:
    """The numba inversion stops once an iterate repeats; it must equal all 20 numpy Newton steps
    bit for bit, with the same success flags (the second model folds over in the corners)."""
    model = CameraModel(97, 61, 40.5, 41.25, 48.3, 29.9, "radtan", coeffs)
    uv = model.pixel_grid(3).reshape(-1, 2)
    xy_d = np.stack([(uv[:, 0] - model.cx) / model.fx, (uv[:, 1] - model.cy) / model.fy], axis=-1)
    xy, ok = model.undistort(xy_d)
    ref, ref_ok = _newton_radtan_numpy(model, xy_d)
    np.testing.assert_array_equal(ok, ref_ok)
    np.testing.assert_array_equal(xy[ok], ref[ok])
    if coeffs[0] == -0.09:
        assert 0 < (~ok).sum() < ok.size
    assert model.undistort(xy_d.reshape(3, -1, 2))[0].shape == (3, xy_d.shape[0] // 3, 2)
