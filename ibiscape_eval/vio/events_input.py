"""ESVI inputs: stereo frames reconstructed, causally, from the events of two DVS cameras.

The VIO's front end tracks corners in grey images, so each DVS camera's events become one frame
per event window (the recording's ``timestamps.csv`` windows, 20 Hz in IBISCape) with the camera
calibration's reconstruction (:class:`ibiscape_eval.calib.events.EventFrameSource`), run forward
only (``bidirectional=False``): a frame at the end of window ``i`` uses only the events before it,
as an online estimator must.

Reconstructions (:data:`ESVI_RECONSTRUCTIONS`; measured with ``benchmarks/bench_vio_setups.py``
on rendered 15 s ESVI drives at 346x260, 107 m, ATE in % of the path, clear / moderate / dynamic):

- ``accumulate-signed`` (default): positive minus negative events of the window alone (50 ms):
  0.09 / 0.35 / 0.96 %, usable frames 279 / 274 / 254 of 300, no lost span in dynamic weather.
  It forgets everything after one window, so the weather's noise events and the edges of the
  past do not build up into texture that moves with nothing.  On the 60 s drives (441 m): 0.21 / 0.57 % and 0.57 % of the 328 m estimated in dynamic weather,
  974/1200 usable frames: standing in the rain from 33.8 s the DVS sees only noise (the IMU's
  zero-velocity hold takes over), and from 47.5 s the corners of its frames seldom live two frames
  (19 % reach the next one), too short for the stereo odometry that re-initialises: 12.5 s lost;
- ``log-intensity``: the leaky integration of the event polarities weighted by the contrast
  thresholds (Scheerlinck et al., ACCV 2018) with a memory ``tau_s``: 0.08 / 0.69 / 5.4 % with
  30 ms (4.9 s lost in dynamic weather).  Its memory drags every edge behind the motion: on a 5 s
  clear drive 0.21 % with 30 ms, 1.1 % with 0.1 s, 2.6 % with 0.3 s;
- ``time-surface``: exponential decay of the latest event per pixel (0.25 % on the 5 s drive,
  with twice the back end's time: more short tracks).

An event window that cannot be read (missing or corrupt ``events/<ns>.npz``) is refused naming the
file; a window that holds no events (a still camera) gives a uniform frame, on which the front end
finds nothing and the estimator continues on the IMU (reported as a failure span).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import CalibrationError, FormatError, IbiscapeError, Remedy
from ibiscape_eval.core.sequence import CameraStream, Sequence

__all__ = ["ESVI_RECONSTRUCTIONS", "EsviOptions", "event_pair_names", "event_stereo_frames"]

ESVI_RECONSTRUCTIONS = ("accumulate-signed", "log-intensity", "time-surface")

#: reader(i) -> (left, right) 8-bit frames of stereo window i
PairReader = Any


@dataclass(frozen=True)
class EsviOptions:
    """How ESVI frames are made from the events.

    Attributes
    ----------
    reconstruction : str
        One of :data:`ESVI_RECONSTRUCTIONS`.
    tau_s : float
        ``log-intensity`` memory [s] (the high-pass time constant).
    """

    reconstruction: str = "accumulate-signed"
    tau_s: float = 0.03

    def __post_init__(self) -> None:
        if self.reconstruction not in ESVI_RECONSTRUCTIONS:
            raise IbiscapeError(f"ESVI reconstruction {self.reconstruction!r}: use one of "
                                f"{', '.join(ESVI_RECONSTRUCTIONS)}")
        if not (np.isfinite(self.tau_s) and self.tau_s > 0):
            raise IbiscapeError(f"ESVI tau_s must be > 0, got {self.tau_s}")


def event_pair_names(seq: Sequence) -> tuple[str, str]:
    """The two event cameras of a sequence (``davisL``, ``davisR`` when present), or refuse naming
    the file that lacks the second one."""
    ev = [c.name for c in seq.cameras if c.kind == "events"]
    if "davisL" in ev and "davisR" in ev:
        return "davisL", "davisR"
    if len(ev) >= 2:
        return ev[0], ev[1]
    where = seq.path / "sequence.yaml" if (seq.path / "sequence.yaml").is_file() else seq.path
    raise CalibrationError(f"{where}: ESVI needs two event cameras (davisL, davisR), the sequence "
                           f"has {', '.join(ev) or 'none'}; record the stereo pair or use "
                           "{0} or {1}", hint=(Remedy("setup", "svi"), Remedy("setup", "rgbd")))


def _window_files(cam: CameraStream) -> tuple[npt.NDArray[np.int64], tuple[Path, ...]]:
    if cam.windows_ns is None or not cam.paths:
        raise FormatError(cam.root / "timestamps.csv", "no event windows (events/<ns>.npz listed "
                          "in timestamps.csv); render or record the DVS events first")
    return np.asarray(cam.windows_ns, np.int64).reshape(-1, 2), cam.paths


def event_stereo_frames(seq: Sequence, left_name: str, right_name: str,
                        options: EsviOptions | None = None
                        ) -> tuple[npt.NDArray[np.int64], PairReader, Any]:
    """Stamps (window ends both cameras share), ``reader(i)`` -> (left, right) 8-bit frames and
    ``labels(i)`` -> the two event files of pair ``i`` (for messages).

    Raises
    ------
    FormatError
        A camera without event windows, left and right windows that share no end time, or (when
        read) a window file that is missing or cannot be read.
    """
    from ibiscape_eval.calib.events import (
        EventFrameSource,
        contrast_from_sequence,
        read_event_window,
    )

    o = options or EsviOptions()
    cams = seq.camera(left_name), seq.camera(right_name)
    srcs = []
    files: list[tuple[Path, ...]] = []
    ends: list[npt.NDArray[np.int64]] = []
    for cam in cams:
        win, paths = _window_files(cam)
        size = cam.sensor_size
        if size is None and cam.camera is not None:
            size = (cam.camera.width_px, cam.camera.height_px)
        if size is None:
            raise CalibrationError(f"{cam.root}: the event camera's resolution is unknown; give "
                                   "the calibration")

        def read(i: int, paths: tuple[Path, ...] = paths) -> Any:
            if not paths[i].is_file():
                raise FormatError(paths[i], "event window listed in timestamps.csv is missing; "
                                  "re-export the events or trim timestamps.csv")
            return read_event_window(paths[i])

        srcs.append(EventFrameSource(read, win, size, o.reconstruction, tau_s=o.tau_s,
                                     contrast=contrast_from_sequence(cam.entry) or (0.3, 0.3),
                                     bidirectional=False, refine=False, cache_frames=2))
        files.append(paths)
        ends.append(win[:, 1])
    common = np.intersect1d(ends[0], ends[1])
    if len(common) < 2:
        raise FormatError(cams[1].root / "timestamps.csv", f"left ({len(ends[0])}) and right "
                          f"({len(ends[1])}) event windows share no end times; the DVS pair must be "
                          "synchronised")
    il, ir = np.searchsorted(ends[0], common), np.searchsorted(ends[1], common)

    def reader(i: int) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]:
        a, b = srcs[0](int(il[i])), srcs[1](int(ir[i]))
        assert a is not None and b is not None  # read errors raise instead
        return a, b

    def labels(i: int) -> tuple[str, str]:
        return str(files[0][int(il[i])]), str(files[1][int(ir[i])])

    return np.asarray(common, np.int64), reader, labels
