"""Synthetic DVS event streams with planted hot pixels, for tests, the demo and the benchmark.

The scene is a bright vertical edge sweeping across the sensor at constant speed (positive
events on the column it enters, negative on the one it leaves), uniform background activity,
and a few hot pixels firing at a high constant rate (Poisson).  Every pixel the edge crosses
gets about the same number of events, so the planted pixels are the only outliers.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

__all__ = ["SyntheticStream", "synthetic_events", "synthetic_windows"]


@dataclass(frozen=True, eq=False)
class SyntheticStream:
    """A generated recording and what was planted in it.

    Attributes
    ----------
    events : Events
        The stream, sorted by time.
    hot_pixels : ndarray, shape (K, 2), int64
        The planted hot pixels as x, y (row-major order).
    sensor_size : (int, int)
        Width, height in pixels.
    """

    events: Events
    hot_pixels: npt.NDArray[np.int64]
    sensor_size: tuple[int, int]


def _plant(rng: np.random.Generator, w: int, h: int, n_hot: int) -> np.ndarray:
    if n_hot > w * h:
        raise IbiscapeError(f"cannot plant {n_hot} hot pixels on a {w}x{h} sensor")
    flat = np.sort(rng.choice(w * h, size=n_hot, replace=False))
    return np.stack([flat % w, flat // w], axis=1).astype(np.int64)


@dataclass(frozen=True, eq=False)
class _Scene:
    """What :func:`synthetic_windows` draws: sensor, edge, background and hot pixels."""

    w: int
    h: int
    t0_ns: int
    speed_px_s: float
    edge_rate_hz: float
    noise_rate_hz: float
    hot: np.ndarray
    hot_rate_hz: float


def _window(rng: np.random.Generator, sc: _Scene, a: int, b: int) -> Events:
    """The events of the window ``[a, b)`` ns, sorted by time."""
    w, h, hot = sc.w, sc.h, sc.hot
    dt_s = (b - a) * 1e-9
    # moving edge: column = speed * t (mod width); both the entering (+) and the leaving
    # (-) column fire
    n_e = rng.poisson(sc.edge_rate_hz * dt_s)
    te = rng.integers(a, b, size=n_e)
    col = np.floor(sc.speed_px_s * (te - sc.t0_ns) * 1e-9).astype(np.int64)
    pos = rng.random(n_e) < 0.5
    xe = np.where(pos, col, col - w // 4) % w
    ye = rng.integers(0, h, size=n_e)
    # background activity
    n_n = rng.poisson(sc.noise_rate_hz * w * h * dt_s)
    tn = rng.integers(a, b, size=n_n)
    xn = rng.integers(0, w, size=n_n)
    yn = rng.integers(0, h, size=n_n)
    pn = rng.random(n_n) < 0.5
    # hot pixels
    per = rng.poisson(sc.hot_rate_hz * dt_s, size=len(hot))
    th = rng.integers(a, b, size=int(per.sum()))
    xh = np.repeat(hot[:, 0], per)
    yh = np.repeat(hot[:, 1], per)
    ph = rng.random(th.size) < 0.5
    t = np.concatenate([te, tn, th])
    order = np.argsort(t, kind="stable")
    return Events(
        t[order],
        np.concatenate([xe, xn, xh]).astype(np.uint16)[order],
        np.concatenate([ye, yn, yh]).astype(np.uint16)[order],
        np.concatenate([pos, pn, ph])[order],
    )


def synthetic_windows(
    *,
    sensor_size: tuple[int, int] = (64, 48),
    duration_s: float = 1.0,
    window_s: float = 0.05,
    edge_rate_hz: float = 200_000.0,
    edge_speed_px_s: float | None = None,
    noise_rate_hz: float = 5.0,
    n_hot: int = 5,
    hot_rate_hz: float = 2000.0,
    hot_pixels: npt.ArrayLike | None = None,
    t0_ns: int = 1_000_000_000,
    seed: int = 0,
) -> tuple[np.ndarray, Iterator[tuple[int, int, Events]]]:
    """Generate a recording window by window (bounded memory, any length).

    Parameters
    ----------
    sensor_size : (int, int)
        Width, height in pixels.
    duration_s, window_s : float
        Length of the recording and of each window, seconds.
    edge_rate_hz : float
        Events per second produced by the moving edge (whole sensor).
    edge_speed_px_s : float, optional
        Edge speed in pixels per second; default: one sweep of the width per 0.25 s.
    noise_rate_hz : float
        Background events per second per pixel.
    n_hot : int
        Hot pixels to plant at random (ignored if ``hot_pixels`` is given).
    hot_rate_hz : float
        Events per second of each hot pixel.
    hot_pixels : array_like, shape (K, 2), optional
        Explicit hot pixels (x, y).
    t0_ns : int
        Time of the first window's start, ns.
    seed : int
        Seed of the random generator.

    Returns
    -------
    hot_pixels : ndarray, shape (K, 2), int64
    windows : iterator of (t_start_ns, t_end_ns, Events)
    """
    w, h = (int(v) for v in sensor_size)
    rng = np.random.default_rng(seed)
    hot = (
        _plant(rng, w, h, int(n_hot))
        if hot_pixels is None
        else np.asarray(hot_pixels, dtype=np.int64).reshape(-1, 2)
    )
    speed = float(edge_speed_px_s) if edge_speed_px_s is not None else w / 0.25
    win_ns = max(1, round(window_s * 1e9))
    n_win = max(1, int(np.ceil(duration_s * 1e9 / win_ns)))

    scene = _Scene(w=w, h=h, t0_ns=int(t0_ns), speed_px_s=speed, edge_rate_hz=edge_rate_hz,
                   noise_rate_hz=noise_rate_hz, hot=hot, hot_rate_hz=hot_rate_hz)

    def gen() -> Iterator[tuple[int, int, Events]]:
        for k in range(n_win):
            a = t0_ns + k * win_ns
            yield a, a + win_ns, _window(rng, scene, a, a + win_ns)

    return hot, gen()


def synthetic_events(
    *,
    sensor_size: tuple[int, int] = (64, 48),
    duration_s: float = 1.0,
    edge_rate_hz: float = 200_000.0,
    noise_rate_hz: float = 5.0,
    n_hot: int = 5,
    hot_rate_hz: float = 2000.0,
    hot_pixels: npt.ArrayLike | None = None,
    seed: int = 0,
) -> SyntheticStream:
    """A whole synthetic recording in memory (see :func:`synthetic_windows` for the options).

    Examples
    --------
    >>> s = synthetic_events(sensor_size=(64, 48), n_hot=5, seed=1)
    >>> s.hot_pixels.shape
    (5, 2)
    """
    hot, windows = synthetic_windows(
        sensor_size=sensor_size, duration_s=duration_s, window_s=duration_s,
        edge_rate_hz=edge_rate_hz, noise_rate_hz=noise_rate_hz, n_hot=n_hot,
        hot_rate_hz=hot_rate_hz, hot_pixels=hot_pixels, seed=seed,
    )
    ev = Events.concatenate([e for _, _, e in windows])
    return SyntheticStream(ev, hot, (int(sensor_size[0]), int(sensor_size[1])))
