"""Synthetic grey scenes for the DVS model without the renderer (tests, examples, benchmarks).

Each returns ``render_gray(t_ns) -> (H, W) float32`` linear intensity in 0..255, the callable
:func:`ibiscape_eval.sim.dvs.write_dvs_camera` takes.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

__all__ = ["brightness_ramp", "log_ramp", "translating_texture"]

RenderGray = Callable[[int], npt.NDArray[np.float32]]


def log_ramp(shape: tuple[int, int], t0_ns: int, slope_per_s: npt.ArrayLike, *,
             l0: float = math.log(0.101), log_eps: float = 0.001) -> RenderGray:
    """An image whose log intensity ``L = log(log_eps + I/255)`` is exactly linear in time:
    ``L(t) = l0 + slope * (t - t0)`` per pixel (``slope_per_s`` scalar or (H, W), 1/s).

    The known answer: a pixel crosses ``|L(t1) - L(t0)| / C`` levels, the k-th at
    ``t0 + k C / |slope|``.
    """
    slope = np.broadcast_to(np.asarray(slope_per_s, dtype=np.float64), shape)

    def render(t_ns: int) -> npt.NDArray[np.float32]:
        lvl = l0 + slope * ((int(t_ns) - int(t0_ns)) * 1e-9)
        return (255.0 * (np.exp(lvl) - log_eps)).astype(np.float32)

    return render


def brightness_ramp(shape: tuple[int, int], t0_ns: int, *, start: float = 20.0,
                    rate_per_s: float = 100.0) -> RenderGray:
    """Uniform image brightening linearly in intensity: ``I = start + rate * (t - t0)``."""

    def render(t_ns: int) -> npt.NDArray[np.float32]:
        v = start + rate_per_s * (int(t_ns) - int(t0_ns)) * 1e-9
        return np.full(shape, np.clip(v, 0.0, 255.0), np.float32)

    return render


def translating_texture(shape: tuple[int, int], t0_ns: int, *, speed_px_s: float = 60.0,
                        seed: int = 0, blur_px: float = 1.5) -> RenderGray:
    """A rendered-looking texture (smoothed noise blobs over a few sharp-edged blocks) moving
    sideways at ``speed_px_s`` (bilinear sub-pixel shift, periodic), brightness 10..245."""
    from scipy.ndimage import gaussian_filter

    h, w = shape
    rng = np.random.default_rng(seed)
    tex = gaussian_filter(rng.standard_normal((h, w)), 6.0, mode="wrap")
    tex = (tex - tex.min()) / max(float(np.ptp(tex)), 1e-12)
    for _ in range(12):
        y0, x0 = rng.integers(0, h), rng.integers(0, w)
        hh, ww = rng.integers(h // 16 + 1, h // 4 + 2), rng.integers(w // 16 + 1, w // 4 + 2)
        ys = (np.arange(y0, y0 + hh) % h)[:, None]
        xs = (np.arange(x0, x0 + ww) % w)[None, :]
        tex[ys, xs] = 0.5 * tex[ys, xs] + 0.5 * rng.uniform(0.0, 1.0)
    tex = gaussian_filter(tex, blur_px, mode="wrap")
    tex = (10.0 + 235.0 * (tex - tex.min()) / max(float(np.ptp(tex)), 1e-12)).astype(np.float32)

    def render(t_ns: int) -> npt.NDArray[np.float32]:
        s = speed_px_s * (int(t_ns) - int(t0_ns)) * 1e-9
        k = math.floor(s)
        f = np.float32(s - k)
        a = np.roll(tex, k, axis=1)
        b = np.roll(tex, k + 1, axis=1)
        return a + f * (b - a)

    return render
