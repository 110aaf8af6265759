"""Light: the sun from the weather state, an ambient sky term, cast shadows and the sky gradient.

Radiance of a surface point (linear, 1 = a white surface under the full midday sun)::

    L = albedo * (E_sun max(0, n . s) V + E_sky (0.6 + 0.4 n_z))

with ``s`` the direction toward the sun (azimuth from world x toward y, altitude above the
horizon), ``V`` the visibility of the sun (a shadow ray), ``E_sun`` falling with the sun's altitude
and with the clouds and ``E_sky`` the hemisphere light, dim at dusk ("dim light at low sun
altitude") and never quite zero (a city at night).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Lighting", "WeatherState", "lighting", "sky_radiance"]

F32 = npt.NDArray[np.float32]


@dataclass(frozen=True)
class WeatherState:
    """The weather at one instant (CARLA's ``WeatherParameters`` names, 0..100 unless noted)."""

    cloudiness: float = 10.0
    precipitation: float = 0.0
    precipitation_deposits: float = 0.0
    wind_intensity: float = 10.0
    fog_density: float = 0.0
    fog_distance: float = 50.0
    fog_falloff: float = 0.2
    wetness: float = 0.0
    sun_azimuth_angle: float = 120.0  # deg
    sun_altitude_angle: float = 50.0  # deg
    storm: float = 50.0


@dataclass(frozen=True)
class Lighting:
    """Sun direction (world, unit), sun and sky irradiance, the exposure gain of the camera."""

    sun_dir: tuple[float, float, float]
    e_sun: float
    e_sky: float
    gain: float


def _smoothstep(a: float, b: float, x: float) -> float:
    t = min(1.0, max(0.0, (x - a) / (b - a)))
    return t * t * (3.0 - 2.0 * t)


def lighting(w: WeatherState) -> Lighting:
    """Light levels and an automatic exposure (gain 1 at midday, at most 6 at night: a real camera
    raises its gain in the dark, so the image gets noisier rather than black)."""
    alt = math.radians(w.sun_altitude_angle)
    az = math.radians(w.sun_azimuth_angle)
    s = (math.cos(alt) * math.cos(az), math.cos(alt) * math.sin(az), math.sin(alt))
    c = w.cloudiness / 100.0
    day = _smoothstep(-12.0, 20.0, w.sun_altitude_angle)
    e_sun = 0.85 * max(0.0, math.sin(alt)) ** 0.5 * _smoothstep(-1.0, 6.0, w.sun_altitude_angle) * (1.0 - 0.85 * c)
    e_sky = 0.02 + 0.38 * day * (1.0 - 0.35 * c)
    gain = min(6.0, max(1.0, 0.75 / (0.55 * e_sun + e_sky)))
    return Lighting(s, e_sun, e_sky, gain)


_ZENITH = np.array([0.22, 0.38, 0.78], np.float32)
_HORIZON = np.array([0.70, 0.78, 0.88], np.float32)
_OVERCAST = np.array([0.62, 0.64, 0.66], np.float32)


def horizon_radiance(w: WeatherState, light: Lighting) -> F32:
    """Sky radiance at the horizon (also the fog's airlight colour), RGB (3,)."""
    c = w.cloudiness / 100.0
    level = 1.6 * light.e_sky + 0.25 * light.e_sun
    return ((1.0 - c) * _HORIZON + c * _OVERCAST) * np.float32(level)


def sky_radiance(dir_z: npt.ArrayLike, w: WeatherState, light: Lighting) -> F32:
    """Sky radiance ``(N, 3)`` for unit-direction z components ``(N,)`` (elevation sine)."""
    e = np.clip(np.asarray(dir_z, dtype=np.float32), 0.0, 1.0)[:, None]
    c = np.float32(w.cloudiness / 100.0)
    clear = _HORIZON + (_ZENITH - _HORIZON) * np.sqrt(e)
    col = (1.0 - c) * clear + c * _OVERCAST
    level = np.float32(1.6 * light.e_sky + 0.25 * light.e_sun)
    return (col * level).astype(np.float32)


def shade(albedo: F32, normal: F32, sun_visible: npt.NDArray[np.bool_] | None, light: Lighting) -> F32:
    """Radiance ``(N, 3)`` of surfaces with ``albedo`` (N, 3) and unit normals (N, 3) facing the viewer."""
    s = np.asarray(light.sun_dir, np.float32)
    ndl = np.maximum(normal @ s, 0.0)
    if sun_visible is not None:
        ndl = ndl * sun_visible
    e = np.float32(light.e_sun) * ndl + np.float32(light.e_sky) * (0.6 + 0.4 * normal[:, 2])
    return (albedo * e[:, None]).astype(np.float32)
