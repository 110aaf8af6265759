"""Saved results: per-pose CSV tables and result JSON files, written atomically and losslessly.

Columns ending in ``_ns`` are integers (exact stamps); a seconds column ``X_t_s`` next to an
integer ``X_stamp_ns`` is written from the integer, exactly, with 9 decimals (a double cannot
hold nanoseconds at today's epochs); other ``t_s`` columns with 9 decimals; every other float
with the shortest text that reads back to the same double.
"""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from .atomic import atomic_write

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["seconds_text", "write_result_csv", "write_result_json"]


def write_result_csv(path: str | os.PathLike[str], frame: pd.DataFrame) -> None:
    """Write ``frame`` as CSV: seconds columns with 9 decimals, other floats round-trip exact."""
    out = frame.copy()
    for col in out.columns:
        name = str(col)
        if not (name.endswith("t_s") and out[col].dtype.kind == "f"):
            continue
        ns_col = name[: -len("t_s")] + "stamp_ns"
        if ns_col in out.columns and out[ns_col].dtype.kind in "iu":
            out[col] = seconds_text(out[ns_col].to_numpy())
        else:
            out[col] = np.char.mod("%.9f", out[col].to_numpy())
    with atomic_write(path) as f:
        out.to_csv(f, index=False, lineterminator="\n")


def seconds_text(stamps_ns: np.ndarray) -> np.ndarray:
    """Integer nanoseconds as exact decimal seconds with 9 decimals (``"12.000000001"``)."""
    ns = np.asarray(stamps_ns, dtype=np.int64)
    sign = np.where(ns < 0, "-", "")
    a = np.abs(ns)
    whole = np.char.mod("%d", a // 1_000_000_000)
    frac = np.char.zfill(np.char.mod("%d", a % 1_000_000_000), 9)
    return np.char.add(np.char.add(sign, whole), np.char.add(".", frac))


def write_result_json(path: str | os.PathLike[str], doc: dict[str, Any]) -> None:
    """Write ``doc`` as strict JSON (NaN and infinities refused), indented."""
    with atomic_write(path) as f:
        json.dump(doc, f, indent=2, allow_nan=False)
        f.write("\n")
