"""GNSS value type: WGS84 fixes (readers and writers in :mod:`ibiscape_eval.io.gnss`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .errors import IbiscapeError

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["GnssFixes"]


@dataclass(frozen=True, eq=False)
class GnssFixes:
    """GNSS fixes (WGS84), arrays read-only.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
        Strictly increasing timestamps, ns.
    lat_deg, lon_deg : ndarray, shape (N,)
        Latitude in [-90, 90] and longitude in [-180, 180], degrees.
    alt_m : ndarray, shape (N,)
        Altitude, metres.
    """

    stamps_ns: npt.NDArray[np.int64]
    lat_deg: npt.NDArray[np.float64]
    lon_deg: npt.NDArray[np.float64]
    alt_m: npt.NDArray[np.float64]

    def __post_init__(self) -> None:
        st = np.array(self.stamps_ns)
        if st.dtype.kind not in "iu" or st.ndim != 1:
            raise IbiscapeError(f"GnssFixes.stamps_ns must be 1-D integer ns, got {st.dtype} "
                                f"{st.shape}")
        object.__setattr__(self, "stamps_ns", st.astype(np.int64))
        for field in ("lat_deg", "lon_deg", "alt_m"):
            a = np.array(getattr(self, field), dtype=np.float64)
            if a.shape != st.shape:
                raise IbiscapeError(f"GnssFixes.{field}: expected shape {st.shape}, got {a.shape}")
            object.__setattr__(self, field, a)
        for field in ("stamps_ns", "lat_deg", "lon_deg", "alt_m"):
            getattr(self, field).flags.writeable = False

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    def to_frame(self) -> pd.DataFrame:
        """Columns ``stamp_ns, lat_deg, lon_deg, alt_m``."""
        import pandas as pd

        return pd.DataFrame({"stamp_ns": self.stamps_ns, "lat_deg": self.lat_deg,
                             "lon_deg": self.lon_deg, "alt_m": self.alt_m})
