"""Numbers in strict JSON: the one NaN/inf -> None conversion every ``to_dict`` uses."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["finite_or_none"]


def finite_or_none(x: Any) -> float | None:
    """``float(x)``, or None when ``x`` is NaN, infinite, None or not a number.

    Strict JSON has no NaN or Infinity: an undetermined value is written as ``null``.
    """
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None
