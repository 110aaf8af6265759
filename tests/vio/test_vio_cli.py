"""``ibiscape-eval vio`` end to end on a short generated sequence with images (a textured street
rendered along the sequence's exact ground truth), checked with the project's own ATE, and every
bad input (missing files, wrong sizes, bad numbers)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from _walls import N_FRAMES
from _walls import render_street_sequence as _render
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.io import read_trajectory
from ibiscape_eval.metrics import ate


def run(*args: object):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def _user_error(res, *words: str) -> None:
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, res.output
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in res.output


def test_vio_end_to_end_clear_weather(street, tmp_path):
    seq, calib = street
    out = tmp_path / "est.txt"
    plot = tmp_path / "top.png"
    res = run("vio", seq, "-o", out, "--calib", calib, "--json", "--plot", plot)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output[res.output.index("{"):])
    assert doc["frames"] == N_FRAMES and doc["poses"] == N_FRAMES
    assert doc["failures"] == []
    assert doc["init_method"] == "standstill"
    assert doc["keyframes"] > 10 and doc["mean_tracked"] > 50
    assert plot.stat().st_size > 1000
    est = read_trajectory(out, "tum")
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    r = ate(est, gt, align="yaw")  # straight street: SE(3) about the path line is undetermined
    length = gt.take(np.flatnonzero(gt.stamps_ns <= est.stamps_ns[-1])).path_length_m()[-1]
    assert length > 5.0
    assert r.translation_m.rmse < 0.01 * length + 0.02
    assert r.rotation_deg.rmse < 0.5


def test_textureless_images_are_a_reported_failure_not_a_crash(svi_folder, tmp_path):
    seq = tmp_path / "SVI_blank"
    calib = _render(svi_folder, seq, blank=True)
    out = tmp_path / "est.txt"
    res = run("vio", seq, "-o", out, "--calib", calib, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output[res.output.index("{"):])
    kinds = {f["kind"] for f in doc["failures"]}
    assert "tracking" in kinds and "lost" in kinds
    assert doc["mean_tracked"] == 0
    assert doc["poses"] < doc["frames"]  # nothing written beyond the IMU-only bound


def test_image_size_must_match_the_calibration(street, tmp_path):
    seq, _ = street  # sequence.yaml describes 1024 px cameras, the frames are 160 px
    out = tmp_path / "est.txt"
    _user_error(run("vio", seq, "-o", out), "160x160", "1024x1024", "--calib")
    assert not out.exists()


def test_missing_calibration(street, tmp_path):
    seq, _ = street
    bad = tmp_path / "nocal"
    shutil.copytree(seq, bad)
    text = (bad / "sequence.yaml").read_text()
    import yaml

    doc = yaml.safe_load(text)
    doc["cameras"] = {}
    (bad / "sequence.yaml").write_text(yaml.safe_dump(doc))
    out = tmp_path / "est.txt"
    _user_error(run("vio", bad, "-o", out), "no calibration", "--calib")
    assert not out.exists()


def test_imu_must_cover_the_images(street, tmp_path):
    seq, calib = street
    bad = tmp_path / "shortimu"
    shutil.copytree(seq, bad)
    imu = bad / "other_sensors" / "imu.csv"
    lines = imu.read_text().splitlines()
    imu.write_text("\n".join(lines[: len(lines) // 4]) + "\n")
    out = tmp_path / "est.txt"
    _user_error(run("vio", bad, "-o", out, "--calib", calib), "does not cover")
    assert not out.exists()


@pytest.mark.parametrize("which", ["frames", "imu"])
def test_non_monotonic_stamps(street, tmp_path, which):
    seq, calib = street
    bad = tmp_path / "mono"
    shutil.copytree(seq, bad)
    f = bad / ("rgbL/timestamps.csv" if which == "frames" else "other_sensors/imu.csv")
    lines = f.read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    f.write_text("\n".join(lines) + "\n")
    out = tmp_path / "est.txt"
    _user_error(run("vio", bad, "-o", out, "--calib", calib), f.name, ":7", "increase")
    assert not out.exists()


def test_not_a_sequence(tmp_path):
    _user_error(run("vio", tmp_path, "-o", tmp_path / "e.txt"), "in none of the sequence layouts", "EuRoC/ASL: no mav0/camN/data.csv")


def test_vio_on_a_sequence_rendered_by_the_generator(tmp_path):
    """The generator's own rendered SVI drive (clear weather, small images): the estimate follows the
    exact ground truth with the project's ATE, and no tracking failure is reported."""
    seq = tmp_path / "SVI_rendered"
    res = run("sim", "--setup", "svi", "--kind", "slam", "--weather", "clear", "--duration-s", "6",
              "--seed", "4", "--resolution", "192", "--out", seq)
    assert res.exit_code == 0, res.output
    out = tmp_path / "est.txt"
    res = run("vio", seq, "-o", out, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output[res.output.index("{"):])
    assert doc["failures"] == [], doc["failures"]
    est = read_trajectory(out, "tum")
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    r = ate(est, gt, align="yaw")
    length = gt.take(np.flatnonzero(gt.stamps_ns <= est.stamps_ns[-1])).path_length_m()[-1]
    assert length > 10.0
    assert r.translation_m.rmse < 0.02 * length, (r.translation_m.rmse, length)


@pytest.mark.parametrize(("given", "during"), [((), 1), (("--cv-threads", "3"), 3), (("--cv-threads", "0"), None)])
def test_opencv_threads_of_the_run_then_restored(street, tmp_path, monkeypatch, given, during):
    """`vio` runs OpenCV on one thread by default (cheaper by CPU time, the same estimate),
    `--cv-threads` changes it, 0 keeps OpenCV's own setting; the setting is restored after."""
    import cv2

    import ibiscape_eval.vio.pipeline as pipeline
    from ibiscape_eval.core.errors import IbiscapeError

    seen = []

    def fake_run_vio(*a, **k):
        seen.append(cv2.getNumThreads())
        raise IbiscapeError("stopped by the test")

    monkeypatch.setattr(pipeline, "run_vio", fake_run_vio)
    before = cv2.getNumThreads()
    seq, calib = street
    res = run("vio", seq, "-o", tmp_path / "est.txt", "--calib", calib, *given)
    _user_error(res, "stopped by the test")
    assert seen == [before if during is None else during]
    assert cv2.getNumThreads() == before
    assert not (tmp_path / "est.txt").exists()
