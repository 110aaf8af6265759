"""Summary statistics of per-pose or per-pair errors (the set evo reports)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["ErrorStats"]


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of a vector of non-negative errors, all in the unit of the errors.

    Attributes
    ----------
    rmse, mean, median, std, min, max, sse : float
        Root mean square, mean, median, population standard deviation (``ddof=0``, like evo),
        minimum, maximum and sum of squares.  NaN (``sse`` 0) when there are no errors.
    n : int
        Number of errors summarised.
    """

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float
    n: int

    @classmethod
    def from_errors(cls, errors: npt.ArrayLike) -> ErrorStats:
        """Summarise ``errors`` (shape ``(N,)``); an empty array gives NaN statistics."""
        e = np.asarray(errors, dtype=np.float64).ravel()
        if e.size == 0:
            nan = math.nan
            return cls(nan, nan, nan, nan, nan, nan, 0.0, 0)
        sq = e * e
        return cls(
            rmse=math.sqrt(float(np.mean(sq))),
            mean=float(np.mean(e)),
            median=float(np.median(e)),
            std=float(np.std(e)),
            min=float(np.min(e)),
            max=float(np.max(e)),
            sse=float(np.sum(sq)),
            n=int(e.size),
        )

    def to_dict(self) -> dict[str, float]:
        """The seven statistics under the keys ``rmse, mean, median, std, min, max, sse``."""
        return {
            "rmse": self.rmse,
            "mean": self.mean,
            "median": self.median,
            "std": self.std,
            "min": self.min,
            "max": self.max,
            "sse": self.sse,
        }
