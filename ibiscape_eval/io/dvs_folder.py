"""Streaming writer of one IBISCape DVS camera folder, window by window.

Layout (``../shared/FORMATS.md``)::

    <camera>/timestamps.csv          #timestamp_start [ns], timestamp_end [ns], filename
    <camera>/events/<end_ns>.npz     t (int64 ns), x, y (uint16), p (bool); one file per window
    <camera>/frames/<end_ns>.png     accumulated event frame of the window (for viewing)
    <camera>/frames/timestamps.csv   same three columns, naming the PNG files

Windows are named after their end, the camera frame at which CARLA hands the events over.  Each
``.npz`` goes through :func:`ibiscape_eval.io.events.write_events` and each file is written
atomically; :meth:`DvsFolderWriter.close` writes the two ``timestamps.csv`` last, so a folder
without them is an unfinished one (the simulator builds the whole sequence in a staging folder
anyway).  Read the result with :func:`ibiscape_eval.io.events.open_events`.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

from .atomic import atomic_output_path, atomic_write
from .events import write_events

__all__ = ["DVS_TIMESTAMPS_HEADER", "DvsFolderWriter", "read_dvs_frame_list"]

DVS_TIMESTAMPS_HEADER = "#timestamp_start [ns], timestamp_end [ns], filename\n"


class DvsFolderWriter:
    """Write ``events/<end>.npz`` (and optionally ``frames/<end>.png``) window by window.

    Parameters
    ----------
    folder : path
        The camera folder (created; ``events/`` and ``frames/`` inside must not hold files).
    frames : bool
        Also write an 8-bit accumulated frame per window.
    """

    def __init__(self, folder: str | os.PathLike[str], *, frames: bool = True) -> None:
        self.folder = Path(folder)
        self.events_dir = self.folder / "events"
        self.frames_dir = self.folder / "frames" if frames else None
        for d in (self.events_dir, self.frames_dir):
            if d is None:
                continue
            if d.exists() and any(d.iterdir()):
                raise IbiscapeError(f"{d}: already holds files; choose an empty camera folder")
            d.mkdir(parents=True, exist_ok=True)
        self._rows: list[str] = []
        self._frame_rows: list[str] = []
        self._last_end: int | None = None

    def add(self, start_ns: int, end_ns: int, events: Events,
            frame: npt.NDArray[np.uint8] | None = None) -> None:
        """Write one window ``[start_ns, end_ns]`` (windows in increasing time order)."""
        a, b = int(start_ns), int(end_ns)
        if b < a or (self._last_end is not None and a < self._last_end):
            raise IbiscapeError(f"DVS window [{a}, {b}] ns is out of order (previous end "
                                f"{self._last_end}); windows must follow each other in time")
        self._last_end = b
        name = f"{b}.npz"
        try:
            write_events(self.events_dir / name, events, fmt="npz")
            self._rows.append(f"{a}, {b}, {name} \n")
            if frame is not None and self.frames_dir is not None:
                import cv2

                png = self.frames_dir / f"{b}.png"
                with atomic_output_path(png) as tmp:
                    if not cv2.imwrite(str(tmp), np.ascontiguousarray(frame, dtype=np.uint8)):
                        raise IbiscapeError(f"{png}: could not write the PNG image (disk full?)")
                self._frame_rows.append(f"{a}, {b}, {b}.png \n")
        except OSError as e:
            if e.errno == errno.ENOSPC:
                raise IbiscapeError(f"{self.folder}: the disk filled up while writing DVS events; "
                                    "free some space or write elsewhere") from None
            raise

    def close(self) -> int:
        """Write the ``timestamps.csv`` files; return the number of windows."""
        with atomic_write(self.folder / "timestamps.csv") as f:
            f.write(DVS_TIMESTAMPS_HEADER)
            f.writelines(self._rows)
        if self.frames_dir is not None:
            with atomic_write(self.frames_dir / "timestamps.csv") as f:
                f.write(DVS_TIMESTAMPS_HEADER)
                f.writelines(self._frame_rows)
        return len(self._rows)


def read_dvs_frame_list(folder: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[Path]]:
    """End stamps [ns] and PNG paths of a DVS camera's accumulated frames
    (``<folder>/frames/timestamps.csv``, three columns)."""
    from .framelists import ns_integer, read_stamped_rows

    csv = Path(folder) / "frames" / "timestamps.csv"
    stamps, rows = read_stamped_rows(
        csv, expected="'timestamp_start [ns], timestamp_end [ns], filename'", ncols=3,
        stamp_col=1, parse=ns_integer,
        missing="not found: this DVS camera has no accumulated frames")
    return stamps, [csv.parent / r[2] for r in rows]
