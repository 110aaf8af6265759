"""Parquet IMU files (columns by header name, in any order, or a column mapping)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.imu import ImuRecord

from .columns import (
    STAMP_UNITS,
    check_rate,
    override_units,
    resolve_layout,
    stamp_unit,
    with_layout,
)
from .timing import record_from_parts

__all__ = ["read_imu_parquet"]


def read_imu_parquet(p: Path, cols: Mapping[str, str | int], rate_hz: float | None, *,
                     units: tuple[float, float] | None = None) -> ImuRecord:
    import pandas as pd

    try:
        df = pd.read_parquet(p)
    except Exception as e:  # pyarrow raises many types for a broken file
        raise FormatError(p, f"not a readable parquet file ({type(e).__name__}: {e})") from None
    names = [str(c) for c in df.columns]
    layout = resolve_layout(p, cols, names, len(names))
    if layout.mapped_by == "default order":
        raise FormatError(p, f"gyro/accelerometer columns not recognised (have {', '.join(names)}); "
                          "give --columns")
    if units is not None:
        layout = override_units(layout, units)
    try:
        data = df.iloc[:, list(layout.axis_columns)].to_numpy(dtype=np.float64)
        t_col = layout.time_column
        stamps = None if t_col is None else df.iloc[:, t_col].to_numpy()
    except (TypeError, ValueError):
        raise FormatError(p, "a mapped column is not numeric") from None
    data = data * np.array([layout.gyro_scale] * 3 + [layout.accel_scale] * 3)
    if stamps is not None:
        if stamps.dtype.kind not in "fiu":
            raise FormatError(p, "the time column is not numeric")
        unit, how = layout.time_unit, layout.time_unit_from
        head = np.asarray(stamps[:4000], dtype=np.float64)
        if unit is None:
            unit, how = stamp_unit(head)
            layout = dataclasses.replace(layout, time_unit=unit, time_unit_from=how)
        else:
            d = np.diff(head)
            check_rate(p, unit, float(np.median(d[d > 0])) if np.any(d > 0) else float("nan"), how)
        f = STAMP_UNITS[unit]
        stamps = (stamps.astype(np.int64) * np.int64(f) if stamps.dtype.kind in "iu"
                  else np.round(stamps.astype(np.float64) * f))
    return with_layout(record_from_parts(p, stamps, data, rate_hz), layout)
