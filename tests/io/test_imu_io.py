"""IMU readers and writers: round trips, formats, units, bad input with file and line."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.io.imu import (
    read_imu,
    write_imu_csv,
    write_imu_npy,
)

T0 = 1_403_636_579_758_555_392


def _data(n: int = 500, seed: int = 0, rate: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = T0 + np.round(np.arange(n) * 1e9 / rate).astype(np.int64)
    return t, rng.normal(size=(n, 6))


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(finite, min_size=6, max_size=6), min_size=3, max_size=40),
       step=st.integers(min_value=1_000_000, max_value=50_000_000))
def test_csv_round_trip(tmp_path: Path, rows: list[list[float]], step: int) -> None:
    y = np.array(rows)
    t = np.int64(1_000_000_000) + np.arange(len(rows), dtype=np.int64) * step
    path = tmp_path / "imu.csv"
    write_imu_csv(path, t, y[:, :3], y[:, 3:])
    rec = read_imu(path)
    # the one IMU csv writer keeps 15 significant digits (relative error ~5e-15, a little more
    # for exponents near the subnormal range)
    np.testing.assert_allclose(rec.samples, y, rtol=1e-14, atol=1e-323)
    assert rec.rate_hz == pytest.approx(1e9 / step)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(finite, min_size=6, max_size=6), min_size=3, max_size=40),
       chunk=st.integers(min_value=1, max_value=50))
def test_npy_round_trip_streamed(tmp_path: Path, rows: list[list[float]], chunk: int) -> None:
    y = np.array(rows)
    t = 10**9 + np.arange(len(rows), dtype=np.int64) * 5_000_000
    full = np.column_stack([t, y])
    path = tmp_path / "imu.npy"
    n = write_imu_npy(path, (full[i : i + chunk] for i in range(0, len(full), chunk)))
    assert n == len(rows)
    np.testing.assert_array_equal(np.load(path, allow_pickle=False), full)
    rec = read_imu(path)
    assert rec.samples is None  # read in chunks, never loaded whole
    np.testing.assert_array_equal(np.concatenate(list(rec.iter_chunks(range(6), 7))), y)
    assert rec.rate_hz == pytest.approx(200.0)


def test_euroc_csv_with_trailing_spaces(tmp_path: Path) -> None:
    t, y = _data(50)
    lines = ["#timestamp [ns],w_x [rad s^-1],w_y,w_z,a_x,a_y,a_z"]
    lines += [",".join([str(ti)] + [repr(float(v)) for v in row]) + " " for ti, row in zip(t, y, strict=True)]
    (tmp_path / "imu.csv").write_text("\n".join(lines) + "\n")
    rec = read_imu(tmp_path / "imu.csv")
    np.testing.assert_array_equal(rec.samples, y)
    assert rec.rate_hz == pytest.approx(200.0, rel=1e-6)
    assert rec.timing.n_gaps == 0


def test_spilled_csv_equals_in_memory(tmp_path: Path) -> None:
    t, y = _data(3000)
    write_imu_csv(tmp_path / "imu.csv", t, y[:, :3], y[:, 3:])
    rec = read_imu(tmp_path / "imu.csv", spill_bytes=1000)
    mem = read_imu(tmp_path / "imu.csv")
    assert rec.samples is None and mem.samples is not None
    np.testing.assert_array_equal(rec.gyro_rad_s, mem.gyro_rad_s)
    np.testing.assert_array_equal(rec.accel_m_s2, mem.accel_m_s2)
    np.testing.assert_allclose(mem.samples, y, rtol=1e-14)


def test_generic_csv_columns_and_units(tmp_path: Path) -> None:
    t, y = _data(100, rate=100.0)
    text = "time,ax,ay,az,gx,gy,gz\n" + "\n".join(
        ",".join([f"{ti * 1e-9:.6f}"] + [repr(float(v)) for v in row]) for ti, row in zip(t - T0, y, strict=True))
    (tmp_path / "log.csv").write_text(text + "\n")
    rec = read_imu(tmp_path / "log.csv", columns="t_s=time,w_x=gx,w_y=gy,w_z=gz,a_x=ax,a_y=ay,a_z=az",
                   units="gyro=deg/s,accel=g")
    np.testing.assert_allclose(rec.gyro_rad_s, y[:, 3:] * np.pi / 180)
    np.testing.assert_allclose(rec.accel_m_s2, y[:, :3] * 9.80665)
    assert rec.rate_hz == pytest.approx(100.0)


def test_npz_parquet_and_rate_without_stamps(tmp_path: Path) -> None:
    import pandas as pd

    t, y = _data(200)
    np.savez(tmp_path / "imu.npz", stamps_ns=t, gyro_rad_s=y[:, :3], accel_m_s2=y[:, 3:])
    np.testing.assert_array_equal(read_imu(tmp_path / "imu.npz").samples, y)
    np.save(tmp_path / "six.npy", y)
    with pytest.raises(FormatError, match="rate_hz"):
        read_imu(tmp_path / "six.npy")
    assert read_imu(tmp_path / "six.npy", rate_hz=50.0).rate_hz == 50.0
    df = pd.DataFrame(y, columns=["w_x", "w_y", "w_z", "a_x", "a_y", "a_z"])
    df.insert(0, "#timestamp [ns]", t)
    df.to_parquet(tmp_path / "imu.parquet")
    rec = read_imu(tmp_path / "imu.parquet")
    np.testing.assert_array_equal(rec.samples, y)


def test_npz_with_pickled_objects_is_refused(tmp_path: Path) -> None:
    np.savez(tmp_path / "bad.npz", data=np.array([{"a": 1}], dtype=object))
    with pytest.raises(FormatError, match="pickled"):
        read_imu(tmp_path / "bad.npz")


@pytest.mark.parametrize("ros", [1, 2])
def test_ros_bags(tmp_path: Path, ros: int) -> None:
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V3 = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    t, y = _data(60)

    def message(ti: int, row: np.ndarray) -> object:
        stamp = Time(sec=int(ti // 10**9), nanosec=int(ti % 10**9))
        header = (Header(seq=0, stamp=stamp, frame_id="imu") if ros == 1
                  else Header(stamp=stamp, frame_id="imu"))
        return Imu(header=header, orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
                   orientation_covariance=np.zeros(9),
                   angular_velocity=V3(x=row[0], y=row[1], z=row[2]),
                   angular_velocity_covariance=np.zeros(9),
                   linear_acceleration=V3(x=row[3], y=row[4], z=row[5]),
                   linear_acceleration_covariance=np.zeros(9))

    if ros == 1:
        from rosbags.rosbag1 import Writer as Writer1

        bag = tmp_path / "imu.bag"
        with Writer1(bag) as w1:
            conn = w1.add_connection("/imu0", Imu.__msgtype__, typestore=ts)
            for ti, row in zip(t, y, strict=True):
                w1.write(conn, int(ti), ts.serialize_ros1(message(ti, row), Imu.__msgtype__))
    else:
        from rosbags.rosbag2 import Writer as Writer2

        bag = tmp_path / "bag"
        with Writer2(bag, version=8) as w2:
            conn = w2.add_connection("/imu0", Imu.__msgtype__, typestore=ts)
            for ti, row in zip(t, y, strict=True):
                w2.write(conn, int(ti), ts.serialize_cdr(message(ti, row), Imu.__msgtype__))
    rec = read_imu(bag)
    np.testing.assert_array_equal(rec.samples, y)
    assert rec.rostopic == "/imu0"
    with pytest.raises(FormatError, match="not in the bag"):
        read_imu(bag, rostopic="/imu1")


# --- bad input -------------------------------------------------------------------------------


def _csv(tmp_path: Path, n: int = 20) -> Path:
    t, y = _data(n)
    path = tmp_path / "imu.csv"
    write_imu_csv(path, t, y[:, :3], y[:, 3:])
    return path


def _edit(path: Path, line: int, text: str) -> None:
    lines = path.read_text().splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")


def test_non_numeric_row_names_line(tmp_path: Path) -> None:
    p = _csv(tmp_path)
    _edit(p, 7, "1403636579788555392,0.1,abc,0.3,0.4,0.5,0.6")
    with pytest.raises(FormatError, match=r"imu.csv:7: column 3 is not a number"):
        read_imu(p)


@pytest.mark.parametrize("row", ["1403636579788555392,0.1,0.2,0.3,0.4,0.5,0.6,0.7",
                                 "1403636579788555392,0.1,0.2,0.3,0.4,0.5"])
def test_wrong_column_count_names_line(tmp_path: Path, row: str) -> None:
    p = _csv(tmp_path)
    _edit(p, 9, row)
    with pytest.raises(FormatError, match=r"imu.csv:9: expected 7 comma-separated columns"):
        read_imu(p)


def test_non_monotonic_timestamps_name_line(tmp_path: Path) -> None:
    p = _csv(tmp_path)
    lines = p.read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"imu.csv:7: timestamps are not strictly increasing"):
        read_imu(p)


def test_gaps_are_measured(tmp_path: Path) -> None:
    t, y = _data(1000)
    keep = np.ones(1000, dtype=bool)
    keep[300:400] = False
    write_imu_csv(tmp_path / "g.csv", t[keep], y[keep, :3], y[keep, 3:])
    tm = read_imu(tmp_path / "g.csv").timing
    assert tm.n_gaps == 1 and tm.missing_samples == 100
    assert tm.largest_gap_s == pytest.approx(0.505)
    assert tm.first_gap_line == 302  # header + 300 rows, then the row after the gap


def test_unknown_units_and_columns(tmp_path: Path) -> None:
    p = _csv(tmp_path)
    with pytest.raises(IbiscapeError, match="unknown gyro unit 'rpm'"):
        read_imu(p, units="gyro=rpm")
    with pytest.raises(IbiscapeError, match="unknown accel unit"):
        read_imu(p, units="accel=furlong")
    with pytest.raises(IbiscapeError, match="lacks"):
        read_imu(p, columns="t=0,w_x=1")


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_imu(tmp_path / "nope.csv")


# ---------------------------------------------------------------------------------------------
# IBISCape: CARLA's left-handed IMU frame (w_x, w_z, a_y negated)

_FLIP = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(finite, min_size=6, max_size=6), min_size=3, max_size=40),
       chunk=st.integers(min_value=1, max_value=50), spill=st.booleans())
def test_ibiscape_frame_round_trip(tmp_path: Path, rows: list[list[float]], chunk: int,
                                   spill: bool) -> None:
    from ibiscape_eval.io.imu import write_imu_csv_chunks

    y = np.array(rows)
    t = np.int64(10**9) + np.arange(len(rows), dtype=np.int64) * 5_000_000
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"

    def chunks() -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        return ((t[i : i + chunk], y[i : i + chunk, :3], y[i : i + chunk, 3:])
                for i in range(0, len(rows), chunk))

    write_imu_csv(a, t, y[:, :3], y[:, 3:], frame="ibiscape")
    assert write_imu_csv_chunks(b, chunks(), frame="ibiscape") == len(rows)
    write_imu_csv_chunks(c, chunks())
    spill_bytes = 1 if spill else 1 << 30

    def read(path: Path, fmt: str) -> np.ndarray:
        rec = read_imu(path, fmt=fmt, spill_bytes=spill_bytes)
        return np.concatenate(list(rec.iter_chunks(range(6), 7)))

    # write_imu_csv is the streaming writer with one chunk: the same bytes
    assert a.read_bytes() == b.read_bytes()
    # 15 digits in either frame: mirroring adds no error
    np.testing.assert_array_equal(read(b, "ibiscape"), read(c, "euroc"))
    np.testing.assert_allclose(read(b, "ibiscape"), y, rtol=1e-14, atol=1e-323)
    # the files themselves hold the mirrored values
    np.testing.assert_allclose(read(a, "euroc"), y * _FLIP, rtol=1e-14, atol=1e-323)
    np.testing.assert_array_equal(read(b, "euroc"), read(c, "euroc") * _FLIP)


def test_writers_refuse_unknown_frame(tmp_path: Path) -> None:
    from ibiscape_eval.io.imu import write_imu_csv_chunks

    t, y = _data(5)
    with pytest.raises(IbiscapeError, match="unknown IMU frame 'carla'"):
        write_imu_csv(tmp_path / "x.csv", t, y[:, :3], y[:, 3:], frame="carla")
    with pytest.raises(IbiscapeError, match="unknown IMU frame"):
        write_imu_csv_chunks(tmp_path / "y.csv", [(t, y[:, :3], y[:, 3:])], frame="left")
    assert not any(tmp_path.iterdir())


def _carla_left_turn_file(path: Path, n: int = 400) -> None:
    """A car driving at 10 m/s turning LEFT at 0.3 rad/s, as CARLA's IMU writes it: yaw rate
    w_z < 0 (CARLA's yaw grows clockwise seen from above), centripetal a_y = -3 m/s^2 (left is -y)."""
    lines = ["#timestamp [ns],w_x [rad s^-1],w_y [rad s^-1],w_z [rad s^-1],a_x [m s^-2],"
             "a_y [m s^-2],a_z [m s^-2]"]
    lines += [f"{T0 + i * 5_000_000},0.02,0.01,-0.3,0.5,-3.0,9.81 " for i in range(n)]
    path.write_text("\n".join(lines) + "\n")


def test_hand_made_carla_left_turn_reads_with_our_signs(tmp_path: Path) -> None:
    _carla_left_turn_file(tmp_path / "imu.csv")
    rec = read_imu(tmp_path / "imu.csv", fmt="ibiscape")
    assert rec.samples is not None
    g, a = rec.gyro_rad_s, rec.accel_m_s2
    np.testing.assert_array_equal(g[0], [-0.02, 0.01, 0.3])  # left turn: positive yaw rate in ours
    np.testing.assert_array_equal(a[0], [0.5, 3.0, 9.81])  # toward the left: a_y > 0 in ours
    # centripetal acceleration = speed x yaw rate, both positive for a left turn in our frame
    assert a[0, 1] == pytest.approx(10.0 * g[0, 2])
    # outside a sequence folder the same file is read as it stands
    np.testing.assert_array_equal(read_imu(tmp_path / "imu.csv").gyro_rad_s[0], [0.02, 0.01, -0.3])


def test_ibiscape_format_is_detected_inside_a_sequence(tmp_path: Path) -> None:
    seq = tmp_path / "SVI_1_town"
    (seq / "other_sensors").mkdir(parents=True)
    for name in ("imu.csv", "imu0.csv", "imu_still.csv"):
        _carla_left_turn_file(seq / "other_sensors" / name)
    _carla_left_turn_file(seq / "other_sensors" / "log.csv")  # not imu*: read as it stands
    # no vehicle_gt/ yet: not the IBISCape layout
    assert read_imu(seq / "other_sensors" / "imu.csv").gyro_rad_s[0, 2] == -0.3
    (seq / "vehicle_gt").mkdir()
    for name in ("imu.csv", "imu0.csv", "imu_still.csv"):
        rec = read_imu(seq / "other_sensors" / name)
        np.testing.assert_array_equal(rec._all()[0], [-0.02, 0.01, 0.3, 0.5, 3.0, 9.81])
    assert read_imu(seq / "other_sensors" / "log.csv").gyro_rad_s[0, 2] == -0.3
    # an explicit format wins over the guess
    assert read_imu(seq / "other_sensors" / "imu.csv", fmt="euroc").gyro_rad_s[0, 2] == -0.3
    # a folder that is only named like it, elsewhere: no conversion
    other = tmp_path / "x" / "other_sensors"
    other.mkdir(parents=True)
    _carla_left_turn_file(other / "imu.csv")
    assert read_imu(other / "imu.csv").gyro_rad_s[0, 2] == -0.3


def test_allan_deviation_is_unchanged_by_the_mirror(tmp_path: Path) -> None:
    from ibiscape_eval.imu import allan_deviation

    t, y = _data(4000, seed=7)
    y[:, 5] += 9.81
    write_imu_csv(tmp_path / "imu.csv", t, y[:, :3], y[:, 3:], frame="ibiscape")
    ours = read_imu(tmp_path / "imu.csv", fmt="ibiscape")
    raw = read_imu(tmp_path / "imu.csv", fmt="euroc")
    np.testing.assert_array_equal(ours.gyro_rad_s, raw.gyro_rad_s * _FLIP[:3])
    assert not np.array_equal(ours.accel_m_s2, raw.accel_m_s2)
    ra, rb = allan_deviation(ours, ours.rate_hz), allan_deviation(raw, raw.rate_hz)
    np.testing.assert_array_equal(ra.taus_s, rb.taus_s)
    np.testing.assert_allclose(ra.adev, rb.adev, rtol=1e-12, atol=0)
    assert ra.adev.shape[1] == 6 and np.all(ra.adev > 0)
