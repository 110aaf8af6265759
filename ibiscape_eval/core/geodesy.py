"""WGS84 geodetic coordinates and a local east-north-up (ENU) tangent frame.

Used to overlay GNSS fixes on trajectories and, in the simulator, to turn local positions into
latitude/longitude/altitude.  Formulas: WGS84 ellipsoid (NIMA TR8350.2), geodetic -> ECEF in closed
form, ECEF -> geodetic with Bowring's (1976) iteration-free approximation refined by two Newton steps.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "WGS84_A_M",
    "WGS84_F",
    "ecef_from_geodetic",
    "enu_from_geodetic",
    "geodetic_from_ecef",
    "geodetic_from_enu",
]

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
_E2 = WGS84_F * (2.0 - WGS84_F)
_B_M = WGS84_A_M * (1.0 - WGS84_F)
_EP2 = (WGS84_A_M**2 - _B_M**2) / _B_M**2

FloatArray = npt.NDArray[np.float64]


def ecef_from_geodetic(
    lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, alt_m: npt.ArrayLike
) -> FloatArray:
    """Earth-centred earth-fixed coordinates ``(N, 3)`` in metres."""
    lat = np.radians(np.asarray(lat_deg, dtype=np.float64))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    h = np.asarray(alt_m, dtype=np.float64)
    sl, cl = np.sin(lat), np.cos(lat)
    n = WGS84_A_M / np.sqrt(1.0 - _E2 * sl * sl)  # prime vertical radius of curvature
    return np.stack(
        ((n + h) * cl * np.cos(lon), (n + h) * cl * np.sin(lon), (n * (1.0 - _E2) + h) * sl),
        axis=-1,
    )


def geodetic_from_ecef(xyz_m: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Latitude [deg], longitude [deg], altitude [m] from ECEF ``(N, 3)``; sub-millimetre accurate."""
    p_ecef = np.asarray(xyz_m, dtype=np.float64)
    x, y, z = p_ecef[..., 0], p_ecef[..., 1], p_ecef[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    # Bowring's initial parametric latitude, then Newton refinement on the exact relation.
    beta = np.arctan2(z * WGS84_A_M, p * _B_M)
    lat = np.arctan2(z + _EP2 * _B_M * np.sin(beta) ** 3, p - _E2 * WGS84_A_M * np.cos(beta) ** 3)
    for _ in range(2):
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
        lat = np.arctan2(
            z + _EP2 * _B_M * np.sin(beta) ** 3, p - _E2 * WGS84_A_M * np.cos(beta) ** 3
        )
    sl = np.sin(lat)
    n = WGS84_A_M / np.sqrt(1.0 - _E2 * sl * sl)
    cl = np.cos(lat)
    # Altitude: robust away from the poles; near the poles use the z-based expression.
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(np.abs(cl) > 1e-6, p / cl - n, np.abs(z) / np.abs(sl) - n * (1.0 - _E2))
    return np.degrees(lat), np.degrees(lon), h


def _enu_rotation(lat0_deg: float, lon0_deg: float) -> FloatArray:
    """Rows: east, north, up unit vectors in ECEF at the reference point."""
    lat, lon = np.radians(lat0_deg), np.radians(lon0_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def enu_from_geodetic(
    lat_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    alt_m: npt.ArrayLike,
    lat0_deg: float,
    lon0_deg: float,
    alt0_m: float,
) -> FloatArray:
    """Local east, north, up coordinates ``(N, 3)`` [m] about the reference (lat0, lon0, alt0)."""
    d = ecef_from_geodetic(lat_deg, lon_deg, alt_m) - ecef_from_geodetic(lat0_deg, lon0_deg, alt0_m)
    return d @ _enu_rotation(lat0_deg, lon0_deg).T


def geodetic_from_enu(
    enu_m: npt.ArrayLike, lat0_deg: float, lon0_deg: float, alt0_m: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Latitude [deg], longitude [deg], altitude [m] of local ENU points ``(N, 3)``."""
    e = np.asarray(enu_m, dtype=np.float64)
    xyz = e @ _enu_rotation(lat0_deg, lon0_deg) + ecef_from_geodetic(lat0_deg, lon0_deg, alt0_m)
    return geodetic_from_ecef(xyz)
