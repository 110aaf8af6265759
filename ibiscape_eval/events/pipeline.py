"""Hot pixels of a recording, one call: open the events, count every pixel (streamed), decide.

The command ``ibiscape-eval hotpix`` and notebooks run the same decisions::

    from ibiscape_eval import hot_pixels
    run = hot_pixels("FULL_Dynamic_1/davisL", n_sigma=5)
    run.result.pixels, run.sensor_size, run.notes
    run.plot().savefig("hotpix.png")
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError, Remedy

from .hotpix import HotPixelResult, PixelCounter, hot_pixels_from_counts

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ibiscape_eval.io.events import EventSource

__all__ = ["HotPixelCriteria", "HotPixelRun", "hot_pixels"]

_SIZE = (Remedy("sensor_size"),)


@dataclass(frozen=True)
class HotPixelCriteria:
    """How a pixel is called hot: the ``top_n`` largest counts, counts above mean + ``n_sigma``
    x std, a rate criterion (``rate_min_events`` within ``rate_window_ms``), or a given list."""

    top_n: int | None = None
    n_sigma: float | None = None
    rate_min_events: int | None = None
    rate_window_ms: float | None = None
    per_polarity: bool = False
    applied: npt.NDArray[np.int64] | None = None

    def check(self, *, applied: bool = False) -> None:
        """Refuse contradictory criteria (a given list with thresholds, half a rate criterion)."""
        if (applied or self.applied is not None) and (self.top_n is not None or self.n_sigma is not None
                                         or self.rate_min_events):
            raise IbiscapeError("{0} uses a given hot-pixel list; drop {1}/{2}/{3}",
                                hint=(Remedy("apply_path"), Remedy("top_n"), Remedy("n_sigma"),
                                      Remedy("rate_min_events")))
        if (self.rate_min_events is None) != (self.rate_window_ms is None):
            raise IbiscapeError("the rate criterion needs both {0} and {1}",
                                hint=(Remedy("rate_min_events"), Remedy("rate_window_ms")))


@dataclass(frozen=True)
class HotPixelRun:
    """The hot pixels of one recording and where its numbers came from."""

    result: HotPixelResult
    source: EventSource
    sensor_size: tuple[int, int]
    size_from: str
    size_inferred: bool

    def plot(self, *, title: str = "events per pixel before and after hot-pixel removal"
             ) -> Figure:
        """Count histograms before / after and the sensor heat map (a new Figure)."""
        return self.result.plot(title=title)


def _check_applied(applied: npt.NDArray[np.int64], size: tuple[int, int],
                   apply_path: str | os.PathLike[str] | None) -> None:
    w, h = size
    out = (applied[:, 0] >= w) | (applied[:, 1] >= h)
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise FormatError(
            apply_path, f"hot pixel ({applied[i, 0]}, {applied[i, 1]}) lies outside the {w}x{h} "
            "sensor; is it the list of this camera? (or pass {0})", hint=_SIZE)


def hot_pixels(events: str | os.PathLike[str] | EventSource, criteria: HotPixelCriteria | None = None,
               *, sensor_size: tuple[int, int] | None = None, fmt: str | None = None,
               topic: str | None = None, apply_path: str | os.PathLike[str] | None = None,
               progress: Callable[[int], Any] | None = None) -> HotPixelRun:
    """Count the events of every pixel of ``events`` (a path any event reader opens, or an open
    :class:`~ibiscape_eval.io.events.EventSource`) in one streamed pass and call the hot pixels.

    ``sensor_size`` (W, H) overrides the file's; without either, the size is inferred from the
    largest coordinates (``size_inferred``).  ``apply_path`` reads a hot-pixel list (it replaces
    the criteria's ``applied``).  ``progress`` is called with the events of each chunk.
    """
    from ibiscape_eval.io.events import EventSource, iter_event_chunks, open_events, read_hot_pixels

    crit = criteria or HotPixelCriteria()
    crit.check(applied=apply_path is not None)
    if apply_path is not None:
        crit = replace(crit, applied=read_hot_pixels(apply_path))
    src = events if isinstance(events, EventSource) else open_events(events, fmt=fmt, topic=topic)
    counter = PixelCounter(
        sensor_size=sensor_size or src.sensor_size, per_polarity=crit.per_polarity,
        rate_min_events=crit.rate_min_events,
        rate_window_ns=None if crit.rate_window_ms is None else round(crit.rate_window_ms * 1e6))
    for chunk in iter_event_chunks(src, reuse_buffers=True):  # the counter keeps nothing
        counter.add(chunk.events, chunk)
        if progress is not None:
            progress(len(chunk.events))
    size = counter.sensor_size
    if crit.applied is not None:
        _check_applied(crit.applied, size, apply_path)
        result = hot_pixels_from_counts(counter.count_map, extra_pixels=crit.applied)
    else:
        result = counter.result(top_n=crit.top_n, n_sigma=crit.n_sigma)
    size_from = ("sensor_size" if sensor_size is not None
                 else src.size_from or "the largest event coordinates")
    return HotPixelRun(result, src, size, size_from,
                       size_inferred=sensor_size is None and src.sensor_size is None)
