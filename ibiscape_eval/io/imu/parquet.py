"""Parquet IMU files (EuRoC column names, or a column mapping)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.imu import AXES, ImuRecord

from .csv import resolve_columns
from .timing import record_from_parts

__all__ = ["read_imu_parquet"]


def read_imu_parquet(p: Path, cols: Mapping[str, str | int], rate_hz: float | None) -> ImuRecord:
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
        t_idx, t_s, axis_idx = resolve_columns(cols, names, len(names), p)
    arr = df.to_numpy()
    try:
        data = arr[:, axis_idx].astype(np.float64)
        stamps = None if t_idx is None else arr[:, t_idx].astype(np.float64)
    except (TypeError, ValueError):
        raise FormatError(p, "a mapped column is not numeric") from None
    if stamps is not None and t_s:
        stamps = np.round(stamps * 1e9)
    return record_from_parts(p, stamps, data, rate_hz)
