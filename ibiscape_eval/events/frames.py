"""Event frames for viewing and for frame-based (DVS) calibration.

* accumulation frames: events per pixel in a time window, signed (positive minus negative) or
  unsigned counts;
* time surfaces: ``exp(-(t_frame - t_last) / tau)`` of the latest event of every pixel
  (Lagorce et al., "HOTS", IEEE TPAMI 2017), optionally signed by that event's polarity.

Frames are produced at a fixed rate (``rate_hz``; each integrating the last ``window_ns``, by
default one period) or for explicit windows (e.g. the IBISCape ``timestamps.csv`` windows).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import DegenerateInputError, IbiscapeError
from ibiscape_eval.core.events import Events

__all__ = ["EventFrames", "accumulate_frames", "frame_windows", "iter_frames", "time_surfaces"]

KINDS = ("accumulate", "time-surface")


@dataclass(frozen=True, eq=False)
class EventFrames:
    """A stack of event frames.

    Attributes
    ----------
    frames : ndarray, shape (F, H, W), float32
        Accumulation: event counts (signed: positive minus negative).  Time surface: values in
        [0, 1] (signed: [-1, 1]).
    t_start_ns, t_end_ns : ndarray, shape (F,), int64
        Window of every frame; a time surface is evaluated at ``t_end_ns``.
    kind : str
        ``"accumulate"`` or ``"time-surface"``.
    signed : bool
        Whether polarity signs the values.
    """

    frames: npt.NDArray[np.float32]
    t_start_ns: npt.NDArray[np.int64]
    t_end_ns: npt.NDArray[np.int64]
    kind: str
    signed: bool

    def __repr__(self) -> str:
        f, h, w = self.frames.shape if self.frames.ndim == 3 else (0, 0, 0)
        span = (f", {(int(self.t_end_ns[-1]) - int(self.t_start_ns[0])) / 1e9:.6g} s"
                if len(self.t_end_ns) else "")
        return (f"EventFrames({f} {'signed' if self.signed else 'unsigned'} {self.kind} frames "
                f"of {w}x{h}{span})")

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON summary (the frames themselves stay arrays): kind, signed, shape, and
        the windows' stamps."""
        return {"kind": self.kind, "signed": bool(self.signed),
                "shape": [int(v) for v in self.frames.shape],
                "t_start_ns": [int(v) for v in self.t_start_ns],
                "t_end_ns": [int(v) for v in self.t_end_ns]}

    def to_uint8(self) -> npt.NDArray[np.uint8]:
        """8-bit images for viewing: signed frames map 0 to grey 128, unsigned 0 to black.
        Accumulation frames are scaled per frame by their 99th percentile of |value|."""
        return np.stack([frame_to_uint8(f, kind=self.kind, signed=self.signed) for f in self.frames]) \
            if len(self.frames) else np.zeros((0, *self.frames.shape[1:]), np.uint8)


def frame_to_uint8(frame: np.ndarray, *, kind: str, signed: bool) -> npt.NDArray[np.uint8]:
    """One frame as an 8-bit image (see :meth:`EventFrames.to_uint8`)."""
    f = np.asarray(frame, dtype=np.float32)
    if kind == "accumulate":
        nz = np.abs(f[f != 0])
        scale = float(np.percentile(nz, 99)) if nz.size else 1.0
        f = f / max(scale, 1e-9)
    v = np.clip(f, -1.0, 1.0)
    img = 127.5 + 127.5 * v if signed else 255.0 * np.clip(v, 0.0, 1.0)
    return np.rint(img).astype(np.uint8)


def frame_windows(
    t_first_ns: int,
    t_last_ns: int,
    *,
    rate_hz: float | None = None,
    window_ns: int | None = None,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Frame windows covering ``[t_first, t_last]``.

    Frames end every ``1 / rate_hz`` s (or every ``window_ns`` when no rate is given) starting one
    period after the first event; each integrates ``window_ns`` (default one period) before its end.

    Returns
    -------
    t_start_ns, t_end_ns : ndarray, shape (F,), int64
    """
    if rate_hz is None and window_ns is None:
        raise IbiscapeError("give a frame rate (rate_hz) or a window length (window_ns)")
    if rate_hz is not None and not (np.isfinite(rate_hz) and rate_hz > 0):
        raise IbiscapeError(f"rate_hz must be > 0, got {rate_hz}")
    if window_ns is not None and int(window_ns) <= 0:
        raise IbiscapeError(f"window must be > 0 ns, got {window_ns}")
    period = round(1e9 / rate_hz) if rate_hz is not None else int(window_ns or 0)
    period = max(period, 1)
    win = int(window_ns) if window_ns is not None else period
    n = max(1, -(-(int(t_last_ns) - int(t_first_ns) + 1) // period))
    ends = int(t_first_ns) + period * np.arange(1, n + 1, dtype=np.int64)
    return ends - win, ends


def _check(events: Events, sensor_size: tuple[int, int]) -> tuple[int, int]:
    w, h = (int(v) for v in sensor_size)
    if len(events) == 0:
        raise DegenerateInputError("no events: nothing to make frames from")
    if int(events.x.max()) >= w or int(events.y.max()) >= h:
        raise IbiscapeError(
            f"events reach pixel ({int(events.x.max())}, {int(events.y.max())}), outside the "
            f"{w}x{h} sensor; pass the right sensor size"
        )
    return w, h


def iter_frames(
    events: Events,
    *,
    sensor_size: tuple[int, int],
    kind: str = "accumulate",
    rate_hz: float | None = None,
    window_ns: int | None = None,
    windows: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    signed: bool = True,
    tau_ns: int = 30_000_000,
) -> Iterator[tuple[int, int, npt.NDArray[np.float32]]]:
    """Yield ``(t_start_ns, t_end_ns, frame (H, W) float32)`` one frame at a time (bounded memory).

    Parameters
    ----------
    events
        The stream, sorted by time.
    sensor_size : (int, int)
        Width, height in pixels.
    kind : {"accumulate", "time-surface"}
    rate_hz, window_ns
        Fixed-rate frames (see :func:`frame_windows`).
    windows : (starts, ends), optional
        Explicit frame windows in ns instead of a rate (ends increasing).
    signed : bool
        Accumulation: positive minus negative events (else all events).  Time surface: value
        signed by the polarity of the latest event.
    tau_ns : int
        Time-surface decay constant, ns.
    """
    from . import _kernels

    if kind not in KINDS:
        raise IbiscapeError(f"unknown frame kind {kind!r}; choose one of {', '.join(KINDS)}")
    if int(tau_ns) <= 0:
        raise IbiscapeError(f"tau must be > 0 ns, got {tau_ns}")
    w, h = _check(events, sensor_size)
    t = events.t_ns
    if windows is not None:
        starts = np.asarray(windows[0], dtype=np.int64)
        ends = np.asarray(windows[1], dtype=np.int64)
    else:
        starts, ends = frame_windows(int(t[0]), int(t[-1]), rate_hz=rate_hz, window_ns=window_ns)
    lo = np.searchsorted(t, starts, side="left")
    hi = np.searchsorted(t, ends, side="left")
    pix = None
    if kind == "accumulate":
        pix = events.y.astype(np.int64) * w + events.x
        weight = np.where(events.p, 1.0, -1.0) if signed else None
        for a, b, i0, i1 in zip(starts, ends, lo, hi, strict=True):
            wts = None if weight is None else weight[i0:i1]
            frame = np.bincount(pix[i0:i1], weights=wts, minlength=w * h).astype(np.float32)
            yield int(a), int(b), frame.reshape(h, w)
        return
    last_t = np.full(w * h, np.iinfo(np.int64).min, np.int64)
    last_p = np.zeros(w * h, np.bool_)
    done = 0
    for a, b, i1 in zip(starts, ends, hi, strict=True):
        if i1 > done:
            _kernels.last_time(t[done:i1], events.x[done:i1], events.y[done:i1],
                               events.p[done:i1], w, last_t, last_p)
            done = int(i1)
        fired = last_t > np.iinfo(np.int64).min
        val = np.zeros(w * h, np.float32)
        val[fired] = np.exp(-(int(b) - last_t[fired]) / float(tau_ns))
        if signed:
            val[fired & ~last_p] *= -1.0
        yield int(a), int(b), val.reshape(h, w)


def _stack(kind: str, signed: bool, it: Iterator[tuple[int, int, np.ndarray]], shape: tuple[int, int]) -> EventFrames:
    rows = list(it)
    frames = np.stack([f for _, _, f in rows]) if rows else np.zeros((0, *shape), np.float32)
    return EventFrames(
        frames=frames.astype(np.float32, copy=False),
        t_start_ns=np.array([a for a, _, _ in rows], np.int64),
        t_end_ns=np.array([b for _, b, _ in rows], np.int64),
        kind=kind,
        signed=signed,
    )


def accumulate_frames(
    events: Events,
    *,
    sensor_size: tuple[int, int],
    rate_hz: float | None = None,
    window_ns: int | None = None,
    windows: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    signed: bool = True,
) -> EventFrames:
    """Accumulation frames (event counts per pixel per window), all in memory.

    See :func:`iter_frames` for the parameters; returns frames of shape (F, H, W).
    """
    it = iter_frames(events, sensor_size=sensor_size, kind="accumulate", rate_hz=rate_hz,
                     window_ns=window_ns, windows=windows, signed=signed)
    return _stack("accumulate", signed, it, (int(sensor_size[1]), int(sensor_size[0])))


def time_surfaces(
    events: Events,
    *,
    sensor_size: tuple[int, int],
    rate_hz: float | None = None,
    window_ns: int | None = None,
    windows: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    tau_ns: int = 30_000_000,
    signed: bool = False,
) -> EventFrames:
    """Exponential-decay time surfaces evaluated at the end of every window, all in memory.

    See :func:`iter_frames` for the parameters; returns frames of shape (F, H, W) in [0, 1]
    (signed: [-1, 1]).
    """
    it = iter_frames(events, sensor_size=sensor_size, kind="time-surface", rate_hz=rate_hz,
                     window_ns=window_ns, windows=windows, signed=signed, tau_ns=tau_ns)
    return _stack("time-surface", signed, it, (int(sensor_size[1]), int(sensor_size[0])))
