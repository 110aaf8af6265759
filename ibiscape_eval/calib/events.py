"""Frames for calibrating event cameras, reconstructed from the events of the recording's windows.

In the spirit of E2CALIB (Muglikar et al., CVPRW 2021: reconstruct images from events, then
calibrate them like frames) but without a learned reconstruction:

- ``log-intensity``: the high-pass (leaky) integration of the event polarities, weighted by the
  contrast thresholds (Scheerlinck et al., ACCV 2018; :mod:`ibiscape_eval.events.intensity`),
  carried across windows with a time constant ``tau_s`` (3 s).  On a moving camera it gives the
  scene's log image (board squares filled) minus a faded, motion-smeared past; the memory of the
  first instants is forgotten after a few ``tau_s``.  By default (``bidirectional``) it is averaged
  with the same filter run backwards in time from the later events, so that the subtracted smear
  is centred on the current image instead of lagging behind it (offline calibration can look
  ahead).  Measured on the rendered ESVI calibration drive (346x260, checkerboard, corners
  against the truth): RMS 0.57 px forward with 1 s, 0.49 px bidirectional with 3 s, and the
  board found in 25 % more frames.  A frame needs the events of the ``memory_tau * tau_s``
  seconds before it: frames are computed in time order from a cached state (restarted from zero
  that long before when asked for an earlier frame).
- ``accumulate-signed``: positive minus negative events per pixel over the window alone.  A
  blinking or fading-in target (the usual way to calibrate a DVS on a bench) reappears as the
  pattern itself; a moving target gives only its edges.
- ``accumulate``: all events per pixel (edge maps).
- ``time-surface``: exponential decay of the latest event per pixel (Lagorce et al. 2017).

``auto`` tries each on a few windows and keeps the one on which the target detector finds the
most corners (ties: the order above); the method used is reported.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

from .targets import CalibrationTarget

__all__ = [
    "DEFAULT_TAU_S",
    "RECONSTRUCTIONS",
    "TIME_SURFACE_TAU_NS",
    "EventFrameSource",
    "board_noise_px",
    "choose_reconstruction",
    "contrast_from_sequence",
    "estimate_contrast",
    "event_frame",
    "event_frame_loader",
    "event_set_frames",
    "read_event_window",
]

RECONSTRUCTIONS = ("log-intensity", "accumulate-signed", "accumulate", "time-surface")
#: high-pass time constant of the log-intensity reconstruction [s]
DEFAULT_TAU_S = 3.0
#: the state is rebuilt from this many time constants before a frame (exp(-5) = 0.7 % left)
MEMORY_TAU = 5.0
#: memory for the backward (future) states one sweep of the bidirectional reconstruction keeps
#: (float32 images; 8..128 windows per sweep)
BACKWARD_BLOCK_BYTES = 64 << 20
#: decay of the time-surface reconstruction [ns]
TIME_SURFACE_TAU_NS = 10_000_000
#: nominal contrast threshold (CARLA's and the paper's 0.3) when only the ratio is known
NOMINAL_CONTRAST = 0.3

ReadWindow = Callable[[int], Events | None]


def read_event_window(path: str | Path) -> Events:
    """One IBISCape event window (``events/<ns>.npz``); an empty window is an empty stream.

    Raises :class:`~ibiscape_eval.core.errors.FormatError` naming the file when it cannot be read.
    """
    from ibiscape_eval.io.events import read_events

    return read_events(path, fmt="npz", allow_empty=True)


def _log_to_uint8(values: npt.NDArray[np.float64], shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """A log-intensity estimate as an 8-bit image for corner detection: ``exp(0.5 L_hat)`` (the
    square root of the high-passed linear intensity), 2nd..98th percentile to 0..255, no blur.

    Corners refined in the log domain itself are biased (the log stretches the dark squares' side of
    every blurred edge): on the simulator's hand-held DVS (192 px, tests/calib/_dvs_handheld.py) the
    corner RMS against the truth is 1.25 px from the log image, 0.80 px from this one."""
    v = np.exp(0.5 * np.clip(values - np.median(values), -20.0, 20.0))
    lo, hi = np.percentile(v, [2.0, 98.0]) if v.size else (0.0, 1.0)
    if hi - lo <= 1e-12:
        return np.full(shape, 128, np.uint8)
    return np.clip((v.reshape(shape) - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)


def event_frame(events: Events, sensor_size: tuple[int, int], window_ns: tuple[int, int], *,
                method: str = "accumulate-signed", tau_ns: int = TIME_SURFACE_TAU_NS,
                contrast: tuple[float, float] = (NOMINAL_CONTRAST, NOMINAL_CONTRAST)) -> npt.NDArray[np.uint8]:
    """One 8-bit frame (H, W) from the events of ``[start, end)`` alone (``log-intensity``: the
    integration starts from zero at ``start``)."""
    import cv2

    from ibiscape_eval.events.frames import frame_to_uint8, iter_frames
    from ibiscape_eval.events.intensity import leaky_integrate

    if method not in RECONSTRUCTIONS:
        raise IbiscapeError(f"reconstruction {method!r}: use one of {', '.join(RECONSTRUCTIONS)}")
    w, h = sensor_size
    if method == "log-intensity":
        state = leaky_integrate(np.zeros(w * h), int(window_ns[0]), events, int(window_ns[1]), width_px=w,
                                tau_s=DEFAULT_TAU_S, contrast=contrast)
        return _log_to_uint8(state, (h, w))
    if len(events) == 0:
        return np.full((h, w), 128 if method == "accumulate-signed" else 0, np.uint8)
    kind = "time-surface" if method == "time-surface" else "accumulate"
    signed = method == "accumulate-signed"
    windows = (np.array([window_ns[0]], np.int64), np.array([window_ns[1]], np.int64))
    [(_, _, frame)] = list(iter_frames(events, sensor_size=(w, h), kind=kind, windows=windows,
                                       signed=signed, tau_ns=tau_ns))
    img = frame_to_uint8(frame, kind=kind, signed=signed)
    return np.asarray(cv2.GaussianBlur(img, (3, 3), 0.8), np.uint8)


class EventFrameSource:
    """``source(i)`` -> the 8-bit frame reconstructed at the end of window ``i`` (None when window
    ``i`` cannot be read).  Thread-safe; suited to
    :class:`~ibiscape_eval.calib.pipeline.CameraFrames` ``load``.

    Parameters
    ----------
    read_window
        ``read_window(i)`` -> the events of window ``i`` (None when unreadable: for ``log-intensity``
        an unreadable window before the frame counts as one without events).
    windows_ns : array (N, 2) int64
        ``[start, end)`` of every window, increasing.
    sensor_size : (int, int)
        Width, height.
    method
        One of :data:`RECONSTRUCTIONS`.
    tau_s
        ``log-intensity`` time constant [s].
    contrast : (C_pos, C_neg)
        ``log-intensity`` contrast thresholds (only their ratio changes the frame).
    bidirectional
        ``log-intensity``: average the forward estimate (the log image minus its exponentially
        weighted past) with the backward one (minus its future, from the later events).  The
        subtracted smear is then centred on the current image: on a camera moving smoothly it is
        locally flat at the corners instead of a displaced copy of the board that pulls them
        backwards along the motion, and the unknown first image of the recording is halved.
    target, max_board_noise_px
        With both: a frame whose detected corners stray from their neighbours' homography by more
        than ``max_board_noise_px`` RMS (:func:`board_noise_px`) is returned blank (uniform grey)
        and counted in ``frames_rejected``: a reconstruction smeared by the past and future of a
        slowly moving board would bring its corner noise into the calibration.
    """

    def __init__(self, read_window: ReadWindow, windows_ns: npt.ArrayLike, sensor_size: tuple[int, int],
                 method: str, *, tau_s: float = DEFAULT_TAU_S,
                 contrast: tuple[float, float] = (NOMINAL_CONTRAST, NOMINAL_CONTRAST),
                 bidirectional: bool = True, target: CalibrationTarget | None = None,
                 max_board_noise_px: float | None = None, cache_frames: int = 8) -> None:
        if method not in RECONSTRUCTIONS:
            raise IbiscapeError(f"reconstruction {method!r}: use one of {', '.join(RECONSTRUCTIONS)}")
        if not (np.isfinite(tau_s) and tau_s > 0):
            raise IbiscapeError(f"tau_s must be > 0, got {tau_s}")
        if not all(np.isfinite(c) and c > 0 for c in contrast):
            raise IbiscapeError(f"contrast thresholds must be > 0, got {contrast}")
        self.read_window = read_window
        self.windows_ns = np.asarray(windows_ns, np.int64).reshape(-1, 2)
        self.sensor_size = (int(sensor_size[0]), int(sensor_size[1]))
        self.method = method
        self.tau_s = float(tau_s)
        self.contrast = (float(contrast[0]), float(contrast[1]))
        self.bidirectional = bool(bidirectional)
        if max_board_noise_px is not None and not (np.isfinite(max_board_noise_px) and max_board_noise_px > 0):
            raise IbiscapeError(f"max_board_noise_px must be > 0, got {max_board_noise_px}")
        self.target = target
        self.max_board_noise_px = None if max_board_noise_px is None else float(max_board_noise_px)
        self.frames_rejected = 0
        self.n_events_read = 0
        self.windows_read = 0
        self._lock = threading.Lock()
        self._state: tuple[int, npt.NDArray[np.float64]] | None = None  # (window index, L_hat at its end)
        self._cache: OrderedDict[int, npt.NDArray[np.uint8] | None] = OrderedDict()
        self._cache_frames = int(cache_frames)
        self._back: dict[int, npt.NDArray[np.float32]] = {}  # window -> backward L_hat (one block)

    def __len__(self) -> int:
        return len(self.windows_ns)

    def __repr__(self) -> str:
        return f"EventFrameSource({len(self)} windows, {self.method})"

    def describe(self) -> dict[str, Any]:
        """What the reconstruction used (for the report)."""
        d: dict[str, Any] = {"method": self.method}
        if self.method == "log-intensity":
            d.update(tau_s=self.tau_s, contrast_pos=self.contrast[0], contrast_neg=self.contrast[1],
                     bidirectional=self.bidirectional)
        if self.target is not None and self.max_board_noise_px is not None:
            d["max_board_noise_px"] = self.max_board_noise_px
        return d

    def _read(self, i: int) -> Events | None:
        ev = self.read_window(i)
        self.windows_read += 1
        if ev is not None:
            self.n_events_read += len(ev)
        return ev

    def __call__(self, i: int) -> npt.NDArray[np.uint8] | None:
        i = int(i)
        if not 0 <= i < len(self.windows_ns):
            raise IbiscapeError(f"window {i}: the recording has {len(self.windows_ns)} windows")
        with self._lock:
            if i in self._cache:
                self._cache.move_to_end(i)
                return self._cache[i]
            frame = self._log_frame(i) if self.method == "log-intensity" else self._window_frame(i)
            if frame is not None and self.target is not None and self.max_board_noise_px is not None:
                frame = self._screen(frame)
            self._cache[i] = frame
            while len(self._cache) > self._cache_frames:
                self._cache.popitem(last=False)
            return frame

    def _screen(self, frame: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
        from .detect import detect_corners

        assert self.target is not None and self.max_board_noise_px is not None
        det = detect_corners(frame, self.target)
        if det is None:
            return frame
        noise = board_noise_px(det.corners_px, self.target.object_points()[det.ids, :2])
        if noise <= self.max_board_noise_px:
            return frame
        self.frames_rejected += 1
        return np.full_like(frame, 128)

    def _window_frame(self, i: int) -> npt.NDArray[np.uint8] | None:
        ev = self._read(i)
        if ev is None:
            return None
        a, b = self.windows_ns[i]
        return event_frame(ev, self.sensor_size, (int(a), int(b)), method=self.method)

    def _log_frame(self, i: int) -> npt.NDArray[np.uint8] | None:
        state = self._log_state(i)
        return None if state is None else _log_to_uint8(state, self.sensor_size[::-1])

    def log_estimate(self, i: int) -> npt.NDArray[np.float64] | None:
        """``log-intensity``: the estimate ``L_hat`` (H, W) at the end of window ``i`` before its
        8-bit mapping (None when window ``i`` cannot be read)."""
        if self.method != "log-intensity":
            raise IbiscapeError(f"log_estimate needs the log-intensity reconstruction, not {self.method}")
        i = int(i)
        if not 0 <= i < len(self.windows_ns):
            raise IbiscapeError(f"window {i}: the recording has {len(self.windows_ns)} windows")
        with self._lock:
            state = self._log_state(i)
        return None if state is None else state.reshape(self.sensor_size[1], self.sensor_size[0])

    def _log_state(self, i: int) -> npt.NDArray[np.float64] | None:
        from ibiscape_eval.events.intensity import leaky_integrate

        w, h = self.sensor_size
        win = self.windows_ns
        first = int(np.searchsorted(win[:, 0], int(win[i, 1]) - round(MEMORY_TAU * self.tau_s * 1e9)))
        first = min(first, i)
        if self._state is not None and first - 1 <= self._state[0] <= i:
            j, state = self._state
            t = int(win[j, 1])
        else:  # start from zero MEMORY_TAU time constants before the frame
            j, state, t = first - 1, np.zeros(w * h, np.float64), int(win[first, 0])
        ok = True
        for k in range(j + 1, i + 1):
            ev = self._read(k)
            if ev is None:
                ok = k != i
                ev = Events(np.zeros(0, np.int64), np.zeros(0, np.uint16), np.zeros(0, np.uint16),
                            np.zeros(0, bool))
            state = leaky_integrate(state, t, ev, int(win[k, 1]), width_px=w, tau_s=self.tau_s,
                                    contrast=self.contrast)
            t = int(win[k, 1])
        self._state = (i, state)
        if not ok:
            return None
        return 0.5 * (state + self._backward(i)) if self.bidirectional else state

    def _backward(self, i: int) -> npt.NDArray[np.float64]:
        """``B(t_i) = -sum_{t_i < t_e <= t_i + MEMORY_TAU tau} C_e exp(-(t_e - t_i) / tau)``: the
        log image at the end of window ``i`` minus its exponentially weighted future.  Computed by
        a backward sweep for a block of windows at once (float32 states, ``BACKWARD_BLOCK_BYTES``)."""
        if i not in self._back:
            w, h = self.sensor_size
            win = self.windows_ns
            block = int(np.clip(BACKWARD_BLOCK_BYTES // (4 * w * h), 8, 128))
            first = (i // block) * block
            last_in = min(first + block, len(win)) - 1
            horizon = int(win[last_in, 1]) + round(MEMORY_TAU * self.tau_s * 1e9)
            end = min(int(np.searchsorted(win[:, 0], horizon)), len(win)) - 1
            rate = 1e-9 / self.tau_s
            state = np.zeros(w * h, np.float64)
            self._back = {}
            for k in range(end, first - 1, -1):  # state = B(t_k), from the events after t_k
                if k <= last_in:
                    self._back[k] = state.astype(np.float32)
                if k == first:
                    break
                ev = self._read(k)
                t_prev = int(win[k - 1, 1])
                state *= np.exp(-rate * (int(win[k, 1]) - t_prev))
                if ev is not None and len(ev):
                    if int(ev.x.max()) >= w or int(ev.y.max()) >= h:
                        raise IbiscapeError(f"events reach pixel ({int(ev.x.max())}, {int(ev.y.max())}), "
                                            f"outside the {w}x{h} sensor; give the right sensor size")
                    c = np.where(ev.p, self.contrast[0], -self.contrast[1])
                    wts = c * np.exp(-rate * (ev.t_ns - t_prev).astype(np.float64))
                    state -= np.bincount(ev.y.astype(np.int64) * w + ev.x, weights=wts, minlength=w * h)
        return self._back[i].astype(np.float64)


def board_noise_px(corners_px: npt.ArrayLike, board_xy_m: npt.ArrayLike, *, k: int = 8) -> float:
    """RMS distance [px] of detected corners from where a homography of their ``k`` nearest
    neighbours on the board puts them: the corner noise of one view, without the camera model
    (a local homography absorbs the lens distortion).  On event frames it follows the error
    against the truth closely (the rendered ESVI drive, 346x260: correlation 0.95 with a global
    homography); ``inf`` with fewer than 6 corners."""
    from .detect import neighbour_residuals_px

    uv = np.asarray(corners_px, np.float64).reshape(-1, 2)
    if len(uv) < 6:
        return float("inf")
    res = neighbour_residuals_px(board_xy_m, uv, k=k)
    return float("inf") if np.isnan(res).any() else float(np.sqrt(np.mean(res**2)))


def event_frame_loader(read_window: ReadWindow, windows_ns: npt.ArrayLike, sensor_size: tuple[int, int],
                       method: str, **options: Any) -> EventFrameSource:
    """``load(i)`` for :func:`ibiscape_eval.calib.pipeline.calibrate_frames` (an
    :class:`EventFrameSource`)."""
    return EventFrameSource(read_window, windows_ns, sensor_size, method, **options)


def contrast_from_sequence(camera_doc: Mapping[str, Any] | None) -> tuple[float, float] | None:
    """The contrast thresholds ``(C_pos, C_neg)`` of a camera's ``sequence.yaml`` entry
    (``dvs: {positive_threshold, negative_threshold}``, CARLA's names), or None."""
    if not isinstance(camera_doc, Mapping):
        return None
    for doc in (camera_doc.get("dvs"), camera_doc.get("dvs_config"), camera_doc):
        if isinstance(doc, Mapping) and "positive_threshold" in doc and "negative_threshold" in doc:
            try:
                c = (float(doc["positive_threshold"]), float(doc["negative_threshold"]))
            except (TypeError, ValueError):
                return None
            return c if all(np.isfinite(v) and v > 0 for v in c) else None
    return None


def estimate_contrast(read_window: ReadWindow, n_windows: int, *, n_probe: int = 16) -> tuple[float, float]:
    """Contrast thresholds ``(NOMINAL_CONTRAST, NOMINAL_CONTRAST * r)`` with ``r = C_neg / C_pos``
    from the polarity balance of ``n_probe`` evenly spread windows
    (:func:`ibiscape_eval.events.intensity.estimate_contrast_ratio`)."""
    from ibiscape_eval.events.intensity import estimate_contrast_ratio

    n_pos = n_all = 0
    for i in np.unique(np.linspace(0, max(n_windows - 1, 0), min(n_probe, n_windows)).round().astype(int)):
        ev = read_window(int(i))
        if ev is not None:
            n_pos += int(np.count_nonzero(ev.p))
            n_all += len(ev)
    r = estimate_contrast_ratio(n_pos, n_all - n_pos)
    return NOMINAL_CONTRAST, NOMINAL_CONTRAST * float(np.clip(r, 0.5, 2.0))


def choose_reconstruction(read_window: ReadWindow, windows_ns: npt.ArrayLike, sensor_size: tuple[int, int],
                          target: CalibrationTarget, *, n_probe: int = 8,
                          candidates: Sequence[str] = RECONSTRUCTIONS, **options: Any
                          ) -> tuple[str, dict[str, Any]]:
    """Try every reconstruction on ``n_probe`` evenly spread windows; the one with the most detected
    corners wins (ties: the earlier in ``candidates``).  Returns the method and the corner counts.
    ``options`` go to :class:`EventFrameSource`."""
    from .detect import detect_corners

    win = np.asarray(windows_ns, np.int64).reshape(-1, 2)
    if len(win) == 0:
        raise IbiscapeError("no event windows to reconstruct frames from")
    probe = np.unique(np.linspace(0, len(win) - 1, min(n_probe, len(win))).round().astype(int))
    counts: dict[str, int] = {}
    for m in candidates:
        src = EventFrameSource(read_window, win, sensor_size, m, **options)
        n = 0
        for i in probe:
            img = src(int(i))
            det = None if img is None else detect_corners(img, target)
            n += 0 if det is None else len(det)
        counts[m] = n
    best = max(candidates, key=lambda m: (counts[m], -list(candidates).index(m)))
    return best, {"probed_windows": len(probe), "corners_found": counts}


def event_set_frames(paths: Sequence[str | Path], windows_ns: npt.ArrayLike,
                     sensor_size: tuple[int, int], target: CalibrationTarget, *,
                     reconstruction: str = "auto",
                     camera_doc: Mapping[str, Any] | None = None,
                     max_board_noise_px: float | None = None,
                     bidirectional: bool = True,
                     ) -> tuple[EventFrameSource, dict[str, Any]]:
    """Frames of one DVS folder (its ``.npz`` windows) for the calibration, and what was used.

    Corrupt windows are skipped with a warning (like corrupt images); the contrast thresholds come
    from the camera's ``sequence.yaml`` entry ``camera_doc`` or from the polarity balance;
    ``reconstruction="auto"`` picks the method that finds the target; ``max_board_noise_px``
    blanks frames whose corners are noisier than that (see :class:`EventFrameSource`);
    ``bidirectional=False`` keeps log-intensity frames causal (the camera-IMU calibration needs the
    instant a frame shows).  Returns the frame source and ``{method, options..., contrast_from}``
    for the report.
    """
    import warnings

    from ibiscape_eval.core.errors import IbiscapeWarning

    files = tuple(Path(p) for p in paths)

    def read_window(i: int) -> Events | None:
        try:
            return read_event_window(files[i])
        except IbiscapeError as e:  # a corrupt window is skipped like a corrupt image
            warnings.warn(f"{e}; skipped", IbiscapeWarning, stacklevel=2)
            return None

    contrast = contrast_from_sequence(camera_doc)
    given = contrast is not None
    if contrast is None:
        contrast = estimate_contrast(read_window, len(files))
    method, probe = reconstruction, dict[str, Any]()
    if method == "auto":
        method, probe = choose_reconstruction(read_window, windows_ns, sensor_size, target,
                                              contrast=contrast)
    source = event_frame_loader(read_window, windows_ns, sensor_size, method, contrast=contrast,
                                target=target, max_board_noise_px=max_board_noise_px,
                                bidirectional=bidirectional)
    return source, {**source.describe(), **probe,
                    "contrast_from": "sequence.yaml" if given else "polarity balance"}
