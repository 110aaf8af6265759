"""A depth unit misread by a factor (issue #24) is caught by physics: the RGB-D odometry's path
against the IMU's (:mod:`ibiscape_eval.vio.scale_check`), on a small generated drive (128x96,
5 s, still until ~0.9 s, then a start).  The right unit passes and measures a factor near 1;
depth 5x too far (a TUM file read as millimetres), 5x too near (millimetres read as TUM), 0.2x
and 1000x are refused with exit 2, one line naming the depth folder, the factor and the unit
that explains it, and no estimate written; a still platform cannot be checked and says so (a
warning), it is never refused."""

from __future__ import annotations

import dataclasses
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import FormatError, IbiscapeWarning
from ibiscape_eval.io.images import read_png, write_png
from ibiscape_eval.io.open_sequence import open_sequence
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.vio.depth import DepthOptions
from ibiscape_eval.vio.inputs import StereoSequence, stereo_inputs
from ibiscape_eval.vio.pipeline import run_vio
from ibiscape_eval.vio.scale_check import DepthScale, check_depth_scale, measure_depth_scale

pytestmark = pytest.mark.filterwarnings("ignore:the rotation of the yaw alignment")


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("depth_unit") / "RGBD_1_town"
    generate(with_resolution(preset("rgbd", "slam", "clear", duration_s=5.0, seed=3), 160, 120), out,
             render=True)
    return out


@pytest.fixture(scope="module")
def inputs(drive: Path) -> StereoSequence:
    return stereo_inputs(open_sequence(drive), setup="rgbd")


@pytest.fixture(scope="module")
def right(inputs: StereoSequence) -> DepthScale:
    return measure_depth_scale(inputs)


def _scaled_copy(src: Path, dst: Path, factor: float) -> Path:
    """The sequence with every 16-bit depth file's counts times ``factor`` (beyond 16 bits: no
    depth, as a TUM camera writes beyond 13 m)."""
    shutil.copytree(src, dst)
    for f in (dst / "depth" / "mm").glob("*.png"):
        d = read_png(f).astype(np.float64) * factor
        d[d > 65535] = 0
        write_png(f, np.round(d).astype(np.uint16))
    return dst


def _refused(args: list[str], out: Path) -> str:
    r = CliRunner().invoke(cli, [*args, "-o", str(out)])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and "Traceback" not in r.output, r.output
    assert not out.exists()
    return err[0]


def test_the_right_unit_measures_one(inputs: StereoSequence, right: DepthScale) -> None:
    """Known answer: the generator's depth is metric, so the factor is 1 within its sigma (2
    sigma: the sigma counts the odometry's drift as one error, a conservative bound)."""
    res = right
    assert res.status == "ok", res
    assert abs(math.log(res.factor)) <= 2 * res.sigma_log  # measured 1.22, sigma of ln 0.22
    assert 0.0 < res.start_s < 2.0 and res.motion_m > 3.0  # the window after the standstill
    assert check_depth_scale(inputs).status == "ok"


@pytest.mark.parametrize("scale", [5.0, 0.2, 1000.0, 0.001])
def test_a_depth_scaled_by_a_factor_measures_that_factor(inputs: StereoSequence, right: DepthScale,
                                                         scale: float) -> None:
    """The factor follows the depth's scale (the odometry is scale-free up to the depth), and
    every misread unit is ``wrong``."""
    res = measure_depth_scale(inputs, scale=scale)
    assert res.status == "wrong", res
    assert res.factor / right.factor == pytest.approx(scale, rel=0.1)


def test_tum_depth_read_as_millimetres_exits_2(drive: Path, tmp_path: Path) -> None:
    bad = _scaled_copy(drive, tmp_path / "tum_as_mm", 5.0)
    err = _refused(["vio", str(bad)], tmp_path / "est.txt")
    assert str(bad / "depth" / "mm") in err and "too far" in err and "--depth-unit tum" in err
    factor = float(err.split("is ")[1].split("x the IMU")[0])
    assert 3.5 < factor < 7.0  # measured 4.4 (the 16-bit files end at 13 m: fewer corners)


def test_the_remedy_runs(drive: Path, tmp_path: Path) -> None:
    """The same files read as TUM (--depth-unit tum, the remedy named) pass the check and run."""
    bad = _scaled_copy(drive, tmp_path / "tum_files", 5.0)
    out = tmp_path / "est.txt"
    r = CliRunner().invoke(cli, ["vio", str(bad), "-o", str(out), "--depth-unit", "tum",
                                 "--max-frames", "90"])
    assert r.exit_code == 0, r.output
    assert out.exists() and "depth unit" not in r.output


def test_millimetres_read_as_tum_exits_2(drive: Path, tmp_path: Path) -> None:
    err = _refused(["vio", str(drive), "--depth-unit", "tum"], tmp_path / "est.txt")
    assert "too near" in err and "not tum" in err and "--depth-unit mm" in err


def test_a_factor_no_unit_explains_exits_2(drive: Path, tmp_path: Path) -> None:
    bad = _scaled_copy(drive, tmp_path / "fifth", 0.2)
    err = _refused(["vio", str(bad)], tmp_path / "est.txt")
    assert "too near" in err and "no depth unit explains it" in err and "--depth-unit" not in err


def test_depth_1000x_too_far_is_refused_before_any_estimate(inputs: StereoSequence) -> None:
    """Beyond 16 bits, so through the library: a reader in micrometres (or metres read as km)."""
    reader = inputs.frame_reader
    assert reader is not None

    def far(i: int) -> tuple[np.ndarray, np.ndarray]:
        left, depth = reader(i)
        return left, depth * np.float32(1000.0)

    with pytest.warns(IbiscapeWarning, match="outside the depth front end"), \
            pytest.raises(FormatError, match=r"too far .*no depth unit explains it") as e:
        run_vio(dataclasses.replace(inputs, frame_reader=far))
    assert "depth/mm" in str(e.value)


def _still(inputs: StereoSequence, scale: float) -> StereoSequence:
    """The drive's first 0.5 s (standing) repeated: frames and IMU samples of a still platform."""
    reader = inputs.frame_reader
    assert reader is not None
    t = inputs.frame_stamps_ns
    n_still = int(np.searchsorted(t, t[0] + int(0.5e9)))
    ti = inputs.imu_stamps_ns
    k = int(np.searchsorted(ti, ti[0] + int(0.5e9)))
    rep = np.arange(len(ti)) % k

    def still(i: int) -> tuple[np.ndarray, np.ndarray]:
        left, depth = reader(i % n_still)
        return left, depth * np.float32(scale)

    return dataclasses.replace(inputs, frame_reader=still, gyro_rad_s=inputs.gyro_rad_s[rep],
                               accel_m_s2=inputs.accel_m_s2[rep], groundtruth=None)


@pytest.mark.parametrize("scale", [1.0, 5.0])
def test_a_still_platform_is_not_checked_nor_refused(inputs: StereoSequence, scale: float) -> None:
    """Without motion the scale is unobservable: a warning saying so, never a refusal, and the
    estimate runs (a 5x depth included: nothing can tell it without motion)."""
    seq = _still(inputs, scale)
    assert measure_depth_scale(seq).status == "not measured"
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        res = run_vio(seq)
    msgs = [str(w.message) for w in got if issubclass(w.category, IbiscapeWarning)]
    assert any("could not be checked against the IMU" in m and "depth/mm" in m for m in msgs), msgs
    assert len(res.trajectory) == seq.n_frames


def test_depth_unit_option_is_checked(drive: Path, tmp_path: Path) -> None:
    """--depth-unit on a run that is not RGB-D, and an unknown unit in Python, are refused."""
    err = _refused(["vio", str(drive), "--setup", "svi", "--depth-unit", "tum"], tmp_path / "e.txt")
    assert "--depth-unit is for RGB + depth" in err
    with pytest.raises(Exception, match="depth unit 'cm'"):
        DepthOptions(depth_unit="cm")
