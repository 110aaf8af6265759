"""Overlapping Allan deviation of rate samples (gyro, accelerometer), exact and streaming.

The estimator is the overlapping Allan variance of IEEE Std 952-1997 / NIST SP 1065 eq. (11),
computed from the integrated signal ``theta`` (the "phase"), exactly as Stable32 and
``allantools.oadev(data, rate=..., data_type="freq")`` do::

    sigma^2(tau) = sum_k (theta[k+2m] - 2 theta[k+m] + theta[k])^2 / (2 tau^2 (N - 2m)),
    tau = m / rate,  theta[0] = 0,  theta[j] = sum_{i<j} (y[i] - mean(y)) / rate

(N = number of samples + 1 phase points).  Subtracting the mean does not change the result in
exact arithmetic (a line in ``theta`` has no second difference); it keeps the cumulative sum small
so that long records lose no precision.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from ibiscape_eval.core.errors import DegenerateInputError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.core.numbers import finite_or_none

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    from matplotlib.figure import Figure

    from .fit import NoiseModel

__all__ = [
    "ONE_SIGMA_CI",
    "AllanResult",
    "ChunkedSamples",
    "allan_deviation",
    "default_averaging_factors",
    "edf_white_fm",
]

#: Probability content of +-1 sigma of a normal distribution, the default confidence level.
ONE_SIGMA_CI = math.erf(1.0 / math.sqrt(2.0))

#: Default memory for the integrated signal of the axes processed together (bytes).
DEFAULT_MEMORY_BUDGET = 2 * 1024**3


@runtime_checkable
class ChunkedSamples(Protocol):
    """A record too large for memory: ``n_samples`` rows of ``n_columns`` rate samples, read in
    order, chunk by chunk, as float64 arrays of shape (rows, len(columns))."""

    @property
    def n_samples(self) -> int: ...

    @property
    def n_columns(self) -> int: ...

    def iter_chunks(self, columns: Sequence[int]) -> Iterator[np.ndarray]: ...


@dataclass(frozen=True)
class _ArraySamples:
    data: np.ndarray  # (N, k), possibly a memmap
    chunk_rows: int = 1 << 20

    @property
    def n_samples(self) -> int:
        return int(self.data.shape[0])

    @property
    def n_columns(self) -> int:
        return int(self.data.shape[1])

    def iter_chunks(self, columns: Sequence[int]) -> Iterator[np.ndarray]:
        cols = list(columns)
        for i in range(0, self.n_samples, self.chunk_rows):
            yield np.asarray(self.data[i : i + self.chunk_rows, cols], dtype=np.float64)


@dataclass(frozen=True)
class AllanResult:
    """Overlapping Allan deviation of one or more axes.

    Attributes
    ----------
    taus_s : ndarray, shape (T,)
        Averaging times actually used, s: whole multiples ``m / rate_hz`` of the sample interval.
    m : ndarray of int64, shape (T,)
        Averaging factors (samples per cluster).
    adev : ndarray, shape (T, k)
        Allan deviation, one column per input column, in the unit of the input samples
        (rad/s for gyro, m/s^2 for accelerometer).
    n_terms : ndarray of int64, shape (T,)
        Number of overlapping second differences summed, ``N - 2m`` with N phase points.
    edf : ndarray, shape (T,)
        Equivalent degrees of freedom, white-FM (white rate noise) formula of NIST SP 1065
        Table 5 (Howe, Allan, Barnes 1981), as Stable32 and ``allantools.edf_simple(N, m, 0)``.
    adev_lo, adev_hi : ndarray, shape (T, k)
        Confidence bounds of ``adev`` at level ``ci`` from the chi-squared distribution with
        ``edf`` degrees of freedom (NIST SP 1065 eq. 45; ``allantools.confidence_interval``).
    ci : float
        Confidence level of the bounds (default: 0.683, one sigma).
    rate_hz : float
        Sample rate used, Hz.
    n_samples : int
        Number of rate samples per axis.
    names : tuple of str
        Axis names, one per column.
    requested_taus_s : ndarray or None
        The taus asked for (before rounding to the sample grid), if any.
    """

    taus_s: np.ndarray
    m: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray
    edf: np.ndarray
    adev_lo: np.ndarray
    adev_hi: np.ndarray
    ci: float
    rate_hz: float
    n_samples: int
    names: tuple[str, ...]
    requested_taus_s: np.ndarray | None = field(default=None)

    @property
    def duration_s(self) -> float:
        """Length of the record, s."""
        return self.n_samples / self.rate_hz

    def plot(self, model: NoiseModel | None = None, *, title: str = "overlapping Allan deviation"
             ) -> Figure:
        """The Allan deviation curves with their bands and the noise fit ``model`` (fitted with
        the defaults of :func:`~ibiscape_eval.imu.fit_noise_model` when not given); a new Figure."""
        from ibiscape_eval.report.plots import allan_figure

        from .fit import fit_noise_model

        return allan_figure(self, model or fit_noise_model(self), title=title)

    def __repr__(self) -> str:
        t = self.taus_s
        span = f"{t[0]:.3g}..{t[-1]:.4g} s" if t.size else "none"
        return (f"AllanResult({len(self.names)} axes {', '.join(self.names)}; {t.size} taus "
                f"{span}; {self.n_samples} samples at {self.rate_hz:.6g} Hz; ci={self.ci:g})")

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(repr(self))}</pre>"

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON document: the scalars and, per axis, the curve and its bounds as lists
        (NaN as null)."""

        def lst(a: np.ndarray) -> list[Any]:
            return [finite_or_none(v) for v in np.asarray(a, dtype=float)]

        return {
            "rate_hz": float(self.rate_hz),
            "n_samples": int(self.n_samples),
            "ci": float(self.ci),
            "taus_s": lst(self.taus_s),
            "edf": lst(self.edf),
            "axes": {n: {"adev": lst(self.adev[:, i]), "adev_lo": lst(self.adev_lo[:, i]),
                         "adev_hi": lst(self.adev_hi[:, i])} for i, n in enumerate(self.names)},
        }

    def to_frame(self) -> pd.DataFrame:
        """One row per tau: ``tau_s, m, n_terms, edf`` then ``adev_<name>``, ``adev_lo_<name>``,
        ``adev_hi_<name>`` for every axis."""
        import pandas as pd

        cols: dict[str, Any] = {
            "tau_s": self.taus_s,
            "m": self.m,
            "n_terms": self.n_terms,
            "edf": self.edf,
        }
        for i, name in enumerate(self.names):
            cols[f"adev_{name}"] = self.adev[:, i]
            cols[f"adev_lo_{name}"] = self.adev_lo[:, i]
            cols[f"adev_hi_{name}"] = self.adev_hi[:, i]
        return pd.DataFrame(cols)


def edf_white_fm(n_phase: int, m: np.ndarray) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping ADEV for white FM noise.

    NIST SP 1065 Table 5: ``edf = (3 (N-1) / (2m) - 2 (N-2) / N) * 4 m^2 / (4 m^2 + 5)`` with
    ``N`` phase points; clipped below at 1.
    """
    N = float(n_phase)
    mf = np.asarray(m, dtype=np.float64)
    edf = (3.0 * (N - 1.0) / (2.0 * mf) - 2.0 * (N - 2.0) / N) * (4.0 * mf**2 / (4.0 * mf**2 + 5.0))
    return np.maximum(edf, 1.0)


def default_averaging_factors(n_samples: int, *, points_per_decade: int = 10,
                              max_fraction: float = 0.25) -> np.ndarray:
    """Log-spaced averaging factors ``1 .. max_fraction * n_samples``, ``points_per_decade`` per
    decade, rounded to integers and de-duplicated (int64, ascending)."""
    m_max = max(1, int(max_fraction * n_samples))
    n_dec = math.log10(m_max) if m_max > 1 else 0.0
    n_pts = max(1, math.ceil(n_dec * points_per_decade) + 1)
    ms = np.unique(np.round(np.logspace(0.0, n_dec, n_pts)).astype(np.int64))
    return ms[(ms >= 1) & (ms <= m_max)]


def _factors_from_taus(taus_s: np.ndarray, rate_hz: float, n_samples: int) -> np.ndarray:
    ms = np.round(np.asarray(taus_s, dtype=np.float64) * rate_hz)
    if not np.all(np.isfinite(ms)):
        raise IbiscapeError("taus_s must be finite numbers of seconds")
    m_max = n_samples // 2  # at least one second difference: n_samples + 1 - 2m >= 1
    keep = (ms >= 1) & (ms <= m_max)
    dropped = np.asarray(taus_s)[~keep]
    if dropped.size:
        warnings.warn(
            f"{dropped.size} of {ms.size} taus are shorter than one sample interval "
            f"({1 / rate_hz:g} s) or longer than half the record ({m_max / rate_hz:g} s); "
            "they were left out",
            IbiscapeWarning,
            stacklevel=3,
        )
    out = np.unique(ms[keep].astype(np.int64))
    if out.size == 0:
        raise DegenerateInputError(
            f"none of the requested taus fits a record of {n_samples} samples at {rate_hz:g} Hz"
        )
    return out


def _as_source(samples: np.ndarray | ChunkedSamples) -> ChunkedSamples:
    """The samples as a :class:`ChunkedSamples` (an array gets a column axis if 1-D); refuses
    fewer than 3 samples."""
    if isinstance(samples, ChunkedSamples) and not isinstance(samples, np.ndarray):
        source: ChunkedSamples = samples
    else:
        arr = samples if isinstance(samples, np.ndarray) else np.asarray(samples)
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2:
            raise IbiscapeError(f"samples must have shape (N,) or (N, k), got {arr.shape}")
        source = _ArraySamples(arr)
    n = int(source.n_samples)
    if n < 3:
        raise DegenerateInputError(f"need at least 3 samples for an Allan deviation, got {n}")
    return source


def _axis_names(names: Sequence[str] | None, k: int) -> tuple[str, ...]:
    """The given names, or ``w_x .. a_z`` for six columns, else ``"0", "1", ...``."""
    if names is None:
        from ibiscape_eval.core.imu import AXES

        axis_names = AXES if k == len(AXES) else tuple(str(i) for i in range(k))
    else:
        axis_names = tuple(names)
    if len(axis_names) != k:
        raise IbiscapeError(f"{len(axis_names)} names for {k} columns")
    return axis_names


def _check_not_constant(adev: np.ndarray, names: tuple[str, ...], where: object) -> None:
    """Refuse an axis whose Allan deviation is 0 at every tau (``where``: the file, if known)."""
    for j, name in enumerate(names):
        if not np.any(adev[:, j] > 0):
            raise DegenerateInputError(
                (f"{where}: " if where else "") + f"axis {name!r} is constant (Allan deviation "
                "0): a real IMU always shows noise; check the column mapping or drop the axis"
            )


def _grouped_sums(source: ChunkedSamples, ms: np.ndarray, names: tuple[str, ...],
                  memory_budget_bytes: int,
                  progress: Callable[[int], None] | None) -> np.ndarray:
    """Second-difference sums (k, T) of every column, integrating as many columns at once as
    the memory budget allows (8 bytes per sample and axis), reading the input once per group."""
    n, k = int(source.n_samples), int(source.n_columns)
    sums = np.empty((k, ms.size))
    group = max(1, min(k, int(memory_budget_bytes // (8 * (n + 1)))))
    for g0 in range(0, k, group):
        cols = list(range(g0, min(k, g0 + group)))
        theta = _integrate(source, cols, n, names, progress)
        sums[cols] = _second_difference_sums(theta, ms)
        del theta
    return sums


def _chi2_bounds(adev: np.ndarray, edf: np.ndarray, ci: float) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper ``ci`` confidence bounds of ``adev`` from the chi-squared distribution
    with ``edf`` degrees of freedom per tau."""
    from scipy.stats import chi2

    lo_q = (1.0 - ci) / 2.0
    chi_lo = chi2.ppf(lo_q, edf)
    chi_hi = chi2.ppf(1.0 - lo_q, edf)
    return adev * np.sqrt(edf / chi_hi)[:, None], adev * np.sqrt(edf / chi_lo)[:, None]


def allan_deviation(
    samples: np.ndarray | ChunkedSamples, rate_hz: float, *,
    taus_s: Sequence[float] | np.ndarray | None = None, points_per_decade: int = 10,
    names: Sequence[str] | None = None, ci: float = ONE_SIGMA_CI,
    memory_budget_bytes: int = DEFAULT_MEMORY_BUDGET,
    progress: Callable[[int], None] | None = None,
) -> AllanResult:
    """Overlapping Allan deviation of rate samples (IEEE Std 952-1997, NIST SP 1065 eq. 11).

    Parameters
    ----------
    samples : ndarray, shape (N,) or (N, k), or ChunkedSamples
        Equally spaced rate samples (rad/s, m/s^2, ...), one column per axis.  A ``np.memmap``
        or any :class:`ChunkedSamples` is read in chunks, so records larger than memory work.
    rate_hz : float
        Sample rate, Hz.
    taus_s : array_like, optional
        Averaging times, s.  Rounded to whole multiples of ``1 / rate_hz`` (the result's
        ``taus_s`` says which were used); duplicates and taus outside
        ``[1 / rate_hz, N / (2 rate_hz)]`` are dropped with a warning.  Default: log-spaced from
        one sample to a quarter of the record, ``points_per_decade`` per decade.
    points_per_decade : int
        Density of the default taus.
    names : sequence of str, optional
        Axis names, used in messages, ``to_frame()`` and plots (default: the usual
        ``w_x, w_y, w_z, a_x, a_y, a_z`` for six columns, else ``"0", "1", ...``).
    ci : float
        Confidence level of ``adev_lo`` / ``adev_hi`` (default one sigma, 0.683).
    memory_budget_bytes : int
        Memory allowed for the integrated signals held at once (8 bytes per sample and axis);
        axes are processed in groups that fit, reading the input once per group.
    progress : callable, optional
        Called with the number of values (rows x axes) integrated as the work advances;
        the total is ``N k``.

    Returns
    -------
    AllanResult
        ``adev`` has shape (T, k), also for a 1-D input (k = 1).

    Raises
    ------
    DegenerateInputError
        Fewer than 3 samples, or an axis that is constant (zero Allan deviation).
    IbiscapeError
        Non-finite samples, bad rate.

    Notes
    -----
    Equal to ``allantools.oadev(y, rate=rate_hz, data_type="freq", taus=taus_s)`` to rounding.
    The sums for all taus are computed in one blocked pass over the integrated signal
    (numba, parallel over blocks), so the cost is O(N T) with the data read from memory once per
    block rather than once per tau.
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise IbiscapeError(f"rate_hz must be a positive number, got {rate_hz!r}")
    if not 0 < ci < 1:
        raise IbiscapeError(f"ci must be in (0, 1), got {ci!r}")
    source = _as_source(samples)
    n, k = int(source.n_samples), int(source.n_columns)
    axis_names = _axis_names(names, k)
    requested = None if taus_s is None else np.atleast_1d(np.asarray(taus_s, dtype=np.float64))
    ms = (default_averaging_factors(n, points_per_decade=points_per_decade) if requested is None
          else _factors_from_taus(requested, rate_hz, n))
    sums = _grouped_sums(source, ms, axis_names, memory_budget_bytes, progress)
    n_terms = (n + 1) - 2 * ms
    # allantools: dev = sqrt(s / (2 n)) / m * rate on phase in seconds; here theta is in samples
    # (not multiplied by 1/rate), so tau^2 = m^2 in those units.
    adev = (np.sqrt(sums / (2.0 * n_terms)) / ms).T  # (T, k)
    _check_not_constant(adev, axis_names, getattr(samples, "path", None))
    edf = edf_white_fm(n + 1, ms)
    adev_lo, adev_hi = _chi2_bounds(adev, edf, ci)
    return AllanResult(
        taus_s=ms / float(rate_hz), m=ms, adev=adev, n_terms=n_terms.astype(np.int64), edf=edf,
        adev_lo=adev_lo, adev_hi=adev_hi, ci=float(ci), rate_hz=float(rate_hz), n_samples=n,
        names=axis_names, requested_taus_s=requested,
    )


def _integrate(source: ChunkedSamples, cols: list[int], n: int, names: tuple[str, ...],
               progress: Callable[[int], None] | None) -> np.ndarray:
    """Cumulative sum of (y - c) for the columns ``cols``, shape (len(cols), n + 1), leading 0.

    ``c`` is the mean of the whole column when the input is in memory (as allantools), else the
    mean of the first chunk: any constant gives the same deviation, a near-mean one keeps the sums
    small.
    """
    theta = np.empty((len(cols), n + 1))
    theta[:, 0] = 0.0
    pos = 0
    offset: np.ndarray | None = None
    if isinstance(source, _ArraySamples) and not isinstance(source.data, np.memmap):
        offset = np.mean(np.asarray(source.data[:, cols], dtype=np.float64), axis=0)
    for chunk in source.iter_chunks(cols):
        rows = chunk.shape[0]
        if rows == 0:
            continue
        if pos + rows > n:
            raise IbiscapeError(f"the input yielded more than the announced {n} samples")
        finite = np.isfinite(chunk)
        if not finite.all():
            r, c = np.argwhere(~finite)[0]
            raise IbiscapeError(
                f"sample {pos + int(r)} of axis {names[cols[int(c)]]!r} is not a finite number"
            )
        if offset is None:
            offset = chunk.mean(axis=0)
        seg = theta[:, pos + 1 : pos + 1 + rows]
        np.cumsum((chunk - offset).T, axis=1, out=seg)
        seg += theta[:, pos : pos + 1]
        pos += rows
        if progress is not None:
            progress(rows * len(cols))
    if pos != n:
        raise IbiscapeError(f"the input yielded {pos} samples, {n} were announced")
    return theta


def _second_difference_sums(theta: np.ndarray, ms: np.ndarray) -> np.ndarray:
    from ._oadev_kernel import oadev_sums

    return np.asarray(oadev_sums(np.ascontiguousarray(theta), np.ascontiguousarray(ms)))
