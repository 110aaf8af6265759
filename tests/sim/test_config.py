"""Simulator configuration: presets, mounting conventions, YAML round trip, bad input."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.config import (
    KINDS,
    SETUPS,
    WEATHERS,
    dump_config,
    load_config,
    preset,
)
from ibiscape_eval.sim.rig import T_body_camera


def test_every_preset_is_valid_with_paper_rates() -> None:
    for setup, kind, weather in itertools.product(SETUPS, KINDS, WEATHERS):
        cfg = preset(setup, kind, weather)
        assert cfg.gt_rate_hz == 200 and all(s.rate_hz == 200 for s in cfg.imus)
        assert all(c.rate_hz == 20 for c in cfg.cameras)
        assert cfg.gnss.rate_hz == (10.0 if cfg.kind == "calibration" else 1.0)
    assert preset("imu", "slam").kind == "calibration" and not preset("imu").cameras
    assert [c.name for c in preset("svi").cameras] == ["rgbL", "rgbR"]
    assert [s.name for s in preset("esvi").imus] == ["imu0", "imu1", "imu2"]
    acc = preset("svi", scenario="accident")
    assert acc.duration_s == pytest.approx(6.13) and acc.kind == "slam"


def test_camera_intrinsics_and_mounting() -> None:
    cfg = preset("full")
    cams = {c.name: c for c in cfg.cameras}
    assert cams["rgbL"].intrinsics == [512.0, 512.0, 511.5, 511.5]
    np.testing.assert_allclose(cams["rgbL"].position_m, [0.0, 0.2, 2.8])  # left, 2.8 m above
    np.testing.assert_allclose(cams["rgbR"].position_m, [0.0, -0.2, 2.8])
    assert np.linalg.norm(np.subtract(cams["davisL"].position_m, cams["davisR"].position_m)) == pytest.approx(0.2)
    imus = {s.name: s for s in cfg.imus}
    assert imus["imu1"].position_m == cams["davisL"].position_m
    assert imus["imu2"].position_m == cams["davisR"].position_m
    assert cfg.gnss.position_m == (0.2, 0.0, 2.8)
    T = T_body_camera(cams["rgbL"])
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0])  # optical axis = body forward
    np.testing.assert_allclose(T[:3, 0], [0, -1, 0])  # image x = right = body -y
    np.testing.assert_allclose(T[:3, 1], [0, 0, -1])  # image y = down
    # a point 10 m ahead projects on the principal point
    p_cam = np.linalg.inv(T) @ np.array([10.0, 0.2, 2.8, 1.0])
    f, _, cu, cv = cams["rgbL"].intrinsics
    assert (f * p_cam[0] / p_cam[2] + cu, f * p_cam[1] / p_cam[2] + cv) == (511.5, 511.5)


def test_dump_and_load_round_trip(tmp_path: Path) -> None:
    for setup, weather in (("full", "dynamic"), ("imu", "clear"), ("svi", "moderate")):
        cfg = preset(setup, "calibration", weather, seed=7, duration_s=12.5, ideal=True)
        p = tmp_path / f"{setup}.yaml"
        p.write_text(dump_config(cfg))
        assert load_config(p) == cfg


@settings(max_examples=25, deadline=None)
@given(seed=hs.integers(0, 2**31), dur=hs.floats(0.1, 1e5), bl=hs.floats(0.06, 2.0),
       model=hs.sampled_from(["continuous", "carla"]), rate=hs.floats(1.0, 2000.0))
def test_round_trip_property(seed: int, dur: float, bl: float, model: str, rate: float) -> None:
    import tempfile

    base = preset("svi", "slam", "clear")
    doc = (f"setup: svi\nseed: {seed}\nduration_s: {dur!r}\nimu_noise: {{model: {model}}}\n"
           f"cameras:\n  rgbR: {{position_m: [0.0, {0.2 - bl!r}, 2.8], rate_hz: {rate!r}}}\n")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "c.yaml"
        p.write_text(doc)
        cfg = load_config(p)
        assert cfg.seed == seed and cfg.duration_s == dur and cfg.imu_noise.model == model
        assert cfg.cameras[1].position_m[1] == 0.2 - bl and cfg.cameras[1].rate_hz == rate
        assert cfg.cameras[0] == base.cameras[0]
        p.write_text(dump_config(cfg))
        assert load_config(p) == cfg


def test_yaml_adds_and_removes_sensors(tmp_path: Path) -> None:
    p = tmp_path / "c.yaml"
    p.write_text("setup: svi\ncameras:\n  rgbR: null\n  wide: {kind: rgb, fov_deg: 120, position_m: [1.0, 0, 2.0]}\n")
    cfg = load_config(p)
    assert [c.name for c in cfg.cameras] == ["rgbL", "wide"]
    assert cfg.cameras[1].focal_px == pytest.approx(512 / np.tan(np.radians(60)))
    p.write_text(dump_config(cfg))
    assert load_config(p) == cfg


@pytest.mark.parametrize(("text", "needles"), [
    ("setup: svi\nduraton_s: 3\n", ["unknown key 'duraton_s'", "duration_s", "seed"]),
    ("imu_noise: {gyro_noise: 1}\n", ["unknown key 'imu_noise.gyro_noise'", "model"]),
    ("cameras: {rgbL: {fov: 3}}\n", ["cameras.rgbL.fov", "fov_deg"]),
    ("setup: stereo\n", ["unknown setup 'stereo'", "svi"]),
    ("weather: stormy\n", ["unknown weather 'stormy'"]),
    ("seed: abc\n", ["seed must be an integer"]),
    ("[1, 2]\n", ["mapping"]),
    ("a: [1,\n", ["not valid YAML"]),
    ("gt_rate_hz: -200\n", ["gt_rate_hz must be a positive number"]),
    ("duration_s: 0\n", ["duration_s must be a positive number"]),
    ("imus: {imu0: {rate_hz: 0}}\n", ["imus.imu0.rate_hz"]),
    ("cameras: {rgbL: {rate_hz: -20}}\n", ["cameras.rgbL.rate_hz"]),
    ("gnss: {rate_hz: 0}\n", ["gnss.rate_hz"]),
    ("cameras: {rgbR: {position_m: [0.0, 0.18, 2.8]}}\n",
     ["cameras.rgbL", "cameras.rgbR", "inside each other", "mount"]),
    ("setup: esvi\nimus: {imu1: {mount: ''}}\n", ["imus.imu1", "cameras.davisL"]),
    ("gnss: {position_m: [0.0, 0.2, 2.8]}\n", ["cameras.rgbL", "gnss"]),
])
def test_bad_config_names_the_key(tmp_path: Path, text: str, needles: list[str]) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(IbiscapeError) as ei:
        load_config(p)
    msg = str(ei.value)
    for n in needles:
        assert n in msg, msg


def test_concentric_rgbd_pair_is_allowed_and_bad_presets_refused() -> None:
    cfg = preset("rgbd")
    assert cfg.cameras[0].position_m == cfg.cameras[1].position_m
    with pytest.raises(IbiscapeError, match="unknown kind"):
        preset("svi", "mapping")
    with pytest.raises(IbiscapeError, match="duration_s"):
        preset("svi", duration_s=-1.0)
    with pytest.raises(IbiscapeError, match="accident needs kind slam"):
        preset("svi", "calibration", scenario="accident")


@pytest.mark.parametrize(("text", "line"), [
    ("setup: svi\nduraton_s: 3\n", 2),
    ("seed: 1\ncameras:\n  rgbL:\n    fov: 3\n", 4),
    ("seed: 1\n\nimus: {imu0: {rate_hz: x}}\n", 3),
])
def test_bad_config_names_the_line(tmp_path: Path, text: str, line: int) -> None:
    from ibiscape_eval.core.errors import FormatError

    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(FormatError) as ei:
        load_config(p)
    assert ei.value.line == line and str(p) in str(ei.value)
