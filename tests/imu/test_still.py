"""The stillness test: generated still IMUs pass (continuous and CARLA noise models, biased
gyros), a generated drive and a still record with a short pick-up are refused with numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _still_data import driving_imu, still_imu

from ibiscape_eval.core.errors import DegenerateInputError
from ibiscape_eval.imu import assess_stillness, check_still
from ibiscape_eval.io.imu import read_imu
from ibiscape_eval.sim.config import ImuNoise


def _six(g: np.ndarray, a: np.ndarray) -> np.ndarray:
    return np.column_stack([g, a])


@pytest.mark.parametrize("noise", [
    ImuNoise(),
    ImuNoise(model="carla"),
    ImuNoise(model="carla", carla_gyro_bias_rad_s=0.1),
    ImuNoise(gyro_turn_on_bias_sigma_rad_s=0.05, accel_turn_on_bias_sigma_m_s2=0.2),
], ids=["continuous", "carla", "carla-bias-0.1", "big-turn-on-bias"])
@pytest.mark.parametrize("seed", [1, 2])
def test_generated_still_imus_pass(noise: ImuNoise, seed: int) -> None:
    _, g, a = still_imu(duration_s=120.0, seed=seed, noise=noise)
    rep = check_still(_six(g, a), 200.0)
    assert rep.still and rep.tested, rep.reasons
    assert rep.ratio < 1.5  # far from the refusal ratio 3
    assert rep.moving_fraction == 0.0
    assert rep.to_dict()["still"] is True


def test_generated_drive_is_refused_with_numbers(tmp_path: Path) -> None:
    p = driving_imu(tmp_path, duration_s=30.0)
    rec = read_imu(p)
    rep = assess_stillness(rec, rec.rate_hz)
    assert not rep.still and rep.ratio > 30
    assert rep.moving_fraction > 0.3
    with pytest.raises(DegenerateInputError) as e:
        check_still(rec, rec.rate_hz, path=p)
    msg = str(e.value)
    assert str(p) in msg and "not a still IMU" in msg and "force=True" in msg
    assert "x what a still IMU with this noise shows" in msg and "\n" not in msg
    forced = check_still(rec, rec.rate_hz, path=p, force=True)
    assert not forced.still and forced.reasons


def test_short_pick_up_in_a_still_record_is_found() -> None:
    _, g, a = still_imu(duration_s=300.0, seed=3)
    t = np.arange(g.shape[0]) / 200.0
    bump = (t > 150.0) & (t < 153.0)
    g = g.copy()
    g[bump, 0] += 0.5 * np.sin(np.pi * (t[bump] - 150.0) / 3.0)  # tilted and put back
    rep = assess_stillness(_six(g, a), 200.0)
    assert not rep.still
    assert rep.first_moving_s == pytest.approx(150.0, abs=2.0)
    assert rep.worst == "w_x"


def test_turning_table_and_wrong_gravity_are_refused() -> None:
    _, g, a = still_imu(duration_s=60.0, seed=4)
    turning = assess_stillness(_six(g + np.array([0.0, 0.0, 0.3]), a), 200.0)
    assert not turning.still and "gyro mean 0.3" in turning.reasons[0]
    assert "deg/s" in turning.reasons[0]
    light = assess_stillness(_six(g, a * 0.8), 200.0)
    assert not light.still and "accelerometer mean norm 7.8" in light.reasons[0]
    cheap = assess_stillness(_six(g, a * 0.92), 200.0)  # an uncalibrated part: a note
    assert cheap.still and any("-8.0 % from g" in n for n in cheap.notes)


def test_gravity_free_noise_passes_with_a_note() -> None:
    from ibiscape_eval.sim.noise import imu_noise

    y = imu_noise(20_000, 50.0, noise_density=[1e-3] * 3 + [2e-2] * 3, random_walk=0.0, seed=5)
    rep = assess_stillness(y, 50.0)
    assert rep.still and any("no gravity" in n for n in rep.notes)


def test_chunked_record_equals_in_memory(tmp_path: Path) -> None:
    from ibiscape_eval.io.imu import write_imu_csv

    t, g, a = still_imu(duration_s=30.0, seed=6)
    write_imu_csv(tmp_path / "imu.csv", t, g, a)
    mem = read_imu(tmp_path / "imu.csv")
    disk = read_imu(tmp_path / "imu.csv", spill_bytes=1)
    assert disk.samples is None
    r1, r2 = assess_stillness(mem, 200.0), assess_stillness(disk, 200.0)
    np.testing.assert_allclose(r1.measured, r2.measured, rtol=1e-9)


REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "mpu6050_still"


def _mpu6050(name: str) -> np.ndarray:
    """A real MPU-6050 record (raw counts, accelerometer first by header name) in rad/s, m/s^2."""
    rec = read_imu(REAL / name, rate_hz=100.0)
    assert rec.layout is not None and rec.layout.axis_columns == (3, 4, 5, 0, 1, 2)
    y = np.array(rec.samples)
    y[:, :3] *= np.pi / 180.0 / 131.0  # +-250 deg/s full scale
    y[:, 3:] *= 9.80665 / 16384.0  # +-2 g full scale
    return y


def test_real_mpu6050_still_passes_and_turned_is_refused() -> None:
    still = assess_stillness(_mpu6050("static.csv"), 100.0)
    assert still.still and still.ratio < 1.0, still.reasons
    # an uncalibrated part: 0.91 g, said in a note rather than refused
    assert any("from g" in n for n in still.notes)
    turned = assess_stillness(_mpu6050("rot_90_x.csv"), 100.0)
    assert not turned.still and turned.worst == "w_x" and turned.ratio > 30
