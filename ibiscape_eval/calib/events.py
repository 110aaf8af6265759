"""Frames for calibrating event cameras, reconstructed from the events of short windows.

In the spirit of E2CALIB (Muglikar et al., CVPRW 2021: reconstruct images from events, then
calibrate them like frames) but without a learned reconstruction:

- ``accumulate-signed``: positive minus negative events per pixel over the window, i.e. the
  integrated log-intensity change (``C * sum p``).  A blinking or fading-in target (the usual way
  to calibrate a DVS) reappears as the pattern itself; a target that moves by a fraction of a
  square gives its edges with signs.
- ``accumulate``: all events per pixel (edge maps).
- ``time-surface``: exponential decay of the latest event per pixel (Lagorce et al. 2017).

``auto`` tries each on a few windows and keeps the one on which the target detector finds the
most corners; the method used is reported.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

from .targets import CalibrationTarget

__all__ = ["RECONSTRUCTIONS", "choose_reconstruction", "event_frame", "event_frame_loader"]

RECONSTRUCTIONS = ("accumulate-signed", "accumulate", "time-surface")


def event_frame(events: Events, sensor_size: tuple[int, int], window_ns: tuple[int, int], *,
                method: str = "accumulate-signed", tau_ns: int = 10_000_000) -> npt.NDArray[np.uint8]:
    """One 8-bit frame (H, W) from the events of ``[start, end)``."""
    import cv2

    from ibiscape_eval.events.frames import frame_to_uint8, iter_frames

    if method not in RECONSTRUCTIONS:
        raise IbiscapeError(f"reconstruction {method!r}: use one of {', '.join(RECONSTRUCTIONS)}")
    w, h = sensor_size
    if len(events) == 0:
        return np.full((h, w), 128 if method == "accumulate-signed" else 0, np.uint8)
    kind = "time-surface" if method == "time-surface" else "accumulate"
    signed = method == "accumulate-signed"
    windows = (np.array([window_ns[0]], np.int64), np.array([window_ns[1]], np.int64))
    [(_, _, frame)] = list(iter_frames(events, sensor_size=(w, h), kind=kind, windows=windows,
                                       signed=signed, tau_ns=tau_ns))
    img = frame_to_uint8(frame, kind=kind, signed=signed)
    # events are quantised: a light blur gives the corner refinement smooth gradients
    return np.asarray(cv2.GaussianBlur(img, (3, 3), 0.8), np.uint8)


def event_frame_loader(read_window: Callable[[int], Events | None], windows_ns: npt.ArrayLike,
                       sensor_size: tuple[int, int], method: str
                       ) -> Callable[[int], npt.NDArray[np.uint8] | None]:
    """``load(i)`` for :func:`ibiscape_eval.calib.pipeline.calibrate_frames`: reads window ``i``'s
    events with ``read_window`` and reconstructs its frame."""
    win = np.asarray(windows_ns, np.int64).reshape(-1, 2)

    def load(i: int) -> npt.NDArray[np.uint8] | None:
        ev = read_window(i)
        if ev is None:
            return None
        return event_frame(ev, sensor_size, (int(win[i, 0]), int(win[i, 1])), method=method)

    return load


def choose_reconstruction(read_window: Callable[[int], Events | None], windows_ns: npt.ArrayLike,
                          sensor_size: tuple[int, int], target: CalibrationTarget, *,
                          n_probe: int = 8, candidates: Sequence[str] = RECONSTRUCTIONS) -> tuple[str, dict[str, Any]]:
    """Try every reconstruction on ``n_probe`` evenly spread windows; the one with the most detected
    corners wins (ties: the earlier in ``candidates``).  Returns the method and the corner counts."""
    from .detect import detect_corners

    win = np.asarray(windows_ns, np.int64).reshape(-1, 2)
    if len(win) == 0:
        raise IbiscapeError("no event windows to reconstruct frames from")
    probe = np.unique(np.linspace(0, len(win) - 1, min(n_probe, len(win))).round().astype(int))
    events = {int(i): read_window(int(i)) for i in probe}
    counts: dict[str, int] = {}
    for m in candidates:
        n = 0
        for i, ev in events.items():
            if ev is None:
                continue
            det = detect_corners(event_frame(ev, sensor_size, (int(win[i, 0]), int(win[i, 1])), method=m),
                                 target)
            n += 0 if det is None else len(det)
        counts[m] = n
    best = max(candidates, key=lambda m: (counts[m], -list(candidates).index(m)))
    return best, {"probed_windows": len(probe), "corners_found": counts}
