"""Weather optics and the camera's sensor: fog, rain streaks, wet road, exposure and noise.

- Fog (Koschmieder's law): ``I = J t + A (1 - t)``, ``t = exp(-beta d)`` with ``d`` the distance
  along the ray, ``A`` the horizon sky (airlight) and ``beta = 0.12 fog_density / 100`` [1/m]
  (visibility ``3.912 / beta``: 33 m at 100 %, 47 m at the dynamic preset's 70 %).  The sky is
  treated as ``d = 1000 m``.
- Wet road: paved ground darkens with ``wetness`` and puddles (where a coarse noise exceeds a level
  set by ``precipitation_deposits``) mirror the sky.
- Rain: drops are particles with fixed world positions moving down at 7 m/s plus the wind
  (``wind_intensity`` 100 % = 8 m/s, blowing toward azimuth 35 deg), wrapped periodically in a 24 m
  box around the camera, so the rain is the same for both cameras of a stereo pair and continuous
  in time (the DVS model asks for any instant).  A drop draws the segment it travels during the
  exposure (10 ms), antialiased, hidden behind nearer surfaces.
- Sensor: 8-bit output of ``255 gain L`` plus Gaussian noise of standard deviation
  ``sqrt((0.6 gain)^2 + 0.04 gain I)`` DN (read noise grows with the gain, shot noise with the
  signal ``I``), so dark scenes are noisier.  The deviates are seeded and counter-based: a
  splitmix64 hash of the key and the value's index picks one of 65536 normal quantiles
  (:func:`normal_table`; tails end at 4.3 sigma), four values per hash.

:func:`fog` and :func:`puddles` are the numpy forms of the formulas; the renderer applies them per
pixel inside its fused shading pass (``_kernels.finish``), which the tests compare with them.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import numpy.typing as npt

from .shading import WeatherState

__all__ = ["add_sensor_noise", "fog", "fog_beta_per_m", "normal_table", "puddles", "rain_streaks", "sensor_output"]

F32 = npt.NDArray[np.float32]

_SKY_DISTANCE_M = 1000.0
_DROP_BOX_M = 24.0
_DROP_FALL_M_S = 7.0
_WIND_MAX_M_S = 8.0
_WIND_AZIMUTH_RAD = math.radians(35.0)
_EXPOSURE_S = 0.010
_DROPS_PER_M3_AT_100 = 0.25


def fog_beta_per_m(fog_density: float) -> float:
    """Extinction coefficient [1/m] of a CARLA fog density 0..100."""
    return 0.12 * max(0.0, fog_density) / 100.0


def fog(radiance: F32, distance_m: F32, beta_per_m: float, airlight: F32) -> F32:
    """Koschmieder: ``I = J t + A (1 - t)``, ``t = exp(-beta d)``; infinite distances count as 1 km."""
    if beta_per_m <= 0.0:
        return radiance
    d = np.minimum(distance_m, np.float32(_SKY_DISTANCE_M))
    t = np.exp(np.float32(-beta_per_m) * d)[:, None]
    return (radiance * t + airlight[None, :] * (1.0 - t)).astype(np.float32)


def puddles(radiance: F32, paved: F32, puddle_noise: F32, sky_reflection: F32, w: WeatherState) -> F32:
    """Mirror the sky in puddles on paved ground: where a coarse noise exceeds a level that falls
    with ``precipitation_deposits``, blend toward the reflected sky (wet-road darkening is applied
    to the albedo by the renderer: ``albedo (1 - 0.45 wetness paved)``)."""
    level = 1.6 - 2.2 * w.precipitation_deposits / 100.0  # more deposits: more of the noise is water
    puddle = np.clip((puddle_noise - level) * 3.0, 0.0, 1.0) * paved
    k = (0.65 * puddle)[:, None]
    return (radiance * (1.0 - k) + sky_reflection * k).astype(np.float32)


def rain_streaks(model: object, T_world_cam: np.ndarray, depth_m: F32, t_ns: int, w: WeatherState,
                 *, seed: int, brightness: float) -> F32 | None:
    """Streak coverage ``(H, W)`` float32 0..1 scaled by ``brightness`` (radiance added on top of the
    image through ``I (1 - a) + a b``), or ``None`` without rain.  ``depth_m`` (H, W) hides streaks
    behind surfaces."""
    import cv2

    rate = w.precipitation / 100.0
    if rate <= 0.0:
        return None
    cam = model  # CameraModel
    H, W = depth_m.shape
    n = int(_DROPS_PER_M3_AT_100 * rate * _DROP_BOX_M ** 3)
    if n == 0:
        return None
    rng = np.random.default_rng([seed, 0x7A17])
    p0 = rng.uniform(0.0, _DROP_BOX_M, (n, 3))
    wind = _WIND_MAX_M_S * w.wind_intensity / 100.0
    vel = np.array([wind * math.cos(_WIND_AZIMUTH_RAD), wind * math.sin(_WIND_AZIMUTH_RAD), -_DROP_FALL_M_S])
    t_s = t_ns * 1e-9
    c = T_world_cam[:3, 3]
    # periodic drop positions in a box centred on the camera: continuous in time and shared by cameras
    pos = np.mod(p0 + vel * t_s - c + 0.5 * _DROP_BOX_M, _DROP_BOX_M) - 0.5 * _DROP_BOX_M + c
    R = T_world_cam[:3, :3]
    a_cam = (pos - c) @ R
    b_cam = (pos - vel * _EXPOSURE_S - c) @ R
    ok = (a_cam[:, 2] > 0.3) & (b_cam[:, 2] > 0.3)
    ua = cam.project(a_cam[ok])  # type: ignore[attr-defined]
    ub = cam.project(b_cam[ok])  # type: ignore[attr-defined]
    z = a_cam[ok, 2]
    inside = np.isfinite(ua).all(1) & (ua[:, 0] >= 0) & (ua[:, 0] < W - 1) & (ua[:, 1] >= 0) & (ua[:, 1] < H - 1)
    ua, ub, z = ua[inside], ub[inside], z[inside]
    visible = z < depth_m[np.round(ua[:, 1]).astype(int), np.round(ua[:, 0]).astype(int)]
    ua, ub = ua[visible], ub[visible]
    if len(ua) == 0:
        return None
    shift = 4
    seg = np.round(np.stack([ua, ub], 1) * (1 << shift)).astype(np.int32)
    mask = np.zeros((H, W), np.uint8)
    thick = max(1, round(W / 1024))
    cv2.polylines(mask, list(seg), False, 255, thick, cv2.LINE_AA, shift)
    return mask.astype(np.float32) * np.float32(brightness / 255.0)


@functools.lru_cache(maxsize=1)
def normal_table() -> F32:
    """The 65536 standard normal quantiles at ``(k + 0.5) / 65536`` (float32, read-only): indexed
    by 16 uniform random bits they give normal deviates (mean 0, standard deviation 0.99995)."""
    from scipy.special import ndtri

    out = ndtri((np.arange(65536) + 0.5) / 65536.0).astype(np.float32)
    out.setflags(write=False)
    return out


def add_sensor_noise(image: F32, gain: float, key: int) -> F32:
    """Gaussian read + shot noise on a 0..255 image (any shape), deterministic in ``key``."""
    from ._kernels import sensor_noise

    return np.asarray(sensor_noise(np.ascontiguousarray(image, dtype=np.float32), float(gain),
                                   int(key) & 0xFFFFFFFFFFFFFFFF, normal_table()), dtype=np.float32)


def sensor_output(image: F32, gain: float, key: int, *, noise: bool = True) -> npt.NDArray[np.uint8]:
    """The 8-bit image: ``rint(clip(add_sensor_noise(image, gain, key), 0, 255))`` (without noise:
    of ``image``), in one pass."""
    from ._kernels import quantize

    img = np.ascontiguousarray(image, dtype=np.float32)
    out = np.empty(img.shape, np.uint8)
    return np.asarray(quantize(img, float(gain), int(key) & 0xFFFFFFFFFFFFFFFF, normal_table(), bool(noise), out))
