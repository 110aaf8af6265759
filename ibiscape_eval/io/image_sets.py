"""Plain image files for calibration, and the view table of several cameras.

- Globs: ``NAME=PATTERN`` (``cam0='left*.jpg'``), paired across cameras by a timestamp (the last
  run of digits) in the file names when every name has one, else by sorted order
  (:func:`image_sets_from_globs`; :func:`ibiscape_eval.io.open_sequence` opens them with
  ``images=``, as it opens every sequence layout).
- :func:`pair_views` turns several cameras (:class:`ImageSet` or the cameras of an opened
  sequence) into one view table (one row per instant).
"""

from __future__ import annotations

import glob
import os
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError, IbiscapeWarning

__all__ = [
    "ImageSet",
    "image_sets_from_globs",
    "pair_views",
    "read_image",
]

_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"}


@dataclass(frozen=True, eq=False)
class ImageSet:
    """One camera's frames.

    Attributes
    ----------
    name : str
    paths : tuple of Path
        Image files (frames), or the event files of each window (``kind == "events"``).
    stamps_ns : ndarray (N,) int64 or None
        Time of every frame (window end for events); None when the names carry none.
    kind : str
        ``"frames"`` or ``"events"``.
    root : Path
        The folder (or glob) the set came from.
    windows_ns : ndarray (N, 2) int64 or None
        Event windows ``[start, end)`` (events only).
    exact_stamps : bool
        The stamps are numbers from file names (matched exactly, not within a tolerance).
    """

    name: str
    paths: tuple[Path, ...]
    stamps_ns: npt.NDArray[np.int64] | None
    kind: str
    root: Path
    windows_ns: npt.NDArray[np.int64] | None = None
    exact_stamps: bool = False

    def __len__(self) -> int:
        return len(self.paths)

    def __repr__(self) -> str:
        return f"ImageSet({self.name}: {len(self)} {self.kind} from {self.root})"


def _digits_stamp(name: str) -> int | None:
    runs = re.findall(r"\d+", Path(name).stem)
    return int(runs[-1]) if runs else None


def image_sets_from_globs(specs: Sequence[str]) -> list[ImageSet]:
    """Image sets from ``NAME=GLOB`` specifications (the names' last digit runs are timestamps
    when every file of every set has a distinct one)."""
    sets: list[tuple[str, list[Path], str]] = []
    for spec in specs:
        if "=" not in spec:
            raise IbiscapeError(f"--images {spec!r}: write NAME=GLOB, e.g. cam0='left*.jpg'")
        name, pattern = (s.strip() for s in spec.split("=", 1))
        if not name or not pattern:
            raise IbiscapeError(f"--images {spec!r}: write NAME=GLOB, e.g. cam0='left*.jpg'")
        files = sorted(Path(p) for p in glob.glob(os.path.expanduser(pattern))
                       if Path(p).suffix.lower() in _IMAGE_SUFFIXES and Path(p).is_file())
        if not files:
            raise IbiscapeError(f"--images {name}={pattern}: no image files match")
        if any(name == s[0] for s in sets):
            raise IbiscapeError(f"--images: the camera name {name!r} is given twice")
        sets.append((name, files, pattern))
    stamps = [[_digits_stamp(p.name) for p in files] for _, files, _ in sets]
    by_stamp = all(None not in st and len(set(st)) == len(st) for st in stamps)
    out = []
    for (name, files, pattern), st in zip(sets, stamps, strict=True):
        arr = np.array(st, np.int64) if by_stamp else None
        if arr is not None:
            order = np.argsort(arr, kind="stable")
            files = [files[i] for i in order]
            arr = arr[order]
        out.append(ImageSet(name, tuple(files), arr, "frames", Path(pattern), exact_stamps=True))
    return out


class _Stamped(Protocol):
    """A camera's frames with their stamps (an :class:`ImageSet` or a ``CameraStream``)."""

    @property
    def name(self) -> str: ...
    @property
    def stamps_ns(self) -> npt.NDArray[np.int64] | None: ...
    @property
    def exact_stamps(self) -> bool: ...
    def __len__(self) -> int: ...


def pair_views(sets: Sequence[_Stamped], *, tolerance_ns: int = 1_000_000) -> list[list[int | None]]:
    """The view table: one row per instant, one column per set (frame index or None).

    Sets with timestamps are matched within ``tolerance_ns`` (exactly for numbers taken from file
    names); without, frames are paired by order (then every set must hold the same number of
    frames).
    """
    if any(s.exact_stamps for s in sets):
        tolerance_ns = 0
    if not sets:
        raise IbiscapeError("no image sets to pair")
    if len(sets) == 1:
        return [[i] for i in range(len(sets[0]))]
    if any(s.stamps_ns is None for s in sets):
        n = {s.name: len(s) for s in sets}
        if len(set(n.values())) != 1:
            raise IbiscapeError(
                "cannot pair the image sets by order: they hold "
                + ", ".join(f"{k} {v}" for k, v in n.items())
                + " images; give equally many, or names with a timestamp/number to pair by")
        return [[i] * len(sets) for i in range(len(sets[0]))]
    allst = np.sort(np.concatenate([s.stamps_ns for s in sets if s.stamps_ns is not None]))
    # merge stamps closer than the tolerance (equal ones too) into one view
    keep = np.concatenate([[True], np.diff(allst) > tolerance_ns])
    views = allst[keep]
    table: list[list[int | None]] = [[None] * len(sets) for _ in range(len(views))]
    for k, s in enumerate(sets):
        st = s.stamps_ns
        assert st is not None
        j = np.clip(np.searchsorted(views, st), 0, len(views) - 1)
        jm = np.clip(j - 1, 0, len(views) - 1)
        pick = np.where(np.abs(views[jm] - st) < np.abs(views[j] - st), jm, j)
        ok = np.abs(views[pick] - st) <= tolerance_ns
        for i in np.flatnonzero(ok):
            table[int(pick[i])][k] = int(i)
    if all(sum(c is not None for c in row) < 2 for row in table):
        raise IbiscapeError(
            "the image sets share no instant: "
            + ", ".join(f"{s.name} {int(s.stamps_ns[0])}..{int(s.stamps_ns[-1])}" for s in sets
                        if s.stamps_ns is not None)
            + f" (matched within {tolerance_ns} ns); are they recordings of the same session?")
    return table


def read_image(path: str | os.PathLike[str]) -> npt.NDArray[Any] | None:
    """Read an image (any depth, grey or colour); None with a warning naming the file when it is
    missing, unreadable or corrupt."""
    import cv2

    p = Path(path)
    img = None
    try:
        data = np.fromfile(p, dtype=np.uint8)
        if data.size:
            img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except OSError:
        img = None
    if img is None:
        warnings.warn(f"{p}: not a readable image; skipped", IbiscapeWarning, stacklevel=2)
    return img
