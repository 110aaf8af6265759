"""The RGB-D depth reader (``ibiscape_eval.vio.depth.DepthReader``) on real recordings: a TUM RGB-D
Kinect frame (16-bit, 5000 per metre) and a Redwood frame (16-bit millimetres), each decoded to
metres as Open3D, the reference reader these files ship with, decodes them; and the real files
refused where the calibration or the unit says otherwise (one line naming the file)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.vio.depth import DepthReader, depth_sigma_m

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
TUM = REAL / "tum_rgbd_depth" / "TUM_depth.png"
REDWOOD = REAL / "redwood_depth" / "00000.png"
#: TUM freiburg1's published RGB intrinsics (the reader only checks the size here)
KINECT = CameraModel(640, 480, 517.3, 516.5, 318.6, 255.3)


def _reader(f: Path, unit: str, cam: CameraModel = KINECT) -> DepthReader:
    return DepthReader([f], unit, cam, np.eye(4), cam, np.eye(4))


def _open3d_metres(f: Path, tum: bool) -> np.ndarray:
    o3d = pytest.importorskip("open3d")
    depth = o3d.io.read_image(str(f))
    color = o3d.geometry.Image(np.zeros((480, 640, 3), np.uint8))
    if tum:  # TUM's documented factor, applied by Open3D's TUM reader
        rgbd = o3d.geometry.RGBDImage.create_from_tum_format(color, depth, False)
    else:  # Open3D's default: millimetres (depth_scale 1000); no truncation
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            color, depth, depth_scale=1000.0, depth_trunc=1e9, convert_rgb_to_intensity=False)
    return np.asarray(rgbd.depth, np.float64)


@pytest.mark.parametrize(("f", "unit", "median_m"), [(TUM, "tum", 2.415), (REDWOOD, "mm", 1.861)])
def test_real_depth_decodes_as_open3d_does(f: Path, unit: str, median_m: float) -> None:
    ours = _reader(f, unit)(0).astype(np.float64)
    ref = _open3d_metres(f, tum=unit == "tum")
    valid = ref > 0
    assert 0.75 < valid.mean() < 0.95  # a real Kinect frame: holes, but mostly depth
    assert np.allclose(ours[valid], ref[valid], rtol=1e-6, atol=0)
    # 0 = no depth (NaN); Open3D's TUM reader also drops what lies beyond 4 m
    beyond = np.isfinite(ours) & ~valid
    assert np.array_equal(np.isnan(ours) | beyond, ~valid)
    assert np.all(ours[beyond] > (4.0 if unit == "tum" else np.inf))
    assert np.nanmedian(ours) == pytest.approx(median_m, abs=1e-3)
    # the metric depth of an indoor Kinect scene: 0.5 m .. 10 m
    assert np.nanmin(ours) > 0.5 and np.nanmax(ours) < 10.0


def test_tum_noise_is_the_kinects() -> None:
    """About 4 cm at 5 m, quadratic in the depth; the millimetre files' quantisation is far below."""
    s = depth_sigma_m(np.array([1.0, 5.0]), "tum")
    assert s[1] == pytest.approx(0.04, abs=0.005) and s[1] / s[0] == pytest.approx(25.0)
    assert depth_sigma_m(np.array([5.0]), "mm")[0] < s[1] / 100


@pytest.mark.parametrize(("f", "unit", "words"), [
    (TUM, "carla-log", "8-bit"),  # a 16-bit file where CARLA's 8-bit log depth is expected
    (REDWOOD, "carla-log", "8-bit"),
])
def test_real_depth_in_another_unit_is_refused_naming_it(tmp_path: Path, f: Path, unit: str,
                                                        words: str) -> None:
    copy = shutil.copy(f, tmp_path / f.name)
    with pytest.raises(FormatError, match=words) as e:
        _reader(Path(copy), unit)(0)
    assert f.name in str(e.value) and "\n" not in str(e.value)


def test_real_depth_of_another_size_than_the_calibration_is_refused(tmp_path: Path) -> None:
    small = CameraModel(346, 260, 300.0, 300.0, 173.0, 130.0)
    with pytest.raises(FormatError, match=r"640x480 px.*346x260") as e:
        _reader(REDWOOD, "mm", small)(0)
    assert REDWOOD.name in str(e.value)


def test_real_depth_scaled_to_metres_is_refused(tmp_path: Path) -> None:
    """The Redwood frame written as whole metres (1, 2, 3): a median under 0.1 m read as mm."""
    from ibiscape_eval.io.images import read_png, write_png

    f = tmp_path / "metres.png"
    write_png(f, np.round(read_png(REDWOOD) / 1000.0).astype(np.uint16))
    for unit in ("mm", "tum"):
        with pytest.raises(FormatError, match="looks like metres") as e:
            _reader(f, unit)(0)
        assert "metres.png" in str(e.value)
