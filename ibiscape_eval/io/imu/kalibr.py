"""Kalibr ``imu.yaml``: the four continuous-time noise densities, topic and rate."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

from ibiscape_eval.core.errors import FormatError, IbiscapeError

from ..atomic import atomic_write

__all__ = ["read_kalibr_imu_yaml", "write_kalibr_imu_yaml"]


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
    from ..yaml_file import read_yaml

    doc = read_yaml(path, what="Kalibr imu.yaml")
    keys = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
            "gyroscope_random_walk", "rostopic", "update_rate")
    if not isinstance(doc, dict) or any(k not in doc for k in keys):
        raise FormatError(path, f"expected the keys {', '.join(keys)}")
    return doc
