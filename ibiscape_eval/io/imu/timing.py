"""Timestamp statistics (monotonicity, gaps, jitter) and building :class:`ImuRecord` objects."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError, Remedy
from ibiscape_eval.core.imu import AXES, ImuRecord, ImuTiming

__all__ = ["MAX_ABS_SAMPLE", "TimingAccumulator", "check_samples", "check_stamp_dtype",
           "finish_record", "no_stamp_timing", "record_from_array", "record_from_parts"]

#: Largest believable IMU reading, rad/s or m/s^2 (no MEMS or FOG IMU comes near it).  Larger
#: values are damaged data: squared in the Allan variance they overflow to inf.
MAX_ABS_SAMPLE = 1.0e6


class TimingAccumulator:
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


def check_samples(p: str | Path, data: np.ndarray, first_line: int = 1) -> None:
    """Refuse non-finite samples and samples beyond :data:`MAX_ABS_SAMPLE` (line of the first)."""
    bad = ~np.isfinite(data)
    what = "is not a finite number"
    if not bad.any():
        bad = np.abs(data) > MAX_ABS_SAMPLE
        what = f"is beyond {MAX_ABS_SAMPLE:g} (rad/s or m/s^2): damaged data"
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        axis = AXES[c] if data.ndim == 2 and data.shape[1] == len(AXES) else f"column {c}"
        raise FormatError(p, f"sample of axis {axis} {what}; fix or remove the row",
                          line=first_line + r)


def check_stamp_dtype(p: str | Path, stamps: np.ndarray) -> None:
    """Refuse floating-point stamps too coarse for the sample interval (float32 ns stamps of a
    1e12 ns clock are quantised to ~65 us, which turns 200 Hz into 200.774 Hz)."""
    t = np.asarray(stamps)
    if t.dtype.kind != "f" or t.size < 2:
        return
    if not np.isfinite(t).all():
        r = int(np.flatnonzero(~np.isfinite(t))[0])
        raise FormatError(p, "timestamp is not a finite number", line=r + 1)
    if np.abs(t).max() >= 2.0**63:
        raise FormatError(p, "timestamps beyond int64 nanoseconds (year 2262); store int64 ns")
    step = float(np.spacing(np.abs(t).max().astype(t.dtype)))
    dt = np.diff(t[: 1 << 16].astype(np.float64))
    med = float(np.median(dt)) if dt.size else 0.0
    if med > 0 and step > 1e-3 * med:
        raise FormatError(p, f"timestamps stored as {t.dtype} are quantised to {step:.4g} ns at "
                          f"these values, {100 * step / med:.2g} % of the {med:.4g} ns interval; "
                          "store them as int64 ns (or float64)")


def no_stamp_timing(path: str, rate_hz: float | None, what: str) -> ImuTiming:
    if rate_hz is None:
        raise FormatError(path, f"{what} has no timestamps; give the sample rate ({{0}})",
                          hint=(Remedy("rate_hz"),))
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise FormatError(path, f"{what} has no timestamps and {{0}} is not a positive number of "
                          "Hz; give the sample rate, e.g. {1}",
                          hint=(Remedy("rate_hz", f"{rate_hz:g}"), Remedy("rate_hz", "200")))
    return ImuTiming(has_stamps=False, median_dt_s=1.0 / rate_hz)


def finish_record(path: str, samples: np.ndarray | None, n: int, timing: ImuTiming,
            rate_hz: float | None, **kw: Any) -> ImuRecord:
    rate = 1.0 / timing.median_dt_s if timing.has_stamps else float(rate_hz)  # type: ignore[arg-type]
    if n < 3:
        raise FormatError(path, f"only {n} sample(s); an Allan deviation needs thousands")
    if timing.has_stamps and rate_hz is not None:
        import warnings

        from ibiscape_eval.core.errors import IbiscapeWarning

        warnings.warn(f"{path}: --rate-hz {rate_hz:g} ignored: the file has timestamps "
                      f"(median rate {rate:.6g} Hz)", IbiscapeWarning, stacklevel=2)
    return ImuRecord(path=path, n_samples=n, rate_hz=rate, timing=timing, samples=samples, **kw)


def record_from_array(p: Path, arr: np.ndarray, rate_hz: float | None) -> ImuRecord:
    arr = np.asarray(arr)
    if arr.ndim != 2 or arr.shape[1] not in (6, 7):
        raise FormatError(p, f"expected shape (N, 7) [t_ns, w_xyz, a_xyz] or (N, 6), got {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise FormatError(p, f"expected a numeric array, got dtype {arr.dtype}")
    first = arr.shape[1] - 6
    data = np.asarray(arr[:, first:], dtype=np.float64)
    if not first:
        return record_from_parts(p, None, data, rate_hz)
    from .columns import STAMP_UNITS, stamp_unit, with_layout

    stamps = arr[:, 0]
    unit, how = stamp_unit(stamps[:4000])
    if unit == "ns":
        return record_from_parts(p, stamps, data, rate_hz)
    scaled = np.round(np.asarray(stamps, dtype=np.float64) * STAMP_UNITS[unit])
    return with_layout(record_from_parts(p, scaled, data, rate_hz), None,
                       (f"timestamps read as {unit} ({how})",))


def record_from_parts(p: Path, stamps: np.ndarray | None, data: np.ndarray, rate_hz: float | None,
                **kw: Any) -> ImuRecord:
    check_samples(p, data)
    if stamps is not None:
        check_stamp_dtype(p, stamps)
        acc = TimingAccumulator(str(p), first_line=1)
        acc.add(np.asarray(stamps).astype(np.int64))
        timing = acc.result()
    else:
        timing = no_stamp_timing(str(p), rate_hz, "the file")
    return finish_record(str(p), np.ascontiguousarray(data), data.shape[0], timing, rate_hz, **kw)
