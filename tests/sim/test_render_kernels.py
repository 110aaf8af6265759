"""The renderer's fused numba passes against the per-stage reference functions they replace, the
seeded sensor noise, and the shortcuts that skip work (movers' pixels, movers' shadows) against
renders that do all the work."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.sim.render import Renderer
from ibiscape_eval.sim.render._kernels import finish
from ibiscape_eval.sim.render.labels import TAG
from ibiscape_eval.sim.render.optics import (
    add_sensor_noise,
    fog,
    fog_beta_per_m,
    normal_table,
    puddles,
    sensor_output,
)
from ibiscape_eval.sim.render.rays import world_rays
from ibiscape_eval.sim.render.shading import (
    _HORIZON,
    _OVERCAST,
    _ZENITH,
    WeatherState,
    horizon_radiance,
    lighting,
    shade,
    sky_radiance,
)
from ibiscape_eval.sim.render.textures import noise_table, sample_bilinear

T0 = 1_000_000_000_000


# ------------------------------------------------------------------------------------ sensor noise
def test_normal_table_is_the_normal_quantiles() -> None:
    t = normal_table()
    k = np.array([0, 1, 1000, 32767, 32768, 50000, 65535])
    np.testing.assert_allclose(t[k], stats.norm.ppf((k + 0.5) / 65536), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(t, -t[::-1])  # symmetric
    assert abs(float(t.astype(np.float64).std()) - 1.0) < 1e-3 and np.all(np.diff(t) > 0)


def test_sensor_noise_has_the_model_sigma_and_is_normal() -> None:
    img = np.full((256, 256, 3), 100.0, np.float32)
    gain = 2.0
    z = (add_sensor_noise(img, gain, 12345) - 100.0).ravel()
    sigma = math.sqrt((0.6 * gain) ** 2 + 0.04 * gain * 100.0)
    assert abs(z.mean()) < 0.01 * sigma * 3
    assert abs(z.std() / sigma - 1.0) < 0.01
    assert stats.kstest(z[:20000] / sigma, "norm").pvalue > 1e-3
    # neighbouring values are independent (four share one hash)
    zz = z.reshape(-1, 4) / sigma
    corr = np.corrcoef(zz.T)
    assert np.abs(corr - np.eye(4)).max() < 0.02


def test_sensor_noise_is_counter_based_and_keyed() -> None:
    img = np.linspace(0.0, 255.0, 3000, dtype=np.float32)
    a = add_sensor_noise(img, 1.0, 7)
    np.testing.assert_array_equal(add_sensor_noise(img[:1001], 1.0, 7), a[:1001])  # same value index, same deviate
    np.testing.assert_array_equal(add_sensor_noise(img.reshape(30, 100), 1.0, 7).ravel(), a)
    assert np.mean(add_sensor_noise(img, 1.0, 8) != a) > 0.99


@pytest.mark.parametrize("noise", [True, False])
def test_sensor_output_is_rounded_clipped_noisy_image(noise: bool) -> None:
    rng = np.random.default_rng(3)
    img = rng.uniform(-20.0, 275.0, (37, 41, 3)).astype(np.float32)
    img[0, :4, 0] = [0.5, 1.5, 2.5, 254.5]  # halves round to even, like np.rint
    got = sensor_output(img, 3.0, 99, noise=noise)
    ref = add_sensor_noise(img, 3.0, 99) if noise else img
    np.testing.assert_array_equal(got, np.clip(np.rint(ref), 0, 255).astype(np.uint8))
    assert got.dtype == np.uint8 and got.shape == img.shape


# ----------------------------------------------------------------------------------- fused passes
def test_world_rays_rotate_and_place_the_camera_rays() -> None:
    rng = np.random.default_rng(0)
    d = rng.normal(size=(5, 7, 3)).astype(np.float32)
    T = np.eye(4)
    T[:3, :3] = stats.special_ortho_group.rvs(3, random_state=1)
    T[:3, 3] = (10.0, -3.0, 2.0)
    r = world_rays(d, T)
    assert r.shape == (5, 7, 6) and r.dtype == np.float32
    np.testing.assert_allclose(r[..., 3:], d.astype(np.float64) @ T[:3, :3].T, rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(r[..., :3], np.broadcast_to(T[:3, 3].astype(np.float32), (5, 7, 3)))


@pytest.mark.parametrize("weather", [
    {},
    {"fog_density": 60.0},
    {"wetness": 70.0, "precipitation_deposits": 80.0, "cloudiness": 40.0},
    {"wetness": 100.0, "precipitation_deposits": 100.0, "fog_density": 30.0, "sun_altitude_angle": 8.0},
])
def test_finish_equals_the_reference_stages(weather: dict) -> None:
    """The fused shading pass against shade, sky_radiance, puddles and fog applied in turn."""
    w = WeatherState(**weather)
    light = lighting(w)
    rng = np.random.default_rng(5)
    n = 4000
    alb = rng.uniform(0.0, 1.0, (n, 3)).astype(np.float32)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = nrm.astype(np.float32)
    visible = rng.uniform(size=n) > 0.3
    rays = np.zeros((n, 6), np.float32)
    rays[:, 3:] = rng.normal(size=(n, 3)) * [1.0, 1.0, 0.5] + [0.0, 0.0, -0.2]
    depth = rng.uniform(0.5, 400.0, n).astype(np.float32)
    depth[rng.uniform(size=n) < 0.2] = np.inf
    paved = np.where(rng.uniform(size=n) < 0.5, rng.uniform(0.0, 1.0, n), 0.0).astype(np.float32)
    uv = rng.uniform(-200.0, 200.0, (n, 2)).astype(np.float32)
    hit = np.isfinite(depth)
    sun = np.asarray(light.sun_dir, np.float32)
    ndl = np.where(visible, np.maximum(nrm @ sun, 0.0), 0.0).astype(np.float32)
    amb = (0.6 + 0.4 * nrm[:, 2]).astype(np.float32)
    wet = w.wetness / 100.0
    level = 1.6 - 2.2 * w.precipitation_deposits / 100.0 if w.precipitation_deposits > 0 else np.inf
    beta = fog_beta_per_m(w.fog_density)
    scale = 255.0 * light.gain
    sky = (np.float32(light.e_sun), np.float32(light.e_sky), _ZENITH, _HORIZON, _OVERCAST,
           np.float32(w.cloudiness / 100.0), np.float32(1.6 * light.e_sky + 0.25 * light.e_sun))
    optics = (np.float32(wet), np.float32(level), np.float32(beta), horizon_radiance(w, light), np.float32(1000.0))
    got = finish(alb, ndl, amb, depth, rays, paved, uv, noise_table(), sky, optics, np.float32(scale))
    # the reference, stage by stage (numpy)
    dn = np.linalg.norm(rays[:, 3:], axis=1)
    ref = shade(alb * (1.0 - 0.45 * wet * paved)[:, None], nrm, visible, light)
    ref[~hit] = sky_radiance(rays[~hit, 5] / dn[~hit], w, light)
    if np.isfinite(level):
        pv = np.flatnonzero(hit & (paved > 0))
        pn = sample_bilinear(noise_table(), uv[pv, 0] * 0.45 + 11.0, uv[pv, 1] * 0.45 + 5.0, wrap=True)
        ref[pv] = puddles(ref[pv], paved[pv], pn, sky_radiance(-rays[pv, 5] / dn[pv], w, light), w)
    ref = fog(ref, np.where(hit, depth * dn, np.inf).astype(np.float32), beta, horizon_radiance(w, light))
    np.testing.assert_allclose(got, ref * scale, rtol=1e-4, atol=1e-3)  # float32 rounding, 1/1000 DN


# ------------------------------------------------------------------------- work the renderer skips
@pytest.fixture(scope="module")
def dynamic(town_dynamic: Renderer) -> Renderer:
    return town_dynamic


def _look(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
    T[:3, 3] = eye
    return T


def _car(r: Renderer) -> tuple[np.ndarray, float]:
    ag = r.world.agents
    pos, yaw = ag.poses_at(np.array([T0]))
    a = int(np.argmax(ag.kind_id == 0))
    return pos[a, 0], float(yaw[a, 0])


def test_car_straddling_the_camera_plane_is_cast_only_where_seen(dynamic: Renderer, monkeypatch) -> None:
    """A car half behind the camera: its pixels come from its outline clipped at the near plane
    (no longer 'cast every ray'), and the render equals one that casts every ray."""
    p, yaw = _car(dynamic)
    fwd, left = np.array([math.cos(yaw), math.sin(yaw), 0.0]), np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    eye = p + 3.5 * left + np.array([0.0, 0.0, 1.2])  # beside the car (outside its bounding box)
    T = _look(eye, eye + 10.0 * fwd - 4.0 * left - np.array([0.0, 0.0, 1.0]))  # ahead, toward its bonnet
    model = CameraModel.from_fov(120, 90, 100.0)
    mask = dynamic._mover_pixels(model, T, T0)
    assert mask is not None and 0.0 < mask.mean() < 0.9
    sunny = WeatherState(sun_altitude_angle=40.0)
    v = dynamic.render_pose(model, T, T0, weather=sunny)
    assert (v.labels == TAG["Vehicles"]).sum() > 200
    assert mask[(v.labels == TAG["Vehicles"]).ravel()].all()
    monkeypatch.setattr(Renderer, "_mover_pixels", lambda self, *a: None)
    full = dynamic.render_pose(model, T, T0, weather=sunny)
    np.testing.assert_array_equal(v.labels, full.labels)
    np.testing.assert_array_equal(v.depth_m, full.depth_m)
    np.testing.assert_array_equal(v.radiance, full.radiance)


@pytest.mark.parametrize(("sun_altitude", "sun_from_heading"), [(30.0, 30.0), (60.0, 150.0)])
def test_mover_shadows_equal_casting_every_shadow_ray(dynamic: Renderer, monkeypatch, sun_altitude: float,
                                                      sun_from_heading: float) -> None:
    """Shadow rays ask the movers' scene only inside the movers' outlines seen along the sun; the
    image equals asking it for every ray, and differs from asking it for none (cars do shade)."""
    p, yaw = _car(dynamic)
    w = WeatherState(sun_altitude_angle=sun_altitude, sun_azimuth_angle=math.degrees(yaw) + sun_from_heading,
                     cloudiness=0.0)
    eye = p + np.array([0.0, 0.0, 9.0]) - 6.0 * np.array([math.cos(yaw), math.sin(yaw), 0.0])
    T = _look(eye, p)  # from above and behind: the car and its shadow
    model = CameraModel.from_fov(96, 96, 80.0)
    limited = dynamic.render_pose(model, T, T0, weather=w).radiance
    e = np.zeros(3, np.float32)
    everywhere = (np.ones((1, 1), bool), np.float32(-1e7), np.float32(-1e7), np.float32(1e9), e, e)
    nowhere = (np.zeros((1, 1), bool), np.float32(0.0), np.float32(0.0), np.float32(1.0), e, e)
    monkeypatch.setattr(Renderer, "_sun_grid", lambda self, *a: everywhere)
    all_rays = dynamic.render_pose(model, T, T0, weather=w).radiance
    monkeypatch.setattr(Renderer, "_sun_grid", lambda self, *a: nowhere)
    none = dynamic.render_pose(model, T, T0, weather=w).radiance
    np.testing.assert_array_equal(limited, all_rays)
    assert (np.abs(none - limited).max(axis=2) > 5.0).sum() > 100


def test_pinhole_subpixel_rays_equal_unproject_bit_for_bit() -> None:
    """The numba supersample directions of an undistorted camera are CameraModel.unproject's,
    bit for bit (so the rendered images do not change, #25)."""
    from ibiscape_eval.sim.render.rays import subpixel_rays

    model = CameraModel(97, 61, 80.5, 81.25, 48.3, 29.9)
    rows, cols = np.meshgrid(np.arange(61), np.arange(97), indexing="ij")
    rows, cols = rows.ravel(), cols.ravel()
    for s in (2, 5, 6):
        off = (np.arange(s) + 0.5) / s - 0.5
        du, dv = np.meshgrid(off, off)
        uv = np.stack([cols[:, None] + du.ravel()[None, :], rows[:, None] + dv.ravel()[None, :]], axis=-1)
        ref = model.unproject(uv)[0].astype(np.float32)
        assert np.array_equal(subpixel_rays(model, rows, cols, s), ref)


@pytest.mark.parametrize("coeffs", [(-0.28, 0.07, 1e-4, -2e-4), (-0.09, 0.0, 0.002, -0.001)])
def test_radtan_subpixel_rays_equal_unproject_bit_for_bit(coeffs) -> None:
    """The supersample directions of a radial-tangential camera are CameraModel.unproject's, bit
    for bit; sub-samples that do not invert (the strongly distorted corners of the second model)
    take their pixel centre's ray (NaN where that fails too)."""
    from ibiscape_eval.sim.render.rays import subpixel_rays

    model = CameraModel(97, 61, 40.5, 41.25, 48.3, 29.9, "radtan", coeffs)
    rows, cols = np.meshgrid(np.arange(61), np.arange(97), indexing="ij")
    rows, cols = rows.ravel(), cols.ravel()
    for s in (1, 3, 6):
        off = (np.arange(s) + 0.5) / s - 0.5
        du, dv = np.meshgrid(off, off)
        uv = np.stack([cols[:, None] + du.ravel()[None, :], rows[:, None] + dv.ravel()[None, :]], axis=-1)
        ref, ok = model.unproject(uv)
        centre = model.unproject(np.stack([cols, rows], axis=-1).astype(float))[0]
        ref = np.where(ok[..., None], ref, centre[:, None, :]).astype(np.float32)
        np.testing.assert_array_equal(subpixel_rays(model, rows, cols, s), ref)
        if coeffs[0] == -0.09 and s == 6:
            assert 0 < (~ok).sum() < ok.size  # the fallback is exercised


@pytest.mark.parametrize("model", [CameraModel.from_fov(90, 70, 100.0),
                                   CameraModel(90, 70, 40.0, 42.0, 44.3, 36.6, "radtan", (-0.3, 0.08, 2e-4, -3e-4))])
def test_rectangle_mask_in_its_window_equals_testing_every_pixel(model: CameraModel) -> None:
    """The movers' outlines straddling the camera plane mark the pixels whose directions fall
    inside them, testing only the rows and columns that the rays' envelopes leave: the same
    pixels as testing every pixel, for a pinhole and a distorted camera, rectangles inside,
    across and beside the image."""
    from ibiscape_eval.sim.render._kernels import rect_mask
    from ibiscape_eval.sim.render.rays import camera_rays
    from ibiscape_eval.sim.render.renderer import _rect_window

    dirs = camera_rays(model)
    x, y = dirs[..., 0], dirs[..., 1]
    rng = np.random.default_rng(11)
    marked = 0
    for _ in range(40):
        c = rng.uniform(-1.8, 1.8, 2)
        h = rng.uniform(0.01, 0.6, 2)
        rects = np.array([[c[0] - h[0], c[0] + h[0], c[1] - h[1], c[1] + h[1]]], np.float32)
        want = (rects[0, 0] <= x) & (x <= rects[0, 1]) & (rects[0, 2] <= y) & (y <= rects[0, 3])
        got = rect_mask(dirs, rects, np.zeros(x.shape, bool), _rect_window(dirs, rects))
        np.testing.assert_array_equal(got, want)
        marked += int(want.any())
    assert 5 < marked < 40  # some rectangles see pixels, some do not
