"""Weather evolving in time, with CARLA's ``WeatherParameters`` names, logged per camera frame.

Model (all seeded, vectorised, evaluated at any stamps):

- a smooth zero-mean process per parameter, built from random Fourier features
  ``z(t) = sqrt(2/K) sum_k cos(omega_k t + phi_k)`` with ``omega_k ~ N(0, 1/tau^2)`` (a Gaussian
  covariance of time scale ``tau``), mixed with a common "storm" process:
  ``z_p = sqrt(c) z_storm + sqrt(1 - c) z_own`` so clouds, rain, wind and fog rise together;
- each process is centred over the sequence, so the preset's means are the sequence averages
  (before clipping to 0..100): ``value = clip(mean + std * z_p, 0, 100)``;
- ``wetness`` and ``precipitation_deposits`` (puddles) follow the rain through a first-order lag
  of time constant ``deposit_lag_s`` (starting at equilibrium); puddles are 80 % of wetness;
- fog geometry from the density: ``fog_distance = 5 + 45 (1 - fog/100)`` m (where fog starts),
  ``fog_falloff = 0.2 + 1.8 fog/100``;
- the sun: ``altitude = 70 sin(phase0 + rate t) - 20`` deg, azimuth ``az0 + rate t`` mod 360 deg,
  like the public acquisition scripts; ``storm`` (0..100) logs the common storm level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

from .imu import sub_seed

if TYPE_CHECKING:
    import pandas as pd

    from .config import WeatherSpec

__all__ = ["WEATHER_COLUMNS", "WeatherLog", "simulate_weather"]

#: Logged columns, in file order (CARLA's names, plus the storm level).
WEATHER_COLUMNS = ("cloudiness", "precipitation", "precipitation_deposits", "wind_intensity",
                   "fog_density", "fog_distance", "fog_falloff", "wetness", "sun_azimuth_angle",
                   "sun_altitude_angle", "storm")
_N_FEATURES = 24


@dataclass(frozen=True, eq=False)
class WeatherLog:
    """Weather state per stamp.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
    values : ndarray, shape (N, 11)
        Columns :data:`WEATHER_COLUMNS`: percentages 0..100, ``fog_distance`` m, ``fog_falloff``
        (CARLA's unit-less exponent), sun angles in degrees.
    """

    stamps_ns: npt.NDArray[np.int64]
    values: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    def column(self, name: str) -> npt.NDArray[np.float64]:
        """One column by its CARLA name."""
        return self.values[:, WEATHER_COLUMNS.index(name)]

    def averages(self) -> dict[str, float]:
        """Mean of every column over the log (NaN when empty)."""
        if len(self) == 0:
            return {k: math.nan for k in WEATHER_COLUMNS}
        m = self.values.mean(axis=0)
        return {k: float(v) for k, v in zip(WEATHER_COLUMNS, m, strict=True)}

    def to_frame(self) -> pd.DataFrame:
        """Columns ``stamp_ns`` and :data:`WEATHER_COLUMNS`."""
        import pandas as pd

        df = pd.DataFrame(self.values, columns=list(WEATHER_COLUMNS))
        df.insert(0, "stamp_ns", self.stamps_ns)
        return df


def _smooth_process(t_s: np.ndarray, tau_s: float, rng: np.random.Generator) -> np.ndarray:
    """Unit-variance (in expectation) Gaussian-covariance process at ``t_s``, centred on the samples."""
    omega = rng.standard_normal(_N_FEATURES) / tau_s
    phi = rng.uniform(0.0, 2.0 * math.pi, _N_FEATURES)
    z = math.sqrt(2.0 / _N_FEATURES) * np.cos(np.outer(t_s, omega) + phi).sum(axis=1)
    return z - z.mean() if z.size else z


def _lag(x: np.ndarray, t_s: np.ndarray, tau_s: float, x0: float) -> np.ndarray:
    """First-order lag ``dy/dt = (x - y) / tau`` (exact for piecewise-constant input), y(0) = x0."""
    if x.size == 0:
        return x
    from scipy.signal import lfilter

    dt = np.diff(t_s, prepend=t_s[0])
    if dt.size > 1 and not np.allclose(dt[1:], dt[1], rtol=1e-6, atol=1e-9):
        raise IbiscapeError("weather: stamps must be uniformly spaced (camera frames)")
    a = math.exp(-float(dt[1]) / tau_s) if dt.size > 1 else 0.0
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x0])
    return np.asarray(y)


def simulate_weather(spec: WeatherSpec, stamps_ns: npt.ArrayLike, *, seed: int,
                     start_ns: int | None = None) -> WeatherLog:
    """The weather at ``stamps_ns`` (uniform, e.g. the camera frames).

    Parameters
    ----------
    spec : WeatherSpec
        Means/stds, coupling, time scales, sun motion (presets in :mod:`ibiscape_eval.sim.config`).
    stamps_ns : array_like of int64, shape (N,)
    seed : int
    start_ns : int, optional
        Time origin of the sun's motion (default the first stamp).

    Returns
    -------
    WeatherLog
    """
    st = np.asarray(stamps_ns, dtype=np.int64)
    t0 = int(st[0]) if start_ns is None and st.size else int(start_ns or 0)
    t_s = (st - t0).astype(np.float64) * 1e-9
    rng = np.random.default_rng(sub_seed(seed, "weather"))
    c = spec.storm_coupling
    storm = _smooth_process(t_s, spec.correlation_time_s * 2.0, rng)

    def level(mean_std: tuple[float, float]) -> np.ndarray:
        own = _smooth_process(t_s, spec.correlation_time_s, rng)
        z = math.sqrt(c) * storm + math.sqrt(1.0 - c) * own
        return np.clip(mean_std[0] + mean_std[1] * z, 0.0, 100.0)

    cloud = level(spec.cloudiness)
    rain = level(spec.precipitation)
    wind = level(spec.wind_intensity)
    fog = level(spec.fog_density)
    wet = np.clip(_lag(rain, t_s, spec.deposit_lag_s, float(spec.precipitation[0])), 0.0, 100.0)
    puddles = 0.8 * wet
    fog_dist = 5.0 + 45.0 * (1.0 - fog / 100.0)
    fog_fall = 0.2 + 1.8 * fog / 100.0
    az = np.mod(spec.sun_azimuth0_deg + spec.sun_azimuth_rate_deg_s * t_s, 360.0)
    alt = 70.0 * np.sin(spec.sun_phase0_rad + spec.sun_phase_rate_rad_s * t_s) - 20.0
    storm_level = np.clip(50.0 + 25.0 * storm, 0.0, 100.0)
    vals = np.stack((cloud, rain, puddles, wind, fog, fog_dist, fog_fall, wet, az, alt, storm_level),
                    axis=1)
    return WeatherLog(st, vals)
