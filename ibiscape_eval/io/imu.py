"""IMU sample files: EuRoC/IBISCape csv, generic CSV, .npy/.npz/parquet, ROS 1/2 bags; Kalibr imu.yaml.

Every reader returns an :class:`ImuRecord`: six axes in the order ``w_x w_y w_z`` (rad/s) then
``a_x a_y a_z`` (m/s^2), the sample rate from the median timestamp interval, and a
:class:`ImuTiming` report of gaps and jitter.  Records are read in chunks; a large CSV is spilled
to a temporary ``.npy`` (float64) so that days of data stay within bounded memory, and a large
``.npy`` is never loaded whole (chunks are read with ``readinto``, not memory-mapped, so the
process' resident memory stays bounded).

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

import contextlib
import math
import os
import tempfile
import weakref
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError

from ._atomic import atomic_write
from .ibiscape import _S

__all__ = [
    "AXES",
    "IBISCAPE_IMU_SIGNS",
    "IMU_FRAMES",
    "ImuRecord",
    "ImuTiming",
    "mirror_ibiscape_imu",
    "parse_columns",
    "parse_units",
    "read_imu",
    "read_kalibr_imu_yaml",
    "write_imu_csv",
    "write_imu_npy",
    "write_kalibr_imu_yaml",
]

#: Axis names in the order of every record: gyro (rad/s) first, then accelerometer (m/s^2).
AXES = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
_EUROC_HEADER = (
    "#timestamp [ns],w_x [rad s^-1],w_y [rad s^-1],w_z [rad s^-1],"
    "a_x [m s^-2],a_y [m s^-2],a_z [m s^-2]"
)
STANDARD_GRAVITY_M_S2 = 9.80665
_GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
_ACCEL_UNITS = {"m/s^2": 1.0, "m/s2": 1.0, "g": STANDARD_GRAVITY_M_S2}
_CHUNK_ROWS = 1 << 20
#: CSV files larger than this are parsed into a temporary .npy instead of memory.
SPILL_BYTES = 512 * 1024**2
FORMATS = ("euroc", "ibiscape", "csv", "npy", "npz", "parquet", "rosbag")
#: Per-axis signs (w_x .. a_z) between CARLA's left-handed IMU frame and ours: gyro ``-S``,
#: accel ``S`` with ``S = diag(1, -1, 1)``, i.e. ``(-1, 1, -1, 1, -1, 1)`` (an involution).
IBISCAPE_IMU_SIGNS = np.concatenate((-_S, _S))
IBISCAPE_IMU_SIGNS.flags.writeable = False
#: ``frame`` values of the writers: as given (right-handed) or mirrored to CARLA's frame.
IMU_FRAMES = ("right-handed", "ibiscape")


@dataclass(frozen=True)
class ImuTiming:
    """Timestamp statistics of a record.

    Attributes
    ----------
    has_stamps : bool
        False when the file has no timestamps (the rate was given).
    median_dt_s : float
        Median sample interval, s (from the first million intervals for long records).
    n_gaps : int
        Intervals longer than 1.5 median intervals.
    missing_samples : int
        Samples that the gaps would have held at the median rate.
    missing_fraction : float
        ``missing_samples / (n_samples + missing_samples)``.
    largest_gap_s : float
        Longest interval, s.
    jitter_s : float
        Standard deviation of the intervals that are not gaps, s.
    first_gap_line : int or None
        1-based file line (row for binary files) where the first gap ends.
    """

    has_stamps: bool
    median_dt_s: float
    n_gaps: int = 0
    missing_samples: int = 0
    missing_fraction: float = 0.0
    largest_gap_s: float = 0.0
    jitter_s: float = 0.0
    first_gap_line: int | None = None


@dataclass(frozen=True, eq=False)
class ImuRecord:
    """Six-axis IMU samples, in memory or in a float64 ``.npy`` read chunk by chunk.

    Satisfies :class:`ibiscape_eval.imu.ChunkedSamples` (``n_samples``, ``n_columns``,
    ``iter_chunks``), so it can be passed to :func:`ibiscape_eval.imu.allan_deviation` directly.

    Attributes
    ----------
    path : str
        The file read.
    n_samples : int
    rate_hz : float
        From the median interval, or as given for files without timestamps.
    timing : ImuTiming
    names : tuple of str
        ``AXES``.
    rostopic : str or None
        The bag topic read, if any.
    samples : ndarray, shape (N, 6), or None
        gyro rad/s then accel m/s^2, when held in memory.
    """

    path: str
    n_samples: int
    rate_hz: float
    timing: ImuTiming
    names: tuple[str, ...] = AXES
    rostopic: str | None = None
    samples: np.ndarray | None = None
    _npy: tuple[str, int, np.dtype[Any], int, int] | None = field(default=None, repr=False)
    _keep: Any = field(default=None, repr=False)  # keeps a spill directory alive

    @property
    def n_columns(self) -> int:
        return len(self.names)

    def iter_chunks(self, columns: Sequence[int], chunk_rows: int = _CHUNK_ROWS) -> Iterator[np.ndarray]:
        """Yield float64 arrays of shape (rows, len(columns)) in order."""
        cols = list(columns)
        if self.samples is not None:
            for i in range(0, self.n_samples, chunk_rows):
                yield np.array(self.samples[i : i + chunk_rows, cols], dtype=np.float64)
            return
        assert self._npy is not None
        fname, offset, dtype, width, first = self._npy
        sel = [first + c for c in cols]
        for block in _npy_blocks(fname, offset, dtype, width, self.n_samples, chunk_rows):
            yield np.asarray(block[:, sel], dtype=np.float64)

    @property
    def gyro_rad_s(self) -> np.ndarray:
        """(N, 3) rad/s (loads the record if it is on disk)."""
        return self._all()[:, :3]

    @property
    def accel_m_s2(self) -> np.ndarray:
        """(N, 3) m/s^2 (loads the record if it is on disk)."""
        return self._all()[:, 3:]

    def _all(self) -> np.ndarray:
        if self.samples is not None:
            return self.samples
        return np.concatenate(list(self.iter_chunks(range(6))), axis=0)


# ---------------------------------------------------------------------------------------------
# options


def parse_units(text: str | Mapping[str, str] | None) -> tuple[float, float]:
    """Scale factors (gyro -> rad/s, accel -> m/s^2) from ``"gyro=deg/s,accel=g"``.

    Known units: gyro ``rad/s``, ``deg/s``; accel ``m/s^2`` (``m/s2``), ``g`` (9.80665 m/s^2).
    """
    if text is None:
        return 1.0, 1.0
    items = dict(text) if isinstance(text, Mapping) else _pairs(text, "--units")
    gyro, accel = 1.0, 1.0
    for key, unit in items.items():
        u = unit.strip().lower().replace(" ", "")
        if key in ("gyro", "w"):
            if u not in _GYRO_UNITS:
                raise IbiscapeError(f"unknown gyro unit {unit!r}; use one of {', '.join(_GYRO_UNITS)}")
            gyro = _GYRO_UNITS[u]
        elif key in ("accel", "a"):
            if u not in _ACCEL_UNITS:
                raise IbiscapeError(f"unknown accel unit {unit!r}; use one of {', '.join(_ACCEL_UNITS)}")
            accel = _ACCEL_UNITS[u]
        else:
            raise IbiscapeError(f"unknown --units key {key!r}; use gyro=... and accel=...")
    return gyro, accel


def parse_columns(text: str | Mapping[str, str | int] | None) -> dict[str, str | int]:
    """Column mapping from ``"t=0,w_x=1,...,a_z=6"`` (indices) or names of the header row.

    Keys: ``t`` (ns) or ``t_s`` (seconds), and the six axes ``w_x w_y w_z a_x a_y a_z``
    (``wx gx ax`` spellings are accepted).  Values: 0-based column numbers or header names.
    """
    if text is None:
        return {}
    raw = dict(text) if isinstance(text, Mapping) else _pairs(text, "--columns")
    alias = {"wx": "w_x", "wy": "w_y", "wz": "w_z", "gx": "w_x", "gy": "w_y", "gz": "w_z",
             "ax": "a_x", "ay": "a_y", "az": "a_z", "t_ns": "t"}
    out: dict[str, str | int] = {}
    for key, val in raw.items():
        k = alias.get(key.lower(), key.lower())
        if k not in (*AXES, "t", "t_s"):
            raise IbiscapeError(f"unknown --columns key {key!r}; use t (ns) or t_s, w_x .. a_z")
        v: str | int = val
        if isinstance(val, str) and val.strip().lstrip("-").isdigit():
            v = int(val)
        out[k] = v
    missing = [a for a in AXES if a not in out]
    if missing:
        raise IbiscapeError(f"--columns lacks {', '.join(missing)}; map all six axes")
    return out


def _pairs(text: str, option: str) -> dict[str, str]:
    out = {}
    for part in text.split(","):
        if not part.strip():
            continue
        if "=" not in part:
            raise IbiscapeError(f"{option}: expected key=value pairs separated by commas, got {part!r}")
        k, v = part.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def mirror_ibiscape_imu(gyro_rad_s: npt.ArrayLike,
                        accel_m_s2: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Convert IMU samples between CARLA's left-handed frame and our right-handed one.

    The map is its own inverse: ``w -> -S w = (-w_x, w_y, -w_z)``, ``a -> S a = (a_x, -a_y,
    a_z)`` with ``S = diag(1, -1, 1)`` (derivation in the module docstring).

    Parameters
    ----------
    gyro_rad_s : array_like, shape (N, 3)
        Angular rate, rad/s.
    accel_m_s2 : array_like, shape (N, 3)
        Specific force, m/s^2.

    Returns
    -------
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        New float64 arrays (the inputs are not modified).
    """
    g = np.asarray(gyro_rad_s, dtype=np.float64)
    a = np.asarray(accel_m_s2, dtype=np.float64)
    return g * IBISCAPE_IMU_SIGNS[:3], a * IBISCAPE_IMU_SIGNS[3:]


def _check_frame(frame: str) -> bool:
    """True when ``frame`` asks for CARLA's (IBISCape) frame."""
    if frame not in IMU_FRAMES:
        raise IbiscapeError(f"unknown IMU frame {frame!r}; use one of {', '.join(IMU_FRAMES)}")
    return frame == "ibiscape"


# ---------------------------------------------------------------------------------------------
# timing


class _TimingAccumulator:
    """Streaming monotonicity / gap / jitter statistics over int64 ns stamps."""

    def __init__(self, path: str, first_line: int):
        self.path = path
        self.first_line = first_line  # file line of row 0
        self.prev: int | None = None
        self.median: float | None = None
        self.n = 0
        self.n_gaps = 0
        self.missing = 0
        self.largest = 0
        self.sum_dev = 0.0
        self.sum_dev2 = 0.0
        self.n_ok = 0
        self.first_gap_row: int | None = None

    def add(self, stamps_ns: np.ndarray) -> None:
        t = np.asarray(stamps_ns, dtype=np.int64)
        if t.size == 0:
            return
        dt = np.diff(t) if self.prev is None else np.diff(t, prepend=self.prev)
        row0 = self.n + (1 if self.prev is None else 0)  # row index of dt[0]'s later sample
        bad = np.flatnonzero(dt <= 0)
        if bad.size:
            r = row0 + int(bad[0])
            raise FormatError(
                self.path,
                f"timestamps are not strictly increasing (interval {int(dt[bad[0]])} ns to the "
                "previous row); sort the file or remove duplicate rows",
                line=self.first_line + r,
            )
        if self.median is None and dt.size:
            self.median = float(np.median(dt[: 1 << 20]))
        if self.median is not None and dt.size:
            med = self.median
            gap = dt > 1.5 * med
            if gap.any():
                if self.first_gap_row is None:
                    self.first_gap_row = row0 + int(np.flatnonzero(gap)[0])
                self.n_gaps += int(gap.sum())
                self.missing += int(np.sum(np.round(dt[gap] / med) - 1))
            self.largest = max(self.largest, int(dt.max()))
            dev = dt[~gap] - med
            self.sum_dev += float(dev.sum())
            self.sum_dev2 += float(np.dot(dev, dev))
            self.n_ok += int(dev.size)
        self.prev = int(t[-1])
        self.n += t.size

    def result(self) -> ImuTiming:
        if self.median is None:
            raise FormatError(self.path, f"only {self.n} sample(s); an Allan deviation needs thousands")
        mean = self.sum_dev / max(self.n_ok, 1)
        jitter = math.sqrt(max(self.sum_dev2 / max(self.n_ok, 1) - mean * mean, 0.0))
        return ImuTiming(
            has_stamps=True,
            median_dt_s=self.median * 1e-9,
            n_gaps=self.n_gaps,
            missing_samples=self.missing,
            missing_fraction=self.missing / (self.n + self.missing),
            largest_gap_s=self.largest * 1e-9,
            jitter_s=jitter * 1e-9,
            first_gap_line=None if self.first_gap_row is None else self.first_line + self.first_gap_row,
        )


def _no_stamp_timing(path: str, rate_hz: float | None, what: str) -> ImuTiming:
    if rate_hz is None or not rate_hz > 0:
        raise FormatError(path, f"{what} has no timestamps; give the sample rate (--rate-hz)")
    return ImuTiming(has_stamps=False, median_dt_s=1.0 / rate_hz)


def _finish(path: str, samples: np.ndarray | None, n: int, timing: ImuTiming,
            rate_hz: float | None, **kw: Any) -> ImuRecord:
    rate = 1.0 / timing.median_dt_s if timing.has_stamps else float(rate_hz)  # type: ignore[arg-type]
    if n < 3:
        raise FormatError(path, f"only {n} sample(s); an Allan deviation needs thousands")
    return ImuRecord(path=path, n_samples=n, rate_hz=rate, timing=timing, samples=samples, **kw)


# ---------------------------------------------------------------------------------------------
# readers


def read_imu(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    columns: str | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    rostopic: str | None = None,
    rate_hz: float | None = None,
    spill_bytes: int = SPILL_BYTES,
) -> ImuRecord:
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

    Raises
    ------
    FormatError
        Naming the file and 1-based line: non-numeric rows, wrong column count, non-increasing
        timestamps, missing keys or columns, too few samples.
    FileNotFoundError
        The file does not exist.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(2, "No such file or directory", str(p))
    f = (fmt or _guess_format(p)).lower()
    gscale, ascale = parse_units(units)
    cols = parse_columns(columns)
    if f in ("euroc", "csv", "ibiscape"):
        rec = _read_csv(p, cols, spill_bytes, rate_hz,
                        signs=IBISCAPE_IMU_SIGNS if f == "ibiscape" else None)
    elif f == "npy":
        rec = _read_npy(p, rate_hz)
    elif f == "npz":
        rec = _read_npz(p, rate_hz)
    elif f == "parquet":
        rec = _read_parquet(p, cols, rate_hz)
    elif f == "rosbag":
        rec = _read_bag(p, rostopic)
    else:
        raise IbiscapeError(f"unknown IMU format {fmt!r}; use one of {', '.join(FORMATS)}")
    if (gscale, ascale) != (1.0, 1.0):
        if rec.samples is None:
            raise IbiscapeError(f"{p}: --units is not supported for records read from disk in chunks")
        s = rec.samples.copy()
        s[:, :3] *= gscale
        s[:, 3:] *= ascale
        rec = ImuRecord(path=rec.path, n_samples=rec.n_samples, rate_hz=rec.rate_hz,
                        timing=rec.timing, rostopic=rec.rostopic, samples=s)
    return rec


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
    raise FormatError(p, f"cannot tell the format from the suffix {suf!r}; give --format "
                      f"({', '.join(FORMATS)})")


def _in_ibiscape_sequence(p: Path) -> bool:
    """``<seq>/other_sensors/imu*.csv`` next to ``<seq>/vehicle_gt/``: the IBISCape layout."""
    return (p.suffix.lower() == ".csv" and p.name.lower().startswith("imu")
            and p.parent.name == "other_sensors" and (p.parent.parent / "vehicle_gt").is_dir())


def _header_lines(p: Path) -> tuple[int, list[str] | None]:
    """Count leading lines that are not numeric rows; return the last one split as names."""
    names = None
    n = 0
    with open(p, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            s = line.strip()
            if not s:
                n += 1
                continue
            first = s.split(",")[0].strip()
            try:
                float(first)
                break
            except ValueError:
                names = [c.strip().lstrip("#").strip() for c in s.split(",")]
                n += 1
            if n > 50:
                break
    return n, names


def _diagnose(p: Path, start_line: int, n_fields: int) -> FormatError:
    """Find the first bad line at or after ``start_line`` (1-based) of a CSV."""
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh, start=1):
            if i < start_line or not line.strip():
                continue
            parts = line.rstrip("\r\n").split(",")
            if parts and not parts[-1].strip() and len(parts) == n_fields + 1:
                parts = parts[:-1]  # trailing comma
            if len(parts) != n_fields:
                return FormatError(p, f"expected {n_fields} comma-separated columns, got "
                                   f"{len(parts)}; fix or delete this row", line=i)
            for j, v in enumerate(parts):
                try:
                    x = float(v)
                except ValueError:
                    return FormatError(p, f"column {j + 1} is not a number ({v.strip()[:30]!r}); "
                                       "fix or delete this row", line=i)
                if not math.isfinite(x):
                    return FormatError(p, f"column {j + 1} is not finite ({v.strip()!r})", line=i)
    return FormatError(p, "unreadable CSV row; check the delimiter (comma expected)", line=start_line)


def _resolve(cols: Mapping[str, str | int], names: list[str] | None, n_fields: int,
             p: Path) -> tuple[int | None, bool, list[int]]:
    """Indices of (time column, time-in-seconds?, six axis columns)."""
    if not cols:
        if n_fields < 7:
            raise FormatError(p, f"expected 7 columns (timestamp ns, w_x w_y w_z rad/s, a_x a_y a_z "
                              f"m/s^2), got {n_fields}; give --columns for another layout", line=None)
        return 0, False, list(range(1, 7))

    def idx(v: str | int) -> int:
        if isinstance(v, int):
            if not 0 <= v < n_fields:
                raise FormatError(p, f"--columns index {v} is outside the file's {n_fields} columns")
            return v
        if names is None or v not in names:
            raise FormatError(p, f"--columns names {v!r}, which is not in the header "
                              f"({', '.join(names or [])})")
        return names.index(v)

    t_key = "t" if "t" in cols else ("t_s" if "t_s" in cols else None)
    t = idx(cols[t_key]) if t_key else None
    return t, t_key == "t_s", [idx(cols[a]) for a in AXES]


def _read_csv(p: Path, cols: Mapping[str, str | int], spill_bytes: int,
              rate_hz: float | None, *, signs: np.ndarray | None = None) -> ImuRecord:
    import pandas as pd

    skip, names = _header_lines(p)
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh):
            if i == skip:
                first_row = line
                break
        else:
            raise FormatError(p, "no data rows; an Allan deviation needs thousands of samples")
    n_fields = len(first_row.rstrip("\r\n").rstrip().rstrip(",").split(","))
    t_col, t_in_s, axis_cols = _resolve(cols, names, n_fields, p)
    if t_col is None:
        timing_acc = None
    else:
        timing_acc = _TimingAccumulator(str(p), first_line=skip + 1)
    spill = p.stat().st_size > spill_bytes
    keep: tempfile.TemporaryDirectory[str] | None = None
    parts: list[np.ndarray] = []
    writer = None
    if spill:
        keep = tempfile.TemporaryDirectory(prefix="ibiscape-imu-")
        spill_path = os.path.join(keep.name, "imu.npy")
        writer = _NpyStreamWriter(spill_path, 6)
    n = 0
    try:
        # integer ns stamps are parsed exactly (float64 would round 1.4e18 ns to 256 ns)
        fields = first_row.split(",")
        int_time = t_col is not None and not t_in_s and fields[t_col].strip().isdigit()
        dtypes: dict[int, Any] = {i: np.float64 for i in range(n_fields)}
        if int_time:
            dtypes[t_col] = np.int64  # type: ignore[index]
        reader = pd.read_csv(p, header=None, skiprows=skip, dtype=dtypes, engine="c",
                             chunksize=_CHUNK_ROWS, skip_blank_lines=True)
        while True:
            try:
                chunk = next(reader)
            except StopIteration:
                break
            except (ValueError, pd.errors.ParserError):
                raise _diagnose(p, skip + 1 + n, n_fields) from None
            if chunk.shape[1] != n_fields:
                raise _diagnose(p, skip + 1 + n, n_fields)
            arr = chunk.to_numpy(dtype=np.float64)
            if not np.isfinite(arr).all():
                raise _diagnose(p, skip + 1 + n, n_fields)
            if timing_acc is not None:
                tcol = np.asarray(chunk.iloc[:, t_col])  # type: ignore[index]
                timing_acc.add(np.round(tcol * 1e9) if t_in_s else tcol)
            data = arr[:, axis_cols]
            if signs is not None:
                data = data * signs
            if writer is not None:
                writer.write(data)
            else:
                parts.append(np.ascontiguousarray(data))
            n += arr.shape[0]
    except BaseException:
        if writer is not None:
            writer.close()
        if keep is not None:
            keep.cleanup()
        raise
    timing = timing_acc.result() if timing_acc is not None else _no_stamp_timing(str(p), rate_hz, "the CSV")
    if writer is not None:
        writer.close()
        assert keep is not None
        hdr = _npy_header(writer.path)
        rec = _finish(str(p), None, n, timing, rate_hz, _npy=(writer.path, hdr[0], hdr[1], 6, 0),
                      _keep=keep)
        weakref.finalize(rec, keep.cleanup)
        return rec
    samples = np.concatenate(parts, axis=0) if parts else np.zeros((0, 6))
    return _finish(str(p), samples, n, timing, rate_hz)


def _npy_header(path: str) -> tuple[int, np.dtype[Any], tuple[int, ...], bool]:
    with open(path, "rb") as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        except ValueError as e:
            raise FormatError(path, f"not a valid .npy file ({e})") from None
        return fh.tell(), dtype, shape, fortran


def _npy_blocks(fname: str, offset: int, dtype: np.dtype[Any], width: int, n_rows: int,
                chunk_rows: int) -> Iterator[np.ndarray]:
    with open(fname, "rb") as fh:
        fh.seek(offset)
        buf = np.empty((min(chunk_rows, max(n_rows, 1)), width), dtype=dtype)
        done = 0
        while done < n_rows:
            rows = min(chunk_rows, n_rows - done)
            view = buf[:rows]
            got = fh.readinto(view.data.cast("B"))
            if got != view.nbytes:
                raise FormatError(fname, f"file ends after {done + (got or 0) // (width * dtype.itemsize)} "
                                  f"of {n_rows} rows; it is truncated")
            yield view
            done += rows


def _read_npy(p: Path, rate_hz: float | None) -> ImuRecord:
    offset, dtype, shape, fortran = _npy_header(str(p))
    if dtype.hasobject or dtype.kind not in "fiu":
        raise FormatError(p, f"expected a numeric array, got dtype {dtype}")
    if len(shape) != 2 or shape[1] not in (6, 7):
        raise FormatError(p, f"expected shape (N, 7) [t_ns, w_xyz, a_xyz] or (N, 6), got {shape}")
    n, width = int(shape[0]), int(shape[1])
    if fortran:
        arr = np.load(p, allow_pickle=False)
        arr = np.ascontiguousarray(arr)
        return _from_array(p, arr, rate_hz)
    first = width - 6
    if first:
        acc = _TimingAccumulator(str(p), first_line=1)
        for block in _npy_blocks(str(p), offset, dtype, width, n, _CHUNK_ROWS):
            acc.add(block[:, 0].astype(np.int64))
        timing = acc.result()
    else:
        timing = _no_stamp_timing(str(p), rate_hz, "an (N, 6) .npy")
    for block in _npy_blocks(str(p), offset, dtype, width, min(n, _CHUNK_ROWS), _CHUNK_ROWS):
        if not np.isfinite(block[:, first:].astype(np.float64)).all():
            r = int(np.argwhere(~np.isfinite(block[:, first:].astype(np.float64)))[0][0])
            raise FormatError(p, "sample is not a finite number", line=r + 1)
    return _finish(str(p), None, n, timing, rate_hz, _npy=(str(p), offset, dtype, width, first))


def _from_array(p: Path, arr: np.ndarray, rate_hz: float | None) -> ImuRecord:
    arr = np.asarray(arr)
    if arr.ndim != 2 or arr.shape[1] not in (6, 7):
        raise FormatError(p, f"expected shape (N, 7) [t_ns, w_xyz, a_xyz] or (N, 6), got {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise FormatError(p, f"expected a numeric array, got dtype {arr.dtype}")
    first = arr.shape[1] - 6
    data = np.asarray(arr[:, first:], dtype=np.float64)
    return _from_parts(p, arr[:, 0] if first else None, data, rate_hz)


def _from_parts(p: Path, stamps: np.ndarray | None, data: np.ndarray, rate_hz: float | None,
                **kw: Any) -> ImuRecord:
    bad = ~np.isfinite(data)
    if bad.any():
        r = int(np.argwhere(bad)[0][0])
        raise FormatError(p, f"sample of axis {AXES[int(np.argwhere(bad)[0][1])]} is not a finite "
                          "number", line=r + 1)
    if stamps is not None:
        acc = _TimingAccumulator(str(p), first_line=1)
        acc.add(np.asarray(stamps).astype(np.int64))
        timing = acc.result()
    else:
        timing = _no_stamp_timing(str(p), rate_hz, "the file")
    return _finish(str(p), np.ascontiguousarray(data), data.shape[0], timing, rate_hz, **kw)


def _read_npz(p: Path, rate_hz: float | None) -> ImuRecord:
    try:
        with np.load(p, allow_pickle=False) as z:
            keys = set(z.files)
            if {"gyro_rad_s", "accel_m_s2"} <= keys:
                g, a = z["gyro_rad_s"], z["accel_m_s2"]
                if g.shape != a.shape or g.ndim != 2 or g.shape[1] != 3:
                    raise FormatError(p, f"gyro_rad_s {g.shape} and accel_m_s2 {a.shape} must both "
                                      "be (N, 3)")
                stamps = z["stamps_ns"] if "stamps_ns" in keys else None
                if stamps is not None and stamps.shape != (g.shape[0],):
                    raise FormatError(p, f"stamps_ns has shape {stamps.shape}, expected ({g.shape[0]},)")
                return _from_parts(p, stamps, np.concatenate([g, a], axis=1).astype(np.float64),
                                   rate_hz)
            if "data" in keys:
                return _from_array(p, z["data"], rate_hz)
    except (ValueError, OSError) as e:
        if isinstance(e, FileNotFoundError):
            raise
        raise FormatError(p, f"not a readable .npz without pickled objects ({e})") from None
    raise FormatError(p, f"expected keys stamps_ns, gyro_rad_s, accel_m_s2 (or data), found "
                      f"{', '.join(sorted(keys)) or 'none'}")


def _read_parquet(p: Path, cols: Mapping[str, str | int], rate_hz: float | None) -> ImuRecord:
    import pandas as pd

    try:
        df = pd.read_parquet(p)
    except Exception as e:  # pyarrow raises many types for a broken file
        raise FormatError(p, f"not a readable parquet file ({type(e).__name__}: {e})") from None
    names = [str(c) for c in df.columns]
    if not cols:
        norm = {n.lstrip("#").split(" ")[0].split("[")[0].strip(): n for n in names}
        t_name = next((norm[k] for k in ("timestamp", "stamps_ns", "t", "t_ns") if k in norm), None)
        missing = [a for a in AXES if a not in norm]
        if missing:
            raise FormatError(p, f"columns {', '.join(missing)} not found (have {', '.join(names)}); "
                              "give --columns")
        t_idx = None if t_name is None else names.index(t_name)
        axis_idx = [names.index(norm[a]) for a in AXES]
        t_s = False
    else:
        t_idx, t_s, axis_idx = _resolve(cols, names, len(names), p)
    arr = df.to_numpy()
    try:
        data = arr[:, axis_idx].astype(np.float64)
        stamps = None if t_idx is None else arr[:, t_idx].astype(np.float64)
    except (TypeError, ValueError):
        raise FormatError(p, "a mapped column is not numeric") from None
    if stamps is not None and t_s:
        stamps = np.round(stamps * 1e9)
    return _from_parts(p, stamps, data, rate_hz)


def _read_bag(p: Path, rostopic: str | None) -> ImuRecord:
    from rosbags.highlevel import AnyReader

    bag_path = p.parent if p.suffix.lower() in (".db3", ".mcap") else p
    try:
        reader_cm = AnyReader([bag_path])
        reader = reader_cm.__enter__()
    except Exception as e:
        raise FormatError(p, f"not a readable ROS bag ({type(e).__name__}: {e})") from None
    try:
        imu_topics = sorted({c.topic for c in reader.connections if c.msgtype == "sensor_msgs/msg/Imu"})
        if rostopic is None:
            if len(imu_topics) != 1:
                raise FormatError(p, f"{len(imu_topics)} sensor_msgs/Imu topics "
                                  f"({', '.join(imu_topics) or 'none'}); choose one with --rostopic")
            rostopic = imu_topics[0]
        conns = [c for c in reader.connections if c.topic == rostopic]
        if not conns:
            raise FormatError(p, f"topic {rostopic!r} not in the bag (IMU topics: "
                              f"{', '.join(imu_topics) or 'none'})")
        if conns[0].msgtype != "sensor_msgs/msg/Imu":
            raise FormatError(p, f"topic {rostopic!r} carries {conns[0].msgtype}, not sensor_msgs/Imu")
        n = sum(c.msgcount for c in conns)
        stamps = np.empty(n, dtype=np.int64)
        data = np.empty((n, 6))
        i = 0
        # one deserialisation per message is inherent to the bag format
        for conn, _t, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            st = msg.header.stamp
            stamps[i] = int(st.sec) * 1_000_000_000 + int(st.nanosec)
            w, a = msg.angular_velocity, msg.linear_acceleration
            data[i] = (w.x, w.y, w.z, a.x, a.y, a.z)
            i += 1
    finally:
        reader_cm.__exit__(None, None, None)
    stamps, data = stamps[:i], data[:i]
    return _from_parts(p, stamps, data, None, rostopic=rostopic)


# ---------------------------------------------------------------------------------------------
# writers


class _NpyStreamWriter:
    """Write an (N, width) float64 .npy row block by row block; the header is rewritten at close."""

    def __init__(self, path: str, width: int):
        self.path = path
        self.width = width
        self.rows = 0
        self.fh = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._header(reserve=True)

    def _header(self, reserve: bool = False) -> None:
        # fixed 128-byte v1.0 header, so that the final row count fits in the same space
        text = repr({"descr": "<f8", "fortran_order": False, "shape": (self.rows, self.width)})
        body = text.ljust(128 - 10 - 1) + "\n"
        self.fh.seek(0)
        self.fh.write(b"\x93NUMPY\x01\x00" + len(body).to_bytes(2, "little") + body.encode("latin1"))
        if reserve:
            self.data_offset = self.fh.tell()

    def write(self, block: np.ndarray) -> None:
        b = np.ascontiguousarray(block, dtype="<f8")
        if b.ndim != 2 or b.shape[1] != self.width:
            raise ValueError(f"expected blocks of width {self.width}, got {b.shape}")
        self.fh.write(b.data.cast("B"))
        self.rows += b.shape[0]

    def close(self) -> None:
        if self.fh.closed:
            return
        end = self.fh.tell()
        self._header()
        self.fh.seek(end)
        self.fh.close()


def write_imu_npy(path: str | os.PathLike[str], blocks: Iterable[np.ndarray], *, width: int = 7) -> int:
    """Write row blocks (each (rows, width), e.g. ``[t_ns, w_xyz, a_xyz]``) to one float64 ``.npy``,
    atomically and in bounded memory.  Returns the number of rows written."""
    with contextlib.ExitStack() as stack:
        from ._atomic import atomic_output_path

        tmp = stack.enter_context(atomic_output_path(path))
        w = _NpyStreamWriter(str(tmp), width)
        try:
            for b in blocks:
                w.write(b)
        finally:
            w.close()
        return w.rows


def write_imu_csv(path: str | os.PathLike[str], stamps_ns: np.ndarray, gyro_rad_s: np.ndarray,
                  accel_m_s2: np.ndarray, *, frame: str = "right-handed") -> None:
    """Write the EuRoC/IBISCape IMU csv (gyro first, 17 significant digits), atomically.

    Parameters
    ----------
    stamps_ns : ndarray of int64, shape (N,)
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        Samples in OUR right-handed frame, rad/s and m/s^2.
    frame : {"right-handed", "ibiscape"}
        ``"ibiscape"`` writes CARLA's left-handed frame like the real dataset (``w_x, w_z, a_y``
        negated; :func:`read_imu` with ``fmt="ibiscape"`` converts back).
    """
    import pandas as pd

    mirror = _check_frame(frame)
    t = np.asarray(stamps_ns, dtype=np.int64)
    g = np.asarray(gyro_rad_s, dtype=np.float64)
    a = np.asarray(accel_m_s2, dtype=np.float64)
    if g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise IbiscapeError(f"expected (N,) stamps and (N, 3) gyro/accel, got {t.shape}, {g.shape}, {a.shape}")
    if mirror:
        g, a = mirror_ibiscape_imu(g, a)
    df = pd.DataFrame(np.concatenate([g, a], axis=1))
    df.insert(0, "t", t)
    with atomic_write(path) as fh:
        fh.write(_EUROC_HEADER + "\n")
        df.to_csv(fh, header=False, index=False, float_format="%.17g", lineterminator="\n")


def write_kalibr_imu_yaml(
    path: str | os.PathLike[str],
    *,
    accelerometer_noise_density: float,
    accelerometer_random_walk: float,
    gyroscope_noise_density: float,
    gyroscope_random_walk: float,
    update_rate_hz: float,
    rostopic: str = "/imu0",
    comments: Sequence[str] = (),
) -> None:
    """Write a Kalibr ``imu.yaml`` (continuous-time densities), atomically.

    NaN values (a random walk the record could not show) are refused: Kalibr needs numbers.
    ``comments`` are written as ``#`` lines at the top (e.g. the per-sample sigmas).
    """
    import yaml

    vals = {
        "accelerometer_noise_density": accelerometer_noise_density,
        "accelerometer_random_walk": accelerometer_random_walk,
        "gyroscope_noise_density": gyroscope_noise_density,
        "gyroscope_random_walk": gyroscope_random_walk,
    }
    bad = [k for k, v in vals.items() if not (math.isfinite(v) and v > 0)]
    if bad:
        raise IbiscapeError(f"cannot write {path}: {', '.join(bad)} not determined (NaN); "
                            "record longer or give the fit ranges")
    doc: dict[str, Any] = {k: float(v) for k, v in vals.items()}
    doc["rostopic"] = str(rostopic)
    doc["update_rate"] = float(update_rate_hz)
    with atomic_write(path) as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        fh.write(yaml.safe_dump(doc, sort_keys=False))


def read_kalibr_imu_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a Kalibr ``imu.yaml`` (``yaml.safe_load``); checks the six keys."""
    import yaml

    with open(path, encoding="utf-8") as fh:
        try:
            doc = yaml.safe_load(fh)
        except yaml.YAMLError as e:
            raise FormatError(path, f"not valid YAML ({e})") from None
    keys = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
            "gyroscope_random_walk", "rostopic", "update_rate")
    if not isinstance(doc, dict) or any(k not in doc for k in keys):
        raise FormatError(path, f"expected the keys {', '.join(keys)}")
    return doc
