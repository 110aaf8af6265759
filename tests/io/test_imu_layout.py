"""IMU tables that today's users actually have: columns found by header name in any order, units
stated in the header, stamps in s / ms / us / ns, rostopic ``-p`` CSVs with a text column, and a
swapped gyro/accelerometer caught by gravity when no header says which is which."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.imu import read_imu

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "imu"))
from _still_data import still_imu, write_table

F = "%.9g"


@pytest.fixture(scope="module")
def still() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return still_imu(duration_s=20.0, seed=2)


def _check(rec, g: np.ndarray, a: np.ndarray, rate: float = 200.0) -> None:  # type: ignore[no-untyped-def]
    assert rec.rate_hz == pytest.approx(rate, rel=1e-6)
    np.testing.assert_allclose(rec.gyro_rad_s, g, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(rec.accel_m_s2, a, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("header", [
    "timestamp,ax,ay,az,gx,gy,gz",
    "#timestamp [ns],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2],"
    "w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1]",
    "time,acc_x,acc_y,acc_z,gyro_x,gyro_y,gyro_z",
    "t,accel_x,accel_y,accel_z,omega_x,omega_y,omega_z",
])
def test_accel_first_header_is_read_by_name(tmp_path: Path, still, header: str) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv", header, [t, *a.T, *g.T], ["%d"] + [F] * 6)
    rec = read_imu(p)
    _check(rec, g, a)
    assert rec.layout is not None and rec.layout.mapped_by == "header names"
    assert rec.layout.axis_columns == (4, 5, 6, 1, 2, 3)


def test_gyro_columns_anywhere_with_extra_columns(tmp_path: Path, still) -> None:
    t, g, a = still
    temp = np.full(t.size, 31.5)
    p = write_table(tmp_path / "imu.csv", "temperature,gz,ax,timestamp,gy,ay,gx,az",
                    [temp, g[:, 2], a[:, 0], t, g[:, 1], a[:, 1], g[:, 0], a[:, 2]],
                    ["%.1f", F, F, "%d", F, F, F, F])
    _check(read_imu(p), g, a)


def test_units_in_header_are_converted_and_said(tmp_path: Path, still) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv",
                    "time [s],gyro_x [deg/s],gyro_y [deg/s],gyro_z [deg/s],acc_x [g],acc_y [g],acc_z [g]",
                    [t / 1e9, *(np.degrees(g)).T, *(a / 9.80665).T], ["%.9f"] + ["%.12g"] * 6)
    rec = read_imu(p)
    np.testing.assert_allclose(rec.gyro_rad_s, g, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(rec.accel_m_s2, a, rtol=1e-9, atol=1e-12)
    assert any("deg/s" in n and "converted" in n for n in rec.notes)
    assert any("in g" in n and "converted" in n for n in rec.notes)


@pytest.mark.parametrize(("unit", "scale", "fmt"), [("s", 1e-9, "%.6f"), ("ms", 1e-6, "%d"),
                                                    ("us", 1e-3, "%d")])
@pytest.mark.parametrize("relative", [False, True])
def test_seconds_ms_us_stamps_from_the_interval(tmp_path: Path, still, unit: str, scale: float,
                                               fmt: str, relative: bool) -> None:
    """No header: the first column in s / ms / us is recognised (not "interval 0 ns")."""
    t, g, a = still
    t0 = t - t[0] if relative else t
    stamps = t0 * scale if fmt != "%d" else np.round(t0 * scale).astype(np.int64)
    p = write_table(tmp_path / "imu.csv", None, [stamps, *g.T, *a.T], [fmt] + [F] * 6)
    rec = read_imu(p)
    _check(rec, g, a)
    assert rec.layout is not None and rec.layout.time_unit == unit
    assert any(f"timestamps read as {unit}" in n for n in rec.notes)


def test_stated_unit_that_gives_no_imu_rate_is_refused(tmp_path: Path, still) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv", "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z",
                    [t / 1e9, *g.T, *a.T], ["%.6f"] + [F] * 6)
    with pytest.raises(FormatError, match=r"imu.csv.*1e\+08|imu.csv.*look like s"):
        read_imu(p)


ROSTOPIC_COV = [f"field.orientation_covariance{i}" for i in range(9)]


def _rostopic_csv(path: Path, t: np.ndarray, g: np.ndarray, a: np.ndarray) -> Path:
    n = t.size
    cols = ["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id",
            "field.orientation.x", "field.orientation.y", "field.orientation.z",
            "field.orientation.w", *ROSTOPIC_COV,
            "field.angular_velocity.x", "field.angular_velocity.y", "field.angular_velocity.z",
            *[f"field.angular_velocity_covariance{i}" for i in range(9)],
            "field.linear_acceleration.x", "field.linear_acceleration.y",
            "field.linear_acceleration.z",
            *[f"field.linear_acceleration_covariance{i}" for i in range(9)]]
    z = np.zeros(n)
    data = [t + 1_234_567, np.arange(n), t, np.array(["imu4"] * n), z, z, z, z + 1, *[z] * 9,
            *g.T, *[z] * 9, *a.T, *[z] * 9]
    fmt = ["%d", "%d", "%d", "%s", *["%g"] * 13, F, F, F, *["%g"] * 9, F, F, F, *["%g"] * 9]
    return write_table(path, ",".join(cols), data, fmt)


def test_rostopic_echo_p_csv(tmp_path: Path, still) -> None:
    """The text frame_id column is not parsed; the sensor stamp (not %time) is the time."""
    t, g, a = still
    p = _rostopic_csv(tmp_path / "imu.csv", t, g, a)
    rec = read_imu(p)
    _check(rec, g, a)
    assert rec.layout is not None and rec.layout.time_column == 2


def test_rostopic_csv_with_columns_by_name(tmp_path: Path, still) -> None:
    t, g, a = still
    p = _rostopic_csv(tmp_path / "imu.csv", t, g, a)
    cols = ("t=field.header.stamp,w_x=field.angular_velocity.x,w_y=field.angular_velocity.y,"
            "w_z=field.angular_velocity.z,a_x=field.linear_acceleration.x,"
            "a_y=field.linear_acceleration.y,a_z=field.linear_acceleration.z")
    _check(read_imu(p, columns=cols), g, a)
    # by 0-based index
    _check(read_imu(p, columns="t=2,w_x=17,w_y=18,w_z=19,a_x=29,a_y=30,a_z=31"), g, a)


@pytest.mark.parametrize("columns", ["t,ax,ay,az,gx,gy,gz", "t=0,a_x=1,a_y=2,a_z=3,w_x=4,w_y=5,w_z=6"])
def test_columns_list_and_index_on_headerless_accel_first(tmp_path: Path, still, columns: str) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv", None, [t, *a.T, *g.T], ["%d"] + [F] * 6)
    _check(read_imu(p, columns=columns), g, a)


def test_headerless_accel_first_is_refused_by_gravity(tmp_path: Path, still) -> None:
    """No header: the default (gyro-first) order would read gravity as a rotation rate."""
    t, g, a = still
    p = write_table(tmp_path / "imu.csv", None, [t, *a.T, *g.T], ["%d"] + [F] * 6)
    with pytest.raises(FormatError, match=r'imu.csv: .*swapped.*columns="t,ax,ay,az,gx,gy,gz"$'):
        read_imu(p)


def test_accel_in_g_without_a_stated_unit_is_refused(tmp_path: Path, still) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv", None, [t, *g.T, *(a / 9.80665).T], ["%d"] + [F] * 6)
    with pytest.raises(FormatError, match=r'imu.csv: .*units="accel=g"'):
        read_imu(p)
    rec = read_imu(p, units="accel=g")
    np.testing.assert_allclose(rec.accel_m_s2, a, rtol=1e-7)


@pytest.mark.parametrize("fortran", [False, True])
def test_npy_with_seconds_stamps(tmp_path: Path, still, fortran: bool) -> None:
    t, g, a = still
    arr = np.column_stack([(t - t[0]) / 1e9 + 1000.0, g, a])
    np.save(tmp_path / "imu.npy", np.asfortranarray(arr) if fortran else arr)
    rec = read_imu(tmp_path / "imu.npy")
    assert rec.rate_hz == pytest.approx(200.0, rel=1e-6)
    assert any("timestamps read as s" in n for n in rec.notes)


def test_columns_by_name_keep_the_header_units(tmp_path: Path, still) -> None:
    t, g, a = still
    p = write_table(tmp_path / "imu.csv",
                    "time_ns,gyro_x [deg/s],gyro_y [deg/s],gyro_z [deg/s],acc_x [g],acc_y [g],acc_z [g]",
                    [t, *(np.degrees(g)).T, *(a / 9.80665).T], ["%d"] + ["%.12g"] * 6)
    rec = read_imu(p, columns="t=0,w_x=gyro_x [deg/s],w_y=gyro_y,w_z=gyro_z,a_x=4,a_y=5,a_z=6")
    np.testing.assert_allclose(rec.gyro_rad_s, g, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(rec.accel_m_s2, a, rtol=1e-9, atol=1e-12)
    assert any("converted to rad/s" in n for n in rec.notes)
