"""The :class:`Events` value type: a stream of DVS events, and :class:`EventChunk`, one piece of
a stream read from a file (so that errors found later can still name the file and the line)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .errors import IbiscapeError

__all__ = ["EventChunk", "Events"]


def _readonly(a: np.ndarray, dtype: type) -> np.ndarray:
    """A read-only view of ``a`` in ``dtype`` (copies only when the dtype differs)."""
    a = np.asarray(a)
    if a.dtype != dtype:
        a = a.astype(dtype)
    v = a.view()
    v.flags.writeable = False
    return v


@dataclass(frozen=True, eq=False)
class Events:
    """DVS events, sorted by time; immutable (its arrays are read-only views, never copies of
    arrays that already have the canonical dtypes).

    Parameters
    ----------
    t_ns : ndarray, shape (N,), int64
        Event timestamps in nanoseconds, non-decreasing.
    x, y : ndarray, shape (N,), uint16
        Pixel column and row (0-based, origin top left).
    p : ndarray, shape (N,), bool
        Polarity: True for a brightness increase.
    """

    t_ns: npt.NDArray[np.int64]
    x: npt.NDArray[np.uint16]
    y: npt.NDArray[np.uint16]
    p: npt.NDArray[np.bool_]

    def __post_init__(self) -> None:
        arrays = [np.asarray(a) for a in (self.t_ns, self.x, self.y, self.p)]
        if any(a.ndim != 1 for a in arrays) or len({a.shape[0] for a in arrays}) != 1:
            raise IbiscapeError(
                "events: t, x, y, p must be 1-D arrays of one length, got shapes "
                + ", ".join(str(a.shape) for a in arrays)
            )
        object.__setattr__(self, "t_ns", _readonly(arrays[0], np.int64))
        object.__setattr__(self, "x", _readonly(arrays[1], np.uint16))
        object.__setattr__(self, "y", _readonly(arrays[2], np.uint16))
        object.__setattr__(self, "p", _readonly(arrays[3], np.bool_))

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    @classmethod
    def empty(cls) -> Events:
        """A stream without events."""
        return cls(
            np.empty(0, np.int64),
            np.empty(0, np.uint16),
            np.empty(0, np.uint16),
            np.empty(0, np.bool_),
        )

    @classmethod
    def concatenate(cls, parts: list[Events]) -> Events:
        """Join streams end to end (the caller guarantees the time order)."""
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([e.t_ns for e in parts]),
            np.concatenate([e.x for e in parts]),
            np.concatenate([e.y for e in parts]),
            np.concatenate([e.p for e in parts]),
        )


@dataclass(frozen=True, eq=False)
class EventChunk:
    """A piece of an event stream as read from one file.

    Parameters
    ----------
    events
        The events of this piece.
    source
        The file they come from.
    offset
        Index of the first event of this piece within ``source`` (0-based).
    first_line
        For text files, the 1-based line of the first event; ``lines`` gives every event's line.
    lines : ndarray, shape (N,), int64, optional
        1-based line number of every event (text files only).
    """

    events: Events
    source: str
    offset: int = 0
    lines: npt.NDArray[np.int64] | None = None

    def where(self, i: int) -> tuple[str, int | None, str]:
        """Locate event ``i`` of this chunk: ``(file, line or None, "event k" text)``."""
        if self.lines is not None:
            return self.source, int(self.lines[i]), f"event {self.offset + i}"
        return self.source, None, f"event {self.offset + i}"
