"""IMU value types: six-axis samples (:class:`ImuRecord`) and their timing report (:class:`ImuTiming`).

Readers live in :mod:`ibiscape_eval.io.imu`; a record read from a large file keeps its samples on
disk and hands them out chunk by chunk (:meth:`ImuRecord.iter_chunks`), so days of data stay in
bounded memory.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

__all__ = ["AXES", "CHUNK_ROWS", "ImuRecord", "ImuTiming", "RowSource"]

#: Axis names in the order of every record: gyro (rad/s) first, then accelerometer (m/s^2).
AXES = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
#: Rows per chunk handed out by :meth:`ImuRecord.iter_chunks` by default.
CHUNK_ROWS = 1 << 20


class RowSource(Protocol):
    """Samples kept outside memory: yields blocks of shape (rows, 6), gyro then accel, in order.

    A block may be a reused buffer: the consumer copies what it keeps.
    """

    def iter_rows(self, chunk_rows: int) -> Iterator[np.ndarray]: ...


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
    """Six-axis IMU samples, in memory or on disk (read chunk by chunk through a
    :class:`RowSource` that :mod:`ibiscape_eval.io.imu` provides).

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
    _source: RowSource | None = field(default=None, repr=False)

    @property
    def n_columns(self) -> int:
        return len(self.names)

    def iter_chunks(self, columns: Sequence[int], chunk_rows: int = CHUNK_ROWS) -> Iterator[np.ndarray]:
        """Yield float64 arrays of shape (rows, len(columns)) in order."""
        cols = list(columns)
        if self.samples is not None:
            for i in range(0, self.n_samples, chunk_rows):
                yield np.array(self.samples[i : i + chunk_rows, cols], dtype=np.float64)
            return
        assert self._source is not None
        for block in self._source.iter_rows(chunk_rows):
            yield np.asarray(block[:, cols], dtype=np.float64)

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
