"""WGS84 conversions: known points and round trips."""

import numpy as np

from ibiscape_eval.core.geodesy import (
    ecef_from_geodetic,
    enu_from_geodetic,
    geodetic_from_ecef,
    geodetic_from_enu,
)


def test_known_ecef_points() -> None:
    np.testing.assert_allclose(ecef_from_geodetic(0.0, 0.0, 0.0), [6378137.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(ecef_from_geodetic(90.0, 0.0, 0.0)[2], 6356752.314245, atol=1e-5)


def test_roundtrip_geodetic_ecef() -> None:
    rng = np.random.default_rng(0)
    lat = rng.uniform(-89.9, 89.9, 1000)
    lon = rng.uniform(-180, 180, 1000)
    alt = rng.uniform(-500, 9000, 1000)
    la, lo, al = geodetic_from_ecef(ecef_from_geodetic(lat, lon, alt))
    np.testing.assert_allclose(la, lat, atol=1e-10)
    np.testing.assert_allclose(lo, lon, atol=1e-10)
    np.testing.assert_allclose(al, alt, atol=1e-5)


def test_enu_axes_and_roundtrip() -> None:
    lat0, lon0, alt0 = 48.62, 2.44, 80.0  # Evry, where IBISC is
    east = enu_from_geodetic(lat0, lon0 + 1e-4, alt0, lat0, lon0, alt0)
    north = enu_from_geodetic(lat0 + 1e-4, lon0, alt0, lat0, lon0, alt0)
    assert east[0] > 7.0 and abs(east[1]) < 1e-3
    assert north[1] > 11.0 and abs(north[0]) < 1e-6
    pts = np.random.default_rng(1).uniform(-2000, 2000, (100, 3))
    la, lo, al = geodetic_from_enu(pts, lat0, lon0, alt0)
    np.testing.assert_allclose(enu_from_geodetic(la, lo, al, lat0, lon0, alt0), pts, atol=1e-6)
