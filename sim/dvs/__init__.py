"""DVS event camera: events from log-intensity changes between internal renders (ESIM / CARLA).

Model (``../shared/FORMATS.md``, Rebecq et al., "ESIM: an Open Event Camera Simulator", CoRL 2018;
CARLA's DVS sensor is a port of it):

- every internal render gives the linear intensity ``I`` (0..255, grey) and per pixel
  ``L = log(log_eps + I / 255)``;
- between two renders ``L`` moves linearly; each crossing of the pixel's reference level by
  ``+C`` (positive) or ``-C`` (negative) emits an event at the interpolated time and moves the
  reference by ``C``; ``C`` may carry ``N(0, sigma)`` noise (clamped at >= 0.01); an event within
  ``refractory_period_ns`` of the pixel's previous event is dropped; the stream is sorted by time
  (ties in raster order);
- adaptive sampling (ESIM's brightness-change criterion): from the last two renders the
  ``adaptive_quantile`` of ``|dL/dt|`` over the pixels predicts when the next render is due,
  ``dt = adaptive_fraction * C / q(|dL/dt|)``, clamped to ``[1 / max_internal_rate_hz, camera
  period]`` and never past a window boundary; ``adaptive=False`` renders at the fixed
  ``max_internal_rate_hz`` (the reference).  ESIM takes the maximum (``adaptive_quantile: 1``);
  on rendered scenes the maximum is set by step edges and rain streaks that jump by ~2.7 in
  ``L`` within any interval (measured at 2 ms), so it always asks for the highest rate.  Measured
  on the rendered dynamic town (stereo 512 px, 0.5 s at speed, against fixed 200 Hz): quantile
  0.9 -> 12 % of the renders, -8.5 % events; 0.99 -> 22 % of the renders, -4.8 %; 0.999 -> 56 %,
  -0.9 %; 1.0 -> every render of the fixed rate.  The default 0.99 trades 5 % of the events for
  a 4.6x faster simulation (``benchmarks/bench_dvs.py``);
- weather (rain and fog droplets): spurious events concentrated on a seeded minority of "noisy"
  pixels (``noisy_pixel_fraction``, each with its own weight in 0.75..1.25) plus a uniform background
  share, at a rate ``weather_noise_gain * level * R`` where ``level = (precipitation +
  fog_density) / 200`` at the window and ``R`` the scene's event rate in the window (at least
  ``weather_noise_floor_hz`` per pixel, so that a still view in the rain has noise too): the paper's
  FULL Dynamic-1 loses about a quarter of its events to the hot-pixel filter, and with the
  dynamic preset (rain ~45, fog ~70 => level ~0.58) the default gain gives that share.  Noise
  events have random polarity, uniform times inside the window and no refractory period.

Output: IBISCape windows ``events/<end_ns>.npz`` (one per camera frame period), ``timestamps.csv``
and accumulated frames ``frames/<end_ns>.png`` (see :mod:`ibiscape_eval.io.dvs_folder`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

if TYPE_CHECKING:
    from ..config import CameraSpec
    from ..weather import WeatherLog

__all__ = ["DvsConfig", "DvsResult", "DvsSimulator", "dvs_config_of", "weather_level", "write_dvs_camera"]

RenderGray = Callable[[int], npt.NDArray[np.float32]]
Progress = Callable[[float, str], None]


def _doc(text: str) -> Any:
    return {"doc": text}


@dataclass(frozen=True)
class DvsConfig:
    """DVS parameters (CARLA's attribute names; defaults are the paper's ``table:dvs``)."""

    positive_threshold: float = field(default=0.3, metadata=_doc(
        "contrast threshold C+ of log-intensity increases"))
    negative_threshold: float = field(default=0.3, metadata=_doc(
        "contrast threshold C- of log-intensity decreases"))
    sigma_positive_threshold: float = field(default=0.0, metadata=_doc(
        "std of the per-pixel, per-interval noise on C+"))
    sigma_negative_threshold: float = field(default=0.0, metadata=_doc(
        "std of the per-pixel, per-interval noise on C-"))
    refractory_period_ns: int = field(default=0, metadata=_doc(
        "minimum time between two events of one pixel [ns]"))
    log_eps: float = field(default=0.001, metadata=_doc(
        "L = log(log_eps + I / 255) (CARLA: 0.001; 0.05 in some scripts)"))
    adaptive: bool = field(default=True, metadata=_doc(
        "adaptive internal render times (ESIM); false: fixed max_internal_rate_hz"))
    adaptive_fraction: float = field(default=0.5, metadata=_doc(
        "predicted |delta L| (at adaptive_quantile) per internal step as a fraction of C"))
    adaptive_quantile: float = field(default=0.99, metadata=_doc(
        "quantile of |dL/dt| over the pixels that sets the step (1: the maximum, as ESIM)"))
    max_internal_rate_hz: float = field(default=200.0, metadata=_doc(
        "highest internal render rate (the fixed rate when adaptive is false) [Hz]"))
    weather_noise_gain: float = field(default=0.6, metadata=_doc(
        "spurious events per scene event at weather level 1 ((rain + fog) / 200)"))
    weather_noise_floor_hz: float = field(default=0.05, metadata=_doc(
        "scene rate assumed at least, per pixel [events/s]: rain and fog still fire on a still "
        "or featureless view"))
    noisy_pixel_fraction: float = field(default=0.001, metadata=_doc(
        "share of the sensor's pixels that rain/fog make noisy (recorded in sequence.yaml)"))
    noisy_pixel_share: float = field(default=0.9, metadata=_doc(
        "share of the weather noise on the noisy pixels; the rest is uniform background"))
    frames: bool = field(default=True, metadata=_doc("write accumulated frames/<ns>.png"))

    def __post_init__(self) -> None:
        for name in ("positive_threshold", "negative_threshold", "log_eps", "adaptive_fraction",
                     "max_internal_rate_hz"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise IbiscapeError(f"dvs: {name} must be a positive number, got {v!r}")
        for name in ("sigma_positive_threshold", "sigma_negative_threshold", "weather_noise_gain",
                     "weather_noise_floor_hz"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise IbiscapeError(f"dvs: {name} must be >= 0, got {v!r}")
        if not isinstance(self.refractory_period_ns, int) or self.refractory_period_ns < 0:
            raise IbiscapeError(f"dvs: refractory_period_ns must be an integer >= 0, got "
                                f"{self.refractory_period_ns!r}")
        if not (isinstance(self.adaptive_quantile, int | float) and 0 < self.adaptive_quantile <= 1):
            raise IbiscapeError(f"dvs: adaptive_quantile must be in (0, 1], got "
                                f"{self.adaptive_quantile!r}")
        for name in ("noisy_pixel_fraction", "noisy_pixel_share"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and 0 <= v <= 1):
                raise IbiscapeError(f"dvs: {name} must be in 0..1, got {v!r}")

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (YAML / JSON)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def sensor_dict(self) -> dict[str, Any]:
        """The sensor's settings for ``sequence.yaml: cameras.<name>.dvs`` (CARLA's names: the
        contrast thresholds and their noise, the refractory period, ``log_eps``, the internal
        sampling and the rain/fog noise settings; not the ``frames`` output switch)."""
        return {k: v for k, v in self.to_dict().items() if k != "frames"}


def dvs_config_of(cfg: Any) -> DvsConfig:
    """The DVS settings of a simulator configuration (its ``dvs`` entry, else the defaults)."""
    got = getattr(cfg, "dvs", None)
    return got if isinstance(got, DvsConfig) else DvsConfig()


@dataclass(frozen=True)
class DvsResult:
    """What :func:`write_dvs_camera` produced, for ``sequence.yaml: cameras.<name>.dvs``.

    Attributes
    ----------
    camera : str
        Camera (folder) name.
    n_events : int
        Events written (scene + weather noise).
    n_positive : int
        Of which positive.
    n_scene_events : int
        Events from intensity changes.
    n_noise_events : int
        Spurious rain/fog events (on the noisy pixels and the uniform background).
    n_noisy_pixel_events : int
        Of which on the noisy pixels.
    n_refractory_dropped : int
        Crossings dropped by the refractory period.
    n_windows : int
        ``events/<ns>.npz`` files.
    n_renders : int
        Internal renders (``render_gray`` calls).
    noisy_pixels : tuple of (x, y)
        Pixels made noisy by rain/fog (empty when the weather never brings rain or fog).
    config : DvsConfig
        The settings the events were simulated with (contrast thresholds, refractory period, ...).
    """

    camera: str
    n_events: int
    n_positive: int
    n_scene_events: int
    n_noise_events: int
    n_noisy_pixel_events: int
    n_refractory_dropped: int
    n_windows: int
    n_renders: int
    noisy_pixels: tuple[tuple[int, int], ...]
    config: DvsConfig = field(default_factory=DvsConfig)

    @property
    def noise_fraction(self) -> float:
        """Share of the events that rain/fog added (0 when there are no events)."""
        return self.n_noise_events / self.n_events if self.n_events else 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (strict JSON / YAML): the sensor settings (:meth:`DvsConfig.sensor_dict`:
        ``positive_threshold``, ``negative_threshold``, ``refractory_period_ns``, ...), the counts,
        ``noise_fraction`` and ``noisy_pixels`` as a list of ``[x, y]``."""
        return {**self.config.sensor_dict(), "camera": self.camera, "n_events": self.n_events, "n_positive": self.n_positive,
                "n_scene_events": self.n_scene_events, "n_noise_events": self.n_noise_events,
                "n_noisy_pixel_events": self.n_noisy_pixel_events,
                "n_refractory_dropped": self.n_refractory_dropped, "n_windows": self.n_windows,
                "n_renders": self.n_renders, "noise_fraction": round(self.noise_fraction, 6),
                "noisy_pixels": [[int(x), int(y)] for x, y in self.noisy_pixels]}

    def __repr__(self) -> str:
        return (f"DvsResult({self.camera}: {self.n_events} events in {self.n_windows} windows, "
                f"{self.n_renders} renders, noise {100 * self.noise_fraction:.1f}% on "
                f"{len(self.noisy_pixels)} noisy pixels)")


def weather_level(weather: WeatherLog | None, t_ns: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``(precipitation + fog_density) / 200`` (0..1) at ``t_ns``, linearly interpolated."""
    t = np.asarray(t_ns, dtype=np.int64)
    if weather is None or len(weather) == 0:
        return np.zeros(t.shape)
    lvl = (weather.column("precipitation") + weather.column("fog_density")) / 200.0
    return np.interp(t.astype(np.float64), weather.stamps_ns.astype(np.float64), lvl)


class DvsSimulator:
    """Per-pixel state of one DVS camera, advanced render by render.

    Parameters
    ----------
    shape : (int, int)
        Height, width in pixels.
    config : DvsConfig
    rng : numpy.random.Generator
        Threshold noise (only drawn when a sigma is set).
    """

    def __init__(self, shape: tuple[int, int], config: DvsConfig, rng: np.random.Generator) -> None:
        from ._kernels import NEVER

        self.h, self.w = (int(v) for v in shape)
        self.cfg = config
        self.rng = rng
        self.ref = np.zeros(self.h * self.w, np.float64)
        self.last_t = np.full(self.h * self.w, NEVER, np.int64)
        self.l_prev: np.ndarray | None = None
        self.t_prev = 0
        self.dropped = 0

    def log_intensity(self, gray: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """``log(log_eps + I / 255)`` of a (H, W) image, flattened."""
        g = np.asarray(gray)
        if g.shape != (self.h, self.w):
            raise IbiscapeError(f"dvs: render_gray returned shape {g.shape}, expected "
                                f"({self.h}, {self.w})")
        out = np.asarray(g, dtype=np.float64).reshape(-1) * (1.0 / 255.0)
        out += self.cfg.log_eps
        return np.log(out, out=out)

    def reset(self, t_ns: int, gray: npt.ArrayLike) -> None:
        """Start at ``t_ns``: the references are the current log intensities."""
        self.l_prev = self.log_intensity(gray)
        self.ref[:] = self.l_prev
        self.t_prev = int(t_ns)

    def step(self, t_ns: int, gray: npt.ArrayLike) -> tuple[Events, float]:
        """Advance to the render at ``t_ns``; return the interval's events (time-ordered) and
        the ``adaptive_quantile`` of ``|delta L|`` over the pixels in the interval."""
        from ._kernels import abs_diff_kth, crossings

        if self.l_prev is None:
            raise IbiscapeError("dvs: call reset() with the first render before step()")
        t = int(t_ns)
        dt = t - self.t_prev
        if dt <= 0:
            raise IbiscapeError(f"dvs: render times must increase, got {t} after {self.t_prev}")
        l1 = self.log_intensity(gray)
        c = self.cfg
        noise = (self.rng.standard_normal(l1.size)
                 if c.sigma_positive_threshold > 0 or c.sigma_negative_threshold > 0
                 else np.zeros(0))
        tt, idx, pol, dropped = crossings(self.l_prev, l1, self.ref, self.last_t, self.t_prev, dt,
                                          float(c.positive_threshold), float(c.negative_threshold),
                                          noise, float(c.sigma_positive_threshold),
                                          float(c.sigma_negative_threshold), 1e-9,
                                          int(c.refractory_period_ns))
        q = c.adaptive_quantile
        if not l1.size:
            dmax = 0.0
        elif q >= 1.0:
            dmax = float(np.abs(l1 - self.l_prev).max())
        else:  # the exact quantile, np.partition's value, in a fraction of its time
            dmax = float(abs_diff_kth(self.l_prev, l1, min(l1.size - 1, int(q * l1.size))))
        self.dropped += int(dropped)
        self.l_prev = l1
        self.t_prev = t
        order = np.argsort(tt, kind="stable")
        idx = idx[order]
        ev = Events(tt[order], (idx % self.w).astype(np.uint16), (idx // self.w).astype(np.uint16),
                    pol[order])
        return ev, dmax


class _WeatherNoise:
    """Spurious rain/fog events: noisy pixels + uniform background (see the module docstring)."""

    def __init__(self, shape: tuple[int, int], cfg: DvsConfig, rng: np.random.Generator,
                 active: bool) -> None:
        self.h, self.w = shape
        self.cfg = cfg
        self.rng = rng
        n_pix = self.h * self.w
        k = round(cfg.noisy_pixel_fraction * n_pix) if active else 0
        k = min(max(k, 1 if active and cfg.noisy_pixel_fraction > 0 else 0), n_pix)
        flat = np.sort(rng.choice(n_pix, size=k, replace=False)) if k else np.zeros(0, np.int64)
        self.pixels = flat.astype(np.int64)
        wts = rng.uniform(0.75, 1.25, size=k)
        self.weights = wts / wts.sum() if k else wts

    def events(self, a_ns: int, b_ns: int, n_scene: int, level: float) -> tuple[Events, int]:
        """Noise events of window ``[a, b)`` given its scene events and weather level."""
        if level <= 0 or self.cfg.weather_noise_gain <= 0 or b_ns <= a_ns:
            return Events.empty(), 0
        floor = self.cfg.weather_noise_floor_hz * 1e-9 * self.h * self.w * (b_ns - a_ns)
        mean = self.cfg.weather_noise_gain * level * max(float(n_scene), floor)
        share = self.cfg.noisy_pixel_share if self.pixels.size else 0.0
        counts = self.rng.poisson(mean * share * self.weights) if self.pixels.size else \
            np.zeros(0, np.int64)
        hot = np.repeat(self.pixels, counts)
        n_bg = int(self.rng.poisson(mean * (1.0 - share)))
        bg = self.rng.integers(0, self.h * self.w, size=n_bg)
        pix = np.concatenate([hot, bg])
        t = self.rng.integers(a_ns, b_ns, size=pix.size, dtype=np.int64)
        p = self.rng.random(pix.size) < 0.5
        return Events(t, (pix % self.w).astype(np.uint16), (pix // self.w).astype(np.uint16), p), \
            int(hot.size)


def _merge(a: Events, b: Events) -> Events:
    if len(b) == 0:
        return a
    ev = Events.concatenate([a, b])
    order = np.argsort(ev.t_ns, kind="stable")
    return Events(ev.t_ns[order], ev.x[order], ev.y[order], ev.p[order])


def _accumulate(ev: Events, shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    from ibiscape_eval.events.frames import frame_to_uint8

    h, w = shape
    pix = ev.y.astype(np.int64) * w + ev.x
    f = np.bincount(pix, weights=np.where(ev.p, 1.0, -1.0), minlength=h * w).reshape(h, w)
    return frame_to_uint8(f, kind="accumulate", signed=True)


def _window_events(sim: DvsSimulator, render_gray: RenderGray, a: int, b: int, dt: int,
                   cfg: DvsConfig) -> tuple[Events, int, int]:
    """The scene's events in the window ``(a, b]`` [ns], rendering every ``dt`` ns (adapted to the
    brightness change when ``cfg.adaptive``); returns the events, the next ``dt`` and the number
    of renders."""
    min_dt = max(1, round(1e9 / cfg.max_internal_rate_hz))
    c_min = min(cfg.positive_threshold, cfg.negative_threshold)
    parts: list[Events] = []
    t = a
    while t < b:
        t_next = min(t + dt, b)
        ev, dmax = sim.step(t_next, render_gray(t_next))
        parts.append(ev)
        if cfg.adaptive:
            rate = dmax / (t_next - t)  # that quantile of |dL/dt|, per ns
            want = cfg.adaptive_fraction * c_min / rate if rate > 0 else float(b - a)
            dt = int(min(max(want, min_dt), b - a))
        else:
            dt = min_dt
        t = t_next
    return Events.concatenate(parts), dt, len(parts)


def write_dvs_camera(render_gray: RenderGray, camera: CameraSpec, frame_stamps_ns: npt.ArrayLike,
                     out_dir: str | os.PathLike[str], *, dvs_config: DvsConfig | None = None,
                     weather: WeatherLog | None = None, rng: np.random.Generator | None = None,
                     progress: Progress | None = None) -> DvsResult:
    """Simulate one DVS camera and write its IBISCape folder.

    Parameters
    ----------
    render_gray : callable(t_ns: int) -> ndarray (H, W) float32
        Linear grey intensity 0..255 of the camera at any time (called in increasing time).
    camera : CameraSpec
        ``name``, ``width_px``, ``height_px``, ``rate_hz`` are used.
    frame_stamps_ns : array_like of int64, shape (N,), N >= 2
        Window boundaries (the camera frames): window ``i`` is ``[s[i-1], s[i]]`` and is written
        as ``events/<s[i]>.npz``; the first render is at ``s[0]`` (no events before it).
    out_dir : path
        The camera folder (the simulator's staging copy); ``events/``, ``frames/`` and
        ``timestamps.csv`` are written inside.
    dvs_config : DvsConfig, optional
    weather : WeatherLog, optional
        Weather per camera frame; rain and fog add spurious events (none when omitted).
    rng : numpy.random.Generator, optional
        The camera's own stream (noisy pixels, noise events, threshold noise); default seed 0.
    progress : callable(fraction, label), optional

    Returns
    -------
    DvsResult
        Counts and ``noisy_pixels`` (x, y) for ``sequence.yaml`` (use ``result.to_dict()``).
    """
    from ibiscape_eval.io.dvs_folder import DvsFolderWriter

    cfg = dvs_config or DvsConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    st = np.asarray(frame_stamps_ns, dtype=np.int64).reshape(-1)
    if st.size < 2 or np.any(np.diff(st) <= 0):
        raise IbiscapeError(f"dvs {camera.name}: frame stamps must be >= 2 increasing values, "
                            f"got {st.size}")
    shape = (int(camera.height_px), int(camera.width_px))
    sim = DvsSimulator(shape, cfg, rng)
    levels = weather_level(weather, (st[:-1] + st[1:]) // 2)
    noise = _WeatherNoise(shape, cfg, rng, active=bool(np.any(levels > 0)))
    writer = DvsFolderWriter(out_dir, frames=cfg.frames)
    sim.reset(int(st[0]), render_gray(int(st[0])))
    n_renders = 1
    dt = max(1, round(1e9 / cfg.max_internal_rate_hz))
    n_scene = n_noise = n_hot = n_pos = 0
    for i in range(1, st.size):
        a, b = int(st[i - 1]), int(st[i])
        scene, dt, renders = _window_events(sim, render_gray, a, b, dt, cfg)
        n_renders += renders
        extra, hot = noise.events(a, b, len(scene), float(levels[i - 1]))
        ev = _merge(scene, extra)
        n_scene += len(scene)
        n_noise += len(extra)
        n_hot += hot
        n_pos += int(np.count_nonzero(ev.p))
        writer.add(a, b, ev, _accumulate(ev, shape) if cfg.frames else None)
        if progress is not None:
            progress(i / (st.size - 1), f"dvs {camera.name}")
    n_windows = writer.close()
    pixels = tuple((int(p % shape[1]), int(p // shape[1])) for p in noise.pixels)
    return DvsResult(camera=camera.name, n_events=n_scene + n_noise, n_positive=n_pos,
                     n_scene_events=n_scene, n_noise_events=n_noise, n_noisy_pixel_events=n_hot,
                     n_refractory_dropped=sim.dropped, n_windows=n_windows, n_renders=n_renders,
                     noisy_pixels=pixels, config=cfg)
