"""The simulator's camera clock offset (``cameras.<name>.timeshift_cam_imu_s``, Kalibr's
``t_imu = t_cam + shift``): a frame stamped ``t_cam`` shows the scene at ``t_cam + shift``."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.io.images import read_frame_timestamps
from ibiscape_eval.io.sequence import read_sequence_yaml
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import dump_config, load_config, with_resolution


def _shifted(cfg, **shifts):  # type: ignore[no-untyped-def]
    return replace(cfg, cameras=tuple(replace(c, timeshift_cam_imu_s=shifts.get(c.name, 0.0))
                                      for c in cfg.cameras))


def test_shifted_frame_shows_the_scene_at_t_plus_shift(tmp_path: Path) -> None:
    base = with_resolution(preset("svi", "calibration", "clear", duration_s=0.4, seed=3), 40, 32)
    period_s = 1.0 / base.cameras[0].rate_hz
    generate(_shifted(base), tmp_path / "a", render=True)
    generate(_shifted(base, rgbL=period_s, rgbR=-period_s), tmp_path / "b", render=True)
    a_st, _ = read_frame_timestamps(tmp_path / "a" / "rgbL" / "timestamps.csv")
    bl_st, _ = read_frame_timestamps(tmp_path / "b" / "rgbL" / "timestamps.csv")
    br_st, _ = read_frame_timestamps(tmp_path / "b" / "rgbR" / "timestamps.csv")
    step = round(period_s * 1e9)
    # the scene instant must stay inside the sequence: +shift loses the last frame, -shift the first
    assert np.array_equal(bl_st, a_st[:-1]) and np.array_equal(br_st, a_st[1:])
    for t in bl_st.tolist():  # left frame t (shift +1 period) == unshifted frame t + period
        assert ((tmp_path / "b" / "rgbL" / "frames" / f"{t}.png").read_bytes()
                == (tmp_path / "a" / "rgbL" / "frames" / f"{t + step}.png").read_bytes())
    for t in br_st.tolist():
        assert ((tmp_path / "b" / "rgbR" / "frames" / f"{t}.png").read_bytes()
                == (tmp_path / "a" / "rgbR" / "frames" / f"{t - step}.png").read_bytes())
    same = (tmp_path / "a" / "rgbL" / "frames" / f"{a_st[1]}.png").read_bytes()
    assert (tmp_path / "b" / "rgbL" / "frames" / f"{a_st[1]}.png").read_bytes() != same
    doc = read_sequence_yaml(tmp_path / "b" / "sequence.yaml")
    assert doc["cameras"]["rgbL"]["timeshift_cam_imu"] == pytest.approx(period_s)
    assert doc["cameras"]["rgbR"]["timeshift_cam_imu"] == pytest.approx(-period_s)
    assert doc["cameras"]["rgbL"]["frames"] == len(bl_st)
    assert read_sequence_yaml(tmp_path / "a" / "sequence.yaml")["cameras"]["rgbL"]["timeshift_cam_imu"] == 0.0


def test_timeshift_default_zero_round_trips_and_is_bounded(tmp_path: Path) -> None:
    cfg = preset("svi", "calibration")
    assert all(c.timeshift_cam_imu_s == 0.0 for c in cfg.cameras)
    shifted = _shifted(cfg, rgbR=-0.0123)
    p = tmp_path / "c.yaml"
    p.write_text(dump_config(shifted))
    assert "timeshift_cam_imu_s" in p.read_text()
    assert load_config(p) == shifted
    p.write_text("kind: calibration\ncameras:\n  rgbL:\n    timeshift_cam_imu_s: 0.02\n")
    assert load_config(p).cameras[0].timeshift_cam_imu_s == 0.02
    for bad in (0.25, -0.11, float("nan")):
        with pytest.raises(IbiscapeError, match="timeshift_cam_imu_s"):
            _shifted(cfg, rgbL=bad)
    p.write_text("cameras:\n  rgbL:\n    timeshift_cam_imu_s: 0.5\n")
    with pytest.raises(IbiscapeError, match=r"rgbL\.timeshift_cam_imu_s.*0\.1"):
        load_config(p)
    p.write_text("cameras:\n  rgbL:\n    timeshift_cam_imu_s: soon\n")
    with pytest.raises(FormatError, match="timeshift_cam_imu_s must be a number"):
        load_config(p)
