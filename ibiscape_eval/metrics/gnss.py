"""Express GNSS fixes in a reference trajectory's world frame (association + 4-DoF alignment),
e.g. for overlays on plots (maths lives here, not in ``report``)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import DegenerateInputError
from ibiscape_eval.core.geodesy import enu_from_geodetic
from ibiscape_eval.core.trajectory import Trajectory

from .alignment import align
from .association import associate

__all__ = ["gnss_in_reference_frame"]


def gnss_in_reference_frame(
    stamps_ns: npt.NDArray[np.int64],
    lat_deg: npt.NDArray[np.float64],
    lon_deg: npt.NDArray[np.float64],
    alt_m: npt.NDArray[np.float64],
    ref: Trajectory,
    *,
    max_diff_s: float = 0.5,
) -> npt.NDArray[np.float64]:
    """GNSS positions ``(K, 3)`` [m] in the reference's world frame.

    The fixes are converted to a local east-north-up frame at the first fix (WGS84), matched to the
    reference by nearest timestamp (within ``max_diff_s``), and placed with a 4-DoF (yaw +
    translation) alignment, since a GNSS frame and a SLAM world frame share the gravity axis but
    not the heading.  Raises :class:`DegenerateInputError` when fewer than 3 fixes match.
    """
    enu = enu_from_geodetic(
        lat_deg, lon_deg, alt_m, float(lat_deg[0]), float(lon_deg[0]), float(alt_m[0])
    )
    ident = np.tile([0.0, 0.0, 0.0, 1.0], (len(enu), 1))
    gnss = Trajectory(np.asarray(stamps_ns, dtype=np.int64), enu, ident, "gnss")
    matched = associate(gnss, ref, max_diff_s=max_diff_s)
    if len(matched.est) < 3:
        raise DegenerateInputError("fewer than 3 GNSS fixes overlap the reference in time")
    result = align(matched.est, matched.ref, method="yaw")
    return result.apply(gnss).pos_m
