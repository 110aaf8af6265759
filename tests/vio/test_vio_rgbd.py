"""RGB-D (+ IMU): depth as the stereo measurement, on a small generated sequence
(128x96, 6 s) against the generator's truth; the depth noise model against the encoding's own
quantisation; registration of a depth camera that sits elsewhere; bad depth files."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.images import (
    decode_depth_carla_log,
    encode_depth_carla_log,
    read_png,
    write_png,
)
from ibiscape_eval.io.open_sequence import open_sequence
from ibiscape_eval.metrics import ate
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.vio.depth import DepthReader, depth_sigma_m
from ibiscape_eval.vio.inputs import resolve_setup, stereo_inputs
from ibiscape_eval.vio.pipeline import run_vio


@pytest.fixture(scope="module")
def rgbd_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rgbd") / "RGBD_1_town"
    generate(with_resolution(preset("rgbd", "slam", "clear", duration_s=6.0, seed=3), 128, 96), out,
             render=True)
    return out


@pytest.mark.filterwarnings("ignore:the rotation of the yaw alignment")
def test_rgbd_runs_within_the_truth(rgbd_folder: Path) -> None:
    seq = open_sequence(rgbd_folder)
    assert resolve_setup(seq) == "rgbd"
    res = run_vio(seq)
    s = res.stats
    assert s.setup == "rgbd" and s.frames == 121 and s.failures == ()
    assert s.usable_frames == s.frames
    gt = seq.ground_truth()
    assert gt is not None
    a = ate(res.trajectory, gt, align="yaw", max_diff_s=0.02)
    length = float(a.ref.path_length_m()[-1])
    assert length > 10.0
    assert a.translation_m.rmse < 0.015 * length  # measured 0.87 % at 128 px


def test_the_measurement_is_the_depth(rgbd_folder: Path) -> None:
    """Triangulating the front end's virtual stereo measurement gives back the depth file's value."""
    from ibiscape_eval.io.images import read_depth_mm
    from ibiscape_eval.vio.params import VioParams
    from ibiscape_eval.vio.pipeline import make_frontend

    s = stereo_inputs(open_sequence(rgbd_folder), setup="rgbd")
    assert s.depth_unit == "mm"
    fe = make_frontend(s, VioParams())
    i = 60
    left, depth = s.read_pair(i)
    obs = fe.process(int(s.frame_stamps_ns[i]), left, depth)
    assert len(obs) > 20
    z = s.rig.rectified().triangulate(obs.uL, obs.uR, obs.v)[:, 2]
    truth = read_depth_mm(rgbd_folder / "depth" / "mm" / f"{int(s.frame_stamps_ns[i])}.png")
    zt = truth[np.round(obs.v).astype(int), np.round(obs.uL).astype(int)]
    np.testing.assert_allclose(z, zt, rtol=1e-6)


def test_carla_log_noise_model_matches_its_quantisation() -> None:
    """The 8-bit log encoding's error is what depth_sigma_m says (uniform over one code step)."""
    rng = np.random.default_rng(0)
    d = np.exp(rng.uniform(math.log(4.0), math.log(60.0), 200_000))
    back = decode_depth_carla_log(encode_depth_carla_log(d[None, :]))[0].astype(np.float64)
    rel = (back - d) / d
    sigma = depth_sigma_m(d, "carla-log") / d
    assert float(np.std(rel)) == pytest.approx(float(sigma.mean()), rel=0.03)
    assert depth_sigma_m(np.array([1.0, 30.0]), "mm") == pytest.approx(1e-3 / math.sqrt(12))


def test_registration_moves_depth_into_the_rgb_camera(tmp_path: Path) -> None:
    """A depth camera 0.1 m to the right of the RGB camera sees the plane z = 5 + 0.2 x (RGB
    frame); registered, the depth at each RGB pixel is the plane's depth along that pixel's ray."""
    cam = CameraModel(160, 120, 80.0, 80.0, 79.5, 59.5)
    T_body_rgb = np.eye(4)
    T_body_depth = np.eye(4)
    T_body_depth[0, 3] = 0.1
    u, _ = np.meshgrid(np.arange(160.0), np.arange(120.0))
    xd = (u - 79.5) / 80.0
    zd = (5.0 + 0.2 * 0.1) / (1.0 - 0.2 * xd)  # the plane in the depth camera's frame
    f = tmp_path / "d.png"
    write_png(f, np.round(zd * 1000).astype(np.uint16))
    reg = DepthReader([f], "mm", cam, T_body_depth, cam, T_body_rgb)
    assert not reg.identity
    out = reg(0)
    truth = 5.0 / (1.0 - 0.2 * xd)
    ok = np.isfinite(out)
    assert ok.mean() > 0.9
    # nearest-pixel splatting: within the depth change over one pixel (0.2 * 5/80 m) plus 1 mm
    assert np.abs(out[ok] - truth[ok]).max() < 0.2 * 5.0 / 80.0 * 1.5 + 1e-3


def _bad_depth(src: Path, dst: Path, image: np.ndarray) -> Path:
    shutil.copytree(src, dst)
    f = sorted((dst / "depth" / "mm").glob("*.png"))[3]
    write_png(f, image)
    return f


@pytest.mark.parametrize("what", ["size", "metres", "8-bit"])
def test_bad_depth_file_exits_2_naming_it(rgbd_folder: Path, tmp_path: Path, what: str) -> None:
    good = read_png(sorted((rgbd_folder / "depth" / "mm").glob("*.png"))[3])
    image = {"size": good[:-8], "metres": np.round(good / 1000.0).astype(np.uint16),
             "8-bit": (good // 256).astype(np.uint8)}[what]
    bad = tmp_path / "bad"
    f = _bad_depth(rgbd_folder, bad, image)
    with pytest.raises(FormatError, match=f.name):
        run_vio(open_sequence(bad), max_frames=20)
    out = tmp_path / "est.txt"
    r = CliRunner().invoke(cli, ["vio", str(bad), "-o", str(out)])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and f.name in err[0] and "Traceback" not in r.output
    assert not out.exists()
