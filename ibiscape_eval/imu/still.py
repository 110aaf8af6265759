"""Is this IMU record still?  A physics test before an Allan deviation is believed.

An Allan deviation reads sensor noise off a record of a sensor at rest; motion in the record is
read as noise (a driving car's yaw rate becomes a "white noise density" of 0.3 rad/s/sqrt(Hz)).
The test compares how much the window means move with what noise can explain:

1. The record is cut into short blocks of ``tau_0 = 0.1 s`` and windows of ``tau_w = 1 s``.
   The noise level at ``tau_0`` is the non-overlapping Allan deviation of the block means,
   taken robustly (median of the absolute differences, 1.4826 MAD / sqrt 2), so that
   intermittent motion does not raise it.
2. A still sensor's Allan deviation falls as ``tau^-1/2`` (white noise) down to its bias
   instability floor: at ``tau_w`` it is at most
   ``sqrt((sigma(tau_0) sqrt(tau_0 / tau_w))^2 + floor^2)``, with an allowance ``floor`` for
   bias instability and random walk at one second that exceeds consumer MEMS parts
   (:data:`GYRO_FLOOR_RAD_S`, :data:`ACCEL_FLOOR_M_S2`).
3. The measured (RMS) Allan deviation of the window means, per axis and for the accelerometer
   norm, must stay within :data:`MAX_RATIO` of that.  Motion (turns, acceleration, handling)
   moves the window means by orders of magnitude more: smooth motion grows as ``tau^+1``.
4. A still gyroscope averages its bias (< :data:`GYRO_MEAN_MAX_RAD_S`), a still accelerometer
   gravity (within :data:`GRAVITY_TOLERANCE` of 9.80665 m/s^2, a note beyond
   :data:`GRAVITY_NOTE`; skipped for gravity-free data).

:func:`check_still` refuses a record that fails, naming the numbers and ``--force``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import DegenerateInputError, Remedy

from .allan import ChunkedSamples

__all__ = [
    "ACCEL_FLOOR_M_S2",
    "GRAVITY_TOLERANCE",
    "GYRO_FLOOR_RAD_S",
    "GYRO_MEAN_MAX_RAD_S",
    "MAX_RATIO",
    "StillnessReport",
    "assess_stillness",
    "check_still",
    "forced_warning",
]

#: Allowance at tau = 1 s for bias instability, random walk and the room's vibration, rad/s
#: (a consumer MEMS gyro's bias instability of 20 deg/h is 1e-4 rad/s).
GYRO_FLOOR_RAD_S = 5e-4
#: The same for the accelerometer, m/s^2 (a consumer part's 0.1 mg is 1e-3 m/s^2).
ACCEL_FLOOR_M_S2 = 5e-3
#: Largest ratio of measured to still-explainable window-mean variation.
MAX_RATIO = 3.0
#: Largest gyroscope mean (norm) of a still IMU, rad/s: real biases reach ~0.1 rad/s.
GYRO_MEAN_MAX_RAD_S = 0.2
#: Largest relative distance of the accelerometer's mean norm from standard gravity (a wrong unit
#: is a factor 9.8 or 1000 off; a real, uncalibrated MPU-6050 at rest reads 0.91 g).
GRAVITY_TOLERANCE = 0.15
#: Beyond this relative distance a note says that the scale is off.
GRAVITY_NOTE = 0.03
#: Below this mean norm (m/s^2) the accelerometer is gravity-free (compensated or simulated).
NO_GRAVITY_M_S2 = 2.5
#: Fewer windows than this cannot tell motion from noise.
MIN_WINDOWS = 10
G = 9.80665
TAU_SHORT_S = 0.1
TAU_WINDOW_S = 1.0


@dataclass(frozen=True)
class StillnessReport:
    """What the stillness test measured (see the module docstring).

    Attributes
    ----------
    still : bool
        No reason to doubt that the IMU was at rest.
    tested : bool
        False when the record was too short to test (then ``still`` is True and a note says so).
    window_s, short_s : float
        ``tau_w`` and ``tau_0``, s (whole samples).
    n_windows : int
    gyro_mean_rad_s, accel_mean_m_s2 : tuple of float
        Means of the three axes.
    accel_norm_m_s2 : float
        Norm of the accelerometer mean.
    measured : tuple of float, shape (7,)
        RMS Allan deviation of the window means: w_x .. a_z (rad/s, m/s^2), then the
        accelerometer norm (m/s^2).
    explained : tuple of float, shape (7,)
        What noise and bias instability of a still IMU explain at ``window_s``, same order.
    worst : str
        Name of the quantity with the largest ratio ``measured / explained``.
    ratio : float
        That largest ratio.
    moving_fraction : float
        Fraction of window-to-window steps beyond 6 sigma of the explained variation.
    first_moving_s : float or None
        Time from the start of the first such step, s.
    reasons : tuple of str
        Why the record is not still, each with its numbers (empty when still).
    notes : tuple of str
    """

    still: bool
    tested: bool
    window_s: float
    short_s: float
    n_windows: int
    gyro_mean_rad_s: tuple[float, ...]
    accel_mean_m_s2: tuple[float, ...]
    accel_norm_m_s2: float
    measured: tuple[float, ...]
    explained: tuple[float, ...]
    worst: str
    ratio: float
    moving_fraction: float
    first_moving_s: float | None
    reasons: tuple[str, ...]
    notes: tuple[str, ...]

    NAMES = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z", "|a|")

    def message(self, path: str | os.PathLike[str] | None = None) -> str:
        """One line: the file, what was measured against what a still IMU shows, the way out."""
        head = f"{os.fspath(path)}: " if path is not None else ""
        return (f"{head}not a still IMU record: {'; '.join(self.reasons)}; an Allan deviation "
                "of a moving IMU reads the motion as noise: record the IMU at rest, cut the "
                "moving part, or pass {0} to analyse anyway")

    @property
    def warning(self) -> str | None:
        """The line every output of an analysis forced past this report carries (None when
        still)."""
        return None if self.still else forced_warning(self)

    def to_dict(self) -> dict[str, Any]:
        def f(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        return {
            "still": self.still,
            "tested": self.tested,
            "window_s": self.window_s,
            "short_s": self.short_s,
            "n_windows": self.n_windows,
            "gyro_mean_rad_s": [f(v) for v in self.gyro_mean_rad_s],
            "accel_mean_m_s2": [f(v) for v in self.accel_mean_m_s2],
            "accel_norm_m_s2": f(self.accel_norm_m_s2),
            "window_adev_measured": {n: f(v) for n, v in zip(self.NAMES, self.measured, strict=True)},
            "window_adev_still_max": {n: f(v) for n, v in zip(self.NAMES, self.explained, strict=True)},
            "worst": self.worst,
            "ratio": f(self.ratio),
            "max_ratio": MAX_RATIO,
            "moving_fraction": f(self.moving_fraction),
            "first_moving_s": f(self.first_moving_s),
            "reasons": list(self.reasons),
            "notes": list(self.notes),
        }

    def __repr__(self) -> str:
        return (f"StillnessReport(still={self.still}, worst={self.worst} ratio {self.ratio:.3g} "
                f"at {self.window_s:g} s, moving {100 * self.moving_fraction:.2g} %)")


def _block_means(samples: np.ndarray | ChunkedSamples, m: int) -> np.ndarray:
    """Means of consecutive blocks of ``m`` rows, (n // m, 6), streamed over chunks."""
    if isinstance(samples, np.ndarray):
        a = np.asarray(samples, dtype=np.float64)
        nb = a.shape[0] // m
        return a[: nb * m].reshape(nb, m, a.shape[1]).mean(axis=1)
    out: list[np.ndarray] = []
    rest = np.zeros((0, 6))
    for chunk in samples.iter_chunks(range(6)):
        c = np.concatenate((rest, chunk), axis=0) if rest.size else chunk
        nb = c.shape[0] // m
        out.append(c[: nb * m].reshape(nb, m, 6).mean(axis=1))
        rest = np.array(c[nb * m:])
    return np.concatenate(out, axis=0) if out else np.zeros((0, 6))


def _mean_checks(g_mean: np.ndarray, a_norm: float) -> tuple[list[str], list[str]]:
    """Reasons (not still) and notes from the record's mean gyro rate and accelerometer norm."""
    reasons: list[str] = []
    notes: list[str] = []
    gn = float(np.linalg.norm(g_mean))
    if gn > GYRO_MEAN_MAX_RAD_S:
        reasons.append(f"gyro mean {gn:.3g} rad/s (norm) where a still gyro shows its bias, "
                       f"below {GYRO_MEAN_MAX_RAD_S:g} rad/s (turning, or in deg/s: --units "
                       "gyro=deg/s)")
    if a_norm < NO_GRAVITY_M_S2:
        notes.append(f"accelerometer mean {a_norm:.3g} m/s^2, no gravity: the gravity check "
                     "was skipped")
    elif abs(a_norm - G) > GRAVITY_TOLERANCE * G:
        reasons.append(f"accelerometer mean norm {a_norm:.4g} m/s^2 where a still IMU reads "
                       f"g = {G:.4g} +- {100 * GRAVITY_TOLERANCE:g} % (moving, or a wrong unit)")
    elif abs(a_norm - G) > GRAVITY_NOTE * G:
        notes.append(f"accelerometer mean norm {a_norm:.4g} m/s^2 is {100 * (a_norm / G - 1):+.1f} % "
                     "from g: an uncalibrated scale or zero-g offset; the accelerometer's noise "
                     "values carry that scale error")
    return reasons, notes


def _explained(white: np.ndarray, floor: np.ndarray, u: np.ndarray | None) -> np.ndarray:
    """Window-mean variation a still IMU explains per axis (white noise and the floors), plus
    the accelerometer norm's when ``u`` (the unit gravity direction) is given."""
    explained = np.sqrt(white**2 + floor**2)
    if u is not None:
        # the norm moves with the accelerometer noise along gravity
        explained = np.append(explained, math.sqrt(float(np.dot(u**2, explained[3:] ** 2))))
    return explained


def assess_stillness(samples: np.ndarray | ChunkedSamples, rate_hz: float, *,
                     window_s: float = TAU_WINDOW_S, short_s: float = TAU_SHORT_S,
                     gyro_floor_rad_s: float = GYRO_FLOOR_RAD_S,
                     accel_floor_m_s2: float = ACCEL_FLOOR_M_S2) -> StillnessReport:
    """Measure whether a six-axis record (gyro rad/s, then accel m/s^2) is of an IMU at rest.

    Parameters
    ----------
    samples : ndarray, shape (N, 6), or ChunkedSamples (e.g. an ImuRecord)
    rate_hz : float
    window_s, short_s : float
        ``tau_w`` and ``tau_0`` of the module docstring, s.
    gyro_floor_rad_s, accel_floor_m_s2 : float
        Allowance for bias instability and random walk at ``window_s``.

    Returns
    -------
    StillnessReport
    """
    m0 = max(1, round(rate_hz * short_s))
    k = max(2, round(window_s * rate_hz / m0))
    b = _block_means(samples, m0)  # (n0, 6)
    n_w = b.shape[0] // k
    mean = b.mean(axis=0) if b.shape[0] else np.full(6, np.nan)
    g_mean, a_mean = mean[:3], mean[3:]
    a_norm = float(np.linalg.norm(a_mean))
    reasons, notes = _mean_checks(g_mean, a_norm)
    nan7 = (math.nan,) * 7
    if n_w < MIN_WINDOWS:
        notes.append(f"record too short to test stillness ({n_w} windows of {window_s:g} s)")
        return StillnessReport(
            still=not reasons, tested=False, window_s=m0 * k / rate_hz, short_s=m0 / rate_hz,
            n_windows=n_w, gyro_mean_rad_s=tuple(map(float, g_mean)),
            accel_mean_m_s2=tuple(map(float, a_mean)), accel_norm_m_s2=a_norm, measured=nan7,
            explained=nan7, worst="", ratio=math.nan, moving_fraction=math.nan,
            first_moving_s=None, reasons=tuple(reasons), notes=tuple(notes))
    # noise level at tau_0, robust to intermittent motion
    d0 = np.diff(b, axis=0)
    sig0 = 1.4826 * np.median(np.abs(d0), axis=0) / math.sqrt(2.0)
    w = b[: n_w * k].reshape(n_w, k, 6).mean(axis=1)  # window means
    gravity = a_norm >= NO_GRAVITY_M_S2
    wn = np.linalg.norm(w[:, 3:], axis=1)[:, None]
    cols = np.concatenate((w, wn), axis=1) if gravity else w
    dw = np.diff(cols, axis=0)
    measured = np.sqrt(0.5 * np.mean(dw**2, axis=0))
    floor = np.array([gyro_floor_rad_s] * 3 + [accel_floor_m_s2] * 3)
    explained = _explained(sig0 / math.sqrt(k), floor, a_mean / a_norm if gravity else None)
    ratios = measured / explained
    i = int(np.argmax(ratios))
    names = StillnessReport.NAMES
    big = np.abs(dw) > 6.0 * math.sqrt(2.0) * explained
    moving = big.any(axis=1)
    frac = float(moving.mean())
    first = float((np.flatnonzero(moving)[0] + 1) * m0 * k / rate_hz) if moving.any() else None
    if ratios[i] > MAX_RATIO:
        unit = "rad/s" if i < 3 else "m/s^2"
        what = "accelerometer norm" if i == 6 else names[i]
        reasons.append(
            f"the {m0 * k / rate_hz:g} s means of {what} vary by {measured[i]:.3g} {unit} "
            f"(Allan deviation), {ratios[i]:.3g} x what a still IMU with this noise shows "
            f"(<= {explained[i]:.3g}); {100 * frac:.2g} % of the windows move"
            + (f", first at {first:.4g} s" if first is not None else ""))

    def pad(a: np.ndarray) -> tuple[float, ...]:
        return tuple(float(v) for v in a) + (() if gravity else (math.nan,))

    return StillnessReport(
        still=not reasons, tested=True, window_s=m0 * k / rate_hz, short_s=m0 / rate_hz,
        n_windows=n_w, gyro_mean_rad_s=tuple(map(float, g_mean)),
        accel_mean_m_s2=tuple(map(float, a_mean)), accel_norm_m_s2=a_norm,
        measured=pad(measured), explained=pad(explained), worst=names[i],
        ratio=float(ratios[i]), moving_fraction=frac, first_moving_s=first,
        reasons=tuple(reasons), notes=tuple(notes))


def check_still(samples: np.ndarray | ChunkedSamples, rate_hz: float, *,
                path: str | os.PathLike[str] | None = None, force: bool = False,
                **kwargs: Any) -> StillnessReport:
    """:func:`assess_stillness`, refusing a record that is not still unless ``force``.

    Raises
    ------
    DegenerateInputError
        One line: the file, what was measured against what a still IMU shows, and the hint ``force``.
    """
    rep = assess_stillness(samples, rate_hz, **kwargs)
    if not rep.still and not force:
        raise DegenerateInputError(rep.message(path if path is not None
                                               else getattr(samples, "path", None)),
                                   hint=(Remedy("force", flag=True),))
    return rep


def forced_warning(rep: StillnessReport) -> str:
    """The line every output of a forced, not-still analysis carries."""
    return ("WARNING: not a still IMU record, analysed anyway (--force): "
            + "; ".join(rep.reasons) + ". The noise values include the motion.")

