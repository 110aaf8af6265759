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

Checkerboard corners found in a reconstructed frame are then refined from the events themselves
(:func:`refine_xcorners`, on by default): a frame carries the reconstruction's errors (the
contrast-threshold quantisation and the faded past), the events' timestamps do not.  The events
near a corner, within a few milliseconds of the frame's instant, are moved back along the corner's
image velocity to that instant; they then lie along the two board edges through the corner, and
the corner is the intersection of the two lines fitted to them.  Each edge line runs through both
sides of the X-junction, whose dark and bright sides swap at the corner: the events' offset
towards the dark side of an edge (a DVS fires more often where the log intensity is steep)
cancels between the two halves.  The pixels' hysteresis would still leave the lines behind the
motion (about 0.2 px with the simulator's 0.7 px blur): a pixel fires its first event of a
transition one full contrast step after the level it stopped at, so every run of same-polarity
events lacks its starting level.  Dropping the last event of every run makes the levels of rising
and falling runs alike, and the lag goes (0.19 -> 0.002 px on an analytic moving checkerboard
through the simulator's pixel model, ``tests/calib/test_calib_events_refine.py``).  The events
of a board that blinks instead of moving are not those of moving edges: a view whose corners lie
off the line through their positions in the two nearest views (:data:`REFINE_MAX_JUMP_PX`)
keeps its frame's corners.
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
from ibiscape_eval.core.kalibr import CalibrationTarget

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
    "refine_xcorners",
]

RECONSTRUCTIONS = ("log-intensity", "accumulate-signed", "accumulate", "time-surface")
#: high-pass time constant of the log-intensity reconstruction [s]
DEFAULT_TAU_S = 3.0
#: the state is rebuilt from this many time constants before a frame (exp(-5) = 0.7 % left)
MEMORY_TAU = 5.0
#: memory for the backward (future) states one sweep of the bidirectional reconstruction keeps
#: (float32 images; 8..128 windows per sweep)
BACKWARD_BLOCK_BYTES = 64 << 20
#: decoded event windows kept per event camera by :func:`event_set_frames` (read again otherwise)
WINDOW_CACHE_BYTES = 64 << 20
#: decay of the time-surface reconstruction [ns]
TIME_SURFACE_TAU_NS = 10_000_000
#: nominal contrast threshold (CARLA's and the paper's 0.3) when only the ratio is known
NOMINAL_CONTRAST = 0.3
#: corner refinement from events: the events used span the time the corner takes to move this far
REFINE_MOVE_PX = 3.0
#: ... within these bounds around the frame's instant [ns]
REFINE_HALF_WINDOW_NS = (2_000_000, 50_000_000)
#: a refined corner whose edge lines' offsets are less certain than this [px] is dropped
REFINE_MAX_SIGMA_PX = 0.1
#: a refined view keeps only its refined corners; with fewer it is dropped
REFINE_MIN_CORNERS = 8
#: with fewer refined views a camera keeps its frames' corners
REFINE_MIN_VIEWS = 10
#: a view whose corners lie farther than this [px] from the straight line through their
#: positions in the two nearest views (a board that jumps: one blinking at a new pose each view)
#: is not refined: its events are not those of edges moving at the velocity the neighbours give;
#: it keeps its frame's corners
REFINE_MAX_JUMP_PX = 3.0
#: ... views within this time of it [ns] (twice the longest the refinement spans either side)
REFINE_JUMP_SPAN_NS = 2 * REFINE_HALF_WINDOW_NS[1]

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
    refine
        :meth:`refine_detections` refines checkerboard corners from the events (the
        calibration's detection calls it); False keeps the frames' corners.
    """

    def __init__(self, read_window: ReadWindow, windows_ns: npt.ArrayLike, sensor_size: tuple[int, int],
                 method: str, *, tau_s: float = DEFAULT_TAU_S,
                 contrast: tuple[float, float] = (NOMINAL_CONTRAST, NOMINAL_CONTRAST),
                 bidirectional: bool = True, target: CalibrationTarget | None = None,
                 max_board_noise_px: float | None = None, cache_frames: int = 8,
                 refine: bool = True) -> None:
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
        self.refine = bool(refine)
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
        self._around: dict[int, Events | None] = {}  # windows of the last events_around call

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
        d["refine_corners"] = "events" if self.refine else "none"
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

    def events_around(self, t_ns: int, half_ns: int) -> Events:
        """The events of every window overlapping ``t_ns +- half_ns`` (unreadable ones skipped)."""
        win = self.windows_ns
        a = int(np.searchsorted(win[:, 1], int(t_ns) - int(half_ns), side="right"))
        b = min(int(np.searchsorted(win[:, 0], int(t_ns) + int(half_ns), side="left")) + 1, len(win))
        # neighbouring frames ask for overlapping windows: keep the last ones read
        for i in [i for i in self._around if not a <= i < b]:
            del self._around[i]
        for i in range(a, b):
            if i not in self._around:
                self._around[i] = self.read_window(i)
        parts = [ev for i in range(a, b) if (ev := self._around[i]) is not None]
        return Events.concatenate(parts) if parts else Events.empty()

    def refine_detections(self, target: CalibrationTarget, frames: Sequence[int | None],
                          detections: Sequence[Any]) -> tuple[list[Any], dict[str, Any]]:
        """Checkerboard detections in this source's frames refined from the events
        (:func:`refine_xcorners`); other targets, and sources built with ``refine=False``, are
        returned unchanged.

        ``frames[j]`` is the window index of ``detections[j]`` (a
        :class:`~ibiscape_eval.calib.detect.Detection` or None), in increasing order.  A corner's
        velocity comes from its positions in the nearest detections before and after (within
        0.3 s).  A view keeps only its refined corners, and is dropped (None) with fewer than
        :data:`REFINE_MIN_CORNERS`.  With fewer than :data:`REFINE_MIN_VIEWS` refined views (a
        still or blinking board) the detections are returned unchanged, with a warning.  A view
        whose corners jump (:func:`_jumps`: a board blinking at one pose, then at the next) is not
        refined, nor its events read: it keeps the frame's corners and counts in
        ``views_not_moving``.  Returns the detections and ``{corners_detected, corners_refined,
        views_detected, views_not_moving, views_kept, method}`` (``method``: ``events``,
        ``frames`` after that fallback, or ``none``).
        """
        from .detect import Detection

        dets = list(detections)
        n_det = sum(len(d) for d in dets if d is not None)
        stats: dict[str, Any] = {"corners_detected": n_det, "corners_refined": n_det,
                                 "views_detected": sum(d is not None for d in dets)}
        if not self.refine or target.target_type != "checkerboard":
            stats["views_kept"] = stats["views_detected"]
            stats["method"] = "none"
            return dets, stats
        obj = target.object_points()[:, :2]
        step = np.array([target.spacing_x_m, target.spacing_y_m])
        t_of = [None if f is None else int(self.windows_ns[int(f), 1]) for f in frames]
        pos = np.full((len(dets), target.n_corners, 2), np.nan)  # view, corner id -> px (NaN: unseen)
        for j, d in enumerate(dets):
            if d is not None:
                pos[j, d.ids] = d.corners_px
        max_gap_ns = 300_000_000
        out: list[Any] = []
        n_ref = n_frames = 0
        seen = [j for j, d in enumerate(dets) if d is not None and t_of[j] is not None]
        rank = {j: k for k, j in enumerate(seen)}
        for j, det in enumerate(dets):
            t = t_of[j]
            if det is None or t is None or len(det) < 4:
                out.append(None if det is None or len(det) < 4 else det)
                continue
            k = rank[j]
            near = [(q, int(t_of[q])) for q in seen[max(k - 2, 0):k + 3]  # type: ignore[arg-type]
                    if q != j and abs(int(t_of[q]) - t) <= max_gap_ns]  # type: ignore[arg-type]
            vel = _corner_velocity(pos, det, t, [(q, tq) for q, tq in near if abs(q - j) == 1])
            ref = sorted((n for n in near if abs(n[1] - t) <= REFINE_JUMP_SPAN_NS), key=lambda n: abs(n[1] - t))
            if _jumps(pos, det, t, ref[:2]):
                out.append(det)  # blinking at new poses: keep the frame's corners
                n_frames += 1
                continue
            lines = _edge_lines(obj[det.ids], det.corners_px, step)
            if lines is None:
                out.append(None)
                continue
            dirs, square = lines
            # a margin beyond the events used, so that the last event of a run is known as such
            ev = self.events_around(t, REFINE_HALF_WINDOW_NS[1] + 20_000_000)
            refined = refine_xcorners(ev, t, det.corners_px, vel, dirs, square)
            ok = np.isfinite(refined[:, 0])
            n_ref += int(ok.sum())
            out.append(Detection(det.ids[ok], refined[ok], det.image_size)
                       if ok.sum() >= REFINE_MIN_CORNERS else None)
        kept = sum(d is not None for d in out) - n_frames
        stats["views_not_moving"] = n_frames
        if kept < REFINE_MIN_VIEWS:  # a still or blinking board: its frames are all there is
            import warnings

            from ibiscape_eval.core.errors import IbiscapeWarning

            warnings.warn(f"only {kept} views with {REFINE_MIN_CORNERS}+ corners could be refined from "
                          "the events (the board moves too little in the image); the frames' corners "
                          "are used", IbiscapeWarning, stacklevel=2)
            stats.update(views_kept=stats["views_detected"], views_refinable=kept, method="frames")
            return dets, stats
        stats.update(corners_refined=n_ref, views_kept=kept + n_frames, method="events")
        return out, stats

    def _screen(self, frame: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
        from .detect import detect_corners

        assert self.target is not None and self.max_board_noise_px is not None
        det = detect_corners(frame, self.target, event_frame=True, fast=False)
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
            det = None if img is None else detect_corners(img, target, event_frame=True, fast=False)
            n += 0 if det is None else len(det)
        counts[m] = n
    best = max(candidates, key=lambda m: (counts[m], -list(candidates).index(m)))
    return best, {"probed_windows": len(probe), "corners_found": counts}


class _WindowCache:
    """The event windows read last, up to ``max_bytes`` (least recently used dropped first).

    The reconstruction choice, the forward and backward log-intensity sweeps and the corner
    refinement read the same windows again (each window ~2x on the 160 px ESVI drive:
    ``tests/calib/test_imu_camera_dvs.py``); :class:`Events` are immutable, so a window read once
    is shared.  Unreadable windows are not kept (read again, and warned about, every time)."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = int(max_bytes)
        self.bytes = 0
        self._lock = threading.Lock()
        self._items: OrderedDict[int, tuple[Events, int]] = OrderedDict()

    def get(self, i: int) -> Events | None:
        with self._lock:
            got = self._items.get(i)
            if got is None:
                return None
            self._items.move_to_end(i)
            return got[0]

    def put(self, i: int, ev: Events) -> None:
        size = 13 * len(ev) + 64  # t int64, x and y uint16, p bool
        with self._lock:
            if size > self.max_bytes or i in self._items:
                return
            self._items[i] = (ev, size)
            self.bytes += size
            while self.bytes > self.max_bytes:
                self.bytes -= self._items.popitem(last=False)[1][1]


def event_set_frames(paths: Sequence[str | Path], windows_ns: npt.ArrayLike,
                     sensor_size: tuple[int, int], target: CalibrationTarget, *,
                     reconstruction: str = "auto",
                     camera_doc: Mapping[str, Any] | None = None,
                     max_board_noise_px: float | None = None,
                     bidirectional: bool = True,
                     refine: bool = True,
                     ) -> tuple[EventFrameSource, dict[str, Any]]:
    """Frames of one DVS folder (its ``.npz`` windows) for the calibration, and what was used.

    Corrupt windows are skipped with a warning (like corrupt images); the contrast thresholds come
    from the camera's ``sequence.yaml`` entry ``camera_doc`` or from the polarity balance;
    ``reconstruction="auto"`` picks the method that finds the target; ``max_board_noise_px``
    blanks frames whose corners are noisier than that (see :class:`EventFrameSource`);
    ``bidirectional=False`` keeps log-intensity frames causal (the camera-IMU calibration needs the
    instant a frame shows); ``refine=False`` keeps the frames' checkerboard corners instead of
    refining them from the events.  Returns the frame source and ``{method, options..., contrast_from}``
    for the report.
    """
    import warnings

    from ibiscape_eval.core.errors import IbiscapeWarning

    files = tuple(Path(p) for p in paths)
    cache = _WindowCache(WINDOW_CACHE_BYTES)

    def read_window(i: int) -> Events | None:
        ev = cache.get(i)
        if ev is not None:
            return ev
        try:
            ev = read_event_window(files[i])
        except IbiscapeError as e:  # a corrupt window is skipped like a corrupt image
            warnings.warn(f"{e}; skipped", IbiscapeWarning, stacklevel=2)
            return None
        cache.put(i, ev)
        return ev

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
                                bidirectional=bidirectional, refine=refine)
    return source, {**source.describe(), **probe,
                    "contrast_from": "sequence.yaml" if given else "polarity balance"}


def _fit_xcorner(xy: npt.NDArray[np.float64], dt: npt.NDArray[np.float64], c: npt.NDArray[np.float64],
                 d1: npt.NDArray[np.float64], d2: npt.NDArray[np.float64],
                 square_px: float) -> tuple[npt.NDArray[np.float64], float] | None:
    """The X-junction ``c`` at ``dt = 0`` of two edge lines (initial directions ``d1``, ``d2``)
    fitted to the motion-compensated event positions ``xy`` (N, 2) at times ``dt`` [s] from the
    frame; None when the events do not support it.

    Each line is a surface in space-time: its offset along its normal is ``b + s dt + q dt^2``,
    so that an error of the given velocity across the line (``s``) and the acceleration (``q``)
    are fitted, not smeared into the line.  Also returns the larger standard error [px] of the
    two lines' offsets ``b`` (from the fit's residuals)."""
    dirs = [d1, d2]
    motion = [np.zeros(3), np.zeros(3)]  # (b, s, q) of each line: only s, q are used to assign
    T = np.stack([np.ones_like(dt), dt, dt * dt], axis=1)
    sigma = np.inf
    for _ in range(4):
        r = xy - c
        dist = np.hypot(r[:, 0], r[:, 1])
        near = (dist > 1.0) & (dist < 0.7 * square_px)  # off the junction itself, before the next
        normals = [np.array([-d[1], d[0]]) for d in dirs]
        res = [np.abs(r @ n - T[:, 1:] @ m[1:]) for n, m in zip(normals, motion, strict=True)]
        normals_new, offsets, sig = [], [], []
        for j in (0, 1):
            sel = near & (res[j] < res[1 - j]) & (res[j] < 2.0)
            ahead = r[sel] @ dirs[j] > 0
            n_a, n_b = int(ahead.sum()), int((~ahead).sum())
            if n_a < 6 or n_b < 6:
                return None
            # both halves of the edge weigh the same: their offsets towards the dark side cancel
            w = np.where(ahead, 1.0 / n_a, 1.0 / n_b)
            p = xy[sel] - np.outer(T[sel, 1:] @ motion[j][1:], normals[j])  # moved to dt = 0
            mu = w @ p / w.sum()
            q = p - mu
            nrm = np.linalg.eigh((q.T * w) @ q / w.sum())[1][:, 0]
            sw = np.sqrt(w)
            A_w = T[sel] * sw[:, None]
            coef = np.linalg.lstsq(A_w, (xy[sel] @ nrm) * sw, rcond=None)[0]
            motion[j] = coef
            # standard error of b: weights scaled to mean 1 (each event one observation)
            wn = w * (len(w) / w.sum())
            e = xy[sel] @ nrm - T[sel] @ coef
            dof = max(len(w) - 3, 1)
            try:
                cov = np.linalg.inv((T[sel].T * wn) @ T[sel]) * (wn @ (e * e) / dof)
            except np.linalg.LinAlgError:
                return None
            sig.append(float(np.sqrt(max(cov[0, 0], 0.0))))
            normals_new.append(nrm)
            offsets.append(float(coef[0]))
        A = np.array(normals_new)
        if abs(np.linalg.det(A)) < 0.2:  # lines closer than ~12 deg: no junction
            return None
        c_new = np.linalg.solve(A, np.array(offsets))
        if not np.all(np.isfinite(c_new)) or np.hypot(*(c_new - c)) > 3.0:
            return None
        dirs = [np.array([-n[1], n[0]]) for n in normals_new]
        c = c_new
        sigma = max(sig)
    return c, sigma


def _run_ends(x: npt.NDArray[Any], y: npt.NDArray[Any], t_ns: npt.NDArray[np.int64],
              p: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """The last event of every run of same-polarity events of a pixel (followed by an event of the
    other polarity, or by none in the events given)."""
    if len(x) == 0:
        return np.zeros(0, bool)
    pix = y.astype(np.int64) * (int(x.max()) + 1) + x
    order = np.lexsort((t_ns, pix))
    p_s, pol_s = pix[order], p[order]
    end_s = np.ones(len(order), bool)
    end_s[:-1] = (p_s[1:] != p_s[:-1]) | (pol_s[1:] != pol_s[:-1])
    out = np.empty(len(order), bool)
    out[order] = end_s
    return out


def refine_xcorners(events: Events, t_ns: int, corners_px: npt.ArrayLike, velocity_px_s: npt.ArrayLike,
                    directions: npt.ArrayLike, square_px: npt.ArrayLike, *,
                    move_px: float = REFINE_MOVE_PX,
                    half_window_ns: tuple[int, int] = REFINE_HALF_WINDOW_NS,
                    drop_run_ends: bool = True,
                    max_sigma_px: float = REFINE_MAX_SIGMA_PX) -> npt.NDArray[np.float64]:
    """Checkerboard corners at ``t_ns`` from the events around them (X-junction line fits).

    Parameters
    ----------
    events
        Events covering ``t_ns +- half_window_ns[1]`` (more are ignored).
    t_ns
        The instant the corners are wanted at.
    corners_px : (K, 2)
        First estimates (e.g. from a reconstructed frame), within ~1 px.
    velocity_px_s : (K, 2)
        Image velocity of each corner [px/s] (from the neighbouring frames).
    directions : (K, 2, 2)
        Image directions of the board's two edge lines through each corner (unit or not).
    square_px : (K,)
        Local square size [px]: events farther than 0.7 of it are not used.

    Returns
    -------
    ndarray (K, 2)
        The refined corners; NaN where the events do not support a fit (too few: the board moved
        less than ~1 px in ``half_window_ns[1]``, or an edge line parallel to the motion).

    Each corner uses the events of ``t_ns +- clip(move_px / |v|, *half_window_ns)``, moved back to
    ``t_ns`` along ``v`` (pixel centres at integer coordinates).  ``drop_run_ends`` leaves out the
    last event of every pixel's run of same-polarity events (see the module docstring): give
    ``events`` a little beyond the window, so that the runs' ends are known.
    """
    uv = np.asarray(corners_px, np.float64).reshape(-1, 2)
    vel = np.asarray(velocity_px_s, np.float64).reshape(-1, 2)
    dirs = np.asarray(directions, np.float64).reshape(-1, 2, 2)
    sq = np.asarray(square_px, np.float64).reshape(-1)
    out = np.full_like(uv, np.nan)
    if len(events) == 0 or len(uv) == 0:
        return out
    speed = np.hypot(vel[:, 0], vel[:, 1])
    half = np.clip(move_px / np.maximum(speed, 1e-9), half_window_ns[0] * 1e-9, half_window_ns[1] * 1e-9)
    # only the pixels within reach of a corner (whole pixels: their runs stay whole)
    valid = np.isfinite(uv).all(axis=1) & np.isfinite(vel).all(axis=1) & (sq > 4.0)
    if not valid.any():
        return out
    reach_all = (0.7 * sq + speed * half + 1.0)[:, None]
    lo, hi = (uv - reach_all)[valid].min(axis=0) - 1.0, (uv + reach_all)[valid].max(axis=0) + 1.0
    box = ((events.x >= lo[0]) & (events.x <= hi[0]) & (events.y >= lo[1]) & (events.y <= hi[1]))
    dt_all = (events.t_ns[box] - int(t_ns)).astype(np.float64) * 1e-9
    keep = np.abs(dt_all) <= half_window_ns[1] * 1e-9
    if drop_run_ends:
        keep &= ~_run_ends(events.x[box], events.y[box], events.t_ns[box], events.p[box])
    ex = events.x[box][keep].astype(np.float64)
    ey = events.y[box][keep].astype(np.float64)
    dt_all = dt_all[keep]
    for k in range(len(uv)):  # ~0.3 ms per corner; the events of one corner are few
        if not (np.all(np.isfinite(uv[k])) and np.all(np.isfinite(vel[k])) and sq[k] > 4.0):
            continue
        reach = 0.7 * sq[k] + speed[k] * half[k] + 1.0
        m = ((np.abs(dt_all) <= half[k]) & (np.abs(ex - uv[k, 0]) <= reach)
             & (np.abs(ey - uv[k, 1]) <= reach))
        if np.count_nonzero(m) < 24:
            continue
        dt = dt_all[m]
        xy = np.stack([ex[m] - vel[k, 0] * dt, ey[m] - vel[k, 1] * dt], axis=1)
        d1, d2 = (dirs[k, j] / max(np.hypot(*dirs[k, j]), 1e-12) for j in (0, 1))
        fit = _fit_xcorner(xy, dt, uv[k].copy(), d1, d2, float(sq[k]))
        if fit is not None and fit[1] <= max_sigma_px:
            out[k] = fit[0]
    return out


def _corner_velocity(pos: npt.NDArray[np.float64], det: Any, t_ns: int,
                     near: list[tuple[int, int]]) -> npt.NDArray[np.float64]:
    """Image velocity [px/s] of every corner of ``det`` (at ``t_ns``) from its positions
    ``pos[q, id]`` in the neighbouring views ``near`` (``(q, t_q_ns)``): the central difference
    over both neighbours, else one-sided with this view (NaN where no neighbour saw the corner)."""
    one = [(pos[q, det.ids] - det.corners_px) / ((tq - t_ns) * 1e-9) for q, tq in near]
    vel = np.full((len(det), 2), np.nan)
    for v in one:
        vel = np.where(np.isnan(vel), v, vel)
    if len(near) == 2:
        (q0, t0), (q1, t1) = near
        both = (pos[q1, det.ids] - pos[q0, det.ids]) / ((t1 - t0) * 1e-9)
        vel = np.where(np.isnan(both), vel, both)
    return vel


def _jumps(pos: npt.NDArray[np.float64], det: Any, t_ns: int, ref: list[tuple[int, int]]) -> bool:
    """Whether the corners of view ``det`` (at ``t_ns``) lie farther than
    :data:`REFINE_MAX_JUMP_PX` (median) from the straight line through their positions
    ``pos[q, id]`` in the two views ``ref`` (``(q, t_q_ns)``, within
    :data:`REFINE_JUMP_SPAN_NS`), interpolated or extrapolated to ``t_ns``: a board blinking at
    one pose, then at the next, sits at one end of that line, not on it (10-106 px off in
    ``tests/calib/test_calib_dvs_cli.py``); one moving smoothly sits on it (ESVI's moving DVS,
    160 px, 16 s: 0.92 px at most, measured)."""
    if len(ref) < 2:
        return False
    (q0, t0), (q1, t1) = ref
    a = (t_ns - t0) / (t1 - t0)
    jump = np.hypot(*(det.corners_px - pos[q0, det.ids] * (1.0 - a) - pos[q1, det.ids] * a).T)
    return bool(np.isfinite(jump).any() and float(np.nanmedian(jump)) > REFINE_MAX_JUMP_PX)


def _edge_lines(P: npt.NDArray[np.float64], uv: npt.NDArray[np.float64], step: npt.NDArray[np.float64]
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None:
    """Through every corner (board points ``P``, image ``uv``), the image directions of the two
    edge lines spanning two squares (N, 2, 2) and half the shorter one [px] (N,), by the board's
    homography; None when it cannot be estimated."""
    import cv2

    H, _ = cv2.findHomography(P, uv, 0)
    if H is None:
        return None
    ex, ey = np.array([step[0], 0.0]), np.array([0.0, step[1]])
    ends = np.concatenate([P + ex, P - ex, P + ey, P - ey])
    q = cv2.perspectiveTransform(ends[None], H)[0].reshape(4, len(P), 2)
    dirs = np.stack([q[0] - q[1], q[2] - q[3]], axis=1)  # two squares along each line
    return dirs, 0.5 * np.minimum(np.hypot(*dirs[:, 0].T), np.hypot(*dirs[:, 1].T))
