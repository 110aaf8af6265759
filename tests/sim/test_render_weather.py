"""Weather optics: Koschmieder fog, dim light and its noise, rain streaks along the wind, wet road."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render.labels import TAG
from ibiscape_eval.sim.render.optics import fog, fog_beta_per_m
from ibiscape_eval.sim.render.renderer import GRAY_WEIGHTS
from ibiscape_eval.sim.render.shading import WeatherState, lighting
from ibiscape_eval.sim.world import build_world

MODEL = CameraModel.from_fov(96, 72, 90.0)


def _forward(x: float, y: float, yaw_rad: float, z: float = 2.8, pitch_down_deg: float = 0.0) -> np.ndarray:
    fwd = np.array([math.cos(yaw_rad), math.sin(yaw_rad), 0.0])
    p = math.radians(pitch_down_deg)
    zc = math.cos(p) * fwd + np.array([0.0, 0.0, -math.sin(p)])
    xc = np.cross(zc, [0.0, 0.0, 1.0])
    xc /= np.linalg.norm(xc)
    T = np.eye(4)
    T[:3, :3] = np.stack([xc, np.cross(zc, xc), zc], 1)
    T[:3, 3] = (x, y, z)
    return T


@pytest.fixture(scope="module")
def town() -> Renderer:
    return Renderer(build_world(kind="slam", seed=1, town_blocks=2), options=RenderOptions(noise=False))


def test_koschmieder_formula() -> None:
    j = np.array([[0.2, 0.4, 0.6]], np.float32)
    a = np.array([0.8, 0.8, 0.8], np.float32)
    beta = fog_beta_per_m(50.0)
    out = fog(j, np.array([30.0], np.float32), beta, a)
    t = math.exp(-beta * 30.0)
    np.testing.assert_allclose(out[0], j[0] * t + a * (1 - t), rtol=1e-6)
    assert fog_beta_per_m(0.0) == 0.0 and fog_beta_per_m(100.0) == pytest.approx(0.12)


def test_contrast_falls_monotonically_with_fog_density(town: Renderer) -> None:
    T = _forward(40.0, -1.75, 0.0)
    contrast = []
    for f in (0.0, 10.0, 25.0, 40.0, 60.0, 80.0, 100.0):
        g = town.render_pose(MODEL, T, weather=WeatherState(fog_density=f)).radiance @ GRAY_WEIGHTS
        contrast.append(float(g.std() / g.mean()))
    assert all(b < a for a, b in itertools.pairwise(contrast)), contrast
    assert contrast[-1] < 0.3 * contrast[0]


def test_dim_light_at_low_sun_and_more_noise_in_the_dark(town: Renderer) -> None:
    alts = [60.0, 30.0, 10.0, 0.0, -10.0, -30.0]
    light = [lighting(WeatherState(sun_altitude_angle=a)) for a in alts]
    total = [x.e_sun + x.e_sky for x in light]
    assert all(b < a for a, b in itertools.pairwise(total))
    assert light[0].gain == 1.0 and light[-1].gain > 4.0
    noisy = Renderer.__new__(Renderer)
    noisy.__dict__.update(town.__dict__)
    noisy.options = RenderOptions(noise=True, psf_sigma_px=0.0)
    T = _forward(40.0, -1.75, 0.0)
    sigma = []
    for a in (50.0, -25.0):
        v = noisy.render_pose(MODEL, T, weather=WeatherState(sun_altitude_angle=a))
        sigma.append(float((v.rgb.astype(np.float32) - v.radiance)[v.radiance < 250].std()))
    assert sigma[1] > 2.0 * sigma[0], sigma


def _streaks(r: Renderer, T: np.ndarray, **weather: float) -> np.ndarray:
    dry = r.render_pose(MODEL, T, 1_000_000_000_000, weather=WeatherState()).radiance @ GRAY_WEIGHTS
    wet = r.render_pose(MODEL, T, 1_000_000_000_000, weather=WeatherState(**weather)).radiance @ GRAY_WEIGHTS
    return np.abs(wet - dry)


def _streak_angle_deg(diff: np.ndarray) -> float:
    """Direction of the streaks from the image's vertical (structure tensor of the difference)."""
    gy, gx = np.gradient(diff)
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    grad_dir = 0.5 * math.atan2(2 * jxy, jxx - jyy)  # dominant gradient direction from +x
    return math.degrees(abs(math.atan(math.tan(grad_dir))))  # streaks are perpendicular to it


def test_rain_streaks_follow_the_wind_and_the_rain(town: Renderer) -> None:
    r = Renderer.__new__(Renderer)
    r.__dict__.update(town.__dict__)
    r.options = RenderOptions(noise=False, psf_sigma_px=0.0)
    across = math.radians(35.0) + math.pi / 2  # looking across the wind (it blows toward 35 deg)
    T = _forward(40.0, -1.75, across)
    calm = _streaks(r, T, precipitation=80.0, wind_intensity=0.0)
    windy = _streaks(r, T, precipitation=80.0, wind_intensity=100.0)
    light_rain = _streaks(r, T, precipitation=20.0, wind_intensity=0.0)
    assert (calm > 1).sum() > 2 * max(1, (light_rain > 1).sum()) > 2
    assert _streak_angle_deg(calm) < 12.0  # falling straight down: vertical in a level camera
    assert _streak_angle_deg(windy) > 25.0  # 8 m/s of cross wind on 7 m/s of fall: ~49 deg


def test_wet_road_darker_and_puddles_mirror_the_sky(town: Renderer) -> None:
    T = _forward(40.0, -1.75, 0.0, pitch_down_deg=25.0)
    views = {k: town.render_pose(MODEL, T, weather=WeatherState(**w)) for k, w in {
        "dry": {}, "wet": {"wetness": 100.0}, "puddles": {"wetness": 100.0, "precipitation_deposits": 100.0}
    }.items()}
    road = views["dry"].labels == TAG["Road"]
    assert road.sum() > 100
    mean = {k: float((v.radiance @ GRAY_WEIGHTS)[road].mean()) for k, v in views.items()}
    assert mean["wet"] < 0.75 * mean["dry"]
    assert mean["puddles"] > mean["wet"]  # the sky in the water is brighter than wet asphalt
    blue = views["puddles"].radiance[road]
    assert (blue[:, 2] - blue[:, 0]).mean() > (views["wet"].radiance[road][:, 2] - views["wet"].radiance[road][:, 0]).mean()
