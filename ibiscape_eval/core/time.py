"""Time handling: int64 nanoseconds inside, seconds only at the edges."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["NS_PER_S", "ns_from_s", "s_from_ns"]

NS_PER_S = 1_000_000_000


def ns_from_s(stamps_s: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Convert seconds (float) to int64 nanoseconds, rounding to the nearest nanosecond.

    A float64 holds about 16 significant digits, so epoch stamps in seconds (1.3e9 s) keep about
    0.2 us of resolution; readers that must be exact parse the decimal text instead.
    """
    return np.rint(np.asarray(stamps_s, dtype=np.float64) * NS_PER_S).astype(np.int64)


def s_from_ns(stamps_ns: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert int64 nanoseconds to float seconds (loses precision below ~0.2 us at epoch scale)."""
    a = np.asarray(stamps_ns, dtype=np.int64)
    # Split to keep the fractional part exact before the final add.
    whole = a // NS_PER_S
    frac = a - whole * NS_PER_S
    return whole.astype(np.float64) + frac.astype(np.float64) / NS_PER_S
