"""Physics checks of a freshly read IMU record: are the gyro and accelerometer where they should be?

Whatever the IMU does, the accelerometer's mean specific force over a record is close to gravity
in norm (9.81 m/s^2; a vehicle's own accelerations average out), while a gyroscope's mean is a
fraction of a rad/s.  So:

- the three columns read as gyro averaging ~g in norm while the three read as accelerometer
  average almost nothing means the two triples are swapped (an accel-first file read in EuRoC's
  gyro-first order): refused, naming the ``--columns`` that reads it right;
- an accelerometer averaging ~1 in norm with no unit stated is in g: refused, naming
  ``--units accel=g``;
- an accelerometer averaging almost nothing is gravity-compensated (or simulated noise): a note
  says the gravity check could not be made.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError, Remedy
from ibiscape_eval.core.imu import ImuRecord

from .columns import ImuLayout
from .options import STANDARD_GRAVITY_M_S2

__all__ = ["SensorMeans", "check_sensor_layout", "sensor_means"]

#: Relative tolerance of "this norm is g" for the swap and unit checks (loose: it only has to
#: tell g from 0 and from 1).
G_TOLERANCE = 0.15
#: Below this mean norm (m/s^2) the accelerometer is taken as gravity-compensated.
NO_GRAVITY_M_S2 = 2.5


@dataclass(frozen=True)
class SensorMeans:
    """Mean of each axis over the record: gyro rad/s (3,), accel m/s^2 (3,)."""

    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray

    @property
    def gyro_norm_rad_s(self) -> float:
        return float(np.linalg.norm(self.gyro_rad_s))

    @property
    def accel_norm_m_s2(self) -> float:
        return float(np.linalg.norm(self.accel_m_s2))

    def to_dict(self) -> dict[str, Any]:
        return {"gyro_mean_rad_s": [float(v) for v in self.gyro_rad_s],
                "accel_mean_m_s2": [float(v) for v in self.accel_m_s2],
                "gyro_mean_norm_rad_s": self.gyro_norm_rad_s,
                "accel_mean_norm_m_s2": self.accel_norm_m_s2}


def sensor_means(rec: ImuRecord) -> SensorMeans:
    """Per-axis means; of the first chunk (a million rows) for a record on disk: gravity tells
    a gyro from an accelerometer within seconds, and a second pass over days of data is not
    needed for it."""
    if rec.samples is not None:
        m = np.mean(rec.samples, axis=0)
    else:
        m = np.mean(next(iter(rec.iter_chunks(range(6)))), axis=0)
    return SensorMeans(np.asarray(m[:3], dtype=float), np.asarray(m[3:], dtype=float))


def _near(x: float, target: float, tol: float = G_TOLERANCE) -> bool:
    return abs(x - target) <= tol * target


def check_sensor_layout(p: str | Path, rec: ImuRecord, layout: ImuLayout | None, *,
                        accel_unit_stated: bool) -> tuple[str, ...]:
    """Refuse a swapped gyro/accelerometer or an accelerometer in g read as m/s^2.

    Returns notes (e.g. that the gravity check could not be made); raises :class:`FormatError`
    naming ``p`` and the fix.
    """
    m = sensor_means(rec)
    g = STANDARD_GRAVITY_M_S2
    gn, an = m.gyro_norm_rad_s, m.accel_norm_m_s2
    if _near(gn, g) and an < 0.2 * g:
        hint: tuple[Remedy, ...]
        if layout is not None:
            fix, hint = "read them the other way with {0}", (Remedy("columns", layout.swapped_option()),)
        else:
            fix, hint = "store the gyro (rad/s) before the accelerometer (m/s^2)", ()
        raise FormatError(
            p, f"the columns read as gyro average {gn:.4g} in norm, like gravity in m/s^2, and "
            f"those read as accelerometer {an:.3g}: gyro and accelerometer look swapped "
            f"(an accelerometer-first file?); {fix}", hint=hint)
    if not accel_unit_stated and _near(an, 1.0) and gn < 0.5:
        raise FormatError(
            p, f"the accelerometer averages {an:.4g} in norm: that is gravity in g, not m/s^2; "
            "give {0} (and gyro=deg/s if the gyro is in deg/s)", hint=(Remedy("units", "accel=g"),))
    notes: list[str] = []
    if an < NO_GRAVITY_M_S2:
        notes.append(f"the accelerometer averages {an:.3g} m/s^2 in norm, not g: gravity removed "
                     "(or simulated noise), so its axes and unit could not be checked by gravity")
    return tuple(notes)
