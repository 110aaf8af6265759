"""Still and moving IMU records from the project's generator, shared by the IMU trap tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ibiscape_eval.sim.config import ImuNoise, ImuSpec
from ibiscape_eval.sim.still import still_imu_chunks

NOISE = ImuNoise()
#: continuous-time densities the generator uses (gyro rad/s/sqrt(Hz), accel m/s^2/sqrt(Hz))
GYRO_N = NOISE.gyro_noise_density_rad_s_sqrt_hz
ACCEL_N = NOISE.accel_noise_density_m_s2_sqrt_hz


def still_imu(duration_s: float = 100.0, seed: int = 1, noise: ImuNoise = NOISE,
              rate_hz: float = 200.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stamps_ns, gyro (n, 3), accel (n, 3)) of a still, level IMU (gravity on +z)."""
    ch = list(still_imu_chunks(ImuSpec(rate_hz=rate_hz), noise, duration_s=duration_s,
                               start_ns=1_403_636_579_758_555_392, seed=seed))
    t = np.concatenate([c[0] for c in ch])
    g = np.concatenate([c[1] for c in ch])
    a = np.concatenate([c[2] for c in ch])
    return t, g, a


def driving_imu(folder: Path, duration_s: float = 30.0, seed: int = 4) -> Path:
    """The IMU csv of a generated SVI drive (a car in town: turns, stops)."""
    from ibiscape_eval.sim import generate, preset

    seq = folder / "drive"
    generate(preset("svi", "slam", "clear", duration_s=duration_s, seed=seed), seq)
    return seq / "other_sensors" / "imu.csv"


def write_table(path: Path, header: str | None, cols: list[np.ndarray], fmt: list[str]) -> Path:
    """Write columns with per-column printf formats (no project writer: the traps are foreign
    files)."""
    rows = np.column_stack([np.asarray(c, dtype=object) for c in cols])
    lines = [] if header is None else [header]
    lines += [",".join(f % v for f, v in zip(fmt, r, strict=True)) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path
