"""GNSS model: WGS84 latitude/longitude/altitude of the antenna, with white noise.

The world frame is the local east-north-up (ENU) frame at the configured WGS84 reference (x east,
y north, z up; CARLA's x east / y south mirrored into our right-handed frame gives the same).  The
antenna sits at ``r`` in the body frame: ``p_ant = p + R r``; noise is added in ENU (sigma
horizontal on east and north, vertical on up) before the conversion
(:func:`ibiscape_eval.core.geodesy.geodetic_from_enu`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ibiscape_eval.core.geodesy import enu_from_geodetic, geodetic_from_enu
from ibiscape_eval.core.rotations import quat_rotate
from ibiscape_eval.io.gnss import GnssFixes

from .types import MotionState

if TYPE_CHECKING:
    from .config import GnssSpec

__all__ = ["antenna_positions_m", "enu_from_fixes", "simulate_gnss"]


def antenna_positions_m(state: MotionState, spec: GnssSpec) -> np.ndarray:
    """Antenna positions in the world (ENU) frame, shape (N, 3), metres."""
    r = np.broadcast_to(np.asarray(spec.position_m, dtype=np.float64), state.pos_m.shape)
    return state.pos_m + quat_rotate(state.quat_xyzw, r)


def simulate_gnss(state: MotionState, spec: GnssSpec, *, seed: int, ideal: bool = False) -> GnssFixes:
    """GNSS fixes at ``state``'s stamps.

    Parameters
    ----------
    state : MotionState
        Body kinematics at the fix stamps.
    spec : GnssSpec
        Antenna lever arm, noise sigmas [m], WGS84 reference.
    seed : int
        Seed of the noise (already specific to the receiver).
    ideal : bool
        No noise.
    """
    enu = antenna_positions_m(state, spec)
    if not ideal:
        rng = np.random.default_rng(seed)
        sig = np.array([spec.sigma_horizontal_m, spec.sigma_horizontal_m, spec.sigma_vertical_m])
        enu = enu + rng.standard_normal(enu.shape) * sig
    lat, lon, alt = geodetic_from_enu(enu, spec.ref_lat_deg, spec.ref_lon_deg, spec.ref_alt_m)
    return GnssFixes(state.stamps_ns, lat, lon, alt)


def enu_from_fixes(fixes: GnssFixes, spec: GnssSpec) -> np.ndarray:
    """Back to world (ENU) coordinates, shape (N, 3), metres."""
    return enu_from_geodetic(fixes.lat_deg, fixes.lon_deg, fixes.alt_m, spec.ref_lat_deg,
                             spec.ref_lon_deg, spec.ref_alt_m)


