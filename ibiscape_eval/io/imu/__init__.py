"""IMU sample files: EuRoC/IBISCape csv, generic CSV, .npy/.npz/parquet, ROS 1/2 bags; Kalibr imu.yaml.

Every reader returns an :class:`~ibiscape_eval.core.imu.ImuRecord`: six axes in the order ``w_x w_y w_z`` (rad/s) then
``a_x a_y a_z`` (m/s^2), the sample rate from the median timestamp interval, and a
:class:`~ibiscape_eval.core.imu.ImuTiming` report of gaps and jitter.  Records are read in chunks; a large CSV is spilled
to a temporary ``.npy`` (float64) so that days of data stay within bounded memory, and a large
``.npy`` is never loaded whole (chunks are read with ``readinto``, not memory-mapped, so the
process' resident memory stays bounded).

Modules, one per concern: :mod:`.options` (``--columns``/``--units`` parsers), :mod:`.frames`
(CARLA's left-handed IMU frame), :mod:`.timing` (gap and jitter statistics), :mod:`.csv`,
:mod:`.npy` (``.npy``/``.npz``), :mod:`.parquet`; ROS bags are read by
:func:`ibiscape_eval.io.bag.read_imu_bag`, Kalibr's ``imu.yaml`` by
:func:`ibiscape_eval.io.kalibr.read_imu_noise`.  Everything public is importable from here.

The EuRoC/IBISCape layout (gyro first, trailing spaces allowed)::

    #timestamp [ns],w_x [rad s^-1],w_y [rad s^-1],w_z [rad s^-1],a_x [m s^-2],a_y [m s^-2],a_z [m s^-2]
    1403636579758555392,-0.099134701513277898,0.14730578886832138,0.02722713633111154,8.1476917083333333,-0.37592158333333331,-2.4026292499999999

IBISCape's IMU frame (format ``"ibiscape"``)
--------------------------------------------
Real IBISCape sequences store ``other_sensors/imu*.csv`` with the same columns, but in CARLA's
LEFT-handed sensor frame (x forward, y right, z up), like ``vehicle_gt/groundtruth_sync.csv``
(see :mod:`ibiscape_eval.io.ibiscape`).  Our frames are right-handed (x forward, y LEFT, z up);
the two are related by the mirror ``S = diag(1, -1, 1)`` (``det S = -1``, ``S = S^-1 = S^T``).

*Specific force* is an ordinary (polar) vector, so its coordinates mirror like a position::

    a = S a_c = (a_x, -a_y, a_z).

*Angular rate.*  With the sensor orientation ``R = S R_c S`` (world and sensor both mirrored),
the gyro reads the body rate ``w_c`` of ``dR_c/dt = R_c [w_c]x``.  Then::

    dR/dt = S R_c [w_c]x S = (S R_c S) (S [w_c]x S) = R [det(S) S w_c]x = R [-S w_c]x

using ``M [w]x M^T = det(M) [M w]x`` for any orthogonal ``M``; hence::

    w = -S w_c = (-w_x, w_y, -w_z).

(CARLA's ROS bridge converts its IMU the same way: ``linear_acceleration.y`` and
``angular_velocity.x``/``.z`` negated.)  Checks: a car turning LEFT (counter-clockwise seen from
above) has ``w_z > 0`` in our frame and ``w_z < 0`` in the file; accelerating toward its left
gives ``a_y > 0`` in ours and ``a_y < 0`` in the file.  Both maps are sign flips and involutions,
so the writer (``write_imu_csv(..., frame="ibiscape")``) applies the same flips; an Allan
deviation does not change under a sign flip.  ``read_imu`` picks ``"ibiscape"`` by itself for a
file ``imu*.csv`` in a folder ``other_sensors`` whose parent holds ``vehicle_gt/`` (the IBISCape
sequence layout); everywhere else a csv is read as it stands (EuRoC).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path

from ibiscape_eval.core.errors import FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.imu import AXES, ImuRecord, ImuTiming

from ..bag import read_imu_bag
from .columns import STAMP_UNITS, ImuFileRecord, ImuLayout, classify_header, stamp_unit, with_layout
from .csv import IMU_CSV_HEADER, read_imu_csv, write_imu_csv, write_imu_csv_chunks
from .frames import IBISCAPE_IMU_SIGNS, IMU_FRAMES, check_imu_frame, mirror_ibiscape_imu
from .npy import read_imu_npy, read_imu_npz, write_imu_npy
from .options import STANDARD_GRAVITY_M_S2, parse_columns, parse_units
from .parquet import read_imu_parquet
from .plausible import SensorMeans, check_sensor_layout, sensor_means
from .timing import record_from_parts

__all__ = [
    "AXES",
    "FORMATS",
    "IBISCAPE_IMU_SIGNS",
    "IMU_CSV_HEADER",
    "IMU_FRAMES",
    "SPILL_BYTES",
    "STAMP_UNITS",
    "STANDARD_GRAVITY_M_S2",
    "ImuFileRecord",
    "ImuLayout",
    "ImuRecord",
    "ImuTiming",
    "SensorMeans",
    "check_imu_frame",
    "check_sensor_layout",
    "classify_header",
    "mirror_ibiscape_imu",
    "parse_columns",
    "parse_units",
    "read_imu",
    "sensor_means",
    "stamp_unit",
    "write_imu_csv",
    "write_imu_csv_chunks",
    "write_imu_npy",
]

#: CSV files larger than this are parsed into a temporary .npy instead of memory.
SPILL_BYTES = 512 * 1024**2
#: ``fmt`` values of :func:`read_imu` (the CLI's ``--format`` choices).
FORMATS = ("euroc", "ibiscape", "csv", "npy", "npz", "parquet", "rosbag")


def read_imu(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    columns: str | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    rostopic: str | None = None,
    rate_hz: float | None = None,
    spill_bytes: int = SPILL_BYTES,
    check_physics: bool = True,
) -> ImuFileRecord:
    """Read IMU samples from any supported file.

    Parameters
    ----------
    path : path
        ``.csv``/``.txt`` (EuRoC/IBISCape layout, or generic with ``columns``), ``.npy`` (shape
        (N, 7) with ns stamps in column 0, or (N, 6) with ``rate_hz``), ``.npz`` (``stamps_ns``,
        ``gyro_rad_s``, ``accel_m_s2``, or ``data`` like .npy), ``.parquet`` (EuRoC column names or
        ``columns``), a ROS 1 ``.bag`` or a ROS 2 bag folder / ``.db3`` / ``.mcap``.
    fmt : {"euroc", "ibiscape", "csv", "npy", "npz", "parquet", "rosbag"}, optional
        Format; guessed from the name by default.  ``"ibiscape"`` is the EuRoC layout in CARLA's
        left-handed frame, converted to ours (``w_x, w_z, a_y`` negated, see the module
        docstring); it is guessed for ``<seq>/other_sensors/imu*.csv`` when ``<seq>/vehicle_gt/``
        exists.
    columns : str or mapping, optional
        Column mapping, see :func:`parse_columns`.
    units : str or mapping, optional
        Units of the file, e.g. ``"gyro=deg/s,accel=g"``, see :func:`parse_units`.
    rostopic : str, optional
        Topic of ``sensor_msgs/msg/Imu`` messages in a bag (default: the only such topic).
    rate_hz : float, optional
        Sample rate for files without timestamps, Hz.
    spill_bytes : int
        CSV files larger than this are parsed into a temporary ``.npy`` (bounded memory).
    check_physics : bool
        Refuse a gyro/accelerometer swap or an accelerometer in g read as m/s^2, judged by
        gravity (see :mod:`ibiscape_eval.io.imu.plausible`).

    Returns
    -------
    ImuFileRecord
        The record; ``layout`` says how a table's columns, units and stamps were read (header
        names, ``columns``, or the EuRoC order) and ``notes`` every conversion and check made.

    Raises
    ------
    FormatError
        Naming the file and 1-based line: non-numeric rows, wrong column count, non-increasing
        timestamps, missing keys or columns, too few samples, stamps whose unit gives no IMU's
        rate, swapped gyro/accelerometer, an accelerometer in g.
    FileNotFoundError
        The file does not exist.
    """
    from ..paths import check_input

    p = check_input(path, "any")
    f = (fmt or _guess_format(p)).lower()
    if f != "rosbag":
        check_input(p, "file")
    gscale, ascale = parse_units(units)
    scales = None if units is None else (gscale, ascale)
    rec, scales = _read_format(p, f, fmt, parse_columns(columns), scales, rostopic=rostopic,
                               rate_hz=rate_hz, spill_bytes=spill_bytes)
    if scales is not None and scales != (1.0, 1.0):
        if rec.samples is None:
            raise IbiscapeError(f"{p}: --units is not supported for records read from disk in chunks")
        s = rec.samples.copy()
        s[:, :3] *= scales[0]
        s[:, 3:] *= scales[1]
        rec = dataclasses.replace(rec, samples=s)
    layout = getattr(rec, "layout", None)
    notes: tuple[str, ...] = ()
    if check_physics:
        stated = units is not None or (layout is not None and layout.accel_scale != 1.0)
        notes = check_sensor_layout(p, rec, layout, accel_unit_stated=stated)
    return with_layout(rec, None, notes)


def _read_format(
    p: Path, f: str, fmt: str | None, cols: Mapping[str, str | int],
    scales: tuple[float, float] | None, *, rostopic: str | None, rate_hz: float | None,
    spill_bytes: int,
) -> tuple[ImuRecord, tuple[float, float] | None]:
    """The record read by the reader of format ``f``, and the unit scales still to apply
    (None when the reader applied them while parsing)."""
    if f in ("euroc", "csv", "ibiscape"):
        rec: ImuRecord = read_imu_csv(p, cols, spill_bytes, rate_hz,
                                      signs=IBISCAPE_IMU_SIGNS if f == "ibiscape" else None,
                                      units=scales)
        return rec, None  # applied while parsing
    if f == "npy":
        return read_imu_npy(p, rate_hz), scales
    if f == "npz":
        return read_imu_npz(p, rate_hz), scales
    if f == "parquet":
        return read_imu_parquet(p, cols, rate_hz, units=scales), None
    if f == "rosbag":
        stamps, data, topic = read_imu_bag(p, rostopic)
        return record_from_parts(p, stamps, data, None, rostopic=topic), scales
    raise IbiscapeError(f"unknown IMU format {fmt!r}; use one of {', '.join(FORMATS)}")


def _guess_format(p: Path) -> str:
    suf = p.suffix.lower()
    if p.is_dir() or suf in (".bag", ".db3", ".mcap"):
        return "rosbag"
    if suf in (".csv", ".txt"):
        return "ibiscape" if _in_ibiscape_sequence(p) else "csv"
    if suf in (".npy", ".npz", ".parquet"):
        return suf[1:]
    if suf == ".pq":
        return "parquet"
    raise FormatError(p, f"cannot tell the format from the suffix {suf!r}; give {{0}} "
                      f"({', '.join(FORMATS)})", hint=(Remedy("fmt"),))


def _in_ibiscape_sequence(p: Path) -> bool:
    """``<seq>/other_sensors/imu*.csv`` next to ``<seq>/vehicle_gt/``: the IBISCape layout."""
    return (p.suffix.lower() == ".csv" and p.name.lower().startswith("imu")
            and p.parent.name == "other_sensors" and (p.parent.parent / "vehicle_gt").is_dir())
